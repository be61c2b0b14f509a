// Exact closest points between a God-object shape and one triangle (METHOD.md §2 step 5, §5).
//
// Every God-object shape is a convex core swept by a sphere of radius r:
//   sphere  = point (the body origin) + r
//   capsule = segment from −h e_z to +h e_z in the body frame + r
//   box     = solid box of half-extents e (r = 0)
// The core–triangle distance is computed exactly (to round-off) by feature enumeration; the
// shape distance is that minus r, so it is negative when the shape overlaps the triangle.
// When the core itself touches or crosses the triangle (core distance 0), `distance` is −r and
// the normal is the triangle's face normal (b−a)×(c−a), flipped to the side of the core's
// centre; callers treat that as deep penetration.
#pragma once

#include "geometry/mesh.h"
#include "model/hand_model.h"

namespace godhand::geo {

struct ClosestPoints {
  double distance = 0.0;             ///< shape–triangle signed distance: core distance − r, m
  double core_distance = 0.0;        ///< ≥ 0
  Vec3 p_shape = Vec3::Zero();       ///< on the shape's surface (core point − r n), frame M:
                                     ///< p_shape − p_triangle = distance · n
  Vec3 p_triangle = Vec3::Zero();    ///< on the triangle, frame M
  Vec3 n = Vec3::UnitZ();            ///< unit, from the triangle towards the shape, frame M
};

/// Radius of the shape's core sphere sweep (0 for a box).
double coreRadius(const Shape& shape);
/// Largest distance from the body origin to any point of the shape (for motion bounds).
double boundingRadius(const Shape& shape);
/// Largest distance from the body origin to any point of the core (sphere 0, capsule h, box |e|):
/// the shape distance is the core distance − r, so only core points matter for motion bounds.
double coreBoundingRadius(const Shape& shape);
/// World-aligned box of the shape at pose X_MB.
Aabb shapeAabb(const Shape& shape, const Pose& X_MB);

/// Closest points between the shape at pose X_MB (body in mesh frame M) and triangle abc (M).
ClosestPoints shapeTriangle(const Shape& shape, const Pose& X_MB, const Vec3& a, const Vec3& b, const Vec3& c);

/// Exact distance from a point to triangle abc, and the closest point (may be null).
/// Degenerate triangles (zero area, needles) are measured as their edges: never NaN.
double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* closest);

/// Closest points between segments p0p1 and q0q1 (either may be a point); returns the distance.
double segmentSegmentDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, Vec3* on_p, Vec3* on_q);

namespace detail {
// The building blocks of shapeTriangle in the body frame B, shared with the BVH so that its
// leaves do not re-derive the rotation for every triangle. Triangle vertices given in B.

/// Core–triangle distance (≥ 0) with the closest core point and triangle point (both B).
double coreTriangle(const Shape& shape, const Vec3& a_B, const Vec3& b_B, const Vec3& c_B, Vec3* core_B,
                    Vec3* tri_B);
/// Assembles the ClosestPoints (frame M) from coreTriangle's output.
ClosestPoints finishClosestPoints(const Shape& shape, const Pose& X_MB, const Mat3& R_MB, double core_distance,
                                  const Vec3& core_B, const Vec3& tri_B, const Vec3& a_B, const Vec3& b_B,
                                  const Vec3& c_B);
}  // namespace detail

}  // namespace godhand::geo
