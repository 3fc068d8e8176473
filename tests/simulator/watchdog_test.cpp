// Real-time mode watchdog with a fake clock.
#include <gtest/gtest.h>

#include "poise/sim/simulator.hpp"
#include "poise/sim/watchdog.hpp"
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(SimWatchdog, DampsWhenCommandsStopAndResumesWhenTheyReturn) {
  CommandWatchdog w(5 * kMs);
  EXPECT_EQ(w.update(0), CommandWatchdog::State::kWaiting);
  EXPECT_TRUE(w.damping());
  std::int64_t now = 0;
  // commands every 1 ms for 10 ms
  for (int k = 0; k < 10; ++k, now += kMs) {
    w.on_command(now);
    EXPECT_EQ(w.update(now), CommandWatchdog::State::kActive);
  }
  const std::int64_t last = now - kMs;
  // silence: active while the gap is <= 5 ms, stale after
  for (; now <= last + 5 * kMs; now += kMs)
    EXPECT_EQ(w.update(now), CommandWatchdog::State::kActive) << now;
  EXPECT_EQ(w.update(last + 5 * kMs + 1), CommandWatchdog::State::kStale);
  EXPECT_TRUE(w.damping());
  EXPECT_EQ(w.stale_events(), 1);
  EXPECT_EQ(w.update(last + 50 * kMs), CommandWatchdog::State::kStale);
  EXPECT_EQ(w.stale_events(), 1) << "one event per outage";
  w.on_command(last + 51 * kMs);
  EXPECT_EQ(w.update(last + 51 * kMs), CommandWatchdog::State::kActive);
  EXPECT_FALSE(w.damping());
  EXPECT_THROW(CommandWatchdog(0), std::invalid_argument);
}

TEST(SimWatchdog, SelectedCommandDampsTheSimulatedRobot) {
  Simulator sim(test::biped_config());
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  JointCommand newest = sim.make_command(), damp = sim.make_command();
  make_damping_command(4.0, damp);
  newest.mode = CommandMode::kTorque;
  newest.tau_ff.setConstant(3.0);
  CommandWatchdog w(5 * kMs);
  std::int64_t now = 0;
  for (int k = 0; k < 20; ++k, now += kMs) {
    if (k < 8) w.on_command(now);  // the controller dies after 8 ticks
    w.update(now);
    const Eigen::VectorXd qd = s.qd;
    sim.step(select_command(w, newest, damp), s, g);
    if (k < 8 + 5) {  // last command at 7 ms: fresh up to 12 ms
      EXPECT_EQ(s.tau_measured, Eigen::VectorXd::Constant(sim.num_joints(), 3.0)) << k;
    } else {
      EXPECT_LT((s.tau_measured + 4.0 * qd).norm(), 1e-12) << k;
    }
  }
}

}  // namespace
}  // namespace poise::sim
