// Lab hosts (Lab.hosts, discovery_server; services/common/lab_config.h): a lab spread over
// machines names them, every service's host must be one of them, `godhand-launch --host NAME`
// selects one (its services, its profiles) and rejects an unknown name naming the known ones.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "common/lab_config.h"

namespace godhand {
namespace {

namespace fs = std::filesystem;

const std::string kLabDir = std::string(GODHAND_DEPLOY_DIR) + "/lab";

const std::string kHead =
    "scene: \"../scenes/default.pbtxt\"\n"
    "clusters { name: \"solo\" model: \"../models/tool1.pbtxt\" side: \"right\" }\n";
const std::string kHosts =
    "hosts { name: \"tracker\" address: \"10.231.0.1\" }\n"
    "hosts { name: \"compute\" address: \"10.231.0.2\" profiles: \"../dds/godhand-multihost.xml\" }\n";
const std::string kServices =
    "services { kind: INGEST host: \"tracker\" }\n"
    "services { kind: SCENE host: \"compute\" }\n"
    "services { kind: RESOLVER host: \"compute\" }\n"
    "services { kind: SOLVER cluster: \"solo\" host: \"compute\" }\n";

std::string parseError(const std::string& text) {
  try {
    parseLab(text, "inline.pbtxt", kLabDir);
  } catch (const LabError& e) {
    return e.what();
  }
  ADD_FAILURE() << "parsed, expected a LabError:\n" << text;
  return "";
}

void expectError(const std::string& text, const std::string& prefix, const std::string& reason) {
  const std::string msg = parseError(text);
  EXPECT_EQ(msg.rfind(prefix, 0), 0u) << "expected prefix '" << prefix << "' in\n" << msg;
  EXPECT_NE(msg.find(reason), std::string::npos) << "expected '" << reason << "' in\n" << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
}

TEST(LabHosts, HostsParsedWithProfilesResolved) {
  const LabConfig lab = parseLab(kHead + kHosts + "discovery_server: \"compute\"\n" + kServices, "inline.pbtxt", kLabDir);
  ASSERT_EQ(lab.hosts.size(), 2u);
  EXPECT_EQ(lab.hosts[0].name, "tracker");
  EXPECT_EQ(lab.hosts[0].address, "10.231.0.1");
  EXPECT_EQ(lab.hosts[0].profiles, "");
  EXPECT_EQ(lab.hosts[1].profiles, fs::path(kLabDir + "/../dds/godhand-multihost.xml").lexically_normal().string());
  EXPECT_EQ(lab.discovery_server, "compute");
  EXPECT_EQ(lab.discovery_port, 11811);
  ASSERT_NE(lab.host("compute"), nullptr);
  EXPECT_EQ(lab.host("compute")->address, "10.231.0.2");
  EXPECT_EQ(lab.host("render"), nullptr);
  const LabConfig port = parseLab(kHead + kHosts + "discovery_server: \"tracker\" discovery_port: 11900\n" + kServices,
                                  "inline.pbtxt", kLabDir);
  EXPECT_EQ(port.discovery_port, 11900);
}

TEST(LabHosts, BadHostsRejectedWithLine) {
  expectError(kHead + "hosts { name: \"a b\" address: \"10.0.0.1\" }\n" + kServices, "inline.pbtxt:3: hosts[0].name: ",
              "1 to 63 characters");
  expectError(kHead + "hosts { name: \"\" address: \"10.0.0.1\" }\n" + kServices, "inline.pbtxt:3: hosts[0].name: ", "got \"\"");
  expectError(kHead + "hosts {\n name: \"a\"\n address: \"10.0.0.300\"\n}\n" + kServices, "inline.pbtxt:5: hosts[0].address: ",
              "IPv4 address");
  expectError(kHead + "hosts { name: \"a\" }\n" + kServices, "inline.pbtxt:3: hosts[0]", "IPv4 address");
  expectError(kHead + kHosts + "hosts { name: \"tracker\" address: \"10.231.0.9\" }\n" + kServices, "inline.pbtxt:5: hosts[2].name: ",
              "duplicate host name \"tracker\" (also hosts[0])");
  expectError(kHead + kHosts + "hosts { name: \"render\" address: \"10.231.0.2\" }\n" + kServices,
              "inline.pbtxt:5: hosts[2].address: ", "also that of hosts[1]");
  expectError(kHead + "hosts { name: \"a\" address: \"10.0.0.1\" profiles: \"/nonexistent/p.xml\" }\n" + kServices,
              "inline.pbtxt:3: hosts[0].profiles: ", "/nonexistent/p.xml");
  expectError(kHead + kHosts + "discovery_server: \"render\"\n" + kServices, "inline.pbtxt:5: discovery_server: ",
              "no host named \"render\" (hosts: tracker, compute)");
  expectError(kHead + "discovery_server: \"render\"\n" + kServices, "inline.pbtxt:3: discovery_server: ", "hosts: none");
  expectError(kHead + kHosts + "discovery_server: \"tracker\" discovery_port: 70000\n" + kServices,
              "inline.pbtxt:5: discovery_port: ", "1..65535");
}

TEST(LabHosts, Security) {
  const LabConfig lab = parseLab(kHead + kHosts + "security: \"pki\"\n" + kServices, "inline.pbtxt", kLabDir);
  EXPECT_EQ(lab.security, fs::path(kLabDir + "/pki").lexically_normal().string());
  EXPECT_EQ(parseLab(kHead + kHosts + kServices, "inline.pbtxt", kLabDir).security, "");
  expectError(kHead + kHosts + "discovery_server: \"compute\"\nsecurity: \"/etc/pki\"\n" + kServices,
              "inline.pbtxt:6: security: ", "do not work together");
}

TEST(LabHosts, EveryServiceNamesAListedHost) {
  expectError(kHead + kHosts + "services { kind: INGEST host: \"render\" }\n", "inline.pbtxt:5: services[0].host: ",
              "no host named \"render\" (hosts: tracker, compute)");
  expectError(kHead + kHosts + "services { kind: INGEST }\n", "inline.pbtxt:5: services[0]", "needs the host of every service");
}

TEST(LabHosts, SelectHostTakesItsProfiles) {
  LabConfig lab = parseLab(kHead + "profiles: \"../dds/godhand-local.xml\"\n" + kHosts + kServices, "inline.pbtxt", kLabDir);
  const std::string lab_profiles = lab.profiles;
  selectHost(lab, "tracker");  // no profiles of its own: the lab's stay
  EXPECT_EQ(lab.profiles, lab_profiles);
  selectHost(lab, "compute");
  EXPECT_EQ(lab.profiles, lab.hosts[1].profiles);
  EXPECT_NE(lab.profiles, lab_profiles);
  try {
    selectHost(lab, "render");
    ADD_FAILURE() << "unknown host accepted";
  } catch (const LabError& e) {
    EXPECT_NE(std::string(e.what()).find("--host \"render\": no such host in the lab (hosts: tracker, compute)"), std::string::npos)
        << e.what();
  }
  std::vector<std::string> here;
  for (const LabService& s : lab.services)
    if (runsHere(s, "compute")) here.push_back(s.name);
  EXPECT_EQ(here, (std::vector<std::string>{"scene", "resolver", "solver/solo"}));
  here.clear();
  for (const LabService& s : lab.services)
    if (runsHere(s, "tracker")) here.push_back(s.name);
  EXPECT_EQ(here, (std::vector<std::string>{"ingest"}));
}

TEST(LabHosts, SelectHostWithoutHostsUsesServiceHosts) {
  LabConfig lab = parseLab(kHead +
                               "services { kind: INGEST host: \"tracker-pc\" }\nservices { kind: SCENE }\n"
                               "services { kind: RESOLVER }\nservices { kind: SOLVER cluster: \"solo\" host: \"tracker-pc\" }\n",
                           "inline.pbtxt", kLabDir);
  selectHost(lab, "tracker-pc");
  EXPECT_TRUE(runsHere(lab.services[0], "tracker-pc"));
  EXPECT_FALSE(runsHere(lab.services[1], "tracker-pc"));  // "" is this machine, not tracker-pc
  EXPECT_TRUE(runsHere(lab.services[1], ""));              // without --host: the local ones
  EXPECT_FALSE(runsHere(lab.services[0], ""));
  EXPECT_THROW(selectHost(lab, "compute-pc"), LabError);
  EXPECT_THROW(selectHost(lab, ""), LabError);
}

TEST(LabHosts, ShippedTwoMachineExampleNamesItsHosts) {
  const LabConfig lab = loadLab(kLabDir + "/two-machines.pbtxt");
  ASSERT_EQ(lab.hosts.size(), 2u);
  EXPECT_EQ(lab.hosts[0].name, "tracker-pc");
  EXPECT_EQ(lab.hosts[1].name, "compute-pc");
  EXPECT_EQ(lab.discovery_server, "compute-pc");
  for (const LabService& s : lab.services) EXPECT_NE(lab.host(s.host), nullptr) << s.name;
}

}  // namespace
}  // namespace godhand
