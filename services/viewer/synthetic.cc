#include "viewer/synthetic.h"

#include <cmath>

#include <nlohmann/json.hpp>

namespace godhand::viewer {

bool parseSyntheticCommand(const std::string& payload, int* hand, Vec3* offset, std::string* why) {
  const nlohmann::json j = nlohmann::json::parse(payload, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return *why = "synthetic command: not a JSON object", false;
  auto h = j.find("hand");
  if (h == j.end() || !h->is_number_integer() || h->get<long long>() < 0 || h->get<long long>() > 1000)
    return *why = "synthetic command: \"hand\" must be an integer in [0, 1000]", false;
  auto o = j.find("offset");
  if (o == j.end() || !o->is_array() || o->size() != 3) return *why = "synthetic command: \"offset\" must be [x, y, z]", false;
  Vec3 v;
  for (int i = 0; i < 3; ++i) {
    const nlohmann::json& x = (*o)[static_cast<std::size_t>(i)];
    if (!x.is_number() || !std::isfinite(x.get<double>()) || std::abs(x.get<double>()) > kMaxSyntheticOffset)
      return *why = "synthetic command: offset components must be finite numbers within 1 m", false;
    v[i] = x.get<double>();
  }
  *hand = static_cast<int>(h->get<long long>());
  *offset = v;
  return true;
}

Pose syntheticStart(const Scene& scene) {
  Pose X;
  X.p = Vec3(0, 0, 0.25);
  const SceneObject* target = nullptr;
  for (const SceneObject& o : scene.objects)
    if (o.id == "bunny") target = &o;
  if (!target && !scene.objects.empty()) target = &scene.objects.front();
  if (target && target->god) {
    double top = -1e300;
    for (const Vec3& v : target->god->mesh().vertices) top = std::max(top, (target->X_WO * v).z());
    X.p = Vec3(target->X_WO.p.x(), target->X_WO.p.y(), top + 0.08);
  }
  return X;
}

void syntheticTarget(const HandModel& model, const Pose& X_WM, std::uint32_t hand, const std::string& cluster,
                     std::uint64_t run, std::uint64_t frame, std::int64_t now_ns, msg::HandTarget* out) {
  const std::vector<Pose> poses = model.restPoses(X_WM);
  out->hand(hand);
  out->cluster(cluster);
  out->stamp().run(run);
  out->stamp().frame(frame);
  out->stamp().source_time_ns(now_ns);
  out->stamp().publish_time_ns(now_ns);
  out->tracked(true);
  out->confidence(1.0f);
  out->targets().resize(poses.size());
  out->driven().assign(poses.size(), true);
  for (std::size_t b = 0; b < poses.size(); ++b) {
    msg::Pose& p = out->targets()[b];
    for (int i = 0; i < 3; ++i) p.p()[static_cast<std::size_t>(i)] = poses[b].p[i];
    p.q()[0] = poses[b].q.w();
    p.q()[1] = poses[b].q.x();
    p.q()[2] = poses[b].q.y();
    p.q()[3] = poses[b].q.z();
  }
}

}  // namespace godhand::viewer
