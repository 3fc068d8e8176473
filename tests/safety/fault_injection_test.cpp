// Fault semantics (idl/README.md "Fault semantics"), injected into a real poise-estimator process
// by this test, which plays the robot's driver: it publishes the robot description and a
// standing robot's sensor frames at 1 kHz, with one fault per test, and judges what the node
// publishes (poise/state), what its diagnostics say (health, last_error) and its summary.
// The estimator runs on Fast DDS and on Cyclone DDS; the driver is on Cyclone.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <poise/msg/diagnostics.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>

#include "poise/dds/dds.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/robot_description.hpp"
#include "support/child_process.hpp"

namespace {

using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
namespace msg = poise::msg;
namespace dds = poise::dds;

const std::string kRobotYaml = std::string(POISE_SOURCE_DIR) +
                               "/deploy/robots/poise_humanoid/robot.yaml";

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct StateRec {
  std::uint64_t tick;
  std::uint32_t flags;
};
struct DiagRec {
  int health;
  std::string last_error;
};

/// The test's robot driver: description + standing sensor frames, written from the IDL.
class Driver {
 public:
  explicit Driver(int domain)
      : participant_(options(domain)),
        robot_(poise::model::load_robot_config(kRobotYaml)),
        model_(poise::model::load_robot_model(robot_)),
        description_pub_(participant_),
        sensors_pub_(participant_),
        states_(participant_,
                [this](const msg::State& s) {
                  std::lock_guard lock(mutex_);
                  states_rec_.push_back({s.header().tick(), s.status_flags()});
                },
                dds::Qos::reliable(5000)),
        diagnostics_(participant_, [this](const msg::Diagnostics& d) {
          if (d.node().to_string() != "estimator") return;
          std::lock_guard lock(mutex_);
          diag_rec_.push_back({static_cast<int>(d.health()), d.last_error().to_string()});
        }) {
    description_pub_.publish(
        poise::node::describe_robot(robot_, model_, read_file(kRobotYaml), 0.001));
    // A standing robot: nominal posture, IMU at rest, half the weight on each foot.
    frame_.joint_count(static_cast<std::uint32_t>(model_.njoints));
    for (int j = 0; j < model_.njoints; ++j)
      frame_.q()[static_cast<std::size_t>(j)] = robot_.q_nominal[model_.idx_q(j)];
    frame_.imu().orientation_wxyz({1.0, 0.0, 0.0, 0.0});
    for (auto& w : frame_.foot_wrench_F())
      w.force()[2] = 0.5 * model_.total_mass * 9.81;
  }

  int joints() const { return model_.njoints; }

  /// Sends frame k (IMU with fresh seeded noise unless `still`), after `mutate`.
  void send(std::uint64_t k, const std::function<void(msg::Sensors&)>& mutate = {},
            bool still = false) {
    msg::Sensors s = frame_;
    s.header().tick(k);
    s.header().stamp_ns(static_cast<std::int64_t>(k) * 1'000'000);
    if (!still) {
      std::normal_distribution<double> n(0.0, 5e-4);
      for (int a = 0; a < 3; ++a)
        s.imu().angular_velocity_I()[static_cast<std::size_t>(a)] = n(rng_);
    }
    s.imu().specific_force_I()[2] = 9.81;
    if (mutate) mutate(s);
    sensors_pub_.publish(s);
  }

  /// Sends ticks [from, to] at 1 kHz.
  void stream(std::uint64_t from, std::uint64_t to,
              const std::function<void(std::uint64_t, msg::Sensors&)>& mutate = {},
              bool still = false) {
    auto next = std::chrono::steady_clock::now();
    for (std::uint64_t k = from; k <= to; ++k) {
      send(k, mutate ? std::function<void(msg::Sensors&)>([&](msg::Sensors& s) { mutate(k, s); })
                     : std::function<void(msg::Sensors&)>{},
           still);
      next += 1ms;
      std::this_thread::sleep_until(next);
    }
  }

  /// Waits until the estimator answers (tick 1 repeated, as a simulator does at start-up).
  bool connect() {
    if (!sensors_pub_.wait_for_matches(1, 30s)) return false;
    for (int i = 0; i < 300; ++i) {
      send(1);
      std::this_thread::sleep_for(20ms);
      std::lock_guard lock(mutex_);
      if (!states_rec_.empty()) return true;
    }
    return false;
  }

  std::vector<StateRec> states() {
    std::lock_guard lock(mutex_);
    return states_rec_;
  }
  std::vector<DiagRec> diagnostics() {
    std::lock_guard lock(mutex_);
    return diag_rec_;
  }
  bool diagnostics_said(const std::string& text, int health_at_least) {
    for (const auto& d : diagnostics())
      if (d.health >= health_at_least && d.last_error.find(text) != std::string::npos) return true;
    return false;
  }
  void settle() { std::this_thread::sleep_for(300ms); }

 private:
  static dds::DdsOptions options(int domain) {
    dds::DdsOptions o;
    o.vendor = dds::Vendor::cyclone;
    o.domain_id = domain;
    o.participant_name = "fault_injection_driver";
    return o;
  }
  dds::Participant participant_;
  poise::model::RobotConfig robot_;
  poise::model::Model model_;
  dds::Publisher<msg::RobotDescription> description_pub_;
  dds::Publisher<msg::Sensors> sensors_pub_;
  msg::Sensors frame_;
  std::mt19937 rng_{42};
  std::mutex mutex_;
  std::vector<StateRec> states_rec_;
  std::vector<DiagRec> diag_rec_;
  dds::Subscriber<msg::State> states_;
  dds::Subscriber<msg::Diagnostics> diagnostics_;
};

class FaultInjection : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    domain_ = poise::testing::unique_domain_id();
    summary_ = ::testing::TempDir() + "fault_estimator_" + GetParam() + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".json";
    std::replace(summary_.begin(), summary_.end(), '/', '_');
    summary_ = ::testing::TempDir() + summary_.substr(::testing::TempDir().size());
    driver_ = std::make_unique<Driver>(domain_);
    std::vector<std::string> argv{bin("poise-estimator"), "--dds",     GetParam(), "--domain",
                                  std::to_string(domain_),  "--summary", summary_};
    // The forged-tick test needs the stream live when the forged tick comes: with the default
    // 20 ms of silence a 1 kHz test driver descheduled for 20 ms on a loaded CI machine (ctest
    // -j2) made the forged tick a stream restart (seen once, 2026-12-05). 1 s is live by any
    // measure; the silence rule itself is the driver-restart test's (a 400 ms pause).
    const std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    if (name.find("AForgedFutureTick") != std::string::npos)
      argv.insert(argv.end(), {"--restart-silence-ms", "1000"});
    estimator_ = std::make_unique<ChildProcess>(argv, std::vector<std::string>{}, false, true);
    ASSERT_TRUE(driver_->connect()) << estimator_->output();
  }
  nlohmann::json finish() {
    driver_->settle();
    estimator_->interrupt(5s);
    std::ifstream in(summary_);
    EXPECT_TRUE(in.good()) << estimator_->output();
    return in.good() ? nlohmann::json::parse(in) : nlohmann::json::object();
  }
  static bool has_tick(const std::vector<StateRec>& s, std::uint64_t k) {
    return std::any_of(s.begin(), s.end(), [&](const StateRec& r) { return r.tick == k; });
  }

  int domain_ = 0;
  std::string summary_;
  std::unique_ptr<Driver> driver_;
  std::unique_ptr<ChildProcess> estimator_;
};

TEST_P(FaultInjection, AForgedFutureTickIsRejectedAndTheStreamGoesOn) {
  const std::uint64_t forged = 1'000'000'000'000ULL;
  driver_->stream(2, 400, [&](std::uint64_t k, msg::Sensors&) {
    if (k == 200) driver_->send(forged);
  });
  const auto j = finish();
  const auto states = driver_->states();
  EXPECT_FALSE(has_tick(states, forged));
  int answered = 0;
  for (std::uint64_t k = 2; k <= 400; ++k)
    answered += has_tick(states, k);
  EXPECT_GE(answered, 390) << estimator_->output();
  EXPECT_EQ(j["out_of_sequence"], 1);
  EXPECT_EQ(j["stream_restarts"], 0);
  EXPECT_TRUE(driver_->diagnostics_said("out of sequence", msg::HEALTH_DEGRADED))
      << estimator_->output();
}

TEST_P(FaultInjection, ADriverRestartIsSeenStaleThenFollowedFromItsNewTicks) {
  driver_->stream(2, 400);
  std::this_thread::sleep_for(400ms);  // the driver is down: stale
  const std::size_t before = driver_->states().size();  // every state of the old stream is in
  EXPECT_TRUE(driver_->diagnostics_said("no poise/sensors for", msg::HEALTH_FAULT))
      << estimator_->output();
  driver_->stream(1, 300);  // back, counting from 1 again
  const auto j = finish();
  const auto states = driver_->states();
  ASSERT_GT(states.size(), before + 280) << estimator_->output();
  EXPECT_EQ(states[before].tick, 1u);
  EXPECT_NE(states[before].flags & msg::STATE_INITIALIZING, 0u);  // re-initialised
  for (std::size_t i = before; i < states.size(); ++i)
    EXPECT_LE(states[i].tick, 300u);  // never an old estimate under a new tick
  EXPECT_EQ(j["stream_restarts"], 1);
  EXPECT_GE(j["stale_events"].get<int>(), 1);  // the pause (and the end of the test)
  EXPECT_NE(estimator_->output().find("sensor stream restarted at tick 1 (previous 400)"),
            std::string::npos)
      << estimator_->output();
}

TEST_P(FaultInjection, AFrozenImuIsReportedDegradedAndFlaggedOnTheState) {
  driver_->stream(2, 100);
  driver_->stream(101, 300, {}, /*still=*/true);  // bit-identical IMU samples
  EXPECT_TRUE(driver_->diagnostics_said("IMU frozen", msg::HEALTH_DEGRADED))
      << estimator_->output();
  driver_->stream(301, 500);  // the IMU is back
  finish();
  const auto states = driver_->states();
  bool frozen_flag = false, cleared = false;
  for (const auto& s : states) {
    if (s.tick > 150 && s.tick <= 300) frozen_flag |= (s.flags & msg::STATE_IMU_FROZEN) != 0;
    if (s.tick > 400) cleared |= (s.flags & msg::STATE_IMU_FROZEN) == 0;
  }
  EXPECT_TRUE(frozen_flag);
  EXPECT_TRUE(cleared);
  EXPECT_NE(estimator_->output().find("cleared: IMU frozen"), std::string::npos)
      << estimator_->output();
}

TEST_P(FaultInjection, AWrongJointCountGetsNoStateAndIsNamed) {
  const auto n = static_cast<std::uint32_t>(driver_->joints());
  driver_->stream(2, 300, [&](std::uint64_t k, msg::Sensors& s) {
    if (k > 100 && k <= 150) s.joint_count(n - 1);
  });
  finish();
  const auto states = driver_->states();
  for (std::uint64_t k = 101; k <= 150; ++k)
    EXPECT_FALSE(has_tick(states, k)) << k;
  EXPECT_TRUE(has_tick(states, 151));
  EXPECT_TRUE(has_tick(states, 300));
  EXPECT_TRUE(driver_->diagnostics_said("joint_count " + std::to_string(n - 1),
                                        msg::HEALTH_DEGRADED))
      << estimator_->output();
}

TEST_P(FaultInjection, ANonFiniteSampleGetsNoStateAndItsFieldIsInLastError) {
  driver_->stream(2, 200, [&](std::uint64_t k, msg::Sensors& s) {
    if (k == 100) s.q()[3] = std::numeric_limits<double>::quiet_NaN();
  });
  const auto j = finish();
  const auto states = driver_->states();
  EXPECT_FALSE(has_tick(states, 100));
  EXPECT_TRUE(has_tick(states, 99));
  EXPECT_TRUE(has_tick(states, 101));
  EXPECT_TRUE(driver_->diagnostics_said("q[3]", msg::HEALTH_DEGRADED)) << estimator_->output();
  EXPECT_GE(j["diagnostics"]["rejected_samples"].get<int>(), 1);
}

INSTANTIATE_TEST_SUITE_P(Vendors, FaultInjection, ::testing::Values("cyclone", "fastdds"),
                         [](const auto& info) { return info.param; });

}  // namespace
