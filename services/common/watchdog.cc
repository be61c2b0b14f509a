#include "common/watchdog.h"

#include <algorithm>

namespace godhand {

void Watchdog::endEpisode(Entry& e, Clock::time_point now, bool by_reset) {
  if (e.silent && e.episode >= 0) {
    episodes_[static_cast<size_t>(e.episode)].end_s = seconds(now);
    episodes_[static_cast<size_t>(e.episode)].reset = by_reset;
  }
  e.silent = false;
  e.episode = -1;
}

void Watchdog::beat(const std::string& service, Clock::time_point now) {
  Entry& e = entries_[service];
  endEpisode(e, now, false);
  if (now > e.last) e.last = now;
  if (now > e.aged) e.aged = now;
}

void Watchdog::shiftOver(Clock::time_point now, bool record) {
  if (last_update_ != Clock::time_point{} && now > last_update_) {
    const auto gap = now - last_update_;
    if (std::chrono::duration<double>(gap).count() > 0.5 * silent_after_) {
      // Recorded (and said) only when longer than the limit itself, where it changed a verdict,
      // and at most kMaxPauses of them (a starved launcher's every loop is such a gap).
      if (record && std::chrono::duration<double>(gap).count() > silent_after_) {
        if (pauses_.size() < kMaxPauses) pauses_.push_back({seconds(last_update_), std::chrono::duration<double>(gap).count()});
        ++pause_count_;
      }
      // The credit is the gap less a quarter of the limit: a launcher whose every loop is slow
      // (0.7 s under load) still ages a dead service by that quarter a loop, so it is found,
      // later, instead of never.
      const auto credit = gap - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(0.25 * silent_after_));
      for (auto& [name, e] : entries_)
        if (e.aged != Clock::time_point{} && !e.silent) e.aged = std::min(e.aged + credit, now);
    }
  }
  last_update_ = std::max(last_update_, now);
}

std::vector<std::string> Watchdog::update(Clock::time_point now) {
  std::vector<std::string> out;
  shiftOver(now, true);
  for (auto& [name, e] : entries_) {
    if (e.aged == Clock::time_point{} || e.silent) continue;
    if (std::chrono::duration<double>(now - e.aged).count() > silent_after_) {
      e.silent = true;
      e.episode = static_cast<int>(episodes_.size());
      episodes_.push_back({name, seconds(e.last) + silent_after_, -1.0});
      out.push_back(name);
    }
  }
  return out;
}

Watchdog::Health Watchdog::health(const std::string& service) const {
  auto it = entries_.find(service);
  if (it == entries_.end() || it->second.last == Clock::time_point{}) return Health::Unknown;
  return it->second.silent ? Health::Silent : Health::Alive;
}

double Watchdog::silentFor(const std::string& service, Clock::time_point now) const {
  auto it = entries_.find(service);
  if (it == entries_.end() || it->second.last == Clock::time_point{}) return -1.0;
  return std::chrono::duration<double>(now - it->second.last).count();
}

void Watchdog::reset(const std::string& service, Clock::time_point now) {
  auto it = entries_.find(service);
  if (it == entries_.end()) return;
  endEpisode(it->second, now, true);
  entries_.erase(it);
}

}  // namespace godhand
