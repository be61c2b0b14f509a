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
#include <limits>
#include <deque>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "common/sweep_spec.h"
#ifdef GODHAND_WITH_MUJOCO
#include "compare.h"
#endif
#include "runtime/trace_env.h"
#include "leap/leap_recording.h"
#include "source/live.h"
#include "source/recording.h"
#include "pipeline/run_metrics.h"
#include "pipeline/run_metrics_json.h"
#include "leap/retarget.h"
#include "leap/tool_target.h"
#include "model/hand_model.h"
#include "physics/physics_world.h"
#include "math/stats.h"
#include "pipeline/pipeline.h"
#include "scene/scene_file.h"

namespace {

using namespace godhand;

const char* kUsage =
    "usage: godhand-bench --recording FILE [--scene FILE|none | --mesh FILE[:SIZE_M] ...]\n"
    "                     [--hand-model FILE] [--left-hand-model FILE] [--tool MODEL:BODY] [--solver exact|pgs]\n"
    "                     [--pgs-iterations N] [--substeps N] [--threads N] [--frames N] [--no-physics]\n"
    "                     [--json OUT] [--poses OUT.csv] [--tracker-pose POSE] [--hand-map MAP] [--quiet] [--check]\n"
    "       godhand-bench --compare mujoco --recording FILE [--mesh FILE[:SIZE_M] ... | --scene FILE --no-physics]\n"
    "                     [--mujoco-timestep S] [--mujoco-weld-timeconst S] [--mujoco-contact-timeconst S] [--json OUT]\n"
    "       godhand-bench --sweep GRID.pbtxt --recording FILE [--scene FILE|none | --mesh FILE[:SIZE_M] ...]\n"
    "                     [--frames N] [--repeat N] [--json OUT] [--plot OUT.png|svg] [--target BOUNDS]\n"
    "\n"
    "Runs the God-object method in one process, in lock-step over every frame of a tracker\n"
    "recording, against a scene, and reports what it measured: penetration, joint gap, and beside\n"
    "them the plausibility of the motion against a free twin (the same hand and targets in an\n"
    "empty scene): excess lag, frozen windows, stuck frames (METHOD.md section 5).\n"
    "  --recording FILE      tracker recording, any supported format (detected by content): Leap\n"
    "                        Motion JSON, DTrack datagrams (.dtrack), OpenXR / MediaPipe JSON Lines, Aria\n"
    "                        MPS CSV, synthetic scripts, godhand raw recordings (bridges/README.md)\n"
    "  --scene FILE|none     scene file (protobuf text, idl/scene.proto); default deploy/scenes/default.pbtxt;\n"
    "                        none: no objects (the free twin run)\n"
    "  --mesh FILE[:SIZE_M][@X,Y,Z]\n"
    "                        ad-hoc static scene instead: each mesh (OBJ/STL) scaled uniformly so its\n"
    "                        largest extent is SIZE_M (default 0.15) and centred on the recording's\n"
    "                        mean palm position, or at world X,Y,Z (m) when given (repeatable)\n"
    "  --god-fidelity F      what the God side collides with of each --mesh, or of each mesh object of the\n"
    "                        scene file instead of its `god` (primitives keep theirs): full (default for\n"
    "                        --mesh), hull, decimated:N (vertex clustering to about N triangles), or auto:MM\n"
    "                        (the coarsest of those within MM mm of the full surface, the God objects grown\n"
    "                        by that distance: scene AUTO); penetration is still measured against the\n"
    "                        full mesh\n"
    "  --hand-model FILE     right-hand model (default deploy/models/hand16_right.pbtxt)\n"
    "  --left-hand-model FILE  left-hand model (default deploy/models/hand16_left.pbtxt)\n"
    "  --tool MODEL:BODY     also a tool model (every body's tracker_segment \"tool\", e.g.\n"
    "                        deploy/models/tool1.pbtxt) driven by the recording's 6-DOF body BODY (a DTrack\n"
    "                        6d id, an OpenXR body id); its cluster is named toolBODY (repeatable)\n"
    "  --solver exact|pgs    QP solver (default exact); --pgs-iterations N sweeps (default 30)\n"
    "  --frames N            only the first N frames\n"
    "  --no-physics          dynamic objects stay put (no Bullet)\n"
    "  --physics-hz N        Bullet's internal step rate (default 240; each frame takes ceil(rate/fps) substeps)\n"
    "  --json OUT            write the report as JSON\n"
    "  --poses OUT.csv       write every God object's world pose every frame, and its target's\n"
    "                        (columns tpx..tqz, empty when the body has no target that frame)\n"
    "  --substeps N          solve -> sweep rounds per frame (default %SUBSTEPS%)\n"
    "  --compare mujoco      also drive the same hands with MuJoCo (each body welded to a mocap target) on the\n"
    "                        same frames, stepped after godhand in each frame, and print both engines' figures\n"
    "                        side by side (JSON: \"compare\"); static scenes only. Needs a build with MuJoCo\n"
    "                        (Debian libmujoco-dev: deploy/run.sh compare installs it)\n"
    "  --mujoco-timestep S   MuJoCo's timestep (default 0.002 s; a frame takes ceil(frame period / S) steps)\n"
    "  --mujoco-weld-timeconst S, --mujoco-contact-timeconst S\n"
    "                        MuJoCo's solref time constants of the welds and of the contacts (default 0.02 s)\n"
    "  --threads N           threads of the in-process run (default: the cores): the hands' solvers at\n"
    "                        once, and each hand's bodies' contact and sweep queries spread over them (a light\n"
    "                        hand leaves its core to the other; 1: everything one after the other). The\n"
    "                        results are the same for every N\n"
    "  --clamped-rounds N    rounds a frame may take while only the motion clamp shortened them (none\n"
    "                        clipped), each gaining on the last (default %CLAMPED_ROUNDS%; the larger of this and --substeps)\n"
    "  --hit-resolves N      a round whose sweep hit is solved again from its start with the hit bodies'\n"
    "                        contacts at their TOC, at most N times, before it is clipped (default %HIT_RESOLVES%; 0: clip)\n"
    "  --reacquire-after S   a hand tracked again after a loss of at least S seconds starts again at its\n"
    "                        targets (or the nearest free pose), the jump swept from where it was lost;\n"
    "                        shorter losses go on from there (default 0.1; inf = never)\n"
    "  --stuck-rotation RAD  a body whose last sweep hit at once may turn at most RAD in its next step\n"
    "                        (default 0.05; 0 = no cap)\n"
    "  --contact-rotation R  most a body within 5 mm of a contact turns per frame, rad (default %CONTACT_ROT%)\n"
    "  --max-rotation R, --max-translation M  most any body turns (rad) / moves (m) per frame (%MAX_ROT%, %MAX_TRANS%)\n"
    "  --contacts-per-pair K contacts kept per (God object, scene object) (default 8)\n"
    "  --stop-distance M     the sweep stops a body this far from a surface, m (default 2.5e-5)\n"
    "  --sweep-iterations N  conservative-advancement iterations per sweep before it stops where verified (default 100)\n"
    "  --contact-margin M    the solver keeps contacts this far apart, m (default 1e-4)\n"
    "  --push-out B          share of a contact's deficit under the margin made good per step (default 0.5)\n"
    "  --tracker-pose POSE   tracker to world: x,y,z[,rx,ry,rz degrees | ,qw,qx,qy,qz] (default identity)\n"
    "  --tracker-units U, --tracker-up A, --palm-offset F,T,P\n"
    "                        DTrack (files and raw recordings of live DTrack): the room's units mm|cm|m\n"
    "                        (default mm), its up axis z|y (default z), the palm centre from the hand target\n"
    "                        (godhand-ingest's options and the lab's tracker { }: give a raw recording the\n"
    "                        calibration of the run that recorded it)\n"
    "  --hand-map MAP        tracker hand id -> side, e.g. 0:left,1:right; other ids dropped, counted\n"
    "                        (--hand-sides is the same)\n"
    "  --tracking-volume M   hands with a coordinate beyond M m of the tracker are dropped, counted (default 50)\n"
    "  --max-speed MPS       palm jumps faster than this are dropped, counted (default 30 m/s)\n"
    "  --quiet               no progress lines\n"
    "  --sweep GRID.pbtxt    the speed/accuracy sweep (services/bench/sweep.py): every point of the grid\n"
    "                        (idl/sweep.proto; deploy/sweeps/default.pbtxt) run on the recording and\n"
    "                        scene, figures per point, the Pareto front; --json writes points and\n"
    "                        pareto, --plot draws them (matplotlib), --target \"penetration_max_m<=1e-4,\n"
    "                        excess_lag_p95_m<=3e-3\" names the fastest point within the bounds; --repeat N\n"
    "                        runs each point N times and takes the median of its timings\n"
    "  --check               exit 1 unless penetration <= margin, joint gap <= 1e-6 m, no solver failures,\n"
    "                        every hand started and was not held in most of its frames, no stuck frame\n"
    "                        and frozen windows <= 5 % of the moving windows\n"
    "Exit status: 0 ok, 1 --check failed, 2 bad arguments or input (one line on stderr).\n";

/// kUsage with the clamp and round defaults filled in from PipelineParams (one definition).
std::string usageText() {
  const PipelineParams d;
  auto num = [](double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return std::string(b);
  };
  std::string u = kUsage;
  const std::pair<const char*, std::string> fields[] = {{"%SUBSTEPS%", std::to_string(d.max_substeps)},
                                                        {"%HIT_RESOLVES%", std::to_string(d.hit_resolves)},
                                                        {"%CLAMPED_ROUNDS%", std::to_string(d.max_clamped_rounds)},
                                                        {"%CONTACT_ROT%", num(d.step.max_step_rotation_in_contact)},
                                                        {"%MAX_ROT%", num(d.step.max_step_rotation)},
                                                        {"%MAX_TRANS%", num(d.step.max_step_translation)}};
  for (const auto& [key, value] : fields) u.replace(u.find(key), std::strlen(key), value);
  return u;
}

struct Args {
  std::string recording, scene, json, poses;
  bridges::CalibrationText calibration;  ///< --tracker-*, --hand-map, --palm-offset, --tracking-volume, --max-speed
  std::vector<std::string> meshes;
  std::string right_model = std::string(GODHAND_DEPLOY_DIR) + "/models/hand16_right.pbtxt";
  std::string left_model = std::string(GODHAND_DEPLOY_DIR) + "/models/hand16_left.pbtxt";
  std::vector<std::pair<std::string, int>> tools;  ///< --tool MODEL:BODY
  SolverKind solver = SolverKind::Exact;
  int pgs_iterations = 30;
  long frames = -1;
  int physics_hz = 240;
  int substeps = PipelineParams{}.max_substeps;
  int clamped_rounds = PipelineParams{}.max_clamped_rounds;
  int hit_resolves = PipelineParams{}.hit_resolves;
  int threads = 0;  // 0: min(hands, cores)
  std::string compare;  // "" or "mujoco"
  double mj_timestep = 0.002, mj_weld = 0.02, mj_contact = 0.02;
  double stuck_rotation = PipelineParams{}.stuck_rotation;
  double reacquire_after = PipelineParams{}.reacquire_after;
  double contact_rotation = PipelineParams{}.step.max_step_rotation_in_contact;
  double max_rotation = PipelineParams{}.step.max_step_rotation;
  int per_pair = PipelineParams{}.contacts.per_pair;
  double max_translation = PipelineParams{}.step.max_step_translation;
  double stop_distance = PipelineParams{}.sweep.stop_distance;
  int sweep_iterations = PipelineParams{}.sweep.max_iterations;
  double contact_margin = PipelineParams{}.step.rows.margin;
  double push_out = PipelineParams{}.step.rows.contact_beta;
  std::string god_fidelity;  // --god-fidelity (for --mesh scenes)
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

double parseDouble(const std::string& flag, const std::string& v, double lo, double hi) {
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || errno != 0 || !(x >= lo && x <= hi) || v.find_first_of("xX") != std::string::npos)
    fail(flag + ": expected a number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got '" + v + "'");
  return x;
}

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) fail(f + ": missing value");
      std::string v = argv[++i];
      if (v.empty()) fail(f + ": empty value (leave the option out for its default)");
      return v;
    };
    if (f == "--help" || f == "-h") {
      std::cout << usageText();
      std::exit(0);
    } else if (f == "--recording") a.recording = value();
    else if (f == "--scene") a.scene = value();
    else if (f == "--mesh") a.meshes.push_back(value());
    else if (f == "--god-fidelity") a.god_fidelity = value();
    else if (f == "--hand-model") a.right_model = value();
    else if (f == "--left-hand-model") a.left_model = value();
    else if (f == "--tool") {
      const std::string v = value();
      const size_t colon = v.rfind(':');
      if (colon == std::string::npos || colon == 0) fail("--tool: expected MODEL:BODY (e.g. deploy/models/tool1.pbtxt:1), got '" + v + "'");
      a.tools.emplace_back(v.substr(0, colon), static_cast<int>(parseCount(f, v.substr(colon + 1), 0, 1000)));
    }
    else if (f == "--json") a.json = value();
    else if (f == "--poses") a.poses = value();
    else if (f == "--tracker-pose") a.calibration.pose = value();
    else if (f == "--tracker-units") a.calibration.units = value();
    else if (f == "--tracker-up") a.calibration.up = value();
    else if (f == "--palm-offset") a.calibration.palm_offset = value();
    else if (f == "--contact-rotation") a.contact_rotation = parseDouble(f, value(), 1e-6, 10.0);
    else if (f == "--max-rotation") a.max_rotation = parseDouble(f, value(), 1e-6, 10.0);
    else if (f == "--contacts-per-pair") a.per_pair = static_cast<int>(parseCount(f, value(), 1, 64));
    else if (f == "--max-translation") a.max_translation = parseDouble(f, value(), 1e-6, 100.0);
    else if (f == "--stop-distance") a.stop_distance = parseDouble(f, value(), 1e-6, 1e-2);
    else if (f == "--sweep-iterations") a.sweep_iterations = static_cast<int>(parseCount(f, value(), 1, 100000));
    else if (f == "--contact-margin") a.contact_margin = parseDouble(f, value(), 0.0, 1e-2);
    else if (f == "--push-out") a.push_out = parseDouble(f, value(), 0.0, 1.0);
    else if (f == "--hand-map" || f == "--hand-sides") a.calibration.hand_map = value();
    else if (f == "--tracking-volume") a.calibration.volume_m = parseDouble(f, value(), 1e-3, 1e9);
    else if (f == "--max-speed") a.calibration.max_speed = parseDouble(f, value(), 1e-3, 1e9);
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
    else if (f == "--clamped-rounds") a.clamped_rounds = static_cast<int>(parseCount(f, value(), 1, 64));
    else if (f == "--hit-resolves") a.hit_resolves = static_cast<int>(parseCount(f, value(), 0, 16));
    else if (f == "--threads") a.threads = static_cast<int>(parseCount(f, value(), 1, 64));
    else if (f == "--compare") {
      a.compare = value();
      if (a.compare != "mujoco") fail("--compare: expected mujoco, got '" + a.compare + "'");
    } else if (f == "--mujoco-timestep") a.mj_timestep = parseDouble(f, value(), 1e-5, 0.1);
    else if (f == "--mujoco-weld-timeconst") a.mj_weld = parseDouble(f, value(), 1e-5, 10.0);
    else if (f == "--mujoco-contact-timeconst") a.mj_contact = parseDouble(f, value(), 1e-5, 10.0);
    else if (f == "--stuck-rotation") a.stuck_rotation = parseDouble(f, value(), 0.0, 10.0);
    else if (f == "--reacquire-after") {
      const std::string v = value();
      a.reacquire_after = v == "inf" ? std::numeric_limits<double>::infinity() : parseDouble(f, v, 0.0, 3600.0);
    }
    else if (f == "--check") a.check = true;
    else fail("unknown argument '" + f + "' (see --help)");
  }
  if (a.recording.empty()) fail("--recording FILE is required (see --help)");
  if (!a.scene.empty() && !a.meshes.empty()) fail("--scene and --mesh exclude each other");
  if (!a.god_fidelity.empty() && a.scene == "none") fail("--god-fidelity: --scene none has no objects");
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
  // The speed/accuracy sweep and its grid (services/bench/sweep.py measures; the grid's text
  // format is read here, the one parser of idl/sweep.proto).
  const std::vector<std::string> all_args(argv + 1, argv + argc);
  if (argc == 3 && all_args[0] == "--print-sweep-grid") {
    try {
      std::cout << sweepSpecJson(loadSweepSpec(all_args[1])) << "\n";
      return 0;
    } catch (const SweepSpecError& e) { fail(e.what()); }
  }
  if (std::find(all_args.begin(), all_args.end(), "--sweep") != all_args.end() &&
      std::find(all_args.begin(), all_args.end(), "--help") == all_args.end()) {
    std::vector<std::string> cmd;
    try {
      cmd = sweepCommand(all_args, GODHAND_SWEEP_SCRIPT, "/proc/self/exe");
      loadSweepSpec(cmd.back());  // a bad grid: its one line here, before anything runs
      char self[4096];
      const ssize_t n = ::readlink("/proc/self/exe", self, sizeof self - 1);
      if (n > 0) cmd[3] = std::string(self, static_cast<size_t>(n));
    } catch (const SweepSpecError& e) { fail(e.what()); }
    std::vector<char*> c_args;
    for (std::string& a : cmd) c_args.push_back(a.data());
    c_args.push_back(nullptr);
    ::execvp(c_args[0], c_args.data());
    fail(std::string("--sweep: cannot run python3: ") + std::strerror(errno));
  }
  const Args args = parseArgs(argc, argv);

  // Inputs: recording, models, scene. Any problem: one line, exit 2.
  bridges::LoadedRecording rec;
  HandModel right, left;
  std::deque<HandModel> tool_models;  // stable addresses
  Scene scene;
  try {
    rec = bridges::loadRecording(args.recording, bridges::sourceOptions(args.calibration));
  } catch (const std::exception& e) { fail(e.what()); }
  if (rec.frames.empty()) fail(args.recording + ": no usable frames (" + rec.rejections + ")");
  try {
    right = loadHandModel(args.right_model);
    left = loadHandModel(args.left_model);
    for (const auto& [file, body] : args.tools) {
      tool_models.push_back(loadHandModel(file));
      if (!leap::isToolModel(tool_models.back()))
        fail("--tool " + file + ": not a tool model (every body needs tracker_segment \"tool\")");
    }
  } catch (const std::exception& e) { fail(e.what()); }
  try {
    if (!args.meshes.empty()) {
      std::vector<MeshSpec> specs;
      const GodFidelity god = args.god_fidelity.empty() ? GodFidelity{} : parseGodFidelity(args.god_fidelity);
      for (const std::string& m : args.meshes) {
        specs.push_back(parseMeshSpec(m));
        specs.back().god = god;
      }
      scene = meshScene(specs, rec.mean_palm_W, meshFileLoader());
    } else if (args.scene == "none") {
      scene.name = "none";
    } else {
      const std::optional<GodFidelity> god =
          args.god_fidelity.empty() ? std::nullopt : std::optional<GodFidelity>(parseGodFidelity(args.god_fidelity));
      scene = loadScene(args.scene.empty() ? std::string(GODHAND_DEPLOY_DIR) + "/scenes/default.pbtxt" : args.scene,
                        god ? &*god : nullptr);
    }
  } catch (const std::exception& e) { fail(e.what()); }
  for (const SceneObject& o : scene.objects)  // said at once: it changes what the figures mean
    if (o.surface_changed)
      std::fprintf(stderr, "godhand-bench: note: %s (%s): %s\n", o.id.c_str(), o.source.c_str(), o.surface_note.c_str());

  // One cluster per hand side that the recording contains (right first).
  bool has_side[2] = {false, false};  // 0 right, 1 left
  for (const leap::TrackerFrame& f : rec.frames)
    for (const leap::TrackedHand& h : f.hands) has_side[h.right ? 0 : 1] = true;
  std::vector<int> sides;  // 0 right, 1 left, 2 + BODY a tool driven by 6-DOF body BODY
  std::vector<const HandModel*> models;
  std::vector<std::string> names;
  for (int s = 0; s < 2; ++s)
    if (has_side[s]) {
      sides.push_back(s);
      models.push_back(s == 0 ? &right : &left);
      names.push_back(s == 0 ? "right" : "left");
    }
  for (size_t t = 0; t < args.tools.size(); ++t) {
    const int body = args.tools[t].second;
    bool seen = false;
    for (const leap::TrackerFrame& f : rec.frames)
      for (const leap::TrackedBody& b : f.bodies) seen = seen || b.id == body;
    if (!seen) fail("--tool " + args.tools[t].first + ":" + std::to_string(body) + ": no frame of " + args.recording +
                    " carries 6-DOF body " + std::to_string(body) + " (" + rec.rejections + ")");
    sides.push_back(2 + body);
    models.push_back(&tool_models[t]);
    names.push_back("tool" + std::to_string(body));
  }
  if (sides.empty()) fail(args.recording + ": no tracked hands (" + rec.rejections + ")");

  const double rate = rec.mean_rate_hz;
  if (!(rate > 1.0 && rate <= 20000.0))
    fail(args.recording + ": frame rate " + std::to_string(rate) +
         " Hz from the timestamps is outside (1, 20000] Hz (timestamps in the wrong unit, repeated or out of order?)");
  PipelineParams params;
  svc::traceFromEnvironment(&params);
  params.step.dt = 1.0 / rate;
  params.step.solver = args.solver;
  params.step.pgs.sweeps = args.pgs_iterations;
  params.simulate = args.physics;
  params.max_substeps = args.substeps;
  params.max_clamped_rounds = args.clamped_rounds;
  params.hit_resolves = args.hit_resolves;
  params.stuck_rotation = args.stuck_rotation;
  params.reacquire_after = args.reacquire_after;
  params.step.max_step_rotation_in_contact = args.contact_rotation;
  params.step.max_step_rotation = args.max_rotation;
  params.step.max_step_translation = args.max_translation;
  params.contacts.per_pair = args.per_pair;
  params.sweep.stop_distance = args.stop_distance;
  params.sweep.max_iterations = args.sweep_iterations;
  params.step.rows.margin = args.contact_margin;
  params.step.rows.contact_beta = args.push_out;
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  params.threads = args.threads > 0 ? args.threads : cores;
  std::unique_ptr<Pipeline> pipe;
  std::unique_ptr<RunMetrics> metrics;
  std::vector<std::unique_ptr<leap::Retargeter>> retarget;  // per cluster; none for a tool
  try {
    const PhysicsParams physics = physicsParamsFor(rate, args.physics_hz);
    pipe = std::make_unique<Pipeline>(scene, models, params, physics);
    metrics = std::make_unique<RunMetrics>(scene, models, names, params);
    for (size_t h = 0; h < models.size(); ++h) {
      retarget.push_back(sides[h] < 2 ? std::make_unique<leap::Retargeter>(*models[h]) : nullptr);
      // A model of the other side would be refused by the retargeter at the hand's first frame.
      const std::optional<bool> is_right = retarget.back() ? retarget.back()->modelIsRight() : std::nullopt;
      if (is_right && *is_right != (sides[h] == 0))
        fail(std::string(sides[h] == 0 ? "--hand-model " + args.right_model : "--left-hand-model " + args.left_model) + ": model '" +
             models[h]->name + "' is a " + (*is_right ? "right" : "left") + " hand, but it would be driven by the recording's " +
             (sides[h] == 0 ? "right" : "left") + " hand (give the " + (sides[h] == 0 ? "right" : "left") + " model, e.g. deploy/models/hand16_" +
             (sides[h] == 0 ? "right" : "left") + ".pbtxt)");
    }
  } catch (const std::exception& e) { fail(e.what()); }
#ifdef GODHAND_WITH_MUJOCO
  std::unique_ptr<bench::Comparison> compare;
  if (!args.compare.empty()) {
    try {
      mujoco::Params mj;
      mj.timestep = args.mj_timestep;
      mj.weld_timeconst = args.mj_weld;
      mj.contact_timeconst = args.mj_contact;
      compare = std::make_unique<bench::Comparison>(scene, models, names, params, 1.0 / rate, mj);
    } catch (const std::exception& e) { fail(e.what()); }
  }
#else
  if (!args.compare.empty())
    fail("--compare mujoco: this godhand-bench was built without MuJoCo (install Debian's libmujoco-dev and rebuild; "
         "deploy/run.sh compare does both)");
#endif

  for (const std::string* out : {&args.json, &args.poses})  // before the run, not after it
    if (!out->empty())
      if (const std::string why = unwritableReason(*out); !why.empty()) fail(*out + ": cannot write: " + why);
  std::ofstream poses_out;
  if (!args.poses.empty()) {
    poses_out.open(args.poses);
    if (!poses_out) fail(args.poses + ": cannot write");
    poses_out << "frame,hand,body,shape,radius,half_length,hx,hy,hz,px,py,pz,qw,qx,qy,qz,tpx,tpy,tpz,tqw,tqx,tqy,tqz\n";
    poses_out.precision(17);
  }

  const size_t n_frames = args.frames > 0 ? std::min(rec.frames.size(), static_cast<size_t>(args.frames)) : rec.frames.size();
  const size_t H = sides.size();
  std::vector<std::vector<Pose>> targets(H);
  std::vector<std::vector<unsigned char>> has(H);
  std::vector<HandInput> inputs(H);
  std::vector<double> step_us, st_contacts, st_assembly, st_solve, st_integrate, st_ccd, st_merge, st_scene;
  double kkt_max = 0;
  int contacts_max = 0;
  ResultHash hash;
  // The dynamic objects' motion (Bullet's poses after every frame): where each started, where it
  // ended, how high it rose above its start, how far it got from it, how fast it went. With
  // --no-physics there is no Bullet world and the objects stay put (none is reported moving).
  struct ObjectTrack {
    int index = 0;
    Pose start, final_pose;
    double max_rise = 0.0, max_drop = 0.0, max_displacement = 0.0, max_speed = 0.0;
    std::uint64_t awake_frames = 0;  // frames after which Bullet had it awake
  };
  std::vector<ObjectTrack> tracks;
  for (size_t o = 0; o < scene.objects.size(); ++o)
    if (scene.objects[o].mass > 0.0) {
      ObjectTrack t;
      t.index = static_cast<int>(o);
      t.start = t.final_pose = pipe->physics() ? pipe->physics()->pose(t.index) : scene.objects[o].X_WO;
      tracks.push_back(t);
    }
  const auto t_run = std::chrono::steady_clock::now();
  auto t_progress = t_run;
  for (size_t fi = 0; fi < n_frames; ++fi) {
    const leap::TrackerFrame& f = rec.frames[fi];
    for (size_t h = 0; h < H; ++h) {
      inputs[h] = HandInput{};
      if (sides[h] >= 2) {  // a tool: its 6-DOF body, when this frame carries it
        double quality = 0.0;
        if (!leap::toolTargets(*models[h], f, sides[h] - 2, &targets[h], &has[h], &quality)) continue;
        inputs[h].tracked = true;
        inputs[h].targets = targets[h].data();
        inputs[h].has_target = has[h].data();
        continue;
      }
      const leap::TrackedHand* th = nullptr;
      for (const leap::TrackedHand& c : f.hands)
        if ((c.right ? 0 : 1) == sides[h] && (!th || c.confidence > th->confidence)) th = &c;
      if (!th) continue;
      retarget[h]->targets(*th, &targets[h], &has[h]);
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
    if (const PhysicsWorld* w = pipe->physics())
      for (ObjectTrack& t : tracks) {
        t.final_pose = w->pose(t.index);
        const Vec3 d = t.final_pose.p - t.start.p;
        t.max_rise = std::max(t.max_rise, d.z());
        t.max_drop = std::max(t.max_drop, -d.z());
        t.max_displacement = std::max(t.max_displacement, d.norm());
        t.max_speed = std::max(t.max_speed, w->linearVelocity(t.index).norm());
        if (w->isAwake(t.index)) ++t.awake_frames;
      }
    // Figures of METHOD.md §5, outside the timed step (core/pipeline/run_metrics.h).
    for (size_t h = 0; h < H; ++h) {
      const HandFrameReport& hr = r.hands[h];
      const std::vector<Pose>& X = pipe->poses(static_cast<int>(h));
      HandSample sample;
      sample.started = hr.started;
      sample.tracked = hr.tracked;
      sample.X = hr.started ? X.data() : nullptr;
      sample.targets = inputs[h].targets;
      sample.has_target = inputs[h].has_target;
      sample.loaded = hr.loaded;
      sample.clipped = hr.diag.clipped;
      sample.toc = hr.diag.toc;
      sample.substeps = hr.diag.substeps;
      sample.joint_gap = hr.diag.joint_errors.gap;
      metrics->add(static_cast<int>(h), sample, inputs[h], pipe->resolver().collision());
      if (!hr.started) continue;
      if (hr.tracked) kkt_max = std::max(kkt_max, hr.diag.kkt);
      const HandModel& m = pipe->model(static_cast<int>(h));
      for (size_t b = 0; b < X.size(); ++b) {
        hash.add(X[b]);
        if (poses_out) {
          const Shape& s = m.bodies[b].shape;
          poses_out << fi << ',' << names[h] << ',' << m.bodies[b].name << ',' << shapeName(s.type) << ',' << s.radius
                    << ',' << s.half_length << ',' << s.half_extents.x() << ',' << s.half_extents.y() << ','
                    << s.half_extents.z() << ',' << X[b].p.x() << ',' << X[b].p.y() << ',' << X[b].p.z() << ','
                    << X[b].q.w() << ',' << X[b].q.x() << ',' << X[b].q.y() << ',' << X[b].q.z();
          if (inputs[h].tracked && has[h][b]) {
            const Pose& T = targets[h][b];
            poses_out << ',' << T.p.x() << ',' << T.p.y() << ',' << T.p.z() << ',' << T.q.w() << ',' << T.q.x() << ','
                      << T.q.y() << ',' << T.q.z() << '\n';
          } else {
            poses_out << ",,,,,,,\n";
          }
        }
      }
    }
#ifdef GODHAND_WITH_MUJOCO
    if (compare) compare->step(inputs, pipe->resolver().collision());
#endif
    const auto now = std::chrono::steady_clock::now();
    if (!args.quiet && std::chrono::duration<double>(now - t_progress).count() > 2.0) {
      t_progress = now;
      std::fprintf(stderr, "godhand-bench: frame %zu/%zu\n", fi + 1, n_frames);
    }
    if (!args.poses.empty() && !poses_out) fail(args.poses + ": write failed at frame " + std::to_string(fi) + " (disk full?)");
  }
  if (!args.poses.empty()) {
    poses_out.close();
    if (poses_out.fail()) fail(args.poses + ": write failed (disk full?)");
  }
  const PipelineCounters& c = pipe->counters();
  const RunSummary sum = metrics->summary();
  const HandSummary& all = sum.all;
  const double median = percentile(step_us, 0.5);
  const double hz = median > 0 ? 1e6 / median : 0.0;
  const double margin = params.step.rows.margin;
  // Each object's share of the frame time (core/pipeline/run_metrics.h).
  std::vector<std::uint64_t> awake;  // empty: no Bullet world
  if (pipe->physics()) awake.assign(scene.objects.size(), 0);
  for (const ObjectTrack& t : tracks)
    if (!awake.empty()) awake[static_cast<size_t>(t.index)] = t.awake_frames;
  double frames_us = 0.0;
  for (double us : step_us) frames_us += us;
  const ObjectShares shares = objectShares(scene, pipe->godCosts(), awake, n_frames, frames_us);

  std::printf("godhand-bench: %s (%s), %zu frames at %.1f Hz, %zu hand(s), scene '%s' (%lld God-collision triangles)\n",
              args.recording.c_str(), rec.format.c_str(), n_frames, rate, H, scene.name.c_str(), scene.god_triangles);
  if (!rec.rejections.empty()) std::printf("  recording: %s\n", rec.rejections.c_str());
  if (rec.gaps)
    std::printf("  recording: %llu gap(s) in the timestamps (0.1 s or more, over twice the median interval) left out of "
                "the rate; %llu of them silences of 1 s or more (as a live source's), filled with %llu frames without hands\n",
                static_cast<unsigned long long>(rec.gaps), static_cast<unsigned long long>(rec.pauses),
                static_cast<unsigned long long>(rec.filled_frames));
  for (const SceneObject& o : scene.objects)
    if (!args.meshes.empty())
      std::printf("  mesh %s: scale %.6g, then translation (%.4f, %.4f, %.4f) m, placed at (%.4f, %.4f, %.4f) m\n",
                  o.source.c_str(), o.scale, o.translation.x(), o.translation.y(), o.translation.z(), o.X_WO.p.x(),
                  o.X_WO.p.y(), o.X_WO.p.z());
  for (const SceneObject& o : scene.objects)
    if (!o.god_note.empty()) std::printf("  God side of %s: %s\n", o.id.c_str(), o.god_note.c_str());
  for (const SceneObject& o : scene.objects)
    if (o.surface_changed)
      std::printf("  surface of %s: %s\n", o.id.c_str(), o.surface_note.c_str());
  std::printf("  step (the in-process frame, every hand and the scene; %d thread%s, %d per hand's bodies): median %.1f us "
              "(%.0f Hz), p99 %.1f us, max %.1f us\n",
              pipe->params().threads, pipe->params().threads == 1 ? "" : "s", pipe->params().body_threads, median, hz,
              percentile(step_us, 0.99), percentile(step_us, 1.0));
  std::printf("  stages (median us): contacts %.1f, assembly %.1f, solve %.1f, integrate %.1f, ccd %.1f, merge %.1f, scene %.1f\n",
              percentile(st_contacts, 0.5), percentile(st_assembly, 0.5), percentile(st_solve, 0.5),
              percentile(st_integrate, 0.5), percentile(st_ccd, 0.5), percentile(st_merge, 0.5), percentile(st_scene, 0.5));
  std::printf("  penetration max %.4f mm (allowed: the %.3f mm margin), joint gap max %.2e m\n", all.penetration_max_m * 1e3,
              margin * 1e3, all.joint_gap_max_m);
  for (const HandSummary& hs : sum.hands) std::printf("  %s\n", describe(hs).c_str());
  std::printf("  clipped %llu hand-frames (TOC < 1e-3 in %llu), solve -> sweep rounds %llu (max %llu in a frame); "
              "contacts max %d, KKT max %.1e, solver failures %llu, inexact solves %llu, QPs in the joints' coordinates %llu of %llu (the rest by the general solver), lifted starts %llu, re-acquisitions after a loss %llu, scene push-outs %llu (%llu objects left squeezed, put back)\n",
              static_cast<unsigned long long>(all.clipped_frames), static_cast<unsigned long long>(all.toc_below_1e3),
              static_cast<unsigned long long>(all.substeps), static_cast<unsigned long long>(all.substeps_max), contacts_max,
              kkt_max, static_cast<unsigned long long>(c.solver_failures), static_cast<unsigned long long>(c.inexact_solves),
              static_cast<unsigned long long>(c.qp_tree), static_cast<unsigned long long>(c.qp_tree + c.qp_general),
              static_cast<unsigned long long>(c.lifted_starts), static_cast<unsigned long long>(c.reacquisitions),
              static_cast<unsigned long long>(c.scene_pushouts),
              static_cast<unsigned long long>(c.pushout_restored));
  std::printf("  sweeps %llu (%llu answered without a query), conservative-advancement iterations %llu (%.2f per sweep), "
              "%llu stopped at the iteration bound; "
              "clipped rounds: %llu with each body at its own TOC, %llu with the hand at TOC_min, %llu left where they started; "
              "rounds whose projection opened the joints: %llu shortened, %llu of them kept the last state; "
              "rounds that went back against the round before (their clamp halved): %llu; "
              "rounds solved again with the contacts their sweep hit: %llu (%llu of them held the hand and were clipped instead)\n",
              static_cast<unsigned long long>(c.sweeps), static_cast<unsigned long long>(c.sweeps_certified),
              static_cast<unsigned long long>(c.sweep_iterations),
              c.sweeps ? static_cast<double>(c.sweep_iterations) / static_cast<double>(c.sweeps) : 0.0,
              static_cast<unsigned long long>(c.sweeps_capped), static_cast<unsigned long long>(c.per_body_clips),
              static_cast<unsigned long long>(c.uniform_clips), static_cast<unsigned long long>(c.held_rounds),
              static_cast<unsigned long long>(c.rounds_shortened), static_cast<unsigned long long>(c.rounds_kept),
              static_cast<unsigned long long>(c.reversed_rounds), static_cast<unsigned long long>(c.hit_resolves),
              static_cast<unsigned long long>(c.resolves_undone));
  std::printf("  %s\n", describe(shares).c_str());
  for (const ObjectTrack& t : tracks) {
    const Vec3 d = t.final_pose.p - t.start.p;
    std::printf("  object %s: moved (%.4f, %.4f, %.4f) m start -> end, rose at most %.4f m, dropped at most %.4f m, "
                "farthest %.4f m from its start, speed max %.3f m/s\n",
                scene.objects[static_cast<size_t>(t.index)].id.c_str(), d.x(), d.y(), d.z(), t.max_rise, t.max_drop,
                t.max_displacement, t.max_speed);
  }
#ifdef GODHAND_WITH_MUJOCO
  if (compare) std::fputs(compare->table(sum, step_us).c_str(), stdout);
#endif
  if (!sum.failure.empty()) std::printf("  FAILED RUN: %s\n", sum.failure.c_str());
  char hex[32];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash.h));
  if (sum.failure.empty()) std::printf("  result hash %s\n", hex);

  if (!args.json.empty()) {
    nlohmann::json j;
    j["recording"] = args.recording;
    j["recording_format"] = rec.format;
    j["recording_rejections"] = rec.rejections;
    j["recording_filled_frames"] = rec.filled_frames;
    j["recording_gaps"] = rec.gaps;
    j["scene"] = scene.name;
    j["frames"] = n_frames;
    j["hands"] = H;
    j["triangles"] = scene.god_triangles;
    j["reference_triangles"] = scene.reference_triangles;
    j["frame_rate_hz"] = rate;
    j["solver"] = args.solver == SolverKind::Exact ? "exact" : "pgs";
    j["physics_hz"] = args.physics ? args.physics_hz : 0;
    j["max_substeps"] = args.substeps;
    j["max_clamped_rounds"] = args.clamped_rounds;
    j["hit_resolves_max"] = args.hit_resolves;
    j["threads"] = params.threads;
    j["body_threads"] = pipe->params().body_threads;
    j["step_us"] = {{"median", median}, {"p99", percentile(step_us, 0.99)}, {"max", percentile(step_us, 1.0)}};
    j["hz_median"] = hz;
    j["stages_us"] = {{"contacts", percentile(st_contacts, 0.5)}, {"assembly", percentile(st_assembly, 0.5)},
                      {"solve", percentile(st_solve, 0.5)},       {"integrate", percentile(st_integrate, 0.5)},
                      {"ccd", percentile(st_ccd, 0.5)},           {"merge", percentile(st_merge, 0.5)},
                      {"scene", percentile(st_scene, 0.5)}};
    j["penetration_max_m"] = all.penetration_max_m;
    j["margin_m"] = margin;
    j["joint_gap_max_m"] = all.joint_gap_max_m;
    j["free_tracking_error_max_m"] = all.free_tracking_error_m.max;
    j["free_tracking_error_median_m"] = all.free_tracking_error_m.median;
    j["excess_lag_m"] = toJson(all.excess_lag_m);
    j["excess_lag_above_5mm"] = all.lag_above_5mm;
    j["moving_windows"] = all.moving_windows;
    j["frozen_windows"] = all.frozen_windows;
    j["stuck_frames"] = all.stuck_frames;
    j["jitter_body_frames"] = all.jitter_body_frames;
    j["jitter_checked"] = all.jitter_checked;
    j["twin_jitter_body_frames"] = all.twin_jitter_body_frames;
    j["model_error_m"] = toJson(all.model_error_m);
    j["contact_gap_m"] = toJson(all.contact_gap_m);
    j["clipped_frames"] = all.clipped_frames;
    j["toc_below_1e-3"] = all.toc_below_1e3;
    j["substeps"] = all.substeps;
    j["plausibility"] = toJson(sum);
    j["contacts_max"] = contacts_max;
    j["kkt_residual_max"] = kkt_max;
    j["solver_failures"] = c.solver_failures;
    j["inexact_solves"] = c.inexact_solves;
    j["qp_tree_solves"] = c.qp_tree;
    j["qp_general_solves"] = c.qp_general;
    j["rounds_shortened"] = c.rounds_shortened;
    j["rounds_kept"] = c.rounds_kept;
    j["clipped_steps"] = c.clipped_steps;
    j["lifted_starts"] = c.lifted_starts;
    j["reacquisitions"] = c.reacquisitions;
    j["reversed_rounds"] = c.reversed_rounds;
    j["hit_resolves"] = c.hit_resolves;
    j["hit_resolves_undone"] = c.resolves_undone;
    j["started_inside"] = c.started_inside;
    j["scene_pushouts"] = c.scene_pushouts;
    j["scene_pushouts_unresolved"] = c.pushout_unresolved;
    j["scene_pushouts_restored"] = c.pushout_restored;
    j["forces_clamped"] = c.forces_clamped;
    j["sweeps"] = c.sweeps;
    j["sweep_iterations"] = c.sweep_iterations;
    j["sweeps_capped"] = c.sweeps_capped;
    j["per_body_clips"] = c.per_body_clips;
    j["sweeps_certified"] = c.sweeps_certified;
    j["held_rounds"] = c.held_rounds;
    j["uniform_clips"] = c.uniform_clips;
    if (sum.failure.empty()) j["result_hash"] = hex;
    else j["failure"] = sum.failure;
    // Every object's placement: file coordinates -> world, p_W = scale R p_file + t (R, t the
    // world pose applied after the scale and the --mesh centring translation).
    nlohmann::json objects = nlohmann::json::array();
    for (size_t oi = 0; oi < scene.objects.size(); ++oi) {
      const SceneObject& o = scene.objects[oi];
      const Vec3 t = o.X_WO.p + o.X_WO.q * o.translation;
      nlohmann::json share = toJson(shares.objects[oi], shares.frames);
      share.erase("id");
      share.erase("dynamic");
      objects.push_back({{"id", o.id},
                         {"source", o.source},
                         {"scale", o.scale},
                         {"rotation_wxyz", {o.X_WO.q.w(), o.X_WO.q.x(), o.X_WO.q.y(), o.X_WO.q.z()}},
                         {"translation_m", {t.x(), t.y(), t.z()}},
                         {"dynamic", o.mass > 0.0},
                         {"god_triangles", o.god ? o.god->triangleCount() : 0},
                         {"reference_triangles", o.reference ? o.reference->triangleCount() : 0},
                         {"god_skin_m", o.god_skin},
                         {"god_note", o.god_note},
                         {"solid", o.reference ? o.reference->solid() : true},
                         {"surface_note", o.surface_note}});
      objects.back().update(share);
    }
    j["objects"] = objects;
    j["god_side"] = {{"us_per_frame", n_frames ? shares.god_us / static_cast<double>(n_frames) : 0.0},
                     {"share_pct", frames_us > 0.0 ? 100.0 * shares.god_us / frames_us : 0.0}};
    // The dynamic objects' motion over the run (Bullet's pose after each frame; world, m).
    nlohmann::json motion = nlohmann::json::array();
    for (const ObjectTrack& t : tracks) {
      const Pose& a = t.start;
      const Pose& b = t.final_pose;
      motion.push_back({{"id", scene.objects[static_cast<size_t>(t.index)].id},
                        {"start_position_m", {a.p.x(), a.p.y(), a.p.z()}},
                        {"start_rotation_wxyz", {a.q.w(), a.q.x(), a.q.y(), a.q.z()}},
                        {"final_position_m", {b.p.x(), b.p.y(), b.p.z()}},
                        {"final_rotation_wxyz", {b.q.w(), b.q.x(), b.q.y(), b.q.z()}},
                        {"max_rise_m", t.max_rise},
                        {"max_drop_m", t.max_drop},
                        {"max_displacement_m", t.max_displacement},
                        {"max_speed_mps", t.max_speed},
                        {"simulated", pipe->physics() != nullptr}});
    }
    j["dynamic_objects"] = motion;
#ifdef GODHAND_WITH_MUJOCO
    if (compare) j["compare"] = compare->json(step_us);
#endif
    if (!args.meshes.empty()) j["meshes"] = objects;
    std::ofstream out(args.json);
    out << j.dump(2) << "\n";
    if (!out) fail(args.json + ": cannot write");
  }
  if (args.check) {
    std::string why;
    const bool plausible_run = plausible(sum, &why);
    const bool ok = all.penetration_max_m <= margin && all.joint_gap_max_m <= 1e-6 && c.solver_failures == 0 && plausible_run;
    if (!plausible_run) std::printf("  not plausible: %s\n", why.c_str());
    std::printf("check: %s (penetration <= %.1e m, joint gap <= 1e-6 m, no solver failures, every hand started and not held, "
                "no stuck frame, frozen windows <= 5 %%)\n",
                ok ? "ok" : "FAILED", margin);
    return ok ? 0 : 1;
  }
  return sum.failure.empty() ? 0 : 1;
}
