// Stark-Parker BVLS: KKT conditions on seeded random problems and agreement with brute-force
// enumeration of all (lower, upper, free) assignments.
#include "poise/contact/bvls.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/QR>

#include "random_problems.hpp"

namespace poise::contact {
namespace {

using test::random_matrix;
using test::uniform;
using test::uniform_int;

double brute_force_bvls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                        const Eigen::VectorXd& lo, const Eigen::VectorXd& hi) {
  const int n = static_cast<int>(A.cols());
  int combos = 1;
  for (int j = 0; j < n; ++j)
    combos *= 3;
  double best = std::numeric_limits<double>::infinity();
  for (int code = 0; code < combos; ++code) {
    Eigen::VectorXd x(n);
    int c = code;
    int k = 0;
    Eigen::VectorXi free(n);
    for (int j = 0; j < n; ++j, c /= 3) {
      if (c % 3 == 0) x[j] = lo[j];
      if (c % 3 == 1) x[j] = hi[j];
      if (c % 3 == 2) free[k++] = j;
    }
    if (k > 0) {
      Eigen::MatrixXd Af(A.rows(), k);
      Eigen::VectorXd rhs = b;
      for (int j = 0; j < n; ++j) {
        bool is_free = false;
        for (int i = 0; i < k; ++i)
          is_free |= free[i] == j;
        if (!is_free) rhs -= A.col(j) * x[j];
      }
      for (int i = 0; i < k; ++i)
        Af.col(i) = A.col(free[i]);
      const Eigen::VectorXd z = Af.completeOrthogonalDecomposition().solve(rhs);
      bool ok = true;
      for (int i = 0; i < k; ++i) {
        ok &= z[i] >= lo[free[i]] - 1e-12 && z[i] <= hi[free[i]] + 1e-12;
        x[free[i]] = z[i];
      }
      if (!ok) continue;
    }
    best = std::min(best, (A * x - b).squaredNorm());
  }
  return best;
}

TEST(Bvls, KktAndBruteForceOnRandomProblems) {
  std::mt19937 rng(2024);
  for (int trial = 0; trial < 400; ++trial) {
    const int m = uniform_int(rng, 1, 9);
    const int n = uniform_int(rng, 1, 6);
    const Eigen::MatrixXd A = random_matrix(rng, m, n);
    const Eigen::VectorXd b = random_matrix(rng, m, 1, 3.0);
    Eigen::VectorXd lo(n), hi(n);
    for (int j = 0; j < n; ++j) {
      lo[j] = uniform(rng, -1.5, 0.5);
      hi[j] = lo[j] + (uniform_int(rng, 0, 9) == 0 ? 0.0 : uniform(rng, 0.0, 2.0));
    }
    Bvls solver(9, 6);
    Eigen::VectorXd x(n);
    ASSERT_EQ(solver.solve(A, b, lo, hi, x), SolverStatus::kOptimal) << "trial " << trial;
    const double scale =
        A.norm() * (b.norm() + A.norm() * hi.cwiseAbs().cwiseMax(lo.cwiseAbs()).norm());
    const Eigen::VectorXd w = A.transpose() * (b - A * x);
    for (int j = 0; j < n; ++j) {
      EXPECT_GE(x[j], lo[j]);
      EXPECT_LE(x[j], hi[j]);
      if (lo[j] == hi[j]) continue;
      if (x[j] == lo[j]) {
        EXPECT_LE(w[j], 1e-9 * scale) << "trial " << trial;
      } else if (x[j] == hi[j]) {
        EXPECT_GE(w[j], -1e-9 * scale) << "trial " << trial;
      } else {
        EXPECT_NEAR(w[j], 0.0, 1e-9 * scale) << "trial " << trial;
      }
    }
    EXPECT_NEAR((A * x - b).squaredNorm(), brute_force_bvls(A, b, lo, hi),
                1e-9 * (1.0 + b.squaredNorm()))
        << "trial " << trial;
  }
}

TEST(Bvls, InteriorSolutionIsUnconstrainedLeastSquares) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    const int n = uniform_int(rng, 1, 6);
    const int m = n + uniform_int(rng, 0, 3);
    const Eigen::MatrixXd A = random_matrix(rng, m, n);
    const Eigen::VectorXd b = random_matrix(rng, m, 1);
    const Eigen::VectorXd x_ls = A.colPivHouseholderQr().solve(b);
    const Eigen::VectorXd lo = x_ls.array() - 1.0, hi = x_ls.array() + 1.0;
    Bvls solver(m, n);
    Eigen::VectorXd x(n);
    ASSERT_EQ(solver.solve(A, b, lo, hi, x), SolverStatus::kOptimal);
    EXPECT_LT((x - x_ls).norm(), 1e-9 * (1.0 + x_ls.norm()));
  }
}

TEST(Bvls, IterationCapAndBadInput) {
  std::mt19937 rng(11);
  const Eigen::MatrixXd A = random_matrix(rng, 6, 6);
  Eigen::VectorXd x_out(6);
  x_out << 2, -1, 0.5, 3, -2, 0.5;  // several variables must end on a bound
  const Eigen::VectorXd b = A * x_out;
  const Eigen::VectorXd lo = Eigen::VectorXd::Zero(6), hi = Eigen::VectorXd::Ones(6);
  Bvls solver(6, 6);
  solver.set_max_iterations(1);
  Eigen::VectorXd x(6);
  EXPECT_EQ(solver.solve(A, b, lo, hi, x), SolverStatus::kIterationLimit);
  EXPECT_TRUE((x.array() >= lo.array()).all() && (x.array() <= hi.array()).all());

  Bvls fresh(6, 6);
  EXPECT_EQ(fresh.solve(A, b, hi, lo, x), SolverStatus::kInvalidInput);  // lower > upper
  Eigen::VectorXd inf_hi = hi;
  inf_hi[2] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(fresh.solve(A, b, lo, inf_hi, x), SolverStatus::kInvalidInput);
  Eigen::VectorXd nan_b = b;
  nan_b[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(fresh.solve(A, nan_b, lo, hi, x), SolverStatus::kInvalidInput);
  EXPECT_TRUE(x.allFinite());
}

TEST(Bvls, NormalEquationFormMatchesDenseForm) {
  std::mt19937 rng(43);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = uniform_int(rng, 1, 6);
    const int m = n + uniform_int(rng, 0, 3);
    const Eigen::MatrixXd A = random_matrix(rng, m, n);
    const Eigen::VectorXd b = random_matrix(rng, m, 1, 3.0);
    Eigen::VectorXd lo(n), hi(n);
    for (int j = 0; j < n; ++j) {
      lo[j] = uniform(rng, -1.5, 0.5);
      hi[j] = lo[j] + (uniform_int(rng, 0, 9) == 0 ? 0.0 : uniform(rng, 0.0, 2.0));
    }
    Bvls dense(9, 6), normal(9, 6);
    Eigen::VectorXd x_dense(n), x_normal(n);
    ASSERT_EQ(dense.solve(A, b, lo, hi, x_dense), SolverStatus::kOptimal) << "trial " << trial;
    ASSERT_EQ(normal.solve_normal(A.transpose() * A, A.transpose() * b, b.norm(), lo, hi, x_normal),
              SolverStatus::kOptimal)
        << "trial " << trial;
    EXPECT_LT((x_normal - x_dense).norm(), 1e-8 * (1.0 + x_dense.norm())) << "trial " << trial;
    const Eigen::VectorXd w = A.transpose() * (b - A * x_normal);
    EXPECT_LT((normal.dual().head(n) - w).norm(), 1e-8 * (1.0 + A.norm() * b.norm()))
        << "trial " << trial;
  }
}

TEST(Bvls, NormalEquationFormReportsIllConditioningAndBadInput) {
  Bvls solver(6, 3);
  Eigen::VectorXd x(3);
  const Eigen::VectorXd lo = -Eigen::VectorXd::Ones(3), hi = Eigen::VectorXd::Ones(3);
  EXPECT_EQ(
      solver.solve_normal(Eigen::MatrixXd::Zero(3, 3), Eigen::VectorXd::Ones(3), 1.0, lo, hi, x),
      SolverStatus::kNotPositiveDefinite);
  EXPECT_TRUE((x.array() >= lo.array()).all() && (x.array() <= hi.array()).all());
  Eigen::MatrixXd H = Eigen::MatrixXd::Identity(3, 3);
  H(0, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(solver.solve_normal(H, Eigen::VectorXd::Ones(3), 1.0, lo, hi, x),
            SolverStatus::kInvalidInput);
  EXPECT_EQ(solver.solve_normal(Eigen::MatrixXd::Identity(3, 3), Eigen::VectorXd::Ones(3), 1.0, hi,
                                lo, x),
            SolverStatus::kInvalidInput);  // lower > upper
  EXPECT_TRUE(x.allFinite());
}

}  // namespace
}  // namespace poise::contact
