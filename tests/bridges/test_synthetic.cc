// Synthetic scripted motions (bridges/synthetic): parsing with line-numbered errors, determinism,
// and the scripted press / slide / lift / dropout / teleport / NaN burst through the real
// in-process pipeline against a table: the God hand stays on the surface while its target goes
// through, slides with it, follows again in free space, is held while lost and not pushed
// through by a jump.
#include <cmath>
#include <functional>
#include <cstdio>
#include <fstream>
#include <gtest/gtest.h>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "leap/retarget.h"
#include "model/hand_model.h"
#include "physics/physics_world.h"
#include "pipeline/pipeline.h"
#include "pipeline/stages.h"
#include "scene/scene_file.h"
#include "source/recording.h"
#include "source/tracker_source.h"
#include "synthetic/synthetic.h"

using namespace godhand;

namespace {
std::string dataPath(const std::string& f) { return std::string(GODHAND_TEST_DATA_DIR) + "/synthetic/" + f; }
std::string readTextFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
/// The right hand of `rec` through the in-process pipeline on `scene` (16-body model, Bullet at
/// 240 Hz): after each frame `each(i, pipe, hand, targets)`, hand the frame's tracked right hand
/// (nullptr when none) and targets its retargeting. Returns the pipeline's counters.
using FrameFn = std::function<void(size_t, Pipeline&, const bridges::TrackedHand*, const std::vector<Pose>&)>;
PipelineCounters driveRightHand(const Scene& scene, const bridges::LoadedRecording& rec, const FrameFn& each = {}) {
  const HandModel right = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  PipelineParams params;
  params.step.dt = 1.0 / rec.mean_rate_hz;
  Pipeline pipe(scene, {&right}, params, physicsParamsFor(rec.mean_rate_hz, 240.0));
  const leap::Retargeter rt(right);
  std::vector<Pose> tg;
  std::vector<unsigned char> has;
  for (size_t i = 0; i < rec.frames.size(); ++i) {
    const bridges::TrackedHand* h = bridges::handOfSide(rec.frames[i], true);
    HandInput in;
    if (h) {
      rt.targets(*h, &tg, &has);
      in = {true, tg.data(), has.data()};
    }
    pipe.step({in});
    if (each) each(i, pipe, h, tg);
  }
  return pipe.counters();
}
}  // namespace

TEST(Synthetic, ParseErrorsNameTheLine) {
  const char* bad[][2] = {
      {"hello\n", ":1: first line"},
      {"godhand-synthetic 1\nmove right 1 0 0\n", ":2: 'move' takes 5 values"},
      {"godhand-synthetic 1\nstart middle 0 0 0\n", ":2: side must be"},
      {"godhand-synthetic 1\nstart right 0 0 0\nrate 50\n", ":3: rate must come before"},
      {"godhand-synthetic 1\nrate 0\n", ":2: rate must be"},
      {"godhand-synthetic 1\nstart right 0 nan 0\n", "is not a finite number"},
      {"godhand-synthetic 1\nmove right 1 0 0 0\n", ":2: 'move' of the right hand before its 'start'"},
      {"godhand-synthetic 1\nstart right 0 0 0\ncurl right 1 2\n", ":3: curl fraction"},
      {"godhand-synthetic 1\nstart right 0 0 0\njump right\n", ":3: unknown command 'jump'"},
      {"godhand-synthetic 1\n# nothing\n", "no hand"},
      {"godhand-synthetic 1\nstart right 0 0 0\nroll right 1 200\n", ":3: roll angle"},
      {"godhand-synthetic 1\nstart right 0 0 0\nroll right 1\n", ":3: 'roll' takes 3 values"},
      {"godhand-synthetic 1\nstart right 0 0 0 ; start left 0 0 0\n", ":2: only move, curl and roll run together"},
      {"godhand-synthetic 1\nstart right 0 0 0\nmove right 1 0 0 0 ; curl right 1 1\n", ":3: one motion per hand"},
      {"godhand-synthetic 1\nstart right 0 0 0\nmove right 1 0 0 0 ;\n", ":3: empty motion"},
      {"godhand-synthetic 1\nstart right 0 0 0\nmove right 1 0 0 0 ; move left 1 0 0 0\n", ":3: 'move' of the left hand before"},
      {"godhand-synthetic 1\nrate 10000\nstart right 0 0 0\nhold 30\nhold 3600\n", ":5: the script makes more than 360000 frames"},
      {"godhand-synthetic 1\nrate 10000\nstart right 0 0 0\nlost right 3600\n", ":4: the script makes more than 360000 frames"},
  };
  for (const auto& b : bad) {
    try {
      synthetic::parseScript(b[0], "s.txt");
      ADD_FAILURE() << "accepted: " << b[0];
    } catch (const synthetic::ScriptError& e) {
      EXPECT_NE(std::string(e.what()).find(b[1]), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
}

TEST(Synthetic, DeterministicAndKilohertz) {
  const auto a = bridges::loadRecording(dataPath("kilohertz.txt"));
  const auto b = bridges::loadRecording(dataPath("kilohertz.txt"));
  EXPECT_EQ(a.format, "synthetic");
  ASSERT_EQ(a.frames.size(), 1000u);
  EXPECT_NEAR(a.mean_rate_hz, 1000.0, 1e-6);
  EXPECT_TRUE(a.has_left && a.has_right);
  for (size_t i = 0; i < a.frames.size(); ++i) {
    ASSERT_EQ(a.frames[i].hands.size(), b.frames[i].hands.size());
    for (size_t k = 0; k < a.frames[i].hands.size(); ++k) {
      EXPECT_EQ(a.frames[i].hands[k].X_W_palm.p, b.frames[i].hands[k].X_W_palm.p);
      EXPECT_EQ(a.frames[i].hands[k].joints_W, b.frames[i].hands[k].joints_W);
    }
  }
  // The hands are where the script says and are hands the models accept.
  const auto& last = a.frames.back();
  ASSERT_EQ(last.hands.size(), 2u);
  EXPECT_NEAR((bridges::handOfSide(last, true)->X_W_palm.p - Vec3(0.15, 0, 0.25)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((bridges::handOfSide(last, false)->X_W_palm.p - Vec3(-0.15, 0, 0.25)).norm(), 0.0, 1e-12);
  for (const char* m : {"hand16_right", "hand6_right"}) {
    const leap::Retargeter rt(loadHandModel(std::string(GODHAND_MODELS_DIR) + "/" + m + ".pbtxt"));
    std::vector<Pose> t;
    std::vector<unsigned char> d;
    EXPECT_EQ(rt.targets(*bridges::handOfSide(last, true), &t, &d), 0) << m;
  }
}

TEST(Synthetic, PressSlideLiftDropoutTeleportNanThroughThePipeline) {
  const Scene scene = loadScene(dataPath("table.pbtxt"));
  const bridges::LoadedRecording rec = bridges::loadRecording(dataPath("press_slide_lift.txt"));
  std::printf("[info] %s\n", rec.rejections.c_str());
  EXPECT_NE(rec.rejections.find("NaN/Inf 5"), std::string::npos) << rec.rejections;
  const double surface = 0.11;
  double pen = 0.0, min_palm_z_pressed = 1.0, held_move = 0.0;
  double x_after_slide = 0.0, free_err_after_lift = 1.0;
  size_t untracked = 0;
  Vec3 last_tracked_pose = Vec3::Zero();
  driveRightHand(scene, rec, [&](size_t i, Pipeline& pipe, const bridges::TrackedHand* h, const std::vector<Pose>& tg) {
    if (!h) ++untracked;
    if (!pipe.started(0)) return;
    pen = std::max(pen, pipe.penetration(0));
    const Vec3 palm = pipe.poses(0)[0].p;
    const double t = static_cast<double>(i) / rec.mean_rate_hz;
    if (t > 0.9 && t < 1.1) min_palm_z_pressed = std::min(min_palm_z_pressed, palm.z());  // target below the top
    if (i == 160) x_after_slide = palm.x();                                              // end of the slide
    if (i == 209 && h) free_err_after_lift = (palm - tg[0].p).norm();                    // lifted, free space
    if (h) last_tracked_pose = palm;
    else held_move = std::max(held_move, (palm - last_tracked_pose).norm());
  });
  std::printf("[figure] synthetic.press.penetration_max_m = %.3g\n", pen);
  std::printf("[figure] synthetic.press.palm_min_z_m = %.4f (surface %.3f)\n", min_palm_z_pressed, surface);
  std::printf("[figure] synthetic.slide.palm_x_m = %.4f (target 0.1)\n", x_after_slide);
  std::printf("[figure] synthetic.lift.free_error_m = %.3g\n", free_err_after_lift);
  EXPECT_LE(pen, 1e-4);                         // the launcher's --check margin
  EXPECT_GT(min_palm_z_pressed, surface);       // held on the surface, not pushed through
  EXPECT_GT(x_after_slide, 0.08);               // slid along with the target
  EXPECT_LT(free_err_after_lift, 1e-3);         // follows again in free space
  EXPECT_EQ(untracked, 20u + 5u);               // 0.2 s lost at 100 Hz, plus the 5 NaN frames
  EXPECT_EQ(held_move, 0.0);                    // a lost hand is held
}

// Glitches (issue 11: "a palm at 1e305 m or a 10-frame glitch to 1 km is accepted silently"):
// every source drops hands outside the tracking volume and single-frame jumps beyond the speed
// limit, counted; the hand is kept again once it is back (or after 0.5 s: a re-acquisition).
TEST(Synthetic, GlitchesBeyondTheVolumeOrTheSpeedLimitAreDropped) {
  const bridges::LoadedRecording r = bridges::loadRecording(dataPath("glitches.txt"));
  std::printf("[info] %s\n", r.rejections.c_str());
  EXPECT_NE(r.rejections.find("hand jumps beyond the speed limit 10"), std::string::npos) << r.rejections;
  EXPECT_NE(r.rejections.find("hands outside the tracking volume 1"), std::string::npos) << r.rejections;
  size_t with_hand = 0;
  for (const auto& f : r.frames) {
    with_hand += f.hands.size();
    for (const auto& h : f.hands) EXPECT_LT(h.X_W_palm.p.norm(), 1.0);
  }
  EXPECT_EQ(with_hand, r.frames.size() - 11);
  // A looser limit keeps the 5 m glitch (so the test is not vacuous), a tighter volume drops all.
  bridges::SourceOptions o;
  o.max_speed_mps = 1000.0;
  const bridges::LoadedRecording loose = bridges::loadRecording(dataPath("glitches.txt"), o);
  EXPECT_EQ(loose.rejections.find("speed limit"), std::string::npos) << loose.rejections;
  o.max_abs_position_m = 0.1;
  EXPECT_THROW(bridges::loadRecording(dataPath("glitches.txt"), o), bridges::SourceError);  // no tracked hands
}

// A jump in a frame whose timestamp equals the last one's is judged as if 1 ms had passed: five
// 0.4 m teleports of pinch's hand are dropped whether their frames carry their own timestamps or
// repeat the previous frame's (found by review: the repeated ones were let through, no time having
// passed to judge them by). Frames that repeat a timestamp without a jump are kept.
TEST(Synthetic, AJumpIsDroppedWhenItsFrameRepeatsTheLastTimestamp) {
  const std::string pinch = std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json";
  for (const bool repeat : {false, true}) {
    nlohmann::json d = nlohmann::json::parse(std::ifstream(pinch));
    auto& F = d["frames"];
    for (int i = 150; i < 160; i += 2) {
      auto shift = [](nlohmann::json& v) { v[0] = v[0].get<double>() + 400.0; };
      for (auto& h : F[i]["hands"])
        for (const char* k : {"palmPosition", "stabilizedPalmPosition", "sphereCenter"})
          if (h.contains(k)) shift(h[k]);
      for (auto& p : F[i]["pointables"])
        for (const char* k : {"tipPosition", "dipPosition", "pipPosition", "mcpPosition", "stabilizedTipPosition", "btipPosition", "carpPosition"})
          if (p.contains(k)) shift(p[k]);
      if (repeat) F[i]["timestamp"] = F[i - 1]["timestamp"];
    }
    F[100]["timestamp"] = F[99]["timestamp"];  // a repeat without a jump
    const std::string path = ::testing::TempDir() + (repeat ? "/repeat.json" : "/teleport.json");
    std::ofstream(path) << d.dump();
    const bridges::LoadedRecording r = bridges::loadRecording(path);
    EXPECT_NE(r.rejections.find("hand jumps beyond the speed limit 5"), std::string::npos) << repeat << ": " << r.rejections;
    std::remove(path.c_str());
  }
}

// Grasp a box between two hands (issue 11): `roll` turns the hands palm to palm, ';' moves them
// at once. The script gives a right and a left hand, tracked in every frame, deterministic, whose
// palms face each other across the box (tests/data/synthetic/grasp_box.pbtxt: sides at x = ±0.04)
// and close on it from opposite sides, then lift together.
TEST(Synthetic, GraspBoxTwoHandsCloseFromOppositeSides) {
  const auto a = bridges::loadRecording(dataPath("grasp_box.txt"));
  const auto b = bridges::loadRecording(dataPath("grasp_box.txt"));
  EXPECT_EQ(a.format, "synthetic");
  EXPECT_TRUE(a.has_left && a.has_right);
  EXPECT_NEAR(a.mean_rate_hz, 100.0, 1e-6);
  ASSERT_EQ(a.frames.size(), b.frames.size());
  ASSERT_GT(a.frames.size(), 500u);
  for (size_t i = 0; i < a.frames.size(); ++i) {
    ASSERT_EQ(a.frames[i].timestamp_us, b.frames[i].timestamp_us);
    ASSERT_EQ(a.frames[i].hands.size(), 2u) << "frame " << i;  // both tracked throughout
    ASSERT_EQ(b.frames[i].hands.size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
      EXPECT_EQ(a.frames[i].hands[k].right, b.frames[i].hands[k].right);
      EXPECT_EQ(a.frames[i].hands[k].X_W_palm.p, b.frames[i].hands[k].X_W_palm.p);
      EXPECT_EQ(a.frames[i].hands[k].X_W_palm.q.coeffs(), b.frames[i].hands[k].X_W_palm.q.coeffs());
      EXPECT_EQ(a.frames[i].hands[k].joints_W, b.frames[i].hands[k].joints_W);
    }
  }
  const Vec3 box_centre(0.0, 0.03, 0.195);
  const double half_x = 0.04;
  // The palm side of the hand is the palm frame's -z (the fingers flex that way).
  auto palmNormal = [](const bridges::TrackedHand& h) -> Vec3 { return -(h.X_W_palm.q * Vec3::UnitZ()); };
  double r_x_prev = 1.0, l_x_prev = -1.0, r_min = 1.0, l_max = -1.0, facing_min = 1.0, z_rise = 0.0;
  size_t facing_frames = 0;
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const bridges::TrackedHand* r = bridges::handOfSide(a.frames[i], true);
    const bridges::TrackedHand* l = bridges::handOfSide(a.frames[i], false);
    ASSERT_TRUE(r && l);
    const Vec3 pr = r->X_W_palm.p, pl = l->X_W_palm.p;
    EXPECT_GT(pr.x(), 0.0);  // the right hand stays on +X, the left on -X: opposite sides
    EXPECT_LT(pl.x(), 0.0);
    EXPECT_EQ(pr.z(), pl.z()) << "frame " << i;      // they move up and down together
    EXPECT_EQ(pr.x(), -pl.x()) << "frame " << i;     // mirror images about the box's plane x = 0
    r_min = std::min(r_min, pr.x());
    l_max = std::max(l_max, pl.x());
    z_rise = std::max(z_rise, pr.z() - a.frames[0].hands[0].X_W_palm.p.z());
    const double t = static_cast<double>(i) / a.mean_rate_hz;
    if (t > 0.6 && t < 4.0) {  // turned palm to palm (after the roll, before the release)
      ++facing_frames;
      facing_min = std::min({facing_min, palmNormal(*r).dot(-Vec3::UnitX()), palmNormal(*l).dot(Vec3::UnitX())});
    }
    if (t > 0.7 && t < 2.0) {  // approach and close: the palms move toward the box, never away
      EXPECT_LE(pr.x(), r_x_prev + 1e-15) << "frame " << i;
      EXPECT_GE(pl.x(), l_x_prev - 1e-15) << "frame " << i;
    }
    r_x_prev = pr.x();
    l_x_prev = pl.x();
  }
  std::printf("[figure] synthetic.grasp.palm_target_inside_face_m = %.4f (palm surface 0.013 from the centre)\n",
              half_x + 0.013 - r_min);
  EXPECT_GT(facing_frames, 300u);
  EXPECT_GT(facing_min, 1.0 - 1e-9);                       // palm normals along -X (right) and +X (left)
  EXPECT_NEAR(r_min, 0.043, 1e-12);                        // closest: palm surfaces 1 cm into the box's sides
  EXPECT_NEAR(l_max, -0.043, 1e-12);
  EXPECT_LT(r_min - 0.013, half_x);                        // targets inside the box: a squeeze
  EXPECT_NEAR(z_rise, 0.05, 1e-12);                        // the scripted lift
  // Started clear of the box: each palm's surface (0.013 from its centre) beyond the box's side.
  const bridges::TrackedHand* r0 = bridges::handOfSide(a.frames[0], true);
  const bridges::TrackedHand* l0 = bridges::handOfSide(a.frames[0], false);
  EXPECT_GT(r0->X_W_palm.p.x() - 0.013, box_centre.x() + half_x);
  EXPECT_LT(l0->X_W_palm.p.x() + 0.013, box_centre.x() - half_x);
  // The retargeter accepts both turned hands.
  for (const char* m : {"hand16_right", "hand16_left"}) {
    const bool right = std::string(m).find("right") != std::string::npos;
    const leap::Retargeter rt(loadHandModel(std::string(GODHAND_MODELS_DIR) + "/" + m + ".pbtxt"));
    std::vector<Pose> t;
    std::vector<unsigned char> d;
    EXPECT_EQ(rt.targets(*bridges::handOfSide(a.frames[150], right), &t, &d), 0) << m;
  }
}

// Gaps in a recording's timestamps (a tracker that wrote nothing while it saw no hand, or frames
// dropped as bad input): each is left out of the rate; a gap of 1 s or more is a silence, as a
// live source's, replayed as frames without hands at the rate, so that the hand is lost and
// re-acquired; a shorter one (or a tracker that slowed down while it saw the hand) is stepped as
// one frame; a recording without gaps is replayed unchanged.
namespace {
std::string writeEdited(const std::string& name, const std::function<void(nlohmann::json&)>& edit) {
  nlohmann::json j = nlohmann::json::parse(readTextFile(std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json"));
  edit(j["frames"]);
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path) << j.dump();
  return path;
}
std::uint64_t reacquisitionsOf(const bridges::LoadedRecording& rec) {
  return driveRightHand(loadScene(std::string(GODHAND_TEST_DATA_DIR) + "/synthetic/table.pbtxt"), rec).reacquisitions;
}
}  // namespace

TEST(Sources, GapsInTheTimestampsAreLeftOutOfTheRateAndSilencesReplayedWithoutHands) {
  const bridges::LoadedRecording whole = bridges::loadRecording(std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json");
  EXPECT_EQ(whole.gaps, 0u);  // Leap's own dropped frames (2–3 intervals) are no gaps
  EXPECT_EQ(whole.filled_frames, 0u);
  ASSERT_GT(whole.frames.size(), 300u);
  // 1. 150 frames (~1.3 s) not written: a silence, filled.
  double t99 = 0, t250 = 0;
  const auto silence = bridges::loadRecording(writeEdited("pinch_silence.json", [&](nlohmann::json& frames) {
    t99 = frames[99]["timestamp"].get<double>();
    t250 = frames[250]["timestamp"].get<double>();
    frames.erase(frames.begin() + 100, frames.begin() + 250);
  }));
  EXPECT_EQ(silence.gaps, 1u);
  EXPECT_EQ(silence.pauses, 1u);
  EXPECT_NEAR(static_cast<double>(silence.filled_frames), 150.0, 3.0);  // round(gap / period) − 1
  EXPECT_EQ(silence.frames.size(), whole.frames.size() - 150 + silence.filled_frames);
  size_t empty = 0;
  for (size_t i = 0; i < silence.frames.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(silence.frames[i].timestamp_us, silence.frames[i - 1].timestamp_us) << i;
    }
    if (silence.frames[i].hands.empty()) {
      ++empty;
      EXPECT_GT(silence.frames[i].timestamp_us, static_cast<std::int64_t>(t99)) << i;
      EXPECT_LT(silence.frames[i].timestamp_us, static_cast<std::int64_t>(t250)) << i;
    }
  }
  EXPECT_EQ(empty, silence.filled_frames);
  EXPECT_NEAR(silence.mean_rate_hz, whole.mean_rate_hz, 0.02 * whole.mean_rate_hz);
  EXPECT_EQ(reacquisitionsOf(silence), 1u);  // lost in the silence, re-acquired after it
  // 2. 50 frames (~0.44 s) not written: a gap under a live source's silence, stepped as one
  // frame; the rate is still the tracker's (the plain mean would be 15 % low).
  const auto gap = bridges::loadRecording(
      writeEdited("pinch_gap.json", [](nlohmann::json& frames) { frames.erase(frames.begin() + 100, frames.begin() + 150); }));
  EXPECT_EQ(gap.gaps, 1u);
  EXPECT_EQ(gap.filled_frames, 0u);
  EXPECT_EQ(gap.frames.size(), whole.frames.size() - 50);
  EXPECT_NEAR(gap.mean_rate_hz, whole.mean_rate_hz, 0.02 * whole.mean_rate_hz);
  EXPECT_EQ(reacquisitionsOf(gap), 0u);
  // 3. A tracker that slowed down to 9 Hz for 60 frames while it saw the hand: no hand lost.
  const auto slow = bridges::loadRecording(writeEdited("pinch_slow.json", [](nlohmann::json& frames) {
    std::vector<std::int64_t> t0;
    for (const auto& f : frames) t0.push_back(f["timestamp"].get<std::int64_t>());
    std::int64_t t = t0[100];
    for (size_t i = 101; i < frames.size(); ++i) {
      t += i <= 160 ? 110000 : t0[i] - t0[i - 1];  // µs
      frames[i]["timestamp"] = t;
    }
  }));
  EXPECT_EQ(slow.filled_frames, 0u);
  EXPECT_EQ(slow.frames.size(), whole.frames.size());
  for (const bridges::TrackerFrame& f : slow.frames) EXPECT_FALSE(f.hands.empty());
  EXPECT_EQ(reacquisitionsOf(slow), 0u);
}

// What a record is differs by source; received + not played is the file's records at any point
// of a replay: a synthetic script's records are hand samples (its frames hold up to two), and the
// frames filled into a silence come from no record.
TEST(Sources, NotPlayedCountsTheRecordsOfTheFramesNotPlayed) {
  bridges::TrackerFrame f;
  auto whole = bridges::openSource(dataPath("press_slide_lift.txt"));
  while (whole->next(&f)) {
  }
  const bridges::SourceStats all = whole->stats();
  EXPECT_EQ(all.not_played, 0u);
  auto part = bridges::openSource(dataPath("press_slide_lift.txt"));
  std::uint64_t hands = 0;
  for (int i = 0; i < 100; ++i) {
    ASSERT_TRUE(part->next(&f));
    hands += f.hands.size();
  }
  const bridges::SourceStats st = part->stats();
  EXPECT_EQ(st.received + st.not_played, all.received);
  EXPECT_EQ(st.received, hands + st.rejected);  // the samples played, and every rejected one
  EXPECT_GT(st.not_played, 0u);
  // A silence of 150 frames in a Leap recording, filled with frames without hands: not records.
  const std::string silent = writeEdited("pinch_silence_np.json", [](nlohmann::json& frames) {
    frames.erase(frames.begin() + 100, frames.begin() + 250);
  });
  auto s = bridges::openSource(silent);
  std::uint64_t played = 0, filled = 0;
  while (played < 200 && s->next(&f)) {
    ++played;
    if (f.hands.empty()) ++filled;
  }
  ASSERT_GT(filled, 0u);
  const bridges::SourceStats ss = s->stats();
  EXPECT_EQ(ss.received, ss.frames - filled + ss.rejected);  // the filled frames received nothing
  EXPECT_EQ(ss.received + ss.not_played, bridges::loadRecording(silent).frames.size() - bridges::loadRecording(silent).filled_frames);
}

TEST(Sources, SilencesThatWouldTakeMillionsOfFramesAreRefused) {
  const std::string src = std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json";
  nlohmann::json j = nlohmann::json::parse(readTextFile(src));
  auto& frames = j["frames"];
  // Ten days of nothing after frame 200 (at ~114 Hz: ~10^8 frames to fill).
  for (size_t i = 200; i < frames.size(); ++i)
    frames[i]["timestamp"] = frames[i]["timestamp"].get<double>() + 864e9;
  const std::string path = ::testing::TempDir() + "/pinch_ten_days.json";
  {
    std::ofstream out(path);
    out << j.dump();
  }
  try {
    bridges::loadRecording(path);
    ADD_FAILURE() << "a ten-day pause was filled";
  } catch (const bridges::SourceError& e) {
    EXPECT_NE(std::string(e.what()).find("more than 2000000 frames without hands"), std::string::npos) << e.what();
  }
}
