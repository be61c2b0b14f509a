// Core stage structs (core/pipeline/stages.h) <-> DDS wire types (idl/godhand.idl), field by
// field. Every double is copied, never recomputed, so a lock-step distributed run computes what
// the in-process run computes bit for bit. Incoming samples are validated: a sample with a
// wrong body count, a non-finite or non-unit pose, or an index out of range is rejected with a
// reason (the service counts it) and never reaches the core.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/source_counts.h"
#include "godhand.h"  // generated wire types
#include "pipeline/stages.h"

namespace godhand::svc {

/// Scene objects the wire carries (idl/godhand.idl: SceneState and SceneDescription): a scene of
/// more is refused by godhand-scene at start-up.
constexpr std::size_t kMaxSceneObjects = 10000;

/// CLOCK_REALTIME in ns (comparable across the processes of one machine; across machines only
/// as far as their clocks are synchronised).
std::int64_t nowNs();

void toWire(const Pose& X, msg::Pose* out);
Pose fromWire(const msg::Pose& X);
void toWire(const Shape& s, msg::BodyShape* out);

/// The stamp of a sample derived from `source` (frame and tracker time carried on, publish time now).
msg::Stamp derivedStamp(const msg::Stamp& source);

// ingest -> solver
bool fromWire(const msg::HandTarget& in, std::size_t bodies, std::vector<Pose>* targets,
              std::vector<unsigned char>* driven, std::string* why);

// solver -> resolver. max loads on the wire: 256 (the rest is dropped and flagged).
void toWire(const HandProposal& p, msg::HandProposal* out);
bool fromWire(const msg::HandProposal& in, std::size_t bodies, int objects, HandProposal* out, std::string* why);

// resolver -> everyone
void toWire(const HandResult& r, const HandModel& model, bool stale, msg::HandState* out);
bool fromWire(const msg::HandState& in, std::size_t bodies, HandResult* out, std::string* why);

// resolver -> scene. objects: the scene's object poses (for the per-object wrench summary).
void toWire(const ForceSet& f, const CollisionWorld& world, msg::ContactForces* out);
bool fromWire(const msg::ContactForces& in, int objects, ForceSet* out, std::string* why);

// scene -> everyone
void toWire(const SceneSnapshot& s, msg::SceneState* out);
bool fromWire(const msg::SceneState& in, int objects, SceneSnapshot* out, std::string* why);

void describeScene(const Scene& scene, const std::string& file, msg::SceneDescription* out);

// ingest -> the launcher (ServiceStatus.source): bounded by boundReasons (the total is kept).
void toWire(std::uint64_t run, const SourceCounts& c, msg::SourceCounts* out);
/// The counts and their run (0: the sample carries no source).
SourceCounts fromWire(const msg::SourceCounts& in, std::uint64_t* run);

/// A heartbeat a service of ours can send: finite rate and latency, every counter (and the
/// source's counts and their sum) at most 2^53. Else false with the reason (a hostile or corrupt
/// sample, whose counts would wrap sums or print NaN in a report).
bool plausible(const msg::ServiceStatus& s, std::string* why);

}  // namespace godhand::svc
