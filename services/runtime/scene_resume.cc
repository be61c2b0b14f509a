#include "runtime/scene_resume.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace godhand::svc {

bool writeSceneResume(const std::string& path, const std::vector<ObjectMotion>& objects) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    char b[512];
    for (const ObjectMotion& o : objects) {
      std::snprintf(b, sizeof b, "%d %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", o.index, o.X.p.x(), o.X.p.y(), o.X.p.z(), o.X.q.w(),
                    o.X.q.x(), o.X.q.y(), o.X.q.z());
      out << b;
    }
    out.flush();
    if (!out) return false;
  }
  return std::rename(tmp.c_str(), path.c_str()) == 0;
}

bool applySceneResume(const std::string& path, Scene* scene, int* moved, std::string* why) {
  *moved = 0;
  std::ifstream in(path);
  if (!in) return true;  // nothing to resume from
  std::vector<std::pair<int, Pose>> poses;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) continue;
    std::istringstream ls(line);
    int index = -1;
    double v[7];
    ls >> index;
    for (double& x : v) ls >> x;
    std::string rest;
    if (!ls || (ls >> rest)) {
      *why = path + ":" + std::to_string(n) + ": expected INDEX PX PY PZ QW QX QY QZ";
      return false;
    }
    if (index < 0 || index >= static_cast<int>(scene->objects.size())) {
      *why = path + ":" + std::to_string(n) + ": object index " + std::to_string(index) + " not in the scene";
      return false;
    }
    for (double x : v)
      if (!std::isfinite(x)) {
        *why = path + ":" + std::to_string(n) + ": not a finite number";
        return false;
      }
    Pose X;
    X.p = Vec3(v[0], v[1], v[2]);
    X.q = Quat(v[3], v[4], v[5], v[6]);
    if (std::abs(X.q.norm() - 1.0) > 1e-6) {
      *why = path + ":" + std::to_string(n) + ": rotation is not a unit quaternion";
      return false;
    }
    poses.push_back({index, X});
  }
  for (const auto& [index, X] : poses) scene->objects[static_cast<size_t>(index)].X_WO = X;
  *moved = static_cast<int>(poses.size());
  return true;
}

}  // namespace godhand::svc
