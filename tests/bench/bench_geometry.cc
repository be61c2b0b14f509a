// Geometry micro-benchmarks on the 69k-triangle Stanford bunny (measured, not asserted):
// BVH build, closest() and near() for a finger-phalanx capsule (r 8 mm, 3 cm segment) at random
// poses near the surface, sweep() for one step of a phalanx (far, approaching, resting and
// sliding), and the winding number.
//
//   build-geo/bin/godhand-bench-geometry                 # per-call medians, then Google Benchmark
//   build-geo/bin/godhand-bench-geometry --benchmark_filter=Closest
//
// Before the Google Benchmark runs, main() times every query of each pose set individually and
// prints "[figure]" lines with the median and 90th percentile per call.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../test_rng.h"
#include "common/files.h"
#include "scene/mesh_io.h"
#include "geometry/bvh.h"
#include "geometry/sweep.h"

namespace {
using namespace godhand;
using namespace godhand::geo;

// The project's OBJ reader (core/scene/mesh_io), so the tests read the bunny as scenes do.
TriangleMesh loadObj(const std::string& path) { return godhand::loadMeshFile(path); }

const TriangleMesh& bunnyMesh() {
  static const TriangleMesh mesh = loadObj(GODHAND_DEPLOY_DIR "/meshes/stanford-bunny.obj");
  return mesh;
}

const MeshBvh& bunny() {
  static const MeshBvh bvh(bunnyMesh());
  return bvh;
}

Shape phalanx() {
  Shape s;
  s.type = ShapeType::Capsule;
  s.radius = 0.008;
  s.half_length = 0.015;
  return s;
}

// Draws are taken one per statement (x, then y, then z): C++ leaves the order of
// function arguments and of a binary operator's operands unspecified, so
// Vec3(draw(), draw(), draw()) or draw() * draw() gives gcc and clang different
// poses and points from one seed.
using test_support::Rng;

/// Poses whose capsule distance to the bunny lies in [lo, hi] (rejection sampling around random
/// surface points).
std::vector<Pose> posesAtDistance(double lo, double hi, int count, unsigned seed) {
  Rng rng{12345};
  rng.gen.seed(seed);
  const MeshBvh& bvh = bunny();
  const TriangleMesh& m = bvh.mesh();
  std::vector<Pose> poses;
  const Shape s = phalanx();
  while (static_cast<int>(poses.size()) < count) {
    const int t = std::uniform_int_distribution<int>(0, m.triangleCount() - 1)(rng.gen);
    double u = rng.uniform(0, 1), v = rng.uniform(0, 1);
    if (u + v > 1) { u = 1 - u; v = 1 - v; }
    const Vec3 a = m.vertex(t, 0), b = m.vertex(t, 1), c = m.vertex(t, 2);
    const Vec3 n = (b - a).cross(c - a).normalized();
    if (!n.allFinite()) continue;
    Pose X;
    X.q = rng.rotation();
    X.p = a + u * (b - a) + v * (c - a) + (s.radius + rng.uniform(lo, hi)) * n;
    NearTriangle nt;
    if (!bvh.closest(s, X, 1.0, &nt)) continue;
    if (nt.closest.distance < lo || nt.closest.distance > hi) continue;
    poses.push_back(X);
  }
  return poses;
}

struct Motion {
  Pose X0, X1;
};

/// One step of a phalanx: ≤ 1 cm translation, ≤ 0.3 rad rotation. kind 0: far (d ≥ 1 cm);
/// 1: approaching the surface from 2–6 mm; 2: resting 0.1 mm above and sliding tangentially.
std::vector<Motion> motions(int kind, int count, unsigned seed) {
  Rng rng{12345};
  rng.gen.seed(seed + 7);
  std::vector<Pose> starts = kind == 0 ? posesAtDistance(0.01, 0.03, count, seed)
                                       : kind == 1 ? posesAtDistance(0.002, 0.006, count, seed)
                                                   : posesAtDistance(0.00009, 0.00011, count, seed);
  std::vector<Motion> out;
  const Shape s = phalanx();
  for (const Pose& X0 : starts) {
    NearTriangle nt;
    bunny().closest(s, X0, 1.0, &nt);
    const Vec3 n = nt.closest.n;
    Vec3 step;
    if (kind == 1) step = -0.01 * n + 0.005 * rng.direction();          // towards the surface
    else if (kind == 2) step = 0.01 * (rng.direction().cross(n)).normalized();  // tangential slide
    else step = 0.01 * rng.direction();
    Motion m;
    m.X0 = X0;
    m.X1.p = X0.p + step;
    const double angle = rng.uniform(0.0, 0.3);
    m.X1.q = expRotation(angle * rng.direction()) * X0.q;
    out.push_back(m);
  }
  return out;
}

const std::vector<Pose>& closePoses() {
  static const std::vector<Pose> p = posesAtDistance(0.0002, 0.02, 1000, 1);
  return p;
}

void BM_BunnyBuild(benchmark::State& state) {
  const TriangleMesh& m = bunnyMesh();
  for (auto _ : state) {
    MeshBvh bvh(m);
    benchmark::DoNotOptimize(bvh.bounds());
  }
  state.counters["triangles"] = m.triangleCount();
}
BENCHMARK(BM_BunnyBuild)->Unit(benchmark::kMillisecond);

void BM_BunnyClosestCapsule(benchmark::State& state) {
  const auto& poses = closePoses();
  const Shape s = phalanx();
  const double window = state.range(0) * 1e-3;
  size_t i = 0;
  NearTriangle nt;
  for (auto _ : state) {
    benchmark::DoNotOptimize(bunny().closest(s, poses[i], window, &nt));
    i = (i + 1) % poses.size();
  }
}
BENCHMARK(BM_BunnyClosestCapsule)->Arg(20)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_BunnyNearCapsule(benchmark::State& state) {
  const auto& poses = closePoses();
  const Shape s = phalanx();
  std::vector<NearTriangle> out;
  size_t i = 0;
  double found = 0;
  for (auto _ : state) {
    out.clear();
    bunny().near(s, poses[i], 0.01, &out);
    found += out.size();
    i = (i + 1) % poses.size();
  }
  state.counters["triangles_found"] = benchmark::Counter(found, benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_BunnyNearCapsule)->Unit(benchmark::kMicrosecond);

void BM_BunnySweep(benchmark::State& state) {
  static const std::vector<Motion> sets[3] = {motions(0, 500, 2), motions(1, 500, 3), motions(2, 500, 4)};
  const auto& ms = sets[state.range(0)];
  const Shape s = phalanx();
  size_t i = 0;
  double iters = 0;
  for (auto _ : state) {
    const SweepResult r = sweep(s, ms[i].X0, ms[i].X1, bunny());
    iters += r.iterations;
    i = (i + 1) % ms.size();
  }
  state.counters["iterations"] = benchmark::Counter(iters, benchmark::Counter::kAvgIterations);
  state.SetLabel(state.range(0) == 0 ? "far" : state.range(0) == 1 ? "approaching" : "resting-sliding");
}
BENCHMARK(BM_BunnySweep)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

void BM_BunnyWindingNumber(benchmark::State& state) {
  static const std::vector<Vec3> points = [] {
    std::vector<Vec3> p;
    Rng rng{12345};
    const Aabb b = bunny().bounds();
    for (int i = 0; i < 1000; ++i)
      p.push_back(rng.inBox(b));
    return p;
  }();
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(bunny().windingNumber(points[i]));
    i = (i + 1) % points.size();
  }
}
BENCHMARK(BM_BunnyWindingNumber)->Unit(benchmark::kMicrosecond);

template <class F>
void perCall(const char* what, int n, F f) {
  std::vector<double> us;
  us.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f(i);
    const auto t1 = std::chrono::steady_clock::now();
    us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  std::sort(us.begin(), us.end());
  std::printf("[figure] %s: median %.2f us, p90 %.2f us, max %.1f us over %d calls\n", what, us[us.size() / 2],
              us[us.size() * 9 / 10], us.back(), n);
}

void perCallFigures() {
  const auto t0 = std::chrono::steady_clock::now();
  const MeshBvh& bvh = bunny();
  const auto t1 = std::chrono::steady_clock::now();
  std::printf("[figure] bunny: %d triangles, BVH built in %.1f ms (first build, incl. cold caches)\n", bvh.triangleCount(),
              std::chrono::duration<double, std::milli>(t1 - t0).count());
  const auto& poses = closePoses();
  const Shape s = phalanx();
  NearTriangle nt;
  std::vector<NearTriangle> out;
  for (int rep = 0; rep < 2; ++rep) {  // first pass warms the caches
    if (rep == 0) {
      for (const Pose& X : poses) bvh.closest(s, X, 0.02, &nt);
      continue;
    }
    perCall("bunny closest() capsule r 8 mm, window 2 cm, 0.2-20 mm away", static_cast<int>(poses.size()),
            [&](int i) { bvh.closest(s, poses[static_cast<size_t>(i)], 0.02, &nt); });
    perCall("bunny near() capsule, max_distance 1 cm", static_cast<int>(poses.size()), [&](int i) {
      out.clear();
      bvh.near(s, poses[static_cast<size_t>(i)], 0.01, &out);
    });
  }
  const char* names[3] = {"far (>= 1 cm)", "approaching (2-6 mm)", "resting 0.1 mm, sliding"};
  for (int kind = 0; kind < 3; ++kind) {
    const auto ms = motions(kind, 500, 10 + static_cast<unsigned>(kind));
    std::vector<int> iters;
    int hits = 0;
    const std::string what = std::string("bunny sweep() phalanx step ") + names[kind];
    perCall(what.c_str(), static_cast<int>(ms.size()), [&](int i) {
      const SweepResult r = sweep(s, ms[static_cast<size_t>(i)].X0, ms[static_cast<size_t>(i)].X1, bvh);
      iters.push_back(r.iterations);
      hits += r.hit;
    });
    std::sort(iters.begin(), iters.end());
    std::printf("[figure]   iterations median %d, max %d; hits %d/%zu\n", iters[iters.size() / 2], iters.back(), hits,
                ms.size());
  }
  Rng rng{12345};
  const Aabb b = bvh.bounds();
  std::vector<Vec3> pts;
  for (int i = 0; i < 1000; ++i)
    pts.push_back(rng.inBox(b));
  perCall("bunny windingNumber() points in the bounding box", 1000, [&](int i) {
    benchmark::DoNotOptimize(bvh.windingNumber(pts[static_cast<size_t>(i)]));
  });
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);  // (--help: prints and exits, before any figure is measured)
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  perCallFigures();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
