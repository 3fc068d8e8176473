#pragma once
// Real-time process settings of a Poise node (issue #19): SCHED_FIFO priority, CPU affinity and
// locked, pre-faulted memory.
//
//   RealtimeOptions rt{.priority = 70, .cpus = "1", .lock_memory = true};
//   RealtimeReport r = apply_process_realtime(rt);   // before any thread is created
//   ... create the DDS participant (its threads inherit policy, priority and affinity) ...
//   demote_housekeeping_threads();                    // discovery / garbage collection: normal
//
// Everything degrades gracefully: a setting the process is not permitted to make (no root, no
// CAP_SYS_NICE / CAP_IPC_LOCK, no rtprio limit) is reported with the reason and the fix, and the
// node runs with normal scheduling. Nothing here is called per tick.

#include <cstdint>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace poise::node {

struct RealtimeOptions {
  int priority = 0;          ///< SCHED_FIFO priority 1..99 of the node's threads; 0: normal
  std::string cpus;          ///< CPU list ("1", "0-1", "0,2"); "": any CPU
  bool lock_memory = false;  ///< mlockall(current + future), pre-faulted stack, no heap trimming
};

/// What apply_process_realtime() did: one line per requested setting, applied or refused (why).
struct RealtimeReport {
  bool priority_applied = false;
  bool affinity_applied = false;
  bool memory_locked = false;
  std::vector<std::string> applied;  ///< "SCHED_FIFO 70", "CPUs 1", "memory locked (...)"
  std::vector<std::string> refused;  ///< "SCHED_FIFO 70 refused (Operation not permitted: ...)"
};

/// Adds --rt-priority, --cpus and --lock-memory.
void add_realtime_options(CLI::App& app, RealtimeOptions& options);

/// Parses a CPU list ("0", "0-3", "0,2-3"). Throws std::invalid_argument naming the problem
/// (empty item, bad number, reversed range, CPU beyond the machine's configured CPUs).
std::vector<int> parse_cpu_list(const std::string& list);
/// The check of a --cpus option (CLI11 validator form): "" when `list` parses, else the error.
std::string cpu_list_check(const std::string& list);

/// Applies `options` to the calling process (a process started SCHED_FIFO/RR by a launcher or
/// chrt with priority 0 is reported as "SCHED_FIFO N (inherited)"): SCHED_FIFO for the calling thread (threads created
/// later inherit it), affinity of the calling thread (inherited likewise), and with lock_memory
/// mlockall(MCL_CURRENT | MCL_FUTURE), M_TRIM_THRESHOLD/M_MMAP_MAX so that freed heap is kept,
/// and a pre-faulted stack. Call before creating threads. Never throws for a refusal.
RealtimeReport apply_process_realtime(const RealtimeOptions& options);

/// The process's threads whose names mark them as the DDS vendor's housekeeping (Cyclone DDS:
/// "gc", "dq.builtins": garbage collection and discovery) go back to SCHED_OTHER, so that
/// discovery bursts never delay the data path (Cyclone "recv"/"recvUC"/"tev"/"dq.user", the
/// node's own threads). Fast DDS 2.9 does not name its threads: all keep the process priority.
/// A thread names itself once it runs: the scan is repeated (at most 200 ms) until `expected`
/// threads were demoted (2 for Cyclone DDS; 0: one scan). Returns the number demoted. Does
/// nothing unless the calling thread runs SCHED_FIFO or SCHED_RR.
int demote_housekeeping_threads(int expected = 0);

/// The scheduling of each thread of this process, "name:policy/priority" (policy "fifo", "rr",
/// "other", "batch", "idle"), for summaries and tests.
std::vector<std::string> describe_threads();

/// Page faults of this process so far (getrusage): minor and major.
struct PageFaults {
  std::uint64_t minor = 0;
  std::uint64_t major = 0;
};
PageFaults page_faults() noexcept;

}  // namespace poise::node
