// The stages' scheduling rules on an injected clock (no processes, no sleeping): the lock-step
// gate (runtime/lockstep_gate.h) and the resolver's live merge (runtime/live_merge.h). Oracles:
// the decisions worked out by hand for short, explicit timelines.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>

#include "runtime/lab_checks.h"
#include "runtime/live_merge.h"
#include "runtime/lockstep_gate.h"

using namespace godhand::svc;
using namespace std::chrono_literals;
using G = LockstepGate;
using M = LiveMerge;

namespace {
const G::Clock::time_point T0 = G::Clock::time_point{} + 100s;
}

TEST(LockstepGate, ReadyWhenEveryInputOfTheFrameIsIn) {
  // The resolver's shape: two proposals (triggers) and the scene of k-1 (input 2).
  G g({true, true, false}, 1.0, T0);
  EXPECT_EQ(g.poll(T0).state, G::State::Idle);
  EXPECT_TRUE(g.offer(2, 1, T0));  // SceneState(0) for frame 1: no trigger yet, still idle
  EXPECT_EQ(g.poll(T0 + 5s).state, G::State::Idle);
  EXPECT_TRUE(g.offer(0, 1, T0 + 5s));
  G::Poll p = g.poll(T0 + 5s);
  EXPECT_EQ(p.state, G::State::Waiting);
  EXPECT_EQ(p.until, T0 + 6s);  // deadline from the first trigger
  ASSERT_EQ(p.missing.size(), 1u);
  EXPECT_EQ(p.missing[0], 1u);
  EXPECT_TRUE(g.offer(1, 1, T0 + 5500ms));
  EXPECT_EQ(g.poll(T0 + 5500ms).state, G::State::Ready);
  g.advance(T0 + 5600ms);
  EXPECT_EQ(g.next(), 2u);
  EXPECT_FALSE(g.offer(0, 1, T0 + 6s));  // late: frame 1 is done
  EXPECT_EQ(g.poll(T0 + 6s).state, G::State::Idle);
}

TEST(LockstepGate, MissesTheDeadlineAndNamesWhatIsMissing) {
  G g({true, false, false}, 2.0, T0);  // the solver's shape: target, scene k-1, state k-1
  g.waive(2, 1);                       // no state before frame 1
  g.offer(0, 1, T0);
  EXPECT_EQ(g.poll(T0 + 1999ms).state, G::State::Waiting);
  const G::Poll p = g.poll(T0 + 2s);
  EXPECT_EQ(p.state, G::State::Missed);
  ASSERT_EQ(p.missing.size(), 1u);
  EXPECT_EQ(p.missing[0], 1u);  // the scene
}

TEST(LockstepGate, EarlyInputsWaitForTheirFrameAndTheDeadlineStartsWhenItIsNext) {
  G g({true, false}, 1.0, T0);
  g.offer(1, 1, T0);
  g.offer(0, 2, T0);  // frame 2's trigger before frame 1 is even triggered
  EXPECT_EQ(g.poll(T0 + 10s).state, G::State::Idle);  // frame 1 has no trigger
  g.offer(0, 1, T0 + 10s);
  ASSERT_EQ(g.poll(T0 + 10s).state, G::State::Ready);
  g.advance(T0 + 10s);
  // Frame 2 was triggered at T0 but became next only now: its deadline runs from now.
  const G::Poll p = g.poll(T0 + 10500ms);
  EXPECT_EQ(p.state, G::State::Waiting);
  EXPECT_EQ(p.until, T0 + 11s);
  EXPECT_FALSE(g.offer(5, 2, T0));  // unknown input
}

TEST(LiveMerge, ResolvesWhenEveryLiveClusterIsInOrAfterTheMergeWait) {
  // 2 clusters, 20 ms frames, wait at most half a frame, stale after 250 ms.
  M m(2, 0.020, 0.5, 0.25, T0);
  EXPECT_EQ(m.decide(true, T0).kind, M::Decision::Wait);  // nothing yet
  EXPECT_EQ(m.offer(0, 7, 1, 1000, T0), M::Offer::NewRun);
  // Cluster 1 has never been heard of: not waited for.
  M::Decision d = m.decide(true, T0);
  EXPECT_EQ(d.kind, M::Decision::Resolve);
  EXPECT_EQ(d.frame, 1u);
  m.published(d, T0);
  EXPECT_FALSE(m.pending(0));
  EXPECT_EQ(m.offer(1, 7, 1, 1000, T0 + 1ms), M::Offer::Accepted);
  // Cluster 0 is live (heard of 1 ms ago) and has nothing new: wait half a frame for it.
  d = m.decide(true, T0 + 1ms);
  EXPECT_EQ(d.kind, M::Decision::Wait);
  EXPECT_EQ(d.until, T0 + 11ms);
  m.published(d, T0 + 1ms);  // a Wait changes nothing
  EXPECT_TRUE(m.pending(1));
  d = m.decide(true, T0 + 11ms);
  EXPECT_EQ(d.kind, M::Decision::Resolve);
  m.published(d, T0 + 11ms);
  // Both live now: frame 2 of cluster 0 waits for cluster 1, at most 10 ms.
  m.offer(0, 7, 2, 2000, T0 + 20ms);
  d = m.decide(true, T0 + 25ms);
  EXPECT_EQ(d.kind, M::Decision::Wait);
  EXPECT_EQ(d.until, T0 + 30ms);
  d = m.decide(true, T0 + 30ms);
  EXPECT_EQ(d.kind, M::Decision::Resolve);  // cluster 1 is held
  EXPECT_EQ(d.frame, 2u);
  m.published(d, T0 + 30ms);
  // Cluster 1's frame 2 arrives after: still newer than what it had resolved, accepted.
  EXPECT_EQ(m.offer(1, 7, 2, 2000, T0 + 31ms), M::Offer::Accepted);
  EXPECT_EQ(m.offer(1, 7, 3, 3000, T0 + 32ms), M::Offer::Superseded);
  EXPECT_EQ(m.frameOf(1), 3u);
  EXPECT_EQ(m.decide(true, T0 + 32ms).kind, M::Decision::Wait);  // cluster 0 is live, not in
}

TEST(LiveMerge, LateAndOldRunsAreDroppedANewRunReplacesTheOld) {
  M m(1, 0.020, 0.5, 0.25, T0);
  m.offer(0, 7, 5, 5000, T0);
  M::Decision d = m.decide(true, T0);
  m.published(d, T0);
  EXPECT_EQ(m.offer(0, 7, 5, 5000, T0 + 1ms), M::Offer::Late);   // already resolved
  EXPECT_EQ(m.offer(0, 7, 4, 4000, T0 + 1ms), M::Offer::Late);   // older
  EXPECT_EQ(m.offer(0, 9, 1, 9000, T0 + 2ms), M::Offer::NewRun); // a restarted ingest: frame 1 again
  EXPECT_EQ(m.run(), 9u);
  EXPECT_EQ(m.offer(0, 7, 6, 6000, T0 + 3ms), M::Offer::Late);   // a straggler of the old run
  EXPECT_EQ(m.run(), 9u);
}

TEST(LiveMerge, NoSingleSampleFarAheadStopsTheRealRun) {
  // 1 cluster, 20 ms frames, stale after 250 ms; the real run 7 sends a frame every 20 ms with
  // source times 20 ms apart (ns).
  const std::int64_t ms = 1000000;
  M m(1, 0.020, 0.5, 0.25, T0);
  auto real = [&](std::uint64_t k) { return m.offer(0, 7, k, static_cast<std::int64_t>(k) * 20 * ms, T0 + k * 20ms); };
  auto resolve = [&](G::Clock::time_point now) {
    const M::Decision d = m.decide(true, now);
    if (d.kind == M::Decision::Resolve) m.published(d, now);
    return d.kind;
  };
  EXPECT_EQ(real(1), M::Offer::NewRun);
  EXPECT_EQ(resolve(T0 + 20ms), M::Decision::Resolve);
  // A forged run whose source time is the largest there is: late, the real run goes on.
  EXPECT_EQ(m.offer(0, 1, 1, INT64_MAX, T0 + 30ms), M::Offer::Late);
  EXPECT_EQ(m.run(), 7u);
  EXPECT_EQ(real(2), M::Offer::Accepted);
  EXPECT_EQ(resolve(T0 + 40ms), M::Decision::Resolve);
  // A forged frame of the real run far ahead: accepted and resolved (nothing tells it apart)...
  EXPECT_EQ(m.offer(0, 7, std::uint64_t{1} << 63, 45 * ms, T0 + 45ms), M::Offer::Accepted);
  EXPECT_EQ(resolve(T0 + 45ms), M::Decision::Resolve);
  // ... so the real frames are late, but only until nothing was accepted for 250 ms: then they
  // are followed again and resolved.
  EXPECT_EQ(real(3), M::Offer::Late);
  EXPECT_EQ(real(14), M::Offer::Late);   // T0 + 280 ms: 235 ms after the forged frame
  EXPECT_EQ(real(15), M::Offer::Accepted);  // T0 + 300 ms: 255 ms
  EXPECT_EQ(m.recoveries(), 1u);
  EXPECT_EQ(resolve(T0 + 300ms), M::Decision::Resolve);
  EXPECT_EQ(real(16), M::Offer::Accepted);
  EXPECT_EQ(m.recoveries(), 1u);
  // A restarted ingest whose clock is an hour ahead (another host): while run 7 is live it is
  // not believed; once run 7 has been quiet for 250 ms it replaces it.
  const std::int64_t hour = 3600LL * 1000 * ms;
  EXPECT_EQ(m.offer(0, 9, 1, 330 * ms + hour, T0 + 330ms), M::Offer::Late);
  EXPECT_EQ(m.offer(0, 9, 20, 700 * ms + hour, T0 + 700ms), M::Offer::NewRun);
  EXPECT_EQ(m.run(), 9u);
  EXPECT_EQ(resolve(T0 + 700ms), M::Decision::Resolve);
  EXPECT_EQ(m.offer(0, 9, 21, 720 * ms + hour, T0 + 720ms), M::Offer::Accepted);
  // And a straggler of run 7 now is late (older source time, run 9 live).
  EXPECT_EQ(m.offer(0, 7, 17, 340 * ms, T0 + 730ms), M::Offer::Late);
}

TEST(LiveMerge, ASlowClustersLeftoverOfTheOldRunDoesNotTakeTheMergeBack) {
  // Cluster 0 proposes every 20 ms, cluster 1 (a slow solver) every 300 ms: cluster 1 is always
  // "quiet" (nothing of it accepted within 250 ms). The ingest restarts (run 7 -> 9) after a 2.5 s
  // gap; cluster 1 then finishes the run-7 target it was busy with. (Found by review: that
  // leftover switched the merge back to run 7 and made run 9's frames late.)
  const std::int64_t ms = 1000000;
  M m(2, 0.020, 0.5, 0.25, T0);
  EXPECT_EQ(m.offer(0, 7, 1, 1 * ms, T0), M::Offer::NewRun);
  EXPECT_EQ(m.offer(1, 7, 1, 1 * ms, T0 + 1ms), M::Offer::Accepted);
  m.published(m.decide(true, T0 + 1ms), T0 + 1ms);
  EXPECT_EQ(m.offer(0, 9, 1, 2600 * ms, T0 + 2600ms), M::Offer::NewRun);
  m.published(m.decide(true, T0 + 2620ms), T0 + 2620ms);
  EXPECT_EQ(m.offer(0, 9, 2, 2620 * ms, T0 + 2620ms), M::Offer::Accepted);
  EXPECT_EQ(m.offer(1, 7, 2, 300 * ms, T0 + 2625ms), M::Offer::Late);  // the slow cluster's leftover
  EXPECT_EQ(m.run(), 9u);
  EXPECT_EQ(m.offer(0, 9, 3, 2640 * ms, T0 + 2640ms), M::Offer::Superseded);  // (frame 2 not resolved yet)
  EXPECT_EQ(m.offer(1, 9, 2, 2600 * ms, T0 + 2900ms), M::Offer::Accepted);    // its first of run 9
  EXPECT_EQ(m.run(), 9u);
}

TEST(LiveMerge, RepublishesHeldHandsWhenNothingComesAndNeverWithoutAScene) {
  M m(2, 0.020, 0.5, 0.25, T0);
  m.offer(0, 7, 3, 3000, T0);
  m.offer(1, 7, 3, 3000, T0);
  M::Decision d = m.decide(false, T0);
  EXPECT_EQ(d.kind, M::Decision::Wait);  // no scene yet: nothing is resolved
  d = m.decide(true, T0);
  ASSERT_EQ(d.kind, M::Decision::Resolve);
  m.published(d, T0);
  EXPECT_EQ(m.decide(true, T0 + 250ms).kind, M::Decision::Wait);
  d = m.decide(true, T0 + 251ms);
  EXPECT_EQ(d.kind, M::Decision::Republish);
  EXPECT_EQ(d.frame, 3u);
  m.published(d, T0 + 251ms);
  EXPECT_EQ(m.decide(true, T0 + 400ms).kind, M::Decision::Wait);
  EXPECT_EQ(m.decide(false, T0 + 10s).kind, M::Decision::Wait);  // never without a scene
}

// A --frame-rate given with a recording must be the replay's rate (the recording's, times
// --speed live), within 1 %: the services step every frame with its period.
TEST(LabChecks, AFrameRateThatIsNotTheReplaysIsRefused) {
  EXPECT_EQ(godhand::svc::replayRateMismatch(0.0, 113.8, 1.0, "pinch.json"), "");     // none given
  EXPECT_EQ(godhand::svc::replayRateMismatch(113.8, 113.8, 1.0, "pinch.json"), "");
  EXPECT_EQ(godhand::svc::replayRateMismatch(114.9, 113.8, 1.0, "pinch.json"), "");   // within 1 %
  EXPECT_EQ(godhand::svc::replayRateMismatch(56.9, 113.8, 0.5, "pinch.json"), "");    // live at half speed
  const std::string off = godhand::svc::replayRateMismatch(30.0, 113.8, 1.0, "pinch.json");
  EXPECT_NE(off.find("--frame-rate 30 Hz: pinch.json replays at 113.8 Hz"), std::string::npos) << off;
  const std::string slow = godhand::svc::replayRateMismatch(113.8, 113.8, 0.5, "pinch.json");
  EXPECT_NE(slow.find("replays at 56.9 Hz here (its 113.8 Hz times --speed 0.5)"), std::string::npos) << slow;
}
