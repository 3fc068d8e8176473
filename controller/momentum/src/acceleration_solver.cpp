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
  const int max_rows = max_eq + n;  // equalities plus every joint bound active
  L_.setZero(nv, nv);
  Y_.setZero(nv, max_eq);
  S_.setZero(max_rows, max_rows);
  u_.setZero(nv);
  lambda_.setZero(max_rows);
  winv_.setZero(nv);
  P_.setZero(6, nv);
  Ft_.setZero(max_rows, 6);
  FtKinv_.setZero(max_rows, 6);
  C_aug_.setZero(max_rows, nv);
  d_aug_.setZero(max_rows);
  active_.assign(static_cast<std::size_t>(n), 0);
  side_.assign(static_cast<std::size_t>(n), 0);
  cols_.assign(static_cast<std::size_t>(nv), 0);
  row0_.assign(static_cast<std::size_t>(nv), 0);
  rows_.assign(static_cast<std::size_t>(nv), 0);
  ncols_ = 0;
  y_.setZero(nv);
  x_corr_.setZero(nv);
  rg_.setZero(nv);
  rd_.setZero(max_rows);
  lambda_corr_.setZero(max_rows);
  perm_.assign(static_cast<std::size_t>(max_rows), 0);
  S_saved_.setZero(max_rows, max_rows);
  schur_diag_.setZero(max_rows);
  C_kept_.setZero(max_eq, nv);
  d_kept_.setZero(max_eq);
  schur_work_.setZero(max_rows);
  schur_m_ = schur_rank_ = 0;
}

// Cholesky of the Schur complement, rank-revealing. S is first factorised with symmetric
// pivoting (the largest remaining diagonal first) until the largest remaining pivot is below
// kDependentPivot x the largest diagonal. Rows left over then are (to round-off) dependent on the
// kept ones: the feet of a leg with fewer than six joints (both feet fixed leave one relative
// motion no joint makes: rank 11 of 12 rows; nearly so when its hip yaws are not zero), or a
// bound on a joint the feet fix. A plain Cholesky "succeeds" on such a matrix with a round-off
// pivot, and the multipliers, hence x, come out as noise (seen: 1e4 N of momentum-rate error on
// a five-joint-leg humanoid); the left-over rows get zero multipliers instead, which is exact
// when their right-hand side is consistent (they then hold with the kept rows). When no row is
// left over, S is factorised again by Eigen's plain Cholesky, so that a well-posed tick keeps
// the round-off it always had (closed-loop runs are sensitive to it; the pivot order is decided
// by the same test either way).
void AccelerationSolver::factor_schur(Eigen::Index m) {
  // Left-looking, on the lower triangle only: column k of L is finished at step k from the
  // original entries below it; schur_diag_[i] holds S(i, i) minus the squares of row i's finished part.
  auto S = S_.topLeftCorner(m, m);
  auto saved = S_saved_.topLeftCorner(m, m);
  saved.triangularView<Eigen::Lower>() = S;
  auto diag = schur_diag_.head(m);
  diag = S.diagonal();
  const double tol = kDependentPivot * diag.maxCoeff();
  for (Eigen::Index i = 0; i < m; ++i) perm_[static_cast<std::size_t>(i)] = static_cast<int>(i);
  Eigen::Index k = 0;
  for (; k < m; ++k) {
    Eigen::Index p = k;
    for (Eigen::Index i = k + 1; i < m; ++i)
      if (diag[i] > diag[p]) p = i;
    if (!(diag[p] > tol)) break;  // also stops on NaN
    if (p != k) {  // symmetric swap of rows and columns k < p, in lower-triangle storage
      S.row(k).head(k).swap(S.row(p).head(k));
      std::swap(S(k, k), S(p, p));
      for (Eigen::Index i = k + 1; i < p; ++i) std::swap(S(i, k), S(p, i));
      for (Eigen::Index i = p + 1; i < m; ++i) std::swap(S(i, k), S(i, p));
      std::swap(diag[k], diag[p]);
      std::swap(perm_[static_cast<std::size_t>(k)], perm_[static_cast<std::size_t>(p)]);
    }
    const double pivot = std::sqrt(diag[k]);
    S(k, k) = pivot;
    // plain loops: at these sizes (m <= ~30) Eigen's GEMV costs more in set-up than in work
    const double inv = 1.0 / pivot;
    for (Eigen::Index i = k + 1; i < m; ++i) {
      double v = S(i, k);
      for (Eigen::Index j = 0; j < k; ++j) v -= S(i, j) * S(k, j);
      v *= inv;
      S(i, k) = v;
      diag[i] -= v * v;
    }
  }
  schur_m_ = m;
  schur_rank_ = k;
  if (k < m) return;
  S.triangularView<Eigen::Lower>() = saved;
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(S);
  if (llt.info() == Eigen::Success) return;  // solve_schur: rows in their order
  schur_rank_ = 0;  // not positive definite after all (round-off at the bound): give up this path
}

void AccelerationSolver::solve_schur(Eigen::Ref<Eigen::VectorXd> v) {
  const Eigen::Index m = schur_m_, r = schur_rank_;
  if (r == m) {  // full rank: the plain Cholesky factor, rows in their order
    const auto L = S_.topLeftCorner(m, m).triangularView<Eigen::Lower>();
    L.solveInPlace(v);
    L.transpose().solveInPlace(v);
    return;
  }
  auto w = schur_work_.head(m);
  for (Eigen::Index i = 0; i < m; ++i) w[i] = v[perm_[static_cast<std::size_t>(i)]];
  const auto L = S_.topLeftCorner(r, r).triangularView<Eigen::Lower>();
  auto head = w.head(r);
  L.solveInPlace(head);
  L.transpose().solveInPlace(head);
  w.tail(m - r).setZero();
  for (Eigen::Index i = 0; i < m; ++i) v[perm_[static_cast<std::size_t>(i)]] = w[i];
}

void AccelerationSolver::form_hessian(const Eigen::Ref<const Eigen::MatrixXd>& A, double w_b,
                                      const Eigen::Ref<const Eigen::VectorXd>& w) {
  G_.noalias() = A.transpose() * A;
  G_ *= w_b;
  G_.diagonal() += w;
}

// The products below are written as loops over the columns of A and C: the sizes are small
// (6 or m <= 12 rows, nv ~ 25 columns), where Eigen's general GEMM/GEMV kernels spend more time on
// blocking and packing than on arithmetic, and C has whole zero columns (a foot's Jacobian does
// not depend on the other limbs' joints), which are skipped (cols_ lists the others).

void AccelerationSolver::apply_g_inverse(const Eigen::Ref<const Eigen::VectorXd>& v,
                                         Eigen::Ref<Eigen::VectorXd> y) {
  // y = W^-1 v - P^T K^-1 P v
  Vector6 pv = Vector6::Zero();
  for (int j = 0; j < nv_; ++j)
    pv += P_.col(j) * v[j];
  const Vector6 kpv = Kinv_ * pv;
  for (int j = 0; j < nv_; ++j)
    y[j] = winv_[j] * v[j] - P_.col(j).dot(kpv);
}

void AccelerationSolver::woodbury_kkt_solve(const Eigen::Ref<const Eigen::MatrixXd>& C,
                                            const Eigen::Ref<const Eigen::VectorXd>& g_rhs,
                                            const Eigen::Ref<const Eigen::VectorXd>& d_rhs,
                                            Eigen::Ref<Eigen::VectorXd> x,
                                            Eigen::Ref<Eigen::VectorXd> lambda) {
  // G x + g = C^T lambda, C x = d:  S lambda = d + C G^-1 g,  x = G^-1 (C^T lambda - g).
  const Eigen::Index m = C.rows();
  if (m == 0) {
    apply_g_inverse(g_rhs, x);
    x = -x;
    return;
  }
  apply_g_inverse(g_rhs, u_);
  lambda = d_rhs;
  for (int k = 0; k < ncols_; ++k)
    lambda.segment(row0_[k], rows_[k]) +=
        C.col(cols_[k]).segment(row0_[k], rows_[k]) * u_[cols_[k]];
  solve_schur(lambda);
  y_ = -g_rhs;
  for (int k = 0; k < ncols_; ++k)
    y_[cols_[k]] +=
        C.col(cols_[k]).segment(row0_[k], rows_[k]).dot(lambda.segment(row0_[k], rows_[k]));
  apply_g_inverse(y_, x);
}

bool AccelerationSolver::solve_equality_woodbury(const Eigen::Ref<const Eigen::MatrixXd>& A,
                                                 double w_b,
                                                 const Eigen::Ref<const Eigen::VectorXd>& w,
                                                 const Eigen::Ref<const Eigen::MatrixXd>& C,
                                                 const Eigen::Ref<const Eigen::VectorXd>& d,
                                                 Eigen::Ref<Eigen::VectorXd> x) {
  const Eigen::Index m = C.rows();
  // P = A W^-1 and K = I / w_b + P A^T (a sum of nv outer products of 6-vectors).
  Matrix6 K = Matrix6::Identity() / w_b;
  for (int j = 0; j < nv_; ++j) {
    winv_[j] = 1.0 / w[j];
    P_.col(j) = A.col(j) * winv_[j];
    K.noalias() += P_.col(j) * A.col(j).transpose();
  }
  llt_k_.compute(K);
  if (llt_k_.info() != Eigen::Success) return false;
  Kinv_ = llt_k_.solve(Matrix6::Identity());
  // Columns of C that are not zero, and the rows [row0, row0 + rows) between their first and
  // last non-zero (a leg joint's column has only its foot's 6 rows).
  ncols_ = 0;
  for (int j = 0; j < nv_ && m > 0; ++j) {
    int first = -1, last = -1;
    for (int r = 0; r < m; ++r)
      if (C(r, j) != 0.0) {
        if (first < 0) first = r;
        last = r;
      }
    if (first < 0) continue;
    cols_[ncols_] = j;
    row0_[ncols_] = first;
    rows_[ncols_] = last - first + 1;
    ++ncols_;
  }
  auto lambda = lambda_.head(m);
  if (m > 0) {
    // S = C W^-1 C^T - F^T K^-1 F with F = P C^T; built as Ft = F^T (m x 6) and the lower triangle
    // of S from outer products of C's columns.
    auto Ft = Ft_.topRows(m);
    auto S = S_.topLeftCorner(m, m);
    Ft.setZero();
    S.setZero();
    for (int k = 0; k < ncols_; ++k) {
      const int j = cols_[k];
      const Eigen::Index r0 = row0_[k], len = rows_[k];
      const auto c = C.col(j).segment(r0, len);
      for (Eigen::Index r = 0; r < 6; ++r)
        Ft.col(r).segment(r0, len) += c * P_(r, j);
      for (Eigen::Index i = 0; i < len; ++i)
        S.col(r0 + i).segment(r0 + i, len - i) += (winv_[j] * c[i]) * c.tail(len - i);
    }
    auto FtKinv = FtKinv_.topRows(m);
    FtKinv.noalias() = Ft.lazyProduct(Kinv_);
    for (Eigen::Index r = 0; r < 6; ++r)
      for (Eigen::Index col = 0; col < m; ++col)
        S.col(col).tail(m - col) -= FtKinv(col, r) * Ft.col(r).tail(m - col);
    factor_schur(m);
    if (schur_rank_ == 0) return false;
  }
  woodbury_kkt_solve(C, g_, d, x, lambda);
  // One step of iterative refinement on the KKT system: the Woodbury form subtracts two large
  // terms when w is small next to A^T A, and the residual is cheap (G v = w .* v + w_b A^T (A v)).
  Vector6 ax = Vector6::Zero();
  for (int j = 0; j < nv_; ++j)
    ax += A.col(j) * x[j];
  ax *= w_b;
  for (int j = 0; j < nv_; ++j)
    rg_[j] = w[j] * x[j] + g_[j] + A.col(j).dot(ax);
  auto rd = rd_.head(m);
  auto lambda_corr = lambda_corr_.head(m);
  if (m > 0) {
    rd = d;
    for (int k = 0; k < ncols_; ++k) {
      const int j = cols_[k];
      rg_[j] -= C.col(j).segment(row0_[k], rows_[k]).dot(lambda.segment(row0_[k], rows_[k]));
      rd.segment(row0_[k], rows_[k]) -= C.col(j).segment(row0_[k], rows_[k]) * x[j];
    }
  }
  woodbury_kkt_solve(C, rg_, rd, x_corr_, lambda_corr);
  x += x_corr_;
  lambda += lambda_corr;
  return x.allFinite();
}

bool AccelerationSolver::solve_bounds_woodbury(
    const Eigen::Ref<const Eigen::MatrixXd>& A, double w_b,
    const Eigen::Ref<const Eigen::VectorXd>& w, const Eigen::Ref<const Eigen::MatrixXd>& C,
    const Eigen::Ref<const Eigen::VectorXd>& d, const Eigen::Ref<const Eigen::VectorXd>& lo,
    const Eigen::Ref<const Eigen::VectorXd>& hi, Eigen::Ref<Eigen::VectorXd> x, Result& r) {
  const int n = nv_ - 6;
  const auto m = static_cast<int>(C.rows());
  C_aug_.topRows(m) = C;
  d_aug_.head(m) = d;
  std::fill(side_.begin(), side_.end(), 0);
  int k = 0;  // active bounds: rows m .. m + k - 1 of C_aug_, joints active_[0, k)
  for (int solves = 0; solves < 2 * n + 4; ++solves) {
    // 1. An active bound whose multiplier has the wrong sign leaves (the most wrong one first).
    //    G x + g = C^T lambda + lambda_b e_j: a lower bound needs lambda_b >= 0, an upper one <= 0.
    if (k > 0) {
      int worst = -1;
      double worst_value = 0.0;
      for (int i = 0; i < k; ++i) {
        const double l = lambda_[m + i] * (side_[active_[i]] > 0 ? -1.0 : 1.0);  // >= 0 is right
        if (l < -1e-10 * (1.0 + std::abs(lambda_[m + i])) && l < worst_value) {
          worst = i;
          worst_value = l;
        }
      }
      if (worst >= 0) {
        side_[active_[worst]] = 0;
        active_[worst] = active_[k - 1];
        --k;
        for (int i = 0; i < k; ++i) {  // rebuild the bound rows
          C_aug_.row(m + i).setZero();
          C_aug_(m + i, 6 + active_[i]) = 1.0;
          d_aug_[m + i] = side_[active_[i]] > 0 ? hi[active_[i]] : lo[active_[i]];
        }
        if (!solve_equality_woodbury(A, w_b, w, C_aug_.topRows(m + k), d_aug_.head(m + k), x))
          return false;
        ++r.iterations;
        continue;
      }
    }
    // 2. The most violated inactive bound joins.
    int add = -1, add_side = 0;
    double add_violation = 0.0;
    for (int j = 0; j < n; ++j) {
      if (side_[j] != 0) continue;
      const double v = x[6 + j];
      const double tol = 1e-9 * (1.0 + std::abs(v));
      if (v < lo[j] - tol && lo[j] - v > add_violation) {
        add = j;
        add_side = -1;
        add_violation = lo[j] - v;
      } else if (v > hi[j] + tol && v - hi[j] > add_violation) {
        add = j;
        add_side = 1;
        add_violation = v - hi[j];
      }
    }
    if (add < 0) {  // primal feasible, multipliers of the right sign: the KKT point
      // unless nearly dependent rows cost the equalities their accuracy
      double res = 0.0, scale = 1.0;
      for (int row = 0; row < m + k; ++row) {
        res = std::max(res, std::abs(C_aug_.row(row).dot(x) - d_aug_[row]));
        scale = std::max(scale, std::abs(d_aug_[row]));
      }
      if (!(res <= 1e-9 * scale)) return false;
      r.active_bounds = k;
      r.dependent_rows = static_cast<int>(schur_m_ - schur_rank_);
      return true;
    }
    side_[add] = add_side;
    active_[k] = add;
    C_aug_.row(m + k).setZero();
    C_aug_(m + k, 6 + add) = 1.0;
    d_aug_[m + k] = add_side > 0 ? hi[add] : lo[add];
    ++k;
    if (!solve_equality_woodbury(A, w_b, w, C_aug_.topRows(m + k), d_aug_.head(m + k), x))
      return false;  // dependent rows (e.g. a bound on a joint the feet fix), or not finite
    ++r.iterations;
  }
  return false;
}

bool AccelerationSolver::solve_equality_dense(const Eigen::Ref<const Eigen::MatrixXd>& C,
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
    factor_schur(m);
    if (schur_rank_ == 0) return false;
    solve_schur(lambda);
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
  // 0.5 x^T G x + g^T x  ==  0.5 * objective + const, G = w_b A^T A + diag(w).
  g_.noalias() = A.transpose() * b;
  g_ *= -w_b;
  g_ -= w.cwiseProduct(t);
  b_in_.head(n) = lo;
  b_in_.tail(n) = -hi;
  const bool woodbury = !dense_equality_ && (w.array() > 0.0).all() && w.allFinite();
  bool have_g = false;
  bool solved = false;
  if (fast_path_) {
    if (woodbury) solved = solve_equality_woodbury(A, w_b, w, C, d, x);
    if (!solved) {
      form_hessian(A, w_b, w);
      have_g = true;
      solved = solve_equality_dense(C, d, x);
    }
  }
  // Rows of C the equality solve found dependent: DualQp below gets only the kept ones
  // (Goldfarb-Idnani needs independent equalities). Copied now, while perm_ still holds them
  // (the active set refactorises); the usual tick has none and copies nothing.
  Eigen::Index kept = C.rows();
  if (solved && C.rows() > 0 && schur_rank_ < schur_m_) {
    kept = schur_rank_;
    for (Eigen::Index i = 0; i < kept; ++i) {
      C_kept_.row(i) = C.row(perm_[static_cast<std::size_t>(i)]);
      d_kept_[i] = d[perm_[static_cast<std::size_t>(i)]];
    }
  }
  const bool reduced = kept < C.rows();
  const Eigen::Ref<const Eigen::MatrixXd> Ck =
      reduced ? Eigen::Ref<const Eigen::MatrixXd>(C_kept_.topRows(kept)) : C;
  const Eigen::Ref<const Eigen::VectorXd> dk =
      reduced ? Eigen::Ref<const Eigen::VectorXd>(d_kept_.head(kept)) : d;
  if (solved) {
    r.dependent_rows = static_cast<int>(C.rows() - kept);
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
  if (solved && woodbury && primal_active_set_ &&
      solve_bounds_woodbury(A, w_b, w, C, d, lo, hi, x, r)) {
    r.status = contact::SolverStatus::kOptimal;
    return r;
  }
  r.used_dual_qp = true;
  r.iterations = 0;
  r.active_bounds = 0;
  if (!have_g) form_hessian(A, w_b, w);
  r.status = qp_.solve(G_, g_, Ck, dk, A_in_, b_in_, x);
  r.iterations = qp_.iterations();
  if (r.status == contact::SolverStatus::kInfeasible) {
    r.bounds_dropped = true;
    r.status = qp_.solve(G_, g_, Ck, dk, A_in_.topRows(0), b_in_.head(0), x);
    r.iterations += qp_.iterations();
    return r;
  }
  r.active_bounds = qp_.active_set_size() - static_cast<int>(kept);
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
