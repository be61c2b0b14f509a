#include "skeleton/jsonl.h"

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

namespace godhand::skeleton {

namespace {

using json = nlohmann::json;

struct Counter {
  std::map<std::string, std::uint64_t> n;
  void add(const std::string& r) { ++n[r]; }
};

/// Reads k finite numbers from an array; returns 0 ok, 1 shape, 2 not finite (JSON null).
int numbers(const json& a, size_t k, double* out) {
  if (!a.is_array() || a.size() != k) return 1;
  for (size_t i = 0; i < k; ++i) {
    if (a[i].is_null()) return 2;
    if (!a[i].is_number()) return 1;
    out[i] = a[i].get<double>();
    if (!std::isfinite(out[i])) return 2;
  }
  return 0;
}

}  // namespace

std::string jsonlFormat(const std::string& first_line) {
  const json h = json::parse(first_line, nullptr, false);
  if (!h.is_object()) return "";
  const auto f = h.find("format");
  if (f == h.end() || !f->is_string()) return "";
  if (*f == "godhand-openxr-hands") return "openxr";
  if (*f == "godhand-mediapipe-world") return "mediapipe";
  return "";
}

std::string jsonlFrameWithoutHeader(const std::string& first_line) {
  const json j = json::parse(first_line, nullptr, false);
  if (!j.is_object() || !j.contains("hands")) return "";
  if (j.contains("time_ns")) return "OpenXR";
  if (j.contains("time_us")) return "MediaPipe";
  return "";
}

std::string JsonlRecording::summary() const {
  std::string s = format + " lines " + std::to_string(frames.size()) + "/" + std::to_string(lines) + " kept, hands " +
                  std::to_string(hands_kept) + (bodies_kept ? ", 6-DOF bodies " + std::to_string(bodies_kept) : std::string()) +
                  " (rejected: ";
  if (by_reason.empty()) s += "none";
  for (size_t i = 0; i < by_reason.size(); ++i) s += (i ? ", " : "") + by_reason[i].first + " " + std::to_string(by_reason[i].second);
  return s + ")";
}

JsonlRecording readJsonl(const std::string& text, const std::string& name, const Pose& X_WT) {
  JsonlRecording rec;
  size_t pos = text.find('\n');
  const std::string header = text.substr(0, pos);
  rec.format = jsonlFormat(header);
  if (rec.format.empty()) throw JsonlError(name + ": not a godhand JSON Lines recording (header {\"format\": ...} expected)");
  {
    const json h = json::parse(header, nullptr, false);
    const auto v = h.find("version");
    if (v == h.end() || !v->is_number_integer() || v->get<int>() != 1) throw JsonlError(name + ": unsupported version (expected 1)");
  }
  const bool xr = rec.format == "openxr";
  Counter c;
  std::int64_t last_t = 0;
  bool have_t = false;
  while (pos != std::string::npos && pos < text.size()) {
    const size_t b = pos + 1;
    pos = text.find('\n', b);
    const std::string line = text.substr(b, pos == std::string::npos ? std::string::npos : pos - b);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    ++rec.lines;
    const json j = json::parse(line, nullptr, false);
    if (!j.is_object()) { c.add("line: parse error"); continue; }
    const auto t = j.find(xr ? "time_ns" : "time_us");
    const auto hands = j.find("hands");
    // (Each reason names what is wrong: "parse error" alone left a user guessing.)
    if (t == j.end() || !t->is_number_integer()) {
      c.add(xr ? "line: time_ns missing or not an integer" : "line: time_us missing or not an integer");
      continue;
    }
    if (hands == j.end() || !hands->is_array()) { c.add("line: hands missing or not an array"); continue; }
    const std::int64_t tu = xr ? t->get<std::int64_t>() / 1000 : t->get<std::int64_t>();
    if (have_t && tu <= last_t) { c.add("line: stale/duplicate time"); continue; }
    leap::TrackerFrame f;
    f.timestamp_us = tu;
    f.frame_id = static_cast<std::int64_t>(rec.lines);
    int index = 0;
    for (const json& h : *hands) {
      ++index;
      if (!h.is_object()) { c.add("hand: not an object"); continue; }
      const char* bad_side = xr ? "hand: side missing or not \"left\"/\"right\"" : "hand: handedness missing or not \"Left\"/\"Right\"";
      const auto side = h.find(xr ? "side" : "handedness");
      if (side == h.end() || !side->is_string()) { c.add(bad_side); continue; }
      const std::string s = side->get<std::string>();
      bool right;
      if (s == "right" || s == "Right") right = true;
      else if (s == "left" || s == "Left") right = false;
      else { c.add(bad_side); continue; }
      double conf = 1.0;
      const auto cf = h.find(xr ? "confidence" : "score");
      if (cf != h.end()) {
        if (cf->is_null()) { c.add("hand: NaN/Inf"); continue; }
        if (!cf->is_number()) { c.add(xr ? "hand: confidence not a number" : "hand: score not a number"); continue; }
        conf = cf->get<double>();
      }
      int id = right ? 1 : 0;
      const auto idj = h.find("id");
      if (idj != h.end()) {
        if (!idj->is_number_integer()) { c.add("hand: id not an integer"); continue; }
        id = idj->get<int>();
      }
      leap::TrackedHand th;
      Reject why = Reject::kDegenerate;
      bool ok = false;
      if (xr) {
        const auto act = h.find("active");
        if (act != h.end() && act->is_boolean() && !act->get<bool>()) { c.add("hand: not active (untracked)"); continue; }
        const auto js = h.find("joints");
        const char* bad_joints = "hand: joints not 26 [px,py,pz,qx,qy,qz,qw,radius,flags]";
        if (js == h.end() || !js->is_array() || js->size() != kXrJoints) { c.add(bad_joints); continue; }
        std::array<XrJoint, kXrJoints> joints;
        int bad = 0;
        for (size_t k = 0; k < kXrJoints && !bad; ++k) {
          double v[9];
          bad = numbers((*js)[k], 9, v);
          joints[k].p = Vec3(v[0], v[1], v[2]);
          joints[k].q = Quat(v[6], v[3], v[4], v[5]);
          joints[k].radius = v[7];
          if (!bad && (v[8] < 0 || v[8] > 15 || std::floor(v[8]) != v[8])) bad = 1;
          joints[k].flags = bad ? 0u : static_cast<std::uint32_t>(v[8]);
        }
        if (bad) { c.add(bad == 2 ? "hand: NaN/Inf" : bad_joints); continue; }
        ok = handFromOpenXr(joints, right, conf, id, X_WT, &th, &why);
      } else {
        const auto lm = h.find("landmarks");
        const char* bad_landmarks = "hand: landmarks not 21 [x,y,z] (or origin not [x,y,z])";
        if (lm == h.end() || !lm->is_array() || lm->size() != kLandmarks) { c.add(bad_landmarks); continue; }
        double o[3] = {0, 0, 0};
        const auto org = h.find("origin");
        int bad = org == h.end() ? 0 : numbers(*org, 3, o);
        std::array<Vec3, kLandmarks> p;
        for (size_t k = 0; k < kLandmarks && !bad; ++k) {
          double v[3];
          bad = numbers((*lm)[k], 3, v);
          // camera (x right, y down, z forward) -> T (x right, y forward, z up)
          p[k] = Vec3(v[0] + o[0], v[2] + o[2], -(v[1] + o[1]));
        }
        if (bad) { c.add(bad == 2 ? "hand: NaN/Inf" : bad_landmarks); continue; }
        ok = handFromLandmarks(p, right, conf, id, X_WT, &th, &why);
      }
      if (!ok) { c.add(std::string("hand: ") + reasonName(why)); continue; }
      f.hands.push_back(th);
      ++rec.hands_kept;
    }
    if (xr) {
      // 6-DOF bodies (a controller's aim or grip pose, a tracked object): an XrSpaceLocation in
      // the same reference space; the body's axes are kept, expressed in T like the joints.
      const auto bodies = j.find("bodies");
      if (bodies != j.end() && !bodies->is_array()) c.add("body: parse error");
      if (bodies != j.end() && bodies->is_array())
        for (const json& body : *bodies) {
          const auto idj = body.is_object() ? body.find("id") : body.end();
          const auto pj = body.is_object() ? body.find("pose") : body.end();
          const auto fj = body.is_object() ? body.find("flags") : body.end();
          if (!body.is_object() || idj == body.end() || !idj->is_number_integer() || pj == body.end() || fj == body.end() ||
              !fj->is_number_integer()) {
            c.add("body: parse error");
            continue;
          }
          double v[7];
          const int bad = numbers(*pj, 7, v);
          if (bad) { c.add(bad == 2 ? "body: NaN/Inf" : "body: parse error"); continue; }
          const std::int64_t flags = fj->get<std::int64_t>();
          if ((flags & 0x3) != 0x3) { c.add("body: not tracked (position or orientation invalid)"); continue; }
          const Quat q_xr(v[6], v[3], v[4], v[5]);
          if (std::abs(q_xr.norm() - 1.0) > 1e-3) { c.add("body: non-unit quaternion"); continue; }
          const Vec3 p_xr(v[0], v[1], v[2]);
          if (p_xr.norm() > 100.0) { c.add("body: beyond 100 m"); continue; }
          Mat3 C;  // OpenXR space -> T: (x, -z, y)
          C << 1, 0, 0, 0, 0, -1, 0, 1, 0;
          leap::TrackedBody tb;
          tb.id = idj->get<int>();
          tb.quality = (flags & 0xC) == 0xC ? 1.0 : 0.5;  // tracked bits set, else inferred
          tb.X_WB.p = X_WT * (C * p_xr);
          tb.X_WB.q = Quat(X_WT.q.toRotationMatrix() * C * q_xr.normalized().toRotationMatrix()).normalized();
          f.bodies.push_back(tb);
          ++rec.bodies_kept;
        }
    }
    have_t = true;
    last_t = tu;
    rec.frames.push_back(std::move(f));
  }
  for (const auto& [k, v] : c.n) rec.by_reason.emplace_back(k, v);
  return rec;
}

}  // namespace godhand::skeleton
