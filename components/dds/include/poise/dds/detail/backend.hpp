#pragma once
// The untyped backend interface that each vendor implements (src/fastdds_backend.cpp,
// src/cyclone_backend.cpp). Backends move serialised CDR bytes (with the 4-byte encapsulation
// header) and know nothing of the C++ types; the typed layer (publisher.hpp, subscriber.hpp)
// serialises with Fast CDR through TypeSupport. Not for node code.

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "poise/dds/qos.hpp"
#include "poise/dds/vendor.hpp"

namespace poise::dds::detail {

/// Metadata of one received sample.
struct SampleMeta {
  std::int64_t source_timestamp_ns = 0;     ///< writer's clock (DDS source timestamp)
  std::int64_t reception_timestamp_ns = 0;  ///< reader's CLOCK_REALTIME at take
  std::uint64_t writer_id = 0;  ///< identifies the writer within this reader (publication handle)
};

class WriterBackend {
 public:
  virtual ~WriterBackend() = default;
  /// Publishes one serialised sample. False when the vendor refused it (logged by the caller).
  virtual bool write(const std::uint8_t* data, std::size_t size) noexcept = 0;
  /// Number of matched readers.
  virtual int matched() const noexcept = 0;
  /// Waits until every matched reliable reader acknowledged every sample written so far. False
  /// on timeout. (A reader that matched the writer on the writer's side may not yet have matched
  /// it on its own: the acknowledgment proves delivery.)
  virtual bool wait_for_acks(std::chrono::nanoseconds timeout) noexcept = 0;
};

/// What the vendor says a reader lost or refused since it was created (DDS SAMPLE_LOST and
/// SAMPLE_REJECTED statuses: gaps the reliability protocol could not fill, samples refused for
/// resource limits).
struct ReaderLosses {
  std::uint64_t lost = 0;
  std::uint64_t rejected = 0;
};

class ReaderBackend {
 public:
  virtual ~ReaderBackend() = default;
  /// Takes the oldest unread valid sample: its bytes replace the content of `bytes` (whose
  /// capacity is reused). False when there is none.
  virtual bool take(std::vector<std::uint8_t>& bytes, SampleMeta& meta) noexcept = 0;
  /// Number of matched writers.
  virtual int matched() const noexcept = 0;
  /// The vendor's loss counters of this reader (polled; cheap, not for the 1 kHz path).
  virtual ReaderLosses losses() const noexcept = 0;
  /// Called on a vendor thread whenever data arrived. Set once, right after creation.
  virtual void set_on_data_available(std::function<void()> callback) = 0;
};

/// A remote or local endpoint appeared (alive) or went away (!alive).
struct EndpointEvent {
  bool is_writer = false;
  bool alive = true;
  std::array<std::uint8_t, 16> guid{};
  std::string topic_name;
  std::string type_name;
};

struct BackendOptions {
  Vendor vendor = Vendor::cyclone;
  int domain_id = 0;
  std::string config_path;  ///< resolved, absolute, existing
  std::string participant_name;
  /// DDS Security files, absolute paths ("" ca: no security).
  struct Security {
    std::string ca, governance, certificate, private_key, permissions;
  } security;
  /// Discovery of every endpoint of other participants (both vendors call it on their threads).
  std::function<void(const EndpointEvent&)> on_endpoint;
};

class ParticipantBackend {
 public:
  virtual ~ParticipantBackend() = default;
  /// Throws std::runtime_error naming the topic on failure (configuration time).
  virtual std::unique_ptr<WriterBackend> create_writer(const std::string& topic_name,
                                                       const std::string& type_name,
                                                       std::size_t max_size, const Qos& qos) = 0;
  virtual std::unique_ptr<ReaderBackend> create_reader(const std::string& topic_name,
                                                       const std::string& type_name,
                                                       std::size_t max_size, const Qos& qos) = 0;
};

std::unique_ptr<ParticipantBackend> make_fastdds_backend(const BackendOptions& options);
std::unique_ptr<ParticipantBackend> make_cyclone_backend(const BackendOptions& options);

}  // namespace poise::dds::detail
