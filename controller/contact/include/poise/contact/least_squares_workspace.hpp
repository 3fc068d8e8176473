#pragma once

// Storage shared by the active-set least-squares solvers (Nnls, Bvls). Their common steps (input
// checks, normal equations, subset solves, the dual of the answer) live in
// src/active_set_common.hpp and work on this workspace.

#include <Eigen/Core>

namespace poise::contact::detail {

/// Preallocated workspace of one active-set least-squares solver. resize() allocates; nothing
/// else does.
struct LeastSquaresWorkspace {
  /// Allocates for problems up to max_rows x max_cols. Throws std::invalid_argument naming
  /// `solver` when a size is not positive.
  void resize(const char* solver, int max_rows, int max_cols);

  int max_rows = 0;
  int max_cols = 0;
  Eigen::MatrixXd W;         // max_rows x max_cols, QR workspace (fallback for ill-conditioning)
  Eigen::VectorXd r;         // max_rows, residual / QR right-hand side
  Eigen::VectorXd qr_rhs;    // max_rows, QR workspace
  Eigen::VectorXd diag;      // max_cols, QR workspace
  Eigen::VectorXd w;         // max_cols, dual A^T (b - A x)
  Eigen::VectorXd z;         // max_cols, sub-problem solution
  Eigen::VectorXi cols;      // max_cols, column list of the sub-problem
  Eigen::VectorXi state;     // max_cols, per-variable state (solver-specific)
  Eigen::VectorXi rejected;  // max_cols, 1 while an entering variable is rejected
  Eigen::MatrixXd AtA;       // max_cols x max_cols, normal matrix
  Eigen::VectorXd Atb;       // max_cols
  Eigen::MatrixXd L;         // max_cols x max_cols, Cholesky factor of a subset
  Eigen::VectorXd pivot;     // max_cols, squared pivots of L
  Eigen::VectorXd rhs;       // max_cols, sub-problem right-hand side
  Eigen::VectorXd xb;        // max_cols, x with the free variables zeroed (Bvls)
};

}  // namespace poise::contact::detail
