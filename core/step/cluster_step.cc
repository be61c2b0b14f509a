#include "step/cluster_step.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

namespace godhand {

namespace {

// A contact the step can use: its body exists, every number is finite, its normal is roughly unit.
bool validContact(const Contact& c, int num_bodies) {
  const double nn = c.n_W.norm();
  return c.body >= 0 && c.body < num_bodies && c.p_W.allFinite() && c.n_W.allFinite() && std::isfinite(c.distance) &&
         nn > 0.5 && nn < 2.0;
}
using Clock = std::chrono::steady_clock;
double micros(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}
void assembleMasses(QpProblem& qp, const HandModel& model, const std::vector<Pose>& X) {
  for (size_t b = 0; b < model.bodies.size(); ++b) {
    const Body& body = model.bodies[b];
    qp.setRigidMass(static_cast<int>(b), body.mass, X[b].q.toRotationMatrix(), body.turn_inertia);
  }
}
bool finitePositive(double x) { return std::isfinite(x) && x > 0.0; }
void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("step parameters: " + what);
}
}  // namespace

void StepParams::validate() const {
  require(finitePositive(dt) && dt <= 1.0, "dt must be in (0, 1] s, got " + std::to_string(dt));
  require(finitePositive(k_s), "k_s must be finite and > 0 (1/s^2)");
  require(finitePositive(rows.beta) && rows.beta <= 1.0, "rows.beta must be in (0, 1]");
  require(finitePositive(rows.contact_beta) && rows.contact_beta <= 1.0, "rows.contact_beta must be in (0, 1]");
  require(std::isfinite(rows.margin) && rows.margin >= 0.0, "rows.margin must be finite and >= 0 (m)");
  require(std::isfinite(rows.limit_activation) && rows.limit_activation >= 0.0, "rows.limit_activation must be >= 0 (rad)");
  require(exact.max_iterations >= 0, "exact.max_iterations must be >= 0");
  require(std::isfinite(exact.regularization) && exact.regularization >= 0.0 && exact.regularization < 1e-3,
          "exact.regularization must be in [0, 1e-3)");
  require(finitePositive(exact.tolerance) && exact.tolerance < 1e-2, "exact.tolerance must be in (0, 1e-2)");
  require(exact.refinement_steps >= 0 && exact.refinement_steps <= 10, "exact.refinement_steps must be in [0, 10]");
  require(pgs.sweeps >= 1, "pgs.sweeps must be >= 1");
  require(finitePositive(pgs.relaxation) && pgs.relaxation < 2.0, "pgs.relaxation must be in (0, 2)");
  require(projection_iterations >= 0 && projection_iterations <= 100, "projection_iterations must be in [0, 100]");
  require(max_step_translation > 0, "max_step_translation must be > 0 (+inf = no clamp)");
  require(max_step_rotation > 0, "max_step_rotation must be > 0 (+inf = no clamp)");
  require(max_step_rotation_in_contact > 0, "max_step_rotation_in_contact must be > 0 (+inf = no clamp)");
  require(contact_rotation_distance >= 0, "contact_rotation_distance must be >= 0");
  require(finitePositive(projection_tolerance), "projection_tolerance must be > 0");
  require(projection_row_reach >= 1.0, "projection_row_reach must be >= 1 (+inf = every contact)");
  require(finitePositive(target_unit_tolerance) && target_unit_tolerance < 0.5, "target_unit_tolerance must be in (0, 0.5)");
}

ClusterStepper::ClusterStepper(const HandModel& model, StepParams params)
    : model_(model), params_(params), exact_(params.exact), pgs_(params.pgs), projector_(model, params_) {
  exact_.setTree(params_.tree_solver);
  params_.validate();
  params_.rows.dt = params_.dt;
  require(!model.bodies.empty(), "the model has no bodies");
  X_W_ = model.restPoses(Pose{});
  X_prev_ = X_W_;
  last_target_ = X_W_;
  goal_ = X_W_;
  has_last_target_.assign(model.bodies.size(), 0);
  reserve(64);
}

void ClusterStepper::reserve(int contacts) {
  const int n = static_cast<int>(model_.bodies.size());
  const int rows = model_.equalityRows() + 4 * static_cast<int>(model_.joints.size()) + contacts;
  qp_.reset(n);
  qp_.reserveRows(rows);
  sol_.resize(n, rows);
  exact_.reserve(n, rows);
  projector_.reserve(rows);
  pgs_.reserve(n, rows);
  if (contact_row_.size() < static_cast<size_t>(contacts)) {
    contact_row_.resize(static_cast<size_t>(contacts));
    lambda_contacts_.resize(static_cast<size_t>(contacts));
  }
  contact_row_.reserve(static_cast<size_t>(contacts));
  lambda_contacts_.reserve(static_cast<size_t>(contacts));
  warm_prev_.reserve(static_cast<size_t>(rows));
  if (warm_lambda_.size() < static_cast<size_t>(rows)) {
    warm_lambda_.resize(static_cast<size_t>(rows));
    warm_flags_.resize(static_cast<size_t>(rows));
  }
}

void ClusterStepper::reset(const std::vector<Pose>& X_W) {
  if (X_W.size() != model_.bodies.size())
    throw std::invalid_argument("reset: expected " + std::to_string(model_.bodies.size()) + " poses, got " +
                                std::to_string(X_W.size()));
  for (size_t i = 0; i < X_W.size(); ++i)
    if (!isValidPose(X_W[i], 1e-6)) throw std::invalid_argument("reset: pose of body '" + model_.bodies[i].name + "' is not finite or not unit");
  X_W_ = X_W;
  for (auto& X : X_W_) X.q.normalize();
  X_prev_ = X_W_;
  std::fill(has_last_target_.begin(), has_last_target_.end(), 0);
  warm_prev_.clear();
}

const StepReport& ClusterStepper::step(const StepInput& in) {
  const auto t0 = Clock::now();
  report_ = StepReport{};
  ++counters_.steps;
  const int n = static_cast<int>(model_.bodies.size());
  const double dt = params_.dt, dt2 = dt * dt;
  const double k = std::min(params_.k_s, 1.0 / dt2);
  const int nc = std::max(0, in.contacts ? in.num_contacts : 0);
  if (static_cast<size_t>(nc) > contact_row_.capacity()) reserve(nc);

  // Coupling (paper Eq. 2): a bad target is counted and replaced by the body's last valid one.
  qp_.reset(n);
  for (int b = 0; b < n; ++b) {
    const bool driven = in.targets && (!in.has_target || in.has_target[b]);
    if (driven) {
      const Pose& T = in.targets[b];
      if (isValidPose(T, params_.target_unit_tolerance)) {
        last_target_[static_cast<size_t>(b)] = {T.p, T.q.normalized()};
        has_last_target_[static_cast<size_t>(b)] = 1;
      } else {
        ++report_.rejected_targets;
      }
    }
    Vec6& zu = qp_.unconstrained(b);
    if (driven && has_last_target_[static_cast<size_t>(b)])
      zu = k * poseDifference(last_target_[static_cast<size_t>(b)], X_W_[static_cast<size_t>(b)]);
    else
      zu.setZero();
  }
  // Motion clamp: one scale for the whole cluster (keeps joint-consistent goals consistent) so
  // that no body is asked to move more than max_step_translation / max_step_rotation in one
  // step. The contact rows are linear in the motion; their error grows with the square of the
  // rotation, and a target far inside an object would otherwise ask for it every step.
  // (A trust outside (0, 1), NaN included, is none: 1.)
  const double trust = in.rotation_trust > 0.0 && in.rotation_trust < 1.0 ? in.rotation_trust : 1.0;
  if (params_.clamp_contact_bodies_apart) {
    // Bodies near a contact are clamped each on its own (their rows hold them anyway), so that
    // one finger pressing towards a target deep inside an object does not slow the free ones;
    // the free bodies share one scale.
    const double dt2k = dt2;
    near_.assign(static_cast<size_t>(n), 0);
    for (int i = 0; i < nc; ++i) {
      const Contact& c = in.contacts[i];
      if (c.body >= 0 && c.body < n && c.distance < params_.contact_rotation_distance) near_[static_cast<size_t>(c.body)] = 1;
    }
    // Per body: the scale under the limits with the rotation trust, and under the full ones.
    auto limit = [&](int b, double max_rot, double* full) {
      const Vec6& zu = qp_.unconstrained(b);
      const double trans = zu.head<3>().norm() * dt2k, rot = zu.tail<3>().norm() * dt2k;
      double s = 1.0;
      if (trans > params_.max_step_translation) s = std::min(s, params_.max_step_translation / trans);
      *full = s;
      if (rot > max_rot) *full = std::min(*full, max_rot / rot);
      if (rot > trust * max_rot) s = std::min(s, trust * max_rot / rot);
      return s;
    };
    double free_scale = 1.0, free_full = 1.0, full = 1.0;
    for (int b = 0; b < n; ++b)
      if (!near_[static_cast<size_t>(b)]) {
        free_scale = std::min(free_scale, limit(b, params_.max_step_rotation, &full));
        free_full = std::min(free_full, full);
      }
    double smallest = free_scale, smallest_full = free_full;
    for (int b = 0; b < n; ++b) {
      double s = free_scale;
      if (near_[static_cast<size_t>(b)]) {
        s = std::min(s, limit(b, std::min(params_.max_step_rotation, params_.max_step_rotation_in_contact), &full));
        smallest_full = std::min(smallest_full, std::min(free_full, full));
      }
      if (s < 1.0) qp_.unconstrained(b) *= s;
      smallest = std::min(smallest, s);
    }
    report_.asked_motion_scale = smallest_full;
    report_.asked_free_motion_scale = free_full;
    report_.motion_scale = smallest;
    report_.free_motion_scale = free_scale;
  } else {
    double scale = 1.0, full = 1.0;
    const double dt2k = dt2;
    for (int b = 0; b < n; ++b) {
      const Vec6& zu = qp_.unconstrained(b);
      const double trans = zu.head<3>().norm() * dt2k, rot = zu.tail<3>().norm() * dt2k;
      if (trans > params_.max_step_translation) {
        scale = std::min(scale, params_.max_step_translation / trans);
        full = std::min(full, params_.max_step_translation / trans);
      }
      if (rot > params_.max_step_rotation) full = std::min(full, params_.max_step_rotation / rot);
      if (rot > trust * params_.max_step_rotation) scale = std::min(scale, trust * params_.max_step_rotation / rot);
    }
    // Bodies close to a contact: the continuous collision sweeps the motion as a rotation about
    // the body origin, whose points bulge off the straight chord by ≈ θ² r / 8 mid-step; near a
    // surface that reads as a collision (and clips the whole cluster) unless θ stays small.
    if (params_.max_step_rotation_in_contact < params_.max_step_rotation)
      for (int i = 0; i < nc; ++i) {
        const Contact& c = in.contacts[i];
        if (c.body < 0 || c.body >= n || !(c.distance < params_.contact_rotation_distance)) continue;
        const double rot = qp_.unconstrained(c.body).tail<3>().norm() * dt2k;
        if (rot > params_.max_step_rotation_in_contact) full = std::min(full, params_.max_step_rotation_in_contact / rot);
        if (rot > trust * params_.max_step_rotation_in_contact)
          scale = std::min(scale, trust * params_.max_step_rotation_in_contact / rot);
      }
    if (scale < 1.0) {
      for (int b = 0; b < n; ++b) qp_.unconstrained(b) *= scale;
      report_.motion_scale = scale;
      report_.free_motion_scale = scale;
    }
    report_.asked_motion_scale = report_.asked_free_motion_scale = full;
  }
  const auto t1 = Clock::now();

  // Assembly: masses at the current orientations, joint rows, limit rows, contact rows.
  assembleMasses(qp_, model_, X_W_);
  addJointRows(qp_, model_, X_W_.data(), params_.rows);
  report_.equality_rows = qp_.numRows();
  report_.limit_rows = addLimitRows(qp_, model_, X_W_.data(), qp_.unconstrainedData(), params_.rows);
  contact_row_.resize(static_cast<size_t>(nc));
  lambda_contacts_.resize(static_cast<size_t>(nc));
  auto addContacts = [&]() {
    report_.contact_rows = 0;
    report_.rejected_contacts = 0;
    for (int i = 0; i < nc; ++i) {
      contact_row_[static_cast<size_t>(i)] = -1;
      lambda_contacts_[static_cast<size_t>(i)] = 0.0;
      Contact c = in.contacts[i];
      if (!validContact(c, n)) {
        ++report_.rejected_contacts;
        continue;
      }
      c.n_W /= c.n_W.norm();
      contact_row_[static_cast<size_t>(i)] = qp_.numRows();
      addContactRow(qp_, c, X_W_[static_cast<size_t>(c.body)], params_.rows);
      ++report_.contact_rows;
    }
  };
  addContacts();
  qp_.finalize();
  report_.rows = qp_.numRows();
  if (warm_lambda_.size() < static_cast<size_t>(report_.rows)) {  // only when rows exceed all seen
    warm_lambda_.resize(static_cast<size_t>(report_.rows));
    warm_flags_.resize(static_cast<size_t>(report_.rows));
  }
  // Warm start from last step's multipliers, matched by row key.
  for (int r = 0; r < report_.rows; ++r) {
    const std::uint64_t key = qp_.row(r).key;
    double l = 0.0;
    if (key && params_.warm_start) {
      auto it = std::lower_bound(warm_prev_.begin(), warm_prev_.end(), std::make_pair(key, -HUGE_VAL));
      if (it != warm_prev_.end() && it->first == key) l = it->second;
    }
    warm_lambda_[static_cast<size_t>(r)] = l;
    warm_flags_[static_cast<size_t>(r)] = qp_.row(r).type == RowType::Inequality && l > 0.0;
  }
  const auto t2 = Clock::now();

  report_.solve = params_.solver == SolverKind::Exact ? exact_.solve(qp_, sol_, warm_flags_.data())
                                                      : pgs_.solve(qp_, sol_, warm_lambda_.data());
  const auto t3 = Clock::now();
  if (report_.solve.status == SolveStatus::IterationLimit || report_.solve.status == SolveStatus::Stalled) {
    report_.flags |= kFlagSolverInexact;
    ++counters_.inexact_solves;
  }
  // A stalled solve (violated rows that could not enter the passive set) whose rows include joint
  // limits: seen on coarse rods, where the palm's contact rows (A_kk ~ 10-100) meet the fingers'
  // limit rows (A_kk ~ 1e5-1e7); the stalled solution turned the palm by 0.3 rad with the
  // coupling scaled to 1e-3, the sweep refused it round after round and the hand froze. Solved
  // again without the limit rows (cold: the rows are renumbered); the projection then restores
  // any violated limit. Flagged and counted. Done before the rotation caps below too (a stalled
  // solution's rotation is no measure of the motion the caps should scale) and again after their
  // re-solve. (Tried as the cure of a palm frozen across a square bar, whose coupling the caps
  // scaled to 1.5e-4: it was not; the bar needed the patch's line clip in collision_world.cc.)
  auto dropLimitsIfStalled = [&] {
    if (!(report_.solve.status == SolveStatus::Stalled && report_.limit_rows > 0)) return;
    qp_.clearRows();
    addJointRows(qp_, model_, X_W_.data(), params_.rows);
    report_.limit_rows = 0;
    addContacts();
    qp_.finalize();
    report_.rows = qp_.numRows();
    report_.solve = params_.solver == SolverKind::Exact ? exact_.solve(qp_, sol_, nullptr) : pgs_.solve(qp_, sol_, nullptr);
    report_.flags |= kFlagLimitsToProjection;
    ++counters_.limits_to_projection;
    if (report_.solve.status == SolveStatus::IterationLimit || report_.solve.status == SolveStatus::Stalled) {
      report_.flags |= kFlagSolverInexact;
      ++counters_.inexact_solves;
    }
  };
  dropLimitsIfStalled();
  // Rotation caps on the solution (StepInput::rotation_cap): scale every coupling and solve
  // again, warm-started from this solution's active set (and without the limits if that stalls).
  if (in.rotation_cap && report_.solve.status != SolveStatus::NumericalFailure) {
    double scale = 1.0;
    for (int b = 0; b < n; ++b) {
      const double cap = in.rotation_cap[b];
      if (!(cap > 0.0) || !std::isfinite(cap)) continue;
      const double rot = sol_.z[static_cast<size_t>(b)].tail<3>().norm() * dt2;
      if (rot > cap) scale = std::min(scale, cap / rot);
    }
    if (scale < 1.0) {
      for (int b = 0; b < n; ++b) qp_.unconstrained(b) *= scale;
      for (int r = 0; r < report_.rows; ++r)
        warm_flags_[static_cast<size_t>(r)] = qp_.row(r).type == RowType::Inequality && sol_.lambda[static_cast<size_t>(r)] > 0.0;
      report_.solve = params_.solver == SolverKind::Exact ? exact_.solve(qp_, sol_, warm_flags_.data())
                                                          : pgs_.solve(qp_, sol_, warm_lambda_.data());
      report_.motion_scale = std::min(report_.motion_scale, scale * report_.motion_scale);
      report_.free_motion_scale *= scale;
      report_.asked_motion_scale = std::min(report_.asked_motion_scale, scale * report_.asked_motion_scale);
      report_.asked_free_motion_scale *= scale;
      if (report_.solve.status == SolveStatus::IterationLimit || report_.solve.status == SolveStatus::Stalled) {
        report_.flags |= kFlagSolverInexact;
        ++counters_.inexact_solves;
      }
      dropLimitsIfStalled();
    }
  }
  if (report_.rejected_targets) report_.flags |= kFlagRejectedTarget;
  if (report_.rejected_contacts) report_.flags |= kFlagRejectedContact;
  counters_.rejected_targets += static_cast<std::uint64_t>(report_.rejected_targets);
  counters_.rejected_contacts += static_cast<std::uint64_t>(report_.rejected_contacts);

  if (report_.solve.status == SolveStatus::NumericalFailure) {
    report_.flags |= kFlagSolverFailed | kFlagStateKept;
    ++counters_.solver_failures;
    ++counters_.states_kept;
    report_.joint_errors = jointErrors(model_, X_W_.data());
    report_.times = {micros(t0, t1), micros(t1, t2), micros(t2, t3), 0.0, 0.0};
    return report_;
  }

  // Integrate from rest: y = z Δt, X ← X ⊕ y Δt.
  for (int b = 0; b < n; ++b) {
    const size_t i = static_cast<size_t>(b);
    X_prev_[i] = X_W_[i];
    goal_[i] = poseUpdate(X_W_[i], qp_.unconstrained(b), dt2);
    X_W_[i] = poseUpdate(X_W_[i], sol_.z[i], dt2);
  }
  const auto t4 = Clock::now();
  X_integrated_ = X_W_;
  report_.projection_iterations = project(in, true, X_prev_, false);
  // A step whose projection leaves the joints more open than they were is not a hand (the
  // Newton projection can diverge when a body's contacts, e.g. the exits of a body that started
  // inside an object, conflict with its joints; seen live: gaps of 0.3 m). The motion is halved
  // and projected again, kShortenings times; then the previous state is kept (below).
  // The errors before the step are measured only when the projection did not close (rare).
  JointErrors before;
  bool have_before = false;
  auto opened = [&] {
    if (params_.projection_iterations <= 0 || jointsClosed(report_.joint_errors, params_)) return false;
    if (!have_before) {
      before = jointErrors(model_, X_prev_.data());
      have_before = true;
    }
    return std::max(report_.joint_errors.gap, report_.joint_errors.lock) > std::max(before.gap, before.lock);
  };
  report_.shortened = 0;
  for (double scale = 0.5; opened() && report_.shortened < kShortenings; scale *= 0.5) {
    ++report_.shortened;
    for (int b = 0; b < n; ++b) {
      const size_t i = static_cast<size_t>(b);
      X_W_[i] = poseUpdate(X_prev_[i], poseDifference(X_integrated_[i], X_prev_[i]), scale);
    }
    report_.projection_iterations += project(in, false, X_prev_, false);
  }
  if (report_.shortened > 0) ++counters_.shortened_steps;
  const bool still_open = opened();
  const auto t5 = Clock::now();

  bool finite = true;
  for (const Pose& X : X_W_) finite = finite && isValidPose(X, 1e-6);
  if (!finite) {
    X_W_ = X_prev_;
    report_.flags |= kFlagStateKept;
    ++counters_.states_kept;
    report_.joint_errors = jointErrors(model_, X_W_.data());  // project() measured the discarded poses
  }
  if (params_.projection_iterations > 0 && !jointsClosed(report_.joint_errors, params_)) {
    report_.flags |= kFlagProjectionIncomplete;
    if (still_open) {  // shortened kShortenings times and still opening the joints: no motion
      X_W_ = X_prev_;
      report_.flags |= kFlagStateKept;
      ++counters_.states_kept;
      report_.joint_errors = before;
    }
  }
  for (int i = 0; i < nc; ++i) {
    const int r = contact_row_[static_cast<size_t>(i)];
    if (r >= 0) lambda_contacts_[static_cast<size_t>(i)] = sol_.lambda[static_cast<size_t>(r)];
  }
  rememberWarmStart();
  report_.times = {micros(t0, t1), micros(t1, t2), micros(t2, t3), micros(t3, t4), micros(t4, t5)};
  return report_;
}

namespace {
/// True when a row from `first` on (the contact rows) carries force.
bool anyActiveFrom(int first, const QpProblem& qp, const QpSolution& sol) {
  for (int r = first; r < qp.numRows(); ++r)
    if (sol.lambda[static_cast<size_t>(r)] > 0.0) return true;
  return false;
}
constexpr int kGoalIterations = 3;
}  // namespace

void cutMotion(const std::vector<Pose>& X_prev, const std::vector<Pose>& X_new, double toc, std::vector<Pose>* X) {
  if (X != &X_new) *X = X_new;
  if (!(toc < 1.0)) return;
  toc = std::max(0.0, toc);
  for (size_t b = 0; b < X->size(); ++b) (*X)[b] = poseUpdate(X_prev[b], poseDifference((*X)[b], X_prev[b]), toc);
}

void ClusterStepper::interpolate(double toc) {
  if (!(toc < 1.0)) return;
  cutMotion(X_prev_, X_W_, toc, &X_W_);
  report_.joint_errors = jointErrors(model_, X_W_.data());
}

void ClusterStepper::interpolate(const double* toc) {
  for (size_t b = 0; b < X_W_.size(); ++b) {
    if (!(toc[b] < 1.0)) continue;
    X_W_[b] = poseUpdate(X_prev_[b], poseDifference(X_W_[b], X_prev_[b]), std::max(0.0, toc[b]));
  }
  report_.joint_errors = jointErrors(model_, X_W_.data());
}

void ClusterStepper::setMotion(const std::vector<Pose>& X_prev, const std::vector<Pose>& X_new) {
  if (X_prev.size() != model_.bodies.size() || X_new.size() != model_.bodies.size())
    throw std::invalid_argument("setMotion: expected " + std::to_string(model_.bodies.size()) + " poses");
  X_prev_ = X_prev;
  X_W_ = X_new;
  report_.joint_errors = jointErrors(model_, X_W_.data());
  report_.projection_iterations = 0;
}

void ClusterStepper::adoptPoses(const std::vector<Pose>& X_W) {
  if (X_W.size() != model_.bodies.size())
    throw std::invalid_argument("adoptPoses: expected " + std::to_string(model_.bodies.size()) + " poses, got " +
                                std::to_string(X_W.size()));
  X_W_ = X_W;
}

void ClusterStepper::reproject(const Contact* contacts, int num_contacts) {
  X_ref_ = X_W_;
  StepInput in;
  in.contacts = contacts;
  in.num_contacts = num_contacts;
  report_.projection_iterations += project(in, false, X_ref_, true);
}

int ClusterStepper::project(const StepInput& in, bool allow_pull, const std::vector<Pose>& X_ref, bool fresh) {
  JointProjector::Input pin;
  pin.contacts = in.contacts;
  // fresh: every valid contact; else the ones the step made rows of.
  pin.num_contacts = fresh ? std::max(0, in.num_contacts) : static_cast<int>(contact_row_.size());
  pin.use = fresh ? nullptr : contact_row_.data();
  pin.X_ref = X_ref.data();
  // The pull only while no contact of the step carries force.
  const int first_contact = report_.equality_rows + report_.limit_rows;
  if (allow_pull && !anyActiveFrom(first_contact, qp_, sol_)) pin.goal = goal_.data();
  const JointProjector::Result r = projector_.project(X_W_, pin);
  report_.joint_errors = r.joint_errors;
  report_.contact_violation = r.contact_violation;
  return r.iterations;
}

JointProjector::JointProjector(const HandModel& model, const StepParams& params)
    : model_(model), params_(params), exact_(params.exact) {
  exact_.setTree(params_.tree_solver);
  const std::vector<Pose> rest = model.restPoses(Pose{});
  for (const Pose& a : rest)
    for (const Pose& b : rest) model_extent_ = std::max(model_extent_, (a.p - b.p).norm());
  model_extent_ += 0.05;
}

void JointProjector::reserve(int rows) {
  const int n = static_cast<int>(model_.bodies.size());
  proj_.reset(n);
  proj_.reserveRows(rows);
  proj_sol_.resize(n, rows);
  exact_.reserve(n, rows);
  warm_.reserve(static_cast<size_t>(rows));
  frames_.reserve(model_.joints.size());
}

JointProjector::Result JointProjector::project(std::vector<Pose>& X_W_, const Input& in) {
  // Position-level Newton iterations on the same rows: Δt = 1, β = 1. While no contact carries
  // force, z_u = G ⊖ X (towards the goal; at most kGoalIterations), otherwise z_u = 0: the
  // M-smallest displacement that closes the joints, brings violated limits back to their bounds
  // and moves no contact further in than it already is. Stops once joints and limits hold to the
  // tolerance.
  RowParams pp = params_.rows;
  pp.dt = 1.0;
  pp.beta = 1.0;
  pp.contact_beta = 1.0;
  const int n = static_cast<int>(model_.bodies.size());
  const Pose* X_ref = in.X_ref;
  bool pull = in.goal != nullptr;
  auto used = [&](size_t i) { return in.use ? in.use[i] >= 0 : validContact(in.contacts[i], n); };
  const size_t nc = static_cast<size_t>(std::max(0, in.num_contacts));
  Result result;
  double last_violation = 0.0;
  int it = 0;
  for (;; ++it) {
    // The errors of the current poses: the result's figures when the loop ends here.
    // (The joint frames serve the rows below as well, at the same poses.)
    jointFrames(model_, X_W_.data(), &frames_);
    result.joint_errors = jointErrors(model_, frames_.data());
    const JointErrors& e = result.joint_errors;
    // Contacts moved further in than allowed (the rows are linear in the rotation; the rigid
    // motion of the contact point is not): min(d_ref, δ) − d_now.
    double contact_violation = 0.0;
    for (size_t i = 0; i < nc; ++i) {
      if (!used(i)) continue;
      const Contact& c = in.contacts[i];
      const size_t b = static_cast<size_t>(c.body);
      const Vec3 p_now = X_W_[b] * (X_ref[b].inverse() * c.p_W);
      const double d_now = c.distance + c.n_W.normalized().dot(p_now - c.p_W);
      contact_violation = std::max(contact_violation, std::min(c.distance, pp.margin) - d_now);
    }
    result.contact_violation = contact_violation;
    if (it >= params_.projection_iterations ||
        std::max({e.gap, e.lock, e.limit, contact_violation}) <= params_.projection_tolerance)
      break;
    // Joints and limits closed, and a contact point still further in than it was by as much as
    // the last iteration left it: the rows hold such a point where it is (they allow no further
    // approach, they do not pull it back out), so more iterations change nothing (seen: 1.1 µm
    // of a rotation's second-order swing, held through all 8 iterations). Reported as it is.
    if (it > 0 && std::max({e.gap, e.lock, e.limit}) <= params_.projection_tolerance &&
        contact_violation >= last_violation * (1.0 - 1e-3))
      break;
    last_violation = contact_violation;
    proj_.reset(n);
    assembleMasses(proj_, model_, X_W_);
    pull = pull && it < kGoalIterations;
    if (pull)
      for (int b = 0; b < n; ++b)
        proj_.unconstrained(b) = poseDifference(in.goal[static_cast<size_t>(b)], X_W_[static_cast<size_t>(b)]);
    addJointRows(proj_, model_, frames_.data(), pp);
    addLimitRows(proj_, model_, frames_.data(), pull ? proj_.unconstrainedData() : nullptr, pp);
    const int proj_first_contact = proj_.numRows();
    // Without the pull the iteration moves a body by about what the errors ask (a gap, a lock's
    // or a limit's angle over the hand's extent): a contact farther from its margin than
    // projection_row_reach times that cannot become active, and its row (inactive: the same
    // solution) is left out. Iterations after the first close µm errors against the few contacts
    // within µm instead of every contact of the step.
    const double row_reach = pull ? std::numeric_limits<double>::infinity()
        : params_.projection_row_reach * (e.gap + model_extent_ * (e.lock + e.limit) + contact_violation);
    for (size_t i = 0; i < nc; ++i) {
      if (!used(i)) continue;
      const Contact& c = in.contacts[i];
      const size_t b = static_cast<size_t>(c.body);
      const Vec3 n_W = c.n_W.normalized();
      // The contact point moves rigidly with its body (from the pose X_ref it was found at);
      // the scene object does not move here.
      const Vec3 p_now = X_W_[b] * (X_ref[b].inverse() * c.p_W);
      const double d_now = c.distance + n_W.dot(p_now - c.p_W);
      if (d_now - pp.margin > row_reach) continue;
      Vec6 J;
      J << n_W, (p_now - X_W_[b].p).cross(n_W);
      proj_.addRow(RowType::Inequality, c.body, J, -1, Vec6::Zero(), std::min(0.0, pp.margin - d_now), 0);
    }
    proj_.finalize();
    // From the second iteration on the rows are the same ones re-linearised a few µm away:
    // warm-started from the last iteration's active set (where the row layout is the same).
    const bool warm = it > 0 && warm_.size() == static_cast<size_t>(proj_.numRows());
    if (warm)
      for (int r = 0; r < proj_.numRows(); ++r)
        warm_[static_cast<size_t>(r)] = proj_.row(r).type == RowType::Inequality && warm_[static_cast<size_t>(r)];
    const SolveStats s = exact_.solve(proj_, proj_sol_, warm ? warm_.data() : nullptr);
    warm_.resize(static_cast<size_t>(proj_.numRows()));
    for (int r = 0; r < proj_.numRows(); ++r) warm_[static_cast<size_t>(r)] = proj_sol_.lambda[static_cast<size_t>(r)] > 0.0;
    if (s.status == SolveStatus::NumericalFailure) break;  // poses unchanged: errors still current
    if (pull && anyActiveFrom(proj_first_contact, proj_, proj_sol_)) pull = false;
    for (int b = 0; b < n; ++b)
      X_W_[static_cast<size_t>(b)] = poseUpdate(X_W_[static_cast<size_t>(b)], proj_sol_.z[static_cast<size_t>(b)], 1.0);
  }
  result.iterations = it;
  return result;
}

void ClusterStepper::rememberWarmStart() {
  warm_prev_.clear();
  for (int r = 0; r < qp_.numRows(); ++r) {
    const std::uint64_t key = qp_.row(r).key;
    if (key) warm_prev_.emplace_back(key, sol_.lambda[static_cast<size_t>(r)]);
  }
  std::sort(warm_prev_.begin(), warm_prev_.end());
}

}  // namespace godhand
