#include "runtime/lab_checks.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "leap/tool_target.h"

namespace godhand::svc {

std::unique_ptr<leap::Retargeter> clusterRetargeter(const LabCluster& cluster, const HandModel& model) {
  const bool tool_cluster = cluster.tracker_body >= 0;
  if (tool_cluster != leap::isToolModel(model))
    throw std::runtime_error(
        "cluster '" + cluster.name + "': model " + cluster.model +
        (tool_cluster ? " is not a tool model (every body's tracker_segment \"tool\"), but the cluster gives tracker_body"
                      : " is a tool model (tracker_segment \"tool\"): give the cluster tracker_body N, not a side"));
  if (tool_cluster) return nullptr;
  std::unique_ptr<leap::Retargeter> r;
  try {
    r = std::make_unique<leap::Retargeter>(model);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("cluster '" + cluster.name + "': " + e.what());
  }
  const auto right = r->modelIsRight();
  if (right && *right != (cluster.side == "right"))
    throw std::runtime_error("cluster '" + cluster.name + "': model " + cluster.model + " is a " + (*right ? "right" : "left") +
                             " hand but the cluster's side is " + cluster.side);
  return r;
}

bridges::CalibrationText labCalibration(const LabConfig& lab) {
  bridges::CalibrationText c;
  if (!lab.tracker.any()) return c;
  c.pose = lab.tracker.pose;
  c.units = lab.tracker.units;
  c.up = lab.tracker.up;
  c.hand_map = lab.tracker.hand_map;
  c.palm_offset = lab.tracker.palm_offset;
  c.volume_m = lab.tracker.volume_m;
  c.max_speed = lab.tracker.max_speed;
  try {
    bridges::sourceOptions(c);
  } catch (const std::exception& e) {
    throw std::runtime_error(lab.file + ": tracker: " + e.what());
  }
  return c;
}

std::string replayRateMismatch(double given_hz, double recording_hz, double speed, const std::string& recording) {
  const double replay_hz = recording_hz * speed;
  if (!(given_hz > 0.0) || std::abs(given_hz - replay_hz) <= 0.01 * replay_hz) return "";
  auto num = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return std::string(buf);
  };
  return "--frame-rate " + num(given_hz) + " Hz: " + recording + " replays at " + num(replay_hz) + " Hz" +
         (speed != 1.0 ? " here (its " + num(recording_hz) + " Hz times --speed " + num(speed) + ")" : std::string()) +
         ": the services step at the replay's rate (godhand-launch gives them that; by hand, give each the same)";
}

}  // namespace godhand::svc
