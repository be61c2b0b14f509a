// Constraint rows of one cluster (METHOD.md §2 step 2; paper §4.2–4.3, §5), appended to a
// QpProblem. All rows are acceleration-level, J z (= or ≥) c, in the world frame, with the
// quasi-static assumption (zero velocity at the start of the step, paper §4.2) and drift
// correction: over a step the row's value changes by J z Δt², so a position error e is
// corrected by c = −β e / Δt².
//
// Joints (anchor r = p + R p_BJ, u = r − p, frame axes x, y, z of J attached to each body):
//   point   (3 rows, axis e_a):  e_a·(r_C − r_P) = 0
//           J_C = [e_a ; u_C × e_a],  J_P = [−e_a ; −u_P × e_a]
//   lock    b_P · a_C = 0 (b parent-fixed, a child-fixed unit vectors):
//           J_P = [0 ; b × a],  J_C = [0 ; −(b × a)]
//           Spherical2Dof: b = x_P, a = y_C (twist lock);  Revolute: b ∈ {y_P, z_P}, a = x_C
//   fixed   3 point rows + 3 orientation rows e_a · log(R_WJc R_WJpᵀ) = 0:
//           J_C = [0 ; e_a],  J_P = [0 ; −e_a]
// Limits (angle θ with rate θ̇ = a·(ω_C − ω_P), a = x_P for angle 1, y_C for angle 2):
//   θ − lower ≥ 0:  J_C = [0 ; a], J_P = [0 ; −a];   upper − θ ≥ 0: signs flipped.
//   A limit row is added only when the limit is within `limit_activation` rad now or after the
//   unconstrained motion.
// Contacts (paper Eq. 24, normal n from the scene object towards the God object, point p on
// the God object, signed distance d ≥ 0 when separated):
//   J = [n ; u × n] with u = p − p_body;   c = −(d − δ)/Δt² when d > δ (the gap may close to
//   the margin δ but not cross it), c = β_c (δ − d)/Δt² when d ≤ δ (pushed out gradually).
//   Limits use the same rule with δ = 0. A gap within 1e-12 (m or rad) of its bound is on it
//   (c = 0): that is the round-off of the distance or angle, not a motion to make.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "model/hand_model.h"
#include "solver/qp.h"

namespace godhand {

/// One contact between a God object of the cluster and a scene object (world frame).
struct Contact {
  int body = -1;              ///< God-object index in the cluster
  Vec3 p_W = Vec3::Zero();    ///< contact point on the God object
  Vec3 n_W = Vec3::UnitZ();   ///< unit normal from the scene object towards the God object
  double distance = 0.0;      ///< signed distance along n, m (< 0 = penetrating)
  std::uint64_t key = 0;      ///< persistent identity for warm starts (0 = none)
  int object = -1;            ///< scene object id, for the reaction force
  int triangle = -1;          ///< the object's God-mesh triangle (CollisionWorld), -1 if none
};

struct RowParams {
  double dt = 1e-3;               ///< s
  double beta = 0.5;              ///< drift correction of equality rows
  double contact_beta = 0.5;      ///< push-out rate of contacts / limits already inside the margin
  double margin = 1e-4;           ///< safety margin δ of contacts, m
  double limit_activation = 0.15; ///< rad
};

/// Row keys: the top 4 bits tag the kind so contact keys never collide with joint keys.
enum class RowKind : std::uint64_t { Joint = 1, Limit = 2, Contact = 3 };
inline std::uint64_t rowKey(RowKind kind, std::uint64_t id) {
  return (static_cast<std::uint64_t>(kind) << 60) | (id & ((std::uint64_t{1} << 60) - 1));
}

/// What the joint rows, the limit rows and the joint errors read of one joint at one
/// configuration: its frame axes (columns x, y, z) attached to parent / child, the anchor
/// relative to each body's origin and in the world, and the joint angles (jointAngles).
/// Computed once per configuration where more than one of them is needed (the projection's
/// iterations); the functions taking frames give the same numbers as those taking poses.
struct JointFrame {
  Mat3 R_P, R_C;
  Vec3 u_P, u_C;
  Vec3 r_P, r_C;
  std::array<double, 2> angles{};
};
JointFrame jointFrame(const Joint& joint, const Pose& X_WP, const Pose& X_WC);
/// One frame per joint (model order) into *frames (resized).
void jointFrames(const HandModel& model, const Pose* X_W, std::vector<JointFrame>* frames);

/// Appends the equality rows of every joint. X_W holds one world pose per body.
void addJointRows(QpProblem& qp, const HandModel& model, const Pose* X_W, const RowParams& params);
void addJointRows(QpProblem& qp, const HandModel& model, const JointFrame* frames, const RowParams& params);

/// Appends the limit rows that are active or about to be. z_u (per body) predicts the
/// unconstrained motion; pass nullptr to use the current angles only. Returns rows added.
int addLimitRows(QpProblem& qp, const HandModel& model, const Pose* X_W, const Vec6* z_u, const RowParams& params);
int addLimitRows(QpProblem& qp, const HandModel& model, const JointFrame* frames, const Vec6* z_u, const RowParams& params);

/// Appends one contact row for body `contact.body` at pose X_WB.
void addContactRow(QpProblem& qp, const Contact& contact, const Pose& X_WB, const RowParams& params);

/// Largest joint error of a configuration: max over joints of the anchor gap (m) and of the
/// locked-direction error (rad), and the largest limit violation (rad, ≥ 0).
struct JointErrors {
  double gap = 0.0;
  double lock = 0.0;
  double limit = 0.0;
};
JointErrors jointErrors(const HandModel& model, const Pose* X_W);
JointErrors jointErrors(const HandModel& model, const JointFrame* frames);

}  // namespace godhand
