#pragma once
// Reads an MCAP file front to back (the streaming way): schemas, channels, messages (chunks
// decompressed, CRCs checked), metadata, and whether the file was finished (DataEnd, footer and
// closing magic present). A file cut short by a crash is read up to its last complete record and
// reported as incomplete, not as an error: everything before the cut is delivered.
//
// Failure: scan() never throws for file content. It returns a ScanResult whose `error` names the
// problem and the byte offset (not an MCAP file, a record longer than the file, a chunk whose CRC
// or compression is wrong, ...). Every length is checked against what remains before it is used,
// and a chunk may not claim more than `max_chunk_bytes` uncompressed.

#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace poise::record {

struct SchemaRecord {
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::string data;
};

struct ChannelRecord {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;
  std::map<std::string, std::string> metadata;
};

/// A message as read; `data` is valid only during the callback.
struct MessageView {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;
  std::uint64_t publish_time = 0;
  std::span<const std::uint8_t> data;
};

struct MetadataRecord {
  std::string name;
  std::map<std::string, std::string> metadata;
};

/// Callbacks of scan(); any may be empty. Returning false from on_message stops the scan early
/// (ScanResult::stopped).
struct ScanHandlers {
  std::function<void(const SchemaRecord&)> on_schema;
  std::function<void(const ChannelRecord&)> on_channel;
  std::function<bool(const MessageView&)> on_message;
  std::function<void(const MetadataRecord&)> on_metadata;
};

struct ScanResult {
  bool is_mcap = false;          ///< started with the MCAP magic and a Header record
  bool complete = false;         ///< DataEnd, footer and closing magic found: the writer finished
  bool stopped = false;          ///< a handler asked to stop
  std::string error;             ///< "" or what is wrong, with the byte offset
  std::string truncation;        ///< "" or where and how the file was cut (incomplete files)
  std::string profile, library;  ///< from the Header record
  std::uint64_t file_size = 0;
  std::uint64_t bytes_read = 0;  ///< up to the end of the last complete record read
  std::uint64_t chunks = 0;
  std::uint64_t messages = 0;
  std::map<std::string, std::uint64_t> compressions;  ///< chunk count per compression ("" = none)
  std::uint64_t compressed_bytes = 0;                 ///< sum of chunk record payloads as stored
  std::uint64_t uncompressed_bytes = 0;               ///< and uncompressed
  bool ok() const noexcept { return error.empty(); }
};

struct ScanOptions {
  std::uint64_t max_chunk_bytes = 1ULL << 30;  ///< refuse chunks claiming more (1 GiB)
  bool check_crc = true;
};

/// Reads `path` from the start. See the file comment for what is reported how.
ScanResult scan(const std::string& path, const ScanHandlers& handlers,
                const ScanOptions& options = {});

}  // namespace poise::record
