// Models driven by one 6-DOF tracked body (a tool, a prop): every body's tracker_segment is
// "tool", and the tracked body's pose is the pose of the model frame M, each God object at its
// rest pose in M (deploy/models/tool1.pbtxt: one box). Which tracked body drives a cluster is the
// lab's `tracker_body` (a DTrack 6d id). The hand models go through Retargeter instead.
#pragma once

#include <string>
#include <vector>

#include "leap/leap_recording.h"
#include "model/hand_model.h"

namespace godhand::leap {

inline constexpr const char* kToolSegment = "tool";

/// True when every body of the model is driven by the tool segment (and there is one at least).
bool isToolModel(const HandModel& model);

/// The targets of a tool model from the frame's body `id`: X_WB · X_MB_rest per body, every
/// body driven. False (and nothing written) when the frame does not carry that body.
bool toolTargets(const HandModel& model, const TrackerFrame& frame, int id, std::vector<Pose>* X_W_targets,
                 std::vector<unsigned char>* has_target, double* quality);

}  // namespace godhand::leap
