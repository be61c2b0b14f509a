#include "leap/tool_target.h"

namespace godhand::leap {

bool isToolModel(const HandModel& model) {
  if (model.bodies.empty()) return false;
  for (const Body& b : model.bodies)
    if (b.tracker_segment != kToolSegment) return false;
  return true;
}

bool toolTargets(const HandModel& model, const TrackerFrame& frame, int id, std::vector<Pose>* X_W_targets,
                 std::vector<unsigned char>* has_target, double* quality) {
  for (const TrackedBody& t : frame.bodies) {
    if (t.id != id) continue;
    X_W_targets->resize(model.bodies.size());
    has_target->assign(model.bodies.size(), 1);
    for (size_t b = 0; b < model.bodies.size(); ++b) (*X_W_targets)[b] = t.X_WB * model.bodies[b].X_MB_rest;
    if (quality) *quality = t.quality;
    return true;
  }
  return false;
}

}  // namespace godhand::leap
