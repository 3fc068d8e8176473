// The estimator node's plan queue (estimator/node/include/poise/estimator_node/
// foot_plan_queue.hpp): the plan of tick k is that of the reference with the largest tick <= k,
// held until due, whatever the order of arrival; the same rule as the controller's
// ReferenceQueue, checked here against hand-made sequences.
#include <gtest/gtest.h>

#include "poise/estimator_node/foot_plan_queue.hpp"

namespace poise::estimator_node {
namespace {

using estimator::FootPlan;
constexpr FootPlan N = FootPlan::kNone, S = FootPlan::kSupport, W = FootPlan::kSwing;

TEST(FootPlanQueue, EachPlanAppliesFromItsTickWhateverTheArrivalOrder) {
  FootPlanQueue q(8);
  EXPECT_EQ(q.at(1), (FootPlanQueue::Plans{N, N}));  // no reference yet: no plan
  // Sent ahead, out of order: swing from tick 12, support from tick 10.
  q.put(12, {W, S});
  q.put(10, {S, S});
  EXPECT_EQ(q.at(9), (FootPlanQueue::Plans{N, N}));
  EXPECT_EQ(q.at(10), (FootPlanQueue::Plans{S, S}));
  EXPECT_EQ(q.at(11), (FootPlanQueue::Plans{S, S}));  // held until a later one is due
  EXPECT_EQ(q.at(12), (FootPlanQueue::Plans{W, S}));
  // Two due at once (a sensor tick skipped): the larger tick wins.
  q.put(14, {S, W});
  q.put(13, {W, W});
  EXPECT_EQ(q.at(15), (FootPlanQueue::Plans{S, W}));
  // Tick 0: at once; ties: the later arrival.
  q.put(0, {W, N});
  q.put(0, {N, W});
  EXPECT_EQ(q.at(16), (FootPlanQueue::Plans{N, W}));
  EXPECT_EQ(q.received(), 6u);
  EXPECT_EQ(q.overflows(), 0u);
}

TEST(FootPlanQueue, AFullQueueDropsTheEarliest) {
  FootPlanQueue q(2);
  q.put(5, {S, S});
  q.put(6, {W, S});
  q.put(7, {S, W});  // full: tick 5 dropped
  EXPECT_EQ(q.overflows(), 1u);
  EXPECT_EQ(q.at(5), (FootPlanQueue::Plans{N, N}));
  EXPECT_EQ(q.at(6), (FootPlanQueue::Plans{W, S}));
  EXPECT_EQ(q.at(7), (FootPlanQueue::Plans{S, W}));
}

}  // namespace
}  // namespace poise::estimator_node
