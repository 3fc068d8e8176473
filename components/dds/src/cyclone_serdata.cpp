// Cyclone DDS 0.10 custom serialisation type carrying already-serialised plain CDR.
//
// The typed layer serialises the fastddsgen C++ objects with Fast CDR (4-byte encapsulation
// header + XCDR1 body, exactly what Fast DDS puts on the wire); this sertype only moves those
// bytes in and out of Cyclone. Topics are keyless, so key handling is trivial.
//
// Everything here depends on Cyclone's internal ddsi_sertype/ddsi_serdata interface of 0.10
// (it changes in 0.11). Nothing else in the project includes these headers.
#include "cyclone_serdata.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/ddsi_sertype.h>
#include <dds/ddsi/q_radmin.h>

namespace poise::dds::detail {
namespace {

constexpr std::uint8_t kEmptyCdr[4] = {0x00, 0x01, 0x00, 0x00};  // header only (CDR_LE)

/// One received or written sample: the generic part, then the bytes inline.
struct CdrSerdata {
  ddsi_serdata c;
  std::uint32_t size;
  std::uint8_t* bytes() { return reinterpret_cast<std::uint8_t*>(this + 1); }
  const std::uint8_t* bytes() const { return reinterpret_cast<const std::uint8_t*>(this + 1); }
};

struct CdrSertype {
  ddsi_sertype c;
};

CdrSerdata* new_serdata(const ddsi_sertype* type, ddsi_serdata_kind kind, std::size_t size) {
  void* mem = std::malloc(sizeof(CdrSerdata) + size);
  if (!mem) return nullptr;
  auto* d = static_cast<CdrSerdata*>(mem);
  ddsi_serdata_init(&d->c, type, kind);
  d->c.hash = type->serdata_basehash;  // keyless: one instance
  d->size = static_cast<std::uint32_t>(size);
  return d;
}

// --- serdata ops ---

bool sd_eqkey(const ddsi_serdata*, const ddsi_serdata*) {
  return true;
}

uint32_t sd_get_size(const ddsi_serdata* d) {
  return reinterpret_cast<const CdrSerdata*>(d)->size;
}

void sd_free(ddsi_serdata* d) {
  std::free(d);
}

ddsi_serdata* sd_from_ser(const ddsi_sertype* type, ddsi_serdata_kind kind,
                          const nn_rdata* fragchain, size_t size) {
  CdrSerdata* d = new_serdata(type, kind, size);
  if (!d) return nullptr;
  // Fragments may overlap; copy each byte once, in order.
  std::uint32_t off = 0;
  std::uint8_t* out = d->bytes();
  while (fragchain) {
    if (fragchain->maxp1 > off) {
      const unsigned char* payload =
          NN_RMSG_PAYLOADOFF(fragchain->rmsg, NN_RDATA_PAYLOAD_OFF(fragchain));
      const std::uint32_t end =
          std::min<std::uint32_t>(fragchain->maxp1, static_cast<std::uint32_t>(size));
      if (end > off) std::memcpy(out + off, payload + (off - fragchain->min), end - off);
      off = fragchain->maxp1;
    }
    fragchain = fragchain->nextfrag;
  }
  return &d->c;
}

ddsi_serdata* sd_from_ser_iov(const ddsi_sertype* type, ddsi_serdata_kind kind,
                              ddsrt_msg_iovlen_t niov, const ddsrt_iovec_t* iov, size_t size) {
  CdrSerdata* d = new_serdata(type, kind, size);
  if (!d) return nullptr;
  std::size_t off = 0;
  for (ddsrt_msg_iovlen_t i = 0; i < niov && off < size; ++i) {
    const std::size_t n = std::min<std::size_t>(iov[i].iov_len, size - off);
    std::memcpy(d->bytes() + off, iov[i].iov_base, n);
    off += n;
  }
  return &d->c;
}

ddsi_serdata* sd_from_keyhash(const ddsi_sertype* type, const ddsi_keyhash*) {
  CdrSerdata* d = new_serdata(type, SDK_KEY, sizeof(kEmptyCdr));
  if (!d) return nullptr;
  std::memcpy(d->bytes(), kEmptyCdr, sizeof(kEmptyCdr));
  return &d->c;
}

ddsi_serdata* sd_from_sample(const ddsi_sertype* type, ddsi_serdata_kind kind, const void* sample) {
  if (kind != SDK_DATA) return sd_from_keyhash(type, nullptr);  // keyless: nothing to carry
  const auto* span = static_cast<const CycloneCdrSpan*>(sample);
  if (!span->data || span->size < 4) return nullptr;
  CdrSerdata* d = new_serdata(type, kind, span->size);
  if (!d) return nullptr;
  std::memcpy(d->bytes(), span->data, span->size);
  return &d->c;
}

void sd_to_ser(const ddsi_serdata* d, size_t off, size_t sz, void* buf) {
  std::memcpy(buf, reinterpret_cast<const CdrSerdata*>(d)->bytes() + off, sz);
}

ddsi_serdata* sd_to_ser_ref(const ddsi_serdata* d, size_t off, size_t sz, ddsrt_iovec_t* ref) {
  ref->iov_base = const_cast<std::uint8_t*>(reinterpret_cast<const CdrSerdata*>(d)->bytes() + off);
  ref->iov_len = static_cast<ddsrt_iov_len_t>(sz);
  return ddsi_serdata_ref(d);
}

void sd_to_ser_unref(ddsi_serdata* d, const ddsrt_iovec_t*) {
  ddsi_serdata_unref(d);
}

// Samples of this sertype are views (CycloneCdrSpan) that cannot own the bytes: readers use
// dds_takecdr, never dds_take.
bool sd_to_sample(const ddsi_serdata*, void*, void**, void*) {
  return false;
}

ddsi_serdata* sd_to_untyped(const ddsi_serdata* d) {
  // Keyless: the untyped (key-only) form carries nothing but the header.
  CdrSerdata* u = new_serdata(d->type, SDK_KEY, sizeof(kEmptyCdr));
  if (!u) return nullptr;
  std::memcpy(u->bytes(), kEmptyCdr, sizeof(kEmptyCdr));
  u->c.type = nullptr;
  return &u->c;
}

bool sd_untyped_to_sample(const ddsi_sertype*, const ddsi_serdata*, void*, void**, void*) {
  return true;  // no key fields to fill
}

size_t sd_print(const ddsi_sertype*, const ddsi_serdata* d, char* buf, size_t size) {
  const int n = std::snprintf(buf, size, "cdr[%u]", reinterpret_cast<const CdrSerdata*>(d)->size);
  return n > 0 ? static_cast<size_t>(n) : 0;
}

void sd_get_keyhash(const ddsi_serdata*, ddsi_keyhash* buf, bool) {
  std::memset(buf, 0, sizeof(*buf));
}

const ddsi_serdata_ops kSerdataOps = [] {
  ddsi_serdata_ops ops{};
  ops.eqkey = sd_eqkey;
  ops.get_size = sd_get_size;
  ops.from_ser = sd_from_ser;
  ops.from_ser_iov = sd_from_ser_iov;
  ops.from_keyhash = sd_from_keyhash;
  ops.from_sample = sd_from_sample;
  ops.to_ser = sd_to_ser;
  ops.to_ser_ref = sd_to_ser_ref;
  ops.to_ser_unref = sd_to_ser_unref;
  ops.to_sample = sd_to_sample;
  ops.to_untyped = sd_to_untyped;
  ops.untyped_to_sample = sd_untyped_to_sample;
  ops.free = sd_free;
  ops.print = sd_print;
  ops.get_keyhash = sd_get_keyhash;
  // get_sample_size / from_iox_buffer stay null: no iceoryx zero-copy for this type.
  return ops;
}();

// --- sertype ops ---

void st_free(ddsi_sertype* t) {
  ddsi_sertype_fini(t);
  delete reinterpret_cast<CdrSertype*>(t);
}

void st_zero_samples(const ddsi_sertype*, void* samples, size_t count) {
  std::memset(samples, 0, count * sizeof(CycloneCdrSpan));
}

void st_realloc_samples(void** ptrs, const ddsi_sertype*, void* old, size_t oldcount,
                        size_t count) {
  auto* p = static_cast<CycloneCdrSpan*>(std::realloc(old, count * sizeof(CycloneCdrSpan)));
  if (p && count > oldcount) {
    std::memset(p + oldcount, 0, (count - oldcount) * sizeof(CycloneCdrSpan));
  }
  for (size_t i = 0; i < count; ++i)
    ptrs[i] = p ? p + i : nullptr;
}

void st_free_samples(const ddsi_sertype*, void** ptrs, size_t, dds_free_op_t op) {
  if ((op & DDS_FREE_ALL_BIT) && ptrs[0]) std::free(ptrs[0]);  // contents are views
}

bool st_equal(const ddsi_sertype*, const ddsi_sertype*) {
  return true;
}  // same name and ops

uint32_t st_hash(const ddsi_sertype*) {
  return 0x504f4953u;
}

size_t st_get_serialized_size(const ddsi_sertype*, const void* sample) {
  return static_cast<const CycloneCdrSpan*>(sample)->size;
}

bool st_serialize_into(const ddsi_sertype*, const void* sample, void* dst, size_t dst_size) {
  const auto* s = static_cast<const CycloneCdrSpan*>(sample);
  if (s->size > dst_size) return false;
  std::memcpy(dst, s->data, s->size);
  return true;
}

const ddsi_sertype_ops kSertypeOps = [] {
  ddsi_sertype_ops ops{};
  ops.version = ddsi_sertype_v0;
  ops.arg = nullptr;
  ops.free = st_free;
  ops.zero_samples = st_zero_samples;
  ops.realloc_samples = st_realloc_samples;
  ops.free_samples = st_free_samples;
  ops.equal = st_equal;
  ops.hash = st_hash;
  ops.get_serialized_size = st_get_serialized_size;
  ops.serialize_into = st_serialize_into;
  return ops;
}();

}  // namespace

ddsi_sertype* cyclone_make_cdr_sertype(const std::string& type_name) {
  auto* t = new CdrSertype{};
  ddsi_sertype_init_flags(&t->c, type_name.c_str(), &kSertypeOps, &kSerdataOps,
                          DDSI_SERTYPE_FLAG_TOPICKIND_NO_KEY);
  // Plain CDR (XCDR1) only: what Fast DDS 2.9 writes and expects.
  t->c.allowed_data_representation = DDS_DATA_REPRESENTATION_FLAG_XCDR1;
  return &t->c;
}

void cyclone_free_sertype(ddsi_sertype* type) {
  st_free(type);
}

bool cyclone_serdata_bytes(const ddsi_serdata* serdata, std::vector<std::uint8_t>& out) noexcept {
  const uint32_t n = ddsi_serdata_size(serdata);
  try {
    out.resize(n);
  } catch (...) {
    return false;
  }
  ddsi_serdata_to_ser(serdata, 0, n, out.data());
  return true;
}

void cyclone_serdata_unref(ddsi_serdata* serdata) noexcept {
  ddsi_serdata_unref(serdata);
}

}  // namespace poise::dds::detail
