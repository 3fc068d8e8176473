#include "poise/record/mcap_writer.hpp"

#include <fcntl.h>
#include <lz4frame.h>
#include <unistd.h>
#include <zstd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "poise/record/mcap_format.hpp"

namespace poise::record {

std::string_view to_string(Compression c) {
  switch (c) {
    case Compression::none:
      return "none";
    case Compression::lz4:
      return "lz4";
    case Compression::zstd:
      return "zstd";
  }
  return "none";
}

Compression parse_compression(std::string_view name) {
  if (name.empty() || name == "none") return Compression::none;
  if (name == "lz4") return Compression::lz4;
  if (name == "zstd") return Compression::zstd;
  throw std::invalid_argument("unknown compression '" + std::string(name) +
                              "' (expected zstd, lz4 or none)");
}

namespace {
// The chunk record's `compression` field: "" for none.
std::string_view mcap_name(Compression c) {
  return c == Compression::none ? std::string_view{} : to_string(c);
}
}  // namespace

McapWriter::McapWriter(const std::string& path, const WriterOptions& options)
    : path_(path), options_(options) {
  // O_EXCL when not overwriting: the check and the creation are one step (no other writer can
  // slip in between).
  fd_ = ::open(path.c_str(),
               O_WRONLY | O_CREAT | O_CLOEXEC | (options_.overwrite ? O_TRUNC : O_EXCL), 0644);
  if (fd_ < 0) {
    if (errno == EEXIST)
      throw std::runtime_error("'" + path + "' exists: a recording is not written over it");
    throw std::runtime_error("cannot create '" + path + "': " + std::strerror(errno));
  }
  chunk_.reserve(options_.chunk_size + (64 << 10));
  scratch_.reserve(4096);
  write_bytes(kMagic, sizeof(kMagic));
  ByteWriter w(scratch_);
  const auto at = w.begin_record(Op::header);
  w.string("");  // profile: none of the well-known ones (plain DDS CDR)
  w.string(options_.library);
  w.end_record(at);
  write_record(scratch_);
  if (failed()) {
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error("cannot write '" + path + "': " + error_);
  }
}

McapWriter::~McapWriter() {
  close();
}

bool McapWriter::fail(std::string why) {
  if (error_.empty()) error_ = std::move(why);
  return false;
}

void McapWriter::cut_back_to(std::uint64_t size) {
  // Shrinking is allowed past a file size limit and frees space on a full disk. If it fails too,
  // the half-written record stays: a streaming reader still stops at it (file cut short).
  if (fd_ >= 0 && ::ftruncate(fd_, static_cast<off_t>(size)) == 0) stats_.bytes_written = size;
}

bool McapWriter::write_bytes(const std::uint8_t* data, std::size_t size) {
  if (failed() || fd_ < 0) return false;
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd_, data + done, size - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      fail("writing '" + path_ + "' failed after " + std::to_string(stats_.bytes_written + done) +
           " bytes: " + std::strerror(e));
      cut_back_to(stats_.bytes_written);  // the bytes of this call that did get written
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  data_crc_ = crc32(data_crc_, data, size);
  stats_.bytes_written += size;
  return true;
}

bool McapWriter::write_record(std::vector<std::uint8_t>& scratch) {
  const bool ok = write_bytes(scratch.data(), scratch.size());
  scratch.clear();
  return ok;
}

void McapWriter::append_schema(std::vector<std::uint8_t>& out, const SchemaInfo& s) const {
  ByteWriter w(out);
  const auto at = w.begin_record(Op::schema);
  w.u16(s.id);
  w.string(s.name);
  w.string(s.encoding);
  w.u32(static_cast<std::uint32_t>(s.data.size()));
  w.bytes(s.data.data(), s.data.size());
  w.end_record(at);
}

void McapWriter::append_channel(std::vector<std::uint8_t>& out, const ChannelInfo& c) const {
  ByteWriter w(out);
  const auto at = w.begin_record(Op::channel);
  w.u16(c.id);
  w.u16(c.schema_id);
  w.string(c.topic);
  w.string(c.encoding);
  w.string_map(c.metadata);
  w.end_record(at);
}

std::uint16_t McapWriter::add_schema(std::string_view name, std::string_view encoding,
                                     std::string_view data) {
  if (failed() || closed_) return 0;
  if (schemas_.size() >= 0xFFFE) {
    fail("too many schemas");
    return 0;
  }
  schemas_.push_back(SchemaInfo{static_cast<std::uint16_t>(schemas_.size() + 1), std::string(name),
                                std::string(encoding), std::string(data)});
  append_schema(scratch_, schemas_.back());
  return write_record(scratch_) ? schemas_.back().id : 0;
}

std::uint16_t McapWriter::add_channel(std::uint16_t schema_id, std::string_view topic,
                                      std::string_view message_encoding,
                                      const std::map<std::string, std::string>& metadata) {
  if (failed() || closed_) return 0xFFFF;
  if (channels_.size() >= 0xFFFF) {
    fail("too many channels");
    return 0xFFFF;
  }
  channels_.push_back(ChannelInfo{static_cast<std::uint16_t>(channels_.size()), schema_id,
                                  std::string(topic), std::string(message_encoding), metadata});
  append_channel(scratch_, channels_.back());
  return write_record(scratch_) ? channels_.back().id : 0xFFFF;
}

bool McapWriter::write_message(std::uint16_t channel_id, std::uint32_t sequence,
                               std::uint64_t log_time, std::uint64_t publish_time,
                               const std::uint8_t* data, std::size_t size) {
  if (failed() || closed_) return false;
  if (channel_id >= channels_.size())
    return fail("message on unknown channel " + std::to_string(channel_id));
  const std::uint64_t offset = chunk_.size();
  ByteWriter w(chunk_);
  const auto at = w.begin_record(Op::message);
  w.u16(channel_id);
  w.u32(sequence);
  w.u64(log_time);
  w.u64(publish_time);
  w.bytes(data, size);
  w.end_record(at);
  chunk_index_[channel_id].emplace_back(log_time, offset);
  if (offset == 0 || log_time < chunk_start_) chunk_start_ = log_time;
  if (offset == 0 || log_time > chunk_end_) chunk_end_ = log_time;
  if (stats_.messages == 0 || log_time < stats_.first_log_time) stats_.first_log_time = log_time;
  if (log_time > stats_.last_log_time) stats_.last_log_time = log_time;
  ++stats_.messages;
  stats_.message_bytes += size;
  ++channels_[channel_id].count;
  if (chunk_.size() >= options_.chunk_size) return write_chunk();
  return true;
}

bool McapWriter::write_chunk() {
  if (chunk_.empty()) return !failed();
  const std::uint32_t crc = crc32(0, chunk_.data(), chunk_.size());
  const std::uint8_t* records = chunk_.data();
  std::size_t records_size = chunk_.size();
  switch (options_.compression) {
    case Compression::none:
      break;
    case Compression::zstd: {
      compressed_.resize(ZSTD_compressBound(chunk_.size()));
      const std::size_t n = ZSTD_compress(compressed_.data(), compressed_.size(), chunk_.data(),
                                          chunk_.size(), options_.zstd_level);
      if (ZSTD_isError(n)) return fail(std::string("zstd: ") + ZSTD_getErrorName(n));
      records = compressed_.data();
      records_size = n;
      break;
    }
    case Compression::lz4: {
      LZ4F_preferences_t prefs{};
      prefs.frameInfo.contentSize = chunk_.size();
      compressed_.resize(LZ4F_compressFrameBound(chunk_.size(), &prefs));
      const std::size_t n = LZ4F_compressFrame(compressed_.data(), compressed_.size(),
                                               chunk_.data(), chunk_.size(), &prefs);
      if (LZ4F_isError(n)) return fail(std::string("lz4: ") + LZ4F_getErrorName(n));
      records = compressed_.data();
      records_size = n;
      break;
    }
  }
  ChunkIndex index{};
  index.start_time = chunk_start_;
  index.end_time = chunk_end_;
  index.offset = stats_.bytes_written;
  index.compressed_size = records_size;
  index.uncompressed_size = chunk_.size();

  ByteWriter w(scratch_);
  const auto at = w.begin_record(Op::chunk);
  w.u64(chunk_start_);
  w.u64(chunk_end_);
  w.u64(chunk_.size());
  w.u32(crc);
  w.string(mcap_name(options_.compression));
  w.u64(records_size);
  // The records follow the header part; write the two pieces without copying the records.
  const std::uint64_t content = scratch_.size() - at - 8 + records_size;
  for (int i = 0; i < 8; ++i)
    scratch_[at + i] = static_cast<std::uint8_t>(content >> (8 * i));
  if (!write_record(scratch_) || !write_bytes(records, records_size)) {
    // No half chunk in the file: it ends with the last complete record, and the messages of
    // this chunk are not counted as in the file.
    scratch_.clear();
    cut_back_to(index.offset);
    return false;
  }
  index.length = stats_.bytes_written - index.offset;
  // The chunk is in the file (a streaming reader reads it; the message indexes are optional).
  for (const auto& [channel, entries] : chunk_index_) {
    channels_[channel].in_file += entries.size();
    stats_.messages_in_file += entries.size();
  }

  const std::uint64_t index_start = stats_.bytes_written;
  for (const auto& [channel, entries] : chunk_index_) {
    index.index_offsets[channel] = stats_.bytes_written + scratch_.size();
    const auto rec = w.begin_record(Op::message_index);
    w.u16(channel);
    w.u32(static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, offset] : entries) {
      w.u64(time);
      w.u64(offset);
    }
    w.end_record(rec);
  }
  if (!write_record(scratch_)) {
    cut_back_to(index_start);  // the chunk stays, complete; its indexes are optional
    return false;
  }
  index.index_length = stats_.bytes_written - index_start;
  chunk_indexes_.push_back(std::move(index));
  ++stats_.chunks;
  chunk_.clear();
  chunk_index_.clear();
  if (options_.sync_chunks && ::fdatasync(fd_) != 0 && errno != EINVAL && errno != EROFS) {
    return fail("fdatasync '" + path_ + "': " + std::strerror(errno));
  }
  return true;
}

bool McapWriter::write_metadata(std::string_view name,
                                const std::map<std::string, std::string>& metadata) {
  if (failed() || closed_) return false;
  ByteWriter w(scratch_);
  const auto at = w.begin_record(Op::metadata);
  w.string(name);
  w.string_map(metadata);
  w.end_record(at);
  const std::uint64_t offset = stats_.bytes_written;
  const std::uint64_t length = scratch_.size();
  if (!write_record(scratch_)) return false;
  metadata_indexes_.push_back(MetadataIndex{offset, length, std::string(name)});
  return true;
}

bool McapWriter::flush() {
  if (failed() || closed_) return false;
  return write_chunk();
}

void McapWriter::append_statistics(std::vector<std::uint8_t>& out) const {
  ByteWriter w(out);
  const auto at = w.begin_record(Op::statistics);
  w.u64(stats_.messages);
  w.u16(static_cast<std::uint16_t>(schemas_.size()));
  w.u32(static_cast<std::uint32_t>(channels_.size()));
  w.u32(0);  // attachments
  w.u32(static_cast<std::uint32_t>(metadata_indexes_.size()));
  w.u32(static_cast<std::uint32_t>(stats_.chunks));
  w.u64(stats_.messages ? stats_.first_log_time : 0);
  w.u64(stats_.messages ? stats_.last_log_time : 0);
  const auto map_at = w.reserve_u32();
  for (const auto& c : channels_) {
    w.u16(c.id);
    w.u64(c.count);
  }
  w.patch_u32(map_at, static_cast<std::uint32_t>(out.size() - map_at - 4));
  w.end_record(at);
}

void McapWriter::append_chunk_indexes(std::vector<std::uint8_t>& out) const {
  ByteWriter w(out);
  for (const auto& ci : chunk_indexes_) {
    const auto at = w.begin_record(Op::chunk_index);
    w.u64(ci.start_time);
    w.u64(ci.end_time);
    w.u64(ci.offset);
    w.u64(ci.length);
    const auto map_at = w.reserve_u32();
    for (const auto& [channel, offset] : ci.index_offsets) {
      w.u16(channel);
      w.u64(offset);
    }
    w.patch_u32(map_at, static_cast<std::uint32_t>(out.size() - map_at - 4));
    w.u64(ci.index_length);
    w.string(mcap_name(options_.compression));
    w.u64(ci.compressed_size);
    w.u64(ci.uncompressed_size);
    w.end_record(at);
  }
}

void McapWriter::append_metadata_indexes(std::vector<std::uint8_t>& out) const {
  ByteWriter w(out);
  for (const auto& mi : metadata_indexes_) {
    const auto at = w.begin_record(Op::metadata_index);
    w.u64(mi.offset);
    w.u64(mi.length);
    w.string(mi.name);
    w.end_record(at);
  }
}

namespace {

// A group of summary records of one opcode: its opcode, file offset and length.
using SummaryGroup = std::tuple<Op, std::uint64_t, std::uint64_t>;

// The Summary Offset records of `groups` and the footer, appended to `summary` (which starts at
// file offset `summary_start`).
void append_offsets_and_footer(std::vector<std::uint8_t>& summary,
                               const std::vector<SummaryGroup>& groups,
                               std::uint64_t summary_start) {
  ByteWriter w(summary);
  const std::uint64_t offsets_start = summary_start + summary.size();
  for (const auto& [op, start, length] : groups) {
    const auto at = w.begin_record(Op::summary_offset);
    w.u8(static_cast<std::uint8_t>(op));
    w.u64(start);
    w.u64(length);
    w.end_record(at);
  }
  // Footer (content: 8 + 8 + 4 bytes); its CRC covers the summary, the offsets and the footer
  // up to the CRC field.
  w.u8(static_cast<std::uint8_t>(Op::footer));
  w.u64(20);
  w.u64(summary_start);
  w.u64(groups.empty() ? 0 : offsets_start);
  w.u32(crc32(0, summary.data(), summary.size()));
  w.bytes(kMagic, sizeof(kMagic));
}

}  // namespace

void McapWriter::write_data_end() {
  // DataEnd carries the CRC of everything before it.
  ByteWriter w(scratch_);
  const auto at = w.begin_record(Op::data_end);
  w.u32(data_crc_);
  w.end_record(at);
  write_record(scratch_);
}

void McapWriter::write_summary() {
  // Summary: records grouped by opcode, each group located by a Summary Offset record.
  const std::uint64_t summary_start = stats_.bytes_written;
  std::vector<std::uint8_t> summary;
  std::vector<SummaryGroup> groups;
  auto group = [&](Op op, auto&& append) {
    const std::size_t before = summary.size();
    append();
    if (summary.size() > before)
      groups.emplace_back(op, summary_start + before, summary.size() - before);
  };
  group(Op::schema, [&] {
    for (const auto& s : schemas_)
      append_schema(summary, s);
  });
  group(Op::channel, [&] {
    for (const auto& c : channels_)
      append_channel(summary, c);
  });
  group(Op::statistics, [&] { append_statistics(summary); });
  group(Op::chunk_index, [&] { append_chunk_indexes(summary); });
  group(Op::metadata_index, [&] { append_metadata_indexes(summary); });
  append_offsets_and_footer(summary, groups, summary_start);
  write_bytes(summary.data(), summary.size());
}

bool McapWriter::close() {
  if (closed_) return !failed();
  closed_ = true;
  if (fd_ < 0) return !failed();
  if (!failed()) write_chunk();
  if (!failed()) write_data_end();
  if (!failed()) write_summary();
  if (::fsync(fd_) != 0 && errno != EINVAL && errno != EROFS && !failed()) {
    fail("fsync '" + path_ + "': " + std::strerror(errno));
  }
  ::close(fd_);
  fd_ = -1;
  return !failed();
}

}  // namespace poise::record
