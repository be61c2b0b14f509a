#include "geometry/mesh.h"

namespace godhand::geo {

// Centre/extent form: the box centre maps as a point, the half extent through |R| (entrywise),
// which is the tightest axis-aligned box around the rotated box.
Aabb transformAabb(const Aabb& box_A, const Pose& X_BA) {
  if (box_A.empty()) return Aabb{};
  const Mat3 R_BA = X_BA.q.toRotationMatrix();
  const Vec3 c_B = X_BA * box_A.centre();
  const Vec3 e_B = R_BA.cwiseAbs() * (0.5 * box_A.extent());
  Aabb out;
  out.lo = c_B - e_B;
  out.hi = c_B + e_B;
  return out;
}

}  // namespace godhand::geo
