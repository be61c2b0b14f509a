// Scene files (protobuf text, schema idl/scene.proto) and the benchmark's `--mesh` scenes, loaded
// into the immutable Scene of scene.h.
//
// Per object (object frame O, metres):
//   mesh:      vertex_O = scale · v_file + translation, then `subdivide` midpoint levels;
//              translation = −scale · (bounding-box centre) when `centre: true`, else 0.
//              god:  FULL → that mesh; DECIMATED → vertex clustering to ~target_triangles;
//                    CONVEX_HULL → its hull; PRIMITIVE → its bounding box (12 triangles).
//              reference: the FULL mesh (the same pointer as god when god is FULL).
//              physics: TRIANGLE_MESH (static only) → the scaled mesh before subdivision (same
//                    surface); CONVEX_HULL → hull vertices; PRIMITIVE → bounding box (the box must
//                    be centred at the origin: use `centre: true`); NONE (static only).
//   box / sphere / cylinder: god = reference = the enclosing tessellation (mesh_io.h); physics
//              PRIMITIVE (default) → the exact primitive; CONVEX_HULL → tessellation vertices;
//              TRIANGLE_MESH (static only) → the tessellation; NONE (static only).
// Objects with the same mesh path, scale, centring, subdivision and god fidelity share their
// BVHs (a cache inside one parse call), so instancing a mesh costs no memory. The path is
// compared as the string the MeshLoader is given (a scene's mesh path joined to the scene's
// directory, lexically normal; a `--mesh` path as written): core asks the file system nothing,
// so two spellings of one file (a symbolic link, an absolute and a relative path) load it twice,
// with the same result.
// World position of a mesh-file vertex v: X_WO * (scale · v + translation).
#pragma once

#include <functional>
#include <stdexcept>
#include <optional>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace godhand {

/// Bad scene file or `--mesh` argument: one line "FILE:LINE: objects[3].mass: reason".
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Reads and cleans the mesh file at `path` (throws MeshError "FILE:LINE: reason"). Core opens
/// no files: the programs pass meshFileLoader() of services/common/files.h, tests may pass
/// meshes from memory. Called once per distinct path string within one parseScene / meshScene.
using MeshLoader = std::function<geo::TriangleMesh(const std::string& path)>;

struct GodFidelity;

/// Parses and validates a scene file's text (throws SceneError; mesh errors carry the scene
/// location followed by the mesh file's own "FILE:LINE: reason"). Mesh paths are relative to
/// `base_dir` and read through `load_mesh`; `source` names the text in errors. (Reading a scene
/// file is loadScene in services/common/files.h.) `god_override`: every mesh object's God side
/// is that instead of the file's `god` (godhand-bench --god-fidelity; primitives keep theirs).
Scene parseScene(const std::string& text, const std::string& source, const std::string& base_dir,
                 const MeshLoader& load_mesh, const GodFidelity* god_override = nullptr);

/// What the God-object collision sees of a `--mesh` object (the scene file's `god` fidelity):
/// the full mesh, a vertex-clustering decimation to about `target_triangles`, the convex hull, or
/// AUTO (idl/scene.proto). Penetration is measured against the full mesh whatever is chosen.
struct GodFidelity {
  enum class Kind { Full, Decimated, Hull, Auto } kind = Kind::Full;
  int target_triangles = 0;  ///< Decimated only, >= 4
  double tolerance_m = 0.0;  ///< Auto only, > 0 (the scene file's AUTO, tolerance_mm)
};

/// "full", "hull", "decimated:N" (N >= 4 triangles) or "auto:MM" (AUTO with a tolerance in mm).
/// Throws SceneError naming the argument.
GodFidelity parseGodFidelity(const std::string& arg);

/// One `--mesh FILE[:SIZE_M]` argument.
struct MeshSpec {
  std::string path;
  double size = 0.15;  ///< largest bounding-box extent after scaling, m
  GodFidelity god;     ///< what the God side collides with (default: the full mesh)
  /// World position (m) of the bounding-box centre; empty: meshScene's `centre` (the programs:
  /// the recording's mean palm, so the mesh lands under the hand).
  std::optional<Vec3> at;
};

/// "path", "path:0.2" (the part after the last ':' is the size in metres unless it ends in
/// .obj / .stl), each optionally followed by "@X,Y,Z" (world position of the mesh's centre, m).
/// Throws SceneError on a bad or non-positive size, a bad position or an empty path.
MeshSpec parseMeshSpec(const std::string& arg);

/// A scene of the given meshes only: each scaled uniformly so its largest extent is spec.size
/// and its bounding-box centre placed at spec.at, else at `centre` (object frame origin = that
/// centre, X_WO = {centre, identity}, translation = −scale · bbox centre), static, god as spec.god, physics
/// TRIANGLE_MESH, friction 0.5. Ids are the file stems (made unique with _2, _3, ...).
/// The meshes are read through `load_mesh`. Throws SceneError (with the mesh file's
/// "FILE:LINE: reason").
Scene meshScene(const std::vector<MeshSpec>& specs, const Vec3& centre, const MeshLoader& load_mesh);

}  // namespace godhand
