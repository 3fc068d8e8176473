// Type-erased (de)serialisation and validation of every topic type, and the topic table.
#include "poise/dds/topics.hpp"

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <exception>

#include <poise/msg/balance_reference.h>
#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/diagnostics.h>
#include <poise/msg/disturbance.h>
#include <poise/msg/estop.h>
#include <poise/msg/estop_state.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>

#include "sample_validation.hpp"

namespace poise::dds {
namespace {

namespace fcdr = eprosima::fastcdr;

template <class T>
std::size_t serialized_size(const void* sample) noexcept {
  return 4 + T::getCdrSerializedSize(*static_cast<const T*>(sample), 0);
}

template <class T>
std::size_t serialize(const void* sample, std::uint8_t* buf, std::size_t capacity) noexcept {
  try {
    fcdr::FastBuffer fb(reinterpret_cast<char*>(buf), capacity);
    fcdr::Cdr ser(fb, fcdr::Cdr::LITTLE_ENDIANNESS, fcdr::Cdr::DDS_CDR);
    ser.serialize_encapsulation();
    static_cast<const T*>(sample)->serialize(ser);
    return ser.getSerializedDataLength();
  } catch (...) {
    return 0;
  }
}

template <class T>
bool deserialize(const std::uint8_t* buf, std::size_t size, void* sample, char* why,
                 std::size_t why_size) noexcept {
  if (size < 4) {
    std::snprintf(why, why_size, "%zu bytes: shorter than the encapsulation header", size);
    return false;
  }
  // Plain CDR only: 0x0000 (big endian) or 0x0001 (little endian). XCDR2 and parameter lists
  // are what @appendable/@mutable would produce; Poise types are @final.
  if (buf[0] != 0 || buf[1] > 1) {
    std::snprintf(why, why_size, "unsupported encapsulation 0x%02x%02x (expected plain CDR)",
                  buf[0], buf[1]);
    return false;
  }
  try {
    fcdr::FastBuffer fb(reinterpret_cast<char*>(const_cast<std::uint8_t*>(buf)), size);
    fcdr::Cdr deser(fb, fcdr::Cdr::DEFAULT_ENDIAN, fcdr::Cdr::DDS_CDR);
    deser.read_encapsulation();
    static_cast<T*>(sample)->deserialize(deser);
    return true;
  } catch (const fcdr::exception::Exception& e) {
    std::snprintf(why, why_size, "malformed CDR (%zu bytes): %s", size, e.what());
  } catch (const std::exception& e) {
    std::snprintf(why, why_size, "malformed CDR (%zu bytes): %s", size, e.what());
  } catch (...) {
    std::snprintf(why, why_size, "malformed CDR (%zu bytes)", size);
  }
  return false;
}

template <class T>
bool validate(const void* sample, char* why, std::size_t why_size) noexcept {
  return detail::validate_sample(*static_cast<const T*>(sample), why, why_size);
}

template <class T>
void* create() {
  return new T();
}
template <class T>
void destroy(void* sample) {
  delete static_cast<T*>(sample);
}
template <class T>
bool equal(const void* a, const void* b) noexcept {
  return *static_cast<const T*>(a) == *static_cast<const T*>(b);
}

template <class T>
constexpr TypeSupport make_support() {
  return TypeSupport{TopicTraits<T>::type_name.data(),
                     0,
                     &serialized_size<T>,
                     &serialize<T>,
                     &deserialize<T>,
                     &validate<T>,
                     &create<T>,
                     &destroy<T>,
                     &equal<T>};
}

template <class T>
TypeSupport support_with_size() {
  TypeSupport s = make_support<T>();
  // fastddsgen's bound: exact for fixed-size types; for unbounded strings it assumes 255 chars.
  s.max_serialized_size = 4 + T::getMaxCdrSerializedSize(0) + 4;
  return s;
}

template <class T>
const TypeSupport& support() {
  static const TypeSupport s = support_with_size<T>();
  return s;
}

template <class T>
TopicDescription row() {
  return TopicDescription{TopicTraits<T>::topic_name, TopicTraits<T>::type_name,
                          TopicTraits<T>::default_qos(), &support<T>()};
}

}  // namespace

#define POISE_DDS_DEFINE_TOPIC(Type)                                          \
  const TypeSupport& TopicTraits<poise::msg::Type>::type_support() noexcept { \
    return support<poise::msg::Type>();                                       \
  }
POISE_DDS_DEFINE_TOPIC(RobotDescription)
POISE_DDS_DEFINE_TOPIC(Sensors)
POISE_DDS_DEFINE_TOPIC(GroundTruth)
POISE_DDS_DEFINE_TOPIC(State)
POISE_DDS_DEFINE_TOPIC(BalanceReference)
POISE_DDS_DEFINE_TOPIC(ContactProblem)
POISE_DDS_DEFINE_TOPIC(ContactSolution)
POISE_DDS_DEFINE_TOPIC(JointCommand)
POISE_DDS_DEFINE_TOPIC(Disturbance)
POISE_DDS_DEFINE_TOPIC(EStop)
POISE_DDS_DEFINE_TOPIC(EStopState)
POISE_DDS_DEFINE_TOPIC(Diagnostics)
#undef POISE_DDS_DEFINE_TOPIC

std::span<const TopicDescription> topic_table() noexcept {
  static const std::array<TopicDescription, 12> table = {
      row<poise::msg::RobotDescription>(), row<poise::msg::Sensors>(),
      row<poise::msg::GroundTruth>(),      row<poise::msg::State>(),
      row<poise::msg::BalanceReference>(), row<poise::msg::ContactProblem>(),
      row<poise::msg::ContactSolution>(),  row<poise::msg::JointCommand>(),
      row<poise::msg::Disturbance>(),      row<poise::msg::EStop>(),
      row<poise::msg::EStopState>(),       row<poise::msg::Diagnostics>()};
  return table;
}

const TopicDescription* find_topic(std::string_view topic_name) noexcept {
  for (const auto& r : topic_table()) {
    if (r.topic_name == topic_name) return &r;
  }
  return nullptr;
}

const TopicDescription* find_topic_by_type(std::string_view type_name) noexcept {
  for (const auto& r : topic_table()) {
    if (r.type_name == type_name) return &r;
  }
  return nullptr;
}

}  // namespace poise::dds
