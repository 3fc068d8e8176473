#pragma once
// Command watchdog of the real-time mode: the robot ticks on the wall clock and uses the newest
// command; when no fresh command arrived for `timeout_ns` it switches to damping mode, and it
// resumes control as soon as commands come back. The clock is an input (nanoseconds, any
// monotonic origin), so the logic is testable with a fake clock. Real-time safe: no allocation.

#include <cstdint>

#include "poise/sim/types.hpp"

namespace poise::sim {

class CommandWatchdog {
 public:
  enum class State : std::uint8_t {
    kWaiting = 0,  ///< no command received yet: damping
    kActive = 1,   ///< commands are fresh: the newest command is applied
    kStale = 2,    ///< commands went stale: damping until the next fresh command
  };

  /// timeout_ns: longest allowed gap between commands (default 5 ms). Throws if <= 0.
  explicit CommandWatchdog(std::int64_t timeout_ns = 5'000'000);

  /// A command arrived at time now_ns.
  void on_command(std::int64_t now_ns);

  /// Evaluates the state at time now_ns (call once per tick before stepping).
  State update(std::int64_t now_ns);

  State state() const { return state_; }
  /// True when the robot must be damped (waiting or stale).
  bool damping() const { return state_ != State::kActive; }
  /// Number of transitions active -> stale since construction.
  std::int64_t stale_events() const { return stale_events_; }
  std::int64_t timeout_ns() const { return timeout_ns_; }

 private:
  std::int64_t timeout_ns_;
  std::int64_t last_command_ns_ = 0;
  bool have_command_ = false;
  State state_ = State::kWaiting;
  std::int64_t stale_events_ = 0;
};

/// Fills `out` (already sized) with a damping command tau = -kd qd for every joint.
void make_damping_command(double kd, JointCommand& out);

/// The command to apply this tick: `newest` when the watchdog is active, else a damping command
/// written into `damping_cmd` (pre-sized). Returns a reference to the one to use.
const JointCommand& select_command(const CommandWatchdog& watchdog, const JointCommand& newest,
                                   JointCommand& damping_cmd);

}  // namespace poise::sim
