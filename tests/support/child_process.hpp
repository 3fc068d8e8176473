#pragma once
// Test support: start a real process, talk to it through pipes, and make sure it ends.
// Every child is bounded in time: wait_for() kills it (SIGTERM, then SIGKILL) by its pid when the
// deadline passes, the destructor does the same for a child still running, and a child is killed
// by the kernel if the test process itself dies (PR_SET_PDEATHSIG).

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "test_domain.hpp"

namespace poise::testing {

/// A domain id no other test running in parallel (ctest -j) uses: the lock-file claim of
/// test_domain.hpp, shared with the DDS tests.
inline int unique_domain_id() {
  return claim_test_domain();
}

/// Path of an executable in build/bin.
inline std::string bin(const std::string& name) {
  return std::string(POISE_BINARY_DIR) + "/bin/" + name;
}

class ChildProcess {
 public:
  /// Starts argv[0] (a path) with the given extra environment ("NAME=value"). stdout (and, if
  /// `merge_stderr`, stderr) is captured; stdin is a pipe when `pipe_stdin`.
  ChildProcess(std::vector<std::string> argv, std::vector<std::string> env = {},
               bool pipe_stdin = false, bool merge_stderr = false) {
    int out_pipe[2];
    int in_pipe[2] = {-1, -1};
    if (::pipe(out_pipe) != 0) throw std::runtime_error("pipe failed");
    if (pipe_stdin && ::pipe(in_pipe) != 0) throw std::runtime_error("pipe failed");
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      ::setpgid(0, 0);
      // If the test process dies (ctest timeout, crash), the kernel kills the child too.
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() == 1) ::_exit(127);  // the parent died before prctl took effect
      ::dup2(out_pipe[1], STDOUT_FILENO);
      if (merge_stderr) ::dup2(out_pipe[1], STDERR_FILENO);
      if (pipe_stdin) {
        ::dup2(in_pipe[0], STDIN_FILENO);
      } else {
        const int devnull = ::open("/dev/null", O_RDONLY);
        ::dup2(devnull, STDIN_FILENO);
      }
      for (const auto& e : env)
        ::putenv(const_cast<char*>(e.c_str()));
      std::vector<char*> args;
      for (auto& a : argv)
        args.push_back(a.data());
      args.push_back(nullptr);
      ::execv(args[0], args.data());
      ::_exit(127);
    }
    ::close(out_pipe[1]);
    out_fd_ = out_pipe[0];
    ::fcntl(out_fd_, F_SETFL, O_NONBLOCK);
    if (pipe_stdin) {
      ::close(in_pipe[0]);
      in_fd_ = in_pipe[1];
    }
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess() {
    if (!exit_code_) kill_now();
    if (out_fd_ >= 0) ::close(out_fd_);
    close_stdin();
  }

  pid_t pid() const { return pid_; }

  void write_stdin(const std::string& text) {
    if (in_fd_ < 0) throw std::logic_error("stdin is not a pipe");
    std::size_t done = 0;
    while (done < text.size()) {
      const auto n = ::write(in_fd_, text.data() + done, text.size() - done);
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
  }
  void close_stdin() {
    if (in_fd_ >= 0) ::close(in_fd_);
    in_fd_ = -1;
  }

  /// Output captured so far (reads what is available without blocking).
  const std::string& output() {
    drain(0);
    return output_;
  }

  /// Waits until `text` appears in the output or the timeout passes.
  bool wait_for_output(const std::string& text, std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (output_.find(text) == std::string::npos) {
      if (std::chrono::steady_clock::now() >= end || exited())
        return output().find(text) != std::string::npos;
      drain(10);
    }
    return true;
  }

  /// Waits for the exit; past the timeout, kills the child and returns nullopt.
  std::optional<int> wait_for(std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!exited()) {
      if (std::chrono::steady_clock::now() >= end) {
        kill_now();
        return std::nullopt;
      }
      drain(10);
    }
    drain(0);
    return exit_code_;
  }

  /// Asks the child to stop (SIGINT) and waits up to `grace`; then kills it.
  std::optional<int> interrupt(std::chrono::milliseconds grace = std::chrono::milliseconds(3000)) {
    if (!exited()) ::kill(pid_, SIGINT);
    return wait_for(grace);
  }

 private:
  bool exited() {
    if (exit_code_) return true;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      return true;
    }
    return false;
  }
  void drain(int timeout_ms) {
    if (out_fd_ < 0) return;
    pollfd p{out_fd_, POLLIN, 0};
    if (timeout_ms > 0) ::poll(&p, 1, timeout_ms);
    char buf[65536];
    for (;;) {
      const auto n = ::read(out_fd_, buf, sizeof(buf));
      if (n <= 0) break;
      output_.append(buf, static_cast<std::size_t>(n));
    }
  }
  void kill_now() {
    if (pid_ <= 0 || exited()) return;
    ::kill(pid_, SIGTERM);
    for (int i = 0; i < 100 && !exited(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (!exited()) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      ::waitpid(pid_, &status, 0);
      exit_code_ = 128 + SIGKILL;
    }
  }

  pid_t pid_ = -1;
  int out_fd_ = -1;
  int in_fd_ = -1;
  std::string output_;
  std::optional<int> exit_code_;
};

/// Runs argv to its end (killed by its pid past `limit`) and returns its exit code (-1 when it
/// was killed or did not start) with what it printed, stdout and stderr together.
inline std::pair<int, std::string> run_command(std::vector<std::string> argv,
                                               std::chrono::milliseconds limit) {
  ChildProcess p(std::move(argv), {}, false, true);
  const auto code = p.wait_for(limit);
  return {code.value_or(-1), p.output()};
}

}  // namespace poise::testing
