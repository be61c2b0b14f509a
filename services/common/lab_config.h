// Lab configuration (protobuf text, schema idl/lab.proto, e.g. deploy/lab/local.pbtxt): which
// godhand services run, with which arguments, on which host, and the clusters, scene, models
// and DDS settings they share. Read by godhand-launch and by every service through --lab, so
// there is one source of truth. Loading validates everything that can be checked without DDS
// and resolves every path to an absolute one (relative paths are relative to the directory of
// the lab file).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "lab.pb.h"

namespace godhand {

/// Clusters a lab may have: the resolver merges at most this many.
constexpr int kMaxLabClusters = 16;

/// Bad or unreadable lab file: one line "FILE:LINE: field: reason", e.g.
/// "lab.pbtxt:12: clusters[1].side: must be \"right\" or \"left\", got \"up\"".
/// LINE is that of the offending field when known (else of the enclosing entry, else 0 for
/// file-level errors); text-format errors are "FILE:LINE:COLUMN: parser message".
class LabError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A hand cluster (one God hand or tool, one godhand-solver process). `index` is its position in
/// the lab file and its key on the wire (HandTarget.hand, HandState.hand, ...).
struct LabCluster {
  int index = 0;
  std::string name;   ///< [a-z0-9_-]{1,31}, unique
  std::string model;  ///< absolute path of the hand model file (exists)
  std::string side;   ///< which tracked hand drives it: "right" or "left" ("" for a tool)
  int tracker_body = -1;  ///< a tool cluster: the 6-DOF tracked body id that drives it; −1: a hand
};

/// A service to run. Exactly one INGEST, SCENE and RESOLVER, and one SOLVER per cluster.
struct LabService {
  pb::Service::Kind kind = pb::Service::KIND_UNSPECIFIED;
  std::string name;     ///< "ingest", "scene", "resolver" or "solver/<cluster>" (unique)
  std::string cluster;  ///< SOLVER: the cluster's name; "" otherwise
  std::string host;     ///< as written in the file ("" = this machine)
  std::vector<std::string> args;  ///< extra command-line arguments, in order
  bool local = false;   ///< isLocalHost(host): "", "localhost", "127.0.0.1", "::1" or this
                        ///< machine's gethostname() (compared case-insensitively)
};

/// A machine of the lab (Lab.hosts): optional; with hosts, every service's host names one.
struct LabHost {
  std::string name;      ///< [A-Za-z0-9.-]{1,63}, unique
  std::string address;   ///< IPv4 dotted quad on the lab network, unique
  std::string profiles;  ///< absolute path of this host's Fast DDS profiles, or "" = the lab's
};

/// Lab.tracker: the ingest's calibration defaults, as written (checked by the ingest, which
/// parses them: bridges::sourceOptions).
struct LabTracker {
  std::string pose, units, up, hand_map, palm_offset;
  double volume_m = 0.0, max_speed = 0.0;
  bool any() const {
    return !pose.empty() || !units.empty() || !up.empty() || !hand_map.empty() || !palm_offset.empty() || volume_m != 0.0 ||
           max_speed != 0.0;
  }
};

struct LabConfig {
  std::string file;       ///< absolute path of the lab file (loadLab); parseLab: its source_name
  std::string name;       ///< the file's `name`, or the file's stem when empty
  std::string profiles;   ///< absolute path of the Fast DDS XML profiles, or "" = the DDS layer's default
  std::string scene;      ///< absolute path of the scene file (exists)
  std::string recording;  ///< absolute path of the default recording (exists), or "" if none
  int domain_id = 0;      ///< 0..232
  double deadline_s = 10.0;     ///< lock-step input deadline (file value, or 10 when 0/absent)
  double stale_after_s = 0.25;  ///< live staleness threshold (file value, or 0.25 when 0/absent)
  std::vector<LabCluster> clusters;  ///< in file order (index = position), at least one
  std::vector<LabService> services;  ///< in file order
  std::vector<LabHost> hosts;        ///< in file order; empty: services run where `host` says
  std::string discovery_server;      ///< the host running `fastdds discovery`, "" = none
  int discovery_port = 11811;        ///< its UDP port
  std::string security;              ///< the lab PKI's directory on the hosts (absolute), "" = none
  LabTracker tracker;                ///< Lab.tracker

  /// The cluster with that name, nullptr if none.
  const LabCluster* cluster(const std::string& name) const;
  /// The service with that name ("ingest", "solver/left", ...), nullptr if none.
  const LabService* service(const std::string& name) const;
  /// The host with that name, nullptr if none.
  const LabHost* host(const std::string& name) const;
};

/// Reads and validates a lab file (throws LabError).
LabConfig loadLab(const std::string& path);

/// Same, from text in memory: `source_name` names it in errors (and becomes LabConfig::file),
/// relative paths are resolved against `base_dir` (itself made absolute against the current
/// directory).
LabConfig parseLab(const std::string& text, const std::string& source_name, const std::string& base_dir);

/// The service name for a kind: "ingest", "scene", "resolver", "solver/<cluster>"; "" for
/// KIND_UNSPECIFIED and unknown kinds.
std::string labServiceName(pb::Service::Kind kind, const std::string& cluster);

/// True if `host` names this machine: "", "localhost", "127.0.0.1", "::1" or gethostname()
/// (case-insensitive).
bool isLocalHost(const std::string& host);

/// `godhand-launch --host NAME`: checks that NAME is one of the lab's hosts (or, in a lab without
/// `hosts`, the host of one of its services) and makes that host's profiles the lab's (when it
/// has its own). Throws LabError "FILE: --host NAME: reason" naming the known hosts.
void selectHost(LabConfig& lab, const std::string& name);

/// Whether godhand-launch starts `s` here: with `host` given (--host), the services whose host
/// is exactly that name; without, those whose host is this machine (LabService::local).
bool runsHere(const LabService& s, const std::string& host);

}  // namespace godhand
