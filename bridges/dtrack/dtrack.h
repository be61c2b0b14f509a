// ART DTrack2/DTrack3 ASCII output (one UDP datagram per measurement): a strict parser, a stream
// decoder that rejects stale / duplicate / incomplete datagrams, and the mapping of DTrack
// Fingertracking hands onto godhand's TrackedHand. The format and the ART SDK's behaviour on bad
// input are in ../shared/design/trackers/DTRACK.md; what this reader does better, point by point:
//
//  | ART C++ SDK (v2.9.0)                                   | here                                   |
//  |--------------------------------------------------------|----------------------------------------|
//  | `nan` / `inf` parse (strtod): NaN poses come out       | rejected, counted "NaN/Inf"            |
//  | a datagram without `gl` / `6d` (e.g. truncated at a    | final CR LF required; a line the stream|
//  | line boundary) keeps the previous hands "tracked"      | had before and now lacks: "incomplete" |
//  | garbage of unknown lines parses (fr 0, old hands kept) | first line must be `fr N`; any byte    |
//  |                                                        | outside printable ASCII / CR LF:       |
//  |                                                        | "parse error"                          |
//  | any whitespace, extra values in a block are accepted   | exactly one space, exact value counts  |
//  |                                                        | (6d position: 3 or 6), `][` adjacency  |
//  | datagram > 32768 bytes silently cut by recv            | received whole (64 KiB buffer),        |
//  |                                                        | rejected "oversized" above the limit   |
//  | no check of rotations                                  | orthonormal within 1e-3, det > 0, then |
//  |                                                        | re-orthonormalised; else counted       |
//  | no range checks                                        | positions, lengths, angles, ids, nf,   |
//  |                                                        | lr, counts checked: "out of range"     |
//  | frame counter unchecked (reordered / repeated frames   | fr must increase: older or equal is    |
//  | delivered as new)                                      | "stale/duplicate" (a jump back by more |
//  |                                                        | than restart_window is a restart)      |
//
// Conventions. Room frame: DTrack "normal" calibration (Z up) in mm, which (with an identity
// calibration) is godhand's tracker frame T in mm; a "powerwall" room (Y up) maps (x, −z, y).
// DTrack hand frame: +X toward the fingers, +Y toward the little finger, Z = X × Y (palmar for
// a right hand, dorsal for a left one). godhand palm frame: y = fingers, z = back of the hand,
// x = y × z, so R_palm = [Y X −Z] (right) or [−Y X Z] (left). Fingers thumb first; joints by
// ART's formula (DIP = (−lo, 0, 0), PIP, MCP in the finger frame). 3-finger hands (thumb, index,
// middle): ring and little are the middle finger shifted by one / two knuckle spacings
// (index→middle MCP) and marked synthesised.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "leap/leap_recording.h"
#include "math/pose.h"

namespace godhand::dtrack {

enum class Reject : int {
  kParse,           ///< not a DTrack datagram, bad syntax, wrong value count, unterminated block
  kNotFinite,       ///< nan / inf in a value
  kNotOrthonormal,  ///< a rotation not orthonormal within kOrthoTolerance, or a reflection
  kOutOfRange,      ///< a value outside its plausible range (position, length, angle, id, nf, lr)
  kOversized,       ///< longer than the configured maximum datagram size
  kStale,           ///< frame counter not newer than the last accepted one (reordered / repeated)
  kIncomplete,      ///< truncated: no final CR LF, or a line the stream carried before is missing
  kCount
};
const char* reasonName(Reject r);

struct Body {
  int id = -1;
  double quality = 0.0;
  Vec3 p_mm = Vec3::Zero();
  Mat3 R = Mat3::Identity();  ///< re-orthonormalised
};

struct Finger {
  Vec3 p_mm = Vec3::Zero();   ///< tip sphere centre, hand frame
  Mat3 R = Mat3::Identity();  ///< outermost phalanx, hand frame
  double ro = 0, lo = 0, a_om = 0, lm = 0, a_mi = 0, li = 0;  ///< mm, degrees
};

struct Hand {
  int id = -1;
  double quality = 0.0;  ///< < 0: not tracked
  bool right = true;
  Vec3 p_mm = Vec3::Zero();  ///< back of the hand (the hand target), room
  Mat3 R = Mat3::Identity();
  std::vector<Finger> fingers;  ///< 3 or 5, thumb first
};

struct Datagram {
  std::uint64_t frame = 0;
  bool has_ts = false;
  double ts = -1.0;  ///< seconds since 00:00 UTC (from ts, or from ts2 as the SDK does)
  bool has_ts2 = false;
  std::int64_t ts2_us = 0;       ///< Unix time, µs
  std::int64_t latency_us = -1;  ///< ts2's exposure-to-send latency
  int bodies_calibrated = -1, hands_calibrated = -1;  ///< 6dcal / glcal, −1 when absent
  bool has_6d = false, has_gl = false;
  std::vector<Body> bodies;
  std::vector<Hand> hands;
  std::size_t unknown_lines = 0;
  /// Bit per line kind seen (kLineFr ...), for the decoder's completeness check.
  unsigned lines = 0;
};
enum LineBit : unsigned { kLineFr = 1, kLineTs = 2, kLineTs2 = 4, kLine6dcal = 8, kLine6d = 16, kLineGlcal = 32, kLineGl = 64 };

struct ParseLimits {
  std::size_t max_bytes = 32768;        ///< the ART SDK's receive buffer; larger is "oversized"
  double max_position_mm = 1.0e5;       ///< |coordinate| of a body / hand (100 m)
  double max_finger_mm = 300.0;         ///< |coordinate| of a fingertip in the hand frame
  double max_length_mm = 200.0;         ///< phalanx length, tip radius
  double max_angle_deg = 180.0;
  int max_id = 1000;
  int max_count = 1000;                 ///< bodies / hands in one line
  double ortho_tolerance = 1e-3;        ///< max |RᵀR − I| (values are printed with 4–6 decimals)
  bool require_final_crlf = true;       ///< a datagram's last line must end with CR LF
};

struct ParseResult {
  bool ok = true;
  Reject reason = Reject::kParse;
  std::string detail;  ///< one line, e.g. "line 6 'gl': block 3: expected 9 values, got 8"
};

/// Parses one datagram. Never throws; on failure `out` is unspecified.
ParseResult parseDatagram(std::string_view bytes, Datagram* out, const ParseLimits& limits = {});

/// Mapping of DTrack hands onto TrackedHand and calibration of the room frame.
struct MapOptions {
  /// Palm centre relative to the hand target, metres, in a mirror-neutral frame: (toward the
  /// fingers, toward the thumb, toward the palm). A real ART target on the back of the hand:
  /// about (0, 0, 0.02). The sample streams need zero (their pose is the Leap palm).
  Vec3 palm_offset_m = Vec3::Zero();
  double units_to_m = 1e-3;  ///< DTrack writes mm
  bool y_up = false;         ///< a "powerwall" room calibration (Y up): (x, y, z) -> (x, −z, y)
  Pose X_WT;                 ///< tracker (room, after units and axes) to world
  /// The tip is the tip sphere's centre plus `ro` along the finger's +X (the manual); false:
  /// the sphere centre itself (ART's Unity plugin).
  bool tip_adds_radius = true;
};

/// Room (DTrack units, after the up-axis change) point -> world metres.
Vec3 roomToWorld(const Vec3& p_room, const MapOptions& o);
/// One DTrack 6d body -> TrackedBody (world): the body frame's pose, calibrated like the hands.
leap::TrackedBody mapBody(const Body& b, const MapOptions& o);
/// One DTrack hand -> TrackedHand (world). Fingers: joints by ART's formula.
leap::TrackedHand mapHand(const Hand& h, const MapOptions& o);
/// Joints of a finger in the hand frame (mm): mcp, pip, dip, tip.
std::array<Vec3, 4> fingerJoints(const Finger& f, bool tip_adds_radius);

/// Per-stream state: parse, reject stale / incomplete datagrams, map hands. Counts everything.
class Decoder {
 public:
  explicit Decoder(const ParseLimits& limits = {}, const MapOptions& map = {}) : limits_(limits), map_(map) {}
  /// A datagram that arrived at arrival_us (any clock; used when it has no ts). Returns true and
  /// fills `frame` when it is accepted.
  bool feed(std::string_view bytes, std::int64_t arrival_us, leap::TrackerFrame* frame);

  std::uint64_t received() const { return received_; }
  std::uint64_t accepted() const { return accepted_; }
  std::uint64_t rejected(Reject r) const { return rejected_[static_cast<std::size_t>(r)]; }
  std::uint64_t rejectedTotal() const;
  std::uint64_t restarts() const { return restarts_; }
  std::uint64_t handsNotTracked() const { return hands_untracked_; }
  std::uint64_t bodiesNotTracked() const { return bodies_untracked_; }
  std::uint64_t handsDuplicate() const { return hands_duplicate_; }
  std::uint64_t fingersSynthesised() const { return fingers_synth_; }
  /// One line: "datagrams 300/307 accepted; rejected: parse error 3, stale/duplicate 4; ...".
  std::string summary() const;
  /// Last rejection's detail (diagnostics).
  const std::string& lastDetail() const { return last_detail_; }
  /// Frame counter jumps back by more than this: a tracker restart, accepted.
  std::uint64_t restart_window = 1000;
  /// Nothing accepted for this long (arrival time) while datagrams keep coming that are all behind
  /// the last accepted frame: they are followed again (counted). One datagram far ahead, e.g. a
  /// spoofed one, stopped tracking for 1,000 frames (10 s at 100 Hz) before this.
  std::int64_t refollow_after_us = 250000;
  std::uint64_t refollows() const { return refollows_; }

 private:
  ParseLimits limits_;
  MapOptions map_;
  std::uint64_t received_ = 0, accepted_ = 0, restarts_ = 0, hands_untracked_ = 0, hands_duplicate_ = 0, fingers_synth_ = 0;
  std::uint64_t bodies_untracked_ = 0;
  std::array<std::uint64_t, static_cast<std::size_t>(Reject::kCount)> rejected_{};
  bool have_last_ = false;
  std::uint64_t last_frame_ = 0;
  std::int64_t last_accept_arrival_us_ = 0;
  std::uint64_t refollows_ = 0;
  unsigned seen_lines_ = 0;  ///< union of the line kinds of accepted datagrams
  double last_ts_ = -1.0;
  std::int64_t day_offset_us_ = 0;  ///< ts wraps at midnight
  double ts_before_last_ = -1.0;    ///< last_ts_ and day_offset_us_ before the last accepted datagram
  std::int64_t day_offset_before_last_ = 0;
  std::string last_detail_;
  void reject(Reject r, const std::string& detail);
};

/// Splits a .dtrack file (datagrams separated by an empty line, CR LF; LF-only files repaired)
/// into datagrams, each ending with CR LF.
std::vector<std::string> splitDatagrams(const std::string& file_bytes);

}  // namespace godhand::dtrack
