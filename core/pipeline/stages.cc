#include "pipeline/stages.h"

#include "pipeline/run_metrics.h"

#include <algorithm>
#include <cstdarg>
#include <chrono>
#include <cmath>
#include <limits>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

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

// One diagnostic line to the params' sink (PipelineParams::trace).
__attribute__((format(printf, 2, 3))) void emit(const PipelineParams& p, const char* fmt, ...) {
  if (!p.trace_sink) return;
  char line[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(line, sizeof line, fmt, args);
  va_end(args);
  p.trace_sink(line);
}

PipelineParams prepared(PipelineParams p) {
  p.validate();
  p.step.rows.dt = p.step.dt;
  return p;
}

/// The same pose, number for number.
bool samePose(const Pose& a, const Pose& b) { return a.p == b.p && a.q.coeffs() == b.q.coeffs(); }

void applySnapshot(CollisionWorld& world, const SceneSnapshot& s) {
  for (const ObjectMotion& o : s.objects)
    if (o.index >= 0 && o.index < world.objectCount() && isValidPose(o.X, 1e-6)) world.setObjectPose(o.index, o.X);
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
  require(sweep.min_stop_distance > 0 && sweep.min_stop_distance <= sweep.stop_distance,
          "sweep.min_stop_distance must be in (0, stop_distance]");
  require(sweep.max_iterations >= 1, "sweep.max_iterations must be >= 1");
  require(max_force_per_contact > 0 && max_force_per_hand > 0, "force bounds must be > 0");
  require(resolve_iterations >= 0 && resolve_iterations <= 100, "resolve_iterations must be in [0, 100]");
  require(finiteNonNeg(start_clearance), "start_clearance must be >= 0");
  require(std::isfinite(max_start_shift) && max_start_shift > 0.0, "max_start_shift must be > 0");
  require(std::isfinite(stuck_rotation) && stuck_rotation >= 0.0, "stuck_rotation must be >= 0 (0 = off)");
  require(max_substeps >= 1 && max_substeps <= 64, "max_substeps must be in [1, 64]");
  require(max_clamped_rounds >= 1 && max_clamped_rounds <= 64, "max_clamped_rounds must be in [1, 64]");
  require(hit_resolves >= 0 && hit_resolves <= 16, "hit_resolves must be in [0, 16]");
  require(reacquire_after >= 0.0, "reacquire_after must be >= 0 (s; +inf = never)");
  require(std::isfinite(start_retry) && start_retry >= 0.0 && start_retry <= 3600.0,
          "start_retry must be in [0, 3600] s");
  require(threads >= 1 && threads <= 64, "threads must be in [1, 64]");
  require(body_threads >= 1 && body_threads <= 64, "body_threads must be in [1, 64]");
}

PhysicsParams physicsParamsFor(double frame_rate, double physics_hz) {
  require(std::isfinite(frame_rate) && frame_rate > 0.0, "frame rate must be > 0");
  require(std::isfinite(physics_hz) && physics_hz >= 10.0 && physics_hz <= 100000.0, "physics rate must be in [10, 100000] Hz");
  PhysicsParams physics;
  physics.fixed_dt = 1.0 / physics_hz;
  physics.max_substeps = std::max(20, static_cast<int>(std::ceil(physics_hz / frame_rate)) + 1);
  return physics;
}

bool receivesForces(const SceneObject& object, const PipelineParams& params) {
  return params.simulate && object.mass > 0.0 && object.physics.type != PhysicsShapeType::None;
}

// ---------------------------------------------------------------------------------------------
// HandSolver

HandSolver::HandSolver(const Scene& scene, const HandModel& model, const PipelineParams& params)
    : model_(model), params_(prepared(params)), collision_(scene), trace_(params_.trace_sink ? params_.trace : 0) {
  stepper_ = std::make_unique<ClusterStepper>(model, params_.step);
  const int body_threads = trace_ > 0 ? 1 : std::min(params_.body_threads, static_cast<int>(model.bodies.size()));
  workers_ = std::make_unique<Workers>(std::max(1, body_threads));
  for (int t = 1; t < workers_->threads(); ++t) slot_worlds_.push_back(std::make_unique<CollisionWorld>(scene));
  body_contacts_.resize(model.bodies.size());
  body_sweeps_.resize(model.bodies.size());
  certified_.assign(model.bodies.size(), 0);
  const int per = static_cast<int>(model.bodies.size()) * params_.contacts.per_pair * 4;
  blocked_.assign(model.bodies.size(), 0);
  rotation_cap_.assign(model.bodies.size(), std::numeric_limits<double>::infinity());
  round_caps_ = rotation_cap_;
  body_toc_.assign(model.bodies.size(), 1.0);
  reclose_toc_.assign(model.bodies.size(), 1.0);
  clear_reach_.assign(model.bodies.size(), -1.0);
  X_clear_.assign(model.bodies.size(), Pose());
  query_start_.resize(model.bodies.size());
  X_query_.assign(model.bodies.size(), Pose());
  persist_.resize(model.bodies.size());
  start_valid_.assign(model.bodies.size(), 0);
  stepper_->reserve(per);
  contacts_.reserve(static_cast<size_t>(per));
  proposal_.loads.reserve(static_cast<size_t>(per));
  proposal_.X_old.reserve(model.bodies.size());
  proposal_.X_new.reserve(model.bodies.size());
}

HandSolver::~HandSolver() = default;

template <class F>
void HandSolver::forEachBody(const F& f, int busy) {
  const int n = static_cast<int>(model_.bodies.size());
  if (slot_worlds_.empty() || busy < kMinParallelBodies) {
    for (int b = 0; b < n; ++b) f(static_cast<size_t>(b), collision_);
    return;
  }
  // Captures two pointers: std::function keeps it without allocating.
  const std::function<void(int, int)> job = [this, &f](int b, int slot) {
    f(static_cast<size_t>(b), slot == 0 ? collision_ : *slot_worlds_[static_cast<size_t>(slot - 1)]);
  };
  if (share_)
    share_->run(share_lane_, share_thread_, n, job);
  else
    workers_->runSlots(n, job);
}

bool HandSolver::useShare(JobShare* share, int lane) {
  if (!share || slot_worlds_.empty() || share->threads() - 1 > static_cast<int>(slot_worlds_.size())) return false;
  share_ = share;
  share_lane_ = lane;
  share_thread_ = 0;
  workers_ = std::make_unique<Workers>(1);  // its own body threads are not needed any more
  return true;
}

void HandSolver::addCosts(std::vector<ObjectCost>* sum) const {
  auto add = [sum](const CollisionWorld& w) {
    for (size_t o = 0; o < sum->size() && o < w.costs().size(); ++o) {
      (*sum)[o].us += w.costs()[o].us;
      (*sum)[o].queries += w.costs()[o].queries;
    }
  };
  add(collision_);
  for (const auto& w : slot_worlds_) add(*w);
}

void HandSolver::setScene(const SceneSnapshot& snapshot) {
  applySnapshot(collision_, snapshot);
  for (auto& w : slot_worlds_) applySnapshot(*w, snapshot);
  scene_frame_ = snapshot.frame;
  scene_step_ = snapshot.step;
  std::fill(start_valid_.begin(), start_valid_.end(), 0);  // the objects may have moved
}

void HandSolver::adopt(const HandResult& result) {
  if (!started_ || !result.started || result.X.size() != model_.bodies.size()) return;
  stepper_->adoptPoses(result.X);
  last_errors_ = result.diag.joint_errors;
}

void HandSolver::resume(const HandResult& result) {
  if (started_ || !result.started || result.X.size() != model_.bodies.size()) return;
  for (const Pose& X : result.X)
    if (!isValidPose(X, 1e-6)) return;
  stepper_->reset(result.X);
  started_ = true;
  last_errors_ = result.diag.joint_errors;
}

bool HandSolver::freeStart(std::vector<Pose>* X, Vec3* shift) const {
  // The hand is moved as one rigid translation: the shorter of two free ones. First out along the
  // exit normal of its deepest overlap, repeatedly (a target a few mm inside a table starts a few
  // mm above it, a target in a cavity starts at the nearest way out), up to kStartPushes times;
  // then straight up, the lowest free height (a hand whose pushes do not settle, or settle farther
  // away than that, e.g. one that wanders around a large object).
  const size_t n = model_.bodies.size();
  const double want = params_.start_clearance;
  *shift = Vec3::Zero();
  // Most-needed push (m, along n_W) of any body, 0 when every body is free.
  auto worst = [&](const Vec3& offset, Vec3* n_W) {
    double need = 0.0;
    for (size_t b = 0; b < n; ++b) {
      Pose Xb = (*X)[b];
      Xb.p += offset;
      for (int o = 0; o < collision_.objectCount(); ++o) {
        Vec3 nb;
        const double d = collision_.signedDistance(o, model_.bodies[b].shape, Xb, want, &nb);
        if (d < want && want - d > need) {
          need = want - d;
          *n_W = nb;
        }
      }
    }
    return need;
  };
  // worst(offset) > 0, stopping at the first body closer than `want` to anything (no depths).
  auto occupied = [&](const Vec3& offset) {
    for (size_t b = 0; b < n; ++b) {
      Pose Xb = (*X)[b];
      Xb.p += offset;
      for (int o = 0; o < collision_.objectCount(); ++o)
        if (collision_.closerThan(o, model_.bodies[b].shape, Xb, want)) return true;
    }
    return false;
  };
  Vec3 offset = Vec3::Zero(), n_W = Vec3::UnitZ();
  bool pushed = false;
  for (int it = 0; it < kStartPushes; ++it) {
    const double need = worst(offset, &n_W);
    if (need <= 0.0) {
      if (it == 0) return true;  // free where it is
      pushed = offset.norm() <= params_.max_start_shift;
      break;
    }
    if (!n_W.allFinite() || n_W.norm() < 0.5) break;
    offset += n_W.normalized() * (need + 0.5 * want);
  }
  // (A search of the shortest free translation along 26 directions was tried: it started the
  // pinch hand on another side of the bunny, where it froze in 146 of 166 windows; not kept.)
  // The lowest free height is then narrowed down between the last occupied and the first free
  // one (to 1 mm): a hand whose targets sit in a large object starts just above it, not up to
  // twice as high (seen: 16 cm above a hand that was free at 9 cm). Heights at or above the
  // pushes' distance are not searched: that one is kept.
  const double limit = pushed ? offset.norm() : params_.max_start_shift;
  double occupied_at = 0.0;  // the highest height found occupied
  for (double h = 0.01; h < 2.0 * limit && occupied_at < limit; h *= 2.0) {
    const double at = std::min(h, limit);
    if (occupied(Vec3(0, 0, at))) {
      occupied_at = at;
      continue;
    }
    double free = at;
    while (free - occupied_at > 1e-3) {
      const double mid = 0.5 * (occupied_at + free);
      (occupied(Vec3(0, 0, mid)) ? occupied_at : free) = mid;
    }
    if (pushed && !(free < limit)) break;
    *shift = Vec3(0, 0, free);
    return true;
  }
  if (!pushed) return false;
  *shift = offset;
  return true;
}

bool HandSolver::start(const HandInput& in) {
  carry_valid_ = false;
  have_last_motion_ = false;
  // Start pose: the targets, with undriven or invalid ones taken from the model's rest pose
  // relative to the palm (body 0) target; where that is occupied, the nearest free translation
  // of it (freeStart), from which the normal steps (with CCD) bring the hand to the surface.
  const size_t n = model_.bodies.size();
  if (!isValidPose(in.targets[0])) return false;
  const Pose X_WM = in.targets[0] * model_.bodies[0].X_MB_rest.inverse();
  const std::vector<Pose> rest = model_.restPoses(X_WM);
  X_start_.assign(n, Pose());
  for (size_t b = 0; b < n; ++b) {
    const bool driven = !in.has_target || in.has_target[b];
    X_start_[b] = driven && isValidPose(in.targets[b]) ? in.targets[b] : rest[b];
  }
  Vec3 shift;
  if (!freeStart(&X_start_, &shift)) return false;  // nowhere free: stay unstarted (reported)
  if (shift.squaredNorm() > 0.0) {
    proposal_.lifted_start = true;
    ++counters_.lifted_starts;
    if (trace_ >= 1)
      emit(params_, "trace: start moved by (%.4f, %.4f, %.4f) m to be free\n", shift.x(), shift.y(), shift.z());
  }
  for (Pose& X : X_start_) X.p += shift;
  stepper_->reset(X_start_);
  // Nothing of a former life (a re-acquisition) carries over: no stuck caps, no blocked bodies,
  // no clearance certificate.
  std::fill(rotation_cap_.begin(), rotation_cap_.end(), std::numeric_limits<double>::infinity());
  std::fill(blocked_.begin(), blocked_.end(), 0);
  std::fill(clear_reach_.begin(), clear_reach_.end(), -1.0);
  rotation_trust_ = 1.0;
  started_ = true;
  last_errors_ = jointErrors(model_, X_start_.data());
  return true;
}

void HandSolver::generateContacts(const HandInput& in) {
  const std::vector<Pose>& X = stepper_->poses();
  int busy = 0;  // bodies that had something within reach at the last query (the rest exit early)
  for (double r : clear_reach_) busy += r > 0.0 ? 0 : 1;
  forEachBody([&](size_t b, CollisionWorld& world) {
    const Shape& shape = model_.bodies[b].shape;
    double reach = params_.contact_reach;
    const bool driven = in.tracked && (!in.has_target || in.has_target[b]);
    if (driven) reach += askedMotion(X[b], in.targets[b], geo::boundingRadius(shape));
    reach = std::min(reach, params_.max_reach);
    // A body that hit within its last kShellSweeps sweeps gets every triangle of its contact
    // shell as a candidate (the face it was about to hit, e.g. the second face of a crease), and
    // so does a box (a palm) always; the others only the closest-point candidates, which is
    // cheaper. (A palm resting on the bunny touches triangles that no part's closest point finds,
    // and its first solve of a round turned into one of them and was solved again in 370 of 386
    // rounds on pinch-bunny, 126 with the shell: 2x the frames a second, see README, fifteenth
    // session.)
    ContactParams cp = params_.contacts;
    if (!shellFor(b)) cp.shell = 0.0;
    std::vector<Contact>& out = body_contacts_[b];
    out.clear();
    const int added = world.contacts(shape, X[b], static_cast<int>(b), reach, cp, &out, &query_start_[b]);
    // A body that hit within its last kShellSweeps sweeps also keeps its last hit's contacts,
    // measured again here (contact persistence): the surface it ran into lies in the direction it
    // is asked to go, often beyond its shell and not the nearest to any of its parts (a palm face
    // over a bulge of the bunny, 0.6 mm off, hit round after round at TOC 0.03: pinch-bunny frame
    // 56), and each round that met it again was solved a second time.
    if (blocked_[b] > 0) {
      const size_t own = out.size();
      for (const Contact& h : persist_[b]) {
        bool dup = false;
        for (size_t i = 0; i < own && !dup; ++i) dup = out[i].key == h.key;
        Contact c;
        if (dup || !world.triangleContact(shape, X[b], h, &c)) continue;
        if (c.distance < reach) out.push_back(c);
      }
    }
    // Nothing within `reach` of the body here: a certificate for the rest of this step.
    clear_reach_[b] = added == 0 ? reach : -1.0;
    X_clear_[b] = X[b];
    X_query_[b] = X[b];
    start_valid_[b] = 1;
  }, busy);
  contacts_.clear();
  for (const std::vector<Contact>& c : body_contacts_) contacts_.insert(contacts_.end(), c.begin(), c.end());
}

bool HandSolver::clearOf(size_t b, const Pose& X_a, const Pose& X_b, double room) const {
  // No triangle within clear_reach_ of the body at X_clear_; every point of it moves at most
  // |Δp| + |θ| ρ from there to X_a and on along the motion to X_b (distance is 1-Lipschitz in
  // the points' displacement), so the motion stays farther than `room` from everything.
  if (!(clear_reach_[b] > 0.0)) return false;
  // (ρ of the shape the God side queries, skin included; a motion that is not finite, e.g. a NaN
  // pose, is never certified: askedMotion reads it as 0.)
  const double rho = collision_.godBoundingRadius(model_.bodies[b].shape);
  if (!isValidPose(X_clear_[b]) || !isValidPose(X_a) || !isValidPose(X_b)) return false;
  const double moved = askedMotion(X_clear_[b], X_a, rho) + askedMotion(X_a, X_b, rho);
  return clear_reach_[b] - moved > room;
}

const CollisionWorld::QueryStart* HandSolver::startAt(size_t b, const Pose& X_from) const {
  if (!start_valid_[b]) return nullptr;
  // Exactly the query's pose (the sweep's own first query would be made at it).
  return samePose(X_query_[b], X_from) ? &query_start_[b] : nullptr;
}

void HandSolver::sweepBodies(const std::vector<Pose>& X_from, const std::vector<Pose>& X_to) {
  int busy = 0;
  for (size_t b = 0; b < model_.bodies.size(); ++b) {
    certified_[b] = clearOf(b, X_from[b], X_to[b], sweepRoom()) ? 1 : 0;
    busy += 1 - certified_[b];
  }
  forEachBody([&](size_t b, CollisionWorld& world) {
    body_sweeps_[b] = certified_[b] ? geo::SweepResult{}
                                    : world.sweep(model_.bodies[b].shape, X_from[b], X_to[b], params_.sweep, nullptr,
                                                  startAt(b, X_from[b]));
  }, busy);
}

double HandSolver::sweepLastMotion(bool* started_inside) {
  const std::vector<Pose>& X0 = stepper_->previousPoses();
  const std::vector<Pose>& X1 = stepper_->poses();
  sweepBodies(X0, X1);
  double toc = 1.0;
  for (size_t b = 0; b < model_.bodies.size(); ++b) {
    const geo::SweepResult& s = body_sweeps_[b];
    countSweep(s);
    if (s.started_inside) *started_inside = true;
    blocked_[b] = s.hit ? kShellSweeps : static_cast<unsigned char>(blocked_[b] > 0 ? blocked_[b] - 1 : 0);
    const bool stuck = params_.stuck_rotation > 0.0 && s.hit && s.toc < 1e-3 && !s.started_inside;
    // Stuck again under a cap: a quarter of it next (a palm resting on a coarse mesh's ridge
    // turns into the face beyond it however small the turn its rows allow, down to the ridge's
    // dihedral angle; rows at the ridge point cannot see that turn).
    const double inf = std::numeric_limits<double>::infinity();
    // (From the cap the round started with: the round's re-solves do not compound it.)
    const double cap0 = round_caps_[b];
    rotation_cap_[b] = !stuck ? inf : cap0 < inf ? std::max(kMinRotationCap, 0.25 * cap0) : params_.stuck_rotation;
    body_toc_[b] = s.toc;
    if ((trace_ >= 2 && (s.toc < 1.0 || collision_.penetration(model_.bodies[b].shape, X1[b]) >
                                               collision_.penetration(model_.bodies[b].shape, X0[b]) + 1e-7)) ||
        trace_ >= 3)
      emit(params_, "trace: body %zu toc %.3g hit %d inside %d it %d d %.3g move %.3g pen0 %.3g pen1 %.3g\n", b, s.toc, s.hit,
                   s.started_inside, s.iterations, s.distance, (X1[b].p - X0[b].p).norm(),
                   collision_.penetration(model_.bodies[b].shape, X0[b]), collision_.penetration(model_.bodies[b].shape, X1[b]));
    toc = std::min(toc, s.toc);
    if (trace_ >= 2 && s.hit && s.toc < 1e-3) {  // a hit at once: its contacts, and where its end pose is inside
      const Vec3 dp = X1[b].p - X0[b].p;
      for (const Contact& c : contacts_)
        if (c.body == static_cast<int>(b))
          emit(params_, "trace:   contact obj %d d %.3g n (%.3f %.3f %.3f) n.dp %.3g\n", c.object, c.distance, c.n_W.x(), c.n_W.y(), c.n_W.z(), c.n_W.dot(dp));
      for (int o = 0; o < collision_.objectCount(); ++o) {
        Vec3 n;
        const double d1 = collision_.signedDistance(o, model_.bodies[b].shape, X1[b], 0.01, &n);
        if (d1 < 0.01) emit(params_, "trace:   end obj %d d %.3g n (%.3f %.3f %.3f) n.dp %.3g dp (%.4f %.4f %.4f) rot %.3g\n", o, d1, n.x(), n.y(), n.z(), n.dot(dp), dp.x(), dp.y(), dp.z(), X1[b].q.angularDistance(X0[b].q));
      }
    }
  }
  return toc;
}

bool HandSolver::addHitContacts() {
  const std::vector<Pose>& X0 = stepper_->previousPoses();
  const std::vector<Pose>& X1 = stepper_->poses();
  const size_t n = model_.bodies.size();
  int busy = 0;
  for (size_t b = 0; b < n; ++b) busy += body_sweeps_[b].hit && !body_sweeps_[b].started_inside ? 1 : 0;
  if (busy == 0) return false;
  hit_contacts_.resize(n);
  forEachBody([&](size_t b, CollisionWorld& world) {
    std::vector<Contact>& out = hit_contacts_[b];
    out.clear();
    const geo::SweepResult& s = body_sweeps_[b];
    if (!s.hit || s.started_inside) return;
    const Pose X_hit = poseUpdate(X0[b], poseDifference(X1[b], X0[b]), std::max(0.0, s.toc));
    world.contacts(model_.bodies[b].shape, X_hit, static_cast<int>(b), params_.contact_reach, params_.contacts, &out, nullptr);
    persist_[b] = out;
    // Each contact point moves rigidly with its body back to the round's start; the distance
    // there along the same (world-fixed) normal.
    const Pose back = X0[b] * X_hit.inverse();
    for (Contact& c : out) {
      const Vec3 p0 = back * c.p_W;
      c.distance += c.n_W.dot(p0 - c.p_W);
      c.p_W = p0;
    }
  }, busy);
  bool added = false;
  for (size_t b = 0; b < n; ++b)
    for (const Contact& h : hit_contacts_[b]) {
      bool found = false;
      for (Contact& c : contacts_) {
        if (c.key != h.key || c.body != h.body || c.object != h.object) continue;
        found = true;
        if (std::abs(c.distance - h.distance) > kHitContactChange || (c.n_W - h.n_W).norm() > kHitNormalChange ||
            (c.p_W - h.p_W).norm() > kHitContactChange) {
          c = h;
          added = true;
        }
        break;
      }
      if (!found) {
        contacts_.push_back(h);
        added = true;
      }
    }
  return added;
}

// Clipping a round's motion. First each body to its own TOC (the bodies whose paths are free take
// their whole motion: one blocked fingertip does not stop the hand), then the joints re-closed
// against the contacts found there. The re-closing moves bodies too, so it is swept as well;
// where it would hit, it is cut at each body's own TOC and re-closed again (kRecloseAttempts);
// then every body goes back to TOC_min instead (Algorithm 1) and the joints are re-closed from
// there, swept once more; where that too would hit, the round leaves the hand at its start.
// Every motion that reaches the result was swept, and every result has closed joints. Returns
// the joint errors of the result.
JointErrors HandSolver::clip(double toc_min) {
  const size_t n = model_.bodies.size();
  // The re-closing motion of body b, X_clip_[b] -> X_b, swept (or certified free) and counted.
  auto sweepRecloseOf = [&](size_t b, const Pose& X_b) {
    const geo::SweepResult s = clearOf(b, X_clip_[b], X_b, sweepRoom())
                                   ? geo::SweepResult{}
                                   : collision_.sweep(model_.bodies[b].shape, X_clip_[b], X_b, params_.sweep, nullptr,
                                                      startAt(b, X_clip_[b]));
    countSweep(s);
    return s;
  };
  // Every body's re-closing motion at once (body_sweeps_), counted in body order.
  auto sweepReclose = [&](const std::vector<Pose>& X) {
    sweepBodies(X_clip_, X);
    for (size_t b = 0; b < n; ++b) countSweep(body_sweeps_[b]);
  };
  auto reclose = [&]() {
    const std::vector<Pose>& X = stepper_->poses();
    int busy = 0;
    for (size_t b = 0; b < n; ++b) {
      certified_[b] = clearOf(b, X_clear_[b], X[b], params_.contact_reach) ? 1 : 0;
      busy += 1 - certified_[b];
    }
    forEachBody([&](size_t b, CollisionWorld& world) {
      std::vector<Contact>& out = body_contacts_[b];
      out.clear();
      // The shell's triangles for boxes and the bodies whose sweep hit, as in generateContacts.
      if (certified_[b]) return;  // nothing within reach there
      ContactParams cp = params_.contacts;
      if (!shellFor(b)) cp.shell = 0.0;
      world.contacts(model_.bodies[b].shape, X[b], static_cast<int>(b), params_.contact_reach, cp, &out, &query_start_[b]);
      X_query_[b] = X[b];
      start_valid_[b] = 1;
    }, busy);
    clip_contacts_.clear();
    for (const std::vector<Contact>& c : body_contacts_) clip_contacts_.insert(clip_contacts_.end(), c.begin(), c.end());
    stepper_->reproject(clip_contacts_.data(), static_cast<int>(clip_contacts_.size()));
  };
  X0_ = stepper_->previousPoses();
  X1_ = stepper_->poses();
  stepper_->interpolate(body_toc_.data());
  // Where the re-closing would hit, its motion is cut at each body's own TOC and the joints are
  // re-closed again from there (a path of swept pieces), a bounded number of times.
  for (int attempt = 0; attempt < kRecloseAttempts; ++attempt) {
    X_clip_ = stepper_->poses();
    reclose();
    bool free = true;
    const std::vector<Pose>& X = stepper_->poses();
    sweepReclose(X);
    for (size_t b = 0; b < n; ++b) {
      const geo::SweepResult& s = body_sweeps_[b];
      reclose_toc_[b] = s.started_inside ? 0.0 : s.toc;
      free = free && !s.hit && !s.started_inside && s.toc >= 1.0;
    }
    free = free && jointsClosed(stepper_->lastReport().joint_errors, params_.step);
    if (free) {
      ++counters_.per_body_clips;
      return stepper_->lastReport().joint_errors;
    }
    if (attempt + 1 < kRecloseAttempts) {
      stepper_->setMotion(X_clip_, X);
      stepper_->interpolate(reclose_toc_.data());
    }
  }
  ++counters_.uniform_clips;
  stepper_->setMotion(X0_, X1_);
  stepper_->interpolate(toc_min);
  X_clip_ = stepper_->poses();
  reclose();
  // Swept as well; where even this re-closing would hit, the round leaves the hand where it
  // started (swept: no motion; closed: a result).
  const std::vector<Pose>& X = stepper_->poses();
  for (size_t b = 0; b <= n; ++b) {
    const geo::SweepResult s = b < n ? sweepRecloseOf(b, X[b]) : geo::SweepResult{};
    if (s.hit || s.started_inside || s.toc < 1.0 || (b == n && !jointsClosed(stepper_->lastReport().joint_errors, params_.step))) {
      ++counters_.held_rounds;
      stepper_->adoptPoses(X0_);
      return jointErrors(model_, X0_.data());
    }
  }
  return stepper_->lastReport().joint_errors;
}

double HandSolver::largestMotion(const std::vector<Pose>& X0, const std::vector<Pose>& X1) const {
  double most = 0.0;
  for (size_t b = 0; b < X0.size(); ++b)
    most = std::max(most, askedMotion(X0[b], X1[b], geo::boundingRadius(model_.bodies[b].shape)));
  return most;
}

double HandSolver::largestGain(const std::vector<Pose>& X0, const std::vector<Pose>& X1, const HandInput& in,
                               const std::vector<double>* toc) const {
  // Per body: |Δp| + bounding radius × angle to its target, before minus after.
  double best = 0.0;
  for (size_t b = 0; b < X0.size(); ++b) {
    if (in.has_target && !in.has_target[b]) continue;
    if (toc && (*toc)[b] < 1.0) continue;
    const Pose& T = in.targets[b];
    if (!isValidPose(T)) continue;
    const Quat q = T.q.normalized();
    const double r = geo::boundingRadius(model_.bodies[b].shape);
    const double g = (T.p - X0[b].p).norm() + r * q.angularDistance(X0[b].q) - (T.p - X1[b].p).norm() - r * q.angularDistance(X1[b].q);
    best = std::max(best, g);
  }
  return best;
}

bool HandSolver::reversedRound(bool* have_last) {
  // The round's motion (round_start_ -> the poses now) as one vector over the bodies: each body's
  // translation, and its rotation times its bounding radius (the motion of its far points).
  const std::vector<Pose>& X = stepper_->poses();
  const size_t n = model_.bodies.size();
  round_motion_.resize(2 * n);
  double along = 0.0, now2 = 0.0, before2 = 0.0;
  for (size_t b = 0; b < n; ++b) {
    const Vec3 dp = X[b].p - round_start_[b].p;
    const Vec3 dth = geo::boundingRadius(model_.bodies[b].shape) * logRotation(X[b].q * round_start_[b].q.inverse());
    if (*have_last) {
      along += dp.dot(last_round_motion_[2 * b]) + dth.dot(last_round_motion_[2 * b + 1]);
      before2 += last_round_motion_[2 * b].squaredNorm() + last_round_motion_[2 * b + 1].squaredNorm();
    }
    now2 += dp.squaredNorm() + dth.squaredNorm();
    round_motion_[2 * b] = dp;
    round_motion_[2 * b + 1] = dth;
  }
  // Turned back by more than 120° against the round before, by more than 0.1 mm: the thresholds
  // of the jitter figure (run_metrics.h), here between rounds.
  const bool reversed = *have_last && now2 > kReversalFloor * kReversalFloor &&
                        along < kReversalCos * std::sqrt(now2 * before2);
  last_round_motion_.swap(round_motion_);
  *have_last = true;
  if (reversed) {
    ++counters_.reversed_rounds;
    rotation_trust_ = std::max(kMinRotationTrust, 0.5 * rotation_trust_);
  } else if (now2 > kReversalFloor * kReversalFloor) {
    rotation_trust_ = std::min(1.0, kRotationTrustGrowth * rotation_trust_);
  } else {
    rotation_trust_ = std::min(1.0, kStillTrustGrowth * rotation_trust_);
  }
  return reversed;
}

const HandProposal& HandSolver::step(const HandInput& in, std::uint64_t frame) {
  HandProposal& p = proposal_;
  StepDiagnostics& d = p.diag;
  p.frame = frame;
  p.scene_frame = scene_frame_;
  p.scene_step = scene_step_;
  p.tracked = in.tracked && in.targets != nullptr;
  p.lifted_start = false;
  p.loads.clear();
  p.diag = StepDiagnostics{};
  p.swept = false;
  ++counters_.steps;
  if (p.tracked && !started_) {
    if (start_wait_ > 0) {
      --start_wait_;
    } else {
      ++counters_.start_searches;
      if (!start(in))
        start_wait_ = std::max(0, static_cast<int>(std::ceil(params_.start_retry / params_.step.dt - 1e-9)) - 1);
    }
  }
  // Re-acquisition after a loss: a new start (kept where the hand was if nowhere is free).
  if (p.tracked && started_ && untracked_steps_ > 0 &&
      static_cast<double>(untracked_steps_) * params_.step.dt >= params_.reacquire_after && start(in)) {
    ++counters_.reacquisitions;
    if (trace_ >= 1) emit(params_, "trace: frame %llu re-acquired after %d untracked steps\n", static_cast<unsigned long long>(frame), untracked_steps_);
  }
  // (Saturating: a lab may run for weeks with one hand away.)
  untracked_steps_ = p.tracked || !started_ ? 0 : std::min(untracked_steps_, kUntrackedCap - 1) + 1;
  p.started = started_;
  p.X_old = stepper_->poses();
  if (!p.tracked || !started_) {  // frozen: no step, no contacts, no forces
    carry_valid_ = false;
    have_last_motion_ = false;
    contacts_.clear();
    p.X_new = p.X_old;
    d.joint_errors = started_ ? last_errors_ : JointErrors{};
    p.swept = true;  // no motion
    return p;
  }
  StepInput si;
  si.targets = in.targets;
  si.has_target = in.has_target;
  bool inside = false;
  double last_free_scale = 1.0, last_least_scale = 1.0, last_toc = 1.0;
  // Rounds of contacts -> Gauss step -> sweep (METHOD.md §2 steps 2-5). A clipped round moves the
  // hand to its TOC (Algorithm 1), re-closes the joints against the contacts found there, and the
  // next round solves the rest of the way towards the same targets from that pose: a body that
  // met a surface slides along it instead of ending the frame, and the bodies whose paths are
  // free go on.
  // reversedRound compares each round with the one before, the last frame's last round included
  // (a body turning back from one frame to the next is the jitter figure's event).
  bool& have_last_motion = have_last_motion_;
  for (;;) {
    round_start_ = stepper_->poses();
    round_caps_ = rotation_cap_;
    si.rotation_trust = rotation_trust_;
    Clock::time_point t0 = Clock::now();
    generateContacts(in);
    d.times.contacts_us += usSince(t0);
    // The Gauss step of this round from round_start_ against contacts_, and its figures (again:
    // the round solved again with its hit's contacts).
    auto solveRound = [&](bool again) -> const StepReport& {
      si.contacts = contacts_.data();
      si.num_contacts = static_cast<int>(contacts_.size());
      si.rotation_cap = nullptr;
      for (double cap : rotation_cap_)
        if (cap < std::numeric_limits<double>::infinity()) si.rotation_cap = rotation_cap_.data();
      const StepReport& sr = stepper_->step(si);
      if (trace_ >= 1)
        emit(params_, "trace: frame %llu round %d%s status %d kkt %.2g proj-it %d gap %.3g rows %d flags %u contacts %zu scale %.3g trust %.3g\n",
                     static_cast<unsigned long long>(frame), d.substeps + (again ? 0 : 1), again ? " re-solved" : "",
                     static_cast<int>(sr.solve.status),
                     sr.solve.kkt_residual, sr.projection_iterations, sr.joint_errors.gap, sr.rows, sr.flags,
                     contacts_.size(), sr.motion_scale, si.rotation_trust);
      d.times.assembly_us += sr.times.coupling_us + sr.times.assembly_us;
      d.times.solve_us += sr.times.solve_us;
      d.times.integrate_us += sr.times.integrate_us + sr.times.project_us;
      d.contacts = std::max(d.contacts, static_cast<int>(contacts_.size()));
      d.kkt = std::max(d.kkt, sr.solve.kkt_residual);
      if (sr.solve.status != SolveStatus::Converged) d.status = sr.solve.status;
      d.flags |= sr.flags;
      d.joint_errors = sr.joint_errors;
      if (sr.flags & kFlagSolverFailed) ++counters_.solver_failures;
      if (sr.flags & kFlagSolverInexact) ++counters_.inexact_solves;
      if (sr.shortened > 0) ++counters_.rounds_shortened;
      if (sr.shortened > 0 && (sr.flags & kFlagStateKept)) ++counters_.rounds_kept;
      // The multipliers of the last solve are the forces of this frame.
      p.loads.clear();
      for (size_t i = 0; i < contacts_.size(); ++i) {
        const Contact& c = contacts_[i];
        const double lambda = stepper_->contactLambda(static_cast<int>(i));
        if (c.object < 0 || !std::isfinite(lambda) || !(lambda > 0.0)) continue;
        p.loads.push_back(ContactLoad{c.body, c.object, c.p_W, c.n_W, lambda});
      }
      return sr;
    };
    const StepReport* srp = &solveRound(false);
    ++d.substeps;
    t0 = Clock::now();
    double toc = sweepLastMotion(&inside);
    d.times.ccd_us += usSince(t0);
    // A hit: the hit bodies' contacts at their TOC poses join the round's (moved back to the
    // round's start with their bodies) and the round is solved again from its start, so that a
    // body that met a face slides along it within this round instead of the hand being clipped,
    // re-closed and solved again from there (Redon et al.: solve, sweep, new contacts, re-solve).
    // At most hit_resolves times, and only while the hit brought a contact the rows lacked;
    // a round still hit is clipped as before.
    // A re-solve that leaves every body where it was (rows linearised at a sharp feature can hold
    // a hand the clip would let slide: a palm on the tip of a spike, whose faces' rows fence it in)
    // is undone where the first motion brought some unhit body kRoundGainProgress closer to its
    // target: that motion is clipped instead.
    bool resolved = false;
    for (int again = 0; toc < 1.0 && !inside && again < params_.hit_resolves; ++again) {
      t0 = Clock::now();
      const bool added = addHitContacts();  // (reads the sweeps and poses; changes only the contacts)
      d.times.contacts_us += usSince(t0);
      if (!added) break;
      if (again == 0) {
        first_.X1 = stepper_->poses();
        first_.report = *srp;
        first_.loads = p.loads;
        first_.sweeps = body_sweeps_;
        first_.body_toc = body_toc_;
        first_.blocked = blocked_;
        first_.caps = rotation_cap_;
        first_.toc = toc;
      }
      stepper_->adoptPoses(round_start_);
      srp = &solveRound(true);
      ++counters_.hit_resolves;
      resolved = true;
      t0 = Clock::now();
      toc = sweepLastMotion(&inside);
      d.times.ccd_us += usSince(t0);
    }
    StepReport sr = *srp;
    // (Held: no body moved more than the frozen figure allows a frame, MetricThresholds.)
    constexpr double kHeld = MetricThresholds::kGodStill / MetricThresholds::kWindow;
    if (resolved && !(toc < 1.0) && !inside && largestMotion(round_start_, stepper_->poses()) < kHeld &&
        largestGain(round_start_, first_.X1, in, &first_.body_toc) >= kRoundGainProgress) {
      ++counters_.resolves_undone;
      stepper_->setMotion(round_start_, first_.X1);
      sr = first_.report;
      p.loads = first_.loads;
      d.joint_errors = sr.joint_errors;
      body_sweeps_ = first_.sweeps;
      body_toc_ = first_.body_toc;
      blocked_ = first_.blocked;
      rotation_cap_ = first_.caps;
      toc = first_.toc;
    }
    // The clamp's scales: the free bodies' shared one, and the least of all (a body near a contact
    // clamped on its own, e.g. a thumb flipping next to a table). The rest of the motion shrinks
    // while either grows from round to round; 5 % is enough to tell growth from a hand whose
    // targets sit deep inside an object (it asks for the same clamped motion every round). A
    // 25 % threshold stopped rounds at 0.777 -> 0.969 with most of the frame's lag left.
    // (Measured under the full rotation limits: a rotation trust growing back is no progress.)
    const double free_scale = sr.free_motion_scale, least_scale = sr.motion_scale;
    const double free_asked = sr.asked_free_motion_scale, least_asked = sr.asked_motion_scale;
    // The first round has no round before it in this frame: it goes on, unless the last frame
    // ended on a clamped round that gained nothing (carry_valid_) and this one neither asks for
    // less than that one nor brings any body kRoundGainProgress closer to its target (a hand
    // held against an object while its targets sit far inside asks the same every frame, and a
    // second round there moves nothing; a hand sliding along a table under the clamp gains
    // millimetres a body while its most-clamped body asks the same).
    const bool first = d.substeps == 1;
    const bool compare_carry = first && carry_valid_;
    if (compare_carry) {
      last_free_scale = carry_free_scale_;
      last_least_scale = carry_least_scale_;
    }
    const bool asks_less = free_asked > kRoundProgress * last_free_scale || least_asked > kRoundProgress * last_least_scale;
    carry_valid_ = false;
    last_free_scale = free_asked;
    last_least_scale = least_asked;
    if (!(toc < 1.0)) {
      // Not clipped. A motion the clamp shortened (StepParams::max_step_*: the rows are linear in
      // the motion) goes on in the next round from here, the rest of the way to the targets, as
      // long as the rest shrinks: up to max_clamped_rounds while no round of this frame was
      // clipped, max_substeps once one was.
      const int rounds = d.clipped ? params_.max_substeps : std::max(params_.max_substeps, params_.max_clamped_rounds);
      reversedRound(&have_last_motion);
      // A later round also goes on when it brought some body closer to its target by more than the
      // lag the plausibility figure counts (MetricThresholds::kLagAbove), whatever the scales: one
      // body held at a joint limit (or by a palm held on a table) asks the same turn every round
      // and pins the free bodies' shared scale while the others still close centimetres (seen:
      // confidence2's left hand flipping 1-1.7 rad beside a table, a fingertip asking 1.67 rad
      // round after round, the frame ended after its second round with the thumb 48 mm from its
      // twin; 0.5 mm instead of 5 mm there cost pinch-bunny's p99 2.2 -> 4.6 ms).
      const double gain = compare_carry || !first ? largestGain(round_start_, stepper_->poses(), in, nullptr) : 0.0;
      if (trace_ >= 2 && (compare_carry || !first)) emit(params_, "trace: round gained %.4g m, asks less %d\n", gain, asks_less);
      const bool progressing = (first && !compare_carry) || asks_less ||
                               (compare_carry && gain > kRoundGainProgress) || (!first && gain > MetricThresholds::kLagAbove);
      const bool clamped = std::min(free_scale, least_scale) < 1.0;
      if (clamped && progressing && d.substeps < rounds) continue;
      if (clamped && !progressing) {
        carry_valid_ = true;
        carry_free_scale_ = free_asked;
        carry_least_scale_ = least_asked;
      }
      break;
    }
    // Two rounds in a row clipped at once: the contacts found at the first did not open a way.
    const bool stuck_round = toc < 1e-3 && last_toc < 1e-3;
    last_toc = toc;
    d.clipped = true;
    d.toc = std::min(d.toc, toc);
    t0 = Clock::now();
    d.joint_errors = clip(toc);
    d.times.integrate_us += usSince(t0);
    reversedRound(&have_last_motion);
    if (d.substeps >= params_.max_substeps || stuck_round) break;
  }
  d.started_inside = inside;
  last_errors_ = d.joint_errors;
  p.X_new = stepper_->poses();
  p.swept = true;
  return p;
}

// ---------------------------------------------------------------------------------------------
// Resolver

Resolver::Resolver(const Scene& scene, std::vector<const HandModel*> hands, const PipelineParams& params)
    : params_(prepared(params)), collision_(scene), trace_(params_.trace_sink ? params_.trace : 0) {
  dynamic_.resize(scene.objects.size());
  for (size_t o = 0; o < scene.objects.size(); ++o) dynamic_[o] = receivesForces(scene.objects[o], params_);
  for (const HandModel* m : hands) {
    if (!m) throw std::invalid_argument("resolver: null hand model");
    Hand h;
    h.model = m;
    h.projector = std::make_unique<JointProjector>(*m, params_.step);
    h.projector->reserve(m->equalityRows() + 4 * static_cast<int>(m->joints.size()) +
                         static_cast<int>(m->bodies.size()) * params_.contacts.per_pair * 4);
    h.contacts.reserve(m->bodies.size() * static_cast<size_t>(params_.contacts.per_pair) * 4);
    h.result.X = m->restPoses(Pose{});
    hands_.push_back(std::move(h));
  }
}

Resolver::~Resolver() = default;

void Resolver::setScene(const SceneSnapshot& snapshot) {
  applySnapshot(collision_, snapshot);
  scene_frame_ = snapshot.frame;
  scene_step_ = snapshot.step;
}

namespace {
bool samePoses(const std::vector<Pose>& a, const std::vector<Pose>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (!samePose(a[i], b[i])) return false;
  return true;
}
}  // namespace

void Resolver::applyForces(int h, const HandProposal& p) {
  HandResult& r = hands_[static_cast<size_t>(h)].result;
  r.force_N = 0.0;
  if (!params_.simulate) return;
  auto dynamic = [&](int o) { return o >= 0 && static_cast<size_t>(o) < dynamic_.size() && dynamic_[static_cast<size_t>(o)]; };
  double total = 0.0;
  for (const ContactLoad& c : p.loads)
    if (dynamic(c.object) && std::isfinite(c.lambda) && c.lambda > 0.0)
      total += std::min(c.lambda, params_.max_force_per_contact);
  if (total <= 0.0) return;
  const double hand_scale = total > params_.max_force_per_hand ? params_.max_force_per_hand / total : 1.0;
  if (hand_scale < 1.0) ++counters_.forces_clamped;
  for (const ContactLoad& c : p.loads) {
    if (!dynamic(c.object) || !std::isfinite(c.lambda) || !(c.lambda > 0.0)) continue;
    double lambda = c.lambda;
    if (lambda > params_.max_force_per_contact) {
      lambda = params_.max_force_per_contact;
      ++counters_.forces_clamped;
    }
    lambda *= hand_scale;
    // The God object is pushed along +n; the reaction on the object is −λ n at the contact.
    forces_.loads.push_back(AppliedLoad{c.object, h, c.body, c.p_W, c.n_W, lambda});
    r.force_N += lambda;
  }
}

void Resolver::resolve(const std::vector<const HandProposal*>& proposals, std::uint64_t frame) {
  if (proposals.size() != hands_.size()) throw std::invalid_argument("resolver: one proposal slot per hand expected");
  ++counters_.frames;
  forces_.frame = frame;
  forces_.loads.clear();
  forces_.bodies.clear();
  for (size_t h = 0; h < hands_.size(); ++h) {
    Hand& hand = hands_[h];
    HandResult& r = hand.result;
    const HandProposal* p = proposals[h];
    const size_t n = hand.model->bodies.size();
    if (!p || p->X_old.size() != n || p->X_new.size() != n) {  // held at the last result
      r.present = false;
      r.frame = frame;
      r.force_N = 0.0;
      if (r.started) ++counters_.held;
      continue;
    }
    // The motion the users see starts at this hand's last result. In lock-step (and in process)
    // the proposal's X_old is that result bit for bit; a live solver that did not have it yet
    // stepped from an older one, and sweeping from there would let the hand jump back unswept.
    const bool continuing = r.started && r.X.size() == n;
    hand.X_from = continuing ? r.X : p->X_old;
    r.present = true;
    r.frame = frame;
    r.scene_frame = scene_frame_;  // trusted or swept again, the poses are checked against this scene
    r.scene_step = scene_step_;
    r.tracked = p->tracked;
    r.started = p->started;
    r.lifted_start = p->lifted_start;
    r.loaded = !p->loads.empty();
    r.diag = p->diag;  // the solver's step; clipping below changes its toc, clipped, joint errors
    StepDiagnostics& d = r.diag;
    r.force_N = 0.0;
    r.ccd_us = r.merge_us = 0.0;
    if (!p->tracked || !p->started) {  // frozen: no motion, no forces
      r.X = hand.X_from;
      d.substeps = 0;
      d.toc = 1.0;
      d.clipped = false;
      d.started_inside = false;
      continue;
    }
    // The solver swept its rounds from this very start against this very scene: its path is the
    // one a sweep here would check (lock-step and in-process runs: always). Otherwise (a live
    // solver that stepped from an older state or scene) the straight motion from the last result
    // is swept again and clipped here.
    if (p->swept && p->scene_frame == scene_frame_ && p->scene_step == scene_step_ && samePoses(hand.X_from, p->X_old)) {
      ++counters_.trusted;
      if (d.started_inside) ++counters_.started_inside;
      if (d.clipped) ++counters_.clipped_steps;
      Clock::time_point t0 = Clock::now();
      applyForces(static_cast<int>(h), *p);
      r.X = p->X_new;
      r.merge_us = usSince(t0);
      if (trace_ >= 1) {
        int o = -1;
        const double pen = penetration(static_cast<int>(h), &o);
        emit(params_, "trace: frame %llu hand %zu rounds %d toc %.3g gap %.3g contacts %d inside %d pen %.3g object %d scene step %llu\n",
                     static_cast<unsigned long long>(frame), h, d.substeps, d.toc, d.joint_errors.gap, d.contacts,
                     d.started_inside, pen, o, static_cast<unsigned long long>(scene_step_));
      }
      continue;
    }
    ++counters_.reswept;
    d.started_inside = false;  // of this sweep, from this start
    // ccd: TOC_min of this cluster
    Clock::time_point t0 = Clock::now();
    double toc = 1.0;
    for (size_t b = 0; b < n; ++b) {
      const Shape& shape = hand.model->bodies[b].shape;
      const geo::SweepResult s = collision_.sweep(shape, hand.X_from[b], p->X_new[b], params_.sweep);
      if (s.started_inside) d.started_inside = true;
      toc = std::min(toc, s.toc);
      if (trace_ >= 2) {
        int o0 = -1, o1 = -1;
        const double pen0 = collision_.penetration(shape, hand.X_from[b], &o0), pen1 = collision_.penetration(shape, p->X_new[b], &o1);
        if (pen1 > pen0 + 1e-7)
          emit(params_, "trace: frame %llu hand %zu body %zu deeper: pen %.3g (object %d) -> %.3g (object %d), toc %.3g hit %d inside %d\n",
               static_cast<unsigned long long>(frame), h, b, pen0, o0, pen1, o1, s.toc, s.hit, s.started_inside);
      }
    }
    if (d.started_inside) ++counters_.started_inside;
    d.toc = std::min(toc, p->diag.toc);
    r.ccd_us = usSince(t0);
    // merge: forces to the scene, clip to TOC_min
    t0 = Clock::now();
    applyForces(static_cast<int>(h), *p);  // λ of this step's contacts
    if (toc < 1.0) {
      // Algorithm 1: move to TOC_min, update the contacts there, re-close the joints against them.
      cutMotion(hand.X_from, p->X_new, toc, &hand.X_toc);
      hand.contacts.clear();
      for (size_t b = 0; b < n; ++b)
        collision_.contacts(hand.model->bodies[b].shape, hand.X_toc[b], static_cast<int>(b), params_.contact_reach,
                            params_.contacts, &hand.contacts);
      hand.X_clip = hand.X_toc;
      JointProjector::Input pin;
      pin.contacts = hand.contacts.data();
      pin.num_contacts = static_cast<int>(hand.contacts.size());
      pin.X_ref = hand.X_toc.data();
      const JointProjector::Result closed = hand.projector->project(hand.X_clip, pin);
      // The re-closing moves bodies too: swept as well. Where it would hit, the hand stays at its
      // last result this frame (swept: no motion), as a solver's round that cannot move would.
      bool free = jointsClosed(closed.joint_errors, params_.step);
      for (size_t b = 0; b < n && free; ++b) {
        const geo::SweepResult s = collision_.sweep(hand.model->bodies[b].shape, hand.X_toc[b], hand.X_clip[b], params_.sweep);
        free = !s.hit && !s.started_inside && s.toc >= 1.0;
      }
      if (free) {
        r.X = hand.X_clip;
        d.joint_errors = closed.joint_errors;
      } else {
        ++counters_.held_back;
        r.X = hand.X_from;
        d.joint_errors = jointErrors(*hand.model, hand.X_from.data());
        d.toc = 0.0;
      }
      d.clipped = true;
    } else {
      r.X = p->X_new;
    }
    if (d.clipped) ++counters_.clipped_steps;
    r.merge_us = usSince(t0);
    if (trace_ >= 1) {
      int o = -1;
      const double pen = penetration(static_cast<int>(h), &o);
      emit(params_, "trace: frame %llu hand %zu toc %.3g gap %.3g contacts %d inside %d pen %.3g object %d scene step %llu\n",
                   static_cast<unsigned long long>(frame), h, toc, d.joint_errors.gap, d.contacts, d.started_inside, pen, o,
                   static_cast<unsigned long long>(scene_step_));
    }
  }
  for (size_t h = 0; h < hands_.size(); ++h) {
    const Hand& hand = hands_[h];
    if (!hand.result.started) continue;
    for (size_t b = 0; b < hand.result.X.size(); ++b)
      forces_.bodies.push_back(GodBody{static_cast<int>(h), static_cast<int>(b), hand.model->bodies[b].shape, hand.result.X[b]});
  }
}

double Resolver::penetration(int hand, int* object) const {
  const Hand& h = hands_[static_cast<size_t>(hand)];
  if (object) *object = -1;
  if (!h.result.started) return 0.0;
  double deepest = 0.0;
  for (size_t b = 0; b < h.result.X.size(); ++b) {
    int o = -1;
    const double d = collision_.penetration(h.model->bodies[b].shape, h.result.X[b], &o);
    if (d > deepest) {
      deepest = d;
      if (object) *object = o;
    }
  }
  return deepest;
}

// ---------------------------------------------------------------------------------------------
// SceneStage

SceneStage::SceneStage(const Scene& scene, const PipelineParams& params, const PhysicsParams& physics)
    : params_(prepared(params)), collision_(scene) {
  if (params_.simulate) physics_ = std::make_unique<PhysicsWorld>(scene, physics);
  snapshot_.objects.reserve(scene.objects.size());
  fill();
}

SceneStage::~SceneStage() = default;

void SceneStage::fill() {
  snapshot_.objects.clear();
  if (!physics_) return;
  for (int o = 0; o < collision_.objectCount(); ++o)
    if (physics_->isDynamic(o))
      snapshot_.objects.push_back(
          ObjectMotion{o, physics_->pose(o), physics_->linearVelocity(o), physics_->angularVelocity(o)});
}

const SceneSnapshot& SceneStage::initial() {
  snapshot_.frame = 0;
  snapshot_.forces_applied = false;
  snapshot_.pushouts = 0;
  snapshot_.step_us = 0.0;
  fill();
  return snapshot_;
}

const SceneSnapshot& SceneStage::step(const ForceSet* forces, std::uint64_t frame) {
  const Clock::time_point t0 = Clock::now();
  snapshot_.frame = frame;
  snapshot_.forces_applied = forces != nullptr;
  snapshot_.pushouts = 0;
  ++snapshot_.step;
  ++counters_.steps;
  if (physics_) {
    if (forces)
      for (const AppliedLoad& l : forces->loads)
        if (l.object >= 0 && l.object < collision_.objectCount() && physics_->isDynamic(l.object))
          physics_->applyForce(l.object, -l.lambda * l.n_W, l.p_W);
    before_.clear();
    for (int o = 0; o < collision_.objectCount(); ++o) before_.push_back(physics_->pose(o));
    physics_->step(params_.step.dt);
    for (int o = 0; o < collision_.objectCount(); ++o)
      if (physics_->isDynamic(o)) collision_.setObjectPose(o, physics_->pose(o));
    // Paper §6.2: objects that Bullet moved into God objects are moved back out, deepest first,
    // iterated to a cap (a push can create a new overlap with another God object).
    const double margin = params_.step.rows.margin;
    bool capped = false;
    for (int it = 0; forces && it < params_.resolve_iterations; ++it) {
      double deepest = 0.0;
      int obj = -1;
      Vec3 n_deep = Vec3::Zero();
      for (const GodBody& g : forces->bodies)
        for (int o = 0; o < collision_.objectCount(); ++o) {
          if (!physics_->isDynamic(o)) continue;
          Vec3 n;
          const double d = collision_.signedDistance(o, g.shape, g.X, margin, &n);
          if (d < margin && margin - d > deepest) {
            deepest = margin - d;
            obj = o;
            n_deep = n;
          }
        }
      if (obj < 0) break;
      // Only penetrations (d < 0) need resolving; closing into the margin is left to the contacts.
      if (deepest <= margin) break;
      Pose X = collision_.objectPose(obj);
      X.p -= n_deep * deepest;  // n points from the object towards the God object
      physics_->setPose(obj, X);
      collision_.setObjectPose(obj, physics_->pose(obj));
      ++snapshot_.pushouts;
      ++counters_.scene_pushouts;
      if (it + 1 == params_.resolve_iterations) {
        ++counters_.pushout_unresolved;
        capped = true;
      }
    }
    // An object the push-outs could not free (squeezed between God objects, e.g. two hands
    // closing on it: each push drives it into the other side) goes back to its pose before this
    // step, the pose the hands were solved against (so clear of them), at rest: held by the hands.
    for (int o = 0; capped && o < collision_.objectCount(); ++o) {
      if (!physics_->isDynamic(o)) continue;
      bool inside = false;
      for (const GodBody& g : forces->bodies) {
        Vec3 n;
        inside = inside || collision_.signedDistance(o, g.shape, g.X, margin, &n) < 0.0;
      }
      if (!inside) continue;
      physics_->setPose(o, before_[static_cast<size_t>(o)]);
      collision_.setObjectPose(o, physics_->pose(o));
      ++counters_.pushout_restored;
    }
  }
  fill();
  snapshot_.step_us = usSince(t0);
  return snapshot_;
}

}  // namespace godhand
