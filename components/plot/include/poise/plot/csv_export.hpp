#pragma once
// CSV export of an MCAP recording of Poise topics (`poise export FILE --csv`, and the data that
// `poise plot` hands to gnuplot).
//
// One CSV file per recorded Poise topic, named after the topic with '/' replaced by '_'
// (poise/state -> poise_state.csv), one row per message in file order. Columns:
//   log_time_s      MCAP log time minus the earliest log time of the file [s]
//   publish_time_s  MCAP publish time minus the same origin [s] (empty when the file has 0)
//   then every member of the type, flattened through the generated reflection (msg::visit_fields)
//   in IDL order: `header.tick`, `com_W[0]`, `feet[1].cop_F[0]`, ...
// Arrays bounded by a length field (q by joint_count) and sequences get as many columns as the
// largest length in the file; a row's cells past its own length are empty. Numbers in shortest
// round-trip form (a double parses back to the same double), booleans 1/0, enums by enumerator
// name, strings always double-quoted with inner quotes doubled (RFC 4180; they may hold commas and
// line breaks). Lines end in '\n'.
//
// The file is read twice (streaming, nothing held in memory but one sample per topic): the first
// pass decodes every message to find the column widths and counts what does not decode, the
// second writes the rows.
//
// Failure: export_csv() never throws for file content. What went wrong is in the ExportReport:
// not an MCAP file (nothing written), a file cut short or damaged (what it holds is exported),
// messages that do not decode (counted per topic with the first reason; their rows are left out),
// channels that are not Poise topics (skipped, listed), topics asked for that the file does not
// hold (nothing written). Output files that cannot be created are reported in `error`.

#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <poise/record/mcap_reader.hpp>

namespace poise::plot {

struct ExportOptions {
  std::string output_dir;           ///< where the CSV files go (created if needed)
  std::vector<std::string> topics;  ///< only these topics (empty: every Poise topic)
  /// true: a topic of `topics` that the file does not hold is an error (nothing is written);
  /// false: such topics are only listed in ExportReport::absent_topics.
  bool topics_must_exist = true;
  /// Progress lines ("N messages") on this stream on long files (nullptr: none).
  std::FILE* progress = nullptr;
  /// Called in the second pass for every decoded sample of an exported topic: `sample` points to
  /// the poise::msg type whose DDS type name is `type_name`. Valid only during the call.
  std::function<void(const std::string& topic, std::string_view type_name, const void* sample,
                     const record::MessageView& message)>
      on_sample;
};

/// One exported topic.
struct TopicExport {
  std::string topic;      ///< e.g. "poise/state"
  std::string type_name;  ///< e.g. "poise::msg::State"
  std::string csv_path;
  std::vector<std::string> columns;  ///< CSV header, in order
  std::uint64_t rows = 0;            ///< messages written
  std::uint64_t decode_failures = 0;
  std::string first_failure;  ///< reason of the first message that did not decode
  std::uint64_t invalid = 0;  ///< decoded but failing field validation (exported anyway)
  std::string first_invalid;  ///< "field: reason" of the first of those

  /// 1-based column number of `name` (the way gnuplot counts), or 0 when absent.
  int column(std::string_view name) const;
};

/// A channel that was not exported and why.
struct SkippedChannel {
  std::string topic;
  std::string schema_name;
  std::string reason;
  std::uint64_t messages = 0;
};

struct ExportReport {
  record::ScanResult scan;           ///< of the second pass (the first when nothing was written)
  std::uint64_t first_log_time = 0;  ///< origin of log_time_s [ns since the Unix epoch]
  std::vector<TopicExport> topics;   ///< by topic name
  std::vector<SkippedChannel> skipped;
  std::vector<std::string> absent_topics;  ///< asked for, not in the file
  std::string error;  ///< "" or why nothing (or not everything) could be written

  std::uint64_t decode_failures() const;
  const TopicExport* find(std::string_view topic) const;
};

/// Exports `mcap_path` as described at the top of this file.
ExportReport export_csv(const std::string& mcap_path, const ExportOptions& options);

/// `name` with '/' replaced by '_' and ".csv" appended (the CSV file name of a topic).
std::string csv_file_name(std::string_view topic);

/// `text` as one RFC 4180 field: in double quotes, inner quotes doubled.
std::string csv_quote(std::string_view text);

}  // namespace poise::plot
