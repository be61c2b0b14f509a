// The skeleton mapping layer (bridges/skeleton) and its JSON Lines recordings. Oracles: OpenXR's
// own joint-frame convention for a hand lying flat (spec: −Z toward the fingertips, +Y on the back
// of the hand), and the Leap recordings: their hands are written out as OpenXR / MediaPipe
// recordings in the other format's coordinates and must come back as the same hands and targets.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <gtest/gtest.h>
#include <sstream>

#include "common/files.h"
#include "leap/leap_recording.h"
#include "leap/retarget.h"
#include "leap/tool_target.h"
#include "model/hand_model.h"
#include "skeleton/jsonl.h"
#include "skeleton/skeleton.h"
#include "source/recording.h"
#include "source/tracker_source.h"

using namespace godhand;
using namespace godhand::skeleton;

namespace {

std::string tmpFile(const std::string& name) {
  return "/tmp/godhand-skeleton-test-" + std::to_string(::getpid()) + "-" + name;
}
Vec3 tToXr(const Vec3& p) { return Vec3(p.x(), p.z(), -p.y()); }  // inverse of xrToT

/// 26 OpenXR joints (OpenXR space) of a tracked Leap hand: palm joint = the Leap palm frame,
/// wrist 2·palm − middle MCP, metacarpal joints halfway wrist → MCP.
std::array<XrJoint, kXrJoints> xrJointsOf(const leap::TrackedHand& h) {
  std::array<XrJoint, kXrJoints> j;
  const Mat3 R = h.X_W_palm.q.toRotationMatrix();
  Mat3 Rxr;  // columns X, Y, Z of the OpenXR palm joint in OpenXR space
  Rxr.col(0) = tToXr(R.col(0));
  Rxr.col(1) = tToXr(R.col(2));
  Rxr.col(2) = -tToXr(R.col(1));
  const Vec3 wrist = 2.0 * h.X_W_palm.p - h.joints_W[2][0];
  j[0] = {tToXr(h.X_W_palm.p), Quat(Rxr), 0.01, 0xF};
  j[1] = {tToXr(wrist), Quat(Rxr), 0.01, 0xF};
  for (int f = 0; f < 5; ++f) {
    const int base = f == 0 ? 2 : 1 + 5 * f;
    if (f > 0) j[static_cast<size_t>(base)] = {tToXr(0.5 * (wrist + h.joints_W[static_cast<size_t>(f)][0])), Quat::Identity(), 0.01, 0x3};
    for (int k = 0; k < 4; ++k)
      j[static_cast<size_t>(base + (f == 0 ? k : k + 1))] = {tToXr(h.joints_W[static_cast<size_t>(f)][static_cast<size_t>(k)]), Quat::Identity(), 0.008, 0x3};
  }
  return j;
}

std::string jointsJson(const std::array<XrJoint, kXrJoints>& j) {
  std::ostringstream os;
  os.precision(17);
  os << "[";
  for (size_t k = 0; k < j.size(); ++k) {
    const XrJoint& x = j[k];
    os << (k ? "," : "") << "[" << x.p.x() << "," << x.p.y() << "," << x.p.z() << "," << x.q.x() << "," << x.q.y() << "," << x.q.z()
       << "," << x.q.w() << "," << x.radius << "," << x.flags << "]";
  }
  return os.str() + "]";
}

}  // namespace

TEST(Skeleton, OpenXrFlatRightHandFollowsTheSpecConvention) {
  // A right hand lying flat, palm down, fingers forward (OpenXR −Z), thumb to the left (−X).
  std::array<XrJoint, kXrJoints> j;
  j[0] = {Vec3(0, 1, -0.3), Quat::Identity(), 0.02, 0xF};
  j[1] = {Vec3(0, 1, -0.25), Quat::Identity(), 0.02, 0xF};
  const double xs[5] = {-0.04, -0.02, 0.0, 0.02, 0.04};
  for (int f = 0; f < 5; ++f) {
    const int base = f == 0 ? 2 : 1 + 5 * f;
    const int n = f == 0 ? 4 : 5;
    for (int k = 0; k < n; ++k) j[static_cast<size_t>(base + k)] = {Vec3(xs[f], 1, -0.27 - 0.03 * (k + (f == 0 ? 1 : 0))), Quat::Identity(), 0.01, 0x3};
  }
  leap::TrackedHand h;
  Reject why;
  ASSERT_TRUE(handFromOpenXr(j, true, 1.0, 3, Pose(), &h, &why)) << reasonName(why);
  const Mat3 R = h.X_W_palm.q.toRotationMatrix();
  EXPECT_NEAR((R.col(1) - Vec3(0, 1, 0)).norm(), 0.0, 1e-12);  // fingers: world forward (+Y, from OpenXR −Z)
  EXPECT_NEAR((R.col(2) - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);  // back of the hand: up
  EXPECT_NEAR((h.X_W_palm.p - Vec3(0, 0.3, 1)).norm(), 0.0, 1e-12);
  EXPECT_LT(h.joints_W[0][3].x(), 0.0);  // the thumb on −x: a right hand as the models expect
  // The palm frame derived from the joints alone agrees (orientation not valid).
  j[0].flags = 0x2;
  leap::TrackedHand d;
  ASSERT_TRUE(handFromOpenXr(j, true, 1.0, 3, Pose(), &d, &why));
  EXPECT_NEAR(d.X_W_palm.q.angularDistance(h.X_W_palm.q), 0.0, 1e-9);
  // The 16-body right model takes it without degenerate segments.
  const leap::Retargeter rt(loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt"));
  std::vector<Pose> tg;
  std::vector<unsigned char> dr;
  EXPECT_EQ(rt.targets(h, &tg, &dr), 0);
  // Bad joints: invalid position, NaN, a 30 cm bone.
  auto bad = j;
  bad[8].flags = 0x1;
  EXPECT_FALSE(handFromOpenXr(bad, true, 1.0, 3, Pose(), &d, &why));
  EXPECT_EQ(why, Reject::kInvalidJoint);
  bad = j;
  bad[8].p.x() = std::nan("");
  EXPECT_FALSE(handFromOpenXr(bad, true, 1.0, 3, Pose(), &d, &why));
  EXPECT_EQ(why, Reject::kNotFinite);
  bad = j;
  bad[10].p.z() -= 0.3;
  EXPECT_FALSE(handFromOpenXr(bad, true, 1.0, 3, Pose(), &d, &why));
  EXPECT_EQ(why, Reject::kDegenerate);
}

TEST(Skeleton, LandmarksOfLeapHandsComeBackAsTheSameHands) {
  const leap::Recording l = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/confidence2-49fps.json");
  double palm_angle = 0.0, joint = 0.0, palm_p = 0.0;
  size_t n = 0;
  for (const leap::TrackerFrame& f : l.frames())
    for (const leap::TrackedHand& h : f.hands) {
      std::array<Vec3, kLandmarks> p;
      p[0] = 2.0 * h.X_W_palm.p - h.joints_W[2][0];
      for (int fi = 0; fi < 5; ++fi)
        for (int k = 0; k < 4; ++k) p[static_cast<size_t>(1 + 4 * fi + k)] = h.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)];
      leap::TrackedHand m;
      Reject why;
      ASSERT_TRUE(handFromLandmarks(p, h.right, h.confidence, h.id, Pose(), &m, &why)) << reasonName(why);
      ++n;
      palm_angle = std::max(palm_angle, m.X_W_palm.q.angularDistance(h.X_W_palm.q));
      palm_p = std::max(palm_p, (m.X_W_palm.p - h.X_W_palm.p).norm());
      for (int fi = 0; fi < 5; ++fi)
        for (int k = 0; k < 4; ++k)
          joint = std::max(joint, (m.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)] - h.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)]).norm());
    }
  std::printf("[figure] skeleton21_vs_leap.hands = %zu\n", n);
  std::printf("[figure] skeleton21_vs_leap.palm_rotation_max_rad = %.4g (palm frame from the MCPs vs Leap's own)\n", palm_angle);
  EXPECT_GT(n, 300u);
  EXPECT_EQ(joint, 0.0);
  EXPECT_LT(palm_p, 1e-15);
  EXPECT_LT(palm_angle, 0.25);  // a different definition of the palm frame: 0.167 rad measured, not zero
}

TEST(Skeleton, OpenXrAndMediaPipeRecordingsGiveTheLeapHands) {
  const leap::Recording l = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/confidence2-49fps.json");
  const std::string xr = tmpFile("hands.jsonl"), mp = tmpFile("mp.jsonl");
  {
    std::ofstream a(xr), b(mp);
    a.precision(17);
    b.precision(17);
    a << "{\"format\": \"godhand-openxr-hands\", \"version\": 1}\n";
    b << "{\"format\": \"godhand-mediapipe-world\", \"version\": 1}\n";
    for (const leap::TrackerFrame& f : l.frames()) {
      a << "{\"time_ns\": " << f.timestamp_us * 1000 << ", \"hands\": [";
      b << "{\"time_us\": " << f.timestamp_us << ", \"hands\": [";
      for (size_t k = 0; k < f.hands.size(); ++k) {
        const leap::TrackedHand& h = f.hands[k];
        a << (k ? "," : "") << "{\"side\": \"" << (h.right ? "right" : "left") << "\", \"id\": " << h.id
          << ", \"active\": true, \"confidence\": " << h.confidence << ", \"joints\": " << jointsJson(xrJointsOf(h)) << "}";
        // MediaPipe camera frame (x right, y down, z forward) relative to an origin at the wrist.
        const Vec3 wrist = 2.0 * h.X_W_palm.p - h.joints_W[2][0];
        auto cam = [](const Vec3& t) { return Vec3(t.x(), -t.z(), t.y()); };
        b << (k ? "," : "") << "{\"handedness\": \"" << (h.right ? "Right" : "Left") << "\", \"score\": " << h.confidence
          << ", \"origin\": [" << cam(wrist).x() << "," << cam(wrist).y() << "," << cam(wrist).z() << "], \"landmarks\": [[0,0,0]";
        for (int fi = 0; fi < 5; ++fi)
          for (int j = 0; j < 4; ++j) {
            const Vec3 c = cam(h.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(j)]) - cam(wrist);
            b << ",[" << c.x() << "," << c.y() << "," << c.z() << "]";
          }
        b << "]}";
      }
      a << "]}\n";
      b << "]}\n";
    }
    // Bad lines, each counted: garbage, a time going back, NaN (null), an inactive hand.
    a << "not json\n{\"time_ns\": 5, \"hands\": []}\n";
    a << "{\"time_ns\": " << (l.frames().back().timestamp_us + 100) * 1000 << ", \"hands\": [{\"side\": \"left\", \"active\": false, \"joints\": []}]}\n";
    b << "{\"time_us\": " << l.frames().back().timestamp_us + 100 << ", \"hands\": [{\"handedness\": \"Right\", \"landmarks\": [[null,0,0]"
      << std::string(",[0,0,0]").append("").c_str();
    for (int i = 0; i < 19; ++i) b << ",[0,0,0]";
    b << "]}]}\n";
  }
  EXPECT_EQ(bridges::detectFormat(xr), "openxr");
  EXPECT_EQ(bridges::detectFormat(mp), "mediapipe");
  const HandModel m16r = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  const HandModel m16l = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_left.pbtxt");
  const leap::Retargeter rt[2] = {leap::Retargeter(m16l), leap::Retargeter(m16r)};
  for (const std::string& file : {xr, mp}) {
    const bridges::LoadedRecording r = bridges::loadRecording(file);
    std::printf("[info] %s: %s\n", r.format.c_str(), r.rejections.c_str());
    const size_t extra = r.format == "openxr" ? 1 : 1;  // the last, hand-less (or bad-hand) frame
    ASSERT_EQ(r.frames.size(), l.frames().size() + extra) << r.format;
    double joint = 0.0, palm_q = 0.0, tgt = 0.0;
    for (size_t i = 0; i < l.frames().size(); ++i) {
      ASSERT_EQ(r.frames[i].hands.size(), l.frames()[i].hands.size()) << r.format << " frame " << i;
      for (const leap::TrackedHand& h : l.frames()[i].hands) {
        const leap::TrackedHand* g = bridges::handOfSide(r.frames[i], h.right);
        ASSERT_NE(g, nullptr);
        for (int fi = 0; fi < 5; ++fi)
          for (int k = 0; k < 4; ++k)
            joint = std::max(joint, (g->joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)] - h.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)]).norm());
        if (r.format == "openxr") palm_q = std::max(palm_q, g->X_W_palm.q.angularDistance(h.X_W_palm.q));
        std::vector<Pose> ta, tb;
        std::vector<unsigned char> da, db;
        rt[h.right ? 1 : 0].targets(*g, &ta, &da);
        rt[h.right ? 1 : 0].targets(h, &tb, &db);
        if (r.format == "openxr")
          for (size_t k = 0; k < ta.size(); ++k) tgt = std::max(tgt, (ta[k].p - tb[k].p).norm());
      }
    }
    std::printf("[figure] %s_vs_leap.joint_position_max_m = %.3g, palm_rotation_max_rad = %.3g, target_position_max_m = %.3g\n",
                r.format.c_str(), joint, palm_q, tgt);
    EXPECT_LT(joint, 1e-12) << r.format;
    EXPECT_LT(palm_q, 1e-7) << r.format;
    EXPECT_LT(tgt, 1e-9) << r.format;
    if (r.format == "openxr") {
      EXPECT_NE(r.rejections.find("line: parse error 1"), std::string::npos) << r.rejections;
      EXPECT_NE(r.rejections.find("line: stale/duplicate time 1"), std::string::npos) << r.rejections;
      EXPECT_NE(r.rejections.find("hand: not active (untracked) 1"), std::string::npos) << r.rejections;
    } else {
      EXPECT_NE(r.rejections.find("hand: NaN/Inf 1"), std::string::npos) << r.rejections;
    }
  }
  std::remove(xr.c_str());
  std::remove(mp.c_str());
  const std::string badh = tmpFile("bad.jsonl");
  { std::ofstream(badh) << "{\"format\": \"godhand-openxr-hands\", \"version\": 2}\n"; }
  EXPECT_THROW(bridges::loadRecording(badh), bridges::SourceError);
  std::remove(badh.c_str());
}

// An OpenXR 6-DOF body (a controller's aim pose) drives the shipped tool model: the body pose
// comes out as the pose written, with the recording's axes changed to T = (x, −z, y) and the
// tracker pose applied (oracle: the same transform written out by hand), and the tool's targets
// are that pose. Invalid bodies are dropped and counted by reason.
TEST(Skeleton, OpenXrBodyDrivesTheToolModel) {
  const std::string file = tmpFile("bodies.jsonl");
  // A body 30 cm in front of the user at eye height, turned 0.4 rad about OpenXR +Y.
  const Vec3 p_xr(0.1, 1.2, -0.3);
  const Quat q_xr(Eigen::AngleAxisd(0.4, Vec3::UnitY()));
  {
    std::ofstream f(file);
    f.precision(17);
    f << "{\"format\": \"godhand-openxr-hands\", \"version\": 1}\n";
    f << "{\"time_ns\": 1000000, \"hands\": [], \"bodies\": [{\"id\": 7, \"pose\": [" << p_xr.x() << "," << p_xr.y() << ","
      << p_xr.z() << "," << q_xr.x() << "," << q_xr.y() << "," << q_xr.z() << "," << q_xr.w() << "], \"flags\": 15}, "
      << "{\"id\": 8, \"pose\": [0,0,0,0,0,0,1], \"flags\": 1}, {\"id\": 9, \"pose\": [0,0,0,0,0,0,2], \"flags\": 3}, "
      << "{\"id\": 10, \"pose\": [null,0,0,0,0,0,1], \"flags\": 3}, {\"id\": 11, \"pose\": [0,0,0], \"flags\": 3}]}\n";
  }
  Pose X_WT;
  X_WT.p = Vec3(0.5, -0.2, -1.0);
  X_WT.q = Quat(Eigen::AngleAxisd(0.3, Vec3::UnitZ()));
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  const JsonlRecording r = readJsonl(text.str(), file, X_WT);
  std::printf("[info] %s\n", r.summary().c_str());
  ASSERT_EQ(r.frames.size(), 1u);
  ASSERT_EQ(r.frames[0].bodies.size(), 1u);
  EXPECT_EQ(r.bodies_kept, 1u);
  const leap::TrackedBody& b = r.frames[0].bodies[0];
  EXPECT_EQ(b.id, 7);
  EXPECT_EQ(b.quality, 1.0);
  Mat3 C;
  C << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  const Vec3 p_want = X_WT.q * (C * p_xr) + X_WT.p;
  const Mat3 R_want = X_WT.q.toRotationMatrix() * C * q_xr.toRotationMatrix();
  EXPECT_LT((b.X_WB.p - p_want).norm(), 1e-12);
  EXPECT_LT((b.X_WB.q.toRotationMatrix() - R_want).norm(), 1e-12);
  // OpenXR's forward (−Z) is T's +y: the body's forward axis, seen in T, is turned 0.4 rad about
  // T's z (OpenXR +Y) from +y.
  const Vec3 fwd_T = C * (q_xr * Vec3(0, 0, -1));
  EXPECT_NEAR(fwd_T.z(), 0.0, 1e-12);
  EXPECT_NEAR(std::atan2(-fwd_T.x(), fwd_T.y()), 0.4, 1e-12);
  for (const char* reason : {"body: not tracked (position or orientation invalid) 1", "body: non-unit quaternion 1",
                             "body: NaN/Inf 1", "body: parse error 1"})
    EXPECT_NE(r.summary().find(reason), std::string::npos) << reason << " in " << r.summary();
  // The tool model rides it: its one God object at its rest pose in the body's frame.
  const HandModel tool = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/tool1.pbtxt");
  ASSERT_TRUE(leap::isToolModel(tool));
  std::vector<Pose> targets;
  std::vector<unsigned char> has;
  double quality = 0;
  ASSERT_TRUE(leap::toolTargets(tool, r.frames[0], 7, &targets, &has, &quality));
  ASSERT_EQ(targets.size(), 1u);
  const Pose want = b.X_WB * tool.bodies[0].X_MB_rest;
  EXPECT_LT((targets[0].p - want.p).norm(), 1e-12);
  EXPECT_LT(targets[0].q.angularDistance(want.q), 1e-9);
  EXPECT_FALSE(leap::toolTargets(tool, r.frames[0], 8, &targets, &has, &quality)) << "body 8 was not tracked";
  std::remove(file.c_str());
}

// Aria MPS hand tracking CSV (tests/data/aria/pinch_head_v2.csv, written by make_aria.py from
// the first 8 frames of pinch.json in the 155-column v2 layout): the Leap hand comes back
// (joints printed to 1e-9 m; Aria has no thumb CMC, so thumb.1 is approximate), left untracked.
TEST(Skeleton, AriaCsvGivesTheLeapHand) {
  const std::string path = std::string(GODHAND_TEST_DATA_DIR) + "/aria/pinch_head_v2.csv";
  EXPECT_EQ(bridges::detectFormat(path), "aria");
  const bridges::LoadedRecording r = bridges::loadRecording(path);
  const leap::Recording l = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json");
  ASSERT_EQ(r.frames.size(), 8u);
  EXPECT_TRUE(r.has_right);
  EXPECT_FALSE(r.has_left);
  double joint = 0.0;
  for (size_t i = 0; i < 8; ++i) {
    ASSERT_EQ(r.frames[i].hands.size(), 1u);
    EXPECT_EQ(r.frames[i].timestamp_us, l.frames()[i].timestamp_us);
    const leap::TrackedHand& a = r.frames[i].hands[0];
    const leap::TrackedHand& b = l.frames()[i].hands[0];
    EXPECT_NEAR((a.X_W_palm.p - b.X_W_palm.p).norm(), 0.0, 2e-9);
    for (int fi = 0; fi < 5; ++fi)
      for (int k = fi == 0 ? 1 : 0; k < 4; ++k)
        joint = std::max(joint, (a.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)] - b.joints_W[static_cast<size_t>(fi)][static_cast<size_t>(k)]).norm());
  }
  std::printf("[figure] aria_vs_leap.joint_position_max_m = %.3g (thumb CMC excluded)\n", joint);
  EXPECT_LT(joint, 2e-9);
  // Bad rows, counted: NaN, a wrong column count, a time going back; confidence −1 is untracked.
  std::ifstream in(path);
  std::string header, row;
  std::getline(in, header);
  std::getline(in, row);
  auto field = [](std::string line, size_t idx, const std::string& v) {
    size_t start = 0;
    for (size_t k = 0; k < idx; ++k) start = line.find(',', start) + 1;
    const size_t end = line.find(',', start);
    return line.replace(start, end - start, v);
  };
  const size_t right_conf = 1 + 1 + 63;
  const std::string p2 = tmpFile("aria.csv");
  {
    std::ofstream o(p2);
    o << header << "\n" << row << "\n";
    o << field(field(row, 0, "12281700000"), right_conf + 5, "nan") << "\n";
    o << field(row, 0, "12281690000") << "\n";                    // back in time
    o << row.substr(0, row.rfind(',')) << "\n";                  // a column short
    o << field(field(row, 0, "12281710000"), right_conf, "-1") << "\n";  // not tracked
  }
  const bridges::LoadedRecording bad = bridges::loadRecording(p2);
  EXPECT_EQ(bad.frames.size(), 3u);
  EXPECT_NE(bad.rejections.find("hand: NaN/Inf 1"), std::string::npos) << bad.rejections;
  EXPECT_NE(bad.rejections.find("line: parse error 1"), std::string::npos) << bad.rejections;
  EXPECT_NE(bad.rejections.find("line: stale/duplicate time 1"), std::string::npos) << bad.rejections;
  EXPECT_TRUE(bad.frames.back().hands.empty());
  { std::ofstream(p2) << "tracking_timestamp_us,left_tracking_confidence\n1,0\n"; }
  EXPECT_THROW(bridges::loadRecording(p2), bridges::SourceError);
  std::remove(p2.c_str());
}

// A second user's right hand in the same frames (1 m to the side, listed first in every other
// frame): the first user's hand goes on in every frame, and the other is counted as a second hand
// of that side, not as a hundred jumps of the one hand; --hand-map picks the user by id.
TEST(Skeleton, ASecondUsersHandOfTheSameSideIsCountedAsSuch) {
  const leap::Recording l = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json");
  const std::string xr = tmpFile("two_users.jsonl");
  {
    std::ofstream a(xr);
    a.precision(17);
    a << "{\"format\": \"godhand-openxr-hands\", \"version\": 1}\n";
    size_t i = 0;
    for (const leap::TrackerFrame& f : l.frames()) {
      const leap::TrackedHand* h = bridges::handOfSide(f, true);
      if (!h) continue;
      leap::TrackedHand other = *h;
      other.X_W_palm.p += Vec3(1.0, 0, 0);
      for (auto& finger : other.joints_W)
        for (Vec3& j : finger) j += Vec3(1.0, 0, 0);
      auto hand = [&](const leap::TrackedHand& x, int id, double confidence) {
        std::ostringstream s;
        s.precision(17);
        s << "{\"side\": \"right\", \"id\": " << id << ", \"active\": true, \"confidence\": " << confidence
          << ", \"joints\": " << jointsJson(xrJointsOf(x)) << "}";
        return s.str();
      };
      // The other user's hand is listed first in the first frame (and every other one), and is
      // less confident: the first frame goes by confidence, the rest by nearness.
      a << "{\"time_ns\": " << f.timestamp_us * 1000 << ", \"hands\": ["
        << (i % 2 == 0 ? hand(other, 3, 0.5) + "," + hand(*h, 1, 1.0) : hand(*h, 1, 1.0) + "," + hand(other, 3, 0.5)) << "]}\n";
      ++i;
    }
  }
  const bridges::LoadedRecording r = bridges::loadRecording(xr);
  std::printf("[info] %s\n", r.rejections.c_str());
  ASSERT_EQ(r.frames.size(), l.frames().size());
  EXPECT_NE(r.rejections.find("second hands of a side in one frame (another user? --hand-map picks by id) " +
                              std::to_string(l.frames().size())),
            std::string::npos)
      << r.rejections;
  EXPECT_EQ(r.rejections.find("jump"), std::string::npos) << r.rejections;
  for (size_t i = 0; i < r.frames.size(); ++i) {
    ASSERT_EQ(r.frames[i].hands.size(), 1u) << i;
    EXPECT_NEAR((r.frames[i].hands[0].X_W_palm.p - bridges::handOfSide(l.frames()[i], true)->X_W_palm.p).norm(), 0.0, 1e-9) << i;
  }
  // The map picks the other user: every frame its hand, 1 m to the side.
  bridges::SourceOptions o;
  o.hand_sides = bridges::parseHandSides("3:right");
  const bridges::LoadedRecording other = bridges::loadRecording(xr, o);
  ASSERT_EQ(other.frames.size(), l.frames().size());
  for (size_t i = 0; i < other.frames.size(); ++i) {
    ASSERT_EQ(other.frames[i].hands.size(), 1u) << i;
    EXPECT_NEAR(other.frames[i].hands[0].X_W_palm.p.x() - bridges::handOfSide(l.frames()[i], true)->X_W_palm.p.x(), 1.0, 1e-9) << i;
  }
  EXPECT_EQ(other.rejections.find("second hands"), std::string::npos) << other.rejections;
}

// What a user's own JSON Lines writer gets wrong is named: a missing header line, a UTF-8 BOM
// (read as if absent), a float time, a hand without its side, 21 joints for OpenXR's 26.
TEST(Skeleton, JsonLinesMistakesAreNamed) {
  const leap::Recording l = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/pinch.json");
  std::vector<std::string> lines;
  for (size_t i = 0; i < 20; ++i) {
    const leap::TrackerFrame& f = l.frames()[i];
    const leap::TrackedHand* h = bridges::handOfSide(f, true);
    if (!h) continue;
    std::ostringstream s;
    s.precision(17);
    s << "{\"time_ns\": " << f.timestamp_us * 1000 << ", \"hands\": [{\"side\": \"right\", \"id\": 1, \"joints\": "
      << jointsJson(xrJointsOf(*h)) << "}]}";
    lines.push_back(s.str());
  }
  ASSERT_GE(lines.size(), 10u);
  const std::string header = "{\"format\": \"godhand-openxr-hands\", \"version\": 1}\n";
  auto file = [&](const std::string& name, const std::string& text) {
    const std::string path = tmpFile(name);
    std::ofstream(path) << text;
    return path;
  };
  std::string body;
  for (const std::string& x : lines) body += x + "\n";
  // No header: the cause, not "not valid JSON ... line 2"; also when the first line is longer
  // than the first read (two hands: ~6 KB).
  std::string two_hands = lines[0];
  {
    const size_t open = two_hands.find("[{"), close = two_hands.rfind("}]");
    const std::string hand = two_hands.substr(open + 1, close - open);
    two_hands.insert(close + 1, "," + hand);
  }
  ASSERT_GT(two_hands.size(), 4096u);
  for (const std::string& text : {body, two_hands + "\n" + body}) {
    try {
      bridges::loadRecording(file("noheader.jsonl", text));
      ADD_FAILURE() << "read without its header";
    } catch (const bridges::SourceError& e) {
      EXPECT_NE(std::string(e.what()).find("the header line is missing"), std::string::npos) << e.what();
    }
  }
  // A byte-order mark: the same frames as without.
  const auto plain = bridges::loadRecording(file("plain.jsonl", header + body));
  const auto bom = bridges::loadRecording(file("bom.jsonl", "\xEF\xBB\xBF" + header + body));
  ASSERT_EQ(bom.frames.size(), plain.frames.size());
  EXPECT_EQ(bom.frames.size(), lines.size());
  // Each mistake on one line, counted under its own name.
  auto edit = [](std::string x, const std::string& from, const std::string& to) {
    const size_t at = x.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? x : x.replace(at, from.size(), to);
  };
  std::string bad = header;
  bad += edit(lines[0], "\"time_ns\": ", "\"time_ns\": 1.5e3 , \"x\": ") + "\n";
  bad += edit(lines[1], "\"side\": \"right\", ", "") + "\n";
  bad += edit(lines[2], "\"side\": \"right\"", "\"side\": \"Unknown\"") + "\n";
  std::string joints21 = lines[3];
  {
    // Cut the joints array after its 21st entry.
    const size_t open = joints21.find("\"joints\": [") + 10;
    size_t at = open + 1;
    for (int k = 0; k < 21; ++k) at = joints21.find(']', at) + 1;
    const size_t close = joints21.rfind("]}]}");
    joints21 = joints21.substr(0, at) + joints21.substr(close);
  }
  bad += joints21 + "\n";
  for (size_t i = 4; i < lines.size(); ++i) bad += lines[i] + "\n";
  const auto r = bridges::loadRecording(file("mistakes.jsonl", bad));
  std::printf("[info] %s\n", r.rejections.c_str());
  EXPECT_EQ(r.frames.size(), lines.size() - 1);  // the float time drops its line, the others a hand
  for (const char* reason : {"line: time_ns missing or not an integer 1", "hand: side missing or not \"left\"/\"right\" 2",
                             "hand: joints not 26 [px,py,pz,qx,qy,qz,qw,radius,flags] 1"})
    EXPECT_NE(r.rejections.find(reason), std::string::npos) << reason << " in " << r.rejections;
  EXPECT_EQ(r.rejections.find("parse error"), std::string::npos) << r.rejections;
  // An empty file says so.
  try {
    bridges::loadRecording(file("empty.jsonl", ""));
    ADD_FAILURE() << "an empty file was read";
  } catch (const bridges::SourceError& e) {
    EXPECT_NE(std::string(e.what()).find(": empty file"), std::string::npos) << e.what();
  }
}

// An Aria-style CSV of one hand (the other side's columns left out, as a user's own export may)
// reads the same hand; a side with its confidence but a landmark column missing is refused, naming it.
TEST(Skeleton, AriaCsvOfOneHandWithoutTheOtherSidesColumns) {
  const std::string path = std::string(GODHAND_TEST_DATA_DIR) + "/aria/pinch_head_v2.csv";
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    rows.push_back(cells);
  }
  ASSERT_GT(rows.size(), 1u);
  auto write = [&](const std::string& name, auto keep) {
    const std::string out = tmpFile(name);
    std::ofstream o(out);
    for (const auto& r : rows) {
      bool first = true;
      for (size_t c = 0; c < r.size(); ++c) {
        if (!keep(rows[0][c])) continue;
        o << (first ? "" : ",") << r[c];
        first = false;
      }
      o << "\n";
    }
    return out;
  };
  auto left = [](const std::string& col) { return col.rfind("left_", 0) == 0 || col.find("_left_") != std::string::npos; };
  const std::string right_only = write("right_only.csv", [&](const std::string& c) { return !left(c); });
  const bridges::LoadedRecording full = bridges::loadRecording(path), one = bridges::loadRecording(right_only);
  ASSERT_EQ(one.frames.size(), full.frames.size());
  EXPECT_TRUE(one.has_right);
  EXPECT_FALSE(one.has_left);
  for (size_t i = 0; i < one.frames.size(); ++i) {
    ASSERT_EQ(one.frames[i].hands.size(), 1u);
    EXPECT_EQ(one.frames[i].hands[0].X_W_palm.p, bridges::handOfSide(full.frames[i], true)->X_W_palm.p);
  }
  const std::string partial =
      write("partial.csv", [&](const std::string& c) { return !left(c) && c != "tx_right_landmark_7_device"; });
  try {
    bridges::loadRecording(partial);
    ADD_FAILURE() << "a side without one of its landmark columns was read";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("missing column tx_right_landmark_7_device"), std::string::npos) << e.what();
  }
}
