#include "poise/dds/detail/endpoint_core.hpp"

#include <time.h>

#include <cstring>
#include <memory>
#include <stdexcept>

#include "poise/dds/log.hpp"

namespace poise::dds::detail {
namespace {

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

}  // namespace

WriterCore::WriterCore(Participant& participant, std::string topic_name, std::string type_name,
                       const TypeSupport* type, const Qos& qos)
    : topic_name_(std::move(topic_name)), type_(type) {
  const std::size_t max = type ? type->max_serialized_size : 0;
  if (type) buffer_.resize(max);
  writer_ = participant.backend().create_writer(topic_name_, type_name, max, qos);
}

WriterCore::~WriterCore() = default;

bool WriterCore::publish(const void* sample) noexcept {
  std::size_t n = type_->serialize(sample, buffer_.data(), buffer_.size());
  if (n == 0) {
    // Only types with unbounded strings get here: grow once to the sample's size.
    try {
      buffer_.resize(type_->serialized_size(sample) + 64);
    } catch (...) {
      return false;
    }
    n = type_->serialize(sample, buffer_.data(), buffer_.size());
    if (n == 0) {
      if (failures_++ == 0) {
        log(LogLevel::error, "topic '%s': cannot serialise a sample", topic_name_.c_str());
      }
      return false;
    }
  }
  return publish_raw(buffer_.data(), n);
}

bool WriterCore::publish_raw(const std::uint8_t* data, std::size_t size) noexcept {
  if (writer_->write(data, size)) return true;
  if (failures_++ % 1000 == 0) {
    log(LogLevel::error, "topic '%s': the DDS write failed (%llu failures so far)",
        topic_name_.c_str(), static_cast<unsigned long long>(failures_));
  }
  return false;
}

ReaderCore::ReaderCore(Participant& participant, std::string topic_name, std::string type_name,
                       const TypeSupport* type, const Qos& qos)
    : participant_(participant),
      topic_name_(std::move(topic_name)),
      type_name_(std::move(type_name)),
      type_(type) {
  const std::size_t max = type ? type->max_serialized_size : 0;
  bytes_.reserve(max > 0 ? max : 4096);
  reader_ = participant.backend().create_reader(topic_name_, type_name_, max, qos);
  if (type_) watch_token_ = participant.watch_topic(topic_name_, type_name_, &counters_);
}

ReaderCore::~ReaderCore() {
  if (watch_token_) participant_.unwatch_topic(watch_token_);
  // Detach the callback first: this waits for a running callback, which uses reader_.
  reader_->set_on_data_available({});
  reader_.reset();
}

void ReaderCore::reject(const char* kind, const char* why) noexcept {
  // One line per second at most; the counters carry the totals.
  const std::int64_t now = monotonic_ns();
  char line[512];
  std::snprintf(line, sizeof(line), "topic '%s': %s sample rejected: %s", topic_name_.c_str(), kind,
                why);
  {
    std::lock_guard lock(error_mutex_);
    try {
      last_error_ = line;
    } catch (...) {
    }
    if (last_log_ns_ != 0 && now - last_log_ns_ < 1000000000LL) {
      ++suppressed_;
      return;
    }
    last_log_ns_ = now;
  }
  if (suppressed_ > 0) {
    log(LogLevel::warn, "%s (%llu more rejected since the last line)", line,
        static_cast<unsigned long long>(suppressed_));
    suppressed_ = 0;
  } else {
    log(LogLevel::warn, "%s", line);
  }
}

bool ReaderCore::take(void* sample, SampleMeta* meta) noexcept {
  std::lock_guard lock(take_mutex_);
  char why[256];
  while (reader_->take(bytes_, meta_)) {
    if (!type_->deserialize(bytes_.data(), bytes_.size(), sample, why, sizeof(why))) {
      counters_.deserialize_errors.fetch_add(1, std::memory_order_relaxed);
      reject("undecodable", why);
      continue;
    }
    if (!type_->validate(sample, why, sizeof(why))) {
      counters_.rejected.fetch_add(1, std::memory_order_relaxed);
      reject("invalid", why);
      continue;
    }
    counters_.received.fetch_add(1, std::memory_order_relaxed);
    if (meta) *meta = meta_;
    return true;
  }
  return false;
}

bool ReaderCore::take_raw(std::vector<std::uint8_t>& bytes, SampleMeta& meta) noexcept {
  std::lock_guard lock(take_mutex_);
  if (!reader_->take(bytes, meta)) return false;
  counters_.received.fetch_add(1, std::memory_order_relaxed);
  return true;
}

void ReaderCore::set_callback(void* scratch,
                              std::function<void(const void*, const SampleMeta&)> callback) {
  reader_->set_on_data_available([this, scratch, cb = std::move(callback)] {
    SampleMeta meta;
    while (take(scratch, &meta))
      cb(scratch, meta);
  });
}

void ReaderCore::set_callback(void* scratch, std::function<void(const void*)> callback) {
  reader_->set_on_data_available([this, scratch, cb = std::move(callback)] {
    while (take(scratch))
      cb(scratch);
  });
}

void ReaderCore::set_raw_callback(
    std::function<void(const std::vector<std::uint8_t>&, const SampleMeta&)> callback) {
  // One buffer for the reader's lifetime: taking a sample does not allocate once it has seen
  // the largest sample (the listener runs on one thread at a time).
  auto bytes = std::make_shared<std::vector<std::uint8_t>>();
  bytes->reserve(4096);
  reader_->set_on_data_available([this, bytes, cb = std::move(callback)] {
    SampleMeta meta;
    while (take_raw(*bytes, meta))
      cb(*bytes, meta);
  });
}

std::string ReaderCore::last_error() const {
  std::lock_guard lock(error_mutex_);
  return last_error_;
}

}  // namespace poise::dds::detail
