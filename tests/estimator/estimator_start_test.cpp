// The scenario's estimator section (type, ground_height, support_height) and where `poise run`
// starts the estimator's soles (scenario::estimator_start, issue #20 item 2): given heights, the ground
// plane, and the platforms' placement at t = 0 checked against the geometry of the shipped
// platforms.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "poise/estimator/estimator.hpp"
#include "poise/scenario/scenario.hpp"

namespace {

using namespace poise;

const std::string kRobot = std::string("robot: {config: ") + POISE_SOURCE_DIR +
                           "/deploy/robots/poise_humanoid/robot.yaml}\n";

scenario::Scenario parse(const std::string& estimator_section) {
  return scenario::parse_scenario("name: t\nduration: 1\n" + kRobot + estimator_section, ".", "test");
}

TEST(EstimatorStart, ScenarioKeysAndDefaults) {
  const scenario::Scenario plain = parse("");
  EXPECT_EQ(plain.estimator.type, "invariant-ekf");
  scenario::EstimatorStart s = scenario::estimator_start(plain);
  EXPECT_EQ(s.source, "ground plane");
  EXPECT_FALSE(s.per_foot);
  EXPECT_EQ(s.ground_height, 0.0);

  const scenario::Scenario g = parse("estimator: {type: leg-odometry, ground_height: 0.05}\n");
  EXPECT_EQ(g.estimator.type, "leg-odometry");
  EXPECT_EQ(estimator::parse_estimator_kind(g.estimator.type),
            estimator::EstimatorKind::kLegOdometry);
  s = scenario::estimator_start(g);
  EXPECT_EQ(s.source, "scenario ground_height");
  EXPECT_DOUBLE_EQ(s.ground_height, 0.05);
  EXPECT_FALSE(s.per_foot);

  const scenario::Scenario f = parse("estimator: {support_height: {left: 0.1, right: 0.2}}\n");
  s = scenario::estimator_start(f);
  EXPECT_EQ(s.source, "scenario support_height");
  ASSERT_TRUE(s.per_foot);
  EXPECT_DOUBLE_EQ(s.support_height[0], 0.2);  // right
  EXPECT_DOUBLE_EQ(s.support_height[1], 0.1);  // left

  // The base-rate fusion's cut-off: NaN (the estimator's default) unless given.
  EXPECT_TRUE(std::isnan(plain.estimator.stance_rate_hz));
  EXPECT_DOUBLE_EQ(parse("estimator: {stance_rate_hz: 0}\n").estimator.stance_rate_hz, 0.0);
  EXPECT_DOUBLE_EQ(parse("estimator: {stance_rate_hz: 12.5}\n").estimator.stance_rate_hz, 12.5);
  // The contact detector's light-touch rule: NaN unless given; what the estimator gets
  // (estimator_contact_ft_noise): the key, else the simulated F/T's noise, else NaN (the
  // estimator's own default).
  EXPECT_TRUE(std::isnan(plain.estimator.contact_ft_noise));
  EXPECT_DOUBLE_EQ(parse("estimator: {contact_ft_noise: 0.5}\n").estimator.contact_ft_noise, 0.5);
  EXPECT_DOUBLE_EQ(scenario::estimator_contact_ft_noise(plain), plain.sim.foot_ft.force_noise_std);
  EXPECT_GT(scenario::estimator_contact_ft_noise(plain), 0.0) << "default sensors: the rule on";
  EXPECT_DOUBLE_EQ(scenario::estimator_contact_ft_noise(
                       parse("estimator: {contact_ft_noise: 0}\n")),
                   0.0);
  EXPECT_DOUBLE_EQ(scenario::estimator_contact_ft_noise(parse(
                       "estimator: {contact_ft_noise: 0.3}\nsensors: {foot_ft: "
                       "{force_noise_std: 0.8}}\n")),
                   0.3);
  EXPECT_DOUBLE_EQ(scenario::estimator_contact_ft_noise(
                       parse("sensors: {foot_ft: {force_noise_std: 0.8}}\n")),
                   0.8);
  EXPECT_TRUE(std::isnan(scenario::estimator_contact_ft_noise(
      parse("sensors: {foot_ft: {force_noise_std: 0}}\n"))));
  // The contact detector's resting rule: NaN (the estimator's default, 0.02 s) unless given.
  EXPECT_TRUE(std::isnan(plain.estimator.contact_rest_time));
  EXPECT_DOUBLE_EQ(parse("estimator: {contact_rest_time: 0.02}\n").estimator.contact_rest_time,
                   0.02);
  // The IMU latency allowed for with an IMU behind joints: the key, else the simulated IMU's.
  EXPECT_EQ(plain.estimator.imu_delay_ticks, -1);
  EXPECT_EQ(scenario::estimator_imu_delay_ticks(plain), plain.sim.imu.delay_ticks);
  EXPECT_EQ(scenario::estimator_imu_delay_ticks(parse("sensors: {imu: {delay_ticks: 3}}\n")), 3);
  EXPECT_EQ(scenario::estimator_imu_delay_ticks(
                parse("estimator: {imu_delay_ticks: 0}\nsensors: {imu: {delay_ticks: 3}}\n")),
            0);
}

TEST(EstimatorStart, BadValuesAreRefusedNamingTheKey) {
  const auto message = [](const std::string& section) {
    try {
      parse(section);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("estimator: {type: kalman}\n").find("estimator.type"), std::string::npos);
  EXPECT_NE(message("estimator: {ground_height: high}\n").find("estimator.ground_height"),
            std::string::npos);
  EXPECT_NE(message("estimator: {support_height: {middle: 0.1}}\n")
                .find("estimator.support_height.middle"),
            std::string::npos);
  EXPECT_NE(message("estimator: {support_height: 0.1}\n").find("estimator.support_height"),
            std::string::npos);
  EXPECT_NE(message("estimator: {stance_rate_hz: -1}\n").find("estimator.stance_rate_hz"),
            std::string::npos);
  EXPECT_NE(message("estimator: {stance_rate_hz: fast}\n").find("estimator.stance_rate_hz"),
            std::string::npos);
  for (const char* bad :
       {"estimator: {contact_rest_time: -0.1}\n", "estimator: {contact_rest_time: .nan}\n",
        "estimator: {contact_rest_time: 20}\n", "estimator: {contact_rest_time: soon}\n"})
    EXPECT_NE(message(bad).find("estimator.contact_rest_time"), std::string::npos) << bad;
  EXPECT_NE(message("estimator: {contact_ft_noise: -0.5}\n").find("estimator.contact_ft_noise"),
            std::string::npos);
  EXPECT_NE(message("estimator: {contact_ft_noise: .nan}\n").find("estimator.contact_ft_noise"),
            std::string::npos);
  for (const char* bad : {"-1", "1.5", "101", "late"})
    EXPECT_NE(message(std::string("estimator: {imu_delay_ticks: ") + bad + "}\n")
                  .find("estimator.imu_delay_ticks"),
              std::string::npos)
        << bad;
  EXPECT_THROW(estimator::parse_estimator_kind("kalman"), estimator::EstimatorError);
}

// The shipped platforms: 0.1 m boxes pitched +10 deg (left, toe down) and -10 deg (right); the
// robot is lifted until its lowest sole point, the left toe (x_max = 0.14 m ahead of the foot
// frame), touches z = 0.1. The left sole point under the foot frame is then 0.14 sin(10 deg)
// higher; the legs are symmetric, so the right one is at the same height.
TEST(EstimatorStart, PlatformHeightsFollowThePlacement) {
  const scenario::Scenario sc =
      scenario::load_scenario(std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/platforms_in_phase.yaml");
  const scenario::EstimatorStart s = scenario::estimator_start(sc);
  EXPECT_EQ(s.source, "platforms at t = 0");
  ASSERT_TRUE(s.per_foot);
  const double expected = 0.1 + 0.14 * std::sin(10.0 * M_PI / 180.0);
  EXPECT_NEAR(s.support_height[1], expected, 1e-3);
  EXPECT_NEAR(s.support_height[0], expected, 2e-3);
}

}  // namespace
