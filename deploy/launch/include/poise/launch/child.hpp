#pragma once
// A child process of the launcher: stdout and stderr go to files, it gets its own process group
// (so the terminal's Ctrl-C reaches the launcher, which stops the children in order), it is
// always ended by its pid, and it gets SIGTERM from the kernel when the launcher dies
// (PR_SET_PDEATHSIG): no orphan survives the launcher, whatever signal ends it.

#include <sys/types.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace poise::launch {

/// CPU affinity and real-time priority of a child, set before it runs (its threads inherit them).
/// What the kernel refuses is written to the child's stderr log; the child runs anyway.
struct Scheduling {
  std::vector<int> cpus;  ///< empty: any CPU
  int priority = 0;       ///< SCHED_FIFO 1..99; 0: normal scheduling
};

class Child {
 public:
  /// Starts argv[0] (a path; a bare name is looked up in PATH). Throws std::runtime_error when
  /// fork or exec preparation fails.
  Child(std::string name, std::vector<std::string> argv, const std::filesystem::path& log_dir,
        const Scheduling& scheduling = {});
  ~Child();
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  const std::string& name() const { return name_; }
  pid_t pid() const { return pid_; }
  std::string command_line() const;
  /// The exit code (128 + signal when killed) once the child ended, else nullopt. Non-blocking.
  std::optional<int> poll();
  /// The way it ended, in words: "exited with code 2", "killed by SIGKILL (Killed, code 137)".
  std::string exit_description() const;
  /// SIGTERM, wait up to `grace_ms`, then SIGKILL. Returns the exit code.
  int stop(int grace_ms);
  const std::filesystem::path& stdout_path() const { return out_path_; }
  const std::filesystem::path& stderr_path() const { return err_path_; }
  /// The last `n` lines of the child's stderr.
  std::string stderr_tail(int n) const;

 private:
  std::string name_;
  std::vector<std::string> argv_;
  std::filesystem::path out_path_, err_path_;
  pid_t pid_ = -1;
  std::optional<int> exit_code_;
  int signal_ = 0;  ///< the signal that ended it, 0 if it exited
};

/// An exit in words; `signal` > 0 if a signal ended the process (then code = 128 + signal).
std::string describe_exit(int code, int signal);

/// Follows a growing text file (a child's stdout) and hands out its complete new lines.
class LineFollower {
 public:
  explicit LineFollower(std::filesystem::path path) : path_(std::move(path)) {}
  /// Lines completed since the last call (a partial last line waits for its end).
  std::vector<std::string> poll();

 private:
  std::filesystem::path path_;
  std::ifstream in_;
  std::string partial_;
};

/// The last `n` lines of a text file ("" if unreadable).
std::string tail_lines(const std::filesystem::path& path, int n);

}  // namespace poise::launch
