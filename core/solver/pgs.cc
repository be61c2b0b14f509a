#include "solver/pgs.h"

#include <algorithm>
#include <cmath>

namespace godhand {

void PgsSolver::reserve(int bodies, int) {
  if (kkt_scratch_.size() < 2 * static_cast<size_t>(bodies)) kkt_scratch_.resize(2 * static_cast<size_t>(bodies));
}

SolveStats PgsSolver::solve(const QpProblem& p, QpSolution& sol, const double* warm) {
  const int m = p.numRows(), nb = p.numBodies();
  reserve(nb, m);
  sol.resize(nb, m);
  SolveStats stats;
  for (int b = 0; b < nb; ++b) sol.z[static_cast<size_t>(b)] = p.unconstrained(b);
  for (int k = 0; k < m; ++k) {
    const Row& row = p.row(k);
    double l = warm ? warm[k] : 0.0;
    if (!std::isfinite(l) || (row.type == RowType::Inequality && l < 0.0)) l = 0.0;
    sol.lambda[static_cast<size_t>(k)] = l;
    if (l != 0.0) {
      sol.z[static_cast<size_t>(row.body0)] += l * row.W0;
      if (row.body1 >= 0) sol.z[static_cast<size_t>(row.body1)] += l * row.W1;
    }
  }
  const double omega = settings_.relaxation;
  for (int sweep = 0; sweep < settings_.sweeps; ++sweep) {
    for (int k = 0; k < m; ++k) {
      const Row& row = p.row(k);
      if (!(row.diag > 0.0)) continue;
      const double w = p.rowDot(k, sol.z.data()) - row.c;
      double& l = sol.lambda[static_cast<size_t>(k)];
      double next = l - omega * w / row.diag;
      if (row.type == RowType::Inequality && next < 0.0) next = 0.0;
      const double d = next - l;
      if (d == 0.0) continue;
      l = next;
      sol.z[static_cast<size_t>(row.body0)] += d * row.W0;
      if (row.body1 >= 0) sol.z[static_cast<size_t>(row.body1)] += d * row.W1;
    }
    ++stats.iterations;
  }
  bool finite = true;
  for (int b = 0; b < nb; ++b) finite = finite && sol.z[static_cast<size_t>(b)].allFinite();
  int active = 0;
  for (int k = 0; k < m; ++k) active += sol.lambda[static_cast<size_t>(k)] != 0.0;
  stats.active_set_size = active;
  stats.kkt_residual = kktResidual(p, sol, kkt_scratch_).max();
  stats.status = (!finite || !std::isfinite(stats.kkt_residual)) ? SolveStatus::NumericalFailure : SolveStatus::SweepLimit;
  return stats;
}

}  // namespace godhand
