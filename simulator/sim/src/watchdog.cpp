#include "poise/sim/watchdog.hpp"

#include <stdexcept>

namespace poise::sim {

CommandWatchdog::CommandWatchdog(std::int64_t timeout_ns) : timeout_ns_(timeout_ns) {
  if (timeout_ns <= 0) throw std::invalid_argument("CommandWatchdog: timeout must be > 0 ns");
}

void CommandWatchdog::on_command(std::int64_t now_ns) {
  last_command_ns_ = now_ns;
  have_command_ = true;
}

CommandWatchdog::State CommandWatchdog::update(std::int64_t now_ns) {
  if (!have_command_) {
    state_ = State::kWaiting;
  } else if (now_ns - last_command_ns_ > timeout_ns_) {
    if (state_ == State::kActive) ++stale_events_;
    state_ = State::kStale;
  } else {
    state_ = State::kActive;
  }
  return state_;
}

void make_damping_command(double kd, JointCommand& out) {
  out.mode = CommandMode::kDamping;
  out.tau_ff.setZero();
  out.q_ref.setZero();
  out.qd_ref.setZero();
  out.kp.setZero();
  out.kd.setConstant(kd);
}

const JointCommand& select_command(const CommandWatchdog& watchdog, const JointCommand& newest,
                                   JointCommand& damping_cmd) {
  if (!watchdog.damping()) return newest;
  return damping_cmd;
}

}  // namespace poise::sim
