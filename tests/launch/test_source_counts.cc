// The tracker source's counts of the launch report (services/common/source_counts.h): bounded for
// the wire without losing a count, summed over ingest runs (never a maximum), one summary line.
#include <gtest/gtest.h>

#include <string>

#include "common/source_counts.h"

namespace godhand {
namespace {

std::uint64_t total(const std::vector<std::pair<std::string, std::uint64_t>>& v) {
  std::uint64_t n = 0;
  for (const auto& r : v) n += r.second;
  return n;
}

TEST(SourceCounts, ReasonMapSumsRepeatsAndDropsZeros) {
  const auto m = reasonMap({{"parse error", 2}, {"NaN/Inf", 0}, {"parse error", 3}, {"oversized", 1}});
  EXPECT_EQ(m, (std::map<std::string, std::uint64_t>{{"parse error", 5}, {"oversized", 1}}));
}

TEST(SourceCounts, BoundReasonsKeepsEverythingThatFits) {
  const std::map<std::string, std::uint64_t> m{{"parse error", 4}, {"NaN/Inf", 2}, {"stale/duplicate frame", 0}};
  const auto v = boundReasons(m);
  ASSERT_EQ(v.size(), 2u);  // the zero is left out
  EXPECT_EQ(v[0], (std::pair<std::string, std::uint64_t>{"NaN/Inf", 2}));
  EXPECT_EQ(v[1], (std::pair<std::string, std::uint64_t>{"parse error", 4}));
}

TEST(SourceCounts, BoundReasonsSumsTheRestAndKeepsTheTotal) {
  std::map<std::string, std::uint64_t> m;
  for (int i = 0; i < 20; ++i) m["reason " + std::to_string(100 + i)] = static_cast<std::uint64_t>(i + 1);
  const auto v = boundReasons(m, 16);
  ASSERT_EQ(v.size(), 16u);
  EXPECT_EQ(total(v), 210u);  // 1 + ... + 20: no count lost
  std::map<std::string, std::uint64_t> got(v.begin(), v.end());
  // The 15 largest (6..20) kept by name, the five smallest summed.
  EXPECT_EQ(got.at(kOtherReasons), 1u + 2 + 3 + 4 + 5);
  EXPECT_EQ(got.at("reason 119"), 20u);
  EXPECT_EQ(got.at("reason 105"), 6u);
  EXPECT_EQ(got.count("reason 104"), 0u);
}

TEST(SourceCounts, BoundReasonsOtherAlreadyPresentTakesTheRest) {
  std::map<std::string, std::uint64_t> m{{kOtherReasons, 100}, {"a", 1}, {"b", 2}, {"c", 3}};
  const auto v = boundReasons(m, 3);
  ASSERT_EQ(v.size(), 2u);  // "c" and "other reasons" (100 + a + b)
  std::map<std::string, std::uint64_t> got(v.begin(), v.end());
  EXPECT_EQ(got.at(kOtherReasons), 103u);
  EXPECT_EQ(got.at("c"), 3u);
  EXPECT_EQ(total(v), 106u);
}

TEST(SourceCounts, BoundReasonsCutsLongNamesAndSumsCollisions) {
  const std::string a(80, 'x'), b = std::string(64, 'x') + "yy";
  const auto v = boundReasons({{a, 2}, {b, 3}, {"6-DOF body outside the tracking volume", 1}}, 16, 64);
  ASSERT_EQ(v.size(), 2u);
  for (const auto& r : v) EXPECT_LE(r.first.size(), 64u);
  std::map<std::string, std::uint64_t> got(v.begin(), v.end());
  EXPECT_EQ(got.at(std::string(64, 'x')), 5u);
  EXPECT_EQ(got.at("6-DOF body outside the tracking volume"), 1u);  // 38 characters: kept whole
}

TEST(SourceTally, NewestHeartbeatOfARunIsItsCount) {
  SourceTally t;
  EXPECT_FALSE(t.any());
  t.update(0, SourceCounts{5, 5, {}, {}});  // no source: ignored
  EXPECT_FALSE(t.any());
  t.update(7, SourceCounts{10, 8, {{"parse error", 2}}, {}});
  t.update(7, SourceCounts{30, 25, {{"parse error", 4}, {"NaN/Inf", 1}}, {}});
  EXPECT_EQ(t.runs(), 1u);
  EXPECT_EQ(t.total(), (SourceCounts{30, 25, {{"parse error", 4}, {"NaN/Inf", 1}}, {}}));
}

TEST(SourceTally, RestartedIngestRunsAreSummedNotMaxed) {
  SourceTally t;
  t.update(1, SourceCounts{100, 90, {{"parse error", 10}}, {}});  // killed by a drill: its last heartbeat
  t.update(2, SourceCounts{40, 35, {{"parse error", 3}, {"oversized", 2}}, {}});  // the restarted one counts from 0
  EXPECT_EQ(t.runs(), 2u);
  const SourceCounts s = t.total();
  EXPECT_EQ(s.received, 140u);
  EXPECT_EQ(s.accepted, 125u);
  EXPECT_EQ(s.rejected, (std::map<std::string, std::uint64_t>{{"oversized", 2}, {"parse error", 13}}));
  EXPECT_EQ(s.rejectedTotal(), 15u);
}

// A killed ingest run's unplayed rest of the recording is not received: its heartbeats count it
// as not played yet, and the report, made once the runs are over, says that this is all the run's
// last heartbeat had counted. A run that ended itself names its reason.
TEST(SourceTally, NotPlayedIsNeitherReceivedNorRejectedAndAKilledRunSaysSo) {
  SourceTally t;
  t.update(1, SourceCounts{30, 30, {}, {{kNotPlayedYet, 141}}});  // killed at frame ~40: its last heartbeat at 30
  t.update(2, SourceCounts{171, 171, {}, {}});                    // the restarted run played the whole recording
  t.update(3, SourceCounts{52, 50, {{"parse error", 2}}, {{"beyond --frames 50", 121}}});
  const SourceCounts s = t.total();
  EXPECT_EQ(s.received, 253u);
  EXPECT_EQ(s.received, s.accepted + s.rejectedTotal());
  EXPECT_EQ(s.notPlayedTotal(), 262u);
  EXPECT_EQ(s.not_played, (std::map<std::string, std::uint64_t>{{kNotPlayedNoFinalCount, 141}, {"beyond --frames 50", 121}}));
  EXPECT_EQ(s.not_played.count(kNotPlayedYet), 0u);  // "yet" no more: the run is over
  EXPECT_EQ(describeSource(s, 3),
            "source: received 253, accepted 251, rejected 2 (parse error 2); not played 262 (beyond --frames 50 121, " +
                std::string(kNotPlayedNoFinalCount) + " 141), over 3 ingest runs (summed)");
}

// Only a run whose final count says its --duration stopped it expects just what it published
// (Delivery::expected): a run stopped by a signal, killed (its last heartbeat: "not played yet"),
// cut by --frames, or unknown, expects the whole recording (the review's case: --duration 60 given,
// the ingest SIGTERMed after 1.5 s, "expected 56, lost 0, check ok" while 250 frames never came).
TEST(SourceTally, OnlyARunItsDurationStoppedIsCutShortOnPurpose) {
  EXPECT_EQ(durationReachedReason(1), "--duration 1 s reached");
  EXPECT_EQ(durationReachedReason(2.5), "--duration 2.5 s reached");
  EXPECT_TRUE(isDurationReached(durationReachedReason(600)));
  EXPECT_FALSE(isDurationReached("--duration  s reached"));
  EXPECT_FALSE(isDurationReached("stopped (SIGINT/SIGTERM)"));
  SourceTally t;
  t.update(1, SourceCounts{115, 115, {}, {{durationReachedReason(1), 192}}});
  t.update(2, SourceCounts{56, 56, {}, {{"stopped (SIGINT/SIGTERM)", 251}}});
  t.update(3, SourceCounts{30, 30, {}, {{kNotPlayedYet, 277}}});
  t.update(4, SourceCounts{50, 50, {}, {{"beyond --frames 50", 257}}});
  t.update(5, SourceCounts{307, 307, {}, {}});
  EXPECT_TRUE(t.stoppedByDuration(1));
  for (std::uint64_t run : {2u, 3u, 4u, 5u, 6u}) EXPECT_FALSE(t.stoppedByDuration(run)) << run;
  EXPECT_FALSE(t.lastRunStoppedByDuration());  // the newest run (5) played to the end
  t.update(7, SourceCounts{3, 3, {}, {{durationReachedReason(0.1), 304}}});
  EXPECT_TRUE(t.lastRunStoppedByDuration());
  EXPECT_FALSE(SourceTally().lastRunStoppedByDuration());
}

TEST(SourceCounts, SummaryLine) {
  EXPECT_EQ(describeSource(SourceCounts{12, 9, {{"parse error", 2}, {"NaN/Inf", 1}}, {}}),
            "source: received 12, accepted 9, rejected 3 (NaN/Inf 1, parse error 2)");
  EXPECT_EQ(describeSource(SourceCounts{4, 4, {}, {}}), "source: received 4, accepted 4, rejected 0 (none)");
  EXPECT_EQ(describeSource(SourceCounts{4, 3, {{"oversized", 1}}, {}}, 2),
            "source: received 4, accepted 3, rejected 1 (oversized 1), over 2 ingest runs (summed)");
}

}  // namespace
}  // namespace godhand
