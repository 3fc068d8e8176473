// `poise envelope`'s outputs of the studies (envelope_cli.cpp runs them): runs.csv (every run),
// envelope.csv (the boundaries), the gnuplot pictures and envelope.md (the summary next to the
// paper's values).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <string>
#include <vector>

#include "envelope_study.hpp"
#include "poise/plot/balance_plot.hpp"

namespace poise::envelope::study {

namespace fs = std::filesystem;

std::string fmt(double v, int prec) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", prec, v);
  return buf;
}

namespace {

std::string csv_field(const std::string& s) {
  std::string out = "\"";
  for (char c : s)
    out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string list(const std::vector<double>& v, int prec = 0) {
  std::string s;
  for (double x : v)
    s += (s.empty() ? "" : ", ") + fmt(x, prec);
  return s.empty() ? "-" : s;
}

/// The plots' data in `data`: the push boundaries per support (a closed polygon) and Fig. 11.
void write_plot_data(const Results& res, const fs::path& data) {
  for (const std::string support : {"double", "single"}) {
    std::ofstream f(data / (support + ".dat"));
    const DirResult* first = nullptr;
    for (const auto& d : res.dirs)
      if (d.support == support) {
        if (!first) first = &d;
        f << d.direction_deg << ' ' << d.b.boundary << ' ' << d.b.monotone << '\n';
      }
    if (first)  // close the polygon
      f << first->direction_deg + 360.0 << ' ' << first->b.boundary << ' ' << first->b.monotone
        << '\n';
  }
  std::ofstream f(data / "fig11.dat");
  for (const auto& p : res.fig11)
    f << p.force << ' ' << p.duration << ' ' << p.force * p.duration << '\n';
}

/// The gnuplot script of terminal `term` (png or svg) for the pictures there is data for, which
/// are added to res.pictures.
void write_gnuplot_script(const Options& o, Results& res, const fs::path& data,
                          const std::string& term, const fs::path& script) {
  std::ofstream s(script);
  const std::string termline =
      term == "png"
          ? "set terminal pngcairo noenhanced size 900,800 font 'sans,11' background 'white'\n"
          : "set terminal svg noenhanced size 900,800 dynamic font 'sans,11' background 'white'\n";
  if (!res.dirs.empty()) {
    const fs::path pic = fs::absolute(fs::path(o.output_dir) / ("push_envelope." + term));
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
    res.pictures.push_back(pic.string());
  }
  if (!res.fig11.empty()) {
    const fs::path pic = fs::absolute(fs::path(o.output_dir) / ("fig11." + term));
    s << termline << "set output '" << pic.string() << "'\n"
      << "reset\nset multiplot layout 1,2 title 'Forward push, double support (paper Fig. "
         "11)'\nset grid\nset xlabel 'force [N]'\nset ylabel 'maximum impulse [N s]'\n"
      << "plot '" << (data / "fig11.dat").string()
      << "' using 1:3 with linespoints lw 2 pt 7 notitle\n"
      << "set ylabel 'maximum duration [s]'\nplot '" << (data / "fig11.dat").string()
      << "' using 1:2 with linespoints lw 2 pt 7 notitle\nunset multiplot\nunset output\n";
    res.pictures.push_back(pic.string());
  }
}

/// envelope.md: the pushes' boundaries by direction, next to the paper's values.
void write_push_section(std::ostream& md, const Options& o, const Results& res) {
  md << "## Pushes of " << fmt(o.push_duration, 2) << " s by direction\n\n"
     << (o.grid_forces.empty()
             ? "Scan in steps of " + fmt(o.force_step, 1) + " N, bisection to " +
                   fmt(o.force_tol, 1) + " N, " + std::to_string(o.probes) +
                   " probes above the first failure"
             : "A grid: every direction at " + list(o.grid_forces, 1) + " N, no search")
     << (o.jitter_deg > 0.0
             ? ", each force run at the direction and at -+" + fmt(o.jitter_deg, 2) +
                   " deg, survived only if all three survived (the three disagreed at " +
                   std::to_string(res.jitter_split) + " forces)"
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
  for (const auto& d : res.dirs) {
    std::string paper = "-";
    if (d.support == "double" && std::abs(d.direction_deg) < 1e-9)
      paper = "120 N survived (Fig. 8)";
    if (d.support == "single" && std::abs(d.direction_deg - 90.0) < 1e-9)
      paper = "100 N survived (Fig. 9, leftward)";
    md << "| " << d.support << " | " << fmt(d.direction_deg, 1) << " | "
       << (d.b.reached_max ? ">= " : "") << fmt(d.b.monotone, 0) << " | "
       << (d.b.reached_max ? ">= " : "") << fmt(d.b.boundary, 1) << " | "
       << list(d.b.non_monotone, 0) << " | " << (d.first_failure.empty() ? "-" : d.first_failure)
       << " | " << paper << " |\n";
  }
  md << "\n";
}

/// envelope.md, with --grid-forces: every run's verdict, direction by force.
void write_grid_table(std::ostream& md, const Options& o, const Results& res) {
  const std::vector<double>& forces = o.grid_forces;
  int runs = 0, survived = 0;
  md << "Every run ("
     << (o.jitter_deg > 0.0 ? "at -" + fmt(o.jitter_deg, 2) + " deg, the direction, +" +
                                  fmt(o.jitter_deg, 2) + " deg; "
                            : std::string())
     << "S survived, f fell, s slipped, t tilted, c slow recovery, e error, x another "
        "criterion):\n\n"
     << "| support | direction (deg) |";
  for (double f : forces)
    md << ' ' << fmt(f, 1) << " N |";
  md << "\n|---|---|";
  for (std::size_t i = 0; i < forces.size(); ++i)
    md << "---|";
  md << "\n";
  for (const auto& d : res.dirs) {
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

/// envelope.md: Fig. 11 and the platforms' frequencies.
void write_fig11_and_platform_sections(std::ostream& md, const Options& o, const Results& res) {
  if (!res.fig11.empty()) {
    md << "## Fig. 11: forward push, double support\n\nLongest push survived per force "
          "(bisection to "
       << fmt(o.duration_tol, 3)
       << " s) and its impulse. Paper: the maximum impulse drops quickly and is roughly "
          "constant above 80 N; the maximum duration drops even faster.\n\n"
       << "| force (N) | max duration (s) | max impulse (N s) |\n|---|---|---|\n";
    for (const auto& p : res.fig11)
      md << "| " << fmt(p.force, 0) << " | " << (p.reached_max ? ">= " : "") << fmt(p.duration, 3)
         << " | " << (p.reached_max ? ">= " : "") << fmt(p.force * p.duration, 1) << " |\n";
    md << "\n";
  }
  if (!res.freqs.empty()) {
    md << "## Moving supports: highest frequency\n\nEach run lasts the ramp plus "
       << fmt(o.periods, 1)
       << " full periods. Paper (Sec. 4.2): in phase, 1 m amplitude: "
          "~0.12 Hz; out of phase, 0.4 m: ~1 Hz.\n\n"
       << "| scenario | amplitude (m) | monotone (Hz) | boundary (Hz) | non-monotone (Hz) "
          "|\n|---|---|---|---|---|\n";
    for (const auto& q : res.freqs)
      md << "| " << q.scenario << " | " << fmt(q.amplitude, 2) << " | "
         << (q.b.reached_max ? ">= " : "") << fmt(q.b.monotone, 3) << " | "
         << (q.b.reached_max ? ">= " : "") << fmt(q.b.boundary, 3) << " | "
         << list(q.b.non_monotone, 3) << " |\n";
    md << "\n";
  }
}

}  // namespace

void write_runs_csv(const Options& o, const Results& res) {
  std::ofstream f(fs::path(o.output_dir) / "runs.csv");
  f << "study,support,direction_deg,force_N,duration_s,frequency_Hz,survived,com_error_max_m,"
       "foot_slip_max_m,foot_slide_max_m,foot_displacement_max_m,foot_tilt_max_deg,"
       "trunk_pitch_max_deg,trunk_roll_max_deg,failed\n";
  for (const Row& r : res.rows)
    f << r.study << ',' << r.support << ',' << r.direction_deg << ',' << r.force_n << ','
      << r.duration_s << ',' << r.frequency_hz << ',' << (r.o.survived ? 1 : 0) << ','
      << r.o.com_error_max_m << ',' << r.o.foot_slip_max_m << ',' << r.o.foot_slide_max_m << ','
      << r.o.foot_displacement_max_m << ',' << r.o.foot_tilt_max_deg << ','
      << r.o.trunk_pitch_max_deg << ',' << r.o.trunk_roll_max_deg << ',' << csv_field(r.o.failed)
      << '\n';
}

void write_envelope_csv(const Options& o, const Results& res) {
  std::ofstream f(fs::path(o.output_dir) / "envelope.csv");
  f << "study,support_or_scenario,direction_deg_or_force_N,monotone,boundary,reached_max,"
       "non_monotone,first_failure\n";
  for (const auto& d : res.dirs)
    f << "push," << d.support << ',' << d.direction_deg << ',' << d.b.monotone << ','
      << d.b.boundary << ',' << (d.b.reached_max ? 1 : 0) << ','
      << csv_field(list(d.b.non_monotone, 1)) << ',' << csv_field(d.first_failure) << '\n';
  for (const auto& p : res.fig11)
    f << "fig11,double," << p.force << ',' << p.duration << ',' << p.duration << ','
      << (p.reached_max ? 1 : 0) << ",\"-\",\"\"\n";
  for (const auto& q : res.freqs)
    f << "platforms," << q.scenario << ",0," << q.b.monotone << ',' << q.b.boundary << ','
      << (q.b.reached_max ? 1 : 0) << ',' << csv_field(list(q.b.non_monotone, 3)) << ",\"\"\n";
}

void draw_pictures(const Options& o, Results& res) {
  if (res.dirs.empty() && res.fig11.empty()) return;
  const std::string gp = plot::find_gnuplot(o.gnuplot);
  if (gp.empty()) {
    res.plot_note = "gnuplot not found (Debian: apt-get install gnuplot-nox): no pictures drawn";
    return;
  }
  const fs::path data = fs::absolute(fs::path(o.output_dir) / "runs" / "plot");
  fs::create_directories(data);
  write_plot_data(res, data);
  for (const std::string term : {"png", "svg"}) {
    const fs::path script = data / ("envelope_" + term + ".gp");
    write_gnuplot_script(o, res, data, term, script);
    const int rc =
        plot::run_gnuplot(gp, script.string(), (data / ("gnuplot_" + term + ".log")).string());
    if (rc != 0)
      res.plot_note += "gnuplot failed (exit " + std::to_string(rc) + ", " +
                       (data / ("gnuplot_" + term + ".log")).string() + "); ";
  }
}

void write_summary(const Options& o, const Results& res, int runs,
                   std::chrono::steady_clock::time_point t0) {
  std::ofstream md(fs::path(o.output_dir) / "envelope.md");
  md << "# Balance envelope\n\nMeasured by `poise envelope` (" << o.mode << ", " << runs
     << " runs, "
     << fmt(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0)
     << " s). Every run: runs.csv. Priority: "
     << (o.priority.empty() ? "the base scenarios' (default lexicographic)" : o.priority)
     << ". Controller: "
     << (o.controller_config.empty() ? std::string("the base scenarios' sections")
                                     : "`" + o.controller_config + "`")
     << ". State: " << (o.ground_truth_state ? "ground truth (debug)" : "the estimator's")
     << ".\n\n";
  if (!res.dirs.empty()) {
    write_push_section(md, o, res);
    if (!o.grid_forces.empty()) write_grid_table(md, o, res);
  }
  write_fig11_and_platform_sections(md, o, res);
  if (!res.pictures.empty()) {
    md << "Pictures:";
    for (const auto& p : res.pictures)
      md << " `" << fs::path(p).filename().string() << "`";
    md << "\n";
  }
  if (!res.plot_note.empty()) md << "\nNote: " << res.plot_note << "\n";
}

}  // namespace poise::envelope::study
