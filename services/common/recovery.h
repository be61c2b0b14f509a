// What the launcher saw of each outage of a service and its restart (a fault drill's kill, the
// watchdog's, an unexpected exit), for the launch report: when the service went down (killed, or
// seen ended), when it was restarted, the restarted process's first heartbeat, when every hand was
// fresh again, the stale states meanwhile and, for a restarted scene, its new run's first state.
// Before this log the report kept one "resumed" time: a lab whose solver and then scene were
// killed showed only the first recovery, and a second restart that never recovered went unseen.
//
// Times are seconds since the replay started (the caller's clock, every call takes it; times
// before the replay started are < 0 and count from the replay's start). A hand state is "fresh"
// unless stale (flagged by the resolver or too old here). An outage has recovered at the first
// state by which every hand has had a fresh state at or after the restarted process's first
// heartbeat (its own pid: states in flight from before the kill, or another hand's fresh state,
// prove nothing; a process that never beats never recovers). Hands that sent no state at all in
// the run are excused (a hand never tracked is not waiting on a restart). An outage of a service
// that goes down again before it recovered is superseded by the next one, not unrecovered. States
// before the replay started (t < 0) and after it ended are not counted.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace godhand {

class RecoveryLog {
 public:
  struct Restart {
    std::string service;
    double down_s = -1;         ///< when it went down: the earliest it can have (killed by the launcher, its last
                                ///< heartbeat, or the launcher's last look before it was seen ended)
    double down_by_s = -1;      ///< and the latest (= down_s when known exactly: a kill)
    bool down_known = false;
    double restarted_s = -1;
    bool restarted = false;     ///< started again (else still down)
    bool beat = false;          ///< a heartbeat of the restarted process came
    double up_s = -1;           ///< when
    long pid = -1;              ///< the restarted process
    double fresh_again_s = -1;  ///< when every hand was fresh again (see above); < 0: not by the end
    double scene_back_s = -1;   ///< a restarted scene: its new run's first state; < 0: none seen (or not the scene)
    bool superseded = false;    ///< it went down again before it recovered (the next outage goes on)
    std::uint64_t stale_states = 0;  ///< stale states received from the outage's start to fresh_again_s
    /// Seconds from the restart (or the replay's start, if later) to every hand fresh again; < 0
    /// when it never was.
    double recoverySeconds() const { return fresh_again_s >= 0 ? fresh_again_s - (restarted_s > 0 ? restarted_s : 0.0) : -1; }
    /// Seconds from the service going down (the earliest it can have) to every hand fresh again; < 0
    /// when not known or never fresh again.
    double outageSeconds() const { return fresh_again_s >= 0 && down_known ? fresh_again_s - (down_s > 0 ? down_s : 0.0) : -1; }
    std::vector<signed char> hand;  ///< per hand since the first heartbeat: −1 no state, 0 newest stale, 1 newest fresh
  };

  explicit RecoveryLog(int hands);

  /// `service` went down some time in [from_s, by_s] (the launcher killed it: from = by; or saw it
  /// end, after its pause perhaps); a second call before its restart is the same outage.
  void down(const std::string& service, double from_s, double by_s);
  /// `service` was started again at t_s, as process `pid` (a restart without a down() first starts
  /// its own outage there).
  void restarted(const std::string& service, double t_s, long pid);
  /// A HandState of `hand` arrived at t_s (stale or fresh).
  void state(int hand, bool stale, double t_s);
  /// A SceneState of a new scene run (its step went back) arrived at t_s.
  void sceneRunBegan(double t_s);
  /// A heartbeat of `service`'s process `pid` arrived at t_s.
  void heartbeat(const std::string& service, long pid, double t_s);
  /// The replay ended at t_s (the ingest is done): later states are not counted, and an outage not
  /// recovered by then had no more frames to recover with, which the report says.
  void replayEnded(double t_s);
  double replayEnd() const { return replay_end_s_; }

  /// The outages, the newest kMaxRestarts of them (older recovered or superseded ones dropped first).
  const std::vector<Restart>& restarts() const { return restarts_; }
  std::uint64_t dropped() const { return dropped_; }
  static constexpr std::size_t kMaxRestarts = 256;
  /// The first and the last stale state of the replay (t_s; < 0: none).
  double staleFirst() const { return stale_first_s_; }
  double staleLast() const { return stale_last_s_; }
  /// Outages that had not recovered by the end (and were not superseded).
  int unrecovered() const;

 private:
  Restart& open(const std::string& service);  // a new outage entry (bounded)
  std::vector<unsigned char> ever_;  // per hand: a state of it came in the run
  std::vector<Restart> restarts_;
  double stale_first_s_ = -1, stale_last_s_ = -1, replay_end_s_ = -1;
  std::uint64_t dropped_ = 0;
};

}  // namespace godhand
