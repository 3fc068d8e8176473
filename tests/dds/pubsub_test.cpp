// Same-process publish/subscribe through both backends and across them.
#include <gtest/gtest.h>

#include <poise/msg/sensors.h>
#include <poise/dds/dds.hpp>

#include <random>

#include "dds_test_util.hpp"

namespace poise::dds {
namespace {

using namespace std::chrono_literals;

DdsOptions options(Vendor v, const char* name) {
  DdsOptions o;
  o.vendor = v;
  o.domain_id = test::claim_test_domain();
  o.participant_name = name;
  return o;
}

poise::msg::Sensors random_sensors(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  poise::msg::Sensors s;
  s.header().tick(rng());
  s.header().stamp_ns(static_cast<std::int64_t>(rng() >> 1));
  s.joint_count(static_cast<std::uint32_t>(rng() % 65));
  for (auto& v : s.q())
    v = u(rng);
  for (auto& v : s.qd())
    v = u(rng);
  for (auto& v : s.tau_measured())
    v = u(rng);
  for (auto& v : s.imu().orientation_wxyz())
    v = u(rng);
  for (auto& w : s.foot_wrench_F()) {
    for (auto& v : w.force())
      v = u(rng);
    for (auto& v : w.torque())
      v = u(rng);
  }
  return s;
}

struct Pairing {
  Vendor writer;
  Vendor reader;
};

class PubSub : public ::testing::TestWithParam<Pairing> {};

TEST_P(PubSub, SensorsArriveIntactInOrder) {
  const auto [wv, rv] = GetParam();
  Participant pw(options(wv, "writer"));
  Participant pr(options(rv, "reader"));
  Subscriber<poise::msg::Sensors> sub(pr, Qos::reliable(16));
  Publisher<poise::msg::Sensors> pub(pw, Qos::reliable(16));
  ASSERT_TRUE(pub.wait_for_matches(1, 10s));
  ASSERT_TRUE(sub.wait_for_matches(1, 10s));

  std::mt19937_64 rng(42);
  std::vector<poise::msg::Sensors> sent;
  for (int i = 0; i < 10; ++i) {
    sent.push_back(random_sensors(rng));
    ASSERT_TRUE(pub.publish(sent.back()));
  }
  std::vector<poise::msg::Sensors> got;
  ASSERT_TRUE(test::eventually([&] {
    poise::msg::Sensors s;
    while (sub.take(s))
      got.push_back(s);
    return got.size() >= sent.size();
  }));
  ASSERT_EQ(got.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i)
    EXPECT_TRUE(got[i] == sent[i]) << "sample " << i;
  EXPECT_EQ(sub.counters().received.load(), sent.size());
  EXPECT_EQ(sub.counters().rejected.load(), 0u);
}

INSTANTIATE_TEST_SUITE_P(Vendors, PubSub,
                         ::testing::Values(Pairing{Vendor::cyclone, Vendor::cyclone},
                                           Pairing{Vendor::fastdds, Vendor::fastdds},
                                           Pairing{Vendor::cyclone, Vendor::fastdds},
                                           Pairing{Vendor::fastdds, Vendor::cyclone}),
                         [](const auto& info) {
                           return std::string(to_string(info.param.writer)) + "_to_" +
                                  std::string(to_string(info.param.reader));
                         });

}  // namespace
}  // namespace poise::dds
