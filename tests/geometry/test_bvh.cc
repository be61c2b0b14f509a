// MeshBvh queries against brute force over every triangle (and FCL on the bunny): the BVH must
// return exactly the brute-force minimum on triangle soups, spheres, 0.1 mm double-sided shells,
// needle triangles and the 69k-triangle scanned bunny.
#include <gtest/gtest.h>

#include <fcl/fcl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>

#include "../test_rng.h"
#include "common/files.h"
#include "scene/mesh_io.h"
#include "geometry/bvh.h"

namespace godhand::geo {
namespace {

// Draws are taken one per statement (x, then y, then z): C++ leaves the order of
// function arguments and of a binary operator's operands unspecified, so
// Vec3(draw(), draw(), draw()) gives gcc and clang different instances from one seed.
using test_support::Rng;

// The project's OBJ reader (core/scene/mesh_io), so the tests read the bunny as scenes do.
TriangleMesh loadObj(const std::string& path) { return godhand::loadMeshFile(path); }

const MeshBvh& bunny() {
  static const MeshBvh bvh(loadObj(GODHAND_DEPLOY_DIR "/meshes/stanford-bunny.obj"));
  return bvh;
}

TriangleMesh soup(Rng& rng, int n, double half, double size) {
  TriangleMesh m;
  for (int t = 0; t < n; ++t) {
    const Vec3 c = rng.vec(half);
    const int base = static_cast<int>(m.vertices.size());
    for (int k = 0; k < 3; ++k) m.vertices.push_back(c + rng.vec(size));
    m.triangles.push_back({base, base + 1, base + 2});
  }
  return m;
}

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
      const int i = static_cast<int>(m.vertices.size()) - 1;
      mid[key] = i;
      return i;
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

/// Two n×n grids 0.1 mm apart, facing away from each other (a thin closed-ish double-sided sheet).
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
        if (side == 1) {
          m.triangles.push_back({a, b, c});
          m.triangles.push_back({a, c, d});
        } else {
          m.triangles.push_back({a, c, b});
          m.triangles.push_back({a, d, c});
        }
      }
    }
  }
  return m;
}

TriangleMesh needles(Rng& rng, int n) {
  TriangleMesh m;
  for (int t = 0; t < n; ++t) {
    const Vec3 a = rng.vec(0.05), dir = rng.vec(1.0).normalized();
    const double len = rng.uniform(0.005, 0.05);
    const int base = static_cast<int>(m.vertices.size());
    m.vertices.push_back(a);
    m.vertices.push_back(a + len * dir);
    const double w = rng.integer(0, 1) ? 0.0 : 1e-9 * len;
    m.vertices.push_back(a + rng.uniform(0, 1) * len * dir + w * dir.unitOrthogonal());
    m.triangles.push_back({base, base + 1, base + 2});
  }
  return m;
}

Shape randomShape(Rng& rng, int i) {
  Shape s;
  s.type = static_cast<ShapeType>(i % 3);
  s.radius = rng.uniform(0.003, 0.01);
  s.half_length = rng.uniform(0.005, 0.02);
  const double ex = rng.uniform(0.002, 0.015);
  const double ey = rng.uniform(0.002, 0.015);
  const double ez = rng.uniform(0.002, 0.015);
  s.half_extents = Vec3(ex, ey, ez);
  return s;
}

/// A pose near the mesh: a random surface point pushed along its normal by −5 mm .. +20 mm.
Pose nearSurfacePose(Rng& rng, const TriangleMesh& mesh, double lo = -0.005, double hi = 0.02) {
  const int t = rng.integer(0, mesh.triangleCount() - 1);
  double u = rng.uniform(0, 1), v = rng.uniform(0, 1);
  if (u + v > 1) { u = 1 - u; v = 1 - v; }
  const Vec3 a = mesh.vertex(t, 0), b = mesh.vertex(t, 1), c = mesh.vertex(t, 2);
  Vec3 n = (b - a).cross(c - a);
  n = n.norm() > 0 ? Vec3(n.normalized()) : Vec3::UnitZ();
  Pose X;
  X.p = a + u * (b - a) + v * (c - a) + rng.uniform(lo, hi) * n;
  X.q = rng.rotation();
  return X;
}

struct Brute {
  double distance = std::numeric_limits<double>::infinity();
  int triangle = -1;
};

Brute bruteClosest(const Shape& s, const Pose& X, const TriangleMesh& mesh) {
  Brute b;
  for (int t = 0; t < mesh.triangleCount(); ++t) {
    const double d = shapeTriangle(s, X, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)).distance;
    if (d < b.distance) { b.distance = d; b.triangle = t; }
  }
  return b;
}

void checkAgainstBruteForce(const char* name, const TriangleMesh& mesh, Rng& rng, int queries) {
  const MeshBvh bvh(mesh);
  std::vector<NearTriangle> near_out;
  std::vector<int> overlap_out;
  double max_err = 0.0;
  int found = 0;
  for (int q = 0; q < queries; ++q) {
    const Shape s = randomShape(rng, q);
    const Pose X = nearSurfacePose(rng, mesh);
    const Brute brute = bruteClosest(s, X, mesh);
    NearTriangle nt;
    ASSERT_TRUE(bvh.closest(s, X, std::numeric_limits<double>::infinity(), &nt)) << name;
    max_err = std::max(max_err, std::abs(nt.closest.distance - brute.distance));
    EXPECT_NEAR(nt.closest.distance, brute.distance, 1e-15) << name << " query " << q;
    // The returned triangle really is at that distance.
    EXPECT_NEAR(shapeTriangle(s, X, mesh.vertex(nt.triangle, 0), mesh.vertex(nt.triangle, 1), mesh.vertex(nt.triangle, 2)).distance,
                nt.closest.distance, 1e-15);
    // A window below / above the minimum.
    const double window = rng.uniform(-0.005, 0.02);
    NearTriangle nt2;
    const bool within = bvh.closest(s, X, window, &nt2);
    if (std::abs(brute.distance - window) > 1e-12) {
      EXPECT_EQ(within, brute.distance <= window) << name;
      if (within) { EXPECT_NEAR(nt2.closest.distance, brute.distance, 1e-15); ++found; }
    }
    // near(): exactly the triangles within the window.
    near_out.clear();
    bvh.near(s, X, window, &near_out);
    std::set<int> got, expected, borderline;
    for (const auto& n : near_out) {
      got.insert(n.triangle);
      EXPECT_LE(n.closest.distance, window);
    }
    for (int t = 0; t < mesh.triangleCount(); ++t) {
      const double d = shapeTriangle(s, X, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)).distance;
      if (std::abs(d - window) < 1e-12) borderline.insert(t);
      else if (d <= window) expected.insert(t);
    }
    for (int t : borderline) got.erase(t);
    EXPECT_EQ(got, expected) << name;
    EXPECT_EQ(got.size(), expected.size());
    // trianglesOverlapping(): exactly the triangles whose boxes overlap.
    const Aabb box = shapeAabb(s, X).inflated(std::max(0.0, window));
    overlap_out.clear();
    bvh.trianglesOverlapping(box, &overlap_out);
    std::set<int> got_o(overlap_out.begin(), overlap_out.end()), expected_o;
    EXPECT_EQ(got_o.size(), overlap_out.size()) << "duplicates";
    for (int t = 0; t < mesh.triangleCount(); ++t) {
      Aabb tb;
      for (int k = 0; k < 3; ++k) tb.grow(mesh.vertex(t, k));
      if (tb.overlaps(box)) expected_o.insert(t);
    }
    EXPECT_EQ(got_o, expected_o) << name;
  }
  std::printf("[figure] bvh %s (%d triangles): closest max |bvh - brute| %.3g m over %d queries (%d within window)\n",
              name, mesh.triangleCount(), max_err, queries, found);
}

TEST(Bvh, RejectsBadMeshes) {
  EXPECT_THROW(MeshBvh(TriangleMesh{}), std::invalid_argument);
  TriangleMesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  m.triangles = {{0, 1, 3}};
  EXPECT_THROW({ MeshBvh b(m); }, std::invalid_argument);
  m.triangles = {{0, 1, -1}};
  EXPECT_THROW({ MeshBvh b(m); }, std::invalid_argument);
  m.triangles = {{0, 1, 2}};
  m.vertices[1].x() = std::nan("");
  EXPECT_THROW({ MeshBvh b(m); }, std::invalid_argument);
  m.vertices[1].x() = 1.0;
  EXPECT_NO_THROW({ MeshBvh b(m); });
}

TEST(Bvh, MatchesBruteForceOnSoups) {
  Rng rng(11);
  checkAgainstBruteForce("soup", soup(rng, 600, 0.05, 0.01), rng, 150);
  checkAgainstBruteForce("soup-large-triangles", soup(rng, 80, 0.05, 0.06), rng, 100);
  checkAgainstBruteForce("single-triangle", soup(rng, 1, 0.0, 0.02), rng, 60);
}

TEST(Bvh, MatchesBruteForceOnSphereShellAndNeedles) {
  Rng rng(12);
  checkAgainstBruteForce("icosphere", icosphere(0.05, 3), rng, 150);
  checkAgainstBruteForce("thin-shell-0.1mm", thinShell(24, 0.1, 1e-4), rng, 150);
  checkAgainstBruteForce("needles", needles(rng, 400), rng, 150);
  // All triangles identical (degenerate split: centroids coincide).
  TriangleMesh same;
  same.vertices = {Vec3(0, 0, 0), Vec3(0.01, 0, 0), Vec3(0, 0.01, 0)};
  for (int i = 0; i < 50; ++i) same.triangles.push_back({0, 1, 2});
  checkAgainstBruteForce("identical-triangles", same, rng, 30);
}

TEST(Bvh, BunnyMatchesBruteForceAndFcl) {
  const MeshBvh& bvh = bunny();
  const TriangleMesh& mesh = bvh.mesh();
  ASSERT_EQ(mesh.triangleCount(), 69451);
  Rng rng(13);
  auto fcl_mesh = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  fcl_mesh->beginModel();
  for (int t = 0; t < mesh.triangleCount(); ++t) fcl_mesh->addTriangle(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2));
  fcl_mesh->endModel();
  double max_err = 0.0, max_err_fcl = 0.0;
  std::vector<double> t_ours, t_fcl;
  for (int q = 0; q < 30; ++q) {
    Shape s;
    s.type = ShapeType::Capsule;
    s.radius = 0.008;
    s.half_length = 0.015;
    const Pose X = nearSurfacePose(rng, mesh, 0.009, 0.03);
    if (q == 0) {  // warm the caches of both before timing
      NearTriangle warm;
      bvh.closest(s, X, 0.02, &warm);
    }
    const Brute brute = bruteClosest(s, X, mesh);
    NearTriangle nt;
    const auto t0 = std::chrono::steady_clock::now();
    const bool hit = bvh.closest(s, X, 0.02, &nt);
    const auto t1 = std::chrono::steady_clock::now();
    ASSERT_EQ(hit, brute.distance <= 0.02);
    if (hit) {
      max_err = std::max(max_err, std::abs(nt.closest.distance - brute.distance));
      EXPECT_NEAR(nt.closest.distance, brute.distance, 1e-15);
    }
    if (brute.distance > 1e-4) {
      auto cap = std::make_shared<fcl::Capsuled>(s.radius, 2 * s.half_length);
      fcl::Transform3d T = fcl::Transform3d::Identity();
      T.translation() = X.p;
      T.linear() = X.q.toRotationMatrix();
      fcl::DistanceRequestd req(true);
      req.distance_tolerance = 1e-12;
      req.gjk_solver_type = fcl::GST_INDEP;
      fcl::DistanceResultd res;
      const auto t2 = std::chrono::steady_clock::now();
      fcl::distance(cap.get(), T, fcl_mesh.get(), fcl::Transform3d::Identity(), req, res);
      const auto t3 = std::chrono::steady_clock::now();
      max_err_fcl = std::max(max_err_fcl, std::abs(res.min_distance - brute.distance));
      EXPECT_NEAR(res.min_distance, brute.distance, 1e-7);
      t_fcl.push_back(std::chrono::duration<double, std::micro>(t3 - t2).count());
      t_ours.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    }
  }
  std::sort(t_ours.begin(), t_ours.end());
  std::sort(t_fcl.begin(), t_fcl.end());
  std::printf("[figure] bunny capsule closest: max |bvh - brute| %.3g m, max |FCL - brute| %.3g m; median time ours %.1f us "
              "vs FCL %.1f us (x%.0f) over %zu poses (timing indicative only)\n",
              max_err, max_err_fcl, t_ours[t_ours.size() / 2], t_fcl[t_fcl.size() / 2],
              t_fcl[t_fcl.size() / 2] / std::max(1e-3, t_ours[t_ours.size() / 2]), t_ours.size());
}

TEST(Bvh, BunnyRandomShapesMatchBruteForce) {
  const MeshBvh& bvh = bunny();
  Rng rng(14);
  std::vector<NearTriangle> near_out;
  for (int q = 0; q < 12; ++q) {
    const Shape s = randomShape(rng, q);
    const Pose X = nearSurfacePose(rng, bvh.mesh());
    const Brute brute = bruteClosest(s, X, bvh.mesh());
    NearTriangle nt;
    ASSERT_TRUE(bvh.closest(s, X, 1.0, &nt));
    EXPECT_NEAR(nt.closest.distance, brute.distance, 1e-15);
    near_out.clear();
    bvh.near(s, X, brute.distance + 0.002, &near_out);
    ASSERT_FALSE(near_out.empty());
    double mn = std::numeric_limits<double>::infinity();
    for (const auto& n : near_out) mn = std::min(mn, n.closest.distance);
    EXPECT_NEAR(mn, brute.distance, 1e-15);
  }
}

// A hint (any triangle: the query's own answer, a neighbour, one far away, an invalid index) is
// measured first to prune sooner; the answer must be the one without it, bit for bit, including
// which of several triangles at the least distance (a shared vertex or edge) is returned.
TEST(Bvh, HintLeavesTheClosestUnchanged) {
  Rng rng(16);
  TriangleMesh far_mesh = icosphere(0.05, 3);
  for (auto& v : far_mesh.vertices) v += Vec3(1e4, 2e3, -1e4);
  const MeshBvh far_bvh(far_mesh);
  int with_ties = 0, checked = 0;
  for (const MeshBvh* bvh : {&bunny(), &far_bvh}) {
    const int nt = bvh->triangleCount();
    for (int q = 0; q < 600; ++q) {
      const Shape s = randomShape(rng, q);
      Pose X = nearSurfacePose(rng, bvh->mesh());
      if (q >= 300) {
        // Resting 0.1 mm off a triangle, a box's face or a capsule's side parallel to it (where
        // a palm or phalanx lies on a surface, and where triangles tie).
        const int t = rng.integer(0, bvh->triangleCount() - 1);
        const Vec3 a = bvh->mesh().vertex(t, 0), b = bvh->mesh().vertex(t, 1), c = bvh->mesh().vertex(t, 2);
        const Vec3 n = (b - a).cross(c - a).normalized();
        const Quat spin(Eigen::AngleAxisd(rng.uniform(0.0, 6.283), Vec3::UnitZ()));
        X.q = Quat::FromTwoVectors(Vec3::UnitZ(), n) * spin;
        if (s.type == ShapeType::Capsule) X.q = X.q * Quat(Eigen::AngleAxisd(1.5707963267948966, Vec3::UnitX()));
        const double reach = s.type == ShapeType::Box ? s.half_extents.z() : s.radius;
        X.p = (a + b + c) / 3.0 + (reach + 1e-4) * n;
      }
      const double window = q % 3 == 0 ? 1.0 : 0.01;
      NearTriangle plain;
      const bool found = bvh->closest(s, X, window, &plain);
      const int hints[] = {found ? plain.triangle : 0, rng.integer(0, nt - 1), found ? (plain.triangle + 1) % nt : 1, -5, nt + 3};
      for (const int hint : hints) {
        NearTriangle hinted;
        ASSERT_EQ(bvh->closest(s, X, window, &hinted, hint), found) << "query " << q << " hint " << hint;
        if (!found) continue;
        ++checked;
        EXPECT_EQ(hinted.triangle, plain.triangle) << "query " << q << " hint " << hint;
        EXPECT_EQ(hinted.closest.distance, plain.closest.distance);
        EXPECT_EQ(hinted.closest.p_triangle, plain.closest.p_triangle);
        EXPECT_EQ(hinted.closest.n, plain.closest.n);
      }
      // A hint at the same distance as the answer (a tie: the triangles sharing the answer's
      // nearest corner or edge): still the answer without the hint.
      if (found) {
        const auto& tris = bvh->mesh().triangles;
        const auto& mine = tris[static_cast<size_t>(plain.triangle)];
        for (int t = 0; t < nt; ++t) {
          if (t == plain.triangle) continue;
          const auto& other = tris[static_cast<size_t>(t)];
          bool shares = false;
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) shares = shares || mine[static_cast<size_t>(i)] == other[static_cast<size_t>(j)];
          if (!shares) continue;
          const double d = shapeTriangle(s, X, bvh->mesh().vertex(t, 0), bvh->mesh().vertex(t, 1), bvh->mesh().vertex(t, 2)).distance;
          if (std::abs(d - plain.closest.distance) > 1e-15) continue;
          ++with_ties;
          NearTriangle hinted;
          ASSERT_TRUE(bvh->closest(s, X, window, &hinted, t));
          EXPECT_EQ(hinted.triangle, plain.triangle) << "tie hint " << t;
          EXPECT_EQ(hinted.closest.distance, plain.closest.distance);
        }
      }
    }
  }
  std::printf("[figure] closest with a hint: %d answers compared, %d tied triangles given as hints\n", checked, with_ties);
  EXPECT_GT(with_ties, 0);  // the tie case was exercised
}

TEST(Bvh, ClosestAmongTheShellIsTheClosestQuery) {
  // closestAmong answers the whole shape's closest-point query from near()'s answer within a
  // shell (CollisionWorld::contacts, for palms and bodies whose sweep hit): where it answers, the
  // answer must be closest()'s bit for bit; where the nearest lies beyond the shell it must not.
  // Shapes resting 0 … 0.5 mm off a random triangle (faces parallel to it, where triangles tie)
  // or anywhere near the surface.
  Rng rng(61);
  const MeshBvh& bvh = bunny();
  int answered = 0, declined = 0, empty = 0;
  std::vector<NearTriangle> shell;
  for (int q = 0; q < 1200; ++q) {
    const Shape s = randomShape(rng, q);
    Pose X = nearSurfacePose(rng, bvh.mesh());
    if (q % 2 == 0) {
      const int t = rng.integer(0, bvh.triangleCount() - 1);
      const Vec3 a = bvh.mesh().vertex(t, 0), b = bvh.mesh().vertex(t, 1), c = bvh.mesh().vertex(t, 2);
      const Vec3 n = (b - a).cross(c - a).normalized();
      const Quat spin(Eigen::AngleAxisd(rng.uniform(0.0, 6.283), Vec3::UnitZ()));
      X.q = Quat::FromTwoVectors(Vec3::UnitZ(), n) * spin;
      if (s.type == ShapeType::Capsule) X.q = X.q * Quat(Eigen::AngleAxisd(1.5707963267948966, Vec3::UnitX()));
      const double reach = s.type == ShapeType::Box ? s.half_extents.z() : s.radius;
      X.p = (a + b + c) / 3.0 + (reach + rng.uniform(0.0, 5e-4)) * n;
    }
    const double shell_distance = q % 3 == 0 ? 3e-4 : 1e-4;
    const double range = q % 5 == 0 ? 5e-5 : 0.01;  // a range below the shell too
    shell.clear();
    bvh.near(s, X, shell_distance, &shell);
    NearTriangle expected, got;
    const bool found = bvh.closest(s, X, range, &expected);
    if (!bvh.closestAmong(shell, s, X, shell_distance, range, &got)) {
      ++declined;
      empty += shell.empty() ? 1 : 0;
      // Declined only where the nearest is not certainly inside the shell and the range.
      if (found) {
        EXPECT_GT(expected.closest.distance, std::min(shell_distance, range) - 1e-12) << "query " << q;
      }
      continue;
    }
    ++answered;
    ASSERT_TRUE(found) << "query " << q;
    EXPECT_EQ(got.triangle, expected.triangle) << "query " << q;
    EXPECT_EQ(got.closest.distance, expected.closest.distance) << "query " << q;
    EXPECT_EQ(got.closest.core_distance, expected.closest.core_distance) << "query " << q;
    EXPECT_EQ(got.closest.p_triangle, expected.closest.p_triangle) << "query " << q;
    EXPECT_EQ(got.closest.p_shape, expected.closest.p_shape) << "query " << q;
    EXPECT_EQ(got.closest.n, expected.closest.n) << "query " << q;
  }
  std::printf("[figure] closest among the shell: %d answered, %d declined (%d with an empty shell)\n", answered,
              declined, empty);
  EXPECT_GT(answered, 300);
  EXPECT_GT(declined - empty, 0);  // some with triangles in the shell but none near enough / in range
}

TEST(Bvh, FarFromTheOrigin) {
  Rng rng(15);
  TriangleMesh m = icosphere(0.05, 2);
  const Vec3 offset(1e4, 2e3, -1e4);
  for (auto& v : m.vertices) v += offset;
  const MeshBvh bvh(m);
  for (int q = 0; q < 60; ++q) {
    const Shape s = randomShape(rng, q);
    const Pose X = nearSurfacePose(rng, m);
    NearTriangle nt;
    ASSERT_TRUE(bvh.closest(s, X, 1.0, &nt));
    EXPECT_NEAR(nt.closest.distance, bruteClosest(s, X, m).distance, 1e-15);
  }
}

}  // namespace
}  // namespace godhand::geo

namespace godhand {
// surfaceDistanceBound: analytic offsets, and a brute-force oracle on dense samples.
TEST(SurfaceDistanceBound, ParallelSquaresAndSpheres) {
  // A unit square in z = 0 and the same square lifted by 0.01: every point is exactly 0.01 away.
  geo::TriangleMesh lo, hi;
  lo.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  lo.triangles = {{0, 1, 2}, {0, 2, 3}};
  hi = lo;
  for (Vec3& v : hi.vertices) v.z() = 0.01;
  const geo::MeshBvh hi_bvh(hi);
  double measured = -1.0;
  // No tolerance: the corners only, plus the longest edge / √3.
  const double coarse_bound = geo::surfaceDistanceBound(lo, hi_bvh, std::numeric_limits<double>::infinity(), &measured);
  EXPECT_NEAR(measured, 0.01, 1e-15);
  EXPECT_NEAR(coarse_bound, 0.01 + std::sqrt(2.0) / std::sqrt(3.0), 1e-12);
  // A tolerance of 0.02: refined until it holds, and never below the true 0.01.
  const double bound = geo::surfaceDistanceBound(lo, hi_bvh, 0.02, &measured);
  EXPECT_GE(bound, 0.01);
  EXPECT_LE(bound, 0.02);
  EXPECT_NEAR(measured, 0.01, 1e-15);
  // Below the true distance it cannot hold: a value above the tolerance.
  EXPECT_GT(geo::surfaceDistanceBound(lo, hi_bvh, 0.009), 0.009);

  // A fine sphere against a coarse one inside it: the bound must cover every point of the fine
  // surface (brute force: random points of every triangle against every coarse triangle).
  const geo::TriangleMesh fine = godhand::sphereMesh(0.1, 3), coarse = godhand::sphereMesh(0.1, 1);
  const geo::MeshBvh coarse_bvh(coarse);
  const double b = geo::surfaceDistanceBound(fine, coarse_bvh, 0.008, &measured);
  ASSERT_LE(b, 0.008);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0.0;
  for (const auto& t : fine.triangles) {
    for (int k = 0; k < 6; ++k) {
      double r1 = u(rng), r2 = u(rng);
      if (r1 + r2 > 1.0) { r1 = 1.0 - r1; r2 = 1.0 - r2; }
      const Vec3 p = fine.vertices[static_cast<size_t>(t[0])] +
                     r1 * (fine.vertices[static_cast<size_t>(t[1])] - fine.vertices[static_cast<size_t>(t[0])]) +
                     r2 * (fine.vertices[static_cast<size_t>(t[2])] - fine.vertices[static_cast<size_t>(t[0])]);
      double d = std::numeric_limits<double>::infinity();
      for (const auto& c : coarse.triangles)
        d = std::min(d, geo::pointTriangleDistance(p, coarse.vertices[static_cast<size_t>(c[0])],
                                                  coarse.vertices[static_cast<size_t>(c[1])], coarse.vertices[static_cast<size_t>(c[2])], nullptr));
      worst = std::max(worst, d);
    }
  }
  EXPECT_LE(worst, b);
  EXPECT_LE(measured, b);
  EXPECT_GT(measured, 0.5 * worst);  // the samples see most of it
  std::printf("[figure] sphere level 3 vs level 1: bound %.3g mm, at the samples %.3g mm, brute force (random points) %.3g mm\n",
              b * 1e3, measured * 1e3, worst * 1e3);
}
}  // namespace godhand
