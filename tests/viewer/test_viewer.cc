// The viewer's rules without a network: the Foxglove WebSocket hub (subscriptions, latching,
// flow control, rejections), the pose CSV reader, the mesh encoding.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>

#include "common/files.h"
#include "viewer/encode.h"
#include "viewer/feed.h"
#include "viewer/offline.h"
#include "viewer/synthetic.h"

using namespace godhand;
using namespace godhand::viewer;
using nlohmann::json;

namespace {
// A connection that records what it was sent and reports a settable queue.
struct Recorder : Sink {
  std::size_t queued = 0;
  std::vector<std::string> texts, binaries;
  std::size_t buffered() const override { return queued; }
  void sendText(const std::string& t) override { texts.push_back(t); }
  void sendBinary(const std::string& b) override { binaries.push_back(b); }
  json lastStatus() const {
    for (auto it = texts.rbegin(); it != texts.rend(); ++it) {
      json j = json::parse(*it);
      if (j["op"] == "status") return j;
    }
    return nullptr;
  }
};

std::uint32_t le32(const std::string& s, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + static_cast<std::size_t>(i)])) << (8 * i);
  return v;
}
}  // namespace

TEST(ViewerHub, OpenSendsServerInfoAndAdvertisesEveryChannel) {
  Hub hub(viewerChannels(), HubLimits{}, "test");
  Recorder r;
  ASSERT_GT(hub.open(&r), 0);
  ASSERT_EQ(r.texts.size(), 2u);
  json info = json::parse(r.texts[0]), adv = json::parse(r.texts[1]);
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["capabilities"], json::array({"clientPublish"}));
  EXPECT_EQ(adv["op"], "advertise");
  ASSERT_EQ(adv["channels"].size(), viewerChannels().size());
  for (const json& c : adv["channels"]) {
    EXPECT_EQ(c["encoding"], "json");
    EXPECT_TRUE(c["topic"].get<std::string>().rfind("godhand/", 0) == 0);
  }
}

TEST(ViewerHub, MessageDataLayoutIsFoxglove) {
  const std::string m = messageData(0x01020304u, 0x1122334455667788ull, "{}");
  ASSERT_EQ(m.size(), 15u);
  EXPECT_EQ(static_cast<unsigned char>(m[0]), 0x01);
  EXPECT_EQ(le32(m, 1), 0x01020304u);
  EXPECT_EQ(le32(m, 5), 0x55667788u);
  EXPECT_EQ(le32(m, 9), 0x11223344u);
  EXPECT_EQ(m.substr(13), "{}");
}

TEST(ViewerHub, SubscribersGetTheirChannelsAndLatchedStateOnSubscribe) {
  Hub hub(viewerChannels(), HubLimits{}, "test");
  const std::uint32_t state = hub.channelId("godhand/hand_state"), forces = hub.channelId("godhand/contact_forces");
  hub.publish(state, "0", "{\"hand\":0}", 1);
  hub.publish(state, "1", "{\"hand\":1}", 2);
  hub.publish(state, "0", "{\"hand\":0,\"v\":2}", 3);  // replaces hand 0's
  hub.publish(forces, "", "{\"f\":1}", 4);            // not latched: gone
  Recorder r;
  const int id = hub.open(&r);
  hub.onText(id, json{{"op", "subscribe"}, {"subscriptions", {{{"id", 7}, {"channelId", state}}, {{"id", 8}, {"channelId", forces}}}}}.dump());
  ASSERT_EQ(r.binaries.size(), 2u);  // the newest of each hand, nothing of the forces
  EXPECT_EQ(le32(r.binaries[0], 1), 7u);
  EXPECT_EQ(r.binaries[0].substr(13), "{\"hand\":0,\"v\":2}");
  EXPECT_EQ(r.binaries[1].substr(13), "{\"hand\":1}");
  hub.publish(forces, "", "{\"f\":2}", 5);
  ASSERT_EQ(r.binaries.size(), 3u);
  EXPECT_EQ(le32(r.binaries[2], 1), 8u);
  hub.onText(id, R"({"op":"unsubscribe","subscriptionIds":[8]})");
  hub.publish(forces, "", "{\"f\":3}", 6);
  EXPECT_EQ(r.binaries.size(), 3u);
  EXPECT_EQ(hub.stats().rejected, 0u);
}

TEST(ViewerHub, SlowClientGetsTheNewestOfEachKeyOthersUnaffected) {
  HubLimits lim;
  lim.max_queued_bytes = 4000;
  lim.send_below_bytes = 1000;
  Hub hub(viewerChannels(), lim, "test");
  Recorder slow, fast;
  const int a = hub.open(&slow), b = hub.open(&fast);
  const std::uint32_t ch = hub.channelId("godhand/contact_forces");
  for (int id : {a, b}) hub.onText(id, json{{"op", "subscribe"}, {"subscriptions", {{{"id", 1}, {"channelId", ch}}}}}.dump());
  slow.queued = 990;  // above the send-below mark once a 100-byte message is added: it waits
  const std::string payload(100, 'x');
  for (int i = 0; i < 10; ++i) hub.publish(ch, "", payload + std::to_string(i), static_cast<std::uint64_t>(i));
  EXPECT_EQ(slow.binaries.size(), 0u);
  EXPECT_EQ(fast.binaries.size(), 10u);
  Hub::Stats s = hub.stats();
  EXPECT_EQ(s.dropped, 9u);  // each newer one superseded the one waiting
  EXPECT_EQ(s.superseded, 9u);
  ASSERT_EQ(s.per_client.size(), 2u);
  EXPECT_EQ(s.per_client[0].waiting, 1);
  EXPECT_EQ(s.per_client[1].dropped, 0u);
  hub.flush();  // still full: nothing goes
  EXPECT_EQ(slow.binaries.size(), 0u);
  slow.queued = 0;  // it caught up: the newest goes out
  hub.flush();
  ASSERT_EQ(slow.binaries.size(), 1u);
  EXPECT_EQ(slow.binaries[0].substr(13), payload + "9");
  EXPECT_EQ(hub.stats().per_client[0].waiting, 0);
  hub.publish(ch, "", payload, 11);
  EXPECT_EQ(slow.binaries.size(), 2u);
}

// The old rule (send what fits under the cap, drop the rest) starved large messages while small
// ones still fitted: a slow page drew the targets (small HandTargets) but a God hand frozen at its
// start (larger HandStates). Now each channel and key waits in line with its newest message.
TEST(ViewerHub, LargeMessagesAreNotStarvedBySmallOnes) {
  HubLimits lim;
  lim.max_queued_bytes = 100000;
  lim.send_below_bytes = 1000;
  Hub hub(viewerChannels(), lim, "test");
  Recorder r;
  const int id = hub.open(&r);
  const std::uint32_t state = hub.channelId("godhand/hand_state"), target = hub.channelId("godhand/hand_target");
  hub.onText(id, json{{"op", "subscribe"}, {"subscriptions", {{{"id", 1}, {"channelId", state}}, {{"id", 2}, {"channelId", target}}}}}.dump());
  r.queued = 900;  // room for small messages only
  const std::string big(500, 's'), small(50, 't');
  std::size_t sent_before = r.binaries.size();
  for (int i = 0; i < 20; ++i) {
    hub.publish(state, "0", big + std::to_string(i), static_cast<std::uint64_t>(2 * i));
    hub.publish(target, "0", small + std::to_string(i), static_cast<std::uint64_t>(2 * i + 1));
  }
  // The state waits at the head of the line; the small targets queue behind it, not past it.
  EXPECT_EQ(r.binaries.size(), sent_before);
  r.queued = 0;
  hub.flush();
  ASSERT_EQ(r.binaries.size(), sent_before + 2);
  EXPECT_EQ(le32(r.binaries[sent_before], 1), 1u);
  EXPECT_EQ(r.binaries[sent_before].substr(13), big + "19");
  EXPECT_EQ(r.binaries[sent_before + 1].substr(13), small + "19");
  const Hub::Stats s = hub.stats();
  EXPECT_EQ(s.superseded, 38u);
  EXPECT_EQ(s.dropped, 38u);
  // A message that could never be sent (over max_queued_bytes) is dropped and counted at once.
  hub.publish(state, "1", std::string(200000, 'x'), 99);
  EXPECT_EQ(hub.stats().dropped, 39u);
  EXPECT_EQ(hub.stats().per_client[0].waiting, 0);
  // Unsubscribing discards what waited for that subscription (the client no longer wants it).
  r.queued = 5000;
  hub.publish(state, "0", big, 100);
  EXPECT_EQ(hub.stats().per_client[0].waiting, 1);
  hub.onText(id, R"({"op":"unsubscribe","subscriptionIds":[1]})");
  EXPECT_EQ(hub.stats().per_client[0].waiting, 0);
  r.queued = 0;
  hub.flush();
  EXPECT_EQ(r.binaries.size(), sent_before + 2);
  // A client that closes with messages waiting: they count as dropped (never sent).
  r.queued = 5000;
  hub.publish(target, "0", small, 101);
  hub.close(id);
  EXPECT_EQ(hub.stats().dropped, 40u);
}

// A page starved of CPU handles its messages seconds after the kernel took them; a page that
// acks is held to max_unacked messages in flight, the newest of each key waiting meanwhile.
TEST(ViewerHub, AckingClientIsHeldToItsUnhandledMessages) {
  HubLimits lim;
  lim.max_unacked = 3;
  Hub hub(viewerChannels(), lim, "test");
  Recorder r;
  const int id = hub.open(&r);
  const std::uint32_t state = hub.channelId("godhand/hand_state");
  hub.onText(id, json{{"op", "subscribe"}, {"subscriptions", {{{"id", 1}, {"channelId", state}}}}}.dump());
  // Before its first ack a client is held to the byte rule only (other Foxglove clients never ack).
  for (int i = 0; i < 5; ++i) hub.publish(state, "0", "{\"v\":" + std::to_string(i) + "}", static_cast<std::uint64_t>(i));
  ASSERT_EQ(r.binaries.size(), 5u);
  hub.onText(id, R"({"op":"ack","received":2})");  // 3 in flight: the next waits
  EXPECT_EQ(hub.stats().rejected, 0u);
  for (int i = 5; i < 9; ++i) hub.publish(state, "0", "{\"v\":" + std::to_string(i) + "}", static_cast<std::uint64_t>(i));
  EXPECT_EQ(r.binaries.size(), 5u);
  EXPECT_EQ(hub.stats().superseded, 3u);
  hub.onText(id, R"({"op":"ack","received":5})");  // all handled: the newest goes out at once
  ASSERT_EQ(r.binaries.size(), 6u);
  EXPECT_EQ(r.binaries[5].substr(13), "{\"v\":8}");
  // Bad acks: counted and answered, the state unchanged.
  for (const char* bad : {R"({"op":"ack","received":7})", R"({"op":"ack","received":4})", R"({"op":"ack","received":-1})",
                          R"({"op":"ack","received":1.5})", R"({"op":"ack"})"})
    hub.onText(id, bad);
  EXPECT_EQ(hub.stats().rejected, 5u);
  EXPECT_EQ(hub.stats().per_client[0].acked, 5u);
  hub.onText(id, R"({"op":"ack","received":6})");
  EXPECT_EQ(hub.stats().rejected, 5u);
}

TEST(ViewerHub, BadClientMessagesAreCountedAndAnsweredNeverFatal) {
  Hub hub(viewerChannels(), HubLimits{}, "test");
  Recorder r;
  const int id = hub.open(&r);
  const char* bad[] = {"", "not json", "[1,2]", "{}", R"({"op":5})", R"({"op":"fly"})", R"({"op":"subscribe"})",
                       R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]})",
                       R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":999}]})",
                       R"({"op":"subscribe","subscriptions":[{"id":1.5,"channelId":1}]})",
                       R"({"op":"unsubscribe","subscriptionIds":[42]})",
                       R"({"op":"advertise","channels":[{"id":1,"topic":"godhand/hand_state","encoding":"json"}]})",
                       R"({"op":"advertise","channels":[{"id":1,"topic":"godhand/synthetic_target","encoding":"cdr"}]})"};
  std::uint64_t n = 0;
  for (const char* m : bad) {
    hub.onText(id, m);
    ++n;
    EXPECT_EQ(hub.stats().rejected, n) << m;
    EXPECT_EQ(r.lastStatus()["level"], 2) << m;
  }
  hub.onText(id, std::string(70 * 1024, ' '));
  EXPECT_EQ(hub.stats().rejected, ++n);
  for (const std::string& b : {std::string("\x01\x00", 2), std::string("\x02\x01\x00\x00\x00{}", 7), std::string("\x01\x09\x00\x00\x00{}", 7)}) {
    hub.onBinary(id, b);
    EXPECT_EQ(hub.stats().rejected, ++n);
  }
  // Still served after all that.
  hub.onText(id, R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":5}]})");
  hub.publish(5, "", "{}", 1);
  EXPECT_EQ(r.binaries.size(), 1u);
  EXPECT_EQ(hub.stats().rejected, n);
}

TEST(ViewerHub, ClientPublishOnTheSyntheticTopicReachesTheHandler) {
  Hub hub(viewerChannels(), HubLimits{}, "test");
  std::vector<ClientPublish> got;
  hub.onClientPublish([&](const ClientPublish& p) { got.push_back(p); });
  Recorder r;
  const int id = hub.open(&r);
  hub.onText(id, R"({"op":"advertise","channels":[{"id":3,"topic":"godhand/synthetic_target","encoding":"json","schemaName":"x"}]})");
  hub.onBinary(id, std::string("\x01\x03\x00\x00\x00{\"hand\":0}", 15));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].topic, kSyntheticTargetTopic);
  EXPECT_EQ(got[0].payload, "{\"hand\":0}");
  hub.onText(id, R"({"op":"unadvertise","channelIds":[3]})");
  hub.onBinary(id, std::string("\x01\x03\x00\x00\x00{}", 7));
  EXPECT_EQ(got.size(), 1u);
  EXPECT_EQ(hub.stats().rejected, 1u);
}

TEST(ViewerHub, RefusesBeyondMaxClientsAndForgetsClosedOnes) {
  HubLimits lim;
  lim.max_clients = 2;
  Hub hub(viewerChannels(), lim, "test");
  Recorder a, b, c;
  const int ia = hub.open(&a);
  EXPECT_GT(hub.open(&b), 0);
  EXPECT_EQ(hub.open(&c), 0);
  hub.close(ia);
  EXPECT_GT(hub.open(&c), 0);
  EXPECT_EQ(hub.stats().refused, 1u);
  EXPECT_EQ(hub.stats().clients, 2);
}

namespace {
const char* kHeader = "frame,hand,body,shape,radius,half_length,hx,hy,hz,px,py,pz,qw,qx,qy,qz";
}

TEST(ViewerPoses, ReadsBenchCsvByHeaderNames) {
  // Columns shuffled and an extra one: read by name.
  const std::string text =
      "hand,frame,extra,body,shape,radius,half_length,hx,hy,hz,px,py,pz,qw,qx,qy,qz\n"
      "right,1,a,palm,box,0.01,0,0.04,0.05,0.01,0.1,0.2,0.3,1,0,0,0\n"
      "right,1,a,index1,capsule,0.008,0.02,0,0,0,0.1,0.25,0.3,0.70710678118654757,0.70710678118654757,0,0\n"
      "left,1,a,palm,box,0.01,0,0.04,0.05,0.01,-0.1,0.2,0.3,1,0,0,0\n"
      "right,2,a,palm,box,0.01,0,0.04,0.05,0.01,0.11,0.2,0.3,1,0,0,0\n"
      "right,2,a,index1,capsule,0.008,0.02,0,0,0,0.11,0.25,0.3,1,0,0,0\n";
  const PoseFile f = parsePosesCsv(text, "t.csv");
  ASSERT_EQ(f.frames, (std::vector<std::int64_t>{1, 2}));
  ASSERT_EQ(f.hands.size(), 2u);
  EXPECT_FALSE(f.has_targets);
  EXPECT_EQ(f.rows, 5u);
  const PoseTrack& r = f.hands[0];
  EXPECT_EQ(r.hand, "right");
  EXPECT_EQ(r.bodies, (std::vector<std::string>{"palm", "index1"}));
  EXPECT_EQ(r.shapes[0][0], 2.0);
  EXPECT_EQ(r.shapes[1][0], 0.0);
  EXPECT_DOUBLE_EQ(r.shapes[1][2], 0.02);
  ASSERT_EQ(r.poses[1].size(), 14u);
  EXPECT_DOUBLE_EQ(r.poses[1][0], 0.11);
  EXPECT_DOUBLE_EQ(r.poses[0][7 + 4], 0.70710678118654757);
  // The left hand has no rows in frame 2.
  EXPECT_TRUE(f.hands[1].poses[1].empty());
  json j = poseFileJson(f);
  EXPECT_EQ(j["hands"][1]["poses"][1], nullptr);
}

TEST(ViewerPoses, TargetColumnsMayBeEmptyPerRow) {
  const std::string text = std::string(kHeader) + ",tpx,tpy,tpz,tqw,tqx,tqy,tqz\n" +
                           "1,right,palm,sphere,0.01,0,0,0,0,0,0,0,1,0,0,0,0.01,0.02,0.03,1,0,0,0\n"
                           "1,right,tip,sphere,0.01,0,0,0,0,0,0,0,1,0,0,0,,,,,,,\n";
  const PoseFile f = parsePosesCsv(text, "t.csv");
  ASSERT_TRUE(f.has_targets);
  EXPECT_DOUBLE_EQ(f.hands[0].targets[0][2], 0.03);
  EXPECT_TRUE(std::isnan(f.hands[0].targets[0][7]));
  EXPECT_EQ(poseFileJson(f)["hands"][0]["targets"][0][7], nullptr);
}

TEST(ViewerPoses, RejectsBadFilesWithFileAndLine) {
  auto error = [](const std::string& text) {
    try {
      parsePosesCsv(text, "p.csv");
    } catch (const PosesError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string row = "1,right,palm,sphere,0.01,0,0,0,0,0,0,0,1,0,0,0\n";
  EXPECT_EQ(error(""), "p.csv:1: empty file (expected a header line)");
  EXPECT_NE(error("frame,hand\n1,right\n").find("p.csv:1: missing column 'body'"), std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n").find("no pose rows"), std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n1,right,palm\n").find("p.csv:2: 3 cells"), std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n1,right,palm,sphere,0.01,0,0,0,0,nan,0,0,1,0,0,0\n").find("p.csv:2: px"), std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n1,right,palm,sphere,0.01,0,0,0,0,0,0,0,2,0,0,0\n").find("quaternion not unit"),
            std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n1,right,palm,cone,0.01,0,0,0,0,0,0,0,1,0,0,0\n").find("shape: 'cone'"), std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n2,right,palm,sphere,0.01,0,0,0,0,0,0,0,1,0,0,0\n" + row).find("p.csv:3: frame 1 after frame 2"),
            std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n" + row + row).find("twice in frame 1"), std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + "\n" + row + "2,right,palm,sphere,0.02,0,0,0,0,0,0,0,1,0,0,0\n").find("changes shape"),
            std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + ",tpx,tpy\n").find("target columns must be all"), std::string::npos);
  EXPECT_NE(error(std::string(kHeader) + ",tpx,tpy,tpz,tqw,tqx,tqy,tqz\n1,right,palm,sphere,0.01,0,0,0,0,0,0,0,1,0,0,0,1,,,,,,\n")
                .find("all seven or none"),
            std::string::npos);
}

TEST(ViewerMesh, BinaryLayoutRoundTrips) {
  geo::TriangleMesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1.5, -2)};
  m.triangles = {{0, 1, 2}};
  const std::string b = meshBinary(m);
  ASSERT_EQ(b.size(), 12u + 36u + 12u);
  EXPECT_EQ(b.substr(0, 4), "GHM1");
  EXPECT_EQ(le32(b, 4), 3u);
  EXPECT_EQ(le32(b, 8), 1u);
  float z = 0;
  const std::uint32_t bits = le32(b, 12 + 8 * 4);
  std::memcpy(&z, &bits, 4);
  EXPECT_EQ(z, -2.0f);
  EXPECT_EQ(le32(b, 48 + 8), 2u);
}

TEST(ViewerSynthetic, CommandsAreParsedStrictly) {
  int hand = -1;
  Vec3 off;
  std::string why;
  ASSERT_TRUE(parseSyntheticCommand(R"({"hand":1,"offset":[0.01,-0.02,0.5]})", &hand, &off, &why)) << why;
  EXPECT_EQ(hand, 1);
  EXPECT_DOUBLE_EQ(off.y(), -0.02);
  for (const char* bad : {"", "[]", R"({"offset":[0,0,0]})", R"({"hand":-1,"offset":[0,0,0]})", R"({"hand":0,"offset":[0,0]})",
                          R"({"hand":0,"offset":[0,0,2]})", R"({"hand":0,"offset":[0,"x",0]})", R"({"hand":0.5,"offset":[0,0,0]})"}) {
    EXPECT_FALSE(parseSyntheticCommand(bad, &hand, &off, &why)) << bad;
    EXPECT_FALSE(why.empty());
  }
}

TEST(ViewerSynthetic, TargetIsTheModelAtRestAtTheCommandedFrame) {
  const HandModel model = loadHandModel(std::string(GODHAND_MODELS_DIR) + "/hand16_right.pbtxt");
  Pose X;
  X.p = Vec3(0.1, 0.2, 0.3);
  msg::HandTarget t;
  syntheticTarget(model, X, 0, "right", 7, 3, 123, &t);
  const std::vector<Pose> rest = model.restPoses(X);
  ASSERT_EQ(t.targets().size(), model.bodies.size());
  ASSERT_EQ(t.driven().size(), model.bodies.size());
  EXPECT_TRUE(t.tracked());
  EXPECT_EQ(t.stamp().frame(), 3u);
  EXPECT_EQ(t.stamp().run(), 7u);
  for (std::size_t b = 0; b < rest.size(); ++b) {
    EXPECT_EQ(t.targets()[b].p()[0], rest[b].p.x());
    EXPECT_EQ(t.targets()[b].q()[0], rest[b].q.w());
    EXPECT_TRUE(t.driven()[b]);
  }
}

TEST(ViewerEncode, HandStateCarriesPosesShapesFlagsAndNullsForNonFinite) {
  msg::HandState s;
  s.hand(1);
  s.cluster("left");
  s.stamp().frame(42);
  s.stamp().source_time_ns(1000);
  s.stale(true);
  s.held(false);
  s.poses().resize(2);
  s.poses()[0].p()[0] = 0.25;
  s.poses()[0].q()[0] = 1.0;
  s.poses()[1].p()[1] = std::numeric_limits<double>::quiet_NaN();
  s.shapes().resize(2);
  s.shapes()[0].type(0);
  s.shapes()[0].radius(0.01);
  s.shapes()[0].half_length(0.02);
  s.shapes()[1].type(2);
  s.shapes()[1].half_extents()[2] = 0.013;
  s.solver_times().solve_us(12.5);
  const json j = handStateJson(s, 5000, 0.0007);
  const json round = json::parse(j.dump());  // valid JSON even with the NaN
  EXPECT_EQ(round["hand"], 1);
  EXPECT_EQ(round["cluster"], "left");
  EXPECT_EQ(round["stamp"]["frame"], 42);
  EXPECT_EQ(round["recv_ns"], 5000);
  EXPECT_EQ(round["stale"], true);
  EXPECT_EQ(round["held"], false);
  EXPECT_DOUBLE_EQ(round["penetration_m"].get<double>(), 0.0007);
  EXPECT_EQ(round["poses"][0], json::array({0.25, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0}));
  EXPECT_TRUE(round["poses"][1][1].is_null());
  EXPECT_EQ(round["shapes"][0], json::array({0, 0.01, 0.02, 0.0, 0.0, 0.0}));
  EXPECT_EQ(round["shapes"][1][0], 2);
  EXPECT_DOUBLE_EQ(round["shapes"][1][5].get<double>(), 0.013);
  EXPECT_DOUBLE_EQ(round["times_us"]["solve"].get<double>(), 12.5);
  EXPECT_TRUE(handStateJson(s, 5000, -1.0)["penetration_m"].is_null());  // unknown
}

TEST(ViewerEncode, ContactsAndSceneState) {
  msg::ContactForces f;
  f.contacts().resize(1);
  f.contacts()[0].object(3);
  f.contacts()[0].body(7);
  f.contacts()[0].n()[2] = 1.0;
  f.contacts()[0].lambda(0.5);
  const json c = contactForcesJson(f, 1);
  EXPECT_EQ(c["contacts"][0]["object"], 3);
  EXPECT_EQ(c["contacts"][0]["body"], 7);
  EXPECT_EQ(c["contacts"][0]["n"], json::array({0.0, 0.0, 1.0}));
  EXPECT_DOUBLE_EQ(c["contacts"][0]["lambda"].get<double>(), 0.5);
  msg::SceneState ss;
  ss.objects().resize(1);
  ss.objects()[0].index(4);
  ss.objects()[0].pose().q()[0] = 1.0;
  ss.objects()[0].pose().p()[2] = 0.1;
  const json j = sceneStateJson(ss, 2);
  EXPECT_EQ(j["objects"][0]["index"], 4);
  EXPECT_DOUBLE_EQ(j["objects"][0]["pose"][2].get<double>(), 0.1);
}
