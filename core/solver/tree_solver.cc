#include "solver/tree_solver.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

namespace godhand {
namespace {

constexpr double kTiny = 1e-300;
/// A child block J_C whose smallest R pivot is below this fraction of its largest is rank
/// deficient: the group's rows do not fix r directions of the child (not this solver's problem).
constexpr double kRankFloor = 1e-10;
/// Columns one body may depend on (its ancestors' and its own): fixed-size scratch, no
/// allocation per solve. A deeper chain is not this solver's problem.
constexpr int kMaxCols = 16;
/// Inequality rows above which the general solver is faster (see structure()).
constexpr int kMaxRows = 128;

/// In-place Cholesky of the leading n × n block of a (column-major, leading dimension ld):
/// lower triangle L with L Lᵀ = a. false where a pivot is not positive.
bool cholesky(double* a, int n, int ld) {
  constexpr int kMaxDense = 128;
  int nz[kMaxDense];  // the columns p < j of row j that are not zero (a tree's H: j's descendants)
  for (int j = 0; j < n; ++j) {
    double* cj = a + static_cast<size_t>(j) * ld;
    // Zero terms left out: the same sums, in the same order, to the bit (and in O(nonzeros) for
    // H, whose factor has no fill: see structure()). Only where the row fits the list.
    int m = 0;
    const bool sparse = n <= kMaxDense;
    if (sparse)
      for (int p = 0; p < j; ++p)
        if (a[static_cast<size_t>(p) * ld + j] != 0.0) nz[m++] = p;
    double d = cj[j];
    if (sparse)
      for (int k = 0; k < m; ++k) d -= a[static_cast<size_t>(nz[k]) * ld + j] * a[static_cast<size_t>(nz[k]) * ld + j];
    else
      for (int p = 0; p < j; ++p) d -= a[static_cast<size_t>(p) * ld + j] * a[static_cast<size_t>(p) * ld + j];
    if (!(d > 0.0) || !std::isfinite(d)) return false;
    const double l = std::sqrt(d);
    cj[j] = l;
    for (int i = j + 1; i < n; ++i) {
      double s = cj[i];
      if (sparse)
        for (int k = 0; k < m; ++k) s -= a[static_cast<size_t>(nz[k]) * ld + i] * a[static_cast<size_t>(nz[k]) * ld + j];
      else
        for (int p = 0; p < j; ++p) s -= a[static_cast<size_t>(p) * ld + i] * a[static_cast<size_t>(p) * ld + j];
      cj[i] = s / l;
    }
  }
  return true;
}

/// x ← L⁻¹ x, then (if `both`) x ← L⁻ᵀ x, for the factor left by cholesky().
void forwardSolve(const double* a, int n, int ld, double* x) {
  for (int j = 0; j < n; ++j) {
    if (x[j] == 0.0) continue;  // (a tree's rows: zero outside a body's chain)
    x[j] /= a[static_cast<size_t>(j) * ld + j];
    const double xj = x[j];
    for (int i = j + 1; i < n; ++i) x[i] -= a[static_cast<size_t>(j) * ld + i] * xj;
  }
}
void backwardSolve(const double* a, int n, int ld, double* x) {
  for (int j = n - 1; j >= 0; --j) {
    double s = x[j];
    for (int i = j + 1; i < n; ++i) s -= a[static_cast<size_t>(j) * ld + i] * x[i];
    x[j] = s / a[static_cast<size_t>(j) * ld + j];
  }
}

}  // namespace

bool TreeSolver::structure(const QpProblem& p) {
  const int nb = p.numBodies(), m = p.numRows();
  group_of_child_.assign(static_cast<size_t>(nb), -1);
  groups_.clear();
  ineq_.clear();
  for (int k = 0; k < m;) {
    const Row& row = p.row(k);
    if (row.type != RowType::Equality) {
      ineq_.push_back(k);
      ++k;
      continue;
    }
    const int child = row.body0, parent = row.body1;
    if (child < 0 || child >= nb || parent >= nb || parent == child) return false;
    int r = 1;
    while (k + r < m && p.row(k + r).type == RowType::Equality && p.row(k + r).body0 == child && p.row(k + r).body1 == parent)
      ++r;
    if (r > 6 || group_of_child_[static_cast<size_t>(child)] >= 0) return false;
    group_of_child_[static_cast<size_t>(child)] = static_cast<int>(groups_.size());
    Group g;
    g.child = child;
    g.parent = parent;
    g.first = k;
    g.rows = r;
    groups_.push_back(g);
    k += r;
  }
  // Hundreds of inequality rows: the slack scan over every row each active-set change costs more
  // than the general solver's sparse factor (godhand-bench-step: 256 rows 93 µs against 78).
  if (static_cast<int>(ineq_.size()) > kMaxRows) return false;
  // Depth of every body (a cycle or a parent chain longer than the bodies: not a forest).
  order_.clear();
  depth_.assign(static_cast<size_t>(nb), -1);
  for (int b = 0; b < nb; ++b) {
    int d = 0, x = b;
    while (group_of_child_[static_cast<size_t>(x)] >= 0) {
      x = groups_[static_cast<size_t>(group_of_child_[static_cast<size_t>(x)])].parent;
      if (x < 0) break;
      if (++d > nb) return false;
    }
    depth_[static_cast<size_t>(b)] = d;
  }
  for (int d = 0; d <= nb; ++d)
    for (int b = 0; b < nb; ++b)
      if (depth_[static_cast<size_t>(b)] == d) order_.push_back(b);
  if (static_cast<int>(order_.size()) != nb) return false;

  // Each group's child block is a joint's: three point rows [I  S] (S: the angular part) and
  // r − 3 lock rows [0  L]. Its free motions are ω ∈ null(L) with v = −S ω (B = [−S W; W], W an
  // orthonormal basis of null(L)), and one particular solution of J_C z = v is
  // ω = Lᵀ (L Lᵀ)⁻¹ v_lock, v = v_point − S ω (P below, z = P v). Other blocks: not a joint's.
  // A group's rows: their parent blocks (zero for a root's child) and right-hand sides.
  auto parentRows = [&](const Group& g, auto* JP, auto* c) {
    for (int i = 0; i < g.rows; ++i) {
      const Row& row = p.row(g.first + i);
      if (g.parent >= 0) JP->row(i) = row.J1.transpose();
      else JP->row(i).setZero();
      (*c)[i] = row.c;
    }
  };
  // The maps of a group of nl = 1 or 2 lock rows (a two-axis and a one-axis joint: every joint
  // of the hand models) with fixed-size matrices, in the general code's order of arithmetic (the
  // results equal to the bit: a lock row's norm is taken from g.L's strided row, as it was).
  auto fixedMaps = [&](auto nl_c, Group& g) -> bool {
    constexpr int NL = decltype(nl_c)::value;
    constexpr int R = 3 + NL, F = 3 - NL;
    const Eigen::Matrix<double, NL, 3> L = g.L.template topRows<NL>();
    using Small = Eigen::Matrix<double, NL, NL>;
    const Small LLt = g.L.template topRows<NL>() * g.L.template topRows<NL>().transpose();
    const Eigen::LDLT<Small> f(LLt);
    const double scale = LLt.diagonal().maxCoeff();
    if (!(scale > 0.0) || f.vectorD().minCoeff() <= kRankFloor * scale) return false;
    const Eigen::Matrix<double, NL, NL> G = f.solve(Small::Identity());
    g.G.setZero();
    g.G.template topLeftCorner<NL, NL>() = G;
    Eigen::Matrix<double, 3, F> W;
    if constexpr (NL == 1) {
      const Vec3 l = g.L.row(0).transpose().normalized();
      const Vec3 a = std::abs(l.x()) < 0.6 ? Vec3::UnitX() : (std::abs(l.y()) < 0.6 ? Vec3::UnitY() : Vec3::UnitZ());
      const Vec3 w0 = l.cross(a).normalized();
      W.col(0) = w0;
      W.col(1) = l.cross(w0);
    } else {
      const Vec3 w = g.L.row(0).transpose().cross(g.L.row(1).transpose());
      if (!(w.norm() > 0.0)) return false;
      W.col(0) = w.normalized();
    }
    g.B.setZero();
    g.B.template topLeftCorner<3, F>() = -g.S * W;
    g.B.template bottomLeftCorner<3, F>() = W;
    Eigen::Matrix<double, 6, R> P = Eigen::Matrix<double, 6, R>::Zero();
    P.template topLeftCorner<3, 3>().setIdentity();
    const Eigen::Matrix<double, 3, NL> LtG = L.transpose() * G;
    P.template block<3, NL>(0, 3) = -g.S * LtG;
    P.template block<3, NL>(3, 3) = LtG;
    Eigen::Matrix<double, R, 6> JP;
    Eigen::Matrix<double, R, 1> c;
    parentRows(g, &JP, &c);
    g.T = -P * JP;
    g.q = P * c;
    return true;
  };
  for (Group& g : groups_) {
    if (g.rows < 3) return false;
    for (int i = 0; i < g.rows; ++i) {
      const Vec6& J = p.row(g.first + i).J0;
      for (int a = 0; a < 3; ++a)
        if (J[a] != (i == a ? 1.0 : 0.0)) return false;
    }
    for (int a = 0; a < 3; ++a) g.S.row(a) = p.row(g.first + a).J0.tail<3>().transpose();
    const int nl = g.rows - 3;
    g.L.setZero();
    for (int i = 0; i < nl; ++i) g.L.row(i) = p.row(g.first + 3 + i).J0.tail<3>().transpose();
    if (nl == 1 || nl == 2) {
      if (!(nl == 1 ? fixedMaps(std::integral_constant<int, 1>{}, g) : fixedMaps(std::integral_constant<int, 2>{}, g)))
        return false;
      continue;
    }
    g.G.setZero();
    Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, 3> W(3, 3 - nl);
    if (nl > 0) {
      const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3> LLt =
          g.L.topRows(nl) * g.L.topRows(nl).transpose();
      const Eigen::LDLT<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>> f(LLt);
      const double scale = LLt.diagonal().maxCoeff();
      if (!(scale > 0.0) || f.vectorD().minCoeff() <= kRankFloor * scale) return false;
      g.G.topLeftCorner(nl, nl) = f.solve(Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>::Identity(nl, nl));
    }
    // (Here nl is 0, a point joint, or 3, a weld: one or two lock rows took fixedMaps above.)
    if (nl == 0) W.setIdentity();
    const int free = 3 - nl;
    g.B.setZero();
    if (free > 0) {
      g.B.topLeftCorner(3, free) = -g.S * W;
      g.B.bottomLeftCorner(3, free) = W;
    }
    // P (6 × r): the particular solution's map; T = −P J_P, q = P c.
    Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6> P(6, g.rows);
    P.setZero();
    P.topLeftCorner(3, 3).setIdentity();
    if (nl > 0) {
      const Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, 3> LtG = g.L.topRows(nl).transpose() * g.G.topLeftCorner(nl, nl);
      P.block(0, 3, 3, nl) = -g.S * LtG;
      P.block(3, 3, 3, nl) = LtG;
    }
    Eigen::Matrix<double, Eigen::Dynamic, 6, 0, 6, 6> JP(g.rows, 6);
    Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1> c(g.rows);
    parentRows(g, &JP, &c);
    g.T = -P * JP;
    g.q = P * c;
  }

  // Columns: the roots' six and each joint's free directions, numbered in postorder (every body
  // after its descendants): H = Nᵀ M N then factors without fill (a column couples only with
  // its ancestors'), and a row's a_i (nonzero at its body's and its ancestors' columns) keeps
  // its substitutions to them.
  k_ = 0;
  col_first_.assign(static_cast<size_t>(nb), 0);
  col_count_.assign(static_cast<size_t>(nb), 0);
  for (int b = 0; b < nb; ++b) {
    const int gi = group_of_child_[static_cast<size_t>(b)];
    col_count_[static_cast<size_t>(b)] = gi < 0 ? 6 : 6 - groups_[static_cast<size_t>(gi)].rows;
  }
  // Deepest first is a postorder of every tree (a body's descendants are deeper).
  for (int idx = nb - 1; idx >= 0; --idx) {
    const int b = order_[static_cast<size_t>(idx)];
    col_first_[static_cast<size_t>(b)] = k_;
    k_ += col_count_[static_cast<size_t>(b)];
  }
  if (k_ == 0) return false;
  cols_.resize(static_cast<size_t>(nb));
  N_.resize(static_cast<size_t>(nb));
  zp_.resize(static_cast<size_t>(nb));
  for (int b : order_) {
    const size_t bi = static_cast<size_t>(b);
    const int gi = group_of_child_[bi];
    std::vector<int>& cols = cols_[bi];
    cols.clear();
    const int own = col_count_[bi];
    if (gi < 0) {
      for (int c = 0; c < 6; ++c) cols.push_back(col_first_[bi] + c);
      N_[bi].setIdentity(6, 6);
      zp_[bi].setZero();
      continue;
    }
    const Group& g = groups_[static_cast<size_t>(gi)];
    const int inherited = g.parent >= 0 ? static_cast<int>(cols_[static_cast<size_t>(g.parent)].size()) : 0;
    if (inherited + own > kMaxCols) return false;
    // Own columns first, then the ancestors' (all numbered after them): ascending.
    for (int c = 0; c < own; ++c) cols.push_back(col_first_[bi] + c);
    if (g.parent >= 0) cols.insert(cols.end(), cols_[static_cast<size_t>(g.parent)].begin(), cols_[static_cast<size_t>(g.parent)].end());
    N_[bi].resize(6, inherited + own);
    N_[bi].leftCols(own) = g.B.leftCols(own);
    if (g.parent >= 0) {
      N_[bi].rightCols(inherited).noalias() = g.T * N_[static_cast<size_t>(g.parent)];
      zp_[bi] = g.T * zp_[static_cast<size_t>(g.parent)] + g.q;
    } else {
      zp_[bi] = g.q;
    }
  }
  return true;
}

void TreeSolver::lowerSolve(double* x) const {
  for (int j = 0; j < k_; ++j) {
    if (x[j] == 0.0) continue;
    x[j] /= H_(j, j);
    const double xj = x[j];
    for (int e = nz_start_[static_cast<size_t>(j)]; e < nz_start_[static_cast<size_t>(j) + 1]; ++e)
      x[nz_row_[static_cast<size_t>(e)]] -= nz_val_[static_cast<size_t>(e)] * xj;
  }
}

void TreeSolver::upperSolve(double* x) const {
  for (int j = k_ - 1; j >= 0; --j) {
    double v = x[j];
    for (int e = nz_start_[static_cast<size_t>(j)]; e < nz_start_[static_cast<size_t>(j) + 1]; ++e)
      v -= nz_val_[static_cast<size_t>(e)] * x[nz_row_[static_cast<size_t>(e)]];
    x[j] = v / H_(j, j);
  }
}

double TreeSolver::gram(int i, int j) const { return A_.col(i).head(k_).dot(Hh_.col(j).head(k_)); }

void TreeSolver::reserve(int bodies, int rows) {
  const Eigen::Index kcap = 6 * std::max(1, bodies), rcap = std::max(1, rows);
  if (A_.rows() < kcap || A_.cols() < rcap) {
    A_.resize(std::max(A_.rows(), kcap), std::max(A_.cols(), rcap));
    Hh_.resize(A_.rows(), A_.cols());
  }
  if (fac_ld_ < rows) {
    fac_ld_ = rows;
    fac_.resize(static_cast<size_t>(fac_ld_) * static_cast<size_t>(fac_ld_));
    tmp_.resize(static_cast<size_t>(fac_ld_));
  }
  // The per-inequality-row buffers, for any count up to `rows` (the projection's iterations take
  // fewer rows than its first: StepParams::projection_row_reach).
  const size_t r = static_cast<size_t>(rcap);
  for (std::vector<double>* v : {&d_, &b_, &scale0_, &enorm2_, &lambda_, &s_}) v->reserve(r);
  for (std::vector<unsigned char>* v : {&in_passive_, &blocked_, &have_e_, &have_h_}) v->reserve(r);
  ineq_.reserve(r);
  passive_.reserve(r);
}

bool TreeSolver::refactor() {
  const int n = static_cast<int>(passive_.size());
  const int ld = fac_ld_;
  for (int j = 0; j < n; ++j)
    for (int i = j; i < n; ++i) {
      double v = gram(passive_[static_cast<size_t>(i)], passive_[static_cast<size_t>(j)]);
      if (i == j) v += settings_.regularization * v;
      fac_[static_cast<size_t>(j) * ld + i] = v;
    }
  return cholesky(fac_.data(), n, ld);
}

bool TreeSolver::append(int i) {
  const int n = static_cast<int>(passive_.size());
  const int ld = fac_ld_;
  double* F = fac_.data();
  double* row = tmp_.data();
  for (int p = 0; p < n; ++p) row[p] = gram(passive_[static_cast<size_t>(p)], i);
  forwardSolve(F, n, ld, row);
  double d = gram(i, i);
  d += settings_.regularization * d;
  double sq = 0.0;
  for (int p = 0; p < n; ++p) sq += row[p] * row[p];
  const double pivot = d - sq;
  if (!(pivot > 1e-14 * d)) return false;
  for (int p = 0; p < n; ++p) F[static_cast<size_t>(p) * ld + n] = row[p];
  F[static_cast<size_t>(n) * ld + n] = std::sqrt(pivot);
  passive_.push_back(i);
  in_passive_[static_cast<size_t>(i)] = 1;
  return true;
}

void TreeSolver::solvePassive() {
  const int n = static_cast<int>(passive_.size());
  s_.resize(static_cast<size_t>(n));
  for (int j = 0; j < n; ++j) s_[static_cast<size_t>(j)] = b_[static_cast<size_t>(passive_[static_cast<size_t>(j)])];
  forwardSolve(fac_.data(), n, fac_ld_, s_.data());
  backwardSolve(fac_.data(), n, fac_ld_, s_.data());
}

void TreeSolver::recoverEqualityMultipliers(const QpProblem& p, QpSolution& sol) {
  const int nb = p.numBodies();
  force_.assign(static_cast<size_t>(nb), Vec6::Zero());
  for (int k : ineq_) {
    const Row& row = p.row(k);
    const double l = sol.lambda[static_cast<size_t>(k)];
    if (l == 0.0) continue;
    force_[static_cast<size_t>(row.body0)] += l * row.J0;
    if (row.body1 >= 0) force_[static_cast<size_t>(row.body1)] += l * row.J1;
  }
  // Leaves first: a joint's multipliers balance its child's force, J_Cᵀ λ = M_C (z_C − z_u,C) − (the rest).
  for (int idx = nb - 1; idx >= 0; --idx) {
    const int b = order_[static_cast<size_t>(idx)];
    const int gi = group_of_child_[static_cast<size_t>(b)];
    if (gi < 0) continue;
    const Group& g = groups_[static_cast<size_t>(gi)];
    const Vec6 res = p.mass(b) * (sol.z[static_cast<size_t>(b)] - p.unconstrained(b)) - force_[static_cast<size_t>(b)];
    // J_Cᵀ λ = res: λ_point = res_linear, Lᵀ λ_lock = res_angular − Sᵀ λ_point (least squares).
    Eigen::Matrix<double, 6, 1> l = Eigen::Matrix<double, 6, 1>::Zero();
    l.head<3>() = res.head<3>();
    const int nl = g.rows - 3;
    if (nl > 0) {
      const Vec3 rest = res.tail<3>() - g.S.transpose() * res.head<3>();
      l.segment(3, nl) = g.G.topLeftCorner(nl, nl) * (g.L.topRows(nl) * rest);
    }
    for (int i = 0; i < g.rows; ++i) {
      const Row& row = p.row(g.first + i);
      sol.lambda[static_cast<size_t>(g.first + i)] = l[i];
      if (g.parent >= 0) force_[static_cast<size_t>(g.parent)] += l[i] * row.J1;
    }
  }
}

bool TreeSolver::solve(const QpProblem& p, QpSolution& sol, const unsigned char* warm_passive, SolveStats* stats) {
  if (!structure(p)) return false;
  const int nb = p.numBodies(), m = p.numRows(), k = k_;
  const int mi = static_cast<int>(ineq_.size());

  // H = Σ N_bᵀ M_b N_b and g = Σ N_bᵀ M_b (z_p − z_u), over each body's own columns.
  H_.setZero(k, k);
  g_.setZero(k);
  for (int b = 0; b < nb; ++b) {
    const size_t bi = static_cast<size_t>(b);
    const std::vector<int>& cols = cols_[bi];
    const int nc = static_cast<int>(cols.size());
    const Mat6& M = p.mass(b);
    const Vec6 dz = zp_[bi] - p.unconstrained(b);
    double MN[6 * kMaxCols];
    for (int j = 0; j < nc; ++j) {
      const Vec6 v = M * N_[bi].col(j);
      for (int r = 0; r < 6; ++r) MN[6 * j + r] = v[r];
    }
    for (int j = 0; j < nc; ++j) {
      const double* mj = MN + 6 * j;
      double gj = 0.0;
      for (int r = 0; r < 6; ++r) gj += mj[r] * dz[r];
      g_[cols[static_cast<size_t>(j)]] += gj;
      double* Hc = H_.data() + static_cast<size_t>(cols[static_cast<size_t>(j)]) * k;
      for (int i = j; i < nc; ++i) {
        const double* ni = N_[bi].col(i).data();
        double v = 0.0;
        for (int r = 0; r < 6; ++r) v += ni[r] * mj[r];
        Hc[cols[static_cast<size_t>(i)]] += v;  // lower triangle (cols are increasing)
      }
    }
  }
  if (!cholesky(H_.data(), k, k)) return false;
  // L's nonzeros below the diagonal, per column (a column's ancestors': no fill in postorder).
  nz_start_.resize(static_cast<size_t>(k) + 1);
  nz_row_.clear();
  nz_val_.clear();
  for (int j = 0; j < k; ++j) {
    nz_start_[static_cast<size_t>(j)] = static_cast<int>(nz_row_.size());
    for (int i = j + 1; i < k; ++i) {
      const double v = H_(i, j);
      if (v != 0.0) {
        nz_row_.push_back(i);
        nz_val_.push_back(v);
      }
    }
  }
  nz_start_[static_cast<size_t>(k)] = static_cast<int>(nz_row_.size());

  // Inequality rows in y: a_i·y ≥ d_i.
  // (Storage grows to the most rows seen and is then reused: no allocation per solve.)
  if (A_.rows() < k || A_.cols() < mi) {  // (reserve() sizes them for the largest problem)
    A_.resize(std::max<Eigen::Index>(A_.rows(), k), std::max<Eigen::Index>(std::max(1, mi), 2 * A_.cols()));
    Hh_.resize(A_.rows(), A_.cols());
  }
  if (fac_ld_ < mi) {
    fac_ld_ = std::max(mi, 2 * fac_ld_);
    fac_.resize(static_cast<size_t>(fac_ld_) * static_cast<size_t>(fac_ld_));
    tmp_.resize(static_cast<size_t>(fac_ld_));
  }
  A_.topLeftCorner(k, mi).setZero();
  d_.resize(static_cast<size_t>(mi));
  b_.resize(static_cast<size_t>(mi));
  scale0_.resize(static_cast<size_t>(mi));
  enorm2_.resize(static_cast<size_t>(mi));
  for (int i = 0; i < mi; ++i) {
    const Row& row = p.row(ineq_[static_cast<size_t>(i)]);
    double d = row.c, sc = std::abs(row.c);
    auto add = [&](int body, const Vec6& J) {
      const size_t bi = static_cast<size_t>(body);
      const std::vector<int>& cols = cols_[bi];
      for (size_t j = 0; j < cols.size(); ++j) A_(cols[j], i) += N_[bi].col(static_cast<Eigen::Index>(j)).dot(J);
      d -= J.dot(zp_[bi]);
      sc += J.cwiseAbs().dot(zp_[bi].cwiseAbs());
    };
    if (row.body0 < 0 || row.body0 >= nb || row.body1 >= nb) return false;
    add(row.body0, row.J0);
    if (row.body1 >= 0) add(row.body1, row.J1);
    d_[static_cast<size_t>(i)] = d;
    scale0_[static_cast<size_t>(i)] = std::max(sc, std::abs(row.c - row.b));
  }
  // y0 = −H⁻¹ g; h_i = H⁻¹ a_i only for the rows found violated (the Gram entries a_i·h_j), so
  // y = y0 + Σ_P λ_p h_p, the slacks a_i·y − d_i and b_i = d_i − a_i·y0.
  have_h_.assign(static_cast<size_t>(mi), 0);
  y0_ = -g_;
  lowerSolve(y0_.data());
  upperSolve(y0_.data());
  for (int i = 0; i < mi; ++i) b_[static_cast<size_t>(i)] = d_[static_cast<size_t>(i)] - A_.col(i).head(k).dot(y0_);
  // e_i = L⁻¹ a_i (|e_i|² = A_ii, the entering score's scale) for the rows found violated, and
  // h_i = L⁻ᵀ e_i for the rows that enter.
  have_e_.assign(static_cast<size_t>(mi), 0);
  auto ensureE = [&](int i) {
    if (have_e_[static_cast<size_t>(i)]) return;
    Hh_.col(i).head(k) = A_.col(i).head(k);
    lowerSolve(Hh_.col(i).data());
    enorm2_[static_cast<size_t>(i)] = Hh_.col(i).head(k).squaredNorm();
    have_e_[static_cast<size_t>(i)] = 1;
  };
  auto ensureH = [&](int i) {
    if (have_h_[static_cast<size_t>(i)]) return;
    ensureE(i);
    upperSolve(Hh_.col(i).data());
    have_h_[static_cast<size_t>(i)] = 1;
  };

  // Lawson–Hanson on the dual (see ActiveSetSolver): the warm rows first, then the most violated.
  passive_.clear();
  lambda_.clear();
  in_passive_.assign(static_cast<size_t>(mi), 0);
  blocked_.assign(static_cast<size_t>(mi), 0);
  auto dropAt = [&](int j) {
    in_passive_[static_cast<size_t>(passive_[static_cast<size_t>(j)])] = 0;
    passive_.erase(passive_.begin() + j);
    if (static_cast<int>(lambda_.size()) > j) lambda_.erase(lambda_.begin() + j);
  };
  if (warm_passive) {
    for (int i = 0; i < mi; ++i)
      if (warm_passive[ineq_[static_cast<size_t>(i)]]) {
        ensureH(i);
        append(i);  // (a row dependent on the warm ones is left out: it may enter below)
      }
    while (!passive_.empty()) {
      solvePassive();
      bool dropped = false;
      for (int j = static_cast<int>(passive_.size()) - 1; j >= 0; --j)
        if (s_[static_cast<size_t>(j)] <= 0.0) {
          dropAt(j);
          dropped = true;
        }
      if (!dropped) {
        lambda_.assign(s_.begin(), s_.end());
        break;
      }
      if (!refactor()) return false;
    }
  }
  const int max_iter = settings_.max_iterations > 0 ? settings_.max_iterations : 3 * m + 50;
  int iterations = 0;
  bool converged = false;
  for (;;) {
    y_ = y0_;
    for (size_t j = 0; j < passive_.size(); ++j) y_ += lambda_[j] * Hh_.col(passive_[j]).head(k);
    absy_ = y_.cwiseAbs();
    int enter = -1;
    double best = 0.0;
    bool blocked_violated = false;
    for (int i = 0; i < mi; ++i) {
      if (in_passive_[static_cast<size_t>(i)]) continue;
      const double w = A_.col(i).head(k).dot(y_) - d_[static_cast<size_t>(i)];
      if (w >= 0.0) continue;
      const double scale = std::max({scale0_[static_cast<size_t>(i)] + A_.col(i).head(k).cwiseAbs().dot(absy_), kTiny});
      if (!(w < -settings_.tolerance * scale)) continue;
      if (blocked_[static_cast<size_t>(i)]) {
        blocked_violated = true;
        continue;
      }
      ensureE(i);
      const double score = w / std::sqrt(std::max(enorm2_[static_cast<size_t>(i)], kTiny));
      if (enter < 0 || score < best) {
        enter = i;
        best = score;
      }
    }
    if (enter < 0) {
      converged = !blocked_violated;
      break;
    }
    // A degenerate vertex (a row dependent on the passive ones, or the active set cycling past
    // a few changes per unknown) is the general solver's (regularised, blocked rows): give up
    // early rather than spend its time twice.
    if (++iterations > std::min(max_iter, 2 * k + 16)) return false;
    ensureH(enter);
    if (!append(enter)) return false;
    lambda_.push_back(0.0);
    for (int inner = 0; inner <= mi; ++inner) {
      solvePassive();
      const int n = static_cast<int>(passive_.size());
      double alpha = 1.0;
      int hit = -1;
      for (int j = 0; j < n; ++j) {
        if (s_[static_cast<size_t>(j)] > 0.0) continue;
        const double lj = lambda_[static_cast<size_t>(j)];
        const double den = lj - s_[static_cast<size_t>(j)];
        const double a = den > 0.0 ? lj / den : 0.0;
        if (hit < 0 || a < alpha) {
          alpha = a;
          hit = j;
        }
      }
      if (hit < 0) {
        lambda_.assign(s_.begin(), s_.end());
        break;
      }
      double lmax = kTiny;
      for (int j = 0; j < n; ++j) {
        double& lj = lambda_[static_cast<size_t>(j)];
        lj += alpha * (s_[static_cast<size_t>(j)] - lj);
        lmax = std::max(lmax, std::abs(lj));
      }
      for (int j = n - 1; j >= 0; --j)
        if (j == hit || lambda_[static_cast<size_t>(j)] <= 1e-15 * lmax) dropAt(j);
      if (!refactor()) return false;
    }
    if (!in_passive_[static_cast<size_t>(enter)]) blocked_[static_cast<size_t>(enter)] = 1;
    else std::fill(blocked_.begin(), blocked_.end(), static_cast<unsigned char>(0));
  }
  if (!converged) return false;
  // One step of iterative refinement against the unregularised A_PP (as ActiveSetSolver): the
  // regularisation moves the passive rows' slacks by ~ε λ A_kk; kept while every λ stays positive.
  if (!passive_.empty()) {
    const int n = static_cast<int>(passive_.size());
    std::vector<double>& r = s_;
    r.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      double ax = 0.0;
      for (int j = 0; j < n; ++j) ax += gram(passive_[static_cast<size_t>(i)], passive_[static_cast<size_t>(j)]) * lambda_[static_cast<size_t>(j)];
      r[static_cast<size_t>(i)] = b_[static_cast<size_t>(passive_[static_cast<size_t>(i)])] - ax;
    }
    forwardSolve(fac_.data(), n, fac_ld_, r.data());
    backwardSolve(fac_.data(), n, fac_ld_, r.data());
    bool positive = true;
    for (int i = 0; i < n; ++i) positive = positive && lambda_[static_cast<size_t>(i)] + r[static_cast<size_t>(i)] > 0.0;
    if (positive)
      for (int i = 0; i < n; ++i) lambda_[static_cast<size_t>(i)] += r[static_cast<size_t>(i)];
    y_ = y0_;
    for (size_t j = 0; j < passive_.size(); ++j) y_ += lambda_[j] * Hh_.col(passive_[j]).head(k);
  }

  // z = N y + z_p (y_ is the final u's), the multipliers, the full problem's KKT residual.
  sol.resize(nb, m);
  for (int b = 0; b < nb; ++b) {
    const size_t bi = static_cast<size_t>(b);
    const std::vector<int>& cols = cols_[bi];
    Vec6 z = zp_[bi];
    for (size_t j = 0; j < cols.size(); ++j) z += N_[bi].col(static_cast<Eigen::Index>(j)) * y_[cols[j]];
    sol.z[bi] = z;
  }
  std::fill(sol.lambda.begin(), sol.lambda.begin() + m, 0.0);
  int active = 0;
  for (size_t j = 0; j < passive_.size(); ++j) {
    sol.lambda[static_cast<size_t>(ineq_[static_cast<size_t>(passive_[j])])] = lambda_[j];
    if (lambda_[j] != 0.0) ++active;
  }
  recoverEqualityMultipliers(p, sol);
  for (int r = 0; r < m; ++r)
    if (p.row(r).type == RowType::Equality) ++active;
  bool finite = true;
  for (int b = 0; b < nb; ++b) finite = finite && sol.z[static_cast<size_t>(b)].allFinite();
  const double kkt = kktResidual(p, sol, kkt_scratch_).max();
  if (!finite || !(kkt <= settings_.converged_kkt)) return false;
  // The residual's round-off scale grows with |λ|: on an ill-posed problem (rows that no motion
  // meets, e.g. push-outs along opposite normals of one body) multipliers of 1e13 made a row
  // violated by a sixth of its own size read as 2e-7. Each row is also held to its own terms,
  // |c| and |J||z|, and otherwise the general solver answers (and says how far it got).
  for (int r = 0; r < m; ++r) {
    const Row& row = p.row(r);
    const Vec6& z0 = sol.z[static_cast<size_t>(row.body0)];
    double jz = row.J0.dot(z0), sk = row.J0.cwiseAbs().dot(z0.cwiseAbs());
    if (row.body1 >= 0) {
      const Vec6& z1 = sol.z[static_cast<size_t>(row.body1)];
      jz += row.J1.dot(z1);
      sk += row.J1.cwiseAbs().dot(z1.cwiseAbs());
    }
    const double slack = jz - row.c;
    const double viol = row.type == RowType::Equality ? std::abs(slack) : std::max(0.0, -slack);
    if (viol > settings_.converged_kkt * std::max({std::abs(row.c), sk, 1e-300})) return false;
  }
  stats->iterations = iterations;
  stats->active_set_size = active;
  stats->kkt_residual = kkt;
  stats->status = SolveStatus::Converged;
  return true;
}

SolveStats ExactSolver::solve(const QpProblem& problem, QpSolution& solution, const unsigned char* warm_passive) {
  SolveStats stats;
  if (use_tree_ && tree_.solve(problem, solution, warm_passive, &stats)) {
    ++tree_solves_;
    return stats;
  }
  ++general_solves_;
  return general_.solve(problem, solution, warm_passive);
}

}  // namespace godhand
