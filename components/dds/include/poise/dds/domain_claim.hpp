#pragma once
// DDS domain ids and the UDP ports they use on this machine.
//
// claim_free_domain(): a domain id that no other process claiming through it holds: `poise run`
// without --domain and every test process use it, so parallel runs and tests (ctest -j) never
// share a domain.
//
// Why the claimed ids stay at or below 100: a domain's well-known ports are
// 7400 + 250 x domain + 10..131 (discovery and user data of participant indices 0..60, the
// loopback configs' range). From domain 101 up they fall inside Linux's default ephemeral port
// range (32768..60999), and Cyclone DDS 0.10 transmits from a socket bound to an ephemeral port
// that it also reads. When that port happens to be another domain's discovery port, the other
// domain's participants announce themselves to it and the two domains discover each other
// (measured here: 6 runs in 12). domain_port_warning() says when a domain is exposed.
// Header-only (the tests use it without linking poise::dds).

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace poise::dds {

/// The ids claim_free_domain() hands out; 0..49 stay for users.
inline constexpr int kFirstClaimedDomain = 50;
inline constexpr int kLastClaimedDomain = 100;

/// The UDP ports domain `domain` uses on one host: participant indices 0..60 (the loopback
/// configs' MaxAutoParticipantIndex and maxInitialPeersRange), discovery and user unicast.
struct PortRange {
  int first = 0;
  int last = 0;
};
inline PortRange domain_ports(int domain) {
  const int base = 7400 + 250 * domain;
  return {base, base + 11 + 2 * 60};
}

/// Why domain `domain` can be discovered by another domain's participants on this machine, or ""
/// when it cannot. `ephemeral` is the text of /proc/sys/net/ipv4/ip_local_port_range ("32768
/// 60999"), `reserved` that of ip_local_reserved_ports ("44900-45149,50000"): ports reserved
/// there are never handed out as ephemeral ports. Unreadable text counts as Linux's default range
/// and no reservation.
inline std::string domain_port_warning(int domain, const std::string& ephemeral,
                                       const std::string& reserved) {
  int lo = 32768, hi = 60999;
  {
    std::istringstream in(ephemeral);
    int a = 0, b = 0;
    if (in >> a >> b && a > 0 && b >= a) {
      lo = a;
      hi = b;
    }
  }
  const PortRange ports = domain_ports(domain);
  const int first = std::max(ports.first, lo), last = std::min(ports.last, hi);
  if (first > last) return "";
  // Every exposed port [first, last] reserved? Then nothing ephemeral can land on it.
  int covered_up_to = first - 1;
  for (bool progress = true; progress && covered_up_to < last;) {
    progress = false;
    std::istringstream list(reserved);
    std::string item;
    while (std::getline(list, item, ',')) {
      int a = 0, b = 0;
      char dash = 0;
      std::istringstream one(item);
      if (!(one >> a)) continue;
      b = (one >> dash >> b && dash == '-') ? b : a;
      if (a <= covered_up_to + 1 && b > covered_up_to) {
        covered_up_to = b;
        progress = true;
      }
    }
  }
  if (covered_up_to >= last) return "";
  return "DDS domain " + std::to_string(domain) + " uses UDP ports " +
         std::to_string(ports.first) + ".." + std::to_string(ports.last) +
         ", inside this machine's ephemeral port range " + std::to_string(lo) + ".." +
         std::to_string(hi) +
         ": a Cyclone DDS participant of another domain can bind one of them as its transmit "
         "port and the two domains then discover each other. Use a domain id of " +
         std::to_string(kLastClaimedDomain) + " or less, or reserve the ports (sysctl "
         "net.ipv4.ip_local_reserved_ports=" +
         std::to_string(ports.first) + "-" + std::to_string(ports.last) + ")";
}

/// domain_port_warning() with this machine's kernel settings.
inline std::string domain_port_warning(int domain) {
  auto read = [](const char* path) {
    std::ifstream in(path);
    std::string text;
    std::getline(in, text);
    return text;
  };
  return domain_port_warning(domain, read("/proc/sys/net/ipv4/ip_local_port_range"),
                             read("/proc/sys/net/ipv4/ip_local_reserved_ports"));
}

/// Starting from a pid-derived id, takes an exclusive lock on /tmp/poise-dds-domain-<id>.lock and
/// holds it for the life of the process (the descriptor stays open; not inherited by children).
/// Ids kFirstClaimedDomain..kLastClaimedDomain. Throws std::runtime_error when all are taken.
inline int claim_free_domain() {
  constexpr int count = kLastClaimedDomain - kFirstClaimedDomain + 1;
  const int start = static_cast<int>(::getpid() % count);
  for (int k = 0; k < count; ++k) {
    const int id = kFirstClaimedDomain + (start + k) % count;
    const std::string path = "/tmp/poise-dds-domain-" + std::to_string(id) + ".lock";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return id;  // fd stays open: lock held
    ::close(fd);
  }
  throw std::runtime_error("no free DDS domain in " + std::to_string(kFirstClaimedDomain) + ".." +
                           std::to_string(kLastClaimedDomain) +
                           " (all /tmp/poise-dds-domain-*.lock held)");
}

}  // namespace poise::dds
