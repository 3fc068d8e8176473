#include "poise/launch/child.hpp"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <ctime>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace poise::launch {
namespace {

/// In a log that already holds an earlier instance's output, a line saying that a new one starts.
void mark_new_instance(int fd) {
  struct stat st{};
  if (::fstat(fd, &st) != 0 || st.st_size == 0) return;
  const std::time_t now = std::time(nullptr);
  char when[32] = "";
  std::tm tm{};
  if (::localtime_r(&now, &tm) != nullptr) std::strftime(when, sizeof when, "%F %T", &tm);
  ::dprintf(fd, "\n----- poise launch: a new instance starts here (%s) -----\n", when);
}

}  // namespace

Child::Child(std::string name, std::vector<std::string> argv, const std::filesystem::path& log_dir,
             const Scheduling& scheduling)
    : name_(std::move(name)),
      argv_(std::move(argv)),
      out_path_(log_dir / (name_ + ".out")),
      err_path_(log_dir / (name_ + ".err")) {
  // Appended, never truncated: a restarted component's log follows its predecessor's, whose
  // last words tell why it was restarted. A line marks where each later instance begins.
  const int out = ::open(out_path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  const int err = ::open(err_path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (out < 0 || err < 0)
    throw std::runtime_error("cannot create the log files of " + name_ + " in " + log_dir.string());
  mark_new_instance(out);
  mark_new_instance(err);
  std::vector<char*> args;
  for (auto& a : argv_)
    args.push_back(a.data());
  args.push_back(nullptr);
  const pid_t parent = ::getpid();
  pid_ = ::fork();
  if (pid_ < 0) throw std::runtime_error("fork failed for " + name_);
  if (pid_ == 0) {
    ::setpgid(0, 0);
    // The launcher owns its children: when it dies, whatever the signal (SIGKILL included),
    // the kernel sends each child SIGTERM, which every Poise process handles by finishing
    // cleanly (the recorder closes its file). The launcher may have died before prctl ran.
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(128 + SIGTERM);
    ::dup2(out, STDOUT_FILENO);
    ::dup2(err, STDERR_FILENO);
    const int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) ::dup2(devnull, STDIN_FILENO);
    if (!scheduling.cpus.empty()) {
      cpu_set_t set;
      CPU_ZERO(&set);
      for (int c : scheduling.cpus)
        CPU_SET(c, &set);
      if (::sched_setaffinity(0, sizeof(set), &set) != 0)
        ::dprintf(STDERR_FILENO, "launcher: CPU affinity refused (%s): running on any CPU\n",
                  ::strerror(errno));
    }
    if (scheduling.priority > 0) {
      sched_param sp{};
      sp.sched_priority = scheduling.priority;
      if (::sched_setscheduler(0, SCHED_FIFO, &sp) != 0)
        ::dprintf(STDERR_FILENO,
                  "launcher: SCHED_FIFO %d refused (%s; needs root, CAP_SYS_NICE or an "
                  "RLIMIT_RTPRIO of at least %d): running with normal scheduling\n",
                  scheduling.priority, ::strerror(errno), scheduling.priority);
    }
    ::execvp(args[0], args.data());
    const std::string msg = "exec " + argv_[0] + " failed\n";
    [[maybe_unused]] auto w = ::write(STDERR_FILENO, msg.data(), msg.size());
    ::_exit(127);
  }
  ::close(out);
  ::close(err);
}

Child::~Child() {
  if (!exit_code_) stop(2000);
}

std::string Child::command_line() const {
  std::string s;
  for (const auto& a : argv_)
    s += (s.empty() ? "" : " ") + a;
  return s;
}

std::optional<int> Child::poll() {
  if (exit_code_ || pid_ <= 0) return exit_code_;
  int status = 0;
  if (::waitpid(pid_, &status, WNOHANG) == pid_) {
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    signal_ = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  }
  return exit_code_;
}

std::string Child::exit_description() const {
  if (!exit_code_) return "still running";
  return describe_exit(*exit_code_, signal_);
}

std::string describe_exit(int code, int signal) {
  if (signal > 0) {
    const char* abbrev = ::sigabbrev_np(signal);
    const char* what = ::strsignal(signal);
    return std::string("killed by SIG") + (abbrev ? abbrev : std::to_string(signal).c_str()) +
           " (" + (what ? what : "signal") + ", code " + std::to_string(128 + signal) + ")";
  }
  if (code == 0) return "exited normally (code 0)";
  if (code == 127) return "could not be started (code 127: exec failed)";
  return "exited with code " + std::to_string(code);
}

int Child::stop(int grace_ms) {
  if (poll()) return *exit_code_;
  ::kill(pid_, SIGTERM);
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(grace_ms);
  while (!poll() && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (!poll()) {
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    exit_code_ = 128 + SIGKILL;
    signal_ = SIGKILL;
  }
  return *exit_code_;
}

std::vector<std::string> LineFollower::poll() {
  std::vector<std::string> out;
  if (!in_.is_open()) in_.open(path_);
  if (!in_.is_open()) return out;
  in_.clear();
  std::string line;
  while (std::getline(in_, line)) {
    if (in_.eof()) {  // no newline yet: keep it for later
      partial_ += line;
      break;
    }
    out.push_back(partial_ + line);
    partial_.clear();
  }
  return out;
}

std::string Child::stderr_tail(int n) const {
  return tail_lines(err_path_, n);
}

std::string tail_lines(const std::filesystem::path& path, int n) {
  std::ifstream in(path);
  if (!in) return "";
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    lines.push_back(line);
    if (static_cast<int>(lines.size()) > n) lines.erase(lines.begin());
  }
  std::string out;
  for (const auto& l : lines)
    out += l + "\n";
  return out;
}

}  // namespace poise::launch
