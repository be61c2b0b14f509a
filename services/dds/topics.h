// Topic and QoS profile names of godhand's DDS graph (ARCHITECTURE.md "Processes"). No Fast DDS
// include: services name topics and profiles through these constants only.
#pragma once

namespace godhand::dds {

namespace topic {
constexpr const char* kHandTarget = "godhand/hand_target";              // ingest -> solver
constexpr const char* kHandProposal = "godhand/hand_proposal";          // solver -> resolver
constexpr const char* kHandState = "godhand/hand_state";                // resolver -> everyone
constexpr const char* kContactForces = "godhand/contact_forces";        // resolver -> scene
constexpr const char* kSceneState = "godhand/scene_state";              // scene -> everyone
constexpr const char* kSceneDescription = "godhand/scene_description";  // scene -> late joiners
constexpr const char* kServiceStatus = "godhand/service_status";        // every service -> monitors
constexpr const char* kSceneResume = "godhand/scene_resume";            // resolver -> a restarted scene (live)
}  // namespace topic

// Profile names of deploy/dds/*.xml. Writers and readers share the names (a data_writer and a
// data_reader profile of each).
namespace profile {
constexpr const char* kParticipant = "godhand_participant";
constexpr const char* kStreamLive = "godhand.stream.live";  // BEST_EFFORT VOLATILE KEEP_LAST 1
constexpr const char* kLockStep = "godhand.lockstep";       // RELIABLE TRANSIENT_LOCAL KEEP_LAST 256
constexpr const char* kState = "godhand.state";             // RELIABLE TRANSIENT_LOCAL KEEP_LAST 1
constexpr const char* kStatus = "godhand.status";           // RELIABLE TRANSIENT_LOCAL KEEP_LAST 1
}  // namespace profile

}  // namespace godhand::dds
