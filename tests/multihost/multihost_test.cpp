// The multi-host DDS templates (deploy/dds/*-multihost.xml) as users deploy them, on one machine:
// two "hosts" are network namespaces whose veth ends meet on a bridge inside a third namespace.
// Each host runs `poise topic` with its own configuration filled in from the template; the only
// path between the hosts is that bridge. Nothing is configured in the root namespace, and no DDS
// traffic exists outside the namespaces the test creates (and deletes, also on failure).
// Needs root (CI runs as root); without permission to create namespaces the tests skip.
#include <arpa/inet.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <poise/reflect/fill.hpp>
#include <poise/reflect/json.hpp>

#include "child_process.hpp"

namespace {

using namespace std::chrono_literals;
using poise::testing::ChildProcess;
namespace fs = std::filesystem;

constexpr const char* kAddressA = "10.77.0.1";
constexpr const char* kAddressB = "10.77.0.2";
constexpr const char* kPrefix = "10.77.0.";  // the test's private /24, inside its namespaces only
// Publishers run at 20 Hz "until stopped" (the test interrupts them once the echo is done); the
// count only bounds them to 60 s should everything else fail.
constexpr const char* kPubCount = "1200";

/// iproute2's `ip`, wherever this distribution puts it; empty if absent.
std::string ip_binary() {
  for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"})
    if (::access(p, X_OK) == 0) return p;
  return {};
}

struct RunResult {
  std::optional<int> rc;  ///< nullopt: killed at the deadline
  std::string output;     ///< stdout and stderr
};

/// Runs a short command to completion (killed by its pid after 10 s).
RunResult run(std::vector<std::string> argv) {
  ChildProcess p(std::move(argv), {}, false, /*merge_stderr=*/true);
  RunResult r;
  r.rc = p.wait_for(10s);
  r.output = p.output();
  return r;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v)
    s += (s.empty() ? "" : " ") + x;
  return s;
}

/// Every interface address of the namespace this test process runs in (the root one), sorted.
std::vector<std::string> own_namespace_addresses() {
  std::vector<std::string> out;
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return {"getifaddrs failed"};
  for (ifaddrs* i = list; i != nullptr; i = i->ifa_next) {
    std::string entry = i->ifa_name;
    char text[INET6_ADDRSTRLEN] = "";
    if (i->ifa_addr != nullptr && i->ifa_addr->sa_family == AF_INET) {
      ::inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(i->ifa_addr)->sin_addr, text,
                  sizeof(text));
      entry += std::string(" inet ") + text;
    } else if (i->ifa_addr != nullptr && i->ifa_addr->sa_family == AF_INET6) {
      ::inet_ntop(AF_INET6, &reinterpret_cast<sockaddr_in6*>(i->ifa_addr)->sin6_addr, text,
                  sizeof(text));
      entry += std::string(" inet6 ") + text;
    }
    out.push_back(entry);
  }
  ::freeifaddrs(list);
  std::sort(out.begin(), out.end());
  return out;
}

/// Local IPv4 addresses of the UDP sockets in the network namespace of `pid` ("self": ours).
std::vector<std::string> udp_local_addresses(const std::string& pid) {
  std::ifstream in("/proc/" + pid + "/net/udp");
  std::vector<std::string> out;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string slot, local;
    fields >> slot >> local;  // "0100007F:1CE8": s_addr as the kernel stores it, in hex
    in_addr a{};
    a.s_addr = static_cast<std::uint32_t>(std::stoul(local.substr(0, 8), nullptr, 16));
    char text[INET_ADDRSTRLEN] = "";
    ::inet_ntop(AF_INET, &a, text, sizeof(text));
    out.emplace_back(text);
  }
  return out;
}

ino_t inode_of(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? st.st_ino : 0;
}

/// Waits until `ip netns exec` has replaced itself with poise in process `pid` (same pid).
bool wait_until_poise(pid_t pid) {
  const auto end = std::chrono::steady_clock::now() + 10s;
  const fs::path exe = "/proc/" + std::to_string(pid) + "/exe";
  while (std::chrono::steady_clock::now() < end) {
    std::error_code ec;
    if (fs::read_symlink(exe, ec).filename() == "poise") return true;
    std::this_thread::sleep_for(2ms);
  }
  return false;
}

/// Two hosts (namespaces A and B, eth0 = 10.77.0.1/24 and 10.77.0.2/24) whose veth peers are
/// ports of the bridge br0 in a third namespace. Every link is created directly inside a
/// namespace: the root namespace never sees an interface or an address of the test. Names carry
/// the pid, so parallel test processes never collide; the destructor deletes the namespaces
/// (which deletes the veths and the bridge with them).
class TwoHosts {
 public:
  explicit TwoHosts(std::string ip) : ip_(std::move(ip)) {
    static int counter = 0;
    const std::string base =
        "poise_mh_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + "_";
    a_ = base + "a";
    b_ = base + "b";
    br_ = base + "br";
  }
  TwoHosts(const TwoHosts&) = delete;
  TwoHosts& operator=(const TwoHosts&) = delete;
  ~TwoHosts() {
    for (auto it = created_.rbegin(); it != created_.rend(); ++it) {
      const auto r = run({ip_, "netns", "delete", *it});
      if (r.rc != 0) std::cerr << "could not delete namespace " << *it << ": " << r.output;
    }
  }

  /// Builds the network. Returns an empty string on success, else what failed; sets
  /// permission_denied() when the failure is a missing privilege.
  std::string build() {
    remove_stale_namespaces();
    for (const auto& ns : {a_, b_, br_}) {
      const auto r = run({ip_, "netns", "add", ns});
      if (r.rc != 0) {
        permission_denied_ = r.output.find("Operation not permitted") != std::string::npos ||
                             r.output.find("Permission denied") != std::string::npos;
        return "ip netns add " + ns + ": " + r.output;
      }
      created_.push_back(ns);
    }
    const std::vector<std::vector<std::string>> steps = {
        {"-n", br_, "link", "add", "br0", "type", "bridge"},
        {"-n", a_, "link", "add", "eth0", "type", "veth", "peer", "name", "port_a", "netns", br_},
        {"-n", b_, "link", "add", "eth0", "type", "veth", "peer", "name", "port_b", "netns", br_},
        {"-n", br_, "link", "set", "port_a", "master", "br0"},
        {"-n", br_, "link", "set", "port_b", "master", "br0"},
        {"-n", a_, "link", "set", "lo", "up"},  // Cyclone hangs in dds_delete with lo down
        {"-n", b_, "link", "set", "lo", "up"},
        {"-n", br_, "link", "set", "lo", "up"},
        {"-n", br_, "link", "set", "br0", "up"},
        {"-n", br_, "link", "set", "port_a", "up"},
        {"-n", br_, "link", "set", "port_b", "up"},
        {"-n", a_, "address", "add", std::string(kAddressA) + "/24", "dev", "eth0"},
        {"-n", b_, "address", "add", std::string(kAddressB) + "/24", "dev", "eth0"},
        {"-n", a_, "link", "set", "eth0", "up"},
        {"-n", b_, "link", "set", "eth0", "up"},
    };
    for (const auto& step : steps) {
      if (auto e = ip(step); !e.empty()) return e;
    }
    return {};
  }

  /// Runs `ip args...`; returns an empty string on success, else the command and its output.
  std::string ip(const std::vector<std::string>& args) const {
    std::vector<std::string> argv{ip_};
    argv.insert(argv.end(), args.begin(), args.end());
    const auto r = run(argv);
    return r.rc == 0 ? std::string() : "'" + join(argv) + "' failed: " + r.output;
  }

  /// Bytes received by eth0 of host `ns` so far (from `ip -s -j link`).
  std::uint64_t rx_bytes(const std::string& ns) const {
    const auto r = run({ip_, "-n", ns, "-s", "-j", "link", "show", "dev", "eth0"});
    if (r.rc != 0) return 0;
    const auto j = poise::reflect::Json::parse(r.output, nullptr, false);
    if (j.is_discarded() || !j.is_array() || j.empty()) return 0;
    return j[0]["stats64"]["rx"]["bytes"].get<std::uint64_t>();
  }

  /// `setpriv --pdeathsig KILL ip netns exec NS argv...`: one process (setpriv and ip exec in
  /// place, the pid stays), killed by the kernel if this test process dies without cleaning up
  /// (e.g. killed at ctest's timeout), so no DDS process outlives the test.
  std::vector<std::string> exec_in(const std::string& ns, std::vector<std::string> argv) const {
    std::vector<std::string> full;
    if (::access("/usr/bin/setpriv", X_OK) == 0) full = {"/usr/bin/setpriv", "--pdeathsig", "KILL"};
    full.insert(full.end(), {ip_, "netns", "exec", ns});
    full.insert(full.end(), argv.begin(), argv.end());
    return full;
  }

  bool permission_denied() const { return permission_denied_; }
  const std::string& a() const { return a_; }
  const std::string& b() const { return b_; }
  const std::string& bridge() const { return br_; }

 private:
  /// Namespaces and temp dirs left by an earlier run of this test that was killed (e.g. at
  /// ctest's timeout) before its destructors ran: the pid in their name is gone.
  void remove_stale_namespaces() const {
    std::error_code ec;
    for (const fs::path& dir : {fs::path("/run/netns"), fs::temp_directory_path(ec)}) {
      std::vector<fs::path> stale;
      for (const auto& entry : fs::directory_iterator(dir, ec)) {
        const std::string name = entry.path().filename();
        if (name.rfind("poise_mh_", 0) != 0) continue;
        const long pid = std::strtol(name.c_str() + 9, nullptr, 10);
        if (pid > 0 && pid != ::getpid() && ::kill(static_cast<pid_t>(pid), 0) != 0 &&
            errno == ESRCH)
          stale.push_back(entry.path());
      }
      for (const auto& path : stale) {
        if (dir == "/run/netns") {
          run({ip_, "netns", "delete", path.filename()});
        } else {
          fs::remove_all(path, ec);
        }
      }
    }
  }

  std::string ip_;
  std::string a_, b_, br_;
  std::vector<std::string> created_;
  bool permission_denied_ = false;
};

/// A directory of its own under the temp dir, removed with its content at the end.
class TempDir {
 public:
  TempDir() {
    std::string pattern =
        (fs::temp_directory_path() / ("poise_mh_" + std::to_string(::getpid()) + "_XXXXXX"))
            .string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  if (!in) throw std::runtime_error("cannot read " + p.string());
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path template_path(const std::string& vendor) {
  return fs::path(POISE_SOURCE_DIR) / "deploy" / "dds" / (vendor + "-multihost.xml");
}

/// The placeholders of the templates and their values for a host at `local`.
std::map<std::string, std::string> placeholders(const std::string& local) {
  return {{"POISE_LOCAL_ADDRESS", local}, {"POISE_PEER_1", kAddressA}, {"POISE_PEER_2", kAddressB}};
}

/// What README.md tells users to do with sed: replace every ${NAME}. Throws if a ${POISE_...}
/// placeholder is left over (the template grew one the documentation does not know).
std::string fill_template(std::string text, const std::map<std::string, std::string>& values) {
  for (const auto& [name, value] : values) {
    const std::string key = "${" + name + "}";
    for (auto at = text.find(key); at != std::string::npos; at = text.find(key, at + value.size()))
      text.replace(at, key.size(), value);
  }
  if (const auto left = text.find("${POISE_"); left != std::string::npos)
    throw std::runtime_error("placeholder left in the filled template: " +
                             text.substr(left, text.find('}', left) - left + 1));
  return text;
}

/// How one host is configured: a config file, and environment variables for the process.
struct HostConfig {
  std::string path;
  std::vector<std::string> env;
};

/// Fast DDS: always a filled-in copy (Fast DDS 2.9 does not expand ${VAR}). Cyclone: the template
/// itself with the placeholders exported as environment variables (`use_env`), or a filled copy.
HostConfig host_config(const std::string& vendor, const std::string& local, bool use_env,
                       const fs::path& dir) {
  const auto values = placeholders(local);
  HostConfig c;
  if (vendor == "cyclone" && use_env) {
    c.path = template_path(vendor).string();
    for (const auto& [name, value] : values)
      c.env.push_back(name + "=" + value);
    return c;
  }
  const fs::path out = dir / (vendor + "-" + local + ".xml");
  std::ofstream(out) << fill_template(read_file(template_path(vendor)), values);
  c.path = out.string();
  return c;
}

std::vector<std::string> topic_cmd(const std::string& vendor, const HostConfig& config,
                                   std::vector<std::string> verb) {
  std::vector<std::string> v{poise::testing::bin("poise"),
                             "topic",
                             "--dds",
                             vendor,
                             "--dds-config",
                             config.path,
                             "--domain",
                             std::to_string(poise::testing::unique_domain_id())};
  v.insert(v.end(), verb.begin(), verb.end());
  return v;
}

std::string echo_line(ChildProcess& echo) {
  const auto& out = echo.output();
  return out.substr(0, out.find('\n'));
}

struct Pairing {
  const char* writer;  ///< vendor of `poise topic pub` on host A
  const char* reader;  ///< vendor of `poise topic echo` on host B
};
void PrintTo(const Pairing& p, std::ostream* os) {
  *os << p.writer << " -> " << p.reader;
}

/// Two hosts, built before each test and deleted after it; skips without the privilege.
class MultiHostFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    if (::geteuid() != 0) {
      GTEST_SKIP() << "multi-host DDS test needs root to create network namespaces";
    }
    ip_ = ip_binary();
    ASSERT_FALSE(ip_.empty()) << "iproute2's 'ip' not found (deploy/bootstrap.sh installs it)";
    root_before_ = own_namespace_addresses();
    hosts_ = std::make_unique<TwoHosts>(ip_);
    const auto error = hosts_->build();
    if (!error.empty() && hosts_->permission_denied()) {
      GTEST_SKIP() << "cannot create network namespaces here (" << error << ")";
    }
    ASSERT_TRUE(error.empty()) << error;
  }
  void TearDown() override {
    hosts_.reset();
    // The root namespace is as it was: the test never put an interface or address there.
    if (!root_before_.empty()) {
      EXPECT_EQ(own_namespace_addresses(), root_before_);
    }
  }

  /// Checks that process `pid` runs poise in the network namespace `ns`, not in ours, and has a
  /// UDP socket on `address` there.
  void expect_in_namespace(pid_t pid, const std::string& ns, const std::string& address) {
    ASSERT_TRUE(wait_until_poise(pid)) << "pid " << pid << " never became poise";
    const std::string proc = "/proc/" + std::to_string(pid);
    const ino_t ns_inode = inode_of("/run/netns/" + ns);
    ASSERT_NE(ns_inode, 0u);
    EXPECT_EQ(inode_of(proc + "/ns/net"), ns_inode) << "pid " << pid << " is not in " << ns;
    EXPECT_NE(inode_of("/proc/self/ns/net"), ns_inode);
    // Sockets appear once the participant exists: poll a little.
    const auto end = std::chrono::steady_clock::now() + 10s;
    std::vector<std::string> udp;
    while (std::chrono::steady_clock::now() < end) {
      udp = udp_local_addresses(std::to_string(pid));
      if (std::find(udp.begin(), udp.end(), address) != udp.end()) return;
      std::this_thread::sleep_for(10ms);
    }
    ADD_FAILURE() << "no UDP socket on " << address << " in " << ns
                  << " (sockets there: " << join(udp) << ")";
  }

  std::string ip_;
  std::vector<std::string> root_before_;
  std::unique_ptr<TwoHosts> hosts_;
};

class MultiHost : public MultiHostFixture, public ::testing::WithParamInterface<Pairing> {};

// Host A publishes with vendor X, host B echoes with vendor Y; the sample crosses the bridge
// unchanged. The Cyclone publisher runs on the unmodified template with the placeholders in its
// environment (Cyclone expands ${VAR}); every other process runs on a filled-in copy.
TEST_P(MultiHost, EchoOnHostBShowsWhatHostAPublished) {
  const auto [writer, reader] = GetParam();
  TempDir dir;
  const HostConfig config_a = host_config(writer, kAddressA, /*use_env=*/true, dir.path());
  const HostConfig config_b = host_config(reader, kAddressB, /*use_env=*/false, dir.path());

  std::mt19937_64 rng(20240611);
  poise::msg::ContactProblem sample;
  poise::reflect::fill_random(sample, rng);
  const std::string json = poise::reflect::to_json(sample).dump();

  const auto rx_before = hosts_->rx_bytes(hosts_->b());
  const auto t0 = std::chrono::steady_clock::now();
  ChildProcess echo(
      hosts_->exec_in(hosts_->b(), topic_cmd(reader, config_b,
                                             {"echo", "poise/contact_problem", "--json", "--once",
                                              "--timeout", "20"})),
      config_b.env);
  expect_in_namespace(echo.pid(), hosts_->b(), kAddressB);
  ChildProcess pub(hosts_->exec_in(hosts_->a(), topic_cmd(writer, config_a,
                                                          {"pub", "poise/contact_problem", json,
                                                           "--rate", "20", "--count", kPubCount})),
                   config_a.env, false, /*merge_stderr=*/true);
  expect_in_namespace(pub.pid(), hosts_->a(), kAddressA);
  // Nothing of the test is visible in the root namespace while the DDS processes run.
  EXPECT_EQ(own_namespace_addresses(), root_before_);
  for (const auto& a : udp_local_addresses("self"))
    EXPECT_NE(a.rfind(kPrefix, 0), 0u) << "UDP socket on " << a << " in the root namespace";

  const auto rc = echo.wait_for(30s);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(rc.has_value()) << "echo did not finish; output: " << echo.output();
  EXPECT_EQ(*rc, 0) << "echo: " << echo.output() << "\npub: " << pub.output();
  const auto pub_rc = pub.interrupt();
  EXPECT_TRUE(pub_rc.has_value()) << "pub did not stop on SIGINT: " << pub.output();

  // What B printed is what A sent, field by field and as JSON.
  const std::string line = echo_line(echo);
  ASSERT_FALSE(line.empty()) << "echo printed nothing; pub: " << pub.output();
  poise::msg::ContactProblem received;
  poise::reflect::from_json(poise::reflect::Json::parse(line), received);
  const auto diff = poise::reflect::first_difference(sample, received);
  EXPECT_FALSE(diff) << *diff;
  EXPECT_EQ(poise::reflect::Json::parse(line), poise::reflect::Json::parse(json));

  // ... and it came in through B's only link: eth0, the veth to the bridge.
  const auto rx_after = hosts_->rx_bytes(hosts_->b());
  EXPECT_GT(rx_after, rx_before + 1000) << "B's eth0 saw (almost) no traffic";
  std::cout << "[ timing ] " << writer << " on host A -> " << reader
            << " on host B: echo started to sample printed " << seconds << " s; B's eth0 received "
            << (rx_after - rx_before) << " bytes\n";
}

INSTANTIATE_TEST_SUITE_P(
    Vendors, MultiHost,
    ::testing::Values(Pairing{"cyclone", "cyclone"}, Pairing{"fastdds", "fastdds"},
                      Pairing{"cyclone", "fastdds"}, Pairing{"fastdds", "cyclone"}),
    [](const auto& info) { return std::string(info.param.writer) + "_to_" + info.param.reader; });

// Control: the bridge is the only path. With br0 down, B hears nothing; with it up again, the
// same processes' configuration delivers.
class MultiHostControl : public MultiHostFixture {};

TEST_F(MultiHostControl, NothingArrivesWhileTheBridgeIsDown) {
  TempDir dir;
  const HostConfig config_a = host_config("cyclone", kAddressA, false, dir.path());
  const HostConfig config_b = host_config("fastdds", kAddressB, false, dir.path());
  const std::string json = R"({"node":"bridge_control"})";
  ASSERT_EQ(hosts_->ip({"-n", hosts_->bridge(), "link", "set", "br0", "down"}), "");

  ChildProcess pub(
      hosts_->exec_in(hosts_->a(), topic_cmd("cyclone", config_a,
                                             {"pub", "poise/diagnostics", json, "--rate", "20",
                                              "--count", kPubCount, "--wait-readers", "0"})),
      config_a.env, false, true);
  {
    ChildProcess echo(hosts_->exec_in(hosts_->b(), topic_cmd("fastdds", config_b,
                                                             {"echo", "poise/diagnostics", "--json",
                                                              "--once", "--timeout", "3"})),
                      config_b.env);
    const auto rc = echo.wait_for(20s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 1) << "a sample arrived with the bridge down: " << echo.output();
    EXPECT_EQ(echo.output(), "");
  }
  ASSERT_EQ(hosts_->ip({"-n", hosts_->bridge(), "link", "set", "br0", "up"}), "");
  ChildProcess echo(hosts_->exec_in(hosts_->b(), topic_cmd("fastdds", config_b,
                                                           {"echo", "poise/diagnostics", "--json",
                                                            "--once", "--timeout", "20"})),
                    config_b.env);
  const auto rc = echo.wait_for(30s);
  pub.interrupt();
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << echo.output() << "\npub: " << pub.output();
  EXPECT_NE(echo_line(echo).find("\"node\":\"bridge_control\""), std::string::npos)
      << echo.output();
}

// Several processes on one host, both vendors, all on the multi-host files (a deployment runs its
// whole stack and its tools on them): they find each other through the host's own address.
TEST_F(MultiHostControl, BothVendorsOnOneHost) {
  TempDir dir;
  const HostConfig cyclone = host_config("cyclone", kAddressA, true, dir.path());
  const HostConfig fastdds = host_config("fastdds", kAddressA, false, dir.path());
  for (const auto& [writer, reader] :
       std::vector<Pairing>{{"cyclone", "fastdds"}, {"fastdds", "cyclone"}}) {
    const HostConfig& w = std::string(writer) == "cyclone" ? cyclone : fastdds;
    const HostConfig& r = std::string(reader) == "cyclone" ? cyclone : fastdds;
    const std::string json = std::string(R"({"node":"from_)") + writer + "\"}";
    ChildProcess echo(hosts_->exec_in(hosts_->a(), topic_cmd(reader, r,
                                                             {"echo", "poise/diagnostics", "--json",
                                                              "--once", "--timeout", "20"})),
                      r.env);
    ChildProcess pub(
        hosts_->exec_in(hosts_->a(), topic_cmd(writer, w,
                                               {"pub", "poise/diagnostics", json, "--rate", "20",
                                                "--count", kPubCount})),
        w.env, false, true);
    const auto rc = echo.wait_for(30s);
    pub.interrupt();
    ASSERT_TRUE(rc.has_value()) << writer << " -> " << reader;
    EXPECT_EQ(*rc, 0) << writer << " -> " << reader << ": " << echo.output()
                      << "\npub: " << pub.output();
    EXPECT_NE(echo_line(echo).find("\"node\":\"from_" + std::string(writer) + "\""),
              std::string::npos)
        << echo.output();
  }
}

// The templates are filled by plain text replacement of the documented placeholders, a filled
// file has none left, and the files are well-formed XML as far as comments go.
TEST(MultiHostTemplates, DocumentedPlaceholdersAreAllThereIs) {
  for (const std::string vendor : {"cyclone", "fastdds"}) {
    const std::string text = read_file(template_path(vendor));
    for (const auto& [name, value] : placeholders(kAddressA))
      EXPECT_NE(text.find("${" + name + "}"), std::string::npos) << vendor << " lacks " << name;
    EXPECT_NO_THROW(fill_template(text, placeholders(kAddressA))) << vendor;
    EXPECT_THROW(fill_template(text, {{"POISE_PEER_1", kAddressA}}), std::runtime_error) << vendor;
    // XML forbids "--" inside a comment (usage lines with --dds-config broke that once; both
    // vendors' parsers are lenient, strict tools are not).
    for (auto open = text.find("<!--"); open != std::string::npos;
         open = text.find("<!--", open + 4)) {
      const auto close = text.find("-->", open + 4);
      ASSERT_NE(close, std::string::npos) << vendor << ": unterminated comment";
      EXPECT_EQ(text.substr(open + 4, close - open - 4).find("--"), std::string::npos)
          << vendor << ": '--' inside the comment at offset " << open;
    }
  }
}

}  // namespace
