#pragma once
// Joint accelerations of the balance controller, paper eq (33):
//
//   min_x  w_b |A x - b|^2 + sum_j w_j (x_j - t_j)^2
//   s.t.   C x = d                    (foot accelerations, eq (36): J qdd = a_d - J_dot qd)
//          lo <= x[6:] <= hi          (joint-acceleration bounds from the joint limits)
//
// x = qdd (dim nv = 6 + n, the model's generalized acceleration), A the centroidal momentum
// matrix (6 x nv), b = hdot_a - A_dot qd (6). The diagonal term carries the paper's upper-body
// objective (1 - w_b) |qdd_u,d - qdd_u|^2 (w_j = 1 - w_b, t_j = qdd_u,d on upper-body joints)
// plus a small posture prior on every DoF (see AccelerationConfig::posture_weight); the caller
// combines them into (w, t).
//
// Method: first the equality-constrained problem alone (the usual case). Its Hessian
// G = w_b A^T A + diag(w) is a diagonal plus a rank-6 term, so when every w_j > 0, G^-1 is applied
// through the Sherman-Morrison-Woodbury identity
//   G^-1 = W^-1 - W^-1 A^T K^-1 A W^-1,   K = I / w_b + A W^-1 A^T   (6 x 6),
// and the multipliers come from the Schur complement S = C G^-1 C^T (m x m): O(nv (36 + m^2))
// work and no nv x nv matrix; one step of iterative refinement on the full KKT system (whose
// residual costs only O(nv (6 + m))) recovers the digits the identity loses when G is badly
// conditioned. With some w_j == 0, G itself is factorised (Cholesky, O(nv^3)). If that solution
// violates a joint bound, a primal active set on the same Woodbury factors follows: the most
// violated bound joins the equalities (x_j = bound), a bound whose multiplier has the wrong sign
// leaves them, and the equality problem is solved again, until the KKT conditions hold (a few
// solves: usually one or two bounds are active). If that does not settle within 2 n + 4 solves, or
// the rows become dependent, or the Woodbury form does not apply, the whole problem is solved as a
// strictly convex QP by the Goldfarb-Idnani dual method (poise::contact::DualQp); when the bounds
// make it infeasible it is solved again without them.

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <vector>

#include "poise/contact/dual_qp.hpp"
#include "poise/contact/solver_status.hpp"

namespace poise::controller {

class AccelerationSolver {
 public:
  AccelerationSolver() = default;
  /// nv: number of variables (>= 7); max_eq: maximum number of equality rows.
  /// Allocates; throws std::invalid_argument on bad sizes.
  AccelerationSolver(int nv, int max_eq) { resize(nv, max_eq); }
  void resize(int nv, int max_eq);

  struct Result {
    contact::SolverStatus status = contact::SolverStatus::kInvalidInput;
    bool bounds_dropped = false;  ///< infeasible with bounds: this is the bound-free solution
    int iterations = 0;
    int active_bounds = 0;
    /// Equality rows found dependent on the others (rank-revealing Cholesky of the Schur
    /// complement) and dropped: their multipliers are zero; they hold when consistent.
    int dependent_rows = 0;
    /// A bound was violated by the equality-only solution (then the primal active set or DualQp).
    bool used_active_set = false;
    bool used_dual_qp = false;  ///< DualQp solved the problem (the primal active set did not)
  };

  /// Disables the fast equality-only path (every solve goes through DualQp); for tests.
  void set_fast_path(bool enabled) { fast_path_ = enabled; }
  /// Forces the equality-only path to factorise G densely even when the Woodbury form applies;
  /// for tests and the benchmark's before/after comparison.
  void set_dense_equality_path(bool dense) { dense_equality_ = dense; }
  /// Disables the primal active set over the bounds (a violated bound then goes straight to
  /// DualQp, the method before it); for tests and the benchmark's before/after comparison.
  void set_primal_active_set(bool enabled) { primal_active_set_ = enabled; }

  /// A: 6 x nv, b: 6, w_b in (0, 1), w: nv (>= 0, with w_b A^T A + diag(w) positive definite),
  /// t: nv, C: m x nv (m <= max_eq), d: m, lo, hi: nv - 6 (lo <= hi), x: nv (output).
  /// Allocation-free, never throws. On failure x holds the solver's last iterate, or zero when the
  /// input was rejected.
  Result solve(const Eigen::Ref<const Eigen::MatrixXd>& A,
               const Eigen::Ref<const Eigen::VectorXd>& b, double w_b,
               const Eigen::Ref<const Eigen::VectorXd>& w,
               const Eigen::Ref<const Eigen::VectorXd>& t,
               const Eigen::Ref<const Eigen::MatrixXd>& C,
               const Eigen::Ref<const Eigen::VectorXd>& d,
               const Eigen::Ref<const Eigen::VectorXd>& lo,
               const Eigen::Ref<const Eigen::VectorXd>& hi, Eigen::Ref<Eigen::VectorXd> x);

  /// Gradient of the last solve, 0.5 x^T G x + g^T x form.
  const Eigen::VectorXd& gradient() const { return g_; }
  const contact::DualQp& qp() const { return qp_; }

 private:
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;

  void form_hessian(const Eigen::Ref<const Eigen::MatrixXd>& A, double w_b,
                    const Eigen::Ref<const Eigen::VectorXd>& w);
  bool solve_equality_dense(const Eigen::Ref<const Eigen::MatrixXd>& C,
                            const Eigen::Ref<const Eigen::VectorXd>& d,
                            Eigen::Ref<Eigen::VectorXd> x);
  bool solve_equality_woodbury(const Eigen::Ref<const Eigen::MatrixXd>& A, double w_b,
                               const Eigen::Ref<const Eigen::VectorXd>& w,
                               const Eigen::Ref<const Eigen::MatrixXd>& C,
                               const Eigen::Ref<const Eigen::VectorXd>& d,
                               Eigen::Ref<Eigen::VectorXd> x);
  // Primal active set over the joint bounds on the Woodbury factors (see the top of the file);
  // x holds the equality-only solution on entry. False: not settled (x is then unspecified).
  bool solve_bounds_woodbury(const Eigen::Ref<const Eigen::MatrixXd>& A, double w_b,
                             const Eigen::Ref<const Eigen::VectorXd>& w,
                             const Eigen::Ref<const Eigen::MatrixXd>& C,
                             const Eigen::Ref<const Eigen::VectorXd>& d,
                             const Eigen::Ref<const Eigen::VectorXd>& lo,
                             const Eigen::Ref<const Eigen::VectorXd>& hi,
                             Eigen::Ref<Eigen::VectorXd> x, Result& r);
  // y = G^-1 v by the Woodbury form (P_, K factor and winv_ of the current solve).
  void apply_g_inverse(const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> y);
  // Rank-revealing Cholesky of S_'s leading m x m block (lower triangle given), in place:
  // schur_rank_ kept rows; with fewer than m, perm_[0, schur_rank_) are the kept rows, else the
  // factor is the plain Cholesky of S in its own order. See the .cpp.
  void factor_schur(Eigen::Index m);
  // v = S^-1 v (full rank), or the kept rows' solution with zero on the dependent ones.
  void solve_schur(Eigen::Ref<Eigen::VectorXd> v);
  // (x, lambda) of G x + g_rhs = C^T lambda, C x = d_rhs from the Woodbury factors (S_ holds the
  // factor_schur factor of the Schur complement).
  void woodbury_kkt_solve(const Eigen::Ref<const Eigen::MatrixXd>& C,
                          const Eigen::Ref<const Eigen::VectorXd>& g_rhs,
                          const Eigen::Ref<const Eigen::VectorXd>& d_rhs,
                          Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> lambda);

  /// Pivot below this fraction of S's largest diagonal: a dependent equality row (see the .cpp).
  static constexpr double kDependentPivot = 1e-7;
  int nv_ = 0;
  int max_eq_ = 0;
  bool fast_path_ = true;
  bool dense_equality_ = false;
  bool primal_active_set_ = true;
  contact::DualQp qp_;
  // Woodbury path: W^-1 = diag(winv_), P = A W^-1 (6 x nv), K = I / w_b + P A^T (factorised, and
  // its inverse), Ft = (P C^T)^T (max_eq x 6), FtKinv = Ft K^-1; cols_[0, ncols_) are the columns
  // of C that are not zero.
  Eigen::VectorXd winv_;
  Eigen::Matrix<double, 6, Eigen::Dynamic> P_;
  Eigen::LLT<Matrix6> llt_k_;
  Matrix6 Kinv_ = Matrix6::Zero();
  Eigen::Matrix<double, Eigen::Dynamic, 6> Ft_, FtKinv_;
  std::vector<int> cols_;
  std::vector<int> row0_, rows_;  // per entry of cols_: its rows [row0, row0 + rows) of C
  int ncols_ = 0;
  Eigen::VectorXd y_, x_corr_, rg_, rd_, lambda_corr_;
  Eigen::MatrixXd L_;  // Cholesky factor of G (in place)
  Eigen::MatrixXd Y_;  // L^-1 C^T (nv x max_eq)
  Eigen::MatrixXd S_;  // Schur complement Y^T Y (max_eq x max_eq), factorised in place
  Eigen::VectorXd u_, lambda_;
  std::vector<int> perm_;        // factor_schur's pivot order
  Eigen::MatrixXd S_saved_;      // S as given (lower triangle), for the plain Cholesky
  Eigen::VectorXd schur_diag_;   // factor_schur's remaining diagonal
  Eigen::MatrixXd C_kept_;       // C's kept rows when some were dependent (for DualQp)
  Eigen::VectorXd d_kept_;
  Eigen::VectorXd schur_work_;
  Eigen::Index schur_m_ = 0, schur_rank_ = 0;
  Eigen::MatrixXd G_;  // formed only for the dense and active-set paths
  Eigen::VectorXd g_;
  // Primal active set: [C; active bound rows] and its right-hand side, the active joints and
  // their side (+1 upper, -1 lower, 0 inactive).
  Eigen::MatrixXd C_aug_;
  Eigen::VectorXd d_aug_;
  std::vector<int> active_;
  std::vector<int> side_;
  Eigen::MatrixXd A_in_;  // 2 (nv - 6) x nv: [I; -I] on the joint columns
  Eigen::VectorXd b_in_;
};

/// Joint-acceleration bounds that keep a joint inside [q_min, q_max] (paper Sec. 3.5, "the
/// upper bound decreases when a joint approaches its upper limit"): with a constant acceleration
/// over the horizon T, q + qd T + qdd T^2 / 2 stays inside the limits:
///   hi = 2 (q_max - q - qd T) / T^2,  lo = 2 (q_min - q - qd T) / T^2,
/// each clamped to [-a_max, a_max] (so lo <= hi always holds; a joint predicted beyond a limit gets
/// a bound of the sign that drives it back). Infinite limits give +-a_max. Allocation-free; dim n.
void joint_acceleration_bounds(const Eigen::Ref<const Eigen::VectorXd>& q,
                               const Eigen::Ref<const Eigen::VectorXd>& qd,
                               const Eigen::Ref<const Eigen::VectorXd>& q_min,
                               const Eigen::Ref<const Eigen::VectorXd>& q_max, double horizon,
                               double a_max, Eigen::Ref<Eigen::VectorXd> lo,
                               Eigen::Ref<Eigen::VectorXd> hi);

}  // namespace poise::controller
