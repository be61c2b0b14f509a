// Open surfaces (a bowl, a panel) are shells: no inside. Closed meshes facing inwards are turned
// outward. Oracles: the analytic winding number of simple closed and open meshes, the signed
// volume, and the analytic depth of a box through a plane.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <string>

#include "geometry/bvh.h"
#include "pipeline/collision_world.h"
#include "scene/mesh_io.h"
#include "scene/scene.h"
#include "scene/scene_file.h"

namespace godhand {
namespace {

/// Open hemisphere bowl of radius 1 (z ≤ 0), outward normals; `rings` × `segments` quads.
geo::TriangleMesh bowl(int rings = 8, int segments = 24) {
  geo::TriangleMesh m;
  const double pi = std::acos(-1.0);
  m.vertices.push_back(Vec3(0, 0, -1));  // bottom pole
  for (int r = 1; r <= rings; ++r) {
    const double polar = pi - 0.5 * pi * r / rings;  // from the bottom up to the rim (z = 0)
    for (int s = 0; s < segments; ++s) {
      const double az = 2 * pi * s / segments;
      m.vertices.push_back(Vec3(std::sin(polar) * std::cos(az), std::sin(polar) * std::sin(az), std::cos(polar)));
    }
  }
  auto at = [&](int r, int s) { return r == 0 ? 0 : 1 + (r - 1) * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) m.triangles.push_back({0, at(1, s + 1), at(1, s)});
  for (int r = 1; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      m.triangles.push_back({at(r, s), at(r, s + 1), at(r + 1, s + 1)});
      m.triangles.push_back({at(r, s), at(r + 1, s + 1), at(r + 1, s)});
    }
  return m;
}

/// A square of half-size h in the plane z = 0, normal +z.
geo::TriangleMesh square(double h) {
  geo::TriangleMesh m;
  m.vertices = {Vec3(-h, -h, 0), Vec3(h, -h, 0), Vec3(h, h, 0), Vec3(-h, h, 0)};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

TEST(Surface, ClosedOpenAndInvertedMeshesAreToldApart) {
  // The oracle: a sphere's winding number is 1 inside, 0 outside; the bowl's cavity is neither.
  const geo::MeshBvh sphere(sphereMesh(1.0, 2));
  const SurfaceVerdict s = classifySurface(sphere);
  EXPECT_EQ(s.kind, SurfaceVerdict::Kind::Solid) << s.describe();
  EXPECT_EQ(s.outward, s.samples);
  const geo::MeshBvh inverted(flipped(sphereMesh(1.0, 2)));
  const SurfaceVerdict i = classifySurface(inverted);
  EXPECT_EQ(i.kind, SurfaceVerdict::Kind::Inverted) << i.describe();
  EXPECT_LT(signedVolume(inverted.mesh()), 0.0);
  EXPECT_GT(signedVolume(flipped(inverted.mesh())), 0.0);
  const geo::MeshBvh b(bowl());
  const SurfaceVerdict v = classifySurface(b);
  EXPECT_EQ(v.kind, SurfaceVerdict::Kind::Shell) << v.describe();
  // The reason: a point in the bowl's cavity has a winding number above ½ (it would read as
  // inside the bowl), one below the bowl a negative one.
  EXPECT_GT(b.windingNumber(Vec3(0, 0, -0.9)), 0.5);
  EXPECT_LT(b.windingNumber(Vec3(0, 0, -1.1)), 0.0);
  const geo::MeshBvh sq(square(1.0));
  EXPECT_EQ(classifySurface(sq).kind, SurfaceVerdict::Kind::Shell);
  // A closed mesh with one small hole (one of 320 triangles missing) stays a solid.
  geo::TriangleMesh holed = sphereMesh(1.0, 2);
  holed.triangles.pop_back();
  const SurfaceVerdict h = classifySurface(geo::MeshBvh(holed));
  EXPECT_EQ(h.kind, SurfaceVerdict::Kind::Solid) << h.describe();
  // A box with its top face missing (an open container) is a shell.
  geo::TriangleMesh open_box = boxMesh(Vec3(1, 1, 1));
  geo::TriangleMesh kept;
  kept.vertices = open_box.vertices;
  for (int t = 0; t < open_box.triangleCount(); ++t) {
    const bool top = open_box.vertex(t, 0).z() > 0 && open_box.vertex(t, 1).z() > 0 && open_box.vertex(t, 2).z() > 0;
    if (!top) kept.triangles.push_back(open_box.triangles[static_cast<size_t>(t)]);
  }
  ASSERT_EQ(kept.triangleCount(), 10);
  EXPECT_EQ(classifySurface(geo::MeshBvh(kept)).kind, SurfaceVerdict::Kind::Shell);
}

TEST(Surface, TheSceneLoaderMakesShellsAndTurnsInvertedMeshesOutward) {
  std::map<std::string, geo::TriangleMesh> files = {
      {"bowl.obj", bowl()}, {"inside-out.obj", flipped(sphereMesh(1.0, 2))}, {"ball.obj", sphereMesh(1.0, 2)}};
  const MeshLoader load = [&files](const std::string& path) { return files.at(path); };
  const Scene s = meshScene({parseMeshSpec("bowl.obj:0.2"), parseMeshSpec("inside-out.obj:0.2"), parseMeshSpec("ball.obj:0.2")},
                            Vec3::Zero(), load);
  ASSERT_EQ(s.objects.size(), 3u);
  const SceneObject& bowl_o = s.objects[0];
  EXPECT_FALSE(bowl_o.reference->solid());
  EXPECT_FALSE(bowl_o.god->solid());
  EXPECT_NE(bowl_o.surface_note.find("thin shell"), std::string::npos) << bowl_o.surface_note;
  // The cavity is not inside a shell.
  EXPECT_FALSE(bowl_o.reference->inside(Vec3(0, 0, -0.09)));
  const SceneObject& turned = s.objects[1];
  EXPECT_TRUE(turned.reference->solid());
  EXPECT_GT(signedVolume(turned.reference->mesh()), 0.0);
  EXPECT_TRUE(turned.reference->inside(Vec3::Zero()));
  EXPECT_NE(turned.surface_note.find("turned outward"), std::string::npos) << turned.surface_note;
  EXPECT_EQ(turned.physics.mesh.triangles, turned.reference->mesh().triangles);  // Bullet gets the same turn
  EXPECT_TRUE(s.objects[2].reference->solid());
  EXPECT_EQ(s.objects[2].surface_note.rfind("closed solid (", 0), 0u) << s.objects[2].surface_note;
  // A decimated God side of a shell is a shell too.
  MeshSpec dec = parseMeshSpec("bowl.obj:0.2");
  dec.god = parseGodFidelity("decimated:64");
  const Scene d = meshScene({dec}, Vec3::Zero(), load);
  EXPECT_NE(d.objects[0].god, d.objects[0].reference);
  EXPECT_FALSE(d.objects[0].god->solid());
}

TEST(Surface, PenetrationThroughAShellIsTheBoxsDepthThroughThePlane) {
  Scene scene;
  SceneObject o;
  o.id = "panel";
  o.index = 0;
  auto sheet = std::make_shared<geo::MeshBvh>(square(1.0));
  sheet->setSolid(false);
  o.god = sheet;
  o.reference = sheet;
  scene.objects.push_back(o);
  scene.god_triangles = 2;
  const CollisionWorld world(scene);
  Shape box;
  box.type = ShapeType::Box;
  box.half_extents = Vec3(0.02, 0.03, 0.01);
  // Analytic: a box whose centre is s above the plane, tilted by a about x, reaches
  // h = ex·0 + ey·|sin a| + ez·|cos a| along z; through the plane by h − |s| on its shallower side.
  const double a = 0.3;
  const double h = 0.03 * std::sin(a) + 0.01 * std::cos(a);
  for (const double s : {0.004, -0.006, 0.0}) {
    const Pose X{Vec3(0.1, -0.2, s), Quat(Eigen::AngleAxisd(a, Vec3::UnitX()))};
    EXPECT_NEAR(world.penetration(box, X), h - std::abs(s), 1e-12) << "s " << s;
  }
  // Apart from the sheet, and beside it (off its edge), nothing.
  EXPECT_EQ(world.penetration(box, Pose{Vec3(0.1, 0.2, h + 1e-4), Quat::Identity()}), 0.0);
  EXPECT_EQ(world.penetration(box, Pose{Vec3(1.2, 0.0, 0.0), Quat::Identity()}), 0.0);
  // A capsule standing across the sheet: its half length + radius minus |s|.
  Shape cap;
  cap.type = ShapeType::Capsule;
  cap.radius = 0.005;
  cap.half_length = 0.02;
  EXPECT_NEAR(world.penetration(cap, Pose{Vec3(0, 0, 0.01), Quat::Identity()}), 0.025 - 0.01, 1e-12);
}

TEST(Surface, ABodyInABowlsCavityIsNotInsideItsShell) {
  // The same bowl as a solid would put a body resting in its cavity 0.1 deep "inside" it.
  Scene scene;
  SceneObject o;
  o.id = "bowl";
  o.index = 0;
  auto shell = std::make_shared<geo::MeshBvh>(bowl());
  shell->setSolid(false);
  o.god = shell;
  o.reference = shell;
  scene.objects.push_back(o);
  scene.god_triangles = shell->triangleCount();
  Shape ball;
  ball.type = ShapeType::Sphere;
  ball.radius = 0.05;
  const Pose in_cavity{Vec3(0, 0, -0.5), Quat::Identity()};
  const CollisionWorld world(scene);
  EXPECT_EQ(world.penetration(ball, in_cavity), 0.0);
  auto solid = std::make_shared<geo::MeshBvh>(bowl());
  scene.objects[0].god = solid;
  scene.objects[0].reference = solid;
  const CollisionWorld as_solid(scene);
  EXPECT_GT(as_solid.penetration(ball, in_cavity), 0.1);
}

}  // namespace
}  // namespace godhand
