#include "common/delivery.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace godhand {

void Delivery::seen(std::uint64_t run, std::uint64_t frame) {
  auto it = highest_.find(run);
  if (it == highest_.end()) {
    runs_.push_back(run);
    highest_[run] = frame;
  } else {
    it->second = std::max(it->second, frame);
  }
}

void Delivery::add(size_t hand, std::uint64_t run, std::uint64_t frame, bool stale) {
  if (hand >= fresh_.size() || frame == 0) return;
  seen(run, frame);
  (stale ? stale_ : fresh_)[hand].insert({run, frame});
}

void Delivery::published(std::uint64_t run, std::uint64_t frame) {
  if (frame > 0) seen(run, frame);
}

void Delivery::unobserved(std::uint64_t run, std::uint64_t first, std::uint64_t last) {
  if (first == 0 || last < first || blind_.size() >= 4096) return;  // (bounded: a day's pauses)
  blind_.push_back({{run, first}, last});
}

std::uint64_t Delivery::highest(std::uint64_t run) const {
  auto it = highest_.find(run);
  return it == highest_.end() ? 0 : it->second;
}

std::map<std::uint64_t, std::uint64_t> Delivery::expected(std::int64_t replay_frames, bool last_run_cut_short) const {
  std::map<std::uint64_t, std::uint64_t> e;
  for (size_t i = 0; i < runs_.size(); ++i) {
    const bool to_the_end = i + 1 == runs_.size() && replay_frames >= 0 && !last_run_cut_short;
    e[runs_[i]] = to_the_end ? static_cast<std::uint64_t>(replay_frames) : highest(runs_[i]);
  }
  if (runs_.empty() && replay_frames > 0 && !last_run_cut_short) e[0] = static_cast<std::uint64_t>(replay_frames);
  return e;
}

DeliveryCounts Delivery::counts(size_t hand, const std::map<std::uint64_t, std::uint64_t>& expected) const {
  DeliveryCounts c;
  if (hand >= fresh_.size()) return c;
  for (const auto& [run, n] : expected) {
    c.expected += n;
    for (auto it = fresh_[hand].lower_bound({run, 1}); it != fresh_[hand].end() && it->first == run && it->second <= n; ++it) ++c.fresh;
    for (auto it = stale_[hand].lower_bound({run, 1}); it != stale_[hand].end() && it->first == run && it->second <= n; ++it)
      if (!fresh_[hand].count(*it)) ++c.stale;
  }
  // Frames of a blind window (merged: windows may overlap) with no state of this hand.
  std::set<Key> blind;
  for (const auto& [from, last] : blind_) {
    auto e = expected.find(from.first);
    if (e == expected.end()) continue;
    for (std::uint64_t k = from.second; k <= last && k <= e->second; ++k) {
      const Key key{from.first, k};
      if (!fresh_[hand].count(key) && !stale_[hand].count(key)) blind.insert(key);
    }
  }
  c.unobserved = blind.size();
  c.lost = c.expected - c.fresh - c.stale - c.unobserved;
  return c;
}

RunVerdict evaluateRun(const RunFigures& f) {
  RunVerdict v;
  auto fail = [&](const std::string& why) {
    v.ok = false;
    v.reasons.push_back(why);
  };
  char b[256];
  if (!f.failure.empty()) fail("the run failed: " + f.failure.substr(0, f.failure.find('\n')));
  if (f.states <= 0) fail("no hand state received");
  if (!(f.penetration_max <= f.margin)) {
    std::snprintf(b, sizeof b, "penetration %.4f mm > margin %.4f mm", f.penetration_max * 1e3, f.margin * 1e3);
    fail(b);
  }
  if (!(f.joint_gap_max <= 1e-6)) {
    std::snprintf(b, sizeof b, "joint gap %.2e m > 1e-6 m", f.joint_gap_max);
    fail(b);
  }
  if (f.solver_failures > 0) fail(std::to_string(f.solver_failures) + " solver failure(s)");
  for (const auto& [cluster, c] : f.delivery) {
    const double allowed = f.lockstep ? 0.0 : std::floor(f.loss_budget * static_cast<double>(c.expected));
    if (c.expected == 0) fail(cluster + ": no frame expected (nothing was replayed)");
    // Frames this launcher did not watch cannot be vouched for: with the lost ones, within the one
    // budget, named apart (they used to be counted lost).
    if (static_cast<double>(c.lost + c.unobserved) > allowed) {
      if (c.unobserved > 0)
        std::snprintf(b, sizeof b, "%s: %llu of %llu frames lost and %llu not observed (this launcher did not watch; budget %.0f)",
                      cluster.c_str(), static_cast<unsigned long long>(c.lost), static_cast<unsigned long long>(c.expected),
                      static_cast<unsigned long long>(c.unobserved), allowed);
      else
        std::snprintf(b, sizeof b, "%s: %llu of %llu frames lost (budget %.0f)", cluster.c_str(),
                      static_cast<unsigned long long>(c.lost), static_cast<unsigned long long>(c.expected), allowed);
      fail(b);
    }
    if (f.lockstep && c.stale > 0) fail(cluster + ": " + std::to_string(c.stale) + " frames delivered stale in lock-step");
  }
  for (const std::string& s : f.dead_at_end) fail(s + " was not running at the end of the run");
  if (!f.late_joiner_ok) fail("the late joiner did not get every cluster's HandState and the SceneDescription");
  for (const std::string& d : f.drills_not_done) fail("drill " + d + " never fired");
  if (!f.foreign.empty())
    fail("another lab shares the DDS domain (" + f.foreign.front() + (f.foreign.size() > 1 ? ", ..." : "") +
         "): its samples mix with this run's");
  return v;
}

}  // namespace godhand
