#include "runtime/lockstep_gate.h"

#include <algorithm>

namespace godhand::svc {

LockstepGate::LockstepGate(std::vector<bool> triggers, double deadline_s, Clock::time_point now, std::uint64_t first_frame)
    : triggers_(std::move(triggers)),
      deadline_(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(deadline_s))),
      next_(first_frame),
      next_since_(now) {}

LockstepGate::Frame& LockstepGate::frame(std::uint64_t k) {
  Frame& f = frames_[k];
  if (f.have.empty()) f.have.assign(triggers_.size(), 0);
  return f;
}

bool LockstepGate::offer(size_t input, std::uint64_t k, Clock::time_point now) {
  if (input >= triggers_.size() || k < next_) return false;
  Frame& f = frame(k);
  if (f.have[input]) return true;
  f.have[input] = 1;
  if (triggers_[input] && !f.triggered) {
    f.triggered = true;
    f.first_trigger = now;
  }
  return true;
}

void LockstepGate::waive(size_t input, std::uint64_t k) {
  if (input >= triggers_.size() || k < next_) return;
  frame(k).have[input] = 1;
}

LockstepGate::Poll LockstepGate::poll(Clock::time_point now) const {
  Poll p;
  auto it = frames_.find(next_);
  if (it == frames_.end() || !it->second.triggered) return p;  // Idle
  const Frame& f = it->second;
  for (size_t i = 0; i < f.have.size(); ++i)
    if (!f.have[i]) p.missing.push_back(i);
  if (p.missing.empty()) {
    p.state = State::Ready;
    return p;
  }
  p.until = std::max(f.first_trigger, next_since_) + deadline_;
  p.state = now >= p.until ? State::Missed : State::Waiting;
  return p;
}

void LockstepGate::advance(Clock::time_point now) {
  frames_.erase(frames_.begin(), frames_.upper_bound(next_));
  ++next_;
  next_since_ = now;
}

}  // namespace godhand::svc
