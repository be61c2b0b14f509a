// The constrained least-squares problem of Gauss' principle (paper Eq. 5, METHOD.md §2–3):
//
//   z_c = argmin ½ ‖z − z_u‖²_M   subject to   J_E z = c_E,   J_I z ≥ c_I
//
// for N bodies with block-diagonal 6×6 mass matrix M = diag(M_1 … M_N) and m rows, each row
// touching at most two bodies (a joint) or one (a contact, a limit against the world).
//
// The dual (METHOD §3): A = J M⁻¹ Jᵀ, b = c − J z_u,
//   min ½ λᵀ A λ − bᵀ λ   over λ_I ≥ 0, λ_E free;   z = z_u + M⁻¹ Jᵀ λ,
// whose KKT conditions are the slack w = A λ − b = J z − c with w_E = 0, w_I ≥ 0, λ_I ≥ 0,
// λ_I ∘ w_I = 0. A is never formed: its entries A_ik = Σ_b J_i,b · (M_b⁻¹ J_k,bᵀ) are read
// from the rows' blocks (nonzero only where rows share a body), and A x = J (M⁻¹ Jᵀ x).
#pragma once

#include <cstdint>
#include <vector>

#include "math/pose.h"

namespace godhand {

enum class RowType : std::uint8_t { Equality, Inequality };

/// One constraint row J_k z (= or ≥) c_k. Blocks are (linear; angular) in the world frame.
struct Row {
  int body0 = -1;
  int body1 = -1;            ///< -1 when the row touches one body
  Vec6 J0 = Vec6::Zero();
  Vec6 J1 = Vec6::Zero();
  Vec6 W0 = Vec6::Zero();    ///< M⁻¹ J0ᵀ (filled by QpProblem::finalize)
  Vec6 W1 = Vec6::Zero();    ///< M⁻¹ J1ᵀ
  double c = 0.0;
  double b = 0.0;            ///< c − J z_u (finalize)
  double diag = 0.0;         ///< A_kk (finalize)
  RowType type = RowType::Inequality;
  std::uint64_t key = 0;     ///< identity across steps for warm starts (0 = none)
};

/// Problem storage, reused across steps: reset() keeps every buffer's capacity, so a warm
/// problem of the same or smaller size allocates nothing.
class QpProblem {
 public:
  void reset(int num_bodies);
  void reserveRows(int rows) { rows_.reserve(static_cast<size_t>(rows)); }

  /// General SPD 6×6 mass block (inverted with a fixed-size Cholesky).
  void setMass(int body, const Mat6& M);
  /// Rigid-body mass block diag(m I₃, R diag(I) Rᵀ) with its exact inverse.
  void setRigidMass(int body, double mass, const Mat3& R_WB, const Vec3& inertia_B);
  Vec6& unconstrained(int body) { return zu_[static_cast<size_t>(body)]; }

  /// Drops every row, keeping the masses and z_u (a problem assembled again with other rows).
  void clearRows() { rows_.clear(); }
  /// Appends a row; blocks for body1 are ignored when body1 < 0.
  Row& addRow(RowType type, int body0, const Vec6& J0, int body1, const Vec6& J1, double c, std::uint64_t key);
  /// Computes W, b and A_kk of every row. Call once after the last addRow().
  void finalize();

  int numBodies() const { return num_bodies_; }
  int numRows() const { return static_cast<int>(rows_.size()); }
  const Row& row(int k) const { return rows_[static_cast<size_t>(k)]; }
  Row& row(int k) { return rows_[static_cast<size_t>(k)]; }
  const Mat6& mass(int body) const { return M_[static_cast<size_t>(body)]; }
  const Mat6& massInverse(int body) const { return Minv_[static_cast<size_t>(body)]; }
  const Vec6& unconstrained(int body) const { return zu_[static_cast<size_t>(body)]; }
  const Vec6* unconstrainedData() const { return zu_.data(); }

  /// A_ik, from the shared bodies of rows i and k.
  [[gnu::always_inline]] double A(int i, int k) const {
    const Row& a = rows_[static_cast<size_t>(i)];
    const Row& b = rows_[static_cast<size_t>(k)];
    double s = 0.0;
    if (a.body0 == b.body0) s += a.J0.dot(b.W0);
    if (b.body1 >= 0 && a.body0 == b.body1) s += a.J0.dot(b.W1);
    if (a.body1 >= 0) {
      if (a.body1 == b.body0) s += a.J1.dot(b.W0);
      if (b.body1 >= 0 && a.body1 == b.body1) s += a.J1.dot(b.W1);
    }
    return s;
  }
  /// J_k z for per-body accelerations z.
  double rowDot(int k, const Vec6* z) const;
  /// Σ |J_k| |z| (elementwise): the round-off scale of rowDot.
  double rowAbsDot(int k, const Vec6* z) const;

 private:
  int num_bodies_ = 0;
  std::vector<Mat6> M_, Minv_;
  std::vector<Vec6> zu_;
  std::vector<Row> rows_;
};

enum class SolveStatus : std::uint8_t {
  Converged,       ///< KKT conditions hold to the tolerance
  IterationLimit,  ///< the exact solver hit its iteration cap (result usable, not optimal)
  SweepLimit,      ///< PGS ran its fixed sweeps (approximate by design)
  Stalled,         ///< violated rows remain that cannot enter the active set (degenerate,
                   ///< infeasible or conflicting rows, passive-set cap): result used, KKT not met
  NumericalFailure ///< non-finite numbers appeared; the result must not be used
};
const char* toString(SolveStatus s);

struct SolveStats {
  int iterations = 0;          ///< exact: active-set changes; PGS: sweeps
  int active_set_size = 0;     ///< rows with λ ≠ 0 (equalities included)
  double kkt_residual = 0.0;   ///< relative, see KktResidual
  SolveStatus status = SolveStatus::Converged;
};

/// Per-body accelerations and per-row multipliers, sized by the solvers.
struct QpSolution {
  std::vector<Vec6> z;
  std::vector<double> lambda;
  void resize(int bodies, int rows) {
    z.resize(static_cast<size_t>(bodies));
    lambda.resize(static_cast<size_t>(rows));
  }
};

/// Relative violation of each KKT condition (METHOD.md §3). Each row is measured against its own
/// scale s_k = max(|c_k|, |J_k|·(|z_u| + Σ_i |λ_i| |M⁻¹J_iᵀ|)), the round-off scale of computing
/// J_k z with z = z_u + Σ λ_i M⁻¹J_iᵀ (large terms may cancel), so linear and angular rows compare
/// and round-off never reads as a violation:
///   stationarity   ‖M(z − z_u) − Jᵀλ‖∞ / max(‖M(z − z_u)‖∞, ‖Jᵀλ‖∞, ‖M z_u‖∞)
///   primal         max_k viol_k / s_k   (viol = |J z − c| for E, max(0, c − J z) for I)
///   dual           max_k max(0, −λ_k) / ‖λ‖∞ over I
///   complementarity max_k min(λ_k / ‖λ‖∞, slack_k / s_k) over I
struct KktResidual {
  double stationarity = 0, primal = 0, dual = 0, complementarity = 0;
  double max() const;
};
KktResidual kktResidual(const QpProblem& problem, const QpSolution& solution);
/// Same, with caller-owned scratch (two Vec6 per body) so that a warm call allocates nothing.
KktResidual kktResidual(const QpProblem& problem, const QpSolution& solution, std::vector<Vec6>& scratch);

}  // namespace godhand
