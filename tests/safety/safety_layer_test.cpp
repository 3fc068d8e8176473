// The robot-side safety layer (components/safety) and the input tick rule every node applies
// (node::TickSequencer): unit tests with a fake clock and seeded random commands.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <Eigen/Geometry>

#include <algorithm>

#include "poise/model/centroidal.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/tick_sequencer.hpp"
#include "poise/safety/safety_layer.hpp"
#include "poise/safety/writer_gate.hpp"

namespace {

using poise::node::TickSequencer;
using poise::safety::Command;
using poise::safety::Config;
using poise::safety::Mode;
using poise::safety::SafetyLayer;
using Verdict = TickSequencer::Verdict;

constexpr std::int64_t kMs = 1'000'000;

Config small_config(int n) {
  Config c;
  for (int i = 0; i < n; ++i) {
    std::string name = std::to_string(i);  // "j" + name: GCC 12's false -Wrestrict warning
    name.insert(name.begin(), 'j');
    c.joint_names.push_back(name);
  }
  c.hold_kp = Eigen::VectorXd::Constant(n, 100.0);
  c.hold_kd = Eigen::VectorXd::Constant(n, 2.0);
  c.damping_kd = Eigen::VectorXd::Constant(n, 5.0);
  c.effort = Eigen::VectorXd::Constant(n, 50.0);
  c.q_min = Eigen::VectorXd::Constant(n, -1.0);
  c.q_max = Eigen::VectorXd::Constant(n, 1.0);
  c.watchdog_s = 0.005;
  c.hold_s = 1.0;
  return c;
}

poise::msg::JointCommand random_command(int n, std::uint64_t tick, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-0.9, 0.9);
  poise::msg::JointCommand c;
  c.header().tick(tick);
  c.mode(poise::msg::COMMAND_TORQUE);
  c.joint_count(static_cast<std::uint32_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto j = static_cast<std::size_t>(i);
    c.tau_ff()[j] = 40.0 * u(rng);
    c.q_ref()[j] = u(rng);
    c.qd_ref()[j] = u(rng);
    c.kp()[j] = 100.0 * (1.0 + u(rng));
    c.kd()[j] = 2.0 * (1.0 + u(rng));
  }
  return c;
}

void expect_command_equals(const Command& got, const poise::msg::JointCommand& want, int n) {
  for (int i = 0; i < n; ++i) {
    const auto j = static_cast<std::size_t>(i);
    EXPECT_EQ(got.tau_ff[i], want.tau_ff()[j]);
    EXPECT_EQ(got.q_ref[i], want.q_ref()[j]);
    EXPECT_EQ(got.qd_ref[i], want.qd_ref()[j]);
    EXPECT_EQ(got.kp[i], want.kp()[j]);
    EXPECT_EQ(got.kd[i], want.kd()[j]);
  }
}

TEST(SafetyLayer, StartupHoldsTheStartPostureUntilTheFirstCommand) {
  const int n = 6;
  SafetyLayer s(small_config(n));
  std::mt19937 rng(1);
  const Eigen::VectorXd q0 = Eigen::VectorXd::Random(n) * 0.5;
  s.start(q0, 0);
  for (std::int64_t t = 0; t < 100 * kMs; t += kMs) {  // no watchdog before the first command
    const Command& c = s.update(t, q0);
    ASSERT_EQ(s.mode(), Mode::kStartup);
    EXPECT_EQ(c.q_ref, q0);
    EXPECT_EQ(c.kp, s.config().hold_kp);
    EXPECT_EQ(c.kd, s.config().hold_kd);
    EXPECT_TRUE(c.tau_ff.isZero());
  }
  const auto cmd = random_command(n, 7, rng);
  ASSERT_TRUE(s.on_command(cmd, 7, 100 * kMs));
  expect_command_equals(s.update(100 * kMs, q0), cmd, n);
  EXPECT_EQ(s.mode(), Mode::kActive);
}

TEST(SafetyLayer, StaleCommandsHoldTheLastTargetsThenDampThenResume) {
  const int n = 5;
  SafetyLayer s(small_config(n));
  std::mt19937 rng(2);
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(n);
  s.start(q, 0);
  std::int64_t t = 0;
  poise::msg::JointCommand last;
  for (std::uint64_t k = 1; k <= 50; ++k, t += kMs) {  // 1 kHz commands
    last = random_command(n, k, rng);
    ASSERT_TRUE(s.on_command(last, static_cast<std::int64_t>(k), t));
    ASSERT_EQ(s.update(t, q).tick, static_cast<std::int64_t>(k));
  }
  const std::int64_t t_last = t - kMs;
  // Within the watchdog: still ACTIVE. Just past it: HOLD of the last targets.
  s.update(t_last + 5 * kMs, q);
  EXPECT_EQ(s.mode(), Mode::kActive);
  const Command& hold = s.update(t_last + 5 * kMs + 1, q);
  ASSERT_EQ(s.mode(), Mode::kHold);
  EXPECT_EQ(s.counters().hold_events, 1u);
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(hold.q_ref[i], last.q_ref()[static_cast<std::size_t>(i)]);
    EXPECT_EQ(hold.tau_ff[i], last.tau_ff()[static_cast<std::size_t>(i)]);
    EXPECT_EQ(hold.qd_ref[i], 0.0);
    EXPECT_EQ(hold.kp[i], 100.0);
    EXPECT_EQ(hold.kd[i], 2.0);
  }
  EXPECT_NE(std::string(s.last_error()).find("HOLD"), std::string::npos);
  // hold_s later: DAMP, tau = -kd qd only.
  const std::int64_t t_hold = t_last + 5 * kMs + 1;
  s.update(t_hold + 1000 * kMs, q);
  EXPECT_EQ(s.mode(), Mode::kHold);
  const Command& damp = s.update(t_hold + 1000 * kMs + 1, q);
  ASSERT_EQ(s.mode(), Mode::kDamp);
  EXPECT_TRUE(damp.kp.isZero());
  EXPECT_TRUE(damp.tau_ff.isZero());
  EXPECT_TRUE(damp.qd_ref.isZero());
  EXPECT_EQ(damp.kd, s.config().damping_kd);
  // A fresh command resumes control.
  const std::int64_t t_back = t_hold + 2000 * kMs;
  const auto cmd = random_command(n, 3000, rng);
  ASSERT_TRUE(s.on_command(cmd, 3000, t_back));
  expect_command_equals(s.update(t_back, q), cmd, n);
  EXPECT_EQ(s.mode(), Mode::kActive);
}

// hold_s = 0 means no hold: the tick the watchdog fires already damps (before, that tick was a
// one-tick HOLD, and a robot whose commands were each just stale never damped at all: the test
// of `poise run --hold-s 0` then depended on the machine's timing).
TEST(SafetyLayer, ZeroHoldDampsOnTheTickTheWatchdogFires) {
  const int n = 4;
  Config c = small_config(n);
  c.hold_s = 0.0;
  SafetyLayer s(c);
  std::mt19937 rng(5);
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(n);
  s.start(q, 0);
  // Commands each arriving 6 ms after the last (watchdog 5 ms): every update just before a
  // command is stale, and must damp; the command then resumes ACTIVE.
  std::int64_t t = 0;
  for (std::uint64_t k = 1; k <= 20; ++k) {
    ASSERT_TRUE(s.on_command(random_command(n, k, rng), static_cast<std::int64_t>(k), t));
    s.update(t, q);
    ASSERT_EQ(s.mode(), Mode::kActive) << k;
    t += 6 * kMs;
    const Command& d = s.update(t - kMs / 2, q);
    ASSERT_EQ(s.mode(), Mode::kDamp) << k;
    EXPECT_TRUE(d.kp.isZero());
    EXPECT_EQ(d.kd, s.config().damping_kd);
  }
  EXPECT_EQ(s.counters().damp_events, 20u);
  EXPECT_EQ(s.counters().ticks_hold, 0u);
  // Within the watchdog nothing changes.
  ASSERT_TRUE(s.on_command(random_command(n, 99, rng), 99, t));
  s.update(t + 5 * kMs, q);
  EXPECT_EQ(s.mode(), Mode::kActive);
}

TEST(SafetyLayer, HoldAfterADampingCommandKeepsThePostureNow) {
  const int n = 3;
  SafetyLayer s(small_config(n));
  poise::msg::JointCommand damping;
  damping.header().tick(1);
  damping.mode(poise::msg::COMMAND_DAMPING);
  damping.joint_count(n);
  for (int i = 0; i < n; ++i)
    damping.kd()[static_cast<std::size_t>(i)] = 1.0;
  const Eigen::VectorXd q = Eigen::Vector3d(0.1, -0.2, 0.3);
  s.start(Eigen::VectorXd::Zero(n), 0);
  ASSERT_TRUE(s.on_command(damping, 1, 0));
  const Command& c = s.update(0, q);
  EXPECT_TRUE(c.kp.isZero());
  EXPECT_EQ(c.kd, Eigen::VectorXd::Ones(n));
  const Command& hold = s.update(10 * kMs, q);
  ASSERT_EQ(s.mode(), Mode::kHold);
  EXPECT_EQ(hold.q_ref, q);
  EXPECT_TRUE(hold.tau_ff.isZero());
}

TEST(SafetyLayer, BadCommandsAreRejectedByReasonAndNeverApplied) {
  const int n = 8;
  std::mt19937 rng(3);
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(n);
  struct Case {
    const char* what;
    void (*mutate)(poise::msg::JointCommand&, std::size_t joint);
    std::int64_t robot_tick;
    const char* message;
  };
  const Case cases[] = {
      {"joint_count", [](poise::msg::JointCommand& c, std::size_t) { c.joint_count(7); }, 10,
       "joint_count 7"},
      {"NaN tau_ff", [](poise::msg::JointCommand& c, std::size_t j) {
         c.tau_ff()[j] = std::numeric_limits<double>::quiet_NaN(); }, 10, "non-finite"},
      {"inf q_ref", [](poise::msg::JointCommand& c, std::size_t j) {
         c.q_ref()[j] = std::numeric_limits<double>::infinity(); }, 10, "non-finite"},
      {"negative kp", [](poise::msg::JointCommand& c, std::size_t j) { c.kp()[j] = -1.0; }, 10,
       "negative gain"},
      {"huge kd", [](poise::msg::JointCommand& c, std::size_t j) { c.kd()[j] = 1e6; }, 10,
       "hold gain"},
      {"q_ref beyond limits", [](poise::msg::JointCommand& c, std::size_t j) { c.q_ref()[j] = 1.2; },
       10, "outside its limits"},
      {"tau_ff beyond effort", [](poise::msg::JointCommand& c, std::size_t j) {
         c.tau_ff()[j] = 150.0; }, 10, "effort limit"},
      {"future tick", [](poise::msg::JointCommand& c, std::size_t) { c.header().tick(11); }, 10,
       "future"},
      {"old tick", [](poise::msg::JointCommand& c, std::size_t) { c.header().tick(1); }, 30,
       "too old"},
  };
  for (const Case& bad : cases) {
    SCOPED_TRACE(bad.what);
    SafetyLayer s(small_config(n));
    s.start(q, 0);
    const auto good = random_command(n, 10, rng);
    ASSERT_TRUE(s.on_command(good, 10, 0));
    const std::size_t joint = std::uniform_int_distribution<std::size_t>(0, n - 1)(rng);
    auto c = random_command(n, 10, rng);
    bad.mutate(c, joint);
    EXPECT_FALSE(s.on_command(c, bad.robot_tick, kMs));
    EXPECT_EQ(s.counters().rejected, 1u);
    EXPECT_NE(std::string(s.last_error()).find(bad.message), std::string::npos) << s.last_error();
    const bool names_a_joint = std::string(bad.what) != "joint_count" &&
                               std::string(bad.what).find("tick") == std::string::npos;
    if (names_a_joint) {
      EXPECT_NE(std::string(s.last_error()).find("j" + std::to_string(joint)), std::string::npos)
          << s.last_error();
    }
    expect_command_equals(s.update(kMs, q), good, n);  // the good one still applies
    // ... and the rejected one does not refresh the watchdog.
    s.update(6 * kMs, q);
    EXPECT_EQ(s.mode(), Mode::kHold);
  }
}

TEST(SafetyLayer, EStopDampsIgnoresCommandsAndIsLatchedUntilReleased) {
  const int n = 4;
  SafetyLayer s(small_config(n));
  std::mt19937 rng(4);
  const Eigen::VectorXd q = Eigen::Vector4d(0.1, 0.2, 0.3, 0.4);
  s.start(Eigen::VectorXd::Zero(n), 0);
  ASSERT_TRUE(s.on_command(random_command(n, 1, rng), 1, 0));
  s.on_estop(true, poise::safety::Stop::kEmergencyDamp, "operator pressed the button", q, kMs);
  ASSERT_EQ(s.mode(), Mode::kEStop);
  EXPECT_NE(std::string(s.last_error()).find("operator pressed the button"), std::string::npos);
  for (std::uint64_t k = 2; k < 20; ++k) {  // fresh commands do not release it
    EXPECT_FALSE(s.on_command(random_command(n, k, rng), static_cast<std::int64_t>(k),
                              static_cast<std::int64_t>(k) * kMs));
    const Command& c = s.update(static_cast<std::int64_t>(k) * kMs, q);
    EXPECT_EQ(s.mode(), Mode::kEStop);
    EXPECT_TRUE(c.kp.isZero());
    EXPECT_TRUE(c.tau_ff.isZero());
  }
  EXPECT_EQ(s.counters().ignored_estop, 18u);
  EXPECT_EQ(s.counters().rejected, 0u);
  s.on_estop(false, poise::safety::Stop::kEmergencyDamp, "", q, 30 * kMs);
  const Command& held = s.update(30 * kMs, q);
  ASSERT_EQ(s.mode(), Mode::kHold);
  EXPECT_EQ(held.q_ref, q);
  const auto cmd = random_command(n, 31, rng);
  ASSERT_TRUE(s.on_command(cmd, 31, 31 * kMs));
  expect_command_equals(s.update(31 * kMs, q), cmd, n);
}

// A protective stop (category 2) holds the posture at the stop with the hold gains and the
// feed-forward that was carrying it, ignores commands, never times out into DAMP, and is
// released into HOLD. An emergency stop takes over from it; it never eases an emergency stop.
TEST(SafetyLayer, AProtectiveStopHoldsThePostureWithoutTimeLimitAndNeverEasesAnEStop) {
  using poise::safety::Stop;
  const int n = 4;
  Config config = small_config(n);
  config.hold_s = 0.5;
  SafetyLayer s(config);
  std::mt19937 rng(6);
  const Eigen::VectorXd q = Eigen::Vector4d(0.1, -0.2, 0.3, -0.4);
  s.start(Eigen::VectorXd::Zero(n), 0);
  const auto carrying = random_command(n, 1, rng);
  ASSERT_TRUE(s.on_command(carrying, 1, kMs));
  s.on_estop(true, Stop::kProtectiveHold, "cell door opened", q, 2 * kMs);
  ASSERT_EQ(s.mode(), Mode::kProtectiveStop);
  EXPECT_TRUE(s.stopped());
  EXPECT_NE(std::string(s.last_error()).find("cell door opened"), std::string::npos);
  const std::int64_t ten_hold_times = 5000;  // ms: ten times hold_s
  for (std::int64_t k = 3; k < ten_hold_times; ++k) {
    EXPECT_FALSE(s.on_command(random_command(n, static_cast<std::uint64_t>(k), rng), k, k * kMs));
    const Command& c = s.update(k * kMs, q);
    ASSERT_EQ(s.mode(), Mode::kProtectiveStop) << "tick " << k;
    if (k == 3) {
      EXPECT_EQ(c.q_ref, q);  // the posture at the stop, not the command's targets
      EXPECT_TRUE(c.qd_ref.isZero());
      EXPECT_EQ(c.kp, config.hold_kp);
      EXPECT_EQ(c.kd, config.hold_kd);
      for (int i = 0; i < n; ++i)  // the feed-forward that carried the robot
        EXPECT_DOUBLE_EQ(c.tau_ff[i], carrying.tau_ff()[static_cast<std::size_t>(i)]);
    }
  }
  EXPECT_EQ(s.counters().damp_events, 0u);
  EXPECT_EQ(s.counters().protective_stop_events, 1u);
  EXPECT_EQ(s.counters().ticks_protective_stop, static_cast<std::uint64_t>(ten_hold_times - 3));
  // Asked again: nothing changes. An emergency stop takes over at once.
  s.on_estop(true, Stop::kProtectiveHold, "again", q, ten_hold_times * kMs);
  EXPECT_EQ(s.counters().protective_stop_events, 1u);
  s.on_estop(true, Stop::kEmergencyDamp, "fell against the door", q, ten_hold_times * kMs);
  ASSERT_EQ(s.mode(), Mode::kEStop);
  EXPECT_TRUE(s.update(ten_hold_times * kMs, q).kp.isZero());
  // A protective request does not ease the emergency stop into a hold.
  s.on_estop(true, Stop::kProtectiveHold, "ease it", q, (ten_hold_times + 1) * kMs);
  EXPECT_EQ(s.mode(), Mode::kEStop);
  EXPECT_EQ(s.counters().refused_protective_stops, 1u);
  EXPECT_NE(std::string(s.last_error()).find("release it first"), std::string::npos);
  // Released: HOLD of the posture now, until a fresh command.
  s.on_estop(false, Stop::kEmergencyDamp, "", q, (ten_hold_times + 2) * kMs);
  EXPECT_EQ(s.mode(), Mode::kHold);
  // A protective stop released goes on holding its posture, into HOLD.
  s.on_estop(true, Stop::kProtectiveHold, "", q, (ten_hold_times + 3) * kMs);
  const Eigen::VectorXd moved = q * 2.0;
  s.on_estop(false, Stop::kProtectiveHold, "", moved, (ten_hold_times + 4) * kMs);
  ASSERT_EQ(s.mode(), Mode::kHold);
  EXPECT_EQ(s.update((ten_hold_times + 4) * kMs, moved).q_ref, q);
  // The wire's kinds: an unknown value reads as the emergency stop.
  EXPECT_EQ(poise::safety::to_stop(poise::msg::STOP_PROTECTIVE_HOLD), Stop::kProtectiveHold);
  EXPECT_EQ(poise::safety::to_stop(poise::msg::STOP_EMERGENCY_DAMP), Stop::kEmergencyDamp);
  EXPECT_EQ(poise::safety::to_stop(static_cast<poise::msg::StopKind>(7)), Stop::kEmergencyDamp);
}

TEST(SafetyLayer, EvaluateIsTheCommandLawClampedToTheEffortLimits) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = 10;
  Command c;
  c.resize(n);
  Eigen::VectorXd q(n), qd(n), effort(n), tau(n);
  for (int i = 0; i < n; ++i) {
    c.tau_ff[i] = 20 * u(rng);
    c.q_ref[i] = u(rng);
    c.qd_ref[i] = u(rng);
    c.kp[i] = 50 * (1 + u(rng));
    c.kd[i] = 1 + u(rng);
    q[i] = u(rng);
    qd[i] = u(rng);
    effort[i] = 30 + 10 * u(rng);
  }
  poise::safety::evaluate(c, q, qd, effort, tau);
  for (int i = 0; i < n; ++i) {
    const double law = c.tau_ff[i] + c.kp[i] * (c.q_ref[i] - q[i]) + c.kd[i] * (c.qd_ref[i] - qd[i]);
    EXPECT_DOUBLE_EQ(tau[i], std::max(-effort[i], std::min(effort[i], law)));
  }
}

// One revolute joint carrying a link of known inertia about the joint axis.
std::string pendulum_urdf(double izz, double mass, double com_offset) {
  return R"(<robot name="pendulum">
  <link name="base"><inertial><mass value="10"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="hand"><inertial><origin xyz=")" + std::to_string(com_offset) + R"( 0 0"/><mass value=")" +
         std::to_string(mass) + R"("/><inertia ixx="1e-4" iyy="1e-4" izz=")" + std::to_string(izz) +
         R"(" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="wrist" type="revolute"><parent link="base"/><child link="hand"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="5" velocity="10"/></joint>
</robot>)";
}

/// Semi-implicit Euler (Bullet's integrator) of J qdd = -kp q - kd qd from q = 0.1 for 2 s:
/// returns max |q| over the last second.
double simulate_pd(double inertia, double kp, double kd, double dt) {
  double q = 0.1, v = 0.0, late = 0.0;
  const int steps = static_cast<int>(2.0 / dt);
  for (int i = 0; i < steps; ++i) {
    v += dt * (-kp * q - kd * v) / inertia;
    q += dt * v;
    if (!std::isfinite(q) || std::abs(q) > 1e6) return std::numeric_limits<double>::infinity();
    if (i > steps / 2) late = std::max(late, std::abs(q));
  }
  return late;
}

TEST(SafetyConfig, HoldGainsAreBoundedByEachJointsInertiaSoALightWristStaysStable) {
  const double dt = 0.001;
  // I about the axis = izz + m r^2 (parallel axis): 1e-4 + 0.01 * 0.02^2 = 1.04e-4 kg m^2.
  const double izz = 1e-4, m = 0.01, r = 0.02, inertia = izz + m * r * r;
  const poise::model::Model model =
      poise::model::build_model_from_urdf_string(pendulum_urdf(izz, m, r), "pendulum");
  const Config c = poise::safety::make_config(model, nullptr, {"wrist"}, dt, 10.0);
  EXPECT_NEAR(c.hold_kd[0], 0.5 * inertia / dt, 1e-9);
  EXPECT_NEAR(c.hold_kp[0], std::min(100.0, 0.2 * inertia / (dt * dt)), 1e-9);
  EXPECT_NEAR(c.damping_kd[0], 0.5 * inertia / dt, 1e-9);
  EXPECT_EQ(c.effort[0], 5.0);
  EXPECT_EQ(c.q_min[0], -1.0);
  // The bounded gains settle; the old constant start-up gains (kp 400, kd 10) diverge.
  EXPECT_LT(simulate_pd(inertia, c.hold_kp[0], c.hold_kd[0], dt), 1e-3);
  EXPECT_GT(simulate_pd(inertia, 400.0, 10.0, dt), 1.0);
  EXPECT_LT(simulate_pd(inertia, c.hold_kp[0], c.damping_kd[0], dt), 1e-3);
}

// The robot's potential energy -M g.c after turning joint j's load by `angle` about the joint
// axis: a joint between the base and a foot turns the rest of the robot about the axis with the
// foot fixed (the base pose turns, q_j takes the opposite turn); any other joint turns its subtree.
double potential_after_turn(const poise::model::Model& model, const Eigen::VectorXd& q, int j,
                            bool foot_side, double angle) {
  poise::model::Data data(model);
  poise::model::forward_kinematics(model, data, q);
  Eigen::VectorXd turned = q;
  if (foot_side) {
    const auto& X = data.oMi[static_cast<std::size_t>(j + 1)];
    const Eigen::Vector3d a = X.R * model.axis[static_cast<std::size_t>(j + 1)];
    const Eigen::AngleAxisd turn(angle, a);
    turned.head<3>() = X.p + turn * (q.head<3>() - X.p);
    const Eigen::Quaterniond base(q[6], q[3], q[4], q[5]);
    const Eigen::Quaterniond rotated = Eigen::Quaterniond(turn) * base;
    turned.segment<4>(3) << rotated.x(), rotated.y(), rotated.z(), rotated.w();
    turned[model.idx_q(j)] -= angle;
  } else {
    turned[model.idx_q(j)] += angle;
  }
  poise::model::center_of_mass(model, data, turned);
  return -model.total_mass * model.gravity.dot(data.com);
}

// gravity_stiffness against the second derivative of the potential energy (central differences)
// of the robot turned about each joint, at seeded random postures around the nominal one.
TEST(SafetyConfig, GravityStiffnessIsTheCurvatureOfThePotentialEnergy) {
  const auto robot = poise::model::load_robot_config(std::string(POISE_SOURCE_DIR) +
                                                     "/deploy/robots/poise_humanoid/robot.yaml");
  const auto model = poise::model::load_robot_model(robot);
  std::vector<bool> foot_side(static_cast<std::size_t>(model.njoints), false);
  for (const auto& foot : robot.feet) {
    const int f = model.frames[static_cast<std::size_t>(model.frame_id(foot.link))].body;
    for (int j = 0; j < model.njoints; ++j)
      if (f >= j + 1 && f <= model.subtree_end[static_cast<std::size_t>(j + 1)])
        foot_side[static_cast<std::size_t>(j)] = true;
  }
  ASSERT_EQ(std::count(foot_side.begin(), foot_side.end(), true), 12);  // two legs of six
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  const double h = 1e-3;
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd q = robot.q_nominal;
    for (int j = 0; j < model.njoints; ++j)
      q[model.idx_q(j)] += trial == 0 ? 0.0 : u(rng);
    const Eigen::Quaterniond tilt(Eigen::AngleAxisd(trial == 0 ? 0.0 : u(rng), Eigen::Vector3d::UnitX()) *
                                  Eigen::AngleAxisd(trial == 0 ? 0.0 : u(rng), Eigen::Vector3d::UnitY()));
    q.segment<4>(3) << tilt.x(), tilt.y(), tilt.z(), tilt.w();
    const Eigen::VectorXd k = poise::safety::gravity_stiffness(model, &robot, q);
    for (int j = 0; j < model.njoints; ++j) {
      const bool fs = foot_side[static_cast<std::size_t>(j)];
      const double curvature = (potential_after_turn(model, q, j, fs, h) -
                                2.0 * potential_after_turn(model, q, j, fs, 0.0) +
                                potential_after_turn(model, q, j, fs, -h)) / (h * h);
      EXPECT_NEAR(k[j], -curvature, 1e-3 * std::max(1.0, std::abs(k[j])))
          << "trial " << trial << " joint " << model.joint_names[static_cast<std::size_t>(j)];
    }
  }
  // Upright at the nominal posture, the ankles carry an inverted pendulum: m g h of the robot
  // minus its foot, h the height of that load's CoM over the ankle.
  const Eigen::VectorXd k = poise::safety::gravity_stiffness(model, &robot, robot.q_nominal);
  EXPECT_GT(k[model.joint_index("l_ankle_pitch")], 300.0);
  EXPECT_LT(k[model.joint_index("l_elbow")], 0.0);  // a hanging forearm is a stable pendulum
}

TEST(SafetyConfig, TheShippedHumanoidKeepsItsGainsWhereTheyHoldItsLoad) {
  const auto robot = poise::model::load_robot_config(std::string(POISE_SOURCE_DIR) +
                                                     "/deploy/robots/poise_humanoid/robot.yaml");
  const auto model = poise::model::load_robot_model(robot);
  const Config c = poise::safety::make_config(model, &robot, model.joint_names, 0.001, 5.0);
  const Eigen::VectorXd kg = poise::safety::gravity_stiffness(model, &robot, robot.q_nominal);
  for (std::size_t j = 0; j < model.joint_names.size(); ++j) {
    SCOPED_TRACE(model.joint_names[j]);
    const auto w = static_cast<Eigen::Index>(j);
    EXPECT_DOUBLE_EQ(c.hold_kp[w], std::max(robot.gains[j].kp, 2.0 * kg[w]));
    EXPECT_DOUBLE_EQ(c.hold_kd[static_cast<Eigen::Index>(j)], robot.gains[j].kd);
  }
  EXPECT_THROW(poise::safety::make_config(model, &robot, {"no_such_joint"}, 0.001, 5.0),
               poise::model::ModelError);
}

// ---- TickSequencer --------------------------------------------------------------------------

TEST(TickSequencer, FollowsRepeatsAndGapsOfOneStream) {
  TickSequencer s;
  EXPECT_EQ(s.accept(0, 0), Verdict::kFirst);
  EXPECT_EQ(s.accept(0, kMs), Verdict::kRepeat);
  for (std::uint64_t k = 1; k < 100; ++k)
    ASSERT_EQ(s.accept(k, static_cast<std::int64_t>(k) * kMs), Verdict::kNext);
  EXPECT_EQ(s.accept(150, 150 * kMs), Verdict::kNext);
  EXPECT_EQ(s.dropped(), 50u);
  EXPECT_EQ(s.rejected(), 0u);
}

TEST(TickSequencer, ASingleForgedTickInALiveStreamIsRejected) {
  std::mt19937 rng(6);
  for (std::uint64_t forged : {std::uint64_t{1'000'000'000'000}, std::uint64_t{1},
                               std::uint64_t{0}, std::uint64_t{400 + 1001}}) {
    SCOPED_TRACE(forged);
    TickSequencer s;
    std::int64_t t = 0;
    std::uint64_t k = 100;
    for (; k < 400; ++k, t += kMs)
      ASSERT_NE(s.accept(k, t), Verdict::kOutOfSequence);
    EXPECT_EQ(s.accept(forged, t), Verdict::kOutOfSequence);
    for (; k < 800; ++k, t += kMs)
      ASSERT_EQ(s.accept(k, t), Verdict::kNext) << k;
    EXPECT_EQ(s.rejected(), 1u);
    EXPECT_EQ(s.restarts(), 0u);
  }
}

TEST(TickSequencer, ARestartedStreamIsFollowedAfterSilenceOrConfirmation) {
  {  // the old robot stopped: its first frame after 20 ms of silence restarts the stream
    TickSequencer s;
    for (std::uint64_t k = 1; k <= 5000; ++k)
      s.accept(k, static_cast<std::int64_t>(k) * kMs);
    EXPECT_EQ(s.accept(0, 5000 * kMs + 10 * kMs), Verdict::kOutOfSequence);  // 10 ms: not yet
    EXPECT_EQ(s.accept(0, 5000 * kMs + 21 * kMs), Verdict::kRestart);
    EXPECT_EQ(s.previous(), 5000u);
    EXPECT_EQ(s.accept(0, 5000 * kMs + 121 * kMs), Verdict::kRepeat);  // lockstep's repeats of 0
    EXPECT_EQ(s.accept(1, 5000 * kMs + 122 * kMs), Verdict::kNext);
  }
  {  // without silence: `confirm` consecutive ticks of the new stream
    TickSequencer s;
    std::int64_t t = 0;
    for (std::uint64_t k = 1; k <= 5000; ++k, t += kMs)
      s.accept(k, t);
    for (std::uint64_t k = 1; k <= 4; ++k, t += kMs / 10)
      EXPECT_EQ(s.accept(k, t), Verdict::kOutOfSequence);
    EXPECT_EQ(s.accept(4, t), Verdict::kOutOfSequence);  // a repeat does not confirm
    EXPECT_EQ(s.accept(5, t), Verdict::kRestart);
    EXPECT_EQ(s.accept(6, t + kMs), Verdict::kNext);
    EXPECT_EQ(s.restarts(), 1u);
  }
}

// One commanding writer: the first writer owns the robot; another is refused while the owner is
// alive (matched and sending), and adopted once the owner is gone (unmatched, or silent for the
// handover time: a killed controller stays matched until its DDS lease expires).
TEST(CommandWriterGate, TheFirstWriterCommandsAnotherIsRefusedUntilTheFirstIsGone) {
  using V = poise::safety::CommandWriterGate::Verdict;
  poise::safety::CommandWriterGate gate(100 * kMs);
  std::int64_t t = 0;
  EXPECT_EQ(gate.check(7, 1, t), V::kOwner);
  EXPECT_EQ(gate.owner(), 7u);
  for (int i = 0; i < 50; ++i) {  // a forger interleaved with a live controller, at 1 kHz
    t += kMs;
    EXPECT_EQ(gate.check(7, 2, t), V::kOwner);
    EXPECT_EQ(gate.check(9, 2, t), V::kForeign);
  }
  EXPECT_EQ(gate.foreign_samples(), 50u);
  EXPECT_EQ(gate.last_foreign_writer(), 9u);
  EXPECT_EQ(gate.owner(), 7u);
  // The controller is killed: still matched, silent; its successor is refused for 100 ms ...
  const std::int64_t killed = t;
  EXPECT_EQ(gate.check(11, 3, killed + 99 * kMs), V::kForeign);
  // ... then adopted; from then on the old writer is the foreign one.
  EXPECT_EQ(gate.check(11, 3, killed + 101 * kMs), V::kAdopted);
  EXPECT_EQ(gate.owner(), 11u);
  EXPECT_EQ(gate.check(7, 3, killed + 102 * kMs), V::kForeign);
  EXPECT_EQ(gate.handovers(), 1u);
  // A restart seen as an unmatch: the only writer matched is adopted at once.
  EXPECT_EQ(gate.check(13, 1, killed + 103 * kMs), V::kAdopted);
  EXPECT_EQ(gate.owner(), 13u);
}

// The refusals reach the loop thread once each, naming both writers; the FAULT stays.
TEST(CommandWriterGate, RefusedCommandsAreReportedOnceNamingBothWriters) {
  poise::safety::ForeignCommands f;
  EXPECT_EQ(f.news(), nullptr);
  EXPECT_FALSE(f.faulted());
  f.refuse(0xabcd, 0x1234);
  f.refuse(0xabcd, 0x1234);
  const char* text = f.news();
  ASSERT_NE(text, nullptr);
  const std::string t = text;
  EXPECT_NE(t.find("2 command(s)"), std::string::npos) << t;
  EXPECT_NE(t.find("000000000000abcd"), std::string::npos) << t;
  EXPECT_NE(t.find("0000000000001234"), std::string::npos) << t;
  EXPECT_EQ(f.news(), nullptr);  // nothing new
  EXPECT_TRUE(f.faulted());
  f.refuse(0xabcd, 0x1234);
  ASSERT_NE(f.news(), nullptr);
  EXPECT_EQ(f.refused(), 3u);
}

}  // namespace
