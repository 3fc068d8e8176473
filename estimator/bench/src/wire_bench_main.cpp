// poise-bench-estimator-wire: the estimator's accuracy measured from the wire (issue #20 item 2).
// For each scenario x estimator: `poise run SCENARIO --estimator E --record` (every component in
// its own process, loopback DDS, lockstep), then poise/state against poise/ground_truth of the
// recording, matched by tick (wire_accuracy.hpp says which figures). Prints a table, optionally
// JSON. `--analyse FILE.mcap --scenario S` analyses an existing recording instead.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "poise/estimator_bench/wire_accuracy.hpp"
#include "poise/cli/parse.hpp"

int main(int argc, char** argv) {
  using namespace poise::estimator_bench;
  namespace fs = std::filesystem;
  CLI::App app{
      "Estimator accuracy from the wire: runs each scenario distributed with each estimator, "
      "records poise/state and poise/ground_truth, prints world-frame errors, errors relative "
      "to the supporting feet and world drift at 5/10/20 s (estimator/README.md)"};
  std::vector<std::string> scenarios{"standing", "forward_push_double_support",
                                     "platforms_in_phase", "platforms_out_of_phase"};
  std::vector<std::string> estimators{"invariant-ekf", "leg-odometry"};
  double duration = -1.0;
  std::string out_dir = "results/estimator_wire", json, analyse;
  std::string poise_bin = (fs::path(argv[0]).parent_path() / "poise").string();
  double timeout_s = 900.0;
  std::vector<std::string> extra;
  app.add_option("--scenarios", scenarios, "scenario names or files")->capture_default_str();
  app.add_option("--estimators", estimators, "invariant-ekf and/or leg-odometry")
      ->check(CLI::IsMember({"invariant-ekf", "leg-odometry"}))
      ->capture_default_str();
  app.add_option("--duration", duration, "override each scenario's duration [s]");
  app.add_option("--out-dir", out_dir, "recordings, results and logs go here")
      ->capture_default_str();
  app.add_option("--json", json, "also write the figures as JSON to this file");
  app.add_option("--poise", poise_bin, "the poise executable")->capture_default_str();
  app.add_option("--timeout", timeout_s, "wall-clock bound of each run [s]")->capture_default_str();
  app.add_option("--run-option", extra, "extra option for every poise run (repeatable), e.g. "
                                        "--run-option=--dds --run-option=fastdds");
  app.add_option("--analyse", analyse, "analyse this recording only (with one --scenarios)");
  POISE_CLI_PARSE(app, argc, argv);

  std::vector<Accuracy> results;
  try {
    if (!analyse.empty()) {
      if (scenarios.size() != 1) {
        std::cerr << "poise-bench-estimator-wire: --analyse takes exactly one --scenarios FILE\n";
        return 2;
      }
      results.push_back(analyse_recording(analyse, scenarios[0]));
    } else {
      for (const auto& sc : scenarios)
        for (const auto& est : estimators) {
          RunOptions o;
          o.poise_bin = poise_bin;
          o.scenario = sc;
          o.estimator = est;
          o.duration = duration;
          o.timeout_s = timeout_s;
          o.extra = extra;
          o.dir = (fs::path(out_dir) / (fs::path(sc).stem().string() + "." + est)).string();
          std::fprintf(stderr, "poise-bench-estimator-wire: %s with %s ...\n", sc.c_str(),
                       est.c_str());
          results.push_back(run_and_analyse(o));
          std::cout << format_table({results.back()}) << std::flush;
        }
    }
  } catch (const std::exception& e) {
    std::cerr << "poise-bench-estimator-wire: " << e.what() << "\n";
    return 2;
  }
  std::cout << "\n" << format_table(results);
  if (!json.empty()) std::ofstream(json) << to_json(results);
  for (const auto& r : results)
    if (!r.error.empty()) return 1;
  return 0;
}
