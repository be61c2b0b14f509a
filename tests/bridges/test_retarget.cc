// Retargeting of tracked Leap hands onto hand models, and HandTracks (bridges/leap/retarget.h).
//
// Oracles: forward kinematics of the model with known joint angles produces a synthetic tracked
// hand, and retargeting must give back exactly those body poses (round trip); on real frames
// the targets must be unit, finite, have zero joint gap, z along the tracked bone, the palm on the
// palm frame; the 6-body tips must be the tracked tips scaled about the palm. Measured figures
// (model vs tracker mismatch, how far targets violate the joints' locked directions, frame-to-
// frame rotation) are printed as "[figure] name = value" lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>

#include "common/files.h"
#include "leap/leap_recording.h"
#include "leap/retarget.h"

namespace godhand::leap {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = 180.0 / kPi;

std::string modelPath(const std::string& f) { return std::string(GODHAND_MODELS_DIR) + "/" + f; }
std::string recordingPath(const std::string& f) { return std::string(GODHAND_DEPLOY_DIR) + "/recordings/" + f; }

std::string readText(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void figure(const std::string& name, double value, const char* unit = "") {
  std::printf("[figure] %s = %.4g%s%s\n", name.c_str(), value, *unit ? " " : "", unit);
}

Quat rotX(double a) { return Quat(Eigen::AngleAxisd(a, Vec3::UnitX())); }
Quat rotY(double a) { return Quat(Eigen::AngleAxisd(a, Vec3::UnitY())); }

/// Forward kinematics: body poses for the model frame at X_WM and the given joint angles.
std::vector<Pose> forwardKinematics(const HandModel& m, const Pose& X_WM, const std::vector<std::array<double, 2>>& angles) {
  std::vector<Pose> X = m.restPoses(X_WM);
  std::vector<bool> done(m.bodies.size(), true);
  for (const Joint& j : m.joints) done[static_cast<std::size_t>(j.child)] = false;
  for (std::size_t pass = 0; pass < m.joints.size(); ++pass)
    for (std::size_t k = 0; k < m.joints.size(); ++k) {
      const Joint& j = m.joints[k];
      if (done[static_cast<std::size_t>(j.child)] || !done[static_cast<std::size_t>(j.parent)]) continue;
      const Quat rel = j.type == JointType::Spherical2Dof ? rotX(angles[k][0]) * rotY(angles[k][1])
                       : j.type == JointType::Revolute    ? rotX(angles[k][0])
                                                          : Quat::Identity();
      X[static_cast<std::size_t>(j.child)] = X[static_cast<std::size_t>(j.parent)] * j.X_PJ * Pose{Vec3::Zero(), rel} * j.X_CJ.inverse();
      done[static_cast<std::size_t>(j.child)] = true;
    }
  return X;
}

int fingerIndex(const std::string& name) {
  for (int f = 0; f < kFingerCount; ++f)
    if (name.rfind(std::string(fingerName(f)) + ".", 0) == 0) return f;
  return -1;
}

/// A tracked hand read off a 16-body model pose: palm frame = model frame, mcp/pip/dip = joint
/// anchors, tip = distal end of the .3 capsule.
TrackedHand trackedFromModel(const HandModel& m, const Pose& X_WM, const std::vector<Pose>& X, bool right) {
  TrackedHand h;
  h.id = 1;
  h.right = right;
  h.confidence = 1.0;
  h.X_W_palm = X_WM;
  for (const Joint& j : m.joints) {
    const Body& c = m.bodies[static_cast<std::size_t>(j.child)];
    const int f = fingerIndex(c.name);
    const int bone = c.name.back() - '1';
    h.joints_W[f][bone] = X[static_cast<std::size_t>(j.child)] * j.X_CJ.p;
    if (bone == 2) h.joints_W[f][kTip] = X[static_cast<std::size_t>(j.child)] * Vec3(0, 0, c.shape.half_length);
  }
  return h;
}

/// Tracked segment that drives a phalanx body ("index.2" -> pip→dip), normalised.
Vec3 trackedDirection(const TrackedHand& h, const std::string& segment) {
  const int f = fingerIndex(segment);
  const int bone = segment.back() - '1';
  return (h.joints_W[f][bone + 1] - h.joints_W[f][bone]).normalized();
}

double angleBetween(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

/// How far a target pair violates a joint's locked directions (rad): SPHERICAL_2DOF twist lock
/// x_P · y_C = 0, REVOLUTE x_C ∥ x_P.
double lockViolation(const Joint& j, const Pose& X_WP, const Pose& X_WC) {
  const Mat3 P = (X_WP.q * j.X_PJ.q).toRotationMatrix(), C = (X_WC.q * j.X_CJ.q).toRotationMatrix();
  if (j.type == JointType::Spherical2Dof) return std::asin(std::min(1.0, std::abs(P.col(0).dot(C.col(1)))));
  if (j.type == JointType::Revolute) return angleBetween(P.col(0), C.col(0));
  return 0.0;
}

struct Loaded {
  HandModel right16, left16, right6, left6;
  Loaded()
      : right16(loadHandModel(modelPath("hand16_right.pbtxt"))),
        left16(loadHandModel(modelPath("hand16_left.pbtxt"))),
        right6(loadHandModel(modelPath("hand6_right.pbtxt"))),
        left6(loadHandModel(modelPath("hand6_left.pbtxt"))) {}
};

const Loaded& models() {
  static const Loaded m;
  return m;
}

// ---------------------------------------------------------------------------------------------
// Construction

TEST(Retarget, ConstructorChecksSegmentNames) {
  EXPECT_TRUE(Retargeter(models().right16).modelIsRight().value());
  EXPECT_FALSE(Retargeter(models().left16).modelIsRight().value());
  EXPECT_TRUE(Retargeter(models().right6).modelIsRight().value());
  EXPECT_FALSE(Retargeter(models().left6).modelIsRight().value());
  const HandModel tool = loadHandModel(modelPath("tool1.pbtxt"));
  try {
    Retargeter r(tool);
    ADD_FAILURE() << "tool1 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown tracker_segment 'tool'"), std::string::npos) << e.what();
  }
  std::string text = readText(modelPath("hand16_right.pbtxt"));
  const std::string from = "tracker_segment: \"ring.2\"";
  text.replace(text.find(from), from.size(), "tracker_segment: \"ring.4\"");
  try {
    Retargeter r(HandModel::fromText(text, "edited"));
    ADD_FAILURE() << "ring.4 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("body 'ring.2' has unknown tracker_segment 'ring.4'"), std::string::npos) << e.what();
  }
}

TEST(Retarget, AModelNothingDrivesIsRefused) {
  std::string text = readText(modelPath("hand16_right.pbtxt"));
  for (size_t at; (at = text.find("tracker_segment:")) != std::string::npos;) text.erase(at, text.find('\n', at) - at);
  try {
    Retargeter r(HandModel::fromText(text, "undriven"));
    ADD_FAILURE() << "a model without tracker segments accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no body has a tracker_segment"), std::string::npos) << e.what();
  }
}

TEST(Retarget, UndrivenBodyHasNoTarget) {
  std::string text = readText(modelPath("hand16_right.pbtxt"));
  const std::string from = "tracker_segment: \"pinky.3\"";
  text.replace(text.find(from), from.size(), "tracker_segment: \"\"");
  const HandModel m = HandModel::fromText(text, "edited");
  const Recording rec = Recording::load(recordingPath("pinch.json"));
  std::vector<Pose> X;
  std::vector<unsigned char> has;
  Retargeter(m).targets(rec.frames()[0].hands[0], &X, &has);
  ASSERT_EQ(has.size(), 16u);
  for (std::size_t i = 0; i < has.size(); ++i) EXPECT_EQ(has[i], m.bodies[i].name == "pinky.3" ? 0 : 1) << m.bodies[i].name;
  EXPECT_TRUE(isValidPose(X[static_cast<std::size_t>(m.bodyIndex("pinky.3"))]));
}

TEST(Retarget, RefusesAHandOfTheOtherSide) {
  const Recording rec = Recording::load(recordingPath("pinch.json"));
  std::vector<Pose> X;
  std::vector<unsigned char> has;
  EXPECT_THROW(Retargeter(models().left16).targets(rec.frames()[0].hands[0], &X, &has), std::invalid_argument);
  EXPECT_THROW(Retargeter(models().left6).targets(rec.frames()[0].hands[0], &X, &has), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Round trip: FK of known angles -> tracked hand -> targets == FK poses

TEST(Retarget, RoundTripRecoversModelPosesExactly) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst_p = 0.0, worst_q = 0.0, worst_p_min = 0.0;
  for (const bool right : {true, false}) {
    const HandModel& m = right ? models().right16 : models().left16;
    const Retargeter exact(m), minimal(m, RetargetOptions{TwistRule::kMinimalRotation});
    for (int trial = 0; trial < 200; ++trial) {
      // Braced lists draw left to right (function arguments: in an unspecified order, which gcc
      // and clang take differently).
      const Pose X_WM{Vec3{u(rng) - 0.5, u(rng) - 0.5, u(rng)}, expRotation(Vec3{u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5} * 4.0)};
      std::vector<std::array<double, 2>> angles(m.joints.size());
      for (std::size_t k = 0; k < m.joints.size(); ++k)
        for (int a = 0; a < m.joints[k].angleCount(); ++a) {
          const JointLimit& l = m.joints[k].limits[static_cast<std::size_t>(a)];
          angles[k][static_cast<std::size_t>(a)] = l.enabled ? l.lower + (l.upper - l.lower) * u(rng) : 0.5 * (u(rng) - 0.5);
        }
      const std::vector<Pose> X = forwardKinematics(m, X_WM, angles);
      const TrackedHand h = trackedFromModel(m, X_WM, X, right);
      std::vector<Pose> T, Tm;
      std::vector<unsigned char> has;
      exact.targets(h, &T, &has);
      minimal.targets(h, &Tm, &has);
      for (std::size_t i = 0; i < X.size(); ++i) {
        worst_p = std::max(worst_p, (T[i].p - X[i].p).norm());
        worst_q = std::max(worst_q, T[i].q.angularDistance(X[i].q));
        // The twist rule changes orientations about the bone only, never positions.
        worst_p_min = std::max(worst_p_min, (Tm[i].p - X[i].p).norm());
      }
      for (std::size_t k = 0; k < m.joints.size(); ++k) {
        const Joint& j = m.joints[k];
        const auto got = jointAngles(j, T[static_cast<std::size_t>(j.parent)], T[static_cast<std::size_t>(j.child)]);
        EXPECT_NEAR(got[0], angles[k][0], 1e-9) << j.name;
        EXPECT_NEAR(got[1], j.type == JointType::Spherical2Dof ? angles[k][1] : 0.0, 1e-9) << j.name;
      }
    }
  }
  EXPECT_LT(worst_p, 1e-12);
  EXPECT_LT(worst_q, 1e-9);
  EXPECT_LT(worst_p_min, 1e-12);
  figure("retarget.round_trip_position_error_max", worst_p, "m");
  figure("retarget.round_trip_orientation_error_max", worst_q, "rad");
}

// ---------------------------------------------------------------------------------------------
// Real frames

struct Figures {
  double gap = 0, z_dev = 0, palm_dev = 0, unit_dev = 0;
  double lock_sph = 0, lock_rev = 0, lock_sph_min = 0, lock_rev_min = 0;
  double limit_excess = 0;
  std::size_t beyond_limits = 0, joint_samples = 0;
  double tip_dist_sum = 0, tip_dist_max = 0;
  std::size_t tip_n = 0;
  double step_palm = 0, step_phalanx = 0;
  std::size_t palm_jumps = 0;  ///< frames whose palm turns by more than 20 deg
};

TEST(Retarget, RealFramesSixteenBodies) {
  std::map<std::string, std::array<std::array<double, 3>, kFingerCount>> bone_sum;
  std::map<std::string, std::size_t> bone_n;
  for (const char* file : {"pinch.json", "HandSplay-110fps.json", "confidence2-49fps.json"}) {
    const Recording rec = Recording::load(recordingPath(file));
    Figures fig;
    std::map<int, std::vector<Pose>> previous;  // by hand id
    for (const TrackerFrame& fr : rec.frames()) {
      for (const TrackedHand& h : fr.hands) {
        const HandModel& m = h.right ? models().right16 : models().left16;
        const Retargeter exact(m), minimal(m, RetargetOptions{TwistRule::kMinimalRotation});
        std::vector<Pose> T, Tm;
        std::vector<unsigned char> has;
        EXPECT_EQ(exact.targets(h, &T, &has), 0);
        minimal.targets(h, &Tm, &has);
        ASSERT_EQ(T.size(), m.bodies.size());
        for (std::size_t i = 0; i < T.size(); ++i) {
          ASSERT_EQ(has[i], 1);
          ASSERT_TRUE(T[i].p.allFinite() && T[i].q.coeffs().allFinite()) << m.bodies[i].name;
          fig.unit_dev = std::max(fig.unit_dev, std::abs(T[i].q.norm() - 1.0));
          const std::string& seg = m.bodies[i].tracker_segment;
          if (seg == "palm") {
            fig.palm_dev = std::max({fig.palm_dev, (T[i].p - h.X_W_palm.p).norm(), T[i].q.angularDistance(h.X_W_palm.q)});
          } else {
            const Vec3 d = trackedDirection(h, seg);
            fig.z_dev = std::max({fig.z_dev, (T[i].q * Vec3::UnitZ()).cross(d).norm(), (Tm[i].q * Vec3::UnitZ()).cross(d).norm()});
            EXPECT_GT((T[i].q * Vec3::UnitZ()).dot(d), 0.0);
          }
        }
        for (const Joint& j : m.joints) {
          const Pose &P = T[static_cast<std::size_t>(j.parent)], &C = T[static_cast<std::size_t>(j.child)];
          const Pose &Pm = Tm[static_cast<std::size_t>(j.parent)], &Cm = Tm[static_cast<std::size_t>(j.child)];
          fig.gap = std::max({fig.gap, jointGap(j, P, C), jointGap(j, Pm, Cm)});
          const double v = lockViolation(j, P, C), vm = lockViolation(j, Pm, Cm);
          if (j.type == JointType::Spherical2Dof) {
            fig.lock_sph = std::max(fig.lock_sph, v);
            fig.lock_sph_min = std::max(fig.lock_sph_min, vm);
          } else {
            // Projecting the hinge is the least violation possible with z on the tracked bone:
            // asin |d · x_hinge| for the parent's hinge axis.
            const Vec3 hinge = P.q * (j.X_PJ.q * Vec3::UnitX()), d = C.q * Vec3::UnitZ();
            EXPECT_NEAR(v, std::asin(std::min(1.0, std::abs(d.dot(hinge)))), 1e-9) << j.name;
            fig.lock_rev = std::max(fig.lock_rev, v);
            fig.lock_rev_min = std::max(fig.lock_rev_min, vm);
          }
          const auto a = jointAngles(j, P, C);
          for (int k = 0; k < j.angleCount(); ++k) {
            const JointLimit& l = j.limits[static_cast<std::size_t>(k)];
            if (!l.enabled) continue;
            const double excess = std::max(l.lower - a[static_cast<std::size_t>(k)], a[static_cast<std::size_t>(k)] - l.upper);
            ++fig.joint_samples;
            if (excess > 0) {
              ++fig.beyond_limits;
              fig.limit_excess = std::max(fig.limit_excess, excess);
            }
          }
        }
        // Tracked tip vs the FK tip of the target (model lengths and knuckles differ).
        for (std::size_t i = 0; i < T.size(); ++i) {
          const std::string& seg = m.bodies[i].tracker_segment;
          if (seg.size() < 2 || seg.back() != '3') continue;
          const Vec3 tip = T[i] * Vec3(0, 0, m.bodies[i].shape.half_length);
          const double dist = (tip - h.joints_W[fingerIndex(seg)][kTip]).norm();
          fig.tip_dist_sum += dist;
          fig.tip_dist_max = std::max(fig.tip_dist_max, dist);
          ++fig.tip_n;
        }
        auto prev = previous.find(h.id);
        if (prev != previous.end()) {
          for (std::size_t i = 0; i < T.size(); ++i) {
            const double step = T[i].q.angularDistance(prev->second[i].q);
            (m.bodies[i].tracker_segment == "palm" ? fig.step_palm : fig.step_phalanx) =
                std::max(m.bodies[i].tracker_segment == "palm" ? fig.step_palm : fig.step_phalanx, step);
          }
        }
        const std::size_t palm = static_cast<std::size_t>(m.bodyIndex("palm"));
        if (prev != previous.end() && T[palm].q.angularDistance(prev->second[palm].q) > 20.0 / kDeg) ++fig.palm_jumps;
        previous[h.id] = T;
        // Tracked bone lengths (per side), for the comparison with the model.
        const std::string side = h.right ? "right" : "left";
        auto& sums = bone_sum[side];
        for (int f = 0; f < kFingerCount; ++f)
          for (int b = 0; b < 3; ++b) sums[f][b] += (h.joints_W[f][b + 1] - h.joints_W[f][b]).norm();
        ++bone_n[side];
      }
    }
    EXPECT_LT(fig.gap, 1e-12) << file;
    EXPECT_LT(fig.z_dev, 1e-12) << file;
    EXPECT_LT(fig.palm_dev, 1e-15) << file;
    EXPECT_LT(fig.unit_dev, 1e-14) << file;
    EXPECT_LT(fig.lock_sph, 1e-12) << file;  // exact twist lock with the joint-consistent rule
    const std::string tag = std::string("retarget16.") + file;
    figure(tag + ".joint_gap_max", fig.gap, "m");
    figure(tag + ".z_vs_tracked_bone_sin_max", fig.z_dev);
    figure(tag + ".twist_lock_violation_max.joint_consistent", fig.lock_sph * kDeg, "deg");
    figure(tag + ".twist_lock_violation_max.minimal_rotation", fig.lock_sph_min * kDeg, "deg");
    figure(tag + ".hinge_violation_max.joint_consistent", fig.lock_rev * kDeg, "deg");
    figure(tag + ".hinge_violation_max.minimal_rotation", fig.lock_rev_min * kDeg, "deg");
    figure(tag + ".joint_angles_beyond_limits_fraction", static_cast<double>(fig.beyond_limits) / static_cast<double>(std::max<std::size_t>(1, fig.joint_samples)));
    figure(tag + ".joint_angle_beyond_limit_max", fig.limit_excess * kDeg, "deg");
    figure(tag + ".tracked_tip_to_target_tip_mean", fig.tip_dist_sum / static_cast<double>(std::max<std::size_t>(1, fig.tip_n)), "m");
    figure(tag + ".tracked_tip_to_target_tip_max", fig.tip_dist_max, "m");
    figure(tag + ".palm_rotation_between_frames_max", fig.step_palm * kDeg, "deg");
    figure(tag + ".phalanx_rotation_between_frames_max", fig.step_phalanx * kDeg, "deg");
    figure(tag + ".frames_with_palm_turning_over_20deg", static_cast<double>(fig.palm_jumps));
  }
  // Tracked bone lengths (mm, mean over frames) vs the model's joint-to-joint lengths.
  const HandModel& m = models().right16;
  for (const auto& [side, sums] : bone_sum) {
    for (int f = 0; f < kFingerCount; ++f) {
      double model_len[3];
      for (int b = 0; b < 3; ++b)
        model_len[b] = 2.0 * m.bodies[static_cast<std::size_t>(m.bodyIndex(std::string(fingerName(f)) + "." + std::to_string(b + 1)))].shape.half_length;
      const double n = static_cast<double>(bone_n[side]);
      std::printf("[figure] retarget16.bone_lengths.%s.%s = tracked %.1f/%.1f/%.1f mm vs model %.1f/%.1f/%.1f mm\n", side.c_str(), fingerName(f),
                  sums[f][0] / n * 1e3, sums[f][1] / n * 1e3, sums[f][2] / n * 1e3, model_len[0] * 1e3, model_len[1] * 1e3, model_len[2] * 1e3);
    }
  }
  // Knuckles: tracked mcp in the palm frame vs the model's MCP anchors (first pinch frame).
  const TrackedHand h = Recording::load(recordingPath("pinch.json")).frames()[0].hands[0];
  for (const Joint& j : m.joints) {
    if (j.parent != m.bodyIndex("palm")) continue;
    const int f = fingerIndex(m.bodies[static_cast<std::size_t>(j.child)].name);
    const Vec3 t = h.X_W_palm.inverse() * h.joints_W[f][kMcp];
    std::printf("[figure] retarget16.knuckle.%s = tracked (%.1f, %.1f, %.1f) mm vs model (%.1f, %.1f, %.1f) mm (palm frame)\n", fingerName(f), t.x() * 1e3,
                t.y() * 1e3, t.z() * 1e3, j.X_PJ.p.x() * 1e3, j.X_PJ.p.y() * 1e3, j.X_PJ.p.z() * 1e3);
  }
}

TEST(Retarget, DegenerateSegmentKeepsTheRestOrientationCarriedByTheParent) {
  const Recording rec = Recording::load(recordingPath("pinch.json"));
  TrackedHand h = rec.frames()[10].hands[0];
  h.joints_W[kIndex][kPip] = h.joints_W[kIndex][kMcp];  // index.1 zero length
  const HandModel& m = models().right16;
  const Retargeter r(m);
  std::vector<Pose> T;
  std::vector<unsigned char> has;
  EXPECT_EQ(r.targets(h, &T, &has), 1);
  const std::size_t i1 = static_cast<std::size_t>(m.bodyIndex("index.1"));
  EXPECT_LT(T[i1].q.angularDistance(h.X_W_palm.q * m.bodies[i1].X_MB_rest.q), 1e-12);
  for (const Joint& j : m.joints) EXPECT_LT(jointGap(j, T[static_cast<std::size_t>(j.parent)], T[static_cast<std::size_t>(j.child)]), 1e-12);
  for (const Pose& X : T) EXPECT_TRUE(isValidPose(X, 1e-12));
}

TEST(Retarget, RealFramesSixBodies) {
  double worst = 0.0, pinch_tracked = 1e9, pinch_target = 1e9, s_min = 1e9, s_max = 0.0;
  for (const char* file : {"pinch.json", "HandSplay-110fps.json", "confidence2-49fps.json"}) {
    const Recording rec = Recording::load(recordingPath(file));
    for (const TrackerFrame& fr : rec.frames())
      for (const TrackedHand& h : fr.hands) {
        const HandModel& m = h.right ? models().right6 : models().left6;
        const Retargeter r(m);
        std::vector<Pose> T;
        std::vector<unsigned char> has;
        r.targets(h, &T, &has);
        const double s = r.tipScale(h);
        s_min = std::min(s_min, s);
        s_max = std::max(s_max, s);
        // s = Σ model |tip| / Σ tracked straight finger length, over index..pinky.
        double model_size = 0.0, tracked_size = 0.0;
        for (int f = kIndex; f <= kPinky; ++f) {
          model_size += m.bodies[static_cast<std::size_t>(m.bodyIndex(std::string(fingerName(f)) + ".tip"))].X_MB_rest.p.norm();
          const auto& jt = h.joints_W[f];
          tracked_size += (jt[0] - h.X_W_palm.p).norm() + (jt[1] - jt[0]).norm() + (jt[2] - jt[1]).norm() + (jt[3] - jt[2]).norm();
        }
        EXPECT_NEAR(s, model_size / tracked_size, 1e-12);
        for (std::size_t i = 0; i < T.size(); ++i) {
          EXPECT_EQ(has[i], 1);
          EXPECT_TRUE(isValidPose(T[i], 1e-12));
          const std::string& seg = m.bodies[i].tracker_segment;
          if (seg == "palm") {
            EXPECT_LT((T[i].p - h.X_W_palm.p).norm(), 1e-15);
            continue;
          }
          const int f = fingerIndex(seg);
          const Vec3 expect = h.X_W_palm * (s * (h.X_W_palm.inverse() * h.joints_W[f][kTip]));
          worst = std::max(worst, (T[i].p - expect).norm());
          EXPECT_LT((T[i].q * Vec3::UnitZ()).cross((h.joints_W[f][kTip] - h.joints_W[f][kDip]).normalized()).norm(), 1e-12);
        }
        // A uniform scale about the palm keeps the pinch: tip distances scale by s.
        const double dt = (h.joints_W[kThumb][kTip] - h.joints_W[kIndex][kTip]).norm();
        const double dm = (T[static_cast<std::size_t>(m.bodyIndex("thumb.tip"))].p - T[static_cast<std::size_t>(m.bodyIndex("index.tip"))].p).norm();
        EXPECT_NEAR(dm, s * dt, 1e-12);
        if (std::string(file) == "pinch.json") {
          pinch_tracked = std::min(pinch_tracked, dt);
          pinch_target = std::min(pinch_target, dm);
        }
      }
  }
  EXPECT_LT(worst, 1e-12);
  figure("retarget6.tip_scale_min", s_min);
  figure("retarget6.tip_scale_max", s_max);
  figure("retarget6.pinch.thumb_index_tip_distance_min.tracked", pinch_tracked, "m");
  figure("retarget6.pinch.thumb_index_tip_distance_min.target", pinch_target, "m");
}

// ---------------------------------------------------------------------------------------------
// HandTracks

TEST(HandTracks, TwoHandRecording) {
  const Recording rec = Recording::load(recordingPath("confidence2-49fps.json"));
  HandTracks tracks;
  for (std::size_t i = 0; i < rec.frames().size(); ++i) {
    tracks.update(rec.frames()[i]);
    const HandSlot& l = tracks.slot(false);
    const HandSlot& r = tracks.slot(true);
    EXPECT_FALSE(l.right);
    EXPECT_TRUE(r.right);
    EXPECT_TRUE(l.present);
    EXPECT_EQ(l.id, 123);
    EXPECT_EQ(l.appeared, i == 0);
    EXPECT_FALSE(l.lost);
    EXPECT_EQ(r.present, i < 132);
    EXPECT_EQ(r.appeared, i == 0);
    EXPECT_EQ(r.lost, i == 132);
    EXPECT_EQ(r.id, 124);  // kept after the loss
    if (r.present) {
      EXPECT_TRUE(r.hand.right);
    }
  }
  EXPECT_EQ(tracks.appearedCount(true), 1u);
  EXPECT_EQ(tracks.lostCount(true), 1u);
  EXPECT_EQ(tracks.appearedCount(false), 1u);
  EXPECT_EQ(tracks.lostCount(false), 0u);
  EXPECT_EQ(tracks.extraHandsIgnored(), 0u);
}

TrackerFrame frameOf(std::initializer_list<std::tuple<int, bool, double>> hands) {
  TrackerFrame f;
  for (const auto& [id, right, conf] : hands) {
    TrackedHand h;
    h.id = id;
    h.right = right;
    h.confidence = conf;
    f.hands.push_back(h);
  }
  return f;
}

TEST(HandTracks, IdChangesDuplicatesAndLosses) {
  HandTracks t;
  const HandSlot& r = t.slot(true);
  const HandSlot& l = t.slot(false);
  t.update(frameOf({{7, true, 1.0}}));
  EXPECT_TRUE(r.present && r.appeared && !r.lost);
  EXPECT_FALSE(l.present || l.appeared || l.lost);
  t.update(frameOf({{7, true, 1.0}}));
  EXPECT_TRUE(r.present && !r.appeared && !r.lost);
  t.update(frameOf({{9, true, 1.0}}));  // new id: lost + appeared
  EXPECT_TRUE(r.present && r.appeared && r.lost);
  EXPECT_EQ(r.id, 9);
  t.update(frameOf({}));
  EXPECT_TRUE(!r.present && !r.appeared && r.lost);
  EXPECT_EQ(r.id, 9);
  t.update(frameOf({}));
  EXPECT_TRUE(!r.present && !r.appeared && !r.lost);
  t.update(frameOf({{9, true, 0.5}, {10, true, 0.9}}));  // two right hands: the more confident
  EXPECT_TRUE(r.present && r.appeared);
  EXPECT_EQ(r.id, 10);
  EXPECT_EQ(t.extraHandsIgnored(), 1u);
  t.update(frameOf({{9, true, 0.9}, {10, true, 0.1}}));  // keeps following id 10
  EXPECT_EQ(r.id, 10);
  EXPECT_FALSE(r.appeared || r.lost);
  EXPECT_EQ(t.extraHandsIgnored(), 2u);
  t.update(frameOf({{5, false, 0.3}}));
  EXPECT_TRUE(l.present && l.appeared);
  EXPECT_EQ(l.id, 5);
  EXPECT_TRUE(!r.present && r.lost);
  EXPECT_EQ(t.appearedCount(true), 3u);
  EXPECT_EQ(t.lostCount(true), 3u);
  t.reset();
  EXPECT_FALSE(t.slot(true).present);
  EXPECT_EQ(t.extraHandsIgnored(), 0u);
}

}  // namespace
}  // namespace godhand::leap
