// Exact solver of the Gauss least-constraint QP (METHOD.md §3): a primal-dual active-set
// method on the dual, the Lawson–Hanson / Bro–de Jong NNLS scheme in normal-equation form
// (paper ref. [9]), with the equality multipliers kept free and always passive.
//
//   passive set P ⊇ E;   A_PP λ_P = b_P  (λ_k = 0 for k ∉ P)
//   add   argmin_k w_k/√A_kk over inequality rows with w_k = (Aλ − b)_k < −tol   (most violated;
//         tol is also never below a few ulps of |J_k| (|z_u| + Σ_P |λ_i| |M⁻¹J_iᵀ|), the round-off
//         of J_k z, so noise-level slacks at degenerate vertices do not enter)
//   drop  inequality rows of P whose λ would turn negative (step to the boundary, L-H inner loop)
//
// A_PP is held as a Cholesky factor L Lᵀ = A_PP + diag(ε A_kk), updated in O(|P|²) when a row
// enters (append) or leaves (row deletion + rank-one update), never refactored from scratch
// within a solve. The small relative regularisation ε keeps redundant rows (duplicated or
// coplanar contacts) factorisable; one step of iterative refinement against the unregularised A
// recovers full accuracy where A_PP is regular. The paper's J k = c step (Eq. 7) is not used:
// only A and b = c − J z_u are needed.
//
// The factor is stored dense but worked on sparsely: zero entries of the substituted vector are
// skipped and every column carries the index of its last possibly-nonzero row, so that rows
// appended in a tree's depth-first postorder (joint rows, see HandModel::joint_order) cost
// only their fill. No allocation once the buffers have grown to the largest problem seen.
#pragma once

#include <memory>
#include <vector>

#include "solver/qp.h"

namespace godhand {

struct ActiveSetSettings {
  int max_iterations = 0;        ///< active-set changes; 0 = automatic (3 m + 50)
  double regularization = 1e-13; ///< ε, relative to each row's A_kk
  double tolerance = 1e-11;      ///< relative slack tolerance for "violated"
  int refinement_steps = 1;      ///< iterative refinement per solve of A_PP
  double converged_kkt = 1e-6;   ///< a solve is Converged only if its KKT residual is below this
  int max_passive = 0;           ///< passive-set (factor) size cap; 0 = 12 N + 128 for N bodies
  /// A solve that ends Stalled or at the iteration limit is continued by up to this many proximal
  /// iterations (the proximal method of multipliers): each solves the dual regularised by
  /// ρ_k = proximal_regularization · A_kk around the last multipliers,
  ///   min ½ λᵀ(A + diag ρ)λ − (b + diag(ρ) λ_j)ᵀλ over λ_I ≥ 0,
  /// whose factor is well conditioned however dependent the rows are, and whose fixed point is a
  /// solution of the original dual. The result is kept only where its KKT residual on the original
  /// problem is lower; its status is measured on the original problem. 0: off.
  int proximal_iterations = 40;
  double proximal_regularization = 1e-8;
};

class ActiveSetSolver {
 public:
  explicit ActiveSetSolver(ActiveSetSettings settings = {}) : settings_(settings) {}

  /// Grows every buffer for problems with up to `bodies` bodies and `rows` rows. The factor is
  /// sized by the passive-set cap, not by the rows: memory stays O(cap²) however many contacts.
  void reserve(int bodies, int rows);

  /// Solves the problem. `warm_passive`, if given, has one flag per row: inequality rows that were
  /// active last step, tried first (dropped if they turn out infeasible).
  SolveStats solve(const QpProblem& problem, QpSolution& solution, const unsigned char* warm_passive = nullptr);

  const ActiveSetSettings& settings() const { return settings_; }

  /// Diagnostic for tests: max |(L Lᵀ)_ij − (A_PP + ε diag A)_ij| / max_i A_ii for the factor
  /// left by the last solve on `problem`, and the passive-set size through `passive_size`.
  double factorResidual(const QpProblem& problem, int* passive_size = nullptr) const;

 private:
  /// One active-set solve (what solve() did before the proximal iterations).
  SolveStats solveOnce(const QpProblem& p, QpSolution& sol, const unsigned char* warm_passive);
  /// The proximal iterations (ActiveSetSettings::proximal_iterations) after a solve that did not
  /// converge: replaces sol and stats where they end with a lower KKT residual.
  void polish(const QpProblem& p, QpSolution& sol, SolveStats& stats);
  /// stats' KKT residual and status for `sol` (converged: no violated row was left outside P;
  /// stalled: violated rows could not enter; equality_missing: an equality could not be factored).
  void finish(const QpProblem& p, const QpSolution& sol, bool converged, bool stalled, bool equality_missing,
              SolveStats& stats);
  bool append(const QpProblem& p, int k);   // Cholesky append; false if numerically impossible
  void remove(int position);                // delete P[position] from the factor
  void indexEqualities(const QpProblem& p); // eq_of_body_: the equality rows touching each body
  void forwardEqualities(const QpProblem& p);  // yE_ = L_E⁻¹ b_E, once the equality block is built
  void solvePassive(const QpProblem& p);    // s_P = A_PP⁻¹ b_P (no refinement)
  void refinePassive(const QpProblem& p);   // s_P += A_PP⁻¹ (b_P − A_PP s_P), refinement_steps times
  void forward(double* x, int from) const;  // x ← L⁻¹ x over columns from … n−1 (columns before done)
  void backward(double* x) const;           // x ← L⁻ᵀ x
  void accumulate(const QpProblem& p, const double* x, std::vector<Vec6>& out) const;  // M⁻¹ Jᵀ x over P
  void accumulateAbs(const QpProblem& p, std::vector<Vec6>& out) const;  // |z_u| + Σ_P |λ_i| |M⁻¹ J_iᵀ|

  ActiveSetSettings settings_;
  int capacity_ = 0;
  std::vector<double> L_;                  // column-major, capacity_ × capacity_
  std::vector<int> passive_;               // row indices in factor order
  std::vector<int> last_;                  // per factor column: last row that may be nonzero
  std::vector<double> inv_diag_;           // per factor column: 1 / L_jj (substitutions multiply)
  // The equality rows are the first n_eq_ of the factor and never leave it. Column j < n_eq_ is
  // zero in rows band_[j]+1 … n_eq_-1 (the equality block's own fill ends at band_[j]); rows
  // from n_eq_ on are inequalities, which fill it down to last_[j]. The substitutions skip the
  // zeros in between (with contacts they are most of a column).
  int n_eq_ = 0;
  bool building_equalities_ = false;  // solve() is appending the equality rows (all of P is E)
  std::vector<int> band_;
  // The right-hand side b_P is fixed within a solve, so the forward substitution over the
  // equality columns is done once: yE_ = L_E⁻¹ b_E, and per passive inequality row (by factor
  // position) gb_ = b − Σ_{j<n_eq} L_·j yE_j, taken in the order a full forward pass would, so
  // solvePassive() gives the same bits while substituting only the inequality columns.
  std::vector<double> yE_, gb_;
  // Some pivot of this solve's factor came out small (a passive row nearly dependent on the
  // others): from then on every passive solve is refined, since the regularisation moves such
  // solutions by more than the active-set tolerance. Well-conditioned solves refine only the
  // final one.
  bool ill_conditioned_ = false;
  static constexpr double kIllPivot = 1e-2;  ///< pivot² / A_kk below this: nearly dependent
  // Equality rows touching each body (CSR over bodies): append() reads A(P_i, k) only where row k
  // shares a body with an equality row, instead of over the whole passive set.
  std::vector<int> eq_start_, eq_rows_, eq_fill_;  // eq_fill_: per-body cursor of indexEqualities
  std::vector<int> hit_pos_, hit_row_;     // append(): the passive equality rows sharing a body
  std::vector<int> position_;              // row -> position in passive_ or -1
  std::vector<unsigned char> blocked_;     // rows that could not enter since the last change
  std::vector<double> s_, lambda_p_, tmp_;
  std::vector<Vec6> dz_;
  std::vector<Vec6> absz_;                 // round-off scale of z (accumulateAbs)
  std::vector<Vec6> kkt_scratch_;
  // polish(): the regularised solver (no polish of its own), its shifted problem and scratch.
  std::unique_ptr<ActiveSetSolver> prox_;
  QpProblem prox_problem_;
  QpSolution prox_sol_;
  std::vector<double> prox_lambda_;
  std::vector<unsigned char> prox_warm_;
};

}  // namespace godhand
