// The scenario's estimator section (type, ground_height, support_height) and where `poise run`
// starts the estimator's soles (scenario::estimator_start, issue #20 item 2): given heights, the ground
// plane, and the platforms' placement at t = 0 checked against the geometry of the shipped
// platforms.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

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

std::string error_of(const std::string& section) {
  try {
    parse(section);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "accepted";
}

// The `estimator:` keys come from one table (deploy/scenario/src/estimator_section.cpp): each is
// parsed, checked and in the reference (estimator/CONFIG.md). A key added to the table without a
// case here fails.
TEST(EstimatorSection, EveryTableKeyIsParsedCheckedAndDocumented) {
  using Hints = scenario::EstimatorHints;
  struct Case {
    std::string good;
    std::function<bool(const Hints&)> stored;
    std::vector<std::string> bad;
  };
  const std::map<std::string, Case> cases = {
      {"type", {"leg-odometry", [](const Hints& h) { return h.type == "leg-odometry"; },
                {"kalman", "[invariant-ekf]", "''"}}},
      {"supports", {"translating", [](const Hints& h) { return h.supports == "translating"; },
                    {"rolling", "{a: 1}"}}},
      {"ground_height", {"0.25", [](const Hints& h) { return h.ground_height == 0.25; },
                         {"high", ".nan"}}},
      {"support_height",
       {"{left: 0.1}",
        [](const Hints& h) {
          return h.support_height.size() == 1 && h.support_height[0].first == "left" &&
                 h.support_height[0].second == 0.1;
        },
        {"0.1", "{middle: 0.1}", "{left: x}"}}},
      {"stance_rate_hz", {"12.5", [](const Hints& h) { return h.stance_rate_hz == 12.5; },
                          {"-1", "fast", ".inf"}}},
      {"contact_ft_noise", {"0.3", [](const Hints& h) { return h.contact_ft_noise == 0.3; },
                            {"-0.5", ".nan"}}},
      {"contact_rest_time", {"0.05", [](const Hints& h) { return h.contact_rest_time == 0.05; },
                             {"-0.1", "20", "soon"}}},
      {"imu_delay_ticks", {"3", [](const Hints& h) { return h.imu_delay_ticks == 3; },
                           {"-1", "101", "2.5"}}},
  };
  const std::vector<std::string_view> keys = scenario::estimator_section_keys();
  EXPECT_EQ(keys.size(), cases.size());
  const std::string md = scenario::estimator_section_markdown();
  const std::string unknown = error_of("estimator: {kind: x}\n");
  EXPECT_NE(unknown.find("estimator.kind: unknown key"), std::string::npos) << unknown;
  for (const std::string_view k : keys) {
    const std::string key(k);
    const auto it = cases.find(key);
    ASSERT_NE(it, cases.end()) << key << ": a table key without a case here";
    EXPECT_NE(md.find("| `estimator." + key + "` |"), std::string::npos) << key;
    EXPECT_NE(unknown.find(key), std::string::npos) << key << " not in the allowed list";
    const scenario::Scenario s = parse("estimator: {" + key + ": " + it->second.good + "}\n");
    EXPECT_TRUE(it->second.stored(s.estimator)) << key << ": " << it->second.good;
    for (const std::string& bad : it->second.bad) {
      const std::string m = error_of("estimator: {" + key + ": " + bad + "}\n");
      EXPECT_NE(m.find("estimator." + key), std::string::npos) << key << ": " << bad << " -> " << m;
    }
  }
}

}  // namespace
