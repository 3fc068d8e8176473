// Domain ids and the UDP ports they use: the claimed ids keep clear of the kernel's ephemeral
// ports (where Cyclone DDS 0.10's transmit socket lands), checked against the ports real
// participants of both vendors bind.
#include <gtest/gtest.h>

#include <poise/dds/dds.hpp>
#include <poise/dds/domain_claim.hpp>

#include <dirent.h>
#include <unistd.h>

#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "dds_test_util.hpp"

namespace poise::dds {
namespace {

// The UDP ports this process has bound, read from the kernel: socket inodes of /proc/self/fd
// matched against /proc/net/udp (local address column "0100007F:ADD4", port in hex).
std::set<int> udp_ports_of_this_process() {
  std::set<std::string> inodes;
  if (DIR* d = ::opendir("/proc/self/fd")) {
    while (const dirent* e = ::readdir(d)) {
      char target[256] = {};
      const std::string link = std::string("/proc/self/fd/") + e->d_name;
      const ssize_t n = ::readlink(link.c_str(), target, sizeof target - 1);
      const std::string t(target, n > 0 ? static_cast<std::size_t>(n) : 0);
      if (t.rfind("socket:[", 0) == 0) inodes.insert(t.substr(8, t.size() - 9));
    }
    ::closedir(d);
  }
  std::set<int> ports;
  std::ifstream udp("/proc/net/udp");
  std::string line;
  std::getline(udp, line);  // header
  while (std::getline(udp, line)) {
    std::istringstream in(line);
    std::string slot, local, remote, state, queues, timer, retr, uid, timeout, inode;
    in >> slot >> local >> remote >> state >> queues >> timer >> retr >> uid >> timeout >> inode;
    if (inodes.count(inode) == 0) continue;
    ports.insert(std::stoi(local.substr(local.find(':') + 1), nullptr, 16));
  }
  return ports;
}

TEST(DomainPorts, WarningSaysWhichPortsAreExposedAndWhichToReserve) {
  const std::string linux_default = "32768\t60999";
  // Domain 150: 7400 + 250 x 150 = 44900; indices 0..60 reach 44900 + 131.
  const std::string w = domain_port_warning(150, linux_default, "");
  EXPECT_NE(w.find("DDS domain 150 uses UDP ports 44900..45031"), std::string::npos) << w;
  EXPECT_NE(w.find("ephemeral port range 32768..60999"), std::string::npos) << w;
  EXPECT_NE(w.find("ip_local_reserved_ports=44900-45031"), std::string::npos) << w;
  // Reserved in two pieces that together cover the ports: nothing ephemeral lands there.
  EXPECT_EQ(domain_port_warning(150, linux_default, "45000-45100,100,44900-44999"), "");
  // A gap in the reservation (45031 left out) keeps the warning.
  EXPECT_NE(domain_port_warning(150, linux_default, "44900-45030"), "");
  // Domain 100 ends at 32531, below 32768; domain 101 ends at 32781, above it.
  EXPECT_EQ(domain_port_warning(100, linux_default, ""), "");
  EXPECT_NE(domain_port_warning(101, linux_default, ""), "");
  // A machine that hands out every port as ephemeral exposes even low domains.
  EXPECT_NE(domain_port_warning(kFirstClaimedDomain, "1024 65535", ""), "");
  // Unreadable settings count as Linux's default range.
  EXPECT_EQ(domain_port_warning(60, "", "garbage"), "");
  EXPECT_NE(domain_port_warning(200, "nonsense", ""), "");
}

TEST(DomainPorts, ClaimedDomainsAreClearOfThisMachinesEphemeralPorts) {
  for (int d = kFirstClaimedDomain; d <= kLastClaimedDomain; ++d)
    EXPECT_EQ(domain_port_warning(d), "") << "domain " << d;
  const int claimed = test::claim_test_domain();
  EXPECT_GE(claimed, kFirstClaimedDomain);
  EXPECT_LE(claimed, kLastClaimedDomain);
}

// The port formula against what the vendors really bind: every port a participant of the claimed
// domain binds is either inside domain_ports() or an ephemeral port (Cyclone's transmit socket,
// Fast DDS's send sockets), and ephemeral ports lie above every claimed domain's ports.
TEST(DomainPorts, RealParticipantsBindTheirDomainsPortsOrEphemeralOnesAboveAllClaimedDomains) {
  const int domain = test::claim_test_domain();
  const PortRange mine = domain_ports(domain);
  const PortRange highest_claimed = domain_ports(kLastClaimedDomain);
  for (Vendor v : {Vendor::cyclone, Vendor::fastdds}) {
    SCOPED_TRACE(to_string(v));
    const std::set<int> before = udp_ports_of_this_process();
    DdsOptions o;
    o.vendor = v;
    o.domain_id = domain;
    o.participant_name = "port-check";
    Participant p(o);
    int in_domain = 0;
    for (int port : udp_ports_of_this_process()) {
      if (before.count(port)) continue;
      if (port >= mine.first && port <= mine.last) {
        ++in_domain;
        continue;
      }
      EXPECT_GT(port, highest_claimed.last)
          << "port " << port << " is neither domain " << domain << "'s (" << mine.first << ".."
          << mine.last << ") nor above every claimed domain's";
    }
    EXPECT_GE(in_domain, 2) << "a participant binds at least a discovery and a data port";
  }
}

TEST(DomainPorts, AParticipantOfAnExposedDomainWarnsOnce) {
  if (domain_port_warning(150).empty()) GTEST_SKIP() << "domain 150 is not exposed here";
  ::testing::internal::CaptureStderr();
  {
    DdsOptions o;
    o.vendor = Vendor::cyclone;
    o.domain_id = 150;
    o.participant_name = "exposed";
    Participant a(o);
    Participant b(o);
  }
  const std::string err = ::testing::internal::GetCapturedStderr();
  const std::string line = "DDS domain 150 uses UDP ports 44900..45031";
  const auto first = err.find(line);
  EXPECT_NE(first, std::string::npos) << err;
  EXPECT_EQ(err.find(line, first + 1), std::string::npos) << "warned twice:\n" << err;
}

}  // namespace
}  // namespace poise::dds
