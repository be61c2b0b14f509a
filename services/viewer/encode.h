// JSON payloads of the viewer's channels (feed.h), from the DDS wire types (idl/godhand.idl).
// Poses are [px, py, pz, qw, qx, qy, qz] (m, W), shapes [type, radius, half_length, hx, hy, hz]
// (type 0 capsule along body z, 1 sphere, 2 box). Every payload carries `recv_ns`, when the
// viewer took the sample (CLOCK_REALTIME ns), so the page can tell the viewer's own delay from
// the services'. Non-finite numbers (a foreign writer) become null, never invalid JSON.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "godhand.h"

namespace godhand::viewer {

nlohmann::json poseJson(const msg::Pose& p);
nlohmann::json stampJson(const msg::Stamp& s);

/// `penetration_m`: exact depth of the hand against the viewer's copy of the scene, < 0 = unknown.
nlohmann::json handStateJson(const msg::HandState& s, std::int64_t recv_ns, double penetration_m);
nlohmann::json handTargetJson(const msg::HandTarget& t, std::int64_t recv_ns);
nlohmann::json sceneStateJson(const msg::SceneState& s, std::int64_t recv_ns);
nlohmann::json contactForcesJson(const msg::ContactForces& f, std::int64_t recv_ns);
nlohmann::json serviceStatusJson(const msg::ServiceStatus& s, std::int64_t recv_ns);
/// `mesh_url(index)` is where the page fetches object `index`'s triangles ("" = not served).
nlohmann::json sceneDescriptionJson(const msg::SceneDescription& d, std::int64_t recv_ns,
                                    const std::string& generation);

}  // namespace godhand::viewer
