// Lab configuration (services/common/lab_config.h): the shipped labs load; every validation
// rule rejects a bad file with "FILE:LINE: field: reason" pointing at the offending line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "common/lab_config.h"

namespace godhand {
namespace {

namespace fs = std::filesystem;

const std::string kDeploy = GODHAND_DEPLOY_DIR;
const std::string kData = std::string(GODHAND_TEST_DATA_DIR) + "/lab";
const std::string kLabDir = kDeploy + "/lab";

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// 1-based number of the line marked "# <- error", 0 if none.
int markedLine(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n)
    if (line.find("# <- error") != std::string::npos) return n;
  return 0;
}

std::string loadError(const std::string& path) {
  try {
    loadLab(path);
  } catch (const LabError& e) {
    return e.what();
  }
  ADD_FAILURE() << path << ": loaded, expected a LabError";
  return "";
}

std::string parseError(const std::string& text) {
  try {
    parseLab(text, "inline.pbtxt", kLabDir);
  } catch (const LabError& e) {
    return e.what();
  }
  ADD_FAILURE() << "parsed, expected a LabError:\n" << text;
  return "";
}

bool isAbsoluteFile(const std::string& p) { return fs::path(p).is_absolute() && fs::is_regular_file(p); }

// ---- the shipped labs ----

TEST(LabConfig, ShippedLocalLabLoads) {
  const std::string path = kLabDir + "/local.pbtxt";
  const LabConfig lab = loadLab(path);
  EXPECT_EQ(lab.file, fs::path(path).lexically_normal().string());
  EXPECT_TRUE(fs::path(lab.file).is_absolute());
  EXPECT_EQ(lab.name, "local");
  EXPECT_EQ(lab.domain_id, 0);
  EXPECT_DOUBLE_EQ(lab.deadline_s, 10.0);
  EXPECT_DOUBLE_EQ(lab.stale_after_s, 0.25);
  EXPECT_TRUE(isAbsoluteFile(lab.profiles)) << lab.profiles;
  EXPECT_EQ(fs::path(lab.profiles).filename(), "godhand-local.xml");
  EXPECT_TRUE(isAbsoluteFile(lab.scene)) << lab.scene;
  EXPECT_EQ(lab.scene, fs::path(kDeploy + "/scenes/default.pbtxt").lexically_normal().string());
  EXPECT_TRUE(isAbsoluteFile(lab.recording)) << lab.recording;
  EXPECT_EQ(fs::path(lab.recording).filename(), "confidence2-49fps.json");

  ASSERT_EQ(lab.clusters.size(), 2u);
  EXPECT_EQ(lab.clusters[0].index, 0);
  EXPECT_EQ(lab.clusters[0].name, "right");
  EXPECT_EQ(lab.clusters[0].side, "right");
  EXPECT_EQ(lab.clusters[0].model, fs::path(kDeploy + "/models/hand16_right.pbtxt").lexically_normal().string());
  EXPECT_EQ(lab.clusters[1].index, 1);
  EXPECT_EQ(lab.clusters[1].name, "left");
  EXPECT_EQ(lab.clusters[1].side, "left");
  EXPECT_EQ(lab.clusters[1].model, fs::path(kDeploy + "/models/hand16_left.pbtxt").lexically_normal().string());
  for (const LabCluster& c : lab.clusters) EXPECT_TRUE(isAbsoluteFile(c.model)) << c.model;

  ASSERT_EQ(lab.services.size(), 5u);
  const char* names[] = {"ingest", "scene", "resolver", "solver/right", "solver/left"};
  const pb::Service::Kind kinds[] = {pb::Service::INGEST, pb::Service::SCENE, pb::Service::RESOLVER, pb::Service::SOLVER,
                                     pb::Service::SOLVER};
  for (size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(lab.services[i].name, names[i]);
    EXPECT_EQ(lab.services[i].kind, kinds[i]);
    EXPECT_TRUE(lab.services[i].local) << names[i];
    EXPECT_TRUE(lab.services[i].args.empty());
  }
  EXPECT_EQ(lab.services[3].cluster, "right");
  EXPECT_EQ(lab.services[4].cluster, "left");

  ASSERT_NE(lab.cluster("left"), nullptr);
  EXPECT_EQ(lab.cluster("left")->index, 1);
  EXPECT_EQ(lab.cluster("tool"), nullptr);
  ASSERT_NE(lab.service("solver/left"), nullptr);
  EXPECT_EQ(lab.service("solver/left")->cluster, "left");
  EXPECT_EQ(lab.service("solver/tool"), nullptr);
}

TEST(LabConfig, ShippedTwoMachineExampleLoads) {
  const LabConfig lab = loadLab(kLabDir + "/two-machines.pbtxt");
  EXPECT_EQ(lab.name, "two-machines");
  EXPECT_EQ(lab.domain_id, 17);
  EXPECT_DOUBLE_EQ(lab.deadline_s, 20.0);
  EXPECT_DOUBLE_EQ(lab.stale_after_s, 0.1);
  EXPECT_TRUE(isAbsoluteFile(lab.profiles));
  ASSERT_EQ(lab.clusters.size(), 2u);
  EXPECT_EQ(lab.clusters[0].name, "right");
  ASSERT_EQ(lab.services.size(), 5u);
  EXPECT_EQ(lab.services[0].host, "tracker-pc");
  EXPECT_EQ(lab.services[1].host, "compute-pc");
  EXPECT_EQ(lab.services[0].local, isLocalHost("tracker-pc"));
}

TEST(LabConfig, MinimalLabDefaults) {
  const LabConfig lab = loadLab(kData + "/minimal.pbtxt");
  EXPECT_EQ(lab.name, "minimal");  // no name: the file's stem
  EXPECT_EQ(lab.profiles, "");     // empty: the DDS layer's default
  EXPECT_EQ(lab.recording, "");
  EXPECT_EQ(lab.domain_id, 0);
  EXPECT_DOUBLE_EQ(lab.deadline_s, 10.0);
  EXPECT_DOUBLE_EQ(lab.stale_after_s, 0.25);
  ASSERT_EQ(lab.clusters.size(), 1u);
  EXPECT_EQ(lab.clusters[0].name, "solo");
  EXPECT_EQ(lab.clusters[0].tracker_body, 1);  // a tool cluster, driven by tracked body 1
  EXPECT_EQ(lab.clusters[0].side, "");
  ASSERT_EQ(lab.services.size(), 4u);
  EXPECT_EQ(lab.services[3].name, "solver/solo");
}

// ---- bad files: one rule each, the offending line marked "# <- error" ----

struct BadFile {
  const char* file;
  const char* field;   ///< expected right after "FILE:LINE: " (or, for syntax errors, in the message)
  const char* reason;  ///< expected somewhere in the message
};

class BadLabFile : public ::testing::TestWithParam<BadFile> {};

TEST_P(BadLabFile, ReportsFileLineAndField) {
  const BadFile& b = GetParam();
  const std::string path = kData + "/" + b.file;
  const std::string text = readFile(path);
  ASSERT_FALSE(text.empty()) << path;
  const int line = b.file == std::string("no_clusters.pbtxt") ? 1 : markedLine(text);
  ASSERT_GT(line, 0) << path << " has no '# <- error' line";
  const std::string msg = loadError(path);
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  if (b.file == std::string("syntax_error.pbtxt")) {
    EXPECT_EQ(msg.rfind(path + ":" + std::to_string(line) + ":", 0), 0u) << msg;
    EXPECT_NE(msg.find(b.field), std::string::npos) << msg;
  } else {
    const std::string prefix = path + ":" + std::to_string(line) + ": " + b.field + ": ";
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << "expected prefix '" << prefix << "' in\n" << msg;
  }
  EXPECT_NE(msg.find(b.reason), std::string::npos) << "expected '" << b.reason << "' in\n" << msg;
}

const BadFile kBadFiles[] = {
    {"syntax_error.pbtxt", "modle", "no field named"},
    {"bad_domain.pbtxt", "domain_id", "233"},
    {"bad_cluster_name.pbtxt", "clusters[0].name", "\"Right Hand\""},
    {"duplicate_cluster.pbtxt", "clusters[1].name", "duplicate cluster name \"hand\""},
    {"bad_side.pbtxt", "clusters[0].side", "\"both\""},
    {"bad_tool_side.pbtxt", "clusters[0].side", "a tool cluster (tracker_body 1) is driven by that body"},
    {"bad_tracker_body.pbtxt", "clusters[0].tracker_body", "0 to 1000, got -2"},
    {"missing_model.pbtxt", "clusters[0].model", "no_such_hand.pbtxt\" (/"},
    {"missing_scene.pbtxt", "scene", "does not exist"},
    {"missing_profiles.pbtxt", "profiles", "no_such_profiles.xml"},
    {"missing_recording.pbtxt", "recording", "no_such_recording.json"},
    {"no_clusters.pbtxt", "clusters", "at least one cluster"},
    {"duplicate_ingest.pbtxt", "services[2].kind", "second INGEST service (the first is services[0])"},
    {"missing_resolver.pbtxt", "services", "no RESOLVER service"},
    {"missing_solver.pbtxt", "clusters[1]", "no SOLVER service for cluster \"left\""},
    {"unknown_cluster.pbtxt", "services[4].cluster", "no cluster named \"left\" (clusters: right)"},
    {"unspecified_kind.pbtxt", "services[4].kind", "needs a kind"},
    {"cluster_on_scene.pbtxt", "services[1].cluster", "SOLVER services only"},
    {"bad_deadline.pbtxt", "deadline_s", "got -1"},
    {"bad_stale_after.pbtxt", "stale_after_s", "got inf"},
};

INSTANTIATE_TEST_SUITE_P(LabConfig, BadLabFile, ::testing::ValuesIn(kBadFiles),
                         [](const ::testing::TestParamInfo<BadFile>& param_info) {
                           std::string n = fs::path(param_info.param.file).stem().string();
                           for (char& c : n)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return n;
                         });

TEST(LabConfig, UnreadableFile) {
  const std::string missing = kData + "/no_such_lab.pbtxt";
  const std::string msg = loadError(missing);
  EXPECT_EQ(msg.rfind(missing + ":0: cannot read lab file", 0), 0u) << msg;
  EXPECT_NE(msg.find("No such file or directory"), std::string::npos) << msg;

  const std::string dir_msg = loadError(kData);
  EXPECT_EQ(dir_msg.rfind(kData + ":0: cannot read lab file", 0), 0u) << dir_msg;
  EXPECT_NE(dir_msg.find("directory"), std::string::npos) << dir_msg;
}

// ---- inline variations (parseLab, paths relative to deploy/lab) ----

/// A valid lab around `clusters` + `services` (+ `extra` top-level lines first).
std::string lab(const std::string& extra, const std::string& clusters, const std::string& services) {
  return "scene: \"../scenes/default.pbtxt\"\n" + extra + clusters + services;
}
const std::string kOneCluster = "clusters { name: \"solo\" model: \"../models/tool1.pbtxt\" side: \"right\" }\n";
const std::string kServices =
    "services { kind: INGEST }\nservices { kind: SCENE }\nservices { kind: RESOLVER }\nservices { kind: SOLVER cluster: \"solo\" }\n";

/// Expects the error of `text` to start "inline.pbtxt:LINE: FIELD: " and contain `reason`.
void expectError(const std::string& text, int line, const std::string& field, const std::string& reason) {
  const std::string msg = parseError(text);
  const std::string prefix = "inline.pbtxt:" + std::to_string(line) + ": " + field + ": ";
  EXPECT_EQ(msg.rfind(prefix, 0), 0u) << "expected prefix '" << prefix << "' in\n" << msg;
  EXPECT_NE(msg.find(reason), std::string::npos) << "expected '" << reason << "' in\n" << msg;
}

TEST(LabConfig, InlineValidLabResolvesPaths) {
  const LabConfig l = parseLab(lab("recording: \"" + kDeploy + "/recordings/pinch.json\"\n", kOneCluster, kServices),
                               "inline.pbtxt", kLabDir);
  EXPECT_EQ(l.file, "inline.pbtxt");
  EXPECT_EQ(l.name, "inline");
  EXPECT_EQ(l.scene, fs::path(kDeploy + "/scenes/default.pbtxt").lexically_normal().string());
  EXPECT_EQ(l.recording, fs::path(kDeploy + "/recordings/pinch.json").lexically_normal().string());
  EXPECT_EQ(l.clusters[0].model, fs::path(kDeploy + "/models/tool1.pbtxt").lexically_normal().string());
}

TEST(LabConfig, TrackerCalibration) {
  const LabConfig l = parseLab(lab("tracker { pose: \"0,0,1,0,0,90\" units: \"cm\" up: \"y\" hand_map: \"0:left\" "
                                   "tracking_volume_m: 3 max_speed_mps: 12 }\n",
                                   kOneCluster, kServices),
                               "inline.pbtxt", kLabDir);
  EXPECT_TRUE(l.tracker.any());
  EXPECT_EQ(l.tracker.pose, "0,0,1,0,0,90");
  EXPECT_EQ(l.tracker.units, "cm");
  EXPECT_EQ(l.tracker.up, "y");
  EXPECT_EQ(l.tracker.hand_map, "0:left");
  EXPECT_EQ(l.tracker.volume_m, 3.0);
  EXPECT_EQ(l.tracker.max_speed, 12.0);
  EXPECT_FALSE(parseLab(lab("", kOneCluster, kServices), "inline.pbtxt", kLabDir).tracker.any());
  const std::string msg = parseError(lab("tracker { max_speed_mps: -1 }\n", kOneCluster, kServices));
  EXPECT_NE(msg.find("tracker.max_speed_mps"), std::string::npos) << msg;
  EXPECT_NE(msg.find("got -1"), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
}

TEST(LabConfig, DomainIdRange) {
  EXPECT_EQ(parseLab(lab("domain_id: 232\n", kOneCluster, kServices), "inline.pbtxt", kLabDir).domain_id, 232);
  expectError(lab("domain_id: 4000000000\n", kOneCluster, kServices), 2, "domain_id", "0..232");
}

TEST(LabConfig, ClusterNames) {
  const auto withName = [](const std::string& name) {
    return lab("", "clusters { name: \"" + name + "\" model: \"../models/tool1.pbtxt\" side: \"left\" }\n",
               "services { kind: INGEST }\nservices { kind: SCENE }\nservices { kind: RESOLVER }\n"
               "services { kind: SOLVER cluster: \"" +
                   name + "\" }\n");
  };
  const std::string ok31(31, 'a');
  EXPECT_EQ(parseLab(withName(ok31), "inline.pbtxt", kLabDir).clusters[0].name, ok31);
  EXPECT_EQ(parseLab(withName("tool_2-b9"), "inline.pbtxt", kLabDir).clusters[0].name, "tool_2-b9");
  expectError(withName(std::string(32, 'a')), 2, "clusters[0].name", "1 to 31 characters");
  expectError(withName(""), 2, "clusters[0].name", "got \"\"");
  expectError(withName("Right"), 2, "clusters[0].name", "got \"Right\"");
  expectError(withName("a.b"), 2, "clusters[0].name", "got \"a.b\"");
}

TEST(LabConfig, ClusterFields) {
  expectError(lab("", "clusters {\n name: \"solo\"\n model: \"../models/tool1.pbtxt\"\n}\n", kServices), 2,
              "clusters[0].side", "got \"\"");
  expectError(lab("", "clusters {\n name: \"solo\"\n side: \"right\"\n}\n", kServices), 2, "clusters[0].model",
              "needs a hand model file");
  expectError(lab("", "clusters {\n name: \"solo\"\n model: \"../models\"\n side: \"right\"\n}\n", kServices), 4,
              "clusters[0].model", "is a directory");
  expectError(lab("", "clusters {\n name: \"solo\"\n model: \"/nonexistent/hand.pbtxt\"\n side: \"right\"\n}\n", kServices),
              4, "clusters[0].model", "\"/nonexistent/hand.pbtxt\" does not exist");
}

TEST(LabConfig, SceneRequired) {
  expectError(kOneCluster + kServices, 1, "scene", "needs a scene file");
  expectError("name: \"x\"\nscene: \"../scenes\"\n" + kOneCluster + kServices, 2, "scene", "is a directory");
}

TEST(LabConfig, ServiceRules) {
  const std::string base = "services { kind: INGEST }\nservices { kind: SCENE }\nservices { kind: RESOLVER }\n";
  // A SOLVER needs a cluster.
  expectError(lab("", kOneCluster, base + "services {\n kind: SOLVER\n}\n"), 6, "services[3].cluster", "needs the name of its cluster");
  // Two SOLVERs for one cluster.
  expectError(lab("", kOneCluster, kServices + "services {\n kind: SOLVER\n cluster: \"solo\"\n}\n"), 9, "services[4].cluster",
              "second SOLVER for cluster \"solo\" (the first is services[3])");
  // Missing INGEST / SCENE (reported at the first service).
  expectError(lab("", kOneCluster, "services { kind: SCENE }\nservices { kind: RESOLVER }\nservices { kind: SOLVER cluster: \"solo\" }\n"),
              3, "services", "no INGEST service");
  expectError(lab("", kOneCluster, "services { kind: INGEST }\nservices { kind: RESOLVER }\nservices { kind: SOLVER cluster: \"solo\" }\n"),
              3, "services", "no SCENE service");
  // No services at all.
  expectError(lab("", kOneCluster, ""), 1, "services", "no INGEST service");
  // Explicit KIND_UNSPECIFIED.
  expectError(lab("", kOneCluster, kServices + "services {\n kind: KIND_UNSPECIFIED\n}\n"), 8, "services[4].kind", "needs a kind");
  // cluster on INGEST / RESOLVER.
  expectError(lab("", kOneCluster, "services {\n kind: INGEST\n cluster: \"solo\"\n}\n"), 5, "services[0].cluster",
              "SOLVER services only (this one is INGEST)");
  // Duplicate SCENE and RESOLVER.
  expectError(lab("", kOneCluster, kServices + "services { kind: RESOLVER }\n"), 7, "services[4].kind", "second RESOLVER");
  expectError(lab("", kOneCluster, kServices + "services { kind: SCENE }\n"), 7, "services[4].kind", "second SCENE");
}

TEST(LabConfig, UnknownNumericKindRejected) {
  // proto3 text format accepts an unknown enum number; the lab does not.
  const std::string msg = parseError(lab("", kOneCluster, kServices + "services {\n kind: 9\n}\n"));
  EXPECT_EQ(msg.rfind("inline.pbtxt:8:", 0), 0u) << msg;
}

TEST(LabConfig, DeadlinesMustBeFinitePositive) {
  for (const char* bad : {"-0.5", "nan", "inf", "-inf", "3600.5", "1e300"}) {
    expectError(lab(std::string("deadline_s: ") + bad + "\n", kOneCluster, kServices), 2, "deadline_s", "seconds in (0, 3600]");
    expectError(lab(std::string("stale_after_s: ") + bad + "\n", kOneCluster, kServices), 2, "stale_after_s",
                "seconds in (0, 3600]");
  }
  const LabConfig zero = parseLab(lab("deadline_s: 0\nstale_after_s: 0\n", kOneCluster, kServices), "inline.pbtxt", kLabDir);
  EXPECT_DOUBLE_EQ(zero.deadline_s, 10.0);
  EXPECT_DOUBLE_EQ(zero.stale_after_s, 0.25);
  const LabConfig set = parseLab(lab("deadline_s: 2.5\nstale_after_s: 0.05\n", kOneCluster, kServices), "inline.pbtxt", kLabDir);
  EXPECT_DOUBLE_EQ(set.deadline_s, 2.5);
  EXPECT_DOUBLE_EQ(set.stale_after_s, 0.05);
}

TEST(LabConfig, SyntaxErrorHasLineAndColumn) {
  const std::string msg = parseError("scene: \"../scenes/default.pbtxt\"\nclusters {\n  name: \"solo\"\n");
  EXPECT_EQ(msg.rfind("inline.pbtxt:4:", 0), 0u) << msg;  // unexpected end of input after line 3
  const std::string dup = parseError("name: \"a\"\nname: \"b\"\n");
  EXPECT_EQ(dup.rfind("inline.pbtxt:2:", 0), 0u) << dup;
  EXPECT_NE(dup.find("name"), std::string::npos) << dup;
}

TEST(LabConfig, HostsAndArgs) {
  char host[256] = {};
  ASSERT_EQ(gethostname(host, sizeof host - 1), 0);
  const std::string services =
      "services { kind: INGEST host: \"\" }\n"
      "services { kind: SCENE host: \"LOCALHOST\" }\n"
      "services { kind: RESOLVER host: \"127.0.0.1\" args: \"--rate\" args: \"90\" args: \"--name=two words\" }\n"
      "services { kind: SOLVER cluster: \"solo\" host: \"" +
      std::string(host) + "\" }\n";
  const LabConfig l = parseLab(lab("", kOneCluster, services), "inline.pbtxt", kLabDir);
  for (const LabService& s : l.services) EXPECT_TRUE(s.local) << s.name << " host '" << s.host << "'";
  EXPECT_EQ(l.services[2].args, (std::vector<std::string>{"--rate", "90", "--name=two words"}));

  const LabConfig remote = parseLab(
      lab("", kOneCluster,
          "services { kind: INGEST host: \"tracker-pc.invalid\" }\nservices { kind: SCENE }\nservices { kind: RESOLVER }\n"
          "services { kind: SOLVER cluster: \"solo\" }\n"),
      "inline.pbtxt", kLabDir);
  EXPECT_FALSE(remote.services[0].local);
  EXPECT_EQ(remote.services[0].host, "tracker-pc.invalid");
  EXPECT_TRUE(remote.services[1].local);

  EXPECT_TRUE(isLocalHost(""));
  EXPECT_TRUE(isLocalHost("localhost"));
  EXPECT_TRUE(isLocalHost("127.0.0.1"));
  EXPECT_TRUE(isLocalHost(host));
  EXPECT_FALSE(isLocalHost("tracker-pc.invalid"));
}

TEST(LabConfig, AtMostSixteenClustersAndArgsDoNotOverrideTheLaunchersOptions) {
  // 17 clusters: refused at load, before anything starts (the resolver merges at most 16).
  std::string clusters, solvers;
  for (int i = 0; i < 17; ++i) {
    clusters += "clusters { name: \"c" + std::to_string(i) + "\" model: \"../models/hand16_right.pbtxt\" side: \"right\" }\n";
    solvers += "services { kind: SOLVER cluster: \"c" + std::to_string(i) + "\" }\n";
  }
  const std::string base = "services { kind: INGEST }\nservices { kind: SCENE }\nservices { kind: RESOLVER }\n";
  const std::string many = parseError(lab("", clusters, base + solvers));
  EXPECT_NE(many.find("17 clusters; a lab has at most 16"), std::string::npos) << many;
  // 16 load.
  const size_t cut = clusters.rfind("clusters {"), cut_s = solvers.rfind("services {");
  EXPECT_NO_THROW(parseLab(lab("", clusters.substr(0, cut), base + solvers.substr(0, cut_s)), "inline.pbtxt", kLabDir));
  // A service's args may not set what godhand-launch sets from the lab (a second --domain took a
  // scene into another domain, where the launcher waited for it in vain).
  for (const char* opt : {"--domain", "--lab", "--profiles", "--lockstep", "--scene=x.pbtxt", "--frame-rate"}) {
    const std::string msg = parseError(
        lab("", kOneCluster,
            "services { kind: INGEST }\nservices { kind: SCENE args: \"" + std::string(opt) +
                "\" args: \"7\" }\nservices { kind: RESOLVER }\nservices { kind: SOLVER cluster: \"solo\" }\n"));
    EXPECT_NE(msg.find("services[1].args"), std::string::npos) << msg;
    EXPECT_NE(msg.find("args may not set"), std::string::npos) << msg;
  }
}

TEST(LabConfig, ServiceNames) {
  EXPECT_EQ(labServiceName(pb::Service::INGEST, ""), "ingest");
  EXPECT_EQ(labServiceName(pb::Service::SCENE, ""), "scene");
  EXPECT_EQ(labServiceName(pb::Service::RESOLVER, ""), "resolver");
  EXPECT_EQ(labServiceName(pb::Service::SOLVER, "left"), "solver/left");
  EXPECT_EQ(labServiceName(pb::Service::KIND_UNSPECIFIED, ""), "");
}

}  // namespace
}  // namespace godhand
