// The launch report's end-to-end latency: the time from a tracker sample (taken by the ingest)
// to its HandState received by the launcher, over the run and over each second of the live line.
//
// Honesty rule kept here: a stale state's age is not a latency. A state flagged stale by the
// resolver, or older than the stale limit when it arrived (the caller's verdict, as Delivery's),
// is a hand held against an old scene or a late one, not a measure of how fast the lab delivers:
// its age goes to a figure of its own (staleAges(), reported as such), never into the latency
// median, p99 or max. (Before, one 2.3 s stale state was the p99 of its second.) The stale states
// themselves are counted by the caller (stale_states). An age that was not measured (<= 0: no
// source time, or a state aged by the launcher's own pause) enters neither figure.
#pragma once

#include <vector>

#include "math/stats.h"

namespace godhand {

class LatencyFigures {
 public:
  /// A HandState received age_us after its tracker sample; `stale`: flagged by the resolver or
  /// older than the stale limit when it arrived. age_us <= 0: not measured.
  void add(double age_us, bool stale);
  /// The latency figures: fresh states only.
  const Sample& latency() const { return fresh_; }
  /// The ages of the stale states (apart: not a latency).
  const Sample& staleAges() const { return stale_; }
  /// The fresh states' latencies since the last clearWindow() (the per-second line).
  const std::vector<double>& window() const { return window_; }
  void clearWindow() { window_.clear(); }

 private:
  Sample fresh_, stale_;
  std::vector<double> window_;
};

}  // namespace godhand
