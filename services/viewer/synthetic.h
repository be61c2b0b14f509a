// A synthetic hand driven from the page, for trying godhand without a tracker: the page sends
// commands on the client channel "godhand/synthetic_target" (feed.h), {"hand": H, "offset": [x, y,
// z]} (m, world, from the start pose), and godhand-viewer --synthetic CLUSTER publishes that
// cluster's HandTarget at the lab's frame rate: the hand model at rest with its model frame at
// start + offset. The viewer is then the tracker of that hand: run the services with a tracker
// source that publishes nothing for it (godhand-launch --source dtrack://127.0.0.1:PORT, silent).
#pragma once

#include <cstdint>
#include <string>

#include "godhand.h"
#include "model/hand_model.h"
#include "scene/scene.h"

namespace godhand::viewer {

/// Largest offset accepted from the page (m).
constexpr double kMaxSyntheticOffset = 1.0;

/// Parses a page command. False with a one-line reason for anything else than {"hand": integer,
/// "offset": [3 finite numbers, each within ±kMaxSyntheticOffset]}.
bool parseSyntheticCommand(const std::string& payload, int* hand, Vec3* offset, std::string* why);

/// Where the synthetic hand starts: 8 cm above the top of the object whose id is "bunny" (else of
/// the first object, else 0.25 m above the origin), model frame unrotated.
Pose syntheticStart(const Scene& scene);

/// The HandTarget of the model at rest with its frame at X_WM (every body driven, tracked).
void syntheticTarget(const HandModel& model, const Pose& X_WM, std::uint32_t hand, const std::string& cluster,
                     std::uint64_t run, std::uint64_t frame, std::int64_t now_ns, msg::HandTarget* out);

}  // namespace godhand::viewer
