#pragma once

// Private helper of Nnls and Bvls: least squares on a subset of the columns of A by Householder QR,
// written with plain loops on preallocated storage so that it never allocates.

#include <cmath>

#include <Eigen/Core>

namespace poise::contact::detail {

/// Solves min_z || A(:, cols) z - rhs || for the k columns listed in `cols`.
/// A: m x n. cols: k indices into A's columns. rhs: m. W: workspace with >= m rows, >= k cols
/// (overwritten). r: workspace >= m. diag: workspace >= k. z: output, >= k entries, z[c] belongs to
/// column cols[c]. A column whose Householder pivot is below `rank_tol` relative to the largest
/// column norm is treated as dependent and gets z = 0 (basic solution).
inline void subset_least_squares(const Eigen::Ref<const Eigen::MatrixXd>& A, const int* cols, int k,
                                 const double* rhs, Eigen::MatrixXd& W, Eigen::VectorXd& r,
                                 Eigen::VectorXd& diag, double* z, double rank_tol = 1e-12) {
  const int m = static_cast<int>(A.rows());
  double max_norm = 0.0;
  for (int c = 0; c < k; ++c) {
    double s = 0.0;
    for (int i = 0; i < m; ++i) {
      const double a = A(i, cols[c]);
      W(i, c) = a;
      s += a * a;
    }
    max_norm = std::max(max_norm, std::sqrt(s));
  }
  for (int i = 0; i < m; ++i)
    r[i] = rhs[i];
  const int steps = std::min(m, k);
  for (int j = 0; j < steps; ++j) {
    double norm2 = 0.0;
    for (int i = j; i < m; ++i)
      norm2 += W(i, j) * W(i, j);
    const double norm = std::sqrt(norm2);
    if (norm <= rank_tol * max_norm || norm == 0.0) {
      diag[j] = 0.0;
      continue;
    }
    const double alpha = W(j, j) > 0.0 ? -norm : norm;
    const double x0 = W(j, j);
    const double v0 = x0 - alpha;
    W(j, j) = v0;  // W(j:m, j) now holds the Householder vector v
    const double vnorm2 = norm2 - x0 * x0 + v0 * v0;  // = ||v||^2
    diag[j] = alpha;
    if (vnorm2 <= 0.0) continue;
    for (int c = j + 1; c < k; ++c) {
      double s = 0.0;
      for (int i = j; i < m; ++i)
        s += W(i, j) * W(i, c);
      const double f = 2.0 * s / vnorm2;
      for (int i = j; i < m; ++i)
        W(i, c) -= f * W(i, j);
    }
    double s = 0.0;
    for (int i = j; i < m; ++i)
      s += W(i, j) * r[i];
    const double f = 2.0 * s / vnorm2;
    for (int i = j; i < m; ++i)
      r[i] -= f * W(i, j);
  }
  for (int j = k - 1; j >= 0; --j) {
    if (j >= steps || diag[j] == 0.0) {
      z[j] = 0.0;
      continue;
    }
    double s = r[j];
    for (int c = j + 1; c < k; ++c)
      s -= W(j, c) * z[c];
    z[j] = s / diag[j];
  }
}

}  // namespace poise::contact::detail

namespace poise::contact::detail {

/// Solves AtA(cols, cols) z = rhs (k x k, rhs[c] for column cols[c]) by Cholesky in the workspace
/// L (>= k x k). Returns false, leaving z unspecified, when a pivot falls below `pivot_tol` times
/// the largest diagonal entry: the subset is too ill-conditioned for the normal equations and the
/// caller must use subset_least_squares() instead.
inline bool subset_normal_equations(const Eigen::MatrixXd& AtA, const int* cols, int k,
                                    const double* rhs, Eigen::MatrixXd& L, double* z,
                                    double pivot_tol = 1e-10) {
  double max_diag = 0.0;
  for (int c = 0; c < k; ++c)
    max_diag = std::max(max_diag, AtA(cols[c], cols[c]));
  for (int j = 0; j < k; ++j) {
    double s = AtA(cols[j], cols[j]);
    for (int p = 0; p < j; ++p)
      s -= L(j, p) * L(j, p);
    if (!(s > pivot_tol * max_diag)) return false;
    const double ljj = std::sqrt(s);
    L(j, j) = ljj;
    for (int i = j + 1; i < k; ++i) {
      double t = AtA(cols[i], cols[j]);
      for (int p = 0; p < j; ++p)
        t -= L(i, p) * L(j, p);
      L(i, j) = t / ljj;
    }
  }
  for (int i = 0; i < k; ++i) {  // L y = rhs
    double s = rhs[i];
    for (int p = 0; p < i; ++p)
      s -= L(i, p) * z[p];
    z[i] = s / L(i, i);
  }
  for (int i = k - 1; i >= 0; --i) {  // L^T z = y
    double s = z[i];
    for (int p = i + 1; p < k; ++p)
      s -= L(p, i) * z[p];
    z[i] = s / L(i, i);
  }
  return true;
}

}  // namespace poise::contact::detail
