// Tests of core/math/pose.h: the rotation-vector exp/log maps, the 6D pose difference / update of
// METHOD.md §2 (steps 1 and 4) and pose validation. Oracles are independent of the code under
// test: Eigen::AngleAxisd for exp and log, rotation matrices for the frame convention.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>
#include <algorithm>

#include "math/pose.h"
#include "math/stats.h"

namespace godhand {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Draws are taken one per statement, left to right: C++ leaves the order of function
// arguments and of a binary operator's operands unspecified, so Vec3(normal(), normal(),
// normal()) or draw() * draw() gives gcc and clang different instances from one seed.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(gen_); }
  double normal() { return std::normal_distribution<double>(0.0, 1.0)(gen_); }
  Vec3 normalVector() {  // x, y, z standard normal
    const double x = normal();
    const double y = normal();
    const double z = normal();
    return Vec3(x, y, z);
  }
  Vec3 unitVector() {
    for (;;) {
      const Vec3 v = normalVector();
      if (v.norm() > 1e-3) return v.normalized();
    }
  }
  Quat unitQuaternion() {  // uniform on SO(3) (both hemispheres: w may be negative)
    for (;;) {
      const double w = normal();
      const double x = normal();
      const double y = normal();
      const double z = normal();
      Eigen::Vector4d v(w, x, y, z);
      if (v.norm() > 1e-3) {
        v.normalize();
        return Quat(v[0], v[1], v[2], v[3]);
      }
    }
  }
  int index(int n) { return std::uniform_int_distribution<int>(0, n - 1)(gen_); }

 private:
  std::mt19937_64 gen_;
};

/// Angle for sample i of the round-trip sweeps: a third uniform in [0, π−1e-6], a third tiny
/// (log-uniform in 1e-12..1e-6, plus the Taylor-branch boundary 1e-4), a third near π
/// (π − 10^U(-6, -1)), and a few exact edge values.
double sampleAngle(Rng& rng, int i) {
  switch (i) {
    case 0: return 0.0;
    case 1: return kPi - 1e-6;
    case 2: return 1e-4;
    case 3: return std::nextafter(1e-4, 0.0);
    case 4: return 1e-8;
    case 5: return std::nextafter(1e-8, 1.0);
    default: break;
  }
  switch (i % 4) {
    case 0: return rng.uniform(0.0, kPi - 1e-6);
    case 1: return std::pow(10.0, rng.uniform(-12.0, -6.0));
    case 2: return 1e-4 * std::pow(10.0, rng.uniform(-1.0, 1.0));  // around the Taylor switch
    default: return kPi - std::pow(10.0, rng.uniform(-6.0, -1.0));
  }
}

double quatDistanceUpToSign(const Quat& a, const Quat& b) {
  return std::min((a.coeffs() - b.coeffs()).norm(), (a.coeffs() + b.coeffs()).norm());
}

constexpr int kRoundTrips = 20000;

TEST(MathRotation, ExpMatchesEigenAngleAxis) {
  Rng rng(1);
  double worst_q = 0.0, worst_R = 0.0;
  for (int i = 0; i < kRoundTrips; ++i) {
    const double angle = sampleAngle(rng, i);
    const Vec3 axis = rng.unitVector();
    const Vec3 theta = angle * axis;
    const Quat q = expRotation(theta);
    const Quat ref(Eigen::AngleAxisd(angle, axis));
    ASSERT_NEAR(q.norm(), 1.0, 4e-16) << "angle " << angle;
    ASSERT_GE(q.w(), 0.0) << "|θ| <= π must give the w >= 0 hemisphere";
    // Vector part relative to its own size (keeps tiny rotations honest), w absolute.
    const double ev = (q.vec() - ref.vec()).norm() / std::max(ref.vec().norm(), 1e-300);
    const double ew = std::abs(q.w() - ref.w());
    ASSERT_LE(ev, 1e-14) << "angle " << angle;
    ASSERT_LE(ew, 1e-15) << "angle " << angle;
    const double eR = (q.toRotationMatrix() - ref.toRotationMatrix()).cwiseAbs().maxCoeff();
    ASSERT_LE(eR, 1e-14) << "angle " << angle;
    worst_q = std::max(worst_q, std::max(ev, ew));
    worst_R = std::max(worst_R, eR);
  }
  std::printf("[ stats    ] exp vs AngleAxis: max quaternion err %.3g, max matrix err %.3g\n", worst_q, worst_R);
}

TEST(MathRotation, ExpBeyondPiMatchesAngleAxis) {
  // exp is defined for every |θ|; it must agree with AngleAxis as a rotation (up to q sign).
  Rng rng(2);
  for (int i = 0; i < 2000; ++i) {
    const double angle = rng.uniform(kPi, 6.0 * kPi);
    const Vec3 axis = rng.unitVector();
    const Quat q = expRotation(angle * axis);
    const Quat ref(Eigen::AngleAxisd(angle, axis));
    ASSERT_LE(quatDistanceUpToSign(q, ref), 1e-14) << "angle " << angle;
    ASSERT_NEAR(q.norm(), 1.0, 4e-16);
  }
}

TEST(MathRotation, LogOfExpRoundTrip) {
  Rng rng(3);
  double worst_rel = 0.0, worst_abs = 0.0;
  for (int i = 0; i < kRoundTrips; ++i) {
    const double angle = sampleAngle(rng, i);
    const Vec3 theta = angle * rng.unitVector();
    const Vec3 back = logRotation(expRotation(theta));
    const double err = (back - theta).norm();
    // 1e-12 relative for every size (tiny angles keep full relative precision), 1e-300 floor for 0.
    ASSERT_LE(err, 1e-12 * angle + 1e-300) << "angle " << angle << " err " << err;
    ASSERT_LE(back.norm(), kPi);
    worst_rel = std::max(worst_rel, angle > 0 ? err / angle : 0.0);
    worst_abs = std::max(worst_abs, err);
  }
  std::printf("[ stats    ] log(exp θ) - θ: max relative %.3g, max absolute %.3g\n", worst_rel, worst_abs);
}

TEST(MathRotation, ExpOfLogRoundTripUpToSign) {
  Rng rng(4);
  double worst = 0.0;
  for (int i = 0; i < kRoundTrips; ++i) {
    Quat q;
    switch (i % 4) {
      case 0: q = rng.unitQuaternion(); break;
      case 1: {  // near identity, both signs
        const double angle = std::pow(10.0, rng.uniform(-12.0, -2.0));
        q = expRotation(angle * rng.unitVector());
        break;
      }
      case 2: {  // near π: w tiny, either sign
        const double angle = kPi - std::pow(10.0, rng.uniform(-10.0, -1.0));
        q = expRotation(angle * rng.unitVector());
        break;
      }
      default: {  // exactly half-turns and their negatives
        const Vec3 a = rng.unitVector();
        q = Quat(0.0, a.x(), a.y(), a.z());
        break;
      }
    }
    if (rng.index(2) == 1) q.coeffs() = -q.coeffs();
    const Vec3 theta = logRotation(q);
    ASSERT_LE(theta.norm(), kPi + 1e-15);
    const double e = quatDistanceUpToSign(expRotation(theta), q);
    ASSERT_LE(e, 1e-14) << "q = " << q.coeffs().transpose();
    worst = std::max(worst, e);
    // q and −q are the same rotation and must have the same log (except at exactly π, where
    // θ and −θ are both valid).
    if (std::abs(q.w()) > 1e-12) {
      Quat mq = q;
      mq.coeffs() = -q.coeffs();
      ASSERT_LE((logRotation(mq) - theta).norm(), 1e-15 * std::max(1.0, theta.norm()));
    }
  }
  std::printf("[ stats    ] exp(log q) vs ±q: max err %.3g\n", worst);
}

TEST(MathRotation, LogMatchesEigenAngleAxis) {
  // Independent oracle: Eigen's AngleAxis from a quaternion (angle in [0, π] after hemisphere fix).
  Rng rng(5);
  for (int i = 0; i < 5000; ++i) {
    Quat q = rng.unitQuaternion();
    const Vec3 theta = logRotation(q);
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    const Eigen::AngleAxisd aa(q);
    const Vec3 ref = aa.angle() * aa.axis();
    ASSERT_LE((theta - ref).norm(), 1e-13 * std::max(1.0, ref.norm())) << q.coeffs().transpose();
  }
}

TEST(MathRotation, TinyAnglesKeepRelativePrecision) {
  // The Taylor branches: θ of size 1e-300 .. 1e-6 survive both maps with full relative precision.
  Rng rng(6);
  for (double a = 1e-300; a < 1e-5; a *= 7.3) {
    const Vec3 theta = a * rng.unitVector();
    const Quat q = expRotation(theta);
    if (a < 1e-8) {
      EXPECT_EQ(q.w(), 1.0) << a;  // cos(a/2) rounds to 1
    }
    EXPECT_NEAR(q.w(), std::cos(0.5 * a), 1e-16) << a;
    const Vec3 v_ref = (std::sin(0.5 * a) / a) * theta;
    EXPECT_LE((q.vec() - v_ref).norm(), 1e-15 * v_ref.norm()) << a;
    EXPECT_LE((logRotation(q) - theta).norm(), 1e-15 * a) << a;
  }
  EXPECT_EQ(logRotation(Quat::Identity()), Vec3::Zero());
  EXPECT_EQ(expRotation(Vec3::Zero()).coeffs(), Quat::Identity().coeffs());
}

TEST(MathPose, DifferenceOfUpdateIsStep) {
  Rng rng(7);
  double worst_p = 0.0, worst_r = 0.0;
  for (int i = 0; i < 10000; ++i) {
    Pose X;
    const Vec3 g = rng.normalVector();
    X.p = g * std::pow(10.0, rng.uniform(-3.0, 4.0));
    X.q = rng.unitQuaternion();
    Vec6 y;
    for (int k = 0; k < 6; ++k) y[k] = rng.normal();
    const double h = std::pow(10.0, rng.uniform(-4.0, 0.0));
    // Scale ω so that |ω h| ranges over [0, π − 1e-3] (tiny ones included).
    const double rot = (i % 3 == 0) ? std::pow(10.0, rng.uniform(-12.0, -3.0)) : rng.uniform(0.0, kPi - 1e-3);
    y.tail<3>() = rng.unitVector() * (rot / h);
    y.head<3>() *= std::pow(10.0, rng.uniform(-3.0, 3.0));
    const Pose Xn = poseUpdate(X, y, h);
    ASSERT_TRUE(isValidPose(Xn, 1e-14));
    const Vec6 d = poseDifference(Xn, X);
    const Vec6 yh = y * h;
    // Position: (p + v h) − p loses the bits of |p|.
    const double ep = (d.head<3>() - yh.head<3>()).norm();
    ASSERT_LE(ep, 4e-16 * (X.p.norm() + yh.head<3>().norm()) * 4) << i;
    // Rotation: the quaternion product and normalisation cost a few ulps of the unit quaternion,
    // i.e. a few 1e-16 rad absolute, plus relative round-off on |ω h|.
    const double er = (d.tail<3>() - yh.tail<3>()).norm();
    ASSERT_LE(er, 1e-12 * rot + 2e-15) << "rot " << rot;
    worst_p = std::max(worst_p, ep / std::max(1e-300, X.p.norm() + yh.head<3>().norm()));
    worst_r = std::max(worst_r, er);
  }
  std::printf("[ stats    ] poseDifference(poseUpdate(X,y,h),X) - y h: position rel %.3g, rotation abs %.3g rad\n",
              worst_p, worst_r);
}

TEST(MathPose, RotationPartIsWorldFrame) {
  // poseDifference's θ is log(R_target R_godᵀ) (world frame), checked with rotation matrices and
  // AngleAxis; the body-frame alternative log(R_godᵀ R_target) differs and must not match.
  Rng rng(8);
  int differs_from_body_frame = 0;
  for (int i = 0; i < 5000; ++i) {
    Pose target, god;
    target.q = rng.unitQuaternion();
    god.q = rng.unitQuaternion();
    target.p = rng.normalVector();
    god.p = rng.normalVector();
    const Vec6 d = poseDifference(target, god);
    EXPECT_LE((d.head<3>() - (target.p - god.p)).norm(), 1e-15);
    const Vec3 theta = d.tail<3>();
    const double angle = theta.norm();
    ASSERT_LE(angle, kPi + 1e-15);
    const Mat3 R_t = target.q.toRotationMatrix(), R_g = god.q.toRotationMatrix();
    const Mat3 R_world = R_t * R_g.transpose();
    const Mat3 R_theta = angle > 0 ? Eigen::AngleAxisd(angle, theta / angle).toRotationMatrix() : Mat3::Identity();
    ASSERT_LE((R_theta - R_world).cwiseAbs().maxCoeff(), 1e-13) << i;
    // Applying it in the world frame brings god onto target.
    ASSERT_LE((R_theta * R_g - R_t).cwiseAbs().maxCoeff(), 1e-13);
    const Mat3 R_body = R_g.transpose() * R_t;
    if ((R_theta - R_body).cwiseAbs().maxCoeff() > 1e-3) ++differs_from_body_frame;
    // poseUpdate applies ω in the world frame too: R_new = exp(ω h) R.
    Vec6 y;
    y << rng.normal(), rng.normal(), rng.normal(), rng.normal(), rng.normal(), rng.normal();
    const Pose Xn = poseUpdate(god, y, 0.5);
    const double a = (0.5 * y.tail<3>()).norm();
    const Mat3 R_step = Eigen::AngleAxisd(a, y.tail<3>().normalized()).toRotationMatrix();
    ASSERT_LE((Xn.q.toRotationMatrix() - R_step * R_g).cwiseAbs().maxCoeff(), 1e-13);
    ASSERT_LE((Xn.p - (god.p + 0.5 * y.head<3>())).norm(), 1e-15 * (1 + god.p.norm() + y.head<3>().norm()));
  }
  EXPECT_GT(differs_from_body_frame, 4500);  // the test can tell world from body frame
}

TEST(MathPose, DifferenceOfIdenticalPosesIsZero) {
  Rng rng(9);
  for (int i = 0; i < 1000; ++i) {
    Pose X;
    X.p = rng.normalVector() * 1e4;  // 10 km from the origin
    X.q = rng.unitQuaternion();
    const Vec6 d = poseDifference(X, X);
    EXPECT_EQ(d.head<3>(), Vec3::Zero());
    EXPECT_LE(d.tail<3>().norm(), 1e-15);
    Pose Xm = X;
    Xm.q.coeffs() = -X.q.coeffs();  // same rotation, other hemisphere
    EXPECT_LE(poseDifference(Xm, X).tail<3>().norm(), 1e-15);
  }
}

TEST(MathPose, IsValidPoseRejectsNonFiniteAndNonUnit) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  Rng rng(10);
  for (int i = 0; i < 200; ++i) {
    Pose X;
    X.p = rng.normalVector() * 1e4;
    X.q = rng.unitQuaternion();
    ASSERT_TRUE(isValidPose(X));
    for (int k = 0; k < 3; ++k) {
      for (double bad : {nan, inf, -inf}) {
        Pose Y = X;
        Y.p[k] = bad;
        ASSERT_FALSE(isValidPose(Y)) << "p[" << k << "] = " << bad;
      }
    }
    for (int k = 0; k < 4; ++k) {  // w, x, y, z through the named accessors
      for (double bad : {nan, inf, -inf}) {
        Pose Y = X;
        double* c[4] = {&Y.q.w(), &Y.q.x(), &Y.q.y(), &Y.q.z()};
        *c[k] = bad;
        ASSERT_FALSE(isValidPose(Y)) << "q[" << k << "] = " << bad;
      }
    }
    for (double s : {0.0, 0.5, 0.999, 1.001, 2.0, 1e10}) {
      Pose Y = X;
      Y.q.coeffs() *= s;
      ASSERT_FALSE(isValidPose(Y)) << "|q| = " << s;
    }
    {  // inside the default tolerance 1e-6, and a custom tolerance
      Pose Y = X;
      Y.q.coeffs() *= 1.0 + 1e-7;
      EXPECT_TRUE(isValidPose(Y));
      EXPECT_FALSE(isValidPose(Y, 1e-8));
      Y.q.coeffs() = X.q.coeffs() * (1.0 + 1e-4);
      EXPECT_FALSE(isValidPose(Y));
      EXPECT_TRUE(isValidPose(Y, 1e-3));
    }
  }
  Pose zero_q;
  zero_q.q = Quat(0, 0, 0, 0);
  EXPECT_FALSE(isValidPose(zero_q));
}

TEST(MathPose, ComposeAndInverse) {
  Rng rng(11);
  for (int i = 0; i < 1000; ++i) {
    Pose X_AB{rng.normalVector(), rng.unitQuaternion()};  // braced: left to right
    Pose X_BC{rng.normalVector(), rng.unitQuaternion()};
    const Vec3 x_C = rng.normalVector();
    // (X_AB X_BC) x = X_AB (X_BC x), checked against rotation matrices.
    const Vec3 ref = X_AB.q.toRotationMatrix() * (X_BC.q.toRotationMatrix() * x_C + X_BC.p) + X_AB.p;
    EXPECT_LE(((X_AB * X_BC) * x_C - ref).norm(), 1e-14);
    const Pose I = X_AB * X_AB.inverse();
    EXPECT_LE(I.p.norm(), 1e-14);
    EXPECT_LE(quatDistanceUpToSign(I.q, Quat::Identity()), 1e-15);
    EXPECT_LE((skew(X_AB.p) * x_C - X_AB.p.cross(x_C)).norm(), 1e-15);
  }
}

}  // namespace
}  // namespace godhand

// The bounded sample of a run's figure (math/stats.h): exact up to its capacity; beyond it a
// uniform sample whose percentiles estimate the exact ones (brute force over the same values),
// with the count and the maximum exact, the memory held to the capacity, the same sample for the
// same values.
TEST(Sample, ExactUpToItsCapacityThenAUniformSampleOfIt) {
  godhand::Sample small(1000);
  std::vector<double> all;
  for (int i = 0; i < 1000; ++i) {
    const double x = std::sin(0.37 * i);
    small.add(x);
    all.push_back(x);
  }
  EXPECT_FALSE(small.sampled());
  EXPECT_EQ(small.values(), all);
  EXPECT_EQ(small.max(), *std::max_element(all.begin(), all.end()));

  godhand::Sample big(4096), again(4096);
  std::vector<double> exact;
  for (int i = 0; i < 1000000; ++i) {
    const double x = std::fmod(0.6180339887 * i, 1.0) * (i % 7 == 0 ? 10.0 : 1.0);  // a skewed mix
    big.add(x);
    again.add(x);
    exact.push_back(x);
  }
  EXPECT_TRUE(big.sampled());
  EXPECT_EQ(big.count(), 1000000u);
  EXPECT_EQ(big.values().size(), 4096u);
  EXPECT_EQ(big.max(), *std::max_element(exact.begin(), exact.end()));
  EXPECT_EQ(big.values(), again.values());  // deterministic
  for (const double p : {0.5, 0.95, 0.99}) {
    // The sample's percentile is within the exact distribution's percentiles p ± 0.03.
    const double est = godhand::percentile(big.values(), p);
    EXPECT_GE(est, godhand::percentile(exact, std::max(0.0, p - 0.03))) << p;
    EXPECT_LE(est, godhand::percentile(exact, std::min(1.0, p + 0.03))) << p;
  }
  // A drifting figure (a ramp): keeping the first or the last values would be far off; a
  // uniform sample's median is the middle of the run.
  godhand::Sample ramp(4096);
  for (int i = 0; i < 1000000; ++i) ramp.add(i * 1e-6);
  EXPECT_NEAR(godhand::percentile(ramp.values(), 0.5), 0.5, 0.03);
  EXPECT_NEAR(godhand::percentile(ramp.values(), 0.05), 0.05, 0.02);
  EXPECT_NEAR(godhand::percentile(ramp.values(), 0.95), 0.95, 0.02);
}
