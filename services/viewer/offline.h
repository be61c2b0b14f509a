// Offline mode and scene assets: the godhand-bench `--poses` CSV read by its header names, and the
// triangles of a loaded scene as the page fetches them.
//
// CSV: one row per frame, hand and body. Required columns (any order, more allowed):
//   frame,hand,body,shape,radius,half_length,hx,hy,hz,px,py,pz,qw,qx,qy,qz
// optional target columns tpx,tpy,tpz,tqw,tqx,tqy,tqz (all seven, or none; a row may leave all
// seven empty: that body has no target that frame). shape: capsule | sphere | box.
// Errors: PosesError "FILE:LINE: reason" (bad number, missing column, non-unit quaternion, a body
// that changes shape, frames out of order, ...).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "geometry/mesh.h"
#include "scene/scene.h"

namespace godhand::viewer {

struct PosesError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct PoseTrack {
  std::string hand;                       ///< "right", "left", ...
  std::vector<std::string> bodies;        ///< in first-seen order
  std::vector<std::array<double, 6>> shapes;  ///< type, radius, half_length, hx, hy, hz
  /// Per frame index (PoseFile::frames): 7 numbers per body, empty when the hand has no rows.
  std::vector<std::vector<double>> poses;
  /// Same for targets: NaN for a body without a target (only when PoseFile::has_targets).
  std::vector<std::vector<double>> targets;
};

struct PoseFile {
  std::vector<std::int64_t> frames;       ///< ascending, as in the file
  std::vector<PoseTrack> hands;           ///< in first-seen order
  bool has_targets = false;
  std::size_t rows = 0;
};

PoseFile parsePosesCsv(const std::string& text, const std::string& source);
PoseFile loadPosesCsv(const std::string& path);

/// {"frames", "hands":[{name, bodies, shapes, poses, targets|null}], "has_targets"}; NaN -> null.
nlohmann::json poseFileJson(const PoseFile& f);

/// Scene description for the page, same shape as encode.h's sceneDescriptionJson.
nlohmann::json sceneJson(const Scene& scene, const std::string& file, const std::string& generation);

/// "GHM1" | u32 LE vertices | u32 LE triangles | float32 LE xyz per vertex | u32 LE indices.
std::string meshBinary(const geo::TriangleMesh& mesh);

/// The mesh the page draws for an object: its full-resolution reference mesh (else its God mesh),
/// decimated by vertex clustering (core decimate) to about max_triangles when it has more
/// (software WebGL draws ~170k triangles at a few frames per second); false when it has none.
bool displayMesh(const Scene& scene, int object, int max_triangles, geo::TriangleMesh* out);

}  // namespace godhand::viewer
