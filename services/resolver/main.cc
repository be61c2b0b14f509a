// godhand-resolver: the final stage. Merges every cluster's HandProposal against the scene
// (core Resolver: continuous collision, TOC clipping with re-closed joints, bounded forces) and
// publishes one HandState per cluster and the frame's ContactForces.
//
// Lock-step: frame k needs every cluster's HandProposal(k) and SceneState(k-1) (deadline once the
// first of them is in). Live: resolves the newest frame as soon as every cluster's proposal of it
// is in, or after --merge-wait of the frame period with what is there (a missing cluster is held
// at its last pose and marked stale); the newest scene is used, and when it is older than the
// lab's stale_after_s every HandState is marked stale (the hands are held against the last scene).
#include <cstdio>
#include <map>

#include "model/hand_model.h"
#include "runtime/convert.h"
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
  std::unique_ptr<Resolver> resolver;
  try {
    for (size_t c = 0; c < C; ++c) models[c] = HandModel::loadFile(lab.clusters[c].model);
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
  if (C > 16) cli.fail(lab.file + ": " + std::to_string(C) + " clusters; at most 16");
  if (god_bodies > 96) cli.fail(lab.file + ": " + std::to_string(god_bodies) + " God objects over all clusters; ContactForces carries at most 96");

  service.connect();
  std::unique_ptr<dds::Reader<msg::HandProposal>> proposals_p;
  std::unique_ptr<dds::Reader<msg::SceneState>> scene_p;
  std::unique_ptr<dds::Writer<msg::HandState>> states_p;
  std::unique_ptr<dds::Writer<msg::ContactForces>> forces_p;
  try {
    proposals_p = std::make_unique<dds::Reader<msg::HandProposal>>(service.dds(), dds::topic::kHandProposal, service.streamProfile());
    scene_p = std::make_unique<dds::Reader<msg::SceneState>>(service.dds(), dds::topic::kSceneState, service.stateProfile());
    states_p = std::make_unique<dds::Writer<msg::HandState>>(service.dds(), dds::topic::kHandState, service.stateProfile());
    forces_p = std::make_unique<dds::Writer<msg::ContactForces>>(service.dds(), dds::topic::kContactForces, service.streamProfile());
  } catch (const std::exception& e) {
    service.fail(e.what());
  }
  auto& proposals_in = *proposals_p;
  auto& scene_in = *scene_p;
  auto& states_out = *states_p;
  auto& forces_out = *forces_p;
  std::fprintf(stderr, "resolver: %zu cluster(s), scene '%s' (%lld triangles), %.3f Hz, %s mode\n", C, scene.name.c_str(),
               scene.god_triangles, service.frameRate(), service.lockstep() ? "lock-step" : "live");

  // Lock-step: frame -> every cluster's proposal. Live: the newest unresolved proposal per
  // cluster (clusters may be at different frames: a lagging solver is not starved).
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
  std::vector<std::uint64_t> done_h(C, 0);              // live: newest frame resolved per cluster
  std::vector<SteadyClock::time_point> last_in(C);      // live: last proposal arrival per cluster
  SteadyClock::time_point first_pending{}, last_publish = SteadyClock::now();
  std::uint64_t run = 0;                                 // the ingest run being resolved
  std::int64_t run_source_ns = 0;
  std::map<std::uint64_t, SceneSnapshot> scenes;
  SteadyClock::time_point scene_seen = SteadyClock::now();
  bool have_scene = false;
  std::uint64_t done = 0;  // lock-step: newest frame resolved; live: newest frame published
  msg::HandProposal mp;
  msg::SceneState ss;
  std::string why;
  HandProposal tmp;
  auto drain = [&] {
    while (proposals_in.take(mp)) {
      ++service.samples_in;
      const std::uint32_t h = mp.hand();
      if (h >= C) { service.reject("hand_proposal: hand index " + std::to_string(h) + " not in the lab"); continue; }
      if (mp.cluster() != lab.clusters[h].name) { service.reject("hand_proposal: cluster name does not match the lab (another lab on this domain?)"); continue; }
      if (!svc::fromWire(mp, models[h].bodies.size(), objects, &tmp, &why)) { service.reject("hand_proposal: " + why); continue; }
      if (mp.loads_truncated()) service.reject("hand_proposal: more loaded contacts than the wire carries (dropped; not bit-identical)");
      if (service.lockstep()) {
        if (tmp.frame <= done) { ++service.late; continue; }
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
      // Live: a new ingest run (frame numbers start again) replaces the old one.
      if (mp.stamp().run() != run) {
        if (run != 0 && mp.stamp().source_time_ns() < run_source_ns) { ++service.late; continue; }  // a straggler of an old run
        run = mp.stamp().run();
        std::fill(done_h.begin(), done_h.end(), 0);
        std::fill(live.have.begin(), live.have.end(), 0);
      }
      run_source_ns = std::max(run_source_ns, mp.stamp().source_time_ns());
      if (tmp.frame <= done_h[h]) { ++service.late; continue; }
      if (live.have[h]) ++service.late;  // superseded before it was resolved
      bool any = false;
      for (unsigned char x : live.have) any = any || x;
      if (!any) first_pending = SteadyClock::now();
      live.p[h] = tmp;
      live.stamp[h] = mp.stamp();
      live.have[h] = 1;
      last_in[h] = SteadyClock::now();
    }
    while (scene_in.take(ss)) {
      SceneSnapshot s;
      if (!svc::fromWire(ss, objects, &s, &why)) { service.reject("scene_state: " + why); continue; }
      scene_seen = SteadyClock::now();
      if (service.lockstep()) scenes[s.frame] = std::move(s);
      else {
        resolver->setScene(s);
        have_scene = true;
      }
    }
  };
  auto complete = [&](const Slot& s) {
    for (unsigned char h : s.have)
      if (!h) return false;
    return true;
  };

  std::vector<const HandProposal*> ptrs(C);
  msg::HandState out;
  msg::ContactForces forces;
  const double deadline = service.deadlineSeconds();
  const double period = 1.0 / service.frameRate();
  const double stale_after = service.staleAfterSeconds();
  auto seconds = [](double x) { return std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(x)); };
  while (!service.stopping()) {
    drain();
    std::uint64_t k = 0;
    Slot* s = nullptr;
    if (service.lockstep()) {
      k = done + 1;
      if (!frames.count(k)) {
        if (!service.wait(after(0.1))) break;
        continue;
      }
      const auto until = after(deadline);
      for (;;) {
        drain();
        if (complete(frames[k]) && scenes.count(k - 1)) break;
        if (SteadyClock::now() >= until) {
          ++service.deadline_misses;
          return service.finish(3, "lock-step frame " + std::to_string(k) + ": " +
                                       (scenes.count(k - 1) ? "a cluster's HandProposal" : "SceneState of frame " + std::to_string(k - 1)) +
                                       " missing after " + std::to_string(deadline) + " s");
        }
        if (!service.wait(until)) return service.finish(0);
      }
      resolver->setScene(scenes[k - 1]);
      scenes.erase(scenes.begin(), scenes.lower_bound(k));
      s = &frames[k];
    } else {
      const SteadyClock::time_point now = SteadyClock::now();
      bool any = false, ready = true;
      for (size_t h = 0; h < C; ++h) {
        any = any || live.have[h];
        // A cluster that has gone quiet is not waited for.
        const bool alive = last_in[h] != SteadyClock::time_point{} && now - last_in[h] < seconds(stale_after);
        if (alive && !live.have[h]) ready = false;
      }
      if (!have_scene || !any) {
        // Nothing new: re-publish the held hands, marked stale, so that subscribers (and late
        // joiners) see that nothing upstream is moving them.
        if (have_scene && now - last_publish > seconds(stale_after)) {
          k = done;
          s = &live;
        } else {
          if (!service.wait(after(0.05), have_scene ? "running" : "waiting")) break;
          continue;
        }
      } else if (!ready && now < first_pending + seconds(merge_wait * period)) {
        if (!service.wait(first_pending + seconds(merge_wait * period))) break;
        continue;
      } else {
        s = &live;
        for (size_t h = 0; h < C; ++h)
          if (live.have[h]) k = std::max(k, live.p[h].frame);
      }
    }
    for (size_t h = 0; h < C; ++h) ptrs[h] = s->have[h] ? &s->p[h] : nullptr;
    resolver->resolve(ptrs, k);
    const bool scene_stale =
        !service.lockstep() && std::chrono::duration<double>(SteadyClock::now() - scene_seen).count() > stale_after;
    // The stamp of the frame: the newest source stamp among its proposals.
    msg::Stamp stamp;
    stamp.run(run);
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
    last_publish = SteadyClock::now();
    done = std::max(done, k);
    if (service.lockstep()) {
      frames.erase(frames.begin(), frames.upper_bound(k));
    } else {
      for (size_t h = 0; h < C; ++h)
        if (live.have[h]) done_h[h] = live.p[h].frame;
      std::fill(live.have.begin(), live.have.end(), 0);
    }
  }
  return service.finish(0);
}
