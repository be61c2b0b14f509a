// The launch report's restarts (common/recovery.h): each restart gets its own recovery, the time
// from the restart to the first state with every hand's newest state fresh. Oracle: small
// histories of two hands worked out by hand.
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
  log.restarted("solver-right", 1.5);
  log.state(0, true, 1.6);
  log.state(1, false, 1.6);
  log.state(0, false, 2.0);  // every hand fresh again: the solver's recovery
  // Then the scene: both hands stale, restarted at 3.0, back at 3.2, fresh at 3.4.
  log.state(0, true, 2.6);
  log.state(1, true, 2.6);
  log.restarted("scene", 3.0);
  log.sceneRunBegan(3.2);
  log.state(0, false, 3.3);
  log.state(1, true, 3.3);  // one hand still stale: not yet
  log.state(1, false, 3.4);

  ASSERT_EQ(log.restarts().size(), 2u);
  const RecoveryLog::Restart& a = log.restarts()[0];
  EXPECT_EQ(a.service, "solver-right");
  EXPECT_DOUBLE_EQ(a.fresh_again_s, 2.0);
  EXPECT_DOUBLE_EQ(a.recoverySeconds(), 0.5);
  EXPECT_EQ(a.stale_states, 2u);  // the two states at 1.6 (hand 0 stale: not every hand fresh)
  EXPECT_LT(a.scene_back_s, 0);   // not the scene
  const RecoveryLog::Restart& b = log.restarts()[1];
  EXPECT_EQ(b.service, "scene");
  EXPECT_DOUBLE_EQ(b.scene_back_s, 3.2);
  EXPECT_DOUBLE_EQ(b.fresh_again_s, 3.4);
  EXPECT_NEAR(b.recoverySeconds(), 0.4, 1e-12);
  EXPECT_EQ(b.stale_states, 2u);
  EXPECT_DOUBLE_EQ(log.staleFirst(), 1.1);
  EXPECT_DOUBLE_EQ(log.staleLast(), 3.3);
  EXPECT_EQ(log.unrecovered(), 0);
}

// A second restart that never recovers is reported as such (the old report kept only the first
// restart's "resumed" time and showed this run as recovered).
TEST(RecoveryLog, ARestartThatNeverRecoversIsCounted) {
  RecoveryLog log(2);
  log.restarted("solver-left", 1.0);
  log.state(0, false, 1.2);
  log.state(1, false, 1.2);  // recovered (hands that never went stale count as fresh)
  log.restarted("resolver", 2.0);
  log.state(0, true, 2.5);
  log.state(1, true, 2.5);
  log.state(0, false, 3.0);  // hand 1 never fresh again
  EXPECT_DOUBLE_EQ(log.restarts()[0].fresh_again_s, 1.2);
  EXPECT_LT(log.restarts()[1].fresh_again_s, 0);
  EXPECT_LT(log.restarts()[1].recoverySeconds(), 0);
  EXPECT_EQ(log.restarts()[1].stale_states, 3u);
  EXPECT_EQ(log.unrecovered(), 1);
}

// States before the replay started (t < 0) and of hands beyond the lab's are ignored; a state at
// the restart's own time counts for it; a scene run that begins belongs to the newest scene
// restart before it, not to a later one.
TEST(RecoveryLog, EdgesOfTheHistory) {
  RecoveryLog log(1);
  log.state(0, true, -1.0);
  log.state(5, true, 1.0);
  log.state(-1, true, 1.0);
  EXPECT_LT(log.staleFirst(), 0);
  log.restarted("scene", 2.0);
  log.sceneRunBegan(1.9);  // before the restart: not its run
  EXPECT_LT(log.restarts()[0].scene_back_s, 0);
  log.state(0, false, 2.0);
  EXPECT_DOUBLE_EQ(log.restarts()[0].fresh_again_s, 2.0);
  log.sceneRunBegan(2.1);
  log.restarted("scene", 4.0);
  log.sceneRunBegan(4.5);
  EXPECT_DOUBLE_EQ(log.restarts()[0].scene_back_s, 2.1);
  EXPECT_DOUBLE_EQ(log.restarts()[1].scene_back_s, 4.5);
}
