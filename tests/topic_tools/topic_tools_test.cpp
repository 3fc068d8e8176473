// `poise topic` verbs, as users run them: real `poise` processes on both vendors, talking over
// the loopback-only configuration on a domain of their own.
#include <chrono>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include <poise/reflect/fill.hpp>
#include <poise/reflect/json.hpp>

#include "child_process.hpp"

namespace {

using namespace std::chrono_literals;
using poise::testing::ChildProcess;

std::vector<std::string> env() {
  return {"POISE_DDS_DOMAIN=" + std::to_string(poise::testing::unique_domain_id())};
}

std::vector<std::string> poise_cmd(std::initializer_list<std::string> args) {
  std::vector<std::string> v{poise::testing::bin("poise"), "topic"};
  v.insert(v.end(), args);
  return v;
}

struct VendorPair {
  const char* writer;
  const char* reader;
};

// Readable parameters in test listings and ctest names.
void PrintTo(const VendorPair& p, std::ostream* os) {
  *os << p.writer << "->" << p.reader;
}

class TopicTools : public ::testing::TestWithParam<VendorPair> {};

// pub on one vendor, echo --json --once on the other: the sample arrives unchanged.
TEST_P(TopicTools, EchoJsonShowsWhatPubSent) {
  const auto [writer, reader] = GetParam();
  std::mt19937_64 rng(11);
  poise::msg::ContactProblem sample;
  poise::reflect::fill_random(sample, rng);
  const std::string json = poise::reflect::to_json(sample).dump();

  ChildProcess echo(poise_cmd({"--dds", reader, "echo", "poise/contact_problem", "--json", "--once",
                               "--timeout", "20"}),
                    env());
  ChildProcess pub(poise_cmd({"--dds", writer, "pub", "poise/contact_problem", json, "--rate", "20",
                              "--count", "200", "--wait", "10"}),
                   env());
  const auto rc = echo.wait_for(30s);
  ASSERT_TRUE(rc.has_value()) << "echo did not finish; output: " << echo.output();
  EXPECT_EQ(*rc, 0) << echo.output();
  pub.interrupt();

  poise::msg::ContactProblem received;
  const auto line = echo.output().substr(0, echo.output().find('\n'));
  poise::reflect::from_json(poise::reflect::Json::parse(line), received);
  const auto diff = poise::reflect::first_difference(sample, received);
  EXPECT_FALSE(diff) << *diff;
}

// list on one vendor sees the other vendor's writer with its type.
TEST_P(TopicTools, ListSeesTheOtherVendorsWriter) {
  const auto [writer, reader] = GetParam();
  ChildProcess pub(poise_cmd({"--dds", writer, "pub", "poise/diagnostics", R"({"node":"lister"})",
                              "--rate", "50", "--count", "0", "--wait-readers", "0"}),
                   env());
  ChildProcess list(poise_cmd({"--dds", reader, "list", "--wait", "3"}), env());
  const auto rc = list.wait_for(30s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0);
  pub.interrupt();
  const auto& out = list.output();
  const auto row = out.find("poise/diagnostics");
  ASSERT_NE(row, std::string::npos) << out;
  EXPECT_NE(out.find("poise::msg::Diagnostics", row), std::string::npos) << out;
}

// hz measures a 200 Hz publisher on the other vendor.
TEST_P(TopicTools, HzMeasuresTheRate) {
  const auto [writer, reader] = GetParam();
  ChildProcess pub(poise_cmd({"--dds", writer, "pub", "poise/joint_command", R"({"joint_count":3})",
                              "--rate", "200", "--count", "0", "--wait-readers", "0"}),
                   env());
  ChildProcess hz(poise_cmd({"--dds", reader, "hz", "poise/joint_command", "--duration", "4.5"}),
                  env());
  const auto rc = hz.wait_for(30s);
  pub.interrupt();
  ASSERT_TRUE(rc.has_value());
  const auto& out = hz.output();
  const auto at = out.rfind("average rate: ");
  ASSERT_NE(at, std::string::npos) << out;
  const double rate = std::stod(out.substr(at + 14));
  // The publisher sleeps to a 5 ms grid; a loaded 2-core machine may stretch a few periods.
  EXPECT_NEAR(rate, 200.0, 20.0) << out;
  EXPECT_NE(out.find("std dev:"), std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(Vendors, TopicTools,
                         ::testing::Values(VendorPair{"cyclone", "fastdds"},
                                           VendorPair{"fastdds", "cyclone"},
                                           VendorPair{"cyclone", "cyclone"}),
                         [](const auto& info) {
                           return std::string(info.param.writer) + "_to_" + info.param.reader;
                         });

// Bad input gets a clear error naming the problem and a non-zero exit, never a crash.
TEST(TopicToolsErrors, BadInputIsNamed) {
  struct Case {
    std::vector<std::string> args;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {{"pub", "poise/nope", "{}"}, "unknown topic 'poise/nope'"},
      {{"pub", "poise/sensors", R"({"joint_count":65})"}, "joint_count: length field 65 exceeds"},
      {{"pub", "poise/sensors", R"({"q":[1,2,"x"]})"}, "q[2]: expected a number"},
      {{"pub", "poise/sensors", "{not json"}, "parse error"},
      {{"--dds", "rti", "list"}, "rti"},
      {{"echo", "poise/nope"}, "unknown topic"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> argv{poise::testing::bin("poise"), "topic"};
    argv.insert(argv.end(), c.args.begin(), c.args.end());
    ChildProcess p(argv, env(), false, /*merge_stderr=*/true);
    const auto rc = p.wait_for(20s);
    ASSERT_TRUE(rc.has_value()) << c.expected;
    EXPECT_NE(*rc, 0) << c.expected;
    EXPECT_LT(*rc, 128) << "crashed: " << p.output();
    EXPECT_NE(p.output().find(c.expected), std::string::npos) << p.output();
  }
}

}  // namespace
