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

TEST(NoMalloc, ControllerTickPhasesAndFallbacks) {
  const auto& h = test::humanoid();
  BalanceController c(h.model, h.robot, ControllerConfig{});
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

  Eigen::internal::set_is_malloc_allowed(false);
  const long before = g_news.load();
  for (int k = 0; k < 20; ++k) {
    c.prepare(states[k], ref, p);
    if (k % 4 == 3) {
      c.finish_fallback(cmd);
    } else {
      opt.solve(p, sol);
      c.finish(sol, cmd);
    }
    c.tick(states[k], ref, solve, cmd);
  }
  const long after = g_news.load();
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_EQ(after, before) << "operator new called inside the tick";
  EXPECT_EQ(c.diagnostics().ticks, 40u);
  EXPECT_EQ(cmd.mode, CommandMode::kTorque);
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
