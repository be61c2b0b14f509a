// The one small interface every tracker source implements, so that adding a tracker (ART DTrack
// over UDP, OpenXR 26-joint hands, 21-landmark skeletons, VRPN, synthetic motions) touches
// bridges/ alone: godhand-ingest opens a source by a spec string, pulls frames from it and
// retargets them onto the lab's hand models.
//
// Frames are in the world frame W (SI units, +Z up; the source applies its tracker-to-world pose)
// and carry the tracker's own timestamp. A source never throws from next(): bad samples are
// dropped and counted by reason in stats().
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

#include "leap/leap_recording.h"

namespace godhand::bridges {

using TrackerFrame = leap::TrackerFrame;
using TrackedHand = leap::TrackedHand;

struct SourceError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct SourceStats {
  std::uint64_t frames = 0;    ///< frames delivered
  std::uint64_t rejected = 0;  ///< frames and hands dropped as bad input
  std::string detail;          ///< one line: the rejections by reason
};

class TrackerSource {
 public:
  virtual ~TrackerSource() = default;
  /// One line for logs, e.g. "leap replay deploy/recordings/pinch.json (307 frames, 110.0 Hz)".
  virtual std::string describe() const = 0;
  /// The rate frames are produced at, Hz (a replay: the recording's mean rate).
  virtual double nominalRate() const = 0;
  /// Which hand sides the source can deliver (a replay: the sides that occur in it).
  virtual bool hasSide(bool right) const = 0;
  /// The next frame; false at the end of the stream (a replay) or when none is ready.
  virtual bool next(TrackerFrame* frame) = 0;
  /// Frames left, or −1 for a live source.
  virtual std::int64_t remaining() const = 0;
  virtual SourceStats stats() const = 0;
};

/// Opens a source. spec: "leap:FILE" or a file ending in ".json" (a Leap Motion JSON recording,
/// formats of bridges/leap/leap_recording.h). frames > 0 limits a replay to its first frames.
/// Throws SourceError with a one-line reason (unknown kind, unreadable or empty recording).
std::unique_ptr<TrackerSource> openSource(const std::string& spec, std::int64_t frames = 0);

/// The best tracked hand of a side in a frame (highest confidence), nullptr if none.
const TrackedHand* handOfSide(const TrackerFrame& frame, bool right);

}  // namespace godhand::bridges
