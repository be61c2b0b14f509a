// Deploying a lab from its one configuration (services/common/render.h): per-host systemd units,
// environment files and profiles rendered from a lab with hosts, against the shipped templates.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>

#include "common/render.h"

namespace godhand {
namespace {

namespace fs = std::filesystem;

const std::string kDeploy = GODHAND_DEPLOY_DIR;

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

RenderOptions options() {
  RenderOptions o;
  o.launch = "/opt/godhand/bin/godhand-launch";
  o.client_template = readFile(kDeploy + "/dds/godhand-multihost-ds.xml");
  o.peers_template = readFile(kDeploy + "/dds/godhand-multihost.xml");
  o.server_template = readFile(kDeploy + "/dds/godhand-discovery-server.xml");
  return o;
}

std::map<std::string, std::string> byPath(const std::vector<RenderedFile>& files) {
  std::map<std::string, std::string> m;
  for (const RenderedFile& f : files) {
    EXPECT_TRUE(m.emplace(f.path, f.text).second) << "rendered twice: " << f.path;
  }
  return m;
}

/// The addresses inside <interfaceWhiteList> elements of a profiles text.
std::vector<std::string> whitelist(const std::string& xml) {
  std::vector<std::string> out;
  const std::regex re("<interfaceWhiteList><address>([0-9.]+)</address></interfaceWhiteList>");
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), re); it != std::sregex_iterator(); ++it) out.push_back((*it)[1]);
  return out;
}

TEST(Render, TwoMachineLabWithDiscoveryServer) {
  const LabConfig lab = loadLab(kDeploy + "/lab/two-machines.pbtxt");
  const auto files = byPath(renderSystemd(lab, options()));
  // Both hosts get their unit, env, lab file, every host's profiles and the instructions; the
  // discovery server's unit and profile only on its host.
  for (const std::string h : {"tracker-pc", "compute-pc"}) {
    for (const std::string f : {"godhand-two-machines.service", "godhand-two-machines.env", "lab.pbtxt",
                                "profiles-tracker-pc.xml", "profiles-compute-pc.xml", "INSTALL"})
      EXPECT_TRUE(files.count(h + "/" + f)) << h << "/" << f;
  }
  EXPECT_TRUE(files.count("compute-pc/godhand-two-machines-discovery.service"));
  EXPECT_TRUE(files.count("compute-pc/discovery-server.xml"));
  EXPECT_FALSE(files.count("tracker-pc/godhand-two-machines-discovery.service"));
  EXPECT_FALSE(files.count("tracker-pc/discovery-server.xml"));

  const std::string unit = files.at("tracker-pc/godhand-two-machines.service");
  EXPECT_NE(unit.find("ExecStart=/opt/godhand/bin/godhand-launch --lab ${GODHAND_LAB} --host ${GODHAND_HOST}"), std::string::npos) << unit;
  EXPECT_NE(unit.find("EnvironmentFile=/etc/godhand/two-machines/godhand-two-machines.env"), std::string::npos) << unit;
  EXPECT_NE(unit.find("(ingest)"), std::string::npos) << unit;
  EXPECT_NE(files.at("compute-pc/godhand-two-machines.service").find("After=network-online.target godhand-two-machines-discovery.service"),
            std::string::npos);
  const std::string env = files.at("compute-pc/godhand-two-machines.env");
  EXPECT_NE(env.find("GODHAND_HOST=compute-pc\n"), std::string::npos) << env;
  EXPECT_NE(env.find("GODHAND_LAB=/etc/godhand/two-machines/lab.pbtxt\n"), std::string::npos) << env;
  EXPECT_NE(env.find("FASTRTPS_DEFAULT_PROFILES_FILE=/etc/godhand/two-machines/profiles-compute-pc.xml\n"), std::string::npos);

  // Profiles: each host's own address whitelisted, the server's address and port, no placeholder.
  const std::string pt = files.at("tracker-pc/profiles-tracker-pc.xml");
  EXPECT_EQ(whitelist(pt), (std::vector<std::string>{"192.0.2.10"}));
  EXPECT_NE(pt.find("<address>192.0.2.11</address><port>11811</port>"), std::string::npos);
  EXPECT_NE(pt.find("<discoveryProtocol>CLIENT</discoveryProtocol>"), std::string::npos);
  const std::string pc = files.at("tracker-pc/profiles-compute-pc.xml");
  EXPECT_EQ(whitelist(pc), (std::vector<std::string>{"192.0.2.11"}));
  EXPECT_EQ(pc.find("192.0.2.10"), std::string::npos) << "the other host's address must not be whitelisted";
  const std::string srv = files.at("compute-pc/discovery-server.xml");
  EXPECT_EQ(whitelist(srv), (std::vector<std::string>{"192.0.2.11"}));
  EXPECT_EQ(srv.find("192.0.2.1<"), std::string::npos);
  EXPECT_NE(files.at("compute-pc/godhand-two-machines-discovery.service")
                .find("ExecStart=/usr/bin/fast-discovery-server -x godhand_discovery_server@/etc/godhand/two-machines/discovery-server.xml"),
            std::string::npos);
  // The same lab file on every host.
  EXPECT_EQ(files.at("tracker-pc/lab.pbtxt"), files.at("compute-pc/lab.pbtxt"));
  // Start order: server, then the other hosts, the ingest's last.
  const std::string install = files.at("tracker-pc/INSTALL");
  ASSERT_NE(install.find("1. compute-pc: the discovery server"), std::string::npos) << install;
  ASSERT_NE(install.find("3. the ingest's host last"), std::string::npos) << install;
  EXPECT_LT(install.find("1. compute-pc: the discovery server"), install.find("3. the ingest's host last")) << install;
}

TEST(Render, RenderedLabFileLoadsAndEqualsTheSource) {
  const LabConfig lab = loadLab(kDeploy + "/lab/two-machines.pbtxt");
  // Rendered with profiles in a real directory, so that loading it checks that they exist.
  const fs::path dir = fs::temp_directory_path() / ("godhand-render-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const LabHost& h : lab.hosts) std::ofstream(dir / ("profiles-" + h.name + ".xml")) << "<profiles/>\n";
  const LabConfig back = parseLab(renderLabText(lab, dir.string()), "rendered.pbtxt", "/");
  EXPECT_EQ(back.name, lab.name);
  EXPECT_EQ(back.domain_id, lab.domain_id);
  EXPECT_EQ(back.scene, lab.scene);
  EXPECT_EQ(back.recording, lab.recording);
  EXPECT_DOUBLE_EQ(back.deadline_s, lab.deadline_s);
  EXPECT_DOUBLE_EQ(back.stale_after_s, lab.stale_after_s);
  EXPECT_EQ(back.discovery_server, lab.discovery_server);
  EXPECT_EQ(back.discovery_port, lab.discovery_port);
  ASSERT_EQ(back.clusters.size(), lab.clusters.size());
  for (size_t i = 0; i < lab.clusters.size(); ++i) {
    EXPECT_EQ(back.clusters[i].name, lab.clusters[i].name);
    EXPECT_EQ(back.clusters[i].model, lab.clusters[i].model);
    EXPECT_EQ(back.clusters[i].side, lab.clusters[i].side);
  }
  ASSERT_EQ(back.services.size(), lab.services.size());
  for (size_t i = 0; i < lab.services.size(); ++i) {
    EXPECT_EQ(back.services[i].name, lab.services[i].name);
    EXPECT_EQ(back.services[i].host, lab.services[i].host);
    EXPECT_EQ(back.services[i].args, lab.services[i].args);
  }
  ASSERT_EQ(back.hosts.size(), lab.hosts.size());
  for (size_t i = 0; i < lab.hosts.size(); ++i) {
    EXPECT_EQ(back.hosts[i].address, lab.hosts[i].address);
    EXPECT_EQ(back.hosts[i].profiles, (dir / ("profiles-" + lab.hosts[i].name + ".xml")).string());
  }
  fs::remove_all(dir);
}

TEST(Render, WithoutDiscoveryServerEveryHostIsAnInitialPeer) {
  LabConfig lab = loadLab(kDeploy + "/lab/two-machines.pbtxt");
  lab.discovery_server.clear();
  const auto files = byPath(renderSystemd(lab, options()));
  EXPECT_FALSE(files.count("compute-pc/godhand-two-machines-discovery.service"));
  const std::string p = files.at("compute-pc/profiles-compute-pc.xml");
  EXPECT_EQ(whitelist(p), (std::vector<std::string>{"192.0.2.11"}));
  const size_t a = p.find("<initialPeersList>"), b = p.find("</initialPeersList>");
  ASSERT_NE(a, std::string::npos);
  const std::string peers = p.substr(a, b - a);
  EXPECT_NE(peers.find("<address>192.0.2.10</address>"), std::string::npos) << peers;
  EXPECT_NE(peers.find("<address>192.0.2.11</address>"), std::string::npos) << peers;
  EXPECT_EQ(peers.find("192.0.2.12"), std::string::npos) << "the template's placeholders are gone: " << peers;
  EXPECT_EQ(p.find("CLIENT"), std::string::npos);
}

TEST(Render, SecuredLabGetsEachHostsIdentity) {
  LabConfig lab = loadLab(kDeploy + "/lab/two-machines.pbtxt");
  lab.discovery_server.clear();  // (a lab file with both is refused, see LabHosts)
  lab.security = "/etc/godhand/two-machines/pki";
  RenderOptions o = options();
  o.security_template = readFile(kDeploy + "/security/participant-security.xml");
  const auto files = byPath(renderSystemd(lab, o));
  for (const std::string h : {"tracker-pc", "compute-pc"}) {
    const std::string p = files.at("compute-pc/profiles-" + h + ".xml");
    EXPECT_NE(p.find("<value>builtin.PKI-DH</value>"), std::string::npos);
    EXPECT_NE(p.find("<value>builtin.AES-GCM-GMAC</value>"), std::string::npos);
    EXPECT_NE(p.find("<value>builtin.Access-Permissions</value>"), std::string::npos);
    EXPECT_NE(p.find("file:///etc/godhand/two-machines/pki/" + h + ".pem"), std::string::npos) << p;
    EXPECT_NE(p.find("file:///etc/godhand/two-machines/pki/" + h + ".key"), std::string::npos);
    EXPECT_NE(p.find("file:///etc/godhand/two-machines/pki/governance.p7s"), std::string::npos);
    EXPECT_EQ(p.find("@IDENTITY@"), std::string::npos);
    EXPECT_EQ(p.find("@PKI_DIR@"), std::string::npos);
    // inside the participant's <rtps>, before it closes
    const size_t props = p.find("<propertiesPolicy>"), rtps_end = p.find("</rtps>", p.find("<participant "));
    EXPECT_LT(props, rtps_end);
    EXPECT_GT(props, p.find("<participant "));
    EXPECT_EQ(renderPlainProfiles(lab, *lab.host(h), o).find("propertiesPolicy"), std::string::npos);
  }
  EXPECT_NE(files.at("tracker-pc/lab.pbtxt").find("security: \"/etc/godhand/two-machines/pki\""), std::string::npos);
  EXPECT_NE(files.at("tracker-pc/INSTALL").find("PKI/tracker-pc.key"), std::string::npos);
  EXPECT_EQ(files.at("tracker-pc/INSTALL").find("compute-pc.key"), std::string::npos) << "only the host's own key";
  o.security_template = "nothing";
  EXPECT_THROW(renderSystemd(lab, o), LabError);
}

TEST(Render, RejectsWhatCannotBeDeployed) {
  const LabConfig local = loadLab(kDeploy + "/lab/local.pbtxt");
  try {
    renderSystemd(local, options());
    ADD_FAILURE() << "a lab without hosts rendered";
  } catch (const LabError& e) {
    EXPECT_NE(std::string(e.what()).find("names no hosts"), std::string::npos) << e.what();
  }
  LabConfig lab = loadLab(kDeploy + "/lab/two-machines.pbtxt");
  lab.name = "my lab";
  EXPECT_THROW(renderSystemd(lab, options()), LabError);
  lab.name = "ok";
  RenderOptions o = options();
  o.client_template = "<profiles/>";
  try {
    renderSystemd(lab, o);
    ADD_FAILURE() << "a template without placeholders rendered";
  } catch (const LabError& e) {
    EXPECT_NE(std::string(e.what()).find("placeholder"), std::string::npos) << e.what();
  }
  o = options();
  o.launch = "godhand-launch";
  EXPECT_THROW(renderSystemd(lab, o), LabError);
}

TEST(Render, TakeRenderArgs) {
  std::string kind, dir, error;
  {
    char a0[] = "godhand-launch", a1[] = "--lab", a2[] = "x.pbtxt", a3[] = "--render", a4[] = "systemd", a5[] = "/tmp/out",
         a6[] = "--quiet";
    char* argv[] = {a0, a1, a2, a3, a4, a5, a6, nullptr};
    int argc = 7;
    ASSERT_TRUE(takeRenderArgs(argc, argv, &kind, &dir, &error)) << error;
    EXPECT_EQ(kind, "systemd");
    EXPECT_EQ(dir, "/tmp/out");
    ASSERT_EQ(argc, 4);
    EXPECT_STREQ(argv[3], "--quiet");
    EXPECT_EQ(argv[4], nullptr);
  }
  {
    char a0[] = "godhand-launch", a1[] = "--render", a2[] = "docker", a3[] = "/tmp/out";
    char* argv[] = {a0, a1, a2, a3, nullptr};
    int argc = 4;
    EXPECT_FALSE(takeRenderArgs(argc, argv, &kind, &dir, &error));
    EXPECT_NE(error.find("unknown kind 'docker'"), std::string::npos) << error;
  }
  {
    char a0[] = "godhand-launch", a1[] = "--render", a2[] = "systemd";
    char* argv[] = {a0, a1, a2, nullptr};
    int argc = 3;
    EXPECT_FALSE(takeRenderArgs(argc, argv, &kind, &dir, &error));
  }
  {
    char a0[] = "godhand-launch", a1[] = "--quiet";
    char* argv[] = {a0, a1, nullptr};
    int argc = 2;
    kind.clear();
    EXPECT_TRUE(takeRenderArgs(argc, argv, &kind, &dir, &error));
    EXPECT_EQ(argc, 2);
    EXPECT_TRUE(kind.empty());
  }
}

}  // namespace
}  // namespace godhand
