// Tests of the generated IDL reflection and the helpers built on it (validation, JSON, text).
// Independent checks: CDR serialization by Fast CDR (a different code path from the visitor)
// must agree with the visitor's view of the sample, and the generated operator== must agree
// with first_difference().
#include <cmath>
#include <limits>
#include <random>
#include <tuple>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <gtest/gtest.h>

#include <poise/reflect/fill.hpp>
#include <poise/reflect/json.hpp>
#include <poise/reflect/print.hpp>
#include <poise/reflect/validate.hpp>

namespace {

using namespace poise;

template <class T>
class EveryTopicType : public ::testing::Test {};

template <class Tuple>
struct ToTypes;
template <class... Ts>
struct ToTypes<std::tuple<Ts...>> {
  using type = ::testing::Types<Ts...>;
};
using TopicTypes = ToTypes<msg::TopicTypeList>::type;
TYPED_TEST_SUITE(EveryTopicType, TopicTypes);

// Serialize with Fast CDR and read back: the generated (de)serializer is independent of the
// visitor, so equality after the round trip checks that fill_random touched only real members.
template <class T>
T cdr_round_trip(const T& in) {
  std::vector<char> buffer(T::getCdrSerializedSize(in) + 64);
  eprosima::fastcdr::FastBuffer fb(buffer.data(), buffer.size());
  eprosima::fastcdr::Cdr writer(fb, eprosima::fastcdr::Cdr::DEFAULT_ENDIAN,
                                eprosima::fastcdr::Cdr::DDS_CDR);
  in.serialize(writer);
  eprosima::fastcdr::Cdr reader(fb, eprosima::fastcdr::Cdr::DEFAULT_ENDIAN,
                                eprosima::fastcdr::Cdr::DDS_CDR);
  T out;
  out.deserialize(reader);
  return out;
}

TYPED_TEST(EveryTopicType, RandomSamplesAreValidAndSurviveJsonAndCdr) {
  std::mt19937_64 rng(20261122);
  for (int trial = 0; trial < 20; ++trial) {
    TypeParam a;
    reflect::fill_random(a, rng);
    reflect::ValidationError err;
    ASSERT_TRUE(reflect::validate(a, &err)) << err.path << ": " << err.reason;

    TypeParam b;
    reflect::from_json(reflect::Json::parse(reflect::to_json(a).dump()), b);
    const auto diff = reflect::first_difference(a, b);
    EXPECT_FALSE(diff) << *diff;
    EXPECT_TRUE(a == b);  // generated operator== agrees

    const TypeParam c = cdr_round_trip(a);
    EXPECT_TRUE(a == c);
    EXPECT_FALSE(reflect::first_difference(a, c));
  }
}

TYPED_TEST(EveryTopicType, FirstDifferenceFindsEveryChangedScalar) {
  // Change one random leaf at a time through the visitor; operator== (generated, independent)
  // must see a difference exactly when first_difference does.
  std::mt19937_64 rng(7);
  TypeParam a;
  reflect::fill_random(a, rng);
  for (int trial = 0; trial < 30; ++trial) {
    TypeParam b = a;
    reflect::fill_random(b, rng);
    EXPECT_EQ(a == b, !reflect::first_difference(a, b).has_value());
  }
}

TEST(Validate, RejectsLengthFieldAboveMaximum) {
  msg::Sensors s;
  s.joint_count(65);
  reflect::ValidationError err;
  EXPECT_FALSE(reflect::validate(s, &err));
  EXPECT_STREQ(err.path, "joint_count");
  EXPECT_NE(std::string(err.reason).find("exceeds the fixed maximum 64"), std::string::npos);
  s.joint_count(64);
  EXPECT_TRUE(reflect::validate(s));
}

TEST(Validate, NamesTheNonFiniteField) {
  msg::State s;
  s.feet()[1].pose_W().position()[2] = std::numeric_limits<double>::quiet_NaN();
  reflect::ValidationError err;
  EXPECT_FALSE(reflect::validate(s, &err));
  EXPECT_STREQ(err.path, "feet[1].pose_W.position[2]");
  EXPECT_STREQ(err.reason, "is NaN");
  s.feet()[1].pose_W().position()[2] = 0;
  s.qd()[63] = -std::numeric_limits<double>::infinity();
  EXPECT_FALSE(reflect::validate(s, &err));
  EXPECT_STREQ(err.path, "qd[63]");
  EXPECT_STREQ(err.reason, "is infinite");
}

TEST(Validate, RejectsOutOfRangeEnumAndOverlongSequence) {
  msg::JointCommand c;
  c.mode(static_cast<msg::CommandMode>(7));
  reflect::ValidationError err;
  EXPECT_FALSE(reflect::validate(c, &err));
  EXPECT_STREQ(err.path, "mode");

  msg::RobotDescription d;
  d.joint_names().resize(65);
  EXPECT_FALSE(reflect::validate(d, &err));
  EXPECT_STREQ(err.path, "joint_names");
}

TEST(Json, ErrorsNameThePath) {
  msg::ContactProblem p;
  auto expect_error = [&](const char* text, const std::string& fragment) {
    try {
      reflect::from_json(reflect::Json::parse(text), p);
      ADD_FAILURE() << "no error for " << text;
    } catch (const reflect::JsonError& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  expect_error(R"({"feet":[{"mu":"high"},{}]})", "feet[0].mu: expected a number");
  expect_error(R"({"feet":[{}]})", "feet: 1 entries, expected 2");
  expect_error(R"({"com_W":[1,2]})", "com_W: 2 entries, expected 3");
  expect_error(R"({"feet":[{},{},{}]})", "feet: 3 entries, at most 2");
  expect_error(R"({"masss":50})", "masss: unknown member of poise::msg::ContactProblem");
  expect_error(R"({"header":{"tick":-1}})", "header.tick: out of range");
  expect_error(R"([1,2])", "expected an object");
}

TEST(Json, ShortArraysAllowedOnlyWhenBoundedByACount) {
  msg::JointCommand c;
  reflect::from_json(
      reflect::Json::parse(R"({"mode":"COMMAND_DAMPING","joint_count":2,"kd":[1.5,2.5]})"), c);
  EXPECT_EQ(c.mode(), msg::COMMAND_DAMPING);
  EXPECT_EQ(c.kd()[1], 2.5);
  EXPECT_EQ(c.kd()[2], 0.0);
  const auto j = reflect::to_json(c);
  EXPECT_EQ(j["kd"].size(), 2u);  // only the valid entries are printed
  EXPECT_EQ(j["mode"], "COMMAND_DAMPING");
}

TEST(Text, ReadableAndNamesNestedMembers) {
  msg::ContactSolution s;
  s.status(msg::CONTACT_PROJECTED);
  s.feet()[0].cop_W()[0] = 0.25;
  const std::string text = reflect::to_text(s);
  EXPECT_NE(text.find("status: \"CONTACT_PROJECTED\""), std::string::npos) << text;
  EXPECT_NE(text.find("feet[0]:\n  wrench_at_ankle_W:"), std::string::npos) << text;
  EXPECT_NE(text.find("  cop_W: [0.25, 0, 0]"), std::string::npos) << text;
}

}  // namespace
