#pragma once

// Private steps shared by the active-set least-squares solvers Nnls and Bvls, on their
// LeastSquaresWorkspace: input checks, the normal equations A^T A, A^T b, the sub-problem solves on
// a subset of the columns (Cholesky of the normal equations, Householder QR of the columns as the
// fallback when the subset is ill-conditioned) and the dual of the answer. Plain loops on
// preallocated storage: nothing here allocates.

#include <algorithm>
#include <cmath>

#include <Eigen/Core>

#include "poise/contact/least_squares_workspace.hpp"

namespace poise::contact::detail {

using ConstMatrixRef = Eigen::Ref<const Eigen::MatrixXd>;
using ConstVectorRef = Eigen::Ref<const Eigen::VectorXd>;

// Finite check without branches: v * 0 is 0 for a finite v and NaN for an infinite or NaN one.
inline bool all_finite(const ConstMatrixRef& M) {
  double acc = 0.0;
  for (Eigen::Index j = 0; j < M.cols(); ++j)
    for (Eigen::Index i = 0; i < M.rows(); ++i)
      acc += M(i, j) * 0.0;
  return acc == 0.0;
}

inline bool all_finite(const ConstVectorRef& v) {
  double acc = 0.0;
  for (Eigen::Index i = 0; i < v.size(); ++i)
    acc += v[i] * 0.0;
  return acc == 0.0;
}

/// Dense form min ||A x - b||: checks that A (m x n) and b fit the workspace and are finite, then
/// forms ws.AtA = A^T A and ws.Atb = A^T b. Returns false on bad input. norm_a = ||A||_F,
/// norm_b = ||b||.
inline bool load_dense(const ConstMatrixRef& A, const ConstVectorRef& b, LeastSquaresWorkspace& ws,
                       double& norm_a, double& norm_b) {
  const int m = static_cast<int>(A.rows());
  const int n = static_cast<int>(A.cols());
  if (m <= 0 || n <= 0 || m > ws.max_rows || n > ws.max_cols || b.size() != m || !all_finite(A) ||
      !all_finite(b)) {
    return false;
  }
  double trace = 0.0;
  for (int j = 0; j < n; ++j) {
    for (int l = 0; l <= j; ++l) {
      double s = 0.0;
      for (int i = 0; i < m; ++i)
        s += A(i, j) * A(i, l);
      ws.AtA(j, l) = s;
      ws.AtA(l, j) = s;
    }
    trace += ws.AtA(j, j);
    double s = 0.0;
    for (int i = 0; i < m; ++i)
      s += A(i, j) * b[i];
    ws.Atb[j] = s;
  }
  norm_a = std::sqrt(trace);
  norm_b = b.norm();
  return true;
}

/// Normal-equation form: H = A^T A (n x n, symmetric positive semidefinite) and c = A^T b given
/// directly. Checks sizes and finiteness, copies them into ws.AtA and ws.Atb. Returns false on bad
/// input. norm_a = sqrt(trace H) = ||A||_F.
inline bool load_normal(const ConstMatrixRef& H, const ConstVectorRef& c, LeastSquaresWorkspace& ws,
                        double& norm_a) {
  const int n = static_cast<int>(H.cols());
  if (n <= 0 || n > ws.max_cols || H.rows() != n || c.size() != n || !all_finite(H) ||
      !all_finite(c)) {
    return false;
  }
  double trace = 0.0;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i)
      ws.AtA(i, j) = H(i, j);
    ws.Atb[j] = c[j];
    trace += H(j, j);
  }
  norm_a = trace > 0.0 ? std::sqrt(trace) : 0.0;
  return true;
}

/// ws.w = A^T (b - A x) through the residual (kept in ws.r): more accurate than the Gram form.
inline void dual_from_residual(const ConstMatrixRef& A, const double* b, const double* x,
                               LeastSquaresWorkspace& ws) {
  const int m = static_cast<int>(A.rows());
  const int n = static_cast<int>(A.cols());
  for (int i = 0; i < m; ++i) {
    double s = b[i];
    for (int j = 0; j < n; ++j)
      s -= A(i, j) * x[j];
    ws.r[i] = s;
  }
  for (int j = 0; j < n; ++j) {
    double s = 0.0;
    for (int i = 0; i < m; ++i)
      s += A(i, j) * ws.r[i];
    ws.w[j] = s;
  }
}

/// ws.w = A^T b - A^T A x from the normal equations.
inline void dual_from_normal(int n, const double* x, LeastSquaresWorkspace& ws) {
  for (int j = 0; j < n; ++j) {
    const double* col = &ws.AtA(0, j);  // AtA is symmetric: column j = row j, contiguous
    double s = ws.Atb[j];
    for (int l = 0; l < n; ++l)
      s -= col[l] * x[l];
    ws.w[j] = s;
  }
}

/// Solves min_z || A(:, cols) z - rhs || for the k columns listed in ws.cols by Householder QR.
/// A: m x n. rhs: m. z: output in ws.z, z[c] belongs to column cols[c]. A column whose Householder
/// pivot is below `rank_tol` relative to the largest column norm is treated as dependent and gets
/// z = 0 (basic solution). Uses ws.W, ws.qr_rhs, ws.diag.
inline void subset_least_squares(const ConstMatrixRef& A, int k, const double* rhs,
                                 LeastSquaresWorkspace& ws, double rank_tol = 1e-12) {
  const int m = static_cast<int>(A.rows());
  const int* cols = ws.cols.data();
  Eigen::MatrixXd& W = ws.W;
  double* r = ws.qr_rhs.data();
  double* diag = ws.diag.data();
  double* z = ws.z.data();
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

/// Solves AtA(cols, cols) z = rhs for the k columns in ws.cols (rhs in ws.rhs, z in ws.z) by an
/// L D L^T factorisation (no square roots), updated incrementally: rows [0, factored) of the factor
/// are those of the current first `factored` columns and are kept (callers append columns at the
/// end and, when they remove one at position p, lower `factored` to p); rows [factored, k) are
/// computed here, and `factored` is set to k. Returns false, leaving z unspecified, when a pivot
/// d_i falls below `pivot_tol` times the largest diagonal entry: the subset is too ill-conditioned
/// for the normal equations and the caller must use subset_least_squares() instead (or give up
/// when it has no A).
/// Storage: ws.L holds the unit lower factor transposed, ws.L(p, i) = L(i, p) for p < i (a row of
/// L is a contiguous column), and 1 / d_i on its diagonal; ws.pivot holds d_i.
inline bool subset_normal_equations(int k, int& factored, LeastSquaresWorkspace& ws,
                                    double pivot_tol = 1e-10) {
  const int* cols = ws.cols.data();
  const Eigen::MatrixXd& AtA = ws.AtA;
  Eigen::MatrixXd& U = ws.L;
  double* pivot = ws.pivot.data();
  const double* rhs = ws.rhs.data();
  double* z = ws.z.data();
  double max_diag = 0.0;
  for (int c = 0; c < k; ++c)
    max_diag = std::max(max_diag, AtA(cols[c], cols[c]));
  const double min_pivot = pivot_tol * max_diag;
  factored = std::min(factored, k);
  for (int j = 0; j < factored; ++j) {  // kept rows: their pivots against the current scale
    if (!(pivot[j] > min_pivot)) {
      factored = j;
      return false;
    }
  }
  for (int i = factored; i < k; ++i) {  // new rows of L (columns of U)
    const double* a = &AtA(0, cols[i]);
    double* ui = &U(0, i);
    for (int j = 0; j < i; ++j) {  // ui[j] = L(i, j) d_j first
      const double* uj = &U(0, j);
      double t = a[cols[j]];
      for (int p = 0; p < j; ++p)
        t -= ui[p] * uj[p];
      ui[j] = t;
    }
    double d = a[cols[i]];
    for (int p = 0; p < i; ++p) {  // then L(i, p) = ui[p] / d_p, d_i = a_ii - sum L(i, p)^2 d_p
      const double l = ui[p] * U(p, p);
      d -= l * ui[p];
      ui[p] = l;
    }
    if (!(d > min_pivot)) {
      factored = i;
      return false;
    }
    pivot[i] = d;
    ui[i] = 1.0 / d;
  }
  factored = k;
  for (int i = 0; i < k; ++i) {  // L y = rhs
    const double* ui = &U(0, i);
    double s = rhs[i];
    for (int p = 0; p < i; ++p)
      s -= ui[p] * z[p];
    z[i] = s;
  }
  for (int i = k - 1; i >= 0; --i) {  // L^T z = D^-1 y
    double s = z[i] * U(i, i);
    for (int p = i + 1; p < k; ++p)
      s -= U(i, p) * z[p];
    z[i] = s;
  }
  return true;
}

/// Removes from ws.cols[0, k) the entries at the positions c where keep(c) is false (keep may
/// read ws.cols[c] and anything indexed by c), keeping the order of the others, and lowers
/// `factored` to the first removed position (the factor rows before it stay valid). Returns the
/// new k.
template <typename Keep>
int compact_columns(int k, int& factored, LeastSquaresWorkspace& ws, Keep keep) {
  int* cols = ws.cols.data();
  int kept = 0;
  for (int c = 0; c < k; ++c) {
    if (keep(c)) {
      cols[kept++] = cols[c];
    } else if (c < factored) {
      factored = c;
    }
  }
  return kept;
}

}  // namespace poise::contact::detail
