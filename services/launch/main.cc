// godhand-launch: starts the lab's local services (deploy/lab/*.pbtxt), watches them, measures
// the run as a subscriber would see it, stops everything cleanly.
//
// While the run goes it prints, once a second, each stage's rate (from the services' heartbeats),
// the end-to-end latency (tracker sample taken by ingest -> HandState received here) and the
// penetration of the received hands against the scene; at the end a summary, a late-joiner check
// (a fresh participant must receive every cluster's HandState and the SceneDescription) and, with
// --json, a report in godhand-bench's format. In lock-step mode its result_hash equals
// godhand-bench's for the same recording and scene (clusters in the lab's order: right, left).
#include <signal.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <dirent.h>
#include <fstream>
#include <deque>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/cli.h"
#include "common/delivery.h"
#include "common/drill.h"
#include "common/files.h"
#include "common/frame_book.h"
#include "common/latency_figures.h"
#include "common/output_rate.h"
#include "common/watchdog.h"
#include "launch/report.h"
#include "common/lab_config.h"
#include "common/render.h"
#include "common/signals.h"
#include "common/source_counts.h"
#include "common/supervisor.h"
#include "dds/dds.h"
#include "dds/topics.h"
#include "godhand.h"
#include "math/stats.h"
#include "pipeline/collision_world.h"
#include "pipeline/run_metrics.h"
#include "pipeline/run_metrics_json.h"
#include "model/hand_model.h"
#include "runtime/lab_checks.h"
#include "runtime/convert.h"
#include "scene/scene_file.h"
#include "source/tracker_source.h"
#include "step/cluster_step.h"

using namespace godhand;
using Clock = std::chrono::steady_clock;

namespace {

constexpr const char* kSynopsis =
    "Starts the services of a lab configuration that run on this machine (ingest, scene, resolver, one\n"
    "solver per hand cluster), watches them, measures the run as a subscriber and stops them cleanly.\n"
    "Prints per-stage rates, end-to-end latency and penetration every second, then a summary.\n"
    "--lockstep --json OUT writes godhand-bench's report format; its result_hash equals godhand-bench's.";

double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::string exeDir() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return ".";
  buf[n] = 0;
  std::string s(buf);
  return s.substr(0, s.rfind('/'));
}

std::set<std::string> shmSegments() {
  std::set<std::string> out;
  if (DIR* d = opendir("/dev/shm")) {
    while (dirent* e = readdir(d)) {
      const std::string n = e->d_name;
      if (n.rfind("fastrtps_", 0) == 0 || n.rfind("sem.fastrtps_", 0) == 0) out.insert(n);
    }
    closedir(d);
  }
  return out;
}

bool unlocked(const std::string& name) {  // nobody holds the entry's lock: left behind
  const std::string el = "/dev/shm/" + name + "_el";
  const int fd = open(el.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) return false;
  const bool free = flock(fd, LOCK_EX | LOCK_NB) == 0;
  if (free) flock(fd, LOCK_UN);
  close(fd);
  return free;
}

// A shared-memory entry is left behind when nobody holds its lock any more (what `fastdds shm
// clean` removes): entries of other, live Fast DDS processes (parallel runs) are not counted.
std::vector<std::string> orphaned(const std::set<std::string>& before) {
  std::vector<std::string> out;
  for (const std::string& name : shmSegments()) {
    if (before.count(name) || name.size() < 3 || name.compare(name.size() - 3, 3, "_el") == 0) continue;
    if (unlocked(name)) out.push_back(name);
  }
  return out;
}

// The Fast DDS shared-memory entries a process has open or mapped (/proc/PID/fd, /proc/PID/maps):
// its own participant segments and the domain's port segments. Read while it runs, so that the
// entries a killed process leaves behind are known by name and removed by this launcher alone
// (never `fastdds shm clean`, which removes every lab's orphaned segments).
void noteShm(pid_t pid, std::set<std::string>* out) {
  const std::string fd_dir = "/proc/" + std::to_string(pid) + "/fd";
  if (DIR* d = opendir(fd_dir.c_str())) {
    while (dirent* e = readdir(d)) {
      char target[512];
      const ssize_t n = readlink((fd_dir + "/" + e->d_name).c_str(), target, sizeof target - 1);
      if (n <= 0) continue;
      target[n] = 0;
      const std::string t(target);
      if (t.rfind("/dev/shm/", 0) == 0 && t.find("fastrtps_") != std::string::npos) out->insert(t.substr(9));
    }
    closedir(d);
  }
  std::ifstream maps("/proc/" + std::to_string(pid) + "/maps");
  std::string line;
  while (std::getline(maps, line)) {
    const size_t at = line.find("/dev/shm/");
    if (at != std::string::npos && line.find("fastrtps_", at) != std::string::npos) {
      std::string n = line.substr(at + 9);
      const size_t sp = n.find(' ');
      if (sp != std::string::npos) n = n.substr(0, sp);
      out->insert(n);
    }
  }
}

// Removes the entries of a dead process that nobody else holds: its participant segments (not the
// domain's port segments, which other live participants of the host share) whose lock is free.
size_t removeOwnShm(const std::set<std::string>& names) {
  size_t n = 0;
  for (const std::string& name : names) {
    if (name.find("fastrtps_port") != std::string::npos) continue;
    if (name.size() > 3 && name.compare(name.size() - 3, 3, "_el") == 0) continue;
    if (!unlocked(name)) continue;
    if (unlink(("/dev/shm/" + name).c_str()) == 0) ++n;
    unlink(("/dev/shm/" + name + "_el").c_str());
  }
  return n;
}

std::string tail(const std::string& file, int lines) {
  std::ifstream in(file);
  std::vector<std::string> v;
  std::string l;
  while (std::getline(in, l)) v.push_back(l);
  std::string out;
  for (size_t i = v.size() > static_cast<size_t>(lines) ? v.size() - static_cast<size_t>(lines) : 0; i < v.size(); ++i)
    out += "    | " + v[i] + "\n";
  return out;
}

std::string fmt17(double x) {
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", x);
  return b;
}

struct FrameHands {
  std::vector<msg::HandState> states;
  std::vector<unsigned char> have;
};

// The lab's profiles file with default publisher and subscriber profiles that put every writer
// and reader in `partition` (Fast DDS takes a participant's default publisher / subscriber QoS,
// partitions included, from the default data_writer / data_reader profile). Written to DIR;
// returns its path. std::runtime_error when the file cannot be read or has no </profiles>.
std::string writePartitionProfiles(const std::string& profiles, const std::string& partition, const std::string& dir) {
  std::ifstream in(profiles);
  std::stringstream ss;
  ss << in.rdbuf();
  std::string xml = ss.str();
  if (!in) throw std::runtime_error(profiles + ": cannot read");
  const size_t end = xml.rfind("</profiles>");
  if (end == std::string::npos) throw std::runtime_error(profiles + ": no </profiles>");
  const std::string part = "<qos><partition><names><name>" + partition + "</name></names></partition></qos>";
  xml.insert(end, "  <!-- added by godhand-launch (partition option) -->\n  <data_writer profile_name=\"godhand.partition\" is_default_profile=\"true\">" +
                      part + "</data_writer>\n  <data_reader profile_name=\"godhand.partition\" is_default_profile=\"true\">" + part +
                      "</data_reader>\n");
  const std::string out_path = dir + "/profiles-" + partition + ".xml";
  std::ofstream out(out_path);
  out << xml;
  if (!out) throw std::runtime_error(out_path + ": cannot write");
  return out_path;
}

// Exit statuses (also in --help).
constexpr int kExitFailed = 1;    // the run failed, or --check failed
constexpr int kExitConfig = 2;    // bad configuration (Cli::fail)
constexpr int kExitStartup = 3;   // services did not come up
// s: how long a restarted scene waits for the scene state the resolver holds (godhand-scene
// --resume-wait; it stops at once when the resolver answers it holds nothing).
constexpr double kSceneResumeWait = 3.0;

std::string endedHow(const ChildStatus& c) {
  return c.exited ? "exit code " + std::to_string(c.exit_code) : "signal " + std::to_string(c.term_signal);
}

}  // namespace

int main(int argc, char** argv) {
  Cli cli("godhand-launch", kSynopsis);
  std::string lab_file = std::string(GODHAND_DEPLOY_DIR) + "/lab/local.pbtxt";
  std::string recording, scene_file, json_out, bin_dir = exeDir(), log_dir, solver = "exact", source_uri;
  std::vector<std::string> kill_specs;
  int domain = -1, frames = 0, physics_hz = 240;
  bool lockstep = false, quiet = false, check = false, restart = false, no_physics = false;
  double speed = 1.0, restart_delay = 0.5, deadline = 0.0, start_timeout = 60.0, loss_budget = 0.05, silent_after = 1.2,
         duration = 0.0;
  cli.option("--lab", &lab_file, "FILE", "lab configuration");
  std::string host_name;  // --host: that lab host's services (and profiles) instead of this machine's
  cli.option("--host", &host_name, "NAME", "start the services of the lab's host NAME, with its profiles (default: this machine's)");
  cli.option("--domain", &domain, "N", "DDS domain id 0..232; -1 = the lab's");
  std::string partition;
  cli.option("--partition", &partition, "NAME",
             "this launch's DDS partition: its services and monitor only match each other, not another lab on the domain "
             "(subscribers must use the same partition; default: none, every lab on the domain matches)");
  cli.flag("--lockstep", &lockstep, "lock-step: deterministic, every stage waits for each frame's inputs");
  cli.option("--recording", &recording, "FILE", "tracker recording (default: the lab's)");
  cli.option("--source", &source_uri, "URI", "tracker source for the ingest (godhand-ingest --source), instead of the lab's recording");
  cli.option("--duration", &duration, "S", "passed to the ingest: it stops after S seconds, a recording too (then the frames expected are those it published; 0: the ingest's default)");
  double live_rate = 0.0;
  cli.option("--frame-rate", &live_rate, "HZ", "the source's frame rate (default: the recording's; a live source: the lab recording's)");
  cli.option("--scene", &scene_file, "FILE", "scene file (default: the lab's)");
  cli.option("--frames", &frames, "N", "replay only the first N frames (0: all)");
  cli.option("--json", &json_out, "OUT", "write the report (godhand-bench's format plus latency, delivery, ...) to OUT");
  cli.option("--solver", &solver, "exact|pgs", "NNLS solver of the hand solvers");
  cli.option("--physics-hz", &physics_hz, "HZ", "Bullet's fixed step rate");
  cli.flag("--no-physics", &no_physics, "no Bullet: dynamic objects stay put");
  cli.option("--speed", &speed, "X", "live replay speed factor");
  cli.option("--deadline", &deadline, "S", "lock-step input deadline of every stage; 0 = the lab's");
  cli.option("--start-timeout", &start_timeout, "S", "how long the services may take to come up");
  cli.option("--bin-dir", &bin_dir, "DIR", "where the godhand-* executables are (default: next to this one)");
  cli.option("--log-dir", &log_dir, "DIR", "keep the service logs here (default: a fresh directory under /tmp, removed after a clean run)");
  cli.flag("--restart", &restart, "live: restart a service that dies or goes silent (after --restart-delay)");
  cli.option("--restart-delay", &restart_delay, "S", "delay before a restart");
  cli.option("--silent-after", &silent_after, "S", "watchdog: a service without a heartbeat for S seconds is dead (heartbeats every 0.5 s)");
  cli.multi("--kill", &kill_specs, "SERVICE@WHEN",
            "fault drill: SIGKILL SERVICE, then restart it; WHEN = S or Ss (seconds after the replay's first frame) "
            "or fN (at tracker frame N), e.g. scene@2, resolver@f120, ingest@1.5s");
  cli.option("--loss-budget", &loss_budget, "F", "--check (live): lost frames (and frames this launcher did not observe) allowed per cluster, as a fraction of the expected frames");
  cli.flag("--check", &check,
           "exit 1 unless penetration <= margin, joint gap <= 1e-6 m, no solver failure, lost frames within --loss-budget "
           "(lock-step: none lost, none stale), every service running at the end, the late joiner served, every drill done, no other lab on the domain");
  cli.flag("--quiet", &quiet, "no per-second lines");
  cli.epilog("exit status: 0 ok; 1 the run or its --check failed; 2 bad configuration; 3 services did not come up.");
  // --render systemd OUTDIR: two values, so taken out of argv before the parser (listed for --help)
  std::string render_kind, render_dir, render_error, render_help;
  cli.option("--render", &render_help, "systemd OUTDIR", "write per-host systemd units, environment files and profiles of the lab to OUTDIR, start nothing");
  if (!takeRenderArgs(argc, argv, &render_kind, &render_dir, &render_error)) cli.fail(render_error);
  cli.parse(argc, argv);
  if (frames < 0) cli.fail("--frames must be >= 0");
  if (!(speed >= 0.01 && speed <= 1000.0)) cli.fail("--speed must be in [0.01, 1000]");
  if (!(restart_delay >= 0.0 && restart_delay < 60.0)) cli.fail("--restart-delay must be in [0, 60)");
  if (!(silent_after >= 0.6 && silent_after <= 60.0)) cli.fail("--silent-after must be in [0.6, 60] s (heartbeats come every 0.5 s)");
  if (!(start_timeout > 0.0 && start_timeout <= 3600.0)) cli.fail("--start-timeout must be in (0, 3600] s");
  if (!(deadline >= 0.0 && deadline <= 3600.0)) cli.fail("--deadline must be in [0, 3600] s");
  if (!(loss_budget >= 0.0 && loss_budget <= 1.0)) cli.fail("--loss-budget must be in [0, 1]");
  if (!(duration >= 0.0 && duration <= 86400.0)) cli.fail("--duration must be in [0, 86400] s");
  if (!(live_rate >= 0.0 && live_rate <= 20000.0)) cli.fail("--frame-rate must be in (0, 20000] Hz");
  if (solver != "exact" && solver != "pgs") cli.fail("--solver must be exact or pgs");
  if (physics_hz < 10 || physics_hz > 100000) cli.fail("--physics-hz must be in [10, 100000]");
  if (domain < -1 || domain > 232) cli.fail("--domain must be in 0..232");
  if (!source_uri.empty() && !recording.empty()) cli.fail("--source and --recording: give one");
  if (!json_out.empty())  // before the run, not after it
    if (const std::string why = unwritableReason(json_out); !why.empty()) cli.fail("--json " + json_out + ": cannot write: " + why);
  if (!partition.empty() && (partition.size() > 64 || partition.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_.-") != std::string::npos))
    cli.fail("--partition must be 1 to 64 characters of [A-Za-z0-9_.-]");
  std::vector<Drill> drills;
  for (const std::string& k : kill_specs) {
    try {
      drills.push_back(parseDrill(k));
    } catch (const std::exception& e) {
      cli.fail(e.what());
    }
  }
  if (lockstep && !drills.empty()) cli.fail("--kill: fault drills are for live runs (a lock-step run stops at a missing stage)");
  installStopHandlers();

  LabConfig lab;
  try {
    lab = loadLab(lab_file);
    if (!host_name.empty()) selectHost(lab, host_name);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  if (domain >= 0) lab.domain_id = domain;
  if (!render_kind.empty()) return renderCommand(lab, render_kind, render_dir, bin_dir + "/godhand-launch", std::string(GODHAND_DEPLOY_DIR) + "/dds");
  if (!recording.empty()) lab.recording = recording;
  const std::string lab_recording = lab.recording;  // the lab's own (before --recording / --source)
  if (!source_uri.empty()) lab.recording = source_uri;
  if (!scene_file.empty()) lab.scene = scene_file;
  if (lab.recording.empty()) cli.fail("no recording: give --recording or --source, or set one in " + lab.file);
  for (const Drill& d : drills) {
    const LabService* s = lab.service(d.service);
    if (!s) {
      std::string names;
      for (const LabService& ls : lab.services) names += (names.empty() ? "" : ", ") + ls.name;
      cli.fail("--kill '" + d.spec + "': no service '" + d.service + "' in the lab (services: " + names + ")");
    }
    if (!runsHere(*s, host_name)) cli.fail("--kill '" + d.spec + "': " + d.service + " runs on " + s->host + ", not started here");
  }

  // The monitor's inputs: the source (frame count, rate) and the scene (penetration).
  double rate = 0.0;
  std::int64_t n_frames = 0;  // < 0: a live source (frames expected = frames published)
  Scene scene;
  try {
    if (source_uri.find("://") != std::string::npos) {
      // A live network source (dtrack://HOST:PORT): the ingest alone opens it (the launcher must
      // not bind its port); its rate is --frame-rate, else the lab recording's.
      n_frames = -1;
      rate = live_rate > 0 ? live_rate : (lab_recording.empty() ? 0.0 : bridges::openSource(lab_recording)->nominalRate());
      if (!(rate > 0)) cli.fail("--source " + source_uri + ": give --frame-rate HZ (the lab names no recording)");
    } else {
      auto src = bridges::openSource(lab.recording, frames);
      const std::string mismatch = svc::replayRateMismatch(live_rate, src->nominalRate(), 1.0, lab.recording);
      if (!mismatch.empty()) cli.fail(mismatch);
      rate = src->nominalRate();
      n_frames = src->remaining();
    }
    scene = loadScene(lab.scene);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  CollisionWorld world(scene);
  const size_t C = lab.clusters.size();
  // The plausibility figures (core/pipeline/run_metrics.h, the same as godhand-bench's): each
  // received HandState with the HandTarget of its frame, against the scene as received.
  std::vector<HandModel> models(C);
  std::unique_ptr<RunMetrics> metrics;
  try {
    std::vector<const HandModel*> mp;
    std::vector<std::string> names;
    for (size_t c = 0; c < C; ++c) {
      models[c] = loadHandModel(lab.clusters[c].model);
      svc::clusterRetargeter(lab.clusters[c], models[c]);  // the ingest's checks, before anything starts
      mp.push_back(&models[c]);
      names.push_back(lab.clusters[c].name);
    }
    svc::labCalibration(lab);
    PipelineParams mparams;
    mparams.step.dt = 1.0 / (lockstep ? rate : rate * speed);
    mparams.step.solver = solver == "pgs" ? SolverKind::Pgs : SolverKind::Exact;
    metrics = std::make_unique<RunMetrics>(scene, mp, names, mparams);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  std::vector<std::vector<Pose>> m_targets(C), m_poses(C);
  std::vector<std::vector<unsigned char>> m_driven(C);
  const double margin = RowParams{}.margin;
  const double stale_after = lab.stale_after_s;

  // Service command lines.
  const bool own_log_dir = log_dir.empty();  // removed again after a clean run
  if (own_log_dir) log_dir = "/tmp/godhand-launch-" + std::to_string(getpid());
  mkdir(log_dir.c_str(), 0755);
  struct stat st{};
  if (stat(log_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) cli.fail("--log-dir " + log_dir + ": cannot create");
  std::string partition_file;  // the lab's profiles plus this launch's partition (removed after a clean run)
  if (!partition.empty()) {
    try {
      partition_file = writePartitionProfiles(dds::Participant::resolveProfiles(lab.profiles), partition, log_dir);
      dds::Participant::checkProfiles(partition_file);
    } catch (const std::exception& e) {
      cli.fail(std::string("--partition: ") + e.what());
    }
    lab.profiles = partition_file;
  }
  std::vector<ChildSpec> specs;
  std::vector<std::string> remote;  // "NAME (on HOST)"
  for (const LabService& s : lab.services) {
    if (!runsHere(s, host_name)) {
      std::printf("launch: %s runs on %s (not started here)\n", s.name.c_str(), s.host.c_str());
      remote.push_back(s.name + " (on " + s.host + ")");
      continue;
    }
    ChildSpec c;
    c.name = s.name;
    const char* prog = s.kind == pb::Service::INGEST ? "godhand-ingest"
                       : s.kind == pb::Service::SOLVER ? "godhand-solver"
                       : s.kind == pb::Service::SCENE ? "godhand-scene" : "godhand-resolver";
    c.argv = {bin_dir + "/" + prog, "--lab", lab.file, "--domain", std::to_string(lab.domain_id), "--frame-rate", fmt17(lockstep ? rate : rate * speed),
              "--scene", lab.scene};
    if (!lab.profiles.empty()) c.argv.insert(c.argv.end(), {"--profiles", lab.profiles});
    if (lockstep) c.argv.push_back("--lockstep");
    if (deadline > 0) c.argv.insert(c.argv.end(), {"--deadline", fmt17(deadline)});
    switch (s.kind) {
      case pb::Service::INGEST:
        c.argv.insert(c.argv.end(), {"--source", lab.recording, "--frames", std::to_string(frames), "--speed", fmt17(speed),
                                     "--start-timeout", fmt17(start_timeout)});
        // Its first frames go to this launcher's monitor as well (the plausibility figures score
        // every state against its target): one reader per cluster, plus this one.
        c.argv.insert(c.argv.end(), {"--readers", std::to_string(lab.clusters.size() + 1)});
        if (duration > 0) c.argv.insert(c.argv.end(), {"--duration", fmt17(duration)});
        break;
      case pb::Service::SOLVER: c.argv.insert(c.argv.end(), {"--cluster", s.cluster, "--solver", solver}); break;
      case pb::Service::SCENE:
        c.argv.insert(c.argv.end(), {"--physics-hz", std::to_string(physics_hz)});
        if (no_physics) c.argv.push_back("--no-physics");
        break;
      case pb::Service::RESOLVER:
        if (no_physics) c.argv.push_back("--no-physics");
        break;
      default: break;
    }
    c.argv.insert(c.argv.end(), s.args.begin(), s.args.end());
    std::string file = s.name;
    for (char& ch : file)
      if (ch == '/') ch = '-';
    c.log_file = log_dir + "/" + file + ".log";
    // Fast DDS loads the lab's profiles itself (its standard variable); the services then use them.
    c.env.push_back({"FASTRTPS_DEFAULT_PROFILES_FILE", dds::Participant::resolveProfiles(lab.profiles)});
    specs.push_back(std::move(c));
  }
  auto specOf = [&](const std::string& name) -> const ChildSpec* {
    for (const ChildSpec& s : specs)
      if (s.name == name) return &s;
    return nullptr;
  };

  // The monitor subscribes before anything starts.
  std::unique_ptr<dds::Participant> dp;
  std::unique_ptr<dds::Reader<msg::HandState>> hs_in;
  std::unique_ptr<dds::Reader<msg::SceneState>> ss_in;
  std::unique_ptr<dds::Reader<msg::HandTarget>> ht_in;
  std::unique_ptr<dds::Reader<msg::ServiceStatus>> st_in;
  const char* state_profile = lockstep ? dds::profile::kLockStep : dds::profile::kState;
  const char* stream_profile = lockstep ? dds::profile::kLockStep : dds::profile::kStreamLive;
  try {
    dp = std::make_unique<dds::Participant>(dds::Options{static_cast<int>(lab.domain_id), lab.profiles, dds::profile::kParticipant, "launch"});
    hs_in = std::make_unique<dds::Reader<msg::HandState>>(*dp, dds::topic::kHandState, state_profile);
    ss_in = std::make_unique<dds::Reader<msg::SceneState>>(*dp, dds::topic::kSceneState, state_profile);
    // Every target is scored against its HandState: a deeper history than the stream's (live:
    // keep-last 1, a monitor waking every 20 ms lost one in two at 114 Hz).
    ht_in = std::make_unique<dds::Reader<msg::HandTarget>>(*dp, dds::topic::kHandTarget, stream_profile, 64);
    st_in = std::make_unique<dds::Reader<msg::ServiceStatus>>(*dp, dds::topic::kServiceStatus, dds::profile::kStatus);
  } catch (const std::exception& e) {
    hs_in.reset();
    ss_in.reset();
    ht_in.reset();
    st_in.reset();
    dp.reset();  // a participant alive at exit() leaves its shared-memory segment behind
    cli.fail(e.what());
  }
  const std::set<std::string> shm_before = shmSegments();

  std::printf("launch: lab '%s' (%s), domain %u, %s mode, %zu cluster(s), source %s (%s at %.2f Hz), scene '%s'\n",
              lab.name.c_str(), lab.file.c_str(), lab.domain_id, lockstep ? "lock-step" : "live", C, lab.recording.c_str(),
              n_frames >= 0 ? (std::to_string(n_frames) + " frames").c_str() : "live", rate, scene.name.c_str());
  std::printf("launch: service logs in %s%s\n", log_dir.c_str(),
              own_log_dir ? " (removed after a clean run; --log-dir DIR keeps them)" : "");
  std::fflush(stdout);
  std::map<std::string, msg::ServiceStatus> status;
  SourceTally source_tally;  // the ingest's source counts, per ingest run (summed in the report)
  OutputRate output_rate;    // what each service wrote per second (the live line's scene figure)
  Supervisor sup;
  const Clock::time_point t_start = Clock::now();
  Watchdog watchdog(silent_after, t_start);
  std::map<pid_t, std::set<std::string>> shm_of;  // pid -> the shared-memory entries it had open
  std::set<std::string> own_shm;  // this launcher's own participant's entries (not removed by it: only told apart)
  noteShm(getpid(), &own_shm);
  auto noteAllShm = [&] {
    for (const ChildStatus& c : sup.status())
      if (c.running) noteShm(c.pid, &shm_of[c.pid]);
  };
  // Another lab on the domain: a heartbeat of a service this lab does not have, or of one this
  // launcher runs from a process it did not start (same host, another pid).
  std::set<pid_t> our_pids;
  std::set<std::string> foreign_seen;
  std::vector<std::string> foreign;
  char this_host[64] = {0};
  gethostname(this_host, sizeof this_host - 1);
  auto reportForeign = [&](const std::string& who) {
    if (foreign_seen.size() > 32) return;  // bounded: a flood of distinct names is not listed
    if (foreign_seen.insert(who).second) {
      if (foreign_seen.size() > 32) {
        foreign.push_back("more, not listed");
        return;
      }
      foreign.push_back(who);
      std::printf("launch: another lab on domain %u: %s was not started by this launcher; its samples mix with this run's "
                  "(give each lab its own domain or --partition)\n", lab.domain_id, who.c_str());
      std::fflush(stdout);
    }
  };
  auto noteForeign = [&](const msg::ServiceStatus& s) {
    const std::string name = s.service().to_string();
    bool ours_name = lab.service(name) != nullptr;
    bool alien = !ours_name;
    std::string why;
    if (ours_name && specOf(name)) {
      // One this launcher runs: only from this host and from a process it started.
      if (s.host().to_string() != this_host) {
        alien = true;
      } else {
        if (!our_pids.count(s.pid()))
          for (const ChildStatus& c : sup.status()) our_pids.insert(c.pid);
        alien = !our_pids.count(s.pid());
      }
    }
    if (!alien && !svc::plausible(s, &why)) alien = true;  // counters no service of ours sends
    if (!alien) return false;
    const std::string who = name + " (pid " + std::to_string(s.pid()) + " on " + s.host().to_string() + ")" +
                            (why.empty() ? "" : ", " + why);
    reportForeign(who);
    return true;
  };
  std::vector<std::pair<std::string, pid_t>> beats;  // heartbeats since the last drain: a restart's first
  auto takeStatus = [&] {
    msg::ServiceStatus s;
    while (st_in->take(s)) {
      if (noteForeign(s)) continue;  // not one of ours: neither its state nor its heartbeat counts
      const std::string name = s.service().to_string();
      status[name] = s;
      output_rate.beat(name, s.pid(), s.time_ns(), s.samples_out());
      watchdog.beat(name, Clock::now());
      if (beats.size() < 256) beats.emplace_back(name, static_cast<pid_t>(s.pid()));
      std::uint64_t source_run = 0;
      const SourceCounts counts = svc::fromWire(s.source(), &source_run);
      source_tally.update(source_run, counts);  // run 0: not a tracker source
    }
  };
  // Start-up failed: stop what runs, say why, release the DDS entities (a participant alive at
  // exit() leaves its shared-memory segment behind); a stop request is not a failure.
  auto startupFailed = [&](const std::string& why) {
    sup.stop(std::chrono::milliseconds(3000));
    std::fprintf(stderr, "godhand-launch: start-up failed: %s\n", why.c_str());
    hs_in.reset();
    ss_in.reset();
    ht_in.reset();
    st_in.reset();
    dp.reset();
    return stopRequested() ? 0 : kExitStartup;
  };
  try {
    for (const ChildSpec& c : specs)
      if (c.name != "ingest" && !stopRequested()) sup.start(c);  // a stop request ends the start-up here
    // The ingest last, once every other service runs and this monitor is matched with the
    // resolver's HandState and the scene's SceneState writers: a monitor that matched late would
    // miss the first frames (a lock-step run of a short recording is over in a second or two).
    const Clock::time_point until = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(start_timeout));
    for (;;) {
      takeStatus();
      bool ready = hs_in->matched() >= 1 && ss_in->matched() >= 1;
      std::vector<std::string> missing;
      for (const LabService& ls : lab.services)
        if (ls.kind != pb::Service::INGEST && !(status.count(ls.name) && status[ls.name].state() == "running"))
          missing.push_back(ls.name + (runsHere(ls, host_name) ? "" : " (on " + ls.host + ", not started here)"));
      ready = ready && missing.empty();
      if (ready) break;
      std::string dead;
      for (const ChildStatus& c : sup.poll()) dead += " " + c.name + " (" + endedHow(c) + ")";
      if (!dead.empty() || stopRequested() || Clock::now() >= until) {
        std::string names;
        for (const std::string& m : missing) names += (names.empty() ? "" : ", ") + m;
        if (names.empty()) names = hs_in->matched() < 1 ? "no HandState writer matched" : "no SceneState writer matched";
        std::string why = !dead.empty() ? "service(s) ended during start-up:" + dead
                        : stopRequested() ? "stopped during start-up"
                                          : "services not running after " + fmt17(start_timeout) + " s: " + names;
        if (specs.empty() && !remote.empty()) why += " (every service of this lab runs on another host; start them there first)";
        for (const ChildSpec& c : specs) why += "\n  " + c.name + ":\n" + tail(c.log_file, 6);
        return startupFailed(why);
      }
      dp->waitForData(Clock::now() + std::chrono::milliseconds(50));
    }
    for (const ChildSpec& c : specs)
      if (c.name == "ingest") sup.start(c);
    if (!specOf("ingest")) {
      // The ingest runs on another host (or is started by hand): its heartbeat must come within
      // the start-up time, or the run would wait for frames that never come (a mistyped host).
      const LabService* ing = lab.service("ingest");
      const Clock::time_point ingest_until =
          Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(start_timeout));
      while (!status.count("ingest") && !stopRequested() && Clock::now() < ingest_until) {
        dp->waitForData(Clock::now() + std::chrono::milliseconds(50));
        takeStatus();
      }
      if (!status.count("ingest")) {
        const std::string host = ing ? ing->host : "?";
        return startupFailed(stopRequested() ? "stopped during start-up"
                                             : "the ingest (on " + host + ", not started here) was not heard from in " +
                                                   fmt17(start_timeout) + " s (is it running there, and is " + host +
                                                   " this lab's name for that machine? this machine is " +
                                                   (host_name.empty() ? std::string(this_host) : host_name) + ")");
      }
    }
    noteAllShm();
  } catch (const std::exception& e) {
    sup.stop(std::chrono::milliseconds(3000));
    std::fprintf(stderr, "godhand-launch: start-up failed: %s\n", e.what());
    return kExitStartup;
  }

  // Measurements.
  RunReport rep;
  // The run's figures in bounded memory (a lab left running for a day: math/stats.h).
  LatencyFigures latency;  // fresh states' latency (the run's and this second's); stale states' ages apart
  Sample st_contacts, st_assembly, st_solve, st_integrate, st_ccd, st_merge, st_scene;
  double window_pen = 0;
  Sample st_total;  // compute time per frame: the stages' own times, no transport
  double last_scene_us = 0;
  ResultHash hash;
  std::map<std::uint64_t, FrameHands> pending;          // lock-step: frame -> hands
  std::map<std::uint64_t, SceneSnapshot> scenes;        // lock-step: frame -> scene
  // Live: the newest scene states by step. A HandState is scored against the scene state it was
  // resolved against (scene_step), not the newest: the scene steps on its own clock, and a hand
  // resting on an object the newest state has moved is not a penetration of the method.
  std::map<std::uint64_t, SceneSnapshot> recent_scenes;
  FrameBook<msg::HandTarget> targets(C);  // (ingest run, frame) -> per cluster
  std::uint64_t tracked_targets_seen = 0;  // HandTargets with a tracked hand (the "no hand tracked" verdict's check)
  std::uint64_t next_frame = 1;
  std::uint64_t last_scene_step = 0;
  RecoveryLog recovery(static_cast<int>(C));  // each restart: when every hand was fresh again
  Delivery delivery(C);
  struct BlindWindow {  // frames published while this launcher did not watch (see its main loop)
    std::uint64_t run = 0, first = 0;
    std::int64_t until_ns = 0;  // the pause's end: the first frame sampled later closes the window
    bool open = false;
  } blind;
  // A closed window is held until no service ended or went silent for a while after it (then its
  // frames were published, and the launcher alone missed them); a service that died or froze in
  // or right after the pause makes them what they are, lost (a resolver killed during the pause
  // had 57 frames published by nobody counted as not observed).
  struct HeldWindow {
    std::uint64_t run, first, last;
    Clock::time_point from, to;  // the pause's start, the window's close
    Clock::time_point commit_at;
  };
  std::vector<HeldWindow> held_blind;
  Clock::time_point blind_from{};  // the open window's pause start
  auto closeBlind = [&](std::uint64_t last) {
    if (last >= blind.first && held_blind.size() < 64)
      held_blind.push_back({blind.run, blind.first, last, blind_from, Clock::now(),
                            Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(silent_after + 1.0))});
    blind.open = false;
  };
  // A service died or froze some time in [lo, hi]: the windows that time can overlap are dropped
  // (their frames may not have been published: lost). A kill by this launcher after a window
  // closed leaves it (its frames were out before the kill).
  auto dropBlind = [&](Clock::time_point lo, Clock::time_point hi) {
    held_blind.erase(std::remove_if(held_blind.begin(), held_blind.end(), [&](const HeldWindow& w) { return lo <= w.to && hi >= w.from; }),
                     held_blind.end());
    if (blind.open && hi >= blind_from) blind.open = false;
  };
  auto commitBlind = [&](bool all) {
    for (auto it = held_blind.begin(); it != held_blind.end();) {
      if (!all && Clock::now() < it->commit_at) {
        ++it;
        continue;
      }
      delivery.unobserved(it->run, it->first, it->last);
      it = held_blind.erase(it);
    }
  };
  // This launcher's latest own pause (tracker-clock ns): what it makes a state's age look like.
  std::int64_t own_pause_start_ns = 0, own_pause_end_ns = 0;
  int exit_code = 0;
  std::string failure;
  // The replay: its first frame's arrival here is time 0 of every drill and of the report's times.
  Clock::time_point t_replay{};
  std::uint64_t replay_run = 0, replay_frame = 0;
  auto replayS = [&]() { return t_replay == Clock::time_point{} ? -1.0 : secondsSince(t_replay); };
  std::vector<DrillReport> drill_reports(drills.size());
  std::vector<unsigned char> drill_fired(drills.size(), 0);
  std::set<std::string> killed_by_us;  // SIGKILLed by a drill or the watchdog: restart it
  std::map<std::string, Clock::time_point> killed_at;  // when (the death's time, for the pause windows)
  bool scene_down = false;             // the scene's poses are old (killed, silent, restarting)
  double unscored_from = -1;
  std::map<int, ObjectMotion> scene_last;  // newest state per dynamic object
  bool scene_restarted = false;     // the scene was restarted: its first state's jump is measured

  Clock::time_point t_first_state{}, t_last_state{};
  bool ingest_done = false;  // the ingest exited 0: every HandTarget it wrote is out
  // When this launcher's ingest first said "stopping" (its last heartbeat, with its final
  // counters) while its process still ran: it has kExitGrace to exit. (Seen once: an ingest that
  // had finished a secured multi-host lock-step run never exited, and the launcher waited for it
  // until the test killed everything 3 minutes later.)
  Clock::time_point ingest_stopping_since{};
  constexpr double kExitGrace = 10.0;
  bool run_over = false;  // the ingest is done: held hands re-published after the run are not counted
  std::vector<long> live_contacts(C, 0);
  std::vector<Pose> gap_poses;
  auto measure = [&](const msg::HandState& h, const SceneSnapshot* snap, double lat_us, bool stale_rx, bool own_scene) {
    if (h.held() && run_over) return;
    // Frame 0: a state before the replay's first frame (start-up, held): not a state of the run.
    if (!lockstep && h.stamp().frame() == 0) return;
    if (!h.held() && !stale_rx) {
      if (t_first_state == Clock::time_point{}) t_first_state = Clock::now();
      t_last_state = Clock::now();
    }
    ++rep.states;
    if (snap)
      for (const ObjectMotion& o : snap->objects) world.setObjectPose(o.index, o.X);
    latency.add(lat_us, stale_rx);
    if (stale_rx) ++rep.stale_states;
    if (h.held()) {  // the last result again: its figures were counted when it was new
      ++rep.held_states;
      return;
    }
    if (!lockstep)
      st_total.add(h.solver_times().contacts_us() + h.solver_times().assembly_us() + h.solver_times().solve_us() +
                         h.solver_times().integrate_us() + h.ccd_us() + h.merge_us() + last_scene_us);
    if (!lockstep && h.hand() < C) {  // live: every hand's newest count, summed (lock-step: per frame, below)
      live_contacts[h.hand()] = h.contacts();
      long sum = 0;
      for (long c : live_contacts) sum += c;
      rep.contacts_max = std::max(rep.contacts_max, sum);
    }
    if (h.toc() < 1.0) ++rep.clipped;
    if (h.lifted_start()) ++rep.lifted;
    if (h.started_inside()) ++rep.inside;
    if (h.flags() & kFlagSolverFailed) ++rep.solver_failures;
    if (h.flags() & kFlagSolverInexact) ++rep.inexact;
    // Penetration and joint gap are of started hands only; the plausibility metrics take every
    // state (an unstarted hand is what "never started" is made of).
    if (!h.started()) {
    } else if (scene_down) {
      ++rep.penetration_unscored;  // the scene's last poses are not where its objects are now
    } else {
      double pen = 0;
      long deepest = -1;
      int deepest_object = -1;
      for (size_t b = 0; b < h.poses().size() && b < h.shapes().size(); ++b) {
        Shape s;
        s.type = static_cast<ShapeType>(std::min<int>(h.shapes()[b].type(), 2));
        s.radius = h.shapes()[b].radius();
        s.half_length = h.shapes()[b].half_length();
        s.half_extents = Vec3(h.shapes()[b].half_extents()[0], h.shapes()[b].half_extents()[1], h.shapes()[b].half_extents()[2]);
        int object = -1;
        const double pb = world.penetration(s, svc::fromWire(h.poses()[b]), &object);
        if (pb > pen) {
          pen = pb;
          deepest = static_cast<long>(b);
          deepest_object = object;
        }
      }
      if (pen > rep.penetration_max_m) {
        RunReport::Worst& w = rep.penetration_worst;
        w.hand = h.hand();
        w.body = deepest;
        w.object = deepest_object >= 0 && static_cast<size_t>(deepest_object) < scene.objects.size()
                       ? scene.objects[static_cast<size_t>(deepest_object)].id
                       : std::string();
        w.frame = h.stamp().frame();
        w.scene_step = h.scene_step();
        w.own_scene = own_scene;
        w.tracked = h.tracked();
        w.stale = stale_rx;
        w.toc = h.toc();
        w.replay_s = replayS();
      }
      rep.penetration_max_m = std::max(rep.penetration_max_m, pen);
      window_pen = std::max(window_pen, pen);
    }
    // The resolver's figure, and measured here from the poses (a second computation, not trust).
    double gap = h.started() ? h.joint_gap() : 0.0;
    if (h.started() && h.hand() < C && h.poses().size() == models[h.hand()].bodies.size()) {
      gap_poses.resize(h.poses().size());
      for (std::size_t b = 0; b < h.poses().size(); ++b) gap_poses[b] = svc::fromWire(h.poses()[b]);
      gap = std::max(gap, jointErrors(models[h.hand()], gap_poses.data()).gap);
    }
    rep.joint_gap_max_m = std::max(rep.joint_gap_max_m, gap);
    if (!scene_down && h.hand() < C && (!h.started() || h.poses().size() == models[h.hand()].bodies.size())) {
      const std::size_t c = h.hand();
      HandSample s;
      s.started = h.started();
      s.tracked = h.tracked();
      s.held = h.held();
      m_poses[c].resize(models[c].bodies.size());
      if (h.started())
        for (std::size_t b = 0; b < h.poses().size(); ++b) m_poses[c][b] = svc::fromWire(h.poses()[b]);
      s.X = h.started() ? m_poses[c].data() : nullptr;
      s.loaded = h.loaded();
      s.clipped = h.clipped();
      s.toc = h.toc();
      s.substeps = static_cast<int>(h.substeps());
      s.joint_gap = h.joint_gap();
      HandInput in;
      if (const msg::HandTarget* tp = targets.find(h.stamp().run(), h.stamp().frame(), c)) {
        const msg::HandTarget& t = *tp;
        if (t.tracked() && t.targets().size() == models[c].bodies.size() && t.driven().size() == models[c].bodies.size()) {
          m_targets[c].resize(t.targets().size());
          m_driven[c].resize(t.driven().size());
          for (std::size_t b = 0; b < t.targets().size(); ++b) {
            m_targets[c][b] = svc::fromWire(t.targets()[b]);
            m_driven[c][b] = t.driven()[b] ? 1 : 0;
          }
          in.tracked = true;
          in.targets = m_targets[c].data();
          in.has_target = m_driven[c].data();
          s.targets = in.targets;
          s.has_target = in.has_target;
        }
      }
      if (!in.tracked) s.tracked = false;  // no target at hand for this frame: not scored against one
      metrics->add(static_cast<int>(c), s, in, world);
    }
    if (h.tracked()) rep.kkt_max = std::max(rep.kkt_max, h.kkt());
  };
  // Live: a HandState is scored once the scene state it was resolved against has arrived here
  // too (the scene's and the resolver's samples take different ways); in arrival order. Scored
  // against the newest scene state instead (and counted so) when its own cannot come any more:
  // an older step that is not kept, or not here 0.5 s after the hand state. A tracked one also
  // waits for its frame's HandTarget (its figures are scored against it): as in lock-step, the
  // topics are not ordered with one another, and drain() takes the targets before the states, so
  // a state can be here before its target; measured then, it counted as untracked (under load,
  // 1-7 of ~210 frames of tests/programs/sources.py's tool, which its solver had stepped tracked:
  // the likely cause of a CI run's "tracked in 197 of 215"). Best-effort: a target not here 0.5 s
  // after the state is lost, and the state is scored untracked.
  struct Awaiting {
    msg::HandState h;
    double lat_us;
    bool stale_rx;
    Clock::time_point at;
  };
  std::deque<Awaiting> awaiting;
  auto targetHere = [&](const msg::HandState& h) {
    return targets.find(h.stamp().run(), h.stamp().frame(), h.hand()) != nullptr;
  };
  auto scoreAwaiting = [&](bool flush) {
    while (!awaiting.empty()) {
      const Awaiting& a = awaiting.front();
      if (a.h.tracked() && !a.h.held() && !targetHere(a.h) && !flush && secondsSince(a.at) < 0.5) break;  // its target: not here yet
      const SceneSnapshot* own = nullptr;
      bool own_state = false;
      if (!recent_scenes.empty()) {
        const auto it = recent_scenes.find(a.h.scene_step());
        const std::uint64_t newest = recent_scenes.rbegin()->first;
        if (it == recent_scenes.end() && a.h.scene_step() > newest && !flush && secondsSince(a.at) < 0.5) break;  // not here yet
        own_state = it != recent_scenes.end();
        own = own_state ? &it->second : &recent_scenes.rbegin()->second;
        if (a.h.started() && !a.h.held() && !scene_down) ++(own_state ? rep.penetration_own_scene : rep.penetration_newest_scene);
      }
      measure(a.h, own, a.lat_us, a.stale_rx, own_state);
      awaiting.pop_front();
    }
  };
  auto setSceneDown = [&](bool down) {
    if (down == scene_down) return;
    scene_down = down;
    if (down) unscored_from = replayS();
    else rep.unscored_windows.push_back({unscored_from, replayS()});
  };
  auto drain = [&] {
    takeStatus();
    for (const auto& [name, pid] : beats) {  // the restarted process's own (not a heartbeat of the dead one in flight)
      const ChildStatus* c = sup.find(name);
      if (c && c->pid == pid) recovery.heartbeat(name, pid, replayS());
    }
    beats.clear();
    msg::HandTarget t;
    while (ht_in->take(t)) {
      delivery.published(t.stamp().run(), t.stamp().frame());
      if (blind.open && (t.stamp().run() != blind.run || t.stamp().source_time_ns() > blind.until_ns)) {
        // Closed by the first frame sampled after the pause, or by a new ingest run (the old run's
        // frames up to its highest then).
        closeBlind(t.stamp().run() == blind.run ? t.stamp().frame() - 1 : delivery.highest(blind.run));
      }
      if (t.stamp().frame() > 0) {
        if (t_replay == Clock::time_point{}) t_replay = Clock::now();
        if (t.stamp().run() != replay_run) {  // a (re)started ingest: its frames count from 1 again
          if (replay_run == 0 || t.stamp().source_time_ns() > 0) {
            replay_run = t.stamp().run();
            replay_frame = 0;
          }
        }
        if (t.stamp().run() == replay_run) replay_frame = std::max<std::uint64_t>(replay_frame, t.stamp().frame());
      }
      if (t.tracked()) ++tracked_targets_seen;
      targets.put(t.stamp().run(), t.stamp().frame(), t.hand(), t);  // (a hand beyond the lab's: ignored)
    }
    msg::SceneState ss;
    std::string why;
    while (ss_in->take(ss)) {
      SceneSnapshot snap;
      if (!svc::fromWire(ss, static_cast<int>(scene.objects.size()), &snap, &why)) continue;
      rep.pushouts += snap.pushouts;
      last_scene_us = snap.step_us;
      if (snap.step < last_scene_step) recovery.sceneRunBegan(replayS());
      last_scene_step = snap.step;
      if (scene_restarted) {  // how far the restarted scene moved the objects from where they were
        scene_restarted = false;
        double jump = 0;
        // Objects at rest before the kill and in the new scene's first state seen (< 1 cm/s) must
        // be where they were (a jump back to the scene file's poses); moving ones move on.
        for (const ObjectMotion& o : snap.objects)
          if (scene_last.count(o.index) && scene_last[o.index].v.norm() < 0.01 && o.v.norm() < 0.01)
            jump = std::max(jump, (o.X.p - scene_last[o.index].X.p).norm());
        rep.scene_restart_jump_m = std::max(rep.scene_restart_jump_m, jump);
      }
      for (const ObjectMotion& o : snap.objects) scene_last[o.index] = o;
      if (lockstep) {
        scenes[snap.frame] = snap;
      } else {
        if (!recent_scenes.empty() && snap.step <= recent_scenes.rbegin()->first) {  // a new scene run
          scoreAwaiting(true);  // the states resolved against the old run's steps: scored with its history
          recent_scenes.clear();
        }
        recent_scenes[snap.step] = snap;
        while (recent_scenes.size() > 256) recent_scenes.erase(recent_scenes.begin());
      }
      const ChildStatus* sc = sup.find("scene");
      if (!sc || sc->running) setSceneDown(false);  // a state of the running scene: its poses are current
    }
    if (!lockstep) scoreAwaiting(false);
    msg::HandState h;
    while (hs_in->take(h)) {
      double lat = h.stamp().source_time_ns() > 0 ? static_cast<double>(svc::nowNs() - h.stamp().source_time_ns()) * 1e-3 : 0.0;
      if (h.hand() >= C || h.cluster() != lab.clusters[h.hand()].name) {  // not this lab's hand
        reportForeign("a HandState of cluster '" + h.cluster().to_string() + "' (hand " + std::to_string(h.hand()) + ")");
        continue;
      }
      // Stale whatever the cause: flagged by the resolver, or older than the stale limit here.
      // (Lock-step frames are never stale by age: a slow deterministic run is still exact.)
      // A state sampled before this launcher's own latest pause ended and read only after it is
      // old partly by the launcher's fault: the part of the pause after its sample is taken off its
      // age for the stale verdict, and its age is no latency (not measured).
      const std::int64_t src_ns = h.stamp().source_time_ns();
      const bool own_late = !lockstep && src_ns > 0 && src_ns <= own_pause_end_ns;
      const double age_s = own_late ? lat * 1e-6 - static_cast<double>(own_pause_end_ns - std::max(src_ns, own_pause_start_ns)) * 1e-9
                                    : lat * 1e-6;
      const bool too_old = !lockstep && src_ns > 0 && age_s > stale_after;
      const bool stale_rx = h.stale() || too_old;
      // The resolver must have flagged it (0.1 s allowed for the way from the resolver to here).
      if (!lockstep && age_s > stale_after + 0.1 && src_ns > 0 && !h.stale() && !(h.held() && run_over)) ++rep.old_unmarked;
      if (own_late) lat = 0.0;
      delivery.add(h.hand(), h.stamp().run(), h.stamp().frame(), stale_rx);
      if (lockstep) {
        FrameHands& f = pending[h.stamp().frame()];
        f.states.resize(C);
        f.have.resize(C, 0);
        f.states[h.hand()] = h;
        f.have[h.hand()] = 1;
        latency.add(lat, stale_rx);
      } else {
        awaiting.push_back(Awaiting{h, lat, stale_rx, Clock::now()});
        scoreAwaiting(false);
        if (h.stamp().frame() == 0) continue;  // start-up is not a stale window
        recovery.state(static_cast<int>(h.hand()), stale_rx, replayS());
      }
    }
    // Lock-step: frames complete in order (every cluster's HandState(k) and SceneState(k), and
    // its HandTarget(k), which the plausibility figures score against: the topics are not
    // ordered with one another, and a state measured before its target came was counted as
    // untracked; reliable, so it comes, unless the ingest is gone).
    while (lockstep) {
      auto it = pending.find(next_frame);
      if (it == pending.end() || !scenes.count(next_frame)) break;
      bool all = true;
      for (unsigned char c : it->second.have) all = all && c;
      if (!all) break;
      // (The states' run: one ingest run in lock-step.)
      const std::uint64_t run = it->second.states[0].stamp().run();
      if (!ingest_done && !targets.complete(run, next_frame)) break;
      const SceneSnapshot& snap = scenes[next_frame];
      double contacts = 0, c_us = 0, a_us = 0, s_us = 0, i_us = 0, ccd = 0, merge = 0;
      for (size_t c = 0; c < C; ++c) {
        const msg::HandState& hsc = it->second.states[c];
        measure(hsc, c == 0 ? &snap : nullptr, 0.0, hsc.stale(), true);
        contacts += hsc.contacts();
        c_us += hsc.solver_times().contacts_us();
        a_us += hsc.solver_times().assembly_us();
        s_us += hsc.solver_times().solve_us();
        i_us += hsc.solver_times().integrate_us();
        ccd += hsc.ccd_us();
        merge += hsc.merge_us();
        if (hsc.started())
          for (const msg::Pose& p : hsc.poses()) hash.add(svc::fromWire(p));
      }
      rep.contacts_max = std::max(rep.contacts_max, static_cast<long>(contacts));
      st_contacts.add(c_us);
      st_assembly.add(a_us);
      st_solve.add(s_us);
      st_integrate.add(i_us);
      st_ccd.add(ccd);
      st_merge.add(merge);
      st_scene.add(snap.step_us);
      st_total.add(c_us + a_us + s_us + i_us + ccd + merge + snap.step_us);
      pending.erase(it);
      scenes.erase(scenes.begin(), scenes.upper_bound(next_frame));
      targets.eraseThrough(run, next_frame);
      ++next_frame;
    }
  };

  // Run until the ingest is done (or a failure, or a stop signal).
  Clock::time_point last_print = Clock::now(), last_shm_scan = Clock::now();
  std::map<std::string, Clock::time_point> restarts;  // service -> when to restart it
  auto restartLater = [&](const std::string& name, const std::string& why) {
    std::printf("launch: %s %s; restarting in %.1f s\n", name.c_str(), why.c_str(), restart_delay);
    restarts[name] = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(restart_delay));
    if (name == "scene") setSceneDown(true);
  };
  Clock::time_point last_drain = Clock::now();  // (taken before each drain: a pause inside one counts too)
  Clock::time_point last_poll = Clock::now();
  while (!stopRequested()) {
    dp->waitForData(Clock::now() + std::chrono::milliseconds(20));
    // This launcher's own pause (as its watchdog records one: longer than the silent limit; a
    // slow loop of 0.6-1.2 s is not one, its missed frames stay lost): the frames published
    // meanwhile were superseded in its keep-newest readers. The window runs from the newest frame
    // seen before to the last one sampled before the pause ended (closed in drain() by the first
    // sampled after it; a second pause while it is open extends it); of its frames, those of which
    // no state comes are not observed rather than lost (Delivery).
    bool paused_now = false;  // (drills wait a loop: the backlog of the pause is not taken yet)
    {
      const Clock::time_point before = Clock::now();
      const double gap_s = std::chrono::duration<double>(before - last_drain).count();
      if (!lockstep && gap_s > silent_after) {
        paused_now = true;
        own_pause_end_ns = svc::nowNs();
        own_pause_start_ns = own_pause_end_ns - static_cast<std::int64_t>(gap_s * 1e9);
        if (blind.open) {
          blind.until_ns = own_pause_end_ns;
        } else if (replay_run != 0) {
          blind = {replay_run, replay_frame + 1, own_pause_end_ns, true};
          blind_from = last_drain;
        }
      }
      last_drain = before;
    }
    drain();
    if (secondsSince(last_shm_scan) >= 1.0) {
      noteAllShm();
      last_shm_scan = Clock::now();
    }
    const Clock::time_point poll_from = last_poll;  // a child seen ended now ended after the last poll
    last_poll = Clock::now();
    for (const ChildStatus& c : sup.poll()) {
      // When it died: at this launcher's kill, or some time since the last poll (within a pause of
      // this launcher: any time in it; not before its last heartbeat).
      Clock::time_point lo = poll_from, hi = Clock::now();
      if (auto k = killed_at.find(c.name); k != killed_at.end() && killed_by_us.count(c.name)) {
        lo = hi = k->second;
        killed_at.erase(k);
      } else if (watchdog.silentFor(c.name, Clock::now()) >= 0) {
        lo = std::max(lo, Clock::now() - std::chrono::duration_cast<Clock::duration>(
                                             std::chrono::duration<double>(watchdog.silentFor(c.name, Clock::now()))));
      }
      watchdog.reset(c.name, Clock::now());  // ended: not running (shown DOWN), no longer silent
      if (c.name == "ingest" && c.exited && c.exit_code == 0) {
        ingest_done = true;
        continue;
      }
      const double seen_s = replayS();
      recovery.down(c.name, seen_s - secondsSince(lo), seen_s - secondsSince(hi));
      dropBlind(lo, hi);
      const bool ours = killed_by_us.erase(c.name) > 0 && c.term_signal == SIGKILL;
      if (c.name == "scene") setSceneDown(true);
      if ((restart || ours) && !lockstep) {
        restartLater(c.name, "ended (" + endedHow(c) + (ours ? ", killed by this launcher" : "") + ")");
      } else if (failure.empty()) {
        failure = c.name + " ended unexpectedly (" + endedHow(c) + ")";
        if (const ChildSpec* sp = specOf(c.name)) failure += "\n" + tail(sp->log_file, 12);
      }
    }
    if (!failure.empty()) break;
    if (!ingest_done) {
      const ChildStatus* ic = sup.find("ingest");
      const auto ist = status.find("ingest");
      if (ic && ic->running && ist != status.end() && ist->second.state() == "stopping") {
        if (ingest_stopping_since == Clock::time_point{}) ingest_stopping_since = Clock::now();
        if (secondsSince(ingest_stopping_since) > kExitGrace) {
          // Where it hangs, before it is killed (gdb, where installed; a few seconds).
          std::printf("launch: the ingest's threads, %s s after its last heartbeat:\n%s", fmt17(kExitGrace).c_str(),
                      sup.backtraces("ingest", std::chrono::seconds(30)).c_str());
          std::fflush(stdout);
          sup.signal("ingest", SIGKILL);
          failure = "ingest finished its run but had not exited " + fmt17(kExitGrace) +
                    " s later (killed: stuck in its shutdown, after its last heartbeat)";
          break;
        }
      }
    }
    // The watchdog: a service without a heartbeat for silent_after is dead, whatever the reason
    // (this launcher's own pauses not counted: watchdog.h).
    const std::uint64_t pauses_before = watchdog.pauseCount();
    const std::vector<std::string> silent_now = watchdog.update(Clock::now());
    if (watchdog.pauseCount() > pauses_before && watchdog.pauseCount() <= Watchdog::kMaxPauses) {
      std::printf("launch: this launcher did not watch for %.1f s (stopped, starved or stalled): not counted against the services\n",
                  watchdog.pauses().back().duration_s);
      std::fflush(stdout);
    }
    for (const std::string& name : silent_now)  // silent since its last heartbeat
      dropBlind(Clock::now() - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(watchdog.silentFor(name, Clock::now()))),
                Clock::now());
    for (const std::string& name : silent_now) {
      std::printf("launch: watchdog: %s silent (no heartbeat for %.1f s)%s\n", name.c_str(), watchdog.silentFor(name, Clock::now()),
                  restart && !lockstep && specOf(name) ? ": killing it for a restart" : "");
      std::fflush(stdout);  // now, not with the next per-second line
      if (name == "scene") setSceneDown(true);
      if (restart && !lockstep && specOf(name) && sup.signal(name, SIGKILL)) {
        killed_by_us.insert(name);
        killed_at[name] = Clock::now();
        rep.watchdog_restarts.push_back(name);
        const double last_beat_s = replayS() - watchdog.silentFor(name, Clock::now());  // down since its last heartbeat
        recovery.down(name, last_beat_s, last_beat_s);
      }
    }
    for (auto it = restarts.begin(); it != restarts.end();) {
      if (Clock::now() < it->second) {
        ++it;
        continue;
      }
      try {
        const ChildSpec* spec = specOf(it->first);
        if (it->first == "scene" && !lockstep && spec) {
          // A restarted scene resumes from the scene state the resolver holds, not the scene file.
          ChildSpec resume = *spec;
          resume.argv.insert(resume.argv.end(), {"--resume-wait", fmt17(kSceneResumeWait)});
          sup.start(resume);
        } else {
          sup.restart(it->first);
        }
      } catch (const std::exception& e) {
        failure = std::string("restart failed: ") + e.what();
        break;
      }
      watchdog.reset(it->first, Clock::now());
      const ChildStatus* started = sup.find(it->first);
      recovery.restarted(it->first, replayS(), started ? started->pid : -1);
      if (it->first == "scene") scene_restarted = true;
      for (size_t i = 0; i < drills.size(); ++i)
        if (drill_fired[i] && drills[i].service == it->first && drill_reports[i].restarted_s < 0) drill_reports[i].restarted_s = replayS();
      std::printf("launch: %s restarted at %.2f s after the replay start\n", it->first.c_str(), replayS());
      it = restarts.erase(it);
    }
    if (!failure.empty()) break;
    commitBlind(false);
    // (Drills wait while a pause's window is open: until a frame sampled after the pause is taken,
    // the replay's frame here is one from before it.)
    for (size_t i = 0; i < drills.size() && !paused_now && !blind.open; ++i) {
      if (drill_fired[i] || !drills[i].due(replayS(), replay_frame)) continue;
      const ChildStatus* c = sup.find(drills[i].service);
      if (!c || !c->running) continue;  // down already (a previous drill): fires once it runs again
      noteShm(c->pid, &shm_of[c->pid]);
      if (!sup.signal(drills[i].service, SIGKILL)) continue;
      drill_fired[i] = 1;
      killed_by_us.insert(drills[i].service);
      killed_at[drills[i].service] = Clock::now();
      drill_reports[i] = {drills[i].spec, drills[i].service, replayS(), -1.0, replay_frame};
      recovery.down(drills[i].service, replayS(), replayS());
      if (drills[i].service == "scene") setSceneDown(true);
      std::printf("launch: fault drill %s: SIGKILL %s at %.2f s after the replay start (frame %llu)\n", drills[i].spec.c_str(),
                  drills[i].service.c_str(), replayS(), static_cast<unsigned long long>(replay_frame));
    }
    if (ingest_done) {
      run_over = true;
      recovery.replayEnded(replayS());
      if (blind.open) closeBlind(delivery.highest(blind.run));  // the replay ended inside the window: up to its highest frame
      // Let the last states arrive (lock-step: until every frame is in, bounded; with --duration,
      // every frame the ingest published: it stopped before the end on purpose, or reached it).
      const Clock::time_point until = Clock::now() + std::chrono::seconds(lockstep ? 5 : 1);
      std::uint64_t last_frame = n_frames < 0 ? 0 : static_cast<std::uint64_t>(n_frames);
      if (duration > 0 && !delivery.runs().empty()) last_frame = std::min(last_frame, delivery.highest(delivery.runs().back()));
      while (Clock::now() < until && (!lockstep || n_frames < 0 || next_frame <= last_frame)) {
        dp->waitForData(Clock::now() + std::chrono::milliseconds(20));
        drain();
      }
      break;
    }
    if (quiet && latency.window().size() > 100000) latency.clearWindow();
    if (!quiet && secondsSince(last_print) >= 1.0) {
      last_print = Clock::now();
      std::string rates;
      for (const auto& s : status) {
        char b[160];
        const Watchdog::Health hl = watchdog.health(s.first);
        const ChildStatus* c = sup.find(s.first);
        if (c && !c->running)
          std::snprintf(b, sizeof b, "%s%s DOWN", rates.empty() ? "" : ", ", s.first.c_str());
        else if (hl == Watchdog::Health::Silent)
          std::snprintf(b, sizeof b, "%s%s DEAD (silent %.1f s)", rates.empty() ? "" : ", ", s.first.c_str(),
                        watchdog.silentFor(s.first, Clock::now()));
        else if (hl == Watchdog::Health::Unknown)  // (re)starting: its last status is a former process's
          std::snprintf(b, sizeof b, "%s%s starting", rates.empty() ? "" : ", ", s.first.c_str());
        else if (s.first == "scene") {
          // The scene: the states it published per second (its heartbeats' samples_out), not its
          // rate_hz, which counts the steps that applied new forces (its inputs: 0 with the resolver gone).
          const double out = output_rate.perSecond(s.first);
          std::snprintf(b, sizeof b, "%s%s %s states/s %s", rates.empty() ? "" : ", ", s.first.c_str(),
                        out < 0 ? "-" : std::to_string(static_cast<long>(std::lround(out))).c_str(), s.second.state().c_str());
        } else {
          std::snprintf(b, sizeof b, "%s%s %.0f Hz %s", rates.empty() ? "" : ", ", s.first.c_str(), s.second.rate_hz(),
                        s.second.state().c_str());
        }
        rates += b;
      }
      char pen_text[48], lat_text[128];
      std::snprintf(pen_text, sizeof pen_text, "%.4f mm", window_pen * 1e3);
      // No fresh HandState this second: no latency to show (a 0 would read as instant).
      if (latency.window().empty())
        std::snprintf(lat_text, sizeof lat_text, "latency - (no fresh hand state this second)");
      else  // (fresh states only: a stale state's age is no latency)
        std::snprintf(lat_text, sizeof lat_text, "latency (tracker sample -> hand state) median %.0f us p99 %.0f us",
                      percentile(latency.window(), 0.5), percentile(latency.window(), 0.99));
      std::printf("launch: t %5.1f s | %s | %s | penetration max %s | hand states %ld (stale %ld)\n", replayS() < 0 ? 0.0 : replayS(),
                  rates.c_str(), lat_text, scene_down ? "not scored (scene down)" : pen_text, rep.states, rep.stale_states);
      std::fflush(stdout);
      latency.clearWindow();
      window_pen = 0;
    }
  }
  scoreAwaiting(true);
  watchdog.resumeAfterOwnWork(Clock::now());
  rep.run_s = secondsSince(t_start);

  // The services' last heartbeats (period 0.5 s) carry their final counters.
  if (failure.empty() && !stopRequested()) {
    const Clock::time_point until = Clock::now() + std::chrono::milliseconds(1200);
    while (Clock::now() < until) {
      dp->waitForData(Clock::now() + std::chrono::milliseconds(50));
      drain();
      watchdog.update(Clock::now());
    }
  }
  scoreAwaiting(true);
  if (scene_down) rep.unscored_windows.push_back({unscored_from, -1.0});
  // Who is not running at the end (the ingest is done when it exited 0).
  watchdog.update(Clock::now());
  for (const ChildStatus& c : sup.poll())
    if (!(c.name == "ingest" && c.exited && c.exit_code == 0) && failure.empty())
      failure = c.name + " ended at the end of the run (" + endedHow(c) + ")";
  for (const LabService& ls : lab.services) {
    const ChildStatus* c = sup.find(ls.name);
    if (ls.kind == pb::Service::INGEST && c && c->exited && c->exit_code == 0) continue;
    if (ls.kind == pb::Service::INGEST && !c) continue;  // remote ingest: its end is its own
    if ((c && !c->running) || watchdog.health(ls.name) != Watchdog::Health::Alive) rep.dead_at_end.push_back(ls.name);
  }
  for (const auto& s : status) {
    ServiceFigures& f = rep.services[s.first];
    f.frame = s.second.frame();
    f.samples_in = s.second.samples_in();
    f.samples_out = s.second.samples_out();
    f.rejected = s.second.rejected();
    f.late = s.second.late();
    f.deadline_misses = s.second.deadline_misses();
    f.latency_median_us = s.second.latency_median_us();
    f.rate_hz = s.second.rate_hz();
    f.state = s.second.state().to_string();
    const ChildStatus* c = sup.find(s.first);
    const Watchdog::Health hl = watchdog.health(s.first);
    f.health = c && !c->running ? (c->exited && c->exit_code == 0 ? "finished" : "not running")
               : hl == Watchdog::Health::Alive ? "alive" : hl == Watchdog::Health::Silent ? "silent" : "unknown";
  }

  // Late joiner: a fresh participant must get every cluster's last HandState and the scene.
  if (failure.empty() && !stopRequested()) {
    try {
      dds::Participant late(dds::Options{static_cast<int>(lab.domain_id), lab.profiles, dds::profile::kParticipant, "launch/late-joiner"});
      dds::Reader<msg::HandState> lh(late, dds::topic::kHandState, state_profile);
      dds::Reader<msg::SceneDescription> ld(late, dds::topic::kSceneDescription, dds::profile::kState);
      const Clock::time_point t0 = Clock::now();
      std::set<std::uint32_t> got;
      msg::HandState h;
      msg::SceneDescription d;
      while (secondsSince(t0) < 5.0 && (got.size() < C || !rep.late_description)) {
        late.waitForData(Clock::now() + std::chrono::milliseconds(50));
        while (lh.take(h)) got.insert(h.hand());
        while (ld.take(d)) rep.late_description = d.objects().size() == scene.objects.size();
      }
      rep.late_states = got.size();
      if (got.size() == C && rep.late_description) rep.late_ms = secondsSince(t0) * 1e3;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "launch: late joiner: %s\n", e.what());
    }
  }

  // Stop everything, check nothing is left behind.
  noteAllShm();
  sup.stop(std::chrono::milliseconds(5000));
  rep.clean_shutdown = true;
  for (const ChildStatus& c : sup.status()) {
    const bool ok = (c.exited && c.exit_code == 0) || (!c.exited && c.term_signal == SIGTERM);
    if (!ok) rep.clean_shutdown = false;
    rep.exits += " " + c.name + (c.exited ? "=" + std::to_string(c.exit_code) : "=sig" + std::to_string(c.term_signal));
  }
  hs_in.reset();
  ss_in.reset();
  ht_in.reset();
  st_in.reset();
  dp.reset();
  // Entries left by this launcher's own dead processes (a SIGKILL leaves them): removed by name.
  for (const auto& [pid, names] : shm_of) rep.shm_removed += removeOwnShm(names);
  // Left behind: this lab's (an entry one of its processes, or this launcher, had open) and, apart,
  // the new unheld entries no process of this lab was seen holding (another Fast DDS program on
  // this machine, e.g. a parallel lab whose process was killed: they used to be counted as this
  // lab's).
  for (const std::string& name : orphaned(shm_before)) {
    const bool ours = own_shm.count(name) > 0 ||
                      std::any_of(shm_of.begin(), shm_of.end(), [&](const auto& p) { return p.second.count(name) > 0; });
    ++(ours ? rep.shm_left : rep.shm_left_other);
  }

  // The report.
  rep.recording = lab.recording;
  rep.scene = scene.name;
  rep.solver = solver;
  rep.mode = lockstep ? "lockstep" : "live";
  rep.lockstep = lockstep;
  rep.hands = C;
  rep.triangles = scene.god_triangles;
  rep.reference_triangles = scene.reference_triangles;
  rep.frame_rate_hz = rate;
  rep.physics_hz = no_physics ? 0 : physics_hz;
  rep.stale_after_s = stale_after;
  rep.silent_after_s = silent_after;
  // Frames expected (Delivery::expected): the replay's frames for the last ingest run, unless its
  // final count says --duration stopped it (not a signal, a kill, a missing final heartbeat);
  // a run cut short, and a live source: the frames published.
  commitBlind(true);  // (held windows at the end: no service died or froze since they closed)
  const bool cut_by_duration = source_tally.lastRunStoppedByDuration();
  const std::map<std::uint64_t, std::uint64_t> expected = delivery.expected(n_frames, cut_by_duration);
  rep.ingest_runs = delivery.runs().size();
  rep.have_source = source_tally.any();
  rep.source = source_tally.total();
  rep.source_runs = source_tally.runs();
  std::uint64_t min_fresh = ~0ull;
  for (size_t c = 0; c < C; ++c) {
    rep.clusters.push_back(lab.clusters[c].name);
    rep.delivery.push_back(delivery.counts(c, expected));
    min_fresh = std::min(min_fresh, rep.delivery.back().fresh);
    rep.expected_frames = rep.delivery.back().expected;
  }
  if (C == 0) min_fresh = 0;
  rep.frames_complete = lockstep ? next_frame - 1 : min_fresh;
  rep.replay_span_s = std::chrono::duration<double>(t_last_state - t_first_state).count();
  // Frames per second from counts: fresh frames (every cluster) over first to last fresh state.
  rep.frames_per_s = rep.frames_complete > 1 && rep.replay_span_s > 0 ? static_cast<double>(rep.frames_complete - 1) / rep.replay_span_s : 0.0;
  rep.latency_median_us = percentile(latency.latency().values(), 0.5);
  rep.latency_p99_us = percentile(latency.latency().values(), 0.99);
  rep.latency_max_us = latency.latency().max();
  rep.latency_samples = latency.latency().count();
  rep.stale_age_median_us = percentile(latency.staleAges().values(), 0.5);
  rep.stale_age_p99_us = percentile(latency.staleAges().values(), 0.99);
  rep.stale_age_max_us = latency.staleAges().max();
  rep.stale_age_samples = latency.staleAges().count();
  // step_us as godhand-bench means it: the compute time of a frame (the stages' own times, every
  // hand, the scene), without the transport; the end-to-end figure is latency_us.
  rep.step_median_us = percentile(st_total.values(), 0.5);
  rep.step_p99_us = percentile(st_total.values(), 0.99);
  rep.step_max_us = st_total.max();
  rep.stages_us = {{"contacts", percentile(st_contacts.values(), 0.5)}, {"assembly", percentile(st_assembly.values(), 0.5)},
                   {"solve", percentile(st_solve.values(), 0.5)},       {"integrate", percentile(st_integrate.values(), 0.5)},
                   {"ccd", percentile(st_ccd.values(), 0.5)},           {"merge", percentile(st_merge.values(), 0.5)},
                   {"scene", percentile(st_scene.values(), 0.5)}};
  rep.margin_m = margin;
  rep.plausibility = metrics->summary();
  rep.have_plausibility = true;
  // The free tracking error has one definition (run_metrics.h), as in godhand-bench.
  rep.free_err_max_m = rep.plausibility.all.free_tracking_error_m.max;
  rep.free_err_median_m = rep.plausibility.all.free_tracking_error_m.median;
  rep.silent = watchdog.episodes();
  for (Watchdog::Episode& e : rep.silent) {  // times from the replay start, as every other time
    const double off = t_replay == Clock::time_point{} ? 0.0 : std::chrono::duration<double>(t_replay - t_start).count();
    e.start_s -= off;
    if (e.end_s >= 0) e.end_s -= off;
  }
  rep.launcher_pauses = watchdog.pauses();
  rep.launcher_pause_count = watchdog.pauseCount();
  for (Watchdog::Pause& p : rep.launcher_pauses)
    p.start_s -= t_replay == Clock::time_point{} ? 0.0 : std::chrono::duration<double>(t_replay - t_start).count();
  rep.drills = drill_reports;
  rep.restarts = recovery.restarts();
  rep.stale_first_s = recovery.staleFirst();
  rep.stale_last_s = recovery.staleLast();
  rep.replay_end_s = recovery.replayEnd();
  rep.restarts_dropped = recovery.dropped();
  for (size_t i = 0; i < drills.size(); ++i)
    if (!drill_fired[i]) rep.drills[i] = {drills[i].spec, drills[i].service, -1.0, -1.0, 0};
  rep.late_ms = rep.late_ms;
  rep.failure = failure;
  rep.foreign = foreign;
  rep.partition = partition;
  rep.have_hash = lockstep;
  rep.result_hash = hash.h;
  rep.checked = check;
  rep.loss_budget = loss_budget;
  if (check) {
    RunFigures f;
    f.lockstep = lockstep;
    f.loss_budget = loss_budget;
    for (size_t c = 0; c < C; ++c) f.delivery[rep.clusters[c]] = rep.delivery[c];
    f.dead_at_end = rep.dead_at_end;
    f.late_joiner_ok = rep.late_states == C && rep.late_description;
    for (size_t i = 0; i < drills.size(); ++i)
      if (!drill_fired[i]) f.drills_not_done.push_back(drills[i].spec);
    f.failure = failure;
    f.foreign = foreign;
    f.penetration_max = rep.penetration_max_m;
    f.margin = margin;
    f.joint_gap_max = rep.joint_gap_max_m;
    f.solver_failures = rep.solver_failures;
    f.states = rep.states;
    rep.verdict = evaluateRun(f);
    // The plausibility rule of godhand-bench's --check, in lock-step (every frame is seen; live
    // runs lose frames, so their windows are figures, not a verdict).
    std::string why;
    // The metrics saw no tracked hand although tracked targets came: the states could not be
    // scored against them (the scene down, the targets late), which is not the source's fault.
    if (rep.plausibility.all.tracked == 0 && tracked_targets_seen > 0 && !rep.plausibility.failure.empty())
      rep.plausibility.failure = "no hand state could be scored against its targets (" + std::to_string(tracked_targets_seen) +
                                 " tracked HandTargets arrived; the scene down or the targets late?)";
    if (lockstep && !plausible(rep.plausibility, &why)) {
      rep.verdict.ok = false;
      rep.verdict.reasons.push_back("not plausible: " + why);
    } else if (!lockstep && rep.plausibility.all.tracked == 0 && !rep.plausibility.failure.empty()) {
      rep.verdict.ok = false;  // live too: a run that tracked no hand measured nothing
      rep.verdict.reasons.push_back(rep.plausibility.failure);
    }
  }
  printSummary(rep);

  if (!json_out.empty()) {
    std::ofstream out(json_out);
    out << reportJson(rep).dump(2) << "\n";
    if (!out) {
      std::fprintf(stderr, "godhand-launch: %s: cannot write\n", json_out.c_str());
      return kExitConfig;
    }
  }
  if (!failure.empty()) exit_code = kExitFailed;
  if (own_log_dir && failure.empty() && rep.clean_shutdown) {
    for (const ChildSpec& c : specs) std::remove(c.log_file.c_str());
    std::remove((log_dir + "/scene.state").c_str());
    if (!partition_file.empty()) std::remove(partition_file.c_str());
    rmdir(log_dir.c_str());
  }
  if (check) {
    std::printf("check: %s (penetration <= %.1e m, joint gap <= 1e-6 m, no solver failures, %s, every service running at the end, late joiner served)\n",
                rep.verdict.ok ? "ok" : "FAILED", margin,
                lockstep ? "every frame fresh" : ("lost frames <= " + fmt17(loss_budget * 100) + " % per cluster").c_str());
    for (const std::string& why : rep.verdict.reasons) std::printf("check:   %s\n", why.c_str());
    if (!rep.verdict.ok) exit_code = kExitFailed;
  }
  return exit_code;
}
