// `poise run`'s result file and summary lines: the components' summaries read back, the
// scenario's criteria applied, the failed result of a run that could not finish.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "poise/contact/contact_optimizer.hpp"
#include "run_distributed.hpp"

namespace poise::launch::distributed {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

Json read_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return Json();
  try {
    return Json::parse(in);
  } catch (...) {
    return Json();
  }
}

/// The summary files the components wrote at their end (null where one wrote none).
struct Summaries {
  Json sim, ctrl, est, con, ref;
};

Summaries read_summaries(const Plan& p) {
  Summaries j;
  j.sim = read_json(p.logs / "sim.summary.json");
  j.ctrl = read_json(p.logs / "controller.summary.json");
  j.est = read_json(p.logs / "estimator.summary.json");
  j.con = read_json(p.logs / "contact.summary.json");
  j.ref = p.scenario.reference.empty() ? Json() : read_json(p.logs / "reference.summary.json");
  return j;
}

/// A counter of a node's diagnostics (0 if none).
std::uint64_t diag(const Json& j, const char* key) {
  return j.is_object() && j.contains("diagnostics") ? j["diagnostics"].value(key, 0ULL) : 0ULL;
}

/// A non-negative count of a summary (0 if missing or not an integer).
std::uint64_t num(const Json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_number_unsigned()
             ? j[key].get<std::uint64_t>()
             : (j.is_object() && j.contains(key) && j[key].is_number_integer()
                    ? static_cast<std::uint64_t>(
                          std::max<std::int64_t>(0, j[key].get<std::int64_t>()))
                    : 0ULL);
}

/// The result's measures: the simulator's verdict and metrics, the nodes' diagnostics and
/// compute times.
Json result_from_summaries(const Plan& p, const Summaries& j) {
  Json r;
  r["scenario"] = p.scenario.name;
  r["survived"] = j.sim.value("survived", false);
  r["completed"] = j.sim.value("completed", false);
  for (const char* k : {"com_error_max_m",
                        "com_error_final_m",
                        "foot_slip_max_m",
                        "foot_slide_max_m",
                        "foot_displacement_max_m",
                        "foot_tilt_max_deg",
                        "non_foot_contacts",
                        "min_base_height_m",
                        "recovery_time_s",
                        "trunk_pitch_max_deg",
                        "trunk_roll_max_deg",
                        "failed_criteria",
                        "tick_latency_us",
                        "realtime_factor",
                        "sim_time_s",
                        "wall_time_s",
                        "command_timeouts",
                        "damping_ticks",
                        "watchdog_stale_events",
                        "hold_ticks",
                        "estop_ticks",
                        "safety",
                        "max_joint_speed",
                        "reality"})
    r[k] = j.sim.value(k, Json());
  // The controller's and the simulator's counts, under the in-process result's names.
  r["ticks"] = num(j.ctrl, "controller_ticks");
  r["contact_fallbacks"] = num(j.ctrl, "late_solutions");
  r["qp_failures"] = num(j.ctrl, "qp_failures");
  r["rejected_commands"] = num(j.sim, "rejected_commands");
  r["in_process"] = false;
  const std::uint64_t misses_sim = diag(j.sim, "deadline_misses");
  const std::uint64_t misses_ctrl = diag(j.ctrl, "deadline_misses");
  r["deadline_misses"] = misses_sim + misses_ctrl;
  r["deadline_misses_by_node"] = {{"sim", misses_sim}, {"controller", misses_ctrl}};
  r["rejected_samples"] = diag(j.sim, "rejected_samples") + diag(j.ctrl, "rejected_samples") +
                          diag(j.est, "rejected_samples") + diag(j.con, "rejected_samples");
  r["errors"] = {{"sim", diag(j.sim, "errors")},
                 {"estimator", diag(j.est, "errors")},
                 {"contact", diag(j.con, "errors")},
                 {"controller", diag(j.ctrl, "errors")}};
  r["compute_us"] = Json::object();    // per node, whole run: sim = step, controller = own
  r["library_us"] = Json::object();    // the library call alone (estimator, controller, contact)
  r["overhead_us"] = Json::object();   // the node's own work around it, DDS write excluded
  r["dds_write_us"] = Json::object();  // its DDS writes (serialisation + vendor write)
  for (const auto& [name, s] : {std::pair<std::string, const Json*>{"sim", &j.sim},
                                {"estimator", &j.est},
                                {"contact", &j.con},
                                {"controller", &j.ctrl}}) {
    r["compute_us"][name] = s->is_object() ? s->value("compute_us_run", Json()) : Json();
    if (s->is_object() && s->contains("library_us_run")) {
      r["library_us"][name] = (*s)["library_us_run"];
      r["overhead_us"][name] = (*s)["overhead_us_run"];
      if (s->contains("dds_write_us_run")) r["dds_write_us"][name] = (*s)["dds_write_us_run"];
    }
  }
  return r;
}

/// Every kind of miss, per node and for the loop (a miss = a tick not handled as designed):
/// returned and set as r["misses"].
Json count_misses(const Summaries& j, Json& r) {
  const Json safety = j.sim.value("safety", Json::object());
  Json misses;
  misses["controller_contact_wait"] = diag(j.ctrl, "deadline_misses");
  misses["controller_commands_withheld"] = num(j.ctrl, "commands_withheld");
  misses["sim_overruns"] = num(j.sim, "overruns");
  misses["sim_command_timeouts"] = num(j.sim, "command_timeouts");
  misses["robot_hold_ticks"] = num(j.sim, "hold_ticks");
  misses["robot_damping_ticks"] = num(j.sim, "damping_ticks");
  misses["robot_late_commands"] = num(safety, "rejected_tick");
  misses["robot_refused_commands"] = num(safety, "rejected") - num(safety, "rejected_tick");
  misses["estimator_dropped_frames"] = num(j.est, "dropped_frames");
  misses["out_of_sequence"] = num(j.est, "out_of_sequence") + num(j.ctrl, "out_of_sequence");
  // Balance references that reached the controller after the state of their tick (a reference
  // player that fell behind: each applied a tick late).
  misses["controller_late_references"] = num(j.ctrl, "late_references");
  r["contact_problems_resent"] = num(j.ctrl, "problems_resent");  // not a miss: a repeat
  misses["samples_rejected"] = r["rejected_samples"];
  misses["robot_foreign_commands"] = num(j.sim, "foreign_commands");
  r["misses"] = misses;
  return misses;
}

/// The robot side's criteria: damping ticks over the scenario's tolerance, commands from a
/// second writer.
void apply_robot_criteria(const Plan& p, const Summaries& j, Json& r) {
  // A damping tick is a lost tick of balance control: the run fails above the scenario's
  // tolerance (success.max_damping_ticks, default 0).
  const long long damping_tolerance = p.scenario.success.max_damping_ticks;
  r["max_damping_ticks"] = damping_tolerance;
  if (!r["failed_criteria"].is_array()) r["failed_criteria"] = Json::array();
  if (static_cast<long long>(num(j.sim, "damping_ticks")) > damping_tolerance) {
    r["failed_criteria"].push_back(std::to_string(num(j.sim, "damping_ticks")) +
                                   " damping ticks > " + std::to_string(damping_tolerance));
    r["survived"] = false;
  }
  // One commanding writer: joint commands from anyone else on the domain were refused by the
  // robot side; the run is not the scenario's (someone else tried to command the robot).
  if (num(j.sim, "foreign_commands") > 0) {
    r["failed_criteria"].push_back(
        std::to_string(num(j.sim, "foreign_commands")) +
        " joint commands from a second writer of poise/joint_command were refused (another "
        "process on the domain commanded the robot; the simulator's log names both writers)");
    r["survived"] = false;
  }
}

/// The balance reference's criteria: played in full, and in lockstep applied at its tick.
void apply_reference_criteria(const Settings& s, const Plan& p, const Summaries& j, Json& r) {
  // The scenario's reference trajectory must have been played in full: a player that fell
  // behind the state stream never sends the references of the ticks it skipped (a step in place
  // that never stepped "survived" before). The in-process loop's player sees every state: it skips
  // none.
  if (!p.scenario.reference.empty()) {
    r["misses"]["reference_skipped_ticks"] = num(j.ref, "skipped_ticks");
    if (num(j.ref, "skipped_ticks") > 0)
      r["failed_criteria"].push_back(
          "the reference player skipped " + std::to_string(num(j.ref, "skipped_ticks")) +
          " ticks of the trajectory (it fell behind the state stream): the scenario's "
          "reference was not played in full");
    if (!j.ref.is_object())
      r["failed_criteria"].push_back("the reference player wrote no summary (" +
                                     (p.logs / "reference.summary.json").string() + ")");
    if (num(j.ref, "skipped_ticks") > 0 || !j.ref.is_object()) r["survived"] = false;
  }
  // In lockstep the run is the scenario only if every balance reference was applied at its
  // tick: a late one (the player starved of CPU) makes a different run than in process.
  if (!s.realtime && num(j.ctrl, "late_references") > 0) {
    r["failed_criteria"].push_back(
        std::to_string(num(j.ctrl, "late_references")) +
        " balance references reached the controller after their tick (the reference player "
        "fell behind): this lockstep run does not follow the scenario");
    r["survived"] = false;
  }
}

/// The controller declared a fall (FallConfig): it damps the joints from then on.
void apply_fall(const Plan& p, const Summaries& j, Json& r) {
  r["controller_fall"] = Json();
  if (j.ctrl.is_object() && j.ctrl.value("fall_tick", -1LL) >= 0) {
    const double t = static_cast<double>(j.ctrl.value("fall_tick", -1LL)) * p.ccfg.dt;
    const std::string why = j.ctrl.value("fall", std::string());
    r["controller_fall"] = {{"time_s", t}, {"reason", why}};
    r["recovery_time_s"] = Json();  // a fall never recovered (null, as in process)
    char ts[32];
    std::snprintf(ts, sizeof ts, "%.3f", t);
    r["failed_criteria"].push_back("the controller declared a fall at " + std::string(ts) + " s (" +
                                   why + "): joints damped");
    r["survived"] = false;
  }
}

/// The failed criteria in one line, also set as r["failure"] ("" when none failed).
std::string verdict_reason(Json& r) {
  std::string reason;
  for (const auto& f : r["failed_criteria"])
    reason += (reason.empty() ? "" : "; ") + f.get<std::string>();
  if (!reason.empty()) r["failure"] = reason;
  return reason;
}

/// How the run was made: real-time settings, state source, vendors, domain, mode, contact
/// optimiser, estimator, recording and pids.
void add_run_facts(const Settings& s, const Plan& p, const Processes& procs,
                   const std::string& record_problem, const Summaries& j, Json& r) {
  // What each process got of the real-time settings (applied or refused, thread policies,
  // page faults after its first tick).
  r["realtime_settings"] = Json::object();
  for (const auto& [name, sj] : {std::pair<std::string, const Json*>{"sim", &j.sim},
                                 {"estimator", &j.est},
                                 {"contact", &j.con},
                                 {"controller", &j.ctrl}})
    if (sj->is_object() && sj->contains("realtime"))
      r["realtime_settings"][name] = (*sj)["realtime"];
  r["state_source"] = s.ground_truth_state ? "ground_truth" : "estimator";
  r["dds"] = p.vendor;
  r["domain"] = p.domain;
  r["mode"] = s.realtime ? "realtime" : "lockstep";
  r["contact_method"] = s.method;
  r["contact_priority"] = contact::to_string(p.ccfg.contact.priority);
  r["contact_torsion_limit"] = contact::to_string(p.ccfg.contact.torsion_limit);
  r["estimator_supports"] = p.scenario.estimator.supports;
  r["estimator"] = s.estimator;
  if (procs.recorder) {
    r["recording"] = procs.recording.string();
    r["recording_ok"] = record_problem.empty();
  }
  r["pids"] = Json::object();
  for (const Child* c : procs.children)
    r["pids"][c->name()] = c->pid();
  if (procs.recorder) r["pids"]["recorder"] = procs.recorder->pid();
}

void print_misses(const Json& misses, const std::string& verdict_reason) {
  const auto n = [&](const char* key) {
    return static_cast<unsigned long long>(misses[key].get<std::uint64_t>());
  };
  std::printf(
      "  misses: contact wait %llu, commands withheld %llu, sim overruns %llu, hold ticks %llu, "
      "damping ticks %llu, late commands %llu, refused commands %llu, dropped frames %llu, "
      "out of sequence %llu, rejected samples %llu, late references %llu%s%s\n",
      n("controller_contact_wait"), n("controller_commands_withheld"), n("sim_overruns"),
      n("robot_hold_ticks"), n("robot_damping_ticks"), n("robot_late_commands"),
      n("robot_refused_commands"), n("estimator_dropped_frames"), n("out_of_sequence"),
      n("samples_rejected"), n("controller_late_references"),
      verdict_reason.empty() ? "" : ": FAILED on ", verdict_reason.c_str());
}

/// With real-time settings: one line per process, what it got, and any refusal in full (never
/// silent, not even with --quiet).
void print_realtime_settings(const Settings& s, const Json& r) {
  if (!(s.rt_priority > 0 || s.lock_memory || !s.cpus.empty())) return;
  const Json& settings = r["realtime_settings"];
  for (auto it = settings.begin(); it != settings.end(); ++it) {
    std::string got;
    for (const auto& a : it.value().value("applied", Json::array()))
      got += (got.empty() ? "" : ", ") + a.get<std::string>();
    if (!s.quiet)
      std::printf("  real time %s: %s\n", it.key().c_str(),
                  got.empty() ? "nothing applied" : got.c_str());
    for (const auto& a : it.value().value("refused", Json::array()))
      std::printf("  real time %s: %s\n", it.key().c_str(), a.get<std::string>().c_str());
  }
}

void print_compute_times(const Json& r) {
  for (const char* node : {"estimator", "controller", "contact"})
    if (r["library_us"].contains(node)) {
      // Per-part percentiles (they do not add up; the means do: library + node + dds write =
      // compute).
      const Json none = Json::object();
      const Json& w = r["dds_write_us"].contains(node) ? r["dds_write_us"][node] : none;
      std::printf(
          "  %s compute p50/p99 %.0f/%.0f us = library %.1f/%.1f us + node %.1f/%.1f us "
          "+ dds write %.1f/%.1f us\n",
          node, r["compute_us"][node].value("p50", 0.0), r["compute_us"][node].value("p99", 0.0),
          r["library_us"][node].value("p50", 0.0), r["library_us"][node].value("p99", 0.0),
          r["overhead_us"][node].value("p50", 0.0), r["overhead_us"][node].value("p99", 0.0),
          w.value("p50", 0.0), w.value("p99", 0.0));
    }
}

/// The verdict line (printed even with --quiet).
void print_verdict(const Settings& s, const Plan& p, const Json& r,
                   const std::string& verdict_reason) {
  const Json& lat = r["tick_latency_us"];
  const std::map<std::string, std::string>& vendor = p.vendor;
  std::printf(
      "%s %s (%s, %s)%s%s: com_error max %.3f m final %.3f m, foot slip %.4f m tilt %.1f deg, "
      "non-foot "
      "contacts %d, trunk pitch/roll max %.1f/%.1f deg, tick latency p50/p99/max %.0f/%.0f/%.0f "
      "us, deadline misses %llu, %.2fx real time -> %s\n",
      r["survived"].get<bool>() ? "SURVIVED" : "FAILED", p.scenario.name.c_str(),
      s.realtime ? "realtime" : "lockstep",
      vendor.at("sim") == vendor.at("controller") && vendor.at("sim") == vendor.at("estimator") &&
              vendor.at("sim") == vendor.at("contact")
          ? vendor.at("sim").c_str()
          : "mixed dds",
      verdict_reason.empty() ? "" : " on ", verdict_reason.c_str(), r.value("com_error_max_m", 0.0),
      r.value("com_error_final_m", 0.0), r.value("foot_slip_max_m", 0.0),
      r.value("foot_tilt_max_deg", 0.0), r.value("non_foot_contacts", 0),
      r.value("trunk_pitch_max_deg", 0.0), r.value("trunk_roll_max_deg", 0.0),
      lat.is_object() ? lat.value("p50", 0.0) : 0.0, lat.is_object() ? lat.value("p99", 0.0) : 0.0,
      lat.is_object() ? lat.value("max", 0.0) : 0.0,
      static_cast<unsigned long long>(r["deadline_misses"].get<std::uint64_t>()),
      r.value("realtime_factor", 0.0), p.output.c_str());
  std::fflush(stdout);
}

}  // namespace

void write_failure(const Settings& s, const Plan& p, Processes& procs, const std::string& reason) {
  Json r;
  r["scenario"] = p.scenario.name;
  r["survived"] = false;
  r["completed"] = false;
  r["failed"] = true;
  r["failure"] = reason;
  r["mode"] = s.realtime ? "realtime" : "lockstep";
  r["dds"] = p.vendor;
  r["domain"] = p.domain;
  r["logs"] = p.logs.string();
  r["exits"] = Json::object();
  r["pids"] = Json::object();
  for (auto& c : procs.children) {
    c->poll();
    r["exits"][c->name()] = c->exit_description();
    r["pids"][c->name()] = c->pid();
  }
  if (procs.recorder) {
    procs.recorder->poll();
    r["exits"]["recorder"] = procs.recorder->exit_description();
    r["pids"]["recorder"] = procs.recorder->pid();
    r["recording"] = procs.recording.string();
  }
  std::ofstream(p.output) << r.dump(2) << "\n";
  std::fprintf(stderr, "poise run %s: result (failed) -> %s\n", p.scenario.name.c_str(),
               p.output.c_str());
}

int write_result(const Settings& s, const Plan& p, Processes& procs,
                 const std::string& record_problem) {
  const Summaries j = read_summaries(p);
  if (j.sim.is_null()) {
    std::fprintf(stderr, "poise run: the simulator wrote no result (%s)\n",
                 (p.logs / "sim.summary.json").c_str());
    write_failure(s, p, procs,
                  "the simulator wrote no result (" + (p.logs / "sim.summary.json").string() + ")");
    return 2;
  }
  Json r = result_from_summaries(p, j);
  const Json misses = count_misses(j, r);
  apply_robot_criteria(p, j, r);
  apply_reference_criteria(s, p, j, r);
  apply_fall(p, j, r);
  const std::string reason = verdict_reason(r);
  add_run_facts(s, p, procs, record_problem, j, r);
  {
    std::ofstream out(p.output);
    out << r.dump(2) << "\n";
  }
  if (!s.quiet) print_misses(misses, reason);
  print_realtime_settings(s, r);
  if (!s.quiet) print_compute_times(r);
  print_verdict(s, p, r, reason);
  if (!record_problem.empty()) return 2;
  return r["survived"].get<bool>() ? 0 : 1;
}

}  // namespace poise::launch::distributed
