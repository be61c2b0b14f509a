// What reached a subscriber, counted per hand cluster and frame (never the highest frame number):
// for each run of the ingest (Stamp.run) and each frame it was expected to publish, a frame is
// delivered fresh (at least one HandState of it, not stale), delivered stale (only stale ones:
// flagged by the resolver, or older than the stale limit when received, whatever the flag says)
// or lost (none). Re-published held states carry the frame they hold, so they add no frames.
// Frames published while the subscriber itself did not watch (the launcher stopped, starved or
// stalled: its readers keep the newest sample only, so what came meanwhile was superseded in its
// own queue, not lost by the lab) and of which no state came are counted apart, as unobserved.
//
// And the verdict of `godhand-launch --check` from the run's figures (evaluateRun): one reason
// per failed condition, so the report says why.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace godhand {

struct DeliveryCounts {
  std::uint64_t expected = 0, fresh = 0, stale = 0, lost = 0;
  std::uint64_t unobserved = 0;  ///< no state seen, published while this subscriber did not watch
};

class Delivery {
 public:
  explicit Delivery(size_t hands) : fresh_(hands), stale_(hands) {}
  /// A HandState of `hand` for (run, frame) was received; `stale`: flagged or too old.
  /// Frame 0 (before the first frame) and unknown hands are ignored.
  void add(size_t hand, std::uint64_t run, std::uint64_t frame, bool stale);
  /// The ingest's run `run` published frame `frame` (seen as a HandTarget, or known otherwise).
  void published(std::uint64_t run, std::uint64_t frame);
  /// Frames first..last of `run` were published while this subscriber did not watch (its own
  /// pause): those without a state count as unobserved, not lost.
  void unobserved(std::uint64_t run, std::uint64_t first, std::uint64_t last);
  /// Runs in order of first appearance and the highest frame seen of each (published or delivered).
  const std::vector<std::uint64_t>& runs() const { return runs_; }
  std::uint64_t highest(std::uint64_t run) const;
  /// Frames expected of each run seen (run -> N: frames 1..N), for counts(): the last run
  /// expects the replay's `replay_frames` (it was to play to the end), unless it was stopped on
  /// purpose before the end (`last_run_cut_short`: the ingest's --duration), then, like a run
  /// cut short by a kill, the frames it published; a live source (replay_frames < 0) expects
  /// the frames published. Nothing seen at all: run 0 expects the replay's frames (all lost),
  /// unless the run was cut short on purpose before its first frame (nothing expected).
  std::map<std::uint64_t, std::uint64_t> expected(std::int64_t replay_frames, bool last_run_cut_short) const;
  /// Counts of `hand` against `expected`: run -> frames 1..N expected of it (runs not listed
  /// expect nothing; frames beyond N are not counted).
  DeliveryCounts counts(size_t hand, const std::map<std::uint64_t, std::uint64_t>& expected) const;
  size_t hands() const { return fresh_.size(); }

 private:
  using Key = std::pair<std::uint64_t, std::uint64_t>;  // run, frame
  void seen(std::uint64_t run, std::uint64_t frame);
  std::vector<std::set<Key>> fresh_, stale_;
  std::vector<std::pair<Key, std::uint64_t>> blind_;  // (run, first frame), last frame
  std::vector<std::uint64_t> runs_;
  std::map<std::uint64_t, std::uint64_t> highest_;
};

/// The figures `--check` judges.
struct RunFigures {
  bool lockstep = false;
  double loss_budget = 0.0;                 ///< lost (and not observed) frames allowed per hand, fraction of expected
  std::map<std::string, DeliveryCounts> delivery;  ///< per cluster
  std::vector<std::string> dead_at_end;     ///< services not running / silent when the run ended
  bool late_joiner_ok = false;
  std::vector<std::string> drills_not_done; ///< --kill drills that never fired
  std::vector<std::string> foreign;         ///< services of another lab seen on the domain (mixed samples)
  std::string failure;                      ///< a run failure ("" = none)
  double penetration_max = 0.0, margin = 0.0, joint_gap_max = 0.0;
  long solver_failures = 0;
  long states = 0;
};

struct RunVerdict {
  bool ok = true;
  std::vector<std::string> reasons;  ///< one line per failed condition
};

RunVerdict evaluateRun(const RunFigures& f);

}  // namespace godhand
