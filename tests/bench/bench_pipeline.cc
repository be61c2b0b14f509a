// The cost of one Workers call as a hand solver makes it (measured, not asserted): 16 jobs of
// ~1.6 µs each (a body's contact or sweep query), then serial work (the QP between two
// parallel phases). Two threads against the same jobs run in the caller alone; the difference
// is the hand-off (waking the other thread, learning that it finished).
//
//   build/bin/godhand-bench-pipeline --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <functional>

#include "pipeline/workers.h"

namespace {

double work(int n) {
  double s = 0.0;
  for (int k = 0; k < n; ++k) s += static_cast<double>(k) * 1e-9 + s * 1e-12;
  return s;
}

void BM_WorkersCall(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const int serial = static_cast<int>(state.range(1));  // work units between two calls
  godhand::Workers workers(threads);
  double sink = 0.0;
  const std::function<void(int, int)> job = [&sink](int, int) {
    const double s = work(800);
    benchmark::DoNotOptimize(s);
  };
  for (auto _ : state) {
    workers.runSlots(16, job);
    state.PauseTiming();
    sink += work(serial);
    state.ResumeTiming();
  }
  benchmark::DoNotOptimize(sink);
  state.counters["threads"] = threads;
}
// Serial gaps of ~10 µs and ~150 µs (a QP).
BENCHMARK(BM_WorkersCall)->Args({1, 5000})->Args({2, 5000})->Args({2, 75000})->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
