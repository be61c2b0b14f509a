#include "geometry/distance.h"

#include <algorithm>
#include <cmath>

namespace godhand::geo {
namespace {

// A segment whose squared length is below this is treated as a point (1e-30 m: far below
// round-off of any hand-scale coordinate, only there to avoid 0/0).
constexpr double kTinySquared = 1e-60;
// A triangle is degenerate (measured as its three edges) when |(b−a)×(c−a)| ≤ kDegenerate·L²
// (L its longest edge): its width is then below 1e-7 L, so the edges are within that of the true
// distance, while for wider triangles the face normal is accurate to ~1e-9 rad.
constexpr double kDegenerate = 1e-7;
// Core distances at or below this use the (flipped) face normal instead of the direction
// between the closest points, which round-off would make meaningless.
constexpr double kNormalTiny = 1e-12;

inline double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

bool nonDegenerate(const Vec3& n, const Vec3& a, const Vec3& b, const Vec3& c) {
  const double l2 = std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
  return n.squaredNorm() > kDegenerate * kDegenerate * l2 * l2;
}

/// Squared distance from p to segment ab, closest point in *q.
double pointSegmentSq(const Vec3& p, const Vec3& a, const Vec3& b, Vec3* q) {
  const Vec3 d = b - a;
  const double dd = d.squaredNorm();
  const double t = dd > kTinySquared ? clamp01((p - a).dot(d) / dd) : 0.0;
  *q = a + t * d;
  return (p - *q).squaredNorm();
}

/// Closest points of segments p0p1, q0q1 (Ericson, Real-Time Collision Detection §5.1.9), with
/// the unclamped parameter written as (d1×d2)·(d2×r)/|d1×d2|², which stays accurate for nearly
/// parallel segments (b f − c e and a e − b² cancel catastrophically there).
double segmentSegmentSq(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, Vec3* cp, Vec3* cq) {
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= kTinySquared && e <= kTinySquared) {
    // two points
  } else if (a <= kTinySquared) {
    t = clamp01(f / e);
  } else {
    const double c = d1.dot(r);
    if (e <= kTinySquared) {
      s = clamp01(-c / a);
    } else {
      const double b = d1.dot(d2);
      const Vec3 n = d1.cross(d2);
      const double denom = n.squaredNorm();
      s = denom > 0.0 ? clamp01(n.dot(d2.cross(r)) / denom) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = clamp01(-c / a);
      } else if (t > 1.0) {
        t = 1.0;
        s = clamp01((b - c) / a);
      }
    }
  }
  *cp = p0 + s * d1;
  *cq = q0 + t * d2;
  return (*cp - *cq).squaredNorm();
}

/// x lies in the prism over triangle abc (normal n = (b−a)×(c−a), non-degenerate).
inline bool inPrism(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n) {
  return (b - a).cross(x - a).dot(n) >= 0.0 && (c - b).cross(x - b).dot(n) >= 0.0 &&
         (a - c).cross(x - c).dot(n) >= 0.0;
}

/// What every point query against triangle abc needs of it, computed once per triangle (a box
/// measures its 8 corners against it, a segment its 2 ends).
struct TriangleFrame {
  Vec3 ab, bc, ca;  ///< edges b − a, c − b, a − c
  Vec3 n;           ///< (b − a) × (c − a)
  bool proper;      ///< nonDegenerate
  TriangleFrame(const Vec3& a, const Vec3& b, const Vec3& c)
      : ab(b - a), bc(c - b), ca(a - c), n(ab.cross(c - a)), proper(nonDegenerate(n, a, b, c)) {}
};

/// Squared point–triangle distance. Face region if the projection falls inside the triangle,
/// otherwise the nearest of the edges whose half-plane test failed (the closest boundary point
/// always lies on such an edge); degenerate triangles: nearest of all three edges.
double pointTriangleSq(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const TriangleFrame& f, Vec3* q) {
  const Vec3 &ab = f.ab, &bc = f.bc, &ca = f.ca, &n = f.n;
  Vec3 tmp;
  if (f.proper) {
    const bool in_ab = ab.cross(p - a).dot(n) >= 0.0;
    const bool in_bc = bc.cross(p - b).dot(n) >= 0.0;
    const bool in_ca = ca.cross(p - c).dot(n) >= 0.0;
    if (in_ab && in_bc && in_ca) {
      const double nn = n.squaredNorm();
      const double k = n.dot(p - a) / nn;
      *q = p - k * n;
      return k * k * nn;
    }
    double best = std::numeric_limits<double>::infinity();
    if (!in_ab) { best = pointSegmentSq(p, a, b, q); }
    if (!in_bc) { const double d = pointSegmentSq(p, b, c, &tmp); if (d < best) { best = d; *q = tmp; } }
    if (!in_ca) { const double d = pointSegmentSq(p, c, a, &tmp); if (d < best) { best = d; *q = tmp; } }
    return best;
  }
  double best = pointSegmentSq(p, a, b, q);
  double d = pointSegmentSq(p, b, c, &tmp);
  if (d < best) { best = d; *q = tmp; }
  d = pointSegmentSq(p, c, a, &tmp);
  if (d < best) { best = d; *q = tmp; }
  return best;
}

double pointTriangleSq(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* q) {
  return pointTriangleSq(p, a, b, c, TriangleFrame(a, b, c), q);
}

/// Segment p0p1 – triangle: 0 if the segment crosses the triangle, else the nearest of
/// endpoints-vs-triangle and segment-vs-edges (a complete feature enumeration for two convex sets
/// that do not intersect).
double segmentTriangleSq(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* core,
                         Vec3* tri) {
  const TriangleFrame frame(a, b, c);
  const Vec3& n = frame.n;
  if (frame.proper) {
    const double s0 = n.dot(p0 - a), s1 = n.dot(p1 - a);
    if (((s0 <= 0.0 && s1 >= 0.0) || (s0 >= 0.0 && s1 <= 0.0)) && s0 != s1) {
      const Vec3 x = p0 + (s0 / (s0 - s1)) * (p1 - p0);
      if (inPrism(x, a, b, c, n)) {
        *core = x;
        *tri = x;
        return 0.0;
      }
    }
  }
  Vec3 qc, qt;
  double best = pointTriangleSq(p0, a, b, c, frame, tri);
  *core = p0;
  double d = pointTriangleSq(p1, a, b, c, frame, &qt);
  if (d < best) { best = d; *core = p1; *tri = qt; }
  const Vec3* v[3] = {&a, &b, &c};
  for (int i = 0; i < 3; ++i) {
    d = segmentSegmentSq(p0, p1, *v[i], *v[(i + 1) % 3], &qc, &qt);
    if (d < best) { best = d; *core = qc; *tri = qt; }
  }
  return best;
}

/// Separating-axis test of the solid box [−e, e] against triangle v0v1v2 (Akenine-Möller 2001):
/// 3 box normals, the triangle normal, 9 edge cross products. Touching counts as overlapping.
bool boxTriangleOverlap(const Vec3& e, const Vec3& v0, const Vec3& v1, const Vec3& v2) {
  for (int i = 0; i < 3; ++i) {
    if (std::min({v0[i], v1[i], v2[i]}) > e[i] || std::max({v0[i], v1[i], v2[i]}) < -e[i]) return false;
  }
  const Vec3 f[3] = {v1 - v0, v2 - v1, v0 - v2};
  const Vec3 n = f[0].cross(v2 - v0);
  // The face axis only for a proper triangle: a degenerate one's normal is round-off noise (its
  // separating axes are then the box normals and the edge cross products alone).
  if (nonDegenerate(n, v0, v1, v2) && std::abs(n.dot(v0)) > e.dot(n.cwiseAbs())) return false;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const Vec3 axis = Vec3::Unit(i).cross(f[j]);
      const double p0 = axis.dot(v0), p1 = axis.dot(v1), p2 = axis.dot(v2);
      const double r = e.dot(axis.cwiseAbs());
      if (std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r) return false;
    }
  }
  return true;
}

/// A point of box [−e, e] ∩ triangle abc when they overlap: the vertex average of the triangle
/// clipped by the six slabs (Sutherland–Hodgman; at most 9 vertices). Falls back to the triangle
/// point nearest the box centre, clamped into the box, if round-off empties the polygon.
Vec3 boxTriangleCommonPoint(const Vec3& e, const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec3 buf[2][12];
  int n = 3;
  buf[0][0] = a;
  buf[0][1] = b;
  buf[0][2] = c;
  int cur = 0;
  for (int plane = 0; plane < 6 && n > 0; ++plane) {
    const int axis = plane / 2;
    const double sign = (plane % 2) ? -1.0 : 1.0;  // keep sign·x[axis] ≤ e[axis]
    const Vec3* in = buf[cur];
    Vec3* out = buf[1 - cur];
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const Vec3& p = in[i];
      const Vec3& q = in[(i + 1) % n];
      const double dp = sign * p[axis] - e[axis], dq = sign * q[axis] - e[axis];
      if (dp <= 0.0) out[m++] = p;
      if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0)) {
        Vec3 x = p + (dp / (dp - dq)) * (q - p);
        x[axis] = sign * e[axis];
        out[m++] = x;
      }
    }
    n = std::min(m, 11);
    cur = 1 - cur;
  }
  if (n > 0) {
    Vec3 sum = Vec3::Zero();
    for (int i = 0; i < n; ++i) sum += buf[cur][i];
    return sum / n;
  }
  Vec3 q;
  pointTriangleSq(Vec3::Zero(), a, b, c, &q);
  return q.cwiseMax(-e).cwiseMin(e);
}

/// Solid box [−e, e] – triangle: 0 if they overlap (SAT), else the nearest of box vertices vs
/// triangle, triangle vertices vs box, and the 12 box edges vs the 3 triangle edges.
double boxTriangleSq(const Vec3& e, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* core, Vec3* tri) {
  if (boxTriangleOverlap(e, a, b, c)) {
    *core = *tri = boxTriangleCommonPoint(e, a, b, c);
    return 0.0;
  }
  double best = std::numeric_limits<double>::infinity();
  Vec3 qc, qt;
  // A feature pair is skipped where a lower bound of its distance already exceeds the best found
  // (by a relative and an absolute round-off margin): every point of the triangle lies in its box
  // [lo, hi], so the squared distance of a box vertex or edge to that box bounds the pair's from
  // below. A skipped pair could not have replaced `best` (the test is strict), so the result is
  // the same as without the skip, bit for bit; on a small triangle near one face of a palm it
  // skips most of the 8 vertex and 36 edge pairs.
  const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
  auto gap = [&](int i, double x0, double x1) {  // distance of [x0, x1] to [lo_i, hi_i]
    return std::max({0.0, lo[i] - x1, x0 - hi[i]});
  };
  // The pairs are met in a fixed order and the first of the least distance is kept, so a pair can
  // also be skipped where its bound exceeds any distance of a later pair: it is then not the
  // least. The triangle vertices' distances to the box (cheap, measured again below in their
  // turn, by the same expressions) give one before the box vertices are measured, which the
  // first box vertex, however far, would otherwise set.
  double later = std::numeric_limits<double>::infinity();
  for (const Vec3* p : {&a, &b, &c}) later = std::min(later, (p->cwiseMax(-e).cwiseMin(e) - *p).squaredNorm());
  auto skip = [&](double lower_sq) { return lower_sq > std::min(best, later) * (1.0 + 1e-6) + 1e-16; };
  // Box vertices vs triangle.
  const TriangleFrame frame(a, b, c);
  for (int k = 0; k < 8; ++k) {
    const Vec3 v((k & 1) ? e.x() : -e.x(), (k & 2) ? e.y() : -e.y(), (k & 4) ? e.z() : -e.z());
    const double gx = gap(0, v.x(), v.x()), gy = gap(1, v.y(), v.y()), gz = gap(2, v.z(), v.z());
    if (skip(gx * gx + gy * gy + gz * gz)) continue;
    const double d = pointTriangleSq(v, a, b, c, frame, &qt);
    if (d < best) { best = d; *core = v; *tri = qt; }
  }
  // Triangle vertices vs box.
  const Vec3* v[3] = {&a, &b, &c};
  for (int i = 0; i < 3; ++i) {
    qc = v[i]->cwiseMax(-e).cwiseMin(e);
    const double d = (qc - *v[i]).squaredNorm();
    if (d < best) { best = d; *core = qc; *tri = *v[i]; }
  }
  // Box edges vs triangle edges.
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
    for (int k = 0; k < 4; ++k) {
      Vec3 e0;
      e0[axis] = -e[axis];
      e0[u] = (k & 1) ? e[u] : -e[u];
      e0[w] = (k & 2) ? e[w] : -e[w];
      Vec3 e1 = e0;
      e1[axis] = e[axis];
      const double ga = gap(axis, -e[axis], e[axis]), gu = gap(u, e0[u], e0[u]), gw = gap(w, e0[w], e0[w]);
      if (skip(ga * ga + gu * gu + gw * gw)) continue;
      for (int i = 0; i < 3; ++i) {
        const double d = segmentSegmentSq(e0, e1, *v[i], *v[(i + 1) % 3], &qc, &qt);
        if (d < best) { best = d; *core = qc; *tri = qt; }
      }
    }
  }
  return best;
}

}  // namespace

double coreRadius(const Shape& shape) {
  return shape.type == ShapeType::Box ? 0.0 : shape.radius;
}

double boundingRadius(const Shape& shape) {
  switch (shape.type) {
    case ShapeType::Sphere: return shape.radius;
    case ShapeType::Capsule: return shape.half_length + shape.radius;
    case ShapeType::Box: return shape.half_extents.norm();
  }
  return 0.0;
}

double coreBoundingRadius(const Shape& shape) {
  switch (shape.type) {
    case ShapeType::Sphere: return 0.0;
    case ShapeType::Capsule: return shape.half_length;
    case ShapeType::Box: return shape.half_extents.norm();
  }
  return 0.0;
}

Aabb shapeAabb(const Shape& shape, const Pose& X_MB) {
  Aabb box;
  switch (shape.type) {
    case ShapeType::Sphere:
      box.lo = X_MB.p;
      box.hi = X_MB.p;
      return box.inflated(shape.radius);
    case ShapeType::Capsule: {
      const Vec3 axis_M = X_MB.q * Vec3(0.0, 0.0, shape.half_length);
      box.lo = X_MB.p - axis_M.cwiseAbs();
      box.hi = X_MB.p + axis_M.cwiseAbs();
      return box.inflated(shape.radius);
    }
    case ShapeType::Box: {
      const Vec3 e_M = X_MB.q.toRotationMatrix().cwiseAbs() * shape.half_extents;
      box.lo = X_MB.p - e_M;
      box.hi = X_MB.p + e_M;
      return box;
    }
  }
  return box;
}

double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* closest) {
  // Relative to a, so that coordinates far from the origin keep their precision.
  Vec3 q;
  const double d2 = pointTriangleSq(p - a, Vec3::Zero(), b - a, c - a, &q);
  if (closest) *closest = q + a;
  return std::sqrt(d2);
}

double segmentSegmentDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, Vec3* on_p, Vec3* on_q) {
  Vec3 cp, cq;
  const double d2 = segmentSegmentSq(Vec3::Zero(), p1 - p0, q0 - p0, q1 - p0, &cp, &cq);
  if (on_p) *on_p = cp + p0;
  if (on_q) *on_q = cq + p0;
  return std::sqrt(d2);
}

namespace detail {

double coreTriangle(const Shape& shape, const Vec3& a_B, const Vec3& b_B, const Vec3& c_B, Vec3* core_B,
                    Vec3* tri_B) {
  switch (shape.type) {
    case ShapeType::Sphere:
      core_B->setZero();
      return std::sqrt(pointTriangleSq(Vec3::Zero(), a_B, b_B, c_B, tri_B));
    case ShapeType::Capsule: {
      const Vec3 h(0.0, 0.0, shape.half_length);
      return std::sqrt(segmentTriangleSq(-h, h, a_B, b_B, c_B, core_B, tri_B));
    }
    case ShapeType::Box:
      return std::sqrt(boxTriangleSq(shape.half_extents, a_B, b_B, c_B, core_B, tri_B));
  }
  core_B->setZero();
  tri_B->setZero();
  return 0.0;
}

ClosestPoints finishClosestPoints(const Shape& shape, const Pose& X_MB, const Mat3& R_MB, double core_distance,
                                  const Vec3& core_B, const Vec3& tri_B, const Vec3& a_B, const Vec3& b_B,
                                  const Vec3& c_B) {
  const double r = coreRadius(shape);
  Vec3 n_B;
  if (core_distance > kNormalTiny) {
    n_B = (core_B - tri_B) / core_distance;
  } else {
    // Touching or crossing: the face normal, on the side of the core centre (the body origin).
    const Vec3 fn = (b_B - a_B).cross(c_B - a_B);
    if (nonDegenerate(fn, a_B, b_B, c_B)) {
      n_B = fn.normalized();
      if (n_B.dot(-a_B) < 0.0) n_B = -n_B;
    } else if (tri_B.squaredNorm() > kTinySquared) {
      n_B = -tri_B.normalized();  // degenerate triangle: from it towards the core centre
    } else {
      n_B = Vec3::UnitZ();
    }
  }
  ClosestPoints out;
  out.core_distance = core_distance;
  out.distance = core_distance - r;
  out.n = R_MB * n_B;
  out.p_triangle = X_MB.p + R_MB * tri_B;
  out.p_shape = X_MB.p + R_MB * (core_B - r * n_B);
  return out;
}

}  // namespace detail

ClosestPoints shapeTriangle(const Shape& shape, const Pose& X_MB, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Mat3 R_MB = X_MB.q.toRotationMatrix();
  const Mat3 R_BM = R_MB.transpose();
  const Vec3 a_B = R_BM * (a - X_MB.p), b_B = R_BM * (b - X_MB.p), c_B = R_BM * (c - X_MB.p);
  Vec3 core_B, tri_B;
  const double d = detail::coreTriangle(shape, a_B, b_B, c_B, &core_B, &tri_B);
  return detail::finishClosestPoints(shape, X_MB, R_MB, d, core_B, tri_B, a_B, b_B, c_B);
}

}  // namespace godhand::geo
