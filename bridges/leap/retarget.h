// Retargeting: a tracked Leap hand (TrackedHand) -> one target pose per body of a hand model,
// and HandTracks: which tracked hand drives the left / right cluster in each frame.
//
// Design. The targets must be consistent with the model, so that a God hand in free space can
// reach them exactly (free-space tracking error ~0, METHOD.md §5): the tracker's bone lengths,
// knuckle positions and palm size differ from the model's (see the [figure] lines of
// tests/bridges/test_retarget.cc), so tracked positions are never copied into 16-body targets.
// Instead only the tracked directions are used, and positions follow by forward kinematics:
//
//  * palm: the model frame M is placed at the tracked palm frame (X_WM = X_W_palm, the model
//    frame is the palm frame: y fingers, z back of the hand); the palm body's target is
//    X_WM · X_MB_rest (= X_W_palm for the shipped models, whose palm body is the model frame).
//  * phalanx "<finger>.k" (k = 1, 2, 3), driven by the tracked segment mcp→pip, pip→dip,
//    dip→tip (the thumb's three Leap bones map to thumb.1..3 the same way), processed parent
//    first. Orientation: its body z axis (the capsule axis) is put exactly along the tracked
//    segment direction d. The twist about d is not observed by the tracker, so it is chosen
//    to satisfy the parent joint (TwistRule::kJointConsistent, the default):
//      - SPHERICAL_2DOF (universal joint Rx(θ1) Ry(θ2) of hand_model.h): the unique angles with
//        Rx(θ1) Ry(θ2) e_z = d in the parent's joint frame (|θ2| ≤ 90°), so the twist lock holds
//        exactly;
//      - REVOLUTE: the child's joint x axis is the parent's hinge axis made orthogonal to d,
//        so the hinge rows are violated only by the part of d the hinge cannot produce,
//        asin|d · x_hinge| (the minimum possible with z on d); zero when the tracked finger
//        bends in the hinge plane. When d is (nearly) along the hinge, or the joint is FIXED,
//        or the model's joint z is not the child's body z, the minimal-rotation rule is used.
//    TwistRule::kMinimalRotation instead takes the rest orientation relative to the parent,
//    carried by the parent's target, and rotates it by the minimal rotation that takes its z
//    onto d (also z exactly on d, but it leaves a twist the joints may not allow). When the
//    tracked segment is degenerate (shorter than kMinSegment) the body keeps the rest
//    orientation carried by its parent (zero joint angles: the parent's direction).
//    Position: the child's joint anchor is placed on the parent's,
//      p_anchor = p_P + R_P X_PJ.p,  p_C = p_anchor − R_C X_CJ.p,
//    so the targets have zero joint gap by construction (up to rounding, ~1e-17 m).
//  * fingertip sphere "<finger>.tip" (6-body model, no joints): the tracked tip position in the
//    tracked palm frame, scaled by s = model hand size / tracked hand size, placed in the model
//    frame: p = X_WM (s · X_W_palm⁻¹ p_tip). Hand size = Σ over the model's non-thumb tips of the
//    palm-centre→tip distance (model: at rest; tracker: |palm→mcp| + the three bone lengths, the
//    straight-finger length, which Leap keeps constant). One uniform s keeps the hand's shape, so
//    a tracked pinch (thumb tip on index tip) stays a pinch on the model. Only the thumb is used
//    when the model has no other tip. Orientation: rest orientation carried by the palm, rotated
//    minimally so its z follows the tracked distal bone (dip→tip); a sphere's orientation has no
//    effect on contacts.
//  * bodies with an empty tracker_segment get has_target 0 (their pose is set to the rest pose
//    carried by the palm target, so it is finite, but it is not a target).
//
// Model requirements (checked by the constructor, std::invalid_argument otherwise): every
// tracker_segment is empty, "palm", "<finger>.1|2|3" or "<finger>.tip" with finger in thumb,
// index, middle, ring, pinky; a phalanx body has a parent joint whose parent body is the palm or a
// phalanx (driven); tips need no joint. The model's side is inferred from its thumb (rest x < 0:
// right, > 0: left); targets() refuses a tracked hand of the other side.
#pragma once

#include <array>
#include <optional>
#include <stdexcept>
#include <vector>

#include "leap/leap_recording.h"
#include "model/hand_model.h"

namespace godhand::leap {

enum class TwistRule { kJointConsistent, kMinimalRotation };

struct RetargetOptions {
  TwistRule twist = TwistRule::kJointConsistent;
};

class Retargeter {
 public:
  static constexpr double kMinSegment = 1e-6;  ///< m; shorter tracked segments are degenerate

  explicit Retargeter(const HandModel& model, const RetargetOptions& options = {});

  /// One target per model body (X_W_targets->size() == bodies.size()); has_target[i] = 1 for
  /// driven bodies. Returns the number of degenerate tracked segments met (diagnostics; 0 on
  /// healthy data). Throws std::invalid_argument when the hand's side differs from the model's.
  /// Const and without hidden state: one Retargeter may serve several threads.
  int targets(const TrackedHand& hand, std::vector<Pose>* X_W_targets, std::vector<unsigned char>* has_target) const;

  /// Model side from its thumb: true = right, false = left, empty when the model has no thumb.
  std::optional<bool> modelIsRight() const { return model_right_; }
  /// Uniform scale applied to fingertip positions for this tracked hand (1 when the model has no tips).
  double tipScale(const TrackedHand& hand) const;

 private:
  enum class Kind { kNone, kPalm, kPhalanx, kTip };
  struct Drive {
    Kind kind = Kind::kNone;
    int finger = -1;
    int bone = -1;    ///< phalanx 0..2
    int joint = -1;   ///< parent joint (phalanx)
    int parent = -1;  ///< parent body (phalanx)
  };
  HandModel model_;                ///< a copy: the Retargeter may outlive the caller's model
  RetargetOptions options_;
  std::vector<Drive> drive_;
  std::vector<int> order_;         ///< bodies, parents before children
  std::optional<bool> model_right_;
  double model_tip_size_ = 0.0;    ///< Σ |tip_rest − palm origin| over the size fingers
  std::array<bool, kFingerCount> size_fingers_{};
};

/// What one side (left or right cluster) sees in a frame.
struct HandSlot {
  bool right = true;
  bool present = false;   ///< a hand of this side is tracked in this frame
  bool appeared = false;  ///< present now, and absent or another id in the previous frame
  bool lost = false;      ///< present in the previous frame, and absent or another id now
  int id = -1;            ///< id of the present hand (of the last one when absent)
  TrackedHand hand;       ///< valid when present
};

/// Assigns each frame's tracked hands to the left / right slot and reports appear / lose
/// events. A hand whose id changes counts as lost + appeared in the same frame (its God hand
/// must be re-acquired, METHOD.md §2 step 7). When one frame has two hands of the same side the
/// one with the slot's current id is kept, else the most confident; the other is ignored and
/// counted.
class HandTracks {
 public:
  HandTracks();
  void update(const TrackerFrame& frame);
  const HandSlot& slot(bool right) const { return slots_[right ? 1 : 0]; }
  std::size_t extraHandsIgnored() const { return extra_ignored_; }
  std::size_t appearedCount(bool right) const { return appeared_[right ? 1 : 0]; }
  std::size_t lostCount(bool right) const { return lost_[right ? 1 : 0]; }
  void reset();

 private:
  std::array<HandSlot, 2> slots_;
  std::array<std::size_t, 2> appeared_{};
  std::array<std::size_t, 2> lost_{};
  std::size_t extra_ignored_ = 0;
};

}  // namespace godhand::leap
