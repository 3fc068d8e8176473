#pragma once
// Passive capture of DDS traffic: `poise record --passive`.
//
// ------------------------------------------------------------------------------------------------
// Why
//   A recorder that subscribes is one more reliable reader of every 1 kHz writer: each sample is
//   sent once more (one more sendmsg on the writer's thread, inside the control loop's tick) and
//   acknowledged. On this 2-core machine that costs the loop tens of microseconds per tick
//   (components/record/README.md, "Passive capture"). The passive recorder is not a reader of any
//   Poise topic: it reads copies of the UDP datagrams the loop sends anyway, from a packet socket
//   on the interface they travel on, and takes each sample's serialised payload out of the RTPS
//   messages (OMG DDSI-RTPS 2.x). The writers do no extra work for it.
//
// What it reads
//   - UDP datagrams to the ports of one DDS domain (the RTPS port mapping: 7400 + 250 x domain
//     ... + 249), IPv4, on one interface (default lo); a socket filter drops everything else in
//     the kernel.
//   - SEDP publication announcements (builtin writer 0x000003c2): writer GUID -> topic and type
//     name. The recorder's own participant (no readers of Poise topics) makes every participant
//     of the domain send it their announcements, late joiners included.
//   - DATA and DATA_FRAG (reassembled) of those writers, with the source timestamp of the
//     preceding INFO_TS. A sample sent to several readers (and repairs) is kept once, by (writer
//     GUID, sequence number).
//
// Limits (stated, not hidden)
//   - Only traffic that passes this machine's interface is seen: the loop's own machine, or
//     loopback. Encrypted traffic (DDS Security with payload protection) cannot be decoded.
//   - A datagram missed by the capture (kernel buffer full, counted) is not repaired: there is no
//     reliability between the recorder and the writers. Sequence numbers never seen are counted
//     per topic as lost ("vendor_lost" in the file's metadata, with capture = passive).
//   - IPv4 datagrams fragmented at the IP level (larger than the MTU) are not reassembled.
//   - Needs CAP_NET_RAW (root).
// ------------------------------------------------------------------------------------------------

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace poise::record {

/// One sample taken from the wire.
struct CapturedSample {
  const std::string* topic = nullptr;      ///< topic name as announced by the writer
  const std::string* type_name = nullptr;  ///< type name as announced by the writer
  const std::uint8_t* data = nullptr;      ///< serialised payload, encapsulation header included
  std::size_t size = 0;
  std::uint64_t writer_key = 0;          ///< hash of the writer's GUID
  std::int64_t source_timestamp_ns = 0;  ///< INFO_TS before the DATA (0: none)
  std::int64_t receive_timestamp_ns = 0;  ///< CLOCK_REALTIME when the capture read the datagram
};

struct CaptureCounters {
  std::uint64_t datagrams = 0;        ///< UDP datagrams read (one copy per datagram)
  std::uint64_t rtps_messages = 0;    ///< of which RTPS messages
  std::uint64_t samples = 0;          ///< samples delivered (after de-duplication)
  std::uint64_t duplicates = 0;       ///< copies of a sample already delivered (other readers, repairs)
  std::uint64_t unknown_writer = 0;   ///< samples of writers not announced (yet): held, or dropped past the buffer
  std::uint64_t malformed = 0;        ///< submessages that could not be parsed
  std::uint64_t kernel_drops = 0;     ///< datagrams the kernel dropped (capture buffer full)
  std::uint64_t writers = 0;          ///< writers announced in the domain
};

/// The RTPS decoding, independent of the socket (fed datagrams by RtpsCapture, or by a test).
class RtpsDecoder {
 public:
  using SampleFn = std::function<void(const CapturedSample&)>;
  explicit RtpsDecoder(SampleFn on_sample);
  ~RtpsDecoder();

  /// One UDP payload, received at `receive_ns`.
  void datagram(const std::uint8_t* data, std::size_t size, std::int64_t receive_ns);

  CaptureCounters counters() const;
  /// Per topic: sequence numbers never seen between the first and the last seen of each writer.
  std::map<std::string, std::uint64_t> lost_per_topic() const;
  /// Per topic: writers announced.
  std::map<std::string, int> writers_per_topic() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct CaptureOptions {
  std::string interface = "lo";
  int domain = 0;
  int receive_buffer_bytes = 64 << 20;  ///< the capture ring (blocks of 1 MiB)
};

/// A packet socket on one interface and a thread that feeds an RtpsDecoder.
class RtpsCapture {
 public:
  /// Opens the socket (throws std::runtime_error naming the cause: no such interface, not
  /// permitted without CAP_NET_RAW) and starts reading.
  RtpsCapture(CaptureOptions options, RtpsDecoder::SampleFn on_sample);
  ~RtpsCapture();
  RtpsCapture(const RtpsCapture&) = delete;
  RtpsCapture& operator=(const RtpsCapture&) = delete;

  /// Stops reading (idempotent); what was read has been delivered when it returns.
  void stop();
  CaptureCounters counters() const;
  std::map<std::string, std::uint64_t> lost_per_topic() const;
  std::map<std::string, int> writers_per_topic() const;

 private:
  void loop();
  CaptureOptions options_;
  RtpsDecoder decoder_;
  static constexpr unsigned kBlockBytes = 1u << 20;
  int fd_ = -1;
  bool loopback_ = false;
  std::uint8_t* ring_ = nullptr;
  std::size_t ring_bytes_ = 0;
  std::size_t blocks_ = 0;
  std::atomic<bool> stop_{false};
  mutable std::atomic<std::uint64_t> kernel_drops_{0};
  std::thread thread_;
};

}  // namespace poise::record
