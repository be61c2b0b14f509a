// Constraint rows (core/step/constraints.h, METHOD.md §2 step 2) against an independent
// finite-difference oracle.
//
// Convention: the generalized velocity of a body is (v; ω) in the world frame and a pose moves as
// p ← p + v h, q ← exp(ω h) q. A row with blocks J0 (body0) and J1 (body1) must equal
// d/dh C(X(h)) at h = 0 of its scalar constraint function C for each of the 6 unit directions of
// each of its bodies. C is evaluated here from the definitions in constraints.h (anchors, frame
// axes, a rotation-vector log written here, joint angles from godhand::jointAngles) — never by
// calling the code under test — and differentiated with central differences (h = 1e-6); the
// perturbation uses Eigen::AngleAxis, not godhand::expRotation.
//
// Rows are identified by their key (rowKey), never by their position, so the tests do not depend
// on the order in which addJointRows visits the joints.
//
// Measured figures are printed as "[figure] name = value" lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <iomanip>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/files.h"
#include "model/hand_model.h"
#include "solver/qp.h"
#include "step/constraints.h"

namespace godhand {
namespace {

using Poses = std::vector<Pose>;
using Angles = std::vector<std::array<double, 2>>;
using RowFunction = std::function<double(const Poses&)>;

constexpr double kPi = 3.14159265358979323846;
constexpr double kH = 1e-6;       // central-difference step
constexpr double kTight = 1e-7;   // relative agreement where the row is exact

void figure(const std::string& name, double value) {
  std::printf("[figure] %s = %.3e\n", name.c_str(), value);
  ::testing::Test::RecordProperty(name, std::to_string(value));
}

// ---------------------------------------------------------------------------------------------
// Keys.

std::uint64_t kindOf(std::uint64_t key) { return key >> 60; }
std::uint64_t idOf(std::uint64_t key) { return key & ((std::uint64_t{1} << 60) - 1); }
std::uint64_t jointKey(size_t ji, int row) {
  return (std::uint64_t{1} << 60) | (static_cast<std::uint64_t>(ji) << 8) | static_cast<std::uint64_t>(row);
}
std::uint64_t limitKey(size_t ji, int angle, int side) {
  return (std::uint64_t{2} << 60) | (static_cast<std::uint64_t>(ji) << 8) | static_cast<std::uint64_t>(2 * angle + side);
}

TEST(ConstraintKeys, RowKeyLayout) {
  // The oracle's own key layout must be the documented one.
  EXPECT_EQ(rowKey(RowKind::Joint, (3u << 8) | 4u), jointKey(3, 4));
  EXPECT_EQ(rowKey(RowKind::Limit, (2u << 8) | 3u), limitKey(2, 1, 1));
  EXPECT_EQ(kindOf(rowKey(RowKind::Contact, 77)), 3u);
  EXPECT_EQ(idOf(rowKey(RowKind::Contact, 77)), 77u);
}

// ---------------------------------------------------------------------------------------------
// Independent geometry.

Mat3 rot(const Pose& X) { return X.q.normalized().toRotationMatrix(); }

/// Rotation vector of R (|θ| ≤ π), written here from the quaternion half-angle form.
Vec3 rotationLog(const Mat3& R) {
  Quat q(R);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1.0;
  const double s = q.vec().norm();
  if (s < 1e-300) return 2.0 * q.vec();
  return q.vec() * (2.0 * std::atan2(s, q.w()) / s);
}

struct Frames {
  Mat3 R_P, R_C;  // joint frame axes (columns x, y, z) carried by parent / child, world
  Vec3 r_P, r_C;  // anchors, world
};

Frames framesOf(const Joint& j, const Poses& X) {
  const Pose& P = X[static_cast<size_t>(j.parent)];
  const Pose& C = X[static_cast<size_t>(j.child)];
  Frames f;
  f.R_P = rot(P) * rot(j.X_PJ);
  f.R_C = rot(C) * rot(j.X_CJ);
  f.r_P = P.p + rot(P) * j.X_PJ.p;
  f.r_C = C.p + rot(C) * j.X_CJ.p;
  return f;
}

/// Scalar constraint function of equality row `r` of joint j (constraints.h).
double jointRowFunction(const Joint& j, int r, const Poses& X) {
  const Frames f = framesOf(j, X);
  if (r < 3) return (f.r_C - f.r_P)[r];
  switch (j.type) {
    case JointType::Spherical2Dof:  // twist lock x_P · y_C
      return f.R_P.col(0).dot(f.R_C.col(1));
    case JointType::Revolute:  // y_P · x_C, then z_P · x_C
      return (r == 3 ? f.R_P.col(1) : f.R_P.col(2)).dot(f.R_C.col(0));
    case JointType::Fixed:  // e_a · log(R_WJc R_WJpᵀ)
      return rotationLog(f.R_C * f.R_P.transpose())[r - 3];
  }
  return 0.0;
}

/// θ − lower (side 0) or upper − θ (side 1) of angle `a`.
double limitRowFunction(const Joint& j, int a, int side, const Poses& X) {
  const auto th = jointAngles(j, X[static_cast<size_t>(j.parent)], X[static_cast<size_t>(j.child)]);
  const JointLimit& lim = j.limits[static_cast<size_t>(a)];
  return side == 0 ? th[static_cast<size_t>(a)] - lim.lower : lim.upper - th[static_cast<size_t>(a)];
}

/// |x_P · y_C|: the error that makes the angle rates (and the limit rows) inexact.
double angleLockError(const Joint& j, const Poses& X) {
  const Frames f = framesOf(j, X);
  return std::abs(f.R_P.col(0).dot(f.R_C.col(1)));
}

Pose perturbed(const Pose& X, int k, double h) {
  Pose Y = X;
  if (k < 3) {
    Y.p[k] += h;
  } else {
    Y.q = (Quat(Eigen::AngleAxisd(h, Vec3::Unit(k - 3))) * X.q).normalized();
  }
  return Y;
}

/// Largest |J_k − dC/dh| / max(1, ‖J‖∞) over the 6 directions of each body of the row.
double fdDiscrepancy(const Row& row, const RowFunction& C, const Poses& X) {
  double scale = std::max(1.0, row.J0.cwiseAbs().maxCoeff());
  if (row.body1 >= 0) scale = std::max(scale, row.J1.cwiseAbs().maxCoeff());
  double worst = 0.0;
  for (int s = 0; s < 2; ++s) {
    const int b = s == 0 ? row.body0 : row.body1;
    if (b < 0) continue;
    const Vec6& J = s == 0 ? row.J0 : row.J1;
    for (int k = 0; k < 6; ++k) {
      Poses Xp = X, Xm = X;
      Xp[static_cast<size_t>(b)] = perturbed(X[static_cast<size_t>(b)], k, kH);
      Xm[static_cast<size_t>(b)] = perturbed(X[static_cast<size_t>(b)], k, -kH);
      const double fd = (C(Xp) - C(Xm)) / (2.0 * kH);
      worst = std::max(worst, std::abs(fd - J[k]) / scale);
    }
  }
  return worst;
}

// ---------------------------------------------------------------------------------------------
// Models and configurations.

const HandModel& hand16() {
  static const HandModel m = loadHandModel(GODHAND_MODELS_DIR "/hand16_right.pbtxt");
  return m;
}

Mat3 axisAngle(double angle, Vec3 axis) { return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix(); }

std::string vecText(const char* field, const Vec3& v) {
  std::ostringstream os;
  os << std::setprecision(17) << field << " { x: " << v.x() << " y: " << v.y() << " z: " << v.z() << " }";
  return os.str();
}

/// A small chain with generic (non-axis-aligned) joint frames:
///   base --FIXED--> link --REVOLUTE--> arm --SPHERICAL_2DOF--> tip
/// Limits: revolute angle 1 [-0.5, 0.8]; spherical angle 1 [-0.6, 0.9], angle 2 [-0.4, 0.3].
/// Rest poses are built so that every joint sits at zero angles.
const HandModel& smallModel() {
  static const HandModel m = [] {
    struct B { const char* name; const char* shape; };
    const B bodies[4] = {{"base", "box { half_extents { x: 0.03 y: 0.02 z: 0.01 } }"},
                         {"link", "sphere { radius: 0.012 }"},
                         {"arm", "capsule { radius: 0.01 half_length: 0.02 }"},
                         {"tip", "capsule { radius: 0.008 half_length: 0.012 }"}};
    struct J {
      const char* name; const char* type; int parent, child;
      Vec3 a_P, a_C; Mat3 R_PJ, R_CJ; const char* limits;
    };
    const J joints[3] = {
        {"fix", "FIXED", 0, 1, {0.021, -0.013, 0.008}, {-0.004, 0.006, -0.009},
         axisAngle(0.7, {1, 2, 3}), axisAngle(-1.1, {-2, 0.5, 1}), ""},
        {"hinge", "REVOLUTE", 1, 2, {0.007, 0.011, -0.005}, {0.002, -0.003, -0.019},
         axisAngle(1.3, {0.3, -1, 0.6}), axisAngle(0.4, {2, 1, -1}), "limits { angle: 1 lower: -0.5 upper: 0.8 }"},
        {"knuckle", "SPHERICAL_2DOF", 2, 3, {-0.001, 0.004, 0.019}, {0.003, 0.002, -0.011},
         axisAngle(-0.9, {1, -1, 0.2}), axisAngle(2.0, {0.1, 0.7, 0.7}),
         "limits { angle: 1 lower: -0.6 upper: 0.9 } limits { angle: 2 lower: -0.4 upper: 0.3 }"}};
    Pose rest[4];
    rest[0] = {Vec3(0.01, -0.02, 0.03), Quat(Eigen::AngleAxisd(0.5, Vec3(0.2, 0.9, -0.4).normalized()))};
    for (const J& j : joints) {
      const Pose X_PJ{j.a_P, Quat(j.R_PJ)}, X_CJ{j.a_C, Quat(j.R_CJ)};
      rest[j.child] = rest[j.parent] * X_PJ * X_CJ.inverse();
    }
    std::ostringstream os;
    os << std::setprecision(17) << "name: \"small\"\n";
    for (int i = 0; i < 4; ++i) {
      const Quat& q = rest[i].q;
      os << "bodies {\n  name: \"" << bodies[i].name << "\"\n  " << bodies[i].shape << "\n  mass: 0.05\n  "
         << vecText("rest_position", rest[i].p) << "\n  rest_orientation { w: " << q.w() << " x: " << q.x()
         << " y: " << q.y() << " z: " << q.z() << " }\n}\n";
    }
    for (const J& j : joints) {
      os << "joints {\n  name: \"" << j.name << "\" type: " << j.type << " parent: \"" << bodies[j.parent].name
         << "\" child: \"" << bodies[j.child].name << "\"\n  " << vecText("anchor_parent", j.a_P) << "\n  "
         << vecText("anchor_child", j.a_C) << "\n  " << vecText("axis_parent", j.R_PJ.col(0)) << "\n  "
         << vecText("axis_child", j.R_CJ.col(0)) << "\n  " << vecText("reference_parent", j.R_PJ.col(2)) << "\n  "
         << vecText("reference_child", j.R_CJ.col(2)) << "\n  " << j.limits << "\n}\n";
    }
    return HandModel::fromText(os.str(), "small.pbtxt");
  }();
  return m;
}

size_t jointOfType(const HandModel& m, JointType t) {
  for (size_t i = 0; i < m.joints.size(); ++i)
    if (m.joints[i].type == t) return i;
  ADD_FAILURE() << "no joint of the requested type";
  return 0;
}

Mat3 jointRotation(const Joint& j, const std::array<double, 2>& a) {
  switch (j.type) {
    case JointType::Spherical2Dof: return axisAngle(a[0], Vec3::UnitX()) * axisAngle(a[1], Vec3::UnitY());
    case JointType::Revolute: return axisAngle(a[0], Vec3::UnitX());
    case JointType::Fixed: break;
  }
  return Mat3::Identity();
}

/// World poses satisfying every joint exactly, at the given joint angles, with the model frame
/// (roots at their rest pose in it) at X_WM.
Poses consistentPoses(const HandModel& m, const Pose& X_WM, const Angles& angles) {
  const size_t n = m.bodies.size();
  Poses X(n);
  std::vector<bool> placed(n, true);
  for (const Joint& j : m.joints) placed[static_cast<size_t>(j.child)] = false;
  for (size_t b = 0; b < n; ++b)
    if (placed[b]) X[b] = X_WM * m.bodies[b].X_MB_rest;
  for (bool progress = true; progress;) {
    progress = false;
    for (size_t ji = 0; ji < m.joints.size(); ++ji) {
      const Joint& j = m.joints[ji];
      const auto p = static_cast<size_t>(j.parent), c = static_cast<size_t>(j.child);
      if (!placed[p] || placed[c]) continue;
      X[c] = X[p] * j.X_PJ * Pose{Vec3::Zero(), Quat(jointRotation(j, angles[ji]))} * j.X_CJ.inverse();
      placed[c] = true;
      progress = true;
    }
  }
  return X;
}

/// Angles within [lower − overshoot, upper + overshoot] of each enabled limit, ±0.8 rad otherwise.
Angles randomAngles(const HandModel& m, std::mt19937& rng, double overshoot) {
  Angles out(m.joints.size(), {0.0, 0.0});
  for (size_t ji = 0; ji < m.joints.size(); ++ji) {
    const Joint& j = m.joints[ji];
    for (int a = 0; a < j.angleCount(); ++a) {
      const JointLimit& lim = j.limits[static_cast<size_t>(a)];
      std::uniform_real_distribution<double> u(lim.enabled ? lim.lower - overshoot : -0.8,
                                               lim.enabled ? lim.upper + overshoot : 0.8);
      out[ji][static_cast<size_t>(a)] = u(rng);
    }
  }
  return out;
}

// Draws are sequenced left to right (separate statements or braced lists, whose elements are
// evaluated in order): C++ leaves the order of function arguments unspecified, so
// f(draw(), draw()) gives gcc and clang different instances from one seed.
Vec3 randomVec(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return {g(rng), g(rng), g(rng)};
}

Quat randomRotation(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, kPi);
  const double angle = u(rng);
  return Quat(Eigen::AngleAxisd(angle, randomVec(rng).normalized()));
}

Pose randomPose(std::mt19937& rng) { return {0.1 * randomVec(rng), randomRotation(rng)}; }

/// Consistent poses at a random base pose (drawn first) and random angles.
Poses randomConsistentPoses(const HandModel& m, std::mt19937& rng, double overshoot) {
  const Pose X_WM = randomPose(rng);
  return consistentPoses(m, X_WM, randomAngles(m, rng, overshoot));
}

/// Moves every body by a random small displacement (σ_p, m) and rotation (σ_r, rad).
void jitter(Poses& X, std::mt19937& rng, double sigma_p, double sigma_r) {
  for (Pose& P : X) {
    P.p += sigma_p * randomVec(rng);
    const Vec3 w = sigma_r * randomVec(rng);
    P.q = (Quat(Eigen::AngleAxisd(w.norm(), w.normalized())) * P.q).normalized();
  }
}

void prepare(QpProblem& qp, const HandModel& m) {
  qp.reset(static_cast<int>(m.bodies.size()));
  for (int b = 0; b < static_cast<int>(m.bodies.size()); ++b)
    qp.setRigidMass(b, m.bodies[static_cast<size_t>(b)].mass, Mat3::Identity(), m.bodies[static_cast<size_t>(b)].inertia);
}

/// key → row index over rows [first, numRows); fails on a duplicate key.
std::map<std::uint64_t, int> rowsByKey(const QpProblem& qp, int first = 0) {
  std::map<std::uint64_t, int> out;
  for (int k = first; k < qp.numRows(); ++k)
    EXPECT_TRUE(out.emplace(qp.row(k).key, k).second) << "duplicate key " << std::hex << qp.row(k).key;
  return out;
}

bool sameBodies(const Row& r, const Joint& j) {
  return (r.body0 == j.child && r.body1 == j.parent) || (r.body0 == j.parent && r.body1 == j.child);
}

/// Block of `row` acting on `body` (zero when the row does not touch it).
Vec6 blockOf(const Row& r, int body) {
  if (r.body0 == body) return r.J0;
  if (r.body1 == body) return r.J1;
  return Vec6::Zero();
}

// ---------------------------------------------------------------------------------------------
// Joint rows.

TEST(ConstraintModel, SmallModelHasGenericFramesAndConsistentGenerator) {
  const HandModel& m = smallModel();
  ASSERT_EQ(m.joints.size(), 3u);
  EXPECT_EQ(m.joints[0].type, JointType::Fixed);
  EXPECT_EQ(m.joints[1].type, JointType::Revolute);
  EXPECT_EQ(m.joints[2].type, JointType::Spherical2Dof);
  for (const Joint& j : m.joints) {  // no joint axis along a body axis
    EXPECT_LT(rot(j.X_PJ).cwiseAbs().maxCoeff(), 0.99);
    EXPECT_LT(rot(j.X_CJ).cwiseAbs().maxCoeff(), 0.99);
  }
  // The generator's configurations have the requested angles and satisfy every joint.
  std::mt19937 rng(7);
  for (const HandModel* model : {&m, &hand16()}) {
    for (int t = 0; t < 5; ++t) {
      const Angles a = randomAngles(*model, rng, 0.1);
      const Poses X = consistentPoses(*model, randomPose(rng), a);
      for (size_t ji = 0; ji < model->joints.size(); ++ji) {
        const Joint& j = model->joints[ji];
        const auto th = jointAngles(j, X[static_cast<size_t>(j.parent)], X[static_cast<size_t>(j.child)]);
        for (int k = 0; k < j.angleCount(); ++k)
          EXPECT_NEAR(th[static_cast<size_t>(k)], a[ji][static_cast<size_t>(k)], 1e-12) << j.name;
        for (int r = 0; r < j.equalityRows(); ++r) EXPECT_NEAR(jointRowFunction(j, r, X), 0.0, 1e-12) << j.name;
      }
    }
  }
}

TEST(ConstraintJointRows, KeysBodiesAndTypes) {
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    const Poses X = m->restPoses(Pose{});
    QpProblem qp;
    prepare(qp, *m);
    // Rows are appended: an earlier row is kept.
    qp.addRow(RowType::Inequality, 0, Vec6::Ones(), -1, Vec6::Zero(), 1.0, 12345);
    addJointRows(qp, *m, X.data(), RowParams{});
    ASSERT_EQ(qp.numRows(), 1 + m->equalityRows()) << m->name;
    EXPECT_EQ(qp.row(0).key, 12345u);
    const auto by_key = rowsByKey(qp, 1);
    for (size_t ji = 0; ji < m->joints.size(); ++ji) {
      const Joint& j = m->joints[ji];
      for (int r = 0; r < j.equalityRows(); ++r) {
        const auto it = by_key.find(jointKey(ji, r));
        ASSERT_NE(it, by_key.end()) << m->name << " joint " << j.name << " row " << r;
        const Row& row = qp.row(it->second);
        EXPECT_EQ(row.type, RowType::Equality);
        EXPECT_TRUE(sameBodies(row, j)) << j.name << " row " << r << ": bodies " << row.body0 << ", " << row.body1;
        if (r >= 3) {  // lock / axis / orientation rows have no linear part
          EXPECT_EQ(row.J0.head<3>().norm(), 0.0);
          EXPECT_EQ(row.J1.head<3>().norm(), 0.0);
        }
      }
    }
  }
}

/// Checks every joint row of `m` at X against the oracle. Returns the largest relative
/// discrepancy per row kind; rows that are exact only at zero error get a tolerance bound.
struct JointFd {
  double point = 0, spherical_lock = 0, revolute_axis = 0, fixed_orientation = 0;
  double fixed_ratio = 0;  // discrepancy / |orientation error| of fixed rows
};

void checkJointRows(const HandModel& m, const Poses& X, bool exact_config, JointFd& out) {
  QpProblem qp;
  prepare(qp, m);
  addJointRows(qp, m, X.data(), RowParams{});
  ASSERT_EQ(qp.numRows(), m.equalityRows());
  const auto by_key = rowsByKey(qp);
  for (size_t ji = 0; ji < m.joints.size(); ++ji) {
    const Joint& j = m.joints[ji];
    for (int r = 0; r < j.equalityRows(); ++r) {
      const auto it = by_key.find(jointKey(ji, r));
      ASSERT_NE(it, by_key.end());
      const Row& row = qp.row(it->second);
      ASSERT_TRUE(sameBodies(row, j));
      const double d = fdDiscrepancy(row, [&](const Poses& Y) { return jointRowFunction(j, r, Y); }, X);
      if (r < 3) {
        out.point = std::max(out.point, d);
        EXPECT_LT(d, kTight) << m.name << " " << j.name << " point row " << r;
      } else if (j.type == JointType::Spherical2Dof) {
        out.spherical_lock = std::max(out.spherical_lock, d);
        EXPECT_LT(d, kTight) << m.name << " " << j.name << " twist-lock row";
      } else if (j.type == JointType::Revolute) {
        out.revolute_axis = std::max(out.revolute_axis, d);
        EXPECT_LT(d, kTight) << m.name << " " << j.name << " axis row " << r;
      } else {
        const Frames f = framesOf(j, X);
        const double err = rotationLog(f.R_C * f.R_P.transpose()).norm();
        out.fixed_orientation = std::max(out.fixed_orientation, d);
        if (exact_config) {
          EXPECT_LT(d, kTight) << m.name << " " << j.name << " orientation row " << r;
        } else {
          // d/dh log(exp(ωh) E) = J_l⁻¹(φ) ω = ω − ½ φ × ω + O(φ²): off by at most ~|φ|/2.
          out.fixed_ratio = std::max(out.fixed_ratio, d / err);
          EXPECT_LT(d, 0.6 * err + kTight) << m.name << " " << j.name << " orientation row " << r << " |φ| " << err;
        }
      }
    }
  }
}

void reportJointFd(const std::string& tag, const JointFd& fd) {
  figure(tag + ".point", fd.point);
  figure(tag + ".spherical_lock", fd.spherical_lock);
  figure(tag + ".revolute_axis", fd.revolute_axis);
  if (fd.fixed_orientation > 0) figure(tag + ".fixed_orientation", fd.fixed_orientation);
  if (fd.fixed_ratio > 0) figure(tag + ".fixed_orientation_over_error", fd.fixed_ratio);
}

TEST(ConstraintJointRows, JacobianMatchesFiniteDifferencesAtConsistentConfigurations) {
  std::mt19937 rng(11);
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    JointFd fd;
    for (int t = 0; t < 6; ++t) {
      const Poses X = randomConsistentPoses(*m, rng, 0.1);
      checkJointRows(*m, X, true, fd);
    }
    reportJointFd("fd_rel.exact." + m->name, fd);
  }
}

TEST(ConstraintJointRows, JacobianMatchesFiniteDifferencesNearConsistentConfigurations) {
  // Point and lock rows are exact derivatives everywhere; fixed orientation rows only at zero
  // error (checked against the |φ|/2 bound here).
  std::mt19937 rng(12);
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    JointFd fd;
    for (int t = 0; t < 6; ++t) {
      Poses X = randomConsistentPoses(*m, rng, 0.1);
      jitter(X, rng, t < 3 ? 1e-3 : 5e-3, t < 3 ? 1e-2 : 5e-2);
      checkJointRows(*m, X, false, fd);
    }
    reportJointFd("fd_rel.near." + m->name, fd);
  }
}

TEST(ConstraintJointRows, PointAndLockRowsExactAtArbitraryPoses) {
  // Far from any consistent configuration (every body at a random pose) the point and lock rows
  // are still the exact derivatives of their functions.
  std::mt19937 rng(13);
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    QpProblem qp;
    double worst = 0;
    for (int t = 0; t < 4; ++t) {
      Poses X(m->bodies.size());
      for (Pose& P : X) P = randomPose(rng);
      prepare(qp, *m);
      addJointRows(qp, *m, X.data(), RowParams{});
      const auto by_key = rowsByKey(qp);
      for (size_t ji = 0; ji < m->joints.size(); ++ji) {
        const Joint& j = m->joints[ji];
        const int rows = j.type == JointType::Fixed ? 3 : j.equalityRows();
        for (int r = 0; r < rows; ++r) {
          const Row& row = qp.row(by_key.at(jointKey(ji, r)));
          const double d = fdDiscrepancy(row, [&](const Poses& Y) { return jointRowFunction(j, r, Y); }, X);
          worst = std::max(worst, d);
          EXPECT_LT(d, kTight) << m->name << " " << j.name << " row " << r;
        }
      }
    }
    figure("fd_rel.arbitrary." + m->name + ".point_and_lock", worst);
  }
}

TEST(ConstraintJointRows, RightHandSideIsMinusBetaErrorOverDt2) {
  std::mt19937 rng(14);
  const RowParams params[] = {{1e-3, 0.5, 0.5, 1e-4, 0.15}, {2e-3, 0.2, 0.5, 1e-4, 0.15}, {5e-4, 1.0, 0.3, 1e-4, 0.15}};
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    for (const RowParams& prm : params) {
      Poses X = randomConsistentPoses(*m, rng, 0.0);
      jitter(X, rng, 1e-3, 2e-2);  // known small error in every row
      QpProblem qp;
      prepare(qp, *m);
      addJointRows(qp, *m, X.data(), prm);
      const auto by_key = rowsByKey(qp);
      const double k = prm.beta / (prm.dt * prm.dt);
      for (size_t ji = 0; ji < m->joints.size(); ++ji) {
        const Joint& j = m->joints[ji];
        for (int r = 0; r < j.equalityRows(); ++r) {
          const Row& row = qp.row(by_key.at(jointKey(ji, r)));
          const double C = jointRowFunction(j, r, X);
          EXPECT_GT(std::abs(C), 1e-9) << "the configuration should carry an error";
          const double expected = -k * C;
          EXPECT_NEAR(row.c, expected, 1e-9 * std::abs(expected) + 1e-9) << m->name << " " << j.name << " row " << r;
        }
      }
    }
  }
  // At an exactly consistent configuration every right-hand side vanishes.
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    const Poses X = randomConsistentPoses(*m, rng, 0.0);
    QpProblem qp;
    prepare(qp, *m);
    addJointRows(qp, *m, X.data(), RowParams{});
    for (int k = 0; k < qp.numRows(); ++k) EXPECT_NEAR(qp.row(k).c, 0.0, 1e-5) << m->name << " row " << k;
  }
}

// ---------------------------------------------------------------------------------------------
// Limit rows.

int enabledLimits(const HandModel& m) {
  int n = 0;
  for (const Joint& j : m.joints)
    for (const JointLimit& l : j.limits) n += l.enabled ? 1 : 0;
  return n;
}

double gapRule(double g, double margin, double beta, double dt) {
  return g > margin ? -(g - margin) / (dt * dt) : beta * (margin - g) / (dt * dt);
}

TEST(ConstraintLimitRows, JacobianAndRightHandSideMatchOracle) {
  std::mt19937 rng(21);
  RowParams prm;
  prm.limit_activation = 100.0;  // every limit row, both sides
  prm.contact_beta = 0.3;
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    double worst_exact = 0, worst_near_ratio = 0, worst_rhs = 0;
    for (int t = 0; t < 10; ++t) {
      const bool exact = t < 6;
      Poses X = randomConsistentPoses(*m, rng, 0.15);
      if (!exact) jitter(X, rng, 1e-3, 1e-2);
      QpProblem qp;
      prepare(qp, *m);
      const int added = addLimitRows(qp, *m, X.data(), nullptr, prm);
      EXPECT_EQ(added, 2 * enabledLimits(*m));
      ASSERT_EQ(qp.numRows(), added);
      const auto by_key = rowsByKey(qp);
      for (size_t ji = 0; ji < m->joints.size(); ++ji) {
        const Joint& j = m->joints[ji];
        for (int a = 0; a < 2; ++a) {
          for (int side = 0; side < 2; ++side) {
            const auto it = by_key.find(limitKey(ji, a, side));
            if (!j.limits[static_cast<size_t>(a)].enabled) {
              EXPECT_EQ(it, by_key.end());
              continue;
            }
            ASSERT_NE(it, by_key.end()) << j.name << " angle " << a + 1 << " side " << side;
            const Row& row = qp.row(it->second);
            EXPECT_EQ(row.type, RowType::Inequality);
            ASSERT_TRUE(sameBodies(row, j));
            const double d =
                fdDiscrepancy(row, [&](const Poses& Y) { return limitRowFunction(j, a, side, Y); }, X);
            if (exact) {
              worst_exact = std::max(worst_exact, d);
              EXPECT_LT(d, kTight) << m->name << " " << j.name << " angle " << a + 1 << " side " << side;
            } else {
              // θ̇ = a·(ω_C − ω_P) holds exactly only when x_P ⟂ y_C; off by about |x_P·y_C|.
              const double lock = angleLockError(j, X);
              worst_near_ratio = std::max(worst_near_ratio, d / lock);
              EXPECT_LT(d, 1.5 * lock + kTight) << m->name << " " << j.name << " angle " << a + 1;
            }
            const double g = limitRowFunction(j, a, side, X);
            const double expected = gapRule(g, 0.0, prm.contact_beta, prm.dt);
            worst_rhs = std::max(worst_rhs, std::abs(row.c - expected) / std::max(1.0, std::abs(expected)));
            EXPECT_NEAR(row.c, expected, 1e-9 * std::abs(expected) + 1e-6) << j.name << " g " << g;
          }
        }
      }
    }
    figure("fd_rel.exact." + m->name + ".limit", worst_exact);
    figure("fd_rel.near." + m->name + ".limit_over_lock_error", worst_near_ratio);
    figure("rhs_rel." + m->name + ".limit", worst_rhs);
  }
}

struct LimitCase {
  const char* what;
  std::array<double, 2> angles;  // of the joint under test
  double rate_child;             // predicted Δθ over the step carried by the child's z_u
  double rate_parent;            // ... and by the parent's (Δθ = a·(z_C − z_P) Δt²)
  bool use_zu;
  bool lower, upper;             // expected rows of the tested angle
};

/// True when body b is `root` or one of its descendants.
bool inSubtree(const HandModel& m, int b, int root) {
  for (int guard = 0; guard <= static_cast<int>(m.bodies.size()); ++guard) {
    if (b == root) return true;
    int parent = -1;
    for (const Joint& j : m.joints)
      if (j.child == b) parent = j.parent;
    if (parent < 0) return false;
    b = parent;
  }
  return false;
}

/// Runs activation cases on angle `a` of joint `ji` of the small model. Every other joint sits
/// at zero angles, ≥ 0.3 rad from its limits, so only the tested angle may add rows.
void runLimitCases(size_t ji, int a, const std::vector<LimitCase>& cases) {
  const HandModel& m = smallModel();
  const Joint& j = m.joints[ji];
  RowParams prm;  // limit_activation 0.15
  std::mt19937 rng(31);
  for (const LimitCase& lc : cases) {
    Angles angles(m.joints.size(), {0.0, 0.0});
    angles[ji] = lc.angles;
    const Poses X = consistentPoses(m, randomPose(rng), angles);
    const Frames f = framesOf(j, X);
    const Vec3 axis = a == 0 ? Vec3(f.R_P.col(0)) : Vec3(f.R_C.col(1));
    // The child's subtree turns by rate_child about the axis, the rest of the model by
    // −rate_parent, so no other joint moves; all bodies share a common rotation (which changes
    // no angle) and arbitrary linear parts (which never matter).
    const double dt2 = prm.dt * prm.dt;
    const Vec3 common = randomVec(rng).normalized() * (0.3 / dt2);
    std::vector<Vec6> zu(m.bodies.size(), Vec6::Zero());
    for (size_t b = 0; b < m.bodies.size(); ++b) {
      zu[b].head<3>() = 1e6 * randomVec(rng);
      const double turn = inSubtree(m, static_cast<int>(b), j.child) ? lc.rate_child : -lc.rate_parent;
      zu[b].tail<3>() = common + axis * (turn / dt2);
    }

    QpProblem qp;
    prepare(qp, m);
    qp.addRow(RowType::Equality, 0, Vec6::Ones(), -1, Vec6::Zero(), 0.0, 999);  // kept, not counted
    const int added = addLimitRows(qp, m, X.data(), lc.use_zu ? zu.data() : nullptr, prm);
    const int expected = (lc.lower ? 1 : 0) + (lc.upper ? 1 : 0);
    EXPECT_EQ(added, expected) << j.name << " angle " << a + 1 << ": " << lc.what;
    ASSERT_EQ(qp.numRows(), 1 + added);
    const auto by_key = rowsByKey(qp, 1);
    for (int side = 0; side < 2; ++side) {
      const bool want = side == 0 ? lc.lower : lc.upper;
      const auto it = by_key.find(limitKey(ji, a, side));
      EXPECT_EQ(it != by_key.end(), want) << j.name << " angle " << a + 1 << " side " << side << ": " << lc.what;
      if (it == by_key.end()) continue;
      const Row& row = qp.row(it->second);
      EXPECT_EQ(row.type, RowType::Inequality);
      // Signs: the lower row pushes θ up (+a on the child), the upper row pushes it down.
      const double sgn = side == 0 ? 1.0 : -1.0;
      EXPECT_LT((blockOf(row, j.child) - (Vec6() << Vec3::Zero(), sgn * axis).finished()).norm(), 1e-12) << lc.what;
      EXPECT_LT((blockOf(row, j.parent) - (Vec6() << Vec3::Zero(), -sgn * axis).finished()).norm(), 1e-12) << lc.what;
      const double g = limitRowFunction(j, a, side, X);
      EXPECT_NEAR(row.c, gapRule(g, 0.0, prm.contact_beta, prm.dt), 1e-6) << lc.what;
      // The oracle, too: the row is the derivative of its gap.
      EXPECT_LT(fdDiscrepancy(row, [&](const Poses& Y) { return limitRowFunction(j, a, side, Y); }, X), kTight);
    }
  }
}

TEST(ConstraintLimitRows, ActivationRevolute) {
  // Revolute limits [-0.5, 0.8], activation 0.15.
  const size_t ji = jointOfType(smallModel(), JointType::Revolute);
  runLimitCases(ji, 0,
                {{"middle, at rest", {0.1, 0}, 0, 0, true, false, false},
                 {"middle, no z_u", {0.1, 0}, 0.65, 0, false, false, false},
                 {"0.10 above lower", {-0.40, 0}, 0, 0, true, true, false},
                 {"0.16 above lower", {-0.34, 0}, 0, 0, true, false, false},
                 {"0.14 above lower", {-0.36, 0}, 0, 0, true, true, false},
                 {"0.10 above lower, moving away", {-0.40, 0}, 0.5, 0, true, true, false},
                 {"0.10 below upper", {0.70, 0}, 0, 0, true, false, true},
                 {"0.16 below upper", {0.64, 0}, 0, 0, true, false, false},
                 {"upper violated", {0.85, 0}, 0, 0, true, false, true},
                 {"lower violated", {-0.55, 0}, 0, 0, true, true, false},
                 {"middle, child moving to upper", {0.1, 0}, 0.6, 0, true, false, true},
                 {"middle, parent moving to upper", {0.1, 0}, 0, 0.6, true, false, true},
                 {"middle, moving to upper, not enough", {0.1, 0}, 0.5, 0, true, false, false},
                 {"middle, moving to lower", {0.1, 0}, -0.3, -0.2, true, true, false},
                 {"middle, moving far past lower", {0.1, 0}, -2.0, 0, true, true, false}});
}

TEST(ConstraintLimitRows, ActivationSpherical) {
  // Spherical limits: angle 1 [-0.6, 0.9], angle 2 [-0.4, 0.3], activation 0.15.
  const size_t ji = jointOfType(smallModel(), JointType::Spherical2Dof);
  runLimitCases(ji, 0,  // angle 2 kept at 0 (0.3 from its limits)
                {{"middle", {0.1, 0}, 0, 0, true, false, false},
                 {"near lower", {-0.5, 0}, 0, 0, true, true, false},
                 {"near upper", {0.8, 0}, 0, 0, true, false, true},
                 {"moving to upper", {0.1, 0}, 0.4, 0.3, true, false, true},
                 {"moving to lower", {0.1, 0}, 0, -0.65, true, true, false},
                 {"moving to upper, no z_u", {0.1, 0}, 0.4, 0.3, false, false, false}});
  runLimitCases(ji, 1,  // angle 1 kept at 0 (0.6 from its limits)
                {{"middle", {0, -0.05}, 0, 0, true, false, false},
                 {"near lower", {0, -0.3}, 0, 0, true, true, false},
                 {"near upper", {0, 0.2}, 0, 0, true, false, true},
                 {"upper violated", {0, 0.35}, 0, 0, true, false, true},
                 {"moving to upper", {0, -0.05}, 0.25, 0, true, false, true},
                 {"moving to lower", {0, -0.05}, 0, -0.25, true, true, false}});
}

TEST(ConstraintLimitRows, Hand16CountsFollowDistanceToLimits) {
  // With z_u = 0, the number of rows is the number of (angle, side) pairs within the activation.
  const HandModel& m = hand16();
  std::mt19937 rng(41);
  for (int t = 0; t < 20; ++t) {
    const Angles a = randomAngles(m, rng, 0.1);
    const Poses X = consistentPoses(m, randomPose(rng), a);
    RowParams prm;
    int expected = 0;
    for (size_t ji = 0; ji < m.joints.size(); ++ji)
      for (size_t k = 0; k < 2; ++k) {
        const JointLimit& lim = m.joints[ji].limits[k];
        if (!lim.enabled) continue;
        expected += (a[ji][k] - lim.lower < prm.limit_activation) + (lim.upper - a[ji][k] < prm.limit_activation);
      }
    QpProblem qp;
    prepare(qp, m);
    const std::vector<Vec6> zu(m.bodies.size(), Vec6::Zero());
    EXPECT_EQ(addLimitRows(qp, m, X.data(), zu.data(), prm), expected);
    EXPECT_EQ(qp.numRows(), expected);
  }
}

// ---------------------------------------------------------------------------------------------
// Contact rows.

TEST(ConstraintContactRows, JacobianAndRightHandSideMatchOracle) {
  std::mt19937 rng(51);
  RowParams prm;
  prm.dt = 2e-3;
  prm.margin = 2e-4;
  prm.contact_beta = 0.4;
  const double distances[] = {0.01, 3e-4, 2e-4, 1.5e-4, 0.0, -1e-3};
  double worst = 0;
  for (int t = 0; t < 12; ++t) {
    const Pose X_WB = randomPose(rng);
    Contact c;
    c.body = t % 3;
    c.p_W = X_WB.p + 0.03 * randomVec(rng);
    c.n_W = randomVec(rng).normalized();
    c.distance = distances[t % 6];
    c.key = t < 6 ? 0 : 1000 + static_cast<std::uint64_t>(t);
    c.object = 4;
    QpProblem qp;
    qp.reset(3);
    for (int b = 0; b < 3; ++b) qp.setRigidMass(b, 0.1, Mat3::Identity(), Vec3::Constant(1e-5));
    addContactRow(qp, c, X_WB, prm);
    ASSERT_EQ(qp.numRows(), 1);
    const Row& row = qp.row(0);
    EXPECT_EQ(row.type, RowType::Inequality);
    EXPECT_EQ(row.body0, c.body);
    EXPECT_LT(row.body1, 0);
    EXPECT_EQ(row.key, c.key ? rowKey(RowKind::Contact, c.key) : 0u);
    // C = n·(p_contact(X) − p_contact(X_0)) + d for the point rigidly attached to the body.
    const Vec3 p_B = rot(X_WB).transpose() * (c.p_W - X_WB.p);
    Poses X(3, randomPose(rng));
    X[static_cast<size_t>(c.body)] = X_WB;
    const RowFunction C = [&](const Poses& Y) {
      const Pose& P = Y[static_cast<size_t>(c.body)];
      return c.n_W.dot(P.p + rot(P) * p_B - c.p_W) + c.distance;
    };
    EXPECT_NEAR(C(X), c.distance, 1e-15);
    const double d = fdDiscrepancy(row, C, X);
    worst = std::max(worst, d);
    EXPECT_LT(d, kTight) << "contact " << t;
    const double expected = gapRule(c.distance, prm.margin, prm.contact_beta, prm.dt);
    EXPECT_NEAR(row.c, expected, 1e-9 * std::abs(expected) + 1e-9) << "d = " << c.distance;
    // Sign sanity: separated beyond the margin may close (c < 0); inside it is pushed out (c ≥ 0).
    if (c.distance > prm.margin) EXPECT_LT(row.c, 0.0);
    else EXPECT_GE(row.c, 0.0);
  }
  figure("fd_rel.contact", worst);
}

// ---------------------------------------------------------------------------------------------
// jointErrors().

TEST(ConstraintJointErrors, MatchIndependentRecomputation) {
  std::mt19937 rng(61);
  for (const HandModel* m : {&smallModel(), &hand16()}) {
    for (int t = 0; t < 8; ++t) {
      Poses X = randomConsistentPoses(*m, rng, 0.2);
      if (t > 0) jitter(X, rng, t * 5e-4, t * 5e-3);
      JointErrors want;
      for (const Joint& j : m->joints) {
        const Frames f = framesOf(j, X);
        want.gap = std::max(want.gap, (f.r_C - f.r_P).norm());
        double lock = 0;
        switch (j.type) {
          case JointType::Spherical2Dof: lock = std::abs(f.R_P.col(0).dot(f.R_C.col(1))); break;
          case JointType::Revolute:
            lock = std::max(std::abs(f.R_P.col(1).dot(f.R_C.col(0))), std::abs(f.R_P.col(2).dot(f.R_C.col(0))));
            break;
          case JointType::Fixed: lock = rotationLog(f.R_C * f.R_P.transpose()).norm(); break;
        }
        want.lock = std::max(want.lock, lock);
        for (int a = 0; a < 2; ++a) {
          if (!j.limits[static_cast<size_t>(a)].enabled) continue;
          want.limit = std::max({want.limit, -limitRowFunction(j, a, 0, X), -limitRowFunction(j, a, 1, X)});
        }
      }
      const JointErrors got = jointErrors(*m, X.data());
      EXPECT_NEAR(got.gap, want.gap, 1e-14) << m->name << " t " << t;
      EXPECT_NEAR(got.lock, want.lock, 1e-12) << m->name << " t " << t;
      EXPECT_NEAR(got.limit, want.limit, 1e-12) << m->name << " t " << t;
      EXPECT_GE(got.limit, 0.0);
      if (t == 0) {
        EXPECT_LT(got.gap, 1e-12);
        EXPECT_LT(got.lock, 1e-12);
      } else {
        EXPECT_GT(got.gap, 0.0);
        EXPECT_GT(got.lock, 0.0);
      }
    }
  }
}

}  // namespace
}  // namespace godhand
