// Bad input never reaches node code and never crashes: oversized length fields, NaN, malformed
// CDR and writers of another type are counted and logged with topic and field.
#include <gtest/gtest.h>

#include <poise/msg/sensors.h>
#include <poise/msg/state.h>
#include <poise/msg/estop.h>
#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <poise/dds/dds.hpp>

#include <cmath>
#include <random>

#include "dds_test_util.hpp"

namespace poise::dds {
namespace {

using namespace std::chrono_literals;
using poise::msg::Sensors;

DdsOptions options(Vendor v, const char* name) {
  DdsOptions o;
  o.vendor = v;
  o.domain_id = test::claim_test_domain();
  o.participant_name = name;
  return o;
}

Sensors valid_sensors(std::uint64_t tick) {
  Sensors s;
  s.header().tick(tick);
  s.joint_count(12);
  s.imu().orientation_wxyz()[0] = 1.0;
  for (std::size_t i = 0; i < 12; ++i)
    s.q()[i] = 0.1 * static_cast<double>(i);
  return s;
}

struct Pairing {
  Vendor writer;
  Vendor reader;
};

class BadInput : public ::testing::TestWithParam<Pairing> {
 protected:
  void SetUp() override {
    pw_ = std::make_unique<Participant>(options(GetParam().writer, "bad-writer"));
    pr_ = std::make_unique<Participant>(options(GetParam().reader, "bad-reader"));
  }
  std::unique_ptr<Participant> pw_, pr_;
};

// Publishes `bad` then a valid sample with tick 99; the subscriber must deliver only the valid
// one, count one rejection and name `field` in its error.
void expect_rejected(Participant& pw, Participant& pr, const Sensors& bad, const char* field) {
  Subscriber<Sensors> sub(pr, Qos::reliable(8));
  Publisher<Sensors> pub(pw, Qos::reliable(8));
  ASSERT_TRUE(pub.wait_for_matches(1, 10s));
  ASSERT_TRUE(sub.wait_for_matches(1, 10s));
  ASSERT_TRUE(pub.publish(bad));
  ASSERT_TRUE(pub.publish(valid_sensors(99)));
  Sensors got;
  std::vector<std::uint64_t> ticks;
  ASSERT_TRUE(test::eventually([&] {
    while (sub.take(got))
      ticks.push_back(got.header().tick());
    return !ticks.empty();
  }));
  EXPECT_EQ(ticks, std::vector<std::uint64_t>{99});
  EXPECT_EQ(sub.counters().rejected.load(), 1u);
  EXPECT_EQ(sub.counters().received.load(), 1u);
  const std::string err = sub.last_error();
  EXPECT_NE(err.find("poise/sensors"), std::string::npos) << err;
  EXPECT_NE(err.find(field), std::string::npos) << err;
}

TEST_P(BadInput, LengthFieldAboveMaximumIsRejected) {
  Sensors bad = valid_sensors(1);
  bad.joint_count(70);  // MAX_JOINTS is 64
  expect_rejected(*pw_, *pr_, bad, "joint_count");
}

TEST_P(BadInput, NaNIsRejectedNamingTheField) {
  Sensors bad = valid_sensors(1);
  bad.q()[3] = std::nan("");
  expect_rejected(*pw_, *pr_, bad, "q[3]");
}

TEST_P(BadInput, InfinityIsRejected) {
  Sensors bad = valid_sensors(1);
  bad.imu().specific_force_I()[2] = -INFINITY;
  expect_rejected(*pw_, *pr_, bad, "specific_force_I[2]");
}

TEST_P(BadInput, MalformedCdrIsCountedNotDelivered) {
  Subscriber<Sensors> sub(*pr_, Qos::reliable(16));
  RawPublisher raw(*pw_, "poise/sensors", "poise::msg::Sensors", Qos::reliable(16));
  ASSERT_TRUE(raw.wait_for_matches(1, 10s));
  ASSERT_TRUE(sub.wait_for_matches(1, 10s));

  // A valid sample's bytes, to cut and corrupt.
  const auto& ts = TopicTraits<Sensors>::type_support();
  const Sensors good = valid_sensors(5);
  std::vector<std::uint8_t> bytes(ts.max_serialized_size);
  const std::size_t n = ts.serialize(&good, bytes.data(), bytes.size());
  ASSERT_GT(n, 100u);

  std::vector<std::uint8_t> truncated(bytes.begin(), bytes.begin() + 40);
  std::vector<std::uint8_t> xcdr2(bytes.begin(), bytes.begin() + n);
  xcdr2[1] = 0x07;  // encapsulation D_CDR2_LE: not plain CDR
  std::mt19937_64 rng(3);
  std::vector<std::uint8_t> garbage(n);
  for (auto& b : garbage)
    b = static_cast<std::uint8_t>(rng());
  garbage[0] = 0;
  garbage[1] = 1;
  garbage.resize(n / 3);

  ASSERT_TRUE(raw.publish(truncated.data(), truncated.size()));
  ASSERT_TRUE(raw.publish(xcdr2.data(), xcdr2.size()));
  ASSERT_TRUE(raw.publish(garbage.data(), garbage.size()));
  ASSERT_TRUE(raw.publish(bytes.data(), n));  // the good one last

  Sensors got;
  std::vector<std::uint64_t> ticks;
  ASSERT_TRUE(test::eventually([&] {
    while (sub.take(got))
      ticks.push_back(got.header().tick());
    return !ticks.empty();
  }));
  EXPECT_EQ(ticks, std::vector<std::uint64_t>{5});
  EXPECT_EQ(sub.counters().deserialize_errors.load() + sub.counters().rejected.load(), 3u);
  EXPECT_GE(sub.counters().deserialize_errors.load(), 2u);  // garbage may happen to decode
  EXPECT_NE(sub.last_error().find("poise/sensors"), std::string::npos);
}

TEST_P(BadInput, WriterOfAnotherTypeIsDetectedAndCounted) {
  Subscriber<poise::msg::State> sub(*pr_);
  // Same topic name, other type name: DDS does not match them; we count and log it.
  RawPublisher raw(*pw_, "poise/state", "poise::msg::Sensors");
  ASSERT_TRUE(test::eventually([&] { return sub.counters().type_mismatches.load() >= 1; }));
  EXPECT_GE(pr_->type_mismatches(), 1u);
  EXPECT_EQ(sub.matched(), 0);
  EXPECT_EQ(sub.counters().received.load(), 0u);
}

// CDR of an EStop / Disturbance written field by field with fastcdr, its strings unbounded: what a
// writer built from another IDL (or by hand) can send. `engaged` stands for the Disturbance's id.
std::vector<std::uint8_t> estop_cdr(std::uint64_t tick, const std::string& source,
                                    const std::string& reason) {
  std::vector<std::uint8_t> buf(64 + source.size() + reason.size());
  eprosima::fastcdr::FastBuffer fb(reinterpret_cast<char*>(buf.data()), buf.size());
  eprosima::fastcdr::Cdr ser(fb, eprosima::fastcdr::Cdr::LITTLE_ENDIANNESS,
                             eprosima::fastcdr::Cdr::DDS_CDR);
  ser.serialize_encapsulation();
  ser << tick << std::int64_t{0} << true << source << reason;
  ser << std::uint64_t{0} << std::uint32_t{0};  // request, kind
  buf.resize(ser.getSerializedDataLength());
  return buf;
}

// A string longer than its IDL bound is a rejected sample, counted and named (fastddsgen's code
// used to cut it to the bound and deliver it): a 10,000-character e-stop reason (bound 128) and
// a 33-character source (bound 32), then a valid e-stop that arrives.
TEST_P(BadInput, AStringLongerThanItsBoundIsRejectedNotCut) {
  Subscriber<poise::msg::EStop> sub(*pr_, Qos::latched(8));  // deep: every sample is seen
  RawPublisher raw(*pw_, "poise/estop", "poise::msg::EStop", Qos::latched(8));
  ASSERT_TRUE(raw.wait_for_matches(1, 10s));
  ASSERT_TRUE(sub.wait_for_matches(1, 10s));
  for (const auto& bytes : {estop_cdr(1, "operator", std::string(10000, 'r')),
                            estop_cdr(2, std::string(33, 's'), "too long a source"),
                            estop_cdr(3, std::string(32, 's'), std::string(128, 'r'))})
    ASSERT_TRUE(raw.publish(bytes.data(), bytes.size()));
  poise::msg::EStop got;
  std::vector<std::uint64_t> ticks;
  ASSERT_TRUE(test::eventually([&] {
    while (sub.take(got))
      ticks.push_back(got.header().tick());
    return !ticks.empty();
  }));
  EXPECT_EQ(ticks, std::vector<std::uint64_t>{3});  // exactly at the bounds: delivered whole
  EXPECT_EQ(got.reason().size(), 128u);
  EXPECT_EQ(sub.counters().deserialize_errors.load() + sub.counters().rejected.load(), 2u);
  const std::string err = sub.last_error();
  EXPECT_NE(err.find("poise/estop"), std::string::npos) << err;
  EXPECT_NE(err.find("longer than its bound"), std::string::npos) << err;
}

INSTANTIATE_TEST_SUITE_P(Vendors, BadInput,
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
