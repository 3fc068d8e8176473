// One controller tick (phase A, the contact optimiser, phase B, and the fallbacks) without heap
// allocation: built against copies of the model, contact and controller libraries compiled with
// EIGEN_RUNTIME_NO_MALLOC, and the global operator new is counted as well.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <random>

#include "controller_test_util.hpp"
#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/acceleration_solver.hpp"

static std::atomic<long> g_news{0};
void* operator new(std::size_t n) {
  ++g_news;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace poise::controller {
namespace {

// Parameter: foot.support_acceleration_tau (0: off, the default; > 0: the moving-support
// options of the platform scenarios run too: the foot acceleration filter and its feed-forward,
// the CoM target's lean, the legs' reference leak, and the ankle-first horizontal demand with its
// support polygon).
class NoMallocTick : public ::testing::TestWithParam<double> {};

TEST_P(NoMallocTick, ControllerTickPhasesAndFallbacks) {
  const auto& h = test::humanoid();
  ControllerConfig config;
  config.foot.support_acceleration_tau = GetParam();
  if (GetParam() > 0.0) {
    config.momentum.support_acceleration_hz = 1.0;
    config.feedback.support_leg_leak_hz = 300.0;
    config.feedback.internal_force_leak_hz = 30.0;
    config.momentum.ankle_first_blend = 0.02;
  }
  BalanceController c(h.model, h.robot, config);
  std::mt19937 rng(7);
  std::vector<RobotState> states;
  for (int k = 0; k < 20; ++k)
    states.push_back(test::random_state(c, rng));
  states[3].feet[0].in_contact = false;  // single support
  BalanceReference ref = c.make_reference();
  ref.feet[1].has_target = true;
  ref.feet[1].X_WF_target = states[0].feet[1].X_WF;
  contact::ContactOptimizer opt;
  contact::ContactProblem p;
  contact::ContactSolution sol;
  JointCommand cmd = c.make_command();
  auto solve = [&opt](const contact::ContactProblem& pr, contact::ContactSolution& s) {
    opt.solve(pr, s);
    return true;
  };

  int internal_split_ticks = 0;  // ticks whose legs' internal-force split ran and found one
  Eigen::internal::set_is_malloc_allowed(false);
  const long before = g_news.load();
  for (int k = 0; k < 20; ++k) {
    c.prepare(states[k], ref, p);
    if (k % 4 == 3) {
      c.finish_fallback(cmd);
    } else {
      opt.solve(p, sol);
      c.finish(sol, cmd);
      internal_split_ticks += c.internal_position_error().isZero() ? 0 : 1;
    }
    c.tick(states[k], ref, solve, cmd);
  }
  const long after = g_news.load();
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_EQ(after, before) << "operator new called inside the tick";
  if (GetParam() > 0.0) {
    EXPECT_GT(internal_split_ticks, 5);
  }
  EXPECT_EQ(c.diagnostics().ticks, 40u);
  EXPECT_EQ(cmd.mode, CommandMode::kTorque);

  // The fall (FallConfig) and the damped ticks after it allocate nothing either.
  RobotState fallen = states[0];
  fallen.X_WB.R = Eigen::AngleAxisd(1.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  Eigen::internal::set_is_malloc_allowed(false);
  const long before_fall = g_news.load();
  for (const RobotState* s : {&fallen, &states[1]}) {
    c.prepare(*s, ref, p);
    opt.solve(p, sol);
    c.finish(sol, cmd);
    c.finish_fallback(cmd);
  }
  const long after_fall = g_news.load();
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_EQ(after_fall, before_fall) << "operator new called by a fall";
  EXPECT_TRUE(c.diagnostics().fallen);
  EXPECT_EQ(cmd.mode, CommandMode::kDamping);
}

INSTANTIATE_TEST_SUITE_P(SupportAccelerationFeedForward, NoMallocTick,
                         ::testing::Values(0.0, 0.01));

// RobotConfig::effort_limited_sole (ankles weakened so that the soles are cut every tick): the
// per-tick cut allocates nothing either.
TEST(NoMalloc, EffortLimitedSoles) {
  model::Model m = test::humanoid().model;
  for (const char* ankle : {"l_ankle_pitch", "r_ankle_pitch"}) m.limits[m.joint_index(ankle)].effort = 6.0;
  model::RobotConfig robot = test::humanoid().robot;
  robot.effort_limited_sole = true;
  BalanceController c(m, robot, ControllerConfig{});
  std::mt19937 rng(9);
  std::vector<RobotState> states;
  for (int k = 0; k < 20; ++k) {
    states.push_back(test::random_state(c, rng));
    for (auto& f : states.back().feet) f.normal_force = 300.0;
  }
  BalanceReference ref = c.make_reference();
  contact::ContactOptimizer opt;
  contact::ContactProblem p;
  contact::ContactSolution sol;
  JointCommand cmd = c.make_command();
  int cut = 0;
  Eigen::internal::set_is_malloc_allowed(false);
  const long before = g_news.load();
  for (int k = 0; k < 20; ++k) {
    c.prepare(states[k], ref, p);
    cut += p.feet[0].sole.x_max < robot.feet[0].sole.x_max ? 1 : 0;
    opt.solve(p, sol);
    c.finish(sol, cmd);
  }
  const long after = g_news.load();
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_EQ(after, before) << "operator new called inside the tick";
  EXPECT_EQ(cut, 20);
}

// Eq (33) with active joint bounds: the primal active set (and DualQp, its fallback) allocate
// nothing either. Seeded random problems with tight bounds, sizes of the humanoid.
TEST(NoMalloc, Eq33WithActiveBounds) {
  std::mt19937 rng(11);
  std::normal_distribution<double> N(0.0, 1.0);
  const int nv = 31, m = 12, n = nv - 6;
  AccelerationSolver primal(nv, m), dual(nv, m);
  dual.set_primal_active_set(false);
  int primal_used = 0, dual_used = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(6, nv, [&] { return 10.0 * N(rng); });
    const Eigen::MatrixXd C = Eigen::MatrixXd::NullaryExpr(m, nv, [&] { return N(rng); });
    const Eigen::VectorXd b = Eigen::VectorXd::NullaryExpr(6, [&] { return 100.0 * N(rng); });
    const Eigen::VectorXd d = Eigen::VectorXd::NullaryExpr(m, [&] { return N(rng); });
    const Eigen::VectorXd w = Eigen::VectorXd::Constant(nv, 0.05);
    const Eigen::VectorXd t = Eigen::VectorXd::NullaryExpr(nv, [&] { return 5.0 * N(rng); });
    const Eigen::VectorXd lo = Eigen::VectorXd::Constant(n, -3.0), hi = -lo;
    Eigen::VectorXd x(nv);
    Eigen::internal::set_is_malloc_allowed(false);
    const long before = g_news.load();
    const auto r1 = primal.solve(A, b, 0.9, w, t, C, d, lo, hi, x);
    const auto r2 = dual.solve(A, b, 0.9, w, t, C, d, lo, hi, x);
    const long after = g_news.load();
    Eigen::internal::set_is_malloc_allowed(true);
    EXPECT_EQ(after, before) << "operator new called in trial " << trial;
    primal_used += r1.used_active_set && !r1.used_dual_qp;
    dual_used += r2.used_dual_qp;
  }
  EXPECT_GT(primal_used, 5);  // both paths really ran
  EXPECT_GT(dual_used, 5);
}

// The guard is live in this build (Release with assertions kept on): an allocation aborts.
TEST(NoMallocDeathTest, GuardIsActive) {
  EXPECT_DEATH(
      {
        Eigen::internal::set_is_malloc_allowed(false);
        Eigen::VectorXd v(1000);
        v.setZero();
      },
      "");
}

}  // namespace
}  // namespace poise::controller
