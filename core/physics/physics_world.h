// The physics simulation of the scene objects (paper §6.2: "We use the physics engine Bullet for
// handling our physics objects"), coupled to the God hands through forces (METHOD.md §2 step 6):
// the pipeline calls applyForce() with the reactions −λ_k n_k at the contact points, then step().
//
// Bullet 3 in double precision, btDiscreteDynamicsWorld + btDbvtBroadphase +
// btSequentialImpulseConstraintSolver, deterministic: the same scene and the same sequence of
// calls give bit-identical states (no randomised solver order, fixed substep rule, no motion-state
// interpolation).
//
// Frames: every pose given or returned here is X_WO, the pose of the object frame O of the
// SceneObject (the frame of its meshes and PhysicsShape). Bullet simulates the body in its centre
// of mass / principal axes frame C; for dynamic convex hulls C ≠ O and X_OC is kept per object.
//
// Safety against "launching" (METHOD.md §2 step 6): per step the summed God-hand force on one
// object is clamped to max_force_per_object (its torque scaled by the same factor and then, for
// force couples that sum to ~0, bounded by max_force_per_object × the object's bounding radius),
// and after every substep the linear / angular speed of every dynamic object is clamped to
// max_speed / max_angular_speed.
//
// Not thread-safe; one instance per simulation thread.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "math/pose.h"
#include "scene/scene.h"

namespace godhand {

struct PhysicsParams {
  double fixed_dt = 1.0 / 1000;      ///< s: upper bound of one Bullet substep
  int max_substeps = 20;             ///< per step() call; beyond it simulated time is dropped
  double max_force_per_object = 50;  ///< N: norm clamp of the summed God-hand force per object
  double max_speed = 2.0;            ///< m/s: linear (centre of mass) speed clamp, dynamic objects
  double max_angular_speed = 20.0;   ///< rad/s: angular speed clamp, dynamic objects
  double linear_damping = 0.05;      ///< Bullet damping, [0, 1]
  double angular_damping = 0.05;     ///< Bullet damping, [0, 1]
  /// m: Bullet collision margin of boxes, cylinders and convex hulls, kept inside the true shape
  /// (boxes / cylinders use Bullet's implicit margin, hulls are shrunk by it, so the surface that
  /// collides is the true one with edges rounded by the margin), capped at a fifth of the
  /// smallest half extent / the hull's inner radius. Spheres are exact, triangle meshes use 0.
  double collision_margin = 0.004;
  /// Throws std::invalid_argument naming the offending field.
  void validate() const;
};

struct PhysicsCounters {
  std::uint64_t steps = 0;            ///< step() calls with dt > 0
  std::uint64_t substeps = 0;         ///< Bullet internal steps taken
  std::uint64_t steps_capped = 0;     ///< step() calls that needed > max_substeps (time dropped)
  std::uint64_t forces_applied = 0;   ///< applyForce() calls accepted on dynamic objects
  std::uint64_t forces_rejected = 0;  ///< applyForce() calls with a non-finite force or point
  std::uint64_t forces_ignored = 0;   ///< finite forces on static / unsimulated objects
  std::uint64_t forces_clamped = 0;   ///< (object, step) pairs whose force or torque was clamped
  std::uint64_t speeds_clamped = 0;   ///< (object, substep) pairs whose speed was clamped
};

class PhysicsWorld {
 public:
  /// Builds the Bullet world from the scene (gravity, shapes, masses, friction, restitution,
  /// initial poses). Throws std::invalid_argument on bad params or an unusable object (the message
  /// names the object id and index): non-finite / non-unit pose, negative or non-finite mass,
  /// bad friction / restitution, zero-size or non-finite primitive, degenerate convex hull, empty
  /// or invalid triangle mesh, dynamic TriangleMesh. Objects with PhysicsShapeType::None are not
  /// simulated: their pose stays the scene pose (or the last setPose) and forces are ignored.
  explicit PhysicsWorld(const Scene& scene, PhysicsParams params = {});
  ~PhysicsWorld();
  PhysicsWorld(const PhysicsWorld&) = delete;
  PhysicsWorld& operator=(const PhysicsWorld&) = delete;
  PhysicsWorld(PhysicsWorld&&) noexcept;
  PhysicsWorld& operator=(PhysicsWorld&&) noexcept;

  const PhysicsParams& params() const;
  int objectCount() const;
  /// True for simulated objects with mass > 0. Object indices are positions in Scene::objects;
  /// every accessor throws std::out_of_range for an index outside [0, objectCount()).
  bool isDynamic(int object) const {  // inline: the scene stage asks it per (God object, object)
    if (object < 0 || object >= static_cast<int>(dynamic_.size())) outOfRange(object);
    return dynamic_[static_cast<size_t>(object)] != 0;
  }
  /// True when the object is in the Bullet world (shape type not None).
  bool isSimulated(int object) const;
  /// True for a dynamic object Bullet is simulating now; false for static ones and for dynamic
  /// objects asleep (Bullet deactivates a body that has rested, below 1 cm/s and 0.05 rad/s, for
  /// 2 s; a God-hand force, setPose or a body that hits it wakes it). A sleeping body costs no
  /// integration, no broad-phase update and no pose conversion.
  bool isAwake(int object) const;
  /// The dynamic objects awake now.
  int awakeCount() const;

  /// Accumulates a God-hand force f_W (N, world frame) applied at world point p_W on `object`
  /// for the next step(): net force f_W plus torque (p_W − com_W) × f_W, com_W taken now.
  /// Non-finite input is counted (forces_rejected) and ignored; forces on static / unsimulated
  /// objects are counted (forces_ignored) and ignored. Wakes a sleeping object.
  void applyForce(int object, const Vec3& f_W, const Vec3& p_W);

  /// Advances the simulation by dt (s, finite, ≥ 0; 0 only clears the accumulators): clamps each
  /// object's accumulated God-hand force / torque, steps Bullet n = ceil(dt / fixed_dt) times by
  /// dt / n (if n > max_substeps: max_substeps steps of fixed_dt, the rest of dt is dropped and
  /// steps_capped counted) with the God-hand wrench applied during every substep, clamps speeds
  /// after every substep, and clears the accumulators. Throws std::invalid_argument on bad dt.
  void step(double dt);

  /// X_WO of the object frame.
  Pose pose(int object) const;
  /// Velocity of the object-frame origin (= centre-of-mass velocity when they coincide), m/s.
  Vec3 linearVelocity(int object) const;
  /// rad/s, world frame.
  Vec3 angularVelocity(int object) const;
  /// World velocity of the material point currently at p_W (v_com + ω × (p_W − com_W)).
  Vec3 pointVelocity(int object, const Vec3& p_W) const;
  /// World position of the centre of mass (the object origin for unsimulated objects).
  Vec3 centreOfMass(int object) const;

  /// Teleports the object frame to X_WO (kinematic reset): zero velocity, pending God-hand force
  /// dropped, contact caches of the object cleared, object woken. Throws std::invalid_argument
  /// on a non-finite / non-unit pose.
  void setPose(int object, const Pose& X_WO);

  const PhysicsCounters& counters() const;
  /// FNV-1a hash of the bits of every object's pose and velocities, for determinism tests.
  std::uint64_t stateHash() const;

 private:
  [[noreturn]] void outOfRange(int object) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<unsigned char> dynamic_;  ///< per object: simulated with mass (isDynamic)
};

}  // namespace godhand
