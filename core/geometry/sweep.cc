#include "geometry/sweep.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace godhand::geo {
namespace {

/// The motion, precomputed once per sweep.
struct Motion {
  Pose X0;
  Vec3 dp;     ///< p1 − p0
  Vec3 theta;  ///< log(R1 R0ᵀ)

  Motion(const Pose& X_M0, const Pose& X_M1)
      : X0(X_M0), dp(X_M1.p - X_M0.p), theta(logRotation(X_M1.q * X_M0.q.conjugate())) {}

  Pose at(double t) const {
    Pose X;
    X.p = X0.p + t * dp;
    X.q = (expRotation(t * theta) * X0.q).normalized();
    return X;
  }
};

/// d(t), looking as far as `window`; +inf if nothing is within it.
double distanceAt(const Shape& shape, const Motion& motion, double t, double window, const MeshBvh& bvh) {
  NearTriangle nt;
  return bvh.closest(shape, motion.at(t), window, &nt) ? nt.closest.distance : std::numeric_limits<double>::infinity();
}

/// Directional conservative advancement (sweep.h) from t = 0, where d(0) = d0 > η.
SweepResult directionalSweep(const Shape& shape, const Motion& motion, double mu, double d0, int nearest, double eta,
                             const MeshBvh& bvh, const SweepParams& params, SweepResult result) {
  double t = 0.0;
  double d_limit = d0;  // distance of the triangle that limited the last step
  NearTriangle limiting;
  limiting.triangle = nearest;
  // What each step could not certify for the rest of the motion, for the next step (bvh.h); the
  // thread's own scratch, grown once.
  thread_local AdvanceFront front;
  front.valid = false;
  for (;;) {
    if (result.iterations >= params.max_iterations) {
      result.hit = true;
      result.capped = true;
      result.toc = t;
      result.distance = params.exact_distance ? distanceAt(shape, motion, t, mu + eta, bvh) : d_limit;
      return result;
    }
    ++result.iterations;
    const double horizon = 1.0 - t;
    const double dt =
        bvh.advancementStep(shape, motion.at(t), motion.dp, motion.theta, eta, horizon, &limiting, limiting.triangle, &front);
    if (limiting.triangle >= 0) {
      d_limit = limiting.closest.distance;
      if (d_limit <= eta + params.tolerance) {
        result.hit = true;
        result.toc = t;
        // The limiting triangle is within η + tolerance; a nearer one may be receding.
        result.distance = params.exact_distance ? std::min(d_limit, distanceAt(shape, motion, t, d_limit, bvh)) : d_limit;
        return result;
      }
    }
    if (limiting.triangle < 0 || dt >= horizon) {
      result.toc = 1.0;
      result.distance = params.exact_distance ? distanceAt(shape, motion, 1.0, mu + eta, bvh)
                                              : std::numeric_limits<double>::quiet_NaN();
      return result;
    }
    t += dt;
  }
}

}  // namespace

Pose interpolateMotion(const Pose& X0, const Pose& X1, double t) { return Motion(X0, X1).at(t); }

SweepResult sweep(const Shape& shape, const Pose& X_M0, const Pose& X_M1, const MeshBvh& bvh,
                  const SweepParams& params, const SweepStart* start) {
  SweepResult result;
  const double inf = std::numeric_limits<double>::infinity();
  const Motion motion(X_M0, X_M1);
  // μ: bound on how far any point of the shape moves over the whole step.
  const double mu = motion.dp.norm() + motion.theta.norm() * boundingRadius(shape);

  // d(0), looking only as far as the motion can reach (+ the largest possible η).
  NearTriangle nt;
  result.iterations = 1;
  const double first_window = mu + params.stop_distance;
  bool near = false;
  if (start && start->found) {  // the nearest triangle: within the window or nothing is
    nt = start->nearest;
    near = !(nt.closest.distance > first_window);
    result.iterations = 0;
  } else if (start && start->range >= first_window) {  // nothing within a larger window
    result.iterations = 0;
  } else {
    near = bvh.closest(shape, X_M0, first_window, &nt);
  }
  if (!near) {
    result.toc = 1.0;
    result.distance = inf;
    return result;
  }
  double d = nt.closest.distance;
  // Only a core inside the surface is "inside" (nothing can be said). A body whose rounded shell
  // overlaps the surface by less than its radius is swept like one at the stop floor: it may
  // recede or slide, never go deeper.
  if (!(nt.closest.core_distance > 0.0)) {
    result.started_inside = true;
    result.toc = 0.0;
    result.distance = d;
    return result;
  }
  // η = min(stop_distance, d(0)/2), but never below min_stop_distance: a body stopped close to a
  // surface keeps a floor, so repeated clips cannot walk it down to touching (where round-off
  // would read it as inside, and inside cannot be clipped). Below the floor it may only recede
  // or slide (bvh.h advancementStep). The tolerance stays below the room between η and d(0): a
  // body resting a few µm from a surface would otherwise count as within η + tolerance at t = 0
  // and stop there for good, whichever way it moves.
  const double eta = std::min(params.stop_distance, std::max(params.min_stop_distance, 0.5 * d));
  SweepParams local = params;
  // A handed-over d(0) counts against the iteration cap as the query it replaces: the same steps,
  // the same (conservative) TOC where the cap is reached.
  if (result.iterations == 0) local.max_iterations = params.max_iterations - 1;
  local.tolerance = std::min(params.tolerance, std::max(0.0, 0.5 * (d - eta)));
  if (params.directional) return directionalSweep(shape, motion, mu, d, nt.triangle, eta, bvh, local, result);
  double t = 0.0;
  for (;;) {
    if (d <= eta + local.tolerance) {
      result.hit = true;
      result.toc = t;
      result.distance = d;
      return result;
    }
    if (!(mu > 0.0)) {  // no motion, and not within the stop distance
      result.toc = 1.0;
      result.distance = d;
      return result;
    }
    if (result.iterations >= local.max_iterations) {
      // Out of iterations: what has been verified so far (conservative), reported as a hit
      // so that the caller stops there.
      result.hit = true;
      result.capped = true;
      result.toc = t;
      result.distance = d;
      return result;
    }
    // Conservative advancement: the distance shrinks at most at rate μ.
    t += (d - eta) / mu;
    if (t >= 1.0) {
      // Only reachable through round-off (the window below keeps d − η ≤ μ (1 − t)).
      t = 1.0;
    }
    const double window = mu * (1.0 - t) + eta;
    ++result.iterations;
    if (!bvh.closest(shape, motion.at(t), window, &nt)) {
      // Nothing within what the rest of the motion can reach: safe to the end.
      result.toc = 1.0;
      result.distance = inf;
      return result;
    }
    d = nt.closest.distance;
    if (t >= 1.0 && d > eta + local.tolerance) {
      result.toc = 1.0;
      result.distance = d;
      return result;
    }
  }
}

}  // namespace godhand::geo
