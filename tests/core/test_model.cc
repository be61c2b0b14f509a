// Model loading, validation and joint kinematics (core/model).
//
// Oracles: independent inertia formulas (sphere, box) and a numeric integration plus a
// Monte-Carlo estimate of a uniform-density capsule; error messages checked for the file name,
// the exact line (found in the text by a marker, not hard-coded) and the field path; joint
// angles recovered from poses built with known Rx(θ1) Ry(θ2).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "common/files.h"
#include "model/hand_model.h"

namespace godhand {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string modelPath(const std::string& file) { return std::string(GODHAND_MODELS_DIR) + "/" + file; }

Quat rotX(double a) { return Quat(Eigen::AngleAxisd(a, Vec3::UnitX())); }
Quat rotY(double a) { return Quat(Eigen::AngleAxisd(a, Vec3::UnitY())); }

// ---------------------------------------------------------------------------------------------
// Shipped models

TEST(ModelShipped, Hand16LoadsWithExpectedStructure) {
  const HandModel m = loadHandModel(modelPath("hand16_right.pbtxt"));
  EXPECT_EQ(m.name, "hand16_right");
  ASSERT_EQ(m.bodies.size(), 16u);
  ASSERT_EQ(m.joints.size(), 15u);
  EXPECT_EQ(m.equalityRows(), 70);  // 5 × SPHERICAL_2DOF (4) + 10 × REVOLUTE (5)
  int spherical = 0, revolute = 0;
  for (const Joint& j : m.joints) {
    spherical += j.type == JointType::Spherical2Dof;
    revolute += j.type == JointType::Revolute;
  }
  EXPECT_EQ(spherical, 5);
  EXPECT_EQ(revolute, 10);
  EXPECT_EQ(m.bodyIndex("palm"), 0);
  EXPECT_EQ(m.bodyIndex("pinky.3"), 15);
  EXPECT_EQ(m.bodyIndex("no such body"), -1);
  EXPECT_FALSE(m.notes.empty());
  // Each body's inertia is the one derived from its shape and mass; the rest pose closes every
  // joint and sits at zero angles (the model validator's claims, re-checked here).
  for (const Body& b : m.bodies) {
    EXPECT_GT(b.mass, 0.0) << b.name;
    EXPECT_EQ(b.inertia, inertiaDiagonal(b.shape, b.mass)) << b.name;
    EXPECT_FALSE(b.tracker_segment.empty()) << b.name;
  }
  const auto rest = m.restPoses(Pose{});
  for (const Joint& j : m.joints) {
    // (To round-off: the loader rejects a model only above 1e-6, so that bound would pass any
    // model that loaded.)
    EXPECT_LT(jointGap(j, rest[static_cast<size_t>(j.parent)], rest[static_cast<size_t>(j.child)]), 1e-12) << j.name;
    const auto a = jointAngles(j, rest[static_cast<size_t>(j.parent)], rest[static_cast<size_t>(j.child)]);
    EXPECT_NEAR(a[0], 0.0, 1e-12) << j.name;
    EXPECT_NEAR(a[1], 0.0, 1e-12) << j.name;
  }
}

TEST(ModelShipped, Hand6AndTool1Load) {
  const HandModel h6 = loadHandModel(modelPath("hand6_right.pbtxt"));
  EXPECT_EQ(h6.bodies.size(), 6u);
  EXPECT_TRUE(h6.joints.empty());
  EXPECT_EQ(h6.equalityRows(), 0);
  EXPECT_EQ(h6.bodies[0].shape.type, ShapeType::Box);
  for (size_t i = 1; i < 6; ++i) EXPECT_EQ(h6.bodies[i].shape.type, ShapeType::Sphere);

  const HandModel tool = loadHandModel(modelPath("tool1.pbtxt"));
  ASSERT_EQ(tool.bodies.size(), 1u);
  EXPECT_TRUE(tool.joints.empty());
  EXPECT_EQ(tool.bodies[0].shape.type, ShapeType::Box);
  EXPECT_EQ(tool.bodies[0].shape.half_extents, Vec3(0.01, 0.01, 0.06));
  EXPECT_DOUBLE_EQ(tool.bodies[0].mass, 0.2);
}

TEST(ModelShipped, RestPosesComposeWithModelFrame) {
  const HandModel m = loadHandModel(modelPath("hand16_right.pbtxt"));
  Pose X_WM;
  X_WM.p = Vec3(0.3, -0.2, 1.1);
  X_WM.q = Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  const auto rest = m.restPoses(X_WM);
  ASSERT_EQ(rest.size(), m.bodies.size());
  for (size_t i = 0; i < rest.size(); ++i) {
    const Vec3 expect_p = X_WM.p + X_WM.q * m.bodies[i].X_MB_rest.p;
    EXPECT_LT((rest[i].p - expect_p).norm(), 1e-15);
    EXPECT_LT(rest[i].q.angularDistance(X_WM.q * m.bodies[i].X_MB_rest.q), 1e-12);
  }
}

// ---------------------------------------------------------------------------------------------
// Inertia

TEST(ModelInertia, SphereAndBoxMatchClosedForms) {
  Shape s;
  s.type = ShapeType::Sphere;
  s.radius = 0.03;
  const Vec3 is = inertiaDiagonal(s, 0.7);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(is[a], 2.0 / 5.0 * 0.7 * 0.03 * 0.03, 1e-18);

  Shape b;
  b.type = ShapeType::Box;
  b.half_extents = Vec3(0.01, 0.02, 0.05);  // full sides 0.02, 0.04, 0.10
  const double m = 0.3;
  const Vec3 ib = inertiaDiagonal(b, m);
  // I_x = m (b² + c²) / 12 with full side lengths = m/3 (h_y² + h_z²) with half extents.
  EXPECT_NEAR(ib.x(), m * (0.04 * 0.04 + 0.10 * 0.10) / 12.0, 1e-16);
  EXPECT_NEAR(ib.y(), m * (0.02 * 0.02 + 0.10 * 0.10) / 12.0, 1e-16);
  EXPECT_NEAR(ib.z(), m * (0.02 * 0.02 + 0.04 * 0.04) / 12.0, 1e-16);
}

/// Capsule moments by slicing along the axis: a disk of radius ρ(z) contributes
/// dI_z = ½ρ² dm, dI_x = (¼ρ² + z²) dm with dm ∝ πρ² dz. Composite Simpson, normalised by the
/// integrated volume (uniform density, total mass m).
Vec3 capsuleInertiaBySlicing(double r, double h, double m) {
  const int n = 200000;  // even
  const double z0 = -(h + r), z1 = h + r, dz = (z1 - z0) / n;
  double vol = 0, ix = 0, iz = 0;
  for (int i = 0; i <= n; ++i) {
    const double z = z0 + i * dz;
    const double over = std::abs(z) - h;
    const double rho2 = over <= 0 ? r * r : std::max(0.0, r * r - over * over);
    const double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    const double area = kPi * rho2;
    vol += w * area;
    iz += w * area * 0.5 * rho2;
    ix += w * area * (0.25 * rho2 + z * z);
  }
  return Vec3(ix, ix, iz) * (m / vol);
}

/// Capsule moments by Monte-Carlo: uniform points in the bounding box, kept when within r of
/// the axis segment (a fully independent check of the shape definition).
Vec3 capsuleInertiaMonteCarlo(double r, double h, double m, int samples) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> ux(-r, r), uz(-(h + r), h + r);
  double sx = 0, sy = 0, sz = 0;
  long inside = 0;
  for (int i = 0; i < samples; ++i) {
    const double x = ux(rng), y = ux(rng), z = uz(rng);
    const double zc = std::clamp(z, -h, h);
    if (x * x + y * y + (z - zc) * (z - zc) > r * r) continue;
    ++inside;
    sx += y * y + z * z;
    sy += x * x + z * z;
    sz += x * x + y * y;
  }
  return Vec3(sx, sy, sz) * (m / static_cast<double>(inside));
}

TEST(ModelInertia, CapsuleMatchesNumericIntegration) {
  struct Case { double r, h, m; };
  for (const Case& c : {Case{0.009, 0.02, 0.0146}, Case{0.01, 0.0, 0.01}, Case{0.005, 0.1, 1.0}, Case{0.02, 0.005, 0.3}}) {
    Shape s;
    s.type = ShapeType::Capsule;
    s.radius = c.r;
    s.half_length = c.h;
    const Vec3 got = inertiaDiagonal(s, c.m);
    const Vec3 slice = capsuleInertiaBySlicing(c.r, c.h, c.m);
    const Vec3 mc = capsuleInertiaMonteCarlo(c.r, c.h, c.m, 400000);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(got[a], slice[a], 1e-7 * slice[a]) << "r=" << c.r << " h=" << c.h << " axis " << a;
      EXPECT_NEAR(got[a], mc[a], 1e-2 * mc[a]) << "Monte-Carlo, r=" << c.r << " h=" << c.h << " axis " << a;
    }
    if (c.h == 0.0) {  // degenerates to a sphere
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(got[a], 0.4 * c.m * c.r * c.r, 1e-15 * c.m);
    }
  }
}

/// The farthest-point weight against an independent search: m times the largest squared distance
/// from each body axis over the shape. A box is convex, so the maximum of that convex function is
/// at a vertex: all 8 are tried. For a sphere and a capsule, 200,000 random points of the surface
/// (the end spheres of a capsule): none may exceed the weight, and the best comes within 0.1 %.
TEST(ModelInertia, FarthestPointWeightIsTheMassAtTheFarthestSurfacePoint) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g;
  auto brute = [&](const Shape& s, double m) {
    Vec3 best = Vec3::Zero();
    auto take = [&](const Vec3& p) {
      best = best.cwiseMax(m * Vec3(p.y() * p.y() + p.z() * p.z(), p.x() * p.x() + p.z() * p.z(), p.x() * p.x() + p.y() * p.y()));
    };
    if (s.type == ShapeType::Box) {
      for (int k = 0; k < 8; ++k)
        take(Vec3((k & 1) ? 1 : -1, (k & 2) ? 1 : -1, (k & 4) ? 1 : -1).cwiseProduct(s.half_extents));
      return best;
    }
    for (int i = 0; i < 200000; ++i) {
      const Vec3 u = Vec3{g(rng), g(rng), g(rng)}.normalized();  // braced: drawn left to right
      const double end = s.type == ShapeType::Capsule ? (u.z() >= 0 ? s.half_length : -s.half_length) : 0.0;
      take(Vec3(0, 0, end) + s.radius * u);
    }
    return best;
  };
  Shape sphere, box, capsule;
  sphere.type = ShapeType::Sphere;
  sphere.radius = 0.011;
  box.type = ShapeType::Box;
  box.half_extents = Vec3(0.04, 0.045, 0.012);
  capsule.type = ShapeType::Capsule;
  capsule.radius = 0.009;
  capsule.half_length = 0.02;
  for (const Shape* s : {&sphere, &box, &capsule}) {
    const Vec3 got = farthestPointInertia(*s, 0.3), want = brute(*s, 0.3), solid = inertiaDiagonal(*s, 0.3);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(want[a], got[a] * (1 + 1e-12)) << "a point beyond the weight: shape " << static_cast<int>(s->type) << " axis " << a;
      EXPECT_GE(want[a], got[a] * (s->type == ShapeType::Box ? 1 - 1e-12 : 1 - 1e-3)) << "shape " << static_cast<int>(s->type) << " axis " << a;
      EXPECT_GT(got[a], 1.99 * solid[a]) << "never less than twice the solid's: shape " << static_cast<int>(s->type);
    }
  }
  // A box's is exactly three times its solid inertia.
  EXPECT_LT((farthestPointInertia(box, 0.3) - 3.0 * inertiaDiagonal(box, 0.3)).norm(), 1e-15);
}

/// A model's rotational weight: the farthest point's unless the file asks for the solid's.
TEST(ModelInertia, RotationWeightIsTheFarthestPointsUnlessSolidIsAsked) {
  const std::string body = "bodies { name: \"a\" box { half_extents { x: 0.01 y: 0.02 z: 0.03 } } mass: 0.1 }\n";
  for (const char* weight : {"", "rotation_weight: FARTHEST_POINT\n", "rotation_weight: SOLID\n"}) {
    const HandModel m = HandModel::fromText(std::string("name: \"w\"\n") + weight + body, "w.pbtxt");
    const Body& b = m.bodies[0];
    EXPECT_EQ(b.inertia, inertiaDiagonal(b.shape, b.mass)) << weight;
    EXPECT_EQ(b.turn_inertia, std::string(weight).find("SOLID") != std::string::npos ? b.inertia : farthestPointInertia(b.shape, b.mass))
        << weight;
  }
  EXPECT_THROW(HandModel::fromText("name: \"w\"\nrotation_weight: HEAVIEST\n" + body, "w.pbtxt"), ModelError);
}

// ---------------------------------------------------------------------------------------------
// Bad model files

// A valid two-body model; each bad case replaces exactly one marker line.
const char* const kGood =
    "name: \"two\"\n"
    "bodies {\n"
    "  name: \"a\"\n"
    "  sphere { radius: 0.01 }\n"
    "  mass: 0.1\n"
    "}\n"
    "bodies {\n"
    "  name: \"b\"\n"
    "  capsule { radius: 0.01 half_length: 0.02 }\n"
    "  mass: 0.05\n"
    "  rest_position { x: 0 y: 0 z: 0.04 }\n"
    "}\n"
    "joints {\n"
    "  name: \"j\" type: REVOLUTE parent: \"a\" child: \"b\"\n"
    "  anchor_parent { x: 0 y: 0 z: 0.01 }\n"
    "  anchor_child { x: 0 y: 0 z: -0.03 }\n"
    "  axis_parent { x: 1 y: 0 z: 0 }\n"
    "  axis_child { x: 1 y: 0 z: 0 }\n"
    "  reference_parent { x: 0 y: 0 z: 1 }\n"
    "  reference_child { x: 0 y: 0 z: 1 }\n"
    "  limits { angle: 1 lower: -1 upper: 1 }\n"
    "}\n";

/// 1-based line of the first line containing `marker`, counting from `from` (0-based offset).
int lineOf(const std::string& text, const std::string& marker, size_t from = 0) {
  const size_t pos = text.find(marker, from);
  if (pos == std::string::npos) return -1;
  int line = 1;
  for (size_t i = 0; i < pos; ++i) line += text[i] == '\n';
  return line;
}

/// The text with the first occurrence of `from` replaced by `to` (must exist).
std::string replaced(const std::string& text, const std::string& from, const std::string& to) {
  const size_t pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  std::string out = text;
  if (pos != std::string::npos) out.replace(pos, from.size(), to);
  return out;
}

/// Parses `text` as "bad.pbtxt"; returns the ModelError message, or "" if it was accepted.
std::string errorOf(const std::string& text) {
  try {
    HandModel::fromText(text, "bad.pbtxt");
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

/// Checks "bad.pbtxt:LINE:" at the start and that the field path appears after it.
void expectError(const std::string& text, int line, const std::string& field, const std::string& reason_word) {
  ASSERT_GT(line, 0);
  const std::string msg = errorOf(text);
  ASSERT_FALSE(msg.empty()) << "accepted:\n" << text;
  const std::string prefix = "bad.pbtxt:" + std::to_string(line) + ":";
  EXPECT_EQ(msg.rfind(prefix, 0), 0u) << "expected prefix '" << prefix << "' in: " << msg;
  EXPECT_NE(msg.find(field), std::string::npos) << "field '" << field << "' not named in: " << msg;
  EXPECT_NE(msg.find(reason_word), std::string::npos) << "'" << reason_word << "' not in: " << msg;
}

TEST(ModelErrors, GoodModelParses) {
  const HandModel m = HandModel::fromText(kGood, "good.pbtxt");
  ASSERT_EQ(m.bodies.size(), 2u);
  ASSERT_EQ(m.joints.size(), 1u);
  EXPECT_EQ(m.joints[0].parent, 0);
  EXPECT_EQ(m.joints[0].child, 1);
  EXPECT_TRUE(m.joints[0].limits[0].enabled);
  EXPECT_FALSE(m.joints[0].limits[1].enabled);
  EXPECT_EQ(m.equalityRows(), 5);
}

TEST(ModelErrors, SyntaxErrorNamesFileAndLine) {
  const std::string text = replaced(kGood, "  mass: 0.05\n", "  mass: zero\n");
  const std::string msg = errorOf(text);
  const int line = lineOf(text, "mass: zero");
  EXPECT_EQ(msg.rfind("bad.pbtxt:" + std::to_string(line) + ":", 0), 0u) << msg;
  // Unknown field name: the message names the field.
  const std::string text2 = replaced(kGood, "  mass: 0.05\n", "  masss: 0.05\n");
  const std::string msg2 = errorOf(text2);
  EXPECT_EQ(msg2.rfind("bad.pbtxt:" + std::to_string(lineOf(text2, "masss")) + ":", 0), 0u) << msg2;
  EXPECT_NE(msg2.find("masss"), std::string::npos) << msg2;
  // Unterminated message: reported at (or after) the last line, never as line 0 or "?".
  const std::string text3 = std::string(kGood).substr(0, std::string(kGood).size() - 2);  // drop "}\n"
  const std::string msg3 = errorOf(text3);
  EXPECT_EQ(msg3.rfind("bad.pbtxt:", 0), 0u) << msg3;
  EXPECT_EQ(msg3.find("bad.pbtxt:0:"), std::string::npos) << msg3;
}

TEST(ModelErrors, MissingShape) {
  const std::string text = replaced(kGood, "  sphere { radius: 0.01 }\n", "");
  expectError(text, lineOf(text, "bodies {"), "bodies[0]", "shape");
}

TEST(ModelErrors, BadShapeDimensions) {
  const std::string text = replaced(kGood, "capsule { radius: 0.01 half_length: 0.02 }", "capsule { radius: 0 half_length: 0.02 }");
  expectError(text, lineOf(text, "capsule {"), "bodies[1].capsule", "radius");
  const std::string box = replaced(kGood, "sphere { radius: 0.01 }", "box { half_extents { x: 0.01 y: -0.01 z: 0.01 } }");
  expectError(box, lineOf(box, "box {"), "bodies[0].box", "half_extents");
}

TEST(ModelErrors, NegativeMass) {
  const std::string text = replaced(kGood, "  mass: 0.05\n", "  mass: -0.05\n");
  expectError(text, lineOf(text, "mass: -0.05"), "bodies[1].mass", "mass");
  // The value as it was written, not as 180 digits or "0.000000".
  const std::string huge = replaced(kGood, "  mass: 0.05\n", "  mass: 1e300\n");
  expectError(huge, lineOf(huge, "mass: 1e300"), "bodies[1].mass", "got 1e+300");
  const std::string tiny = replaced(kGood, "  mass: 0.05\n", "  mass: 1e-300\n");
  expectError(tiny, lineOf(tiny, "mass: 1e-300"), "bodies[1].mass", "got 1e-300");
  // A missing mass (proto3 default 0) is reported at the body.
  const std::string text2 = replaced(kGood, "  mass: 0.05\n", "");
  const int second_body = lineOf(text2, "bodies {", text2.find("bodies {") + 1);
  expectError(text2, second_body, "bodies[1].mass", "mass");
}

TEST(ModelErrors, TooManyBodiesAndUnknownRotationWeight) {
  // 33 bodies: refused at once (a hand's samples carry at most 32 poses; 3,000 bodies once ran the
  // machine out of memory before any message).
  std::string many;
  for (int i = 0; i < 33; ++i)
    many += "bodies { name: \"b" + std::to_string(i) + "\" sphere { radius: 0.01 } mass: 0.01 }\n";
  const std::string msg = errorOf(many);
  EXPECT_NE(msg.find("33 bodies; a model has at most 32"), std::string::npos) << msg;
  std::string ok;
  for (int i = 0; i < 32; ++i) ok += "bodies { name: \"b" + std::to_string(i) + "\" sphere { radius: 0.01 } mass: 0.01 }\n";
  EXPECT_EQ(errorOf(ok), "");
  // proto3 text takes an unknown enum number; the model does not.
  const std::string weight = errorOf("rotation_weight: 7\n" + std::string(kGood));
  EXPECT_NE(weight.find("rotation_weight: unknown value 7"), std::string::npos) << weight;
}

TEST(ModelErrors, DuplicateBodyName) {
  const std::string text = replaced(kGood, "  name: \"b\"\n", "  name: \"a\"\n");
  const int second = lineOf(text, "name: \"a\"", text.find("name: \"a\"") + 1);
  expectError(text, second, "bodies[1].name", "duplicate");
}

TEST(ModelErrors, UnknownParentAndChild) {
  const std::string text = replaced(kGood, "parent: \"a\"", "parent: \"nope\"");
  expectError(text, lineOf(text, "parent: \"nope\""), "joints[0].parent", "nope");
  const std::string text2 = replaced(kGood, "child: \"b\"", "child: \"nobody\"");
  expectError(text2, lineOf(text2, "child: \"nobody\""), "joints[0].child", "nobody");
}

TEST(ModelErrors, NonOrthogonalOrZeroAxis) {
  const std::string text = replaced(kGood, "reference_child { x: 0 y: 0 z: 1 }", "reference_child { x: 0.5 y: 0 z: 1 }");
  expectError(text, lineOf(text, "reference_child"), "joints[0].reference_child", "orthogonal");
  const std::string text2 = replaced(kGood, "axis_parent { x: 1 y: 0 z: 0 }", "axis_parent { x: 0 y: 0 z: 0 }");
  expectError(text2, lineOf(text2, "axis_parent"), "joints[0].axis_parent", "non-zero");
}

TEST(ModelErrors, LimitsLowerAboveUpper) {
  const std::string text = replaced(kGood, "limits { angle: 1 lower: -1 upper: 1 }", "limits { angle: 1 lower: 1 upper: -1 }");
  expectError(text, lineOf(text, "limits {"), "joints[0].limits[0]", "lower");
}

TEST(ModelErrors, SecondAngleOnRevolute) {
  const std::string text = replaced(kGood, "  limits { angle: 1 lower: -1 upper: 1 }\n",
                                    "  limits { angle: 1 lower: -1 upper: 1 }\n  limits { angle: 2 lower: -1 upper: 1 }\n");
  expectError(text, lineOf(text, "angle: 2"), "joints[0].limits[1]", "angle");
}

TEST(ModelErrors, RestPoseOutsideLimits) {
  const std::string text = replaced(kGood, "lower: -1 upper: 1", "lower: 0.2 upper: 1");
  expectError(text, lineOf(text, "limits {"), "joints[0].limits[0]", "outside");
}

TEST(ModelErrors, RestFramesViolateLockedDirections) {
  // Orthogonal to its reference, but at rest the child's hinge axis is not the parent's.
  const std::string text = replaced(kGood, "axis_child { x: 1 y: 0 z: 0 }", "axis_child { x: 0 y: 1 z: 0 }");
  expectError(text, lineOf(text, "axis_child"), "joints[0].axis_child", "locked");
}

TEST(ModelErrors, RestAnchorsDoNotCoincide) {
  const std::string text = replaced(kGood, "rest_position { x: 0 y: 0 z: 0.04 }", "rest_position { x: 0 y: 0 z: 0.05 }");
  expectError(text, lineOf(text, "anchor_child"), "joints[0].anchor_child", "apart");
}

TEST(ModelErrors, NonUnitRestOrientation) {
  const std::string text = replaced(kGood, "  rest_position { x: 0 y: 0 z: 0.04 }\n",
                                    "  rest_position { x: 0 y: 0 z: 0.04 }\n  rest_orientation { w: 0.9 x: 0 y: 0 z: 0 }\n");
  expectError(text, lineOf(text, "rest_orientation"), "bodies[1].rest_orientation", "unit");
}

TEST(ModelErrors, TwoParents) {
  // Third body c hanging off a; then a second joint gives b a second parent.
  std::string text = replaced(kGood, "joints {\n",
                              "bodies {\n  name: \"c\"\n  sphere { radius: 0.01 }\n  mass: 0.1\n}\njoints {\n");
  text += "joints {\n"
          "  name: \"k\" type: FIXED parent: \"c\" child: \"b\"\n"
          "  anchor_parent { x: 0 y: 0 z: 0.01 }\n"
          "  anchor_child { x: 0 y: 0 z: -0.03 }\n"
          "  axis_parent { x: 1 y: 0 z: 0 }\n"
          "  axis_child { x: 1 y: 0 z: 0 }\n"
          "  reference_parent { x: 0 y: 0 z: 1 }\n"
          "  reference_child { x: 0 y: 0 z: 1 }\n"
          "}\n";
  expectError(text, lineOf(text, "name: \"k\""), "joints[1].child", "parent");
}

TEST(ModelErrors, Cycle) {
  // a → b (the good joint), then b → a: a has no parent yet, so only a cycle check catches it.
  const std::string text = std::string(kGood) +
                           "joints {\n"
                           "  name: \"back\" type: FIXED parent: \"b\" child: \"a\"\n"
                           "  anchor_parent { x: 0 y: 0 z: -0.03 }\n"
                           "  anchor_child { x: 0 y: 0 z: 0.01 }\n"
                           "  axis_parent { x: 1 y: 0 z: 0 }\n"
                           "  axis_child { x: 1 y: 0 z: 0 }\n"
                           "  reference_parent { x: 0 y: 0 z: 1 }\n"
                           "  reference_child { x: 0 y: 0 z: 1 }\n"
                           "}\n";
  expectError(text, lineOf(text, "name: \"back\""), "joints[1].child", "cycle");
  // A joint from a body to itself.
  const std::string self = replaced(kGood, "child: \"b\"", "child: \"a\"");
  expectError(self, lineOf(self, "child: \"a\""), "joints[0].child", "itself");
}

TEST(ModelErrors, NoBodies) {
  const std::string msg = errorOf("name: \"empty\"\n");
  EXPECT_EQ(msg.rfind("bad.pbtxt:1:", 0), 0u) << msg;
  EXPECT_NE(msg.find("bodies"), std::string::npos) << msg;
}

TEST(ModelErrors, MissingFile) {
  const std::string path = "/nonexistent/dir/missing_model.pbtxt";
  try {
    loadHandModel(path);
    FAIL() << "loadHandModel accepted a missing file";
  } catch (const ModelError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path, 0), 0u) << msg;
    EXPECT_NE(msg.find("cannot open"), std::string::npos) << msg;
  }
}

TEST(ModelErrors, LoadFileReportsPathInParseErrors) {
  // A model file is parsed through loadHandModel with its own path as the source.
  const std::string path = ::testing::TempDir() + "godhand_bad_model.pbtxt";
  const std::string text = replaced(kGood, "  mass: 0.05\n", "  mass: -0.05\n");
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(text.data(), 1, text.size(), f);
    std::fclose(f);
  }
  try {
    loadHandModel(path);
    FAIL() << "accepted";
  } catch (const ModelError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ":" + std::to_string(lineOf(text, "mass: -0.05")) + ":", 0), 0u) << e.what();
  }
  std::remove(path.c_str());
}

// ---------------------------------------------------------------------------------------------
// Joint angles and gap

/// Child pose such that the joint's angles are (θ1, θ2) and its anchors coincide:
/// R_WJc = R_WJp Rx(θ1) Ry(θ2).
Pose childPose(const Joint& j, const Pose& X_WP, double t1, double t2) {
  const Quat q_WJp = X_WP.q * j.X_PJ.q;
  const Quat q_WJc = q_WJp * rotX(t1) * rotY(t2);
  Pose X_WC;
  X_WC.q = (q_WJc * j.X_CJ.q.conjugate()).normalized();
  const Vec3 anchor = X_WP * j.X_PJ.p;
  X_WC.p = anchor - X_WC.q * j.X_CJ.p;
  return X_WC;
}

TEST(ModelJointAngles, RecoverKnownFlexionAndAbduction) {
  const HandModel m = loadHandModel(modelPath("hand16_right.pbtxt"));
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double worst = 0.0, worst_gap = 0.0;
  for (const Joint& j : m.joints) {
    for (int trial = 0; trial < 200; ++trial) {
      Pose X_WP;
      // Braced lists draw left to right (function arguments: in an unspecified order, which
      // gcc and clang take differently).
      X_WP.p = Vec3{u(rng), u(rng), u(rng)};
      X_WP.q = Quat{u(rng), u(rng), u(rng), u(rng)}.normalized();
      // Full range of atan2 except the ±π seam; abduction within (−π/2, π/2).
      const double t1 = 3.1 * u(rng);
      const double t2 = j.type == JointType::Spherical2Dof ? 1.5 * u(rng) : 0.0;
      const Pose X_WC = childPose(j, X_WP, t1, t2);
      const auto a = jointAngles(j, X_WP, X_WC);
      worst = std::max({worst, std::abs(a[0] - t1), std::abs(a[1] - t2)});
      worst_gap = std::max(worst_gap, jointGap(j, X_WP, X_WC));
    }
  }
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(worst_gap, 1e-14);
}

TEST(ModelJointAngles, RevoluteIgnoresNothingAndGapIsAnchorDistance) {
  const HandModel m = loadHandModel(modelPath("hand16_right.pbtxt"));
  const Joint& j = m.joints[1];  // thumb.mcp, revolute
  ASSERT_EQ(j.type, JointType::Revolute);
  const Pose X_WP = m.restPoses(Pose{})[static_cast<size_t>(j.parent)];
  Pose X_WC = childPose(j, X_WP, 0.4, 0.0);
  EXPECT_NEAR(jointAngles(j, X_WP, X_WC)[0], 0.4, 1e-12);
  EXPECT_EQ(jointAngles(j, X_WP, X_WC)[1], 0.0);
  // Translate the child: the gap is the translation length.
  const Vec3 d(0.001, -0.002, 0.0005);
  X_WC.p += d;
  EXPECT_NEAR(jointGap(j, X_WP, X_WC), d.norm(), 1e-15);
}

}  // namespace
}  // namespace godhand

namespace godhand {
namespace {

// Review findings: sizes and masses whose derived inertia overflows, underflows or is NaN, and a
// limit angle beyond int range, must be rejected with file:line:field, never loaded or crash.
TEST(ModelErrors, ExtremeSizesAndMassesAreRejected) {
  const int a_sphere = lineOf(kGood, "sphere { radius: 0.01 }");
  expectError(replaced(kGood, "sphere { radius: 0.01 }", "sphere { radius: 1e200 }"), a_sphere, "bodies[0].sphere", "dimensions");
  expectError(replaced(kGood, "sphere { radius: 0.01 }", "sphere { radius: 1e-200 }"), a_sphere, "bodies[0].sphere", "dimensions");
  const int b_capsule = lineOf(kGood, "capsule {");
  expectError(replaced(kGood, "half_length: 0.02", "half_length: 1e308"), b_capsule, "bodies[1].capsule", "dimensions");
  const int a_mass = lineOf(kGood, "  mass: 0.1\n");
  expectError(replaced(kGood, "  mass: 0.1\n", "  mass: 1e-320\n"), a_mass, "bodies[0].mass", "mass");
  expectError(replaced(kGood, "  mass: 0.1\n", "  mass: 1e308\n"), a_mass, "bodies[0].mass", "mass");
  const int box_line = a_sphere;
  expectError(replaced(kGood, "sphere { radius: 0.01 }", "box { half_extents { x: 0.01 y: 1e200 z: 0.01 } }"), box_line,
              "bodies[0].box", "dimensions");
}

TEST(ModelErrors, HugeLimitAngleIsRejected) {
  const int line = lineOf(kGood, "limits {");
  for (const char* angle : {"4294967295", "2147483648", "3"})
    expectError(replaced(kGood, "limits { angle: 1", std::string("limits { angle: ") + angle), line, "limits[0]", "angle");
}

}  // namespace
}  // namespace godhand
