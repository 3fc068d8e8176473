// QoS behaviour both vendors must show alike: late joiners on transient-local topics, keep-last
// depth; and discovery of topics on the domain.
#include <gtest/gtest.h>

#include <poise/msg/balance_reference.h>
#include <poise/msg/disturbance.h>
#include <poise/msg/sensors.h>
#include <poise/dds/dds.hpp>

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

struct Pairing {
  Vendor writer;
  Vendor reader;
};

class QosBehaviour : public ::testing::TestWithParam<Pairing> {};

TEST_P(QosBehaviour, TransientLocalLateJoinerGetsTheHistory) {
  Participant pw(options(GetParam().writer, "latched-writer"));
  Publisher<poise::msg::Disturbance> pub(pw, Qos::latched(3));
  for (std::uint32_t id = 1; id <= 5; ++id) {
    poise::msg::Disturbance d;
    d.id(id);
    ASSERT_TRUE(pub.publish(d));
  }
  // The reader joins after the writes.
  Participant pr(options(GetParam().reader, "late-reader"));
  Subscriber<poise::msg::Disturbance> sub(pr, Qos::latched(3));
  std::vector<std::uint32_t> ids;
  poise::msg::Disturbance got;
  ASSERT_TRUE(test::eventually([&] {
    while (sub.take(got))
      ids.push_back(got.id());
    return ids.size() >= 3;
  }));
  EXPECT_EQ(ids, (std::vector<std::uint32_t>{3, 4, 5}));
}

TEST_P(QosBehaviour, KeepLastDepthKeepsTheNewest) {
  Participant pw(options(GetParam().writer, "depth-writer"));
  Participant pr(options(GetParam().reader, "depth-reader"));
  Subscriber<poise::msg::Sensors> shallow(pr, Qos::reliable(2));
  Subscriber<poise::msg::Sensors> deep(pr, Qos::reliable(16));
  Publisher<poise::msg::Sensors> pub(pw, Qos::reliable(16));
  ASSERT_TRUE(pub.wait_for_matches(2, 10s));
  ASSERT_TRUE(shallow.wait_for_matches(1, 10s));
  ASSERT_TRUE(deep.wait_for_matches(1, 10s));
  for (std::uint64_t t = 1; t <= 6; ++t) {
    poise::msg::Sensors s;
    s.header().tick(t);
    ASSERT_TRUE(pub.publish(s));
  }
  std::vector<std::uint64_t> all;
  poise::msg::Sensors got;
  ASSERT_TRUE(test::eventually([&] {
    while (deep.take(got))
      all.push_back(got.header().tick());
    return all.size() >= 6;
  })) << "the deep reader got " << all.size() << " of 6 samples";
  // The shallow reader (same participant) has had all six delivered too, but kept the newest 2.
  std::vector<std::uint64_t> kept;
  ASSERT_TRUE(test::eventually([&] {
    while (shallow.take(got))
      kept.push_back(got.header().tick());
    return !kept.empty() && kept.back() == 6;
  })) << "the shallow reader got " << kept.size() << " samples";
  EXPECT_EQ(kept, (std::vector<std::uint64_t>{5, 6}));
  // take_latest drains and returns only the newest.
  for (std::uint64_t t = 7; t <= 9; ++t) {
    poise::msg::Sensors s;
    s.header().tick(t);
    ASSERT_TRUE(pub.publish(s));
  }
  std::uint64_t latest = 0;
  ASSERT_TRUE(test::eventually([&] {
    if (deep.take_latest(got)) latest = got.header().tick();
    return latest == 9;
  }));
}

TEST_P(QosBehaviour, DiscoveredTopicsListWritersAndReaders) {
  Participant pw(options(GetParam().writer, "list-writer"));
  Participant pr(options(GetParam().reader, "list-reader"));
  Publisher<poise::msg::Sensors> pub(pw);
  Subscriber<poise::msg::BalanceReference> sub(pw);
  ASSERT_TRUE(test::eventually([&] {
    int found = 0;
    for (const auto& t : pr.discovered_topics()) {
      if (t.topic_name == "poise/sensors" && t.type_name == "poise::msg::Sensors" &&
          t.writers == 1 && t.readers == 0) {
        ++found;
      }
      if (t.topic_name == "poise/balance_reference" &&
          t.type_name == "poise::msg::BalanceReference" && t.writers == 0 && t.readers == 1) {
        ++found;
      }
    }
    return found == 2;
  }));
}

INSTANTIATE_TEST_SUITE_P(Vendors, QosBehaviour,
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
