#pragma once
// A fixed set of compute threads that run the jobs 0..n-1 of one call, the caller taking its
// share: the pipeline's hand solvers run on them (PipelineParams::threads), as the distributed
// services run one solver process per hand cluster. Each job touches only its own hand's
// state, so the results are the same for every thread count (tested by the determinism hash).
// No I/O, no allocation per call.
//
// A thread that has run out of jobs polls for up to kSpinMicros (yielding the core at every poll)
// before it blocks: waking a blocked thread takes ~25 µs here (a futex wake and a reschedule),
// which a hand solver would otherwise pay at each of the several parallel phases of a frame, the
// serial QPs between them being ~0.1–0.3 ms. Measured (godhand-bench-pipeline BM_WorkersCall, two
// threads, 16 jobs of ~1.6 µs between serial work): 35–41 → 17 µs a call.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace godhand {

class Workers {
 public:
  /// threads >= 1: the caller and threads - 1 background threads. Throws std::invalid_argument
  /// on threads < 1 or > 64.
  explicit Workers(int threads);
  ~Workers();
  Workers(const Workers&) = delete;
  Workers& operator=(const Workers&) = delete;

  int threads() const { return static_cast<int>(threads_.size()) + 1; }

  /// job(i) for every i in [0, n), each exactly once, spread over the threads; returns when all
  /// have finished. The first exception a job throws is rethrown here (the others still run).
  void run(int n, const std::function<void(int)>& job);
  /// The same, telling each job the slot of the thread that runs it (0: the caller, 1 ..
  /// threads() − 1: the background threads), for per-thread scratch. No two jobs run at once
  /// in one slot.
  void runSlots(int n, const std::function<void(int job, int slot)>& job);

 private:
  void loop(int slot);
  void drain(std::unique_lock<std::mutex>& lock, int slot);

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  const std::function<void(int, int)>* job_ = nullptr;
  int n_ = 0, next_ = 0, running_ = 0;
  // Written under mutex_; read without it too, by the polls before a thread blocks.
  std::atomic<std::uint64_t> generation_{0};
  std::atomic<bool> stop_{false};
  std::atomic<int> unfinished_{0};  ///< jobs of the current call not finished yet
  std::exception_ptr error_;
};

/// Per-body jobs of several owners (the hands' solvers, each running on one thread of a pool),
/// shared with the pool's threads that have run out of work of their own. An owner posts its
/// jobs in its lane and takes them itself, a helper takes what is left of any posted lane, so a
/// light hand's thread finishes its own hand and then works on the heavy hand's bodies, and no
/// core is oversubscribed (a hand with its own body threads competes with the other hand's
/// thread for the two cores: a thread the scheduler takes off in the middle of a job holds its
/// hand's next phase up to a time slice). Each job is told the slot it runs in: 0 for the owner,
/// 1 .. threads − 1 for a helper (distinct among the helpers of one owner: the thread's own
/// index, skipping the owner's), for per-slot scratch. No allocation per call.
class JobShare {
 public:
  /// lanes: owners that may post at once; threads: the pool's threads (owners and helpers).
  /// Throws std::invalid_argument on lanes < 1 or threads outside [1, 64].
  JobShare(int lanes, int threads);
  ~JobShare();
  JobShare(const JobShare&) = delete;
  JobShare& operator=(const JobShare&) = delete;

  int threads() const { return threads_; }
  /// Owner side, from pool thread `thread` (0 .. threads − 1): job(i, slot) for every i in
  /// [0, n), each exactly once; returns when all have finished. The first exception a job throws
  /// is rethrown here (the others still run). One call at a time per lane.
  void run(int lane, int thread, int n, const std::function<void(int job, int slot)>& job);
  /// Helper side, from pool thread `thread`: takes posted jobs until done() holds (polled;
  /// yields the core whenever nothing is posted).
  void help(int thread, const std::function<bool()>& done);
  /// A lane's weight (e.g. its owner's time in the last frame; 0 at first). An owner running its
  /// own lane takes, before each of its own jobs, a job of any posted lane that weighs more: the
  /// light hand's thread works on the heavy hand's bodies while they are posted and on its own
  /// hand while the heavy one is in a serial phase (its QPs), where it would otherwise wait for
  /// it once done. Which thread runs a job never changes its result.
  void setWeight(int lane, double weight);
  /// The time (µs) the owner of `lane` spent in heavier lanes' jobs since the last call (what
  /// setWeight's caller takes off its owner's time: a weight is the owner's own work).
  double takeLent(int lane);

 private:
  struct Lane;
  /// Takes jobs of `lane` (posted: checked under its users count) until none is left; true if it
  /// ran any.
  bool take(Lane& lane, int thread);
  /// One job of a posted lane other than `own` that weighs more than it; true if it ran one.
  bool takeHeavier(int own, int thread);
  /// One job of `lane`; true if it ran one.
  bool takeOne(Lane& lane, int thread);

  int threads_;
  std::vector<std::unique_ptr<Lane>> lanes_;
};

}  // namespace godhand
