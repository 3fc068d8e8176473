// deploy/launch/bench/loop_guard.sh against this build: a deliberate slowdown (poise-bench-loop
// --add-work-us, busy work in every in-process tick) is flagged with the figures, and bad
// arguments are refused with exit 2 and a message naming them.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>

#include "child_process.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::string guard() {
  return (fs::path(POISE_SOURCE_DIR) / "deploy/launch/bench/loop_guard.sh").string();
}

struct Outcome {
  int code = -1;
  std::string output;
};

Outcome run_guard(std::vector<std::string> args) {
  args.insert(args.begin(), {"/bin/bash", guard()});
  poise::testing::ChildProcess p(args, {}, false, true);
  const auto code = p.wait_for(240s);
  return {code.value_or(-1), p.output()};
}

TEST(LoopGuard, FlagsADeliberateSlowdownOfTheInProcessLoopAndPrintsTheFigures) {
  // About 95 us a tick here: 300 us of busy work more makes it about 4x slower, far past 15 %.
  const Outcome o = run_guard({"--ref-build", POISE_BINARY_DIR, "--build", POISE_BINARY_DIR,
                               "--rounds", "1", "--duration", "1", "--", "--add-work-us", "300"});
  EXPECT_EQ(o.code, 1) << o.output;
  EXPECT_NE(o.output.find("round 1/1"), std::string::npos) << o.output;
  const auto line = o.output.find("\nin-process ");
  ASSERT_NE(line, std::string::npos) << o.output;
  const std::string in_process = o.output.substr(line + 1, o.output.find('\n', line + 1) - line);
  EXPECT_NE(in_process.find("SLOWER"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("\ndistributed "), std::string::npos) << o.output;
}

TEST(LoopGuard, RefusesBadArgumentsByName) {
  Outcome o = run_guard({"--build", POISE_BINARY_DIR});
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("give --ref COMMIT or --ref-build DIR"), std::string::npos) << o.output;
  o = run_guard({"--ref-build", POISE_BINARY_DIR, "--rounds", "0"});
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("--rounds"), std::string::npos) << o.output;
  o = run_guard({"--ref-build", "/nonexistent/build"});
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("/nonexistent/build/bin/poise-bench-loop not found"), std::string::npos)
      << o.output;
  o = run_guard({"--ref", "no-such-commit-xyz"});
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("no commit 'no-such-commit-xyz'"), std::string::npos) << o.output;
  o = run_guard({"--bogus"});
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.output.find("unknown argument '--bogus'"), std::string::npos) << o.output;
}

}  // namespace
