// The balance-reference player without its transport (components/reference player.hpp), which
// poise-reference publishes from and the in-process loop queues from, and the in-order state
// queue poise-reference feeds it with (components/node mailbox.hpp SampleQueue). What makes the
// two modes give one answer: the references of a tick are the same whichever states the player
// saw, and the player sees every state.
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <poise/msg/balance_reference.h>
#include <poise/msg/state.h>

#include "poise/model/robot_config.hpp"
#include "poise/node/mailbox.hpp"
#include "poise/reference/player.hpp"
#include "poise/reference/trajectory.hpp"

namespace {

using namespace poise;

struct Robot {
  model::RobotConfig config;
  model::Model model;
  std::vector<int> model_to_wire;
};

const Robot& robot() {
  static const Robot r = [] {
    Robot x;
    x.config = model::load_robot_config(std::string(POISE_SOURCE_DIR) +
                                        "/deploy/robots/poise_humanoid/robot.yaml");
    x.model = model::load_robot_model(x.config);
    for (int j = 0; j < x.model.njoints; ++j)  // a wire order that is not the model's
      x.model_to_wire.push_back(x.model.njoints - 1 - j);
    return x;
  }();
  return r;
}

reference::Trajectory step_in_place() {
  return reference::load_trajectory(std::string(POISE_SOURCE_DIR) +
                                    "/deploy/scenarios/references/step_in_place.yaml");
}

/// A state of tick k at the robot's 1 kHz; with `noise`, the CoM and feet differ from tick to
/// tick (seeded), so that an origin or stood pose taken from another state would show.
msg::State state_of(std::uint64_t k, bool noise = true) {
  std::mt19937 rng(static_cast<unsigned>(k) * 7919u + 3u);
  std::uniform_real_distribution<double> dist(-1e-3, 1e-3);
  auto u = [&] { return noise ? dist(rng) : 0.0; };
  msg::State s;
  s.header().tick(k);
  s.header().stamp_ns(static_cast<long long>(k) * 1000000LL);
  s.com_W() = {0.01 + u(), u(), 0.83 + u()};
  for (int f = 0; f < 2; ++f) {
    s.feet()[f].pose_W().orientation_wxyz() = {1.0, 0.0, 0.0, 0.0};
    s.feet()[f].pose_W().position() = {u(), f == 0 ? 0.1 : -0.1, u()};
  }
  return s;
}

/// Plays ticks first..last, giving the player every `stride`-th state only (after the first).
std::map<std::uint64_t, msg::BalanceReference> play(std::uint64_t first, std::uint64_t last,
                                                    int stride, reference::Player& p,
                                                    bool noise) {
  std::map<std::uint64_t, msg::BalanceReference> out;
  for (std::uint64_t k = first; k <= last; ++k) {
    if (k != first && (k - first) % static_cast<std::uint64_t>(stride) != 0) continue;
    p.on_state(state_of(k, noise), [&](const msg::BalanceReference& r) {
      EXPECT_EQ(out.count(r.header().tick()), 0u) << "tick " << r.header().tick() << " twice";
      out[r.header().tick()] = r;
      return true;
    });
  }
  return out;
}

TEST(ReferencePlayer, ProducesEachTickOnceAheadOfTheStateAndStopsAtTheEnd) {
  const Robot& r = robot();
  const reference::Trajectory traj = step_in_place();
  reference::Player p(traj, r.model, r.config, r.model_to_wire, 1e-3, 200);
  std::uint64_t k_max = 0;
  for (std::uint64_t k = 10; k <= 7000; ++k) {
    p.on_state(state_of(k), [&](const msg::BalanceReference& ref) {
      EXPECT_GT(ref.header().tick(), k);
      EXPECT_LE(ref.header().tick(), k + 200);
      EXPECT_EQ(ref.header().stamp_ns(), static_cast<long long>(ref.header().tick()) * 1000000LL);
      k_max = std::max<std::uint64_t>(k_max, ref.header().tick());
      return true;
    });
  }
  EXPECT_FALSE(p.started_late());
  EXPECT_TRUE(p.done());
  // From the trajectory's first change (2.0 s) to its end (6.3 s), each tick once.
  EXPECT_EQ(p.first_sent(), 2000u);
  EXPECT_EQ(p.last_sent(), 6300u);
  EXPECT_EQ(k_max, 6300u);
  EXPECT_EQ(p.sent(), 4301u);
}

// States that jump past ticks not yet produced (a player that fell behind and lost states) leave
// those ticks' references unsent: counted once as skipped (only the trajectory's ticks, 2000 to
// 6300), never produced later; strides within the lead skip nothing (test above). The tick of
// the state jumped to is not counted: no player produces the tick of the state it handles
// (references go to the ticks after it).
TEST(ReferencePlayer, CountsTheTicksStatesJumpedPastAsSkipped) {
  const Robot& r = robot();
  for (const auto& [jump_to, expected] :
       std::vector<std::pair<std::uint64_t, std::uint64_t>>{{1500, 0}, {3000, 1000}, {9000, 4301}}) {
    SCOPED_TRACE(jump_to);
    reference::Player p(step_in_place(), r.model, r.config, r.model_to_wire, 1e-3, 200);
    std::map<std::uint64_t, int> sent;
    auto emit = [&](const msg::BalanceReference& ref) {
      ++sent[ref.header().tick()];
      return true;
    };
    for (std::uint64_t k = 10; k <= 1000; ++k) p.on_state(state_of(k), emit);  // up to 1200 made
    p.on_state(state_of(jump_to), emit);
    p.on_state(state_of(jump_to + 1), emit);
    for (std::uint64_t k = jump_to + 2; k <= std::max<std::uint64_t>(jump_to + 2, 7000); ++k)
      p.on_state(state_of(k), emit);
    EXPECT_EQ(p.skipped(), expected);
    // Every trajectory tick is sent once or skipped, except the tick of the state jumped to
    // (3000: no player produces the tick of the state it handles).
    std::uint64_t produced = 0;
    for (const auto& [tick, n] : sent) {
      EXPECT_EQ(n, 1) << tick;
      if (tick >= 2000 && tick <= 6300) ++produced;
    }
    EXPECT_EQ(produced + p.skipped(), jump_to == 3000 ? 4300u : 4301u);
  }
  // A first state after the trajectory's first ticks is not a skip: the player cannot tell it
  // from the loop's own first state (poise-sim's first frame is tick 10); started_late() says it.
  for (const std::uint64_t first : {0, 2000, 3000}) {
    reference::Player p(step_in_place(), r.model, r.config, r.model_to_wire, 1e-3, 200);
    for (std::uint64_t k = first; k <= 7000; ++k)
      p.on_state(state_of(k), [](const msg::BalanceReference&) { return true; });
    EXPECT_EQ(p.skipped(), 0u) << "first state " << first;
    EXPECT_EQ(p.started_late(), first >= 2000) << "first state " << first;
  }
}

TEST(ReferencePlayer, TheReferencesOfATickDoNotDependOnWhichStatesItSaw) {
  // A player that skips states (a busy one behind a newest-sample mailbox) computes the time of
  // tick j from another state k. On states that carry the same CoM and feet, its references must
  // still be the same to the bit: the time of tick j comes from integer nanoseconds, not from a
  // double sum t_k + (j - k) * period, whose rounding depends on k.
  const Robot& r = robot();
  reference::Player every(step_in_place(), r.model, r.config, r.model_to_wire, 1e-3, 200);
  const auto a = play(10, 6400, 1, every, false);
  ASSERT_EQ(a.size(), 4301u);
  for (int stride : {3, 7, 50}) {
    reference::Player some(step_in_place(), r.model, r.config, r.model_to_wire, 1e-3, 200);
    const auto b = play(10, 6400, stride, some, false);
    ASSERT_EQ(a.size(), b.size()) << "stride " << stride;
    std::size_t differ = 0;
    for (const auto& [tick, ra] : a) {
      const msg::BalanceReference& rb = b.at(tick);
      bool same = ra.header().stamp_ns() == rb.header().stamp_ns() &&
                  ra.has_com_target() == rb.has_com_target();
      for (int i = 0; i < 3; ++i)
        same = same && ra.com_W()[i] == rb.com_W()[i] &&
               ra.com_velocity_W()[i] == rb.com_velocity_W()[i];
      for (int f = 0; f < 2; ++f)
        same = same && ra.feet()[f].mode() == rb.feet()[f].mode() &&
               ra.feet()[f].target_W().position() == rb.feet()[f].target_W().position() &&
               ra.feet()[f].target_velocity_W().linear() == rb.feet()[f].target_velocity_W().linear();
      differ += same ? 0 : 1;
    }
    EXPECT_EQ(differ, 0u) << "stride " << stride << ": references that differ";
  }
}

TEST(ReferencePlayer, TheOriginAndTheStoodPoseComeFromTheStateLeadTicksAhead) {
  // The CoM origin from the state on which the first move is produced (tick 2000 - 200), the
  // step's stood pose from the state on which the step's first reference is (3700 - 200).
  const Robot& r = robot();
  reference::Player p(step_in_place(), r.model, r.config, r.model_to_wire, 1e-3, 200);
  const auto refs = play(10, 6400, 1, p, true);
  const msg::State s1800 = state_of(1800), s3500 = state_of(3500);
  const msg::BalanceReference& first = refs.at(2000);
  ASSERT_TRUE(first.has_com_target());
  for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(first.com_W()[i], s1800.com_W()[i]);
  const msg::BalanceReference& lift = refs.at(3700);  // the step begins: the right foot swings
  const int right = model::kRight;
  ASSERT_EQ(lift.feet()[right].mode(), msg::FOOT_SWING);
  EXPECT_EQ(lift.feet()[1 - right].mode(), msg::FOOT_SUPPORT);
  for (int i = 0; i < 2; ++i)
    EXPECT_DOUBLE_EQ(lift.feet()[right].target_W().position()[i],
                     s3500.feet()[right].pose_W().position()[i]);
}

// A CoM move `over` a foot: the player resolves it on the state it produces the move's start
// from (lead ticks ahead), so the move ends with the CoM target over that state's left sole
// centre (the foot pose composed with robot.yaml's sole rectangle, computed here).
TEST(ReferencePlayer, AMoveOverAFootEndsOverThatSoleCentre) {
  const Robot& r = robot();
  reference::Trajectory t = step_in_place();
  t.com[0].over = reference::ComOver::kLeft;
  t.com[0].resolved = false;
  reference::Player p(t, r.model, r.config, r.model_to_wire, 1e-3, 200);
  const auto refs = play(10, 6400, 1, p, true);
  const msg::State s1800 = state_of(1800);
  const auto& sole = r.config.feet[model::kLeft].sole;
  const auto& foot = s1800.feet()[model::kLeft].pose_W().position();  // identity orientation
  const double x = foot[0] + 0.5 * (sole.x_min + sole.x_max);
  const double y = foot[1] + 0.5 * (sole.y_min + sole.y_max);
  const msg::BalanceReference& end = refs.at(3500);  // the move is over (2.0 + 1.5 s)
  ASSERT_TRUE(end.has_com_target());
  EXPECT_NEAR(end.com_W()[0], x, 1e-12);
  EXPECT_NEAR(end.com_W()[1], y, 1e-12);
  EXPECT_NEAR(end.com_W()[2], s1800.com_W()[2], 1e-12);  // no vertical change
  // The same references whichever states the player saw (here every 7th).
  reference::Player q(t, r.model, r.config, r.model_to_wire, 1e-3, 200);
  const auto sparse = play(10, 6400, 7, q, true);
  EXPECT_NEAR(sparse.at(3500).com_W()[1], y, 1e-12);
}

TEST(ReferencePlayer, ARestartedStateStreamIsCountedAndNothingIsProducedTwice) {
  const Robot& r = robot();
  reference::Player p(step_in_place(), r.model, r.config, r.model_to_wire, 1e-3, 200);
  std::map<std::uint64_t, int> produced;
  auto feed = [&](std::uint64_t from, std::uint64_t to) {
    for (std::uint64_t k = from; k <= to; ++k)
      p.on_state(state_of(k, false), [&](const msg::BalanceReference& ref) {
        ++produced[ref.header().tick()];
        return true;
      });
  };
  feed(10, 2500);  // references up to tick 2700
  EXPECT_EQ(p.restarts(), 0u);
  const std::uint64_t sent = p.sent();
  feed(1, 2400);  // the robot side restarted: ticks 1.. again
  EXPECT_EQ(p.restarts(), 1u);
  EXPECT_EQ(p.sent(), sent) << "nothing new until the stream is past tick 2500";
  feed(2401, 2600);
  EXPECT_EQ(p.sent(), sent + 100);
  for (const auto& [tick, n] : produced) EXPECT_EQ(n, 1) << "tick " << tick;
}

TEST(ReferencePlayer, ABadSwingJointOrLeadIsRefusedByName) {
  const Robot& r = robot();
  reference::Trajectory t;
  t.name = "bad";
  t.joints.push_back({});
  t.joints.back().joint = "no_such_joint";
  try {
    reference::Player p(t, r.model, r.config, r.model_to_wire, 1e-3, 200);
    FAIL() << "accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_joint"), std::string::npos) << e.what();
  }
  EXPECT_THROW(reference::Player(step_in_place(), r.model, r.config, r.model_to_wire, 1e-3, 0),
               std::runtime_error);
}

TEST(SampleQueue, KeepsEverySampleInOrderAndCountsWhatOverflows) {
  node::SampleQueue<int> q(4);
  for (int i = 1; i <= 3; ++i) q.put(i);
  int v = 0;
  const std::int64_t soon = node::now_ns() + 1000000;
  ASSERT_TRUE(q.pop(v, soon));
  EXPECT_EQ(v, 1);
  for (int i = 4; i <= 8; ++i) q.put(i);  // 2..8 is 7 samples in 4 slots: 2, 3, 4 dropped
  EXPECT_EQ(q.dropped(), 3u);
  std::vector<int> got;
  while (q.pop(v, node::now_ns())) got.push_back(v);
  EXPECT_EQ(got, (std::vector<int>{5, 6, 7, 8}));
  EXPECT_FALSE(q.pop(v, node::now_ns() + 1000000));  // empty: waits until the deadline
}

}  // namespace
