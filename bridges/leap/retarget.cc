#include "leap/retarget.h"

#include <cmath>
#include <string>

namespace godhand::leap {
namespace {

/// Minimal rotation taking unit vector a onto unit vector b (Eigen picks an axis when opposite).
Quat minimalRotation(const Vec3& a, const Vec3& b) {
  Quat q;
  q.setFromTwoVectors(a, b);
  return q.normalized();
}

/// Parses "palm", "<finger>.1|2|3", "<finger>.tip"; returns false for anything else.
bool parseSegment(const std::string& s, int* kind, int* finger, int* bone) {
  if (s == "palm") {
    *kind = 1;
    return true;
  }
  const auto dot = s.find('.');
  if (dot == std::string::npos) return false;
  const std::string f = s.substr(0, dot), rest = s.substr(dot + 1);
  *finger = -1;
  for (int k = 0; k < kFingerCount; ++k)
    if (f == fingerName(k)) *finger = k;
  if (*finger < 0) return false;
  if (rest == "tip") {
    *kind = 3;
    return true;
  }
  if (rest.size() == 1 && rest[0] >= '1' && rest[0] <= '3') {
    *kind = 2;
    *bone = rest[0] - '1';
    return true;
  }
  return false;
}

/// Straight-finger length of a tracked finger: palm centre → mcp plus the three bones.
double trackedFingerLength(const TrackedHand& h, int finger) {
  const auto& j = h.joints_W[static_cast<std::size_t>(finger)];
  return (j[0] - h.X_W_palm.p).norm() + (j[1] - j[0]).norm() + (j[2] - j[1]).norm() + (j[3] - j[2]).norm();
}

}  // namespace

Retargeter::Retargeter(const HandModel& model, const RetargetOptions& options) : model_(model), options_(options) {
  const std::size_t n = model_.bodies.size();
  drive_.assign(n, Drive{});
  std::vector<int> parent_joint(n, -1);
  for (std::size_t j = 0; j < model_.joints.size(); ++j) parent_joint[static_cast<std::size_t>(model_.joints[j].child)] = static_cast<int>(j);

  for (std::size_t i = 0; i < n; ++i) {
    const Body& b = model_.bodies[i];
    if (b.tracker_segment.empty()) continue;
    int kind = 0, finger = -1, bone = -1;
    if (!parseSegment(b.tracker_segment, &kind, &finger, &bone))
      throw std::invalid_argument("model '" + model_.name + "': body '" + b.name + "' has unknown tracker_segment '" + b.tracker_segment +
                                  "' (known: palm, {thumb,index,middle,ring,pinky}.{1,2,3,tip}" +
                                  (b.tracker_segment == "tool" ? "; 'tool' is a 6-DOF tracked body: give its cluster tracker_body N in the lab, not a side" : "") + ")");
    Drive& d = drive_[i];
    d.kind = kind == 1 ? Kind::kPalm : kind == 2 ? Kind::kPhalanx : Kind::kTip;
    d.finger = finger;
    d.bone = bone;
    if (d.kind == Kind::kPhalanx) {
      d.joint = parent_joint[i];
      if (d.joint < 0)
        throw std::invalid_argument("model '" + model_.name + "': phalanx body '" + b.name + "' has no parent joint (needed for forward kinematics)");
      d.parent = model_.joints[static_cast<std::size_t>(d.joint)].parent;
    }
    if (finger == kThumb && !model_right_) model_right_ = b.X_MB_rest.p.x() < 0.0;
  }
  bool any_driven = false;
  for (std::size_t i = 0; i < n; ++i) any_driven = any_driven || !model_.bodies[i].tracker_segment.empty();
  if (!any_driven)
    throw std::invalid_argument("model '" + model_.name + "': no body has a tracker_segment, so nothing would drive this hand "
                                "(give its palm tracker_segment \"palm\" and its phalanges theirs)");
  for (std::size_t i = 0; i < n; ++i) {
    const Drive& d = drive_[i];
    if (d.kind != Kind::kPhalanx) continue;
    const Kind pk = drive_[static_cast<std::size_t>(d.parent)].kind;
    if (pk != Kind::kPalm && pk != Kind::kPhalanx)
      throw std::invalid_argument("model '" + model_.name + "': phalanx body '" + model_.bodies[i].name + "' hangs from body '" +
                                  model_.bodies[static_cast<std::size_t>(d.parent)].name + "', which is not driven by the palm or a phalanx");
  }
  // Parents before children: depth of each body in the joint tree, then a stable sort by depth.
  std::vector<int> depth(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (int b = static_cast<int>(i), guard = 0; parent_joint[static_cast<std::size_t>(b)] >= 0 && guard <= static_cast<int>(n); ++guard) {
      b = model_.joints[static_cast<std::size_t>(parent_joint[static_cast<std::size_t>(b)])].parent;
      ++depth[i];
    }
  for (int dpt = 0; dpt <= static_cast<int>(n); ++dpt)
    for (std::size_t i = 0; i < n; ++i)
      if (depth[i] == dpt) order_.push_back(static_cast<int>(i));

  // Model hand size for fingertip scaling: the non-thumb tips, else the thumb.
  for (int pass = 0; pass < 2 && model_tip_size_ == 0.0; ++pass)
    for (std::size_t i = 0; i < n; ++i) {
      const Drive& d = drive_[i];
      if (d.kind != Kind::kTip || (pass == 0) == (d.finger == kThumb)) continue;
      size_fingers_[static_cast<std::size_t>(d.finger)] = true;
      model_tip_size_ += model_.bodies[i].X_MB_rest.p.norm();
    }
}

double Retargeter::tipScale(const TrackedHand& hand) const {
  double tracked = 0.0;
  for (int f = 0; f < kFingerCount; ++f)
    if (size_fingers_[static_cast<std::size_t>(f)]) tracked += trackedFingerLength(hand, f);
  return model_tip_size_ > 0.0 && tracked > 1e-6 ? model_tip_size_ / tracked : 1.0;
}

int Retargeter::targets(const TrackedHand& hand, std::vector<Pose>* X_W_targets, std::vector<unsigned char>* has_target) const {
  if (model_right_ && *model_right_ != hand.right)
    throw std::invalid_argument(std::string("Retargeter: a ") + (hand.right ? "right" : "left") + " hand cannot drive model '" + model_.name +
                                "' (a " + (*model_right_ ? "right" : "left") + " hand)");
  const std::size_t n = model_.bodies.size();
  X_W_targets->resize(n);
  has_target->assign(n, 0);
  int degenerate = 0;
  const Pose& X_WM = hand.X_W_palm;
  const Vec3 ez = Vec3::UnitZ();
  const double s = tipScale(hand);
  const Pose X_palm_W = X_WM.inverse();

  for (const int bi : order_) {
    const std::size_t i = static_cast<std::size_t>(bi);
    const Body& b = model_.bodies[i];
    const Drive& d = drive_[i];
    Pose& X = (*X_W_targets)[i];
    switch (d.kind) {
      case Kind::kNone:
        X = X_WM * b.X_MB_rest;
        break;
      case Kind::kPalm:
        X = X_WM * b.X_MB_rest;
        (*has_target)[i] = 1;
        break;
      case Kind::kTip: {
        const auto& jt = hand.joints_W[static_cast<std::size_t>(d.finger)];
        const Vec3 p_P = X_palm_W * jt[kTip];
        const Quat q0 = (X_WM.q * b.X_MB_rest.q).normalized();
        const Vec3 seg = jt[kTip] - jt[kDip];
        Quat q = q0;
        if (seg.norm() >= kMinSegment) {
          q = (minimalRotation(q0 * ez, seg.normalized()) * q0).normalized();
        } else {
          ++degenerate;
        }
        X = {X_WM * Vec3(s * p_P), q};
        (*has_target)[i] = 1;
        break;
      }
      case Kind::kPhalanx: {
        const Joint& j = model_.joints[static_cast<std::size_t>(d.joint)];
        const Pose& X_WP = (*X_W_targets)[static_cast<std::size_t>(d.parent)];
        const Pose& rest_P = model_.bodies[static_cast<std::size_t>(d.parent)].X_MB_rest;
        // Rest orientation relative to the parent, carried by the parent's target.
        const Quat q_carried = (X_WP.q * (rest_P.q.conjugate() * b.X_MB_rest.q)).normalized();
        const auto& jt = hand.joints_W[static_cast<std::size_t>(d.finger)];
        const Vec3 seg = jt[static_cast<std::size_t>(d.bone + 1)] - jt[static_cast<std::size_t>(d.bone)];
        Quat q = q_carried;
        if (seg.norm() < kMinSegment) {
          ++degenerate;
        } else {
          const Vec3 dir = seg.normalized();
          bool done = false;
          const Vec3 u = j.X_CJ.q.conjugate() * ez;  // child body z in the joint frame
          if (options_.twist == TwistRule::kJointConsistent && (u - ez).norm() < 1e-9) {
            const Quat A = (X_WP.q * j.X_PJ.q).normalized();  // parent's copy of the joint frame, world
            if (j.type == JointType::Spherical2Dof) {
              const Vec3 e = A.conjugate() * dir;
              const double a = std::atan2(-e.y(), e.z());
              const double c = std::atan2(e.x(), std::hypot(e.y(), e.z()));
              const Quat rel = Quat(Eigen::AngleAxisd(a, Vec3::UnitX())) * Quat(Eigen::AngleAxisd(c, Vec3::UnitY()));
              q = (A * rel * j.X_CJ.q.conjugate()).normalized();
              done = true;
            } else if (j.type == JointType::Revolute) {
              const Vec3 hinge = A * Vec3::UnitX();
              const Vec3 x = hinge - dir * dir.dot(hinge);
              if (x.norm() > 1e-6) {
                Mat3 R;
                R.col(0) = x.normalized();
                R.col(1) = dir.cross(R.col(0));
                R.col(2) = dir;
                q = (Quat(R) * j.X_CJ.q.conjugate()).normalized();
                done = true;
              }
            }
          }
          if (!done) q = (minimalRotation(q_carried * ez, dir) * q_carried).normalized();
        }
        const Vec3 p_anchor = X_WP * j.X_PJ.p;
        X = {p_anchor - q * j.X_CJ.p, q};
        (*has_target)[i] = 1;
        break;
      }
    }
  }
  return degenerate;
}

HandTracks::HandTracks() { reset(); }

void HandTracks::reset() {
  slots_[0] = HandSlot{};
  slots_[0].right = false;
  slots_[1] = HandSlot{};
  slots_[1].right = true;
  appeared_ = {};
  lost_ = {};
  extra_ignored_ = 0;
}

void HandTracks::update(const TrackerFrame& frame) {
  for (int side = 0; side < 2; ++side) {
    HandSlot& slot = slots_[static_cast<std::size_t>(side)];
    const bool right = side == 1;
    const TrackedHand* pick = nullptr;
    int candidates = 0;
    for (const TrackedHand& h : frame.hands) {
      if (h.right != right) continue;
      ++candidates;
      if (pick == nullptr) {
        pick = &h;
      } else if (slot.present && h.id == slot.id && pick->id != slot.id) {
        pick = &h;  // keep following the hand this slot already follows
      } else if (!(slot.present && pick->id == slot.id) && h.confidence > pick->confidence) {
        pick = &h;
      }
    }
    if (candidates > 1) extra_ignored_ += static_cast<std::size_t>(candidates - 1);
    const bool was = slot.present;
    const int old_id = slot.id;
    slot.present = pick != nullptr;
    slot.appeared = slot.present && (!was || pick->id != old_id);
    slot.lost = was && (!slot.present || pick->id != old_id);
    if (slot.present) {
      slot.id = pick->id;
      slot.hand = *pick;
    }
    appeared_[static_cast<std::size_t>(side)] += slot.appeared;
    lost_[static_cast<std::size_t>(side)] += slot.lost;
  }
}

}  // namespace godhand::leap
