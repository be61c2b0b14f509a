#include "geometry/bvh.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace godhand::geo {
namespace {

constexpr int kLeafSize = 4;       ///< leaves hold at most this many triangles
constexpr int kBins = 16;          ///< binned SAH
constexpr int kMaxSahDepth = 48;   ///< below this depth: object-median splits (depth ≤ 48 + log2 n)
constexpr int kStackSize = 256;    ///< traversal stack (≥ 2 × the maximum depth)
constexpr double kWindingBeta = 2.0;  ///< Barill et al. 2018 accuracy parameter
constexpr double kPi = 3.14159265358979323846;
constexpr double kTieSlack = 1e-12;  ///< closest(): pruning slack per metre of coordinates (round-off)
constexpr double kMinShrink = 1e-9;  ///< m: least margin of a triangle in advancementStep
/// advancementStep refines a node's first-order bound (second-order and body-axis, as for a
/// triangle) only where the turn is more than this share of its approach rate: the refinements
/// remove (part of) the turn's term, and where it is small they cost more than they prune.
constexpr double kTurnShare = 0.25;

/// A triangle's centroid, as the bounds take it.
Vec3 centroid(const std::array<Vec3, 3>& v) { return (v[0] + v[1] + v[2]) / 3.0; }

double surfaceArea(const Aabb& b) {
  if (b.empty()) return 0.0;
  const Vec3 e = b.extent();
  return 2.0 * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
}

/// What the turning bounds below need of one advancement step's motion (Δp, θ per unit time) and
/// core, computed once per step: every term is the one the bounds computed per triangle and per
/// node before, evaluated the same way, so the bounds are the same to the bit.
struct StepMotion {
  Vec3 dp = Vec3::Zero(), theta = Vec3::Zero();
  Vec3 axes[3];           ///< the core's axes in M (capsule: its axis; box: three; sphere: none)
  Vec3 theta_x_axes[3];   ///< θ × a_j
  double halves[3] = {0.0, 0.0, 0.0};  ///< e_j
  int n_axes = 0;
  double esum = 0.0;         ///< Σ_j e_j
  double half_theta = 0.0;   ///< ½ |θ|
  double theta_norm = 0.0;   ///< |θ|
  double two_dp_norm = 0.0;  ///< 2 |Δp|
  bool turning = false;      ///< |θ|² > 0

  StepMotion(const Vec3& dp_M, const Vec3& theta_M, const Vec3* core_axes, const double* core_halves, int n)
      : dp(dp_M), theta(theta_M), n_axes(n) {
    for (int j = 0; j < n; ++j) {
      axes[j] = core_axes[j];
      halves[j] = core_halves[j];
      theta_x_axes[j] = theta.cross(axes[j]);
      esum += halves[j];
    }
    theta_norm = theta.norm();
    half_theta = 0.5 * theta_norm;
    two_dp_norm = 2.0 * dp.norm();
    turning = theta.squaredNorm() > 0.0;
  }
};

/// What the first-order rate and the turning bounds share of one direction w: w·Δp and |w × θ|.
struct Direction {
  double w_dp = 0.0, w_x_theta = 0.0;
  Direction(const Vec3& w, const StepMotion& m) : w_dp(w.dot(m.dp)), w_x_theta(w.cross(m.theta).norm()) {}
};

/// Second-order directional bound (sweep.h): the earliest τ ∈ (0, horizon] at which the separation
/// along the fixed unit direction w between the moving core and a fixed convex set can have
/// shrunk by `margin` (> 0); +inf if it cannot within the horizon. The core's support along w is
///   h(τ) = w·p(τ) + Σ_j e_j |w·a_j(τ)|   (capsule: its axis, e = half length; box: three axes),
/// with p(τ) = p + τ Δp and a_j(τ) = exp(τθ) a_j. Taylor with a bounded remainder gives
///   h(τ) − h(0) ≤ τ w·Δp + Σ_j e_j (|c_j + τ ω_j| − |c_j|) + ½ τ² |θ| |w × θ| Σ_j e_j,
///   c_j = w·a_j,  ω_j = w·(θ × a_j)   (|d²/dτ² w·a_j| = |(θ × a_j)·(w × θ)| ≤ |θ| |w × θ|),
/// which is convex in τ: the first crossing is found piece by piece between the kinks −c_j/ω_j.
/// Unlike the first-order rate w·Δp + ρ_c |w × θ| (always > 0 under any tangential rotation),
/// it sees an end of the core that turns away from the set as receding.
/// *support gets the core's support along w, Σ_j e_j |c_j| (bodyAxisTime's). N: the core's axis
/// count (motion.n_axes), a template parameter so that the loops over the axes are unrolled.
template <int N>
double secondOrderTime(double margin, const Vec3& w, const Direction& dir, const StepMotion& motion, double horizon,
                       double* support) {
  const double inf = std::numeric_limits<double>::infinity();
  constexpr int n = N;
  const double* half = motion.halves;
  double c[3], om[3], kinks[5];
  double h = 0.0;
  int nk = 0;
  kinks[nk++] = 0.0;
  for (int j = 0; j < n; ++j) {
    c[j] = w.dot(motion.axes[j]);
    om[j] = w.dot(motion.theta_x_axes[j]);
    h += half[j] * std::abs(c[j]);
    if (om[j] != 0.0) {
      const double k = -c[j] / om[j];
      if (k > 0.0 && k < horizon) kinks[nk++] = k;
    }
  }
  kinks[nk++] = horizon;
  for (int i = 2; i + 1 < nk; ++i)  // insertion sort of the (at most three) interior kinks
    for (int k = i; k > 1 && kinks[k] < kinks[k - 1]; --k) std::swap(kinks[k], kinks[k - 1]);
  *support = h;
  const double A = motion.half_theta * dir.w_x_theta * motion.esum;
  const double lin = dir.w_dp;
  for (int piece = 0; piece + 1 < nk; ++piece) {
    const double lo = kinks[piece], hi = kinks[piece + 1];
    if (!(hi > lo)) continue;
    const double mid = 0.5 * (lo + hi);
    double B = lin, C = -margin;
    for (int j = 0; j < n; ++j) {
      const double s = c[j] + mid * om[j] >= 0.0 ? 1.0 : -1.0;
      B += half[j] * s * om[j];
      C += half[j] * (s * c[j] - std::abs(c[j]));
    }
    const auto g = [&](double t) { return (A * t + B) * t + C; };
    if (g(hi) < 0.0) continue;  // still short of the margin at the end of this piece
    // g(lo) < 0 ≤ g(hi), g convex: the larger root of A t² + B t + C (or the linear one).
    double t;
    if (A > 0.0) {
      const double disc = std::max(0.0, B * B - 4.0 * A * C);
      const double q = std::sqrt(disc);
      t = B >= 0.0 ? (-2.0 * C) / (B + q) : (q - B) / (2.0 * A);
    } else {
      t = B > 0.0 ? -C / B : hi;
    }
    if (!std::isfinite(t)) t = lo;
    // Round-off: never later than the true crossing by more than a relative 1e-12.
    return std::clamp(t * (1.0 - 1e-12), lo, hi);
  }
  return inf;
}

/// A lower bound of the time before a triangle (corners v, frame M) comes within `reach` (core
/// radius + η) of a body's core, along the separating axis fixed in the BODY (w at t = 0, then
/// turning with the body): the triangle, seen from the body, moves by the inverse motion, and a
/// triangle under the body's centre hardly moves when the body turns, however large the body.
/// (The axis fixed in the mesh frame, secondOrderTime, counts every turn of a large box about a
/// tangential axis as an approach of its far corners, which is what made a palm resting on a
/// curved surface creep along in tiny steps.)
///   s(t) = min_i a(t)·(v_i − p(t)) − h(u) ≤ distance(core, triangle), a(t) = R(t) u, h: the core's
///   support along u (constant in the body). −ds_i/dt = a·dp + θ·(r_i × a), r_i = v_i − p(t):
///   at t = 0 it is B_i = w·dp + θ·(r_i0 × w); |a(t) − w| ≤ t|θ| and |r_i(t) − r_i0| ≤ t|dp| bound
///   its change by t|θ|(2|dp| + |θ||r_i0|) = A_i t. So s_i falls by at most B_i t + A_i t²/2.
/// `floor`: the least margin (as visitTriangle's).
double bodyAxisTime(const Vec3* v, int n, const Vec3& p0, const Vec3& w, const Direction& dir, double support,
                    double reach, const StepMotion& motion, double floor) {
  const Vec3& theta = motion.theta;
  const double th = motion.theta_norm;
  double t_min = std::numeric_limits<double>::infinity();
  for (int k = 0; k < n; ++k) {
    const Vec3& vi = v[k];
    const Vec3 r = vi - p0;
    const double m = std::max(w.dot(r) - support - reach, floor);
    const double B = dir.w_dp + theta.dot(r.cross(w));
    const double A = th * (motion.two_dp_norm + th * r.norm());
    double t;
    if (A > 0.0) {
      const double q = std::sqrt(B * B + 2.0 * A * m);
      t = B >= 0.0 ? 2.0 * m / (B + q) : (q - B) / A;
    } else {
      t = B > 0.0 ? m / B : std::numeric_limits<double>::infinity();
    }
    t_min = std::min(t_min, t);
  }
  return t_min * (1.0 - 1e-12);  // round-off: never later than the bound
}

/// The shape's core in frame M, with what the box lower bounds need. The shape type is a
/// template parameter so that the traversals below are compiled once per type, with the core's
/// distance inlined into them (no dispatch per node).
template <ShapeType kType>
struct CoreM {
  Vec3 p0 = Vec3::Zero(), p1 = Vec3::Zero();  ///< segment (sphere: p0 = p1 = centre)
  Vec3 d = Vec3::Zero();                      ///< p1 − p0
  double inv_dd = 0.0;                        ///< 1/|d|² (0 for a point segment)
  Mat3 R_MB = Mat3::Identity();
  Vec3 e = Vec3::Zero();                      ///< box half extents
  Aabb box;                                   ///< of the core

  CoreM(const Shape& shape, const Pose& X_MB) : R_MB(X_MB.q.toRotationMatrix()) {
    if constexpr (kType == ShapeType::Sphere) {
      p0 = p1 = X_MB.p;
    } else if constexpr (kType == ShapeType::Capsule) {
      const Vec3 h_M = R_MB.col(2) * shape.half_length;
      p0 = X_MB.p - h_M;
      p1 = X_MB.p + h_M;
      d = p1 - p0;
      inv_dd = d.squaredNorm() > 0.0 ? 1.0 / d.squaredNorm() : 0.0;
    } else {
      p0 = p1 = X_MB.p;
      e = shape.half_extents;
    }
    if constexpr (kType == ShapeType::Box) {
      const Vec3 e_M = R_MB.cwiseAbs() * e;
      box.lo = p0 - e_M;
      box.hi = p0 + e_M;
    } else {
      box.lo = p0.cwiseMin(p1);
      box.hi = p0.cwiseMax(p1);
    }
  }

  /// Distance f(x) from point x to the core, with the unit gradient u of f at x (zero if x is in
  /// the core). f is convex, so f(y) ≥ f(x) + u·(y − x) for every y: the lower bounds below.
  double pointDistance(const Vec3& x, Vec3* u) const {
    Vec3 w;
    if constexpr (kType == ShapeType::Sphere) {
      w = x - p0;
    } else if constexpr (kType == ShapeType::Capsule) {
      const Vec3 v = x - p0;
      const double s = std::clamp(v.dot(d) * inv_dd, 0.0, 1.0);
      w = v - s * d;
    } else {
      const Vec3 x_B = R_MB.transpose() * (x - p0);
      w = R_MB * (x_B - x_B.cwiseMax(-e).cwiseMin(e));
    }
    const double f = w.norm();
    if (f > 0.0) *u = w / f;
    else u->setZero();
    return f;
  }

  /// Distance between the core's box and b (a lower bound of the core distance to b).
  double gapBound(const Aabb& b) const {
    const Vec3 gap = (b.lo - box.hi).cwiseMax(box.lo - b.hi).cwiseMax(0.0);
    return std::sqrt(gap.squaredNorm());
  }

  /// f(c) − Σ|u_i| h_i at the centre c of box b (h its half extents) with the gradient u at c:
  /// the first-order (convexity) bound of the core distance to the box, the separation of the
  /// two along u. Returns f(c); *sep gets the bound (only where f(c) > 0).
  double centreBound(const Aabb& b, Vec3* u, double* sep) const {
    const double f = pointDistance(b.centre(), u);
    *sep = f - u->cwiseAbs().dot(0.5 * b.extent());
    return f;
  }

  /// The box–box gap and the first-order bound at the box centre (centreBound); the second is
  /// skipped when the gap already exceeds `cutoff`.
  double lowerBound(const Aabb& b, double cutoff = std::numeric_limits<double>::infinity()) const {
    const double lb = gapBound(b);
    if (kType == ShapeType::Sphere || lb > cutoff) return lb;  // sphere: exact point–box distance
    Vec3 u;
    double sep;
    centreBound(b, &u, &sep);
    return std::max(lb, sep);
  }

  /// Separation of the core and triangle v along the core distance's gradient u at the centroid
  /// c (centroid(v), stored with the hierarchy): f(c) + min_k u·(v_k − c) (the minimum of a linear
  /// function over the triangle is at a corner), a lower bound of their distance. Returns f(c);
  /// *sep gets the separation.
  double triangleBound(const std::array<Vec3, 3>& v, const Vec3& c, Vec3* u, double* sep) const {
    const double f = pointDistance(c, u);
    *sep = f + std::min({u->dot(v[0] - c), u->dot(v[1] - c), u->dot(v[2] - c)});
    return f;
  }
  double lowerBound(const std::array<Vec3, 3>& v, const Vec3& c) const {
    Vec3 u;
    double sep;
    triangleBound(v, c, &u, &sep);
    return sep;
  }
};

#if defined(__SSE2__)
/// Two doubles, one per child of a BVH node: the bounds of both children evaluated at once
/// (SSE2). Every lane does the arithmetic of CoreM's scalar code in the same order (sums of
/// three terms as (x + y) + z, as Eigen's Vector3d kernels do), so each lane's value is the
/// same to the bit as the scalar bound of that child (the traversals' results do not change).
struct Lanes {
  __m128d v;
};
inline Lanes operator+(Lanes a, Lanes b) { return {_mm_add_pd(a.v, b.v)}; }
inline Lanes operator-(Lanes a, Lanes b) { return {_mm_sub_pd(a.v, b.v)}; }
inline Lanes operator*(Lanes a, Lanes b) { return {_mm_mul_pd(a.v, b.v)}; }
inline Lanes operator/(Lanes a, Lanes b) { return {_mm_div_pd(a.v, b.v)}; }
inline Lanes splat(double x) { return {_mm_set1_pd(x)}; }
inline Lanes pair(double left, double right) { return {_mm_set_pd(right, left)}; }
/// std::max(a, b) per lane (a where they compare equal, as std::max).
inline Lanes lmax(Lanes a, Lanes b) { return {_mm_max_pd(b.v, a.v)}; }
inline Lanes lmin(Lanes a, Lanes b) { return {_mm_min_pd(b.v, a.v)}; }
inline Lanes labs(Lanes a) { return {_mm_andnot_pd(_mm_set1_pd(-0.0), a.v)}; }
inline Lanes lsqrt(Lanes a) { return {_mm_sqrt_pd(a.v)}; }
inline double lane0(Lanes a) { return _mm_cvtsd_f64(a.v); }
inline double lane1(Lanes a) { return _mm_cvtsd_f64(_mm_unpackhi_pd(a.v, a.v)); }
inline double lane0or1(Lanes a, int k) { return k == 0 ? lane0(a) : lane1(a); }

/// A 3-vector per lane.
struct Lanes3 {
  Lanes x, y, z;
};
inline Lanes dot(const Lanes3& a, const Lanes3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Lanes dot(const Lanes3& a, const Vec3& b) { return a.x * splat(b.x()) + a.y * splat(b.y()) + a.z * splat(b.z()); }

/// The two children's boxes (lanes: left, right).
struct BoxPair {
  Lanes3 lo, hi;
  BoxPair(const Aabb& l, const Aabb& r)
      : lo{pair(l.lo.x(), r.lo.x()), pair(l.lo.y(), r.lo.y()), pair(l.lo.z(), r.lo.z())},
        hi{pair(l.hi.x(), r.hi.x()), pair(l.hi.y(), r.hi.y()), pair(l.hi.z(), r.hi.z())} {}
};

/// CoreM::gapBound per lane.
template <class Core>
Lanes gapBound2(const Core& core, const BoxPair& b) {
  const Lanes zero = splat(0.0);
  const Lanes gx = lmax(lmax(b.lo.x - splat(core.box.hi.x()), splat(core.box.lo.x()) - b.hi.x), zero);
  const Lanes gy = lmax(lmax(b.lo.y - splat(core.box.hi.y()), splat(core.box.lo.y()) - b.hi.y), zero);
  const Lanes gz = lmax(lmax(b.lo.z - splat(core.box.hi.z()), splat(core.box.lo.z()) - b.hi.z), zero);
  return lsqrt(gx * gx + gy * gy + gz * gz);
}

/// CoreM::centreBound per lane: f(c) returned, the gradient in *u, f(c) − |u|·h in *sep.
template <ShapeType kType, class Core>
Lanes centreBound2(const Core& core, const BoxPair& b, Lanes3* u, Lanes* sep) {
  const Lanes half = splat(0.5);
  const Lanes3 y{half * (b.lo.x + b.hi.x) - splat(core.p0.x()), half * (b.lo.y + b.hi.y) - splat(core.p0.y()),
                 half * (b.lo.z + b.hi.z) - splat(core.p0.z())};
  Lanes3 w;
  if constexpr (kType == ShapeType::Sphere) {
    w = y;
  } else if constexpr (kType == ShapeType::Capsule) {
    const Lanes s = lmin(lmax(dot(y, core.d) * splat(core.inv_dd), splat(0.0)), splat(1.0));
    w = {y.x - s * splat(core.d.x()), y.y - s * splat(core.d.y()), y.z - s * splat(core.d.z())};
  } else {
    const Mat3& R = core.R_MB;
    Lanes xb[3];
    for (int i = 0; i < 3; ++i) {
      const Lanes v = splat(R(0, i)) * y.x + splat(R(1, i)) * y.y + splat(R(2, i)) * y.z;
      const Lanes e = splat(core.e[i]);
      xb[i] = v - lmin(lmax(v, splat(-core.e[i])), e);
    }
    w = {splat(R(0, 0)) * xb[0] + splat(R(0, 1)) * xb[1] + splat(R(0, 2)) * xb[2],
         splat(R(1, 0)) * xb[0] + splat(R(1, 1)) * xb[1] + splat(R(1, 2)) * xb[2],
         splat(R(2, 0)) * xb[0] + splat(R(2, 1)) * xb[1] + splat(R(2, 2)) * xb[2]};
  }
  const Lanes f = lsqrt(dot(w, w));
  // u = w / f where f > 0, else 0 (the division's lanes with f = 0 are masked off).
  const __m128d positive = _mm_cmpgt_pd(f.v, _mm_setzero_pd());
  const Lanes safe = {_mm_or_pd(_mm_and_pd(positive, f.v), _mm_andnot_pd(positive, _mm_set1_pd(1.0)))};
  u->x = {_mm_and_pd(positive, (w.x / safe).v)};
  u->y = {_mm_and_pd(positive, (w.y / safe).v)};
  u->z = {_mm_and_pd(positive, (w.z / safe).v)};
  *sep = f - (labs(u->x) * (half * (b.hi.x - b.lo.x)) + labs(u->y) * (half * (b.hi.y - b.lo.y)) +
              labs(u->z) * (half * (b.hi.z - b.lo.z)));
  return f;
}
#endif

/// Solid angle of triangle abc seen from the origin (Van Oosterom & Strackee 1983), positive
/// when the origin is behind the counter-clockwise face.
double solidAngle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double num = a.dot(b.cross(c));
  const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
  return 2.0 * std::atan2(num, den);
}

/// Per-triangle quantities the build needs, computed once.
struct BuildData {
  std::vector<Aabb> boxes;
  std::vector<Vec3> centroids;
  std::vector<Vec3> area_vectors;  ///< ½ (b − a) × (c − a)
  std::vector<double> areas;
};

}  // namespace

struct MeshBvh::Impl {
  /// Builds the subtree over order_[begin, end); returns its node index.
  static int build(MeshBvh& bvh, int begin, int end, int depth, const BuildData& data) {
    const std::vector<Vec3>& centroids = data.centroids;
    const std::vector<Aabb>& boxes = data.boxes;
    const int index = static_cast<int>(bvh.nodes_.size());
    bvh.nodes_.emplace_back();
    Aabb box, cbox;
    for (int i = begin; i < end; ++i) {
      const int t = bvh.order_[static_cast<size_t>(i)];
      box.grow(boxes[static_cast<size_t>(t)]);
      cbox.grow(centroids[static_cast<size_t>(t)]);
    }
    fillDipole(bvh, index, begin, end, data);
    bvh.nodes_[static_cast<size_t>(index)].box = box;
    const int n = end - begin;
    if (n <= kLeafSize) {
      bvh.nodes_[static_cast<size_t>(index)].first = begin;
      bvh.nodes_[static_cast<size_t>(index)].count = n;
      return index;
    }
    int* first = bvh.order_.data() + begin;
    int* last = bvh.order_.data() + end;
    int mid = -1;
    if (depth < kMaxSahDepth) mid = sahSplit(first, last, cbox, centroids, boxes);
    if (mid <= 0 || mid >= n) {
      int axis = 0;
      cbox.extent().maxCoeff(&axis);
      mid = n / 2;
      std::nth_element(first, first + mid, last, [&](int x, int y) {
        return centroids[static_cast<size_t>(x)][axis] < centroids[static_cast<size_t>(y)][axis];
      });
    }
    const int left = build(bvh, begin, begin + mid, depth + 1, data);
    const int right = build(bvh, begin + mid, end, depth + 1, data);
    Node& node = bvh.nodes_[static_cast<size_t>(index)];
    node.first = left;
    node.right = right;
    node.count = 0;
    return index;
  }

  /// Binned SAH over the three axes; partitions [first, last) and returns the left count, or −1.
  static int sahSplit(int* first, int* last, const Aabb& cbox, const std::vector<Vec3>& centroids,
                      const std::vector<Aabb>& boxes) {
    double best_cost = std::numeric_limits<double>::infinity();
    int best_axis = -1, best_split = -1;
    const Vec3 ext = cbox.extent();
    for (int axis = 0; axis < 3; ++axis) {
      if (!(ext[axis] > 0.0)) continue;
      const double scale = kBins / ext[axis];
      Aabb bin_box[kBins];
      int bin_count[kBins] = {};
      for (int* it = first; it != last; ++it) {
        const auto t = static_cast<size_t>(*it);
        const int b = std::min(kBins - 1, static_cast<int>((centroids[t][axis] - cbox.lo[axis]) * scale));
        bin_box[b].grow(boxes[t]);
        ++bin_count[b];
      }
      double right_area[kBins];
      int right_count[kBins];
      Aabb acc;
      int cnt = 0;
      for (int b = kBins - 1; b > 0; --b) {
        acc.grow(bin_box[b]);
        cnt += bin_count[b];
        right_area[b] = surfaceArea(acc);
        right_count[b] = cnt;
      }
      acc = Aabb{};
      cnt = 0;
      for (int b = 0; b < kBins - 1; ++b) {
        acc.grow(bin_box[b]);
        cnt += bin_count[b];
        if (cnt == 0 || right_count[b + 1] == 0) continue;
        const double cost = surfaceArea(acc) * cnt + right_area[b + 1] * right_count[b + 1];
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_split = b + 1;
        }
      }
    }
    if (best_axis < 0) return -1;
    const double scale = kBins / ext[best_axis];
    int* mid = std::partition(first, last, [&](int t) {
      const int b = std::min(kBins - 1,
                             static_cast<int>((centroids[static_cast<size_t>(t)][best_axis] - cbox.lo[best_axis]) * scale));
      return b < best_split;
    });
    return static_cast<int>(mid - first);
  }

  /// Area-weighted centroid, summed area vector, second moment and radius of the node's triangles.
  static void fillDipole(MeshBvh& bvh, int index, int begin, int end, const BuildData& data) {
    Vec3 normal = Vec3::Zero(), weighted = Vec3::Zero(), plain = Vec3::Zero();
    double area = 0.0;
    for (int i = begin; i < end; ++i) {
      const auto t = static_cast<size_t>(bvh.order_[static_cast<size_t>(i)]);
      normal += data.area_vectors[t];
      weighted += data.areas[t] * data.centroids[t];
      plain += data.centroids[t];
      area += data.areas[t];
    }
    const Vec3 centre = area > 0.0 ? Vec3(weighted / area) : Vec3(plain / (end - begin));
    double radius2 = 0.0;
    Mat3 moment = Mat3::Zero();
    for (int i = begin; i < end; ++i) {
      const int t = bvh.order_[static_cast<size_t>(i)];
      const Aabb& b = data.boxes[static_cast<size_t>(t)];
      // Farthest corner of the triangle's box: cheap, conservative radius (only used by the
      // far-field test, where a larger radius just means more exact evaluation).
      radius2 = std::max(radius2, (b.lo - centre).cwiseAbs().cwiseMax((b.hi - centre).cwiseAbs()).squaredNorm());
      moment += (data.centroids[static_cast<size_t>(t)] - centre) * data.area_vectors[static_cast<size_t>(t)].transpose();
    }
    if (bvh.dipole_moment_.size() <= static_cast<size_t>(index)) bvh.dipole_moment_.resize(static_cast<size_t>(index) + 1);
    if (bvh.dipoles_.size() <= static_cast<size_t>(index)) bvh.dipoles_.resize(static_cast<size_t>(index) + 1);
    bvh.dipole_moment_[static_cast<size_t>(index)] = moment;
    NodeDipole& dipole = bvh.dipoles_[static_cast<size_t>(index)];
    dipole.centre = centre;
    dipole.normal = normal;
    dipole.radius = std::sqrt(radius2);
  }
  // The queries, compiled once per shape type (CoreM<kType>); see bvh.h for what they return.
  template <ShapeType kType>
  static bool closest(const MeshBvh& bvh, const Shape& shape, const Pose& X_MB, double max_distance,
                      NearTriangle* out, int hint) {
    if (bvh.nodes_.empty() || std::isnan(max_distance)) return false;
    double best = max_distance + coreRadius(shape);  // core-distance threshold, inclusive
    if (best < 0.0) return false;
    const CoreM<kType> core(shape, X_MB);
    const Mat3 R_BM = core.R_MB.transpose();
    // Bounds are pruned only above the best by more than their round-off (a bound of a triangle
    // at the best distance may come out a few ulps of the coordinates above it), so that every
    // triangle at the least distance is visited whatever the order the best was found in: the
    // hint then cannot change the result.
    const double tie = kTieSlack * (1.0 + bvh.max_coordinate_ + X_MB.p.cwiseAbs().maxCoeff());
    int best_index = -1;  // position in order_
    int best_triangle = std::numeric_limits<int>::max();  // its mesh index: ties go to the lowest
    Vec3 best_core_B, best_tri_B;
    std::array<Vec3, 3> best_abc_B;
    // The hint first: its distance prunes from the start what the traversal would prune only once
    // it got there. The traversal still visits every triangle whose bound is within the best (the
    // hint's own leaf included) and keeps, of those at the least distance, the lowest index, which
    // does not depend on the order they are met in: the result is the one without the hint, bit
    // for bit (Bvh.HintLeavesTheClosestUnchanged).
    // Measures one triangle (corners v in M; `index` as best_index) and keeps it if it is nearer
    // than the best, or as near and of a lower index (the first one at the threshold is kept).
    auto measure = [&](const std::array<Vec3, 3>& v, int triangle, int index) {
      const std::array<Vec3, 3> abc_B = {R_BM * (v[0] - X_MB.p), R_BM * (v[1] - X_MB.p), R_BM * (v[2] - X_MB.p)};
      Vec3 core_B, tri_B;
      const double d = detail::coreTriangle(shape, abc_B[0], abc_B[1], abc_B[2], &core_B, &tri_B);
      if (d < best || (d == best && (best_index == -1 || triangle < best_triangle))) {
        best = d;
        best_index = index;
        best_triangle = triangle;
        best_core_B = core_B;
        best_tri_B = tri_B;
        best_abc_B = abc_B;
      }
    };
    // The traversal skips the hint's position: measured again there it would give the same
    // distance, which cannot replace the best (the best is at most that distance, and at a tie it
    // is the hint itself or a lower index).
    int hint_at = -1;
    if (hint >= 0 && hint < bvh.mesh_.triangleCount()) {
      hint_at = bvh.position_[static_cast<size_t>(hint)];
      measure(bvh.tri_vertices_[static_cast<size_t>(hint_at)], hint, hint_at);
    }

    int stack[kStackSize];
    double stack_lb[kStackSize];
    int sp = 0;
    stack[sp] = 0;
    stack_lb[sp++] = core.lowerBound(bvh.nodes_[0].box);
    while (sp > 0) {
      --sp;
      if (stack_lb[sp] > best + tie) continue;
      const Node& node = bvh.nodes_[static_cast<size_t>(stack[sp])];
      if (node.count > 0) {
        for (int i = node.first; i < node.first + node.count; ++i) {
          if (i == hint_at) continue;
          if (core.gapBound(bvh.tri_boxes_[static_cast<size_t>(i)]) > best + tie) continue;
          const auto& v = bvh.tri_vertices_[static_cast<size_t>(i)];
          if (core.lowerBound(v, bvh.tri_centroids_[static_cast<size_t>(i)]) > best + tie) continue;
          measure(v, bvh.order_[static_cast<size_t>(i)], i);
        }
        continue;
      }
#if defined(__SSE2__)
      // Both children at once; each lane as core.lowerBound(box, best).
      double lb_left, lb_right;
      {
        const BoxPair pair_box(bvh.nodes_[static_cast<size_t>(node.first)].box, bvh.nodes_[static_cast<size_t>(node.right)].box);
        const Lanes gap = gapBound2(core, pair_box);
        lb_left = lane0(gap);
        lb_right = lane1(gap);
        if constexpr (kType != ShapeType::Sphere) {
          if (!(lb_left > best + tie) || !(lb_right > best + tie)) {
            Lanes3 u;
            Lanes sep;
            centreBound2<kType>(core, pair_box, &u, &sep);
            const Lanes lb = lmax(gap, sep);
            if (!(lb_left > best + tie)) lb_left = lane0(lb);
            if (!(lb_right > best + tie)) lb_right = lane1(lb);
          }
        }
      }
#else
      const double lb_left = core.lowerBound(bvh.nodes_[static_cast<size_t>(node.first)].box, best + tie);
      const double lb_right = core.lowerBound(bvh.nodes_[static_cast<size_t>(node.right)].box, best + tie);
#endif
      // Nearer child on top of the stack.
      const bool left_first = lb_left <= lb_right;
      const int far_node = left_first ? node.right : node.first, near_node = left_first ? node.first : node.right;
      const double far_lb = left_first ? lb_right : lb_left, near_lb = left_first ? lb_left : lb_right;
      if (far_lb <= best + tie) { stack[sp] = far_node; stack_lb[sp++] = far_lb; }
      if (near_lb <= best + tie) { stack[sp] = near_node; stack_lb[sp++] = near_lb; }
    }
    if (best_index == -1) return false;
    out->triangle = bvh.order_[static_cast<size_t>(best_index)];
    out->closest = detail::finishClosestPoints(shape, X_MB, core.R_MB, best, best_core_B, best_tri_B, best_abc_B[0],
                                               best_abc_B[1], best_abc_B[2]);
    return true;
  }

  template <ShapeType kType>
  static void near(const MeshBvh& bvh, const Shape& shape, const Pose& X_MB, double max_distance,
                   std::vector<NearTriangle>* out) {
    if (bvh.nodes_.empty() || std::isnan(max_distance)) return;
    const double limit = max_distance + coreRadius(shape);
    if (limit < 0.0) return;
    const CoreM<kType> core(shape, X_MB);
    const Mat3 R_BM = core.R_MB.transpose();
    // Depth first, left child first (the answer in order_'s order); a node is pushed only where
    // its bound is within the limit, both children's bounds taken at once.
    int stack[kStackSize];
    int sp = 0;
    if (!(core.lowerBound(bvh.nodes_[0].box, limit) > limit)) stack[sp++] = 0;
    while (sp > 0) {
      const Node& node = bvh.nodes_[static_cast<size_t>(stack[--sp])];
      if (node.count > 0) {
        for (int i = node.first; i < node.first + node.count; ++i) {
          if (core.gapBound(bvh.tri_boxes_[static_cast<size_t>(i)]) > limit) continue;
          const auto& v = bvh.tri_vertices_[static_cast<size_t>(i)];
          if (core.lowerBound(v, bvh.tri_centroids_[static_cast<size_t>(i)]) > limit) continue;
          const Vec3 a_B = R_BM * (v[0] - X_MB.p), b_B = R_BM * (v[1] - X_MB.p), c_B = R_BM * (v[2] - X_MB.p);
          Vec3 core_B, tri_B;
          const double d = detail::coreTriangle(shape, a_B, b_B, c_B, &core_B, &tri_B);
          if (d <= limit) {
            NearTriangle nt;
            nt.triangle = bvh.order_[static_cast<size_t>(i)];
            nt.closest = detail::finishClosestPoints(shape, X_MB, core.R_MB, d, core_B, tri_B, a_B, b_B, c_B);
            out->push_back(nt);
          }
        }
        continue;
      }
      const Aabb& left = bvh.nodes_[static_cast<size_t>(node.first)].box;
      const Aabb& right = bvh.nodes_[static_cast<size_t>(node.right)].box;
#if defined(__SSE2__)
      // Each lane as core.lowerBound(box, limit).
      double lb_left, lb_right;
      {
        const BoxPair pair_box(left, right);
        const Lanes gap = gapBound2(core, pair_box);
        lb_left = lane0(gap);
        lb_right = lane1(gap);
        if constexpr (kType != ShapeType::Sphere) {
          if (!(lb_left > limit) || !(lb_right > limit)) {
            Lanes3 u;
            Lanes sep;
            centreBound2<kType>(core, pair_box, &u, &sep);
            const Lanes lb = lmax(gap, sep);
            if (!(lb_left > limit)) lb_left = lane0(lb);
            if (!(lb_right > limit)) lb_right = lane1(lb);
          }
        }
      }
#else
      const double lb_left = core.lowerBound(left, limit), lb_right = core.lowerBound(right, limit);
#endif
      if (!(lb_right > limit)) stack[sp++] = node.right;
      if (!(lb_left > limit)) stack[sp++] = node.first;
    }
  }

  template <ShapeType kType>
  static double advancementStep(const MeshBvh& bvh, const Shape& shape, const Pose& X_MB, const Vec3& dp_M,
                                const Vec3& theta_M, double eta, double horizon, NearTriangle* limiting, int hint,
                                AdvanceFront* front) {
    limiting->triangle = -1;
    if (bvh.nodes_.empty() || !(horizon > 0.0)) return std::max(0.0, horizon);
    const double r = coreRadius(shape), rho_c = coreBoundingRadius(shape);
    const double mu_c = dp_M.norm() + rho_c * theta_M.norm();  // bound along any direction
    const CoreM<kType> core(shape, X_MB);
    const Mat3 R_BM = core.R_MB.transpose();
    // The core's axes in M for the second-order bound (a sphere's core is a point: exact already).
    Vec3 axes[3];
    double halves[3];
    int n_axes = 0;
    if (kType == ShapeType::Capsule && shape.half_length > 0.0) {
      axes[0] = core.R_MB.col(2);
      halves[0] = shape.half_length;
      n_axes = 1;
    } else if (kType == ShapeType::Box) {
      for (int j = 0; j < 3; ++j) {
        axes[j] = core.R_MB.col(j);
        halves[j] = shape.half_extents[j];
      }
      n_axes = 3;
    }
    const StepMotion motion(dp_M, theta_M, axes, halves, n_axes);
    constexpr int kAxes = kType == ShapeType::Box ? 3 : 1;  // where n_axes > 0
    // Lower bound of the time before box b can come within η: the larger of the directional bound
    // along the first-order separating direction and the box-gap bound at the full speed μ_c.
    // `along` (optional) gets that direction, the margin along it and the turn's share of the rate
    // where the directional bound was taken (margin > 0), for refineNode.
    struct Along {
      Vec3 u = Vec3::Zero();
      double margin = 0.0, turn = 0.0, rate = 0.0;
      bool valid = false;
    };
    // boxTime's two parts for a triangle's box, taken apart: the gap time, and the directional
    // time (0 where it does not apply); boxTime(b, best) >= best exactly where either is.
    auto gapTime = [&](const Aabb& b) {
      const double margin_gap = core.gapBound(b) - r - eta;
      double t_gap = 0.0;
      if (margin_gap > 0.0) t_gap = mu_c > 0.0 ? margin_gap / mu_c : std::numeric_limits<double>::infinity();
      return t_gap;
    };
    auto directionalTime = [&](const Aabb& b) {
      Vec3 u;
      double sep;
      if (core.centreBound(b, &u, &sep) <= 0.0) return 0.0;
      const double margin = sep - r - eta;
      if (margin <= 0.0) return 0.0;
      const double rate = u.dot(dp_M) + rho_c * u.cross(theta_M).norm();
      return rate > 0.0 ? margin / rate : std::numeric_limits<double>::infinity();
    };
    auto boxTime = [&](const Aabb& b, double cutoff, Along* along = nullptr) {
      const double margin_gap = core.gapBound(b) - r - eta;
      double t_gap = 0.0;
      if (margin_gap > 0.0) t_gap = mu_c > 0.0 ? margin_gap / mu_c : std::numeric_limits<double>::infinity();
      if (t_gap >= cutoff) return t_gap;
      Vec3 u;
      double sep;
      if (core.centreBound(b, &u, &sep) <= 0.0) return t_gap;
      const double margin = sep - r - eta;
      if (margin <= 0.0) return t_gap;
      const double turn = rho_c * u.cross(theta_M).norm(), rate = u.dot(dp_M) + turn;
      if (along) *along = Along{u, margin, turn, rate, true};
      return std::max(t_gap, rate > 0.0 ? margin / rate : std::numeric_limits<double>::infinity());
    };
    double best = horizon;
    int best_index = -1;  // none yet
    Vec3 best_core_B, best_tri_B;
    std::array<Vec3, 3> best_abc_B;
    double best_d = 0.0;
    // A node's first-order bound t along u (separation margin > 0 beyond r + η) raised by the
    // second-order and body-axis bounds, as for a triangle: both hold for any convex set along a
    // fixed direction (the body-axis one over the box's eight corners), so a turning body's
    // receding end prunes whole subtrees, not only their triangles one by one.
    auto refineNode = [&](int index, const Vec3& u, double margin, double t) {
      const Direction dir(u, motion);
      double support = 0.0;
      if (n_axes > 0) t = std::max(t, secondOrderTime<kAxes>(margin, u, dir, motion, horizon, &support));
      if (t < best && motion.turning) {
        const Aabb& b = bvh.nodes_[static_cast<size_t>(index)].box;
        Vec3 corners[8];
        for (int c = 0; c < 8; ++c)
          corners[c] = Vec3((c & 1) ? b.hi.x() : b.lo.x(), (c & 2) ? b.hi.y() : b.lo.y(), (c & 4) ? b.hi.z() : b.lo.z());
        t = std::max(t, bodyAxisTime(corners, 8, X_MB.p, u, dir, support, r + eta, motion, 0.0));
      }
      return t;
    };
    // Exact time bound of one triangle (corners in M); updates the best.
    auto visitTriangle = [&](int i, const std::array<Vec3, 3>& v) -> double {
      const std::array<Vec3, 3> abc_B = {R_BM * (v[0] - X_MB.p), R_BM * (v[1] - X_MB.p), R_BM * (v[2] - X_MB.p)};
      Vec3 core_B, tri_B;
      const double d_core = detail::coreTriangle(shape, abc_B[0], abc_B[1], abc_B[2], &core_B, &tri_B);
      double t_i = 0.0;
      if (d_core > 0.0) {
        // Separating direction from the core towards the triangle, frame M (the closest pair's, so
        // the separation along it is the distance now): the larger of the first-order and the
        // second-order bound (both are lower bounds of the contact time). A triangle already
        // within η (a body resting at the sweep's floor) may not come closer by more than
        // kMinShrink: the body can recede or slide along it, not creep in. (Only here: for boxes
        // and the pre-check the separation is a lower bound below the distance, so a margin <= 0
        // there says nothing and they are always visited.)
        const Vec3 w_M = core.R_MB * ((tri_B - core_B) / d_core);
        const double margin = std::max(d_core - r - eta, kMinShrink);
        const Direction dir(w_M, motion);
        const double rate = dir.w_dp + rho_c * dir.w_x_theta;
        t_i = rate > 0.0 ? margin / rate : std::numeric_limits<double>::infinity();
        double support = 0.0;
        if (t_i < best && n_axes > 0)
          t_i = std::max(t_i, secondOrderTime<kAxes>(margin, w_M, dir, motion, horizon, &support));
        if (t_i < best && motion.turning)
          t_i = std::max(t_i, bodyAxisTime(v.data(), 3, X_MB.p, w_M, dir, support, r + eta, motion, kMinShrink));
      }
      if (t_i < best) {
        best = t_i;
        best_index = i;
        best_core_B = core_B;
        best_tri_B = tri_B;
        best_abc_B = abc_B;
        best_d = d_core;
      }
      return t_i;
    };
    // The traversal skips the hint's position: visited again there it would give the same time
    // (its bounds refined at least as far, the best being at most the hint's time), which cannot
    // replace the best.
    int hint_at = -1;
    double hint_t = std::numeric_limits<double>::infinity();
    std::vector<int>* next = front ? &front->next : nullptr;
    auto keep = [&](int item, double t) {
      if (next && t < horizon) next->push_back(item);
    };
    if (hint >= 0 && hint < bvh.mesh_.triangleCount()) {
      hint_at = bvh.position_[static_cast<size_t>(hint)];
      hint_t = visitTriangle(hint_at, bvh.tri_vertices_[static_cast<size_t>(hint_at)]);
    }
    // One triangle (its position i): its bounds cheapest first, its visit where none reaches the
    // best; returns the bound that settled it (a lower bound of its time).
    auto leafTriangle = [&](int i) -> double {
      // A triangle is visited only where none of its bounds reaches the best; they are taken
      // cheapest and most often pruning first: the box gap, the first-order bound along the
      // centroid's direction, then the box's directional one (boxTime's second part), then the
      // centroid direction's second-order and body-axis ones.
      const Aabb& tri_box = bvh.tri_boxes_[static_cast<size_t>(i)];
      {
        const double tg = gapTime(tri_box);
        if (tg >= best) return tg;
      }
      const auto& v = bvh.tri_vertices_[static_cast<size_t>(i)];
      // f(c) + min_k u·(v_k − c), u the core distance's gradient at the centroid c, is the
      // separation of core and triangle along the fixed direction u (u is the core's outward
      // normal at the point nearest c), so every bound of visitTriangle holds along it too:
      // the first-order one, then (where that does not settle it) the second-order and the
      // body-axis ones, which see a turning body's far end recede. Only where the shape is
      // more than η clear along u (a smaller separation says nothing: the triangle is visited).
      Vec3 u;
      double sep;
      const bool along_u = core.triangleBound(v, bvh.tri_centroids_[static_cast<size_t>(i)], &u, &sep) > 0.0;
      const double margin = sep - r - eta;
      double t_u = 0.0;  // a separation within r + η: time 0
      if (along_u && !(margin <= 0.0)) {
        const double rate = u.dot(dp_M) + rho_c * u.cross(theta_M).norm();
        t_u = rate > 0.0 ? margin / rate : std::numeric_limits<double>::infinity();
      }
      if (along_u && t_u >= best) return t_u;
      {
        const double td = directionalTime(tri_box);
        if (td >= best) return td;
      }
      if (along_u && !(margin <= 0.0)) {
        const Direction dir(u, motion);
        double support = 0.0;
        if (t_u < best && margin > 0.0 && n_axes > 0)
          t_u = std::max(t_u, secondOrderTime<kAxes>(margin, u, dir, motion, horizon, &support));
        if (t_u < best && margin > 0.0 && motion.turning)
          t_u = std::max(t_u, bodyAxisTime(v.data(), 3, X_MB.p, u, dir, support, r + eta, motion, 0.0));
        if (t_u >= best) return t_u;
      }
      return visitTriangle(i, v);
    };
    int stack[kStackSize];
    double stack_t[kStackSize];
    int sp = 0;
    // Depth first from what is on the stack, the nearer child on top; what is not taken goes to
    // the front when it is not certified for the rest of the motion.
    auto run = [&]() {
      while (sp > 0) {
        --sp;
        if (stack_t[sp] >= best) {
          keep(stack[sp], stack_t[sp]);
          continue;
        }
        const Node& node = bvh.nodes_[static_cast<size_t>(stack[sp])];
        if (node.count > 0) {
          for (int i = node.first; i < node.first + node.count; ++i) {
            if (i == hint_at) continue;
            keep(-(i + 1), leafTriangle(i));
          }
          continue;
        }
  #if defined(__SSE2__)
        // Both children at once; each lane as boxTime(box, best).
        double t_left, t_right;
        {
          const BoxPair pair_box(bvh.nodes_[static_cast<size_t>(node.first)].box, bvh.nodes_[static_cast<size_t>(node.right)].box);
          const Lanes gap = gapBound2(core, pair_box);
          double t[2];
          const double g[2] = {lane0(gap), lane1(gap)};
          for (int k = 0; k < 2; ++k) {
            const double margin_gap = g[k] - r - eta;
            t[k] = 0.0;
            if (margin_gap > 0.0) t[k] = mu_c > 0.0 ? margin_gap / mu_c : std::numeric_limits<double>::infinity();
          }
          if (t[0] < best || t[1] < best) {
            Lanes3 u;
            Lanes sep;
            const Lanes f = centreBound2<kType>(core, pair_box, &u, &sep);
            const Lanes margin = sep - splat(r) - splat(eta);
            const Lanes cx = u.y * splat(theta_M.z()) - u.z * splat(theta_M.y());
            const Lanes cy = u.z * splat(theta_M.x()) - u.x * splat(theta_M.z());
            const Lanes cz = u.x * splat(theta_M.y()) - u.y * splat(theta_M.x());
            const Lanes turn = splat(rho_c) * lsqrt(cx * cx + cy * cy + cz * cz);
            const Lanes rate = dot(u, dp_M) + turn;
            const Lanes q = margin / rate;
            const double fs[2] = {lane0(f), lane1(f)}, ms[2] = {lane0(margin), lane1(margin)};
            const double rs[2] = {lane0(rate), lane1(rate)}, qs[2] = {lane0(q), lane1(q)};
            const double ts[2] = {lane0(turn), lane1(turn)};
            for (int k = 0; k < 2; ++k) {
              if (t[k] >= best || fs[k] <= 0.0 || ms[k] <= 0.0) continue;
              t[k] = std::max(t[k], rs[k] > 0.0 ? qs[k] : std::numeric_limits<double>::infinity());
              if (t[k] < best && ts[k] > kTurnShare * rs[k])
                t[k] = refineNode(k == 0 ? node.first : node.right, Vec3(lane0or1(u.x, k), lane0or1(u.y, k), lane0or1(u.z, k)), ms[k], t[k]);
            }
          }
          t_left = t[0];
          t_right = t[1];
        }
  #else
        // The lanes' arithmetic, one child at a time.
        auto nodeTime = [&](int index) {
          Along a;
          double t = boxTime(bvh.nodes_[static_cast<size_t>(index)].box, best, &a);
          if (a.valid && t < best && a.turn > kTurnShare * a.rate) t = refineNode(index, a.u, a.margin, t);
          return t;
        };
        const double t_left = nodeTime(node.first);
        const double t_right = nodeTime(node.right);
  #endif
        const bool left_first = t_left <= t_right;
        const int far_node = left_first ? node.right : node.first, near_node = left_first ? node.first : node.right;
        const double far_t = left_first ? t_right : t_left, near_t = left_first ? t_left : t_right;
        if (far_t < best) { stack[sp] = far_node; stack_t[sp++] = far_t; } else keep(far_node, far_t);
        if (near_t < best) { stack[sp] = near_node; stack_t[sp++] = near_t; } else keep(near_node, near_t);
      }
    };
    if (front && front->valid) {
      // Only what the last step could not certify for the rest of the motion (the front):
      // every other triangle's bound reached that step's horizon.
      front->current.swap(front->next);
      front->next.clear();
      if (hint_at >= 0) keep(-(hint_at + 1), hint_t);
      for (int item : front->current) {
        if (item < 0) {
          const int i = -item - 1;
          if (i != hint_at) keep(item, leafTriangle(i));
          continue;
        }
        stack[0] = item;
        stack_t[0] = -1.0;  // expanded: its children's bounds are taken now
        sp = 1;
        run();
      }
    } else {
      if (next) next->clear();
      if (hint_at >= 0) keep(-(hint_at + 1), hint_t);
      stack[sp] = 0;
      stack_t[sp++] = boxTime(bvh.nodes_[0].box, best);
      run();
    }
    if (front) front->valid = true;
    if (best_index >= 0) {  // its position in bvh.order_
      limiting->triangle = bvh.order_[static_cast<size_t>(best_index)];
      limiting->closest = detail::finishClosestPoints(shape, X_MB, core.R_MB, best_d, best_core_B, best_tri_B,
                                                      best_abc_B[0], best_abc_B[1], best_abc_B[2]);
    }
    return best;
  }

};

namespace {
std::vector<std::uint8_t> edgeCreases(const TriangleMesh& mesh) {
  std::vector<std::uint8_t> out;
  const size_t nt = static_cast<size_t>(mesh.triangleCount());
  // Edge e of triangle t (from corner e to e + 1) is a crease where two triangles meet at an
  // angle (normals more than 1° apart) or more than two meet. An edge of one triangle (a hole, a
  // crack, an open surface's rim) is not: a crack in a flat face must not tilt its rows (seen: a
  // cracked cube, 30 of 166 windows frozen).
  constexpr double kFlatCos = 0.9998476951563913;  // cos 1°
  std::vector<std::array<std::uint64_t, 2>> keys;  // (vertex pair, 3 t + e)
  keys.reserve(3 * nt);
  for (size_t t = 0; t < nt; ++t)
    for (int e = 0; e < 3; ++e) {
      const std::uint64_t a = static_cast<std::uint32_t>(mesh.triangles[t][static_cast<size_t>(e)]);
      const std::uint64_t b = static_cast<std::uint32_t>(mesh.triangles[t][static_cast<size_t>((e + 1) % 3)]);
      keys.push_back({std::min(a, b) << 32 | std::max(a, b), 3 * t + static_cast<size_t>(e)});
    }
  std::sort(keys.begin(), keys.end());
  auto normal = [&mesh](size_t t) {
    const int ti = static_cast<int>(t);
    const Vec3 n = (mesh.vertex(ti, 1) - mesh.vertex(ti, 0)).cross(mesh.vertex(ti, 2) - mesh.vertex(ti, 0));
    const double len = n.norm();
    return len > 0.0 ? Vec3(n / len) : Vec3::Zero();
  };
  out.assign(3 * nt, 1);
  for (size_t i = 0; i < keys.size();) {
    size_t j = i + 1;
    while (j < keys.size() && keys[j][0] == keys[i][0]) ++j;
    if (j - i == 1 || (j - i == 2 && normal(keys[i][1] / 3).dot(normal(keys[i + 1][1] / 3)) > kFlatCos))
      for (size_t k = i; k < j; ++k) out[keys[k][1]] = 0;
    i = j;
  }
  return out;
}
}  // namespace

MeshBvh::MeshBvh(TriangleMesh mesh) : mesh_(std::move(mesh)) {
  if (mesh_.triangles.empty()) throw std::invalid_argument("MeshBvh: the mesh has no triangles");
  const int nv = static_cast<int>(mesh_.vertices.size());
  for (size_t v = 0; v < mesh_.vertices.size(); ++v) {
    if (!mesh_.vertices[v].allFinite())
      throw std::invalid_argument("MeshBvh: vertex " + std::to_string(v) + " is not finite");
  }
  for (size_t t = 0; t < mesh_.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh_.triangles[t][static_cast<size_t>(k)];
      if (v < 0 || v >= nv)
        throw std::invalid_argument("MeshBvh: triangle " + std::to_string(t) + " has vertex index " + std::to_string(v) +
                                    " out of range [0, " + std::to_string(nv) + ")");
    }
  }
  const int n = mesh_.triangleCount();
  creases_ = edgeCreases(mesh_);
  BuildData data;
  data.boxes.resize(static_cast<size_t>(n));
  data.centroids.resize(static_cast<size_t>(n));
  data.area_vectors.resize(static_cast<size_t>(n));
  data.areas.resize(static_cast<size_t>(n));
  for (int t = 0; t < n; ++t) {
    const auto i = static_cast<size_t>(t);
    const Vec3 a = mesh_.vertex(t, 0), b = mesh_.vertex(t, 1), c = mesh_.vertex(t, 2);
    data.boxes[i].grow(a);
    data.boxes[i].grow(b);
    data.boxes[i].grow(c);
    data.centroids[i] = (a + b + c) / 3.0;
    data.area_vectors[i] = 0.5 * (b - a).cross(c - a);
    data.areas[i] = data.area_vectors[i].norm();
  }
  const std::vector<Aabb>& boxes = data.boxes;
  order_.resize(static_cast<size_t>(n));
  std::iota(order_.begin(), order_.end(), 0);
  nodes_.reserve(2 * static_cast<size_t>(n));  // ≤ 2n − 1 nodes
  dipole_moment_.reserve(nodes_.capacity());
  dipoles_.reserve(nodes_.capacity());
  Impl::build(*this, 0, n, 0, data);
  nodes_.shrink_to_fit();
  dipole_moment_.shrink_to_fit();
  dipoles_.shrink_to_fit();
  tri_boxes_.resize(static_cast<size_t>(n));
  tri_vertices_.resize(static_cast<size_t>(n));
  tri_centroids_.resize(static_cast<size_t>(n));
  position_.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const int t = order_[static_cast<size_t>(i)];
    position_[static_cast<size_t>(t)] = i;
    tri_boxes_[static_cast<size_t>(i)] = boxes[static_cast<size_t>(t)];
    tri_vertices_[static_cast<size_t>(i)] = {mesh_.vertex(t, 0), mesh_.vertex(t, 1), mesh_.vertex(t, 2)};
    tri_centroids_[static_cast<size_t>(i)] = centroid(tri_vertices_[static_cast<size_t>(i)]);
  }
  bounds_ = nodes_.front().box;
  max_coordinate_ = bounds_.lo.cwiseAbs().cwiseMax(bounds_.hi.cwiseAbs()).maxCoeff();
}

void MeshBvh::trianglesOverlapping(const Aabb& box_M, std::vector<int>* out) const {
  if (nodes_.empty() || box_M.empty()) return;
  int stack[kStackSize];
  int sp = 0;
  stack[sp++] = 0;
  while (sp > 0) {
    const Node& node = nodes_[static_cast<size_t>(stack[--sp])];
    if (!node.box.overlaps(box_M)) continue;
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        if (tri_boxes_[static_cast<size_t>(i)].overlaps(box_M)) out->push_back(order_[static_cast<size_t>(i)]);
      }
    } else {
      stack[sp++] = node.right;
      stack[sp++] = node.first;
    }
  }
}

bool MeshBvh::closest(const Shape& shape, const Pose& X_MB, double max_distance, NearTriangle* out, int hint) const {
  switch (shape.type) {
    case ShapeType::Sphere: return Impl::closest<ShapeType::Sphere>(*this, shape, X_MB, max_distance, out, hint);
    case ShapeType::Capsule: return Impl::closest<ShapeType::Capsule>(*this, shape, X_MB, max_distance, out, hint);
    case ShapeType::Box: return Impl::closest<ShapeType::Box>(*this, shape, X_MB, max_distance, out, hint);
  }
  return false;
}

void MeshBvh::near(const Shape& shape, const Pose& X_MB, double max_distance, std::vector<NearTriangle>* out) const {
  switch (shape.type) {
    case ShapeType::Sphere: return Impl::near<ShapeType::Sphere>(*this, shape, X_MB, max_distance, out);
    case ShapeType::Capsule: return Impl::near<ShapeType::Capsule>(*this, shape, X_MB, max_distance, out);
    case ShapeType::Box: return Impl::near<ShapeType::Box>(*this, shape, X_MB, max_distance, out);
  }
}

bool MeshBvh::closestAmong(const std::vector<NearTriangle>& near_answer, const Shape& shape, const Pose& X_MB,
                           double near_distance, double max_distance, NearTriangle* out) const {
  if (near_answer.empty() || std::isnan(max_distance) || std::isnan(near_distance)) return false;
  const double r = coreRadius(shape);
  // near() prunes at its limit without closest()'s slack: a triangle whose bound came out a few
  // ulps above the limit may be missing, so only what lies below limit − slack is certain.
  const double tie = kTieSlack * (1.0 + max_coordinate_ + X_MB.p.cwiseAbs().maxCoeff());
  const NearTriangle* best = nullptr;
  for (const NearTriangle& t : near_answer) {
    const double d = t.closest.core_distance;
    if (!best || d < best->closest.core_distance ||
        (d == best->closest.core_distance && t.triangle < best->triangle))
      best = &t;
  }
  const double d = best->closest.core_distance;
  if (!(d < near_distance + r - tie) || !(d <= max_distance + r)) return false;
  *out = *best;
  return true;
}

double MeshBvh::advancementStep(const Shape& shape, const Pose& X_MB, const Vec3& dp_M, const Vec3& theta_M,
                                double eta, double horizon, NearTriangle* limiting, int hint, AdvanceFront* front) const {
  switch (shape.type) {
    case ShapeType::Sphere:
      return Impl::advancementStep<ShapeType::Sphere>(*this, shape, X_MB, dp_M, theta_M, eta, horizon, limiting, hint, front);
    case ShapeType::Capsule:
      return Impl::advancementStep<ShapeType::Capsule>(*this, shape, X_MB, dp_M, theta_M, eta, horizon, limiting, hint, front);
    case ShapeType::Box:
      return Impl::advancementStep<ShapeType::Box>(*this, shape, X_MB, dp_M, theta_M, eta, horizon, limiting, hint, front);
  }
  limiting->triangle = -1;
  return std::max(0.0, horizon);
}

double MeshBvh::windingNumber(const Vec3& p_M) const {
  if (nodes_.empty()) return 0.0;
  double omega = 0.0;
  int stack[kStackSize];
  int sp = 0;
  stack[sp++] = 0;
  while (sp > 0) {
    const int index = stack[--sp];
    const Node& node = nodes_[static_cast<size_t>(index)];
    const NodeDipole& dipole = dipoles_[static_cast<size_t>(index)];
    const Vec3 r = dipole.centre - p_M;
    const double dist2 = r.squaredNorm();
    if (dist2 > kWindingBeta * kWindingBeta * dipole.radius * dipole.radius) {
      // Far field (see bvh.h): dipole N·r/|r|³ plus the second-order moment term.
      const Mat3& M = dipole_moment_[static_cast<size_t>(index)];
      const double inv3 = 1.0 / (dist2 * std::sqrt(dist2));
      omega += inv3 * (r.dot(dipole.normal) + M.trace() - 3.0 * r.dot(M * r) / dist2);
    } else if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const auto& v = tri_vertices_[static_cast<size_t>(i)];
        omega += solidAngle(v[0] - p_M, v[1] - p_M, v[2] - p_M);
      }
    } else {
      stack[sp++] = node.right;
      stack[sp++] = node.first;
    }
  }
  return omega / (4.0 * kPi);
}

double surfaceDistanceBound(const TriangleMesh& from, const MeshBvh& to, double tolerance, double* measured) {
  Shape point;
  point.type = ShapeType::Sphere;
  point.radius = 0.0;
  double sampled = 0.0;
  auto distanceOf = [&](const Vec3& x) {
    NearTriangle c;
    Pose X;
    X.p = x;
    const double d = to.closest(point, X, std::numeric_limits<double>::infinity(), &c) ? std::max(0.0, c.closest.distance)
                                                                                         : std::numeric_limits<double>::infinity();
    sampled = std::max(sampled, d);
    return d;
  };
  constexpr int kMaxDepth = 7;
  const double inv_sqrt3 = 1.0 / std::sqrt(3.0);
  // Bound over triangle abc with its corners' distances: every point of it lies within its
  // longest side / √3 of a corner; where that exceeds the tolerance, split at the midpoints.
  std::function<double(const Vec3&, const Vec3&, const Vec3&, double, double, double, int)> triangle =
      [&](const Vec3& a, const Vec3& b, const Vec3& c, double da, double db, double dc, int depth) {
        const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
        const double base = std::max({da, db, dc}) + longest * inv_sqrt3;
        // Refined until within the tolerance with a cover term of at most a tenth of it (so the
        // bound is close to the true distance, not just under the tolerance).
        if ((base <= tolerance && longest * inv_sqrt3 <= 0.1 * tolerance) || depth >= kMaxDepth) return base;
        const Vec3 ab = 0.5 * (a + b), bc = 0.5 * (b + c), ca = 0.5 * (c + a);
        const double dab = distanceOf(ab), dbc = distanceOf(bc), dca = distanceOf(ca);
        double worst = 0.0;
        for (const double w : {triangle(a, ab, ca, da, dab, dca, depth + 1), triangle(ab, b, bc, dab, db, dbc, depth + 1),
                               triangle(ca, bc, c, dca, dbc, dc, depth + 1), triangle(ab, bc, ca, dab, dbc, dca, depth + 1)}) {
          worst = std::max(worst, w);
          if (worst > tolerance) break;
        }
        return worst;
      };
  std::vector<double> at_vertex(from.vertices.size(), -1.0);
  double bound = 0.0;
  for (const auto& t : from.triangles) {
    double d[3];
    for (int k = 0; k < 3; ++k) {
      double& dv = at_vertex[static_cast<size_t>(t[k])];
      if (dv < 0.0) dv = distanceOf(from.vertices[static_cast<size_t>(t[k])]);
      d[k] = dv;
    }
    bound = std::max(bound, triangle(from.vertices[static_cast<size_t>(t[0])], from.vertices[static_cast<size_t>(t[1])],
                                     from.vertices[static_cast<size_t>(t[2])], d[0], d[1], d[2], 0));
    if (bound > tolerance) break;
  }
  if (measured) *measured = sampled;
  return bound;
}

}  // namespace godhand::geo
