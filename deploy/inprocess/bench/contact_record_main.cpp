// poise-contact-record: records real contact problems for the benchmark corpus. Runs scenarios
// in the in-process loop (simulator -> estimator -> balance controller -> contact optimiser, no
// DDS; poise::inprocess::InProcessLoop, used as it is) and writes, tick by tick, the contact
// problem the balance controller posed to the optimiser (BalanceController::problem()) in the
// corpus text format, tagged recorded_double / recorded_single by the support of that tick.
//
//   poise-contact-record OUTPUT [SCENARIO...] [--every N] [--method sequential|qp]
//                        [--ground-truth] [--duration S]
// Default scenarios: the paper's pushes, forward_push_double_support and
// lateral_push_single_support (deploy/scenarios/). Lockstep simulation: the same command line
// gives the same file.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "contact_corpus.hpp"
#include "poise/inprocess/in_process_loop.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/cli/parse.hpp"

namespace {

namespace fs = std::filesystem;
using namespace poise;

/// A path, or a scenario name looked up in deploy/scenarios/ of the source tree.
fs::path resolve_scenario(const std::string& arg) {
  if (fs::exists(arg)) return arg;
  for (const std::string& cand : {arg, arg + ".yaml"}) {
    const fs::path q = fs::path(POISE_SOURCE_DIR) / "deploy/scenarios" / cand;
    if (fs::exists(q)) return q;
  }
  return arg;  // the loader reports the missing file
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Record the contact problems the balance controller poses while the simulator runs "
      "scenarios (in process), as a corpus for poise-bench-contact."};
  std::string out;
  std::vector<std::string> scenarios{"forward_push_double_support", "lateral_push_single_support"};
  int every = 1;
  std::string method = "sequential";
  bool ground_truth = false;
  double duration = 0.0;
  app.add_option("output", out, "output corpus file")->required();
  app.add_option("scenarios", scenarios, "scenario files or names in deploy/scenarios/")
      ->capture_default_str();
  app.add_option("--every", every, "record every N-th tick")->check(CLI::PositiveNumber);
  app.add_option("--method", method, "contact method inside the loop")
      ->check(CLI::IsMember({"sequential", "qp"}));
  app.add_flag("--ground-truth", ground_truth,
               "controller state from the simulator's ground truth (default: the estimator)");
  app.add_option("--duration", duration, "simulated seconds per scenario (default: the scenario's)")
      ->check(CLI::NonNegativeNumber);
  POISE_CLI_PARSE(app, argc, argv);

  std::vector<contact::bench::CorpusEntry> corpus;
  std::vector<std::string> comments{
      "recorded by poise-contact-record from BalanceController::problem() in the in-process loop"};
  try {
    for (const std::string& name : scenarios) {
      const scenario::Scenario scenario = scenario::load_scenario(resolve_scenario(name));
      inprocess::LoopOptions opt;
      opt.state_source = ground_truth || !inprocess::estimator_available()
                             ? inprocess::StateSource::kGroundTruth
                             : inprocess::StateSource::kEstimator;
      opt.contact_method = *contact::parse_method(method);
      opt.duration = duration;
      inprocess::InProcessLoop loop(scenario, opt);
      long ticks = 0, kept_double = 0, kept_single = 0, skipped = 0;
      while (loop.time() < loop.duration()) {
        loop.step();
        if (ticks++ % every != 0) continue;
        const contact::ContactProblem& p = loop.controller().problem();
        const bool right = p.feet[0].in_contact, left = p.feet[1].in_contact;
        if (contact::validate(p) != nullptr || (!right && !left)) {
          ++skipped;  // nothing for the optimiser to do (or a problem it would refuse)
          continue;
        }
        const bool two = right && left;
        corpus.push_back(
            {two ? contact::bench::Kind::kRecordedDouble : contact::bench::Kind::kRecordedSingle,
             p});
        ++(two ? kept_double : kept_single);
      }
      const inprocess::RunResult r = loop.result();
      char line[512];
      std::snprintf(line, sizeof line,
                    "%s: %ld ticks, %s, state %s, method %s, every %d: %ld double + %ld single "
                    "support problems (%ld skipped); CoM error max %.4f m, final %.4f m",
                    scenario.name.c_str(), ticks, r.survived ? "survived" : "FAILED",
                    inprocess::to_string(opt.state_source), method.c_str(), every, kept_double,
                    kept_single, skipped, r.com_error_max_m, r.com_error_final_m);
      std::printf("%s\n", line);
      comments.emplace_back(line);
    }
    contact::bench::write_corpus(out, corpus, comments);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-contact-record: error: %s\n", e.what());
    return 1;
  }
  std::printf("wrote %zu recorded problems to %s\n", corpus.size(), out.c_str());
  return 0;
}
