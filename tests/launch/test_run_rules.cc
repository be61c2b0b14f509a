// The launcher's rules, apart from any process or DDS: fault-drill specs (common/drill.h), the
// heartbeat watchdog on an injected clock (common/watchdog.h), delivery counts and the --check
// verdict (common/delivery.h). Oracles: counts worked out by hand for small, explicit histories.
#include <gtest/gtest.h>

#include <chrono>

#include "common/delivery.h"
#include "common/drill.h"
#include "common/watchdog.h"

using namespace godhand;
using namespace std::chrono_literals;

TEST(Drill, SecondsAndFrames) {
  Drill d = parseDrill("scene@2");
  EXPECT_EQ(d.service, "scene");
  EXPECT_FALSE(d.by_frame);
  EXPECT_DOUBLE_EQ(d.seconds, 2.0);
  d = parseDrill("solver/right@1.5s");
  EXPECT_EQ(d.service, "solver/right");
  EXPECT_DOUBLE_EQ(d.seconds, 1.5);
  d = parseDrill("ingest@f120");
  EXPECT_TRUE(d.by_frame);
  EXPECT_EQ(d.frame, 120u);
}

TEST(Drill, DueFromTheReplayNotTheLauncher) {
  const Drill s = parseDrill("scene@2");
  EXPECT_FALSE(s.due(-1.0, 0));    // replay not started: never, however long start-up takes
  EXPECT_FALSE(s.due(1.99, 500));
  EXPECT_TRUE(s.due(2.0, 1));
  const Drill f = parseDrill("scene@f10");
  EXPECT_FALSE(f.due(100.0, 9));
  EXPECT_TRUE(f.due(0.1, 10));
  EXPECT_FALSE(f.due(-1.0, 10));
}

TEST(Drill, RejectsIncompleteSpecsWithOneLine) {
  for (const char* bad : {"@2", "scene@", "scene", "scene@-1", "scene@f0", "scene@f", "scene@2x", "scene@fx", "scene@1e3",
                          "scene@nan", "scene@s", "scene@inf"}) {
    try {
      parseDrill(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(bad), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
}

TEST(Watchdog, SilentServiceIsNoticedAndComesBack) {
  const auto t0 = Watchdog::Clock::time_point{} + 1000s;
  Watchdog w(1.0, t0);
  EXPECT_EQ(w.health("resolver"), Watchdog::Health::Unknown);
  EXPECT_TRUE(w.update(t0 + 10s).empty());  // never beat: not aged (still starting)
  w.beat("resolver", t0);
  w.beat("scene", t0);
  EXPECT_TRUE(w.update(t0 + 900ms).empty());
  w.beat("scene", t0 + 900ms);
  // The resolver stops beating (SIGSTOP): silent once its newest beat is older than 1 s.
  const auto silent = w.update(t0 + 1100ms);
  ASSERT_EQ(silent.size(), 1u);
  EXPECT_EQ(silent[0], "resolver");
  EXPECT_EQ(w.health("resolver"), Watchdog::Health::Silent);
  EXPECT_EQ(w.health("scene"), Watchdog::Health::Alive);
  EXPECT_TRUE(w.update(t0 + 1500ms).empty());  // reported once per spell
  EXPECT_NEAR(w.silentFor("resolver", t0 + 1500ms), 1.5, 1e-9);
  // It resumes: alive again, one episode from 1.0 s (last beat + limit) to 3.0 s.
  w.beat("resolver", t0 + 3s);
  EXPECT_EQ(w.health("resolver"), Watchdog::Health::Alive);
  ASSERT_EQ(w.episodes().size(), 1u);
  EXPECT_EQ(w.episodes()[0].service, "resolver");
  EXPECT_NEAR(w.episodes()[0].start_s, 1.0, 1e-9);
  EXPECT_NEAR(w.episodes()[0].end_s, 3.0, 1e-9);
  // The scene goes silent and is restarted: the episode ends at the reset, Unknown until it beats.
  ASSERT_EQ(w.update(t0 + 3s).size(), 1u);
  EXPECT_LT(w.episodes()[1].end_s, 0.0);
  w.reset("scene", t0 + 4s);
  EXPECT_EQ(w.health("scene"), Watchdog::Health::Unknown);
  EXPECT_NEAR(w.episodes()[1].end_s, 4.0, 1e-9);
  EXPECT_TRUE(w.update(t0 + 20s).size() == 1u);  // only the resolver (silent again), not the reset scene
}

// The launcher itself paused (SIGSTOP, a starved process, a stalled machine): 2.5 s in which
// nobody looked, while the services kept beating into its sockets. Seen live: all five healthy
// services killed and restarted. The gap is not counted against them; a service that stays
// silent after the pause is still found, one limit after the pause ended.
TEST(Watchdog, ItsOwnPauseIsNotCountedAgainstTheServices) {
  const auto t0 = Watchdog::Clock::time_point{} + 1000s;
  Watchdog w(1.2, t0);
  for (int ms = 0; ms <= 1000; ms += 20) {  // the launcher's loop: beats every 0.5 s, updates every 20 ms
    const auto t = t0 + std::chrono::milliseconds(ms);
    if (ms % 500 == 0) {
      w.beat("resolver", t);
      w.beat("scene", t);
    }
    EXPECT_TRUE(w.update(t).empty());
  }
  EXPECT_TRUE(w.pauses().empty());
  // Paused from 1.0 s to 3.5 s. The scene's queued heartbeat is read at once; the resolver's only later.
  const auto resumed = t0 + 3500ms;
  w.beat("scene", resumed);
  EXPECT_TRUE(w.update(resumed).empty());
  EXPECT_EQ(w.health("resolver"), Watchdog::Health::Alive);
  ASSERT_EQ(w.pauses().size(), 1u);
  EXPECT_NEAR(w.pauses()[0].start_s, 1.0, 1e-9);
  EXPECT_NEAR(w.pauses()[0].duration_s, 2.5, 1e-9);
  // The resolver really is silent (its last beat at 1.0 s): credited with the pause less a quarter
  // of the limit (2.2 s), it is found 1.2 s later, at 4.4 s.
  int found_ms = -1;
  for (int ms = 3520; ms <= 6000 && found_ms < 0; ms += 20) {
    const auto t = t0 + std::chrono::milliseconds(ms);
    if (ms % 500 == 0) w.beat("scene", t);
    const auto silent = w.update(t);
    if (!silent.empty()) {
      EXPECT_EQ(silent, std::vector<std::string>{"resolver"});
      found_ms = ms;
    }
  }
  EXPECT_GT(found_ms, 4400);
  EXPECT_LE(found_ms, 4440);
  EXPECT_EQ(w.health("scene"), Watchdog::Health::Alive);
  EXPECT_EQ(w.pauses().size(), 1u);  // 20 ms steps are no pauses
  // The credit delays the verdict only: the silence reported is the resolver's own, from its
  // last beat at 1.0 s (it read 1.2 s at 4.4 s, and an episode from 3.4 s, before).
  const auto found = t0 + std::chrono::milliseconds(found_ms);
  EXPECT_NEAR(w.silentFor("resolver", found), found_ms * 1e-3 - 1.0, 1e-9);
  ASSERT_EQ(w.episodes().size(), 1u);
  EXPECT_NEAR(w.episodes()[0].start_s, 1.0 + 1.2, 1e-9);
}

// A launcher whose every loop is slow (0.7 s under load, each gap above half the limit) is not
// paused but starved: a service that stops beating must still be found (each loop ages it by a
// quarter of the limit), while the one that beats stays alive.
TEST(Watchdog, ASlowLauncherStillFindsADeadService) {
  const auto t0 = Watchdog::Clock::time_point{} + 1000s;
  Watchdog w(1.2, t0);
  w.beat("resolver", t0);
  w.beat("scene", t0);
  EXPECT_TRUE(w.update(t0).empty());
  double found_s = -1;
  for (int k = 1; k <= 20 && found_s < 0; ++k) {
    const auto t = t0 + std::chrono::milliseconds(700 * k);
    w.beat("scene", t);
    const auto silent = w.update(t);
    if (!silent.empty()) {
      EXPECT_EQ(silent, std::vector<std::string>{"resolver"});
      found_s = 0.7 * k;
    }
  }
  EXPECT_GT(found_s, 0.0) << "never found";
  EXPECT_LE(found_s, 4.2);  // 1.2 / 0.3 = 4 loops past the first, at 0.7 s each
  EXPECT_EQ(w.health("scene"), Watchdog::Health::Alive);
  EXPECT_EQ(w.pauseCount(), 0u);  // gaps under the limit itself are not reported as pauses
}

TEST(Delivery, CountsFramesNotTheHighestFrameNumber) {
  Delivery d(2);
  const std::uint64_t run = 77;
  // Hand 0: frames 1..10 fresh. Hand 1: frames 1..3 fresh, 4..5 only stale, 6 stale then fresh,
  // then only frame 10 (7, 8, 9 lost).
  for (std::uint64_t k = 1; k <= 10; ++k) d.add(0, run, k, false);
  for (std::uint64_t k = 1; k <= 3; ++k) d.add(1, run, k, false);
  d.add(1, run, 4, true);
  d.add(1, run, 5, true);
  d.add(1, run, 5, true);  // held and re-published: still one frame
  d.add(1, run, 6, true);
  d.add(1, run, 6, false);
  d.add(1, run, 10, false);
  d.add(1, run, 0, false);     // before the first frame: ignored
  d.add(5, run, 1, false);     // unknown hand: ignored
  const std::map<std::uint64_t, std::uint64_t> expected{{run, 12}};
  const DeliveryCounts a = d.counts(0, expected), b = d.counts(1, expected);
  EXPECT_EQ(a.expected, 12u);
  EXPECT_EQ(a.fresh, 10u);
  EXPECT_EQ(a.stale, 0u);
  EXPECT_EQ(a.lost, 2u);  // 11 and 12 never came
  EXPECT_EQ(b.fresh, 5u);  // 1, 2, 3, 6, 10
  EXPECT_EQ(b.stale, 2u);  // 4, 5
  EXPECT_EQ(b.lost, 5u);   // 7, 8, 9, 11, 12
  EXPECT_EQ(d.highest(run), 10u);
}

TEST(Delivery, RunsOfARestartedIngestCountApart) {
  Delivery d(1);
  d.published(1, 30);  // the first ingest run reached frame 30, then was killed
  for (std::uint64_t k = 1; k <= 20; ++k) d.add(0, 1, k, false);
  for (std::uint64_t k = 1; k <= 50; ++k) d.add(0, 2, k, false);
  d.add(0, 3, 1, false);  // another run (another lab?) not expected: not counted
  ASSERT_EQ(d.runs().size(), 3u);
  EXPECT_EQ(d.highest(1), 30u);
  const DeliveryCounts c = d.counts(0, {{1, d.highest(1)}, {2, 50}});
  EXPECT_EQ(c.expected, 80u);
  EXPECT_EQ(c.fresh, 70u);
  EXPECT_EQ(c.lost, 10u);
}

// Frames expected of each run: the last one was to play the whole replay, unless it was stopped
// on purpose (the ingest's --duration: `godhand-launch --recording pinch.json --duration 1` counted
// the 192 frames never played as lost and failed --check); runs cut short by a kill, and a live
// source, expect what was published; nothing seen at all expects the whole replay (all lost).
TEST(Delivery, FramesExpectedOfEachRun) {
  Delivery d(1);
  for (std::uint64_t k = 1; k <= 4; ++k) d.published(1, k);
  for (std::uint64_t k = 1; k <= 3; ++k) d.add(0, 1, k, false);  // frame 4's state lost
  using E = std::map<std::uint64_t, std::uint64_t>;
  EXPECT_EQ(d.expected(10, false), (E{{1, 10}}));  // to the end: 6 never published are lost
  EXPECT_EQ(d.counts(0, d.expected(10, false)).lost, 7u);
  EXPECT_EQ(d.expected(10, true), (E{{1, 4}}));  // --duration: what it published
  EXPECT_EQ(d.counts(0, d.expected(10, true)).lost, 1u);
  EXPECT_EQ(d.expected(-1, false), (E{{1, 4}}));  // live
  d.published(2, 2);  // the ingest restarted (run 2): run 1 was cut short by a kill
  EXPECT_EQ(d.expected(10, false), (E{{1, 4}, {2, 10}}));
  EXPECT_EQ(d.expected(10, true), (E{{1, 4}, {2, 2}}));
  EXPECT_EQ(Delivery(1).expected(10, false), (E{{0, 10}}));
  EXPECT_EQ(Delivery(1).expected(10, true), E{});  // --duration ended it before its first frame
  EXPECT_EQ(Delivery(1).expected(-1, false), E{});
}

// The launcher's own pause (SIGSTOP 2.5 s): frames published meanwhile were superseded in its
// keep-newest readers. Those without a state are not observed, not lost; those whose state came
// count as usual; windows may overlap; frames beyond the expected ones and other runs' windows
// count nothing.
TEST(Delivery, FramesPublishedWhileTheLauncherDidNotWatchAreNotObservedNotLost) {
  Delivery d(2);
  const std::uint64_t run = 5;
  for (std::uint64_t k = 1; k <= 40; ++k) {
    if (k <= 10 || k >= 31) d.add(0, run, k, false);  // hand 0: 11..30 not seen
    if (k <= 10 || k == 20 || k >= 31) d.add(1, run, k, k == 20);  // hand 1: its frame 20 came, stale
  }
  d.add(0, run, 35, true);   // (stale copy of a fresh frame: still fresh)
  d.unobserved(run, 11, 25);  // the pause
  d.unobserved(run, 20, 30);  // overlapping: one window 11..30
  d.unobserved(9, 1, 40);     // another run, not expected
  d.unobserved(run, 0, 3);    // frame 0: refused
  d.unobserved(run, 8, 7);    // empty: refused
  const std::map<std::uint64_t, std::uint64_t> expected{{run, 42}};
  const DeliveryCounts a = d.counts(0, expected), b = d.counts(1, expected);
  EXPECT_EQ(a.expected, 42u);
  EXPECT_EQ(a.fresh, 20u);        // 1..10, 31..40
  EXPECT_EQ(a.unobserved, 20u);  // 11..30
  EXPECT_EQ(a.lost, 2u);         // 41, 42: after the pause, really lost
  EXPECT_EQ(b.fresh, 20u);
  EXPECT_EQ(b.stale, 1u);        // 20
  EXPECT_EQ(b.unobserved, 19u);  // 11..30 but 20
  EXPECT_EQ(b.lost, 2u);
  EXPECT_EQ(a.expected, a.fresh + a.stale + a.lost + a.unobserved);
  // The verdict says so: 20 of 42 not observed is beyond a 5 % budget, and named as such.
  RunFigures f;
  f.loss_budget = 0.05;
  f.delivery["right"] = a;
  f.late_joiner_ok = true;
  f.margin = 1e-4;
  f.states = 100;
  const RunVerdict v = evaluateRun(f);
  EXPECT_FALSE(v.ok);
  ASSERT_EQ(v.reasons.size(), 1u);
  EXPECT_NE(v.reasons[0].find("2 of 42 frames lost and 20 not observed"), std::string::npos) << v.reasons[0];
  // One budget for both: 5 % of 1000 is 50; 30 lost and 30 not observed is 60, beyond it.
  f.delivery["right"] = {1000, 940, 0, 30, 30};
  EXPECT_FALSE(evaluateRun(f).ok);
  f.delivery["right"] = {1000, 960, 0, 20, 20};
  EXPECT_TRUE(evaluateRun(f).ok);
}

namespace {
RunFigures goodRun() {
  RunFigures f;
  f.loss_budget = 0.05;
  f.delivery["right"] = {100, 99, 0, 1};
  f.late_joiner_ok = true;
  f.margin = 1e-4;
  f.states = 200;
  return f;
}
}  // namespace

TEST(RunVerdict, PassesACleanRunAndNamesEachFailure) {
  EXPECT_TRUE(evaluateRun(goodRun()).ok);
  RunFigures f = goodRun();
  f.delivery["left"] = {100, 40, 4, 56};
  f.dead_at_end = {"resolver"};
  f.late_joiner_ok = false;
  f.drills_not_done = {"scene@f999"};
  f.foreign = {"resolver (pid 42 on pc)"};
  const RunVerdict v = evaluateRun(f);
  EXPECT_FALSE(v.ok);
  ASSERT_EQ(v.reasons.size(), 5u);
  EXPECT_NE(v.reasons[4].find("another lab shares the DDS domain (resolver (pid 42 on pc))"), std::string::npos) << v.reasons[4];
  EXPECT_NE(v.reasons[0].find("left: 56 of 100 frames lost (budget 5)"), std::string::npos) << v.reasons[0];
  EXPECT_NE(v.reasons[1].find("resolver"), std::string::npos);
  EXPECT_NE(v.reasons[2].find("late joiner"), std::string::npos);
  EXPECT_NE(v.reasons[3].find("scene@f999"), std::string::npos);
}

TEST(RunVerdict, LockStepAllowsNoLossAndNoStaleFrame) {
  RunFigures f = goodRun();
  f.lockstep = true;
  EXPECT_FALSE(evaluateRun(f).ok);  // 1 lost
  f.delivery["right"] = {100, 100, 0, 0};
  EXPECT_TRUE(evaluateRun(f).ok);
  f.delivery["right"] = {100, 99, 1, 0};
  EXPECT_FALSE(evaluateRun(f).ok);
  f = goodRun();
  f.failure = "ingest ended with exit code 3\nlog...";
  const RunVerdict v = evaluateRun(f);
  ASSERT_EQ(v.reasons.size(), 1u);
  EXPECT_EQ(v.reasons[0], "the run failed: ingest ended with exit code 3");
  f = goodRun();
  f.delivery["right"] = {0, 0, 0, 0};
  EXPECT_FALSE(evaluateRun(f).ok);  // nothing expected is not a success
}
