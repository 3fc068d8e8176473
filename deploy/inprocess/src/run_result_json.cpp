#include "poise/inprocess/run_result_json.hpp"

#include <unistd.h>

#include <cmath>
#include <fstream>
#include <stdexcept>

#include "poise/safety/counters_json.hpp"
#include "poise/sim/reality_json.hpp"

namespace poise::inprocess {
namespace {

using Json = nlohmann::json;

Json stats_json(const LatencyStats& s) {
  return {{"count", s.count}, {"mean", s.mean_us}, {"p50", s.p50_us}, {"p99", s.p99_us},
          {"max", s.max_us}};
}

/// The scenario monitor's verdict and measures.
void add_verdict(const RunResult& r, Json& j) {
  j["scenario"] = r.scenario;
  j["survived"] = r.survived;
  j["completed"] = r.completed;
  j["com_error_max_m"] = r.com_error_max_m;
  j["com_error_final_m"] = r.com_error_final_m;
  j["foot_slip_max_m"] = r.foot_slip_max_m;
  j["foot_slide_max_m"] = r.foot_slide_max_m;
  j["foot_displacement_max_m"] = r.foot_displacement_max_m;
  j["foot_tilt_max_deg"] = r.foot_tilt_max_deg;
  j["non_foot_contacts"] = r.non_foot_contacts;
  j["min_base_height_m"] = r.min_base_height_m;
  j["recovery_time_s"] = std::isfinite(r.recovery_time_s) ? Json(r.recovery_time_s) : Json();
  j["trunk_pitch_max_deg"] = r.trunk_pitch_max_deg;
  j["trunk_roll_max_deg"] = r.trunk_roll_max_deg;
  j["failed_criteria"] = r.failed;
  j["controller_fall"] = r.controller_fall.empty()
                             ? Json()
                             : Json{{"time_s", r.controller_fall_time_s},
                                    {"reason", r.controller_fall}};
  if (!r.failed.empty()) {
    std::string why;
    for (const auto& f : r.failed) why += (why.empty() ? "" : "; ") + f;
    j["failure"] = why;
  }
  j["reality"] = sim::reality_to_json(r.reality);
}

/// The robot side: the safety layer's counters and the ticks in each of its modes.
void add_robot_side(const RunResult& r, Json& j) {
  const safety::Counters& c = r.safety;
  j["hold_ticks"] = r.hold_ticks;
  j["damping_ticks"] = r.damping_ticks;
  j["estop_ticks"] = r.estop_ticks;
  j["watchdog_stale_events"] = c.hold_events;
  j["safety"] = safety::counters_to_json(c, r.safety_mode);
  j["max_joint_speed"] = {{"joint", r.fastest_joint}, {"speed", r.max_joint_speed}};
}

/// The loop's times and counts, under the distributed run's names.
void add_loop_figures(const RunResult& r, Json& j) {
  j["tick_latency_us"] = stats_json(r.tick_latency_us);
  j["deadline_misses"] = r.deadline_misses;
  j["deadline_misses_by_node"] = {{"loop", r.deadline_misses}};
  j["realtime_factor"] = r.realtime_factor;
  j["sim_time_s"] = r.sim_time_s;
  j["wall_time_s"] = r.wall_time_s;
  j["ticks"] = r.ticks;
  j["command_timeouts"] = r.command_timeouts;
  j["contact_fallbacks"] = r.contact_fallbacks;
  j["qp_failures"] = r.qp_failures;
  j["rejected_commands"] = r.rejected_commands;
  j["rejected_samples"] = r.invalid_messages;
  j["errors"] = Json::object();
  j["contact_problems_resent"] = 0;  // one thread: a problem is never sent twice
  j["compute_us"] = {{"estimator", stats_json(r.estimator_us)},
                     {"controller", stats_json(r.controller_us)},
                     {"contact", stats_json(r.contact_us)}};
  j["library_us"] = j["compute_us"];
  j["overhead_us"] = Json();   // no node around the libraries
  j["dds_write_us"] = Json();  // no DDS
}

/// The distributed run's kinds of miss; those only a transport or a second process can cause
/// are 0 here by construction.
Json misses(const RunResult& r, const RunFacts& facts) {
  const safety::Counters& c = r.safety;
  return {{"controller_contact_wait", 0},
          {"controller_commands_withheld", 0},
          {"sim_overruns", facts.overruns},
          {"sim_command_timeouts", r.command_timeouts},
          {"robot_hold_ticks", r.hold_ticks},
          {"robot_damping_ticks", r.damping_ticks},
          {"robot_late_commands", c.rejected_tick},
          {"robot_refused_commands", c.rejected - c.rejected_tick},
          {"estimator_dropped_frames", 0},
          {"out_of_sequence", 0},
          {"controller_late_references", 0},
          {"samples_rejected", r.invalid_messages},
          {"robot_foreign_commands", 0}};
}

}  // namespace

Json to_json(const RunResult& r) {
  Json j;
  add_verdict(r, j);
  add_robot_side(r, j);
  add_loop_figures(r, j);
  j["state_source"] = to_string(r.state_source);
  j["in_process"] = true;
  return j;
}

Json to_json(const RunResult& r, const InProcessLoop& loop, const RunFacts& facts) {
  Json j = to_json(r);
  j["misses"] = misses(r, facts);
  j["max_damping_ticks"] = loop.scenario().success.max_damping_ticks;
  j["mode"] = facts.realtime ? "realtime" : "lockstep";
  j["dds"] = Json();
  j["domain"] = Json();
  j["pids"] = {{"poise", static_cast<long long>(::getpid())}};
  j["realtime_settings"] = facts.realtime_settings;
  j["contact_method"] = facts.method;
  const controller::ControllerConfig& cc = loop.controller().config();
  j["contact_priority"] = contact::to_string(cc.contact.priority);
  j["contact_torsion_limit"] = contact::to_string(cc.contact.torsion_limit);
  j["estimator_supports"] = loop.scenario().estimator.supports;
  j["estimator"] = facts.estimator;
  if (!facts.recording.empty()) {
    j["recording"] = facts.recording;
    j["recording_ok"] = facts.recording_error.empty();
  }
  return j;
}

void write_result_file(const std::filesystem::path& path, const Json& j) {
  std::ofstream out(path);
  out << j.dump(2) << "\n";
  if (!out) throw std::runtime_error("cannot write the result file " + path.string());
}

}  // namespace poise::inprocess
