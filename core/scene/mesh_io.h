// Mesh files (OBJ, STL) in, clean triangle meshes out; plus the few mesh operations scenes need
// (decimation, convex hull, enclosing primitive tessellations, subdivision).
//
// Why hand-written readers and no library: the two formats are tiny (OBJ `v`/`f`, STL facets),
// we need exact per-line error positions and our own cleaning rules (welding, degenerate and
// duplicate triangles, open-edge counts), and the Debian mesh-import library (assimp) would pull
// in ~40 formats and its own post-processing whose results we would have to re-check anyway.
//
// Cleaning (parseMeshFile / parseObj / parseStl / cleanMesh), in this order:
//   1. weld vertices with bit-identical coordinates (-0 = +0); STL's unshared corners weld here;
//   2. drop degenerate triangles: repeated vertex indices, or |(b−a)×(c−a)| ≤ 1e-12 · L² with L
//      the bounding-box diagonal (zero area relative to the mesh size);
//   3. drop duplicate triangles: the same three vertices in any order (the first one stays);
//   4. drop vertices no triangle uses;
//   5. count open edges: an edge used by one triangle is a boundary edge, by more than two a
//      non-manifold edge. Open meshes are accepted (stats say so); an empty result is an error.
// Errors are MeshError with one line "FILE:LINE: reason" (binary STL: "FILE:triangle N: reason";
// a file that cannot be opened: "FILE:0: cannot open mesh file: reason").
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "geometry/bvh.h"
#include "geometry/mesh.h"

namespace godhand {

/// Bad or unreadable mesh file: one line "FILE:LINE: reason".
class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What reading and cleaning did to a mesh.
struct MeshStats {
  long long input_vertices = 0;      ///< as in the file (STL: 3 per facet)
  long long input_triangles = 0;     ///< after fan triangulation of polygons
  long long output_vertices = 0;
  long long output_triangles = 0;
  long long welded = 0;              ///< vertices merged into an identical one
  long long unreferenced = 0;        ///< vertices dropped because no kept triangle uses them
  long long degenerate_dropped = 0;  ///< repeated indices or zero area
  long long duplicates_dropped = 0;  ///< same vertex triple as an earlier triangle
  long long boundary_edges = 0;      ///< edges of exactly one triangle (open mesh)
  long long nonmanifold_edges = 0;   ///< edges of three or more triangles
  long long misoriented_edges = 0;   ///< two-triangle edges walked the same way by both
  geo::Aabb bounds;                  ///< of the output vertices

  bool closed() const { return boundary_edges == 0 && nonmanifold_edges == 0; }
  /// One line: "35947 -> 34834 vertices (1113 welded, ...), 69451 -> 69451 triangles (...), ...".
  std::string summary() const;
};

/// The format a mesh file's name says, from its extension in any case: ".obj" or ".stl".
/// Throws MeshError "PATH:0: unsupported mesh format 'EXT' (expected .obj or .stl)" otherwise.
/// (Reading the file is loadMeshFile in services/common/files.h: core opens no files.)
std::string meshFormat(const std::string& path);

/// The bytes of an OBJ (.obj) or STL (.stl, ASCII or binary) file, parsed in the format
/// meshFormat(path) names and cleaned (see above); `path` names it in errors. Coordinates are
/// taken as they are (no unit conversion). Throws MeshError.
geo::TriangleMesh parseMeshFile(const std::string& bytes, const std::string& path, MeshStats* stats = nullptr);

/// Parses OBJ / STL text or bytes already in memory; `source` names it in errors.
geo::TriangleMesh parseObj(const std::string& text, const std::string& source, MeshStats* stats = nullptr);
geo::TriangleMesh parseStl(const std::string& bytes, const std::string& source, MeshStats* stats = nullptr);

/// Cleaning steps 1–5 on any mesh (indices must be in range). Returns an empty mesh when
/// nothing is left (callers decide whether that is an error). Counts into *stats (input counts
/// are set from `raw`).
geo::TriangleMesh cleanMesh(const geo::TriangleMesh& raw, MeshStats* stats = nullptr);

/// Edge counts and bounds of a mesh without changing it (fills the edge fields and bounds).
void countEdges(const geo::TriangleMesh& mesh, MeshStats* stats);

/// Bounding box of the vertices.
geo::Aabb meshBounds(const geo::TriangleMesh& mesh);

/// Σ over triangles of a·(b×c)/6: > 0 for a closed outward-oriented mesh.
double signedVolume(const geo::TriangleMesh& mesh);

/// Whether the winding number of a mesh decides inside and outside next to its surface: at the
/// centroids of up to `samples` triangles (the largest of each of `samples` equal runs of the
/// triangle list), the points ε = 1e-6 · (bounding-box diagonal) behind and in front of the face. A closed
/// outward-facing surface gives w ≈ 1 behind and ≈ 0 in front; one facing inwards ≈ 0 and ≈ −1;
/// an open surface (a bowl, a panel) gives neither (a bowl's cavity has 0.5 < w < 1: it would
/// read as inside the bowl). "≈" is within 0.1; small holes leave most samples decided.
struct SurfaceVerdict {
  enum class Kind { Solid, Inverted, Shell };
  int samples = 0;
  int outward = 0;  ///< samples decided as a closed outward-facing surface
  int inward = 0;   ///< samples decided as a closed inward-facing surface
  Kind kind = Kind::Solid;
  /// Solid: ≥ 90 % outward; Inverted: ≥ 90 % inward; else Shell.
  static constexpr double kDecided = 0.9;
  static constexpr double kTolerance = 0.1;
  /// One phrase for load reports, e.g. "open surface (inside/outside decided at 0 of 256 surface
  /// samples): a thin shell, touched from either side, no inside".
  std::string describe() const;
};
SurfaceVerdict classifySurface(const geo::MeshBvh& bvh, int samples = 256);

/// The mesh with every triangle's orientation reversed (b and c swapped).
geo::TriangleMesh flipped(geo::TriangleMesh mesh);

/// Vertex clustering on a uniform grid: every vertex moves to the mean of its cell's vertices,
/// collapsed and duplicate triangles are dropped. The cell size is searched so that the result
/// has about `target_triangles` (within ~15 % where the mesh allows). Each output vertex lies in
/// its cell, so it is within √3·cell of an input vertex. Returns the input unchanged when it
/// already has ≤ target triangles. *cell_size receives the cell edge used (0 if unchanged).
/// Throws std::invalid_argument when target_triangles < 4.
geo::TriangleMesh decimate(const geo::TriangleMesh& mesh, int target_triangles, double* cell_size = nullptr);

/// Convex hull of the points (quickhull in double precision; Bullet's btConvexHullComputer snaps
/// points to a grid of extent/10216, see mesh_io.cc), triangulated, closed, outward oriented.
/// Hull vertices are input points; every input point is inside or within ~1e-14 · |coordinates|
/// of it. Throws std::invalid_argument when the points span no volume (fewer than 4
/// non-coplanar points) or are not finite.
geo::TriangleMesh convexHull(const std::vector<Vec3>& points);

/// Vertices scaled by s about the origin / moved by t.
geo::TriangleMesh uniformScale(geo::TriangleMesh mesh, double s);
geo::TriangleMesh translate(geo::TriangleMesh mesh, const Vec3& t);

/// Primitive tessellations centred at the origin that ENCLOSE the true primitive (every point of
/// the solid primitive is inside or on the polyhedron), outward oriented, closed.
/// Box: exact, 8 vertices, 12 triangles.
geo::TriangleMesh boxMesh(const Vec3& half_extents);
/// Icosphere (20·4^levels triangles) scaled so its inscribed radius (smallest face-plane distance)
/// is r; the vertices lie at r / cos(...) ≤ 1.006 r for levels = 3.
geo::TriangleMesh sphereMesh(double radius, int levels = 3);
/// Prism along local z (z ∈ [−h, h]) whose regular `segments`-gon has apothem r (circumradius
/// r / cos(π/segments)); caps fan around their centre: 4·segments triangles.
geo::TriangleMesh cylinderMesh(double radius, double half_height, int segments = 32);

/// Midpoint subdivision, 1 triangle → 4, flat (the surface is unchanged), shared edge midpoints
/// so a closed mesh stays closed. 4^levels times the triangles.
geo::TriangleMesh subdivide(const geo::TriangleMesh& mesh, int levels);

}  // namespace godhand
