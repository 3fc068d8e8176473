#pragma once
// How poise-controller applies the balance references it holds (reference_queue.hpp) to the
// controller library's reference at the state of tick k: the one due is converted
// (controller_messages.hpp) and, since the IDL has no posture-target velocity, upper_body_qd is
// the difference of the upper-body posture targets of consecutive ticks over the control period
// (a trajectory played per tick), else zero. The in-process loop applies references through the
// same class, so that both give one answer.
//
//   ReferenceApplier refs(512, model_to_wire, period_s);
//   listener thread:  refs.queue().put(msg);
//   state k:          const auto a = refs.apply(k, have_handled, handled, reference);
//
// No allocation and no exception after construction.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "poise/controller/balance_reference.hpp"
#include "poise/controller_node/reference_queue.hpp"

namespace poise::controller_node {

class ReferenceApplier {
 public:
  ReferenceApplier(std::size_t capacity, std::vector<int> model_to_wire, double period_s);

  ReferenceQueue& queue() noexcept { return queue_; }
  const ReferenceQueue& queue() const noexcept { return queue_; }

  struct Applied {
    bool taken = false;          ///< a reference was applied at this tick
    std::uint64_t tick = 0;      ///< its header tick
    std::uint32_t late = 0;      ///< references that arrived after the state of their tick
    bool joints_applied = true;  ///< false: its joint_count is not the robot's (joints ignored)
    std::uint32_t joint_count = 0;
  };

  /// The references due at state tick k into `reference` (model order). `have_handled` /
  /// `handled`: the tick handled before this one (false at the first state).
  Applied apply(std::uint64_t k, bool have_handled, std::uint64_t handled,
                controller::BalanceReference& reference) noexcept;

  /// The state stream restarted: the next reference does not follow the last one applied.
  void restart() noexcept { applied_has_q_ = false; }

  std::uint64_t applied() const noexcept { return applied_count_; }

 private:
  ReferenceQueue queue_;
  std::vector<int> model_to_wire_;
  double period_s_;
  msg::BalanceReference in_;
  std::vector<double> previous_wire_q_;
  Eigen::VectorXd applied_q_;
  bool applied_has_q_ = false;
  std::uint64_t applied_tick_ = 0, applied_count_ = 0;
};

}  // namespace poise::controller_node
