#include "poise/contact/bvls.hpp"

#include "active_set_common.hpp"

namespace poise::contact {

void Bvls::resize(int max_rows, int max_cols) {
  ws_.resize("Bvls", max_rows, max_cols);
  if (max_iterations_ == 0) max_iterations_ = 3 * max_cols + 10;
}

bool Bvls::check_bounds(int n, const Eigen::Ref<const Eigen::VectorXd>& lower,
                        const Eigen::Ref<const Eigen::VectorXd>& upper,
                        Eigen::Ref<Eigen::VectorXd> x) {
  bool ok = lower.size() == n && upper.size() == n && x.size() == n;
  for (int j = 0; ok && j < n; ++j) {
    ok = std::isfinite(lower[j]) && std::isfinite(upper[j]) && lower[j] <= upper[j];
  }
  if (x.size() > 0) x.setZero();
  if (ok) {
    for (int j = 0; j < n; ++j)
      x[j] = std::clamp(0.0, lower[j], upper[j]);
  }
  return ok;
}

SolverStatus Bvls::solve(const Eigen::Ref<const Eigen::MatrixXd>& A,
                         const Eigen::Ref<const Eigen::VectorXd>& b,
                         const Eigen::Ref<const Eigen::VectorXd>& lower,
                         const Eigen::Ref<const Eigen::VectorXd>& upper,
                         Eigen::Ref<Eigen::VectorXd> x) {
  iterations_ = 0;
  const int n = static_cast<int>(A.cols());
  double norm_a = 0.0, norm_b = 0.0;
  if (!check_bounds(n, lower, upper, x) || !detail::load_dense(A, b, ws_, norm_a, norm_b)) {
    return SolverStatus::kInvalidInput;
  }
  const SolverStatus status = run(&A, b.data(), n, norm_a, norm_b, lower, upper, x);
  detail::dual_from_residual(A, b.data(), x.data(), ws_);  // final residual and dual
  return status;
}

SolverStatus Bvls::solve_normal(const Eigen::Ref<const Eigen::MatrixXd>& H,
                                const Eigen::Ref<const Eigen::VectorXd>& c, double b_norm,
                                const Eigen::Ref<const Eigen::VectorXd>& lower,
                                const Eigen::Ref<const Eigen::VectorXd>& upper,
                                Eigen::Ref<Eigen::VectorXd> x) {
  iterations_ = 0;
  const int n = static_cast<int>(H.cols());
  double norm_a = 0.0;
  if (!check_bounds(n, lower, upper, x) || !std::isfinite(b_norm) ||
      !detail::load_normal(H, c, ws_, norm_a)) {
    return SolverStatus::kInvalidInput;
  }
  const SolverStatus status = run(nullptr, nullptr, n, norm_a, std::abs(b_norm), lower, upper, x);
  detail::dual_from_normal(n, x.data(), ws_);
  return status;
}

/// One run's problem and its free set: the free variables are ws_.cols[0..k), the Cholesky rows
/// of the first `factored` of them are valid.
struct Bvls::Problem {
  const Eigen::Ref<const Eigen::MatrixXd>* A;  // null in the normal-equation form
  const double* b;
  int n;
  const Eigen::Ref<const Eigen::VectorXd>& lower;
  const Eigen::Ref<const Eigen::VectorXd>& upper;
  Eigen::Ref<Eigen::VectorXd>& x;
  int k = 0;
  int factored = 0;
};

SolverStatus Bvls::run(const Eigen::Ref<const Eigen::MatrixXd>* A, const double* b, int n,
                       double norm_a, double b_norm, const Eigen::Ref<const Eigen::VectorXd>& lower,
                       const Eigen::Ref<const Eigen::VectorXd>& upper,
                       Eigen::Ref<Eigen::VectorXd> x) {
  double bound_scale = 0.0;
  for (int j = 0; j < n; ++j) {
    const double v = std::max(std::abs(lower[j]), std::abs(upper[j]));
    bound_scale += v * v;
  }
  const double tol = tolerance_ * norm_a * (b_norm + norm_a * std::sqrt(bound_scale)) + 1e-300;
  Problem p{A, b, n, lower, upper, x};
  for (int j = 0; j < n; ++j) ws_.rejected[j] = 0;
  cold_start(p);
  warm_start(p);
  bool x_changed = true;
  for (;;) {
    if (x_changed) {
      detail::dual_from_normal(n, x.data(), ws_);
      for (int j = 0; j < n; ++j)
        ws_.rejected[j] = 0;
    }
    const int t = entering_variable(p, tol);
    if (t < 0) return SolverStatus::kOptimal;
    x_changed = false;
    const SolverStatus status = free_variable(p, t, x_changed);
    if (status != SolverStatus::kOptimal) return status;
    // A rejected entering variable leaves x and the duals unchanged: the next one is picked.
  }
}

// Right-hand side of the free variables' normal equations, A_F^T (b - A_B x_B), in ws_.rhs.
void Bvls::free_rhs(const Problem& p) {
  const int* cols = ws_.cols.data();
  double* x_bound = ws_.xb.data();
  for (int j = 0; j < p.n; ++j)
    x_bound[j] = ws_.state[j] != kFree ? p.x[j] : 0.0;
  for (int c = 0; c < p.k; ++c) {
    const double* col = &ws_.AtA(0, cols[c]);  // symmetric: column = row, contiguous
    double s = ws_.Atb[cols[c]];
    for (int j = 0; j < p.n; ++j)
      s -= col[j] * x_bound[j];
    ws_.rhs[c] = s;
  }
}

// Every variable at its lower bound (Stark-Parker's cold start).
void Bvls::cold_start(Problem& p) {
  for (int j = 0; j < p.n; ++j) {
    p.x[j] = p.lower[j];
    ws_.state[j] = kAtLower;
  }
  p.k = 0;
  p.factored = 0;
}

// Warm start (Stark-Parker's alternative start): solve with every non-fixed variable free; move
// the variables that leave their bounds onto the violated bound and re-solve, until the free
// solution is inside its bounds. The result is a feasible point from which the main loop
// continues; if a sub-problem is ill-conditioned the cold start is kept.
void Bvls::warm_start(Problem& p) {
  int* cols = ws_.cols.data();
  for (int j = 0; j < p.n; ++j)
    if (p.lower[j] < p.upper[j]) {
      ws_.state[j] = kFree;
      cols[p.k++] = j;
    }
  while (iterations_ < max_iterations_) {
    ++iterations_;
    if (p.k == 0) return;
    free_rhs(p);
    if (!detail::subset_normal_equations(p.k, p.factored, ws_)) break;
    if (clamp_to_bounds(p)) {
      for (int c = 0; c < p.k; ++c)
        p.x[cols[c]] = ws_.z[c];
      return;
    }
    p.k = detail::compact_columns(p.k, p.factored, ws_,
                                  [&](int c) { return ws_.state[cols[c]] == kFree; });
  }
  cold_start(p);  // back to the cold start
}

// The warm start's free variables whose solution leaves their bounds, put on the bound they
// cross. True when none does.
bool Bvls::clamp_to_bounds(Problem& p) {
  bool inside = true;
  for (int c = 0; c < p.k; ++c) {
    const int j = ws_.cols[c];
    if (ws_.z[c] < p.lower[j]) {
      p.x[j] = p.lower[j];
      ws_.state[j] = kAtLower;
      inside = false;
    } else if (ws_.z[c] > p.upper[j]) {
      p.x[j] = p.upper[j];
      ws_.state[j] = kAtUpper;
      inside = false;
    }
  }
  return inside;
}

// The bound variable whose dual most strongly asks to leave its bound (beyond tol), or -1.
int Bvls::entering_variable(const Problem& p, double tol) const {
  int t = -1;
  double best = tol;
  for (int j = 0; j < p.n; ++j) {
    if (ws_.state[j] == kFree || ws_.rejected[j] || p.lower[j] == p.upper[j]) continue;
    const double v = ws_.state[j] == kAtLower ? ws_.w[j] : -ws_.w[j];
    if (v > best) {
      best = v;
      t = j;
    }
  }
  return t;
}

// Solves the free set's sub-problem into ws_.z: the normal equations, or the QR fallback on the
// columns when they are ill-conditioned. False when neither is possible (normal-equation form).
bool Bvls::solve_free_set(Problem& p) {
  free_rhs(p);
  if (detail::subset_normal_equations(p.k, p.factored, ws_)) return true;
  if (p.A == nullptr) return false;  // normal-equation form: no columns to fall back on
  // rhs = b - A_B x_B in ws_.r (the residual is recomputed at the end).
  const int m = static_cast<int>(p.A->rows());
  for (int i = 0; i < m; ++i) {
    double s = p.b[i];
    for (int j = 0; j < p.n; ++j)
      if (ws_.state[j] != kFree) s -= (*p.A)(i, j) * p.x[j];
    ws_.r[i] = s;
  }
  detail::subset_least_squares(*p.A, p.k, ws_.r.data(), ws_);
  return true;
}

// Frees variable t (last of the free set): solve on the free set, and while its solution leaves
// the bounds, step towards it as far as feasible and bind the variables that reach a bound.
// An entering variable that would not move into the box is put back and rejected.
SolverStatus Bvls::free_variable(Problem& p, int t, bool& x_changed) {
  const int t_old_state = ws_.state[t];
  ws_.state[t] = kFree;
  ws_.cols[p.k++] = t;
  for (bool first = true;; first = false) {
    if (iterations_ >= max_iterations_) return SolverStatus::kIterationLimit;
    ++iterations_;
    if (!solve_free_set(p)) {
      if (first) {  // x[t] is still on its old bound: x stays feasible
        ws_.state[t] = t_old_state;
        --p.k;
        p.factored = std::min(p.factored, p.k);
      }
      return SolverStatus::kNotPositiveDefinite;
    }
    if (first) {
      const double z_t = ws_.z[p.k - 1];  // the entering variable is the last free one
      const bool moves_in = t_old_state == kAtLower ? z_t > p.x[t] : z_t < p.x[t];
      if (!moves_in) {
        ws_.state[t] = t_old_state;
        ws_.rejected[t] = 1;
        --p.k;
        p.factored = std::min(p.factored, p.k);
        return SolverStatus::kOptimal;
      }
    }
    x_changed = true;
    if (step_to_free_solution(p)) return SolverStatus::kOptimal;
    p.k = detail::compact_columns(p.k, p.factored, ws_,
                                  [&](int c) { return ws_.state[ws_.cols[c]] == kFree; });
  }
}

// x moves towards the free set's solution z: all the way when z is inside the bounds (returns
// true), else as far as the first variable to reach a bound (those that do become bound).
bool Bvls::step_to_free_solution(Problem& p) {
  const int* cols = ws_.cols.data();
  const double* z = ws_.z.data();
  double alpha = 2.0;
  int blocking = -1;
  for (int c = 0; c < p.k; ++c) {
    const int j = cols[c];
    double a = 2.0;
    if (z[c] < p.lower[j]) {
      a = (p.lower[j] - p.x[j]) / (z[c] - p.x[j]);
    } else if (z[c] > p.upper[j]) {
      a = (p.upper[j] - p.x[j]) / (z[c] - p.x[j]);
    }
    if (a < alpha) {
      alpha = a;
      blocking = j;
    }
  }
  if (blocking < 0) {
    for (int c = 0; c < p.k; ++c)
      p.x[cols[c]] = z[c];
    return true;
  }
  alpha = std::max(alpha, 0.0);
  for (int c = 0; c < p.k; ++c) {
    const int j = cols[c];
    p.x[j] += alpha * (z[c] - p.x[j]);
    if (j == blocking) {
      const bool to_lower = z[c] < p.lower[j];
      p.x[j] = to_lower ? p.lower[j] : p.upper[j];
      ws_.state[j] = to_lower ? kAtLower : kAtUpper;
    } else if (p.x[j] <= p.lower[j]) {
      p.x[j] = p.lower[j];
      ws_.state[j] = kAtLower;
    } else if (p.x[j] >= p.upper[j]) {
      p.x[j] = p.upper[j];
      ws_.state[j] = kAtUpper;
    }
  }
  return false;
}

}  // namespace poise::contact
