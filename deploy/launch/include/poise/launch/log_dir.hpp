#pragma once
// A run's log directory, held exclusively. `poise run` and `poise launch` read their components'
// results back from summary files in the log directory; two runs sharing one (two scenarios with
// the same name started from one directory, a sweep run in parallel) would each read the other's
// files and report the wrong run without a word. So a run holds an advisory lock (flock) on
// <dir>/.lock for its whole life; the kernel drops it when the process ends, however it ends.

#include <filesystem>
#include <optional>
#include <string>

namespace poise::launch {

class LogDirLock {
 public:
  /// Creates `dir` and locks it. Returns nullopt if another live process holds it; then
  /// `*holder` (if given) says which ("pid 1234"). Throws std::runtime_error if the directory or
  /// its lock file cannot be made.
  static std::optional<LogDirLock> try_lock(const std::filesystem::path& dir,
                                            std::string* holder = nullptr);
  LogDirLock(LogDirLock&& o) noexcept;
  LogDirLock& operator=(LogDirLock&& o) noexcept;
  LogDirLock(const LogDirLock&) = delete;
  LogDirLock& operator=(const LogDirLock&) = delete;
  ~LogDirLock();

  const std::filesystem::path& dir() const noexcept { return dir_; }

 private:
  LogDirLock(std::filesystem::path dir, int fd) : dir_(std::move(dir)), fd_(fd) {}
  std::filesystem::path dir_;
  int fd_ = -1;
};

/// The log directory of a run, locked. `requested` non-empty (the user's --log-dir): that one,
/// or std::runtime_error naming the process that holds it. Empty: `<parent>/<stem>.logs`, or, if
/// another run holds that, the first free `<parent>/<stem>.2.logs`, `.3.logs`, ... (up to 999);
/// `*suffix` is then ".2" etc. (else ""), for the run's other default file names to follow.
LogDirLock claim_log_dir(const std::filesystem::path& requested,
                         const std::filesystem::path& parent, const std::string& stem,
                         std::string* suffix);

}  // namespace poise::launch
