// One mapping layer from any hand skeleton to TrackedHand (palm frame + mcp/pip/dip/tip per
// finger), so that every source drives the 16- and 6-body models through the same Retargeter:
//  - 21 landmarks (MediaPipe order: wrist, thumb CMC MCP IP TIP, then MCP PIP DIP TIP of index,
//    middle, ring, little), positions only: orientations derived from the bones and the palm;
//  - OpenXR XR_EXT_hand_tracking's 26 joints (palm, wrist, thumb metacarpal proximal distal tip,
//    then metacarpal proximal intermediate distal tip of index, middle, ring, little), each with
//    a pose, radius and location flags: the palm joint's orientation is used when valid.
//
// Frames. Input positions are in the tracker frame T (metres, +Z up) unless a reader converts
// them (OpenXR's +Y up, −Z forward: p_T = (x, −z, y)); X_WT places T in the world.
// Palm frame (as the Leap reader's): y toward the fingers, z the back of the hand, x = y × z
// (thumb on −x for a right hand, +x for a left hand). From 21 landmarks: origin the midpoint of
// the wrist and the middle MCP (OpenXR's palm joint: the centre of the middle metacarpal), y
// along wrist → middle MCP, x from the index → little MCP line (right hand; little → index for a
// left hand) made orthogonal to y, z = x × y.
// Joints: thumb = CMC, MCP, IP, tip (= Leap's mcp, pip, dip, tip of the thumb); fingers = MCP,
// PIP, DIP, tip. OpenXR: thumb = metacarpal, proximal, distal, tip joints; fingers = proximal,
// intermediate, distal, tip (the metacarpal joints are not used).
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "leap/leap_recording.h"
#include "math/pose.h"

namespace godhand::skeleton {

constexpr int kLandmarks = 21;
constexpr int kXrJoints = 26;

struct SkeletonLimits {
  double max_position_m = 100.0;  ///< |coordinate| in the tracker's frame (before calibration)
  double min_bone_m = leap::kMinBoneM;  ///< every bone used (wrist→MCP, phalanges) at least this long
  double max_bone_m = leap::kMaxBoneM;  ///< and at most this long
};

/// Why a skeleton was refused (counted by the readers).
enum class Reject : int { kNotFinite, kOutOfRange, kDegenerate, kInvalidJoint, kCount };
const char* reasonName(Reject r);

/// 21 landmarks in T (m) -> TrackedHand in W. Returns false (and the reason) for a hand that
/// cannot be a hand: not finite, beyond max_position, a bone shorter / longer than the limits,
/// or a degenerate palm (index and little MCP on the wrist→middle line).
bool handFromLandmarks(const std::array<Vec3, kLandmarks>& p_T, bool right, double confidence, int id, const Pose& X_WT,
                       leap::TrackedHand* out, Reject* why, const SkeletonLimits& limits = {});

/// One OpenXR joint (XrHandJointLocationEXT): pose in the OpenXR space, radius, location flags.
struct XrJoint {
  Vec3 p = Vec3::Zero();
  Quat q = Quat::Identity();
  double radius = 0.0;
  std::uint32_t flags = 0;  ///< XR_SPACE_LOCATION_*: 0x1 orientation valid, 0x2 position valid, 0x4 / 0x8 tracked
};
constexpr std::uint32_t kXrOrientationValid = 0x1, kXrPositionValid = 0x2;

/// OpenXR space (+Y up, −Z forward, m) -> T (+Z up): (x, −z, y).
inline Vec3 xrToT(const Vec3& p) { return Vec3(p.x(), -p.z(), p.y()); }

/// The entry point a host application calls once per frame with xrLocateHandJointsEXT's 26
/// joints (positions and orientations in its reference space, converted with xrToT): fills a
/// TrackedHand in W for the Retargeter. Every joint used needs a valid position (else
/// kInvalidJoint); the palm joint's orientation is used when it is valid, else the palm frame
/// is derived from the joints as for 21 landmarks.
bool handFromOpenXr(const std::array<XrJoint, kXrJoints>& joints, bool right, double confidence, int id, const Pose& X_WT,
                    leap::TrackedHand* out, Reject* why, const SkeletonLimits& limits = {});

}  // namespace godhand::skeleton
