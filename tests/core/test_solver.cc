// Tests of the Gauss least-constraint QP solvers (core/solver/*, METHOD.md §3).
//
// The oracle is independent of the library: every problem is generated here from its own data
// (mass blocks, rows, z_u, a feasible point z0), assembled into dense Eigen matrices M (6N×6N)
// and J (m×6N), and the solver's z and λ are checked against the four KKT conditions, which are
// necessary and sufficient for the strictly convex QP. Small problems are additionally checked
// by brute-force enumeration of active sets. godhand::kktResidual is only compared, never trusted.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "solver/active_set.h"
#include "solver/pgs.h"
#include "solver/qp.h"
#include "../test_sanitized.h"

namespace godhand {
namespace {

using MatX = Eigen::MatrixXd;
using VecX = Eigen::VectorXd;

constexpr double kKktTol = 1e-9;

// Draws are taken one per statement, left to right: C++ leaves the order of function
// arguments and of a binary operator's operands unspecified, so Vec3(normal(), normal(),
// normal()) or draw() * draw() gives gcc and clang different problems from one seed.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(gen_); }
  double normal() { return std::normal_distribution<double>(0.0, 1.0)(gen_); }
  int integer(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(gen_); }  // inclusive
  bool chance(double p) { return uniform(0.0, 1.0) < p; }
  double logUniform(double lo_exp, double hi_exp) { return std::pow(10.0, uniform(lo_exp, hi_exp)); }
  Vec6 vec6() {
    Vec6 v;
    for (int i = 0; i < 6; ++i) v[i] = normal();
    return v;
  }
  Vec3 normal3() {
    const double x = normal();
    const double y = normal();
    const double z = normal();
    return Vec3(x, y, z);
  }
  Vec3 uniform3(double lo, double hi) {
    const double x = uniform(lo, hi);
    const double y = uniform(lo, hi);
    const double z = uniform(lo, hi);
    return Vec3(x, y, z);
  }
  Vec3 unit3() {
    for (;;) {
      const Vec3 v = normal3();
      if (v.norm() > 1e-3) return v.normalized();
    }
  }

 private:
  std::mt19937_64 gen_;
};

// ---------------------------------------------------------------------------------------------
// Test problems, held independently of QpProblem.

struct TRow {
  RowType type = RowType::Inequality;
  int b0 = 0, b1 = -1;
  Vec6 J0 = Vec6::Zero(), J1 = Vec6::Zero();
  double c = 0.0;
};

struct TProblem {
  int N = 0;
  std::vector<Mat6> M;
  std::vector<Vec6> zu;
  std::vector<Vec6> z0;  // a feasible point (empty when unknown)
  std::vector<TRow> rows;

  int m() const { return static_cast<int>(rows.size()); }
  void load(QpProblem& p) const {
    p.reset(N);
    for (int b = 0; b < N; ++b) {
      p.setMass(b, M[static_cast<size_t>(b)]);
      p.unconstrained(b) = zu[static_cast<size_t>(b)];
    }
    for (const TRow& r : rows) p.addRow(r.type, r.b0, r.J0, r.b1, r.J1, r.c, 0);
    p.finalize();
  }
  MatX denseM() const {
    MatX D = MatX::Zero(6 * N, 6 * N);
    for (int b = 0; b < N; ++b) D.block<6, 6>(6 * b, 6 * b) = M[static_cast<size_t>(b)];
    return D;
  }
  MatX denseJ() const {
    MatX J = MatX::Zero(m(), 6 * N);
    for (int k = 0; k < m(); ++k) {
      const TRow& r = rows[static_cast<size_t>(k)];
      J.block<1, 6>(k, 6 * r.b0) += r.J0.transpose();
      if (r.b1 >= 0) J.block<1, 6>(k, 6 * r.b1) += r.J1.transpose();
    }
    return J;
  }
  VecX denseZu() const { return stack(zu); }
  VecX denseC() const {
    VecX c(m());
    for (int k = 0; k < m(); ++k) c[k] = rows[static_cast<size_t>(k)].c;
    return c;
  }
  static VecX stack(const std::vector<Vec6>& v) {
    VecX x(6 * static_cast<int>(v.size()));
    for (size_t b = 0; b < v.size(); ++b) x.segment<6>(6 * static_cast<int>(b)) = v[b];
    return x;
  }
  double jDot(const TRow& r, const std::vector<Vec6>& z) const {
    double s = r.J0.dot(z[static_cast<size_t>(r.b0)]);
    if (r.b1 >= 0) s += r.J1.dot(z[static_cast<size_t>(r.b1)]);
    return s;
  }
};

/// SPD block B Bᵀ + c I, c log-uniform in 10^[c_lo, c_hi], times a body scale.
Mat6 randomMass(Rng& rng, double c_lo, double c_hi, double scale) {
  Mat6 B;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) B(i, j) = rng.normal();
  Mat6 M = B * B.transpose() + rng.logUniform(c_lo, c_hi) * Mat6::Identity();
  M = 0.5 * (M + M.transpose());
  return scale * M;
}

/// Row blocks: half plain Gaussian, half contact-like (n, r × n) with a lever arm of ~10 cm.
Vec6 randomJ(Rng& rng) {
  if (rng.chance(0.5)) return rng.vec6();
  const Vec3 n = rng.unit3();
  const Vec3 r = 0.1 * rng.normal3();
  Vec6 J;
  J << n, r.cross(n);
  return J;
}

struct GenOptions {
  int N = 1;
  int num_eq = 0;
  int num_ineq = 0;
  double two_body = 0.5;       // probability that a row touches two bodies
  double zero_slack = 0.3;     // probability that an inequality is tight at z0
  int num_redundant = 0;       // extra rows: positive combinations of two existing rows
  int num_duplicates = 0;      // exact copies of existing rows (same J and c)
  int num_near_parallel = 0;   // copies with J perturbed by near_eps (relative)
  double near_eps = 1e-8;
  double mass_c_lo = -3.0, mass_c_hi = 1.0;
  bool varied_body_scale = true;
  bool varied_problem_scale = true;
};

TProblem generate(Rng& rng, const GenOptions& o) {
  TProblem P;
  P.N = o.N;
  const double zscale = o.varied_problem_scale ? rng.logUniform(-3.0, 3.0) : 1.0;
  for (int b = 0; b < o.N; ++b) {
    const double bscale = o.varied_body_scale ? rng.logUniform(-1.0, 1.0) : 1.0;
    P.M.push_back(randomMass(rng, o.mass_c_lo, o.mass_c_hi, bscale));
    P.z0.push_back(zscale * rng.vec6());
  }
  for (int b = 0; b < o.N; ++b) {
    const double s = rng.logUniform(-1.0, 1.0);
    P.zu.push_back(P.z0[static_cast<size_t>(b)] + zscale * s * rng.vec6());
  }
  auto addRow = [&](RowType type) {
    TRow r;
    r.type = type;
    r.b0 = rng.integer(0, o.N - 1);
    if (o.N > 1 && rng.chance(o.two_body)) {
      do r.b1 = rng.integer(0, o.N - 1);
      while (r.b1 == r.b0);
      r.J1 = randomJ(rng);
    }
    r.J0 = randomJ(rng);
    P.rows.push_back(r);
  };
  for (int k = 0; k < o.num_eq; ++k) addRow(RowType::Equality);
  for (int k = 0; k < o.num_ineq; ++k) addRow(RowType::Inequality);
  // Right-hand sides from z0: equalities exact, inequalities with slack >= 0 (feasible).
  auto setC = [&](TRow& r) {
    const double jz = P.jDot(r, P.z0);
    if (r.type == RowType::Equality || rng.chance(o.zero_slack)) {
      r.c = jz;
    } else {
      r.c = jz - zscale * std::abs(rng.normal());
    }
  };
  for (TRow& r : P.rows) setC(r);
  const int base = P.m();
  for (int k = 0; k < o.num_redundant && base >= 2; ++k) {
    // a·row_i + b·row_j for two rows on the same bodies (a single-body row may combine with any
    // row on that body); equality pairs stay equalities, otherwise an inequality with slack.
    const TRow& ri = P.rows[static_cast<size_t>(rng.integer(0, base - 1))];
    TRow r = ri;
    for (int tries = 0; tries < 20; ++tries) {
      const TRow& rj = P.rows[static_cast<size_t>(rng.integer(0, base - 1))];
      if (rj.b0 != ri.b0 || rj.b1 != ri.b1) continue;
      const double a = rng.uniform(0.1, 2.0), bb = rng.uniform(0.1, 2.0);
      r.J0 = a * ri.J0 + bb * rj.J0;
      r.J1 = a * ri.J1 + bb * rj.J1;
      r.type = (ri.type == RowType::Equality && rj.type == RowType::Equality) ? RowType::Equality : RowType::Inequality;
      break;
    }
    setC(r);
    P.rows.push_back(r);
  }
  for (int k = 0; k < o.num_duplicates && base >= 1; ++k) {
    P.rows.push_back(P.rows[static_cast<size_t>(rng.integer(0, base - 1))]);
  }
  for (int k = 0; k < o.num_near_parallel && base >= 1; ++k) {
    TRow r = P.rows[static_cast<size_t>(rng.integer(0, base - 1))];
    r.J0 += o.near_eps * r.J0.norm() * rng.vec6();
    if (r.b1 >= 0) r.J1 += o.near_eps * r.J1.norm() * rng.vec6();
    const double jz = P.jDot(r, P.z0);
    r.c = (r.type == RowType::Equality || rng.chance(0.5)) ? jz : jz - zscale * 1e-6 * std::abs(rng.normal());
    P.rows.push_back(r);
  }
  // Shuffle so that duplicates and combinations are not always last.
  for (int k = P.m() - 1; k > 0; --k) std::swap(P.rows[static_cast<size_t>(k)], P.rows[static_cast<size_t>(rng.integer(0, k))]);
  return P;
}

// ---------------------------------------------------------------------------------------------
// Independent KKT oracle (dense Eigen).

struct Kkt {
  double stationarity = 0, primal = 0, dual = 0, complementarity = 0;
  // Primal and complementarity measured against the round-off scale of J_k z as the solution is
  // computed, z = z_u + M⁻¹Jᵀλ: s'_k = max(s_k, |J_k| (|z_u| + |M⁻¹| |J|ᵀ |λ|)). Larger than s_k
  // where the terms of M⁻¹Jᵀλ cancel (ill-conditioned masses, large λ of nearly dependent rows);
  // `cancellation` is max s'_k / s_k.
  double primal_roundoff = 0, complementarity_roundoff = 0, cancellation = 1;
  double max() const { return std::max({stationarity, primal, dual, complementarity}); }
  double maxRoundoff() const { return std::max({stationarity, primal_roundoff, dual, complementarity_roundoff}); }
  bool finite() const { return std::isfinite(max()); }
};

Kkt oracleKkt(const TProblem& P, const QpSolution& s) {
  const MatX M = P.denseM(), J = P.denseJ();
  const VecX zu = P.denseZu(), c = P.denseC();
  const VecX z = TProblem::stack(s.z);
  VecX lam(P.m());
  for (int k = 0; k < P.m(); ++k) lam[k] = s.lambda[static_cast<size_t>(k)];
  Kkt r;
  // Stationarity M (z − z_u) = Jᵀ λ, against the round-off scale of each side.
  const VecX lhs = M * (z - zu), rhs = J.transpose() * lam;
  const VecX scale_vec = M.cwiseAbs() * (z.cwiseAbs() + zu.cwiseAbs()) + J.cwiseAbs().transpose() * lam.cwiseAbs();
  const double stat_scale = std::max({scale_vec.size() ? scale_vec.maxCoeff() : 0.0, 1e-300});
  r.stationarity = lhs.size() ? (lhs - rhs).cwiseAbs().maxCoeff() / stat_scale : 0.0;
  const double lam_max = lam.size() ? lam.cwiseAbs().maxCoeff() : 0.0;
  const VecX Jz = J * z, absJz = J.cwiseAbs() * z.cwiseAbs(), absJzu = J.cwiseAbs() * zu.cwiseAbs();
  const MatX Minv = M.inverse();
  const VecX absJroundoff = J.cwiseAbs() * (zu.cwiseAbs() + Minv.cwiseAbs() * (J.cwiseAbs().transpose() * lam.cwiseAbs()));
  for (int k = 0; k < P.m(); ++k) {
    const double sk = std::max({std::abs(c[k]), absJz[k], absJzu[k], 1e-300});
    const double sr = std::max(sk, absJroundoff[k]);
    r.cancellation = std::max(r.cancellation, sr / sk);
    const double slack = Jz[k] - c[k];
    if (P.rows[static_cast<size_t>(k)].type == RowType::Equality) {
      r.primal = std::max(r.primal, std::abs(slack) / sk);
      r.primal_roundoff = std::max(r.primal_roundoff, std::abs(slack) / sr);
    } else {
      r.primal = std::max(r.primal, std::max(0.0, -slack) / sk);
      r.primal_roundoff = std::max(r.primal_roundoff, std::max(0.0, -slack) / sr);
      if (lam_max > 0) {
        r.dual = std::max(r.dual, std::max(0.0, -lam[k]) / lam_max);
        r.complementarity = std::max(r.complementarity, std::min(std::abs(lam[k]) / lam_max, std::abs(slack) / sk));
        r.complementarity_roundoff =
            std::max(r.complementarity_roundoff, std::min(std::abs(lam[k]) / lam_max, std::abs(slack) / sr));
      }
    }
  }
  if (!z.allFinite() || !lam.allFinite()) r.stationarity = std::numeric_limits<double>::infinity();
  return r;
}

double objective(const TProblem& P, const VecX& z) {
  const VecX d = z - P.denseZu();
  return 0.5 * d.dot(P.denseM() * d);
}

double relDiffZ(const std::vector<Vec6>& a, const std::vector<Vec6>& b, const std::vector<Vec6>& zu) {
  const VecX x = TProblem::stack(a), y = TProblem::stack(b), u = TProblem::stack(zu);
  const double scale = std::max({y.norm(), u.norm(), 1e-300});
  return (x - y).norm() / scale;
}

/// Problems whose solution carries more cancellation than this (z = z_u + M⁻¹Jᵀλ with terms
/// > 1e4 × |z|: ill-conditioned masses, nearly dependent rows with large λ) are ill-conditioned:
/// with z formed that way (as the dual method must), double precision cannot promise J z − c to
/// 1e-9 of |J||z|. On them the KKT bound is asserted against the round-off scale
/// (Kkt::maxRoundoff), and the plain-scale residual is reported and guarded in aggregate.
constexpr double kCancellationLimit = 1e4;

/// ‖a − b‖∞ relative to the round-off scale of z = z_u + M⁻¹Jᵀλ (λ of the reference solution b):
/// max(‖z‖∞, ‖z_u‖∞, ‖ |z_u| + |M⁻¹| |J|ᵀ |λ| ‖∞).
double roundoffDiffZ(const TProblem& P, const QpSolution& a, const QpSolution& b) {
  const MatX Minv = P.denseM().inverse();
  VecX lam(P.m());
  for (int k = 0; k < P.m(); ++k) lam[k] = std::abs(b.lambda[static_cast<size_t>(k)]);
  const VecX zu = P.denseZu(), za = TProblem::stack(a.z), zb = TProblem::stack(b.z);
  const VecX scale = zu.cwiseAbs() + Minv.cwiseAbs() * (P.denseJ().cwiseAbs().transpose() * lam);
  const double s = std::max({scale.maxCoeff(), zb.cwiseAbs().maxCoeff(), 1e-300});
  return (za - zb).cwiseAbs().maxCoeff() / s;
}

struct CategoryStats {
  std::string name;
  int problems = 0, rows = 0, max_iterations = 0, ill_conditioned = 0, ill_over = 0, ill_stalled = 0;
  double max_oracle = 0, max_library = 0, max_stat = 0, max_primal = 0, max_compl = 0;
  double max_roundoff = 0, max_ill_oracle = 0;
  void print() const {
    std::printf("[ stats    ] %-22s problems %5d rows %6d | max KKT %.2e (stat %.1e primal %.1e compl %.1e) library %.2e"
                " | round-off-scaled %.2e | ill-conditioned %d (plain KKT max %.2e, %d above 1e-9, %d stalled) | max iters %d\n",
                name.c_str(), problems, rows, max_oracle, max_stat, max_primal, max_compl, max_library, max_roundoff,
                ill_conditioned, max_ill_oracle, ill_over, ill_stalled, max_iterations);
  }
};

/// Checks an exact solution against the oracle: status Converged, λ_I ≥ 0, KKT ≤ 1e-9 (plain
/// scale, and round-off scale; see kCancellationLimit).
void checkExact(const TProblem& P, const QpSolution& sol, const SolveStats& st, CategoryStats& cat, const char* where) {
  const Kkt k = oracleKkt(P, sol);
  ++cat.problems;
  cat.rows += P.m();
  cat.max_iterations = std::max(cat.max_iterations, st.iterations);
  cat.max_roundoff = std::max(cat.max_roundoff, k.maxRoundoff());
  const bool ill = k.cancellation > kCancellationLimit;
  if (ill) {
    ++cat.ill_conditioned;
    cat.ill_over += k.max() > kKktTol;
    cat.max_ill_oracle = std::max(cat.max_ill_oracle, k.max());
  } else {
    cat.max_oracle = std::max(cat.max_oracle, k.max());
    cat.max_library = std::max(cat.max_library, st.kkt_residual);
    cat.max_stat = std::max(cat.max_stat, k.stationarity);
    cat.max_primal = std::max(cat.max_primal, k.primal);
    cat.max_compl = std::max(cat.max_compl, k.complementarity);
  }
  // An ill-conditioned problem may end Stalled: SolverWeakness.MixedDegenerateProblems' case (a
  // row that must enter depends numerically on a full, ill-conditioned passive set), which the
  // generic category draws too (seen: N = 6, 99 rows, 48 of them tight at the optimum in 36
  // dimensions, cancellation 2e8; an independent QP found the optimum 0.019 away). Counted and
  // guarded in aggregate (RandomProblemsSatisfyKkt), never hidden: the status says Stalled and
  // the library's residual is the oracle's, within the factor MixedDegenerateProblems allows.
  if (ill && st.status == SolveStatus::Stalled) {
    ++cat.ill_stalled;
    EXPECT_GE(st.kkt_residual, 0.25 * k.maxRoundoff() - kKktTol) << where << " #" << cat.problems;
    EXPECT_LE(st.kkt_residual, 4.0 * k.maxRoundoff() + kKktTol) << where << " #" << cat.problems;
    return;
  }
  ASSERT_EQ(st.status, SolveStatus::Converged) << where << " #" << cat.problems << ": " << toString(st.status)
                                               << " N=" << P.N << " m=" << P.m() << " kkt=" << k.max()
                                               << " cancellation=" << k.cancellation;
  ASSERT_LE(k.maxRoundoff(), kKktTol) << where << " #" << cat.problems;
  if (!ill) {
    ASSERT_LE(k.max(), kKktTol) << where << " #" << cat.problems << " stat " << k.stationarity << " primal "
                                << k.primal << " dual " << k.dual << " compl " << k.complementarity;
    ASSERT_LE(st.kkt_residual, kKktTol) << where;
  }
  for (int i = 0; i < P.m(); ++i) {
    if (P.rows[static_cast<size_t>(i)].type == RowType::Inequality) {
      ASSERT_GE(sol.lambda[static_cast<size_t>(i)], 0.0) << where;
    }
  }
}

/// Loads, solves with the exact solver and checks (checkExact).
void solveAndCheck(const TProblem& P, ActiveSetSolver& solver, QpProblem& qp, QpSolution& sol, CategoryStats& cat,
                   const char* where) {
  P.load(qp);
  const SolveStats st = solver.solve(qp, sol);
  checkExact(P, sol, st, cat, where);
}

// ---------------------------------------------------------------------------------------------
// Random problems, by category.

TEST(SolverActiveSet, RandomProblemsSatisfyKkt) {
  Rng rng(101);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  CategoryStats generic{"generic"}, redundant{"redundant"}, duplicated{"duplicated"}, near{"near-parallel 1e-8"},
      many{"200 rows on 2 bodies"}, eq_only{"equalities only"};
  // Categories in a fixed order (the random sequence, hence every problem, is reproducible).
  // generic: m_E < 6N, m_I up to 3·6N.
  struct Category {
    int count;
    CategoryStats* stats;
    const char* label;
    void (*options)(Rng&, GenOptions&);
  };
  const Category categories[] = {
      {2000, &generic, "generic", [](Rng& r, GenOptions& o) { o.N = r.integer(1, 8); o.num_eq = r.integer(0, 6 * o.N - 1); o.num_ineq = r.integer(0, 18 * o.N); }},
      {300, &eq_only, "equalities only", [](Rng& r, GenOptions& o) { o.N = r.integer(1, 8); o.num_eq = r.integer(0, 6 * o.N); o.num_ineq = 0; o.num_redundant = r.integer(0, 4); }},  // redundant = dependent, consistent equality combinations
      {500, &redundant, "redundant", [](Rng& r, GenOptions& o) { o.N = r.integer(1, 6); o.num_eq = r.integer(0, 3 * o.N); o.num_ineq = r.integer(1, 12 * o.N); o.num_redundant = r.integer(1, 3 * o.N); }},
      {500, &duplicated, "duplicated", [](Rng& r, GenOptions& o) { o.N = r.integer(1, 6); o.num_eq = r.integer(0, 3 * o.N); o.num_ineq = r.integer(1, 12 * o.N); o.num_duplicates = r.integer(1, 4 * o.N); }},
      {500, &near, "near-parallel", [](Rng& r, GenOptions& o) { o.N = r.integer(1, 6); o.num_eq = r.integer(0, 3 * o.N); o.num_ineq = r.integer(1, 12 * o.N); o.num_near_parallel = r.integer(1, 3 * o.N); o.near_eps = 1e-8; }},
      {200, &many, "200 rows", [](Rng& r, GenOptions& o) { o.N = 2; o.num_eq = r.integer(0, 5); o.num_ineq = 200; }},
  };
  const auto t0 = std::chrono::steady_clock::now();
  for (const Category& c : categories) {
    for (int i = 0; i < c.count; ++i) {
      GenOptions o;
      c.options(rng, o);
      const TProblem P = generate(rng, o);
      ASSERT_NO_FATAL_FAILURE(solveAndCheck(P, solver, qp, sol, *c.stats, c.label)) << c.label << " #" << i;
    }
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (const CategoryStats* c : {&generic, &eq_only, &redundant, &duplicated, &near, &many}) c->print();
  std::printf("[ stats    ] random KKT sweep: %.2f s\n", secs);
  // Regression guard on the plain scale: ill-conditioned problems above 1e-9 stay rare (measured
  // over 10 000 problems per category: generic 0.14 %, equalities 0.11 %, redundant 0.01 %,
  // duplicated 0 %, 200 rows 0.01 %). Near-parallel rows at 1e-8 are a known weakness of the
  // normal equations (cond(A) ~ 1e16; ~40 % above 1e-9), reported but not guarded.
  for (const CategoryStats* c : {&generic, &eq_only, &redundant, &duplicated, &many}) {
    EXPECT_LE(c->ill_over, c->problems / 100) << c->name;
  }
  // Stalled ill-conditioned problems stay rare: 1 of 4,000 here (generic); 2 % of the mixed
  // degenerate problems, where they are the rule rather than the exception.
  for (const CategoryStats* c : {&generic, &eq_only, &redundant, &duplicated, &near, &many}) {
    EXPECT_LE(c->ill_stalled, c->problems / 500) << c->name;
  }
}

// ---------------------------------------------------------------------------------------------
// Brute force: enumerate every active set of a tiny problem.

/// min ½‖z − z_u‖²_M over the feasible set, by trying every subset of inequalities as equalities.
/// Returns +inf if no subset is feasible (never happens: z0 is feasible).
double bruteForceMinimum(const TProblem& P, VecX& z_best) {
  const MatX M = P.denseM(), J = P.denseJ();
  const VecX zu = P.denseZu(), c = P.denseC();
  const int n = 6 * P.N;
  std::vector<int> eq, ineq;
  for (int k = 0; k < P.m(); ++k) (P.rows[static_cast<size_t>(k)].type == RowType::Equality ? eq : ineq).push_back(k);
  const int ni = static_cast<int>(ineq.size());
  double best = std::numeric_limits<double>::infinity();
  for (int mask = 0; mask < (1 << ni); ++mask) {
    std::vector<int> act = eq;
    for (int i = 0; i < ni; ++i)
      if (mask & (1 << i)) act.push_back(ineq[static_cast<size_t>(i)]);
    const int a = static_cast<int>(act.size());
    // [M  −J_Aᵀ; J_A  0] [z; λ] = [M z_u; c_A], solved with a rank-revealing decomposition.
    MatX K = MatX::Zero(n + a, n + a);
    VecX rhs(n + a);
    K.topLeftCorner(n, n) = M;
    rhs.head(n) = M * zu;
    for (int i = 0; i < a; ++i) {
      K.block(0, n + i, n, 1) = -J.row(act[static_cast<size_t>(i)]).transpose();
      K.block(n + i, 0, 1, n) = J.row(act[static_cast<size_t>(i)]);
      rhs[n + i] = c[act[static_cast<size_t>(i)]];
    }
    const VecX x = K.completeOrthogonalDecomposition().solve(rhs);
    if ((K * x - rhs).norm() > 1e-9 * (K.norm() * x.norm() + rhs.norm())) continue;  // inconsistent set
    const VecX z = x.head(n);
    bool feasible = true;
    for (int k : ineq) {
      const double sk = std::max({std::abs(c[k]), (J.row(k).cwiseAbs() * z.cwiseAbs())(0)});
      if (J.row(k).dot(z) < c[k] - 1e-12 * sk) feasible = false;
    }
    if (!feasible) continue;
    const double f = 0.5 * (z - zu).dot(M * (z - zu));
    if (f < best) {
      best = f;
      z_best = z;
    }
  }
  return best;
}

TEST(SolverActiveSet, MatchesBruteForceOnTinyProblems) {
  Rng rng(202);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  double worst_f = 0.0, worst_z = 0.0;
  int nontrivial = 0;
  for (int i = 0; i < 3000; ++i) {
    GenOptions o;
    o.N = (i % 3 == 2) ? 2 : 1;  // mostly the 1-body case, some 2-body ones
    o.num_eq = rng.integer(0, 2);
    o.num_ineq = rng.integer(1, o.N == 1 ? 4 : 5);
    o.num_duplicates = rng.chance(0.1) ? 1 : 0;
    o.zero_slack = 0.5;
    const TProblem P = generate(rng, o);
    P.load(qp);
    const SolveStats st = solver.solve(qp, sol);
    ASSERT_EQ(st.status, SolveStatus::Converged);
    VecX z_bf;
    const double f_bf = bruteForceMinimum(P, z_bf);
    ASSERT_TRUE(std::isfinite(f_bf)) << "brute force found no feasible active set";
    const VecX z = TProblem::stack(sol.z);
    const double f = objective(P, z);
    // Floor for f_bf = 0 (z_u feasible): relative to the objective's natural size ½‖z_u‖²_M.
    const double f_scale = std::max(f_bf, 1e-12 * objective(P, VecX::Zero(6 * P.N)));
    ASSERT_LE(std::abs(f - f_bf), 1e-9 * f_scale) << "i=" << i << " f=" << f << " brute force " << f_bf;
    const double ez = (z - z_bf).norm() / std::max({z_bf.norm(), P.denseZu().norm(), 1e-300});
    EXPECT_LE(ez, 1e-7) << i;  // z is unique; looser than f (f is flat to first order at the optimum)
    worst_f = std::max(worst_f, std::abs(f - f_bf) / f_scale);
    worst_z = std::max(worst_z, ez);
    nontrivial += st.active_set_size > o.num_eq;
  }
  std::printf("[ stats    ] brute force (3000 tiny problems, %d with active inequalities): max rel objective "
              "diff %.2e, max rel z diff %.2e\n", nontrivial, worst_f, worst_z);
  EXPECT_GT(nontrivial, 1000);  // the problems exercise the inequality logic
}

// ---------------------------------------------------------------------------------------------
// Warm starts of the exact solver.

TEST(SolverActiveSet, WarmStartFromPreviousActiveSet) {
  // Same problem, solved cold, then warm from the cold active set (the rows with λ > 0), then warm
  // from a random set. z is unique; λ is unique where the active rows are independent.
  Rng rng(303);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution cold, warm, wrong;
  double worst_z = 0.0, worst_l = 0.0, worst_wrong = 0.0, worst_z_plain = 0.0;
  long cold_iters = 0, warm_iters = 0, wrong_iters = 0;
  int ill = 0;
  CategoryStats cat{"warm start, random set"};
  for (int i = 0; i < 1000; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 6);
    o.num_eq = rng.integer(0, 3 * o.N);
    o.num_ineq = rng.integer(1, 15 * o.N);
    const TProblem P = generate(rng, o);
    P.load(qp);
    const SolveStats sc = solver.solve(qp, cold);
    ASSERT_EQ(sc.status, SolveStatus::Converged);
    const bool well = oracleKkt(P, cold).cancellation <= kCancellationLimit;
    ill += !well;
    std::vector<unsigned char> flags(static_cast<size_t>(P.m()), 0), random_flags(static_cast<size_t>(P.m()), 0);
    for (int k = 0; k < P.m(); ++k) {
      flags[static_cast<size_t>(k)] = P.rows[static_cast<size_t>(k)].type == RowType::Inequality && cold.lambda[static_cast<size_t>(k)] > 0.0;
      random_flags[static_cast<size_t>(k)] = rng.chance(0.5);
    }
    const SolveStats sw = solver.solve(qp, warm, flags.data());
    ASSERT_EQ(sw.status, SolveStatus::Converged);
    ASSERT_LE(sw.iterations, sc.iterations) << i;
    // The warm set is factorised in another order than the cold path built it, so the results
    // agree to round-off: 1e-12 of the scale of the arithmetic (and of |z| where well-conditioned).
    const double dz = roundoffDiffZ(P, warm, cold), dz_plain = relDiffZ(warm.z, cold.z, P.zu);
    ASSERT_LE(dz, 1e-12) << i;
    if (well) {
      ASSERT_LE(dz_plain, 1e-12) << i;
      worst_z_plain = std::max(worst_z_plain, dz_plain);
    }
    double lam_scale = 1e-300, dl = 0.0;
    for (int k = 0; k < P.m(); ++k) {
      lam_scale = std::max(lam_scale, std::abs(cold.lambda[static_cast<size_t>(k)]));
      dl = std::max(dl, std::abs(warm.lambda[static_cast<size_t>(k)] - cold.lambda[static_cast<size_t>(k)]));
    }
    if (well) {
      // λ's forward error is cond(A_PP)·ε (z's is not), hence the looser bound.
      ASSERT_LE(dl, 1e-10 * lam_scale) << i;
      worst_l = std::max(worst_l, dl / lam_scale);
    }
    worst_z = std::max(worst_z, dz);
    // A wrong (random) warm set: still converges, to the same z.
    const SolveStats sr = solver.solve(qp, wrong, random_flags.data());
    ASSERT_NO_FATAL_FAILURE(checkExact(P, wrong, sr, cat, "random warm set"));
    const double dr = roundoffDiffZ(P, wrong, cold);
    ASSERT_LE(dr, 1e-10) << i;
    if (well) {
      ASSERT_LE(relDiffZ(wrong.z, cold.z, P.zu), 1e-9) << i;
    }
    worst_wrong = std::max(worst_wrong, dr);
    cold_iters += sc.iterations;
    warm_iters += sw.iterations;
    wrong_iters += sr.iterations;
  }
  std::printf("[ stats    ] warm start (1000 problems, %d ill-conditioned): iterations cold %ld, right warm set %ld, "
              "random warm set %ld\n", ill, cold_iters, warm_iters, wrong_iters);
  std::printf("[ stats    ] warm start: right set max z diff %.2e (round-off scale), %.2e (|z|, well-conditioned), "
              "max λ diff %.2e (well-conditioned); random set max z diff %.2e (round-off scale)\n",
              worst_z, worst_z_plain, worst_l, worst_wrong);
  cat.print();
}

// The incremental factor (append, and row deletion with its rank-one update, both working only on
// each column's nonzero range) must equal a Cholesky factor of A_PP + ε diag(A) after every solve.
// Random warm sets make the solver drop many rows, so deletions at every position are exercised.
TEST(SolverActiveSet, IncrementalFactorMatchesPassiveBlock) {
  Rng rng(404);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  double worst = 0.0;
  long passive_total = 0;
  for (int i = 0; i < 400; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 6);
    o.num_eq = rng.integer(0, 3 * o.N);
    o.num_ineq = rng.integer(1, 15 * o.N);
    const TProblem P = generate(rng, o);
    P.load(qp);
    std::vector<unsigned char> random_flags(static_cast<size_t>(P.m()), 0);
    for (auto& f : random_flags) f = rng.chance(0.6);
    const unsigned char* starts[] = {nullptr, random_flags.data()};
    for (const unsigned char* warm : starts) {
      solver.solve(qp, sol, warm);
      int n = 0;
      const double r = solver.factorResidual(qp, &n);
      passive_total += n;
      ASSERT_LE(r, 1e-12) << "problem " << i;
      worst = std::max(worst, r);
    }
  }
  std::printf("[ stats    ] incremental factor: max |L Lᵀ − A_PP − εD| / max A_kk = %.2e (mean passive size %.1f)\n",
              worst, static_cast<double>(passive_total) / 800.0);
}

// A random problem of 1-3 bodies and 4-27 rows whose entries are in {-2, -1, 0, 1} (exact
// cancellations and dependencies); with `equalities`, a quarter of the rows are equalities. Returns
// the row count.
int integerRows(std::mt19937& gen, bool equalities, QpProblem* qp) {
  const int nb = 1 + static_cast<int>(gen() % 3), m = 4 + static_cast<int>(gen() % 24);
  qp->reset(nb);
  for (int b = 0; b < nb; ++b) qp->setRigidMass(b, 1.0 + b, Mat3::Identity(), Vec3(0.1, 0.2, 0.3));
  for (int k = 0; k < m; ++k) {
    Vec6 J0, J1;
    for (int i = 0; i < 6; ++i) {
      const int r0 = static_cast<int>(gen() % 5), r1 = static_cast<int>(gen() % 5);
      J0[i] = r0 < 2 ? 0.0 : r0 - 3.0;
      J1[i] = r1 < 2 ? 0.0 : r1 - 3.0;
    }
    if (J0.isZero()) J0[0] = 1.0;
    const int b0 = static_cast<int>(gen() % static_cast<unsigned>(nb));
    const int b1 = nb > 1 && gen() % 2 ? (b0 + 1) % nb : -1;
    const RowType type = equalities && gen() % 4 == 0 ? RowType::Equality : RowType::Inequality;
    qp->addRow(type, b0, J0, b1, J1, static_cast<double>(static_cast<int>(gen() % 7) - 3), 0);
  }
  qp->finalize();
  return m;
}

// Review finding: with integer-like rows (entries in {−2, −1, 0, 1}) factor entries cancel to
// exactly zero, so the deletion's rank-one update must still extend each column's nonzero bound as
// x fills in. Random warm sets force deletions at every position; the factor must stay exact.
TEST(SolverActiveSet, IncrementalFactorWithExactCancellations) {
  std::mt19937 gen(2024);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  double worst = 0.0;
  // The failure this guards against is rare (~1 in 40,000): every trial in the release run.
  constexpr int kTrials = test_support::sanitizedTrials(200000, 10);
  for (int trial = 0; trial < kTrials; ++trial) {
    const int m = integerRows(gen, false, &qp);
    std::vector<unsigned char> flags(static_cast<size_t>(m));
    for (auto& f : flags) f = gen() % 2;
    solver.solve(qp, sol, flags.data());
    const double r = solver.factorResidual(qp);
    ASSERT_LE(r, 1e-12) << "trial " << trial;
    worst = std::max(worst, r);
  }
  std::printf("[ stats    ] factor with exact cancellations: max residual %.2e over %d warm-started solves\n", worst, kTrials);
}

// Without regularisation (ε = 0) a dependent row's pivot fails and append() must leave the factor
// as it was: row n of the factor is written only once the pivot is known (with ε > 0 the pivot
// cannot fail and the row is written during the substitution). Integer rows on few bodies give
// exact dependencies, so failed appends are followed by successful ones at the same size.
TEST(SolverActiveSet, IncrementalFactorWithoutRegularization) {
  std::mt19937 gen(77);
  ActiveSetSettings settings;
  settings.regularization = 0.0;
  ActiveSetSolver solver(settings);
  QpProblem qp;
  QpSolution sol;
  double worst = 0.0;
  int failed_pivots = 0;
  constexpr int kTrials = test_support::sanitizedTrials(20000, 5);
  for (int trial = 0; trial < kTrials; ++trial) {
    const int m = integerRows(gen, true, &qp);
    std::vector<unsigned char> flags(static_cast<size_t>(m));
    for (auto& f : flags) f = gen() % 2;
    const SolveStats st = solver.solve(qp, sol, flags.data());
    int n = 0;
    const double r = solver.factorResidual(qp, &n);
    ASSERT_LE(r, 1e-12) << "trial " << trial;
    worst = std::max(worst, r);
    if (st.status != SolveStatus::Converged) ++failed_pivots;
  }
  std::printf("[ stats    ] factor without regularisation: max residual %.2e over %d solves (%d not converged)\n", worst,
              kTrials, failed_pivots);
}

// Review finding: conflicting equalities (z₀ = 0 and z₀ = 1) or an equality that cannot be
// factorised must not be reported Converged: the regularised factor returns huge multipliers.
TEST(SolverActiveSet, ConflictingEqualitiesAreNotConverged) {
  QpProblem qp;
  qp.reset(1);
  qp.setRigidMass(0, 1.0, Mat3::Identity(), Vec3(1, 1, 1));
  Vec6 e0 = Vec6::Zero();
  e0[0] = 1.0;
  qp.addRow(RowType::Equality, 0, e0, -1, Vec6::Zero(), 0.0, 0);
  qp.addRow(RowType::Equality, 0, e0, -1, Vec6::Zero(), 1.0, 0);
  qp.finalize();
  ActiveSetSolver solver;
  QpSolution sol;
  const SolveStats st = solver.solve(qp, sol);
  EXPECT_NE(st.status, SolveStatus::Converged);
  EXPECT_GT(st.kkt_residual, 1e-3);
  // A zero equality row with c ≠ 0 (unsatisfiable) is not converged either.
  QpProblem z;
  z.reset(1);
  z.setRigidMass(0, 1.0, Mat3::Identity(), Vec3(1, 1, 1));
  z.addRow(RowType::Equality, 0, Vec6::Zero(), -1, Vec6::Zero(), 1.0, 0);
  z.finalize();
  EXPECT_NE(solver.solve(z, sol).status, SolveStatus::Converged);
}


// Fewer rows than bodies: the solver's per-body scratch once borrowed a per-row buffer, which a
// problem without rows left null (found by clang's UBSan: "store to null pointer") and one row
// over eight bodies overran (ASan: heap-buffer-overflow). Analytic answer: bodies without rows
// take their unconstrained motion; the one body with a bound row x ≥ c stops at it.
TEST(SolverActiveSet, FewerRowsThanBodies) {
  for (const int rows : {0, 1}) {
    QpProblem qp;
    constexpr int kBodies = 8;
    qp.reset(kBodies);
    for (int b = 0; b < kBodies; ++b) {
      qp.setRigidMass(b, 1.0 + b, Mat3::Identity(), Vec3(1, 2, 3));
      qp.unconstrained(b) = Vec6::Constant(-0.1 * (b + 1));
    }
    Vec6 e0 = Vec6::Zero();
    e0[0] = 1.0;
    if (rows == 1) qp.addRow(RowType::Equality, 3, e0, -1, Vec6::Zero(), 0.25, 0);
    qp.finalize();
    ActiveSetSolver solver;
    QpSolution sol;
    const SolveStats st = solver.solve(qp, sol);
    ASSERT_EQ(st.status, SolveStatus::Converged) << rows << " rows";
    for (int b = 0; b < kBodies; ++b)
      for (int i = 0; i < 6; ++i) {
        const double want = rows == 1 && b == 3 && i == 0 ? 0.25 : -0.1 * (b + 1);
        EXPECT_NEAR(sol.z[static_cast<size_t>(b)][i], want, 1e-12) << rows << " rows, body " << b << " coordinate " << i;
      }
  }
}
// ---------------------------------------------------------------------------------------------
// Projected Gauss–Seidel against the exact solution.

TEST(SolverPgs, ConvergesToExactSolution) {
  Rng rng(404);
  ActiveSetSolver exact;
  QpProblem qp;
  QpSolution ex, pg;
  const int sweeps[] = {10, 100, 1000, 5000};
  constexpr int kProblems = 60;
  std::vector<double> err[4], kkt[4];
  for (int i = 0; i < kProblems; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 4);
    o.num_eq = rng.integer(0, 2 * o.N);
    o.num_ineq = rng.integer(1, 4 * o.N);  // m ≤ 6N: no duplicates, no near-parallel rows
    o.mass_c_lo = -1.0;
    o.mass_c_hi = 1.0;
    const TProblem P = generate(rng, o);
    P.load(qp);
    ASSERT_EQ(exact.solve(qp, ex).status, SolveStatus::Converged);
    for (int s = 0; s < 4; ++s) {
      PgsSolver pgs(PgsSettings{sweeps[s], 1.0});
      const SolveStats st = pgs.solve(qp, pg);
      EXPECT_EQ(st.status, SolveStatus::SweepLimit);
      EXPECT_EQ(st.iterations, sweeps[s]);
      err[s].push_back(relDiffZ(pg.z, ex.z, P.zu));
      kkt[s].push_back(oracleKkt(P, pg).max());
    }
  }
  auto quant = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))];
  };
  for (int s = 0; s < 4; ++s)
    std::printf("[ stats    ] PGS %5d sweeps: rel z error median %.2e p90 %.2e max %.2e | KKT median %.2e max %.2e\n",
                sweeps[s], quant(err[s], 0.5), quant(err[s], 0.9), quant(err[s], 1.0), quant(kkt[s], 0.5),
                quant(kkt[s], 1.0));
  // Coarse monotonicity, per problem: 10 sweeps is worse than 1000 unless both are already exact.
  int better = 0;
  for (int i = 0; i < kProblems; ++i) {
    const size_t k = static_cast<size_t>(i);
    if (kkt[2][k] < kkt[0][k] || kkt[0][k] < 1e-12) ++better;
    EXPECT_LE(err[3][k], err[0][k] + 1e-12) << i;
  }
  EXPECT_EQ(better, kProblems);
  EXPECT_LE(quant(err[3], 0.5), 1e-6);
  EXPECT_LE(quant(err[3], 0.9), 1e-6);
}

TEST(SolverPgs, ConvergesToExactSolutionAllProblems) {
  // The strict version of the previous test: every problem within 1e-6 after 5000 sweeps.
  Rng rng(404);
  ActiveSetSolver exact;
  QpProblem qp;
  QpSolution ex, pg;
  PgsSolver pgs(PgsSettings{5000, 1.0});
  double worst = 0.0;
  int worst_i = -1;
  for (int i = 0; i < 60; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 4);
    o.num_eq = rng.integer(0, 2 * o.N);
    o.num_ineq = rng.integer(1, 4 * o.N);
    o.mass_c_lo = -1.0;
    o.mass_c_hi = 1.0;
    const TProblem P = generate(rng, o);
    P.load(qp);
    ASSERT_EQ(exact.solve(qp, ex).status, SolveStatus::Converged);
    pgs.solve(qp, pg);
    const double e = relDiffZ(pg.z, ex.z, P.zu);
    if (e > worst) {
      worst = e;
      worst_i = i;
    }
  }
  std::printf("[ stats    ] PGS 5000 sweeps: worst rel z error %.2e (problem %d)\n", worst, worst_i);
  EXPECT_LE(worst, 1e-6);
}

// Generic (harder) problems: PGS's error against the exact solver printed per sweep count; what is
// asserted is only that 5000 sweeps are never worse than 10 (PGS is not exact there, and no bound
// on its error is claimed: the exact solver is the default).
TEST(SolverPgs, MoreSweepsAreNeverWorseOnGenericProblems) {
  // The generic distribution (m up to 24N, mass blocks down to B Bᵀ + 1e-3 I): PGS still improves
  // with sweeps but its rate follows cond(A); reported, with a coarse monotonicity check.
  Rng rng(4242);
  ActiveSetSolver exact;
  QpProblem qp;
  QpSolution ex, pg;
  const int sweeps[] = {10, 100, 1000, 5000};
  std::vector<double> err[4];
  for (int i = 0; i < 40; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 4);
    o.num_eq = rng.integer(0, 6 * o.N - 1);
    o.num_ineq = rng.integer(1, 18 * o.N);
    const TProblem P = generate(rng, o);
    P.load(qp);
    ASSERT_EQ(exact.solve(qp, ex).status, SolveStatus::Converged);
    for (int s = 0; s < 4; ++s) {
      PgsSolver pgs(PgsSettings{sweeps[s], 1.0});
      pgs.solve(qp, pg);
      err[s].push_back(relDiffZ(pg.z, ex.z, P.zu));
    }
    EXPECT_LE(err[3].back(), err[0].back() + 1e-12) << i;
  }
  for (int s = 0; s < 4; ++s) {
    std::vector<double> v = err[s];
    std::sort(v.begin(), v.end());
    std::printf("[ stats    ] PGS on generic problems, %5d sweeps: rel z error median %.2e p90 %.2e max %.2e\n",
                sweeps[s], v[v.size() / 2], v[v.size() * 9 / 10], v.back());
  }
}

TEST(SolverPgs, WarmStartFromExactMultipliers) {
  Rng rng(505);
  ActiveSetSolver exact;
  PgsSolver pgs(PgsSettings{1, 1.0});
  QpProblem qp;
  QpSolution ex, pg;
  double worst = 0.0, worst_exact = 0.0;
  for (int i = 0; i < 1000; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 6);
    o.num_eq = rng.integer(0, 3 * o.N);
    o.num_ineq = rng.integer(1, 12 * o.N);
    const TProblem P = generate(rng, o);
    P.load(qp);
    const SolveStats se = exact.solve(qp, ex);
    ASSERT_EQ(se.status, SolveStatus::Converged);
    const SolveStats sp = pgs.solve(qp, pg, ex.lambda.data());
    const double k = oracleKkt(P, pg).max();
    ASSERT_LE(k, kKktTol) << i << " exact solver's own " << oracleKkt(P, ex).max();
    worst = std::max(worst, k);
    worst_exact = std::max(worst_exact, oracleKkt(P, ex).max());
    ASSERT_LE(relDiffZ(pg.z, ex.z, P.zu), 1e-9);
    (void)sp;
  }
  std::printf("[ stats    ] PGS 1 sweep warm-started from exact λ: max KKT %.2e (exact solver %.2e)\n", worst,
              worst_exact);
}

// ---------------------------------------------------------------------------------------------
// Extremes (METHOD.md §6).

TRow contactRow(int body, const Vec3& n, const Vec3& r, double c) {
  TRow row;
  row.type = RowType::Inequality;
  row.b0 = body;
  row.J0 << n, r.cross(n);
  row.c = c;
  return row;
}

Mat6 rigidMass(double m, const Mat3& R, const Vec3& I) {
  Mat6 M = Mat6::Zero();
  M.topLeftCorner<3, 3>() = m * Mat3::Identity();
  M.bottomRightCorner<3, 3>() = R * I.asDiagonal() * R.transpose();
  return M;
}

TEST(SolverExtremes, MassRatios) {
  // Two bodies tied by a spherical joint (3 point rows) plus contacts on both, mass ratio 1e-4..1e4.
  Rng rng(606);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  CategoryStats cat{"mass ratio 1e-4..1e4"};
  for (int e = -4; e <= 4; ++e) {
    for (int rep = 0; rep < 50; ++rep) {
      const double ratio = std::pow(10.0, e);
      TProblem P;
      P.N = 2;
      const double m0 = 0.01;
      for (int b = 0; b < 2; ++b) {
        const double m = b == 0 ? m0 : m0 * ratio;
        const Vec3 I = m * 1e-4 * rng.uniform3(0.5, 2);
        const double angle = rng.uniform(0, 3);
        const Mat3 R = Eigen::AngleAxisd(angle, rng.unit3()).toRotationMatrix();
        P.M.push_back(rigidMass(m, R, I));
        P.zu.push_back(rng.vec6() * 10.0);
      }
      const Vec3 r0 = 0.02 * rng.unit3(), r1 = 0.02 * rng.unit3();
      for (int a = 0; a < 3; ++a) {  // a_0 + α_0 × r0 = a_1 + α_1 × r1
        TRow row;
        row.type = RowType::Equality;
        row.b0 = 0;
        row.b1 = 1;
        const Vec3 ea = Vec3::Unit(a);
        row.J0 << ea, r0.cross(ea);
        row.J1 << -ea, -r1.cross(ea);
        row.c = 0.0;
        P.rows.push_back(row);
      }
      const int contacts = rng.integer(1, 8);
      for (int k = 0; k < contacts; ++k) {
        const int b = rng.integer(0, 1);
        const Vec3 n = rng.unit3();
        const Vec3 r = 0.02 * rng.unit3();
        P.rows.push_back(contactRow(b, n, r, -std::abs(rng.normal())));
      }
      // z = 0 satisfies every row (c ≤ 0 for the contacts), so the problem is feasible.
      P.load(qp);
      ASSERT_NO_FATAL_FAILURE(solveAndCheck(P, solver, qp, sol, cat, "mass ratio"));
      // setRigidMass path: same problem, same answer.
      QpProblem qp2;
      qp2.reset(2);
      for (int b = 0; b < 2; ++b) {
        const Mat3 Ib = P.M[static_cast<size_t>(b)].bottomRightCorner<3, 3>();
        Eigen::SelfAdjointEigenSolver<Mat3> es(Ib);
        qp2.setRigidMass(b, P.M[static_cast<size_t>(b)](0, 0), es.eigenvectors(), es.eigenvalues());
        qp2.unconstrained(b) = P.zu[static_cast<size_t>(b)];
      }
      for (const TRow& r : P.rows) qp2.addRow(r.type, r.b0, r.J0, r.b1, r.J1, r.c, 0);
      qp2.finalize();
      QpSolution sol2;
      ASSERT_EQ(solver.solve(qp2, sol2).status, SolveStatus::Converged);
      ASSERT_LE(oracleKkt(P, sol2).max(), kKktTol);
      ASSERT_LE(relDiffZ(sol2.z, sol.z, P.zu), 1e-9);
    }
  }
  cat.print();
}

TEST(SolverExtremes, ThousandDuplicatedContacts) {
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol, single;
  CategoryStats cat{"1000 duplicates"};
  Rng rng(707);
  for (int rep = 0; rep < 20; ++rep) {
    TProblem P;
    P.N = 1;
    P.M.push_back(rep % 2 ? randomMass(rng, -3, 1, 1.0) : rigidMass(0.01, Mat3::Identity(), Vec3(1e-6, 2e-6, 3e-6)));
    Vec6 zu = rng.vec6();
    zu.head<3>() = Vec3(0.3, -0.2, -9.81 * 100);  // pushed into the floor
    P.zu.push_back(zu);
    const double c = -0.5;
    const TRow row = contactRow(0, Vec3::UnitZ(), Vec3(0.01, 0.02, -0.01), c);
    TProblem one = P;
    one.rows.push_back(row);
    for (int k = 0; k < 1000; ++k) P.rows.push_back(row);
    ASSERT_NO_FATAL_FAILURE(solveAndCheck(P, solver, qp, sol, cat, "1000 duplicates"));
    double sum = 0.0;
    for (double l : sol.lambda) sum += l;
    ASSERT_TRUE(std::isfinite(sum));
    one.load(qp);
    ASSERT_EQ(solver.solve(qp, single).status, SolveStatus::Converged);
    // The total push equals the single row's multiplier, z the single row's solution.
    EXPECT_NEAR(sum, single.lambda[0], 1e-9 * std::abs(single.lambda[0]));
    EXPECT_LE(relDiffZ(sol.z, single.z, P.zu), 1e-12);
  }
  // 250 copies each of 4 coplanar corner contacts (rank 3) under a flat box, pushed down and tilted.
  for (int rep = 0; rep < 20; ++rep) {
    TProblem P;
    P.N = 1;
    P.M.push_back(rigidMass(0.02, Mat3::Identity(), Vec3(1e-6, 1e-6, 2e-6)));
    Vec6 zu;
    zu << rng.normal(), rng.normal(), -100.0, 50 * rng.normal(), 50 * rng.normal(), rng.normal();
    P.zu.push_back(zu);
    const double hx = 0.02, hy = 0.01;
    for (int k = 0; k < 1000; ++k) {
      const int corner = k % 4;
      const Vec3 r((corner & 1) ? hx : -hx, (corner & 2) ? hy : -hy, -0.005);
      P.rows.push_back(contactRow(0, Vec3::UnitZ(), r, -0.1 * (rep % 3)));
    }
    ASSERT_NO_FATAL_FAILURE(solveAndCheck(P, solver, qp, sol, cat, "1000 coplanar"));
    double sum = 0.0;
    for (double l : sol.lambda) sum += l;
    ASSERT_TRUE(std::isfinite(sum));
    ASSERT_GT(sum, 0.0);
  }
  cat.print();
}

TEST(SolverExtremes, NearParallelNormals) {
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  Rng rng(808);
  for (double angle : {1e-8, 1e-7, 1e-6, 1e-5, 1e-4}) {
    char name[32];
    std::snprintf(name, sizeof(name), "contacts at %.0e rad", angle);
    CategoryStats cat{name};
    for (int rep = 0; rep < 200; ++rep) {
      TProblem P;
      P.N = rep % 4 == 3 ? 2 : 1;
      for (int b = 0; b < P.N; ++b) {
        P.M.push_back(randomMass(rng, -2, 1, 1.0));
        Vec6 zu = rng.vec6();
        zu[2] = -10.0 * std::abs(rng.normal());  // into the plane
        P.zu.push_back(zu);
      }
      const Vec3 n0 = Vec3::UnitZ();
      const int count = rng.integer(2, 6);
      for (int k = 0; k < count; ++k) {
        // Normals within `angle` of each other, contact points close together.
        const double ax = rng.normal();
        const double ay = rng.normal();
        const Vec3 axis = Vec3(ax, ay, 0.0).normalized();
        const Vec3 n = Eigen::AngleAxisd(angle * rng.uniform(0.0, 1.0), axis) * n0;
        const double rx = rng.normal();
        const double ry = rng.normal();
        const Vec3 r = 0.01 * Vec3(rx, ry, -1.0);
        const double c = rng.chance(0.5) ? 0.0 : -1e-3 * std::abs(rng.normal());
        P.rows.push_back(contactRow(rng.integer(0, P.N - 1), n, r, c));
      }
      ASSERT_NO_FATAL_FAILURE(solveAndCheck(P, solver, qp, sol, cat, "near-parallel normals"));
    }
    cat.print();
  }
}

TEST(SolverExtremes, NonFiniteInputsNeverCrash) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  Rng rng(909);
  GenOptions o;
  o.N = 3;
  o.num_eq = 4;
  o.num_ineq = 12;
  o.varied_problem_scale = false;
  const TProblem base = generate(rng, o);
  int first_eq = -1, first_ineq = -1;
  for (int k = 0; k < base.m(); ++k) {
    if (base.rows[static_cast<size_t>(k)].type == RowType::Equality && first_eq < 0) first_eq = k;
    if (base.rows[static_cast<size_t>(k)].type == RowType::Inequality && first_ineq < 0) first_ineq = k;
  }
  ASSERT_GE(first_eq, 0);
  ASSERT_GE(first_ineq, 0);
  struct Case {
    const char* name;
    TProblem P;
  };
  std::vector<Case> cases;
  auto add = [&](const char* name, auto edit) {
    Case c{name, base};
    edit(c.P);
    cases.push_back(c);
  };
  add("NaN in z_u", [&](TProblem& P) { P.zu[1][3] = nan; });
  add("Inf in z_u", [&](TProblem& P) { P.zu[0][0] = inf; });
  add("NaN c, equality", [&](TProblem& P) { P.rows[static_cast<size_t>(first_eq)].c = nan; });
  add("NaN c, inequality", [&](TProblem& P) { P.rows[static_cast<size_t>(first_ineq)].c = nan; });
  add("+Inf c, inequality", [&](TProblem& P) { P.rows[static_cast<size_t>(first_ineq)].c = inf; });
  add("-Inf c, inequality", [&](TProblem& P) { P.rows[static_cast<size_t>(first_ineq)].c = -inf; });
  add("NaN in J", [&](TProblem& P) { P.rows[static_cast<size_t>(first_ineq)].J0[2] = nan; });
  add("NaN in z_u, no rows", [&](TProblem& P) {
    P.rows.clear();
    P.zu[2][1] = nan;
  });
  ActiveSetSolver solver;
  PgsSolver pgs(PgsSettings{20, 1.0});
  QpProblem qp;
  QpSolution sol;
  for (const Case& c : cases) {
    c.P.load(qp);
    for (int which = 0; which < 2; ++which) {
      const SolveStats st = which == 0 ? solver.solve(qp, sol) : pgs.solve(qp, sol);
      bool finite = true;
      for (const Vec6& z : sol.z) finite = finite && z.allFinite();
      for (double l : sol.lambda) finite = finite && std::isfinite(l);
      std::printf("[ stats    ] %-20s %-10s -> %-17s output %s\n", c.name, which == 0 ? "exact" : "PGS",
                  toString(st.status), finite ? "finite" : "non-finite");
      // Either a clear failure or a finite answer; never a non-finite answer reported as usable.
      EXPECT_TRUE(st.status == SolveStatus::NumericalFailure || finite) << c.name;
      if (st.status != SolveStatus::NumericalFailure) {
        EXPECT_TRUE(finite) << c.name;
      }
    }
  }
  // Documented behaviour of the exact solver (pinned): every non-finite input that can change the
  // answer is a NumericalFailure; a row J z ≥ −inf is inert and the solve converges.
  //   NaN / Inf in z_u, NaN c of an equality: z itself is non-finite.
  //   NaN c or NaN J of an inequality, c = +inf: z stays finite but the row's feasibility is
  //   unknown or impossible; kktResidual reports it (before the fix these were silently dropped
  //   and reported Converged).
  for (size_t i = 0; i < cases.size(); ++i) {
    cases[i].P.load(qp);
    const SolveStatus expected =
        std::string(cases[i].name) == "-Inf c, inequality" ? SolveStatus::Converged : SolveStatus::NumericalFailure;
    EXPECT_EQ(solver.solve(qp, sol).status, expected) << cases[i].name;
  }
  // The solvers are not poisoned: the clean problem still solves exactly afterwards.
  CategoryStats cat{"after non-finite"};
  ASSERT_NO_FATAL_FAILURE(solveAndCheck(base, solver, qp, sol, cat, "after NaN"));
}

TEST(SolverExtremes, ZeroRowIsIgnored) {
  Rng rng(1010);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution with, without;
  CategoryStats cat{"zero rows"};
  for (int i = 0; i < 200; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 4);
    o.num_eq = rng.integer(0, 2 * o.N);
    o.num_ineq = rng.integer(1, 8 * o.N);
    const TProblem P = generate(rng, o);
    TProblem Z = P;
    const int zeros = rng.integer(1, 3);
    for (int k = 0; k < zeros; ++k) {
      TRow r;
      r.type = (k == 2) ? RowType::Equality : RowType::Inequality;
      r.b0 = rng.integer(0, o.N - 1);
      r.c = (k == 0 || r.type == RowType::Equality) ? 0.0 : -std::abs(rng.normal());  // J = 0, c ≤ 0 (= 0 for E)
      Z.rows.insert(Z.rows.begin() + rng.integer(0, Z.m()), r);
    }
    ASSERT_NO_FATAL_FAILURE(solveAndCheck(Z, solver, qp, with, cat, "zero row"));
    for (int k = 0; k < Z.m(); ++k)
      if (Z.rows[static_cast<size_t>(k)].J0.isZero(0.0)) {
        EXPECT_EQ(with.lambda[static_cast<size_t>(k)], 0.0);
      }
    P.load(qp);
    ASSERT_EQ(solver.solve(qp, without).status, SolveStatus::Converged);
    EXPECT_LE(relDiffZ(with.z, without.z, P.zu), 1e-12);
  }
  cat.print();
}

// ---------------------------------------------------------------------------------------------
// Known weaknesses: these run every time, assert what does hold (no crash, finite output, an honest
// status), and skip with the measured numbers while the weakness remains. When the solver is
// improved they start asserting the full KKT bound on their own.

TEST(SolverWeakness, NearParallelEqualityRows) {
  // Two bodies tied by an equality row and its twin tilted by `angle` (a0,z = a1,z and, through
  // the `angle` lever, a0,x = a1,x), plus contacts. A = J M⁻¹ Jᵀ has cond ~ 1/angle². The pair's
  // multipliers grow like 1/angle with opposite signs and cancel in z = z_u + M⁻¹Jᵀλ, and below
  // ~sqrt(ε_reg) = 3e-7 the twin's Schur complement falls under the regularisation ε A_kk so the
  // pair is solved as a duplicate: the rows' residual is round-off on the scale of the arithmetic
  // (|J|(|z_u| + |M⁻¹||J|ᵀ|λ|)) but 1e-8 … 2e-7 of |J||z|, i.e. the a0,x = a1,x tie is loose.
  Rng rng(1313);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  std::string failures;
  for (double angle : {1e-8, 1e-7, 1e-6, 1e-5, 1e-4}) {
    double worst = 0.0, worst_roundoff = 0.0;
    for (int rep = 0; rep < 100; ++rep) {
      TProblem P;
      P.N = 2;
      for (int b = 0; b < 2; ++b) {
        P.M.push_back(randomMass(rng, -2, 1, 1.0));
        Vec6 zu = rng.vec6();
        zu[2] = -10.0 * std::abs(rng.normal());
        P.zu.push_back(zu);
      }
      for (int k = 0; k < 3; ++k) {
        const int b = rng.integer(0, 1);
        const Vec3 n = rng.unit3();
        const Vec3 r = 0.01 * rng.unit3();
        P.rows.push_back(contactRow(b, n, r, -1e-3));
      }
      TRow row;
      row.type = RowType::Equality;
      row.b0 = 0;
      row.b1 = 1;
      row.J0 << 0, 0, 1, 0, 0, 0;
      row.J1 << 0, 0, -1, 0, 0, 0;
      P.rows.push_back(row);
      row.J0[0] = angle;
      row.J1[0] = -angle;
      P.rows.push_back(row);
      P.load(qp);
      const SolveStats st = solver.solve(qp, sol);
      const Kkt k = oracleKkt(P, sol);
      ASSERT_EQ(st.status, SolveStatus::Converged) << angle;
      ASSERT_TRUE(k.finite());
      ASSERT_LE(k.maxRoundoff(), kKktTol) << angle;  // round-off-level on the arithmetic's own scale
      worst = std::max(worst, k.max());
      worst_roundoff = std::max(worst_roundoff, k.maxRoundoff());
    }
    std::printf("[ stats    ] near-parallel equality pair at %.0e rad: max KKT %.2e (round-off-scaled %.2e)\n", angle,
                worst, worst_roundoff);
    if (worst > kKktTol) {
      char buf[128];
      std::snprintf(buf, sizeof(buf), " angle %.0e: KKT %.2e;", angle, worst);
      failures += buf;
    }
  }
  if (!failures.empty()) {
    GTEST_SKIP() << "KNOWN WEAKNESS (normal equations + regularisation 1e-13): near-parallel equality rows are "
                    "solved as duplicates, primal residual above 1e-9:"
                 << failures;
  }
}

// The draw of SolverWeakness.MixedDegenerateProblems and Solver.ProximalIterations…: redundant,
// duplicated and near-parallel rows (1e-8 … 1e-4) with many inequalities.
GenOptions mixedDegenerateOptions(Rng& rng) {
  GenOptions o;
  o.N = rng.integer(1, 8);
  o.num_eq = rng.integer(0, 4 * o.N);
  o.num_ineq = rng.integer(0, 20 * o.N);
  o.num_redundant = rng.integer(0, 2 * o.N);
  o.num_duplicates = rng.integer(0, 2 * o.N);
  o.num_near_parallel = rng.integer(0, 2 * o.N);
  o.near_eps = rng.logUniform(-8.0, -4.0);
  return o;
}

// The proximal iterations (ActiveSetSettings::proximal_iterations) on the degenerate problems
// of SolverWeakness.MixedDegenerateProblems, drawn afresh (another seed, 2000 problems): the same
// solver without them is the control. Measured before this test was written, 2 × 5000 problems
// of other seeds: 97 and 110 ended Stalled or at the iteration limit without them, 1 and 1 with
// them (KKT 2.6e-9 and 3.1e-7, both reported Stalled).
TEST(Solver, ProximalIterationsFinishDegenerateProblems) {
  ActiveSetSettings off;
  off.proximal_iterations = 0;
  ActiveSetSolver with, without(off);
  ASSERT_GT(with.settings().proximal_iterations, 0);
  Rng rng(20261206);
  QpProblem qp;
  QpSolution sol, sol_off;
  CategoryStats cat{"degenerate, proximal"};
  int open_with = 0, open_without = 0;
  constexpr int kProblems = 2000;
  for (int i = 0; i < kProblems; ++i) {
    const TProblem P = generate(rng, mixedDegenerateOptions(rng));
    P.load(qp);
    const SolveStats st_off = without.solve(qp, sol_off);
    const SolveStats st = with.solve(qp, sol);
    open_without += st_off.status != SolveStatus::Converged ? 1 : 0;
    const Kkt k = oracleKkt(P, sol);
    ASSERT_TRUE(k.finite()) << i;
    ASSERT_NE(st.status, SolveStatus::NumericalFailure) << i;
    for (int r = 0; r < P.m(); ++r) {
      if (P.rows[static_cast<size_t>(r)].type == RowType::Inequality) {
        ASSERT_GE(sol.lambda[static_cast<size_t>(r)], 0.0) << i;
      }
    }
    // A solve the first pass finished is not touched.
    if (st_off.status == SolveStatus::Converged) {
      ASSERT_EQ(st.status, SolveStatus::Converged) << i;
      for (size_t b = 0; b < sol.z.size(); ++b) ASSERT_EQ(sol.z[b], sol_off.z[b]) << i;
    }
    if (st.status != SolveStatus::Converged) {
      ++open_with;
      // Never worse than without, and honest: the library's residual is the oracle's.
      EXPECT_LE(st.kkt_residual, st_off.kkt_residual) << i;
      EXPECT_GE(st.kkt_residual, 0.25 * k.maxRoundoff() - kKktTol) << i;
      EXPECT_LE(st.kkt_residual, 4.0 * k.maxRoundoff() + kKktTol) << i;
      continue;
    }
    // Converged means the KKT conditions hold on the round-off scale, by the independent oracle.
    ASSERT_NO_FATAL_FAILURE(checkExact(P, sol, st, cat, "degenerate, proximal"));
  }
  cat.print();
  std::printf("[ stats    ] of %d degenerate problems not converged: %d without the proximal iterations, %d with them\n",
              kProblems, open_without, open_with);
  // The control shows the problems are the hard ones (~2 % measured), the iterations finish all
  // but a few of them.
  EXPECT_GE(open_without, kProblems / 200);
  EXPECT_LE(open_with, kProblems / 500);
}

TEST(SolverWeakness, MixedDegenerateProblems) {
  // Random problems mixing redundant, duplicated and near-parallel rows (1e-8 … 1e-4) with many
  // inequalities tight at a feasible point (degenerate vertices). Measured over 10 000 such
  // problems: ~2 % end Stalled, with KKT up to ~1e-2: a row that must enter is numerically
  // dependent on a full, ill-conditioned passive set (|P| = 6N, cond(A_PP) ≳ 1e12), its Schur
  // complement is noise, its new multiplier comes out ≤ 0 and it is blocked. A Goldfarb–Idnani
  // "dependent constraint" exchange step fixes some of these but cycles on others. Since
  // 2026-12-06 such a solve goes on with proximal iterations (regularised around the last
  // multipliers, ActiveSetSettings::proximal_iterations), which finish all but ~1 in 5000
  // (Solver.ProximalIterationsFinishDegenerateProblems); this test skips while any is left.
  Rng rng(1414);
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  CategoryStats cat{"mixed degenerate"};
  int stalled = 0, other = 0, over_roundoff = 0;
  double worst_stalled = 0.0;
  for (int i = 0; i < 500; ++i) {
    const TProblem P = generate(rng, mixedDegenerateOptions(rng));
    P.load(qp);
    const SolveStats st = solver.solve(qp, sol);
    const Kkt k = oracleKkt(P, sol);
    // What always holds: finite output, λ_I ≥ 0, an honest status.
    ASSERT_TRUE(k.finite()) << i;
    ASSERT_NE(st.status, SolveStatus::NumericalFailure);
    ASSERT_NE(st.status, SolveStatus::SweepLimit);
    for (int r = 0; r < P.m(); ++r) {
      if (P.rows[static_cast<size_t>(r)].type == RowType::Inequality) {
        ASSERT_GE(sol.lambda[static_cast<size_t>(r)], 0.0);
      }
    }
    if (st.status != SolveStatus::Converged) {
      (st.status == SolveStatus::Stalled ? stalled : other) += 1;
      worst_stalled = std::max(worst_stalled, k.max());
      // Reported, never hidden: the status says Stalled, and the library's own residual (measured,
      // like the solver's acceptance test, on the round-off scale of J z) matches the oracle's.
      // The oracle's scale |M⁻¹||J|ᵀ|λ| bounds the library's |M⁻¹Jᵀ||λ| from above: agree within 4×.
      EXPECT_GE(st.kkt_residual, 0.25 * k.maxRoundoff() - kKktTol);
      EXPECT_LE(st.kkt_residual, 4.0 * k.maxRoundoff() + kKktTol);
      continue;
    }
    if (k.maxRoundoff() > kKktTol) {
      ++over_roundoff;
      continue;
    }
    ASSERT_NO_FATAL_FAILURE(checkExact(P, sol, st, cat, "mixed, converged"));
  }
  cat.print();
  std::printf("[ stats    ] mixed degenerate: of 500, %d stalled and %d at the iteration limit (max KKT %.2e); %d "
              "converged but above 1e-9 on the round-off scale\n", stalled, other, worst_stalled, over_roundoff);
  if (stalled + other + over_roundoff > 0) {
    GTEST_SKIP() << "KNOWN WEAKNESS: of 500 mixed degenerate problems " << stalled << " end Stalled and " << other
                 << " at the iteration limit (max KKT " << worst_stalled << "), " << over_roundoff
                 << " converge above 1e-9 (round-off scale): a dependent entering row with a noise Schur "
                 << "complement in a full, ill-conditioned passive set";
  }
}

// ---------------------------------------------------------------------------------------------
// Determinism.

std::uint64_t hashSolution(const QpSolution& s) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a over the raw bytes
  auto mix = [&](const void* data, size_t n) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  };
  for (const Vec6& z : s.z) mix(z.data(), sizeof(double) * 6);
  mix(s.lambda.data(), sizeof(double) * s.lambda.size());
  return h;
}

TEST(SolverDeterminism, BitIdenticalAcrossFreshAndReusedSolvers) {
  Rng rng(1111);
  ActiveSetSolver reused;
  PgsSolver pgs_reused(PgsSettings{50, 1.0});
  QpProblem qp_reused;
  QpSolution a, b, c;
  for (int i = 0; i < 300; ++i) {
    GenOptions o;
    o.N = rng.integer(1, 8);
    o.num_eq = rng.integer(0, 3 * o.N);
    o.num_ineq = rng.integer(0, 15 * o.N);
    o.num_duplicates = rng.integer(0, 2);
    o.num_near_parallel = rng.integer(0, 2);
    const TProblem P = generate(rng, o);
    {
      ActiveSetSolver fresh;
      QpProblem qp;
      P.load(qp);
      fresh.solve(qp, a);
      fresh.solve(qp, b);  // same solver twice
    }
    // Reused solver and problem storage, after having solved a different (larger) problem.
    GenOptions big = o;
    big.N = 8;
    big.num_ineq = 150;
    generate(rng, big).load(qp_reused);
    reused.solve(qp_reused, c);
    P.load(qp_reused);
    reused.solve(qp_reused, c);
    ASSERT_EQ(a.z.size(), c.z.size());
    ASSERT_EQ(0, std::memcmp(a.z.data(), b.z.data(), sizeof(Vec6) * a.z.size())) << i;
    ASSERT_EQ(0, std::memcmp(a.z.data(), c.z.data(), sizeof(Vec6) * a.z.size())) << i;
    ASSERT_EQ(0, std::memcmp(a.lambda.data(), c.lambda.data(), sizeof(double) * a.lambda.size())) << i;
    ASSERT_EQ(hashSolution(a), hashSolution(b));
    ASSERT_EQ(hashSolution(a), hashSolution(c));
    // PGS too.
    PgsSolver pgs_fresh(PgsSettings{50, 1.0});
    QpProblem qp;
    P.load(qp);
    pgs_fresh.solve(qp, a);
    pgs_reused.solve(qp_reused, c);
    ASSERT_EQ(hashSolution(a), hashSolution(c)) << i;
  }
}

// ---------------------------------------------------------------------------------------------
// Analytic cases.

TEST(SolverAnalytic, SingleContactProjectsNormalComponent) {
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  Rng rng(1212);
  for (int i = 0; i < 200; ++i) {
    const double m = rng.logUniform(-3, 3);
    const Vec3 I = m * rng.uniform3(0.1, 1);
    const double c = rng.normal();
    Vec6 zu = rng.vec6() * 10;
    const bool into = i % 4 != 3;
    zu[2] = into ? c - std::abs(rng.normal()) - 1e-3 : c + std::abs(rng.normal());
    qp.reset(1);
    const double angle = rng.uniform(0, 3);
    qp.setRigidMass(0, m, Eigen::AngleAxisd(angle, rng.unit3()).toRotationMatrix(), I);
    qp.unconstrained(0) = zu;
    Vec6 J;
    J << 0, 0, 1, 0, 0, 0;  // n = +Z at u = 0: J = (n, u × n)
    qp.addRow(RowType::Inequality, 0, J, -1, Vec6::Zero(), c, 7);
    qp.finalize();
    ASSERT_EQ(solver.solve(qp, sol).status, SolveStatus::Converged);
    Vec6 expected = zu;
    double lambda = 0.0;
    if (into) {
      expected[2] = c;
      lambda = m * (c - zu[2]);
    }
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(sol.z[0][k], expected[k], 1e-14 * (std::abs(expected[k]) + std::abs(c) + 1)) << k;
    EXPECT_NEAR(sol.lambda[0], lambda, 1e-13 * (m * (std::abs(c) + std::abs(zu[2])))) << i;
  }
}

TEST(SolverAnalytic, TwoOrthogonalContactsAndAnEquality) {
  // A point mass (linear part only matters) with contacts on +Z and +X and an equality a_y = e:
  // each component is clamped independently, λ = m · (c − z_u) where active.
  ActiveSetSolver solver;
  QpProblem qp;
  QpSolution sol;
  const double m = 2.5;
  qp.reset(1);
  qp.setRigidMass(0, m, Mat3::Identity(), Vec3(1, 1, 1));
  Vec6 zu;
  zu << -3.0, 4.0, -7.0, 0.5, 0.25, -1.0;
  qp.unconstrained(0) = zu;
  Vec6 nz, nx, ey;
  nz << 0, 0, 1, 0, 0, 0;
  nx << 1, 0, 0, 0, 0, 0;
  ey << 0, 1, 0, 0, 0, 0;
  qp.addRow(RowType::Inequality, 0, nz, -1, Vec6::Zero(), -1.0, 1);  // active: -7 < -1
  qp.addRow(RowType::Inequality, 0, nx, -1, Vec6::Zero(), -5.0, 2);  // inactive: -3 > -5
  qp.addRow(RowType::Equality, 0, ey, -1, Vec6::Zero(), 1.5, 3);
  qp.finalize();
  ASSERT_EQ(solver.solve(qp, sol).status, SolveStatus::Converged);
  Vec6 expected = zu;
  expected[2] = -1.0;
  expected[1] = 1.5;
  EXPECT_LE((sol.z[0] - expected).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_NEAR(sol.lambda[0], m * 6.0, 1e-13);
  EXPECT_EQ(sol.lambda[1], 0.0);
  EXPECT_NEAR(sol.lambda[2], m * (1.5 - 4.0), 1e-13);
}

}  // namespace
}  // namespace godhand
