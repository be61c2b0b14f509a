// The file side of core's parsers. core/ does no I/O (tests/structure/core_no_io.py checks it):
// its parsers take text and bytes (HandModel::fromText, parseScene, parseMeshFile) and scenes read
// their meshes through an injected MeshLoader. These functions open the files, with the errors the
// parsers' callers have always seen. Users include "common/files.h" (library godhand_files).
#pragma once

#include <string>

#include "model/hand_model.h"
#include "scene/mesh_io.h"
#include "scene/scene_file.h"

namespace godhand {

/// Reads and validates a hand / cluster model file; throws ModelError "FILE:LINE: field: reason"
/// ("FILE: cannot open model file" when it cannot be read).
HandModel loadHandModel(const std::string& path);

/// Reads an OBJ (.obj) or STL (.stl, ASCII or binary) file and cleans it (mesh_io.h). Throws
/// MeshError "FILE:LINE: reason"; a file that cannot be read: "FILE:0: cannot open mesh file:
/// no such file / not a regular file / the system's reason", a name that is neither .obj nor
/// .stl: "FILE:0: unsupported mesh format '.EXT' (expected .obj or .stl)".
geo::TriangleMesh loadMeshFile(const std::string& path, MeshStats* stats = nullptr);

/// loadMeshFile as the MeshLoader that parseScene and meshScene take.
MeshLoader meshFileLoader();

/// Reads and validates a scene file, its meshes relative to the file's directory (throws
/// SceneError; "FILE:0: cannot open scene file" when it cannot be read; mesh errors carry the
/// scene location followed by the mesh file's own "FILE:LINE: reason"). `god`: every mesh
/// object's God side instead of the file's (parseScene's god_override).
Scene loadScene(const std::string& path, const GodFidelity* god = nullptr);

/// Why an output file could not be written, checked before a run (its directory exists and is
/// writable, the file itself, if it exists, is a writable regular file or a device); "" when it
/// can. Nothing is created: a run that fails leaves no empty file behind.
std::string unwritableReason(const std::string& path);

}  // namespace godhand
