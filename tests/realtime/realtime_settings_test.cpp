// Real-time process settings (issue #19): what poise::node::apply_process_realtime() does to a
// process and its threads, and `poise run --rt-priority --lock-memory` end to end: applied as
// root, refused with a clear message (and the run still balancing) as an unprivileged user.
// The unit checks run in forked children so that the test process itself keeps normal
// scheduling.
#include <gtest/gtest.h>
#include <grp.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "poise/node/realtime.hpp"
#include "support/child_process.hpp"

namespace {

namespace fs = std::filesystem;
using poise::node::RealtimeOptions;
using poise::testing::bin;
using poise::testing::ChildProcess;
using namespace std::chrono_literals;

/// Runs `check` in a forked child; returns its message ("" = passed). The child's scheduling
/// changes end with it.
template <class F>
std::string in_child(F check) {
  int fds[2];
  if (::pipe(fds) != 0) return "pipe failed";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    std::string msg;
    try {
      msg = check();
    } catch (const std::exception& e) {
      msg = std::string("exception: ") + e.what();
    }
    if (!msg.empty()) (void)!::write(fds[1], msg.data(), msg.size());
    ::_exit(msg.empty() ? 0 : 1);
  }
  ::close(fds[1]);
  std::string msg;
  char buf[512];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof(buf))) > 0;) msg.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (msg.empty() && !(WIFEXITED(status) && WEXITSTATUS(status) == 0))
    return "child ended abnormally (status " + std::to_string(status) + ")";
  return msg;
}

std::string policy_of(pid_t tid) {
  const int p = ::sched_getscheduler(tid);
  sched_param sp{};
  ::sched_getparam(tid, &sp);
  return std::string(p == SCHED_FIFO ? "fifo" : p == SCHED_OTHER ? "other" : "?") + "/" +
         std::to_string(sp.sched_priority);
}

long vm_locked_kb() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmLck:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

bool contains(const std::vector<std::string>& v, const std::string& part) {
  for (const auto& s : v)
    if (s.find(part) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST(RealtimeSettings, CpuListsAreParsedAndBadOnesNamed) {
  EXPECT_EQ(poise::node::parse_cpu_list("0"), (std::vector<int>{0}));
  const long n = ::sysconf(_SC_NPROCESSORS_CONF);
  if (n >= 2) {
    EXPECT_EQ(poise::node::parse_cpu_list("0-1"), (std::vector<int>{0, 1}));
    EXPECT_EQ(poise::node::parse_cpu_list("1,0"), (std::vector<int>{1, 0}));
  }
  auto error_of = [](const std::string& list) {
    try {
      poise::node::parse_cpu_list(list);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("").find("empty item"), std::string::npos);
  EXPECT_NE(error_of("0,,1").find("empty item"), std::string::npos);
  EXPECT_NE(error_of("x").find("'x' is not a CPU number"), std::string::npos);
  EXPECT_NE(error_of("1-0").find("reversed"), std::string::npos);
  EXPECT_NE(error_of("4096").find("CPU 4096 does not exist"), std::string::npos);
}

// As root: SCHED_FIFO, affinity and locked memory are applied to the process, inherited by the
// threads it creates afterwards (as the DDS vendors' threads are), and housekeeping threads
// named like Cyclone's ("gc", "dq.builtins") go back to normal scheduling.
TEST(RealtimeSettings, AppliedAndInheritedByLaterThreads) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root (CI runs as root)";
  const std::string failure = in_child([]() -> std::string {
    RealtimeOptions o;
    o.priority = 11;
    o.cpus = "0";
    o.lock_memory = true;
    const auto r = poise::node::apply_process_realtime(o);
    if (!r.refused.empty()) return "refused as root: " + r.refused.front();
    if (!r.priority_applied || !r.affinity_applied || !r.memory_locked) return "not all applied";
    if (policy_of(0) != "fifo/11") return "main thread is " + policy_of(0);
    if (vm_locked_kb() <= 0) return "VmLck is " + std::to_string(vm_locked_kb()) + " kB";
    std::string worker_policy, gc_policy;
    int worker_cpus = -1;
    bool worker_on_0 = false;
    std::thread worker([&] {
      worker_policy = policy_of(0);
      cpu_set_t set;
      CPU_ZERO(&set);
      ::sched_getaffinity(0, sizeof(set), &set);
      worker_cpus = CPU_COUNT(&set);
      worker_on_0 = CPU_ISSET(0, &set);
    });
    worker.join();
    if (worker_policy != "fifo/11") return "a later thread is " + worker_policy;
    if (worker_cpus != 1 || !worker_on_0) return "a later thread's affinity is not CPU 0";
    // A thread named like Cyclone's garbage collector, still running when demoted.
    std::atomic<bool> stop{false};
    std::atomic<pid_t> gc_tid{0};
    std::thread gc([&] {
      ::pthread_setname_np(::pthread_self(), "gc");
      gc_tid = ::gettid();
      while (!stop) std::this_thread::sleep_for(1ms);
    });
    while (gc_tid == 0) std::this_thread::sleep_for(1ms);
    const int demoted = poise::node::demote_housekeeping_threads();
    gc_policy = policy_of(gc_tid);
    const auto threads = poise::node::describe_threads();
    stop = true;
    gc.join();
    if (demoted != 1) return "demoted " + std::to_string(demoted) + " threads, expected 1";
    if (gc_policy != "other/0") return "the gc thread is " + gc_policy;
    if (!contains(threads, "gc:other/0") || !contains(threads, ":fifo/11"))
      return "describe_threads() does not show them";
    return "";
  });
  EXPECT_EQ(failure, "");
}

// A process started SCHED_FIFO by someone else (poise launch's per-component priority, chrt)
// reports it as inherited, and its housekeeping threads are demoted the same way.
TEST(RealtimeSettings, InheritedRealTimeIsReported) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root (CI runs as root)";
  const std::string failure = in_child([]() -> std::string {
    sched_param sp{};
    sp.sched_priority = 12;
    if (::sched_setscheduler(0, SCHED_FIFO, &sp) != 0) return "cannot set SCHED_FIFO";
    const auto r = poise::node::apply_process_realtime(RealtimeOptions{});
    if (!r.priority_applied || !contains(r.applied, "SCHED_FIFO 12 (inherited)"))
      return "not reported as inherited";
    std::atomic<bool> stop{false};
    std::atomic<pid_t> tid{0};
    std::thread builtins([&] {
      ::pthread_setname_np(::pthread_self(), "dq.builtins");
      tid = ::gettid();
      while (!stop) std::this_thread::sleep_for(1ms);
    });
    while (tid == 0) std::this_thread::sleep_for(1ms);
    const int demoted = poise::node::demote_housekeeping_threads(1);
    const std::string policy = policy_of(tid);
    stop = true;
    builtins.join();
    if (demoted != 1 || policy != "other/0") return "dq.builtins is " + policy;
    return "";
  });
  EXPECT_EQ(failure, "");
}

// Without the privilege (no CAP_SYS_NICE, no rtprio limit, no CAP_IPC_LOCK, memlock limit 0)
// every setting is refused with the reason and the fix, and the process keeps normal scheduling.
TEST(RealtimeSettings, RefusedWithTheReasonWithoutPrivilege) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to drop to an unprivileged user";
  const std::string failure = in_child([]() -> std::string {
    const rlimit zero{0, 0};
    ::setrlimit(RLIMIT_MEMLOCK, &zero);
    ::setrlimit(RLIMIT_RTPRIO, &zero);
    if (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0)
      return "cannot drop to nobody";
    RealtimeOptions o;
    o.priority = 11;
    o.lock_memory = true;
    const auto r = poise::node::apply_process_realtime(o);
    if (r.priority_applied || r.memory_locked) return "applied without privilege";
    if (!contains(r.refused, "SCHED_FIFO 11 refused") || !contains(r.refused, "CAP_SYS_NICE") ||
        !contains(r.refused, "running with normal scheduling"))
      return "priority refusal not explained";
    if (!contains(r.refused, "memory locking refused") || !contains(r.refused, "CAP_IPC_LOCK"))
      return "memory refusal not explained";
    if (policy_of(0) != "other/0") return "policy changed: " + policy_of(0);
    return "";
  });
  EXPECT_EQ(failure, "");
}

namespace {

fs::path work_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("poise-realtime-test-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return in ? nlohmann::json::parse(in, nullptr, false) : nlohmann::json();
}

}  // namespace

// `poise run --realtime --rt-priority 20 --lock-memory`: every process of the stack runs its
// data-path threads SCHED_FIFO at its priority (simulator 20, contact 19, controller 18,
// estimator 17), with memory locked, and the robot balances.
TEST(RealtimeSettings, PoiseRunAppliesThemToEveryProcess) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root (CI runs as root)";
  const fs::path dir = work_dir("root");
  const int domain = poise::testing::unique_domain_id();
  ChildProcess run({bin("poise"), "run", "standing", "--realtime", "--duration", "2",
                    "--rt-priority", "20", "--lock-memory", "--cpus", "0", "--domain",
                    std::to_string(domain), "-o", (dir / "run.json").string(), "--log-dir",
                    (dir / "logs").string()},
                   {}, false, true);
  const auto code = run.wait_for(120s);
  ASSERT_EQ(code.value_or(-1), 0) << run.output();
  EXPECT_NE(run.output().find("real time sim: CPUs 0, memory locked"), std::string::npos)
      << run.output();
  const auto r = read_json(dir / "run.json");
  ASSERT_TRUE(r.contains("realtime_settings")) << r.dump(2);
  const std::map<std::string, int> expected{
      {"sim", 20}, {"contact", 19}, {"controller", 18}, {"estimator", 17}};
  for (const auto& [name, prio] : expected) {
    SCOPED_TRACE(name);
    ASSERT_TRUE(r["realtime_settings"].contains(name)) << r["realtime_settings"].dump(2);
    const auto& s = r["realtime_settings"][name];
    EXPECT_TRUE(s["refused"].empty()) << s.dump(2);
    const auto applied = s["applied"].get<std::vector<std::string>>();
    EXPECT_TRUE(contains(applied, "SCHED_FIFO " + std::to_string(prio))) << s.dump(2);
    EXPECT_TRUE(contains(applied, "memory locked")) << s.dump(2);
    EXPECT_TRUE(contains(applied, "CPUs 0")) << s.dump(2);
    int fifo = 0;
    for (const auto& t : s["threads"].get<std::vector<std::string>>()) {
      const bool housekeeping = t.rfind("gc:", 0) == 0 || t.rfind("dq.builtins:", 0) == 0;
      if (housekeeping) {
        EXPECT_NE(t.find(":other/"), std::string::npos) << t;
      } else {
        EXPECT_NE(t.find(":fifo/" + std::to_string(prio)), std::string::npos) << t;
        ++fifo;
      }
    }
    EXPECT_GE(fifo, 2) << "the node's own thread and at least a DDS receive thread";
    EXPECT_TRUE(s.contains("page_faults_in_loop")) << s.dump(2);
  }
  EXPECT_TRUE(r.value("survived", false)) << r.dump(2);
}

// The same command as an unprivileged user: each process says what was refused and why, runs
// with normal scheduling, and the robot still balances.
TEST(RealtimeSettings, PoiseRunWithoutPrivilegeSaysSoAndStillBalances) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to drop to an unprivileged user";
  const fs::path dir = work_dir("nobody");
  fs::permissions(dir, fs::perms::all);
  const int domain = poise::testing::unique_domain_id();
  ChildProcess run({"/usr/bin/setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                    bin("poise"), "run", "standing", "--realtime", "--duration", "2",
                    "--rt-priority", "20", "--lock-memory", "--domain", std::to_string(domain),
                    "-o", (dir / "run.json").string(), "--log-dir", (dir / "logs").string()},
                   {}, false, true);
  const auto code = run.wait_for(120s);
  ASSERT_EQ(code.value_or(-1), 0) << run.output();
  EXPECT_NE(run.output().find("real time sim: SCHED_FIFO 20 refused"), std::string::npos)
      << run.output();
  const auto r = read_json(dir / "run.json");
  for (const char* name : {"sim", "estimator", "controller", "contact"}) {
    SCOPED_TRACE(name);
    const auto& s = r["realtime_settings"][name];
    const auto refused = s["refused"].get<std::vector<std::string>>();
    EXPECT_TRUE(contains(refused, "refused (Operation not permitted")) << s.dump(2);
    EXPECT_TRUE(s["applied"].empty()) << s.dump(2);
    for (const auto& t : s["threads"].get<std::vector<std::string>>())
      EXPECT_NE(t.find(":other/0"), std::string::npos) << t;
  }
  EXPECT_TRUE(r.value("survived", false)) << r.dump(2);
}

// A bad CPU list is refused before anything starts, naming the problem.
TEST(RealtimeSettings, PoiseRunRefusesABadCpuList) {
  ChildProcess run({bin("poise"), "run", "standing", "--cpus", "1-0"}, {}, false, true);
  const auto code = run.wait_for(30s);
  EXPECT_NE(code.value_or(0), 0) << run.output();
  EXPECT_NE(run.output().find("range '1-0' is reversed"), std::string::npos) << run.output();
}
