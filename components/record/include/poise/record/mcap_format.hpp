#pragma once
// The pieces of the MCAP container format (https://mcap.dev/spec, version 0) that Poise's writer
// and reader share: opcodes, the magic, CRC-32 and little-endian record encoding.
//
// A file is  <magic><Header><data section ... DataEnd>[<summary>][<summary offsets>]<Footer><magic>
// and every record is  <opcode u8><content length u64><content>.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace poise::record {

inline constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum class Op : std::uint8_t {
  header = 0x01,
  footer = 0x02,
  schema = 0x03,
  channel = 0x04,
  message = 0x05,
  chunk = 0x06,
  message_index = 0x07,
  chunk_index = 0x08,
  attachment = 0x09,
  attachment_index = 0x0A,
  statistics = 0x0B,
  metadata = 0x0C,
  metadata_index = 0x0D,
  summary_offset = 0x0E,
  data_end = 0x0F,
};

/// Size of a record's opcode and length prefix.
inline constexpr std::size_t kRecordPrefix = 9;

/// CRC-32 (ISO-HDLC, the zlib/PNG one MCAP uses), continued from `crc` (0 to start).
std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size) noexcept;

/// Appends little-endian fields to a byte vector (record content under construction).
class ByteWriter {
 public:
  explicit ByteWriter(std::vector<std::uint8_t>& out) : out_(out) {}
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) { le(v); }
  void u32(std::uint32_t v) { le(v); }
  void u64(std::uint64_t v) { le(v); }
  void bytes(const void* data, std::size_t size) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    out_.insert(out_.end(), p, p + size);
  }
  /// uint32 length + UTF-8 bytes.
  void string(std::string_view s) {
    u32(static_cast<std::uint32_t>(s.size()));
    bytes(s.data(), s.size());
  }
  /// Map<string, string>: uint32 byte length, then key/value strings.
  void string_map(const std::map<std::string, std::string>& m) {
    const std::size_t at = reserve_u32();
    for (const auto& [k, v] : m) {
      string(k);
      string(v);
    }
    patch_u32(at, static_cast<std::uint32_t>(out_.size() - at - 4));
  }
  /// Reserves a uint32 to be patched later (a length prefix); returns its position.
  std::size_t reserve_u32() {
    const std::size_t at = out_.size();
    u32(0);
    return at;
  }
  void patch_u32(std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i)
      out_[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
  }
  /// Starts a record: opcode and a length to patch with end_record().
  std::size_t begin_record(Op op) {
    u8(static_cast<std::uint8_t>(op));
    const std::size_t at = out_.size();
    u64(0);
    return at;
  }
  void end_record(std::size_t at) {
    const std::uint64_t n = out_.size() - at - 8;
    for (int i = 0; i < 8; ++i)
      out_[at + i] = static_cast<std::uint8_t>(n >> (8 * i));
  }

 private:
  template <class T>
  void le(T v) {
    for (std::size_t i = 0; i < sizeof(T); ++i)
      out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t>& out_;
};

/// Reads little-endian fields from a record's content. Every read is bounds-checked: a read past
/// the end sets ok() to false and returns zero / empty (never reads out of bounds).
class ByteReader {
 public:
  explicit ByteReader(std::span<const std::uint8_t> data) : data_(data) {}
  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  std::string string() {
    const std::uint32_t n = u32();
    const auto b = take(n);
    return std::string(reinterpret_cast<const char*>(b.data()), b.size());
  }
  std::map<std::string, std::string> string_map() {
    std::map<std::string, std::string> m;
    const std::uint32_t n = u32();
    ByteReader inner(take(n));
    while (ok_ && inner.ok() && inner.remaining() > 0) {
      std::string k = inner.string();
      std::string v = inner.string();
      if (inner.ok()) m[std::move(k)] = std::move(v);
    }
    if (!inner.ok()) ok_ = false;
    return m;
  }
  /// The next n bytes (empty and !ok() when fewer remain).
  std::span<const std::uint8_t> take(std::uint64_t n) {
    if (!ok_ || n > remaining()) {
      ok_ = false;
      return {};
    }
    auto s = data_.subspan(pos_, static_cast<std::size_t>(n));
    pos_ += static_cast<std::size_t>(n);
    return s;
  }
  std::span<const std::uint8_t> rest() { return take(remaining()); }
  std::size_t remaining() const noexcept { return data_.size() - pos_; }
  bool ok() const noexcept { return ok_; }

 private:
  std::uint64_t le(std::size_t n) {
    const auto b = take(n);
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < b.size(); ++i)
      v |= static_cast<std::uint64_t>(b[i]) << (8 * i);
    return v;
  }
  std::span<const std::uint8_t> data_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

}  // namespace poise::record
