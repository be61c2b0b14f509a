// Recordings of skeleton hands in JSON Lines (formats of ours; bridges/README.md documents them):
//  - "godhand-openxr-hands" v1: OpenXR XR_EXT_hand_tracking, 26 joints per hand, the OpenXR
//    reference space (+Y up, −Z forward, metres), time in ns; optionally 6-DOF bodies (a
//    controller's aim or grip pose: an XrSpaceLocation with its flags) that drive tool models;
//  - "godhand-mediapipe-world" v1: MediaPipe Hands world landmarks, 21 per hand, camera frame
//    (x right, y down, z forward, metres) plus an optional origin, time in µs.
// The first line is a header {"format": NAME, "version": 1}; every other line one frame. Bad
// lines and hands are dropped and counted by reason, never fatal; an unreadable header is.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "leap/leap_recording.h"
#include "skeleton/skeleton.h"

namespace godhand::skeleton {

struct JsonlError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct JsonlRecording {
  std::string format;  ///< "openxr" or "mediapipe"
  std::vector<leap::TrackerFrame> frames;
  std::uint64_t lines = 0;  ///< frame lines read (without the header and empty lines)
  std::uint64_t hands_kept = 0;
  std::uint64_t bodies_kept = 0;  ///< OpenXR 6-DOF bodies ("bodies": aim / grip poses, objects)
  std::vector<std::pair<std::string, std::uint64_t>> by_reason;  ///< line and hand rejections
  std::string summary() const;  ///< one line
};

/// "openxr", "mediapipe" or "" from a file's first line.
std::string jsonlFormat(const std::string& first_line);
/// "OpenXR" or "MediaPipe" when the line is a frame of that format (an object with "hands" and
/// "time_ns" / "time_us"), i.e. a file whose header line is missing; "" otherwise.
std::string jsonlFrameWithoutHeader(const std::string& first_line);

/// Parses a whole file's text. Throws JsonlError ("NAME: reason") on a bad header.
JsonlRecording readJsonl(const std::string& text, const std::string& name, const Pose& X_WT = Pose());

}  // namespace godhand::skeleton
