// A restarted scene's resume file (runtime/scene_resume.h): poses round-trip bit for bit through
// the file, a missing file moves nothing, a malformed one is one line naming FILE:LINE.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>

#include "runtime/scene_resume.h"

using namespace godhand;

namespace {
Scene threeObjects() {
  Scene s;
  s.objects.resize(3);
  return s;
}
std::string tmpPath(const char* name) { return "/tmp/godhand-resume-" + std::to_string(getpid()) + "-" + name; }
}  // namespace

TEST(SceneResume, PosesRoundTripBitForBit) {
  const std::string path = tmpPath("ok");
  ObjectMotion a, b;
  a.index = 2;
  a.X.p = Vec3(0.1, -1.0 / 3.0, 1e-17);
  a.X.q = Quat(0.5, 0.5, -0.5, 0.5);
  b.index = 0;
  b.X.p = Vec3(-10.885556343833178, 0.2, 3.0);
  b.X.q = Quat(std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0);
  ASSERT_TRUE(svc::writeSceneResume(path, {a, b}));
  Scene s = threeObjects();
  const Pose untouched = s.objects[1].X_WO;
  int moved = 0;
  std::string why;
  ASSERT_TRUE(svc::applySceneResume(path, &s, &moved, &why)) << why;
  EXPECT_EQ(moved, 2);
  EXPECT_EQ(s.objects[2].X_WO.p, a.X.p);
  EXPECT_EQ(s.objects[2].X_WO.q.coeffs(), a.X.q.coeffs());
  EXPECT_EQ(s.objects[0].X_WO.p, b.X.p);
  EXPECT_EQ(s.objects[0].X_WO.q.coeffs(), b.X.q.coeffs());
  EXPECT_EQ(s.objects[1].X_WO.p, untouched.p);
  std::remove(path.c_str());
}

TEST(SceneResume, MissingFileMovesNothing) {
  Scene s = threeObjects();
  int moved = -1;
  std::string why;
  EXPECT_TRUE(svc::applySceneResume(tmpPath("missing"), &s, &moved, &why));
  EXPECT_EQ(moved, 0);
}

TEST(SceneResume, MalformedFileIsOneLineAndTouchesNothing) {
  const std::string path = tmpPath("bad");
  for (const char* text : {"0 1 2 3 1 0 0 0\n7 0 0 0 1 0 0 0\n", "0 1 2 3 1 0 0\n", "0 1 2 nan 1 0 0 0\n", "0 1 2 3 2 0 0 0\n",
                           "0 1 2 3 1 0 0 0 extra\n"}) {
    std::ofstream(path) << text;
    Scene s = threeObjects();
    int moved = 0;
    std::string why;
    EXPECT_FALSE(svc::applySceneResume(path, &s, &moved, &why)) << text;
    EXPECT_NE(why.find(path + ":"), std::string::npos) << why;
    EXPECT_EQ(why.find('\n'), std::string::npos);
    EXPECT_EQ(s.objects[0].X_WO.p, Pose{}.p) << text;
  }
  std::remove(path.c_str());
}
