// godhand-bench: the whole in-process method over a tracker recording, in lock-step, with the
// figures of METHOD.md §5 (penetration, joint gap, free-space tracking error, step time and its
// stages) as a human summary and optionally a JSON report and a per-frame pose CSV.
#include <algorithm>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "leap/leap_recording.h"
#include "leap/retarget.h"
#include "model/hand_model.h"
#include "physics/physics_world.h"
#include "math/stats.h"
#include "pipeline/pipeline.h"
#include "scene/scene_file.h"

namespace {

using namespace godhand;

const char* kUsage =
    "usage: godhand-bench --recording FILE [--scene FILE | --mesh FILE[:SIZE_M] ...]\n"
    "                     [--hand-model FILE] [--left-hand-model FILE] [--solver exact|pgs]\n"
    "                     [--pgs-iterations N] [--frames N] [--no-physics] [--json OUT] [--poses OUT.csv]\n"
    "                     [--quiet]\n"
    "\n"
    "Runs the God-object method in one process, in lock-step over every frame of a Leap Motion\n"
    "JSON recording, against a scene, and reports what it measured.\n"
    "  --recording FILE      Leap Motion JSON recording (leapjs-playback formats 0.1 and 1)\n"
    "  --scene FILE          scene file (protobuf text, idl/scene.proto); default deploy/scenes/default.pbtxt\n"
    "  --mesh FILE[:SIZE_M]  ad-hoc static scene instead: each mesh (OBJ/STL) scaled uniformly so its\n"
    "                        largest extent is SIZE_M (default 0.15) and centred on the recording's\n"
    "                        mean palm position (repeatable)\n"
    "  --hand-model FILE     right-hand model (default deploy/models/hand16_right.pbtxt)\n"
    "  --left-hand-model FILE  left-hand model (default deploy/models/hand16_left.pbtxt)\n"
    "  --solver exact|pgs    QP solver (default exact); --pgs-iterations N sweeps (default 30)\n"
    "  --frames N            only the first N frames\n"
    "  --no-physics          dynamic objects stay put (no Bullet)\n"
    "  --physics-hz N        Bullet's internal step rate (default 240; each frame takes ceil(rate/fps) substeps)\n"
    "  --json OUT            write the report as JSON\n"
    "  --poses OUT.csv       write every God object's world pose every frame\n"
    "  --quiet               no progress lines\n"
    "  --check               exit 1 unless penetration <= margin, joint gap <= 1e-6 m and no solver failures\n"
    "Exit status: 0 ok, 1 --check failed, 2 bad arguments or input (one line on stderr).\n";

struct Args {
  std::string recording, scene, json, poses;
  std::vector<std::string> meshes;
  std::string right_model = std::string(GODHAND_DEPLOY_DIR) + "/models/hand16_right.pbtxt";
  std::string left_model = std::string(GODHAND_DEPLOY_DIR) + "/models/hand16_left.pbtxt";
  SolverKind solver = SolverKind::Exact;
  int pgs_iterations = 30;
  long frames = -1;
  int physics_hz = 240;
  int substeps = PipelineParams{}.max_substeps;
  bool physics = true, quiet = false, check = false;
};

[[noreturn]] void fail(const std::string& msg) {
  std::cerr << "godhand-bench: " << msg << "\n";
  std::exit(2);
}

long parseCount(const std::string& flag, const std::string& v, long lo, long hi) {
  char* end = nullptr;
  errno = 0;
  const long x = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || errno != 0 || x < lo || x > hi)
    fail(flag + ": expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got '" + v + "'");
  return x;
}

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) fail(f + ": missing value");
      return argv[++i];
    };
    if (f == "--help" || f == "-h") {
      std::cout << kUsage;
      std::exit(0);
    } else if (f == "--recording") a.recording = value();
    else if (f == "--scene") a.scene = value();
    else if (f == "--mesh") a.meshes.push_back(value());
    else if (f == "--hand-model") a.right_model = value();
    else if (f == "--left-hand-model") a.left_model = value();
    else if (f == "--json") a.json = value();
    else if (f == "--poses") a.poses = value();
    else if (f == "--solver") {
      const std::string s = value();
      if (s == "exact") a.solver = SolverKind::Exact;
      else if (s == "pgs") a.solver = SolverKind::Pgs;
      else fail("--solver: expected exact or pgs, got '" + s + "'");
    } else if (f == "--pgs-iterations") a.pgs_iterations = static_cast<int>(parseCount(f, value(), 1, 100000));
    else if (f == "--frames") a.frames = parseCount(f, value(), 1, 1L << 40);
    else if (f == "--no-physics") a.physics = false;
    else if (f == "--physics-hz") a.physics_hz = static_cast<int>(parseCount(f, value(), 10, 100000));
    else if (f == "--quiet") a.quiet = true;
    else if (f == "--substeps") a.substeps = static_cast<int>(parseCount(f, value(), 1, 64));
    else if (f == "--check") a.check = true;
    else fail("unknown argument '" + f + "' (see --help)");
  }
  if (a.recording.empty()) fail("--recording FILE is required (see --help)");
  if (!a.scene.empty() && !a.meshes.empty()) fail("--scene and --mesh exclude each other");
  return a;
}

const char* shapeName(ShapeType t) {
  switch (t) {
    case ShapeType::Capsule: return "capsule";
    case ShapeType::Sphere: return "sphere";
    case ShapeType::Box: return "box";
  }
  return "?";
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parseArgs(argc, argv);

  // Inputs: recording, models, scene. Any problem: one line, exit 2.
  leap::Recording rec;
  HandModel right, left;
  Scene scene;
  try {
    rec = leap::Recording::load(args.recording);
  } catch (const std::exception& e) { fail(e.what()); }
  if (rec.frames().empty()) fail(args.recording + ": no usable frames");
  try {
    right = HandModel::loadFile(args.right_model);
    left = HandModel::loadFile(args.left_model);
  } catch (const std::exception& e) { fail(e.what()); }
  try {
    if (!args.meshes.empty()) {
      std::vector<MeshSpec> specs;
      for (const std::string& m : args.meshes) specs.push_back(parseMeshSpec(m));
      scene = meshScene(specs, rec.meanPalmPosition());
    } else {
      scene = loadScene(args.scene.empty() ? std::string(GODHAND_DEPLOY_DIR) + "/scenes/default.pbtxt" : args.scene);
    }
  } catch (const std::exception& e) { fail(e.what()); }

  // One cluster per hand side that the recording contains (right first).
  bool has_side[2] = {false, false};  // 0 right, 1 left
  for (const leap::TrackerFrame& f : rec.frames())
    for (const leap::TrackedHand& h : f.hands) has_side[h.right ? 0 : 1] = true;
  std::vector<int> sides;
  std::vector<const HandModel*> models;
  for (int s = 0; s < 2; ++s)
    if (has_side[s]) {
      sides.push_back(s);
      models.push_back(s == 0 ? &right : &left);
    }
  if (sides.empty()) fail(args.recording + ": no tracked hands");

  const double rate = rec.meanFrameRate();
  if (!(rate > 1.0 && rate < 10000.0)) fail(args.recording + ": implausible frame rate " + std::to_string(rate));
  PipelineParams params;
  params.step.dt = 1.0 / rate;
  params.step.solver = args.solver;
  params.step.pgs.sweeps = args.pgs_iterations;
  params.simulate = args.physics;
  params.max_substeps = args.substeps;
  std::unique_ptr<Pipeline> pipe;
  std::vector<leap::Retargeter> retarget;
  try {
    const PhysicsParams physics = physicsParamsFor(rate, args.physics_hz);
    pipe = std::make_unique<Pipeline>(scene, models, params, physics);
    for (const HandModel* m : models) retarget.emplace_back(*m);
  } catch (const std::exception& e) { fail(e.what()); }

  std::ofstream poses_out;
  if (!args.poses.empty()) {
    poses_out.open(args.poses);
    if (!poses_out) fail(args.poses + ": cannot write");
    poses_out << "frame,hand,body,shape,radius,half_length,hx,hy,hz,px,py,pz,qw,qx,qy,qz\n";
    poses_out.precision(17);
  }

  const size_t n_frames = args.frames > 0 ? std::min(rec.frames().size(), static_cast<size_t>(args.frames)) : rec.frames().size();
  const size_t H = sides.size();
  std::vector<std::vector<Pose>> targets(H);
  std::vector<std::vector<unsigned char>> has(H);
  std::vector<HandInput> inputs(H);
  std::vector<double> step_us, st_contacts, st_assembly, st_solve, st_integrate, st_ccd, st_merge, st_scene;
  double pen_max = 0, gap_max = 0, free_err_max = 0, kkt_max = 0;
  std::vector<double> free_err;
  int contacts_max = 0;
  long clipped_frames = 0, lifted = 0;
  ResultHash hash;
  const auto t_run = std::chrono::steady_clock::now();
  auto t_progress = t_run;
  for (size_t fi = 0; fi < n_frames; ++fi) {
    const leap::TrackerFrame& f = rec.frames()[fi];
    for (size_t h = 0; h < H; ++h) {
      inputs[h] = HandInput{};
      const leap::TrackedHand* th = nullptr;
      for (const leap::TrackedHand& c : f.hands)
        if ((c.right ? 0 : 1) == sides[h] && (!th || c.confidence > th->confidence)) th = &c;
      if (!th) continue;
      retarget[h].targets(*th, &targets[h], &has[h]);
      inputs[h].tracked = true;
      inputs[h].targets = targets[h].data();
      inputs[h].has_target = has[h].data();
    }
    const FrameReport& r = pipe->step(inputs);
    step_us.push_back(r.times.total_us);
    st_contacts.push_back(r.times.contacts_us);
    st_assembly.push_back(r.times.assembly_us);
    st_solve.push_back(r.times.solve_us);
    st_integrate.push_back(r.times.integrate_us);
    st_ccd.push_back(r.times.ccd_us);
    st_merge.push_back(r.times.merge_us);
    st_scene.push_back(r.times.scene_us);
    contacts_max = std::max(contacts_max, r.contacts);
    // Figures of METHOD.md §5, outside the timed step.
    for (size_t h = 0; h < H; ++h) {
      const HandFrameReport& hr = r.hands[h];
      if (hr.lifted_start) ++lifted;
      if (hr.toc < 1.0) ++clipped_frames;
      if (!hr.started) continue;
      pen_max = std::max(pen_max, pipe->penetration(static_cast<int>(h)));
      gap_max = std::max(gap_max, hr.joint_errors.gap);
      if (hr.tracked) {
        kkt_max = std::max(kkt_max, hr.kkt);
        // Free space: no contact of this hand carries force this frame.
        if (!hr.loaded) {
          const std::vector<Pose>& X = pipe->poses(static_cast<int>(h));
          double e = 0;
          for (size_t b = 0; b < X.size(); ++b)
            if (has[h][b]) e = std::max(e, (X[b].p - targets[h][b].p).norm());
          free_err.push_back(e);
          free_err_max = std::max(free_err_max, e);
        }
      }
      const std::vector<Pose>& X = pipe->poses(static_cast<int>(h));
      const HandModel& m = pipe->model(static_cast<int>(h));
      for (size_t b = 0; b < X.size(); ++b) {
        hash.add(X[b]);
        if (poses_out) {
          const Shape& s = m.bodies[b].shape;
          poses_out << fi << ',' << (sides[h] == 0 ? "right" : "left") << ',' << m.bodies[b].name << ','
                    << shapeName(s.type) << ',' << s.radius << ',' << s.half_length << ',' << s.half_extents.x() << ','
                    << s.half_extents.y() << ',' << s.half_extents.z() << ',' << X[b].p.x() << ',' << X[b].p.y() << ','
                    << X[b].p.z() << ',' << X[b].q.w() << ',' << X[b].q.x() << ',' << X[b].q.y() << ',' << X[b].q.z()
                    << '\n';
        }
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (!args.quiet && std::chrono::duration<double>(now - t_progress).count() > 2.0) {
      t_progress = now;
      std::fprintf(stderr, "godhand-bench: frame %zu/%zu, penetration max %.4f mm\n", fi + 1, n_frames, pen_max * 1e3);
    }
  }
  const PipelineCounters& c = pipe->counters();
  const double median = percentile(step_us, 0.5);
  const double hz = median > 0 ? 1e6 / median : 0.0;

  std::printf("godhand-bench: %s, %zu frames at %.1f Hz, %zu hand(s), scene '%s' (%lld God-collision triangles)\n",
              args.recording.c_str(), n_frames, rate, H, scene.name.c_str(), scene.god_triangles);
  for (const SceneObject& o : scene.objects)
    if (!args.meshes.empty())
      std::printf("  mesh %s: scale %.6g, translation (%.4f, %.4f, %.4f) m\n", o.source.c_str(), o.scale,
                  o.translation.x(), o.translation.y(), o.translation.z());
  std::printf("  step: median %.1f us (%.0f Hz), p99 %.1f us, max %.1f us\n", median, hz, percentile(step_us, 0.99),
              percentile(step_us, 1.0));
  std::printf("  stages (median us): contacts %.1f, assembly %.1f, solve %.1f, integrate %.1f, ccd %.1f, merge %.1f, scene %.1f\n",
              percentile(st_contacts, 0.5), percentile(st_assembly, 0.5), percentile(st_solve, 0.5),
              percentile(st_integrate, 0.5), percentile(st_ccd, 0.5), percentile(st_merge, 0.5), percentile(st_scene, 0.5));
  std::printf("  penetration max %.4f mm (margin %.3f mm), joint gap max %.2e m, free tracking error max %.2f mm (median %.2f mm)\n",
              pen_max * 1e3, params.step.rows.margin * 1e3, gap_max, free_err_max * 1e3, percentile(free_err, 0.5) * 1e3);
  std::printf("  contacts max %d, KKT max %.1e, solver failures %llu, inexact solves %llu, clipped steps %llu, lifted starts %llu, scene push-outs %llu\n",
              contacts_max, kkt_max, static_cast<unsigned long long>(c.solver_failures),
              static_cast<unsigned long long>(c.inexact_solves), static_cast<unsigned long long>(c.clipped_steps),
              static_cast<unsigned long long>(c.lifted_starts), static_cast<unsigned long long>(c.scene_pushouts));
  std::printf("  result hash %016llx\n", static_cast<unsigned long long>(hash.h));

  if (!args.json.empty()) {
    nlohmann::json j;
    j["recording"] = args.recording;
    j["scene"] = scene.name;
    j["frames"] = n_frames;
    j["hands"] = H;
    j["triangles"] = scene.god_triangles;
    j["reference_triangles"] = scene.reference_triangles;
    j["frame_rate_hz"] = rate;
    j["solver"] = args.solver == SolverKind::Exact ? "exact" : "pgs";
    j["physics_hz"] = args.physics ? args.physics_hz : 0;
    j["step_us"] = {{"median", median}, {"p99", percentile(step_us, 0.99)}, {"max", percentile(step_us, 1.0)}};
    j["hz_median"] = hz;
    j["stages_us"] = {{"contacts", percentile(st_contacts, 0.5)}, {"assembly", percentile(st_assembly, 0.5)},
                      {"solve", percentile(st_solve, 0.5)},       {"integrate", percentile(st_integrate, 0.5)},
                      {"ccd", percentile(st_ccd, 0.5)},           {"merge", percentile(st_merge, 0.5)},
                      {"scene", percentile(st_scene, 0.5)}};
    j["penetration_max_m"] = pen_max;
    j["margin_m"] = params.step.rows.margin;
    j["joint_gap_max_m"] = gap_max;
    j["free_tracking_error_max_m"] = free_err_max;
    j["free_tracking_error_median_m"] = percentile(free_err, 0.5);
    j["contacts_max"] = contacts_max;
    j["kkt_residual_max"] = kkt_max;
    j["solver_failures"] = c.solver_failures;
    j["inexact_solves"] = c.inexact_solves;
    j["clipped_steps"] = c.clipped_steps;
    j["lifted_starts"] = c.lifted_starts;
    j["started_inside"] = c.started_inside;
    j["scene_pushouts"] = c.scene_pushouts;
    j["forces_clamped"] = c.forces_clamped;
    char hex[32];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash.h));
    j["result_hash"] = hex;
    if (!args.meshes.empty()) {
      nlohmann::json meshes = nlohmann::json::array();
      for (const SceneObject& o : scene.objects)
        meshes.push_back({{"mesh", o.source}, {"scale", o.scale},
                          {"translation_m", {o.translation.x(), o.translation.y(), o.translation.z()}}});
      j["meshes"] = meshes;
    }
    std::ofstream out(args.json);
    out << j.dump(2) << "\n";
    if (!out) fail(args.json + ": cannot write");
  }
  if (args.check) {
    const bool ok = pen_max <= params.step.rows.margin && gap_max <= 1e-6 && c.solver_failures == 0;
    std::printf("check: %s (penetration <= %.1e m, joint gap <= 1e-6 m, no solver failures)\n", ok ? "ok" : "FAILED",
                params.step.rows.margin);
    return ok ? 0 : 1;
  }
  return 0;
}
