// Synthetic scripted hand motions for tests and demos: a small text file, deterministic (no
// randomness; the same file gives the same frames bit for bit).
//
//   godhand-synthetic 1                first line
//   # comment                          (also after a command)
//   rate HZ                            frame rate, 1..10000 (default 100); before any motion
//   start SIDE X Y Z                   the hand exists from now on, flat,
//                                      palm down, fingers along +Y, palm centre at X Y Z (m)
//   move SIDE S X Y Z                  over S seconds, linearly to X Y Z (the other hands hold,
//                                      unless joined by ';', below)
//   curl SIDE S F                      over S seconds, the fingers flex to fraction F in [0, 1]
//   roll SIDE S DEG                    over S seconds, the hand turns about its finger axis (+Y
//                                      through the palm centre) to DEG degrees in [-180, 180]
//                                      (right-handed about +Y; 0 = palm down): roll right 90 has
//                                      the right palm facing -X, thumb up; roll left -90 has the
//                                      left palm facing +X (two hands facing, e.g. a grasp)
//   hold S                             every hand still for S seconds
//   lost SIDE S                        the hand is not tracked for S seconds (dropout), then
//                                      re-acquired where it was
//   teleport SIDE X Y Z                the next frame has the hand at X Y Z (a jump)
//   nan SIDE N                         the next N frames carry NaN for that hand (rejected and
//                                      counted by the source, like a tracker's bad samples)
//   A ; B                              motions (move, curl, roll; one per hand) joined by ';'
//                                      on one line run at the same time, each over its own S,
//                                      e.g. both hands closing on a box or lifting it:
//                                        move right 0.5 0.04 0 0.16 ; move left 0.5 -0.04 0 0.16
//
// SIDE is right or left. Positions are in the tracker frame T (m, +Z up), placed by X_WT. Each
// hand is a 21-landmark skeleton mapped by bridges/skeleton (the same path as MediaPipe's).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "leap/leap_recording.h"
#include "math/pose.h"

namespace godhand::synthetic {

struct ScriptError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Command {
  std::string op;
  int side = -1;  ///< 1 right, 0 left, −1 none
  double seconds = 0.0;
  Vec3 p = Vec3::Zero();
  double value = 0.0;
  int line = 0;
};

struct Script {
  double rate_hz = 100.0;
  std::vector<Command> commands;
};

/// Parses a script; throws ScriptError "NAME:LINE: reason".
Script parseScript(const std::string& text, const std::string& name);

struct Generated {
  std::vector<leap::TrackerFrame> frames;
  std::uint64_t samples = 0;           ///< hand samples generated (tracked ones, NaN included)
  std::uint64_t rejected = 0;          ///< samples the skeleton layer refused (NaN bursts, ...)
  std::vector<std::pair<std::string, std::uint64_t>> by_reason;  ///< those, by reason
};

/// The frames of a script (timestamps from 0 at rate_hz), hands in W.
Generated generate(const Script& script, const Pose& X_WT = Pose());

/// 21 landmarks (T, m) of the flat hand with the palm centre at `palm`, curl in [0, 1], turned by
/// `roll_deg` about +Y through the palm centre (see `roll`).
std::vector<Vec3> handLandmarks(bool right, const Vec3& palm, double curl, double roll_deg = 0.0);

}  // namespace godhand::synthetic
