// godhand-resolver: the final stage. Merges every cluster's HandProposal against the scene
// (core Resolver: continuous collision, TOC clipping with re-closed joints, bounded forces) and
// publishes one HandState per cluster and the frame's ContactForces.
//
// Lock-step: frame k needs every cluster's HandProposal(k) and SceneState(k-1) (deadline once the
// first of them is in). Live: resolves the newest frame as soon as every cluster's proposal of it
// is in, or after --merge-wait of the frame period with what is there (a missing cluster is held
// at its last pose and marked stale); the newest scene is used, and when it is older than the
// lab's stale_after_s every HandState is marked stale (the hands are held against the last scene).
#include <algorithm>
#include <cstdio>
#include <map>

#include "common/files.h"
#include "runtime/trace_env.h"
#include "model/hand_model.h"
#include "runtime/convert.h"
#include "runtime/live_merge.h"
#include "runtime/lockstep_gate.h"
#include "runtime/service.h"
#include "scene/scene_file.h"

using namespace godhand;
using svc::SteadyClock;

namespace {
constexpr const char* kSynopsis =
    "The final stage: every godhand/hand_proposal + godhand/scene_state -> godhand/hand_state per cluster\n"
    "and godhand/contact_forces (continuous collision, TOC clipping, merged bounded forces).";

SteadyClock::time_point after(double s) {
  return SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(s));
}
}  // namespace

int main(int argc, char** argv) {
  Cli cli("godhand-resolver", kSynopsis);
  svc::CommonOptions common;
  common.declare(cli);
  bool no_physics = false;
  double merge_wait = 0.5;
  cli.flag("--no-physics", &no_physics, "no forces to the scene (pure God-object run)");
  cli.option("--merge-wait", &merge_wait, "F", "live: wait at most F frame periods for the other live clusters' proposals");
  cli.parse(argc, argv);
  if (!(merge_wait >= 0.0 && merge_wait <= 10.0)) cli.fail("--merge-wait must be in [0, 10]");

  svc::Service service("resolver", common, cli);
  const LabConfig& lab = service.lab();
  const size_t C = lab.clusters.size();
  std::vector<HandModel> models(C);
  std::vector<const HandModel*> model_ptrs;
  Scene scene;
  PipelineParams params;
  svc::traceFromEnvironment(&params);
  std::unique_ptr<Resolver> resolver;
  try {
    for (size_t c = 0; c < C; ++c) models[c] = loadHandModel(lab.clusters[c].model);
    for (const HandModel& m : models) model_ptrs.push_back(&m);
    scene = loadScene(service.sceneFile());
    params.step.dt = 1.0 / service.frameRate();
    params.simulate = !no_physics;
    resolver = std::make_unique<Resolver>(scene, model_ptrs, params);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  const int objects = static_cast<int>(scene.objects.size());
  // What the wire carries (idl/godhand.idl bounds): checked here rather than truncated later.
  size_t god_bodies = 0;
  for (size_t c = 0; c < C; ++c) {
    if (models[c].bodies.size() > 32) cli.fail(lab.clusters[c].model + ": " + std::to_string(models[c].bodies.size()) + " bodies; the wire carries at most 32 per hand");
    god_bodies += models[c].bodies.size();
  }
  if (C > static_cast<size_t>(kMaxLabClusters)) cli.fail(lab.file + ": " + std::to_string(C) + " clusters; at most " + std::to_string(kMaxLabClusters));
  if (god_bodies > 96) cli.fail(lab.file + ": " + std::to_string(god_bodies) + " God objects over all clusters; ContactForces carries at most 96");

  service.connect();
  std::unique_ptr<dds::Reader<msg::HandProposal>> proposals_p;
  std::unique_ptr<dds::Reader<msg::SceneState>> scene_p;
  std::unique_ptr<dds::Writer<msg::HandState>> states_p;
  std::unique_ptr<dds::Writer<msg::ContactForces>> forces_p;
  // Live: the newest SceneState taken, held for a scene that restarts (runtime/scene_resume.h).
  std::unique_ptr<dds::Writer<msg::SceneState>> resume_p;
  try {
    proposals_p = std::make_unique<dds::Reader<msg::HandProposal>>(service.dds(), dds::topic::kHandProposal, service.streamProfile());
    scene_p = std::make_unique<dds::Reader<msg::SceneState>>(service.dds(), dds::topic::kSceneState, service.stateProfile());
    states_p = std::make_unique<dds::Writer<msg::HandState>>(service.dds(), dds::topic::kHandState, service.stateProfile());
    forces_p = std::make_unique<dds::Writer<msg::ContactForces>>(service.dds(), dds::topic::kContactForces, service.streamProfile());
  } catch (const std::exception& e) {
    service.fail(e.what());
  }
  // Not vital: refused (e.g. by the permissions of a lab PKI made before this topic existed),
  // the resolver runs on and a restarted scene starts from the scene file (it says so).
  if (!service.lockstep()) {
    try {
      resume_p = std::make_unique<dds::Writer<msg::SceneState>>(service.dds(), dds::topic::kSceneResume, dds::profile::kState);
    } catch (const std::exception& e) {
      service.reject(std::string("scene_resume: no writer (a restarted scene will start from the scene file): ") + e.what());
    }
  }
  auto& proposals_in = *proposals_p;
  auto& scene_in = *scene_p;
  auto& states_out = *states_p;
  auto& forces_out = *forces_p;
  std::fprintf(stderr, "resolver: %zu cluster(s), scene '%s' (%lld triangles), %.3f Hz, %s mode\n", C, scene.name.c_str(),
               scene.god_triangles, service.frameRate(), service.lockstep() ? "lock-step" : "live");

  // Payloads: lock-step, frame -> every cluster's proposal; live, the newest unresolved proposal
  // per cluster. What to resolve and when: svc::LockstepGate / svc::LiveMerge (injected clock).
  struct Slot {
    std::vector<HandProposal> p;
    std::vector<msg::Stamp> stamp;
    std::vector<unsigned char> have;
  };
  std::map<std::uint64_t, Slot> frames;
  Slot live;
  live.p.resize(C);
  live.stamp.resize(C);
  live.have.assign(C, 0);
  const double deadline = service.deadlineSeconds();
  const double period = 1.0 / service.frameRate();
  const double stale_after = service.staleAfterSeconds();
  // Lock-step inputs of frame k: every cluster's HandProposal(k) (they start the deadline) and,
  // as input C, SceneState(k-1).
  std::vector<bool> triggers(C + 1, true);
  triggers[C] = false;
  svc::LockstepGate gate(triggers, deadline, SteadyClock::now());
  svc::LiveMerge merge(C, period, merge_wait, stale_after, SteadyClock::now());
  std::map<std::uint64_t, SceneSnapshot> scenes;
  SteadyClock::time_point scene_seen = SteadyClock::now();
  bool have_scene = false;
  msg::HandProposal mp;
  msg::SceneState ss;
  std::string why;
  HandProposal tmp;
  auto drain = [&] {
    while (proposals_in.take(mp)) {
      ++service.samples_in;
      const std::uint32_t h = mp.hand();
      if (h >= C) { service.reject("hand_proposal: hand index not in the lab"); continue; }
      if (mp.cluster() != lab.clusters[h].name) { service.reject("hand_proposal: cluster name does not match the lab (another lab on this domain?)"); continue; }
      if (!svc::fromWire(mp, models[h].bodies.size(), objects, &tmp, &why)) { service.reject("hand_proposal: " + why); continue; }
      if (mp.loads_truncated()) service.reject("hand_proposal: more loaded contacts than the wire carries (dropped; not bit-identical)");
      const SteadyClock::time_point now = SteadyClock::now();
      if (service.lockstep()) {
        if (!gate.offer(h, tmp.frame, now)) { ++service.late; continue; }
        Slot& s = frames[tmp.frame];
        if (s.p.empty()) {
          s.p.resize(C);
          s.stamp.resize(C);
          s.have.assign(C, 0);
        }
        s.p[h] = tmp;
        s.stamp[h] = mp.stamp();
        s.have[h] = 1;
        continue;
      }
      const svc::LiveMerge::Offer o = merge.offer(h, mp.stamp().run(), tmp.frame, mp.stamp().source_time_ns(), now);
      if (o == svc::LiveMerge::Offer::Late) { ++service.late; continue; }
      if (o == svc::LiveMerge::Offer::Superseded) ++service.late;  // superseded before it was resolved
      live.p[h] = tmp;
      live.stamp[h] = mp.stamp();
    }
    while (scene_in.take(ss)) {
      SceneSnapshot s;
      if (!svc::fromWire(ss, objects, &s, &why)) { service.reject("scene_state: " + why); continue; }
      scene_seen = SteadyClock::now();
      if (service.lockstep()) {
        if (gate.offer(C, s.frame + 1, scene_seen)) scenes[s.frame] = std::move(s);
      } else {
        resolver->setScene(s);
        have_scene = true;
        if (resume_p && !resume_p->write(ss)) service.reject("scene_resume: write failed");
      }
    }
  };

  std::vector<const HandProposal*> ptrs(C);
  msg::HandState out;
  msg::ContactForces forces;
  while (!service.stopping()) {
    drain();
    std::uint64_t k = 0;
    Slot* s = nullptr;
    svc::LiveMerge::Decision decision;
    if (service.lockstep()) {
      const svc::LockstepGate::Poll poll = gate.poll(SteadyClock::now());
      if (poll.state == svc::LockstepGate::State::Idle) {
        if (!service.wait(after(0.1))) break;
        continue;
      }
      if (poll.state == svc::LockstepGate::State::Missed) {
        ++service.deadline_misses;
        const bool scene_missing = std::find(poll.missing.begin(), poll.missing.end(), C) != poll.missing.end();
        return service.finish(3, "lock-step frame " + std::to_string(gate.next()) + ": " +
                                     (scene_missing ? "SceneState of frame " + std::to_string(gate.next() - 1) : "a cluster's HandProposal") +
                                     " missing after " + std::to_string(deadline) + " s");
      }
      if (poll.state == svc::LockstepGate::State::Waiting) {
        if (!service.wait(poll.until)) return service.finish(0);
        continue;
      }
      k = gate.next();
      resolver->setScene(scenes[k - 1]);
      scenes.erase(scenes.begin(), scenes.lower_bound(k));
      s = &frames[k];
    } else {
      const SteadyClock::time_point now = SteadyClock::now();
      decision = merge.decide(have_scene, now);
      if (decision.kind == svc::LiveMerge::Decision::Wait) {
        if (!service.wait(decision.until, have_scene ? "running" : "waiting")) break;
        continue;
      }
      // Republish: nothing new, the held hands again, marked stale, so that subscribers (and late
      // joiners) see that nothing upstream is moving them.
      k = decision.frame;
      for (size_t h = 0; h < C; ++h) live.have[h] = merge.pending(h);
      s = &live;
    }
    for (size_t h = 0; h < C; ++h) ptrs[h] = s->have[h] ? &s->p[h] : nullptr;
    resolver->resolve(ptrs, k);
    const bool scene_stale =
        !service.lockstep() && std::chrono::duration<double>(SteadyClock::now() - scene_seen).count() > stale_after;
    // The stamp of the frame: the newest source stamp among its proposals.
    msg::Stamp stamp;
    stamp.run(service.lockstep() ? 0 : merge.run());
    stamp.frame(k);
    for (size_t h = 0; h < C; ++h)
      if (s->have[h] && s->stamp[h].source_time_ns() >= stamp.source_time_ns()) stamp = s->stamp[h];
    for (size_t h = 0; h < C; ++h) {
      const HandResult& r = resolver->result(static_cast<int>(h));
      // Stale whatever the cause: the scene is old, the cluster is held, or its tracker sample is
      // older than the stale limit (a stage was frozen and its backlog arrives late).
      const msg::Stamp& src = s->have[h] ? s->stamp[h] : stamp;
      const bool too_old = !service.lockstep() && src.source_time_ns() > 0 &&
                           static_cast<double>(svc::nowNs() - src.source_time_ns()) * 1e-9 > stale_after;
      if (too_old && s->have[h]) ++service.late;
      svc::toWire(r, models[h], scene_stale || !s->have[h] || too_old, &out);
      out.hand(static_cast<std::uint32_t>(h));
      out.cluster(lab.clusters[h].name);
      out.stamp() = svc::derivedStamp(s->have[h] ? s->stamp[h] : stamp);
      if (service.lockstep()) out.stamp().frame(k);
      if (states_out.write(out)) ++service.samples_out;
      else service.reject("hand_state: write failed");
    }
    svc::toWire(resolver->forces(), resolver->collision(), &forces);
    forces.stamp() = svc::derivedStamp(stamp);
    forces.stamp().frame(k);
    if (!forces_out.write(forces)) service.reject("contact_forces: write failed");
    bool resolved_any = false;
    for (unsigned char x : s->have) resolved_any = resolved_any || x;
    if (resolved_any) service.processed(k, stamp.source_time_ns());
    if (service.lockstep()) {
      frames.erase(frames.begin(), frames.upper_bound(k));
      gate.advance(SteadyClock::now());
    } else {
      merge.published(decision, SteadyClock::now());
      std::fill(live.have.begin(), live.have.end(), 0);
    }
  }
  if (merge.recoveries() > 0)
    std::fprintf(stderr, "resolver: live merge followed a cluster again %llu time(s) after everything it sent had been behind its book for %.2f s (a sample far ahead, e.g. from another writer)\n",
                 static_cast<unsigned long long>(merge.recoveries()), stale_after);
  const ResolverCounters& rc = resolver->counters();
  std::fprintf(stderr, "resolver: proposals trusted as swept %llu, swept again %llu (kept at the last result %llu), clipped %llu, held %llu\n",
               static_cast<unsigned long long>(rc.trusted), static_cast<unsigned long long>(rc.reswept),
               static_cast<unsigned long long>(rc.held_back), static_cast<unsigned long long>(rc.clipped_steps),
               static_cast<unsigned long long>(rc.held));
  return service.finish(0);
}
