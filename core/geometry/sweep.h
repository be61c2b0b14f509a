// Continuous collision: the time of contact of one God object's motion over a step against one
// mesh (paper §6.3, METHOD.md §2 step 5), by conservative advancement (Mirtich 1996; Zhang et
// al. 2006) on the BVH's exact distances.
//
// Motion over t ∈ [0, 1], in the mesh frame M: the body origin moves on a straight line and
// the orientation rotates at constant angular velocity,
//   p(t) = p0 + t (p1 − p0),   R(t) = exp(t θ) R0  with  θ = log(R1 R0ᵀ)   (the same ⊕ as the step).
// Any point of the shape at distance ≤ ρ (boundingRadius) from the origin moves at most
// μ = |p1 − p0| + |θ| ρ over the whole step, so the distance d(t) shrinks at most at rate μ and
// t_{k+1} = t_k + (d(t_k) − η)/μ never steps past the first time the distance reaches η.
//
// Directional advancement (SweepParams::directional, the default) takes larger, still
// conservative steps, which is what lets a body resting ~0.1 mm above a surface slide along it in a
// few iterations instead of ~(slide length)/(d − η). The shape distance is the core distance − r,
// and the separation of two sets along any fixed unit direction w is ≤ their distance. A core
// point x moves with velocity Δp + θ × (x − p(t)), whose component along w is at most
//   rate(w) = w·Δp + ρ_c |w × θ|,   ρ_c = coreBoundingRadius ≤ ρ,   rate(w) ≤ μ.
// For each triangle (convex) with separating direction w_t from its closest points at t_k (core
// distance d_t), no point of it comes within η before t_k + (d_t − r − η)/rate(w_t); BVH boxes
// get the same bound along their first-order separating direction (MeshBvh::advancementStep).
// The step is the minimum over all triangles, so the guarantee below holds unchanged; since
// rate(w) ≤ μ each step is at least the plain one.
//
// Guarantee (tested against fine sampling of the motion with exact brute-force / BVH distances,
// tests/geometry/test_sweep.cc): the returned toc is
// never later than the first time the shape touches the mesh, and d(s) ≥ η − tolerance for
// every s ≤ toc. Stop distance η = min(stop_distance, ½ d(0)) so that a body already resting
// close to a surface can still slide along it.
#pragma once

#include "geometry/bvh.h"

namespace godhand::geo {

struct SweepParams {
  double stop_distance = 2.5e-5;  ///< η, m: stop this far from the surface
  double min_stop_distance = 1e-6;  ///< η never below this, m (no ratchet down to touching)
  double tolerance = 1e-6;        ///< CA stops once within η + tolerance, m (directional: once
                                  ///< the triangle limiting the step is)
  int max_iterations = 100;       ///< then the toc reached so far is returned (conservative)
  /// Directional per-triangle bounds (see above); false: the plain global-μ advancement.
  bool directional = true;
  /// SweepResult::distance exact at toc (one more closest query per sweep that meets a
  /// triangle); false: for a hit, the distance of the triangle that stopped it (≥ the exact
  /// one), for a free motion NaN. toc, hit and the guarantee are the same either way.
  bool exact_distance = true;
};

struct SweepResult {
  double toc = 1.0;            ///< fraction of the step that is safe, in [0, 1]
  bool hit = false;            ///< the motion reaches the stop distance before t = 1
  bool started_inside = false; ///< d(0) ≤ 0: nothing can be said; toc = 0
  int iterations = 0;
  double distance = 0.0;       ///< d(toc), m (+inf if nothing within reach: μ + η at toc = 1;
                               ///< see SweepParams::exact_distance)
  bool capped = false;         ///< max_iterations ran out: toc is the conservative time reached
                               ///< (< 1), reported with hit = true so that the caller stops there
};

/// Pose at fraction t of the motion X0 → X1 (see above).
Pose interpolateMotion(const Pose& X0, const Pose& X1, double t);

/// d(0) known already: a MeshBvh::closest query of the same shape at the same X_M0 within
/// `range` (the contact query's). The sweep uses it instead of its own first query where that
/// query would give the same answer: when a triangle was found (the nearest one, whatever the
/// window) or when `range` covers the sweep's window (μ + stop distance).
struct SweepStart {
  double range = 0.0;    ///< m: the query's window
  bool found = false;    ///< a triangle was within it
  NearTriangle nearest;  ///< the nearest, when found
};

/// `start` (optional): d(0) as above (nullptr: queried here).
SweepResult sweep(const Shape& shape, const Pose& X_M0, const Pose& X_M1, const MeshBvh& bvh,
                  const SweepParams& params = {}, const SweepStart* start = nullptr);

}  // namespace godhand::geo
