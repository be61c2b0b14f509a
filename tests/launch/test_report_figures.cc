// Figures of the launch report, apart from any process or DDS: the end-to-end latency without
// stale states (common/latency_figures.h) and a service's output rate from its heartbeats
// (common/output_rate.h). Oracles: small histories worked out by hand.
#include <gtest/gtest.h>

#include <cmath>

#include "common/latency_figures.h"
#include "common/output_rate.h"

using namespace godhand;

// The run of the soak's finding: 99 fresh states of 2-3 ms, then one stale state 2.3 s old (a hand
// held against a dead scene). The latency figures are the fresh states'; the stale one's age is
// reported apart, and counted there.
TEST(LatencyFigures, AStaleStateIsNoLatency) {
  LatencyFigures f;
  for (int i = 0; i < 99; ++i) f.add(2000.0 + 10.0 * i, false);  // 2000 .. 2980 us
  f.add(2.3e6, true);
  EXPECT_EQ(f.latency().count(), 99u);
  EXPECT_DOUBLE_EQ(f.latency().max(), 2980.0);
  EXPECT_DOUBLE_EQ(percentile(f.latency().values(), 0.5), 2490.0);
  EXPECT_LE(percentile(f.latency().values(), 0.99), 2980.0);  // was 2.3 s's share with the stale state in
  EXPECT_EQ(f.staleAges().count(), 1u);
  EXPECT_DOUBLE_EQ(f.staleAges().max(), 2.3e6);
  // The per-second window: the fresh ones only.
  EXPECT_EQ(f.window().size(), 99u);
  for (double v : f.window()) EXPECT_LT(v, 3000.0);
  f.clearWindow();
  EXPECT_TRUE(f.window().empty());
  EXPECT_EQ(f.latency().count(), 99u);  // the run's figures stay
}

TEST(LatencyFigures, ASecondOfStaleStatesOnlyHasNoLatency) {
  LatencyFigures f;
  f.add(400000.0, true);
  f.add(900000.0, true);
  EXPECT_TRUE(f.window().empty());  // the line says "no fresh hand state this second"
  EXPECT_TRUE(f.latency().empty());
  EXPECT_DOUBLE_EQ(f.latency().max(), 0.0);
  EXPECT_EQ(f.staleAges().count(), 2u);
}

TEST(LatencyFigures, AgesNotMeasuredEnterNeitherFigure) {
  LatencyFigures f;
  f.add(0.0, false);   // no source time, or aged by the launcher's own pause
  f.add(-5.0, true);
  f.add(std::nan(""), false);
  EXPECT_TRUE(f.latency().empty());
  EXPECT_TRUE(f.staleAges().empty());
  EXPECT_TRUE(f.window().empty());
}

// The scene publishes a state every step of its clock (24 a second at half speed), forces or
// not: its output rate is what it wrote, whatever came in.
TEST(OutputRate, SamplesWrittenBetweenTwoHeartbeatsOfOneProcess) {
  OutputRate r;
  EXPECT_LT(r.perSecond("scene"), 0);  // nothing heard
  r.beat("scene", 100, 1'000'000'000, 50);
  EXPECT_LT(r.perSecond("scene"), 0);  // one heartbeat: no rate yet
  r.beat("scene", 100, 1'500'000'000, 62);
  EXPECT_DOUBLE_EQ(r.perSecond("scene"), 24.0);  // 12 states in 0.5 s
  r.beat("scene", 100, 2'000'000'000, 74);
  EXPECT_DOUBLE_EQ(r.perSecond("scene"), 24.0);
  r.beat("scene", 100, 2'500'000'000, 74);  // wrote nothing in this half second
  EXPECT_DOUBLE_EQ(r.perSecond("scene"), 0.0);
  EXPECT_LT(r.perSecond("resolver"), 0);  // per service
}

TEST(OutputRate, ARestartedProcessStartsAgain) {
  OutputRate r;
  r.beat("scene", 100, 1'000'000'000, 500);
  r.beat("scene", 100, 1'500'000'000, 512);
  r.beat("scene", 200, 4'000'000'000, 3);  // the restarted scene: its own counters
  EXPECT_LT(r.perSecond("scene"), 0);       // not (3 - 512) / 2.5 s, nor 3 / 2.5 s
  r.beat("scene", 200, 4'500'000'000, 15);
  EXPECT_DOUBLE_EQ(r.perSecond("scene"), 24.0);
  // A late heartbeat of the old process (in flight when it was killed) starts it again too.
  r.beat("scene", 100, 1'600'000'000, 515);
  EXPECT_LT(r.perSecond("scene"), 0);
}

TEST(OutputRate, ACounterOrClockGoingBackStartsAgain) {
  OutputRate r;
  r.beat("scene", 7, 1'000'000'000, 100);
  r.beat("scene", 7, 1'500'000'000, 90);  // counter down: not an output of -20/s
  EXPECT_LT(r.perSecond("scene"), 0);
  r.beat("scene", 7, 2'000'000'000, 102);
  EXPECT_DOUBLE_EQ(r.perSecond("scene"), 24.0);
  r.beat("scene", 7, 1'000'000'000, 110);  // clock back
  EXPECT_LT(r.perSecond("scene"), 0);
  r.beat("scene", 7, 1'000'000'000, 110);  // the same heartbeat again: no interval
  EXPECT_LT(r.perSecond("scene"), 0);
}
