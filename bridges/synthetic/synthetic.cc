#include "synthetic/synthetic.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "skeleton/skeleton.h"

namespace godhand::synthetic {

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

[[noreturn]] void fail(const std::string& name, int line, const std::string& why) {
  throw ScriptError(name + ":" + std::to_string(line) + ": " + why);
}

}  // namespace

std::vector<Vec3> handLandmarks(bool right, const Vec3& palm, double curl, double roll_deg) {
  const double s = right ? 1.0 : -1.0;  // mirror x for a left hand (thumb on +x)
  std::vector<Vec3> p(21);
  p[0] = palm + Vec3(0, -0.047, 0);  // the palm centre is the midpoint of wrist and middle MCP
  // Thumb: CMC, then three bones toward the index side, flexing toward the palm (−z).
  const Vec3 cmc = palm + Vec3(s * -0.025, -0.030, -0.010);
  const Vec3 d0 = Vec3(s * -0.45, 0.89, 0.0).normalized();
  const double tl[3] = {0.040, 0.032, 0.026}, ta[3] = {20.0, 50.0, 80.0};
  p[1] = cmc;
  for (int k = 0; k < 3; ++k) {
    const double a = curl * ta[k] * kDeg;
    p[static_cast<size_t>(2 + k)] = p[static_cast<size_t>(1 + k)] + tl[k] * (std::cos(a) * d0 + std::sin(a) * Vec3(0, 0, -1));
  }
  const double mx[4] = {-0.022, 0.0, 0.020, 0.038}, my[4] = {0.045, 0.047, 0.043, 0.037};
  const double len[4][3] = {{0.040, 0.024, 0.020}, {0.044, 0.028, 0.022}, {0.041, 0.027, 0.021}, {0.033, 0.019, 0.018}};
  const double ang[3] = {70.0, 160.0, 220.0};
  for (int f = 0; f < 4; ++f) {
    const size_t b = static_cast<size_t>(5 + 4 * f);
    p[b] = palm + Vec3(s * mx[f], my[f], 0.0);
    for (int k = 0; k < 3; ++k) {
      const double a = curl * ang[k] * kDeg;
      p[b + static_cast<size_t>(k) + 1] = p[b + static_cast<size_t>(k)] + len[f][k] * Vec3(0, std::cos(a), -std::sin(a));
    }
  }
  if (roll_deg != 0.0) {  // about +Y through the palm centre
    const double c = std::cos(roll_deg * kDeg), sn = std::sin(roll_deg * kDeg);
    for (Vec3& v : p) {
      const Vec3 d = v - palm;
      v = palm + Vec3(c * d.x() + sn * d.z(), d.y(), -sn * d.x() + c * d.z());
    }
  }
  return p;
}

namespace {
constexpr int kMaxScriptFrames = 360000;  // an hour at 100 Hz
}  // namespace

Script parseScript(const std::string& text, const std::string& name) {
  Script sc;
  std::istringstream in(text);
  std::string line;
  int n = 0;
  bool header = false, moved = false;
  double total_frames = 0.0;
  while (std::getline(in, line)) {
    ++n;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    // Motions joined by ';' on one line run at the same time (each over its own S).
    std::vector<std::string> parts;
    for (size_t a = 0;;) {
      const size_t semi = line.find(';', a);
      parts.push_back(line.substr(a, semi == std::string::npos ? std::string::npos : semi - a));
      if (semi == std::string::npos) break;
      a = semi + 1;
    }
    std::vector<std::string> tok;
    int hands_on_line[2] = {0, 0};
    double line_seconds = -1.0;  // the frames this line emits: its longest timed motion (hold: its time)
    for (size_t part = 0; part < parts.size(); ++part) {
      tok.clear();
      std::istringstream ls(parts[part]);
      for (std::string t; ls >> t;) tok.push_back(t);
      if (tok.empty()) {
        if (parts.size() > 1) fail(name, n, "empty motion between ';'");
        continue;
      }
      if (!header) {
        if (tok.size() != 2 || tok[0] != "godhand-synthetic" || tok[1] != "1") fail(name, n, "first line must be 'godhand-synthetic 1'");
        header = true;
        continue;
      }
      auto num = [&](size_t i) {
        if (i >= tok.size()) fail(name, n, "'" + tok[0] + "': missing value");
        char* end = nullptr;
        const double v = std::strtod(tok[i].c_str(), &end);
        if (*end != '\0' || !std::isfinite(v)) fail(name, n, "'" + tok[i] + "' is not a finite number");
        return v;
      };
      auto side = [&](size_t i) {
        if (i >= tok.size()) fail(name, n, "'" + tok[0] + "': missing side");
        if (tok[i] == "right") return 1;
        if (tok[i] == "left") return 0;
        fail(name, n, "side must be right or left, not '" + tok[i] + "'");
      };
      auto arity = [&](size_t k) {
        if (tok.size() != k) fail(name, n, "'" + tok[0] + "' takes " + std::to_string(k - 1) + " values");
      };
      auto seconds = [&](size_t i) {
        const double v = num(i);
        if (!(v >= 0.0 && v <= 3600.0)) fail(name, n, "duration must be in [0, 3600] s");
        return v;
      };
      auto position = [&](size_t i) {
        const Vec3 p(num(i), num(i + 1), num(i + 2));
        if (p.cwiseAbs().maxCoeff() > 1000.0) fail(name, n, "position beyond 1 km");
        return p;
      };
      if (parts.size() > 1 && tok[0] != "move" && tok[0] != "curl" && tok[0] != "roll")
        fail(name, n, "only move, curl and roll run together (';'), not '" + tok[0] + "'");
      Command c;
      c.op = tok[0];
      c.line = n;
      if (c.op == "rate") {
        arity(2);
        if (moved) fail(name, n, "rate must come before any motion");
        sc.rate_hz = num(1);
        if (!(sc.rate_hz >= 1.0 && sc.rate_hz <= 10000.0)) fail(name, n, "rate must be in [1, 10000] Hz");
        continue;
      } else if (c.op == "start" || c.op == "teleport") {
        arity(5);
        c.side = side(1);
        c.p = position(2);
      } else if (c.op == "move") {
        arity(6);
        c.side = side(1);
        c.seconds = seconds(2);
        c.p = position(3);
      } else if (c.op == "curl" || c.op == "roll") {  // SIDE S VALUE
        arity(4);
        c.side = side(1);
        c.seconds = seconds(2);
        c.value = num(3);
        if (c.op == "curl" && !(c.value >= 0.0 && c.value <= 1.0)) fail(name, n, "curl fraction must be in [0, 1]");
        if (c.op == "roll" && !(c.value >= -180.0 && c.value <= 180.0)) fail(name, n, "roll angle must be in [-180, 180] degrees");
      } else if (c.op == "hold") {
        arity(2);
        c.seconds = seconds(1);
      } else if (c.op == "lost") {
        arity(3);
        c.side = side(1);
        c.seconds = seconds(2);
      } else if (c.op == "nan") {
        arity(3);
        c.side = side(1);
        c.value = num(2);
        if (!(c.value >= 1 && c.value <= 1e6) || std::floor(c.value) != c.value) fail(name, n, "nan takes a frame count 1..1000000");
      } else {
        fail(name, n, "unknown command '" + c.op + "'");
      }
      if (parts.size() > 1 && ++hands_on_line[c.side] > 1) fail(name, n, "one motion per hand on a line");
      moved = true;
      if (c.op == "move" || c.op == "curl" || c.op == "roll" || c.op == "hold" || c.op == "lost")
        line_seconds = std::max(line_seconds, c.seconds);
      sc.commands.push_back(c);
    }
    if (line_seconds >= 0.0) {
      // Every frame is made up front: the script's length is bounded, not the machine's memory.
      total_frames += std::max(1.0, std::round(line_seconds * sc.rate_hz));
      if (total_frames > kMaxScriptFrames)
        fail(name, n, "the script makes more than " + std::to_string(kMaxScriptFrames) + " frames (" +
                          std::to_string(static_cast<long long>(std::round(kMaxScriptFrames / sc.rate_hz))) +
                          " s at its rate): shorten it or lower its rate");
    }
  }
  if (!header) fail(name, n, "empty script (first line must be 'godhand-synthetic 1')");
  bool started[2] = {false, false};
  for (const Command& c : sc.commands) {
    if (c.op == "start") started[c.side] = true;
    else if (c.side >= 0 && !started[c.side]) fail(name, c.line, "'" + c.op + "' of the " + (c.side ? "right" : "left") + " hand before its 'start'");
  }
  if (!started[0] && !started[1]) fail(name, n, "no hand: add 'start right X Y Z'");
  return sc;
}

Generated generate(const Script& sc, const Pose& X_WT) {
  struct HandState {
    bool exists = false;
    Vec3 p = Vec3::Zero();
    double curl = 0.0;
    double roll = 0.0;  // degrees
    int lost_frames = 0;
    int nan_frames = 0;
  };
  HandState h[2];
  Generated g;
  std::map<std::string, std::uint64_t> reasons;
  const double dt = 1.0 / sc.rate_hz;
  std::int64_t k = 0;
  auto emit = [&] {
    leap::TrackerFrame f;
    f.timestamp_us = static_cast<std::int64_t>(std::llround(static_cast<double>(k) * dt * 1e6));
    f.frame_id = k;
    ++k;
    for (int s = 1; s >= 0; --s) {
      HandState& st = h[s];
      if (!st.exists) continue;
      if (st.lost_frames > 0) {
        --st.lost_frames;
        continue;
      }
      const std::vector<Vec3> lm = handLandmarks(s == 1, st.p, st.curl, st.roll);
      std::array<Vec3, skeleton::kLandmarks> a;
      for (size_t i = 0; i < a.size(); ++i) a[i] = lm[i];
      if (st.nan_frames > 0) {
        --st.nan_frames;
        a[8].x() = std::numeric_limits<double>::quiet_NaN();
      }
      ++g.samples;
      leap::TrackedHand th;
      skeleton::Reject why;
      if (skeleton::handFromLandmarks(a, s == 1, 1.0, s, X_WT, &th, &why)) {
        f.hands.push_back(th);
      } else {
        ++g.rejected;
        ++reasons[skeleton::reasonName(why)];
      }
    }
    g.frames.push_back(std::move(f));
  };
  auto framesFor = [&](double seconds) { return static_cast<int>(std::llround(seconds * sc.rate_hz)); };
  for (size_t ci = 0; ci < sc.commands.size(); ++ci) {
    const Command& c = sc.commands[ci];
    HandState* st = c.side >= 0 ? &h[c.side] : nullptr;
    if (c.op == "start") {
      st->exists = true;
      st->p = c.p;
      st->curl = 0.0;
      st->roll = 0.0;
    } else if (c.op == "teleport") {
      st->p = c.p;
    } else if (c.op == "nan") {
      st->nan_frames = static_cast<int>(c.value);
    } else if (c.op == "move" || c.op == "curl" || c.op == "roll") {
      // This motion and the ones joined to it by ';' (same line), at once.
      size_t last = ci;
      while (last + 1 < sc.commands.size() && sc.commands[last + 1].line == c.line) ++last;
      struct Motion {
        const Command* c;
        HandState* st;
        int n;
        Vec3 p0;
        double c0, r0;
      };
      std::vector<Motion> ms;
      int frames = 0;
      for (size_t j = ci; j <= last; ++j) {
        const Command& m = sc.commands[j];
        HandState* s = &h[m.side];
        ms.push_back({&m, s, std::max(1, framesFor(m.seconds)), s->p, s->curl, s->roll});
        frames = std::max(frames, ms.back().n);
      }
      ci = last;
      for (int i = 1; i <= frames; ++i) {
        for (const Motion& m : ms) {
          if (i > m.n) continue;
          const double u = static_cast<double>(i) / m.n;
          if (m.c->op == "move") m.st->p = m.p0 + u * (m.c->p - m.p0);
          else if (m.c->op == "curl") m.st->curl = m.c0 + u * (m.c->value - m.c0);
          else m.st->roll = m.r0 + u * (m.c->value - m.r0);
        }
        emit();
      }
    } else if (c.op == "hold") {
      for (int i = framesFor(c.seconds); i > 0; --i) emit();
    } else if (c.op == "lost") {
      const int n = framesFor(c.seconds);
      st->lost_frames = n;
      for (int i = 0; i < n; ++i) emit();
    }
  }
  if (g.frames.empty()) emit();
  for (const auto& [reason, n] : reasons) g.by_reason.emplace_back(reason, n);
  return g;
}

}  // namespace godhand::synthetic
