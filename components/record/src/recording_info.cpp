#include "poise/record/recording_info.hpp"

#include <algorithm>
#include <cstdio>
#include <ctime>

namespace poise::record {

bool header_tick(const std::uint8_t* data, std::size_t size, std::uint64_t& tick) {
  if (size < 4 + 16 || data[0] != 0 || data[1] > 1) return false;
  const bool little = data[1] == 1;
  tick = 0;
  for (int i = 0; i < 8; ++i) {
    const std::uint64_t b = data[4 + (little ? i : 7 - i)];
    tick |= b << (8 * i);
  }
  return true;
}

namespace {

struct Accumulator {
  TopicInfo info;
  bool description = false;  // poise/robot_description: its header tick is the run's k0
  std::uint64_t previous_time = 0;
  std::uint64_t previous_sequence = 0;
  std::vector<std::uint64_t> ticks;
};

std::string utc(std::uint64_t ns) {
  const std::time_t t = static_cast<std::time_t>(ns / 1000000000ULL);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[64];
  std::strftime(b, sizeof(b), "%Y-%m-%d %H:%M:%S", &tm);
  char out[80];
  std::snprintf(out, sizeof(out), "%s.%03u UTC", b,
                static_cast<unsigned>((ns / 1000000ULL) % 1000ULL));
  return out;
}

/// The run's first tick (the description's k0, or the earliest tick of any per-tick topic if
/// lower or if there is none) and each per-tick topic's ticks missing before its first one.
void find_missing_starts(RecordingInfo& out, std::uint64_t description_tick) {
  bool any = false;
  std::uint64_t earliest = 0;
  for (const auto& t : out.topics)
    if (t.per_tick && (!any || t.first_tick < earliest)) {
      earliest = t.first_tick;
      any = true;
    }
  if (!any) return;
  if (description_tick > 0 && description_tick <= earliest) {
    out.run_first_tick = description_tick;
    out.run_first_tick_source = "poise/robot_description";
  } else {
    out.run_first_tick = earliest;
    out.run_first_tick_source = "earliest per-tick topic";
  }
  for (auto& t : out.topics)
    if (t.per_tick) t.missing_at_start = t.first_tick - out.run_first_tick;
}

}  // namespace

RecordingInfo read_recording_info(const std::string& path) {
  RecordingInfo out;
  out.path = path;
  std::map<std::uint16_t, SchemaRecord> schemas;
  std::map<std::uint16_t, Accumulator> channels;
  ScanHandlers h;
  h.on_schema = [&](const SchemaRecord& s) { schemas[s.id] = s; };
  h.on_channel = [&](const ChannelRecord& c) {
    Accumulator& a = channels[c.id];
    a.info.topic = c.topic;
    a.info.message_encoding = c.message_encoding;
    if (auto it = schemas.find(c.schema_id); it != schemas.end()) {
      a.info.schema_name = it->second.name;
      a.info.schema_encoding = it->second.encoding;
    }
    a.description =
        c.topic == "poise/robot_description" && a.info.schema_name == "poise::msg::RobotDescription";
  };
  std::uint64_t description_tick = 0;  // 0: none, or a robot that does not say (tick 0)
  h.on_message = [&](const MessageView& m) {
    Accumulator& a = channels[m.channel_id];
    TopicInfo& t = a.info;
    if (t.messages == 0) {
      t.first_log_time = m.log_time;
    } else {
      if (m.log_time > a.previous_time)
        t.longest_interval_s =
            std::max(t.longest_interval_s, (m.log_time - a.previous_time) * 1e-9);
      if (m.sequence > a.previous_sequence + 1)
        t.sequence_gaps += m.sequence - a.previous_sequence - 1;
    }
    t.first_log_time = std::min(t.first_log_time, m.log_time);
    t.last_log_time = std::max(t.last_log_time, m.log_time);
    a.previous_time = m.log_time;
    a.previous_sequence = m.sequence;
    ++t.messages;
    t.bytes += m.data.size();
    std::uint64_t tick;
    if (t.message_encoding == "cdr" && t.schema_name.starts_with("poise::msg::") &&
        header_tick(m.data.data(), m.data.size(), tick)) {
      a.ticks.push_back(tick);
      if (a.description && tick > 0 && (description_tick == 0 || tick < description_tick))
        description_tick = tick;
    }
    return true;
  };
  h.on_metadata = [&](const MetadataRecord& m) {
    auto& dst = out.metadata[m.name];
    for (const auto& [k, v] : m.metadata)
      dst[k] = v;
  };
  out.scan = scan(path, h);
  for (auto& [id, a] : channels) {
    TopicInfo& t = a.info;
    if (t.topic.empty()) t.topic = "(channel " + std::to_string(id) + ")";
    if (t.messages > 1 && t.last_log_time > t.first_log_time)
      t.mean_rate_hz = (t.messages - 1) / ((t.last_log_time - t.first_log_time) * 1e-9);
    if (!a.ticks.empty() && a.ticks.size() == t.messages) {
      t.has_ticks = true;
      std::uint64_t unit_steps = 0;
      for (std::size_t i = 1; i < a.ticks.size(); ++i)
        unit_steps += a.ticks[i] == a.ticks[i - 1] + 1;
      std::sort(a.ticks.begin(), a.ticks.end());
      t.first_tick = a.ticks.front();
      t.last_tick = a.ticks.back();
      t.distinct_ticks =
          static_cast<std::uint64_t>(std::unique(a.ticks.begin(), a.ticks.end()) - a.ticks.begin());
      t.duplicate_ticks = t.messages - t.distinct_ticks;
      t.per_tick = a.ticks.size() > 2 && unit_steps * 2 > a.ticks.size();
      if (t.per_tick) t.missing_ticks = (t.last_tick - t.first_tick + 1) - t.distinct_ticks;
    }
    if (t.messages > 0) {
      if (out.start_time == 0 || t.first_log_time < out.start_time)
        out.start_time = t.first_log_time;
      out.end_time = std::max(out.end_time, t.last_log_time);
    }
    out.topics.push_back(std::move(t));
  }
  std::sort(out.topics.begin(), out.topics.end(),
            [](const TopicInfo& a, const TopicInfo& b) { return a.topic < b.topic; });
  find_missing_starts(out, description_tick);
  return out;
}

namespace {

/// Appends printf-formatted text (at most 511 characters) to `s`.
template <class... Args>
void append_line(std::string& s, const char* fmt, Args... args) {
  char line[512];
  std::snprintf(line, sizeof(line), fmt, args...);
  s += line;
}

/// A topic's TICKS column: the range, and for per-tick topics what is missing and repeated.
std::string ticks_text(const TopicInfo& t) {
  std::string ticks = "-";
  if (t.has_ticks) {
    char b[200];
    if (t.per_tick && t.missing_at_start > 0) {
      std::snprintf(b, sizeof(b), "%llu..%llu, %llu missing at the start, %llu missing after, "
                    "%llu repeated",
                    static_cast<unsigned long long>(t.first_tick),
                    static_cast<unsigned long long>(t.last_tick),
                    static_cast<unsigned long long>(t.missing_at_start),
                    static_cast<unsigned long long>(t.missing_ticks),
                    static_cast<unsigned long long>(t.duplicate_ticks));
    } else if (t.per_tick) {
      std::snprintf(b, sizeof(b), "%llu..%llu, %llu missing, %llu repeated",
                    static_cast<unsigned long long>(t.first_tick),
                    static_cast<unsigned long long>(t.last_tick),
                    static_cast<unsigned long long>(t.missing_ticks),
                    static_cast<unsigned long long>(t.duplicate_ticks));
    } else {
      std::snprintf(b, sizeof(b), "%llu..%llu", static_cast<unsigned long long>(t.first_tick),
                    static_cast<unsigned long long>(t.last_tick));
    }
    ticks = b;
  }
  return ticks;
}

/// The recorder's loss counters from the file's poise_recorder metadata.
std::string recorder_losses_text(const RecordingInfo& info) {
  std::string s;
  const auto add = [&s](const char* fmt, auto... args) { append_line(s, fmt, args...); };
  if (auto it = info.metadata.find("poise_recorder"); it != info.metadata.end()) {
    const auto& m = it->second;
    auto get = [&](const std::string& k) {
      auto f = m.find(k);
      return f == m.end() ? std::string("?") : f->second;
    };
    add("\nRecorder losses: %s dropped by the recorder, %s lost or rejected by DDS, %s ticks "
        "skipped within a writer's stream (seen live)\n",
        get("total.dropped").c_str(), get("total.vendor_lost").c_str(),
        m.count("total.tick_gaps") ? get("total.tick_gaps").c_str() : "?");
    for (const auto& t : info.topics) {
      const std::string gaps = m.count(t.topic + ".tick_gaps") ? get(t.topic + ".tick_gaps") : "0";
      if (get(t.topic + ".dropped") != "0" || get(t.topic + ".vendor_lost") != "0" ||
          get(t.topic + ".vendor_rejected") != "0" || gaps != "0") {
        add("  %-24s received %s, dropped %s, DDS lost %s, DDS rejected %s, tick gaps %s\n",
            t.topic.c_str(), get(t.topic + ".received").c_str(), get(t.topic + ".dropped").c_str(),
            get(t.topic + ".vendor_lost").c_str(), get(t.topic + ".vendor_rejected").c_str(),
            gaps.c_str());
      }
    }
  } else {
    add("\nRecorder losses: unknown (no poise_recorder metadata: the recording did not finish)\n");
  }
  return s;
}

}  // namespace

std::string format_recording_info(const RecordingInfo& info) {
  std::string s;
  const auto add = [&s](const char* fmt, auto... args) { append_line(s, fmt, args...); };
  const ScanResult& r = info.scan;
  add("File:        %s (%.2f MB)\n", info.path.c_str(), r.file_size / 1e6);
  if (!r.complete) {
    add("State:       INCOMPLETE: %s; %.2f of %.2f MB read (every complete chunk), the rest is "
        "lost\n",
        r.truncation.empty() ? "no footer" : r.truncation.c_str(), r.bytes_read / 1e6,
        r.file_size / 1e6);
  } else {
    add("State:       complete (summary and footer present)\n");
  }
  add("Library:     %s\n", r.library.c_str());
  if (info.end_time > 0) {
    add("Start:       %s\n", utc(info.start_time).c_str());
    add("End:         %s\n", utc(info.end_time).c_str());
  }
  add("Duration:    %.3f s\n", info.duration_s());
  std::string comp;
  for (const auto& [name, n] : r.compressions)
    comp += (comp.empty() ? "" : ", ") + (name.empty() ? std::string("none") : name) + " (" +
            std::to_string(n) + " chunks)";
  add("Compression: %s; %.2f MB of messages stored in %.2f MB\n", comp.empty() ? "-" : comp.c_str(),
      r.uncompressed_bytes / 1e6, r.compressed_bytes / 1e6);
  add("Messages:    %llu in %zu topics\n\n", static_cast<unsigned long long>(r.messages),
      info.topics.size());
  add("%-26s %-30s %9s %9s %9s %10s %s\n", "TOPIC", "TYPE", "MESSAGES", "RATE[Hz]", "MAXGAP[s]",
      "SIZE[MB]", "TICKS");
  for (const auto& t : info.topics) {
    std::string ticks = ticks_text(t);
    if (t.sequence_gaps) ticks += ", " + std::to_string(t.sequence_gaps) + " dropped (sequence)";
    add("%-26s %-30s %9llu %9.1f %9.3f %10.3f %s\n", t.topic.c_str(), t.schema_name.c_str(),
        static_cast<unsigned long long>(t.messages), t.mean_rate_hz, t.longest_interval_s,
        t.bytes / 1e6, ticks.c_str());
  }
  bool start_missing = false;
  for (const auto& t : info.topics) {
    if (t.missing_at_start == 0) continue;
    if (!start_missing)
      add("\nThe recording misses the start of the run (first tick %llu, from %s):\n",
          static_cast<unsigned long long>(info.run_first_tick),
          info.run_first_tick_source.c_str());
    start_missing = true;
    add("  first tick %llu on %s, expected %llu: %llu ticks missing at the start\n",
        static_cast<unsigned long long>(t.first_tick), t.topic.c_str(),
        static_cast<unsigned long long>(info.run_first_tick),
        static_cast<unsigned long long>(t.missing_at_start));
  }
  s += recorder_losses_text(info);
  if (!r.ok()) add("\nERROR: %s\n", r.error.c_str());
  return s;
}

nlohmann::ordered_json recording_info_json(const RecordingInfo& info) {
  nlohmann::ordered_json j;
  const ScanResult& r = info.scan;
  j["file"] = info.path;
  j["complete"] = r.complete;
  j["error"] = r.error;
  j["truncation"] = r.truncation;
  j["file_size"] = r.file_size;
  j["bytes_read"] = r.bytes_read;
  j["library"] = r.library;
  j["start_time_ns"] = info.start_time;
  j["end_time_ns"] = info.end_time;
  j["duration_s"] = info.duration_s();
  j["chunks"] = r.chunks;
  j["messages"] = r.messages;
  if (!info.run_first_tick_source.empty()) {
    j["run_first_tick"] = info.run_first_tick;
    j["run_first_tick_source"] = info.run_first_tick_source;
  }
  for (const auto& [name, n] : r.compressions)
    j["compression"][name.empty() ? "none" : name] = n;
  j["topics"] = nlohmann::ordered_json::array();
  for (const auto& t : info.topics) {
    nlohmann::ordered_json o;
    o["topic"] = t.topic;
    o["schema"] = t.schema_name;
    o["schema_encoding"] = t.schema_encoding;
    o["message_encoding"] = t.message_encoding;
    o["messages"] = t.messages;
    o["bytes"] = t.bytes;
    o["mean_rate_hz"] = t.mean_rate_hz;
    o["longest_interval_s"] = t.longest_interval_s;
    o["sequence_gaps"] = t.sequence_gaps;
    if (t.has_ticks) {
      o["first_tick"] = t.first_tick;
      o["last_tick"] = t.last_tick;
      o["distinct_ticks"] = t.distinct_ticks;
      o["duplicate_ticks"] = t.duplicate_ticks;
      o["per_tick"] = t.per_tick;
      o["missing_ticks"] = t.missing_ticks;
      if (t.per_tick) o["missing_at_start"] = t.missing_at_start;
    }
    j["topics"].push_back(o);
  }
  j["metadata"] = info.metadata;
  return j;
}

}  // namespace poise::record
