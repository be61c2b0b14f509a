#include "common/recovery.h"

#include <algorithm>

namespace godhand {

RecoveryLog::RecoveryLog(int hands) : ever_(static_cast<size_t>(std::max(hands, 0)), 0) {}

RecoveryLog::Restart& RecoveryLog::open(const std::string& service) {
  if (restarts_.size() >= kMaxRestarts) {  // bounded (a crash loop for a day): the oldest finished one goes
    auto it = std::find_if(restarts_.begin(), restarts_.end(),
                           [](const Restart& r) { return r.fresh_again_s >= 0 || r.superseded; });
    restarts_.erase(it != restarts_.end() ? it : restarts_.begin());
    ++dropped_;
  }
  // An outage of the same service still waiting goes no further: superseded by this one.
  for (Restart& r : restarts_)
    if (r.service == service && r.restarted && r.fresh_again_s < 0) r.superseded = true;
  Restart r;
  r.service = service;
  r.hand.assign(ever_.size(), -1);
  restarts_.push_back(r);
  return restarts_.back();
}

void RecoveryLog::down(const std::string& service, double from_s, double by_s) {
  // Killed, then seen ended: one outage, from the earlier.
  for (auto it = restarts_.rbegin(); it != restarts_.rend(); ++it)
    if (it->service == service && !it->restarted && !it->superseded) return;
  Restart& r = open(service);
  r.down_s = std::min(from_s, by_s);
  r.down_by_s = std::max(from_s, by_s);
  r.down_known = true;
}

void RecoveryLog::restarted(const std::string& service, double t_s, long pid) {
  Restart* r = nullptr;
  for (auto it = restarts_.rbegin(); it != restarts_.rend() && !r; ++it)
    if (it->service == service && !it->restarted && !it->superseded) r = &*it;
  if (!r) r = &open(service);
  r->restarted = true;
  r->restarted_s = t_s;
  r->pid = pid;
}

void RecoveryLog::state(int hand, bool stale, double t_s) {
  if (hand < 0 || static_cast<size_t>(hand) >= ever_.size() || !(t_s >= 0)) return;
  if (replay_end_s_ >= 0 && t_s > replay_end_s_) return;
  const size_t h = static_cast<size_t>(hand);
  ever_[h] = 1;
  if (stale) {
    if (stale_first_s_ < 0) stale_first_s_ = t_s;
    stale_last_s_ = t_s;
  }
  for (Restart& r : restarts_) {
    if (r.fresh_again_s >= 0 || r.superseded) continue;
    const double from = r.down_known ? r.down_s : r.restarted_s;
    if (t_s < from) continue;
    if (stale) ++r.stale_states;
    if (!r.restarted || !r.beat || t_s < r.up_s) continue;
    r.hand[h] = stale ? 0 : 1;
    bool all = true;
    for (size_t k = 0; k < ever_.size() && all; ++k) all = r.hand[k] == 1 || !ever_[k];
    if (all) r.fresh_again_s = t_s;
  }
}

void RecoveryLog::sceneRunBegan(double t_s) {
  // The newest scene restart still waiting for its first state (an older one that never saw its
  // own was superseded by this restart).
  for (auto it = restarts_.rbegin(); it != restarts_.rend(); ++it) {
    if (it->service != "scene" || !it->restarted || t_s < it->restarted_s) continue;
    if (it->scene_back_s < 0) it->scene_back_s = t_s;
    return;
  }
}

void RecoveryLog::heartbeat(const std::string& service, long pid, double t_s) {
  for (Restart& r : restarts_)
    if (r.service == service && r.restarted && r.pid == pid && !r.beat) {
      r.beat = true;
      r.up_s = std::max(t_s, r.restarted_s);
    }
}

void RecoveryLog::replayEnded(double t_s) {
  if (replay_end_s_ < 0) replay_end_s_ = t_s;
}

int RecoveryLog::unrecovered() const {
  return static_cast<int>(
      std::count_if(restarts_.begin(), restarts_.end(), [](const Restart& r) { return r.fresh_again_s < 0 && !r.superseded; }));
}

}  // namespace godhand
