// Eq (33) solver: feasibility, bounds and KKT conditions on seeded random problems, and the
// bound-free case against a direct solve of the KKT system (Eigen full-pivot LU).
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cstdio>
#include <random>

#include "controller_test_util.hpp"
#include "poise/contact/sequential_optimizer.hpp"
#include "poise/controller/acceleration_solver.hpp"
#include "poise/controller/balance_controller.hpp"

namespace poise::controller {
namespace {

struct RandomEq33 {
  int nv, m;
  Eigen::MatrixXd A, C;
  Eigen::VectorXd b, w, t, d, lo, hi;
  double w_b;
};

RandomEq33 make_problem(std::mt19937& rng, int nv, int m, double bound) {
  std::normal_distribution<double> N(0.0, 1.0);
  RandomEq33 p;
  p.nv = nv;
  p.m = m;
  p.A = Eigen::MatrixXd::NullaryExpr(6, nv, [&] { return 10.0 * N(rng); });
  p.C = Eigen::MatrixXd::NullaryExpr(m, nv, [&] { return N(rng); });
  p.b = Eigen::VectorXd::NullaryExpr(6, [&] { return 100.0 * N(rng); });
  p.d = Eigen::VectorXd::NullaryExpr(m, [&] { return N(rng); });
  p.w = Eigen::VectorXd::NullaryExpr(nv, [&] { return test::uniform(rng, 1e-3, 0.1); });
  p.t = Eigen::VectorXd::NullaryExpr(nv, [&] { return 5.0 * N(rng); });
  p.lo =
      Eigen::VectorXd::NullaryExpr(nv - 6, [&] { return -test::uniform(rng, 0.2, 1.0) * bound; });
  p.hi = Eigen::VectorXd::NullaryExpr(nv - 6, [&] { return test::uniform(rng, 0.2, 1.0) * bound; });
  p.w_b = test::uniform(rng, 0.8, 0.99);
  return p;
}

TEST(AccelerationSolver, KktConditionsHoldOnRandomProblems) {
  std::mt19937 rng(33);
  int with_active = 0, used_fast = 0, primal_active_set = 0, dual_qp = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int nv = 6 + 8 + trial % 12;
    const int m = trial % 13;
    const RandomEq33 p = make_problem(rng, nv, m, trial % 2 ? 5.0 : 1e3);
    AccelerationSolver s(nv, 12);
    Eigen::VectorXd x(nv);
    const auto r = s.solve(p.A, p.b, p.w_b, p.w, p.t, p.C, p.d, p.lo, p.hi, x);
    ASSERT_EQ(r.status, contact::SolverStatus::kOptimal) << trial;
    if (r.bounds_dropped) continue;  // checked in its own test
    // The fast equality-only path and the active-set path agree.
    AccelerationSolver slow(nv, 12);
    slow.set_fast_path(false);
    Eigen::VectorXd x2(nv);
    ASSERT_EQ(slow.solve(p.A, p.b, p.w_b, p.w, p.t, p.C, p.d, p.lo, p.hi, x2).status,
              contact::SolverStatus::kOptimal);
    EXPECT_LT((x - x2).norm(), 1e-7 * (1.0 + x.norm())) << trial;
    used_fast += r.used_active_set ? 0 : 1;
    primal_active_set += r.used_active_set && !r.used_dual_qp;
    dual_qp += r.used_dual_qp;
    // Equalities and bounds.
    if (m > 0) {
      EXPECT_LT((p.C * x - p.d).lpNorm<Eigen::Infinity>(), 1e-8) << trial;
    }
    EXPECT_TRUE((x.tail(nv - 6).array() >= p.lo.array() - 1e-8).all()) << trial;
    EXPECT_TRUE((x.tail(nv - 6).array() <= p.hi.array() + 1e-8).all()) << trial;
    // Gradient of the objective as written in (33), from the problem data only:
    // grad = 2 w_b A^T (A x - b) + 2 w .* (x - t) = C^T lambda + [0; mu_lo - mu_hi].
    const Eigen::VectorXd grad =
        2.0 * p.w_b * p.A.transpose() * (p.A * x - p.b) + 2.0 * p.w.cwiseProduct(x - p.t);
    // Bound multipliers: active where x sits on a bound.
    Eigen::MatrixXd K(nv, m + nv - 6);
    K.leftCols(m) = p.C.transpose();
    K.rightCols(nv - 6).setZero();
    std::vector<int> sign(nv - 6, 0);
    for (int j = 0; j < nv - 6; ++j) {
      if (std::abs(x[6 + j] - p.lo[j]) < 1e-8) sign[j] = 1;
      if (std::abs(x[6 + j] - p.hi[j]) < 1e-8) sign[j] = -1;
      if (sign[j]) K(6 + j, m + j) = sign[j];
      with_active += sign[j] != 0;
    }
    // Solve grad = K y in least squares; the residual must vanish and bound multipliers >= 0.
    const Eigen::VectorXd y = K.completeOrthogonalDecomposition().solve(grad);
    EXPECT_LT((K * y - grad).norm(), 1e-6 * (1.0 + grad.norm())) << trial;
    for (int j = 0; j < nv - 6; ++j)
      if (sign[j]) {
        EXPECT_GE(y[m + j], -1e-6 * (1.0 + grad.norm())) << trial << " bound " << j;
      }
  }
  std::printf("200 problems: %d equality-only, %d primal active set, %d DualQp; %d active bounds\n",
              used_fast, primal_active_set, dual_qp, with_active);
  EXPECT_GT(with_active, 50);        // the bounds were really exercised
  EXPECT_GT(used_fast, 50);          // and so was the fast path
  EXPECT_GT(primal_active_set, 50);  // and the primal active set (compared with DualQp above)
}

TEST(AccelerationSolver, WithoutActiveBoundsEqualsDirectKktSolve) {
  std::mt19937 rng(34);
  for (int trial = 0; trial < 50; ++trial) {
    const int nv = 25, m = 12;
    const RandomEq33 p = make_problem(rng, nv, m, 1e9);
    AccelerationSolver s(nv, m);
    Eigen::VectorXd x(nv);
    ASSERT_EQ(s.solve(p.A, p.b, p.w_b, p.w, p.t, p.C, p.d, p.lo, p.hi, x).status,
              contact::SolverStatus::kOptimal);
    Eigen::MatrixXd KKT = Eigen::MatrixXd::Zero(nv + m, nv + m);
    KKT.topLeftCorner(nv, nv) = p.w_b * p.A.transpose() * p.A;
    KKT.topLeftCorner(nv, nv).diagonal() += p.w;
    KKT.topRightCorner(nv, m) = p.C.transpose();
    KKT.bottomLeftCorner(m, nv) = p.C;
    Eigen::VectorXd rhs(nv + m);
    rhs << p.w_b * p.A.transpose() * p.b + p.w.cwiseProduct(p.t), p.d;
    const Eigen::VectorXd sol = KKT.fullPivLu().solve(rhs);
    EXPECT_LT((sol.head(nv) - x).norm(), 1e-7 * (1.0 + x.norm())) << trial;
  }
}

// The controller's own data (project humanoid, CMM, foot Jacobians, posture weight 1e-3 next to
// w_b |A|^2 ~ 1e3: G has a condition number ~1e7): the Woodbury path, the dense-Cholesky path and a
// full-pivot LU solve of the KKT system agree, and the constraints hold.
TEST(AccelerationSolver, WoodburyEqualsDenseAndKktOnHumanoidTicks) {
  BalanceController c(test::humanoid().model, test::humanoid().robot, ControllerConfig{});
  const int nv = c.model().nv;
  std::mt19937 rng(36);
  contact::ContactProblem problem;
  int compared = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const RobotState st = test::random_state(c, rng, 0.15, 1.0);
    c.prepare(st, c.make_reference(), problem);
    contact::ContactSolution sol;
    contact::SequentialOptimizer().solve(problem, sol);
    JointCommand cmd = c.make_command();
    c.finish(sol, cmd);
    const double w_b = c.config().acceleration.w_b;
    const Eigen::MatrixXd A = c.centroidal_matrix();
    const Eigen::VectorXd b = c.diagnostics().hdot_admissible - c.centroidal_bias();
    const Eigen::MatrixXd& C = c.foot_jacobians();
    Eigen::VectorXd d = -c.foot_bias_acceleration();
    for (int i = 0; i < 2; ++i)
      d.segment<6>(6 * i) += c.diagnostics().foot_acceleration_desired[i];
    const Eigen::VectorXd& w = c.qp_weights();
    const Eigen::VectorXd& t = c.qp_targets();
    const Eigen::VectorXd lo = Eigen::VectorXd::Constant(nv - 6, -1e9), hi = -lo;
    AccelerationSolver fast(nv, 12), dense(nv, 12);
    dense.set_dense_equality_path(true);
    Eigen::VectorXd x(nv), x_dense(nv);
    ASSERT_EQ(fast.solve(A, b, w_b, w, t, C, d, lo, hi, x).status, contact::SolverStatus::kOptimal);
    ASSERT_EQ(dense.solve(A, b, w_b, w, t, C, d, lo, hi, x_dense).status,
              contact::SolverStatus::kOptimal);
    Eigen::MatrixXd KKT = Eigen::MatrixXd::Zero(nv + 12, nv + 12);
    KKT.topLeftCorner(nv, nv) = w_b * A.transpose() * A;
    KKT.topLeftCorner(nv, nv).diagonal() += w;
    KKT.topRightCorner(nv, 12) = C.transpose();
    KKT.bottomLeftCorner(12, nv) = C;
    Eigen::VectorXd rhs(nv + 12);
    rhs << w_b * A.transpose() * b + w.cwiseProduct(t), d;
    const Eigen::VectorXd ref = KKT.fullPivLu().solve(rhs).head(nv);
    const double scale = 1.0 + ref.norm();
    EXPECT_LT((x - ref).norm(), 1e-8 * scale) << trial;
    EXPECT_LT((x_dense - ref).norm(), 1e-8 * scale) << trial;
    EXPECT_LT((C * x - d).lpNorm<Eigen::Infinity>(), 1e-9 * (1.0 + d.norm())) << trial;
    ++compared;
  }
  EXPECT_EQ(compared, 40);
}

// Dependent equality rows (the feet of legs with five joints: twelve rows of rank eleven; a bound
// on a joint the feet fix): with a consistent right-hand side the solution is that of the problem
// without the dependent rows, which a full-pivot LU of the reduced KKT system gives independently.
// A plain Cholesky of the Schur complement takes a round-off pivot there and returns noise.
TEST(AccelerationSolver, DependentEqualityRowsGiveTheReducedProblemsSolution) {
  std::mt19937 rng(37);
  std::normal_distribution<double> N(0.0, 1.0);
  int checked = 0, fast = 0, with_bounds = 0;
  for (int trial = 0; trial < 120; ++trial) {
    const int nv = 25, independent = 9 + trial % 4, dependent = 1 + trial % 3;
    const int m = independent + dependent;
    // Bounds far away in half the trials (the equality path), tight in the others.
    RandomEq33 p = make_problem(rng, nv, independent, trial % 2 ? 1e9 : 20.0);
    // Rows of C0 scaled like foot Jacobians (metres and radians mixed).
    const Eigen::MatrixXd C0 = p.C;
    const Eigen::VectorXd d0 = p.d;
    Eigen::MatrixXd C(m, nv);
    Eigen::VectorXd d(m);
    // The dependent rows are combinations of the others, put at random places among them.
    std::vector<int> order(static_cast<std::size_t>(m));
    for (int i = 0; i < m; ++i) order[static_cast<std::size_t>(i)] = i;
    std::shuffle(order.begin(), order.end(), rng);
    for (int i = 0; i < independent; ++i) {
      C.row(order[static_cast<std::size_t>(i)]) = C0.row(i);
      d[order[static_cast<std::size_t>(i)]] = d0[i];
    }
    for (int k = 0; k < dependent; ++k) {
      const Eigen::VectorXd a = Eigen::VectorXd::NullaryExpr(independent, [&] { return N(rng); });
      C.row(order[static_cast<std::size_t>(independent + k)]) = a.transpose() * C0;
      d[order[static_cast<std::size_t>(independent + k)]] = a.dot(d0);
    }
    for (const bool dense : {false, true}) {
      AccelerationSolver s(nv, 16);
      s.set_dense_equality_path(dense);
      Eigen::VectorXd x(nv);
      const auto r = s.solve(p.A, p.b, p.w_b, p.w, p.t, C, d, p.lo, p.hi, x);
      ASSERT_EQ(r.status, contact::SolverStatus::kOptimal) << trial << (dense ? " dense" : "");
      EXPECT_LT((C * x - d).lpNorm<Eigen::Infinity>(), 1e-8 * (1.0 + d.norm())) << trial;
      // Reference: the reduced problem (C0 only), independently.
      Eigen::VectorXd ref(nv);
      if (r.active_bounds == 0 && !r.used_dual_qp) {
        EXPECT_EQ(r.dependent_rows, dependent) << trial << (dense ? " dense" : "");
        Eigen::MatrixXd KKT = Eigen::MatrixXd::Zero(nv + independent, nv + independent);
        KKT.topLeftCorner(nv, nv) = p.w_b * p.A.transpose() * p.A;
        KKT.topLeftCorner(nv, nv).diagonal() += p.w;
        KKT.topRightCorner(nv, independent) = C0.transpose();
        KKT.bottomLeftCorner(independent, nv) = C0;
        Eigen::VectorXd rhs(nv + independent);
        rhs << p.w_b * p.A.transpose() * p.b + p.w.cwiseProduct(p.t), d0;
        ref = KKT.fullPivLu().solve(rhs).head(nv);
        fast += 1;
      } else {
        AccelerationSolver reduced(nv, 16);
        reduced.set_fast_path(false);  // DualQp on the independent rows
        ASSERT_EQ(reduced.solve(p.A, p.b, p.w_b, p.w, p.t, C0, d0, p.lo, p.hi, ref).status,
                  contact::SolverStatus::kOptimal);
        with_bounds += 1;
      }
      EXPECT_LT((x - ref).norm(), 1e-7 * (1.0 + ref.norm())) << trial << (dense ? " dense" : "");
      ++checked;
    }
  }
  std::printf("%d solves with dependent rows: %d equality-only, %d with active bounds\n", checked,
              fast, with_bounds);
  EXPECT_GT(fast, 80);
  EXPECT_GT(with_bounds, 40);
}

TEST(AccelerationSolver, InfeasibleBoundsAreDroppedNotViolatedSilently) {
  // x[6] is forced to 10 by an equality, but bounded by +-1: infeasible with bounds.
  std::mt19937 rng(35);
  RandomEq33 p = make_problem(rng, 10, 1, 1.0);
  p.C.setZero();
  p.C(0, 6) = 1.0;
  p.d[0] = 10.0;
  AccelerationSolver s(10, 2);
  Eigen::VectorXd x(10);
  const auto r = s.solve(p.A, p.b, p.w_b, p.w, p.t, p.C, p.d, p.lo, p.hi, x);
  EXPECT_TRUE(r.bounds_dropped);
  EXPECT_EQ(r.status, contact::SolverStatus::kOptimal);
  EXPECT_NEAR(x[6], 10.0, 1e-9);
}

TEST(AccelerationSolver, BadInputIsRejectedWithZeroOutput) {
  AccelerationSolver s(10, 2);
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(6, 10), C(1, 10);
  C.setOnes();
  Eigen::VectorXd b = Eigen::VectorXd::Ones(6), w = Eigen::VectorXd::Ones(10), t = w, d(1),
                  lo = -Eigen::VectorXd::Ones(4), hi = Eigen::VectorXd::Ones(4), x(10);
  d << 0.5;
  x.setConstant(3.0);
  EXPECT_EQ(s.solve(A, b, 1.0, w, t, C, d, lo, hi, x).status, contact::SolverStatus::kInvalidInput);
  EXPECT_TRUE(x.isZero());
  EXPECT_EQ(s.solve(A, b.head(5), 0.9, w, t, C, d, lo, hi, x).status,
            contact::SolverStatus::kInvalidInput);
  b[2] = std::nan("");
  EXPECT_EQ(s.solve(A, b, 0.9, w, t, C, d, lo, hi, x).status, contact::SolverStatus::kInvalidInput);
  EXPECT_THROW(AccelerationSolver(3, 1), std::invalid_argument);
}

TEST(JointAccelerationBounds, ConstantBoundAccelerationReachesTheLimitAtTheHorizon) {
  std::mt19937 rng(36);
  const int n = 40;
  Eigen::VectorXd q(n), qd(n), qmin(n), qmax(n), lo(n), hi(n);
  for (int j = 0; j < n; ++j) {
    qmin[j] = test::uniform(rng, -2.0, -0.5);
    qmax[j] = test::uniform(rng, 0.5, 2.0);
    q[j] = test::uniform(rng, qmin[j], qmax[j]);
    qd[j] = test::uniform(rng, -3.0, 3.0);
  }
  const double T = 0.1, amax = 1e6;
  joint_acceleration_bounds(q, qd, qmin, qmax, T, amax, lo, hi);
  for (int j = 0; j < n; ++j) {
    // Simulate the bound acceleration for T in small steps (independent of the closed form).
    double p = q[j], v = qd[j];
    const int steps = 10000;
    for (int k = 0; k < steps; ++k) {
      v += hi[j] * T / steps;
      p += (v - 0.5 * hi[j] * T / steps) * T / steps;
    }
    EXPECT_NEAR(p, qmax[j], 1e-6);
    EXPECT_LE(lo[j], hi[j]);
    // The bound decreases as the joint approaches its upper limit.
    Eigen::VectorXd q2 = q, lo2(n), hi2(n);
    q2[j] += 0.5 * (qmax[j] - q[j]);
    joint_acceleration_bounds(q2, qd, qmin, qmax, T, amax, lo2, hi2);
    EXPECT_LT(hi2[j], hi[j]);
  }
  // Clamping and infinite limits.
  qmin.setConstant(-std::numeric_limits<double>::infinity());
  qmax.setConstant(std::numeric_limits<double>::infinity());
  joint_acceleration_bounds(q, qd, qmin, qmax, T, 50.0, lo, hi);
  EXPECT_TRUE((lo.array() == -50.0).all() && (hi.array() == 50.0).all());
}

}  // namespace
}  // namespace poise::controller
