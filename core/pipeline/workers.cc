#include "pipeline/workers.h"

#include <chrono>
#include <stdexcept>

namespace godhand {
namespace {

constexpr double kSpinMicros = 300.0;  ///< how long a thread out of jobs polls before it blocks

/// Polls `done` until it holds or kSpinMicros have passed, yielding the core at every poll (a
/// runnable thread, e.g. the other hand's solver, gets it at once).
template <class Done>
void pollFor(const Done& done) {
  const auto start = std::chrono::steady_clock::now();
  for (int i = 1; !done(); ++i) {
    std::this_thread::yield();
    if (i % 16 == 0 &&
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count() > kSpinMicros)
      return;
  }
}

}  // namespace

Workers::Workers(int threads) {
  if (threads < 1 || threads > 64) throw std::invalid_argument("threads must be in [1, 64]");
  threads_.reserve(static_cast<size_t>(threads - 1));
  for (int t = 1; t < threads; ++t) threads_.emplace_back([this, t] { loop(t); });
}

Workers::~Workers() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (std::thread& t : threads_) t.join();
}

// Takes jobs until none is left; called and returns with the lock held.
void Workers::drain(std::unique_lock<std::mutex>& lock, int slot) {
  while (next_ < n_) {
    const int i = next_++;
    ++running_;
    lock.unlock();
    std::exception_ptr e;
    try {
      (*job_)(i, slot);
    } catch (...) {
      e = std::current_exception();
    }
    lock.lock();
    if (e && !error_) error_ = e;
    unfinished_.fetch_sub(1, std::memory_order_release);
    if (--running_ == 0 && next_ >= n_) done_.notify_all();
  }
}

void Workers::loop(int slot) {
  std::unique_lock<std::mutex> lock(mutex_);
  std::uint64_t seen = 0;  // a thread that starts late still joins the first run
  for (;;) {
    lock.unlock();
    pollFor([&] { return stop_.load(std::memory_order_relaxed) || generation_.load(std::memory_order_acquire) != seen; });
    lock.lock();
    start_.wait(lock, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    drain(lock, slot);
  }
}

void Workers::run(int n, const std::function<void(int)>& job) {
  const std::function<void(int, int)> plain = [&job](int i, int) { job(i); };  // fits std::function's buffer
  runSlots(n, plain);
}

void Workers::runSlots(int n, const std::function<void(int, int)>& job) {
  if (n <= 0) return;
  if (threads_.empty() || n == 1) {
    std::exception_ptr first;
    for (int i = 0; i < n; ++i) {
      try {
        job(i, 0);
      } catch (...) {
        if (!first) first = std::current_exception();
      }
    }
    if (first) std::rethrow_exception(first);
    return;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  job_ = &job;
  n_ = n;
  next_ = 0;
  error_ = nullptr;
  unfinished_.store(n, std::memory_order_relaxed);
  ++generation_;
  start_.notify_all();
  drain(lock, 0);
  if (running_ > 0) {  // the last jobs are still running on other threads
    lock.unlock();
    pollFor([&] { return unfinished_.load(std::memory_order_acquire) <= 0; });
    lock.lock();
  }
  done_.wait(lock, [&] { return running_ == 0 && next_ >= n_; });
  job_ = nullptr;
  n_ = 0;
  std::exception_ptr e = error_;
  error_ = nullptr;
  lock.unlock();
  if (e) std::rethrow_exception(e);
}

// ---------------------------------------------------------------------------------------------
// JobShare

struct JobShare::Lane {
  // Set by the owner before it posts the lane, read by helpers only while posted (users > 0).
  const std::function<void(int, int)>* job = nullptr;
  int n = 0;
  int owner = 0;
  std::atomic<int> next{0};
  std::atomic<int> unfinished{0};
  std::atomic<int> users{0};   ///< helpers between their check of `posted` and their last job
  std::atomic<bool> posted{false};
  std::atomic<double> weight{0.0};
  std::atomic<double> lent_us{0.0};  ///< its owner's time in heavier lanes' jobs (takeHeavier)
  std::mutex error_mutex;
  std::exception_ptr error;
};

JobShare::JobShare(int lanes, int threads) : threads_(threads) {
  if (lanes < 1) throw std::invalid_argument("lanes must be at least 1");
  if (threads < 1 || threads > 64) throw std::invalid_argument("threads must be in [1, 64]");
  for (int l = 0; l < lanes; ++l) lanes_.push_back(std::make_unique<Lane>());
}

JobShare::~JobShare() = default;

bool JobShare::takeOne(Lane& lane, int thread) {
  // The owner's slot is 0; a helper's is its thread index, shifted past the owner's.
  const int slot = thread == lane.owner ? 0 : thread < lane.owner ? thread + 1 : thread;
  const int i = lane.next.fetch_add(1);
  if (i >= lane.n) return false;
  try {
    (*lane.job)(i, slot);
  } catch (...) {
    std::lock_guard<std::mutex> lock(lane.error_mutex);
    if (!lane.error) lane.error = std::current_exception();
  }
  lane.unfinished.fetch_sub(1);
  return true;
}

bool JobShare::take(Lane& lane, int thread) {
  bool ran = false;
  while (takeOne(lane, thread)) ran = true;
  return ran;
}

bool JobShare::takeHeavier(int own, int thread) {
  const double mine = lanes_[static_cast<size_t>(own)]->weight.load(std::memory_order_relaxed);
  for (size_t l = 0; l < lanes_.size(); ++l) {
    if (static_cast<int>(l) == own) continue;
    Lane& lane = *lanes_[l];
    if (!lane.posted.load() || !(lane.weight.load(std::memory_order_relaxed) > mine)) continue;
    lane.users.fetch_add(1);
    // Checked again once counted (as in help()): a lane its owner has taken down is left alone.
    const auto t0 = std::chrono::steady_clock::now();
    const bool ran = lane.posted.load() && takeOne(lane, thread);
    lane.users.fetch_sub(1);
    if (ran) {
      const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
      std::atomic<double>& lent = lanes_[static_cast<size_t>(own)]->lent_us;
      lent.store(lent.load(std::memory_order_relaxed) + us, std::memory_order_relaxed);  // (only its owner adds)
      return true;
    }
  }
  return false;
}

double JobShare::takeLent(int lane) {
  if (lane < 0 || lane >= static_cast<int>(lanes_.size())) throw std::invalid_argument("JobShare::takeLent: no such lane");
  return lanes_[static_cast<size_t>(lane)]->lent_us.exchange(0.0, std::memory_order_relaxed);
}

void JobShare::setWeight(int lane, double weight) {
  if (lane < 0 || lane >= static_cast<int>(lanes_.size())) throw std::invalid_argument("JobShare::setWeight: no such lane");
  lanes_[static_cast<size_t>(lane)]->weight.store(weight, std::memory_order_relaxed);
}

void JobShare::run(int lane_index, int thread, int n, const std::function<void(int, int)>& job) {
  if (lane_index < 0 || lane_index >= static_cast<int>(lanes_.size()))
    throw std::invalid_argument("JobShare::run: no such lane");
  if (thread < 0 || thread >= threads_) throw std::invalid_argument("JobShare::run: no such thread");
  if (n <= 0) return;
  Lane& lane = *lanes_[static_cast<size_t>(lane_index)];
  lane.job = &job;
  lane.n = n;
  lane.owner = thread;
  lane.error = nullptr;
  lane.next.store(0);
  lane.unfinished.store(n);
  lane.posted.store(true);  // (sequentially consistent: the fields above are seen by whoever sees this)
  // Its own jobs, each after any job of a heavier posted lane (setWeight).
  for (;;) {
    if (takeHeavier(lane_index, thread)) continue;
    if (!takeOne(lane, thread)) break;
  }
  // A helper may still run the last jobs: at most one each (meanwhile, a heavier lane's).
  while (lane.unfinished.load() > 0)
    if (!takeHeavier(lane_index, thread)) std::this_thread::yield();
  lane.posted.store(false);
  // A helper that saw the lane posted may not have left it yet (it finds no job left): the lane
  // is not reset under it.
  while (lane.users.load() > 0) std::this_thread::yield();
  std::exception_ptr e = lane.error;
  lane.error = nullptr;
  if (e) std::rethrow_exception(e);
}

void JobShare::help(int thread, const std::function<bool()>& done) {
  if (thread < 0 || thread >= threads_) throw std::invalid_argument("JobShare::help: no such thread");
  while (!done()) {
    bool ran = false;
    for (const auto& l : lanes_) {
      Lane& lane = *l;
      if (!lane.posted.load()) continue;
      lane.users.fetch_add(1);
      // Checked again once counted: a lane the owner has taken down (and may be resetting) is left.
      if (lane.posted.load()) ran = take(lane, thread) || ran;
      lane.users.fetch_sub(1);
    }
    if (!ran) std::this_thread::yield();
  }
}

}  // namespace godhand
