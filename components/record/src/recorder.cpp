#include "poise/record/recorder.hpp"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <stdexcept>

#include <poise/dds/log.hpp>
#include <poise/dds/topics.hpp>
#include <poise/msg/idl_schemas_gen.hpp>

namespace poise::record {
namespace {

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

std::string_view schema_of(std::string_view type_name) {
  for (const auto& s : msg::kIdlSchemas)
    if (s.type_name == type_name) return s.idl;
  return {};
}

/// Reliable or best effort as the topic is, keep-last deep enough for bursts.
dds::Qos recorder_qos(const dds::Qos& topic_qos) {
  dds::Qos q = topic_qos;
  q.history_depth = 1000;
  q.deadline = dds::Qos::infinite;
  return q;
}

constexpr std::uint16_t kNoChannel = 0xFFFF;

/// The Header.tick of a serialised Poise sample (every type begins with its Header; the tick is
/// the first 8 bytes after the 4-byte encapsulation header). False if too short or unknown.
bool tick_of(const std::vector<std::uint8_t>& bytes, std::uint64_t& tick) {
  if (bytes.size() < 12 || bytes[0] != 0x00 || (bytes[1] != 0x00 && bytes[1] != 0x01))
    return false;
  const bool little = bytes[1] == 0x01;
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) {
    const std::uint64_t b = bytes[static_cast<std::size_t>(4 + (little ? i : 7 - i))];
    v |= b << (8 * i);
  }
  tick = v;
  return true;
}

}  // namespace

struct Recorder::Topic {
  std::size_t index;
  std::string name;
  std::string type_name;
  std::string_view schema;
  std::atomic<std::uint64_t> received{0};
  std::atomic<std::uint64_t> dropped{0};
  std::atomic<std::uint64_t> written{0};  ///< in the file (complete chunks), all files
  // Writer thread only: in the files closed before, and accepted by the open file's writer
  // (in its open chunk or in the file).
  std::uint64_t written_closed_files = 0;
  std::uint64_t accepted_open_file = 0;
  std::atomic<std::uint64_t> tick_gaps{0};
  bool per_tick = false;  ///< one sample per tick per writer (Qos::control() topics)
  std::mutex ticks_mutex;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> last_tick;  ///< (writer, tick)
  std::unique_ptr<dds::RawSubscriber> subscriber;

  /// Counts the ticks skipped since this writer's previous sample. A tick at or before the
  /// previous one (a repeat, a restarted writer) restarts the count from it.
  void count_tick(std::uint64_t writer, std::uint64_t tick) {
    std::lock_guard lock(ticks_mutex);
    for (auto& [w, last] : last_tick) {
      if (w != writer) continue;
      if (tick > last + 1) tick_gaps.fetch_add(tick - last - 1, std::memory_order_relaxed);
      last = tick;
      return;
    }
    last_tick.emplace_back(writer, tick);
  }
};

Recorder::Recorder(dds::Participant& participant, RecorderOptions options)
    : participant_(&participant), domain_(participant.domain_id()), options_(std::move(options)) {
  options_.passive = false;
  init();
}

Recorder::Recorder(int domain, RecorderOptions options)
    : domain_(domain), options_(std::move(options)) {
  options_.passive = true;
  init();
}

void Recorder::init() {
  std::vector<const dds::TopicDescription*> chosen;
  if (options_.topics.empty()) {
    for (const auto& t : dds::topic_table())
      chosen.push_back(&t);
  } else {
    for (const auto& name : options_.topics) {
      const auto* t = dds::find_topic(name);
      if (!t) {
        std::string known;
        for (const auto& k : dds::topic_table())
          known += (known.empty() ? "" : ", ") + std::string(k.topic_name);
        throw std::invalid_argument("unknown topic '" + name + "'; Poise topics: " + known);
      }
      if (std::find(chosen.begin(), chosen.end(), t) == chosen.end()) chosen.push_back(t);
    }
  }
  if (options_.output.empty()) throw std::invalid_argument("no output file given");
  // The file first: a bad path fails before anything subscribes.
  if (!open_file()) throw std::runtime_error(error_);
  for (const auto* t : chosen) {
    auto topic = std::make_unique<Topic>();
    topic->index = topics_.size();
    topic->name = std::string(t->topic_name);
    topic->type_name = std::string(t->type_name);
    topic->schema = schema_of(t->type_name);
    topic->per_tick = t->qos == dds::Qos::control();
    if (topic->schema.empty())
      throw std::logic_error("no IDL schema generated for " + topic->type_name);
    topics_.push_back(std::move(topic));
  }
  channel_of_.assign(topics_.size(), kNoChannel);
  thread_ = std::thread([this] { writer_loop(); });
  if (options_.passive) {
    try {
      capture_ = std::make_unique<RtpsCapture>(
          CaptureOptions{options_.capture_interface, domain_},
          [this](const CapturedSample& s) { on_captured(s); });
    } catch (...) {
      finish();
      throw;
    }
    return;
  }
  for (auto& topic : topics_) {
    Topic* tp = topic.get();
    tp->subscriber = std::make_unique<dds::RawSubscriber>(
        *participant_, tp->name, tp->type_name, recorder_qos(dds::find_topic(tp->name)->qos),
        [this, tp](const std::vector<std::uint8_t>& bytes, const dds::SampleMeta& meta) {
          on_sample(*tp, bytes.data(), bytes.size(), meta);
        });
  }
}

Recorder::~Recorder() {
  finish();
}

void Recorder::on_captured(const CapturedSample& s) {
  for (auto& t : topics_) {
    if (t->name != *s.topic) continue;
    if (*s.type_name != t->type_name) break;  // a foreign type under a Poise topic name
    dds::SampleMeta meta;
    meta.writer_id = s.writer_key;
    meta.source_timestamp_ns = s.source_timestamp_ns;
    meta.reception_timestamp_ns = s.receive_timestamp_ns;
    on_sample(*t, s.data, s.size, meta);
    return;
  }
  foreign_.fetch_add(1, std::memory_order_relaxed);
}

void Recorder::on_sample(Topic& topic, const std::uint8_t* data, std::size_t size,
                         const dds::SampleMeta& meta) {
  if (!accepting_.load(std::memory_order_relaxed)) return;  // after the end of the recording
  std::vector<std::uint8_t> bytes(data, data + size);
  if (std::uint64_t tick = 0; topic.per_tick && tick_of(bytes, tick))
    topic.count_tick(meta.writer_id, tick);
  const std::uint64_t sequence = topic.received.fetch_add(1, std::memory_order_relaxed) + 1;
  const auto log_time = static_cast<std::uint64_t>(meta.reception_timestamp_ns);
  const auto publish_time = meta.source_timestamp_ns > 0
                                ? static_cast<std::uint64_t>(meta.source_timestamp_ns)
                                : log_time;
  {
    std::lock_guard lock(queue_mutex_);
    if (queue_bytes_ + bytes.size() > options_.max_queue_bytes) {
      topic.dropped.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    queue_.push_back(Item{&topic, static_cast<std::uint32_t>(sequence), log_time, publish_time,
                          std::move(bytes)});
    queue_bytes_ += size;
  }
  queue_cv_.notify_one();
}

std::string Recorder::next_path() {
  const bool splitting = options_.split_size_mb > 0 || options_.split_duration_s > 0;
  if (!splitting) return options_.output;
  const std::filesystem::path p(options_.output);
  const std::string ext = p.has_extension() ? p.extension().string() : ".mcap";
  return (p.parent_path() / (p.stem().string() + "_" + std::to_string(file_index_) + ext)).string();
}

bool Recorder::open_file() {
  const std::string path = next_path();
  try {
    writer_ = std::make_unique<McapWriter>(path, options_.writer);
  } catch (const std::exception& e) {
    std::lock_guard lock(status_mutex_);
    error_ = e.what();
    return false;
  }
  file_opened_ns_ = monotonic_ns();
  char host[256] = {};
  ::gethostname(host, sizeof(host) - 1);
  writer_->write_metadata("poise_recording",
                          {{"dds_vendor", participant_ ? std::string(dds::to_string(participant_->vendor()))
                                                       : std::string("any (passive capture)")},
                           {"domain", std::to_string(domain_)},
                           {"capture", options_.passive ? "passive:" + options_.capture_interface
                                                        : std::string("dds reader")},
                           {"host", host},
                           {"file_index", std::to_string(file_index_)},
                           {"compression", std::string(to_string(options_.writer.compression))}});
  std::fill(channel_of_.begin(), channel_of_.end(), kNoChannel);
  std::lock_guard lock(status_mutex_);
  files_.push_back(path);
  return true;
}

std::map<std::string, std::string> Recorder::loss_metadata() const {
  std::map<std::string, std::string> m;
  std::uint64_t dropped = 0, lost = 0, gaps = 0;
  const auto capture_lost =
      capture_ ? capture_->lost_per_topic() : std::map<std::string, std::uint64_t>{};
  for (const auto& t : topics_) {
    auto losses = t->subscriber ? t->subscriber->losses() : dds::ReaderLosses{};
    if (capture_) {
      // Passive: sequence numbers of announced writers never seen on the wire.
      const auto it = capture_lost.find(t->name);
      if (it != capture_lost.end()) losses.lost = it->second;
    }
    if (t->received.load() == 0 && losses.lost == 0 && losses.rejected == 0) continue;
    m[t->name + ".received"] = std::to_string(t->received.load());
    m[t->name + ".written"] = std::to_string(t->written.load());
    m[t->name + ".dropped"] = std::to_string(t->dropped.load());
    m[t->name + ".vendor_lost"] = std::to_string(losses.lost);
    m[t->name + ".vendor_rejected"] = std::to_string(losses.rejected);
    if (t->per_tick) m[t->name + ".tick_gaps"] = std::to_string(t->tick_gaps.load());
    dropped += t->dropped.load();
    lost += losses.lost + losses.rejected;
    gaps += t->tick_gaps.load();
  }
  m["total.dropped"] = std::to_string(dropped);
  m["total.vendor_lost"] = std::to_string(lost);
  m["total.tick_gaps"] = std::to_string(gaps);
  if (capture_) {
    const CaptureCounters c = capture_->counters();
    m["capture.datagrams"] = std::to_string(c.datagrams);
    m["capture.samples"] = std::to_string(c.samples);
    m["capture.duplicates"] = std::to_string(c.duplicates);
    m["capture.kernel_drops"] = std::to_string(c.kernel_drops);
    m["capture.unknown_writer"] = std::to_string(c.unknown_writer);
    m["capture.malformed"] = std::to_string(c.malformed);
    m["capture.foreign"] = std::to_string(foreign_.load());
  }
  return m;
}

void Recorder::count_written() {
  if (!writer_) return;
  for (auto& t : topics_) {
    const std::uint16_t channel = channel_of_[t->index];
    if (channel == kNoChannel) continue;
    const std::uint64_t in_file = writer_->messages_in_file(channel);
    if (writer_->failed() && t->accepted_open_file > in_file) {
      // The chunk that failed: accepted, never in the file.
      t->dropped.fetch_add(t->accepted_open_file - in_file, std::memory_order_relaxed);
      t->accepted_open_file = in_file;
    }
    t->written.store(t->written_closed_files + in_file, std::memory_order_relaxed);
  }
}

bool Recorder::close_file() {
  if (!writer_) return true;
  // The open chunk first, so that the counts of the metadata are those of the file.
  writer_->flush();
  count_written();
  writer_->write_metadata("poise_recorder", loss_metadata());
  const bool ok = writer_->close();
  count_written();
  for (auto& t : topics_) {
    t->written_closed_files = t->written.load(std::memory_order_relaxed);
    t->accepted_open_file = 0;
  }
  std::lock_guard lock(status_mutex_);
  if (!ok && error_.empty()) error_ = writer_->error();
  bytes_closed_files_ += writer_->stats().bytes_written;
  bytes_ = bytes_closed_files_;
  writer_.reset();
  return ok;
}

void Recorder::write_item(Item& item) {
  Topic& t = *item.topic;
  if (!writer_ || writer_->failed()) {
    t.dropped.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  std::uint16_t& channel = channel_of_[t.index];
  if (channel == kNoChannel) {
    const std::uint16_t schema = writer_->add_schema(t.type_name, "omgidl", t.schema);
    channel = writer_->add_channel(schema, t.name, "cdr");
  }
  // Written = in the file: counted once its chunk is (count_written), not when accepted here.
  if (writer_->write_message(channel, item.sequence, item.log_time, item.publish_time,
                             item.bytes.data(), item.bytes.size())) {
    ++t.accepted_open_file;
  } else {
    t.dropped.fetch_add(1, std::memory_order_relaxed);
  }
}

void Recorder::writer_loop() {
  std::vector<Item> batch;
  const auto flush_ns = static_cast<std::int64_t>(options_.flush_interval_s * 1e9);
  std::int64_t last_flush = monotonic_ns();
  for (;;) {
    bool stopping;
    {
      std::unique_lock lock(queue_mutex_);
      queue_cv_.wait_for(lock,
                         std::chrono::nanoseconds(std::max<std::int64_t>(flush_ns / 2, 1000000)),
                         [this] { return stopping_ || !queue_.empty(); });
      batch.swap(queue_);
      queue_bytes_ = 0;
      stopping = stopping_;
    }
    for (auto& item : batch)
      write_item(item);
    batch.clear();
    count_written();
    const std::int64_t now = monotonic_ns();
    if (writer_ && !writer_->failed()) {
      if (now - last_flush >= flush_ns) {
        writer_->flush();
        last_flush = now;
      }
      const bool too_big = options_.split_size_mb > 0 &&
                           writer_->stats().bytes_written >= options_.split_size_mb * 1e6;
      const bool too_long =
          options_.split_duration_s > 0 && now - file_opened_ns_ >= options_.split_duration_s * 1e9;
      count_written();  // after the flush
      if (!stopping && (too_big || too_long)) {
        close_file();
        ++file_index_;
        open_file();
      }
    }
    if (writer_) {
      std::lock_guard lock(status_mutex_);
      bytes_ = bytes_closed_files_ + writer_->stats().bytes_written;
      if (writer_->failed() && error_.empty()) error_ = writer_->error();
    }
    if (stopping) {
      // Samples that arrived while this batch was written.
      std::unique_lock lock(queue_mutex_);
      if (queue_.empty()) break;
    }
  }
}

RecorderStatus Recorder::status() const {
  RecorderStatus s;
  const auto capture_writers = capture_ ? capture_->writers_per_topic() : std::map<std::string, int>{};
  const auto capture_lost =
      capture_ ? capture_->lost_per_topic() : std::map<std::string, std::uint64_t>{};
  for (const auto& t : topics_) {
    TopicCounts c;
    c.writers = t->subscriber ? t->subscriber->matched() : 0;
    if (capture_) {
      const auto w = capture_writers.find(t->name);
      c.writers = w == capture_writers.end() ? 0 : w->second;
      const auto l = capture_lost.find(t->name);
      c.vendor_lost = l == capture_lost.end() ? 0 : l->second;
    }
    c.received = t->received.load();
    if (c.writers == 0 && c.received == 0) continue;
    c.topic = t->name;
    c.type_name = t->type_name;
    c.written = t->written.load();
    c.dropped = t->dropped.load();
    c.tick_gaps = t->tick_gaps.load();
    if (t->subscriber) {
      const auto l = t->subscriber->losses();
      c.vendor_lost = l.lost;
      c.vendor_rejected = l.rejected;
    }
    s.messages += c.written;
    s.dropped += c.dropped;
    s.vendor_lost += c.vendor_lost + c.vendor_rejected;
    s.tick_gaps += c.tick_gaps;
    s.topics.push_back(std::move(c));
  }
  std::lock_guard lock(status_mutex_);
  s.bytes = bytes_;
  s.files = files_;
  s.error = error_;
  return s;
}

RecorderStatus Recorder::finish() {
  if (finished_) return status();
  finished_ = true;
  // Stop taking new samples, but keep the subscribers (their loss counters) until the end. The
  // capture delivers what it has read first.
  if (capture_) capture_->stop();
  accepting_.store(false);
  {
    std::lock_guard lock(queue_mutex_);
    stopping_ = true;
  }
  queue_cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  close_file();
  RecorderStatus s = status();
  for (auto& t : topics_)
    t->subscriber.reset();
  return s;
}

}  // namespace poise::record
