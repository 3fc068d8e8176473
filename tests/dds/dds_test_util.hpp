#pragma once
// Test helpers: a DDS domain of one's own, and bounded waiting.

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>

namespace poise::dds::test {

/// Claims a DDS domain id no other process on this machine is using through this function:
/// starting from a pid-derived id, takes an exclusive lock on /tmp/poise-dds-domain-<id>.lock and
/// holds it for the life of the process. Domains 100..231 are used (0..99 stay for users).
inline int claim_test_domain() {
  static int claimed = [] {
    const int first = 100 + static_cast<int>(::getpid() % 132);
    for (int k = 0; k < 132; ++k) {
      const int id = 100 + (first - 100 + k) % 132;
      const std::string path = "/tmp/poise-dds-domain-" + std::to_string(id) + ".lock";
      const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
      if (fd < 0) continue;
      if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return id;  // fd stays open: lock held
      ::close(fd);
    }
    throw std::runtime_error("no free DDS test domain in 100..231");
  }();
  return claimed;
}

/// Polls `done` every millisecond until it is true or `timeout` passes.
inline bool eventually(const std::function<bool()>& done,
                       std::chrono::milliseconds timeout = std::chrono::milliseconds(10000)) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

}  // namespace poise::dds::test
