// A bounding-volume hierarchy over one triangle mesh, in the mesh's frame M: the proximity
// structure of the God-object collision stage (FCL is the test oracle, too slow for the hot
// path: see DEVELOPERS notes). Built once per mesh; queries are const and allocate nothing
// once the caller's output vectors have grown.
//
// Inside/outside (meshes are hollow to distance queries): the generalized winding number
// w(p) = Σ_t Ω_t(p) / 4π (Jacobson et al. 2013), ≈ 1 inside and ≈ 0 outside a closed,
// outward-oriented mesh, and still a usable vote (> 0.5 = inside) for meshes with small holes.
// Far BVH nodes use the dipole approximation of Barill et al. 2018; near ones are exact.
// A node of area-weighted centre c and radius R is far from p when |c − p| > β R (β = 2); then,
// with r = c − p and Ω_t ≈ A_t·(x_t − p)/|x_t − p|³ expanded about c to second order,
//   Ω_node ≈ N·r/|r|³ + tr(M)/|r|³ − 3 rᵀ M r/|r|⁵,   N = Σ A_t,  M = Σ (x_t − c) A_tᵀ.
// Near nodes sum the exact solid angles (Van Oosterom & Strackee 1983).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "geometry/distance.h"
#include "geometry/mesh.h"

namespace godhand::geo {

/// The nodes and triangles (positions in the leaf order, as −(i + 1)) one advancement step could
/// not certify for the rest of its motion: the next step of the same sweep starts from them
/// instead of the root (MeshBvh::advancementStep).
struct AdvanceFront {
  std::vector<int> current, next;
  bool valid = false;
};

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
  /// *out and returns true; else returns false. Exact to round-off (brute-force equal); of
  /// triangles at exactly the least distance (a shared corner or edge), the lowest index.
  /// `hint` (a triangle index, e.g. what the same query found a step before) is measured first so
  /// that the traversal prunes from the start; the result is the same bit for bit without it.
  bool closest(const Shape& shape, const Pose& X_MB, double max_distance, NearTriangle* out, int hint = -1) const;

  /// Appends every triangle within max_distance of the shape at X_MB, with its closest points.
  void near(const Shape& shape, const Pose& X_MB, double max_distance, std::vector<NearTriangle>* out) const;

  /// What closest(shape, X_MB, max_distance) answers, taken from `near_answer`, near()'s answer
  /// for the same shape and pose within near_distance, without a second traversal: true with
  /// *out (bit for bit closest()'s) where the nearest of them lies inside near_distance by more
  /// than the bounds' round-off (then every triangle at the least distance is among them) and
  /// within max_distance; false where the answer cannot be told from them (call closest()).
  bool closestAmong(const std::vector<NearTriangle>& near_answer, const Shape& shape, const Pose& X_MB,
                    double near_distance, double max_distance, NearTriangle* out) const;

  /// One step of directional conservative advancement (sweep.h) for the shape at X_MB moving
  /// with constant velocity over the step: origin by dp_M, rotation θ_M (rad, frame M), per unit
  /// time. Returns the largest Δ ≤ horizon such that no triangle can come within eta of the shape
  /// during [0, Δ]: for each triangle, Δ_t = (d_t − η) / rate_t, where d_t is its distance now
  /// and rate_t = max(0, w·dp + ρ_c |w × θ|) bounds how fast the separation along the fixed
  /// direction w from the shape towards the triangle can shrink (ρ_c = coreBoundingRadius). BVH
  /// nodes are skipped with the same bound on their boxes. *limiting gets the triangle that sets
  /// Δ with its closest points now (triangle −1 if Δ = horizon). `hint` (a triangle index, e.g.
  /// the previous step's limiting one) is evaluated first to tighten the pruning. Unlike
  /// closest()'s, it can change the answer a little, never its safety: of triangles with the
  /// same time the first met is *limiting (the hint, if it is one of them), and (presumably, as
  /// in closest() before its round-off slack) a subtree whose bound comes out a few ulps above
  /// the best is pruned. Measured on the bunny (capsules, spheres and boxes resting 0.1 mm off it
  /// and moving, 3,000 poses, three hints each): of 9,000 calls the time differed in 10, the
  /// limiting triangle in 1,061. Every Δ returned is a lower bound of the contact time either
  /// way. `front` (optional, one per sweep, valid = false before its first step): each step
  /// leaves in it the nodes and triangles whose bound fell short of the horizon, and the next
  /// step (the same motion, from later on) looks at those only: everything else was shown not
  /// to come within η before the motion's end. Never throws; allocates nothing once the front's
  /// vectors have grown.
  double advancementStep(const Shape& shape, const Pose& X_MB, const Vec3& dp_M, const Vec3& theta_M, double eta,
                         double horizon, NearTriangle* limiting, int hint = -1, AdvanceFront* front = nullptr) const;

  /// Generalized winding number at p_M (see above).
  double windingNumber(const Vec3& p_M) const;
  /// Winding number > ½ on a solid; never on a shell (an open surface, e.g. a bowl or a panel,
  /// whose winding number is no inside/outside vote: it is a thin sheet, touched from either
  /// side). Meshes are solid unless the scene loader found them open (classifySurface).
  bool inside(const Vec3& p_M) const { return solid_ && windingNumber(p_M) > 0.5; }
  bool solid() const { return solid_; }
  /// Per edge (3 t + e, the edge from corner e to e + 1): 1 where it is a crease (its two
  /// triangles more than 1° apart, or more than two meet), 0 inside a flat region or on a
  /// boundary (a hole, a crack, an open surface's rim). Built with the hierarchy.
  const std::vector<std::uint8_t>& creases() const { return creases_; }
  void setSolid(bool solid) { solid_ = solid; }

 private:
  /// What the distance queries read of a node: 64 bytes, one cache line (the winding number's
  /// data is kept apart, in NodeDipole, so that the queries do not drag it through the cache).
  struct alignas(64) Node {
    Aabb box;
    int first = 0;   ///< leaf: first index into order_; inner: left child
    int count = 0;   ///< leaf: triangle count; inner: 0 (right child = first + 1 or stored)
    int right = -1;
  };
  struct NodeDipole {
    Vec3 centre = Vec3::Zero();  ///< area-weighted centroid
    Vec3 normal = Vec3::Zero();  ///< Σ area-weighted normals (½ (b−a)×(c−a))
    double radius = 0.0;         ///< of the node's triangles around centre
  };
  struct Impl;  ///< build and traversal helpers (bvh.cc)
  TriangleMesh mesh_;
  Aabb bounds_;
  double max_coordinate_ = 0.0;  ///< max |coordinate| of bounds_: closest()'s round-off scale
  bool solid_ = true;
  std::vector<std::uint8_t> creases_;
  std::vector<Node> nodes_;       ///< depth-first: an inner node's left child follows it
  std::vector<NodeDipole> dipoles_;  ///< per node, indexed like nodes_
  std::vector<int> order_;  ///< triangle indices, grouped by leaf
  std::vector<int> position_;  ///< per triangle: its index into order_ (order_'s inverse)
  std::vector<Aabb> tri_boxes_;   ///< per triangle, indexed like order_ (leaf-contiguous)
  std::vector<std::array<Vec3, 3>> tri_vertices_;  ///< corners, indexed like order_
  std::vector<Vec3> tri_centroids_;  ///< (a + b + c) / 3, indexed like order_ (the bounds' centre)
  /// Per node: second-order far-field moment Σ_t (x_t − c) A_tᵀ (x_t centroid, A_t area vector).
  std::vector<Mat3> dipole_moment_;
};

/// An upper bound of the one-sided Hausdorff distance from the surface of `from` to the surface
/// of `to` (the largest distance of a point of `from` to its nearest point of `to`), m, fine
/// enough to answer whether it is within `tolerance`. Distance is 1-Lipschitz and every point of
/// a triangle lies within its longest side / √3 of a corner (the equilateral triangle's centre is
/// the worst case), so a triangle's bound is its corners' largest distance (measured exactly)
/// plus that; where this exceeds the tolerance, or that cover term a tenth of it, the triangle
/// is split at its edge midpoints, up to 7 levels. Returns as soon as some triangle's bound stays above the tolerance (a value above
/// it). `measured` (optional) gets the largest distance at the points measured (a lower bound).
double surfaceDistanceBound(const TriangleMesh& from, const MeshBvh& to,
                            double tolerance = std::numeric_limits<double>::infinity(), double* measured = nullptr);

}  // namespace godhand::geo
