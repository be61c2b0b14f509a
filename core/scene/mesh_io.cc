#include "scene/mesh_io.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>
#include <unordered_map>

namespace godhand {

namespace {

using geo::TriangleMesh;
using Tri = std::array<int, 3>;

/// Relative zero-area threshold: |(b−a)×(c−a)| ≤ kZeroArea · L² is degenerate.
constexpr double kZeroArea = 1e-12;

[[noreturn]] void fail(const std::string& source, long long line, const std::string& reason) {
  throw MeshError(source + ":" + std::to_string(line) + ": " + reason);
}

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/// Splits a line into whitespace-separated tokens (views into the text).
void tokenize(const char* b, const char* e, std::vector<std::string_view>* out) {
  out->clear();
  while (b < e) {
    while (b < e && isSpace(*b)) ++b;
    const char* s = b;
    while (b < e && !isSpace(*b)) ++b;
    if (b > s) out->emplace_back(s, static_cast<size_t>(b - s));
  }
}

/// Whole token as a double (accepts a leading '+', "nan", "inf"); false when it is not a number.
bool parseDouble(std::string_view t, double* x) {
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  if (t.empty()) return false;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), *x);
  if (r.ec == std::errc::result_out_of_range) {  // overflow / underflow: still a number
    *x = std::strtod(std::string(t).c_str(), nullptr);
    return true;
  }
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

bool parseInt(std::string_view t, long long* x) {
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  if (t.empty()) return false;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), *x);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

std::string quoted(std::string_view t) {
  std::string s(t.substr(0, 40));
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) >= 127) c = '?';
  return "'" + s + (t.size() > 40 ? "...'" : "'");
}

/// Calls f(line_number, begin, end) for every line (without the '\n').
template <class F>
long long forEachLine(const std::string& text, F&& f) {
  const char* p = text.data();
  const char* end = p + text.size();
  long long line = 0;
  while (p < end) {
    ++line;
    const char* nl = static_cast<const char*>(std::memchr(p, '\n', static_cast<size_t>(end - p)));
    const char* e = nl ? nl : end;
    f(line, p, e);
    p = nl ? nl + 1 : end;
  }
  return line;
}

uint64_t bitsOf(double x) {
  if (x == 0.0) x = 0.0;  // -0 welds with +0
  uint64_t u;
  std::memcpy(&u, &x, sizeof u);
  return u;
}

struct VertexKey {
  uint64_t x, y, z;
  bool operator==(const VertexKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct VertexKeyHash {
  size_t operator()(const VertexKey& k) const {
    uint64_t h = k.x * 0x9E3779B97F4A7C15ull;
    h ^= (k.y + 0x632BE59BD9B4E019ull + (h << 6) + (h >> 2)) * 0xC2B2AE3D27D4EB4Full;
    h ^= (k.z + 0x165667B19E3779F9ull + (h << 6) + (h >> 2)) * 0x9E3779B97F4A7C15ull;
    return static_cast<size_t>(h ^ (h >> 29));
  }
};

Tri sortedTri(const Tri& t) {
  Tri s = t;
  if (s[0] > s[1]) std::swap(s[0], s[1]);
  if (s[1] > s[2]) std::swap(s[1], s[2]);
  if (s[0] > s[1]) std::swap(s[0], s[1]);
  return s;
}

/// Indices of triangles that repeat an earlier triangle's vertex set.
std::vector<char> duplicateMask(const std::vector<Tri>& tris) {
  std::vector<std::pair<Tri, int>> keys(tris.size());
  for (size_t i = 0; i < tris.size(); ++i) keys[i] = {sortedTri(tris[i]), static_cast<int>(i)};
  std::sort(keys.begin(), keys.end());
  std::vector<char> dup(tris.size(), 0);
  for (size_t i = 1; i < keys.size(); ++i)
    if (keys[i].first == keys[i - 1].first) dup[static_cast<size_t>(keys[i].second)] = 1;
  return dup;
}

/// Flips every triangle whose normal points towards the origin (for star-shaped meshes
/// around the origin: the primitives).
void orientAwayFromOrigin(TriangleMesh* m) {
  for (auto& t : m->triangles) {
    const Vec3& a = m->vertices[static_cast<size_t>(t[0])];
    const Vec3& b = m->vertices[static_cast<size_t>(t[1])];
    const Vec3& c = m->vertices[static_cast<size_t>(t[2])];
    if ((b - a).cross(c - a).dot(a + b + c) < 0.0) std::swap(t[1], t[2]);
  }
}

std::string fmt(double x) {
  std::ostringstream os;
  os.precision(6);
  os << x;
  return os.str();
}

}  // namespace

std::string MeshStats::summary() const {
  std::ostringstream os;
  os << input_vertices << " -> " << output_vertices << " vertices (" << welded << " welded, " << unreferenced
     << " unreferenced), " << input_triangles << " -> " << output_triangles << " triangles (" << degenerate_dropped
     << " degenerate, " << duplicates_dropped << " duplicate), " << boundary_edges << " boundary edges, "
     << nonmanifold_edges << " non-manifold edges, " << misoriented_edges << " misoriented edges";
  if (!bounds.empty()) {
    const Vec3 e = bounds.extent();
    os << ", box [" << fmt(bounds.lo.x()) << ", " << fmt(bounds.lo.y()) << ", " << fmt(bounds.lo.z()) << "] .. ["
       << fmt(bounds.hi.x()) << ", " << fmt(bounds.hi.y()) << ", " << fmt(bounds.hi.z()) << "] (extent " << fmt(e.x())
       << " x " << fmt(e.y()) << " x " << fmt(e.z()) << ")";
  }
  return os.str();
}

geo::Aabb meshBounds(const TriangleMesh& mesh) {
  geo::Aabb b;
  for (const Vec3& v : mesh.vertices) b.grow(v);
  return b;
}

double signedVolume(const TriangleMesh& mesh) {
  double v = 0.0;
  for (int t = 0; t < mesh.triangleCount(); ++t)
    v += mesh.vertex(t, 0).dot(mesh.vertex(t, 1).cross(mesh.vertex(t, 2)));
  return v / 6.0;
}

SurfaceVerdict classifySurface(const geo::MeshBvh& bvh, int samples) {
  SurfaceVerdict v;
  const TriangleMesh& mesh = bvh.mesh();
  const int n = mesh.triangleCount();
  if (n == 0 || samples <= 0) {
    v.kind = SurfaceVerdict::Kind::Shell;
    return v;
  }
  const double eps = 1e-6 * bvh.bounds().extent().norm();
  const int windows = std::min(n, samples);
  for (int w = 0; w < windows; ++w) {
    // The largest triangle of this window of the list: its centroid is farthest from its edges.
    const int lo = static_cast<int>(static_cast<long long>(w) * n / windows);
    const int hi = static_cast<int>(static_cast<long long>(w + 1) * n / windows);
    int best = -1;
    double best_area = 0.0;
    Vec3 best_normal = Vec3::Zero();
    for (int t = lo; t < hi; ++t) {
      const Vec3 a = mesh.vertex(t, 0);
      const Vec3 cross = (mesh.vertex(t, 1) - a).cross(mesh.vertex(t, 2) - a);
      const double area = cross.norm();
      if (area > best_area) {
        best = t;
        best_area = area;
        best_normal = cross / area;
      }
    }
    if (best < 0) continue;
    const Vec3 c = (mesh.vertex(best, 0) + mesh.vertex(best, 1) + mesh.vertex(best, 2)) / 3.0;
    const double behind = bvh.windingNumber(c - eps * best_normal), front = bvh.windingNumber(c + eps * best_normal);
    ++v.samples;
    const double tol = SurfaceVerdict::kTolerance;
    if (std::abs(behind - 1.0) <= tol && std::abs(front) <= tol) ++v.outward;
    if (std::abs(behind) <= tol && std::abs(front + 1.0) <= tol) ++v.inward;
  }
  const double need = SurfaceVerdict::kDecided * v.samples;
  v.kind = v.samples > 0 && v.outward >= need  ? SurfaceVerdict::Kind::Solid
           : v.samples > 0 && v.inward >= need ? SurfaceVerdict::Kind::Inverted
                                               : SurfaceVerdict::Kind::Shell;
  return v;
}

std::string SurfaceVerdict::describe() const {
  const std::string of = " of " + std::to_string(samples) + " surface samples";
  switch (kind) {
    case Kind::Solid: return "closed solid (" + std::to_string(outward) + of + " inside/outside as oriented)";
    case Kind::Inverted: return "closed solid with inward-facing triangles (" + std::to_string(inward) + of + "): turned outward";
    case Kind::Shell: break;
  }
  return "open surface (inside/outside decided at " + std::to_string(std::max(outward, inward)) + of +
         "): a thin shell, touched from either side, no inside";
}

TriangleMesh flipped(TriangleMesh mesh) {
  for (Tri& t : mesh.triangles) std::swap(t[1], t[2]);
  return mesh;
}

void countEdges(const TriangleMesh& mesh, MeshStats* stats) {
  // Key: (min << 32 | max) << 1 | direction bit; sorted, runs are the uses of one edge.
  std::vector<uint64_t> keys;
  keys.reserve(mesh.triangles.size() * 3);
  for (const Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const auto u = static_cast<uint64_t>(static_cast<uint32_t>(t[static_cast<size_t>(k)]));
      const auto v = static_cast<uint64_t>(static_cast<uint32_t>(t[static_cast<size_t>((k + 1) % 3)]));
      const uint64_t lo = std::min(u, v), hi = std::max(u, v);
      keys.push_back((((lo << 32) | hi) << 1) | (u < v ? 1u : 0u));
    }
  }
  std::sort(keys.begin(), keys.end());
  stats->boundary_edges = stats->nonmanifold_edges = stats->misoriented_edges = 0;
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && (keys[j] >> 1) == (keys[i] >> 1)) ++j;
    const size_t uses = j - i;
    if (uses == 1) ++stats->boundary_edges;
    else if (uses > 2) ++stats->nonmanifold_edges;
    else if ((keys[i] & 1u) == (keys[i + 1] & 1u)) ++stats->misoriented_edges;
    i = j;
  }
  stats->bounds = meshBounds(mesh);
}

TriangleMesh cleanMesh(const TriangleMesh& raw, MeshStats* stats_out) {
  MeshStats local;
  MeshStats& st = stats_out ? *stats_out : local;
  st.input_vertices = static_cast<long long>(raw.vertices.size());
  st.input_triangles = static_cast<long long>(raw.triangles.size());

  // 1. Weld bit-identical vertices.
  std::unordered_map<VertexKey, int, VertexKeyHash> index;
  index.reserve(raw.vertices.size());
  std::vector<int> remap(raw.vertices.size());
  std::vector<Vec3> unique;
  unique.reserve(raw.vertices.size());
  for (size_t i = 0; i < raw.vertices.size(); ++i) {
    const Vec3& v = raw.vertices[i];
    const auto ins = index.emplace(VertexKey{bitsOf(v.x()), bitsOf(v.y()), bitsOf(v.z())}, static_cast<int>(unique.size()));
    if (ins.second) unique.push_back(v);
    remap[i] = ins.first->second;
  }
  st.welded = static_cast<long long>(raw.vertices.size() - unique.size());

  // 2. Degenerate triangles (size from the vertices triangles use).
  geo::Aabb used;
  for (const Tri& t : raw.triangles)
    for (int k : t) used.grow(raw.vertices[static_cast<size_t>(k)]);
  const double L = used.empty() ? 0.0 : used.extent().norm();
  const double min_cross = kZeroArea * L * L;
  std::vector<Tri> tris;
  tris.reserve(raw.triangles.size());
  st.degenerate_dropped = 0;
  for (const Tri& t0 : raw.triangles) {
    const Tri t{remap[static_cast<size_t>(t0[0])], remap[static_cast<size_t>(t0[1])], remap[static_cast<size_t>(t0[2])]};
    bool degenerate = t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
    if (!degenerate) {
      const Vec3& a = unique[static_cast<size_t>(t[0])];
      degenerate = !((unique[static_cast<size_t>(t[1])] - a).cross(unique[static_cast<size_t>(t[2])] - a).norm() > min_cross);
    }
    if (degenerate) ++st.degenerate_dropped;
    else tris.push_back(t);
  }

  // 3. Duplicates (any vertex order).
  const std::vector<char> dup = duplicateMask(tris);
  st.duplicates_dropped = 0;
  TriangleMesh out;
  out.triangles.reserve(tris.size());
  for (size_t i = 0; i < tris.size(); ++i) {
    if (dup[i]) ++st.duplicates_dropped;
    else out.triangles.push_back(tris[i]);
  }

  // 4. Compact: keep used vertices in their original order.
  std::vector<int> newIndex(unique.size(), -1);
  for (const Tri& t : out.triangles)
    for (int k : t) newIndex[static_cast<size_t>(k)] = 0;
  for (size_t i = 0; i < unique.size(); ++i) {
    if (newIndex[i] < 0) continue;
    newIndex[i] = static_cast<int>(out.vertices.size());
    out.vertices.push_back(unique[i]);
  }
  for (Tri& t : out.triangles)
    for (int& k : t) k = newIndex[static_cast<size_t>(k)];
  st.unreferenced = static_cast<long long>(unique.size() - out.vertices.size());
  st.output_vertices = static_cast<long long>(out.vertices.size());
  st.output_triangles = static_cast<long long>(out.triangles.size());

  // 5. Open edges, bounds.
  countEdges(out, &st);
  return out;
}

namespace {

TriangleMesh finish(const TriangleMesh& raw, const std::string& source, long long last_line, MeshStats* stats) {
  MeshStats st;
  TriangleMesh m = cleanMesh(raw, &st);
  if (m.triangles.empty()) {
    if (raw.triangles.empty()) fail(source, last_line, "no triangles in mesh file");
    fail(source, last_line, "no triangles left after cleaning (" + std::to_string(st.degenerate_dropped) +
                                " degenerate, " + std::to_string(st.duplicates_dropped) + " duplicate)");
  }
  if (stats) *stats = st;
  return m;
}

}  // namespace

TriangleMesh parseObj(const std::string& text, const std::string& source, MeshStats* stats) {
  TriangleMesh raw;
  std::vector<long long> tri_line;  // for out-of-range forward references
  std::vector<std::string_view> tok;
  std::vector<long long> poly;
  const long long lines = forEachLine(text, [&](long long line, const char* b, const char* e) {
    if (std::memchr(b, '\0', static_cast<size_t>(e - b))) fail(source, line, "binary data in OBJ text (not an OBJ file?)");
    tokenize(b, e, &tok);
    for (size_t k = 0; k < tok.size(); ++k)
      if (tok[k][0] == '#') { tok.resize(k); break; }  // comment to the end of the line
    if (tok.empty()) return;
    if (tok[0] == "v") {
      if (tok.size() < 4) fail(source, line, "vertex needs 3 coordinates");
      Vec3 v;
      for (int k = 0; k < 3; ++k)
        if (!parseDouble(tok[static_cast<size_t>(k + 1)], &v[k]))
          fail(source, line, "bad vertex coordinate " + quoted(tok[static_cast<size_t>(k + 1)]));
      if (!v.allFinite()) fail(source, line, "non-finite vertex coordinate");
      raw.vertices.push_back(v);
    } else if (tok[0] == "f") {
      poly.clear();
      const auto nv = static_cast<long long>(raw.vertices.size());
      for (size_t k = 1; k < tok.size(); ++k) {
        const std::string_view t = tok[k];
        const std::string_view first = t.substr(0, t.find('/'));
        long long idx = 0;
        if (!parseInt(first, &idx)) fail(source, line, "bad face vertex " + quoted(t));
        if (idx == 0) fail(source, line, "face vertex index 0 (OBJ indices start at 1)");
        if (idx < 0) {
          if (-idx > nv) fail(source, line, "relative face index " + std::to_string(idx) + " out of range (" +
                                                std::to_string(nv) + " vertices so far)");
          idx = nv + idx;
        } else {
          idx -= 1;
          if (idx > 2147483646) fail(source, line, "face index " + std::to_string(idx + 1) + " out of range");
        }
        poly.push_back(idx);
      }
      if (poly.size() < 3) fail(source, line, "face needs at least 3 vertices");
      for (size_t k = 1; k + 1 < poly.size(); ++k) {
        raw.triangles.push_back({static_cast<int>(poly[0]), static_cast<int>(poly[k]), static_cast<int>(poly[k + 1])});
        tri_line.push_back(line);
      }
    }
    // Everything else (vt, vn, g, o, s, usemtl, mtllib, l, p, ...) is ignored.
  });
  for (size_t i = 0; i < raw.triangles.size(); ++i)
    for (int k : raw.triangles[i])
      if (k >= static_cast<int>(raw.vertices.size()))
        fail(source, tri_line[i], "face index " + std::to_string(k + 1) + " out of range (file has " +
                                      std::to_string(raw.vertices.size()) + " vertices)");
  return finish(raw, source, std::max(1LL, lines), stats);
}

namespace {

TriangleMesh parseStlBinary(const std::string& bytes, const std::string& source, MeshStats* stats) {
  uint32_t n = 0;
  std::memcpy(&n, bytes.data() + 80, 4);
  TriangleMesh raw;
  raw.vertices.reserve(size_t{3} * n);
  raw.triangles.reserve(n);
  for (uint32_t i = 0; i < n; ++i) {
    const char* rec = bytes.data() + 84 + size_t{50} * i;
    float f[9];
    std::memcpy(f, rec + 12, sizeof f);  // skip the normal
    const int base = static_cast<int>(raw.vertices.size());
    for (int k = 0; k < 3; ++k) {
      const Vec3 v(f[3 * k], f[3 * k + 1], f[3 * k + 2]);
      if (!v.allFinite())
        throw MeshError(source + ":triangle " + std::to_string(i + 1) + ": non-finite vertex coordinate");
      raw.vertices.push_back(v);
    }
    raw.triangles.push_back({base, base + 1, base + 2});
  }
  if (n == 0) throw MeshError(source + ":triangle 0: binary STL with no triangles");
  try {
    return finish(raw, source, 0, stats);
  } catch (const MeshError&) {
    throw MeshError(source + ":triangle " + std::to_string(n) + ": no triangles left after cleaning (all degenerate or duplicate)");
  }
}

TriangleMesh parseStlAscii(const std::string& text, const std::string& source, MeshStats* stats) {
  TriangleMesh raw;
  std::vector<std::string_view> tok;
  bool in_loop = false;
  long long loop_line = 0;
  std::vector<int> poly;
  const long long lines = forEachLine(text, [&](long long line, const char* b, const char* e) {
    tokenize(b, e, &tok);
    if (tok.empty()) return;
    const std::string_view k = tok[0];
    if (k == "solid" || k == "endsolid") {
      if (in_loop) fail(source, line, quoted(k) + " inside a facet loop");
    } else if (k == "facet") {
      if (in_loop) fail(source, line, "'facet' inside a facet loop");
    } else if (k == "endfacet") {
      if (in_loop) fail(source, line, "'endfacet' before 'endloop'");
    } else if (k == "outer") {
      if (in_loop) fail(source, line, "'outer loop' inside a facet loop");
      in_loop = true;
      loop_line = line;
      poly.clear();
    } else if (k == "vertex") {
      if (!in_loop) fail(source, line, "'vertex' outside 'outer loop'");
      if (tok.size() < 4) fail(source, line, "vertex needs 3 coordinates");
      Vec3 v;
      for (int c = 0; c < 3; ++c)
        if (!parseDouble(tok[static_cast<size_t>(c + 1)], &v[c]))
          fail(source, line, "bad vertex coordinate " + quoted(tok[static_cast<size_t>(c + 1)]));
      if (!v.allFinite()) fail(source, line, "non-finite vertex coordinate");
      poly.push_back(static_cast<int>(raw.vertices.size()));
      raw.vertices.push_back(v);
    } else if (k == "endloop") {
      if (!in_loop) fail(source, line, "'endloop' without 'outer loop'");
      if (poly.size() < 3) fail(source, loop_line, "facet needs at least 3 vertices");
      for (size_t i = 1; i + 1 < poly.size(); ++i) raw.triangles.push_back({poly[0], poly[i], poly[i + 1]});
      in_loop = false;
    } else {
      fail(source, line, "unexpected " + quoted(k) + " in ASCII STL");
    }
  });
  if (in_loop) fail(source, std::max(1LL, lines), "file ends inside a facet loop (opened at line " + std::to_string(loop_line) + ")");
  return finish(raw, source, std::max(1LL, lines), stats);
}

}  // namespace

TriangleMesh parseStl(const std::string& bytes, const std::string& source, MeshStats* stats) {
  // Binary: 80-byte header, uint32 count, 50 bytes per triangle. Binary files may also start
  // with "solid", so the size decides, unless the whole file is plain text starting with "solid".
  size_t s = 0;
  while (s < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[s]))) ++s;
  const bool starts_solid = bytes.compare(s, 5, "solid") == 0;
  bool size_ok = false;
  uint32_t n = 0;
  if (bytes.size() >= 84) {
    std::memcpy(&n, bytes.data() + 80, 4);
    size_ok = uint64_t{84} + uint64_t{50} * n == bytes.size();
  }
  bool text = true;
  for (char c : bytes) {
    const auto u = static_cast<unsigned char>(c);
    if (u == 127 || (u < 32 && u != '\t' && u != '\n' && u != '\r' && u != '\v' && u != '\f')) { text = false; break; }
  }
  if (size_ok && !(starts_solid && text)) return parseStlBinary(bytes, source, stats);
  if (starts_solid) return parseStlAscii(bytes, source, stats);
  if (bytes.size() >= 84)
    fail(source, 1, "not an STL file: no 'solid' and the binary header's " + std::to_string(n) + " triangles need " +
                        std::to_string(uint64_t{84} + uint64_t{50} * n) + " bytes, the file has " + std::to_string(bytes.size()));
  fail(source, 1, "not an STL file: no 'solid' and too short (" + std::to_string(bytes.size()) + " bytes) for binary STL");
}

std::string meshFormat(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext != ".obj" && ext != ".stl") fail(path, 0, "unsupported mesh format '" + ext + "' (expected .obj or .stl)");
  return ext;
}

TriangleMesh parseMeshFile(const std::string& bytes, const std::string& path, MeshStats* stats) {
  return meshFormat(path) == ".obj" ? parseObj(bytes, path, stats) : parseStl(bytes, path, stats);
}

// ---------------------------------------------------------------------------------------------

TriangleMesh decimate(const TriangleMesh& mesh, int target_triangles, double* cell_size) {
  if (target_triangles < 4) throw std::invalid_argument("decimate: target_triangles must be >= 4");
  if (cell_size) *cell_size = 0.0;
  if (mesh.triangleCount() <= target_triangles) return mesh;
  const geo::Aabb box = meshBounds(mesh);
  const Vec3 lo = box.lo;
  const double L = box.extent().maxCoeff();
  double area = 0.0;
  for (int t = 0; t < mesh.triangleCount(); ++t)
    area += 0.5 * (mesh.vertex(t, 1) - mesh.vertex(t, 0)).cross(mesh.vertex(t, 2) - mesh.vertex(t, 0)).norm();

  auto cluster = [&](double cell) {
    const double lim = 2097151.0;  // 21 bits per axis
    std::unordered_map<uint64_t, int> id;
    id.reserve(mesh.vertices.size());
    std::vector<int> of(mesh.vertices.size());
    std::vector<Vec3> sum;
    std::vector<int> count;
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
      const Vec3 q = ((mesh.vertices[i] - lo) / cell).array().floor().min(lim).max(0.0);
      const uint64_t key = (static_cast<uint64_t>(q.x()) << 42) | (static_cast<uint64_t>(q.y()) << 21) | static_cast<uint64_t>(q.z());
      const auto ins = id.emplace(key, static_cast<int>(sum.size()));
      if (ins.second) { sum.push_back(Vec3::Zero()); count.push_back(0); }
      of[i] = ins.first->second;
      sum[static_cast<size_t>(of[i])] += mesh.vertices[i];
      ++count[static_cast<size_t>(of[i])];
    }
    TriangleMesh out;
    out.vertices.resize(sum.size());
    for (size_t c = 0; c < sum.size(); ++c) out.vertices[c] = sum[c] / count[c];
    for (const Tri& t : mesh.triangles) {
      const Tri u{of[static_cast<size_t>(t[0])], of[static_cast<size_t>(t[1])], of[static_cast<size_t>(t[2])]};
      if (u[0] != u[1] && u[1] != u[2] && u[0] != u[2]) out.triangles.push_back(u);
    }
    return cleanMesh(out);
  };

  // Triangles ≈ k / cell² on a surface: start from the area, correct by that law.
  double cell = std::sqrt(3.0 * area / target_triangles);
  if (!(cell > 0.0) || !std::isfinite(cell)) cell = L / std::sqrt(static_cast<double>(target_triangles));
  cell = std::max(cell, L / 2.0e6);
  TriangleMesh best;
  double best_err = std::numeric_limits<double>::infinity(), best_cell = cell;
  for (int it = 0; it < 10; ++it) {
    TriangleMesh m = cluster(cell);
    const double n = std::max(1, m.triangleCount());
    const double err = std::abs(std::log(n / target_triangles));
    if (err < best_err && m.triangleCount() > 0) { best_err = err; best = std::move(m); best_cell = cell; }
    if (best_err < std::log(1.08)) break;
    cell = std::max(cell * std::clamp(std::sqrt(n / target_triangles), 0.5, 2.0), L / 2.0e6);
  }
  if (best.triangles.empty()) return mesh;
  if (cell_size) *cell_size = best_cell;
  return best;
}

// Quickhull (Barber, Dobkin & Huhdanpaa 1996) in double precision. Not Bullet's
// btConvexHullComputer: it snaps its input to a grid of extent/10216 per axis, so its hull
// vertices are not input points and input points end up outside by up to ~1e-4 of the extent.
// Here a point counts as outside a face only beyond eps = 1e-12-ish of the coordinates' size, so
// every input point is inside or within eps of the hull, and hull vertices are input points.
TriangleMesh convexHull(const std::vector<Vec3>& points) {
  if (points.size() < 4) throw std::invalid_argument("convex hull needs at least 4 points");
  geo::Aabb box;
  for (const Vec3& p : points) {
    if (!p.allFinite()) throw std::invalid_argument("convex hull: non-finite point");
    box.grow(p);
  }
  const double eps = 3.0 * std::numeric_limits<double>::epsilon() *
                     (box.lo.cwiseAbs().cwiseMax(box.hi.cwiseAbs())).sum() * 16.0;
  const int n = static_cast<int>(points.size());
  auto P = [&](int i) -> const Vec3& { return points[static_cast<size_t>(i)]; };

  // Initial tetrahedron: extreme pair, farthest from its line, farthest from that plane.
  int i0 = 0, i1 = 0;
  {
    double best = -1.0;
    for (int ax = 0; ax < 3; ++ax) {
      int lo = 0, hi = 0;
      for (int i = 1; i < n; ++i) {
        if (P(i)[ax] < P(lo)[ax]) lo = i;
        if (P(i)[ax] > P(hi)[ax]) hi = i;
      }
      if (P(hi)[ax] - P(lo)[ax] > best) { best = P(hi)[ax] - P(lo)[ax]; i0 = lo; i1 = hi; }
    }
    if (!(best > eps)) throw std::invalid_argument("convex hull: the points span no volume (all equal)");
  }
  const Vec3 dir = (P(i1) - P(i0)).normalized();
  int i2 = -1;
  double best2 = eps;
  for (int i = 0; i < n; ++i) {
    const Vec3 d = P(i) - P(i0);
    const double dist = (d - d.dot(dir) * dir).norm();
    if (dist > best2) { best2 = dist; i2 = i; }
  }
  if (i2 < 0) throw std::invalid_argument("convex hull: the points span no volume (collinear)");
  const Vec3 n012 = (P(i1) - P(i0)).cross(P(i2) - P(i0)).normalized();
  int i3 = -1;
  double best3 = eps;
  for (int i = 0; i < n; ++i) {
    const double dist = std::abs(n012.dot(P(i) - P(i0)));
    if (dist > best3) { best3 = dist; i3 = i; }
  }
  if (i3 < 0) throw std::invalid_argument("convex hull: the points span no volume (coplanar)");

  struct Face {
    Tri v;
    Vec3 n;
    double d;
    bool alive = true;
    std::vector<int> outside;
  };
  std::vector<Face> faces;
  std::unordered_map<uint64_t, int> edge_face;  // directed edge (a -> b) -> face
  auto key = [](int a, int b) { return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b); };
  auto addFace = [&](int a, int b, int c) {
    Face f;
    f.v = {a, b, c};
    f.n = (P(b) - P(a)).cross(P(c) - P(a)).normalized();
    f.d = f.n.dot(P(a));
    const int id = static_cast<int>(faces.size());
    faces.push_back(std::move(f));
    edge_face[key(a, b)] = id;
    edge_face[key(b, c)] = id;
    edge_face[key(c, a)] = id;
    return id;
  };
  if (n012.dot(P(i3) - P(i0)) > 0.0) std::swap(i1, i2);  // make (i0, i1, i2) face away from i3
  addFace(i0, i1, i2);
  addFace(i0, i3, i1);
  addFace(i1, i3, i2);
  addFace(i2, i3, i0);

  auto assign = [&](int p, const std::vector<int>& candidates) {
    for (int f : candidates) {
      if (faces[static_cast<size_t>(f)].n.dot(P(p)) - faces[static_cast<size_t>(f)].d > eps) {
        faces[static_cast<size_t>(f)].outside.push_back(p);
        return;
      }
    }
  };
  {
    const std::vector<int> first{0, 1, 2, 3};
    for (int i = 0; i < n; ++i)
      if (i != i0 && i != i1 && i != i2 && i != i3) assign(i, first);
  }

  std::vector<int> stack, visible, new_faces, orphans;
  std::vector<std::pair<int, int>> horizon;
  std::vector<int> visit(faces.size(), 0);
  int stamp = 0;
  for (size_t fi = 0; fi < faces.size(); ++fi) {
    if (!faces[fi].alive || faces[fi].outside.empty()) continue;
    // Farthest outside point of this face.
    int apex = -1;
    double far = -1.0;
    for (int p : faces[fi].outside) {
      const double d = faces[fi].n.dot(P(p)) - faces[fi].d;
      if (d > far) { far = d; apex = p; }
    }
    // Faces visible from the apex (connected to fi), and the horizon edges around them.
    ++stamp;
    visit.resize(faces.size(), 0);
    visible.clear();
    horizon.clear();
    stack.assign(1, static_cast<int>(fi));
    visit[fi] = stamp;
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      visible.push_back(f);
      for (int k = 0; k < 3; ++k) {
        const int a = faces[static_cast<size_t>(f)].v[static_cast<size_t>(k)];
        const int b = faces[static_cast<size_t>(f)].v[static_cast<size_t>((k + 1) % 3)];
        const int g = edge_face.at(key(b, a));
        const Face& G = faces[static_cast<size_t>(g)];
        if (visit[static_cast<size_t>(g)] == stamp) continue;
        if (G.n.dot(P(apex)) - G.d > eps) {
          visit[static_cast<size_t>(g)] = stamp;
          stack.push_back(g);
        } else {
          horizon.emplace_back(a, b);
        }
      }
    }
    // Replace the visible faces by a cone from the horizon to the apex.
    orphans.clear();
    for (int f : visible) {
      Face& F = faces[static_cast<size_t>(f)];
      F.alive = false;
      for (int p : F.outside)
        if (p != apex) orphans.push_back(p);
      F.outside.clear();
      F.outside.shrink_to_fit();
      for (int k = 0; k < 3; ++k) {
        const auto it = edge_face.find(key(F.v[static_cast<size_t>(k)], F.v[static_cast<size_t>((k + 1) % 3)]));
        if (it != edge_face.end() && it->second == f) edge_face.erase(it);
      }
    }
    new_faces.clear();
    for (const auto& e : horizon) new_faces.push_back(addFace(e.first, e.second, apex));
    for (int p : orphans) assign(p, new_faces);
  }

  // Compact.
  TriangleMesh m;
  std::unordered_map<int, int> index;
  for (const Face& f : faces) {
    if (!f.alive) continue;
    Tri t;
    for (int k = 0; k < 3; ++k) {
      const auto ins = index.emplace(f.v[static_cast<size_t>(k)], static_cast<int>(m.vertices.size()));
      if (ins.second) m.vertices.push_back(P(f.v[static_cast<size_t>(k)]));
      t[static_cast<size_t>(k)] = ins.first->second;
    }
    m.triangles.push_back(t);
  }
  return m;
}

TriangleMesh uniformScale(TriangleMesh mesh, double s) {
  for (Vec3& v : mesh.vertices) v *= s;
  return mesh;
}

TriangleMesh translate(TriangleMesh mesh, const Vec3& t) {
  for (Vec3& v : mesh.vertices) v += t;
  return mesh;
}

TriangleMesh boxMesh(const Vec3& e) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i)
    m.vertices.emplace_back((i & 1) ? e.x() : -e.x(), (i & 2) ? e.y() : -e.y(), (i & 4) ? e.z() : -e.z());
  // Two triangles per face (corner bits: 1 = +x, 2 = +y, 4 = +z); orientation fixed below.
  m.triangles = {{0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3},   // -x, +x
                 {0, 4, 5}, {0, 5, 1}, {2, 3, 7}, {2, 7, 6},   // -y, +y
                 {0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}};  // -z, +z
  orientAwayFromOrigin(&m);
  return m;
}

TriangleMesh sphereMesh(double r, int levels) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.vertices = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  m.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (Vec3& v : m.vertices) v.normalize();
  for (int l = 0; l < levels; ++l) {
    m = subdivide(m, 1);
    for (Vec3& v : m.vertices) v.normalize();
  }
  orientAwayFromOrigin(&m);
  // Radial projection is a bijection onto the sphere, so the polyhedron is star-shaped about the
  // origin: a ray leaves it through some face at a distance ≥ that face's plane distance.
  double d_min = 1.0;
  for (int t = 0; t < m.triangleCount(); ++t) {
    const Vec3 a = m.vertex(t, 0);
    const Vec3 n = (m.vertex(t, 1) - a).cross(m.vertex(t, 2) - a).normalized();
    d_min = std::min(d_min, n.dot(a));
  }
  const double s = r / d_min * (1.0 + 1e-12);  // round-off margin: never inscribed below r
  for (Vec3& v : m.vertices) v *= s;
  return m;
}

TriangleMesh cylinderMesh(double r, double h, int segments) {
  const int n = std::max(3, segments);
  const double pi = 3.14159265358979323846;
  const double R = r / std::cos(pi / n) * (1.0 + 1e-12);
  TriangleMesh m;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * pi * i / n;
    m.vertices.emplace_back(R * std::cos(a), R * std::sin(a), -h);
  }
  for (int i = 0; i < n; ++i) m.vertices.emplace_back(m.vertices[static_cast<size_t>(i)].x(), m.vertices[static_cast<size_t>(i)].y(), h);
  const int cb = 2 * n, ct = 2 * n + 1;
  m.vertices.emplace_back(0.0, 0.0, -h);
  m.vertices.emplace_back(0.0, 0.0, h);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    m.triangles.push_back({i, j, n + j});
    m.triangles.push_back({i, n + j, n + i});
    m.triangles.push_back({cb, j, i});
    m.triangles.push_back({ct, n + i, n + j});
  }
  return m;  // wound outward by construction (tested)
}

TriangleMesh subdivide(const TriangleMesh& mesh, int levels) {
  TriangleMesh cur = mesh;
  for (int l = 0; l < levels; ++l) {
    TriangleMesh next;
    next.vertices = cur.vertices;
    next.vertices.reserve(cur.vertices.size() + cur.triangles.size() * 3 / 2 + 16);
    next.triangles.reserve(cur.triangles.size() * 4);
    std::unordered_map<uint64_t, int> mid;
    mid.reserve(cur.triangles.size() * 3 / 2 + 16);
    auto midpoint = [&](int a, int b) {
      const auto lo = static_cast<uint64_t>(std::min(a, b)), hi = static_cast<uint64_t>(std::max(a, b));
      const auto ins = mid.emplace((lo << 32) | hi, static_cast<int>(next.vertices.size()));
      if (ins.second) next.vertices.push_back(0.5 * (cur.vertices[static_cast<size_t>(a)] + cur.vertices[static_cast<size_t>(b)]));
      return ins.first->second;
    };
    for (const Tri& t : cur.triangles) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      next.triangles.push_back({t[0], ab, ca});
      next.triangles.push_back({ab, t[1], bc});
      next.triangles.push_back({ca, bc, t[2]});
      next.triangles.push_back({ab, bc, ca});
    }
    cur = std::move(next);
  }
  return cur;
}

}  // namespace godhand
