#include "pipeline/collision_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace godhand {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kPartSamples = 21;  ///< the whole shape, then a box's 8 corners and 12 edge midpoints
constexpr int kShellSample = 15;  ///< sample id of shell candidates (in the contact key)
constexpr int kPatchSample = 9;   ///< sample ids 9 … 14: the corners of a box face's patch
constexpr int kEdgeSample = 16;   ///< sample ids 16 … 27: a box's edge midpoints (parts 9 … 20)
constexpr int kMaxPatch = 6;

/// A box face lying against a mesh touches it along a patch or a line (a face, or an edge of a
/// coarse rod), and the closest point gives one row there: the box can tilt about that point
/// into the surface (seen: a palm flat on a thin octagonal rod turned about its one row each
/// round, the sweep refused every round's motion and the hand froze). The patch: the nearest
/// triangle projected onto the box face that faces the contact (its normal within 20° of the
/// contact's), clipped by the face's rectangle, for a triangle within 45° of the face. Each
/// corner (at most kMaxPatch) becomes a candidate with the normal and distance of the two
/// features that meet there (the clipped polygon's edges lie on triangle edges or face sides):
///   - a triangle vertex over the face: the face's normal, the vertex's height above the face;
///   - a face corner under the triangle: the triangle's normal, the corner's distance to its plane;
///   - a triangle edge crossing a side of the face: the two edges' common normal (e_T × e_B,
///     towards the box), their distance along it (where they are parallel, as for a vertex).
/// Each is the exact first-order gap of its feature pair. (One normal for every corner, the
/// triangle's, was wrong where the triangle meets the face at an angle: an octagonal rod's edge
/// lying on a palm, its faces 17° and 28° off the palm's; rows along the triangle's normal at the
/// line's ends let the palm slide along the triangle's plane into the edge, seen as a hand frozen
/// for 82 frames: every round's motion entered the rod at the end the closest point did not hold.)
/// A corner within `spread` of the closest point with the closest point's normal (within
/// `cos_same`) adds no row: no lever against a tilt there, and the thinning would drop it (a
/// fine mesh's small triangles add nothing; an edge contact's faces do). A corner where the
/// features cross (negative gap) is left to the other rows. Frame M throughout.
int facePatch(const Shape& box, const Pose& X_MB, const geo::NearTriangle& c, const geo::TriangleMesh& mesh,
              const std::vector<std::uint8_t>& crease, double reach, double spread, double cos_same,
              geo::NearTriangle* out) {
  const double kCosFace = 0.9396926207859084;   // cos 20°
  const double kCosPlane = 0.7071067811865476;  // cos 45°
  const double kSinParallel = 0.01;             // edges closer than ~0.6° to parallel: no common normal
  const Vec3 v0 = mesh.vertex(c.triangle, 0), v1 = mesh.vertex(c.triangle, 1), v2 = mesh.vertex(c.triangle, 2);
  Vec3 n_T = (v1 - v0).cross(v2 - v0);
  const double len = n_T.norm();
  if (!(len > 0.0)) return 0;
  n_T /= len;
  if (n_T.dot(c.closest.n) < 0.0) n_T = -n_T;
  const Mat3 R = X_MB.q.toRotationMatrix();
  const Vec3 n_B = R.transpose() * c.closest.n;
  int j = 0;
  n_B.cwiseAbs().maxCoeff(&j);
  if (std::abs(n_B[j]) < kCosFace) return 0;  // the contact is at an edge or corner of the box
  const double s = n_B[j] > 0.0 ? -1.0 : 1.0;  // the face whose outward normal is -n
  const Vec3 n_F = -s * R.col(j);              // the face's normal, from the mesh towards the box
  const double cos_tilt = n_T.dot(n_F);
  if (cos_tilt < kCosPlane) return 0;  // the triangle too steep to the face
  const int u = (j + 1) % 3, w = (j + 2) % 3;
  const Vec3& h = box.half_extents;
  // The triangle in the face's coordinates (u, w), clipped by |u| <= h_u, |w| <= h_w. Each
  // polygon edge k (from vertex k to k + 1) carries the feature it lies on: 0 … 2 the triangle's
  // edge from vertex e to e + 1, 3 + side for a side of the face (side / 2: the clipped axis,
  // 0 = u, 1 = w).
  double poly[2][12][2];
  int tag[2][12];
  int count = 0, cur = 0;
  const Vec3 verts[3] = {v0, v1, v2};
  // Where the exact face and the triangle meet in no area, the face is clipped again grown by
  // `grow` and the corners are put back on it: a face whose side lies along a mesh edge (a palm
  // overhanging a square bar's edge) meets the triangle in a line, which the exact rectangle clips
  // to nothing (seen: a palm frozen for 157 frames, turning about its one row into the bar); the
  // grown one keeps the line's ends.
  for (const double grow : {0.0, std::min(reach, 1e-4)}) {
  if (count > 0) break;
  count = 3;
  cur = 0;
  for (int k = 0; k < 3; ++k) {
    const Vec3 t = R.transpose() * (verts[k] - X_MB.p);
    poly[0][k][0] = t[u];
    poly[0][k][1] = t[w];
    tag[0][k] = k;
  }
  for (int side = 0; side < 4 && count > 0; ++side) {
    const int axis = side / 2;
    const double sign = side % 2 ? -1.0 : 1.0, lim = (axis == 0 ? h[u] : h[w]) + grow;
    auto inside = [&](const double* p) { return sign * p[axis] <= lim; };
    int next = 0;
    for (int k = 0; k < count; ++k) {
      const double* a = poly[cur][k];
      const double* b = poly[cur][(k + 1) % count];
      const bool ia = inside(a), ib = inside(b);
      if (ia) {
        poly[1 - cur][next][0] = a[0];
        poly[1 - cur][next][1] = a[1];
        tag[1 - cur][next++] = tag[cur][k];
      }
      if (ia != ib) {
        const double t = (sign * lim - a[axis]) / (b[axis] - a[axis]);
        poly[1 - cur][next][0] = a[0] + t * (b[0] - a[0]);
        poly[1 - cur][next][1] = a[1] + t * (b[1] - a[1]);
        // Leaving: the polygon goes on along this side; entering: along the edge it crossed.
        tag[1 - cur][next++] = ia ? 3 + side : tag[cur][k];
      }
    }
    count = next;
    cur = 1 - cur;
  }
  }
  int added = 0;
  for (int k = 0; k < count && added < kMaxPatch; ++k) {
    Vec3 P_B = Vec3::Zero();
    P_B[j] = s * h[j];
    P_B[u] = std::clamp(poly[cur][k][0], -h[u], h[u]);
    P_B[w] = std::clamp(poly[cur][k][1], -h[w], h[w]);
    const Vec3 P = X_MB * P_B;
    // The triangle's point over P along the face's normal is P − h_F n_F.
    const double d_T = n_T.dot(P - v0), h_F = d_T / cos_tilt;
    const int in = tag[cur][(k + count - 1) % count], on = tag[cur][k];
    Vec3 n = n_F;
    double d = h_F;
    if (in >= 3 && on >= 3) {  // a corner of the face under the triangle
      n = n_T;
      d = d_T;
    } else if ((in >= 3 || on >= 3) && !crease[static_cast<size_t>(3 * c.triangle + (in < 3 ? in : on))]) {
      n = n_T;  // a triangle edge inside a flat region (a box face's diagonal): the plane's row
      d = d_T;
    } else if (in >= 3 || on >= 3) {  // a crease edge of the mesh across a side of the face
      const int e = in < 3 ? in : on, side = (in >= 3 ? in : on) - 3;
      const Vec3 e_T = verts[(e + 1) % 3] - verts[e];
      const Vec3 e_B = R.col(side / 2 == 0 ? w : u);  // a side clipping u runs along w
      Vec3 m = e_T.cross(e_B);
      const double mn = m.norm();
      if (mn > kSinParallel * e_T.norm()) {  // else parallel: the edge's height over the face
        m /= mn;
        if (m.dot(n_F) < 0.0) m = -m;
        n = m;
        d = h_F * m.dot(n_F);
      }
    }  // else a triangle vertex over the face: its height along the face's normal
    if (!(d >= 0.0) || d > reach) continue;  // crossing there: left to the other rows
    // Near the closest point only a row along another normal (an edge contact's face) adds a
    // constraint; a row along the same normal there is no lever against a tilt.
    if ((P - c.closest.p_shape).squaredNorm() < spread * spread && n.dot(c.closest.n) > cos_same) continue;
    geo::NearTriangle& o = out[added++];
    o.triangle = c.triangle;
    o.closest.distance = d;
    o.closest.core_distance = d;  // a box's core is the box
    o.closest.p_shape = P;
    o.closest.p_triangle = P - d * n;
    o.closest.n = n;
  }
  return added;
}

std::uint64_t contactKey(int object, int triangle, int body, int sample) {
  const std::uint64_t id = (static_cast<std::uint64_t>(object) << 45) ^
                           (static_cast<std::uint64_t>(static_cast<std::uint32_t>(triangle)) << 13) ^
                           (static_cast<std::uint64_t>(sample & 0x1f) << 8) ^ static_cast<std::uint64_t>(body & 0xff);
  return rowKey(RowKind::Contact, id);
}

// The shape grown by `skin` (a sphere or capsule's radius; a box's half extents, which encloses
// the box rounded by it): what the God side of an object with a skin collides.
Shape grown(const Shape& shape, double skin) {
  if (!(skin > 0.0)) return shape;
  Shape g = shape;
  if (g.type == ShapeType::Box) g.half_extents.array() += skin;
  else g.radius += skin;
  return g;
}

// Box of a sphere of radius r swept along the segment a–b.
geo::Aabb sweptBox(const Vec3& a, const Vec3& b, double r) {
  geo::Aabb box;
  box.grow(a);
  box.grow(b);
  return box.inflated(r);
}
}  // namespace

CollisionWorld::CollisionWorld(const Scene& scene) {
  objects_.reserve(scene.objects.size());
  union_box_.resize(scene.objects.size());
  leaf_of_.assign(scene.objects.size(), -1);
  split_key_.resize(scene.objects.size());
  is_moved_.assign(scene.objects.size(), 0);
  moved_.reserve(scene.objects.size());
  costs_.resize(scene.objects.size());
  for (const SceneObject& so : scene.objects) {
    Object o;
    o.god = so.god.get();
    o.reference = so.reference ? so.reference.get() : so.god.get();
    o.dynamic = so.mass > 0.0;
    o.skin = std::isfinite(so.god_skin) && so.god_skin > 0.0 ? so.god_skin : 0.0;
    max_skin_ = std::max(max_skin_, o.skin);
    objects_.push_back(o);
    place(objects_.size() - 1, so.X_WO);
  }
  const size_t slots = std::max<size_t>(1, std::min<size_t>(kHintSlots, scene.objects.size()));
  hints_.assign(slots * kHintBodies * kPartSamples, -1);
  hint_tag_.assign(slots, -1);
  near_.reserve(1024);
  shell_.reserve(1024);
  order_.reserve(1024);
  sample_.reserve(64);
  kept_.reserve(16);
  cand_.reserve(scene.objects.size());
  stack_.reserve(128);
  build_ids_.reserve(scene.objects.size());
  nodes_.reserve(2 * scene.objects.size());
  if (objectCount() > kLinearUpTo) buildTree();
}

double CollisionWorld::godBoundingRadius(const Shape& shape) const {
  return geo::boundingRadius(grown(shape, max_skin_));
}

void CollisionWorld::place(size_t object, const Pose& X_WO) {
  Object& o = objects_[object];
  o.X_WO = X_WO;
  o.box_W = o.god ? geo::transformAabb(o.god->bounds(), X_WO).inflated(o.skin) : geo::Aabb{};
  o.ref_box_W = o.reference ? geo::transformAabb(o.reference->bounds(), X_WO) : geo::Aabb{};
  geo::Aabb u = o.box_W;
  u.grow(o.ref_box_W);
  geo::Aabb& old = union_box_[object];
  if (u.lo != old.lo || u.hi != old.hi) {
    old = u;
    if (leaf_of_[object] < 0) {
      rebuild_ = true;  // not in the tree (it had no box)
    } else if (!is_moved_[object]) {
      is_moved_[object] = 1;
      moved_.push_back(static_cast<int>(object));
    }
  }
}

void CollisionWorld::setObjectPose(int object, const Pose& X_WO) {
  const Object& o = objects_[static_cast<size_t>(object)];
  // The same pose again (a resting object in every snapshot): nothing to recompute.
  if (X_WO.p == o.X_WO.p && X_WO.q.coeffs() == o.X_WO.q.coeffs()) return;
  place(static_cast<size_t>(object), X_WO);
}

void CollisionWorld::resetCosts() {
  std::fill(costs_.begin(), costs_.end(), ObjectCost{});
  visited_ = 0;
}

void CollisionWorld::CostClock::charge(size_t object) {
  if (!on_) return;
  const std::chrono::steady_clock::time_point t = std::chrono::steady_clock::now();
  ObjectCost& c = w_.costs_[object];
  c.us += std::chrono::duration<double, std::micro>(t - t_).count();
  ++c.queries;
  t_ = t;
}

void CollisionWorld::buildTree() const {
  nodes_.clear();
  build_ids_.clear();
  std::fill(leaf_of_.begin(), leaf_of_.end(), -1);
  for (int i = 0; i < objectCount(); ++i)
    if (!union_box_[static_cast<size_t>(i)].empty()) build_ids_.push_back(i);
  if (!build_ids_.empty()) buildNode(build_ids_.data(), static_cast<int>(build_ids_.size()), -1);
  for (int o : moved_) is_moved_[static_cast<size_t>(o)] = 0;
  moved_.clear();
  moved_since_build_ = 0;
  rebuild_ = false;
}

int CollisionWorld::buildNode(int* ids, int count, int parent) const {
  const int me = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  geo::Aabb box, centres;
  for (int k = 0; k < count; ++k) {
    const geo::Aabb& b = union_box_[static_cast<size_t>(ids[k])];
    box.grow(b);
    centres.grow(b.centre());
  }
  nodes_[static_cast<size_t>(me)].box = box;
  nodes_[static_cast<size_t>(me)].parent = parent;
  if (count == 1) {
    nodes_[static_cast<size_t>(me)].object = ids[0];
    leaf_of_[static_cast<size_t>(ids[0])] = me;
    return me;
  }
  int axis = 0;
  centres.extent().maxCoeff(&axis);
  for (int k = 0; k < count; ++k) {  // the split key (twice the centre), once per object
    const geo::Aabb& b = union_box_[static_cast<size_t>(ids[k])];
    split_key_[static_cast<size_t>(ids[k])] = b.lo[axis] + b.hi[axis];
  }
  const int mid = count / 2;
  std::nth_element(ids, ids + mid, ids + count, [&](int a, int b) {
    const double ka = split_key_[static_cast<size_t>(a)], kb = split_key_[static_cast<size_t>(b)];
    return ka < kb || (ka == kb && a < b);
  });
  buildNode(ids, mid, me);  // the left child: node me + 1
  const int right = buildNode(ids + mid, count - mid, me);
  nodes_[static_cast<size_t>(me)].right = right;
  return me;
}

void CollisionWorld::refitTree() const {
  if (moved_.size() * 16 > nodes_.size()) {  // many moved: one pass from the leaves up (children after parents)
    for (size_t i = nodes_.size(); i-- > 0;) {
      Node& nd = nodes_[i];
      if (nd.object >= 0) {
        nd.box = union_box_[static_cast<size_t>(nd.object)];
      } else {
        nd.box = nodes_[i + 1].box;
        nd.box.grow(nodes_[static_cast<size_t>(nd.right)].box);
      }
    }
    for (int o : moved_) is_moved_[static_cast<size_t>(o)] = 0;
    moved_since_build_ += moved_.size();
    moved_.clear();
    return;
  }
  for (int o : moved_) {  // a few moved: their leaves and the paths up
    is_moved_[static_cast<size_t>(o)] = 0;
    int i = leaf_of_[static_cast<size_t>(o)];
    nodes_[static_cast<size_t>(i)].box = union_box_[static_cast<size_t>(o)];
    for (i = nodes_[static_cast<size_t>(i)].parent; i >= 0; i = nodes_[static_cast<size_t>(i)].parent) {
      Node& nd = nodes_[static_cast<size_t>(i)];
      nd.box = nodes_[static_cast<size_t>(i) + 1].box;
      nd.box.grow(nodes_[static_cast<size_t>(nd.right)].box);
    }
  }
  moved_since_build_ += moved_.size();
  moved_.clear();
}

const std::vector<int>& CollisionWorld::candidates(const geo::Aabb& query) const {
  cand_.clear();
  const int n = objectCount();
  if (n <= kLinearUpTo) {
    for (int i = 0; i < n; ++i) cand_.push_back(i);
    if (untimed_ == 0) visited_ += cand_.size();
    return cand_;
  }
  if (rebuild_ || moved_since_build_ + moved_.size() >= std::max<std::size_t>(kRebuildAfter, kRebuildFactor * static_cast<size_t>(n)))
    buildTree();
  else if (!moved_.empty()) refitTree();
  if (nodes_.empty() || !nodes_[0].box.overlaps(query)) return cand_;
  stack_.clear();
  stack_.push_back(0);
  while (!stack_.empty()) {
    const int i = stack_.back();
    stack_.pop_back();
    const Node& nd = nodes_[static_cast<size_t>(i)];
    if (!nd.box.overlaps(query)) continue;
    if (nd.object >= 0) {
      cand_.push_back(nd.object);
    } else {
      stack_.push_back(nd.right);
      stack_.push_back(i + 1);
    }
  }
  std::sort(cand_.begin(), cand_.end());  // index order: the answers of a scan over every object
  if (untimed_ == 0) visited_ += cand_.size();
  return cand_;
}

bool CollisionWorld::insideGod(const Object& o, const Pose& X_OB) const {
  if (!o.dynamic) return false;  // static objects: the sweep never lets a God object in
  const geo::Aabb& b = o.god->bounds();
  if ((X_OB.p.array() < b.lo.array()).any() || (X_OB.p.array() > b.hi.array()).any()) return false;
  return o.god->inside(X_OB.p);
}

int& CollisionWorld::hintOf(int object, int body, int sample) {
  scratch_hint_ = -1;
  if (body < 0 || body >= kHintBodies || object < 0) return scratch_hint_;
  const size_t per_slot = static_cast<size_t>(kHintBodies) * kPartSamples;
  const size_t slot = static_cast<size_t>(object) % hint_tag_.size();
  int* h = hints_.data() + slot * per_slot;
  if (hint_tag_[slot] != object) {  // another object's hints: forgotten
    std::fill(h, h + per_slot, -1);
    hint_tag_[slot] = object;
  }
  return h[static_cast<size_t>(body) * kPartSamples + static_cast<size_t>(sample)];
}

int CollisionWorld::contacts(const Shape& body_shape, const Pose& X_WB, int body, double reach,
                             const ContactParams& params, std::vector<Contact>* out, QueryStart* start) {
  if (start) {
    start->reach = reach;
    start->objects.clear();
  }
  // (The shape as the God side sees it, grown by the largest skin: a box's corners reach √3 skin
  // farther, more than the object's box grown by its skin allows for.)
  const geo::Aabb query_W = geo::shapeAabb(grown(body_shape, max_skin_), X_WB).inflated(reach);
  const double cos_same = std::cos(params.normal_angle);
  const double spread = std::max(params.spread, params.spread_fraction * geo::boundingRadius(body_shape));
  const double spread2 = spread * spread;
  Shape samples[kPartSamples];
  Vec3 offsets[kPartSamples];
  int num_samples = 0;
  double samples_skin = -1.0;
  int added = 0;
  CostClock clock(*this);
  for (const int object : candidates(query_W)) {
    const size_t oi = static_cast<size_t>(object);
    const Object& o = objects_[oi];
    if (!o.god || !o.box_W.overlaps(query_W)) continue;
    const Charge charge(clock, oi);
    const Shape shape = grown(body_shape, o.skin);
    if (o.skin != samples_skin) {
      // Sample shapes (body frame): the whole shape, plus the capsule's end spheres or the box's
      // corners, so that a body lying along a surface gets contacts at both ends / all corners.
      samples_skin = o.skin;
      num_samples = 1;
      samples[0] = shape;
      offsets[0] = Vec3::Zero();
      if (shape.type == ShapeType::Capsule) {
        Shape end;
        end.type = ShapeType::Sphere;
        end.radius = shape.radius;
        for (int s = -1; s <= 1; s += 2) {
          samples[num_samples] = end;
          offsets[num_samples++] = Vec3(0, 0, s * shape.half_length);
        }
      } else if (shape.type == ShapeType::Box) {
        Shape corner;
        corner.type = ShapeType::Sphere;
        corner.radius = 0.0;
        for (int c = 0; c < 8; ++c) {
          samples[num_samples] = corner;
          offsets[num_samples++] = Vec3((c & 1) ? 1 : -1, (c & 2) ? 1 : -1, (c & 4) ? 1 : -1).cwiseProduct(shape.half_extents);
        }
        // And the midpoints of its twelve edges: a mesh ridge or vertex under the middle of an
        // edge is nearer that point than any corner, and the whole shape's closest point finds
        // only the nearest feature. Without them a palm beside the fandisk's ridges (pinch at
        // 0.15 m) turned its edge into a face 5 mm off that no row held, every round was clipped
        // and held, and the hand froze in 51 of 166 windows.
        for (int ax = 0; ax < 3; ++ax)
            for (int c = 0; c < 4; ++c) {
              const Vec3 sg((c & 1) ? 1 : -1, (c & 2) ? 1 : -1, 0);
              Vec3 e;
              e[ax] = 0; e[(ax + 1) % 3] = sg.x(); e[(ax + 2) % 3] = sg.y();
              samples[num_samples] = corner;
              offsets[num_samples++] = e.cwiseProduct(shape.half_extents);
            }
      }
    }
    const Pose X_OB = o.X_WO.inverse() * X_WB;
    const bool inside = insideGod(o, X_OB);
    near_.clear();
    sample_.clear();
    // Inside a (dynamic) object the nearest surface may be farther than the reach.
    const double range = inside ? kInf : reach;
    // The shell's triangles (below) first: where the shape is within the shell, its nearest
    // triangle is among them, and the whole shape's closest-point query is answered from them
    // (MeshBvh::closestAmong: the same triangle and points, bit for bit) instead of traversing
    // the same part of the hierarchy a second time.
    const bool shell_query = !inside && params.shell > 0.0;
    if (shell_query) {
      shell_.clear();
      o.god->near(shape, X_OB, params.shell, &shell_);
    }
    for (int k = 0; k < num_samples; ++k) {
      geo::NearTriangle c;
      const Pose X_OS{X_OB * offsets[k], X_OB.q};
      // What this sample of this body found here last time starts the search (the same result,
      // found sooner: MeshBvh::closest).
      int& hint = hintOf(object, body, k);
      const bool found = (k == 0 && shell_query && o.god->closestAmong(shell_, shape, X_OB, params.shell, range, &c)) ||
                         o.god->closest(samples[k], X_OS, range, &c, hint);
      if (found) hint = c.triangle;
      if (k == 0 && start) {
        geo::SweepStart s;
        s.range = range;
        s.found = found;
        if (found) s.nearest = c;
        start->objects.emplace_back(object, s);
      }
      if (!found) {
        if (k == 0) break;  // nothing within reach of the whole shape: none of its parts either
        continue;
      }
      near_.push_back(c);
      sample_.push_back(k < 9 ? k : kEdgeSample + (k - 9));  // (9 … 15 are the patch and shell ids)
    }
    if (near_.empty()) continue;
    if (!inside && shape.type == ShapeType::Box && sample_[0] == 0) {
      geo::NearTriangle patch[kMaxPatch];
      const int np = facePatch(shape, X_OB, near_[0], o.god->mesh(), o.god->creases(), range, spread, cos_same, patch);
      for (int i = 0; i < np; ++i) {
        near_.push_back(patch[i]);
        sample_.push_back(kPatchSample + i);
      }
    }
    if (shell_query) {
      double nearest = kInf;
      for (const geo::NearTriangle& c : near_) nearest = std::min(nearest, c.closest.distance);
      if (nearest < params.shell) {
        for (const geo::NearTriangle& c : shell_) {
          near_.push_back(c);
          sample_.push_back(kShellSample);
        }
        // A box gets the patch of every shell triangle too, not only of the nearest one: a palm
        // whose face lies on a square bar's edge has both of the bar's faces at that edge in its
        // shell, and the nearest may be the one too steep to the palm for a patch (67° off; the
        // other, 23° off, holds the line's ends). With one patch the palm turned about its one
        // row into the bar round after round: pinch on bar_x at 0.3 m froze in 71 of 166 windows.
        if (shape.type == ShapeType::Box) {
          geo::NearTriangle patch[kMaxPatch];
          for (size_t f = 0; f < shell_.size(); ++f) {
            if (shell_[f].triangle == near_[0].triangle) continue;  // patched above
            const int np = facePatch(shape, X_OB, shell_[f], o.god->mesh(), o.god->creases(), range, spread, cos_same, patch);
            for (int i = 0; i < np; ++i) {
              near_.push_back(patch[i]);
              sample_.push_back(kPatchSample + i);
            }
          }
        }
      }
    }
    order_.resize(near_.size());
    for (size_t i = 0; i < near_.size(); ++i) order_[i] = static_cast<int>(i);
    // The parts' own closest points within the shell first (they span the body: a box resting
    // on an edge keeps rows at its other corners, which stop it from rolling about that edge),
    // then the shell's triangles, then the parts' points farther out; nearest first within each.
    const double shell = params.shell;
    auto rank = [&](int i) {
      if (sample_[static_cast<size_t>(i)] == kShellSample) return 1;
      return near_[static_cast<size_t>(i)].closest.distance < shell || shell <= 0.0 ? 0 : 2;
    };
    std::sort(order_.begin(), order_.end(), [&](int a, int b) {
      const int ra = rank(a), rb = rank(b);
      if (ra != rb) return ra < rb;
      const double da = near_[static_cast<size_t>(a)].closest.distance, db = near_[static_cast<size_t>(b)].closest.distance;
      return da < db || (da == db && near_[static_cast<size_t>(a)].triangle < near_[static_cast<size_t>(b)].triangle);
    });
    kept_.clear();
    for (int idx : order_) {
      if (static_cast<int>(kept_.size()) >= params.per_pair) break;
      const geo::NearTriangle& c = near_[static_cast<size_t>(idx)];
      bool redundant = false;
      for (int k : kept_) {
        const geo::ClosestPoints& q = near_[static_cast<size_t>(k)].closest;
        if ((q.p_triangle - c.closest.p_triangle).squaredNorm() < spread2 && q.n.dot(c.closest.n) > cos_same) {
          redundant = true;
          break;
        }
      }
      if (!redundant) kept_.push_back(idx);
    }
    for (int k : kept_) {
      const geo::NearTriangle& c = near_[static_cast<size_t>(k)];
      Contact ct;
      ct.body = body;
      ct.object = static_cast<int>(oi);
      ct.key = contactKey(static_cast<int>(oi), c.triangle, body, sample_[static_cast<size_t>(k)]);
      ct.triangle = c.triangle;
      ct.p_W = o.X_WO * c.closest.p_shape;
      ct.n_W = o.X_WO.q * c.closest.n;
      ct.distance = c.closest.distance;
      if (inside) {  // the triangle's closest point is an exit: push out through it
        ct.n_W = -ct.n_W;
        ct.distance = -(c.closest.core_distance + geo::coreRadius(shape));
        ct.p_W = o.X_WO * c.closest.p_triangle;
      }
      out->push_back(ct);
      ++added;
    }
  }
  return added;
}

bool CollisionWorld::triangleContact(const Shape& body_shape, const Pose& X_WB, const Contact& c, Contact* out) const {
  if (c.object < 0 || static_cast<size_t>(c.object) >= objects_.size() || c.triangle < 0) return false;
  const Object& o = objects_[static_cast<size_t>(c.object)];
  if (!o.god || c.triangle >= o.god->triangleCount()) return false;
  const Pose X_OB = o.X_WO.inverse() * X_WB;
  if (insideGod(o, X_OB)) return false;
  const geo::TriangleMesh& mesh = o.god->mesh();
  const auto& t = mesh.triangles[static_cast<size_t>(c.triangle)];
  const geo::ClosestPoints cp = geo::shapeTriangle(grown(body_shape, o.skin), X_OB, mesh.vertices[static_cast<size_t>(t[0])],
                                                   mesh.vertices[static_cast<size_t>(t[1])], mesh.vertices[static_cast<size_t>(t[2])]);
  *out = c;
  out->p_W = o.X_WO * cp.p_shape;
  out->n_W = o.X_WO.q * cp.n;
  out->distance = cp.distance;
  return true;
}

geo::SweepResult CollisionWorld::sweep(const Shape& shape, const Pose& X_W0, const Pose& X_W1,
                                       const geo::SweepParams& params, int* object_hit, const QueryStart* start) const {
  geo::SweepResult best;
  best.distance = kInf;
  if (object_hit) *object_hit = -1;
  int total_iterations = 0;
  const geo::Aabb swept = sweptBox(X_W0.p, X_W1.p, godBoundingRadius(shape) + params.stop_distance);
  CostClock clock(*this);
  for (const int object : candidates(swept)) {
    const size_t oi = static_cast<size_t>(object);
    const Object& o = objects_[oi];
    if (!o.god || !o.box_W.overlaps(swept)) continue;
    const Charge charge(clock, oi);
    const Pose X_WOinv = o.X_WO.inverse();
    const geo::SweepStart* known = nullptr;
    geo::SweepStart none;
    if (start) {
      none.range = start->reach;  // not listed: nothing within the reach
      known = &none;
      for (const auto& e : start->objects)
        if (e.first == object) known = &e.second;
    }
    const geo::SweepResult r = geo::sweep(grown(shape, o.skin), X_WOinv * X_W0, X_WOinv * X_W1, *o.god, params, known);
    total_iterations += r.iterations;
    if (r.started_inside) {
      // Inside: no time of contact to find (resolved by push-out contacts). It may recede or
      // slide in there, never go deeper: a motion that takes it deeper (the exact depth at the
      // end or at the quarter points along it) does not move at all.
      best.started_inside = true;
      if (deeperAlong(o, shape, X_W0, X_W1)) {
        best.toc = 0.0;
        best.hit = true;
        best.distance = 0.0;
        if (object_hit) *object_hit = static_cast<int>(oi);
      }
      continue;
    }
    if (r.toc < best.toc || (r.hit && !best.hit && r.toc <= best.toc)) {
      const bool started = best.started_inside;
      best = r;
      best.started_inside = started;
      if (object_hit) *object_hit = static_cast<int>(oi);
    }
    best.iterations = std::max(best.iterations, r.iterations);
  }
  best.capped = best.hit && best.capped;
  best.iterations = total_iterations;  // the work of every object's sweep
  return best;
}

namespace {
/// Depth (m) of point p (body frame) inside the shape (< 0 outside) and the shape's outward
/// normal there (body frame): r − signed distance to the core.
double depthInShape(const Shape& shape, const Vec3& p, Vec3* n) {
  if (shape.type == ShapeType::Box) {
    const Vec3 q = p.cwiseAbs() - shape.half_extents;
    if ((q.array() <= 0.0).all()) {  // inside: out through the nearest face
      int k = 0;
      q.maxCoeff(&k);
      *n = Vec3::Zero();
      (*n)[k] = p[k] >= 0.0 ? 1.0 : -1.0;
      return -q[k];
    }
    const Vec3 out = q.cwiseMax(0.0);
    const double d = out.norm();
    *n = out.cwiseProduct(p.cwiseSign()) / d;
    return -d;
  }
  const double h = shape.type == ShapeType::Capsule ? shape.half_length : 0.0;
  const Vec3 c(0, 0, std::clamp(p.z(), -h, h));
  const Vec3 v = p - c;
  const double d = v.norm();
  *n = d > 0.0 ? Vec3(v / d) : Vec3::UnitZ();
  return shape.radius - d;
}

/// Points of the shape's core, body frame: its centre, its extreme points (a capsule's ends, a
/// box's corners) and points along its edges (a box's 12 edges, a capsule's axis).
int corePoints(const Shape& shape, Vec3* pts) {
  int np = 0;
  pts[np++] = Vec3::Zero();
  if (shape.type == ShapeType::Capsule) {
    for (int k = -4; k <= 4; ++k)
      if (k != 0) pts[np++] = Vec3(0, 0, shape.half_length * k / 4.0);
  } else if (shape.type == ShapeType::Box) {
    const Vec3& e = shape.half_extents;
    for (int k = 0; k < 8; ++k) pts[np++] = Vec3((k & 1) ? 1 : -1, (k & 2) ? 1 : -1, (k & 4) ? 1 : -1).cwiseProduct(e);
    for (int axis = 0; axis < 3; ++axis)
      for (int k = 0; k < 4; ++k)
        for (int s = 1; s < 4; ++s) {  // 3 interior points on each of the 12 edges
          Vec3 q((k & 1) ? 1 : -1, (k & 2) ? 1 : -1, 0);
          Vec3 pt;
          pt[axis] = (s - 2) * 0.5;
          pt[(axis + 1) % 3] = q.x();
          pt[(axis + 2) % 3] = q.y();
          pts[np++] = pt.cwiseProduct(e);
        }
  }
  return np;
}
constexpr int kMaxCorePoints = 1 + 8 + 36;

/// The largest depth inside the shape (body frame) of a point of segment ab, if it exceeds
/// `floor` (else any value ≤ floor), and the shape's outward normal there. Sphere and capsule:
/// r − the segment's distance to the core, exact. Box: the depth min_i (h_i − |p_i|) is concave
/// and piecewise linear along the segment, so its maximum is at an end or where two of its six
/// lines cross; each axis alone bounds it, which skips most segments.
double deepestOnSegment(const Shape& shape, const Vec3& a, const Vec3& b, double floor, Vec3* n) {
  if (shape.type != ShapeType::Box) {
    const double h = shape.type == ShapeType::Capsule ? shape.half_length : 0.0;
    Vec3 on_seg, on_core;
    const double d = geo::segmentSegmentDistance(a, b, Vec3(0, 0, -h), Vec3(0, 0, h), &on_seg, &on_core);
    const double depth = shape.radius - d;
    if (depth > floor) depthInShape(shape, on_seg, n);
    return depth;
  }
  const Vec3& e = shape.half_extents;
  const Vec3 d = b - a;
  for (int i = 0; i < 3; ++i) {  // h_i − min_t |a_i + t d_i| bounds the depth
    const bool crosses = (a[i] <= 0.0) != (b[i] <= 0.0);
    const double m = crosses ? 0.0 : std::min(std::abs(a[i]), std::abs(b[i]));
    if (e[i] - m <= floor) return floor;
  }
  // Lines s = h_i − σ (a_i + t d_i), σ = ±1: the candidates are t = 0, 1 and their crossings.
  double cand[2 + 15];
  int nc = 0;
  cand[nc++] = 0.0;
  cand[nc++] = 1.0;
  double c0[6], c1[6];  // line j: c0 + c1 t
  for (int j = 0; j < 6; ++j) {
    const int i = j / 2;
    const double sg = (j & 1) ? -1.0 : 1.0;
    c0[j] = e[i] - sg * a[i];
    c1[j] = -sg * d[i];
  }
  for (int j = 0; j < 6; ++j)
    for (int l = j + 1; l < 6; ++l) {
      const double den = c1[j] - c1[l];
      if (den == 0.0) continue;
      const double t = (c0[l] - c0[j]) / den;
      if (t > 0.0 && t < 1.0) cand[nc++] = t;
    }
  double best = -std::numeric_limits<double>::infinity(), t_best = 0.0;
  for (int c = 0; c < nc; ++c) {
    double s = std::numeric_limits<double>::infinity();
    for (int j = 0; j < 6; ++j) s = std::min(s, c0[j] + c1[j] * cand[c]);
    if (s > best) {
      best = s;
      t_best = cand[c];
    }
  }
  if (best > floor) depthInShape(shape, a + t_best * d, n);
  return best;
}
}  // namespace

CollisionWorld::Overlap CollisionWorld::overlapIn(const geo::MeshBvh& mesh, const Pose& X_WO, const Shape& shape,
                                                  const Pose& X_WB, int origin_known,
                                                  const geo::NearTriangle* nearest) const {
  Overlap best;
  const Pose X_OB = X_WO.inverse() * X_WB;
  const double r = geo::coreRadius(shape);
  const geo::Aabb& rb = mesh.bounds();
  auto in_box = [&](const Vec3& p) { return (p.array() >= rb.lo.array()).all() && (p.array() <= rb.hi.array()).all(); };
  geo::NearTriangle c;
  const bool origin_inside = origin_known >= 0 ? origin_known == 1 : in_box(X_OB.p) && mesh.inside(X_OB.p);
  if (!origin_inside) {
    if (nearest && !(nearest->closest.core_distance > 0.0)) c = *nearest;
    else if (!mesh.closest(shape, X_OB, 0.0, &c)) return best;  // apart
    best.depth = std::max(0.0, -c.closest.distance);       // the rounded shell's overlap
    best.n_W = X_WO.q * c.closest.n;
    if (c.closest.core_distance > 0.0) return best;         // the cores do not cross
  }
  // The cores cross (or the body's origin is inside): the depth is that of the deepest witness,
  // a point of the body inside the object or a point of the object inside the body. Two solids
  // overlap only where an edge of one crosses the other, so the body's core points (its centre,
  // ends, corners and edges) and the deepest point of each of the object's edges near the body
  // (depth inside a convex shape is concave along a line: a golden-section search) find it.
  Shape point;
  point.type = ShapeType::Sphere;
  point.radius = 0.0;
  Vec3 pts[kMaxCorePoints];
  const int np = corePoints(shape, pts);
  for (int k = 0; k < np; ++k) {
    const Vec3 q = X_OB * pts[k];
    if (!in_box(q) || !mesh.inside(q)) continue;
    geo::NearTriangle e;
    if (!mesh.closest(point, Pose{q, Quat::Identity()}, kInf, &e)) continue;
    const double depth = e.closest.core_distance + r;
    if (depth > best.depth) {
      best.depth = depth;
      // From the point out through the nearest surface: the object leaves along −n.
      const Vec3 out = e.closest.p_triangle - q;
      best.n_W = X_WO.q * (out.norm() > 0.0 ? Vec3(out.normalized()) : Vec3(-e.closest.n));
    }
  }
  // A shell (an open surface) has no inside, so no point of the body is "inside" it: where the
  // body's core crosses one of its faces, the depth is how far the body reaches through that
  // face's plane on its shallower side, h − |s| (h: the body's extent along the normal, s: its
  // centre's distance from the plane). Exact where the face covers the body's footprint, an
  // over-estimate near the face's edges (whose own witnesses follow): never less than the truth.
  if (!mesh.solid()) {
    tris_.clear();
    mesh.trianglesOverlapping(geo::shapeAabb(shape, X_OB), &tris_);
    const Pose X_BO = X_OB.inverse();
    const Mat3 R_BO = X_BO.q.toRotationMatrix();
    for (int t : tris_) {
      const Vec3 v0 = R_BO * mesh.mesh().vertex(t, 0) + X_BO.p, v1 = R_BO * mesh.mesh().vertex(t, 1) + X_BO.p,
                 v2 = R_BO * mesh.mesh().vertex(t, 2) + X_BO.p;
      const Vec3 cross = (v1 - v0).cross(v2 - v0);
      if (!(cross.norm() > 0.0)) continue;
      Vec3 core_B, tri_B;
      if (geo::detail::coreTriangle(shape, v0, v1, v2, &core_B, &tri_B) > 0.0) continue;
      const Vec3 n = cross.normalized();
      const double s = -n.dot(v0);  // the body origin (0 in B) from the plane
      double h = r;
      if (shape.type == ShapeType::Box) h += n.cwiseAbs().dot(shape.half_extents);
      else if (shape.type == ShapeType::Capsule) h += std::abs(n.z()) * shape.half_length;
      const double depth = h - std::abs(s);
      if (depth > best.depth) {
        best.depth = depth;
        best.n_W = X_WB.q * Vec3(s >= 0.0 ? n : Vec3(-n));  // from the face towards the body's centre
      }
    }
  }
  // The object's edges inside the body: the deepest point of each. A point deeper than the
  // deepest witness so far lies inside the shape eroded by that depth (exact for boxes, capsules
  // and spheres): only triangles that reach into its box are looked at, none when it is empty.
  Shape eroded = shape;
  if (shape.type == ShapeType::Box) {
    eroded.half_extents = shape.half_extents - Vec3::Constant(best.depth);
    if ((eroded.half_extents.array() <= 0.0).any()) return best;
  } else {
    eroded.radius = shape.radius - best.depth;
    if (eroded.radius <= 0.0) return best;
  }
  tris_.clear();
  mesh.trianglesOverlapping(geo::shapeAabb(eroded, X_OB), &tris_);
  const Pose X_BO = X_OB.inverse();
  const Mat3 R_BO = X_BO.q.toRotationMatrix();
  for (int t : tris_) {
    const Vec3 v[3] = {R_BO * mesh.mesh().vertex(t, 0) + X_BO.p, R_BO * mesh.mesh().vertex(t, 1) + X_BO.p,
                       R_BO * mesh.mesh().vertex(t, 2) + X_BO.p};
    // No point of the triangle is deeper than its bounding sphere's centre allows.
    const Vec3 centre = (v[0] + v[1] + v[2]) / 3.0;
    const double rho =
        std::sqrt(std::max({(v[0] - centre).squaredNorm(), (v[1] - centre).squaredNorm(), (v[2] - centre).squaredNorm()}));
    Vec3 unused;
    if (depthInShape(shape, centre, &unused) + rho <= best.depth) continue;
    for (int k = 0; k < 3; ++k) {
      Vec3 n_B;
      const double depth = deepestOnSegment(shape, v[k], v[(k + 1) % 3], best.depth, &n_B);
      if (depth > best.depth) {
        best.depth = depth;
        // The object's point leaves the body through the body's nearest surface: along −n.
        best.n_W = X_WB.q * Vec3(-n_B);
      }
    }
  }
  return best;
}

double CollisionWorld::depthIn(const Object& o, const Shape& shape, const Pose& X_WB) const {
  return o.reference ? overlapIn(*o.reference, o.X_WO, shape, X_WB).depth : 0.0;
}

bool CollisionWorld::deeperAlong(const Object& o, const Shape& shape, const Pose& X_W0, const Pose& X_W1) const {
  if (!o.reference) return false;
  const double d0 = depthIn(o, shape, X_W0);
  for (int k = 1; k <= 4; ++k)
    if (depthIn(o, shape, geo::interpolateMotion(X_W0, X_W1, 0.25 * k)) > d0 + kDeeperTolerance) return true;
  return false;
}

double CollisionWorld::penetration(const Shape& shape, const Pose& X_WB, int* object) const {
  double deepest = 0.0;
  if (object) *object = -1;
  const geo::Aabb box = geo::shapeAabb(shape, X_WB);
  for (const int candidate : candidates(box)) {
    const size_t oi = static_cast<size_t>(candidate);
    const Object& o = objects_[oi];
    if (!o.reference || !o.ref_box_W.overlaps(box)) continue;
    const double depth = depthIn(o, shape, X_WB);
    if (depth > deepest) {
      deepest = depth;
      if (object) *object = static_cast<int>(oi);
    }
  }
  return deepest;
}

double CollisionWorld::signedDistance(int object, const Shape& body_shape, const Pose& X_WB, double range,
                                      Vec3* n_W) const {
  const Object& o = objects_[static_cast<size_t>(object)];
  const Shape shape = grown(body_shape, o.skin);
  if (!o.god) return kInf;
  // Callers ask every object about one body in turn: its query box is computed once.
  if (!memo_.valid || memo_.range != range || memo_.shape.type != shape.type || memo_.shape.radius != shape.radius ||
      memo_.shape.half_length != shape.half_length || memo_.shape.half_extents != shape.half_extents ||
      memo_.X.p != X_WB.p || memo_.X.q.coeffs() != X_WB.q.coeffs()) {
    memo_.valid = true;
    memo_.shape = shape;
    memo_.X = X_WB;
    memo_.range = range;
    memo_.box = geo::shapeAabb(shape, X_WB).inflated(range);
  }
  if (!o.box_W.overlaps(memo_.box)) return kInf;
  CostClock clock(*this);
  const Charge charge(clock, static_cast<size_t>(object));
  const Pose X_OB = o.X_WO.inverse() * X_WB;
  geo::NearTriangle c;
  const geo::Aabb& gb = o.god->bounds();
  const bool in_box = (X_OB.p.array() >= gb.lo.array()).all() && (X_OB.p.array() <= gb.hi.array()).all();
  const bool origin_inside = in_box && o.god->inside(X_OB.p);
  if (!origin_inside) {
    if (!o.god->closest(shape, X_OB, range, &c)) return kInf;
    if (c.closest.core_distance > 0.0) {  // apart, or only the shells overlap
      if (n_W) *n_W = o.X_WO.q * c.closest.n;
      return c.closest.distance;
    }
  }
  // The cores cross: the depth of the deepest witness (overlapIn), not the 0 of crossing cores.
  const Overlap ov = overlapIn(*o.god, o.X_WO, shape, X_WB, origin_inside ? 1 : 0, origin_inside ? nullptr : &c);
  if (n_W) *n_W = ov.n_W;
  return -ov.depth;
}

bool CollisionWorld::closerThan(int object, const Shape& body_shape, const Pose& X_WB, double range) const {
  if (!(range > 0.0)) return signedDistance(object, body_shape, X_WB, range, nullptr) < range;
  const Object& o = objects_[static_cast<size_t>(object)];
  if (!o.god) return false;
  const Shape shape = grown(body_shape, o.skin);
  // signedDistance's steps up to where its answer is known to be below the range: an origin inside
  // (−depth ≤ 0) or crossing cores (the same), else the distance itself.
  if (!o.box_W.overlaps(geo::shapeAabb(shape, X_WB).inflated(range))) return false;
  CostClock clock(*this);
  const Charge charge(clock, static_cast<size_t>(object));
  const Pose X_OB = o.X_WO.inverse() * X_WB;
  const geo::Aabb& gb = o.god->bounds();
  const bool in_box = (X_OB.p.array() >= gb.lo.array()).all() && (X_OB.p.array() <= gb.hi.array()).all();
  if (in_box && o.god->inside(X_OB.p)) return true;
  geo::NearTriangle c;
  if (!o.god->closest(shape, X_OB, range, &c)) return false;
  return !(c.closest.core_distance > 0.0) || c.closest.distance < range;
}

double CollisionWorld::clearance(const Shape& body_shape, const Pose& X_WB, double range) const {
  return nearest(false, body_shape, X_WB, range);
}

double CollisionWorld::referenceClearance(const Shape& shape, const Pose& X_WB, double range) const {
  return nearest(true, shape, X_WB, range);
}

double CollisionWorld::nearest(bool reference, const Shape& body_shape, const Pose& X_WB, double range) const {
  double best = kInf;
  const geo::Aabb box = geo::shapeAabb(reference ? body_shape : grown(body_shape, max_skin_), X_WB).inflated(range);
  CostClock clock(*this);
  for (const int object : candidates(box)) {
    const Object& o = objects_[static_cast<size_t>(object)];
    const geo::MeshBvh* mesh = reference ? o.reference : o.god;
    if (!mesh || !(reference ? o.ref_box_W : o.box_W).overlaps(box)) continue;
    std::optional<Charge> charge;  // the God side's cost; the reference is a measurement
    if (!reference) charge.emplace(clock, static_cast<size_t>(object));
    const Shape shape = reference ? body_shape : grown(body_shape, o.skin);
    const Pose X_OB = o.X_WO.inverse() * X_WB;
    const geo::Aabb& gb = mesh->bounds();
    const bool in_box = (X_OB.p.array() >= gb.lo.array()).all() && (X_OB.p.array() <= gb.hi.array()).all();
    geo::NearTriangle c;
    if (in_box && mesh->inside(X_OB.p)) {
      mesh->closest(shape, X_OB, kInf, &c);
      best = std::min(best, -(c.closest.core_distance + geo::coreRadius(shape)));
    } else if (mesh->closest(shape, X_OB, range, &c)) {
      best = std::min(best, c.closest.distance);
    }
  }
  return best;
}

}  // namespace godhand
