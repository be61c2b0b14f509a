// One 16-body hand step against the number of contact rows, exact (TreeSolver, and without it:
// `exact_general`) vs PGS (measured, not asserted). Every body rests on its own horizontal support (a stepped table whose step heights
// are the bodies' rest undersides, so that all 16 bodies touch at once); the tracked hand
// presses 5 mm into it and slides in a circle. N contacts are spread over the 16 bodies (points
// along each body's underside, exact signed distances to its support), regenerated every step
// as the collision stage will: many are redundant and coplanar, the hard case for the solver.
//
//   build/bin/godhand-bench-step --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// Counters: rows, solver iterations, active-set size, KKT residual (max over the run), mean
// solve-stage time. `_cold` variants solve every step without the previous step's active set /
// multipliers.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/files.h"
#include "model/hand_model.h"
#include "step/cluster_step.h"

namespace {
using namespace godhand;

const HandModel& hand() {
  static const HandModel model = loadHandModel(GODHAND_MODELS_DIR "/hand16_right.pbtxt");
  return model;
}

/// Lowest point of a body's shape along -z at parameter s ∈ [-1, 1] along its long axis.
Vec3 underside(const Body& b, const Pose& X, double s, double t) {
  switch (b.shape.type) {
    case ShapeType::Capsule:
      return X * Vec3(0, 0, s * b.shape.half_length) - Vec3(0, 0, b.shape.radius);
    case ShapeType::Sphere:
      return X.p - Vec3(0, 0, b.shape.radius);
    case ShapeType::Box: {
      const Vec3 h = b.shape.half_extents;
      return X * Vec3(s * h.x(), t * h.y(), -h.z());
    }
  }
  return X.p;
}

struct Scenario {
  Scenario(SolverKind kind, bool warm, int contacts, bool tree = true)
      : params(makeParams(kind, warm, tree)), stepper(hand(), params), n(contacts) {
    start = hand().restPoses(Pose{});
    for (size_t b = 0; b < start.size(); ++b) support.push_back(underside(hand().bodies[b], start[b], 0, 0).z());
    stepper.reset(start);
    stepper.reserve(contacts);
    targets = start;
    contacts_buf.resize(static_cast<size_t>(contacts));
  }
  static StepParams makeParams(SolverKind kind, bool warm, bool tree) {
    StepParams p;
    p.solver = kind;
    p.warm_start = warm;
    p.tree_solver = tree;
    p.pgs.sweeps = 30;
    return p;
  }
  void update(int frame) {
    // Targets: rigid circle in xy, 5 mm into the table, fingers curling 0..60° about their axes.
    const double a = 0.002 * frame;
    Pose X_M;
    X_M.p = Vec3(0.01 * std::cos(a), 0.01 * std::sin(a), -0.005);
    for (size_t b = 0; b < targets.size(); ++b) targets[b] = X_M * start[b];
    const auto& poses = stepper.poses();
    for (int i = 0; i < n; ++i) {
      const int b = i % 16, slot = i / 16, per = (n + 15 - b) / 16;
      const double s = per > 1 ? -1.0 + 2.0 * slot / (per - 1) : 0.0;
      const double t = std::sin(1.7 * slot);
      const Body& body = hand().bodies[static_cast<size_t>(b)];
      Contact& c = contacts_buf[static_cast<size_t>(i)];
      c.body = b;
      c.p_W = underside(body, poses[static_cast<size_t>(b)], s, t);
      c.n_W = Vec3(0, 0, 1);
      c.distance = c.p_W.z() - support[static_cast<size_t>(b)];
      c.key = static_cast<std::uint64_t>(i) + 1;
      c.object = 0;
    }
  }
  StepParams params;
  ClusterStepper stepper;
  int n;
  std::vector<Pose> start, targets;
  std::vector<double> support;  // height of each body's support
  std::vector<Contact> contacts_buf;
};

void BM_HandStep(benchmark::State& state, SolverKind kind, bool warm, bool tree = true) {
  Scenario sc(kind, warm, static_cast<int>(state.range(0)), tree);
  int frame = 0;
  for (int i = 0; i < 50; ++i) {  // warm up into steady contact
    sc.update(frame++);
    StepInput in{sc.targets.data(), nullptr, sc.contacts_buf.data(), sc.n};
    sc.stepper.step(in);
  }
  double iters = 0, active = 0, kkt = 0, rows = 0, solve_us = 0;
  std::int64_t steps = 0;
  for (auto _ : state) {
    sc.update(frame++);
    StepInput in{sc.targets.data(), nullptr, sc.contacts_buf.data(), sc.n};
    const StepReport& r = sc.stepper.step(in);
    benchmark::DoNotOptimize(r.solve.kkt_residual);
    iters += r.solve.iterations;
    active += r.solve.active_set_size;
    kkt = std::max(kkt, r.solve.kkt_residual);
    rows += r.rows;
    solve_us += r.times.solve_us;
    ++steps;
  }
  const double k = steps ? 1.0 / static_cast<double>(steps) : 0.0;
  state.counters["rows"] = rows * k;
  state.counters["solver_iters"] = iters * k;
  state.counters["active"] = active * k;
  state.counters["solve_us"] = solve_us * k;
  state.counters["kkt_max"] = kkt;
  state.counters["failures"] = static_cast<double>(sc.stepper.counters().solver_failures);
}

void contactCounts(benchmark::internal::Benchmark* b) {
  for (int n : {0, 16, 64, 256, 1024}) b->Arg(n);
  b->Unit(benchmark::kMicrosecond);
}

}  // namespace

BENCHMARK_CAPTURE(BM_HandStep, exact, godhand::SolverKind::Exact, true)->Apply(contactCounts);
// The same exact solution without TreeSolver (ActiveSetSolver on every problem): before and after.
BENCHMARK_CAPTURE(BM_HandStep, exact_general, godhand::SolverKind::Exact, true, false)->Apply(contactCounts);
BENCHMARK_CAPTURE(BM_HandStep, pgs, godhand::SolverKind::Pgs, true)->Apply(contactCounts);
BENCHMARK_CAPTURE(BM_HandStep, exact_cold, godhand::SolverKind::Exact, false)->Apply(contactCounts);
BENCHMARK_CAPTURE(BM_HandStep, pgs_cold, godhand::SolverKind::Pgs, false)->Apply(contactCounts);
BENCHMARK_MAIN();
