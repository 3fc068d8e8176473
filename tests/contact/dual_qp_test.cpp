// Goldfarb-Idnani dual QP: KKT conditions on seeded random problems and agreement with
// brute-force enumeration of active sets.
#include "poise/contact/dual_qp.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/LU>

#include "random_problems.hpp"

namespace poise::contact {
namespace {

using test::random_matrix;
using test::uniform_int;

struct Qp {
  Eigen::MatrixXd G;
  Eigen::VectorXd g;
  Eigen::MatrixXd Ae;
  Eigen::VectorXd be;
  Eigen::MatrixXd Ai;
  Eigen::VectorXd bi;
};

double objective(const Qp& qp, const Eigen::VectorXd& x) {
  return 0.5 * x.dot(qp.G * x) + qp.g.dot(x);
}

// Optimum by enumeration: for every subset S of inequalities treated as equalities, solve the
// equality-constrained QP via its KKT system; keep primal-feasible points with u_S >= 0. For a
// strictly convex QP exactly one such point is the optimum; we return the best objective among
// primal-feasible candidates (the smallest feasible candidate is the optimum).
double brute_force_qp(const Qp& qp, bool* feasible) {
  const int n = static_cast<int>(qp.G.rows());
  const int me = static_cast<int>(qp.Ae.rows());
  const int mi = static_cast<int>(qp.Ai.rows());
  double best = std::numeric_limits<double>::infinity();
  *feasible = false;
  for (int mask = 0; mask < (1 << mi); ++mask) {
    const int k = me + __builtin_popcount(mask);
    if (k > n) continue;
    Eigen::MatrixXd C(k, n);
    Eigen::VectorXd c(k);
    C.topRows(me) = qp.Ae;
    c.head(me) = qp.be;
    int r = me;
    for (int i = 0; i < mi; ++i)
      if (mask & (1 << i)) {
        C.row(r) = qp.Ai.row(i);
        c[r++] = qp.bi[i];
      }
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n + k, n + k);
    K.topLeftCorner(n, n) = qp.G;
    K.topRightCorner(n, k) = C.transpose();
    K.bottomLeftCorner(k, n) = C;
    Eigen::VectorXd rhs(n + k);
    rhs << -qp.g, c;
    Eigen::FullPivLU<Eigen::MatrixXd> lu(K);
    if (lu.rank() < n + k) continue;
    const Eigen::VectorXd sol = lu.solve(rhs);
    const Eigen::VectorXd x = sol.head(n);
    if (me > 0 && (qp.Ae * x - qp.be).norm() > 1e-8) continue;
    if (mi > 0 && ((qp.Ai * x - qp.bi).array() < -1e-9).any()) continue;
    *feasible = true;
    best = std::min(best, objective(qp, x));
  }
  return best;
}

Qp random_qp(std::mt19937& rng, int n, int me, int mi) {
  Qp qp;
  const Eigen::MatrixXd M = random_matrix(rng, n + 2, n);
  qp.G = M.transpose() * M + 0.1 * Eigen::MatrixXd::Identity(n, n);
  qp.g = random_matrix(rng, n, 1, 2.0);
  qp.Ae = random_matrix(rng, me, n);
  qp.be = random_matrix(rng, me, 1);
  qp.Ai = random_matrix(rng, mi, n);
  qp.bi = random_matrix(rng, mi, 1);
  return qp;
}

TEST(DualQp, KktAndBruteForceOnRandomProblems) {
  std::mt19937 rng(31337);
  int solved = 0, infeasible = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int n = uniform_int(rng, 1, 6);
    const int me = uniform_int(rng, 0, std::min(2, n - 1));
    const int mi = uniform_int(rng, 0, 8);
    const Qp qp = random_qp(rng, n, me, mi);
    DualQp solver(6, 2, 8);
    Eigen::VectorXd x(n);
    const SolverStatus status = solver.solve(qp.G, qp.g, qp.Ae, qp.be, qp.Ai, qp.bi, x);
    bool feasible = false;
    const double f_brute = brute_force_qp(qp, &feasible);
    if (!feasible) {
      EXPECT_EQ(status, SolverStatus::kInfeasible) << "trial " << trial;
      ++infeasible;
      continue;
    }
    ASSERT_EQ(status, SolverStatus::kOptimal) << "trial " << trial;
    ++solved;
    const double scale = 1.0 + qp.G.norm() * x.norm() + qp.g.norm();
    // Stationarity, primal and dual feasibility, complementarity.
    const Eigen::VectorXd& lam = solver.multipliers_eq();
    const Eigen::VectorXd& u = solver.multipliers_in();
    Eigen::VectorXd grad = qp.G * x + qp.g;
    if (me > 0) grad -= qp.Ae.transpose() * lam.head(me);
    if (mi > 0) grad -= qp.Ai.transpose() * u.head(mi);
    EXPECT_LT(grad.norm(), 1e-8 * scale) << "trial " << trial;
    if (me > 0) {
      EXPECT_LT((qp.Ae * x - qp.be).norm(), 1e-8 * scale);
    }
    for (int i = 0; i < mi; ++i) {
      const double s = qp.Ai.row(i).dot(x) - qp.bi[i];
      EXPECT_GE(s, -1e-8 * scale) << "trial " << trial;
      EXPECT_GE(u[i], 0.0);
      EXPECT_LT(std::abs(u[i] * s), 1e-8 * scale * (1.0 + u[i]));
    }
    EXPECT_NEAR(solver.objective(), objective(qp, x), 1e-9 * scale);
    EXPECT_NEAR(objective(qp, x), f_brute, 1e-7 * (1.0 + std::abs(f_brute))) << "trial " << trial;
  }
  EXPECT_GT(solved, 250);  // the corpus really exercises the solver
  EXPECT_GT(infeasible, 0);
}

TEST(DualQp, BoxConstrainedProblemEqualsClampForIdentityHessian) {
  // min 0.5||x - c||^2 s.t. lo <= x <= hi has solution clamp(c, lo, hi): an independent check.
  std::mt19937 rng(4);
  for (int trial = 0; trial < 50; ++trial) {
    const int n = uniform_int(rng, 1, 6);
    const Eigen::VectorXd c = random_matrix(rng, n, 1, 2.0);
    Eigen::MatrixXd Ai(2 * n, n);
    Ai << Eigen::MatrixXd::Identity(n, n), -Eigen::MatrixXd::Identity(n, n);
    Eigen::VectorXd bi(2 * n);
    bi << Eigen::VectorXd::Constant(n, -1.0), Eigen::VectorXd::Constant(n, -1.0);
    DualQp solver(6, 0, 12);
    Eigen::VectorXd x(n);
    ASSERT_EQ(solver.solve(Eigen::MatrixXd::Identity(n, n), -c, Eigen::MatrixXd(0, n),
                           Eigen::VectorXd(0), Ai, bi, x),
              SolverStatus::kOptimal);
    EXPECT_LT((x - c.cwiseMax(-1.0).cwiseMin(1.0)).norm(), 1e-12);
  }
}

TEST(DualQp, FailureResults) {
  DualQp solver(3, 1, 2);
  Eigen::VectorXd x(3);
  const Eigen::MatrixXd none(0, 3);
  const Eigen::VectorXd empty(0);
  Eigen::MatrixXd G = Eigen::MatrixXd::Identity(3, 3);
  G(2, 2) = -1.0;
  EXPECT_EQ(solver.solve(G, Eigen::VectorXd::Zero(3), none, empty, none, empty, x),
            SolverStatus::kNotPositiveDefinite);
  G(2, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(solver.solve(G, Eigen::VectorXd::Zero(3), none, empty, none, empty, x),
            SolverStatus::kInvalidInput);
  // x0 >= 1 and -x0 >= 0: infeasible.
  Eigen::MatrixXd Ai(2, 3);
  Ai << 1, 0, 0, -1, 0, 0;
  Eigen::VectorXd bi(2);
  bi << 1, 0;
  EXPECT_EQ(solver.solve(Eigen::MatrixXd::Identity(3, 3), Eigen::VectorXd::Zero(3), none, empty, Ai,
                         bi, x),
            SolverStatus::kInfeasible);
  EXPECT_EQ(solver.solve(Eigen::MatrixXd::Identity(4, 4), Eigen::VectorXd::Zero(4),
                         Eigen::MatrixXd(0, 4), empty, Eigen::MatrixXd(0, 4), empty, x),
            SolverStatus::kInvalidInput);
}

}  // namespace
}  // namespace poise::contact
