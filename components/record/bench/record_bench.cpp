// poise-bench-record: what `poise record` costs and sustains, measured in one run.
//
//   poise-bench-record [--seconds S] [--dir DIR] [--skip-latency] [--long-minutes M] ...
//
//  1. Disk: raw write speed of the recording directory (1 MiB blocks, fdatasync at the end, and
//     fdatasync after every block as the recorder does after every chunk).
//  2. Throughput: a publisher process (this program, hidden --publisher role) publishes one sample
//     of every per-tick Poise topic type per tick at 1 kHz (RobotDescription once, latched), with
//     seeded random contents (poise::reflect::fill_random), on a private DDS domain, while
//     `poise record` records it; per compression (zstd, lz4, none): messages/s, MB/s, file size,
//     compression ratio, recorder CPU, drops and losses. Then the same flat out (saturation).
//  3. Latency cost: `poise run standing --realtime` with and without --record, alternated, and
//     the tick latency, deadline misses and damping ticks of each.
//  4. Optionally (--long-minutes M) a long real-time run with --record: lost samples, file size,
//     recorder CPU and memory.
// Progress goes to stderr, figures to stdout. Every child is started by this program, bounded in
// time, and ended by its pid (SIGTERM, then SIGKILL) on every way out.
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <poise/msg/balance_reference.h>
#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/diagnostics.h>
#include <poise/msg/disturbance.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>
#include <nlohmann/json.hpp>
#include <poise/dds/dds.hpp>
#include <poise/dds/domain_claim.hpp>
#include <poise/reflect/fill.hpp>

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

void progress(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
void progress(const char* fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  std::fputs("[bench-record] ", stderr);
  std::vfprintf(stderr, fmt, ap);
  std::fputc('\n', stderr);
  va_end(ap);
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

fs::path self_exe() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw std::runtime_error("cannot read /proc/self/exe");
  return exe;
}

// ------------------------------------------------------------------------------------------------
// Children: started by fork+exec, stdout/stderr to files, killed by pid on every way out.

constexpr int kMaxChildren = 32;
volatile sig_atomic_t g_child_pids[kMaxChildren] = {};

void register_pid(pid_t pid) {
  for (auto& slot : g_child_pids)
    if (slot == 0) {
      slot = pid;
      return;
    }
}
void unregister_pid(pid_t pid) {
  for (auto& slot : g_child_pids)
    if (slot == pid) slot = 0;
}

extern "C" void bench_on_signal(int sig) {
  // Async-signal-safe: kill, waitpid, nanosleep, _exit.
  for (auto& slot : g_child_pids)
    if (slot > 0) ::kill(static_cast<pid_t>(slot), SIGTERM);
  for (int i = 0; i < 300; ++i) {  // up to 3 s
    bool any = false;
    for (auto& slot : g_child_pids) {
      if (slot <= 0) continue;
      if (::waitpid(static_cast<pid_t>(slot), nullptr, WNOHANG) != 0)
        slot = 0;
      else
        any = true;
    }
    if (!any) break;
    const timespec ts{0, 10'000'000};
    ::nanosleep(&ts, nullptr);
  }
  for (auto& slot : g_child_pids)
    if (slot > 0) ::kill(static_cast<pid_t>(slot), SIGKILL);
  ::_exit(128 + sig);
}

class Child {
 public:
  Child(std::string name, const std::vector<std::string>& argv, const fs::path& log_dir)
      : name_(std::move(name)),
        out_(log_dir / (name_ + ".stdout")),
        err_(log_dir / (name_ + ".stderr")) {
    std::vector<char*> args;
    for (const auto& a : argv)
      args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    const int out_fd = ::open(out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    const int err_fd = ::open(err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (out_fd < 0 || err_fd < 0)
      throw std::runtime_error("cannot create logs in " + log_dir.string());
    const pid_t parent = ::getpid();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed: " + std::string(std::strerror(errno)));
    if (pid_ == 0) {
      // Own process group (the bench ends it in order); SIGTERM if the bench dies.
      ::setpgid(0, 0);
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      if (::getppid() != parent) ::_exit(127);
      ::dup2(out_fd, 1);
      ::dup2(err_fd, 2);
      ::execv(args[0], args.data());
      ::_exit(127);
    }
    ::close(out_fd);
    ::close(err_fd);
    register_pid(pid_);
    started_ = Clock::now();
  }
  ~Child() { stop(3000); }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  pid_t pid() const { return pid_; }
  const fs::path& stdout_path() const { return out_; }
  const fs::path& stderr_path() const { return err_; }
  const rusage& usage() const { return usage_; }
  bool running() { return !poll().has_value(); }

  /// Exit code (128 + signal) once ended, else nullopt. Non-blocking.
  std::optional<int> poll() {
    if (code_ || pid_ <= 0) return code_;
    int status = 0;
    rusage ru{};
    const pid_t r = ::wait4(pid_, &status, WNOHANG, &ru);
    if (r == pid_) {
      usage_ = ru;
      code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      unregister_pid(pid_);
    } else if (r < 0) {
      code_ = -1;
      unregister_pid(pid_);
    }
    return code_;
  }
  /// Waits for the end up to `timeout_s`; nullopt if still running.
  std::optional<int> wait(double timeout_s) {
    const auto t0 = Clock::now();
    while (running()) {
      if (seconds_since(t0) >= timeout_s) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return code_;
  }
  /// SIGTERM, wait up to `grace_ms`, SIGKILL. The exit code.
  int stop(int grace_ms) {
    if (pid_ <= 0) return -1;
    if (!running()) return *code_;
    ::kill(pid_, SIGTERM);
    if (auto c = wait(grace_ms * 1e-3)) return *c;
    progress("%s (pid %d) did not stop within %d ms: SIGKILL", name_.c_str(), pid_, grace_ms);
    ::kill(pid_, SIGKILL);
    if (auto c = wait(10.0)) return *c;
    return -1;
  }

 private:
  std::string name_;
  fs::path out_, err_;
  pid_t pid_ = -1;
  std::optional<int> code_;
  rusage usage_{};
  Clock::time_point started_;
};

double cpu_seconds(const rusage& ru) {
  return static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
         (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
}

/// utime + stime of a live process in seconds, and its parent; nullopt when gone.
struct ProcStat {
  double cpu_s = 0;
  pid_t ppid = 0;
};
std::optional<ProcStat> proc_stat(pid_t pid) {
  const std::string s = slurp("/proc/" + std::to_string(pid) + "/stat");
  const auto close = s.rfind(')');
  if (close == std::string::npos) return std::nullopt;
  std::istringstream in(s.substr(close + 2));
  std::vector<std::string> f;
  for (std::string t; in >> t;)
    f.push_back(t);
  if (f.size() < 13) return std::nullopt;
  // After the command: state(3) ppid(4) ... utime(14) stime(15).
  ProcStat p;
  p.ppid = static_cast<pid_t>(std::stol(f[1]));
  const double tick = static_cast<double>(::sysconf(_SC_CLK_TCK));
  p.cpu_s = (std::stod(f[11]) + std::stod(f[12])) / tick;
  return p;
}

/// VmHWM (peak resident set) of a live process in MB, or 0.
double peak_rss_mb(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;
  return 0;
}

/// A child of `parent` whose command line holds the argument `arg` (the recorder of `poise run`).
pid_t find_child_with_arg(pid_t parent, const std::string& arg) {
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.empty() || name.find_first_not_of("0123456789") != std::string::npos) continue;
    const pid_t pid = static_cast<pid_t>(std::stol(name));
    const auto st = proc_stat(pid);
    if (!st || st->ppid != parent) continue;
    const std::string cmd = slurp(e.path() / "cmdline");
    std::size_t at = 0;
    while (at < cmd.size()) {
      const std::size_t end = cmd.find('\0', at);
      if (cmd.substr(at, end - at) == arg) return pid;
      if (end == std::string::npos) break;
      at = end + 1;
    }
  }
  return 0;
}

/// Samples the CPU time and peak memory of one process while it lives.
struct CpuSampler {
  pid_t pid = 0;
  bool have_first = false;
  double first_cpu = 0, last_cpu = 0, peak_mb = 0;
  Clock::time_point first_t, last_t;
  void sample() {
    if (pid <= 0) return;
    const auto st = proc_stat(pid);
    if (!st) return;
    const auto now = Clock::now();
    if (!have_first) {
      have_first = true;
      first_cpu = st->cpu_s;
      first_t = now;
    }
    last_cpu = st->cpu_s;
    last_t = now;
    peak_mb = std::max(peak_mb, peak_rss_mb(pid));
  }
  double window_s() const { return std::chrono::duration<double>(last_t - first_t).count(); }
  double percent() const {
    return window_s() > 0 ? 100.0 * (last_cpu - first_cpu) / window_s() : 0.0;
  }
};

// ------------------------------------------------------------------------------------------------
// Publisher role.

using PerTickTypes = std::tuple<poise::msg::Sensors, poise::msg::GroundTruth, poise::msg::State,
                                poise::msg::BalanceReference, poise::msg::ContactProblem,
                                poise::msg::ContactSolution, poise::msg::JointCommand,
                                poise::msg::Disturbance, poise::msg::Diagnostics>;

template <class F>
void for_each_per_tick_type(F&& f) {
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (f(std::integral_constant<std::size_t, I>{}), ...);
  }
  (std::make_index_sequence<std::tuple_size_v<PerTickTypes>>{});
}

struct Stream {
  std::string topic;
  std::function<bool(std::uint64_t tick, std::size_t& bytes)> publish;
  std::function<bool(std::chrono::nanoseconds)> wait_matched;
  std::uint64_t published = 0, failed = 0, bytes = 0;
  std::size_t sample_bytes_min = SIZE_MAX, sample_bytes_max = 0;
};

/// A stream cycling through `pool` distinct random samples (no repeat within a 1 MiB chunk, so
/// the compressors see realistic, not repeated, bytes).
template <class T>
Stream make_stream(poise::dds::Participant& participant, std::uint64_t seed, std::size_t index,
                   std::size_t pool) {
  auto pub = std::make_shared<poise::dds::Publisher<T>>(participant);
  auto samples = std::make_shared<std::vector<T>>(pool);
  auto sizes = std::make_shared<std::vector<std::size_t>>(pool);
  std::mt19937_64 rng(seed * 1000003u + index);
  for (std::size_t k = 0; k < pool; ++k) {
    poise::reflect::fill_random((*samples)[k], rng);
    (*sizes)[k] = poise::dds::TopicTraits<T>::type_support().serialized_size(&(*samples)[k]);
  }
  Stream s;
  s.topic = std::string(poise::dds::TopicTraits<T>::topic_name);
  s.publish = [pub, samples, sizes](std::uint64_t tick, std::size_t& bytes) {
    const std::size_t k = tick % samples->size();
    T& sample = (*samples)[k];
    sample.header().tick(tick);
    sample.header().stamp_ns(static_cast<std::int64_t>(tick) * 1'000'000);
    bytes = (*sizes)[k];
    return pub->publish(sample);
  };
  s.wait_matched = [pub](std::chrono::nanoseconds t) { return pub->wait_for_matches(1, t); };
  for (auto n : *sizes) {
    s.sample_bytes_min = std::min(s.sample_bytes_min, n);
    s.sample_bytes_max = std::max(s.sample_bytes_max, n);
  }
  return s;
}

int publisher_main(int domain, double rate_hz, double seconds, std::uint64_t seed, std::size_t pool,
                   const std::string& out) {
  poise::dds::DdsOptions options = poise::dds::dds_options_from_env();
  options.domain_id = domain;
  options.participant_name = "poise-bench-record-publisher";
  poise::dds::Participant participant(options);
  std::vector<Stream> streams;
  // RobotDescription: once, latched (its default QoS), like the simulator.
  poise::dds::Publisher<poise::msg::RobotDescription> description_pub(participant);
  poise::msg::RobotDescription description;
  {
    std::mt19937_64 rng(seed * 1000003u + 99);
    poise::reflect::fill_random(description, rng);
    description.header().tick(0);
  }
  for_each_per_tick_type([&](auto index) {
    using T = std::tuple_element_t<decltype(index)::value, PerTickTypes>;
    streams.push_back(make_stream<T>(participant, seed, index, pool));
  });
  const auto match_timeout = std::chrono::seconds(20);
  if (!description_pub.wait_for_matches(1, match_timeout)) {
    std::fprintf(stderr, "publisher: no reader on poise/robot_description within 20 s\n");
    return 3;
  }
  for (auto& s : streams)
    if (!s.wait_matched(match_timeout)) {
      std::fprintf(stderr, "publisher: no reader on %s within 20 s\n", s.topic.c_str());
      return 3;
    }
  // Matched here does not yet mean the reader has matched this writer (discovery is not
  // symmetric in time): a volatile sample written in between is never delivered. Let it settle.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const std::size_t description_bytes =
      poise::dds::TopicTraits<poise::msg::RobotDescription>::type_support().serialized_size(
          &description);
  const bool description_ok = description_pub.publish(description);

  std::printf("PUBLISHING\n");
  std::fflush(stdout);
  const auto start = Clock::now();
  const auto period = std::chrono::duration<double>(rate_hz > 0 ? 1.0 / rate_hz : 0.0);
  std::uint64_t ticks = 0, late_ticks = 0;
  double max_late_us = 0;
  for (std::uint64_t tick = 1;; ++tick) {
    if (rate_hz > 0) {
      const auto due = start + std::chrono::duration_cast<Clock::duration>(
                                   period * static_cast<double>(tick - 1));
      std::this_thread::sleep_until(due);
      const double late_us = std::chrono::duration<double, std::micro>(Clock::now() - due).count();
      max_late_us = std::max(max_late_us, late_us);
      if (late_us > 1000) ++late_ticks;
    }
    if (seconds_since(start) >= seconds) break;
    for (auto& s : streams) {
      std::size_t bytes = 0;
      if (s.publish(tick, bytes)) {
        ++s.published;
        s.bytes += bytes;
      } else {
        ++s.failed;
      }
    }
    ticks = tick;
  }
  const double elapsed = seconds_since(start);
  std::printf("DONE\n");
  std::fflush(stdout);
  // Let reliable retransmissions finish before the writers go away.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));

  Json j;
  j["ticks"] = ticks;
  j["seconds"] = elapsed;
  j["rate_hz"] = rate_hz;
  j["late_ticks"] = late_ticks;
  j["max_late_us"] = max_late_us;
  j["published"]["poise/robot_description"] = description_ok ? 1 : 0;
  j["bytes"]["poise/robot_description"] = description_bytes;
  j["sample_bytes"]["poise/robot_description"] = {description_bytes, description_bytes};
  for (const auto& s : streams) {
    j["published"][s.topic] = s.published;
    j["failed"][s.topic] = s.failed;
    j["bytes"][s.topic] = s.bytes;
    j["sample_bytes"][s.topic] = {s.sample_bytes_min, s.sample_bytes_max};
  }
  std::ofstream(out) << j.dump(2) << "\n";
  return 0;
}

// ------------------------------------------------------------------------------------------------
// Disk.

struct DiskResult {
  double sync_end_mb_s = 0;    ///< fdatasync once at the end
  double sync_block_mb_s = 0;  ///< fdatasync after every 1 MiB
  double sync_block_ms = 0;    ///< mean time of one write + fdatasync of 1 MiB
  std::size_t mb_end = 0, mb_block = 0;
};

/// Writes up to `mib` MiB in 1 MiB blocks (at most `cap_s` seconds); MB/s incl. the final sync.
double disk_write(const fs::path& file, std::size_t mib, bool sync_each, double cap_s,
                  std::size_t& written_mib) {
  std::vector<std::uint8_t> block(1 << 20);
  std::mt19937_64 rng(42);
  for (std::size_t i = 0; i + 8 <= block.size(); i += 8) {
    const std::uint64_t v = rng();
    std::memcpy(&block[i], &v, 8);
  }
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error("cannot create " + file.string());
  const auto t0 = Clock::now();
  written_mib = 0;
  for (std::size_t k = 0; k < mib; ++k) {
    block[0] = static_cast<std::uint8_t>(k);  // no two blocks alike
    std::size_t done = 0;
    while (done < block.size()) {
      const ssize_t n = ::write(fd, block.data() + done, block.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        ::close(fd);
        throw std::runtime_error("write " + file.string() + ": " + std::strerror(errno));
      }
      done += static_cast<std::size_t>(n);
    }
    if (sync_each) ::fdatasync(fd);
    ++written_mib;
    if (seconds_since(t0) > cap_s) break;
  }
  ::fdatasync(fd);
  const double s = seconds_since(t0);
  ::close(fd);
  fs::remove(file);
  return static_cast<double>(written_mib) * (1 << 20) / 1e6 / s;
}

DiskResult measure_disk(const fs::path& dir, std::size_t mib) {
  DiskResult r;
  r.sync_end_mb_s = disk_write(dir / "disk_test.bin", mib, false, 120, r.mb_end);
  r.sync_block_mb_s = disk_write(dir / "disk_test.bin", mib, true, 60, r.mb_block);
  r.sync_block_ms = r.sync_block_mb_s > 0 ? (1 << 20) / 1e6 / r.sync_block_mb_s * 1e3 : 0;
  return r;
}

// ------------------------------------------------------------------------------------------------
// Throughput.

struct CaseResult {
  std::string compression;
  bool flat_out = false;
  bool ok = false;
  std::string problem;
  double pub_seconds = 0;
  std::uint64_t ticks = 0, late_ticks = 0;
  double pub_max_late_us = 0;
  std::uint64_t published = 0, recorded = 0, lost = 0;  ///< messages; lost = published - recorded
  std::uint64_t message_bytes = 0, file_bytes = 0;
  std::uint64_t dropped = 0, vendor_lost = 0, sequence_gaps = 0, tick_gaps = 0;
  std::uint64_t missing_ticks = 0;  ///< per-tick topics, as `poise info` sees them
  double cpu_percent = 0;           ///< recorder, publishing window
  double cpu_total_s = 0;           ///< recorder, whole life (wait4)
  double max_rss_mb = 0;
  double stop_s = 0;  ///< SIGTERM to exit (writing what was queued, the summary)
  std::map<std::string, std::pair<std::uint64_t, std::uint64_t>> per_topic;  ///< published, in file
  std::map<std::string, std::pair<std::size_t, std::size_t>> sample_bytes;
  bool complete = false;
};

std::uint64_t metadata_u64(const Json& info, const std::string& key) {
  try {
    return std::stoull(info.at("metadata").at("poise_recorder").at(key).get<std::string>());
  } catch (...) {
    return 0;
  }
}

Json poise_info(const fs::path& poise, const fs::path& file, const fs::path& log_dir,
                const std::string& tag) {
  Child info("info_" + tag, {poise.string(), "info", "--json", file.string()}, log_dir);
  if (!info.wait(600)) {
    info.stop(2000);
    throw std::runtime_error("poise info " + file.string() + " took more than 600 s");
  }
  const std::string text = slurp(info.stdout_path());
  if (text.empty()) return Json();
  return Json::parse(text, nullptr, false);
}

bool stdout_has(const Child& c, const char* word) {
  return slurp(c.stdout_path()).find(word) != std::string::npos;
}

// Waits for the recorder's first line; false (with r.problem) when it did not start.
bool wait_for_recorder(Child& recorder, CaseResult& r) {
  const auto t_ready = Clock::now();
  while (slurp(recorder.stderr_path()).find("poise record: ") == std::string::npos) {
    if (!recorder.running() || seconds_since(t_ready) > 20) {
      r.problem = "the recorder did not start (see " + recorder.stderr_path().string() + ")";
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

// Follows the publisher to its end, sampling the recorder's CPU when it starts and when it is
// done publishing; false (with r.problem) when it did not finish or failed.
bool watch_publisher(Child& publisher, Child& recorder, CpuSampler& cpu, double seconds,
                     CaseResult& r) {
  bool started = false, done = false;
  const auto t0 = Clock::now();
  const double bound = seconds + 60;
  while (publisher.running()) {
    if (!started && stdout_has(publisher, "PUBLISHING")) {
      started = true;
      cpu.sample();
    }
    if (started && !done && stdout_has(publisher, "DONE")) {
      done = true;
      cpu.sample();
    }
    if (!recorder.running()) break;
    if (seconds_since(t0) > bound) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (publisher.running()) {
    publisher.stop(3000);
    r.problem = recorder.running() ? "the publisher did not finish in time"
                                   : "the recorder exited during the run";
    return false;
  }
  if (*publisher.poll() != 0) {
    r.problem = "the publisher failed: " + slurp(publisher.stderr_path());
    return false;
  }
  return true;
}

// The recording as `poise info --json` sees it, against what the publisher says it published.
void count_recorded(const Json& info, const Json& pub, CaseResult& r) {
  r.complete = info.value("complete", false);
  r.file_bytes = info.value("file_size", 0ULL);
  r.dropped = metadata_u64(info, "total.dropped");
  r.vendor_lost = metadata_u64(info, "total.vendor_lost");
  r.tick_gaps = metadata_u64(info, "total.tick_gaps");
  std::map<std::string, std::uint64_t> in_file;
  for (const auto& t : info["topics"]) {
    in_file[t.value("topic", "")] = t.value("messages", 0ULL);
    r.message_bytes += t.value("bytes", 0ULL);
    r.sequence_gaps += t.value("sequence_gaps", 0ULL);
    r.missing_ticks += t.value("missing_ticks", 0ULL);
  }
  for (const auto& [topic, n] : pub["published"].items()) {
    const auto published = n.get<std::uint64_t>();
    const std::uint64_t got = in_file.count(topic) ? in_file[topic] : 0;
    r.per_topic[topic] = {published, got};
    r.published += published;
    r.recorded += got;
    r.lost += published > got ? published - got : 0;
  }
  for (const auto& [topic, b] : pub["sample_bytes"].items())
    r.sample_bytes[topic] = {b[0].get<std::size_t>(), b[1].get<std::size_t>()};
}

CaseResult run_case(const fs::path& poise, const fs::path& self, const fs::path& dir, int domain,
                    const std::string& compression, double rate_hz, double seconds,
                    const std::string& tag) {
  CaseResult r;
  r.compression = compression;
  r.flat_out = rate_hz <= 0;
  const fs::path file = dir / (tag + ".mcap");
  const fs::path logs = dir / "logs";
  const fs::path pub_json = logs / (tag + ".publisher.json");
  fs::remove(file);
  Child recorder("record_" + tag,
                 {poise.string(), "record", "--domain", std::to_string(domain), "-o", file.string(),
                  "--compression", compression, "--progress", "0", "--duration",
                  std::to_string(static_cast<int>(seconds + 180))},
                 logs);
  if (!wait_for_recorder(recorder, r)) return r;
  Child publisher(
      "publisher_" + tag,
      {self.string(), "--publisher", "--domain", std::to_string(domain), "--rate",
       std::to_string(rate_hz), "--seconds", std::to_string(seconds), "--out", pub_json.string()},
      logs);
  CpuSampler cpu;
  cpu.pid = recorder.pid();
  if (!watch_publisher(publisher, recorder, cpu, seconds, r)) return r;
  r.cpu_percent = cpu.percent();
  const auto t_stop = Clock::now();
  const int code = recorder.stop(120000);
  r.stop_s = seconds_since(t_stop);
  r.cpu_total_s = cpu_seconds(recorder.usage());
  r.max_rss_mb = recorder.usage().ru_maxrss / 1024.0;
  if (code != 0) {
    r.problem = "the recorder exited with code " + std::to_string(code);
    return r;
  }
  const Json pub = Json::parse(slurp(pub_json), nullptr, false);
  if (pub.is_discarded()) {
    r.problem = "no publisher result";
    return r;
  }
  r.pub_seconds = pub.value("seconds", 0.0);
  r.ticks = pub.value("ticks", 0ULL);
  r.late_ticks = pub.value("late_ticks", 0ULL);
  r.pub_max_late_us = pub.value("max_late_us", 0.0);
  progress("  %s: poise info ...", tag.c_str());
  const Json info = poise_info(poise, file, logs, tag);
  if (info.is_null() || info.is_discarded()) {
    r.problem = "poise info gave no JSON";
    return r;
  }
  count_recorded(info, pub, r);
  r.ok = true;
  return r;
}

// ------------------------------------------------------------------------------------------------
// `poise run` (latency cost, long run).

/// How a latency run records: not at all, `poise run --record` (a subscribing recorder),
/// `poise run --record --passive` (the launcher starts `poise record --passive`: no reader of the
/// loop's topics, readers of ground truth and diagnostics), or `poise record --passive
/// --no-passive-read` started by hand before a plain `poise run` (passive-hand: no DDS reader at
/// all; the nodes do not wait for it).
enum class RecordMode { none, subscribing, passive, passive_hand };
const char* mode_name(RecordMode m) {
  switch (m) {
    case RecordMode::none: return "no";
    case RecordMode::subscribing: return "dds";
    case RecordMode::passive: return "passive";
    case RecordMode::passive_hand: return "passive-hand";
  }
  return "?";
}

/// Extra settings of the latency runs (--loop-cpus): the loop's processes on these CPUs with
/// SCHED_FIFO and locked memory, the recorder on the others.
struct LoopSettings {
  std::string loop_cpus;      ///< "" = the defaults of `poise run`
  std::string recorder_cpus;  ///< taskset list for the recorder ("" = anywhere)
  int domain = 0;
};

struct RunResult {
  bool recorded = false;
  RecordMode mode = RecordMode::none;
  bool ok = false;
  std::string problem;
  int exit_code = -1;
  double p50 = 0, p99 = 0, max = 0, mean = 0;
  std::uint64_t latency_count = 0;
  /// Time the nodes (estimator, controller, contact optimiser) spend in DDS writes per tick: the
  /// sums of their dds_write_us p50 and p99 (a subscribing recorder is one more reader each write
  /// serves; a passive one is none).
  double write_p50 = 0, write_p99 = 0;
  std::uint64_t deadline_misses = 0, damping_ticks = 0;
  bool survived = false;
  double realtime_factor = 0;
  double tree_cpu_s = 0;  ///< every process of the run (wait4 of the launcher)
  /// The loop's processes: tree_cpu_s less the recorder's CPU when the recorder is a child of
  /// `poise run` (dds, passive; its last sample, up to 250 ms before its end).
  double loop_cpu_s = 0;
  double wall_s = 0;
  CpuSampler recorder;
  Json result, info;
  fs::path logs;
};

// The command line of the `poise run` of a latency or long run.
std::vector<std::string> run_argv(const fs::path& poise, double duration, const fs::path& json,
                                  const fs::path& logs, const fs::path& mcap, RecordMode mode,
                                  const LoopSettings& loop) {
  std::vector<std::string> argv{
      poise.string(),           "run", "standing",    "--realtime", "--duration",
      std::to_string(duration), "-o",  json.string(), "--log-dir",  logs.string()};
  if (loop.domain > 0) argv.insert(argv.end(), {"--domain", std::to_string(loop.domain)});
  if (!loop.loop_cpus.empty())
    argv.insert(argv.end(), {"--cpus", loop.loop_cpus, "--rt-priority", "80", "--lock-memory"});
  if (mode == RecordMode::subscribing || mode == RecordMode::passive) {
    argv.push_back("--record");
    argv.push_back(mcap.string());
    if (mode == RecordMode::passive) argv.push_back("--passive");
  }
  return argv;
}

// passive-hand: `poise record --passive --no-passive-read` started before the run, once it
// captures; null (with r.problem) when it did not start.
std::unique_ptr<Child> start_passive_recorder(const fs::path& poise, const fs::path& dir,
                                              const std::string& tag, const fs::path& mcap,
                                              const LoopSettings& loop, RunResult& r) {
  std::vector<std::string> rec;
  if (!loop.recorder_cpus.empty()) rec = {"/usr/bin/taskset", "-c", loop.recorder_cpus};
  // No DDS reader at all (--no-passive-read): nothing but the capture (ground truth and
  // diagnostics are then not in the file: nothing else reads them).
  rec.insert(rec.end(), {poise.string(), "record", "--passive", "--no-passive-read", "--domain",
                         std::to_string(loop.domain), "-o", mcap.string(), "--progress", "0"});
  auto passive = std::make_unique<Child>("rec_" + tag, rec, dir / "logs");
  const auto w0 = Clock::now();
  while (slurp(passive->stderr_path()).find("poise record: passive capture") == std::string::npos) {
    if (!passive->running() || seconds_since(w0) > 20) {
      r.problem = "the passive recorder did not start: " + slurp(passive->stderr_path());
      return nullptr;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  r.recorder.pid = passive->pid();
  return passive;
}

// Follows `poise run` to its end (bounded), sampling the recorder every 250 ms; false (with
// r.problem) when it took too long.
bool watch_run(Child& run, Clock::time_point t0, const std::string& tag, double duration,
               bool record, RunResult& r) {
  const double bound = duration + 120;
  auto last_sample = Clock::now() - std::chrono::hours(1);
  double last_note = 0;
  while (run.running()) {
    if (seconds_since(t0) > bound) {
      run.stop(30000);
      r.problem = "poise run took more than " + std::to_string(bound) + " s";
      return false;
    }
    if (record && Clock::now() - last_sample > std::chrono::milliseconds(250)) {
      last_sample = Clock::now();
      if (r.recorder.pid == 0) r.recorder.pid = find_child_with_arg(run.pid(), "record");
      r.recorder.sample();
    }
    if (duration >= 60 && seconds_since(t0) - last_note >= 60) {
      last_note = seconds_since(t0);
      progress("  %s: %.0f s of %.0f; recorder CPU so far %.1f %%, peak RSS %.0f MB", tag.c_str(),
               last_note, duration, r.recorder.percent(), r.recorder.peak_mb);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

// The figures of the run's result JSON; false (with r.problem) when it has none or no latency.
bool read_run_result(const fs::path& json, const Child& run, const fs::path& logs, RunResult& r) {
  r.result = Json::parse(slurp(json), nullptr, false);
  if (r.result.is_discarded() || !r.result.is_object()) {
    r.problem = "no result JSON (exit " + std::to_string(r.exit_code) + ", see " +
                run.stderr_path().string() + ")";
    return false;
  }
  const Json& lat = r.result["tick_latency_us"];
  if (lat.is_object()) {
    r.p50 = lat.value("p50", 0.0);
    r.p99 = lat.value("p99", 0.0);
    r.max = lat.value("max", 0.0);
    r.mean = lat.value("mean", 0.0);
    r.latency_count = lat.value("count", 0ULL);
  }
  if (const Json& w = r.result["dds_write_us"]; w.is_object()) {
    for (const char* node : {"estimator", "controller", "contact"})
      if (w.contains(node)) {
        r.write_p50 += w[node].value("p50", 0.0);
        r.write_p99 += w[node].value("p99", 0.0);
      }
  }
  if (r.latency_count == 0) {
    // A run that failed (a component exited, ...) has no latency: not a sample of the cost.
    r.problem = "no tick latency in the result: " + r.result.value("failure", std::string("?")) +
                " (see " + logs.string() + ")";
    return false;
  }
  r.deadline_misses = r.result.value("deadline_misses", 0ULL);
  r.damping_ticks = r.result.value("damping_ticks", 0ULL);
  r.survived = r.result.value("survived", false);
  r.realtime_factor = r.result.value("realtime_factor", 0.0);
  return true;
}

RunResult run_stack(const fs::path& poise, const fs::path& dir, const std::string& tag,
                    double duration, RecordMode mode, const LoopSettings& loop = {}) {
  RunResult r;
  const bool record = mode != RecordMode::none;
  r.recorded = record;
  r.mode = mode;
  const fs::path json = dir / (tag + ".json");
  const fs::path logs = dir / (tag + ".logs");
  const fs::path mcap = dir / (tag + ".mcap");
  fs::create_directories(logs);
  r.logs = logs;
  const std::vector<std::string> argv = run_argv(poise, duration, json, logs, mcap, mode, loop);
  // The passive recorder captures before the run starts (it must see the writers' announcements).
  std::unique_ptr<Child> passive;
  if (mode == RecordMode::passive_hand) {
    passive = start_passive_recorder(poise, dir, tag, mcap, loop, r);
    if (!passive) return r;
  } else if (record && !loop.recorder_cpus.empty()) {
    progress("  note: the recorder of `poise run --record` is not pinned");
  }
  const auto t0 = Clock::now();
  Child run("run_" + tag, argv, dir / "logs");
  if (!watch_run(run, t0, tag, duration, record, r)) return r;
  r.wall_s = seconds_since(t0);
  r.exit_code = *run.poll();
  if (passive) {
    r.recorder.sample();
    ::kill(passive->pid(), SIGINT);
    if (!passive->wait(30)) passive->stop(3000);
  }
  r.tree_cpu_s = cpu_seconds(run.usage());
  r.loop_cpu_s = r.tree_cpu_s;
  if (mode == RecordMode::subscribing || mode == RecordMode::passive)
    r.loop_cpu_s -= r.recorder.last_cpu;
  if (!read_run_result(json, run, logs, r)) return r;
  if (mode == RecordMode::passive_hand) r.info = poise_info(poise, mcap, dir / "logs", tag);
  if (mode == RecordMode::subscribing || mode == RecordMode::passive) {
    if (r.result.contains("pids") && r.result["pids"].contains("recorder") &&
        r.result["pids"]["recorder"].get<pid_t>() != r.recorder.pid)
      progress("  %s: note: sampled pid %d, result says recorder pid %d", tag.c_str(),
               r.recorder.pid, r.result["pids"]["recorder"].get<pid_t>());
    r.info = poise_info(poise, mcap, dir / "logs", tag);
  }
  r.ok = true;
  return r;
}

// ------------------------------------------------------------------------------------------------
// Reports.

double ratio(std::uint64_t a, std::uint64_t b) {
  return b ? static_cast<double>(a) / static_cast<double>(b) : 0.0;
}

void print_throughput(const std::vector<CaseResult>& cases, const DiskResult& disk, bool flat_out) {
  std::printf("\n%s\n", flat_out ? "SATURATION: publisher flat out (no sleep)"
                                 : "THROUGHPUT: 1 kHz, 9 per-tick topics + RobotDescription once");
  std::printf("%-5s %7s %9s %9s %9s %10s %8s %6s %6s %7s %7s %8s %7s %7s %7s %7s %7s\n",
              "COMPR", "PUB[s]", "PUB[m/s]", "REC[m/s]", "MSG[MB/s]", "FILE[MB/s]", "FILE[MB]",
              "RATIO", "CPU%", "CPU[s]", "LOST", "MISSING", "DROPPED", "DDSLOST", "SEQGAP",
              "TICKGAP", "STOP[s]");
  for (const auto& c : cases) {
    if (!c.ok) {
      std::printf("%-5s FAILED: %s\n", c.compression.c_str(), c.problem.c_str());
      continue;
    }
    const double s = c.pub_seconds > 0 ? c.pub_seconds : 1;
    std::printf(
        "%-5s %7.2f %9.0f %9.0f %9.1f %10.1f %8.1f %6.2f %6.1f %7.2f %7llu %8llu %7llu %7llu "
        "%7llu %7llu %7.2f%s\n",
        c.compression.c_str(), c.pub_seconds, c.published / s, c.recorded / s,
        c.message_bytes / 1e6 / s, c.file_bytes / 1e6 / s, c.file_bytes / 1e6,
        ratio(c.message_bytes, c.file_bytes), c.cpu_percent, c.cpu_total_s,
        static_cast<unsigned long long>(c.lost), static_cast<unsigned long long>(c.missing_ticks),
        static_cast<unsigned long long>(c.dropped), static_cast<unsigned long long>(c.vendor_lost),
        static_cast<unsigned long long>(c.sequence_gaps),
        static_cast<unsigned long long>(c.tick_gaps), c.stop_s, c.complete ? "" : "  (file INCOMPLETE)");
  }
  for (const auto& c : cases) {
    if (!c.ok) continue;
    std::printf(
        "  %-5s: %llu ticks in %.2f s (%.0f ticks/s); publisher late >1 ms on %llu ticks (max "
        "%.0f us); recorder peak RSS %.0f MB; message MB/s vs disk (fdatasync per MiB) %.2f\n",
        c.compression.c_str(), static_cast<unsigned long long>(c.ticks), c.pub_seconds,
        c.ticks / std::max(c.pub_seconds, 1e-9), static_cast<unsigned long long>(c.late_ticks),
        c.pub_max_late_us, c.max_rss_mb,
        disk.sync_block_mb_s > 0 ? c.message_bytes / 1e6 / c.pub_seconds / disk.sync_block_mb_s
                                 : 0.0);
    for (const auto& [topic, pr] : c.per_topic)
      if (pr.first != pr.second)
        std::printf("         %-26s published %llu, in file %llu (%lld)\n", topic.c_str(),
                    static_cast<unsigned long long>(pr.first),
                    static_cast<unsigned long long>(pr.second),
                    static_cast<long long>(pr.second) - static_cast<long long>(pr.first));
  }
}

void print_ramp(const std::vector<CaseResult>& cases) {
  if (cases.empty()) return;
  std::printf(
      "\nRAMP: paced tick rates (9 messages per tick), per compression until the first loss\n");
  std::printf("%-5s %9s %9s %9s %9s %8s %8s %7s %7s %8s\n", "COMPR", "TICKS/s", "PUB[m/s]",
              "REC[m/s]", "MSG[MB/s]", "LOST", "MISSING", "LOST%", "CPU%", "LATE>1ms");
  std::map<std::string, double> best;
  for (const auto& c : cases) {
    if (!c.ok) {
      std::printf("%-5s FAILED: %s\n", c.compression.c_str(), c.problem.c_str());
      continue;
    }
    const double s = c.pub_seconds > 0 ? c.pub_seconds : 1;
    std::printf("%-5s %9.0f %9.0f %9.0f %9.1f %8llu %8llu %7.2f %7.1f %8llu\n",
                c.compression.c_str(), c.ticks / s, c.published / s, c.recorded / s,
                c.message_bytes / 1e6 / s, static_cast<unsigned long long>(c.lost),
                static_cast<unsigned long long>(c.missing_ticks),
                100.0 * ratio(c.lost, c.published), c.cpu_percent,
                static_cast<unsigned long long>(c.late_ticks));
    if (c.lost == 0 && c.missing_ticks == 0)
      best[c.compression] = std::max(best[c.compression], c.recorded / s);
  }
  for (const auto& [comp, rate] : best)
    std::printf("  %-5s: no loss up to %.0f messages/s (highest loss-free step)\n", comp.c_str(),
                rate);
}

void print_sample_sizes(const CaseResult& c) {
  std::printf(
      "\nSample sizes (CDR incl. 4-byte header, fill_random contents, min..max of the "
      "pool):\n");
  std::size_t lo = 0, hi = 0;
  for (const auto& [topic, b] : c.sample_bytes) {
    std::printf("  %-26s %6zu..%zu\n", topic.c_str(), b.first, b.second);
    if (topic != "poise/robot_description") {
      lo += b.first;
      hi += b.second;
    }
  }
  std::printf("  one tick (9 per-tick topics): %zu..%zu bytes\n", lo, hi);
}

void print_run_table(const std::vector<RunResult>& runs) {
  std::printf("%-4s %-12s %8s %8s %8s %8s %8s %8s %6s %8s %11s %13s %8s %7s %9s\n", "RUN",
              "RECORD", "p50[us]", "p99[us]", "max[us]", "mean[us]", "MISSES", "DAMPING", "RTF",
              "CPU[s]", "LOOP-CPU[s]", "WRITE50/99us", "REC-CPU%", "SURVIVED", "FILE[MB]");
  int i = 0;
  for (const auto& r : runs) {
    ++i;
    if (!r.ok) {
      std::printf("%-4d %-12s FAILED: %s\n", i, mode_name(r.mode), r.problem.c_str());
      continue;
    }
    std::printf("%-4d %-12s %8.0f %8.0f %8.0f %8.0f %8llu %8llu %6.3f %8.2f %11.2f %6.0f/%-6.0f %8s %7s %9s\n",
                i, mode_name(r.mode), r.p50, r.p99, r.max, r.mean,
                static_cast<unsigned long long>(r.deadline_misses),
                static_cast<unsigned long long>(r.damping_ticks), r.realtime_factor, r.tree_cpu_s,
                r.loop_cpu_s, r.write_p50, r.write_p99,
                r.recorded ? std::to_string(r.recorder.percent()).substr(0, 5).c_str() : "-",
                r.survived ? "yes" : "NO",
                r.recorded && r.info.is_object()
                    ? std::to_string(r.info.value("file_size", 0ULL) / 1e6).substr(0, 6).c_str()
                    : "-");
  }
}

/// Losses in a recording of the real stack, from `poise info --json`.
void print_recording_losses(const Json& info) {
  if (!info.is_object()) {
    std::printf("  (no poise info)\n");
    return;
  }
  std::uint64_t bytes = 0;
  for (const auto& t : info["topics"])
    bytes += t.value("bytes", 0ULL);
  const std::uint64_t file = info.value("file_size", 0ULL);
  std::printf(
      "  file %.2f MB, %llu messages, %.2f MB of messages, ratio %.2f, %.1f s, complete %s, "
      "recorder: %llu dropped, %llu lost/rejected by DDS\n",
      file / 1e6, static_cast<unsigned long long>(info.value("messages", 0ULL)), bytes / 1e6,
      ratio(bytes, file), info.value("duration_s", 0.0),
      info.value("complete", false) ? "yes" : "NO",
      static_cast<unsigned long long>(metadata_u64(info, "total.dropped")),
      static_cast<unsigned long long>(metadata_u64(info, "total.vendor_lost")));
  std::printf("  %-26s %9s %9s %9s %8s %8s %8s %9s\n", "TOPIC", "MESSAGES", "RATE[Hz]",
              "MAXGAP[ms]", "SEQGAPS", "PERTICK", "MISSING", "REPEATED");
  for (const auto& t : info["topics"]) {
    const bool per_tick = t.value("per_tick", false);
    std::printf("  %-26s %9llu %9.1f %9.1f %8llu %8s %8s %9s\n", t.value("topic", "").c_str(),
                static_cast<unsigned long long>(t.value("messages", 0ULL)),
                t.value("mean_rate_hz", 0.0), t.value("longest_interval_s", 0.0) * 1e3,
                static_cast<unsigned long long>(t.value("sequence_gaps", 0ULL)),
                per_tick ? "yes" : "no",
                per_tick ? std::to_string(t.value("missing_ticks", 0ULL)).c_str() : "-",
                per_tick ? std::to_string(t.value("duplicate_ticks", 0ULL)).c_str() : "-");
  }
}

/// Samples each node says it published (diagnostics.ticks of its summary, one sample of its
/// per-tick topics per tick) against the messages of those topics in the recording.
void print_node_crosscheck(const fs::path& logs, const Json& info) {
  if (!info.is_object()) return;
  std::map<std::string, std::uint64_t> in_file;
  for (const auto& t : info["topics"])
    in_file[t.value("topic", "")] = t.value("messages", 0ULL);
  const std::vector<std::pair<std::string, std::vector<std::string>>> outputs{
      {"sim", {"poise/sensors", "poise/ground_truth"}},
      {"estimator", {"poise/state"}},
      {"controller", {"poise/contact_problem", "poise/joint_command"}},
      {"contact", {"poise/contact_solution"}}};
  std::printf("  node ticks (summary diagnostics.ticks) vs messages in the file:");
  std::uint64_t short_total = 0;
  for (const auto& [node, topics] : outputs) {
    const Json j = Json::parse(slurp(logs / (node + ".summary.json")), nullptr, false);
    if (!j.is_object() || !j.contains("diagnostics")) {
      std::printf(" %s ?", node.c_str());
      continue;
    }
    const auto ticks = j["diagnostics"].value("ticks", 0ULL);
    for (const auto& t : topics) {
      const std::uint64_t got = in_file.count(t) ? in_file[t] : 0;
      std::printf(" %s %llu/%llu", t.c_str() + 6, static_cast<unsigned long long>(got),
                  static_cast<unsigned long long>(ticks));
      if (got < ticks) short_total += ticks - got;
    }
  }
  std::printf("\n  => %llu fewer in the file than node ticks (an upper bound of recorder loss)\n",
              static_cast<unsigned long long>(short_total));
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void usage() {
  std::printf(
      "usage: poise-bench-record [--seconds S] [--saturation-seconds S] [--dir DIR] "
      "[--skip-throughput] [--skip-latency] [--latency-duration S] [--latency-reps N] "
      "[--latency-modes no,dds,passive,passive-hand] [--loop-cpus LIST --recorder-cpus LIST] "
      "[--long-minutes M] [--ramp R1,R2,..] [--disk-mb N] [--keep]\n"
      "\n"
      "Measures `poise record` in one run and prints the figures (progress on stderr):\n"
      "  disk        raw write speed of DIR: 1 MiB blocks, fdatasync at the end / per block\n"
      "  throughput  a publisher process sends one sample of each of the 9 per-tick Poise topic\n"
      "              types per tick at 1 kHz (RobotDescription once, latched; random seeded\n"
      "              contents) on a private DDS domain for S s (default 10) while `poise record`\n"
      "              records it: zstd, lz4, none\n"
      "  saturation  the same flat out for --saturation-seconds (default 3), then paced at the\n"
      "              --ramp tick rates (default 2000,4000,6000,8000; empty: none) until the\n"
      "              first loss, per compression\n"
      "  latency     `poise run standing --realtime --duration D` (default 10) without a\n"
      "              recorder (no), with `--record` (dds: a subscribing recorder), with\n"
      "              `--record --passive` (passive: `poise record --passive` started by the\n"
      "              launcher, no reader of the loop's topics; needs root) and with\n"
      "              `poise record --passive --no-passive-read` started by hand before it\n"
      "              (passive-hand: no DDS reader at all),\n"
      "              alternated N times each (default 2); --latency-modes picks (default\n"
      "              no,dds,passive as root, else no,dds); --loop-cpus LIST runs the loop there\n"
      "              with SCHED_FIFO 80 and locked memory (`poise run --cpus`), --recorder-cpus\n"
      "              LIST pins the hand-started passive recorder (taskset). LOOP-CPU = CPU of\n"
      "              the run's processes less the recorder's (dds, passive); WRITE = the sums of\n"
      "              the estimator's, controller's and contact optimiser's DDS write time p50/p99\n"
      "  long        with --long-minutes M: one M-minute real-time run with --record\n"
      "Options:\n"
      "  --dir DIR        where files go (default: a fresh /tmp/poise-bench-record-<pid>)\n"
      "  --disk-mb N      MiB written by the disk test (default 256)\n"
      "  --keep           keep the MCAP files (default: removed at the end)\n");
}

// The hidden role: the publisher child (--publisher --domain N --out FILE ...).
int publisher_role(int argc, char** argv) {
  int domain = -1;
  double rate = 1000, seconds = 10;
  std::uint64_t seed = 1;
  std::size_t pool = 256;
  std::string out;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--domain")
      domain = std::atoi(argv[i + 1]);
    else if (a == "--rate")
      rate = std::atof(argv[i + 1]);
    else if (a == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else if (a == "--seed")
      seed = std::strtoull(argv[i + 1], nullptr, 10);
    else if (a == "--pool")
      pool = std::max<std::size_t>(1, std::strtoull(argv[i + 1], nullptr, 10));
    else if (a == "--out")
      out = argv[i + 1];
  }
  if (domain < 0 || out.empty() || seconds <= 0 || seconds > 3600) {
    std::fprintf(stderr, "publisher: --domain, --out and --seconds (0..3600] are required\n");
    return 2;
  }
  try {
    return publisher_main(domain, rate, seconds, seed, pool, out);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "publisher: %s\n", e.what());
    return 1;
  }
}

// The command line of the bench.
struct BenchArgs {
  double seconds = 10, sat_seconds = 3, latency_duration = 10, long_minutes = 0;
  int latency_reps = 2;
  std::vector<RecordMode> latency_modes{RecordMode::none, RecordMode::subscribing};
  std::string loop_cpus, recorder_cpus;
  std::vector<double> ramp_rates{2000, 4000, 6000, 8000};
  std::size_t disk_mb = 256;
  bool skip_latency = false, skip_throughput = false, keep = false;
  std::string dir_arg;
};

// --latency-modes no,dds,passive,passive-hand; false (with the message) when a name is unknown
// or the list is empty.
bool parse_latency_modes(const std::string& text, std::vector<RecordMode>& modes) {
  modes.clear();
  std::stringstream list(text);
  for (std::string m; std::getline(list, m, ',');) {
    if (m == "no") modes.push_back(RecordMode::none);
    else if (m == "dds") modes.push_back(RecordMode::subscribing);
    else if (m == "passive") modes.push_back(RecordMode::passive);
    else if (m == "passive-hand") modes.push_back(RecordMode::passive_hand);
    else {
      std::fprintf(stderr,
                   "poise-bench-record: --latency-modes: '%s' is not no, dds, passive or "
                   "passive-hand\n",
                   m.c_str());
      return false;
    }
  }
  if (modes.empty()) {
    std::fprintf(stderr, "poise-bench-record: --latency-modes is empty\n");
    return false;
  }
  return true;
}

// --ramp R1,R2,..; false (with the message) when a rate is out of (0, 1e6].
bool parse_ramp(const std::string& text, std::vector<double>& rates) {
  rates.clear();
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) rates.push_back(std::atof(item.c_str()));
  for (double r : rates)
    if (!(r > 0 && r <= 1e6)) {
      std::fprintf(stderr, "poise-bench-record: --ramp takes tick rates in (0, 1e6]\n");
      return false;
    }
  return true;
}

// Parses the command line into `args`; an exit code when the bench is not to run (0 after
// --help, 2 on a bad argument).
std::optional<int> parse_bench_args(int argc, char** argv, BenchArgs& args) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "poise-bench-record: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--seconds") {
      args.seconds = std::atof(value().c_str());
    } else if (a == "--saturation-seconds") {
      args.sat_seconds = std::atof(value().c_str());
    } else if (a == "--dir") {
      args.dir_arg = value();
    } else if (a == "--skip-latency") {
      args.skip_latency = true;
    } else if (a == "--skip-throughput") {
      args.skip_throughput = true;
    } else if (a == "--latency-duration") {
      args.latency_duration = std::atof(value().c_str());
    } else if (a == "--latency-modes") {
      if (!parse_latency_modes(value(), args.latency_modes)) return 2;
    } else if (a == "--loop-cpus") {
      args.loop_cpus = value();
    } else if (a == "--recorder-cpus") {
      args.recorder_cpus = value();
    } else if (a == "--latency-reps") {
      args.latency_reps = std::atoi(value().c_str());
    } else if (a == "--long-minutes") {
      args.long_minutes = std::atof(value().c_str());
    } else if (a == "--disk-mb") {
      args.disk_mb = std::strtoull(value().c_str(), nullptr, 10);
    } else if (a == "--ramp") {
      if (!parse_ramp(value(), args.ramp_rates)) return 2;
    } else if (a == "--keep") {
      args.keep = true;
    } else {
      std::fprintf(stderr, "poise-bench-record: unknown argument '%s' (see --help)\n", a.c_str());
      return 2;
    }
  }
  return std::nullopt;
}

bool bench_args_in_range(const BenchArgs& a) {
  if (!(a.seconds > 0 && a.seconds <= 3600) || !(a.sat_seconds > 0 && a.sat_seconds <= 600) ||
      !(a.latency_duration > 0 && a.latency_duration <= 3600) || a.latency_reps < 1 ||
      a.latency_reps > 20 || !(a.long_minutes >= 0 && a.long_minutes <= 24 * 60) ||
      a.disk_mb < 1) {
    std::fprintf(stderr, "poise-bench-record: a value is out of range (see --help)\n");
    return false;
  }
  return true;
}

void install_bench_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = bench_on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGHUP, &sa, nullptr);
}

// The first line of the figures: host, cores, CPU model, load, directory.
void print_machine(const fs::path& dir) {
  char host[256] = {};
  ::gethostname(host, sizeof(host) - 1);
  std::string cpu_model = "?";
  {
    std::ifstream f("/proc/cpuinfo");
    for (std::string line; std::getline(f, line);)
      if (line.rfind("model name", 0) == 0) {
        cpu_model = line.substr(line.find(':') + 2);
        break;
      }
  }
  double load[3] = {};
  ::getloadavg(load, 3);
  std::printf("poise-bench-record: %s, %ld cores, %s; load average %.2f %.2f %.2f; dir %s\n",
              host, ::sysconf(_SC_NPROCESSORS_ONLN), cpu_model.c_str(), load[0], load[1], load[2],
              dir.c_str());
  std::fflush(stdout);
}

// Where the bench runs: the `poise` beside it, the files' directory.
struct BenchPaths {
  fs::path self, poise, dir;
};

DiskResult run_disk(const BenchPaths& p, const BenchArgs& args) {
  progress("disk: %zu MiB in 1 MiB blocks ...", args.disk_mb);
  const DiskResult disk = measure_disk(p.dir, args.disk_mb);
  std::printf(
      "\nDISK (%s): %.0f MB/s with fdatasync at the end (%zu MiB); %.0f MB/s with fdatasync "
      "per 1 MiB (%zu MiB, %.2f ms per block)\n",
      p.dir.c_str(), disk.sync_end_mb_s, disk.mb_end, disk.sync_block_mb_s, disk.mb_block,
      disk.sync_block_ms);
  std::fflush(stdout);
  return disk;
}

// One case per compression at `rate_hz` ticks/s (0: flat out), tagged `prefix` + compression.
std::vector<CaseResult> run_compressions(const BenchPaths& p, const BenchArgs& args, int domain,
                                         const char* prefix, double rate_hz, double seconds) {
  std::vector<CaseResult> cases;
  for (const char* c : {"zstd", "lz4", "none"}) {
    const std::string tag = prefix + std::string(c);
    if (rate_hz > 0)
      progress("throughput %s: 1 kHz for %.0f s ...", c, seconds);
    else
      progress("saturation %s: flat out for %.0f s ...", c, seconds);
    cases.push_back(run_case(p.poise, p.self, p.dir, domain, c, rate_hz, seconds, tag));
    if (!cases.back().ok) progress("  FAILED: %s", cases.back().problem.c_str());
    if (!args.keep) fs::remove(p.dir / (tag + ".mcap"));
  }
  return cases;
}

// Ramp: the highest paced tick rate recorded without a loss, per compression.
std::vector<CaseResult> run_ramp(const BenchPaths& p, const BenchArgs& args, int domain) {
  std::vector<CaseResult> ramp_cases;
  for (const char* c : {"zstd", "lz4", "none"}) {
    for (const double rate : args.ramp_rates) {
      const std::string tag = "ramp" + std::to_string(static_cast<int>(rate)) + "_" + c;
      progress("ramp %s: %.0f ticks/s for %.0f s ...", c, rate, args.sat_seconds);
      ramp_cases.push_back(
          run_case(p.poise, p.self, p.dir, domain, c, rate, args.sat_seconds, tag));
      if (!args.keep) fs::remove(p.dir / (tag + ".mcap"));
      const CaseResult& r = ramp_cases.back();
      if (!r.ok) progress("  FAILED: %s", r.problem.c_str());
      if (!r.ok || r.lost > 0 || r.missing_ticks > 0) break;
    }
  }
  return ramp_cases;
}

// 1. disk, 2. throughput, saturation and ramp.
void run_throughput_part(const BenchPaths& p, const BenchArgs& args) {
  const DiskResult disk = run_disk(p, args);
  const int domain = poise::dds::claim_free_domain();
  progress("DDS domain %d", domain);
  const std::vector<CaseResult> rate_cases =
      run_compressions(p, args, domain, "tp_", 1000, args.seconds);
  const std::vector<CaseResult> flat_cases =
      run_compressions(p, args, domain, "sat_", 0, args.sat_seconds);
  const std::vector<CaseResult> ramp_cases = run_ramp(p, args, domain);
  if (rate_cases[0].ok) print_sample_sizes(rate_cases[0]);
  print_throughput(rate_cases, disk, false);
  print_throughput(flat_cases, disk, true);
  print_ramp(ramp_cases);
  std::printf(
      "  PUB/REC[m/s] = messages published / in the file per second of publishing; LOST = "
      "published - in file; DROPPED/DDSLOST = the recorder's own counters (metadata "
      "poise_recorder); SEQGAP = gaps in the recorder's sequence numbers; TICKGAP = ticks "
      "skipped within a writer's stream as the recorder saw it live (poise_recorder "
      "total.tick_gaps: a loss the queue and DDS did not see); CPU%% = recorder, "
      "%% of one core while the publisher published; CPU[s] = recorder's whole life; "
      "MISSING = ticks missing in per-tick topics (poise info); RATIO = message bytes / file "
      "bytes; STOP = SIGTERM to exit.\n");
  std::fflush(stdout);
}

// Medians of the latency runs per recorder mode, and their ratios to the runs without one.
void print_latency_medians(const std::vector<RunResult>& runs) {
  auto rt = [](double a, double b) { return b > 0 ? a / b : 0.0; };
  struct Agg {
    std::vector<double> p50, p99, mx, cpu, loop_cpu, rec_pct, w50, w99;
    std::uint64_t misses = 0, damping = 0;
  };
  std::map<RecordMode, Agg> agg;
  for (const auto& r : runs) {
    if (!r.ok) continue;
    Agg& a = agg[r.mode];
    a.p50.push_back(r.p50);
    a.p99.push_back(r.p99);
    a.mx.push_back(r.max);
    a.cpu.push_back(r.tree_cpu_s);
    a.loop_cpu.push_back(r.loop_cpu_s);
    a.w50.push_back(r.write_p50);
    a.w99.push_back(r.write_p99);
    if (r.recorded) a.rec_pct.push_back(r.recorder.percent());
    a.misses += r.deadline_misses;
    a.damping += r.damping_ticks;
  }
  const Agg base = agg.count(RecordMode::none) ? agg[RecordMode::none] : Agg{};
  for (const auto& [mode, a] : agg) {
    std::printf("median over %zu runs, recorder %-12s: p50 %.0f p99 %.0f max %.0f us, CPU %.2f s, "
                "loop CPU %.2f s, nodes' DDS writes p50 %.0f p99 %.0f us, recorder %.1f %% of a "
                "core; deadline misses %llu, damping ticks %llu (sums)",
                a.p50.size(), mode_name(mode), median(a.p50), median(a.p99), median(a.mx),
                median(a.cpu), median(a.loop_cpu), median(a.w50), median(a.w99),
                a.rec_pct.empty() ? 0.0 : median(a.rec_pct),
                static_cast<unsigned long long>(a.misses),
                static_cast<unsigned long long>(a.damping));
    if (mode != RecordMode::none && !base.p50.empty())
      std::printf(" | ratio to none: p50 %.2f, p99 %.2f, max %.2f, CPU of the run %.2f, loop "
                  "CPU %.2f, DDS writes p50 %.2f p99 %.2f",
                  rt(median(a.p50), median(base.p50)), rt(median(a.p99), median(base.p99)),
                  rt(median(a.mx), median(base.mx)), rt(median(a.cpu), median(base.cpu)),
                  rt(median(a.loop_cpu), median(base.loop_cpu)),
                  rt(median(a.w50), median(base.w50)), rt(median(a.w99), median(base.w99)));
    std::printf("\n");
  }
}

// 3. The latency runs, alternated between the recorder modes.
void run_latency_part(const BenchPaths& p, const BenchArgs& args) {
  std::vector<RunResult> runs;
  LoopSettings loop;
  loop.loop_cpus = args.loop_cpus;
  loop.recorder_cpus = args.recorder_cpus;
  loop.domain = poise::dds::claim_free_domain();
  const int n_modes = static_cast<int>(args.latency_modes.size());
  for (int k = 0; k < n_modes * args.latency_reps; ++k) {
    const RecordMode mode = args.latency_modes[static_cast<std::size_t>(k % n_modes)];
    const std::string tag = "lat" + std::to_string(k + 1) + "_" + mode_name(mode);
    progress("latency run %d/%d (recorder: %s): poise run standing --realtime --duration %.0f%s%s ...",
             k + 1, n_modes * args.latency_reps, mode_name(mode), args.latency_duration,
             args.loop_cpus.empty() ? "" : " --cpus ", args.loop_cpus.c_str());
    runs.push_back(run_stack(p.poise, p.dir, tag, args.latency_duration, mode, loop));
    if (!runs.back().ok) progress("  FAILED: %s", runs.back().problem.c_str());
    if (!args.keep) fs::remove(p.dir / (tag + ".mcap"));
  }
  std::printf(
      "\nLATENCY COST: poise run standing --realtime --duration %.0f%s%s, alternated (tick "
      "latency = sensors k published -> command k received); recorder: no = none, dds = "
      "`poise run --record` (a subscribing recorder), passive = `poise run --record --passive`, "
      "passive-hand = `poise record --passive --no-passive-read` started by hand%s%s\n",
      args.latency_duration, args.loop_cpus.empty() ? "" : " --cpus ", args.loop_cpus.c_str(),
      args.recorder_cpus.empty() ? "" : " on CPUs ", args.recorder_cpus.c_str());
  print_run_table(runs);
  print_latency_medians(runs);
  // The first recording of each kind, against the nodes' own tick counts.
  std::set<RecordMode> shown;
  for (const auto& r : runs)
    if (r.ok && r.recorded && shown.insert(r.mode).second) {
      std::printf(
          "recording of a real run, recorder %s (recorder CPU %.1f %% of a core, peak RSS "
          "%.0f MB):\n",
          mode_name(r.mode), r.recorder.percent(), r.recorder.peak_mb);
      print_recording_losses(r.info);
      print_node_crosscheck(r.logs, r.info);
    }
  std::fflush(stdout);
}

// 4. The long real-time run with --record.
void run_long_part(const BenchPaths& p, const BenchArgs& args) {
  const double long_minutes = args.long_minutes;
  double l0[3] = {};
  ::getloadavg(l0, 3);
  progress("long run: poise run standing --realtime --duration %.0f --record ... (load %.2f)",
           long_minutes * 60, l0[0]);
  RunResult r = run_stack(p.poise, p.dir, "long", long_minutes * 60, RecordMode::subscribing);
  double l1[3] = {};
  ::getloadavg(l1, 3);
  std::printf(
      "\nLONG RUN: poise run standing --realtime --duration %.0f --record (load average "
      "before %.2f %.2f %.2f, after %.2f %.2f %.2f)\n",
      long_minutes * 60, l0[0], l0[1], l0[2], l1[0], l1[1], l1[2]);
  if (!r.ok) {
    std::printf("FAILED: %s\n", r.problem.c_str());
  } else {
    std::printf(
        "exit %d, survived %s, wall %.0f s, tick latency p50 %.0f p99 %.0f max %.0f us over "
        "%llu ticks, deadline misses %llu, damping ticks %llu, realtime factor %.3f\n",
        r.exit_code, r.survived ? "yes" : "NO", r.wall_s, r.p50, r.p99, r.max,
        static_cast<unsigned long long>(r.latency_count),
        static_cast<unsigned long long>(r.deadline_misses),
        static_cast<unsigned long long>(r.damping_ticks), r.realtime_factor);
    std::printf(
        "recorder (pid %d): %.1f %% of one core over %.0f s sampled (%.1f s CPU), peak RSS "
        "%.0f MB; whole run tree CPU %.1f s\n",
        r.recorder.pid, r.recorder.percent(), r.recorder.window_s(),
        r.recorder.last_cpu - r.recorder.first_cpu, r.recorder.peak_mb, r.tree_cpu_s);
    print_recording_losses(r.info);
    print_node_crosscheck(r.logs, r.info);
  }
  if (!args.keep) fs::remove(p.dir / "long.mcap");
}

// The `poise` beside this program and the files' directory (created).
BenchPaths bench_paths(const BenchArgs& args) {
  BenchPaths p;
  p.self = self_exe();
  p.poise = p.self.parent_path() / "poise";
  if (!fs::exists(p.poise)) throw std::runtime_error(p.poise.string() + " not found");
  p.dir = args.dir_arg.empty() ? fs::temp_directory_path() /
                                     ("poise-bench-record-" + std::to_string(::getpid()))
                               : fs::path(args.dir_arg);
  fs::create_directories(p.dir / "logs");
  progress("files in %s", p.dir.c_str());
  return p;
}

int run_bench(const BenchArgs& args) {
  const BenchPaths p = bench_paths(args);
  print_machine(p.dir);
  if (!args.skip_throughput) run_throughput_part(p, args);
  if (!args.skip_latency) run_latency_part(p, args);
  if (args.long_minutes > 0) run_long_part(p, args);
  double l2[3] = {};
  ::getloadavg(l2, 3);
  std::printf("\nload average at the end %.2f %.2f %.2f; logs and JSON in %s\n", l2[0], l2[1],
              l2[2], p.dir.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::string(argv[1]) == "--publisher") return publisher_role(argc, argv);
  BenchArgs args;
  if (::geteuid() == 0) args.latency_modes.push_back(RecordMode::passive);
  if (const auto code = parse_bench_args(argc, argv, args)) return *code;
  if (!bench_args_in_range(args)) return 2;
  install_bench_signal_handlers();
  // The shipped loopback configurations only.
  ::unsetenv("POISE_DDS_CONFIG");
  try {
    return run_bench(args);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-bench-record: %s\n", e.what());
    return 1;
  }
}
