#pragma once
// N "hosts" for multi-machine tests: one network namespace each (eth0 = 10.<net>.0.<i+1>/24),
// their veth peers ports of a bridge in one more namespace. Every link is created directly inside
// a namespace: the root namespace never sees an interface or an address of the test. Names carry
// the pid, so parallel test processes never collide; the destructor deletes the namespaces
// (which deletes the veths and the bridge with them). Needs root (CI runs as root).
#include <errno.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "child_process.hpp"

namespace poise::testing {

class NetnsHosts {
 public:
  /// `names` of the hosts; addresses 10.`net`.0.1, .2, ... in that order.
  NetnsHosts(std::vector<std::string> names, int net) : names_(std::move(names)), net_(net) {
    for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"})
      if (::access(p, X_OK) == 0) {
        ip_ = p;
        break;
      }
    static int counter = 0;
    base_ = "poise_nh_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + "_";
  }
  NetnsHosts(const NetnsHosts&) = delete;
  NetnsHosts& operator=(const NetnsHosts&) = delete;
  ~NetnsHosts() {
    for (auto it = created_.rbegin(); it != created_.rend(); ++it) {
      const auto r = run({ip_, "netns", "delete", *it});
      if (r.first != 0) std::cerr << "could not delete namespace " << *it << ": " << r.second;
    }
  }

  /// Builds the network: "" on success, else what failed (permission_denied() says if that is a
  /// missing privilege).
  std::string build() {
    if (ip_.empty()) return "no `ip` (iproute2)";
    remove_stale();
    std::vector<std::string> all = {bridge()};
    for (const auto& n : names_)
      all.push_back(ns(n));
    for (const auto& n : all) {
      const auto r = run({ip_, "netns", "add", n});
      if (r.first != 0) {
        permission_denied_ = r.second.find("Operation not permitted") != std::string::npos ||
                             r.second.find("Permission denied") != std::string::npos;
        return "ip netns add " + n + ": " + r.second;
      }
      created_.push_back(n);
    }
    std::vector<std::vector<std::string>> steps = {
        {"-n", bridge(), "link", "add", "br0", "type", "bridge"},
        {"-n", bridge(), "link", "set", "lo", "up"},
        {"-n", bridge(), "link", "set", "br0", "up"}};
    for (std::size_t i = 0; i < names_.size(); ++i) {
      const std::string port = "port" + std::to_string(i);
      const std::string n = ns(names_[i]);
      steps.push_back({"-n", n, "link", "add", "eth0", "type", "veth", "peer", "name", port,
                       "netns", bridge()});
      steps.push_back({"-n", bridge(), "link", "set", port, "master", "br0"});
      steps.push_back({"-n", bridge(), "link", "set", port, "up"});
      steps.push_back({"-n", n, "link", "set", "lo", "up"});  // Cyclone hangs with lo down
      steps.push_back({"-n", n, "address", "add", address(names_[i]) + "/24", "dev", "eth0"});
      steps.push_back({"-n", n, "link", "set", "eth0", "up"});
    }
    for (const auto& s : steps) {
      std::vector<std::string> argv{ip_};
      argv.insert(argv.end(), s.begin(), s.end());
      const auto r = run(argv);
      if (r.first != 0) return "ip " + s[2] + " ... failed: " + r.second;
    }
    return "";
  }

  bool permission_denied() const { return permission_denied_; }
  std::string ns(const std::string& host) const { return base_ + host; }
  std::string bridge() const { return base_ + "br"; }
  std::string address(const std::string& host) const {
    for (std::size_t i = 0; i < names_.size(); ++i)
      if (names_[i] == host)
        return "10." + std::to_string(net_) + ".0." + std::to_string(i + 1);
    return "";
  }

  /// `setpriv --pdeathsig KILL ip netns exec NS argv...` (one process: the pid stays, and the
  /// kernel kills it if the test process dies without cleaning up).
  std::vector<std::string> exec_in(const std::string& host, std::vector<std::string> argv) const {
    std::vector<std::string> full;
    if (::access("/usr/bin/setpriv", X_OK) == 0) full = {"/usr/bin/setpriv", "--pdeathsig", "KILL"};
    full.insert(full.end(), {ip_, "netns", "exec", ns(host)});
    full.insert(full.end(), argv.begin(), argv.end());
    return full;
  }

  /// Packets received + sent by every interface of the root namespace except lo
  /// (/proc/net/dev of this process's namespace).
  static std::uint64_t root_packets() {
    std::ifstream in("/proc/net/dev");
    std::string line;
    std::uint64_t total = 0;
    while (std::getline(in, line)) {
      const auto colon = line.find(':');
      if (colon == std::string::npos) continue;
      std::string name = line.substr(0, colon);
      name.erase(0, name.find_first_not_of(' '));
      if (name == "lo") continue;
      std::istringstream f(line.substr(colon + 1));
      std::uint64_t v[16] = {};
      for (auto& x : v)
        f >> x;
      total += v[1] + v[9];  // rx packets, tx packets
    }
    return total;
  }

 private:
  std::pair<int, std::string> run(std::vector<std::string> argv) const {
    ChildProcess p(std::move(argv), {}, false, true);
    const auto rc = p.wait_for(std::chrono::seconds(10));
    return {rc.value_or(-1), p.output()};
  }
  /// Namespaces of an earlier run of a test that was killed before its destructor ran.
  void remove_stale() const {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator("/run/netns", ec)) {
      const std::string n = e.path().filename();
      if (n.rfind("poise_nh_", 0) != 0) continue;
      const long pid = std::strtol(n.c_str() + 9, nullptr, 10);
      if (pid > 0 && pid != ::getpid() && ::kill(static_cast<pid_t>(pid), 0) != 0 &&
          errno == ESRCH)
        run({ip_, "netns", "delete", n});
    }
  }

  std::vector<std::string> names_;
  int net_;
  std::string ip_, base_;
  std::vector<std::string> created_;
  bool permission_denied_ = false;
};

}  // namespace poise::testing
