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

}  // namespace godhand
