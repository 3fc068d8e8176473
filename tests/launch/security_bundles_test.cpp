// Credentials split per host (issue #51 item 7): `poise security init DIR --deployment FILE`
// keeps the CA's key apart (DIR/authority) and writes one bundle per host holding only that
// host's identities, owner-only; a process holding only the desk's bundle cannot command the
// robot of a secured run.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "test_domain.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
using poise::testing::run_command;

unsigned mode_of(const fs::path& p) {
  struct stat st{};
  EXPECT_EQ(::stat(p.c_str(), &st), 0) << p;
  return st.st_mode & 0777;
}

// Every key.pem (and ca.key) below `dir`, relative to it.
std::vector<std::string> keys_below(const fs::path& dir) {
  std::vector<std::string> keys;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.path().filename() == "key.pem" || e.path().filename() == "ca.key")
      keys.push_back(fs::relative(e.path(), dir).string());
  std::sort(keys.begin(), keys.end());
  return keys;
}

TEST(SecurityBundles, AHostHoldsOnlyItsOwnIdentities) {
  const int domain = poise::testing::unique_domain_id();
  if (domain > 230) GTEST_SKIP() << "Cyclone's security plugins take domains 0..230 only";
  const fs::path dir = fs::path(::testing::TempDir()) / ("poise_bundles_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path sec = dir / "sec";
  std::ofstream(dir / "three.yaml")
      << "name: three\ndomain: " << domain
      << "\nscenario: standing\nmode: lockstep\nsecurity: sec\nhosts:\n"
         "  robot: {address: 10.251.0.1}\n  ctrl: {address: 10.251.0.2}\n"
         "  desk: {address: 10.251.0.3}\ncomponents:\n"
         "  sim: {host: robot}\n  estimator: {host: ctrl}\n  controller: {host: ctrl}\n"
         "  contact: {host: ctrl}\n  recorder: {host: desk, output: three.mcap}\n";
  {
    auto [code, out] = run_command({bin("poise"), "security", "init", sec.string(),
                                    "--deployment", (dir / "three.yaml").string()},
                                   120s);
    ASSERT_EQ(code, 0) << out;
  }
  // The CA's key only in DIR/authority; each bundle holds its own identities' keys only.
  EXPECT_EQ(keys_below(sec / "hosts" / "robot"), std::vector<std::string>{"sim/key.pem"});
  EXPECT_EQ(keys_below(sec / "hosts" / "ctrl"),
            (std::vector<std::string>{"contact/key.pem", "controller/key.pem",
                                      "estimator/key.pem"}));
  EXPECT_EQ(keys_below(sec / "hosts" / "desk"), std::vector<std::string>{"recorder/key.pem"});
  EXPECT_EQ(keys_below(sec / "hosts" / "operator"), std::vector<std::string>{"operator/key.pem"});
  EXPECT_FALSE(fs::exists(sec / "ca.key"));
  EXPECT_TRUE(fs::exists(sec / "authority" / "ca.key"));
  for (const auto& e : fs::recursive_directory_iterator(sec)) {
    if (e.is_directory()) {
      EXPECT_EQ(mode_of(e.path()), 0700u) << e.path();
    }
    if (e.path().filename() == "key.pem" || e.path().filename() == "ca.key") {
      EXPECT_EQ(mode_of(e.path()), 0600u) << e.path();
    }
  }
  for (const char* host : {"robot", "ctrl", "desk", "operator"})
    for (const char* f : {"ca.pem", "governance.p7s"})
      EXPECT_TRUE(fs::exists(sec / "hosts" / host / f)) << host << "/" << f;

  // A secured run; the desk's bundle cannot command its robot: it has no controller identity,
  // and its recorder identity may not write poise/joint_command.
  const std::string d = std::to_string(domain);
  ChildProcess run({bin("poise"), "run", "standing", "--domain", d, "--lockstep", "--duration",
                    "30", "--security", sec.string(), "-o", (dir / "run.json").string(),
                    "--log-dir", (dir / "logs").string()},
                   {}, false, true);
  ASSERT_TRUE(run.wait_for_output("t=1.0 s", 90s)) << run.output();
  const std::string desk = (sec / "hosts" / "desk").string();
  {
    auto [code, out] = run_command({bin("poise"), "topic", "pub", "poise/joint_command", "{}",
                                    "--count", "1", "--domain", d, "--security", desk,
                                    "--identity", "controller"},
                                   30s);
    EXPECT_NE(code, 0) << out;
    EXPECT_NE(out.find("controller/cert.pem does not exist"), std::string::npos) << out;
  }
  {
    auto [code, out] = run_command({bin("poise"), "topic", "pub", "poise/joint_command", "{}",
                                    "--count", "1", "--domain", d, "--security", desk,
                                    "--identity", "recorder"},
                                   30s);
    EXPECT_NE(code, 0) << out;
    EXPECT_NE(out.find("Not Allowed By Security"), std::string::npos) << out;
  }
  const auto rc = run.wait_for(240s);
  ASSERT_TRUE(rc.has_value()) << run.output();
  EXPECT_EQ(*rc, 0) << run.output();
  fs::remove_all(dir);
}

}  // namespace
