// The DDS nodes as separate processes: --help, the contact node's round trip on both vendors
// (valid, NaN and inconsistent problems), the estimator node's states, the controller node's
// handling of states, solutions, repeats and the contact deadline, the lockstep closed loop
// through `poise run`'s distributed launcher (Cyclone, mixed vendors, the paper's forward push)
// and the real-time watchdog when the controller process dies and comes back.
#include <gtest/gtest.h>

#include <signal.h>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>

#include "dds/dds_test_util.hpp"
#include "poise/dds/dds.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/reflect/validate.hpp"
#include "support/child_process.hpp"

namespace {

using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
namespace fs = std::filesystem;
namespace msg = poise::msg;
namespace dds = poise::dds;

const std::string kSource = POISE_SOURCE_DIR;

std::vector<std::string> node_args(const std::string& exe, const std::string& vendor,
                                   std::vector<std::string> extra = {}) {
  std::vector<std::string> a{bin(exe), "--dds", vendor, "--domain",
                             std::to_string(dds::test::claim_test_domain())};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

dds::DdsOptions options(const std::string& vendor) {
  dds::DdsOptions o;
  o.vendor = dds::parse_vendor(vendor);
  o.domain_id = dds::test::claim_test_domain();
  o.participant_name = "nodes_test";
  return o;
}

// ---------------------------------------------------------------------------------------------
TEST(Nodes, EveryNodeAnswersHelp) {
  for (const std::string exe :
       {"poise-sim", "poise-estimator", "poise-contact", "poise-controller", "poise-launch"}) {
    ChildProcess p({bin(exe), "--help"}, {}, false, true);
    const auto code = p.wait_for(20s);
    ASSERT_TRUE(code.has_value()) << exe << " --help did not end";
    EXPECT_EQ(*code, 0) << exe;
    EXPECT_NE(p.output().find("--dds"), std::string::npos) << exe << ":\n" << p.output();
  }
  if (fs::exists(bin("poise"))) {
    ChildProcess p({bin("poise"), "push", "--help"}, {}, false, true);
    ASSERT_EQ(p.wait_for(20s).value_or(-1), 0);
    EXPECT_NE(p.output().find("--force"), std::string::npos) << p.output();
  }
}

TEST(Nodes, BadArgumentsAreRefusedWithAMessage) {
  ChildProcess p({bin("poise-contact"), "--method", "simplex"}, {}, false, true);
  const auto code = p.wait_for(20s);
  ASSERT_TRUE(code.has_value());
  EXPECT_NE(*code, 0);
  EXPECT_NE(p.output().find("--method"), std::string::npos) << p.output();
}

// ---------------------------------------------------------------------------------------------
// Contact node: a double-support problem of a 50 kg robot standing still, random CoM offsets.

msg::ContactProblem standing_problem(std::uint64_t tick, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  msg::ContactProblem p;
  p.header().tick(tick);
  p.header().stamp_ns(static_cast<long long>(tick) * 1'000'000);
  p.mass(50.0);
  p.gravity_W({0.0, 0.0, -9.81});
  p.com_W({u(rng), u(rng), 0.8});
  p.l_dot_desired_W({10 * u(rng), 10 * u(rng), 0.0});
  for (int f = 0; f < 2; ++f) {
    msg::ContactFoot& foot = p.feet()[f];
    foot.in_contact(true);
    foot.pose_W().position({0.0, f == 0 ? -0.1 : 0.1, 0.08});
    foot.pose_W().orientation_wxyz({1.0, 0.0, 0.0, 0.0});
    foot.x_min(-0.08);
    foot.x_max(0.14);
    foot.y_min(-0.055);
    foot.y_max(0.055);
    foot.safety_margin(0.01);
    foot.ankle_height(0.08);
    foot.mu(0.8);
    foot.mu_torsion(0.02);
  }
  return p;
}

bool receive(dds::Subscriber<msg::ContactSolution>& sub, std::uint64_t tick,
             msg::ContactSolution& out) {
  return dds::test::eventually(
      [&] {
        while (sub.take(out))
          if (out.header().tick() == tick) return true;
        return false;
      },
      10000ms);
}

class ContactNode : public ::testing::TestWithParam<std::string> {};

TEST_P(ContactNode, RoundTripCopiesTheTickAndAnswersBadInputSafely) {
  const std::string vendor = GetParam();
  ChildProcess node(node_args("poise-contact", vendor), {}, false, true);
  dds::Participant participant(options(vendor));
  dds::Publisher<msg::ContactProblem> pub(participant);
  dds::Subscriber<msg::ContactSolution> sub(participant);
  ASSERT_TRUE(pub.wait_for_matches(1, 15s)) << node.output();
  ASSERT_TRUE(sub.wait_for_matches(1, 15s)) << node.output();
  std::this_thread::sleep_for(300ms);  // the node's side of the match

  std::mt19937 rng(7);
  for (std::uint64_t k = 100; k < 105; ++k) {
    const msg::ContactProblem p = standing_problem(k, rng);
    ASSERT_TRUE(pub.publish(p));
    msg::ContactSolution s;
    ASSERT_TRUE(receive(sub, k, s)) << "no solution of tick " << k << "\n" << node.output();
    EXPECT_EQ(s.header().stamp_ns(), p.header().stamp_ns());
    EXPECT_TRUE(s.status() == msg::CONTACT_OK || s.status() == msg::CONTACT_PROJECTED)
        << s.status();
    EXPECT_TRUE(poise::reflect::validate(s));
    // Independent check, Newton: the admissible linear rate is m g + the sum of the foot forces.
    for (int i = 0; i < 3; ++i) {
      const double sum_f =
          s.feet()[0].wrench_at_ankle_W().force()[i] + s.feet()[1].wrench_at_ankle_W().force()[i];
      EXPECT_NEAR(s.l_dot_admissible_W()[i], p.mass() * p.gravity_W()[i] + sum_f, 1e-6);
      // Standing still is admissible: the desired rate is reproduced.
      EXPECT_NEAR(s.l_dot_admissible_W()[i], p.l_dot_desired_W()[i], 0.02 * p.mass() * 9.81);
    }
    EXPECT_GT(s.feet()[0].wrench_at_ankle_W().force()[2], 0.0);
    EXPECT_GT(s.feet()[1].wrench_at_ankle_W().force()[2], 0.0);
    EXPECT_GE(s.solve_time_us(), 0.0);
    EXPECT_EQ(s.method(), 0u);
  }

  // A NaN in the problem: the DDS layer would drop it; the node answers with INVALID_INPUT and
  // the safe (all zero, finite) answer, for the same tick.
  msg::ContactProblem bad = standing_problem(200, rng);
  bad.com_W()[1] = std::nan("");
  ASSERT_TRUE(pub.publish(bad));
  msg::ContactSolution s;
  ASSERT_TRUE(receive(sub, 200, s)) << node.output();
  EXPECT_EQ(s.status(), msg::CONTACT_INVALID_INPUT);
  EXPECT_TRUE(poise::reflect::validate(s));
  for (int f = 0; f < 2; ++f)
    for (int i = 0; i < 3; ++i)
      EXPECT_EQ(s.feet()[f].wrench_at_ankle_W().force()[i], 0.0);

  // Finite but inconsistent: a zero quaternion is no rotation.
  msg::ContactProblem zero_q = standing_problem(201, rng);
  zero_q.feet()[1].pose_W().orientation_wxyz({0.0, 0.0, 0.0, 0.0});
  ASSERT_TRUE(pub.publish(zero_q));
  ASSERT_TRUE(receive(sub, 201, s)) << node.output();
  EXPECT_EQ(s.status(), msg::CONTACT_INVALID_INPUT);
  EXPECT_TRUE(poise::reflect::validate(s));

  // Still answering after bad input.
  ASSERT_TRUE(pub.publish(standing_problem(202, rng)));
  ASSERT_TRUE(receive(sub, 202, s)) << node.output();
  EXPECT_NE(s.status(), msg::CONTACT_INVALID_INPUT);

  const auto code = node.interrupt(5000ms);
  ASSERT_TRUE(code.has_value()) << "the node did not stop on SIGINT";
  EXPECT_EQ(*code, 0) << node.output();
  EXPECT_NE(node.output().find("rejected contact problem"), std::string::npos) << node.output();
}

INSTANTIATE_TEST_SUITE_P(Vendors, ContactNode, ::testing::Values("cyclone", "fastdds"));

// ---------------------------------------------------------------------------------------------
// Estimator node: a standing robot's sensor samples in, one state per sample out, joints mapped
// through a permuted robot description.

/// The project humanoid's robot description with the joints in `wire` order, 1 kHz: the
/// robot.yaml and URDF texts the nodes build their robot from (no --robot).
msg::RobotDescription humanoid_description(const std::vector<std::string>& wire) {
  msg::RobotDescription d;
  d.robot_name("poise_humanoid");
  const auto text = [](const std::string& path) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  d.robot_config(text(kSource + "/deploy/robots/poise_humanoid/robot.yaml"));
  d.urdf(text(kSource + "/deploy/robots/poise_humanoid/poise_humanoid.urdf"));
  d.joint_names(wire);
  d.control_period_s(0.001);
  return d;
}

TEST(Nodes, EstimatorNodeAnswersEverySensorSampleWithItsState) {
  const auto robot =
      poise::model::load_robot_config(kSource + "/deploy/robots/poise_humanoid/robot.yaml");
  const auto model = poise::model::load_robot_model(robot);
  std::vector<std::string> wire(model.joint_names.rbegin(), model.joint_names.rend());  // permuted
  const int n = static_cast<int>(wire.size());

  dds::Participant participant(options("cyclone"));
  dds::Publisher<msg::RobotDescription> description(participant);
  ASSERT_TRUE(description.publish(humanoid_description(wire)));
  ChildProcess node(node_args("poise-estimator", "cyclone"), {}, false, true);
  dds::Publisher<msg::Sensors> sensors(participant);
  dds::Subscriber<msg::State> states(participant);
  ASSERT_TRUE(sensors.wait_for_matches(1, 20s)) << node.output();
  ASSERT_TRUE(states.wait_for_matches(1, 20s)) << node.output();
  std::this_thread::sleep_for(300ms);

  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  msg::Sensors s;
  s.joint_count(static_cast<std::uint32_t>(n));
  std::vector<double> q(n);
  for (int i = 0; i < n; ++i)
    q[i] = u(rng);
  const double weight = model.total_mass * 9.81;
  for (std::uint64_t k = 0; k < 50; ++k) {
    s.header().tick(k);
    s.header().stamp_ns(static_cast<long long>(k) * 1'000'000);
    for (int i = 0; i < n; ++i)
      s.q()[i] = q[i];
    s.imu().orientation_wxyz({1.0, 0.0, 0.0, 0.0});
    s.imu().specific_force_I({0.0, 0.0, 9.81});
    for (int f = 0; f < 2; ++f)
      s.foot_wrench_F()[f].force({0.0, 0.0, weight / 2});
    ASSERT_TRUE(sensors.publish(s));
    msg::State st;
    const bool got = dds::test::eventually(
        [&] {
          while (states.take(st))
            if (st.header().tick() == k) return true;
          return false;
        },
        5000ms);
    ASSERT_TRUE(got) << "no state of tick " << k << "\n" << node.output();
    EXPECT_EQ(st.header().stamp_ns(), s.header().stamp_ns());
    EXPECT_TRUE(poise::reflect::validate(st));
    ASSERT_EQ(st.joint_count(), static_cast<std::uint32_t>(n));
    for (int i = 0; i < n; ++i)
      EXPECT_EQ(st.q()[i], q[i]) << wire[i];  // mapping round trip
    EXPECT_EQ(st.status_flags() & msg::STATE_GROUND_TRUTH, 0u);
    if (k == 49) {  // weight on both feet: both in contact
      EXPECT_TRUE(st.feet()[0].in_contact());
      EXPECT_TRUE(st.feet()[1].in_contact());
      EXPECT_NEAR(st.feet()[0].normal_force(), weight / 2, 1e-6 * weight);
    }
  }
  EXPECT_EQ(node.interrupt(5000ms).value_or(-1), 0) << node.output();
}

// ---------------------------------------------------------------------------------------------
// Controller node, with this test in the roles of the estimator and the contact optimiser: a
// state that arrives while the node still waits for the optimiser is kept and handled at the
// start; state k -> contact problem k -> solution k -> command k; a repeated state gets the same
// command again; a repeat while its tick waits for the solution is ignored; no solution -> the
// fallback command at the deadline (counted), and a late solution is not used.
msg::State standing_state(std::uint64_t k, int n, const std::vector<double>& q, double weight) {
  msg::State s;
  s.header().tick(k);
  s.header().stamp_ns(static_cast<long long>(k) * 1'000'000);
  s.base_W().position({0.0, 0.0, 0.85});
  s.base_W().orientation_wxyz({1.0, 0.0, 0.0, 0.0});
  s.joint_count(static_cast<std::uint32_t>(n));
  for (int i = 0; i < n; ++i)
    s.q()[i] = q[i];
  s.com_W({0.0, 0.0, 0.8});
  for (int f = 0; f < 2; ++f) {
    msg::FootState& foot = s.feet()[f];
    foot.in_contact(true);
    foot.pose_W().position({0.0, f == 0 ? -0.1 : 0.1, 0.08});
    foot.pose_W().orientation_wxyz({1.0, 0.0, 0.0, 0.0});
    foot.cop_W({0.0, f == 0 ? -0.1 : 0.1, 0.0});
    foot.normal_force(weight / 2);
  }
  return s;
}

/// Each foot carries half the weight (what the optimiser answers for a robot standing still).
msg::ContactSolution half_weight_solution(const msg::ContactProblem& p) {
  msg::ContactSolution s;
  s.header(p.header());
  s.status(msg::CONTACT_OK);
  const double weight = -p.mass() * p.gravity_W()[2];
  s.l_dot_admissible_W({0.0, 0.0, 0.0});
  for (int f = 0; f < 2; ++f) {
    s.feet()[f].wrench_at_ankle_W().force({0.0, 0.0, weight / 2});
    s.feet()[f].cop_W(p.feet()[f].pose_W().position());
  }
  return s;
}

template <class T>
std::vector<T> take_all(dds::Subscriber<T>& sub) {
  std::vector<T> out;
  T s;
  while (sub.take(s))
    out.push_back(s);
  return out;
}

TEST(Nodes, ControllerNodeAnswersEachStateOnceAndFallsBackAtTheDeadline) {
  const auto robot =
      poise::model::load_robot_config(kSource + "/deploy/robots/poise_humanoid/robot.yaml");
  const auto model = poise::model::load_robot_model(robot);
  std::vector<std::string> wire(model.joint_names.rbegin(), model.joint_names.rend());  // permuted
  const int n = static_cast<int>(wire.size());
  const double weight = model.total_mass * 9.81;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  std::vector<double> q(n);
  for (auto& v : q)
    v = u(rng);

  const fs::path summary =
      fs::temp_directory_path() / ("poise-controller-test-" + std::to_string(::getpid()) + ".json");
  fs::remove(summary);
  dds::Participant participant(options("cyclone"));
  dds::Publisher<msg::RobotDescription> description(participant);
  ASSERT_TRUE(description.publish(humanoid_description(wire)));
  constexpr int kDeadlineMs = 1000;
  ChildProcess node(node_args("poise-controller", "cyclone",
                              {"--contact-deadline-us", std::to_string(kDeadlineMs * 1000),
                               "--contact-wait-ms", "20000", "--summary", summary.string()}),
                    {}, false, true);
  dds::Publisher<msg::State> states(participant);
  dds::Subscriber<msg::ContactProblem> problems(participant, dds::Qos::reliable(100));
  dds::Subscriber<msg::JointCommand> commands(participant, dds::Qos::reliable(100));
  ASSERT_TRUE(states.wait_for_matches(1, 20s)) << node.output();
  ASSERT_TRUE(problems.wait_for_matches(1, 20s)) << node.output();
  ASSERT_TRUE(commands.wait_for_matches(1, 20s)) << node.output();
  std::this_thread::sleep_for(300ms);  // the node's side of the matches

  // State 0 while the node waits for the optimiser's solution endpoint: kept, handled at start.
  ASSERT_TRUE(states.publish(standing_state(0, n, q, weight)));
  std::this_thread::sleep_for(300ms);
  EXPECT_TRUE(take_all(problems).empty()) << "problem sent before the optimiser was there";
  dds::Publisher<msg::ContactSolution> solutions(participant);
  // Takes samples from `reader` until one of tick k arrives (10 s at most).
  auto next_of_tick = [](auto& reader, std::uint64_t k, auto& sample) {
    return dds::test::eventually(
        [&] {
          while (reader.take(sample))
            if (sample.header().tick() == k) return true;
          return false;
        },
        10000ms);
  };
  auto next_problem = [&](std::uint64_t k, msg::ContactProblem& p) {
    return next_of_tick(problems, k, p);
  };
  auto next_command = [&](std::uint64_t k, msg::JointCommand& c) {
    return next_of_tick(commands, k, c);
  };
  msg::ContactProblem p;
  ASSERT_TRUE(next_problem(0, p)) << node.output();
  EXPECT_TRUE(poise::reflect::validate(p));
  EXPECT_NEAR(p.mass(), model.total_mass, 1e-9);
  ASSERT_TRUE(solutions.wait_for_matches(1, 10s));
  ASSERT_TRUE(solutions.publish(half_weight_solution(p)));
  msg::JointCommand c0;
  ASSERT_TRUE(next_command(0, c0)) << node.output();
  EXPECT_EQ(c0.mode(), msg::COMMAND_TORQUE);
  EXPECT_EQ(c0.joint_count(), static_cast<std::uint32_t>(n));
  EXPECT_TRUE(poise::reflect::validate(c0));
  EXPECT_EQ(c0.header().stamp_ns(), 0);

  // A repeated state: the same command again, and no new problem.
  ASSERT_TRUE(states.publish(standing_state(0, n, q, weight)));
  msg::JointCommand again;
  ASSERT_TRUE(next_command(0, again)) << node.output();
  for (int i = 0; i < n; ++i)
    EXPECT_EQ(again.tau_ff()[i], c0.tau_ff()[i]) << wire[i];
  EXPECT_TRUE(take_all(problems).empty());

  // State 1 unanswered: the fallback command, not before the deadline; a late solution is not
  // used (no second command of tick 1).
  const auto t1 = std::chrono::steady_clock::now();
  ASSERT_TRUE(states.publish(standing_state(1, n, q, weight)));
  ASSERT_TRUE(next_problem(1, p)) << node.output();
  msg::JointCommand c1;
  ASSERT_TRUE(next_command(1, c1)) << node.output();
  EXPECT_GE(std::chrono::steady_clock::now() - t1, std::chrono::milliseconds(kDeadlineMs));
  EXPECT_TRUE(poise::reflect::validate(c1));
  ASSERT_TRUE(solutions.publish(half_weight_solution(p)));

  // State 2 twice before its solution: problem 2 is sent again (at start-up the optimiser's
  // reader may have missed the first: the simulator repeats tick 0 in lockstep for that), the
  // same problem; both copies answered, one command.
  ASSERT_TRUE(states.publish(standing_state(2, n, q, weight)));
  ASSERT_TRUE(next_problem(2, p)) << node.output();
  ASSERT_TRUE(states.publish(standing_state(2, n, q, weight)));
  msg::ContactProblem p_again;
  ASSERT_TRUE(next_problem(2, p_again)) << node.output();
  EXPECT_EQ(p_again.header().stamp_ns(), p.header().stamp_ns());
  EXPECT_EQ(p_again.mass(), p.mass());
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(p_again.l_dot_desired_W()[i], p.l_dot_desired_W()[i]);
  ASSERT_TRUE(solutions.publish(half_weight_solution(p)));
  ASSERT_TRUE(solutions.publish(half_weight_solution(p_again)));
  msg::JointCommand c2;
  ASSERT_TRUE(next_command(2, c2)) << node.output();
  std::this_thread::sleep_for(200ms);
  for (const auto& c : take_all(commands)) {
    EXPECT_NE(c.header().tick(), 1u) << "a second command of tick 1 (late solution used)";
    EXPECT_NE(c.header().tick(), 2u) << "a second command of tick 2 (second answer used)";
  }
  EXPECT_TRUE(take_all(problems).empty()) << "a problem sent with no repeated state";

  EXPECT_EQ(node.interrupt(5000ms).value_or(-1), 0) << node.output();
  std::ifstream in(summary);
  ASSERT_TRUE(in) << node.output();
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["diagnostics"]["deadline_misses"].get<int>(), 1) << j.dump(2);  // tick 1 only
  EXPECT_EQ(j["diagnostics"]["ticks"].get<int>(), 3) << j.dump(2);
  EXPECT_EQ(j["problems_resent"].get<int>(), 1) << j.dump(2);
  fs::remove(summary);
}

// Start-up (until the optimiser has answered once): no fallback wrenches at the real-time
// deadline, and a newer state replaces the unanswered tick, which gets no command.
TEST(Nodes, ControllerSendsNoFallbackBeforeTheOptimiserFirstAnswers) {
  const auto robot =
      poise::model::load_robot_config(kSource + "/deploy/robots/poise_humanoid/robot.yaml");
  const auto model = poise::model::load_robot_model(robot);
  const std::vector<std::string> wire(model.joint_names.begin(), model.joint_names.end());
  const int n = static_cast<int>(wire.size());
  const double weight = model.total_mass * 9.81;
  const std::vector<double> q(n, 0.0);
  const fs::path summary = fs::temp_directory_path() /
                           ("poise-controller-start-" + std::to_string(::getpid()) + ".json");
  fs::remove(summary);
  dds::Participant participant(options("cyclone"));
  dds::Publisher<msg::RobotDescription> description(participant);
  ASSERT_TRUE(description.publish(humanoid_description(wire)));
  ChildProcess node(node_args("poise-controller", "cyclone",
                              {"--contact-deadline-us", "400", "--contact-wait-ms", "20000",
                               "--summary", summary.string()}),
                    {}, false, true);
  dds::Publisher<msg::State> states(participant);
  dds::Subscriber<msg::ContactProblem> problems(participant, dds::Qos::reliable(100));
  dds::Subscriber<msg::JointCommand> commands(participant, dds::Qos::reliable(100));
  dds::Publisher<msg::ContactSolution> solutions(participant);
  ASSERT_TRUE(states.wait_for_matches(1, 20s)) << node.output();
  ASSERT_TRUE(problems.wait_for_matches(1, 20s)) << node.output();
  ASSERT_TRUE(commands.wait_for_matches(1, 20s)) << node.output();
  ASSERT_TRUE(solutions.wait_for_matches(1, 20s)) << node.output();
  std::this_thread::sleep_for(300ms);  // the node's side of the matches

  // State 0, its problem "lost" (not answered): no fallback command, 400 us or 300 ms later.
  ASSERT_TRUE(states.publish(standing_state(0, n, q, weight)));
  msg::ContactProblem p;
  ASSERT_TRUE(dds::test::eventually([&] { return problems.take(p); }, 10000ms)) << node.output();
  EXPECT_EQ(p.header().tick(), 0u);
  std::this_thread::sleep_for(300ms);
  EXPECT_TRUE(take_all(commands).empty()) << "a fallback command before the first answer";
  // State 1 replaces tick 0; its problem is answered: command 1, and never one of tick 0.
  ASSERT_TRUE(states.publish(standing_state(1, n, q, weight)));
  ASSERT_TRUE(dds::test::eventually([&] { return problems.take(p) && p.header().tick() == 1; },
                                    10000ms))
      << node.output();
  ASSERT_TRUE(solutions.publish(half_weight_solution(p)));
  msg::JointCommand c;
  ASSERT_TRUE(dds::test::eventually([&] { return commands.take(c); }, 10000ms)) << node.output();
  EXPECT_EQ(c.header().tick(), 1u);
  // From the first answer on, the real-time deadline applies: state 2 unanswered gets the
  // fallback command within a fraction of a second.
  ASSERT_TRUE(states.publish(standing_state(2, n, q, weight)));
  ASSERT_TRUE(dds::test::eventually([&] { return commands.take(c) && c.header().tick() == 2; },
                                    2000ms))
      << node.output();
  std::this_thread::sleep_for(100ms);
  for (const auto& x : take_all(commands)) EXPECT_NE(x.header().tick(), 0u);

  EXPECT_EQ(node.interrupt(5000ms).value_or(-1), 0) << node.output();
  std::ifstream in(summary);
  ASSERT_TRUE(in) << node.output();
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["startup_skipped"].get<int>(), 1) << j.dump(2);
  EXPECT_EQ(j["diagnostics"]["deadline_misses"].get<int>(), 1) << j.dump(2);  // tick 2 only
  fs::remove(summary);
}

// ---------------------------------------------------------------------------------------------
// The closed loop through the distributed launcher.

nlohmann::json run_scenario(const std::string& scenario, std::vector<std::string> extra,
                            std::string* output = nullptr, int expect_code = 0) {
  const fs::path dir =
      fs::temp_directory_path() / ("poise-nodes-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path out = dir / "result.json";
  std::vector<std::string> a{bin("poise-launch"), scenario,
                             "--domain",          std::to_string(dds::test::claim_test_domain()),
                             "--output",          out.string(),
                             "--log-dir",         (dir / "logs").string()};
  a.insert(a.end(), extra.begin(), extra.end());
  ChildProcess p(a, {}, false, true);
  const auto code = p.wait_for(150s);
  if (output) *output = p.output();
  EXPECT_TRUE(code.has_value()) << "poise run did not finish\n" << p.output();
  EXPECT_EQ(code.value_or(-1), expect_code) << p.output();
  std::ifstream in(out);
  nlohmann::json j;
  if (in) j = nlohmann::json::parse(in);
  fs::remove_all(dir);
  return j;
}

void expect_healthy_run(const nlohmann::json& r, const std::string& out) {
  ASSERT_TRUE(r.is_object()) << out;
  EXPECT_TRUE(r["survived"].get<bool>()) << r.dump(2);
  EXPECT_TRUE(r["completed"].get<bool>()) << r.dump(2);
  EXPECT_EQ(r["state_source"], "estimator");
  EXPECT_EQ(r["mode"], "lockstep");
  EXPECT_EQ(r["command_timeouts"].get<int>(), 0) << r.dump(2);
  const auto& lat = r["tick_latency_us"];
  EXPECT_GT(lat["count"].get<int>(), 1000);
  EXPECT_GT(lat["p50"].get<double>(), 0.0);
  EXPECT_LE(lat["p50"].get<double>(), lat["p99"].get<double>());
  EXPECT_LE(lat["p99"].get<double>(), lat["max"].get<double>());
  EXPECT_GT(r["realtime_factor"].get<double>(), 0.0);
  EXPECT_EQ(r["rejected_samples"].get<int>(), 0) << r.dump(2);
  EXPECT_NE(out.find("SURVIVED standing_short"), std::string::npos) << out;
}

TEST(ClosedLoop, LockstepStandingOnCyclone) {
  std::string out;
  const auto r =
      run_scenario(kSource + "/tests/nodes/standing_short.yaml", {"--dds", "cyclone"}, &out);
  expect_healthy_run(r, out);
  EXPECT_EQ(r["dds"]["sim"], "cyclone");
  EXPECT_EQ(r["dds"]["controller"], "cyclone");
  EXPECT_EQ(r["deadline_misses"].get<int>(), 0) << r.dump(2);
  EXPECT_NE(out.find("t=1.0 s"), std::string::npos) << "no progress line\n" << out;
}

TEST(ClosedLoop, LockstepStandingWithMixedVendors) {
  std::string out;
  const auto r = run_scenario(kSource + "/tests/nodes/standing_short.yaml",
                              {"--dds-sim", "fastdds", "--dds-estimator", "fastdds",
                               "--dds-contact", "cyclone", "--dds-controller", "cyclone"},
                              &out);
  expect_healthy_run(r, out);
  EXPECT_EQ(r["dds"]["sim"], "fastdds");
  EXPECT_EQ(r["dds"]["estimator"], "fastdds");
  EXPECT_EQ(r["dds"]["contact"], "cyclone");
  EXPECT_EQ(r["dds"]["controller"], "cyclone");
}

TEST(ClosedLoop, AFailingChildIsNamedWithItsLastStderrLines) {
  // A controller that dies at start: the launcher must stop the others, name the controller,
  // show its stderr and exit with 2 (not hang until its timeout).
  const fs::path dir = fs::temp_directory_path() / ("poise-fake-bin-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const std::string exe : {"poise-sim", "poise-estimator", "poise-contact"})
    fs::create_symlink(bin(exe), dir / exe);
  {
    std::ofstream script(dir / "poise-controller");
    script << "#!/bin/sh\necho 'controller boom: cannot start' >&2\nsleep 1\nexit 4\n";
  }
  fs::permissions(dir / "poise-controller", fs::perms::owner_all);
  const fs::path logs = dir / "logs";
  ChildProcess p({bin("poise-launch"), kSource + "/tests/nodes/standing_short.yaml", "--domain",
                  std::to_string(dds::test::claim_test_domain()), "--output",
                  (dir / "r.json").string(), "--log-dir", logs.string(), "--timeout", "60"},
                 {"POISE_BIN_DIR=" + dir.string()}, false, true);
  const auto code = p.wait_for(90s);
  ASSERT_TRUE(code.has_value()) << p.output();
  EXPECT_EQ(*code, 2) << p.output();
  EXPECT_NE(p.output().find("controller exited with code 4"), std::string::npos)
      << p.output();
  EXPECT_NE(p.output().find("controller boom: cannot start"), std::string::npos) << p.output();
  // The failed run still writes its result, marked failed, with the reason.
  const auto r = nlohmann::json::parse(std::ifstream(dir / "r.json"), nullptr, false);
  ASSERT_TRUE(r.is_object()) << p.output();
  EXPECT_TRUE(r.value("failed", false)) << r.dump(2);
  EXPECT_NE(r.value("failure", std::string()).find("controller exited with code 4"),
            std::string::npos)
      << r.dump(2);
  fs::remove_all(dir);
}

TEST(ClosedLoop, ForwardPushOfThePaperOverDds) {
  // Paper Fig. 8 (120 N x 0.1 s on the pelvis, double support), all four processes on Cyclone.
  std::string out;
  const auto r = run_scenario(kSource + "/deploy/scenarios/forward_push_double_support.yaml",
                              {"--dds", "cyclone"}, &out);
  ASSERT_TRUE(r.is_object()) << out;
  EXPECT_TRUE(r["survived"].get<bool>()) << r.dump(2);
  EXPECT_EQ(r["non_foot_contacts"].get<int>(), 0);
  // The push moved the CoM measurably (the run is not a standing run in disguise).
  EXPECT_GT(r["com_error_max_m"].get<double>(), 0.005) << r.dump(2);
  EXPECT_EQ(r["command_timeouts"].get<int>(), 0) << r.dump(2);
}

// The simulator's safety layer (components/safety): a killed controller -> HOLD of the last
// targets, then DAMP after --hold-s; a new controller -> control resumed.
TEST(RealTime, WatchdogHoldsThenDampsWhenTheControllerDiesAndResumesWhenOneReturns) {
  const std::string scenario = kSource + "/tests/nodes/standing_short.yaml";
  ChildProcess sim(node_args("poise-sim", "cyclone",
                             {scenario, "--realtime", "--duration", "30", "--progress", "--hold-s",
                              "0.5"}),
                   {}, false, true);
  ChildProcess contact(node_args("poise-contact", "cyclone"), {}, false, true);
  ChildProcess estimator(node_args("poise-estimator", "cyclone"), {}, false, true);
  auto controller = std::make_unique<ChildProcess>(
      node_args("poise-controller", "cyclone", {"--contact-deadline-us", "400"}),
      std::vector<std::string>{}, false, true);
  ASSERT_TRUE(sim.wait_for_output("control resumed", 30000ms))
      << "the controller never took over\n"
      << sim.output() << controller->output();
  std::this_thread::sleep_for(500ms);
  const std::size_t before_kill = sim.output().size();
  ::kill(controller->pid(), SIGKILL);  // a crash, not a clean stop
  controller->wait_for(5000ms);
  ASSERT_TRUE(dds::test::eventually(
      [&] { return sim.output().find("safety: DAMP", before_kill) != std::string::npos; }, 5000ms))
      << sim.output();
  const std::size_t damp = sim.output().find("safety: DAMP", before_kill);
  controller = std::make_unique<ChildProcess>(
      node_args("poise-controller", "cyclone", {"--contact-deadline-us", "400"}),
      std::vector<std::string>{}, false, true);
  const bool resumed_again = dds::test::eventually(
      [&] { return sim.output().find("control resumed", damp) != std::string::npos; }, 30000ms);
  EXPECT_TRUE(resumed_again) << sim.output() << controller->output();
  EXPECT_EQ(sim.interrupt(5000ms).value_or(-1), 3) << "an interrupted run reports exit code 3\n"
                                                   << sim.output();
  EXPECT_NE(sim.output().find("\"damp_events\":1"), std::string::npos) << sim.output();
}

// `poise-sim --realtime --start-when-answered` (what poise run and poise launch use): the first
// frame is repeated every 100 ms until a joint command for it comes back, and the wall clock
// starts only then; with no answer within --startup-timeout-ms it says so and starts anyway.
TEST(RealTime, TheClockStartsOnceTheLoopAnsweredTheFirstFrame) {
  const std::string scenario = kSource + "/deploy/scenarios/standing.yaml";
  for (const bool answer : {true, false}) {
    SCOPED_TRACE(answer ? "answered after two repeats" : "never answered");
    const fs::path summary = fs::temp_directory_path() /
                             ("poise-sim-start-" + std::to_string(::getpid()) + ".json");
    fs::remove(summary);
    const dds::DdsOptions o = options("cyclone");
    dds::Participant participant(o);
    dds::Subscriber<msg::Sensors> sensors(participant, dds::Qos::reliable(100));
    dds::Publisher<msg::JointCommand> commands(participant);
    ChildProcess sim(
        {bin("poise-sim"), "--dds", "cyclone", "--domain", std::to_string(o.domain_id), scenario,
         "--realtime",
         "--start-when-answered", "--duration", "0.3", "--startup-timeout-ms",
         answer ? "20000" : "600", "--summary", summary.string()},
        {}, false, true);
    std::int64_t k0 = -1;
    int k0_seen = 0;
    bool later_before_answer = false, answered = false, later_after = false;
    const auto until = std::chrono::steady_clock::now() + 20s;
    msg::Sensors s;
    while (std::chrono::steady_clock::now() < until && !later_after) {
      while (sensors.take(s)) {
        const auto t = static_cast<std::int64_t>(s.header().tick());
        if (k0 < 0) k0 = t;
        if (t == k0) ++k0_seen;
        if (t > k0) (answered ? later_after : later_before_answer) = true;
      }
      if (answer && !answered && k0_seen >= 3) {  // k0 and two repeats: now the loop answers
        msg::JointCommand c;
        c.header().tick(static_cast<std::uint64_t>(k0));
        ASSERT_TRUE(commands.publish(c));
        answered = true;
      }
      if (!answer && k0_seen > 0 && later_before_answer) break;
      std::this_thread::sleep_for(1ms);
    }
    ASSERT_GE(k0, 0) << sim.output();
    EXPECT_GE(k0_seen, 3) << sim.output();
    const auto code = sim.wait_for(20s);
    ASSERT_TRUE(code.has_value()) << sim.output();
    if (answer) {
      EXPECT_FALSE(later_before_answer) << "the clock started before the loop answered";
      EXPECT_TRUE(later_after) << sim.output();
      EXPECT_NE(sim.output().find("start-up: the loop answered frame"), std::string::npos)
          << sim.output();
      std::ifstream in(summary);
      ASSERT_TRUE(in) << sim.output();
      const auto j = nlohmann::json::parse(in);
      EXPECT_GE(j["start_repeats"].get<int>(), 2) << j.dump(2);
    } else {
      EXPECT_TRUE(later_before_answer) << "no answer: the run starts anyway\n" << sim.output();
      EXPECT_NE(sim.output().find("no joint command for frame"), std::string::npos)
          << sim.output();
    }
    fs::remove(summary);
  }
}

}  // namespace
