#pragma once
// Non-template cores behind Publisher<T>, Subscriber<T>, RawPublisher and RawSubscriber.

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "poise/dds/detail/backend.hpp"
#include "poise/dds/participant.hpp"
#include "poise/dds/qos.hpp"
#include "poise/dds/topics.hpp"

namespace poise::dds::detail {

class WriterCore {
 public:
  /// `type` may be null (raw writer: bytes only).
  WriterCore(Participant& participant, std::string topic_name, std::string type_name,
             const TypeSupport* type, const Qos& qos);
  ~WriterCore();
  /// Serialises with `type` into a buffer allocated at construction, then writes.
  bool publish(const void* sample) noexcept;
  /// Writes bytes (4-byte encapsulation header + CDR) as they are.
  bool publish_raw(const std::uint8_t* data, std::size_t size) noexcept;
  int matched() const noexcept { return writer_->matched(); }
  bool wait_for_acks(std::chrono::nanoseconds timeout) noexcept {
    return writer_->wait_for_acks(timeout);
  }
  const std::string& topic_name() const noexcept { return topic_name_; }

 private:
  std::string topic_name_;
  const TypeSupport* type_;
  std::vector<std::uint8_t> buffer_;
  std::uint64_t failures_ = 0;
  std::unique_ptr<WriterBackend> writer_;
};

class ReaderCore {
 public:
  /// `type` may be null (raw reader: bytes only, no validation).
  ReaderCore(Participant& participant, std::string topic_name, std::string type_name,
             const TypeSupport* type, const Qos& qos);
  ~ReaderCore();

  /// Typed: takes the oldest unread sample that deserialises and validates into `sample`.
  /// Rejected samples are counted, logged (rate-limited) and skipped.
  bool take(void* sample, SampleMeta* meta = nullptr) noexcept;
  /// Raw: takes the oldest unread sample's bytes.
  bool take_raw(std::vector<std::uint8_t>& bytes, SampleMeta& meta) noexcept;

  /// Typed callback: every accepted sample is deserialised into `scratch` and passed to
  /// `callback` on a vendor listener thread. Call at most once, right after construction.
  void set_callback(void* scratch, std::function<void(const void*)> callback);
  /// The same, with each sample's metadata (its writer, timestamps).
  void set_callback(void* scratch, std::function<void(const void*, const SampleMeta&)> callback);
  /// Raw callback.
  void set_raw_callback(
      std::function<void(const std::vector<std::uint8_t>&, const SampleMeta&)> cb);

  int matched() const noexcept { return reader_->matched(); }
  ReaderLosses losses() const noexcept { return reader_->losses(); }
  const SubscriberCounters& counters() const noexcept { return counters_; }
  const std::string& topic_name() const noexcept { return topic_name_; }
  /// The newest rejection or error message (names topic and field), "" if none.
  std::string last_error() const;

 private:
  void reject(const char* kind, const char* why) noexcept;

  Participant& participant_;
  std::string topic_name_;
  std::string type_name_;
  const TypeSupport* type_;
  SubscriberCounters counters_;
  std::vector<std::uint8_t> bytes_;
  SampleMeta meta_;
  std::mutex take_mutex_;  // take() from the user thread vs. the listener thread
  mutable std::mutex error_mutex_;
  std::string last_error_;
  std::int64_t last_log_ns_ = 0;
  std::uint64_t suppressed_ = 0;
  int watch_token_ = 0;
  std::unique_ptr<ReaderBackend> reader_;  // last: destroyed (and its listener stopped) first
};

}  // namespace poise::dds::detail
