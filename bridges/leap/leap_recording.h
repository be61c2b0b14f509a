// Reader of Leap Motion recordings written by leapjs-playback (JSON), converted to godhand's
// conventions: SI units (m), world right-handed +Z up (ARCHITECTURE.md).
//
// Leap frame (device, mm, right-handed): x right, +Y up, +z towards the user. Our device frame T
// (m, +Z up): p_T = (x, −z, y) / 1000 (a rotation of +90° about x, det +1, so directions map
// with the same matrix without the 1/1000). Then p_W = X_WT p_T for a tracker placed at X_WT.
//
// Formats: 0.1 and 1 (every frame a full Leap frame object) and 2 (packed: frames[0] is the
// packing structure, every other entry an array laid out by it, unpacked the way leapjs-playback
// does). Format 2 omits the pointable "type"; it is then recovered from Leap's id convention
// (pointable id = 10 · hand id + type), and the pointable is ignored (counted) when that fails.
//
// Validation (every rejection is counted by reason in ReadStats, nothing is dropped silently):
//  - frame: must be an object with an integer timestamp (µs) and a hands array; timestamps must
//    be non-decreasing (a frame older than the last accepted one is rejected, equal is kept);
//  - hand: integer id, type "left"/"right", finite palmPosition / palmNormal / direction (JSON
//    writes NaN as null: null counts as not finite), direction and normal of unit length within
//    kUnitTolerance and orthogonal within kOrthoTolerance, confidence in [0, 1] (absent: kDefaultConfidence), unique id in its
//    frame, exactly one pointable of each finger type 0..4 with finite mcp/pip/dip/tip positions.
//    A bad hand is dropped from its frame; the rest of the frame is kept.
//  - pointable: tools, unknown finger types and pointables of unknown hands are ignored (counted).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "math/pose.h"

namespace godhand::leap {

enum Finger : int { kThumb = 0, kIndex = 1, kMiddle = 2, kRing = 3, kPinky = 4 };
constexpr int kFingerCount = 5;
/// "thumb", "index", "middle", "ring", "pinky" (the model's tracker_segment prefixes).
const char* fingerName(int finger);

/// Joint indices in TrackedHand::joints_W[finger].
enum FingerJoint : int { kMcp = 0, kPip = 1, kDip = 2, kTip = 3 };

using FingerJoints = std::array<std::array<Vec3, 4>, kFingerCount>;
/// All joints at the origin (Eigen's Vec3 default constructor leaves its storage unset).
inline FingerJoints zeroFingerJoints() {
  FingerJoints j;
  for (auto& finger : j) for (Vec3& p : finger) p.setZero();
  return j;
}

/// One tracked hand, world frame, metres.
struct TrackedHand {
  int id = -1;
  bool right = true;
  double confidence = 0.0;
  /// Palm frame at palmPosition: y = direction (towards the fingers), z = −palmNormal (back of
  /// the hand), x = y × z (thumb side −x for a right hand, +x for a left hand). Orthonormalised:
  /// y exactly along the direction, z the normal made orthogonal to it.
  Pose X_W_palm;
  /// Per finger (thumb..pinky): mcp, pip, dip, tip. For the thumb Leap's "mcp" is the carpo-
  /// metacarpal end of its first bone, so the three thumb segments are metacarpal, proximal,
  /// distal (like the model's thumb.1..3).
  FingerJoints joints_W = zeroFingerJoints();
};

/// One 6-DOF tracked rigid body (a DTrack `6d` body: a tool, a prop), world frame, metres.
struct TrackedBody {
  int id = -1;
  double quality = 0.0;
  Pose X_WB;
};

struct TrackerFrame {
  std::int64_t timestamp_us = 0;
  std::int64_t frame_id = -1;  ///< Leap's frame id, −1 when the file has none
  std::vector<TrackedHand> hands;
  std::vector<TrackedBody> bodies;  ///< 6-DOF bodies (sources that track them: DTrack)
};

enum class FrameReject : int { kNotObject, kMissingTimestamp, kDecreasingTimestamp, kMissingHands, kCount };
enum class HandReject : int {
  kNotObject,          ///< hand entry is not a JSON object
  kMissingField,       ///< id, type, palmPosition, palmNormal or direction absent / wrong shape; confidence not a number
  kBadType,            ///< type is not "left" / "right", or the id is not an integer
  kNotFinite,          ///< NaN (null) or infinite palm position / normal / direction / confidence
  kBadDirection,       ///< direction or normal not unit length, degenerate, or not orthogonal
  kBadConfidence,      ///< confidence outside [0, 1]
  kDuplicateId,        ///< two hands with the same id in one frame (all of them dropped)
  kMissingFinger,      ///< some finger type 0..4 has no pointable
  kDuplicateFinger,    ///< some finger type has two pointables
  kFingerMissingField, ///< a finger's mcp/pip/dip/tip position absent or not 3 numbers
  kFingerNotFinite,    ///< a finger position is NaN (null) or infinite
  kDegenerateFinger,   ///< a bone (palm→mcp, mcp→pip, pip→dip, dip→tip) outside [kMinBoneM, kMaxBoneM]
  kCount
};
const char* reasonName(FrameReject r);
const char* reasonName(HandReject r);

struct ReadStats {
  std::size_t frames_in = 0;    ///< entries in the file's frame list (format 2: without the packing entry)
  std::size_t frames_read = 0;  ///< frames kept
  std::size_t hands_read = 0;   ///< hands kept, over all kept frames
  std::array<std::size_t, static_cast<std::size_t>(FrameReject::kCount)> frames_rejected{};
  std::array<std::size_t, static_cast<std::size_t>(HandReject::kCount)> hands_rejected{};
  std::size_t pointables_ignored = 0;  ///< tools, unknown finger types, unknown hands
  std::size_t hands_confidence_defaulted = 0;  ///< kept hands without "confidence" (Leap SDK 2.0 files)
  std::size_t frames_rejected_total() const;
  std::size_t hands_rejected_total() const;
  std::size_t frameRejects(FrameReject r) const { return frames_rejected[static_cast<std::size_t>(r)]; }
  std::size_t handRejects(HandReject r) const { return hands_rejected[static_cast<std::size_t>(r)]; }
  /// One line: "frames 306/307 (rejected: timestamp decreases 1), hands 305 (rejected: none),
  /// pointables ignored 0".
  std::string summary() const;
};

/// One-line error "FILE: reason".
class RecordingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The bone lengths a tracked hand may have (every source's skeleton check: Leap's palm→mcp and
/// phalanges, the skeleton bridges' wrist→MCP and phalanges): a hand with every joint at one
/// point, or a bone longer than a hand, is not a hand (real Leap hands: 16–61 mm).
constexpr double kMinBoneM = 1e-3;
constexpr double kMaxBoneM = 0.15;

class Recording {
 public:
  static constexpr double kUnitTolerance = 1e-2;   ///< | |v| − 1 | for direction and palmNormal
  static constexpr double kOrthoTolerance = 2e-2;  ///< |direction · palmNormal| (about 1.1°)
  /// A hand without "confidence" (Leap SDK 2.0 recordings have none): a hand in a frame is a
  /// tracked hand, so it gets full confidence (counted in ReadStats::hands_confidence_defaulted).
  static constexpr double kDefaultConfidence = 1.0;

  /// Reads a leapjs-playback JSON file. X_WT: tracker (device frame T, see above) to world,
  /// applied after the unit/axis conversion. Throws RecordingError ("FILE: reason") when the file
  /// cannot be read, is not JSON, has an unsupported format or no usable frame.
  static Recording load(const std::string& path, const Pose& X_WT = Pose());
  /// Same from JSON text; `source` names it in error messages.
  static Recording fromText(const std::string& text, const std::string& source, const Pose& X_WT = Pose());

  const std::vector<TrackerFrame>& frames() const { return frames_; }
  const ReadStats& stats() const { return stats_; }
  /// The file's metadata.formatVersion as written ("0.1", "1", "2").
  const std::string& formatVersion() const { return format_; }
  /// (frames − 1) / (last − first timestamp), Hz; 0 for fewer than two frames or zero duration.
  double meanFrameRate() const;
  /// Mean palm position (world) over all tracked hands of all frames; zero when there are none.
  Vec3 meanPalmPosition() const;

 private:
  std::vector<TrackerFrame> frames_;
  ReadStats stats_;
  std::string format_;
};

/// Leap device coordinates (mm, +Y up) to our device frame T (m, +Z up): (x, −z, y) / 1000.
inline Vec3 leapPointToT(const Vec3& p_mm) { return Vec3(p_mm.x(), -p_mm.z(), p_mm.y()) / 1000.0; }
/// Same axis change for a direction (no scaling).
inline Vec3 leapDirectionToT(const Vec3& d) { return Vec3(d.x(), -d.z(), d.y()); }

}  // namespace godhand::leap
