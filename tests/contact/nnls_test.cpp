// Lawson-Hanson NNLS: KKT conditions on seeded random problems and agreement with brute-force
// enumeration of all active sets.
#include "poise/contact/nnls.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/QR>

#include "random_problems.hpp"

namespace poise::contact {
namespace {

using test::random_matrix;
using test::uniform_int;

// Minimum of ||A x - b||^2 over x >= 0 by trying every support set S: the optimum is the
// unconstrained least-squares solution on its own support, so the smallest objective among the
// non-negative candidates is the optimum.
double brute_force_nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const int n = static_cast<int>(A.cols());
  double best = b.squaredNorm();  // S = {}
  for (int mask = 1; mask < (1 << n); ++mask) {
    Eigen::MatrixXd As(A.rows(), __builtin_popcount(mask));
    int k = 0;
    for (int j = 0; j < n; ++j)
      if (mask & (1 << j)) As.col(k++) = A.col(j);
    const Eigen::VectorXd z = As.completeOrthogonalDecomposition().solve(b);
    if ((z.array() < -1e-12).any()) continue;
    best = std::min(best, (As * z - b).squaredNorm());
  }
  return best;
}

TEST(Nnls, KktAndBruteForceOnRandomProblems) {
  std::mt19937 rng(12345);
  for (int trial = 0; trial < 400; ++trial) {
    const int m = uniform_int(rng, 1, 10);
    const int n = uniform_int(rng, 1, 8);
    const Eigen::MatrixXd A = random_matrix(rng, m, n);
    const Eigen::VectorXd b = random_matrix(rng, m, 1, 3.0);
    Nnls solver(10, 8);
    Eigen::VectorXd x(n);
    ASSERT_EQ(solver.solve(A, b, x), SolverStatus::kOptimal) << "trial " << trial;

    const double scale = A.norm() * b.norm() + 1e-12;
    const Eigen::VectorXd w = A.transpose() * (b - A * x);
    for (int j = 0; j < n; ++j) {
      EXPECT_GE(x[j], 0.0);                                // primal feasibility
      EXPECT_LE(w[j], 1e-9 * scale) << "trial " << trial;  // dual feasibility
      if (x[j] > 0.0) {
        EXPECT_NEAR(w[j], 0.0, 1e-9 * scale);  // complementarity
      }
      EXPECT_NEAR(solver.dual()[j], w[j], 1e-9 * scale);
    }
    const double f = (A * x - b).squaredNorm();
    const double f_brute = brute_force_nnls(A, b);
    EXPECT_NEAR(f, f_brute, 1e-9 * (1.0 + b.squaredNorm())) << "trial " << trial;
  }
}

TEST(Nnls, MatchesUniqueSolutionForFullColumnRank) {
  // b = A x_true with x_true >= 0 and A of full column rank: the solution is x_true.
  std::mt19937 rng(7);
  for (int trial = 0; trial < 100; ++trial) {
    const int n = uniform_int(rng, 1, 8);
    const int m = n + uniform_int(rng, 0, 6);
    const Eigen::MatrixXd A = random_matrix(rng, m, n);
    Eigen::VectorXd x_true = random_matrix(rng, n, 1).cwiseAbs();
    for (int j = 0; j < n; ++j)
      if (uniform_int(rng, 0, 2) == 0) x_true[j] = 0.0;
    Nnls solver(m, n);
    Eigen::VectorXd x(n);
    ASSERT_EQ(solver.solve(A, A * x_true, x), SolverStatus::kOptimal);
    EXPECT_LT((x - x_true).norm(), 1e-9 * (1.0 + x_true.norm()));
  }
}

TEST(Nnls, IterationCapGivesStatusAndFeasiblePoint) {
  std::mt19937 rng(99);
  const Eigen::MatrixXd A = random_matrix(rng, 10, 8);
  Eigen::VectorXd x_signs(8);
  x_signs << 1, -1, 1, -1, 1, -1, 1, -1;  // the unconstrained solution is not feasible
  const Eigen::VectorXd b = A * x_signs;
  Nnls solver(10, 8);
  solver.set_max_iterations(1);
  Eigen::VectorXd x(8);
  EXPECT_EQ(solver.solve(A, b, x), SolverStatus::kIterationLimit);
  EXPECT_LE(solver.iterations(), 1);
  EXPECT_TRUE((x.array() >= 0.0).all());
  EXPECT_TRUE(x.allFinite());
}

TEST(Nnls, RejectsBadInput) {
  Nnls solver(4, 3);
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(4, 3);
  Eigen::VectorXd b = Eigen::VectorXd::Ones(4);
  Eigen::VectorXd x(3);
  Eigen::VectorXd x_wrong(2);
  EXPECT_EQ(solver.solve(A, b, x_wrong), SolverStatus::kInvalidInput);
  EXPECT_EQ(solver.solve(Eigen::MatrixXd::Identity(5, 3), Eigen::VectorXd::Ones(5), x),
            SolverStatus::kInvalidInput);  // more rows than configured
  A(1, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(solver.solve(A, b, x), SolverStatus::kInvalidInput);
  EXPECT_TRUE(x.isZero());
  EXPECT_THROW(Nnls(0, 3), std::invalid_argument);
}

TEST(Nnls, NormalEquationFormMatchesDenseForm) {
  // solve_normal(A^T A, A^T b, |b|) follows the same iterates as solve(A, b) when every sub-problem
  // is well-conditioned (A of full column rank): same x, and the dual is A^T (b - A x).
  std::mt19937 rng(31);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = uniform_int(rng, 1, 8);
    const int m = n + uniform_int(rng, 0, 6);
    const Eigen::MatrixXd A = random_matrix(rng, m, n);
    const Eigen::VectorXd b = random_matrix(rng, m, 1, 2.0);
    Nnls dense(m, n), normal(m, n);
    Eigen::VectorXd x_dense(n), x_normal(n);
    ASSERT_EQ(dense.solve(A, b, x_dense), SolverStatus::kOptimal) << "trial " << trial;
    const Eigen::MatrixXd H = A.transpose() * A;
    const Eigen::VectorXd c = A.transpose() * b;
    ASSERT_EQ(normal.solve_normal(H, c, b.norm(), x_normal), SolverStatus::kOptimal)
        << "trial " << trial;
    EXPECT_LT((x_normal - x_dense).norm(), 1e-8 * (1.0 + x_dense.norm())) << "trial " << trial;
    const Eigen::VectorXd w = A.transpose() * (b - A * x_normal);
    EXPECT_LT((normal.dual().head(n) - w).norm(), 1e-8 * (1.0 + A.norm() * b.norm()))
        << "trial " << trial;
  }
}

TEST(Nnls, NormalEquationFormReportsIllConditioningAndBadInput) {
  Nnls solver(6, 4);
  Eigen::VectorXd x(4);
  // H = 0 with a positive c: every sub-problem is singular; without A there is no QR fallback.
  EXPECT_EQ(solver.solve_normal(Eigen::MatrixXd::Zero(4, 4), Eigen::VectorXd::Ones(4), 1.0, x),
            SolverStatus::kNotPositiveDefinite);
  EXPECT_TRUE((x.array() >= 0.0).all() && x.allFinite());
  // A rank-deficient H (A of 2 rows, 4 columns): either solved, or reported; x always feasible,
  // and when solved its objective is the dense solver's.
  std::mt19937 rng(77);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::MatrixXd A = random_matrix(rng, 2, 4);
    const Eigen::VectorXd b = random_matrix(rng, 2, 1);
    const SolverStatus s = solver.solve_normal(A.transpose() * A, A.transpose() * b, b.norm(), x);
    ASSERT_TRUE(s == SolverStatus::kOptimal || s == SolverStatus::kNotPositiveDefinite);
    EXPECT_TRUE((x.array() >= 0.0).all() && x.allFinite());
    if (s == SolverStatus::kOptimal) {
      Eigen::VectorXd x_dense(4);
      ASSERT_EQ(solver.solve(A, b, x_dense), SolverStatus::kOptimal);
      EXPECT_NEAR((A * x - b).squaredNorm(), (A * x_dense - b).squaredNorm(), 1e-9);
    }
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Identity(4, 4);
  H(2, 2) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(solver.solve_normal(H, Eigen::VectorXd::Ones(4), 1.0, x), SolverStatus::kInvalidInput);
  EXPECT_EQ(solver.solve_normal(Eigen::MatrixXd::Identity(5, 5), Eigen::VectorXd::Ones(5), 1.0, x),
            SolverStatus::kInvalidInput);  // more columns than configured / x of the wrong size
  EXPECT_TRUE(x.isZero());
}

}  // namespace
}  // namespace poise::contact
