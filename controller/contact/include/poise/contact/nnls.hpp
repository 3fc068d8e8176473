#pragma once

#include <Eigen/Core>

#include "poise/contact/least_squares_workspace.hpp"
#include "poise/contact/solver_status.hpp"

namespace poise::contact {

/// Non-negative least squares, min ||A x - b||_2 s.t. x >= 0, by the active-set method of
/// Lawson and Hanson ("Solving Least Squares Problems", 1974, ch. 23).
///
/// Usage: construct (or resize()) once with the largest sizes; solve() then never allocates
/// (checked with EIGEN_RUNTIME_NO_MALLOC in tests/contact). Not thread-safe: one object per thread.
///
/// Every iterate is feasible (x >= 0), so the output of a solve that hits the iteration cap is
/// still a feasible point, only not optimal.
class Nnls {
 public:
  Nnls() = default;
  /// Allocates workspace for problems up to max_rows x max_cols. Throws std::invalid_argument if a
  /// size is not positive.
  Nnls(int max_rows, int max_cols) { resize(max_rows, max_cols); }
  void resize(int max_rows, int max_cols);

  /// Cap on the number of least-squares sub-solves (inner iterations). Default 3 * max_cols + 10.
  void set_max_iterations(int n) { max_iterations_ = n; }
  /// Relative tolerance on the dual w = A^T (b - A x): stop when max w_j <= tol * ||A||_F * ||b||.
  void set_tolerance(double tol) { tolerance_ = tol; }

  /// Solves for x (size n). A: m x n with m <= max_rows, n <= max_cols; b: m.
  /// Failure results: kInvalidInput (sizes do not fit or a non-finite entry; x set to zero),
  /// kIterationLimit (x is the last feasible iterate). Never throws, never allocates.
  SolverStatus solve(const Eigen::Ref<const Eigen::MatrixXd>& A,
                     const Eigen::Ref<const Eigen::VectorXd>& b, Eigen::Ref<Eigen::VectorXd> x);

  /// The same problem given by its normal equations, for callers that form them cheaply from the
  /// structure of A: H = A^T A (n x n, n <= max_cols), c = A^T b, b_norm = ||b|| (used only for
  /// the stopping tolerance). Same algorithm, same iterates as solve() as long as every
  /// sub-problem is well-conditioned; when one is not (solve() would then use QR of the columns
  /// of A, which this form lacks) it stops with kNotPositiveDefinite and x the last feasible
  /// iterate: the caller must then call solve() with A. dual() is A^T b - H x.
  SolverStatus solve_normal(const Eigen::Ref<const Eigen::MatrixXd>& H,
                            const Eigen::Ref<const Eigen::VectorXd>& c, double b_norm,
                            Eigen::Ref<Eigen::VectorXd> x);

  /// Dual vector w = A^T (b - A x) of the last solve (first n entries valid). At the optimum
  /// w_j <= 0 where x_j = 0 and w_j = 0 where x_j > 0.
  const Eigen::VectorXd& dual() const { return ws_.w; }
  /// Inner iterations (least-squares sub-solves) used by the last solve.
  int iterations() const { return iterations_; }

 private:
  /// Lawson-Hanson on the normal equations loaded in ws_ (n variables). A and b (null in the
  /// normal-equation form) serve the QR fallback of ill-conditioned sub-problems.
  SolverStatus run(const Eigen::Ref<const Eigen::MatrixXd>* A, const double* b, int n, double tol,
                   Eigen::Ref<Eigen::VectorXd> x);
  int warm_start(int n, Eigen::Ref<Eigen::VectorXd> x, int& factored);
  int entering_variable(int n, double tol) const;
  SolverStatus add_variable(const Eigen::Ref<const Eigen::MatrixXd>* A, const double* b, int t,
                            int& k, int& factored, bool& x_changed, Eigen::Ref<Eigen::VectorXd> x);
  bool step_to_passive_solution(int k, Eigen::Ref<Eigen::VectorXd> x);

  int max_iterations_ = 0;
  double tolerance_ = 1e-12;
  int iterations_ = 0;
  detail::LeastSquaresWorkspace ws_;  // ws_.state: 1 if the variable is in the passive set
};

}  // namespace poise::contact
