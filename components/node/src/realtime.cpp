#include "poise/node/realtime.hpp"

#include <dirent.h>
#include <malloc.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace poise::node {

namespace {

std::string errno_text(int e) { return std::strerror(e); }

const char* policy_name(int policy) {
  switch (policy) {
    case SCHED_FIFO:
      return "fifo";
    case SCHED_RR:
      return "rr";
    case SCHED_OTHER:
      return "other";
    case SCHED_BATCH:
      return "batch";
    case SCHED_IDLE:
      return "idle";
    default:
      return "unknown";
  }
}

/// Touches `bytes` of stack below the caller so that the pages are present (and, after
/// mlockall, locked) before the loop needs them.
__attribute__((noinline)) void prefault_stack(std::size_t bytes) {
  constexpr std::size_t kMax = 512 * 1024;
  volatile unsigned char buffer[kMax];
  const std::size_t n = bytes < kMax ? bytes : kMax;
  for (std::size_t i = 0; i < n; i += 4096) buffer[i] = 0;
  buffer[n - 1] = 0;
  asm volatile("" : : "r"(buffer) : "memory");  // the stores are the point: keep them
}

/// Thread ids and names of this process.
std::vector<std::pair<pid_t, std::string>> threads_of_self() {
  std::vector<std::pair<pid_t, std::string>> out;
  DIR* dir = ::opendir("/proc/self/task");
  if (!dir) return out;
  while (const dirent* e = ::readdir(dir)) {
    if (e->d_name[0] < '0' || e->d_name[0] > '9') continue;
    std::ifstream comm(std::string("/proc/self/task/") + e->d_name + "/comm");
    std::string name;
    std::getline(comm, name);
    out.emplace_back(static_cast<pid_t>(std::stol(e->d_name)), name);
  }
  ::closedir(dir);
  return out;
}

}  // namespace

void add_realtime_options(CLI::App& app, RealtimeOptions& options) {
  app.add_option("--rt-priority", options.priority,
                 "run the node's threads SCHED_FIFO at this priority (1..99; 0: normal "
                 "scheduling). Needs root, CAP_SYS_NICE or an rtprio limit; refused, the node "
                 "says why and runs with normal scheduling")
      ->check(CLI::Range(0, 99))
      ->capture_default_str();
  app.add_option("--cpus", options.cpus,
                 "CPU affinity of the node's threads, a CPU list: 1, 0-1, 0,2 (default: any)")
      ->check(cpu_list_check);
  app.add_flag("--lock-memory", options.lock_memory,
               "lock the node's memory (mlockall), pre-fault its stack and keep freed heap, so "
               "that no page fault happens in the loop");
}

std::string cpu_list_check(const std::string& list) {
  try {
    parse_cpu_list(list);
    return {};
  } catch (const std::exception& e) {
    return e.what();
  }
}

std::vector<int> parse_cpu_list(const std::string& list) {
  const long configured = ::sysconf(_SC_NPROCESSORS_CONF);
  auto number = [&](const std::string& s) {
    if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos)
      throw std::invalid_argument("CPU list '" + list + "': '" + s + "' is not a CPU number");
    const long v = std::stol(s);
    if (v >= configured)
      throw std::invalid_argument("CPU list '" + list + "': CPU " + s + " does not exist (this "
                                  "machine has CPUs 0-" + std::to_string(configured - 1) + ")");
    return static_cast<int>(v);
  };
  std::vector<int> cpus;
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t comma = list.find(',', start);
    const std::string item =
        list.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (item.empty()) throw std::invalid_argument("CPU list '" + list + "': empty item");
    const std::size_t dash = item.find('-');
    if (dash == std::string::npos) {
      cpus.push_back(number(item));
    } else {
      const int lo = number(item.substr(0, dash)), hi = number(item.substr(dash + 1));
      if (hi < lo)
        throw std::invalid_argument("CPU list '" + list + "': range '" + item + "' is reversed");
      for (int c = lo; c <= hi; ++c) cpus.push_back(c);
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return cpus;
}

RealtimeReport apply_process_realtime(const RealtimeOptions& options) {
  RealtimeReport r;
  if (!options.cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int c : parse_cpu_list(options.cpus)) CPU_SET(c, &set);
    if (::sched_setaffinity(0, sizeof(set), &set) == 0) {
      r.affinity_applied = true;
      r.applied.push_back("CPUs " + options.cpus);
    } else {
      r.refused.push_back("CPU affinity " + options.cpus + " refused (" + errno_text(errno) +
                          "): running on any CPU");
    }
  }
  if (options.lock_memory) {
    // Keep freed heap in the process (no trimming, no mmap'ed chunks) so that a later
    // allocation never faults in fresh pages; then lock everything, present and future.
    ::mallopt(M_TRIM_THRESHOLD, -1);
    ::mallopt(M_MMAP_MAX, 0);
    if (::mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      prefault_stack(256 * 1024);
      r.memory_locked = true;
      r.applied.push_back("memory locked (mlockall current + future, 256 kB stack pre-faulted)");
    } else {
      const int e = errno;
      r.refused.push_back("memory locking refused (" + errno_text(e) +
                          "; needs root, CAP_IPC_LOCK or a large enough `ulimit -l`): memory "
                          "may page-fault in the loop");
    }
  }
  if (options.priority == 0) {
    // Started real-time by someone else (poise launch's deployment priority, chrt): say so, and
    // the housekeeping threads are demoted as with --rt-priority.
    const int policy = ::sched_getscheduler(0);
    sched_param sp{};
    ::sched_getparam(0, &sp);
    if (policy == SCHED_FIFO || policy == SCHED_RR) {
      r.priority_applied = true;
      r.applied.push_back(std::string(policy == SCHED_FIFO ? "SCHED_FIFO " : "SCHED_RR ") +
                          std::to_string(sp.sched_priority) + " (inherited)");
    }
  }
  if (options.priority > 0) {
    sched_param sp{};
    sp.sched_priority = options.priority;
    if (::sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
      r.priority_applied = true;
      r.applied.push_back("SCHED_FIFO " + std::to_string(options.priority));
    } else {
      const int e = errno;
      r.refused.push_back("SCHED_FIFO " + std::to_string(options.priority) + " refused (" +
                          errno_text(e) +
                          "; needs root, CAP_SYS_NICE or an rtprio limit in "
                          "/etc/security/limits.conf): running with normal scheduling");
    }
  }
  return r;
}

int demote_housekeeping_threads(int expected) {
  const int own = ::sched_getscheduler(0);
  if (own != SCHED_FIFO && own != SCHED_RR) return 0;
  // A vendor's thread names itself once it runs, shortly after the participant is created:
  // scan again (at most 200 ms) until the expected number is found.
  int demoted = 0;
  for (int attempt = 0; attempt < 40; ++attempt) {
    for (const auto& [tid, name] : threads_of_self()) {
      if (name != "gc" && name != "dq.builtins") continue;
      if (::sched_getscheduler(tid) == SCHED_OTHER) continue;  // done in an earlier scan
      sched_param sp{};
      if (::sched_setscheduler(tid, SCHED_OTHER, &sp) == 0) ++demoted;
    }
    if (demoted >= expected) break;
    ::usleep(5000);
  }
  return demoted;
}

std::vector<std::string> describe_threads() {
  std::vector<std::string> out;
  for (const auto& [tid, name] : threads_of_self()) {
    const int policy = ::sched_getscheduler(tid);
    sched_param sp{};
    ::sched_getparam(tid, &sp);
    out.push_back(name + ":" + policy_name(policy) + "/" + std::to_string(sp.sched_priority));
  }
  return out;
}

PageFaults page_faults() noexcept {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return {static_cast<std::uint64_t>(u.ru_minflt), static_cast<std::uint64_t>(u.ru_majflt)};
}

}  // namespace poise::node
