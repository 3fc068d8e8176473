#pragma once
// Internal to the Cyclone backend: a Cyclone DDS 0.10 serialisation type (ddsi_sertype) whose
// samples are already-serialised CDR bytes. Cyclone's sertype/serdata interface is internal and
// changes in 0.11; everything that touches it lives in cyclone_serdata.cpp.

#include <cstdint>
#include <string>
#include <vector>

struct ddsi_sertype;
struct ddsi_serdata;

namespace poise::dds::detail {

/// The "sample" that dds_write() takes for a CDR sertype: bytes with the 4-byte header.
struct CycloneCdrSpan {
  const std::uint8_t* data;
  std::uint32_t size;
};

/// A new sertype for `type_name` (keyless, plain CDR). Ownership passes to Cyclone when
/// dds_create_topic_sertype succeeds; otherwise release it with cyclone_free_sertype().
ddsi_sertype* cyclone_make_cdr_sertype(const std::string& type_name);
void cyclone_free_sertype(ddsi_sertype* type);

/// Copies the serialised bytes (header included) of any serdata into `out`.
bool cyclone_serdata_bytes(const ddsi_serdata* serdata, std::vector<std::uint8_t>& out) noexcept;
/// Drops a reference obtained from dds_takecdr().
void cyclone_serdata_unref(ddsi_serdata* serdata) noexcept;

}  // namespace poise::dds::detail
