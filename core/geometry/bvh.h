// A bounding-volume hierarchy over one triangle mesh, in the mesh's frame M: the proximity
// structure of the God-object collision stage (FCL is the test oracle, too slow for the hot
// path: see DEVELOPERS notes). Built once per mesh; queries are const and allocate nothing
// once the caller's output vectors have grown.
//
// Inside/outside (meshes are hollow to distance queries): the generalized winding number
// w(p) = Σ_t Ω_t(p) / 4π (Jacobson et al. 2013), ≈ 1 inside and ≈ 0 outside a closed,
// outward-oriented mesh, and still a usable vote (> 0.5 = inside) for meshes with small holes.
// Far BVH nodes use the dipole approximation of Barill et al. 2018; near ones are exact.
#pragma once

#include <vector>

#include "geometry/distance.h"
#include "geometry/mesh.h"

namespace godhand::geo {

struct NearTriangle {
  int triangle = -1;
  ClosestPoints closest;
};

class MeshBvh {
 public:
  MeshBvh() = default;
  /// Builds the hierarchy; throws std::invalid_argument on an empty mesh, indices out of
  /// range or non-finite vertices.
  explicit MeshBvh(TriangleMesh mesh);

  const TriangleMesh& mesh() const { return mesh_; }
  const Aabb& bounds() const { return bounds_; }
  int triangleCount() const { return mesh_.triangleCount(); }

  /// Appends to `out` every triangle whose bounding box overlaps `box_M`.
  void trianglesOverlapping(const Aabb& box_M, std::vector<int>* out) const;

  /// Closest triangle to the shape at X_MB if the shape distance is ≤ max_distance: fills
  /// *out and returns true; else returns false. Exact to round-off (brute-force equal).
  bool closest(const Shape& shape, const Pose& X_MB, double max_distance, NearTriangle* out) const;

  /// Appends every triangle within max_distance of the shape at X_MB, with its closest points.
  void near(const Shape& shape, const Pose& X_MB, double max_distance, std::vector<NearTriangle>* out) const;

  /// Generalized winding number at p_M (see above).
  double windingNumber(const Vec3& p_M) const;
  bool inside(const Vec3& p_M) const { return windingNumber(p_M) > 0.5; }

 private:
  struct Node {
    Aabb box;
    int first = 0;   ///< leaf: first index into order_; inner: left child
    int count = 0;   ///< leaf: triangle count; inner: 0 (right child = first + 1 or stored)
    int right = -1;
    Vec3 dipole_centre = Vec3::Zero();  ///< area-weighted centroid
    Vec3 dipole_normal = Vec3::Zero();  ///< Σ area-weighted normals (½ (b−a)×(c−a))
    double radius = 0.0;                ///< of the node's triangles around dipole_centre
  };
  TriangleMesh mesh_;
  Aabb bounds_;
  std::vector<Node> nodes_;
  std::vector<int> order_;  ///< triangle indices, grouped by leaf
  std::vector<Aabb> tri_boxes_;
};

}  // namespace godhand::geo
