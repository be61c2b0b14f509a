// Pieces of a live ingest loop kept out of the service's main so that they are tested:
// calibration given as text (command line, later the lab) -> SourceOptions, and the silence
// monitor that reports a source which stopped delivering frames.
#pragma once

#include <cstdint>
#include <string>

#include "source/tracker_source.h"

namespace godhand::bridges {

/// Calibration as given on godhand-ingest's command line; empty fields keep the defaults.
struct CalibrationText {
  std::string pose;         ///< tracker to world, parsePose(): "x,y,z[,rx,ry,rz | ,qw,qx,qy,qz]"
  std::string units;        ///< DTrack room units: "mm" (default), "cm", "m"
  std::string up;           ///< DTrack room up axis: "z" (default, "normal"), "y" ("powerwall")
  std::string hand_map;     ///< parseHandSides(): "0:left,1:right"
  std::string palm_offset;  ///< DTrack: "F,T,P" metres from the hand target to the palm centre
  int max_datagram = 0;     ///< bytes; 0: 32768
  double volume_m = 0.0;    ///< tracking volume: max |coordinate| (m) of a hand; 0: 50 m
  double max_speed = 0.0;   ///< palm speed limit (m/s); 0: 30 m/s
};

/// Throws SourceError with one line naming the bad field.
SourceOptions sourceOptions(const CalibrationText& text, std::int64_t frames = 0);

/// Reports a live source that delivers no frame for `silence_s` (once per silence) and when it
/// resumes. Times are seconds on any monotonic clock.
class SilenceMonitor {
 public:
  explicit SilenceMonitor(double silence_s = 1.0) : silence_s_(silence_s) {}
  /// A frame arrived at t. Returns true when it ends a reported silence.
  bool frame(double t);
  /// Returns true exactly once when, at time t, the source has been silent for silence_s
  /// (counted from the first call of frame() or of poll()).
  bool poll(double t);
  bool silent() const { return silent_; }
  std::uint64_t silences() const { return silences_; }
  double lastFrameTime() const { return last_; }

 private:
  double silence_s_;
  double last_ = -1.0;
  bool silent_ = false;
  std::uint64_t silences_ = 0;
};

}  // namespace godhand::bridges
