#include "poise/contact/nnls.hpp"

#include <cmath>
#include <stdexcept>

#include "subset_least_squares.hpp"

namespace poise::contact {

namespace {

bool all_finite(const Eigen::Ref<const Eigen::MatrixXd>& M) {
  for (Eigen::Index j = 0; j < M.cols(); ++j)
    for (Eigen::Index i = 0; i < M.rows(); ++i)
      if (!std::isfinite(M(i, j))) return false;
  return true;
}

}  // namespace

void Nnls::resize(int max_rows, int max_cols) {
  if (max_rows <= 0 || max_cols <= 0) {
    throw std::invalid_argument("Nnls::resize: sizes must be positive, got " +
                                std::to_string(max_rows) + " x " + std::to_string(max_cols));
  }
  max_rows_ = max_rows;
  max_cols_ = max_cols;
  if (max_iterations_ == 0) max_iterations_ = 3 * max_cols + 10;
  W_.setZero(max_rows, max_cols);
  r_.setZero(max_rows);
  qr_rhs_.setZero(max_rows);
  diag_.setZero(max_cols);
  w_.setZero(max_cols);
  z_.setZero(max_cols);
  cols_.setZero(max_cols);
  passive_.setZero(max_cols);
  rejected_.setZero(max_cols);
  AtA_.setZero(max_cols, max_cols);
  Atb_.setZero(max_cols);
  L_.setZero(max_cols, max_cols);
  rhs_.setZero(max_cols);
}

SolverStatus Nnls::solve(const Eigen::Ref<const Eigen::MatrixXd>& A,
                         const Eigen::Ref<const Eigen::VectorXd>& b,
                         Eigen::Ref<Eigen::VectorXd> x) {
  iterations_ = 0;
  const int m = static_cast<int>(A.rows());
  const int n = static_cast<int>(A.cols());
  if (x.size() > 0) x.setZero();
  if (m <= 0 || n <= 0 || m > max_rows_ || n > max_cols_ || b.size() != m || x.size() != n ||
      !all_finite(A) || !all_finite(b)) {
    return SolverStatus::kInvalidInput;
  }

  double norm_a = 0.0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < m; ++i)
      norm_a += A(i, j) * A(i, j);
  norm_a = std::sqrt(norm_a);
  const double tol = tolerance_ * norm_a * b.norm() + 1e-300;

  for (int j = 0; j < n; ++j) {
    passive_[j] = 0;
    rejected_[j] = 0;
  }
  // Gram matrix and A^T b: the dual is w = A^T b - A^T A x and the passive-set sub-problems are
  // solved by Cholesky of A^T A restricted to the set (QR of the columns when ill-conditioned).
  for (int j = 0; j < n; ++j) {
    for (int l = 0; l <= j; ++l) {
      double s = 0.0;
      for (int i = 0; i < m; ++i)
        s += A(i, j) * A(i, l);
      AtA_(j, l) = s;
      AtA_(l, j) = s;
    }
    double s = 0.0;
    for (int i = 0; i < m; ++i)
      s += A(i, j) * b[i];
    Atb_[j] = s;
  }

  // Warm start: the unconstrained least-squares solution, pruned repeatedly to its positive
  // entries, gives a feasible point (x_P > 0, x_Z = 0) from which Lawson-Hanson continues; when the
  // unconstrained solution is already non-negative this is the answer. If a sub-problem is
  // ill-conditioned the solver starts cold from x = 0.
  {
    int k = n;
    for (int j = 0; j < n; ++j)
      cols_[j] = j;
    while (k > 0 && iterations_ < max_iterations_) {
      ++iterations_;
      for (int c = 0; c < k; ++c)
        rhs_[c] = Atb_[cols_[c]];
      if (!detail::subset_normal_equations(AtA_, cols_.data(), k, rhs_.data(), L_, z_.data())) {
        break;
      }
      int kept = 0;
      for (int c = 0; c < k; ++c) {
        if (z_[c] > 0.0) cols_[kept++] = cols_[c];
      }
      if (kept == k) {
        for (int c = 0; c < k; ++c) {
          x[cols_[c]] = z_[c];
          passive_[cols_[c]] = 1;
        }
        break;
      }
      k = kept;
    }
  }

  SolverStatus status = SolverStatus::kOptimal;
  for (;;) {
    // Dual w = A^T (b - A x).
    for (int j = 0; j < n; ++j) {
      double s = Atb_[j];
      for (int l = 0; l < n; ++l)
        s -= AtA_(j, l) * x[l];
      w_[j] = s;
    }
    // Most positive dual among the zero (non-passive, not rejected) variables.
    int t = -1;
    double best = tol;
    for (int j = 0; j < n; ++j) {
      if (!passive_[j] && !rejected_[j] && w_[j] > best) {
        best = w_[j];
        t = j;
      }
    }
    if (t < 0) break;  // KKT conditions hold
    passive_[t] = 1;

    bool x_changed = false;
    bool first = true;
    for (;;) {
      if (iterations_ >= max_iterations_) {
        status = SolverStatus::kIterationLimit;
        break;
      }
      ++iterations_;
      int k = 0;
      for (int j = 0; j < n; ++j)
        if (passive_[j]) cols_[k++] = j;
      for (int c = 0; c < k; ++c)
        rhs_[c] = Atb_[cols_[c]];
      if (!detail::subset_normal_equations(AtA_, cols_.data(), k, rhs_.data(), L_, z_.data())) {
        detail::subset_least_squares(A, cols_.data(), k, b.data(), W_, qr_rhs_, diag_, z_.data());
      }
      if (first) {
        first = false;
        // The entering variable must move into the positive orthant; otherwise (round-off or a
        // dependent column) it is rejected until x changes, as in Lawson-Hanson's NNLS code.
        int pos_t = 0;
        while (cols_[pos_t] != t)
          ++pos_t;
        if (!(z_[pos_t] > 0.0)) {
          passive_[t] = 0;
          rejected_[t] = 1;
          break;
        }
      }
      bool all_positive = true;
      double alpha = 2.0;
      int blocking = -1;
      for (int c = 0; c < k; ++c) {
        if (z_[c] <= 0.0) {
          all_positive = false;
          const int j = cols_[c];
          const double a = x[j] / (x[j] - z_[c]);
          if (a < alpha) {
            alpha = a;
            blocking = j;
          }
        }
      }
      x_changed = true;
      if (all_positive) {
        for (int c = 0; c < k; ++c)
          x[cols_[c]] = z_[c];
        break;
      }
      for (int c = 0; c < k; ++c) {
        const int j = cols_[c];
        x[j] += alpha * (z_[c] - x[j]);
        if (j == blocking || x[j] <= 0.0) {
          x[j] = 0.0;
          passive_[j] = 0;
        }
      }
    }
    if (x_changed) {
      for (int j = 0; j < n; ++j)
        rejected_[j] = 0;
    }
    if (status != SolverStatus::kOptimal) break;
  }
  // Dual of the returned point from the residual (more accurate than the Gram form).
  for (int i = 0; i < m; ++i) {
    double s = b[i];
    for (int j = 0; j < n; ++j)
      s -= A(i, j) * x[j];
    r_[i] = s;
  }
  for (int j = 0; j < n; ++j) {
    double s = 0.0;
    for (int i = 0; i < m; ++i)
      s += A(i, j) * r_[i];
    w_[j] = s;
  }
  return status;
}

}  // namespace poise::contact
