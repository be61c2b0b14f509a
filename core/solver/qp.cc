#include "solver/qp.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

namespace godhand {

void QpProblem::reset(int num_bodies) {
  num_bodies_ = num_bodies;
  M_.resize(static_cast<size_t>(num_bodies));
  Minv_.resize(static_cast<size_t>(num_bodies));
  zu_.resize(static_cast<size_t>(num_bodies));
  for (auto& z : zu_) z.setZero();
  rows_.clear();
}

void QpProblem::setMass(int body, const Mat6& M) {
  M_[static_cast<size_t>(body)] = M;
  Eigen::LLT<Mat6> llt(M);
  Minv_[static_cast<size_t>(body)] = llt.solve(Mat6::Identity());
}

void QpProblem::setRigidMass(int body, double mass, const Mat3& R, const Vec3& I) {
  Mat6& M = M_[static_cast<size_t>(body)];
  Mat6& Mi = Minv_[static_cast<size_t>(body)];
  M.setZero();
  Mi.setZero();
  M.topLeftCorner<3, 3>().diagonal().setConstant(mass);
  Mi.topLeftCorner<3, 3>().diagonal().setConstant(1.0 / mass);
  M.bottomRightCorner<3, 3>() = R * I.asDiagonal() * R.transpose();
  Mi.bottomRightCorner<3, 3>() = R * I.cwiseInverse().asDiagonal() * R.transpose();
}

Row& QpProblem::addRow(RowType type, int body0, const Vec6& J0, int body1, const Vec6& J1, double c,
                       std::uint64_t key) {
  rows_.emplace_back();
  Row& r = rows_.back();
  r.type = type;
  r.body0 = body0;
  r.J0 = J0;
  r.body1 = body1;
  if (body1 >= 0) r.J1 = J1;
  r.c = c;
  r.key = key;
  return r;
}

void QpProblem::finalize() {
  for (Row& r : rows_) {
    r.W0 = Minv_[static_cast<size_t>(r.body0)] * r.J0;
    double jzu = r.J0.dot(zu_[static_cast<size_t>(r.body0)]);
    r.diag = r.J0.dot(r.W0);
    if (r.body1 >= 0) {
      r.W1 = Minv_[static_cast<size_t>(r.body1)] * r.J1;
      jzu += r.J1.dot(zu_[static_cast<size_t>(r.body1)]);
      r.diag += r.J1.dot(r.W1);
    } else {
      r.W1.setZero();
    }
    r.b = r.c - jzu;
  }
}

double QpProblem::rowDot(int k, const Vec6* z) const {
  const Row& r = rows_[static_cast<size_t>(k)];
  double s = r.J0.dot(z[r.body0]);
  if (r.body1 >= 0) s += r.J1.dot(z[r.body1]);
  return s;
}

double QpProblem::rowAbsDot(int k, const Vec6* z) const {
  const Row& r = rows_[static_cast<size_t>(k)];
  double s = r.J0.cwiseAbs().dot(z[r.body0].cwiseAbs());
  if (r.body1 >= 0) s += r.J1.cwiseAbs().dot(z[r.body1].cwiseAbs());
  return s;
}

const char* toString(SolveStatus s) {
  switch (s) {
    case SolveStatus::Converged: return "converged";
    case SolveStatus::IterationLimit: return "iteration-limit";
    case SolveStatus::SweepLimit: return "sweep-limit";
    case SolveStatus::Stalled: return "stalled";
    case SolveStatus::NumericalFailure: return "numerical-failure";
  }
  return "?";
}

double KktResidual::max() const { return std::max({stationarity, primal, dual, complementarity}); }

KktResidual kktResidual(const QpProblem& p, const QpSolution& s) {
  std::vector<Vec6> scratch;
  return kktResidual(p, s, scratch);
}

KktResidual kktResidual(const QpProblem& p, const QpSolution& s, std::vector<Vec6>& jtl) {
  constexpr double kTiny = 1e-300;
  KktResidual r;
  const int n = p.numBodies(), m = p.numRows();
  double lam_max = 0.0;
  if (jtl.size() < 2 * static_cast<size_t>(n)) jtl.resize(2 * static_cast<size_t>(n));
  for (auto& v : jtl) v.setZero();
  Vec6* absz = jtl.data() + n;  // |z_u| + Σ |λ| |M⁻¹Jᵀ| per body: the round-off scale of z
  for (int b = 0; b < n; ++b) absz[b] = p.unconstrained(b).cwiseAbs();
  for (int k = 0; k < m; ++k) {
    const Row& row = p.row(k);
    const double l = s.lambda[static_cast<size_t>(k)];
    lam_max = std::max(lam_max, std::abs(l));
    jtl[static_cast<size_t>(row.body0)] += l * row.J0;
    absz[row.body0] += std::abs(l) * row.W0.cwiseAbs();
    if (row.body1 >= 0) {
      jtl[static_cast<size_t>(row.body1)] += l * row.J1;
      absz[row.body1] += std::abs(l) * row.W1.cwiseAbs();
    }
  }
  // Stationarity, body by body: M_b (z_b − z_u,b) − Σ_k J_k,bᵀ λ_k.
  double stat = 0.0, scale = kTiny;
  bool finite = true;  // NaN must not vanish in a max(): track it explicitly
  for (int b = 0; b < n; ++b) {
    const Vec6& jb = jtl[static_cast<size_t>(b)];
    const Vec6 mz = p.mass(b) * (s.z[static_cast<size_t>(b)] - p.unconstrained(b));
    finite = finite && mz.allFinite() && jb.allFinite();
    stat = std::max(stat, (mz - jb).cwiseAbs().maxCoeff());
    scale = std::max({scale, mz.cwiseAbs().maxCoeff(), jb.cwiseAbs().maxCoeff(),
                      (p.mass(b) * p.unconstrained(b)).cwiseAbs().maxCoeff()});
  }
  r.stationarity = stat / scale;
  for (int k = 0; k < m; ++k) {
    const Row& row = p.row(k);
    const Vec6& z0 = s.z[static_cast<size_t>(row.body0)];
    double jz = row.J0.dot(z0);
    double sk = row.J0.cwiseAbs().dot(z0.cwiseAbs());
    double su = row.J0.cwiseAbs().dot(absz[row.body0]);
    if (row.body1 >= 0) {
      const Vec6& z1 = s.z[static_cast<size_t>(row.body1)];
      jz += row.J1.dot(z1);
      sk += row.J1.cwiseAbs().dot(z1.cwiseAbs());
      su += row.J1.cwiseAbs().dot(absz[row.body1]);
    }
    const double scale_k = std::max({std::abs(row.c), sk, su, kTiny});
    const double slack = jz - row.c;
    const double l = s.lambda[static_cast<size_t>(k)];
    // A NaN slack (NaN c or J) or an unbounded violation (c = +inf) is not a satisfied row.
    const double viol = row.type == RowType::Equality ? std::abs(slack) : (slack >= 0.0 ? 0.0 : -slack);
    const double primal_k = viol / scale_k;
    finite = finite && !std::isnan(primal_k);
    r.primal = std::max(r.primal, primal_k);
    if (row.type == RowType::Inequality) {
      if (lam_max > 0.0) {
        r.dual = std::max(r.dual, std::max(0.0, -l) / lam_max);
        r.complementarity = std::max(r.complementarity, std::min(std::abs(l) / lam_max, std::abs(slack) / scale_k));
      }
    }
  }
  if (!finite || !std::isfinite(r.max())) r.stationarity = std::numeric_limits<double>::infinity();
  return r;
}

}  // namespace godhand
