// Scene files (idl/scene.proto text): fields, defaults, sharing, every error with its line, the
// shipped scenes, and the benchmark's --mesh scenes.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <string>

#include <unistd.h>

#include "common/files.h"
#include "geometry/bvh.h"
#include "scene/mesh_io.h"
#include "scene/scene_file.h"

namespace godhand {
namespace {

namespace fs = std::filesystem;

const char* const kCubeObj =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
    "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 1 5 8 4\nf 2 3 7 6\n";

class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("godhand_scene_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    write("cube.obj", kCubeObj);
  }
  ~TempDir() { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) const {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

 private:
  fs::path dir_;
};

std::string sceneError(const TempDir& tmp, const std::string& text) {
  const std::string p = tmp.write("s.pbtxt", text);
  try {
    loadScene(p);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

void expectError(const TempDir& tmp, const std::string& text, const std::string& prefix, const std::string& what) {
  const std::string msg = sceneError(tmp, text);
  SCOPED_TRACE(text);
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  const std::string full = tmp.path("s.pbtxt") + ":" + prefix;
  EXPECT_EQ(msg.rfind(full, 0), 0u) << "got: " << msg << "\nexpected prefix: " << full;
  EXPECT_NE(msg.find(what), std::string::npos) << "got: " << msg << "\nexpected: " << what;
}

const SceneObject& byId(const Scene& s, const std::string& id) {
  for (const SceneObject& o : s.objects)
    if (o.id == id) return o;
  throw std::runtime_error("no object " + id);
}

/// World-aligned box of an object's God mesh at its initial pose.
geo::Aabb worldBox(const SceneObject& o) {
  geo::Aabb b;
  for (const Vec3& v : o.god->mesh().vertices) b.grow(o.X_WO * v);
  return b;
}

TEST(SceneFile, FieldsDefaultsAndSharing) {
  TempDir tmp;
  const std::string text = R"(
name: "unit"
objects { id: "static_cube" mesh: "cube.obj" }
objects { id: "dyn_cube" mesh: "cube.obj" mass: 2 friction: 0.9 restitution: 0.25
          position { x: 1 y: 2 z: 3 } orientation { w: 0 x: 0 y: 0 z: 2 } }
objects { id: "half" mesh: "cube.obj" size: 0.5 centre: true subdivide: 1 physics { fidelity: PRIMITIVE } }
objects { id: "hull" mesh: "cube.obj" scale: 2 god { fidelity: CONVEX_HULL } physics { fidelity: NONE } }
objects { id: "dec" mesh: "cube.obj" scale: 2 subdivide: 3 god { fidelity: DECIMATED target_triangles: 100 } }
objects { id: "bbox" mesh: "cube.obj" scale: 2 god { fidelity: PRIMITIVE } }
objects { id: "box" box { half_extents { x: 0.1 y: 0.2 z: 0.3 } } mass: 1 }
objects { id: "ball" sphere { radius: 0.05 } mass: 0.5 physics { fidelity: CONVEX_HULL } }
objects { id: "can" cylinder { radius: 0.02 half_height: 0.05 } physics { fidelity: TRIANGLE_MESH } }
objects { id: "ball2" sphere { radius: 0.05 } }
)";
  const Scene s = loadScene(tmp.write("scene.pbtxt", text));
  EXPECT_EQ(s.name, "unit");
  EXPECT_EQ(s.gravity, Vec3(0, 0, -9.81));
  ASSERT_EQ(s.objects.size(), 10u);
  for (size_t i = 0; i < s.objects.size(); ++i) EXPECT_EQ(s.objects[i].index, static_cast<int>(i));

  const SceneObject& sc = byId(s, "static_cube");
  EXPECT_EQ(sc.mass, 0.0);
  EXPECT_EQ(sc.friction, 0.5);
  EXPECT_EQ(sc.restitution, 0.0);
  EXPECT_EQ(sc.god, sc.reference);
  EXPECT_EQ(sc.god->triangleCount(), 12);
  EXPECT_EQ(sc.physics.type, PhysicsShapeType::TriangleMesh);
  EXPECT_EQ(sc.physics.mesh.triangleCount(), 12);
  EXPECT_EQ(sc.scale, 1.0);
  EXPECT_EQ(sc.source, tmp.path("cube.obj"));

  const SceneObject& dc = byId(s, "dyn_cube");
  EXPECT_EQ(dc.god, sc.god);  // same file, scale, fidelity: one BVH
  EXPECT_EQ(dc.physics.type, PhysicsShapeType::ConvexHull);
  EXPECT_EQ(dc.physics.points.size(), 8u);
  EXPECT_EQ(dc.mass, 2.0);
  EXPECT_EQ(dc.friction, 0.9);
  EXPECT_EQ(dc.restitution, 0.25);
  EXPECT_EQ(dc.X_WO.p, Vec3(1, 2, 3));
  EXPECT_NEAR(dc.X_WO.q.z(), 1.0, 1e-15);  // normalised

  const SceneObject& half = byId(s, "half");
  EXPECT_DOUBLE_EQ(half.scale, 0.5);
  EXPECT_EQ(half.translation, Vec3(-0.25, -0.25, -0.25));
  EXPECT_EQ(half.god->triangleCount(), 48);
  EXPECT_EQ(half.physics.type, PhysicsShapeType::Box);
  EXPECT_EQ(half.physics.half_extents, Vec3(0.25, 0.25, 0.25));
  EXPECT_EQ(half.god->bounds().lo, Vec3(-0.25, -0.25, -0.25));
  EXPECT_EQ(half.god->bounds().hi, Vec3(0.25, 0.25, 0.25));

  const SceneObject& hull = byId(s, "hull");
  EXPECT_NE(hull.god, hull.reference);
  EXPECT_EQ(hull.reference->triangleCount(), 12);
  EXPECT_NEAR(signedVolume(hull.god->mesh()), 8.0, 1e-12);
  EXPECT_EQ(hull.physics.type, PhysicsShapeType::None);

  const SceneObject& dec = byId(s, "dec");
  EXPECT_EQ(dec.reference->triangleCount(), 12 * 64);
  EXPECT_LT(dec.god->triangleCount(), 12 * 64);
  EXPECT_EQ(dec.physics.mesh.triangleCount(), 12);  // Bullet gets the unsubdivided surface

  const SceneObject& bbox = byId(s, "bbox");
  EXPECT_EQ(bbox.god->triangleCount(), 12);
  EXPECT_EQ(bbox.reference, hull.reference);  // same file and scale
  EXPECT_EQ(bbox.god->bounds().lo, Vec3(0, 0, 0));
  EXPECT_EQ(bbox.god->bounds().hi, Vec3(2, 2, 2));

  const SceneObject& box = byId(s, "box");
  EXPECT_EQ(box.physics.type, PhysicsShapeType::Box);
  EXPECT_EQ(box.physics.half_extents, Vec3(0.1, 0.2, 0.3));
  EXPECT_EQ(box.god->triangleCount(), 12);
  EXPECT_EQ(box.god, box.reference);

  const SceneObject& ball = byId(s, "ball");
  EXPECT_EQ(ball.physics.type, PhysicsShapeType::ConvexHull);
  EXPECT_EQ(ball.physics.points.size(), ball.god->mesh().vertices.size());
  EXPECT_EQ(ball.god->triangleCount(), 1280);
  EXPECT_EQ(byId(s, "ball2").god, ball.god);  // identical primitives share
  EXPECT_EQ(byId(s, "ball2").physics.type, PhysicsShapeType::Sphere);
  EXPECT_EQ(byId(s, "ball2").physics.radius, 0.05);

  const SceneObject& can = byId(s, "can");
  EXPECT_EQ(can.physics.type, PhysicsShapeType::TriangleMesh);
  EXPECT_EQ(can.physics.mesh.triangleCount(), 128);

  long long god = 0, ref = 0;
  for (const SceneObject& o : s.objects) { god += o.god->triangleCount(); ref += o.reference->triangleCount(); }
  EXPECT_EQ(s.god_triangles, god);
  EXPECT_EQ(s.reference_triangles, ref);
}

TEST(SceneFile, ErrorsNameFileLineAndField) {
  TempDir tmp;
  const std::string ok = "objects { id: \"t\" box { half_extents { x: 1 y: 1 z: 1 } } }\n";
  expectError(tmp, "objects {\n  id: \"a\"\n  box { half_extents { x: 1 y: 1 z: 1 } }\n  mass: -1\n}\n",
              "4: objects[0].mass: ", "mass must lie in [0, 1e6] kg");
  expectError(tmp, "objects {\n  id: \"a\"\n  box { half_extents { x: 1 y: 1 z: 1 } }\n  mass: nan\n}\n",
              "4: objects[0].mass: ", "mass");
  expectError(tmp, ok + "objects {\n  id: \"t\"\n  sphere { radius: 1 }\n}\n",
              "3: objects[1].id: ", "duplicate object id 't'");
  expectError(tmp, ok + "objects {\n  id: \"m\"\n\n  mesh: \"missing.obj\"\n}\n",
              "5: objects[1].mesh: " + tmp.path("missing.obj") + ":0: ", "cannot open mesh file");
  expectError(tmp, "objects {\n  id: \"d\"\n  mesh: \"cube.obj\"\n  mass: 1\n  physics { fidelity: TRIANGLE_MESH }\n}\n",
              "5: objects[0].physics: ", "static objects only");
  expectError(tmp, "objects {\n  id: \"d\"\n  mesh: \"cube.obj\"\n  mass: 1\n  physics { fidelity: NONE }\n}\n",
              "5: objects[0].physics: ", "needs a physics shape");
  expectError(tmp, "objects {\n  id: \"q\"\n  box { half_extents { x: 1 y: 1 z: 1 } }\n  orientation { w: 0 }\n}\n",
              "4: objects[0].orientation: ", "non-zero quaternion");
  expectError(tmp, "objects {\n  id: \"q\"\n  box { half_extents { x: 1 y: 1 z: 1 } }\n  orientation { w: inf }\n}\n",
              "4: objects[0].orientation: ", "finite");
  expectError(tmp, "objects {\n  id: \"b\"\n  box { half_extents { x: 1 y: 0 z: 1 } }\n}\n",
              "3: objects[0].box: ", "half_extents");
  expectError(tmp, "objects {\n  id: \"b\"\n  sphere { radius: -1 }\n}\n", "3: objects[0].sphere: ", "radius");
  expectError(tmp, "objects {\n  id: \"b\"\n  cylinder { radius: 1 }\n}\n", "3: objects[0].cylinder: ", "half_height");
  expectError(tmp, "objects {\n  id: \"b\"\n  sphere { radius: 1 }\n  scale: 2\n}\n", "4: objects[0].scale: ", "mesh objects only");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  size: -2\n}\n", "4: objects[0].size: ", "size must lie");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  scale: 0\n}\n", "4: objects[0].scale: ", "scale must lie");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  subdivide: 9\n}\n", "4: objects[0].subdivide: ", "limit");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  god { fidelity: DECIMATED }\n}\n",
              "4: objects[0].god: ", "target_triangles in [4, 100000000]");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  god { fidelity: DECIMATED target_triangles: 4000000000 }\n}\n",
              "4: objects[0].god: ", "got 4000000000");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  god { fidelity: 42 }\n}\n", "4: objects[0].god: ",
              "unknown fidelity 42");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  physics { fidelity: 9 }\n}\n", "4: objects[0].physics: ",
              "unknown fidelity 9");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  physics { fidelity: PRIMITIVE }\n}\n",
              "4: objects[0].physics: ", "centre: true");
  expectError(tmp, "objects {\n  id: \"b\"\n  box { half_extents { x: 1 y: 1 z: 1 } }\n  restitution: 2\n}\n",
              "4: objects[0].restitution: ", "[0, 1]");
  expectError(tmp, "objects {\n  id: \"b\"\n  box { half_extents { x: 1 y: 1 z: 1 } }\n  position { x: nan }\n}\n",
              "4: objects[0].position: ", "finite");
  expectError(tmp, ok + "\nobjects {\n  id: \"nothing\"\n  mass: 1\n}\n", "3: objects[1]: ", "has no geometry");
  expectError(tmp, "objects {\n  box { half_extents { x: 1 y: 1 z: 1 } }\n}\n", "1: objects[0].id: ", "needs an id");
  expectError(tmp, "name: \"x\"\n", "1: objects: ", "at least one object");
  expectError(tmp, "gravity { z: nan }\n" + ok, "1: gravity: ", "finite");
  expectError(tmp, "gravity { z: -1e300 }\n" + ok, "1: gravity: ", "at most 1000");
  expectError(tmp, ok + "objects {\n  id: \"x\"\n  mas: 1\n}\n", "4:", "no field named \"mas\"");  // protobuf syntax error: line:column
  tmp.write("nan.obj", "v 0 0 0\nv 0 nan 0\nv 0 0 1\nf 1 2 3\n");
  expectError(tmp, "objects {\n  id: \"n\"\n  mesh: \"nan.obj\"\n}\n",
              "3: objects[0].mesh: " + tmp.path("nan.obj") + ":2: ", "non-finite");
  // A missing scene file.
  try {
    loadScene(tmp.path("none.pbtxt"));
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), tmp.path("none.pbtxt") + ":0: cannot open scene file");
  }
}

TEST(SceneFile, CommittedBadSceneReportsItsLine) {
  try {
    loadScene(std::string(GODHAND_TEST_DATA_DIR) + "/scene/bad_mass.pbtxt");
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("bad_mass.pbtxt:8: objects[1].mass: mass must lie in [0, 1e6] kg"), std::string::npos) << e.what();
  }
}

TEST(SceneFile, MeshesComeThroughTheLoaderOnly) {
  // core opens no files: parseScene gets its meshes from the MeshLoader it is given, once per
  // path (joined to base_dir, lexically normal), and a loader's MeshError carries the scene
  // location as the file loader's does.
  std::map<std::string, int> calls;
  const MeshLoader memory = [&](const std::string& path) {
    ++calls[path];
    if (path != "/virtual/meshes/cube.obj") throw MeshError(path + ":0: cannot open mesh file: no such file");
    return parseMeshFile(kCubeObj, path);
  };
  const Scene s = parseScene("objects { id: \"a\" mesh: \"meshes/cube.obj\" }\n"
                             "objects { id: \"b\" mesh: \"./meshes/../meshes/cube.obj\" scale: 2 }\n"
                             "objects { id: \"c\" mesh: \"/virtual/meshes/cube.obj\" }\n",
                             "mem.pbtxt", "/virtual", memory);
  ASSERT_EQ(s.objects.size(), 3u);
  EXPECT_EQ(s.name, "mem");
  EXPECT_EQ(calls, (std::map<std::string, int>{{"/virtual/meshes/cube.obj", 1}}));
  EXPECT_EQ(byId(s, "a").source, "/virtual/meshes/cube.obj");
  EXPECT_EQ(byId(s, "a").god, byId(s, "c").god);  // same path and scale: one BVH
  EXPECT_NE(byId(s, "a").god, byId(s, "b").god);
  EXPECT_EQ(byId(s, "b").god->bounds().hi, Vec3(2, 2, 2));
  try {
    parseScene("objects {\n  id: \"m\"\n  mesh: \"gone.obj\"\n}\n", "mem.pbtxt", "/virtual", memory);
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), "mem.pbtxt:3: objects[0].mesh: /virtual/gone.obj:0: cannot open mesh file: no such file");
  }
}

TEST(ShippedScenes, DefaultSceneLoadsWithAbout100kTriangles) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene s = loadScene(std::string(GODHAND_DEPLOY_DIR) + "/scenes/default.pbtxt");
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[figure] default scene: %zu objects, %lld God triangles, %lld reference triangles, load %.0f ms\n",
              s.objects.size(), s.god_triangles, s.reference_triangles, ms);
  for (const SceneObject& o : s.objects) {
    const geo::Aabb b = worldBox(o);
    std::printf("[figure]   %-12s mass %.2f kg  god %6d tri  ref %6d tri  physics %d  world box [%.3f %.3f %.3f]..[%.3f %.3f %.3f]\n",
                o.id.c_str(), o.mass, o.god->triangleCount(), o.reference->triangleCount(), static_cast<int>(o.physics.type),
                b.lo.x(), b.lo.y(), b.lo.z(), b.hi.x(), b.hi.y(), b.hi.z());
  }
  EXPECT_EQ(s.name, "default");
  ASSERT_EQ(s.objects.size(), 8u);
  EXPECT_GT(s.god_triangles, 90000);
  EXPECT_LT(s.god_triangles, 110000);
  EXPECT_EQ(byId(s, "fandisk").god, byId(s, "fandisk_2").god);
  EXPECT_EQ(byId(s, "bunny").god, byId(s, "bunny").reference);
  EXPECT_NEAR(byId(s, "small_bunny").god->triangleCount(), 5000, 1000);
  EXPECT_EQ(byId(s, "table").physics.type, PhysicsShapeType::Box);
  EXPECT_EQ(byId(s, "bunny").physics.type, PhysicsShapeType::TriangleMesh);
  EXPECT_EQ(byId(s, "small_bunny").physics.type, PhysicsShapeType::ConvexHull);
  EXPECT_EQ(byId(s, "light_box").physics.type, PhysicsShapeType::Box);
  EXPECT_EQ(byId(s, "ball").physics.type, PhysicsShapeType::Sphere);
  EXPECT_EQ(byId(s, "can").physics.type, PhysicsShapeType::Cylinder);
  EXPECT_NEAR(byId(s, "fandisk").god->bounds().extent().maxCoeff(), 0.15, 1e-12);

  // Everything rests on the table top (z = 0.11), inside its footprint, without overlaps.
  const geo::Aabb table = worldBox(byId(s, "table"));
  EXPECT_NEAR(table.hi.z(), 0.11, 1e-12);
  for (const SceneObject& o : s.objects) {
    if (o.id == "table") continue;
    const geo::Aabb b = worldBox(o);
    EXPECT_NEAR(b.lo.z(), 0.11, 1e-3) << o.id;
    EXPECT_GE(b.lo.z(), 0.11 - 0.006 * 0.03) << o.id;  // tessellations enclose: the ball's is 0.45 % larger
    EXPECT_TRUE((b.lo.head<2>().array() >= table.lo.head<2>().array()).all() && (b.hi.head<2>().array() <= table.hi.head<2>().array()).all()) << o.id;
    for (const SceneObject& q : s.objects)
      if (q.index > o.index && q.id != "table") {
        EXPECT_FALSE(b.overlaps(worldBox(q))) << o.id << " overlaps " << q.id;
      }
  }
  // A ring around the recorded single-hand envelope (pinch, HandSplay: palm and every finger
  // joint over all frames, converted to metres, +Z up), inflated by 1 cm for the hand's radii:
  // no object but the table inside it (the recorded fingertips reach down to the table top and
  // press on it), the meshes within 3 cm of it.
  geo::Aabb hand;
  hand.grow(Vec3(-0.084, -0.102, 0.107));
  hand.grow(Vec3(0.115, 0.090, 0.230));
  hand = hand.inflated(0.01);
  for (const SceneObject& o : s.objects) {
    if (o.id != "table") {
      EXPECT_FALSE(worldBox(o).overlaps(hand)) << o.id;
    }
  }
  EXPECT_TRUE(table.overlaps(hand));
  for (const char* id : {"bunny", "fandisk", "fandisk_2"}) EXPECT_TRUE(worldBox(byId(s, id)).overlaps(hand.inflated(0.03))) << id;
}

TEST(ShippedScenes, StressSceneLoadsWithAbout1MTriangles) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene s = loadScene(std::string(GODHAND_DEPLOY_DIR) + "/scenes/stress.pbtxt");
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[figure] stress scene: %zu objects, %lld God triangles, load %.0f ms (parse, subdivide, BVH build)\n",
              s.objects.size(), s.god_triangles, ms);
  EXPECT_GT(s.god_triangles, 1000000);
  EXPECT_LT(s.god_triangles, 1200000);
  EXPECT_EQ(byId(s, "bunny").physics.mesh.triangleCount() * 16, byId(s, "bunny").god->triangleCount());
}

TEST(MeshScene, ScalesAndCentresExactly) {
  const std::string bunny = std::string(GODHAND_DEPLOY_DIR) + "/meshes/stanford-bunny.obj";
  const std::string fandisk = std::string(GODHAND_DEPLOY_DIR) + "/meshes/fandisk.obj";
  const Vec3 centre(0.1, -0.2, 0.3);
  const Scene s = meshScene({parseMeshSpec(bunny + ":0.2"), parseMeshSpec(bunny + ":0.2"), parseMeshSpec(fandisk)}, centre,
                            meshFileLoader());
  ASSERT_EQ(s.objects.size(), 3u);
  EXPECT_EQ(s.objects[0].id, "stanford-bunny");
  EXPECT_EQ(s.objects[1].id, "stanford-bunny_2");
  EXPECT_EQ(s.objects[2].id, "fandisk");
  EXPECT_EQ(s.objects[0].god, s.objects[1].god);
  const double sizes[3] = {0.2, 0.2, 0.15};
  for (size_t i = 0; i < 3; ++i) {
    const SceneObject& o = s.objects[i];
    const geo::Aabb b = worldBox(o);
    EXPECT_NEAR((b.centre() - centre).norm(), 0.0, 1e-15) << o.id;
    EXPECT_NEAR(b.extent().maxCoeff(), sizes[i], 1e-15) << o.id;
    EXPECT_EQ(o.mass, 0.0);
    EXPECT_EQ(o.god, o.reference);
    EXPECT_EQ(o.physics.type, PhysicsShapeType::TriangleMesh);
    EXPECT_EQ(o.X_WO.p, centre);
    // vertex_W = X_WO * (scale * v_file + translation)
    const geo::TriangleMesh raw = loadMeshFile(i < 2 ? bunny : fandisk);
    EXPECT_NEAR((o.god->mesh().vertices[5] - (o.scale * raw.vertices[5] + o.translation)).norm(), 0.0, 1e-15);
    std::printf("[figure] --mesh %s: scale %.6g, translation (%.6g, %.6g, %.6g), %d triangles\n", o.id.c_str(), o.scale,
                o.translation.x(), o.translation.y(), o.translation.z(), o.god->triangleCount());
  }
  EXPECT_EQ(s.god_triangles, 2LL * s.objects[0].god->triangleCount() + s.objects[2].god->triangleCount());
  // A mesh given a position goes there, exactly; the others still take the centre.
  const Vec3 there(1.5, 0.25, -0.75);
  MeshSpec at = parseMeshSpec(fandisk + ":0.2");
  at.at = there;
  const Scene t = meshScene({parseMeshSpec(bunny + ":0.2"), at}, centre, meshFileLoader());
  EXPECT_NEAR((worldBox(t.objects[0]).centre() - centre).norm(), 0.0, 1e-15);
  EXPECT_NEAR((worldBox(t.objects[1]).centre() - there).norm(), 0.0, 1e-15);
  EXPECT_NEAR(worldBox(t.objects[1]).extent().maxCoeff(), 0.2, 1e-15);
  try {
    meshScene({parseMeshSpec("/nonexistent/x.obj:0.1")}, centre, meshFileLoader());
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/nonexistent/x.obj:0: cannot open mesh file", 0), 0u) << e.what();
  }
}

TEST(MeshScene, GodFidelityChangesTheGodSideOnly) {
  EXPECT_EQ(parseGodFidelity("full").kind, GodFidelity::Kind::Full);
  EXPECT_EQ(parseGodFidelity("HULL").kind, GodFidelity::Kind::Hull);
  EXPECT_EQ(parseGodFidelity("decimated:500").kind, GodFidelity::Kind::Decimated);
  EXPECT_EQ(parseGodFidelity("decimated:500").target_triangles, 500);
  EXPECT_EQ(parseGodFidelity("auto:1.5").kind, GodFidelity::Kind::Auto);
  EXPECT_DOUBLE_EQ(parseGodFidelity("auto:1.5").tolerance_m, 1.5e-3);
  for (const char* bad : {"decimated:3", "decimated:", "decimated:5x", "decimated:-8", "decimated:5.5", "half", "", "auto:", "auto:0", "auto:-1", "auto:nan"}) {
    try {
      parseGodFidelity(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("expected full, hull, decimated:N"), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
  const std::string fandisk = std::string(GODHAND_DEPLOY_DIR) + "/meshes/fandisk.obj";
  const Vec3 centre(0.0, 0.0, 0.1);
  MeshSpec full = parseMeshSpec(fandisk + ":0.2"), dec = full, hull = full;
  dec.god = parseGodFidelity("decimated:1000");
  hull.god = parseGodFidelity("hull");
  const Scene s = meshScene({full, dec, hull}, centre, meshFileLoader());
  ASSERT_EQ(s.objects.size(), 3u);
  const geo::MeshBvh& ref = *s.objects[0].reference;
  for (const SceneObject& o : s.objects) {
    // The penetration figure's reference is the full mesh whatever the God side sees.
    EXPECT_EQ(o.reference->triangleCount(), ref.triangleCount()) << o.id;
    EXPECT_EQ(o.reference->mesh().vertices, ref.mesh().vertices) << o.id;
    EXPECT_EQ(o.physics.type, PhysicsShapeType::TriangleMesh);
  }
  EXPECT_EQ(s.objects[0].god, s.objects[0].reference);
  const geo::MeshBvh& d = *s.objects[1].god;
  EXPECT_LT(d.triangleCount(), 1300);
  EXPECT_GT(d.triangleCount(), 200);
  // Vertex clustering averages vertices: the decimated mesh stays within the full mesh's box.
  const geo::Aabb box = meshBounds(ref.mesh());
  for (const Vec3& v : d.mesh().vertices)
    EXPECT_TRUE((v.array() >= box.lo.array() - 1e-12).all() && (v.array() <= box.hi.array() + 1e-12).all());
  // The hull encloses every vertex of the full mesh (brute force over its faces).
  const geo::TriangleMesh& h = s.objects[2].god->mesh();
  Vec3 c = Vec3::Zero();
  for (const Vec3& v : h.vertices) c += v;
  c /= static_cast<double>(h.vertices.size());
  double worst = -1.0;
  for (const auto& t : h.triangles) {
    const Vec3 a = h.vertices[static_cast<size_t>(t[0])], b = h.vertices[static_cast<size_t>(t[1])], e = h.vertices[static_cast<size_t>(t[2])];
    Vec3 n = (b - a).cross(e - a);
    if (n.norm() < 1e-18) continue;
    n.normalize();
    if (n.dot(c - a) > 0.0) n = -n;
    for (const Vec3& v : ref.mesh().vertices) worst = std::max(worst, n.dot(v - a));
  }
  EXPECT_LE(worst, 1e-9) << "a full-mesh vertex outside the hull";
  std::printf("[figure] fandisk god side: full %d, decimated:1000 %d, hull %d triangles; max vertex beyond the hull %.2e m\n",
              ref.triangleCount(), d.triangleCount(), s.objects[2].god->triangleCount(), worst);
}

TEST(SceneFile, AutoFidelityPicksTheCoarsestWithinTheTolerance) {
  TempDir tmp;
  const std::string fandisk = std::string(GODHAND_DEPLOY_DIR) + "/meshes/fandisk.obj";
  auto object = [&](const std::string& id, const std::string& god) {
    return "objects { id: \"" + id + "\" mesh: \"" + fandisk + "\" size: 0.2 centre: true god { " + god + " } }\n";
  };
  const Scene s = loadScene(tmp.write("auto.pbtxt", object("full", "fidelity: FULL") + object("auto5", "fidelity: AUTO tolerance_mm: 5") +
                                                        object("auto_tiny", "fidelity: AUTO tolerance_mm: 0.001") +
                                                        "objects { id: \"ball\" sphere { radius: 0.05 } god { fidelity: AUTO } }\n"));
  const SceneObject& full = byId(s, "full");
  const SceneObject& a2 = byId(s, "auto5");
  const SceneObject& tiny = byId(s, "auto_tiny");
  EXPECT_EQ(full.god_skin, 0.0);
  EXPECT_TRUE(full.god_note.empty());
  // AUTO 5 mm: a coarser God side, its skin within the tolerance and covering the full surface:
  // every vertex and triangle centroid of the full mesh within the skin of the God mesh, by brute
  // force over every God triangle (no BVH, not the bound the choice was made with).
  EXPECT_LT(a2.god->triangleCount(), full.god->triangleCount());
  EXPECT_GT(a2.god_skin, 0.0);
  EXPECT_LE(a2.god_skin, 0.005);
  EXPECT_EQ(a2.reference->triangleCount(), full.god->triangleCount());
  const geo::TriangleMesh& ref = a2.reference->mesh();
  const geo::TriangleMesh& god = a2.god->mesh();
  std::vector<Vec3> samples = ref.vertices;
  for (int t = 0; t < ref.triangleCount(); ++t)
    samples.push_back((ref.vertex(t, 0) + ref.vertex(t, 1) + ref.vertex(t, 2)) / 3.0);
  double farthest = 0.0;
  for (const Vec3& q : samples) {
    double d = std::numeric_limits<double>::infinity();
    for (int t = 0; t < god.triangleCount() && d > farthest; ++t)
      d = std::min(d, geo::pointTriangleDistance(q, god.vertex(t, 0), god.vertex(t, 1), god.vertex(t, 2), nullptr));
    farthest = std::max(farthest, d);
  }
  std::printf("[figure] AUTO 5 mm on the fandisk: %d of %d triangles, skin %.2f mm, full surface at most %.2f mm off "
              "(brute force, %zu points)\n", a2.god->triangleCount(), full.god->triangleCount(), a2.god_skin * 1e3,
              farthest * 1e3, samples.size());
  EXPECT_LE(farthest, a2.god_skin);
  EXPECT_EQ(a2.god_note.rfind("AUTO 5 mm: ", 0), 0u) << a2.god_note;
  EXPECT_NE(a2.god_note.find("God objects grown by"), std::string::npos) << a2.god_note;
  // Nothing coarser within 1 µm: the full mesh, no skin, and the report says why.
  EXPECT_EQ(tiny.god, tiny.reference);
  EXPECT_EQ(tiny.god_skin, 0.0);
  EXPECT_NE(tiny.god_note.find("no coarser level is within it"), std::string::npos) << tiny.god_note;
  // A primitive's tessellation is what it gets.
  EXPECT_EQ(byId(s, "ball").god_skin, 0.0);
  EXPECT_NE(byId(s, "ball").god_note.find("primitive"), std::string::npos);
  // Validation.
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  god { fidelity: AUTO tolerance_mm: -1 }\n}\n",
              "4: objects[0].god: ", "tolerance_mm in (0, 1000]");
  expectError(tmp, "objects {\n  id: \"b\"\n  mesh: \"cube.obj\"\n  god { fidelity: FULL tolerance_mm: 1 }\n}\n",
              "4: objects[0].god: ", "tolerance_mm applies to AUTO only");
}

// godhand-bench --god-fidelity over a scene file: every mesh object's God side is the one given
// instead of the file's `god`; the reference (penetration) stays the full mesh, primitives keep
// their tessellation, and AUTO gives the same choice as the file's own AUTO of that tolerance.
TEST(SceneFile, GodFidelityGivenInsteadAppliesToMeshObjectsOnly) {
  TempDir tmp;
  const std::string fandisk = std::string(GODHAND_DEPLOY_DIR) + "/meshes/fandisk.obj";
  const std::string text = "objects { id: \"fan\" mesh: \"" + fandisk + "\" size: 0.2 centre: true }\n"
                           "objects { id: \"auto\" mesh: \"" + fandisk + "\" size: 0.2 centre: true god { fidelity: AUTO tolerance_mm: 5 } }\n"
                           "objects { id: \"box\" box { half_extents { x: 0.1 y: 0.1 z: 0.1 } } }\n";
  const std::string file = tmp.write("over.pbtxt", text);
  const Scene plain = loadScene(file);
  const GodFidelity hull = parseGodFidelity("hull"), auto5 = parseGodFidelity("auto:5");
  const Scene hulls = loadScene(file, &hull), autos = loadScene(file, &auto5);
  for (const char* id : {"fan", "auto"}) {
    EXPECT_LT(byId(hulls, id).god->triangleCount(), byId(plain, "fan").god->triangleCount()) << id;
    EXPECT_EQ(byId(hulls, id).god_skin, 0.0) << id << ": a hull encloses: no skin";
    EXPECT_EQ(byId(hulls, id).reference->triangleCount(), byId(plain, "fan").reference->triangleCount()) << id;
    EXPECT_EQ(byId(autos, id).god->triangleCount(), byId(plain, "auto").god->triangleCount()) << id;
    EXPECT_EQ(byId(autos, id).god_skin, byId(plain, "auto").god_skin) << id;
    EXPECT_EQ(byId(autos, id).god_note, byId(plain, "auto").god_note) << id;
  }
  EXPECT_EQ(byId(hulls, "box").god->triangleCount(), 12);
  EXPECT_EQ(byId(autos, "box").god_skin, 0.0);
  GodFidelity bad;
  bad.kind = GodFidelity::Kind::Decimated;
  bad.target_triangles = 2;
  try {
    loadScene(file, &bad);
    ADD_FAILURE() << "a decimation to 2 triangles was accepted";
  } catch (const SceneError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("objects[0].god: (the --god-fidelity given instead) decimation needs >= 4 triangles"), std::string::npos)
        << what;
  }
}

TEST(MeshScene, ParseMeshSpec) {
  EXPECT_EQ(parseMeshSpec("a.obj").path, "a.obj");
  EXPECT_EQ(parseMeshSpec("a.obj").size, 0.15);
  EXPECT_EQ(parseMeshSpec("dir/a.stl:0.2").path, "dir/a.stl");
  EXPECT_EQ(parseMeshSpec("dir/a.stl:0.2").size, 0.2);
  EXPECT_EQ(parseMeshSpec("x:y/a.obj").path, "x:y/a.obj");
  EXPECT_EQ(parseMeshSpec("odd:name.OBJ").path, "odd:name.OBJ");
  EXPECT_EQ(parseMeshSpec("a.obj:1e-1").size, 0.1);
  // "@X,Y,Z": where the mesh's centre goes; a path that merely contains '@' stays a path.
  const MeshSpec placed = parseMeshSpec("dir/a.obj:0.25@0.5,-1,2e-1");
  EXPECT_EQ(placed.path, "dir/a.obj");
  EXPECT_EQ(placed.size, 0.25);
  ASSERT_TRUE(placed.at.has_value());
  EXPECT_EQ(*placed.at, Vec3(0.5, -1.0, 0.2));
  EXPECT_EQ(*parseMeshSpec("a.obj@0,0,1").at, Vec3(0, 0, 1));
  EXPECT_EQ(parseMeshSpec("a.obj@0,0,1").size, 0.15);
  EXPECT_FALSE(parseMeshSpec("a.obj:0.2").at.has_value());
  EXPECT_EQ(parseMeshSpec("me@lab/a.obj").path, "me@lab/a.obj");
  EXPECT_EQ(parseMeshSpec("scan@1,2,3.obj").path, "scan@1,2,3.obj");  // three words, not three numbers
  EXPECT_FALSE(parseMeshSpec("scan@1,2,3.obj").at.has_value());
  EXPECT_FALSE(parseMeshSpec("me@lab/a.obj").at.has_value());
  for (const char* bad : {"a.obj:abc", "a.obj:", "a.obj:-1", "a.obj:0", "a.obj:0.2x", "a.obj:nan", ":0.2", "",
                          "a.obj@1,2", "a.obj@1,2,3,4", "a.obj:0.2@1,,3", "a.obj@1e9,0,0", "a.obj@-", "@1,2,3"}) {
    try {
      parseMeshSpec(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("--mesh"), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
  // A position that is not finite is refused as a position (was taken for part of the file name:
  // "cannot open mesh file").
  for (const char* bad : {"a.obj@nan,0,0", "a.obj:0.2@0,inf,0", "a.obj@0,0,-inf"}) {
    try {
      parseMeshSpec(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("must be three finite numbers"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace godhand
