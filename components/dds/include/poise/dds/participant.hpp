#pragma once
// A process's membership of one DDS domain, on the vendor chosen at start.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "poise/dds/detail/backend.hpp"
#include "poise/dds/vendor.hpp"

namespace poise::dds {

/// A topic seen on the domain through discovery of other participants' endpoints.
struct DiscoveredTopic {
  std::string topic_name;
  std::string type_name;
  int writers = 0;
  int readers = 0;
};

/// Counters of one subscriber (and, summed, of a participant). Updated on vendor threads.
struct SubscriberCounters {
  std::atomic<std::uint64_t> received{0};            ///< valid samples delivered
  std::atomic<std::uint64_t> rejected{0};            ///< failed validation (bad length, NaN, ...)
  std::atomic<std::uint64_t> deserialize_errors{0};  ///< truncated or malformed CDR
  std::atomic<std::uint64_t> type_mismatches{0};     ///< writers on the topic with another type
};

/// Joins a domain. Not copyable; must outlive its publishers and subscribers.
///
/// Failure: the constructor throws std::runtime_error naming the vendor, domain and config file.
class Participant {
 public:
  explicit Participant(const DdsOptions& options);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  Vendor vendor() const noexcept { return vendor_; }
  int domain_id() const noexcept { return domain_id_; }
  const std::string& name() const noexcept { return name_; }
  const std::string& config_path() const noexcept { return config_path_; }

  /// Topics of other participants on the domain (topic, type, writer and reader counts), sorted
  /// by topic then type. Discovery is asynchronous: a just-started process sees nothing for
  /// ~20 ms (same vendor) to ~1 s (other vendor).
  std::vector<DiscoveredTopic> discovered_topics() const;

  /// Writers of other participants on `topic_name` known to discovery now (any type and QoS).
  /// From this participant's own table: no vendor call, no allocation, never blocks on a vendor
  /// lock (safe under locks a listener callback also takes).
  int writers_of(std::string_view topic_name) const noexcept;

  /// Writers discovered with a known topic name but another type, since start (all subscribers).
  std::uint64_t type_mismatches() const noexcept { return type_mismatches_.load(); }

  /// Internal: the vendor backend.
  detail::ParticipantBackend& backend() noexcept { return *backend_; }
  /// Internal: a subscriber registers its (topic, type) to be told about mismatching writers.
  /// Returns a token to pass to unwatch_topic().
  int watch_topic(const std::string& topic_name, const std::string& type_name,
                  SubscriberCounters* counters);
  void unwatch_topic(int token);

 private:
  struct Endpoint {
    detail::EndpointEvent event;
  };
  struct Watch {
    int token;
    std::string topic_name;
    std::string type_name;
    SubscriberCounters* counters;
  };
  void on_endpoint(const detail::EndpointEvent& event);
  void check_mismatch_locked(const detail::EndpointEvent& event, const Watch& watch);

  Vendor vendor_;
  int domain_id_;
  std::string name_;
  std::string config_path_;
  mutable std::mutex mutex_;
  std::vector<Endpoint> endpoints_;  // guarded by mutex_
  std::vector<Watch> watches_;       // guarded by mutex_
  int next_token_ = 1;
  std::atomic<std::uint64_t> type_mismatches_{0};
  std::unique_ptr<detail::ParticipantBackend> backend_;  // last: destroyed first
};

/// Polls `matched` every millisecond until it returns >= count or `timeout` passes.
template <class F>
bool wait_until_matched(F&& matched, int count, std::chrono::nanoseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (matched() < count) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

}  // namespace poise::dds
