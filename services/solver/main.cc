// godhand-solver --cluster NAME: the God-hand step of one hand cluster (core HandSolver: start,
// contacts, Gauss' least-constraint step). Reads its HandTarget, the SceneState and its own last
// HandState; publishes HandProposal. One process per cluster.
//
// Lock-step: frame k needs HandTarget(k), SceneState(k-1) and, after the first frame, this
// cluster's HandState(k-1); once the target is in, the rest must come within the deadline.
// Live: steps on each new target with the newest scene; a step always starts from a resolved
// state (the last HandState adopted), never from its own unresolved proposal.
#include <algorithm>
#include <cstdio>
#include <map>

#include "common/files.h"
#include "runtime/trace_env.h"
#include "model/hand_model.h"
#include "runtime/convert.h"
#include "runtime/lockstep_gate.h"
#include "runtime/service.h"
#include "scene/scene_file.h"

using namespace godhand;
using svc::SteadyClock;

namespace {
constexpr const char* kSynopsis =
    "One God-hand cluster's solver: godhand/hand_target + godhand/scene_state + its godhand/hand_state\n"
    "-> godhand/hand_proposal (the constrained step before continuous collision).";

SteadyClock::time_point after(double s) {
  return SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(s));
}
}  // namespace

int main(int argc, char** argv) {
  Cli cli("godhand-solver", kSynopsis);
  svc::CommonOptions common;
  common.declare(cli);
  std::string cluster_name, solver_kind = "exact";
  int pgs_iterations = 30, threads = 1;
  cli.option("--cluster", &cluster_name, "NAME", "the lab's hand cluster this process solves (required)");
  cli.option("--threads", &threads, "N",
             "threads the cluster's bodies' contact and sweep queries are spread over (the results "
             "are the same for every N)");
  cli.option("--solver", &solver_kind, "exact|pgs", "NNLS solver");
  cli.option("--pgs-iterations", &pgs_iterations, "N", "PGS sweeps");
  cli.parse(argc, argv);
  if (cluster_name.empty()) cli.fail("--cluster NAME is required");
  if (solver_kind != "exact" && solver_kind != "pgs") cli.fail("--solver must be exact or pgs");
  if (pgs_iterations < 1 || pgs_iterations > 100000) cli.fail("--pgs-iterations must be in [1, 100000]");
  if (threads < 1 || threads > 64) cli.fail("--threads must be in [1, 64]");

  svc::Service service("solver/" + cluster_name, common, cli);
  const LabConfig& lab = service.lab();
  const LabCluster* cluster = lab.cluster(cluster_name);
  if (!cluster) cli.fail("--cluster " + cluster_name + ": no such cluster in " + lab.file);
  const std::uint32_t index = static_cast<std::uint32_t>(cluster->index);
  HandModel model;
  Scene scene;
  PipelineParams params;
  svc::traceFromEnvironment(&params);
  std::unique_ptr<HandSolver> solver;
  try {
    model = loadHandModel(cluster->model);
    scene = loadScene(service.sceneFile());
    params.step.dt = 1.0 / service.frameRate();
    params.step.solver = solver_kind == "exact" ? SolverKind::Exact : SolverKind::Pgs;
    params.step.pgs.sweeps = pgs_iterations;
    params.body_threads = threads;
    solver = std::make_unique<HandSolver>(scene, model, params);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  const size_t n = model.bodies.size();
  const int objects = static_cast<int>(scene.objects.size());

  service.connect();
  std::unique_ptr<dds::Reader<msg::HandTarget>> targets_p;
  std::unique_ptr<dds::Reader<msg::SceneState>> scene_p;
  std::unique_ptr<dds::Reader<msg::HandState>> state_p;
  std::unique_ptr<dds::Writer<msg::HandProposal>> out_p;
  try {
    targets_p = std::make_unique<dds::Reader<msg::HandTarget>>(service.dds(), dds::topic::kHandTarget, service.streamProfile());
    scene_p = std::make_unique<dds::Reader<msg::SceneState>>(service.dds(), dds::topic::kSceneState, service.stateProfile());
    state_p = std::make_unique<dds::Reader<msg::HandState>>(service.dds(), dds::topic::kHandState, service.stateProfile());
    out_p = std::make_unique<dds::Writer<msg::HandProposal>>(service.dds(), dds::topic::kHandProposal, service.streamProfile());
  } catch (const std::exception& e) {
    service.fail(e.what());
  }
  auto& targets_in = *targets_p;
  auto& scene_in = *scene_p;
  auto& state_in = *state_p;
  auto& out = *out_p;
  std::fprintf(stderr, "solver/%s: model %s (%zu bodies), scene '%s' (%lld triangles), %.3f Hz, %s mode\n",
               cluster_name.c_str(), cluster->model.c_str(), n, scene.name.c_str(), scene.god_triangles,
               service.frameRate(), service.lockstep() ? "lock-step" : "live");

  // Inputs by frame (lock-step) or newest (live).
  std::map<std::uint64_t, msg::HandTarget> targets;
  std::map<std::uint64_t, SceneSnapshot> scenes;
  std::map<std::uint64_t, HandResult> states;
  HandResult resolved;      // the last adopted HandState
  HandResult latest_state;  // live: the newest HandState received
  bool latest_new = false;
  std::uint64_t run = 0;    // live: the ingest run of the targets
  bool have_resolved = false;
  std::uint64_t adopted_frame = 0;
  bool have_scene = false;
  msg::HandTarget t;
  msg::SceneState ss;
  msg::HandState hs;
  std::string why;
  // Lock-step inputs of frame k (svc::LockstepGate, injected clock): the HandTarget(k) starts the
  // deadline; SceneState(k-1) and this hand's HandState(k-1) (none before frame 1) must follow.
  svc::LockstepGate gate({true, false, false}, service.deadlineSeconds(), SteadyClock::now());
  gate.waive(2, 1);
  auto drain = [&] {
    const SteadyClock::time_point now = SteadyClock::now();
    while (targets_in.take(t)) {
      if (t.hand() != index) continue;
      if (t.cluster() != cluster_name) { service.reject("hand_target: cluster name does not match the lab (another lab on this domain?)"); continue; }
      if (!service.lockstep() && t.stamp().run() != run) {  // a new ingest run: frame numbers start again
        run = t.stamp().run();
        targets.clear();
      }
      ++service.samples_in;
      if (service.lockstep()) {
        if (!gate.offer(0, t.stamp().frame(), now)) { ++service.late; continue; }
      } else if (!targets.empty() && t.stamp().frame() <= targets.rbegin()->first) {
        ++service.late;
      }
      targets[t.stamp().frame()] = t;
    }
    while (scene_in.take(ss)) {
      SceneSnapshot s;
      if (!svc::fromWire(ss, objects, &s, &why)) { service.reject("scene_state: " + why); continue; }
      if (service.lockstep()) {
        if (gate.offer(1, s.frame + 1, now)) scenes[s.frame] = std::move(s);
      } else {  // live: the newest by arrival (a restarted scene starts again at frame 0)
        solver->setScene(s);
        have_scene = true;
      }
    }
    while (state_in.take(hs)) {
      if (hs.hand() != index) continue;
      if (hs.cluster() != cluster_name) { service.reject("hand_state: cluster name does not match the lab (another lab on this domain?)"); continue; }
      HandResult r;
      if (!svc::fromWire(hs, n, &r, &why)) { service.reject("hand_state: " + why); continue; }
      if (service.lockstep()) {
        if (gate.offer(2, r.frame + 1, now)) states[r.frame] = std::move(r);
      } else {  // live: the newest by arrival (a restarted resolver or ingest numbers frames anew)
        latest_state = std::move(r);
        latest_new = true;
      }
    }
    // Bounded memory: live keeps only the newest; lock-step drops what is behind.
    if (!service.lockstep()) {
      while (targets.size() > 1) targets.erase(targets.begin());
    }
  };

  std::uint64_t next = 1;  // lock-step: the frame to solve
  std::vector<Pose> X_target;
  std::vector<unsigned char> driven;
  msg::HandProposal p;
  const double deadline = service.deadlineSeconds();
  while (!service.stopping()) {
    drain();
    if (service.lockstep()) {
      const svc::LockstepGate::Poll poll = gate.poll(SteadyClock::now());
      if (poll.state == svc::LockstepGate::State::Idle) {
        if (!service.wait(after(0.1), "running")) break;
        continue;
      }
      if (poll.state == svc::LockstepGate::State::Missed) {
        ++service.deadline_misses;
        const bool scene_missing = std::find(poll.missing.begin(), poll.missing.end(), size_t{1}) != poll.missing.end();
        return service.finish(3, "lock-step frame " + std::to_string(next) + ": no " +
                                     (scene_missing ? "SceneState of frame " : "HandState of frame ") + std::to_string(next - 1) +
                                     " within " + std::to_string(deadline) + " s");
      }
      if (poll.state == svc::LockstepGate::State::Waiting) {
        if (!service.wait(poll.until)) return service.finish(0);
        continue;
      }
      solver->setScene(scenes[next - 1]);
      if (next > 1 && states.count(next - 1)) solver->adopt(states[next - 1]);
      scenes.erase(scenes.begin(), scenes.lower_bound(next - 1));
      states.erase(states.begin(), states.lower_bound(next - 1));
    } else {
      if (targets.empty() || !have_scene) {
        if (!service.wait(after(0.1), have_scene ? "running" : "waiting")) break;
        continue;
      }
      next = targets.rbegin()->first;
      // Start from a resolved state: the newest HandState, else the last one adopted.
      if (latest_new) {
        resolved = latest_state;
        have_resolved = true;
        adopted_frame = resolved.frame;
        latest_new = false;
      }
      if (have_resolved) {
        solver->resume(resolved);  // a restarted solver goes on from the hand's last resolved pose
        solver->adopt(resolved);
      }
    }
    const msg::HandTarget& target = targets[next];
    HandInput in;
    if (target.tracked()) {
      if (svc::fromWire(target, n, &X_target, &driven, &why)) {
        in.tracked = true;
        in.targets = X_target.data();
        in.has_target = driven.data();
      } else {
        service.reject("hand_target: " + why);  // treated as not tracked this frame (frozen)
      }
    }
    const HandProposal& prop = solver->step(in, next);
    svc::toWire(prop, &p);
    p.hand(index);
    p.cluster(cluster_name);
    p.stamp() = svc::derivedStamp(target.stamp());
    p.base_frame(service.lockstep() ? (next > 1 ? next - 1 : 0) : adopted_frame);
    if (out.write(p)) ++service.samples_out;
    else service.reject("hand_proposal: write failed");
    service.processed(next, target.stamp().source_time_ns());
    targets.erase(targets.begin(), targets.upper_bound(next));
    if (service.lockstep()) {
      ++next;
      gate.advance(SteadyClock::now());
    }
  }
  return service.finish(0);
}
