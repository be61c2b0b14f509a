// The lock-step gate of a stage: frame k is processed once every input it needs for k is in, or
// the stage gives up when the frame's deadline passes. Only presence is tracked here (the main
// keeps the payloads); the clock is the caller's (every call takes `now`), so the rule is
// unit-tested without processes or sleeping.
//
// Inputs are numbered 0..N-1. Trigger inputs (the solver's HandTarget, the resolver's
// HandProposals) start the frame's deadline: it runs from the first trigger of frame k, or from
// when k became the next frame, whichever is later. The other inputs are prerequisites (the
// scene of k-1, the hand's state of k-1: the caller offers them as inputs of frame k). A frame
// with no trigger yet is Idle (nothing to wait for: the run has not reached it).
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <vector>

namespace godhand::svc {

class LockstepGate {
 public:
  using Clock = std::chrono::steady_clock;
  enum class State { Idle, Waiting, Ready, Missed };
  struct Poll {
    State state = State::Idle;
    Clock::time_point until{};        ///< Waiting: when the deadline passes
    std::vector<size_t> missing;      ///< Waiting / Missed: the inputs not in yet
  };

  /// triggers[i]: input i starts the deadline. deadline_s > 0.
  LockstepGate(std::vector<bool> triggers, double deadline_s, Clock::time_point now, std::uint64_t first_frame = 1);

  /// Input `input` of `frame` is in. False (and nothing recorded) when the frame is already done
  /// (a late or repeated sample) or the input is unknown.
  bool offer(size_t input, std::uint64_t frame, Clock::time_point now);
  /// Input `input` is not needed for `frame` (the solver's own state before frame 1).
  void waive(size_t input, std::uint64_t frame);

  /// The state of next() at `now`.
  Poll poll(Clock::time_point now) const;
  std::uint64_t next() const { return next_; }
  /// next() has been processed: the gate moves to the frame after it.
  void advance(Clock::time_point now);

 private:
  struct Frame {
    std::vector<unsigned char> have;
    Clock::time_point first_trigger{};
    bool triggered = false;
  };
  Frame& frame(std::uint64_t k);

  std::vector<bool> triggers_;
  Clock::duration deadline_;
  std::uint64_t next_;
  Clock::time_point next_since_;
  std::map<std::uint64_t, Frame> frames_;
};

}  // namespace godhand::svc
