// The launch report's outages and restarts (common/recovery.h): each gets its own recovery, the
// first state by which every hand has had a fresh state since the restarted process first beat.
// Oracle: small histories of two hands worked out by hand.
#include <gtest/gtest.h>

#include "common/recovery.h"

using namespace godhand;

TEST(RecoveryLog, EachOutageHasItsOwnRecovery) {
  RecoveryLog log(2);
  log.state(0, false, 0.5);
  log.state(1, false, 0.5);
  // The solver of hand 0 is killed at 1.0 s: its states go stale, then it is restarted.
  log.down("solver-right", 1.0, 1.0);
  log.state(0, true, 1.1);
  log.state(1, false, 1.1);
  log.restarted("solver-right", 1.5, 101);
  log.state(0, true, 1.6);
  log.state(1, false, 1.6);
  log.heartbeat("solver-right", 101, 1.8);
  log.state(0, false, 2.0);  // hand 0 fresh; hand 1 has had no state since the heartbeat: not yet
  log.state(1, false, 2.0);  // every hand fresh again: the solver's recovery
  // Then the scene: both hands stale, killed at 2.5, restarted at 3.0, beats at 3.1, back at 3.2.
  log.down("scene", 2.5, 2.5);
  log.down("scene", 2.5, 2.55);  // (then seen ended: the same outage)
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
  EXPECT_DOUBLE_EQ(a.down_s, 1.0);
  EXPECT_DOUBLE_EQ(a.up_s, 1.8);
  EXPECT_DOUBLE_EQ(a.fresh_again_s, 2.0);
  EXPECT_DOUBLE_EQ(a.recoverySeconds(), 0.5);
  EXPECT_DOUBLE_EQ(a.outageSeconds(), 1.0);
  EXPECT_EQ(a.stale_states, 2u);  // hand 0's at 1.1 and 1.6 (hand 1's fresh ones are not counted)
  EXPECT_LT(a.scene_back_s, 0);   // not the scene
  const RecoveryLog::Restart& b = log.restarts()[1];
  EXPECT_EQ(b.service, "scene");
  EXPECT_DOUBLE_EQ(b.down_s, 2.5);
  EXPECT_DOUBLE_EQ(b.scene_back_s, 3.2);
  EXPECT_DOUBLE_EQ(b.fresh_again_s, 3.4);
  EXPECT_NEAR(b.recoverySeconds(), 0.4, 1e-12);
  EXPECT_EQ(b.stale_states, 3u);  // both hands' at 2.6, hand 1's at 3.3
  EXPECT_DOUBLE_EQ(log.staleFirst(), 1.1);
  EXPECT_DOUBLE_EQ(log.staleLast(), 3.3);
  EXPECT_EQ(log.unrecovered(), 0);
}

// A death the launcher saw only after its own pause: it went down some time in the pause, the
// outage runs from the earliest it can have (its stale states counted from there).
TEST(RecoveryLog, ADeathInsideAPauseIsAnInterval) {
  RecoveryLog log(1);
  log.state(0, false, 3.9);
  log.down("resolver", 4.0, 6.5);
  log.down("resolver", 6.5, 6.5);  // (the same outage)
  log.state(0, true, 6.6);
  log.restarted("resolver", 6.8, 9);
  log.heartbeat("resolver", 9, 7.1);
  log.state(0, false, 7.5);
  ASSERT_EQ(log.restarts().size(), 1u);
  EXPECT_DOUBLE_EQ(log.restarts()[0].down_s, 4.0);
  EXPECT_DOUBLE_EQ(log.restarts()[0].down_by_s, 6.5);
  EXPECT_DOUBLE_EQ(log.restarts()[0].outageSeconds(), 3.5);
  EXPECT_EQ(log.restarts()[0].stale_states, 1u);
}

// Seen in a soak: the resolver restarted, hand 0's first new state fresh, hand 1's still stale and
// held for two frames. Each hand's newest state before the restart was fresh, which must not count.
TEST(RecoveryLog, EveryHandNeedsAFreshStateOfItsOwnAfterTheRestart) {
  RecoveryLog log(2);
  log.state(0, false, 9.0);
  log.state(1, false, 9.0);
  log.down("resolver", 9.0, 9.0);
  log.restarted("resolver", 9.36, 7);
  log.heartbeat("resolver", 7, 9.69);
  log.state(0, false, 9.86);
  EXPECT_LT(log.restarts()[0].fresh_again_s, 0);
  log.state(1, true, 9.86);
  log.state(1, true, 9.95);
  log.state(0, false, 9.95);
  log.state(1, false, 10.06);
  EXPECT_DOUBLE_EQ(log.restarts()[0].fresh_again_s, 10.06);
  EXPECT_NEAR(log.restarts()[0].recoverySeconds(), 0.70, 1e-12);
  EXPECT_EQ(log.restarts()[0].stale_states, 2u);
}

// Fresh states still in flight from before the kill, read after the restart, prove nothing: a
// restart recovers only with states at or after its own process's first heartbeat. A heartbeat of
// another process of the service (the dead one's, in flight; a later restart's) is not its own.
// A service that goes down again before it recovered: that outage is superseded, not unrecovered.
TEST(RecoveryLog, OnlyTheRestartedProcessesOwnHeartbeatCounts) {
  RecoveryLog log(1);
  log.restarted("resolver", 1.0, 200);   // (no down() first: its outage starts at the restart)
  log.state(0, false, 1.01);             // in flight: fresh, but before the new process beat
  log.heartbeat("resolver", 199, 1.05);  // the dead process's last heartbeat, in flight
  log.state(0, false, 1.1);
  EXPECT_LT(log.restarts()[0].fresh_again_s, 0);
  EXPECT_FALSE(log.restarts()[0].beat);
  EXPECT_LT(log.restarts()[0].outageSeconds(), 0);  // down time not known
  // A crash loop: the first restart's process never beats and dies; the second's beats.
  log.down("resolver", 1.9, 1.9);
  log.restarted("resolver", 2.0, 201);
  log.heartbeat("resolver", 201, 2.4);
  log.state(0, false, 2.5);
  EXPECT_TRUE(log.restarts()[0].superseded);
  EXPECT_FALSE(log.restarts()[0].beat);
  EXPECT_TRUE(log.restarts()[1].beat);
  EXPECT_DOUBLE_EQ(log.restarts()[1].fresh_again_s, 2.5);
  EXPECT_EQ(log.unrecovered(), 0);
  // Down and never restarted: unrecovered.
  log.down("scene", 3.0, 3.0);
  EXPECT_FALSE(log.restarts()[2].restarted);
  EXPECT_EQ(log.unrecovered(), 1);
}

// A restart that never recovers is reported as such (the old report kept only the first restart's
// "resumed" time and showed this run as recovered); states after the replay's end do not count.
TEST(RecoveryLog, ARestartThatNeverRecoversIsCounted) {
  RecoveryLog log(2);
  log.state(0, false, 0.5);
  log.state(1, false, 0.5);
  log.restarted("solver-left", 1.0, 300);
  log.heartbeat("solver-left", 300, 1.1);
  log.state(0, false, 1.2);
  log.state(1, false, 1.2);
  log.restarted("resolver", 2.0, 301);
  log.heartbeat("resolver", 301, 2.2);
  log.state(0, true, 2.5);
  log.state(1, true, 2.5);
  log.state(0, false, 3.0);  // hand 1 never fresh again before the end
  log.replayEnded(3.1);
  log.replayEnded(4.0);      // the first end is the end
  log.state(1, false, 3.5);  // after the end (a held state re-sent): not counted
  EXPECT_DOUBLE_EQ(log.restarts()[0].fresh_again_s, 1.2);
  EXPECT_LT(log.restarts()[1].fresh_again_s, 0);
  EXPECT_LT(log.restarts()[1].recoverySeconds(), 0);
  EXPECT_EQ(log.restarts()[1].stale_states, 2u);
  EXPECT_EQ(log.unrecovered(), 1);
  EXPECT_DOUBLE_EQ(log.replayEnd(), 3.1);
  EXPECT_DOUBLE_EQ(log.staleLast(), 2.5);
}

// A restart before the replay started (start-up, under --restart; the caller's time is then < 0)
// counts its recovery from the replay's start. States before the replay (t < 0) and of hands
// beyond the lab's are ignored; hands that sent no state at all are excused; a scene run that
// begins belongs to the newest scene restart before it, not to a later one.
TEST(RecoveryLog, EdgesOfTheHistory) {
  RecoveryLog log(2);
  log.restarted("ingest", -1.0, 400);
  log.heartbeat("ingest", 400, -1.0);
  log.state(0, true, -1.0);
  log.state(5, true, 1.0);
  log.state(-1, true, 1.0);
  EXPECT_LT(log.staleFirst(), 0);
  log.state(0, false, 0.4);  // hand 1 never sent a state: excused
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

// Bounded: a crash loop for a day keeps the newest outages, dropping finished ones first.
TEST(RecoveryLog, ACrashLoopIsBounded) {
  RecoveryLog log(1);
  log.restarted("scene", 0.5, 1);  // never beats, never recovers: kept
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
