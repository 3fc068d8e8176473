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

#include "envelope_study.hpp"
#include "poise/cli/parse.hpp"
#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/inprocess/in_process_loop.hpp"
#include "poise/launch/child.hpp"
#include "poise/scenario/scenario.hpp"
#include "random_study.hpp"

namespace poise::envelope {
namespace study {

namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

constexpr double kPi = 3.14159265358979323846;

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
        const scenario::Scenario sc =
            scenario::parse_scenario(e.c_str(), work_, "scenario " + name);
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
        for (const auto& f : r.failed)
          out.failed += (out.failed.empty() ? "" : "; ") + f;
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
    std::vector<std::string> args{
        poise_,      "run",         file.string(), "-q",
        "-o",        json.string(), "--log-dir",   (work_ / (name + ".logs")).string(),
        "--timeout", timeout};
    if (o_.ground_truth_state) args.push_back("--ground-truth-state");
    // The launcher's child process: logs in NAME.out / NAME.err, its own process group, ended
    // with this process (PR_SET_PDEATHSIG). `poise run --timeout` bounds it.
    launch::Child run(name, args, work_);
    while (!run.poll())
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
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

/// One letter for a run's verdict in the grid table: e, f, s, t, c (failure_kind), x other;
/// S is a survival.
char failure_letter(const std::string& failed) {
  const std::string k = failure_kind(failed);
  return k == "slow recovery" ? 'c' : k == "other" ? 'x' : k[0];
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

/// One `poise envelope`: its options, its runs and the studies' results.
struct Envelope : Results {
  Envelope(const Options& opts, std::chrono::steady_clock::time_point start, const fs::path& work)
      : o(opts), t0(start), runner(o, fs::absolute(work)) {}

  const Options& o;
  std::chrono::steady_clock::time_point t0;
  Runner runner;

  /// Keeps a finished run and says it (unless --quiet).
  void progress(const Row& r) {
    rows.push_back(r);
    if (o.quiet) return;
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr,
                 "[%4d, %6.0f s] %-9s %-6s dir %5.1f deg  F %6.1f N  T %.3f s  f %.3f Hz: %s%s%s\n",
                 runner.count(), el, r.study.c_str(), r.support.c_str(), r.direction_deg, r.force_n,
                 r.duration_s, r.frequency_hz, r.o.survived ? "survived" : "FAILED",
                 r.o.failed.empty() ? "" : " on ", r.o.failed.c_str());
  }
};

/// `poise envelope`'s options of the study, the base scenarios and the push scan.
void add_study_options(CLI::App& app, Options& o) {
  app.add_option("study", o.what,
                 "all, pushes, fig11 or platforms; `random` (pushes drawn at random) and "
                 "`merge` (its shards) take options of their own: poise envelope random --help, "
                 "poise envelope merge --help")
      ->check(CLI::IsMember({"all", "pushes", "fig11", "platforms"}))
      ->capture_default_str();
  app.add_option("--mode", o.mode,
                 "in-process (one process, fast) or lockstep (each run a distributed `poise "
                 "run` over loopback DDS)")
      ->check(CLI::IsMember({"in-process", "lockstep"}))
      ->capture_default_str();
  app.add_option("--double", o.double_base,
                 "base scenario of the double-support pushes and Fig. 11")
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
}

/// `poise envelope`'s options of the push grid, Fig. 11 and the platform sweep.
void add_sweep_options(CLI::App& app, Options& o) {
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
}

/// `poise envelope`'s options of every run (controller, state) and of the outputs.
void add_run_options(CLI::App& app, Options& o) {
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
}

/// Parses the studies' command line into `o`. Returns the exit status when the command line
/// ends the verb (0 after --help, 2 for a usage error), else -1.
int parse_options(int argc, char** argv, Options& o) {
  o.double_base = source_file("deploy/scenarios/forward_push_double_support.yaml");
  o.single_base = source_file("deploy/scenarios/lateral_push_single_support.yaml");
  o.platform_bases = {source_file("deploy/scenarios/platforms_in_phase.yaml"),
                      source_file("deploy/scenarios/platforms_out_of_phase.yaml"),
                      source_file("deploy/scenarios/platforms_out_of_phase_20cm.yaml")};
  CLI::App app{
      "Balance envelope: push forces survived in N directions (double and single support), the "
      "paper's Fig. 11 (longest push survived per force) and the highest platform frequency, by "
      "running scenarios (deploy/envelope/README.md)."};
  add_study_options(app, o);
  add_sweep_options(app, o);
  add_run_options(app, o);
  POISE_CLI_PARSE(app, argc, argv);
  // The grid's forces ascending, each once (a force given twice would be run twice and its
  // runs counted twice).
  std::sort(o.grid_forces.begin(), o.grid_forces.end());
  o.grid_forces.erase(std::unique(o.grid_forces.begin(), o.grid_forces.end()), o.grid_forces.end());
  return -1;
}

/// --controller-config: refused before the first run, naming the key (poise::controller's own
/// parser); kept as a node for every run's scenario.
void read_controller_config(Options& o) {
  if (o.controller_config.empty()) return;
  (void)controller::load_controller_config(o.controller_config);
  o.controller_node = YAML::LoadFile(o.controller_config);
  if (o.controller_node && !o.controller_node.IsNull() && !o.controller_node.IsMap())
    throw std::runtime_error("--controller-config " + o.controller_config +
                             ": not a YAML mapping of controller keys");
}

/// Pushes: the boundary of one direction `deg` in one support (a scan and a bisection, or the
/// grid's forces).
DirResult push_direction(Envelope& e, const std::string& support, const std::string& base_path,
                         const YAML::Node& base, double deg) {
  const Options& o = e.o;
  std::map<double, std::string> failed_at;  // force -> kinds of its failed runs
  std::map<double, std::string> cells;      // force -> one letter per run (grid table)
  auto survives_at = [&](double force, double angle_deg) {
    YAML::Node sc = YAML::Clone(base);
    YAML::Node push = first_push(sc, base_path);
    const double a = angle_deg * kPi / 180.0;
    push["force"] = std::vector<double>{force * std::cos(a), force * std::sin(a), 0.0};
    push["duration"] = o.push_duration;
    char name[96];
    std::snprintf(name, sizeof(name), "push_%s_%05.1fdeg_%06.1fN", support.c_str(), angle_deg,
                  force);
    Row r{"push", support, angle_deg, force, o.push_duration, 0.0, e.runner.run(sc, name)};
    e.progress(r);
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
    if (n_survived != 0 && n_survived != 3) ++e.jitter_split;
    return n_survived == 3;
  };
  const Boundary b = o.grid_forces.empty()
                         ? sweep(o.force_step, o.force_tol, o.force_max, o.probes, survives)
                         : grid(o.grid_forces, survives);
  std::string first;
  if (!failed_at.empty())
    first = fmt(failed_at.begin()->first, 1) + " N: " + failed_at.begin()->second;
  return {support, deg, b, first, cells};
}

/// Pushes: every direction of each support asked for.
void run_pushes(Envelope& e) {
  for (const std::string support : {"double", "single"}) {
    if (e.o.supports.find(support) == std::string::npos) continue;
    const std::string base_path = support == "double" ? e.o.double_base : e.o.single_base;
    const YAML::Node base = load_base(base_path);
    const int n = support == "double" ? e.o.directions : e.o.single_directions;
    for (int k = 0; k < n; ++k)
      e.dirs.push_back(push_direction(e, support, base_path, base, 360.0 * k / n));
  }
}

/// Fig. 11: the longest push survived at `force`.
Fig11Point fig11_point(Envelope& e, const YAML::Node& base, double force) {
  const Options& o = e.o;
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
    Row r{"fig11", "double", 0.0, force, d, 0.0, e.runner.run(sc, name)};
    e.progress(r);
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
  return {force, lo, reached};
}

void run_fig11(Envelope& e) {
  const YAML::Node base = load_base(e.o.double_base);
  for (double force : e.o.fig11_forces)
    e.fig11.push_back(fig11_point(e, base, force));
}

/// Platforms: the highest frequency survived of the base scenario `path`.
FreqResult platform_sweep(Envelope& e, const std::string& path) {
  const Options& o = e.o;
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
    Row r{"platforms", stem, 0.0, 0.0, sc["duration"].as<double>(), f, e.runner.run(sc, name)};
    e.progress(r);
    return r.o.survived;
  };
  return {stem, amplitude, sweep(o.freq_step, o.freq_tol, o.freq_max, o.probes, survives)};
}

void run_platforms(Envelope& e) {
  for (const std::string& path : e.o.platform_bases)
    e.freqs.push_back(platform_sweep(e, path));
}

/// The studies asked for, their outputs in the output directory and the summary on stdout.
/// Returns the exit status: 0, or 1 when the pictures could not be drawn.
int run_studies(Options& o, std::chrono::steady_clock::time_point t0) {
  read_controller_config(o);
  const fs::path out_dir = o.output_dir;
  const fs::path work = out_dir / "runs";
  fs::create_directories(work);
  Envelope e(o, t0, work);
  const bool all = o.what == "all";
  if (all || o.what == "pushes") run_pushes(e);
  if (all || o.what == "fig11") run_fig11(e);
  if (all || o.what == "platforms") run_platforms(e);
  write_runs_csv(o, e);
  write_envelope_csv(o, e);
  draw_pictures(o, e);
  write_summary(o, e, e.runner.count(), t0);
  std::ifstream summary(out_dir / "envelope.md");
  std::cout << summary.rdbuf();
  std::printf("poise envelope: %d runs; %s, %s, %s%s\n", e.runner.count(),
              (out_dir / "envelope.md").c_str(), (out_dir / "envelope.csv").c_str(),
              (out_dir / "runs.csv").c_str(), e.pictures.empty() ? "" : ", pictures");
  if (!e.plot_note.empty()) {
    std::fprintf(stderr, "poise envelope: %s\n", e.plot_note.c_str());
    return 1;
  }
  return 0;
}

}  // namespace
}  // namespace study

int envelope_main(int argc, char** argv) {
  // The random study and the merge of its shards have options of their own (random_study.cpp).
  if (argc > 1 && std::string(argv[1]) == "random") return random_main(argc - 1, argv + 1);
  if (argc > 1 && std::string(argv[1]) == "merge") return merge_main(argc - 1, argv + 1);
  study::Options o;
  if (const int code = study::parse_options(argc, argv, o); code >= 0) return code;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    return study::run_studies(o, t0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise envelope: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::envelope
