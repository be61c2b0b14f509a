#include "skeleton/aria.h"

#include <cmath>
#include <cstdlib>
#include <map>
#include <vector>

namespace godhand::skeleton {

namespace {

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else if (c != '\r' && c != ' ') {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

/// 0 ok, 1 not a number, 2 NaN / Inf.
int parseNumber(const std::string& s, double* v) {
  if (s.empty()) return 1;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size()) return 1;
  return std::isfinite(*v) ? 0 : 2;
}

// Aria landmark index -> our 21-landmark index (MediaPipe order); the thumb CMC (1) is derived.
constexpr int kAriaToOurs[21] = {4, 8, 12, 16, 20, 0, 2, 3, 5, 6, 7, 9, 10, 11, 13, 14, 15, 17, 18, 19, -1};

}  // namespace

bool isAriaHeader(const std::string& first_line) { return first_line.rfind("tracking_timestamp_us", 0) == 0; }

JsonlRecording readAriaCsv(const std::string& text, const std::string& name, const Pose& X_WT) {
  JsonlRecording rec;
  rec.format = "aria";
  size_t pos = text.find('\n');
  const std::vector<std::string> header = splitCsv(text.substr(0, pos));
  std::map<std::string, size_t> col;
  for (size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
  auto need = [&](const std::string& c) {
    const auto it = col.find(c);
    if (it == col.end()) throw JsonlError(name + ": not an Aria MPS hand tracking CSV (missing column " + c + ")");
    return it->second;
  };
  const size_t t_col = need("tracking_timestamp_us");
  size_t conf_col[2] = {0, 0}, lm_col[2][21][3] = {};
  const char* sides[2] = {"left", "right"};
  // A file of one hand (a user's own export) may leave the other side's columns out; a side
  // whose confidence column is there needs all of its landmarks.
  bool has_side[2];
  for (int s = 0; s < 2; ++s) has_side[s] = col.count(std::string(sides[s]) + "_tracking_confidence") > 0;
  if (!has_side[0] && !has_side[1]) need("right_tracking_confidence");
  for (int s = 0; s < 2; ++s) {
    if (!has_side[s]) continue;
    conf_col[s] = need(std::string(sides[s]) + "_tracking_confidence");
    for (int i = 0; i < 21; ++i)
      for (int a = 0; a < 3; ++a)
        lm_col[s][i][a] = need(std::string("t") + "xyz"[a] + "_" + sides[s] + "_landmark_" + std::to_string(i) + "_device");
  }
  std::map<std::string, std::uint64_t> reasons;
  std::int64_t last_t = 0;
  bool have_t = false;
  while (pos != std::string::npos && pos < text.size()) {
    const size_t b = pos + 1;
    pos = text.find('\n', b);
    const std::string line = text.substr(b, pos == std::string::npos ? std::string::npos : pos - b);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    ++rec.lines;
    const std::vector<std::string> v = splitCsv(line);
    if (v.size() != header.size()) { ++reasons["line: parse error"]; continue; }
    double t = 0;
    if (parseNumber(v[t_col], &t) != 0 || std::floor(t) != t || std::abs(t) > 9e15) { ++reasons["line: parse error"]; continue; }
    const auto tu = static_cast<std::int64_t>(t);
    if (have_t && tu <= last_t) { ++reasons["line: stale/duplicate time"]; continue; }
    leap::TrackerFrame f;
    f.timestamp_us = tu;
    f.frame_id = static_cast<std::int64_t>(rec.lines);
    for (int s = 1; s >= 0; --s) {
      if (!has_side[s]) continue;
      double conf = 0;
      const int cs = parseNumber(v[conf_col[s]], &conf);
      if (cs != 0) { ++reasons[cs == 2 ? "hand: NaN/Inf" : "hand: parse error"]; continue; }
      if (conf < 0.0) continue;  // −1: not tracked (not a rejection)
      std::array<Vec3, kLandmarks> p;
      int bad = 0;
      for (int i = 0; i < 20 && !bad; ++i)
        for (int a = 0; a < 3 && !bad; ++a) {
          double x = 0;
          bad = parseNumber(v[lm_col[s][i][a]], &x);
          p[static_cast<size_t>(kAriaToOurs[i])][a] = x;
        }
      if (bad) { ++reasons[bad == 2 ? "hand: NaN/Inf" : "hand: parse error"]; continue; }
      p[1] = p[0] + (p[2] - p[0]) / 3.0;  // thumb CMC: not in Aria's set
      leap::TrackedHand th;
      Reject why;
      if (!handFromLandmarks(p, s == 1, conf, s, X_WT, &th, &why)) { ++reasons[std::string("hand: ") + reasonName(why)]; continue; }
      f.hands.push_back(th);
      ++rec.hands_kept;
    }
    have_t = true;
    last_t = tu;
    rec.frames.push_back(std::move(f));
  }
  for (const auto& [k, n] : reasons) rec.by_reason.emplace_back(k, n);
  return rec;
}

}  // namespace godhand::skeleton
