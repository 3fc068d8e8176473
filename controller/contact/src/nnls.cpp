#include "poise/contact/nnls.hpp"

#include "active_set_common.hpp"

namespace poise::contact {

void Nnls::resize(int max_rows, int max_cols) {
  ws_.resize("Nnls", max_rows, max_cols);
  if (max_iterations_ == 0) max_iterations_ = 3 * max_cols + 10;
}

SolverStatus Nnls::solve(const Eigen::Ref<const Eigen::MatrixXd>& A,
                         const Eigen::Ref<const Eigen::VectorXd>& b,
                         Eigen::Ref<Eigen::VectorXd> x) {
  iterations_ = 0;
  if (x.size() > 0) x.setZero();
  double norm_a = 0.0, norm_b = 0.0;
  if (x.size() != A.cols() || !detail::load_dense(A, b, ws_, norm_a, norm_b)) {
    return SolverStatus::kInvalidInput;
  }
  const SolverStatus status =
      run(&A, b.data(), static_cast<int>(A.cols()), tolerance_ * norm_a * norm_b + 1e-300, x);
  // Dual of the returned point from the residual (more accurate than the Gram form).
  detail::dual_from_residual(A, b.data(), x.data(), ws_);
  return status;
}

SolverStatus Nnls::solve_normal(const Eigen::Ref<const Eigen::MatrixXd>& H,
                                const Eigen::Ref<const Eigen::VectorXd>& c, double b_norm,
                                Eigen::Ref<Eigen::VectorXd> x) {
  iterations_ = 0;
  if (x.size() > 0) x.setZero();
  double norm_a = 0.0;
  if (x.size() != H.cols() || !std::isfinite(b_norm) || !detail::load_normal(H, c, ws_, norm_a)) {
    return SolverStatus::kInvalidInput;
  }
  const int n = static_cast<int>(H.cols());
  const SolverStatus status =
      run(nullptr, nullptr, n, tolerance_ * norm_a * std::abs(b_norm) + 1e-300, x);
  detail::dual_from_normal(n, x.data(), ws_);
  return status;
}

SolverStatus Nnls::run(const Eigen::Ref<const Eigen::MatrixXd>* A, const double* b, int n,
                       double tol, Eigen::Ref<Eigen::VectorXd> x) {
  int* cols = ws_.cols.data();  // the passive set, in the order its variables entered
  int* passive = ws_.state.data();
  int* rejected = ws_.rejected.data();
  for (int j = 0; j < n; ++j) {
    passive[j] = 0;
    rejected[j] = 0;
  }
  int factored = 0;  // leading columns whose Cholesky rows are valid
  int k = warm_start(n, x, factored);  // size of the passive set
  for (;;) {
    detail::dual_from_normal(n, x.data(), ws_);  // w = A^T (b - A x)
    const int t = entering_variable(n, tol);
    if (t < 0) return SolverStatus::kOptimal;  // KKT conditions hold
    passive[t] = 1;
    cols[k++] = t;
    bool x_changed = false;
    const SolverStatus status = add_variable(A, b, t, k, factored, x_changed, x);
    if (x_changed)
      for (int j = 0; j < n; ++j)
        rejected[j] = 0;
    if (status != SolverStatus::kOptimal) return status;
  }
}

// Warm start: the unconstrained least-squares solution, pruned repeatedly to its positive
// entries, gives a feasible point (x_P > 0, x_Z = 0) from which Lawson-Hanson continues; when the
// unconstrained solution is already non-negative this is the answer. If a sub-problem is
// ill-conditioned the solver starts cold from x = 0. Returns the size of the passive set.
int Nnls::warm_start(int n, Eigen::Ref<Eigen::VectorXd> x, int& factored) {
  int* cols = ws_.cols.data();
  const double* z = ws_.z.data();
  int k = 0;
  int m = n;
  for (int j = 0; j < n; ++j)
    cols[j] = j;
  while (m > 0 && iterations_ < max_iterations_) {
    ++iterations_;
    for (int c = 0; c < m; ++c)
      ws_.rhs[c] = ws_.Atb[cols[c]];
    if (!detail::subset_normal_equations(m, factored, ws_)) break;
    const int kept = detail::compact_columns(m, factored, ws_, [&](int c) { return z[c] > 0.0; });
    if (kept == m) {
      for (int c = 0; c < m; ++c) {
        x[cols[c]] = z[c];
        ws_.state[cols[c]] = 1;
      }
      k = m;
      break;
    }
    m = kept;
  }
  if (k == 0) factored = 0;  // cold start
  return k;
}

// Most positive dual (above tol) among the zero (non-passive, not rejected) variables, or -1.
int Nnls::entering_variable(int n, double tol) const {
  int t = -1;
  double best = tol;
  for (int j = 0; j < n; ++j) {
    if (!ws_.state[j] && !ws_.rejected[j] && ws_.w[j] > best) {
      best = ws_.w[j];
      t = j;
    }
  }
  return t;
}

// Lawson-Hanson's inner loop for the entering variable t (last of the k passive columns): solve
// on the passive set, and while a passive variable would turn non-positive, step towards that
// solution as far as feasible and drop the variables that reach 0.
SolverStatus Nnls::add_variable(const Eigen::Ref<const Eigen::MatrixXd>* A, const double* b, int t,
                                int& k, int& factored, bool& x_changed,
                                Eigen::Ref<Eigen::VectorXd> x) {
  const int* cols = ws_.cols.data();
  const double* z = ws_.z.data();
  for (bool first = true;; first = false) {
    if (iterations_ >= max_iterations_) return SolverStatus::kIterationLimit;
    ++iterations_;
    for (int c = 0; c < k; ++c)
      ws_.rhs[c] = ws_.Atb[cols[c]];
    if (!detail::subset_normal_equations(k, factored, ws_)) {
      // Normal-equation form: no columns to fall back on (x stays feasible).
      if (A == nullptr) return SolverStatus::kNotPositiveDefinite;
      detail::subset_least_squares(*A, k, b, ws_);
    }
    // The entering variable (last in the set) must move into the positive orthant; otherwise
    // (round-off or a dependent column) it is rejected until x changes, as in Lawson-Hanson's
    // NNLS code.
    if (first && !(z[k - 1] > 0.0)) {
      ws_.state[t] = 0;
      ws_.rejected[t] = 1;
      --k;
      factored = std::min(factored, k);
      return SolverStatus::kOptimal;
    }
    x_changed = true;
    if (step_to_passive_solution(k, x)) return SolverStatus::kOptimal;
    k = detail::compact_columns(k, factored, ws_,
                                [&](int c) { return ws_.state[cols[c]] != 0; });
  }
}

// x moves towards the passive set's solution z: all the way when z > 0 (returns true), else as
// far as the first variable to reach 0 (those that do leave the passive set).
bool Nnls::step_to_passive_solution(int k, Eigen::Ref<Eigen::VectorXd> x) {
  const int* cols = ws_.cols.data();
  const double* z = ws_.z.data();
  bool all_positive = true;
  double alpha = 2.0;
  int blocking = -1;
  for (int c = 0; c < k; ++c) {
    if (z[c] <= 0.0) {
      all_positive = false;
      const int j = cols[c];
      const double a = x[j] / (x[j] - z[c]);
      if (a < alpha) {
        alpha = a;
        blocking = j;
      }
    }
  }
  if (all_positive) {
    for (int c = 0; c < k; ++c)
      x[cols[c]] = z[c];
    return true;
  }
  for (int c = 0; c < k; ++c) {
    const int j = cols[c];
    x[j] += alpha * (z[c] - x[j]);
    if (j == blocking || x[j] <= 0.0) {
      x[j] = 0.0;
      ws_.state[j] = 0;
    }
  }
  return false;
}

}  // namespace poise::contact
