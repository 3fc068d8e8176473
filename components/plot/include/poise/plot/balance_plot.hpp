#pragma once
// The balance sheet of a push run (`poise plot FILE`): the panels of the paper's Figs. 8 and 9
// (Lee & Goswami, Sec. 4.1) drawn by gnuplot from the CSV export of the recording.
//
// Panels, all against robot time (header.stamp_ns of each sample, in seconds):
//   (a) CoM x, y and (b) CoM z      poise/state com_W (estimate), poise/ground_truth com_W (truth)
//   (c) linear momentum rate        poise/contact_problem l_dot_desired_W vs
//                                   poise/contact_solution l_dot_admissible_W
//   (d) angular momentum rate       k_dot_desired_W vs k_dot_admissible_W
//   (e) vertical GRF per foot       contact_solution feet[i].wrench_at_ankle_W.force[2]
//                                   (admissible), ground_truth feet[i].wrench_W.force[2] (truth)
//   (f), (g) CoP x, y in the foot frame   contact_solution feet[i].cop_F, with the borders of the
//                                   safe region: robot_description feet[i] x_min/x_max/y_min/y_max
//                                   inset by safety_margin (contact_problem's feet as fallback)
//   (h) what the sheet was drawn from: topics missing, push intervals and their source.
// Every push (poise/disturbance of kind PUSH, or --push) is a shaded band on every panel: its
// start_time_s is robot time; a push sent "at once" (start < 0) starts at the robot time of the
// state sample logged nearest to the disturbance message.
//
// Output: DIR/<stem>_balance.png and DIR/<stem>_balance.svg. A missing topic leaves its panels
// empty with a note, never fails the sheet.

#include <cstdio>
#include <string>
#include <vector>

namespace poise::plot {

/// A push interval in robot time [s].
struct PushInterval {
  double start_s = 0;
  double duration_s = 0;
  std::string source;  ///< "poise/disturbance", "--push"
};

struct PlotOptions {
  std::string file;                        ///< MCAP recording
  std::string output_dir;                  ///< "" = the recording's directory
  std::string title;                       ///< "" = the file name
  std::string gnuplot;                     ///< gnuplot executable ("" = `gnuplot` found on PATH)
  std::vector<PushInterval> extra_pushes;  ///< given on the command line
  bool keep_data = false;   ///< keep the CSV and the gnuplot script in DIR/<stem>_plot_data/
  std::FILE* log = stderr;  ///< notes and problems
};

struct PlotResult {
  int exit_code = 0;  ///< as cli.hpp says
  std::string png, svg;
  std::vector<std::string> missing_topics;
  std::vector<PushInterval> pushes;
  std::string error;  ///< "" or why no sheet was drawn
};

/// The gnuplot executable: `requested` if it names an executable file, or else `gnuplot` on PATH.
/// "" when there is none.
std::string find_gnuplot(const std::string& requested);

/// Runs `gnuplot script` as a child process, its stdout and stderr to `log_path`. Returns the
/// exit status (127: could not be started; 128 + N: killed by signal N).
int run_gnuplot(const std::string& gnuplot, const std::string& script, const std::string& log_path);

/// Draws the sheet as the top of this file says.
PlotResult plot_balance(const PlotOptions& options);

}  // namespace poise::plot
