#pragma once
// A DDS domain id of this machine that no other process claiming through this function holds:
// `poise run` without --domain and every test process use it, so parallel runs and tests
// (ctest -j) never share a domain. Header-only (the tests use it without linking poise::dds).

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace poise::dds {

/// Starting from a pid-derived id, takes an exclusive lock on /tmp/poise-dds-domain-<id>.lock and
/// holds it for the life of the process (the descriptor stays open; not inherited by children).
/// Ids 100..231 (0..99 stay for users). Throws std::runtime_error when all are taken.
inline int claim_free_domain() {
  const int first = 100 + static_cast<int>(::getpid() % 132);
  for (int k = 0; k < 132; ++k) {
    const int id = 100 + (first - 100 + k) % 132;
    const std::string path = "/tmp/poise-dds-domain-" + std::to_string(id) + ".lock";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return id;  // fd stays open: lock held
    ::close(fd);
  }
  throw std::runtime_error(
      "no free DDS domain in 100..231 (all /tmp/poise-dds-domain-*.lock held)");
}

}  // namespace poise::dds
