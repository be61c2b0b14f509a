// The whole method in one process (ARCHITECTURE.md "single in-process mode"): one or more God-hand
// clusters against a scene simulated by Bullet, in lock-step, one call per tracker frame. This is
// the reference the distributed services are compared against, and what godhand-bench drives.
//
// One frame (METHOD.md §2; paper §6.2 simulation loop, Algorithm 1), every stage timed:
//   contacts  per tracked hand and body: thinned contacts with every object within reach, where
//             reach = contact_reach + the motion the body's target asks for (|Δp| + |θ| ρ),
//             capped at max_reach; generated at the current poses after the scene moved
//             (Algorithm 1's "update contacts", done at the start of the next frame).
//   assembly, solve, integrate (incl. the joint projection): ClusterStepper::step per hand.
//   ccd       sweep of every God object from its old to its new pose against every object it can
//             reach; TOC_min per cluster (hands never touch each other, METHOD.md §4).
//   merge     clusters with TOC_min < 1 are moved back to TOC_min and their joints re-closed
//             (ClusterStepper::clip); contact multipliers become forces −λ n on the scene objects,
//             bounded per contact and per hand (METHOD.md §2 step 6).
//   scene     Bullet steps Δt; object poses come back; dynamic objects that Bullet moved into God
//             objects are pushed back out (paper §6.2: deepest first, iterated to a cap), so the
//             God hand never ends inside an object it did not move into.
//
// Start and re-acquisition (METHOD.md §2 step 7): a hand seen for the first time starts at its
// target if that is free, else lifted straight up (+z, doubling from 1 cm) to the first free pose,
// from which the normal steps (with CCD) bring it down to the surface. A hand that loses tracking
// is frozen where it is and reported untracked; when it is tracked again it moves on from there
// (the sweep clips that motion like any other: it never teleports through an object).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "model/hand_model.h"
#include "pipeline/collision_world.h"
#include "scene/scene.h"
#include "step/cluster_step.h"

namespace godhand {

class PhysicsWorld;
struct PhysicsParams;

/// The stepper's parameters as the pipeline uses them: the motion clamp on (see StepParams).
inline StepParams pipelineStepParams() {
  StepParams p;
  p.max_step_translation = 0.03;
  p.max_step_rotation = 0.25;
  p.max_step_rotation_in_contact = 0.05;
  return p;
}

struct PipelineParams {
  StepParams step = pipelineStepParams();  ///< dt here is the frame period
  ContactParams contacts;
  double contact_reach = 0.003;       ///< m, beyond the motion asked for
  double max_reach = 0.02;            ///< m
  geo::SweepParams sweep;             ///< CCD: stop 25 µm from a surface, tolerance 1 µm
  double max_force_per_contact = 20;  ///< N
  double max_force_per_hand = 60;     ///< N (Σ |f| over the hand's contacts)
  int resolve_iterations = 4;         ///< scene push-out passes (paper §6.2)
  bool simulate = true;               ///< false: dynamic objects stay put (pure God-object run)
  double start_clearance = 2e-4;      ///< m: a start pose closer than this is not free

  void validate() const;              ///< throws std::invalid_argument naming the field
};

struct PipelineTimes {
  double contacts_us = 0, assembly_us = 0, solve_us = 0, integrate_us = 0, ccd_us = 0, merge_us = 0, scene_us = 0;
  double total_us = 0;
};

struct HandFrameReport {
  bool tracked = false;               ///< targets were given this frame
  bool started = false;               ///< the hand exists (was tracked at least once)
  bool lifted_start = false;          ///< this frame started it above an occupied target
  int contacts = 0;
  double toc = 1.0;                   ///< TOC_min of this cluster
  bool started_inside = false;        ///< a sweep began inside an object (counted)
  double kkt = 0.0;
  SolveStatus status = SolveStatus::Converged;
  std::uint32_t flags = 0;
  double force_N = 0.0;               ///< Σ |f| sent to the scene
  JointErrors joint_errors;
};

struct FrameReport {
  PipelineTimes times;
  std::vector<HandFrameReport> hands;
  int contacts = 0;
  int scene_pushouts = 0;             ///< dynamic objects pushed out of God objects
};

struct PipelineCounters {
  std::uint64_t frames = 0, clipped_steps = 0, started_inside = 0, lifted_starts = 0, solver_failures = 0,
                inexact_solves = 0, forces_clamped = 0, scene_pushouts = 0, pushout_unresolved = 0;
};

/// Targets of one hand for one frame. tracked = false freezes the hand.
struct HandInput {
  bool tracked = false;
  const Pose* targets = nullptr;              ///< one per body of the hand's model
  const unsigned char* has_target = nullptr;  ///< per body, nullptr = all
};

class Pipeline {
 public:
  /// The scene and models must outlive the pipeline. Throws std::invalid_argument on bad
  /// parameters or shapes Bullet cannot simulate.
  Pipeline(const Scene& scene, std::vector<const HandModel*> hands, PipelineParams params);
  Pipeline(const Scene& scene, std::vector<const HandModel*> hands, PipelineParams params,
           const PhysicsParams& physics);
  ~Pipeline();

  /// One frame; inputs.size() must equal the number of hands.
  const FrameReport& step(const std::vector<HandInput>& inputs);

  int handCount() const { return static_cast<int>(hands_.size()); }
  bool started(int hand) const { return hands_[static_cast<size_t>(hand)].started; }
  const std::vector<Pose>& poses(int hand) const { return hands_[static_cast<size_t>(hand)].stepper->poses(); }
  const HandModel& model(int hand) const { return *hands_[static_cast<size_t>(hand)].model; }
  const ClusterStepper& stepper(int hand) const { return *hands_[static_cast<size_t>(hand)].stepper; }
  const std::vector<Contact>& contacts(int hand) const { return hands_[static_cast<size_t>(hand)].contacts; }
  const CollisionWorld& collision() const { return collision_; }
  const PhysicsWorld* physics() const { return physics_.get(); }
  const Scene& scene() const { return scene_; }
  const PipelineParams& params() const { return params_; }
  const PipelineCounters& counters() const { return counters_; }

  /// Exact penetration (m, ≥ 0) of every God object of a hand against the reference meshes.
  double penetration(int hand) const;

 private:
  struct Hand {
    const HandModel* model = nullptr;
    std::unique_ptr<ClusterStepper> stepper;
    bool started = false;
    std::vector<Contact> contacts;
    std::vector<Pose> X_start, X_old;  // scratch
  };
  bool start(Hand& hand, const HandInput& in, HandFrameReport& rep);
  void generateContacts(Hand& hand, const HandInput& in);
  void applyForces(Hand& hand, HandFrameReport& rep);
  void stepScene();

  const Scene& scene_;
  PipelineParams params_;
  CollisionWorld collision_;
  std::unique_ptr<PhysicsWorld> physics_;
  std::vector<Hand> hands_;
  FrameReport report_;
  PipelineCounters counters_;
  int trace_ = 0;  ///< GODHAND_TRACE level (diagnostics on stderr)
};

}  // namespace godhand
