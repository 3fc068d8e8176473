#pragma once
// The feet's planned modes of the balance references (poise/balance_reference, FootMode), held
// until the tick they are for, as the contact detector's prior (contact_detector.hpp).
//
//   FootPlanQueue plans(512);
//   listener thread:  plans.put(ref.header().tick(), {plan of ref.feet()[0], of ref.feet()[1]});
//   sensor tick k:    frame.foot_plan = plans.at(k);
//
// The same timing rule as the controller's ReferenceQueue (idl/balance_reference.idl: header.tick
// is the first tick a reference applies to, 0 = at once): at tick k every held plan with a tick
// <= k is removed and the one with the largest tick (ties: the one that arrived last) becomes the
// plan in force, which stays until a later one is due. A player that sends its references ahead
// (`poise reference play`) thus gives the estimator the same plan of tick k as the controller,
// whatever the order in which DDS delivers. Before any reference every foot is kNone (no plan).
// node::TickQueue underneath: fixed storage allocated at construction; put() and at() neither
// allocate nor throw.

#include <array>
#include <cstdint>

#include "poise/estimator/types.hpp"
#include "poise/node/tick_queue.hpp"

namespace poise::estimator_node {

class FootPlanQueue {
 public:
  using Plans = std::array<estimator::FootPlan, estimator::kNumFeet>;

  explicit FootPlanQueue(std::size_t capacity) : queue_(capacity) {}

  /// Holds the plan of a reference for `tick`. When every slot is taken the one with the
  /// smallest tick is dropped (counted in overflows()).
  void put(std::uint64_t tick, const Plans& plans) noexcept { queue_.put(tick, plans); }

  /// The plan in force at sensor tick k (see the header comment). One thread calls it.
  Plans at(std::uint64_t k) noexcept {
    queue_.take_due(k, current_, [](std::uint64_t, const Plans&) {});
    return current_;
  }

  std::uint64_t received() const noexcept { return queue_.received(); }
  std::uint64_t overflows() const noexcept { return queue_.overflows(); }

 private:
  node::TickQueue<Plans> queue_;
  Plans current_{estimator::FootPlan::kNone, estimator::FootPlan::kNone};
};

}  // namespace poise::estimator_node
