#include "launch/report.h"

#include "pipeline/run_metrics_json.h"

#include <algorithm>
#include <cstdio>

namespace godhand {

namespace {
std::string secs(double s) {
  if (s < 0) return "never";
  char b[32];
  std::snprintf(b, sizeof b, "%.2f s", s);
  return b;
}
nlohmann::json orNull(double s) { return s < 0 ? nlohmann::json(nullptr) : nlohmann::json(s); }
}  // namespace

nlohmann::json sourceJson(const SourceCounts& c, std::size_t runs) {
  nlohmann::json rejected = nlohmann::json::object(), not_played = nlohmann::json::object();
  for (const auto& [reason, n] : c.rejected) rejected[reason] = n;
  for (const auto& [reason, n] : c.not_played) not_played[reason] = n;
  return {{"received", c.received},
          {"accepted", c.accepted},
          {"rejected", rejected},
          {"rejected_total", c.rejectedTotal()},
          {"not_played", not_played},
          {"not_played_total", c.notPlayedTotal()},
          {"ingest_runs", runs}};
}

namespace {
}  // namespace

const RecoveryLog::Restart* RunReport::restartOf(const std::string& service, double t_s) const {
  for (const RecoveryLog::Restart& x : restarts)
    if (x.service == service && x.restarted && x.restarted_s >= t_s) return &x;
  return nullptr;
}

void printSummary(const RunReport& r) {
  std::printf("launch: %s run of %.1f s: %llu of %llu frames delivered fresh in every cluster%s, %ld hand states received "
              "(%ld of them stale: flagged by the resolver, or older than %.2f s when they arrived)\n",
              r.lockstep ? "lock-step" : "live", r.run_s, static_cast<unsigned long long>(r.frames_complete),
              static_cast<unsigned long long>(r.expected_frames),
              r.ingest_runs > 1 ? (" (" + std::to_string(r.ingest_runs) + " ingest runs)").c_str() : "", r.states, r.stale_states,
              r.stale_after_s);
  for (size_t c = 0; c < r.clusters.size() && c < r.delivery.size(); ++c) {
    const DeliveryCounts& d = r.delivery[c];
    std::printf("  delivery %-8s frames expected %llu, fresh %llu, stale %llu, lost %llu%s\n", r.clusters[c].c_str(),
                static_cast<unsigned long long>(d.expected), static_cast<unsigned long long>(d.fresh),
                static_cast<unsigned long long>(d.stale), static_cast<unsigned long long>(d.lost),
                d.unobserved ? (", not observed " + std::to_string(d.unobserved) + " (published while this launcher did not watch)").c_str()
                             : "");
  }
  if (r.have_source) std::printf("  %s\n", describeSource(r.source, r.source_runs).c_str());
  else std::printf("  source: no counts from the ingest (no heartbeat with its source arrived)\n");
  if (r.old_unmarked > 0)
    std::printf("  WARNING: %ld hand states arrived older than %.2f s without the stale flag (counted stale)\n", r.old_unmarked,
                r.stale_after_s + 0.1);
  if (r.latency_samples > 0)
    std::printf("  end-to-end latency of the fresh hand states (tracker sample -> HandState here): median %.0f us, p99 %.0f us, max %.0f us "
                "over %llu states; %.1f fresh frames/s\n",
                r.latency_median_us, r.latency_p99_us, r.latency_max_us, static_cast<unsigned long long>(r.latency_samples), r.frames_per_s);
  else  // (0 us would read as instant)
    std::printf("  end-to-end latency: none measured (no fresh hand state with a tracker sample time); %.1f fresh frames/s\n",
                r.frames_per_s);
  if (r.stale_age_samples > 0)
    std::printf("  age of the stale hand states (not a latency, not in the figures above): median %.0f us, p99 %.0f us, max %.0f us "
                "over %llu states\n",
                r.stale_age_median_us, r.stale_age_p99_us, r.stale_age_max_us, static_cast<unsigned long long>(r.stale_age_samples));
  if (!r.services.empty())
    std::printf("  per service: its last frame; source->output = tracker sample to the service's output, median "
                "(the scene steps on its own clock, live: up to a frame more); samples in / out (the scene's out: the states it "
                "published, every step with or without new forces); inputs rejected; inputs late for their frame; lock-step "
                "deadlines missed\n");
  for (const auto& [name, s] : r.services)
    std::printf("  %-14s frame %llu, source->output %.0f us, in %llu, out %llu, rejected %llu, late %llu, deadline misses %llu, state %s, %s\n",
                name.c_str(), static_cast<unsigned long long>(s.frame), s.latency_median_us,
                static_cast<unsigned long long>(s.samples_in), static_cast<unsigned long long>(s.samples_out),
                static_cast<unsigned long long>(s.rejected), static_cast<unsigned long long>(s.late),
                static_cast<unsigned long long>(s.deadline_misses), s.state.c_str(), s.health.c_str());
  std::printf("  penetration max %.4f mm (margin %.3f mm), joint gap max %.2e m, free tracking error (no contact loaded) max "
              "%.2f mm, hand states clipped by the sweep %ld, scene push-outs (an object moved out of a God object) %ld\n",
              r.penetration_max_m * 1e3, r.margin_m * 1e3, r.joint_gap_max_m, r.free_err_max_m * 1e3, r.clipped, r.pushouts);
  if (r.have_plausibility)
    for (const HandSummary& h : r.plausibility.hands) std::printf("  %s\n", describe(h).c_str());
  if (r.penetration_max_m > r.margin_m) {
    const RunReport::Worst& w = r.penetration_worst;
    std::printf("  deepest state: hand %ld body %ld in '%s', frame %llu, scene step %llu (%s), %s%s, toc %.3f, at %s\n", w.hand, w.body,
                w.object.c_str(),
                static_cast<unsigned long long>(w.frame), static_cast<unsigned long long>(w.scene_step),
                w.own_scene ? "its own scene state" : "scored against the newest scene state", w.tracked ? "tracked" : "untracked",
                w.stale ? ", stale" : "", w.toc, secs(w.replay_s).c_str());
  }
  if (r.penetration_newest_scene > 0)
    std::printf("  penetration of %ld states scored against the newest scene state (the one they were resolved against was not "
                "kept), %ld against their own\n",
                r.penetration_newest_scene, r.penetration_own_scene);
  if (r.penetration_unscored > 0)
    std::printf("  penetration not scored for %ld states in %zu window(s) while the scene was down (its last poses are old)\n",
                r.penetration_unscored, r.unscored_windows.size());
  for (const Watchdog::Episode& e : r.silent)
    std::printf("  watchdog: %s silent (no heartbeat for > %.1f s) from %s to %s%s\n", e.service.c_str(), r.silent_after_s,
                secs(e.start_s).c_str(), e.end_s < 0 ? "the end" : secs(e.end_s).c_str(),
                e.end_s >= 0 && e.reset ? " (then it was killed or ended: its outage below)" : "");
  if (r.launcher_pause_count > r.launcher_pauses.size())
    std::printf("  this launcher did not watch for more than %.1f s %llu times (the first %zu below): it was starved or stalled\n",
                r.silent_after_s, static_cast<unsigned long long>(r.launcher_pause_count), r.launcher_pauses.size());
  for (const Watchdog::Pause& p : r.launcher_pauses)
    std::printf("  this launcher did not watch for %.1f s from %s (stopped, starved or stalled): not counted against the "
                "services; frames published meanwhile of which no state came are counted as not observed, unless a service "
                "died or froze then (lost)\n",
                p.duration_s, secs(p.start_s).c_str());
  for (const DrillReport& d : r.drills)
    std::printf("  fault drill %s: killed at %s (frame %llu), restarted at %s (times from the replay start)\n", d.spec.c_str(),
                secs(d.killed_s).c_str(), static_cast<unsigned long long>(d.killed_frame), secs(d.restarted_s).c_str());
  if (r.stale_first_s >= 0 && !r.restarts.empty())
    std::printf("  stale states from %s to %s\n", secs(r.stale_first_s).c_str(), secs(r.stale_last_s).c_str());
  for (const RecoveryLog::Restart& x : r.restarts) {
    auto at = [](double t) { return t >= 0 ? "at " + secs(t) : std::string("before the replay started"); };
    std::string line = "  " + x.service;
    if (x.down_known)
      line += x.down_by_s - x.down_s > 0.1 ? " down between " + secs(std::max(x.down_s, 0.0)) + " and " + secs(x.down_by_s) +
                                                 " (seen ended after this launcher's pause)"
                                           : " down " + at(x.down_s);
    if (!x.restarted) {
      std::printf("%s: not restarted by the end\n", line.c_str());
      continue;
    }
    line += (x.down_known ? ", restarted " : " restarted ") + at(x.restarted_s);
    std::string back;
    if (x.service == "scene")
      back = x.scene_back_s >= 0 ? "; its first state " + at(x.scene_back_s) : "; no state of the new scene seen";
    const std::string up = !x.beat ? "no heartbeat of it seen" : "its first heartbeat " + at(x.up_s);
    char b[256];
    if (x.fresh_again_s >= 0) {
      if (x.down_known)
        std::snprintf(b, sizeof b, "%.2f s after it went down, %.2f s after the restart", x.outageSeconds(), x.recoverySeconds());
      else
        std::snprintf(b, sizeof b, "%.2f s after the restart", x.recoverySeconds());
      std::printf("%s: every hand fresh again at %s (%s; %llu stale states meanwhile; %s)%s\n", line.c_str(), secs(x.fresh_again_s).c_str(), b,
                  static_cast<unsigned long long>(x.stale_states), up.c_str(), back.c_str());
    } else if (x.superseded) {
      std::printf("%s: down again before every hand was fresh (the next outage of it goes on; %llu stale states meanwhile; %s)%s\n",
                  line.c_str(), static_cast<unsigned long long>(x.stale_states), up.c_str(), back.c_str());
    } else {
      std::printf("%s: NOT every hand fresh again by the end (%llu stale states since; %s%s)%s\n", line.c_str(),
                  static_cast<unsigned long long>(x.stale_states), up.c_str(),
                  r.replay_end_s >= 0 && r.replay_end_s >= x.restarted_s ? (", the replay ended at " + secs(r.replay_end_s)).c_str() : "",
                  back.c_str());
    }
  }
  if (r.restarts_dropped > 0)
    std::printf("  (%llu older outages that recovered or were superseded are not listed)\n", static_cast<unsigned long long>(r.restarts_dropped));
  if (r.scene_restart_jump_m > 0 || std::any_of(r.restarts.begin(), r.restarts.end(), [](const RecoveryLog::Restart& x) {
        return x.service == "scene" && x.scene_back_s >= 0;
      }))
    std::printf("  restarted scene: objects moved %.3f mm from the dead scene's last poses\n", r.scene_restart_jump_m * 1e3);
  std::printf("  late joiner: %zu of %llu HandStates and the SceneDescription %s%s\n", r.late_states,
              static_cast<unsigned long long>(r.hands), r.late_description ? "received" : "NOT received",
              r.late_ms >= 0 ? (" in " + std::to_string(static_cast<int>(r.late_ms)) + " ms").c_str() : "");
  std::printf("  exit codes at shutdown:%s; shared-memory segments left: %zu%s%s\n", r.exits.c_str(), r.shm_left,
              r.shm_removed ? (" (" + std::to_string(r.shm_removed) + " left by this lab's killed processes, removed)").c_str() : "",
              r.shm_left_other ? ("; " + std::to_string(r.shm_left_other) +
                                  " more unheld since the start that no process of this lab had open (another Fast DDS program on "
                                  "this machine?), not removed").c_str()
                               : "");
  if (!r.foreign.empty()) {
    std::string names;
    for (const std::string& f : r.foreign) names += (names.empty() ? "" : ", ") + f;
    std::printf("  ANOTHER LAB on this DDS domain: %s; its samples were mixed with this run's (give each lab its own domain or --partition)\n",
                names.c_str());
  } else if (!r.partition.empty()) {
    std::printf("  partition '%s': only this launch's services matched\n", r.partition.c_str());
  }
  if (r.have_hash && !r.failed()) std::printf("  result hash %016llx\n", static_cast<unsigned long long>(r.result_hash));
  if (!r.failure.empty()) std::printf("launch: FAILED: %s\n", r.failure.c_str());
}

nlohmann::json reportJson(const RunReport& r) {
  nlohmann::json j;
  j["recording"] = r.recording;
  j["scene"] = r.scene;
  j["frames"] = r.frames_complete;
  j["expected_frames"] = r.expected_frames;
  j["hands"] = r.hands;
  j["triangles"] = r.triangles;
  j["reference_triangles"] = r.reference_triangles;
  j["frame_rate_hz"] = r.frame_rate_hz;
  j["solver"] = r.solver;
  j["physics_hz"] = r.physics_hz;
  j["mode"] = r.mode;
  j["step_us"] = {{"median", r.step_median_us}, {"p99", r.step_p99_us}, {"max", r.step_max_us}};
  j["hz_median"] = r.step_median_us > 0 ? 1e6 / r.step_median_us : 0.0;
  j["held_states"] = r.held_states;
  // Figures of no sample are null, not 0 (which would read as instant).
  auto figure = [](double v, std::uint64_t samples) { return samples > 0 ? nlohmann::json(v) : nlohmann::json(nullptr); };
  j["latency_us"] = {{"median", figure(r.latency_median_us, r.latency_samples)},
                     {"p99", figure(r.latency_p99_us, r.latency_samples)},
                     {"max", figure(r.latency_max_us, r.latency_samples)},
                     {"samples", r.latency_samples}};
  j["stale_state_age_us"] = {{"median", figure(r.stale_age_median_us, r.stale_age_samples)},
                             {"p99", figure(r.stale_age_p99_us, r.stale_age_samples)},
                             {"max", figure(r.stale_age_max_us, r.stale_age_samples)},
                             {"samples", r.stale_age_samples}};
  j["stale_after_s"] = r.stale_after_s;
  j["run_s"] = r.run_s;
  j["frames_per_s"] = r.frames_per_s;
  j["stages_us"] = r.stages_us;
  j["penetration_max_m"] = r.penetration_max_m;
  j["penetration_unscored_states"] = r.penetration_unscored;
  if (r.penetration_max_m > 0) {
    const RunReport::Worst& w = r.penetration_worst;
    j["penetration_worst"] = {{"hand", w.hand}, {"body", w.body}, {"object", w.object}, {"frame", w.frame}, {"scene_step", w.scene_step},
                              {"own_scene_state", w.own_scene}, {"tracked", w.tracked}, {"stale", w.stale}, {"toc", w.toc},
                              {"replay_s", orNull(w.replay_s)}};
  }
  j["penetration_own_scene_states"] = r.penetration_own_scene;
  j["penetration_newest_scene_states"] = r.penetration_newest_scene;
  nlohmann::json w = nlohmann::json::array();
  for (const auto& [a, b] : r.unscored_windows) w.push_back({{"from_s", orNull(a)}, {"to_s", orNull(b)}});
  j["penetration_unscored_windows"] = w;
  j["margin_m"] = r.margin_m;
  j["joint_gap_max_m"] = r.joint_gap_max_m;
  j["free_tracking_error_max_m"] = r.free_err_max_m;
  j["free_tracking_error_median_m"] = r.free_err_median_m;
  if (r.have_plausibility) {
    j["plausibility"] = toJson(r.plausibility);
    j["excess_lag_m"] = toJson(r.plausibility.all.excess_lag_m);
    j["frozen_windows"] = r.plausibility.all.frozen_windows;
    j["moving_windows"] = r.plausibility.all.moving_windows;
    j["stuck_frames"] = r.plausibility.all.stuck_frames;
    j["jitter_body_frames"] = r.plausibility.all.jitter_body_frames;
    j["jitter_checked"] = r.plausibility.all.jitter_checked;
    j["twin_jitter_body_frames"] = r.plausibility.all.twin_jitter_body_frames;
  }
  j["contacts_max"] = r.contacts_max;
  j["kkt_residual_max"] = r.kkt_max;
  j["solver_failures"] = r.solver_failures;
  j["inexact_solves"] = r.inexact;
  j["clipped_steps"] = r.clipped;
  j["lifted_starts"] = r.lifted;
  j["started_inside"] = r.inside;
  j["scene_pushouts"] = r.pushouts;
  j["hand_states"] = r.states;
  j["stale_states"] = r.stale_states;
  j["old_unmarked_states"] = r.old_unmarked;
  j["ingest_runs"] = r.ingest_runs;
  j["source"] = r.have_source ? sourceJson(r.source, r.source_runs) : nlohmann::json(nullptr);
  nlohmann::json delivery = nlohmann::json::object();
  for (size_t c = 0; c < r.clusters.size() && c < r.delivery.size(); ++c)
    delivery[r.clusters[c]] = {{"expected", r.delivery[c].expected}, {"fresh", r.delivery[c].fresh},
                               {"stale", r.delivery[c].stale}, {"lost", r.delivery[c].lost},
                               {"unobserved", r.delivery[c].unobserved}};
  j["delivery"] = delivery;
  nlohmann::json services = nlohmann::json::object();
  for (const auto& [name, s] : r.services)
    services[name] = {{"frame", s.frame}, {"samples_in", s.samples_in}, {"samples_out", s.samples_out}, {"rejected", s.rejected},
                      {"late", s.late}, {"deadline_misses", s.deadline_misses}, {"state", s.state}, {"health", s.health}};
  j["services"] = services;
  nlohmann::json silent = nlohmann::json::array();
  for (const Watchdog::Episode& e : r.silent)
    silent.push_back({{"service", e.service}, {"from_s", orNull(e.start_s)}, {"to_s", orNull(e.end_s)}, {"ended_by_kill_or_exit", e.reset}});
  nlohmann::json pauses = nlohmann::json::array();
  for (const Watchdog::Pause& p : r.launcher_pauses) pauses.push_back({{"from_s", p.start_s}, {"duration_s", p.duration_s}});
  j["watchdog"] = {{"silent_after_s", r.silent_after_s}, {"silent", silent}, {"restarted", r.watchdog_restarts},
                   {"launcher_pauses", pauses}, {"launcher_pause_count", r.launcher_pause_count}};
  j["late_joiner"] = {{"hand_states", r.late_states}, {"scene_description", r.late_description}, {"ms", orNull(r.late_ms)}};
  j["shm_segments_left"] = r.shm_left;
  j["shm_segments_left_other"] = r.shm_left_other;
  j["shm_segments_removed"] = r.shm_removed;
  j["clean_shutdown"] = r.clean_shutdown;
  j["dead_at_end"] = r.dead_at_end;
  j["foreign_services"] = r.foreign;
  j["partition"] = r.partition;
  if (!r.drills.empty()) {
    nlohmann::json drills = nlohmann::json::array();
    for (const DrillReport& d : r.drills)
      drills.push_back({{"spec", d.spec}, {"service", d.service}, {"killed_s", orNull(d.killed_s)}, {"killed_frame", d.killed_frame},
                        {"restarted_s", orNull(d.restarted_s)}});
    j["fault_drills"] = drills;
    // The first drill with the run's stale window and its own restart's recovery (times from the
    // replay start; every restart is in "restarts").
    const DrillReport& d = r.drills.front();
    const RecoveryLog::Restart* x = d.killed_s >= 0 ? r.restartOf(d.service, d.killed_s) : nullptr;
    const double resumed = x ? x->fresh_again_s : -1, back = x ? x->scene_back_s : -1;
    j["fault_drill"] = {{"service", d.service}, {"killed_s", orNull(d.killed_s)}, {"restarted_s", orNull(d.restarted_s)},
                        {"stale_first_s", orNull(r.stale_first_s)}, {"stale_last_s", orNull(r.stale_last_s)},
                        {"resumed_s", orNull(resumed)}, {"scene_back_s", orNull(back)},
                        {"scene_restart_jump_m", r.scene_restart_jump_m},
                        {"resume_after_restart_s", x && x->fresh_again_s >= 0 ? orNull(x->recoverySeconds()) : nullptr}};
  }
  nlohmann::json restarts = nlohmann::json::array();
  for (const RecoveryLog::Restart& x : r.restarts)
    restarts.push_back({{"service", x.service}, {"down_s", x.down_known ? nlohmann::json(std::max(x.down_s, 0.0)) : nlohmann::json(nullptr)},
                        {"down_by_s", x.down_known ? nlohmann::json(std::max(x.down_by_s, 0.0)) : nlohmann::json(nullptr)},
                        {"restarted", x.restarted}, {"superseded", x.superseded}, {"outage_s", orNull(x.outageSeconds())},
                        {"restarted_s", x.restarted ? orNull(x.restarted_s) : nullptr}, {"fresh_again_s", orNull(x.fresh_again_s)},
                        {"recovery_s", orNull(x.recoverySeconds())}, {"stale_states", x.stale_states},
                        {"up_s", x.beat ? nlohmann::json(std::max(x.up_s, 0.0)) : nlohmann::json(nullptr)},
                        {"scene_back_s", orNull(x.scene_back_s)}});
  j["restarts"] = restarts;
  j["restarts_dropped"] = r.restarts_dropped;
  j["restarts_unrecovered"] = std::count_if(r.restarts.begin(), r.restarts.end(),
                                            [](const RecoveryLog::Restart& x) { return x.fresh_again_s < 0 && !x.superseded; });
  if (r.have_hash && !r.failed()) {
    char hex[32];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(r.result_hash));
    j["result_hash"] = hex;
  }
  j["failure"] = r.failure;
  if (r.checked) j["check"] = {{"ok", r.verdict.ok}, {"reasons", r.verdict.reasons}, {"loss_budget", r.loss_budget}};
  return j;
}

}  // namespace godhand
