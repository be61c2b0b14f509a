// The Gauss QP (solver/qp.h) solved in the joints' own coordinates, where its equality rows tie
// the bodies into a forest (a hand: every body the child of at most one joint).
//
// Each joint's equality rows J_C z_C + J_P z_P = c (r of them, on the child C and its parent P)
// give the child's motion from its parent's and the joint's free motions:
//   z_C = P_j (c − J_P z_P) + B_j y_j,   P_j a particular solution's map (J_C P_j = I),
//   B_j an orthonormal basis of the null space of J_C,
// so every motion that meets the equality rows is z = N y + z_p, y the roots' six coordinates and
// each joint's 6 − r free ones (a 16-body hand: 26 instead of 96 unknowns and ~70 equality rows).
// The problem left is small and dense:
//   min ½ yᵀ H y + gᵀ y  subject to  a_iᵀ y ≥ d_i   (H = Nᵀ M N, g = Nᵀ M (z_p − z_u)),
// whose dual over the inequality rows, A_ij = a_iᵀ H⁻¹ a_j (H = L Lᵀ factored once), is solved by
// the same Lawson–Hanson active-set scheme as ActiveSetSolver (most violated row enters,
// multipliers that would turn negative leave). A row's slack is a_i·y − d_i, checked against
// the tolerance times its round-off scale |c_i| + |J_i|·|z_p| + |a_i|·|y|. The equality multipliers are recovered
// afterwards from stationarity, leaves first (each joint's r multipliers from its child's force
// balance), so the solution is the same (z, λ) as ActiveSetSolver's, to round-off, and its KKT
// residual is measured the same way (kktResidual on the full problem).
//
// solve() answers only where that holds: equality rows in groups of one (child, parent) pair, a
// forest, each child block of full row rank, H positive definite, the active set converged and the
// full problem's KKT residual within ActiveSetSettings::converged_kkt. Otherwise it returns false
// and leaves the solution to the caller's general solver (ExactSolver below does both).
#pragma once

#include <cstdint>
#include <vector>

#include "solver/active_set.h"
#include "solver/qp.h"

namespace godhand {

class TreeSolver {
 public:
  explicit TreeSolver(ActiveSetSettings settings = {}) : settings_(settings) {}

  /// Sizes every buffer for problems of up to `bodies` bodies and `rows` rows (no allocation in
  /// a solve of such a problem once the structure's own buffers have seen it).
  void reserve(int bodies, int rows);

  /// true with `sol` and `stats` filled where the problem has the structure above and the solve
  /// converged; false otherwise (sol then holds no result).
  bool solve(const QpProblem& problem, QpSolution& sol, const unsigned char* warm_passive, SolveStats* stats);

  /// Unknowns of the last structured problem (the forest's degrees of freedom).
  int coordinates() const { return k_; }

 private:
  struct Group {           // one joint's equality rows
    int child = -1, parent = -1, first = 0, rows = 0;
    Mat6 T = Mat6::Zero();  // z_C = T z_P + q + B y_j, T = −P_j J_P
    Vec6 q = Vec6::Zero();  // P_j c
    Mat3 S = Mat3::Zero();  // the point rows' angular part
    Mat3 L = Mat3::Zero();  // the lock rows' (rows − 3 of them) angular part
    Mat3 G = Mat3::Zero();  // (L Lᵀ)⁻¹
    Mat6 B = Mat6::Zero();  // the first 6 − rows columns: the joint's free motions
  };
  bool structure(const QpProblem& p);
  void lowerSolve(double* x) const;  // x ← L⁻¹ x (L: H's factor, sparse by columns)
  void upperSolve(double* x) const;  // x ← L⁻ᵀ x
  double gram(int i, int j) const;  // A_ij = a_i · H⁻¹ a_j (h_j computed)
  bool append(int i);      // row i into P and its factor; false if it is (nearly) dependent
  bool refactor();         // the factor of A_PP (regularised) from scratch
  void solvePassive();     // s_ = A_PP⁻¹ b_P
  void recoverEqualityMultipliers(const QpProblem& p, QpSolution& sol);

  ActiveSetSettings settings_;
  int k_ = 0;                               // unknowns
  std::vector<int> group_of_child_;         // per body: its group, −1 for a root
  std::vector<Group> groups_;
  std::vector<int> order_, depth_;          // bodies by depth (roots first); per body its depth
  std::vector<int> col_first_, col_count_;  // per body: its own columns
  std::vector<std::vector<int>> cols_;      // per body: every column it depends on (ancestors' and own)
  std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> N_;  // per body: 6 × cols_[b].size()
  std::vector<Vec6> zp_;                    // per body: the particular motion
  Eigen::MatrixXd H_;                       // k × k, then its Cholesky factor L (lower)
  std::vector<int> nz_start_, nz_row_;      // L's nonzeros below the diagonal, by column
  std::vector<double> nz_val_;
  Eigen::MatrixXd A_, Hh_;                  // k × m_I: columns a_i and h_i = H⁻¹ a_i (first L⁻¹ a_i)
  Eigen::VectorXd g_, y0_, y_, absy_;      // g; y0 = −H⁻¹ g; y; |y|
  std::vector<int> ineq_;                   // inequality row indices (their columns in A_, Hh_)
  std::vector<double> d_, b_, scale0_, enorm2_;  // per inequality: d_i, b_i = d_i − a_i·y0, round-off scale, A_ii
  std::vector<int> passive_;                // positions into ineq_
  std::vector<double> lambda_, s_;          // per passive entry
  std::vector<unsigned char> in_passive_, blocked_, have_e_, have_h_;
  std::vector<double> fac_, tmp_;           // the factor of A_PP (fac_ld_ × fac_ld_), scratch
  int fac_ld_ = 0;
  std::vector<Vec6> force_;                 // per body: Σ Jᵀλ of the rows recovered so far
  std::vector<Vec6> kkt_scratch_;
};

/// The exact solver of the pipeline: TreeSolver where the problem is a forest of joints and it
/// converges, ActiveSetSolver (the general one) otherwise. Both give the same solution to
/// round-off; treeSolves() / generalSolves() count which one answered.
class ExactSolver {
 public:
  explicit ExactSolver(ActiveSetSettings settings = {}) : tree_(settings), general_(settings) {}
  void reserve(int bodies, int rows) {
    general_.reserve(bodies, rows);
    tree_.reserve(bodies, rows);
  }
  SolveStats solve(const QpProblem& problem, QpSolution& solution, const unsigned char* warm_passive = nullptr);
  const ActiveSetSettings& settings() const { return general_.settings(); }
  std::uint64_t treeSolves() const { return tree_solves_; }
  std::uint64_t generalSolves() const { return general_solves_; }
  /// Off: every problem goes to ActiveSetSolver (the solver before TreeSolver, for comparison).
  void setTree(bool on) { use_tree_ = on; }

 private:
  TreeSolver tree_;
  ActiveSetSolver general_;
  bool use_tree_ = true;
  std::uint64_t tree_solves_ = 0, general_solves_ = 0;
};

}  // namespace godhand
