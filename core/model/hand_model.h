// The immutable model of one cluster of God objects: rigid bodies (capsule, sphere, box) with
// mass and inertia, tied by joints into a tree. Loaded from protobuf text (schema:
// idl/hand_model.proto). The model never changes during a step (METHOD.md §1; STYLE habit 1).
//
// Joint frames: each joint stores its frame J in the parent (X_PJ) and in the child (X_CJ).
// At zero joint angles the two coincide. J's x axis is the primary (flexion / hinge) axis, z
// points along the child. Constraint rows per type (METHOD.md §2, paper §5):
//   Spherical2Dof: 3 point rows + 1 twist-lock row (x_P · y_C = 0); angles: 1 about the parent's
//                  x, 2 about the child's y (a universal joint, paper Eq. 25).
//   Revolute:      3 point rows + 2 axis rows (x_C ⟂ y_P, x_C ⟂ z_P); angle 1 about x (Eq. 26).
//   Fixed:         3 point rows + 3 orientation rows.
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "math/pose.h"

namespace godhand {

enum class ShapeType { Capsule, Sphere, Box };

/// Collision shape of a God object in its body frame (origin at the centre of mass).
struct Shape {
  ShapeType type = ShapeType::Sphere;
  double radius = 0.0;                 ///< capsule / sphere radius, m
  double half_length = 0.0;            ///< capsule: half the axis segment along local z, m
  Vec3 half_extents = Vec3::Zero();    ///< box, m
};

/// Principal moments of inertia (body frame, about the centre of mass) of a solid shape of
/// uniform density with total mass m. Capsule = cylinder + two hemispherical caps.
Vec3 inertiaDiagonal(const Shape& shape, double mass);

/// Principal moments (body frame, about the centre) of the mass m put at the shape's farthest
/// point from each axis: m max|r⊥|². What a turn moves the body's outermost point, the rotational
/// weight of a step by default (idl/hand_model.proto, RotationWeight FARTHEST_POINT).
Vec3 farthestPointInertia(const Shape& shape, double mass);

struct Body {
  std::string name;
  Shape shape;
  double mass = 0.0;                   ///< kg
  Vec3 inertia = Vec3::Zero();         ///< principal moments, body frame, kg m² (a uniform solid)
  Vec3 turn_inertia = Vec3::Zero();    ///< the step's rotational weight (Gauss' metric), body frame, kg m²:
                                       ///< farthestPointInertia or inertia (the model's rotation_weight)
  Pose X_MB_rest;                      ///< rest pose in the model frame
  std::string tracker_segment;         ///< which tracker segment drives it ("" = undriven)
};

enum class JointType { Spherical2Dof, Revolute, Fixed };

struct JointLimit {
  bool enabled = false;
  double lower = 0.0;                  ///< rad
  double upper = 0.0;                  ///< rad
};

struct Joint {
  std::string name;
  JointType type = JointType::Revolute;
  int parent = -1;
  int child = -1;
  Pose X_PJ;                           ///< joint frame in the parent body frame
  Pose X_CJ;                           ///< joint frame in the child body frame
  std::array<JointLimit, 2> limits{};  ///< angle 1, angle 2 (Spherical2Dof only)

  /// Number of equality rows: 4, 5 or 6.
  int equalityRows() const;
  /// Number of angles (1 or 2; 0 for Fixed).
  int angleCount() const;
};

/// Thrown on a bad model file: the message names the file, line and field.
class ModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bodies a model may have: the wire's bound on the poses of one hand (idl/godhand.idl).
constexpr int kMaxModelBodies = 32;

struct HandModel {
  std::string name;
  std::vector<Body> bodies;
  std::vector<Joint> joints;
  std::string notes;
  /// Joint indices in depth-first postorder (every joint after the joints below it, one chain
  /// after another). Assembling joint rows in this order keeps the Cholesky factor of the
  /// equality block sparse and banded: fill only towards the root, within each chain's block.
  std::vector<int> joint_order;

  int bodyIndex(const std::string& body_name) const;  ///< -1 if absent
  int equalityRows() const;                           ///< sum over joints

  /// World poses of all bodies at rest when the model frame is placed at X_WM.
  std::vector<Pose> restPoses(const Pose& X_WM) const;

  /// Parses and validates a model; throws ModelError with "SOURCE:LINE: field: reason" on any
  /// problem. `source` names the origin in error messages. (Reading a model file is
  /// loadHandModel in services/common/files.h: core opens no files.)
  static HandModel fromText(const std::string& text, const std::string& source);
};

/// Joint angles (rad) of joint j for the given body poses (world): [angle 1, angle 2].
/// Spherical2Dof: flexion about the parent's x, then abduction about the child's y.
/// Revolute: rotation about x. Fixed: zeros.
std::array<double, 2> jointAngles(const Joint& joint, const Pose& X_WP, const Pose& X_WC);

/// Distance between the two anchor points of a joint (the "joint gap" of METHOD.md §5), m.
double jointGap(const Joint& joint, const Pose& X_WP, const Pose& X_WC);

}  // namespace godhand
