#pragma once
// Typed subscriber of one Poise topic.

#include <chrono>
#include <functional>
#include <memory>
#include <string_view>

#include "poise/dds/detail/endpoint_core.hpp"
#include "poise/dds/participant.hpp"
#include "poise/dds/topics.hpp"

namespace poise::dds {

/// Receives samples of T. Every incoming sample is deserialised and validated before delivery
/// (TypeSupport::validate: length fields within their maximum, finite numbers, valid enums,
/// bounded strings); a sample that fails is never delivered: it is counted
/// (counters().rejected / .deserialize_errors) and logged with topic and field, at most once a
/// second. Writers with this topic name but another type are counted (counters().type_mismatches)
/// and logged once each.
///
/// Two ways to receive, not to be mixed on one subscriber:
///  - polling: take() returns samples oldest first (in order); take_latest() drains the queue and
///    returns only the newest, which is what a 1 kHz loop usually wants;
///  - callback: given at construction, called on a vendor listener thread for each sample, in
///    order. Keep it short; it must not destroy the subscriber.
template <TopicType T>
class Subscriber {
 public:
  using Callback = std::function<void(const T&)>;

  explicit Subscriber(Participant& participant, const Qos& qos = TopicTraits<T>::default_qos(),
                      std::string_view topic_name = TopicTraits<T>::topic_name)
      : scratch_(std::make_unique<T>()),
        core_(participant, std::string(topic_name), std::string(TopicTraits<T>::type_name),
              &TopicTraits<T>::type_support(), qos) {}

  Subscriber(Participant& participant, Callback callback,
             const Qos& qos = TopicTraits<T>::default_qos(),
             std::string_view topic_name = TopicTraits<T>::topic_name)
      : Subscriber(participant, qos, topic_name) {
    callback_ = std::move(callback);
    core_.set_callback(scratch_.get(),
                       [this](const void* s) { callback_(*static_cast<const T*>(s)); });
  }

  /// A callback given each sample with its metadata (`meta.writer_id` tells writers apart).
  using MetaCallback = std::function<void(const T&, const detail::SampleMeta&)>;
  Subscriber(Participant& participant, MetaCallback callback,
             const Qos& qos = TopicTraits<T>::default_qos(),
             std::string_view topic_name = TopicTraits<T>::topic_name)
      : Subscriber(participant, qos, topic_name) {
    meta_callback_ = std::move(callback);
    core_.set_callback(scratch_.get(), [this](const void* s, const detail::SampleMeta& m) {
      meta_callback_(*static_cast<const T*>(s), m);
    });
  }

  /// The oldest unread valid sample into `out`. False (out untouched) when there is none.
  /// No allocation for fixed-size types. Never throws.
  bool take(T& out) noexcept {
    if (!core_.take(scratch_.get())) return false;
    out = *scratch_;
    return true;
  }

  /// Drains all unread samples; the newest valid one goes to `out`. False (out untouched) when
  /// there was none.
  bool take_latest(T& out) noexcept {
    bool any = false;
    while (core_.take(scratch_.get()))
      any = true;
    if (any) out = *scratch_;
    return any;
  }

  /// Number of writers matched on the other side.
  int matched() const noexcept { return core_.matched(); }
  bool wait_for_matches(int count, std::chrono::nanoseconds timeout) const {
    return wait_until_matched([this] { return matched(); }, count, timeout);
  }

  const SubscriberCounters& counters() const noexcept { return core_.counters(); }
  std::string last_error() const { return core_.last_error(); }
  const std::string& topic_name() const noexcept { return core_.topic_name(); }

 private:
  std::unique_ptr<T> scratch_;
  Callback callback_;
  MetaCallback meta_callback_;
  detail::ReaderCore core_;  // last: its reader (and listener) goes first
};

/// Raw CDR bytes of any topic and type (tools, recorder). No validation, no type check.
class RawSubscriber {
 public:
  using Callback = std::function<void(const std::vector<std::uint8_t>&, const detail::SampleMeta&)>;

  RawSubscriber(Participant& participant, std::string_view topic_name, std::string_view type_name,
                const Qos& qos = Qos{}, Callback callback = {})
      : core_(participant, std::string(topic_name), std::string(type_name), nullptr, qos) {
    if (callback) core_.set_raw_callback(std::move(callback));
  }
  /// The oldest unread sample's bytes (4-byte header + CDR) and timestamps.
  bool take(std::vector<std::uint8_t>& bytes, detail::SampleMeta& meta) noexcept {
    return core_.take_raw(bytes, meta);
  }
  int matched() const noexcept { return core_.matched(); }
  bool wait_for_matches(int count, std::chrono::nanoseconds timeout) const {
    return wait_until_matched([this] { return matched(); }, count, timeout);
  }
  const SubscriberCounters& counters() const noexcept { return core_.counters(); }
  /// Samples the vendor reports lost or rejected for this reader (DDS statuses, polled).
  detail::ReaderLosses losses() const noexcept { return core_.losses(); }

 private:
  detail::ReaderCore core_;
};

using SampleMeta = detail::SampleMeta;
using ReaderLosses = detail::ReaderLosses;

}  // namespace poise::dds
