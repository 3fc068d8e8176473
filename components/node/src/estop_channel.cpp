#include "poise/node/estop_channel.hpp"

#include <unistd.h>

namespace poise::node {

std::string robot_side_name(const std::string& program) {
  char host[256] = "";
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::string name = program + "@" + (host[0] != '\0' ? host : "unknown-host");
  if (name.size() > 64) name.resize(64);
  return name;
}

EStopChannel::EStopChannel(dds::Participant& participant, const std::string& robot)
    : in_(participant), out_(participant) {
  state_.robot(robot.size() > 64 ? robot.substr(0, 64) : robot);
  state_.engaged(false);
  state_.request(0);
  out_.publish(state_);
}

const msg::EStop* EStopChannel::take() noexcept {
  return in_.take(stop_) ? &stop_ : nullptr;
}

void EStopChannel::acknowledge(const msg::EStop& stop, bool engaged, msg::StopKind kind,
                               std::uint64_t tick) noexcept {
  state_.header().tick(tick);
  state_.engaged(engaged);
  state_.kind(kind);
  state_.request(stop.request());
  state_.source(stop.source());
  if (out_.publish(state_)) ++acknowledged_;
}

}  // namespace poise::node
