#include "common/render.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace godhand {

namespace {

namespace fs = std::filesystem;

constexpr const char* kThisHost = "192.0.2.10";  // placeholders of the shipped templates
constexpr const char* kServer = "192.0.2.1<";

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

bool validUnitName(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '.' || c == '-'))
      return false;
  return true;
}

/// Replaces every `from` in `text` by `to`; throws unless there was at least one.
std::string replaceAll(std::string text, const std::string& from, const std::string& to, const std::string& what) {
  size_t pos = text.find(from);
  if (pos == std::string::npos) throw LabError("--render: the " + what + " template has no placeholder '" + from + "'");
  while (pos != std::string::npos) {
    text.replace(pos, from.size(), to);
    pos = text.find(from, pos + to.size());
  }
  return text;
}

const char* kindName(pb::Service::Kind k) {
  switch (k) {
    case pb::Service::INGEST: return "INGEST";
    case pb::Service::SOLVER: return "SOLVER";
    case pb::Service::SCENE: return "SCENE";
    case pb::Service::RESOLVER: return "RESOLVER";
    default: return "KIND_UNSPECIFIED";
  }
}

std::string num(double x) {
  std::ostringstream os;
  os.precision(17);
  os << x;
  return os.str();
}

}  // namespace

namespace {

/// `xml` with the DDS-Security properties of identity `identity` inserted into the participant
/// profile (before its </rtps>).
std::string secured(const std::string& xml, const LabConfig& lab, const std::string& identity, const RenderOptions& o) {
  if (lab.security.empty()) return xml;
  const size_t block = o.security_template.find("<propertiesPolicy>");
  const size_t end = o.security_template.find("</propertiesPolicy>");
  if (block == std::string::npos || end == std::string::npos)
    throw LabError("--render: the security template has no <propertiesPolicy> block");
  std::string props = o.security_template.substr(block, end + std::strlen("</propertiesPolicy>") - block);
  props = replaceAll(props, "@PKI_DIR@", lab.security, "security");
  props = replaceAll(props, "@IDENTITY@", identity, "security");
  const size_t participant = xml.find("<participant ");
  const size_t rtps_end = participant == std::string::npos ? std::string::npos : xml.find("</rtps>", participant);
  if (rtps_end == std::string::npos) throw LabError("--render: the profiles template has no participant <rtps> element");
  return xml.substr(0, rtps_end) + props + "\n    " + xml.substr(rtps_end);
}

}  // namespace

std::string renderHostProfiles(const LabConfig& lab, const LabHost& host, const RenderOptions& o) {
  return secured(renderPlainProfiles(lab, host, o), lab, host.name, o);
}

std::string renderPlainProfiles(const LabConfig& lab, const LabHost& host, const RenderOptions& o) {
  if (!lab.discovery_server.empty()) {
    const LabHost* server = lab.host(lab.discovery_server);
    if (!server) throw LabError("--render: discovery_server " + quoted(lab.discovery_server) + " is not a host of the lab");
    std::string x = replaceAll(o.client_template, kThisHost, host.address, "discovery-client profiles");
    x = replaceAll(x, kServer, server->address + "<", "discovery-client profiles");
    return replaceAll(x, "<port>11811</port>", "<port>" + std::to_string(lab.discovery_port) + "</port>",
                      "discovery-client profiles");
  }
  // No server: unicast initial peers to every host, this host's address whitelisted.
  std::string x = o.peers_template;
  const size_t a = x.find("<initialPeersList>"), b = x.find("</initialPeersList>");
  if (a == std::string::npos || b == std::string::npos || b < a)
    throw LabError("--render: the multi-host profiles template has no <initialPeersList>");
  std::string peers = "<initialPeersList>\n";
  for (const LabHost& h : lab.hosts)
    peers += "          <locator><udpv4><address>" + h.address + "</address></udpv4></locator>  <!-- " + h.name + " -->\n";
  peers += "        ";
  x.replace(a, b - a, peers);
  return replaceAll(x, "<maxInitialPeersRange>32</maxInitialPeersRange>",
                    "<maxInitialPeersRange>32</maxInitialPeersRange>\n      <interfaceWhiteList><address>" + host.address +
                        "</address></interfaceWhiteList>",
                    "multi-host profiles");
}

std::string renderLabText(const LabConfig& lab, const std::string& profiles_dir) {
  std::ostringstream s;
  s << "# Lab " << quoted(lab.name) << ", rendered by godhand-launch --render from " << lab.file << ".\n"
    << "# Identical on every host of the lab (cluster order = wire numbering): do not edit one copy.\n"
    << "name: " << quoted(lab.name) << "\n"
    << "domain_id: " << lab.domain_id << "\n";
  if (!lab.profiles.empty() && profiles_dir.empty()) s << "profiles: " << quoted(lab.profiles) << "\n";
  s << "scene: " << quoted(lab.scene) << "\n";
  if (!lab.recording.empty()) s << "recording: " << quoted(lab.recording) << "\n";
  s << "deadline_s: " << num(lab.deadline_s) << "\n"
    << "stale_after_s: " << num(lab.stale_after_s) << "\n";
  for (const LabHost& h : lab.hosts) {
    s << "hosts { name: " << quoted(h.name) << " address: " << quoted(h.address);
    const std::string p = profiles_dir.empty() ? h.profiles : profiles_dir + "/profiles-" + h.name + ".xml";
    if (!p.empty()) s << " profiles: " << quoted(p);
    s << " }\n";
  }
  if (!lab.discovery_server.empty())
    s << "discovery_server: " << quoted(lab.discovery_server) << "\ndiscovery_port: " << lab.discovery_port << "\n";
  if (!lab.security.empty()) s << "security: " << quoted(lab.security) << "\n";
  for (const LabCluster& c : lab.clusters) {
    s << "clusters { name: " << quoted(c.name) << " model: " << quoted(c.model);
    if (c.tracker_body >= 0) s << " tracker_body: " << c.tracker_body;
    else s << " side: " << quoted(c.side);
    s << " }\n";
  }
  for (const LabService& v : lab.services) {
    s << "services { kind: " << kindName(v.kind);
    if (!v.cluster.empty()) s << " cluster: " << quoted(v.cluster);
    if (!v.host.empty()) s << " host: " << quoted(v.host);
    for (const std::string& a : v.args) s << " args: " << quoted(a);
    s << " }\n";
  }
  return s.str();
}

std::vector<RenderedFile> renderSystemd(const LabConfig& lab, const RenderOptions& o) {
  if (lab.hosts.empty())
    throw LabError(lab.file + ": --render: the lab names no hosts (add hosts { name: \"...\" address: \"...\" }, see "
                              "deploy/lab/two-machines.pbtxt)");
  if (!validUnitName(lab.name))
    throw LabError(lab.file + ": --render: lab name " + quoted(lab.name) +
                   " cannot name a systemd unit (1 to 64 characters of A-Z, a-z, 0-9, '_', '.', '-')");
  if (o.launch.empty() || o.launch[0] != '/') throw LabError("--render: the path of godhand-launch must be absolute");
  const std::string dir = o.install_dir + "/" + lab.name;  // on the hosts
  const std::string unit = "godhand-" + lab.name;
  const std::string lab_text = renderLabText(lab, dir);
  std::vector<RenderedFile> out;
  for (const LabHost& h : lab.hosts) {
    const std::string p = h.name + "/";
    const bool server = h.name == lab.discovery_server;
    std::string services;
    for (const LabService& v : lab.services)
      if (v.host == h.name) services += (services.empty() ? "" : ", ") + v.name;
    if (services.empty()) services = "no godhand service (monitor only)";

    out.push_back({p + "lab.pbtxt", lab_text});
    for (const LabHost& other : lab.hosts) out.push_back({p + "profiles-" + other.name + ".xml", renderHostProfiles(lab, other, o)});

    out.push_back({p + unit + ".env",
                   "# Environment of " + unit + ".service on host " + h.name + " (rendered by godhand-launch --render).\n"
                   "GODHAND_LAB=" + dir + "/lab.pbtxt\n"
                   "GODHAND_HOST=" + h.name + "\n"
                   "# Extra godhand-launch arguments (e.g. --source dtrack:5000 on the tracker host, --quiet).\n"
                   "GODHAND_LAUNCH_ARGS=--restart\n"
                   "FASTRTPS_DEFAULT_PROFILES_FILE=" + dir + "/profiles-" + h.name + ".xml\n"});

    std::string after = "network-online.target";
    if (server) after += " " + unit + "-discovery.service";
    out.push_back({p + unit + ".service",
                   "# godhand lab " + lab.name + ", host " + h.name + ": " + services + ".\n"
                   "# Rendered by godhand-launch --render systemd from " + lab.file + "; install with " + p + "INSTALL.\n"
                   "[Unit]\n"
                   "Description=godhand lab " + lab.name + " on " + h.name + " (" + services + ")\n"
                   "Wants=network-online.target\n"
                   "After=" + after + "\n"
                   "\n"
                   "[Service]\n"
                   "Type=simple\n"
                   "EnvironmentFile=" + dir + "/" + unit + ".env\n"
                   "ExecStart=" + o.launch + " --lab ${GODHAND_LAB} --host ${GODHAND_HOST} --log-dir /var/log/" + unit +
                       " $GODHAND_LAUNCH_ARGS\n"
                   "LogsDirectory=" + unit + "\n"
                   "KillSignal=SIGTERM\n"
                   "TimeoutStopSec=20\n"
                   "Restart=on-failure\n"
                   "RestartSec=2\n"
                   "\n"
                   "[Install]\n"
                   "WantedBy=multi-user.target\n"});
    if (server) {
      std::string x = replaceAll(o.server_template, kServer, h.address + "<", "discovery-server profiles");
      x = replaceAll(x, "<port>11811</port>", "<port>" + std::to_string(lab.discovery_port) + "</port>", "discovery-server profiles");
      out.push_back({p + "discovery-server.xml", x});
      out.push_back({p + unit + "-discovery.service",
                     "# The Fast DDS Discovery Server of godhand lab " + lab.name + " (rendered by godhand-launch --render).\n"
                     "[Unit]\n"
                     "Description=godhand lab " + lab.name + ": Fast DDS discovery server on " + h.address + ":" +
                         std::to_string(lab.discovery_port) + "\n"
                     "Wants=network-online.target\n"
                     "After=network-online.target\n"
                     "Before=" + unit + ".service\n"
                     "\n"
                     "[Service]\n"
                     "Type=simple\n"
                     "ExecStart=" + o.discovery_tool + " -x godhand_discovery_server@" + dir + "/discovery-server.xml\n"
                     "Restart=always\n"
                     "RestartSec=2\n"
                     "\n"
                     "[Install]\n"
                     "WantedBy=multi-user.target\n"});
    }
    std::string order;
    if (!lab.discovery_server.empty()) order += "  1. " + lab.discovery_server + ": the discovery server (" + unit + "-discovery)\n";
    order += "  " + std::string(lab.discovery_server.empty() ? "1" : "2") +
             ". every host but the ingest's, in any order: " + unit + "\n";
    order += "  " + std::string(lab.discovery_server.empty() ? "2" : "3") +
             ". the ingest's host last (its launcher waits for every other service, then starts the tracker)\n";
    out.push_back({p + "INSTALL",
                   "godhand lab " + lab.name + ", host " + h.name + " (" + h.address + "): " + services + "\n\n"
                   "On " + h.name + ", as root:\n" +
                   (lab.security.empty() ? std::string()
                                         : "  mkdir -p " + lab.security + " && chmod 700 " + lab.security +
                                               " && cp PKI/ca.pem PKI/governance.p7s PKI/permissions.p7s PKI/" + h.name +
                                               ".pem PKI/" + h.name + ".key " + lab.security +
                                               "/   (PKI: make-lab-pki.sh's output; only this host's key)\n") +
                   "  mkdir -p " + dir + " && cp lab.pbtxt profiles-*.xml " + unit + ".env" +
                       (server ? " discovery-server.xml" : "") + " " + dir + "/\n"
                   "  cp " + unit + ".service" + (server ? " " + unit + "-discovery.service" : "") + " /etc/systemd/system/\n"
                   "  systemctl daemon-reload\n"
                   "  systemctl enable --now " + (server ? unit + "-discovery " : "") + unit + "\n"
                   "Needs: godhand installed with " + o.launch + " and the lab's data at the paths in lab.pbtxt (same on every\n"
                   "host), UDP between the hosts' addresses (ports 7400 + 250 * domain and up" +
                       (lab.discovery_server.empty() ? "" : ", and " + std::to_string(lab.discovery_port) + " on the server") +
                       "), clocks synchronised (chrony/PTP) for the latency figures.\n"
                   "Start order across the lab:\n" + order +
                   "Logs: journalctl -u " + unit + ", service logs in /var/log/" + unit + "/.\n"});
  }
  return out;
}

bool takeRenderArgs(int& argc, char** argv, std::string* kind, std::string* dir, std::string* error) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--render=", 0) == 0) {
      *error = "--render takes two values: --render systemd OUTDIR";
      return false;
    }
    if (a != "--render") continue;
    if (i + 2 >= argc || std::string(argv[i + 1]).rfind("--", 0) == 0 || std::string(argv[i + 2]).rfind("--", 0) == 0) {
      *error = "--render needs a kind and a directory: --render systemd OUTDIR";
      return false;
    }
    *kind = argv[i + 1];
    *dir = argv[i + 2];
    if (*kind != "systemd") {
      *error = "--render: unknown kind '" + *kind + "' (known: systemd)";
      return false;
    }
    for (int j = i; j + 3 <= argc; ++j) argv[j] = argv[j + 3];
    argc -= 3;
    return true;
  }
  return true;
}

void writeRendered(const std::vector<RenderedFile>& files, const std::string& outdir) {
  for (const RenderedFile& f : files) {
    const fs::path p = fs::path(outdir) / f.path;
    std::error_code ec;
    fs::create_directories(p.parent_path(), ec);
    if (ec) throw LabError("--render: cannot create " + p.parent_path().string() + ": " + ec.message());
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out << f.text;
    out.close();
    if (!out) throw LabError("--render: cannot write " + p.string() + ": " + std::strerror(errno));
  }
}

int renderCommand(const LabConfig& lab, const std::string& kind, const std::string& outdir, const std::string& launch,
                  const std::string& dds_dir) {
  try {
    if (kind != "systemd") throw LabError("--render: unknown kind '" + kind + "' (known: systemd)");
    auto read = [](const std::string& path) {
      std::ifstream in(path, std::ios::binary);
      if (!in) throw LabError("--render: cannot read the template " + path);
      std::ostringstream ss;
      ss << in.rdbuf();
      return ss.str();
    };
    RenderOptions o;
    o.launch = launch;
    o.client_template = read(dds_dir + "/godhand-multihost-ds.xml");
    o.peers_template = read(dds_dir + "/godhand-multihost.xml");
    o.server_template = read(dds_dir + "/godhand-discovery-server.xml");
    if (!lab.security.empty()) o.security_template = read(dds_dir + "/../security/participant-security.xml");
    const std::vector<RenderedFile> files = renderSystemd(lab, o);
    writeRendered(files, outdir);
    std::printf("godhand-launch: rendered lab '%s' for %zu host(s) into %s (%zu files); see HOST/INSTALL\n", lab.name.c_str(),
                lab.hosts.size(), outdir.c_str(), files.size());
    for (const LabHost& h : lab.hosts) std::printf("  %s/%s/\n", outdir.c_str(), h.name.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "godhand-launch: %s\n", e.what());
    return 2;
  }
}

}  // namespace godhand
