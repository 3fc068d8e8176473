#pragma once
// Typed publisher of one Poise topic.

#include <chrono>
#include <string_view>

#include "poise/dds/detail/endpoint_core.hpp"
#include "poise/dds/participant.hpp"
#include "poise/dds/topics.hpp"

namespace poise::dds {

/// Publishes samples of T on TopicTraits<T>::topic_name (or another name given at construction).
///
/// publish() is real-time friendly: it serialises into a buffer allocated at construction (for
/// fixed-size types; types with unbounded strings grow it when a sample is larger than any
/// before) and hands the bytes to the vendor. Thread-safe only if the vendor's write is (both are).
template <TopicType T>
class Publisher {
 public:
  /// Throws std::runtime_error naming the topic when the vendor refuses the writer.
  explicit Publisher(Participant& participant, const Qos& qos = TopicTraits<T>::default_qos(),
                     std::string_view topic_name = TopicTraits<T>::topic_name)
      : core_(participant, std::string(topic_name), std::string(TopicTraits<T>::type_name),
              &TopicTraits<T>::type_support(), qos) {}

  /// False when serialisation or the vendor write failed (logged, rate-limited). Never throws.
  bool publish(const T& sample) noexcept { return core_.publish(&sample); }

  /// Number of readers matched on the other side.
  int matched() const noexcept { return core_.matched(); }

  /// Waits until at least `count` readers are matched. False on timeout.
  bool wait_for_matches(int count, std::chrono::nanoseconds timeout) const {
    return wait_until_matched([this] { return matched(); }, count, timeout);
  }

  /// Waits until every matched reliable reader acknowledged every sample published so far (the
  /// proof that they receive this writer: a writer-side match alone is not). False on timeout.
  bool wait_for_acknowledgments(std::chrono::nanoseconds timeout) noexcept {
    return core_.wait_for_acks(timeout);
  }

  const std::string& topic_name() const noexcept { return core_.topic_name(); }

 private:
  detail::WriterCore core_;
};

/// Publishes raw CDR bytes (4-byte encapsulation header + body) under any topic and type name.
/// For tools (`poise topic pub`), replay and tests.
class RawPublisher {
 public:
  RawPublisher(Participant& participant, std::string_view topic_name, std::string_view type_name,
               const Qos& qos = Qos{})
      : core_(participant, std::string(topic_name), std::string(type_name), nullptr, qos) {}
  bool publish(const std::uint8_t* data, std::size_t size) noexcept {
    return core_.publish_raw(data, size);
  }
  int matched() const noexcept { return core_.matched(); }
  bool wait_for_matches(int count, std::chrono::nanoseconds timeout) const {
    return wait_until_matched([this] { return matched(); }, count, timeout);
  }

 private:
  detail::WriterCore core_;
};

}  // namespace poise::dds
