// `poise run SCENARIO` in its distributed form: four processes over loopback DDS.
#include <algorithm>
#include <cstdlib>
#include <signal.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/dds/domain_claim.hpp"
#include "poise/dds/vendor.hpp"
#include "poise/launch/child.hpp"
#include "poise/launch/deployment.hpp"
#include "poise/launch/launch.hpp"
#include "poise/launch/log_dir.hpp"
#include "poise/launch/supervisor.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/realtime.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/sim_config.hpp"
#include "poise/cli/parse.hpp"

namespace poise::launch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

std::atomic<bool> g_interrupted{false};
extern "C" void on_interrupt(int) {
  g_interrupted.store(true);
}

/// "cyclonedds" (scenario files) -> "cyclone"; validates.
std::string vendor_name(const std::string& v) {
  const std::string n = v == "cyclonedds" ? "cyclone" : v == "fastrtps" ? "fastdds" : v;
  return std::string(dds::to_string(dds::parse_vendor(n)));
}

Json read_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return Json();
  try {
    return Json::parse(in);
  } catch (...) {
    return Json();
  }
}

struct Settings {
  std::string scenario;
  bool realtime = false;
  std::string dds_all, dds_sim, dds_estimator, dds_contact, dds_controller;
  int domain = -1;
  std::string output, log_dir;
  double duration = -1.0;
  bool ground_truth_state = false;
  std::string method;  ///< "" = the scenario's contact.method, else sequential
  std::string estimator;  ///< "" = the scenario's estimator.type, else invariant-ekf
  std::string controller_config;  ///< "" = the scenario's controller: section, else defaults
  double contact_deadline_us = -1.0;
  int command_timeout_ms = sim::kDefaultCommandTimeoutMs;
  int settle_ticks = -1;      ///< simulator start-up hold steps (-1: the simulator's default)
  double watchdog_ms = -1.0;  ///< safety layer watchdog (-1: default)
  double hold_s = -1.0;       ///< safety layer hold before damping (-1: default)
  double timeout_s = -1.0;
  bool quiet = false;
  std::string record;  ///< MCAP file of `--record` ("" with the flag alone: the default path)
  bool record_passive = false;  ///< `--record --passive`: `poise record --passive` (packet capture)
  std::string security;  ///< DDS Security directory (poise security init), "" = none
  int rt_priority = 0;   ///< SCHED_FIFO base priority of the processes (0: normal scheduling)
  bool lock_memory = false;  ///< every process locks its memory (mlockall)
  std::string cpus;          ///< CPU affinity of every process ("": any CPU)
};

/// SCHED_FIFO priority of a component for `poise run --rt-priority P`: the simulator (the robot
/// side, its safety layer and the clock) at P; the controller chain below it, each stage above
/// the one that feeds it (estimator P-3 < controller P-2 < contact P-1), so that a stage woken
/// by its input preempts whatever fed it and the tick drains without waiting.
int rt_priority_of(const std::string& component, int base) {
  if (base <= 0) return 0;
  const int below = component == "sim" ? 0
                    : component == "contact" ? 1
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
      return "the recorder " + recorder.exit_description() + ":\n" +
             recorder.stderr_tail(8);
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
      {"poise/robot_description", 1}, {"poise/sensors", 1},          {"poise/ground_truth", 1},
      {"poise/state", 1},             {"poise/contact_problem", 1},  {"poise/contact_solution", 1},
      {"poise/joint_command", 1},     {"poise/diagnostics", 4}};
  return w;
}

}  // namespace

int run_distributed(int argc, char** argv) {
  Settings s;
  CLI::App app{
      "Run a scenario with every component in its own process over DDS (loopback): "
      "poise-sim, poise-estimator, poise-contact, poise-controller. `poise run --in-process` "
      "composes them in one process instead (no DDS)."};
  app.name(argc > 0 ? argv[0] : "poise run");
  app.add_option("scenario", s.scenario, "scenario YAML file, or a name in deploy/scenarios/")
      ->required();
  bool lockstep_flag = false;
  auto* lock = app.add_flag("--lockstep", lockstep_flag,
                            "simulator steps k+1 only after command k (default)");
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
  app.add_option("--domain", s.domain, "DDS domain id (default: $POISE_DDS_DOMAIN, else a free one in 50..100)")
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
  POISE_CLI_PARSE(app, argc, argv);
  if (s.record_passive && !s.security.empty()) {
    std::fprintf(stderr,
                 "poise run: --passive cannot record a run with --security: DDS Security "
                 "encrypts the samples and discovery on the wire, which a packet capture cannot "
                 "read; use --record without --passive (the recorder authenticates as "
                 "'recorder')\n");
    return 2;
  }

  try {
    s.scenario = resolve_scenario(s.scenario);  // a file, or a name in deploy/scenarios/
    const scenario::Scenario scenario = scenario::load_scenario(s.scenario);
    const double duration = s.duration > 0 ? s.duration : scenario.duration;
    if (s.method.empty())
      s.method = scenario.contact_method.empty() ? "sequential" : scenario.contact_method;
    // Vendors: scenario hints, then --dds, then per component.
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

    // --domain, else $POISE_DDS_DOMAIN (as every other verb), else a free one.
    if (s.domain < 0) {
      const char* env = std::getenv("POISE_DDS_DOMAIN");
      if (env != nullptr && *env != '\0') s.domain = dds::dds_options_from_env().domain_id;
    }
    const int domain = s.domain >= 0 ? s.domain : dds::claim_free_domain();
    // Cyclone's security plugins take domains 0..230 only.
    if (!s.security.empty() && domain > 230)
      throw std::runtime_error("DDS Security takes domains 0..230 (Cyclone's plugins)");
    // The log directory is this run's alone (log_dir.hpp): with the default and another run of
    // a scenario of this name going on here, this one takes results/<scenario>.2.logs, and its
    // default result and recording follow (<scenario>.2.json, .mcap).
    std::string run_suffix;
    const LogDirLock logs_lock = claim_log_dir(s.log_dir, "results", scenario.name, &run_suffix);
    const fs::path logs = logs_lock.dir();
    if (!run_suffix.empty())
      std::fprintf(stderr, "poise run %s: results/%s.logs is in use by another run: logs in %s%s\n",
                   scenario.name.c_str(), scenario.name.c_str(), logs.c_str(),
                   s.output.empty() ? ", result to the same name" : "");
    const fs::path output = s.output.empty()
                                ? fs::path("results") / (scenario.name + run_suffix + ".json")
                                : fs::path(s.output);
    if (output.has_parent_path()) fs::create_directories(output.parent_path());
    for (const char* n : {"sim", "estimator", "contact", "controller", "reference"})
      fs::remove(logs / (std::string(n) + ".summary.json"));
    // A result from an earlier run must never stand for this one.
    fs::remove(output);
    const double deadline_us =
        s.contact_deadline_us > 0 ? s.contact_deadline_us : (s.realtime ? 400.0 : 1e6);
    const double timeout_s =
        s.timeout_s > 0 ? s.timeout_s : (s.realtime ? 60.0 + duration : 60.0 + 30.0 * duration);
    const fs::path bin = bin_dir();

    auto common = [&](const std::string& name) {
      std::vector<std::string> a{(bin / ("poise-" + name)).string(),
                                 "--dds",
                                 vendor[name],
                                 "--domain",
                                 std::to_string(domain),
                                 "--summary",
                                 (logs / (name + ".summary.json")).string()};
      if (!s.security.empty()) a.insert(a.end(), {"--security", s.security});
      if (s.rt_priority > 0)
        a.insert(a.end(), {"--rt-priority", std::to_string(rt_priority_of(name, s.rt_priority))});
      if (s.lock_memory) a.push_back("--lock-memory");
      if (!s.cpus.empty()) a.insert(a.end(), {"--cpus", s.cpus});
      return a;
    };
    std::vector<std::string> sim_args = common("sim");
    sim_args.insert(sim_args.end(), {fs::absolute(s.scenario).string(), "--progress",
                                     s.realtime ? "--realtime" : "--lockstep",
                                     "--command-timeout-ms", std::to_string(s.command_timeout_ms)});
    // Real time: the clock starts once the loop has answered the first frame (poise-sim).
    if (s.realtime) sim_args.push_back("--start-when-answered");
    if (s.duration > 0) sim_args.insert(sim_args.end(), {"--duration", std::to_string(s.duration)});
    if (s.settle_ticks >= 0)
      sim_args.insert(sim_args.end(), {"--settle-ticks", std::to_string(s.settle_ticks)});
    if (s.watchdog_ms > 0)
      sim_args.insert(sim_args.end(), {"--watchdog-ms", std::to_string(s.watchdog_ms)});
    if (s.hold_s >= 0) sim_args.insert(sim_args.end(), {"--hold-s", std::to_string(s.hold_s)});
    // With a recorder, the simulator waits for its readers too, so that the file holds the run
    // from its first tick (sensors: estimator + recorder; ground truth: recorder).
    // It also waits for a start file, made once the recorder has matched every writer of the
    // stack (the nodes create theirs once they have the robot description).
    const fs::path start_file = logs / "start";
    std::error_code ignored;
    fs::remove(start_file, ignored);
    const bool recording_run = record_opt->count() > 0;
    // A passive recorder reads no sensors (it captures the estimator's copy) but holds a reader
    // of the ground truth, which nothing else reads: its writer sends only to matched readers.
    const bool passive = recording_run && s.record_passive;
    if (recording_run)
      sim_args.insert(sim_args.end(), {"--wait-readers", passive ? "1" : "2",
                                       "--wait-truth-readers", "1", "--start-file",
                                       start_file.string()});
    // Each node's outputs: their consumer and a subscribing recorder (a passive recorder captures
    // what is sent to the consumer), matched before its first input.
    const char* output_readers = passive ? "1" : "2";
    std::vector<std::string> est_args = common("estimator");
    if (s.ground_truth_state) est_args.push_back("--ground-truth-state");
    if (s.estimator.empty()) s.estimator = scenario.estimator.type;
    {
      const std::vector<std::string> from_scenario = estimator_scenario_args(scenario, s.estimator);
      est_args.insert(est_args.end(), from_scenario.begin(), from_scenario.end());
    }
    if (recording_run) est_args.insert(est_args.end(), {"--output-readers", output_readers});
    // Lockstep: a tick takes as long as the slowest process needs, and a loaded machine stalls
    // the loop for 100+ ms now and then (171 ms in a CI run); the nodes' 50 ms wall-clock
    // staleness default would call that a fault. The simulator waits --command-timeout-ms for a
    // command before it damps, so the nodes wait that long for their input too.
    const std::vector<std::string> lockstep_stale =
        s.realtime ? std::vector<std::string>{}
                   : std::vector<std::string>{"--input-stale-ms",
                                              std::to_string(s.command_timeout_ms)};
    est_args.insert(est_args.end(), lockstep_stale.begin(), lockstep_stale.end());
    std::vector<std::string> contact_args = common("contact");
    if (recording_run) contact_args.insert(contact_args.end(), {"--output-readers", output_readers});
    contact_args.insert(contact_args.end(), {"--method", s.method});
    // The controller configuration: --controller-config, else the scenario's section (written to
    // the log directory for the controller node), checked here so a bad key fails before launch.
    controller::ControllerConfig ccfg;
    fs::path ctrl_config_file;
    if (!s.controller_config.empty()) {
      ccfg = controller::load_controller_config(s.controller_config);
      ctrl_config_file = fs::absolute(s.controller_config);
    } else if (!scenario.controller_yaml.empty()) {
      ccfg = controller::parse_controller_config(scenario.controller_yaml,
                                                 "scenario '" + scenario.name + "', controller");
      ctrl_config_file = fs::absolute(logs / "controller.yaml");
      std::ofstream cf(ctrl_config_file);
      cf << "# the controller: section of " << s.scenario << "\n" << scenario.controller_yaml << "\n";
      if (!cf) throw std::runtime_error("cannot write " + ctrl_config_file.string());
    }
    contact_args.insert(contact_args.end(),
                        {"--priority", contact::to_string(ccfg.contact.priority),
                         "--torsion-limit", contact::to_string(ccfg.contact.torsion_limit)});
    std::vector<std::string> ctrl_args = common("controller");
    // The planned supports of the scenario from the first tick, as the in-process loop plans them
    // (the first supports were a difference between the two modes: issue #17 item 4).
    // A foot name is the side whose robot-configuration frame is that simulated foot's frame
    // (the in-process loop's rule), not only a foot named "left" or "right".
    std::string planned_support = scenario.support == "double" ? "double" : "auto";
    if (planned_support == "auto" && !scenario.robot_config.empty()) {
      const model::RobotConfig rc = model::load_robot_config(scenario.robot_config);
      for (const auto& foot : scenario.sim.robot.feet)
        if (foot.name == scenario.support)
          for (int side = 0; side < 2; ++side)
            if (foot.frame == rc.feet[side].frame)
              planned_support = side == model::kLeft ? "left" : "right";
    }
    ctrl_args.insert(ctrl_args.end(), {"--planned-support", planned_support});
    if (!ctrl_config_file.empty())
      ctrl_args.insert(ctrl_args.end(), {"--config", ctrl_config_file.string()});
    ctrl_args.insert(ctrl_args.end(), {"--contact-deadline-us", std::to_string(deadline_us)});
    ctrl_args.insert(ctrl_args.end(), lockstep_stale.begin(), lockstep_stale.end());
    if (recording_run) ctrl_args.insert(ctrl_args.end(), {"--output-readers", output_readers});

    if (!s.quiet)
      std::printf(
          "poise run %s: %s, %.1f s, domain %d, dds sim=%s estimator=%s contact=%s "
          "controller=%s, logs in %s\n",
          scenario.name.c_str(), s.realtime ? "real time" : "lockstep", duration, domain,
          vendor["sim"].c_str(), vendor["estimator"].c_str(), vendor["contact"].c_str(),
          vendor["controller"].c_str(), logs.c_str());
    if (!s.quiet) {
      const scenario::EstimatorStart start = scenario::estimator_start(scenario);
      if (start.per_foot)
        std::printf("  estimator %s, supports %s, soles start at z right %.4f m, left %.4f m (%s)\n",
                    s.estimator.c_str(), scenario.estimator.supports.c_str(),
                    std::isfinite(start.support_height[0]) ? start.support_height[0] : start.ground_height,
                    std::isfinite(start.support_height[1]) ? start.support_height[1] : start.ground_height,
                    start.source.c_str());
      else
        std::printf("  estimator %s, supports %s, soles start at z %.4f m (%s)\n", s.estimator.c_str(),
                    scenario.estimator.supports.c_str(), start.ground_height, start.source.c_str());
    }
    std::fflush(stdout);

    struct sigaction sa {};
    sa.sa_handler = on_interrupt;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);

    // The recorder joins first, so that it holds the run from its first sample.
    // One supervisor with `poise launch`: every process of the run is its Child (own process
    // group, ended with the launcher), each end is said in words, and the stop is ordered.
    Supervisor supervisor("poise run", logs);
    Child* recorder = nullptr;
    std::vector<Child*> children;
    fs::path recording;
    // A run that fails still writes its result file: failed, with the reason and how each
    // process ended.
    auto write_failure = [&](const std::string& reason) {
      Json r;
      r["scenario"] = scenario.name;
      r["survived"] = false;
      r["completed"] = false;
      r["failed"] = true;
      r["failure"] = reason;
      r["mode"] = s.realtime ? "realtime" : "lockstep";
      r["dds"] = vendor;
      r["domain"] = domain;
      r["logs"] = logs.string();
      r["exits"] = Json::object();
      r["pids"] = Json::object();
      for (auto& c : children) {
        c->poll();
        r["exits"][c->name()] = c->exit_description();
        r["pids"][c->name()] = c->pid();
      }
      if (recorder) {
        recorder->poll();
        r["exits"]["recorder"] = recorder->exit_description();
        r["pids"]["recorder"] = recorder->pid();
        r["recording"] = recording.string();
      }
      std::ofstream(output) << r.dump(2) << "\n";
      std::fprintf(stderr, "poise run %s: result (failed) -> %s\n", scenario.name.c_str(),
                   output.c_str());
    };
    if (record_opt->count() > 0) {
      recording = s.record.empty() ? fs::path("results") / (scenario.name + run_suffix + ".mcap")
                                   : fs::path(s.record);
      if (recording.has_parent_path()) fs::create_directories(recording.parent_path());
      ComponentSpec rec;
      rec.name = "recorder";
      rec.argv = [&] {
        // The run's recording replaces the last run's, as its result does.
        std::vector<std::string> a{(bin / "poise").string(),
                                   "record",
                                   "--dds",
                                   "cyclone",
                                   "--domain",
                                   std::to_string(domain),
                                   "-o",
                                   recording.string(),
                                   "--if-exists",
                                   "overwrite",
                                   "--progress",
                                   "0"};
        // Passive: the capture on loopback (every process of `poise run` is on this
        // machine), and readers of the topics nothing else reads (ground truth, diagnostics).
        if (s.record_passive) a.insert(a.end(), {"--passive", "--interface", "lo"});
        if (!s.security.empty())
          a.insert(a.end(), {"--security", s.security, "--identity", "recorder"});
        return a;
      }();
      rec.runs_until_stopped = true;
      rec.stop_grace_ms = 30000;  // SIGTERM makes it write what it holds
      recorder = &supervisor.start(std::move(rec));
      if (const std::string why = wait_for_recorder(*recorder, 10.0); !why.empty()) {
        std::fprintf(stderr, "poise run %s: FAILED: cannot record to %s: %s\n",
                     scenario.name.c_str(), recording.c_str(), why.c_str());
        recorder->stop(3000);
        write_failure("cannot record to " + recording.string() + ": " + why);
        return 2;
      }
      if (!s.quiet)
        std::printf("  recording every topic to %s%s\n", recording.c_str(),
                    s.record_passive ? " (passive capture on lo)" : "");
    }

    std::string failure;
    try {
      // The scenario's balance-reference trajectory: played by poise-reference in step with the
      // state (it waits for the robot description and the first state), kept running (--hold)
      // so that it ends with the run like the nodes.
      if (!scenario.reference.empty()) {
        ComponentSpec c;
        c.name = "reference";
        vendor["reference"] = vendor["controller"];
        c.argv = common("reference");
        c.argv.insert(c.argv.end(), {scenario.reference.string(), "--hold"});
        c.runs_until_stopped = true;
        children.push_back(&supervisor.start(std::move(c)));
      }
      for (auto* spec : {&sim_args, &contact_args, &est_args, &ctrl_args}) {
        ComponentSpec c;
        c.name = spec == &sim_args       ? "sim"
                 : spec == &contact_args ? "contact"
                 : spec == &est_args     ? "estimator"
                                         : "controller";
        c.argv = *spec;
        c.ends_run = spec == &sim_args;   // the simulator's end is the run's end
        c.runs_until_stopped = !c.ends_run;  // a node that ends before it is a failure
        children.push_back(&supervisor.start(std::move(c)));
      }
    } catch (const std::exception& e) {
      write_failure(std::string("cannot start a component: ") + e.what());
      return 2;
    }
    Child& sim = *children[scenario.reference.empty() ? 0 : 1];

    if (recorder) {
      const auto t0 = std::chrono::steady_clock::now();
      std::string missing;
      for (;;) {
        const auto have = recorder_writers(recorder->stderr_path());
        missing.clear();
        for (const auto& [topic, n] : stack_writers()) {
          const auto it = have.find(topic);
          if (it == have.end() || it->second < n)
            missing += (missing.empty() ? "" : ", ") + topic;
        }
        // And the writer side: each node has matched the readers of its outputs.
        for (auto& c : children) {
          if (c == &sim || c->name() == "reference") continue;  // no outputs of the loop
          std::ifstream err(c->stderr_path());
          const std::string text((std::istreambuf_iterator<char>(err)),
                                 std::istreambuf_iterator<char>());
          if (text.find("output readers matched") == std::string::npos)
            missing += (missing.empty() ? "" : ", ") + c->name() + "'s output readers";
        }
        const double waited =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (missing.empty()) {
          if (!s.quiet) std::printf("  every writer and reader of the run matched after %.2f s\n", waited);
          break;
        }
        if (waited > 20.0) {
          std::fprintf(stderr,
                       "poise run %s: warning: after 20 s still waiting for %s; starting anyway "
                       "(the recording may miss their first samples)\n",
                       scenario.name.c_str(), missing.c_str());
          break;
        }
        const Supervisor::Status st = supervisor.poll("during start-up");
        if (st.run_ended) failure = "sim " + sim.exit_description() + " during start-up";
        if (failure.empty()) failure = st.failure;
        if (!failure.empty() || g_interrupted.load()) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      std::ofstream(start_file) << "go\n";
    }

    const auto t_start = std::chrono::steady_clock::now();
    LineFollower progress(sim.stdout_path());
    int sim_code = -1;
    while (failure.empty()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      for (const auto& line : progress.poll())  // relay the simulator's progress lines
        if (!s.quiet && line.rfind("progress ", 0) == 0) std::printf("  %s\n", line.c_str() + 9);
      std::fflush(stdout);
      const Supervisor::Status st = supervisor.poll("before the end of the run");
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
      if (std::chrono::steady_clock::now() - t_start > std::chrono::duration<double>(timeout_s)) {
        failure = "timeout: the run took more than " + std::to_string(timeout_s) + " s";
        break;
      }
    }
    // Stop the simulator first (it writes its result), then the others (they write summaries),
    // last the recorder: SIGTERM makes it write what it holds, the loss counters and the summary.
    supervisor.stop({"sim", "contact", "estimator", "controller", "reference", "recorder"});
    if (!failure.empty()) sim_code = sim.poll().value_or(-1);
    std::string record_problem;
    if (recorder) {
      const int code = recorder->poll().value_or(-1);
      const std::string summary = recorder->stderr_tail(1);
      if (code != 0) {
        record_problem = "the recorder " + recorder->exit_description();
        std::fprintf(stderr, "poise run %s: %s (%s):\n%s", scenario.name.c_str(),
                     record_problem.c_str(), recorder->stderr_path().c_str(),
                     recorder->stderr_tail(8).c_str());
      } else if (!s.quiet) {
        std::printf("  recorded: %s", summary.c_str());
      }
    }

    if (!failure.empty() || (sim_code != 0 && sim_code != 3)) {
      if (failure.empty()) failure = "sim " + sim.exit_description();
      std::fprintf(stderr, "poise run %s: FAILED: %s\n", scenario.name.c_str(), failure.c_str());
      for (auto& c : children) {
        const std::string tail = c->stderr_tail(8);
        const bool culprit = failure.rfind(c->name() + " ", 0) == 0;
        if (culprit || failure.rfind("sim", 0) == 0 || failure.rfind("timeout", 0) == 0)
          std::fprintf(stderr, "--- last stderr lines of %s (pid %d, %s):\n%s", c->name().c_str(),
                       static_cast<int>(c->pid()), c->stderr_path().c_str(), tail.c_str());
      }
      write_failure(failure);
      if (failure != "interrupted") return 2;
      return 130;
    }

    const Json sim_r = read_json(logs / "sim.summary.json");
    const Json ctrl_r = read_json(logs / "controller.summary.json");
    const Json est_r = read_json(logs / "estimator.summary.json");
    const Json con_r = read_json(logs / "contact.summary.json");
    const Json ref_r = scenario.reference.empty() ? Json() : read_json(logs / "reference.summary.json");
    if (sim_r.is_null()) {
      std::fprintf(stderr, "poise run: the simulator wrote no result (%s)\n",
                   (logs / "sim.summary.json").c_str());
      write_failure("the simulator wrote no result (" + (logs / "sim.summary.json").string() +
                    ")");
      return 2;
    }
    auto diag = [](const Json& j, const char* key) -> std::uint64_t {
      return j.is_object() && j.contains("diagnostics") ? j["diagnostics"].value(key, 0ULL) : 0ULL;
    };
    Json r;
    r["scenario"] = scenario.name;
    r["survived"] = sim_r.value("survived", false);
    r["completed"] = sim_r.value("completed", false);
    for (const char* k :
         {"com_error_max_m", "com_error_final_m", "foot_slip_max_m", "foot_slide_max_m",
          "foot_displacement_max_m", "foot_tilt_max_deg", "non_foot_contacts",
          "min_base_height_m", "recovery_time_s", "trunk_pitch_max_deg", "trunk_roll_max_deg",
          "failed_criteria", "tick_latency_us", "realtime_factor", "sim_time_s", "wall_time_s",
          "command_timeouts", "damping_ticks", "watchdog_stale_events", "hold_ticks",
          "estop_ticks", "safety", "max_joint_speed", "reality"})
      r[k] = sim_r.value(k, Json());
    const std::uint64_t misses_sim = diag(sim_r, "deadline_misses");
    const std::uint64_t misses_ctrl = diag(ctrl_r, "deadline_misses");
    r["deadline_misses"] = misses_sim + misses_ctrl;
    r["deadline_misses_by_node"] = {{"sim", misses_sim}, {"controller", misses_ctrl}};
    r["rejected_samples"] = diag(sim_r, "rejected_samples") + diag(ctrl_r, "rejected_samples") +
                            diag(est_r, "rejected_samples") + diag(con_r, "rejected_samples");
    r["errors"] = {{"sim", diag(sim_r, "errors")},
                   {"estimator", diag(est_r, "errors")},
                   {"contact", diag(con_r, "errors")},
                   {"controller", diag(ctrl_r, "errors")}};
    r["compute_us"] = Json::object();  // per node, whole run: sim = step, controller = own
    r["library_us"] = Json::object();   // the library call alone (estimator, controller, contact)
    r["overhead_us"] = Json::object();  // the node's own work around it, DDS write excluded
    r["dds_write_us"] = Json::object();  // its DDS writes (serialisation + vendor write)
    for (const auto& [name, j] : {std::pair<std::string, const Json*>{"sim", &sim_r},
                                  {"estimator", &est_r},
                                  {"contact", &con_r},
                                  {"controller", &ctrl_r}}) {
      r["compute_us"][name] = j->is_object() ? j->value("compute_us_run", Json()) : Json();
      if (j->is_object() && j->contains("library_us_run")) {
        r["library_us"][name] = (*j)["library_us_run"];
        r["overhead_us"][name] = (*j)["overhead_us_run"];
        if (j->contains("dds_write_us_run")) r["dds_write_us"][name] = (*j)["dds_write_us_run"];
      }
    }
    // Every kind of miss, per node and for the loop (a miss = a tick not handled as designed).
    auto num = [](const Json& j, const char* key) -> std::uint64_t {
      return j.is_object() && j.contains(key) && j[key].is_number_unsigned()
                 ? j[key].get<std::uint64_t>()
                 : (j.is_object() && j.contains(key) && j[key].is_number_integer()
                        ? static_cast<std::uint64_t>(std::max<std::int64_t>(0, j[key].get<std::int64_t>()))
                        : 0ULL);
    };
    const Json safety = sim_r.value("safety", Json::object());
    Json misses;
    misses["controller_contact_wait"] = misses_ctrl;
    misses["controller_commands_withheld"] = num(ctrl_r, "commands_withheld");
    misses["sim_overruns"] = num(sim_r, "overruns");
    misses["sim_command_timeouts"] = num(sim_r, "command_timeouts");
    misses["robot_hold_ticks"] = num(sim_r, "hold_ticks");
    misses["robot_damping_ticks"] = num(sim_r, "damping_ticks");
    misses["robot_late_commands"] = num(safety, "rejected_tick");
    misses["robot_refused_commands"] = num(safety, "rejected") - num(safety, "rejected_tick");
    misses["estimator_dropped_frames"] = num(est_r, "dropped_frames");
    misses["out_of_sequence"] = num(est_r, "out_of_sequence") + num(ctrl_r, "out_of_sequence");
    // Balance references that reached the controller after the state of their tick (a reference
    // player that fell behind: each applied a tick late).
    misses["controller_late_references"] = num(ctrl_r, "late_references");
    r["contact_problems_resent"] = num(ctrl_r, "problems_resent");  // not a miss: a repeat
    misses["samples_rejected"] = r["rejected_samples"];
    r["misses"] = misses;
    // A damping tick is a lost tick of balance control: the run fails above the scenario's
    // tolerance (success.max_damping_ticks, default 0).
    const long long damping_tolerance = scenario.success.max_damping_ticks;
    r["max_damping_ticks"] = damping_tolerance;
    std::string verdict_reason;
    if (!r["failed_criteria"].is_array()) r["failed_criteria"] = Json::array();
    if (static_cast<long long>(num(sim_r, "damping_ticks")) > damping_tolerance) {
      r["failed_criteria"].push_back(std::to_string(num(sim_r, "damping_ticks")) +
                                     " damping ticks > " + std::to_string(damping_tolerance));
      r["survived"] = false;
    }
    // One commanding writer: joint commands from anyone else on the domain were refused by the
    // robot side; the run is not the scenario's (someone else tried to command the robot).
    misses["robot_foreign_commands"] = num(sim_r, "foreign_commands");
    if (num(sim_r, "foreign_commands") > 0) {
      r["failed_criteria"].push_back(
          std::to_string(num(sim_r, "foreign_commands")) +
          " joint commands from a second writer of poise/joint_command were refused (another "
          "process on the domain commanded the robot; the simulator's log names both writers)");
      r["survived"] = false;
    }
    r["misses"] = misses;
    // The scenario's reference trajectory must have been played in full: a player that fell
    // behind the state stream never sends the references of the ticks it skipped (a step in place that never stepped
    // "survived" before). The in-process loop's player sees every state: it skips none.
    if (!scenario.reference.empty()) {
      r["misses"]["reference_skipped_ticks"] = num(ref_r, "skipped_ticks");
      if (num(ref_r, "skipped_ticks") > 0)
        r["failed_criteria"].push_back(
            "the reference player skipped " + std::to_string(num(ref_r, "skipped_ticks")) +
            " ticks of the trajectory (it fell behind the state stream): the scenario's "
            "reference was not played in full");
      if (!ref_r.is_object())
        r["failed_criteria"].push_back("the reference player wrote no summary (" +
                                       (logs / "reference.summary.json").string() + ")");
      if (num(ref_r, "skipped_ticks") > 0 || !ref_r.is_object()) r["survived"] = false;
    }
    // In lockstep the run is the scenario only if every balance reference was applied at its
    // tick: a late one (the player starved of CPU) makes a different run than in process.
    if (!s.realtime && num(ctrl_r, "late_references") > 0) {
      r["failed_criteria"].push_back(
          std::to_string(num(ctrl_r, "late_references")) +
          " balance references reached the controller after their tick (the reference player "
          "fell behind): this lockstep run does not follow the scenario");
      r["survived"] = false;
    }
    // The controller declared a fall (FallConfig): it damps the joints from then on.
    r["controller_fall"] = Json();
    if (ctrl_r.is_object() && ctrl_r.value("fall_tick", -1LL) >= 0) {
      const double t = static_cast<double>(ctrl_r.value("fall_tick", -1LL)) * ccfg.dt;
      const std::string why = ctrl_r.value("fall", std::string());
      r["controller_fall"] = {{"time_s", t}, {"reason", why}};
      r["recovery_time_s"] = Json();  // a fall never recovered (null, as in process)
      char ts[32];
      std::snprintf(ts, sizeof ts, "%.3f", t);
      r["failed_criteria"].push_back("the controller declared a fall at " + std::string(ts) +
                                     " s (" + why + "): joints damped");
      r["survived"] = false;
    }
    for (const auto& f : r["failed_criteria"])
      verdict_reason += (verdict_reason.empty() ? "" : "; ") + f.get<std::string>();
    if (!verdict_reason.empty()) r["failure"] = verdict_reason;
    // What each process got of the real-time settings (applied or refused, thread policies,
    // page faults after its first tick).
    r["realtime_settings"] = Json::object();
    for (const auto& [name, j] : {std::pair<std::string, const Json*>{"sim", &sim_r},
                                  {"estimator", &est_r},
                                  {"contact", &con_r},
                                  {"controller", &ctrl_r}})
      if (j->is_object() && j->contains("realtime")) r["realtime_settings"][name] = (*j)["realtime"];
    r["state_source"] = s.ground_truth_state ? "ground_truth" : "estimator";
    r["dds"] = vendor;
    r["domain"] = domain;
    r["mode"] = s.realtime ? "realtime" : "lockstep";
    r["contact_method"] = s.method;
    r["contact_priority"] = contact::to_string(ccfg.contact.priority);
    r["contact_torsion_limit"] = contact::to_string(ccfg.contact.torsion_limit);
    r["estimator_supports"] = scenario.estimator.supports;
    r["estimator"] = s.estimator;
    if (recorder) {
      r["recording"] = recording.string();
      r["recording_ok"] = record_problem.empty();
    }
    r["pids"] = Json::object();
    for (auto& c : children)
      r["pids"][c->name()] = c->pid();
    if (recorder) r["pids"]["recorder"] = recorder->pid();
    {
      std::ofstream out(output);
      out << r.dump(2) << "\n";
    }
    const Json& lat = r["tick_latency_us"];
    if (!s.quiet) std::printf(
        "  misses: contact wait %llu, commands withheld %llu, sim overruns %llu, hold ticks %llu, "
        "damping ticks %llu, late commands %llu, refused commands %llu, dropped frames %llu, "
        "out of sequence %llu, rejected samples %llu, late references %llu%s%s\n",
        static_cast<unsigned long long>(misses["controller_contact_wait"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["controller_commands_withheld"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["sim_overruns"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["robot_hold_ticks"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["robot_damping_ticks"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["robot_late_commands"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["robot_refused_commands"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["estimator_dropped_frames"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["out_of_sequence"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["samples_rejected"].get<std::uint64_t>()),
        static_cast<unsigned long long>(misses["controller_late_references"].get<std::uint64_t>()),
        verdict_reason.empty() ? "" : ": FAILED on ", verdict_reason.c_str());
    if (s.rt_priority > 0 || s.lock_memory || !s.cpus.empty()) {
      // One line per process: what it got, and any refusal in full (never silent).
      for (auto it = r["realtime_settings"].begin(); it != r["realtime_settings"].end(); ++it) {
        std::string got;
        for (const auto& a : it.value().value("applied", Json::array()))
          got += (got.empty() ? "" : ", ") + a.get<std::string>();
        if (!s.quiet)
          std::printf("  real time %s: %s\n", it.key().c_str(), got.empty() ? "nothing applied" : got.c_str());
        for (const auto& a : it.value().value("refused", Json::array()))
          std::printf("  real time %s: %s\n", it.key().c_str(), a.get<std::string>().c_str());
      }
    }
    for (const char* node : {"estimator", "controller", "contact"})
      if (!s.quiet && r["library_us"].contains(node)) {
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
    std::printf(
        "%s %s (%s, %s)%s%s: com_error max %.3f m final %.3f m, foot slip %.4f m tilt %.1f deg, "
        "non-foot "
        "contacts %d, trunk pitch/roll max %.1f/%.1f deg, tick latency p50/p99/max %.0f/%.0f/%.0f "
        "us, deadline misses %llu, %.2fx real time -> %s\n",
        r["survived"].get<bool>() ? "SURVIVED" : "FAILED", scenario.name.c_str(),
        s.realtime ? "realtime" : "lockstep",
        vendor["sim"] == vendor["controller"] && vendor["sim"] == vendor["estimator"] &&
                vendor["sim"] == vendor["contact"]
            ? vendor["sim"].c_str()
            : "mixed dds",
        verdict_reason.empty() ? "" : " on ", verdict_reason.c_str(),
        r.value("com_error_max_m", 0.0), r.value("com_error_final_m", 0.0),
        r.value("foot_slip_max_m", 0.0), r.value("foot_tilt_max_deg", 0.0),
        r.value("non_foot_contacts", 0),
        r.value("trunk_pitch_max_deg", 0.0), r.value("trunk_roll_max_deg", 0.0),
        lat.is_object() ? lat.value("p50", 0.0) : 0.0,
        lat.is_object() ? lat.value("p99", 0.0) : 0.0,
        lat.is_object() ? lat.value("max", 0.0) : 0.0,
        static_cast<unsigned long long>(misses_sim + misses_ctrl), r.value("realtime_factor", 0.0),
        output.c_str());
    std::fflush(stdout);
    if (!record_problem.empty()) return 2;
    return r["survived"].get<bool>() ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise run: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::launch
