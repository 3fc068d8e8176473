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
// Fixed storage allocated at construction; put() and at() neither allocate nor throw.

#include <array>
#include <cstdint>
#include <memory>
#include <mutex>

#include "poise/estimator/types.hpp"

namespace poise::estimator_node {

class FootPlanQueue {
 public:
  using Plans = std::array<estimator::FootPlan, estimator::kNumFeet>;

  explicit FootPlanQueue(std::size_t capacity)
      : slots_(std::make_unique<Slot[]>(capacity < 1 ? 1 : capacity)),
        capacity_(capacity < 1 ? 1 : capacity) {}
  FootPlanQueue(const FootPlanQueue&) = delete;
  FootPlanQueue& operator=(const FootPlanQueue&) = delete;

  /// Holds the plan of a reference for `tick`. When every slot is taken the one with the
  /// smallest tick is dropped (counted in overflows()).
  void put(std::uint64_t tick, const Plans& plans) noexcept {
    std::lock_guard lock(mutex_);
    std::size_t slot = capacity_;
    for (std::size_t i = 0; i < capacity_ && slot == capacity_; ++i)
      if (!slots_[i].used) slot = i;
    if (slot == capacity_) {
      slot = 0;
      for (std::size_t i = 1; i < capacity_; ++i)
        if (slots_[i].tick < slots_[slot].tick) slot = i;
      ++overflows_;
    }
    slots_[slot] = Slot{true, tick, ++arrivals_, plans};
  }

  /// The plan in force at sensor tick k (see the header comment).
  Plans at(std::uint64_t k) noexcept {
    std::lock_guard lock(mutex_);
    std::size_t best = capacity_;
    for (std::size_t i = 0; i < capacity_; ++i) {
      const Slot& s = slots_[i];
      if (!s.used || s.tick > k) continue;
      if (best == capacity_ || s.tick > slots_[best].tick ||
          (s.tick == slots_[best].tick && s.order > slots_[best].order))
        best = i;
    }
    if (best == capacity_) return current_;
    current_ = slots_[best].plans;
    for (std::size_t i = 0; i < capacity_; ++i)
      if (slots_[i].used && slots_[i].tick <= k) slots_[i].used = false;
    return current_;
  }

  std::uint64_t received() const noexcept {
    std::lock_guard lock(mutex_);
    return arrivals_;
  }
  std::uint64_t overflows() const noexcept {
    std::lock_guard lock(mutex_);
    return overflows_;
  }

 private:
  struct Slot {
    bool used = false;
    std::uint64_t tick = 0;
    std::uint64_t order = 0;
    Plans plans{estimator::FootPlan::kNone, estimator::FootPlan::kNone};
  };
  mutable std::mutex mutex_;
  std::unique_ptr<Slot[]> slots_;
  std::size_t capacity_;
  Plans current_{estimator::FootPlan::kNone, estimator::FootPlan::kNone};
  std::uint64_t arrivals_ = 0;
  std::uint64_t overflows_ = 0;
};

}  // namespace poise::estimator_node
