// Deploy a lab from its one configuration: `godhand-launch --render systemd OUTDIR` writes, for
// every host of the lab (Lab.hosts), the files that host needs, in OUTDIR/HOST/:
//
//   godhand-LAB.service             systemd unit: godhand-launch --lab ... --host HOST
//   godhand-LAB.env                 its environment (lab file, host, extra launch arguments,
//                                   FASTRTPS_DEFAULT_PROFILES_FILE)
//   godhand-LAB-discovery.service   only on Lab.discovery_server: `fast-discovery-server`
//   discovery-server.xml            its profile (only there)
//   lab.pbtxt                       the lab file, identical on every host: absolute paths, each
//                                   host's `profiles` pointing at its profiles-HOST.xml
//   profiles-H.xml (every host H)   Fast DDS profiles of host H: UDP on H's address only, SHM
//                                   between H's processes; discovery through the server
//                                   (godhand-multihost-ds.xml) or, without one, unicast initial
//                                   peers to every host (godhand-multihost.xml)
//   INSTALL                         where each file goes, in which order to start the hosts
//
// With Lab.security (a lab PKI directory on the hosts, from deploy/security/make-lab-pki.sh),
// every host's profiles carry the DDS-Security properties (participant-security.xml) with the
// host's own identity (HOST.pem, HOST.key) and the lab's CA, governance and permissions.
//
// Every host's directory is meant for /etc/godhand/LAB/ (RenderOptions::install_dir) and its
// units for /etc/systemd/system/. Rendering is pure (text in, files as text out) apart from
// writeRendered(); errors are LabError with one line.
#pragma once

#include <string>
#include <vector>

#include "common/lab_config.h"

namespace godhand {

struct RenderedFile {
  std::string path;  ///< relative to OUTDIR: "HOST/NAME"
  std::string text;
};

struct RenderOptions {
  std::string launch;                 ///< absolute path of godhand-launch on the hosts
  std::string client_template;        ///< text of deploy/dds/godhand-multihost-ds.xml
  std::string peers_template;         ///< text of deploy/dds/godhand-multihost.xml
  std::string server_template;        ///< text of deploy/dds/godhand-discovery-server.xml
  std::string security_template;      ///< text of deploy/security/participant-security.xml (Lab.security)
  std::string install_dir = "/etc/godhand";  ///< each host's files go to INSTALL_DIR/LAB/
  std::string discovery_tool = "/usr/bin/fast-discovery-server";
};

/// The files of every host (throws LabError: a lab without hosts, a template without its
/// placeholders, a lab name that cannot name a unit).
std::vector<RenderedFile> renderSystemd(const LabConfig& lab, const RenderOptions& options);

/// Host `host`'s Fast DDS profiles from the templates (see above), secured with Lab.security.
std::string renderHostProfiles(const LabConfig& lab, const LabHost& host, const RenderOptions& options);
/// The same without the security properties.
std::string renderPlainProfiles(const LabConfig& lab, const LabHost& host, const RenderOptions& options);

/// The lab as protobuf text (schema idl/lab.proto) with absolute paths; `profiles_dir` non-empty:
/// every host's `profiles` is PROFILES_DIR/profiles-HOST.xml.
std::string renderLabText(const LabConfig& lab, const std::string& profiles_dir);

/// Takes "--render KIND OUTDIR" (two values, which the option parser cannot) out of argv.
/// Returns false with `error` set on a malformed use; true otherwise (kind/dir empty if absent).
bool takeRenderArgs(int& argc, char** argv, std::string* kind, std::string* dir, std::string* error);

/// Writes the files under `outdir` (created). Throws LabError naming the file that failed.
void writeRendered(const std::vector<RenderedFile>& files, const std::string& outdir);

/// `godhand-launch --render KIND OUTDIR`: renders `lab` with the templates of `dds_dir`
/// (deploy/dds) for `launch` (absolute path of godhand-launch), writes OUTDIR, prints what it
/// wrote. Returns the exit status: 0, or 2 after one line on stderr.
int renderCommand(const LabConfig& lab, const std::string& kind, const std::string& outdir, const std::string& launch,
                  const std::string& dds_dir);

}  // namespace godhand
