#include "poise/node/node.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "poise/reflect/json.hpp"

namespace poise::node {
namespace fs = std::filesystem;

std::string default_robot_config() {
  const fs::path rel = "deploy/robots/poise_humanoid/robot.yaml";
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    for (fs::path dir = exe.parent_path(); !dir.empty() && dir != dir.root_path();
         dir = dir.parent_path()) {
      if (fs::exists(dir / rel)) return (dir / rel).string();
    }
  }
#ifdef POISE_SOURCE_DIR
  if (fs::exists(fs::path(POISE_SOURCE_DIR) / rel))
    return (fs::path(POISE_SOURCE_DIR) / rel).string();
#endif
  return rel.string();
}

void add_node_options(CLI::App& app, NodeOptions& options, const std::string& kind) {
  options.name = kind;
  app.add_option("--name", options.name, "node name in logs and diagnostics")
      ->capture_default_str();
  app.add_option("--robot", options.robot,
                 "robot configuration YAML (its URDF beside it). Default: none, the robot comes "
                 "from poise/robot_description (configuration + URDF). Given, it must be that "
                 "robot (the node refuses to run and names what differs); needed only for a "
                 "driver whose description carries no robot configuration")
      ->check(CLI::ExistingFile);
  app.add_option("--summary", options.summary,
                 "write a JSON summary (last diagnostics and node figures) to this file at exit");
  app.add_option("--diagnostics-hz", options.diagnostics_hz, "diagnostics publication rate [Hz]")
      ->check(CLI::Range(0.1, 1000.0))
      ->capture_default_str();
  app.add_option("--output-readers", options.output_readers,
                 "before taking its first input, wait until each per-tick output topic has this "
                 "many matched readers (a launcher that records: consumer + recorder; 0: no wait)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--output-readers-timeout-ms", options.output_readers_timeout_ms,
                 "longest wait for --output-readers")
      ->check(CLI::Range(0, 600000))
      ->capture_default_str();
  dds::add_dds_options(app, options.dds);
  add_realtime_options(app, options.rt);
}

void add_input_options(CLI::App& app, NodeOptions& options) {
  app.add_option("--input-stale-ms", options.input_stale_ms,
                 "report the per-tick input stale (health FAULT) after this long without a sample")
      ->check(CLI::Range(1.0, 600000.0))
      ->capture_default_str();
  app.add_option("--max-tick-jump", options.ticks.max_jump,
                 "largest forward tick step taken as the next tick; larger jumps and regressions "
                 "are out of sequence (rejected unless they restart the stream)")
      ->check(CLI::Range(1, 1000000000))
      ->capture_default_str();
  app.add_option("--restart-confirm", options.ticks.confirm,
                 "consecutive out-of-sequence ticks that confirm a restarted input stream")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  double silence_ms = static_cast<double>(options.ticks.restart_silence_ns) * 1e-6;
  app.add_option_function<double>(
         "--restart-silence-ms",
         [&options](double ms) {
           options.ticks.restart_silence_ns = static_cast<std::int64_t>(ms * 1e6);
         },
         "silence of the accepted input stream after which a new stream is followed at once")
      ->check(CLI::Range(0.0, 600000.0))
      ->default_str(std::to_string(static_cast<int>(silence_ms)));
}

Node::Node(const NodeOptions& options) : options_(options) {
  dds::set_log_name(options_.name);
  install_shutdown_handlers();
  options_.dds.participant_name = "poise/" + options_.name;
  // Under DDS Security a node authenticates as its name unless told otherwise.
  if (!options_.dds.security_dir.empty() && options_.dds.identity.empty())
    options_.dds.identity = options_.name;
  // Real-time settings first: the participant's threads inherit policy and affinity.
  const RealtimeReport rt = apply_process_realtime(options_.rt);
  for (const std::string& line : rt.applied) dds::log(dds::LogLevel::info, "real time: %s", line.c_str());
  for (const std::string& line : rt.refused) dds::log(dds::LogLevel::warn, "real time: %s", line.c_str());
  rt_applied_ = rt.applied;
  rt_refused_ = rt.refused;
  participant_ = std::make_unique<dds::Participant>(options_.dds);
  if (rt.priority_applied) {
    const int demoted =
        demote_housekeeping_threads(participant_->vendor() == dds::Vendor::cyclone ? 2 : 0);
    if (demoted > 0)
      dds::log(dds::LogLevel::info,
               "real time: %d DDS housekeeping thread(s) (discovery, garbage collection) back to "
               "normal scheduling", demoted);
  }
  diag_pub_ = std::make_unique<dds::Publisher<msg::Diagnostics>>(*participant_);
  diag_.node(options_.name.substr(0, 32));
  diag_.dds_vendor(std::string(dds::to_string(participant_->vendor())));
  period_ns_ = static_cast<std::int64_t>(1e9 / options_.diagnostics_hz);
  next_diag_ns_ = now_ns() + period_ns_;
  dds::log(dds::LogLevel::info, "%s on %s, domain %d", options_.name.c_str(),
           std::string(dds::to_string(participant_->vendor())).c_str(), participant_->domain_id());
}

Node::~Node() = default;

void Node::tick_done(std::uint64_t tick, std::int64_t compute_ns) noexcept {
  // Page faults in the loop: sampled at the first tick and then once every 1000 ticks (one
  // getrusage call a second at 1 kHz), so that the summary's own allocations are not counted.
  if (ticks_ == 0) faults_at_first_tick_ = page_faults();
  if (ticks_ % 1000 == 0) faults_in_loop_ = page_faults();
  last_tick_ = tick;
  ++ticks_;
  compute_.add(static_cast<double>(compute_ns) * 1e-3);
  compute_run_.add(static_cast<double>(compute_ns) * 1e-3);
  tick_dds_write_ns_ = 0;
}

void Node::tick_done(std::uint64_t tick, std::int64_t compute_ns,
                     std::int64_t library_ns) noexcept {
  const std::int64_t dds_write_ns = tick_dds_write_ns_;
  tick_done(tick, compute_ns);
  library_run_.add(static_cast<double>(library_ns) * 1e-3);
  dds_write_run_.add(static_cast<double>(dds_write_ns) * 1e-3);
  overhead_run_.add(static_cast<double>(compute_ns - library_ns - dds_write_ns) * 1e-3);
}

void Node::error(const char* format, ...) noexcept {
  ++errors_;
  va_list args;
  va_start(args, format);
  std::vsnprintf(last_error_, sizeof(last_error_), format, args);
  va_end(args);
  error_since_diag_ = true;
  const std::int64_t now = now_ns();
  if (now - last_log_ns_ < 1'000'000'000) {
    ++suppressed_logs_;
    return;
  }
  last_log_ns_ = now;
  if (suppressed_logs_)
    dds::log(dds::LogLevel::warn, "%s (%llu more errors since the last line)", last_error_,
             static_cast<unsigned long long>(suppressed_logs_));
  else
    dds::log(dds::LogLevel::warn, "%s", last_error_);
  suppressed_logs_ = 0;
}

std::int64_t Node::poll() noexcept {
  const std::int64_t now = now_ns();
  if (now >= next_diag_ns_) {
    publish_diagnostics();
    next_diag_ns_ += period_ns_;
    if (next_diag_ns_ <= now) next_diag_ns_ = now + period_ns_;
  }
  return next_diag_ns_;
}

void Node::serve(std::mutex& state_mutex) noexcept {
  while (running()) {
    std::int64_t next = 0;
    {
      std::lock_guard lock(state_mutex);
      next = poll();
    }
    // A shutdown signal may go to another thread: wake at least every 50 ms to notice it.
    sleep_until_ns(std::min(next, now_ns() + 50'000'000));
  }
}

int Node::expect_input(const std::string& topic, double stale_ms) {
  if (num_inputs_ >= kMaxInputs) throw std::runtime_error("too many inputs for one node");
  Input& in = inputs_[static_cast<std::size_t>(num_inputs_)];
  in.topic = topic;
  in.stale_ns = static_cast<std::int64_t>(stale_ms * 1e6);
  return num_inputs_++;
}

void Node::input_seen(int id, std::uint64_t tick) noexcept {
  if (id < 0 || id >= num_inputs_) return;
  Input& in = inputs_[static_cast<std::size_t>(id)];
  in.last_tick.store(tick, std::memory_order_relaxed);
  in.last_ns.store(now_ns(), std::memory_order_relaxed);
}

bool Node::input_stale(int id) const noexcept {
  return id >= 0 && id < num_inputs_ && inputs_[static_cast<std::size_t>(id)].stale;
}

void Node::set_condition(msg::NodeHealth health, const char* text) noexcept {
  if (text == condition_) return;
  if (text)
    dds::log(health == msg::HEALTH_FAULT ? dds::LogLevel::error : dds::LogLevel::warn, "%s",
             text);
  else if (condition_)
    dds::log(dds::LogLevel::info, "cleared: %s", condition_);
  condition_ = text;
  condition_health_ = text ? health : msg::HEALTH_OK;
}

void Node::publish_diagnostics() noexcept {
  const std::int64_t now = now_ns();
  bool any_stale = false;
  // An error since the last sample (e.g. every sample of an input rejected) is the likely cause
  // of a stale input: keep it in the stale message, or the reason would never reach the wire.
  char newest_error[sizeof(last_error_)] = {};
  if (error_since_diag_) std::snprintf(newest_error, sizeof(newest_error), "%s", last_error_);
  error_since_diag_ = false;
  for (int i = 0; i < num_inputs_; ++i) {
    Input& in = inputs_[static_cast<std::size_t>(i)];
    const std::int64_t last = in.last_ns.load(std::memory_order_relaxed);
    const bool stale = last != 0 && now - last > in.stale_ns;
    const auto tick = static_cast<unsigned long long>(in.last_tick.load(std::memory_order_relaxed));
    if (stale) {
      any_stale = true;
      std::snprintf(last_error_, sizeof(last_error_),
                    "no %s for %.0f ms (last tick %llu): input stale%s%s", in.topic.c_str(),
                    static_cast<double>(now - last) * 1e-6, tick,
                    newest_error[0] ? "; newest error: " : "", newest_error);
      if (!in.stale) {  // a state, not an error: counted as stale_events, health FAULT
        ++stale_events_;
        dds::log(dds::LogLevel::error, "%s: FAULT", last_error_);
      }
    } else if (in.stale) {
      dds::log(dds::LogLevel::info, "%s back (tick %llu): input fresh again", in.topic.c_str(),
               tick);
    }
    in.stale = stale;
  }
  for (auto& w : single_writers_) {
    const int n = participant_->writers_of(w.topic);
    if (n > 1 && n != w.reported) {
      ++extra_writer_events_;
      error("%s has %d writers, one expected: another process publishes this node's input, "
            "or a killed one's writer is still listed until its DDS lease expires "
            "(`poise topic list` shows the writers)",
            w.topic.c_str(), n);
    }
    w.reported = n;
  }
  std::uint64_t rejected = 0, mismatches = participant_->type_mismatches();
  for (auto& w : watched_) {
    const std::uint64_t r = w.counters->rejected.load() + w.counters->deserialize_errors.load();
    if (r != w.seen && !any_stale) {  // newest rejection reason (rare: allocation tolerated)
      try {
        const std::string why = w.last_error();
        std::snprintf(last_error_, sizeof(last_error_), "%s", why.c_str());
      } catch (...) {
      }
    }
    w.seen = r;
    rejected += r;
  }
  if (condition_ && !any_stale) std::snprintf(last_error_, sizeof(last_error_), "%s", condition_);
  const WindowStats w = compute_.window();
  diag_.header().tick(last_tick_);
  msg::NodeHealth health =
      errors_ || rejected || deadline_misses_ ? msg::HEALTH_DEGRADED : msg::HEALTH_OK;
  health = std::max(health, health_);
  health = std::max(health, condition_health_);
  if (any_stale) health = msg::HEALTH_FAULT;
  diag_.health(health);
  diag_.heartbeat(diag_.heartbeat() + 1);
  diag_.ticks(ticks_);
  diag_.compute_us_p50(w.p50);
  diag_.compute_us_p99(w.p99);
  diag_.compute_us_max(w.max);
  diag_.deadline_misses(deadline_misses_);
  diag_.rejected_samples(rejected);
  diag_.type_mismatches(mismatches);
  diag_.errors(errors_);
  diag_.last_error() = last_error_;
  diag_pub_->publish(diag_);
}

void Node::write_summary(const std::string& extra_json) {
  if (options_.summary.empty()) return;
  try {
    publish_diagnostics();
    nlohmann::json j;
    j["node"] = options_.name;
    j["diagnostics"] = reflect::to_json(diag_);
    j["compute_us_max_all"] = compute_.max_all();
    j["compute_us_run"] = {{"p50", compute_run_.percentile(0.5)},
                           {"p99", compute_run_.percentile(0.99)},
                           {"max", compute_run_.max()},
                           {"mean", compute_run_.mean()},
                           {"count", compute_run_.count()}};
    if (library_run_.count() > 0) {
      auto hist = [](const LatencyHistogram& h) {
        return nlohmann::json{{"p50", h.percentile(0.5)}, {"p99", h.percentile(0.99)},
                              {"max", h.max()},           {"mean", h.mean()},
                              {"count", h.count()}};
      };
      j["library_us_run"] = hist(library_run_);
      j["overhead_us_run"] = hist(overhead_run_);  // the node's own work, DDS write excluded
      j["dds_write_us_run"] = hist(dds_write_run_);
    }
    j["non_finite_refused"] = non_finite_;
    {
      // What the node called stale and how often (a launcher sets these per mode).
      nlohmann::json inputs = nlohmann::json::array();
      for (int i = 0; i < num_inputs_; ++i) {
        const Input& in = inputs_[static_cast<std::size_t>(i)];
        inputs.push_back({{"topic", in.topic}, {"stale_ms", static_cast<double>(in.stale_ns) * 1e-6}});
      }
      j["inputs"] = inputs;
      j["stale_events"] = stale_events_;
    }
    {
      nlohmann::json rt;
      rt["priority"] = options_.rt.priority;
      rt["cpus"] = options_.rt.cpus;
      rt["lock_memory"] = options_.rt.lock_memory;
      rt["applied"] = rt_applied_;
      rt["refused"] = rt_refused_;
      rt["threads"] = describe_threads();
      if (ticks_ > 1000) {
        rt["page_faults_in_loop"] = {
            {"minor", faults_in_loop_.minor - faults_at_first_tick_.minor},
            {"major", faults_in_loop_.major - faults_at_first_tick_.major},
            {"ticks", (ticks_ - 1) / 1000 * 1000}};
      }
      j["realtime"] = rt;
    }
    if (!extra_json.empty()) {
      const auto extra = nlohmann::json::parse(extra_json);
      for (auto it = extra.begin(); it != extra.end(); ++it)
        j[it.key()] = it.value();
    }
    const std::string tmp = options_.summary + ".tmp";
    {
      std::ofstream out(tmp);
      out << j.dump(2) << "\n";
    }
    std::filesystem::rename(tmp, options_.summary);
  } catch (const std::exception& e) {
    dds::log(dds::LogLevel::error, "cannot write the summary %s: %s", options_.summary.c_str(),
             e.what());
  }
}

}  // namespace poise::node
