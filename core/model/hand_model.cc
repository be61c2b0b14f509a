#include "model/hand_model.h"

#include <google/protobuf/text_format.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "model/text_proto.h"
#include "hand_model.pb.h"

namespace godhand {

namespace {

/// A number as a person reads it (1e+300, 1e-300, 0.05), not std::to_string's fixed six decimals.
std::string shortest(double x) {
  std::ostringstream os;
  os.precision(6);
  os << x;
  return os.str();
}

constexpr double kPi = 3.14159265358979323846;
using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::TextFormat;


/// Finds the source line of a field in a parsed message, for error messages.
class Locator {
 public:
  Locator(const std::string& source, const TextFormat::ParseInfoTree* tree) : source_(source), tree_(tree) {}

  /// "SOURCE:LINE: PATH: " for field `name` of `msg` (index -1 for singular fields), falling
  /// back to the enclosing message's line when the field is absent.
  std::string at(const Message& msg, const TextFormat::ParseInfoTree* tree, const std::string& name,
                 int index, int fallback_line, const std::string& path) const {
    int line = fallback_line;
    const FieldDescriptor* f = msg.GetDescriptor()->FindFieldByName(name);
    if (tree && f) {
      auto loc = tree->GetLocation(f, index);
      if (loc.line >= 0) line = loc.line + 1;
    }
    return source_ + ":" + (line > 0 ? std::to_string(line) : "?") + ": " + path + ": ";
  }
  const TextFormat::ParseInfoTree* root() const { return tree_; }

 private:
  std::string source_;
  const TextFormat::ParseInfoTree* tree_;
};

Vec3 toVec(const pb::Vec3& v) { return {v.x(), v.y(), v.z()}; }

bool finite(double x) { return std::isfinite(x); }

/// Unit vector from a file vector, or an error naming it.
Vec3 unitAxis(const pb::Vec3& v, const std::string& where) {
  const Vec3 a = toVec(v);
  if (!a.allFinite() || a.norm() < 1e-9) throw ModelError(where + "must be a finite non-zero vector");
  return a.normalized();
}

/// Joint frame from its x axis and z reference; they must be orthogonal.
Pose jointFrame(const pb::Vec3& anchor, const pb::Vec3& axis, const pb::Vec3& ref,
                const std::string& where_anchor, const std::string& where_axis, const std::string& where_ref) {
  const Vec3 p = toVec(anchor);
  if (!p.allFinite()) throw ModelError(where_anchor + "must be finite");
  const Vec3 x = unitAxis(axis, where_axis);
  const Vec3 z = unitAxis(ref, where_ref);
  if (std::abs(x.dot(z)) > 1e-6) {
    std::ostringstream os;
    os << where_ref << "must be orthogonal to the axis (cos angle " << x.dot(z) << ")";
    throw ModelError(os.str());
  }
  const Vec3 zo = (z - x * x.dot(z)).normalized();
  Mat3 R;
  R.col(0) = x;
  R.col(1) = zo.cross(x);
  R.col(2) = zo;
  return {p, Quat(R).normalized()};
}

}  // namespace

Vec3 farthestPointInertia(const Shape& s, double m) {
  switch (s.type) {
    case ShapeType::Sphere:
      return Vec3::Constant(m * s.radius * s.radius);
    case ShapeType::Box: {  // a corner: sqrt(h_y² + h_z²) from the x axis
      const Vec3 h = s.half_extents.cwiseProduct(s.half_extents);
      return {m * (h.y() + h.z()), m * (h.x() + h.z()), m * (h.x() + h.y())};
    }
    case ShapeType::Capsule: {  // across the axis: a tip, h + r from the centre; along it: r
      const double t = s.half_length + s.radius;
      return {m * t * t, m * t * t, m * s.radius * s.radius};
    }
  }
  return Vec3::Zero();
}

Vec3 inertiaDiagonal(const Shape& s, double m) {
  switch (s.type) {
    case ShapeType::Sphere: {
      const double i = 0.4 * m * s.radius * s.radius;
      return {i, i, i};
    }
    case ShapeType::Box: {
      const Vec3 h = s.half_extents;
      return {m / 3.0 * (h.y() * h.y() + h.z() * h.z()), m / 3.0 * (h.x() * h.x() + h.z() * h.z()),
              m / 3.0 * (h.x() * h.x() + h.y() * h.y())};
    }
    case ShapeType::Capsule: {
      const double r = s.radius, h = s.half_length;
      const double v_cyl = kPi * r * r * 2.0 * h;
      const double v_sph = 4.0 / 3.0 * kPi * r * r * r;
      const double mc = m * v_cyl / (v_cyl + v_sph);
      const double ms = m - mc;  // both hemispheres
      const double iz = mc * r * r / 2.0 + ms * 0.4 * r * r;
      const double ix = mc * (4.0 * h * h / 12.0 + r * r / 4.0) + ms * (0.4 * r * r + h * h + 0.75 * h * r);
      return {ix, ix, iz};
    }
  }
  return Vec3::Zero();
}

int Joint::equalityRows() const {
  switch (type) {
    case JointType::Spherical2Dof: return 4;
    case JointType::Revolute: return 5;
    case JointType::Fixed: return 6;
  }
  return 0;
}

int Joint::angleCount() const {
  switch (type) {
    case JointType::Spherical2Dof: return 2;
    case JointType::Revolute: return 1;
    case JointType::Fixed: return 0;
  }
  return 0;
}

int HandModel::bodyIndex(const std::string& body_name) const {
  for (size_t i = 0; i < bodies.size(); ++i)
    if (bodies[i].name == body_name) return static_cast<int>(i);
  return -1;
}

int HandModel::equalityRows() const {
  int n = 0;
  for (const Joint& j : joints) n += j.equalityRows();
  return n;
}

std::vector<Pose> HandModel::restPoses(const Pose& X_WM) const {
  std::vector<Pose> out;
  out.reserve(bodies.size());
  for (const Body& b : bodies) out.push_back(X_WM * b.X_MB_rest);
  return out;
}

std::array<double, 2> jointAngles(const Joint& j, const Pose& X_WP, const Pose& X_WC) {
  const Mat3 R = ((X_WP.q * j.X_PJ.q).conjugate() * (X_WC.q * j.X_CJ.q)).toRotationMatrix();
  switch (j.type) {
    case JointType::Spherical2Dof:  // R = Rx(θ1) Ry(θ2)
      return {std::atan2(R(2, 1), R(1, 1)), std::atan2(R(0, 2), R(0, 0))};
    case JointType::Revolute:
      return {std::atan2(R(2, 1), R(1, 1)), 0.0};
    case JointType::Fixed:
      break;
  }
  return {0.0, 0.0};
}

double jointGap(const Joint& j, const Pose& X_WP, const Pose& X_WC) {
  return ((X_WC * j.X_CJ.p) - (X_WP * j.X_PJ.p)).norm();
}

HandModel HandModel::fromText(const std::string& text, const std::string& source) {
  pb::HandModel msg;
  TextFormat::ParseInfoTree tree;
  std::string syntax;
  if (!parseTextProto(text, &msg, &tree, &syntax, "unparsable model")) throw ModelError(source + ":" + syntax);
  const Locator loc(source, &tree);
  const FieldDescriptor* f_bodies = msg.GetDescriptor()->FindFieldByName("bodies");
  const FieldDescriptor* f_joints = msg.GetDescriptor()->FindFieldByName("joints");

  HandModel model;
  model.name = msg.name().empty() ? source : msg.name();
  model.notes = msg.notes();
  if (msg.bodies_size() == 0) throw ModelError(source + ":1: bodies: a model needs at least one body");
  if (msg.bodies_size() > kMaxModelBodies)
    throw ModelError(source + ":1: bodies: " + std::to_string(msg.bodies_size()) + " bodies; a model has at most " +
                     std::to_string(kMaxModelBodies) + " (the poses a hand's samples carry)");
  if (!pb::RotationWeight_IsValid(msg.rotation_weight()))
    throw ModelError(source + ":1: rotation_weight: unknown value " + std::to_string(static_cast<int>(msg.rotation_weight())));

  std::set<std::string> names;
  for (int i = 0; i < msg.bodies_size(); ++i) {
    const pb::Body& pbb = msg.bodies(i);
    const auto* t = tree.GetTreeForNested(f_bodies, i);
    const int line = tree.GetLocation(f_bodies, i).line + 1;
    const std::string path = "bodies[" + std::to_string(i) + "]";
    auto where = [&](const std::string& field) {
      return loc.at(pbb, t, field, -1, line, path + (field.empty() ? "" : "." + field));
    };
    Body b;
    b.name = pbb.name();
    if (b.name.empty()) throw ModelError(where("name") + "every body needs a name");
    if (!names.insert(b.name).second) throw ModelError(where("name") + "duplicate body name '" + b.name + "'");
    switch (pbb.shape_case()) {
      case pb::Body::kCapsule:
        b.shape.type = ShapeType::Capsule;
        b.shape.radius = pbb.capsule().radius();
        b.shape.half_length = pbb.capsule().half_length();
        if (!(b.shape.radius > 0 && finite(b.shape.radius)) || !(b.shape.half_length >= 0 && finite(b.shape.half_length)))
          throw ModelError(where("capsule") + "capsule needs radius > 0 and half_length >= 0 (m)");
        break;
      case pb::Body::kSphere:
        b.shape.type = ShapeType::Sphere;
        b.shape.radius = pbb.sphere().radius();
        if (!(b.shape.radius > 0 && finite(b.shape.radius))) throw ModelError(where("sphere") + "sphere needs radius > 0 (m)");
        break;
      case pb::Body::kBox:
        b.shape.type = ShapeType::Box;
        b.shape.half_extents = toVec(pbb.box().half_extents());
        if (!b.shape.half_extents.allFinite() || !(b.shape.half_extents.minCoeff() > 0))
          throw ModelError(where("box") + "box needs all half_extents > 0 (m)");
        break;
      default:
        throw ModelError(where("") + "body '" + b.name + "' has no shape (capsule, sphere or box)");
    }
    b.mass = pbb.mass();
    if (!(b.mass > 0 && finite(b.mass))) throw ModelError(where("mass") + "mass must be > 0 (kg), got " + shortest(b.mass));
    // Sizes from 1 µm to 100 m and masses from 1 µg to 1000 t keep every derived quantity (inertia,
    // its inverse, Δt² terms) far from overflow and underflow.
    const double size = b.shape.type == ShapeType::Box ? b.shape.half_extents.maxCoeff()
                                                       : b.shape.radius + b.shape.half_length;
    const double small = b.shape.type == ShapeType::Box ? b.shape.half_extents.minCoeff() : b.shape.radius;
    if (!(small >= 1e-6 && size <= 100.0))
      throw ModelError(where(b.shape.type == ShapeType::Box ? "box" : b.shape.type == ShapeType::Sphere ? "sphere" : "capsule") +
                       "shape dimensions must lie in [1e-6, 100] m");
    if (!(b.mass >= 1e-9 && b.mass <= 1e6)) throw ModelError(where("mass") + "mass must lie in [1e-9, 1e6] kg, got " + shortest(b.mass));
    b.inertia = inertiaDiagonal(b.shape, b.mass);
    b.turn_inertia = msg.rotation_weight() == pb::SOLID ? b.inertia : farthestPointInertia(b.shape, b.mass);
    if (!b.inertia.allFinite() || !(b.inertia.minCoeff() > 0.0) || !b.turn_inertia.allFinite() ||
        !(b.turn_inertia.minCoeff() > 0.0))
      throw ModelError(where("mass") + "the inertia derived from shape and mass is not finite and positive");
    b.X_MB_rest.p = toVec(pbb.rest_position());
    if (!b.X_MB_rest.p.allFinite()) throw ModelError(where("rest_position") + "must be finite");
    if (pbb.has_rest_orientation()) {
      const auto& q = pbb.rest_orientation();
      Quat qq(q.w(), q.x(), q.y(), q.z());
      if (!qq.coeffs().allFinite() || std::abs(qq.norm() - 1.0) > 1e-6)
        throw ModelError(where("rest_orientation") + "must be a unit quaternion (w, x, y, z)");
      b.X_MB_rest.q = qq.normalized();
    }
    b.tracker_segment = pbb.tracker_segment();
    model.bodies.push_back(b);
  }

  std::vector<int> parent_of(model.bodies.size(), -1);
  for (int i = 0; i < msg.joints_size(); ++i) {
    const pb::Joint& pj = msg.joints(i);
    const auto* t = tree.GetTreeForNested(f_joints, i);
    const int line = tree.GetLocation(f_joints, i).line + 1;
    const std::string path = "joints[" + std::to_string(i) + "]";
    auto where = [&](const std::string& field) {
      return loc.at(pj, t, field, -1, line, path + (field.empty() ? "" : "." + field));
    };
    Joint j;
    j.name = pj.name().empty() ? path : pj.name();
    switch (pj.type()) {
      case pb::Joint::SPHERICAL_2DOF: j.type = JointType::Spherical2Dof; break;
      case pb::Joint::REVOLUTE: j.type = JointType::Revolute; break;
      case pb::Joint::FIXED: j.type = JointType::Fixed; break;
      default: throw ModelError(where("type") + "joint type must be SPHERICAL_2DOF, REVOLUTE or FIXED");
    }
    j.parent = model.bodyIndex(pj.parent());
    j.child = model.bodyIndex(pj.child());
    if (j.parent < 0) throw ModelError(where("parent") + "unknown body '" + pj.parent() + "'");
    if (j.child < 0) throw ModelError(where("child") + "unknown body '" + pj.child() + "'");
    if (j.parent == j.child) throw ModelError(where("child") + "a joint cannot tie a body to itself");
    if (parent_of[j.child] >= 0) throw ModelError(where("child") + "body '" + pj.child() + "' already has a parent joint (the model must be a tree)");
    // The joints so far form a forest, so walking up from the parent ends; meeting the child
    // means this joint would close a cycle.
    for (int p = j.parent; p >= 0; p = parent_of[static_cast<size_t>(p)])
      if (p == j.child)
        throw ModelError(where("child") + "joint would close a cycle through body '" + pj.child() + "' (the model must be a tree)");
    parent_of[j.child] = j.parent;
    j.X_PJ = jointFrame(pj.anchor_parent(), pj.axis_parent(), pj.reference_parent(), where("anchor_parent"),
                        where("axis_parent"), where("reference_parent"));
    j.X_CJ = jointFrame(pj.anchor_child(), pj.axis_child(), pj.reference_child(), where("anchor_child"),
                        where("axis_child"), where("reference_child"));
    std::array<int, 2> limit_entry{-1, -1};  // index in pj.limits of each angle's limit
    for (int k = 0; k < pj.limits_size(); ++k) {
      const pb::Limit& l = pj.limits(k);
      const std::string wl = loc.at(pj, t, "limits", k, line, path + ".limits[" + std::to_string(k) + "]");
      if (l.angle() < 1 || l.angle() > static_cast<unsigned>(j.angleCount()))
        throw ModelError(wl + "angle must be 1" + std::string(j.angleCount() == 2 ? " or 2" : "") +
                         (j.angleCount() == 0 ? " (a FIXED joint has no angles)" : "") + " for this joint type");
      if (!finite(l.lower()) || !finite(l.upper()) || l.lower() > l.upper() || l.lower() < -kPi || l.upper() > kPi)
        throw ModelError(wl + "need -pi <= lower <= upper <= pi (rad)");
      JointLimit& jl = j.limits[l.angle() - 1];
      if (jl.enabled) throw ModelError(wl + "angle " + std::to_string(l.angle()) + " is limited twice");
      jl = {true, l.lower(), l.upper()};
      limit_entry[l.angle() - 1] = k;
    }
    // The rest pose must satisfy the joint: anchors coincide, locked directions agree, angles
    // within the limits.
    const Pose& X_P = model.bodies[j.parent].X_MB_rest;
    const Pose& X_C = model.bodies[j.child].X_MB_rest;
    const double gap = jointGap(j, X_P, X_C);
    if (gap > 1e-6) {
      std::ostringstream os;
      os << where("anchor_child") << "at rest the anchors are " << gap << " m apart (must coincide)";
      throw ModelError(os.str());
    }
    const Mat3 R = ((X_P.q * j.X_PJ.q).conjugate() * (X_C.q * j.X_CJ.q)).toRotationMatrix();
    const double lock = j.type == JointType::Spherical2Dof ? std::abs(R(0, 1))
                        : j.type == JointType::Revolute    ? std::max(std::abs(R(1, 0)), std::abs(R(2, 0)))
                                                           : (R - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (lock > 1e-6) throw ModelError(where("axis_child") + "at rest the joint frames violate the joint's locked directions");
    const auto angles = jointAngles(j, X_P, X_C);
    for (int a = 0; a < 2; ++a) {
      const JointLimit& jl = j.limits[a];
      if (jl.enabled && (angles[a] < jl.lower - 1e-9 || angles[a] > jl.upper + 1e-9))
        throw ModelError(loc.at(pj, t, "limits", limit_entry[a], line, path + ".limits[" + std::to_string(limit_entry[a]) + "]") +
                         "the rest pose lies outside the limits of angle " + std::to_string(a + 1));
    }
    model.joints.push_back(j);
  }
  // Depth-first postorder of the joint tree (children of a joint are the joints whose parent
  // body is its child body); roots are joints whose parent body has no parent joint.
  model.joint_order.clear();
  std::vector<int> stack;  // (joint, expanded?) encoded as 2 j + expanded
  for (size_t r = model.joints.size(); r-- > 0;)
    if (parent_of[static_cast<size_t>(model.joints[r].parent)] < 0) stack.push_back(2 * static_cast<int>(r));
  while (!stack.empty()) {
    const int top = stack.back();
    stack.pop_back();
    const int j = top / 2;
    if (top % 2) {
      model.joint_order.push_back(j);
      continue;
    }
    stack.push_back(2 * j + 1);
    for (size_t c = model.joints.size(); c-- > 0;)
      if (model.joints[c].parent == model.joints[static_cast<size_t>(j)].child) stack.push_back(2 * static_cast<int>(c));
  }
  return model;
}

}  // namespace godhand
