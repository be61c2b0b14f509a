#include "math/pose.h"

#include <cmath>

namespace godhand {

Quat expRotation(const Vec3& theta) {
  const double angle = theta.norm();
  const double half = 0.5 * angle;
  double s;  // sin(half) / angle
  if (angle < 1e-4) {
    const double a2 = angle * angle;
    s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0;  // series of sin(a/2)/a
  } else {
    s = std::sin(half) / angle;
  }
  return Quat(std::cos(half), s * theta.x(), s * theta.y(), s * theta.z());
}

Vec3 logRotation(const Quat& q_in) {
  // Pick the hemisphere with w >= 0 so the angle is in [0, π].
  const double sign = q_in.w() < 0.0 ? -1.0 : 1.0;
  const double w = sign * q_in.w();
  const Vec3 v = sign * q_in.vec();
  const double sin_half = v.norm();
  if (sin_half < 1e-8) {
    // angle ≈ 2 sin_half; first-order series keeps precision and avoids 0/0.
    return (2.0 / w) * v;
  }
  const double angle = 2.0 * std::atan2(sin_half, w);
  return (angle / sin_half) * v;
}

Vec6 poseDifference(const Pose& X_target, const Pose& X_god) {
  Vec6 d;
  d.head<3>() = X_target.p - X_god.p;
  d.tail<3>() = logRotation(X_target.q * X_god.q.conjugate());
  return d;
}

Pose poseUpdate(const Pose& X, const Vec6& y, double h) {
  Pose out;
  out.p = X.p + h * y.head<3>();
  out.q = (expRotation(h * y.tail<3>()) * X.q).normalized();
  return out;
}

bool isValidPose(const Pose& X, double unit_tolerance) {
  if (!X.p.allFinite() || !X.q.coeffs().allFinite()) return false;
  return std::abs(X.q.norm() - 1.0) <= unit_tolerance;
}

}  // namespace godhand
