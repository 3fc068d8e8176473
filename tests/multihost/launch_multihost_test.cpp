// `poise launch` across machines: three hosts (network namespaces the test creates: robot =
// simulator, brain = estimator + controller, solver = contact optimiser) started with
// `poise launch FILE --host NAME` from one deployment file, mixed vendors across hosts, and a
// fourth host that only looks (`poise topic list` on the DDS files the launcher generates).
// The forward push (run for 15 s, so that the observer looks while even a lockstep run is on)
// must survive in lockstep and in real time, match the single-machine run of the same scenario
// and vendors (lockstep: to 1e-9; real time: the verdict and the settled CoM error), and no DDS packet may leave the namespaces (packet counters of
// the root namespace's interfaces).
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>
#include <poise/dds/domain_claim.hpp>

#include "child_process.hpp"
#include "netns_hosts.hpp"

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
using poise::testing::NetnsHosts;

Json read_json(const fs::path& p) {
  std::ifstream in(p);
  return in ? Json::parse(in, nullptr, false) : Json();
}

class LaunchMultiHost : public ::testing::TestWithParam<std::string> {};

TEST_P(LaunchMultiHost, ForwardPushSurvivesAcrossThreeHostsAsOnOne) {
  const std::string mode = GetParam();
  NetnsHosts hosts({"robot", "brain", "solver", "observer"}, 78);
  if (const std::string e = hosts.build(); !e.empty()) {
    if (hosts.permission_denied()) GTEST_SKIP() << "needs root: " << e;
    FAIL() << e;
  }
  const fs::path dir = fs::path(POISE_BINARY_DIR) / "test_output" / "launch_multihost" / mode;
  fs::remove_all(dir);
  fs::create_directories(dir);
  const int domain = poise::dds::claim_free_domain();
  const fs::path file = dir / "three_hosts.yaml";
  // Real time: 6 s (the push at 1.0-1.1 s, 5 s of recovery; the observer lists the topics at
  // ~1-4 s). Not 15 s: after this push the robot stands 10 mm higher than before it (lockstep
  // too) in a posture where, in real time, a foot sometimes slides long after the push (one of
  // four 15 s single-machine runs: 14.7 mm at ~6 s, CoM error 5.5 mm; issue #17 item 2).
  // Lockstep is deterministic and runs 15 s.
  const std::string duration = mode == "realtime" ? "6" : "15";
  std::ofstream(file) << "name: three_hosts\n"
                      << "domain: " << domain << "\n"
                      << "scenario: forward_push_double_support\n"
                      << "mode: " << mode << "\n"
                      << "hosts:\n"
                      << "  robot: {address: " << hosts.address("robot") << "}\n"
                      << "  brain: {address: " << hosts.address("brain") << "}\n"
                      << "  solver: {address: " << hosts.address("solver") << "}\n"
                      << "  observer: {address: " << hosts.address("observer") << "}\n"
                      // SCHED_FIFO as on a robot (root: CI; otherwise each component says it
                      // runs normally): without it, 2 of 14 real-time runs on a 2-core machine
                      // failed on a foot slip of 12-20 mm; with it 7 of 7 survived, 3 beside two
                      // busy loops (deploy/deployments/README.md).
                      << "components:\n"
                      << "  sim: {host: robot, dds: fastdds, priority: 60, options: [--duration, "
                      << duration << "]}\n"
                      << "  estimator: {host: brain, dds: cyclone, priority: 57}\n"
                      << "  controller: {host: brain, dds: fastdds, priority: 58}\n"
                      << "  contact: {host: solver, dds: cyclone, priority: 59}\n";
  auto launch = [&](const std::string& host) {
    return std::make_unique<ChildProcess>(
        hosts.exec_in(host, {bin("poise"), "launch", file.string(), "--host", host, "-o",
                             (dir / (host + ".json")).string(), "--log-dir",
                             (dir / (host + ".logs")).string()}),
        std::vector<std::string>{}, false, true);
  };
  const std::uint64_t root_before = NetnsHosts::root_packets();
  auto brain = launch("brain");
  auto solver = launch("solver");
  ASSERT_TRUE(brain->wait_for_output("controller", 30s)) << brain->output();
  ASSERT_TRUE(solver->wait_for_output("contact", 30s)) << solver->output();
  auto robot = launch("robot");
  ASSERT_TRUE(robot->wait_for_output("t=1.0 s", 120s)) << robot->output() << brain->output();

  // The fourth host sees every topic of the loop, on the files the launcher writes for it.
  {
    ChildProcess files(hosts.exec_in("observer", {bin("poise"), "launch", file.string(), "--host",
                                                  "observer", "--dds-files",
                                                  (dir / "observer_dds").string()}),
                       {}, false, true);
    ASSERT_EQ(files.wait_for(20s).value_or(-1), 0) << files.output();
    ChildProcess list(
        hosts.exec_in("observer", {bin("poise"), "topic", "list", "--dds", "cyclone",
                                   "--dds-config", (dir / "observer_dds" / "cyclone.xml").string(),
                                   "--domain", std::to_string(domain), "--wait", "2"}),
        {}, false, true);
    ASSERT_EQ(list.wait_for(30s).value_or(-1), 0) << list.output();
    for (const char* t : {"poise/sensors", "poise/state", "poise/contact_problem",
                          "poise/contact_solution", "poise/joint_command",
                          "poise/robot_description"})
      EXPECT_NE(list.output().find(t), std::string::npos) << t << "\n" << list.output();
  }

  const auto robot_code = robot->wait_for(240s);
  ASSERT_TRUE(robot_code.has_value()) << robot->output();
  EXPECT_EQ(*robot_code, 0) << robot->output();
  EXPECT_EQ(brain->interrupt(20s).value_or(-1), 0) << brain->output();
  EXPECT_EQ(solver->interrupt(20s).value_or(-1), 0) << solver->output();
  const std::uint64_t root_after = NetnsHosts::root_packets();

  const Json r = read_json(dir / "robot.json");
  ASSERT_TRUE(r.is_object()) << robot->output();
  EXPECT_TRUE(r.value("survived", false)) << r.dump(2);
  for (const char* h : {"brain", "solver"}) {
    const Json hr = read_json(dir / (std::string(h) + ".json"));
    EXPECT_FALSE(hr.value("failed", true)) << h << ": " << hr.dump(2);
  }
  // Tens of thousands of DDS packets crossed the bridge; the root namespace's interfaces carried
  // only the machine's own background traffic.
  EXPECT_LT(root_after - root_before, 2000u)
      << "packets on the root namespace's interfaces during the run";

  // The same scenario and vendors on one machine (loopback).
  ChildProcess single({bin("poise"), "run", "forward_push_double_support", "--" + mode,
                       "--duration", duration, "--rt-priority", "60",
                       "--dds-sim", "fastdds", "--dds-estimator", "cyclone", "--dds-controller",
                       "fastdds", "--dds-contact", "cyclone", "-o", (dir / "single.json").string(),
                       "--log-dir", (dir / "single.logs").string()},
                      {}, false, true);
  ASSERT_EQ(single.wait_for(240s).value_or(-1), 0) << single.output();
  const Json one = read_json(dir / "single.json");
  const Json& three = r["sim"];
  const auto number = [](const Json& j, const char* key) {
    return j.contains(key) && j[key].is_number() ? j[key].get<double>() : -1.0;
  };
  std::printf("%s: com_error_max three hosts %.6f m, one machine %.6f m; com_error_final %.6f / "
              "%.6f m; foot slip %.6f / %.6f m; hold ticks %.0f / %.0f, overruns (three hosts) "
              "%.0f, deadline misses (one machine) %.0f (controller %.0f), contact problems "
              "resent (one machine) %.0f\n",
              mode.c_str(), three.value("com_error_max_m", -1.0), one.value("com_error_max_m", -1.0),
              three.value("com_error_final_m", -1.0), one.value("com_error_final_m", -1.0),
              three.value("foot_slip_max_m", -1.0), one.value("foot_slip_max_m", -1.0),
              number(three, "hold_ticks"), number(one, "hold_ticks"), number(three, "overruns"),
              number(one, "deadline_misses"),
              one.contains("deadline_misses_by_node")
                  ? number(one["deadline_misses_by_node"], "controller")
                  : -1.0,
              number(one, "contact_problems_resent"));
  EXPECT_EQ(three.value("survived", false), one.value("survived", true));
  if (mode == "lockstep") {
    // Lockstep is deterministic: the same numbers, wherever the processes run.
    EXPECT_NEAR(three.value("com_error_max_m", -1.0), one.value("com_error_max_m", 1.0), 1e-9);
    EXPECT_NEAR(three.value("foot_slip_max_m", -1.0), one.value("foot_slip_max_m", 1.0), 1e-9);
  } else {
    // Real time depends on the wall clock: which ticks miss their deadline (and are held by the
    // safety layer) differs from run to run, and the CoM error at the push depends on them. On a
    // loaded 2-core machine the single-machine run alone measured 5.5 to 23.9 mm of CoM error max
    // in CI (and three hosts 8.4 to 21.5 mm), so the peak is no measure of "the same result".
    // What must match: the verdict (asserted above: every criterion of the scenario met in both)
    // and where the robot settles once the push is over (final CoM error at the end of the run).
    EXPECT_NEAR(three.value("com_error_final_m", 1.0), one.value("com_error_final_m", -1.0), 0.005);
  }
}

INSTANTIATE_TEST_SUITE_P(Modes, LaunchMultiHost, ::testing::Values("lockstep", "realtime"));

}  // namespace
