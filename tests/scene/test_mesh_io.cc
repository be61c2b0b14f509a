// Mesh import (OBJ, STL), cleaning counts, open edges, and the mesh utilities (enclosing
// primitive tessellations, convex hull, decimation, subdivision).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "common/files.h"
#include "geometry/distance.h"
#include "scene/mesh_io.h"

namespace godhand {
namespace {

namespace fs = std::filesystem;
using geo::TriangleMesh;
constexpr double kPi = 3.14159265358979323846;

/// A fresh temporary folder per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("godhand_mesh_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~TempDir() { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& bytes) const {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }

 private:
  fs::path dir_;
};

/// The error message of loading `path` (empty when it loads).
std::string loadError(const std::string& path) {
  try {
    loadMeshFile(path);
  } catch (const MeshError& e) {
    return e.what();
  }
  return "";
}

/// Error is one line that starts with "PATH:LINE: ".
void expectLocated(const std::string& msg, const std::string& path, const std::string& line, const std::string& what) {
  SCOPED_TRACE(msg);
  EXPECT_EQ(msg.find('\n'), std::string::npos);
  EXPECT_EQ(msg.rfind(path + ":" + line + ": ", 0), 0u) << "expected prefix " << path << ":" << line << ": ";
  EXPECT_NE(msg.find(what), std::string::npos) << "expected '" << what << "'";
}

MeshStats statsOf(const TriangleMesh& m) {
  MeshStats s;
  countEdges(m, &s);
  return s;
}

std::string binaryStl(const std::string& header, const std::vector<std::array<Vec3, 3>>& tris) {
  std::string out(80, ' ');
  std::memcpy(out.data(), header.data(), std::min<size_t>(80, header.size()));
  const auto n = static_cast<uint32_t>(tris.size());
  out.append(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : tris) {
    float f[12] = {0, 0, 0};
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) f[3 + 3 * k + c] = static_cast<float>(t[static_cast<size_t>(k)][c]);
    out.append(reinterpret_cast<const char*>(f), sizeof f);
    out.append(2, '\0');
  }
  return out;
}

/// Regular tetrahedron-like solid (outward), as triangle corner lists.
std::vector<std::array<Vec3, 3>> tetra() {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), d(0, 0, 1);
  return {{a, c, b}, {a, b, d}, {a, d, c}, {b, c, d}};
}

// ------------------------------------------------------------------------------------- OBJ

TEST(Obj, AllFaceFormsNegativeIndicesQuadsAndIgnoredStatements) {
  TempDir tmp;
  const std::string obj =
      "# unit cube, every face written differently\r\n"
      "mtllib cube.mtl\n"
      "o cube\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\r\n"
      "v 0 0 1\nv 1 0 1\nv 1 1 1 1.0\nv 0 1 1 0.5 0.5 0.5\n"
      "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
      "vn 0 0 1\n"
      "g faces\ns off\nusemtl red\n"
      "\n"
      "f 1 4 3 2\n"                      // plain quad (bottom)
      "f 5/1 6/2 7/3 8/4\n"              // v/vt (top)
      "f 1//1 2//1 6//1 5//1\n"          // v//vn (front)
      "f 3/1/1 4/2/1 8/3/1 7/4/1\r\n"    // v/vt/vn (back)
      "f -8 -4 -1 -5\n"                  // negative (left: 1 5 8 4)
      "f +2 3 7 # comment\n\tf  2 7   6  \n"  // triangles, '+', comment, odd whitespace (right)
      "l 1 2\np 3\n";
  MeshStats st;
  const TriangleMesh m = loadMeshFile(tmp.write("cube.obj", obj), &st);
  EXPECT_EQ(m.vertices.size(), 8u);
  EXPECT_EQ(m.triangleCount(), 12);
  EXPECT_EQ(st.input_vertices, 8);
  EXPECT_EQ(st.input_triangles, 12);
  EXPECT_EQ(st.welded, 0);
  EXPECT_EQ(st.degenerate_dropped, 0);
  EXPECT_EQ(st.duplicates_dropped, 0);
  EXPECT_TRUE(st.closed());
  EXPECT_EQ(st.misoriented_edges, 0);
  EXPECT_DOUBLE_EQ(signedVolume(m), 1.0);
  EXPECT_EQ(st.bounds.lo, Vec3(0, 0, 0));
  EXPECT_EQ(st.bounds.hi, Vec3(1, 1, 1));
}

TEST(Obj, NegativeIndicesAreRelativeToVerticesSoFar) {
  TempDir tmp;
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n"
      "v 0 0 2\nv 2 0 2\nv 0 2 2\nf -3 -2 -1\n";
  const TriangleMesh m = loadMeshFile(tmp.write("rel.obj", obj));
  ASSERT_EQ(m.triangleCount(), 2);
  EXPECT_EQ(m.vertex(1, 1), Vec3(2, 0, 2));
  EXPECT_EQ(m.vertex(0, 2), Vec3(0, 1, 0));
}

TEST(Obj, PentagonIsFanTriangulated) {
  TempDir tmp;
  std::string obj;
  for (int i = 0; i < 5; ++i) obj += "v " + std::to_string(std::cos(2 * kPi * i / 5)) + " " + std::to_string(std::sin(2 * kPi * i / 5)) + " 0\n";
  obj += "f 1 2 3 4 5\n";
  MeshStats st;
  const TriangleMesh m = loadMeshFile(tmp.write("penta.obj", obj), &st);
  EXPECT_EQ(m.triangleCount(), 3);
  EXPECT_EQ(st.boundary_edges, 5);
  EXPECT_EQ(st.nonmanifold_edges, 0);
}

TEST(Obj, ErrorsAreOneLineWithFileAndLine) {
  TempDir tmp;
  std::string p;
  p = tmp.write("nan.obj", "v 0 0 0\nv 0 nan 0\nv 1 1 1\nf 1 2 3\n");
  expectLocated(loadError(p), p, "2", "non-finite");
  p = tmp.write("inf.obj", "v 0 0 0\nv 1 0 0\nv 0 1e999 0\nf 1 2 3\n");
  expectLocated(loadError(p), p, "3", "non-finite");
  p = tmp.write("badnum.obj", "# x\nv 0 0 0\nv 1 0x 0\n");
  expectLocated(loadError(p), p, "3", "bad vertex coordinate '0x'");
  p = tmp.write("short.obj", "v 0 0\n");
  expectLocated(loadError(p), p, "1", "3 coordinates");
  p = tmp.write("index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\nf 1 2 9\n");
  expectLocated(loadError(p), p, "6", "face index 9 out of range (file has 3 vertices)");
  p = tmp.write("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  expectLocated(loadError(p), p, "4", "index 0");
  p = tmp.write("relative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
  expectLocated(loadError(p), p, "4", "relative face index -4 out of range");
  p = tmp.write("badface.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x/1\n");
  expectLocated(loadError(p), p, "4", "bad face vertex 'x/1'");
  p = tmp.write("twoverts.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
  expectLocated(loadError(p), p, "3", "at least 3 vertices");
  p = tmp.write("empty.obj", "");
  expectLocated(loadError(p), p, "1", "no triangles");
  p = tmp.write("nofaces.obj", "# only vertices\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
  expectLocated(loadError(p), p, "4", "no triangles");
  p = tmp.write("degenerate.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n");
  expectLocated(loadError(p), p, "5", "no triangles left after cleaning (2 degenerate, 0 duplicate)");
  std::string junk = "v 0 0 0\n";
  for (int i = 0; i < 300; ++i) junk.push_back(static_cast<char>((i * 37) % 256));
  p = tmp.write("garbage.obj", junk);
  const std::string g = loadError(p);
  EXPECT_EQ(g.find('\n'), std::string::npos);
  EXPECT_EQ(g.rfind(p + ":", 0), 0u) << g;
  EXPECT_NE(g.find("binary data"), std::string::npos) << g;
  p = (fs::path(p).parent_path() / "missing.obj").string();
  expectLocated(loadError(p), p, "0", "cannot open mesh file");
  p = tmp.write("mesh.ply", "ply\n");
  expectLocated(loadError(p), p, "0", "unsupported mesh format");
}

TEST(MeshFile, CoreParsesBytesTheProgramsReadTheFile) {
  // core opens no files: parseMeshFile takes the bytes, the name only picks the format (any
  // case) and names the mesh in errors; loadMeshFile (services/common/files.h) reads the file.
  const std::string stl = binaryStl("binary", tetra());
  MeshStats st;
  EXPECT_EQ(parseMeshFile(stl, "in/memory.STL", &st).triangleCount(), 4);
  EXPECT_EQ(st.input_triangles, 4);
  EXPECT_EQ(parseMeshFile("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "t.Obj").triangleCount(), 1);
  EXPECT_EQ(meshFormat("a/b.STL"), ".stl");
  auto parseError = [](const std::string& bytes, const std::string& name) -> std::string {
    try {
      parseMeshFile(bytes, name);
    } catch (const MeshError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(parseError(stl, "t.ply"), "t.ply:0: unsupported mesh format '.ply' (expected .obj or .stl)");
  EXPECT_EQ(parseError("v 0 0 0\nf 1 2 3\n", "mem/x.obj").rfind("mem/x.obj:2: ", 0), 0u);

  // The file side keeps its order: a missing file is missing whatever its name, a directory is
  // not a regular file, then the name's format, then the bytes.
  TempDir tmp;
  const std::string dir = fs::path(tmp.write("m.stl", stl)).parent_path().string();
  fs::create_directories(dir + "/d.obj");
  EXPECT_EQ(loadError(dir + "/none.ply"), dir + "/none.ply:0: cannot open mesh file: no such file");
  EXPECT_EQ(loadError(dir + "/d.obj"), dir + "/d.obj:0: cannot open mesh file: not a regular file");
  const std::string ply = tmp.write("m.ply", "ply\n");
  EXPECT_EQ(loadError(ply), ply + ":0: unsupported mesh format '.ply' (expected .obj or .stl)");
  EXPECT_EQ(loadMeshFile(dir + "/m.stl").triangleCount(), 4);
}

TEST(ModelFile, MissingFileOrDirectoryIsNamed) {
  TempDir tmp;
  const std::string dir = fs::path(tmp.write("x.txt", "")).parent_path().string();
  auto modelError = [](const std::string& path) -> std::string {
    try {
      loadHandModel(path);
    } catch (const ModelError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(modelError(dir), dir + ": cannot open model file");
  EXPECT_EQ(modelError(dir + "/none.pbtxt"), dir + "/none.pbtxt: cannot open model file");
}

// ------------------------------------------------------------------------------------- STL

TEST(Stl, BinaryStartingWithSolidIsReadAsBinaryAndWelded) {
  TempDir tmp;
  MeshStats st;
  const TriangleMesh m = loadMeshFile(tmp.write("b.stl", binaryStl("solid looks like ascii but is binary", tetra())), &st);
  EXPECT_EQ(m.triangleCount(), 4);
  EXPECT_EQ(m.vertices.size(), 4u);
  EXPECT_EQ(st.input_vertices, 12);
  EXPECT_EQ(st.welded, 8);
  EXPECT_TRUE(st.closed());
  EXPECT_EQ(st.misoriented_edges, 0);
  EXPECT_NEAR(signedVolume(m), 1.0 / 6.0, 1e-15);
}

TEST(Stl, AsciiWithPolygonLoopsAndSeveralSolids) {
  TempDir tmp;
  std::string s = "solid first\n";
  int i = 0;
  for (const auto& t : tetra()) {
    if (i++ == 2) s += "endsolid first\nsolid second\n";
    s += "  facet normal 0 0 0\n    outer loop\n";
    for (const Vec3& v : t) s += "      vertex " + std::to_string(v.x()) + " " + std::to_string(v.y()) + " " + std::to_string(v.z()) + "\n";
    s += "    endloop\n  endfacet\n";
  }
  // A quad facet in the plane z = 5 (fan-triangulated): an open patch.
  s += "facet normal 0 0 1\nouter loop\nvertex 0 0 5\nvertex 1 0 5\nvertex 1 1 5\nvertex 0 1 5\nendloop\nendfacet\nendsolid second\n";
  MeshStats st;
  const TriangleMesh m = loadMeshFile(tmp.write("a.STL", s), &st);
  EXPECT_EQ(m.triangleCount(), 6);
  EXPECT_EQ(m.vertices.size(), 8u);
  EXPECT_EQ(st.boundary_edges, 4);
}

TEST(Stl, ErrorsAreOneLineWithFileAndLineOrTriangle) {
  TempDir tmp;
  std::string p;
  p = tmp.write("nan.stl", "solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 nan 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n");
  expectLocated(loadError(p), p, "5", "non-finite");
  p = tmp.write("word.stl", "solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nbanana 1 0 0\n");
  expectLocated(loadError(p), p, "5", "unexpected 'banana'");
  p = tmp.write("open.stl", "solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n");
  expectLocated(loadError(p), p, "6", "ends inside a facet loop");
  p = tmp.write("empty.stl", "solid nothing\nendsolid nothing\n");
  expectLocated(loadError(p), p, "2", "no triangles");
  auto tris = tetra();
  tris[1][2] = Vec3(0, std::numeric_limits<double>::quiet_NaN(), 0);
  p = tmp.write("nanbin.stl", binaryStl("binary", tris));
  expectLocated(loadError(p), p, "triangle 2", "non-finite");
  p = tmp.write("zero.stl", binaryStl("solid", {}));
  expectLocated(loadError(p), p, "triangle 0", "no triangles");
  std::string junk(500, '\0');
  for (size_t i = 0; i < junk.size(); ++i) junk[i] = static_cast<char>((i * 131 + 7) % 256);
  p = tmp.write("garbage.stl", junk);
  expectLocated(loadError(p), p, "1", "not an STL file");
  p = tmp.write("tiny.stl", "abc");
  expectLocated(loadError(p), p, "1", "not an STL file");
}

// ------------------------------------------------------------------------------------- cleaning

TEST(Clean, WeldDegenerateDuplicateAndUnreferencedCountsAreExact) {
  TriangleMesh raw;
  raw.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 0, 0} /*=1*/, {-0.0, 0, 0} /*=0*/, {0, 0, 1}, {2, 0, 0}, {5, 5, 5}};
  raw.triangles = {
      {0, 1, 2},  // kept
      {4, 3, 2},  // = (0,1,2) after welding: duplicate
      {2, 1, 0},  // same vertices, other order: duplicate
      {0, 1, 1},  // repeated index: degenerate
      {0, 3, 1},  // repeated after welding: degenerate
      {0, 1, 6},  // collinear, zero area: degenerate
      {0, 1, 5},  // kept
      {0, 2, 5},  // kept
  };
  MeshStats st;
  const TriangleMesh m = cleanMesh(raw, &st);
  EXPECT_EQ(st.input_vertices, 8);
  EXPECT_EQ(st.input_triangles, 8);
  EXPECT_EQ(st.welded, 2);
  EXPECT_EQ(st.degenerate_dropped, 3);
  EXPECT_EQ(st.duplicates_dropped, 2);
  EXPECT_EQ(st.unreferenced, 2);  // (2,0,0) and (5,5,5)
  EXPECT_EQ(st.output_vertices, 4);
  EXPECT_EQ(st.output_triangles, 3);
  EXPECT_EQ(m.triangleCount(), 3);
  EXPECT_EQ(st.boundary_edges, 3);
  EXPECT_EQ(st.nonmanifold_edges, 0);
  EXPECT_EQ(st.misoriented_edges, 2);
  std::printf("[figure] cleaning case: %s\n", st.summary().c_str());
}

TEST(Clean, TinyButRealTrianglesStay) {
  // A sliver 1e-9 high in a mesh 1 unit wide is not zero area (threshold 1e-12 L^2).
  TriangleMesh raw;
  raw.vertices = {{0, 0, 0}, {1, 0, 0}, {0.5, 1e-9, 0}, {0, 1, 0}};
  raw.triangles = {{0, 1, 2}, {0, 1, 3}};
  MeshStats st;
  EXPECT_EQ(cleanMesh(raw, &st).triangleCount(), 2);
  EXPECT_EQ(st.degenerate_dropped, 0);
}

TEST(Clean, OpenCubeHasFourBoundaryEdgesAndFinsAreNonManifold) {
  TriangleMesh cube = boxMesh(Vec3(1, 1, 1));
  EXPECT_TRUE(statsOf(cube).closed());
  TriangleMesh open = cube;
  // Remove the two triangles of one face (the ones whose vertices all have z = +1).
  open.triangles.clear();
  for (int t = 0; t < cube.triangleCount(); ++t)
    if (!(cube.vertex(t, 0).z() > 0 && cube.vertex(t, 1).z() > 0 && cube.vertex(t, 2).z() > 0)) open.triangles.push_back(cube.triangles[static_cast<size_t>(t)]);
  ASSERT_EQ(open.triangleCount(), 10);
  const MeshStats so = statsOf(open);
  EXPECT_EQ(so.boundary_edges, 4);
  EXPECT_EQ(so.nonmanifold_edges, 0);
  EXPECT_FALSE(so.closed());

  TriangleMesh fin;
  fin.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  fin.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const MeshStats sf = statsOf(fin);
  EXPECT_EQ(sf.nonmanifold_edges, 1);
  EXPECT_EQ(sf.boundary_edges, 6);
}

// ------------------------------------------------------------------------------------- primitives

/// Largest signed plane distance of p over the faces (≤ 0: inside a convex mesh).
double maxPlaneDistance(const TriangleMesh& m, const Vec3& p) {
  double d = -1e300;
  for (int t = 0; t < m.triangleCount(); ++t) {
    const Vec3 a = m.vertex(t, 0);
    const Vec3 n = (m.vertex(t, 1) - a).cross(m.vertex(t, 2) - a).normalized();
    d = std::max(d, n.dot(p - a));
  }
  return d;
}

void expectClosedConvexOutward(const TriangleMesh& m, double tol) {
  const MeshStats s = statsOf(m);
  EXPECT_TRUE(s.closed());
  EXPECT_EQ(s.misoriented_edges, 0);
  EXPECT_GT(signedVolume(m), 0.0);
  for (const Vec3& v : m.vertices) EXPECT_LE(maxPlaneDistance(m, v), tol);  // convex
}

/// Points spread evenly over the unit sphere (Fibonacci).
std::vector<Vec3> sphereDirections(int n) {
  std::vector<Vec3> d;
  const double g = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
    d.emplace_back(r * std::cos(g * i), r * std::sin(g * i), z);
  }
  return d;
}

TEST(Primitives, BoxIsExactClosedOutward) {
  const Vec3 e(0.3, 0.2, 0.1);
  const TriangleMesh m = boxMesh(e);
  EXPECT_EQ(m.triangleCount(), 12);
  EXPECT_EQ(m.vertices.size(), 8u);
  for (const Vec3& v : m.vertices) EXPECT_EQ(v.cwiseAbs(), e);
  EXPECT_NEAR(signedVolume(m), 8 * e.prod(), 1e-15);
  expectClosedConvexOutward(m, 1e-15);
}

TEST(Primitives, SphereTessellationEnclosesTheSphereAndStaysClose) {
  for (int levels : {0, 1, 2, 3}) {
    const double r = 0.037;
    const TriangleMesh m = sphereMesh(r, levels);
    EXPECT_EQ(m.triangleCount(), 20 << (2 * levels));
    expectClosedConvexOutward(m, 1e-15);
    double worst = -1e300;
    for (const Vec3& d : sphereDirections(4000)) worst = std::max(worst, maxPlaneDistance(m, r * d));
    EXPECT_LE(worst, 0.0) << "a point of the sphere is outside the tessellation, levels " << levels;
    double far = 0.0;
    for (const Vec3& v : m.vertices) far = std::max(far, v.norm() - r);
    if (levels == 3) {
      EXPECT_LT(far, 0.006 * r);
    }
    std::printf("[figure] sphere levels %d: %d triangles, vertices at most %.3f %% of r outside\n", levels, m.triangleCount(), 100 * far / r);
  }
}

TEST(Primitives, CylinderPrismEnclosesTheCylinderAndStaysClose) {
  const double r = 0.025, h = 0.04;
  const TriangleMesh m = cylinderMesh(r, h, 32);
  EXPECT_EQ(m.triangleCount(), 128);
  expectClosedConvexOutward(m, 1e-15);
  double worst = -1e300;
  for (int i = 0; i < 720; ++i) {
    const double a = 2 * kPi * i / 720;
    for (int k = 0; k <= 10; ++k) worst = std::max(worst, maxPlaneDistance(m, Vec3(r * std::cos(a), r * std::sin(a), -h + 2 * h * k / 10)));
    for (double s : {0.0, 0.5, 1.0}) {  // caps
      worst = std::max(worst, maxPlaneDistance(m, Vec3(s * r * std::cos(a), s * r * std::sin(a), h)));
      worst = std::max(worst, maxPlaneDistance(m, Vec3(s * r * std::cos(a), s * r * std::sin(a), -h)));
    }
  }
  EXPECT_LE(worst, 0.0);
  double far = 0.0;
  for (const Vec3& v : m.vertices) {
    far = std::max(far, v.head<2>().norm() - r);
    EXPECT_LE(std::abs(v.z()), h);
  }
  EXPECT_LT(far, 0.005 * r);
  std::printf("[figure] cylinder 32-gon: vertices at most %.3f %% of r outside\n", 100 * far / r);
}

// ------------------------------------------------------------------------------------- hull, decimate, subdivide

TEST(ConvexHull, ContainsAllPointsAndIsOutward) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Vec3> pts;
  for (int i = 0; i < 2000; ++i) {  // x, then y, then z (argument order is unspecified in C++)
    const double x = g(rng);
    const double y = 0.5 * g(rng);
    const double z = 2.0 * g(rng);
    pts.emplace_back(x, y, z);
  }
  const TriangleMesh h = convexHull(pts);
  expectClosedConvexOutward(h, 1e-9);
  for (const Vec3& p : pts) EXPECT_LE(maxPlaneDistance(h, p), 1e-9);
  for (const Vec3& v : h.vertices) {
    double best = 1e300;
    for (const Vec3& p : pts) best = std::min(best, (p - v).norm());
    EXPECT_LT(best, 1e-12);  // hull vertices are input points
  }
  std::printf("[figure] hull of 2000 gaussian points: %zu vertices, %d triangles\n", h.vertices.size(), h.triangleCount());

  std::vector<Vec3> corners;
  for (const Vec3& v : boxMesh(Vec3(1, 2, 3)).vertices) corners.push_back(v);
  corners.emplace_back(0.1, 0.2, 0.3);  // interior point
  const TriangleMesh hb = convexHull(corners);
  EXPECT_EQ(hb.vertices.size(), 8u);
  EXPECT_NEAR(signedVolume(hb), 48.0, 1e-12);

  EXPECT_THROW(convexHull({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0.5, 0.5, 0}}), std::invalid_argument);
  EXPECT_THROW(convexHull({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), std::invalid_argument);
}

TEST(Subdivide, FlatMidpointSplitKeepsSurfaceAndClosure) {
  const TriangleMesh cube = boxMesh(Vec3(1, 1, 1));
  const TriangleMesh s1 = subdivide(cube, 1), s2 = subdivide(cube, 2);
  EXPECT_EQ(s1.triangleCount(), 48);
  EXPECT_EQ(s1.vertices.size(), 26u);  // V - E + F = 2
  EXPECT_EQ(s2.triangleCount(), 192);
  EXPECT_TRUE(statsOf(s2).closed());
  EXPECT_EQ(statsOf(s2).misoriented_edges, 0);
  EXPECT_DOUBLE_EQ(signedVolume(s2), 8.0);
}

TEST(Decimate, ReachesAboutTheTargetAndStaysWithinTheCell) {
  const std::string path = std::string(GODHAND_DEPLOY_DIR) + "/meshes/stanford-bunny.obj";
  const TriangleMesh bunny = loadMeshFile(path);
  for (int target : {20000, 5000, 1000}) {
    double cell = 0.0;
    const TriangleMesh d = decimate(bunny, target, &cell);
    ASSERT_GT(cell, 0.0);
    EXPECT_GT(d.triangleCount(), 0.7 * target);
    EXPECT_LT(d.triangleCount(), 1.3 * target);
    // Every output vertex is the mean of the input vertices in its cell (the grid from the input's
    // bounds at the returned cell size; summed in input order, as a second implementation would).
    {
      const Vec3 lo = meshBounds(bunny).lo;
      std::map<std::array<long, 3>, std::pair<Vec3, int>> cells;
      auto keyOf = [&](const Vec3& v) {
        const Vec3 q = ((v - lo) / cell).array().floor();
        return std::array<long, 3>{static_cast<long>(q.x()), static_cast<long>(q.y()), static_cast<long>(q.z())};
      };
      for (const Vec3& v : bunny.vertices) {
        auto& c = cells.try_emplace(keyOf(v), Vec3::Zero(), 0).first->second;
        c.first += v;
        ++c.second;
      }
      int mismatched = 0;
      for (const Vec3& v : d.vertices) {
        const auto it = cells.find(keyOf(v));
        if (it == cells.end() || !(it->second.first / it->second.second == v)) ++mismatched;
      }
      EXPECT_EQ(mismatched, 0) << "of " << d.vertices.size() << " output vertices, target " << target;
    }
    double out_to_in = 0.0;
    for (size_t i = 0; i < d.vertices.size(); i += 3) {
      double best = 1e300;
      for (const Vec3& v : bunny.vertices) best = std::min(best, (v - d.vertices[i]).squaredNorm());
      out_to_in = std::max(out_to_in, std::sqrt(best));
    }
    EXPECT_LE(out_to_in, std::sqrt(3.0) * cell);
    // Input vertices are near the decimated surface (sampled).
    double in_to_out = 0.0;
    for (size_t i = 0; i < bunny.vertices.size(); i += 97) {
      double best = 1e300;
      Vec3 c;
      for (int t = 0; t < d.triangleCount(); ++t)
        best = std::min(best, geo::pointTriangleDistance(bunny.vertices[i], d.vertex(t, 0), d.vertex(t, 1), d.vertex(t, 2), &c));
      in_to_out = std::max(in_to_out, best);
    }
    EXPECT_LE(in_to_out, 2.0 * std::sqrt(3.0) * cell);
    std::printf("[figure] decimate bunny to %d: %d triangles, cell %.2f mm, output->input vertex %.2f mm, input->output %.2f mm\n",
                target, d.triangleCount(), 1e3 * cell, 1e3 * out_to_in, 1e3 * in_to_out);
  }
  EXPECT_EQ(decimate(bunny, 100000).triangleCount(), bunny.triangleCount());
  EXPECT_THROW(decimate(bunny, 3), std::invalid_argument);
}

// ------------------------------------------------------------------------------------- shipped meshes

TEST(ShippedMeshes, BunnyAndFandiskStats) {
  MeshStats sb, sf;
  const TriangleMesh bunny = loadMeshFile(std::string(GODHAND_DEPLOY_DIR) + "/meshes/stanford-bunny.obj", &sb);
  const TriangleMesh fandisk = loadMeshFile(std::string(GODHAND_DEPLOY_DIR) + "/meshes/fandisk.obj", &sf);
  std::printf("[figure] stanford-bunny.obj: %s\n", sb.summary().c_str());
  std::printf("[figure] fandisk.obj: %s\n", sf.summary().c_str());
  EXPECT_EQ(sb.input_vertices, 35947);
  EXPECT_EQ(sb.input_triangles, 69451);
  EXPECT_GT(sb.output_triangles, 69000);
  EXPECT_NEAR(sb.bounds.extent().maxCoeff(), 0.156, 0.002);  // metres
  EXPECT_EQ(sf.input_triangles, 12946);
  EXPECT_GT(sf.output_triangles, 12900);
  EXPECT_NEAR(sf.bounds.extent().maxCoeff(), 5.24, 0.05);  // unitless
  EXPECT_EQ(bunny.triangleCount(), sb.output_triangles);
  EXPECT_EQ(fandisk.triangleCount(), sf.output_triangles);
}

}  // namespace
}  // namespace godhand
