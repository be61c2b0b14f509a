// Core stage structs <-> wire types (services/runtime/convert.h), no DDS involved.
// Oracles: bit-for-bit equality (memcmp of every double) after a round trip; the in-process
// Pipeline, replayed against the same stages with every exchanged struct passed through the wire
// types (what the services do), must give bit-identical poses on a real recording and scene.
#include <gtest/gtest.h>

#include <functional>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "common/files.h"
#include "leap/leap_recording.h"
#include "leap/retarget.h"
#include "math/stats.h"
#include "model/hand_model.h"
#include "physics/physics_world.h"
#include "pipeline/pipeline.h"
#include "runtime/convert.h"
#include "scene/scene_file.h"

namespace godhand {
namespace {

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool sameBits(const Vec3& a, const Vec3& b) { return sameBits(a.x(), b.x()) && sameBits(a.y(), b.y()) && sameBits(a.z(), b.z()); }
bool sameBits(const Pose& a, const Pose& b) {
  return sameBits(a.p, b.p) && sameBits(a.q.w(), b.q.w()) && sameBits(a.q.x(), b.q.x()) && sameBits(a.q.y(), b.q.y()) &&
         sameBits(a.q.z(), b.q.z());
}

// Poses whose doubles use every bit (not round numbers).
Pose oddPose(int i) {
  const double t = 0.1 + 0.37 * i;
  Pose X;
  X.p = Vec3(std::sin(t) / 3.0, std::cos(t) / 7.0, t / 11.0);
  X.q = Quat(Eigen::AngleAxisd(t, Vec3(1.0, 2.0 / 3.0, -0.3).normalized()));
  return X;
}

TEST(Convert, PoseRoundTripIsBitExact) {
  for (int i = 0; i < 100; ++i) {
    msg::Pose w;
    svc::toWire(oddPose(i), &w);
    EXPECT_TRUE(sameBits(svc::fromWire(w), oddPose(i))) << i;
  }
}

TEST(Convert, ProposalRoundTripIsBitExactAndChecked) {
  HandProposal p;
  p.frame = 7;
  p.scene_frame = 6;
  p.tracked = p.started = true;
  for (int b = 0; b < 16; ++b) {
    p.X_old.push_back(oddPose(b));
    p.X_new.push_back(oddPose(b + 50));
  }
  p.diag.contacts = 9;
  p.loads.push_back(ContactLoad{3, 2, Vec3(0.1, 0.2, 1.0 / 3.0), Vec3(0, 0.6, 0.8), 1.0 / 7.0});
  p.diag.kkt = 1e-17;
  p.diag.status = SolveStatus::Stalled;
  p.diag.flags = 5;
  p.diag.joint_errors = JointErrors{1e-11 / 3.0, 2e-9, 0.0};
  msg::HandProposal w;
  svc::toWire(p, &w);
  w.stamp().frame(7);
  HandProposal q;
  std::string why;
  ASSERT_TRUE(svc::fromWire(w, 16, 4, &q, &why)) << why;
  EXPECT_EQ(q.frame, 7u);
  EXPECT_EQ(q.scene_frame, 6u);
  for (int b = 0; b < 16; ++b) EXPECT_TRUE(sameBits(q.X_old[b], p.X_old[b]) && sameBits(q.X_new[b], p.X_new[b])) << b;
  ASSERT_EQ(q.loads.size(), 1u);
  EXPECT_TRUE(sameBits(q.loads[0].p_W, p.loads[0].p_W) && sameBits(q.loads[0].lambda, p.loads[0].lambda));
  EXPECT_EQ(q.diag.status, SolveStatus::Stalled);
  EXPECT_TRUE(sameBits(q.diag.joint_errors.gap, p.diag.joint_errors.gap));

  // Rejections name the field.
  EXPECT_FALSE(svc::fromWire(w, 15, 4, &q, &why));
  EXPECT_NE(why.find("x_old"), std::string::npos) << why;
  msg::HandProposal bad = w;
  bad.x_new()[3].p()[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(svc::fromWire(bad, 16, 4, &q, &why));
  EXPECT_NE(why.find("x_new[3]"), std::string::npos) << why;
  bad = w;
  bad.x_old()[0].q() = {0.5, 0.0, 0.0, 0.0};  // not unit
  EXPECT_FALSE(svc::fromWire(bad, 16, 4, &q, &why));
  bad = w;
  bad.loads()[0].object(4);  // the scene has objects 0..3
  EXPECT_FALSE(svc::fromWire(bad, 16, 4, &q, &why));
  EXPECT_NE(why.find("out of range"), std::string::npos) << why;
  // Diagnostics no step can produce (a hostile or corrupt sample): rejected with the field named,
  // never carried into a HandState (reviewed: NaN kkt/toc/joint errors reached HandState).
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::pair<std::function<void(msg::HandProposal&)>, const char*> hostile[] = {
      {[&](msg::HandProposal& m) { m.kkt(nan); }, "kkt"},
      {[&](msg::HandProposal& m) { m.kkt(-1.0); }, "kkt"},
      {[&](msg::HandProposal& m) { m.toc(nan); }, "toc"},
      {[&](msg::HandProposal& m) { m.toc(1.5); }, "toc"},
      {[&](msg::HandProposal& m) { m.joint_gap(nan); }, "joint errors"},
      {[&](msg::HandProposal& m) { m.joint_limit(-1e-3); }, "joint errors"},
      {[&](msg::HandProposal& m) { m.times().solve_us(std::numeric_limits<double>::infinity()); }, "solver times"},
      {[&](msg::HandProposal& m) { m.status(99); }, "status"},
      {[&](msg::HandProposal& m) { m.substeps(0xffffffffu); }, "substep"},
      {[&](msg::HandProposal& m) { m.contact_count(0xffffffffu); }, "contact"},
      {[&](msg::HandProposal& m) { m.loads()[0].lambda(-2.0); }, "negative force"},
  };
  for (const auto& [spoil, field] : hostile) {
    bad = w;
    spoil(bad);
    EXPECT_FALSE(svc::fromWire(bad, 16, 4, &q, &why)) << field;
    EXPECT_NE(why.find(field), std::string::npos) << why;
  }
  // A diverged solve's residual (+inf) is a real step's: carried, not rejected.
  bad = w;
  bad.kkt(std::numeric_limits<double>::infinity());
  EXPECT_TRUE(svc::fromWire(bad, 16, 4, &q, &why)) << why;

  // The same checks on a HandState (what solvers adopt and the launcher scores).
  HandResult r;
  r.X = p.X_new;
  r.diag = p.diag;
  r.force_N = 0.5;
  HandModel model;
  model.bodies.resize(16);
  msg::HandState ws;
  svc::toWire(r, model, false, &ws);
  HandResult rr;
  ASSERT_TRUE(svc::fromWire(ws, 16, &rr, &why)) << why;
  msg::HandState bad_state = ws;
  bad_state.toc(nan);
  EXPECT_FALSE(svc::fromWire(bad_state, 16, &rr, &why));
  EXPECT_NE(why.find("toc"), std::string::npos) << why;
  bad_state = ws;
  bad_state.force_n(nan);
  EXPECT_FALSE(svc::fromWire(bad_state, 16, &rr, &why));
}

TEST(Convert, TargetsRejectBadCountsAndUndrivenPalm) {
  msg::HandTarget t;
  t.tracked(true);
  for (int b = 0; b < 16; ++b) {
    t.targets().emplace_back();
    svc::toWire(oddPose(b), &t.targets().back());
    t.driven().push_back(true);
  }
  std::vector<Pose> X;
  std::vector<unsigned char> driven;
  std::string why;
  ASSERT_TRUE(svc::fromWire(t, 16, &X, &driven, &why)) << why;
  EXPECT_TRUE(sameBits(X[5], oddPose(5)));
  EXPECT_FALSE(svc::fromWire(t, 6, &X, &driven, &why));
  t.driven()[0] = false;
  EXPECT_FALSE(svc::fromWire(t, 16, &X, &driven, &why));
  EXPECT_NE(why.find("palm"), std::string::npos) << why;
}

TEST(Convert, SourceCountsRoundTripWithinTheWireBounds) {
  SourceCounts c;
  c.received = 500;
  c.accepted = 400;
  for (int i = 0; i < 20; ++i) c.rejected["reason " + std::to_string(10 + i)] = 5;  // 20 reasons: 4 over the bound
  c.rejected[std::string(70, 'z')] = 1;                                             // a name over string<64>
  msg::SourceCounts w;
  svc::toWire(99, c, &w);
  EXPECT_EQ(w.rejected().size(), kWireReasons);
  std::uint64_t run = 0;
  const SourceCounts back = svc::fromWire(w, &run);
  EXPECT_EQ(run, 99u);
  EXPECT_EQ(back.received, 500u);
  EXPECT_EQ(back.accepted, 400u);
  EXPECT_EQ(back.rejectedTotal(), c.rejectedTotal());  // bounded, nothing lost
  EXPECT_EQ(back.rejected.count(kOtherReasons), 1u);
  for (const auto& [reason, n] : back.rejected) EXPECT_LE(reason.size(), kWireReasonChars);

  SourceCounts small{12, 9, {{"parse error", 2}, {"NaN/Inf", 1}}, {}};
  svc::toWire(7, small, &w);
  EXPECT_EQ(svc::fromWire(w, &run), small);  // within the bounds: exact
  EXPECT_EQ(run, 7u);

  // Not played, by reason (at most kWireNotPlayedReasons on the wire; the total kept).
  SourceCounts cut{40, 40, {}, {{kNotPlayedYet, 131}, {"beyond --frames 171", 3}}};
  svc::toWire(8, cut, &w);
  EXPECT_EQ(svc::fromWire(w, &run), cut);
  for (int i = 0; i < 6; ++i) cut.not_played["reason " + std::to_string(i)] = 1;
  svc::toWire(8, cut, &w);
  EXPECT_EQ(w.not_played().size(), kWireNotPlayedReasons);
  EXPECT_EQ(svc::fromWire(w, &run).notPlayedTotal(), cut.notPlayedTotal());
  msg::ServiceStatus hostile;
  msg::ReasonCount huge;
  huge.reason("not played yet");
  huge.count(std::uint64_t{1} << 60);
  hostile.source().not_played().push_back(huge);
  std::string why;
  EXPECT_FALSE(svc::plausible(hostile, &why));
  EXPECT_NE(why.find("2^53"), std::string::npos) << why;
}

TEST(Convert, ForcesAndSceneRoundTrip) {
  ForceSet f;
  f.frame = 3;
  f.loads.push_back(AppliedLoad{1, 0, 4, Vec3(0.1, 0.2, 0.3), Vec3(0, 0, 1), 2.0 / 3.0});
  GodBody g;
  g.hand = 1;
  g.body = 2;
  g.shape.type = ShapeType::Capsule;
  g.shape.radius = 0.008;
  g.shape.half_length = 0.02 / 3.0;
  g.X = oddPose(3);
  f.bodies.push_back(g);
  Scene scene;  // two objects at the origin for the wrench summary
  for (int i = 0; i < 2; ++i) {
    SceneObject o;
    o.index = i;
    scene.objects.push_back(o);
  }
  CollisionWorld world(scene);
  msg::ContactForces w;
  svc::toWire(f, world, &w);
  w.stamp().frame(3);
  ASSERT_EQ(w.objects().size(), 1u);
  EXPECT_DOUBLE_EQ(w.objects()[0].force()[2], -2.0 / 3.0);                 // −λ n
  EXPECT_DOUBLE_EQ(w.objects()[0].torque()[0], 0.2 * (-2.0 / 3.0));        // (p × f)_x = p_y f_z
  ForceSet r;
  std::string why;
  ASSERT_TRUE(svc::fromWire(w, 2, &r, &why)) << why;
  EXPECT_TRUE(sameBits(r.loads[0].lambda, f.loads[0].lambda) && sameBits(r.bodies[0].X, g.X) &&
              sameBits(r.bodies[0].shape.half_length, g.shape.half_length));
  w.contacts()[0].lambda(-1.0);
  EXPECT_FALSE(svc::fromWire(w, 2, &r, &why));

  SceneSnapshot s;
  s.frame = 9;
  s.objects.push_back(ObjectMotion{1, oddPose(8), Vec3(1.0 / 3.0, 0, 0), Vec3(0, 0, 1e-300)});
  msg::SceneState ws;
  svc::toWire(s, &ws);
  ws.stamp().frame(9);
  SceneSnapshot rs;
  ASSERT_TRUE(svc::fromWire(ws, 2, &rs, &why)) << why;
  EXPECT_TRUE(sameBits(rs.objects[0].X, s.objects[0].X) && sameBits(rs.objects[0].w, s.objects[0].w));
  EXPECT_FALSE(svc::fromWire(ws, 1, &rs, &why));  // object index 1 out of range
  msg::SceneState bad_scene = ws;
  bad_scene.objects()[0].v()[0] = std::nan("");
  EXPECT_FALSE(svc::fromWire(bad_scene, 2, &rs, &why));
  EXPECT_NE(why.find("velocity"), std::string::npos) << why;
  w.contacts()[0].lambda(1.0);
  w.god_bodies()[0].shape().half_length(-0.01);
  EXPECT_FALSE(svc::fromWire(w, 2, &r, &why));
  EXPECT_NE(why.find("god_bodies[0]"), std::string::npos) << why;
}

// A scene at the wire's bound (10,000 dynamic objects, issue 14) goes through bit for bit; one
// hostile object among them (an index out of range, a NaN or non-unit pose) makes the whole
// sample a rejection with its reason, as with a small scene.
TEST(Convert, SceneAtTheWireBoundRoundTripsAndHostileObjectsAreRejected) {
  SceneSnapshot s;
  s.frame = 4;
  for (int i = 0; i < static_cast<int>(svc::kMaxSceneObjects); ++i)
    s.objects.push_back(ObjectMotion{i, oddPose(i), Vec3(1e-3 * i, 0, 0), Vec3::Zero()});
  msg::SceneState ws;
  svc::toWire(s, &ws);
  ASSERT_EQ(ws.objects().size(), svc::kMaxSceneObjects);
  const int n = static_cast<int>(svc::kMaxSceneObjects);
  SceneSnapshot rs;
  std::string why;
  ASSERT_TRUE(svc::fromWire(ws, n, &rs, &why)) << why;
  ASSERT_EQ(rs.objects.size(), svc::kMaxSceneObjects);
  EXPECT_TRUE(sameBits(rs.objects.back().X, s.objects.back().X) && sameBits(rs.objects.back().v, s.objects.back().v));
  msg::SceneState bad = ws;
  bad.objects().back().index(n);
  EXPECT_FALSE(svc::fromWire(bad, n, &rs, &why));
  EXPECT_NE(why.find("objects[9999]: index out of range"), std::string::npos) << why;
  bad = ws;
  bad.objects()[5000].pose().p()[1] = std::nan("");
  EXPECT_FALSE(svc::fromWire(bad, n, &rs, &why));
  EXPECT_NE(why.find("objects[5000]: pose not finite or not unit"), std::string::npos) << why;
  bad = ws;
  bad.objects()[7].pose().q()[0] = 2.0;
  EXPECT_FALSE(svc::fromWire(bad, n, &rs, &why));
  EXPECT_NE(why.find("objects[7]: pose not finite or not unit"), std::string::npos) << why;
}

// The services' data path without the network: every struct the stages exchange goes through
// the wire types. Must equal the in-process Pipeline bit for bit on a real recording and scene.
TEST(Convert, StagesThroughTheWireEqualThePipeline) {
  const leap::Recording rec = leap::Recording::load(std::string(GODHAND_DEPLOY_DIR) + "/recordings/confidence2-49fps.json");
  const Scene scene = loadScene(std::string(GODHAND_DEPLOY_DIR) + "/scenes/default.pbtxt");
  const HandModel right = loadHandModel(std::string(GODHAND_DEPLOY_DIR) + "/models/hand16_right.pbtxt");
  const HandModel left = loadHandModel(std::string(GODHAND_DEPLOY_DIR) + "/models/hand16_left.pbtxt");
  const std::vector<const HandModel*> models = {&right, &left};
  const double rate = rec.meanFrameRate();
  PipelineParams params;
  params.step.dt = 1.0 / rate;
  const PhysicsParams physics = physicsParamsFor(rate, 240);

  Pipeline pipe(scene, models, params, physics);
  std::vector<std::unique_ptr<HandSolver>> solvers;
  for (const HandModel* m : models) solvers.push_back(std::make_unique<HandSolver>(scene, *m, params));
  Resolver resolver(scene, models, params);
  SceneStage stage(scene, params, physics);
  const int objects = static_cast<int>(scene.objects.size());
  std::string why;
  // Scene 0 through the wire.
  msg::SceneState ws;
  SceneSnapshot snap;
  svc::toWire(stage.initial(), &ws);
  ASSERT_TRUE(svc::fromWire(ws, objects, &snap, &why)) << why;
  for (auto& s : solvers) s->setScene(snap);
  resolver.setScene(snap);

  std::vector<leap::Retargeter> retarget = {leap::Retargeter(right), leap::Retargeter(left)};
  std::vector<std::vector<Pose>> targets(2), wire_targets(2);
  std::vector<std::vector<unsigned char>> has(2), wire_has(2);
  std::vector<HandProposal> props(2);
  std::vector<const HandProposal*> ptrs(2);
  ResultHash h_pipe, h_wire;
  int compared = 0;
  const size_t frames = std::min<size_t>(rec.frames().size(), 80);
  for (size_t fi = 0; fi < frames; ++fi) {
    std::vector<HandInput> in(2), win(2);
    for (int h = 0; h < 2; ++h) {
      const leap::TrackedHand* th = nullptr;
      for (const leap::TrackedHand& c : rec.frames()[fi].hands)
        if (c.right == (h == 0) && (!th || c.confidence > th->confidence)) th = &c;
      if (!th) continue;
      retarget[static_cast<size_t>(h)].targets(*th, &targets[static_cast<size_t>(h)], &has[static_cast<size_t>(h)]);
      in[static_cast<size_t>(h)] = HandInput{true, targets[static_cast<size_t>(h)].data(), has[static_cast<size_t>(h)].data()};
      // ingest -> solver through the wire
      msg::HandTarget t;
      t.tracked(true);
      for (size_t b = 0; b < targets[static_cast<size_t>(h)].size(); ++b) {
        t.targets().emplace_back();
        svc::toWire(targets[static_cast<size_t>(h)][b], &t.targets().back());
        t.driven().push_back(has[static_cast<size_t>(h)][b] != 0);
      }
      ASSERT_TRUE(svc::fromWire(t, 16, &wire_targets[static_cast<size_t>(h)], &wire_has[static_cast<size_t>(h)], &why)) << why;
      win[static_cast<size_t>(h)] = HandInput{true, wire_targets[static_cast<size_t>(h)].data(), wire_has[static_cast<size_t>(h)].data()};
    }
    pipe.step(in);
    const std::uint64_t k = fi + 1;
    for (int h = 0; h < 2; ++h) {
      msg::HandProposal wp;
      svc::toWire(solvers[static_cast<size_t>(h)]->step(win[static_cast<size_t>(h)], k), &wp);
      wp.stamp().frame(k);
      ASSERT_TRUE(svc::fromWire(wp, 16, objects, &props[static_cast<size_t>(h)], &why)) << why;
      ptrs[static_cast<size_t>(h)] = &props[static_cast<size_t>(h)];
    }
    resolver.resolve(ptrs, k);
    for (int h = 0; h < 2; ++h) {
      msg::HandState hs;
      svc::toWire(resolver.result(h), *models[static_cast<size_t>(h)], false, &hs);
      hs.stamp().frame(k);
      HandResult r;
      ASSERT_TRUE(svc::fromWire(hs, 16, &r, &why)) << why;
      solvers[static_cast<size_t>(h)]->adopt(r);
      if (r.started) {
        for (const Pose& X : r.X) h_wire.add(X);
        for (const Pose& X : pipe.poses(h)) h_pipe.add(X);
        for (size_t b = 0; b < r.X.size(); ++b) ASSERT_TRUE(sameBits(r.X[b], pipe.poses(h)[b])) << "frame " << k << " hand " << h;
        ++compared;
      }
    }
    msg::ContactForces cf;
    svc::toWire(resolver.forces(), resolver.collision(), &cf);
    cf.stamp().frame(k);
    ForceSet fs;
    ASSERT_TRUE(svc::fromWire(cf, objects, &fs, &why)) << why;
    svc::toWire(stage.step(&fs, k), &ws);
    ws.stamp().frame(k);
    ASSERT_TRUE(svc::fromWire(ws, objects, &snap, &why)) << why;
    for (auto& s : solvers) s->setScene(snap);
    resolver.setScene(snap);
  }
  EXPECT_GT(compared, 100) << "both hands compared on most frames";
  EXPECT_EQ(h_wire.h, h_pipe.h);
}

TEST(Convert, ResumeContinuesFromTheResolvedPose) {
  const Scene scene = loadScene(std::string(GODHAND_DEPLOY_DIR) + "/scenes/default.pbtxt");
  const HandModel right = loadHandModel(std::string(GODHAND_DEPLOY_DIR) + "/models/hand16_right.pbtxt");
  PipelineParams params;
  params.step.dt = 0.01;
  HandSolver solver(scene, right, params);
  HandResult r;
  r.started = true;
  r.X = right.restPoses(Pose{Vec3(0.0, 0.0, 0.5), Quat::Identity()});
  solver.resume(r);
  ASSERT_TRUE(solver.started());
  for (size_t b = 0; b < r.X.size(); ++b) EXPECT_TRUE(sameBits(solver.stepper().poses()[b], r.X[b]));
  // An untracked frame proposes no motion from there.
  const HandProposal& p = solver.step(HandInput{}, 1);
  EXPECT_TRUE(p.started && !p.tracked);
  for (size_t b = 0; b < r.X.size(); ++b) EXPECT_TRUE(sameBits(p.X_new[b], r.X[b]));
  // Once started, resume does nothing.
  HandResult other = r;
  other.X = right.restPoses(Pose{Vec3(1.0, 0.0, 0.5), Quat::Identity()});
  solver.resume(other);
  EXPECT_TRUE(sameBits(solver.stepper().poses()[0], r.X[0]));
}

}  // namespace
}  // namespace godhand
