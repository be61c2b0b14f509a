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
#include "dds/topics.h"
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
  double resume_wait = 0.0;
  cli.option("--resume-wait", &resume_wait, "S",
             "live, a restarted scene: wait up to S s for the scene state the lab holds (godhand/scene_resume, kept by the "
             "resolver) and start the dynamic objects there instead of at the scene file's poses (default 0: do not)");
  cli.parse(argc, argv);
  if (physics_hz < 10 || physics_hz > 100000) cli.fail("--physics-hz must be in [10, 100000]");
  if (!(resume_wait >= 0.0 && resume_wait <= 60.0)) cli.fail("--resume-wait must be in [0, 60] s");

  svc::Service service("scene", common, cli);
  Scene scene;
  PipelineParams params;
  svc::traceFromEnvironment(&params);
  std::unique_ptr<SceneStage> stage;
  const bool resuming = resume_wait > 0.0 && !service.lockstep();
  // First, before the scene file is read (a large mesh takes a while): a scene killed during its
  // start-up leaves this line in its log. On stdout (line-buffered, the same log under the
  // launcher), so that a bad scene file is still one line on stderr, the error.
  std::printf("scene: starting: %s, %.3f Hz, %s mode%s\n", service.sceneFile().c_str(), service.frameRate(),
              service.lockstep() ? "lock-step" : "live", resuming ? ", resuming" : "");
  try {
    scene = loadScene(service.sceneFile());
    params.step.dt = 1.0 / service.frameRate();
    params.simulate = !no_physics;
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  const int objects = static_cast<int>(scene.objects.size());
  if (static_cast<std::size_t>(objects) > svc::kMaxSceneObjects)
    cli.fail(service.sceneFile() + ": " + std::to_string(objects) + " objects; the wire carries at most " +
             std::to_string(svc::kMaxSceneObjects));

  // Said before the resume wait (up to --resume-wait s) and the world's build, not after them (a
  // scene killed meanwhile left no line at all).
  std::fprintf(stderr, "scene: '%s' (%d objects, %lld God triangles), %.3f Hz, physics %s, %s mode\n", scene.name.c_str(),
               objects, scene.god_triangles, service.frameRate(), no_physics ? "off" : (std::to_string(physics_hz) + " Hz").c_str(),
               service.lockstep() ? "lock-step" : "live");
  if (resuming)
    std::fprintf(stderr, "scene: resuming: waiting up to %.1f s for the scene state the lab holds (godhand/scene_resume)\n", resume_wait);
  // A resuming scene builds its world once it has the held poses (after the wait below).
  try {
    if (!resuming) stage = std::make_unique<SceneStage>(scene, params, physicsParamsFor(service.frameRate(), physics_hz));
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }

  service.connect();
  // A restarted scene: the dynamic objects start where the lab last saw them (runtime/scene_resume.h).
  std::string resume_note;
  if (resuming) {
    try {
      dds::Reader<msg::SceneState> held(service.dds(), dds::topic::kSceneResume, dds::profile::kState);
      const SteadyClock::time_point t0 = SteadyClock::now();
      svc::ResumeWait wait(resume_wait, 1.0, t0);
      msg::SceneState ss;
      for (;;) {
        if (held.take(ss)) {
          SceneSnapshot s;
          std::string why;
          int moved = 0;
          if (!svc::fromWire(ss, objects, &s, &why) || !svc::applySceneResume(s, &scene, &moved, &why)) {
            service.reject("scene_resume: " + why);
            resume_note = "not resumed: " + why + "; the scene file's poses";
          } else {
            char b[160];
            std::snprintf(b, sizeof b, "resumed %d dynamic object pose(s) from the held scene state (step %llu, %.2f s after start)", moved,
                          static_cast<unsigned long long>(s.step), std::chrono::duration<double>(SteadyClock::now() - t0).count());
            resume_note = b;
          }
          break;
        }
        const svc::ResumeWait::State st = wait.poll(held.matched(), SteadyClock::now());
        if (st == svc::ResumeWait::State::NothingHeld) {
          resume_note = "not resumed: the lab holds no scene state (nothing from the resolver's godhand/scene_resume); the scene file's poses";
          break;
        }
        if (st == svc::ResumeWait::State::TimedOut) {
          char b[160];
          std::snprintf(b, sizeof b, "not resumed: no held scene state within %.1f s (no resolver running?); the scene file's poses", resume_wait);
          resume_note = b;
          break;
        }
        if (!service.wait(SteadyClock::now() + std::chrono::milliseconds(20))) break;
      }
    } catch (const std::exception& e) {
      resume_note = std::string("not resumed: ") + e.what() + "; the scene file's poses";
    }
  }
  if (resuming) {
    try {
      stage = std::make_unique<SceneStage>(scene, params, physicsParamsFor(service.frameRate(), physics_hz));
    } catch (const std::exception& e) {
      service.fail(e.what());
    }
  }
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
  if (!resume_note.empty()) std::fprintf(stderr, "scene: %s\n", resume_note.c_str());
  for (const SceneObject& o : scene.objects)  // an open or inverted mesh: what it was taken for
    if (o.surface_changed)
      std::fprintf(stderr, "scene: %s (%s): %s\n", o.id.c_str(), o.source.c_str(), o.surface_note.c_str());

  msg::SceneDescription description;
  svc::describeScene(scene, service.sceneFile(), &description);
  description_out.write(description);
  msg::SceneState out;
  {  // What this scene puts on the wire (a sample above 64 KB goes out in RTPS fragments).
    svc::toWire(stage->initial(), &out);
    std::fprintf(stderr, "scene: on the wire: SceneDescription %zu bytes (once), SceneState %zu bytes a frame (%zu dynamic objects)\n",
                 msg::SceneDescription::getCdrSerializedSize(description) + 4, msg::SceneState::getCdrSerializedSize(out) + 4,
                 out.objects().size());
  }
  auto publish = [&](const SceneSnapshot& s, const msg::Stamp& stamp) {
    svc::toWire(s, &out);
    out.stamp() = svc::derivedStamp(stamp);
    out.stamp().frame(s.frame);
    if (state_out.write(out)) ++service.samples_out;
    else service.reject("scene_state: write failed");
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
