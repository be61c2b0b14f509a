// The MuJoCo side of godhand-bench --compare (bridges/mujoco): the model it builds must be the
// hands and scene godhand sees, or the comparison compares something else. Oracles: analytic
// rest heights of a capsule and a box on a tilted, displaced table (shape axes, mesh placement:
// MuJoCo re-centres mesh assets, the geom must stay where the scene has it), the target pose of
// a body in free space (weld with the identity relative pose), counted resets on NaN targets.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "geometry/bvh.h"
#include "mujoco/mujoco_hands.h"
#include "pipeline/stages.h"
#include "scene/mesh_io.h"
#include "scene/scene.h"
#include "../pipeline/probe_model.h"

namespace godhand {
namespace {

// A static table: a box mesh (half extents 0.2 x 0.2 x 0.02) placed off its object frame's
// origin and turned in it by X_OM (MuJoCo moves a mesh asset to its centre of mass and principal
// axes; the geom must still put it where the scene has it), the object frame at `X_WO`.
Scene tableScene(const Pose& X_WO, const Pose& X_OM = Pose{}) {
  Scene s;
  s.name = "table";
  SceneObject o;
  o.id = "table";
  o.index = 0;
  o.X_WO = X_WO;
  geo::TriangleMesh mesh = boxMesh(Vec3(0.2, 0.2, 0.02));
  for (Vec3& v : mesh.vertices) v = X_OM * v;
  o.god = std::make_shared<geo::MeshBvh>(std::move(mesh));
  o.reference = o.god;
  o.source = "box";
  s.objects.push_back(std::move(o));
  return s;
}

// Drives the one-body model's target to `target` for `frames` frames at 100 Hz; returns the pose.
Pose settle(mujoco::Hands& hands, const Pose& target, int frames) {
  Pose T = target;
  const std::vector<HandInput> in{{true, &T, nullptr}};
  for (int k = 0; k < frames; ++k) hands.step(in);
  return hands.poses(0)[0];
}

TEST(MujocoHands, AFreeBodyIsPlacedAtItsTargetAndFollowsIt) {
  const HandModel probe = testing::probeModel("capsule { radius: 0.01 half_length: 0.02 }", 0.02);
  const Scene scene = tableScene(Pose{Vec3(0, 0, -1.0), Quat::Identity()});
  mujoco::Hands hands(scene, {&probe}, 0.01, mujoco::Params{});
  EXPECT_EQ(hands.stepsPerFrame(), 5);
  EXPECT_FALSE(hands.started(0));
  const Pose T0{Vec3(0.1, -0.2, 0.3), Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()))};
  const Pose first = settle(hands, T0, 1);
  EXPECT_TRUE(hands.started(0));
  EXPECT_LT((first.p - T0.p).norm(), 1e-9) << "placed at the target, at rest";
  EXPECT_LT(first.q.angularDistance(T0.q), 1e-9);
  const Pose T1{Vec3(0.12, -0.2, 0.3), Quat(Eigen::AngleAxisd(0.9, Vec3(1, 2, 3).normalized()))};
  const Pose later = settle(hands, T1, 100);  // 1 s against a 0.02 s time constant
  EXPECT_LT((later.p - T1.p).norm(), 1e-4);
  EXPECT_LT(later.q.angularDistance(T1.q), 1e-3);
  EXPECT_FALSE(hands.loaded(0));
}

// A capsule lying along world y (its axis is local z, turned by 90 degrees about x) and a box
// pressed 5 mm into a table whose mesh is displaced and tilted in its object frame and the object
// in the world: each rests 2.5 mm inside the table plane (see below).
TEST(MujocoHands, ShapesRestOnADisplacedTiltedTableWhereTheSceneHasIt) {
  const Pose X_WO{Vec3(0.3, -0.1, 0.05), Quat(Eigen::AngleAxisd(0.3, Vec3::UnitY()))};
  const Pose X_OM{Vec3(0.05, 0.02, -0.03), Quat(Eigen::AngleAxisd(-0.2, Vec3::UnitX()))};
  const Scene scene = tableScene(X_WO, X_OM);
  const Pose X_WM = X_WO * X_OM;  // the box's own frame in the world
  const Quat tilt = X_WM.q;
  const Vec3 up = tilt * Vec3::UnitZ();
  const Vec3 top = X_WM * Vec3(0.0, 0.0, 0.02);  // a point on the table's top face
  struct Case {
    std::string shape;
    Quat q_local;  // the body's orientation in the table frame
    double low;    // its lowest point below its origin, along the table normal
  };
  const std::vector<Case> cases = {
      {"capsule { radius: 0.01 half_length: 0.03 }", Quat(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitX())), 0.01},
      {"box { half_extents { x: 0.01 y: 0.02 z: 0.005 } }", Quat::Identity(), 0.005},
  };
  for (const Case& c : cases) {
    const HandModel probe = testing::probeModel(c.shape, 0.02);
    mujoco::Hands hands(scene, {&probe}, 0.01, mujoco::Params{});
    const Quat q = tilt * c.q_local;
    const Pose above{top + up * (c.low + 0.01), q};
    settle(hands, above, 20);
    EXPECT_FALSE(hands.loaded(0)) << c.shape << ": 1 cm above the table";
    const Pose pressed{top + up * (c.low - 0.005), q};
    const Pose rest = settle(hands, pressed, 200);
    const double depth = -(up.dot(rest.p - top) - c.low);  // > 0: inside the table
    std::printf("[figure] %s pressed 5 mm into the tilted table: rests %.3f mm inside (MuJoCo's soft contact)\n",
                c.shape.c_str(), depth * 1e3);
    EXPECT_TRUE(hands.loaded(0)) << c.shape;
    // Weld and contact with the same time constant (and MuJoCo's default impedance) are equally
    // stiff: at rest they share the 5 mm, half each; a wrong shape axis (30 mm off) or a
    // re-centred table (cm) would be far from it.
    EXPECT_NEAR(depth, 0.0025, 1e-4) << c.shape;
  }
}

TEST(MujocoHands, NaNTargetsAreCountedAndIgnoredAndAnUnstableStepIsACountedReset) {
  const HandModel probe = testing::probeModel("sphere { radius: 0.01 }", 0.02);
  const Scene scene = tableScene(Pose{Vec3(0, 0, -1.0), Quat::Identity()});
  mujoco::Hands hands(scene, {&probe}, 0.01, mujoco::Params{});
  const Pose good{Vec3(0, 0, 0.2), Quat::Identity()};
  settle(hands, good, 5);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Pose held = settle(hands, Pose{Vec3(nan, 0, 0.2), Quat::Identity()}, 3);
  EXPECT_EQ(hands.rejectedTargets(), 3);
  EXPECT_LT((held.p - good.p).norm(), 1e-6) << "the hand keeps its last targets";
  EXPECT_EQ(hands.resets(), 0);
  // A target 1e30 m away is finite but no simulation survives it: MuJoCo's own bad-number check
  // resets its data; counted, the poses stay finite, the hand starts again at its next target.
  settle(hands, Pose{Vec3(1e30, 0, 0), Quat::Identity()}, 2);
  EXPECT_GE(hands.resets(), 1);
  EXPECT_TRUE(hands.poses(0)[0].p.allFinite());
  const Pose again = settle(hands, good, 1);
  EXPECT_LT((again.p - good.p).norm(), 1e-9);
}

TEST(MujocoHands, BadParametersAndObjectsAreRefusedByName) {
  const HandModel probe = testing::probeModel("sphere { radius: 0.01 }", 0.02);
  const Scene scene = tableScene(Pose{});
  mujoco::Params p;
  p.timestep = 0.0;
  EXPECT_THROW(mujoco::modelXml(scene, {&probe}, p), std::invalid_argument);
  Scene empty_object = scene;
  empty_object.objects[0].god.reset();
  empty_object.objects[0].reference.reset();
  try {
    mujoco::modelXml(empty_object, {&probe}, mujoco::Params{});
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'table' has no mesh"), std::string::npos) << e.what();
  }
  EXPECT_THROW(mujoco::Hands(scene, {&probe}, 0.0, mujoco::Params{}), std::invalid_argument);
  EXPECT_NE(mujoco::version().find("MuJoCo "), std::string::npos);
}

}  // namespace
}  // namespace godhand
