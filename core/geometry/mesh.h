// Triangle meshes and axis-aligned boxes: the geometry every collision query works on.
// A mesh lives in its own frame M (the scene object's frame, scale already applied, metres).
// Triangles are counter-clockwise seen from outside (outward normal (b−a)×(c−a)) when the
// mesh is closed and oriented; open meshes are allowed (inside tests then use the winding
// number, which degrades gracefully, see bvh.h).
#pragma once

#include <array>
#include <limits>
#include <vector>

#include "math/pose.h"

namespace godhand::geo {

struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;

  int triangleCount() const { return static_cast<int>(triangles.size()); }
  Vec3 vertex(int tri, int corner) const {
    return vertices[static_cast<size_t>(triangles[static_cast<size_t>(tri)][static_cast<size_t>(corner)])];
  }
};

struct Aabb {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());

  bool empty() const { return (lo.array() > hi.array()).any(); }
  void grow(const Vec3& p) { lo = lo.cwiseMin(p); hi = hi.cwiseMax(p); }
  void grow(const Aabb& b) { lo = lo.cwiseMin(b.lo); hi = hi.cwiseMax(b.hi); }
  Aabb inflated(double r) const { Aabb b = *this; b.lo.array() -= r; b.hi.array() += r; return b; }
  bool overlaps(const Aabb& b) const {
    return (lo.array() <= b.hi.array()).all() && (b.lo.array() <= hi.array()).all();
  }
  Vec3 centre() const { return 0.5 * (lo + hi); }
  Vec3 extent() const { return hi - lo; }
};

/// Box of `box` (given in frame A) expressed in frame B, where X_BA maps A to B.
Aabb transformAabb(const Aabb& box_A, const Pose& X_BA);

}  // namespace godhand::geo
