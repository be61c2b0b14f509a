// Scenes of boxes for the pipeline tests: a box object (its God, reference and Bullet shape the
// same box) and a scene of given objects (indices and triangle totals filled in).
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "geometry/bvh.h"
#include "scene/mesh_io.h"
#include "scene/scene.h"

namespace godhand::testing {

inline SceneObject boxObject(const std::string& id, const Vec3& half, const Pose& X_WO, double mass) {
  SceneObject o;
  o.id = id;
  o.X_WO = X_WO;
  o.mass = mass;
  o.god = std::make_shared<geo::MeshBvh>(boxMesh(half));
  o.reference = o.god;
  o.physics.type = PhysicsShapeType::Box;
  o.physics.half_extents = half;
  o.source = "box";
  return o;
}

inline Scene sceneOf(std::vector<SceneObject> objects, Vec3 gravity = Vec3(0, 0, -9.81)) {
  Scene s;
  s.name = "test";
  s.gravity = gravity;
  for (SceneObject& o : objects) {
    o.index = static_cast<int>(s.objects.size());
    s.god_triangles += o.god->triangleCount();
    s.objects.push_back(std::move(o));
  }
  return s;
}

}  // namespace godhand::testing
