#include <zlib.h>

#include "poise/record/mcap_format.hpp"

namespace poise::record {

std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size) noexcept {
  // zlib's CRC-32 is the one MCAP specifies; feed it in pieces zlib's uInt can hold.
  const auto* p = static_cast<const Bytef*>(data);
  uLong c = crc;
  while (size > 0) {
    const std::size_t n = size > (1u << 30) ? (1u << 30) : size;
    c = ::crc32(c, p, static_cast<uInt>(n));
    p += n;
    size -= n;
  }
  return static_cast<std::uint32_t>(c);
}

}  // namespace poise::record
