// A loaded scene: the objects God hands collide with and the Bullet world simulates, each at
// the fidelity the scene file asks for ("model only what a scene requires"). Produced by
// parseScene() / meshScene() (scene_file.h) from idl/scene.proto text (the programs read the
// files with loadScene() of services/common/files.h); immutable after loading (poses of dynamic
// objects live in the physics world, not here).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "geometry/bvh.h"
#include "geometry/mesh.h"
#include "math/pose.h"

namespace godhand {

/// What Bullet simulates for an object.
enum class PhysicsShapeType { None, Box, Sphere, Cylinder, ConvexHull, TriangleMesh };

struct PhysicsShape {
  PhysicsShapeType type = PhysicsShapeType::None;  ///< None: not simulated (God-collision only)
  Vec3 half_extents = Vec3::Zero();  ///< Box; Cylinder: (r, r, half height) along local z
  double radius = 0.0;               ///< Sphere
  std::vector<Vec3> points;          ///< ConvexHull: hull vertices, object frame
  geo::TriangleMesh mesh;            ///< TriangleMesh (static objects only), object frame
};

struct SceneObject {
  std::string id;                    ///< unique name
  int index = -1;                    ///< position in Scene::objects
  Pose X_WO;                         ///< initial pose of the object frame in the world
  double mass = 0.0;                 ///< kg; 0 = static
  double friction = 0.5;
  double restitution = 0.0;
  /// What the God-object collision sees (object frame, scale applied, metres): always a
  /// triangle mesh; primitives are tessellated so that the mesh encloses the true primitive.
  std::shared_ptr<const geo::MeshBvh> god;
  /// The full-resolution geometry the penetration figure is measured against (METHOD.md §5);
  /// the same pointer as `god` when the God collision uses the full mesh.
  std::shared_ptr<const geo::MeshBvh> reference;
  /// m: the God side takes every distance to this object from the God object grown by this much
  /// (fidelity AUTO: the measured bound of the full surface's distance from `god`), else 0.
  double god_skin = 0.0;
  /// What the God side got and why, for reports ("AUTO 1 mm: decimated to 4,949 triangles, ...").
  std::string god_note;
  /// Mesh objects: how inside and outside were decided (scene/mesh_io.h classifySurface), e.g.
  /// "open surface (...): a thin shell, touched from either side, no inside". Empty for primitives.
  std::string surface_note;
  /// The mesh is not what it said: open (a shell) or facing inwards (turned outward). Programs
  /// print surface_note when set.
  bool surface_changed = false;
  PhysicsShape physics;
  std::string source;                ///< mesh file or primitive description, for messages
  double scale = 1.0;                ///< uniform scale applied to the mesh file
  Vec3 translation = Vec3::Zero();   ///< --mesh scenes: translation applied (reported)
};

struct Scene {
  std::string name;
  Vec3 gravity{0.0, 0.0, -9.81};
  std::vector<SceneObject> objects;
  long long god_triangles = 0;       ///< Σ triangles the God-object collision sees
  long long reference_triangles = 0; ///< Σ full-resolution triangles
};

}  // namespace godhand
