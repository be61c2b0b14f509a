// services/dds: the Fast DDS layer, with real participants (no mocks) on loopback only (every
// participant comes from deploy/dds/godhand-local.xml). Each test uses its own DDS domain in
// 201..223, which no other test uses (tests/CMakeLists.txt: the table of domains), so that tests
// run in parallel (ctest -j) never see each other; every wait has a deadline.
#include <dirent.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "dds/dds.h"
#include "dds/topics.h"

namespace {

namespace dds = godhand::dds;
namespace msg = godhand::msg;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

const std::string kLocal = std::string(GODHAND_DEPLOY_DIR) + "/dds/godhand-local.xml";
const std::string kMultihost = std::string(GODHAND_DEPLOY_DIR) + "/dds/godhand-multihost.xml";
const std::string kData = std::string(GODHAND_TEST_DATA_DIR) + "/dds/";
constexpr auto kMatchDeadline = 10s;  // discovery on loopback takes well under a second
constexpr auto kDataDeadline = 5s;
constexpr std::uint64_t kLossyFrames = 100;  // DdsLossRepair

dds::Options options(int domain, const std::string& name) {
  dds::Options o;
  o.domain = domain;
  o.profiles = kLocal;
  o.name = name;
  return o;
}

// Polls `done` until it is true or `timeout` passes.
template <class Pred>
bool waitFor(Pred done, Clock::duration timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  while (!done()) {
    if (Clock::now() >= deadline) return false;
    std::this_thread::sleep_for(5ms);
  }
  return true;
}

// Takes from `reader` until `count` samples arrived (appended to `out`) or the deadline passes.
template <class T>
bool takeN(dds::Participant& p, dds::Reader<T>& reader, std::size_t count, std::vector<T>* out,
           Clock::duration timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  T s;
  for (;;) {
    while (out->size() < count && reader.take(s)) out->push_back(s);
    if (out->size() >= count) return true;
    if (Clock::now() >= deadline) return false;
    p.waitForData(std::min(deadline, Clock::now() + 100ms));
  }
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

msg::Pose pose(double seed) {
  msg::Pose x;
  x.p() = {seed, -seed * 1e-3, std::nextafter(seed, 1e9)};
  x.q() = {std::sqrt(0.5), -std::sqrt(0.5) * seed, 1.0 / 3.0, -0.0};
  return x;
}

msg::HandState handState(std::uint32_t hand, std::uint64_t frame, std::size_t poses) {
  msg::HandState s;
  s.hand(hand);
  s.cluster(hand == 0 ? "right" : "left");
  s.stamp().frame(frame);
  s.stamp().source_time_ns(1700000000123456789LL + static_cast<long long>(frame));
  s.stamp().publish_time_ns(-1);
  s.scene_frame(frame + 7);
  s.scene_step(frame + 0x100000000ull);
  s.tracked(true);
  s.stale(frame % 2 == 0);
  s.toc(0.1 + 1e-17);
  for (std::size_t i = 0; i < poses; ++i) s.poses().push_back(pose(static_cast<double>(i) * 0.1 + 1.0 / 7.0));
  msg::BodyShape shape;
  shape.type(1);
  shape.radius(0.0095);
  shape.half_length(0.02);
  s.shapes().assign(poses, shape);
  s.kkt(std::numeric_limits<double>::denorm_min());
  s.joint_gap(5e-324);
  s.force_n(std::numeric_limits<double>::max());
  s.solver_times().solve_us(12.5);
  s.ccd_us(1e300);
  s.merge_us(-1e-300);
  return s;
}

// The Fast DDS shared-memory entries (/dev/shm/fastrtps_*) process `pid` has mapped or open:
// certainly its own (other processes on the machine create theirs concurrently).
std::set<std::string> shmEntriesOf(const std::string& pid) {
  std::set<std::string> out;
  const std::string prefix = "/dev/shm/fastrtps_";
  auto add = [&](const std::string& path) {
    if (path.rfind(prefix, 0) == 0) out.insert(path.substr(std::string("/dev/shm/").size()));
  };
  std::ifstream maps("/proc/" + pid + "/maps");
  for (std::string line; std::getline(maps, line);) {
    const std::size_t at = line.find(prefix);
    if (at != std::string::npos) add(line.substr(at, line.find(' ', at) - at));
  }
  const std::string fd_dir = "/proc/" + pid + "/fd";
  if (DIR* d = opendir(fd_dir.c_str())) {
    while (dirent* e = readdir(d)) {
      char target[512];
      const ssize_t n = readlink((fd_dir + "/" + e->d_name).c_str(), target, sizeof target - 1);
      if (n > 0) add(std::string(target, static_cast<std::size_t>(n)));
    }
    closedir(d);
  }
  return out;
}

bool shmEntryExists(const std::string& name) { return access(("/dev/shm/" + name).c_str(), F_OK) == 0; }

// Waits (up to `timeout`) for the entries to disappear; returns those still there.
std::string shmEntriesLeft(const std::set<std::string>& entries, Clock::duration timeout) {
  std::string left;
  waitFor(
      [&] {
        left.clear();
        for (const auto& n : entries)
          if (shmEntryExists(n)) left += n + " ";
        return left.empty();
      },
      timeout);
  return left;
}

// A scene at the wire's bound (idl/godhand.idl: 10,000 objects): every object's SceneState
// (112 bytes each, 1.1 MB) and a SceneDescription with the longest id and mesh path (3.3 MB).
constexpr std::size_t kWireObjects = 10000;
msg::SceneState bigSceneState() {
  msg::SceneState s;
  s.step(7);
  s.objects().resize(kWireObjects);
  for (std::size_t i = 0; i < kWireObjects; ++i) {
    s.objects()[i].index(static_cast<std::int32_t>(i));
    s.objects()[i].pose() = pose(1.0 / static_cast<double>(i + 3));
  }
  return s;
}
void expectBigSceneState(const msg::SceneState& x) {
  const msg::SceneState sent = bigSceneState();
  ASSERT_EQ(x.objects().size(), kWireObjects);
  for (std::size_t i = 0; i < kWireObjects; i += 997) {
    EXPECT_EQ(x.objects()[i].index(), static_cast<std::int32_t>(i));
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(sameBits(x.objects()[i].pose().p()[k], sent.objects()[i].pose().p()[k]));
  }
  EXPECT_EQ(x.objects().back().index(), static_cast<std::int32_t>(kWireObjects - 1));
}
msg::SceneDescription bigSceneDescription() {
  msg::SceneDescription d;
  d.objects().resize(kWireObjects);
  for (std::size_t i = 0; i < kWireObjects; ++i) {
    msg::ObjectDescription& o = d.objects()[i];
    o.index(static_cast<std::int32_t>(i));
    o.id(std::string(64 - std::to_string(i).size(), 'i') + std::to_string(i));
    o.mesh(std::string(160, 'm'));
  }
  return d;
}
void expectBigSceneDescription(const msg::SceneDescription& x) {
  ASSERT_EQ(x.objects().size(), kWireObjects);
  EXPECT_EQ(x.objects()[0].mesh().to_string(), std::string(160, 'm'));
  EXPECT_EQ(x.objects().back().id().to_string(), std::string(60, 'i') + "9999");
}

// ---------------------------------------------------------------------------------------------
// Child processes for the cross-process tests: the test binary runs itself again with
// GODHAND_DDS_TEST_CHILD=<role>:<domain>; the role runs before gtest starts, then exits.
constexpr const char* kChildEnv = "GODHAND_DDS_TEST_CHILD";
constexpr auto kChildDeadline = 30s;

pid_t spawnChild(const std::string& role, int domain, const std::vector<std::string>& extra_env = {}) {
  char exe[4096];
  const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n <= 0) return -1;
  exe[n] = '\0';
  std::vector<std::string> env_strings;
  for (char** e = environ; *e != nullptr; ++e)
    if (std::string(*e).rfind(std::string(kChildEnv) + "=", 0) != 0) env_strings.push_back(*e);
  env_strings.push_back(std::string(kChildEnv) + "=" + role + ":" + std::to_string(domain));
  env_strings.insert(env_strings.end(), extra_env.begin(), extra_env.end());
  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  char* argv[] = {exe, nullptr};
  pid_t pid = -1;
  if (posix_spawn(&pid, exe, nullptr, nullptr, argv, envp.data()) != 0) return -1;
  return pid;
}

// The child's exit code, or -1 if it had to be killed at the deadline (or did not exit normally).
// A child killed here (e.g. hung inside Fast DDS) leaves its shared-memory entries behind: the
// ones it held are noted before the kill and removed once it is gone (its own, not the host's
// port segments, which other participants share).
int waitChild(pid_t pid, Clock::duration timeout) {
  int status = 0;
  if (waitFor([&] { return waitpid(pid, &status, WNOHANG) == pid; }, timeout))
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  const std::set<std::string> own = shmEntriesOf(std::to_string(pid));
  kill(pid, SIGKILL);
  waitpid(pid, &status, 0);
  for (const std::string& n : own)
    if (n.find("fastrtps_port") == std::string::npos) std::remove(("/dev/shm/" + n).c_str());
  return -1;
}

// Children not yet waited for when a test leaves early (a failed ASSERT): killed and reaped at
// the end of the scope, so that none stays on the test's domain. waited() after waitChild.
struct Children {
  std::vector<pid_t> running;
  void add(pid_t pid) { if (pid > 0) running.push_back(pid); }
  void waited(pid_t pid) { running.erase(std::remove(running.begin(), running.end(), pid), running.end()); }
  ~Children() {
    for (pid_t pid : running) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

// DdsTeardown's writers and readers, one topic each.
constexpr int kTeardownWriters = 60;
constexpr int kTeardownSamples = 512;
std::string teardownTopic(int k) { return "test/teardown/" + std::to_string(k); }
volatile sig_atomic_t g_continued = 0;  // "stalled-reader": set by SIGCONT

// "state-writer": writes one HandState (handState(1, 77, 16)) on godhand.state, then stays until
// a reader has matched and gone again. "status-reader": waits for the ServiceStatus of
// "test/parent". "env-default": with $FASTRTPS_DEFAULT_PROFILES_FILE naming godhand-local.xml
// (Fast DDS loads it itself), participants from Options::profiles "" and from the same file by
// name both work, and a writer and reader of theirs match. Exit 0 on success, 3 on a deadline.
int runChild(const std::string& role, int domain) {
  const Clock::time_point deadline = Clock::now() + kChildDeadline;
  if (role == "env-default") {
    dds::Options by_env;
    by_env.domain = domain;
    dds::Participant a(by_env);
    dds::Participant b(options(domain, "test/child-by-name"));
    if (a.profilesFile() != kLocal || a.info().builtin_transports) return 7;
    dds::Writer<msg::HandState> w(a, dds::topic::kHandState, dds::profile::kState);
    dds::Reader<msg::HandState> r(b, dds::topic::kHandState, dds::profile::kState);
    return waitFor([&] { return w.matched() == 1 && r.matched() == 1; }, deadline - Clock::now()) ? 0 : 3;
  }
  if (role == "limited-reader") {  // DdsLosses: profiles from $GODHAND_DDS_TEST_PROFILES
    const char* file = std::getenv("GODHAND_DDS_TEST_PROFILES");
    if (file == nullptr) return 5;
    dds::Options oa = options(domain, "test/writer"), ob = options(domain, "test/limited");
    oa.profiles = ob.profiles = file;
    dds::Participant a(oa);
    dds::Participant b(ob);
    dds::Writer<msg::HandTarget> w(a, dds::topic::kHandTarget, dds::profile::kLockStep);
    dds::Reader<msg::HandTarget> r(b, dds::topic::kHandTarget, "test.two_samples");
    // Both sides matched: a (volatile) reader the writer has not matched yet would not get the
    // samples written before (seen: 1 run in 40, neither a rejection nor the 4 samples).
    if (!waitFor([&] { return r.matched() == 1 && w.matched() == 1; }, kMatchDeadline)) return 3;
    msg::HandTarget t;
    t.targets().assign(16, pose(0.3));
    constexpr int kSent = 4;
    for (std::uint64_t f = 1; f <= kSent; ++f) {
      t.stamp().frame(f);
      if (!w.write(t)) return 4;
    }
    if (!waitFor([&] { return b.samplesRejected() > 0; }, kDataDeadline)) return 10;
    std::vector<msg::HandTarget> got;
    const bool all = takeN(b, r, kSent, &got, 2 * kDataDeadline);
    std::printf("[figure] a reader holding 2 samples, %d sent: %zu arrived within %lld s%s, %llu rejections, %llu lost\n",
                kSent, got.size(), static_cast<long long>(std::chrono::duration_cast<std::chrono::seconds>(2 * kDataDeadline).count()),
                all ? "" : " (the rest not re-sent in time)", static_cast<unsigned long long>(b.samplesRejected()),
                static_cast<unsigned long long>(b.samplesLost()));
    if (got.size() < 2) return 11;
    for (std::size_t i = 0; i < got.size(); ++i)
      if (got[i].stamp().frame() != i + 1) return 12;
    if (b.samplesLost() != 0) return 13;
    if (a.samplesLost() + a.samplesRejected() != 0) return 14;  // the writer's side has no reader
    // Per topic: all of them on the one topic read, none elsewhere.
    const std::vector<dds::Participant::TopicLosses> by_topic = b.lossesByTopic();
    // (The participant's total grows before the topic's, so the total read after is not less.)
    if (by_topic.size() != 1 || by_topic[0].topic != dds::topic::kHandTarget || by_topic[0].newest_only || by_topic[0].lost != 0 ||
        by_topic[0].rejected == 0 || by_topic[0].rejected > b.samplesRejected())
      return 15;
    if (!a.lossesByTopic().empty()) return 16;
    return 0;
  }
  if (role == "stalled-reader") {  // DdsTeardown: readers that the other side stops (SIGSTOP)
    const char* file = std::getenv("GODHAND_DDS_TEST_PROFILES");
    if (file == nullptr) return 5;
    dds::Options o = options(domain, "test/stalled-reader");
    o.profiles = file;
    signal(SIGCONT, [](int) { g_continued = 1; });
    dds::Participant p(o);
    std::vector<std::unique_ptr<dds::Reader<msg::HandTarget>>> readers;
    for (int k = 0; k < kTeardownWriters; ++k)
      readers.push_back(std::make_unique<dds::Reader<msg::HandTarget>>(p, teardownTopic(k), dds::profile::kLockStep));
    // Stopped by the writer's process once its writers have matched these readers; leaves (its
    // participant deleted) once the test continues it. (Whether it sees the writers leave then
    // depends on what its buffers kept while it was stopped.)
    return waitFor([] { return g_continued != 0; }, deadline - Clock::now()) ? 0 : 9;
  }
  if (role == "teardown-writer") {  // DdsTeardown: the stalled reader's pid in GODHAND_DDS_TEST_PEER
    const char* file = std::getenv("GODHAND_DDS_TEST_PROFILES");
    const char* peer = std::getenv("GODHAND_DDS_TEST_PEER");
    if (file == nullptr || peer == nullptr) return 5;
    dds::Options o = options(domain, "test/teardown-writer");
    o.profiles = file;
    dds::Participant p(o);
    std::vector<std::unique_ptr<dds::Writer<msg::HandTarget>>> writers;
    for (int k = 0; k < kTeardownWriters; ++k)
      writers.push_back(std::make_unique<dds::Writer<msg::HandTarget>>(p, teardownTopic(k), "test.fast_heartbeat"));
    if (!waitFor([&] {
          for (const auto& w : writers)
            if (w->matched() != 1) return false;
          return true;
        }, deadline - Clock::now()))
      return 3;
    // The only reader stops acknowledging: every sample stays unacknowledged, and each writer's
    // periodic heartbeat stays armed (every millisecond) until the writer is deleted.
    if (kill(static_cast<pid_t>(std::atol(peer)), SIGSTOP) != 0) return 8;
    msg::HandTarget t;
    t.targets().assign(16, pose(0.3));
    for (const auto& w : writers)
      for (std::uint64_t f = 1; f <= kTeardownSamples; ++f) {
        t.hand(static_cast<std::uint32_t>(f % 2));
        t.stamp().frame(f);
        if (!w->write(t)) return 4;
      }
    std::this_thread::sleep_for(20ms);
    const Clock::time_point t0 = Clock::now();
    writers.clear();  // (a hang here is what the test is about: killed at its deadline)
    std::printf("[figure] %d writers with %d unacknowledged samples each and a 1 ms heartbeat deleted in %.1f ms\n",
                kTeardownWriters, kTeardownSamples, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    return 0;
  }
  dds::Participant p(options(domain, "test/child-" + role));
  if (role == "lossy-periodic") {  // DdsLossRepair: a live state stream, one frame every 20 ms
    dds::Writer<msg::HandState> w(p, dds::topic::kHandState, dds::profile::kState);
    if (!waitFor([&] { return w.matched() == 1; }, kMatchDeadline)) return 3;
    msg::HandState s = handState(1, 0, 16);
    for (std::uint64_t f = 1; f <= kLossyFrames; ++f) {
      s.stamp().frame(f);
      if (!w.write(s)) return 4;
      std::this_thread::sleep_for(20ms);
    }
    // Stay until the reader has gone (it has the last frame by then, or its test failed).
    return waitFor([&] { return w.matched() == 0; }, deadline - Clock::now()) ? 0 : 3;
  }
  if (role == "lossy-echo") {  // DdsLossRepair: each HandTarget frame back as a HandState frame
    dds::Reader<msg::HandTarget> r(p, dds::topic::kHandTarget, dds::profile::kLockStep);
    dds::Writer<msg::HandState> w(p, dds::topic::kHandState, dds::profile::kLockStep);
    msg::HandTarget t;
    msg::HandState s = handState(1, 0, 16);
    std::uint64_t next = 1;
    while (next <= kLossyFrames && Clock::now() < deadline) {
      while (r.take(t)) {
        if (t.stamp().frame() != next) return 12;
        s.stamp().frame(next++);
        if (!w.write(s)) return 4;
      }
      p.waitForData(std::min(deadline, Clock::now() + 100ms));
    }
    if (next <= kLossyFrames) return 3;
    if (p.samplesLost() != 0) return 13;
    // Stay until the other side has gone (its reader acknowledged every frame before).
    return waitFor([&] { return w.matched() == 0 && r.matched() == 0; }, deadline - Clock::now()) ? 0 : 3;
  }
  if (role == "state-writer") {
    dds::Writer<msg::HandState> w(p, dds::topic::kHandState, dds::profile::kState);
    if (!w.write(handState(1, 77, 16))) return 4;
    if (!waitFor([&] { return w.matched() > 0; }, deadline - Clock::now())) return 3;
    return waitFor([&] { return w.matched() == 0; }, deadline - Clock::now()) ? 0 : 3;
  }
  if (role == "scene-writer") {  // the scene at the wire's bound, transient local, for a late reader
    dds::Writer<msg::SceneDescription> wd(p, dds::topic::kSceneDescription, dds::profile::kState);
    dds::Writer<msg::SceneState> ws(p, dds::topic::kSceneState, dds::profile::kState);
    if (!wd.write(bigSceneDescription()) || !ws.write(bigSceneState())) return 4;
    if (!waitFor([&] { return wd.matched() > 0 && ws.matched() > 0; }, deadline - Clock::now())) return 3;
    return waitFor([&] { return wd.matched() == 0 && ws.matched() == 0; }, deadline - Clock::now()) ? 0 : 3;
  }
  if (role == "status-reader") {
    dds::Reader<msg::ServiceStatus> r(p, dds::topic::kServiceStatus, dds::profile::kStatus);
    msg::ServiceStatus s;
    while (Clock::now() < deadline) {
      while (r.take(s))
        if (s.service().to_string() == "test/parent") return 0;
      p.waitForData(std::min(deadline, Clock::now() + 100ms));
    }
    return 3;
  }
  return 5;
}

void expectOneLine(const std::string& what) {
  EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  EXPECT_FALSE(what.empty());
}

// -------------------------------------------------------------------------------------------------

TEST(DdsProfiles, ShippedProfilesKeepEverythingOnLoopback) {
  dds::Participant p(options(202, "test/loopback"));
  EXPECT_EQ(p.domain(), 202);
  EXPECT_EQ(p.profilesFile(), kLocal);
  const dds::ParticipantInfo info = p.info();
  EXPECT_EQ(info.name, "test/loopback");
  EXPECT_FALSE(info.builtin_transports);
  EXPECT_EQ(info.transports, (std::vector<std::string>{"SHM", "UDPv4"}));
  EXPECT_EQ(info.udp_whitelist, (std::vector<std::string>{"127.0.0.1"}));
  EXPECT_EQ(info.initial_peers, (std::vector<std::string>{"127.0.0.1"}));
  EXPECT_EQ(info.unicast_locators, (std::vector<std::string>{"127.0.0.1", "127.0.0.1"}));
  EXPECT_FALSE(info.multicast_locators);
}

TEST(DdsProfiles, DefaultProfilesFileIsTheShippedOneUnlessTheEnvironmentNamesOne) {
  EXPECT_EQ(dds::Participant::resolveProfiles("/some/file.xml"), "/some/file.xml");
  const char* env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  if (env != nullptr && *env != '\0') {
    EXPECT_EQ(dds::Participant::resolveProfiles(""), env);
  } else {
    const std::string def = dds::Participant::resolveProfiles("");
    const std::string tail = "/deploy/dds/godhand-local.xml";
    ASSERT_GE(def.size(), tail.size());
    EXPECT_EQ(def.substr(def.size() - tail.size()), tail);
    dds::Options o;
    o.domain = 220;  // the default file is the shipped one: same loopback-only participant
    dds::Participant p(o);
    EXPECT_FALSE(p.info().builtin_transports);
    EXPECT_EQ(p.info().udp_whitelist, (std::vector<std::string>{"127.0.0.1"}));
  }
}

TEST(DdsProfiles, MultihostProfilesParse) {
  // Parsed exactly as Fast DDS parses it, without registering its profiles: this process uses
  // godhand-local.xml (same profile names), before and after the check.
  dds::Participant before(options(203, "test/multihost"));
  EXPECT_NO_THROW(dds::Participant::checkProfiles(kMultihost));
  EXPECT_NO_THROW(dds::Participant::checkProfiles(kMultihost));  // again: cached
  EXPECT_NO_THROW(dds::Participant::checkProfiles(kLocal));
  dds::Participant after(options(203, "test/multihost2"));
  EXPECT_THROW(dds::Participant::checkProfiles(kData + "bad.xml"), dds::DdsError);
  EXPECT_THROW(dds::Participant::checkProfiles(kData + "bad_element.xml"), dds::DdsError);
}

TEST(DdsQos, EachProfileGivesItsQos) {
  dds::Participant p(options(204, "test/qos"));
  struct Expect {
    const char* profile;
    dds::QosInfo qos;
  };
  const Expect expected[] = {
      // reliable, transient_local, keep_all, depth, max_samples (bounded memory), synchronous (writers)
      {dds::profile::kStreamLive, {false, false, false, 1, 64, true}},
      {dds::profile::kLockStep, {true, true, false, 256, 4096, true}},
      {dds::profile::kState, {true, true, false, 1, 64, true}},
      {dds::profile::kStatus, {true, true, false, 1, 256, true}},
  };
  for (const Expect& e : expected) {
    SCOPED_TRACE(e.profile);
    const std::string topic = std::string("test/qos/") + e.profile;
    dds::Writer<msg::HandState> w(p, topic, e.profile);
    dds::Reader<msg::HandState> r(p, topic, e.profile);
    for (const dds::QosInfo& got : {w.qos(), r.qos()}) {
      EXPECT_EQ(got.reliable, e.qos.reliable);
      EXPECT_EQ(got.transient_local, e.qos.transient_local);
      EXPECT_EQ(got.keep_all, e.qos.keep_all);
      EXPECT_EQ(got.depth, e.qos.depth);
      EXPECT_EQ(got.max_samples, e.qos.max_samples);
    }
    EXPECT_EQ(w.qos().synchronous, e.qos.synchronous);
    EXPECT_FALSE(r.qos().synchronous);
    EXPECT_EQ(w.topic(), topic);
  }
}

TEST(DdsRoundTrip, HandStateArrivesBitIdenticalAtAnotherParticipant) {
  dds::Participant a(options(205, "test/a"));
  dds::Participant b(options(205, "test/b"));
  dds::Writer<msg::HandState> w(a, dds::topic::kHandState, dds::profile::kState);
  dds::Reader<msg::HandState> r(b, dds::topic::kHandState, dds::profile::kState);
  ASSERT_TRUE(waitFor([&] { return w.matched() == 1 && r.matched() == 1; }, kMatchDeadline));

  const msg::HandState sent = handState(1, 42, 16);
  const Clock::time_point t0 = Clock::now();
  ASSERT_TRUE(w.write(sent));
  std::vector<msg::HandState> got;
  ASSERT_TRUE(takeN(b, r, 1, &got, kDataDeadline));
  EXPECT_LT(Clock::now() - t0, kDataDeadline);
  const msg::HandState& x = got[0];
  EXPECT_EQ(x.hand(), 1u);
  EXPECT_EQ(x.cluster().to_string(), "left");
  EXPECT_EQ(x.stamp().frame(), sent.stamp().frame());
  EXPECT_EQ(x.stamp().source_time_ns(), sent.stamp().source_time_ns());
  EXPECT_EQ(x.stamp().publish_time_ns(), -1);
  EXPECT_EQ(x.scene_frame(), sent.scene_frame());
  EXPECT_EQ(x.scene_step(), sent.scene_step());
  EXPECT_EQ(x.stale(), sent.stale());
  ASSERT_EQ(x.poses().size(), 16u);
  ASSERT_EQ(x.shapes().size(), 16u);
  for (std::size_t i = 0; i < 16; ++i) {
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(sameBits(x.poses()[i].p()[k], sent.poses()[i].p()[k])) << i << " p" << k;
    for (int k = 0; k < 4; ++k) EXPECT_TRUE(sameBits(x.poses()[i].q()[k], sent.poses()[i].q()[k])) << i << " q" << k;
    EXPECT_TRUE(sameBits(x.shapes()[i].radius(), sent.shapes()[i].radius()));
    EXPECT_TRUE(sameBits(x.shapes()[i].half_length(), sent.shapes()[i].half_length()));
  }
  for (auto [got_v, sent_v] : {std::pair{x.toc(), sent.toc()}, {x.kkt(), sent.kkt()}, {x.joint_gap(), sent.joint_gap()},
                               {x.force_n(), sent.force_n()}, {x.ccd_us(), sent.ccd_us()}, {x.merge_us(), sent.merge_us()},
                               {x.solver_times().solve_us(), sent.solver_times().solve_us()}})
    EXPECT_TRUE(sameBits(got_v, sent_v));
  EXPECT_EQ(w.written(), 1u);
  EXPECT_EQ(w.failed(), 0u);
  EXPECT_EQ(r.received(), 1u);
  msg::HandState none;
  EXPECT_FALSE(r.take(none));
}

TEST(DdsRoundTrip, EveryTopicTypeAtItsBoundsArrives) {
  // The largest samples (every sequence at its IDL bound, ContactForces ~40 KB) go through.
  dds::Participant a(options(206, "test/a"));
  dds::Participant b(options(206, "test/b"));

  msg::HandTarget target;
  target.hand(3);
  target.targets().assign(32, pose(0.5));
  target.driven().assign(32, true);
  msg::HandProposal proposal;
  proposal.x_old().assign(32, pose(0.25));
  proposal.x_new().assign(32, pose(0.75));
  proposal.loads().resize(256);
  proposal.loads()[255].lambda(3.5);
  msg::HandState state = handState(0, 1, 32);
  msg::ContactForces forces;
  forces.objects().resize(64);
  forces.contacts().resize(320);
  forces.contacts()[319].lambda(-2.0);
  forces.god_bodies().resize(96);
  msg::SceneState scene = bigSceneState();
  msg::SceneDescription description = bigSceneDescription();
  msg::ServiceStatus status;
  status.service("solver/right");
  status.state("running");
  status.source().run(42);
  status.source().rejected().resize(16);  // the ingest's source counts at their bounds
  status.source().rejected()[15].reason(std::string(64, 'r'));
  status.source().rejected()[15].count(92);

  auto roundTrip = [&](auto sample, const char* topic, const char* profile, auto check) {
    using T = decltype(sample);
    SCOPED_TRACE(topic);
    dds::Writer<T> w(a, topic, profile);
    dds::Reader<T> r(b, topic, profile);
    ASSERT_TRUE(waitFor([&] { return w.matched() == 1 && r.matched() == 1; }, kMatchDeadline));
    ASSERT_TRUE(w.write(sample));
    EXPECT_TRUE(w.waitForAcknowledgments(std::chrono::milliseconds(5000)));  // matched: acknowledged (at once when best-effort)
    std::vector<T> got;
    ASSERT_TRUE(takeN(b, r, 1, &got, kDataDeadline));
    check(got[0]);
  };
  roundTrip(target, dds::topic::kHandTarget, dds::profile::kStreamLive, [](const msg::HandTarget& x) {
    EXPECT_EQ(x.hand(), 3u);
    EXPECT_EQ(x.targets().size(), 32u);
    EXPECT_EQ(x.driven().size(), 32u);
  });
  roundTrip(proposal, dds::topic::kHandProposal, dds::profile::kLockStep, [](const msg::HandProposal& x) {
    EXPECT_EQ(x.x_new().size(), 32u);
    ASSERT_EQ(x.loads().size(), 256u);
    EXPECT_EQ(x.loads()[255].lambda(), 3.5);
  });
  roundTrip(state, dds::topic::kHandState, dds::profile::kState,
            [](const msg::HandState& x) { EXPECT_EQ(x.poses().size(), 32u); });
  roundTrip(forces, dds::topic::kContactForces, dds::profile::kLockStep, [](const msg::ContactForces& x) {
    EXPECT_EQ(x.objects().size(), 64u);
    ASSERT_EQ(x.contacts().size(), 320u);
    EXPECT_EQ(x.contacts()[319].lambda(), -2.0);
    EXPECT_EQ(x.god_bodies().size(), 96u);
  });
  roundTrip(scene, dds::topic::kSceneState, dds::profile::kState, [](const msg::SceneState& x) { expectBigSceneState(x); });
  roundTrip(description, dds::topic::kSceneDescription, dds::profile::kState,
            [](const msg::SceneDescription& x) { expectBigSceneDescription(x); });
  roundTrip(status, dds::topic::kServiceStatus, dds::profile::kStatus, [](const msg::ServiceStatus& x) {
    EXPECT_EQ(x.service().to_string(), "solver/right");
    EXPECT_EQ(x.state().to_string(), "running");
    EXPECT_EQ(x.source().run(), 42u);
    ASSERT_EQ(x.source().rejected().size(), 16u);
    EXPECT_EQ(x.source().rejected()[15].reason().to_string(), std::string(64, 'r'));
    EXPECT_EQ(x.source().rejected()[15].count(), 92u);
  });
}

TEST(DdsDurability, TransientLocalLateJoinerGetsTheLastSample) {
  dds::Participant a(options(207, "test/writer"));
  dds::Writer<msg::HandState> w(a, dds::topic::kHandState, dds::profile::kState);
  for (std::uint64_t f = 1; f <= 3; ++f) ASSERT_TRUE(w.write(handState(0, f, 16)));

  dds::Participant b(options(207, "test/late"));
  dds::Reader<msg::HandState> r(b, dds::topic::kHandState, dds::profile::kState);
  std::vector<msg::HandState> got;
  ASSERT_TRUE(takeN(b, r, 1, &got, kMatchDeadline + kDataDeadline));
  EXPECT_EQ(got[0].stamp().frame(), 3u);  // keep_last 1: the last one only
  std::this_thread::sleep_for(300ms);
  msg::HandState more;
  EXPECT_FALSE(r.take(more));
}

TEST(DdsDurability, KeyedLateReaderGetsOneSamplePerHand) {
  dds::Participant a(options(208, "test/resolver"));
  dds::Writer<msg::HandState> w(a, dds::topic::kHandState, dds::profile::kState);
  for (std::uint64_t f = 1; f <= 4; ++f) {
    ASSERT_TRUE(w.write(handState(0, f, 16)));
    ASSERT_TRUE(w.write(handState(1, f + 100, 6)));
  }
  dds::Participant b(options(208, "test/viewer"));
  dds::Reader<msg::HandState> r(b, dds::topic::kHandState, dds::profile::kState);
  std::vector<msg::HandState> got;
  ASSERT_TRUE(takeN(b, r, 2, &got, kMatchDeadline + kDataDeadline));
  std::this_thread::sleep_for(300ms);
  msg::HandState more;
  EXPECT_FALSE(r.take(more)) << "more than one sample per key";
  ASSERT_EQ(got.size(), 2u);
  std::sort(got.begin(), got.end(), [](const msg::HandState& x, const msg::HandState& y) { return x.hand() < y.hand(); });
  EXPECT_EQ(got[0].hand(), 0u);
  EXPECT_EQ(got[0].stamp().frame(), 4u);
  EXPECT_EQ(got[0].poses().size(), 16u);
  EXPECT_EQ(got[1].hand(), 1u);
  EXPECT_EQ(got[1].stamp().frame(), 104u);
  EXPECT_EQ(got[1].poses().size(), 6u);
}

TEST(DdsDurability, LockStepLateJoinerGetsTheHistoryInOrder) {
  dds::Participant a(options(209, "test/ingest"));
  dds::Writer<msg::HandTarget> w(a, dds::topic::kHandTarget, dds::profile::kLockStep);
  msg::HandTarget t;
  t.targets().assign(16, pose(0.3));
  for (std::uint64_t f = 1; f <= 300; ++f) {
    t.stamp().frame(f);
    ASSERT_TRUE(w.write(t));
  }
  dds::Participant b(options(209, "test/solver"));
  dds::Reader<msg::HandTarget> r(b, dds::topic::kHandTarget, dds::profile::kLockStep);
  std::vector<msg::HandTarget> got;
  ASSERT_TRUE(takeN(b, r, 256, &got, kMatchDeadline + kDataDeadline));
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].stamp().frame(), 45u + i);  // the last 256
}

TEST(DdsWrite, SequenceLongerThanItsBoundIsACountedFailure) {
  dds::Participant a(options(210, "test/a"));
  dds::Participant b(options(210, "test/b"));
  dds::Writer<msg::HandState> w(a, dds::topic::kHandState, dds::profile::kLockStep);
  dds::Reader<msg::HandState> r(b, dds::topic::kHandState, dds::profile::kLockStep);
  ASSERT_TRUE(waitFor([&] { return w.matched() == 1 && r.matched() == 1; }, kMatchDeadline));

  EXPECT_FALSE(w.write(handState(0, 1, 33)));  // poses: sequence<Pose, 32>
  EXPECT_EQ(w.failed(), 1u);
  EXPECT_EQ(w.written(), 0u);
  msg::HandState shapes_over = handState(0, 2, 32);
  shapes_over.shapes().resize(33);
  EXPECT_FALSE(w.write(shapes_over));
  EXPECT_EQ(w.failed(), 2u);
  EXPECT_TRUE(w.write(handState(0, 3, 32)));  // at the bound: fine
  EXPECT_EQ(w.written(), 1u);

  std::vector<msg::HandState> got;
  ASSERT_TRUE(takeN(b, r, 1, &got, kDataDeadline));
  EXPECT_EQ(got[0].stamp().frame(), 3u);  // nothing of the failed ones went out
  std::this_thread::sleep_for(200ms);
  msg::HandState more;
  EXPECT_FALSE(r.take(more));

  // Other types: far over the bound (the serializer would otherwise overflow the payload).
  dds::Writer<msg::ContactForces> f(a, dds::topic::kContactForces, dds::profile::kStreamLive);
  msg::ContactForces forces;
  forces.contacts().resize(321);
  EXPECT_FALSE(f.write(forces));
  forces.contacts().resize(5000);
  EXPECT_FALSE(f.write(forces));
  EXPECT_EQ(f.failed(), 2u);
  dds::Writer<msg::HandTarget> t(a, dds::topic::kHandTarget, dds::profile::kStreamLive);
  msg::HandTarget target;
  target.driven().assign(33, true);
  EXPECT_FALSE(t.write(target));
  EXPECT_EQ(t.failed(), 1u);
}

TEST(DdsErrors, BadInputsGiveOneLineErrorsNamingTheCause) {
  auto error = [](auto make) -> std::string {
    try {
      make();
    } catch (const dds::DdsError& e) {
      return e.what();
    } catch (const std::exception& e) {
      return std::string("not a DdsError: ") + e.what();
    }
    return "no error";
  };
  // Missing file.
  std::string e = error([] {
    dds::Options o = options(211, "test/err");
    o.profiles = "/nonexistent/godhand-profiles.xml";
    dds::Participant p(o);
  });
  expectOneLine(e);
  EXPECT_NE(e.find("/nonexistent/godhand-profiles.xml"), std::string::npos) << e;
  EXPECT_NE(e.find("does not exist"), std::string::npos) << e;
  // Malformed XML: the file and the line.
  e = error([] {
    dds::Options o = options(211, "test/err");
    o.profiles = kData + "bad.xml";
    dds::Participant p(o);
  });
  expectOneLine(e);
  EXPECT_NE(e.find("bad.xml"), std::string::npos) << e;
  EXPECT_NE(e.find("not valid XML (line 5): XML_ERROR_MISMATCHED_ELEMENT"), std::string::npos) << e;
  // Well-formed XML that Fast DDS rejects: its reason.
  e = error([] { dds::Participant::loadProfiles(kData + "bad_element.xml"); });
  expectOneLine(e);
  EXPECT_NE(e.find("bad_element.xml"), std::string::npos) << e;
  EXPECT_NE(e.find("reliabilty"), std::string::npos) << e;
  // Unknown participant profile.
  e = error([] {
    dds::Options o = options(211, "test/err");
    o.participant_profile = "no_such_participant";
    dds::Participant p(o);
  });
  expectOneLine(e);
  EXPECT_NE(e.find("'no_such_participant'"), std::string::npos) << e;
  EXPECT_NE(e.find("godhand-local.xml"), std::string::npos) << e;
  EXPECT_NE(e.find("godhand_participant"), std::string::npos) << e;  // what the file has
  // Unknown writer / reader profile.
  dds::Participant p(options(211, "test/err"));
  e = error([&] { dds::Writer<msg::HandState> w(p, dds::topic::kHandState, "godhand.no_such_profile"); });
  expectOneLine(e);
  EXPECT_NE(e.find("data_writer profile 'godhand.no_such_profile'"), std::string::npos) << e;
  EXPECT_NE(e.find("godhand.stream.live"), std::string::npos) << e;  // what the file has
  e = error([&] { dds::Reader<msg::HandState> r(p, dds::topic::kHandState, "godhand.no_such_profile"); });
  expectOneLine(e);
  EXPECT_NE(e.find("data_reader profile 'godhand.no_such_profile'"), std::string::npos) << e;
  // A topic name reused with another type.
  dds::Writer<msg::HandState> ok(p, dds::topic::kHandState, dds::profile::kState);
  e = error([&] { dds::Reader<msg::SceneState> r(p, dds::topic::kHandState, dds::profile::kState); });
  expectOneLine(e);
  EXPECT_NE(e.find("godhand/hand_state"), std::string::npos) << e;
  // Domain out of range.
  for (int domain : {999, 233, -1}) {
    e = error([domain] { dds::Participant bad(options(domain, "test/err")); });
    expectOneLine(e);
    EXPECT_NE(e.find("domain " + std::to_string(domain)), std::string::npos) << e;
  }
  // Another file declaring the same profile names as the one in use in this process.
  e = error([] { dds::Participant::loadProfiles(kData + "clash.xml"); });
  expectOneLine(e);
  EXPECT_NE(e.find("clash.xml"), std::string::npos) << e;
  EXPECT_NE(e.find("participant profile 'godhand_participant' is already registered"), std::string::npos) << e;
  // The error is remembered (the file is not half-loaded twice).
  EXPECT_EQ(error([] { dds::Participant::loadProfiles(kData + "clash.xml"); }), e);
  // Fault injection: a percentage out of range, from the option or the environment.
  e = error([] {
    dds::Options o = options(211, "test/err");
    o.drop_data_percent = 101;
    dds::Participant bad(o);
  });
  expectOneLine(e);
  EXPECT_NE(e.find("drop_data_percent 101"), std::string::npos) << e;
  for (const char* v : {"abc", "-3", "250", "5%"}) {
    setenv("GODHAND_DDS_DROP_DATA_PERCENT", v, 1);
    e = error([] { dds::Participant bad(options(211, "test/err")); });
    unsetenv("GODHAND_DDS_DROP_DATA_PERCENT");
    expectOneLine(e);
    EXPECT_NE(e.find(std::string("GODHAND_DDS_DROP_DATA_PERCENT='") + v + "' is not a percentage"), std::string::npos) << e;
  }
}

TEST(DdsTopics, WritersAndReadersShareTopicsWithinAParticipant) {
  dds::Participant p(options(212, "test/one"));
  dds::Writer<msg::HandState> w1(p, dds::topic::kHandState, dds::profile::kState);
  dds::Writer<msg::HandState> w2(p, dds::topic::kHandState, dds::profile::kState);
  dds::Reader<msg::HandState> r1(p, dds::topic::kHandState, dds::profile::kState);
  dds::Reader<msg::HandState> r2(p, dds::topic::kHandState, dds::profile::kState);
  ASSERT_TRUE(waitFor([&] { return w1.matched() == 2 && w2.matched() == 2 && r1.matched() == 2; }, kMatchDeadline));
  ASSERT_TRUE(w1.write(handState(0, 1, 4)));
  ASSERT_TRUE(w2.write(handState(1, 2, 4)));
  std::vector<msg::HandState> got1, got2;
  ASSERT_TRUE(takeN(p, r1, 2, &got1, kDataDeadline));
  ASSERT_TRUE(takeN(p, r2, 2, &got2, kDataDeadline));
  EXPECT_EQ(r1.received(), 2u);
  EXPECT_EQ(r2.received(), 2u);
}

// The shipped profiles file's text (kLocal).
std::string shippedProfiles() {
  std::ifstream in(kLocal);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// The shipped profiles with `extra` profiles added, in a file of a new temporary directory, both
// removed with this object. path() is "" where it could not be written.
class ProfilesFile {
 public:
  explicit ProfilesFile(const std::string& extra) {
    std::string xml = shippedProfiles();
    const std::size_t end = xml.rfind("</profiles>");
    char dir[] = "/tmp/godhand_dds_profiles_XXXXXX";
    if (end == std::string::npos || mkdtemp(dir) == nullptr) return;
    xml.insert(end, extra);
    dir_ = dir;
    path_ = dir_ + "/profiles.xml";
    std::ofstream(path_) << xml;
  }
  ~ProfilesFile() {
    if (dir_.empty()) return;
    std::remove(path_.c_str());
    rmdir(dir_.c_str());
  }
  ProfilesFile(const ProfilesFile&) = delete;
  ProfilesFile& operator=(const ProfilesFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string dir_, path_;
};

// What a participant's readers were told DDS gave up on (Participant::samplesLost / samplesRejected,
// printed on every service's exit line). A reader whose history holds 2 samples (KEEP_ALL) and is
// not read while a reliable writer sends 4: Fast DDS rejects what does not fit (counted), none is
// reported lost, and the two that fit arrive, in order. The writer sends the rejected ones again
// later (at a heartbeat, every 3 s by default), and they usually arrive too, but not always
// within 10 s: about 1 run in 100 here (with 10 samples, 2 more arrived per heartbeat: 4-7 of 10
// within 20 s). So that part is reported, not asserted. (The shipped profiles' readers are
// KEEP_LAST, which replaces the oldest sample instead of rejecting one.) In a child process (role
// "limited-reader"): its profiles file is not the shipped one, and a process has one.
TEST(DdsLosses, SamplesAReaderCannotHoldAreCountedAsRejected) {
  const std::string reader_profile = R"(
  <data_reader profile_name="test.two_samples">
    <topic>
      <historyQos><kind>KEEP_ALL</kind></historyQos>
      <resourceLimitsQos><max_samples>2</max_samples><max_instances>1</max_instances><max_samples_per_instance>2</max_samples_per_instance><allocated_samples>2</allocated_samples></resourceLimitsQos>
    </topic>
    <qos>
      <reliability><kind>RELIABLE</kind></reliability>
      <liveliness><kind>AUTOMATIC</kind><lease_duration><sec>1</sec><nanosec>0</nanosec></lease_duration></liveliness>
      <data_sharing><kind>OFF</kind></data_sharing>
    </qos>
  </data_reader>
)";
  const ProfilesFile profiles(reader_profile);
  ASSERT_FALSE(profiles.path().empty());
  const pid_t child = spawnChild("limited-reader", 219, {"GODHAND_DDS_TEST_PROFILES=" + profiles.path()});
  ASSERT_GT(child, 0);
  Children guard;
  guard.add(child);
  const int code = waitChild(child, kChildDeadline);
  guard.waited(child);
  EXPECT_EQ(code, 0) << "10: no rejection reported, 11: fewer than the 2 held arrived, 12: out of order, "
                        "13: a sample reported lost, 14: the writer's participant counted something, "
                        "15: the per-topic count is not the reader's topic's, 16: the writer's has a topic, "
                        "3: not matched, -1: killed at the deadline";
}

// Deleting a reliable writer whose samples a matched reader has not acknowledged. Fast DDS 2.9.1's
// ~StatefulWriter returns the history's samples to their pool one at a time (RTPSWriter::deinit,
// the writer's mutex taken and released for each) while they are still in the history, before
// it deletes the periodic heartbeat event. A heartbeat that fires in between walks a history
// whose first samples now have sequence number 0 (CacheChangePool::return_cache_to_pool) in
// StatefulWriter::add_gaps_for_holes_in_history_, counting up from 1 to a 0 it never reaches: the
// event thread spins for good and the deletion waits for the writer's mutex forever. Seen as an
// ingest stuck at exit in secured multi-host runs (security_three_namespaces: 50 ms heartbeats,
// readers that never acknowledge; 2 of 130 stressed runs, 1 of 3 CI runs), with these stacks.
// dds::Writer empties the history first (DataWriter::clear_history, under the writer's mutex).
// Here the race is made likely: 60 writers with 512 unacknowledged samples each and a heartbeat
// every millisecond, deleted one after the other. Without the emptying the writers' process hung
// in 3 of 3 runs (and in 2 of 3 with 30 writers of 300 samples). In child processes: the writers'
// one stops the readers' one (SIGSTOP) once matched, the test continues it.
TEST(DdsTeardown, WriterWithUnacknowledgedSamplesIsDeletedWhileItsHeartbeatRuns) {
  const std::string xml = shippedProfiles();
  // The shipped lock-step writer's profile, its heartbeat every millisecond instead of 50 ms.
  const std::size_t from = xml.find("<data_writer profile_name=\"godhand.lockstep\">");
  ASSERT_NE(from, std::string::npos);
  const std::size_t to = xml.find("</data_writer>", from);
  ASSERT_NE(to, std::string::npos);
  std::string writer_profile = xml.substr(from, to + std::strlen("</data_writer>") - from) + "\n";
  writer_profile.replace(writer_profile.find("godhand.lockstep"), std::strlen("godhand.lockstep"), "test.fast_heartbeat");
  const std::string period = "<heartbeatPeriod><sec>0</sec><nanosec>50000000</nanosec></heartbeatPeriod>";
  const std::size_t at = writer_profile.find(period);
  ASSERT_NE(at, std::string::npos) << "the shipped lock-step writer's heartbeat period is not 50 ms any more";
  writer_profile.replace(at, period.size(), "<heartbeatPeriod><sec>0</sec><nanosec>1000000</nanosec></heartbeatPeriod>");
  const ProfilesFile profiles(writer_profile);
  ASSERT_FALSE(profiles.path().empty());
  const std::string file = profiles.path();
  Children guard;
  const pid_t reader = spawnChild("stalled-reader", 201, {"GODHAND_DDS_TEST_PROFILES=" + file});
  ASSERT_GT(reader, 0);
  guard.add(reader);
  const pid_t writer = spawnChild("teardown-writer", 201,
                                  {"GODHAND_DDS_TEST_PROFILES=" + file, "GODHAND_DDS_TEST_PEER=" + std::to_string(reader)});
  ASSERT_GT(writer, 0);
  guard.add(writer);
  const int code = waitChild(writer, kChildDeadline);
  guard.waited(writer);
  kill(reader, SIGCONT);  // (stopped by the writer's process; it leaves once continued)
  const int reader_code = waitChild(reader, kChildDeadline);
  guard.waited(reader);
  EXPECT_EQ(code, 0) << "-1: the writers' process was killed at the deadline (stuck deleting a writer), "
                        "3: not matched, 4: a write failed, 8: could not stop the reader";
  EXPECT_EQ(reader_code, 0) << "9: never continued, -1: killed";
}

TEST(DdsWait, DeadlineWakeAndNoLostWakeUp) {
  dds::Participant p(options(213, "test/wait"));
  // Deadline: returns false, not before it.
  Clock::time_point t0 = Clock::now();
  EXPECT_FALSE(p.waitForData(t0 + 50ms));
  EXPECT_GE(Clock::now() - t0, 50ms);
  // wake() from another thread ends a long wait early.
  t0 = Clock::now();
  std::thread waker([&p] {
    std::this_thread::sleep_for(50ms);
    p.wake();
  });
  EXPECT_FALSE(p.waitForData(t0 + 10s));
  waker.join();
  EXPECT_LT(Clock::now() - t0, 5s);
  // wake() before the wait: the next wait returns at once.
  p.wake();
  t0 = Clock::now();
  EXPECT_FALSE(p.waitForData(t0 + 10s));
  EXPECT_LT(Clock::now() - t0, 5s);

  // Data that arrives before the wait is not lost.
  dds::Writer<msg::HandState> w(p, dds::topic::kHandState, dds::profile::kState);
  dds::Reader<msg::HandState> r(p, dds::topic::kHandState, dds::profile::kState);
  ASSERT_TRUE(waitFor([&] { return w.matched() == 1; }, kMatchDeadline));
  ASSERT_TRUE(w.write(handState(0, 1, 4)));
  msg::HandState s;
  ASSERT_TRUE(waitFor([&] { return r.take(s); }, kDataDeadline));  // arrived and taken, no wait yet
  t0 = Clock::now();
  EXPECT_TRUE(p.waitForData(t0 + 10s));  // ... the next wait still reports it
  EXPECT_LT(Clock::now() - t0, 5s);
  EXPECT_FALSE(p.waitForData(Clock::now() + 20ms));  // and only once
  // Data arriving while another thread waits wakes it.
  std::thread writer([&w] {
    std::this_thread::sleep_for(50ms);
    w.write(handState(0, 2, 4));
  });
  t0 = Clock::now();
  EXPECT_TRUE(p.waitForData(t0 + 10s));
  EXPECT_LT(Clock::now() - t0, 5s);
  writer.join();
  EXPECT_TRUE(waitFor([&] { return r.take(s); }, kDataDeadline));
  EXPECT_EQ(s.stamp().frame(), 2u);
}

TEST(DdsDiscovery, ManyParticipantsInOneProcessAllMatch) {
  constexpr int kParticipants = 7;
  std::vector<std::unique_ptr<dds::Participant>> ps;
  std::vector<std::unique_ptr<dds::Reader<msg::ServiceStatus>>> readers;
  for (int i = 0; i < kParticipants; ++i) {
    ps.push_back(std::make_unique<dds::Participant>(options(214, "test/p" + std::to_string(i))));
    readers.push_back(std::make_unique<dds::Reader<msg::ServiceStatus>>(*ps.back(), dds::topic::kServiceStatus,
                                                                         dds::profile::kStatus));
  }
  dds::Writer<msg::ServiceStatus> w(*ps.back(), dds::topic::kServiceStatus, dds::profile::kStatus);
  const bool all = waitFor(
      [&] {
        for (const auto& r : readers)
          if (r->matched() != 1) return false;
        return w.matched() == kParticipants;
      },
      kMatchDeadline);
  std::string counts;
  for (const auto& r : readers) counts += std::to_string(r->matched()) + " ";
  EXPECT_TRUE(all) << "writer matched " << w.matched() << ", readers: " << counts;
}

TEST(DdsLifetime, EndpointsOutlivingTheirParticipantAreInert) {
  auto p = std::make_unique<dds::Participant>(options(215, "test/short"));
  dds::Writer<msg::HandState> w(*p, dds::topic::kHandState, dds::profile::kState);
  dds::Reader<msg::HandState> r(*p, dds::topic::kHandState, dds::profile::kState);
  p.reset();  // deletes the writer's and reader's entities too
  EXPECT_FALSE(w.write(handState(0, 1, 4)));
  EXPECT_EQ(w.failed(), 1u);
  msg::HandState s;
  EXPECT_FALSE(r.take(s));
  EXPECT_EQ(w.matched(), 0);
  EXPECT_EQ(r.matched(), 0);
}

TEST(DdsShm, SegmentsOfDestroyedParticipantsAreReleased) {
  std::set<std::string> ours;
  {
    dds::Participant a(options(216, "test/shm-a"));
    dds::Participant b(options(216, "test/shm-b"));
    dds::Writer<msg::HandState> w(a, dds::topic::kHandState, dds::profile::kState);
    dds::Reader<msg::HandState> r(b, dds::topic::kHandState, dds::profile::kState);
    ASSERT_TRUE(waitFor([&] { return w.matched() == 1 && r.matched() == 1; }, kMatchDeadline));
    ASSERT_TRUE(w.write(handState(0, 1, 16)));
    std::vector<msg::HandState> got;
    ASSERT_TRUE(takeN(b, r, 1, &got, kDataDeadline));
    ours = shmEntriesOf("self");
  }
  EXPECT_FALSE(ours.empty()) << "the SHM transport of godhand-local.xml maps a segment per participant";
  const std::string left = shmEntriesLeft(ours, 2s);
  EXPECT_TRUE(left.empty()) << "left in /dev/shm: " << left;
}

TEST(DdsCrossProcess, HandStateFromAnotherProcessArrivesBitIdenticalAndItsShmIsReleased) {
  const pid_t child = spawnChild("state-writer", 217);
  ASSERT_GT(child, 0);
  Children guard;
  guard.add(child);
  std::set<std::string> child_shm;
  {
    dds::Participant p(options(217, "test/parent"));
    dds::Reader<msg::HandState> r(p, dds::topic::kHandState, dds::profile::kState);
    std::vector<msg::HandState> got;
    const bool arrived = takeN(p, r, 1, &got, kMatchDeadline + kDataDeadline);
    child_shm = shmEntriesOf(std::to_string(child));
    if (!arrived) {
      ADD_FAILURE() << "no HandState from the child process";
    } else {
      const msg::HandState sent = handState(1, 77, 16);
      const msg::HandState& x = got[0];
      EXPECT_EQ(x.hand(), 1u);
      EXPECT_EQ(x.stamp().frame(), 77u);
      ASSERT_EQ(x.poses().size(), 16u);
      for (std::size_t i = 0; i < 16; ++i) {
        for (int k = 0; k < 3; ++k) EXPECT_TRUE(sameBits(x.poses()[i].p()[k], sent.poses()[i].p()[k]));
        for (int k = 0; k < 4; ++k) EXPECT_TRUE(sameBits(x.poses()[i].q()[k], sent.poses()[i].q()[k]));
      }
      EXPECT_TRUE(sameBits(x.kkt(), sent.kkt()));
      EXPECT_TRUE(sameBits(x.merge_us(), sent.merge_us()));
    }
  }  // the reader leaves: the child sees it unmatch, and exits
  EXPECT_EQ(waitChild(child, kChildDeadline), 0);
  guard.waited(child);
  EXPECT_FALSE(child_shm.empty());
  const std::string left = shmEntriesLeft(child_shm, 2s);
  EXPECT_TRUE(left.empty()) << "left in /dev/shm by the child: " << left;
}

// Scenes of many objects through the distributed run (issue 14): a SceneDescription (3.3 MB) and
// a SceneState (1.1 MB) at the wire's bound of 10,000 objects cross processes (RTPS fragments of
// the shipped profile's transports) and reach a reader that joins after they were written.
TEST(DdsCrossProcess, ASceneOfTenThousandObjectsCrossesProcesses) {
  const pid_t child = spawnChild("scene-writer", 221);
  ASSERT_GT(child, 0);
  Children guard;
  guard.add(child);
  {
    dds::Participant p(options(221, "test/parent"));
    dds::Reader<msg::SceneDescription> rd(p, dds::topic::kSceneDescription, dds::profile::kState);
    dds::Reader<msg::SceneState> rs(p, dds::topic::kSceneState, dds::profile::kState);
    const Clock::time_point t0 = Clock::now();
    std::vector<msg::SceneDescription> d;
    std::vector<msg::SceneState> st;
    const bool got_d = takeN(p, rd, 1, &d, kMatchDeadline + kDataDeadline);
    const bool got_s = takeN(p, rs, 1, &st, kMatchDeadline + kDataDeadline);
    std::printf("[figure] 10,000-object SceneDescription and SceneState from another process in %.2f s\n",
                std::chrono::duration<double>(Clock::now() - t0).count());
    ASSERT_TRUE(got_d) << "no SceneDescription from the child process";
    ASSERT_TRUE(got_s) << "no SceneState from the child process";
    expectBigSceneDescription(d[0]);
    expectBigSceneState(st[0]);
  }  // the readers leave: the child sees them unmatch, and exits
  EXPECT_EQ(waitChild(child, kChildDeadline), 0);
  guard.waited(child);
}

TEST(DdsCrossProcess, ProfilesFileThatFastDdsLoadedItselfIsNotAClash) {
  const pid_t child = spawnChild("env-default", 219, {"FASTRTPS_DEFAULT_PROFILES_FILE=" + kLocal});
  ASSERT_GT(child, 0);
  EXPECT_EQ(waitChild(child, kChildDeadline), 0);
}

TEST(DdsCrossProcess, ManyProcessesOnOneHostAllMatch) {
  // More processes than Fast DDS's default initial-peer range reaches (4 participants per host:
  // with it, the 5th and later never discover each other; godhand-local.xml sets 32).
  constexpr int kChildren = 6;
  std::vector<pid_t> children;
  Children guard;
  for (int i = 0; i < kChildren; ++i) {
    children.push_back(spawnChild("status-reader", 218));
    guard.add(children.back());
    ASSERT_GT(children.back(), 0);
  }
  dds::Participant p(options(218, "test/parent"));
  dds::Writer<msg::ServiceStatus> w(p, dds::topic::kServiceStatus, dds::profile::kStatus);
  msg::ServiceStatus s;
  s.service("test/parent");
  s.state("running");
  ASSERT_TRUE(w.write(s));  // transient local: children that match later get it too
  int ok = 0;
  std::string codes;
  for (pid_t c : children) {
    const int code = waitChild(c, kChildDeadline);
    guard.waited(c);
    ok += code == 0;
    codes += std::to_string(code) + " ";
  }
  EXPECT_EQ(ok, kChildren) << "child exit codes (0 = got the sample, -1 = killed at the deadline): " << codes;
}

// Last in the file: runs a child role (see runChild) when the binary was started as one.
const bool kRanAsChild = [] {
  const char* role = std::getenv(kChildEnv);
  if (role == nullptr) return false;
  const std::string r = role;
  const std::size_t colon = r.find(':');
  int code = 6;
  try {
    code = runChild(r.substr(0, colon), std::atoi(r.substr(colon + 1).c_str()));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "test_dds child %s: %s\n", role, e.what());
  }
  std::exit(code);
}();

}  // namespace

// Lost packets in a lab network: lock-step frames go back and forth between two processes whose
// transports each drop a fifth of the DATA messages they send, each frame written only after
// the last one came back (as in lock-step, where nothing else is sent that could carry a
// heartbeat). Every frame arrives, in order, and nothing is reported lost: the repair is Fast
// DDS's (heartbeats, acknacks), timed by the lock-step profile. The figure line gives the
// round trips' waits. (Two processes: within one, Fast DDS delivers past the transport.)
TEST(DdsLossRepair, LockStepFramesUnderDataLossArriveWholeAndInOrder) {
  Children guard;
  pid_t child = -1;
  std::vector<double> waits_ms;
  double total_s = 0.0;
  {
    dds::Options o = options(223, "test/lossy-ingest");
    o.drop_data_percent = 20;
    dds::Participant a(o);
    dds::Writer<msg::HandTarget> w(a, dds::topic::kHandTarget, dds::profile::kLockStep);
    dds::Reader<msg::HandState> r(a, dds::topic::kHandState, dds::profile::kLockStep);
    child = spawnChild("lossy-echo", 223, {"GODHAND_DDS_DROP_DATA_PERCENT=20"});
    ASSERT_GT(child, 0);
    guard.add(child);
    ASSERT_TRUE(waitFor([&] { return w.matched() == 1 && r.matched() == 1; }, kMatchDeadline));
    msg::HandTarget t;
    t.targets().assign(16, pose(0.3));
    std::vector<msg::HandState> got;
    const Clock::time_point start = Clock::now();
    for (std::uint64_t f = 1; f <= kLossyFrames; ++f) {
      t.stamp().frame(f);
      ASSERT_TRUE(w.write(t));
      const Clock::time_point t0 = Clock::now();
      ASSERT_TRUE(takeN(a, r, f, &got, kDataDeadline)) << "frame " << f << " did not come back";
      waits_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    }
    total_s = std::chrono::duration<double>(Clock::now() - start).count();
    for (std::size_t i = 0; i < got.size(); ++i) ASSERT_EQ(got[i].stamp().frame(), i + 1);
    EXPECT_EQ(a.samplesLost(), 0u);
  }  // (the echo leaves once this side's endpoints are gone)
  const int code = waitChild(child, kChildDeadline);
  guard.waited(child);
  EXPECT_EQ(code, 0) << "12: out of order at the echo, 13: the echo counted a loss, 3: deadline, -1: killed";
  std::sort(waits_ms.begin(), waits_ms.end());
  std::printf("[figure] %llu lock-step round trips, 20 %% of DATA dropped each way: %.2f s, wait median %.1f ms, "
              "p90 %.1f ms, max %.1f ms\n",
              static_cast<unsigned long long>(kLossyFrames), total_s, waits_ms[waits_ms.size() / 2],
              waits_ms[waits_ms.size() * 9 / 10], waits_ms.back());
}

// A live state stream (KEEP_LAST 1, written every 20 ms whatever came back) from a process whose
// transport drops a fifth of its DATA: a lost sample is replaced by the next one, and the reader
// never stays behind it. The last frame arrives; the figure line gives the longest silence.
TEST(DdsLossRepair, LiveStateStreamUnderDataLossKeepsFlowingToTheLastFrame) {
  Children guard;
  pid_t child = -1;
  std::uint64_t last = 0, received = 0, lost = 0;
  double longest_ms = 0.0;
  {
    dds::Participant a(options(222, "test/state-reader"));
    dds::Reader<msg::HandState> r(a, dds::topic::kHandState, dds::profile::kState);
    child = spawnChild("lossy-periodic", 222, {"GODHAND_DDS_DROP_DATA_PERCENT=20"});
    ASSERT_GT(child, 0);
    guard.add(child);
    msg::HandState s;
    Clock::time_point t_last{};
    const Clock::time_point end = Clock::now() + kChildDeadline;
    while (Clock::now() < end && last < kLossyFrames) {
      while (r.take(s)) {
        const Clock::time_point now = Clock::now();
        if (received++ > 0) longest_ms = std::max(longest_ms, std::chrono::duration<double, std::milli>(now - t_last).count());
        t_last = now;
        EXPECT_GT(s.stamp().frame(), last);
        last = s.stamp().frame();
      }
      a.waitForData(std::min(end, Clock::now() + 100ms));
    }
    lost = a.samplesLost();
    // Every loss is on the state topic's newest-only reader (reliable, keep-last 1): a sample a
    // newer one replaced before its lost packet was resent, listed as such (Service::finish).
    std::uint64_t newest_only = 0;
    for (const dds::Participant::TopicLosses& t : a.lossesByTopic()) {
      EXPECT_EQ(t.topic, dds::topic::kHandState);
      EXPECT_TRUE(t.newest_only) << t.topic;
      newest_only += t.newest_only ? t.lost : 0;
    }
    EXPECT_EQ(newest_only, lost);
    EXPECT_GT(lost, 0u) << "20 % of 100 frames dropped and none superseded: the drop did not happen";
  }  // (the writer leaves once this reader is gone)
  EXPECT_EQ(last, kLossyFrames) << "the stream stopped short of its last frame";
  const int code = waitChild(child, kChildDeadline);
  guard.waited(child);
  EXPECT_EQ(code, 0) << "3: not matched or the reader stayed, 4: a write failed, -1: killed";
  std::printf("[figure] a live state stream of %llu frames every 20 ms, 20 %% of DATA dropped: %llu received, "
              "%llu superseded (reported lost on the newest-only reader), longest silence %.1f ms\n",
              static_cast<unsigned long long>(kLossyFrames), static_cast<unsigned long long>(received),
              static_cast<unsigned long long>(lost), longest_ms);
}
