// `poise run`: run a scenario. `--in-process` composes the libraries in this process (no DDS);
// the DDS-distributed mode (the default) is poise::launch::run_distributed (deploy/launch).
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <string_view>

#include "poise/inprocess/in_process_loop.hpp"
#include "poise/launch/launch.hpp"
#include "poise/sim/reality_json.hpp"
#include "poise/cli/parse.hpp"

namespace poise::inprocess {

nlohmann::json to_json(const RunResult& r) {
  nlohmann::json j;
  j["scenario"] = r.scenario;
  j["survived"] = r.survived;
  j["com_error_max_m"] = r.com_error_max_m;
  j["com_error_final_m"] = r.com_error_final_m;
  j["foot_slip_max_m"] = r.foot_slip_max_m;
  j["foot_slide_max_m"] = r.foot_slide_max_m;
  j["foot_displacement_max_m"] = r.foot_displacement_max_m;
  j["foot_tilt_max_deg"] = r.foot_tilt_max_deg;
  j["non_foot_contacts"] = r.non_foot_contacts;
  j["tick_latency_us"] = {{"p50", r.tick_latency_us.p50_us},
                          {"p99", r.tick_latency_us.p99_us},
                          {"max", r.tick_latency_us.max_us}};
  j["deadline_misses"] = r.deadline_misses;
  j["realtime_factor"] = r.realtime_factor;
  j["state_source"] = to_string(r.state_source);
  j["mode"] = "in_process";
  j["sim_time_s"] = r.sim_time_s;
  j["ticks"] = r.ticks;
  j["min_base_height_m"] = r.min_base_height_m;
  j["recovery_time_s"] = std::isfinite(r.recovery_time_s) ? nlohmann::json(r.recovery_time_s)
                                                          : nlohmann::json(nullptr);
  j["trunk_pitch_max_deg"] = r.trunk_pitch_max_deg;
  j["trunk_roll_max_deg"] = r.trunk_roll_max_deg;
  j["failed_criteria"] = r.failed;
  j["controller_fall"] = r.controller_fall.empty()
                             ? nlohmann::json(nullptr)
                             : nlohmann::json{{"time_s", r.controller_fall_time_s},
                                              {"reason", r.controller_fall}};
  if (!r.failed.empty()) {
    std::string why;
    for (const auto& f : r.failed) why += (why.empty() ? "" : "; ") + f;
    j["failure"] = why;
  }
  j["completed"] = r.completed;
  j["command_timeouts"] = r.command_timeouts;
  j["contact_fallbacks"] = r.contact_fallbacks;
  j["qp_failures"] = r.qp_failures;
  j["rejected_commands"] = r.rejected_commands;
  j["reality"] = sim::reality_to_json(r.reality);
  return j;
}

namespace {

/// A path, or a scenario name looked up in deploy/scenarios/ of the source tree.
std::filesystem::path resolve_scenario(const std::string& arg) {
  std::filesystem::path p(arg);
  if (std::filesystem::exists(p)) return p;
  for (const std::string& cand : {arg, arg + ".yaml"}) {
    const std::filesystem::path q =
        std::filesystem::path(POISE_SOURCE_DIR) / "deploy/scenarios" / cand;
    if (std::filesystem::exists(q)) return q;
  }
  return p;  // let the loader report the missing file
}

}  // namespace

int cli_main(int argc, char** argv) {
  // Default mode: every component in its own process over DDS (deploy/launch).
  const auto has = [&](std::string_view flag) {
    return std::any_of(argv + 1, argv + argc, [&](const char* a) { return flag == a; });
  };
  if (!has("--in-process")) {
    const int rc = launch::run_distributed(argc, argv);
    if (has("--help") || has("-h")) {
      std::cout << "\nWith --in-process, all components run in this process without DDS "
                   "(the baseline for the DDS overhead): see `poise run --in-process --help`.\n";
    }
    return rc;
  }
  CLI::App app{"Run a scenario (paper Sec. 4 experiments in deploy/scenarios/)", "poise run"};
  std::string scenario_arg, output, method, controller_config;
  bool in_process = false, ground_truth = false, quiet = false;
  double duration = 0.0;
  app.add_option("scenario", scenario_arg, "Scenario YAML file, or a name in deploy/scenarios/")
      ->required();
  app.add_flag("--in-process", in_process,
               "Compose simulator, estimator, controller and contact optimiser in this process "
               "(no DDS)");
  app.add_flag("--ground-truth-state", ground_truth,
               "DEBUG: feed the controller the simulator's ground truth instead of the estimator");
  app.add_option("--output,-o", output,
                 "JSON result file, the distributed run's fields (default: none; the verdict is "
                 "printed)");
  app.add_option("--contact-method", method,
                 "Contact optimiser: sequential (paper) or qp (default: the scenario's "
                 "contact.method, else sequential)")
      ->check(CLI::IsMember({"sequential", "qp"}));
  app.add_option("--controller-config", controller_config,
                 "Controller YAML (default: built-in paper values, "
                 "controller/momentum/config/balance_controller.yaml)");
  app.add_option("--duration", duration, "Simulated time [s] (default: the scenario's)")
      ->check(CLI::Range(0.0, 1e6));
  std::string estimator_kind;
  app.add_option("--estimator", estimator_kind,
                 "Estimator that makes the state: invariant-ekf or leg-odometry (default: the "
                 "scenario's estimator.type, else invariant-ekf)")
      ->check(CLI::IsMember({"invariant-ekf", "leg-odometry"}));
  int settle_ticks = -1;
  app.add_option("--settle-ticks", settle_ticks,
                 "start-up: simulator steps with the joints held by the safety layer before the "
                 "first control tick (default: poise-sim's, 10, as `poise run` distributed)")
      ->check(CLI::Range(0, 10000));
  app.add_flag("--quiet,-q", quiet, "No progress lines");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return poise::cli::usage_exit(app, e);
  }
  try {
    const scenario::Scenario scenario = scenario::load_scenario(resolve_scenario(scenario_arg));
    LoopOptions opt;
    opt.state_source = ground_truth ? StateSource::kGroundTruth : StateSource::kEstimator;
    if (opt.state_source == StateSource::kEstimator && !estimator_available()) {
      std::cerr << "poise run: WARNING: the estimator library is not built; using the ground-truth "
                   "state (debug)\n";
      opt.state_source = StateSource::kGroundTruth;
    }
    if (!method.empty()) opt.contact_method = *contact::parse_method(method);
    method = contact::to_string(contact_method_of(scenario, opt));
    opt.controller_config_file = controller_config;
    opt.duration = duration;
    opt.settle_ticks = settle_ticks;
    opt.estimator = estimator_kind.empty() ? scenario.estimator.type : estimator_kind;
    InProcessLoop loop(scenario, opt);
    if (!quiet)
      std::cerr << "poise run: " << scenario.name << " in process, " << loop.duration()
                << " s, state from " << to_string(opt.state_source)
                << (opt.state_source == StateSource::kEstimator ? " (" + opt.estimator + ")" : "")
                << ", contact method " << method
                << "\n";
    for (const std::string& w : loop.safety_warnings())
      std::cerr << "  safety: " << w << "\n";
    if (!quiet && scenario.sim.reality.enabled)
      std::cerr << "  " << sim::describe_reality(loop.result().reality) << "\n";
    const RunResult r = loop.run([&](double t) {
      if (quiet) return;
      const auto p = loop.result();
      std::fprintf(stderr, "  t = %5.1f s  CoM error %.4f m (max %.4f)  tick p50 %.1f us\n", t,
                   p.com_error_final_m, p.com_error_max_m, p.tick_latency_us.p50_us);
    });
    std::string why;
    for (const auto& f : r.failed) why += (why.empty() ? " on " : "; ") + f;
    std::printf(
        "%s: %s%s  (CoM error max %.4f m, final %.4f m; foot slip %.4f m, tilt %.1f deg; "
        "non-foot contacts %d; "
        "trunk pitch/roll max %.1f/%.1f deg; tick p50 %.1f us p99 %.1f us; %llu deadline misses; "
        "x%.2f real time; state %s)\n",
        r.scenario.c_str(), r.survived ? "SURVIVED" : "FAILED", why.c_str(), r.com_error_max_m,
        r.com_error_final_m, r.foot_slip_max_m, r.foot_tilt_max_deg, r.non_foot_contacts,
        r.trunk_pitch_max_deg, r.trunk_roll_max_deg, r.tick_latency_us.p50_us,
        r.tick_latency_us.p99_us,
        static_cast<unsigned long long>(r.deadline_misses), r.realtime_factor,
        to_string(r.state_source));
    if (!output.empty()) {
      std::ofstream out(output);
      if (!out) {
        std::cerr << "poise run: cannot write " << output << "\n";
        return 2;
      }
      nlohmann::json j = to_json(r);
      j["contact_method"] = method;
      j["contact_priority"] = contact::to_string(loop.controller().config().contact.priority);
      j["contact_torsion_limit"] =
          contact::to_string(loop.controller().config().contact.torsion_limit);
      j["estimator_supports"] = scenario.estimator.supports;
      j["estimator"] = opt.estimator;
      out << j.dump(2) << "\n";
    }
    return r.survived ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "poise run: " << e.what() << "\n";
    return 2;
  }
}

}  // namespace poise::inprocess
