#pragma once
// What a recording holds (`poise info`): per topic the type, count, rate, gaps and size; the
// recorder's loss counters; whether the file was finished.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "poise/record/mcap_reader.hpp"

namespace poise::record {

struct TopicInfo {
  std::string topic;
  std::string schema_name;
  std::string schema_encoding;
  std::string message_encoding;
  std::uint64_t messages = 0;
  std::uint64_t bytes = 0;  ///< message payload bytes
  std::uint64_t first_log_time = 0, last_log_time = 0;
  double mean_rate_hz = 0;          ///< (messages - 1) / (last - first)
  double longest_interval_s = 0;    ///< between two consecutive messages (log time)
  std::uint64_t sequence_gaps = 0;  ///< messages missing by the MCAP sequence numbers
  // Poise topics carry Header.tick first: per-tick streams are checked tick by tick.
  bool has_ticks = false;
  bool per_tick = false;  ///< one message per control tick (most consecutive ticks differ by 1)
  std::uint64_t first_tick = 0, last_tick = 0;
  std::uint64_t distinct_ticks = 0;
  std::uint64_t duplicate_ticks = 0;  ///< messages whose tick was seen before on this topic
  std::uint64_t missing_ticks = 0;    ///< per-tick streams: ticks in [first, last] never seen
  /// Per-tick streams: ticks of the run before this topic's first one, never seen (first_tick -
  /// RecordingInfo::run_first_tick): a recorder that joined late, or a writer that began late.
  std::uint64_t missing_at_start = 0;
};

struct RecordingInfo {
  std::string path;
  ScanResult scan;
  std::uint64_t start_time = 0, end_time = 0;  ///< log times (ns since the Unix epoch)
  std::vector<TopicInfo> topics;               ///< by topic name
  /// The run's first tick, the reference of TopicInfo::missing_at_start: the tick poise-sim puts
  /// in poise/robot_description's header (k0, the first frame it publishes; latched, so a late
  /// recorder has it too), or lower, the earliest tick of any per-tick topic in the file.
  /// Meaningful when run_first_tick_source is not empty.
  std::uint64_t run_first_tick = 0;
  /// "poise/robot_description", "earliest per-tick topic", or "" (no per-tick topic).
  std::string run_first_tick_source;
  std::map<std::string, std::map<std::string, std::string>> metadata;  ///< by record name

  double duration_s() const { return end_time > start_time ? (end_time - start_time) * 1e-9 : 0; }
};

/// Reads the whole file. Never throws for file content: see info.scan.error / .complete.
RecordingInfo read_recording_info(const std::string& path);

/// Human-readable report (what `poise info` prints).
std::string format_recording_info(const RecordingInfo& info);
/// The same as JSON (`poise info --json`).
nlohmann::ordered_json recording_info_json(const RecordingInfo& info);

/// Header.tick of a Poise sample's CDR bytes (encapsulation + body): false when the bytes are not
/// little- or big-endian plain CDR of at least a Header.
bool header_tick(const std::uint8_t* data, std::size_t size, std::uint64_t& tick);

}  // namespace poise::record
