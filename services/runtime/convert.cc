#include "runtime/convert.h"

#include <chrono>
#include <cmath>

namespace godhand::svc {

namespace {
constexpr std::size_t kMaxLoads = 256;      // HandProposal.loads bound
constexpr std::size_t kMaxApplied = 320;    // ContactForces.contacts bound
constexpr std::size_t kMaxGodBodies = 96;   // ContactForces.god_bodies bound
constexpr std::size_t kMaxWrenches = 64;    // ContactForces.objects bound
constexpr int kMaxSubsteps = 1 << 16;       // far above any round count a step takes
constexpr int kMaxContacts = 1 << 20;       // far above any contact count a step has

Vec3 vec(const std::array<double, 3>& a) { return Vec3(a[0], a[1], a[2]); }
void put(const Vec3& v, std::array<double, 3>* a) { *a = {v.x(), v.y(), v.z()}; }
bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }
bool fail(std::string* why, const std::string& reason) {
  if (why) *why = reason;
  return false;
}
bool poses(const std::vector<msg::Pose>& in, std::size_t n, const char* field, std::vector<Pose>* out, std::string* why) {
  if (in.size() != n)
    return fail(why, std::string(field) + ": " + std::to_string(in.size()) + " poses, the model has " + std::to_string(n));
  out->resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    (*out)[i] = fromWire(in[i]);
    if (!isValidPose((*out)[i], 1e-6)) return fail(why, std::string(field) + "[" + std::to_string(i) + "]: not finite or not unit");
  }
  return true;
}
SolveStatus status(std::int32_t s) {
  return s >= 0 && s <= static_cast<std::int32_t>(SolveStatus::NumericalFailure) ? static_cast<SolveStatus>(s)
                                                                                 : SolveStatus::NumericalFailure;
}

// The step's diagnostics (StepDiagnostics) on the wire: HandProposal and HandState carry the same
// fields, the contact count and the solver's times under their own names (passed here).
template <class Msg>
void putDiagnostics(const StepDiagnostics& d, Msg* out, msg::SolverTimes* times) {
  out->kkt(d.kkt);
  out->status(static_cast<std::int32_t>(d.status));
  out->flags(d.flags);
  out->joint_gap(d.joint_errors.gap);
  out->joint_lock(d.joint_errors.lock);
  out->joint_limit(d.joint_errors.limit);
  times->contacts_us(d.times.contacts_us);
  times->assembly_us(d.times.assembly_us);
  times->solve_us(d.times.solve_us);
  times->integrate_us(d.times.integrate_us);
  times->ccd_us(d.times.ccd_us);
  out->substeps(static_cast<std::uint32_t>(d.substeps));
  out->toc(d.toc);
  out->clipped(d.clipped);
  out->started_inside(d.started_inside);
}
/// The diagnostics a real step can carry: residuals and joint errors ≥ 0 (not NaN; +inf is a
/// diverged solve's), a TOC in [0, 1], times finite and ≥ 0, a known status, counts in range. A
/// sample with anything else is not one of ours (or is corrupt): rejected, so that no NaN reaches
/// a HandState or a report.
bool validDiagnostics(const StepDiagnostics& d, std::int32_t wire_status, std::string* why) {
  auto nonNegative = [](double x) { return x >= 0.0; };  // false for NaN
  auto time = [](double x) { return std::isfinite(x) && x >= 0.0; };
  if (!nonNegative(d.kkt)) return fail(why, "kkt: NaN or negative");
  if (!nonNegative(d.joint_errors.gap) || !nonNegative(d.joint_errors.lock) || !nonNegative(d.joint_errors.limit))
    return fail(why, "joint errors: NaN or negative");
  if (!(d.toc >= 0.0 && d.toc <= 1.0)) return fail(why, "toc: not in [0, 1]");
  if (!time(d.times.contacts_us) || !time(d.times.assembly_us) || !time(d.times.solve_us) ||
      !time(d.times.integrate_us) || !time(d.times.ccd_us))
    return fail(why, "solver times: not finite or negative");
  if (wire_status < 0 || wire_status > static_cast<std::int32_t>(SolveStatus::NumericalFailure))
    return fail(why, "status: unknown");
  // (Counts above INT_MAX arrive here negative: the wire's uint32 cast to int.)
  if (d.substeps < 0 || d.substeps > kMaxSubsteps) return fail(why, "substeps: out of range");
  if (d.contacts < 0 || d.contacts > kMaxContacts) return fail(why, "contact count: out of range");
  return true;
}

template <class Msg>
StepDiagnostics diagnostics(const Msg& in, const msg::SolverTimes& times, std::uint32_t contacts) {
  StepDiagnostics d;
  d.contacts = static_cast<int>(contacts);
  d.kkt = in.kkt();
  d.status = status(in.status());
  d.flags = in.flags();
  d.joint_errors = JointErrors{in.joint_gap(), in.joint_lock(), in.joint_limit()};
  d.times = SolverTimes{times.contacts_us(), times.assembly_us(), times.solve_us(), times.integrate_us(), times.ccd_us()};
  d.substeps = static_cast<int>(in.substeps());
  d.toc = in.toc();
  d.clipped = in.clipped();
  d.started_inside = in.started_inside();
  return d;
}
}  // namespace

std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

void toWire(const Pose& X, msg::Pose* out) {
  out->p() = {X.p.x(), X.p.y(), X.p.z()};
  out->q() = {X.q.w(), X.q.x(), X.q.y(), X.q.z()};
}

Pose fromWire(const msg::Pose& X) {
  Pose P;
  P.p = Vec3(X.p()[0], X.p()[1], X.p()[2]);
  P.q = Quat(X.q()[0], X.q()[1], X.q()[2], X.q()[3]);  // Eigen's constructor takes (w, x, y, z)
  return P;
}

void toWire(const Shape& s, msg::BodyShape* out) {
  out->type(static_cast<std::uint8_t>(s.type));
  out->radius(s.radius);
  out->half_length(s.half_length);
  put(s.half_extents, &out->half_extents());
}

msg::Stamp derivedStamp(const msg::Stamp& source) {
  msg::Stamp s = source;
  s.publish_time_ns(nowNs());
  return s;
}

bool fromWire(const msg::HandTarget& in, std::size_t bodies, std::vector<Pose>* targets,
              std::vector<unsigned char>* driven, std::string* why) {
  if (!in.tracked()) return true;
  if (!poses(in.targets(), bodies, "targets", targets, why)) return false;
  if (in.driven().size() != bodies)
    return fail(why, "driven: " + std::to_string(in.driven().size()) + " flags, the model has " + std::to_string(bodies));
  driven->resize(bodies);
  for (std::size_t i = 0; i < bodies; ++i) (*driven)[i] = in.driven()[i] ? 1 : 0;
  if (!(*driven)[0]) return fail(why, "driven[0]: the palm (body 0) must be driven");
  return true;
}

void toWire(const HandProposal& p, msg::HandProposal* out) {
  out->scene_frame(p.scene_frame);
  out->scene_step(p.scene_step);
  out->tracked(p.tracked);
  out->started(p.started);
  out->lifted_start(p.lifted_start);
  out->x_old().resize(p.X_old.size());
  for (std::size_t i = 0; i < p.X_old.size(); ++i) toWire(p.X_old[i], &out->x_old()[i]);
  out->x_new().resize(p.X_new.size());
  for (std::size_t i = 0; i < p.X_new.size(); ++i) toWire(p.X_new[i], &out->x_new()[i]);
  out->contact_count(static_cast<std::uint32_t>(p.diag.contacts));
  const std::size_t n = std::min(p.loads.size(), kMaxLoads);
  out->loads_truncated(p.loads.size() > kMaxLoads);
  out->loads().resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    msg::ContactLoad& c = out->loads()[i];
    c.body(p.loads[i].body);
    c.object(p.loads[i].object);
    put(p.loads[i].p_W, &c.p());
    put(p.loads[i].n_W, &c.n());
    c.lambda(p.loads[i].lambda);
  }
  putDiagnostics(p.diag, out, &out->times());
  out->swept(p.swept);
}

bool fromWire(const msg::HandProposal& in, std::size_t bodies, int objects, HandProposal* out, std::string* why) {
  out->frame = in.stamp().frame();
  out->scene_frame = in.scene_frame();
  out->scene_step = in.scene_step();
  out->tracked = in.tracked();
  out->started = in.started();
  out->lifted_start = in.lifted_start();
  if (!poses(in.x_old(), bodies, "x_old", &out->X_old, why)) return false;
  if (!poses(in.x_new(), bodies, "x_new", &out->X_new, why)) return false;
  out->loads.resize(in.loads().size());
  for (std::size_t i = 0; i < in.loads().size(); ++i) {
    const msg::ContactLoad& c = in.loads()[i];
    ContactLoad& l = out->loads[i];
    l.body = c.body();
    l.object = c.object();
    l.p_W = vec(c.p());
    l.n_W = vec(c.n());
    l.lambda = c.lambda();
    if (l.body < 0 || static_cast<std::size_t>(l.body) >= bodies || l.object < 0 || l.object >= objects)
      return fail(why, "loads[" + std::to_string(i) + "]: body or object index out of range");
    if (!finite(l.p_W) || !finite(l.n_W) || !std::isfinite(l.lambda) || l.lambda < 0.0)
      return fail(why, "loads[" + std::to_string(i) + "]: not finite or negative force");
  }
  out->diag = diagnostics(in, in.times(), in.contact_count());
  if (!validDiagnostics(out->diag, in.status(), why)) return false;
  out->swept = in.swept();
  return true;
}

void toWire(const HandResult& r, const HandModel& model, bool stale, msg::HandState* out) {
  out->scene_frame(r.scene_frame);
  out->scene_step(r.scene_step);
  out->tracked(r.tracked);
  out->started(r.started);
  out->lifted_start(r.lifted_start);
  out->stale(stale);
  out->held(!r.present);
  out->loaded(r.loaded);
  out->poses().resize(r.X.size());
  for (std::size_t i = 0; i < r.X.size(); ++i) toWire(r.X[i], &out->poses()[i]);
  out->shapes().resize(model.bodies.size());
  for (std::size_t i = 0; i < model.bodies.size(); ++i) toWire(model.bodies[i].shape, &out->shapes()[i]);
  out->contacts(static_cast<std::uint32_t>(r.diag.contacts));
  putDiagnostics(r.diag, out, &out->solver_times());
  out->force_n(r.force_N);
  out->ccd_us(r.ccd_us);
  out->merge_us(r.merge_us);
}

bool fromWire(const msg::HandState& in, std::size_t bodies, HandResult* out, std::string* why) {
  out->frame = in.stamp().frame();
  out->scene_frame = in.scene_frame();
  out->scene_step = in.scene_step();
  out->present = !in.held();
  out->tracked = in.tracked();
  out->started = in.started();
  out->lifted_start = in.lifted_start();
  out->loaded = in.loaded();
  if (!poses(in.poses(), bodies, "poses", &out->X, why)) return false;
  out->diag = diagnostics(in, in.solver_times(), in.contacts());
  if (!validDiagnostics(out->diag, in.status(), why)) return false;
  out->force_N = in.force_n();
  out->ccd_us = in.ccd_us();
  out->merge_us = in.merge_us();
  if (!(std::isfinite(out->force_N) && out->force_N >= 0.0) || !(std::isfinite(out->ccd_us) && out->ccd_us >= 0.0) ||
      !(std::isfinite(out->merge_us) && out->merge_us >= 0.0))
    return fail(why, "force or times: not finite or negative");
  return true;
}

void toWire(const ForceSet& f, const CollisionWorld& world, msg::ContactForces* out) {
  // Per-object wrench summary (for renderers and logs): Σ f and Σ (p − o) × f about the object origin.
  out->objects().clear();
  for (const AppliedLoad& l : f.loads) {
    msg::ObjectWrench* w = nullptr;
    for (msg::ObjectWrench& o : out->objects())
      if (o.object() == l.object) w = &o;
    if (!w) {
      if (out->objects().size() >= kMaxWrenches) continue;
      out->objects().emplace_back();
      w = &out->objects().back();
      w->object(l.object);
      w->force() = {0, 0, 0};
      w->torque() = {0, 0, 0};
    }
    const Vec3 force = -l.lambda * l.n_W;
    const Vec3 torque = (l.p_W - world.objectPose(l.object).p).cross(force);
    for (int k = 0; k < 3; ++k) {
      w->force()[static_cast<std::size_t>(k)] += force[k];
      w->torque()[static_cast<std::size_t>(k)] += torque[k];
    }
  }
  const std::size_t n = std::min(f.loads.size(), kMaxApplied);
  out->contacts().resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const AppliedLoad& l = f.loads[i];
    msg::AppliedForce& a = out->contacts()[i];
    a.object(l.object);
    a.hand(static_cast<std::uint32_t>(l.hand));
    a.body(l.body);
    put(l.p_W, &a.p());
    put(l.n_W, &a.n());
    a.lambda(l.lambda);
  }
  const std::size_t nb = std::min(f.bodies.size(), kMaxGodBodies);
  out->god_bodies().resize(nb);
  for (std::size_t i = 0; i < nb; ++i) {
    const GodBody& g = f.bodies[i];
    msg::GodBody& w = out->god_bodies()[i];
    w.hand(static_cast<std::uint32_t>(g.hand));
    w.body(g.body);
    toWire(g.shape, &w.shape());
    toWire(g.X, &w.pose());
  }
}

bool fromWire(const msg::ContactForces& in, int objects, ForceSet* out, std::string* why) {
  out->frame = in.stamp().frame();
  out->loads.resize(in.contacts().size());
  for (std::size_t i = 0; i < in.contacts().size(); ++i) {
    const msg::AppliedForce& a = in.contacts()[i];
    AppliedLoad& l = out->loads[i];
    l.object = a.object();
    l.hand = static_cast<int>(a.hand());
    l.body = a.body();
    l.p_W = vec(a.p());
    l.n_W = vec(a.n());
    l.lambda = a.lambda();
    if (l.object < 0 || l.object >= objects) return fail(why, "contacts[" + std::to_string(i) + "]: object index out of range");
    if (!finite(l.p_W) || !finite(l.n_W) || !std::isfinite(l.lambda) || l.lambda < 0.0)
      return fail(why, "contacts[" + std::to_string(i) + "]: not finite or negative force");
  }
  out->bodies.resize(in.god_bodies().size());
  for (std::size_t i = 0; i < in.god_bodies().size(); ++i) {
    const msg::GodBody& w = in.god_bodies()[i];
    GodBody& g = out->bodies[i];
    g.hand = static_cast<int>(w.hand());
    g.body = w.body();
    const std::uint8_t t = w.shape().type();
    if (t > static_cast<std::uint8_t>(ShapeType::Box)) return fail(why, "god_bodies[" + std::to_string(i) + "]: unknown shape type");
    g.shape.type = static_cast<ShapeType>(t);
    g.shape.radius = w.shape().radius();
    g.shape.half_length = w.shape().half_length();
    g.shape.half_extents = vec(w.shape().half_extents());
    g.X = fromWire(w.pose());
    if (!isValidPose(g.X, 1e-6) || !std::isfinite(g.shape.radius) || g.shape.radius < 0.0 ||
        !std::isfinite(g.shape.half_length) || g.shape.half_length < 0.0 || !finite(g.shape.half_extents) ||
        (g.shape.half_extents.array() < 0.0).any())
      return fail(why, "god_bodies[" + std::to_string(i) + "]: bad shape or pose");
  }
  return true;
}

void toWire(const SceneSnapshot& s, msg::SceneState* out) {
  out->step(s.step);
  out->forces_applied(s.forces_applied);
  out->pushouts(static_cast<std::uint32_t>(s.pushouts));
  out->step_us(s.step_us);
  const std::size_t n = std::min(s.objects.size(), kMaxSceneObjects);
  out->objects().resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    msg::ObjectState& o = out->objects()[i];
    o.index(s.objects[i].index);
    toWire(s.objects[i].X, &o.pose());
    put(s.objects[i].v, &o.v());
    put(s.objects[i].w, &o.w());
  }
}

bool fromWire(const msg::SceneState& in, int objects, SceneSnapshot* out, std::string* why) {
  out->frame = in.stamp().frame();
  out->step = in.step();
  out->forces_applied = in.forces_applied();
  out->pushouts = static_cast<int>(in.pushouts());
  out->step_us = in.step_us();
  out->objects.resize(in.objects().size());
  for (std::size_t i = 0; i < in.objects().size(); ++i) {
    const msg::ObjectState& o = in.objects()[i];
    ObjectMotion& m = out->objects[i];
    m.index = o.index();
    m.X = fromWire(o.pose());
    m.v = vec(o.v());
    m.w = vec(o.w());
    if (m.index < 0 || m.index >= objects) return fail(why, "objects[" + std::to_string(i) + "]: index out of range");
    if (!isValidPose(m.X, 1e-6)) return fail(why, "objects[" + std::to_string(i) + "]: pose not finite or not unit");
    if (!finite(m.v) || !finite(m.w)) return fail(why, "objects[" + std::to_string(i) + "]: velocity not finite");
  }
  if (!(std::isfinite(out->step_us) && out->step_us >= 0.0)) return fail(why, "step_us: not finite or negative");
  return true;
}

void describeScene(const Scene& scene, const std::string& file, msg::SceneDescription* out) {
  out->name(scene.name.substr(0, 64));
  out->file(file.size() <= 160 ? file : file.substr(file.size() - 160));
  const std::size_t n = std::min(scene.objects.size(), kMaxSceneObjects);
  out->objects().resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const SceneObject& so = scene.objects[i];
    msg::ObjectDescription& d = out->objects()[i];
    d.index(static_cast<std::int32_t>(i));
    d.id(so.id.substr(0, 64));
    d.mesh(so.source.size() <= 160 ? so.source : so.source.substr(so.source.size() - 160));
    d.scale(so.scale);
    d.mass(so.mass);
    d.dynamic(so.mass > 0.0 && so.physics.type != PhysicsShapeType::None);
    d.triangles(so.god ? static_cast<std::uint32_t>(so.god->mesh().triangles.size()) : 0u);
    toWire(so.X_WO, &d.initial_pose());
  }
}

void toWire(std::uint64_t run, const SourceCounts& c, msg::SourceCounts* out) {
  out->run(run);
  out->received(c.received);
  out->accepted(c.accepted);
  out->rejected().clear();
  for (const auto& [reason, n] : boundReasons(c.rejected)) {
    msg::ReasonCount r;
    r.reason(reason);
    r.count(n);
    out->rejected().push_back(r);
  }
  out->not_played().clear();
  for (const auto& [reason, n] : boundReasons(c.not_played, kWireNotPlayedReasons)) {
    msg::ReasonCount r;
    r.reason(reason);
    r.count(n);
    out->not_played().push_back(r);
  }
}

SourceCounts fromWire(const msg::SourceCounts& in, std::uint64_t* run) {
  SourceCounts c;
  if (run) *run = in.run();
  c.received = in.received();
  c.accepted = in.accepted();
  for (const msg::ReasonCount& r : in.rejected())
    if (r.count() > 0) c.rejected[r.reason().to_string()] += r.count();
  for (const msg::ReasonCount& r : in.not_played())
    if (r.count() > 0) c.not_played[r.reason().to_string()] += r.count();
  return c;
}

bool plausible(const msg::ServiceStatus& s, std::string* why) {
  // No real run counts 2^53 of anything (that is 3,000 years of frames at 100 kHz); above it
  // sums over runs could wrap, and doubles no longer hold every count.
  constexpr std::uint64_t kMaxCount = std::uint64_t{1} << 53;
  if (!std::isfinite(s.rate_hz()) || s.rate_hz() < 0.0) return fail(why, "rate not finite or negative");
  if (!std::isfinite(s.latency_median_us())) return fail(why, "latency not finite");
  // (Not the frame: a number from the wire, which one hostile sample can set for a real service.)
  for (const std::uint64_t c : {s.samples_in(), s.samples_out(), s.rejected(), s.late(), s.deadline_misses()})
    if (c > kMaxCount) return fail(why, "a counter above 2^53");
  const msg::SourceCounts& src = s.source();
  std::uint64_t rejected = 0;
  for (const msg::ReasonCount& r : src.rejected()) {
    if (r.count() > kMaxCount) return fail(why, "a source count above 2^53");
    rejected += r.count();  // at most 16 × 2^53: no wrap
  }
  std::uint64_t not_played = 0;
  for (const msg::ReasonCount& r : src.not_played()) {
    if (r.count() > kMaxCount) return fail(why, "a source count above 2^53");
    not_played += r.count();  // at most 4 × 2^53: no wrap
  }
  if (src.received() > kMaxCount || src.accepted() > kMaxCount || rejected > kMaxCount || not_played > kMaxCount)
    return fail(why, "a source count above 2^53");
  return true;
}

}  // namespace godhand::svc
