// Balance references over time: the trajectory sampler of `poise reference play`
// (components/reference) and the controller node's queue that applies references by tick
// (controller/controller_node/reference_queue.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "poise/controller_node/reference_queue.hpp"
#include "poise/reference/trajectory.hpp"

namespace {

namespace fs = std::filesystem;
using namespace poise;

std::string write(const std::string& name, const std::string& text) {
  const fs::path p = fs::temp_directory_path() /
                     ("poise-reference-test-" + std::to_string(::getpid()) + "-" + name + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

TEST(ReferenceTrajectory, ShippedFilesLoad) {
  const std::string dir = std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/references/";
  const auto shift = reference::load_trajectory(dir + "com_shift.yaml");
  ASSERT_EQ(shift.com.size(), 1u);
  EXPECT_DOUBLE_EQ(shift.begin(), 1.0);
  EXPECT_DOUBLE_EQ(shift.end(), 2.0);
  const auto any = reference::load_trajectory(dir + "step_in_place_any_robot.yaml");
  ASSERT_EQ(any.com.size(), 2u);
  EXPECT_EQ(any.com[0].over, reference::ComOver::kLeft);
  EXPECT_EQ(any.com[1].over, reference::ComOver::kBetween);
  const auto arms = reference::load_trajectory(dir + "arm_swing.yaml");
  ASSERT_EQ(arms.joints.size(), 2u);
  EXPECT_DOUBLE_EQ(arms.end(), 4.0);
}

TEST(ReferenceTrajectory, ComMovesAreMinimumJerkAndAddUp) {
  reference::Trajectory t;
  t.com.push_back({1.0, 2.0, Eigen::Vector3d(0.0, 0.04, 0.0)});
  t.com.push_back({4.0, 1.0, Eigen::Vector3d(0.01, 0.0, -0.02)});
  Eigen::Vector3d c, v;
  EXPECT_FALSE(reference::com_offset(t, 0.99, c, v));
  ASSERT_TRUE(reference::com_offset(t, 2.0, c, v));  // half-way through the first move
  EXPECT_NEAR(c.y(), 0.02, 1e-12);
  EXPECT_NEAR(v.y(), 0.04 * 1.875 / 2.0, 1e-12);  // peak of 30 s^2 (1-s)^2 at s = 1/2
  ASSERT_TRUE(reference::com_offset(t, 3.5, c, v));
  EXPECT_NEAR((c - Eigen::Vector3d(0.0, 0.04, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(v.norm(), 0.0, 1e-12);
  ASSERT_TRUE(reference::com_offset(t, 9.0, c, v));
  EXPECT_NEAR((c - Eigen::Vector3d(0.01, 0.04, -0.02)).norm(), 0.0, 1e-12);
  // The velocity is the derivative of the position (central differences, seeded times).
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.9, 5.1);
  for (int i = 0; i < 50; ++i) {
    const double s = u(rng), h = 1e-6;
    Eigen::Vector3d cp, cm, vp;
    reference::com_offset(t, s + h, cp, vp);
    reference::com_offset(t, s - h, cm, vp);
    reference::com_offset(t, s, c, v);
    EXPECT_NEAR(((cp - cm) / (2 * h) - v).norm(), 0.0, 1e-6) << "t = " << s;
  }
}

// `over: left|right|between`: the move ends with the CoM over that sole centre (or their
// mid-point), horizontally, measured when the move begins; the target before it is the origin
// plus the earlier moves. Values worked by hand.
TEST(ReferenceTrajectory, AMoveOverAFootEndsOverItsSoleCentre) {
  reference::Trajectory t = reference::load_trajectory(
      write("over", "name: over\ncom:\n  - {start: 2.0, duration: 1.0, over: left}\n"
                    "  - {start: 4.0, duration: 1.0, shift: [0.0, 0.0, -0.02]}\n"
                    "  - {start: 6.0, duration: 2.0, over: between}\n"));
  ASSERT_EQ(t.com.size(), 3u);
  EXPECT_EQ(t.com[0].over, reference::ComOver::kLeft);
  EXPECT_FALSE(t.com[0].resolved);
  EXPECT_TRUE(t.com[1].resolved);
  EXPECT_EQ(t.com[2].over, reference::ComOver::kBetween);
  const Eigen::Vector3d origin(0.01, 0.002, 0.8);
  const Eigen::Vector3d right(0.03, -0.11, 0.0), left(0.02, 0.09, 0.05);
  Eigen::Vector3d c, v;
  reference::resolve_com_moves(t, 1.9, origin, right, left);  // nothing has begun
  EXPECT_FALSE(t.com[0].resolved);
  reference::resolve_com_moves(t, 2.0, origin, right, left);
  ASSERT_TRUE(t.com[0].resolved);
  EXPECT_FALSE(t.com[2].resolved);
  EXPECT_NEAR((t.com[0].shift - Eigen::Vector3d(0.01, 0.088, 0.0)).norm(), 0.0, 1e-15);
  ASSERT_TRUE(reference::com_offset(t, 5.5, c, v));  // the third, unresolved, counts as none
  EXPECT_NEAR((origin + c - Eigen::Vector3d(0.02, 0.09, 0.78)).norm(), 0.0, 1e-12);
  // The feet measured later (the robot moved): the mid-point then.
  reference::resolve_com_moves(t, 6.0, origin, right + Eigen::Vector3d(0.01, 0, 0),
                               left + Eigen::Vector3d(0.01, 0, 0));
  ASSERT_TRUE(t.com[2].resolved);
  ASSERT_TRUE(reference::com_offset(t, 9.0, c, v));
  EXPECT_NEAR((origin + c - Eigen::Vector3d(0.035, -0.01, 0.78)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(v.norm(), 0.0, 1e-12);
  // Resolved once: later feet do not move it.
  reference::resolve_com_moves(t, 9.0, origin, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  ASSERT_TRUE(reference::com_offset(t, 9.0, c, v));
  EXPECT_NEAR((origin + c - Eigen::Vector3d(0.035, -0.01, 0.78)).norm(), 0.0, 1e-12);
}

TEST(ReferenceTrajectory, SwingDerivativesAndEnvelope) {
  reference::JointSwing s;
  s.start = 1.0;
  s.duration = 3.0;
  s.amplitude = 0.4;
  s.frequency = 1.0;
  s.phase = 0.3;
  s.fade = 0.5;
  double q, qd, qdd;
  reference::swing_offset(s, 0.5, q, qd, qdd);
  EXPECT_EQ(q, 0.0);
  reference::swing_offset(s, 4.5, q, qd, qdd);
  EXPECT_EQ(q, 0.0);
  reference::swing_offset(s, 2.2, q, qd, qdd);  // full amplitude: the plain sine
  EXPECT_NEAR(q, 0.4 * std::sin(2 * M_PI * 1.2 + 0.3), 1e-12);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(1.0, 4.0);
  for (int i = 0; i < 200; ++i) {
    const double t = u(rng), h = 1e-5;
    double qp, qdp, qddp, qm, qdm, qddm;
    reference::swing_offset(s, t + h, qp, qdp, qddp);
    reference::swing_offset(s, t - h, qm, qdm, qddm);
    reference::swing_offset(s, t, q, qd, qdd);
    EXPECT_NEAR((qp - qm) / (2 * h), qd, 1e-5) << "t = " << t;
    EXPECT_NEAR((qdp - qdm) / (2 * h), qdd, 1e-3) << "t = " << t;
    EXPECT_LE(std::abs(q), 0.4 + 1e-12);
  }
}

TEST(ReferenceTrajectory, BadFilesAreRefusedNamingTheKey) {
  auto refused = [](const std::string& text, const std::string& key) {
    try {
      reference::load_trajectory(write("bad", text));
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
      return true;
    }
    return false;
  };
  EXPECT_TRUE(refused("name: x\ncom: [{start: 1, duration: 1, shfit: [0, 0, 0]}]\n", "shfit"));
  EXPECT_TRUE(
      refused("name: x\ncom: [{start: 1, duration: 0, shift: [0, 0, 0]}]\n", "com[0].duration"));
  EXPECT_TRUE(
      refused("name: x\ncom: [{start: 1, duration: 2, shift: [0, 0, 0]},\n"
              "       {start: 2, duration: 1, shift: [0, 0, 0]}]\n",
              "com[1].start"));
  EXPECT_TRUE(
      refused("name: x\njoints: [{joint: a, start: 0, duration: 1, amplitude: 0.1, "
              "fade: 0.6}]\n",
              "joints[0].fade"));
  EXPECT_TRUE(refused("name: x\ncom: [{start: 1, duration: 1, over: up}]\n", "com[0].over"));
  EXPECT_TRUE(refused("name: x\ncom: [{start: 1, duration: 1, over: [left]}]\n", "com[0].over"));
  EXPECT_TRUE(refused(
      "name: x\ncom: [{start: 1, duration: 1, over: left, shift: [0, 0, 0]}]\n", "com[0].over"));
  EXPECT_TRUE(refused("name: x\ncom: [{start: 1, duration: 1}]\n", "com[0].shift"));
  EXPECT_TRUE(refused("name: x\n", "neither"));
  EXPECT_TRUE(refused("com: []\n", "name"));
}

// ---------------------------------------------------------------------------------------------
msg::BalanceReference ref(std::uint64_t tick, double marker) {
  msg::BalanceReference r;
  r.header().tick(tick);
  r.com_W({marker, 0.0, 0.0});
  r.has_upper_body_q(true);
  r.upper_body_q()[0] = marker;
  return r;
}

TEST(ReferenceQueue, AppliesEachReferenceAtItsTick) {
  controller_node::ReferenceQueue q(8);
  for (std::uint64_t t : {12u, 10u, 11u})  // out of order
    q.put(ref(t, static_cast<double>(t)));
  msg::BalanceReference out;
  double prev[4] = {};
  auto d = q.take_due(9, true, 8, out, prev, 4);
  EXPECT_FALSE(d.taken);
  for (std::uint64_t k = 10; k <= 12; ++k) {
    d = q.take_due(k, true, k - 1, out, prev, 4);
    ASSERT_TRUE(d.taken);
    EXPECT_EQ(d.tick, k);
    EXPECT_EQ(out.com_W()[0], static_cast<double>(k));
    EXPECT_EQ(d.late, 0u);
    EXPECT_EQ(d.removed, 1u);
  }
  EXPECT_FALSE(q.take_due(13, true, 12, out).taken);
  EXPECT_EQ(q.late(), 0u);
}

TEST(ReferenceQueue, LateAndSupersededReferences) {
  controller_node::ReferenceQueue q(8);
  msg::BalanceReference out;
  double prev[4] = {};
  // Ticks 20 and 21 arrive only after state 21 was handled: both late at state 22, the newer one
  // applies, and the one for tick 20 is its predecessor.
  q.put(ref(20, 20.0));
  q.put(ref(21, 21.0));
  const auto d = q.take_due(22, true, 21, out, prev, 4);
  ASSERT_TRUE(d.taken);
  EXPECT_EQ(d.tick, 21u);
  EXPECT_EQ(d.removed, 2u);
  EXPECT_EQ(d.late, 2u);
  EXPECT_TRUE(d.has_previous);
  EXPECT_EQ(prev[0], 20.0);
  EXPECT_EQ(q.late(), 2u);
  // Tick 0 = at once, never late; the newest of two equal ticks wins.
  q.put(ref(0, 1.0));
  q.put(ref(0, 2.0));
  const auto now = q.take_due(30, true, 29, out);
  ASSERT_TRUE(now.taken);
  EXPECT_EQ(out.com_W()[0], 2.0);
  EXPECT_EQ(now.late, 0u);
  // The first state: nothing counts as late.
  controller_node::ReferenceQueue fresh(4);
  fresh.put(ref(3, 3.0));
  EXPECT_EQ(fresh.take_due(100, false, 0, out).late, 0u);
}

TEST(ReferenceQueue, OverflowDropsTheEarliestAndCounts) {
  controller_node::ReferenceQueue q(3);
  for (std::uint64_t t = 1; t <= 5; ++t)
    q.put(ref(t, static_cast<double>(t)));
  EXPECT_EQ(q.overflows(), 2u);
  EXPECT_EQ(q.received(), 5u);
  msg::BalanceReference out;
  const auto d = q.take_due(10, false, 0, out);
  EXPECT_EQ(d.removed, 3u);  // 3, 4, 5 kept
  EXPECT_EQ(out.com_W()[0], 5.0);
}

}  // namespace
