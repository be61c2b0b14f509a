// What the ingest takes from a lab and refuses when it does not fit: each cluster's hand model
// against the cluster (a tool cluster needs a tool model, a hand cluster a hand model of its side
// that the tracker can drive) and the lab's tracker calibration. The ingest uses these;
// godhand-launch calls the same checks before it starts anything, so that such a lab is a
// configuration error (exit 2, one line) instead of an ingest that fails after every other
// service has started.
#pragma once

#include <memory>

#include "common/lab_config.h"
#include "leap/retarget.h"
#include "source/live.h"
#include "model/hand_model.h"

namespace godhand::svc {

/// The retargeting of a hand cluster's model (nullptr for a tool cluster, driven by its tracked
/// body). std::runtime_error (one line, naming the cluster and the model) when the model does
/// not fit the cluster.
std::unique_ptr<leap::Retargeter> clusterRetargeter(const LabCluster& cluster, const HandModel& model);

/// The lab's tracker calibration as the ingest's options (empty fields: not set), checked:
/// std::runtime_error "LAB: tracker: reason" when bridges::sourceOptions refuses it.
bridges::CalibrationText labCalibration(const LabConfig& lab);

/// A recording replays at its own rate (live: times --speed), and the services that step
/// (solvers, scene, resolver) take --frame-rate as the period of every step: a --frame-rate given
/// for a recording that is not that rate (beyond 1 %) would step every frame with the wrong
/// period. "" when given_hz is recording_hz × speed within 1 % (or none was given: given_hz <= 0),
/// else the one-line reason.
std::string replayRateMismatch(double given_hz, double recording_hz, double speed, const std::string& recording);

}  // namespace godhand::svc
