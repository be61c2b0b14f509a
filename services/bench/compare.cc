#include "compare.h"

#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "math/stats.h"
#include "pipeline/run_metrics_json.h"
#include "step/constraints.h"

namespace godhand::bench {

namespace {

const Scene& staticScene(const Scene& scene, const PipelineParams& params) {
  if (params.simulate)
    for (const SceneObject& o : scene.objects)
      if (o.mass > 0.0)
        throw std::invalid_argument("--compare mujoco: object '" + o.id +
                                    "' is dynamic and MuJoCo would have to simulate it too (not modelled): use --mesh "
                                    "scenes, static objects or --no-physics");
  return scene;
}

std::string line(const char* what, double a, double b, const char* unit, double scale = 1.0) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "    %-44s %12.2f %12.2f %s\n", what, a * scale, b * scale, unit);
  return buf;
}

std::string countLine(const char* what, unsigned long long a, unsigned long long of_a, unsigned long long b,
                      unsigned long long of_b) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "    %-44s %5llu of %-4llu %5llu of %-4llu\n", what, a, of_a, b, of_b);
  return buf;
}

}  // namespace

Comparison::Comparison(const Scene& scene, std::vector<const HandModel*> models, std::vector<std::string> names,
                       const PipelineParams& params, double frame_dt, const mujoco::Params& mj)
    : params_(mj),
      hands_(staticScene(scene, params), models, frame_dt, mj),
      metrics_(scene, models, std::move(names), params),
      models_(std::move(models)) {}

void Comparison::step(const std::vector<HandInput>& inputs, const CollisionWorld& world) {
  const auto t0 = std::chrono::steady_clock::now();
  hands_.step(inputs);
  step_us_.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  for (int h = 0; h < hands_.handCount(); ++h) {
    HandSample s;
    s.started = hands_.started(h);
    s.tracked = inputs[static_cast<size_t>(h)].tracked;
    s.X = s.started ? hands_.poses(h).data() : nullptr;
    s.targets = inputs[static_cast<size_t>(h)].targets;
    s.has_target = inputs[static_cast<size_t>(h)].has_target;
    s.loaded = hands_.loaded(h);
    s.substeps = hands_.stepsPerFrame();
    // The hand's joints are not modelled in MuJoCo (the welds to the targets hold it together):
    // how far apart its bodies drift is the same joint-gap figure as godhand's.
    s.joint_gap = s.started ? jointErrors(*models_[static_cast<size_t>(h)], s.X).gap : 0.0;
    metrics_.add(h, s, inputs[static_cast<size_t>(h)], world);
  }
}

std::string Comparison::describeModel() const {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "%s: every body a free body welded to a mocap target (weld time constant %.3g s), no joints between "
                "them, contacts time constant %.3g s, timestep %.3g s (%d steps per frame), meshes collided as their "
                "convex hulls, no gravity on the hands",
                mujoco::version().c_str(), params_.weld_timeconst, params_.contact_timeconst, params_.timestep,
                hands_.stepsPerFrame());
  return buf;
}

std::string Comparison::table(const RunSummary& g, const std::vector<double>& g_us) const {
  const RunSummary m = summary();
  const double g_med = percentile(g_us, 0.5), m_med = percentile(step_us_, 0.5);
  std::string t = "  compare: the same frames and targets driven by " + describeModel() +
                  "; stepped after godhand in each frame, measured by the same figures\n";
  char head[160];
  std::snprintf(head, sizeof head, "    %-44s %12s %12s\n", "", "godhand", "MuJoCo");
  t += head;
  t += line("frame time median (us)", g_med, m_med, "us");
  t += line("frame time p99 (us)", percentile(g_us, 0.99), percentile(step_us_, 0.99), "us");
  t += line("penetration max (reference meshes)", g.all.penetration_max_m, m.all.penetration_max_m, "mm", 1e3);
  t += line("excess lag median", g.all.excess_lag_m.median, m.all.excess_lag_m.median, "mm", 1e3);
  t += line("excess lag p95", g.all.excess_lag_m.p95, m.all.excess_lag_m.p95, "mm", 1e3);
  t += line("excess lag max", g.all.excess_lag_m.max, m.all.excess_lag_m.max, "mm", 1e3);
  t += countLine("frames with excess lag > 5 mm", g.all.lag_above_5mm, g.all.excess_lag_m.count, m.all.lag_above_5mm,
                 m.all.excess_lag_m.count);
  // Where the twin is inside an object the excess lag is an upper bound (run_metrics.h); the same
  // twin for both, so the same frames.
  if (g.all.excess_lag_twin_outside_m.count > 0 || m.all.excess_lag_twin_outside_m.count > 0) {
    t += line("excess lag p95, twin outside every object", g.all.excess_lag_twin_outside_m.p95,
              m.all.excess_lag_twin_outside_m.p95, "mm", 1e3);
    t += countLine("  those frames with excess lag > 5 mm", g.all.lag_above_5mm_twin_outside,
                   g.all.excess_lag_twin_outside_m.count, m.all.lag_above_5mm_twin_outside,
                   m.all.excess_lag_twin_outside_m.count);
  } else {
    char buf[200];
    std::snprintf(buf, sizeof buf, "    %-44s %12s %12s\n", "excess lag, twin outside every object", "no frame", "no frame");
    t += buf;
  }
  t += countLine("frozen windows", g.all.frozen_windows, g.all.moving_windows, m.all.frozen_windows, m.all.moving_windows);
  {
    // Over the frames in which no contact of the hand is active: each engine has its own count.
    char buf[200];
    auto cell = [](const Spread& s) {
      char c[40];
      if (s.count == 0) std::snprintf(c, sizeof c, "%12s", "no frame");
      else std::snprintf(c, sizeof c, "%7.2f (%3zu)", s.median * 1e3, s.count);
      return std::string(c);
    };
    std::snprintf(buf, sizeof buf, "    %-44s %s %s mm (frames)\n", "free tracking error median (no contact)",
                  cell(g.all.free_tracking_error_m).c_str(), cell(m.all.free_tracking_error_m).c_str());
    t += buf;
  }
  t += line("joint gap max", g.all.joint_gap_max_m, m.all.joint_gap_max_m, "mm", 1e3);
  char ratio[200];
  std::snprintf(ratio, sizeof ratio, "    frames/s: godhand %.0f, MuJoCo %.0f (godhand / MuJoCo = %.2f)\n",
                g_med > 0 ? 1e6 / g_med : 0.0, m_med > 0 ? 1e6 / m_med : 0.0, m_med > 0 && g_med > 0 ? m_med / g_med : 0.0);
  t += ratio;
  char mj[200];
  std::snprintf(mj, sizeof mj, "    MuJoCo: %ld frames reset after a bad number, %ld hand-frames of non-finite targets ignored, "
                "%ld frames with its contact list full\n", hands_.resets(), hands_.rejectedTargets(), hands_.overflows());
  t += mj;
  return t;
}

nlohmann::json Comparison::json(const std::vector<double>& g_us) const {
  const RunSummary m = summary();
  const double g_med = percentile(g_us, 0.5), m_med = percentile(step_us_, 0.5);
  nlohmann::json j;
  j["engine"] = mujoco::version();
  j["model"] = describeModel();
  j["timestep_s"] = params_.timestep;
  j["steps_per_frame"] = hands_.stepsPerFrame();
  j["step_us"] = {{"median", m_med}, {"p99", percentile(step_us_, 0.99)}, {"max", percentile(step_us_, 1.0)}};
  j["hz_median"] = m_med > 0 ? 1e6 / m_med : 0.0;
  j["hz_ratio_godhand_over_engine"] = m_med > 0 && g_med > 0 ? m_med / g_med : 0.0;
  j["penetration_max_m"] = m.all.penetration_max_m;
  j["joint_gap_max_m"] = m.all.joint_gap_max_m;
  j["excess_lag_m"] = toJson(m.all.excess_lag_m);
  j["excess_lag_above_5mm"] = m.all.lag_above_5mm;
  j["excess_lag_twin_outside_m"] = toJson(m.all.excess_lag_twin_outside_m);
  j["excess_lag_twin_outside_above_5mm"] = m.all.lag_above_5mm_twin_outside;
  j["frozen_windows"] = m.all.frozen_windows;
  j["moving_windows"] = m.all.moving_windows;
  j["free_tracking_error_m"] = toJson(m.all.free_tracking_error_m);
  j["resets"] = hands_.resets();
  j["rejected_targets"] = hands_.rejectedTargets();
  j["contact_overflows"] = hands_.overflows();
  j["plausibility"] = toJson(m);
  return j;
}

}  // namespace godhand::bench
