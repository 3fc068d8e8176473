#pragma once
// A DDS domain of one's own for every test process, so that tests run in parallel (ctest -j)
// never discover each other's participants.

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace poise::testing {

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

}  // namespace poise::testing
