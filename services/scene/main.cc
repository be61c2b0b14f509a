// godhand-scene: the Bullet world (core SceneStage). Publishes the SceneDescription (transient
// local, for late joiners) and SceneState(0), then per frame applies the ContactForces(k) of the
// resolver, steps one frame period, pushes dynamic objects out of the God objects and publishes
// SceneState(k). Live: steps on its own clock at the frame rate with the newest forces (without
// forces, the last known God objects still keep dynamic objects out).
#include <cstdio>
#include <map>

#include "common/files.h"
#include "runtime/trace_env.h"
#include "physics/physics_world.h"
#include "runtime/convert.h"
#include "runtime/scene_resume.h"
#include "runtime/service.h"
#include "scene/scene_file.h"

using namespace godhand;
using svc::SteadyClock;

namespace {
constexpr const char* kSynopsis =
    "The scene: godhand/contact_forces -> Bullet -> godhand/scene_state; godhand/scene_description for late\n"
    "joiners.";

SteadyClock::time_point after(double s) {
  return SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(s));
}
}  // namespace

int main(int argc, char** argv) {
  Cli cli("godhand-scene", kSynopsis);
  svc::CommonOptions common;
  common.declare(cli);
  bool no_physics = false;
  int physics_hz = 240;
  cli.flag("--no-physics", &no_physics, "do not simulate: dynamic objects stay put");
  cli.option("--physics-hz", &physics_hz, "HZ", "Bullet's fixed step rate");
  std::string state_file;
  cli.option("--state-file", &state_file, "FILE",
             "live: keep the dynamic objects' poses in FILE after each step and, when FILE exists at start, start from them "
             "(a restarted scene resumes instead of jumping back to the scene file)");
  cli.parse(argc, argv);
  if (physics_hz < 10 || physics_hz > 100000) cli.fail("--physics-hz must be in [10, 100000]");

  svc::Service service("scene", common, cli);
  Scene scene;
  PipelineParams params;
  svc::traceFromEnvironment(&params);
  std::unique_ptr<SceneStage> stage;
  int resumed = 0;
  try {
    scene = loadScene(service.sceneFile());
    std::string why;
    if (!state_file.empty() && !service.lockstep() && !svc::applySceneResume(state_file, &scene, &resumed, &why)) cli.fail(why);
    params.step.dt = 1.0 / service.frameRate();
    params.simulate = !no_physics;
    stage = std::make_unique<SceneStage>(scene, params, physicsParamsFor(service.frameRate(), physics_hz));
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  const int objects = static_cast<int>(scene.objects.size());
  if (objects > 100) cli.fail(service.sceneFile() + ": " + std::to_string(objects) + " objects; the wire carries at most 100");

  service.connect();
  std::unique_ptr<dds::Reader<msg::ContactForces>> forces_p;
  std::unique_ptr<dds::Writer<msg::SceneState>> state_p;
  std::unique_ptr<dds::Writer<msg::SceneDescription>> description_p;
  try {
    forces_p = std::make_unique<dds::Reader<msg::ContactForces>>(service.dds(), dds::topic::kContactForces, service.streamProfile());
    state_p = std::make_unique<dds::Writer<msg::SceneState>>(service.dds(), dds::topic::kSceneState, service.stateProfile());
    description_p = std::make_unique<dds::Writer<msg::SceneDescription>>(service.dds(), dds::topic::kSceneDescription, dds::profile::kState);
  } catch (const std::exception& e) {
    service.fail(e.what());
  }
  auto& forces_in = *forces_p;
  auto& state_out = *state_p;
  auto& description_out = *description_p;
  std::fprintf(stderr, "scene: '%s' (%d objects, %lld God triangles), %.3f Hz, physics %s, %s mode\n", scene.name.c_str(),
               objects, scene.god_triangles, service.frameRate(), no_physics ? "off" : (std::to_string(physics_hz) + " Hz").c_str(),
               service.lockstep() ? "lock-step" : "live");

  if (resumed > 0) std::fprintf(stderr, "scene: resumed %d dynamic object pose(s) from %s\n", resumed, state_file.c_str());

  msg::SceneDescription description;
  svc::describeScene(scene, service.sceneFile(), &description);
  description_out.write(description);
  msg::SceneState out;
  auto publish = [&](const SceneSnapshot& s, const msg::Stamp& stamp) {
    svc::toWire(s, &out);
    out.stamp() = svc::derivedStamp(stamp);
    out.stamp().frame(s.frame);
    if (state_out.write(out)) ++service.samples_out;
    else service.reject("scene_state: write failed");
    if (!state_file.empty() && !service.lockstep() && !s.objects.empty() && !svc::writeSceneResume(state_file, s.objects))
      service.reject("state file " + state_file + ": write failed");
  };
  publish(stage->initial(), msg::Stamp{});

  std::map<std::uint64_t, std::pair<ForceSet, msg::Stamp>> pending;
  ForceSet last_bodies;  // live: the newest God objects, kept out of dynamic objects between forces
  std::uint64_t done = 0, last_frame = 0;
  msg::ContactForces cf;
  std::string why;
  const double period = 1.0 / service.frameRate();
  SteadyClock::time_point tick = SteadyClock::now();
  while (!service.stopping()) {
    while (forces_in.take(cf)) {
      ++service.samples_in;
      ForceSet f;
      if (!svc::fromWire(cf, objects, &f, &why)) { service.reject("contact_forces: " + why); continue; }
      if (service.lockstep() && f.frame <= done) { ++service.late; continue; }
      pending[f.frame] = {std::move(f), cf.stamp()};
    }
    if (service.lockstep()) {
      auto it = pending.find(done + 1);
      if (it == pending.end()) {
        if (!service.wait(after(0.1))) break;
        continue;
      }
      const SceneSnapshot& s = stage->step(&it->second.first, it->first);
      publish(s, it->second.second);
      service.processed(it->first, it->second.second.source_time_ns());
      done = it->first;
      pending.erase(pending.begin(), pending.upper_bound(done));
    } else {
      if (SteadyClock::now() < tick) {
        if (!service.wait(tick)) break;
        continue;
      }
      tick += std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(period));
      if (tick < SteadyClock::now()) tick = SteadyClock::now();  // fell behind: do not catch up in a burst
      if (!pending.empty()) {
        // Every ContactForces that came in since the last tick is applied (their impulses add up
        // over this step); the newest God objects keep dynamic objects out.
        auto newest = std::prev(pending.end());
        ForceSet& merged = newest->second.first;
        for (auto it = pending.begin(); it != newest; ++it)
          merged.loads.insert(merged.loads.begin(), it->second.first.loads.begin(), it->second.first.loads.end());
        last_bodies.bodies = merged.bodies;
        last_frame = newest->first;
        const SceneSnapshot& s = stage->step(&merged, newest->first);
        publish(s, newest->second.second);
        service.processed(newest->first, newest->second.second.source_time_ns());
        pending.clear();
      } else {
        SceneSnapshot s = stage->step(&last_bodies, last_frame);
        s.forces_applied = false;
        publish(s, msg::Stamp{});
      }
    }
  }
  return service.finish(0);
}
