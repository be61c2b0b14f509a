// A restarted godhand-scene takes its dynamic objects back from where the last one left them,
// not from the scene file (no jump back). The running scene writes the poses of its dynamic
// objects after its steps to a small text file (one line per object: index and pose, %.17g, bit
// exact), replaced atomically (write + rename); a scene started with that file moves the objects'
// initial poses there before building its world. Velocities are not kept (objects restart at rest).
//
// Why a file: SceneState is transient-local, but its history lives in the writer, which dies with
// the scene process; nobody re-serves it to the scene's next incarnation.
#pragma once

#include <string>
#include <vector>

#include "pipeline/stages.h"
#include "scene/scene.h"

namespace godhand::svc {

/// Writes the objects' poses to `path` (via path + ".tmp" and rename). False on an I/O error.
bool writeSceneResume(const std::string& path, const std::vector<ObjectMotion>& objects);

/// Reads `path` and sets scene->objects[index].X_WO for each line. Returns how many objects were
/// moved; 0 when the file does not exist. A malformed file: false, *why = "FILE:LINE: reason", the
/// scene untouched.
bool applySceneResume(const std::string& path, Scene* scene, int* moved, std::string* why);

}  // namespace godhand::svc
