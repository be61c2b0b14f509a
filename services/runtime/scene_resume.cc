#include "runtime/scene_resume.h"

#include <cmath>
#include <vector>

namespace godhand::svc {

bool applySceneResume(const SceneSnapshot& held, Scene* scene, int* moved, std::string* why) {
  *moved = 0;
  for (const ObjectMotion& o : held.objects) {
    if (o.index < 0 || o.index >= static_cast<int>(scene->objects.size())) {
      *why = "held scene state: object index " + std::to_string(o.index) + " not in the scene";
      return false;
    }
    const SceneObject& so = scene->objects[static_cast<size_t>(o.index)];
    if (!(so.mass > 0.0) || so.physics.type == PhysicsShapeType::None) {
      *why = "held scene state: object " + std::to_string(o.index) + " ('" + so.id + "') is not dynamic in this scene";
      return false;
    }
    if (!o.X.p.allFinite() || !o.X.q.coeffs().allFinite() || std::abs(o.X.q.norm() - 1.0) > 1e-6) {
      *why = "held scene state: object " + std::to_string(o.index) + ": pose not finite or not unit";
      return false;
    }
  }
  for (const ObjectMotion& o : held.objects) scene->objects[static_cast<size_t>(o.index)].X_WO = o.X;
  *moved = static_cast<int>(held.objects.size());
  return true;
}

ResumeWait::ResumeWait(double wait_s, double grace_s, Clock::time_point start)
    : until_(start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait_s))),
      grace_(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(grace_s))) {}

ResumeWait::State ResumeWait::poll(int writers, Clock::time_point now) {
  if (writers > 0 && !matched_) {
    matched_ = true;
    matched_at_ = now;
  }
  if (matched_ && now - matched_at_ >= grace_) return State::NothingHeld;
  if (now >= until_) return State::TimedOut;
  return State::Waiting;
}

}  // namespace godhand::svc
