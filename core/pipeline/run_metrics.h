// The quality figures of a run (METHOD.md §5), defined once for every report: godhand-bench and
// godhand-launch feed the same RunMetrics with what a frame produced and print/write its summary.
//
// Plausibility (a God hand that is penetration-free because it froze is a failure):
//   free twin      the same hand model driven by the same targets against an empty scene (a
//                  HandSolver of its own, stepped here): the model's best rendition of the
//                  targets. What the model cannot represent (limits, twist, palm offset) is the
//                  twin's distance to the targets: `model_error`, reported apart.
//   excess lag     per frame and hand: E = max_b |p_god,b − p_twin,b| − max_b depth_b(twin), the
//                  depth measured exactly against the scene's reference meshes. An ideal God hand
//                  scores ≤ ~0 (where the twin is outside it coincides with it, where the twin
//                  sinks d it sits about d away). Median / p95 / max, frames above 5 mm.
//                  The same over the frames whose twin is outside every object (its deepest body
//                  less than kTwinInside in) is reported beside it: nothing is subtracted there.
//                  Where the twin is inside an object E assumes the God hand could reach the
//                  surface point nearest the twin: an upper bound of the method's own lag, far
//                  above it where targets go on through a thick object (the God hand stays at its
//                  near side, as a God object must; seen: confidence2's right hand through the
//                  default scene's fandisk, E median 58 mm, its twin inside in every frame).
//   frozen         windows of 5 frames in which the twin moves > 2 mm but the God hand < 0.05 mm.
//   jitter         body-frames in which a body that moved more than 0.1 mm since the frame before
//                  turns back by more than 120° against its motion of that frame (also > 0.1 mm):
//                  a hand shaking at the frame rate (seen: a palm pressed onto a curved surface,
//                  rocking about one contact and back every frame, its fingertips 1-3 mm apart
//                  from frame to frame). Counted for the God hand and for its free twin (what
//                  the tracking itself does); the God hand's excess is the method's.
//   stuck frames   frames in which the God hand moves < 0.05 mm although it is > 1 mm farther
//                  from its targets than its free twin is (the model's best; without a twin:
//                  > 1 mm from them) and the straight motion of every driven body to its target
//                  is free (swept against the scene as it is).
// Also per hand: penetration (max), joint gap (max), free tracking error (God to target while
// no contact carries force), frames clipped, frames whose TOC < 1e-3, solve -> sweep rounds.
// Accuracy of the God side (issue 14, what a coarser God mesh costs):
//   contact gap    per frame and body touching the God side (within 0.5 mm of the surface the
//                  method keeps it off: the God mesh, the body grown by the object's AUTO skin),
//                  its exact distance to the full-resolution surface: ~the contact margin with
//                  full meshes, up to about twice the AUTO distance with a coarser God side; a
//                  negative gap is a penetration. Median / p95 / max over those body-frames.
//
// No I/O: the caller formats the Summary (services/bench, services/launch).
#pragma once

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "math/stats.h"
#include "model/hand_model.h"
#include "pipeline/collision_world.h"
#include "pipeline/stages.h"
#include "scene/scene.h"

namespace godhand {

/// What one frame produced for one hand, as any report sees it.
struct HandSample {
  bool started = false;      ///< the God hand exists
  bool tracked = false;      ///< targets were given this frame
  bool held = false;         ///< no new result this frame (live: the last pose again)
  const Pose* X = nullptr;   ///< God-object poses (model body order), nullptr if none
  const Pose* targets = nullptr;              ///< when tracked
  const unsigned char* has_target = nullptr;  ///< per body, nullptr = all
  bool loaded = false;       ///< some contact carried force
  bool clipped = false;
  double toc = 1.0;
  int substeps = 0;
  double joint_gap = 0.0;    ///< m
};

/// Median, p95, max of a sample (0 for none) and its size.
struct Spread {
  double median = 0, p95 = 0, max = 0;
  std::size_t count = 0;
  /// The median and p95 are estimates from a uniform sample (a run of more values than
  /// Sample::kDefaultCapacity, math/stats.h); count and max are exact.
  bool sampled = false;
};

/// The spread of one or more samples together (several hands' figure for "all"): count and max
/// exact; median and p95 exact when none is sampled, else each kept value weighted by the count
/// it stands for (a sampled hand's values are not outvoted by an exact hand's).
Spread spreadOf(const std::vector<const Sample*>& samples);

struct HandSummary {
  std::string name;
  std::uint64_t frames = 0, tracked = 0, started = 0, held = 0;
  std::uint64_t never_started = 0;     ///< tracked frames before (or without) a start
  double penetration_max_m = 0, joint_gap_max_m = 0;
  Spread free_tracking_error_m;        ///< God to targets, frames without load
  Spread model_error_m;                ///< twin to targets: what the model cannot represent
  Spread excess_lag_m;                 ///< see above
  /// The excess lag of the frames whose twin is outside every object, and of those the frames
  /// above 5 mm (see above).
  Spread excess_lag_twin_outside_m;
  std::uint64_t lag_above_5mm_twin_outside = 0;
  /// The frames whose twin is inside an object: every excess-lag frame that is not outside.
  std::uint64_t twinInsideFrames() const { return excess_lag_m.count - excess_lag_twin_outside_m.count; }
  Spread contact_gap_m;                ///< see above (body-frames touching the God side)
  std::uint64_t lag_above_5mm = 0;
  std::uint64_t moving_windows = 0, frozen_windows = 0;
  std::uint64_t stuck_frames = 0;
  /// Body-frames checked for jitter (a body with a motion in this frame and the one before),
  /// those that turned back (see above), and the same for the free twin.
  std::uint64_t jitter_checked = 0, jitter_body_frames = 0, twin_jitter_checked = 0, twin_jitter_body_frames = 0;
  std::uint64_t clipped_frames = 0, toc_below_1e3 = 0;
  std::uint64_t substeps = 0, substeps_max = 0;
};

struct RunSummary {
  std::vector<HandSummary> hands;
  HandSummary all;                     ///< every hand's frames together
  /// Why the run is not a plausible run of every hand (empty if it is): no hand ever tracked, a
  /// hand that never started, or that was held or unstarted in most of its tracked frames.
  std::string failure;
};

class RunMetrics {
 public:
  /// models/names: one per hand, in the report's order. twin = false: no free twin (no excess
  /// lag, frozen windows or model error; used where the caller has no targets).
  RunMetrics(const Scene& scene, std::vector<const HandModel*> models, std::vector<std::string> names,
             const PipelineParams& params, bool twin = true);
  ~RunMetrics();

  /// One frame of hand h. `input` is what the God hand was driven with (the twin gets the
  /// same); `world` is the scene as this frame's result was resolved against (penetration,
  /// twin depth, stuck sweeps).
  void add(int hand, const HandSample& sample, const HandInput& input, const CollisionWorld& world);

  RunSummary summary() const;
  int handCount() const { return static_cast<int>(hands_.size()); }

 private:
  struct Hand;
  const Scene empty_{};  // the twins' scene: declared first, destroyed last
  PipelineParams params_;
  std::vector<std::unique_ptr<Hand>> hands_;
};

/// Each scene object's share of the frame time (issue 14, "model only what a scene requires"):
/// the God side's queries of it (contacts, sweeps, distances: CollisionWorld::costs summed over
/// the hands' solvers and the resolver, Pipeline::godCosts) against the frames' total time, and
/// for a dynamic object the frames after which Bullet had it awake (asleep: not integrated).
struct ObjectShare {
  std::string id;
  double god_us = 0.0;             ///< over the run
  std::uint64_t god_queries = 0;   ///< queries that reached it
  double god_share = 0.0;          ///< god_us / the frames' total time (0..1)
  bool dynamic = false;
  std::uint64_t awake_frames = 0;  ///< dynamic: frames that ended with it awake in Bullet
};
struct ObjectShares {
  std::vector<ObjectShare> objects;  ///< scene order
  std::uint64_t frames = 0;
  double frames_us = 0.0;            ///< the frames' total time
  double god_us = 0.0;               ///< every object's god_us
  bool simulated = true;             ///< Bullet ran (awake_frames given)
};
/// costs and awake_frames per scene object (awake_frames empty: no physics).
ObjectShares objectShares(const Scene& scene, const std::vector<ObjectCost>& costs,
                          const std::vector<std::uint64_t>& awake_frames, std::uint64_t frames, double frames_us);
/// One line for a summary (the same words in every report).
std::string describe(const ObjectShares& s);

/// The thresholds of the figures above (one definition; reports quote them).
struct MetricThresholds {
  static constexpr double kLagAbove = 5e-3;      ///< m
  static constexpr double kTwinInside = 1e-3;    ///< m: a twin sunk deeper than this is inside an object
  static constexpr double kTwinMoves = 2e-3;     ///< m over the window
  static constexpr double kGodStill = 5e-5;      ///< m
  static constexpr int kWindow = 5;              ///< frames
  static constexpr double kAwayFromTarget = 1e-3;  ///< m
  static constexpr double kTinyToc = 1e-3;
  static constexpr double kTouching = 5e-4;     ///< m: a body this near the God side touches it
  static constexpr double kGapRange = 0.1;      ///< m: contact gaps beyond it are reported as it
  static constexpr double kJitterMove = 1e-4;   ///< m: a body's motion from one frame to the next
  static constexpr double kJitterCos = -0.5;    ///< turning back by more than 120°
};

}  // namespace godhand

namespace godhand {

/// The plausibility verdict every --check uses (godhand-bench, godhand-launch in lock-step):
/// every hand started and was not held in most of its frames, no stuck frame, frozen windows at
/// most 5 % of the moving windows. `why` gets the first reason it fails.
inline bool plausible(const RunSummary& s, std::string* why) {
  if (!s.failure.empty()) {
    *why = s.failure;
    return false;
  }
  if (s.all.stuck_frames > 0) {
    *why = std::to_string(s.all.stuck_frames) + " stuck frames (not moving although the way to the targets is free)";
    return false;
  }
  if (s.all.frozen_windows * 20 > std::max<std::uint64_t>(s.all.moving_windows, 1)) {
    *why = std::to_string(s.all.frozen_windows) + " of " + std::to_string(s.all.moving_windows) +
           " moving windows frozen (more than 5 %)";
    return false;
  }
  return true;
}

/// One line per hand for a summary (the same words in every report). A figure over no frames is
/// said to be so, never printed as zeros (which read as a perfect result).
inline std::string describe(const HandSummary& h) {
  auto mm = [](double m) {
    char b[32];
    std::snprintf(b, sizeof b, "%.2f", m * 1e3);
    return std::string(b);
  };
  auto u = [](std::uint64_t n) { return std::to_string(n); };
  std::string o = h.name + " hand: excess lag (distance to the free twin beyond what the scene forces) ";
  o += h.excess_lag_m.count == 0
           ? std::string("not measured (no tracked frame)")
           : "median " + mm(h.excess_lag_m.median) + " p95 " + mm(h.excess_lag_m.p95) + " max " + mm(h.excess_lag_m.max) +
                 " mm, " + u(h.lag_above_5mm) + " of " + std::to_string(h.excess_lag_m.count) + " frames above 5 mm (" +
                 u(h.twinInsideFrames()) + " frames with the twin inside an object, where the figure is an upper bound" +
                 (h.excess_lag_twin_outside_m.count == 0
                      ? std::string("; the twin was inside in every one)")
                      : "; in the other " + std::to_string(h.excess_lag_twin_outside_m.count) + ", the twin outside: median " +
                            mm(h.excess_lag_twin_outside_m.median) + " p95 " + mm(h.excess_lag_twin_outside_m.p95) + " max " +
                            mm(h.excess_lag_twin_outside_m.max) + " mm, " + u(h.lag_above_5mm_twin_outside) + " above 5 mm)");
  o += "; frozen " + u(h.frozen_windows) + " of " + u(h.moving_windows) + " moving windows; stuck " + u(h.stuck_frames) + " frames";
  o += "; model error (twin to targets: what the hand model cannot follow) " +
       (h.model_error_m.count == 0 ? std::string("not measured")
                                   : "median " + mm(h.model_error_m.median) + " max " + mm(h.model_error_m.max) + " mm");
  o += "; free tracking error (no contact loaded) " +
       (h.free_tracking_error_m.count == 0
            ? std::string("not measured (a contact was loaded in every tracked frame)")
            : "median " + mm(h.free_tracking_error_m.median) + " max " + mm(h.free_tracking_error_m.max) + " mm");
  char gap[160];
  std::snprintf(gap, sizeof gap, "median %.3f p95 %.3f max %.3f mm (%zu body-frames)", h.contact_gap_m.median * 1e3,
                h.contact_gap_m.p95 * 1e3, h.contact_gap_m.max * 1e3, h.contact_gap_m.count);
  o += "; gap to the full surface while touching " + (h.contact_gap_m.count == 0 ? std::string("none (never touching)") : std::string(gap));
  o += "; jitter (a body's motion turning back from one frame to the next) " + u(h.jitter_body_frames) + " of " +
       u(h.jitter_checked) + " body-frames, free twin " + u(h.twin_jitter_body_frames);
  o += "; clipped frames " + u(h.clipped_frames) + " (TOC < 1e-3 in " + u(h.toc_below_1e3) + "), solve -> sweep rounds " + u(h.substeps);
  for (const Spread* x : {&h.excess_lag_m, &h.excess_lag_twin_outside_m, &h.model_error_m, &h.free_tracking_error_m, &h.contact_gap_m})
    if (x->sampled) {
      o += "; medians and p95 estimated from a uniform sample of " + std::to_string(Sample::kDefaultCapacity) +
           " values per figure (a longer run; counts and maxima exact)";
      break;
    }
  return o;
}

}  // namespace godhand
