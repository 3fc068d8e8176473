#include "poise/contact/dual_qp.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace poise::contact {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool all_finite(const Eigen::Ref<const Eigen::MatrixXd>& M) {
  for (Eigen::Index j = 0; j < M.cols(); ++j)
    for (Eigen::Index i = 0; i < M.rows(); ++i)
      if (!std::isfinite(M(i, j))) return false;
  return true;
}

}  // namespace

void DualQp::resize(int max_vars, int max_eq, int max_ineq) {
  if (max_vars <= 0 || max_eq < 0 || max_ineq < 0) {
    throw std::invalid_argument("DualQp::resize: bad sizes (vars " + std::to_string(max_vars) +
                                ", eq " + std::to_string(max_eq) + ", ineq " +
                                std::to_string(max_ineq) + ")");
  }
  max_vars_ = max_vars;
  max_eq_ = max_eq;
  max_ineq_ = max_ineq;
  if (max_iterations_ == 0) max_iterations_ = 4 * (max_vars + max_eq + max_ineq) + 20;
  L_.setZero(max_vars, max_vars);
  J_.setZero(max_vars, max_vars);
  R_.setZero(max_vars, max_vars);
  d_.setZero(max_vars);
  z_.setZero(max_vars);
  r_.setZero(max_vars);
  u_.setZero(max_vars);
  np_.setZero(max_vars);
  active_.setZero(max_vars);
  lambda_eq_.setZero(std::max(max_eq, 1));
  u_in_.setZero(std::max(max_ineq, 1));
  is_active_.setZero(std::max(max_ineq, 1));
}

void DualQp::add_to_active_set(int n) {
  // Rotate d = J^T n+ so that d(q+1:n) = 0, rotating the columns of J alike; then d(0:q) is the new
  // column of R.
  const int q = q_;
  for (int j = n - 1; j > q; --j) {
    const double a = d_[j - 1];
    const double b = d_[j];
    if (b == 0.0) continue;
    const double h = std::hypot(a, b);
    const double c = a / h;
    const double s = b / h;
    d_[j - 1] = h;
    d_[j] = 0.0;
    for (int k = 0; k < n; ++k) {
      const double t1 = J_(k, j - 1);
      const double t2 = J_(k, j);
      J_(k, j - 1) = c * t1 + s * t2;
      J_(k, j) = -s * t1 + c * t2;
    }
  }
  for (int i = 0; i <= q; ++i)
    R_(i, q) = d_[i];
  for (int i = q + 1; i < n; ++i)
    R_(i, q) = 0.0;
  ++q_;
}

void DualQp::drop_from_active_set(int n, int k) {
  const int q = q_;
  // Remove column k of R and entry k of the active list and multipliers.
  for (int c = k; c < q - 1; ++c) {
    for (int i = 0; i < q; ++i)
      R_(i, c) = R_(i, c + 1);
    active_[c] = active_[c + 1];
    u_[c] = u_[c + 1];
  }
  // R is now upper Hessenberg from column k on: restore triangularity by row rotations, which
  // rotate the matching columns of J.
  for (int j = k; j < q - 1; ++j) {
    const double a = R_(j, j);
    const double b = R_(j + 1, j);
    if (b == 0.0) continue;
    const double h = std::hypot(a, b);
    const double c = a / h;
    const double s = b / h;
    for (int col = j; col < q - 1; ++col) {
      const double t1 = R_(j, col);
      const double t2 = R_(j + 1, col);
      R_(j, col) = c * t1 + s * t2;
      R_(j + 1, col) = -s * t1 + c * t2;
    }
    R_(j + 1, j) = 0.0;
    for (int row = 0; row < n; ++row) {
      const double t1 = J_(row, j);
      const double t2 = J_(row, j + 1);
      J_(row, j) = c * t1 + s * t2;
      J_(row, j + 1) = -s * t1 + c * t2;
    }
  }
  for (int i = 0; i < q; ++i)
    R_(i, q - 1) = 0.0;
  --q_;
}

SolverStatus DualQp::solve(const Eigen::Ref<const Eigen::MatrixXd>& G,
                           const Eigen::Ref<const Eigen::VectorXd>& g,
                           const Eigen::Ref<const Eigen::MatrixXd>& A_eq,
                           const Eigen::Ref<const Eigen::VectorXd>& b_eq,
                           const Eigen::Ref<const Eigen::MatrixXd>& A_in,
                           const Eigen::Ref<const Eigen::VectorXd>& b_in,
                           Eigen::Ref<Eigen::VectorXd> x) {
  iterations_ = 0;
  q_ = 0;
  objective_ = 0.0;
  const int n = static_cast<int>(G.rows());
  const int meq = static_cast<int>(A_eq.rows());
  const int min = static_cast<int>(A_in.rows());
  if (x.size() > 0) x.setZero();
  lambda_eq_.setZero();
  u_in_.setZero();
  if (n <= 0 || n > max_vars_ || G.cols() != n || g.size() != n || x.size() != n || meq > max_eq_ ||
      min > max_ineq_ || (meq > 0 && A_eq.cols() != n) || b_eq.size() != meq ||
      (min > 0 && A_in.cols() != n) || b_in.size() != min || !all_finite(G) || !all_finite(g) ||
      !all_finite(A_eq) || !all_finite(b_eq) || !all_finite(A_in) || !all_finite(b_in)) {
    return SolverStatus::kInvalidInput;
  }
  if (!factor(G)) return SolverStatus::kNotPositiveDefinite;
  unconstrained_minimum(g, x);
  for (int i = 0; i < min; ++i)
    is_active_[i] = 0;
  if (add_equalities(A_eq, b_eq, x) != SolverStatus::kOptimal) return SolverStatus::kInfeasible;
  // Inequalities: the most violated one made active, until none is violated.
  SolverStatus status = SolverStatus::kOptimal;
  for (int p = most_violated(A_in, b_in, x); p >= 0; p = most_violated(A_in, b_in, x)) {
    for (int k = 0; k < n; ++k)
      np_[k] = A_in(p, k);
    status = add_inequality(p, b_in[p], x);
    if (status != SolverStatus::kOptimal) break;
  }
  store_multipliers();
  objective_ = objective_at(G, g, x);
  return status;
}

// Cholesky G = L L^T (lower triangle of G), then J = L^{-T}. False when G is not positive
// definite (a pivot below 1e-14 of the trace).
bool DualQp::factor(const Eigen::Ref<const Eigen::MatrixXd>& G) {
  const int n = static_cast<int>(G.rows());
  double trace = 0.0;
  for (int j = 0; j < n; ++j)
    trace += std::abs(G(j, j));
  for (int j = 0; j < n; ++j) {
    double s = G(j, j);
    for (int k = 0; k < j; ++k)
      s -= L_(j, k) * L_(j, k);
    if (!(s > 1e-14 * trace)) return false;
    const double ljj = std::sqrt(s);
    L_(j, j) = ljj;
    for (int i = j + 1; i < n; ++i) {
      double t = G(i, j);
      for (int k = 0; k < j; ++k)
        t -= L_(i, k) * L_(j, k);
      L_(i, j) = t / ljj;
    }
  }
  // J = L^{-T}: column c of L^{-1} is the solution of L y = e_c; J(c, :) = y^T.
  J_.topLeftCorner(n, n).setZero();
  for (int c = 0; c < n; ++c) {
    for (int i = c; i < n; ++i) {
      double s = i == c ? 1.0 : 0.0;
      for (int k = c; k < i; ++k)
        s -= L_(i, k) * J_(c, k);
      J_(c, i) = s / L_(i, i);
    }
  }
  return true;
}

// Unconstrained minimum x = -G^{-1} g = -J J^T g.
void DualQp::unconstrained_minimum(const Eigen::Ref<const Eigen::VectorXd>& g,
                                   Eigen::Ref<Eigen::VectorXd> x) {
  const int n = static_cast<int>(g.size());
  for (int i = 0; i < n; ++i) {
    double s = 0.0;
    for (int k = 0; k < n; ++k)
      s += J_(k, i) * g[k];
    d_[i] = s;
  }
  for (int i = 0; i < n; ++i) {
    double s = 0.0;
    for (int k = 0; k < n; ++k)
      s -= J_(i, k) * d_[k];
    x[i] = s;
  }
}

// d = J^T np; z = J(:, q:n) d(q:n); r = R^{-1} d(0:q).
void DualQp::compute_directions(int n) {
  for (int i = 0; i < n; ++i) {
    double s = 0.0;
    for (int k = 0; k < n; ++k)
      s += J_(k, i) * np_[k];
    d_[i] = s;
  }
  for (int i = 0; i < n; ++i) {
    double s = 0.0;
    for (int k = q_; k < n; ++k)
      s += J_(i, k) * d_[k];
    z_[i] = s;
  }
  for (int i = q_ - 1; i >= 0; --i) {
    double s = d_[i];
    for (int k = i + 1; k < q_; ++k)
      s -= R_(i, k) * r_[k];
    r_[i] = s / R_(i, i);
  }
}

double DualQp::dot_np(const Eigen::Ref<const Eigen::VectorXd>& v, int n) const {
  double s = 0.0;
  for (int i = 0; i < n; ++i)
    s += v[i] * np_[i];
  return s;
}

// Equalities: full steps. kInfeasible for a dependent equality.
SolverStatus DualQp::add_equalities(const Eigen::Ref<const Eigen::MatrixXd>& A_eq,
                                    const Eigen::Ref<const Eigen::VectorXd>& b_eq,
                                    Eigen::Ref<Eigen::VectorXd> x) {
  const int n = static_cast<int>(x.size());
  for (int e = 0; e < static_cast<int>(A_eq.rows()); ++e) {
    for (int i = 0; i < n; ++i)
      np_[i] = A_eq(e, i);
    compute_directions(n);
    const double znp = dot_np(z_, n);
    if (!(std::abs(znp) > 1e-14 * (1.0 + np_.head(n).squaredNorm())))
      return SolverStatus::kInfeasible;  // dependent equality
    const double t2 = (b_eq[e] - dot_np(x, n)) / znp;
    for (int i = 0; i < n; ++i)
      x[i] += t2 * z_[i];
    for (int i = 0; i < q_; ++i)
      u_[i] -= t2 * r_[i];
    u_[q_] = t2;
    active_[q_] = -(e + 1);
    add_to_active_set(n);
  }
  return SolverStatus::kOptimal;
}

// The inactive inequality most violated at x (beyond a tolerance relative to its scale), or -1.
int DualQp::most_violated(const Eigen::Ref<const Eigen::MatrixXd>& A_in,
                          const Eigen::Ref<const Eigen::VectorXd>& b_in,
                          const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const int n = static_cast<int>(x.size());
  const double scale_x = 1.0 + x.norm();
  int p = -1;
  double worst = 0.0;
  for (int i = 0; i < static_cast<int>(A_in.rows()); ++i) {
    if (is_active_[i]) continue;
    double s = -b_in[i];
    double row_norm2 = 0.0;
    for (int k = 0; k < n; ++k) {
      s += A_in(i, k) * x[k];
      row_norm2 += A_in(i, k) * A_in(i, k);
    }
    const double tol = 1e-12 * (std::abs(b_in[i]) + std::sqrt(row_norm2) * scale_x);
    if (s < -tol && s < worst) {
      worst = s;
      p = i;
    }
  }
  return p;
}

// Makes inequality p (normal np_, bound b_p) active: partial (dual) steps drop active
// inequalities whose multipliers would turn negative, until the full (primal) step satisfies p.
SolverStatus DualQp::add_inequality(int p, double b_p, Eigen::Ref<Eigen::VectorXd> x) {
  const int n = static_cast<int>(x.size());
  double u_plus = 0.0;
  for (;;) {
    if (iterations_ >= max_iterations_) return SolverStatus::kIterationLimit;
    ++iterations_;
    compute_directions(n);
    // Partial (dual) step: largest step keeping the active inequality multipliers >= 0.
    double t1 = kInf;
    int drop = -1;
    for (int k = 0; k < q_; ++k) {
      if (active_[k] < 0 || !(r_[k] > 0.0)) continue;
      const double t = u_[k] / r_[k];
      if (t < t1) {
        t1 = t;
        drop = k;
      }
    }
    // Full (primal) step: makes constraint p active.
    const double znp = dot_np(z_, n);
    double t2 = kInf;
    if (znp > 1e-14 * np_.head(n).squaredNorm()) t2 = -(dot_np(x, n) - b_p) / znp;
    if (t1 == kInf && t2 == kInf) return SolverStatus::kInfeasible;
    const double t = t2 == kInf ? t1 : std::min(t1, t2);
    if (t2 != kInf)
      for (int i = 0; i < n; ++i)
        x[i] += t * z_[i];
    for (int k = 0; k < q_; ++k)
      u_[k] -= t * r_[k];
    u_plus += t;
    if (t2 != kInf && t2 <= t1) {
      u_[q_] = u_plus;
      active_[q_] = p;
      is_active_[p] = 1;
      add_to_active_set(n);
      return SolverStatus::kOptimal;
    }
    is_active_[active_[drop]] = 0;
    drop_from_active_set(n, drop);
  }
}

void DualQp::store_multipliers() {
  for (int k = 0; k < q_; ++k) {
    if (active_[k] >= 0) {
      u_in_[active_[k]] = u_[k];
    } else {
      lambda_eq_[-active_[k] - 1] = u_[k];
    }
  }
}

// 1/2 x^T G x + g^T x, G from its lower triangle.
double DualQp::objective_at(const Eigen::Ref<const Eigen::MatrixXd>& G,
                            const Eigen::Ref<const Eigen::VectorXd>& g,
                            const Eigen::Ref<const Eigen::VectorXd>& x) const {
  const int n = static_cast<int>(x.size());
  double obj = 0.0;
  for (int i = 0; i < n; ++i) {
    double gi = g[i];
    for (int k = 0; k < n; ++k) {
      const double gik = i >= k ? G(i, k) : G(k, i);
      gi += 0.5 * gik * x[k];
    }
    obj += gi * x[i];
  }
  return obj;
}

}  // namespace poise::contact
