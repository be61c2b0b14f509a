// Rigid poses, the rotation-vector log/exp maps and the 6D pose difference / update of
// METHOD.md §2.
//
// Frames are in the names: X_WB is the pose of body B in world W, p_WB its position, R_WB /
// q_WB its orientation. Quaternions are Eigen's (constructed w, x, y, z; Eigen stores x, y, z, w
// internally, so convert with w(), x(), y(), z() at every boundary, never with coeffs()).
//
// Generalized quantities are 6-vectors stacked (linear; angular), both in the world frame:
// acceleration z = (a, α), velocity y = (v, ω), pose difference (Δp; θ).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace godhand {

using Vec3 = Eigen::Vector3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Quat = Eigen::Quaterniond;

/// Pose of a frame: position p and unit quaternion q (X_WB = {p_WB, q_WB}).
struct Pose {
  Vec3 p = Vec3::Zero();
  Quat q = Quat::Identity();

  /// Maps a point given in this frame to the parent frame: p + R x.
  Vec3 operator*(const Vec3& x_B) const { return p + q * x_B; }
  /// Composition X_AC = X_AB * X_BC.
  Pose operator*(const Pose& X_BC) const { return {p + q * X_BC.p, (q * X_BC.q).normalized()}; }
  Pose inverse() const {
    const Quat qi = q.conjugate();
    return {-(qi * p), qi};
  }
};

/// Skew matrix [v]x with [v]x w = v × w.
inline Mat3 skew(const Vec3& v) {
  Mat3 S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

/// exp: rotation vector θ (axis · angle, rad) -> unit quaternion. Exact for all |θ|, with a
/// Taylor branch near 0 so that tiny rotations keep full precision.
Quat expRotation(const Vec3& theta);

/// log: unit quaternion -> rotation vector θ with |θ| ≤ π (shortest rotation; q and -q give the
/// same result). Robust near 0 and near π.
Vec3 logRotation(const Quat& q);

/// 6D difference X_target ⊖ X_god of METHOD.md §2 step 1: (p_target − p_god ;
/// log(R_target R_godᵀ)), world frame.
Vec6 poseDifference(const Pose& X_target, const Pose& X_god);

/// X ⊕ (y·h): p += v h, q = exp(ω h) q, the rotation applied in the world frame (METHOD §2 step 4).
Pose poseUpdate(const Pose& X, const Vec6& y, double h);

/// True when every coefficient is finite and |q| is within tol of 1.
bool isValidPose(const Pose& X, double unit_tolerance = 1e-6);

}  // namespace godhand
