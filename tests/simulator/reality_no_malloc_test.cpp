// The reality section's per-tick work (actuator delay, lag, noise, clamp; friction) allocates
// nothing: with `reality: typical` the biped standing under PD is stepped with Eigen's heap
// forbidden (poise_sim is built with EIGEN_RUNTIME_NO_MALLOC) and the global operator new
// counted; the count is the same as the robot's without the section (zero here: a robot at rest
// makes no new contact manifolds).
#define EIGEN_RUNTIME_NO_MALLOC
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "poise/sim/simulator.hpp"
#include "sim_test_util.hpp"

static std::atomic<long> g_news{0};
void* operator new(std::size_t n) {
  ++g_news;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace poise::sim {
namespace {

long allocations_while_standing(bool reality) {
  SimulatorConfig cfg = test::biped_config();
  if (reality) {
    cfg.reality = typical_reality();
    cfg.reality.seed = 3;
    cfg.reality.actuators.torque_noise_std = 0.1;  // the noise path too
  }
  Simulator sim(cfg);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  sim.read(s, g);
  const JointCommand cmd = test::hold_command(sim, s, 300.0, 6.0);
  for (int k = 0; k < 300; ++k) sim.step(cmd, s, g);  // settle: contacts made
  const long before = g_news.load();
  Eigen::internal::set_is_malloc_allowed(false);
  for (int k = 0; k < 300; ++k) sim.step(cmd, s, g);
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_LT(g.com_vel_W.norm(), 0.05) << "the biped stands";
  return g_news.load() - before;
}

TEST(RealityNoMalloc, AStepWithTheTypicalProfileAllocatesNothing) {
  const long plain = allocations_while_standing(false);
  const long typical = allocations_while_standing(true);
  EXPECT_EQ(typical, plain);
  EXPECT_EQ(typical, 0);
}

}  // namespace
}  // namespace poise::sim
