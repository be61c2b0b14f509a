// The run metrics (run_metrics.h) as JSON, the same fields in every report (godhand-bench and
// godhand-launch). Header-only: nlohmann-json is header-only too.
#pragma once

#include <nlohmann/json.hpp>

#include "pipeline/run_metrics.h"

namespace godhand {

inline nlohmann::json toJson(const Spread& s) {
  // "estimated": the median and p95 come from a uniform sample of a longer run (count and max exact).
  return nlohmann::json{{"median", s.median}, {"p95", s.p95}, {"max", s.max}, {"count", s.count}, {"estimated", s.sampled}};
}

inline nlohmann::json toJson(const HandSummary& h) {
  return nlohmann::json{{"frames", h.frames},
                        {"tracked", h.tracked},
                        {"started", h.started},
                        {"not_started", h.never_started},
                        {"held", h.held},
                        {"penetration_max_m", h.penetration_max_m},
                        {"joint_gap_max_m", h.joint_gap_max_m},
                        {"excess_lag_m", toJson(h.excess_lag_m)},
                        {"excess_lag_above_5mm", h.lag_above_5mm},
                        {"excess_lag_twin_outside_m", toJson(h.excess_lag_twin_outside_m)},
                        {"excess_lag_twin_outside_above_5mm", h.lag_above_5mm_twin_outside},
                        {"twin_inside_frames", h.twinInsideFrames()},
                        {"moving_windows", h.moving_windows},
                        {"frozen_windows", h.frozen_windows},
                        {"stuck_frames", h.stuck_frames},
                        {"jitter_checked", h.jitter_checked},
                        {"jitter_body_frames", h.jitter_body_frames},
                        {"twin_jitter_checked", h.twin_jitter_checked},
                        {"twin_jitter_body_frames", h.twin_jitter_body_frames},
                        {"model_error_m", toJson(h.model_error_m)},
                        {"free_tracking_error_m", toJson(h.free_tracking_error_m)},
                        {"contact_gap_m", toJson(h.contact_gap_m)},
                        {"clipped_frames", h.clipped_frames},
                        {"toc_below_1e-3", h.toc_below_1e3},
                        {"substeps", h.substeps},
                        {"substeps_max", h.substeps_max}};
}

/// `plausibility`: {all: ..., per_hand: {NAME: ...}, failure: "" or why}.
inline nlohmann::json toJson(const RunSummary& s) {
  nlohmann::json j;
  j["all"] = toJson(s.all);
  j["per_hand"] = nlohmann::json::object();
  for (const HandSummary& h : s.hands) j["per_hand"][h.name] = toJson(h);
  j["failure"] = s.failure;
  return j;
}

/// Per object: {id, god_us, god_us_per_frame, god_queries, god_share_pct, dynamic, awake_frames}.
inline nlohmann::json toJson(const ObjectShare& o, std::uint64_t frames) {
  return nlohmann::json{{"id", o.id},
                        {"god_us", o.god_us},
                        {"god_us_per_frame", frames ? o.god_us / static_cast<double>(frames) : 0.0},
                        {"god_queries", o.god_queries},
                        {"god_share_pct", 100.0 * o.god_share},
                        {"dynamic", o.dynamic},
                        {"awake_frames", o.awake_frames}};
}

}  // namespace godhand
