#include "solver/active_set.h"

#include <algorithm>
#include <cmath>
#include <limits>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace godhand {

namespace {
constexpr double kTiny = 1e-300;
// x[i] -= col[i] * xj for i = lo … hi: each entry on its own (one product, one difference, as a
// scalar loop computes them), two at a time where SSE2 is there (baseline x86-64; no FMA),
// eight per round.
[[gnu::always_inline]] inline void subScaled(double* x, const double* col, double xj, int lo, int hi) {
  int i = lo;
#if defined(__SSE2__)
  const __m128d v = _mm_set1_pd(xj);
  for (; i + 7 <= hi; i += 8) {
    const __m128d a = _mm_sub_pd(_mm_loadu_pd(x + i), _mm_mul_pd(_mm_loadu_pd(col + i), v));
    const __m128d b = _mm_sub_pd(_mm_loadu_pd(x + i + 2), _mm_mul_pd(_mm_loadu_pd(col + i + 2), v));
    const __m128d c = _mm_sub_pd(_mm_loadu_pd(x + i + 4), _mm_mul_pd(_mm_loadu_pd(col + i + 4), v));
    const __m128d d = _mm_sub_pd(_mm_loadu_pd(x + i + 6), _mm_mul_pd(_mm_loadu_pd(col + i + 6), v));
    _mm_storeu_pd(x + i, a);
    _mm_storeu_pd(x + i + 2, b);
    _mm_storeu_pd(x + i + 4, c);
    _mm_storeu_pd(x + i + 6, d);
  }
  if (i + 3 <= hi) {
    const __m128d a = _mm_sub_pd(_mm_loadu_pd(x + i), _mm_mul_pd(_mm_loadu_pd(col + i), v));
    const __m128d b = _mm_sub_pd(_mm_loadu_pd(x + i + 2), _mm_mul_pd(_mm_loadu_pd(col + i + 2), v));
    _mm_storeu_pd(x + i, a);
    _mm_storeu_pd(x + i + 2, b);
    i += 4;
  }
  if (i + 1 <= hi) {
    _mm_storeu_pd(x + i, _mm_sub_pd(_mm_loadu_pd(x + i), _mm_mul_pd(_mm_loadu_pd(col + i), v)));
    i += 2;
  }
  if (i <= hi) x[i] -= col[i] * xj;
#else
  for (; i <= hi; ++i) x[i] -= col[i] * xj;
#endif
}
// acc − Σ col[i] x[i] over i = lo … hi. The sum is split over four partial sums (two SSE2
// registers of two lanes) so that the products do not wait on one long chain of additions; the
// order is fixed by lo and hi alone, so the bits are the same on every run and in every process.
[[gnu::always_inline]] inline double subDot(double acc, const double* col, const double* x, int lo, int hi) {
  int i = lo;
#if defined(__SSE2__)
  __m128d s0 = _mm_setzero_pd(), s1 = _mm_setzero_pd();
  for (; i + 3 <= hi; i += 4) {
    s0 = _mm_add_pd(s0, _mm_mul_pd(_mm_loadu_pd(col + i), _mm_loadu_pd(x + i)));
    s1 = _mm_add_pd(s1, _mm_mul_pd(_mm_loadu_pd(col + i + 2), _mm_loadu_pd(x + i + 2)));
  }
  if (i + 1 <= hi) {
    s0 = _mm_add_pd(s0, _mm_mul_pd(_mm_loadu_pd(col + i), _mm_loadu_pd(x + i)));
    i += 2;
  }
  s0 = _mm_add_pd(s0, s1);
  double sum = _mm_cvtsd_f64(s0) + _mm_cvtsd_f64(_mm_unpackhi_pd(s0, s0));
  if (i <= hi) sum += col[i] * x[i];
  return acc - sum;
#else
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
  for (; i + 3 <= hi; i += 4) {
    s0 += col[i] * x[i];
    s1 += col[i + 1] * x[i + 1];
    s2 += col[i + 2] * x[i + 2];
    s3 += col[i + 3] * x[i + 3];
  }
  if (i + 1 <= hi) {
    s0 += col[i] * x[i];
    s1 += col[i + 1] * x[i + 1];
    i += 2;
  }
  double sum = (s0 + s2) + (s1 + s3);
  if (i <= hi) sum += col[i] * x[i];
  return acc - sum;
#endif
}
constexpr double kNoiseUlps = 4.0 * std::numeric_limits<double>::epsilon();  // round-off floor of a slack
template <class V>
void growTo(V& v, size_t n) {
  if (v.size() < n) v.resize(n);
}
}  // namespace

void ActiveSetSolver::reserve(int bodies, int rows) {
  const int cap_limit = settings_.max_passive > 0 ? settings_.max_passive : 12 * bodies + 128;
  const int want = std::min(rows, cap_limit);
  if (want > capacity_) {
    // Grow geometrically (up to the cap) so that slowly rising contact counts reallocate rarely.
    capacity_ = std::min(cap_limit, std::max(want, capacity_ + capacity_ / 2));
    L_.assign(static_cast<size_t>(capacity_) * static_cast<size_t>(capacity_), 0.0);
    passive_.reserve(static_cast<size_t>(capacity_));
    last_.assign(static_cast<size_t>(capacity_), 0);
    inv_diag_.assign(static_cast<size_t>(capacity_), 0.0);
    band_.assign(static_cast<size_t>(capacity_), 0);
  }
  const size_t m = static_cast<size_t>(rows);
  growTo(position_, m);
  growTo(blocked_, m);
  growTo(s_, m);
  growTo(lambda_p_, m);
  growTo(tmp_, m);
  growTo(yE_, m);
  growTo(gb_, m);
  growTo(eq_rows_, 2 * m);
  growTo(hit_pos_, 2 * m);
  growTo(hit_row_, 2 * m);
  growTo(eq_start_, static_cast<size_t>(bodies) + 1);
  growTo(eq_fill_, static_cast<size_t>(bodies));
  growTo(dz_, static_cast<size_t>(bodies));
  growTo(absz_, static_cast<size_t>(bodies));
  growTo(kkt_scratch_, 2 * static_cast<size_t>(bodies));
}

bool ActiveSetSolver::append(const QpProblem& p, int k) {
  const Row& row = p.row(k);
  if (!(row.diag > 0.0) || !std::isfinite(row.diag)) return false;
  if (static_cast<int>(passive_.size()) >= capacity_) return false;  // passive-set cap reached
  const size_t cap = static_cast<size_t>(capacity_);
  const int n = static_cast<int>(passive_.size());
  double* L = L_.data();
  double* x = tmp_.data();
  // l = L⁻¹ a with a_i = A(P_i, k): column-oriented forward substitution skipping zeros. A(P_i, k)
  // is zero unless the rows share a body: equality rows are found through their bodies, the
  // (few) passive inequality rows are all read.
  // x is zero above its first nonzero entry (`first`), and so is its substitution: the loops
  // below start there. Equality rows appended in postorder share bodies only with their
  // neighbours, so building the equality block costs its fill, not O(n) per row.
  auto shares = [&row](const Row& a) {
    return a.body0 == row.body0 || a.body0 == row.body1 || (a.body1 >= 0 && (a.body1 == row.body0 || a.body1 == row.body1));
  };
  // One pass over the equality rows of the row's bodies collects the passive ones (position and
  // row); a row touching both bodies is listed under each and taken once. While the equality
  // block is built every passive row precedes k, and the lists are sorted by row.
  int first = n, hits = 0;
  int* hit_pos = hit_pos_.data();
  int* hit_row = hit_row_.data();
  for (const int body : {row.body0, row.body1}) {
    if (body < 0) continue;
    const bool second = body != row.body0 && row.body0 >= 0;
    const int e_end = eq_start_[static_cast<size_t>(body) + 1];
    for (int e = eq_start_[static_cast<size_t>(body)]; e < e_end; ++e) {
      const int r = eq_rows_[static_cast<size_t>(e)];
      if (building_equalities_ && r >= k) break;
      const int pos = position_[static_cast<size_t>(r)];
      if (!(pos >= 0 && pos < n)) continue;
      if (second) {
        const Row& a = p.row(r);
        if (a.body0 == row.body0 || a.body1 == row.body0) continue;  // listed under body0 too
      }
      first = std::min(first, pos);
      hit_pos[hits] = pos;
      hit_row[hits] = r;
      ++hits;
    }
  }
  // Passive inequality rows (none while the equality block is built) are all read.
  const int ineq_from = building_equalities_ ? n : n_eq_;
  for (int i = ineq_from; i < first; ++i)
    if (shares(p.row(passive_[static_cast<size_t>(i)]))) { first = i; break; }
  std::fill(x + first, x + n, 0.0);
  for (int h = 0; h < hits; ++h) x[hit_pos[h]] = p.A(hit_row[h], k);
  for (int i = std::max(ineq_from, first); i < n; ++i) {
    const Row& a = p.row(passive_[static_cast<size_t>(i)]);
    if (shares(a)) x[i] = p.A(passive_[static_cast<size_t>(i)], k);
  }
  // With ε A_kk > 0 the pivot below cannot fail (it is at least that), so row n of the factor is
  // written as the substitution finishes each entry; otherwise only once the pivot is known.
  // Row n of the columns before `first` stays past their bounds (never read, zeroed when a
  // bound grows over it).
  const double eps = settings_.regularization * row.diag;
  const bool write_now = eps > 0.0;
  auto setRow = [&](int j, double* col) {
    col[n] = x[j];
    if (x[j] == 0.0) return;
    int& lj = last_[static_cast<size_t>(j)];
    for (int i = std::min(lj, n - 1) + 1; i < n; ++i) col[i] = 0.0;  // rows the bound now covers
    lj = n;
  };
  double ll = 0.0;
  for (int j = first; j < n; ++j) {
    double* col = L + static_cast<size_t>(j) * cap;
    if (x[j] == 0.0) {
      if (write_now) col[n] = x[j];
      continue;
    }
    x[j] *= inv_diag_[static_cast<size_t>(j)];
    ll += x[j] * x[j];
    const int end = std::min(last_[static_cast<size_t>(j)], n - 1);
    if (j < n_eq_) {
      subScaled(x, col, x[j], j + 1, std::min(end, band_[static_cast<size_t>(j)]));
      subScaled(x, col, x[j], n_eq_, end);
    } else {
      subScaled(x, col, x[j], j + 1, end);
    }
    if (write_now) setRow(j, col);  // column j is not read again here
  }
  double pivot2 = row.diag + eps - ll;
  if (!(pivot2 > kIllPivot * row.diag)) ill_conditioned_ = true;
  if (!(pivot2 > eps)) pivot2 = eps;  // row (numerically) dependent on P: regularisation pivot
  if (!std::isfinite(pivot2) || !(pivot2 > 0.0)) return false;
  if (!write_now)
    for (int j = first; j < n; ++j) setRow(j, L + static_cast<size_t>(j) * cap);
  const double diag = std::sqrt(pivot2);
  L[static_cast<size_t>(n) * cap + static_cast<size_t>(n)] = diag;
  inv_diag_[static_cast<size_t>(n)] = 1.0 / diag;
  last_[static_cast<size_t>(n)] = n;
  if (n_eq_ > 0 || row.type == RowType::Inequality) {
    // The row's share of the forward substitution over the equality columns (see gb_).
    double g = row.b;
    for (int j = first; j < n_eq_; ++j)
      if (yE_[static_cast<size_t>(j)] != 0.0 && x[j] != 0.0) g -= x[j] * yE_[static_cast<size_t>(j)];
    gb_[static_cast<size_t>(n)] = g;
  }
  passive_.push_back(k);
  position_[static_cast<size_t>(k)] = n;
  lambda_p_[static_cast<size_t>(n)] = 0.0;
  return true;
}

void ActiveSetSolver::remove(int pos) {
  const size_t cap = static_cast<size_t>(capacity_);
  const int n = static_cast<int>(passive_.size());
  double* L = L_.data();
  auto at = [&](int i, int j) -> double& { return L[static_cast<size_t>(j) * cap + static_cast<size_t>(i)]; };
  auto lastOf = [&](int j) { return std::min(last_[static_cast<size_t>(j)], n - 1); };
  // x = the removed column below the diagonal (new row indices pos … x_last); it feeds a
  // rank-one update of the trailing block. Entries past the column's last row are zero.
  const int r = n - 1 - pos;
  const int x_last = lastOf(pos) - 1;
  for (int i = 0; i < r; ++i) tmp_[static_cast<size_t>(i)] = pos + i <= x_last ? at(pos + 1 + i, pos) : 0.0;
  // Columns before pos lose row pos (rows below move up one).
  for (int j = 0; j < pos; ++j) {
    const int lj = lastOf(j);
    for (int i = pos + 1; i <= lj; ++i) at(i - 1, j) = at(i, j);
    last_[static_cast<size_t>(j)] = lj >= pos ? std::max(j, lj - 1) : lj;
  }
  // Columns after pos move one left and up (the rank-one update below extends their bounds).
  for (int j = pos + 1; j < n; ++j) {
    const int lj = lastOf(j);
    for (int i = j; i <= lj; ++i) at(i - 1, j - 1) = at(i, j);
    last_[static_cast<size_t>(j - 1)] = lj - 1;
  }
  // Rank-one update T Tᵀ + x xᵀ of the trailing r×r block at (pos, pos). Passing column k, x
  // takes on that column's nonzeros, so x's extent (xend) grows, and every later column it
  // meets must cover it: its bound is raised and the newly covered entries start as zero.
  int xend = x_last - pos;
  for (int k = 0; k < r; ++k) {
    const double xk = tmp_[static_cast<size_t>(k)];
    if (xk == 0.0) continue;
    int& lk = last_[static_cast<size_t>(pos + k)];
    for (int i = lk + 1; i <= pos + xend; ++i) at(i, pos + k) = 0.0;
    lk = std::max(lk, pos + xend);
    const int end = lk - pos;
    xend = end;
    double& Tkk = at(pos + k, pos + k);
    // (A factor's entries are square roots of the rows' scales: no overflow to guard against.)
    const double rr = std::sqrt(Tkk * Tkk + xk * xk);
    const double inv_t = 1.0 / Tkk;
    const double c = rr * inv_t, s = xk * inv_t, inv_c = Tkk / rr;
    Tkk = rr;
    for (int i = k + 1; i <= end; ++i) {
      double& Tik = at(pos + i, pos + k);
      Tik = (Tik + s * tmp_[static_cast<size_t>(i)]) * inv_c;
      tmp_[static_cast<size_t>(i)] = c * tmp_[static_cast<size_t>(i)] - s * Tik;
    }
  }
  for (int j = pos; j + 1 < n; ++j) inv_diag_[static_cast<size_t>(j)] = 1.0 / at(j, j);
  position_[static_cast<size_t>(passive_[static_cast<size_t>(pos)])] = -1;
  for (int i = pos + 1; i < n; ++i) {
    passive_[static_cast<size_t>(i - 1)] = passive_[static_cast<size_t>(i)];
    lambda_p_[static_cast<size_t>(i - 1)] = lambda_p_[static_cast<size_t>(i)];
    gb_[static_cast<size_t>(i - 1)] = gb_[static_cast<size_t>(i)];
    position_[static_cast<size_t>(passive_[static_cast<size_t>(i - 1)])] = i - 1;
  }
  passive_.pop_back();
}

double ActiveSetSolver::factorResidual(const QpProblem& p, int* passive_size) const {
  const int n = static_cast<int>(passive_.size());
  if (passive_size) *passive_size = n;
  const size_t cap = static_cast<size_t>(capacity_);
  // Entries past a column's bound are zero by construction; read only what the bound covers.
  auto L = [&](int i, int j) { return i >= j && i <= std::min(last_[static_cast<size_t>(j)], n - 1) ? L_[static_cast<size_t>(j) * cap + static_cast<size_t>(i)] : 0.0; };
  double err = 0.0, scale = kTiny;
  for (int i = 0; i < n; ++i) {
    const Row& ri = p.row(passive_[static_cast<size_t>(i)]);
    scale = std::max(scale, ri.diag);
    for (int j = 0; j <= i; ++j) {
      double llt = 0.0;
      for (int t = 0; t <= j; ++t) llt += L(i, t) * L(j, t);
      double a = p.A(passive_[static_cast<size_t>(i)], passive_[static_cast<size_t>(j)]);
      if (i == j) a += settings_.regularization * ri.diag;
      err = std::max(err, std::abs(llt - a));
    }
  }
  return err / scale;
}

void ActiveSetSolver::accumulate(const QpProblem& p, const double* x, std::vector<Vec6>& out) const {
  for (int b = 0; b < p.numBodies(); ++b) out[static_cast<size_t>(b)].setZero();
  for (size_t i = 0; i < passive_.size(); ++i) {
    const Row& row = p.row(passive_[i]);
    out[static_cast<size_t>(row.body0)] += x[i] * row.W0;
    if (row.body1 >= 0) out[static_cast<size_t>(row.body1)] += x[i] * row.W1;
  }
}

void ActiveSetSolver::accumulateAbs(const QpProblem& p, std::vector<Vec6>& out) const {
  for (int b = 0; b < p.numBodies(); ++b) out[static_cast<size_t>(b)] = p.unconstrained(b).cwiseAbs();
  for (size_t i = 0; i < passive_.size(); ++i) {
    const Row& row = p.row(passive_[i]);
    const double l = std::abs(lambda_p_[i]);
    out[static_cast<size_t>(row.body0)] += l * row.W0.cwiseAbs();
    if (row.body1 >= 0) out[static_cast<size_t>(row.body1)] += l * row.W1.cwiseAbs();
  }
}

void ActiveSetSolver::indexEqualities(const QpProblem& p) {
  const int m = p.numRows(), nb = p.numBodies();
  std::fill(eq_start_.begin(), eq_start_.begin() + nb + 1, 0);
  for (int k = 0; k < m; ++k) {
    const Row& row = p.row(k);
    if (row.type != RowType::Equality) continue;
    ++eq_start_[static_cast<size_t>(row.body0) + 1];
    if (row.body1 >= 0 && row.body1 != row.body0) ++eq_start_[static_cast<size_t>(row.body1) + 1];
  }
  for (int b = 0; b < nb; ++b) eq_start_[static_cast<size_t>(b) + 1] += eq_start_[static_cast<size_t>(b)];
  // (Its own storage: tmp_, which this once borrowed, holds one double per row, fewer than the
  // bodies' cursors need when there are few rows: a problem without rows wrote through null.)
  int* fill = eq_fill_.data();
  for (int b = 0; b < nb; ++b) fill[b] = eq_start_[static_cast<size_t>(b)];
  for (int k = 0; k < m; ++k) {
    const Row& row = p.row(k);
    if (row.type != RowType::Equality) continue;
    eq_rows_[static_cast<size_t>(fill[row.body0]++)] = k;
    if (row.body1 >= 0 && row.body1 != row.body0) eq_rows_[static_cast<size_t>(fill[row.body1]++)] = k;
  }
}

void ActiveSetSolver::forward(double* x, int from) const {
  const size_t cap = static_cast<size_t>(capacity_);
  const int n = static_cast<int>(passive_.size());
  const double* L = L_.data();
  // Equality columns: their band, then the inequality rows; the others: one range.
  int j = from;
  for (; j < n_eq_; ++j) {
    if (x[j] == 0.0) continue;
    const double* col = L + static_cast<size_t>(j) * cap;
    x[j] *= inv_diag_[static_cast<size_t>(j)];
    const int end = std::min(last_[static_cast<size_t>(j)], n - 1);
    subScaled(x, col, x[j], j + 1, std::min(end, band_[static_cast<size_t>(j)]));
    subScaled(x, col, x[j], n_eq_, end);
  }
  for (; j < n; ++j) {
    if (x[j] == 0.0) continue;
    const double* col = L + static_cast<size_t>(j) * cap;
    x[j] *= inv_diag_[static_cast<size_t>(j)];
    subScaled(x, col, x[j], j + 1, std::min(last_[static_cast<size_t>(j)], n - 1));
  }
}

void ActiveSetSolver::backward(double* x) const {
  const size_t cap = static_cast<size_t>(capacity_);
  const int n = static_cast<int>(passive_.size());
  const double* L = L_.data();
  int j = n - 1;
  for (; j >= n_eq_; --j) {
    const double* col = L + static_cast<size_t>(j) * cap;
    x[j] = subDot(x[j], col, x, j + 1, std::min(last_[static_cast<size_t>(j)], n - 1)) * inv_diag_[static_cast<size_t>(j)];
  }
  for (; j >= 0; --j) {
    const double* col = L + static_cast<size_t>(j) * cap;
    const int end = std::min(last_[static_cast<size_t>(j)], n - 1);
    const double acc = subDot(x[j], col, x, j + 1, std::min(end, band_[static_cast<size_t>(j)]));
    x[j] = subDot(acc, col, x, n_eq_, end) * inv_diag_[static_cast<size_t>(j)];
  }
}

void ActiveSetSolver::forwardEqualities(const QpProblem& p) {
  for (int i = 0; i < n_eq_; ++i) yE_[static_cast<size_t>(i)] = p.row(passive_[static_cast<size_t>(i)]).b;
  // Only the equality block is in the factor yet: a plain forward pass over it.
  forward(yE_.data(), 0);
}

void ActiveSetSolver::solvePassive(const QpProblem& p) {
  const int n = static_cast<int>(passive_.size());
  // The forward pass over the equality columns is cached (yE_, gb_): bit for bit what it computes.
  for (int i = 0; i < n_eq_; ++i) s_[static_cast<size_t>(i)] = yE_[static_cast<size_t>(i)];
  for (int i = n_eq_; i < n; ++i) s_[static_cast<size_t>(i)] = gb_[static_cast<size_t>(i)];
  forward(s_.data(), n_eq_);
  backward(s_.data());
  if (ill_conditioned_) refinePassive(p);
}

void ActiveSetSolver::refinePassive(const QpProblem& p) {
  const int n = static_cast<int>(passive_.size());
  for (int step = 0; step < settings_.refinement_steps; ++step) {
    // r = b_P − A_PP s, with A_PP s = J_P (M⁻¹ J_Pᵀ s).
    accumulate(p, s_.data(), dz_);
    for (int i = 0; i < n; ++i) {
      const int k = passive_[static_cast<size_t>(i)];
      tmp_[static_cast<size_t>(i)] = p.row(k).b - p.rowDot(k, dz_.data());
    }
    forward(tmp_.data(), 0);
    backward(tmp_.data());
    for (int i = 0; i < n; ++i) s_[static_cast<size_t>(i)] += tmp_[static_cast<size_t>(i)];
  }
}

SolveStats ActiveSetSolver::solve(const QpProblem& p, QpSolution& sol, const unsigned char* warm_passive) {
  SolveStats stats = solveOnce(p, sol, warm_passive);
  if (settings_.proximal_iterations > 0 &&
      (stats.status == SolveStatus::Stalled || stats.status == SolveStatus::IterationLimit))
    polish(p, sol, stats);
  return stats;
}

void ActiveSetSolver::polish(const QpProblem& p, QpSolution& sol, SolveStats& stats) {
  const int m = p.numRows(), nb = p.numBodies();
  if (!prox_) {
    ActiveSetSettings s = settings_;
    s.proximal_iterations = 0;
    s.regularization = settings_.proximal_regularization;
    s.refinement_steps = 0;  // (refinement aims at the unregularised A_PP: not this problem's)
    prox_ = std::make_unique<ActiveSetSolver>(s);
  }
  prox_lambda_.assign(sol.lambda.begin(), sol.lambda.begin() + m);
  prox_warm_.assign(static_cast<size_t>(m), 0);
  double best = stats.kkt_residual;
  const SolveStatus first = stats.status;
  // b_k + ρ_k λ_k through c_k (b = c − J z_u): the same rows, masses and z_u, so the
  // subproblem's z is a motion of the original problem too.
  prox_problem_ = p;
  for (int it = 0; it < settings_.proximal_iterations; ++it) {
    for (int k = 0; k < m; ++k) {
      Row& row = prox_problem_.row(k);
      const size_t ki = static_cast<size_t>(k);
      if (row.type == RowType::Inequality) prox_lambda_[ki] = std::max(0.0, prox_lambda_[ki]);
      row.c = p.row(k).c + settings_.proximal_regularization * p.row(k).diag * prox_lambda_[ki];
      prox_warm_[ki] = row.type == RowType::Inequality && prox_lambda_[ki] > 0.0;
    }
    prox_problem_.finalize();
    const SolveStats inner = prox_->solveOnce(prox_problem_, prox_sol_, prox_warm_.data());
    stats.iterations += inner.iterations;
    if (inner.status == SolveStatus::NumericalFailure) break;
    bool finite = true;
    for (int b = 0; b < nb; ++b) finite = finite && prox_sol_.z[static_cast<size_t>(b)].allFinite();
    if (!finite) break;
    for (int k = 0; k < m; ++k) prox_lambda_[static_cast<size_t>(k)] = prox_sol_.lambda[static_cast<size_t>(k)];
    SolveStats trial;
    trial.iterations = stats.iterations;
    finish(p, prox_sol_, true, false, false, trial);
    if (trial.status == SolveStatus::NumericalFailure || !(trial.kkt_residual < best)) continue;
    best = trial.kkt_residual;
    sol.z = prox_sol_.z;
    sol.lambda = prox_sol_.lambda;
    stats = trial;
    // (Not Converged: the status the first solve ended with.)
    if (stats.status != SolveStatus::Converged) stats.status = first;
    if (stats.status == SolveStatus::Converged && best <= 1e-3 * settings_.converged_kkt) break;
  }
}

SolveStats ActiveSetSolver::solveOnce(const QpProblem& p, QpSolution& sol, const unsigned char* warm_passive) {
  const int m = p.numRows(), nb = p.numBodies();
  reserve(nb, m);
  sol.resize(nb, m);
  SolveStats stats;
  passive_.clear();
  std::fill(position_.begin(), position_.begin() + m, -1);
  std::fill(blocked_.begin(), blocked_.begin() + m, static_cast<unsigned char>(0));
  const int max_iter = settings_.max_iterations > 0 ? settings_.max_iterations : 3 * m + 50;
  auto isIneq = [&](int k) { return p.row(k).type == RowType::Inequality; };

  // P starts with every equality row (multipliers free), then last step's active rows.
  bool equality_missing = false;  // an equality that cannot be factorised: not a converged solve
  n_eq_ = 0;  // no gap while the equality block is built
  ill_conditioned_ = false;
  indexEqualities(p);
  building_equalities_ = true;
  for (int k = 0; k < m; ++k)
    if (!isIneq(k) && !append(p, k)) equality_missing = equality_missing || p.row(k).c != 0.0 || p.row(k).diag != 0.0;
  building_equalities_ = false;
  n_eq_ = static_cast<int>(passive_.size());
  for (int j = 0; j < n_eq_; ++j) band_[static_cast<size_t>(j)] = std::min(last_[static_cast<size_t>(j)], n_eq_ - 1);
  forwardEqualities(p);
  if (warm_passive)
    for (int k = 0; k < m; ++k)
      if (isIneq(k) && warm_passive[k]) append(p, k);
  solvePassive(p);
  // A warm set may be infeasible: drop every row whose multiplier is not positive, solve again,
  // until λ_I > 0 (each pass shrinks the set; a row dropped too early enters again below).
  for (;;) {
    bool dropped = false;
    for (int i = static_cast<int>(passive_.size()) - 1; i >= n_eq_; --i)
      if (isIneq(passive_[static_cast<size_t>(i)]) && s_[static_cast<size_t>(i)] <= 0.0) {
        remove(i);
        dropped = true;
      }
    if (!dropped) break;
    solvePassive(p);
  }
  for (size_t i = 0; i < passive_.size(); ++i) lambda_p_[i] = s_[i];

  bool converged = false, stalled = false;
  bool z_current = false;  // sol.z = z_u + M⁻¹ J_Pᵀ λ_P for the final λ_P already
  while (stats.iterations < max_iter) {
    // z = z_u + M⁻¹ J_Pᵀ λ_P and the most violated inequality outside P.
    accumulate(p, lambda_p_.data(), dz_);
    for (int b = 0; b < nb; ++b) sol.z[static_cast<size_t>(b)] = p.unconstrained(b) + dz_[static_cast<size_t>(b)];
    // Round-off floor of J_k z: the terms of z = z_u + Σ λ_i M⁻¹J_iᵀ can cancel (large λ of nearly
    // dependent rows), so a slack within a few ulps of |J_k| (|z_u| + Σ |λ_i| |M⁻¹J_iᵀ|) is noise,
    // whatever its sign. Letting such rows enter P (they are dependent at a degenerate vertex)
    // gives them huge λ, which raises the noise further and ends in a false or real stall.
    // (|z| is summed only once a row's slack passes the relative tolerance: the noise floor can
    // only raise the threshold, so rows inside the tolerance never need it.)
    bool have_absz = false;
    int enter = -1;
    double best = 0.0;
    bool blocked_violated = false;
    for (int k = 0; k < m; ++k) {
      if (position_[static_cast<size_t>(k)] >= 0 || !isIneq(k)) continue;
      const Row& row = p.row(k);
      const double jz = p.rowDot(k, sol.z.data());
      const double w = jz - row.c;
      // A slack w ≥ 0 is never below −tol·scale (scale > 0): its scale is not needed.
      if (w >= 0.0 && settings_.tolerance >= 0.0) continue;
      const double scale = std::max({std::abs(row.c), std::abs(row.c - row.b), p.rowAbsDot(k, sol.z.data()), kTiny});
      const double tol = settings_.tolerance * scale;
      if (!(w < -tol)) continue;
      if (!have_absz) {
        accumulateAbs(p, absz_);
        have_absz = true;
      }
      const double noise = kNoiseUlps * p.rowAbsDot(k, absz_.data());
      if (!(w < -std::max(tol, noise))) continue;
      if (blocked_[static_cast<size_t>(k)]) { blocked_violated = true; continue; }
      const double score = w / std::sqrt(std::max(row.diag, kTiny));
      if (enter < 0 || score < best) { enter = k; best = score; }
    }
    if (enter < 0) {
      converged = !blocked_violated;
      stalled = blocked_violated;
      z_current = true;
      break;
    }
    ++stats.iterations;
    if (!append(p, enter)) {
      blocked_[static_cast<size_t>(enter)] = 1;
      continue;
    }
    // Lawson–Hanson inner loop: move towards the new passive solution, dropping rows whose
    // multiplier reaches zero, until every passive inequality multiplier is positive.
    for (int inner = 0; inner <= m; ++inner) {
      solvePassive(p);
      const int n = static_cast<int>(passive_.size());
      double alpha = 1.0;
      int hit = -1;
      for (int i = 0; i < n; ++i) {
        if (!isIneq(passive_[static_cast<size_t>(i)]) || s_[static_cast<size_t>(i)] > 0.0) continue;
        const double li = lambda_p_[static_cast<size_t>(i)];
        const double den = li - s_[static_cast<size_t>(i)];
        const double a = den > 0.0 ? li / den : 0.0;  // li = s_i = 0: the row leaves at once
        if (hit < 0 || a < alpha) { alpha = a; hit = i; }
      }
      if (hit < 0) {
        for (int i = 0; i < n; ++i) lambda_p_[static_cast<size_t>(i)] = s_[static_cast<size_t>(i)];
        break;
      }
      double lmax = kTiny;
      for (int i = 0; i < n; ++i) {
        double& li = lambda_p_[static_cast<size_t>(i)];
        li += alpha * (s_[static_cast<size_t>(i)] - li);
        lmax = std::max(lmax, std::abs(li));
      }
      for (int i = n - 1; i >= 0; --i) {
        if (!isIneq(passive_[static_cast<size_t>(i)])) continue;
        if (i == hit || lambda_p_[static_cast<size_t>(i)] <= 1e-15 * lmax) remove(i);
      }
    }
    if (position_[static_cast<size_t>(enter)] < 0) {
      blocked_[static_cast<size_t>(enter)] = 1;  // could not enter: avoid cycling on it
    } else {
      std::fill(blocked_.begin(), blocked_.begin() + m, static_cast<unsigned char>(0));
    }
  }

  // Iterative refinement of the final passive solution against the unregularised A_PP (the
  // active-set decisions above need no more than the regularised solves: their tolerance is far
  // above ε). s_ holds the solve of this passive set; kept only while every passive inequality
  // multiplier stays positive.
  if (settings_.refinement_steps > 0 && !passive_.empty() && !ill_conditioned_) {
    refinePassive(p);
    bool positive = true;
    for (size_t i = 0; i < passive_.size(); ++i)
      positive = positive && (!isIneq(passive_[i]) || s_[i] > 0.0);
    if (positive) {
      for (size_t i = 0; i < passive_.size(); ++i) lambda_p_[i] = s_[i];
      z_current = false;
    }
  }
  for (int k = 0; k < m; ++k) sol.lambda[static_cast<size_t>(k)] = 0.0;
  int active = 0;
  for (size_t i = 0; i < passive_.size(); ++i) {
    sol.lambda[static_cast<size_t>(passive_[i])] = lambda_p_[i];
    if (lambda_p_[i] != 0.0) ++active;
  }
  // (Unless the search loop ended on this λ_P: then sol.z holds exactly this sum.)
  if (!z_current) {
    accumulate(p, lambda_p_.data(), dz_);
    for (int b = 0; b < nb; ++b) sol.z[static_cast<size_t>(b)] = p.unconstrained(b) + dz_[static_cast<size_t>(b)];
  }
  stats.active_set_size = active;
  finish(p, sol, converged, stalled, equality_missing, stats);
  return stats;
}

void ActiveSetSolver::finish(const QpProblem& p, const QpSolution& sol, bool converged, bool stalled,
                             bool equality_missing, SolveStats& stats) {
  const int m = p.numRows(), nb = p.numBodies();
  bool finite = true;
  for (int b = 0; b < nb; ++b) finite = finite && sol.z[static_cast<size_t>(b)].allFinite();
  if (stats.active_set_size == 0)
    for (int k = 0; k < m; ++k) stats.active_set_size += sol.lambda[static_cast<size_t>(k)] != 0.0 ? 1 : 0;
  stats.kkt_residual = kktResidual(p, sol, kkt_scratch_).max();
  // Equalities must hold in plain terms too: the round-off-scaled residual cannot see conflicting
  // equalities, whose regularised multipliers (~1/ε) inflate the very scale it divides by.
  {
    double global = kTiny;
    double* abs_jz = tmp_.data();  // |J_k| |z| per row, read again below
    for (int k = 0; k < m; ++k) {
      const Row& row = p.row(k);
      abs_jz[k] = p.rowAbsDot(k, sol.z.data());
      global = std::max({global, std::abs(row.c), std::abs(row.c - row.b), abs_jz[k]});
    }
    // Ill-conditioning leaves at most ~1e-5 of a row's scale; conflicts leave O(1).
    for (int k = 0; k < m; ++k) {
      const Row& row = p.row(k);
      if (row.type != RowType::Equality) continue;
      const double scale = std::max({std::abs(row.c), std::abs(row.c - row.b), abs_jz[k]});
      const double viol = std::abs(p.rowDot(k, sol.z.data()) - row.c);
      if (viol > 1e-3 * scale + 1e-9 * global) {
        equality_missing = true;
        stats.kkt_residual = std::max(stats.kkt_residual, viol / std::max(scale, kTiny));
      }
    }
  }
  if (!finite || !std::isfinite(stats.kkt_residual)) stats.status = SolveStatus::NumericalFailure;
  else if (converged && !equality_missing && stats.kkt_residual <= settings_.converged_kkt) stats.status = SolveStatus::Converged;
  else if (converged) stats.status = SolveStatus::Stalled;  // no violated row can enter, KKT not met
  else if (stalled) stats.status = SolveStatus::Stalled;
  else stats.status = SolveStatus::IterationLimit;
}

}  // namespace godhand
