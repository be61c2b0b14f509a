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

#include <chrono>
#include <cmath>
#include <cstdio>
#include <dirent.h>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/cli.h"
#include "common/lab_config.h"
#include "common/signals.h"
#include "common/supervisor.h"
#include "dds/dds.h"
#include "dds/topics.h"
#include "godhand.h"
#include "math/stats.h"
#include "pipeline/collision_world.h"
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

// A shared-memory entry is left behind when nobody holds its lock any more (what `fastdds shm
// clean` removes): entries of other, live Fast DDS processes (parallel runs) are not counted.
size_t orphaned(const std::set<std::string>& before) {
  size_t n = 0;
  for (const std::string& name : shmSegments()) {
    if (before.count(name) || name.size() < 3 || name.compare(name.size() - 3, 3, "_el") == 0) continue;
    const std::string el = "/dev/shm/" + name + "_el";
    const int fd = open(el.c_str(), O_RDWR | O_CLOEXEC);
    if (fd < 0) continue;
    if (flock(fd, LOCK_EX | LOCK_NB) == 0) {
      ++n;
      flock(fd, LOCK_UN);
    }
    close(fd);
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

}  // namespace

int main(int argc, char** argv) {
  Cli cli("godhand-launch", kSynopsis);
  std::string lab_file = std::string(GODHAND_DEPLOY_DIR) + "/lab/local.pbtxt";
  std::string recording, scene_file, json_out, bin_dir = exeDir(), log_dir, kill_spec, solver = "exact";
  int domain = -1, frames = 0, physics_hz = 240;
  bool lockstep = false, quiet = false, check = false, restart = false, no_physics = false;
  double speed = 1.0, restart_delay = 0.5, deadline = 0.0, start_timeout = 60.0;
  cli.option("--lab", &lab_file, "FILE", "lab configuration");
  std::string host_name;  // --host: that lab host's services (and profiles) instead of this machine's
  cli.option("--host", &host_name, "NAME", "start the services of the lab's host NAME, with its profiles (default: this machine's)");
  cli.option("--domain", &domain, "N", "DDS domain id 0..232; -1 = the lab's");
  cli.flag("--lockstep", &lockstep, "lock-step: deterministic, every stage waits for each frame's inputs");
  cli.option("--recording", &recording, "FILE", "tracker recording (default: the lab's)");
  cli.option("--scene", &scene_file, "FILE", "scene file (default: the lab's)");
  cli.option("--frames", &frames, "N", "replay only the first N frames (0: all)");
  cli.option("--json", &json_out, "OUT", "write the report (godhand-bench's format plus latency) to OUT");
  cli.option("--solver", &solver, "exact|pgs", "NNLS solver of the hand solvers");
  cli.option("--physics-hz", &physics_hz, "HZ", "Bullet's fixed step rate");
  cli.flag("--no-physics", &no_physics, "no Bullet: dynamic objects stay put");
  cli.option("--speed", &speed, "X", "live replay speed factor");
  cli.option("--deadline", &deadline, "S", "lock-step input deadline of every stage; 0 = the lab's");
  cli.option("--start-timeout", &start_timeout, "S", "how long the services may take to come up");
  cli.option("--bin-dir", &bin_dir, "DIR", "where the godhand-* executables are (default: next to this one)");
  cli.option("--log-dir", &log_dir, "DIR", "keep the service logs here (default: a fresh directory under /tmp, removed after a clean run)");
  cli.flag("--restart", &restart, "live: restart a service that dies (after --restart-delay)");
  cli.option("--restart-delay", &restart_delay, "S", "delay before a restart");
  cli.option("--kill", &kill_spec, "SERVICE@S", "fault drill: SIGKILL SERVICE S seconds into the run (e.g. scene@2)");
  cli.flag("--check", &check, "exit 1 unless penetration <= margin, joint gap <= 1e-6 m, no solver failure, no frame lost (lock-step)");
  cli.flag("--quiet", &quiet, "no per-second lines");
  cli.parse(argc, argv);
  if (frames < 0) cli.fail("--frames must be >= 0");
  if (!(speed >= 0.01 && speed <= 1000.0)) cli.fail("--speed must be in [0.01, 1000]");
  if (!(restart_delay >= 0.0 && restart_delay < 60.0)) cli.fail("--restart-delay must be in [0, 60)");
  if (!(start_timeout > 0.0 && start_timeout <= 3600.0)) cli.fail("--start-timeout must be in (0, 3600] s");
  if (!(deadline >= 0.0 && deadline <= 3600.0)) cli.fail("--deadline must be in [0, 3600] s");
  if (solver != "exact" && solver != "pgs") cli.fail("--solver must be exact or pgs");
  if (physics_hz < 10 || physics_hz > 100000) cli.fail("--physics-hz must be in [10, 100000]");
  if (domain < -1 || domain > 232) cli.fail("--domain must be in 0..232");
  std::string kill_service;
  double kill_at = -1.0;
  if (!kill_spec.empty()) {
    const size_t at = kill_spec.find('@');
    char* end = nullptr;
    if (at == std::string::npos) cli.fail("--kill: expected SERVICE@SECONDS, got '" + kill_spec + "'");
    kill_service = kill_spec.substr(0, at);
    kill_at = std::strtod(kill_spec.c_str() + at + 1, &end);
    if (!end || *end || !(kill_at >= 0.0) || !std::isfinite(kill_at)) cli.fail("--kill: bad time in '" + kill_spec + "'");
  }
  installStopHandlers();

  LabConfig lab;
  try {
    lab = loadLab(lab_file);
    if (!host_name.empty()) selectHost(lab, host_name);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  if (domain >= 0) lab.domain_id = domain;
  if (!recording.empty()) lab.recording = recording;
  if (!scene_file.empty()) lab.scene = scene_file;
  if (lab.recording.empty()) cli.fail("no recording: give --recording or set one in " + lab.file);
  if (!kill_service.empty() && !lab.service(kill_service)) cli.fail("--kill: no service '" + kill_service + "' in the lab");
  if (kill_service == "ingest") cli.fail("--kill: the ingest ends the run; kill scene, resolver or solver/NAME");

  // The monitor's inputs: the recording (frame count, rate) and the scene (penetration).
  double rate = 0.0;
  std::int64_t n_frames = 0;
  Scene scene;
  try {
    auto src = bridges::openSource(lab.recording, frames);
    rate = src->nominalRate();
    n_frames = src->remaining();
    scene = loadScene(lab.scene);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  CollisionWorld world(scene);
  const size_t C = lab.clusters.size();
  const double margin = RowParams{}.margin;

  // Service command lines.
  const bool own_log_dir = log_dir.empty();  // removed again after a clean run
  if (own_log_dir) log_dir = "/tmp/godhand-launch-" + std::to_string(getpid());
  mkdir(log_dir.c_str(), 0755);
  struct stat st{};
  if (stat(log_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) cli.fail("--log-dir " + log_dir + ": cannot create");
  std::vector<ChildSpec> specs;
  for (const LabService& s : lab.services) {
    if (!runsHere(s, host_name)) {
      std::printf("launch: %s runs on %s (not started here)\n", s.name.c_str(), s.host.c_str());
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
    ht_in = std::make_unique<dds::Reader<msg::HandTarget>>(*dp, dds::topic::kHandTarget, stream_profile);
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

  std::printf("launch: lab '%s' (%s), domain %u, %s mode, %zu cluster(s), recording %s (%lld frames at %.2f Hz), scene '%s'\n",
              lab.name.c_str(), lab.file.c_str(), lab.domain_id, lockstep ? "lock-step" : "live", C, lab.recording.c_str(),
              static_cast<long long>(n_frames), rate, scene.name.c_str());
  std::printf("launch: service logs in %s\n", log_dir.c_str());
  std::fflush(stdout);
  std::map<std::string, msg::ServiceStatus> status;
  Supervisor sup;
  const Clock::time_point t_start = Clock::now();
  try {
    for (const ChildSpec& c : specs)
      if (c.name != "ingest") sup.start(c);
    // The ingest last, once every other service runs and this monitor is matched with the
    // resolver's HandState and the scene's SceneState writers: a monitor that matched late would
    // miss the first frames (a lock-step run of a short recording is over in a second or two).
    const Clock::time_point until = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(start_timeout));
    for (;;) {
      msg::ServiceStatus s;
      while (st_in->take(s)) status[s.service().to_string()] = s;
      bool ready = hs_in->matched() >= 1 && ss_in->matched() >= 1;
      for (const LabService& ls : lab.services)
        if (ls.kind != pb::Service::INGEST) ready = ready && status.count(ls.name) && status[ls.name].state() == "running";
      if (ready) break;
      std::string dead;
      for (const ChildStatus& c : sup.poll()) dead += " " + c.name;
      if (!dead.empty() || stopRequested() || Clock::now() >= until) {
        std::string why = !dead.empty() ? "service(s) ended during start-up:" + dead
                        : stopRequested() ? "stopped during start-up" : "services not running after " + fmt17(start_timeout) + " s";
        for (const ChildSpec& c : specs) why += "\n  " + c.name + ":\n" + tail(c.log_file, 6);
        sup.stop(std::chrono::milliseconds(3000));
        std::fprintf(stderr, "godhand-launch: %s\n", why.c_str());
        return stopRequested() ? 0 : 1;
      }
      dp->waitForData(Clock::now() + std::chrono::milliseconds(50));
    }
    for (const ChildSpec& c : specs)
      if (c.name == "ingest") sup.start(c);
  } catch (const std::exception& e) {
    sup.stop(std::chrono::milliseconds(3000));
    std::fprintf(stderr, "godhand-launch: %s\n", e.what());
    return 2;
  }

  // Measurements.
  std::vector<double> latency_us, window_latency;
  std::vector<double> st_contacts, st_assembly, st_solve, st_integrate, st_ccd, st_merge, st_scene;
  double pen_max = 0, gap_max = 0, free_err_max = 0, kkt_max = 0, window_pen = 0;
  std::vector<double> free_err;
  long contacts_max = 0, clipped = 0, lifted = 0, inside = 0, failures = 0, inexact = 0, stale = 0, pushouts = 0, states = 0, held = 0;
  std::vector<double> st_total;  // compute time per frame: the stages' own times, no transport
  double last_scene_us = 0;
  ResultHash hash;
  std::map<std::uint64_t, FrameHands> pending;          // lock-step: frame -> hands
  std::map<std::uint64_t, SceneSnapshot> scenes;        // lock-step: frame -> scene
  std::map<std::uint64_t, std::vector<msg::HandTarget>> targets;  // frame -> per cluster
  std::uint64_t next_frame = 1, last_fresh_frame = 0;
  double stale_first_s = -1, stale_last_s = -1, resumed_s = -1, killed_s = -1, restarted_s = -1, scene_back_s = -1;
  std::uint64_t last_scene_step = 0;
  std::vector<unsigned char> hand_stale(C, 0);
  bool killed = false;
  int exit_code = 0;
  std::string failure;

  Clock::time_point t_first_state{}, t_last_state{};
  bool run_over = false;  // the ingest is done: held hands re-published after the run are not counted
  auto measure = [&](const msg::HandState& h, const SceneSnapshot* snap, double lat_us) {
    if (h.held() && run_over) return;
    if (!h.held()) {
      if (t_first_state == Clock::time_point{}) t_first_state = Clock::now();
      t_last_state = Clock::now();
    }
    ++states;
    if (snap)
      for (const ObjectMotion& o : snap->objects) world.setObjectPose(o.index, o.X);
    if (lat_us > 0) {
      latency_us.push_back(lat_us);
      window_latency.push_back(lat_us);
    }
    if (h.stale()) ++stale;
    if (h.held()) {  // the last result again: its figures were counted when it was new
      ++held;
      return;
    }
    if (!lockstep)
      st_total.push_back(h.solver_times().contacts_us() + h.solver_times().assembly_us() + h.solver_times().solve_us() +
                         h.solver_times().integrate_us() + h.ccd_us() + h.merge_us() + last_scene_us);
    if (h.toc() < 1.0) ++clipped;
    if (h.lifted_start()) ++lifted;
    if (h.started_inside()) ++inside;
    if (h.flags() & kFlagSolverFailed) ++failures;
    if (h.flags() & kFlagSolverInexact) ++inexact;
    if (!h.started()) return;
    double pen = 0;
    for (size_t b = 0; b < h.poses().size() && b < h.shapes().size(); ++b) {
      Shape s;
      s.type = static_cast<ShapeType>(std::min<int>(h.shapes()[b].type(), 2));
      s.radius = h.shapes()[b].radius();
      s.half_length = h.shapes()[b].half_length();
      s.half_extents = Vec3(h.shapes()[b].half_extents()[0], h.shapes()[b].half_extents()[1], h.shapes()[b].half_extents()[2]);
      pen = std::max(pen, world.penetration(s, svc::fromWire(h.poses()[b])));
    }
    pen_max = std::max(pen_max, pen);
    window_pen = std::max(window_pen, pen);
    gap_max = std::max(gap_max, h.joint_gap());
    if (h.tracked()) {
      kkt_max = std::max(kkt_max, h.kkt());
      if (!h.loaded()) {  // free space: the distance to the tracked targets
        auto it = targets.find(h.stamp().frame());
        if (it != targets.end() && h.hand() < it->second.size()) {
          const msg::HandTarget& t = it->second[h.hand()];
          if (t.tracked() && t.targets().size() == h.poses().size()) {
            double e = 0;
            for (size_t b = 0; b < t.targets().size(); ++b)
              if (b < t.driven().size() && t.driven()[b])
                e = std::max(e, (svc::fromWire(h.poses()[b]).p - svc::fromWire(t.targets()[b]).p).norm());
            free_err.push_back(e);
            free_err_max = std::max(free_err_max, e);
          }
        }
      }
    }
  };
  auto drain = [&] {
    msg::ServiceStatus s;
    while (st_in->take(s)) status[s.service().to_string()] = s;
    msg::HandTarget t;
    while (ht_in->take(t))
      if (t.hand() < C) {
        auto& v = targets[t.stamp().frame()];
        v.resize(C);
        v[t.hand()] = t;
      }
    while (targets.size() > 512) targets.erase(targets.begin());
    msg::SceneState ss;
    std::string why;
    while (ss_in->take(ss)) {
      SceneSnapshot snap;
      if (!svc::fromWire(ss, static_cast<int>(scene.objects.size()), &snap, &why)) continue;
      pushouts += snap.pushouts;
      last_scene_us = snap.step_us;
      if (restarted_s >= 0 && scene_back_s < 0 && snap.step < last_scene_step) scene_back_s = secondsSince(t_start);
      last_scene_step = snap.step;
      if (lockstep) scenes[snap.frame] = snap;
      else
        for (const ObjectMotion& o : snap.objects) world.setObjectPose(o.index, o.X);
    }
    msg::HandState h;
    while (hs_in->take(h)) {
      const double lat = h.stamp().source_time_ns() > 0 ? static_cast<double>(svc::nowNs() - h.stamp().source_time_ns()) * 1e-3 : 0.0;
      if (h.hand() >= C) continue;
      if (lockstep) {
        FrameHands& f = pending[h.stamp().frame()];
        f.states.resize(C);
        f.have.resize(C, 0);
        f.states[h.hand()] = h;
        f.have[h.hand()] = 1;
        if (lat > 0) {
          latency_us.push_back(lat);
          window_latency.push_back(lat);
        }
      } else {
        measure(h, nullptr, lat);
        const double now_s = secondsSince(t_start);
        hand_stale[h.hand()] = h.stale();
        bool any_stale = false;
        for (unsigned char st_h : hand_stale) any_stale = any_stale || st_h;
        if (h.stale()) {
          if (stale_first_s < 0) stale_first_s = now_s;
          stale_last_s = now_s;
        } else {
          // Resumed: after the restart, every hand's newest state is fresh again.
          if (stale_last_s >= 0 && resumed_s < 0 && restarted_s >= 0 && !any_stale) resumed_s = now_s;
          last_fresh_frame = std::max<std::uint64_t>(last_fresh_frame, h.stamp().frame());
        }
      }
    }
    // Lock-step: frames complete in order (every cluster's HandState(k) and SceneState(k)).
    while (lockstep) {
      auto it = pending.find(next_frame);
      if (it == pending.end() || !scenes.count(next_frame)) break;
      bool all = true;
      for (unsigned char c : it->second.have) all = all && c;
      if (!all) break;
      const SceneSnapshot& snap = scenes[next_frame];
      double contacts = 0, c_us = 0, a_us = 0, s_us = 0, i_us = 0, ccd = 0, merge = 0;
      for (size_t c = 0; c < C; ++c) {
        const msg::HandState& hsc = it->second.states[c];
        measure(hsc, c == 0 ? &snap : nullptr, 0.0);
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
      contacts_max = std::max(contacts_max, static_cast<long>(contacts));
      st_contacts.push_back(c_us);
      st_assembly.push_back(a_us);
      st_solve.push_back(s_us);
      st_integrate.push_back(i_us);
      st_ccd.push_back(ccd);
      st_merge.push_back(merge);
      st_scene.push_back(snap.step_us);
      st_total.push_back(c_us + a_us + s_us + i_us + ccd + merge + snap.step_us);
      pending.erase(it);
      scenes.erase(scenes.begin(), scenes.upper_bound(next_frame));
      targets.erase(targets.begin(), targets.upper_bound(next_frame));
      ++next_frame;
    }
  };

  // Run until the ingest is done (or a failure, or a stop signal).
  Clock::time_point last_print = Clock::now();
  bool ingest_done = false;
  std::map<std::string, Clock::time_point> restarts;  // service -> when to restart it
  while (!stopRequested()) {
    dp->waitForData(Clock::now() + std::chrono::milliseconds(20));
    drain();
    for (const ChildStatus& c : sup.poll()) {
      if (c.name == "ingest") {
        ingest_done = true;
        if (!c.exited || c.exit_code != 0) {
          failure = "ingest ended with " + (c.exited ? "exit code " + std::to_string(c.exit_code) : "signal " + std::to_string(c.term_signal));
          const ChildSpec* sp = nullptr;
          for (const ChildSpec& s : specs)
            if (s.name == c.name) sp = &s;
          if (sp) failure += "\n" + tail(sp->log_file, 12);
        }
        continue;
      }
      const bool drill = killed && c.name == kill_service && c.term_signal == SIGKILL;
      if ((restart || drill) && !lockstep) {
        std::printf("launch: %s ended (%s); restarting in %.1f s\n", c.name.c_str(),
                    c.exited ? ("exit " + std::to_string(c.exit_code)).c_str() : ("signal " + std::to_string(c.term_signal)).c_str(),
                    restart_delay);
        restarts[c.name] = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(restart_delay));
      } else if (failure.empty()) {
        failure = c.name + " ended unexpectedly (" + (c.exited ? "exit code " + std::to_string(c.exit_code) : "signal " + std::to_string(c.term_signal)) + ")";
        for (const ChildSpec& s : specs)
          if (s.name == c.name) failure += "\n" + tail(s.log_file, 12);
      }
    }
    if (!failure.empty()) break;
    for (auto it = restarts.begin(); it != restarts.end();) {
      if (Clock::now() < it->second) {
        ++it;
        continue;
      }
      sup.restart(it->first);
      restarted_s = secondsSince(t_start);
      std::printf("launch: %s restarted at %.2f s\n", it->first.c_str(), restarted_s);
      it = restarts.erase(it);
    }
    if (kill_at >= 0 && !killed && secondsSince(t_start) >= kill_at && states > 0) {
      sup.signal(kill_service, SIGKILL);
      killed = true;
      killed_s = secondsSince(t_start);
      std::printf("launch: fault drill: SIGKILL %s at %.2f s\n", kill_service.c_str(), killed_s);
    }
    if (ingest_done) {
      run_over = true;
      // Let the last states arrive (lock-step: until every frame is in, bounded).
      const Clock::time_point until = Clock::now() + std::chrono::seconds(lockstep ? 5 : 1);
      while (Clock::now() < until && (!lockstep || next_frame <= static_cast<std::uint64_t>(n_frames))) {
        dp->waitForData(Clock::now() + std::chrono::milliseconds(20));
        drain();
      }
      break;
    }
    if (quiet && window_latency.size() > 100000) window_latency.clear();
    if (!quiet && secondsSince(last_print) >= 1.0) {
      last_print = Clock::now();
      std::string rates;
      for (const auto& s : status) {
        char b[96];
        std::snprintf(b, sizeof b, "%s%s %.0f Hz", rates.empty() ? "" : ", ", s.first.c_str(), s.second.rate_hz());
        rates += b;
      }
      std::printf("launch: t %5.1f s | %s | latency median %.0f us p99 %.0f us | penetration %.4f mm | states %ld stale %ld\n",
                  secondsSince(t_start), rates.c_str(), percentile(window_latency, 0.5), percentile(window_latency, 0.99),
                  window_pen * 1e3, states, stale);
      std::fflush(stdout);
      window_latency.clear();
      window_pen = 0;
    }
  }
  const double run_s = secondsSince(t_start);

  // The services' last heartbeats (period 0.5 s) carry their final counters.
  if (failure.empty() && !stopRequested()) {
    const Clock::time_point until = Clock::now() + std::chrono::milliseconds(1200);
    while (Clock::now() < until) {
      dp->waitForData(Clock::now() + std::chrono::milliseconds(50));
      drain();
    }
  }

  // Late joiner: a fresh participant must get every cluster's last HandState and the scene.
  double late_ms = -1;
  size_t late_states = 0;
  bool late_description = false;
  if (failure.empty() && !stopRequested()) {
    try {
      dds::Participant late(dds::Options{static_cast<int>(lab.domain_id), lab.profiles, dds::profile::kParticipant, "launch/late-joiner"});
      dds::Reader<msg::HandState> lh(late, dds::topic::kHandState, state_profile);
      dds::Reader<msg::SceneDescription> ld(late, dds::topic::kSceneDescription, dds::profile::kState);
      const Clock::time_point t0 = Clock::now();
      std::set<std::uint32_t> got;
      msg::HandState h;
      msg::SceneDescription d;
      while (secondsSince(t0) < 5.0 && (got.size() < C || !late_description)) {
        late.waitForData(Clock::now() + std::chrono::milliseconds(50));
        while (lh.take(h)) got.insert(h.hand());
        while (ld.take(d)) late_description = d.objects().size() == scene.objects.size();
      }
      late_states = got.size();
      if (got.size() == C && late_description) late_ms = secondsSince(t0) * 1e3;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "launch: late joiner: %s\n", e.what());
    }
  }

  // Stop everything, check nothing is left behind.
  sup.stop(std::chrono::milliseconds(5000));
  std::string exits;
  bool clean_exits = true;
  for (const ChildStatus& c : sup.status()) {
    const bool ok = (c.exited && c.exit_code == 0) || (!c.exited && c.term_signal == SIGTERM);
    if (!ok) clean_exits = false;
    exits += " " + c.name + (c.exited ? "=" + std::to_string(c.exit_code) : "=sig" + std::to_string(c.term_signal));
  }
  hs_in.reset();
  ss_in.reset();
  ht_in.reset();
  st_in.reset();
  dp.reset();
  size_t shm_killed = 0;
  if (killed) {  // the killed process could not release its segments: count them, then clean up
    shm_killed = orphaned(shm_before);
    if (std::system("fastdds shm clean >/dev/null 2>&1") != 0) std::fprintf(stderr, "launch: fastdds shm clean failed\n");
  }
  const size_t shm_left = orphaned(shm_before);

  // Summary.
  const std::uint64_t frames_done = lockstep ? next_frame - 1 : last_fresh_frame;
  const double lat_med = percentile(latency_us, 0.5), lat_p99 = percentile(latency_us, 0.99);
  // Frames per second from the first to the last HandState received (startup excluded).
  const double span_s = std::chrono::duration<double>(t_last_state - t_first_state).count();
  const double fps = frames_done > 1 && span_s > 0 ? static_cast<double>(frames_done - 1) / span_s : 0.0;
  std::printf("launch: %s run of %.1f s: %llu of %lld frames %s, %ld hand states received (%ld stale)\n",
              lockstep ? "lock-step" : "live", run_s, static_cast<unsigned long long>(frames_done),
              static_cast<long long>(n_frames), lockstep ? "complete" : "seen fresh", states, stale);
  std::printf("  end-to-end latency (tracker sample -> HandState here): median %.0f us, p99 %.0f us, max %.0f us; %.1f frames/s\n",
              lat_med, lat_p99, percentile(latency_us, 1.0), fps);
  for (const auto& s : status)
    std::printf("  %-14s frame %llu, source->output %.0f us, in %llu, out %llu, rejected %llu, late %llu, deadline misses %llu, state %s\n",
                s.first.c_str(), static_cast<unsigned long long>(s.second.frame()), s.second.latency_median_us(),
                static_cast<unsigned long long>(s.second.samples_in()), static_cast<unsigned long long>(s.second.samples_out()),
                static_cast<unsigned long long>(s.second.rejected()), static_cast<unsigned long long>(s.second.late()),
                static_cast<unsigned long long>(s.second.deadline_misses()), s.second.state().c_str());
  std::printf("  penetration max %.4f mm (margin %.3f mm), joint gap max %.2e m, free tracking error max %.2f mm, clipped %ld, scene push-outs %ld\n",
              pen_max * 1e3, margin * 1e3, gap_max, free_err_max * 1e3, clipped, pushouts);
  if (killed)
    std::printf("  fault drill: %s killed at %.2f s, restarted at %.2f s, stale from %.2f to %.2f s, fresh again at %.2f s (every hand; %.2f s after the restart; a restarted scene's first state seen at %.2f s)\n",
                kill_service.c_str(), killed_s, restarted_s, stale_first_s, stale_last_s, resumed_s,
                resumed_s >= 0 && restarted_s >= 0 ? resumed_s - restarted_s : -1.0, scene_back_s);
  std::printf("  late joiner: %zu of %zu HandStates and the SceneDescription %s%s\n", late_states, C,
              late_description ? "received" : "NOT received",
              late_ms >= 0 ? (" in " + std::to_string(static_cast<int>(late_ms)) + " ms").c_str() : "");
  std::printf("  shutdown:%s; shared-memory segments left: %zu%s\n", exits.c_str(), shm_left,
              killed ? (" (" + std::to_string(shm_killed) + " orphaned by the killed process, removed with fastdds shm clean)").c_str() : "");
  if (lockstep) std::printf("  result hash %016llx\n", static_cast<unsigned long long>(hash.h));
  if (!failure.empty()) std::printf("launch: FAILED: %s\n", failure.c_str());

  if (!json_out.empty()) {
    nlohmann::json j;
    j["recording"] = lab.recording;
    j["scene"] = scene.name;
    j["frames"] = frames_done;
    j["hands"] = C;
    j["triangles"] = scene.god_triangles;
    j["reference_triangles"] = scene.reference_triangles;
    j["frame_rate_hz"] = rate;
    j["solver"] = solver;
    j["physics_hz"] = no_physics ? 0 : physics_hz;
    j["mode"] = lockstep ? "lockstep" : "live";
    // step_us as godhand-bench means it: the compute time of a frame (the stages' own times, every
    // hand, the scene), without the transport; the end-to-end figure is latency_us.
    const double step_med = percentile(st_total, 0.5);
    j["step_us"] = {{"median", step_med}, {"p99", percentile(st_total, 0.99)}, {"max", percentile(st_total, 1.0)}};
    j["hz_median"] = step_med > 0 ? 1e6 / step_med : 0.0;
    j["held_states"] = held;
    j["latency_us"] = {{"median", lat_med}, {"p99", lat_p99}, {"max", percentile(latency_us, 1.0)}, {"samples", latency_us.size()}};
    j["run_s"] = run_s;
  j["frames_per_s"] = fps;
    j["stages_us"] = {{"contacts", percentile(st_contacts, 0.5)}, {"assembly", percentile(st_assembly, 0.5)},
                      {"solve", percentile(st_solve, 0.5)},       {"integrate", percentile(st_integrate, 0.5)},
                      {"ccd", percentile(st_ccd, 0.5)},           {"merge", percentile(st_merge, 0.5)},
                      {"scene", percentile(st_scene, 0.5)}};
    j["penetration_max_m"] = pen_max;
    j["margin_m"] = margin;
    j["joint_gap_max_m"] = gap_max;
    j["free_tracking_error_max_m"] = free_err_max;
    j["free_tracking_error_median_m"] = percentile(free_err, 0.5);
    j["contacts_max"] = contacts_max;
    j["kkt_residual_max"] = kkt_max;
    j["solver_failures"] = failures;
    j["inexact_solves"] = inexact;
    j["clipped_steps"] = clipped;
    j["lifted_starts"] = lifted;
    j["started_inside"] = inside;
    j["scene_pushouts"] = pushouts;
    j["hand_states"] = states;
    j["stale_states"] = stale;
    nlohmann::json services = nlohmann::json::object();
    for (const auto& s : status)
      services[s.first] = {{"frame", s.second.frame()}, {"samples_in", s.second.samples_in()}, {"samples_out", s.second.samples_out()},
                           {"rejected", s.second.rejected()}, {"late", s.second.late()}, {"deadline_misses", s.second.deadline_misses()}};
    j["services"] = services;
    j["late_joiner"] = {{"hand_states", late_states}, {"scene_description", late_description}, {"ms", late_ms}};
    j["shm_segments_left"] = shm_left;
  j["shm_segments_orphaned_by_kill"] = shm_killed;
    j["clean_shutdown"] = clean_exits;
    if (killed)
      j["fault_drill"] = {{"service", kill_service}, {"killed_s", killed_s}, {"restarted_s", restarted_s}, {"stale_first_s", stale_first_s},
                          {"stale_last_s", stale_last_s}, {"resumed_s", resumed_s}, {"scene_back_s", scene_back_s},
                          {"resume_after_restart_s", resumed_s >= 0 && restarted_s >= 0 ? resumed_s - restarted_s : -1.0}};
    if (lockstep) {
      char hex[32];
      std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash.h));
      j["result_hash"] = hex;
    }
    j["failure"] = failure;
    std::ofstream out(json_out);
    out << j.dump(2) << "\n";
    if (!out) {
      std::fprintf(stderr, "godhand-launch: %s: cannot write\n", json_out.c_str());
      return 2;
    }
  }
  if (!failure.empty()) exit_code = 1;
  if (own_log_dir && failure.empty() && clean_exits) {
    for (const ChildSpec& c : specs) std::remove(c.log_file.c_str());
    rmdir(log_dir.c_str());
  }
  if (check) {
    const bool frames_ok = !lockstep || frames_done == static_cast<std::uint64_t>(n_frames);
    const bool ok = failure.empty() && pen_max <= margin && gap_max <= 1e-6 && failures == 0 && frames_ok && states > 0;
    std::printf("check: %s (penetration <= %.1e m, joint gap <= 1e-6 m, no solver failures%s)\n", ok ? "ok" : "FAILED", margin,
                lockstep ? ", every frame" : "");
    if (!ok) exit_code = 1;
  }
  return exit_code;
}
