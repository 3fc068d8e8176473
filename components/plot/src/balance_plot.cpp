// plot_balance(): export the topics of the balance sheet to CSV, gather the few values gnuplot
// cannot read from CSV (safe regions, pushes, the log time -> robot time map), write a gnuplot
// script and run gnuplot on it as a child process.
#include "poise/plot/balance_plot.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>
#include <utility>

#include <poise/msg/reflection_gen.hpp>

#include "export_problems.hpp"
#include "poise/plot/csv_export.hpp"

namespace poise::plot {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kState = "poise/state";
constexpr std::string_view kTruth = "poise/ground_truth";
constexpr std::string_view kProblem = "poise/contact_problem";
constexpr std::string_view kSolution = "poise/contact_solution";
constexpr std::string_view kDescription = "poise/robot_description";
constexpr std::string_view kDisturbance = "poise/disturbance";

/// Lines per series at most (every N-th sample beyond): enough for 1600 px, keeps the SVG small.
constexpr std::uint64_t kMaxPointsPerLine = 4000;

constexpr const char* kRed = "#d62728";
constexpr const char* kGreen = "#2ca02c";
constexpr const char* kBlue = "#1f77b4";
constexpr const char* kRight = "#1f77b4";
constexpr const char* kLeft = "#ff7f0e";
constexpr const char* kPushColour = "#f4a261";

/// Safe CoP region of a foot in its foot frame (sole rectangle inset by the safety margin).
struct SafeRegion {
  bool known = false;
  double x_lo = 0, x_hi = 0, y_lo = 0, y_hi = 0;
};

struct RecordedDisturbance {
  std::uint64_t log_time = 0;
  bool push = false;
  double start_s = 0, duration_s = 0;
};

/// What the plot needs beyond the CSV columns, collected from the export's decoded samples.
struct Gathered {
  std::array<SafeRegion, 2> feet;
  std::string region_source;
  std::vector<std::pair<std::uint64_t, std::int64_t>> state_log_to_stamp;
  std::vector<RecordedDisturbance> disturbances;
  // Pushes as the simulator applied them (GroundTruth.push_force_W non-zero), robot time [ns].
  bool has_truth = false;
  std::int64_t truth_previous_stamp = 0;
  bool truth_pushing = false;
  std::vector<std::pair<std::int64_t, std::int64_t>> truth_pushes;  // [start, end)
  std::int64_t min_stamp = std::numeric_limits<std::int64_t>::max();
  std::int64_t max_stamp = std::numeric_limits<std::int64_t>::min();

  void stamp(std::int64_t ns) {
    min_stamp = std::min(min_stamp, ns);
    max_stamp = std::max(max_stamp, ns);
  }
  bool has_time() const { return min_stamp <= max_stamp; }

  void on_sample(std::string_view type, const void* sample, const record::MessageView& m) {
    if (type == msg::IdlName<msg::State>::value) {
      const auto& s = *static_cast<const msg::State*>(sample);
      stamp(s.header().stamp_ns());
      state_log_to_stamp.emplace_back(m.log_time, s.header().stamp_ns());
    } else if (type == msg::IdlName<msg::GroundTruth>::value) {
      const auto& t = *static_cast<const msg::GroundTruth*>(sample);
      const std::int64_t ns = t.header().stamp_ns();
      stamp(ns);
      const auto& f = t.push_force_W();
      const bool pushing = f[0] != 0 || f[1] != 0 || f[2] != 0;
      // The truth of tick k carries the push of the step from k-1 to k: it began a step earlier.
      if (pushing && !truth_pushing)
        truth_pushes.emplace_back(has_truth ? truth_previous_stamp : ns, ns);
      if (pushing) truth_pushes.back().second = ns;
      truth_pushing = pushing;
      has_truth = true;
      truth_previous_stamp = ns;
    } else if (type == msg::IdlName<msg::ContactSolution>::value) {
      stamp(static_cast<const msg::ContactSolution*>(sample)->header().stamp_ns());
    } else if (type == msg::IdlName<msg::ContactProblem>::value) {
      const auto& p = *static_cast<const msg::ContactProblem*>(sample);
      stamp(p.header().stamp_ns());
      if (region_source.empty()) {
        for (std::size_t i = 0; i < 2; ++i) {
          const auto& f = p.feet()[i];
          feet[i] = {true, f.x_min() + f.safety_margin(), f.x_max() - f.safety_margin(),
                     f.y_min() + f.safety_margin(), f.y_max() - f.safety_margin()};
        }
        region_source = std::string(kProblem);
      }
    } else if (type == msg::IdlName<msg::RobotDescription>::value) {
      const auto& d = *static_cast<const msg::RobotDescription*>(sample);
      for (std::size_t i = 0; i < 2; ++i) {
        const auto& f = d.feet()[i];
        feet[i] = {true, f.x_min() + f.safety_margin(), f.x_max() - f.safety_margin(),
                   f.y_min() + f.safety_margin(), f.y_max() - f.safety_margin()};
      }
      region_source = std::string(kDescription);
    } else if (type == msg::IdlName<msg::Disturbance>::value) {
      const auto& d = *static_cast<const msg::Disturbance*>(sample);
      disturbances.push_back(
          {m.log_time, d.kind() == msg::DISTURBANCE_PUSH, d.start_time_s(), d.duration_s()});
    }
  }

  /// Robot time [s] of the state sample logged nearest to `log_time`; NaN without state.
  double robot_time_at(std::uint64_t log_time) const {
    if (state_log_to_stamp.empty()) return std::nan("");
    const auto it = std::lower_bound(state_log_to_stamp.begin(), state_log_to_stamp.end(),
                                     std::make_pair(log_time, std::int64_t{0}));
    auto best = it == state_log_to_stamp.end() ? it - 1 : it;
    if (it != state_log_to_stamp.begin() && it != state_log_to_stamp.end() &&
        log_time - (it - 1)->first < it->first - log_time) {
      best = it - 1;
    }
    return static_cast<double>(best->second) * 1e-9;
  }
};

/// A gnuplot double-quoted string (noenhanced text).
std::string gp_string(std::string_view text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') out.push_back('\\');
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out.push_back(c);
  }
  return out + "\"";
}

/// A gnuplot single-quoted string (file names: no escapes but '' for ').
std::string gp_file(std::string_view text) {
  std::string out = "'";
  for (char c : text) {
    if (c == '\'') out.push_back('\'');
    out.push_back(c);
  }
  return out + "'";
}

/// `text` broken into lines of at most `width` characters at spaces (continuations indented).
std::vector<std::string> wrap(const std::string& text, std::size_t width) {
  std::vector<std::string> lines;
  std::string rest = text;
  while (rest.size() > width) {
    std::size_t cut = rest.rfind(' ', width);
    if (cut == std::string::npos || cut < width / 3) cut = width;
    lines.push_back(rest.substr(0, cut));
    rest = "    " + rest.substr(rest[cut] == ' ' ? cut + 1 : cut);
  }
  lines.push_back(rest);
  return lines;
}

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

/// Builds one panel's plot command from the exported topics.
class Panel {
 public:
  Panel(std::string title, std::string ylabel)
      : title_(std::move(title)), ylabel_(std::move(ylabel)) {}

  /// A line of `column` of `topic` against its header.stamp_ns; a missing topic is noted.
  void line(const TopicExport* topic, std::string_view topic_name, const std::string& column,
            const std::string& title, const char* colour, int dash, double width = 1.5) {
    if (!topic) {
      note_missing(topic_name);
      return;
    }
    const int t = topic->column("header.stamp_ns");
    const int v = topic->column(column);
    if (!t || !v) {
      note_missing(std::string(topic_name) + " " + column);
      return;
    }
    const std::uint64_t every = std::max<std::uint64_t>(1, topic->rows / kMaxPointsPerLine);
    std::ostringstream s;
    s << gp_file(topic->csv_path) << " every " << every << " using ($" << t << "*1e-9-T0):" << v
      << " with lines lc rgb " << gp_string(colour) << " dt " << dash << " lw " << width
      << " title " << gp_string(title);
    items_.push_back(s.str());
    ++data_lines_;
  }
  /// A horizontal line at `y` (safe-region border), drawn only when the panel has data.
  void level(double y, const std::string& title, const char* colour) {
    levels_.push_back(number(y) + " with lines lc rgb " + gp_string(colour) +
                      " dt 3 lw 1.5 title " + gp_string(title));
  }
  void key_entry(const std::string& item) { extra_.push_back(item); }
  void note(const std::string& text) { notes_.push_back(text); }

  std::string script() const {
    std::ostringstream s;
    s << "set title " << gp_string(title_) << "\nset ylabel " << gp_string(ylabel_) << "\n";
    if (data_lines_ == 0) {
      std::string why = "no data";
      if (!missing_.empty()) why += ": not in the recording: " + join(missing_);
      s << "set yrange [0:1]\nset label 90 " << gp_string(why)
        << " at graph 0.5, graph 0.5 center\nplot -1 notitle\nunset label 90\nset autoscale y\n";
      return s.str();
    }
    std::vector<std::string> all = items_;
    all.insert(all.end(), levels_.begin(), levels_.end());
    all.insert(all.end(), extra_.begin(), extra_.end());
    std::string label;
    if (!missing_.empty()) label = "not in the recording: " + join(missing_);
    for (const auto& n : notes_)
      label += (label.empty() ? "" : "; ") + n;
    if (!label.empty())
      s << "set label 90 " << gp_string(label) << " at graph 0.02, graph 0.06 left font \",9\"\n";
    s << "plot ";
    for (std::size_t i = 0; i < all.size(); ++i)
      s << (i ? ", \\\n     " : "") << all[i];
    s << "\n";
    if (!label.empty()) s << "unset label 90\n";
    return s.str();
  }
  bool has_data() const { return data_lines_ > 0; }

 private:
  static std::string join(const std::vector<std::string>& v) {
    std::string out;
    for (const auto& x : v)
      out += (out.empty() ? "" : ", ") + x;
    return out;
  }
  void note_missing(std::string_view what) {
    if (std::find(missing_.begin(), missing_.end(), what) == missing_.end())
      missing_.emplace_back(what);
  }
  std::string title_, ylabel_;
  std::vector<std::string> items_, levels_, extra_, notes_, missing_;
  int data_lines_ = 0;
};


std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

bool executable(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}

}  // namespace

std::string find_gnuplot(const std::string& requested) {
  if (!requested.empty()) {
    if (requested.find('/') != std::string::npos) return executable(requested) ? requested : "";
  }
  const std::string name = requested.empty() ? "gnuplot" : requested;
  const char* path = std::getenv("PATH");
  std::string_view dirs = path ? path : "/usr/bin:/bin";
  while (!dirs.empty()) {
    const auto colon = dirs.find(':');
    const std::string_view dir = dirs.substr(0, colon);
    if (!dir.empty() && executable(fs::path(dir) / name)) return (fs::path(dir) / name).string();
    if (colon == std::string_view::npos) break;
    dirs.remove_prefix(colon + 1);
  }
  return {};
}

int run_gnuplot(const std::string& gnuplot, const std::string& script,
                const std::string& log_path) {
  const pid_t pid = ::fork();
  if (pid < 0) return 127;
  if (pid == 0) {
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, STDERR_FILENO);
      ::dup2(fd, STDOUT_FILENO);
    }
    const int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) ::dup2(devnull, STDIN_FILENO);
    ::execl(gnuplot.c_str(), gnuplot.c_str(), script.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

namespace {

/// Where the sheet goes (out_dir) and where its data and script are made (work: a temporary
/// directory removed at the end, or DIR/<stem>_plot_data/ with --keep-data).
struct PlotDirs {
  fs::path file, out_dir, work;
  std::string stem;
  bool keep = false;
  PlotDirs() = default;
  PlotDirs(const PlotDirs&) = delete;
  PlotDirs& operator=(const PlotDirs&) = delete;
  ~PlotDirs() {
    std::error_code e;
    if (!keep && !work.empty()) fs::remove_all(work, e);
  }
};

/// Makes the output and work directories. Returns "" or why it could not.
std::string make_dirs(const PlotOptions& o, PlotDirs& d) {
  std::error_code ec;
  d.file = fs::path(o.file);
  d.stem = d.file.stem().string();
  d.out_dir = o.output_dir.empty()
                  ? (d.file.has_parent_path() ? d.file.parent_path() : fs::path("."))
                  : fs::path(o.output_dir);
  fs::create_directories(d.out_dir, ec);
  if (ec) return "cannot create " + d.out_dir.string() + ": " + ec.message();
  d.keep = o.keep_data;
  if (o.keep_data) {
    d.work = d.out_dir / (d.stem + "_plot_data");
    fs::create_directories(d.work, ec);
    if (ec) return "cannot create " + d.work.string() + ": " + ec.message();
    return "";
  }
  std::string pattern = (fs::temp_directory_path(ec) / "poise-plot-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) return "cannot create a temporary directory";
  d.work = pattern;
  return "";
}

/// Exports the sheet's topics to CSV in `work`, gathering what the CSV cannot give into `g`.
ExportReport export_sheet_topics(const PlotOptions& o, const fs::path& work, std::FILE* log,
                                 Gathered& g) {
  ExportOptions ex;
  ex.output_dir = work.string();
  ex.topics = {std::string(kState),    std::string(kTruth),       std::string(kProblem),
               std::string(kSolution), std::string(kDescription), std::string(kDisturbance)};
  ex.topics_must_exist = false;
  ex.progress = log;
  ex.on_sample = [&](const std::string&, std::string_view type, const void* sample,
                     const record::MessageView& m) { g.on_sample(type, sample, m); };
  ExportReport report = export_csv(o.file, ex);
  std::sort(g.state_log_to_stamp.begin(), g.state_log_to_stamp.end());
  return report;
}

/// The time axis: robot time in seconds (from 0 when the stamps look like a wall clock).
struct TimeAxis {
  double t0 = 0, lo = 0, hi = 0;
  std::string label;
};

TimeAxis time_axis(const Gathered& g) {
  TimeAxis a;
  const bool epoch_like = g.min_stamp > 100'000LL * 1'000'000'000LL;  // > ~1 day
  a.t0 = epoch_like ? static_cast<double>(g.min_stamp) * 1e-9 : 0.0;
  a.lo = static_cast<double>(g.min_stamp) * 1e-9 - a.t0;
  a.hi = static_cast<double>(g.max_stamp) * 1e-9 - a.t0;
  if (a.hi - a.lo < 1e-3) {
    a.lo -= 0.5;
    a.hi += 0.5;
  }
  a.label = epoch_like ? "robot time since the first sample [s] (header.stamp_ns)"
                       : "robot time [s] (header.stamp_ns)";
  return a;
}

/// Push intervals: as the simulator applied them (ground truth; includes a scenario's own pushes)
/// when the recording shows any, else as requested on poise/disturbance (a robot has no truth),
/// then those of the command line. `notes`: pushes that cannot be placed.
std::vector<PushInterval> find_pushes(const PlotOptions& o, const Gathered& g,
                                      std::vector<std::string>& notes) {
  std::vector<PushInterval> pushes;
  for (const auto& [start, end] : g.truth_pushes)
    pushes.push_back(PushInterval{static_cast<double>(start) * 1e-9,
                                  static_cast<double>(end - start) * 1e-9,
                                  std::string(kTruth) + " push_force_W"});
  for (const auto& d : g.disturbances) {
    if (!d.push || !g.truth_pushes.empty()) continue;
    PushInterval p{d.start_s, d.duration_s, std::string(kDisturbance)};
    if (d.start_s < 0) {
      p.start_s = g.robot_time_at(d.log_time);
      p.source += " (sent 'at once': start = robot time when it was logged)";
      if (std::isnan(p.start_s)) {
        notes.push_back("a push sent 'at once' cannot be placed (no poise/state)");
        continue;
      }
    }
    pushes.push_back(p);
  }
  for (const auto& p : o.extra_pushes)
    pushes.push_back(p);
  return pushes;
}

const char* const kAxisColour[3] = {kRed, kGreen, kBlue};
const char* const kAxisName[3] = {"x", "y", "z"};
const char* const kFootColour[2] = {kRight, kLeft};
const char* const kFootName[2] = {"right", "left"};

/// Panels (a) and (b): the CoM, estimated and true.
void add_com_panels(const ExportReport& report, bool pushes, std::vector<Panel>& panels) {
  const TopicExport* state = report.find(kState);
  const TopicExport* truth = report.find(kTruth);
  Panel a("(a) CoM x, y (estimate solid, ground truth dashed)", "CoM [m]");
  a.line(state, kState, "com_W[0]", "x", kRed, 1);
  a.line(state, kState, "com_W[1]", "y", kGreen, 1);
  a.line(truth, kTruth, "com_W[0]", "x truth", kRed, 2);
  a.line(truth, kTruth, "com_W[1]", "y truth", kGreen, 2);
  if (pushes)
    a.key_entry(std::string("keyentry with boxes fc rgb ") + gp_string(kPushColour) +
                " fs transparent solid 0.35 noborder title \"push\"");
  panels.push_back(std::move(a));
  Panel b("(b) CoM z (estimate solid, ground truth dashed)", "CoM z [m]");
  b.line(state, kState, "com_W[2]", "z", kBlue, 1);
  b.line(truth, kTruth, "com_W[2]", "z truth", kBlue, 2);
  panels.push_back(std::move(b));
}

/// Panels (c) and (d): the momentum rates of eqs. (10)-(11), desired and admissible.
void add_momentum_panels(const ExportReport& report, std::vector<Panel>& panels) {
  const TopicExport* problem = report.find(kProblem);
  const TopicExport* solution = report.find(kSolution);
  const auto rate_panel = [&](const char* title, const char* unit, const char* what) {
    Panel p(title, unit);
    for (int i = 0; i < 3; ++i)
      p.line(problem, kProblem, std::string(what) + "_desired_W[" + std::to_string(i) + "]",
             std::string(kAxisName[i]) + " desired", kAxisColour[i], 1, 1.2);
    for (int i = 0; i < 3; ++i)
      p.line(solution, kSolution, std::string(what) + "_admissible_W[" + std::to_string(i) + "]",
             std::string(kAxisName[i]) + " admissible", kAxisColour[i], 2, 2.0);
    panels.push_back(std::move(p));
  };
  rate_panel("(c) Linear momentum rate: desired (solid) vs admissible (dashed)", "dl/dt [N]",
             "l_dot");
  rate_panel("(d) Angular momentum rate: desired (solid) vs admissible (dashed)", "dk/dt [N m]",
             "k_dot");
}

/// Panel (e): the vertical ground reaction forces, solved and true.
void add_force_panel(const ExportReport& report, std::vector<Panel>& panels) {
  Panel e("(e) Vertical ground reaction force (solution solid, ground truth dashed)", "GRF z [N]");
  for (int i = 0; i < 2; ++i)
    e.line(report.find(kSolution), kSolution,
           "feet[" + std::to_string(i) + "].wrench_at_ankle_W.force[2]", kFootName[i],
           kFootColour[i], 1);
  for (int i = 0; i < 2; ++i)
    e.line(report.find(kTruth), kTruth, "feet[" + std::to_string(i) + "].wrench_W.force[2]",
           std::string(kFootName[i]) + " truth", kFootColour[i], 2);
  panels.push_back(std::move(e));
}

/// Panels (f) and (g): the admissible CoPs in the foot frames, with the safe regions.
void add_cop_panels(const ExportReport& report, const Gathered& g, std::vector<Panel>& panels) {
  for (int axis = 0; axis < 2; ++axis) {
    const char* xy = axis == 0 ? "x" : "y";
    Panel p(std::string(axis == 0 ? "(f)" : "(g)") + " Admissible CoP " + xy +
                " in the foot frame, safe region dotted",
            std::string("CoP ") + xy + " [m]");
    for (int i = 0; i < 2; ++i)
      p.line(report.find(kSolution), kSolution,
             "feet[" + std::to_string(i) + "].cop_F[" + std::to_string(axis) + "]", kFootName[i],
             kFootColour[i], 1);
    const auto lo = [&](const SafeRegion& r) { return axis == 0 ? r.x_lo : r.y_lo; };
    const auto hi = [&](const SafeRegion& r) { return axis == 0 ? r.x_hi : r.y_hi; };
    const SafeRegion& r = g.feet[0];
    const SafeRegion& l = g.feet[1];
    if (r.known && l.known && lo(r) == lo(l) && hi(r) == hi(l)) {
      p.level(lo(r), "safe region", "black");
      p.level(hi(r), "", "black");
    } else {
      for (int i = 0; i < 2; ++i) {
        if (!g.feet[i].known) continue;
        p.level(lo(g.feet[i]), std::string("safe region ") + kFootName[i], kFootColour[i]);
        p.level(hi(g.feet[i]), "", kFootColour[i]);
      }
    }
    if (!r.known && !l.known) p.note("safe region unknown (no robot_description or contact_problem)");
    panels.push_back(std::move(p));
  }
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& t : items) out += (out.empty() ? "" : ", ") + t;
  return out;
}

/// The push lines of the info panel.
void add_push_info(const std::vector<PushInterval>& pushes, const std::vector<std::string>& notes,
                   double t0, std::vector<std::string>& info) {
  if (pushes.empty())
    info.push_back(
        "Push: none recorded (ground truth, poise/disturbance); --push START,DURATION adds one");
  for (const auto& p : pushes) {
    char buf[256];
    std::snprintf(buf, sizeof(buf), "Push: %.3f s to %.3f s robot time (%.3f s), from %s",
                  p.start_s - t0, p.start_s + p.duration_s - t0, p.duration_s, p.source.c_str());
    info.push_back(buf);
  }
  for (const auto& n : notes) info.push_back("Note: " + n);
}

/// Panel (h): what the sheet was drawn from.
std::vector<std::string> info_lines(const fs::path& file, const ExportReport& report,
                                    const Gathered& g, const std::vector<PushInterval>& pushes,
                                    const std::vector<std::string>& notes, const TimeAxis& time) {
  std::vector<std::string> info;
  info.push_back("Recording: " + file.filename().string() +
                 (report.scan.complete ? "" : "  (INCOMPLETE: cut short)"));
  std::vector<std::string> have;
  for (const auto& t : report.topics) have.push_back(t.topic + " (" + std::to_string(t.rows) + ")");
  info.push_back("Topics (messages): " + joined(have));
  if (!report.absent_topics.empty()) info.push_back("Missing: " + joined(report.absent_topics));
  add_push_info(pushes, notes, time.t0, info);
  if (!g.region_source.empty()) {
    char buf[256];
    std::snprintf(buf, sizeof(buf),
                  "Safe CoP region (from %s): right x [%.4f, %.4f] y [%.4f, %.4f], "
                  "left x [%.4f, %.4f] y [%.4f, %.4f] m",
                  g.region_source.c_str(), g.feet[0].x_lo, g.feet[0].x_hi, g.feet[0].y_lo,
                  g.feet[0].y_hi, g.feet[1].x_lo, g.feet[1].x_hi, g.feet[1].y_lo, g.feet[1].y_hi);
    info.push_back(buf);
  }
  info.push_back("Time axis: " + time.label + "; shaded: push");
  info.push_back("Desired: contact_problem; admissible, GRF, CoP: contact_solution");
  return info;
}

/// The gnuplot commands of the sheet (the same on both terminals).
std::string sheet_script(const std::string& title, const TimeAxis& time,
                         const std::vector<PushInterval>& pushes, const std::vector<Panel>& panels,
                         const std::vector<std::string>& info) {
  std::ostringstream sheet;
  sheet << "set datafile separator comma\nset datafile columnheaders\n"
        << "T0 = " << number(time.t0) << "\n"
        << "set xrange [" << number(time.lo) << ":" << number(time.hi) << "]\n"
        << "set xlabel " << gp_string(time.label) << "\n"
        << "set grid\nset key top right font \",9\" samplen 2.5 spacing 0.9 opaque box\n"
        << "set border 3\nset tics nomirror\nset samples 2\n";
  int object = 1;
  for (const auto& p : pushes)
    sheet << "set object " << object++ << " rect from first " << number(p.start_s - time.t0)
          << ", graph 0 to first " << number(p.start_s + p.duration_s - time.t0)
          << ", graph 1 behind fc rgb " << gp_string(kPushColour)
          << " fs transparent solid 0.35 noborder\n";
  sheet << "set multiplot layout 4,2 title " << gp_string(title) << " font \",14\"\n";
  for (const auto& p : panels) sheet << p.script();
  // (h): the info panel.
  sheet << "unset object\nunset grid\nunset border\nunset tics\nunset xlabel\nunset ylabel\n"
        << "unset key\nset title \"(h) Drawn from\"\n";
  std::vector<std::string> lines;
  for (const auto& text : info) {
    const auto wrapped = wrap(text, 90);
    lines.insert(lines.end(), wrapped.begin(), wrapped.end());
  }
  for (std::size_t i = 0; i < lines.size(); ++i)
    sheet << "set label " << 100 + i << " " << gp_string(lines[i]) << " at graph 0, graph "
          << number(0.97 - 0.07 * static_cast<double>(i)) << " left font \",10\"\n";
  sheet << "plot [0:1][0:1] -1 notitle\nunset multiplot\nreset\n";
  return sheet.str();
}

/// Writes the script (PNG, then SVG) and runs gnuplot on it. Returns "" or what failed.
std::string draw(const PlotOptions& o, const PlotDirs& d, const std::string& gnuplot,
                 const std::string& sheet, const PlotResult& result, std::FILE* log) {
  const std::string script_path = (d.work / (d.stem + "_balance.gp")).string();
  {
    std::ofstream s(script_path);
    s << "# poise plot " << o.file << ": the paper's Fig. 8/9 panels (components/plot)\n";
    s << "set terminal pngcairo noenhanced size 1600,1800 font \"sans,10\" background \"white\"\n"
      << "set output " << gp_file(result.png) << "\n"
      << sheet << "set output\n";
    s << "set terminal svg noenhanced size 1600,1800 dynamic font \"sans,10\" background "
         "\"white\"\n"
      << "set output " << gp_file(result.svg) << "\n"
      << sheet << "set output\n";
    if (!s) return "cannot write " + script_path;
  }
  const std::string gp_log = (d.work / "gnuplot.log").string();
  const int gp = run_gnuplot(gnuplot, script_path, gp_log);
  const std::string messages = read_text(gp_log);
  if (gp != 0) {
    std::fprintf(log, "%s", messages.c_str());
    return "gnuplot (" + gnuplot + ") failed with status " + std::to_string(gp) +
           (o.keep_data ? "; script: " + script_path : "; --keep-data keeps the script");
  }
  std::error_code ec;
  for (const auto& path : {result.png, result.svg})
    if (fs::file_size(path, ec) == 0 || ec) return "gnuplot wrote no " + path;
  if (!messages.empty()) std::fprintf(log, "poise plot: gnuplot says:\n%s", messages.c_str());
  return "";
}

/// "" when the recording has something to plot (says on `log` which topics are left out), else
/// why not.
std::string check_plottable(const PlotOptions& o, const ExportReport& report, const Gathered& g,
                            std::FILE* log) {
  if (!g.has_time())
    return o.file + ": none of " + std::string(kState) + ", " + std::string(kTruth) + ", " +
           std::string(kProblem) + ", " + std::string(kSolution) + " has a sample: nothing to plot";
  for (const auto& t : report.absent_topics)
    if (t != kDisturbance)
      std::fprintf(log, "poise plot: %s is not in the recording: its lines are left out\n",
                   t.c_str());
  return "";
}

}  // namespace

PlotResult plot_balance(const PlotOptions& o) {
  PlotResult result;
  std::FILE* log = o.log ? o.log : stderr;
  auto fail = [&](std::string why) {
    result.exit_code = 2;
    result.error = std::move(why);
    return result;
  };
  const std::string gnuplot = find_gnuplot(o.gnuplot);
  if (gnuplot.empty())
    return fail((o.gnuplot.empty() ? std::string("gnuplot is not on PATH")
                                   : "gnuplot '" + o.gnuplot + "' not found") +
                ": install it (Debian: apt-get install gnuplot-nox, as deploy/bootstrap.sh does) "
                "or name it with --gnuplot");
  std::error_code ec;
  if (!fs::exists(o.file, ec)) return fail(o.file + ": no such file");
  PlotDirs dirs;
  if (std::string why = make_dirs(o, dirs); !why.empty()) return fail(why);
  Gathered g;
  const ExportReport report = export_sheet_topics(o, dirs.work, log, g);
  if (!report.scan.is_mcap) return fail(o.file + ": not an MCAP file (" + report.error + ")");
  if (!report.error.empty()) return fail(report.error);
  const int code = print_export_problems("plot", o.file, report);
  result.missing_topics = report.absent_topics;
  if (std::string why = check_plottable(o, report, g, log); !why.empty()) return fail(why);
  std::vector<std::string> notes;
  result.pushes = find_pushes(o, g, notes);
  if (result.pushes.empty())
    std::fprintf(log,
                 "poise plot: no push in the recording (no push force in poise/ground_truth, no "
                 "poise/disturbance of kind PUSH): no push band. Give one with --push "
                 "START,DURATION (robot time, s).\n");
  std::vector<Panel> panels;
  add_com_panels(report, !result.pushes.empty(), panels);
  add_momentum_panels(report, panels);
  add_force_panel(report, panels);
  add_cop_panels(report, g, panels);
  const TimeAxis time = time_axis(g);
  const std::string sheet =
      sheet_script(o.title.empty() ? dirs.file.filename().string() : o.title, time, result.pushes,
                   panels, info_lines(dirs.file, report, g, result.pushes, notes, time));
  result.png = (dirs.out_dir / (dirs.stem + "_balance.png")).string();
  result.svg = (dirs.out_dir / (dirs.stem + "_balance.svg")).string();
  if (std::string why = draw(o, dirs, gnuplot, sheet, result, log); !why.empty()) return fail(why);
  result.exit_code = code;
  return result;
}

}  // namespace poise::plot
