#include "mujoco/mujoco_hands.h"

#include <mujoco/mujoco.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <stdexcept>

namespace godhand::mujoco {

namespace {

// Where a hand's bodies wait before its first tracked frame: far from any scene, out of contact.
constexpr double kParkedZ = 1000.0;

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("mujoco: " + what);
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void poseAttrs(std::ostringstream& x, const Pose& X) {
  x << " pos=\"" << num(X.p.x()) << ' ' << num(X.p.y()) << ' ' << num(X.p.z()) << "\" quat=\"" << num(X.q.w()) << ' '
    << num(X.q.x()) << ' ' << num(X.q.y()) << ' ' << num(X.q.z()) << '"';
}

std::string bodyName(size_t hand, size_t body) { return "h" + std::to_string(hand) + "b" + std::to_string(body); }

void validate(const Params& p) {
  require(std::isfinite(p.timestep) && p.timestep >= 1e-5 && p.timestep <= 0.1, "timestep must be in [1e-5, 0.1] s");
  require(std::isfinite(p.weld_timeconst) && p.weld_timeconst > 0.0 && p.weld_timeconst <= 10.0,
          "weld time constant must be in (0, 10] s");
  require(std::isfinite(p.contact_timeconst) && p.contact_timeconst > 0.0 && p.contact_timeconst <= 10.0,
          "contact time constant must be in (0, 10] s");
}

}  // namespace

std::string version() { return std::string("MuJoCo ") + mj_versionString(); }

std::string modelXml(const Scene& scene, const std::vector<const HandModel*>& models, const Params& params) {
  validate(params);
  std::ostringstream x;
  size_t bodies = 0;
  for (const HandModel* m : models) {
    require(m != nullptr, "null hand model");
    bodies += m->bodies.size();
  }
  x << "<mujoco model=\"godhand-compare\">\n"
    << "  <option timestep=\"" << num(params.timestep) << "\" gravity=\"0 0 0\"/>\n"
    << "  <size nconmax=\"" << 64 * (bodies + 1) << "\" njmax=\"" << 64 * 6 * (bodies + 1) << "\"/>\n"
    << "  <default><geom solref=\"" << num(params.contact_timeconst) << " 1\"/>"
    << "<equality solref=\"" << num(params.weld_timeconst) << " 1\"/></default>\n"
    << "  <asset>\n";
  // Scene objects: their full-resolution meshes (what the penetration figure is measured against).
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const SceneObject& obj = scene.objects[o];
    const geo::MeshBvh* mesh = obj.reference ? obj.reference.get() : obj.god.get();
    require(mesh != nullptr && mesh->triangleCount() > 0, "object '" + obj.id + "' has no mesh");
    x << "    <mesh name=\"m" << o << "\" vertex=\"";
    for (const Vec3& v : mesh->mesh().vertices) x << num(v.x()) << ' ' << num(v.y()) << ' ' << num(v.z()) << ' ';
    x << "\" face=\"";
    for (const auto& t : mesh->mesh().triangles) x << t[0] << ' ' << t[1] << ' ' << t[2] << ' ';
    x << "\"/>\n";
  }
  x << "  </asset>\n  <worldbody>\n";
  // contype/conaffinity: scene 1/2, hand 2/1: hand-scene pairs collide, hand-hand and scene-scene not.
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    x << "    <geom name=\"o" << o << "\" type=\"mesh\" mesh=\"m" << o << "\" contype=\"1\" conaffinity=\"2\"";
    poseAttrs(x, scene.objects[o].X_WO);
    x << "/>\n";
  }
  for (size_t h = 0; h < models.size(); ++h) {
    const HandModel& m = *models[h];
    for (size_t b = 0; b < m.bodies.size(); ++b) {
      const Body& body = m.bodies[b];
      require(std::isfinite(body.mass) && body.mass > 0.0, "body '" + body.name + "' needs a mass > 0");
      const std::string name = bodyName(h, b);
      const std::string parked = "0 0 " + num(kParkedZ);
      x << "    <body name=\"" << name << "t\" mocap=\"true\" pos=\"" << parked << "\"/>\n";
      x << "    <body name=\"" << name << "\" pos=\"" << parked << "\"><freejoint/><geom contype=\"2\" conaffinity=\"1\" mass=\""
        << num(body.mass) << '"';
      const Shape& s = body.shape;
      switch (s.type) {
        case ShapeType::Sphere: x << " type=\"sphere\" size=\"" << num(s.radius) << '"'; break;
        case ShapeType::Capsule: x << " type=\"capsule\" size=\"" << num(s.radius) << ' ' << num(s.half_length) << '"'; break;
        case ShapeType::Box:
          x << " type=\"box\" size=\"" << num(s.half_extents.x()) << ' ' << num(s.half_extents.y()) << ' '
            << num(s.half_extents.z()) << '"';
          break;
      }
      x << "/></body>\n";
    }
  }
  x << "  </worldbody>\n  <equality>\n";
  for (size_t h = 0; h < models.size(); ++h)
    for (size_t b = 0; b < models[h]->bodies.size(); ++b) {
      const std::string name = bodyName(h, b);
      x << "    <weld body1=\"" << name << "t\" body2=\"" << name << "\" relpose=\"0 0 0 1 0 0 0\"/>\n";
    }
  x << "  </equality>\n</mujoco>\n";
  return x.str();
}

struct Hands::Impl {
  mjVFS vfs;
  mjModel* m = nullptr;
  mjData* d = nullptr;
  ~Impl() {
    if (d) mj_deleteData(d);
    if (m) mj_deleteModel(m);
    mj_deleteVFS(&vfs);
  }
};

namespace {
// MuJoCo prints its warnings to stdout; the counts come from mjData::warning instead (a library
// writes nowhere). Process-wide, as MuJoCo's hook is.
void quietWarning(const char*) {}
}  // namespace

Hands::Hands(const Scene& scene, std::vector<const HandModel*> models, double frame_dt, const Params& params)
    : impl_(std::make_unique<Impl>()) {
  mju_user_warning = quietWarning;
  require(std::isfinite(frame_dt) && frame_dt > 0.0 && frame_dt <= 10.0, "frame period must be in (0, 10] s");
  const std::string xml = modelXml(scene, models, params);
  mj_defaultVFS(&impl_->vfs);
  const char* file = "godhand-compare.xml";
  require(mj_makeEmptyFileVFS(&impl_->vfs, file, static_cast<int>(xml.size())) == 0, "cannot make the in-memory model file");
  std::memcpy(impl_->vfs.filedata[impl_->vfs.nfile - 1], xml.data(), xml.size());
  char err[1024] = "";
  impl_->m = mj_loadXML(file, &impl_->vfs, err, sizeof err);
  require(impl_->m != nullptr, std::string("MuJoCo refused the model: ") + err);
  impl_->d = mj_makeData(impl_->m);
  require(impl_->d != nullptr, "MuJoCo could not allocate its data");
  steps_per_frame_ = std::max(1, static_cast<int>(std::ceil(frame_dt / params.timestep - 1e-9)));
  const mjModel* m = impl_->m;
  for (size_t h = 0; h < models.size(); ++h) {
    Hand hand;
    hand.model = models[h];
    const std::string b0 = bodyName(h, 0);
    hand.first_body = mj_name2id(m, mjOBJ_BODY, b0.c_str());
    const int mocap_body = mj_name2id(m, mjOBJ_BODY, (b0 + "t").c_str());
    require(hand.first_body >= 0 && mocap_body >= 0, "model bodies not found");
    hand.first_mocap = m->body_mocapid[mocap_body];
    hand.first_qpos = m->jnt_qposadr[m->body_jntadr[hand.first_body]];
    hand.first_geom = m->body_geomadr[hand.first_body];
    hand.geoms = static_cast<int>(hand.model->bodies.size());
    hand.X.assign(hand.model->bodies.size(), Pose{});
    hands_.push_back(std::move(hand));
  }
}

Hands::~Hands() = default;

void Hands::step(const std::vector<HandInput>& inputs) {
  require(inputs.size() == hands_.size(), "one input per hand expected");
  const mjModel* m = impl_->m;
  mjData* d = impl_->d;
  // Body b of a hand is MuJoCo body first_body + 2 b (each target body comes before its body),
  // mocap first_mocap + b, qpos first_qpos + 7 b, geom first_geom + b.
  for (size_t h = 0; h < hands_.size(); ++h) {
    Hand& hand = hands_[h];
    const HandInput& in = inputs[h];
    if (!in.tracked || !in.targets) continue;
    const size_t n = hand.model->bodies.size();
    bool finite_targets = true;
    for (size_t b = 0; b < n; ++b)
      finite_targets = finite_targets && in.targets[b].p.allFinite() && in.targets[b].q.coeffs().allFinite();
    if (!finite_targets) {  // the hand keeps its last targets
      ++rejected_;
      continue;
    }
    auto has = [&](size_t b) { return !in.has_target || in.has_target[b]; };
    std::vector<Pose> start;
    if (!hand.started) {
      if (!has(0)) continue;  // placed from body 0's target
      const Pose X_WM = in.targets[0] * hand.model->bodies[0].X_MB_rest.inverse();
      start = hand.model->restPoses(X_WM);
      for (size_t b = 0; b < n; ++b)
        if (has(b)) start[b] = in.targets[b];
    }
    for (size_t b = 0; b < n; ++b) {
      const Pose* T = has(b) ? &in.targets[b] : (hand.started ? nullptr : &start[b]);
      if (!T) continue;
      const size_t k = static_cast<size_t>(hand.first_mocap) + b;
      const double pq[7] = {T->p.x(), T->p.y(), T->p.z(), T->q.w(), T->q.x(), T->q.y(), T->q.z()};
      for (int i = 0; i < 3; ++i) d->mocap_pos[3 * k + static_cast<size_t>(i)] = pq[i];
      for (int i = 0; i < 4; ++i) d->mocap_quat[4 * k + static_cast<size_t>(i)] = pq[3 + i];
      if (!hand.started) {
        const size_t a = static_cast<size_t>(hand.first_qpos) + 7 * b;
        for (int i = 0; i < 7; ++i) d->qpos[a + static_cast<size_t>(i)] = pq[i];
        const size_t v = static_cast<size_t>(m->jnt_dofadr[m->body_jntadr[hand.first_body + 2 * static_cast<int>(b)]]);
        for (int i = 0; i < 6; ++i) d->qvel[v + static_cast<size_t>(i)] = 0.0;
      }
    }
    hand.started = true;
  }
  auto warnings = [d](std::initializer_list<int> kinds) {
    long n = 0;
    for (int k : kinds) n += d->warning[k].number;
    return n;
  };
  const long unstable0 = warnings({mjWARN_BADQPOS, mjWARN_BADQVEL, mjWARN_BADQACC});
  const long full0 = warnings({mjWARN_CONTACTFULL, mjWARN_CNSTRFULL});
  for (int s = 0; s < steps_per_frame_; ++s) mj_step(m, d);
  if (warnings({mjWARN_CONTACTFULL, mjWARN_CNSTRFULL}) > full0) ++overflows_;
  bool finite = true;
  for (int i = 0; i < m->nq; ++i) finite = finite && std::isfinite(d->qpos[i]);
  // MuJoCo resets its data itself when it meets a bad number (and says so in a warning).
  if (!finite || warnings({mjWARN_BADQPOS, mjWARN_BADQVEL, mjWARN_BADQACC}) > unstable0) {
    ++resets_;
    mj_resetData(m, d);  // the poses reported stay the last finite ones; the hands start again
    for (Hand& hand : hands_) hand.started = false;
    return;
  }
  for (Hand& hand : hands_) {
    hand.loaded = false;
    if (!hand.started) continue;
    for (size_t b = 0; b < hand.X.size(); ++b) {
      const size_t id = static_cast<size_t>(hand.first_body) + 2 * b;
      hand.X[b].p = Vec3(d->xpos[3 * id], d->xpos[3 * id + 1], d->xpos[3 * id + 2]);
      hand.X[b].q = Quat(d->xquat[4 * id], d->xquat[4 * id + 1], d->xquat[4 * id + 2], d->xquat[4 * id + 3]).normalized();
    }
  }
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& con = d->contact[c];
    if (con.dist > 0.0) continue;
    for (Hand& hand : hands_)
      for (int g : {con.geom1, con.geom2})
        if (g >= hand.first_geom && g < hand.first_geom + hand.geoms) hand.loaded = true;
  }
}

}  // namespace godhand::mujoco
