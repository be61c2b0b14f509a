// The left-hand models (deploy/models/hand16_left.pbtxt, hand6_left.pbtxt, written by
// make_models.py as the mirror image of the right hand in the model's x).
//
// Oracle: the mirror F = diag(−1, 1, 1). Rest positions map x → −x, rest orientations R → F R F
// (mirror, then flip x so frames stay right-handed); flexion keeps its sign and abduction flips,
// so forward kinematics with angles (θ1, θ2) on the right and (θ1, −θ2) on the left gives
// mirrored body positions, and jointAngles recovers those angles on both.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "common/files.h"
#include "model/hand_model.h"

namespace godhand {
namespace {

std::string modelPath(const std::string& f) { return std::string(GODHAND_MODELS_DIR) + "/" + f; }

const Mat3 kF = Vec3(-1.0, 1.0, 1.0).asDiagonal();

Quat rotX(double a) { return Quat(Eigen::AngleAxisd(a, Vec3::UnitX())); }
Quat rotY(double a) { return Quat(Eigen::AngleAxisd(a, Vec3::UnitY())); }

std::vector<Pose> forwardKinematics(const HandModel& m, const Pose& X_WM, const std::vector<std::array<double, 2>>& angles) {
  std::vector<Pose> X = m.restPoses(X_WM);
  std::vector<bool> done(m.bodies.size(), true);
  for (const Joint& j : m.joints) done[static_cast<std::size_t>(j.child)] = false;
  for (std::size_t pass = 0; pass < m.joints.size(); ++pass)
    for (std::size_t k = 0; k < m.joints.size(); ++k) {
      const Joint& j = m.joints[k];
      if (done[static_cast<std::size_t>(j.child)] || !done[static_cast<std::size_t>(j.parent)]) continue;
      const Quat rel = j.type == JointType::Spherical2Dof ? rotX(angles[k][0]) * rotY(angles[k][1]) : rotX(angles[k][0]);
      X[static_cast<std::size_t>(j.child)] = X[static_cast<std::size_t>(j.parent)] * j.X_PJ * Pose{Vec3::Zero(), rel} * j.X_CJ.inverse();
      done[static_cast<std::size_t>(j.child)] = true;
    }
  return X;
}

void expectMirroredRest(const HandModel& right, const HandModel& left) {
  ASSERT_EQ(right.bodies.size(), left.bodies.size());
  const std::vector<Pose> R = right.restPoses(Pose()), L = left.restPoses(Pose());
  for (std::size_t i = 0; i < R.size(); ++i) {
    SCOPED_TRACE(left.bodies[i].name);
    EXPECT_EQ(right.bodies[i].name, left.bodies[i].name);
    EXPECT_EQ(right.bodies[i].tracker_segment, left.bodies[i].tracker_segment);
    EXPECT_EQ(right.bodies[i].mass, left.bodies[i].mass);
    EXPECT_LT((L[i].p - kF * R[i].p).norm(), 1e-15);
    EXPECT_LT((L[i].q.toRotationMatrix() - kF * R[i].q.toRotationMatrix() * kF).norm(), 1e-12);
    EXPECT_NEAR(L[i].q.toRotationMatrix().determinant(), 1.0, 1e-12);
  }
}

TEST(LeftModel, LoadsAndIsTheMirrorImageAtRest) {
  const HandModel r16 = loadHandModel(modelPath("hand16_right.pbtxt"));
  const HandModel l16 = loadHandModel(modelPath("hand16_left.pbtxt"));
  const HandModel r6 = loadHandModel(modelPath("hand6_right.pbtxt"));
  const HandModel l6 = loadHandModel(modelPath("hand6_left.pbtxt"));
  EXPECT_EQ(l16.name, "hand16_left");
  EXPECT_EQ(l6.name, "hand6_left");
  EXPECT_EQ(l16.bodies.size(), 16u);
  EXPECT_EQ(l16.joints.size(), 15u);
  EXPECT_EQ(l16.equalityRows(), r16.equalityRows());
  EXPECT_EQ(l16.joint_order, r16.joint_order);
  EXPECT_EQ(l6.bodies.size(), 6u);
  EXPECT_TRUE(l6.joints.empty());
  expectMirroredRest(r16, l16);
  expectMirroredRest(r6, l6);
  // Thumb on +x in the left hand.
  EXPECT_GT(l16.bodies[static_cast<std::size_t>(l16.bodyIndex("thumb.3"))].X_MB_rest.p.x(), 0.05);
  EXPECT_GT(l6.bodies[static_cast<std::size_t>(l6.bodyIndex("thumb.tip"))].X_MB_rest.p.x(), 0.05);
  // Limits: flexion unchanged, abduction mirrored ([lo, hi] -> [-hi, -lo]).
  for (std::size_t k = 0; k < r16.joints.size(); ++k) {
    const Joint &a = r16.joints[k], &b = l16.joints[k];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.type, b.type);
    EXPECT_EQ(a.limits[0].lower, b.limits[0].lower);
    EXPECT_EQ(a.limits[0].upper, b.limits[0].upper);
    EXPECT_EQ(a.limits[1].enabled, b.limits[1].enabled);
    if (a.limits[1].enabled) {
      EXPECT_EQ(-a.limits[1].upper, b.limits[1].lower);
      EXPECT_EQ(-a.limits[1].lower, b.limits[1].upper);
    }
  }
}

TEST(LeftModel, SameFlexionGivesMirroredPoses) {
  const HandModel r = loadHandModel(modelPath("hand16_right.pbtxt"));
  const HandModel l = loadHandModel(modelPath("hand16_left.pbtxt"));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0.0;
  for (int trial = 0; trial < 100; ++trial) {
    std::vector<std::array<double, 2>> ar(r.joints.size()), al(r.joints.size());
    for (std::size_t k = 0; k < r.joints.size(); ++k) {
      const Joint& j = r.joints[k];
      const double t1 = j.limits[0].lower + (j.limits[0].upper - j.limits[0].lower) * u(rng);
      const double t2 = j.limits[1].enabled ? j.limits[1].lower + (j.limits[1].upper - j.limits[1].lower) * u(rng) : 0.0;
      ar[k] = {t1, t2};
      al[k] = {t1, -t2};
    }
    const std::vector<Pose> XR = forwardKinematics(r, Pose(), ar), XL = forwardKinematics(l, Pose(), al);
    for (std::size_t i = 0; i < XR.size(); ++i) {
      worst = std::max(worst, (XL[i].p - kF * XR[i].p).norm());
      EXPECT_LT((XL[i].q.toRotationMatrix() - kF * XR[i].q.toRotationMatrix() * kF).norm(), 1e-12);
    }
    for (std::size_t k = 0; k < r.joints.size(); ++k) {
      const Joint& j = l.joints[k];
      const auto got = jointAngles(j, XL[static_cast<std::size_t>(j.parent)], XL[static_cast<std::size_t>(j.child)]);
      EXPECT_NEAR(got[0], al[k][0], 1e-12) << j.name;
      if (j.type == JointType::Spherical2Dof) {
        EXPECT_NEAR(got[1], al[k][1], 1e-12) << j.name;
      }
    }
  }
  EXPECT_LT(worst, 1e-14);
  std::printf("[figure] left_model.mirrored_fk_position_error_max = %.3g m\n", worst);
}

TEST(LeftModel, PositiveFlexionCurlsTowardThePalmInBothHands) {
  for (const char* file : {"hand16_right.pbtxt", "hand16_left.pbtxt"}) {
    const HandModel m = loadHandModel(modelPath(file));
    for (std::size_t k = 0; k < m.joints.size(); ++k) {
      const Joint& j = m.joints[k];
      std::vector<std::array<double, 2>> angles(m.joints.size(), {0.0, 0.0});
      angles[k][0] = 0.3;
      const std::vector<Pose> X0 = forwardKinematics(m, Pose(), std::vector<std::array<double, 2>>(m.joints.size(), {0.0, 0.0}));
      const std::vector<Pose> X1 = forwardKinematics(m, Pose(), angles);
      // The child's distal end moves toward the palmar side (−z of the model/palm frame).
      const Body& c = m.bodies[static_cast<std::size_t>(j.child)];
      const Vec3 end = Vec3(0, 0, c.shape.half_length);
      EXPECT_LT((X1[static_cast<std::size_t>(j.child)] * end).z(), (X0[static_cast<std::size_t>(j.child)] * end).z() - 1e-4) << file << " " << j.name;
    }
  }
}

}  // namespace
}  // namespace godhand
