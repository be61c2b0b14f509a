// Conservative advancement against fine sampling of the motion with exact distances: the toc is
// never later than the first time the shape comes within η of the mesh (so never later than
// contact), d(toc) ≥ η − tolerance, and a hit is not absurdly early. Random motions (translation
// and fast rotation) of all three shapes against 0.1 mm thin shells, spheres, needle soups and the
// bunny; distances from brute force over all triangles or from the BVH (itself tested against
// brute force in test_bvh.cc).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>

#include "../test_rng.h"
#include "common/files.h"
#include "scene/mesh_io.h"
#include "geometry/sweep.h"
#include "../test_sanitized.h"

namespace godhand::geo {
namespace {

// The sanitizer build runs a third of the random motions (test_sanitized.h).
constexpr int kMotionDivisor = test_support::kSanitized ? 3 : 1;

// Draws are taken one per statement (x, then y, then z): C++ leaves the order of
// function arguments and of a binary operator's operands unspecified, so
// Vec3(draw(), draw(), draw()) or draw() * draw() gives gcc and clang different
// instances from one seed.
using test_support::Rng;

// The project's OBJ reader (core/scene/mesh_io), so the tests read the bunny as scenes do.
TriangleMesh loadObj(const std::string& path) { return godhand::loadMeshFile(path); }

TriangleMesh icosphere(double radius, int subdivisions) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  m.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::vector<std::array<int, 3>> next;
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      m.vertices.push_back(0.5 * (m.vertices[static_cast<size_t>(a)] + m.vertices[static_cast<size_t>(b)]));
      mid[key] = static_cast<int>(m.vertices.size()) - 1;
      return mid[key];
    };
    for (const auto& f : m.triangles) {
      const int a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
      next.push_back({f[0], a, c});
      next.push_back({f[1], b, a});
      next.push_back({f[2], c, b});
      next.push_back({a, b, c});
    }
    m.triangles = next;
  }
  for (auto& v : m.vertices) v = radius * v.normalized();
  return m;
}

TriangleMesh thinShell(int n, double size, double thickness) {
  TriangleMesh m;
  for (int side = 0; side < 2; ++side) {
    const int base = static_cast<int>(m.vertices.size());
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j)
        m.vertices.push_back(Vec3(size * (i / double(n) - 0.5), size * (j / double(n) - 0.5), side * thickness));
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        const int a = base + i * (n + 1) + j, b = a + n + 1, c = b + 1, d = a + 1;
        if (side == 1) { m.triangles.push_back({a, b, c}); m.triangles.push_back({a, c, d}); }
        else { m.triangles.push_back({a, c, b}); m.triangles.push_back({a, d, c}); }
      }
    }
  }
  return m;
}

/// Random triangles of 2–20 mm plus needles (zero-area and 1e-9-wide) in a 6 cm cube.
TriangleMesh needleSoup(Rng& rng, int n) {
  TriangleMesh m;
  for (int t = 0; t < n; ++t) {
    const double ax = rng.uniform(-1, 1);
    const double ay = rng.uniform(-1, 1);
    const double az = rng.uniform(-1, 1);
    const Vec3 a = 0.03 * Vec3(ax, ay, az);
    const Vec3 dir = rng.direction();
    const double len = rng.uniform(0.002, 0.02);
    const int base = static_cast<int>(m.vertices.size());
    m.vertices.push_back(a);
    m.vertices.push_back(a + len * dir);
    const int kind = rng.integer(0, 2);
    const Vec3 side = kind == 0 ? Vec3(len * rng.direction()) : Vec3((kind == 1 ? 0.0 : 1e-9 * len) * dir.unitOrthogonal());
    m.vertices.push_back(a + rng.uniform(0, 1) * len * dir + side);
    m.triangles.push_back({base, base + 1, base + 2});
  }
  return m;
}

const MeshBvh& bunny() {
  static const MeshBvh bvh(loadObj(GODHAND_DEPLOY_DIR "/meshes/stanford-bunny.obj"));
  return bvh;
}

Shape randomShape(Rng& rng, int i) {
  Shape s;
  s.type = static_cast<ShapeType>(i % 3);
  s.radius = rng.uniform(0.002, 0.01);
  s.half_length = rng.uniform(0.005, 0.02);
  const double ex = rng.uniform(0.002, 0.012);
  const double ey = rng.uniform(0.002, 0.012);
  const double ez = rng.uniform(0.001, 0.012);
  s.half_extents = Vec3(ex, ey, ez);
  return s;
}

/// Exact distance of the shape at X to the mesh (≥ `far` reported as `far`).
struct Oracle {
  const MeshBvh* bvh = nullptr;
  bool brute = false;
  static constexpr double kFar = 0.001;  // beyond: reported as 1 mm (≫ η)
  double operator()(const Shape& s, const Pose& X) const {
    if (brute) {
      double best = kFar;
      const TriangleMesh& m = bvh->mesh();
      for (int t = 0; t < m.triangleCount(); ++t)
        best = std::min(best, shapeTriangle(s, X, m.vertex(t, 0), m.vertex(t, 1), m.vertex(t, 2)).distance);
      return best;
    }
    NearTriangle nt;
    return bvh->closest(s, X, kFar, &nt) ? nt.closest.distance : kFar;
  }
};

struct Stats {
  int motions = 0, hits = 0, started_inside = 0, capped = 0, no_reach_after_hit = 0;
  std::vector<int> iterations;
  std::vector<double> gaps;        ///< sampled first time of reaching η − toc, for hits
  std::vector<double> us;
  double min_margin = std::numeric_limits<double>::infinity();  ///< min over s ≤ toc of d(s) − η
  void print(const char* name) {
    std::sort(iterations.begin(), iterations.end());
    std::sort(gaps.begin(), gaps.end());
    std::sort(us.begin(), us.end());
    std::printf("[figure] sweep %s: %d motions, %d hits (%d capped), %d started inside; iterations median %d max %d; "
                "toc gap to sampled first η-time median %.2e max %.2e (step fraction); min d(s)-η for s<=toc %.2e m; "
                "%.2f us/sweep median\n",
                name, motions, hits, capped, started_inside, iterations.empty() ? 0 : iterations[iterations.size() / 2],
                iterations.empty() ? 0 : iterations.back(), gaps.empty() ? 0.0 : gaps[gaps.size() / 2],
                gaps.empty() ? 0.0 : gaps.back(), min_margin, us.empty() ? 0.0 : us[us.size() / 2]);
  }
};

/// Sweeps X0 → X1 and checks it against N samples (+ bisection) of the exact distance.
void checkMotion(const Shape& s, const Pose& X0, const Pose& X1, const MeshBvh& bvh, const Oracle& dist, Stats* st,
                 const SweepParams& params = {}, int samples = 2000) {
  const auto t0 = std::chrono::steady_clock::now();
  const SweepResult r = sweep(s, X0, X1, bvh, params);
  const auto t1 = std::chrono::steady_clock::now();
  st->us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  ++st->motions;
  const double d0 = dist(s, X0);
  ASSERT_GE(r.toc, 0.0);
  ASSERT_LE(r.toc, 1.0);
  auto d = [&](double t) { return dist(s, interpolateMotion(X0, X1, t)); };
  if (r.started_inside) {  // only a core touching the surface: nothing can be said
    EXPECT_LE(d0, 0.0);
    EXPECT_EQ(r.toc, 0.0);
    ++st->started_inside;
    return;
  }
  if (d0 <= 0.0) {
    // The shell overlaps the surface, the core does not: the motion may recede or slide, never
    // go deeper (by more than the advancement's 1e-9 m per iteration).
    for (int j = 1; j <= samples; ++j) {
      const double t = r.toc * j / samples;
      ASSERT_GE(d(t), d0 - 1e-7) << "deeper than it started: t " << t << " toc " << r.toc << " d0 " << d0;
    }
    ++st->started_inside;
    return;
  }
  st->iterations.push_back(r.iterations);
  // η and the tolerance as sweep.h states them: η never below the floor; below it (d0 <= η)
  // the body may not come closer than it is.
  const double eta = std::min(params.stop_distance, std::max(params.min_stop_distance, 0.5 * d0));
  const double tol = d0 > eta ? std::min(params.tolerance, 0.5 * (d0 - eta)) : 0.0;
  const double floor_d = d0 > eta ? eta - tol - 1e-12 : d0 - 1e-7;
  // Every sample before toc (and toc itself) keeps at least η − tolerance.
  double prev_t = 0.0, prev_d = d0;
  double first_eta = -1.0;  // sampled (and refined) first time with d ≤ η
  for (int j = 1; j <= samples; ++j) {
    const double t = r.toc * j / samples;
    const double dt = d(t);
    st->min_margin = std::min(st->min_margin, dt - eta);
    ASSERT_GE(dt, 0.0) << "contact before toc: t " << t << " toc " << r.toc;
    ASSERT_GE(dt, floor_d) << "closer than η before toc: t " << t << " toc " << r.toc << " d " << dt;
    prev_t = t;
    prev_d = dt;
  }
  // (At toc = 0 too: a hit at once from a clear start is checked against d(0), not the sweep's
  // own figure.)
  if (r.distance < Oracle::kFar) {
    EXPECT_NEAR(r.distance, d(r.toc), 1e-12);
  }
  // After toc: find the first time the distance reaches η (sampling at the same density, then
  // bisection around the sign change).
  const int after = std::max(1, static_cast<int>(std::ceil((1.0 - r.toc) * samples)));
  for (int j = 1; j <= after && first_eta < 0.0; ++j) {
    const double t = std::min(1.0, r.toc + (1.0 - r.toc) * j / after);
    const double dt = d(t);
    if (dt <= eta) {
      double lo = prev_t, hi = t;
      for (int k = 0; k < 50; ++k) {
        const double m = 0.5 * (lo + hi);
        (d(m) <= eta ? hi : lo) = m;
      }
      first_eta = hi;
    }
    prev_t = t;
    prev_d = dt;
  }
  (void)prev_d;
  if (r.hit) {
    ++st->hits;
    if (r.capped) {
      ++st->capped;
      EXPECT_LT(r.toc, 1.0);
    } else {
      // Terminated within the tolerance of η.
      EXPECT_LE(r.distance, eta + tol + 1e-12);
      if (first_eta >= 0.0) st->gaps.push_back(first_eta - r.toc);
      else ++st->no_reach_after_hit;  // reached η + tol at toc, then moved away
    }
  } else {
    EXPECT_EQ(r.toc, 1.0);
    EXPECT_LT(first_eta, 0.0) << "the motion reaches η at " << first_eta << " but the sweep reports no hit";
  }
}

struct MotionSpec {
  double max_translation = 0.015;
  double max_rotation = 1.5;
};

/// A start pose near a random surface point (−3 .. +20 mm along its normal), a motion biased
/// towards the surface, tangential, or random, with rotation up to max_rotation.
void randomMotion(Rng& rng, const TriangleMesh& m, const MotionSpec& spec, Pose* X0, Pose* X1) {
  const int t = rng.integer(0, m.triangleCount() - 1);
  double u = rng.uniform(0, 1), v = rng.uniform(0, 1);
  if (u + v > 1) { u = 1 - u; v = 1 - v; }
  const Vec3 a = m.vertex(t, 0), b = m.vertex(t, 1), c = m.vertex(t, 2);
  Vec3 n = (b - a).cross(c - a);
  n = n.norm() > 0 ? Vec3(n.normalized()) : rng.direction();
  X0->p = a + u * (b - a) + v * (c - a) + rng.uniform(-0.003, 0.02) * n;
  X0->q = rng.rotation();
  Vec3 step;
  switch (rng.integer(0, 2)) {
    case 0: {
      const double toward = rng.uniform(0.0, spec.max_translation);
      const double jitter = rng.uniform(0, 1);
      step = -toward * n + 0.3 * spec.max_translation * jitter * rng.direction();
      break;
    }
    case 1: {
      const double length = rng.uniform(0.2, 1.0);
      step = spec.max_translation * length * rng.direction().cross(n);
      break;
    }
    default: {
      const double length = rng.uniform(0.0, 1.0);
      step = spec.max_translation * length * rng.direction();
      break;
    }
  }
  X1->p = X0->p + step;
  const double angle = rng.uniform(0.0, spec.max_rotation);
  X1->q = expRotation(angle * rng.direction()) * X0->q;
}

void runRandomMotions(const char* name, const MeshBvh& bvh, int count, unsigned seed, bool brute_every_50th,
                      const MotionSpec& spec = {}, const SweepParams& params = {}) {
  Rng rng(seed);
  Stats st;
  Oracle fast{&bvh, false}, brute{&bvh, true};
  count /= kMotionDivisor;
  for (int i = 0; i < count; ++i) {
    const Shape s = randomShape(rng, i);
    Pose X0, X1;
    // Mostly starts clear of the mesh (a few penetrating starts check started_inside).
    for (int attempt = 0; attempt < 20; ++attempt) {
      randomMotion(rng, bvh.mesh(), spec, &X0, &X1);
      if (i % 20 == 0 || fast(s, X0) > 0.0) break;
    }
    checkMotion(s, X0, X1, bvh, brute_every_50th && i % 50 == 0 ? brute : fast, &st, params);
    if (::testing::Test::HasFatalFailure()) {
      std::printf("motion %d shape %d failed\n", i, static_cast<int>(s.type));
      return;
    }
  }
  st.print(name);
  EXPECT_GT(st.hits, count / 8);  // the motion mix really exercises contact
}

// d(0) handed over from a contact query (SweepStart) changes nothing but the work: on random
// motions near the bunny, with the start queried at a range below, at and above the sweep's own
// window (found, or nothing within a range that covers the window), the result equals the
// sweep's own (toc, hit, inside, distance bit for bit), also where the iteration cap ends it (the
// handed-over query counts against the cap); a start that cannot answer (nothing within a
// smaller range) is not used.
TEST(Sweep, AHandedOverStartGivesTheSameResult) {
  Rng rng(4242);
  const MeshBvh& bvh = bunny();
  SweepParams params;
  params.exact_distance = false;  // as the pipeline sweeps
  int used = 0, hits = 0, capped = 0;
  for (int i = 0; i < 600 / kMotionDivisor; ++i) {
    params.max_iterations = i % 2 ? 100 : 3;
    const Shape s = randomShape(rng, i);
    Pose X0, X1;
    randomMotion(rng, bvh.mesh(), MotionSpec{}, &X0, &X1);
    const SweepResult own = sweep(s, X0, X1, bvh, params);
    const double mu = (X1.p - X0.p).norm() + logRotation(X1.q * X0.q.conjugate()).norm() * boundingRadius(s);
    const double window = mu + params.stop_distance;
    for (const double range : {0.25 * window, window, 4.0 * window + 0.01}) {
      SweepStart start;
      start.range = range;
      start.found = bvh.closest(s, X0, range, &start.nearest);
      const SweepResult r = sweep(s, X0, X1, bvh, params, &start);
      ASSERT_EQ(r.toc, own.toc) << i << " range " << range;
      ASSERT_EQ(r.hit, own.hit) << i;
      ASSERT_EQ(r.started_inside, own.started_inside) << i;
      ASSERT_EQ(r.capped, own.capped) << i;
      ASSERT_TRUE(r.distance == own.distance || (std::isnan(r.distance) && std::isnan(own.distance))) << i;
      const bool answers = start.found || range >= window;
      // One query fewer when it answered (the handed-over one), the same count when it could not.
      EXPECT_EQ(r.iterations, own.iterations - (answers ? 1 : 0)) << i;
      used += answers ? 1 : 0;
    }
    hits += own.hit ? 1 : 0;
    capped += own.capped ? 1 : 0;
  }
  std::printf("[figure] handed-over starts used %d, hits %d, capped %d\n", used, hits, capped);
  EXPECT_GT(hits, 10);
  EXPECT_GT(capped, 5);
  EXPECT_GT(used, 100);
}

TEST(Sweep, InterpolateMotionEndpointsAndMotionBound) {
  Rng rng(20);
  for (int i = 0; i < 200; ++i) {
    Pose X0, X1;
    X0.p = 0.1 * rng.direction();
    X0.q = rng.rotation();
    X1.p = X0.p + 0.02 * rng.direction();
    const double angle = rng.uniform(0, 3.0);
    X1.q = expRotation(angle * rng.direction()) * X0.q;
    const Pose A = interpolateMotion(X0, X1, 0.0), B = interpolateMotion(X0, X1, 1.0);
    EXPECT_LT((A.p - X0.p).norm(), 1e-15);
    EXPECT_NEAR(std::abs(A.q.dot(X0.q)), 1.0, 1e-12);
    EXPECT_LT((B.p - X1.p).norm(), 1e-15);
    EXPECT_NEAR(std::abs(B.q.dot(X1.q)), 1.0, 1e-12);
    // Constant angular velocity: equal rotation angle between equal time steps.
    const double a1 = logRotation(interpolateMotion(X0, X1, 0.3).q * interpolateMotion(X0, X1, 0.1).q.conjugate()).norm();
    const double a2 = logRotation(interpolateMotion(X0, X1, 0.9).q * interpolateMotion(X0, X1, 0.7).q.conjugate()).norm();
    EXPECT_NEAR(a1, a2, 1e-12);
    // μ = |Δp| + |θ| ρ bounds the path length of every point within ρ of the origin.
    const Shape s = randomShape(rng, i);
    const double rho = boundingRadius(s);
    const double mu = (X1.p - X0.p).norm() + logRotation(X1.q * X0.q.conjugate()).norm() * rho;
    const Vec3 x_B = rho * rng.direction();
    double path = 0.0;
    Vec3 prev = X0 * x_B;
    for (int k = 1; k <= 200; ++k) {
      const Vec3 x = interpolateMotion(X0, X1, k / 200.0) * x_B;
      path += (x - prev).norm();
      prev = x;
    }
    EXPECT_LE(path, mu * (1 + 1e-12));
  }
}

TEST(Sweep, RandomMotionsAgainstThinShell) {
  const MeshBvh shell(thinShell(12, 0.12, 1e-4));
  runRandomMotions("thin shell 0.1 mm", shell, 300, 21, true);
}

TEST(Sweep, RandomMotionsAgainstSphere) {
  const MeshBvh sphere(icosphere(0.03, 2));
  runRandomMotions("icosphere", sphere, 200, 22, true);
}

TEST(Sweep, RandomMotionsAgainstNeedleSoup) {
  Rng rng(23);
  const MeshBvh soup(needleSoup(rng, 150));
  runRandomMotions("needle soup", soup, 300, 24, true);
}

TEST(Sweep, RandomMotionsAgainstBunny) {
  runRandomMotions("bunny", bunny(), 200, 25, false);
  MotionSpec slow;
  slow.max_translation = 0.01;
  slow.max_rotation = 0.3;
  runRandomMotions("bunny phalanx steps (1 cm, 0.3 rad)", bunny(), 150, 26, false, slow);
}

TEST(Sweep, PlainAdvancementRandomMotions) {
  // The global-μ advancement (SweepParams::directional = false) under the same checks.
  SweepParams plain;
  plain.directional = false;
  const MeshBvh shell(thinShell(12, 0.12, 1e-4));
  runRandomMotions("plain CA, thin shell 0.1 mm", shell, 100, 31, true, {}, plain);
  Rng rng(33);
  const MeshBvh soup(needleSoup(rng, 150));
  runRandomMotions("plain CA, needle soup", soup, 100, 34, true, {}, plain);
  MotionSpec slow;
  slow.max_translation = 0.01;
  slow.max_rotation = 0.3;
  runRandomMotions("plain CA, bunny phalanx steps", bunny(), 80, 35, false, slow, plain);
}

TEST(Sweep, ThinShellCrossedAt10MetresPerSecond) {
  // 1 cm per 1 ms step straight through a 0.1 mm shell: the end pose is clear on the far side,
  // so only the sweep can see the crossing.
  const MeshBvh shell(thinShell(4, 0.2, 1e-4));
  Oracle brute{&shell, true}, fast{&shell, false};
  Stats st;
  for (int t = 0; t < 3; ++t) {
    for (int k = 0; k < 20; ++k) {
      Shape s;
      s.type = static_cast<ShapeType>(t);
      s.radius = 0.002;
      s.half_length = 0.001;
      s.half_extents = Vec3(0.002, 0.002, 0.001);
      Pose X0, X1;
      X0.p = Vec3(0.003 * k - 0.03, 0.001 * k, 0.0045);
      X0.q = expRotation(Vec3(0.05 * k, 0.0, 0.0));
      X1.p = X0.p - Vec3(0.0, 0.0, 0.01);
      X1.q = expRotation(Vec3(0.0, 0.3, 0.01 * k)) * X0.q;
      const double d1 = brute(s, X1);
      ASSERT_GT(d1, 0.0) << "the end pose must be clear of the shell";
      SweepParams params;
      params.directional = k % 2 == 0;
      const SweepResult r = sweep(s, X0, X1, shell, params);
      EXPECT_TRUE(r.hit);
      EXPECT_LT(r.toc, 0.5);
      checkMotion(s, X0, X1, shell, k % 10 == 0 ? brute : fast, &st, params);
    }
  }
  st.print("0.1 mm shell crossed at 10 m/s");
  EXPECT_EQ(st.hits, 60);
}

TEST(Sweep, StartedInsideAndNoMotion) {
  const MeshBvh sphere(icosphere(0.03, 2));
  Shape s;
  s.type = ShapeType::Sphere;
  s.radius = 0.005;
  Pose X0;
  X0.p = Vec3(0.0, 0.0, 0.031);  // the shell overlaps the surface, the core (centre) is outside
  Pose X1 = X0;
  X1.p.z() += 0.01;               // receding: free to go
  SweepResult r = sweep(s, X0, X1, sphere);
  EXPECT_FALSE(r.started_inside);
  EXPECT_EQ(r.toc, 1.0);
  X1.p.z() = 0.030;               // going deeper: stopped where it is
  r = sweep(s, X0, X1, sphere);
  EXPECT_FALSE(r.started_inside);
  EXPECT_TRUE(r.hit);
  EXPECT_EQ(r.toc, 0.0);
  EXPECT_LT(r.distance, 0.0);
  // A capsule whose core crosses the surface: inside, nothing can be said.
  Shape c;
  c.type = ShapeType::Capsule;
  c.radius = 0.002;
  c.half_length = 0.01;
  Pose Xc;
  Xc.p = Vec3(0.0, 0.0, 0.03);
  r = sweep(c, Xc, Xc, sphere);
  EXPECT_TRUE(r.started_inside);
  EXPECT_EQ(r.toc, 0.0);
  // Resting 0.1 mm above, not moving: toc 1, no hit.
  X0.p = Vec3(0.0, 0.0, 0.0351);
  r = sweep(s, X0, X0, sphere);
  EXPECT_FALSE(r.hit);
  EXPECT_EQ(r.toc, 1.0);
  // Far away: a single query, toc 1, distance +inf (nothing within reach).
  X0.p = Vec3(0.0, 0.0, 0.2);
  X1 = X0;
  X1.p.x() += 0.01;
  r = sweep(s, X0, X1, sphere);
  EXPECT_FALSE(r.hit);
  EXPECT_EQ(r.toc, 1.0);
  EXPECT_EQ(r.iterations, 1);
  EXPECT_TRUE(std::isinf(r.distance));
}

TEST(Sweep, IterationCapIsConservative) {
  const MeshBvh sphere(icosphere(0.03, 2));
  Oracle fast{&sphere, false};
  Stats st;
  SweepParams params;
  params.max_iterations = 2;
  Rng rng(27);
  int capped = 0;
  for (int i = 0; i < 40; ++i) {
    Shape s = randomShape(rng, i);
    Pose X0, X1;
    X0.p = Vec3(0.0, 0.0, 0.05);
    X0.q = rng.rotation();
    X1.p = Vec3(0.001, 0.0, 0.025);
    const double angle = rng.uniform(0, 1.0);
    X1.q = expRotation(angle * rng.direction()) * X0.q;
    const SweepResult r = sweep(s, X0, X1, sphere, params);
    capped += r.capped;
    if (r.capped) { EXPECT_TRUE(r.hit); EXPECT_LT(r.toc, 1.0); }
    checkMotion(s, X0, X1, sphere, fast, &st, params, 1000);
  }
  EXPECT_GT(capped, 10);
}

TEST(Sweep, RestingAndSlidingMakesProgress) {
  // A capsule resting 0.1 mm above the shell slides 1 cm tangentially (rotating up to 0.3 rad).
  const MeshBvh shell(thinShell(20, 0.2, 1e-4));
  Oracle fast{&shell, false};
  Stats st;
  Rng rng(28);
  std::vector<double> tocs, plain_tocs;
  std::vector<int> plain_iterations;
  for (int i = 0; i < 60; ++i) {
    Shape s;
    s.type = ShapeType::Capsule;
    s.radius = 0.008;
    s.half_length = 0.015;
    Pose X0, X1;
    X0.q = expRotation(Vec3(0.0, 1.5707963267948966, 0.0)) * expRotation(Vec3(0.0, 0.0, rng.uniform(0, 3)));
    X0.p = Vec3(0.0, 0.0, 1e-4 + 0.008 + 1e-4);
    X1.p = X0.p + 0.01 * Vec3(std::cos(i), std::sin(i), 0.0);
    X1.q = expRotation(rng.uniform(0, 0.3) * Vec3(0, 0, 1)) * X0.q;
    const SweepResult r = sweep(s, X0, X1, shell);
    tocs.push_back(r.toc);
    checkMotion(s, X0, X1, shell, fast, &st);
    SweepParams plain_params;
    plain_params.directional = false;
    const SweepResult p = sweep(s, X0, X1, shell, plain_params);
    plain_tocs.push_back(p.toc);
    plain_iterations.push_back(p.iterations);
    EXPECT_GE(r.toc, p.toc);  // on a flat surface the directional bound is never worse
  }
  std::sort(tocs.begin(), tocs.end());
  std::sort(plain_tocs.begin(), plain_tocs.end());
  std::sort(plain_iterations.begin(), plain_iterations.end());
  std::printf("[figure] resting 0.1 mm and sliding 1 cm (rotating <= 0.3 rad about the normal): directional toc median %.3f "
              "min %.3f; plain CA toc median %.3f min %.3f, iterations median %d\n",
              tocs[tocs.size() / 2], tocs.front(), plain_tocs[plain_tocs.size() / 2], plain_tocs.front(),
              plain_iterations[plain_iterations.size() / 2]);
  st.print("directional, resting and sliding on the shell");
  EXPECT_EQ(tocs.front(), 1.0);  // sliding parallel to a plane is never stopped
}

TEST(Sweep, PalmTurningOverACurvedSurfaceKeepsItsStride) {
  // A palm-sized box (8 x 8 x 2 cm) resting 60 µm above a sphere (r = 5 cm) turns up to 0.06 rad
  // about a tangential axis through its centre while it slides 2 mm. Along the mesh-fixed axis
  // the far corners dip (ρ|θ| ≈ 2.5 mm per step), which made the sweep creep in steps of 1-2 %
  // of the motion until its iteration cap (a stop that is no contact: a frozen palm); along the
  // body-fixed axis the triangles under the palm hardly move. Where the sampled motion never
  // comes within 2η, the sweep must let the whole motion through, in a few iterations.
  const MeshBvh ball(icosphere(0.05, 4));
  Oracle fast{&ball, false};
  Stats st;
  Rng rng(41);
  Shape box;
  box.type = ShapeType::Box;
  box.half_extents = Vec3(0.04, 0.04, 0.01);
  const SweepParams params;
  std::vector<int> iterations;
  int free_motions = 0;
  for (int i = 0; i < 40; ++i) {
    Pose X0, X1;
    X0.q = expRotation(Vec3(0, 0, rng.uniform(0, 3)));
    X0.p = Vec3(0, 0, 0.05 + 0.01 + 6e-5);
    const Vec3 axis = Vec3(std::cos(0.7 * i), std::sin(0.7 * i), 0.0);
    X1.q = expRotation(rng.uniform(0.01, 0.06) * axis) * X0.q;
    X1.p = X0.p + 0.002 * Vec3(-std::sin(0.3 * i), std::cos(0.3 * i), 0.0);
    checkMotion(box, X0, X1, ball, fast, &st, params);
    double d_min = fast(box, X0);
    for (int k = 1; k <= 400; ++k) d_min = std::min(d_min, fast(box, interpolateMotion(X0, X1, k / 400.0)));
    if (!(d_min > 2.0 * params.stop_distance)) continue;
    ++free_motions;
    const SweepResult r = sweep(box, X0, X1, ball, params);
    EXPECT_FALSE(r.hit) << "motion " << i << " never comes within " << d_min << " m";
    EXPECT_EQ(r.toc, 1.0);
    iterations.push_back(r.iterations);
  }
  ASSERT_GE(free_motions, 10) << "the mix must have free motions to judge";
  std::sort(iterations.begin(), iterations.end());
  std::printf("[figure] palm turning over a sphere: %d free motions, iterations median %d max %d\n", free_motions,
              iterations[iterations.size() / 2], iterations.back());
  st.print("palm turning over a sphere");
  EXPECT_LE(iterations.back(), 12);
}

}  // namespace
}  // namespace godhand::geo
