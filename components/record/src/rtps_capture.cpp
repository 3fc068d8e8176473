// Passive capture of DDS traffic: RTPS decoding of captured UDP datagrams (rtps_capture.hpp).
#include "poise/record/rtps_capture.hpp"

#include <arpa/inet.h>
#include <linux/filter.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <unordered_map>

namespace poise::record {
namespace {

// RTPS submessage ids and the entity id of the SEDP publications writer (DDSI-RTPS 2.3, 9.4.5
// and 9.3.1.4).
constexpr std::uint8_t kInfoTs = 0x09;
constexpr std::uint8_t kInfoSrc = 0x0c;
constexpr std::uint8_t kData = 0x15;
constexpr std::uint8_t kDataFrag = 0x16;
constexpr std::uint32_t kSedpPublicationsWriter = 0x000003c2;
// Parameter ids (9.6.2.2).
constexpr std::uint16_t kPidSentinel = 0x0001;
constexpr std::uint16_t kPidTopicName = 0x0005;
constexpr std::uint16_t kPidTypeName = 0x0007;
constexpr std::uint16_t kPidEndpointGuid = 0x005a;
constexpr std::uint16_t kPidKeyHash = 0x0070;
constexpr std::uint16_t kPidStatusInfo = 0x0071;

constexpr std::uint64_t kWindow = 1024;  // sequence numbers remembered per writer
constexpr std::size_t kMaxPendingPerWriter = 4096;
constexpr std::size_t kMaxPendingBytes = 64u << 20;
constexpr std::size_t kMaxSampleBytes = 16u << 20;

struct Guid {
  std::array<std::uint8_t, 16> b{};
  bool operator==(const Guid& o) const { return b == o.b; }
};
struct GuidHash {
  std::size_t operator()(const Guid& g) const noexcept {
    // FNV-1a over the 16 bytes.
    std::uint64_t h = 1469598103934665603ULL;
    for (auto c : g.b) h = (h ^ c) * 1099511628211ULL;
    return static_cast<std::size_t>(h);
  }
};

std::uint16_t rd16(const std::uint8_t* p, bool little) {
  return little ? static_cast<std::uint16_t>(p[0] | (p[1] << 8))
                : static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}
std::uint32_t rd32(const std::uint8_t* p, bool little) {
  return little ? (std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
                   (std::uint32_t{p[3]} << 24))
                : ((std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) |
                   (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]});
}
std::uint32_t entity_id(const std::uint8_t* p) {  // entity ids are byte arrays: big-endian value
  return rd32(p, false);
}

/// A parameter list (9.4.2.11): calls f(pid, value, length) until the sentinel. False if it runs
/// past the end.
template <class F>
bool parameters(const std::uint8_t* p, std::size_t n, bool little, F&& f) {
  std::size_t i = 0;
  while (i + 4 <= n) {
    const std::uint16_t pid = rd16(p + i, little);
    const std::uint16_t len = rd16(p + i + 2, little);
    i += 4;
    if (pid == kPidSentinel) return true;
    if (i + len > n) return false;
    f(static_cast<std::uint16_t>(pid & 0x3fff), p + i, std::size_t{len});
    i += len;
  }
  return false;
}

std::string cdr_string(const std::uint8_t* p, std::size_t n, bool little) {
  if (n < 4) return {};
  std::uint32_t len = rd32(p, little);
  if (len == 0 || len > n - 4) return {};
  if (p[4 + len - 1] == 0) --len;  // the terminating NUL
  return std::string(reinterpret_cast<const char*>(p + 4), len);
}

// The inline QoS parameters of a DATA or DATA_FRAG submessage that matter here.
struct InlineQos {
  const std::uint8_t* key_hash = nullptr;
  bool disposed = false;
};

// Reads the inline QoS parameter list at q (qn bytes to the end of the submessage); `consumed`:
// its length up to and including the sentinel. False when it has no sentinel (malformed).
bool read_inline_qos(const std::uint8_t* q, std::size_t qn, bool little, InlineQos& qos,
                     std::size_t& consumed) {
  std::size_t k = 0;
  while (k + 4 <= qn) {
    const std::uint16_t pid = rd16(q + k, little);
    const std::uint16_t plen = rd16(q + k + 2, little);
    k += 4;
    if (pid == kPidSentinel) {
      consumed = k;
      return true;
    }
    if (k + plen > qn) break;
    if (pid == kPidKeyHash && plen >= 16) qos.key_hash = q + k;
    if (pid == kPidStatusInfo && plen >= 4) qos.disposed = (q[k + 3] & 0x03) != 0;
    k += plen;
  }
  return false;
}

}  // namespace

struct RtpsDecoder::Impl {
  struct Pending {
    std::vector<std::uint8_t> bytes;
    std::uint64_t sn;
    std::int64_t source_ns, receive_ns;
  };
  struct Fragments {
    std::vector<std::uint8_t> bytes;  // sample_size of the first fragment seen
    std::size_t frag_size = 0;        // of the first fragment seen
    std::vector<bool> have;
    std::size_t missing = 0;
    std::int64_t source_ns = 0;
  };
  struct Writer {
    Guid guid;
    std::uint64_t key = 0;
    bool announced = false;
    bool gone = false;
    std::string topic, type_name;
    // Sequence numbers seen: a ring of kWindow bits ending at max_sn.
    bool any = false;
    std::uint64_t first_sn = 0, max_sn = 0, lost = 0;
    std::array<std::uint64_t, kWindow / 64> seen{};
    std::vector<Pending> pending;  // samples before the announcement
    std::map<std::uint64_t, Fragments> fragments;

    bool bit(std::uint64_t sn) const { return (seen[(sn % kWindow) / 64] >> (sn % 64)) & 1u; }
    void set(std::uint64_t sn, bool v) {
      auto& w = seen[(sn % kWindow) / 64];
      const std::uint64_t m = std::uint64_t{1} << (sn % 64);
      w = v ? (w | m) : (w & ~m);
    }
    /// True the first time `sn` is seen.
    bool first_time(std::uint64_t sn) {
      if (!any) {
        any = true;
        first_sn = max_sn = sn;
        set(sn, true);
        return true;
      }
      if (sn > max_sn) {
        const std::uint64_t d = sn - max_sn;
        if (d >= kWindow) {
          // Nothing of the old window stays in the new one.
          lost = lost_now();
          const std::uint64_t new_lo = sn + 1 - kWindow;
          if (new_lo > max_sn + 1) lost += new_lo - (max_sn + 1);
          seen.fill(0);
        } else {
          for (std::uint64_t s = max_sn + 1; s <= sn; ++s) {
            if (s >= kWindow) {
              const std::uint64_t old = s - kWindow;
              if (old >= first_sn && !bit(old)) ++lost;
            }
            set(s, false);
          }
        }
        max_sn = sn;
        set(sn, true);
        return true;
      }
      if (max_sn - sn >= kWindow || sn < first_sn) return false;  // too old: a late repair
      if (bit(sn)) return false;
      set(sn, true);
      return true;
    }
    /// Lost so far plus the holes still inside the window.
    std::uint64_t lost_now() const {
      if (!any) return 0;
      std::uint64_t n = lost;
      const std::uint64_t lo = max_sn + 1 > kWindow ? max_sn + 1 - kWindow : 0;
      for (std::uint64_t s = std::max(lo, first_sn); s <= max_sn; ++s)
        if (!bit(s)) ++n;
      return n;
    }
  };

  SampleFn on_sample;
  mutable std::mutex mutex;
  std::unordered_map<Guid, std::unique_ptr<Writer>, GuidHash> writers;
  std::size_t pending_bytes = 0;
  std::size_t fragment_bytes = 0;  // samples being reassembled, all writers
  CaptureCounters c;

  Writer& writer(const Guid& g) {
    auto& w = writers[g];
    if (!w) {
      w = std::make_unique<Writer>();
      w->guid = g;
      w->key = GuidHash{}(g);
    }
    return *w;
  }

  void deliver(Writer& w, std::uint64_t sn, const std::uint8_t* data, std::size_t n,
               std::int64_t source_ns, std::int64_t receive_ns) {
    if (!w.first_time(sn)) {
      ++c.duplicates;
      return;
    }
    ++c.samples;
    CapturedSample s;
    s.topic = &w.topic;
    s.type_name = &w.type_name;
    s.data = data;
    s.size = n;
    s.writer_key = w.key;
    s.source_timestamp_ns = source_ns;
    s.receive_timestamp_ns = receive_ns;
    on_sample(s);
  }

  void sample(Writer& w, std::uint64_t sn, const std::uint8_t* data, std::size_t n,
              std::int64_t source_ns, std::int64_t receive_ns) {
    if (w.announced) {
      deliver(w, sn, data, n, source_ns, receive_ns);
      return;
    }
    // Not announced yet (the capture began after this writer's SEDP): keep it, bounded.
    for (const auto& p : w.pending)
      if (p.sn == sn) {
        ++c.duplicates;
        return;
      }
    if (w.pending.size() >= kMaxPendingPerWriter || pending_bytes + n > kMaxPendingBytes) {
      ++c.unknown_writer;
      return;
    }
    w.pending.push_back(Pending{std::vector<std::uint8_t>(data, data + n), sn, source_ns, receive_ns});
    pending_bytes += n;
  }

  void announce(const std::uint8_t* payload, std::size_t n, const std::uint8_t* key_hash,
                bool disposed) {
    Guid g;
    bool have_guid = false;
    std::string topic, type;
    if (payload && n >= 4) {
      const bool little = payload[1] == 0x03 || payload[1] == 0x01;  // PL_CDR_LE / CDR_LE
      parameters(payload + 4, n - 4, little,
                 [&](std::uint16_t pid, const std::uint8_t* v, std::size_t len) {
                   if (pid == kPidTopicName) topic = cdr_string(v, len, little);
                   else if (pid == kPidTypeName) type = cdr_string(v, len, little);
                   else if (pid == kPidEndpointGuid && len >= 16) {
                     std::memcpy(g.b.data(), v, 16);
                     have_guid = true;
                   }
                 });
    }
    if (!have_guid && key_hash) {
      std::memcpy(g.b.data(), key_hash, 16);
      have_guid = true;
    }
    if (!have_guid) {
      ++c.malformed;
      return;
    }
    Writer& w = writer(g);
    if (disposed) {
      w.gone = true;
      return;
    }
    if (topic.empty()) return;
    if (!w.announced) ++c.writers;
    w.announced = true;
    w.gone = false;
    w.topic = topic;
    w.type_name = type;
    for (auto& p : w.pending) {
      pending_bytes -= p.bytes.size();
      deliver(w, p.sn, p.bytes.data(), p.bytes.size(), p.source_ns, p.receive_ns);
    }
    w.pending.clear();
    w.pending.shrink_to_fit();
  }

  void message(const std::uint8_t* m, std::size_t size, std::int64_t receive_ns) {
    if (size < 20 || std::memcmp(m, "RTPS", 4) != 0) return;
    ++c.rtps_messages;
    std::array<std::uint8_t, 12> prefix;
    std::memcpy(prefix.data(), m + 8, 12);
    std::int64_t source_ns = 0;
    std::size_t i = 20;
    while (i + 4 <= size) {
      const std::uint8_t id = m[i];
      const std::uint8_t flags = m[i + 1];
      const bool little = flags & 0x01;
      std::size_t len = rd16(m + i + 2, little);
      const std::uint8_t* b = m + i + 4;
      const std::size_t avail = size - (i + 4);
      if (len == 0 && id != kInfoTs && id != 0x01 /*PAD*/) len = avail;  // to the end
      if (len > avail) {
        ++c.malformed;
        return;
      }
      if (id == kInfoTs) {
        if ((flags & 0x02) == 0 && len >= 8) {
          const auto sec = static_cast<std::int32_t>(rd32(b, little));
          const std::uint32_t frac = rd32(b + 4, little);
          source_ns = static_cast<std::int64_t>(sec) * 1000000000LL +
                      static_cast<std::int64_t>((static_cast<std::uint64_t>(frac) * 1000000000ULL) >> 32);
        } else {
          source_ns = 0;
        }
      } else if (id == kInfoSrc && len >= 20) {
        std::memcpy(prefix.data(), b + 8, 12);
      } else if ((id == kData || id == kDataFrag) && len >= 20) {
        submessage(id, flags, little, b, len, prefix, source_ns, receive_ns);
      }
      i += 4 + len;
    }
  }

  // The fixed part of a DATA or DATA_FRAG submessage (9.4.5.3, 9.4.5.4) and whether its writer
  // is the SEDP publications writer.
  struct DataHeader {
    std::uint8_t id, flags;
    bool little, sedp;
    std::uint64_t sn;
    std::size_t frag_start = 0, frags_here = 0, frag_size = 0, sample_size = 0;
  };

  void submessage(std::uint8_t id, std::uint8_t flags, bool little, const std::uint8_t* b,
                  std::size_t len, const std::array<std::uint8_t, 12>& prefix,
                  std::int64_t source_ns, std::int64_t receive_ns) {
    const std::uint16_t to_qos = rd16(b + 2, little);
    const std::uint32_t writer_id = entity_id(b + 8);
    const std::uint64_t sn = (static_cast<std::uint64_t>(rd32(b + 12, little)) << 32) |
                             rd32(b + 16, little);
    DataHeader h{id, flags, little, writer_id == kSedpPublicationsWriter, sn};
    const std::uint8_t kind = writer_id & 0xff;
    if ((kind & 0xc0) == 0xc0 && !h.sedp) return;  // other builtin endpoints
    const std::size_t qos_at = 4 + std::size_t{to_qos};
    if (id == kDataFrag) {
      if (len < 32) return;
      h.frag_start = rd32(b + 20, little);
      h.frags_here = rd16(b + 24, little);
      h.frag_size = rd16(b + 26, little);
      h.sample_size = rd32(b + 28, little);
    }
    if (qos_at > len) {
      ++c.malformed;
      return;
    }
    InlineQos qos;
    std::size_t data_at = qos_at;
    if (flags & 0x02) {  // inline QoS
      std::size_t consumed = 0;
      if (!read_inline_qos(b + qos_at, len - qos_at, little, qos, consumed)) {
        ++c.malformed;
        return;
      }
      data_at = qos_at + consumed;
    }
    Guid g;
    std::memcpy(g.b.data(), prefix.data(), 12);
    std::memcpy(g.b.data() + 12, b + 8, 4);
    const std::uint8_t* payload = b + data_at;
    const std::size_t payload_n = len - data_at;
    if (id == kData)
      data(h, g, qos, payload, payload_n, source_ns, receive_ns);
    else
      data_frag(h, g, qos, payload, payload_n, source_ns, receive_ns);
  }

  // DATA: a sample, or (from the SEDP writer) a writer's announcement.
  void data(const DataHeader& h, const Guid& g, const InlineQos& qos, const std::uint8_t* payload,
            std::size_t payload_n, std::int64_t source_ns, std::int64_t receive_ns) {
    const bool has_data = h.flags & 0x04;
    if (h.sedp) {
      // A serialised key alone (K flag) is the writer going away (dispose / unregister).
      const bool has_key = h.flags & 0x08;
      announce(has_data || has_key ? payload : nullptr, has_data || has_key ? payload_n : 0,
               qos.key_hash, qos.disposed || (has_key && !has_data));
      return;
    }
    if (!has_data) return;  // key only: dispose / unregister
    sample(writer(g), h.sn, payload, payload_n, source_ns, receive_ns);
  }

  // DATA_FRAG: collect the fragments of (writer, sn) until the sample is whole.
  void data_frag(const DataHeader& h, const Guid& g, const InlineQos& qos,
                 const std::uint8_t* payload, std::size_t payload_n, std::int64_t source_ns,
                 std::int64_t receive_ns) {
    if (h.frag_size == 0 || h.sample_size == 0 || h.sample_size > kMaxSampleBytes ||
        h.frag_start == 0) {
      ++c.malformed;
      return;
    }
    Writer& w = writer(g);
    if (w.any && (h.sn <= w.max_sn && (w.max_sn - h.sn >= kWindow || w.bit(h.sn)))) {
      ++c.duplicates;  // already whole (or too old)
      return;
    }
    const std::size_t total = (h.sample_size + h.frag_size - 1) / h.frag_size;
    Fragments* f = fragments_of(w, h, total, source_ns);
    if (f == nullptr) return;
    add_fragments(*f, h, total, payload, payload_n);
    if (f->missing == 0) complete_sample(w, h, qos, *f, receive_ns);
    // Forget samples that can no longer be completed (their sequence numbers have left the
    // window unseen: counted as lost there).
    while (!w.fragments.empty() && w.any && w.fragments.begin()->first + kWindow < w.max_sn) {
      fragment_bytes -= w.fragments.begin()->second.bytes.size();
      w.fragments.erase(w.fragments.begin());
    }
  }

  // The sample (w, h.sn) being reassembled, begun if new; null when over the memory bound.
  Fragments* fragments_of(Writer& w, const DataHeader& h, std::size_t total,
                          std::int64_t source_ns) {
    auto found = w.fragments.find(h.sn);
    if (found == w.fragments.end()) {
      if (fragment_bytes + h.sample_size > kMaxPendingBytes) {
        ++c.malformed;  // more half-assembled samples than any sane stream has
        return nullptr;
      }
      fragment_bytes += h.sample_size;
      found = w.fragments.emplace(h.sn, Fragments{}).first;
    }
    Fragments& f = found->second;
    if (f.have.empty()) {
      f.bytes.assign(h.sample_size, 0);
      f.frag_size = h.frag_size;
      f.have.assign(total, false);
      f.missing = total;
      f.source_ns = source_ns;
    } else if (h.sample_size != f.bytes.size() || h.frag_size != f.frag_size) {
      // A fragment of the same sample that says otherwise of its size or its fragments' (a
      // malformed or hostile datagram): its offsets would point outside what was allocated.
      ++c.malformed;
      return nullptr;
    }
    return &f;
  }

  // Copies the fragments of this submessage not yet seen into `f`.
  static void add_fragments(Fragments& f, const DataHeader& h, std::size_t total,
                            const std::uint8_t* payload, std::size_t payload_n) {
    for (std::size_t j = 0; j < h.frags_here; ++j) {
      const std::size_t num = h.frag_start + j;  // 1-based
      if (num == 0 || num > total) break;
      const std::size_t off = (num - 1) * h.frag_size;
      const std::size_t n = std::min(h.frag_size, h.sample_size - off);
      if (j * h.frag_size + n > payload_n) break;
      if (f.have[num - 1]) continue;
      std::memcpy(f.bytes.data() + off, payload + j * h.frag_size, n);
      f.have[num - 1] = true;
      --f.missing;
    }
  }

  // A reassembled sample: out of the writer's fragments, delivered (or announced, from SEDP).
  void complete_sample(Writer& w, const DataHeader& h, const InlineQos& qos, Fragments& f,
                       std::int64_t receive_ns) {
    Fragments whole = std::move(f);
    w.fragments.erase(h.sn);
    fragment_bytes -= whole.bytes.size();
    if (h.sedp)
      announce(whole.bytes.data(), whole.bytes.size(), qos.key_hash, qos.disposed);
    else
      sample(w, h.sn, whole.bytes.data(), whole.bytes.size(), whole.source_ns, receive_ns);
  }
};

RtpsDecoder::RtpsDecoder(SampleFn on_sample) : impl_(std::make_unique<Impl>()) {
  impl_->on_sample = std::move(on_sample);
}
RtpsDecoder::~RtpsDecoder() = default;

void RtpsDecoder::datagram(const std::uint8_t* data, std::size_t size, std::int64_t receive_ns) {
  std::lock_guard lock(impl_->mutex);
  ++impl_->c.datagrams;
  impl_->message(data, size, receive_ns);
}

CaptureCounters RtpsDecoder::counters() const {
  std::lock_guard lock(impl_->mutex);
  CaptureCounters c = impl_->c;
  // Samples still held for a writer never announced: at the end of a recording they are lost.
  for (const auto& [g, w] : impl_->writers)
    c.unknown_writer += w->pending.size();
  return c;
}

std::map<std::string, std::uint64_t> RtpsDecoder::lost_per_topic() const {
  std::lock_guard lock(impl_->mutex);
  std::map<std::string, std::uint64_t> out;
  for (const auto& [g, w] : impl_->writers)
    if (w->announced) out[w->topic] += w->lost_now();
  return out;
}

std::map<std::string, int> RtpsDecoder::writers_per_topic() const {
  std::lock_guard lock(impl_->mutex);
  std::map<std::string, int> out;
  for (const auto& [g, w] : impl_->writers)
    if (w->announced && !w->gone) ++out[w->topic];
  return out;
}

// ------------------------------------------------------------------------------------------------

RtpsCapture::RtpsCapture(CaptureOptions options, RtpsDecoder::SampleFn on_sample)
    : options_(std::move(options)), decoder_(std::move(on_sample)) {
  if (options_.domain < 0 || options_.domain > 232)
    throw std::invalid_argument("domain " + std::to_string(options_.domain) + " is not 0..232");
  const unsigned ifindex = ::if_nametoindex(options_.interface.c_str());
  if (ifindex == 0)
    throw std::runtime_error("no network interface '" + options_.interface +
                             "' (see `ip link`)");
  fd_ = ::socket(AF_PACKET, SOCK_DGRAM | SOCK_CLOEXEC, htons(ETH_P_IP));
  if (fd_ < 0) {
    const int e = errno;
    throw std::runtime_error(
        std::string("cannot open a packet socket: ") + std::strerror(e) +
        (e == EPERM || e == EACCES
             ? " (passive capture needs CAP_NET_RAW: run as root, or `sudo setcap "
               "cap_net_raw+ep build/bin/poise`)"
             : ""));
  }
  auto fail = [this](const std::string& what) {
    const int e = errno;
    if (ring_ != nullptr) ::munmap(ring_, ring_bytes_);
    ring_ = nullptr;
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error(what + ": " + std::strerror(e));
  };
  {
    ifreq ifr{};
    std::strncpy(ifr.ifr_name, options_.interface.c_str(), IFNAMSIZ - 1);
    if (::ioctl(fd_, SIOCGIFFLAGS, &ifr) == 0) loopback_ = (ifr.ifr_flags & IFF_LOOPBACK) != 0;
  }
  // In the kernel, so that the capture costs the senders as little as possible: on loopback
  // only the received copy of each datagram (every datagram passes the tap twice there); IPv4
  // UDP, not a non-first IP fragment, destination port in the domain's range of the RTPS port
  // mapping (PB 7400, DG 250: 7400 + 250 d ... + 249).
  const std::uint32_t lo = 7400 + 250 * static_cast<std::uint32_t>(options_.domain);
  const std::uint32_t hi = lo + 250;
  std::vector<sock_filter> code;
  if (loopback_) {
    code.push_back(BPF_STMT(BPF_LD | BPF_W | BPF_ABS,
                            static_cast<std::uint32_t>(SKF_AD_OFF + SKF_AD_PKTTYPE)));
    code.push_back(BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, PACKET_OUTGOING, 9, 0));
  }
  const sock_filter rest[] = {
      BPF_STMT(BPF_LD | BPF_B | BPF_ABS, 9),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, 17, 0, 7),
      BPF_STMT(BPF_LD | BPF_H | BPF_ABS, 6),
      BPF_JUMP(BPF_JMP | BPF_JSET | BPF_K, 0x1fff, 5, 0),
      BPF_STMT(BPF_LDX | BPF_B | BPF_MSH, 0),
      BPF_STMT(BPF_LD | BPF_H | BPF_IND, 2),
      BPF_JUMP(BPF_JMP | BPF_JGE | BPF_K, lo, 0, 2),
      BPF_JUMP(BPF_JMP | BPF_JGE | BPF_K, hi, 1, 0),
      BPF_STMT(BPF_RET | BPF_K, 0x40000),
      BPF_STMT(BPF_RET | BPF_K, 0),
  };
  code.insert(code.end(), std::begin(rest), std::end(rest));
  sock_fprog prog{static_cast<unsigned short>(code.size()), code.data()};
  if (::setsockopt(fd_, SOL_SOCKET, SO_ATTACH_FILTER, &prog, sizeof(prog)) != 0)
    fail("cannot attach the capture filter");
  // A memory-mapped ring (TPACKET_V3): the kernel fills blocks of datagrams and wakes the
  // reader once per block (full, or 10 ms old), not once per datagram; no copy, no syscall per
  // datagram; the kernel's own receive timestamps.
  const int version = TPACKET_V3;
  if (::setsockopt(fd_, SOL_PACKET, PACKET_VERSION, &version, sizeof(version)) != 0)
    fail("cannot select TPACKET_V3");
  tpacket_req3 req{};
  req.tp_block_size = kBlockBytes;
  req.tp_block_nr = static_cast<unsigned>(
      std::max<std::size_t>(4, static_cast<std::size_t>(options_.receive_buffer_bytes) / kBlockBytes));
  req.tp_frame_size = 2048;
  req.tp_frame_nr = req.tp_block_size / req.tp_frame_size * req.tp_block_nr;
  req.tp_retire_blk_tov = 10;  // ms
  if (::setsockopt(fd_, SOL_PACKET, PACKET_RX_RING, &req, sizeof(req)) != 0)
    fail("cannot create the capture ring");
  blocks_ = req.tp_block_nr;
  ring_bytes_ = static_cast<std::size_t>(req.tp_block_size) * req.tp_block_nr;
  void* ring = ::mmap(nullptr, ring_bytes_, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, 0);
  if (ring == MAP_FAILED) fail("cannot map the capture ring");
  ring_ = static_cast<std::uint8_t*>(ring);
  sockaddr_ll addr{};
  addr.sll_family = AF_PACKET;
  addr.sll_protocol = htons(ETH_P_IP);
  addr.sll_ifindex = static_cast<int>(ifindex);
  if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0)
    fail("cannot bind the packet socket to " + options_.interface);
  tpacket_stats_v3 st{};
  socklen_t sl = sizeof(st);
  ::getsockopt(fd_, SOL_PACKET, PACKET_STATISTICS, &st, &sl);  // resets the counters
  thread_ = std::thread([this] { loop(); });
}

RtpsCapture::~RtpsCapture() {
  stop();
  if (ring_ != nullptr) ::munmap(ring_, ring_bytes_);
  if (fd_ >= 0) ::close(fd_);
}

void RtpsCapture::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

void RtpsCapture::loop() {
  std::size_t current = 0;
  // Reads every block the kernel has handed over, in ring order. False if none was ready.
  auto drain = [&]() {
    bool any = false;
    for (;;) {
      auto* block = reinterpret_cast<tpacket_block_desc*>(ring_ + current * kBlockBytes);
      if ((__atomic_load_n(&block->hdr.bh1.block_status, __ATOMIC_ACQUIRE) & TP_STATUS_USER) == 0)
        return any;
      any = true;
      const std::uint32_t n = block->hdr.bh1.num_pkts;
      auto* p = reinterpret_cast<std::uint8_t*>(block) + block->hdr.bh1.offset_to_first_pkt;
      for (std::uint32_t i = 0; i < n; ++i) {
        const auto* h = reinterpret_cast<const tpacket3_hdr*>(p);
        const auto* ll = reinterpret_cast<const sockaddr_ll*>(p + TPACKET_ALIGN(sizeof(tpacket3_hdr)));
        const std::uint8_t* ip = p + h->tp_net;
        const std::size_t len = h->tp_snaplen - (h->tp_net - h->tp_mac);
        const std::int64_t t = static_cast<std::int64_t>(h->tp_sec) * 1000000000LL + h->tp_nsec;
        if (!(loopback_ && ll->sll_pkttype == PACKET_OUTGOING) && len >= 28 && (ip[0] >> 4) == 4 &&
            ip[9] == 17 && (ip[6] & 0x20) == 0) {
          const std::size_t ihl = std::size_t{ip[0] & 0x0fu} * 4;
          const std::size_t total = (std::size_t{ip[2]} << 8) | ip[3];
          if (total <= len && ihl + 8 <= total) decoder_.datagram(ip + ihl + 8, total - ihl - 8, t);
        }
        p += h->tp_next_offset;
      }
      __atomic_store_n(&block->hdr.bh1.block_status, TP_STATUS_KERNEL, __ATOMIC_RELEASE);
      current = (current + 1) % blocks_;
    }
  };
  while (!stop_.load()) {
    if (drain()) continue;
    pollfd pfd{fd_, POLLIN | POLLERR, 0};
    ::poll(&pfd, 1, 50);
  }
  // What is still in the open block is handed over by the block timeout (10 ms).
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  drain();
  tpacket_stats_v3 st{};
  socklen_t sl = sizeof(st);
  if (::getsockopt(fd_, SOL_PACKET, PACKET_STATISTICS, &st, &sl) == 0)
    kernel_drops_.fetch_add(st.tp_drops);
}

CaptureCounters RtpsCapture::counters() const {
  CaptureCounters c = decoder_.counters();
  if (fd_ >= 0 && !stop_.load()) {
    // Reading the statistics resets them: accumulate.
    tpacket_stats_v3 st{};
    socklen_t sl = sizeof(st);
    if (::getsockopt(fd_, SOL_PACKET, PACKET_STATISTICS, &st, &sl) == 0)
      kernel_drops_.fetch_add(st.tp_drops);
  }
  c.kernel_drops = kernel_drops_.load();
  return c;
}

std::map<std::string, std::uint64_t> RtpsCapture::lost_per_topic() const {
  return decoder_.lost_per_topic();
}
std::map<std::string, int> RtpsCapture::writers_per_topic() const {
  return decoder_.writers_per_topic();
}

}  // namespace poise::record
