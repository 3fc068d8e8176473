#pragma once
// The topic registry: for every IDL topic type, its DDS topic name, DDS type name, default QoS
// (from the header comment of its idl/*.idl file) and type-erased (de)serialisation.
//
// Compile time:  TopicTraits<poise::msg::State>::topic_name == "poise/state"
// Run time:      topic_table(), find_topic("poise/state") (for tools such as `poise topic`).
//
// Wire format (both vendors, identical bytes): 4-byte encapsulation header {0x00, 0x01, 0, 0}
// (plain CDR = XCDR1, little endian) followed by the Fast CDR serialisation of the fastddsgen type.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "poise/dds/qos.hpp"

namespace poise::msg {
class RobotDescription;
class Sensors;
class GroundTruth;
class State;
class BalanceReference;
class ContactProblem;
class ContactSolution;
class JointCommand;
class Disturbance;
class EStop;
class EStopState;
class Diagnostics;
}  // namespace poise::msg

namespace poise::dds {

/// Type-erased operations on one generated type. All functions are noexcept and never throw;
/// `sample` points to an object of the type. Used by the typed Publisher/Subscriber templates and
/// by tools that handle raw CDR.
struct TypeSupport {
  const char* type_name;  ///< DDS type name as fastddsgen registers it, e.g. "poise::msg::State"
  /// Upper bound of the serialised size incl. the 4-byte header for fixed-size types; for types
  /// with unbounded strings a generous first guess (buffers grow on demand).
  std::size_t max_serialized_size;
  /// Serialised size of this sample, incl. the 4-byte header.
  std::size_t (*serialized_size)(const void* sample) noexcept;
  /// Writes header + CDR into buf. Returns the number of bytes, or 0 if `capacity` is too small.
  std::size_t (*serialize)(const void* sample, std::uint8_t* buf, std::size_t capacity) noexcept;
  /// Reads header + CDR. Returns false (sample content unspecified) on truncated or malformed
  /// input, or an unknown encapsulation; writes the reason to `why` (NUL-terminated).
  bool (*deserialize)(const std::uint8_t* buf, std::size_t size, void* sample, char* why,
                      std::size_t why_size) noexcept;
  /// Field validation of a deserialised sample (length fields within their maximum, finite
  /// numbers, ...). Returns false and writes "field: reason" to `why` for the first bad field.
  bool (*validate)(const void* sample, char* why, std::size_t why_size) noexcept;
  void* (*create)();              ///< new default-constructed sample (configuration time only)
  void (*destroy)(void* sample);  ///< delete a sample from create()
  bool (*equal)(const void* a, const void* b) noexcept;  ///< operator==
};

/// One row of the topic table.
struct TopicDescription {
  std::string_view topic_name;  ///< e.g. "poise/state"
  std::string_view type_name;   ///< e.g. "poise::msg::State"
  Qos qos;                      ///< default QoS of the topic (writers and readers)
  const TypeSupport* type;
};

/// Compile-time traits of a topic type; specialised for every poise::msg topic type.
template <class T>
struct TopicTraits;

#define POISE_DDS_DECLARE_TOPIC(Type, Name, QosValue)                   \
  template <>                                                           \
  struct TopicTraits<poise::msg::Type> {                                \
    static constexpr std::string_view topic_name = Name;                \
    static constexpr std::string_view type_name = "poise::msg::" #Type; \
    static constexpr Qos default_qos() { return QosValue; }             \
    static const TypeSupport& type_support() noexcept;                  \
  };

// Topic names use '/', which both Cyclone DDS 0.10 and Fast DDS 2.9 accept (ROS 2 does the same).
POISE_DDS_DECLARE_TOPIC(RobotDescription, "poise/robot_description", Qos::latched(1))
POISE_DDS_DECLARE_TOPIC(Sensors, "poise/sensors", Qos::control())
POISE_DDS_DECLARE_TOPIC(GroundTruth, "poise/ground_truth", Qos::control())
POISE_DDS_DECLARE_TOPIC(State, "poise/state", Qos::control())
POISE_DDS_DECLARE_TOPIC(BalanceReference, "poise/balance_reference", Qos::latched(1))
POISE_DDS_DECLARE_TOPIC(ContactProblem, "poise/contact_problem", Qos::control())
POISE_DDS_DECLARE_TOPIC(ContactSolution, "poise/contact_solution", Qos::control())
POISE_DDS_DECLARE_TOPIC(JointCommand, "poise/joint_command", Qos::control())
POISE_DDS_DECLARE_TOPIC(Disturbance, "poise/disturbance", Qos::reliable(16))
POISE_DDS_DECLARE_TOPIC(EStop, "poise/estop", Qos::latched(1))
POISE_DDS_DECLARE_TOPIC(EStopState, "poise/estop_state", Qos::latched(16))
POISE_DDS_DECLARE_TOPIC(Diagnostics, "poise/diagnostics", Qos::best_effort(1))

#undef POISE_DDS_DECLARE_TOPIC

/// True for the types that have TopicTraits.
template <class T>
concept TopicType = requires {
  TopicTraits<T>::topic_name;
};

/// All topics, in the order of the architecture page.
std::span<const TopicDescription> topic_table() noexcept;

/// The row with this topic name, or nullptr.
const TopicDescription* find_topic(std::string_view topic_name) noexcept;

/// The row whose type has this DDS type name, or nullptr.
const TopicDescription* find_topic_by_type(std::string_view type_name) noexcept;

}  // namespace poise::dds
