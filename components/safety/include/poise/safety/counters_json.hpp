#pragma once
// The robot side's safety counters as the run results write them (`safety` of poise-sim's
// summary, of `poise run`'s result in both modes). Header-only: the JSON library is the
// caller's (nlohmann/json, as every result writer uses).
#include <nlohmann/json.hpp>

#include "poise/safety/safety_layer.hpp"

namespace poise::safety {

inline nlohmann::json counters_to_json(const Counters& c, Mode mode) {
  return {{"mode", to_string(mode)},
          {"accepted", c.accepted},
          {"rejected", c.rejected},
          {"rejected_size", c.rejected_size},
          {"rejected_non_finite", c.rejected_non_finite},
          {"rejected_gain", c.rejected_gain},
          {"rejected_range", c.rejected_range},
          {"rejected_tick", c.rejected_tick},
          {"ignored_during_estop", c.ignored_estop},
          {"hold_events", c.hold_events},
          {"damp_events", c.damp_events},
          {"estop_events", c.estop_events},
          {"protective_stop_events", c.protective_stop_events},
          {"refused_protective_stops", c.refused_protective_stops},
          {"ticks_protective_stop", c.ticks_protective_stop}};
}

}  // namespace poise::safety
