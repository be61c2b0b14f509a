#include "pipeline/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <cstdio>
#include <cstdlib>

#include "physics/physics_world.h"

namespace godhand {

namespace {
using Clock = std::chrono::steady_clock;
double usSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
}
void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("pipeline parameter: ") + what);
}
bool finiteNonNeg(double x) { return std::isfinite(x) && x >= 0.0; }

// Motion a target asks of a body: |Δp| + |θ| ρ (bounds how far any point of it wants to go).
double askedMotion(const Pose& X, const Pose& target, double rho) {
  const Vec6 d = poseDifference(target, X);
  const double m = d.head<3>().norm() + d.tail<3>().norm() * rho;
  return std::isfinite(m) ? m : 0.0;
}
}  // namespace

void PipelineParams::validate() const {
  step.validate();
  require(contacts.per_pair >= 1 && contacts.per_pair <= 64, "contacts.per_pair must be in [1, 64]");
  require(finiteNonNeg(contacts.spread), "contacts.spread must be >= 0");
  require(finiteNonNeg(contacts.normal_angle), "contacts.normal_angle must be >= 0");
  require(finiteNonNeg(contact_reach), "contact_reach must be >= 0");
  require(std::isfinite(max_reach) && max_reach >= contact_reach, "max_reach must be >= contact_reach");
  require(sweep.stop_distance > 0 && std::isfinite(sweep.stop_distance), "sweep.stop_distance must be > 0");
  require(sweep.stop_distance < step.rows.margin, "sweep.stop_distance must be below the contact margin");
  require(sweep.tolerance > 0 && sweep.tolerance < sweep.stop_distance, "sweep.tolerance must be in (0, stop_distance)");
  require(sweep.max_iterations >= 1, "sweep.max_iterations must be >= 1");
  require(max_force_per_contact > 0 && max_force_per_hand > 0, "force bounds must be > 0");
  require(resolve_iterations >= 0 && resolve_iterations <= 100, "resolve_iterations must be in [0, 100]");
  require(finiteNonNeg(start_clearance), "start_clearance must be >= 0");
}

Pipeline::Pipeline(const Scene& scene, std::vector<const HandModel*> hands, PipelineParams params)
    : Pipeline(scene, std::move(hands), std::move(params), PhysicsParams{}) {}

Pipeline::Pipeline(const Scene& scene, std::vector<const HandModel*> hands, PipelineParams params,
                   const PhysicsParams& physics)
    : scene_(scene), params_(std::move(params)), collision_(scene) {
  params_.validate();
  params_.step.rows.dt = params_.step.dt;
  // Diagnostics on stderr: GODHAND_TRACE=1 per frame and hand, =2 also every clipping sweep.
  if (const char* t = std::getenv("GODHAND_TRACE")) trace_ = std::atoi(t);
  if (params_.simulate) physics_ = std::make_unique<PhysicsWorld>(scene, physics);
  for (const HandModel* m : hands) {
    if (!m) throw std::invalid_argument("pipeline: null hand model");
    Hand h;
    h.model = m;
    h.stepper = std::make_unique<ClusterStepper>(*m, params_.step);
    h.stepper->reserve(static_cast<int>(m->bodies.size()) * params_.contacts.per_pair * 4);
    h.contacts.reserve(m->bodies.size() * static_cast<size_t>(params_.contacts.per_pair) * 4);
    hands_.push_back(std::move(h));
  }
  report_.hands.resize(hands_.size());
}

Pipeline::~Pipeline() = default;

bool Pipeline::start(Hand& hand, const HandInput& in, HandFrameReport& rep) {
  // Start pose: the targets, with undriven or invalid ones taken from the model's rest pose
  // relative to the palm (body 0) target.
  const HandModel& m = *hand.model;
  const size_t n = m.bodies.size();
  if (!isValidPose(in.targets[0])) return false;
  const Pose X_WM = in.targets[0] * m.bodies[0].X_MB_rest.inverse();
  const std::vector<Pose> rest = m.restPoses(X_WM);
  hand.X_start.assign(n, Pose());
  for (size_t b = 0; b < n; ++b) {
    const bool driven = !in.has_target || in.has_target[b];
    hand.X_start[b] = driven && isValidPose(in.targets[b]) ? in.targets[b] : rest[b];
  }
  auto free = [&](const Vec3& lift) {
    for (size_t b = 0; b < n; ++b) {
      Pose X = hand.X_start[b];
      X.p += lift;
      if (collision_.clearance(m.bodies[b].shape, X, params_.start_clearance) < params_.start_clearance) return false;
    }
    return true;
  };
  Vec3 lift = Vec3::Zero();
  if (!free(lift)) {
    bool found = false;
    for (double h = 0.01; h <= 4.0 && !found; h *= 2.0) {
      lift = Vec3(0, 0, h);
      found = free(lift);
    }
    if (!found) return false;  // nowhere free within 4 m above: stay unstarted (reported)
    rep.lifted_start = true;
    ++counters_.lifted_starts;
  }
  for (Pose& X : hand.X_start) X.p += lift;
  hand.stepper->reset(hand.X_start);
  hand.started = true;
  return true;
}

void Pipeline::generateContacts(Hand& hand, const HandInput& in) {
  hand.contacts.clear();
  const HandModel& m = *hand.model;
  const std::vector<Pose>& X = hand.stepper->poses();
  for (size_t b = 0; b < m.bodies.size(); ++b) {
    const Shape& shape = m.bodies[b].shape;
    double reach = params_.contact_reach;
    const bool driven = in.tracked && (!in.has_target || in.has_target[b]);
    if (driven) reach += askedMotion(X[b], in.targets[b], geo::boundingRadius(shape));
    reach = std::min(reach, params_.max_reach);
    collision_.contacts(shape, X[b], static_cast<int>(b), reach, params_.contacts, &hand.contacts);
  }
}

void Pipeline::applyForces(Hand& hand, HandFrameReport& rep) {
  rep.force_N = 0.0;
  if (!physics_) return;
  const ClusterStepper& s = *hand.stepper;
  double total = 0.0;
  for (size_t i = 0; i < hand.contacts.size(); ++i) {
    const Contact& c = hand.contacts[i];
    if (c.object < 0 || !physics_->isDynamic(c.object)) continue;
    const double lambda = s.contactLambda(static_cast<int>(i));
    if (std::isfinite(lambda) && lambda > 0.0) total += std::min(lambda, params_.max_force_per_contact);
  }
  if (total <= 0.0) return;
  const double hand_scale = total > params_.max_force_per_hand ? params_.max_force_per_hand / total : 1.0;
  if (hand_scale < 1.0) ++counters_.forces_clamped;
  for (size_t i = 0; i < hand.contacts.size(); ++i) {
    const Contact& c = hand.contacts[i];
    if (c.object < 0 || !physics_->isDynamic(c.object)) continue;
    double lambda = s.contactLambda(static_cast<int>(i));
    if (!std::isfinite(lambda) || lambda <= 0.0) continue;
    if (lambda > params_.max_force_per_contact) {
      lambda = params_.max_force_per_contact;
      ++counters_.forces_clamped;
    }
    lambda *= hand_scale;
    // The God object is pushed along +n; the reaction on the object is −λ n at the contact.
    physics_->applyForce(c.object, -lambda * c.n_W, c.p_W);
    rep.force_N += lambda;
  }
}

void Pipeline::stepScene() {
  if (!physics_) return;
  physics_->step(params_.step.dt);
  for (int o = 0; o < collision_.objectCount(); ++o)
    if (physics_->isDynamic(o)) collision_.setObjectPose(o, physics_->pose(o));
  // Paper §6.2: objects that Bullet moved into God objects are moved back out, deepest first,
  // iterated to a cap (a push can create a new overlap with another God object).
  const double margin = params_.step.rows.margin;
  for (int it = 0; it < params_.resolve_iterations; ++it) {
    double deepest = 0.0;
    int obj = -1;
    Vec3 n_deep = Vec3::Zero();
    for (const Hand& h : hands_) {
      if (!h.started) continue;
      const std::vector<Pose>& X = h.stepper->poses();
      for (size_t b = 0; b < X.size(); ++b)
        for (int o = 0; o < collision_.objectCount(); ++o) {
          if (!physics_->isDynamic(o)) continue;
          Vec3 n;
          const double d = collision_.signedDistance(o, h.model->bodies[b].shape, X[b], margin, &n);
          if (d < margin && margin - d > deepest) {
            deepest = margin - d;
            obj = o;
            n_deep = n;
          }
        }
    }
    if (obj < 0) break;
    // Only penetrations (d < 0) need resolving; closing into the margin is left to the contacts.
    if (deepest <= margin) break;
    Pose X = collision_.objectPose(obj);
    X.p -= n_deep * deepest;  // n points from the object towards the God object
    physics_->setPose(obj, X);
    collision_.setObjectPose(obj, physics_->pose(obj));
    ++report_.scene_pushouts;
    ++counters_.scene_pushouts;
    if (it + 1 == params_.resolve_iterations) ++counters_.pushout_unresolved;
  }
}

const FrameReport& Pipeline::step(const std::vector<HandInput>& inputs) {
  if (inputs.size() != hands_.size()) throw std::invalid_argument("pipeline: one input per hand expected");
  const Clock::time_point t_frame = Clock::now();
  report_.times = PipelineTimes{};
  report_.contacts = 0;
  report_.scene_pushouts = 0;
  ++counters_.frames;
  for (size_t h = 0; h < hands_.size(); ++h) {
    Hand& hand = hands_[h];
    const HandInput& in = inputs[h];
    HandFrameReport& rep = report_.hands[h];
    rep = HandFrameReport{};
    rep.tracked = in.tracked && in.targets != nullptr;
    if (rep.tracked && !hand.started) start(hand, in, rep);
    rep.started = hand.started;
    if (!rep.tracked || !hand.started) {  // frozen: no step, no contacts, no forces
      hand.contacts.clear();
      rep.joint_errors = hand.started ? hand.stepper->lastReport().joint_errors : JointErrors{};
      continue;
    }
    // contacts
    Clock::time_point t0 = Clock::now();
    generateContacts(hand, in);
    report_.times.contacts_us += usSince(t0);
    // assembly, solve, integrate (+ projection)
    StepInput si;
    si.targets = in.targets;
    si.has_target = in.has_target;
    si.contacts = hand.contacts.data();
    si.num_contacts = static_cast<int>(hand.contacts.size());
    hand.X_old = hand.stepper->poses();
    const std::vector<Pose>& X_old = hand.X_old;
    const StepReport& sr = hand.stepper->step(si);
    if (trace_ >= 1) {
      std::fprintf(stderr, "trace: frame %llu step status %d kkt %.2g proj-it %d gap %.3g rows %d flags %u\n",
                   static_cast<unsigned long long>(counters_.frames + 1), static_cast<int>(sr.solve.status),
                   sr.solve.kkt_residual, sr.projection_iterations, sr.joint_errors.gap, sr.rows, sr.flags);
      for (const Contact& c : hand.contacts)
        std::fprintf(stderr, "   contact body %d d %.3g n (%.3f %.3f %.3f) lambda\n", c.body, c.distance, c.n_W.x(), c.n_W.y(), c.n_W.z());
    }
    report_.times.assembly_us += sr.times.coupling_us + sr.times.assembly_us;
    report_.times.solve_us += sr.times.solve_us;
    report_.times.integrate_us += sr.times.integrate_us + sr.times.project_us;
    rep.contacts = static_cast<int>(hand.contacts.size());
    rep.kkt = sr.solve.kkt_residual;
    rep.status = sr.solve.status;
    rep.flags = sr.flags;
    if (sr.flags & kFlagSolverFailed) ++counters_.solver_failures;
    if (sr.flags & kFlagSolverInexact) ++counters_.inexact_solves;
    report_.contacts += rep.contacts;
    // ccd: TOC_min of this cluster
    t0 = Clock::now();
    const std::vector<Pose>& X_new = hand.stepper->poses();
    double toc = 1.0;
    for (size_t b = 0; b < X_new.size(); ++b) {
      const geo::SweepResult r = collision_.sweep(hand.model->bodies[b].shape, X_old[b], X_new[b], params_.sweep);
      if (r.started_inside) rep.started_inside = true;
      if (trace_ >= 2 && r.toc < 1.0)
        std::fprintf(stderr, "trace: body %zu toc %.3g hit %d inside %d it %d d %.3g move %.3g\n", b, r.toc, r.hit,
                     r.started_inside, r.iterations, r.distance, (X_new[b].p - X_old[b].p).norm());
      toc = std::min(toc, r.toc);
    }
    if (rep.started_inside) ++counters_.started_inside;
    rep.toc = toc;
    report_.times.ccd_us += usSince(t0);
    // merge: clip to TOC_min, forces to the scene
    t0 = Clock::now();
    applyForces(hand, rep);  // λ of this step's contacts, before they are replaced
    if (toc < 1.0) {
      // Algorithm 1: move to TOC_min, update the contacts there, re-close the joints against them.
      hand.stepper->interpolate(toc);
      hand.contacts.clear();
      const std::vector<Pose>& X = hand.stepper->poses();
      for (size_t b = 0; b < X.size(); ++b)
        collision_.contacts(hand.model->bodies[b].shape, X[b], static_cast<int>(b), params_.contact_reach,
                            params_.contacts, &hand.contacts);
      hand.stepper->reproject(hand.contacts.data(), static_cast<int>(hand.contacts.size()));
      ++counters_.clipped_steps;
    }
    rep.joint_errors = hand.stepper->lastReport().joint_errors;
    if (trace_ >= 1)
      std::fprintf(stderr, "trace: frame %llu hand %zu toc %.3g gap %.3g it %d contacts %zu pre-gap %.3g inside %d\n",
                   static_cast<unsigned long long>(counters_.frames), h, toc, rep.joint_errors.gap,
                   hand.stepper->lastReport().projection_iterations, hand.contacts.size(), sr.joint_errors.gap,
                   rep.started_inside);
    report_.times.merge_us += usSince(t0);
  }
  const Clock::time_point t_scene = Clock::now();
  stepScene();
  report_.times.scene_us = usSince(t_scene);
  report_.times.total_us = usSince(t_frame);
  return report_;
}

double Pipeline::penetration(int hand) const {
  const Hand& h = hands_[static_cast<size_t>(hand)];
  if (!h.started) return 0.0;
  double deepest = 0.0;
  const std::vector<Pose>& X = h.stepper->poses();
  for (size_t b = 0; b < X.size(); ++b)
    deepest = std::max(deepest, collision_.penetration(h.model->bodies[b].shape, X[b]));
  return deepest;
}

}  // namespace godhand
