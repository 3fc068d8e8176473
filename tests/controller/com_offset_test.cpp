// The CoM-error observer (poise/controller/com_offset_observer.hpp, ControllerConfig::com_offset):
// its filter against the closed-form response of a first-order discrete filter, its gates and
// its clamp with seeded random inputs; its configuration keys; and, in closed loop with the real
// Bullet simulator and the estimator, a robot whose every link mass is off by 10 % and whose
// trunk CoM is off by 2 cm (a `reality:` draw the controller does not know): the observer's
// estimate against the simulator's own mass properties, and where the robot comes to rest.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>

#include "poise/controller/com_offset_observer.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/inprocess/in_process_loop.hpp"

namespace poise::controller {
namespace {

constexpr double kDt = 0.001;
constexpr double kWeight = 500.0;

TEST(ComOffsetObserver, FollowsAFirstOrderFilterAtRestAndHoldsWhenItsGatesClose) {
  std::mt19937_64 rng(53);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  ComOffsetObserverConfig c;
  c.bandwidth_hz = 0.5;
  c.limit = 0.05;
  const double a = kDt / (kDt + 1.0 / (2.0 * M_PI * c.bandwidth_hz));
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d com(u(rng), u(rng), 0.8 + u(rng));
    const Eigen::Vector3d cop(com.x() + u(rng), com.y() + u(rng), 0.0);
    ComOffsetObserver o;
    const int n = 1 + static_cast<int>(std::abs(u(rng)) * 1e5);  // up to 2000 ticks
    for (int k = 0; k < n; ++k)
      o.update(c, kDt, cop, kWeight, kWeight, com, Eigen::Vector3d::Zero());
    // delta_n = (1 - (1 - a)^n) (p - r): the discrete first-order step response.
    const double g = 1.0 - std::pow(1.0 - a, n);
    EXPECT_NEAR(o.offset().x(), g * (cop.x() - com.x()), 1e-12);
    EXPECT_NEAR(o.offset().y(), g * (cop.y() - com.y()), 1e-12);
    EXPECT_EQ(o.offset().z(), 0.0) << "the vertical error is not observable from the CoP";
    EXPECT_TRUE(o.learning());

    // Gates: a CoM moving at the gate's speed, a robot with less than half its weight on the
    // feet, a non-finite CoP: the estimate is held exactly.
    const Eigen::Vector3d held = o.offset();
    const Eigen::Vector3d far = cop + Eigen::Vector3d(0.05, -0.05, 0.0);
    o.update(c, kDt, far, kWeight, kWeight, com, Eigen::Vector3d(c.speed_gate, 0.0, 0.0));
    EXPECT_FALSE(o.learning());
    o.update(c, kDt, far, 0.49 * kWeight, kWeight, com, Eigen::Vector3d::Zero());
    EXPECT_FALSE(o.learning());
    o.update(c, kDt, Eigen::Vector3d::Constant(NAN), kWeight, kWeight, com,
             Eigen::Vector3d::Zero());
    EXPECT_FALSE(o.learning());
    EXPECT_EQ(o.offset(), held);
    // A vertical CoM velocity is not a horizontal motion: it learns.
    o.update(c, kDt, cop, kWeight, kWeight, com, Eigen::Vector3d(0.0, 0.0, 1.0));
    EXPECT_TRUE(o.learning());
  }
}

TEST(ComOffsetObserver, IsClampedToItsLimitAndOffWithoutABandwidth) {
  ComOffsetObserverConfig c;
  c.bandwidth_hz = 5.0;
  c.limit = 0.01;
  ComOffsetObserver o;
  const Eigen::Vector3d com(0.0, 0.0, 0.8), cop(0.03, 0.04, 0.0);  // 5 cm away
  for (int k = 0; k < 5000; ++k) o.update(c, kDt, cop, kWeight, kWeight, com, Eigen::Vector3d::Zero());
  EXPECT_NEAR(o.offset().head<2>().norm(), 0.01, 1e-12);
  EXPECT_NEAR(o.offset().x() / o.offset().y(), 0.75, 1e-9) << "clamped along its direction";
  o.reset();
  EXPECT_EQ(o.offset(), Eigen::Vector3d::Zero());
  c.bandwidth_hz = 0.0;
  o.update(c, kDt, cop, kWeight, kWeight, com, Eigen::Vector3d::Zero());
  EXPECT_FALSE(o.learning());
  EXPECT_EQ(o.offset(), Eigen::Vector3d::Zero());
}

std::string config_error(const std::string& yaml) {
  try {
    parse_controller_config(yaml, "test");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ComOffsetObserver, ConfigKeysParseAndBadValuesNameTheirKey) {
  EXPECT_EQ(parse_controller_config("", "test").com_offset.bandwidth_hz, 0.0) << "off by default";
  const ControllerConfig c =
      parse_controller_config("com_offset: {bandwidth_hz: 0.5, limit: 0.02, speed_gate: 0.1}", "t");
  EXPECT_EQ(c.com_offset.bandwidth_hz, 0.5);
  EXPECT_EQ(c.com_offset.limit, 0.02);
  EXPECT_EQ(c.com_offset.speed_gate, 0.1);
  EXPECT_NE(config_error("com_offset: {bandwidth_hz: -1}").find("com_offset.bandwidth_hz"),
            std::string::npos);
  EXPECT_NE(config_error("com_offset: {bandwidth_hz: 600}").find("com_offset.bandwidth_hz"),
            std::string::npos);
  EXPECT_NE(config_error("com_offset: {limit: 0.5}").find("com_offset.limit"), std::string::npos);
  EXPECT_NE(config_error("com_offset: {speed_gate: 0}").find("com_offset.speed_gate"),
            std::string::npos);
  EXPECT_NE(config_error("com_offset: {bandwidth: 1}").find("bandwidth"), std::string::npos);
}

// ---- closed loop ---------------------------------------------------------------------------

struct Rest {
  double com_error_final_m = 0.0;  ///< the monitor's: the robot's CoM against the intended point
  Eigen::Vector3d estimate = Eigen::Vector3d::Zero();  ///< the observer's, at the end
  Eigen::Vector3d truth = Eigen::Vector3d::Zero();     ///< robot minus model CoM, at the end
  bool survived = false;
};

/// Stands `seconds` on a robot whose every body's mass is x 0.9 or x 1.1 (signs from `seed`)
/// and whose trunk CoM is 2 cm off in a direction from `seed`, with the estimator's state.
Rest stand_off_model(unsigned seed, double bandwidth_hz, double seconds) {
  scenario::Scenario s = scenario::load_scenario(std::string(POISE_SOURCE_DIR) +
                                                 "/deploy/scenarios/standing.yaml");
  s.duration = seconds;
  std::vector<std::string> bodies;
  {
    sim::Simulator probe(s.sim);
    bodies = probe.body_names();
  }
  std::mt19937_64 rng(seed);
  auto& r = s.sim.reality;
  r.enabled = true;
  r.profile = "test";
  r.seed = seed;
  for (const auto& b : bodies)
    r.links.mass_scale.emplace_back(b, (rng() & 1u) ? 1.1 : 0.9);
  const double angle = std::uniform_real_distribution<double>(0.0, 2.0 * M_PI)(rng);
  if (std::find(bodies.begin(), bodies.end(), "torso") == bodies.end())
    throw std::runtime_error("the shipped robot has no body named torso");
  r.links.com_offset.emplace_back("torso",
                                  Eigen::Vector3d(0.02 * std::cos(angle), 0.02 * std::sin(angle), 0));
  s.controller_yaml = "com_offset: {bandwidth_hz: " + std::to_string(bandwidth_hz) + "}\n";
  inprocess::InProcessLoop loop(s, inprocess::LoopOptions{});
  const inprocess::RunResult res = loop.run();
  Rest rest;
  rest.com_error_final_m = res.com_error_final_m;
  rest.survived = res.survived;
  rest.estimate = loop.controller().diagnostics().com_offset_W;
  rest.truth = -loop.truth().model_com_shift_W;
  std::printf("[stand off model, seed %u, observer %.1f Hz] CoM error at rest %.2f mm; observed "
              "(%.2f, %.2f) mm, true (%.2f, %.2f) mm\n",
              seed, bandwidth_hz, 1e3 * rest.com_error_final_m, 1e3 * rest.estimate.x(),
              1e3 * rest.estimate.y(), 1e3 * rest.truth.x(), 1e3 * rest.truth.y());
  return rest;
}

// The target: a standing robot whose every link mass is off by 10 % and whose trunk CoM
// is off by 2 cm comes to rest with its CoM over the intended point within 5 mm. Without the
// observer it stands where the model's CoM is over that point, off by the model's error.
TEST(ComOffsetObserverClosedLoop, ARobotThatIsNotItsModelComesToRestOverTheIntendedPoint) {
  for (const unsigned seed : {11u, 12u}) {
    const Rest off = stand_off_model(seed, 0.0, 6.0);
    const Rest on = stand_off_model(seed, 0.5, 6.0);
    EXPECT_TRUE(off.survived);
    EXPECT_TRUE(on.survived);
    EXPECT_GT(off.com_error_final_m, 0.5 * off.truth.head<2>().norm())
        << "without the observer the robot stands with the model's CoM over the point";
    EXPECT_LT(on.com_error_final_m, 0.005);
    EXPECT_LT(on.com_error_final_m, 0.3 * off.com_error_final_m);
    // The estimate is the simulator's own mass properties' error (the estimator's state, the
    // F/T noise and what the robot still moves leave a millimetre or two).
    EXPECT_LT((on.estimate - on.truth).head<2>().norm(), 0.003);
    EXPECT_GT(on.truth.head<2>().norm(), 0.004) << "a draw that moves the CoM";
  }
}

}  // namespace
}  // namespace poise::controller
