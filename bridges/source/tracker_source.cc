#include "source/tracker_source.h"

#include <algorithm>
#include <cstdio>
#include <vector>

namespace godhand::bridges {

namespace {

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Replays a Leap JSON recording frame by frame (pacing is the caller's business).
class LeapReplay final : public TrackerSource {
 public:
  LeapReplay(const std::string& path, std::int64_t frames) : path_(path) {
    try {
      rec_ = leap::Recording::load(path);
    } catch (const std::exception& e) {
      throw SourceError(e.what());
    }
    if (rec_.frames().empty()) throw SourceError(path + ": no usable frames");
    rate_ = rec_.meanFrameRate();
    if (!(rate_ > 1.0 && rate_ < 10000.0)) throw SourceError(path + ": implausible frame rate " + std::to_string(rate_));
    end_ = rec_.frames().size();
    if (frames > 0) end_ = std::min(end_, static_cast<size_t>(frames));
    for (const TrackerFrame& f : rec_.frames())
      for (const TrackedHand& h : f.hands) (h.right ? right_ : left_) = true;
  }
  std::string describe() const override {
    char buf[96];
    std::snprintf(buf, sizeof buf, " (%zu frames, %.2f Hz)", end_, rate_);
    return "leap replay " + path_ + buf;
  }
  double nominalRate() const override { return rate_; }
  bool hasSide(bool right) const override { return right ? right_ : left_; }
  bool next(TrackerFrame* frame) override {
    if (pos_ >= end_) return false;
    *frame = rec_.frames()[pos_++];
    return true;
  }
  std::int64_t remaining() const override { return static_cast<std::int64_t>(end_ - pos_); }
  SourceStats stats() const override {
    SourceStats s;
    s.frames = pos_;
    const leap::ReadStats& r = rec_.stats();
    s.rejected = r.frames_rejected_total() + r.hands_rejected_total();
    s.detail = r.summary();
    return s;
  }

 private:
  std::string path_;
  leap::Recording rec_;
  double rate_ = 0.0;
  size_t pos_ = 0, end_ = 0;
  bool right_ = false, left_ = false;
};

}  // namespace

std::unique_ptr<TrackerSource> openSource(const std::string& spec, std::int64_t frames) {
  if (spec.rfind("leap:", 0) == 0) return std::make_unique<LeapReplay>(spec.substr(5), frames);
  if (endsWith(spec, ".json")) return std::make_unique<LeapReplay>(spec, frames);
  throw SourceError("unknown tracker source '" + spec + "' (expected leap:FILE or FILE.json)");
}

const TrackedHand* handOfSide(const TrackerFrame& frame, bool right) {
  const TrackedHand* best = nullptr;
  for (const TrackedHand& h : frame.hands)
    if (h.right == right && (!best || h.confidence > best->confidence)) best = &h;
  return best;
}

}  // namespace godhand::bridges
