// `poise envelope`: the balance envelope of a robot and controller, measured by running scenarios
// (deploy/envelope/README.md).
//
//   pushes      for each of N directions of the horizontal plane, in double and in single support:
//               the force of a 0.1 s push is raised in steps until the first failure, the boundary
//               is bisected between the last survival and that failure, and a few forces above
//               it are probed: a survival there is a non-monotone point, reported.
//   fig11       the paper's Fig. 11 (forward push, double support): for each force, the longest
//               push survived (bisection on the duration) and its impulse.
//   platforms   for each platform scenario, the highest support frequency survived over a given
//               number of full periods (steps, bisection, probes as for pushes).
// Every run is a scenario derived from a base file (a shipped scenario unless given), run in
// process (default) or distributed in lockstep (`poise run` children). Output in DIR: runs.csv
// (every run), envelope.csv (the boundaries), envelope.md (summary next to the paper's values),
// push_envelope.png/.svg (polar) and fig11.png/.svg (gnuplot).
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/inprocess/in_process_loop.hpp"
#include "poise/launch/child.hpp"
#include "poise/plot/balance_plot.hpp"
#include "poise/scenario/scenario.hpp"
#include "random_study.hpp"
#include "poise/cli/parse.hpp"

namespace poise::envelope {

namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Options {
  std::string what = "all";  // all | pushes | fig11 | platforms
  std::string mode = "in-process";
  std::string double_base, single_base;
  std::vector<std::string> platform_bases;
  int directions = 8;
  int single_directions = 4;
  std::string supports = "double,single";
  double push_duration = 0.1;
  double force_step = 25.0, force_tol = 5.0, force_max = 500.0;
  int probes = 3;
  double jitter_deg = 0.0;  // > 0: each push force also at direction -+ this; all must survive
  std::vector<double> grid_forces;  // pushes: these forces only (a grid), no scan or bisection
  std::vector<double> fig11_forces{40, 60, 80, 100, 120, 160, 200, 250};
  double duration_max = 1.5, duration_tol = 0.01;
  double freq_step = 0.1, freq_tol = 0.02, freq_max = 2.0;
  double periods = 3.0;
  std::string priority;  // "" = the base scenario's / controller default
  /// --controller-config: a controller YAML that replaces every run's `controller:` section
  /// (loaded and validated before the first run; null node: not given).
  std::string controller_config;
  YAML::Node controller_node;
  std::string output_dir = "results/envelope";
  std::string gnuplot;
  double run_timeout_s = 600.0;
  bool ground_truth_state = false;
  bool quiet = false;
};

/// What one run gave.
struct Outcome {
  bool survived = false;
  double com_error_max_m = 0.0, foot_slip_max_m = 0.0;
  double foot_slide_max_m = 0.0;  // the sliding part of the slip (ScenarioMonitor)
  double foot_displacement_max_m = 0.0, foot_tilt_max_deg = 0.0;  // (ScenarioMonitor)
  double trunk_pitch_max_deg = 0.0, trunk_roll_max_deg = 0.0;
  std::string failed;  // the failed criteria, or the error that stopped the run
};

/// One row of runs.csv.
struct Row {
  std::string study, support;
  double direction_deg = 0.0, force_n = 0.0, duration_s = 0.0, frequency_hz = 0.0;
  Outcome o;
};

std::string csv_field(const std::string& s) {
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string source_file(const std::string& rel) {
  return (fs::path(POISE_SOURCE_DIR) / rel).string();
}

/// Makes relative robot paths of a scenario node absolute (the trial files live elsewhere).
void absolutise_paths(YAML::Node root, const fs::path& base_dir) {
  YAML::Node robot = root["robot"];
  if (!robot) return;
  for (const char* key : {"config", "urdf"}) {
    if (!robot[key] || !robot[key].IsScalar()) continue;
    const fs::path p = robot[key].as<std::string>();
    if (p.is_absolute()) continue;
    fs::path cand = base_dir / p;
    if (!fs::exists(cand)) cand = fs::path(POISE_SOURCE_DIR) / p;
    robot[key] = fs::weakly_canonical(cand).string();
  }
}

/// Runs scenarios and keeps every run.
class Runner {
 public:
  Runner(const Options& o, fs::path work) : o_(o), work_(std::move(work)) {
    if (o_.mode == "lockstep") {
      char buf[4096];
      const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof(buf) - 1);
      if (n <= 0) throw std::runtime_error("cannot find the poise executable (/proc/self/exe)");
      poise_ = std::string(buf, static_cast<std::size_t>(n));
    }
  }

  Outcome run(YAML::Node scenario, const std::string& name) {
    ++count_;
    scenario["name"] = name;
    if (!o_.controller_config.empty()) {
      if (o_.controller_node.IsMap())
        scenario["controller"] = YAML::Clone(o_.controller_node);
      else
        scenario.remove("controller");  // an empty file: the controller's defaults
    }
    if (!o_.priority.empty()) scenario["controller"]["contact"]["priority"] = o_.priority;
    Outcome out;
    try {
      // Every run's scenario is kept (runs/NAME.yaml): `poise run` re-runs one case.
      YAML::Emitter e;
      e << scenario;
      const fs::path file = work_ / (name + ".yaml");
      {
        std::ofstream f(file);
        f << e.c_str() << "\n";
        if (!f) throw std::runtime_error("cannot write " + file.string());
      }
      if (o_.mode == "in-process") {
        const scenario::Scenario sc = scenario::parse_scenario(e.c_str(), work_, "scenario " + name);
        inprocess::LoopOptions lo;
        if (o_.ground_truth_state) lo.state_source = inprocess::StateSource::kGroundTruth;
        inprocess::InProcessLoop loop(sc, lo);
        const inprocess::RunResult r = loop.run();
        out.survived = r.survived;
        out.com_error_max_m = r.com_error_max_m;
        out.foot_slip_max_m = r.foot_slip_max_m;
        out.foot_slide_max_m = r.foot_slide_max_m;
        out.foot_displacement_max_m = r.foot_displacement_max_m;
        out.foot_tilt_max_deg = r.foot_tilt_max_deg;
        out.trunk_pitch_max_deg = r.trunk_pitch_max_deg;
        out.trunk_roll_max_deg = r.trunk_roll_max_deg;
        for (const auto& f : r.failed) out.failed += (out.failed.empty() ? "" : "; ") + f;
      } else {
        out = run_lockstep(file, name);
      }
    } catch (const std::exception& e) {
      out.survived = false;
      out.failed = std::string("error: ") + e.what();
      if (!o_.quiet) std::fprintf(stderr, "poise envelope: %s: %s\n", name.c_str(), e.what());
    }
    return out;
  }

  int count() const { return count_; }

 private:
  Outcome run_lockstep(const fs::path& file, const std::string& name) {
    const fs::path json = work_ / (name + ".json");
    const std::string timeout = std::to_string(static_cast<int>(o_.run_timeout_s));
    std::vector<std::string> args{poise_, "run", file.string(), "-q", "-o", json.string(),
                                  "--log-dir", (work_ / (name + ".logs")).string(), "--timeout",
                                  timeout};
    if (o_.ground_truth_state) args.push_back("--ground-truth-state");
    // The launcher's child process: logs in NAME.out / NAME.err, its own process group, ended
    // with this process (PR_SET_PDEATHSIG). `poise run --timeout` bounds it.
    launch::Child run(name, args, work_);
    while (!run.poll()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    Outcome out;
    std::ifstream in(json);
    if (!in) {
      out.failed = "error: poise run wrote no result (it " + run.exit_description() + ", see " +
                   run.stdout_path().string() + " and " + run.stderr_path().string() + ")";
      return out;
    }
    const Json r = Json::parse(in, nullptr, false);
    if (r.is_discarded()) {
      out.failed = "error: unreadable result " + json.string();
      return out;
    }
    out.survived = r.value("survived", false);
    out.com_error_max_m = r.value("com_error_max_m", 0.0);
    out.foot_slip_max_m = r.value("foot_slip_max_m", 0.0);
    out.foot_slide_max_m = r.value("foot_slide_max_m", 0.0);
    out.foot_displacement_max_m = r.value("foot_displacement_max_m", 0.0);
    out.foot_tilt_max_deg = r.value("foot_tilt_max_deg", 0.0);
    out.trunk_pitch_max_deg = r.value("trunk_pitch_max_deg", 0.0);
    out.trunk_roll_max_deg = r.value("trunk_roll_max_deg", 0.0);
    out.failed = r.value("failure", std::string());
    return out;
  }

  const Options& o_;
  fs::path work_;
  std::string poise_;
  int count_ = 0;
};

/// The boundary of one swept quantity (a force, a frequency).
struct Boundary {
  double monotone = 0.0;      ///< largest value with every step below it surviving
  double boundary = 0.0;      ///< bisected between the last survival and the first failure
  bool reached_max = false;   ///< survived up to the maximum: the boundary is at least that
  std::vector<double> non_monotone;  ///< values above the first failure that survived
  std::vector<double> failed_below;  ///< (bisection) failures below the boundary found
};

/// Steps up from `step` until the first failure, bisects, probes above. `survives(x)` runs one.
Boundary sweep(double step, double tol, double max, int probes,
               const std::function<bool(double)>& survives) {
  Boundary b;
  double last_ok = 0.0, first_fail = -1.0;
  for (double x = step; x <= max + 1e-9; x += step) {
    if (survives(x)) {
      last_ok = x;
    } else {
      first_fail = x;
      break;
    }
  }
  b.monotone = last_ok;
  if (first_fail < 0.0) {
    b.reached_max = true;
    b.boundary = last_ok;
    return b;
  }
  double lo = last_ok, hi = first_fail;
  while (hi - lo > tol) {
    const double mid = 0.5 * (lo + hi);
    if (survives(mid)) {
      lo = mid;
    } else {
      hi = mid;
      b.failed_below.push_back(mid);
    }
  }
  b.boundary = lo;
  for (int k = 1; k <= probes; ++k) {
    const double x = first_fail + k * step;
    if (x > max + 1e-9) break;
    if (survives(x)) b.non_monotone.push_back(x);
  }
  return b;
}

/// Runs every force of `forces` (ascending, each once), no search: monotone = the largest force
/// with every smaller one surviving, boundary = the largest that survived, non-monotone =
/// survivals above the first failure.
Boundary grid(const std::vector<double>& forces, const std::function<bool(double)>& survives) {
  Boundary b;
  bool failed = false;
  for (const double x : forces) {
    const bool ok = survives(x);
    if (ok && !failed) b.monotone = x;
    if (ok) b.boundary = x;
    if (ok && failed) b.non_monotone.push_back(x);
    failed = failed || !ok;
  }
  b.reached_max = !failed;
  return b;
}

std::string fmt(double v, int prec = 1) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", prec, v);
  return buf;
}

/// One letter for a run's verdict in the grid table: e, f, s, t, c (failure_kind), x other;
/// S is a survival.
char failure_letter(const std::string& failed) {
  const std::string k = failure_kind(failed);
  return k == "slow recovery" ? 'c' : k == "other" ? 'x' : k[0];
}

std::string list(const std::vector<double>& v, int prec = 0) {
  std::string s;
  for (double x : v) s += (s.empty() ? "" : ", ") + fmt(x, prec);
  return s.empty() ? "-" : s;
}

YAML::Node load_base(const std::string& path) {
  YAML::Node n;
  try {
    n = YAML::LoadFile(path);
  } catch (const std::exception& e) {
    throw std::runtime_error("base scenario " + path + ": " + e.what());
  }
  // Validate it once as a whole (clear errors before hundreds of runs).
  (void)scenario::load_scenario(path);
  absolutise_paths(n, fs::absolute(path).parent_path());
  return n;
}

YAML::Node first_push(YAML::Node& root, const std::string& base) {
  YAML::Node pushes = root["disturbances"]["pushes"];
  if (!pushes || !pushes.IsSequence() || pushes.size() == 0)
    throw std::runtime_error("base scenario " + base +
                             " has no push to vary (disturbances.pushes[0] is needed)");
  return pushes[0];
}

}  // namespace

int envelope_main(int argc, char** argv) {
  // The random study and the merge of its shards have options of their own (random_study.cpp).
  if (argc > 1 && std::string(argv[1]) == "random") return random_main(argc - 1, argv + 1);
  if (argc > 1 && std::string(argv[1]) == "merge") return merge_main(argc - 1, argv + 1);
  Options o;
  o.double_base = source_file("deploy/scenarios/forward_push_double_support.yaml");
  o.single_base = source_file("deploy/scenarios/lateral_push_single_support.yaml");
  o.platform_bases = {source_file("deploy/scenarios/platforms_in_phase.yaml"),
                      source_file("deploy/scenarios/platforms_out_of_phase.yaml"),
                      source_file("deploy/scenarios/platforms_out_of_phase_20cm.yaml")};
  CLI::App app{
      "Balance envelope: push forces survived in N directions (double and single support), the "
      "paper's Fig. 11 (longest push survived per force) and the highest platform frequency, by "
      "running scenarios (deploy/envelope/README.md)."};
  app.add_option("study", o.what,
                 "all, pushes, fig11 or platforms; `random` (pushes drawn at random) and "
                 "`merge` (its shards) take options of their own: poise envelope random --help")
      ->check(CLI::IsMember({"all", "pushes", "fig11", "platforms"}))
      ->capture_default_str();
  app.add_option("--mode", o.mode,
                 "in-process (one process, fast) or lockstep (each run a distributed `poise "
                 "run` over loopback DDS)")
      ->check(CLI::IsMember({"in-process", "lockstep"}))
      ->capture_default_str();
  app.add_option("--double", o.double_base, "base scenario of the double-support pushes and Fig. 11")
      ->check(CLI::ExistingFile);
  app.add_option("--single", o.single_base, "base scenario of the single-support pushes")
      ->check(CLI::ExistingFile);
  app.add_option("--platforms", o.platform_bases, "base scenarios of the frequency sweep")
      ->check(CLI::ExistingFile);
  app.add_option("--directions", o.directions, "push directions in double support (0 = forward)")
      ->check(CLI::Range(1, 72))
      ->capture_default_str();
  app.add_option("--single-directions", o.single_directions, "push directions in single support")
      ->check(CLI::Range(1, 72))
      ->capture_default_str();
  app.add_option("--supports", o.supports, "double, single or double,single")
      ->check(CLI::IsMember({"double", "single", "double,single", "single,double"}))
      ->capture_default_str();
  app.add_option("--push-duration", o.push_duration, "push duration of the force sweep [s]")
      ->check(CLI::Range(0.001, 10.0))
      ->capture_default_str();
  app.add_option("--force-step", o.force_step, "force step of the upward scan [N]")
      ->check(CLI::Range(0.1, 1e4))
      ->capture_default_str();
  app.add_option("--force-tol", o.force_tol, "bisection tolerance [N]")
      ->check(CLI::Range(0.01, 1e4))
      ->capture_default_str();
  app.add_option("--force-max", o.force_max, "largest force tried [N]")
      ->check(CLI::Range(1.0, 1e5))
      ->capture_default_str();
  app.add_option("--probes", o.probes,
                 "steps above the first failure tried for non-monotone survival")
      ->check(CLI::Range(0, 20))
      ->capture_default_str();
  app.add_option("--jitter-deg", o.jitter_deg,
                 "pushes: run each force also at the direction -+ this angle and count it "
                 "survived only if all three runs survive (the verdict near a boundary can flip "
                 "with a change far smaller than any physical uncertainty: deploy/envelope/"
                 "README.md); 0: one run per force")
      ->check(CLI::Range(0.0, 45.0))
      ->capture_default_str();
  app.add_option("--grid-forces", o.grid_forces,
                 "pushes: run exactly these forces in every direction (with --jitter-deg, each "
                 "at the direction and -+ it) instead of the scan and bisection, and tabulate "
                 "every verdict: a fixed grid, for comparing two builds or configurations run "
                 "for run [N]")
      ->check(CLI::Range(0.001, 1e5))
      ->delimiter(',');
  app.add_option("--fig11-forces", o.fig11_forces, "forces of Fig. 11 [N]")
      ->check(CLI::Range(1.0, 1e5));
  app.add_option("--duration-max", o.duration_max, "longest push tried for Fig. 11 [s]")
      ->check(CLI::Range(0.01, 30.0))
      ->capture_default_str();
  app.add_option("--duration-tol", o.duration_tol, "Fig. 11 bisection tolerance [s]")
      ->check(CLI::Range(0.001, 1.0))
      ->capture_default_str();
  app.add_option("--freq-step", o.freq_step, "frequency step of the platform scan [Hz]")
      ->check(CLI::Range(0.001, 10.0))
      ->capture_default_str();
  app.add_option("--freq-tol", o.freq_tol, "frequency bisection tolerance [Hz]")
      ->check(CLI::Range(0.0001, 10.0))
      ->capture_default_str();
  app.add_option("--freq-max", o.freq_max, "highest frequency tried [Hz]")
      ->check(CLI::Range(0.001, 50.0))
      ->capture_default_str();
  app.add_option("--periods", o.periods,
                 "full support periods each platform run lasts after the ramp")
      ->check(CLI::Range(0.5, 100.0))
      ->capture_default_str();
  app.add_option("--priority", o.priority,
                 "contact optimiser priority for every run (default: the base scenario's "
                 "controller section, else lexicographic)")
      ->check(CLI::IsMember({"lexicographic", "weighted"}));
  app.add_option("--controller-config", o.controller_config,
                 "controller YAML for every run (keys of "
                 "controller/momentum/config/balance_controller.yaml, e.g. "
                 "controller/momentum/config/paper.yaml); replaces the base scenarios' "
                 "controller: sections; --priority still applies (default: those sections)")
      ->check(CLI::ExistingFile);
  app.add_option("--output-dir,-o", o.output_dir, "where the CSV, the summary and the plots go")
      ->capture_default_str();
  app.add_option("--run-timeout", o.run_timeout_s, "lockstep: wall-clock bound of one run [s]")
      ->check(CLI::Range(10.0, 36000.0))
      ->capture_default_str();
  app.add_option("--gnuplot", o.gnuplot, "gnuplot executable (default: gnuplot on PATH)");
  app.add_flag("--ground-truth-state", o.ground_truth_state,
               "the controller gets the simulator's ground truth instead of the estimator's state "
               "(separates the controller's limits from the estimator's)");
  app.add_flag("-q,--quiet", o.quiet, "no progress lines");
  POISE_CLI_PARSE(app, argc, argv);
  // The grid's forces ascending, each once (a force given twice would be run twice and its
  // runs counted twice).
  std::sort(o.grid_forces.begin(), o.grid_forces.end());
  o.grid_forces.erase(std::unique(o.grid_forces.begin(), o.grid_forces.end()),
                      o.grid_forces.end());

  const auto t0 = std::chrono::steady_clock::now();
  try {
    if (!o.controller_config.empty()) {
      // Refused before the first run, naming the key (poise::controller's own parser).
      (void)controller::load_controller_config(o.controller_config);
      o.controller_node = YAML::LoadFile(o.controller_config);
      if (o.controller_node && !o.controller_node.IsNull() && !o.controller_node.IsMap())
        throw std::runtime_error("--controller-config " + o.controller_config +
                                 ": not a YAML mapping of controller keys");
    }
    const fs::path out_dir = o.output_dir;
    const fs::path work = out_dir / "runs";
    fs::create_directories(work);
    Runner runner(o, fs::absolute(work));
    std::vector<Row> rows;
    auto progress = [&](const Row& r) {
      rows.push_back(r);
      if (o.quiet) return;
      const double el =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::fprintf(stderr, "[%4d, %6.0f s] %-9s %-6s dir %5.1f deg  F %6.1f N  T %.3f s  f %.3f Hz: %s%s%s\n",
                   runner.count(), el, r.study.c_str(), r.support.c_str(), r.direction_deg,
                   r.force_n, r.duration_s, r.frequency_hz, r.o.survived ? "survived" : "FAILED",
                   r.o.failed.empty() ? "" : " on ", r.o.failed.c_str());
    };
    const bool all = o.what == "all";

    // ---- pushes
    struct DirResult {
      std::string support;
      double direction_deg;
      Boundary b;
      /// The smallest force that failed (just above the boundary) and how its runs failed.
      std::string first_failure;
      /// Per force run: one letter per run (failure_letter; S survived), in run order.
      std::map<double, std::string> cells;
    };
    std::vector<DirResult> dirs;
    int jitter_split = 0;  // --jitter-deg: forces whose three runs did not agree
    if (all || o.what == "pushes") {
      for (const std::string support : {"double", "single"}) {
        if (o.supports.find(support) == std::string::npos) continue;
        const std::string base_path = support == "double" ? o.double_base : o.single_base;
        const YAML::Node base = load_base(base_path);
        const int n = support == "double" ? o.directions : o.single_directions;
        for (int k = 0; k < n; ++k) {
          const double deg = 360.0 * k / n;
          std::map<double, std::string> failed_at;  // force -> kinds of its failed runs
          std::map<double, std::string> cells;      // force -> one letter per run (grid table)
          auto survives_at = [&](double force, double angle_deg) {
            YAML::Node sc = YAML::Clone(base);
            YAML::Node push = first_push(sc, base_path);
            const double a = angle_deg * kPi / 180.0;
            push["force"] = std::vector<double>{force * std::cos(a), force * std::sin(a), 0.0};
            push["duration"] = o.push_duration;
            char name[96];
            std::snprintf(name, sizeof(name), "push_%s_%05.1fdeg_%06.1fN", support.c_str(),
                          angle_deg, force);
            Row r{"push", support, angle_deg, force, o.push_duration, 0.0, runner.run(sc, name)};
            progress(r);
            if (!r.o.survived) {
              std::string& k = failed_at[force];
              const std::string kind = failure_kind(r.o.failed);
              if (k.find(kind) == std::string::npos) k += (k.empty() ? "" : ", ") + kind;
            }
            cells[force] += r.o.survived ? 'S' : failure_letter(r.o.failed);
            return r.o.survived;
          };
          auto survives = [&](double force) {
            if (!(o.jitter_deg > 0.0)) return survives_at(force, deg);
            int n_survived = 0;
            for (const double j : {0.0, -o.jitter_deg, o.jitter_deg})
              n_survived += survives_at(force, deg + j) ? 1 : 0;
            if (n_survived != 0 && n_survived != 3) ++jitter_split;
            return n_survived == 3;
          };
          const Boundary b = o.grid_forces.empty()
                                 ? sweep(o.force_step, o.force_tol, o.force_max, o.probes, survives)
                                 : grid(o.grid_forces, survives);
          std::string first;
          if (!failed_at.empty())
            first = fmt(failed_at.begin()->first, 1) + " N: " + failed_at.begin()->second;
          dirs.push_back({support, deg, b, first, cells});
        }
      }
    }

    // ---- Fig. 11
    struct Fig11Point {
      double force, duration;
      bool reached_max;
    };
    std::vector<Fig11Point> fig11;
    if (all || o.what == "fig11") {
      const YAML::Node base = load_base(o.double_base);
      for (double force : o.fig11_forces) {
        double start = 1.0, base_duration = 4.0;
        {
          YAML::Node sc = YAML::Clone(base);
          start = first_push(sc, o.double_base)["start"].as<double>();
          base_duration = sc["duration"].as<double>();
        }
        auto survives = [&](double d) {
          YAML::Node sc = YAML::Clone(base);
          YAML::Node push = first_push(sc, o.double_base);
          push["force"] = std::vector<double>{force, 0.0, 0.0};
          push["duration"] = d;
          sc["duration"] = std::max(base_duration, start + d + 3.0);
          char name[96];
          std::snprintf(name, sizeof(name), "fig11_%06.1fN_%.4fs", force, d);
          Row r{"fig11", "double", 0.0, force, d, 0.0, runner.run(sc, name)};
          progress(r);
          return r.o.survived;
        };
        // Durations bisected in [0, duration_max] (a push of ~0 s is survived).
        double lo = 0.0, hi = o.duration_max;
        bool reached = false;
        if (survives(hi)) {
          lo = hi;
          reached = true;
        } else {
          while (hi - lo > o.duration_tol) {
            const double mid = 0.5 * (lo + hi);
            (survives(mid) ? lo : hi) = mid;
          }
        }
        fig11.push_back({force, lo, reached});
      }
    }

    // ---- platform frequency
    struct FreqResult {
      std::string scenario;
      double amplitude;
      Boundary b;
    };
    std::vector<FreqResult> freqs;
    if (all || o.what == "platforms") {
      for (const std::string& path : o.platform_bases) {
        const YAML::Node base = load_base(path);
        const std::string stem = fs::path(path).stem().string();
        double amplitude = 0.0, motion_end = 0.0;
        {
          const YAML::Node ps = base["world"]["platforms"];
          if (!ps || !ps.IsSequence() || ps.size() == 0)
            throw std::runtime_error("base scenario " + path + " has no world.platforms");
          for (const auto& p : ps) {
            if (p["translation"] && p["translation"]["amplitude"])
              amplitude = std::max(amplitude, std::abs(p["translation"]["amplitude"].as<double>()));
            const double ms = p["motion_start"] ? p["motion_start"].as<double>() : 0.0;
            const double mr = p["motion_ramp"] ? p["motion_ramp"].as<double>() : 0.0;
            motion_end = std::max(motion_end, ms + mr);
          }
        }
        auto survives = [&](double f) {
          YAML::Node sc = YAML::Clone(base);
          for (auto p : sc["world"]["platforms"])
            for (const char* m : {"translation", "rotation"})
              if (p[m] && p[m]["frequency"] && p[m]["frequency"].as<double>() > 0.0)
                p[m]["frequency"] = f;
          sc["duration"] = motion_end + o.periods / f;
          char name[96];
          std::snprintf(name, sizeof(name), "platforms_%s_%.4fHz", stem.c_str(), f);
          Row r{"platforms", stem, 0.0, 0.0, sc["duration"].as<double>(), f, runner.run(sc, name)};
          progress(r);
          return r.o.survived;
        };
        freqs.push_back(
            {stem, amplitude, sweep(o.freq_step, o.freq_tol, o.freq_max, o.probes, survives)});
      }
    }

    // ---- outputs
    {
      std::ofstream f(out_dir / "runs.csv");
      f << "study,support,direction_deg,force_N,duration_s,frequency_Hz,survived,com_error_max_m,"
           "foot_slip_max_m,foot_slide_max_m,foot_displacement_max_m,foot_tilt_max_deg,"
           "trunk_pitch_max_deg,trunk_roll_max_deg,failed\n";
      for (const Row& r : rows)
        f << r.study << ',' << r.support << ',' << r.direction_deg << ',' << r.force_n << ','
          << r.duration_s << ',' << r.frequency_hz << ',' << (r.o.survived ? 1 : 0) << ','
          << r.o.com_error_max_m << ',' << r.o.foot_slip_max_m << ',' << r.o.foot_slide_max_m
          << ',' << r.o.foot_displacement_max_m << ',' << r.o.foot_tilt_max_deg
          << ',' << r.o.trunk_pitch_max_deg
          << ',' << r.o.trunk_roll_max_deg << ',' << csv_field(r.o.failed) << '\n';
    }
    {
      std::ofstream f(out_dir / "envelope.csv");
      f << "study,support_or_scenario,direction_deg_or_force_N,monotone,boundary,reached_max,"
           "non_monotone,first_failure\n";
      for (const auto& d : dirs)
        f << "push," << d.support << ',' << d.direction_deg << ',' << d.b.monotone << ','
          << d.b.boundary << ',' << (d.b.reached_max ? 1 : 0) << ','
          << csv_field(list(d.b.non_monotone, 1)) << ',' << csv_field(d.first_failure) << '\n';
      for (const auto& p : fig11)
        f << "fig11,double," << p.force << ',' << p.duration << ',' << p.duration << ','
          << (p.reached_max ? 1 : 0) << ",\"-\",\"\"\n";
      for (const auto& q : freqs)
        f << "platforms," << q.scenario << ",0," << q.b.monotone << ',' << q.b.boundary << ','
          << (q.b.reached_max ? 1 : 0) << ',' << csv_field(list(q.b.non_monotone, 3)) << ",\"\"\n";
    }
    // Plot data and gnuplot script.
    std::vector<std::string> pictures;
    std::string plot_note;
    if (!dirs.empty() || !fig11.empty()) {
      const std::string gp = plot::find_gnuplot(o.gnuplot);
      if (gp.empty()) {
        plot_note = "gnuplot not found (Debian: apt-get install gnuplot-nox): no pictures drawn";
      } else {
        const fs::path data = fs::absolute(work / "plot");
        fs::create_directories(data);
        for (const std::string support : {"double", "single"}) {
          std::ofstream f(data / (support + ".dat"));
          const DirResult* first = nullptr;
          for (const auto& d : dirs)
            if (d.support == support) {
              if (!first) first = &d;
              f << d.direction_deg << ' ' << d.b.boundary << ' ' << d.b.monotone << '\n';
            }
          if (first)  // close the polygon
            f << first->direction_deg + 360.0 << ' ' << first->b.boundary << ' '
              << first->b.monotone << '\n';
        }
        {
          std::ofstream f(data / "fig11.dat");
          for (const auto& p : fig11) f << p.force << ' ' << p.duration << ' ' << p.force * p.duration << '\n';
        }
        for (const std::string term : {"png", "svg"}) {
          const fs::path script = data / ("envelope_" + term + ".gp");
          std::ofstream s(script);
          const std::string termline =
              term == "png" ? "set terminal pngcairo noenhanced size 900,800 font 'sans,11' background 'white'\n"
                            : "set terminal svg noenhanced size 900,800 dynamic font 'sans,11' background 'white'\n";
          if (!dirs.empty()) {
            const fs::path pic = fs::absolute(out_dir / ("push_envelope." + term));
            s << termline << "set output '" << pic.string() << "'\n"
              << "set polar\nset angles degrees\nset size square\nset grid polar 45\n"
              << "unset border\nunset xtics\nunset ytics\nset key outside bottom center horizontal\n"
              << "set title 'Largest push survived (" << fmt(o.push_duration, 2)
              << " s) by direction, N; 0 deg = forward, 90 deg = left'\n"
              << "set rtics axis scale 0.5 nomirror\n"
              << "plot '" << (data / "double.dat").string()
              << "' using 1:2 with linespoints lw 2 pt 7 title 'double support: boundary', '"
              << (data / "double.dat").string()
              << "' using 1:3 with lines dt 2 title 'double: monotone up to', '"
              << (data / "single.dat").string()
              << "' using 1:2 with linespoints lw 2 pt 5 title 'single support: boundary'\n"
              << "unset polar\nunset output\n";
            pictures.push_back(pic.string());
          }
          if (!fig11.empty()) {
            const fs::path pic = fs::absolute(out_dir / ("fig11." + term));
            s << termline << "set output '" << pic.string() << "'\n"
              << "reset\nset multiplot layout 1,2 title 'Forward push, double support (paper Fig. "
                 "11)'\nset grid\nset xlabel 'force [N]'\nset ylabel 'maximum impulse [N s]'\n"
              << "plot '" << (data / "fig11.dat").string()
              << "' using 1:3 with linespoints lw 2 pt 7 notitle\n"
              << "set ylabel 'maximum duration [s]'\nplot '" << (data / "fig11.dat").string()
              << "' using 1:2 with linespoints lw 2 pt 7 notitle\nunset multiplot\nunset output\n";
            pictures.push_back(pic.string());
          }
          s.close();
          const int rc = plot::run_gnuplot(gp, script.string(), (data / ("gnuplot_" + term + ".log")).string());
          if (rc != 0)
            plot_note += "gnuplot failed (exit " + std::to_string(rc) + ", " +
                         (data / ("gnuplot_" + term + ".log")).string() + "); ";
        }
      }
    }
    // Summary.
    {
      std::ofstream md(out_dir / "envelope.md");
      md << "# Balance envelope\n\nMeasured by `poise envelope` (" << o.mode << ", "
         << runner.count() << " runs, "
         << fmt(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0)
         << " s). Every run: runs.csv. Priority: "
         << (o.priority.empty() ? "the base scenarios' (default lexicographic)" : o.priority)
         << ". Controller: "
         << (o.controller_config.empty() ? std::string("the base scenarios' sections")
                                         : "`" + o.controller_config + "`")
         << ". State: " << (o.ground_truth_state ? "ground truth (debug)" : "the estimator's")
         << ".\n\n";
      if (!dirs.empty()) {
        md << "## Pushes of " << fmt(o.push_duration, 2)
           << " s by direction\n\n"
           << (o.grid_forces.empty()
                   ? "Scan in steps of " + fmt(o.force_step, 1) + " N, bisection to " +
                         fmt(o.force_tol, 1) + " N, " + std::to_string(o.probes) +
                         " probes above the first failure"
                   : "A grid: every direction at " + list(o.grid_forces, 1) +
                         " N, no search")
           << (o.jitter_deg > 0.0
                   ? ", each force run at the direction and at -+" + fmt(o.jitter_deg, 2) +
                         " deg, survived only if all three survived (the three disagreed at " +
                         std::to_string(jitter_split) + " forces)"
                   : std::string())
           << ". *Monotone*: every step up to it survived. "
           << (o.grid_forces.empty() ? "*Boundary*: the bisected edge. "
                                     : "*Boundary*: the largest force survived. ")
           << "*Non-monotone*: forces above the first failure "
              "that survived. *Failure above it*: the smallest force that failed and how, the "
              "most severe per run (fall: CoM error over its maximum, the base too low or a "
              "non-foot contact; slip: a foot's sole centre moved too far; slow recovery: the CoM "
              "not back in time).\n\n"
           << "| support | direction (deg, 0 = forward, 90 = left) | monotone (N) | boundary (N) "
              "| non-monotone (N) | failure above it | paper |\n|---|---|---|---|---|---|---|\n";
        for (const auto& d : dirs) {
          std::string paper = "-";
          if (d.support == "double" && std::abs(d.direction_deg) < 1e-9) paper = "120 N survived (Fig. 8)";
          if (d.support == "single" && std::abs(d.direction_deg - 90.0) < 1e-9)
            paper = "100 N survived (Fig. 9, leftward)";
          md << "| " << d.support << " | " << fmt(d.direction_deg, 1) << " | "
             << (d.b.reached_max ? ">= " : "") << fmt(d.b.monotone, 0) << " | "
             << (d.b.reached_max ? ">= " : "") << fmt(d.b.boundary, 1) << " | "
             << list(d.b.non_monotone, 0) << " | "
             << (d.first_failure.empty() ? "-" : d.first_failure) << " | " << paper << " |\n";
        }
        md << "\n";
        if (!o.grid_forces.empty()) {
          const std::vector<double>& forces = o.grid_forces;
          int runs = 0, survived = 0;
          md << "Every run (" << (o.jitter_deg > 0.0 ? "at -" + fmt(o.jitter_deg, 2) +
                                                           " deg, the direction, +" +
                                                           fmt(o.jitter_deg, 2) + " deg; "
                                                     : std::string())
             << "S survived, f fell, s slipped, t tilted, c slow recovery, e error, x another "
                "criterion):\n\n"
             << "| support | direction (deg) |";
          for (double f : forces) md << ' ' << fmt(f, 1) << " N |";
          md << "\n|---|---|";
          for (std::size_t i = 0; i < forces.size(); ++i) md << "---|";
          md << "\n";
          for (const auto& d : dirs) {
            md << "| " << d.support << " | " << fmt(d.direction_deg, 1) << " |";
            for (double f : forces) {
              const auto it = d.cells.find(f);
              if (it == d.cells.end()) {
                md << " - |";
                continue;
              }
              // Recorded in run order (survives: 0, -J, +J), shown -J, 0, +J.
              const std::string& c = it->second;
              md << ' ' << (c.size() == 3 ? std::string{c[1], c[0], c[2]} : c) << " |";
              runs += static_cast<int>(c.size());
              survived += static_cast<int>(std::count(c.begin(), c.end(), 'S'));
            }
            md << "\n";
          }
          md << "\n" << survived << " of " << runs << " runs survived.\n\n";
        }
      }
      if (!fig11.empty()) {
        md << "## Fig. 11: forward push, double support\n\nLongest push survived per force "
              "(bisection to "
           << fmt(o.duration_tol, 3)
           << " s) and its impulse. Paper: the maximum impulse drops quickly and is roughly "
              "constant above 80 N; the maximum duration drops even faster.\n\n"
           << "| force (N) | max duration (s) | max impulse (N s) |\n|---|---|---|\n";
        for (const auto& p : fig11)
          md << "| " << fmt(p.force, 0) << " | " << (p.reached_max ? ">= " : "")
             << fmt(p.duration, 3) << " | " << (p.reached_max ? ">= " : "")
             << fmt(p.force * p.duration, 1) << " |\n";
        md << "\n";
      }
      if (!freqs.empty()) {
        md << "## Moving supports: highest frequency\n\nEach run lasts the ramp plus "
           << fmt(o.periods, 1) << " full periods. Paper (Sec. 4.2): in phase, 1 m amplitude: "
              "~0.12 Hz; out of phase, 0.4 m: ~1 Hz.\n\n"
           << "| scenario | amplitude (m) | monotone (Hz) | boundary (Hz) | non-monotone (Hz) "
              "|\n|---|---|---|---|---|\n";
        for (const auto& q : freqs)
          md << "| " << q.scenario << " | " << fmt(q.amplitude, 2) << " | "
             << (q.b.reached_max ? ">= " : "") << fmt(q.b.monotone, 3) << " | "
             << (q.b.reached_max ? ">= " : "") << fmt(q.b.boundary, 3) << " | "
             << list(q.b.non_monotone, 3) << " |\n";
        md << "\n";
      }
      if (!pictures.empty()) {
        md << "Pictures:";
        for (const auto& p : pictures) md << " `" << fs::path(p).filename().string() << "`";
        md << "\n";
      }
      if (!plot_note.empty()) md << "\nNote: " << plot_note << "\n";
    }
    std::ifstream summary(out_dir / "envelope.md");
    std::cout << summary.rdbuf();
    std::printf("poise envelope: %d runs; %s, %s, %s%s\n", runner.count(),
                (out_dir / "envelope.md").c_str(), (out_dir / "envelope.csv").c_str(),
                (out_dir / "runs.csv").c_str(), pictures.empty() ? "" : ", pictures");
    if (!plot_note.empty()) {
      std::fprintf(stderr, "poise envelope: %s\n", plot_note.c_str());
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise envelope: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::envelope
