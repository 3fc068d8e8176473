#include "poise/record/mcap_reader.hpp"

#include <lz4frame.h>
#include <zstd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

#include "poise/record/mcap_format.hpp"

namespace poise::record {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

std::string at(std::uint64_t offset) {
  return " at byte " + std::to_string(offset);
}

bool decompress(const std::string& compression, std::span<const std::uint8_t> in,
                std::uint64_t size, std::vector<std::uint8_t>& out, std::string& why) {
  out.resize(size);
  if (compression.empty()) {
    if (in.size() != size) {
      why = "uncompressed chunk of " + std::to_string(in.size()) + " bytes claims " +
            std::to_string(size);
      return false;
    }
    std::memcpy(out.data(), in.data(), in.size());
    return true;
  }
  if (compression == "zstd") {
    const std::size_t n = ZSTD_decompress(out.data(), out.size(), in.data(), in.size());
    if (ZSTD_isError(n)) {
      why = std::string("zstd: ") + ZSTD_getErrorName(n);
      return false;
    }
    if (n != size) {
      why = "zstd chunk decompressed to " + std::to_string(n) + " bytes, claims " +
            std::to_string(size);
      return false;
    }
    return true;
  }
  if (compression == "lz4") {
    LZ4F_dctx* ctx = nullptr;
    if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) {
      why = "lz4: cannot create a context";
      return false;
    }
    std::size_t src_done = 0, dst_done = 0;
    std::size_t rc = 1;
    while (rc != 0 && src_done < in.size() && dst_done <= out.size()) {
      std::size_t dst = out.size() - dst_done, src = in.size() - src_done;
      rc = LZ4F_decompress(ctx, out.data() + dst_done, &dst, in.data() + src_done, &src, nullptr);
      if (LZ4F_isError(rc)) {
        why = std::string("lz4: ") + LZ4F_getErrorName(rc);
        LZ4F_freeDecompressionContext(ctx);
        return false;
      }
      if (src == 0 && dst == 0) break;
      src_done += src;
      dst_done += dst;
    }
    LZ4F_freeDecompressionContext(ctx);
    if (dst_done != size || rc != 0) {
      why = "lz4 chunk decompressed to " + std::to_string(dst_done) + " bytes, claims " +
            std::to_string(size);
      return false;
    }
    return true;
  }
  why = "unknown compression '" + compression + "'";
  return false;
}

class Scanner {
 public:
  Scanner(std::FILE* f, const ScanHandlers& h, const ScanOptions& o, ScanResult& r)
      : file_(f), handlers_(h), options_(o), result_(r) {}

  void run() {
    std::uint8_t magic[8];
    if (!read_exact(magic, 8) || std::memcmp(magic, kMagic, 8) != 0) {
      result_.error = "not an MCAP file (no MCAP magic at the start)";
      return;
    }
    offset_ = 8;
    bool first = true;
    bool in_summary = false;
    for (;;) {
      std::uint8_t prefix[kRecordPrefix];
      const std::size_t got = std::fread(prefix, 1, kRecordPrefix, file_);
      if (got == 0) {
        result_.truncation = "file ends" + at(offset_) + " before the footer";
        return;
      }
      if (got < kRecordPrefix) {
        // The closing magic is 8 bytes, less than a record prefix.
        if (in_summary_end_ && got == 8 && std::memcmp(prefix, kMagic, 8) == 0) {
          result_.complete = true;
          result_.bytes_read = offset_ + 8;
          return;
        }
        result_.truncation = "record header cut" + at(offset_);
        return;
      }
      const auto op = static_cast<Op>(prefix[0]);
      std::uint64_t length = 0;
      for (int i = 0; i < 8; ++i)
        length |= static_cast<std::uint64_t>(prefix[1 + i]) << (8 * i);
      if (first && op != Op::header) {
        result_.error = "not an MCAP file (first record is not a Header)";
        return;
      }
      if (length > result_.file_size - offset_ - kRecordPrefix) {
        result_.truncation = "record (opcode 0x" + hex(prefix[0]) + ", " + std::to_string(length) +
                             " bytes) cut by the end of the file" + at(offset_);
        return;
      }
      record_offset_ = offset_;
      if (op == Op::chunk) {
        if (!chunk(length)) return;
      } else {
        content_.resize(length);
        if (!read_exact(content_.data(), length)) {
          result_.truncation = "record cut" + at(offset_);
          return;
        }
        if (!record(op, content_, in_summary)) return;
      }
      if (first) result_.is_mcap = true;
      first = false;
      offset_ += kRecordPrefix + length;
      result_.bytes_read = offset_;
      if (result_.stopped) return;
      if (op == Op::data_end) in_summary = true;
      if (op == Op::footer) in_summary_end_ = true;
    }
  }

 private:
  static std::string hex(std::uint8_t v) {
    char b[3];
    std::snprintf(b, sizeof(b), "%02x", v);
    return b;
  }

  bool read_exact(void* dst, std::size_t n) { return std::fread(dst, 1, n, file_) == n; }

  bool bad(const std::string& what) {
    result_.error = what + at(record_offset_);
    return false;
  }

  bool chunk(std::uint64_t length) {
    content_.resize(length);
    if (!read_exact(content_.data(), length)) {
      result_.truncation = "chunk cut" + at(offset_);
      return false;
    }
    ByteReader r(content_);
    r.u64();  // message_start_time
    r.u64();  // message_end_time
    const std::uint64_t uncompressed_size = r.u64();
    const std::uint32_t crc = r.u32();
    const std::string compression = r.string();
    const std::uint64_t records_size = r.u64();
    const auto records = r.take(records_size);
    if (!r.ok()) return bad("malformed chunk record");
    if (uncompressed_size > options_.max_chunk_bytes) {
      return bad("chunk claims " + std::to_string(uncompressed_size) +
                 " uncompressed bytes (limit " + std::to_string(options_.max_chunk_bytes) + ")");
    }
    std::string why;
    if (!decompress(compression, records, uncompressed_size, chunk_, why))
      return bad("chunk: " + why);
    if (options_.check_crc && crc != 0 && crc32(0, chunk_.data(), chunk_.size()) != crc)
      return bad("chunk CRC mismatch");
    ++result_.chunks;
    ++result_.compressions[compression];
    result_.compressed_bytes += records.size();
    result_.uncompressed_bytes += chunk_.size();
    ByteReader inner(chunk_);
    while (inner.remaining() > 0) {
      const auto op = static_cast<Op>(inner.u8());
      const std::uint64_t n = inner.u64();
      const auto body = inner.take(n);
      if (!inner.ok()) return bad("record inside a chunk overruns the chunk");
      if (!record(op, body, false)) return false;
      if (result_.stopped) return true;
    }
    return true;
  }

  bool record(Op op, std::span<const std::uint8_t> body, bool in_summary) {
    ByteReader r(body);
    switch (op) {
      case Op::header:
        result_.profile = r.string();
        result_.library = r.string();
        if (!r.ok()) return bad("malformed Header record");
        return true;
      case Op::schema: {
        SchemaRecord s;
        s.id = r.u16();
        s.name = r.string();
        s.encoding = r.string();
        const std::uint32_t n = r.u32();
        const auto data = r.take(n);
        s.data.assign(reinterpret_cast<const char*>(data.data()), data.size());
        if (!r.ok()) return bad("malformed Schema record");
        if (!in_summary && s.id != 0 && handlers_.on_schema) handlers_.on_schema(s);
        return true;
      }
      case Op::channel: {
        ChannelRecord c;
        c.id = r.u16();
        c.schema_id = r.u16();
        c.topic = r.string();
        c.message_encoding = r.string();
        c.metadata = r.string_map();
        if (!r.ok()) return bad("malformed Channel record");
        if (!in_summary && handlers_.on_channel) handlers_.on_channel(c);
        return true;
      }
      case Op::message: {
        MessageView m;
        m.channel_id = r.u16();
        m.sequence = r.u32();
        m.log_time = r.u64();
        m.publish_time = r.u64();
        m.data = r.rest();
        if (!r.ok()) return bad("malformed Message record");
        ++result_.messages;
        if (handlers_.on_message && !handlers_.on_message(m)) result_.stopped = true;
        return true;
      }
      case Op::metadata: {
        MetadataRecord m;
        m.name = r.string();
        m.metadata = r.string_map();
        if (!r.ok()) return bad("malformed Metadata record");
        if (handlers_.on_metadata) handlers_.on_metadata(m);
        return true;
      }
      default:
        return true;  // indexes, statistics, footer, private records: not needed front to back
    }
  }

  std::FILE* file_;
  const ScanHandlers& handlers_;
  const ScanOptions& options_;
  ScanResult& result_;
  std::uint64_t offset_ = 0;
  std::uint64_t record_offset_ = 0;
  bool in_summary_end_ = false;
  std::vector<std::uint8_t> content_;
  std::vector<std::uint8_t> chunk_;
};

}  // namespace

ScanResult scan(const std::string& path, const ScanHandlers& handlers, const ScanOptions& options) {
  ScanResult result;
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) {
    result.error = "cannot open '" + path + "': " + std::strerror(errno);
    return result;
  }
  if (std::fseek(f.get(), 0, SEEK_END) != 0) {
    result.error = "'" + path + "' is not a regular file (cannot seek)";
    return result;
  }
  const long size = std::ftell(f.get());
  if (size < 0) {
    result.error = "'" + path + "': cannot tell its size";
    return result;
  }
  result.file_size = static_cast<std::uint64_t>(size);
  std::rewind(f.get());
  Scanner(f.get(), handlers, options, result).run();
  return result;
}

}  // namespace poise::record
