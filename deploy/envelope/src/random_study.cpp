// `poise envelope random` / `poise envelope merge` (random_study.hpp): runs drawn at random, in
// process, `--jobs` at a time (one forked process a run: a crash is that run's error, not the
// study's), `--shard I/N` of them; the files a study leaves and the report made from them.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

#include "poise/inprocess/in_process_loop.hpp"
#include "poise/plot/balance_plot.hpp"
#include "poise/scenario/scenario.hpp"
#include "random_study.hpp"
#include "poise/cli/parse.hpp"

namespace poise::envelope {

namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

/// Everything that defines a study: two studies with equal StudyDefinitions are the same runs.
struct StudyDefinition {
  std::uint64_t seed = 0;
  int runs = 0;
  std::string base_double, base_single;
  std::string reality;  ///< "" (the robot is its model) or a profile name
  bool keep_push = false;  ///< the base scenarios' pushes as they are: only the model is drawn
  SamplingOptions sampling;
  ReportOptions report;
};

Json to_json(const StudyDefinition& d) {
  const SamplingOptions& s = d.sampling;
  return {{"seed", d.seed},
          {"runs", d.runs},
          {"base_double", d.base_double},
          {"base_single", d.base_single},
          {"reality", d.reality.empty() ? Json(nullptr) : Json(d.reality)},
          {"keep_push", d.keep_push},
          {"sampling",
           {{"single_fraction", s.single_fraction},
            {"impulse_double_ns", {s.impulse_double[0], s.impulse_double[1]}},
            {"impulse_single_ns", {s.impulse_single[0], s.impulse_single[1]}},
            {"duration_s", {s.duration[0], s.duration[1]}},
            {"height_m", {s.height[0], s.height[1]}},
            {"start_spread_s", s.start_spread}}},
          {"report",
           {{"bin_ns", d.report.bin_ns},
            {"band_deg", d.report.band_deg},
            {"sector_deg", d.report.sector_deg},
            {"worst", d.report.worst},
            {"bootstrap", d.report.bootstrap}}}};
}

StudyDefinition definition_from_json(const Json& j) {
  StudyDefinition d;
  d.seed = j.at("seed").get<std::uint64_t>();
  d.runs = j.at("runs").get<int>();
  d.base_double = j.at("base_double").get<std::string>();
  d.base_single = j.at("base_single").get<std::string>();
  d.reality = j.at("reality").is_null() ? "" : j.at("reality").get<std::string>();
  d.keep_push = j.at("keep_push").get<bool>();
  const Json& s = j.at("sampling");
  d.sampling.single_fraction = s.at("single_fraction").get<double>();
  const auto pair = [](const Json& a, double (&out)[2]) {
    out[0] = a.at(0).get<double>();
    out[1] = a.at(1).get<double>();
  };
  pair(s.at("impulse_double_ns"), d.sampling.impulse_double);
  pair(s.at("impulse_single_ns"), d.sampling.impulse_single);
  pair(s.at("duration_s"), d.sampling.duration);
  pair(s.at("height_m"), d.sampling.height);
  d.sampling.start_spread = s.at("start_spread_s").get<double>();
  const Json& r = j.at("report");
  d.report.bin_ns = r.at("bin_ns").get<double>();
  d.report.band_deg = r.at("band_deg").get<double>();
  d.report.sector_deg = r.at("sector_deg").get<double>();
  d.report.worst = r.at("worst").get<int>();
  d.report.bootstrap = r.at("bootstrap").get<int>();
  return d;
}

/// The base scenarios, loaded and checked once.
struct Bases {
  YAML::Node node[2];  // double, single
  double start[2] = {0.0, 0.0};
  double duration[2] = {4.0, 4.0};
  double push_duration[2] = {0.0, 0.0}, push_force[2] = {0.0, 0.0};  // the first push's, if any
};

YAML::Node load_base_scenario(const std::string& path, bool need_push, double& start,
                              double& duration, double& push_duration, double& push_force) {
  (void)scenario::load_scenario(path);  // every problem named before the first run
  YAML::Node n = YAML::LoadFile(path);
  const YAML::Node pushes = n["disturbances"]["pushes"];
  const bool has_push = pushes && pushes.IsSequence() && pushes.size() > 0;
  if (need_push && !has_push)
    throw std::runtime_error("base scenario " + path +
                             " has no push to vary (disturbances.pushes[0] is needed)");
  if (has_push) {
    start = pushes[0]["start"] ? pushes[0]["start"].as<double>() : 0.0;
    push_duration = pushes[0]["duration"] ? pushes[0]["duration"].as<double>() : 0.0;
    if (pushes[0]["force"])
      for (const double f : pushes[0]["force"].as<std::vector<double>>()) push_force += f * f;
    push_force = std::sqrt(push_force);
  }
  duration = n["duration"].as<double>();
  const fs::path dir = fs::absolute(path).parent_path();
  for (const char* key : {"config", "urdf"})
    if (n["robot"][key] && n["robot"][key].IsScalar()) {
      const fs::path p = n["robot"][key].as<std::string>();
      if (!p.is_absolute()) n["robot"][key] = fs::weakly_canonical(dir / p).string();
    }
  if (n["reference"] && n["reference"].IsScalar()) {
    const fs::path p = n["reference"].as<std::string>();
    if (!p.is_absolute()) n["reference"] = fs::weakly_canonical(dir / p).string();
  }
  return n;
}

Bases load_bases(const StudyDefinition& d) {
  Bases b;
  for (int k = 0; k < 2; ++k)
    b.node[k] = load_base_scenario(k == 0 ? d.base_double : d.base_single, !d.keep_push,
                                   b.start[k], b.duration[k], b.push_duration[k], b.push_force[k]);
  if (!d.keep_push && b.start[0] != b.start[1])
    throw std::runtime_error("the base scenarios push at different times (" +
                             std::to_string(b.start[0]) + " and " + std::to_string(b.start[1]) +
                             " s): the draw needs one start");
  return b;
}

/// The scenario of one run: the base of its support with the drawn push (world frame) and, with
/// a reality profile, the run's own model draw. The recovery time after the push stays the
/// base's.
YAML::Node scenario_for(const Sample& s, const Bases& b, const StudyDefinition& d) {
  const int k = s.support == "double" ? 0 : 1;
  YAML::Node sc = YAML::Clone(b.node[k]);
  sc["name"] = "random_" + std::to_string(s.index);
  if (!d.reality.empty()) {
    YAML::Node r;
    r["profile"] = d.reality;
    r["seed"] = s.model_seed;
    sc["reality"] = r;
  }
  if (d.keep_push) return sc;
  YAML::Node push = sc["disturbances"]["pushes"][0];
  const double a = s.direction_deg * M_PI / 180.0;
  push["force"] = std::vector<double>{s.force_n * std::cos(a), s.force_n * std::sin(a), 0.0};
  push.remove("frame");
  std::vector<double> point{0.0, 0.0, 0.0};
  if (push["point"]) point = push["point"].as<std::vector<double>>();
  point[2] += s.height_m;
  push["point"] = point;
  push["start"] = s.start_s;
  push["duration"] = s.duration_s;
  sc["duration"] = b.duration[k] + (s.start_s - b.start[k]);
  return sc;
}

std::string emit(const YAML::Node& n) {
  YAML::Emitter e;
  e << n;
  return std::string(e.c_str()) + "\n";
}

/// Runs one sample in this process.
RunRecord run_sample(const Sample& s, const Bases& b, const StudyDefinition& d,
                     const fs::path& work) {
  RunRecord r;
  r.s = s;
  try {
    const std::string text = emit(scenario_for(s, b, d));
    const scenario::Scenario sc = scenario::parse_scenario(text, work, "run " + std::to_string(s.index));
    inprocess::InProcessLoop loop(sc, inprocess::LoopOptions{});
    const inprocess::RunResult res = loop.run();
    r.survived = res.survived;
    for (const auto& f : res.failed) r.failed += (r.failed.empty() ? "" : "; ") + f;
    r.com_error_max_m = res.com_error_max_m;
    r.foot_slip_max_m = res.foot_slip_max_m;
  } catch (const std::exception& e) {
    r.survived = false;
    r.failed = std::string("error: ") + e.what();
  }
  r.kind = r.survived ? "" : failure_kind(r.failed);
  return r;
}

Json record_to_json(const RunRecord& r) {
  return {{"survived", r.survived},
          {"failed", r.failed},
          {"kind", r.kind},
          {"com_error_max_m", r.com_error_max_m},
          {"foot_slip_max_m", r.foot_slip_max_m}};
}

/// At most `jobs` runs at once, each in a forked child that writes its record to work/N.json.
class Pool {
 public:
  Pool(int jobs, double timeout_s, fs::path work) : jobs_(jobs), timeout_s_(timeout_s), work_(std::move(work)) {}

  template <typename Done>
  void run(const std::vector<Sample>& samples, const Bases& b, const StudyDefinition& d,
           Done done) {
    for (const Sample& s : samples) {
      while (static_cast<int>(running_.size()) >= jobs_) reap(done);
      std::fflush(nullptr);
      const pid_t pid = ::fork();
      if (pid < 0) throw std::runtime_error("fork failed: " + std::string(std::strerror(errno)));
      if (pid == 0) {
        // The run's own chatter (the simulator's notes on the URDF, repeated for every run) is
        // not the study's: its verdict and error go into the record.
        if (const int null = ::open("/dev/null", O_WRONLY); null >= 0) {
          ::dup2(null, STDOUT_FILENO);
          ::dup2(null, STDERR_FILENO);
        }
        const RunRecord r = run_sample(s, b, d, work_);
        std::ofstream(result_file(s.index)) << record_to_json(r).dump() << "\n";
        std::fflush(nullptr);
        ::_exit(0);
      }
      running_[pid] = {s, std::chrono::steady_clock::now()};
    }
    while (!running_.empty()) reap(done);
  }

  ~Pool() {
    for (const auto& [pid, job] : running_) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
  }

 private:
  struct Job {
    Sample s;
    std::chrono::steady_clock::time_point started;
  };

  fs::path result_file(int index) const { return work_ / (std::to_string(index) + ".json"); }

  template <typename Done>
  void reap(Done& done) {
    int status = 0;
    const pid_t pid = ::waitpid(-1, &status, WNOHANG);
    if (pid <= 0) {
      const auto now = std::chrono::steady_clock::now();
      for (const auto& [p, job] : running_)
        if (std::chrono::duration<double>(now - job.started).count() > timeout_s_) ::kill(p, SIGKILL);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      return;
    }
    const auto it = running_.find(pid);
    if (it == running_.end()) return;
    RunRecord r;
    r.s = it->second.s;
    const fs::path file = result_file(r.s.index);
    const Json j = Json::parse(std::ifstream(file), nullptr, false);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0 && j.is_object()) {
      r.survived = j.value("survived", false);
      r.failed = j.value("failed", std::string());
      r.kind = j.value("kind", std::string());
      r.com_error_max_m = j.value("com_error_max_m", 0.0);
      r.foot_slip_max_m = j.value("foot_slip_max_m", 0.0);
    } else {
      r.failed = WIFSIGNALED(status) ? "error: the run's process ended on signal " +
                                           std::to_string(WTERMSIG(status)) +
                                           (WTERMSIG(status) == SIGKILL ? " (timeout?)" : "")
                                     : "error: the run's process wrote no result";
      r.kind = "error";
    }
    fs::remove(file);
    running_.erase(it);
    done(r);
  }

  int jobs_;
  double timeout_s_;
  fs::path work_;
  std::map<pid_t, Job> running_;
};

// ---- files

std::string g17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string csv_quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

constexpr const char* kCsvHeader =
    "index,support,direction_deg,height_m,start_s,duration_s,impulse_Ns,force_N,model_seed,"
    "survived,kind,com_error_max_m,foot_slip_max_m,failed";

void write_runs_csv(const fs::path& file, const std::vector<RunRecord>& runs) {
  std::ofstream f(file);
  f << kCsvHeader << "\n";
  for (const RunRecord& r : runs)
    f << r.s.index << ',' << r.s.support << ',' << g17(r.s.direction_deg) << ','
      << g17(r.s.height_m) << ',' << g17(r.s.start_s) << ',' << g17(r.s.duration_s) << ','
      << g17(r.s.impulse_ns) << ',' << g17(r.s.force_n) << ',' << r.s.model_seed << ','
      << (r.survived ? 1 : 0) << ',' << r.kind << ',' << g17(r.com_error_max_m) << ','
      << g17(r.foot_slip_max_m) << ',' << csv_quoted(r.failed) << '\n';
  if (!f) throw std::runtime_error("cannot write " + file.string());
}

/// Splits one CSV line (quoted last field) into its fields.
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cur += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cur += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

std::vector<RunRecord> read_runs_csv(const fs::path& file) {
  std::ifstream f(file);
  if (!f) throw std::runtime_error("cannot read " + file.string());
  std::string line;
  if (!std::getline(f, line) || line != kCsvHeader)
    throw std::runtime_error(file.string() + ": not a runs.csv of `poise envelope random`");
  std::vector<RunRecord> runs;
  for (int n = 2; std::getline(f, line); ++n) {
    const std::vector<std::string> v = csv_fields(line);
    if (v.size() != 14)
      throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": expected 14 fields, got " +
                               std::to_string(v.size()));
    RunRecord r;
    try {
      r.s.index = std::stoi(v[0]);
      r.s.support = v[1];
      r.s.direction_deg = std::stod(v[2]);
      r.s.height_m = std::stod(v[3]);
      r.s.start_s = std::stod(v[4]);
      r.s.duration_s = std::stod(v[5]);
      r.s.impulse_ns = std::stod(v[6]);
      r.s.force_n = std::stod(v[7]);
      r.s.model_seed = std::stoull(v[8]);
      r.survived = v[9] == "1";
      r.kind = v[10];
      r.com_error_max_m = std::stod(v[11]);
      r.foot_slip_max_m = std::stod(v[12]);
      r.failed = v[13];
    } catch (const std::exception&) {
      throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": unreadable run");
    }
    runs.push_back(r);
  }
  return runs;
}

std::string fmt(double v, int prec = 1) {
  if (!std::isfinite(v)) return "-";
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", prec, v);
  return buf;
}

Json report_json(const std::vector<SupportReport>& reps) {
  const auto num = [](double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); };
  Json out = Json::array();
  for (const SupportReport& r : reps) {
    Json bins = Json::array(), worst = Json::array();
    for (const auto& b : r.bins)
      bins.push_back({{"impulse_ns", {b.lo, b.hi}},
                      {"runs", b.runs},
                      {"survived", b.survived},
                      {"ci95", {b.ci_lo, b.ci_hi}}});
    for (const auto& s : r.worst)
      worst.push_back({{"direction_deg", {s.from_deg, s.to_deg}},
                       {"runs", s.runs},
                       {"survived", s.survived},
                       {"smallest_failure_ns", s.smallest_failure}});
    out.push_back({{"support", r.support},
                   {"runs", r.runs},
                   {"survived", r.survived},
                   {"impulse_95_ns", num(r.j95)},
                   {"impulse_95_ci95_ns", {num(r.j95_lo), num(r.j95_hi)}},
                   {"impulse_50_ns", r.fit ? num(r.fit->j50) : Json(nullptr)},
                   {"logistic_scale_ns", r.fit ? num(r.fit->scale) : Json(nullptr)},
                   {"smallest_failure_ns", num(r.smallest_failure)},
                   {"largest_survival_ns", num(r.largest_survival)},
                   {"non_monotone_runs", r.non_monotone},
                   {"non_monotone_share", r.runs ? static_cast<double>(r.non_monotone) / r.runs : 0.0},
                   {"bins", bins},
                   {"worst_directions", worst}});
  }
  return out;
}

std::string report_markdown(const std::vector<SupportReport>& reps, const StudyDefinition& d) {
  std::ostringstream md;
  md << "# Random push study\n\nSeed " << d.seed << ", " << d.runs << " runs"
     << (d.reality.empty() ? ", the robot is its model" : ", reality profile " + d.reality);
  if (d.keep_push) {
    md << ". The base scenarios' pushes as they are (" << fs::path(d.base_double).filename().string()
       << ", " << fs::path(d.base_single).filename().string() << "): only the model is drawn.\n\n";
  } else {
    md << ". Pushes: direction uniform on the circle, duration " << fmt(d.sampling.duration[0], 2)
     << "-" << fmt(d.sampling.duration[1], 2) << " s, height " << fmt(d.sampling.height[0], 2)
     << " to +" << fmt(d.sampling.height[1], 2) << " m on the pushed link, start + 0-"
     << fmt(d.sampling.start_spread, 2) << " s.\n\n";
  }
  md << "| support | runs | survived (Wilson 95 %) | impulse at 95 % survival (N s) | 95 % CI | "
        "at 50 % | smallest failure | non-monotone runs |\n|---|---|---|---|---|---|---|---|\n";
  for (const SupportReport& r : reps) {
    const auto [lo, hi] = wilson_interval(r.survived, r.runs);
    md << "| " << r.support << " | " << r.runs << " | " << r.survived << " ("
       << fmt(100.0 * lo) << "-" << fmt(100.0 * hi) << " %) | " << fmt(r.j95)
       << " | " << (std::isfinite(r.j95_lo) ? fmt(r.j95_lo) + "-" + fmt(r.j95_hi) : "-") << " | "
       << (r.fit ? fmt(r.fit->j50) : "-") << " | " << fmt(r.smallest_failure) << " | "
       << r.non_monotone << " (" << fmt(r.runs ? 100.0 * r.non_monotone / r.runs : 0.0)
       << " %) |\n";
  }
  for (const SupportReport& r : reps) {
    md << "\n## " << r.support << " support: survival by impulse (Wilson 95 % interval)\n\n"
       << "| impulse (N s) | runs | survived | share | 95 % interval |\n|---|---|---|---|---|\n";
    for (const auto& b : r.bins)
      if (b.runs > 0)
        md << "| " << fmt(b.lo) << "-" << fmt(b.hi) << " | " << b.runs << " | " << b.survived
           << " | " << fmt(100.0 * b.survived / b.runs, 0) << " % | " << fmt(100.0 * b.ci_lo, 0)
           << "-" << fmt(100.0 * b.ci_hi, 0) << " % |\n";
    md << "\nWorst directions (smallest failed impulse per " << fmt(d.report.sector_deg)
       << " deg sector; 0 deg = +x, 90 deg = +y):";
    for (const auto& s : r.worst)
      md << " " << fmt(s.from_deg) << "-" << fmt(s.to_deg) << " deg: " << fmt(s.smallest_failure)
         << " N s (" << s.survived << "/" << s.runs << " survived);";
    md << "\n";
  }
  return md.str();
}

void draw_polar(const fs::path& dir, const std::vector<RunRecord>& runs, const std::string& gnuplot) {
  const std::string gp = plot::find_gnuplot(gnuplot);
  if (gp.empty()) {
    std::fprintf(stderr, "poise envelope: gnuplot not found: no picture drawn\n");
    return;
  }
  const fs::path data = dir / "plot";
  fs::create_directories(data);
  for (const char* support : {"double", "single"})
    for (const int ok : {1, 0}) {
      std::ofstream f(data / (std::string(support) + (ok ? "_survived" : "_failed") + ".dat"));
      for (const RunRecord& r : runs)
        if (r.s.support == support && r.survived == (ok == 1))
          f << r.s.direction_deg << ' ' << r.s.impulse_ns << '\n';
    }
  std::vector<std::string> supports;  // those with runs: one panel each
  for (const char* support : {"double", "single"})
    if (std::any_of(runs.begin(), runs.end(), [&](const RunRecord& r) { return r.s.support == support; }))
      supports.emplace_back(support);
  if (supports.empty()) return;
  const fs::path script = data / "random_polar.gp";
  std::ofstream s(script);
  s << "set terminal pngcairo noenhanced size " << 700 * supports.size()
    << ",700 font 'sans,11' background 'white'\n"
    << "set output '" << fs::absolute(dir / "random_polar.png").string() << "'\n"
    << "set multiplot layout 1," << supports.size() << "\nset polar\nset angles degrees\n"
    << "set size square\nset grid polar 45\nunset border\nunset xtics\nunset ytics\n"
    << "set rtics axis nomirror\nset key outside bottom center horizontal\n";
  for (const std::string& support : supports)
    s << "set title \"" << support << " support: impulse of each run (N s) by push direction\\n"
      << "0 deg = +x (forward), 90 deg = +y (left)\"\n"
      << "plot '" << (data / (support + "_survived.dat")).string()
      << "' using 1:2 with points pt 7 ps 0.5 lc rgb '#2a9d2a' title 'survived', '"
      << (data / (support + "_failed.dat")).string()
      << "' using 1:2 with points pt 2 ps 0.8 lc rgb '#d62728' title 'failed'\n";
  s << "unset multiplot\n";
  s.close();
  if (plot::run_gnuplot(gp, script.string(), (data / "gnuplot.log").string()) != 0)
    std::fprintf(stderr, "poise envelope: gnuplot failed (%s)\n", (data / "gnuplot.log").c_str());
}

/// Writes the study's files in `dir` from its runs: runs.csv, study.json, summary.json,
/// envelope.md (+ the polar picture unless `picture` is false).
/// Returns the markdown report. The runs are analysed in index order whatever order they
/// finished in (the bootstrap's resamples pick runs by position).
std::string write_study(const fs::path& dir, std::vector<RunRecord> runs, const StudyDefinition& d,
                        const std::string& shard, const std::string& gnuplot, bool picture) {
  std::sort(runs.begin(), runs.end(),
            [](const RunRecord& a, const RunRecord& b) { return a.s.index < b.s.index; });
  write_runs_csv(dir / "runs.csv", runs);
  Json study = to_json(d);
  study["shard"] = shard.empty() ? Json(nullptr) : Json(shard);
  std::ofstream(dir / "study.json") << study.dump(2) << "\n";
  const std::vector<SupportReport> reps = analyse(runs, d.report, d.seed);
  Json summary = {{"study", to_json(d)}, {"complete", shard.empty()}, {"supports", report_json(reps)}};
  std::ofstream(dir / "summary.json") << summary.dump(2) << "\n";
  const std::string md = report_markdown(reps, d);
  std::ofstream(dir / "envelope.md") << md;
  if (picture) draw_polar(dir, runs, gnuplot);
  return md;
}

bool parse_shard(const std::string& text, int& index, int& count) {
  const auto slash = text.find('/');
  if (slash == std::string::npos) return false;
  try {
    std::size_t a = 0, b = 0;
    index = std::stoi(text.substr(0, slash), &a);
    count = std::stoi(text.substr(slash + 1), &b);
    return a == slash && b == text.size() - slash - 1 && count >= 1 && index >= 0 &&
           index < count;
  } catch (const std::exception&) {
    return false;
  }
}

void add_range(CLI::App& app, const std::string& name, double (&range)[2], const std::string& what,
               double lo, double hi) {
  app.add_option_function<std::vector<double>>(
         name,
         [&range, name, lo, hi](const std::vector<double>& v) {
           if (v.size() != 2 || !(v[0] >= lo && v[1] <= hi && v[0] <= v[1]))
             throw CLI::ValidationError(name, "needs MIN,MAX with " + std::to_string(lo) +
                                                   " <= MIN <= MAX <= " + std::to_string(hi));
           range[0] = v[0];
           range[1] = v[1];
         },
         what + " (default " + fmt(range[0], 2) + "," + fmt(range[1], 2) + ")")
      ->delimiter(',')
      ->expected(2);
}

}  // namespace

namespace {

/// How a study is run (not what it is: StudyDefinition).
struct RunOptions {
  std::string seed_text, shard, output = "results/envelope_random", gnuplot;
  std::string supports = "double,single";
  int jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  double run_timeout = 300.0;
  bool quiet = false, no_picture = false;
  int shard_index = 0, shard_count = 1;
};

void add_random_options(CLI::App& app, StudyDefinition& d, RunOptions& o) {
  app.add_option("--runs,-n", d.runs, "number of runs in the study")->check(CLI::Range(1, 10000000))->capture_default_str();
  app.add_option("--seed", o.seed_text, "the study's seed (default: a new one, printed)");
  app.add_option("--jobs,-j", o.jobs, "runs at once (default: the number of cores)")->check(CLI::Range(1, 1024));
  app.add_option("--shard", o.shard, "I/N: run only runs i with i % N == I (then `poise envelope merge`)");
  app.add_flag("--keep-push", d.keep_push,
               "keep the base scenarios' pushes (or none) as they are and draw only the model "
               "(with --reality): the share of model draws that survive one experiment");
  app.add_option("--reality", d.reality, "a reality profile for every run, each with its own model draw (typical)")
      ->check(CLI::IsMember({"typical"}));
  app.add_option("--supports", o.supports, "double, single or double,single")
      ->check(CLI::IsMember({"double", "single", "double,single", "single,double"}))
      ->capture_default_str();
  app.add_option("--single-fraction", d.sampling.single_fraction,
                 "share of runs in single support with both supports")
      ->check(CLI::Range(0.0, 1.0))->capture_default_str();
  add_range(app, "--impulse-double", d.sampling.impulse_double, "impulse range in double support [N s]", 0.0, 1e4);
  add_range(app, "--impulse-single", d.sampling.impulse_single, "impulse range in single support [N s]", 0.0, 1e4);
  add_range(app, "--push-duration", d.sampling.duration, "push duration range [s]", 0.001, 10.0);
  add_range(app, "--height", d.sampling.height, "range added to the base push point's z [m]", -2.0, 2.0);
  app.add_option("--start-spread", d.sampling.start_spread, "push start = base start + uniform [0, this] [s]")
      ->check(CLI::Range(0.0, 100.0))->capture_default_str();
  app.add_option("--double", d.base_double, "base scenario of the double-support runs")->check(CLI::ExistingFile);
  app.add_option("--single", d.base_single, "base scenario of the single-support runs")->check(CLI::ExistingFile);
  app.add_option("--bin", d.report.bin_ns, "impulse bin width of the table [N s]")->check(CLI::Range(0.01, 1e4))->capture_default_str();
  app.add_option("--band-deg", d.report.band_deg, "direction band of the non-monotone count [deg]")->check(CLI::Range(0.1, 360.0))->capture_default_str();
  app.add_option("--output-dir,-o", o.output, "where runs.csv, study.json, summary.json, envelope.md and random_polar.png go")->capture_default_str();
  app.add_option("--run-timeout", o.run_timeout, "wall-clock bound of one run [s]")->check(CLI::Range(1.0, 36000.0))->capture_default_str();
  app.add_option("--gnuplot", o.gnuplot, "gnuplot executable (default: gnuplot on PATH)");
  app.add_flag("--no-picture", o.no_picture, "no polar picture");
  app.add_flag("-q,--quiet", o.quiet, "no progress lines");
}

/// The shard and the seed from the command line; throws std::invalid_argument naming the option.
void settle_seed_and_shard(StudyDefinition& d, RunOptions& o) {
  if (o.supports == "double") d.sampling.single_fraction = 0.0;
  if (o.supports == "single") d.sampling.single_fraction = 1.0;
  if (!o.shard.empty() && !parse_shard(o.shard, o.shard_index, o.shard_count))
    throw std::invalid_argument("--shard '" + o.shard + "': expected I/N with 0 <= I < N");
  if (o.seed_text.empty()) {
    if (!o.shard.empty()) throw std::invalid_argument("--shard needs --seed (every shard draws from it)");
    d.seed = (static_cast<std::uint64_t>(std::random_device{}()) << 21) ^ std::random_device{}();
    return;
  }
  std::size_t used = 0;
  try {
    d.seed = std::stoull(o.seed_text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != o.seed_text.size() || o.seed_text[0] == '-')
    throw std::invalid_argument("--seed '" + o.seed_text + "': not a whole number");
}

/// The runs of this shard: drawn, or with --keep-push the bases' pushes as they are.
std::vector<Sample> samples_of_shard(const StudyDefinition& d, const Bases& bases,
                                     const RunOptions& o) {
  std::vector<Sample> samples;
  for (int i = o.shard_index; i < d.runs; i += o.shard_count) {
    Sample s = draw_sample(d.seed, i, d.sampling, bases.start[0]);
    if (d.keep_push) {
      const int k = s.support == "double" ? 0 : 1;
      s.direction_deg = s.height_m = 0.0;
      s.start_s = bases.start[k];
      s.duration_s = bases.push_duration[k];
      s.force_n = bases.push_force[k];
      s.impulse_ns = s.force_n * s.duration_s;
    }
    samples.push_back(s);
  }
  return samples;
}

void print_progress(const RunRecord& r, std::size_t done, std::size_t total, double elapsed_s) {
  const double left = elapsed_s / static_cast<double>(done) * static_cast<double>(total - done);
  std::fprintf(stderr,
               "[%5zu/%zu %6.0f s, %5.0f s left] #%d %s %5.1f deg %5.1f N s (%6.1f N x %.3f s, "
               "h %+.2f m): %s%s\n",
               done, total, elapsed_s, left, r.s.index, r.s.support.c_str(), r.s.direction_deg,
               r.s.impulse_ns, r.s.force_n, r.s.duration_s, r.s.height_m,
               r.survived ? "survived" : "FAILED ", r.survived ? "" : r.kind.c_str());
}

int run_study(StudyDefinition& d, const RunOptions& o) {
  d.base_double = fs::weakly_canonical(d.base_double).string();
  d.base_single = fs::weakly_canonical(d.base_single).string();
  const Bases bases = load_bases(d);
  const fs::path dir = o.output;
  const fs::path work = fs::absolute(dir / "runs");
  fs::create_directories(work);
  const std::vector<Sample> samples = samples_of_shard(d, bases, o);
  std::fprintf(stderr, "poise envelope random: seed %llu, %zu of %d runs%s%s, %d at a time -> %s\n",
               static_cast<unsigned long long>(d.seed), samples.size(), d.runs,
               o.shard.empty() ? "" : (" (shard " + o.shard + ")").c_str(),
               d.reality.empty() ? "" : (", reality " + d.reality).c_str(), o.jobs, dir.c_str());
  std::vector<RunRecord> records;
  const auto t0 = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  Pool pool(o.jobs, o.run_timeout, work);
  pool.run(samples, bases, d, [&](const RunRecord& r) {
    records.push_back(r);
    if (!r.survived)  // the scenario of a failed run, for `poise run` to re-run it
      std::ofstream(work / ("random_" + std::to_string(r.s.index) + ".yaml"))
          << emit(scenario_for(r.s, bases, d));
    if (!o.quiet) print_progress(r, records.size(), samples.size(), elapsed());
  });
  const std::string md =
      write_study(dir, records, d, o.shard, o.gnuplot, !o.no_picture && o.shard.empty());
  std::fprintf(stderr, "poise envelope random: %zu runs in %.0f s; %s\n", records.size(),
               elapsed(), (dir / "envelope.md").c_str());
  if (o.shard.empty()) std::fputs(md.c_str(), stdout);
  return 0;
}

}  // namespace

int random_main(int argc, char** argv) {
  StudyDefinition d;
  d.base_double = (fs::path(POISE_SOURCE_DIR) / "deploy/scenarios/forward_push_double_support.yaml").string();
  d.base_single = (fs::path(POISE_SOURCE_DIR) / "deploy/scenarios/lateral_push_single_support.yaml").string();
  d.runs = 200;
  RunOptions o;
  CLI::App app{
      "Balance envelope drawn at random: each run pushes once with a direction uniform on the "
      "circle, a height on the pushed link, a start time, a duration and an impulse drawn "
      "uniformly, in double or single support, with a fresh model draw per run under a reality "
      "profile. Reports survival against impulse with Wilson intervals, the impulse at 95 % "
      "survival (logistic fit, bootstrap interval), the worst directions and non-monotone "
      "bands (deploy/envelope/README.md \"The random study\")."};
  app.name("poise envelope random");
  add_random_options(app, d, o);
  POISE_CLI_PARSE(app, argc, argv);
  try {
    settle_seed_and_shard(d, o);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "poise envelope random: %s\n", e.what());
    return 2;
  }
  try {
    return run_study(d, o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise envelope random: %s\n", e.what());
    return 2;
  }
}

int merge_main(int argc, char** argv) {
  std::vector<std::string> inputs;
  std::string output = "results/envelope_random", gnuplot;
  bool no_picture = false;
  CLI::App app{"Merges the shards of a random study (`poise envelope random --shard I/N`) into "
               "one study: the same files and figures as the study run whole."};
  app.name("poise envelope merge");
  app.add_option("shards", inputs, "the shards' output directories")->required()->check(CLI::ExistingDirectory);
  app.add_option("--output-dir,-o", output, "where the merged study goes")->capture_default_str();
  app.add_option("--gnuplot", gnuplot, "gnuplot executable (default: gnuplot on PATH)");
  app.add_flag("--no-picture", no_picture, "no polar picture");
  POISE_CLI_PARSE(app, argc, argv);
  try {
    std::optional<StudyDefinition> def;
    Json first;
    std::vector<RunRecord> runs;
    for (const std::string& in : inputs) {
      const fs::path file = fs::path(in) / "study.json";
      Json j = Json::parse(std::ifstream(file), nullptr, false);
      if (!j.is_object()) throw std::runtime_error(file.string() + ": missing or unreadable");
      j.erase("shard");
      if (!def) {
        def = definition_from_json(j);
        first = j;
      } else if (j != first) {
        throw std::runtime_error(in + " is a shard of another study (its study.json differs from " +
                                 inputs.front() + "'s: seed, runs, bases or options)");
      }
      for (RunRecord& r : read_runs_csv(fs::path(in) / "runs.csv")) runs.push_back(std::move(r));
    }
    std::vector<int> seen(static_cast<std::size_t>(def->runs), 0);
    for (const RunRecord& r : runs) {
      if (r.s.index < 0 || r.s.index >= def->runs)
        throw std::runtime_error("run " + std::to_string(r.s.index) + " is outside the study's " +
                                 std::to_string(def->runs) + " runs");
      if (seen[static_cast<std::size_t>(r.s.index)]++)
        throw std::runtime_error("run " + std::to_string(r.s.index) + " is in two shards");
    }
    std::string missing;
    int n_missing = 0;
    for (std::size_t i = 0; i < seen.size(); ++i)
      if (!seen[i] && ++n_missing <= 10) missing += (missing.empty() ? "" : ", ") + std::to_string(i);
    if (n_missing > 0)
      throw std::runtime_error(std::to_string(n_missing) + " of " + std::to_string(def->runs) +
                               " runs are in no shard (" + missing + (n_missing > 10 ? ", ..." : "") +
                               "): merge every shard of the study");
    fs::create_directories(output);
    std::fputs(write_study(output, runs, *def, "", gnuplot, !no_picture).c_str(), stdout);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise envelope merge: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::envelope
