#include "physics/physics_world.h"

#include <btBulletDynamicsCommon.h>
#include <LinearMath/btConvexHullComputer.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace godhand {
namespace {

btVector3 toBt(const Vec3& v) { return btVector3(v.x(), v.y(), v.z()); }
Vec3 fromBt(const btVector3& v) { return Vec3(v.x(), v.y(), v.z()); }

btTransform toBt(const Pose& X) {
  return btTransform(btQuaternion(X.q.x(), X.q.y(), X.q.z(), X.q.w()), toBt(X.p));
}
Pose fromBt(const btTransform& T) {
  const btQuaternion r = T.getRotation();
  Pose X;
  X.p = fromBt(T.getOrigin());
  X.q = Quat(r.w(), r.x(), r.y(), r.z()).normalized();
  return X;
}

bool finite(const Vec3& v) { return v.allFinite(); }

std::string describe(const SceneObject& o, int index) {
  return "scene object '" + o.id + "' (index " + std::to_string(index) + ")";
}

[[noreturn]] void fail(const SceneObject& o, int index, const std::string& what) {
  throw std::invalid_argument("PhysicsWorld: " + describe(o, index) + ": " + what);
}

std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

/// Volume, centre of mass and unit-density inertia (about the centre of mass) of a closed convex
/// hull given by btConvexHullComputer's faces, by signed tetrahedra from an interior point.
struct HullMassProps {
  double volume = 0.0;
  Vec3 com = Vec3::Zero();
  Mat3 inertia = Mat3::Zero();  ///< unit density, about com, object axes
};

HullMassProps hullMassProps(const btConvexHullComputer& hc, const std::vector<Vec3>& input) {
  HullMassProps out;
  const int nv = hc.vertices.size();
  if (nv < 4 || hc.faces.size() < 4) return out;
  // btConvexHullComputer quantises its output vertices (~1e-5 of the hull size); use the exact
  // input points they come from.
  std::vector<Vec3> exact(static_cast<size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    const int k = i < hc.original_vertex_index.size() ? hc.original_vertex_index[i] : -1;
    exact[static_cast<size_t>(i)] =
        (k >= 0 && k < static_cast<int>(input.size())) ? input[static_cast<size_t>(k)] : fromBt(hc.vertices[i]);
  }
  Vec3 ref = Vec3::Zero();
  for (const Vec3& v : exact) ref += v;
  ref /= nv;
  auto vert = [&](int i) { return Vec3(exact[static_cast<size_t>(i)] - ref); };
  double V = 0.0;
  Vec3 S = Vec3::Zero();
  Mat3 C = Mat3::Zero();  // ∫ x xᵀ dV about ref
  for (int f = 0; f < hc.faces.size(); ++f) {
    const btConvexHullComputer::Edge* e0 = &hc.edges[hc.faces[f]];
    const int v0 = e0->getSourceVertex();
    const Vec3 a = vert(v0);
    const btConvexHullComputer::Edge* e = e0->getNextEdgeOfFace();
    int guard = 0;
    while (e->getTargetVertex() != v0 && guard++ < nv + 2) {
      const Vec3 b = vert(e->getSourceVertex());
      const Vec3 c = vert(e->getTargetVertex());
      const double d = a.dot(b.cross(c));
      const Vec3 s = a + b + c;
      V += d / 6.0;
      S += d / 24.0 * s;
      C += d / 120.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
      e = e->getNextEdgeOfFace();
    }
  }
  if (V < 0.0) {  // face orientation convention: the sign is global, so flip everything
    V = -V;
    S = -S;
    C = -C;
  }
  if (!(V > 0.0)) return out;
  const Vec3 s = S / V;  // com − ref
  const Mat3 Ccom = C - V * s * s.transpose();
  out.volume = V;
  out.com = ref + s;
  out.inertia = Ccom.trace() * Mat3::Identity() - Ccom;
  return out;
}

}  // namespace

void PhysicsParams::validate() const {
  auto bad = [](const char* field, const std::string& why) {
    throw std::invalid_argument(std::string("PhysicsParams.") + field + ": " + why);
  };
  if (!(std::isfinite(fixed_dt) && fixed_dt > 0.0))
    bad("fixed_dt", "must be finite and > 0, got " + fmt(fixed_dt));
  if (max_substeps < 1) bad("max_substeps", "must be >= 1, got " + std::to_string(max_substeps));
  // Clamps may be +inf (disabled) but not NaN, zero or negative.
  if (!(max_force_per_object > 0.0))
    bad("max_force_per_object", "must be > 0 (inf disables), got " + fmt(max_force_per_object));
  if (!(max_speed > 0.0)) bad("max_speed", "must be > 0 (inf disables), got " + fmt(max_speed));
  if (!(max_angular_speed > 0.0))
    bad("max_angular_speed", "must be > 0 (inf disables), got " + fmt(max_angular_speed));
  if (!(linear_damping >= 0.0 && linear_damping <= 1.0))
    bad("linear_damping", "must be in [0, 1], got " + fmt(linear_damping));
  if (!(angular_damping >= 0.0 && angular_damping <= 1.0))
    bad("angular_damping", "must be in [0, 1], got " + fmt(angular_damping));
  if (!(std::isfinite(collision_margin) && collision_margin > 0.0))
    bad("collision_margin", "must be finite and > 0, got " + fmt(collision_margin));
}

struct PhysicsWorld::Impl {
  struct Object {
    bool simulated = false;
    bool dynamic = false;
    Pose X_OC;                  ///< Bullet body frame (com, principal axes) in the object frame
    Pose X_WO_unsimulated;      ///< pose of an object not in the Bullet world
    double radius = 0.0;        ///< bounding radius about the centre of mass (torque bound)
    Vec3 force = Vec3::Zero();  ///< accumulated God-hand wrench for the next step
    Vec3 torque = Vec3::Zero();
    bool has_wrench = false;
    // X_WO as pose() computes it, kept while Bullet cannot have moved the body (static, or asleep
    // through a whole step): a scene of many resting objects does not convert every transform
    // every frame. Invalidated by a step in which the body was awake and by setPose.
    mutable Pose X_WO_cached;
    mutable bool cached = false;
    std::unique_ptr<btTriangleMesh> mesh;
    std::unique_ptr<btCollisionShape> shape;
    std::unique_ptr<btRigidBody> body;
  };

  PhysicsParams params;
  PhysicsCounters counters;
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<btDiscreteDynamicsWorld> world;
  std::vector<Object> objects;
  std::vector<Object*> moving;  ///< the dynamic objects (only they take wrenches and move)

  ~Impl() {
    if (world) {
      for (Object& o : objects)
        if (o.body) world->removeRigidBody(o.body.get());
    }
    world.reset();  // before the bodies, shapes, solver, broadphase, dispatcher it refers to
  }

  Object& at(int i) {
    if (i < 0 || i >= static_cast<int>(objects.size()))
      throw std::out_of_range("PhysicsWorld: object index " + std::to_string(i) + " out of range [0, " +
                              std::to_string(objects.size()) + ")");
    return objects[static_cast<size_t>(i)];
  }

  void build(const SceneObject& so, int index);
  void clampSpeeds(Object& o);
};

void PhysicsWorld::Impl::build(const SceneObject& so, int index) {
  Object& o = objects[static_cast<size_t>(index)];
  if (!isValidPose(so.X_WO, 1e-6)) fail(so, index, "pose X_WO is not finite or its quaternion is not unit");
  if (!(std::isfinite(so.mass) && so.mass >= 0.0))
    fail(so, index, "mass must be finite and >= 0 (0 = static), got " + fmt(so.mass));
  if (!(std::isfinite(so.friction) && so.friction >= 0.0))
    fail(so, index, "friction must be finite and >= 0, got " + fmt(so.friction));
  if (!(std::isfinite(so.restitution) && so.restitution >= 0.0 && so.restitution <= 1.0))
    fail(so, index, "restitution must be in [0, 1], got " + fmt(so.restitution));
  const Pose X_WO{so.X_WO.p, so.X_WO.q.normalized()};
  o.X_WO_unsimulated = X_WO;
  const PhysicsShape& ps = so.physics;
  if (ps.type == PhysicsShapeType::None) return;

  const bool dynamic = so.mass > 0.0;
  const double m = so.mass;
  const double margin_max = params.collision_margin;
  Vec3 inertia = Vec3::Zero();  // principal moments (body frame C)
  switch (ps.type) {
    case PhysicsShapeType::Box: {
      const Vec3& h = ps.half_extents;
      if (!(finite(h) && h.minCoeff() > 0.0))
        fail(so, index, "Box half_extents must be finite and > 0, got (" + fmt(h.x()) + ", " + fmt(h.y()) +
                            ", " + fmt(h.z()) + ")");
      auto shape = std::make_unique<btBoxShape>(toBt(h));
      shape->setMargin(std::min(margin_max, 0.2 * h.minCoeff()));  // keeps the outer size exact
      o.shape = std::move(shape);
      inertia = m / 3.0 * Vec3(h.y() * h.y() + h.z() * h.z(), h.x() * h.x() + h.z() * h.z(),
                               h.x() * h.x() + h.y() * h.y());
      o.radius = h.norm();
      break;
    }
    case PhysicsShapeType::Sphere: {
      const double r = ps.radius;
      if (!(std::isfinite(r) && r > 0.0)) fail(so, index, "Sphere radius must be finite and > 0, got " + fmt(r));
      o.shape = std::make_unique<btSphereShape>(r);
      inertia = Vec3::Constant(0.4 * m * r * r);
      o.radius = r;
      break;
    }
    case PhysicsShapeType::Cylinder: {
      const Vec3& h = ps.half_extents;
      if (!(finite(h) && h.minCoeff() > 0.0))
        fail(so, index, "Cylinder half_extents (r, r, half height) must be finite and > 0");
      if (std::abs(h.x() - h.y()) > 1e-9 * std::max(h.x(), h.y()))
        fail(so, index, "Cylinder half_extents must be (r, r, half height) along local z, got x " + fmt(h.x()) +
                            " != y " + fmt(h.y()));
      const double r = h.x(), hz = h.z();
      auto shape = std::make_unique<btCylinderShapeZ>(toBt(h));
      shape->setMargin(std::min(margin_max, 0.2 * std::min(r, hz)));
      o.shape = std::move(shape);
      const double ixy = m * (3.0 * r * r + 4.0 * hz * hz) / 12.0;
      inertia = Vec3(ixy, ixy, 0.5 * m * r * r);
      o.radius = std::hypot(r, hz);
      break;
    }
    case PhysicsShapeType::ConvexHull: {
      const std::vector<Vec3>& pts = ps.points;
      if (pts.size() < 4)
        fail(so, index, "ConvexHull needs at least 4 points, got " + std::to_string(pts.size()));
      geo::Aabb box;
      for (const Vec3& p : pts) {
        if (!finite(p)) fail(so, index, "ConvexHull has a non-finite point");
        box.grow(p);
      }
      std::vector<double> coords;
      coords.reserve(3 * pts.size());
      for (const Vec3& p : pts) coords.insert(coords.end(), {p.x(), p.y(), p.z()});
      const int count = static_cast<int>(pts.size());
      btConvexHullComputer hull;
      hull.compute(coords.data(), 3 * static_cast<int>(sizeof(double)), count, 0.0, 0.0);
      const HullMassProps mp = hullMassProps(hull, pts);
      const double diag = box.extent().norm();
      if (!(mp.volume > 1e-9 * diag * diag * diag) || !(diag > 0.0))
        fail(so, index, "ConvexHull is degenerate (flat or zero volume: " + fmt(mp.volume) + " m^3)");
      if (dynamic) {
        // Body frame C: centre of mass and principal axes of the uniform-density hull.
        Eigen::SelfAdjointEigenSolver<Mat3> es(mp.inertia);
        Mat3 R = es.eigenvectors();
        if (R.determinant() < 0.0) R.col(2) = -R.col(2);
        o.X_OC = Pose{mp.com, Quat(R).normalized()};
        inertia = (m / mp.volume) * es.eigenvalues().cwiseMax(0.0);
      }
      // Collision shape: the hull shrunk by the margin, so hull + margin is the true hull.
      btConvexHullComputer shrunk;
      const double shrink =
          shrunk.compute(coords.data(), 3 * static_cast<int>(sizeof(double)), count, margin_max, 0.2);
      auto shape = std::make_unique<btConvexHullShape>();
      const Pose X_CO = o.X_OC.inverse();
      double margin = 0.0;
      if (shrink > 0.0 && shrunk.vertices.size() >= 4) {
        margin = shrink;
        for (int i = 0; i < shrunk.vertices.size(); ++i)
          shape->addPoint(toBt(X_CO * fromBt(shrunk.vertices[i])), false);
      } else {  // could not shrink (very thin hull): the exact hull vertices with a zero margin
        for (int i = 0; i < hull.original_vertex_index.size(); ++i)
          shape->addPoint(toBt(X_CO * pts[static_cast<size_t>(hull.original_vertex_index[i])]), false);
      }
      shape->recalcLocalAabb();
      shape->setMargin(margin);
      o.shape = std::move(shape);
      for (const Vec3& p : pts) o.radius = std::max(o.radius, (p - o.X_OC.p).norm());
      break;
    }
    case PhysicsShapeType::TriangleMesh: {
      if (dynamic)
        fail(so, index, "a TriangleMesh physics shape must be static (mass 0), got mass " + fmt(so.mass) +
                            " kg; use a ConvexHull (or primitive) for dynamic objects");
      const geo::TriangleMesh& tm = ps.mesh;
      if (tm.vertices.empty() || tm.triangles.empty())
        fail(so, index, "TriangleMesh is empty (" + std::to_string(tm.vertices.size()) + " vertices, " +
                            std::to_string(tm.triangles.size()) + " triangles)");
      for (const Vec3& v : tm.vertices)
        if (!finite(v)) fail(so, index, "TriangleMesh has a non-finite vertex");
      auto mesh = std::make_unique<btTriangleMesh>(true, false);
      for (const Vec3& v : tm.vertices) mesh->findOrAddVertex(toBt(v), false);
      const int nv = static_cast<int>(tm.vertices.size());
      for (size_t t = 0; t < tm.triangles.size(); ++t) {
        const auto& tri = tm.triangles[t];
        for (int k = 0; k < 3; ++k)
          if (tri[static_cast<size_t>(k)] < 0 || tri[static_cast<size_t>(k)] >= nv)
            fail(so, index, "TriangleMesh triangle " + std::to_string(t) + " has vertex index " +
                                std::to_string(tri[static_cast<size_t>(k)]) + " out of range [0, " +
                                std::to_string(nv) + ")");
        mesh->addTriangleIndices(tri[0], tri[1], tri[2]);
      }
      o.shape = std::make_unique<btBvhTriangleMeshShape>(mesh.get(), true);
      o.mesh = std::move(mesh);
      break;
    }
    case PhysicsShapeType::None:
      break;
  }

  o.simulated = true;
  o.dynamic = dynamic;
  btRigidBody::btRigidBodyConstructionInfo ci(dynamic ? m : 0.0, nullptr, o.shape.get(),
                                              dynamic ? toBt(inertia) : btVector3(0, 0, 0));
  ci.m_startWorldTransform = toBt(X_WO * o.X_OC);
  // Bullet combines a contact's coefficients as the product of the two objects'; store the
  // square roots so that the pair gets the geometric mean sqrt(μ_A μ_B) (μ when both are equal).
  ci.m_friction = std::sqrt(so.friction);
  ci.m_restitution = std::sqrt(so.restitution);
  ci.m_linearDamping = params.linear_damping;
  ci.m_angularDamping = params.angular_damping;
  // Bullet's defaults (0.8 m/s, 1 rad/s) are for metre-sized objects; hand-sized ones sleep
  // only when really at rest. A God-hand force always wakes the object (applyForce).
  ci.m_linearSleepingThreshold = 0.01;
  ci.m_angularSleepingThreshold = 0.05;
  o.body = std::make_unique<btRigidBody>(ci);
  o.body->setUserIndex(index);
  world->addRigidBody(o.body.get());
}

void PhysicsWorld::Impl::clampSpeeds(Object& o) {
  btRigidBody& b = *o.body;
  bool clamped = false;
  const btVector3 v = b.getLinearVelocity();
  const double sv = v.length();
  if (sv > params.max_speed) {
    b.setLinearVelocity(v * (params.max_speed / sv));
    clamped = true;
  }
  const btVector3 w = b.getAngularVelocity();
  const double sw = w.length();
  if (sw > params.max_angular_speed) {
    b.setAngularVelocity(w * (params.max_angular_speed / sw));
    clamped = true;
  }
  if (clamped) ++counters.speeds_clamped;
}

PhysicsWorld::PhysicsWorld(const Scene& scene, PhysicsParams params) : impl_(std::make_unique<Impl>()) {
  params.validate();
  if (!finite(scene.gravity)) throw std::invalid_argument("PhysicsWorld: scene gravity is not finite");
  Impl& s = *impl_;
  s.params = params;
  s.config = std::make_unique<btDefaultCollisionConfiguration>();
  // Several contact points per pair from the first contact on (generic convex-convex and
  // convex-triangle pairs otherwise add one point per step and rock/slide when landing).
  s.config->setConvexConvexMultipointIterations(3, 3);
  s.config->setPlaneConvexMultipointIterations(3, 3);
  s.dispatcher = std::make_unique<btCollisionDispatcher>(s.config.get());
  s.broadphase = std::make_unique<btDbvtBroadphase>();
  s.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  s.world = std::make_unique<btDiscreteDynamicsWorld>(s.dispatcher.get(), s.broadphase.get(), s.solver.get(),
                                                      s.config.get());
  s.world->setGravity(toBt(scene.gravity));
  // Deterministic: fixed solver order, no randomisation (the default mode has none; make it explicit).
  s.world->getSolverInfo().m_solverMode &= ~SOLVER_RANDMIZE_ORDER;
  // Only awake bodies get their broad-phase boxes recomputed each substep (Bullet's default
  // recomputes every object's, static and asleep too: 1,000 static boxes cost ~60 us a frame).
  // Static and sleeping bodies do not move; setPose updates a moved body's box itself.
  s.world->setForceUpdateAllAabbs(false);
  s.objects.resize(scene.objects.size());
  dynamic_.assign(scene.objects.size(), 0);
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    s.build(scene.objects[i], static_cast<int>(i));
    dynamic_[i] = s.objects[i].dynamic ? 1 : 0;
    if (s.objects[i].dynamic) s.moving.push_back(&s.objects[i]);
  }
}

PhysicsWorld::~PhysicsWorld() = default;
PhysicsWorld::PhysicsWorld(PhysicsWorld&&) noexcept = default;
PhysicsWorld& PhysicsWorld::operator=(PhysicsWorld&&) noexcept = default;

const PhysicsParams& PhysicsWorld::params() const { return impl_->params; }
int PhysicsWorld::objectCount() const { return static_cast<int>(impl_->objects.size()); }
void PhysicsWorld::outOfRange(int object) const {
  impl_->at(object);  // throws std::out_of_range naming the index
  throw std::out_of_range("PhysicsWorld: object index " + std::to_string(object));
}
bool PhysicsWorld::isAwake(int object) const {
  const Impl::Object& o = impl_->at(object);
  return o.dynamic && o.body->isActive();
}
int PhysicsWorld::awakeCount() const {
  int n = 0;
  for (const Impl::Object* o : impl_->moving) n += o->body->isActive() ? 1 : 0;
  return n;
}
bool PhysicsWorld::isSimulated(int object) const { return impl_->at(object).simulated; }
const PhysicsCounters& PhysicsWorld::counters() const { return impl_->counters; }

void PhysicsWorld::applyForce(int object, const Vec3& f_W, const Vec3& p_W) {
  Impl::Object& o = impl_->at(object);
  if (!finite(f_W) || !finite(p_W)) {
    ++impl_->counters.forces_rejected;
    return;
  }
  if (!o.dynamic) {
    ++impl_->counters.forces_ignored;
    return;
  }
  const Vec3 com = fromBt(o.body->getCenterOfMassPosition());
  o.force += f_W;
  o.torque += (p_W - com).cross(f_W);
  o.has_wrench = true;
  o.body->activate(true);
  ++impl_->counters.forces_applied;
}

void PhysicsWorld::step(double dt) {
  Impl& s = *impl_;
  if (!(std::isfinite(dt) && dt >= 0.0))
    throw std::invalid_argument("PhysicsWorld::step: dt must be finite and >= 0, got " + fmt(dt));
  auto clearWrenches = [&] {
    for (Impl::Object* d : s.moving) {
      Impl::Object& o = *d;
      o.force.setZero();
      o.torque.setZero();
      o.has_wrench = false;
    }
  };
  if (dt == 0.0) {
    clearWrenches();
    return;
  }
  // n equal substeps of dt/n ≤ fixed_dt (the small tolerance keeps dt = k·fixed_dt at k steps).
  const double ratio = dt / s.params.fixed_dt;
  long long n = static_cast<long long>(std::ceil(ratio - 1e-9 * std::max(1.0, ratio)));
  n = std::max<long long>(n, 1);
  double h = dt / static_cast<double>(n);
  if (n > s.params.max_substeps) {  // a hitch: keep the substep stable, drop the rest of dt
    n = s.params.max_substeps;
    h = s.params.fixed_dt;
    ++s.counters.steps_capped;
  }

  // Clamp each object's wrench once per step.
  const double fmax = s.params.max_force_per_object;
  for (Impl::Object* d : s.moving) {
    Impl::Object& o = *d;
    if (!o.has_wrench) continue;
    bool clamped = false;
    const double fn = o.force.norm();
    if (fn > fmax) {
      const double k = fmax / fn;
      o.force *= k;
      o.torque *= k;
      clamped = true;
    }
    // A couple (forces summing to ~0) escapes the force clamp: bound its torque by what the
    // clamped force could produce at the object's bounding radius.
    const double tmax = fmax * o.radius;
    const double tn = o.torque.norm();
    if (tn > tmax) {
      o.torque *= tmax / tn;
      clamped = true;
    }
    if (clamped) ++s.counters.forces_clamped;
  }

  // Bodies awake before the step (or woken by it, below) may move: their cached poses go.
  for (Impl::Object* o : s.moving)
    if (o->body->isActive()) o->cached = false;
  for (long long i = 0; i < n; ++i) {
    for (Impl::Object* o : s.moving) {
      if (!o->has_wrench) continue;
      o->body->applyCentralForce(toBt(o->force));
      o->body->applyTorque(toBt(o->torque));
    }
    // maxSubSteps = 0: exactly one internal step of h (Bullet clears the forces after it).
    s.world->stepSimulation(h, 0, h);
    // A sleeping body is not integrated and rests below its sleeping thresholds, far under the clamps.
    for (Impl::Object* o : s.moving)
      if (o->body->isActive()) s.clampSpeeds(*o);
  }
  for (Impl::Object* o : s.moving)
    if (o->body->isActive()) o->cached = false;
  clearWrenches();
  ++s.counters.steps;
  s.counters.substeps += static_cast<std::uint64_t>(n);
}

Pose PhysicsWorld::pose(int object) const {
  const Impl::Object& o = impl_->at(object);
  if (!o.simulated) return o.X_WO_unsimulated;
  if (!o.cached) {
    o.X_WO_cached = fromBt(o.body->getWorldTransform()) * o.X_OC.inverse();
    o.cached = true;
  }
  return o.X_WO_cached;
}

Vec3 PhysicsWorld::pointVelocity(int object, const Vec3& p_W) const {
  const Impl::Object& o = impl_->at(object);
  if (!o.dynamic) return Vec3::Zero();
  const btRigidBody& b = *o.body;
  return fromBt(b.getLinearVelocity()) +
         fromBt(b.getAngularVelocity()).cross(p_W - fromBt(b.getCenterOfMassPosition()));
}

Vec3 PhysicsWorld::linearVelocity(int object) const { return pointVelocity(object, pose(object).p); }

Vec3 PhysicsWorld::angularVelocity(int object) const {
  const Impl::Object& o = impl_->at(object);
  if (!o.dynamic) return Vec3::Zero();
  return fromBt(o.body->getAngularVelocity());
}

Vec3 PhysicsWorld::centreOfMass(int object) const {
  const Impl::Object& o = impl_->at(object);
  if (!o.simulated) return o.X_WO_unsimulated.p;
  return fromBt(o.body->getCenterOfMassPosition());
}

void PhysicsWorld::setPose(int object, const Pose& X_WO) {
  Impl& s = *impl_;
  Impl::Object& o = s.at(object);
  if (!isValidPose(X_WO, 1e-6))
    throw std::invalid_argument("PhysicsWorld::setPose: object " + std::to_string(object) +
                                ": pose is not finite or its quaternion is not unit");
  const Pose X{X_WO.p, X_WO.q.normalized()};
  o.X_WO_unsimulated = X;
  o.force.setZero();
  o.torque.setZero();
  o.has_wrench = false;
  o.cached = false;
  if (!o.simulated) return;
  btRigidBody& b = *o.body;
  const btTransform T = toBt(X * o.X_OC);
  b.setWorldTransform(T);
  b.setInterpolationWorldTransform(T);
  b.setLinearVelocity(btVector3(0, 0, 0));
  b.setAngularVelocity(btVector3(0, 0, 0));
  b.setInterpolationLinearVelocity(btVector3(0, 0, 0));
  b.setInterpolationAngularVelocity(btVector3(0, 0, 0));
  b.clearForces();
  s.world->updateSingleAabb(&b);
  // Drop cached contacts (and their warm-start impulses) of the old pose.
  s.world->getBroadphase()->getOverlappingPairCache()->cleanProxyFromPairs(b.getBroadphaseHandle(),
                                                                           s.world->getDispatcher());
  if (o.dynamic) {
    b.activate(true);
  } else {  // a moved static object: wake everything that may have rested on it
    for (Impl::Object* other : s.moving) other->body->activate(true);
  }
}

std::uint64_t PhysicsWorld::stateHash() const {
  std::uint64_t h = 1469598103934665603ULL;
  auto mix = [&](double v) {
    unsigned char bytes[sizeof(double)];
    std::memcpy(bytes, &v, sizeof v);
    for (unsigned char c : bytes) {
      h ^= c;
      h *= 1099511628211ULL;
    }
  };
  auto mixVec = [&](const btVector3& v) {
    mix(v.x());
    mix(v.y());
    mix(v.z());
  };
  for (const Impl::Object& o : impl_->objects) {
    if (!o.simulated) {
      const Pose& X = o.X_WO_unsimulated;
      for (double v : {X.p.x(), X.p.y(), X.p.z(), X.q.w(), X.q.x(), X.q.y(), X.q.z()}) mix(v);
      continue;
    }
    const btTransform& T = o.body->getWorldTransform();
    for (int r = 0; r < 3; ++r) mixVec(T.getBasis()[r]);
    mixVec(T.getOrigin());
    mixVec(o.body->getLinearVelocity());
    mixVec(o.body->getAngularVelocity());
  }
  return h;
}

}  // namespace godhand
