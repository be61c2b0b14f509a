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
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "leap/leap_recording.h"

namespace godhand::bridges {

using TrackerFrame = leap::TrackerFrame;
using TrackedHand = leap::TrackedHand;
using TrackedBody = leap::TrackedBody;

struct SourceError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct SourceStats {
  std::uint64_t frames = 0;    ///< frames delivered
  std::uint64_t rejected = 0;  ///< frames and hands dropped as bad input
  std::string detail;          ///< one line: the rejections by reason
  /// Records / datagrams that came in. A replay reads and checks its whole file when it is opened:
  /// its received are the records of the frames played so far plus every rejected record (its
  /// rejections are the whole file's); the records of frames not played are not_played, not received.
  std::uint64_t received = 0;
  std::vector<std::pair<std::string, std::uint64_t>> by_reason;  ///< rejections by reason (nonzero)
  /// A replay: records of the file whose frames were not played (yet), and of them those beyond the
  /// frames limit (SourceOptions::frames: never played). A live source: 0.
  std::uint64_t not_played = 0, not_played_beyond_limit = 0;
};

/// How a source is opened: calibration and source-specific settings. The defaults reproduce the
/// behaviour of openSource(spec, frames).
struct SourceOptions {
  std::int64_t frames = 0;  ///< > 0: a replay stops after its first frames
  /// Tracker frame T (after units and up-axis conversion) to world. Leap's T is fixed by the
  /// reader (mm, +Y up -> m, +Z up); DTrack's is the room frame.
  Pose X_WT;
  double units_to_m = 0.0;  ///< DTrack room units; 0: the format's (mm)
  bool y_up = false;        ///< DTrack room calibrated Y up ("powerwall")
  Vec3 palm_offset_m = Vec3::Zero();  ///< DTrack: palm centre from the hand target (fingers, thumb, palm)
  /// Tracker hand id -> side ("0:left,1:right"); empty: the tracker's own side. A hand whose id
  /// is not listed is dropped (counted) when the map is not empty.
  std::vector<std::pair<int, bool>> hand_sides;
  double live_rate_hz = 60.0;  ///< nominal rate reported by a live source
  std::size_t max_datagram_bytes = 32768;
  /// Plausibility of every source's hands (after calibration): a hand with a palm or joint
  /// coordinate beyond max_abs_position_m (the tracking volume, a box about the tracker's origin
  /// in its frame T, so that a world placed far away keeps its hands), or
  /// whose palm moved faster than max_speed_mps since the last accepted hand of its side (within
  /// 0.5 s: after a longer gap it is a re-acquisition), is dropped and counted.
  double max_abs_position_m = 50.0;
  double max_speed_mps = 30.0;
};

/// Parses "ID:left|right[,ID:left|right...]" for SourceOptions::hand_sides; throws SourceError.
std::vector<std::pair<int, bool>> parseHandSides(const std::string& text);
/// Parses a pose: "x,y,z" (metres), "x,y,z,rx,ry,rz" (plus rotations in degrees about the fixed
/// X, then Y, then Z axis: R = Rz Ry Rx) or "x,y,z,qw,qx,qy,qz" (a quaternion, normalised; not
/// zero). Throws SourceError with one line.
Pose parsePose(const std::string& text);

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
  /// The frame last returned by next() was not used (the caller stopped before publishing it): a
  /// replay counts it as not played again; a live source counted its datagram when it came.
  virtual void unplay() {}
  /// Frames left, or −1 for a live source.
  virtual std::int64_t remaining() const = 0;
  virtual SourceStats stats() const = 0;
  /// Live sources (a socket): next() returning false means "nothing yet", not the end.
  virtual bool live() const { return false; }
  /// Live: acquires the resource (binds the socket); throws SourceError. Replays: nothing.
  /// next() calls it when it was not called; openSource does not, so that a process that only
  /// wants nominalRate() never binds the port.
  virtual void start() {}
  /// Live: waits up to timeout_ms for input (poll); returns true when some may be ready.
  virtual bool waitReadable(int timeout_ms) { (void)timeout_ms; return true; }
  /// Arrival time (steady clock, ns) of the frame last returned by next(); 0 when unknown.
  virtual std::int64_t lastArrivalNs() const { return 0; }
  /// Raw input recording (see recording.h): called with every datagram / record that comes in.
  virtual void setTap(std::function<void(const std::string& bytes, std::int64_t arrival_ns)> tap) { (void)tap; }
};

/// Opens a source. spec:
///  - a recording file of any supported format, detected by content (not by its name): Leap
///    Motion JSON (bridges/leap/leap_recording.h), DTrack datagrams (.dtrack, bridges/dtrack),
///    a godhand raw recording (`godhand-ingest --record`, recording.h), OpenXR / MediaPipe JSON
///    Lines (bridges/skeleton/jsonl.h);
///  - "leap:FILE" / "dtrack:FILE" force a reader;
///  - "dtrack://HOST:PORT" a live DTrack UDP stream received on HOST:PORT (HOST an IPv4 address,
///    e.g. 127.0.0.1; default port 5000 when ":PORT" is omitted).
/// Throws SourceError with a one-line reason (unknown kind, unreadable or empty recording).
std::unique_ptr<TrackerSource> openSource(const std::string& spec, std::int64_t frames = 0);
std::unique_ptr<TrackerSource> openSource(const std::string& spec, const SourceOptions& options);

/// The format of a recording file by its first bytes: "leap", "dtrack", "raw", "openxr",
/// "mediapipe" (JSON Lines with a godhand header line, bridges/skeleton/jsonl.h), or "" (unknown).
std::string detectFormat(const std::string& path);

/// The best tracked hand of a side in a frame (highest confidence), nullptr if none.
const TrackedHand* handOfSide(const TrackerFrame& frame, bool right);

}  // namespace godhand::bridges
