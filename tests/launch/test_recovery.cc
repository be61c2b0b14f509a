// The launch report's restarts (common/recovery.h): each restart gets its own recovery, the time
// from the restart to the first state with every hand's newest state fresh, once the restarted
// process has beaten. Oracle: small histories of two hands worked out by hand.
#include <gtest/gtest.h>

#include "common/recovery.h"

using namespace godhand;

TEST(RecoveryLog, EachRestartHasItsOwnRecovery) {
  RecoveryLog log(2);
  log.state(0, false, 0.5);
  log.state(1, false, 0.5);
  // The solver of hand 0 is killed at 1.0 s: its states go stale, then it is restarted.
  log.state(0, true, 1.1);
  log.state(1, false, 1.1);
  log.restarted("solver-right", 1.5, 101);
  log.state(0, true, 1.6);
  log.state(1, false, 1.6);
  log.heartbeat("solver-right", 101, 1.8);
  log.state(0, false, 2.0);  // every hand fresh again: the solver's recovery
  // Then the scene: both hands stale, restarted at 3.0, beats at 3.1, back at 3.2, fresh at 3.4.
  log.state(0, true, 2.6);
  log.state(1, true, 2.6);
  log.restarted("scene", 3.0, 102);
  log.heartbeat("scene", 102, 3.1);
  log.sceneRunBegan(3.2);
  log.state(0, false, 3.3);
  log.state(1, true, 3.3);  // one hand still stale: not yet
  log.state(1, false, 3.4);

  ASSERT_EQ(log.restarts().size(), 2u);
  const RecoveryLog::Restart& a = log.restarts()[0];
  EXPECT_EQ(a.service, "solver-right");
  EXPECT_DOUBLE_EQ(a.up_s, 1.8);
  EXPECT_DOUBLE_EQ(a.fresh_again_s, 2.0);
  EXPECT_DOUBLE_EQ(a.recoverySeconds(), 0.5);
  EXPECT_EQ(a.stale_states, 1u);  // hand 0's at 1.6 (hand 1's fresh one is not counted)
  EXPECT_LT(a.scene_back_s, 0);   // not the scene
  const RecoveryLog::Restart& b = log.restarts()[1];
  EXPECT_EQ(b.service, "scene");
  EXPECT_DOUBLE_EQ(b.scene_back_s, 3.2);
  EXPECT_DOUBLE_EQ(b.fresh_again_s, 3.4);
  EXPECT_NEAR(b.recoverySeconds(), 0.4, 1e-12);
  EXPECT_EQ(b.stale_states, 1u);  // hand 1's at 3.3
  EXPECT_DOUBLE_EQ(log.staleFirst(), 1.1);
  EXPECT_DOUBLE_EQ(log.staleLast(), 3.3);
  EXPECT_EQ(log.unrecovered(), 0);
}

// Fresh states still in flight from before the kill, read after the restart, prove nothing: a
// restart recovers only with states at or after its own process's first heartbeat. A heartbeat of
// another process of the service (the dead one's, in flight; a later restart's) is not its own.
TEST(RecoveryLog, OnlyTheRestartedProcessesOwnHeartbeatCounts) {
  RecoveryLog log(1);
  log.restarted("resolver", 1.0, 200);
  log.state(0, false, 1.01);             // in flight: fresh, but before the new process beat
  log.heartbeat("resolver", 199, 1.05);  // the dead process's last heartbeat, in flight
  log.state(0, false, 1.1);
  EXPECT_LT(log.restarts()[0].fresh_again_s, 0);
  EXPECT_FALSE(log.restarts()[0].beat);
  // A crash loop: the first restart's process never beats; the second's does.
  log.restarted("resolver", 2.0, 201);
  log.heartbeat("resolver", 201, 2.4);
  log.state(0, false, 2.5);
  EXPECT_FALSE(log.restarts()[0].beat);
  EXPECT_LT(log.restarts()[0].fresh_again_s, 0);
  EXPECT_TRUE(log.restarts()[1].beat);
  EXPECT_DOUBLE_EQ(log.restarts()[1].fresh_again_s, 2.5);
  EXPECT_EQ(log.unrecovered(), 1);
}

// A second restart that never recovers is reported as such (the old report kept only the first
// restart's "resumed" time and showed this run as recovered); the replay's end is kept.
TEST(RecoveryLog, ARestartThatNeverRecoversIsCounted) {
  RecoveryLog log(2);
  log.restarted("solver-left", 1.0, 300);
  log.heartbeat("solver-left", 300, 1.1);
  log.state(0, false, 1.2);
  log.state(1, false, 1.2);  // recovered (hands that never went stale count as fresh)
  log.restarted("resolver", 2.0, 301);
  log.heartbeat("resolver", 301, 2.2);
  log.state(0, true, 2.5);
  log.state(1, true, 2.5);
  log.state(0, false, 3.0);  // hand 1 never fresh again
  log.replayEnded(3.1);
  log.replayEnded(4.0);      // the first end is the end
  EXPECT_DOUBLE_EQ(log.restarts()[0].fresh_again_s, 1.2);
  EXPECT_LT(log.restarts()[1].fresh_again_s, 0);
  EXPECT_LT(log.restarts()[1].recoverySeconds(), 0);
  EXPECT_EQ(log.restarts()[1].stale_states, 2u);
  EXPECT_EQ(log.unrecovered(), 1);
  EXPECT_DOUBLE_EQ(log.replayEnd(), 3.1);
}

// A restart before the replay started (start-up, under --restart; the caller's time is then < 0)
// counts its recovery from the replay's start. States before the replay (t < 0) and of hands
// beyond the lab's are ignored; a scene run that begins belongs to the newest scene restart
// before it, not to a later one.
TEST(RecoveryLog, EdgesOfTheHistory) {
  RecoveryLog log(1);
  log.restarted("ingest", -1.0, 400);
  log.heartbeat("ingest", 400, -1.0);
  log.state(0, true, -1.0);
  log.state(5, true, 1.0);
  log.state(-1, true, 1.0);
  EXPECT_LT(log.staleFirst(), 0);
  log.state(0, false, 0.4);
  EXPECT_DOUBLE_EQ(log.restarts()[0].fresh_again_s, 0.4);
  EXPECT_DOUBLE_EQ(log.restarts()[0].recoverySeconds(), 0.4);
  log.restarted("scene", 2.0, 401);
  log.heartbeat("scene", 401, 2.0);
  log.sceneRunBegan(1.9);  // before the restart: not its run
  EXPECT_LT(log.restarts()[1].scene_back_s, 0);
  log.state(0, false, 2.0);
  EXPECT_DOUBLE_EQ(log.restarts()[1].fresh_again_s, 2.0);
  log.sceneRunBegan(2.1);
  log.restarted("scene", 4.0, 402);
  log.sceneRunBegan(4.5);
  EXPECT_DOUBLE_EQ(log.restarts()[1].scene_back_s, 2.1);
  EXPECT_DOUBLE_EQ(log.restarts()[2].scene_back_s, 4.5);
}

// Bounded: a crash loop for a day keeps the newest restarts, dropping recovered ones first.
TEST(RecoveryLog, ACrashLoopIsBounded) {
  RecoveryLog log(1);
  log.restarted("scene", 0.5, 1);  // never recovers: kept
  for (int k = 0; k < 1000; ++k) {
    log.restarted("resolver", 1.0 + k, 1000 + k);
    log.heartbeat("resolver", 1000 + k, 1.1 + k);
    log.state(0, false, 1.2 + k);
  }
  EXPECT_EQ(log.restarts().size(), RecoveryLog::kMaxRestarts);
  EXPECT_EQ(log.dropped(), 1000u + 1u - RecoveryLog::kMaxRestarts);
  EXPECT_EQ(log.restarts().front().service, "scene");
  EXPECT_EQ(log.restarts().back().pid, 1999);
  EXPECT_EQ(log.unrecovered(), 1);
}
