// `poise plot FILE [-o DIR] [--title T] [--push START,DURATION]...`: argument parsing around
// plot_balance().
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "poise/plot/balance_plot.hpp"
#include "poise/plot/cli.hpp"
#include "poise/cli/parse.hpp"

namespace poise::plot {

int plot_main(int argc, char** argv) {
  PlotOptions o;
  std::vector<std::string> pushes;
  CLI::App app{
      "Draw the balance sheet of a push run from an MCAP recording, as the paper's Figs. 8 and 9 "
      "show it (Lee & Goswami, Sec. 4.1): (a, b) CoM position, estimate and ground truth; "
      "(c, d) desired vs admissible linear and angular momentum rate; (e) vertical ground "
      "reaction force per foot; (f, g) admissible CoP in the foot frame with the borders of the "
      "safe region; (h) what the sheet was drawn from. Every push (poise/disturbance messages, "
      "or --push) is a shaded band. Time axis: robot time (header.stamp_ns), seconds.\n"
      "Writes DIR/<stem>_balance.png and DIR/<stem>_balance.svg with gnuplot (Debian package "
      "gnuplot-nox), fed with the CSV of `poise export`. Topics missing from the recording leave "
      "their panels empty, with a note.\n"
      "Exit status: 0 drawn; 1 drawn, but messages did not decode or the file is incomplete; 2 "
      "not drawn (gnuplot missing or failing, not MCAP, no data)."};
  app.name("poise plot");
  app.add_option("file", o.file, "MCAP recording of a run (poise run SCENARIO --record FILE)")
      ->required();
  app.add_option("-o,--output", o.output_dir,
                 "directory for the panels' PNG and SVG files (default: the recording's "
                 "directory)");
  app.add_option("--title", o.title, "sheet title (default: the file name)");
  app.add_option("--push", pushes,
                 "an extra push band START,DURATION in robot time [s], e.g. 1.0,0.1 (pushes of a "
                 "scenario file are applied inside the simulator and are not recorded)");
  app.add_option("--gnuplot", o.gnuplot, "gnuplot executable (default: gnuplot on PATH)");
  app.add_flag("--keep-data", o.keep_data,
               "keep the CSV and the gnuplot script in DIR/<stem>_plot_data/");
  POISE_CLI_PARSE(app, argc, argv);
  for (const auto& p : pushes) {
    PushInterval push;
    push.source = "--push";
    double start = 0, duration = 0;
    char extra = 0;
    if (std::sscanf(p.c_str(), "%lf,%lf%c", &start, &duration, &extra) != 2 || duration < 0) {
      std::fprintf(stderr,
                   "poise plot: --push %s: expected START,DURATION in seconds, e.g. 1.0,0.1\n",
                   p.c_str());
      return 2;
    }
    push.start_s = start;
    push.duration_s = duration;
    o.extra_pushes.push_back(push);
  }
  const PlotResult r = plot_balance(o);
  if (!r.error.empty()) {
    std::fprintf(stderr, "poise plot: %s\n", r.error.c_str());
    return r.exit_code ? r.exit_code : 2;
  }
  std::printf("%s\n%s\n", r.png.c_str(), r.svg.c_str());
  return r.exit_code;
}

}  // namespace poise::plot
