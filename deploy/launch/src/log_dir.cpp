#include "poise/launch/log_dir.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace poise::launch {

namespace fs = std::filesystem;

std::optional<LogDirLock> LogDirLock::try_lock(const fs::path& dir, std::string* holder) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec)
    throw std::runtime_error("cannot create the log directory " + dir.string() + ": " +
                             ec.message());
  const fs::path file = dir / ".lock";
  // O_CLOEXEC: the components started from this process must not keep the lock after it ends.
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0)
    throw std::runtime_error("cannot open " + file.string() + ": " + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    if (err != EWOULDBLOCK) {
      ::close(fd);
      throw std::runtime_error("cannot lock " + file.string() + ": " + std::strerror(err));
    }
    if (holder) {
      char buf[32] = {};
      const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
      *holder = n > 0 ? "pid " + std::string(buf, static_cast<std::size_t>(n)) : "another process";
      while (!holder->empty() && (holder->back() == '\n' || holder->back() == ' '))
        holder->pop_back();
    }
    ::close(fd);
    return std::nullopt;
  }
  // Who holds it, for the next run's message.
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) < 0) {
    // The lock holds without the pid; the message then says "pid " with nothing: harmless.
  }
  return LogDirLock(dir, fd);
}

LogDirLock::LogDirLock(LogDirLock&& o) noexcept
    : dir_(std::move(o.dir_)), fd_(std::exchange(o.fd_, -1)) {}

LogDirLock& LogDirLock::operator=(LogDirLock&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    dir_ = std::move(o.dir_);
    fd_ = std::exchange(o.fd_, -1);
  }
  return *this;
}

LogDirLock::~LogDirLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the last descriptor releases the flock
}

LogDirLock claim_log_dir(const fs::path& requested, const fs::path& parent, const std::string& stem,
                         std::string* suffix) {
  if (suffix) suffix->clear();
  std::string holder;
  if (!requested.empty()) {
    if (auto l = LogDirLock::try_lock(requested, &holder)) return std::move(*l);
    throw std::runtime_error("the log directory " + requested.string() +
                             " is in use by another run (" + holder +
                             "): give each run running at the same time its own --log-dir");
  }
  for (int n = 1; n <= 999; ++n) {
    std::string sfx;
    if (n > 1) sfx.append(1, '.').append(std::to_string(n));
    if (auto l = LogDirLock::try_lock(parent / (stem + sfx + ".logs"), &holder)) {
      if (suffix) *suffix = sfx;
      return std::move(*l);
    }
  }
  throw std::runtime_error("the log directories " + (parent / (stem + ".logs")).string() + " to " +
                           stem + ".999.logs are all in use: pass --log-dir");
}

}  // namespace poise::launch
