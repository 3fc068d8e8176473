#pragma once
// Writes an MCAP file: chunked (zstd, lz4 or uncompressed), one Message Index per channel after
// every chunk, and on close a summary section (schemas, channels, statistics, chunk indexes,
// metadata indexes) with summary offsets, so that indexed readers find everything from the footer.
//
// Crash safety. Schema, Channel and Metadata records go straight to the file; messages are
// collected in the open chunk, which is written (and by default fdatasync'ed) when it reaches
// chunk_size bytes or when flush() is called. After SIGKILL or power loss, every chunk written
// before is readable by a streaming reader; what is lost is the open chunk: at most chunk_size
// bytes of messages, or the time between two flush() calls (the recorder calls it every
// 100 ms), whichever comes first.
//
// Failure: the constructor throws std::runtime_error naming the file when it cannot be created.
// After that nothing throws for I/O: a failed write (disk full, file size limit) puts the writer
// in a failed state, error() says why (the file and the errno text), and every later call
// returns false. The file is cut back to the end of its last complete record (a chunk half
// written is removed), so what was written before the failure stays on disk and remains
// readable as a file cut short. A message accepted by write_message() is in the file only once
// its chunk is: messages_in_file() counts those, stats().messages every message accepted
// (the messages of a chunk that failed are in the second count, not the first).
//
// Not thread-safe: one thread writes (the recorder has a writer thread of its own).

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace poise::record {

enum class Compression { none, lz4, zstd };

/// "none", "lz4", "zstd".
std::string_view to_string(Compression c);
/// Parses "none", "lz4" or "zstd" ("" means none). Throws std::invalid_argument otherwise.
Compression parse_compression(std::string_view name);

struct WriterOptions {
  Compression compression = Compression::zstd;
  /// A chunk is written once its uncompressed records reach this many bytes.
  std::size_t chunk_size = 1 << 20;
  /// fdatasync after every chunk (bounds what power loss costs; off for benchmarks on tmpfs).
  bool sync_chunks = true;
  /// zstd level (1 = fastest); lz4 uses its default frame settings.
  int zstd_level = 1;
  /// The Header record's library field.
  std::string library = "poise record";
  /// false: an existing file is refused (the constructor throws, naming it), never truncated.
  bool overwrite = true;
};

/// Per-file counts, as the Statistics record will say.
struct WriterStats {
  std::uint64_t messages = 0;          ///< accepted by write_message (open chunk included)
  std::uint64_t messages_in_file = 0;  ///< in chunks written completely to the file
  std::uint64_t chunks = 0;
  std::uint64_t bytes_written = 0;  ///< file size so far
  std::uint64_t message_bytes = 0;  ///< sum of message payload sizes
  std::uint64_t first_log_time = 0;
  std::uint64_t last_log_time = 0;
};

class McapWriter {
 public:
  /// Creates (truncates) `path` and writes the magic and the Header record.
  McapWriter(const std::string& path, const WriterOptions& options = {});
  /// Closes the file properly (close()) if that was not done; errors are then lost: call close().
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Registers a schema and writes its record. Returns its id (>= 1), or 0 when failed.
  std::uint16_t add_schema(std::string_view name, std::string_view encoding, std::string_view data);
  /// Registers a channel and writes its record. Returns its id, or 0xFFFF when failed (ids start at
  /// 0; at most 65535 channels).
  std::uint16_t add_channel(std::uint16_t schema_id, std::string_view topic,
                            std::string_view message_encoding,
                            const std::map<std::string, std::string>& metadata = {});
  /// Adds a message to the open chunk (written when full). False when failed or on an unknown
  /// channel.
  bool write_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
                     std::uint64_t publish_time, const std::uint8_t* data, std::size_t size);
  /// Writes a Metadata record (straight to the file, indexed in the summary).
  bool write_metadata(std::string_view name, const std::map<std::string, std::string>& metadata);
  /// Writes the open chunk, if it holds anything.
  bool flush();
  /// Writes the open chunk, DataEnd, the summary and the footer, and closes the file.
  /// Idempotent. False (with error()) when any write failed.
  bool close();

  bool failed() const noexcept { return !error_.empty(); }
  const std::string& error() const noexcept { return error_; }
  const WriterStats& stats() const noexcept { return stats_; }
  /// Bytes of messages in the open chunk (not yet on disk).
  std::size_t open_chunk_bytes() const noexcept { return chunk_.size(); }
  const std::string& path() const noexcept { return path_; }
  /// Messages of a channel in chunks written completely to the file (not those of the open
  /// chunk, nor of a chunk whose write failed).
  std::uint64_t messages_in_file(std::uint16_t channel_id) const noexcept {
    return channel_id < channels_.size() ? channels_[channel_id].in_file : 0;
  }

 private:
  struct ChannelInfo {
    std::uint16_t id;
    std::uint16_t schema_id;
    std::string topic;
    std::string encoding;
    std::map<std::string, std::string> metadata;
    std::uint64_t count = 0;    // accepted
    std::uint64_t in_file = 0;  // in chunks written completely
  };
  struct SchemaInfo {
    std::uint16_t id;
    std::string name;
    std::string encoding;
    std::string data;
  };
  struct ChunkIndex {
    std::uint64_t start_time, end_time, offset, length;
    std::map<std::uint16_t, std::uint64_t> index_offsets;
    std::uint64_t index_length;
    std::uint64_t compressed_size, uncompressed_size;
  };
  struct MetadataIndex {
    std::uint64_t offset, length;
    std::string name;
  };

  bool write_bytes(const std::uint8_t* data, std::size_t size);
  bool write_record(std::vector<std::uint8_t>& scratch);
  bool write_chunk();
  bool fail(std::string why);
  // After a failed write: cuts the file back to `size` bytes (the end of the last complete
  // record), so that it ends on a record boundary.
  void cut_back_to(std::uint64_t size);
  void append_schema(std::vector<std::uint8_t>& out, const SchemaInfo& s) const;
  void append_channel(std::vector<std::uint8_t>& out, const ChannelInfo& c) const;
  // close(): the DataEnd record, then the summary (records by opcode, their offsets, the footer).
  void write_data_end();
  void write_summary();
  void append_statistics(std::vector<std::uint8_t>& out) const;
  void append_chunk_indexes(std::vector<std::uint8_t>& out) const;
  void append_metadata_indexes(std::vector<std::uint8_t>& out) const;

  std::string path_;
  WriterOptions options_;
  int fd_ = -1;
  bool closed_ = false;
  std::string error_;
  WriterStats stats_;
  std::uint32_t data_crc_ = 0;  // CRC of every byte written so far (until DataEnd)
  std::vector<SchemaInfo> schemas_;
  std::vector<ChannelInfo> channels_;
  std::vector<ChunkIndex> chunk_indexes_;
  std::vector<MetadataIndex> metadata_indexes_;
  // The open chunk: uncompressed records, time range and per-channel message index.
  std::vector<std::uint8_t> chunk_;
  std::uint64_t chunk_start_ = 0, chunk_end_ = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;
  std::vector<std::uint8_t> scratch_;     // one record under construction
  std::vector<std::uint8_t> compressed_;  // compressed chunk records
};

}  // namespace poise::record
