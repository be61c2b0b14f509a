// The method split into the stages the distributed services run (ARCHITECTURE.md "Processes"):
//
//   HandSolver (one per hand cluster)   targets + scene + its last resolved state -> HandProposal
//   Resolver   (one)                    every proposal + scene -> HandResult per hand, ForceSet
//   SceneStage (one)                    ForceSet -> SceneSnapshot (Bullet steps, push-out)
//
// The in-process Pipeline (pipeline.h) is exactly these stages called in this order with the
// structs passed by reference; the services pass the same structs over Fast DDS (services/
// convert them to and from the wire types field by field, every double bit for bit). So a
// lock-step distributed run computes what the in-process run computes, and the tests check it
// with the result hash.
//
// Frame k, lock-step:  solver_c(k) needs targets(k), SceneSnapshot(k-1), HandResult_c(k-1);
//                      resolver(k) needs every Proposal(k) and SceneSnapshot(k-1);
//                      scene(k)    needs ForceSet(k).  SceneSnapshot(0) is the initial scene.
// Live mode runs the same calls on the newest inputs; the resolver holds a hand whose proposal
// is missing at its last resolved pose (and keeps it in the ForceSet so that the scene keeps
// dynamic objects out of it).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "model/hand_model.h"
#include "pipeline/collision_world.h"
#include "pipeline/workers.h"
#include "scene/scene.h"
#include "step/cluster_step.h"

namespace godhand {

class PhysicsWorld;
struct PhysicsParams;

/// The stepper's parameters as the pipeline uses them: the motion clamp on (see StepParams).
inline StepParams pipelineStepParams() {
  StepParams p;
  p.max_step_translation = 0.03;
  p.max_step_rotation = 0.5;
  p.max_step_rotation_in_contact = 0.5;
  p.clamp_contact_bodies_apart = true;
  return p;
}

/// The pipeline reads toc, hit and started_inside of its sweeps, never d(toc): it skips the
/// closest query that would measure it.
inline geo::SweepParams pipelineSweepParams() {
  geo::SweepParams p;
  p.exact_distance = false;
  return p;
}

struct PipelineParams {
  StepParams step = pipelineStepParams();  ///< dt here is the frame period
  ContactParams contacts;
  double contact_reach = 0.003;       ///< m, beyond the motion asked for
  double max_reach = 0.02;            ///< m
  geo::SweepParams sweep = pipelineSweepParams();  ///< CCD: stop 25 µm from a surface, tolerance 1 µm
  /// Diagnostic lines: 0 none, 1 per frame and hand (and a moved start), 2 also every clipping
  /// sweep, 3 every sweep. Each line goes to trace_sink (none: no trace); core writes nowhere
  /// itself (the services set both from GODHAND_TRACE, to stderr: svc::traceFromEnvironment).
  int trace = 0;
  std::function<void(const char* line)> trace_sink;
  double max_force_per_contact = 20;  ///< N
  double max_force_per_hand = 60;     ///< N (Σ |f| over the hand's contacts)
  int resolve_iterations = 4;         ///< scene push-out passes (paper §6.2)
  bool simulate = true;               ///< false: dynamic objects stay put (pure God-object run)
  double start_clearance = 2e-4;      ///< m: a start pose closer than this is not free
  /// m: a free start pose farther than this from the targets is no start (the hand stays
  /// unstarted, reported): a mesh that encloses the tracking volume (a CAD part in millimetres
  /// read as metres) has its nearest way out metres away, where the user would never see it.
  double max_start_shift = 0.5;
  /// s: a hand tracked again after it was lost for at least this long starts again (METHOD.md §2
  /// step 7: at its targets where they are free, else at the nearest free pose) instead of
  /// gliding from where it was lost at the motion clamp's pace; the resolver sweeps that jump from
  /// the last result, so it never passes through an object. Shorter losses (a dropped frame in a
  /// grasp) go on from where the hand was. 0 = every loss; +inf = never.
  double reacquire_after = 0.1;
  /// s: a hand whose start found no free pose (targets deep in an object that encloses them)
  /// searches again after this long, not every frame (a search costs up to ~10 ms).
  double start_retry = 0.1;
  /// Solve -> sweep rounds per frame (Ortega et al., Redon; METHOD.md §2 step 5): after a clip
  /// the contacts at the clipped pose are found and the rest of the motion towards the same
  /// targets is solved and swept again, at most this many rounds in all.
  int max_substeps = 3;
  /// Rounds a frame may take while no round was clipped and only the motion clamp
  /// (StepParams::max_step_*) shortened the motion, each round gaining on the last (a clamp scale
  /// growing by 5 %, or some body brought MetricThresholds::kLagAbove closer to its target) (a low-confidence
  /// Leap hand turning 1.5-3 rad between two 24 fps frames: with 3 rounds the hand in contact and
  /// its free twin ended the frame 7-12 mm apart in free space). Rounds after a clip stay bounded by
  /// max_substeps. The larger of the two applies. 8 since 2026-12-05: a hand held on a table while
  /// its targets flip 1-1.7 rad still gained 15 mm in its fifth round (confidence2 under a tracker
  /// tilted 15-30°: 11 -> 6 table frames above 5 mm over 27 tables; the 42 mesh runs +0.4 % rounds).
  int max_clamped_rounds = 8;
  /// Within a round whose sweep hit: the hit bodies' contacts at their TOC poses join the round's
  /// and the round is solved again from its start, at most this many times (while the hit brings
  /// a contact the rows lacked), before the round is clipped (0: clip at once).
  int hit_resolves = 1;
  /// rad (0 = off): a body whose last sweep hit at once (TOC < 1e-3, from outside) may turn at
  /// most this much in its next solved step (StepInput::rotation_cap): resting on a surface, a
  /// larger turn about its origin swings its contact point into the surface and the whole round
  /// is refused, round after round (seen: a pinky phalanx at a fandisk crease turned 0.55 rad per
  /// step and held the hand still while its targets moved 15 cm on).
  double stuck_rotation = 0.05;
  /// Threads the Pipeline steps its hands' solvers on (1: one after the other on the caller's
  /// thread). The results are the same for every count; with trace on, the solvers run on the
  /// caller's thread so that the lines keep their order.
  int threads = 1;
  /// Threads one HandSolver spreads its bodies' collision queries over (contacts and sweeps: the
  /// bodies' queries are independent, each thread has its own collision scratch, and the results
  /// are merged in body order, so they are the same for every count). The Pipeline gives each
  /// solver all its `threads` (a light hand leaves its core to the other's bodies); with trace on, 1.
  int body_threads = 1;

  void validate() const;              ///< throws std::invalid_argument naming the field
};

/// Targets of one hand for one frame. tracked = false freezes the hand.
struct HandInput {
  bool tracked = false;
  const Pose* targets = nullptr;              ///< one per body of the hand's model
  const unsigned char* has_target = nullptr;  ///< per body, nullptr = all
};

/// A contact that carries force (finite λ > 0), in the solver's contact order.
struct ContactLoad {
  int body = -1;
  int object = -1;
  Vec3 p_W = Vec3::Zero();
  Vec3 n_W = Vec3::UnitZ();  ///< from the object towards the God object
  double lambda = 0.0;       ///< N on the God object along n
};

struct SolverTimes {
  double contacts_us = 0, assembly_us = 0, solve_us = 0, integrate_us = 0, ccd_us = 0;
};

/// What one hand's step did, as every report shows it: filled by the solver's step, carried
/// unchanged to the resolver's result (which adds only what clipping there changed), the
/// pipeline's frame report, the wire (HandProposal, HandState) and the bench, launch and viewer.
struct StepDiagnostics {
  int contacts = 0;               ///< contacts of the step (the most of any round)
  double kkt = 0.0;               ///< largest KKT residual of its solves
  SolveStatus status = SolveStatus::Converged;
  std::uint32_t flags = 0;        ///< StepFlag bits of its rounds
  JointErrors joint_errors;       ///< of the resulting poses
  SolverTimes times;              ///< the solver's stages
  int substeps = 0;               ///< solve -> sweep rounds taken (0: not stepped)
  double toc = 1.0;               ///< smallest TOC of those rounds (and of the resolver's sweep)
  bool clipped = false;           ///< some round was clipped (or the resolver clipped it)
  bool started_inside = false;    ///< a sweep began inside an object
};

/// solver -> resolver: the constrained step of one cluster, before continuous collision.
struct HandProposal {
  std::uint64_t frame = 0;
  std::uint64_t scene_frame = 0;  ///< SceneSnapshot frame the step was taken against
  std::uint64_t scene_step = 0;   ///< and its step: live, several snapshots share a frame
  bool tracked = false;
  bool started = false;
  bool lifted_start = false;
  std::vector<Pose> X_old;        ///< start of the step (a resolved state)
  std::vector<Pose> X_new;        ///< after the step
  std::vector<ContactLoad> loads;
  StepDiagnostics diag;           ///< of the step X_old -> X_new
  /// X_old -> X_new was swept, round by round, against the scene of scene_frame: a resolver
  /// with the same start and scene would find the same (safe) path and need not sweep again.
  bool swept = false;
};

/// resolver -> everyone: the final pose of one cluster for one frame.
struct HandResult {
  std::uint64_t frame = 0;
  std::uint64_t scene_frame = 0;  ///< the SceneSnapshot (frame, step) the poses were resolved against
  std::uint64_t scene_step = 0;
  bool present = false;           ///< a proposal was resolved this frame (else: held)
  bool tracked = false;
  bool started = false;
  bool lifted_start = false;
  bool loaded = false;            ///< some contact carries force
  std::vector<Pose> X;
  StepDiagnostics diag;           ///< the solver's, with the resolver's clipping (toc, clipped, joint errors)
  double force_N = 0.0;
  double ccd_us = 0.0, merge_us = 0.0;
};

/// A point force on a scene object, in application order.
struct AppliedLoad {
  int object = -1;
  int hand = -1;
  int body = -1;
  Vec3 p_W = Vec3::Zero();
  Vec3 n_W = Vec3::UnitZ();
  double lambda = 0.0;  ///< after the bounds: the object feels −λ n at p
};

/// A God object as the scene keeps dynamic objects out of it.
struct GodBody {
  int hand = -1;
  int body = -1;
  Shape shape;
  Pose X;
};

/// resolver -> scene.
struct ForceSet {
  std::uint64_t frame = 0;
  std::vector<AppliedLoad> loads;
  std::vector<GodBody> bodies;  ///< every started hand, hand order then body order
};

struct ObjectMotion {
  int index = -1;
  Pose X;
  Vec3 v = Vec3::Zero(), w = Vec3::Zero();
};

/// scene -> everyone: the dynamic objects after a step (frame 0: the initial scene).
struct SceneSnapshot {
  std::uint64_t frame = 0;
  std::uint64_t step = 0;
  bool forces_applied = false;
  int pushouts = 0;
  double step_us = 0.0;
  std::vector<ObjectMotion> objects;
};

struct SolverCounters {
  std::uint64_t steps = 0, lifted_starts = 0, solver_failures = 0, inexact_solves = 0;
  /// Searches for a free start pose of a hand not started yet (PipelineParams::start_retry apart).
  std::uint64_t start_searches = 0;
  /// Starts again after a loss of at least PipelineParams::reacquire_after (of those, the lifted
  /// ones are counted in lifted_starts too).
  std::uint64_t reacquisitions = 0;
  /// Rounds whose motion was halved because its projection opened the joints, and of those the
  /// ones that kept the previous state (ClusterStepper::kShortenings halvings did not close).
  std::uint64_t rounds_shortened = 0, rounds_kept = 0;
  /// Body sweeps, their conservative-advancement iterations (every object), and the sweeps that
  /// ran out of iterations (SweepParams::max_iterations: stopped where verified, a hit that
  /// may be none: a friction of the method, counted).
  std::uint64_t sweeps = 0, sweep_iterations = 0, sweeps_capped = 0;
  /// Of those, the ones answered without a query: the round's contact query had found nothing
  /// within a reach the motion cannot cross (or no object's box was near).
  std::uint64_t sweeps_certified = 0;
  /// Clipped rounds: every body to its own TOC (then re-closed, swept), or, where that re-closing
  /// would hit, the whole hand to TOC_min (HandSolver::clip).
  std::uint64_t per_body_clips = 0, uniform_clips = 0;
  /// Of the rounds at TOC_min, those whose re-closing would hit as well: the round does not move
  /// the hand (it stays at the round's start).
  std::uint64_t held_rounds = 0;
  /// Rounds that turned the hand back against the round before them (the rows' linearisation
  /// overshot on a curved surface): each halved the rotation trust (HandSolver::reversedRound).
  std::uint64_t reversed_rounds = 0;
  /// Rounds solved again from their start with the contacts their sweep hit (hit_resolves).
  std::uint64_t hit_resolves = 0;
  /// Of the rounds re-solved, those whose re-solve held every body while the first motion had
  /// brought an unhit body closer: that motion was clipped instead.
  std::uint64_t resolves_undone = 0;
};
struct ResolverCounters {
  std::uint64_t frames = 0, clipped_steps = 0, started_inside = 0, forces_clamped = 0, held = 0;
  std::uint64_t trusted = 0;      ///< proposals taken as swept by their solver (same start, scene)
  std::uint64_t reswept = 0;      ///< proposals swept again here (another start or scene)
  std::uint64_t held_back = 0;    ///< of those, clipped and re-closed into the scene: kept at the last result
};
struct SceneCounters {
  std::uint64_t steps = 0, scene_pushouts = 0, pushout_unresolved = 0;
  std::uint64_t pushout_restored = 0;  ///< objects put back to their pose before the step (unresolved push-outs)
};

/// One hand cluster's solver: start / lift, contacts, the Gauss step (ClusterStepper).
class HandSolver {
 public:
  /// scene and model must outlive the solver. Throws std::invalid_argument on bad parameters.
  HandSolver(const Scene& scene, const HandModel& model, const PipelineParams& params);
  ~HandSolver();

  /// Object poses of a snapshot (the solver's own copy of the collision world).
  void setScene(const SceneSnapshot& snapshot);
  /// The resolver's result for this hand becomes the start of the next step.
  void adopt(const HandResult& result);
  /// A solver that (re)starts while its hand already exists (a restarted process, the resolver's
  /// last HandState at hand): the hand goes on from its resolved pose instead of jumping to the
  /// new target (which the sweep would never see). No-op once started or for an unstarted result.
  void resume(const HandResult& result);
  const HandProposal& step(const HandInput& input, std::uint64_t frame);
  /// From now on the bodies' queries are jobs of `share`'s lane `lane` (taken by this solver's
  /// thread and by the pool's idle threads) instead of this solver's own body threads; the pool
  /// names the thread each step() runs on with setShareThread(). Only where the solver has a
  /// collision world for each of the share's helpers (body_threads ≥ the share's threads, and
  /// more than one body): false, and nothing changed, otherwise (its bodies stay on its own
  /// threads: a one-body tool on its caller's).
  bool useShare(JobShare* share, int lane);
  void setShareThread(int thread) { share_thread_ = thread; }

  bool started() const { return started_; }
  const ClusterStepper& stepper() const { return *stepper_; }
  const std::vector<Contact>& contacts() const { return contacts_; }
  const SolverCounters& counters() const { return counters_; }
  /// The rotation trust the next round's motion clamp gets (StepInput::rotation_trust).
  double rotationTrust() const { return rotation_trust_; }
  const CollisionWorld& collision() const { return collision_; }
  /// Adds every object's God-side cost (CollisionWorld::costs) of this solver's collision worlds
  /// (the caller's and each body thread's) to `sum` (one entry per scene object).
  void addCosts(std::vector<ObjectCost>* sum) const;

 private:
  void countSweep(const geo::SweepResult& s) {
    ++counters_.sweeps;
    if (s.iterations == 0) ++counters_.sweeps_certified;
    counters_.sweep_iterations += static_cast<std::uint64_t>(s.iterations);
    if (s.capped) ++counters_.sweeps_capped;
  }
  /// f(b, world) for every body b, spread over the body threads, each call with that thread's
  /// own collision world (the same scene, its own scratch). `busy`: how many of the calls are
  /// expected to query the meshes; below kMinParallelBodies they all run on the caller's thread
  /// (waking a thread costs more than a few certified bodies: the results are the same).
  template <class F>
  void forEachBody(const F& f, int busy);
  /// freeStart's pushes along the exit normals at most (the bundled recordings over the bunny and
  /// the fandisk at 0.06-0.6 m: 45 of 46 starts settle within 46 pushes, one never; with 16, 9
  /// were lifted straight up by 10-22 cm, 7 of them where a way out to the side was shorter).
  static constexpr int kStartPushes = 64;
  static constexpr int kMinParallelBodies = 2;
  /// Body b's contact queries take every triangle of the contact shell as a candidate: a box, or
  /// a body one of whose last kShellSweeps sweeps hit.
  bool shellFor(size_t b) const { return blocked_[b] > 0 || model_.bodies[b].shape.type == ShapeType::Box; }
  /// A body that hit keeps its shell this many of its sweeps (the hit's included). With the last
  /// sweep alone (1) a body sliding along a surface lost the shell as soon as the round solved
  /// again with its hit's contacts swept free, and hit the next round (thumb.1 of confidence2's
  /// left hand, round after round): solved again 122 / 133 / 301 times on pinch-bunny /
  /// splay-fandisk / twohands-bunny, 70 / 51 / 274 with 4 (README, twenty-ninth session).
  static constexpr unsigned char kShellSweeps = 4;
  bool start(const HandInput& in);
  /// The nearest free rigid translation of the poses X (shift; zero when X is free already).
  bool freeStart(std::vector<Pose>* X, Vec3* shift) const;
  void generateContacts(const HandInput& in);
  /// Every body's motion X_from -> X_to swept (or certified free by clearOf) into body_sweeps_,
  /// spread over the body threads; not counted.
  void sweepBodies(const std::vector<Pose>& X_from, const std::vector<Pose>& X_to);
  /// TOC_min of the stepper's last motion (previous -> current poses) against the scene; each
  /// body's own TOC in body_toc_.
  double sweepLastMotion(bool* started_inside);
  /// The contacts of every body the last sweep hit (from outside), at its own TOC pose, moved
  /// back with the body to the round's start (stepper's previous poses) and merged into contacts_
  /// (replacing those of the same key). False when they brought nothing the rows lacked.
  bool addHitContacts();
  /// Clips the last motion (METHOD.md §2 step 5): see stages.cc.
  JointErrors clip(double toc_min);
  /// Whether the round just taken (round_start_ -> the stepper's poses) turned back against the
  /// round before it (*have_last: one was taken, in this frame or as the last one's last round, since the
  /// hand started or was last tracked; set here); counted, and the rotation trust halved (else
  /// grown by kRotationTrustGrowth, or doubled after a round that moved less than kReversalFloor,
  /// up to 1).
  bool reversedRound(bool* have_last);
  /// m: the most any body with a valid target came closer to it from X0 to X1, counting |Δp| +
  /// bounding radius × angle (0 when none did).
  /// m: the most any body moved from X0 to X1 (|Δp| + bounding radius × angle).
  double largestMotion(const std::vector<Pose>& X0, const std::vector<Pose>& X1) const;
  /// toc (per body, or nullptr): only the bodies whose TOC is 1 (unhit) count.
  double largestGain(const std::vector<Pose>& X0, const std::vector<Pose>& X1, const HandInput& in,
                     const std::vector<double>* toc) const;
  /// A round's first solved motion and its sweep, while its re-solves are tried (step()).
  struct FirstAttempt {
    std::vector<Pose> X1;
    StepReport report;
    std::vector<ContactLoad> loads;
    std::vector<geo::SweepResult> sweeps;
    std::vector<double> body_toc, caps;
    std::vector<unsigned char> blocked;
    double toc = 1.0;
  };
  FirstAttempt first_;
  std::vector<Pose> round_start_;
  std::vector<Vec3> round_motion_, last_round_motion_;  // per body: Δp, ρ θ
  // The rotation trust region (StepInput::rotation_trust), kept across frames. A palm pressed
  // onto a curved surface towards targets deep inside it turns about its one contact until
  // another point of its face meets the surface, and the next round, from the contact found
  // there, turns it back: rows linear in the rotation overshoot. Seen on pinch + bunny: the palm
  // rocked 0.06 rad every round, the fingertips 1-3 mm apart from frame to frame (50 % of the
  // body-frames turned back), three clipped rounds a frame. Halving the rotation allowed on each
  // round that turns back (and growing it back by 10 % per round that does not) lets the hand
  // settle; only the rotation: scaling the translation too slowed sliding (excess lag p95 on the
  // two-hand bunny case 58 -> 86 mm). A round that moves the hand less than the reversal floor
  // (no turn it takes could count as one) doubles the trust instead: a damping cannot hold a hand
  // still. Growing back by 10 % there too, the trust stayed near its floor for tens of frames under
  // a hand pressed towards targets far inside an object after a burst of reversals, and the hand
  // froze (pinch on the bunny at 0.2 and 0.25 m: 15 and 27 of 166 windows; now 6 and 0).
  double rotation_trust_ = 1.0;
  static constexpr double kMinRotationTrust = 1.0 / 32;
  static constexpr double kRotationTrustGrowth = 1.1;
  static constexpr double kStillTrustGrowth = 2.0;  ///< after a round that moved less than the floor
  static constexpr double kReversalCos = -0.5;     ///< a turn of more than 120°
  static constexpr double kReversalFloor = 1e-4;   ///< m: rounds moving less are no evidence

  const HandModel& model_;
  PipelineParams params_;
  CollisionWorld collision_;
  std::unique_ptr<ClusterStepper> stepper_;
  std::unique_ptr<Workers> workers_;                    // body threads (PipelineParams::body_threads)
  std::vector<std::unique_ptr<CollisionWorld>> slot_worlds_;  // threads 1 …: their own collision worlds
  JobShare* share_ = nullptr;  // useShare: the pool's job share (instead of workers_), its lane,
  int share_lane_ = 0;         // and the pool thread the current step runs on
  int share_thread_ = 0;
  std::vector<std::vector<Contact>> body_contacts_;     // per body, merged in body order
  std::vector<geo::SweepResult> body_sweeps_;           // per body
  std::vector<unsigned char> certified_;                // per body: clearOf its motion (no query)
  bool started_ = false;
  int start_wait_ = 0;       // tracked steps before the next start search (after a failed one)
  int untracked_steps_ = 0;  // steps since the started hand was last tracked (saturating)
  static constexpr int kUntrackedCap = 1 << 30;
  std::uint64_t scene_frame_ = 0, scene_step_ = 0;
  JointErrors last_errors_;
  std::vector<Contact> contacts_;
  std::vector<Contact> clip_contacts_;  // scratch: contacts at a clipped pose
  std::vector<std::vector<Contact>> hit_contacts_;  // per body: at its TOC pose (addHitContacts)
  std::vector<unsigned char> blocked_;  // per body: sweeps left with shell contacts (kShellSweeps after a hit)
  // Per body: stuck_rotation where its last sweep hit at once (TOC < 1e-3, from outside), a
  // quarter of its last cap where it hit at once under one (down to kMinRotationCap), else
  // +inf (StepInput::rotation_cap).
  std::vector<double> rotation_cap_;
  std::vector<double> round_caps_;  // rotation_cap_ as the round started (its sweeps update from these)
  static constexpr double kMinRotationCap = 1e-4;  ///< rad
  std::vector<double> body_toc_;        // per body: TOC of the last sweep
  std::vector<Pose> X0_, X1_, X_clip_;
  std::vector<double> reclose_toc_;     // per body: TOC of the re-closing motion
  // Per body: nothing was within clear_reach_ (< 0: something was) of it at X_clear_ (this
  // round's contact query), so motions that stay within that room need no sweep (clearOf).
  std::vector<double> clear_reach_;
  std::vector<Pose> X_clear_;
  // Per body: what its last contact query (the round's, or a re-closing's) found of the whole
  // shape at X_query_: d(0) of a sweep from there, valid until the scene moves (start_valid_).
  std::vector<CollisionWorld::QueryStart> query_start_;
  std::vector<Pose> X_query_;
  std::vector<std::vector<Contact>> persist_;  // per body: its last hit's contacts
  std::vector<unsigned char> start_valid_;
  /// Body b's QueryStart for a sweep from X_from, or nullptr (another pose or scene).
  const CollisionWorld::QueryStart* startAt(size_t b, const Pose& X_from) const;
  bool clearOf(size_t b, const Pose& X_a, const Pose& X_b, double room) const;
  /// The room a sweep could still stop a body in: its largest stop distance and tolerance.
  double sweepRoom() const { return params_.sweep.stop_distance + params_.sweep.tolerance; }
  static constexpr int kRecloseAttempts = 3;
  /// A hit's contact that differs from the round's one of the same key by less (distance and
  /// point, m; normal, unit vector) brings nothing new.
  static constexpr double kHitContactChange = 1e-6, kHitNormalChange = 1e-4;
  /// A clamped round goes on while a clamp scale grows by more than this factor per round.
  static constexpr double kRoundProgress = 1.05;
  /// m: a first round bringing any body this much closer to its target (largestGain) is progress
  /// even where the most-clamped body asks for no less. Without it a hand sliding on a flat table
  /// under the clamp fell 8 mm behind (confidence2, left), and a box sliding 1 cm a frame with its
  /// target 5 cm under the plane trailed by the one-round fixed point (7.7 mm; 2.0 mm with it).
  /// Summed over the hand at 5 mm instead, that box kept one round a frame (README, issue 10).
  static constexpr double kRoundGainProgress = 5e-4;
  /// The last frame ended on a clamped round that gained nothing on the round before: its asked
  /// scales. The next frame's first round goes on only if it gains on them (a hand held against
  /// an object while its targets sit far inside asks the same every frame; a second round there
  /// moves nothing). Cleared by a start, a loss and a frame that ended otherwise.
  bool carry_valid_ = false;
  bool have_last_motion_ = false;  ///< last_round_motion_ holds a round (reversedRound compares)
  double carry_free_scale_ = 1.0, carry_least_scale_ = 1.0;
  std::vector<Pose> X_start_;
  HandProposal proposal_;
  SolverCounters counters_;
  int trace_ = 0;
};

/// The final stage: continuous collision of every hand against the scene, TOC clipping with
/// re-closed joints, merged and bounded forces.
class Resolver {
 public:
  /// dynamic[o]: forces go to object o (the scene simulates it and it has mass).
  Resolver(const Scene& scene, std::vector<const HandModel*> hands, const PipelineParams& params);
  ~Resolver();

  void setScene(const SceneSnapshot& snapshot);
  /// proposals.size() == hand count; nullptr: no proposal for that hand this frame (held).
  void resolve(const std::vector<const HandProposal*>& proposals, std::uint64_t frame);

  int handCount() const { return static_cast<int>(hands_.size()); }
  const HandResult& result(int hand) const { return hands_[static_cast<size_t>(hand)].result; }
  const ForceSet& forces() const { return forces_; }
  const ResolverCounters& counters() const { return counters_; }
  const CollisionWorld& collision() const { return collision_; }
  /// Exact penetration (m, ≥ 0) of a hand's last result against the reference meshes of the
  /// scene as the resolver last saw it.
  double penetration(int hand, int* object = nullptr) const;

 private:
  struct Hand {
    const HandModel* model = nullptr;
    std::unique_ptr<JointProjector> projector;  // re-closes a clipped motion's joints
    HandResult result;
    std::vector<Contact> contacts;            // scratch
    std::vector<Pose> X_from;                 // scratch: start of the resolved motion
    std::vector<Pose> X_toc;                  // scratch: the clipped poses before re-closing
    std::vector<Pose> X_clip;                 // scratch: those poses re-closed
  };
  void applyForces(int h, const HandProposal& p);

  PipelineParams params_;
  CollisionWorld collision_;
  std::uint64_t scene_frame_ = 0, scene_step_ = 0;
  std::vector<unsigned char> dynamic_;
  std::vector<Hand> hands_;
  ForceSet forces_;
  ResolverCounters counters_;
  int trace_ = 0;
};

/// The Bullet world: applies forces, steps, pushes dynamic objects out of God objects.
class SceneStage {
 public:
  /// params.simulate = false: nothing moves, snapshots list no objects.
  SceneStage(const Scene& scene, const PipelineParams& params, const PhysicsParams& physics);
  ~SceneStage();

  /// The initial scene (frame 0).
  const SceneSnapshot& initial();
  /// One frame of dt = params.step.dt. forces == nullptr: step without hand forces (live mode).
  const SceneSnapshot& step(const ForceSet* forces, std::uint64_t frame);

  const PhysicsWorld* physics() const { return physics_.get(); }
  const SceneCounters& counters() const { return counters_; }
  const SceneSnapshot& snapshot() const { return snapshot_; }

 private:
  void fill();

  PipelineParams params_;
  CollisionWorld collision_;
  std::unique_ptr<PhysicsWorld> physics_;
  SceneSnapshot snapshot_;
  SceneCounters counters_;
  std::vector<Pose> before_;  ///< the objects' poses before the current step
};

/// Bullet's parameters for a tracker frame rate: fixed steps of 1/physics_hz, enough substeps
/// for one frame (what godhand-bench and godhand-scene both use, so that they agree bit for bit).
PhysicsParams physicsParamsFor(double frame_rate, double physics_hz);

/// Whether forces of the God hand go to this object (it has mass and Bullet simulates it).
bool receivesForces(const SceneObject& object, const PipelineParams& params);

}  // namespace godhand
