#include "common/source_counts.h"

#include <algorithm>
#include <cstdio>

namespace godhand {

std::uint64_t SourceCounts::rejectedTotal() const {
  std::uint64_t n = 0;
  for (const auto& r : rejected) n += r.second;
  return n;
}

std::uint64_t SourceCounts::notPlayedTotal() const {
  std::uint64_t n = 0;
  for (const auto& r : not_played) n += r.second;
  return n;
}

std::map<std::string, std::uint64_t> reasonMap(const std::vector<std::pair<std::string, std::uint64_t>>& by_reason) {
  std::map<std::string, std::uint64_t> m;
  for (const auto& [reason, n] : by_reason)
    if (n > 0) m[reason] += n;
  return m;
}

std::vector<std::pair<std::string, std::uint64_t>> boundReasons(const std::map<std::string, std::uint64_t>& reasons,
                                                                std::size_t max_reasons, std::size_t max_chars) {
  std::map<std::string, std::uint64_t> cut;
  for (const auto& [reason, n] : reasons)
    if (n > 0) cut[reason.substr(0, max_chars)] += n;
  std::vector<std::pair<std::string, std::uint64_t>> v(cut.begin(), cut.end());
  if (max_reasons == 0) return {};  // nowhere to put anything (not the wire's case)
  if (v.size() > max_reasons) {
    std::stable_sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
    std::uint64_t rest = 0;
    for (std::size_t i = max_reasons - 1; i < v.size(); ++i) rest += v[i].second;
    v.resize(max_reasons - 1);
    // A reason already called kOtherReasons among the kept ones takes the rest too.
    const std::string other = std::string(kOtherReasons).substr(0, max_chars);
    auto it = std::find_if(v.begin(), v.end(), [&](const auto& r) { return r.first == other; });
    if (it != v.end()) it->second += rest;
    else v.emplace_back(other, rest);
    std::sort(v.begin(), v.end());
  }
  return v;
}

void SourceTally::update(std::uint64_t run, const SourceCounts& counts) {
  if (run == 0) return;
  runs_[run] = counts;  // a run's newest heartbeat: its counters so far
}

namespace {
constexpr const char* kDurationPrefix = "--duration ";
constexpr const char* kDurationSuffix = " s reached";
}  // namespace

std::string durationReachedReason(double duration_s) {
  char b[64];
  std::snprintf(b, sizeof b, "%s%g%s", kDurationPrefix, duration_s, kDurationSuffix);
  return b;
}

bool isDurationReached(const std::string& reason) {
  const std::string pre = kDurationPrefix, suf = kDurationSuffix;
  return reason.size() > pre.size() + suf.size() && reason.compare(0, pre.size(), pre) == 0 &&
         reason.compare(reason.size() - suf.size(), suf.size(), suf) == 0;
}

bool SourceTally::stoppedByDuration(std::uint64_t run) const {
  const auto it = runs_.find(run);
  if (it == runs_.end()) return false;
  for (const auto& [reason, n] : it->second.not_played)
    if (n > 0 && isDurationReached(reason)) return true;
  return false;
}

SourceCounts SourceTally::total() const {
  SourceCounts t;
  for (const auto& [run, c] : runs_) {
    t.received += c.received;
    t.accepted += c.accepted;
    for (const auto& [reason, n] : c.rejected)
      if (n > 0) t.rejected[reason] += n;
    for (const auto& [reason, n] : c.not_played)
      if (n > 0) t.not_played[reason == kNotPlayedYet ? kNotPlayedNoFinalCount : reason] += n;
  }
  return t;
}

std::string describeSource(const SourceCounts& c, std::size_t runs) {
  std::string reasons;
  for (const auto& [reason, n] : c.rejected) reasons += (reasons.empty() ? "" : ", ") + reason + " " + std::to_string(n);
  std::string s = "source: received " + std::to_string(c.received) + ", accepted " + std::to_string(c.accepted) + ", rejected " +
                  std::to_string(c.rejectedTotal()) + " (" + (reasons.empty() ? "none" : reasons) + ")";
  if (c.notPlayedTotal() > 0) {
    std::string why;
    for (const auto& [reason, n] : c.not_played) why += (why.empty() ? "" : ", ") + reason + " " + std::to_string(n);
    s += "; not played " + std::to_string(c.notPlayedTotal()) + " (" + why + ")";
  }
  if (runs > 1) s += ", over " + std::to_string(runs) + " ingest runs (summed)";
  return s;
}

}  // namespace godhand
