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
// target if that is free, else moved as one translation by the shorter of two: out along the exit
// normal of its deepest overlap, push after push (up to 64), and straight up (+z) to the lowest
// free height; from there the normal steps (with CCD) bring it to the surface. A hand that loses tracking
// is frozen where it is and reported untracked; when it is tracked again within
// PipelineParams::reacquire_after it moves on from there, after a longer loss it starts again as
// above; either way the motion from where it was is swept (the resolver sweeps a new start from
// the last result), so it never teleports through an object.
//
// The pipeline is the three stages of stages.h called in order (every HandSolver, the Resolver,
// the SceneStage), the structs they exchange passed by reference: the distributed services run
// the same stages and pass the same structs over Fast DDS.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "model/hand_model.h"
#include "pipeline/collision_world.h"
#include "scene/scene.h"
#include "step/cluster_step.h"
#include "pipeline/stages.h"
#include "pipeline/workers.h"

namespace godhand {

class PhysicsWorld;
struct PhysicsParams;

struct PipelineTimes {
  double contacts_us = 0, assembly_us = 0, solve_us = 0, integrate_us = 0, ccd_us = 0, merge_us = 0, scene_us = 0;
  double total_us = 0;
};

struct HandFrameReport {
  bool tracked = false;               ///< targets were given this frame
  bool started = false;               ///< the hand exists (was tracked at least once)
  bool lifted_start = false;          ///< this frame started it above an occupied target
  StepDiagnostics diag;               ///< the resolved step's (HandResult::diag)
  double force_N = 0.0;               ///< Σ |f| sent to the scene
  bool loaded = false;                ///< some contact carried force this frame
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
  std::uint64_t pushout_restored = 0;  ///< squeezed objects put back to their pose before the step
  std::uint64_t sweeps = 0, sweep_iterations = 0, sweeps_capped = 0;  ///< the solvers' (SolverCounters)
  std::uint64_t per_body_clips = 0, uniform_clips = 0, sweeps_certified = 0, held_rounds = 0;
  std::uint64_t rounds_shortened = 0, rounds_kept = 0;  ///< the solvers' (SolverCounters)
  std::uint64_t reacquisitions = 0;                    ///< the solvers' (SolverCounters)
  std::uint64_t reversed_rounds = 0;                   ///< the solvers' (SolverCounters)
  std::uint64_t hit_resolves = 0, resolves_undone = 0;  ///< the solvers' (SolverCounters)
  /// The hand solvers' QPs (Gauss steps and projections) answered in the joints' coordinates
  /// (TreeSolver) and by the general solver (ActiveSetSolver: not a tree, or degenerate).
  std::uint64_t qp_tree = 0, qp_general = 0;
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

  int handCount() const { return static_cast<int>(solvers_.size()); }
  bool started(int hand) const { return resolver_->result(hand).started; }
  const std::vector<Pose>& poses(int hand) const { return resolver_->result(hand).X; }
  const HandModel& model(int hand) const { return *models_[static_cast<size_t>(hand)]; }
  const HandSolver& solver(int hand) const { return *solvers_[static_cast<size_t>(hand)]; }
  const Resolver& resolver() const { return *resolver_; }
  const SceneStage& sceneStage() const { return *scene_stage_; }
  const HandResult& result(int hand) const { return resolver_->result(hand); }
  const PhysicsWorld* physics() const { return scene_stage_->physics(); }
  const Scene& scene() const { return scene_; }
  const PipelineParams& params() const { return params_; }
  const PipelineCounters& counters() const { return counters_; }

  /// Exact penetration (m, ≥ 0) of every God object of a hand against the reference meshes.
  double penetration(int hand) const { return resolver_->penetration(hand); }

  /// Per scene object, the God side's share so far: the time and count of its contact, sweep
  /// and distance queries in every hand's solver and in the resolver (CollisionWorld::costs).
  /// The scene stage's push-out queries are not in it (its world is its own); Bullet's time is
  /// the scene stage's, not split by object.
  std::vector<ObjectCost> godCosts() const;

 private:
  const Scene& scene_;
  PipelineParams params_;
  std::vector<const HandModel*> models_;
  std::vector<std::unique_ptr<HandSolver>> solvers_;
  std::unique_ptr<Resolver> resolver_;
  std::unique_ptr<SceneStage> scene_stage_;
  std::unique_ptr<Workers> workers_;
  std::vector<const HandInput*> inputs_;
  std::uint64_t frame_ = 0;
  std::function<void(int)> solve_hand_;
  // Two or more hands on two or more threads: each pool thread takes hands, then helps the
  // others' bodies through share_ (JobShare) until every hand is done.
  std::unique_ptr<JobShare> share_;
  std::function<void(int, int)> solve_hands_shared_;
  std::atomic<int> next_hand_{0}, hands_done_{0};
  std::vector<double> hand_weight_;  // per hand: its JobShare weight this frame
  std::vector<int> hand_order_;      // the hands by weight, heaviest first (taken in this order)
  std::vector<const HandProposal*> proposals_;
  std::vector<double> hand_us_;  // per hand: its solver's time in the last frame (JobShare weights)
  FrameReport report_;
  PipelineCounters counters_;
};

}  // namespace godhand
