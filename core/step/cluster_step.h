// One step of one cluster of God objects (METHOD.md §2, paper §4), taking the contact set as
// input (contact generation and CCD against meshes live in the collision stage):
//
//   coupling   z_u,i = k (X_target,i ⊖ X_god,i)            paper Eq. 2, k = min(k_s, 1/Δt²)
//   assembly   masses M_i = diag(m I, R I_turn Rᵀ) (I_turn: the model's rotational weight), rows J, c
//   solve      z = argmin ½‖z − z_u‖²_M s.t. J_E z = c_E, J_I z ≥ c_I   (exact or PGS)
//   integrate  X_i ← X_i ⊕ z_i Δt²                         symplectic Euler from rest, §2 step 4
//   project    post-stabilisation: Newton iterations of the same QP at position level
//              (Δt = 1, β = 1, rows re-linearised at the current poses) so that joints close to
//              round-off, limits hold and no contact is pushed further in than it is. While no
//              contact carries force, the first iterations also pull every body towards its
//              unconstrained goal G = X ⊕ z_u Δt² (z_u = G ⊖ X): this is Newton's method on the
//              nonlinear problem, so joint-consistent targets are reached exactly even under
//              large rotations, where the velocity-level rows alone lag by ≈ ½θ²L. Limits are
//              re-linearised every iteration and may be active; contacts are the previous
//              stage's and are not re-generated here, so once one carries force (or after three
//              iterations) the pull stops and the iterations are a pure projection (z_u = 0).
//              Always the exact solver.
//
// The clamp k ≤ 1/Δt² means a free God object reaches its target in one step and never
// overshoots it (k Δt² > 1 would overshoot; > 2 diverge).
//
// Model, data, solver (STYLE habit 1): the HandModel is const, per-step results live in
// StepReport, factorisations in the solvers. Nothing is allocated once warm (same or fewer rows
// than seen before). Bad inputs inside the step are counted and flagged, never thrown.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "model/hand_model.h"
#include "solver/active_set.h"
#include "solver/tree_solver.h"
#include "solver/pgs.h"
#include "step/constraints.h"

namespace godhand {

enum class SolverKind { Exact, Pgs };

struct StepParams {
  double dt = 1e-3;                 ///< s
  double k_s = 1e6;                 ///< coupling stiffness, 1/s² (clamped to 1/Δt²)
  RowParams rows;                   ///< β, margin δ, … (rows.dt is overwritten by dt)
  SolverKind solver = SolverKind::Exact;
  bool warm_start = true;           ///< start from last step's active set (exact) or λ (PGS)
  ActiveSetSettings exact;
  /// The exact solver in the joints' coordinates where the problem is a tree of joints
  /// (TreeSolver, falling back to ActiveSetSolver); false: ActiveSetSolver always (the same
  /// solution to round-off, slower; for comparisons).
  bool tree_solver = true;
  PgsSettings pgs;
  int projection_iterations = 8;    ///< cap; 0 disables the projection (it stops when converged)
  /// Motion clamp (m, rad; +inf = off): the coupling asks no body to move or turn further per
  /// step (one scale for the whole cluster). Contact rows are linear in the rotation, so their
  /// error grows with its square; the pipeline sets 0.03 m / 0.25 rad.
  double max_step_translation = std::numeric_limits<double>::infinity();
  double max_step_rotation = std::numeric_limits<double>::infinity();
  /// The same for bodies with a contact closer than contact_rotation_distance (m): the sweep's
  /// rotation about the body origin bulges ≈ θ² r / 8 off the chord; the pipeline sets 0.05 rad.
  double max_step_rotation_in_contact = std::numeric_limits<double>::infinity();
  double contact_rotation_distance = 0.005;
  /// true: bodies with a contact closer than contact_rotation_distance are clamped each on its
  /// own and the others share one scale (a finger pressing into a surface does not slow the
  /// rest of the hand); false: one scale for every body.
  bool clamp_contact_bodies_apart = false;
  double projection_tolerance = 1e-10;  ///< m / rad: joints and limits closed to this
  /// A projection iteration without the pull takes the rows of the contacts within this many
  /// times its errors' reach (gap + extent × (lock + limit) + contact violation) of their margin
  /// only; the others cannot become active. +inf: every contact's row, every iteration.
  double projection_row_reach = 10.0;
  double target_unit_tolerance = 1e-3;  ///< |‖q‖ − 1| above this rejects a target

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

enum StepFlag : std::uint32_t {
  kFlagRejectedTarget = 1u << 0,   ///< a target was NaN/Inf/non-unit: its last valid one was used
  kFlagRejectedContact = 1u << 1,  ///< a contact was malformed and ignored
  kFlagSolverFailed = 1u << 2,     ///< numerical failure: the previous state was kept
  kFlagSolverInexact = 1u << 3,    ///< iteration limit / stalled: result used, KKT not met
  kFlagStateKept = 1u << 4,        ///< the step produced non-finite poses, or opened the joints: previous state kept
  kFlagProjectionIncomplete = 1u << 5,  ///< joint error above tolerance after projection
  /// The solve with the joint-limit rows stalled: solved again without them, the limits left to
  /// the projection (which restores violated ones).
  kFlagLimitsToProjection = 1u << 6,
};

/// Joints closed well enough to be a hand: gap and lock within 1000 × the projection tolerance
/// (what kFlagProjectionIncomplete marks when not). Every accepted motion ends closed.
inline bool jointsClosed(const JointErrors& e, const StepParams& p) {
  return std::max(e.gap, e.lock) <= 1e3 * p.projection_tolerance;
}

/// The motion X_prev → X_new cut at fraction `toc` of each body's own motion, X = X_prev ⊕ t (X_new ⊖
/// X_prev) (the motion the sweep assumed, paper Eqs. 29–30), into X (which may be X_new itself).
/// toc ≥ 1: X = X_new.
void cutMotion(const std::vector<Pose>& X_prev, const std::vector<Pose>& X_new, double toc, std::vector<Pose>* X);

/// The projection (post-stabilisation, METHOD.md §2 step 4): position-level Newton iterations of
/// the Gauss QP (Δt = 1, β = 1, rows re-linearised at the current poses) until the joints close to
/// round-off and the limits hold, moving no contact further in than it is. While `goal` is given
/// and no contact carries force, the first iterations also pull every body towards its goal
/// (Newton on the nonlinear problem); otherwise the M-smallest displacement (z_u = 0). Always the
/// exact solver. One unit with its own QP, solver and scratch, used by the step (after its
/// integration) and by every clipping of a motion (Algorithm 1: to TOC_min, contacts there, the
/// joints re-closed against them: HandSolver::clip, Resolver), which own only their poses.
class JointProjector {
 public:
  /// params as the stepper's (validated there); the model must outlive the projector.
  JointProjector(const HandModel& model, const StepParams& params);
  /// Grows buffers for problems of up to `rows` rows (nothing allocated once warm).
  void reserve(int rows);

  struct Input {
    const Contact* contacts = nullptr;
    int num_contacts = 0;
    /// Per contact, nullptr = every valid contact: a negative entry skips the contact.
    const int* use = nullptr;
    /// Per body: the poses the contacts were found at (their points move rigidly from there).
    const Pose* X_ref = nullptr;
    /// Per body, nullptr = none: the goal the first iterations pull towards (see above).
    const Pose* goal = nullptr;
  };
  struct Result {
    int iterations = 0;
    JointErrors joint_errors;        ///< of the final poses
    double contact_violation = 0.0;  ///< m: contact points further in than allowed
  };
  /// Projects the poses X (one per body) in place.
  Result project(std::vector<Pose>& X, const Input& in);
  /// Its QP solver (which of TreeSolver and ActiveSetSolver answered, counted).
  const ExactSolver& solver() const { return exact_; }

 private:
  const HandModel& model_;
  StepParams params_;
  QpProblem proj_;
  QpSolution proj_sol_;
  ExactSolver exact_;
  std::vector<unsigned char> warm_;  // the last iteration's active rows (the next one's warm start)
  std::vector<JointFrame> frames_;   // the joints at the current poses: errors and rows from one evaluation
  double model_extent_ = 0.0;        // m: the bodies' largest distance apart at rest, plus 5 cm
};

struct StageTimes {
  double coupling_us = 0, assembly_us = 0, solve_us = 0, integrate_us = 0, project_us = 0;
  double total_us() const { return coupling_us + assembly_us + solve_us + integrate_us + project_us; }
};

struct StepReport {
  SolveStats solve;
  StageTimes times;
  int rows = 0, equality_rows = 0, limit_rows = 0, contact_rows = 0;
  int projection_iterations = 0;
  JointErrors joint_errors;         ///< after the step
  double contact_violation = 0.0;   ///< m: contact points further in than allowed after the projection
  double motion_scale = 1.0;        ///< < 1 when the motion clamp or a rotation cap scaled the coupling (smallest)
  double free_motion_scale = 1.0;   ///< the scale of the bodies away from contacts
  /// The same two under the full rotation limits (StepInput::rotation_trust = 1): how much of the
  /// rest of the motion the coupling asks for beyond the clamp itself.
  double asked_motion_scale = 1.0, asked_free_motion_scale = 1.0;
  std::uint32_t flags = 0;
  int rejected_targets = 0, rejected_contacts = 0;
  int shortened = 0;                ///< halvings of a motion whose projection opened the joints (0: none)
};

/// Counters over the stepper's lifetime (printed by services on exit).
struct StepCounters {
  std::uint64_t steps = 0, rejected_targets = 0, rejected_contacts = 0, solver_failures = 0,
                inexact_solves = 0, states_kept = 0, shortened_steps = 0;
  std::uint64_t limits_to_projection = 0;  ///< steps with kFlagLimitsToProjection
};

struct StepInput {
  const Pose* targets = nullptr;              ///< one per body
  const unsigned char* has_target = nullptr;  ///< per body; nullptr = every body driven
  const Contact* contacts = nullptr;
  int num_contacts = 0;
  /// Per body (nullptr = none): the largest rotation (rad) its solved step may make; a solution
  /// that turns a capped body further is scaled down, the coupling of every body with it, and
  /// solved again. For bodies resting on a surface whose last sweep hit at once: the contact rows
  /// are linear, and a large turn about the body origin swings the contact point along an arc
  /// into the surface (θ² r / 2 at the end), which the sweep rightly refuses.
  const double* rotation_cap = nullptr;
  /// The motion clamp's rotation limits (StepParams::max_step_rotation, _in_contact) times this,
  /// in (0, 1]: a trust region the caller shrinks where its rounds turn the hand back and forth
  /// (HandSolver: rows linear in the rotation overshoot on a curved surface). Outside (0, 1),
  /// NaN included: 1.
  double rotation_trust = 1.0;
};

class ClusterStepper {
 public:
  /// Halvings of a step's motion whose projection would open the joints, before the previous
  /// state is kept instead (kFlagStateKept).
  static constexpr int kShortenings = 3;
  /// Throws std::invalid_argument on bad parameters. The model must outlive the stepper.
  ClusterStepper(const HandModel& model, StepParams params);

  /// Places the bodies; throws std::invalid_argument on a wrong count or invalid pose.
  void reset(const std::vector<Pose>& X_W);
  /// Grows buffers for up to `contacts` contacts so that the first steps allocate nothing.
  void reserve(int contacts);

  const StepReport& step(const StepInput& input);

  /// Continuous-collision clipping (paper §6.3, Eqs. 29–30): moves every body back to the
  /// fraction `toc` ∈ [0, 1] of the last step's motion, X(t) = X_prev ⊕ t (X ⊖ X_prev) (the
  /// motion the sweep assumed). Interpolating each body on its own opens the joints by O(θ²) of
  /// the step's rotation θ: follow with reproject(). toc ≥ 1: no-op.
  void interpolate(double toc);
  /// The same with one fraction per body (toc[b] ≥ 1: body b keeps its new pose).
  void interpolate(const double* toc);
  /// The pure projection (no pull towards the goal) from the current poses, against contacts
  /// found at the current poses (Algorithm 1's regenerated contacts): joints re-closed and
  /// limits restored by the M-smallest displacement that moves no contact further in than it
  /// is. Updates lastReport().joint_errors and adds to its projection_iterations.
  void reproject(const Contact* contacts, int num_contacts);

  /// The distributed split (core/pipeline/stages.h): the stage that clips a step is not the one
  /// that took it. setMotion gives this stepper another stepper's last motion (X_prev -> X_new,
  /// bit for bit), so interpolate() and reproject() here compute exactly what they would there.
  /// adoptPoses makes the clipped result the start of the next step without touching the warm
  /// start or the last targets. Both throw std::invalid_argument on a wrong count.
  void setMotion(const std::vector<Pose>& X_prev, const std::vector<Pose>& X_new);
  void adoptPoses(const std::vector<Pose>& X_W);

  const std::vector<Pose>& poses() const { return X_W_; }
  /// Poses before the last step (or before setMotion's motion): where interpolate() starts.
  const std::vector<Pose>& previousPoses() const { return X_prev_; }
  const HandModel& model() const { return model_; }
  const StepParams& params() const { return params_; }
  const StepCounters& counters() const { return counters_; }
  /// QPs (the Gauss steps' and the projection's) answered by TreeSolver, and by ActiveSetSolver.
  std::uint64_t qpTreeSolves() const { return exact_.treeSolves() + projector_.solver().treeSolves(); }
  std::uint64_t qpGeneralSolves() const { return exact_.generalSolves() + projector_.solver().generalSolves(); }
  const StepReport& lastReport() const { return report_; }
  /// Multiplier (N, along the contact normal on the God object) of contact i of the last step.
  double contactLambda(int i) const { return lambda_contacts_[static_cast<size_t>(i)]; }
  /// The last step's problem and solution (for tests and diagnostics).
  const QpProblem& problem() const { return qp_; }
  const QpSolution& solution() const { return sol_; }

 private:
  // Also sets report_.joint_errors of the final poses. Contacts were found at poses X_ref; fresh:
  // use every valid contact (else only those the last step added as rows).
  int project(const StepInput& in, bool allow_pull, const std::vector<Pose>& X_ref, bool fresh);
  void rememberWarmStart();

  const HandModel& model_;
  StepParams params_;
  std::vector<Pose> X_W_, X_prev_, X_ref_, last_target_, goal_, X_integrated_;
  std::vector<unsigned char> has_last_target_;
  QpProblem qp_;
  QpSolution sol_;
  ExactSolver exact_;
  PgsSolver pgs_;
  JointProjector projector_;
  std::vector<int> contact_row_;       // contact i -> row index or -1
  std::vector<unsigned char> near_;    // per body: a contact within contact_rotation_distance
  std::vector<double> lambda_contacts_;
  // Warm start: keys and λ of the last step, sorted by key.
  std::vector<std::pair<std::uint64_t, double>> warm_prev_;
  std::vector<double> warm_lambda_;
  std::vector<unsigned char> warm_flags_;
  StepReport report_;
  StepCounters counters_;
};

}  // namespace godhand
