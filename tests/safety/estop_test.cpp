// `poise estop` succeeds only when every robot side has acknowledged (issue: 7 of 10 stops never
// reached a gantry while the CLI printed ENGAGED, because a monitor's reader had matched first).
// Real processes: poise-gantry as the robot side (its safety layer answers on poise/estop_state),
// monitors subscribed to poise/estop on both vendors, and the CLI on alternating vendors.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "support/child_process.hpp"

namespace {

using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;

struct Ran {
  int code = -1;
  std::string output;
};

Ran poise_cli(std::vector<std::string> args, std::chrono::seconds limit = 60s) {
  args.insert(args.begin(), bin("poise"));
  ChildProcess p(args, {}, false, true);
  const auto code = p.wait_for(limit);
  return {code.value_or(-1), p.output()};
}

ChildProcess gantry(const std::string& domain, const char* vendor, const std::string& summary,
                    const char* duration = "60") {
  // --wait-readers 0: its loop (which takes and acknowledges the stops) starts at once.
  return ChildProcess({bin("poise-gantry"), "--dds", vendor, "--domain", domain, "--duration",
                       duration, "--summary", summary, "--wait-readers", "0"},
                      {}, false, true);
}

// A reader of poise/estop that is not a robot: `poise topic echo`, on the given vendor.
ChildProcess monitor(const std::string& domain, const char* vendor) {
  return ChildProcess({bin("poise"), "topic", "echo", "poise/estop", "--dds", vendor, "--domain",
                       domain, "--timeout", "120"},
                      {}, false, true);
}

// Twenty engages and releases, alternating the CLI's vendor, with two monitors subscribed (one
// per vendor): every one is acknowledged by the gantry and reaches its safety layer.
TEST(EStop, TwentyEngagesAndReleasesAllArriveBesideMonitorsOnBothVendors) {
  const std::string d = std::to_string(poise::testing::unique_domain_id());
  const std::string summary = ::testing::TempDir() + "estop_gantry_summary.json";
  std::remove(summary.c_str());
  ChildProcess robot = gantry(d, "cyclone", summary);
  ChildProcess watch_fast = monitor(d, "fastdds");
  ChildProcess watch_cyclone = monitor(d, "cyclone");
  ASSERT_TRUE(robot.wait_for_output("gantry:", 30s)) << robot.output();
  for (int i = 0; i < 20; ++i) {
    const bool engage = i % 2 == 0;
    std::vector<std::string> args = {"estop", "--domain", d, "--dds",
                                     (i / 2) % 2 == 0 ? "fastdds" : "cyclone", "--discover-ms",
                                     "200", "--reason", "test " + std::to_string(i)};
    if (!engage) args.push_back("--release");
    const Ran r = poise_cli(args);
    ASSERT_EQ(r.code, 0) << "stop " << i << ":\n" << r.output << "\ngantry:\n" << robot.output();
    EXPECT_NE(r.output.find(engage ? "ENGAGED" : "RELEASED"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("acknowledged by 1 robot side(s)"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("poise-gantry@"), std::string::npos) << r.output;
  }
  robot.interrupt();
  std::ifstream in(summary);
  ASSERT_TRUE(in.good()) << robot.output();
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["safety"]["estop_events"].get<int>(), 10) << j.dump(2);
}

// The stop is latched: a robot side that starts after the command was given gets it, and the
// command reports it acknowledged.
TEST(EStop, ARobotSideThatStartsLaterGetsTheStop) {
  const std::string d = std::to_string(poise::testing::unique_domain_id());
  ChildProcess cli({bin("poise"), "estop", "--domain", d, "--dds", "fastdds", "--wait-ms",
                    "30000", "--reason", "late robot"},
                   {}, false, true);
  std::this_thread::sleep_for(1500ms);
  const std::string summary = ::testing::TempDir() + "estop_late_summary.json";
  ChildProcess robot = gantry(d, "cyclone", summary);
  const auto code = cli.wait_for(60s);
  ASSERT_TRUE(code.has_value()) << cli.output();
  EXPECT_EQ(*code, 0) << cli.output() << "\ngantry:\n" << robot.output();
  EXPECT_NE(cli.output().find("acknowledged by 1 robot side(s)"), std::string::npos)
      << cli.output();
  EXPECT_TRUE(robot.wait_for_output("safety: ESTOP", 10s)) << robot.output();
  robot.interrupt();
}

// Readers of poise/estop that are not robots (a monitor) never make the command succeed.
TEST(EStop, AMonitorAloneIsNotARobot) {
  const std::string d = std::to_string(poise::testing::unique_domain_id());
  ChildProcess watch = monitor(d, "cyclone");
  std::this_thread::sleep_for(500ms);
  const Ran r = poise_cli({"estop", "--domain", d, "--wait-ms", "2000"});
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("no robot side"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("ENGAGED"), std::string::npos) << r.output;
  watch.interrupt();
}

// The same for pushes: a reader of poise/disturbance that is not a simulator (a recorder, a
// monitor) does not make `poise push` report a push.
TEST(EStop, APushWithNoSimulatorIsNotReportedDone) {
  const std::string d = std::to_string(poise::testing::unique_domain_id());
  ChildProcess watch({bin("poise"), "topic", "echo", "poise/disturbance", "--domain", d,
                      "--timeout", "60"},
                     {}, false, true);
  std::this_thread::sleep_for(500ms);
  const Ran r = poise_cli({"push", "--domain", d, "--force", "30", "0", "0", "--wait-ms", "2000"});
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("no simulator"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("pushed"), std::string::npos) << r.output;
  watch.interrupt();
}

}  // namespace
