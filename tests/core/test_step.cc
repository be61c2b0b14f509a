// One step of one cluster (core/step, METHOD.md §2, §5, §6), with ClusterStepper and the default
// StepParams (Δt = 1e-3 s, k_s = 1e6 1/s², so k Δt² = 1: a free God object reaches its target in
// one step).
//
// Oracles, none taken from the code under test:
//   - free space: the target itself (k Δt² = 1), and the order of the linearisation error;
//   - joints: jointErrors() gap / lock / limit after every step (the step's own post-condition);
//   - contacts: exact signed distances recomputed from the new poses with the shape geometry, the
//     margin δ, the tangential target motion, m k × depth for the normal force, and the KKT
//     conditions checked independently (stationarity rebuilt from the model's mass and inertia);
//   - extremes: finiteness, counters and flags; determinism: FNV-1a hashes of the pose bytes.
// Measured figures are printed as "[figure] name = value" lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "common/files.h"
#include "model/hand_model.h"
#include "step/cluster_step.h"
#include "../pipeline/probe_model.h"
#include "../test_sanitized.h"

namespace godhand {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

void figure(const char* name, double value) {
  std::printf("[figure] %s = %.3e\n", name, value);
  ::testing::Test::RecordProperty(name, std::to_string(value));
}

const HandModel& hand16() {
  static const HandModel m = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  return m;
}
const HandModel& tool1() {
  static const HandModel m = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/tool1.pbtxt");
  return m;
}
const HandModel& ball() {
  static const HandModel m = HandModel::fromText(
      "name: \"ball\"\n"
      "bodies { name: \"ball\" sphere { radius: 0.01 } mass: 0.01 }\n",
      "ball.pbtxt");
  return m;
}

// ---------------------------------------------------------------------------------------------
// Helpers

// Draws are taken one per statement, left to right: C++ leaves the order of function
// arguments and of a binary operator's operands unspecified, so Vec3(g(), g(), g()) or
// unit() * uniform() gives gcc and clang different instances from one seed.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(gen_); }
  Vec3 unit() {
    std::normal_distribution<double> g(0.0, 1.0);
    for (;;) {
      const double x = g(gen_);
      const double y = g(gen_);
      const double z = g(gen_);
      const Vec3 v(x, y, z);
      if (v.norm() > 1e-3) return v.normalized();
    }
  }
  /// Uniform direction, length uniform in [0, max_len].
  Vec3 vector(double max_len) {
    const Vec3 u = unit();
    return u * uniform(0.0, max_len);
  }
  Quat rotation(double max_angle) { return expRotation(vector(max_angle)); }

 private:
  std::mt19937_64 gen_;
};

/// X_new = {p + d.p, d.q q}: a rigid motion of the model frame about its own origin.
Pose moveRigid(const Pose& X, const Vec3& dp, const Quat& dq) { return {X.p + dp, (dq * X.q).normalized()}; }

double maxPositionError(const std::vector<Pose>& X, const std::vector<Pose>& T) {
  double e = 0.0;
  for (size_t i = 0; i < X.size(); ++i) e = std::max(e, (X[i].p - T[i].p).norm());
  return e;
}
double maxRotationError(const std::vector<Pose>& X, const std::vector<Pose>& T) {
  double e = 0.0;
  for (size_t i = 0; i < X.size(); ++i) e = std::max(e, logRotation(T[i].q * X[i].q.conjugate()).norm());
  return e;
}
bool allFinite(const std::vector<Pose>& X) {
  for (const Pose& P : X)
    if (!P.p.allFinite() || !P.q.coeffs().allFinite()) return false;
  return true;
}

/// Child pose with joint angles (θ1, θ2) and coincident anchors: R_WJc = R_WJp Rx(θ1) Ry(θ2).
Pose childPose(const Joint& j, const Pose& X_WP, double t1, double t2) {
  const Quat q_WJc = X_WP.q * j.X_PJ.q * Quat(Eigen::AngleAxisd(t1, Vec3::UnitX())) *
                     Quat(Eigen::AngleAxisd(t2, Vec3::UnitY()));
  Pose X_WC;
  X_WC.q = (q_WJc * j.X_CJ.q.conjugate()).normalized();
  X_WC.p = X_WP * j.X_PJ.p - X_WC.q * j.X_CJ.p;
  return X_WC;
}

/// Forward kinematics from the palm pose with the same flexion on every joint (abduction 0).
/// hand16 lists every joint after the joint of its parent.
std::vector<Pose> curledPose(const HandModel& m, const Pose& X_WM, double flexion) {
  std::vector<Pose> X = m.restPoses(X_WM);
  for (const Joint& j : m.joints) X[static_cast<size_t>(j.child)] = childPose(j, X[static_cast<size_t>(j.parent)], flexion, 0.0);
  return X;
}

/// Shape features that can touch a plane: sphere centre, capsule segment ends, box corners
/// (body frame) with the radius to subtract.
struct Feature {
  Vec3 p_B;
  double radius;
};
std::vector<Feature> features(const Body& b) {
  std::vector<Feature> f;
  switch (b.shape.type) {
    case ShapeType::Sphere: f.push_back({Vec3::Zero(), b.shape.radius}); break;
    case ShapeType::Capsule:
      f.push_back({Vec3(0, 0, -b.shape.half_length), b.shape.radius});
      f.push_back({Vec3(0, 0, b.shape.half_length), b.shape.radius});
      break;
    case ShapeType::Box: {
      const Vec3 h = b.shape.half_extents;
      for (int i = 0; i < 8; ++i)
        f.push_back({Vec3(i & 1 ? h.x() : -h.x(), i & 2 ? h.y() : -h.y(), i & 4 ? h.z() : -h.z()), 0.0});
      break;
    }
  }
  return f;
}

/// Exact signed distance of body b's shape above the plane z = h (negative = penetrating).
double heightAbovePlane(const Body& b, const Pose& X, double h) {
  double d = std::numeric_limits<double>::infinity();
  for (const Feature& f : features(b)) d = std::min(d, (X * f.p_B).z() - f.radius - h);
  return d;
}
double minHeightAbovePlane(const HandModel& m, const std::vector<Pose>& X, double h) {
  double d = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < X.size(); ++i) d = std::min(d, heightAbovePlane(m.bodies[i], X[i], h));
  return d;
}

/// Contacts of every feature within `reach` of the plane z = h (normal +z), as the collision
/// stage would generate them at the current poses: the point is the feature's lowest point.
void planeContacts(const HandModel& m, const std::vector<Pose>& X, double h, double reach, std::vector<Contact>& out) {
  out.clear();
  for (size_t i = 0; i < X.size(); ++i) {
    const auto fs = features(m.bodies[i]);
    for (size_t k = 0; k < fs.size(); ++k) {
      const Vec3 c = X[i] * fs[k].p_B;
      const double d = c.z() - fs[k].radius - h;
      if (d > reach) continue;
      Contact ct;
      ct.body = static_cast<int>(i);
      ct.p_W = c - fs[k].radius * Vec3::UnitZ();
      ct.n_W = Vec3::UnitZ();
      ct.distance = d;
      ct.key = i * 16 + k + 1;
      ct.object = 0;
      out.push_back(ct);
    }
  }
}

std::uint64_t fnv1a(const std::vector<Pose>& X, std::uint64_t h = 1469598103934665603ull) {
  auto mix = [&](double v) {
    unsigned char bytes[sizeof(double)];
    std::memcpy(bytes, &v, sizeof v);
    for (unsigned char c : bytes) {
      h ^= c;
      h *= 1099511628211ull;
    }
  };
  for (const Pose& P : X) {
    mix(P.p.x()); mix(P.p.y()); mix(P.p.z());
    mix(P.q.w()); mix(P.q.x()); mix(P.q.y()); mix(P.q.z());
  }
  return h;
}

/// Targets around a slowly moving rigid hand pose, each body independently perturbed by up to
/// `offset` m and `angle` rad (not joint-consistent).
struct JitteredHand {
  explicit JitteredHand(std::uint64_t seed, Vec3 centre_W = Vec3(0, 0, 0.2)) : rng(seed), centre(centre_W) {}
  Pose base(int step) const {
    const double a = 2.0 * kPi * step / 4000.0;
    Pose X;
    X.p = centre + Vec3(0.05 * std::cos(a), 0.05 * std::sin(a), 0.02 * std::sin(2 * a));
    X.q = expRotation(Vec3(0.3 * std::sin(a), 0.2 * std::sin(3 * a), a));
    return X;
  }
  void targets(const HandModel& m, int step, double offset, double angle, std::vector<Pose>& T) {
    T = m.restPoses(base(step));
    for (Pose& P : T) {
      const Vec3 dp = rng.vector(offset);
      P = moveRigid(P, dp, rng.rotation(angle));
    }
  }
  Rng rng;
  Vec3 centre;
};

// ---------------------------------------------------------------------------------------------
// Free-space tracking

TEST(HandFreeSpace, TranslatedRestPoseIsTrackedExactly) {
  const HandModel& m = hand16();
  ClusterStepper s(m, StepParams{});
  Pose X_WM;
  X_WM.p = Vec3(0.1, -0.2, 0.3);
  X_WM.q = expRotation(Vec3(0.3, -0.2, 1.0));
  s.reset(m.restPoses(X_WM));
  Rng rng(11);
  double err = 0, rot = 0, gap = 0;
  for (int i = 0; i < 1000; ++i) {
    X_WM.p += rng.vector(0.005);
    const auto T = m.restPoses(X_WM);
    const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
    ASSERT_EQ(r.solve.status, SolveStatus::Converged) << "step " << i;
    err = std::max(err, maxPositionError(s.poses(), T));
    rot = std::max(rot, maxRotationError(s.poses(), T));
    gap = std::max(gap, r.joint_errors.gap);
    ASSERT_LT(maxPositionError(s.poses(), T), 1e-9) << "step " << i;
    ASSERT_LT(maxRotationError(s.poses(), T), 1e-9) << "step " << i;
  }
  figure("free_translation_max_position_error_m", err);
  figure("free_translation_max_rotation_error_rad", rot);
  EXPECT_LT(gap, 1e-9);
}

/// Runs `steps` rigid motions of up to 5 mm and `angle` rad per step; returns the largest
/// position error after a step (and its rotation error).
std::pair<double, double> rigidTracking(double angle, int steps, double* final_error = nullptr, double flexion = 0.0) {
  const HandModel& m = hand16();
  ClusterStepper s(m, StepParams{});
  Pose X_WM;
  X_WM.p = Vec3(0.1, -0.2, 0.3);
  s.reset(curledPose(m, X_WM, flexion));
  Rng rng(12);
  double err = 0, rot = 0;
  for (int i = 0; i < steps; ++i) {
    const Vec3 dp = rng.vector(0.005);
    const Vec3 axis = rng.unit();
    const double a = rng.uniform(0.0, 1.0) * angle;
    X_WM = moveRigid(X_WM, dp, expRotation(axis * a));
    const auto T = curledPose(m, X_WM, flexion);
    const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
    EXPECT_EQ(r.solve.status, SolveStatus::Converged);
    EXPECT_LT(r.joint_errors.gap, 1e-9);
    EXPECT_LT(r.joint_errors.lock, 1e-9);
    EXPECT_LE(r.joint_errors.limit, 1e-9);
    err = std::max(err, maxPositionError(s.poses(), T));
    rot = std::max(rot, maxRotationError(s.poses(), T));
  }
  if (final_error) {  // target held still: the lag must vanish (no "stuck hand")
    const auto T = curledPose(m, X_WM, flexion);
    for (int i = 0; i < 3; ++i) s.step({T.data(), nullptr, nullptr, 0});
    *final_error = std::max(maxPositionError(s.poses(), T), maxRotationError(s.poses(), T));
  }
  return {err, rot};
}

// Rotating rigid motions (5 mm and 0.05 rad per step, up to 0.025 rad with the fingers curled
// away from every limit): joint-consistent targets are reached after every step. The
// velocity-level rows alone leave a second-order lag (≈ ½θ²L, measured 3e-5 m before the
// projection pulled towards the unconstrained goal); the sequential-QP projection removes it.
TEST(HandFreeSpace, RotatingRigidMotionIsTrackedEveryStep) {
  double still = 1.0;
  const auto full = rigidTracking(0.05, 300, &still);
  const auto half = rigidTracking(0.025, 300);
  const auto curled = rigidTracking(0.05, 300, nullptr, 0.5);
  figure("free_rotation_0.05rad_max_position_error_m", full.first);
  figure("free_rotation_0.05rad_max_rotation_error_rad", full.second);
  figure("free_rotation_0.025rad_max_position_error_m", half.first);
  figure("free_rotation_0.05rad_curled_max_position_error_m", curled.first);
  figure("free_rotation_error_after_target_stops", still);
  EXPECT_LT(full.first, 1e-9);
  EXPECT_LT(full.second, 1e-9);
  EXPECT_LT(half.first, 1e-9);
  EXPECT_LT(curled.first, 1e-9);
  EXPECT_LT(curled.second, 1e-9);
  EXPECT_LT(still, 1e-9);
}

// The rotation trust (StepInput::rotation_trust) scales the clamp's rotation limit only: a free
// body asked to turn 1 rad with a 0.5 rad clamp turns 0.5 rad, and 0.125 rad under a trust of
// 1/4 (analytic: one free body reaches the scaled goal exactly); the asked scale stays the clamp's
// own (0.5), a translation-only goal is not slowed, and a trust outside (0, 1) is none.
TEST(HandFreeSpace, RotationTrustScalesTheClampsRotationOnly) {
  const HandModel& m = ball();
  for (const bool apart : {false, true}) {  // both clamps: one scale, or bodies near contacts apart
    SCOPED_TRACE(apart ? "clamp_contact_bodies_apart" : "one scale");
    StepParams prm;
    prm.max_step_rotation = 0.5;
    prm.max_step_rotation_in_contact = 0.5;
    prm.max_step_translation = 0.03;
    prm.clamp_contact_bodies_apart = apart;
    std::unique_ptr<ClusterStepper> s;
    const StepReport* r = nullptr;
    // One step from rest towards `target` under `trust`: the angle turned (rad).
    auto turned = [&](double trust, const Pose& target) {
      s = std::make_unique<ClusterStepper>(m, prm);
      s->reset({Pose{}});
      StepInput in{&target, nullptr, nullptr, 0};
      in.rotation_trust = trust;
      r = &s->step(in);
      return logRotation(s->poses()[0].q).norm();
    };
    const Pose turn{Vec3::Zero(), Quat(Eigen::AngleAxisd(1.0, Vec3::UnitZ()))};
    EXPECT_NEAR(turned(1.0, turn), 0.5, 1e-9);
    EXPECT_NEAR(r->motion_scale, 0.5, 1e-12);
    EXPECT_NEAR(turned(0.25, turn), 0.125, 1e-9);
    EXPECT_NEAR(r->motion_scale, 0.125, 1e-12);
    EXPECT_NEAR(r->asked_motion_scale, 0.5, 1e-12);
    EXPECT_NEAR(r->asked_free_motion_scale, 0.5, 1e-12);
    for (double none : {0.0, -1.0, 2.0, std::numeric_limits<double>::quiet_NaN()}) {
      EXPECT_NEAR(turned(none, turn), 0.5, 1e-9) << none;
    }
    const Pose slide{Vec3(0.02, 0, 0), Quat::Identity()};  // within the translation clamp
    turned(0.25, slide);
    EXPECT_NEAR(s->poses()[0].p.x(), 0.02, 1e-9);
    EXPECT_EQ(r->motion_scale, 1.0);
  }
}

// ---------------------------------------------------------------------------------------------
// Joints and limits

TEST(HandJoints, GapStaysClosedUnderInconsistentTargets) {
  const HandModel& m = hand16();
  ClusterStepper s(m, StepParams{});
  JitteredHand gen(21);
  s.reset(m.restPoses(gen.base(0)));
  std::vector<Pose> T;
  double gap = 0, lock = 0, limit = 0, err = 0;
  int not_converged = 0, limit_rows = 0;
  const auto t0 = std::chrono::steady_clock::now();
  constexpr int kSteps = test_support::sanitizedTrials(10000, 5);
  for (int i = 0; i < kSteps; ++i) {
    gen.targets(m, i, 0.005, 0.1, T);
    const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
    not_converged += r.solve.status != SolveStatus::Converged;
    limit_rows = std::max(limit_rows, r.limit_rows);
    const JointErrors e = jointErrors(m, s.poses().data());
    gap = std::max(gap, e.gap);
    lock = std::max(lock, e.lock);
    limit = std::max(limit, e.limit);
    err = std::max(err, maxPositionError(s.poses(), T));
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  figure("jitter_10k_max_joint_gap_m", gap);
  figure("jitter_10k_max_lock_error", lock);
  figure("jitter_10k_max_limit_violation_rad", limit);
  figure("jitter_10k_max_position_error_m", err);
  figure("jitter_10k_runtime_s", secs);
  figure("jitter_10k_max_limit_rows", limit_rows);
  EXPECT_LE(gap, 1e-9);
  EXPECT_LE(lock, 1e-9);
  EXPECT_LE(limit, 1e-9);
  EXPECT_EQ(not_converged, 0);
  EXPECT_TRUE(allFinite(s.poses()));
  EXPECT_EQ(s.counters().solver_failures, 0u);
  EXPECT_EQ(s.counters().states_kept, 0u);
}

struct LimitFigures {
  double gap = 0, lock = 0, limit = 0, off_bound = 0;
  int incomplete_flags = 0, steps_over_1e9 = 0, unflagged_over_1e9 = 0;
  std::vector<double> end_angle;  ///< each joint's angle 1 after the last step
};

/// Drives every joint towards `flexion` (jump: at once; else ramped over 150 steps), 300 steps.
LimitFigures driveFlexion(double flexion, bool jump, const StepParams& prm, const HandModel& m = hand16()) {
  ClusterStepper s(m, prm);
  Pose X_WM;
  X_WM.p = Vec3(0, 0, 0.2);
  s.reset(m.restPoses(X_WM));
  LimitFigures f;
  for (int i = 0; i < 300; ++i) {
    const double a = jump ? flexion : flexion * std::min(1.0, i / 150.0);
    const auto T = curledPose(m, X_WM, a);
    const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
    EXPECT_TRUE(allFinite(s.poses()));
    EXPECT_NE(r.solve.status, SolveStatus::NumericalFailure);
    const JointErrors e = jointErrors(m, s.poses().data());
    f.gap = std::max(f.gap, e.gap);
    f.lock = std::max(f.lock, e.lock);
    f.limit = std::max(f.limit, e.limit);
    const bool over = std::max({e.gap, e.lock, e.limit}) > 1e-9;
    const bool flagged = r.flags & kFlagProjectionIncomplete;
    f.incomplete_flags += flagged;
    f.steps_over_1e9 += over;
    f.unflagged_over_1e9 += over && !flagged;
  }
  // How far each joint ends from the bound it is pulled towards.
  for (const Joint& j : m.joints) {
    const auto a = jointAngles(j, s.poses()[static_cast<size_t>(j.parent)], s.poses()[static_cast<size_t>(j.child)]);
    const double bound = flexion > 0 ? j.limits[0].upper : j.limits[0].lower;
    f.off_bound = std::max(f.off_bound, std::abs(a[0] - bound));
    f.end_angle.push_back(a[0]);
  }
  return f;
}

void reportLimits(const std::string& tag, const LimitFigures& f) {
  figure(("limits_" + tag + "_max_limit_violation_rad").c_str(), f.limit);
  figure(("limits_" + tag + "_max_joint_gap_m").c_str(), f.gap);
  figure(("limits_" + tag + "_max_lock_error").c_str(), f.lock);
  figure(("limits_" + tag + "_max_distance_from_bound_rad").c_str(), f.off_bound);
  figure(("limits_" + tag + "_steps_above_1e-9").c_str(), f.steps_over_1e9);
}

// Targets ramped to 150° (resp. −60°) at every joint: each joint ends on its upper (lower)
// bound, and no step leaves a limit, joint or lock error above 1e-9, with default parameters.
// 150° at every joint puts the thumb's outer phalanges' targets more than 180° from where its
// limits hold them (cmc 50° + mcp 60° against 300°), so their shortest turn is backwards: with the
// shipped model's rotational weight (the farthest point's, which weighs the turn more against the
// move) the thumb's mcp is pulled to its lower bound instead. With the solid inertia every joint
// ends on its upper bound; with the shipped weight every other joint does and every limit holds.
TEST(HandLimits, RampTo150DegreesHoldsUpperLimits) {
  const HandModel solid = testing::withRotationWeight(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt", "SOLID");
  const LimitFigures f = driveFlexion(150 * kDeg, false, StepParams{}, solid);
  reportLimits("curl150_ramp", f);
  EXPECT_LE(f.limit, 1e-9);
  EXPECT_LE(f.gap, 1e-9);
  EXPECT_LE(f.lock, 1e-9);
  EXPECT_LT(f.off_bound, 1e-9);
  const LimitFigures d = driveFlexion(150 * kDeg, false, StepParams{});
  reportLimits("curl150_ramp_shipped_weight", d);
  EXPECT_LE(d.limit, 1e-9);
  EXPECT_LE(d.gap, 1e-9);
  EXPECT_LE(d.lock, 1e-9);
  const HandModel& m = hand16();
  for (size_t k = 0; k < m.joints.size(); ++k) {
    const Joint& j = m.joints[k];
    EXPECT_NEAR(d.end_angle[k], j.name == "thumb.mcp" ? j.limits[0].lower : j.limits[0].upper, 1e-9) << j.name;
  }
}

TEST(HandLimits, RampBack60DegreesHoldsLowerLimits) {
  const LimitFigures f = driveFlexion(-60 * kDeg, false, StepParams{});
  reportLimits("back60_ramp", f);
  EXPECT_LE(f.limit, 1e-9);
  EXPECT_LE(f.gap, 1e-9);
  EXPECT_LE(f.lock, 1e-9);
  EXPECT_LT(f.off_bound, 1e-9);
}

TEST(HandLimits, JumpBack60DegreesHoldsLowerLimits) {
  const LimitFigures f = driveFlexion(-60 * kDeg, true, StepParams{});
  reportLimits("back60_jump", f);
  EXPECT_LE(f.limit, 1e-9);
  EXPECT_LE(f.gap, 1e-9);
  EXPECT_LE(f.lock, 1e-9);
  EXPECT_LT(f.off_bound, 1e-9);
}

// Targets jumping to 150° at once: single steps rotate phalanxes by more than 1 rad, and the
// post-stabilisation's Newton iterations need 4–5 iterations to close the joints to round-off
// (quadratic convergence: 1e-2 → 1e-3 → 1e-4 → 1e-7 → 1e-12 m). With the default cap of 3 a few
// steps end with errors above 1e-9 (measured ≈ 7e-7 m gap, 7e-6 lock, 2.5e-9 rad limit), and
// each of them must carry kFlagProjectionIncomplete; with 8 iterations every step is closed.
// (The targets wrap — 3 × 150° per finger — so the distal joints settle inside their range:
// no "ends at the bound" check here.)
TEST(HandLimits, JumpTo150DegreesHoldsUpperLimits) {
  StepParams prm;
  prm.projection_iterations = 8;
  const LimitFigures f = driveFlexion(150 * kDeg, true, prm);
  reportLimits("curl150_jump_8_projection_iterations", f);
  EXPECT_LE(f.limit, 1e-9);
  EXPECT_LE(f.gap, 1e-9);
  EXPECT_LE(f.lock, 1e-9);

  const LimitFigures d = driveFlexion(150 * kDeg, true, StepParams{});
  reportLimits("curl150_jump_default_projection_iterations", d);
  EXPECT_EQ(d.unflagged_over_1e9, 0) << "a step left joint errors above 1e-9 without kFlagProjectionIncomplete";
  EXPECT_LE(d.steps_over_1e9, 10);
  EXPECT_LE(std::max(d.gap, d.lock), 1e-4);
}

// A step whose projection leaves the joints more open than they were is not a hand: the stepper
// halves its motion and projects again (ClusterStepper::kShortenings times), then keeps the
// previous state (kFlagStateKept). With one Newton iteration a slow curl (0.75° a step) moves on
// (often halved), while a jump of 180° does not; every state the stepper returns has closed joints
// (jointsClosed), and the slow curl is still followed. (Seen live: a projection that diverged
// left a hand with a 0.3 m gap, which the solver published.)
TEST(HandLimits, AStepThatOpensTheJointsIsShortenedOrKept) {
  const HandModel& m = hand16();
  StepParams prm;
  prm.projection_iterations = 1;
  ClusterStepper s(m, prm);
  Pose X_WM;
  X_WM.p = Vec3(0, 0, 0.2);
  s.reset(m.restPoses(X_WM));
  int kept = 0, shortened = 0, whole = 0;
  double worst = 0;
  for (int i = 0; i < 200; ++i) {
    const bool jump = i == 100 || i == 101 || i == 150 || i == 151;  // to -30° and back to the ramp
    const auto T = curledPose(m, X_WM, (jump && i % 2 == 0 ? -30.0 : 150.0 * i / 200.0) * kDeg);
    const std::vector<Pose> before = s.poses();
    const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
    const JointErrors e = jointErrors(m, s.poses().data());
    worst = std::max({worst, e.gap, e.lock});
    if (r.flags & kFlagStateKept) {
      ++kept;
      EXPECT_EQ(r.shortened, ClusterStepper::kShortenings);
      for (size_t b = 0; b < before.size(); ++b) EXPECT_EQ((s.poses()[b].p - before[b].p).norm(), 0.0);
    } else if (r.shortened > 0) {
      ++shortened;
    } else {
      ++whole;
    }
    EXPECT_TRUE(jointsClosed(r.joint_errors, prm)) << "step " << i;
    EXPECT_TRUE(jointsClosed(e, prm)) << "step " << i;
  }
  figure("one_projection_iteration_steps_kept", kept);
  figure("one_projection_iteration_steps_shortened", shortened);
  figure("one_projection_iteration_max_joint_error", worst);
  EXPECT_GT(kept + shortened, 0) << "one iteration closes every jump: the case does not exercise the guard";
  EXPECT_GE(whole + shortened, 190) << "the slow curl was not followed";
  EXPECT_LE(worst, 1e3 * prm.projection_tolerance);
  EXPECT_EQ(s.counters().states_kept, static_cast<std::uint64_t>(kept));
  EXPECT_EQ(s.counters().shortened_steps, static_cast<std::uint64_t>(kept + shortened));
}

// ---------------------------------------------------------------------------------------------
// Contacts against the plane z = 0 (normal +z)

TEST(StepContact, SphereSlidesWithoutArtificialFriction) {
  const HandModel& m = ball();
  StepParams prm;
  const double r = 0.01, margin = prm.rows.margin;
  ClusterStepper s(m, prm);
  Pose X;
  X.p = Vec3(0, 0, r + margin);
  s.reset({X});
  Rng rng(31);
  Pose T = X;
  T.p.z() = -0.004;  // 4 mm below the plane
  std::vector<Contact> contacts;
  double lag = 0, rot = 0, low = 1.0, high = -1.0;
  for (int i = 0; i < 500; ++i) {
    const Vec3 step = rng.vector(0.005);
    T.p.x() += step.x();
    T.p.y() += step.y();
    T.q = (rng.rotation(0.1) * T.q).normalized();
    planeContacts(m, s.poses(), 0.0, 0.01, contacts);
    ASSERT_EQ(contacts.size(), 1u);
    const StepReport& rep = s.step({&T, nullptr, contacts.data(), 1});
    ASSERT_EQ(rep.solve.status, SolveStatus::Converged);
    const Pose& P = s.poses()[0];
    lag = std::max({lag, std::abs(P.p.x() - T.p.x()), std::abs(P.p.y() - T.p.y())});
    rot = std::max(rot, logRotation(T.q * P.q.conjugate()).norm());
    const double d = heightAbovePlane(m.bodies[0], P, 0.0);
    low = std::min(low, d);
    high = std::max(high, d);
    EXPECT_GT(s.contactLambda(0), 0.0);
  }
  figure("slide_max_tangential_lag_m", lag);
  figure("slide_min_distance_minus_margin_m", low - margin);
  figure("slide_max_distance_minus_margin_m", high - margin);
  EXPECT_LE(lag, 1e-9);
  EXPECT_LE(rot, 1e-9);  // a sphere's contact row has no angular part: it spins freely
  EXPECT_GE(low, margin - 1e-12);
  EXPECT_LE(high, margin + 1e-12);
}

TEST(StepContact, BodyPulledIntoPlaneLandsAtMargin) {
  const HandModel& m = ball();
  StepParams prm;
  const double r = 0.01, margin = prm.rows.margin, dt2 = prm.dt * prm.dt;
  ClusterStepper s(m, prm);
  Pose X;
  X.p = Vec3(0.01, 0.02, r + 0.02);
  s.reset({X});
  Pose T = X;
  T.p.z() = -0.05;
  std::vector<Contact> contacts;
  planeContacts(m, s.poses(), 0.0, 0.1, contacts);
  s.step({&T, nullptr, contacts.data(), 1});
  const double d = heightAbovePlane(m.bodies[0], s.poses()[0], 0.0);
  figure("landing_distance_minus_margin_m", d - margin);
  EXPECT_NEAR(d, margin, 1e-15);
  // λ = m (z − z_u) along n: the force that stops the remaining fall into the target.
  const double z_u = (T.p.z() - (r + 0.02)) / dt2, z = -(0.02 - margin) / dt2;
  EXPECT_NEAR(s.contactLambda(0), m.bodies[0].mass * (z - z_u), 1e-9 * m.bodies[0].mass * std::abs(z_u));
  // It stays there.
  for (int i = 0; i < 10; ++i) {
    planeContacts(m, s.poses(), 0.0, 0.1, contacts);
    s.step({&T, nullptr, contacts.data(), 1});
    EXPECT_NEAR(heightAbovePlane(m.bodies[0], s.poses()[0], 0.0), margin, 1e-15);
  }
  // A target above the margin is reached exactly (the contact row stays inactive).
  T.p.z() = r + 0.003;
  planeContacts(m, s.poses(), 0.0, 0.1, contacts);
  s.step({&T, nullptr, contacts.data(), 1});
  EXPECT_LT((s.poses()[0].p - T.p).norm(), 1e-15);
  EXPECT_EQ(s.contactLambda(0), 0.0);
}

TEST(StepContact, PenetratingBodyIsPushedOutAtContactBeta) {
  const HandModel& m = ball();
  StepParams prm;
  const double r = 0.01, margin = prm.rows.margin, beta = prm.rows.contact_beta;
  ClusterStepper s(m, prm);
  Pose X;
  X.p = Vec3(0, 0, r - 0.002);  // 2 mm inside
  s.reset({X});
  Pose T = X;
  T.p.z() = -0.01;
  std::vector<Contact> contacts;
  double d = -0.002;
  for (int i = 0; i < 20; ++i) {
    planeContacts(m, s.poses(), 0.0, 0.1, contacts);
    s.step({&T, nullptr, contacts.data(), 1});
    const double expected = d + beta * (margin - d);  // c = β (δ − d)/Δt², header of constraints.h
    d = heightAbovePlane(m.bodies[0], s.poses()[0], 0.0);
    EXPECT_NEAR(d, expected, 1e-15) << "step " << i;
  }
  EXPECT_NEAR(d, margin, 1e-8);
}

/// Independent KKT check of a 1-body problem: M (z − z_u) = Σ J_kᵀ λ_k with M built from the
/// model's mass and rotational weight (turn_inertia) at the pose's orientation.
double stationarityError(const Body& b, const Pose& X_before, const QpProblem& qp, const QpSolution& sol) {
  Mat6 M = Mat6::Zero();
  const Mat3 R = X_before.q.toRotationMatrix();
  M.topLeftCorner<3, 3>() = b.mass * Mat3::Identity();
  M.bottomRightCorner<3, 3>() = R * b.turn_inertia.asDiagonal() * R.transpose();
  Vec6 jtl = Vec6::Zero();
  for (int k = 0; k < qp.numRows(); ++k) jtl += sol.lambda[static_cast<size_t>(k)] * qp.row(k).J0;
  const Vec6 lhs = M * (sol.z[0] - qp.unconstrained(0));
  return (lhs - jtl).cwiseAbs().maxCoeff() / std::max(lhs.cwiseAbs().maxCoeff(), jtl.cwiseAbs().maxCoeff());
}

TEST(StepContact, BoxCornerOnPlane) {
  const HandModel& m = tool1();
  const Body& body = m.bodies[0];
  StepParams prm;
  const double margin = prm.rows.margin, dt2 = prm.dt * prm.dt;
  // Tilted so that exactly one corner is lowest, that corner exactly at the margin.
  Pose X;
  X.q = expRotation(Vec3(0.5, 0.3, 0.2));
  X.p = Vec3(0.02, -0.01, 0.0);
  int corner = -1;
  double lowest = 1e9;
  const auto fs = features(body);
  for (size_t k = 0; k < fs.size(); ++k) {
    const double z = (X * fs[k].p_B).z();
    if (z < lowest) { lowest = z; corner = static_cast<int>(k); }
  }
  X.p.z() = margin - lowest;
  ClusterStepper s(m, prm);
  s.reset({X});
  const Vec3 corner_B = fs[static_cast<size_t>(corner)].p_B;
  Contact c;
  c.body = 0;
  c.p_W = X * corner_B;
  c.n_W = Vec3::UnitZ();
  c.distance = c.p_W.z();
  c.key = 1;
  ASSERT_NEAR(c.distance, margin, 1e-16);
  Pose T = X;
  T.p.z() -= 0.01;  // straight down, 1 cm
  const StepReport& r = s.step({&T, nullptr, &c, 1});
  ASSERT_EQ(r.solve.status, SolveStatus::Converged);
  figure("corner_kkt_residual", r.solve.kkt_residual);
  EXPECT_LE(r.solve.kkt_residual, 1e-9);
  EXPECT_LE(kktResidual(s.problem(), s.solution()).max(), 1e-9);
  const double stat = stationarityError(body, X, s.problem(), s.solution());
  figure("corner_independent_stationarity", stat);
  EXPECT_LE(stat, 1e-12);
  EXPECT_GT(s.contactLambda(0), 0.0);
  // Linearised: the corner stops exactly at the margin; the box rotates (it pivots about the
  // corner) and its centre still moves down.
  const Vec6 step = s.solution().z[0] * dt2;
  const Vec3 u = c.p_W - X.p;
  EXPECT_NEAR(c.distance + step[2] + Vec3::UnitZ().dot(step.tail<3>().cross(u)), margin, 1e-15);
  const Vec3 theta = step.tail<3>();
  EXPECT_GT(theta.norm(), 1e-4);
  EXPECT_LT(s.poses()[0].p.z(), X.p.z());
  // Exact corner height from the new pose (exp map): off the margin only by the second-order
  // term ‖(R(θ) − I) u − θ × u‖ ≤ ½ |θ|² |u|.
  const double h_exact = (s.poses()[0] * corner_B).z();
  const double bound = 0.5 * theta.squaredNorm() * u.norm();
  figure("corner_rotation_rad", theta.norm());
  figure("corner_exact_height_minus_margin_m", h_exact - margin);
  figure("corner_second_order_bound_m", bound);
  EXPECT_LE(std::abs(h_exact - margin), bound * (1 + 1e-9) + 1e-15);
  // No other corner went through the plane.
  EXPECT_GE(heightAbovePlane(body, s.poses()[0], 0.0), h_exact - 1e-15);
}

TEST(StepContact, ToolIsTheClassicGodObject) {
  const HandModel& m = tool1();
  StepParams prm;
  const double margin = prm.rows.margin, k = 1.0 / (prm.dt * prm.dt);
  // Lying on its long side: local z along world x, the 0.12 × 0.02 face down, at the margin.
  Pose X;
  X.q = Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()));
  X.p = Vec3(0, 0, 0.01 + margin);
  ClusterStepper s(m, prm);
  s.reset({X});
  Pose T = X;
  T.p.z() = -0.005;  // 1.5 cm into the plane
  Rng rng(41);
  std::vector<Contact> contacts;
  double lag = 0, yaw_err = 0, tilt = 0, low = 1, high = -1, force_err = 0, kkt = 0;
  for (int i = 0; i < 500; ++i) {
    const Vec3 dp = rng.vector(0.005);
    T.p.x() += dp.x();
    T.p.y() += dp.y();
    T.q = (expRotation(Vec3(0, 0, rng.uniform(-0.05, 0.05))) * T.q).normalized();
    planeContacts(m, s.poses(), 0.0, 0.005, contacts);
    ASSERT_EQ(contacts.size(), 4u) << "step " << i;
    const StepReport& r = s.step({&T, nullptr, contacts.data(), 4});
    ASSERT_EQ(r.solve.status, SolveStatus::Converged) << "step " << i;
    kkt = std::max(kkt, r.solve.kkt_residual);
    const Pose& P = s.poses()[0];
    lag = std::max({lag, std::abs(P.p.x() - T.p.x()), std::abs(P.p.y() - T.p.y())});
    const Vec3 dq = logRotation(T.q * P.q.conjugate());
    yaw_err = std::max(yaw_err, std::abs(dq.z()));
    tilt = std::max(tilt, std::abs((P.q * Vec3::UnitZ()).z()));  // long axis stays horizontal
    const double d = heightAbovePlane(m.bodies[0], P, 0.0);
    low = std::min(low, d);
    high = std::max(high, d);
    // Total normal force = m k × (how far the target sits below the resting pose).
    double sum = 0;
    for (int c = 0; c < 4; ++c) sum += s.contactLambda(c);
    const double expected = m.bodies[0].mass * k * ((0.01 + margin) - T.p.z());
    force_err = std::max(force_err, std::abs(sum - expected) / expected);
  }
  figure("tool_max_tangential_lag_m", lag);
  figure("tool_max_yaw_error_rad", yaw_err);
  figure("tool_min_distance_minus_margin_m", low - margin);
  figure("tool_max_distance_minus_margin_m", high - margin);
  figure("tool_normal_force_relative_error", force_err);
  figure("tool_max_kkt_residual", kkt);
  figure("tool_max_tilt_rad", tilt);
  EXPECT_LE(lag, 1e-9);
  EXPECT_LE(yaw_err, 1e-9);
  // Four coplanar contacts make A singular (3 DOF, 4 rows): the solver is then exact to its KKT
  // tolerance, 1e-9 relative to the row scale |J z_u| Δt² = the target's depth (1.5 cm), i.e.
  // 1.5e-11 m at the corners and 1.5e-11 m / 0.01 m half-width of tilt. Measured: 2e-13 m and
  // 2e-12 rad in the RelWithDebInfo build, 2.3e-12 m and 1.8e-11 rad in the sanitizer build.
  const double depth = 0.01 + margin + 0.005;
  EXPECT_LE(tilt, 1e-9 * depth / 0.01);
  EXPECT_GE(low, margin - 1e-9 * depth);
  EXPECT_LE(high, margin + 1e-12);
  EXPECT_LE(force_err, 1e-9);
  EXPECT_LE(kkt, 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Extremes (METHOD.md §6)

/// Hand resting 1 mm above the plane z = 0, targets pressed 1 cm into it with per-body jitter.
struct PressScenario {
  explicit PressScenario(const StepParams& prm, std::uint64_t seed = 51, Vec3 origin_W = Vec3::Zero())
      : stepper(hand16(), prm), rng(seed), origin(origin_W) {
    const auto rest = hand16().restPoses(Pose{});
    const double low = minHeightAbovePlane(hand16(), rest, 0.0);
    X_WM.p = origin + Vec3(0, 0, 0.001 - low);
    stepper.reset(hand16().restPoses(X_WM));
  }
  const StepReport& step(int i, double jitter_m, double jitter_rad) {
    Pose X = X_WM;
    X.p += Vec3(0.01 * std::sin(0.01 * i), 0.01 * std::cos(0.013 * i) - 0.01, -0.01);
    T = hand16().restPoses(X);
    for (Pose& P : T) {
      const Vec3 dp = rng.vector(jitter_m);
      P = moveRigid(P, dp, rng.rotation(jitter_rad));
    }
    planeContacts(hand16(), stepper.poses(), origin.z(), 0.01, contacts);
    before = stepper.poses();
    const StepReport& r = stepper.step({T.data(), nullptr, contacts.data(), static_cast<int>(contacts.size())});
    checkPenetration();
    return r;
  }
  /// Exact penetration beyond the margin, body by body, against what the linearised contact rows
  /// allow: a body already inside is pushed out by at least the fraction β of its depth, and the
  /// rows are exact up to the second-order term ‖(R(θ) − I) u − θ × u‖ ≤ ½ θ² |u| of the body's
  /// rotation θ over the step (u: lever of the feature). `excess` is the worst ratio of the
  /// penetration to that allowance (≤ 1 when the step is as exact as its linearisation).
  void checkPenetration() {
    const HandModel& m = hand16();
    const StepParams& prm = stepper.params();
    const double margin = prm.rows.margin;
    const auto& X = stepper.poses();
    if (prev_pen.empty()) prev_pen.assign(X.size(), 0.0);
    for (size_t b = 0; b < X.size(); ++b) {
      const double pen = margin - heightAbovePlane(m.bodies[b], X[b], origin.z());
      double lever = 0;
      for (const Feature& f : features(m.bodies[b])) lever = std::max(lever, f.p_B.norm());
      const double theta = logRotation(X[b].q * before[b].q.conjugate()).norm();
      const double allowed = (1.0 - prm.rows.contact_beta) * std::max(0.0, prev_pen[b]) + 0.5 * theta * theta * lever;
      max_pen = std::max(max_pen, pen);
      if (pen > 1e-12) excess = std::max(excess, pen / (allowed + 1e-12));
      prev_pen[b] = pen;
    }
  }
  ClusterStepper stepper;
  Rng rng;
  Vec3 origin;
  Pose X_WM;
  std::vector<Pose> T, before;
  std::vector<Contact> contacts;
  std::vector<double> prev_pen;
  double max_pen = 0.0, excess = 0.0;
};

TEST(StepExtremes, StiffnessAndTimeStepOverFourOrders) {
  double worst_pen = 0, worst_excess = 0, worst_gap = 0, worst_lock = 0, ball_pen = 0, ball_lag = 0;
  int failures = 0;
  for (double dt : {1e-5, 1e-4, 1e-3, 1e-2, 1e-1}) {
    for (double ks : {1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8}) {
      StepParams prm;
      prm.dt = dt;
      prm.k_s = ks;
      // The hand pressed into a plane.
      PressScenario sc(prm);
      for (int i = 0; i < 40; ++i) {
        const StepReport& r = sc.step(i, 0.001, 0.01);
        ASSERT_TRUE(allFinite(sc.stepper.poses())) << "dt " << dt << " k_s " << ks;
        failures += r.solve.status == SolveStatus::NumericalFailure;
        worst_gap = std::max(worst_gap, r.joint_errors.gap);
        worst_lock = std::max(worst_lock, r.joint_errors.lock);
        EXPECT_LE(r.joint_errors.gap, 1e-9) << "dt " << dt << " k_s " << ks << " step " << i;
        EXPECT_LE(r.joint_errors.lock, 1e-9) << "dt " << dt << " k_s " << ks << " step " << i;
      }
      worst_pen = std::max(worst_pen, sc.max_pen);
      worst_excess = std::max(worst_excess, sc.excess);
      // A sphere on the plane: its contact row is exact, so no penetration at all, and the
      // tangential motion is the coupling's k Δt² fraction of the remaining distance.
      const HandModel& m = ball();
      ClusterStepper s(m, prm);
      Pose X;
      X.p = Vec3(0, 0, 0.01 + prm.rows.margin + 0.002);
      s.reset({X});
      Pose T = X;
      T.p = Vec3(0.01, 0, -0.01);
      std::vector<Contact> c;
      const double frac = std::min(ks, 1.0 / (dt * dt)) * dt * dt;
      for (int i = 0; i < 20; ++i) {
        planeContacts(m, s.poses(), 0.0, 0.1, c);
        const double x0 = s.poses()[0].p.x();
        s.step({&T, nullptr, c.data(), 1});
        ASSERT_TRUE(allFinite(s.poses()));
        ball_pen = std::max(ball_pen, prm.rows.margin - heightAbovePlane(m.bodies[0], s.poses()[0], 0.0));
        const double expect_x = x0 + frac * (T.p.x() - x0);
        ball_lag = std::max(ball_lag, std::abs(s.poses()[0].p.x() - expect_x));
      }
    }
  }
  figure("dt_ks_grid_hand_max_penetration_beyond_margin_m", worst_pen);
  figure("dt_ks_grid_hand_penetration_over_second_order_allowance", worst_excess);
  figure("dt_ks_grid_max_joint_gap_m", worst_gap);
  figure("dt_ks_grid_max_lock_error", worst_lock);
  figure("dt_ks_grid_ball_max_penetration_beyond_margin_m", ball_pen);
  figure("dt_ks_grid_ball_max_tangential_error_m", ball_lag);
  EXPECT_EQ(failures, 0);
  EXPECT_LE(worst_excess, 1.0);
  EXPECT_LE(ball_pen, 1e-15);
  EXPECT_LE(ball_lag, 1e-15);
}

const char* const kTwoBodyTemplate =
    "name: \"pair\"\n"
    "bodies { name: \"a\" box { half_extents { x: 0.02 y: 0.02 z: 0.02 } } mass: 1 }\n"
    "bodies { name: \"b\" capsule { radius: 0.01 half_length: 0.03 } mass: MASS\n"
    "         rest_position { x: 0 y: 0 z: 0.06 } }\n"
    "joints { name: \"j\" type: TYPE parent: \"a\" child: \"b\"\n"
    "  anchor_parent { x: 0 y: 0 z: 0.02 } anchor_child { x: 0 y: 0 z: -0.04 }\n"
    "  axis_parent { x: 1 y: 0 z: 0 } axis_child { x: 1 y: 0 z: 0 }\n"
    "  reference_parent { x: 0 y: 0 z: 1 } reference_child { x: 0 y: 0 z: 1 }\n"
    "  LIMITS }\n";

HandModel twoBodyModel(double child_mass, const std::string& type, const std::string& limits) {
  std::string t = kTwoBodyTemplate;
  auto sub = [&](const std::string& key, const std::string& val) { t.replace(t.find(key), key.size(), val); };
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", child_mass);
  sub("MASS", buf);
  sub("TYPE", type);
  sub("LIMITS", limits);
  return HandModel::fromText(t, "pair.pbtxt");
}

TEST(StepExtremes, MassRatiosFrom1eMinus4To1e4) {
  double worst_gap = 0, worst_lock = 0, worst_limit = 0, worst_kkt = 0;
  int not_converged = 0;
  for (const char* type : {"REVOLUTE", "SPHERICAL_2DOF"}) {
    const std::string limits = std::string(type) == "REVOLUTE" ? "limits { angle: 1 lower: -0.5 upper: 0.5 }"
                                                               : "limits { angle: 1 lower: -0.5 upper: 0.5 } limits { angle: 2 lower: -0.3 upper: 0.3 }";
    for (double ratio : {1e-4, 1e-3, 1e-2, 1e-1, 1.0, 1e1, 1e2, 1e3, 1e4}) {
      const HandModel m = twoBodyModel(ratio, type, limits);
      ClusterStepper s(m, StepParams{});
      s.reset(m.restPoses(Pose{}));
      Rng rng(61);
      std::vector<Pose> T;
      for (int i = 0; i < 300; ++i) {
        Pose base;
        base.p = Vec3(0.02 * std::sin(0.05 * i), 0, 0);
        base.q = expRotation(Vec3(0.3 * std::sin(0.03 * i), 0, 0));
        T = m.restPoses(base);
        for (Pose& P : T) {
          const Vec3 dp = rng.vector(0.005);
          P = moveRigid(P, dp, rng.rotation(0.3));
        }
        const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
        ASSERT_TRUE(allFinite(s.poses())) << type << " ratio " << ratio;
        not_converged += r.solve.status != SolveStatus::Converged;
        worst_kkt = std::max(worst_kkt, r.solve.kkt_residual);
        worst_gap = std::max(worst_gap, r.joint_errors.gap);
        worst_lock = std::max(worst_lock, r.joint_errors.lock);
        worst_limit = std::max(worst_limit, r.joint_errors.limit);
        EXPECT_LE(r.joint_errors.gap, 1e-9) << type << " ratio " << ratio << " step " << i;
        EXPECT_LE(r.joint_errors.lock, 1e-9) << type << " ratio " << ratio << " step " << i;
        EXPECT_LE(r.joint_errors.limit, 1e-9) << type << " ratio " << ratio << " step " << i;
      }
    }
  }
  figure("mass_ratio_max_joint_gap_m", worst_gap);
  figure("mass_ratio_max_lock_error", worst_lock);
  figure("mass_ratio_max_limit_violation_rad", worst_limit);
  figure("mass_ratio_max_kkt_residual", worst_kkt);
  figure("mass_ratio_not_converged_steps", not_converged);
  EXPECT_EQ(not_converged, 0);
}

TEST(StepExtremes, ThousandDuplicatedContacts) {
  const HandModel& m = tool1();
  StepParams prm;
  const double margin = prm.rows.margin;
  Pose X;
  X.q = Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()));
  X.p = Vec3(0, 0, 0.01 + margin);
  ClusterStepper s(m, prm);
  s.reset({X});
  Pose T = X;
  T.p.z() = -0.005;
  Rng rng(71);
  std::vector<Contact> four, many(1000);
  double lag = 0, low = 1, kkt = 0;
  int not_converged = 0;
  for (int i = 0; i < 30; ++i) {
    const Vec3 dp = rng.vector(0.003);
    T.p.x() += dp.x();
    T.p.y() += dp.y();
    planeContacts(m, s.poses(), 0.0, 0.005, four);
    ASSERT_EQ(four.size(), 4u);
    for (size_t k = 0; k < many.size(); ++k) {
      many[k] = four[k % 4];
      many[k].key = k + 1;
    }
    const StepReport& r = s.step({&T, nullptr, many.data(), 1000});
    ASSERT_TRUE(allFinite(s.poses()));
    EXPECT_EQ(r.contact_rows, 1000);
    not_converged += r.solve.status != SolveStatus::Converged;
    kkt = std::max(kkt, r.solve.kkt_residual);
    lag = std::max({lag, std::abs(s.poses()[0].p.x() - T.p.x()), std::abs(s.poses()[0].p.y() - T.p.y())});
    low = std::min(low, heightAbovePlane(m.bodies[0], s.poses()[0], 0.0));
  }
  figure("dup1000_min_distance_minus_margin_m", low - margin);
  figure("dup1000_max_tangential_lag_m", lag);
  figure("dup1000_max_kkt_residual", kkt);
  EXPECT_EQ(not_converged, 0);
  EXPECT_GE(low, margin - 1e-9 * (0.01 + margin + 0.005));  // KKT tolerance × depth, as above
  EXPECT_LE(lag, 1e-9);
  // Same contact point on one sphere, a thousand times (fully duplicated single row).
  const HandModel& b = ball();
  ClusterStepper sb(b, prm);
  Pose Xb;
  Xb.p = Vec3(0, 0, 0.01 + margin);
  sb.reset({Xb});
  Pose Tb = Xb;
  Tb.p = Vec3(0.003, 0.001, -0.02);
  std::vector<Contact> one;
  planeContacts(b, sb.poses(), 0.0, 0.01, one);
  std::vector<Contact> dup(1000, one[0]);
  const StepReport& r = sb.step({&Tb, nullptr, dup.data(), 1000});
  EXPECT_EQ(r.solve.status, SolveStatus::Converged);
  EXPECT_NEAR(heightAbovePlane(b.bodies[0], sb.poses()[0], 0.0), margin, 1e-12);
  EXPECT_NEAR(sb.poses()[0].p.x(), 0.003, 1e-12);
  double sum = 0;
  for (int k = 0; k < 1000; ++k) sum += sb.contactLambda(k);
  const double expected = b.bodies[0].mass * 1e6 * (0.01 + margin + 0.02);
  EXPECT_NEAR(sum, expected, 1e-9 * expected);
}

TEST(StepExtremes, NearParallelNormals) {
  const HandModel& m = ball();
  StepParams prm;
  const double r = 0.01, margin = prm.rows.margin;
  double worst = 0;
  for (double eps : {1e-3, 1e-6, 1e-9, 1e-12, 1e-15}) {
    ClusterStepper s(m, prm);
    Pose X;
    X.p = Vec3(0, 0, r + margin);
    s.reset({X});
    Pose T = X;
    T.p = Vec3(0.004, -0.002, -0.01);
    // Two contacts at the same sphere, normals ε apart, plus a third tilted the other way.
    const Vec3 normals[3] = {Vec3::UnitZ(), Vec3(eps, 0, 1).normalized(), Vec3(0, -eps, 1).normalized()};
    Contact c[3];
    for (int k = 0; k < 3; ++k) {
      c[k].body = 0;
      c[k].n_W = normals[k];
      c[k].p_W = X.p - r * normals[k];
      c[k].distance = margin;  // each touching a plane through its own point at the margin
      c[k].key = static_cast<std::uint64_t>(k) + 1;
    }
    const StepReport& rep = s.step({&T, nullptr, c, 3});
    ASSERT_TRUE(allFinite(s.poses())) << eps;
    EXPECT_EQ(rep.solve.status, SolveStatus::Converged) << eps;
    EXPECT_LE(rep.solve.kkt_residual, 1e-9) << eps;
    // No motion into any of the three planes (linear rows are exact for a sphere).
    const Vec3 disp = s.poses()[0].p - X.p;
    for (int k = 0; k < 3; ++k) {
      const double into = -normals[k].dot(disp);
      worst = std::max(worst, into);
      EXPECT_LE(into, 1e-15) << "eps " << eps << " contact " << k;
    }
  }
  figure("near_parallel_max_motion_into_plane_m", worst);
}

TEST(StepExtremes, BadTargetsAreCountedAndLastValidOneUsed) {
  const HandModel& m = hand16();
  ClusterStepper s(m, StepParams{});
  Pose X_WM;
  X_WM.p = Vec3(0, 0, 0.2);
  s.reset(m.restPoses(X_WM));
  Pose X1 = X_WM;
  X1.p += Vec3(0.003, 0, 0);
  const auto T1 = m.restPoses(X1);
  s.step({T1.data(), nullptr, nullptr, 0});
  ASSERT_LT(maxPositionError(s.poses(), T1), 1e-12);

  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  Pose X2 = X1;
  X2.p += Vec3(0, 0.002, 0);
  std::vector<Pose> T2 = m.restPoses(X2);
  T2[0].p.x() = nan;                         // palm: NaN position
  T2[3].q = Quat(inf, 0, 0, 0);              // Inf quaternion
  T2[5].q.coeffs() *= 1.5;                   // non-unit quaternion
  T2[7].p.z() = -inf;                        // Inf position
  T2[9].q = Quat(nan, nan, nan, nan);
  const StepReport& r = s.step({T2.data(), nullptr, nullptr, 0});
  EXPECT_EQ(r.rejected_targets, 5);
  EXPECT_TRUE(r.flags & kFlagRejectedTarget);
  EXPECT_EQ(s.counters().rejected_targets, 5u);
  ASSERT_TRUE(allFinite(s.poses()));
  for (const Pose& P : s.poses()) EXPECT_NEAR(P.q.norm(), 1.0, 1e-12);
  EXPECT_LE(r.joint_errors.gap, 1e-9);
  // The other bodies pull the hand towards X2, the rejected ones hold their last valid target
  // (T1): the hand ends between the two, never at a NaN.
  EXPECT_GT(s.poses()[0].p.y(), T1[0].p.y());
  EXPECT_LT(s.poses()[0].p.y(), X2.p.y() + m.bodies[0].X_MB_rest.p.y());
  // Slightly non-unit (within target_unit_tolerance) is accepted and normalised.
  std::vector<Pose> T3 = m.restPoses(X2);
  for (Pose& P : T3) P.q.coeffs() *= 1.0 + 1e-4;
  const StepReport& r3 = s.step({T3.data(), nullptr, nullptr, 0});
  EXPECT_EQ(r3.rejected_targets, 0);
  EXPECT_EQ(r3.flags & kFlagRejectedTarget, 0u);
  for (int i = 0; i < 3; ++i) s.step({T3.data(), nullptr, nullptr, 0});
  EXPECT_LT(maxPositionError(s.poses(), m.restPoses(X2)), 1e-12);
  // A body that never had a valid target stays where it is (zero coupling).
  ClusterStepper s2(m, StepParams{});
  s2.reset(m.restPoses(X_WM));
  std::vector<Pose> T4 = m.restPoses(X2);
  for (Pose& P : T4) P.p.x() = nan;
  const StepReport& r4 = s2.step({T4.data(), nullptr, nullptr, 0});
  EXPECT_EQ(r4.rejected_targets, 16);
  EXPECT_LT(maxPositionError(s2.poses(), m.restPoses(X_WM)), 1e-15);
}

TEST(StepExtremes, BadContactsAreCountedAndIgnored) {
  const HandModel& m = ball();
  StepParams prm;
  const double r = 0.01, margin = prm.rows.margin;
  ClusterStepper s(m, prm);
  Pose X;
  X.p = Vec3(0, 0, r + margin);
  s.reset({X});
  Pose T = X;
  T.p = Vec3(0.002, 0, -0.01);
  std::vector<Contact> c;
  planeContacts(m, s.poses(), 0.0, 0.01, c);
  const Contact good = c[0];
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  Contact bad = good;
  bad.p_W.x() = nan; c.push_back(bad);
  bad = good; bad.n_W = Vec3(nan, 0, 1); c.push_back(bad);
  bad = good; bad.distance = inf; c.push_back(bad);
  bad = good; bad.distance = nan; c.push_back(bad);
  bad = good; bad.n_W = Vec3::Zero(); c.push_back(bad);
  bad = good; bad.body = 1; c.push_back(bad);    // no such body
  bad = good; bad.body = -1; c.push_back(bad);
  const StepReport& rep = s.step({&T, nullptr, c.data(), static_cast<int>(c.size())});
  EXPECT_EQ(rep.rejected_contacts, 7);
  EXPECT_EQ(rep.contact_rows, 1);
  EXPECT_TRUE(rep.flags & kFlagRejectedContact);
  EXPECT_EQ(s.counters().rejected_contacts, 7u);
  ASSERT_TRUE(allFinite(s.poses()));
  // The good contact still holds the ball at the margin; the target's x is reached.
  EXPECT_NEAR(heightAbovePlane(m.bodies[0], s.poses()[0], 0.0), margin, 1e-15);
  EXPECT_NEAR(s.poses()[0].p.x(), 0.002, 1e-15);
  for (int i = 1; i < 8; ++i) EXPECT_EQ(s.contactLambda(i), 0.0);
}

TEST(StepExtremes, OverflowingTargetKeepsPreviousState) {
  // A finite but absurd target (1e308 m away): k × difference overflows to Inf inside the step.
  for (const HandModel* m : {&tool1(), &hand16()}) {
    ClusterStepper s(*m, StepParams{});
    Pose X_WM;
    X_WM.p = Vec3(0, 0, 0.2);
    const auto start = m->restPoses(X_WM);
    s.reset(start);
    std::vector<Pose> T = start;
    T[0].p.x() = 1e308;
    const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
    EXPECT_EQ(r.rejected_targets, 0);
    EXPECT_TRUE(r.flags & kFlagStateKept) << m->name;
    EXPECT_TRUE(r.flags & (kFlagSolverFailed | kFlagStateKept));
    EXPECT_EQ(s.counters().states_kept, 1u);
    ASSERT_TRUE(allFinite(s.poses()));
    EXPECT_EQ(maxPositionError(s.poses(), start), 0.0);
    // It recovers on the next sane target.
    T = start;
    T[0].p.x() += 0.001;
    s.step({T.data(), nullptr, nullptr, 0});
    EXPECT_TRUE(allFinite(s.poses()));
    EXPECT_GT(s.poses()[0].p.x(), start[0].p.x());
  }
}

TEST(StepExtremes, TenKilometresFromOrigin) {
  const HandModel& m = hand16();
  const Vec3 far(7071.0678, -7071.0678, 12.5);  // ≈ 10 km
  // (a) Rigid translations: tracked to round-off of the coordinates.
  {
    ClusterStepper s(m, StepParams{});
    Pose X_WM;
    X_WM.p = far;
    X_WM.q = expRotation(Vec3(0.2, 0.1, 2.0));
    s.reset(m.restPoses(X_WM));
    Rng rng(81);
    double err = 0, gap = 0;
    for (int i = 0; i < 500; ++i) {
      X_WM.p += rng.vector(0.005);
      const auto T = m.restPoses(X_WM);
      const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
      err = std::max(err, maxPositionError(s.poses(), T));
      gap = std::max(gap, r.joint_errors.gap);
    }
    figure("far_translation_max_position_error_m", err);
    figure("far_translation_relative_error", err / far.norm());
    figure("far_translation_max_joint_gap_m", gap);
    EXPECT_LT(err / far.norm(), 1e-14);
    EXPECT_LE(gap, 1e-9);
  }
  // (b) Jittered targets: joints stay closed at 10 km.
  {
    ClusterStepper s(m, StepParams{});
    JitteredHand gen(82, far);
    s.reset(m.restPoses(gen.base(0)));
    std::vector<Pose> T;
    double gap = 0, lock = 0;
    for (int i = 0; i < 1000; ++i) {
      gen.targets(m, i, 0.005, 0.1, T);
      const StepReport& r = s.step({T.data(), nullptr, nullptr, 0});
      gap = std::max(gap, r.joint_errors.gap);
      lock = std::max(lock, r.joint_errors.lock);
    }
    figure("far_jitter_max_joint_gap_m", gap);
    figure("far_jitter_max_lock_error", lock);
    EXPECT_LE(gap, 1e-9);
    EXPECT_LE(lock, 1e-9);
    EXPECT_TRUE(allFinite(s.poses()));
  }
  // (c) Pressing on a plane 10 km out.
  {
    PressScenario sc(StepParams{}, 83, far);
    double gap = 0;
    for (int i = 0; i < 300; ++i) gap = std::max(gap, sc.step(i, 0.001, 0.01).joint_errors.gap);
    figure("far_press_max_penetration_beyond_margin_m", sc.max_pen);
    figure("far_press_penetration_over_second_order_allowance", sc.excess);
    figure("far_press_max_joint_gap_m", gap);
    EXPECT_LE(sc.excess, 1.0);
    EXPECT_LE(gap, 1e-9);
  }
}

// ---------------------------------------------------------------------------------------------
// Determinism

std::vector<std::uint64_t> hashedRun(SolverKind kind, int steps) {
  StepParams prm;
  prm.solver = kind;
  PressScenario sc(prm, 91);
  std::vector<std::uint64_t> hashes;
  for (int i = 0; i < steps; ++i) {
    sc.step(i, 0.003, 0.05);
    hashes.push_back(fnv1a(sc.stepper.poses()));
  }
  return hashes;
}

// The two projection tests' motion: a curled hand moved and turned, cut at half of each body's
// own motion (cutMotion), which opens the joints.
std::vector<Pose> halfCutMotion(const HandModel& m, std::vector<Pose>* X_prev, std::vector<Pose>* X_new) {
  const Pose X_WM0{Vec3(0.0, 0.0, 0.10), Quat::Identity()};
  const Pose X_WM1{Vec3(0.03, -0.02, 0.08), Quat(Eigen::AngleAxisd(0.9, Vec3(1, 1, 0).normalized()))};
  *X_prev = curledPose(m, X_WM0, 0.2);
  *X_new = curledPose(m, X_WM1, 0.9);
  std::vector<Pose> X_cut;
  cutMotion(*X_prev, *X_new, 0.5, &X_cut);
  return X_cut;
}

// JointProjector on poses X (in place) against contacts found at X_ref.
JointProjector::Result projectAgainst(const HandModel& m, const StepParams& params, const std::vector<Pose>& X_ref,
                                      const std::vector<Contact>& contacts, std::vector<Pose>* X) {
  JointProjector projector(m, params);
  projector.reserve(512);
  JointProjector::Input in;
  in.contacts = contacts.data();
  in.num_contacts = static_cast<int>(contacts.size());
  in.X_ref = X_ref.data();
  return projector.project(*X, in);
}

// Clipping a motion (Algorithm 1): each body cut back to a fraction of its own motion opens the
// joints by O(θ²); the projection re-closes them against contacts found at the cut poses, by a
// correction of the order of the gap, pushing no contact point further in than it was (the plane
// distances recomputed from the shapes). The Resolver's path (cutMotion + JointProjector) and the
// solver's (ClusterStepper::setMotion, interpolate, reproject) give the same poses bit for bit.
TEST(JointProjection, ReclosesACutMotionWithoutPushingAContactIn) {
  const HandModel& m = hand16();
  std::vector<Pose> X_prev, X_new;
  const std::vector<Pose> X_cut = halfCutMotion(m, &X_prev, &X_new);
  ASSERT_LE(jointErrors(m, X_prev.data()).gap, 1e-12);
  ASSERT_LE(jointErrors(m, X_new.data()).gap, 1e-12);
  const double gap_before = jointErrors(m, X_cut.data()).gap;
  EXPECT_GT(gap_before, 1e-5);  // per-body interpolation opens the joints
  const double h = minHeightAbovePlane(m, X_cut, 0.0) - 5e-4;  // a plane 0.5 mm below the lowest point
  std::vector<Contact> contacts;
  planeContacts(m, X_cut, h, 0.01, contacts);
  ASSERT_FALSE(contacts.empty());

  StepParams params;
  std::vector<Pose> X = X_cut;
  const JointProjector::Result r = projectAgainst(m, params, X_cut, contacts, &X);
  const JointErrors after = jointErrors(m, X.data());
  figure("projection_gap_before_m", gap_before);
  figure("projection_gap_after_m", after.gap);
  EXPECT_LE(after.gap, 1e-9);
  EXPECT_LE(after.lock, 1e-9);
  EXPECT_DOUBLE_EQ(r.joint_errors.gap, after.gap);
  EXPECT_GE(r.iterations, 1);
  // No contact point further in than min(its distance, the margin), within the projection's
  // second-order round-off (1 µm).
  const double allowed = std::min(5e-4, params.rows.margin);
  EXPECT_GE(minHeightAbovePlane(m, X, h), allowed - 1e-6);
  // The correction is of the order of the gap, not a new pose.
  EXPECT_LE(maxPositionError(X, X_cut), 20.0 * gap_before);

  ClusterStepper stepper(m, params);
  stepper.setMotion(X_prev, X_new);
  stepper.interpolate(0.5);
  EXPECT_EQ(fnv1a(stepper.poses()), fnv1a(X_cut));
  stepper.reproject(contacts.data(), static_cast<int>(contacts.size()));
  EXPECT_EQ(fnv1a(stepper.poses()), fnv1a(X));
}

// The projection's iterations after the first take the rows of the contacts near their margin
// only (StepParams::projection_row_reach): the rows left out, of contacts centimetres below, are
// inactive, so the poses are the same bit for bit as with every row (an infinite reach), and no
// contact, near or far, ends further in than allowed.
TEST(JointProjection, RowsOfFarContactsLeftOutChangeNothing) {
  const HandModel& m = hand16();
  std::vector<Pose> X_prev, X_new;
  const std::vector<Pose> X_cut = halfCutMotion(m, &X_prev, &X_new);
  const double h_near = minHeightAbovePlane(m, X_cut, 0.0) - 5e-4;
  std::vector<Contact> contacts;
  planeContacts(m, X_cut, h_near, 0.01, contacts);
  const size_t near_count = contacts.size();
  ASSERT_GT(near_count, 0u);
  for (double below : {0.02, 0.05}) {
    std::vector<Contact> far;
    planeContacts(m, X_cut, h_near - below, 0.1, far);
    contacts.insert(contacts.end(), far.begin(), far.end());
  }
  ASSERT_GT(contacts.size(), near_count);
  std::vector<std::vector<Pose>> results;
  std::vector<int> iterations;
  for (double reach : {10.0, std::numeric_limits<double>::infinity()}) {
    StepParams params;
    params.projection_row_reach = reach;
    std::vector<Pose> X = X_cut;
    const JointProjector::Result r = projectAgainst(m, params, X_cut, contacts, &X);
    EXPECT_GE(r.iterations, 2);  // (the later iterations are the ones that leave rows out)
    EXPECT_LE(r.joint_errors.gap, 1e-9);
    EXPECT_GE(minHeightAbovePlane(m, X, h_near), std::min(5e-4, params.rows.margin) - 1e-6);
    results.push_back(X);
    iterations.push_back(r.iterations);
  }
  EXPECT_EQ(fnv1a(results[0]), fnv1a(results[1]));
  EXPECT_EQ(iterations[0], iterations[1]);
  StepParams bad;
  bad.projection_row_reach = 0.5;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(StepDeterminism, IdenticalInputsGiveBitIdenticalPoses) {
  for (SolverKind kind : {SolverKind::Exact, SolverKind::Pgs}) {
    // Two steppers in lock-step on the same inputs.
    StepParams prm;
    prm.solver = kind;
    PressScenario a(prm, 92), b(prm, 92);
    int first_diff = -1;
    for (int i = 0; i < 1000 && first_diff < 0; ++i) {
      a.step(i, 0.003, 0.05);
      b.step(i, 0.003, 0.05);
      if (fnv1a(a.stepper.poses()) != fnv1a(b.stepper.poses())) first_diff = i;
    }
    EXPECT_EQ(first_diff, -1) << (kind == SolverKind::Exact ? "exact" : "pgs");
    // A later re-run from scratch reproduces the whole hash sequence.
    EXPECT_EQ(hashedRun(kind, 1000), hashedRun(kind, 1000)) << (kind == SolverKind::Exact ? "exact" : "pgs");
  }
}

// ---------------------------------------------------------------------------------------------
// PGS in the step

TEST(StepPgs, FiniteAndJointsClosedByProjection) {
  StepParams prm;
  prm.solver = SolverKind::Pgs;
  PressScenario sc(prm, 101);
  double gap = 0, lock = 0, limit = 0, kkt = 0, err = 0;
  for (int i = 0; i < 3000; ++i) {
    const StepReport& r = sc.step(i, 0.003, 0.05);
    ASSERT_TRUE(allFinite(sc.stepper.poses())) << i;
    EXPECT_EQ(r.solve.status, SolveStatus::SweepLimit);
    gap = std::max(gap, r.joint_errors.gap);
    lock = std::max(lock, r.joint_errors.lock);
    limit = std::max(limit, r.joint_errors.limit);
    kkt = std::max(kkt, r.solve.kkt_residual);
    err = std::max(err, maxPositionError(sc.stepper.poses(), sc.T));
  }
  figure("pgs_max_joint_gap_m", gap);
  figure("pgs_max_lock_error", lock);
  figure("pgs_max_limit_violation_rad", limit);
  figure("pgs_max_penetration_beyond_margin_m", sc.max_pen);
  figure("pgs_penetration_over_second_order_allowance", sc.excess);
  figure("pgs_max_kkt_residual", kkt);
  figure("pgs_max_position_error_m", err);
  EXPECT_LE(gap, 1e-9);
  EXPECT_LE(lock, 1e-9);
  EXPECT_EQ(sc.stepper.counters().solver_failures, 0u);
}

}  // namespace
}  // namespace godhand

namespace godhand {
namespace {

// Review finding: the contact count rising past what was reserved (64 → 65 → 128 → 300) must grow
// every per-row buffer, never write past a vector's size (the sanitizer build checks this with
// _GLIBCXX_ASSERTIONS), and keep the results finite and converged.
TEST(StepGrowth, RisingContactCountsGrowEveryBuffer) {
  const HandModel& m = hand16();
  ClusterStepper s(m, StepParams{});
  s.reserve(64);
  std::vector<Contact> base, many;
  for (int n : {64, 65, 128, 300, 16, 300}) {
    planeContacts(m, s.poses(), -0.02, 1.0, base);
    ASSERT_FALSE(base.empty());
    many.resize(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) {
      many[static_cast<size_t>(k)] = base[static_cast<size_t>(k) % base.size()];
      many[static_cast<size_t>(k)].key = static_cast<std::uint64_t>(k) + 1;
    }
    std::vector<Pose> T = s.poses();
    for (auto& t : T) t.p.z() -= 0.001;
    const StepReport& r = s.step({T.data(), nullptr, many.data(), n});
    EXPECT_EQ(r.contact_rows, n);
    EXPECT_NE(r.solve.status, SolveStatus::NumericalFailure);
    for (const Pose& X : s.poses()) ASSERT_TRUE(isValidPose(X, 1e-9));
  }
}

}  // namespace
}  // namespace godhand
