// A restarted godhand-scene takes its dynamic objects back from where the last one left them,
// not from the scene file (no jump back), through DDS: the resolver keeps the newest SceneState
// it took on godhand/scene_resume (profile godhand.state: reliable, transient local, KEEP_LAST
// 1), so the lab holds the scene's state while the scene is gone, on whichever host. A scene
// started with --resume-wait reads that sample before it builds its world and moves the objects'
// initial poses there. Velocities are not restored (objects restart at rest).
//
// Why not the scene's own SceneState: its transient-local history lives in the writer, which
// dies with the scene process.
#pragma once

#include <chrono>
#include <string>

#include "pipeline/stages.h"
#include "scene/scene.h"

namespace godhand::svc {

/// Moves scene->objects[index].X_WO to each held object's pose. Every held object must be a
/// dynamic object of this scene (else false, *why = one line, the scene untouched: the sample is
/// of another scene). *moved = how many objects moved.
bool applySceneResume(const SceneSnapshot& held, Scene* scene, int* moved, std::string* why);

/// When a resuming scene stops waiting for the held state (injected clock, no DDS): once a
/// writer of godhand/scene_resume has been matched for `grace` without a sample, the lab holds
/// nothing (a first start, or a resolver that has not seen a scene yet: transient-local history
/// arrives right after the match); at `wait` at the latest.
class ResumeWait {
 public:
  using Clock = std::chrono::steady_clock;
  enum class State { Waiting, NothingHeld, TimedOut };
  ResumeWait(double wait_s, double grace_s, Clock::time_point start);
  /// writers: the reader's matched writers now.
  State poll(int writers, Clock::time_point now);

 private:
  Clock::time_point until_;
  Clock::duration grace_;
  bool matched_ = false;
  Clock::time_point matched_at_{};
};

}  // namespace godhand::svc
