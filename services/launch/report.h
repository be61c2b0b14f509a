// godhand-launch's report: every figure of a run in one struct (RunReport), printed as the
// summary (printSummary) and written as JSON (reportJson: godhand-bench's format plus the
// distributed figures). Nothing here measures; main.cc fills the struct. A further block of
// figures goes in as a field here plus its lines in report.cc.
//
// Honesty rules kept here: "N of M frames" are counts (delivery, per cluster), never the highest
// frame number; frames/s comes from counts; a time that never happened is printed "never" and
// written null (never -1); a failed run (failure, or a failed --check) has no result_hash.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/delivery.h"
#include "common/recovery.h"
#include "common/source_counts.h"
#include "common/watchdog.h"
#include "pipeline/run_metrics.h"

namespace godhand {

struct ServiceFigures {
  std::uint64_t frame = 0, samples_in = 0, samples_out = 0, rejected = 0, late = 0, deadline_misses = 0;
  double latency_median_us = 0, rate_hz = 0;
  std::string state;        ///< its last heartbeat's
  std::string health;       ///< the watchdog's at the end: "alive", "silent", "unknown", "not running"
};

struct DrillReport {
  std::string spec, service;
  double killed_s = -1, restarted_s = -1;  ///< seconds after the replay started; < 0: never
  std::uint64_t killed_frame = 0;          ///< newest replay frame when it fired
};

struct RunReport {
  // What ran.
  std::string recording, scene, solver, mode;
  std::uint64_t hands = 0;
  long long triangles = 0, reference_triangles = 0;
  double frame_rate_hz = 0;
  int physics_hz = 0;
  bool lockstep = false;
  double run_s = 0;

  // Delivery (per cluster, in the lab's order) and the frames complete in every cluster.
  std::vector<std::string> clusters;
  std::vector<DeliveryCounts> delivery;
  std::uint64_t frames_complete = 0;    ///< lock-step: frames with every cluster's state; live: min fresh over clusters
  std::uint64_t expected_frames = 0;    ///< per cluster
  std::uint64_t ingest_runs = 0;
  /// The tracker source's counts from the ingest's heartbeats (ServiceStatus.source), summed over
  /// the ingest runs that sent any (source_runs); have_source false: none came (written null).
  bool have_source = false;
  SourceCounts source;
  std::size_t source_runs = 0;
  double replay_span_s = 0;             ///< first to last fresh HandState received
  double frames_per_s = 0;              ///< fresh frames (min over clusters) / replay_span_s
  long states = 0, stale_states = 0, held_states = 0;
  long old_unmarked = 0;                ///< received older than the stale limit + 0.1 s but not flagged stale (the resolver's miss)
  double stale_after_s = 0;

  // Latency and compute.
  /// Fresh states only (common/latency_figures.h): a stale state's age is not a latency.
  double latency_median_us = 0, latency_p99_us = 0, latency_max_us = 0;
  std::uint64_t latency_samples = 0;
  /// The stale states' ages (tracker sample to arrival here), apart; samples: those with a measured age.
  double stale_age_median_us = 0, stale_age_p99_us = 0, stale_age_max_us = 0;
  std::uint64_t stale_age_samples = 0;
  double step_median_us = 0, step_p99_us = 0, step_max_us = 0;
  std::map<std::string, double> stages_us;

  // Contact figures.
  double penetration_max_m = 0, margin_m = 0, joint_gap_max_m = 0, free_err_max_m = 0, free_err_median_m = 0, kkt_max = 0;
  long contacts_max = 0, solver_failures = 0, inexact = 0, clipped = 0, lifted = 0, inside = 0, pushouts = 0;
  long penetration_unscored = 0;        ///< states not scored: the scene was dead (its poses are old)
  /// Live: states scored against the scene state they were resolved against (its step was still
  /// in the launcher's history) / against the newest scene state instead (their own was gone).
  long penetration_own_scene = 0, penetration_newest_scene = 0;
  std::vector<std::pair<double, double>> unscored_windows;  ///< seconds after the replay start
  /// The state that scored penetration_max_m (when > 0): where to look.
  struct Worst {
    long hand = -1, body = -1;
    std::string object;  ///< the scene object it was inside
    std::uint64_t frame = 0, scene_step = 0;
    bool own_scene = false, tracked = false, stale = false;
    double toc = 1, replay_s = -1;
  } penetration_worst;

  // Plausibility (core/pipeline/run_metrics.h: the same figures as godhand-bench's).
  RunSummary plausibility;
  bool have_plausibility = false;

  // Services, liveness, drills.
  std::map<std::string, ServiceFigures> services;
  std::vector<Watchdog::Episode> silent;  ///< watchdog episodes (seconds since the replay start)
  double silent_after_s = 0;
  std::vector<std::string> watchdog_restarts;
  std::vector<Watchdog::Pause> launcher_pauses;  ///< this launcher's own stalls (seconds since the replay start), the first 32
  std::uint64_t launcher_pause_count = 0;        ///< all of them
  std::vector<DrillReport> drills;
  double stale_first_s = -1, stale_last_s = -1;  ///< the run's first and last stale state
  std::vector<RecoveryLog::Restart> restarts;      ///< every restart, with when every hand was fresh again
  double replay_end_s = -1;                        ///< when the ingest was done (live)
  std::uint64_t restarts_dropped = 0;              ///< restarts beyond RecoveryLog::kMaxRestarts (recovered ones)
  /// The first restart of `service` at or after t_s (a drill's kill), or nullptr.
  const RecoveryLog::Restart* restartOf(const std::string& service, double t_s) const;
  double scene_restart_jump_m = 0;   ///< largest displacement of an object at rest in both a dead scene's last state and its successor's first seen

  // End of the run.
  std::size_t late_states = 0;
  bool late_description = false;
  double late_ms = -1;
  std::string exits;
  bool clean_shutdown = false;
  std::size_t shm_left = 0, shm_removed = 0;
  std::size_t shm_left_other = 0;  ///< new unheld entries that no process of this lab was seen holding
  std::vector<std::string> dead_at_end;
  std::vector<std::string> foreign;     ///< services of another lab seen on this domain
  std::string partition;                ///< --partition ("" = none)

  // Verdict.
  std::string failure;
  bool checked = false;
  double loss_budget = 0;
  RunVerdict verdict;
  bool have_hash = false;
  std::uint64_t result_hash = 0;
  /// The run failed (a failure, or --check failed): no result hash is printed or written.
  bool failed() const { return !failure.empty() || (checked && !verdict.ok); }
};

void printSummary(const RunReport& r);
nlohmann::json reportJson(const RunReport& r);
/// The report's `source` block: {received, accepted, rejected: {REASON: n}, rejected_total,
/// not_played: {REASON: n}, not_played_total, ingest_runs (the runs summed)}.
nlohmann::json sourceJson(const SourceCounts& c, std::size_t runs);

}  // namespace godhand
