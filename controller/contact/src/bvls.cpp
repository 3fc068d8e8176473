#include "poise/contact/bvls.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "subset_least_squares.hpp"

namespace poise::contact {

void Bvls::resize(int max_rows, int max_cols) {
  if (max_rows <= 0 || max_cols <= 0) {
    throw std::invalid_argument("Bvls::resize: sizes must be positive, got " +
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
  state_.setZero(max_cols);
  rejected_.setZero(max_cols);
  AtA_.setZero(max_cols, max_cols);
  Atb_.setZero(max_cols);
  L_.setZero(max_cols, max_cols);
  rhs_.setZero(max_cols);
}

SolverStatus Bvls::solve(const Eigen::Ref<const Eigen::MatrixXd>& A,
                         const Eigen::Ref<const Eigen::VectorXd>& b,
                         const Eigen::Ref<const Eigen::VectorXd>& lower,
                         const Eigen::Ref<const Eigen::VectorXd>& upper,
                         Eigen::Ref<Eigen::VectorXd> x) {
  iterations_ = 0;
  const int m = static_cast<int>(A.rows());
  const int n = static_cast<int>(A.cols());
  bool bounds_ok = lower.size() == n && upper.size() == n && x.size() == n;
  for (int j = 0; bounds_ok && j < n; ++j) {
    bounds_ok = std::isfinite(lower[j]) && std::isfinite(upper[j]) && lower[j] <= upper[j];
  }
  if (x.size() > 0) x.setZero();
  if (bounds_ok) {
    for (int j = 0; j < n; ++j)
      x[j] = std::clamp(0.0, lower[j], upper[j]);
  }
  bool ok = bounds_ok && m > 0 && n > 0 && m <= max_rows_ && n <= max_cols_ && b.size() == m;
  for (int j = 0; ok && j < n; ++j)
    for (int i = 0; ok && i < m; ++i)
      ok = std::isfinite(A(i, j));
  for (int i = 0; ok && i < m; ++i)
    ok = std::isfinite(b[i]);
  if (!ok) return SolverStatus::kInvalidInput;

  double norm_a = 0.0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < m; ++i)
      norm_a += A(i, j) * A(i, j);
  norm_a = std::sqrt(norm_a);
  double bound_scale = 0.0;
  for (int j = 0; j < n; ++j) {
    const double v = std::max(std::abs(lower[j]), std::abs(upper[j]));
    bound_scale += v * v;
  }
  const double tol = tolerance_ * norm_a * (b.norm() + norm_a * std::sqrt(bound_scale)) + 1e-300;

  // Gram matrix and A^T b (see Nnls): duals and sub-problems use the normal equations, with QR of
  // the free columns as the fallback when they are ill-conditioned.
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

  // Start with every variable at its lower bound (Stark-Parker's cold start).
  for (int j = 0; j < n; ++j) {
    x[j] = lower[j];
    state_[j] = kAtLower;
    rejected_[j] = 0;
  }

  // Warm start (Stark-Parker's alternative start): solve with every non-fixed variable free; move
  // the variables that leave their bounds onto the violated bound and re-solve, until the free
  // solution is inside its bounds. The result is a feasible point from which the main loop
  // continues; if a sub-problem is ill-conditioned the cold start above is kept.
  {
    for (int j = 0; j < n; ++j)
      if (lower[j] < upper[j]) state_[j] = kFree;
    bool done = false;
    while (!done && iterations_ < max_iterations_) {
      ++iterations_;
      int k = 0;
      for (int j = 0; j < n; ++j)
        if (state_[j] == kFree) cols_[k++] = j;
      if (k == 0) {
        done = true;
        break;
      }
      for (int c = 0; c < k; ++c) {
        double s = Atb_[cols_[c]];
        for (int j = 0; j < n; ++j)
          if (state_[j] != kFree) s -= AtA_(cols_[c], j) * x[j];
        rhs_[c] = s;
      }
      if (!detail::subset_normal_equations(AtA_, cols_.data(), k, rhs_.data(), L_, z_.data())) {
        break;
      }
      bool inside = true;
      for (int c = 0; c < k; ++c) {
        const int j = cols_[c];
        if (z_[c] < lower[j]) {
          x[j] = lower[j];
          state_[j] = kAtLower;
          inside = false;
        } else if (z_[c] > upper[j]) {
          x[j] = upper[j];
          state_[j] = kAtUpper;
          inside = false;
        }
      }
      if (inside) {
        for (int c = 0; c < k; ++c)
          x[cols_[c]] = z_[c];
        done = true;
      }
    }
    if (!done) {  // back to the cold start
      for (int j = 0; j < n; ++j) {
        x[j] = lower[j];
        state_[j] = kAtLower;
      }
    }
  }

  SolverStatus status = SolverStatus::kOptimal;
  bool x_changed = true;
  for (;;) {
    if (x_changed) {
      for (int j = 0; j < n; ++j) {
        double s = Atb_[j];
        for (int l = 0; l < n; ++l)
          s -= AtA_(j, l) * x[l];
        w_[j] = s;
      }
      for (int j = 0; j < n; ++j)
        rejected_[j] = 0;
    }
    // Bound variable whose dual most strongly asks to leave its bound.
    int t = -1;
    double best = tol;
    for (int j = 0; j < n; ++j) {
      if (state_[j] == kFree || rejected_[j] || lower[j] == upper[j]) continue;
      const double v = state_[j] == kAtLower ? w_[j] : -w_[j];
      if (v > best) {
        best = v;
        t = j;
      }
    }
    if (t < 0) break;
    const int t_old_state = state_[t];
    state_[t] = kFree;

    x_changed = false;
    bool first = true;
    for (;;) {
      if (iterations_ >= max_iterations_) {
        status = SolverStatus::kIterationLimit;
        break;
      }
      ++iterations_;
      int k = 0;
      for (int j = 0; j < n; ++j)
        if (state_[j] == kFree) cols_[k++] = j;
      // Normal equations of the free variables: A_F^T A_F z = A_F^T (b - A_B x_B).
      for (int c = 0; c < k; ++c) {
        double s = Atb_[cols_[c]];
        for (int j = 0; j < n; ++j)
          if (state_[j] != kFree) s -= AtA_(cols_[c], j) * x[j];
        rhs_[c] = s;
      }
      if (!detail::subset_normal_equations(AtA_, cols_.data(), k, rhs_.data(), L_, z_.data())) {
        // rhs = b - A_B x_B in r_ (the residual is recomputed at the end).
        for (int i = 0; i < m; ++i) {
          double s = b[i];
          for (int j = 0; j < n; ++j)
            if (state_[j] != kFree) s -= A(i, j) * x[j];
          r_[i] = s;
        }
        detail::subset_least_squares(A, cols_.data(), k, r_.data(), W_, qr_rhs_, diag_, z_.data());
      }
      if (first) {
        first = false;
        int pos_t = 0;
        while (cols_[pos_t] != t)
          ++pos_t;
        const bool moves_in = t_old_state == kAtLower ? z_[pos_t] > x[t] : z_[pos_t] < x[t];
        if (!moves_in) {
          state_[t] = t_old_state;
          rejected_[t] = 1;
          break;
        }
      }
      x_changed = true;
      double alpha = 2.0;
      int blocking = -1;
      for (int c = 0; c < k; ++c) {
        const int j = cols_[c];
        double a = 2.0;
        if (z_[c] < lower[j]) {
          a = (lower[j] - x[j]) / (z_[c] - x[j]);
        } else if (z_[c] > upper[j]) {
          a = (upper[j] - x[j]) / (z_[c] - x[j]);
        }
        if (a < alpha) {
          alpha = a;
          blocking = j;
        }
      }
      if (blocking < 0) {
        for (int c = 0; c < k; ++c)
          x[cols_[c]] = z_[c];
        break;
      }
      alpha = std::max(alpha, 0.0);
      for (int c = 0; c < k; ++c) {
        const int j = cols_[c];
        x[j] += alpha * (z_[c] - x[j]);
        if (j == blocking) {
          const bool to_lower = z_[c] < lower[j];
          x[j] = to_lower ? lower[j] : upper[j];
          state_[j] = to_lower ? kAtLower : kAtUpper;
        } else if (x[j] <= lower[j]) {
          x[j] = lower[j];
          state_[j] = kAtLower;
        } else if (x[j] >= upper[j]) {
          x[j] = upper[j];
          state_[j] = kAtUpper;
        }
      }
    }
    if (status != SolverStatus::kOptimal) break;
    if (!x_changed) continue;  // rejected entering variable: duals unchanged, pick the next one
  }
  // Final residual and dual of the returned point.
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
