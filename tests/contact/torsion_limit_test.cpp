// The friction-coupled normal-torque limit (contact_problem.hpp TorsionLimit):
// |tau_n| <= mu_torsion (f_n - |f_t| / mu).
//
// Checked against an independent model: a foot resting on one edge is two point contacts a
// distance w apart, each with half the normal force and its own Coulomb cone. The largest twist
// those two points can resist while they also carry the tangential force f_t is found here by a
// brute-force search over how f_t is shared between them (no formula of the library is used).
// The coupled limit with mu_torsion = mu w / 2 must never exceed it, and must equal it when f_t
// is across the edge (the worst direction); the independent limit exceeds it once f_t is large,
// which is the torsional slide of issue #17's forward pushes.

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

#include "contact_fixtures.hpp"
#include "poise/contact/contact_optimizer.hpp"
#include "poise/contact/qp_optimizer.hpp"
#include "poise/contact/sequential_optimizer.hpp"

namespace poise::contact {
namespace {

using test::uniform;

/// Largest |twist| about the mid-point of two contact points at (0, +-w/2), each pressed with
/// f_n / 2, whose friction forces g1, g2 (|g_k| <= mu f_n / 2) add up to f_t. g1 = f_t / 2 + d,
/// g2 = f_t / 2 - d; the twist is w (g2_x - g1_x) / 2 = -w d_x. Search over d on a fine grid.
double two_point_twist_capacity(double w, double mu, double f_n, const Eigen::Vector2d& f_t) {
  const double r = 0.5 * mu * f_n;
  double best = -1.0;
  const int n = 400;
  for (int i = 0; i <= n; ++i) {
    const double dx = -r + 2.0 * r * i / n;
    for (int j = 0; j <= n; ++j) {
      const double dy = -r + 2.0 * r * j / n;
      const Eigen::Vector2d d(dx, dy);
      if ((0.5 * f_t + d).norm() <= r && (0.5 * f_t - d).norm() <= r)
        best = std::max(best, std::abs(w * dx));
    }
  }
  return best;  // -1: f_t cannot be carried at all
}

TEST(TorsionLimit, CoupledLimitLiesInsideTwoPointContactCapacityAndIndependentDoesNot) {
  std::mt19937 rng(20261203);
  int independent_outside = 0;
  for (int trial = 0; trial < 60; ++trial) {
    FootContact foot;
    foot.mu = uniform(rng, 0.1, 1.5);
    const double w = uniform(rng, 0.05, 0.15);
    foot.mu_torsion = 0.5 * foot.mu * w;
    const double f_n = uniform(rng, 10.0, 600.0);
    const double angle = uniform(rng, -M_PI, M_PI);
    const double usage = trial % 3 == 0 ? 0.0 : uniform(rng, 0.0, 0.98);
    const Eigen::Vector2d f_t = usage * foot.mu * f_n * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    const Eigen::Vector3d f(f_t.x(), f_t.y(), f_n);
    const double capacity = two_point_twist_capacity(w, foot.mu, f_n, f_t);
    ASSERT_GE(capacity, 0.0);
    const double grid = 2.0 * w * 0.5 * foot.mu * f_n / 400.0;  // the search's resolution
    const double coupled = torsion_limit(foot, f, TorsionLimit::kFrictionCoupled);
    const double independent = torsion_limit(foot, f, TorsionLimit::kIndependent);
    EXPECT_LE(coupled, capacity + grid) << "trial " << trial;
    if (independent > capacity + grid) ++independent_outside;
    // Across the edge (f_t along x), the coupled limit is the capacity itself.
    const Eigen::Vector2d across(f_t.norm(), 0.0);
    const double cap_across = two_point_twist_capacity(w, foot.mu, f_n, across);
    EXPECT_NEAR(coupled, cap_across, grid) << "trial " << trial;
  }
  std::cout << "independent limit above the two-point capacity in " << independent_outside
            << " of 60 cases\n";
  EXPECT_GE(independent_outside, 20) << "the independent limit should overstate the twist a "
                                        "loaded edge can resist in most trials with f_t > 0";
}

TEST(TorsionLimit, LimitCases) {
  FootContact foot;
  foot.mu = 0.8;
  foot.mu_torsion = 0.02;
  const auto coupled = [&](double fx, double fy, double fz) {
    return torsion_limit(foot, Eigen::Vector3d(fx, fy, fz), TorsionLimit::kFrictionCoupled);
  };
  EXPECT_DOUBLE_EQ(coupled(0.0, 0.0, 300.0), 0.02 * 300.0);           // no tangential force
  EXPECT_NEAR(coupled(0.8 * 300.0, 0.0, 300.0), 0.0, 1e-12);          // at the friction limit
  EXPECT_NEAR(coupled(0.0, 0.4 * 300.0, 300.0), 0.02 * 150.0, 1e-12);  // half the friction used
  EXPECT_DOUBLE_EQ(coupled(0.0, 0.0, -5.0), 0.0);                      // a pull: no torque
  foot.mu = 0.0;  // no Coulomb friction given: the independent limit
  EXPECT_DOUBLE_EQ(coupled(0.0, 0.0, 300.0), 0.02 * 300.0);
  EXPECT_STREQ(to_string(TorsionLimit::kFrictionCoupled), "friction-coupled");
  EXPECT_EQ(parse_torsion_limit("friction-coupled"), TorsionLimit::kFrictionCoupled);
  EXPECT_EQ(parse_torsion_limit("independent"), TorsionLimit::kIndependent);
  EXPECT_FALSE(parse_torsion_limit("coupled").has_value());
}

/// Every foot of every answer within the coupled limit, for both methods, on random problems
/// (tilted feet up to 25 deg, mu 0.1-1.5, zero torsional friction now and then).
TEST(TorsionLimit, BothMethodsKeepEveryAnswerWithinTheCoupledLimit) {
  std::mt19937 rng(7);
  SequentialOptimizer sequential;
  QpOptimizer qp1, qp2;
  qp2.set_torsion_passes(2);
  int binding = 0;  // answers in which the coupled limit was tighter than the independent one
  for (int trial = 0; trial < 600; ++trial) {
    const int support = trial % 3;  // 0: double, 1: right only, 2: left only
    ContactProblem p = trial % 2 == 0
                           ? test::random_arbitrary(rng, support != 2, support != 1)
                           : test::random_feasible(rng, support != 2, support != 1);
    for (FootContact& f : p.feet) {
      f.R_WF = test::rpy(uniform(rng, -0.44, 0.44), uniform(rng, -0.44, 0.44),
                         uniform(rng, -0.3, 0.3));
      f.mu = uniform(rng, 0.1, 1.5);
      if (trial % 7 == 0) f.mu_torsion = 0.0;
    }
    // Large yaw demands make the normal torques bind.
    p.k_dot_desired.z() += uniform(rng, -40.0, 40.0);
    p.weights.priority = trial % 4 == 0 ? Priority::kWeighted : Priority::kLexicographic;
    p.weights.torsion = TorsionLimit::kFrictionCoupled;
    for (int m = 0; m < 3; ++m) {
      ContactSolution s;
      if (m == 0) sequential.solve(p, s);
      if (m == 1) qp1.solve(p, s);
      if (m == 2) qp2.solve(p, s);
      ASSERT_NE(s.status, ContactStatus::kInvalidInput) << "trial " << trial;
      for (int i = 0; i < kMaxFeet; ++i) {
        if (!p.feet[i].in_contact) continue;
        const Eigen::Vector3d f_F = p.feet[i].R_WF.transpose() * s.feet[i].force_W;
        const double lim = torsion_limit(p.feet[i], f_F, TorsionLimit::kFrictionCoupled);
        EXPECT_LE(std::abs(s.feet[i].normal_torque), lim + 1e-9 * (1.0 + f_F.norm()))
            << "trial " << trial << " method " << m << " foot " << i;
        if (m == 0 && std::abs(s.feet[i].normal_torque) > 1e-6 &&
            lim < torsion_limit(p.feet[i], f_F, TorsionLimit::kIndependent) - 1e-6 &&
            std::abs(std::abs(s.feet[i].normal_torque) - lim) < 1e-9 * (1.0 + f_F.norm()))
          ++binding;
      }
    }
  }
  std::cout << "coupled limit binding (tighter than the independent one) on " << binding
            << " sequential answers' feet of 600 problems\n";
  EXPECT_GE(binding, 30) << "the coupled limit should bind in some of the answers";
}

/// The limit changes the answer only where it binds: the same problem solved with both limits
/// gives the same forces (the force stage does not see the torsion bound) and, where the
/// independent answer's normal torques are within the coupled limit, the same CoPs and torques.
TEST(TorsionLimit, SequentialAnswerChangesOnlyWhereTheCoupledLimitBinds) {
  std::mt19937 rng(11);
  SequentialOptimizer a, b;
  int same = 0, changed = 0;
  for (int trial = 0; trial < 400; ++trial) {
    ContactProblem p = trial % 2 == 0 ? test::random_feasible(rng, true, true)
                                      : test::random_arbitrary(rng, true, true);
    if (trial % 2 == 1) p.k_dot_desired.z() += uniform(rng, -30.0, 30.0);
    ContactSolution si, sc;
    p.weights.torsion = TorsionLimit::kIndependent;
    a.solve(p, si);
    p.weights.torsion = TorsionLimit::kFrictionCoupled;
    b.solve(p, sc);
    bool within = true;
    for (int i = 0; i < kMaxFeet; ++i) {
      EXPECT_LE((si.feet[i].force_W - sc.feet[i].force_W).norm(), 1e-9 * (1.0 + si.feet[i].force_W.norm()));
      const Eigen::Vector3d f_F = p.feet[i].R_WF.transpose() * si.feet[i].force_W;
      if (std::abs(si.feet[i].normal_torque) >
          torsion_limit(p.feet[i], f_F, TorsionLimit::kFrictionCoupled) + 1e-9)
        within = false;
    }
    if (within) {
      ++same;
      for (int i = 0; i < kMaxFeet; ++i) {
        EXPECT_NEAR(si.feet[i].normal_torque, sc.feet[i].normal_torque, 1e-6) << trial;
        EXPECT_LE((si.feet[i].cop_F - sc.feet[i].cop_F).norm(), 1e-6) << trial;
      }
    } else {
      ++changed;
    }
  }
  std::cout << "sequential answers unchanged: " << same << ", changed where it binds: " << changed
            << " of 400\n";
  EXPECT_GE(same, 20);
  EXPECT_GE(changed, 20);
}

}  // namespace
}  // namespace poise::contact
