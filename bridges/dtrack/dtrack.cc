#include "dtrack/dtrack.h"

#include <Eigen/SVD>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>

namespace godhand::dtrack {

const char* reasonName(Reject r) {
  switch (r) {
    case Reject::kParse: return "parse error";
    case Reject::kNotFinite: return "NaN/Inf";
    case Reject::kNotOrthonormal: return "non-orthonormal rotation";
    case Reject::kOutOfRange: return "out of range";
    case Reject::kOversized: return "oversized";
    case Reject::kStale: return "stale/duplicate frame";
    case Reject::kIncomplete: return "incomplete (truncated)";
    case Reject::kCount: break;
  }
  return "?";
}

namespace {

struct Fail {
  Reject reason;
  std::string detail;
};

// Cursor over one line's payload. Every read either succeeds or sets `fail` and returns false.
class Cursor {
 public:
  Cursor(std::string_view s, const std::string& where) : s_(s), where_(where) {}
  bool ok() const { return !failed_; }
  const Fail& fail() const { return fail_; }
  bool atEnd() const { return pos_ >= s_.size(); }

  bool error(Reject r, const std::string& what) {
    if (!failed_) fail_ = {r, where_ + ": " + what};
    failed_ = true;
    return false;
  }
  bool expect(char c) {
    if (pos_ < s_.size() && s_[pos_] == c) {
      ++pos_;
      return true;
    }
    return error(Reject::kParse, std::string("expected '") + c + "' at column " + std::to_string(pos_ + 1));
  }
  bool peek(char c) const { return pos_ < s_.size() && s_[pos_] == c; }

  /// Unsigned integer: digits only.
  bool readUint(std::uint64_t* v) {
    const std::size_t b = pos_;
    while (pos_ < s_.size() && s_[pos_] >= '0' && s_[pos_] <= '9') ++pos_;
    if (pos_ == b || pos_ - b > 18) return error(Reject::kParse, "expected an unsigned integer at column " + std::to_string(b + 1));
    std::uint64_t x = 0;
    for (std::size_t i = b; i < pos_; ++i) x = x * 10 + static_cast<std::uint64_t>(s_[i] - '0');
    *v = x;
    return true;
  }
  /// Decimal number: [-+]?(digits[.digits*]|.digits)([eE][-+]?digits)?; nan / inf: kNotFinite.
  bool readNumber(double* v) {
    const std::size_t b = pos_;
    std::size_t i = pos_;
    if (i < s_.size() && (s_[i] == '-' || s_[i] == '+')) ++i;
    if (i < s_.size() && (s_[i] == 'n' || s_[i] == 'N' || s_[i] == 'i' || s_[i] == 'I')) {
      std::string word;
      while (i < s_.size() && std::isalpha(static_cast<unsigned char>(s_[i]))) word += static_cast<char>(std::tolower(s_[i++]));
      if (word == "nan" || word == "inf" || word == "infinity") {
        pos_ = i;
        return error(Reject::kNotFinite, "'" + std::string(s_.substr(b, i - b)) + "' at column " + std::to_string(b + 1));
      }
      return error(Reject::kParse, "expected a number at column " + std::to_string(b + 1));
    }
    std::size_t digits = 0;
    while (i < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i]))) ++i, ++digits;
    if (i < s_.size() && s_[i] == '.') {
      ++i;
      while (i < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i]))) ++i, ++digits;
    }
    if (digits == 0) return error(Reject::kParse, "expected a number at column " + std::to_string(b + 1));
    if (i < s_.size() && (s_[i] == 'e' || s_[i] == 'E')) {
      std::size_t j = i + 1;
      if (j < s_.size() && (s_[j] == '-' || s_[j] == '+')) ++j;
      std::size_t ed = 0;
      while (j < s_.size() && std::isdigit(static_cast<unsigned char>(s_[j]))) ++j, ++ed;
      if (ed == 0) return error(Reject::kParse, "bad exponent at column " + std::to_string(i + 1));
      i = j;
    }
    const char* first = s_.data() + b + (s_[b] == '+' ? 1 : 0);
    double x = 0.0;
    const auto r = std::from_chars(first, s_.data() + i, x);
    if (r.ec == std::errc::result_out_of_range) return error(Reject::kOutOfRange, "number out of range at column " + std::to_string(b + 1));
    if (r.ec != std::errc() || r.ptr != s_.data() + i) return error(Reject::kParse, "bad number at column " + std::to_string(b + 1));
    if (!std::isfinite(x)) return error(Reject::kNotFinite, "not finite at column " + std::to_string(b + 1));
    pos_ = i;
    *v = x;
    return true;
  }
  /// "[v0 v1 ... vk]" with single spaces; exactly n values (or n2 when n2 > 0).
  bool readBlock(double* out, int n, int n2 = 0, int* got = nullptr) {
    if (!expect('[')) return false;
    int k = 0;
    const int cap = std::max(n, n2);
    for (;;) {
      double x;
      if (k >= cap) return error(Reject::kParse, "block has more than " + std::to_string(cap) + " values");
      if (!readNumber(&x)) return false;
      out[k++] = x;
      if (peek(']')) break;
      if (!expect(' ')) return false;
    }
    ++pos_;
    if (k != n && k != n2)
      return error(Reject::kParse, "block of " + std::to_string(k) + " values, expected " + std::to_string(n) +
                                       (n2 ? " or " + std::to_string(n2) : ""));
    if (got) *got = k;
    return true;
  }

 private:
  std::string_view s_;
  std::size_t pos_ = 0;
  std::string where_;
  bool failed_ = false;
  Fail fail_{Reject::kParse, ""};
};

bool isInteger(double x) { return std::floor(x) == x; }

/// Column-wise b0..b8 -> R, checked and re-orthonormalised (nearest rotation, SVD).
bool rotation(const double* b, double tol, Mat3* R, std::string* why) {
  Mat3 M;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) M(i, j) = b[i + 3 * j];
  const double err = (M.transpose() * M - Mat3::Identity()).cwiseAbs().maxCoeff();
  const double det = M.determinant();
  if (!(err <= tol) || !(det > 0.0)) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "rotation |RtR - I| = %.3g, det = %.3g", err, det);
    *why = buf;
    return false;
  }
  Eigen::JacobiSVD<Mat3> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  *R = svd.matrixU() * svd.matrixV().transpose();
  return true;
}

}  // namespace

ParseResult parseDatagram(std::string_view bytes, Datagram* out, const ParseLimits& L) {
  ParseResult res;
  auto failWith = [&](Reject r, std::string d) {
    res.ok = false;
    res.reason = r;
    res.detail = std::move(d);
    return res;
  };
  if (bytes.size() > L.max_bytes)
    return failWith(Reject::kOversized, std::to_string(bytes.size()) + " bytes > limit " + std::to_string(L.max_bytes));
  if (bytes.empty()) return failWith(Reject::kParse, "empty datagram");
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(bytes[i]);
    if ((c < 0x20 || c > 0x7e) && c != '\r' && c != '\n') {
      char buf[64];
      std::snprintf(buf, sizeof buf, "byte 0x%02x at offset %zu", c, i);
      return failWith(Reject::kParse, buf);
    }
  }
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const bool cr = bytes[i] == '\r', lf = bytes[i] == '\n';
    if ((cr && (i + 1 >= bytes.size() || bytes[i + 1] != '\n') && i + 1 < bytes.size()) || (lf && (i == 0 || bytes[i - 1] != '\r')))
      return failWith(Reject::kParse, "bare CR or LF at offset " + std::to_string(i) + " (lines end with CR LF)");
  }
  *out = Datagram();
  Datagram& d = *out;
  const bool terminated = bytes.size() >= 2 && bytes.substr(bytes.size() - 2) == "\r\n";
  if (L.require_final_crlf && !terminated) {
    // Tell a cut datagram from a non-DTrack one: a datagram must start with "fr ".
    if (bytes.substr(0, 3) != "fr ") return failWith(Reject::kParse, "does not start with 'fr '");
    return failWith(Reject::kIncomplete, "last line has no CR LF (truncated)");
  }
  std::size_t pos = 0, line_no = 0;
  while (pos < bytes.size()) {
    std::size_t e = bytes.find("\r\n", pos);
    if (e == std::string_view::npos) e = bytes.size();
    const std::string_view line = bytes.substr(pos, e - pos);
    pos = e + 2;
    ++line_no;
    const std::string where = "line " + std::to_string(line_no);
    if (line.empty()) return failWith(Reject::kParse, where + ": empty line");
    if (line.find('\r') != std::string_view::npos || line.find('\n') != std::string_view::npos)
      return failWith(Reject::kParse, where + ": bare CR or LF");
    const std::size_t sp = line.find(' ');
    if (sp == std::string_view::npos || sp == 0 || sp + 1 >= line.size())
      return failWith(Reject::kParse, where + ": expected 'identifier payload'");
    const std::string id(line.substr(0, sp));
    for (char c : id)
      if (!(std::islower(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c))))
        return failWith(Reject::kParse, where + ": bad identifier");
    Cursor cur(line.substr(sp + 1), where + " '" + id + "'");
    if (line_no == 1 && id != "fr") return failWith(Reject::kParse, "does not start with 'fr '");
    unsigned bit = 0;
    if (id == "fr") bit = kLineFr;
    else if (id == "ts") bit = kLineTs;
    else if (id == "ts2") bit = kLineTs2;
    else if (id == "6dcal") bit = kLine6dcal;
    else if (id == "6d") bit = kLine6d;
    else if (id == "glcal") bit = kLineGlcal;
    else if (id == "gl") bit = kLineGl;
    if (!bit) {  // unknown identifiers may be valid in future DTracks (the SDK's rule): ignored
      ++d.unknown_lines;
      continue;
    }
    if (d.lines & bit) return failWith(Reject::kParse, where + ": second '" + id + "' line");
    d.lines |= bit;
    if (bit == kLineFr) {
      cur.readUint(&d.frame);
    } else if (bit == kLineTs) {
      double t = 0;
      if (cur.readNumber(&t)) {
        if (!(t >= 0.0 && t < 86400.0)) cur.error(Reject::kOutOfRange, "ts outside [0, 86400) s");
        d.ts = t;
        d.has_ts = true;
      }
    } else if (bit == kLineTs2) {
      std::uint64_t sec = 0, usec = 0, lat = 0;
      if (cur.readUint(&sec) && cur.expect(' ') && cur.readUint(&usec) && cur.expect(' ') && cur.readUint(&lat)) {
        if (usec >= 1000000 || sec > 100000000000ull) {  // (found by fuzz_dtrack: sec * 1e6 overflowed)
          cur.error(Reject::kOutOfRange, "ts2 µs >= 1e6 or seconds too large");
        } else {
          d.has_ts2 = true;
          d.ts2_us = static_cast<std::int64_t>(sec) * 1000000 + static_cast<std::int64_t>(usec);
          d.latency_us = static_cast<std::int64_t>(lat);
          if (!d.has_ts) d.ts = static_cast<double>(sec % 86400) + static_cast<double>(usec) * 1e-6;
        }
      }
    } else if (bit == kLine6dcal || bit == kLineGlcal) {
      std::uint64_t n = 0;
      if (cur.readUint(&n) && n > static_cast<std::uint64_t>(L.max_count)) cur.error(Reject::kOutOfRange, "count too large");
      (bit == kLine6dcal ? d.bodies_calibrated : d.hands_calibrated) = static_cast<int>(n);
    } else if (bit == kLine6d) {
      d.has_6d = true;
      std::uint64_t n = 0;
      if (cur.readUint(&n)) {
        if (n > static_cast<std::uint64_t>(L.max_count)) cur.error(Reject::kOutOfRange, "body count too large");
        if (n > 0) cur.expect(' ');
        for (std::uint64_t k = 0; k < n && cur.ok(); ++k) {
          double a[2], p[6], b[9];
          if (!cur.readBlock(a, 2) || !cur.readBlock(p, 3, 6) || !cur.readBlock(b, 9)) break;
          Body body;
          if (!isInteger(a[0]) || a[0] < 0 || a[0] > L.max_id) { cur.error(Reject::kOutOfRange, "body id"); break; }
          body.id = static_cast<int>(a[0]);
          body.quality = a[1];
          if (!(a[1] >= -1.0 && a[1] <= 1.0)) { cur.error(Reject::kOutOfRange, "body quality outside [-1, 1]"); break; }
          for (int i = 0; i < 3; ++i)
            if (std::abs(p[i]) > L.max_position_mm) cur.error(Reject::kOutOfRange, "body position beyond limit");
          body.p_mm = Vec3(p[0], p[1], p[2]);
          std::string why;
          if (cur.ok() && !rotation(b, L.ortho_tolerance, &body.R, &why)) cur.error(Reject::kNotOrthonormal, "body " + std::to_string(body.id) + ": " + why);
          for (const Body& o : d.bodies)
            if (o.id == body.id) cur.error(Reject::kParse, "duplicate body id " + std::to_string(body.id));
          d.bodies.push_back(body);
        }
      }
    } else if (bit == kLineGl) {
      d.has_gl = true;
      std::uint64_t n = 0;
      if (cur.readUint(&n)) {
        if (n > static_cast<std::uint64_t>(L.max_count)) cur.error(Reject::kOutOfRange, "hand count too large");
        if (n > 0) cur.expect(' ');
        for (std::uint64_t k = 0; k < n && cur.ok(); ++k) {
          double a[4], s[3], b[9];
          if (!cur.readBlock(a, 4) || !cur.readBlock(s, 3) || !cur.readBlock(b, 9)) break;
          Hand h;
          if (!isInteger(a[0]) || a[0] < 0 || a[0] > L.max_id) { cur.error(Reject::kOutOfRange, "hand id"); break; }
          h.id = static_cast<int>(a[0]);
          h.quality = a[1];
          if (!(a[1] >= -1.0 && a[1] <= 1.0)) { cur.error(Reject::kOutOfRange, "hand quality outside [-1, 1]"); break; }
          if (a[2] != 0.0 && a[2] != 1.0) { cur.error(Reject::kOutOfRange, "hand lr not 0 or 1"); break; }
          h.right = a[2] == 1.0;
          if (a[3] != 3.0 && a[3] != 5.0) { cur.error(Reject::kOutOfRange, "hand nf not 3 or 5"); break; }
          const int nf = static_cast<int>(a[3]);
          for (int i = 0; i < 3; ++i)
            if (std::abs(s[i]) > L.max_position_mm) cur.error(Reject::kOutOfRange, "hand position beyond limit");
          h.p_mm = Vec3(s[0], s[1], s[2]);
          std::string why;
          if (cur.ok() && !rotation(b, L.ortho_tolerance, &h.R, &why)) cur.error(Reject::kNotOrthonormal, "hand " + std::to_string(h.id) + ": " + why);
          for (int f = 0; f < nf && cur.ok(); ++f) {
            double fp[3], fb[9], fl[6];
            if (!cur.readBlock(fp, 3) || !cur.readBlock(fb, 9) || !cur.readBlock(fl, 6)) break;
            Finger fi;
            for (int i = 0; i < 3; ++i)
              if (std::abs(fp[i]) > L.max_finger_mm) cur.error(Reject::kOutOfRange, "finger position beyond limit");
            fi.p_mm = Vec3(fp[0], fp[1], fp[2]);
            if (cur.ok() && !rotation(fb, L.ortho_tolerance, &fi.R, &why))
              cur.error(Reject::kNotOrthonormal, "hand " + std::to_string(h.id) + " finger " + std::to_string(f) + ": " + why);
            fi.ro = fl[0], fi.lo = fl[1], fi.a_om = fl[2], fi.lm = fl[3], fi.a_mi = fl[4], fi.li = fl[5];
            for (double len : {fi.ro, fi.lo, fi.lm, fi.li})
              if (!(len >= 0.0 && len <= L.max_length_mm)) cur.error(Reject::kOutOfRange, "finger length / radius outside [0, limit]");
            for (double ang : {fi.a_om, fi.a_mi})
              if (!(std::abs(ang) <= L.max_angle_deg)) cur.error(Reject::kOutOfRange, "finger angle beyond limit");
            h.fingers.push_back(fi);
          }
          for (const Hand& o : d.hands)
            if (o.id == h.id) cur.error(Reject::kParse, "duplicate hand id " + std::to_string(h.id));
          d.hands.push_back(std::move(h));
        }
      }
    }
    if (cur.ok() && !cur.atEnd()) cur.error(Reject::kParse, "unexpected text after the values");
    if (!cur.ok()) return failWith(cur.fail().reason, cur.fail().detail);
  }
  if (!(d.lines & kLineFr)) return failWith(Reject::kParse, "no 'fr' line");
  if (d.hands_calibrated >= 0)
    for (const Hand& h : d.hands)
      if (h.id >= d.hands_calibrated) return failWith(Reject::kOutOfRange, "hand id " + std::to_string(h.id) + " >= glcal");
  if (d.bodies_calibrated >= 0)
    for (const Body& b : d.bodies)
      if (b.id >= d.bodies_calibrated) return failWith(Reject::kOutOfRange, "body id " + std::to_string(b.id) + " >= 6dcal");
  // A calibration line is always followed by its data line: without it, the datagram was cut.
  if ((d.lines & kLine6dcal) && !(d.lines & kLine6d)) return failWith(Reject::kIncomplete, "'6dcal' without '6d'");
  if ((d.lines & kLineGlcal) && !(d.lines & kLineGl)) return failWith(Reject::kIncomplete, "'glcal' without 'gl'");
  return res;
}

namespace {
Vec3 axes(const Vec3& v, bool y_up) { return y_up ? Vec3(v.x(), -v.z(), v.y()) : v; }
Mat3 axesMatrix(bool y_up) {
  Mat3 A = Mat3::Identity();
  if (y_up) A << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  return A;
}
}  // namespace

Vec3 roomToWorld(const Vec3& p_room, const MapOptions& o) { return o.X_WT * (axes(p_room, o.y_up) * o.units_to_m); }

std::array<Vec3, 4> fingerJoints(const Finger& f, bool tip_adds_radius) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  const Vec3 j1(-f.lo, 0.0, 0.0);
  const Vec3 j2 = j1 + f.lm * Vec3(-std::cos(f.a_om * kDeg), 0.0, std::sin(f.a_om * kDeg));
  const Vec3 j3 = j2 + f.li * Vec3(-std::cos((f.a_om + f.a_mi) * kDeg), 0.0, std::sin((f.a_om + f.a_mi) * kDeg));
  const Vec3 tip = tip_adds_radius ? Vec3(f.ro, 0.0, 0.0) : Vec3::Zero();
  auto hand = [&](const Vec3& p) -> Vec3 { return f.p_mm + f.R * p; };
  return {hand(j3), hand(j2), hand(j1), hand(tip)};
}

leap::TrackedBody mapBody(const Body& b, const MapOptions& o) {
  leap::TrackedBody t;
  t.id = b.id;
  t.quality = std::clamp(b.quality, 0.0, 1.0);
  t.X_WB.q = Quat(o.X_WT.q.toRotationMatrix() * axesMatrix(o.y_up) * b.R).normalized();
  t.X_WB.p = roomToWorld(b.p_mm, o);
  return t;
}

leap::TrackedHand mapHand(const Hand& h, const MapOptions& o) {
  leap::TrackedHand t;
  t.id = h.id;
  t.right = h.right;
  t.confidence = std::clamp(h.quality, 0.0, 1.0);
  const Mat3 A = axesMatrix(o.y_up);
  const Mat3 Rh = A * h.R;  // hand frame in the tracker frame T
  Mat3 Rp;
  if (h.right) Rp << Rh.col(1), Rh.col(0), -Rh.col(2);
  else Rp << -Rh.col(1), Rh.col(0), Rh.col(2);
  const Mat3 Rw = o.X_WT.q.toRotationMatrix() * Rp;
  const Vec3 off_palm(h.right ? -o.palm_offset_m.y() : o.palm_offset_m.y(), o.palm_offset_m.x(), -o.palm_offset_m.z());
  t.X_W_palm.q = Quat(Rw).normalized();
  t.X_W_palm.p = roomToWorld(h.p_mm, o) + Rw * off_palm;
  auto toWorld = [&](const Vec3& p_hand_mm) { return roomToWorld(h.p_mm + h.R * p_hand_mm, o); };
  const int nf = static_cast<int>(h.fingers.size());
  for (int f = 0; f < std::min(nf, leap::kFingerCount); ++f) {
    const auto j = fingerJoints(h.fingers[static_cast<std::size_t>(f)], o.tip_adds_radius);
    for (int k = 0; k < 4; ++k) t.joints_W[static_cast<std::size_t>(f)][static_cast<std::size_t>(k)] = toWorld(j[static_cast<std::size_t>(k)]);
  }
  if (nf == 3) {  // ring and little follow the middle finger, one / two knuckle spacings further
    const Vec3 step = t.joints_W[leap::kMiddle][leap::kMcp] - t.joints_W[leap::kIndex][leap::kMcp];
    for (int f : {leap::kRing, leap::kPinky})
      for (int k = 0; k < 4; ++k)
        t.joints_W[static_cast<std::size_t>(f)][static_cast<std::size_t>(k)] =
            t.joints_W[leap::kMiddle][static_cast<std::size_t>(k)] + (f - leap::kMiddle) * step;
  }
  return t;
}

std::uint64_t Decoder::rejectedTotal() const {
  std::uint64_t s = 0;
  for (auto v : rejected_) s += v;
  return s;
}

void Decoder::reject(Reject r, const std::string& detail) {
  ++rejected_[static_cast<std::size_t>(r)];
  last_detail_ = detail;
}

bool Decoder::feed(std::string_view bytes, std::int64_t arrival_us, leap::TrackerFrame* frame) {
  ++received_;
  Datagram d;
  const ParseResult pr = parseDatagram(bytes, &d, limits_);
  if (!pr.ok) {
    reject(pr.reason, pr.detail);
    return false;
  }
  const unsigned essential = kLineTs | kLineTs2 | kLine6d | kLineGl;
  const unsigned missing = seen_lines_ & essential & ~d.lines;
  if (missing) {
    std::string names;
    for (auto [bit, name] : {std::pair<unsigned, const char*>{kLineTs, "ts"}, {kLineTs2, "ts2"}, {kLine6d, "6d"}, {kLineGl, "gl"}})
      if (missing & bit) names += std::string(names.empty() ? "" : ", ") + name;
    reject(Reject::kIncomplete, "fr " + std::to_string(d.frame) + ": no '" + names + "' line, which earlier datagrams carried");
    return false;
  }
  if (have_last_ && d.frame <= last_frame_) {
    if (last_frame_ - d.frame > restart_window) {
      // A tracker restart: its frame counter starts again, its ts is still the time of day (the
      // day goes on, and a restart across midnight is one: the ts is compared as usual below).
      ++restarts_;
    } else if (arrival_us - last_accept_arrival_us_ >= refollow_after_us) {
      // Everything behind the book for a while: the book was wrong (the datagram that put it ahead,
      // e.g. a spoofed one, was the last accepted), follow the stream with the day as it was before
      // that datagram (its ts may have read as a midnight; after one the offset went back a day).
      ++refollows_;
      last_ts_ = ts_before_last_;
      day_offset_us_ = day_offset_before_last_;
    } else {
      reject(Reject::kStale, "fr " + std::to_string(d.frame) + " after fr " + std::to_string(last_frame_));
      return false;
    }
  }
  have_last_ = true;
  last_frame_ = d.frame;
  last_accept_arrival_us_ = arrival_us;
  seen_lines_ |= d.lines;
  ++accepted_;
  frame->frame_id = static_cast<std::int64_t>(d.frame);
  if (d.has_ts2) {
    frame->timestamp_us = d.ts2_us;
  } else if (d.has_ts) {
    // Midnight: the time of day went back by more than half a day. A midnight the next datagram
    // does not confirm (its ts half a day or more ahead of it: the one before was an outlier, e.g.
    // a spoofed datagram, however it was accepted) is taken back.
    const double ts_before = last_ts_;
    const std::int64_t day_before = day_offset_us_;
    if (last_ts_ >= 0.0 && d.ts > last_ts_ + 43200.0 && day_offset_us_ != day_offset_before_last_)
      day_offset_us_ = day_offset_before_last_;
    else if (last_ts_ >= 0.0 && d.ts < last_ts_ - 43200.0)
      day_offset_us_ += 86400LL * 1000000LL;
    ts_before_last_ = ts_before;
    day_offset_before_last_ = day_before;
    last_ts_ = d.ts;
    frame->timestamp_us = day_offset_us_ + static_cast<std::int64_t>(std::llround(d.ts * 1e6));
  } else {
    frame->timestamp_us = arrival_us;
  }
  frame->bodies.clear();
  for (const Body& b : d.bodies) {
    if (b.quality < 0.0) {
      ++bodies_untracked_;
      continue;
    }
    frame->bodies.push_back(mapBody(b, map_));
  }
  frame->hands.clear();
  for (const Hand& h : d.hands) {
    if (h.quality < 0.0) {
      ++hands_untracked_;
      continue;
    }
    frame->hands.push_back(mapHand(h, map_));
    if (h.fingers.size() == 3) fingers_synth_ += 2;
  }
  return true;
}

std::string Decoder::summary() const {
  std::string s = "datagrams " + std::to_string(accepted_) + "/" + std::to_string(received_) + " accepted; rejected: ";
  bool any = false;
  for (int r = 0; r < static_cast<int>(Reject::kCount); ++r)
    if (rejected_[static_cast<std::size_t>(r)]) {
      s += std::string(any ? ", " : "") + reasonName(static_cast<Reject>(r)) + " " + std::to_string(rejected_[static_cast<std::size_t>(r)]);
      any = true;
    }
  if (!any) s += "none";
  if (restarts_) s += "; tracker restarts " + std::to_string(restarts_);
  if (refollows_) s += "; followed again after everything was behind a frame far ahead for " +
                       std::to_string(refollow_after_us / 1000) + " ms " + std::to_string(refollows_);
  if (hands_untracked_) s += "; hands with quality < 0 (not tracked) " + std::to_string(hands_untracked_);
  if (bodies_untracked_) s += "; 6d bodies with quality < 0 (not tracked) " + std::to_string(bodies_untracked_);
  if (fingers_synth_) s += "; fingers synthesised (3-finger hands) " + std::to_string(fingers_synth_);
  return s;
}

std::vector<std::string> splitDatagrams(const std::string& file_bytes) {
  std::string data = file_bytes;
  if (data.find("\r\n") == std::string::npos && data.find('\n') != std::string::npos) {  // LF-only: repair
    std::string fixed;
    fixed.reserve(data.size() * 2);
    for (char c : data) {
      if (c == '\n') fixed += '\r';
      fixed += c;
    }
    data.swap(fixed);
  }
  std::vector<std::string> out;
  std::size_t pos = 0;
  while (pos < data.size()) {
    std::size_t e = data.find("\r\n\r\n", pos);
    if (e == std::string::npos) {
      out.push_back(data.substr(pos));  // a last datagram without the separator (kept as it is)
      break;
    }
    if (e > pos) out.push_back(data.substr(pos, e - pos) + "\r\n");
    pos = e + 4;
  }
  return out;
}

}  // namespace godhand::dtrack
