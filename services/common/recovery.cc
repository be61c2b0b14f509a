#include "common/recovery.h"

#include <algorithm>

namespace godhand {

RecoveryLog::RecoveryLog(int hands) : stale_(static_cast<size_t>(std::max(hands, 0)), 0) {}

void RecoveryLog::restarted(const std::string& service, double t_s, long pid) {
  if (restarts_.size() >= kMaxRestarts) {  // bounded (a crash loop for a day): the oldest recovered one goes
    auto it = std::find_if(restarts_.begin(), restarts_.end(), [](const Restart& r) { return r.fresh_again_s >= 0; });
    restarts_.erase(it != restarts_.end() ? it : restarts_.begin());
    ++dropped_;
  }
  Restart r;
  r.service = service;
  r.restarted_s = t_s;
  r.pid = pid;
  restarts_.push_back(r);
}

void RecoveryLog::state(int hand, bool stale, double t_s) {
  if (hand < 0 || static_cast<size_t>(hand) >= stale_.size() || !(t_s >= 0)) return;
  stale_[static_cast<size_t>(hand)] = stale ? 1 : 0;
  if (stale) {
    if (stale_first_s_ < 0) stale_first_s_ = t_s;
    stale_last_s_ = t_s;
  }
  const bool all_fresh = std::none_of(stale_.begin(), stale_.end(), [](unsigned char s) { return s != 0; });
  for (Restart& r : restarts_) {
    if (r.fresh_again_s >= 0 || t_s < r.restarted_s) continue;
    if (all_fresh && r.beat && t_s >= r.up_s) r.fresh_again_s = t_s;
    else if (stale) ++r.stale_states;
  }
}

void RecoveryLog::sceneRunBegan(double t_s) {
  // The newest scene restart still waiting for its first state (an older one that never saw its
  // own was superseded by this restart).
  for (auto it = restarts_.rbegin(); it != restarts_.rend(); ++it) {
    if (it->service != "scene" || t_s < it->restarted_s) continue;
    if (it->scene_back_s < 0) it->scene_back_s = t_s;
    return;
  }
}

void RecoveryLog::heartbeat(const std::string& service, long pid, double t_s) {
  for (Restart& r : restarts_)
    if (r.service == service && r.pid == pid && !r.beat) {
      r.beat = true;
      r.up_s = std::max(t_s, r.restarted_s);
    }
}

void RecoveryLog::replayEnded(double t_s) {
  if (replay_end_s_ < 0) replay_end_s_ = t_s;
}

int RecoveryLog::unrecovered() const {
  return static_cast<int>(std::count_if(restarts_.begin(), restarts_.end(), [](const Restart& r) { return r.fresh_again_s < 0; }));
}

}  // namespace godhand
