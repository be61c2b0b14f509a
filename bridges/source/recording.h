// Recordings as a whole (for godhand-bench and tests) and godhand's raw input recording.
//
// Raw recording (what `godhand-ingest --record FILE` writes): every datagram / record exactly as
// it came in, bad ones included, with its arrival time, so that replaying the file as a source
// feeds the same bytes through the same decoder:
//
//   godhand-raw 1 dtrack\n                 header: format version, payload kind
//   @ <arrival_ns> <n>\n<n bytes>\n        one record (arrival: steady clock ns of the recorder)
//
// The payload bytes are arbitrary (garbage datagrams are kept); a reader takes exactly n bytes.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "source/tracker_source.h"

namespace godhand::bridges {

struct LoadedRecording {
  std::vector<TrackerFrame> frames;  ///< world frame, as openSource would deliver them
  double mean_rate_hz = 0.0;         ///< (frames − 1) / duration (gaps left out, see below); 0 for < 2 frames
  Vec3 mean_palm_W = Vec3::Zero();   ///< mean palm position over all hands of all frames
  std::string format;                ///< "leap", "dtrack", "raw"
  std::string rejections;            ///< one line: what was dropped, by reason
  bool has_right = false, has_left = false;
  /// Gaps in the timestamps (intervals of at least 0.1 s and over twice the median), left out of
  /// the rate; of them the silences (1 s or more, as a live source's --silence) filled with
  /// frames without hands at the rate (included in frames), and how many frames that took.
  std::uint64_t gaps = 0, pauses = 0, filled_frames = 0;
};

/// Loads every frame of a recording file of any supported format (detected by content).
/// X_WT: tracker to world (as SourceOptions::X_WT). Throws SourceError with one line
/// ("FILE: reason") when the file is unreadable, of unknown format or holds no usable frame.
LoadedRecording loadRecording(const std::string& path, const Pose& X_WT = Pose());
LoadedRecording loadRecording(const std::string& path, const SourceOptions& options);

/// Writes a raw recording (header at construction). Throws SourceError when the file cannot be
/// opened; write errors are remembered (ok() false) rather than thrown.
class RawWriter {
 public:
  RawWriter(const std::string& path, const std::string& kind);
  ~RawWriter();
  RawWriter(const RawWriter&) = delete;
  RawWriter& operator=(const RawWriter&) = delete;
  void write(const std::string& bytes, std::int64_t arrival_ns);
  bool ok() const { return ok_; }
  std::uint64_t records() const { return records_; }

 private:
  std::FILE* f_ = nullptr;
  bool ok_ = true;
  std::uint64_t records_ = 0;
};

struct RawRecord {
  std::int64_t arrival_ns = 0;
  std::string bytes;
};
/// Reads a raw recording; throws SourceError ("FILE: reason") on a bad header or a cut record.
std::vector<RawRecord> readRaw(const std::string& path, std::string* kind);

}  // namespace godhand::bridges
