// What the launcher saw of each restart of a service (a fault drill's, the watchdog's, or after
// an unexpected exit), for the launch report: when it was restarted, when every hand's newest
// state was fresh again after it, and for a restarted scene, its new run's first state. Before
// this log the report kept one "resumed" time: a lab whose solver and then scene were killed
// showed only the first recovery, and a second restart that never recovered went unseen.
//
// Times are seconds since the replay started (the caller's clock, every call takes it). A hand
// state is "fresh" unless stale (flagged by the resolver or too old here); a restart has
// recovered at the first state, at or after it, with every hand's newest state fresh (hands that
// have not sent a state yet count as fresh: a hand never tracked is not waiting on a restart).
// States before the replay started (t < 0) and of frame 0 (start-up) are not counted.
#pragma once

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
    double up_s = -1;           ///< the restarted service's first heartbeat; < 0: none seen
    std::uint64_t stale_states = 0;  ///< stale states between the restart and fresh_again_s
    /// Seconds from the restart to every hand fresh again; < 0 when it never was.
    double recoverySeconds() const { return fresh_again_s >= 0 ? fresh_again_s - restarted_s : -1; }
  };

  explicit RecoveryLog(int hands);

  /// `service` was started again at t_s.
  void restarted(const std::string& service, double t_s);
  /// A HandState of `hand` arrived at t_s (stale or fresh).
  void state(int hand, bool stale, double t_s);
  /// A SceneState of a new scene run (its step went back) arrived at t_s.
  void sceneRunBegan(double t_s);
  /// A heartbeat of `service` arrived at t_s.
  void heartbeat(const std::string& service, double t_s);
  /// The replay ended at t_s (the ingest is done): a restart not recovered by then had no more
  /// frames to recover with, which the report says.
  void replayEnded(double t_s);
  double replayEnd() const { return replay_end_s_; }

  const std::vector<Restart>& restarts() const { return restarts_; }
  /// The first and the last stale state of the run (t_s; < 0: none).
  double staleFirst() const { return stale_first_s_; }
  double staleLast() const { return stale_last_s_; }
  /// Restarts that had not recovered by now (every hand fresh again).
  int unrecovered() const;

 private:
  std::vector<unsigned char> stale_;  // per hand: its newest state was stale
  std::vector<Restart> restarts_;
  double stale_first_s_ = -1, stale_last_s_ = -1, replay_end_s_ = -1;
};

}  // namespace godhand
