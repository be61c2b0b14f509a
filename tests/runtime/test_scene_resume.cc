// A restarted scene's resume from the scene state the lab holds (runtime/scene_resume.h): the
// held poses reach the scene bit for bit through the wire types; a held state that is not of
// this scene (unknown index, a static object, a bad pose) moves nothing and says why in one
// line; the wait ends when the resolver answers it holds nothing, or at the deadline.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "runtime/convert.h"
#include "runtime/scene_resume.h"

using namespace godhand;
using Clock = std::chrono::steady_clock;

namespace {
// Objects 0 and 2 dynamic, 1 static.
Scene threeObjects() {
  Scene s;
  s.objects.resize(3);
  for (int i : {0, 2}) {
    s.objects[static_cast<size_t>(i)].mass = 0.2;
    s.objects[static_cast<size_t>(i)].physics.type = PhysicsShapeType::Box;
  }
  for (size_t i = 0; i < 3; ++i) s.objects[i].id = "o" + std::to_string(i);
  return s;
}
ObjectMotion motion(int index, const Vec3& p, const Quat& q) {
  ObjectMotion m;
  m.index = index;
  m.X.p = p;
  m.X.q = q;
  return m;
}
Clock::time_point at(double s) { return Clock::time_point{} + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); }
}  // namespace

TEST(SceneResume, HeldPosesReachTheSceneBitForBitThroughTheWire) {
  SceneSnapshot held;
  held.frame = 41;
  held.step = 97;
  held.objects = {motion(2, Vec3(0.1, -1.0 / 3.0, 1e-17), Quat(0.5, 0.5, -0.5, 0.5)),
                  motion(0, Vec3(-10.885556343833178, 0.2, 3.0), Quat(std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0))};
  msg::SceneState wire;
  svc::toWire(held, &wire);
  SceneSnapshot back;
  std::string why;
  ASSERT_TRUE(svc::fromWire(wire, 3, &back, &why)) << why;
  Scene s = threeObjects();
  const Pose untouched = s.objects[1].X_WO;
  int moved = 0;
  ASSERT_TRUE(svc::applySceneResume(back, &s, &moved, &why)) << why;
  EXPECT_EQ(moved, 2);
  EXPECT_EQ(s.objects[2].X_WO.p, held.objects[0].X.p);
  EXPECT_EQ(s.objects[2].X_WO.q.coeffs(), held.objects[0].X.q.coeffs());
  EXPECT_EQ(s.objects[0].X_WO.p, held.objects[1].X.p);
  EXPECT_EQ(s.objects[0].X_WO.q.coeffs(), held.objects[1].X.q.coeffs());
  EXPECT_EQ(s.objects[1].X_WO.p, untouched.p);
}

TEST(SceneResume, AHeldStateOfAnotherSceneMovesNothingAndSaysWhy) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const struct {
    ObjectMotion bad;
    const char* says;
  } cases[] = {
      {motion(7, Vec3(0, 0, 0), Quat::Identity()), "object index 7 not in the scene"},
      {motion(1, Vec3(0, 0, 0), Quat::Identity()), "object 1 ('o1') is not dynamic"},
      {motion(2, Vec3(nan, 0, 0), Quat::Identity()), "pose not finite or not unit"},
      {motion(2, Vec3(0, 0, 0), Quat(2, 0, 0, 0)), "pose not finite or not unit"},
  };
  for (const auto& c : cases) {
    SceneSnapshot held;
    held.objects = {motion(0, Vec3(1, 2, 3), Quat::Identity()), c.bad};
    Scene s = threeObjects();
    int moved = -1;
    std::string why;
    EXPECT_FALSE(svc::applySceneResume(held, &s, &moved, &why)) << c.says;
    EXPECT_NE(why.find(c.says), std::string::npos) << why;
    EXPECT_EQ(why.find('\n'), std::string::npos);
    EXPECT_EQ(moved, 0);
    EXPECT_EQ(s.objects[0].X_WO.p, Pose{}.p) << "the first, valid object must not move either";
  }
}

TEST(SceneResume, TheWaitEndsWhenNothingIsHeldOrAtTheDeadline) {
  using State = svc::ResumeWait::State;
  {  // the resolver matched at 0.5 s and sent nothing within the 1 s grace: nothing held
    svc::ResumeWait w(3.0, 1.0, at(0));
    EXPECT_EQ(w.poll(0, at(0.2)), State::Waiting);
    EXPECT_EQ(w.poll(1, at(0.5)), State::Waiting);
    EXPECT_EQ(w.poll(1, at(1.4)), State::Waiting);
    EXPECT_EQ(w.poll(0, at(1.5)), State::NothingHeld) << "a writer once matched counts (it may have gone again)";
  }
  {  // no resolver at all: the deadline
    svc::ResumeWait w(3.0, 1.0, at(10));
    EXPECT_EQ(w.poll(0, at(12.9)), State::Waiting);
    EXPECT_EQ(w.poll(0, at(13.0)), State::TimedOut);
  }
  {  // matched just before the deadline: the deadline still holds
    svc::ResumeWait w(3.0, 1.0, at(0));
    EXPECT_EQ(w.poll(1, at(2.9)), State::Waiting);
    EXPECT_EQ(w.poll(1, at(3.0)), State::TimedOut);
  }
}
