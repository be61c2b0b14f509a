// PhysicsWorld (core/physics/physics_world.h): resting contact, analytic force / torque response,
// clamps against launching, determinism, convex-hull centre of mass handling, bad input.
// Oracles are analytic (rigid-body mechanics), never Bullet itself. No timing assertions.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

#include "physics/physics_world.h"

namespace godhand {
namespace {

constexpr double kTableTop = 0.72;  // z of the table's top face

Pose at(const Vec3& p, const Quat& q = Quat::Identity()) { return Pose{p, q}; }

SceneObject makeBox(const std::string& id, const Vec3& half, double mass, const Pose& X_WO) {
  SceneObject o;
  o.id = id;
  o.X_WO = X_WO;
  o.mass = mass;
  o.physics.type = PhysicsShapeType::Box;
  o.physics.half_extents = half;
  o.source = "box";
  return o;
}

SceneObject makeSphere(const std::string& id, double r, double mass, const Pose& X_WO) {
  SceneObject o;
  o.id = id;
  o.X_WO = X_WO;
  o.mass = mass;
  o.physics.type = PhysicsShapeType::Sphere;
  o.physics.radius = r;
  return o;
}

SceneObject makeHull(const std::string& id, const std::vector<Vec3>& pts, double mass, const Pose& X_WO) {
  SceneObject o;
  o.id = id;
  o.X_WO = X_WO;
  o.mass = mass;
  o.physics.type = PhysicsShapeType::ConvexHull;
  o.physics.points = pts;
  return o;
}

/// Points of the box [−h, h] mapped by X (object frame).
std::vector<Vec3> boxPoints(const Vec3& h, const Pose& X = Pose{}) {
  std::vector<Vec3> pts;
  for (int i = 0; i < 8; ++i)
    pts.push_back(X * Vec3((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(), (i & 4) ? h.z() : -h.z()));
  return pts;
}

SceneObject makeTable() {
  return makeBox("table", Vec3(0.5, 0.5, 0.02), 0.0, at(Vec3(0, 0, kTableTop - 0.02)));
}

/// A 2 m square ground of 2 triangles at z = 0, static TriangleMesh.
SceneObject makeGroundMesh() {
  SceneObject o;
  o.id = "ground";
  o.mass = 0.0;
  o.physics.type = PhysicsShapeType::TriangleMesh;
  o.physics.mesh.vertices = {Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0)};
  o.physics.mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return o;
}

Scene makeScene(const Vec3& gravity = Vec3(0, 0, -9.81)) {
  Scene s;
  s.name = "test";
  s.gravity = gravity;
  return s;
}

void add(Scene& s, SceneObject o) {
  o.index = static_cast<int>(s.objects.size());
  s.objects.push_back(std::move(o));
}

void run(PhysicsWorld& w, double seconds, double dt = 0.01) {
  const int n = static_cast<int>(std::lround(seconds / dt));
  for (int i = 0; i < n; ++i) w.step(dt);
}

double angleBetween(const Quat& a, const Quat& b) { return a.angularDistance(b); }

PhysicsParams undamped() {
  PhysicsParams p;
  p.linear_damping = 0.0;
  p.angular_damping = 0.0;
  return p;
}

// ---------------------------------------------------------------------------------------------
// Resting contact

struct DropCase {
  const char* name;
  SceneObject object;
  double rest_z;  // expected object-frame z at rest
  bool mesh_ground;
};

void expectRests(const DropCase& c) {
  Scene s = makeScene();
  add(s, c.mesh_ground ? makeGroundMesh() : makeTable());
  add(s, c.object);
  PhysicsWorld w(s);
  ASSERT_TRUE(w.isDynamic(1));
  ASSERT_FALSE(w.isDynamic(0));
  run(w, 1.5);
  const Pose X = w.pose(1);
  const double err = X.p.z() - c.rest_z;
  std::printf("[figure] rest %-18s height error %+.4f mm, speed %.2e m/s, xy drift %.4f mm\n", c.name,
              err * 1e3, w.linearVelocity(1).norm(), (X.p.head<2>() - c.object.X_WO.p.head<2>()).norm() * 1e3);
  EXPECT_NEAR(X.p.z(), c.rest_z, 1e-3) << c.name;
  EXPECT_LT(w.linearVelocity(1).norm(), 1e-3) << c.name;
  EXPECT_LT(w.angularVelocity(1).norm(), 1e-2) << c.name;
  EXPECT_LT((X.p.head<2>() - c.object.X_WO.p.head<2>()).norm(), 1e-3) << c.name;
  EXPECT_EQ(w.pose(0).p, s.objects[0].X_WO.p) << "static objects do not move";
}

TEST(PhysicsWorld, BoxDroppedOntoTableRestsOnIt) {
  const double h = 0.03;
  expectRests({"box/table", makeBox("cube", Vec3(h, h, h), 0.2, at(Vec3(0.1, -0.05, kTableTop + h + 0.02))),
               kTableTop + h, false});
  // A flat, rotated (yaw) box.
  const Quat yaw(Eigen::AngleAxisd(0.6, Vec3::UnitZ()));
  expectRests({"flatbox/table", makeBox("plate", Vec3(0.08, 0.04, 0.01), 0.3, at(Vec3(0, 0, kTableTop + 0.03), yaw)),
               kTableTop + 0.01, false});
}

TEST(PhysicsWorld, SphereDroppedOntoTableRestsOnIt) {
  const double r = 0.025;
  expectRests({"sphere/table", makeSphere("ball", r, 0.1, at(Vec3(0, 0.1, kTableTop + r + 0.03))), kTableTop + r,
               false});
}

TEST(PhysicsWorld, CylinderDroppedOntoTableRestsUpright) {
  SceneObject c;
  c.id = "can";
  c.mass = 0.25;
  c.X_WO = at(Vec3(0, 0, kTableTop + 0.06 + 0.01));
  c.physics.type = PhysicsShapeType::Cylinder;
  c.physics.half_extents = Vec3(0.03, 0.03, 0.06);
  expectRests({"cylinder/table", c, kTableTop + 0.06, false});
}

TEST(PhysicsWorld, BoxAndSphereRestOnStaticTriangleMeshGround) {
  const double h = 0.04, r = 0.03;
  expectRests({"box/mesh", makeBox("cube", Vec3(h, h, h), 0.5, at(Vec3(0.2, 0.3, h + 0.02))), h, true});
  expectRests({"sphere/mesh", makeSphere("ball", r, 0.2, at(Vec3(-0.2, 0.1, r + 0.05))), r, true});
}

// ---------------------------------------------------------------------------------------------
// Analytic force / torque response (zero gravity, no damping)

TEST(PhysicsWorld, ConstantForceGivesAnalyticAcceleration) {
  Scene s = makeScene(Vec3::Zero());
  const double m = 0.5;
  const Vec3 h(0.05, 0.02, 0.01);
  add(s, makeBox("bar", h, m, at(Vec3(0, 0, 1))));
  PhysicsWorld w(s, undamped());
  const Vec3 F(2.0, -1.0, 0.5);
  const double dt = 0.01;
  const int steps = 10;
  for (int i = 0; i < steps; ++i) {
    w.applyForce(0, F, w.centreOfMass(0));
    w.step(dt);
  }
  const double T = dt * steps;
  const Vec3 v_expected = F / m * T;
  const Vec3 v = w.linearVelocity(0);
  const int n = steps * 10;  // substeps of 1 ms
  const double hs = T / n;
  // Symplectic Euler: x_n = a h² n(n+1)/2; continuous: ½ a T².
  const Vec3 x_discrete = F / m * hs * hs * n * (n + 1) / 2.0;
  const Vec3 x_analytic = 0.5 * F / m * T * T;
  const Vec3 dx = w.pose(0).p - Vec3(0, 0, 1);
  std::printf("[figure] constant force: v error %.2e m/s, x error vs ½at² %.3f %%\n", (v - v_expected).norm(),
              100.0 * (dx - x_analytic).norm() / x_analytic.norm());
  EXPECT_LT((v - v_expected).norm(), 1e-9 * v_expected.norm());
  EXPECT_LT((dx - x_discrete).norm(), 1e-9);
  EXPECT_LT((dx - x_analytic).norm(), 0.02 * x_analytic.norm());
  EXPECT_LT(w.angularVelocity(0).norm(), 1e-12) << "a force at the centre of mass makes no torque";
  EXPECT_EQ(w.counters().forces_applied, static_cast<std::uint64_t>(steps));
  EXPECT_EQ(w.counters().forces_clamped, 0u);
}

TEST(PhysicsWorld, OffsetForceProducesAnalyticTorqueResponse) {
  Scene s = makeScene(Vec3::Zero());
  const double m = 0.5;
  const Vec3 h(0.05, 0.02, 0.01);
  add(s, makeBox("bar", h, m, at(Vec3(0, 0, 1))));
  PhysicsWorld w(s, undamped());
  const Vec3 I = m / 3.0 * Vec3(h.y() * h.y() + h.z() * h.z(), h.x() * h.x() + h.z() * h.z(),
                                h.x() * h.x() + h.y() * h.y());
  // +y force at the +x end: torque +z. +z force at the +x end: torque −y.
  const Vec3 F(0.0, 0.2, 0.1);
  const Vec3 arm(0.05, 0.0, 0.0);
  const Vec3 tau = arm.cross(F);  // (0, −0.005, 0.01)
  ASSERT_GT(tau.z(), 0.0);
  ASSERT_LT(tau.y(), 0.0);
  const double dt = 0.01;
  w.applyForce(0, F, w.centreOfMass(0) + arm);
  w.step(dt);
  const Vec3 w_expected = tau.cwiseQuotient(I) * dt;
  const Vec3 omega = w.angularVelocity(0);
  const double rel = (omega - w_expected).norm() / w_expected.norm();
  std::printf("[figure] offset force: omega (%.4f, %.4f, %.4f) expected (%.4f, %.4f, %.4f) rad/s, rel err %.3f %%\n",
              omega.x(), omega.y(), omega.z(), w_expected.x(), w_expected.y(), w_expected.z(), 100 * rel);
  EXPECT_LT(rel, 0.03);
  EXPECT_GT(omega.z(), 0.0);
  EXPECT_LT(omega.y(), 0.0);
  EXPECT_LT((w.linearVelocity(0) - F / m * dt).norm(), 0.03 * (F / m * dt).norm())
      << "the object-origin velocity is the COM velocity plus a small ω × r";
}

// ---------------------------------------------------------------------------------------------
// Pushing and squeezing a light object: pushed, not launched

struct Tracked {
  double max_speed = 0, max_angular = 0, max_dz = 0, max_dxy = 0, max_tilt = 0;
  Vec3 omega_end = Vec3::Zero();       ///< angular velocity after the last step
  std::uint64_t speeds_clamped = 0;    ///< the world's counter after the last step
};

TEST(PhysicsWorld, PushingALightBoxMovesItAlongTheTableWithoutLaunching) {
  Scene s = makeScene();
  add(s, makeTable());
  const double h = 0.025;
  add(s, makeBox("light", Vec3(h, h, h), 0.2, at(Vec3(-0.2, 0, kTableTop + h + 0.005))));
  PhysicsWorld w(s);
  run(w, 1.0);  // settle
  const Pose X0 = w.pose(1);
  ASSERT_NEAR(X0.p.z(), kTableTop + h, 1e-3);
  // 1.5 N at the centre of the −x face for 0.3 s, at 90 Hz (dt not a multiple of 1 ms).
  Tracked t;
  const double dt = 1.0 / 90;
  for (int i = 0; i < 27; ++i) {
    const Pose X = w.pose(1);
    w.applyForce(1, Vec3(1.5, 0, 0), X * Vec3(-h, 0, 0));
    w.step(dt);
    t.max_speed = std::max(t.max_speed, w.linearVelocity(1).norm());
    t.max_dz = std::max(t.max_dz, std::abs(w.pose(1).p.z() - X0.p.z()));
    // Roll / pitch only: yaw is free (a push behind the centre of mass is unstable in yaw).
    t.max_tilt = std::max(t.max_tilt, std::acos(std::min(1.0, (w.pose(1).q * Vec3::UnitZ()).z())));
  }
  run(w, 0.5, dt);  // coast to rest under friction
  const Pose X1 = w.pose(1);
  const Vec3 d = X1.p - X0.p;
  // Coulomb oracle, μ = 0.5 (both objects 0.5; the pair uses their geometric mean):
  // push phase a = (F − μ m g) / m for 0.3 s, then deceleration μ g to rest.
  const double mu = 0.5, g = 9.81, m = 0.2, F = 1.5, T = 27 * dt;
  const double a = (F - mu * m * g) / m, v = a * T;
  const double x_expected = 0.5 * a * T * T + v * v / (2 * mu * g);
  std::printf("[figure] push 1.5 N x 0.3 s: moved %.1f mm along x (Coulomb oracle %.1f mm), %.2f mm sideways, "
              "max speed %.3f m/s (oracle %.3f), max |dz| %.3f mm, max roll/pitch %.2f deg\n",
              d.x() * 1e3, x_expected * 1e3, std::abs(d.y()) * 1e3, t.max_speed, v, t.max_dz * 1e3,
              t.max_tilt * 180 / M_PI);
  EXPECT_NEAR(d.x(), x_expected, 0.15 * x_expected);
  EXPECT_NEAR(t.max_speed, v, 0.1 * v);
  EXPECT_LT(std::abs(d.y()), 0.05 * d.x());
  EXPECT_LT(t.max_dz, 2e-3);
  EXPECT_LT(t.max_tilt, 0.05) << "it slides, it does not tip";
  EXPECT_LE(t.max_speed, w.params().max_speed + 1e-9);
  EXPECT_NEAR(X1.p.z(), kTableTop + h, 1e-3) << "still on the table";
  EXPECT_LT(w.linearVelocity(1).norm(), 1e-3);
}

TEST(PhysicsWorld, HugePushIsClampedAndDoesNotLaunchTheBox) {
  Scene s = makeScene();
  add(s, makeTable());
  const double h = 0.025;
  add(s, makeBox("light", Vec3(h, h, h), 0.2, at(Vec3(-0.4, 0, kTableTop + h))));
  PhysicsWorld w(s);
  run(w, 0.3);
  const Pose X0 = w.pose(1);
  Tracked t;
  for (int i = 0; i < 10; ++i) {  // 1000 N for 0.1 s, then a sharp stop
    w.applyForce(1, Vec3(1000, 0, 0), w.pose(1) * Vec3(-h, 0, 0));
    w.step(0.01);
    t.max_speed = std::max(t.max_speed, w.linearVelocity(1).norm());
    t.max_dz = std::max(t.max_dz, std::abs(w.pose(1).p.z() - X0.p.z()));
  }
  std::printf("[figure] 1000 N push: max speed %.3f m/s (clamp %.1f), max |dz| %.3f mm, clamps %llu force / %llu "
              "speed\n",
              t.max_speed, w.params().max_speed, t.max_dz * 1e3,
              static_cast<unsigned long long>(w.counters().forces_clamped),
              static_cast<unsigned long long>(w.counters().speeds_clamped));
  EXPECT_LE(t.max_speed, w.params().max_speed + 1e-9);
  EXPECT_LT(t.max_dz, 3e-3) << "does not fly off the table";
  EXPECT_EQ(w.counters().forces_clamped, 10u);
  EXPECT_GT(w.counters().speeds_clamped, 0u);
}

TEST(PhysicsWorld, ForceWakesASleepingStackAndTheTopBoxRidesAlong) {
  Scene s = makeScene();
  add(s, makeTable());
  const double h = 0.025;
  add(s, makeBox("bottom", Vec3(h, h, h), 0.2, at(Vec3(-0.2, 0, kTableTop + h))));
  add(s, makeBox("top", Vec3(0.6 * h, 0.6 * h, 0.6 * h), 0.05, at(Vec3(-0.2, 0, kTableTop + 2 * h + 0.6 * h))));
  PhysicsWorld w(s);
  run(w, 4.0);  // long enough for Bullet to put the stack to sleep
  const std::uint64_t asleep = w.stateHash();
  w.step(0.01);
  EXPECT_EQ(w.stateHash(), asleep) << "a resting stack stays bit-identical (asleep)";
  const Pose B0 = w.pose(1), T0 = w.pose(2);
  for (int i = 0; i < 30; ++i) {
    w.applyForce(1, Vec3(1.6, 0, 0), w.pose(1) * Vec3(-h, 0, 0));
    w.step(0.01);
  }
  run(w, 0.5);
  const double db = w.pose(1).p.x() - B0.p.x(), dt = w.pose(2).p.x() - T0.p.x();
  std::printf("[figure] stack push after 4 s asleep: bottom moved %.1f mm, top moved %.1f mm, top height change "
              "%.3f mm\n",
              db * 1e3, dt * 1e3, (w.pose(2).p.z() - T0.p.z()) * 1e3);
  EXPECT_GT(db, 0.02);
  EXPECT_NEAR(dt, db, 0.005) << "static friction carries the top box";
  EXPECT_NEAR(w.pose(2).p.z(), T0.p.z(), 1e-3);
}

// Model only what a scene requires (issue 14): a box resting on a table goes to sleep (Bullet's
// deactivation: 2 s below the thresholds), stays bit-identical while asleep, and is woken by
// what touches it: a teleport (the scene's push-out uses setPose) or a God-hand force. Its pose
// is read from a cache while it sleeps: after setPose the new pose, not the cached one.
TEST(PhysicsWorld, ARestingBoxSleepsAndSetPoseOrAForceWakesIt) {
  Scene s = makeScene();
  add(s, makeTable());
  const double h = 0.025;
  add(s, makeBox("box", Vec3(h, h, h), 0.2, at(Vec3(0, 0, kTableTop + h))));
  PhysicsWorld w(s);
  EXPECT_FALSE(w.isAwake(0)) << "static objects are never awake";
  EXPECT_TRUE(w.isAwake(1));
  run(w, 3.0);
  ASSERT_FALSE(w.isAwake(1)) << "at rest for more than 2 s: asleep";
  EXPECT_EQ(w.awakeCount(), 0);
  const Pose rest = w.pose(1);
  w.step(0.01);
  EXPECT_EQ(w.pose(1).p, rest.p);
  // Pushed out by 4 mm (what the scene stage does to an object in a God object): awake, there.
  Pose moved = rest;
  moved.p.x() += 0.004;
  w.setPose(1, moved);
  EXPECT_TRUE(w.isAwake(1));
  EXPECT_EQ(w.pose(1).p, moved.p) << "the new pose, not the one cached while it slept";
  run(w, 3.0);
  ASSERT_FALSE(w.isAwake(1)) << "asleep again";
  const Pose before = w.pose(1);
  for (int i = 0; i < 20; ++i) {
    w.applyForce(1, Vec3(2.0, 0, 0), w.pose(1) * Vec3(-h, 0, 0));
    w.step(0.01);
  }
  EXPECT_TRUE(w.isAwake(1));
  std::printf("[figure] woken by a 2 N push after sleeping: moved %.2f mm\n", (w.pose(1).p.x() - before.p.x()) * 1e3);
  EXPECT_GT(w.pose(1).p.x() - before.p.x(), 0.002) << "a force on a sleeping box moves it";
}

Tracked squeeze(double offset, double force, double seconds, Vec3* displacement) {
  Scene s = makeScene();
  add(s, makeTable());
  const double h = 0.025;
  add(s, makeBox("light", Vec3(h, h, h), 0.2, at(Vec3(0, 0, kTableTop + h))));
  PhysicsWorld w(s);
  run(w, 0.3);
  const Pose X0 = w.pose(1);
  Tracked t;
  const double dt = 1.0 / 90;
  const int n = static_cast<int>(seconds / dt);
  for (int i = 0; i < n; ++i) {
    const Pose X = w.pose(1);
    const Vec3 ax = X.q * Vec3::UnitX();
    // Two hands press the ±x faces towards each other, contact points offset ±offset along y.
    w.applyForce(1, force * ax, X * Vec3(-h, offset, 0));
    w.applyForce(1, -force * ax, X * Vec3(h, -offset, 0));
    w.step(dt);
    t.max_speed = std::max(t.max_speed, w.linearVelocity(1).norm());
    t.max_angular = std::max(t.max_angular, w.angularVelocity(1).norm());
    t.max_dz = std::max(t.max_dz, std::abs(w.pose(1).p.z() - X0.p.z()));
    t.max_dxy = std::max(t.max_dxy, (w.pose(1).p - X0.p).head<2>().norm());
  }
  *displacement = w.pose(1).p - X0.p;
  t.omega_end = w.angularVelocity(1);
  t.speeds_clamped = w.counters().speeds_clamped;
  EXPECT_LE(t.max_angular, w.params().max_angular_speed + 1e-9);
  return t;
}

TEST(PhysicsWorld, SqueezingALightBoxDoesNotLaunchIt) {
  Vec3 d;
  const Tracked t = squeeze(0.0, 100.0, 2.0, &d);
  std::printf("[figure] squeeze 2x100 N on-axis 2 s: displacement %.2e mm, max speed %.2e m/s, max |dz| %.2e mm\n",
              d.norm() * 1e3, t.max_speed, t.max_dz * 1e3);
  EXPECT_LT(d.norm(), 1e-4);
  EXPECT_LT(t.max_speed, 1e-3);
  EXPECT_LT(t.max_dz, 1e-4);
}

TEST(PhysicsWorld, OffAxisSqueezeStaysBounded) {
  Vec3 d;
  const Tracked t = squeeze(0.002, 100.0, 2.0, &d);  // 0.4 N m couple about z
  std::printf("[figure] squeeze 2x100 N off-axis 2 mm, 2 s: COM displacement %.3f mm, max speed %.3f m/s, "
              "max spin %.2f rad/s, max |dz| %.3f mm\n",
              t.max_dxy * 1e3, t.max_speed, t.max_angular, t.max_dz * 1e3);
  EXPECT_LT(t.max_dxy, 5e-3);
  EXPECT_LT(t.max_dz, 2e-3);
  EXPECT_LT(t.max_speed, 0.1);
  // The spin: the couple is -2 x 2 mm x 100 N = -0.4 N m about z, against I_z = m (2h)^2 / 6 =
  // 8.3e-5 kg m^2 and table friction of at most mu m g h ~ 0.05 N m, so the box spins up about -z
  // by more than 4,000 rad/s^2, past the angular speed clamp within one frame: at the end it turns
  // about -z at exactly the clamp (the clamp acted), and neither tips nor wobbles about x or y.
  const double clamp = PhysicsParams{}.max_angular_speed;
  std::printf("[figure] squeeze off-axis: spin at the end (%.3f, %.3f, %.3f) rad/s, clamp %.1f, clamped %llu times\n",
              t.omega_end.x(), t.omega_end.y(), t.omega_end.z(), clamp, static_cast<unsigned long long>(t.speeds_clamped));
  EXPECT_NEAR(-t.omega_end.z(), clamp, 1e-6 * clamp) << "spins about -z, the couple's axis, at the clamp";
  EXPECT_LT(t.omega_end.head<2>().norm(), 0.05 * clamp) << "no tipping about x or y";
  EXPECT_GT(t.speeds_clamped, 0u) << "the clamp, not the couple, bounds the spin";
}

// ---------------------------------------------------------------------------------------------
// Force clamp and non-finite input

TEST(PhysicsWorld, HugeForceGivesAtMostTheClampedAcceleration) {
  Scene s = makeScene(Vec3::Zero());
  const double m = 1.0;
  add(s, makeBox("crate", Vec3(0.05, 0.05, 0.05), m, at(Vec3(0, 0, 1))));
  PhysicsWorld w(s, undamped());
  const double dt = 0.01;
  w.applyForce(0, Vec3(0, 1e6, 0), w.centreOfMass(0));
  w.step(dt);
  const double dv_max = w.params().max_force_per_object / m * dt;
  const Vec3 v = w.linearVelocity(0);
  std::printf("[figure] 1e6 N force: speed after 10 ms %.6f m/s (clamped bound %.6f)\n", v.norm(), dv_max);
  EXPECT_LE(v.norm(), dv_max * (1 + 1e-12));
  EXPECT_NEAR(v.y(), dv_max, 1e-9) << "the direction is kept, the norm clamped";
  EXPECT_EQ(w.counters().forces_clamped, 1u);
  // Torque is scaled alike: a huge force at an offset point gives the spin of the clamped force
  // there, r x F (F_max / |F|) dt / I (the angular speed clamp off, so that it is not what bounds
  // it): about y, 0.05 F_max dt / (m (0.1² + 0.1²) / 12).
  PhysicsParams free_spin = undamped();
  free_spin.max_angular_speed = std::numeric_limits<double>::infinity();
  PhysicsWorld spin(s, free_spin);
  spin.applyForce(0, Vec3(0, 0, 1e6), spin.centreOfMass(0) + Vec3(0.05, 0, 0));
  spin.step(dt);
  const double inertia = m * (0.1 * 0.1 + 0.1 * 0.1) / 12.0;
  const double w_expected = 0.05 * spin.params().max_force_per_object * dt / inertia;
  std::printf("[figure] 1e6 N couple: spin after 10 ms %.6f rad/s (analytic for the clamped force %.6f)\n",
              spin.angularVelocity(0).norm(), w_expected);
  EXPECT_NEAR(-spin.angularVelocity(0).y(), w_expected, 1e-9 * w_expected);
  EXPECT_NEAR(spin.angularVelocity(0).norm(), w_expected, 1e-9 * w_expected);
  EXPECT_EQ(spin.counters().forces_clamped, 1u);
  EXPECT_EQ(spin.counters().speeds_clamped, 0u);
}

TEST(PhysicsWorld, NonFiniteForcesAreRejectedAndCounted) {
  Scene s = makeScene();
  add(s, makeTable());
  add(s, makeBox("crate", Vec3(0.05, 0.05, 0.05), 1.0, at(Vec3(0, 0, kTableTop + 0.05))));
  PhysicsWorld w(s);
  run(w, 0.2);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const Vec3 c = w.centreOfMass(1);
  w.applyForce(1, Vec3(nan, 0, 0), c);
  w.applyForce(1, Vec3(0, inf, 0), c);
  w.applyForce(1, Vec3(1, 0, 0), Vec3(0, nan, 0));
  w.applyForce(0, Vec3(1, 0, 0), c);  // the static table ignores forces
  EXPECT_EQ(w.counters().forces_rejected, 3u);
  EXPECT_EQ(w.counters().forces_ignored, 1u);
  EXPECT_EQ(w.counters().forces_applied, 0u);
  for (int i = 0; i < 10; ++i) w.step(0.01);
  EXPECT_TRUE(w.pose(1).p.allFinite());
  EXPECT_TRUE(w.pose(1).q.coeffs().allFinite());
  EXPECT_TRUE(w.linearVelocity(1).allFinite());
  EXPECT_LT(w.linearVelocity(1).norm(), 1e-3);
  EXPECT_NEAR(w.pose(1).p.z(), kTableTop + 0.05, 1e-3);
  EXPECT_THROW(w.applyForce(2, Vec3(1, 0, 0), c), std::out_of_range);
  EXPECT_THROW(w.applyForce(-1, Vec3(1, 0, 0), c), std::out_of_range);
}

// ---------------------------------------------------------------------------------------------
// Determinism and substeps

Scene mixedScene() {
  Scene s = makeScene();
  add(s, makeTable());
  for (int i = 0; i < 4; ++i)
    add(s, makeBox("box" + std::to_string(i), Vec3(0.02, 0.03, 0.015), 0.1 + 0.05 * i,
                   at(Vec3(-0.15 + 0.1 * i, 0.01 * i, kTableTop + 0.05 + 0.04 * i),
                      Quat(Eigen::AngleAxisd(0.3 * i, Vec3(1, 1, 0).normalized())))));
  add(s, makeSphere("ball", 0.03, 0.2, at(Vec3(0.05, 0.2, kTableTop + 0.2))));
  add(s, makeHull("hull", boxPoints(Vec3(0.02, 0.02, 0.04), at(Vec3(0.05, 0.0, 0.03))), 0.3,
                  at(Vec3(-0.1, -0.2, kTableTop + 0.1))));
  return s;
}

void drive(PhysicsWorld& w, int i, double scale) {
  // A deterministic but irregular force pattern on a few objects.
  const int obj = 1 + i % 6;
  const Vec3 f = scale * Vec3(std::sin(0.37 * i), std::cos(0.11 * i), 0.3 * std::sin(0.05 * i));
  w.applyForce(obj, f, w.centreOfMass(obj) + Vec3(0.01, -0.005, 0.003));
}

TEST(PhysicsWorld, SameInputsGiveBitIdenticalStates) {
  const Scene s = mixedScene();
  PhysicsWorld a(s), b(s), c(s);
  const double dt = 1.0 / 115;
  bool diverged_c = false;
  for (int i = 0; i < 230; ++i) {
    drive(a, i, 1.0);
    drive(b, i, 1.0);
    drive(c, i, i == 50 ? 1.0 + 1e-9 : 1.0);  // one tiny difference
    a.step(dt);
    b.step(dt);
    c.step(dt);
    ASSERT_EQ(a.stateHash(), b.stateHash()) << "step " << i;
    diverged_c = diverged_c || a.stateHash() != c.stateHash();
  }
  EXPECT_TRUE(diverged_c) << "the hash sees a 1e-9 relative force difference";
  // dt = 1/115 s = 8.70 ms: 9 equal substeps of 0.966 ms each.
  EXPECT_EQ(a.counters().steps, 230u);
  EXPECT_EQ(a.counters().substeps, 230u * 9u);
  EXPECT_EQ(a.counters().steps_capped, 0u);
  for (int o = 0; o < a.objectCount(); ++o) {
    EXPECT_TRUE(a.pose(o).p.allFinite());
    EXPECT_LT(a.linearVelocity(o).norm(), a.params().max_speed + 1e-9) << o;
  }
  std::printf("[figure] determinism: 230 steps of 1/115 s, hash %016llx\n",
              static_cast<unsigned long long>(a.stateHash()));
}

TEST(PhysicsWorld, SubstepSplitAndCap) {
  const Scene s = mixedScene();
  PhysicsWorld w(s);
  w.step(1.0 / 1000);
  EXPECT_EQ(w.counters().substeps, 1u);
  w.step(0.01);
  EXPECT_EQ(w.counters().substeps, 11u);
  w.step(0.0105);
  EXPECT_EQ(w.counters().substeps, 22u);
  w.step(0.1);  // a 100 ms hitch: capped at max_substeps = 20 of 1 ms
  EXPECT_EQ(w.counters().substeps, 42u);
  EXPECT_EQ(w.counters().steps_capped, 1u);
  const std::uint64_t hash = w.stateHash();
  w.step(0.0);  // no-op
  EXPECT_EQ(w.stateHash(), hash);
  EXPECT_EQ(w.counters().steps, 4u);
  EXPECT_THROW(w.step(-0.01), std::invalid_argument);
  EXPECT_THROW(w.step(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  // Step cost, printed only.
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 100; ++i) w.step(1.0 / 90);
  const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / 100;
  std::printf("[figure] step cost: %.1f us per 1/90 s step (12 substeps, 7 objects)\n", us);
}

// ---------------------------------------------------------------------------------------------
// Convex hulls: centre of mass offset from the object frame

TEST(PhysicsWorld, DynamicConvexHullFallsAndRestsInTheObjectFrame) {
  Scene s = makeScene();
  add(s, makeTable());
  // A 5 cm cube whose centre sits at (0.1, 0.2, 0.05) in its object frame.
  const Vec3 offset(0.1, 0.2, 0.05);
  const double hh = 0.025;
  const Quat yaw(Eigen::AngleAxisd(M_PI / 6, Vec3::UnitZ()));
  const Pose X_WO0 = at(Vec3(-0.2, -0.1, kTableTop - (offset.z() - hh) + 0.015), yaw);
  add(s, makeHull("offset_cube", boxPoints(Vec3::Constant(hh), at(offset)), 0.3, X_WO0));
  PhysicsWorld w(s);
  // At t = 0 the pose is the scene pose and the centre of mass is the cube centre.
  EXPECT_LT((w.pose(1).p - X_WO0.p).norm(), 1e-12);
  EXPECT_LT(angleBetween(w.pose(1).q, X_WO0.q), 1e-12);
  EXPECT_LT((w.centreOfMass(1) - X_WO0 * offset).norm(), 1e-12);
  run(w, 1.5);
  const Pose X = w.pose(1);
  const double rest_z = kTableTop - (offset.z() - hh);
  std::printf("[figure] rest hull/table object-frame height error %+.4f mm, xy drift %.4f mm, yaw change %.4f deg\n",
              (X.p.z() - rest_z) * 1e3, (X.p - X_WO0.p).head<2>().norm() * 1e3,
              angleBetween(X.q, X_WO0.q) * 180 / M_PI);
  EXPECT_NEAR(X.p.z(), rest_z, 1e-3);
  EXPECT_LT((X.p - X_WO0.p).head<2>().norm(), 1e-3);
  EXPECT_LT(angleBetween(X.q, X_WO0.q), 2e-3);
  EXPECT_LT((w.centreOfMass(1) - X * offset).norm(), 1e-9);
  EXPECT_LT(w.linearVelocity(1).norm(), 1e-3);
}

TEST(PhysicsWorld, ConvexHullInertiaMatchesAnalyticBoxInRotatedOffsetFrame) {
  // Box hull rotated and offset in its object frame: the object axes are not principal axes.
  Scene s = makeScene(Vec3::Zero());
  const double m = 0.4;
  const Vec3 h(0.06, 0.03, 0.015);
  const Pose X_OB = at(Vec3(0.05, -0.02, 0.1), Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized())));
  const Pose X_WO = at(Vec3(0, 0, 1), Quat(Eigen::AngleAxisd(-0.4, Vec3(0, 1, 1).normalized())));
  add(s, makeHull("tilted", boxPoints(h, X_OB), m, X_WO));
  PhysicsWorld w(s, undamped());
  const Pose X_WB = X_WO * X_OB;
  const Mat3 R = X_WB.q.toRotationMatrix();
  const Vec3 Ib = m / 3.0 * Vec3(h.y() * h.y() + h.z() * h.z(), h.x() * h.x() + h.z() * h.z(),
                                 h.x() * h.x() + h.y() * h.y());
  const Mat3 I_W = R * Ib.asDiagonal() * R.transpose();
  EXPECT_LT((w.centreOfMass(0) - X_WB.p).norm(), 1e-12);
  const Vec3 F(0.3, -0.1, 0.2);
  const Vec3 p = X_WB * Vec3(h.x(), 0.5 * h.y(), -h.z());  // a corner-ish point of the box
  const double dt = 0.005;
  w.applyForce(0, F, p);
  w.step(dt);
  const Vec3 w_expected = I_W.inverse() * (p - X_WB.p).cross(F) * dt;
  const double rel = (w.angularVelocity(0) - w_expected).norm() / w_expected.norm();
  std::printf("[figure] hull inertia (rotated, offset box): omega rel err %.3f %%\n", rel * 100);
  EXPECT_LT(rel, 0.03);
  EXPECT_LT((w.pointVelocity(0, w.centreOfMass(0)) - F / m * dt).norm(), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Unsimulated objects, teleport

TEST(PhysicsWorld, UnsimulatedObjectKeepsItsPoseAndIgnoresForces) {
  Scene s = makeScene();
  SceneObject ghost;
  ghost.id = "ghost";
  ghost.mass = 1.0;  // a mass without a physics shape: still not simulated
  ghost.X_WO = at(Vec3(1, 2, 3), Quat(Eigen::AngleAxisd(0.3, Vec3::UnitX())));
  add(s, ghost);
  PhysicsWorld w(s);
  EXPECT_FALSE(w.isSimulated(0));
  EXPECT_FALSE(w.isDynamic(0));
  w.applyForce(0, Vec3(10, 0, 0), Vec3(1, 2, 3));
  run(w, 0.1);
  EXPECT_EQ(w.pose(0).p, ghost.X_WO.p);
  EXPECT_EQ(w.counters().forces_ignored, 1u);
  EXPECT_EQ(w.linearVelocity(0), Vec3::Zero());
  w.setPose(0, at(Vec3(0, 0, 0)));
  EXPECT_EQ(w.pose(0).p, Vec3::Zero());
}

TEST(PhysicsWorld, SetPoseTeleportsWithZeroVelocity) {
  Scene s = makeScene();
  add(s, makeTable());
  add(s, makeHull("hull", boxPoints(Vec3(0.02, 0.02, 0.02), at(Vec3(0.03, 0, 0))), 0.2,
                  at(Vec3(0, 0, kTableTop + 0.3))));
  PhysicsWorld w(s);
  run(w, 0.1);
  ASSERT_GT(w.linearVelocity(1).norm(), 0.5);
  const Pose target = at(Vec3(0.1, 0.1, kTableTop + 0.02 + 0.001), Quat(Eigen::AngleAxisd(1.0, Vec3::UnitZ())));
  w.setPose(1, target);
  EXPECT_LT((w.pose(1).p - target.p).norm(), 1e-12);
  EXPECT_LT(angleBetween(w.pose(1).q, target.q), 1e-12);
  EXPECT_EQ(w.linearVelocity(1), Vec3::Zero());
  EXPECT_EQ(w.angularVelocity(1), Vec3::Zero());
  run(w, 0.5);
  EXPECT_NEAR(w.pose(1).p.z(), kTableTop + 0.02, 1e-3);
  EXPECT_THROW(w.setPose(1, at(Vec3(std::nan(""), 0, 0))), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Bad input

void expectRejected(const SceneObject& bad, const std::string& what) {
  Scene s = makeScene();
  add(s, makeTable());
  add(s, bad);
  try {
    PhysicsWorld w(s);
    ADD_FAILURE() << what << ": accepted";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    std::printf("[figure] rejected %-22s: %s\n", what.c_str(), msg.c_str());
    EXPECT_NE(msg.find("'" + bad.id + "'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("index 1"), std::string::npos) << msg;
  }
}

TEST(PhysicsWorld, RejectsUnusableObjectsNamingThem) {
  SceneObject dyn_mesh = makeGroundMesh();
  dyn_mesh.id = "heavy_mesh";
  dyn_mesh.mass = 1.0;
  expectRejected(dyn_mesh, "dynamic TriangleMesh");
  expectRejected(makeBox("flat_box", Vec3(0.1, 0.0, 0.1), 1.0, Pose{}), "zero-size box");
  expectRejected(makeBox("neg_mass", Vec3(0.1, 0.1, 0.1), -1.0, Pose{}), "negative mass");
  expectRejected(makeBox("nan_pose", Vec3(0.1, 0.1, 0.1), 1.0, at(Vec3(0, std::nan(""), 0))), "NaN pose");
  expectRejected(makeBox("bad_quat", Vec3(0.1, 0.1, 0.1), 1.0, at(Vec3::Zero(), Quat(2, 0, 0, 0))),
                 "non-unit quaternion");
  expectRejected(makeSphere("no_ball", 0.0, 1.0, Pose{}), "zero sphere");
  expectRejected(makeHull("flat_hull", {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}, 1.0, Pose{}),
                 "coplanar hull");
  expectRejected(makeHull("few_points", {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, 1.0, Pose{}),
                 "3-point hull");
  SceneObject cyl;
  cyl.id = "oval_can";
  cyl.mass = 1.0;
  cyl.physics.type = PhysicsShapeType::Cylinder;
  cyl.physics.half_extents = Vec3(0.03, 0.04, 0.05);
  expectRejected(cyl, "elliptic cylinder");
  SceneObject bad_mesh = makeGroundMesh();
  bad_mesh.id = "broken_mesh";
  bad_mesh.physics.mesh.triangles.push_back({0, 1, 7});
  expectRejected(bad_mesh, "mesh index");
  SceneObject slippery = makeBox("slippery", Vec3(0.1, 0.1, 0.1), 1.0, Pose{});
  slippery.friction = -0.1;
  expectRejected(slippery, "negative friction");
  // A static convex hull and a static mesh are fine.
  Scene ok = makeScene();
  add(ok, makeGroundMesh());
  add(ok, makeHull("static_hull", boxPoints(Vec3::Constant(0.05)), 0.0, at(Vec3(0, 0, 0.05))));
  EXPECT_NO_THROW(PhysicsWorld{ok});
}

TEST(PhysicsWorld, ParamsValidateNamesTheField) {
  auto expectField = [](PhysicsParams p, const std::string& field) {
    try {
      p.validate();
      ADD_FAILURE() << field << ": accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
    EXPECT_THROW(PhysicsWorld(Scene{}, p), std::invalid_argument);
  };
  PhysicsParams p;
  EXPECT_NO_THROW(p.validate());
  p.fixed_dt = 0;
  expectField(p, "fixed_dt");
  p = {};
  p.max_substeps = 0;
  expectField(p, "max_substeps");
  p = {};
  p.max_force_per_object = std::nan("");
  expectField(p, "max_force_per_object");
  p = {};
  p.max_speed = -1;
  expectField(p, "max_speed");
  p = {};
  p.max_angular_speed = 0;
  expectField(p, "max_angular_speed");
  p = {};
  p.linear_damping = 1.5;
  expectField(p, "linear_damping");
  p = {};
  p.angular_damping = -0.1;
  expectField(p, "angular_damping");
  p = {};
  p.collision_margin = 0;
  expectField(p, "collision_margin");
  p = {};
  p.max_force_per_object = std::numeric_limits<double>::infinity();  // disables the clamp
  EXPECT_NO_THROW(p.validate());
}

}  // namespace
}  // namespace godhand
