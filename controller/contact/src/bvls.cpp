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

SolverStatus Bvls::run(const Eigen::Ref<const Eigen::MatrixXd>* A, const double* b, int n,
                       double norm_a, double b_norm, const Eigen::Ref<const Eigen::VectorXd>& lower,
                       const Eigen::Ref<const Eigen::VectorXd>& upper,
                       Eigen::Ref<Eigen::VectorXd> x) {
  int* cols = ws_.cols.data();  // the free variables, in the order they were freed
  int* state = ws_.state.data();
  int* rejected = ws_.rejected.data();
  const double* z = ws_.z.data();
  double bound_scale = 0.0;
  for (int j = 0; j < n; ++j) {
    const double v = std::max(std::abs(lower[j]), std::abs(upper[j]));
    bound_scale += v * v;
  }
  const double tol = tolerance_ * norm_a * (b_norm + norm_a * std::sqrt(bound_scale)) + 1e-300;

  // Right-hand side of the free variables' normal equations, A_F^T (b - A_B x_B), in ws_.rhs.
  double* x_bound = ws_.xb.data();
  auto free_rhs = [&](int k) {
    for (int j = 0; j < n; ++j)
      x_bound[j] = state[j] != kFree ? x[j] : 0.0;
    for (int c = 0; c < k; ++c) {
      const double* col = &ws_.AtA(0, cols[c]);  // symmetric: column = row, contiguous
      double s = ws_.Atb[cols[c]];
      for (int j = 0; j < n; ++j)
        s -= col[j] * x_bound[j];
      ws_.rhs[c] = s;
    }
  };
  auto is_free = [&](int c) { return state[cols[c]] == kFree; };

  // Start with every variable at its lower bound (Stark-Parker's cold start).
  for (int j = 0; j < n; ++j) {
    x[j] = lower[j];
    state[j] = kAtLower;
    rejected[j] = 0;
  }
  int k = 0;         // number of free variables
  int factored = 0;  // leading columns whose Cholesky rows are valid

  // Warm start (Stark-Parker's alternative start): solve with every non-fixed variable free; move
  // the variables that leave their bounds onto the violated bound and re-solve, until the free
  // solution is inside its bounds. The result is a feasible point from which the main loop
  // continues; if a sub-problem is ill-conditioned the cold start above is kept.
  {
    for (int j = 0; j < n; ++j) {
      if (lower[j] < upper[j]) {
        state[j] = kFree;
        cols[k++] = j;
      }
    }
    bool done = false;
    while (!done && iterations_ < max_iterations_) {
      ++iterations_;
      if (k == 0) {
        done = true;
        break;
      }
      free_rhs(k);
      if (!detail::subset_normal_equations(k, factored, ws_)) break;
      bool inside = true;
      for (int c = 0; c < k; ++c) {
        const int j = cols[c];
        if (z[c] < lower[j]) {
          x[j] = lower[j];
          state[j] = kAtLower;
          inside = false;
        } else if (z[c] > upper[j]) {
          x[j] = upper[j];
          state[j] = kAtUpper;
          inside = false;
        }
      }
      if (inside) {
        for (int c = 0; c < k; ++c)
          x[cols[c]] = z[c];
        done = true;
      } else {
        k = detail::compact_columns(k, factored, ws_, is_free);
      }
    }
    if (!done) {  // back to the cold start
      for (int j = 0; j < n; ++j) {
        x[j] = lower[j];
        state[j] = kAtLower;
      }
      k = 0;
      factored = 0;
    }
  }

  SolverStatus status = SolverStatus::kOptimal;
  bool x_changed = true;
  for (;;) {
    if (x_changed) {
      detail::dual_from_normal(n, x.data(), ws_);
      for (int j = 0; j < n; ++j)
        rejected[j] = 0;
    }
    // Bound variable whose dual most strongly asks to leave its bound.
    int t = -1;
    double best = tol;
    for (int j = 0; j < n; ++j) {
      if (state[j] == kFree || rejected[j] || lower[j] == upper[j]) continue;
      const double v = state[j] == kAtLower ? ws_.w[j] : -ws_.w[j];
      if (v > best) {
        best = v;
        t = j;
      }
    }
    if (t < 0) break;
    const int t_old_state = state[t];
    state[t] = kFree;
    cols[k++] = t;

    x_changed = false;
    bool first = true;
    for (;;) {
      if (iterations_ >= max_iterations_) {
        status = SolverStatus::kIterationLimit;
        break;
      }
      ++iterations_;
      free_rhs(k);
      if (!detail::subset_normal_equations(k, factored, ws_)) {
        if (A == nullptr) {  // normal-equation form: no columns to fall back on
          if (first) {       // x[t] is still on its old bound: x stays feasible
            state[t] = t_old_state;
            --k;
            factored = std::min(factored, k);
          }
          status = SolverStatus::kNotPositiveDefinite;
          break;
        }
        // rhs = b - A_B x_B in ws_.r (the residual is recomputed at the end).
        const int m = static_cast<int>(A->rows());
        for (int i = 0; i < m; ++i) {
          double s = b[i];
          for (int j = 0; j < n; ++j)
            if (state[j] != kFree) s -= (*A)(i, j) * x[j];
          ws_.r[i] = s;
        }
        detail::subset_least_squares(*A, k, ws_.r.data(), ws_);
      }
      if (first) {
        first = false;
        // The entering variable is the last free one.
        const bool moves_in = t_old_state == kAtLower ? z[k - 1] > x[t] : z[k - 1] < x[t];
        if (!moves_in) {
          state[t] = t_old_state;
          rejected[t] = 1;
          --k;
          factored = std::min(factored, k);
          break;
        }
      }
      x_changed = true;
      double alpha = 2.0;
      int blocking = -1;
      for (int c = 0; c < k; ++c) {
        const int j = cols[c];
        double a = 2.0;
        if (z[c] < lower[j]) {
          a = (lower[j] - x[j]) / (z[c] - x[j]);
        } else if (z[c] > upper[j]) {
          a = (upper[j] - x[j]) / (z[c] - x[j]);
        }
        if (a < alpha) {
          alpha = a;
          blocking = j;
        }
      }
      if (blocking < 0) {
        for (int c = 0; c < k; ++c)
          x[cols[c]] = z[c];
        break;
      }
      alpha = std::max(alpha, 0.0);
      for (int c = 0; c < k; ++c) {
        const int j = cols[c];
        x[j] += alpha * (z[c] - x[j]);
        if (j == blocking) {
          const bool to_lower = z[c] < lower[j];
          x[j] = to_lower ? lower[j] : upper[j];
          state[j] = to_lower ? kAtLower : kAtUpper;
        } else if (x[j] <= lower[j]) {
          x[j] = lower[j];
          state[j] = kAtLower;
        } else if (x[j] >= upper[j]) {
          x[j] = upper[j];
          state[j] = kAtUpper;
        }
      }
      k = detail::compact_columns(k, factored, ws_, is_free);
    }
    if (status != SolverStatus::kOptimal) break;
    if (!x_changed) continue;  // rejected entering variable: duals unchanged, pick the next one
  }
  return status;
}

}  // namespace poise::contact
