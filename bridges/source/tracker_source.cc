#include "source/tracker_source.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#include "dtrack/dtrack.h"
#include "skeleton/aria.h"
#include "skeleton/jsonl.h"
#include "synthetic/synthetic.h"
#include "source/recording.h"

namespace godhand::bridges {

namespace {

std::int64_t systemNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

constexpr const char* kUtf8Bom = "\xEF\xBB\xBF";

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SourceError(path + ": cannot open (" + std::strerror(errno) + ")");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw SourceError(path + ": read error");
  std::string text = ss.str();
  if (text.compare(0, 3, kUtf8Bom) == 0) text.erase(0, 3);  // a text editor's byte-order mark
  return text;
}

/// Keeps the hands the tracker-id map lists with their own side (the map selects; it does not
/// re-side a hand: its skeleton is that of its side); returns how many were dropped.
std::uint64_t applyHandSides(TrackerFrame* f, const SourceOptions& o) {
  if (o.hand_sides.empty()) return 0;
  std::uint64_t dropped = 0;
  std::vector<TrackedHand> kept;
  for (TrackedHand& h : f->hands) {
    const auto it = std::find_if(o.hand_sides.begin(), o.hand_sides.end(), [&](const auto& p) { return p.first == h.id; });
    if (it == o.hand_sides.end()) {
      ++dropped;
      continue;
    }
    if (h.right != it->second) {
      // The tracker calls it the other side: its palm frame's x (thumb side) flips with the side.
      ++dropped;
      continue;
    }
    kept.push_back(h);
  }
  f->hands.swap(kept);
  return dropped;
}

/// Drops hands outside the tracking volume or jumping beyond the speed limit (SourceOptions).
class Plausibility {
 public:
  explicit Plausibility(const SourceOptions& o) : o_(o), X_TW_(o.X_WT.inverse()) {}
  void apply(TrackerFrame* f) {
    std::vector<TrackedHand> kept;
    // The volume is the tracker's: a box about its origin, in its frame (a world whose origin
    // is kilometres away, as CAD and site coordinates are, keeps every hand).
    auto within = [&](const Vec3& p_W) { return (X_TW_ * p_W).cwiseAbs().maxCoeff() <= o_.max_abs_position_m; };
    std::vector<unsigned char> inside(f->hands.size(), 1);
    for (size_t i = 0; i < f->hands.size(); ++i) {
      const TrackedHand& h = f->hands[i];
      bool in = within(h.X_W_palm.p);
      for (const auto& finger : h.joints_W)
        for (const Vec3& j : finger) in = in && within(j);
      inside[i] = in;
      if (!in) ++outside;
    }
    // Two hands of one side in a frame (a second user, or a tracker's mix-up): the one nearest
    // that side's last hand of the last 0.5 s goes on (the window the jump check looks back);
    // without one, the most confident (as handOfSide picks). The others are counted as what they
    // are, not as jumps of the one hand.
    std::vector<unsigned char> chosen(inside);
    for (const bool right : {false, true}) {
      int best = -1, n = 0;
      const Last& last = last_[right ? 1 : 0];
      const std::int64_t age_us = f->timestamp_us - last.t_us;
      const Last l = last.valid && age_us >= 0 && age_us <= 500000 ? last : Last{};
      for (size_t i = 0; i < f->hands.size(); ++i) {
        const TrackedHand& h = f->hands[i];
        if (!inside[i] || h.right != right) continue;
        ++n;
        if (best < 0) {
          best = static_cast<int>(i);
          continue;
        }
        const TrackedHand& b = f->hands[static_cast<size_t>(best)];
        const bool better = l.valid ? (h.X_W_palm.p - l.p).norm() < (b.X_W_palm.p - l.p).norm() : h.confidence > b.confidence;
        if (better) best = static_cast<int>(i);
      }
      if (n < 2) continue;
      same_side += static_cast<std::uint64_t>(n - 1);
      for (size_t i = 0; i < f->hands.size(); ++i)
        if (inside[i] && f->hands[i].right == right && static_cast<int>(i) != best) chosen[i] = 0;
    }
    for (size_t i = 0; i < f->hands.size(); ++i) {
      if (!chosen[i]) continue;
      const TrackedHand& h = f->hands[i];
      Last& l = last_[h.right ? 1 : 0];
      const std::int64_t dt_us = f->timestamp_us - l.t_us;
      // (A frame with the last one's timestamp counts as 1 ms later: a jump there is not waved
      // through as if no time had passed to judge it by.)
      if (l.valid && dt_us >= 0 && dt_us <= 500000 &&
          (h.X_W_palm.p - l.p).norm() / (static_cast<double>(std::max<std::int64_t>(dt_us, 1000)) * 1e-6) > o_.max_speed_mps) {
        ++jumps;
        continue;
      }
      l = {true, h.X_W_palm.p, f->timestamp_us};
      kept.push_back(h);
    }
    f->hands.swap(kept);
    std::vector<leap::TrackedBody> bodies;
    for (const leap::TrackedBody& b : f->bodies) {
      if ((X_TW_ * b.X_WB.p).cwiseAbs().maxCoeff() > o_.max_abs_position_m) {
        ++bodies_outside;
        continue;
      }
      bodies.push_back(b);
    }
    f->bodies.swap(bodies);
  }
  void addTo(SourceStats* s) const {
    if (bodies_outside) {
      s->by_reason.emplace_back("6-DOF body outside the tracking volume", bodies_outside);
      s->detail += "; 6-DOF bodies outside the tracking volume " + std::to_string(bodies_outside);
    }
    s->rejected += bodies_outside;
    if (outside) {
      s->by_reason.emplace_back("hand outside the tracking volume", outside);
      s->detail += "; hands outside the tracking volume " + std::to_string(outside);
    }
    if (jumps) {
      s->by_reason.emplace_back("hand jump beyond the speed limit", jumps);
      s->detail += "; hand jumps beyond the speed limit " + std::to_string(jumps);
    }
    if (same_side) {
      s->by_reason.emplace_back("second hand of a side in a frame (another user?)", same_side);
      s->detail += "; second hands of a side in one frame (another user? --hand-map picks by id) " + std::to_string(same_side);
    }
    s->rejected += outside + jumps + same_side;
  }
  std::uint64_t outside = 0, jumps = 0, bodies_outside = 0, same_side = 0;

 private:
  struct Last {
    bool valid = false;
    Vec3 p = Vec3::Zero();
    std::int64_t t_us = 0;
  };
  SourceOptions o_;
  Pose X_TW_;
  Last last_[2];
};

double meanRate(const std::vector<TrackerFrame>& frames) {
  if (frames.size() < 2) return 0.0;
  const double dt = static_cast<double>(frames.back().timestamp_us - frames.front().timestamp_us) * 1e-6;
  return dt > 0.0 ? static_cast<double>(frames.size() - 1) / dt : 0.0;
}

/// The timing of a replay. A gap in the timestamps (an interval of at least kGapS and more than
/// twice the median: frames the tracker did not write, or dropped as bad input) is not a period:
/// the rate is the mean over the other intervals. (Without gaps, as the bundled recordings'
/// dropped frames of 2–3 intervals, it is the plain mean rate, bit for bit.) A gap of
/// kSilenceS or more is what a live source's silence is (godhand-ingest --silence: its hands
/// are published untracked): the replay fills it with frames without hands at that rate, so that
/// the hand is lost and re-acquired as it would be live. A shorter gap is stepped as one frame,
/// as a live source's late frame would be.
struct PauseFill {
  std::uint64_t gaps = 0;      ///< intervals left out of the rate
  std::uint64_t pauses = 0;    ///< gaps of kSilenceS or more, filled
  std::uint64_t frames = 0;    ///< frames without hands put into them
  std::vector<unsigned char> is_filled;  ///< per frame of the replay (empty: none filled)
};
constexpr double kGapS = 0.1;
constexpr double kSilenceS = 1.0;  // godhand-ingest's --silence default
constexpr std::uint64_t kMaxFilledFrames = 2000000;  // ~130 MB of empty frames

double replayRate(const std::vector<TrackerFrame>& frames, PauseFill* fill) {
  if (frames.size() < 3) return meanRate(frames);
  std::vector<std::int64_t> iv;
  iv.reserve(frames.size() - 1);
  for (size_t i = 1; i < frames.size(); ++i) iv.push_back(frames[i].timestamp_us - frames[i - 1].timestamp_us);
  std::vector<std::int64_t> sorted = iv;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  const std::int64_t median = sorted[sorted.size() / 2];
  if (median <= 0) return meanRate(frames);
  const std::int64_t gap = std::max<std::int64_t>(static_cast<std::int64_t>(kGapS * 1e6), 2 * median + 1);
  long double kept_us = 0;
  std::uint64_t kept = 0;
  for (const std::int64_t d : iv) {
    if (d >= gap) {
      ++fill->gaps;
    } else {
      kept_us += static_cast<long double>(d);
      ++kept;
    }
  }
  if (fill->gaps == 0 || kept == 0 || kept_us <= 0) return meanRate(frames);
  return static_cast<double>(static_cast<long double>(kept) / (kept_us * 1e-6L));
}

void fillSilences(std::vector<TrackerFrame>* frames, double rate_hz, const std::string& path, PauseFill* fill) {
  if (!(rate_hz > 0.0) || frames->size() < 2) return;
  const long double period_us = 1e6L / static_cast<long double>(rate_hz);
  const std::int64_t silence = static_cast<std::int64_t>(std::max<long double>(kSilenceS * 1e6L, 2 * period_us));
  std::vector<TrackerFrame> out;
  std::vector<unsigned char> is_filled;
  for (size_t i = 0; i < frames->size(); ++i) {
    if (i > 0) {
      const std::int64_t t0 = (*frames)[i - 1].timestamp_us, gap = (*frames)[i].timestamp_us - t0;
      if (gap >= silence) {
        const long double n = std::floor(static_cast<long double>(gap) / period_us + 0.5L) - 1;
        if (n > static_cast<long double>(kMaxFilledFrames - fill->frames))
          throw SourceError(path + ": silences in the timestamps (the last at " + std::to_string(t0) + " us, " +
                            std::to_string(gap / 1000) + " ms) would take more than " + std::to_string(kMaxFilledFrames) +
                            " frames without hands at the recording's rate to replay; cut the recording");
        const std::uint64_t missing = n > 0 ? static_cast<std::uint64_t>(n) : 0;
        if (fill->pauses == 0) {  // the frames before the first: moved, not copied
          out.reserve(frames->size() + missing);
          for (size_t k = 0; k < i; ++k) out.push_back(std::move((*frames)[k]));
          is_filled.assign(i, 0);
        }
        for (std::uint64_t k = 1; k <= missing; ++k) {
          TrackerFrame f;
          f.timestamp_us = t0 + static_cast<std::int64_t>(static_cast<long double>(gap) * static_cast<long double>(k) /
                                                          static_cast<long double>(missing + 1));
          out.push_back(std::move(f));
          is_filled.push_back(1);
        }
        ++fill->pauses;
        fill->frames += missing;
      }
    }
    if (fill->pauses) {
      out.push_back(std::move((*frames)[i]));
      is_filled.push_back(0);
    }
  }
  if (fill->pauses) {
    frames->swap(out);
    fill->is_filled.swap(is_filled);
  }
}

/// A replay of frames decoded up front (every file format). The file is read and checked whole
/// when it is opened (base: its records and every rejection); stats() counts as received only the
/// records of the frames played so far (and every rejected one), the others as not played: a
/// replay cut short (killed, --frames, --duration) received what it played. A record is a frame of
/// the file (a line, a datagram, a Leap frame), or for a synthetic script (records_are_hands) a hand
/// sample; frames filled into silences come from no record.
class FrameReplay : public TrackerSource {
 public:
  FrameReplay(std::string what, std::string path, std::vector<TrackerFrame> frames, SourceStats base, const SourceOptions& o,
              bool records_are_hands = false)
      : what_(std::move(what)), path_(std::move(path)), frames_(std::move(frames)), base_(std::move(base)) {
    const std::int64_t limit = o.frames;
    Plausibility plausible(o);
    for (TrackerFrame& f : frames_) plausible.apply(&f);
    plausible.addTo(&base_);
    if (frames_.empty()) throw SourceError(path_ + ": no usable frames (" + base_.detail + ")");
    rate_ = replayRate(frames_, &fill_);
    fillSilences(&frames_, rate_, path_, &fill_);
    if (!(rate_ > 1.0 && rate_ <= 20000.0)) {  // up to 20 kHz: 10 kHz streams (dt 0.1 ms) are real
      char buf[200];
      if (frames_.size() < 2)
        std::snprintf(buf, sizeof buf, ": only %zu usable frame, no frame rate", frames_.size());
      else
        std::snprintf(buf, sizeof buf, ": implausible frame rate %.6g Hz over %zu frames (timestamps %lld..%lld us)", rate_,
                      frames_.size(), static_cast<long long>(frames_.front().timestamp_us),
                      static_cast<long long>(frames_.back().timestamp_us));
      // Why frames went: e.g. timestamps that decrease (a reversed file) or repeat.
      throw SourceError(path_ + buf + (base_.detail.empty() ? std::string() : " (" + base_.detail + ")"));
    }
    end_ = frames_.size();
    if (limit > 0) end_ = std::min(end_, static_cast<size_t>(limit));
    for (const TrackerFrame& f : frames_)
      for (const TrackedHand& h : f.hands) (h.right ? right_ : left_) = true;
    records_.resize(frames_.size());
    for (size_t i = 0; i < frames_.size(); ++i) {
      const bool filled = i < fill_.is_filled.size() && fill_.is_filled[i];
      records_[i] = filled ? 0u : records_are_hands ? static_cast<std::uint32_t>(frames_[i].hands.size()) : 1u;
      records_total_ += records_[i];
      if (i < end_) records_to_limit_ += records_[i];
    }
  }
  std::string describe() const override {
    char buf[200];
    const std::uint64_t filled = filledIn(end_);
    int n = std::snprintf(buf, sizeof buf, " (%zu frames, %.2f Hz", end_, rate_);
    if (fill_.gaps)
      n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), ", %llu gap(s) in the timestamps left out of the rate",
                         static_cast<unsigned long long>(fill_.gaps));
    if (filled)
      n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), ", %llu of the frames without hands in silences of 1 s or more",
                         static_cast<unsigned long long>(filled));
    std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), ")");
    return what_ + " " + path_ + buf;
  }
  double nominalRate() const override { return rate_; }
  bool hasSide(bool right) const override { return right ? right_ : left_; }
  bool next(TrackerFrame* frame) override {
    if (pos_ >= end_) return false;
    records_played_ += records_[pos_];
    *frame = frames_[pos_++];
    unplayable_ = true;
    return true;
  }
  void unplay() override {
    if (!unplayable_ || pos_ == 0) return;  // once per next()
    unplayable_ = false;
    --pos_;
    records_played_ -= records_[pos_];
  }
  std::int64_t remaining() const override { return static_cast<std::int64_t>(end_ - pos_); }
  SourceStats stats() const override {
    SourceStats s = base_;
    s.frames = pos_;
    s.not_played = records_total_ - records_played_;
    s.not_played_beyond_limit = records_total_ - records_to_limit_;
    s.received = base_.received > s.not_played ? base_.received - s.not_played : 0;
    return s;
  }
  const std::vector<TrackerFrame>& all() const { return frames_; }
  const PauseFill& filled() const { return fill_; }
  /// Frames filled into silences among the first `n`.
  std::uint64_t filledIn(size_t n) const {
    std::uint64_t c = 0;
    for (size_t i = 0; i < n && i < fill_.is_filled.size(); ++i) c += fill_.is_filled[i];
    return c;
  }

 private:
  PauseFill fill_;
  std::string what_, path_;
  std::vector<TrackerFrame> frames_;
  SourceStats base_;
  std::vector<std::uint32_t> records_;  // per frame: the records it came from (0: filled into a silence)
  std::uint64_t records_total_ = 0, records_to_limit_ = 0, records_played_ = 0;
  bool unplayable_ = false;  // next() returned a frame that unplay() may take back
  double rate_ = 0.0;
  size_t pos_ = 0, end_ = 0;
  bool right_ = false, left_ = false;
};

dtrack::MapOptions mapOptions(const SourceOptions& o) {
  dtrack::MapOptions m;
  m.X_WT = o.X_WT;
  if (o.units_to_m > 0.0) m.units_to_m = o.units_to_m;
  m.y_up = o.y_up;
  m.palm_offset_m = o.palm_offset_m;
  return m;
}
dtrack::ParseLimits parseLimits(const SourceOptions& o) {
  dtrack::ParseLimits l;
  l.max_bytes = o.max_datagram_bytes;
  return l;
}

void addDecoderStats(const dtrack::Decoder& d, std::uint64_t side_dropped, SourceStats* s) {
  s->received = d.received();
  s->rejected = d.rejectedTotal() + side_dropped;
  s->detail = d.summary();
  if (side_dropped) s->detail += "; hands not in the hand map (id, or not its side) " + std::to_string(side_dropped);
  s->by_reason.clear();
  for (int r = 0; r < static_cast<int>(dtrack::Reject::kCount); ++r)
    if (d.rejected(static_cast<dtrack::Reject>(r)))
      s->by_reason.emplace_back(dtrack::reasonName(static_cast<dtrack::Reject>(r)), d.rejected(static_cast<dtrack::Reject>(r)));
  if (side_dropped) s->by_reason.emplace_back("hand not in the hand map (id, or not its side)", side_dropped);
}

std::unique_ptr<FrameReplay> leapReplay(const std::string& path, const SourceOptions& o) {
  leap::Recording rec;
  try {
    rec = leap::Recording::load(path, o.X_WT);
  } catch (const std::exception& e) {
    throw SourceError(e.what());
  }
  std::vector<TrackerFrame> frames = rec.frames();
  std::uint64_t dropped = 0;
  for (TrackerFrame& f : frames) dropped += applyHandSides(&f, o);
  SourceStats s;
  const leap::ReadStats& r = rec.stats();
  s.received = r.frames_in;
  s.rejected = r.frames_rejected_total() + r.hands_rejected_total() + dropped;
  s.detail = r.summary();
  if (dropped) s.detail += "; hands not in the hand map (id, or not its side) " + std::to_string(dropped);
  for (int i = 0; i < static_cast<int>(leap::FrameReject::kCount); ++i)
    if (r.frameRejects(static_cast<leap::FrameReject>(i)))
      s.by_reason.emplace_back(std::string("frame: ") + leap::reasonName(static_cast<leap::FrameReject>(i)),
                               r.frameRejects(static_cast<leap::FrameReject>(i)));
  for (int i = 0; i < static_cast<int>(leap::HandReject::kCount); ++i)
    if (r.handRejects(static_cast<leap::HandReject>(i)))
      s.by_reason.emplace_back(std::string("hand: ") + leap::reasonName(static_cast<leap::HandReject>(i)),
                               r.handRejects(static_cast<leap::HandReject>(i)));
  if (dropped) s.by_reason.emplace_back("hand not in the hand map (id, or not its side)", dropped);
  return std::make_unique<FrameReplay>("leap replay", path, std::move(frames), std::move(s), o);
}

/// DTrack datagrams (a .dtrack file, or the records of a raw recording with their arrival times).
std::unique_ptr<FrameReplay> dtrackReplay(const std::string& path, const std::vector<RawRecord>& records, const SourceOptions& o,
                                          const char* what) {
  dtrack::Decoder dec(parseLimits(o), mapOptions(o));
  std::vector<TrackerFrame> frames;
  std::uint64_t dropped = 0;
  TrackerFrame f;
  for (const RawRecord& r : records)
    if (dec.feed(r.bytes, r.arrival_ns / 1000, &f)) {
      dropped += applyHandSides(&f, o);
      frames.push_back(f);
    }
  SourceStats s;
  addDecoderStats(dec, dropped, &s);
  if (frames.empty() && records.size() > 0 && dec.rejectedTotal() > 0)
    throw SourceError(path + ": no usable frames (" + s.detail + "; last: " + dec.lastDetail() + ")");
  return std::make_unique<FrameReplay>(what, path, std::move(frames), std::move(s), o);
}

std::vector<RawRecord> dtrackFileRecords(const std::string& path) {
  std::vector<RawRecord> out;
  for (std::string& d : dtrack::splitDatagrams(readFile(path))) out.push_back({0, std::move(d)});
  if (out.empty()) throw SourceError(path + ": no datagrams");
  return out;
}

std::unique_ptr<FrameReplay> jsonlReplay(const std::string& path, const SourceOptions& o, bool aria) {
  skeleton::JsonlRecording r;
  try {
    r = aria ? skeleton::readAriaCsv(readFile(path), path, o.X_WT) : skeleton::readJsonl(readFile(path), path, o.X_WT);
  } catch (const skeleton::JsonlError& e) {
    throw SourceError(e.what());
  }
  std::uint64_t dropped = 0;
  for (TrackerFrame& f : r.frames) dropped += applyHandSides(&f, o);
  SourceStats s;
  s.received = r.lines;
  s.by_reason = r.by_reason;
  for (const auto& [k, v] : r.by_reason) s.rejected += v;
  s.detail = r.summary();
  if (dropped) {
    s.detail += "; hands not in the hand map (id, or not its side) " + std::to_string(dropped);
    s.by_reason.emplace_back("hand not in the hand map (id, or not its side)", dropped);
    s.rejected += dropped;
  }
  return std::make_unique<FrameReplay>(r.format + " replay", path, std::move(r.frames), std::move(s), o);
}

std::unique_ptr<FrameReplay> openReplay(const std::string& path, const std::string& format, const SourceOptions& o) {
  if (format == "leap") return leapReplay(path, o);
  if (format == "openxr" || format == "mediapipe" || format == "aria") return jsonlReplay(path, o, format == "aria");
  if (format == "synthetic") {
    synthetic::Generated g;
    try {
      g = synthetic::generate(synthetic::parseScript(readFile(path), path), o.X_WT);
    } catch (const synthetic::ScriptError& e) {
      throw SourceError(e.what());
    }
    std::uint64_t dropped = 0;
    for (TrackerFrame& f : g.frames) dropped += applyHandSides(&f, o);
    SourceStats s;
    s.received = g.samples;
    s.rejected = g.rejected + dropped;
    s.by_reason = g.by_reason;
    s.detail = "synthetic hand samples " + std::to_string(g.samples) + " (rejected: ";
    for (size_t i = 0; i < g.by_reason.size(); ++i)
      s.detail += (i ? ", " : "") + g.by_reason[i].first + " " + std::to_string(g.by_reason[i].second);
    s.detail += g.by_reason.empty() ? "none)" : ")";
    if (dropped) s.by_reason.emplace_back("hand not in the hand map (id, or not its side)", dropped);
    return std::make_unique<FrameReplay>("synthetic", path, std::move(g.frames), std::move(s), o, /*records_are_hands=*/true);
  }
  if (format == "dtrack") return dtrackReplay(path, dtrackFileRecords(path), o, "dtrack replay");
  if (format == "raw") {
    std::string kind;
    const std::vector<RawRecord> recs = readRaw(path, &kind);
    if (kind != "dtrack") throw SourceError(path + ": raw recording of unsupported kind '" + kind + "'");
    return dtrackReplay(path, recs, o, "raw dtrack replay");
  }
  throw SourceError(path + ": unknown recording format (expected Leap JSON, DTrack datagrams or a godhand raw recording)");
}

/// Live ART DTrack over UDP: a non-blocking socket bound to host:port (at start()).
class DtrackUdp final : public TrackerSource {
 public:
  DtrackUdp(std::string host, int port, const SourceOptions& o)
      : host_(std::move(host)), port_(port), opt_(o), dec_(parseLimits(o), mapOptions(o)), plausible_(o), buf_(65536 + 1) {}
  ~DtrackUdp() override {
    if (fd_ >= 0) ::close(fd_);
  }
  std::string describe() const override {
    return "dtrack udp " + host_ + ":" + std::to_string(port_) + (fd_ >= 0 ? " (bound)" : "");
  }
  double nominalRate() const override { return opt_.live_rate_hz; }
  bool hasSide(bool) const override { return true; }
  bool live() const override { return true; }
  std::int64_t remaining() const override { return -1; }
  void start() override {
    if (fd_ >= 0) return;
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port_));
    if (::inet_pton(AF_INET, host_.c_str(), &a.sin_addr) != 1) throw SourceError("dtrack://" + host_ + ": not an IPv4 address");
    const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) throw SourceError(std::string("dtrack: socket: ") + std::strerror(errno));
    const int rcvbuf = 1 << 20;
    (void)::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    if (::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
      const std::string why = std::strerror(errno);
      ::close(fd);
      throw SourceError("dtrack: cannot bind " + host_ + ":" + std::to_string(port_) + ": " + why);
    }
    fd_ = fd;
  }
  bool waitReadable(int timeout_ms) override {
    if (fd_ < 0) start();
    pollfd p{fd_, POLLIN, 0};
    return ::poll(&p, 1, std::max(0, timeout_ms)) > 0;
  }
  bool next(TrackerFrame* frame) override {
    if (fd_ < 0) start();
    // At most kDatagramsPerCall datagrams a call: a flood of datagrams that parse slowly and are
    // rejected (29 KB each, 20,000 a second) otherwise kept this loop from returning, and the
    // ingest from publishing or sending heartbeats, for as long as the flood lasted.
    for (int handled = 0; handled < kDatagramsPerCall; ++handled) {
      const ssize_t n = ::recv(fd_, buf_.data(), buf_.size(), MSG_TRUNC);
      if (n < 0) {
        if (errno == EINTR) continue;
        return false;  // EAGAIN: nothing ready (other errors: counted as nothing, retried later)
      }
      const std::int64_t arrival = systemNowNs();
      const size_t len = std::min(static_cast<size_t>(n), buf_.size());
      std::string bytes(buf_.data(), len);
      if (static_cast<size_t>(n) > buf_.size()) bytes.append(static_cast<size_t>(n) - len, '\0');  // keeps the size: oversized
      if (tap_) tap_(bytes, arrival);
      if (dec_.feed(bytes, arrival / 1000, frame)) {
        side_dropped_ += applyHandSides(frame, opt_);
        plausible_.apply(frame);
        last_arrival_ = arrival;
        return true;
      }
    }
    return false;  // more may be waiting: the caller polls again
  }
  static constexpr int kDatagramsPerCall = 64;
  SourceStats stats() const override {
    SourceStats s;
    s.frames = dec_.accepted();
    addDecoderStats(dec_, side_dropped_, &s);
    plausible_.addTo(&s);
    return s;
  }
  std::int64_t lastArrivalNs() const override { return last_arrival_; }
  void setTap(std::function<void(const std::string&, std::int64_t)> tap) override { tap_ = std::move(tap); }

 private:
  std::string host_;
  int port_;
  SourceOptions opt_;
  dtrack::Decoder dec_;
  Plausibility plausible_;
  std::vector<char> buf_;
  int fd_ = -1;
  std::uint64_t side_dropped_ = 0;
  std::int64_t last_arrival_ = 0;
  std::function<void(const std::string&, std::int64_t)> tap_;
};

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

double number(const std::string& s, const std::string& what) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) throw SourceError(what + ": '" + s + "' is not a finite number");
  return v;
}

}  // namespace

std::string detectFormat(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SourceError(path + ": cannot open (" + std::strerror(errno) + ")");
  char buf[4096] = {};
  in.read(buf, sizeof buf);
  std::string head(buf, static_cast<size_t>(in.gcount()));
  if (head.compare(0, 3, kUtf8Bom) == 0) head.erase(0, 3);  // every reader skips it too
  size_t i = 0;
  while (i < head.size() && std::isspace(static_cast<unsigned char>(head[i]))) ++i;
  if (i == head.size()) throw SourceError(path + (head.empty() ? ": empty file" : ": only white space"));
  if (head[i] == '{') {
    // The first line whole (a JSON Lines frame of two OpenXR hands is ~6 KB), up to 1 MB.
    std::string first = head;
    while (first.find('\n') == std::string::npos && first.size() < (1u << 20) && in) {
      in.read(buf, sizeof buf);
      first.append(buf, static_cast<size_t>(in.gcount()));
    }
    const size_t nl = first.find('\n');
    if (nl != std::string::npos) {
      first.resize(nl);
      const std::string f = skeleton::jsonlFormat(first);
      if (!f.empty()) return f;
      // A frame where the header belongs: JSON Lines whose header line is missing (read as Leap
      // JSON it fails on line 2, which says nothing about the cause).
      const std::string frame = skeleton::jsonlFrameWithoutHeader(first);
      if (!frame.empty())
        throw SourceError(path + ": the first line is a frame of " + frame +
                          " JSON Lines: the header line is missing (first line {\"format\": \"" +
                          (frame == "OpenXR" ? "godhand-openxr-hands" : "godhand-mediapipe-world") + "\", \"version\": 1})");
    }
    return "leap";
  }
  if (head.compare(0, 11, "godhand-raw") == 0) return "raw";
  if (skeleton::isAriaHeader(head)) return "aria";
  if (head.compare(i, 17, "godhand-synthetic") == 0) return "synthetic";
  if (head.compare(0, 3, "fr ") == 0) return "dtrack";
  return "";
}

std::vector<std::pair<int, bool>> parseHandSides(const std::string& text) {
  std::vector<std::pair<int, bool>> out;
  if (text.empty()) return out;
  for (const std::string& item : split(text, ',')) {
    const auto parts = split(item, ':');
    if (parts.size() != 2 || (parts[1] != "left" && parts[1] != "right"))
      throw SourceError("hand map '" + text + "': expected ID:left|right[,ID:left|right]");
    const double id = number(parts[0], "hand map id");
    if (id < 0 || id > 1000 || std::floor(id) != id) throw SourceError("hand map '" + text + "': id must be an integer in 0..1000");
    for (const auto& p : out)
      if (p.first == static_cast<int>(id)) throw SourceError("hand map '" + text + "': id " + parts[0] + " given twice");
    out.emplace_back(static_cast<int>(id), parts[1] == "right");
  }
  return out;
}

Pose parsePose(const std::string& text) {
  const auto parts = split(text, ',');
  std::vector<double> v;
  for (const std::string& p : parts) v.push_back(number(p, "pose '" + text + "'"));
  Pose X;
  if (v.size() != 3 && v.size() != 6 && v.size() != 7)
    throw SourceError("pose '" + text + "': expected x,y,z[,rx,ry,rz degrees | ,qw,qx,qy,qz]");
  for (double c : {v[0], v[1], v[2]})
    if (std::abs(c) > 1e4) throw SourceError("pose '" + text + "': translation beyond 10 km");
  X.p = Vec3(v[0], v[1], v[2]);
  if (v.size() == 6) {
    constexpr double kDeg = 3.14159265358979323846 / 180.0;
    X.q = Quat(Eigen::AngleAxisd(v[5] * kDeg, Vec3::UnitZ()) * Eigen::AngleAxisd(v[4] * kDeg, Vec3::UnitY()) *
               Eigen::AngleAxisd(v[3] * kDeg, Vec3::UnitX()));
  } else if (v.size() == 7) {
    Quat q(v[3], v[4], v[5], v[6]);
    if (!(q.norm() > 1e-9)) throw SourceError("pose '" + text + "': zero quaternion");
    X.q = q.normalized();
  }
  return X;
}

std::unique_ptr<TrackerSource> openSource(const std::string& spec, std::int64_t frames) {
  SourceOptions o;
  o.frames = frames;
  return openSource(spec, o);
}

std::unique_ptr<TrackerSource> openSource(const std::string& spec, const SourceOptions& o) {
  if (spec.rfind("dtrack://", 0) == 0) {
    std::string rest = spec.substr(9);
    while (!rest.empty() && rest.back() == '/') rest.pop_back();
    std::string host = rest;
    int port = 5000;
    const auto colon = rest.rfind(':');
    if (colon != std::string::npos) {
      host = rest.substr(0, colon);
      const std::string ps = rest.substr(colon + 1);
      char* end = nullptr;
      const long p = std::strtol(ps.c_str(), &end, 10);
      if (ps.empty() || *end != '\0' || p < 1 || p > 65535) throw SourceError(spec + ": port must be 1..65535");
      port = static_cast<int>(p);
    }
    if (host.empty()) host = "127.0.0.1";
    in_addr tmp{};
    if (::inet_pton(AF_INET, host.c_str(), &tmp) != 1) throw SourceError(spec + ": host must be an IPv4 address (e.g. 127.0.0.1)");
    return std::make_unique<DtrackUdp>(host, port, o);
  }
  if (spec.find("://") != std::string::npos) throw SourceError("unknown live source '" + spec + "' (expected dtrack://HOST:PORT)");
  if (spec.rfind("leap:", 0) == 0) return openReplay(spec.substr(5), "leap", o);
  if (spec.rfind("dtrack:", 0) == 0) return openReplay(spec.substr(7), "dtrack", o);
  if (spec.rfind("raw:", 0) == 0) return openReplay(spec.substr(4), "raw", o);
  const std::string format = detectFormat(spec);
  if (format.empty())
    throw SourceError(spec + ": unknown recording format (expected Leap JSON, DTrack datagrams (fr ...), OpenXR / MediaPipe JSON Lines, Aria MPS hand tracking CSV, a synthetic script or a godhand raw recording)");
  return openReplay(spec, format, o);
}

const TrackedHand* handOfSide(const TrackerFrame& frame, bool right) {
  const TrackedHand* best = nullptr;
  for (const TrackedHand& h : frame.hands)
    if (h.right == right && (!best || h.confidence > best->confidence)) best = &h;
  return best;
}

// ---- recording.h ----

LoadedRecording loadRecording(const std::string& path, const Pose& X_WT) {
  SourceOptions o;
  o.X_WT = X_WT;
  return loadRecording(path, o);
}

LoadedRecording loadRecording(const std::string& path, const SourceOptions& options) {
  if (path.find("://") != std::string::npos) throw SourceError(path + ": a live source, not a recording file");
  const std::string format = detectFormat(path);
  if (format.empty())
    throw SourceError(path + ": unknown recording format (expected Leap JSON, DTrack datagrams (fr ...), OpenXR / MediaPipe JSON Lines, Aria MPS hand tracking CSV, a synthetic script or a godhand raw recording)");
  SourceOptions o = options;
  o.frames = 0;
  const std::unique_ptr<FrameReplay> r = openReplay(path, format, o);
  LoadedRecording out;
  out.frames = r->all();
  out.format = format;
  out.mean_rate_hz = r->nominalRate();
  out.rejections = r->stats().detail;
  out.filled_frames = r->filled().frames;
  out.pauses = r->filled().pauses;
  out.gaps = r->filled().gaps;
  std::size_t n = 0;
  for (const TrackerFrame& f : out.frames)
    for (const TrackedHand& h : f.hands) {
      out.mean_palm_W += h.X_W_palm.p;
      ++n;
      (h.right ? out.has_right : out.has_left) = true;
    }
  if (n == 0) throw SourceError(path + ": no tracked hands (" + out.rejections + ")");
  out.mean_palm_W /= static_cast<double>(n);
  return out;
}

RawWriter::RawWriter(const std::string& path, const std::string& kind) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) throw SourceError(path + ": cannot write (" + std::strerror(errno) + ")");
  ok_ = std::fprintf(f_, "godhand-raw 1 %s\n", kind.c_str()) > 0;
}

RawWriter::~RawWriter() {
  if (f_) std::fclose(f_);
}

void RawWriter::write(const std::string& bytes, std::int64_t arrival_ns) {
  if (!f_) return;
  ok_ = ok_ && std::fprintf(f_, "@ %lld %zu\n", static_cast<long long>(arrival_ns), bytes.size()) > 0;
  ok_ = ok_ && std::fwrite(bytes.data(), 1, bytes.size(), f_) == bytes.size();
  ok_ = ok_ && std::fputc('\n', f_) != EOF;
  ++records_;
}

std::vector<RawRecord> readRaw(const std::string& path, std::string* kind) {
  const std::string data = readFile(path);
  size_t pos = data.find('\n');
  if (pos == std::string::npos) throw SourceError(path + ": raw recording without a header line");
  {
    std::istringstream h(data.substr(0, pos));
    std::string magic;
    int version = 0;
    h >> magic >> version >> *kind;
    if (magic != "godhand-raw" || version != 1 || kind->empty()) throw SourceError(path + ": bad raw recording header");
  }
  ++pos;
  std::vector<RawRecord> out;
  while (pos < data.size()) {
    const size_t e = data.find('\n', pos);
    if (e == std::string::npos) throw SourceError(path + ": record " + std::to_string(out.size() + 1) + " header cut");
    const std::string line = data.substr(pos, e - pos);
    long long t = 0;
    unsigned long long n = 0;
    char at = 0;
    int used = 0;
    if (std::sscanf(line.c_str(), "%c %lld %llu%n", &at, &t, &n, &used) != 3 || at != '@' || static_cast<size_t>(used) != line.size() ||
        n > (1u << 20))
      throw SourceError(path + ": record " + std::to_string(out.size() + 1) + ": bad record header");
    pos = e + 1;
    if (data.size() - pos < n + 1 || data[pos + n] != '\n') throw SourceError(path + ": record " + std::to_string(out.size() + 1) + " cut");
    out.push_back({t, data.substr(pos, n)});
    pos += n + 1;
  }
  if (out.empty()) throw SourceError(path + ": raw recording holds no records");
  return out;
}

}  // namespace godhand::bridges
