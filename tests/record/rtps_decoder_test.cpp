// The RTPS decoding of `poise record --passive` (components/record/src/rtps_capture.cpp) on
// datagrams built here byte by byte from the DDSI-RTPS 2.3 layouts (9.4): announcements, samples
// out of order and repeated, fragments out of order, samples before their writer's announcement,
// lost sequence numbers, and garbage. The end-to-end check against real vendors is
// record_test.cpp (PassiveCaptureHoldsWhatASubscribingRecorderHolds).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <poise/record/rtps_capture.hpp>

namespace {

using Bytes = std::vector<std::uint8_t>;

void put16(Bytes& b, std::uint16_t v) {
  b.push_back(static_cast<std::uint8_t>(v));
  b.push_back(static_cast<std::uint8_t>(v >> 8));
}
void put32(Bytes& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_be32(Bytes& b, std::uint32_t v) {
  for (int i = 3; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

struct Participant {
  std::uint8_t prefix[12];
  explicit Participant(std::uint8_t id) {
    for (int i = 0; i < 12; ++i) prefix[i] = static_cast<std::uint8_t>(0x10 * id + i);
  }
  Bytes header() const {
    Bytes b{'R', 'T', 'P', 'S', 2, 3, 0x01, 0x10};
    b.insert(b.end(), prefix, prefix + 12);
    return b;
  }
};

/// Appends a submessage (little-endian) with its body.
void submessage(Bytes& m, std::uint8_t id, std::uint8_t flags, const Bytes& body) {
  m.push_back(id);
  m.push_back(static_cast<std::uint8_t>(flags | 0x01));
  put16(m, static_cast<std::uint16_t>(body.size()));
  m.insert(m.end(), body.begin(), body.end());
}

void info_ts(Bytes& m, std::int32_t sec, std::uint32_t frac) {
  Bytes b;
  put32(b, static_cast<std::uint32_t>(sec));
  put32(b, frac);
  submessage(m, 0x09, 0, b);
}

Bytes data_body(std::uint32_t writer_entity, std::uint64_t sn, const Bytes& payload) {
  Bytes b;
  put16(b, 0);   // extra flags
  put16(b, 16);  // octets to inline QoS
  put_be32(b, 0);
  put_be32(b, writer_entity);
  put32(b, static_cast<std::uint32_t>(sn >> 32));
  put32(b, static_cast<std::uint32_t>(sn));
  b.insert(b.end(), payload.begin(), payload.end());
  return b;
}

void param(Bytes& p, std::uint16_t pid, const Bytes& v) {
  Bytes padded = v;
  while (padded.size() % 4) padded.push_back(0);
  put16(p, pid);
  put16(p, static_cast<std::uint16_t>(padded.size()));
  p.insert(p.end(), padded.begin(), padded.end());
}
Bytes cdr_string(const std::string& s) {
  Bytes b;
  put32(b, static_cast<std::uint32_t>(s.size() + 1));
  b.insert(b.end(), s.begin(), s.end());
  b.push_back(0);
  return b;
}

/// An SEDP publication DATA announcing writer (prefix, entity) on topic/type.
void announce(Bytes& m, const Participant& p, std::uint32_t entity, const std::string& topic,
              const std::string& type, std::uint64_t sn) {
  Bytes pl{0x00, 0x03, 0x00, 0x00};  // PL_CDR_LE
  Bytes guid(p.prefix, p.prefix + 12);
  put_be32(guid, entity);
  param(pl, 0x005a, guid);
  param(pl, 0x0005, cdr_string(topic));
  param(pl, 0x0007, cdr_string(type));
  put16(pl, 0x0001);
  put16(pl, 0);
  submessage(m, 0x15, 0x04, data_body(0x000003c2, sn, pl));
}

Bytes sample_payload(std::uint64_t sn, std::size_t size) {
  Bytes b{0x00, 0x01, 0x00, 0x00};  // CDR_LE
  for (std::size_t i = 4; i < size; ++i) b.push_back(static_cast<std::uint8_t>(sn * 31 + i));
  return b;
}

void data(Bytes& m, std::uint32_t entity, std::uint64_t sn, const Bytes& payload) {
  submessage(m, 0x15, 0x04, data_body(entity, sn, payload));
}

void data_frag(Bytes& m, std::uint32_t entity, std::uint64_t sn, std::uint32_t first,
               std::uint16_t count, std::uint16_t frag_size, const Bytes& whole) {
  Bytes b;
  put16(b, 0);
  put16(b, 28);
  put_be32(b, 0);
  put_be32(b, entity);
  put32(b, static_cast<std::uint32_t>(sn >> 32));
  put32(b, static_cast<std::uint32_t>(sn));
  put32(b, first);
  put16(b, count);
  put16(b, frag_size);
  put32(b, static_cast<std::uint32_t>(whole.size()));
  for (std::uint32_t k = first; k < first + count; ++k) {
    const std::size_t off = (k - 1) * std::size_t{frag_size};
    const std::size_t n = std::min<std::size_t>(frag_size, whole.size() - off);
    b.insert(b.end(), whole.begin() + static_cast<long>(off),
             whole.begin() + static_cast<long>(off + n));
  }
  submessage(m, 0x16, 0, b);
}

struct Got {
  std::string topic, type;
  Bytes bytes;
  std::int64_t source_ns;
  std::uint64_t writer;
};

struct Harness {
  std::vector<Got> got;
  poise::record::RtpsDecoder decoder{[this](const poise::record::CapturedSample& s) {
    got.push_back(Got{*s.topic, *s.type_name, Bytes(s.data, s.data + s.size),
                      s.source_timestamp_ns, s.writer_key});
  }};
  void feed(const Bytes& m) { decoder.datagram(m.data(), m.size(), 1); }
};

constexpr std::uint32_t kWriter = 0x00000103;  // user writer, no key

TEST(RtpsDecoder, SamplesAreDeliveredOnceWithTheirTimestampAndLossesCounted) {
  Harness h;
  const Participant p(1);
  Bytes m = p.header();
  announce(m, p, kWriter, "poise/sensors", "poise::msg::Sensors", 1);
  h.feed(m);
  // SNs 1..10 without 4 and 7; 5 twice (a second reader's copy); in two datagrams.
  std::vector<std::uint64_t> order{1, 2, 3, 5, 5, 6, 8, 9, 10};
  for (std::size_t half = 0; half < 2; ++half) {
    Bytes d = p.header();
    for (std::size_t i = half * 5; i < std::min<std::size_t>(order.size(), half * 5 + 5); ++i) {
      info_ts(d, 100, 0x80000000u);  // 100.5 s
      data(d, kWriter, order[i], sample_payload(order[i], 40));
    }
    h.feed(d);
  }
  ASSERT_EQ(h.got.size(), 8u);
  EXPECT_EQ(h.got[0].topic, "poise/sensors");
  EXPECT_EQ(h.got[0].type, "poise::msg::Sensors");
  EXPECT_EQ(h.got[3].bytes, sample_payload(5, 40));
  EXPECT_EQ(h.got[3].source_ns, 100500000000LL);
  const auto c = h.decoder.counters();
  EXPECT_EQ(c.duplicates, 1u);
  EXPECT_EQ(c.samples, 8u);
  EXPECT_EQ(c.malformed, 0u);
  EXPECT_EQ(c.writers, 1u);
  EXPECT_EQ(h.decoder.lost_per_topic().at("poise/sensors"), 2u);
  EXPECT_EQ(h.decoder.writers_per_topic().at("poise/sensors"), 1);
  // A late repair of 4 fills its hole.
  Bytes r = p.header();
  data(r, kWriter, 4, sample_payload(4, 40));
  h.feed(r);
  EXPECT_EQ(h.got.size(), 9u);
  EXPECT_EQ(h.decoder.lost_per_topic().at("poise/sensors"), 1u);
  // A jump far past the window: everything between is lost.
  Bytes j = p.header();
  data(j, kWriter, 5000, sample_payload(5000, 40));
  h.feed(j);
  EXPECT_EQ(h.decoder.lost_per_topic().at("poise/sensors"), 1u + (4999u - 10u));
}

TEST(RtpsDecoder, SamplesBeforeTheAnnouncementAreKeptUntilIt) {
  Harness h;
  const Participant p(2);
  Bytes d = p.header();
  data(d, kWriter, 7, sample_payload(7, 12));
  data(d, kWriter, 8, sample_payload(8, 12));
  h.feed(d);
  EXPECT_TRUE(h.got.empty());
  EXPECT_EQ(h.decoder.counters().unknown_writer, 2u) << "held samples are counted, not silent";
  Bytes a = p.header();
  announce(a, p, kWriter, "poise/state", "poise::msg::State", 3);
  h.feed(a);
  ASSERT_EQ(h.got.size(), 2u);
  EXPECT_EQ(h.decoder.counters().unknown_writer, 0u);
  EXPECT_EQ(h.got[0].bytes, sample_payload(7, 12));
  EXPECT_EQ(h.got[1].bytes, sample_payload(8, 12));
  // Another participant's writer with the same entity id is another writer.
  const Participant q(3);
  Bytes b = q.header();
  announce(b, q, kWriter, "poise/state", "poise::msg::State", 1);
  data(b, kWriter, 7, sample_payload(70, 12));
  h.feed(b);
  ASSERT_EQ(h.got.size(), 3u);
  EXPECT_NE(h.got[2].writer, h.got[0].writer);
  EXPECT_EQ(h.decoder.writers_per_topic().at("poise/state"), 2);
}

TEST(RtpsDecoder, FragmentsAreReassembledInAnyOrder) {
  Harness h;
  const Participant p(4);
  Bytes a = p.header();
  announce(a, p, kWriter, "poise/state", "poise::msg::State", 1);
  h.feed(a);
  const Bytes whole = sample_payload(1, 3000);  // fragments of 1344, 1344, 312
  for (std::uint32_t k : {3u, 1u, 1u, 2u}) {
    Bytes d = p.header();
    data_frag(d, kWriter, 1, k, 1, 1344, whole);
    h.feed(d);
  }
  ASSERT_EQ(h.got.size(), 1u);
  EXPECT_EQ(h.got[0].bytes, whole);
  // Two fragments in one submessage, then the last: sample 2.
  const Bytes second = sample_payload(2, 3000);
  Bytes d = p.header();
  data_frag(d, kWriter, 2, 1, 2, 1344, second);
  data_frag(d, kWriter, 2, 3, 1, 1344, second);
  h.feed(d);
  ASSERT_EQ(h.got.size(), 2u);
  EXPECT_EQ(h.got[1].bytes, second);
  // A sample whose last fragment never comes is lost once the window has passed it.
  Bytes e = p.header();
  data_frag(e, kWriter, 3, 1, 1, 1344, sample_payload(3, 3000));
  data(e, kWriter, 2000, sample_payload(2000, 20));
  h.feed(e);
  EXPECT_EQ(h.got.size(), 3u);
  EXPECT_EQ(h.decoder.lost_per_topic().at("poise/state"), 1996u + 1u);  // 4..1999 and 3
  EXPECT_EQ(h.decoder.counters().malformed, 0u);
}

// A fragment that contradicts the sample's size or fragment size given by the first fragment of
// the same (writer, sequence number) is refused and counted: its offsets would reach past the
// buffer reassembling the sample. The sample still completes from consistent fragments.
TEST(RtpsDecoder, AFragmentThatContradictsTheSamplesSizeIsRefused) {
  Harness h;
  const Participant p(6);
  Bytes a = p.header();
  announce(a, p, kWriter, "poise/state", "poise::msg::State", 1);
  h.feed(a);
  const Bytes whole = sample_payload(1, 3000);  // fragments of 1344, 1344, 312
  Bytes first = p.header();
  data_frag(first, kWriter, 1, 1, 1, 1344, whole);
  h.feed(first);
  const Bytes larger = sample_payload(1, 9000);  // 7 fragments of 1344: numbers 3..7 reach past
  for (std::uint32_t k : {3u, 5u, 7u}) {
    Bytes bad = p.header();
    data_frag(bad, kWriter, 1, k, 1, 1344, larger);
    h.feed(bad);
  }
  Bytes other_size = p.header();
  data_frag(other_size, kWriter, 1, 2, 1, 2000, whole);  // another fragment size
  h.feed(other_size);
  EXPECT_EQ(h.decoder.counters().malformed, 4u);
  EXPECT_TRUE(h.got.empty());
  Bytes rest = p.header();
  data_frag(rest, kWriter, 1, 2, 2, 1344, whole);
  h.feed(rest);
  ASSERT_EQ(h.got.size(), 1u);
  EXPECT_EQ(h.got[0].bytes, whole);
}

TEST(RtpsDecoder, GarbageAndTruncatedMessagesNeverCrashAndAreCounted) {
  Harness h;
  const Participant p(5);
  Bytes a = p.header();
  announce(a, p, kWriter, "poise/sensors", "poise::msg::Sensors", 1);
  data(a, kWriter, 1, sample_payload(1, 64));
  h.feed(a);
  ASSERT_EQ(h.got.size(), 1u);
  // Every truncation of a valid message.
  Bytes full = p.header();
  info_ts(full, 1, 2);
  data(full, kWriter, 2, sample_payload(2, 64));
  data_frag(full, kWriter, 3, 1, 1, 32, sample_payload(3, 64));
  for (std::size_t n = 0; n < full.size(); ++n) h.decoder.datagram(full.data(), n, 1);
  EXPECT_GT(h.decoder.counters().malformed, 0u);
  // Seeded random bytes after a valid header, and random flips of a valid message.
  std::mt19937 rng(20261202);
  for (int i = 0; i < 3000; ++i) {
    Bytes m = p.header();
    const std::size_t n = rng() % 200;
    for (std::size_t k = 0; k < n; ++k) m.push_back(static_cast<std::uint8_t>(rng()));
    h.feed(m);
    Bytes f = full;
    for (int k = 0; k < 4; ++k) f[20 + rng() % (f.size() - 20)] ^= static_cast<std::uint8_t>(rng());
    h.feed(f);
  }
  // Not RTPS at all.
  const Bytes junk{'H', 'T', 'T', 'P'};
  h.feed(junk);
  EXPECT_GE(h.decoder.counters().datagrams, 6000u);
}

}  // namespace
