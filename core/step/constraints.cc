#include "step/constraints.h"

#include <algorithm>
#include <cmath>

namespace godhand {

namespace {
// The frame without the angles (what the joint rows need).
JointFrame geometry(const Joint& j, const Pose& X_WP, const Pose& X_WC) {
  JointFrame g;
  g.R_P = (X_WP.q * j.X_PJ.q).toRotationMatrix();
  g.R_C = (X_WC.q * j.X_CJ.q).toRotationMatrix();
  g.u_P = X_WP.q * j.X_PJ.p;
  g.u_C = X_WC.q * j.X_CJ.p;
  g.r_P = X_WP.p + g.u_P;
  g.r_C = X_WC.p + g.u_C;
  return g;
}
}  // namespace

JointFrame jointFrame(const Joint& j, const Pose& X_WP, const Pose& X_WC) {
  JointFrame g = geometry(j, X_WP, X_WC);
  g.angles = jointAngles(j, X_WP, X_WC);
  return g;
}

void jointFrames(const HandModel& model, const Pose* X_W, std::vector<JointFrame>* frames) {
  frames->resize(model.joints.size());
  for (size_t ji = 0; ji < model.joints.size(); ++ji) {
    const Joint& j = model.joints[ji];
    (*frames)[ji] = jointFrame(j, X_W[j.parent], X_W[j.child]);
  }
}

namespace {

Vec6 block(const Vec3& lin, const Vec3& ang) {
  Vec6 v;
  v << lin, ang;
  return v;
}

/// Gaps within this of their bound (m or rad) are on it: distances and angles are computed with
/// about this much round-off, and dividing noise by Δt² would make the solver chase it.
constexpr double kGapRoundoff = 1e-12;

/// Gap-style right-hand side: full closing allowed while g > margin, gradual push-out inside.
double gapRhs(double g, double margin, double beta, double dt2) {
  if (std::abs(g - margin) < kGapRoundoff) return 0.0;
  return g > margin ? -(g - margin) / dt2 : beta * (margin - g) / dt2;
}


// The rows of joint ji from its frame g (the same numbers whether g was computed here or kept).
template <class FrameOf>
void jointRows(QpProblem& qp, const HandModel& model, FrameOf frameOf, const RowParams& prm) {
  const double k = prm.beta / (prm.dt * prm.dt);
  const Vec3 zero = Vec3::Zero();
  const bool ordered = model.joint_order.size() == model.joints.size();
  for (size_t idx = 0; idx < model.joints.size(); ++idx) {
    const size_t ji = ordered ? static_cast<size_t>(model.joint_order[idx]) : idx;
    const Joint& j = model.joints[ji];
    const auto& g = frameOf(ji, j);
    const std::uint64_t base = static_cast<std::uint64_t>(ji) << 8;
    const Vec3 e = g.r_C - g.r_P;
    for (int a = 0; a < 3; ++a) {
      const Vec3 ea = Vec3::Unit(a);
      qp.addRow(RowType::Equality, j.child, block(ea, g.u_C.cross(ea)), j.parent, block(-ea, -g.u_P.cross(ea)),
                -k * e[a], rowKey(RowKind::Joint, base | static_cast<std::uint64_t>(a)));
    }
    auto lock = [&](const Vec3& b, const Vec3& a, std::uint64_t id) {
      const Vec3 bxa = b.cross(a);
      qp.addRow(RowType::Equality, j.child, block(zero, -bxa), j.parent, block(zero, bxa), -k * b.dot(a),
                rowKey(RowKind::Joint, base | id));
    };
    switch (j.type) {
      case JointType::Spherical2Dof:
        lock(g.R_P.col(0), g.R_C.col(1), 3);
        break;
      case JointType::Revolute:
        lock(g.R_P.col(1), g.R_C.col(0), 3);
        lock(g.R_P.col(2), g.R_C.col(0), 4);
        break;
      case JointType::Fixed: {
        const Vec3 err = logRotation(Quat(g.R_C * g.R_P.transpose()));
        for (int a = 0; a < 3; ++a) {
          const Vec3 ea = Vec3::Unit(a);
          qp.addRow(RowType::Equality, j.child, block(zero, ea), j.parent, block(zero, -ea), -k * err[a],
                    rowKey(RowKind::Joint, base | static_cast<std::uint64_t>(3 + a)));
        }
        break;
      }
    }
  }
}
}  // namespace

void addJointRows(QpProblem& qp, const HandModel& model, const Pose* X_W, const RowParams& prm) {
  jointRows(qp, model, [&](size_t, const Joint& j) { return geometry(j, X_W[j.parent], X_W[j.child]); }, prm);
}

void addJointRows(QpProblem& qp, const HandModel& model, const JointFrame* frames, const RowParams& prm) {
  jointRows(qp, model, [&](size_t ji, const Joint&) -> const JointFrame& { return frames[ji]; }, prm);
}

namespace {
// The limit rows from each limited joint's angles and axes (frameOf: angles, R_P, R_C).
template <class FrameOf>
int limitRows(QpProblem& qp, const HandModel& model, FrameOf frameOf, const Vec6* z_u, const RowParams& prm) {
  const double dt2 = prm.dt * prm.dt;
  const Vec3 zero = Vec3::Zero();
  int added = 0;
  for (size_t ji = 0; ji < model.joints.size(); ++ji) {
    const Joint& j = model.joints[ji];
    if (!j.limits[0].enabled && !j.limits[1].enabled) continue;
    const auto& f = frameOf(ji, j);
    const auto& angles = f.angles;
    const Mat3& R_P = f.R_P;
    const Mat3& R_C = f.R_C;
    for (int a = 0; a < 2; ++a) {
      const JointLimit& lim = j.limits[static_cast<size_t>(a)];
      if (!lim.enabled) continue;
      const Vec3 axis = a == 0 ? Vec3(R_P.col(0)) : Vec3(R_C.col(1));
      double rate = 0.0;  // predicted change of θ over the step from the unconstrained motion
      if (z_u) rate = axis.dot(z_u[j.child].tail<3>() - z_u[j.parent].tail<3>()) * dt2;
      const double theta = angles[static_cast<size_t>(a)];
      const std::uint64_t id = (static_cast<std::uint64_t>(ji) << 8) | static_cast<std::uint64_t>(2 * a);
      const double g_lo = theta - lim.lower, g_hi = lim.upper - theta;
      if (std::min(g_lo, g_lo + rate) < prm.limit_activation) {
        qp.addRow(RowType::Inequality, j.child, block(zero, axis), j.parent, block(zero, -axis),
                  gapRhs(g_lo, 0.0, prm.contact_beta, dt2), rowKey(RowKind::Limit, id));
        ++added;
      }
      if (std::min(g_hi, g_hi - rate) < prm.limit_activation) {
        qp.addRow(RowType::Inequality, j.child, block(zero, -axis), j.parent, block(zero, axis),
                  gapRhs(g_hi, 0.0, prm.contact_beta, dt2), rowKey(RowKind::Limit, id | 1));
        ++added;
      }
    }
  }
  return added;
}
}  // namespace

int addLimitRows(QpProblem& qp, const HandModel& model, const Pose* X_W, const Vec6* z_u, const RowParams& prm) {
  struct Axes {
    std::array<double, 2> angles;
    Mat3 R_P, R_C;
  };
  return limitRows(qp, model, [&](size_t, const Joint& j) {
    const Pose& X_P = X_W[j.parent];
    const Pose& X_C = X_W[j.child];
    Axes f;
    f.angles = jointAngles(j, X_P, X_C);
    f.R_P = (X_P.q * j.X_PJ.q).toRotationMatrix();
    f.R_C = (X_C.q * j.X_CJ.q).toRotationMatrix();
    return f;
  }, z_u, prm);
}

int addLimitRows(QpProblem& qp, const HandModel& model, const JointFrame* frames, const Vec6* z_u, const RowParams& prm) {
  return limitRows(qp, model, [&](size_t ji, const Joint&) -> const JointFrame& { return frames[ji]; }, z_u, prm);
}

void addContactRow(QpProblem& qp, const Contact& c, const Pose& X_WB, const RowParams& prm) {
  const Vec3 u = c.p_W - X_WB.p;
  qp.addRow(RowType::Inequality, c.body, block(c.n_W, u.cross(c.n_W)), -1, Vec6::Zero(),
            gapRhs(c.distance, prm.margin, prm.contact_beta, prm.dt * prm.dt),
            c.key ? rowKey(RowKind::Contact, c.key) : 0);
}

namespace {
template <class FrameOf>
JointErrors errorsOf(const HandModel& model, FrameOf frameOf) {
  JointErrors e;
  for (size_t ji = 0; ji < model.joints.size(); ++ji) {
    const Joint& j = model.joints[ji];
    const auto& g = frameOf(ji, j);
    e.gap = std::max(e.gap, (g.r_C - g.r_P).norm());
    switch (j.type) {
      case JointType::Spherical2Dof:
        e.lock = std::max(e.lock, std::abs(g.R_P.col(0).dot(g.R_C.col(1))));
        break;
      case JointType::Revolute:
        e.lock = std::max({e.lock, std::abs(g.R_P.col(1).dot(g.R_C.col(0))), std::abs(g.R_P.col(2).dot(g.R_C.col(0)))});
        break;
      case JointType::Fixed:
        e.lock = std::max(e.lock, logRotation(Quat(g.R_C * g.R_P.transpose())).norm());
        break;
    }
    const auto& angles = g.angles;
    for (int a = 0; a < 2; ++a) {
      const JointLimit& lim = j.limits[static_cast<size_t>(a)];
      if (!lim.enabled) continue;
      const double th = angles[static_cast<size_t>(a)];
      e.limit = std::max({e.limit, lim.lower - th, th - lim.upper});
    }
  }
  return e;
}
}  // namespace

JointErrors jointErrors(const HandModel& model, const Pose* X_W) {
  return errorsOf(model, [&](size_t, const Joint& j) { return jointFrame(j, X_W[j.parent], X_W[j.child]); });
}

JointErrors jointErrors(const HandModel& model, const JointFrame* frames) {
  return errorsOf(model, [&](size_t ji, const Joint&) -> const JointFrame& { return frames[ji]; });
}

}  // namespace godhand
