// What users would pick instead (issue 14): the same hands driven by MuJoCo, for a side-by-side
// comparison measured by godhand's own figures (core/pipeline/run_metrics.h).
//
// The MuJoCo model (built as MJCF text, loaded from memory): every body of every hand model is a
// free body with the model's shape and mass, welded (an equality constraint, MuJoCo's soft
// constraint model) to a mocap body that is put at the body's target each frame; no joints
// between the bodies (the targets hold them together, as the hand's joints do not exist in
// MuJoCo here) and no collision between hand bodies. The scene's objects are static geoms at
// their poses; MuJoCo collides mesh geoms as their convex hull (its documented behaviour), which
// is what a user gets from it. No gravity on the hands (godhand's God objects feel none either).
// A frame is ceil(frame dt / timestep) mj_step calls.
//
// No I/O: the model is built in memory (mjVFS).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "math/pose.h"
#include "model/hand_model.h"
#include "pipeline/stages.h"
#include "scene/scene.h"

namespace godhand::mujoco {

struct Params {
  double timestep = 0.002;        ///< s, MuJoCo's default
  /// s: the weld's and the contacts' time constant (MuJoCo's solref[0], default 0.02 for both;
  /// MuJoCo wants it at least twice the timestep).
  double weld_timeconst = 0.02;
  double contact_timeconst = 0.02;
};

/// The MJCF text of the comparison model (for tests and --help-level inspection). Throws
/// std::invalid_argument on a scene object MuJoCo cannot hold (no mesh) or bad parameters.
std::string modelXml(const Scene& scene, const std::vector<const HandModel*>& models, const Params& params);

/// "MuJoCo 2.2.2" (the library's own version string).
std::string version();

class Hands {
 public:
  /// The scene and models must outlive this. frame_dt: the recording's frame period (s). Throws
  /// std::invalid_argument naming the problem (bad parameters, MuJoCo's own load error).
  Hands(const Scene& scene, std::vector<const HandModel*> models, double frame_dt, const Params& params);
  ~Hands();
  Hands(const Hands&) = delete;
  Hands& operator=(const Hands&) = delete;

  /// One frame: each tracked hand's mocap bodies go to its targets (a body without a target keeps
  /// its last one); a hand's first tracked frame also places its bodies there (at rest where a
  /// body has no target: the model's rest pose about the first body's target). Then the steps.
  void step(const std::vector<HandInput>& inputs);

  int handCount() const { return static_cast<int>(hands_.size()); }
  bool started(int hand) const { return hands_[static_cast<size_t>(hand)].started; }
  /// The bodies' poses after the last step (model body order).
  const std::vector<Pose>& poses(int hand) const { return hands_[static_cast<size_t>(hand)].X; }
  /// Some MuJoCo contact of this hand with the scene is active (distance <= 0).
  bool loaded(int hand) const { return hands_[static_cast<size_t>(hand)].loaded; }
  int stepsPerFrame() const { return steps_per_frame_; }
  /// Frames after which MuJoCo's state was reset (a bad number in qpos/qvel/qacc: MuJoCo's
  /// instability warning); the hands keep their last finite poses and start again at their
  /// next targets.
  long resets() const { return resets_; }
  /// Hand-frames whose targets were not finite (ignored: the hand keeps its last targets).
  long rejectedTargets() const { return rejected_; }
  /// Frames in which MuJoCo's contact or constraint list was full (contacts dropped).
  long overflows() const { return overflows_; }

 private:
  struct Hand {
    const HandModel* model = nullptr;
    int first_body = 0;   ///< MuJoCo body id of body 0 (then one per model body, in order)
    int first_mocap = 0;  ///< mocap index of body 0's target
    int first_qpos = 0;   ///< qpos address of body 0's free joint
    int first_geom = 0, geoms = 0;
    bool started = false, loaded = false;
    std::vector<Pose> X;
  };
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<Hand> hands_;
  int steps_per_frame_ = 1;
  long resets_ = 0, rejected_ = 0, overflows_ = 0;
};

}  // namespace godhand::mujoco
