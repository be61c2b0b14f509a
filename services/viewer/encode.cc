#include "viewer/encode.h"

#include <cmath>

namespace godhand::viewer {

using nlohmann::json;

namespace {
json num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }
}  // namespace

json poseJson(const msg::Pose& p) {
  return json::array({num(p.p()[0]), num(p.p()[1]), num(p.p()[2]), num(p.q()[0]), num(p.q()[1]), num(p.q()[2]), num(p.q()[3])});
}

json stampJson(const msg::Stamp& s) {
  return {{"run", s.run()}, {"frame", s.frame()}, {"source_ns", s.source_time_ns()}, {"publish_ns", s.publish_time_ns()}};
}

json handStateJson(const msg::HandState& s, std::int64_t recv_ns, double penetration_m) {
  json poses = json::array(), shapes = json::array();
  for (const msg::Pose& p : s.poses()) poses.push_back(poseJson(p));
  for (const msg::BodyShape& b : s.shapes())
    shapes.push_back(json::array({static_cast<int>(b.type()), num(b.radius()), num(b.half_length()), num(b.half_extents()[0]),
                                  num(b.half_extents()[1]), num(b.half_extents()[2])}));
  const msg::SolverTimes& t = s.solver_times();
  return {{"hand", s.hand()},
          {"cluster", s.cluster().to_string()},
          {"stamp", stampJson(s.stamp())},
          {"recv_ns", recv_ns},
          {"scene_frame", s.scene_frame()},
          {"tracked", s.tracked()},
          {"started", s.started()},
          {"stale", s.stale()},
          {"held", s.held()},
          {"loaded", s.loaded()},
          {"toc", num(s.toc())},
          {"contacts", s.contacts()},
          {"force_n", num(s.force_n())},
          {"joint_gap", num(s.joint_gap())},
          {"penetration_m", penetration_m >= 0 ? num(penetration_m) : json(nullptr)},
          {"times_us",
           {{"contacts", num(t.contacts_us())},
            {"assembly", num(t.assembly_us())},
            {"solve", num(t.solve_us())},
            {"integrate", num(t.integrate_us())},
            {"ccd", num(s.ccd_us())},
            {"merge", num(s.merge_us())}}},
          {"poses", poses},
          {"shapes", shapes}};
}

json handTargetJson(const msg::HandTarget& t, std::int64_t recv_ns) {
  json targets = json::array(), driven = json::array();
  for (const msg::Pose& p : t.targets()) targets.push_back(poseJson(p));
  for (bool d : t.driven()) driven.push_back(d);
  return {{"hand", t.hand()},       {"cluster", t.cluster().to_string()}, {"stamp", stampJson(t.stamp())},
          {"recv_ns", recv_ns},     {"tracked", t.tracked()},             {"confidence", num(t.confidence())},
          {"targets", targets},     {"driven", driven}};
}

json sceneStateJson(const msg::SceneState& s, std::int64_t recv_ns) {
  json objects = json::array();
  for (const msg::ObjectState& o : s.objects()) objects.push_back({{"index", o.index()}, {"pose", poseJson(o.pose())}});
  return {{"stamp", stampJson(s.stamp())}, {"recv_ns", recv_ns},        {"step", s.step()},     {"forces_applied", s.forces_applied()},
          {"pushouts", s.pushouts()},     {"step_us", num(s.step_us())}, {"objects", objects}};
}

json contactForcesJson(const msg::ContactForces& f, std::int64_t recv_ns) {
  json contacts = json::array();
  for (const msg::AppliedForce& c : f.contacts())
    contacts.push_back({{"object", c.object()},
                        {"hand", c.hand()},
                        {"body", c.body()},
                        {"p", json::array({num(c.p()[0]), num(c.p()[1]), num(c.p()[2])})},
                        {"n", json::array({num(c.n()[0]), num(c.n()[1]), num(c.n()[2])})},
                        {"lambda", num(c.lambda())}});
  return {{"stamp", stampJson(f.stamp())}, {"recv_ns", recv_ns}, {"contacts", contacts}};
}

json serviceStatusJson(const msg::ServiceStatus& s, std::int64_t recv_ns) {
  return {{"service", s.service().to_string()},
          {"host", s.host().to_string()},
          {"pid", s.pid()},
          {"time_ns", s.time_ns()},
          {"recv_ns", recv_ns},
          {"state", s.state().to_string()},
          {"frame", s.frame()},
          {"rate_hz", num(s.rate_hz())},
          {"latency_median_us", num(s.latency_median_us())},
          {"samples_in", s.samples_in()},
          {"samples_out", s.samples_out()},
          {"rejected", s.rejected()},
          {"late", s.late()},
          {"deadline_misses", s.deadline_misses()}};
}

json sceneDescriptionJson(const msg::SceneDescription& d, std::int64_t recv_ns, const std::string& generation) {
  json objects = json::array();
  for (const msg::ObjectDescription& o : d.objects())
    objects.push_back({{"index", o.index()},
                       {"id", o.id().to_string()},
                       {"mesh", o.mesh().to_string()},
                       {"scale", num(o.scale())},
                       {"mass", num(o.mass())},
                       {"dynamic", o.dynamic()},
                       {"triangles", o.triangles()},
                       {"pose", poseJson(o.initial_pose())}});
  return {{"name", d.name().to_string()}, {"file", d.file().to_string()}, {"recv_ns", recv_ns},
          {"generation", generation},      {"objects", objects}};
}

}  // namespace godhand::viewer
