// Start-up must not depend on the robot's inertia: a humanoid whose hands weigh 1e-4 kg m^2
// about their wrist axes (tests/data/robots/light_wrist) starts over DDS as cleanly as in
// process. Before the safety layer, poise-sim held every joint at start-up with kp 400, kd 10:
// on such a wrist (kd dt / I = 100) the explicit 1 kHz PD diverges within a few ticks.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "support/child_process.hpp"

namespace {

using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;

const std::string kScenario =
    std::string(POISE_SOURCE_DIR) + "/tests/data/scenarios/light_wrist_standing.yaml";

nlohmann::json run(const std::vector<std::string>& extra, const std::string& name) {
  const std::string out = ::testing::TempDir() + "light_wrist_" + name + ".json";
  std::vector<std::string> args{bin("poise"), "run", kScenario, "-o", out};
  args.insert(args.end(), extra.begin(), extra.end());
  ChildProcess p(args, {}, false, true);
  const auto code = p.wait_for(180s);
  EXPECT_TRUE(code.has_value()) << p.output();
  std::ifstream in(out);
  EXPECT_TRUE(in.good()) << p.output();
  if (!in.good()) return nlohmann::json::object();
  auto j = nlohmann::json::parse(in);
  j["_output"] = p.output();
  return j;
}

TEST(LightWrist, StartsOverDdsAsCleanlyAsInProcess) {
  const auto in_process = run({"--in-process"}, "in_process");
  const auto distributed =
      run({"--dds", "cyclone", "--log-dir", ::testing::TempDir() + "light_wrist.logs"},
          "distributed");
  ASSERT_TRUE(in_process.value("survived", false)) << in_process["_output"];
  ASSERT_TRUE(distributed.value("survived", false)) << distributed["_output"];
  const double speed = distributed["max_joint_speed"]["speed"].get<double>();
  std::printf("light wrist: CoM error max %.4f m in process, %.4f m distributed; fastest joint "
              "distributed %s at %.3f rad/s\n",
              in_process["com_error_max_m"].get<double>(),
              distributed["com_error_max_m"].get<double>(),
              distributed["max_joint_speed"]["joint"].get<std::string>().c_str(), speed);
  EXPECT_LT(speed, 5.0);  // an exploding wrist spins at 30-155 rad/s
  EXPECT_NEAR(distributed["com_error_max_m"].get<double>(),
              in_process["com_error_max_m"].get<double>(), 0.003);
  EXPECT_EQ(distributed["safety"]["rejected"].get<int>(), 0);
}

}  // namespace
