// Projected Gauss–Seidel on the dual of the Gauss least-constraint QP (METHOD.md §3): the fast,
// approximate alternative to the exact active-set solver, as in Bullet and most game engines.
//
//   for each sweep, for each row k:  λ_k ← λ_k − (J_k z − c_k) / A_kk,
//                                     λ_k ← max(0, λ_k) for inequality rows,
//                                     z   ← z + M⁻¹ J_kᵀ Δλ_k
//
// with a fixed number of sweeps and a warm start from the previous step's multipliers. It
// converges to the exact solution as sweeps → ∞ (A is SPD on the rows' span); with a fixed
// count it trades accuracy (measured by the KKT residual) for a bounded, predictable cost.
#pragma once

#include <vector>

#include "solver/qp.h"

namespace godhand {

struct PgsSettings {
  int sweeps = 30;
  double relaxation = 1.0;  ///< successive over-relaxation factor ω ∈ (0, 2)
};

class PgsSolver {
 public:
  explicit PgsSolver(PgsSettings settings = {}) : settings_(settings) {}
  void reserve(int bodies, int rows);
  /// `warm_lambda`, if given, holds one starting multiplier per row (clamped to ≥ 0 for
  /// inequality rows); otherwise λ starts at 0.
  SolveStats solve(const QpProblem& problem, QpSolution& solution, const double* warm_lambda = nullptr);
  const PgsSettings& settings() const { return settings_; }

 private:
  PgsSettings settings_;
  std::vector<Vec6> kkt_scratch_;
};

}  // namespace godhand
