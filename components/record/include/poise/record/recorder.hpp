#pragma once
// Records Poise DDS topics to MCAP files (`poise record`, `poise run --record`).
//
// ------------------------------------------------------------------------------------------------
// Contract
//   subscribes  every Poise topic of the topic table (or the ones named), from the start, so that
//               no early sample is missed; writers of either vendor, late joiners included.
//               QoS: the topic's own reliability and durability, keep-last 1000 (a latched topic's
//               history reaches the recorder when it joins late).
//   writes      one MCAP file (or a series when splitting): schema encoding `omgidl` (the
//               self-contained IDL text of the type, idl/gen_schemas.py), message encoding `cdr`
//               (the bytes as they arrived, encapsulation header included), log time = receive
//               time (CLOCK_REALTIME), publish time = the writer's source timestamp, sequence =
//               the recorder's receive count on that topic (a gap = a sample dropped here).
//   threading   DDS listener threads only copy the bytes into a queue; one writer thread writes
//               the file and writes the open chunk every `flush_interval_s`. A full queue
//               (`max_queue_bytes`, a disk slower than the traffic) drops and counts: the
//               recorder never slows a writer of the robot's topics.
//   losses      per topic: samples dropped by the recorder's queue, the vendor's SAMPLE_LOST
//               and SAMPLE_REJECTED counts, and on the per-tick topics (Qos::control()) the tick
//               gaps: ticks skipped between two consecutive samples of one writer (a tick the
//               node did not publish, or a sample lost on the way; every Poise type begins with
//               its Header, so the tick is read from the raw bytes). Written at the end as MCAP
//               metadata "poise_recorder" and printed.
//   crash       after SIGKILL or power loss, at most the open chunk is lost: 1.5 x
//               `flush_interval_s` of traffic (150 ms: the writer thread looks every half
//               interval and writes a chunk once it is an interval old) or `chunk_size` (1 MiB),
//               whichever is less, plus what was still queued while the disk lagged.
// ------------------------------------------------------------------------------------------------

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <poise/dds/participant.hpp>
#include <poise/dds/subscriber.hpp>

#include "poise/record/mcap_writer.hpp"
#include "poise/record/rtps_capture.hpp"

namespace poise::record {

struct RecorderOptions {
  std::string output;               ///< file path; with splitting, <stem>_<k><ext>
  std::vector<std::string> topics;  ///< empty: every Poise topic
  double split_size_mb = 0;         ///< start a new file past this size (0: never)
  double split_duration_s = 0;      ///< start a new file after this long (0: never)
  double flush_interval_s = 0.1;    ///< write the open chunk at least this often
  std::size_t max_queue_bytes = 256u << 20;
  WriterOptions writer;
  /// Passive capture (rtps_capture.hpp): no DDS reader of any Poise topic; the samples are taken
  /// from the UDP datagrams on `capture_interface`.
  bool passive = false;
  std::string capture_interface = "lo";
};

/// Totals of one topic.
struct TopicCounts {
  std::string topic;
  std::string type_name;
  std::uint64_t received = 0;  ///< delivered by DDS to the recorder
  std::uint64_t written = 0;   ///< in the file: in chunks written completely (not the open one)
  std::uint64_t dropped = 0;   ///< dropped by the recorder (queue full; after a write failure,
                               ///< every sample not in the file, the failed chunk's included)
  std::uint64_t vendor_lost = 0;
  std::uint64_t vendor_rejected = 0;
  std::uint64_t tick_gaps = 0;  ///< per-tick topics: ticks skipped within one writer's stream
  int writers = 0;              ///< matched writers now
};

struct RecorderStatus {
  std::vector<TopicCounts> topics;  ///< topics that have matched a writer or received a sample
  std::uint64_t messages = 0;       ///< written: in the file
  std::uint64_t bytes = 0;          ///< file bytes written (all files)
  std::uint64_t dropped = 0;
  std::uint64_t vendor_lost = 0;
  std::uint64_t tick_gaps = 0;
  std::vector<std::string> files;
  std::string error;  ///< the file failed (disk full, ...): "" while all is well
};

class Recorder {
 public:
  /// Subscribes and opens the first file. Throws std::invalid_argument naming an unknown topic,
  /// std::runtime_error when the file cannot be created.
  Recorder(dds::Participant& participant, RecorderOptions options);
  /// Passive (options.passive): opens the file and starts capturing domain `domain`'s datagrams.
  /// Create the DDS participant that makes the domain's writers announce themselves to this
  /// machine AFTER this (an announcement sent before the capture began is not seen again).
  /// Throws as above, and std::runtime_error when the capture cannot start (names the cause).
  Recorder(int domain, RecorderOptions options);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// Counters now (thread-safe).
  RecorderStatus status() const;
  /// Stops receiving, writes what is queued, the loss metadata and the summary. Idempotent.
  /// The final status (error set if a write failed).
  RecorderStatus finish();

 private:
  struct Topic;
  struct Item {
    Topic* topic;
    std::uint32_t sequence;
    std::uint64_t log_time, publish_time;
    std::vector<std::uint8_t> bytes;
  };
  void init();
  void on_sample(Topic& topic, const std::uint8_t* data, std::size_t size,
                 const dds::SampleMeta& m);
  void on_captured(const CapturedSample& s);
  void writer_loop();
  bool open_file();
  bool close_file();
  void write_item(Item& item);
  // Topic::written from the writer's messages in the file; after a failure, the messages of
  // the failed chunk counted as dropped. Writer thread.
  void count_written();
  std::string next_path();
  std::map<std::string, std::string> loss_metadata() const;

  dds::Participant* participant_ = nullptr;  // null when passive
  int domain_ = 0;
  RecorderOptions options_;
  std::unique_ptr<RtpsCapture> capture_;
  std::atomic<std::uint64_t> foreign_{0};  // passive: samples of topics not recorded
  std::vector<std::unique_ptr<Topic>> topics_;

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::vector<Item> queue_;  // guarded by queue_mutex_
  std::size_t queue_bytes_ = 0;
  bool stopping_ = false;
  std::atomic<bool> accepting_{true};

  // Writer thread only (status copies under status_mutex_).
  std::unique_ptr<McapWriter> writer_;
  std::vector<std::uint16_t> channel_of_;  // per topic index: channel id in the current file
  int file_index_ = 0;
  std::uint64_t bytes_closed_files_ = 0;
  std::int64_t file_opened_ns_ = 0;
  mutable std::mutex status_mutex_;
  std::vector<std::string> files_;
  std::string error_;
  std::uint64_t bytes_ = 0;
  std::uint64_t messages_ = 0;

  std::thread thread_;
  bool finished_ = false;
};

}  // namespace poise::record
