#include "skeleton/skeleton.h"

#include <cmath>

namespace godhand::skeleton {

const char* reasonName(Reject r) {
  switch (r) {
    case Reject::kNotFinite: return "NaN/Inf";
    case Reject::kOutOfRange: return "out of range";
    case Reject::kDegenerate: return "degenerate skeleton (bone length / palm)";
    case Reject::kInvalidJoint: return "joint not valid";
    case Reject::kCount: break;
  }
  return "?";
}

namespace {

// Joint indices of the 21-landmark layout per finger (thumb..little) and joint (mcp..tip).
constexpr int kFingerBase[5] = {1, 5, 9, 13, 17};

bool fail(Reject r, Reject* why) {
  if (why) *why = r;
  return false;
}

bool checkBones(const std::array<Vec3, kLandmarks>& p, const SkeletonLimits& L) {
  auto ok = [&](int a, int b) {
    const double d = (p[static_cast<size_t>(a)] - p[static_cast<size_t>(b)]).norm();
    return d >= L.min_bone_m && d <= L.max_bone_m;
  };
  for (int f = 0; f < 5; ++f) {
    const int b = kFingerBase[f];
    if (!ok(0, b)) return false;
    for (int k = 0; k < 3; ++k)
      if (!ok(b + k, b + k + 1)) return false;
  }
  return true;
}

/// Palm frame from wrist, index / middle / little MCP (T frame); false when degenerate.
bool palmFrame(const Vec3& wrist, const Vec3& index_mcp, const Vec3& middle_mcp, const Vec3& little_mcp, bool right, Mat3* R) {
  Vec3 y = middle_mcp - wrist;
  if (y.norm() < 1e-6) return false;
  y.normalize();
  Vec3 x = right ? (little_mcp - index_mcp) : (index_mcp - little_mcp);
  x -= x.dot(y) * y;
  if (x.norm() < 1e-6) return false;
  x.normalize();
  const Vec3 z = x.cross(y);
  R->col(0) = x;
  R->col(1) = y;
  R->col(2) = z;
  return true;
}

}  // namespace

bool handFromLandmarks(const std::array<Vec3, kLandmarks>& p_T, bool right, double confidence, int id, const Pose& X_WT,
                       leap::TrackedHand* out, Reject* why, const SkeletonLimits& L) {
  for (const Vec3& v : p_T)
    if (!v.allFinite()) return fail(Reject::kNotFinite, why);
  if (!std::isfinite(confidence)) return fail(Reject::kNotFinite, why);
  std::array<Vec3, kLandmarks> p;
  for (size_t i = 0; i < p.size(); ++i) {
    if (p_T[i].cwiseAbs().maxCoeff() > L.max_position_m) return fail(Reject::kOutOfRange, why);  // in the tracker's frame
    p[i] = X_WT * p_T[i];
  }
  if (!(confidence >= 0.0 && confidence <= 1.0)) return fail(Reject::kOutOfRange, why);
  if (!checkBones(p, L)) return fail(Reject::kDegenerate, why);
  Mat3 R;
  if (!palmFrame(p[0], p[5], p[9], p[17], right, &R)) return fail(Reject::kDegenerate, why);
  leap::TrackedHand h;
  h.id = id;
  h.right = right;
  h.confidence = confidence;
  h.X_W_palm.p = 0.5 * (p[0] + p[9]);
  h.X_W_palm.q = Quat(R).normalized();
  for (int f = 0; f < 5; ++f)
    for (int k = 0; k < 4; ++k) h.joints_W[static_cast<size_t>(f)][static_cast<size_t>(k)] = p[static_cast<size_t>(kFingerBase[f] + k)];
  *out = h;
  return true;
}

bool handFromOpenXr(const std::array<XrJoint, kXrJoints>& j, bool right, double confidence, int id, const Pose& X_WT,
                    leap::TrackedHand* out, Reject* why, const SkeletonLimits& L) {
  // 26 -> 21: wrist, thumb metacarpal/proximal/distal/tip, finger proximal/intermediate/distal/tip.
  static constexpr int kMap[kLandmarks] = {1, 2, 3, 4, 5, 7, 8, 9, 10, 12, 13, 14, 15, 17, 18, 19, 20, 22, 23, 24, 25};
  std::array<Vec3, kLandmarks> p;
  for (int i = 0; i < kLandmarks; ++i) {
    const XrJoint& x = j[static_cast<size_t>(kMap[i])];
    if (!x.p.allFinite()) return fail(Reject::kNotFinite, why);
    if (!(x.flags & kXrPositionValid)) return fail(Reject::kInvalidJoint, why);
    p[static_cast<size_t>(i)] = xrToT(x.p);
  }
  leap::TrackedHand h;
  if (!handFromLandmarks(p, right, confidence, id, X_WT, &h, why, L)) return false;
  const XrJoint& palm = j[0];
  if ((palm.flags & kXrOrientationValid) && (palm.flags & kXrPositionValid)) {
    if (!palm.p.allFinite() || !palm.q.coeffs().allFinite()) return fail(Reject::kNotFinite, why);
    if (!(std::abs(palm.q.norm() - 1.0) < 1e-3)) return fail(Reject::kOutOfRange, why);
    Mat3 A;
    A << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    const Mat3 Rxr = palm.q.normalized().toRotationMatrix();
    Mat3 R;
    R.col(0) = A * Rxr.col(0);   // x: OpenXR's +X
    R.col(1) = -(A * Rxr.col(2));  // y (fingers): OpenXR's −Z
    R.col(2) = A * Rxr.col(1);   // z (back of the hand): OpenXR's +Y
    h.X_W_palm.q = (X_WT.q * Quat(R)).normalized();
    if (xrToT(palm.p).cwiseAbs().maxCoeff() > L.max_position_m) return fail(Reject::kOutOfRange, why);
    h.X_W_palm.p = X_WT * xrToT(palm.p);
  }
  *out = h;
  return true;
}

}  // namespace godhand::skeleton
