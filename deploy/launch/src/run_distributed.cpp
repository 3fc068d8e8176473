// `poise run SCENARIO` in its distributed form: four processes over loopback DDS.
#include <signal.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdlib>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <thread>

#include "poise/cli/parse.hpp"
#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/dds/domain_claim.hpp"
#include "poise/dds/vendor.hpp"
#include "poise/launch/child.hpp"
#include "poise/launch/deployment.hpp"
#include "poise/launch/launch.hpp"
#include "poise/launch/log_dir.hpp"
#include "poise/launch/run_settings.hpp"
#include "poise/launch/supervisor.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/realtime.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/sim_config.hpp"
#include "run_distributed.hpp"

namespace poise::launch {
namespace distributed {
namespace {

namespace fs = std::filesystem;

std::atomic<bool> g_interrupted{false};
extern "C" void on_interrupt(int) {
  g_interrupted.store(true);
}

/// "cyclonedds" (scenario files) -> "cyclone"; validates.
std::string vendor_name(const std::string& v) {
  const std::string n = v == "cyclonedds" ? "cyclone" : v == "fastrtps" ? "fastdds" : v;
  return std::string(dds::to_string(dds::parse_vendor(n)));
}

/// SCHED_FIFO priority of a component for `poise run --rt-priority P`: the simulator (the robot
/// side, its safety layer and the clock) at P; the controller chain below it, each stage above
/// the one that feeds it (estimator P-3 < controller P-2 < contact P-1), so that a stage woken
/// by its input preempts whatever fed it and the tick drains without waiting.
int rt_priority_of(const std::string& component, int base) {
  if (base <= 0) return 0;
  const int below = component == "sim"          ? 0
                    : component == "contact"    ? 1
                    : component == "controller" ? 2
                                                : 3;
  return std::max(1, base - below);
}

/// Waits until the recorder child says it is recording (its subscribers exist), it exits, or
/// `timeout_s` passes. Returns "" when ready, else what went wrong.
std::string wait_for_recorder(Child& recorder, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    const std::string tail = tail_lines(recorder.stderr_path(), 20);
    if (tail.find("poise record: error") != std::string::npos) {
      // It exits after saying why (a passive recorder without CAP_NET_RAW, a bad path).
      recorder.stop(3000);
      return "the recorder failed:\n" + recorder.stderr_tail(8);
    }
    if (tail.find("poise record: ") != std::string::npos) return "";
    if (auto code = recorder.poll())
      return "the recorder " + recorder.exit_description() + ":\n" + recorder.stderr_tail(8);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return "the recorder did not start within " + std::to_string(timeout_s) + " s";
}

/// The writers the recorder has matched, per topic, from its "poise record: TOPIC: N writers"
/// lines (the last line of each topic counts).
std::map<std::string, int> recorder_writers(const fs::path& stderr_path) {
  std::map<std::string, int> out;
  std::ifstream in(stderr_path);
  std::string line;
  const std::string prefix = "poise record: poise/";
  while (std::getline(in, line)) {
    const auto at = line.find(prefix);
    if (at == std::string::npos) continue;
    const auto colon = line.find(": ", at + prefix.size());
    if (colon == std::string::npos) continue;
    const std::string topic = line.substr(at + 14, colon - at - 14);
    const std::string rest = line.substr(colon + 2);
    if (rest.find(" writer") == std::string::npos) continue;
    try {
      out[topic] = std::stoi(rest);
    } catch (const std::exception&) {
    }
  }
  return out;
}

/// Topics a recorder must have matched, with the number of writers, before the run starts: what
/// a writer's reader matches late is missing from the file (mixed-vendor endpoint discovery takes
/// ~1 s, longer than a lockstep run's first second).
const std::vector<std::pair<std::string, int>>& stack_writers() {
  static const std::vector<std::pair<std::string, int>> w{
      {"poise/robot_description", 1}, {"poise/sensors", 1},
      {"poise/ground_truth", 1},      {"poise/state", 1},
      {"poise/contact_problem", 1},   {"poise/contact_solution", 1},
      {"poise/joint_command", 1},     {"poise/diagnostics", 4}};
  return w;
}

/// `poise run`'s options of the scenario, the mode, the vendors, the domain and the run's files.
void add_scenario_options(CLI::App& app, Settings& s) {
  app.add_option("scenario", s.scenario, "scenario YAML file, or a name in deploy/scenarios/")
      ->required();
  app.add_flag("--in-process", s.in_process,
               "every component in this process, no DDS (the footer says what each option does "
               "then)");
  auto* lock =
      app.add_flag("--lockstep", s.lockstep, "simulator steps k+1 only after command k (default)");
  app.add_flag("--realtime", s.realtime, "simulator ticks at 1 kHz on the wall clock")
      ->excludes(lock);
  const auto vendors = CLI::IsMember({"fastdds", "cyclone", "cyclonedds"});
  app.add_option("--dds", s.dds_all,
                 "DDS vendor of every component (default: scenario hint, else "
                 "cyclone)")
      ->check(vendors);
  app.add_option("--dds-sim", s.dds_sim, "vendor of the simulator")->check(vendors);
  app.add_option("--dds-estimator", s.dds_estimator, "vendor of the estimator")->check(vendors);
  app.add_option("--dds-contact", s.dds_contact, "vendor of the contact optimiser")->check(vendors);
  app.add_option("--dds-controller", s.dds_controller, "vendor of the controller")->check(vendors);
  app.add_option("--domain", s.domain,
                 "DDS domain id (default: $POISE_DDS_DOMAIN, else a free one in 50..100)")
      ->check(CLI::Range(0, 232));
  app.add_option("--output,-o", s.output,
                 "JSON result file (default: results/<scenario>.json; <scenario>.2.json and so "
                 "on while another run holds the default log directory)");
  app.add_option("--log-dir", s.log_dir,
                 "children's stdout/stderr and summaries, held by this run alone: one in use by "
                 "another run is refused (default: results/<scenario>.logs, or the first free "
                 "results/<scenario>.2.logs, .3.logs, ... while other runs of a scenario of this "
                 "name hold it)");
  app.add_option("--duration", s.duration, "override the scenario duration [s]")
      ->check(CLI::Range(0.0, 1e6));
}

/// `poise run`'s options of the components: estimator, contact optimiser, controller, timing
/// and the robot's safety layer.
void add_component_options(CLI::App& app, Settings& s) {
  app.add_flag("--ground-truth-state", s.ground_truth_state,
               "DEBUG: the estimator sends the simulator's ground truth as the state");
  app.add_option("--estimator", s.estimator,
                 "estimator that publishes poise/state: invariant-ekf or leg-odometry (the "
                 "baseline; default: the scenario's estimator.type, else invariant-ekf; "
                 "estimator/README.md)")
      ->check(CLI::IsMember({"invariant-ekf", "leg-odometry"}));
  app.add_option("--method,--contact-method", s.method,
                 "contact optimiser: sequential (paper) or qp (default: the scenario's "
                 "contact.method, else sequential)")
      ->check(CLI::IsMember({"sequential", "qp"}));
  app.add_option("--controller-config", s.controller_config,
                 "controller YAML (controller/momentum/config/balance_controller.yaml); replaces "
                 "the scenario's controller: section (default: that section, else the built-in "
                 "values). Its contact.priority goes to poise-contact as --priority")
      ->check(CLI::ExistingFile);
  app.add_option("--contact-deadline-us", s.contact_deadline_us,
                 "controller's wait for a contact solution (default 400 real time, 1e6 lockstep)");
  app.add_option("--command-timeout-ms", s.command_timeout_ms,
                 "lockstep: simulator's wait for a joint command; the estimator's and the "
                 "controller's --input-stale-ms too")
      ->check(CLI::Range(1, 600000))
      ->capture_default_str();
  app.add_option("--settle-ticks", s.settle_ticks,
                 "start-up: simulator steps with the joints held by the safety layer before the "
                 "first sensor frame (default: poise-sim's, 10)")
      ->check(CLI::Range(0, 10000));
  app.add_option("--watchdog-ms", s.watchdog_ms,
                 "robot safety layer: HOLD after this long without a joint command (default: "
                 "poise-sim's, 5)")
      ->check(CLI::Range(0.1, 60000.0));
  app.add_option("--hold-s", s.hold_s,
                 "robot safety layer: hold the last targets this long, then damp (default: "
                 "poise-sim's, 5)")
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--timeout", s.timeout_s,
                 "wall-clock bound of the whole run [s] "
                 "(default: 60 + 30 x duration lockstep, 60 + duration real time)");
  app.add_flag("-q,--quiet", s.quiet, "only the verdict line");
}

/// `poise run`'s options of the recording, DDS Security and real-time scheduling. Returns the
/// --record option (given with or without a file).
const CLI::Option* add_record_and_realtime_options(CLI::App& app, Settings& s) {
  auto* record_opt =
      app.add_option("--record", s.record,
                     "record every topic of the run (all processes, whole run) to this MCAP file "
                     "with `poise record` (default: results/<scenario>.mcap)")
          ->expected(0, 1);
  app.add_flag("--passive", s.record_passive,
               "with --record: record with `poise record --passive`, from copies of the loopback "
               "datagrams the stack sends anyway (no DDS reader of the loop's topics: the loop is "
               "not slowed, components/record/README.md), instead of a subscribing recorder. "
               "Needs root or CAP_NET_RAW (`sudo setcap cap_net_raw+ep build/bin/poise`)")
      ->needs(record_opt);
  app.add_option("--security", s.security,
                 "DDS Security for every process of the run: the directory `poise security "
                 "init` made (each node authenticates as its name, the recorder as recorder)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--rt-priority", s.rt_priority,
                 "real-time scheduling: SCHED_FIFO for every process, the simulator at this "
                 "priority and the estimator, controller and contact optimiser at 3, 2 and 1 "
                 "below (0: normal scheduling; refused without root or CAP_SYS_NICE, each "
                 "process says so and runs normally)")
      ->check(CLI::Range(0, 99))
      ->capture_default_str();
  app.add_flag("--lock-memory", s.lock_memory,
               "every process locks its memory (mlockall) and pre-faults its stack");
  app.add_option("--cpus", s.cpus,
                 "CPU affinity of every process, a CPU list (1, 0-1, 0,2). One tick is a "
                 "chain of processes of which one works at a time: on one CPU a hand-off is a "
                 "context switch, not a cross-CPU wake-up (deploy/realtime/README.md)")
      ->check(poise::node::cpu_list_check);
  return record_opt;
}

/// Parses `poise run`'s command line into `s`. Returns the exit status when the command line
/// ends the verb (0 after --help, 2 for a usage error), else -1.
int parse_settings(int argc, char** argv, Settings& s) {
  CLI::App app{
      "Run a scenario with every component in its own process over DDS (loopback): "
      "poise-sim, poise-estimator, poise-contact, poise-controller. With --in-process, the same "
      "libraries in this one process instead (no DDS), the same trajectory bit for bit."};
  app.name(argc > 0 ? argv[0] : "poise run");
  app.footer(
      "In process (--in-process): one thread steps the simulator, the estimator, the controller "
      "and the contact optimiser in turn, as the distributed lockstep run does. It takes every "
      "option above and writes the same result file with the same fields (those of DDS null). "
      "--realtime paces the ticks at 1 kHz on the wall clock; --record writes every tick's "
      "messages to the MCAP file as the nodes would publish them (no poise/diagnostics); "
      "--rt-priority, --cpus and --lock-memory apply to this process; --dds*, --domain, "
      "--security, --passive and --contact-deadline-us have no effect (a note says so). "
      "deploy/inprocess/README.md.");
  add_scenario_options(app, s);
  add_component_options(app, s);
  const CLI::Option* record_opt = add_record_and_realtime_options(app, s);
  POISE_CLI_PARSE(app, argc, argv);
  s.record_given = record_opt->count() > 0;
  if (s.record_passive && !s.security.empty()) {
    std::fprintf(stderr,
                 "poise run: --passive cannot record a run with --security: DDS Security "
                 "encrypts the samples and discovery on the wire, which a packet capture cannot "
                 "read; use --record without --passive (the recorder authenticates as "
                 "'recorder')\n");
    return 2;
  }
  return -1;
}

/// Each component's DDS vendor: scenario hints, then --dds, then per component.
std::map<std::string, std::string> choose_vendors(const Settings& s,
                                                  const scenario::Scenario& scenario) {
  std::string all = scenario.dds.vendor.empty() ? "cyclone" : vendor_name(scenario.dds.vendor);
  if (!s.dds_all.empty()) all = vendor_name(s.dds_all);
  std::map<std::string, std::string> vendor{
      {"sim", all}, {"estimator", all}, {"contact", all}, {"controller", all}};
  if (s.dds_all.empty())
    for (const auto& [component, v] : scenario.dds.per_component)
      vendor[component == "simulator" ? "sim" : component] = vendor_name(v);
  if (!s.dds_sim.empty()) vendor["sim"] = vendor_name(s.dds_sim);
  if (!s.dds_estimator.empty()) vendor["estimator"] = vendor_name(s.dds_estimator);
  if (!s.dds_contact.empty()) vendor["contact"] = vendor_name(s.dds_contact);
  if (!s.dds_controller.empty()) vendor["controller"] = vendor_name(s.dds_controller);
  return vendor;
}

/// --domain, else $POISE_DDS_DOMAIN (as every other verb), else a free one.
int choose_domain(Settings& s) {
  if (s.domain < 0) {
    const char* env = std::getenv("POISE_DDS_DOMAIN");
    if (env != nullptr && *env != '\0') s.domain = dds::dds_options_from_env().domain_id;
  }
  const int domain = s.domain >= 0 ? s.domain : dds::claim_free_domain();
  // Cyclone's security plugins take domains 0..230 only.
  if (!s.security.empty() && domain > 230)
    throw std::runtime_error("DDS Security takes domains 0..230 (Cyclone's plugins)");
  return domain;
}

/// Takes the run's log directory and result file, and clears what an earlier run left there.
void claim_files(const Settings& s, Plan& p) {
  // The log directory is this run's alone (log_dir.hpp): with the default and another run of
  // a scenario of this name going on here, this one takes results/<scenario>.2.logs, and its
  // default result and recording follow (<scenario>.2.json, .mcap).
  p.logs_lock.emplace(claim_log_dir(s.log_dir, "results", p.scenario.name, &p.run_suffix));
  p.logs = p.logs_lock->dir();
  if (!p.run_suffix.empty())
    std::fprintf(stderr, "poise run %s: results/%s.logs is in use by another run: logs in %s%s\n",
                 p.scenario.name.c_str(), p.scenario.name.c_str(), p.logs.c_str(),
                 s.output.empty() ? ", result to the same name" : "");
  p.output = s.output.empty() ? fs::path("results") / (p.scenario.name + p.run_suffix + ".json")
                              : fs::path(s.output);
  if (p.output.has_parent_path()) fs::create_directories(p.output.parent_path());
  for (const char* n : {"sim", "estimator", "contact", "controller", "reference"})
    fs::remove(p.logs / (std::string(n) + ".summary.json"));
  // A result from an earlier run must never stand for this one.
  fs::remove(p.output);
}

/// The command line every node of the run starts with: its vendor, the domain, its summary
/// file, DDS Security and the real-time settings.
std::vector<std::string> node_args(const Settings& s, const Plan& p, const std::string& name) {
  std::vector<std::string> a{(p.bin / ("poise-" + name)).string(),
                             "--dds",
                             p.vendor.at(name),
                             "--domain",
                             std::to_string(p.domain),
                             "--summary",
                             (p.logs / (name + ".summary.json")).string()};
  if (!s.security.empty()) a.insert(a.end(), {"--security", s.security});
  if (s.rt_priority > 0)
    a.insert(a.end(), {"--rt-priority", std::to_string(rt_priority_of(name, s.rt_priority))});
  if (s.lock_memory) a.push_back("--lock-memory");
  if (!s.cpus.empty()) a.insert(a.end(), {"--cpus", s.cpus});
  return a;
}

/// The simulator's command line. Removes the start file of an earlier run.
std::vector<std::string> sim_args(const Settings& s, const Plan& p) {
  std::vector<std::string> a = node_args(s, p, "sim");
  a.insert(a.end(), {fs::absolute(s.scenario).string(), "--progress",
                     s.realtime ? "--realtime" : "--lockstep", "--command-timeout-ms",
                     std::to_string(s.command_timeout_ms)});
  // Real time: the clock starts once the loop has answered the first frame (poise-sim).
  if (s.realtime) a.push_back("--start-when-answered");
  if (s.duration > 0) a.insert(a.end(), {"--duration", std::to_string(s.duration)});
  if (s.settle_ticks >= 0) a.insert(a.end(), {"--settle-ticks", std::to_string(s.settle_ticks)});
  if (s.watchdog_ms > 0) a.insert(a.end(), {"--watchdog-ms", std::to_string(s.watchdog_ms)});
  if (s.hold_s >= 0) a.insert(a.end(), {"--hold-s", std::to_string(s.hold_s)});
  // With a recorder, the simulator waits for its readers too, so that the file holds the run
  // from its first tick (sensors: estimator + recorder; ground truth: recorder).
  // It also waits for a start file, made once the recorder has matched every writer of the
  // stack (the nodes create theirs once they have the robot description).
  std::error_code ignored;
  fs::remove(p.start_file, ignored);
  // A passive recorder reads no sensors (it captures the estimator's copy) but holds a reader
  // of the ground truth, which nothing else reads: its writer sends only to matched readers.
  if (p.recording_run)
    a.insert(a.end(), {"--wait-readers", p.passive ? "1" : "2", "--wait-truth-readers", "1",
                       "--start-file", p.start_file.string()});
  return a;
}

/// Each node's outputs: their consumer and a subscribing recorder (a passive recorder captures
/// what is sent to the consumer), matched before its first input.
const char* output_readers(const Plan& p) {
  return p.passive ? "1" : "2";
}

/// Lockstep: a tick takes as long as the slowest process needs, and a loaded machine stalls
/// the loop for 100+ ms now and then (171 ms in a CI run); the nodes' 50 ms wall-clock
/// staleness default would call that a fault. The simulator waits --command-timeout-ms for a
/// command before it damps, so the nodes wait that long for their input too.
std::vector<std::string> lockstep_stale_args(const Settings& s) {
  return s.realtime
             ? std::vector<std::string>{}
             : std::vector<std::string>{"--input-stale-ms", std::to_string(s.command_timeout_ms)};
}

/// The estimator's command line; `s.estimator` becomes the scenario's when not given.
std::vector<std::string> estimator_args(Settings& s, const Plan& p) {
  std::vector<std::string> a = node_args(s, p, "estimator");
  if (s.ground_truth_state) a.push_back("--ground-truth-state");
  if (s.estimator.empty()) s.estimator = p.scenario.estimator.type;
  const std::vector<std::string> from_scenario = estimator_scenario_args(p.scenario, s.estimator);
  a.insert(a.end(), from_scenario.begin(), from_scenario.end());
  if (p.recording_run) a.insert(a.end(), {"--output-readers", output_readers(p)});
  const std::vector<std::string> stale = lockstep_stale_args(s);
  a.insert(a.end(), stale.begin(), stale.end());
  return a;
}

/// The controller configuration: --controller-config, else the scenario's section (written to
/// the log directory for the controller node), checked here so a bad key fails before launch.
void choose_controller_config(const Settings& s, Plan& p) {
  if (!s.controller_config.empty()) {
    p.ccfg = controller::load_controller_config(s.controller_config);
    p.ctrl_config_file = fs::absolute(s.controller_config);
  } else if (!p.scenario.controller_yaml.empty()) {
    p.ccfg = controller::parse_controller_config(p.scenario.controller_yaml,
                                                 "scenario '" + p.scenario.name + "', controller");
    p.ctrl_config_file = fs::absolute(p.logs / "controller.yaml");
    std::ofstream cf(p.ctrl_config_file);
    cf << "# the controller: section of " << s.scenario << "\n"
       << p.scenario.controller_yaml << "\n";
    if (!cf) throw std::runtime_error("cannot write " + p.ctrl_config_file.string());
  }
}

/// The contact optimiser's command line; chooses the controller configuration (its priority and
/// torsion limit go to the optimiser).
std::vector<std::string> contact_args(const Settings& s, Plan& p) {
  std::vector<std::string> a = node_args(s, p, "contact");
  if (p.recording_run) a.insert(a.end(), {"--output-readers", output_readers(p)});
  a.insert(a.end(), {"--method", s.method});
  choose_controller_config(s, p);
  a.insert(a.end(), {"--priority", contact::to_string(p.ccfg.contact.priority), "--torsion-limit",
                     contact::to_string(p.ccfg.contact.torsion_limit)});
  return a;
}

/// The planned supports of the scenario from the first tick, as the in-process loop plans them
/// (the first supports were a difference between the two modes: issue #17 item 4).
/// A foot name is the side whose robot-configuration frame is that simulated foot's frame
/// (the in-process loop's rule), not only a foot named "left" or "right".
std::string planned_support(const scenario::Scenario& scenario) {
  std::string planned = scenario.support == "double" ? "double" : "auto";
  if (planned == "auto" && !scenario.robot_config.empty()) {
    const model::RobotConfig rc = model::load_robot_config(scenario.robot_config);
    for (const auto& foot : scenario.sim.robot.feet)
      if (foot.name == scenario.support)
        for (int side = 0; side < 2; ++side)
          if (foot.frame == rc.feet[side].frame) planned = side == model::kLeft ? "left" : "right";
  }
  return planned;
}

/// The controller's command line.
std::vector<std::string> controller_args(const Settings& s, const Plan& p) {
  std::vector<std::string> a = node_args(s, p, "controller");
  a.insert(a.end(), {"--planned-support", planned_support(p.scenario)});
  if (!p.ctrl_config_file.empty()) a.insert(a.end(), {"--config", p.ctrl_config_file.string()});
  a.insert(a.end(), {"--contact-deadline-us", std::to_string(p.deadline_us)});
  const std::vector<std::string> stale = lockstep_stale_args(s);
  a.insert(a.end(), stale.begin(), stale.end());
  if (p.recording_run) a.insert(a.end(), {"--output-readers", output_readers(p)});
  return a;
}

/// Everything decided before a process starts: the scenario (a file, or a name in
/// deploy/scenarios/), the vendors, the domain, the log directory, the command lines.
Plan make_plan(Settings& s) {
  Plan p;
  s.scenario = resolve_scenario(s.scenario);
  p.scenario = scenario::load_scenario(s.scenario);
  p.duration = s.duration > 0 ? s.duration : p.scenario.duration;
  if (s.method.empty())
    s.method = p.scenario.contact_method.empty() ? "sequential" : p.scenario.contact_method;
  p.vendor = choose_vendors(s, p.scenario);
  p.domain = choose_domain(s);
  claim_files(s, p);
  p.deadline_us = s.contact_deadline_us > 0 ? s.contact_deadline_us : (s.realtime ? 400.0 : 1e6);
  p.timeout_s =
      s.timeout_s > 0 ? s.timeout_s : (s.realtime ? 60.0 + p.duration : 60.0 + 30.0 * p.duration);
  p.bin = bin_dir();
  p.start_file = p.logs / "start";
  p.recording_run = s.record_given;
  p.passive = p.recording_run && s.record_passive;
  p.sim_args = sim_args(s, p);
  p.est_args = estimator_args(s, p);
  p.contact_args = contact_args(s, p);
  p.ctrl_args = controller_args(s, p);
  return p;
}

/// The lines that open a run (none with --quiet).
void print_plan(const Settings& s, const Plan& p) {
  const scenario::Scenario& scenario = p.scenario;
  if (!s.quiet)
    std::printf(
        "poise run %s: %s, %.1f s, domain %d, dds sim=%s estimator=%s contact=%s "
        "controller=%s, logs in %s\n",
        scenario.name.c_str(), s.realtime ? "real time" : "lockstep", p.duration, p.domain,
        p.vendor.at("sim").c_str(), p.vendor.at("estimator").c_str(),
        p.vendor.at("contact").c_str(), p.vendor.at("controller").c_str(), p.logs.c_str());
  if (!s.quiet) {
    const scenario::EstimatorStart start = scenario::estimator_start(scenario);
    if (start.per_foot)
      std::printf(
          "  estimator %s, supports %s, soles start at z right %.4f m, left %.4f m (%s)\n",
          s.estimator.c_str(), scenario.estimator.supports.c_str(),
          std::isfinite(start.support_height[0]) ? start.support_height[0] : start.ground_height,
          std::isfinite(start.support_height[1]) ? start.support_height[1] : start.ground_height,
          start.source.c_str());
    else
      std::printf("  estimator %s, supports %s, soles start at z %.4f m (%s)\n",
                  s.estimator.c_str(), scenario.estimator.supports.c_str(), start.ground_height,
                  start.source.c_str());
  }
  std::fflush(stdout);
}

/// SIGINT and SIGTERM end the run as "interrupted" (the processes stopped in order, the result
/// written).
void catch_interrupts() {
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

/// The recorder's command line.
std::vector<std::string> recorder_args(const Settings& s, const Plan& p,
                                       const fs::path& recording) {
  // The run's recording replaces the last run's, as its result does.
  std::vector<std::string> a{(p.bin / "poise").string(),
                             "record",
                             "--dds",
                             "cyclone",
                             "--domain",
                             std::to_string(p.domain),
                             "-o",
                             recording.string(),
                             "--if-exists",
                             "overwrite",
                             "--progress",
                             "0"};
  // Passive: the capture on loopback (every process of `poise run` is on this
  // machine), and readers of the topics nothing else reads (ground truth, diagnostics).
  if (s.record_passive) a.insert(a.end(), {"--passive", "--interface", "lo"});
  if (!s.security.empty()) a.insert(a.end(), {"--security", s.security, "--identity", "recorder"});
  return a;
}

/// --record: starts `poise record` and waits until it records. The recorder joins first, so
/// that it holds the run from its first sample. Returns false when it cannot record (the
/// failed result written).
bool start_recorder(const Settings& s, const Plan& p, Processes& procs) {
  procs.recording = s.record.empty()
                        ? fs::path("results") / (p.scenario.name + p.run_suffix + ".mcap")
                        : fs::path(s.record);
  if (procs.recording.has_parent_path()) fs::create_directories(procs.recording.parent_path());
  ComponentSpec rec;
  rec.name = "recorder";
  rec.argv = recorder_args(s, p, procs.recording);
  rec.runs_until_stopped = true;
  rec.stop_grace_ms = 30000;  // SIGTERM makes it write what it holds
  procs.recorder = &procs.supervisor.start(std::move(rec));
  if (const std::string why = wait_for_recorder(*procs.recorder, 10.0); !why.empty()) {
    std::fprintf(stderr, "poise run %s: FAILED: cannot record to %s: %s\n", p.scenario.name.c_str(),
                 procs.recording.c_str(), why.c_str());
    procs.recorder->stop(3000);
    write_failure(s, p, procs, "cannot record to " + procs.recording.string() + ": " + why);
    return false;
  }
  if (!s.quiet)
    std::printf("  recording every topic to %s%s\n", procs.recording.c_str(),
                s.record_passive ? " (passive capture on lo)" : "");
  return true;
}

/// Starts the scenario's reference player, then the simulator and the nodes. Returns false
/// when one cannot be started (the failed result written).
bool start_nodes(const Settings& s, Plan& p, Processes& procs) {
  try {
    // The scenario's balance-reference trajectory: played by poise-reference in step with the
    // state (it waits for the robot description and the first state), kept running (--hold)
    // so that it ends with the run like the nodes.
    if (!p.scenario.reference.empty()) {
      ComponentSpec c;
      c.name = "reference";
      p.vendor["reference"] = p.vendor["controller"];
      c.argv = node_args(s, p, "reference");
      c.argv.insert(c.argv.end(), {p.scenario.reference.string(), "--hold"});
      c.runs_until_stopped = true;
      procs.children.push_back(&procs.supervisor.start(std::move(c)));
    }
    for (auto* spec : {&p.sim_args, &p.contact_args, &p.est_args, &p.ctrl_args}) {
      ComponentSpec c;
      c.name = spec == &p.sim_args       ? "sim"
               : spec == &p.contact_args ? "contact"
               : spec == &p.est_args     ? "estimator"
                                         : "controller";
      c.argv = *spec;
      c.ends_run = spec == &p.sim_args;    // the simulator's end is the run's end
      c.runs_until_stopped = !c.ends_run;  // a node that ends before it is a failure
      procs.children.push_back(&procs.supervisor.start(std::move(c)));
    }
  } catch (const std::exception& e) {
    write_failure(s, p, procs, std::string("cannot start a component: ") + e.what());
    return false;
  }
  return true;
}

/// What the recorder and the nodes have not matched yet: the stack's writers the recorder has
/// not seen, and each node whose output readers are not all matched ("" when all are).
std::string missing_matches(const Processes& procs, const Child& sim) {
  std::string missing;
  const auto have = recorder_writers(procs.recorder->stderr_path());
  for (const auto& [topic, n] : stack_writers()) {
    const auto it = have.find(topic);
    if (it == have.end() || it->second < n) missing += (missing.empty() ? "" : ", ") + topic;
  }
  // And the writer side: each node has matched the readers of its outputs.
  for (const Child* c : procs.children) {
    if (c == &sim || c->name() == "reference") continue;  // no outputs of the loop
    std::ifstream err(c->stderr_path());
    const std::string text((std::istreambuf_iterator<char>(err)), std::istreambuf_iterator<char>());
    if (text.find("output readers matched") == std::string::npos)
      missing += (missing.empty() ? "" : ", ") + c->name() + "'s output readers";
  }
  return missing;
}

/// With a recorder: waits until every writer and reader of the run has matched (20 s at most),
/// then makes the start file. Returns what failed meanwhile ("" if nothing did).
std::string wait_for_matching(const Settings& s, const Plan& p, Processes& procs, Child& sim) {
  std::string failure;
  const auto t0 = std::chrono::steady_clock::now();
  for (;;) {
    const std::string missing = missing_matches(procs, sim);
    const double waited =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (missing.empty()) {
      if (!s.quiet)
        std::printf("  every writer and reader of the run matched after %.2f s\n", waited);
      break;
    }
    if (waited > 20.0) {
      std::fprintf(stderr,
                   "poise run %s: warning: after 20 s still waiting for %s; starting anyway "
                   "(the recording may miss their first samples)\n",
                   p.scenario.name.c_str(), missing.c_str());
      break;
    }
    const Supervisor::Status st = procs.supervisor.poll("during start-up");
    if (st.run_ended) failure = "sim " + sim.exit_description() + " during start-up";
    if (failure.empty()) failure = st.failure;
    if (!failure.empty() || g_interrupted.load()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::ofstream(p.start_file) << "go\n";
  return failure;
}

/// Relays the simulator's progress lines until the run ends, a process fails, the run is
/// interrupted or times out (then `failure` says which). Returns the simulator's exit code when
/// its end ended the run, else -1.
int wait_for_run(const Settings& s, const Plan& p, Processes& procs, Child& sim,
                 std::string& failure) {
  const auto t_start = std::chrono::steady_clock::now();
  LineFollower progress(sim.stdout_path());
  int sim_code = -1;
  while (failure.empty()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    for (const auto& line : progress.poll())  // relay the simulator's progress lines
      if (!s.quiet && line.rfind("progress ", 0) == 0) std::printf("  %s\n", line.c_str() + 9);
    std::fflush(stdout);
    const Supervisor::Status st = procs.supervisor.poll("before the end of the run");
    if (st.run_ended) {
      sim_code = sim.poll().value_or(-1);
      break;
    }
    if (!st.failure.empty()) {
      failure = st.failure;
      break;
    }
    if (g_interrupted.load()) {
      failure = "interrupted";
      break;
    }
    if (std::chrono::steady_clock::now() - t_start > std::chrono::duration<double>(p.timeout_s)) {
      failure = "timeout: the run took more than " + std::to_string(p.timeout_s) + " s";
      break;
    }
  }
  return sim_code;
}

/// After the stop: "" when the recorder (if any) wrote its file, else what went wrong (said on
/// stderr with its last lines).
std::string recorder_problem(const Settings& s, const Plan& p, Processes& procs) {
  std::string problem;
  if (!procs.recorder) return problem;
  Child& recorder = *procs.recorder;
  const int code = recorder.poll().value_or(-1);
  const std::string summary = recorder.stderr_tail(1);
  if (code != 0) {
    problem = "the recorder " + recorder.exit_description();
    std::fprintf(stderr, "poise run %s: %s (%s):\n%s", p.scenario.name.c_str(), problem.c_str(),
                 recorder.stderr_path().c_str(), recorder.stderr_tail(8).c_str());
  } else if (!s.quiet) {
    std::printf("  recorded: %s", summary.c_str());
  }
  return problem;
}

/// A run that ended otherwise than by the simulator's end (code 0 or 3): says why, with the last
/// stderr lines of the processes concerned, and writes the failed result. Returns the exit status.
int report_failure(const Settings& s, const Plan& p, Processes& procs, Child& sim,
                   std::string failure) {
  if (failure.empty()) failure = "sim " + sim.exit_description();
  std::fprintf(stderr, "poise run %s: FAILED: %s\n", p.scenario.name.c_str(), failure.c_str());
  for (auto& c : procs.children) {
    const std::string tail = c->stderr_tail(8);
    const bool culprit = failure.rfind(c->name() + " ", 0) == 0;
    if (culprit || failure.rfind("sim", 0) == 0 || failure.rfind("timeout", 0) == 0)
      std::fprintf(stderr, "--- last stderr lines of %s (pid %d, %s):\n%s", c->name().c_str(),
                   static_cast<int>(c->pid()), c->stderr_path().c_str(), tail.c_str());
  }
  write_failure(s, p, procs, failure);
  if (failure != "interrupted") return 2;
  return 130;
}

/// A distributed run, phase by phase. Returns the exit status: 0 survived, 1 failed the
/// scenario's criteria, 2 could not run (or the recording failed), 130 interrupted.
int run_scenario(Settings& s) {
  Plan p = make_plan(s);
  print_plan(s, p);
  catch_interrupts();
  Processes procs(p.logs);
  if (s.record_given && !start_recorder(s, p, procs)) return 2;
  if (!start_nodes(s, p, procs)) return 2;
  Child& sim = *procs.children[p.scenario.reference.empty() ? 0 : 1];
  std::string failure = procs.recorder ? wait_for_matching(s, p, procs, sim) : std::string();
  int sim_code = wait_for_run(s, p, procs, sim, failure);
  // Stop the simulator first (it writes its result), then the others (they write summaries),
  // last the recorder: SIGTERM makes it write what it holds, the loss counters and the summary.
  procs.supervisor.stop({"sim", "contact", "estimator", "controller", "reference", "recorder"});
  if (!failure.empty()) sim_code = sim.poll().value_or(-1);
  const std::string record_problem = recorder_problem(s, p, procs);
  if (!failure.empty() || (sim_code != 0 && sim_code != 3))
    return report_failure(s, p, procs, sim, failure);
  return write_result(s, p, procs, record_problem);
}

}  // namespace
}  // namespace distributed

int parse_run_settings(int argc, char** argv, RunSettings& s) {
  return distributed::parse_settings(argc, argv, s);
}

std::string dds_only_options(const RunSettings& s) {
  std::string out;
  const auto add = [&](bool given, const char* name) {
    if (given) out += (out.empty() ? "" : " ") + std::string(name);
  };
  add(!s.dds_all.empty(), "--dds");
  add(!s.dds_sim.empty(), "--dds-sim");
  add(!s.dds_estimator.empty(), "--dds-estimator");
  add(!s.dds_contact.empty(), "--dds-contact");
  add(!s.dds_controller.empty(), "--dds-controller");
  add(s.domain >= 0, "--domain");
  add(!s.security.empty(), "--security");
  add(s.record_passive, "--passive");
  add(s.contact_deadline_us >= 0.0, "--contact-deadline-us");
  return out;
}

int run_distributed(int argc, char** argv) {
  RunSettings s;
  if (const int code = parse_run_settings(argc, argv, s); code >= 0) return code;
  return run_distributed(s);
}

int run_distributed(RunSettings& s) {
  if (s.in_process) {
    std::fprintf(stderr,
                 "poise run: --in-process: this launcher runs the distributed stack only; use "
                 "`poise run --in-process`\n");
    return 2;
  }
  try {
    return distributed::run_scenario(s);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise run: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::launch
