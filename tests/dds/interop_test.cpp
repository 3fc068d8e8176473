// Wire interop between separate processes: every topic type, in both directions and on each
// vendor by itself, content checked field by field by the receiving process (interop_peer.cpp).
#include <fcntl.h>
#include <gtest/gtest.h>

#include <string>

#include "dds_test_util.hpp"
#include "process.hpp"

namespace poise::dds::test {
namespace {

using namespace std::chrono_literals;

struct Pairing {
  const char* pub;
  const char* sub;
};

class Interop : public ::testing::TestWithParam<Pairing> {};

TEST_P(Interop, EveryTopicTypeArrivesFieldByFieldEqual) {
  const auto [pub_vendor, sub_vendor] = GetParam();
  const std::string peer = std::string(POISE_BINARY_DIR) + "/tests/poise-dds-interop-peer";
  const std::string domain = std::to_string(claim_test_domain());
  const std::string tag =
      std::string(pub_vendor) + "_" + sub_vendor + "_" + std::to_string(::getpid());
  const std::string seed = std::to_string(1000 + ::getpid() % 1000);

  ChildProcess sub({peer, "--dds", sub_vendor, "--domain", domain, "--role", "sub", "--seed", seed,
                    "--timeout-s", "25"},
                   "/tmp/poise-interop-sub-" + tag + ".log");
  ChildProcess pub({peer, "--dds", pub_vendor, "--domain", domain, "--role", "pub", "--seed", seed,
                    "--timeout-s", "30"},
                   "/tmp/poise-interop-pub-" + tag + ".log");
  const auto code = sub.wait(35s);
  pub.kill();
  sub.kill();
  const std::string sub_out = sub.output();
  const std::string pub_out = pub.output();
  ASSERT_TRUE(code.has_value()) << "subscriber did not finish\n" << sub_out;
  EXPECT_EQ(*code, 0) << "subscriber (" << sub_vendor << "):\n"
                      << sub_out << "\npublisher (" << pub_vendor << "):\n"
                      << pub_out;
  EXPECT_NE(sub_out.find("ALL OK"), std::string::npos) << sub_out;
  std::remove(("/tmp/poise-interop-sub-" + tag + ".log").c_str());
  std::remove(("/tmp/poise-interop-pub-" + tag + ".log").c_str());
}

INSTANTIATE_TEST_SUITE_P(
    SeparateProcesses, Interop,
    ::testing::Values(Pairing{"cyclone", "fastdds"}, Pairing{"fastdds", "cyclone"},
                      Pairing{"cyclone", "cyclone"}, Pairing{"fastdds", "fastdds"}),
    [](const auto& info) { return std::string(info.param.pub) + "_to_" + info.param.sub; });

}  // namespace
}  // namespace poise::dds::test
