// ART DTrack reader (bridges/dtrack) and the sources behind openSource (bridges/source):
// strict parsing with every rejection counted by reason, the mapping onto TrackedHand checked
// against the Leap recordings the sample streams were made from (an independent reader of the
// same motion), live UDP on loopback, format detection by content, raw record / replay.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <gtest/gtest.h>
#include <random>
#include <sstream>
#include <thread>

#include "common/files.h"
#include "dtrack/dtrack.h"
#include "leap/leap_recording.h"
#include "leap/retarget.h"
#include "model/hand_model.h"
#include "source/live.h"
#include "source/recording.h"
#include "source/tracker_source.h"

using namespace godhand;
using namespace godhand::dtrack;
namespace br = godhand::bridges;

namespace {

std::string dataPath(const std::string& f) { return std::string(GODHAND_TEST_DATA_DIR) + "/dtrack/" + f; }
std::string leapPath(const std::string& f) { return std::string(GODHAND_DEPLOY_DIR) + "/recordings/" + f; }

std::string slurp(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void figure(const std::string& name, double v) { std::printf("[figure] %s = %.6g\n", name.c_str(), v); }

std::vector<std::string> sample(const std::string& f) { return splitDatagrams(slurp(dataPath(f))); }

double angleBetween(const Quat& a, const Quat& b) { return a.angularDistance(b); }

std::string tmpFile(const std::string& name) {
  const char* t = std::getenv("TMPDIR");
  return std::string(t ? t : "/tmp") + "/godhand-dtrack-test-" + std::to_string(::getpid()) + "-" + name;
}

}  // namespace

TEST(DtrackParse, SampleDatagramFields) {
  const auto dgs = sample("pinch.dtrack");
  ASSERT_EQ(dgs.size(), 307u);
  Datagram d;
  const ParseResult r = parseDatagram(dgs[0], &d);
  ASSERT_TRUE(r.ok) << r.detail;
  EXPECT_EQ(d.frame, 132892u);
  EXPECT_TRUE(d.has_ts);
  EXPECT_DOUBLE_EQ(d.ts, 36000.0);
  EXPECT_EQ(d.bodies_calibrated, 2);
  EXPECT_EQ(d.hands_calibrated, 2);
  ASSERT_EQ(d.bodies.size(), 1u);
  ASSERT_EQ(d.hands.size(), 1u);
  const Hand& h = d.hands[0];
  EXPECT_EQ(h.id, 1);
  EXPECT_TRUE(h.right);
  ASSERT_EQ(h.fingers.size(), 5u);
  EXPECT_NEAR(h.p_mm.x(), 38.4326, 1e-12);
  // Column-wise: the first column is b0 b1 b2.
  EXPECT_NEAR(h.R(0, 0), -0.1930179, 1e-6);
  EXPECT_NEAR(h.R(1, 0), 0.6797487, 1e-6);
  EXPECT_NEAR(h.R(0, 1), 0.9809697, 1e-6);
  EXPECT_NEAR((h.R.transpose() * h.R - Mat3::Identity()).norm(), 0.0, 1e-12);  // re-orthonormalised
  EXPECT_NEAR(h.fingers[0].ro, 9.8438, 1e-12);
  EXPECT_NEAR(h.fingers[0].li, 42.0, 1e-12);
  // The 6d body repeats the hand pose.
  EXPECT_NEAR((d.bodies[0].p_mm - h.p_mm).norm(), 0.0, 1e-9);
  // Every datagram of both samples parses.
  for (const char* f : {"pinch.dtrack", "confidence2-49fps.dtrack"})
    for (const std::string& g : sample(f)) {
      const ParseResult rr = parseDatagram(g, &d);
      EXPECT_TRUE(rr.ok) << f << ": " << rr.detail;
    }
}

TEST(DtrackParse, TsTwoAndUnknownLines) {
  Datagram d;
  ParseResult r = parseDatagram("fr 7\r\nts2 1764547200 250000 1800\r\nzz 0000\r\n6d 0\r\ngl 0\r\n", &d);
  ASSERT_TRUE(r.ok) << r.detail;
  EXPECT_TRUE(d.has_ts2);
  EXPECT_EQ(d.ts2_us, 1764547200LL * 1000000 + 250000);
  EXPECT_EQ(d.latency_us, 1800);
  EXPECT_NEAR(d.ts, 1764547200 % 86400 + 0.25, 1e-9);  // the SDK's ts from ts2
  EXPECT_EQ(d.unknown_lines, 1u);
  // 6d with a 3-value position block (DTrack3 may send 3) parses too.
  r = parseDatagram("fr 8\r\n6d 1 [0 1.000][1 2 3][1 0 0 0 1 0 0 0 1]\r\n", &d);
  ASSERT_TRUE(r.ok) << r.detail;
  EXPECT_EQ(d.bodies.at(0).p_mm, Vec3(1, 2, 3));
}

TEST(DtrackParse, EveryFaultIsRejectedWithItsReason) {
  const std::string good = sample("pinch.dtrack")[0];
  auto replace = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  struct Case {
    const char* what;
    std::string bytes;
    Reject reason;
  } cases[] = {
      {"nan in a finger block", replace("9.8438", "nan"), Reject::kNotFinite},
      {"inf in the hand position", replace("[38.4326 -54.9802 155.3320][", "[38.4326 inf 155.3320]["), Reject::kNotFinite},
      {"-nan in 6d", replace("-101.1315", "-nan"), Reject::kNotFinite},
      {"non-orthonormal hand rotation", replace("-0.1930179 0.6797487 0.7075915 0.9809697", "-0.3930179 0.6797487 0.7075915 0.9809697"), Reject::kNotOrthonormal},
      {"reflection", "fr 1\r\n6d 1 [0 1.000][1 2 3][1 0 0 0 1 0 0 0 -1]\r\n", Reject::kNotOrthonormal},
      {"nf 4", replace("[1 1.000 1 5]", "[1 1.000 1 4]"), Reject::kOutOfRange},
      {"nf 6 (the SDK also fails it)", replace("[1 1.000 1 5]", "[1 1.000 1 6]"), Reject::kOutOfRange},
      {"lr 2", replace("[1 1.000 1 5]", "[1 1.000 2 5]"), Reject::kOutOfRange},
      {"hand id >= glcal", replace("[1 1.000 1 5]", "[7 1.000 1 5]"), Reject::kOutOfRange},
      {"palm at 1e305 mm", replace("[38.4326 -54.9802 155.3320][", "[1e305 -54.9802 155.3320]["), Reject::kOutOfRange},
      {"1e999 (overflows)", replace("[38.4326 -54.9802 155.3320][", "[1e999 -54.9802 155.3320]["), Reject::kOutOfRange},
      {"negative phalanx length", replace("11.1562", "-11.1562"), Reject::kOutOfRange},
      {"oversized", good + std::string(40000, 'z') + "\r\n", Reject::kOversized},
      {"missing final CR LF", good.substr(0, good.size() - 2), Reject::kIncomplete},
      {"glcal without gl", good.substr(0, good.find("gl 1")), Reject::kIncomplete},
      {"does not start with fr", "xx 1\r\n" + good, Reject::kParse},
      {"two spaces", replace("[1 1.000 1 5]", "[1  1.000 1 5]"), Reject::kParse},
      {"extra value in a block", replace("[1 1.000 1 5]", "[1 1.000 1 5 0]"), Reject::kParse},
      {"missing value", replace("[9.8438 11.1562 ", "[9.8438 "), Reject::kParse},
      {"block spacing '] ['", replace("][0.4346", "] [0.4346"), Reject::kParse},
      {"hand count larger than the hands", replace("gl 1 [", "gl 2 ["), Reject::kParse},
      {"NUL byte", replace("fr 132892", std::string("fr 13\0" "2892", 9)), Reject::kParse},
      {"LF only", "fr 1\ngl 0\n", Reject::kParse},
      {"empty", "", Reject::kParse},
      {"second fr line", good + "fr 3\r\n", Reject::kParse},
      {"trailing text after the hands", replace("33.6002]\r\n", "33.6002]x\r\n"), Reject::kParse},
      {"letters in a number", replace("9.8438", "9.8x38"), Reject::kParse},
  };
  for (const Case& c : cases) {
    Datagram d;
    const ParseResult r = parseDatagram(c.bytes, &d);
    EXPECT_FALSE(r.ok) << c.what;
    EXPECT_EQ(static_cast<int>(r.reason), static_cast<int>(c.reason)) << c.what << ": got " << reasonName(r.reason) << " (" << r.detail << ")";
    EXPECT_FALSE(r.detail.empty()) << c.what;
    EXPECT_EQ(r.detail.find('\n'), std::string::npos) << c.what;
  }
}

TEST(DtrackDecoder, EveryTruncationOfAStreamDatagramIsRejected) {
  // The SDK accepts a datagram cut at a line boundary and keeps the old hands tracked; the
  // decoder knows the lines this stream carries, so no prefix of a datagram is ever accepted.
  const auto dgs = sample("confidence2-49fps.dtrack");
  Decoder dec;
  br::TrackerFrame f;
  ASSERT_TRUE(dec.feed(dgs[0], 0, &f)) << dec.lastDetail();
  size_t tried = 0;
  for (size_t i = 1; i < 40; ++i) {
    const std::string& g = dgs[i];
    for (size_t k = 1; k < g.size(); ++k) {
      ++tried;
      EXPECT_FALSE(dec.feed(g.substr(0, k), 0, &f)) << "datagram " << i << " cut at " << k << " of " << g.size();
    }
    ASSERT_TRUE(dec.feed(g, 0, &f)) << dec.lastDetail();  // the whole one still goes through
  }
  EXPECT_EQ(dec.accepted(), 40u);
  EXPECT_EQ(dec.rejectedTotal(), tried);
  EXPECT_EQ(dec.rejected(Reject::kStale), 0u);
  figure("dtrack.truncations_rejected", static_cast<double>(tried));
}

TEST(DtrackDecoder, StaleDuplicateRestartAndGarbage) {
  const auto dgs = sample("pinch.dtrack");
  Decoder dec;
  br::TrackerFrame f;
  ASSERT_TRUE(dec.feed(dgs[1], 0, &f));
  EXPECT_FALSE(dec.feed(dgs[1], 0, &f));  // duplicate
  EXPECT_FALSE(dec.feed(dgs[0], 0, &f));  // reordered (older)
  EXPECT_EQ(dec.rejected(Reject::kStale), 2u);
  ASSERT_TRUE(dec.feed(dgs[2], 0, &f));
  EXPECT_EQ(f.frame_id, 132894);
  // Random bytes (dtrack-send --garbage) are never accepted.
  std::mt19937 rng(11);
  for (int i = 0; i < 2000; ++i) {
    std::string g(dgs[0].size(), '\0');
    for (char& c : g) c = static_cast<char>(rng() & 0xff);
    if (i % 2) g.replace(0, 3, "fr ");  // even when it starts like a datagram
    EXPECT_FALSE(dec.feed(g, 0, &f)) << i;
  }
  // A frame counter far back is a tracker restart, not a stale frame.
  std::string restarted = dgs[3];
  restarted.replace(0, restarted.find("\r\n"), "fr 5");
  EXPECT_TRUE(dec.feed(restarted, 0, &f)) << dec.lastDetail();
  EXPECT_EQ(dec.restarts(), 1u);
  EXPECT_EQ(dec.accepted(), 3u);
  EXPECT_EQ(dec.received(), 2000u + 5u);
  const std::string s = dec.summary();
  EXPECT_NE(s.find("stale/duplicate frame 2"), std::string::npos) << s;
  EXPECT_NE(s.find("parse error"), std::string::npos) << s;
}

TEST(DtrackDecoder, OneDatagramFarAheadStopsTrackingForAQuarterSecondAtMost) {
  // pinch.dtrack's datagrams at 100 Hz (arrival 10 ms apart); after the 20th, one copy whose frame
  // counter is 999 ahead (a spoofed datagram: within the restart window, so the real ones behind
  // it read as stale). Found by review: every real datagram was then rejected for 1,000 frames.
  const auto dgs = sample("pinch.dtrack");
  ASSERT_GT(dgs.size(), 80u);
  auto frameOf = [](const std::string& d) { return std::stoull(d.substr(3, d.find("\r\n") - 3)); };
  Decoder dec;
  br::TrackerFrame f;
  std::int64_t t = 0;
  for (int i = 0; i < 20; ++i, t += 10000) ASSERT_TRUE(dec.feed(dgs[static_cast<size_t>(i)], t, &f)) << i;
  std::string spoof = dgs[20];
  spoof.replace(0, spoof.find("\r\n"), "fr " + std::to_string(frameOf(dgs[19]) + 999));
  ASSERT_TRUE(dec.feed(spoof, t, &f));
  t += 10000;
  int rejected = 0, first_accepted = -1;
  for (int i = 20; i < 80; ++i, t += 10000) {
    if (dec.feed(dgs[static_cast<size_t>(i)], t, &f)) {
      if (first_accepted < 0) first_accepted = i;
      EXPECT_EQ(static_cast<std::uint64_t>(f.frame_id), frameOf(dgs[static_cast<size_t>(i)]));
    } else {
      ASSERT_LT(first_accepted, 0) << "a real datagram rejected after the stream was followed again: " << i;
      ++rejected;
    }
  }
  EXPECT_EQ(dec.refollows(), 1u);
  EXPECT_EQ(rejected, 24);  // arrivals 10 … 240 ms after the spoofed one: stale; at 250 ms followed again
  EXPECT_EQ(first_accepted, 44);
  EXPECT_EQ(dec.restarts(), 0u);
  EXPECT_NE(dec.summary().find("followed again"), std::string::npos) << dec.summary();
}

// A datagram of a sample with its frame counter and its `ts` line (time of day, s) replaced.
static std::string withFrameAndTs(std::string d, std::uint64_t frame, double ts) {
  d.replace(0, d.find("\r\n"), "fr " + std::to_string(frame));
  const size_t at = d.find("\r\nts ") + 2;
  char buf[40];
  std::snprintf(buf, sizeof buf, "ts %.6f", ts);
  d.replace(at, d.find("\r\n", at) - at, buf);
  return d;
}

// A stream that passed midnight (ts 86399.9 … then 0.0 …: a day added to the times) keeps its day
// when it is followed again after a datagram far ahead, and across a tracker restart (the ts is the
// time of day either way). Both used to set the day back to 0: the hands' times jumped back 24 h.
TEST(DtrackDecoder, TheDayGoesOnAfterAFollowAgainAndARestart) {
  const auto dgs = sample("pinch.dtrack");
  ASSERT_GT(dgs.size(), 60u);
  constexpr std::int64_t kDay = 86400LL * 1000000LL;
  Decoder dec;
  br::TrackerFrame f;
  std::int64_t t = 0;
  std::uint64_t frame = 5000;
  long cs = 8639995;  // ts in hundredths: 50 ms before midnight, 100 Hz
  auto tsNow = [&] { return static_cast<double>(cs % 8640000) / 100.0; };
  std::int64_t last_time = 0;
  auto feed = [&](size_t i, bool expect_accepted) {
    const bool ok = dec.feed(withFrameAndTs(dgs[i], frame, tsNow()), t, &f);
    EXPECT_EQ(ok, expect_accepted) << i << ": " << dec.lastDetail();
    if (ok) {
      EXPECT_GT(f.timestamp_us, last_time) << i;  // never back
      EXPECT_NEAR(static_cast<double>(f.timestamp_us), (86399.95 + 0.01 * static_cast<double>(i)) * 1e6, 1.0) << i;
      last_time = f.timestamp_us;
    }
    ++frame;
    t += 10000;
    ++cs;
  };
  for (size_t i = 0; i < 20; ++i) feed(i, true);  // across midnight at i = 5
  ASSERT_GE(last_time, kDay);
  // A spoofed datagram far ahead …
  ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[20], frame + 900, tsNow()), t, &f));
  t += 10000;
  // … the real ones behind it are stale for a quarter second, then followed again, the same day.
  for (size_t i = 20; i < 46; ++i) feed(i, i >= 44);
  EXPECT_EQ(dec.refollows(), 1u);
  // A tracker restart (its frame counter starts again): the day goes on.
  frame = 1;
  for (size_t i = 46; i < 50; ++i) feed(i, true);
  EXPECT_EQ(dec.restarts(), 1u);
}

// A spoofed datagram whose ts reads as a midnight (1 s past it, in the afternoon) adds a day; the
// next real datagram takes it back, whichever way the spoofed one was accepted: far ahead within
// the restart window (the real ones stale, then followed again), far ahead beyond it (the real
// ones read as a tracker restart), or far behind (read as a restart itself). Found by review: the
// first fix kept the false day in the second case.
TEST(DtrackDecoder, AFalseMidnightIsTakenBack) {
  const auto dgs = sample("pinch.dtrack");
  ASSERT_GT(dgs.size(), 50u);
  for (std::uint64_t spoof_frame : {std::uint64_t{1000}, std::uint64_t{5000}, std::uint64_t{1000000000}, std::uint64_t{1}}) {
    SCOPED_TRACE(spoof_frame);
    Decoder dec;
    br::TrackerFrame f;
    std::int64_t t = 0;
    const std::uint64_t base = 2000;
    for (int i = 0; i < 10; ++i, t += 10000)
      ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[static_cast<size_t>(i)], base + static_cast<std::uint64_t>(i), 50000.0 + 0.01 * i), t, &f));
    ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[10], spoof_frame, 1.0), t, &f));
    EXPECT_EQ(f.timestamp_us, (86400LL + 1LL) * 1000000LL);  // read as the next day (nothing tells it apart yet)
    t += 10000;
    int accepted_at = -1;
    for (int i = 10; i < 40 && accepted_at < 0; ++i, t += 10000)
      if (dec.feed(withFrameAndTs(dgs[static_cast<size_t>(i)], base + static_cast<std::uint64_t>(i), 50000.0 + 0.01 * i), t, &f))
        accepted_at = i;
    ASSERT_GE(accepted_at, 0);
    EXPECT_NEAR(static_cast<double>(f.timestamp_us), (50000.0 + 0.01 * accepted_at) * 1e6, 1.0);  // the same day again
    ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[40], base + 40, 50000.4), t, &f));
    EXPECT_NEAR(static_cast<double>(f.timestamp_us), 50000.4e6, 1.0);
  }
}

// A tracker restarted across midnight (its last datagram at 23:59:59.9, its first after the
// restart at 00:00:01): the day goes on (before the review's fix: back 24 h).
TEST(DtrackDecoder, ARestartAcrossMidnightIsTheNextDay) {
  const auto dgs = sample("pinch.dtrack");
  Decoder dec;
  br::TrackerFrame f;
  ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[0], 90000, 86399.8), 0, &f));
  ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[1], 90001, 86399.9), 10000, &f));
  ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[2], 1, 1.0), 1200000, &f));
  EXPECT_EQ(dec.restarts(), 1u);
  EXPECT_EQ(f.timestamp_us, (86400LL + 1LL) * 1000000LL);
  ASSERT_TRUE(dec.feed(withFrameAndTs(dgs[3], 2, 1.01), 1210000, &f));
  EXPECT_EQ(f.timestamp_us, 86401010000LL);
}

TEST(DtrackDecoder, QualityMinusOneIsNotTracked) {
  std::string g = sample("pinch.dtrack")[0];
  g.replace(g.find("[1 1.000 1 5]"), 13, "[1 -1.000 1 5]");
  Decoder dec;
  br::TrackerFrame f;
  ASSERT_TRUE(dec.feed(g, 0, &f)) << dec.lastDetail();
  EXPECT_TRUE(f.hands.empty());
  EXPECT_EQ(dec.handsNotTracked(), 1u);
}

// A 6d body is a rigid body's pose (a tool): in the sample streams body 1 is the hand target, so
// its mapped pose must be the hand's palm pose (no palm offset) up to the fixed change of axes
// between DTrack's hand frame and godhand's palm frame (R_palm = R_body [Y X -Z], right hand),
// with and without a calibration (tracker pose, Y-up room). Bodies with quality -1 are dropped
// and counted.
TEST(DtrackMapping, SixDofBodyIsThePoseOfItsTarget) {
  MapOptions plain, calibrated;
  calibrated.y_up = true;
  calibrated.X_WT = Pose{Vec3(0.3, -1.2, 0.8), Quat(Eigen::AngleAxisd(0.7, Vec3(0.2, 0.3, 0.9).normalized()))};
  for (const MapOptions& o : {plain, calibrated}) {
    Decoder dec(ParseLimits{}, o);
    br::TrackerFrame f;
    int frames = 0;
    for (const std::string& g : sample("pinch.dtrack")) {
      if (!dec.feed(g, 0, &f)) continue;
      ASSERT_EQ(f.bodies.size(), 1u);
      ASSERT_EQ(f.hands.size(), 1u);
      const br::TrackedBody& b = f.bodies[0];
      const br::TrackedHand& h = f.hands[0];
      EXPECT_EQ(b.id, 1);
      EXPECT_NEAR((b.X_WB.p - h.X_W_palm.p).norm(), 0.0, 1e-12);
      const Mat3 Rb = b.X_WB.q.toRotationMatrix();
      Mat3 expected;
      expected << Rb.col(1), Rb.col(0), -Rb.col(2);
      EXPECT_NEAR((expected - h.X_W_palm.q.toRotationMatrix()).norm(), 0.0, 1e-9);
      ++frames;
    }
    EXPECT_EQ(frames, 307);
  }
  std::string g = sample("pinch.dtrack")[0];
  g.replace(g.find("[1 1.000]"), 9, "[1 -1.000]");
  Decoder dec;
  br::TrackerFrame f;
  ASSERT_TRUE(dec.feed(g, 0, &f)) << dec.lastDetail();
  EXPECT_TRUE(f.bodies.empty());
  EXPECT_EQ(dec.bodiesNotTracked(), 1u);
  EXPECT_NE(dec.summary().find("6d bodies with quality < 0 (not tracked) 1"), std::string::npos) << dec.summary();
}

// The sample streams were made from the bundled Leap recordings: same motion, same world frame.
// The Leap reader is the oracle. The residual comes from DTrack's printed precision (4 decimals
// for fingers: 1e-4 mm, 1e-4° ≈ 1.7e-6 rad over ~50 mm levers), so a few micrometres.
TEST(DtrackVersusLeap, SameHandsAndTargetsAsTheLeapReader) {
  for (const auto& [dt, lp] : {std::pair<const char*, const char*>{"pinch.dtrack", "pinch.json"}, {"confidence2-49fps.dtrack", "confidence2-49fps.json"}}) {
    const br::LoadedRecording d = br::loadRecording(dataPath(dt));
    const leap::Recording l = leap::Recording::load(leapPath(lp));
    ASSERT_EQ(d.frames.size(), l.frames().size()) << dt;
    EXPECT_EQ(d.format, "dtrack");
    EXPECT_NEAR(d.mean_rate_hz, l.meanFrameRate(), 1e-6 * l.meanFrameRate()) << dt;
    EXPECT_LT((d.mean_palm_W - l.meanPalmPosition()).norm(), 1e-6) << dt;
    const HandModel m16r = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
    const HandModel m16l = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_left.pbtxt");
    const HandModel m6r = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand6_right.pbtxt");
    const HandModel m6l = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand6_left.pbtxt");
    const leap::Retargeter r16[2] = {leap::Retargeter(m16l), leap::Retargeter(m16r)};
    const leap::Retargeter r6[2] = {leap::Retargeter(m6l), leap::Retargeter(m6r)};
    double palm_p = 0, palm_q = 0, joint = 0, tgt_p = 0, tgt_q = 0, conf = 0;
    size_t hands = 0;
    for (size_t i = 0; i < d.frames.size(); ++i) {
      const br::TrackerFrame& a = d.frames[i];
      const br::TrackerFrame& b = l.frames()[i];
      ASSERT_EQ(a.frame_id, b.frame_id);
      ASSERT_EQ(a.timestamp_us - d.frames[0].timestamp_us, b.timestamp_us - l.frames()[0].timestamp_us) << dt << " frame " << i;
      ASSERT_EQ(a.hands.size(), b.hands.size()) << dt << " frame " << i;
      for (const br::TrackedHand& hb : b.hands) {
        const br::TrackedHand* ha = br::handOfSide(a, hb.right);
        ASSERT_NE(ha, nullptr);
        ++hands;
        palm_p = std::max(palm_p, (ha->X_W_palm.p - hb.X_W_palm.p).norm());
        palm_q = std::max(palm_q, angleBetween(ha->X_W_palm.q, hb.X_W_palm.q));
        conf = std::max(conf, std::abs(ha->confidence - 1.0));  // DTrack2's qu is "unused", printed 1.000
        for (int fi = 0; fi < 5; ++fi)
          for (int k = 0; k < 4; ++k)
            joint = std::max(joint, (ha->joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)] -
                                     hb.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)]).norm());
        for (const leap::Retargeter* rt : {&r16[hb.right ? 1 : 0], &r6[hb.right ? 1 : 0]}) {
          std::vector<Pose> ta, tb;
          std::vector<unsigned char> da, db;
          rt->targets(*ha, &ta, &da);
          rt->targets(hb, &tb, &db);
          ASSERT_EQ(da, db);
          for (size_t k = 0; k < ta.size(); ++k) {
            tgt_p = std::max(tgt_p, (ta[k].p - tb[k].p).norm());
            tgt_q = std::max(tgt_q, angleBetween(ta[k].q, tb[k].q));
          }
        }
      }
    }
    const std::string tag = std::string("dtrack_vs_leap.") + dt;
    figure(tag + ".hands", static_cast<double>(hands));
    figure(tag + ".palm_position_max_m", palm_p);
    figure(tag + ".palm_rotation_max_rad", palm_q);
    figure(tag + ".joint_position_max_m", joint);
    figure(tag + ".target_position_max_m", tgt_p);
    figure(tag + ".target_rotation_max_rad", tgt_q);
    EXPECT_GT(hands, 100u);
    EXPECT_LT(palm_p, 1e-6) << dt;    // positions printed to 1e-4 mm
    EXPECT_LT(palm_q, 1e-5) << dt;    // rotations printed to 7 decimals
    EXPECT_LT(joint, 2e-5) << dt;     // finger rotations to 7 decimals, angles to 1e-5°
    EXPECT_LT(tgt_p, 5e-5) << dt;
    EXPECT_LT(tgt_q, 1e-3) << dt;
    EXPECT_EQ(conf, 0.0);
  }
}

TEST(DtrackMapping, ThreeFingerHandsOffsetAndYUp) {
  const std::string g = sample("pinch.dtrack")[0];
  Datagram d;
  ASSERT_TRUE(parseDatagram(g, &d).ok);
  Hand h5 = d.hands[0];
  Hand h3 = h5;
  h3.fingers.resize(3);
  MapOptions o;
  const br::TrackedHand t5 = mapHand(h5, o), t3 = mapHand(h3, o);
  for (int f = 0; f < 3; ++f)
    for (int k = 0; k < 4; ++k) EXPECT_EQ(t5.joints_W[static_cast<size_t>(f)][static_cast<size_t>(k)], t3.joints_W[static_cast<size_t>(f)][static_cast<size_t>(k)]);
  const Vec3 step = t3.joints_W[2][0] - t3.joints_W[1][0];
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR((t3.joints_W[3][static_cast<size_t>(k)] - t3.joints_W[2][static_cast<size_t>(k)] - step).norm(), 0.0, 1e-12);
    EXPECT_NEAR((t3.joints_W[4][static_cast<size_t>(k)] - t3.joints_W[2][static_cast<size_t>(k)] - 2 * step).norm(), 0.0, 1e-12);
  }
  // The 3-finger hand drives the 16-body model without degenerate segments.
  const leap::Retargeter rt(loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt"));
  std::vector<Pose> tg;
  std::vector<unsigned char> dr;
  EXPECT_EQ(rt.targets(t3, &tg, &dr), 0);
  // Back-of-hand offset: 2 cm toward the palm is along −z of the palm frame (z = back of the hand).
  o.palm_offset_m = Vec3(0.0, 0.0, 0.02);
  const br::TrackedHand to = mapHand(h5, o);
  const Vec3 moved = to.X_W_palm.p - t5.X_W_palm.p;
  EXPECT_NEAR((moved - (-0.02) * (t5.X_W_palm.q * Vec3::UnitZ())).norm(), 0.0, 1e-12);
  EXPECT_EQ(to.joints_W[1][3], t5.joints_W[1][3]);  // the fingers do not move
  // Toward the thumb: a right hand's thumb is on −x.
  o.palm_offset_m = Vec3(0.0, 0.01, 0.0);
  EXPECT_NEAR(((mapHand(h5, o).X_W_palm.p - t5.X_W_palm.p) - (-0.01) * (t5.X_W_palm.q * Vec3::UnitX())).norm(), 0.0, 1e-12);
  // A Y-up ("powerwall") room: (x, y, z) -> (x, −z, y); the palm frame stays a rotation.
  MapOptions y;
  y.y_up = true;
  EXPECT_NEAR((roomToWorld(Vec3(1000, 2000, 3000), y) - Vec3(1, -3, 2)).norm(), 0.0, 1e-12);
  Hand hy = h5;
  Mat3 A;
  A << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // Z-up room -> Y-up room (inverse of the conversion)
  hy.p_mm = A * h5.p_mm;
  hy.R = A * h5.R;
  const br::TrackedHand ty = mapHand(hy, y);
  EXPECT_NEAR((ty.X_W_palm.p - t5.X_W_palm.p).norm(), 0.0, 1e-12);
  EXPECT_NEAR(angleBetween(ty.X_W_palm.q, t5.X_W_palm.q), 0.0, 1e-9);
  EXPECT_NEAR((ty.joints_W[0][3] - t5.joints_W[0][3]).norm(), 0.0, 1e-12);
}

TEST(Sources, FormatDetectedByContentAndCalibration) {
  // A .dtrack stream under a .json name is still read as DTrack.
  const std::string p = tmpFile("named.json");
  { std::ofstream(p, std::ios::binary) << slurp(dataPath("pinch.dtrack")); }
  EXPECT_EQ(br::detectFormat(p), "dtrack");
  EXPECT_EQ(br::detectFormat(leapPath("pinch.json")), "leap");
  auto s = br::openSource(p);
  EXPECT_EQ(s->remaining(), 307);
  EXPECT_NE(s->describe().find("dtrack replay"), std::string::npos);
  // Calibration: a tracker pose moves every hand by it; a hand map keeps only the listed ids.
  br::SourceOptions o;
  o.X_WT = br::parsePose("0.1,0.2,0.3,0,0,90");
  o.hand_sides = br::parseHandSides("1:right");
  auto c = br::openSource(p, o);
  br::TrackerFrame f0, f1;
  ASSERT_TRUE(s->next(&f0));
  ASSERT_TRUE(c->next(&f1));
  ASSERT_EQ(f1.hands.size(), 1u);
  EXPECT_NEAR((f1.hands[0].X_W_palm.p - (o.X_WT * f0.hands[0].X_W_palm.p)).norm(), 0.0, 1e-12);
  o.hand_sides = br::parseHandSides("0:left");  // pinch's hand is id 1: dropped and counted
  EXPECT_THROW(br::loadRecording(p, o), br::SourceError);
  // Bad input: one line each.
  for (const char* bad : {"1,2", "1,2,3,0,0,0,0", "a,b,c", "1,2,3,nan,0,0"}) EXPECT_THROW(br::parsePose(bad), br::SourceError) << bad;
  for (const char* bad : {"1:up", "x:left", "1:left,1:right", "-1:left"}) EXPECT_THROW(br::parseHandSides(bad), br::SourceError) << bad;
  for (const char* bad : {"dtrack://127.0.0.1:0", "dtrack://localhost:5000", "dtrack://127.0.0.1:99999", "vrpn://x", "/nonexistent.dtrack"})
    EXPECT_THROW(br::openSource(bad), br::SourceError) << bad;
  const std::string junk = tmpFile("junk.bin");
  { std::ofstream(junk) << "hello\n"; }
  try {
    br::openSource(junk);
    ADD_FAILURE() << "junk accepted";
  } catch (const br::SourceError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown recording format"), std::string::npos) << e.what();
  }
  std::remove(p.c_str());
  std::remove(junk.c_str());
}

TEST(Sources, LoadRecordingEveryFormat) {
  const br::LoadedRecording l = br::loadRecording(leapPath("confidence2-49fps.json"));
  EXPECT_EQ(l.format, "leap");
  EXPECT_EQ(l.frames.size(), 171u);
  EXPECT_TRUE(l.has_left && l.has_right);
  EXPECT_NE(l.rejections.find("frames"), std::string::npos);
  const br::LoadedRecording d = br::loadRecording(dataPath("confidence2-49fps.dtrack"));
  EXPECT_EQ(d.frames.size(), 171u);
  EXPECT_NEAR(d.mean_rate_hz, l.mean_rate_hz, 1e-6);
  EXPECT_EQ(d.rejections, "datagrams 171/171 accepted; rejected: none");
  EXPECT_THROW(br::loadRecording("dtrack://127.0.0.1:5000"), br::SourceError);
}

TEST(Sources, RawRecordingReplaysTheSameStreamWithItsFaults) {
  // Record a faulty stream (good, garbage, duplicate, truncated, nan), replay it, compare with
  // a decoder fed directly.
  const auto dgs = sample("pinch.dtrack");
  std::vector<std::string> stream;
  for (size_t i = 0; i < 60; ++i) {
    stream.push_back(dgs[i]);
    if (i % 7 == 3) stream.push_back(std::string("\x01\x02\r\n\r\n@ 1 2\n", 12));  // looks like record syntax
    if (i % 11 == 5) stream.push_back(dgs[i]);
    if (i % 13 == 2) stream.push_back(dgs[i].substr(0, dgs[i].size() / 2));
  }
  const std::string p = tmpFile("rec.raw");
  {
    br::RawWriter w(p, "dtrack");
    for (size_t i = 0; i < stream.size(); ++i) w.write(stream[i], static_cast<std::int64_t>(i) * 1000000);
    EXPECT_TRUE(w.ok());
  }
  EXPECT_EQ(br::detectFormat(p), "raw");
  Decoder direct;
  std::vector<br::TrackerFrame> want;
  br::TrackerFrame f;
  for (const std::string& g : stream)
    if (direct.feed(g, 0, &f)) want.push_back(f);
  const br::LoadedRecording got = br::loadRecording(p);
  ASSERT_EQ(got.frames.size(), want.size());
  EXPECT_EQ(got.frames.size(), 60u);
  for (size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(got.frames[i].frame_id, want[i].frame_id);
    ASSERT_EQ(got.frames[i].hands.size(), want[i].hands.size());
    for (size_t k = 0; k < want[i].hands.size(); ++k) EXPECT_EQ(got.frames[i].hands[k].X_W_palm.p, want[i].hands[k].X_W_palm.p);
  }
  EXPECT_EQ(got.rejections, direct.summary());
  // A cut raw file is a one-line error.
  const std::string cut = tmpFile("cut.raw");
  { std::ofstream(cut, std::ios::binary) << slurp(p).substr(0, 500); }
  EXPECT_THROW(br::loadRecording(cut), br::SourceError);
  std::remove(p.c_str());
  std::remove(cut.c_str());
}

// A replay reads its whole file when it is opened; an ingest killed (or cut by --frames) after k
// frames received what it played: the rest is not played, neither received nor rejected (it was
// counted received, so that received != accepted + rejected in the launch report's source block).
TEST(Sources, AReplayCutShortReceivedWhatItPlayedTheRestIsNotPlayed) {
  br::TrackerFrame f;
  auto s = br::openSource(dataPath("pinch.dtrack"));  // 307 datagrams, every one good
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(s->next(&f));
  br::SourceStats st = s->stats();
  EXPECT_EQ(st.frames, 100u);
  EXPECT_EQ(st.rejected, 0u);
  EXPECT_EQ(st.received, 100u);  // was 307: the 207 never played counted as received
  EXPECT_EQ(st.not_played, 207u);
  EXPECT_EQ(st.not_played_beyond_limit, 0u);
  // A frame taken but not used (the ingest stopped before publishing it) is not played again,
  // once: a second unplay() takes nothing more back.
  ASSERT_TRUE(s->next(&f));
  EXPECT_EQ(s->stats().frames, 101u);
  s->unplay();
  s->unplay();
  st = s->stats();
  EXPECT_EQ(st.frames, 100u);
  EXPECT_EQ(st.received, 100u);
  EXPECT_EQ(st.not_played, 207u);
  ASSERT_TRUE(s->next(&f));  // and it is the next one played
  EXPECT_EQ(s->stats().frames, 101u);
  while (s->next(&f)) {
  }
  st = s->stats();
  EXPECT_EQ(st.received, 307u);  // played to the end: every record received
  EXPECT_EQ(st.frames, 307u);
  EXPECT_EQ(st.not_played, 0u);
  // --frames 50: the frames after the limit are never played.
  auto limited = br::openSource(dataPath("pinch.dtrack"), 50);
  while (limited->next(&f)) {
  }
  st = limited->stats();
  EXPECT_EQ(st.frames, 50u);
  EXPECT_EQ(st.received, 50u);
  EXPECT_EQ(st.not_played, 257u);
  EXPECT_EQ(st.not_played_beyond_limit, 257u);
  // A stream with faults (rejected datagrams are read and checked when the file is opened: the
  // whole file's rejections count): received = accepted + rejected at any point, and received +
  // not played = the datagrams of the file.
  const auto dgs = sample("pinch.dtrack");
  std::vector<std::string> stream;
  for (size_t i = 0; i < 60; ++i) {
    stream.push_back(dgs[i]);
    if (i % 7 == 3) stream.push_back("garbage\r\n");
    if (i % 11 == 5) stream.push_back(dgs[i]);  // a duplicate: stale
  }
  const std::string p = tmpFile("faulty.raw");
  {
    br::RawWriter w(p, "dtrack");
    for (size_t i = 0; i < stream.size(); ++i) w.write(stream[i], static_cast<std::int64_t>(i) * 1000000);
    ASSERT_TRUE(w.ok());
  }
  auto faulty = br::openSource(p);
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(faulty->next(&f));
  st = faulty->stats();
  EXPECT_EQ(st.rejected, stream.size() - 60);
  EXPECT_EQ(st.received, st.frames + st.rejected);
  EXPECT_EQ(st.received + st.not_played, stream.size());
  EXPECT_EQ(st.not_played, 40u);
  std::remove(p.c_str());
}

TEST(Sources, LiveUdpOnLoopbackNeverBlocks) {
  // A free port: bind port 0, read it, release it.
  int port = 0;
  {
    const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    socklen_t len = sizeof a;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    port = ntohs(a.sin_port);
    ::close(fd);
  }
  auto src = br::openSource("dtrack://127.0.0.1:" + std::to_string(port));
  EXPECT_TRUE(src->live());
  EXPECT_EQ(src->remaining(), -1);
  src->start();
  EXPECT_THROW(br::openSource("dtrack://127.0.0.1:" + std::to_string(port))->start(), br::SourceError);  // port in use
  br::TrackerFrame f;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(src->next(&f));  // nothing sent: returns at once
  EXPECT_FALSE(src->waitReadable(50));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1.0);
  std::vector<std::string> tapped;
  src->setTap([&](const std::string& b, std::int64_t) { tapped.push_back(b); });
  const int tx = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<std::uint16_t>(port));
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const auto dgs = sample("confidence2-49fps.dtrack");
  std::vector<std::string> sent = {dgs[0], "garbage\r\n", dgs[2], dgs[1], dgs[3].substr(0, 100), dgs[4] + std::string(40000, 'z') + "\r\n", dgs[5]};
  for (const std::string& s : sent)
    ASSERT_EQ(::sendto(tx, s.data(), s.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to), static_cast<ssize_t>(s.size()));
  ::close(tx);
  std::vector<std::int64_t> ids;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (ids.size() < 3 && std::chrono::steady_clock::now() < until) {
    if (src->next(&f)) {
      ids.push_back(f.frame_id);
      EXPECT_GT(src->lastArrivalNs(), 0);
    } else {
      src->waitReadable(20);
    }
  }
  EXPECT_EQ(ids, (std::vector<std::int64_t>{75360, 75364, 75370}));
  const br::SourceStats st = src->stats();
  EXPECT_EQ(st.received, sent.size());
  EXPECT_EQ(st.not_played, 0u);  // (a live source plays what it receives)
  EXPECT_EQ(st.frames, 3u);
  EXPECT_EQ(st.rejected, 4u);
  EXPECT_NE(st.detail.find("oversized 1"), std::string::npos) << st.detail;
  EXPECT_NE(st.detail.find("stale/duplicate frame 1"), std::string::npos) << st.detail;
  EXPECT_EQ(tapped, sent);
}

TEST(Sources, CalibrationTextAndSilenceMonitor) {
  br::CalibrationText t;
  t.pose = "1,2,3";
  t.units = "cm";
  t.up = "y";
  t.hand_map = "0:left,1:right";
  t.palm_offset = "0,0,0.02";
  const br::SourceOptions o = br::sourceOptions(t, 12);
  EXPECT_EQ(o.frames, 12);
  EXPECT_EQ(o.X_WT.p, Vec3(1, 2, 3));
  EXPECT_DOUBLE_EQ(o.units_to_m, 0.01);
  EXPECT_TRUE(o.y_up);
  ASSERT_EQ(o.hand_sides.size(), 2u);
  EXPECT_EQ(o.palm_offset_m, Vec3(0, 0, 0.02));
  for (auto bad : {br::CalibrationText{"", "inch", "", "", "", 0, 0.0, 0.0}, br::CalibrationText{"", "", "x", "", "", 0, 0.0, 0.0},
                   br::CalibrationText{"", "", "", "", "0,0,2", 0, 0.0, 0.0}, br::CalibrationText{"", "", "", "", "", 70000, 0.0, 0.0},
                   br::CalibrationText{"1,2", "", "", "", "", 0, 0.0, 0.0}, br::CalibrationText{"", "", "", "", "", 0, -1.0, 0.0},
                   br::CalibrationText{"", "", "", "", "", 0, 0.0, -5.0}})
    EXPECT_THROW(br::sourceOptions(bad), br::SourceError);
  // cm units scale the DTrack stream: the palm lands 10x further from the origin.
  br::CalibrationText cm;
  cm.units = "cm";
  const auto a = br::loadRecording(dataPath("pinch.dtrack"));
  const auto b = br::loadRecording(dataPath("pinch.dtrack"), br::sourceOptions(cm));
  EXPECT_NEAR((b.mean_palm_W - 10.0 * a.mean_palm_W).norm(), 0.0, 1e-9);
  br::SilenceMonitor m(1.0);
  EXPECT_FALSE(m.poll(0.0));
  EXPECT_FALSE(m.poll(0.99));
  EXPECT_TRUE(m.poll(1.0));  // reported once
  EXPECT_FALSE(m.poll(5.0));
  EXPECT_TRUE(m.silent());
  EXPECT_TRUE(m.frame(5.5));  // ends the silence
  EXPECT_FALSE(m.frame(5.6));
  EXPECT_FALSE(m.poll(6.5));
  EXPECT_TRUE(m.poll(6.7));
  EXPECT_EQ(m.silences(), 2u);
}

// Found by fuzz_dtrack (tests/fuzz/regressions/dtrack/ts2-seconds-overflow.dtrack): ts2 seconds
// beyond the range were multiplied into an int64 overflow before the range check stopped them.
TEST(DtrackParse, RegressionTs2SecondsOverflow) {
  Datagram d;
  const ParseResult r = parseDatagram(slurp(std::string(GODHAND_TEST_DATA_DIR) + "/../fuzz/regressions/dtrack/ts2-seconds-overflow.dtrack"), &d);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(static_cast<int>(r.reason), static_cast<int>(Reject::kOutOfRange)) << r.detail;
  EXPECT_FALSE(d.has_ts2);
}
