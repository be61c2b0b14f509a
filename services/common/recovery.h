// What the launcher saw of each restart of a service (a fault drill's, the watchdog's, or after
// an unexpected exit), for the launch report: when it was restarted, when every hand's newest
// state was fresh again after it, and for a restarted scene, its new run's first state. Before
// this log the report kept one "resumed" time: a lab whose solver and then scene were killed
// showed only the first recovery, and a second restart that never recovered went unseen.
//
// Times are seconds since the replay started (the caller's clock, every call takes it; a restart
// before the replay started has a time < 0 and counts from the replay's start). A hand state is
// "fresh" unless stale (flagged by the resolver or too old here); a restart has recovered at the
// first state with every hand's newest state fresh that came at or after the restarted process's
// first heartbeat (its own pid: states still in flight from before the kill prove nothing; a
// process that never beats never recovers). Hands that have not sent a state yet count as fresh
// (a hand never tracked is not waiting on a restart). States before the replay started (t < 0)
// are not counted.
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
    double restarted_s = -1;
    double fresh_again_s = -1;  ///< first state with every hand fresh at or after the restart; < 0: not by the end
    double scene_back_s = -1;   ///< a restarted scene: its new run's first state; < 0: none seen (or not the scene)
    bool beat = false;          ///< a heartbeat of the restarted process came
    double up_s = -1;           ///< when (< 0: before the replay started)
    long pid = -1;              ///< the restarted process
    std::uint64_t stale_states = 0;  ///< stale states received between the restart and fresh_again_s
    /// Seconds from the restart (or the replay's start, if later) to every hand fresh again; < 0
    /// when it never was.
    double recoverySeconds() const { return fresh_again_s >= 0 ? fresh_again_s - (restarted_s > 0 ? restarted_s : 0.0) : -1; }
  };

  explicit RecoveryLog(int hands);

  /// `service` was started again at t_s, as process `pid`.
  void restarted(const std::string& service, double t_s, long pid);
  /// A HandState of `hand` arrived at t_s (stale or fresh).
  void state(int hand, bool stale, double t_s);
  /// A SceneState of a new scene run (its step went back) arrived at t_s.
  void sceneRunBegan(double t_s);
  /// A heartbeat of `service`'s process `pid` arrived at t_s.
  void heartbeat(const std::string& service, long pid, double t_s);
  /// The replay ended at t_s (the ingest is done): a restart not recovered by then had no more
  /// frames to recover with, which the report says.
  void replayEnded(double t_s);
  double replayEnd() const { return replay_end_s_; }

  /// The restarts, the newest kMaxRestarts of them (older ones that recovered dropped first).
  const std::vector<Restart>& restarts() const { return restarts_; }
  std::uint64_t dropped() const { return dropped_; }
  static constexpr std::size_t kMaxRestarts = 256;
  /// The first and the last stale state of the run (t_s; < 0: none).
  double staleFirst() const { return stale_first_s_; }
  double staleLast() const { return stale_last_s_; }
  /// Restarts that had not recovered by now (every hand fresh again).
  int unrecovered() const;

 private:
  std::vector<unsigned char> stale_;  // per hand: its newest state was stale
  std::vector<Restart> restarts_;
  double stale_first_s_ = -1, stale_last_s_ = -1, replay_end_s_ = -1;
  std::uint64_t dropped_ = 0;
};

}  // namespace godhand
