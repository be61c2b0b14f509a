// Plausibility of the God-hand motion (issue 10, METHOD.md §5): the hand stays outside AND
// follows, slides, lifts off. Real BVHs, real sweeps, the real pipeline. Oracles: analytic
// geometry (a plane, a cylinder, a wedge) evaluated by brute force at the bodies' extreme points,
// the free twin (the same model and targets in an empty scene), the analytic excess lag.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "common/files.h"
#include "geometry/bvh.h"
#include "leap/leap_recording.h"
#include "leap/retarget.h"
#include "pipeline/collision_world.h"
#include "pipeline/pipeline.h"
#include "pipeline/run_metrics.h"
#include "scene/mesh_io.h"
#include "scene/scene.h"
#include "scene/scene_file.h"
#include "probe_model.h"

namespace godhand {
namespace {

HandModel bodyModel(const std::string& shape_text, double mass = 0.05) { return testing::probeModel(shape_text, mass); }

SceneObject meshObject(const std::string& id, geo::TriangleMesh mesh, const Pose& X_WO) {
  SceneObject o;
  o.id = id;
  o.X_WO = X_WO;
  o.mass = 0.0;
  o.god = std::make_shared<geo::MeshBvh>(std::move(mesh));
  o.reference = o.god;
  o.physics.type = PhysicsShapeType::None;
  o.source = id;
  return o;
}

Scene sceneOf(std::vector<SceneObject> objects) {
  Scene s;
  s.name = "test";
  for (SceneObject& o : objects) {
    o.index = static_cast<int>(s.objects.size());
    s.god_triangles += o.god->triangleCount();
    s.objects.push_back(std::move(o));
  }
  return s;
}

Pose at(double x, double y, double z, const Quat& q = Quat::Identity()) { return Pose{Vec3(x, y, z), q}; }
Quat aboutY(double a) { return Quat(Eigen::AngleAxisd(a, Vec3::UnitY())); }

PipelineParams params(double dt) {
  PipelineParams p;
  p.step.dt = dt;
  p.simulate = false;
  return p;
}

// Lowest point (world z) of a box / capsule / sphere: brute force over its extreme points.
double lowestZ(const Shape& s, const Pose& X) {
  const Mat3 R = X.q.toRotationMatrix();
  switch (s.type) {
    case ShapeType::Box: {
      double z = 1e9;
      for (int k = 0; k < 8; ++k)
        z = std::min(z, (X.p + R * Vec3((k & 1) ? 1 : -1, (k & 2) ? 1 : -1, (k & 4) ? 1 : -1).cwiseProduct(s.half_extents)).z());
      return z;
    }
    case ShapeType::Capsule:
      return X.p.z() - std::abs(R.col(2).z()) * s.half_length - s.radius;
    case ShapeType::Sphere:
      return X.p.z() - s.radius;
  }
  return 0.0;
}

// A box slides along a plane while its target turns about a tangential axis, rocking on its
// trailing bottom edge (the target itself just clears the plane): the God box follows the slide
// and the turn (no artificial friction, no freeze) and no corner ever goes below the plane.
TEST(Plausibility, BoxSlidesAndTurnsAboutATangentialAxisOnAPlane) {
  const double top = 0.0;
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(1.0, 1.0, 0.05)), at(0, 0, top - 0.05))});
  const HandModel m = bodyModel("box { half_extents { x: 0.03 y: 0.02 z: 0.01 } }");
  Pipeline pipe(scene, {&m}, params(1.0 / 100));
  const Shape& s = m.bodies[0].shape;
  double worst_follow = 0.0, worst_low = 1e9;
  for (int k = 0; k <= 120; ++k) {
    const double x = 0.002 * k;                          // 20 cm/s along +x
    const double phi = 0.25 * std::sin(0.05 * k);        // rocks about y by up to 0.25 rad
    // Pivot about the bottom edge that the tilt lowers (R_y(φ > 0) lowers +x), 0.3 mm above.
    const double ex = phi >= 0 ? 0.03 : -0.03;
    // 50 µm: inside the 0.1 mm contact margin, so the plane's rows are active all along.
    const Vec3 pivot(x + ex, 0.0, top + 5e-5);
    const Mat3 R = aboutY(phi).toRotationMatrix();
    const Pose target{pivot + R * Vec3(-ex, 0.0, 0.01), aboutY(phi)};
    ASSERT_GE(lowestZ(s, target), top + 5e-5 - 1e-12);  // the target is free (by construction)
    const std::vector<HandInput> in{{true, &target, nullptr}};
    pipe.step(in);
    const Pose& X = pipe.poses(0)[0];
    worst_low = std::min(worst_low, lowestZ(s, X));
    if (k > 3) worst_follow = std::max(worst_follow, (X.p - target.p).norm() + 0.03 * X.q.angularDistance(target.q));
  }
  std::printf("[figure] box sliding + rocking on a plane: lowest corner %.3g m above, follow error max %.3g m\n",
              worst_low - top, worst_follow);
  EXPECT_GE(worst_low, top - 1e-9) << "a corner went through the plane";
  EXPECT_LT(worst_follow, 1e-3) << "the box did not follow its free target along the plane";
}

// A palm-sized box pressed onto a finely tessellated bumpy plate (bumps 0.4 mm high every 2 cm,
// 2 mm triangles; target 5 mm below the plate, sliding and turning): the box rests on a few bump
// tops at once and slides over them. Oracles: no vertex of the plate inside the box, the exact
// reference penetration 0 every frame, and the target (followed within 2 mm sideways); the depth of
// the box's bottom face below the smooth height field at a 21 x 21 grid is printed.
// The rounds and the second solves after a hit are printed: most rounds here are solved twice
// (the closest points of the box's parts find one bump; it tilts onto another), with or without
// the 0.3 mm shell's triangles as candidates for a box (tried: no fewer).
TEST(Plausibility, APalmSlidesAndTurnsOverABumpyPlate) {
  const double amp = 2e-4, wave = 0.02, cell = 0.002, half = 0.15;
  auto height = [&](double x, double y) { return amp * (1.0 + std::sin(2 * M_PI * x / wave) * std::sin(2 * M_PI * y / wave)); };
  geo::TriangleMesh plate;
  const int n = static_cast<int>(2 * half / cell);
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      const double x = -half + i * cell, y = -half + j * cell;
      plate.vertices.push_back(Vec3(x, y, height(x, y)));
    }
  auto vid = [&](int i, int j) { return i * (n + 1) + j; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      plate.triangles.push_back({vid(i, j), vid(i + 1, j), vid(i + 1, j + 1)});
      plate.triangles.push_back({vid(i, j), vid(i + 1, j + 1), vid(i, j + 1)});
    }
  // Closed below: a floor 5 cm down, joined to the rim (the God side needs a solid).
  const int base = static_cast<int>(plate.vertices.size());
  for (const Vec3& c : {Vec3(-half, -half, -0.05), Vec3(half, -half, -0.05), Vec3(half, half, -0.05), Vec3(-half, half, -0.05)})
    plate.vertices.push_back(c);
  plate.triangles.push_back({base, base + 2, base + 1});
  plate.triangles.push_back({base, base + 3, base + 2});
  for (int k = 0; k < n; ++k) {
    // rim y = -half (j = 0), x = +half (i = n), y = +half (j = n), x = -half (i = 0)
    plate.triangles.push_back({vid(k, 0), base, base + 1});
    plate.triangles.push_back({vid(k, 0), base + 1, vid(k + 1, 0)});
  }
  for (int k = 0; k < n; ++k) {
    plate.triangles.push_back({vid(n, k), base + 1, base + 2});
    plate.triangles.push_back({vid(n, k), base + 2, vid(n, k + 1)});
    plate.triangles.push_back({vid(k + 1, n), base + 2, base + 3});
    plate.triangles.push_back({vid(k + 1, n), base + 3, vid(k, n)});
    plate.triangles.push_back({vid(0, k + 1), base + 3, base});
    plate.triangles.push_back({vid(0, k + 1), base, vid(0, k)});
  }
  const std::vector<Vec3> plate_vertices = plate.vertices;
  Scene scene = sceneOf({meshObject("plate", std::move(plate), at(0, 0, 0))});
  const HandModel m = bodyModel("box { half_extents { x: 0.042 y: 0.047 z: 0.013 } }", 0.35);
  const Shape& s = m.bodies[0].shape;
  Pipeline pipe(scene, {&m}, params(1.0 / 100));
  double below = 0.0, lag_late = 0.0, worst_penetration = 0.0, vertex_inside = 0.0;
  std::uint64_t rounds = 0;
  for (int k = 0; k <= 120; ++k) {
    const Quat q(Eigen::AngleAxisd(0.004 * k, Vec3::UnitZ()));
    const Pose target{Vec3(0.0005 * k - 0.03, 0.0003 * k, s.half_extents.z() - 0.005), q};
    rounds += static_cast<std::uint64_t>(pipe.step({HandInput{true, &target, nullptr}}).hands[0].diag.substeps);
    const Pose& X = pipe.poses(0)[0];
    const Mat3 Rb = X.q.toRotationMatrix();
    for (int i = -10; i <= 10; ++i)
      for (int j = -10; j <= 10; ++j) {
        const Vec3 p = X.p + Rb * Vec3(0.1 * i * s.half_extents.x(), 0.1 * j * s.half_extents.y(), -s.half_extents.z());
        below = std::max(below, height(p.x(), p.y()) - p.z());
      }
    // Exact, two ways: the reference penetration, and every vertex of the plate against the box
    // (a vertex inside the box is a penetration however the faces between them lie).
    worst_penetration = std::max(worst_penetration, pipe.penetration(0));
    for (const Vec3& v : plate_vertices) {
      const Vec3 l = Rb.transpose() * (v - X.p);
      const Vec3 in_by = s.half_extents - l.cwiseAbs();
      if (in_by.minCoeff() > 0.0) vertex_inside = std::max(vertex_inside, in_by.minCoeff());
    }
    if (k >= 30) lag_late = std::max(lag_late, std::hypot(X.p.x() - target.p.x(), X.p.y() - target.p.y()));
  }
  const PipelineCounters& c = pipe.counters();
  std::printf("[figure] palm on a bumpy plate: %llu rounds, %llu solved again after a hit; deepest sample below the smooth "
              "surface %.2e m (the mesh is its 2 mm linear interpolation); sideways distance to the target late %.4f m\n",
              static_cast<unsigned long long>(rounds), static_cast<unsigned long long>(c.hit_resolves), below, lag_late);
  EXPECT_EQ(worst_penetration, 0.0) << "the box went into the plate";
  EXPECT_EQ(vertex_inside, 0.0) << "a vertex of the plate inside the box";
  EXPECT_LT(lag_late, 2e-3) << "the box does not follow its target along the plate";
}

// A palm-sized box lying on a coarse octagonal rod (on one of its edges, and turned 22.5° about
// the axis: on one of its flat sides) touches it along a line; the closest point alone is one row,
// about which the box tilts into the rod (the hand froze on such a rod). The contacts now span
// the line: rows near both ends of the box along the rod (span ≥ 80 % of the box's length), and
// none asks the surface for more room than there is (each row's distance ≤ its point's exact
// distance to the mesh, from a point query of the BVH).
TEST(Plausibility, ABoxOnACoarseRodGetsRowsAlongTheWholeLine) {
  const Vec3 half(0.042, 0.047, 0.013);
  for (const double roll : {0.0, 22.5 * M_PI / 180.0}) {
    // The rod's axis is world y (its local z turned about x), rolled about y.
    const Quat q = Quat(Eigen::AngleAxisd(roll, Vec3::UnitY())) * Quat(Eigen::AngleAxisd(0.5 * M_PI, Vec3::UnitX()));
    Scene scene = sceneOf({meshObject("rod", cylinderMesh(0.007, 0.1, 8), at(0, 0, 0, q))});
    const geo::TriangleMesh& mesh = scene.objects[0].god->mesh();
    double top = -1.0;
    for (int t = 0; t < mesh.triangleCount(); ++t)
      for (int k = 0; k < 3; ++k) top = std::max(top, (q * mesh.vertex(t, k)).z());
    Shape box;
    box.type = ShapeType::Box;
    box.half_extents = half;
    const Pose X_WB{Vec3(0.0, 0.0, top + half.z() + 2e-5), Quat::Identity()};
    CollisionWorld world(scene);
    std::vector<Contact> contacts;
    world.contacts(box, X_WB, 0, 0.003, ContactParams{}, &contacts);
    ASSERT_FALSE(contacts.empty());
    double y_min = 1.0, y_max = -1.0;
    Shape point;
    point.type = ShapeType::Sphere;
    point.radius = 0.0;
    for (const Contact& c : contacts) {
      y_min = std::min(y_min, c.p_W.y());
      y_max = std::max(y_max, c.p_W.y());
      const double exact = world.clearance(point, Pose{c.p_W, Quat::Identity()}, 0.05);
      EXPECT_LE(c.distance, exact + 1e-9) << "roll " << roll;
      EXPECT_GE(c.distance, 0.0);
    }
    std::printf("[figure] roll %.3f rad: %zu rows spanning %.4f m of the %.4f m box along the rod\n", roll,
                contacts.size(), y_max - y_min, 2.0 * half.y());
    EXPECT_GE(y_max - y_min, 0.8 * 2.0 * half.y()) << "roll " << roll;
  }
}

// The rows of a box face lying on a coarse rod's edge hold every first-order motion out of the
// rod: a small motion (translations of up to 2e-4 m across the rod and 2e-5 m down, rotations of
// up to 2e-3 rad about the face's axes) that no row refuses (each row's gap d + n·(t + φ × r) ≥ 0)
// ends with the box at most second-order (1e-6 m) inside. The rod runs along the box's length or
// across its face (0.5, 1 rad), and the line contact ends at the face's sides. Before the patch
// corners had their features' normals, every corner took the triangle's (22.5° off the face's on
// an edge): rows at the line's ends along it let the box slide along the triangle's plane and
// tilt into the edge (7e-5 to 8e-5 m in), the motion the sweep refused round after round on the
// octagonal rod along y (rod_y8). Not held yet, measured: the box on a flat side 5.4 mm wide
// (the grid lets 6e-6 m in along the rod, 1.1e-5 m across it at 0.5 rad; 1e-4 m before): the
// thinning keeps one row per end (spread 16 mm), and the patch is the nearest triangle's, half
// of the side.
TEST(Plausibility, TheRowsOfABoxOnACoarseRodLetNoSmallMotionIntoIt) {
  const Vec3 half(0.042, 0.047, 0.013);
  Shape box;
  box.type = ShapeType::Box;
  box.half_extents = half;
  for (const double yaw : {0.0, 0.5, 1.0}) {
    // The rod's axis is world y (its local z turned about x; an edge on top), turned about z.
    const Quat q = Quat(Eigen::AngleAxisd(yaw, Vec3::UnitZ())) * Quat(Eigen::AngleAxisd(0.5 * M_PI, Vec3::UnitX()));
    const Scene scene = sceneOf({meshObject("rod", cylinderMesh(0.007, 0.1, 8), at(0, 0, 0, q))});
    const geo::TriangleMesh& mesh = scene.objects[0].god->mesh();
    double top = -1.0;
    for (int t = 0; t < mesh.triangleCount(); ++t)
      for (int k = 0; k < 3; ++k) top = std::max(top, (q * mesh.vertex(t, k)).z());
    const Pose X{Vec3(0.0, 0.0, top + half.z() + 2e-5), Quat::Identity()};
    CollisionWorld world(scene);
    std::vector<Contact> contacts;
    world.contacts(box, X, 0, 0.003, ContactParams{}, &contacts);
    ASSERT_FALSE(contacts.empty());
    ASSERT_EQ(world.penetration(box, X), 0.0);
    // Translations along x and z, rotations about x and y: every combination of -2 … 2 steps.
    const double step_t = 1e-4, step_z = 1e-5, step_r = 1e-3;
    int allowed = 0;
    double worst = 0.0;
    for (int tx = -2; tx <= 2; ++tx)
      for (int tz = -2; tz <= 2; ++tz)
        for (int rx = -2; rx <= 2; ++rx)
          for (int ry = -2; ry <= 2; ++ry) {
            const Vec3 t(tx * step_t, 0.0, tz * step_z), phi(rx * step_r, ry * step_r, 0.0);
            bool refused = false;
            for (const Contact& c : contacts)
              refused = refused || c.distance + c.n_W.dot(t + phi.cross(c.p_W - X.p)) < 0.0;
            if (refused) continue;
            ++allowed;
            Pose moved{X.p + t, X.q};
            if (phi.norm() > 0.0) moved.q = (Quat(Eigen::AngleAxisd(phi.norm(), phi.normalized())) * X.q).normalized();
            worst = std::max(worst, world.penetration(box, moved));
          }
    std::printf("[figure] yaw %.1f rad: %zu rows, %d of 625 motions allowed, deepest %.3g m\n", yaw, contacts.size(),
                allowed, worst);
    EXPECT_GE(allowed, 50) << "yaw " << yaw << ": the rows hold the box still";
    EXPECT_LE(worst, 1e-6) << "yaw " << yaw;
  }
}

// A capsule rolls around a cylinder with its target 2 mm inside it: the God capsule stays outside
// the true cylinder (its axis distance checked at both core ends and the middle) and keeps up
// with the target's angle.
TEST(Plausibility, CapsuleRollsAlongACylinderWithoutSinkingOrStalling) {
  const double R = 0.05, len = 0.4;
  Scene scene = sceneOf({meshObject("cylinder", cylinderMesh(R, 0.5 * len, 128), at(0, 0, 0, Quat(Eigen::AngleAxisd(0.5 * M_PI, Vec3::UnitX()))))});
  // The cylinder's axis is world y (its local z turned about x).
  const HandModel m = bodyModel("capsule { radius: 0.008 half_length: 0.02 }");
  Pipeline pipe(scene, {&m}, params(1.0 / 100));
  const Shape& s = m.bodies[0].shape;
  double worst_out = 1e9, worst_angle = 0.0;
  for (int k = 0; k <= 150; ++k) {
    const double a = 0.02 * k;  // rolls 2e-2 rad per frame around the axis, in the x-z plane
    const double rt = R + s.radius - 0.002;  // target 2 mm inside
    const Vec3 radial(std::cos(a), 0.0, std::sin(a));
    // Capsule axis along the cylinder axis (world y).
    const Pose target{rt * radial, Quat(Eigen::AngleAxisd(-0.5 * M_PI, Vec3::UnitX()))};
    const std::vector<HandInput> in{{true, &target, nullptr}};
    pipe.step(in);
    const Pose& X = pipe.poses(0)[0];
    const Vec3 axis = X.q * Vec3::UnitZ();
    for (double u : {-1.0, 0.0, 1.0}) {
      const Vec3 c = X.p + u * s.half_length * axis;
      worst_out = std::min(worst_out, std::hypot(c.x(), c.z()) - s.radius - R);
    }
    if (k > 5) {
      const double angle = std::atan2(X.p.z(), X.p.x());
      double d = std::abs(angle - std::atan2(target.p.z(), target.p.x()));
      d = std::min(d, 2 * M_PI - d);
      worst_angle = std::max(worst_angle, d);
    }
  }
  std::printf("[figure] capsule rolling on a cylinder, target 2 mm inside: min clearance %.3g m, angle lag max %.3g rad\n",
              worst_out, worst_angle);
  EXPECT_GE(worst_out, -1e-9) << "sank into the cylinder";
  EXPECT_LT(worst_angle, 0.02) << "lags its target around the cylinder by more than one frame's roll";
}

// Pressed into a plane (target 5 mm below the surface, turned), then lifted clear while turning:
// the frame after the target is free again the God box is at it (within 1 mm), not stuck below.
TEST(Plausibility, LiftsOffWhileRotatingWithinOneFrame) {
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(0.5, 0.5, 0.05)), at(0, 0, -0.05))});
  const HandModel m = bodyModel("box { half_extents { x: 0.03 y: 0.02 z: 0.01 } }");
  Pipeline pipe(scene, {&m}, params(1.0 / 60));
  Pose target = at(0, 0, 0.01 - 0.005);
  for (int k = 0; k < 30; ++k) {
    const std::vector<HandInput> in{{true, &target, nullptr}};
    pipe.step(in);
  }
  EXPECT_GE(lowestZ(m.bodies[0].shape, pipe.poses(0)[0]), -1e-9);
  target = at(0.01, 0.0, 0.03, aboutY(0.2));  // 2.5 cm up, turned: free
  ASSERT_GT(lowestZ(m.bodies[0].shape, target), 0.01);
  const std::vector<HandInput> in{{true, &target, nullptr}};
  pipe.step(in);
  const Pose& X = pipe.poses(0)[0];
  std::printf("[figure] lift-off while turning: error %.3g m, %.3g rad one frame later\n", (X.p - target.p).norm(),
              X.q.angularDistance(target.q));
  EXPECT_LT((X.p - target.p).norm(), 1e-3);
  EXPECT_LT(X.q.angularDistance(target.q), 1e-3);
}

// A box pressed onto a plane by a target 5 cm under it: the motion clamp (3 cm a frame) shortens
// every round. Held still, a second round gains nothing, so after the first frames each frame
// takes one round (HandSolver: a frame's first round goes on only where it gains on the last
// frame's stalled round). Sliding (the target moves 1 cm a frame along the plane), the rounds go
// on while they bring the box closer. The frictionless ideal follows the target's x exactly; with
// one round a frame the clamp (it scales the whole asked motion, lift and slide alike) has a fixed
// point: lag before the step Δ with 1 cm = 3 cm · Δ / √(Δ² + (5 cm)²), Δ = 1.77 cm, 0.77 cm after
// it. The box never goes through the plane.
TEST(Plausibility, AHeldBoxTakesOneRoundAFrameAndStillSlidesUnderTheClamp) {
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(1.0, 1.0, 0.05)), at(0, 0, -0.05))});
  const HandModel m = bodyModel("box { half_extents { x: 0.03 y: 0.02 z: 0.01 } }");
  Pipeline pipe(scene, {&m}, params(1.0 / 100));
  const Shape& s = m.bodies[0].shape;
  double low = 1e9;
  int one_round = 0, held = 0;
  Pose target = at(0, 0, 0.01);  // resting on the plane: the start is free
  for (int k = 0; k < 5; ++k) {
    const std::vector<HandInput> in{{true, &target, nullptr}};
    pipe.step(in);
  }
  target = at(0, 0, -0.04);  // 5 cm under the plane, held still
  for (int k = 0; k < 40; ++k) {
    const std::vector<HandInput> in{{true, &target, nullptr}};
    pipe.step(in);
    low = std::min(low, lowestZ(s, pipe.poses(0)[0]));
    if (k >= 5) {
      ++held;
      one_round += pipe.result(0).diag.substeps == 1;
    }
  }
  double lag = 0.0;
  for (int k = 1; k <= 60; ++k) {  // slides 1 cm a frame along +x, still 5 cm under
    target = at(0.01 * k, 0, -0.04);
    const std::vector<HandInput> in{{true, &target, nullptr}};
    pipe.step(in);
    low = std::min(low, lowestZ(s, pipe.poses(0)[0]));
    if (k > 20) lag = std::max(lag, target.p.x() - pipe.poses(0)[0].p.x());
  }
  std::printf("[figure] box held on a plane by a target 5 cm under it: %d of %d frames one round; sliding 1 cm a "
              "frame: x lag max %.3g m (one round a frame: 7.7 mm); lowest corner %.3g m\n",
              one_round, held, lag, low);
  EXPECT_GE(low, -1e-9) << "a corner went through the plane";
  EXPECT_EQ(one_round, held) << "held still, a frame took a second round that gained nothing";
  EXPECT_LT(lag, 0.005) << "the sliding box trailed its target as if it took one round a frame (7.7 mm)";
}

// A capsule lying across a washboard (ridges 1 mm high every 5 mm, 38° flanks, one open mesh),
// pressed 3 mm under the ridge tops and dragged 5 mm a frame across them. The frictionless ideal
// rests on the ridge tops at the target's x every frame. The ridges ahead are no part's nearest
// feature (they are no contact of the round), so the sweep meets them: with a round solved again
// from its start with the contacts the sweep met (hit_resolves), the capsule rides over them in
// that round; clipped at once (0), it stops at the ridge and takes the next round from there.
// Oracles: exact 2-D distances to the ridge profile (the capsule's axis sampled every 0.2 mm), the
// target's x, and the pipeline's own counters of clipped rounds.
TEST(Plausibility, ACapsuleDraggedOverRidgesRidesOverThemWithinTheRound) {
  // The profile in x-z: z = 0 at even knots, 1 mm at odd ones, every 2.5 mm; extruded along y.
  std::vector<Vec3> prof;
  for (int i = 0; i <= 160; ++i) prof.emplace_back(-0.1 + 0.0025 * i, 0.0, (i % 2) ? 0.001 : 0.0);
  geo::TriangleMesh mesh;
  for (const Vec3& q : prof) {
    mesh.vertices.push_back(q + Vec3(0, -0.1, 0));
    mesh.vertices.push_back(q + Vec3(0, 0.1, 0));
  }
  for (int i = 0; i + 1 < static_cast<int>(prof.size()); ++i) {
    mesh.triangles.push_back({2 * i, 2 * i + 2, 2 * i + 3});
    mesh.triangles.push_back({2 * i, 2 * i + 3, 2 * i + 1});
  }
  const Scene scene = sceneOf({meshObject("washboard", mesh, Pose{})});
  const HandModel m = bodyModel("capsule { radius: 0.008 half_length: 0.02 }");
  const Shape& s = m.bodies[0].shape;
  const Quat along_x(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitY()));
  // Exact 2-D distance from a point (x, z) to the profile polyline.
  auto profileDistance = [&](double x, double z) {
    double best = 1e9;
    for (size_t i = 0; i + 1 < prof.size(); ++i) {
      const Vec3 a(prof[i].x(), 0, prof[i].z()), b(prof[i + 1].x(), 0, prof[i + 1].z()), p(x, 0, z);
      const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
      best = std::min(best, (a + t * (b - a) - p).norm());
    }
    return best;
  };
  auto gap = [&](const Pose& X) {  // the capsule's distance to the ridges (the surface is y-invariant)
    const Vec3 axis = X.q * Vec3::UnitZ();
    double best = 1e9;
    for (int k = 0; k <= 200; ++k) {
      const Vec3 c = X.p + (-1.0 + 2.0 * k / 200) * s.half_length * axis;
      best = std::min(best, profileDistance(c.x(), c.z()) - s.radius);
    }
    return best;
  };
  auto run = [&](int hit_resolves, double* lag, double* worst_gap, std::uint64_t* clipped, std::uint64_t* resolves) {
    PipelineParams p = params(1.0 / 100);
    p.hit_resolves = hit_resolves;
    Pipeline pipe(scene, {&m}, p);
    *lag = 0.0;
    *worst_gap = 1e9;
    *clipped = 0;
    for (int k = 0; k < 40; ++k) {
      // Resting on the ridge tops first (free), then 3 mm under them, dragged 5 mm a frame.
      const double x = k < 5 ? 0.0 : 0.005 * (k - 5);
      const Pose target{Vec3(x, 0, k < 5 ? 0.001 + s.radius + 1e-4 : 0.001 + s.radius - 0.003), along_x};
      const std::vector<HandInput> in{{true, &target, nullptr}};
      pipe.step(in);
      const Pose& X = pipe.poses(0)[0];
      *worst_gap = std::min(*worst_gap, gap(X));
      if (k >= 10) *lag = std::max(*lag, std::abs(target.p.x() - X.p.x()));
      *clipped += pipe.result(0).diag.clipped ? 1 : 0;
    }
    *resolves = pipe.counters().hit_resolves;
  };
  double lag_on, gap_on, lag_off, gap_off;
  std::uint64_t clipped_on, clipped_off, res_on, res_off;
  run(PipelineParams{}.hit_resolves, &lag_on, &gap_on, &clipped_on, &res_on);
  run(0, &lag_off, &gap_off, &clipped_off, &res_off);
  std::printf("[figure] capsule dragged over ridges: x lag max %.3g m with re-solves (%llu, %llu clipped frames), "
              "%.3g m clipped at once (%llu clipped frames); least gap %.3g / %.3g m\n",
              lag_on, static_cast<unsigned long long>(res_on), static_cast<unsigned long long>(clipped_on), lag_off,
              static_cast<unsigned long long>(clipped_off), gap_on, gap_off);
  EXPECT_GE(gap_on, -1e-6) << "the capsule went into a ridge";
  EXPECT_GE(gap_off, -1e-6) << "the capsule went into a ridge";
  EXPECT_GT(res_off + clipped_off, 0u) << "the sweep never met a ridge: the test shows nothing";
  EXPECT_EQ(res_off, 0u);
  EXPECT_GT(res_on, 0u);
  EXPECT_LT(clipped_on, clipped_off) << "re-solved rounds should be clipped less often";
  EXPECT_LT(lag_on, 1e-3) << "the frictionless capsule should ride over the ridges at its target's x";
  // (Within 1 µm: since a body that hit keeps its hit's contacts into the next rounds, the run
  // clipped at once rides the ridges it met as well; the two lags came out 0.6717 and 0.6714 mm.)
  EXPECT_LE(lag_on, lag_off + 1e-6) << "riding over within the round should not trail more than stopping at each ridge";
}

// The whole 16-body hand: its index fingertip's target is pushed up into a crease (two plates
// meeting in a roof above it: the tip touches both faces) while the hand's other targets move
// freely: those bodies follow their targets as the free twin does (within 1 mm; the finger
// flexes to keep its tip out, within its joint range), the blocked tip stays outside both plates.
TEST(Plausibility, FingertipInACreaseDoesNotHoldTheRestOfTheHand) {
  const HandModel hand = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  int tip = -1;
  for (size_t b = 0; b < hand.bodies.size(); ++b)
    if (hand.bodies[b].name == "index.3") tip = static_cast<int>(b);
  ASSERT_GE(tip, 0);
  const std::vector<Pose> rest = hand.restPoses(Pose{});
  const Vec3 c = rest[static_cast<size_t>(tip)].p;
  // The crease: two thin plates crossing on a line along x 4 mm above the tip at ±45°; below
  // the line they form a roof over the tip.
  const double h = 0.002;
  auto plate = [&](double angle, const std::string& id) {
    const Quat q(Eigen::AngleAxisd(angle, Vec3::UnitX()));
    return meshObject(id, boxMesh(Vec3(0.008, 0.02, h)), Pose{c + q * Vec3(0, 0, h) + Vec3(0, 0, 0.004 + 0.008 + 0.002), q});
  };
  Scene scene = sceneOf({plate(M_PI / 4, "left-face"), plate(-M_PI / 4, "right-face")});
  Scene empty;
  Pipeline pipe(scene, {&hand}, params(1.0 / 100));
  Pipeline twin(empty, {&hand}, params(1.0 / 100));
  std::vector<Pose> targets(hand.bodies.size());
  double worst_free = 0.0;
  for (int k = 0; k < 60; ++k) {
    // The palm and the other fingers sway 2 mm around the rest pose; the index tip is pushed
    // 6 mm up into the crease.
    const Vec3 sway(0.002 * std::sin(0.2 * k), 0.002 * std::cos(0.15 * k), 0.0);
    for (size_t b = 0; b < targets.size(); ++b) targets[b] = Pose{rest[b].p + sway, rest[b].q};
    std::vector<unsigned char> driven(targets.size(), 1);
    // The index chain follows its tip down (joint-consistent targets: translate the finger).
    for (size_t b = 0; b < targets.size(); ++b)
      if (hand.bodies[b].name == "index.3") targets[b].p.z() += 0.006;
    const std::vector<HandInput> in{{true, targets.data(), driven.data()}};
    if (k == 0) {  // start outside: the first frame without the push
      std::vector<Pose> first = targets;
      for (size_t b = 0; b < first.size(); ++b) first[b] = Pose{rest[b].p + Vec3(0, 0, -0.02), rest[b].q};
      const std::vector<HandInput> in0{{true, first.data(), driven.data()}};
      pipe.step(in0);
      twin.step(in0);
    }
    pipe.step(in);
    twin.step(in);
    if (k < 10) continue;
    for (size_t b = 0; b < targets.size(); ++b) {
      const std::string& name = hand.bodies[b].name;
      if (name.rfind("index.", 0) == 0 || name == "palm") continue;  // the blocked finger and its base
      worst_free = std::max(worst_free, (pipe.poses(0)[b].p - twin.poses(0)[b].p).norm());
    }
    EXPECT_EQ(pipe.penetration(0), 0.0);
  }
  const double held = targets[static_cast<size_t>(tip)].p.z() - pipe.poses(0)[static_cast<size_t>(tip)].p.z();
  std::printf("[figure] fingertip in a crease: tip held %.3g m below its target; the other fingers' distance to the "
              "free twin max %.3g m\n", held, worst_free);
  EXPECT_GT(held, 0.003) << "the crease does not hold the tip: the test would show nothing";
  EXPECT_LT(worst_free, 1e-3);
}

// A phalanx resting on a crease must not hold the hand still while its targets move on. Real
// data: the bundled two-hand recording over the default scene with the fandisk moved 12 cm
// back, so that the right hand's fingers meet its -x side at a crease while the targets move
// 15 cm on in +x and up. Without the rotation cap (stuck_rotation = 0) the pinky's solved step
// turned 0.55 rad about its origin, swinging its contact point into the crease: every round
// was refused at TOC 0 and the hand did not move for 30 frames (with rounds clipped at once,
// hit_resolves = 0). Either cure alone lets it move on: the cap, and a round solved again with
// the contacts its sweep hit. That held hand was measured with the solid inertia as the step's
// rotational weight (`rotation_weight: SOLID`); the shipped weight (the farthest point's) turns
// the pinky less and moves on even without either cure, so the held case is shown with SOLID.
// Oracle: the free twin (same model and targets, empty scene) and the hand's own motion;
// penetration exact.
TEST(Plausibility, APhalanxOnACreaseDoesNotHoldTheHandStill) {
  const leap::Recording rec = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/confidence2-49fps.json");
  const HandModel shipped = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  const HandModel solid = testing::withRotationWeight(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt", "SOLID");
  const HandModel* model = &solid;
  Scene scene = loadScene(std::string(GODHAND_DEPLOY_DIR) + "/scenes/default.pbtxt");
  bool moved = false;
  for (SceneObject& o : scene.objects)
    if (o.id == "fandisk") {
      o.X_WO.p.y() += 0.12;
      moved = true;
    }
  ASSERT_TRUE(moved);
  auto run = [&](double stuck_rotation, int hit_resolves, double* god_moved, double* twin_moved, double* pen) {
    PipelineParams p;
    p.step.dt = 1.0 / rec.meanFrameRate();
    p.simulate = false;
    p.stuck_rotation = stuck_rotation;
    p.hit_resolves = hit_resolves;
    const HandModel& hand = *model;
    leap::Retargeter rt(hand);
    Pipeline pipe(scene, {&hand}, p);
    Pipeline twin(Scene{}, {&hand}, p);
    std::vector<Pose> targets, god_from, twin_from;
    std::vector<unsigned char> has;
    *pen = 0.0;
    for (size_t k = 0; k <= 140 && k < rec.frames().size(); ++k) {
      HandInput in;
      for (const leap::TrackedHand& h : rec.frames()[k].hands)
        if (h.right) {
          rt.targets(h, &targets, &has);
          in = HandInput{true, targets.data(), has.data()};
        }
      pipe.step({in});
      twin.step({in});
      *pen = std::max(*pen, pipe.penetration(0));
      if (k == 116) {
        god_from = pipe.poses(0);
        twin_from = twin.poses(0);
      }
    }
    *god_moved = (pipe.poses(0)[0].p - god_from[0].p).norm();
    *twin_moved = (twin.poses(0)[0].p - twin_from[0].p).norm();
  };
  const PipelineParams d;
  double god_on, twin_on, pen_on, god_off, twin_off, pen_off, god_cap, twin_cap, pen_cap, god_res, twin_res, pen_res;
  run(d.stuck_rotation, d.hit_resolves, &god_on, &twin_on, &pen_on);
  run(0.0, 0, &god_off, &twin_off, &pen_off);
  run(d.stuck_rotation, 0, &god_cap, &twin_cap, &pen_cap);
  run(0.0, d.hit_resolves, &god_res, &twin_res, &pen_res);
  double god_shipped, twin_shipped, pen_shipped, god_shipped_off, twin_shipped_off, pen_shipped_off;
  model = &shipped;
  run(d.stuck_rotation, d.hit_resolves, &god_shipped, &twin_shipped, &pen_shipped);
  run(0.0, 0, &god_shipped_off, &twin_shipped_off, &pen_shipped_off);
  std::printf("[figure] frames 116-140, the shipped rotational weight: the twin's palm moved %.3f m; the God palm "
              "%.4f m by default, %.4f m with neither cure; penetration %.2e / %.2e m\n",
              twin_shipped, god_shipped, god_shipped_off, pen_shipped, pen_shipped_off);
  EXPECT_GT(god_shipped, 0.01) << "by default the hand moves on";
  EXPECT_LE(std::max(pen_shipped, pen_shipped_off), d.step.rows.margin);
  std::printf("[figure] rotation_weight SOLID: frames 116-140: the twin's palm moved %.3f m; the God palm %.4f m by default, %.4f m with "
              "neither the rotation cap nor re-solves, %.4f m with the cap alone, %.4f m with the re-solves alone; "
              "penetration %.2e / %.2e / %.2e / %.2e m\n",
              twin_on, god_on, god_off, god_cap, god_res, pen_on, pen_off, pen_cap, pen_res);
  EXPECT_GT(twin_on, 0.1) << "the targets must move on, else the test shows nothing";
  EXPECT_LT(god_off, 1e-3) << "with neither cure the hand is held (the case this test is about)";
  EXPECT_GT(god_on, 0.01) << "by default the hand moves on";
  EXPECT_GT(god_cap, 0.01) << "with the cap alone the hand moves on";
  EXPECT_GT(god_res, 0.01) << "with the re-solves alone the hand moves on";
  for (double pen : {pen_on, pen_off, pen_cap, pen_res}) EXPECT_LE(pen, d.step.rows.margin);
}

// The first start of a recording's right hand in a scene, stepped frame by frame until it starts:
// its targets there and where the start moved them (the pipeline's trace line; NaN: not moved).
struct FirstStart {
  std::vector<Pose> targets;
  std::vector<unsigned char> has;
  Vec3 shift = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  bool started = false;
  PipelineParams params;
};
FirstStart firstStart(const leap::Recording& rec, const HandModel& hand, const Scene& scene) {
  FirstStart out;
  leap::Retargeter rt(hand);
  PipelineParams& p = out.params;
  p.step.dt = 1.0 / rec.meanFrameRate();
  p.simulate = false;
  p.trace = 1;
  p.trace_sink = [&out](const char* line) {
    double x, y, z;
    if (std::sscanf(line, "trace: start moved by (%lf, %lf, %lf)", &x, &y, &z) == 3) out.shift = Vec3(x, y, z);
  };
  Pipeline pipe(scene, {&hand}, p);
  for (size_t k = 0; k < rec.frames().size() && !out.started; ++k)
    for (const leap::TrackedHand& h : rec.frames()[k].hands)
      if (h.right) {
        rt.targets(h, &out.targets, &out.has);
        out.started = pipe.step({HandInput{true, out.targets.data(), out.has.data()}}).hands[0].started;
        break;
      }
  out.params.trace_sink = nullptr;  // (it refers to this function's `out`)
  return out;
}
// The least clearance of the driven bodies at their first targets moved by `offset`.
double startClearance(const FirstStart& s, const HandModel& hand, const CollisionWorld& world, const Vec3& offset) {
  double least = std::numeric_limits<double>::infinity();
  for (size_t b = 0; b < hand.bodies.size(); ++b) {
    if (!s.has.empty() && !s.has[b]) continue;
    Pose X = s.targets[b];
    X.p += offset;
    least = std::min(least, world.clearance(hand.bodies[b].shape, X, 0.05));
  }
  return least;
}

// A hand whose targets sit deep in a mesh starts just above the mesh, not up to twice as high:
// where moving out along the exit normals does not settle, the start is lifted straight up to the
// lowest free height (found to 1 mm between the last occupied and the first free doubling step).
// Real data: the bundled two-hand recording's right hand starts inside the default scene's bunny
// (lifted 16 cm before, 9.5 cm now). Oracle: the scene's own distances at the reported lift and
// 2 mm below it (the trace line says where the start went).
TEST(Plausibility, AHandStartingInsideAMeshStartsJustAboveIt) {
  const leap::Recording rec = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/confidence2-49fps.json");
  const HandModel hand = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  const Scene scene = loadScene(std::string(GODHAND_DEPLOY_DIR) + "/scenes/default.pbtxt");
  const FirstStart s = firstStart(rec, hand, scene);
  const Vec3& shift = s.shift;
  ASSERT_TRUE(shift.allFinite()) << "the right hand's start was not lifted: the test shows nothing";
  EXPECT_EQ(shift.x(), 0.0);
  EXPECT_EQ(shift.y(), 0.0);
  // Distances of the start pose lifted by h: the least over bodies and objects.
  const CollisionWorld world(scene);
  const double at_start = startClearance(s, hand, world, Vec3(0, 0, shift.z()));
  const double below = startClearance(s, hand, world, Vec3(0, 0, shift.z() - 0.002));
  std::printf("[figure] right hand lifted %.4f m to start; clearance there %.2e m, 2 mm lower %.2e m\n", shift.z(), at_start,
              below);
  EXPECT_GE(at_start, s.params.start_clearance - 1e-9) << "the start is not free";
  EXPECT_LT(below, s.params.start_clearance) << "2 mm lower was free too: the start is higher than it need be";
  EXPECT_LT(shift.z(), 0.12);
}

// A start is the shorter of the two free translations: out along the exit normals (where those
// pushes settle) or straight up. Real data: the pinch recording's hand starts inside the bundled
// bunny at 0.15 m (godhand-bench --mesh's placement: centred on the mean palm). Its pushes settle
// after more than 16 of them, 5.9 cm to the side; with 16 allowed it was lifted straight up by 10.3 cm, and
// for the whole run it lay on the bunny's top 6 cm from its targets (excess lag median 61 mm;
// 23 mm from the side). Oracle: the scene's own distances, the lowest free height scanned at 1 mm.
TEST(Plausibility, AHandStartingInsideAMeshStartsAtTheNearerOfTheWayOutAndAbove) {
  const leap::Recording rec = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json");
  const HandModel hand = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  Vec3 mean_palm = Vec3::Zero();
  int palms = 0;
  for (const leap::TrackerFrame& f : rec.frames())
    for (const leap::TrackedHand& h : f.hands) {
      mean_palm += h.X_W_palm.p;
      ++palms;
    }
  ASSERT_GT(palms, 0);
  mean_palm /= palms;
  const Scene scene =
      meshScene({parseMeshSpec(std::string(GODHAND_DEPLOY_DIR) + "/meshes/stanford-bunny.obj:0.15")}, mean_palm, meshFileLoader());
  const FirstStart s = firstStart(rec, hand, scene);
  ASSERT_TRUE(s.started);
  const Vec3& shift = s.shift;
  ASSERT_TRUE(shift.allFinite()) << "the start was not moved: the test shows nothing";
  const CollisionWorld world(scene);
  double up = 0.0;
  while (up < 0.5 && startClearance(s, hand, world, Vec3(0, 0, up)) < s.params.start_clearance) up += 1e-3;
  std::printf("[figure] start moved by (%.4f, %.4f, %.4f) m, %.4f m; the lowest free height %.3f m\n", shift.x(), shift.y(),
              shift.z(), shift.norm(), up);
  EXPECT_GE(startClearance(s, hand, world, shift), s.params.start_clearance - 1e-9) << "the start is not free";
  EXPECT_GT(std::hypot(shift.x(), shift.y()), 0.01) << "lifted straight up although the way out to the side is shorter";
  EXPECT_LT(shift.norm(), up - 0.01);
}

// The excess lag of METHOD.md §5 on an analytic case: a sphere whose target sinks d into a plane
// rests on the plane, so E = |god − twin| − depth(twin) = (d + δ) − d ≈ δ (the contact margin).
// A sphere of radius 1 cm driven to `targets` (one a frame, 100 Hz) above a plate 10 cm thick whose
// top is z = 0; the run's metrics.
RunSummary sphereOverAPlate(const std::vector<Pose>& targets, double* margin) {
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(0.5, 0.5, 0.05)), at(0, 0, -0.05))});
  const HandModel m = bodyModel("sphere { radius: 0.01 }");
  const PipelineParams p = params(1.0 / 100);
  Pipeline pipe(scene, {&m}, p);
  RunMetrics metrics(scene, {&m}, {"probe"}, p);
  for (const Pose& target : targets) {
    const HandInput in{true, &target, nullptr};
    pipe.step({in});
    HandSample s;
    s.started = s.tracked = true;
    s.X = pipe.poses(0).data();
    s.targets = &target;
    s.joint_gap = 0.0;
    s.loaded = pipe.result(0).loaded;
    metrics.add(0, s, in, pipe.resolver().collision());
  }
  *margin = p.step.rows.margin;
  return metrics.summary();
}

TEST(Plausibility, ExcessLagOfARestingSphereIsTheMargin) {
  const double d = 0.004;
  std::vector<Pose> targets;
  for (int k = 0; k < 40; ++k) targets.push_back(k < 5 ? at(0.001 * k, 0, 0.03) : at(0.001 * k, 0, 0.01 - d));
  double margin = 0.0;
  const RunSummary sum = sphereOverAPlate(targets, &margin);
  std::printf("[figure] resting sphere: excess lag median %.3g m (margin %.3g m), model error max %.3g m\n",
              sum.all.excess_lag_m.median, margin, sum.all.model_error_m.max);
  EXPECT_NEAR(sum.all.excess_lag_m.median, margin, 2e-5);
  EXPECT_LT(sum.all.model_error_m.max, 1e-9);  // one free body reaches any target exactly
  EXPECT_EQ(sum.all.stuck_frames, 0u);
  EXPECT_EQ(sum.all.frozen_windows, 0u);
  EXPECT_EQ(sum.all.penetration_max_m, 0.0);
  EXPECT_TRUE(sum.failure.empty());
}

// The excess lag split by where the twin is (run_metrics.h): a sphere above a plate, then its
// target sinks into it. Oracle: the target's analytic depth below the slab's top (the sphere's
// centre z < 0 puts its surface r − z deep, far more than kTwinInside here); above it the free
// sphere reaches its target exactly, so the frames with the twin outside have no lag at all.
TEST(Plausibility, ExcessLagIsSplitByTheTwinInsideOrOutside) {
  int above = 0, inside = 0;
  std::vector<Pose> targets;
  for (int k = 0; k < 40; ++k) {
    const double z = k < 10 ? 0.03 : -0.005 - 0.04 * (k - 10) / 29.0;
    targets.push_back(at(0.001 * k, 0, z));
    (z - 0.01 > 0.0 ? above : inside) += 1;
  }
  double margin = 0.0;
  const HandSummary h = sphereOverAPlate(targets, &margin).hands.at(0);
  std::printf("[figure] plate: excess lag median %.3g max %.3g m; twin inside %llu frames; outside: %zu frames, max %.3g m\n",
              h.excess_lag_m.median, h.excess_lag_m.max, static_cast<unsigned long long>(h.twinInsideFrames()),
              h.excess_lag_twin_outside_m.count, h.excess_lag_twin_outside_m.max);
  EXPECT_EQ(h.twinInsideFrames(), static_cast<std::uint64_t>(inside));
  EXPECT_EQ(h.excess_lag_twin_outside_m.count, static_cast<size_t>(above));
  EXPECT_EQ(h.excess_lag_m.count, static_cast<size_t>(above + inside));
  EXPECT_LT(h.excess_lag_twin_outside_m.max, 1e-9);
  EXPECT_EQ(h.lag_above_5mm_twin_outside, 0u);
  EXPECT_EQ(h.penetration_max_m, 0.0);
  // Pressed straight down, the depth subtraction is exact: the resting sphere's margin.
  EXPECT_NEAR(h.excess_lag_m.max, margin, 2e-5);
}

// A scene that encloses the tracking volume: the hand never starts, and the run says so. The
// nearest way out of the solid box is 0.5 m (its top, straight up: 0.51 m with the clearance);
// with max_start_shift 0.1 m nowhere is close enough, and with 1 m the hand starts outside.
TEST(Plausibility, AHandThatNeverStartsIsAFailedRun) {
  Scene scene = sceneOf({meshObject("room", boxMesh(Vec3(0.5, 0.5, 0.5)), at(0, 0, 0))});
  const HandModel m = bodyModel("sphere { radius: 0.01 }");
  for (const double shift : {0.1, 1.0}) {
    PipelineParams p = params(1.0 / 100);
    p.max_start_shift = shift;
    Pipeline pipe(scene, {&m}, p);
    RunMetrics metrics(scene, {&m}, {"probe"}, p);
    const Pose target = at(0, 0, 0);  // at the centre of the solid box
    for (int k = 0; k < 5; ++k) {
      const HandInput in{true, &target, nullptr};
      pipe.step({in});
      HandSample s;
      s.started = pipe.started(0);
      s.tracked = true;
      s.X = s.started ? pipe.poses(0).data() : nullptr;
      s.targets = &target;
      metrics.add(0, s, in, pipe.resolver().collision());
    }
    const RunSummary sum = metrics.summary();
    if (shift < 0.5) {
      EXPECT_FALSE(pipe.started(0)) << "no free pose within 0.1 m of a target 0.5 m deep";
      EXPECT_NE(sum.failure.find("never started"), std::string::npos) << sum.failure;
    } else {
      ASSERT_TRUE(pipe.started(0)) << "a free pose 0.51 m away is within 1 m";
      EXPECT_EQ(pipe.penetration(0), 0.0);
      EXPECT_GE(pipe.poses(0)[0].p.norm(), 0.5 + 0.01) << "started outside the box";
      EXPECT_EQ(sum.failure.find("never started"), std::string::npos) << sum.failure;
    }
  }
}

// A lab whose clusters the source never had a hand for (one left cluster and a right-hand
// recording) measured nothing and passed --check: such a run is a failed run, and says why. One
// idle cluster beside a tracked one (a two-hand lab and a one-hand recording) is a run of the
// other hand; a hand tracked in one frame of five is measured.
TEST(Plausibility, ARunWithNoHandEverTrackedIsAFailedRun) {
  Scene scene = sceneOf({});
  const HandModel m = bodyModel("sphere { radius: 0.01 }");
  struct Case {
    std::vector<int> tracked_frames;  // per hand
    bool fails;
  };
  for (const Case& c : {Case{{0}, true}, Case{{0, 0}, true}, Case{{1}, false}, Case{{0, 5}, false}}) {
    const size_t H = c.tracked_frames.size();
    PipelineParams p = params(1.0 / 100);
    std::vector<const HandModel*> models(H, &m);
    std::vector<std::string> names;
    for (size_t h = 0; h < H; ++h) names.push_back(h ? "right" : "left");
    Pipeline pipe(scene, models, p);
    RunMetrics metrics(scene, models, names, p);
    std::vector<Pose> targets(H);
    for (size_t h = 0; h < H; ++h) targets[h] = at(0.2 * static_cast<double>(h), 0, 0);
    for (int k = 0; k < 5; ++k) {
      std::vector<HandInput> in(H);
      for (size_t h = 0; h < H; ++h)
        if (k < c.tracked_frames[h]) in[h] = HandInput{true, &targets[h], nullptr};
      pipe.step(in);
      for (size_t h = 0; h < H; ++h) {
        HandSample s;
        s.started = pipe.started(static_cast<int>(h));
        s.tracked = in[h].tracked;
        s.X = s.started ? pipe.poses(static_cast<int>(h)).data() : nullptr;
        s.targets = in[h].tracked ? &targets[h] : nullptr;
        metrics.add(static_cast<int>(h), s, in[h], pipe.resolver().collision());
      }
    }
    const RunSummary sum = metrics.summary();
    std::string why;
    SCOPED_TRACE(::testing::Message() << H << " hand(s), first tracked in " << c.tracked_frames[0] << " frames");
    if (c.fails) {
      EXPECT_NE(sum.failure.find("no hand was ever tracked ('left'"), std::string::npos) << sum.failure;
      EXPECT_FALSE(plausible(sum, &why));
    } else {
      EXPECT_EQ(sum.failure, "");
      EXPECT_TRUE(plausible(sum, &why)) << why;
    }
  }
}

// A hand that cannot start (its target deep in a closed box) searches again every start_retry
// (0.1 s), not every frame, and starts within that once its target is out: 30 frames at 100 Hz
// inside make 3 searches, then a target 2 cm above the box starts it within 10 frames.
TEST(Plausibility, AHandThatCannotStartSearchesAgainAtTheRetryInterval) {
  Scene scene = sceneOf({meshObject("room", boxMesh(Vec3(0.5, 0.5, 0.5)), at(0, 0, 0))});
  const HandModel m = bodyModel("sphere { radius: 0.01 }");
  PipelineParams p = params(1.0 / 100);
  p.max_start_shift = 0.1;
  ASSERT_NEAR(p.start_retry, 0.1, 1e-12);
  Pipeline pipe(scene, {&m}, p);
  Pose target = at(0, 0, 0);
  for (int k = 0; k < 30; ++k) pipe.step({HandInput{true, &target, nullptr}});
  EXPECT_FALSE(pipe.started(0));
  EXPECT_EQ(pipe.solver(0).counters().start_searches, 3u) << "frames 0, 10 and 20";
  target = at(0, 0, 0.5 + 0.02);
  int frames = 0;
  while (!pipe.started(0) && frames < 20) {
    pipe.step({HandInput{true, &target, nullptr}});
    ++frames;
  }
  EXPECT_TRUE(pipe.started(0));
  EXPECT_LE(frames, 10) << "started within start_retry of a free target";
  EXPECT_NEAR(pipe.poses(0)[0].p.z(), 0.52, 1e-9) << "at its free target";
}

// The stuck figure counts a God hand that stays put while its free twin goes to a target it could
// reach straight (a fed, frozen pose: a second, deliberately stuck "implementation"), and does not
// count a hand that is where its twin is.
TEST(Plausibility, StuckFramesCountAHandThatCouldMoveButDoesNot) {
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(0.5, 0.5, 0.05)), at(0, 0, -1.0))});
  const HandModel m = bodyModel("sphere { radius: 0.01 }");
  const PipelineParams p = params(1.0 / 100);
  Pipeline pipe(scene, {&m}, p);
  RunMetrics frozen(scene, {&m}, {"probe"}, p), following(scene, {&m}, {"probe"}, p);
  const Pose still = at(0, 0, 0.1);
  for (int k = 0; k < 30; ++k) {
    const Pose target = at(0.002 * k, 0, 0.1);  // 2 mm per frame, nothing in the way
    const HandInput in{true, &target, nullptr};
    pipe.step({in});
    HandSample s;
    s.started = s.tracked = true;
    s.targets = &target;
    s.X = &still;
    frozen.add(0, s, in, pipe.resolver().collision());
    s.X = pipe.poses(0).data();
    following.add(0, s, in, pipe.resolver().collision());
  }
  const RunSummary a = frozen.summary(), b = following.summary();
  std::printf("[figure] stuck frames: a frozen sphere %llu of 30, the pipeline's %llu\n",
              static_cast<unsigned long long>(a.all.stuck_frames), static_cast<unsigned long long>(b.all.stuck_frames));
  EXPECT_GE(a.all.stuck_frames, 25u) << "from the frame it is 1 mm behind its twin on, every frame";
  std::string why;
  EXPECT_FALSE(plausible(a, &why));
  EXPECT_NE(why.find("stuck"), std::string::npos) << why;
  EXPECT_EQ(b.all.stuck_frames, 0u);
  EXPECT_TRUE(plausible(b, &why)) << why;
}

// A frame's rounds go on while they still bring a body centimetres closer, although one body pins
// the clamp's shared scale: a finger held at its joint limit asks the same 1.6 rad turn every
// round (the scale stays 0.5 / 1.6), while a free probe, 6 cm from its target, closes 31 % of the
// rest each round. Oracle: the clamp's arithmetic. Stopped after the second round (the scale did
// not grow) the probe ends 6 cm × 0.69² ≈ 29 mm short. Going on while a round gains more than
// MetricThresholds::kLagAbove (5 mm), the rounds gain 18.6, 12.8, 8.9, 6.1 and 4.2 mm: the frame
// ends after the fifth, 6 cm × 0.69⁵ ≈ 9 mm short, before max_clamped_rounds (8).
TEST(Plausibility, AFingerHeldAtItsLimitDoesNotStopTheOthersCatchingUp) {
  const std::string text = R"(name: "pinned"
bodies { name: "palm" box { half_extents { x: 0.04 y: 0.04 z: 0.01 } } mass: 1.0
  rest_position { x: 0 y: 0 z: 0 } rest_orientation { w: 1 x: 0 y: 0 z: 0 } tracker_segment: "palm" }
bodies { name: "finger" capsule { radius: 0.008 half_length: 0.02 } mass: 0.02
  rest_position { x: 0 y: 0.07 z: 0 } rest_orientation { w: 0.7071067811865476 x: -0.7071067811865476 y: 0 z: 0 }
  tracker_segment: "finger" }
bodies { name: "probe" sphere { radius: 0.01 } mass: 0.01
  rest_position { x: 0.2 y: 0 z: 0 } rest_orientation { w: 1 x: 0 y: 0 z: 0 } tracker_segment: "probe" }
joints { name: "knuckle" type: REVOLUTE parent: "palm" child: "finger"
  anchor_parent { x: 0 y: 0.045 z: 0 } anchor_child { x: 0 y: 0 z: -0.025 }
  axis_parent { x: 1 y: 0 z: 0 } axis_child { x: 1 y: 0 z: 0 }
  reference_parent { x: 0 y: 1 z: 0 } reference_child { x: 0 y: 0 z: 1 }
  limits { angle: 1 lower: -0.05 upper: 0.05 } }
)";
  const HandModel m = HandModel::fromText(text, "pinned");
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(0.5, 0.5, 0.05)), at(0, 0, -1.0))});
  const PipelineParams p = params(1.0 / 100);
  Pipeline pipe(scene, {&m}, p);
  std::vector<Pose> targets = m.restPoses(Pose{});
  pipe.step({HandInput{true, targets.data(), nullptr}});  // starts at its targets
  // The finger's target turned 1.6 rad about the knuckle's axis (x through the anchor): 1.55 rad
  // beyond its limit. The probe's 6 cm along +x.
  const Quat turn(Eigen::AngleAxisd(1.6, Vec3::UnitX()));
  const Vec3 anchor(0, 0.045, 0);
  targets[1].p = anchor + turn * (targets[1].p - anchor);
  targets[1].q = turn * targets[1].q;
  targets[2].p.x() += 0.06;
  pipe.step({HandInput{true, targets.data(), nullptr}});
  const std::vector<Pose>& X = pipe.poses(0);
  const double short_of = (targets[2].p - X[2].p).norm();
  const int rounds = pipe.result(0).diag.substeps;
  std::printf("[figure] a finger held at its limit: the free probe ends the frame %.2f mm short of its 60 mm move "
              "after %d rounds (stopped at the second: 29 mm)\n", 1e3 * short_of, rounds);
  EXPECT_EQ(rounds, 5);
  EXPECT_LT(rounds, p.max_clamped_rounds);
  EXPECT_LT(short_of, 0.012) << "the frame stopped while the probe still closed centimetres a round";
  EXPECT_LT(pipe.result(0).diag.joint_errors.gap, 1e-6);
  EXPECT_LT(std::abs(logRotation(X[1].q * X[0].q.conjugate() * m.bodies[1].X_MB_rest.q.conjugate()).x()), 0.05 + 1e-6)
      << "the finger went past its limit";
}

// A palm with a stiff finger on its deep side, the target tilted 30 degrees about the palm's x
// axis and pressed 1-3 cm into a table, held there. The free ideal is the target lifted straight
// out: every body within the target's depth of its own target (excess lag 0, METHOD section 5).
// Gauss' metric trades the palm's turn against its move: the palm turns about its lowest edge
// (it flattens) to bring its centre nearer a target it cannot reach, and the finger on that edge
// rises away from its target. The trade is in the metric's rotational block: with the default,
// a turn weighing what it moves the body's farthest point (idl/hand_model.proto), the palm turns
// less and the finger lags less than with the uniform solid's inertia (`rotation_weight: SOLID`,
// the paper's), run beside it. Neither is the ideal: both figures are printed.
TEST(Plausibility, ATiltedHandPressedIntoATableFlattensLessWithTheFarthestPointWeight) {
  const std::string body_text = R"(
bodies { name: "palm" box { half_extents { x: 0.04 y: 0.045 z: 0.012 } } mass: 0.4
  rest_position { x: 0 y: 0 z: 0 } rest_orientation { w: 1 x: 0 y: 0 z: 0 } tracker_segment: "palm" }
bodies { name: "finger" capsule { radius: 0.009 half_length: 0.02 } mass: 0.02
  rest_position { x: 0 y: 0.06550609665440988 z: 0.020506096654409877 }
  rest_orientation { w: 0.9238795325112867 x: -0.3826834323650898 y: 0 z: 0 } tracker_segment: "finger" }
joints { name: "knuckle" type: REVOLUTE parent: "palm" child: "finger"
  anchor_parent { x: 0 y: 0.045 z: 0 } anchor_child { x: 0 y: 0 z: -0.029 }
  axis_parent { x: 1 y: 0 z: 0 } axis_child { x: 1 y: 0 z: 0 }
  reference_parent { x: 0 y: 0.7071067811865476 z: 0.7071067811865476 } reference_child { x: 0 y: 0 z: 1 }
  limits { angle: 1 lower: -0.05 upper: 0.05 } }
)";  // the finger points 45 degrees up from the palm's +y edge, held within 0.05 rad of that
  Scene scene = sceneOf({meshObject("table", boxMesh(Vec3(0.5, 0.5, 0.05)), at(0, 0, -0.05))});
  const Quat tilt(Eigen::AngleAxisd(-0.52, Vec3::UnitX()));  // the finger's side down
  for (const double depth : {0.01, 0.02, 0.03}) {  // the target's lowest point under the top (z = 0)
    double excess[2] = {0, 0}, turn[2] = {0, 0};
    for (int solid = 0; solid < 2; ++solid) {
      const HandModel m =
          HandModel::fromText(std::string("name: \"tilted\"\n") + (solid ? "rotation_weight: SOLID\n" : "") + body_text, "tilted");
      std::vector<Pose> targets = m.restPoses(Pose{Vec3(0, 0, 0.1), tilt});
      double low = 1e9;
      for (size_t b = 0; b < targets.size(); ++b) low = std::min(low, lowestZ(m.bodies[b].shape, targets[b]));
      for (Pose& T : targets) T.p.z() -= low + depth;
      Pipeline pipe(scene, {&m}, params(1.0 / 60));
      for (int k = 0; k < 60; ++k) pipe.step({HandInput{true, targets.data(), nullptr}});
      const std::vector<Pose>& X = pipe.poses(0);
      double far = 0.0;
      for (size_t b = 0; b < X.size(); ++b) {
        far = std::max(far, (X[b].p - targets[b].p).norm());
        EXPECT_GE(lowestZ(m.bodies[b].shape, X[b]), -1e-9) << m.bodies[b].name << " went into the table";
      }
      excess[solid] = far - depth;
      turn[solid] = X[0].q.angularDistance(targets[0].q);
      EXPECT_LT(pipe.result(0).diag.joint_errors.gap, 1e-6);
    }
    std::printf("[figure] a tilted hand pressed %.0f cm into a table: excess lag %.2f mm, palm turned %.1f deg from its "
                "target (rotation_weight SOLID: %.2f mm, %.1f deg)\n",
                100 * depth, 1e3 * excess[0], turn[0] * 180 / M_PI, 1e3 * excess[1], turn[1] * 180 / M_PI);
    EXPECT_LT(turn[0], 0.7 * turn[1]) << depth << " m deep: the farthest point's weight did not keep the tilt better";
    EXPECT_LT(excess[0], 0.7 * excess[1]) << depth << " m deep: the finger lagged as much as with the solid inertia";
    EXPECT_GT(excess[1], 1e-3) << depth << " m deep: the solid inertia did not flatten the hand: the case shows nothing";
  }
}

// The jitter figure counts a body whose motion turns back from one frame to the next: a fed God
// pose shaking ±1 mm about a target that moves 1 mm per frame (a second, deliberately shaking
// "implementation"), against the pipeline following the same target (no turn). The free twin
// follows the target and never turns back.
TEST(Plausibility, JitterCountsABodyThatTurnsBackEveryFrame) {
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(0.5, 0.5, 0.05)), at(0, 0, -1.0))});
  const HandModel m = bodyModel("sphere { radius: 0.01 }");
  const PipelineParams p = params(1.0 / 100);
  Pipeline pipe(scene, {&m}, p);
  RunMetrics shaking(scene, {&m}, {"probe"}, p), following(scene, {&m}, {"probe"}, p);
  const int frames = 30;
  for (int k = 0; k < frames; ++k) {
    const Pose target = at(0.001 * k, 0, 0.1);
    // 1 mm ahead of the target on even frames, 1 mm behind on odd ones: its steps alternate
    // −1 mm and +3 mm, each turning back against the one before.
    const Pose shake = at(0.001 * k + (k % 2 == 0 ? 0.001 : -0.001), 0, 0.1);
    const HandInput in{true, &target, nullptr};
    pipe.step({in});
    HandSample s;
    s.started = s.tracked = true;
    s.targets = &target;
    s.X = &shake;
    shaking.add(0, s, in, pipe.resolver().collision());
    s.X = pipe.poses(0).data();
    following.add(0, s, in, pipe.resolver().collision());
  }
  const RunSummary a = shaking.summary(), b = following.summary();
  std::printf("[figure] jitter: a shaking sphere %llu of %llu body-frames, the pipeline's %llu of %llu, twin %llu\n",
              static_cast<unsigned long long>(a.all.jitter_body_frames), static_cast<unsigned long long>(a.all.jitter_checked),
              static_cast<unsigned long long>(b.all.jitter_body_frames), static_cast<unsigned long long>(b.all.jitter_checked),
              static_cast<unsigned long long>(b.all.twin_jitter_body_frames));
  // Frames 2 … 29 have a motion and one before it: 28 checked, every one turning back.
  EXPECT_EQ(a.all.jitter_checked, static_cast<std::uint64_t>(frames - 2));
  EXPECT_EQ(a.all.jitter_body_frames, static_cast<std::uint64_t>(frames - 2));
  EXPECT_EQ(b.all.jitter_body_frames, 0u);
  EXPECT_GE(b.all.jitter_checked, static_cast<std::uint64_t>(frames - 4));
  EXPECT_EQ(b.all.twin_jitter_body_frames, 0u);
  EXPECT_EQ(a.all.twin_jitter_body_frames, 0u);
}


// The rotation trust region damps a hand that turns back and forth, but cannot hold one still: a
// box whose target jumps back and forth by 2 mm (every round turns back against the one before)
// drives its trust to the floor; once the target stops and the box stands at it (rounds moving
// less than the reversal floor, so no evidence of a turn either way), the trust doubles a round
// and is back to 1 within 5 frames. Grown back by 10 % a round it took 36 frames, and a hand
// pressed towards targets far inside the bunny froze meanwhile (pinch at 0.25 m: 27 of 166
// windows).
TEST(Plausibility, ARotationTrustAtItsFloorComesBackOnceTheHandStandsStill) {
  Scene scene = sceneOf({meshObject("plate", boxMesh(Vec3(0.5, 0.5, 0.05)), at(0, 0, -1.0))});
  const HandModel m = bodyModel("box { half_extents { x: 0.02 y: 0.02 z: 0.01 } }");
  Pipeline pipe(scene, {&m}, params(1.0 / 100));
  for (int k = 0; k < 12; ++k) {
    const Pose target = at(k % 2 == 0 ? 0.001 : -0.001, 0, 0.1);
    pipe.step({HandInput{true, &target, nullptr}});
  }
  const double floor_trust = pipe.solver(0).rotationTrust();
  EXPECT_GT(pipe.solver(0).counters().reversed_rounds, 8u);
  EXPECT_LE(floor_trust, 1.0 / 16) << "reversals halve the trust";
  int frames = 0;
  const Pose still = at(0.0, 0, 0.1);
  pipe.step({HandInput{true, &still, nullptr}});  // the last jump back: a reversal
  while (pipe.solver(0).rotationTrust() < 1.0 && frames < 40) {
    pipe.step({HandInput{true, &still, nullptr}});
    ++frames;
  }
  std::printf("[figure] rotation trust %.4f after the jumps, back to 1 in %d frames standing still\n", floor_trust, frames);
  EXPECT_LE(frames, 6);
  EXPECT_LT((pipe.poses(0)[0].p - still.p).norm(), 1e-4) << "the box stands at its target";
}

// "all" pools the hands' figures: a hand whose figure was sampled (a long run) is weighted by
// the count each kept value stands for, not outvoted by an exact hand's values (a review's case:
// 10^6 values of 1 mm against 1,000 of 5 mm gave a median of ~3 mm).
TEST(Plausibility, PooledFiguresWeighASampledHandByItsCount) {
  Sample left(1000), right(1000);
  for (int i = 0; i < 1000000; ++i) left.add(1e-3);
  for (int i = 0; i < 1000; ++i) right.add(5e-3);
  ASSERT_TRUE(left.sampled());
  ASSERT_FALSE(right.sampled());
  const Spread all = spreadOf({&left, &right});
  EXPECT_TRUE(all.sampled);
  EXPECT_EQ(all.count, 1001000u);
  EXPECT_EQ(all.max, 5e-3);
  EXPECT_EQ(all.median, 1e-3);
  EXPECT_EQ(all.p95, 1e-3);  // 5 mm is 0.1 % of the values
  // Exact samples pool as one exact sample (the bench's case).
  Sample a(1000), b(1000);
  std::vector<double> both;
  for (int i = 0; i < 300; ++i) {
    a.add(i * 1e-4);
    both.push_back(i * 1e-4);
  }
  for (int i = 0; i < 500; ++i) {
    b.add(0.01 + i * 1e-5);
    both.push_back(0.01 + i * 1e-5);
  }
  const Spread ab = spreadOf({&a, &b});
  EXPECT_FALSE(ab.sampled);
  EXPECT_EQ(ab.median, percentile(both, 0.5));
  EXPECT_EQ(ab.p95, percentile(both, 0.95));
}

}  // namespace
}  // namespace godhand
