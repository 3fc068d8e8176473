#include "poise/controller/acceleration_solver.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace poise::controller {

void AccelerationSolver::resize(int nv, int max_eq) {
  if (nv < 7) throw std::invalid_argument("AccelerationSolver: nv must be >= 7");
  if (max_eq < 0) throw std::invalid_argument("AccelerationSolver: max_eq must be >= 0");
  nv_ = nv;
  max_eq_ = max_eq;
  const int n = nv - 6;
  qp_.resize(nv, max_eq, 2 * n);
  G_.setZero(nv, nv);
  g_.setZero(nv);
  A_in_.setZero(2 * n, nv);
  for (int j = 0; j < n; ++j) {
    A_in_(j, 6 + j) = 1.0;
    A_in_(n + j, 6 + j) = -1.0;
  }
  b_in_.setZero(2 * n);
  L_.setZero(nv, nv);
  Y_.setZero(nv, max_eq);
  S_.setZero(max_eq, max_eq);
  u_.setZero(nv);
  lambda_.setZero(max_eq);
  r_.setZero(max_eq);
}

bool AccelerationSolver::solve_equality_only(const Eigen::Ref<const Eigen::MatrixXd>& C,
                                             const Eigen::Ref<const Eigen::VectorXd>& d,
                                             Eigen::Ref<Eigen::VectorXd> x) {
  // G x + g = C^T lambda, C x = d.  With G = L L^T, Y = L^-1 C^T, u = L^-1 g:
  //   (Y^T Y) lambda = d + Y^T u,   x = L^-T (Y lambda - u).
  const Eigen::Index m = C.rows();
  L_ = G_;
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt_g(L_);
  if (llt_g.info() != Eigen::Success) return false;
  const auto L = llt_g.matrixL();
  u_ = g_;
  L.solveInPlace(u_);
  if (m > 0) {
    auto Y = Y_.leftCols(m);
    Y = C.transpose();
    L.solveInPlace(Y);
    auto S = S_.topLeftCorner(m, m);
    S.noalias() = Y.transpose() * Y;
    auto lambda = lambda_.head(m);
    lambda = d;
    lambda.noalias() += Y.transpose() * u_;
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt_s(S);
    if (llt_s.info() != Eigen::Success) return false;
    llt_s.solveInPlace(lambda);
    x.noalias() = Y * lambda;
    x -= u_;
  } else {
    x = -u_;
  }
  L.transpose().solveInPlace(x);
  return x.allFinite();
}

AccelerationSolver::Result AccelerationSolver::solve(
    const Eigen::Ref<const Eigen::MatrixXd>& A, const Eigen::Ref<const Eigen::VectorXd>& b,
    double w_b, const Eigen::Ref<const Eigen::VectorXd>& w,
    const Eigen::Ref<const Eigen::VectorXd>& t, const Eigen::Ref<const Eigen::MatrixXd>& C,
    const Eigen::Ref<const Eigen::VectorXd>& d, const Eigen::Ref<const Eigen::VectorXd>& lo,
    const Eigen::Ref<const Eigen::VectorXd>& hi, Eigen::Ref<Eigen::VectorXd> x) {
  Result r;
  const int n = nv_ - 6;
  if (nv_ == 0 || A.rows() != 6 || A.cols() != nv_ || b.size() != 6 || w.size() != nv_ ||
      t.size() != nv_ || C.cols() != nv_ || C.rows() > max_eq_ || d.size() != C.rows() ||
      lo.size() != n || hi.size() != n || x.size() != nv_ || !(w_b > 0.0 && w_b < 1.0)) {
    if (x.size() > 0) x.setZero();
    return r;
  }
  // 0.5 x^T G x + g^T x  ==  0.5 * objective + const.
  G_.noalias() = A.transpose() * A;
  G_ *= w_b;
  G_.diagonal() += w;
  g_.noalias() = A.transpose() * b;
  g_ *= -w_b;
  g_ -= w.cwiseProduct(t);
  b_in_.head(n) = lo;
  b_in_.tail(n) = -hi;

  if (fast_path_ && solve_equality_only(C, d, x)) {
    bool inside = true;
    for (int j = 0; j < n && inside; ++j) {
      const double tol = 1e-9 * (1.0 + std::abs(x[6 + j]));
      inside = x[6 + j] >= lo[j] - tol && x[6 + j] <= hi[j] + tol;
    }
    if (inside) {
      r.status = contact::SolverStatus::kOptimal;
      return r;
    }
  }
  r.used_active_set = true;
  r.status = qp_.solve(G_, g_, C, d, A_in_, b_in_, x);
  r.iterations = qp_.iterations();
  if (r.status == contact::SolverStatus::kInfeasible) {
    r.bounds_dropped = true;
    r.status = qp_.solve(G_, g_, C, d, A_in_.topRows(0), b_in_.head(0), x);
    r.iterations += qp_.iterations();
    return r;
  }
  r.active_bounds = qp_.active_set_size() - static_cast<int>(C.rows());
  return r;
}

void joint_acceleration_bounds(const Eigen::Ref<const Eigen::VectorXd>& q,
                               const Eigen::Ref<const Eigen::VectorXd>& qd,
                               const Eigen::Ref<const Eigen::VectorXd>& q_min,
                               const Eigen::Ref<const Eigen::VectorXd>& q_max, double horizon,
                               double a_max, Eigen::Ref<Eigen::VectorXd> lo,
                               Eigen::Ref<Eigen::VectorXd> hi) {
  const double k = 2.0 / (horizon * horizon);
  for (Eigen::Index j = 0; j < q.size(); ++j) {
    const double pred = q[j] + qd[j] * horizon;
    double l = std::isfinite(q_min[j]) ? k * (q_min[j] - pred) : -a_max;
    double h = std::isfinite(q_max[j]) ? k * (q_max[j] - pred) : a_max;
    l = std::clamp(l, -a_max, a_max);
    h = std::clamp(h, -a_max, a_max);
    lo[j] = l;
    hi[j] = h;
  }
}

}  // namespace poise::controller
