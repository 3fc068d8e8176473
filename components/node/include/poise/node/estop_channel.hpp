#pragma once
// The robot side's end of the e-stop: poise/estop in, poise/estop_state out.
//
//   node::EStopChannel estop(node.participant(), "poise-sim");   // announces: released, request 0
//   node.watch(estop.subscriber());
//   while (const msg::EStop* e = estop.take()) {                  // in the loop
//     safety.on_estop(e->engaged(), safety::to_stop(e->kind()), e->reason().c_str(), q, now);
//     estop.acknowledge(*e, safety.stopped(), safety::held_stop(safety.mode()), tick);
//   }
//
// The state it publishes (reliable, transient-local) names the robot side and echoes the request
// id of the newest stop it applied: `poise estop` counts a robot only by this state, so a
// recorder or a monitor subscribed to poise/estop is never taken for a robot, and it reports
// success only when every robot side it knows of has acknowledged its request.
//
// Real-time: take() does not allocate. acknowledge() publishes one sample, only when a stop
// arrives (an exceptional event, not a per-tick cost).
#include <cstdint>
#include <string>

#include <poise/msg/estop.h>
#include <poise/msg/estop_state.h>

#include "poise/dds/dds.hpp"

namespace poise::node {

/// "<program>@<host name>", the default robot-side name in poise/estop_state (at most 64
/// characters, its IDL bound).
std::string robot_side_name(const std::string& program);

class EStopChannel {
 public:
  /// Subscribes to poise/estop and announces this robot side on poise/estop_state (released,
  /// request 0). `robot` is cut to 64 characters.
  EStopChannel(dds::Participant& participant, const std::string& robot);

  /// The next e-stop sample, or nullptr when none is waiting.
  const msg::EStop* take() noexcept;

  /// Publishes the state after `stop` was applied: `engaged` and `kind` as the safety layer now
  /// holds them (a protective request refused during an emergency stop is acknowledged as the
  /// emergency stop it still holds).
  void acknowledge(const msg::EStop& stop, bool engaged, msg::StopKind kind,
                   std::uint64_t tick) noexcept;

  dds::Subscriber<msg::EStop>& subscriber() noexcept { return in_; }
  std::uint64_t acknowledged() const noexcept { return acknowledged_; }

 private:
  dds::Subscriber<msg::EStop> in_;
  dds::Publisher<msg::EStopState> out_;
  msg::EStop stop_;
  msg::EStopState state_;
  std::uint64_t acknowledged_ = 0;
};

}  // namespace poise::node
