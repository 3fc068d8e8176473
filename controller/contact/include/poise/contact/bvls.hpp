#pragma once

#include <Eigen/Core>

#include "poise/contact/least_squares_workspace.hpp"
#include "poise/contact/solver_status.hpp"

namespace poise::contact {

/// Bounded-variable least squares, min ||A x - b||_2 s.t. lower <= x <= upper, by the active-set
/// method of Stark and Parker ("Bounded-Variable Least-Squares: an Algorithm and Applications",
/// Computational Statistics 10, 1995). Bounds must be finite with lower <= upper; lower == upper
/// fixes a variable.
///
/// Usage: construct (or resize()) once with the largest sizes; solve() then never allocates.
/// Every iterate is feasible, so the output of a solve that hits the iteration cap still satisfies
/// the bounds. Not thread-safe: one object per thread.
class Bvls {
 public:
  Bvls() = default;
  /// Allocates workspace for problems up to max_rows x max_cols. Throws std::invalid_argument if a
  /// size is not positive.
  Bvls(int max_rows, int max_cols) { resize(max_rows, max_cols); }
  void resize(int max_rows, int max_cols);

  /// Cap on the number of least-squares sub-solves. Default 3 * max_cols + 10.
  void set_max_iterations(int n) { max_iterations_ = n; }
  /// Relative tolerance on the dual (see Nnls::set_tolerance).
  void set_tolerance(double tol) { tolerance_ = tol; }

  /// Solves for x (size n). A: m x n (m <= max_rows, n <= max_cols); b: m; lower, upper: n.
  /// Failure results: kInvalidInput (sizes, non-finite entries, lower > upper; x set to the
  /// clamp of 0 into the bounds when they are finite and ordered, else to 0), kIterationLimit (x is
  /// the last feasible iterate). Never throws, never allocates.
  SolverStatus solve(const Eigen::Ref<const Eigen::MatrixXd>& A,
                     const Eigen::Ref<const Eigen::VectorXd>& b,
                     const Eigen::Ref<const Eigen::VectorXd>& lower,
                     const Eigen::Ref<const Eigen::VectorXd>& upper, Eigen::Ref<Eigen::VectorXd> x);

  /// The same problem given by its normal equations (see Nnls::solve_normal): H = A^T A,
  /// c = A^T b, b_norm = ||b|| (stopping tolerance only). kNotPositiveDefinite when a sub-problem
  /// is too ill-conditioned for the normal equations (x: the last feasible iterate): the caller
  /// must then call solve() with A.
  SolverStatus solve_normal(const Eigen::Ref<const Eigen::MatrixXd>& H,
                            const Eigen::Ref<const Eigen::VectorXd>& c, double b_norm,
                            const Eigen::Ref<const Eigen::VectorXd>& lower,
                            const Eigen::Ref<const Eigen::VectorXd>& upper,
                            Eigen::Ref<Eigen::VectorXd> x);

  /// Dual w = A^T (b - A x) of the last solve. At the optimum: w_j <= 0 at a lower bound,
  /// w_j >= 0 at an upper bound, w_j = 0 for a free variable.
  const Eigen::VectorXd& dual() const { return ws_.w; }
  int iterations() const { return iterations_; }

 private:
  enum : int { kFree = 0, kAtLower = 1, kAtUpper = 2 };
  /// Checks the bounds (finite, lower <= upper, size n) and sets x to the clamp of 0 into them
  /// (x = 0 when they are bad). Returns false on bad bounds.
  static bool check_bounds(int n, const Eigen::Ref<const Eigen::VectorXd>& lower,
                           const Eigen::Ref<const Eigen::VectorXd>& upper,
                           Eigen::Ref<Eigen::VectorXd> x);
  /// Stark-Parker on the normal equations loaded in ws_; A and b (null in the normal-equation
  /// form) serve the QR fallback of ill-conditioned sub-problems.
  SolverStatus run(const Eigen::Ref<const Eigen::MatrixXd>* A, const double* b, int n,
                   double norm_a, double b_norm, const Eigen::Ref<const Eigen::VectorXd>& lower,
                   const Eigen::Ref<const Eigen::VectorXd>& upper, Eigen::Ref<Eigen::VectorXd> x);
  struct Problem;
  void free_rhs(const Problem& p);
  void cold_start(Problem& p);
  void warm_start(Problem& p);
  bool clamp_to_bounds(Problem& p);
  int entering_variable(const Problem& p, double tol) const;
  bool solve_free_set(Problem& p);
  SolverStatus free_variable(Problem& p, int t, bool& x_changed);
  bool step_to_free_solution(Problem& p);

  int max_iterations_ = 0;
  double tolerance_ = 1e-12;
  int iterations_ = 0;
  detail::LeastSquaresWorkspace ws_;  // ws_.state: kFree / kAtLower / kAtUpper
};

}  // namespace poise::contact
