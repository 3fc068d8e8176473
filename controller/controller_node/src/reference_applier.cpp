#include "poise/controller_node/reference_applier.hpp"

#include <utility>

#include "poise/controller_node/controller_messages.hpp"

namespace poise::controller_node {

ReferenceApplier::ReferenceApplier(std::size_t capacity, std::vector<int> model_to_wire,
                                   double period_s)
    : queue_(capacity),
      model_to_wire_(std::move(model_to_wire)),
      period_s_(period_s),
      previous_wire_q_(msg::MAX_JOINTS, 0.0),
      applied_q_(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model_to_wire_.size()))) {}

ReferenceApplier::Applied ReferenceApplier::apply(std::uint64_t k, bool have_handled,
                                                  std::uint64_t handled,
                                                  controller::BalanceReference& reference) noexcept {
  Applied a;
  const auto due = queue_.take_due(k, have_handled, handled, in_, previous_wire_q_.data(),
                                   previous_wire_q_.size());
  a.late = due.late;
  if (!due.taken) return a;
  a.taken = true;
  a.tick = due.tick;
  a.joint_count = in_.joint_count();
  ++applied_count_;
  if (!from_msg(in_, model_to_wire_, reference)) {
    a.joints_applied = false;
    return a;
  }
  const auto n = static_cast<Eigen::Index>(model_to_wire_.size());
  const bool follows = due.tick > 1 && reference.has_upper_body_q;
  if (follows && due.has_previous) {
    for (Eigen::Index j = 0; j < n; ++j)
      reference.upper_body_qd[j] =
          (reference.upper_body_q[j] -
           previous_wire_q_[static_cast<std::size_t>(model_to_wire_[static_cast<std::size_t>(j)])]) /
          period_s_;
  } else if (follows && applied_has_q_ && applied_tick_ + 1 == due.tick) {
    reference.upper_body_qd = (reference.upper_body_q - applied_q_) / period_s_;
  } else {
    reference.upper_body_qd.setZero();
  }
  applied_q_ = reference.upper_body_q;
  applied_has_q_ = reference.has_upper_body_q;
  applied_tick_ = due.tick;
  return a;
}

}  // namespace poise::controller_node
