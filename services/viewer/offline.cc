#include "viewer/offline.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "scene/mesh_io.h"
#include "viewer/encode.h"

namespace godhand::viewer {

using nlohmann::json;

namespace {

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else if (c != '\r') {
      cur.push_back(c);
    }
  }
  out.push_back(cur);
  return out;
}

bool parseDouble(const std::string& s, double* v) {
  if (s.empty()) return false;
  std::size_t used = 0;
  try {
    *v = std::stod(s, &used);
  } catch (...) {
    return false;
  }
  return used == s.size() && std::isfinite(*v);
}

}  // namespace

PoseFile parsePosesCsv(const std::string& text, const std::string& source) {
  std::istringstream in(text);
  std::string line;
  std::size_t line_no = 0;
  auto fail = [&](const std::string& why) { throw PosesError(source + ":" + std::to_string(line_no) + ": " + why); };
  if (!std::getline(in, line)) {
    line_no = 1;
    fail("empty file (expected a header line)");
  }
  line_no = 1;
  const std::vector<std::string> header = splitCsv(line);
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < header.size(); ++i) {
    if (col.count(header[i])) fail("column '" + header[i] + "' appears twice");
    col[header[i]] = i;
  }
  const char* required[] = {"frame", "hand", "body", "shape", "radius", "half_length", "hx", "hy",
                            "hz",    "px",   "py",   "pz",    "qw",     "qx",          "qy", "qz"};
  for (const char* r : required)
    if (!col.count(r)) fail(std::string("missing column '") + r + "'");
  const char* tcols[] = {"tpx", "tpy", "tpz", "tqw", "tqx", "tqy", "tqz"};
  int tcount = 0;
  for (const char* t : tcols) tcount += col.count(t) ? 1 : 0;
  if (tcount != 0 && tcount != 7) fail("target columns must be all of tpx,tpy,tpz,tqw,tqx,tqy,tqz or none");
  PoseFile f;
  f.has_targets = tcount == 7;

  std::map<std::string, std::size_t> hand_index;
  std::vector<std::map<std::string, std::size_t>> body_index;
  std::int64_t last_frame = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> cells = splitCsv(line);
    if (cells.size() != header.size())
      fail(std::to_string(cells.size()) + " cells, the header has " + std::to_string(header.size()));
    auto cell = [&](const char* name) -> const std::string& { return cells[col.at(name)]; };
    auto number = [&](const char* name) {
      double v = 0;
      if (!parseDouble(cell(name), &v)) fail(std::string(name) + ": not a finite number: '" + cell(name).substr(0, 40) + "'");
      return v;
    };
    const double frame_d = number("frame");
    if (frame_d != std::floor(frame_d) || frame_d < 0 || frame_d > 9e15) fail("frame: not a whole number >= 0");
    const auto frame = static_cast<std::int64_t>(frame_d);
    if (f.frames.empty() || frame > last_frame) {
      f.frames.push_back(frame);
      last_frame = frame;
      for (PoseTrack& h : f.hands) {
        h.poses.emplace_back();
        if (f.has_targets) h.targets.emplace_back();
      }
    } else if (frame < last_frame) {
      fail("frame " + std::to_string(frame) + " after frame " + std::to_string(last_frame) + " (rows must be in frame order)");
    }
    const std::string& hand = cell("hand");
    if (hand.empty() || hand.size() > 32) fail("hand: empty or longer than 32 characters");
    auto hi = hand_index.find(hand);
    if (hi == hand_index.end()) {
      hi = hand_index.emplace(hand, f.hands.size()).first;
      PoseTrack t;
      t.hand = hand;
      t.poses.resize(f.frames.size());
      if (f.has_targets) t.targets.resize(f.frames.size());
      f.hands.push_back(std::move(t));
      body_index.emplace_back();
    }
    PoseTrack& h = f.hands[hi->second];
    const std::string& body = cell("body");
    if (body.empty() || body.size() > 64) fail("body: empty or longer than 64 characters");
    const std::string& shape = cell("shape");
    double type = 0;
    if (shape == "capsule") type = 0;
    else if (shape == "sphere") type = 1;
    else if (shape == "box") type = 2;
    else fail("shape: '" + shape.substr(0, 20) + "' (expected capsule, sphere or box)");
    const std::array<double, 6> sh{type, number("radius"), number("half_length"), number("hx"), number("hy"), number("hz")};
    for (std::size_t i = 1; i < 6; ++i)
      if (sh[i] < 0 || sh[i] > 10) fail("shape dimensions must be in [0, 10] m");
    auto& bi = body_index[hi->second];
    auto b = bi.find(body);
    if (b == bi.end()) {
      if (h.bodies.size() >= 64) fail("more than 64 bodies in hand '" + hand + "'");
      b = bi.emplace(body, h.bodies.size()).first;
      h.bodies.push_back(body);
      h.shapes.push_back(sh);
      // Earlier frames of this hand get room for the new body (NaN: not drawn).
      for (auto& fr : h.poses)
        if (!fr.empty()) fr.resize(7 * h.bodies.size(), NAN);
      for (auto& fr : h.targets)
        if (!fr.empty()) fr.resize(7 * h.bodies.size(), NAN);
    } else if (h.shapes[b->second] != sh) {
      fail("body '" + body + "' of hand '" + hand + "' changes shape");
    }
    auto pose = [&](const char* const names[7], std::vector<double>* dst) {
      double v[7];
      for (int i = 0; i < 7; ++i) v[i] = number(names[i]);
      const double qn = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
      if (std::abs(qn - 1.0) > 1e-6) fail(std::string(names[3]) + "..: quaternion not unit (norm " + std::to_string(qn) + ")");
      for (int i = 0; i < 7; ++i) (*dst)[7 * b->second + static_cast<std::size_t>(i)] = v[i];
    };
    std::vector<double>& fp = h.poses.back();
    if (fp.size() < 7 * h.bodies.size()) fp.resize(7 * h.bodies.size(), NAN);
    if (!std::isnan(fp[7 * b->second])) fail("body '" + body + "' of hand '" + hand + "' twice in frame " + std::to_string(frame));
    static const char* const pcols[7] = {"px", "py", "pz", "qw", "qx", "qy", "qz"};
    pose(pcols, &fp);
    if (f.has_targets) {
      int empty = 0;
      for (const char* t : tcols) empty += cell(t).empty() ? 1 : 0;
      std::vector<double>& ft = h.targets.back();
      if (ft.size() < 7 * h.bodies.size()) ft.resize(7 * h.bodies.size(), NAN);
      if (empty == 0) pose(tcols, &ft);
      else if (empty != 7) fail("target columns: all seven or none of a row may be empty");
    }
    ++f.rows;
  }
  if (f.rows == 0) fail("no pose rows");
  // Frames where a hand had rows for only some bodies keep NaN for the others (not drawn).
  for (PoseTrack& h : f.hands) {
    for (auto& fr : h.poses)
      if (!fr.empty()) fr.resize(7 * h.bodies.size(), NAN);
    for (auto& fr : h.targets)
      if (!fr.empty()) fr.resize(7 * h.bodies.size(), NAN);
  }
  return f;
}

PoseFile loadPosesCsv(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw PosesError(path + ": cannot read");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parsePosesCsv(ss.str(), path);
}

namespace {
json numbers(const std::vector<double>& v) {
  if (v.empty()) return nullptr;
  json a = json::array();
  for (double x : v) a.push_back(std::isfinite(x) ? json(x) : json(nullptr));
  return a;
}
}  // namespace

json poseFileJson(const PoseFile& f) {
  json hands = json::array();
  for (const PoseTrack& h : f.hands) {
    json poses = json::array(), targets = json::array(), shapes = json::array();
    for (const auto& fr : h.poses) poses.push_back(numbers(fr));
    for (const auto& fr : h.targets) targets.push_back(numbers(fr));
    for (const auto& s : h.shapes) shapes.push_back(json::array({static_cast<int>(s[0]), s[1], s[2], s[3], s[4], s[5]}));
    hands.push_back({{"name", h.hand}, {"bodies", h.bodies}, {"shapes", shapes}, {"poses", poses},
                     {"targets", f.has_targets ? targets : json(nullptr)}});
  }
  return {{"frames", f.frames}, {"hands", hands}, {"has_targets", f.has_targets}, {"rows", f.rows}};
}

json sceneJson(const Scene& scene, const std::string& file, const std::string& generation) {
  json objects = json::array();
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    msg::Pose p;
    p.p()[0] = o.X_WO.p.x();
    p.p()[1] = o.X_WO.p.y();
    p.p()[2] = o.X_WO.p.z();
    p.q()[0] = o.X_WO.q.w();
    p.q()[1] = o.X_WO.q.x();
    p.q()[2] = o.X_WO.q.y();
    p.q()[3] = o.X_WO.q.z();
    objects.push_back({{"index", static_cast<int>(i)},
                       {"id", o.id},
                       {"mesh", o.source},
                       {"scale", o.scale},
                       {"mass", o.mass},
                       {"dynamic", o.mass > 0.0 && o.physics.type != PhysicsShapeType::None},
                       {"triangles", o.god ? o.god->mesh().triangles.size() : 0u},
                       {"pose", poseJson(p)}});
  }
  return {{"name", scene.name}, {"file", file}, {"generation", generation}, {"objects", objects}};
}

bool displayMesh(const Scene& scene, int object, int max_triangles, geo::TriangleMesh* out) {
  if (object < 0 || object >= static_cast<int>(scene.objects.size())) return false;
  const SceneObject& o = scene.objects[static_cast<std::size_t>(object)];
  const geo::MeshBvh* m = o.reference ? o.reference.get() : o.god.get();
  if (!m || m->mesh().triangles.empty()) return false;
  if (static_cast<int>(m->mesh().triangles.size()) <= max_triangles) *out = m->mesh();
  else *out = decimate(m->mesh(), std::max(4, max_triangles));
  return true;
}

std::string meshBinary(const geo::TriangleMesh& mesh) {
  const auto nv = static_cast<std::uint32_t>(mesh.vertices.size());
  const auto nt = static_cast<std::uint32_t>(mesh.triangles.size());
  std::string out;
  out.reserve(12 + 12 * static_cast<std::size_t>(nv) + 12 * static_cast<std::size_t>(nt));
  out += "GHM1";
  auto u32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xffu));
  };
  u32(nv);
  u32(nt);
  for (const Vec3& v : mesh.vertices)
    for (int k = 0; k < 3; ++k) {
      const float x = static_cast<float>(v[k]);
      std::uint32_t bits = 0;
      std::memcpy(&bits, &x, 4);
      u32(bits);
    }
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) u32(static_cast<std::uint32_t>(t[static_cast<std::size_t>(k)]));
  return out;
}

}  // namespace godhand::viewer
