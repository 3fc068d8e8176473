#pragma once
// `poise envelope`'s studies (pushes, fig11, platforms): their options, runs and results, shared
// by envelope_cli.cpp (the command line and the runs) and envelope_report.cpp (runs.csv,
// envelope.csv, the pictures and envelope.md).
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <map>
#include <string>
#include <vector>

namespace poise::envelope::study {

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

/// The boundary of one swept quantity (a force, a frequency).
struct Boundary {
  double monotone = 0.0;             ///< largest value with every step below it surviving
  double boundary = 0.0;             ///< bisected between the last survival and the first failure
  bool reached_max = false;          ///< survived up to the maximum: the boundary is at least that
  std::vector<double> non_monotone;  ///< values above the first failure that survived
  std::vector<double> failed_below;  ///< (bisection) failures below the boundary found
};

/// Pushes: one direction's boundary in one support.
struct DirResult {
  std::string support;
  double direction_deg;
  Boundary b;
  /// The smallest force that failed (just above the boundary) and how its runs failed.
  std::string first_failure;
  /// Per force run: one letter per run (failure_letter; S survived), in run order.
  std::map<double, std::string> cells;
};

/// Fig. 11: the longest push survived at one force.
struct Fig11Point {
  double force, duration;
  bool reached_max;
};

/// Platforms: the highest frequency survived of one platform scenario.
struct FreqResult {
  std::string scenario;
  double amplitude;
  Boundary b;
};

/// What the studies of one `poise envelope` found: every run, the boundaries, and the pictures
/// drawn of them.
struct Results {
  std::vector<Row> rows;
  std::vector<DirResult> dirs;
  int jitter_split = 0;  // --jitter-deg: forces whose three runs did not agree
  std::vector<Fig11Point> fig11;
  std::vector<FreqResult> freqs;
  std::vector<std::string> pictures;  ///< drawn by draw_pictures
  std::string plot_note;              ///< what went wrong drawing them ("" if nothing)
};

/// `v` with `prec` decimals.
std::string fmt(double v, int prec = 1);

/// runs.csv in the output directory: every run.
void write_runs_csv(const Options& o, const Results& res);
/// envelope.csv in the output directory: the boundaries.
void write_envelope_csv(const Options& o, const Results& res);
/// The pictures of the pushes and Fig. 11 (png, svg), drawn with gnuplot from plot data and
/// scripts written in <output directory>/runs/plot: into res.pictures, what went wrong into
/// res.plot_note.
void draw_pictures(const Options& o, Results& res);
/// envelope.md in the output directory: the summary of the studies, `runs` runs since `t0`.
void write_summary(const Options& o, const Results& res, int runs,
                   std::chrono::steady_clock::time_point t0);

}  // namespace poise::envelope::study
