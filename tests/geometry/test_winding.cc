// Winding number (hierarchical: exact near, dipole far) against the exact brute-force solid-angle
// sum and analytic inside tests on closed meshes; the bunny (small holes in its base) classifies
// points well inside / outside correctly.
#include <gtest/gtest.h>

#include <algorithm>
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
#include "geometry/bvh.h"

namespace godhand::geo {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Draws are taken one per statement (x, then y, then z): C++ leaves the order of
// function arguments unspecified, so Vec3(draw(), draw(), draw()) gives gcc and
// clang different instances from one seed.
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

TriangleMesh boxMesh(const Vec3& e) {
  TriangleMesh m;
  for (int k = 0; k < 8; ++k) m.vertices.push_back(Vec3((k & 1) ? e.x() : -e.x(), (k & 2) ? e.y() : -e.y(), (k & 4) ? e.z() : -e.z()));
  // Outward counter-clockwise faces.
  m.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                 {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return m;
}

/// Exact generalized winding number: Σ solid angles / 4π (Van Oosterom–Strackee, written here
/// independently of bvh.cc).
double exactWinding(const TriangleMesh& m, const Vec3& p) {
  double sum = 0.0;
  for (int t = 0; t < m.triangleCount(); ++t) {
    const Vec3 a = m.vertex(t, 0) - p, b = m.vertex(t, 1) - p, c = m.vertex(t, 2) - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    sum += 2.0 * std::atan2(a.dot(b.cross(c)), la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb);
  }
  return sum / (4.0 * kPi);
}

/// Inside a closed convex mesh: behind every face plane.
bool insideConvex(const TriangleMesh& m, const Vec3& p) {
  for (int t = 0; t < m.triangleCount(); ++t) {
    const Vec3 a = m.vertex(t, 0), n = (m.vertex(t, 1) - a).cross(m.vertex(t, 2) - a);
    if (n.dot(p - a) > 0.0) return false;
  }
  return true;
}

/// Distance from p to the mesh surface (brute force).
double surfaceDistance(const TriangleMesh& m, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (int t = 0; t < m.triangleCount(); ++t)
    best = std::min(best, pointTriangleDistance(p, m.vertex(t, 0), m.vertex(t, 1), m.vertex(t, 2), nullptr));
  return best;
}

void checkConvex(const char* name, const TriangleMesh& m, Rng& rng, int points, double* max_err) {
  const MeshBvh bvh(m);
  const Aabb b = bvh.bounds().inflated(0.5 * bvh.bounds().extent().maxCoeff());
  int classified = 0;
  for (int i = 0; i < points; ++i) {
    const double x = rng.uniform(b.lo.x(), b.hi.x());
    const double y = rng.uniform(b.lo.y(), b.hi.y());
    const double z = rng.uniform(b.lo.z(), b.hi.z());
    const Vec3 p(x, y, z);
    const double fast = bvh.windingNumber(p), exact = exactWinding(m, p);
    *max_err = std::max(*max_err, std::abs(fast - exact));
    EXPECT_NEAR(fast, exact, 0.1) << name;  // far-field dipoles (2nd order) at β = 2: a few %
    const bool in = insideConvex(m, p);
    EXPECT_NEAR(exact, in ? 1.0 : 0.0, 1e-9) << name;  // closed mesh: the exact sum is an integer
    if (surfaceDistance(m, p) > 1e-3 * bvh.bounds().extent().maxCoeff()) {
      EXPECT_EQ(bvh.inside(p), in) << name << " w " << fast;
      ++classified;
    }
  }
  EXPECT_GT(classified, points / 2);
}

TEST(Winding, ClosedMeshesMatchExactAndAnalytic) {
  Rng rng(30);
  double max_err = 0.0;
  checkConvex("icosphere", icosphere(0.05, 3), rng, 400, &max_err);
  checkConvex("box", boxMesh(Vec3(0.02, 0.05, 0.01)), rng, 400, &max_err);
  for (int k = 0; k < 6; ++k) {
    // Random convex polytopes: icospheres under random affine maps (convexity is preserved).
    TriangleMesh m = icosphere(1.0, 1 + k % 2);
    Mat3 A = Mat3::Random() * 0.05;
    if (A.determinant() < 0) A.col(0) *= -1.0;  // keep the orientation outward
    if (std::abs(A.determinant()) < 1e-6) A += 0.03 * Mat3::Identity();
    const Vec3 offset = 0.1 * rng.direction();
    for (auto& v : m.vertices) v = A * v + offset;
    checkConvex("affine icosphere", m, rng, 150, &max_err);
  }
  std::printf("[figure] winding closed meshes: max |fast - exact| %.3g\n", max_err);
}

TEST(Winding, NearTheSurfaceStaysClose) {
  // Points within 1 mm of a fine icosphere (exact near field is what makes this accurate).
  const TriangleMesh m = icosphere(0.05, 4);
  const MeshBvh bvh(m);
  Rng rng(31);
  double max_err = 0.0;
  for (int i = 0; i < 200; ++i) {
    const Vec3 dir = rng.direction();
    const double r = 0.05 + rng.uniform(-0.001, 0.001);
    const Vec3 p = r * dir;
    const double fast = bvh.windingNumber(p), exact = exactWinding(m, p);
    max_err = std::max(max_err, std::abs(fast - exact));
    EXPECT_NEAR(fast, exact, 0.1);
  }
  std::printf("[figure] winding within 1 mm of a 5120-triangle sphere: max |fast - exact| %.3g\n", max_err);
}

TEST(Winding, BunnyInsideOutside) {
  static const MeshBvh bvh(loadObj(GODHAND_DEPLOY_DIR "/meshes/stanford-bunny.obj"));
  const TriangleMesh& m = bvh.mesh();
  Rng rng(32);
  const Aabb b = bvh.bounds();
  double max_err = 0.0;
  int well_in = 0, well_out = 0, agree = 0, total = 0;
  for (int i = 0; i < 120; ++i) {
    const double x = rng.uniform(b.lo.x(), b.hi.x());
    const double y = rng.uniform(b.lo.y(), b.hi.y());
    const double z = rng.uniform(b.lo.z(), b.hi.z());
    const Vec3 p(x, y, z);
    const double fast = bvh.windingNumber(p), exact = exactWinding(m, p);
    max_err = std::max(max_err, std::abs(fast - exact));
    EXPECT_NEAR(fast, exact, 0.1);
    if (surfaceDistance(m, p) < 0.003) continue;  // only points well inside / outside
    ++total;
    // Well inside: exact w near 1; well outside: near 0 (holes only shift it slightly).
    EXPECT_TRUE(exact > 0.8 || exact < 0.2) << "exact " << exact;
    const bool in = exact > 0.5;
    well_in += in;
    well_out += !in;
    agree += bvh.inside(p) == in;
  }
  // Far outside the bounding box: 0.
  for (int i = 0; i < 20; ++i) EXPECT_NEAR(bvh.windingNumber(b.centre() + 0.5 * rng.direction()), 0.0, 0.02);
  std::printf("[figure] winding bunny: max |fast - exact| %.3g; %d/%d well-inside/outside points classified as the exact "
              "winding number does (%d inside, %d outside)\n",
              max_err, agree, total, well_in, well_out);
  EXPECT_EQ(agree, total);
  EXPECT_GT(well_in, 5);
}

}  // namespace
}  // namespace godhand::geo
