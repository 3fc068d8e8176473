// `poise run`: run a scenario. One command line for both modes (poise/launch/run_settings.hpp):
// the DDS-distributed run (the default) is poise::launch::run_distributed (deploy/launch);
// `--in-process` composes the libraries in this process (no DDS), here.
#include <signal.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "poise/inprocess/in_process_loop.hpp"
#include "poise/inprocess/loop_recording.hpp"
#include "poise/inprocess/run_result_json.hpp"
#include "poise/launch/deployment.hpp"
#include "poise/launch/log_dir.hpp"
#include "poise/launch/run_settings.hpp"
#include "poise/node/realtime.hpp"
#include "poise/sim/reality_json.hpp"

namespace poise::inprocess {
namespace {

namespace fs = std::filesystem;

std::atomic<bool> g_interrupted{false};
extern "C" void on_in_process_interrupt(int) {
  g_interrupted.store(true);
}

/// The files of the run: the log directory held (as the distributed run holds it, so that side
/// by side runs of one scenario take <scenario>.2.json and so on), the result and the recording.
struct RunFiles {
  std::optional<launch::LogDirLock> logs;
  fs::path output, recording;
};

RunFiles claim_files(const launch::RunSettings& s, const std::string& name) {
  RunFiles f;
  std::string suffix;
  f.logs.emplace(launch::claim_log_dir(s.log_dir, "results", name, &suffix));
  f.output = s.output.empty() ? fs::path("results") / (name + suffix + ".json") : fs::path(s.output);
  if (f.output.has_parent_path()) fs::create_directories(f.output.parent_path());
  fs::remove(f.output);  // a result from an earlier run must never stand for this one
  if (s.record_given)
    f.recording = s.record.empty() ? fs::path("results") / (name + suffix + ".mcap") : fs::path(s.record);
  return f;
}

LoopOptions loop_options(const launch::RunSettings& s, const scenario::Scenario& scenario) {
  LoopOptions opt;
  opt.state_source = s.ground_truth_state ? StateSource::kGroundTruth : StateSource::kEstimator;
  if (opt.state_source == StateSource::kEstimator && !estimator_available()) {
    std::cerr << "poise run: WARNING: the estimator library is not built; using the ground-truth "
                 "state (debug)\n";
    opt.state_source = StateSource::kGroundTruth;
  }
  if (!s.method.empty()) opt.contact_method = *contact::parse_method(s.method);
  opt.controller_config_file = s.controller_config;
  opt.duration = s.duration > 0.0 ? s.duration : 0.0;
  opt.settle_ticks = s.settle_ticks;
  opt.estimator = s.estimator.empty() ? scenario.estimator.type : s.estimator;
  opt.command_timeout_ms = s.command_timeout_ms;
  if (s.watchdog_ms > 0.0) opt.watchdog_ms = s.watchdog_ms;
  if (s.hold_s >= 0.0) opt.hold_s = s.hold_s;
  return opt;
}

/// --rt-priority, --cpus, --lock-memory for this process (the one thread that runs the loop).
nlohmann::json apply_realtime(const launch::RunSettings& s) {
  nlohmann::json j = nlohmann::json::object();
  if (!(s.rt_priority > 0 || s.lock_memory || !s.cpus.empty())) return j;
  const node::RealtimeReport r = node::apply_process_realtime(
      {.priority = s.rt_priority, .cpus = s.cpus, .lock_memory = s.lock_memory});
  for (const std::string& line : r.refused) std::fprintf(stderr, "  real time: %s\n", line.c_str());
  j["poise"] = {{"priority", s.rt_priority},
                {"cpus", s.cpus},
                {"lock_memory", s.lock_memory},
                {"applied", r.applied},
                {"refused", r.refused}};
  return j;
}

void print_start(const launch::RunSettings& s, const InProcessLoop& loop, const LoopOptions& opt,
                 const std::string& method) {
  if (const std::string unused = launch::dds_only_options(s); !unused.empty())
    std::cerr << "poise run: note: in process there is no DDS: " << unused << " has no effect\n";
  if (!s.quiet)
    std::cerr << "poise run: " << loop.scenario().name << " in process, " << loop.duration()
              << " s, " << (s.realtime ? "real time" : "lockstep") << ", state from "
              << to_string(opt.state_source)
              << (opt.state_source == StateSource::kEstimator ? " (" + opt.estimator + ")" : "")
              << ", contact method " << method << "\n";
  for (const std::string& w : loop.safety_warnings()) std::cerr << "  safety: " << w << "\n";
  if (!s.quiet && loop.scenario().sim.reality.enabled)
    std::cerr << "  " << sim::describe_reality(loop.result().reality) << "\n";
}

/// The wall-clock pacing of --realtime: tick k ends no earlier than start + (k + 1) dt.
class Pacer {
 public:
  Pacer(bool on, double dt) : on_(on), dt_ns_(static_cast<std::int64_t>(dt * 1e9)) {
    clock_gettime(CLOCK_MONOTONIC, &start_);
  }
  /// Sleeps until the end of tick `k` (counted from 0). Returns false when that end had passed.
  bool wait_end_of(std::int64_t k) {
    if (!on_) return true;
    const std::int64_t due = start_.tv_sec * 1000000000LL + start_.tv_nsec + (k + 1) * dt_ns_;
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    if (now.tv_sec * 1000000000LL + now.tv_nsec > due) return false;
    const timespec until{static_cast<time_t>(due / 1000000000LL), static_cast<long>(due % 1000000000LL)};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &until, nullptr);
    return true;
  }

 private:
  bool on_;
  std::int64_t dt_ns_;
  timespec start_{};
};

/// Steps the loop to its end (recording each tick, pacing it with --realtime, a progress line a
/// simulated second) unless interrupted or past the wall-clock bound. Returns "" or why it
/// stopped early; `overruns`: real-time ticks that ended after their deadline.
std::string step_to_end(const launch::RunSettings& s, InProcessLoop& loop, LoopRecording* rec,
                        std::uint64_t& overruns) {
  const double bound_s = s.timeout_s > 0 ? s.timeout_s
                                         : (s.realtime ? 60.0 + loop.duration()
                                                       : 60.0 + 30.0 * loop.duration());
  const auto t_start = std::chrono::steady_clock::now();
  Pacer pacer(s.realtime, loop.simulator().dt());
  double next_report = 1.0;
  for (std::int64_t k = 0; !loop.done(); ++k) {
    if (rec) rec->before_step();
    loop.step();
    if (rec) rec->after_step();
    if (!pacer.wait_end_of(k)) ++overruns;
    if (!s.quiet && loop.time() >= next_report - 0.5 * loop.simulator().dt()) {
      const RunResult p = loop.result();
      std::fprintf(stderr, "  t = %5.1f s  CoM error %.4f m (max %.4f)  tick p50 %.1f us\n",
                   loop.time(), p.com_error_final_m, p.com_error_max_m, p.tick_latency_us.p50_us);
      next_report += 1.0;
    }
    if (g_interrupted.load()) return "interrupted";
    if (std::chrono::steady_clock::now() - t_start > std::chrono::duration<double>(bound_s))
      return "timeout: the run took more than " + std::to_string(bound_s) + " s";
  }
  return "";
}

void print_verdict(const RunResult& r) {
  std::string why;
  for (const auto& f : r.failed) why += (why.empty() ? " on " : "; ") + f;
  std::printf(
      "%s: %s%s  (CoM error max %.4f m, final %.4f m; foot slip %.4f m, tilt %.1f deg; "
      "non-foot contacts %d; trunk pitch/roll max %.1f/%.1f deg; tick p50 %.1f us p99 %.1f us; "
      "%llu deadline misses; x%.2f real time; state %s)\n",
      r.scenario.c_str(), r.survived ? "SURVIVED" : "FAILED", why.c_str(), r.com_error_max_m,
      r.com_error_final_m, r.foot_slip_max_m, r.foot_tilt_max_deg, r.non_foot_contacts,
      r.trunk_pitch_max_deg, r.trunk_roll_max_deg, r.tick_latency_us.p50_us,
      r.tick_latency_us.p99_us, static_cast<unsigned long long>(r.deadline_misses),
      r.realtime_factor, to_string(r.state_source));
}

/// `poise run --in-process`, parsed. Returns the exit status: 0 survived, 1 failed the
/// scenario's criteria, 2 could not run (or the recording failed), 130 interrupted.
int run_in_process(launch::RunSettings& s) {
  s.scenario = launch::resolve_scenario(s.scenario);
  const scenario::Scenario scenario = scenario::load_scenario(s.scenario);
  const RunFiles files = claim_files(s, scenario.name);
  const LoopOptions opt = loop_options(s, scenario);
  const nlohmann::json realtime = apply_realtime(s);
  InProcessLoop loop(scenario, opt);
  RunFacts facts;
  facts.method = contact::to_string(contact_method_of(scenario, opt));
  facts.estimator = opt.estimator;
  facts.realtime = s.realtime;
  facts.realtime_settings = realtime;
  print_start(s, loop, opt, facts.method);
  std::unique_ptr<LoopRecording> rec;
  if (!files.recording.empty()) rec = std::make_unique<LoopRecording>(files.recording, loop);
  ::signal(SIGINT, on_in_process_interrupt);
  ::signal(SIGTERM, on_in_process_interrupt);
  const auto t0 = std::chrono::steady_clock::now();
  const std::string stopped = step_to_end(s, loop, rec.get(), facts.overruns);
  RunResult r = loop.result();
  // The run's wall time, paced ticks and recording included (the loop's own counts its ticks).
  r.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.realtime_factor = r.wall_time_s > 0.0 ? r.sim_time_s / r.wall_time_s : 0.0;
  if (!stopped.empty()) {
    r.survived = false;
    r.completed = false;
    r.failed.push_back(stopped);
  }
  if (rec) {
    facts.recording = rec->file().string();
    facts.recording_error = rec->close();
    if (!s.quiet && facts.recording_error.empty())
      std::printf("  recorded: %llu messages to %s\n",
                  static_cast<unsigned long long>(rec->messages()), facts.recording.c_str());
  }
  print_verdict(r);
  write_result_file(files.output, to_json(r, loop, facts));
  if (!facts.recording_error.empty()) {
    std::fprintf(stderr, "poise run: the recording failed: %s\n", facts.recording_error.c_str());
    return 2;
  }
  if (stopped == "interrupted") return 130;
  if (!stopped.empty()) return 2;
  return r.survived ? 0 : 1;
}

}  // namespace

int cli_main(int argc, char** argv) {
  launch::RunSettings s;
  if (const int code = launch::parse_run_settings(argc, argv, s); code >= 0) return code;
  if (!s.in_process) return launch::run_distributed(s);
  try {
    return run_in_process(s);
  } catch (const std::exception& e) {
    std::cerr << "poise run: " << e.what() << "\n";
    return 2;
  }
}

}  // namespace poise::inprocess
