// godhand-demo: the in-process demonstration of the God-hand solver (until the distributed
// services exist). A 16-body God hand follows a scripted tracked hand that descends onto a
// table, presses 2 cm into it, slides, closes its fingers around a ball resting on the table
// (targets curl past the anatomical limits and into the ball) and lifts off. Contacts come from
// exact analytic distances (capsule/sphere/box against plane and sphere); mesh collision and
// CCD are the next stage. It prints what it measured per phase and overall.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/files.h"
#include "model/hand_model.h"
#include "step/cluster_step.h"

namespace {
using namespace godhand;

const char* kUsage =
    "usage: godhand-demo [--model FILE] [--solver exact|pgs] [--pgs-sweeps N] [--dt SECONDS]\n"
    "                    [--frames-per-phase N]\n"
    "In-process God-hand demonstration: a scripted hand presses into a table and grasps a ball.\n"
    "Prints per phase: step time (median/p99), contacts, penetration (exact, analytic), joint gap,\n"
    "limit violation, free-space tracking error and solver KKT residual.\n"
    "  --model FILE          hand model (protobuf text); default: the bundled 16-body right hand\n"
    "  --solver exact|pgs    exact active-set solver (default) or projected Gauss-Seidel\n"
    "  --pgs-sweeps N        PGS sweeps per step (default 30)\n"
    "  --dt SECONDS          time step (default 0.001)\n"
    "  --frames-per-phase N  steps per phase (default 400)\n";

struct Plane { double height; };
struct Ball { Vec3 centre; double radius; };

/// Closest point on segment [a, b] to p.
Vec3 closestOnSegment(const Vec3& a, const Vec3& b, const Vec3& p) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return a + t * ab;
}

/// Exact contacts of one body against the table and the ball within `reach`, and the body's
/// exact signed distance to each (for the penetration figure).
struct DemoScene {
  Plane table{0.0};
  Ball ball{Vec3(0.0, 0.19, 0.04), 0.04};
  double reach = 0.05;  // speculative contacts: tangent half-spaces of convex obstacles are conservative

  double contacts(int bi, const Body& body, const Pose& X, std::vector<Contact>& out) const {
    double dmin = 1e9;
    auto add = [&](const Vec3& p, const Vec3& n, double d, std::uint64_t id, int object) {
      dmin = std::min(dmin, d);
      if (d < reach) out.push_back({bi, p, n, d, (static_cast<std::uint64_t>(bi) << 16) | id, object});
    };
    const Vec3 up(0, 0, 1);
    switch (body.shape.type) {
      case ShapeType::Capsule:
      case ShapeType::Sphere: {
        const double r = body.shape.radius;
        const double h = body.shape.type == ShapeType::Capsule ? body.shape.half_length : 0.0;
        const Vec3 a = X * Vec3(0, 0, -h), b = X * Vec3(0, 0, h);
        add(a - r * up, up, a.z() - r - table.height, 1, 0);
        if (h > 0) add(b - r * up, up, b.z() - r - table.height, 2, 0);
        const Vec3 q = closestOnSegment(a, b, ball.centre);
        const Vec3 n = (q - ball.centre).normalized();
        add(q - r * n, n, (q - ball.centre).norm() - r - ball.radius, 3, 1);
        break;
      }
      case ShapeType::Box: {
        const Vec3 he = body.shape.half_extents;
        for (int c = 0; c < 8; ++c) {
          const Vec3 corner = X * Vec3((c & 1 ? 1 : -1) * he.x(), (c & 2 ? 1 : -1) * he.y(), (c & 4 ? 1 : -1) * he.z());
          add(corner, up, corner.z() - table.height, 10 + static_cast<std::uint64_t>(c), 0);
        }
        const Vec3 local = X.inverse() * ball.centre;
        const Vec3 cp = X * local.cwiseMax(-he).cwiseMin(he);
        const Vec3 d = cp - ball.centre;
        if (d.norm() > 1e-12) add(cp, d.normalized(), d.norm() - ball.radius, 20, 1);
        break;
      }
    }
    return dmin;
  }
};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(std::min<double>(static_cast<double>(v.size() - 1), q * static_cast<double>(v.size())))];
}

/// Scripted tracker: the hand frame pose and finger curl (rad per joint) at phase time s ∈ [0,1].
struct Phase { const char* name; Vec3 from, to; double curl_from, curl_to; };

[[noreturn]] void fail(const std::string& msg) {
  std::fprintf(stderr, "godhand-demo: %s\n", msg.c_str());
  std::exit(2);
}

double numberArg(const char* flag, const char* v) {
  char* end = nullptr;
  const double x = std::strtod(v, &end);
  if (!end || *end || !std::isfinite(x) || std::strpbrk(v, "xX")) fail(std::string(flag) + ": not a number: '" + v + "'");
  return x;
}

}  // namespace

int main(int argc, char** argv) {
  std::string model_path = GODHAND_MODELS_DIR "/hand16_right.pbtxt";
  StepParams params;
  int frames = 400;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) fail(a + " needs a value (see --help)");
      return argv[++i];
    };
    if (a == "--help" || a == "-h") { std::fputs(kUsage, stdout); return 0; }
    else if (a == "--model") model_path = value();
    else if (a == "--solver") {
      const std::string s = value();
      if (s == "exact") params.solver = SolverKind::Exact;
      else if (s == "pgs") params.solver = SolverKind::Pgs;
      else fail("--solver must be exact or pgs, got '" + s + "'");
    } else if (a == "--pgs-sweeps") {
      const double n = numberArg("--pgs-sweeps", value());
      if (!(n >= 1 && n <= 100000) || n != std::floor(n)) fail("--pgs-sweeps must be a whole number in [1, 100000]");
      params.pgs.sweeps = static_cast<int>(n);
    }
    else if (a == "--dt") params.dt = numberArg("--dt", value());
    else if (a == "--frames-per-phase") {
      const double n = numberArg("--frames-per-phase", value());
      frames = n >= 1 && n <= 1000000 && n == std::floor(n) ? static_cast<int>(n) : 0;  // 0: refused below
    }
    else fail("unknown argument '" + a + "' (see --help)");
  }
  if (frames < 1 || frames > 1000000) fail("--frames-per-phase must be in [1, 1000000]");
  if (!(params.dt >= 1e-6 && params.dt <= 1.0)) fail("--dt must be in [1e-6, 1] s");

  HandModel model;
  try {
    model = loadHandModel(model_path);
  } catch (const ModelError& e) {
    fail(e.what());
  }
  std::unique_ptr<ClusterStepper> stepper;
  try {
    stepper = std::make_unique<ClusterStepper>(model, params);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  const DemoScene scene;
  // Model frame: palm-down hand, fingers along +y; place it 5 cm above the table, behind the ball.
  const double lift = 0.05;
  const Phase phases[] = {
      {"approach", Vec3(0, 0, lift), Vec3(0, 0, 0.016), 0.0, 0.0},
      {"press 2 cm into the table", Vec3(0, 0, 0.016), Vec3(0, 0, -0.004), 0.0, 0.0},
      {"slide while pressed", Vec3(0, 0, -0.004), Vec3(0.0, 0.02, -0.004), 0.0, 0.0},
      {"move over the ball", Vec3(0.0, 0.02, -0.004), Vec3(0.0, 0.06, 0.075), 0.0, 0.0},
      {"close fingers on the ball", Vec3(0.0, 0.06, 0.075), Vec3(0.0, 0.06, 0.075), 0.0, 2.6},
      {"lift off, fingers open", Vec3(0.0, 0.06, 0.075), Vec3(0.0, 0.03, 0.15), 2.6, 0.0},
  };
  const size_t n = model.bodies.size();
  const auto rest = model.restPoses(Pose{});
  // Raise the whole script for models that would start inside the table (a long tool): the God
  // objects must start collision-free (re-acquisition inside objects is the tracker stage's).
  Vec3 raise = Vec3::Zero();
  {
    std::vector<Contact> tmp;
    Pose X0;
    X0.p = phases[0].from;
    for (size_t b = 0; b < n; ++b) {
      const Pose Xb = X0 * rest[b];
      const double lowest = model.bodies[b].shape.type == ShapeType::Box
                                ? Xb.p.z() - (Xb.q.toRotationMatrix().cwiseAbs() * model.bodies[b].shape.half_extents).z()
                                : std::min((Xb * Vec3(0, 0, -model.bodies[b].shape.half_length)).z(),
                                           (Xb * Vec3(0, 0, model.bodies[b].shape.half_length)).z()) - model.bodies[b].shape.radius;
      raise.z() = std::max(raise.z(), 0.01 - lowest);
    }
  }
  Pose X_WM;
  X_WM.p = phases[0].from + raise;
  stepper->reset(model.restPoses(X_WM));
  std::vector<Pose> targets(n);
  std::vector<Contact> contacts;
  contacts.reserve(64 * n);
  stepper->reserve(static_cast<int>(4 * n));

  std::printf("godhand-demo: model %s (%zu bodies, %zu joints), solver %s, dt %.3g s, %d steps per phase\n",
              model.name.c_str(), n, model.joints.size(), params.solver == SolverKind::Exact ? "exact" : "pgs", params.dt, frames);
  std::printf("scene: table plane z = 0, static ball r = %.0f mm at (%.3f, %.3f, %.3f); margin %.2g mm\n\n",
              scene.ball.radius * 1e3, scene.ball.centre.x(), scene.ball.centre.y(), scene.ball.centre.z(), params.rows.margin * 1e3);
  std::printf("%-28s %9s %9s %8s %12s %12s %11s %12s %10s\n", "phase", "median_us", "p99_us", "contacts", "penetr_mm",
              "target_in_mm", "gap_m", "free_err_m", "kkt_max");
  double pen_all = 0, gap_all = 0, lim_all = 0, kkt_all = 0;
  std::vector<double> times_all, st_coupling, st_assembly, st_solve, st_integrate, st_project;
  for (const Phase& ph : phases) {
    std::vector<double> times;
    double pen = 0, gap = 0, kkt = 0, free_err = 0, target_depth = 0;
    int cmax = 0;
    for (int f = 0; f < frames; ++f) {
      const double s = (f + 1.0) / frames;
      Pose X;
      X.p = ph.from + s * (ph.to - ph.from) + raise;
      const double curl = ph.curl_from + s * (ph.curl_to - ph.curl_from);
      // Tracked hand: the model's rest pose with every finger joint curled by `curl`, built
      // forward along each chain (this is a target: it may exceed limits and enter objects).
      std::vector<Pose> local = rest;
      for (const Joint& j : model.joints) {
        const Pose& P = local[static_cast<size_t>(j.parent)];
        const Pose X_WJ = P * j.X_PJ * Pose{Vec3::Zero(), Quat(Eigen::AngleAxisd(j.type == JointType::Fixed ? 0.0 : curl * 0.5, Vec3::UnitX()))};
        local[static_cast<size_t>(j.child)] = X_WJ * j.X_CJ.inverse();
      }
      for (size_t b = 0; b < n; ++b) {
        targets[b] = X * local[b];
        double dmin = 1e9;
        std::vector<Contact> tmp;
        dmin = scene.contacts(static_cast<int>(b), model.bodies[b], targets[b], tmp);
        target_depth = std::max(target_depth, -dmin);
      }
      contacts.clear();
      for (size_t b = 0; b < n; ++b) scene.contacts(static_cast<int>(b), model.bodies[b], stepper->poses()[b], contacts);
      StepInput in{targets.data(), nullptr, contacts.data(), static_cast<int>(contacts.size())};
      const auto t0 = std::chrono::steady_clock::now();
      const StepReport& r = stepper->step(in);
      const auto t1 = std::chrono::steady_clock::now();
      times.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      cmax = std::max(cmax, r.contact_rows);
      st_coupling.push_back(r.times.coupling_us);
      st_assembly.push_back(r.times.assembly_us);
      st_solve.push_back(r.times.solve_us);
      st_integrate.push_back(r.times.integrate_us);
      st_project.push_back(r.times.project_us);
      kkt = std::max(kkt, r.solve.kkt_residual);
      gap = std::max(gap, r.joint_errors.gap);
      lim_all = std::max(lim_all, r.joint_errors.limit);
      std::vector<Contact> after;
      bool any_contact = false;
      for (size_t b = 0; b < n; ++b) {
        const double d = scene.contacts(static_cast<int>(b), model.bodies[b], stepper->poses()[b], after);
        pen = std::max(pen, -d);
        any_contact = any_contact || d < 2 * params.rows.margin;
      }
      if (!any_contact && r.limit_rows == 0)
        for (size_t b = 0; b < n; ++b) free_err = std::max(free_err, (targets[b].p - stepper->poses()[b].p).norm());
    }
    std::printf("%-28s %9.1f %9.1f %8d %12.4f %12.1f %11.1e %12.1e %10.1e\n", ph.name, percentile(times, 0.5),
                percentile(times, 0.99), cmax, std::max(0.0, pen) * 1e3, std::max(0.0, target_depth) * 1e3, gap, free_err, kkt);
    pen_all = std::max(pen_all, pen);
    gap_all = std::max(gap_all, gap);
    kkt_all = std::max(kkt_all, kkt);
    times_all.insert(times_all.end(), times.begin(), times.end());
  }
  const StepCounters& c = stepper->counters();
  std::printf("\nsummary: %llu steps, step median %.1f us (%.0f Hz), p99 %.1f us; penetration max %.4f mm (margin %.2g mm);\n"
              "         joint gap max %.1e m; limit violation max %.1e rad; KKT max %.1e; solver failures %llu, inexact %llu\n",
              static_cast<unsigned long long>(c.steps), percentile(times_all, 0.5), 1e6 / percentile(times_all, 0.5),
              percentile(times_all, 0.99), std::max(0.0, pen_all) * 1e3, params.rows.margin * 1e3, gap_all, lim_all, kkt_all,
              static_cast<unsigned long long>(c.solver_failures), static_cast<unsigned long long>(c.inexact_solves));
  std::printf("stages (median us): coupling %.1f, assembly %.1f, solve %.1f, integrate %.1f, project %.1f;"
              " contact generation is the caller's (analytic here)\n",
              percentile(st_coupling, 0.5), percentile(st_assembly, 0.5), percentile(st_solve, 0.5),
              percentile(st_integrate, 0.5), percentile(st_project, 0.5));
  return 0;
}
