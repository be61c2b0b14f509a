// Leap recording reader (bridges/leap/leap_recording.h).
//
// Oracles: the bundled recordings' frame and hand counts (counted independently with Python
// while writing this test, and the data notice: 39 one-hand and 132 two-hand frames); a
// hand-written file whose numbers convert by hand (palm (10, 200, −30) mm → (0.010, 0.030,
// 0.200) m); the same 12 frames in format 0.1 and packed format 2 must read identically; bad
// inputs give one-line errors naming the file, or counted rejections by reason.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "leap/leap_recording.h"

namespace godhand::leap {
namespace {

std::string recordingPath(const std::string& f) { return std::string(GODHAND_DEPLOY_DIR) + "/recordings/" + f; }
std::string dataPath(const std::string& f) { return std::string(GODHAND_TEST_DATA_DIR) + "/leap/" + f; }

std::string readText(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Replaces the first occurrence of `from` (which must exist) in `text`.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "test bug: '" << from << "' not in text";
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

void figure(const std::string& name, double value, const char* unit = "") {
  std::printf("[figure] %s = %.6g%s%s\n", name.c_str(), value, *unit ? " " : "", unit);
}

std::string errorOf(const std::string& path) {
  try {
    Recording::load(path);
  } catch (const RecordingError& e) {
    return e.what();
  }
  return "(no error)";
}

void expectOneLine(const std::string& msg, const std::string& file) {
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  EXPECT_EQ(msg.rfind(file + ": ", 0), 0u) << msg;
}

// ---------------------------------------------------------------------------------------------
// Bundled recordings

struct Bundled {
  const char* file;
  std::size_t frames;
  const char* format;
};

TEST(LeapRecording, BundledRecordingsLoadCompletely) {
  for (const Bundled& b : {Bundled{"pinch.json", 307, "0.1"}, Bundled{"HandSplay-110fps.json", 288, "1"},
                           Bundled{"confidence2-49fps.json", 171, "0.1"}}) {
    SCOPED_TRACE(b.file);
    const Recording rec = Recording::load(recordingPath(b.file));
    EXPECT_EQ(rec.frames().size(), b.frames);
    EXPECT_EQ(rec.formatVersion(), b.format);
    EXPECT_EQ(rec.stats().frames_in, b.frames);
    EXPECT_EQ(rec.stats().frames_rejected_total(), 0u) << rec.stats().summary();
    EXPECT_EQ(rec.stats().hands_rejected_total(), 0u) << rec.stats().summary();
    EXPECT_EQ(rec.stats().pointables_ignored, 0u);
    std::int64_t min_dt = INT64_MAX, max_dt = 0;
    for (std::size_t i = 1; i < rec.frames().size(); ++i) {
      const std::int64_t dt = rec.frames()[i].timestamp_us - rec.frames()[i - 1].timestamp_us;
      min_dt = std::min(min_dt, dt);
      max_dt = std::max(max_dt, dt);
      EXPECT_GT(rec.frames()[i].frame_id, rec.frames()[i - 1].frame_id);
    }
    EXPECT_GT(min_dt, 0);
    const std::string tag = std::string("leap.") + b.file;
    figure(tag + ".mean_frame_rate", rec.meanFrameRate(), "Hz");
    figure(tag + ".frame_interval_min", static_cast<double>(min_dt) * 1e-3, "ms");
    figure(tag + ".frame_interval_max", static_cast<double>(max_dt) * 1e-3, "ms");
    const Vec3 m = rec.meanPalmPosition();
    std::printf("[figure] %s.mean_palm_position = (%.4f, %.4f, %.4f) m\n", tag.c_str(), m.x(), m.y(), m.z());
    std::printf("[figure] %s.summary: %s\n", tag.c_str(), rec.stats().summary().c_str());
    // Hands hover above the device: +Z up, 10-40 cm.
    EXPECT_GT(m.z(), 0.10);
    EXPECT_LT(m.z(), 0.40);
  }
}

TEST(LeapRecording, HandsPerFrame) {
  for (const char* f : {"pinch.json", "HandSplay-110fps.json"}) {
    const Recording rec = Recording::load(recordingPath(f));
    for (const TrackerFrame& fr : rec.frames()) {
      ASSERT_EQ(fr.hands.size(), 1u) << f;
      EXPECT_TRUE(fr.hands[0].right);
    }
  }
  // The two-hand file: the left hand (id 123) is tracked throughout; the right hand (id 124) is
  // there from the first frame and leaves after frame 132 (it does not enter within the file).
  const Recording rec = Recording::load(recordingPath("confidence2-49fps.json"));
  std::size_t one = 0, two = 0, first_one = rec.frames().size();
  for (std::size_t i = 0; i < rec.frames().size(); ++i) {
    const TrackerFrame& fr = rec.frames()[i];
    if (fr.hands.size() == 1) {
      ++one;
      first_one = std::min(first_one, i);
      EXPECT_FALSE(fr.hands[0].right);
      EXPECT_EQ(fr.hands[0].id, 123);
    } else {
      ASSERT_EQ(fr.hands.size(), 2u);
      ++two;
      EXPECT_NE(fr.hands[0].right, fr.hands[1].right);
      EXPECT_LT(i, 132u) << "right hand back after it left";
    }
  }
  EXPECT_EQ(one, 39u);
  EXPECT_EQ(two, 132u);
  EXPECT_EQ(first_one, 132u);
  figure("leap.confidence2.frames_with_one_hand", static_cast<double>(one));
  figure("leap.confidence2.frames_with_two_hands", static_cast<double>(two));
}

TEST(LeapRecording, PalmFramesOrthonormalRightHandedAndThumbOnTheExpectedSide) {
  double worst_ortho = 0.0;
  for (const char* f : {"pinch.json", "HandSplay-110fps.json", "confidence2-49fps.json"}) {
    const Recording rec = Recording::load(recordingPath(f));
    for (const TrackerFrame& fr : rec.frames())
      for (const TrackedHand& h : fr.hands) {
        const Mat3 R = h.X_W_palm.q.toRotationMatrix();
        worst_ortho = std::max(worst_ortho, (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff());
        EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
        EXPECT_NEAR(h.X_W_palm.q.norm(), 1.0, 1e-12);
        EXPECT_TRUE(h.X_W_palm.p.allFinite());
        // Model convention: thumb on −x of the palm frame for a right hand, +x for a left hand;
        // the middle knuckle lies ahead of the palm centre (+y).
        const Vec3 thumb_P = h.X_W_palm.inverse() * h.joints_W[kThumb][kMcp];
        const Vec3 middle_P = h.X_W_palm.inverse() * h.joints_W[kMiddle][kMcp];
        EXPECT_EQ(thumb_P.x() < 0.0, h.right) << f << " frame " << fr.frame_id;
        EXPECT_GT(middle_P.y(), 0.0);
        for (const auto& finger : h.joints_W)
          for (const Vec3& p : finger) EXPECT_TRUE(p.allFinite());
      }
  }
  EXPECT_LT(worst_ortho, 1e-12);
  figure("leap.palm_frame_orthonormality_error_max", worst_ortho);
}

// ---------------------------------------------------------------------------------------------
// Hand-written file: units, axes, X_WT

TEST(LeapRecording, UnitAndAxisConversion) {
  const Recording rec = Recording::load(dataPath("tiny.json"));
  ASSERT_EQ(rec.frames().size(), 3u);
  EXPECT_EQ(rec.frames()[0].timestamp_us, 1000000);
  EXPECT_EQ(rec.frames()[0].frame_id, 100);
  ASSERT_EQ(rec.frames()[0].hands.size(), 1u);
  const TrackedHand& h = rec.frames()[0].hands[0];
  EXPECT_EQ(h.id, 7);
  EXPECT_TRUE(h.right);
  EXPECT_DOUBLE_EQ(h.confidence, 0.9);
  // (x, y, z) mm with +Y up -> (x, -z, y) / 1000 m with +Z up.
  EXPECT_LT((h.X_W_palm.p - Vec3(0.010, 0.030, 0.200)).norm(), 1e-15);
  // Palm down (normal -Y), fingers away from the user (-z): palm frame = world axes.
  EXPECT_LT((h.X_W_palm.q.toRotationMatrix() - Mat3::Identity()).norm(), 1e-15);
  EXPECT_LT((h.joints_W[kThumb][kMcp] - Vec3(-0.020, 0.010, 0.195)).norm(), 1e-15);
  EXPECT_LT((h.joints_W[kMiddle][kTip] - Vec3(0.005, 0.130, 0.150)).norm(), 1e-15);
  EXPECT_LT((h.joints_W[kPinky][kPip] - Vec3(0.046, 0.078, 0.200)).norm(), 1e-15);

  // Frame 2: the left hand, palm facing +x (Leap), fingers up.
  ASSERT_EQ(rec.frames()[1].hands.size(), 2u);
  const TrackedHand& l = rec.frames()[1].hands[1];
  EXPECT_FALSE(l.right);
  EXPECT_EQ(l.id, 8);
  const Mat3 R = l.X_W_palm.q.toRotationMatrix();
  EXPECT_LT((R.col(1) - Vec3(0, 0, 1)).norm(), 1e-15);   // direction: Leap +Y = up = our +Z
  EXPECT_LT((R.col(2) - Vec3(-1, 0, 0)).norm(), 1e-15);  // back of the hand = −normal
  EXPECT_LT((R.col(0) - Vec3(0, -1, 0)).norm(), 1e-15);  // x = y × z
  EXPECT_EQ(rec.stats().pointables_ignored, 1u);          // the tool
  EXPECT_TRUE(rec.frames()[2].hands.empty());
  EXPECT_EQ(rec.stats().hands_read, 3u);
  EXPECT_NEAR(rec.meanFrameRate(), 100.0, 1e-9);
}

TEST(LeapRecording, TrackerPoseApplied) {
  const Pose X_WT{Vec3(1.0, -2.0, 0.75), Quat(Eigen::AngleAxisd(0.7, Vec3(0.2, -0.5, 1.0).normalized()))};
  const Recording dev = Recording::load(dataPath("tiny.json"));
  const Recording world = Recording::load(dataPath("tiny.json"), X_WT);
  ASSERT_EQ(dev.frames().size(), world.frames().size());
  for (std::size_t f = 0; f < dev.frames().size(); ++f)
    for (std::size_t k = 0; k < dev.frames()[f].hands.size(); ++k) {
      const TrackedHand& a = dev.frames()[f].hands[k];
      const TrackedHand& b = world.frames()[f].hands[k];
      const Pose expect = X_WT * a.X_W_palm;
      EXPECT_LT((b.X_W_palm.p - expect.p).norm(), 1e-14);
      EXPECT_LT(b.X_W_palm.q.angularDistance(expect.q), 1e-12);
      for (int fi = 0; fi < kFingerCount; ++fi)
        for (int j = 0; j < 4; ++j)
          EXPECT_LT((b.joints_W[fi][j] - X_WT * a.joints_W[fi][j]).norm(), 1e-14);
    }
  EXPECT_LT((world.meanPalmPosition() - X_WT * dev.meanPalmPosition()).norm(), 1e-14);
  // A non-unit quaternion is a configuration error.
  Pose bad;
  bad.q = Quat(2.0, 0.0, 0.0, 0.0);
  EXPECT_THROW(Recording::load(dataPath("tiny.json"), bad), RecordingError);
}

TEST(LeapRecording, PackedFormat2ReadsLikeFormat01) {
  const Recording packed = Recording::load(dataPath("pinch_head_packed.json"));
  const Recording full = Recording::load(recordingPath("pinch.json"));
  EXPECT_EQ(packed.formatVersion(), "2");
  ASSERT_EQ(packed.frames().size(), 12u);
  EXPECT_EQ(packed.stats().hands_rejected_total(), 0u) << packed.stats().summary();
  for (std::size_t f = 0; f < 12; ++f) {
    const TrackerFrame& a = packed.frames()[f];
    const TrackerFrame& b = full.frames()[f];
    EXPECT_EQ(a.timestamp_us, b.timestamp_us);
    EXPECT_EQ(a.frame_id, b.frame_id);
    ASSERT_EQ(a.hands.size(), b.hands.size());
    for (std::size_t k = 0; k < a.hands.size(); ++k) {
      EXPECT_EQ(a.hands[k].id, b.hands[k].id);
      EXPECT_EQ(a.hands[k].X_W_palm.p, b.hands[k].X_W_palm.p);
      EXPECT_EQ(a.hands[k].X_W_palm.q.coeffs(), b.hands[k].X_W_palm.q.coeffs());
      EXPECT_EQ(a.hands[k].joints_W, b.hands[k].joints_W);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Bad input

TEST(LeapRecording, BadFilesGiveOneLineErrors) {
  const std::string missing = dataPath("does_not_exist.json");
  std::string msg = errorOf(missing);
  expectOneLine(msg, missing);
  EXPECT_NE(msg.find("cannot open"), std::string::npos) << msg;

  const std::string not_json = dataPath("not_json.json");
  msg = errorOf(not_json);
  expectOneLine(msg, not_json);
  EXPECT_NE(msg.find("not valid JSON"), std::string::npos) << msg;

  const std::string no_frames = dataPath("no_frames.json");
  msg = errorOf(no_frames);
  expectOneLine(msg, no_frames);
  EXPECT_NE(msg.find("no frames"), std::string::npos) << msg;

  const std::string unsupported = dataPath("unsupported_format.json");
  msg = errorOf(unsupported);
  expectOneLine(msg, unsupported);
  EXPECT_NE(msg.find("unsupported formatVersion 3"), std::string::npos) << msg;
  std::printf("[figure] leap.error_example: %s\n", msg.c_str());
}

TEST(LeapRecording, NaNPalmDropsOnlyThatHand) {
  const Recording rec = Recording::load(dataPath("nan_palm.json"));
  ASSERT_EQ(rec.frames().size(), 3u);
  ASSERT_EQ(rec.frames()[1].hands.size(), 1u);
  EXPECT_TRUE(rec.frames()[1].hands[0].right);
  EXPECT_EQ(rec.stats().handRejects(HandReject::kNotFinite), 1u);
  EXPECT_EQ(rec.stats().hands_rejected_total(), 1u);
  EXPECT_EQ(rec.stats().frames_rejected_total(), 0u);
  EXPECT_NE(rec.stats().summary().find("NaN or infinite value 1"), std::string::npos) << rec.stats().summary();
}

TEST(LeapRecording, PointableWithMissingFieldDropsItsHand) {
  const Recording rec = Recording::load(dataPath("missing_field.json"));
  ASSERT_EQ(rec.frames().size(), 3u);
  ASSERT_EQ(rec.frames()[1].hands.size(), 1u);
  EXPECT_FALSE(rec.frames()[1].hands[0].right);  // the right hand lost its middle finger's dip
  EXPECT_EQ(rec.stats().handRejects(HandReject::kFingerMissingField), 1u);
  EXPECT_EQ(rec.stats().hands_rejected_total(), 1u);
}

TEST(LeapRecording, DecreasingTimestampRejectsTheFrame) {
  const Recording rec = Recording::load(dataPath("decreasing.json"));
  ASSERT_EQ(rec.frames().size(), 2u);
  EXPECT_EQ(rec.frames()[0].frame_id, 100);
  EXPECT_EQ(rec.frames()[1].frame_id, 102);
  EXPECT_EQ(rec.stats().frameRejects(FrameReject::kDecreasingTimestamp), 1u);
  EXPECT_EQ(rec.stats().frames_in, 3u);
  EXPECT_EQ(rec.stats().frames_read, 2u);
}

/// Each edit of tiny.json and the one rejection it must cause (all in frame 101 or 100).
struct Edit {
  const char* what;
  const char* from;
  const char* to;
  HandReject reason;
};

TEST(LeapRecording, HandRejectionReasons) {
  const std::string tiny = readText(dataPath("tiny.json"));
  const Edit edits[] = {
      {"duplicate id", "{\"id\": 8, \"type\": \"left\"", "{\"id\": 7, \"type\": \"left\"", HandReject::kDuplicateId},
      {"bad type", "\"type\": \"left\"", "\"type\": \"middle\"", HandReject::kBadType},
      {"float id", "{\"id\": 8,", "{\"id\": 8.5,", HandReject::kBadType},
      {"confidence not a number", "\"confidence\": 0.5,", "\"confidence\": \"high\",", HandReject::kMissingField},
      {"confidence > 1", "\"confidence\": 0.5,", "\"confidence\": 1.5,", HandReject::kBadConfidence},
      {"short vector", "\"palmPosition\": [-150, 180, 0]", "\"palmPosition\": [-150, 180]", HandReject::kMissingField},
      {"string component", "\"palmPosition\": [-150, 180, 0]", "\"palmPosition\": [-150, \"x\", 0]", HandReject::kMissingField},
      {"zero direction", "\"direction\": [0, 1, 0]", "\"direction\": [0, 0, 0]", HandReject::kBadDirection},
      {"non-unit normal", "\"palmNormal\": [1, 0, 0]", "\"palmNormal\": [2, 0, 0]", HandReject::kBadDirection},
      {"normal along direction", "\"palmNormal\": [1, 0, 0]", "\"palmNormal\": [0.6, 0.8, 0]", HandReject::kBadDirection},
      {"missing finger", "{\"id\": 82, \"handId\": 8, \"type\": 2,", "{\"id\": 82, \"handId\": 99, \"type\": 2,", HandReject::kMissingFinger},
      {"finger type twice", "{\"id\": 82, \"handId\": 8, \"type\": 2,", "{\"id\": 82, \"handId\": 8, \"type\": 1,", HandReject::kDuplicateFinger},
      {"NaN finger", "\"tipPosition\": [-155, 305, 0]", "\"tipPosition\": [null, 305, 0]", HandReject::kFingerNotFinite},
      // A bone of no length (the tip on the dip), one longer than a hand, a finger at the palm.
      {"tip on its dip", "\"tipPosition\": [-155, 305, 0]", "\"tipPosition\": [-155, 285.5, 0]", HandReject::kDegenerateFinger},
      {"tip 0.2 m out", "\"tipPosition\": [-155, 305, 0]", "\"tipPosition\": [-155, 485.1, 0]", HandReject::kDegenerateFinger},
      {"mcp 0.2 m from the palm", "\"mcpPosition\": [-155, 212, 0]", "\"mcpPosition\": [-155, 212, 200]", HandReject::kDegenerateFinger},
  };
  for (const Edit& e : edits) {
    SCOPED_TRACE(e.what);
    const Recording rec = Recording::fromText(replaced(tiny, e.from, e.to), e.what);
    EXPECT_EQ(rec.stats().handRejects(e.reason), e.reason == HandReject::kDuplicateId ? 2u : 1u) << rec.stats().summary();
    EXPECT_EQ(rec.stats().hands_rejected_total(), rec.stats().handRejects(e.reason)) << rec.stats().summary();
    EXPECT_EQ(rec.frames().size(), 3u);
  }
  // A sixth pointable for a finger that is already there (the tool entry replaced).
  const std::string dup = replaced(tiny, "{\"id\": 90, \"handId\": -1, \"type\": -1, \"tool\": true, \"tipPosition\": [0, 100, 0]}",
                                   "{\"id\": 91, \"handId\": 8, \"type\": 4, \"mcpPosition\": [0, 0, 0], \"pipPosition\": [0, 0, 1], "
                                   "\"dipPosition\": [0, 0, 2], \"tipPosition\": [0, 0, 3]}");
  const Recording rec = Recording::fromText(dup, "dup");
  EXPECT_EQ(rec.stats().handRejects(HandReject::kDuplicateFinger), 1u) << rec.stats().summary();
  EXPECT_EQ(rec.stats().pointables_ignored, 0u);
}

TEST(LeapRecording, FrameRejectionReasonsAndStructureErrors) {
  const std::string tiny = readText(dataPath("tiny.json"));
  {
    const Recording rec = Recording::fromText(replaced(tiny, "\"id\": 101, \"timestamp\": 1010000,", "\"id\": 101,"), "t");
    EXPECT_EQ(rec.stats().frameRejects(FrameReject::kMissingTimestamp), 1u);
    EXPECT_EQ(rec.frames().size(), 2u);
  }
  {
    const Recording rec = Recording::fromText(replaced(tiny, "\"hands\": [], \"pointables\": []", "\"pointables\": []"), "t");
    EXPECT_EQ(rec.stats().frameRejects(FrameReject::kMissingHands), 1u);
  }
  {  // equal timestamps are kept (non-decreasing)
    const Recording rec = Recording::fromText(replaced(tiny, "\"timestamp\": 1010000", "\"timestamp\": 1000000"), "t");
    EXPECT_EQ(rec.frames().size(), 3u);
  }
  auto error = [](const std::string& text) {
    try {
      Recording::fromText(text, "SRC");
    } catch (const RecordingError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  // JSON cannot hold an infinity; an overflowing number makes the file invalid JSON.
  EXPECT_EQ(error(replaced(tiny, "[-150, 180, 0]", "[-150, 1e999, 0]")).rfind("SRC: not valid JSON: ", 0), 0u);
  EXPECT_EQ(error("[1, 2]"), "SRC: expected a JSON object with \"metadata\" and \"frames\"");
  EXPECT_EQ(error("{\"frames\": 3}"), "SRC: no \"frames\" array");
  EXPECT_EQ(error("{\"metadata\": {\"formatVersion\": 2}, \"frames\": [{\"id\": 1}]}"),
            "SRC: format 2 needs the packing structure as the first frame entry");
  EXPECT_EQ(error("{\"frames\": [5, {\"id\": 1}]}").rfind("SRC: no usable frames (frames 0/2 (rejected: not an object 1, missing or non-integer timestamp 1)", 0), 0u);
  EXPECT_EQ(error("{\"metadata\": {\"formatVersion\": \"0.2\"}, \"frames\": []}"),
            "SRC: unsupported formatVersion 0.2 (supported: 0.1, 1, 2)");
}

// Leap SDK 2.0 recordings carry no "confidence" on hands: the format's default (a hand in a frame
// is tracked, confidence 1), counted, instead of rejecting every hand ("no tracked hands").
TEST(LeapRecording, MissingConfidenceIsTheFormatDefault) {
  const std::string tiny = readText(dataPath("tiny.json"));
  std::string sdk2 = tiny;
  size_t removed = 0;
  for (size_t at; (at = sdk2.find("\"confidence\": ")) != std::string::npos; ++removed) {
    const size_t comma = sdk2.find(',', at);
    sdk2.erase(at, comma + 1 - at);
  }
  ASSERT_GT(removed, 0u);
  const Recording with = Recording::fromText(tiny, "tiny");
  const Recording without = Recording::fromText(sdk2, "sdk2");
  EXPECT_EQ(without.stats().hands_rejected_total(), 0u) << without.stats().summary();
  EXPECT_EQ(without.stats().hands_read, with.stats().hands_read);
  EXPECT_EQ(without.stats().hands_confidence_defaulted, without.stats().hands_read);
  EXPECT_EQ(with.stats().hands_confidence_defaulted, 0u);
  EXPECT_NE(without.stats().summary().find("hands without confidence (default 1)"), std::string::npos) << without.stats().summary();
  ASSERT_EQ(without.frames().size(), with.frames().size());
  for (size_t i = 0; i < with.frames().size(); ++i) {
    ASSERT_EQ(without.frames()[i].hands.size(), with.frames()[i].hands.size());
    for (size_t k = 0; k < with.frames()[i].hands.size(); ++k) {
      EXPECT_EQ(without.frames()[i].hands[k].confidence, Recording::kDefaultConfidence);
      EXPECT_EQ(without.frames()[i].hands[k].X_W_palm.p, with.frames()[i].hands[k].X_W_palm.p);
    }
  }
}

}  // namespace
}  // namespace godhand::leap
