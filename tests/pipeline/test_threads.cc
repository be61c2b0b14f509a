// The hands' solvers on worker threads (PipelineParams::threads, core/pipeline/workers.h), and
// each solver's bodies' collision queries on threads of their own (PipelineParams::body_threads).
// Oracles: a determinism hash over a real two-hand recording on the bunny (poses of every God
// body, contact counts, forces and TOCs) that must be the same bit for bit for 1, 2 and 3
// threads of either kind; the Workers run every job exactly once, in a slot no other running
// job holds, and hand back a job's exception.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/files.h"
#include "leap/leap_recording.h"
#include "leap/retarget.h"
#include "pipeline/pipeline.h"
#include "pipeline/workers.h"
#include "scene/scene.h"
#include "scene/scene_file.h"
#include "../test_sanitized.h"

namespace godhand {
namespace {

std::uint64_t mix(std::uint64_t h, double d) {
  std::uint64_t bits;
  std::memcpy(&bits, &d, sizeof bits);
  return (h ^ bits) * 1099511628211ull;
}

std::uint64_t mixPose(std::uint64_t h, const Pose& P) {
  for (double d : {P.p.x(), P.p.y(), P.p.z(), P.q.w(), P.q.x(), P.q.y(), P.q.z()}) h = mix(h, d);
  return h;
}

struct RunResult {
  std::uint64_t hash = 1469598103934665603ull;
  long loads = 0;  ///< contacts, summed over frames and hands
  int threads = 0;
};

// confidence2 and the bunny at 0.25 m centred on its palms (acceptance.sh's twohands-bunny, where
// both hands press into it), with the pipeline's parameters for `threads`.
struct BunnyCase {
  leap::Recording rec = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/confidence2-49fps.json");
  Scene scene = meshScene({parseMeshSpec(std::string(GODHAND_DEPLOY_DIR) + "/meshes/stanford-bunny.obj:0.25")},
                          rec.meanPalmPosition(), meshFileLoader());
  PipelineParams params;
  explicit BunnyCase(int threads) {
    params.step.dt = 1.0 / rec.meanFrameRate();
    params.threads = threads;
  }
};

HandModel modelFile(const char* name) { return loadHandModel(std::string(GODHAND_MODELS_DIR) + "/" + name); }

// Every hand's poses and figures of the last step into the run's hash (with the frame's TOC where
// `with_toc`).
void addStep(const Pipeline& pipe, bool with_toc, RunResult* res) {
  for (int hand = 0; hand < 2; ++hand) {
    for (const Pose& P : pipe.poses(hand)) res->hash = mixPose(res->hash, P);
    const HandResult& r = pipe.result(hand);
    res->hash = mix(res->hash, r.force_N);
    if (with_toc) res->hash = mix(res->hash, r.diag.toc);
    res->hash = mix(res->hash, static_cast<double>(r.diag.contacts));
    res->loads += r.diag.contacts;
  }
}

// Both hands, the first 120 frames (40 under the sanitizers: the hands press into the bunny from
// the first frame on).
constexpr size_t kTwoHandFrames = test_support::kSanitized ? 40 : 120;
RunResult runTwoHands(int threads, int body_threads = 1) {
  BunnyCase c(threads);
  const HandModel right = modelFile("hand16_right.pbtxt"), left = modelFile("hand16_left.pbtxt");
  c.params.body_threads = body_threads;
  Pipeline pipe(c.scene, {&right, &left}, c.params);
  leap::Retargeter rt_right(right), rt_left(left);
  std::vector<Pose> tr, tl;
  std::vector<unsigned char> hr, hl;
  RunResult res;
  res.threads = pipe.params().threads;
  for (size_t k = 0; k < kTwoHandFrames && k < c.rec.frames().size(); ++k) {
    std::vector<HandInput> in(2);
    for (const leap::TrackedHand& h : c.rec.frames()[k].hands) {
      if (h.right) {
        rt_right.targets(h, &tr, &hr);
        in[0] = HandInput{true, tr.data(), hr.data()};
      } else {
        rt_left.targets(h, &tl, &hl);
        in[1] = HandInput{true, tl.data(), hl.data()};
      }
    }
    pipe.step(in);
    addStep(pipe, true, &res);
  }
  return res;
}

TEST(Threads, TwoHandsGiveTheSameResultOnOneTwoAndThreeThreads) {
  const RunResult one = runTwoHands(1), two = runTwoHands(2), three = runTwoHands(3);
  std::printf("[figure] two hands, %zu frames: hash %016llx on 1 thread, %016llx on 2, %016llx on 3 (%ld contacts)\n",
              kTwoHandFrames, static_cast<unsigned long long>(one.hash), static_cast<unsigned long long>(two.hash),
              static_cast<unsigned long long>(three.hash), one.loads);
  EXPECT_GT(one.loads, 0) << "the hands must touch the bunny, else the run shows little";
  EXPECT_EQ(one.hash, two.hash);
  EXPECT_EQ(one.hash, three.hash);
}

// A hand and a one-body tool in one pipeline: the tool has no collision world for a helper, so
// it keeps its body on its own thread while the hand's bodies go through the job share. Both
// thread counts run (the pipeline was once built to refuse such a pair) and agree bit for bit.
RunResult runHandAndTool(int threads) {
  BunnyCase c(threads);
  const HandModel right = modelFile("hand16_right.pbtxt"), tool = modelFile("tool1.pbtxt");
  Pipeline pipe(c.scene, {&right, &tool}, c.params);
  leap::Retargeter rt_right(right);
  std::vector<Pose> tr, tt(1);
  std::vector<unsigned char> hr, ht(1, 1);
  RunResult res;
  res.threads = pipe.params().threads;
  for (size_t k = 0; k < 60 && k < c.rec.frames().size(); ++k) {
    std::vector<HandInput> in(2);
    for (const leap::TrackedHand& h : c.rec.frames()[k].hands) {
      if (!h.right) continue;
      rt_right.targets(h, &tr, &hr);
      in[0] = HandInput{true, tr.data(), hr.data()};
      // The tool held 5 cm beside the palm target, pointing along it: into the bunny and out.
      tt[0] = tr[0];
      tt[0].p += Vec3(0.05, 0.0, 0.0);
      in[1] = HandInput{true, tt.data(), ht.data()};
    }
    pipe.step(in);
    addStep(pipe, false, &res);
  }
  return res;
}

TEST(Threads, AHandAndAOneBodyToolGiveTheSameResultOnOneAndTwoThreads) {
  const RunResult one = runHandAndTool(1), two = runHandAndTool(2);
  std::printf("[figure] hand and tool, 60 frames: hash %016llx on 1 thread, %016llx on 2 (%ld contacts)\n",
              static_cast<unsigned long long>(one.hash), static_cast<unsigned long long>(two.hash), one.loads);
  EXPECT_EQ(two.threads, 2);
  EXPECT_GT(one.loads, 0);
  EXPECT_EQ(one.hash, two.hash);
}

TEST(Threads, BodyThreadsGiveTheSameResultAsOne) {
  const RunResult one = runTwoHands(1, 1), two = runTwoHands(1, 2), three = runTwoHands(1, 3);
  std::printf("[figure] two hands, %zu frames, body threads 1/2/3: hash %016llx %016llx %016llx (%ld contacts)\n",
              kTwoHandFrames, static_cast<unsigned long long>(one.hash), static_cast<unsigned long long>(two.hash),
              static_cast<unsigned long long>(three.hash), one.loads);
  EXPECT_GT(one.loads, 0);
  EXPECT_EQ(one.hash, two.hash);
  EXPECT_EQ(one.hash, three.hash);
  EXPECT_EQ(one.hash, runTwoHands(2, 2).hash);  // both kinds at once
}

TEST(Threads, SlotsAreExclusiveAndInRange) {
  for (int threads : {1, 2, 3}) {
    Workers w(threads);
    std::vector<std::atomic<int>> busy(static_cast<size_t>(threads));
    for (auto& b : busy) b = 0;
    std::atomic<int> bad{0}, ran{0};
    for (int rep = 0; rep < 200; ++rep)
      w.runSlots(17, [&](int, int slot) {
        if (slot < 0 || slot >= threads || busy[static_cast<size_t>(slot)].fetch_add(1) != 0) ++bad;
        ++ran;
        if (slot >= 0 && slot < threads) --busy[static_cast<size_t>(slot)];
      });
    EXPECT_EQ(bad.load(), 0) << threads << " threads";
    EXPECT_EQ(ran.load(), 200 * 17);
  }
}

TEST(Threads, WorkersRunEveryJobExactlyOnce) {
  for (int threads : {1, 2, 4}) {
    Workers w(threads);
    EXPECT_EQ(w.threads(), threads);
    for (int n : {0, 1, 2, 3, 17}) {
      for (int rep = 0; rep < 200; ++rep) {
        std::vector<std::atomic<int>> count(static_cast<size_t>(n));
        for (auto& c : count) c = 0;
        w.run(n, [&](int i) { ++count[static_cast<size_t>(i)]; });
        for (int i = 0; i < n; ++i) ASSERT_EQ(count[static_cast<size_t>(i)].load(), 1) << "threads " << threads << " n " << n << " job " << i;
      }
    }
  }
}

// Calls in quick succession and calls after the other threads have given up polling and blocked
// (the two ways a thread waits for work; a lost wake-up would hang here until ctest's timeout).
TEST(Threads, WorkersWakeForQuickAndForLateCalls) {
  Workers w(3);
  std::atomic<long> sum{0};
  long expected = 0;
  for (int rep = 0; rep < 3000; ++rep) {
    w.run(5, [&](int i) { sum += i + 1; });
    expected += 15;
    if (rep % 500 == 499) std::this_thread::sleep_for(std::chrono::milliseconds(2));  // past the poll
  }
  EXPECT_EQ(sum.load(), expected);
}

TEST(Threads, AJobsExceptionComesBackAfterTheOthersRan) {
  for (int threads : {1, 2}) {
    Workers w(threads);
    std::atomic<int> ran{0};
    try {
      w.run(4, [&](int i) {
        ++ran;
        if (i == 1) throw std::runtime_error("job 1 failed");
      });
      ADD_FAILURE() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "job 1 failed");
    }
    EXPECT_EQ(ran.load(), 4);
    ran = 0;
    w.run(3, [&](int) { ++ran; });  // usable after
    EXPECT_EQ(ran.load(), 3);
  }
  EXPECT_THROW(Workers(0), std::invalid_argument);
  PipelineParams p;
  p.threads = 0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p.threads = 1;
  p.body_threads = 0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

// JobShare: owners on their own threads post jobs, idle threads help. Every job of every call
// runs exactly once; the owner's jobs run in slot 0 on the owner's thread, a helper's in a slot
// 1 .. threads − 1 that no other running job of the same owner holds; run() returns only after
// all of its jobs have finished (a job still running on a helper would be caught by the count).
// (Also with the lanes weighted apart, where an owner takes a heavier lane's jobs between its own.)
TEST(Threads, JobShareRunsEveryJobOnceInExclusiveSlots) {
  for (int threads : {2, 3, 4}) {
    for (int owners : {1, threads - 1, threads}) {
     for (bool weighted : {false, true}) {
      if (owners < 1) continue;
      JobShare share(owners, threads);
      if (weighted)
        for (int o = 0; o < owners; ++o) share.setWeight(o, (o * 7) % 3 + 0.5 * o);
      constexpr int kCalls = 100, kJobs = 17;
      // Per owner: how often each job ran, and which slots are held right now.
      std::vector<std::vector<std::atomic<int>>> count(static_cast<size_t>(owners));
      std::vector<std::vector<std::atomic<int>>> held(static_cast<size_t>(owners));
      for (int o = 0; o < owners; ++o) {
        count[static_cast<size_t>(o)] = std::vector<std::atomic<int>>(kJobs);
        held[static_cast<size_t>(o)] = std::vector<std::atomic<int>>(static_cast<size_t>(threads));
        for (auto& c : count[static_cast<size_t>(o)]) c = 0;
        for (auto& h : held[static_cast<size_t>(o)]) h = 0;
      }
      std::atomic<int> bad_slot{0}, overlap{0}, unfinished_at_return{0}, by_helpers{0}, owners_done{0};
      auto body = [&](int t) {
        if (t < owners) {
          const size_t o = static_cast<size_t>(t);
          const std::thread::id me = std::this_thread::get_id();
          for (int call = 0; call < kCalls; ++call) {
            std::atomic<int> running{0}, helped{0};
            const std::function<void(int, int)> job = [&](int i, int slot) {
              ++running;
              // The owner's first job waits (up to 1 ms) for a helper to take one: the calls
              // then overlap wherever a helper thread gets a core.
              if (slot == 0 && i == 0) {
                const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(1);
                while (helped.load() == 0 && std::chrono::steady_clock::now() < until) std::this_thread::yield();
              }
              if (slot != 0) ++helped;
              if (slot < 0 || slot >= threads) {
                ++bad_slot;
              } else {
                if ((slot == 0) != (std::this_thread::get_id() == me)) ++bad_slot;  // slot 0: the owner's thread
                if (held[o][static_cast<size_t>(slot)].fetch_add(1) != 0) ++overlap;
                if (slot != 0) ++by_helpers;
                for (volatile int k = 0; k < 200; ++k) {}
                --held[o][static_cast<size_t>(slot)];
              }
              ++count[o][static_cast<size_t>(i)];
              --running;
            };
            share.run(t, t, kJobs, job);
            if (running.load() != 0) ++unfinished_at_return;
          }
          ++owners_done;
        }
        share.help(t, [&] { return owners_done.load() >= owners; });
      };
      std::vector<std::thread> pool;
      for (int t = 1; t < threads; ++t) pool.emplace_back(body, t);
      body(0);
      for (std::thread& th : pool) th.join();
      for (int o = 0; o < owners; ++o)
        for (int i = 0; i < kJobs; ++i)
          ASSERT_EQ(count[static_cast<size_t>(o)][static_cast<size_t>(i)].load(), kCalls)
              << threads << " threads, " << owners << " owners: owner " << o << " job " << i;
      EXPECT_EQ(bad_slot.load(), 0);
      EXPECT_EQ(overlap.load(), 0) << threads << " threads, " << owners << " owners";
      EXPECT_EQ(unfinished_at_return.load(), 0);
      std::printf("[figure] JobShare, %d threads, %d owners%s: %d of %d jobs run by helpers\n", threads, owners,
                  weighted ? " weighted apart" : "", by_helpers.load(), owners * kCalls * kJobs);
     }
    }
  }
}

// setWeight: the owner of a light lane takes what is left of a heavier posted lane before each
// of its own jobs (the light hand's thread helps the heavy hand first), and never the other way
// round. The heavy owner's first job holds until the light owner has taken the rest of its jobs
// (or 2 s pass: then the order below fails).
TEST(Threads, JobShareLightOwnerTakesAHeavierLanesJobsFirst) {
  for (bool weighted : {true, false}) {
    JobShare share(2, 2);
    if (weighted) {
      share.setWeight(0, 10.0);
      share.setWeight(1, 1.0);
    }
    std::atomic<bool> heavy_posted{false};
    std::atomic<int> heavy_by_light{0};
    std::mutex log_mutex;
    std::vector<std::pair<int, int>> light_log;  // (lane, job) as the light owner's thread ran them
    const auto deadline = [] { return std::chrono::steady_clock::now() + std::chrono::seconds(2); };
    std::thread light([&] {
      const auto until = deadline();
      while (!heavy_posted.load() && std::chrono::steady_clock::now() < until) std::this_thread::yield();
      share.run(1, 1, 4, [&](int i, int) {
        std::lock_guard<std::mutex> lock(log_mutex);
        light_log.emplace_back(1, i);
      });
    });
    const std::thread::id heavy_id = std::this_thread::get_id();
    share.run(0, 0, 4, [&](int i, int) {
      if (std::this_thread::get_id() != heavy_id) {
        std::lock_guard<std::mutex> lock(log_mutex);
        light_log.emplace_back(0, i);
        ++heavy_by_light;
        return;
      }
      if (i != 0) return;
      heavy_posted = true;
      // Weighted: wait for the light owner to take jobs 1-3; not weighted, it never does (a
      // short wait shows that it does not).
      const auto until = weighted ? deadline() : std::chrono::steady_clock::now() + std::chrono::milliseconds(50);
      while (heavy_by_light.load() < 3 && std::chrono::steady_clock::now() < until) std::this_thread::yield();
    });
    light.join();
    // The time the light owner lent to the heavy lane is told apart (and then reset).
    const double lent_light = share.takeLent(1), lent_heavy = share.takeLent(0);
    EXPECT_EQ(lent_heavy, 0.0);
    EXPECT_EQ(share.takeLent(1), 0.0);
    if (weighted) {
      const std::vector<std::pair<int, int>> expected{{0, 1}, {0, 2}, {0, 3}, {1, 0}, {1, 1}, {1, 2}, {1, 3}};
      EXPECT_EQ(light_log, expected);
      EXPECT_GT(lent_light, 0.0);
    } else {
      EXPECT_EQ(lent_light, 0.0);
      // Equal weights: the light owner runs only its own jobs from run() (none of the heavy lane's).
      for (const auto& e : light_log) EXPECT_EQ(e.first, 1);
      EXPECT_EQ(light_log.size(), 4u);
    }
  }
  JobShare share(2, 2);
  EXPECT_THROW(share.setWeight(2, 1.0), std::invalid_argument);
  EXPECT_THROW(share.setWeight(-1, 1.0), std::invalid_argument);
  EXPECT_THROW(share.takeLent(2), std::invalid_argument);
}

// The owner's slot is 0 and only the owner's thread runs in it; helpers run elsewhere.
TEST(Threads, JobShareOwnerRunsInSlotZero) {
  JobShare share(1, 2);
  std::atomic<bool> stop{false};
  std::atomic<int> wrong{0};
  const std::thread::id owner_id = std::this_thread::get_id();
  std::thread helper([&] { share.help(1, [&] { return stop.load(); }); });
  for (int call = 0; call < 500; ++call) {
    const std::function<void(int, int)> job = [&](int, int slot) {
      const bool on_owner = std::this_thread::get_id() == owner_id;
      if (on_owner != (slot == 0)) ++wrong;
      if (slot != 0 && slot != 1) ++wrong;
    };
    share.run(0, 0, 9, job);
  }
  stop = true;
  helper.join();
  EXPECT_EQ(wrong.load(), 0);
}

TEST(Threads, JobShareHandsBackAJobsExceptionAfterTheOthersRan) {
  JobShare share(1, 2);
  std::atomic<bool> stop{false};
  std::thread helper([&] { share.help(1, [&] { return stop.load(); }); });
  for (int rep = 0; rep < 50; ++rep) {
    std::atomic<int> ran{0};
    const std::function<void(int, int)> job = [&](int i, int) {
      ++ran;
      if (i == 3) throw std::runtime_error("job 3 failed");
    };
    try {
      share.run(0, 0, 8, job);
      ADD_FAILURE() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "job 3 failed");
    }
    EXPECT_EQ(ran.load(), 8);
  }
  std::atomic<int> ran{0};
  share.run(0, 0, 5, [&](int, int) { ++ran; });  // usable after
  EXPECT_EQ(ran.load(), 5);
  stop = true;
  helper.join();
  EXPECT_THROW(JobShare(0, 2), std::invalid_argument);
  EXPECT_THROW(JobShare(1, 0), std::invalid_argument);
  EXPECT_THROW(JobShare(1, 65), std::invalid_argument);
  EXPECT_THROW(share.run(1, 0, 1, [](int, int) {}), std::invalid_argument);
  EXPECT_THROW(share.run(0, 2, 1, [](int, int) {}), std::invalid_argument);
}

}  // namespace
}  // namespace godhand
