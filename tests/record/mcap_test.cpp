// MCAP writer and reader: round trips with every compression, files cut at many points (a
// recorder killed mid-write), corrupted bytes, input that is not MCAP, and a disk that fills up.
// The files are also handed to the independent MCAP reader (npm @mcap/core, see
// tests/record/mcap_reader_js) by independent_reader_test.cpp.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include <poise/record/mcap_format.hpp>
#include <poise/record/mcap_reader.hpp>
#include <poise/record/mcap_writer.hpp>
#include <poise/record/recording_info.hpp>

namespace fs = std::filesystem;
using namespace poise::record;

namespace {

struct Written {
  std::uint16_t channel;
  std::uint32_t sequence;
  std::uint64_t log_time, publish_time;
  std::vector<std::uint8_t> data;
};

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() / ("poise_mcap_test_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

/// Writes `n` messages on three channels with seeded random sizes and content.
std::vector<Written> write_file(const fs::path& path, Compression c, std::size_t chunk_size, int n,
                                std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  WriterOptions o;
  o.compression = c;
  o.chunk_size = chunk_size;
  o.sync_chunks = false;
  McapWriter w(path.string(), o);
  const auto s1 = w.add_schema("poise::msg::A", "omgidl", "module m { struct A { long x; }; };");
  const auto s2 = w.add_schema("poise::msg::B", "omgidl", "module m { struct B { long y; }; };");
  std::vector<std::uint16_t> ch{w.add_channel(s1, "a", "cdr"),
                                w.add_channel(s2, "b", "cdr", {{"k", "v"}}),
                                w.add_channel(s1, "c", "cdr")};
  std::vector<Written> out;
  std::vector<std::uint32_t> seq(3, 0);
  for (int i = 0; i < n; ++i) {
    const int k = static_cast<int>(rng() % 3);
    Written m{
        ch[k], ++seq[k], 1'000'000'000ULL + 1'000'000ULL * i, 999'000'000ULL + 1000ULL * i, {}};
    // Mostly small (like 1 kHz topics), sometimes large, sometimes empty.
    const std::size_t size = (i % 97 == 0)   ? 20000 + rng() % 5000
                             : (i % 13 == 0) ? 0
                                             : rng() % 1600;
    m.data.resize(size);
    for (auto& b : m.data)
      b = static_cast<std::uint8_t>(rng() % 7);  // compressible, like CDR of doubles
    EXPECT_TRUE(w.write_message(m.channel, m.sequence, m.log_time, m.publish_time, m.data.data(),
                                m.data.size()));
    out.push_back(std::move(m));
  }
  EXPECT_TRUE(w.write_metadata("poise_test", {{"seed", std::to_string(seed)}, {"x", "y"}}));
  EXPECT_TRUE(w.close()) << w.error();
  return out;
}

std::vector<Written> read_messages(
    const fs::path& path, ScanResult* result = nullptr,
    std::map<std::string, std::map<std::string, std::string>>* md = nullptr) {
  std::vector<Written> got;
  ScanHandlers h;
  h.on_message = [&](const MessageView& m) {
    got.push_back(Written{m.channel_id, m.sequence, m.log_time, m.publish_time,
                          std::vector<std::uint8_t>(m.data.begin(), m.data.end())});
    return true;
  };
  h.on_metadata = [&](const MetadataRecord& m) {
    if (md) {
      (*md)[m.name] = m.metadata;
    }
  };
  const ScanResult r = scan(path.string(), h);
  if (result) *result = r;
  return got;
}

void expect_prefix(const std::vector<Written>& got, const std::vector<Written>& all) {
  ASSERT_LE(got.size(), all.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].channel, all[i].channel) << "message " << i;
    ASSERT_EQ(got[i].sequence, all[i].sequence) << "message " << i;
    ASSERT_EQ(got[i].log_time, all[i].log_time) << "message " << i;
    ASSERT_EQ(got[i].publish_time, all[i].publish_time) << "message " << i;
    ASSERT_EQ(got[i].data, all[i].data) << "message " << i;
  }
}

std::vector<std::uint8_t> file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {});
}

void write_bytes(const fs::path& p, const std::uint8_t* data, std::size_t n) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(n));
}

class McapRoundTrip : public ::testing::TestWithParam<Compression> {};

}  // namespace

TEST_P(McapRoundTrip, EveryMessageComesBackInOrderWithItsTimesAndMetadata) {
  const fs::path path = temp_dir() / ("round_trip_" + std::string(to_string(GetParam())) + ".mcap");
  const auto written = write_file(path, GetParam(), 16 << 10, 3000, 42);
  ScanResult r;
  std::map<std::string, std::map<std::string, std::string>> md;
  const auto got = read_messages(path, &r, &md);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.is_mcap);
  EXPECT_TRUE(r.complete) << r.truncation;
  EXPECT_EQ(r.bytes_read, r.file_size);
  EXPECT_GT(r.chunks, 10u);
  ASSERT_EQ(got.size(), written.size());
  expect_prefix(got, written);
  EXPECT_EQ(md["poise_test"]["seed"], "42");
  EXPECT_EQ(r.compressions.count(
                GetParam() == Compression::none ? "" : std::string(to_string(GetParam()))),
            1u);
  if (GetParam() != Compression::none) {
    EXPECT_LT(r.compressed_bytes, r.uncompressed_bytes * 9 / 10);  // random symbols 0..6
  }
}

INSTANTIATE_TEST_SUITE_P(Compressions, McapRoundTrip,
                         ::testing::Values(Compression::none, Compression::lz4, Compression::zstd),
                         [](const auto& info) { return std::string(to_string(info.param)); });

TEST(Mcap, DataEndCrcCoversEveryByteBeforeIt) {
  // An identity independent of the writer's running CRC: zlib's CRC of the file prefix.
  const fs::path path = temp_dir() / "crc.mcap";
  write_file(path, Compression::zstd, 8 << 10, 500, 7);
  const auto bytes = file_bytes(path);
  // Find DataEnd by walking the records from the start.
  std::size_t pos = 8;
  while (pos + kRecordPrefix <= bytes.size() &&
         bytes[pos] != static_cast<std::uint8_t>(Op::data_end)) {
    std::uint64_t len = 0;
    for (int i = 0; i < 8; ++i)
      len |= static_cast<std::uint64_t>(bytes[pos + 1 + i]) << (8 * i);
    pos += kRecordPrefix + len;
  }
  ASSERT_LT(pos + kRecordPrefix + 4, bytes.size());
  std::uint32_t stored = 0;
  for (int i = 0; i < 4; ++i)
    stored |= static_cast<std::uint32_t>(bytes[pos + kRecordPrefix + i]) << (8 * i);
  EXPECT_EQ(stored, crc32(0, bytes.data(), pos));
  EXPECT_NE(stored, 0u);
}

TEST(Mcap, AFileCutAnywhereYieldsEveryCompleteChunkAndSaysItIsIncomplete) {
  const fs::path path = temp_dir() / "cut_source.mcap";
  const auto written = write_file(path, Compression::zstd, 8 << 10, 2000, 3);
  const auto bytes = file_bytes(path);
  const fs::path cut = temp_dir() / "cut.mcap";
  std::size_t previous = 0;
  int cuts = 0;
  std::mt19937_64 rng(11);
  for (std::size_t at = 0; at < bytes.size(); at += 1 + rng() % 1500) {
    write_bytes(cut, bytes.data(), at);
    ScanResult r;
    const auto got = read_messages(cut, &r);
    ++cuts;
    if (at < 8 + kRecordPrefix) {
      EXPECT_FALSE(r.is_mcap && r.complete) << "cut at " << at;
      continue;
    }
    ASSERT_TRUE(r.ok()) << "cut at " << at << ": " << r.error;
    EXPECT_FALSE(r.complete) << "cut at " << at;
    EXPECT_FALSE(r.truncation.empty()) << "cut at " << at;
    expect_prefix(got, written);
    // The longer the file, the more it yields (never fewer messages from more bytes).
    EXPECT_GE(got.size(), previous) << "cut at " << at;
    previous = got.size();
  }
  EXPECT_GT(cuts, 50);
  // The full file minus its last byte: everything but the closing magic.
  write_bytes(cut, bytes.data(), bytes.size() - 1);
  ScanResult r;
  EXPECT_EQ(read_messages(cut, &r).size(), written.size());
  EXPECT_FALSE(r.complete);
}

TEST(Mcap, CorruptedBytesAreReportedNeverCrash) {
  const fs::path path = temp_dir() / "corrupt_source.mcap";
  const auto written = write_file(path, Compression::lz4, 8 << 10, 800, 5);
  const auto clean = file_bytes(path);
  const fs::path bad = temp_dir() / "corrupt.mcap";
  std::mt19937_64 rng(99);
  int errors = 0;
  for (int trial = 0; trial < 300; ++trial) {
    auto bytes = clean;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f)
      bytes[8 + rng() % (bytes.size() - 8)] ^= static_cast<std::uint8_t>(1 + rng() % 255);
    write_bytes(bad, bytes.data(), bytes.size());
    ScanResult r;
    read_messages(bad, &r);  // must return, whatever the bytes
    if (!r.ok()) {
      ++errors;
      EXPECT_NE(r.error.find("at byte"), std::string::npos) << r.error;
    }
  }
  EXPECT_GT(errors, 30) << "CRC and length checks should catch many of 300 corruptions";
}

TEST(Mcap, AFlippedByteInsideAChunkFailsItsCrc) {
  const fs::path path = temp_dir() / "crc_source.mcap";
  write_file(path, Compression::none, 8 << 10, 200, 8);
  auto bytes = file_bytes(path);
  // The first chunk's records start after its header fields; flip a byte well inside it.
  std::size_t pos = 8;
  while (bytes[pos] != static_cast<std::uint8_t>(Op::chunk)) {
    std::uint64_t len = 0;
    for (int i = 0; i < 8; ++i)
      len |= static_cast<std::uint64_t>(bytes[pos + 1 + i]) << (8 * i);
    pos += kRecordPrefix + len;
  }
  bytes[pos + kRecordPrefix + 8 + 8 + 8 + 4 + 4 + 8 + 200] ^= 0x40;
  const fs::path bad = temp_dir() / "crc_bad.mcap";
  write_bytes(bad, bytes.data(), bytes.size());
  ScanResult r;
  read_messages(bad, &r);
  EXPECT_NE(r.error.find("CRC"), std::string::npos) << r.error;
}

TEST(Mcap, InputThatIsNotMcapIsNamedAsSuch) {
  const fs::path d = temp_dir();
  { std::ofstream(d / "text.mcap") << "this is not a recording\n"; }
  std::ofstream(d / "empty.mcap").close();
  for (const fs::path& p : {d / "text.mcap", d / "empty.mcap", fs::path("/dev/null")}) {
    ScanResult r;
    read_messages(p, &r);
    EXPECT_FALSE(r.is_mcap) << p;
    EXPECT_NE(r.error.find("not an MCAP file"), std::string::npos) << p << ": " << r.error;
  }
  ScanResult r;
  read_messages(d / "does_not_exist.mcap", &r);
  EXPECT_NE(r.error.find("cannot open"), std::string::npos) << r.error;
  EXPECT_THROW(McapWriter("/nonexistent_dir/x.mcap"), std::runtime_error);
}

// WriterOptions::overwrite = false (what `poise record` uses unless told --if-exists overwrite):
// an existing file is refused by name and left as it was.
TEST(Mcap, AWriterThatMayNotOverwriteRefusesAnExistingFile) {
  const fs::path d = temp_dir();
  fs::remove(d / "kept.mcap");
  { std::ofstream(d / "kept.mcap") << "an earlier recording"; }
  WriterOptions keep;
  keep.overwrite = false;
  try {
    McapWriter w((d / "kept.mcap").string(), keep);
    ADD_FAILURE() << "an existing file was opened for writing";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("kept.mcap' exists"), std::string::npos) << e.what();
  }
  std::ifstream kept(d / "kept.mcap");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(kept), {}), "an earlier recording");
}

TEST(Mcap, AFullDiskFailsTheWriterAndKeepsWhatWasWritten) {
  // RLIMIT_FSIZE makes write() fail with EFBIG past 64 KiB, as a full disk fails with ENOSPC.
  // The writer's count of messages in the file is what a reader finds there (not the messages
  // it accepted: those of the chunk that failed are not in the file), and the file ends with its
  // last complete record (the half-written chunk is cut off).
  const fs::path path = temp_dir() / "full.mcap";
  const fs::path counts = temp_dir() / "full.counts";
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::signal(SIGXFSZ, SIG_IGN);
    rlimit lim{64 << 10, 64 << 10};
    ::setrlimit(RLIMIT_FSIZE, &lim);
    WriterOptions o;
    o.chunk_size = 4 << 10;
    o.compression = Compression::none;
    McapWriter w(path.string(), o);
    const auto ch = w.add_channel(w.add_schema("poise::msg::A", "omgidl", "x"), "a", "cdr");
    std::vector<std::uint8_t> payload(500, 1);
    int accepted = 0;
    for (int i = 0; i < 1000; ++i)
      accepted += w.write_message(ch, i + 1, 1000 + i, 1000 + i, payload.data(), payload.size());
    const bool closed = w.close();
    const bool named = w.error().find("File too large") != std::string::npos &&
                       w.error().find(path.string()) != std::string::npos;
    {
      std::ofstream c(counts);  // a few bytes: the limit is far
      c << w.messages_in_file(ch) << " " << w.stats().messages_in_file << " "
        << w.stats().bytes_written << "\n";
    }
    ::_exit(!closed && named && accepted > 50 && accepted < 1000 ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the writer did not fail cleanly with EFBIG";
  ScanResult r;
  const auto got = read_messages(path, &r);
  EXPECT_TRUE(r.ok()) << r.error;
  EXPECT_FALSE(r.complete);
  EXPECT_GT(got.size(), 100u);  // ~120 messages fit in 64 KiB
  for (std::size_t i = 0; i < got.size(); ++i)
    EXPECT_EQ(got[i].sequence, i + 1);
  std::uint64_t channel_in_file = 0, in_file = 0, bytes_written = 0;
  std::ifstream(counts) >> channel_in_file >> in_file >> bytes_written;
  EXPECT_EQ(channel_in_file, got.size()) << "the writer counts messages that are not in the file";
  EXPECT_EQ(in_file, got.size());
  EXPECT_EQ(fs::file_size(path), bytes_written);
  EXPECT_EQ(r.bytes_read, fs::file_size(path)) << "a record cut in the middle: " << r.truncation;
}

TEST(Mcap, InfoCountsTopicsTicksAndGaps) {
  // Poise-shaped payloads: encapsulation + Header{tick, stamp}; one per-tick stream with a hole.
  const fs::path path = temp_dir() / "info.mcap";
  {
    McapWriter w(path.string());
    const auto s = w.add_schema("poise::msg::Sensors", "omgidl", "x");
    const auto ch = w.add_channel(s, "poise/sensors", "cdr");
    std::uint32_t seq = 0;
    for (std::uint64_t tick = 1; tick <= 1000; ++tick) {
      if (tick >= 500 && tick < 510) continue;  // 10 ticks never published
      std::vector<std::uint8_t> b{0, 1, 0, 0};
      for (int i = 0; i < 8; ++i)
        b.push_back(static_cast<std::uint8_t>(tick >> (8 * i)));
      b.resize(40, 0);
      ++seq;
      if (tick == 700) ++seq;  // one sample dropped by the recorder
      w.write_message(ch, seq, tick * 1'000'000ULL, tick * 1'000'000ULL, b.data(), b.size());
    }
    w.close();
  }
  const RecordingInfo info = read_recording_info(path.string());
  ASSERT_TRUE(info.scan.complete);
  ASSERT_EQ(info.topics.size(), 1u);
  const TopicInfo& t = info.topics[0];
  EXPECT_EQ(t.messages, 990u);
  EXPECT_TRUE(t.per_tick);
  EXPECT_EQ(t.first_tick, 1u);
  EXPECT_EQ(t.last_tick, 1000u);
  EXPECT_EQ(t.missing_ticks, 10u);
  EXPECT_EQ(t.duplicate_ticks, 0u);
  EXPECT_EQ(t.sequence_gaps, 1u);
  EXPECT_NEAR(t.longest_interval_s, 0.011, 1e-9);
  EXPECT_NEAR(info.duration_s(), 0.999, 1e-9);
}

namespace {
// A Poise-shaped payload: encapsulation + Header{tick, stamp} + padding.
std::vector<std::uint8_t> poise_payload(std::uint64_t tick) {
  std::vector<std::uint8_t> b{0, 1, 0, 0};
  for (int i = 0; i < 8; ++i)
    b.push_back(static_cast<std::uint8_t>(tick >> (8 * i)));
  b.resize(40, 0);
  return b;
}
}  // namespace

TEST(Mcap, InfoCountsTheTicksMissingAtTheStartOfTheRun) {
  // A recorder started after the stack: every per-tick topic begins at tick 2453, but the run
  // began at tick 10, as the latched robot description (header tick = the run's first tick)
  // says. Before, info said "0 missing".
  const fs::path late = temp_dir() / "late.mcap";
  {
    McapWriter w(late.string());
    const auto d = w.add_channel(w.add_schema("poise::msg::RobotDescription", "omgidl", "x"),
                                 "poise/robot_description", "cdr");
    const auto s = w.add_channel(w.add_schema("poise::msg::Sensors", "omgidl", "x"),
                                 "poise/sensors", "cdr");
    const auto st =
        w.add_channel(w.add_schema("poise::msg::State", "omgidl", "x"), "poise/state", "cdr");
    const auto desc = poise_payload(10);
    w.write_message(d, 1, 1'000'000ULL, 1'000'000ULL, desc.data(), desc.size());
    std::uint32_t seq = 0;
    for (std::uint64_t tick = 2453; tick <= 3000; ++tick) {
      const auto b = poise_payload(tick);
      ++seq;
      w.write_message(s, seq, tick * 1'000'000ULL, tick * 1'000'000ULL, b.data(), b.size());
      w.write_message(st, seq, tick * 1'000'000ULL, tick * 1'000'000ULL, b.data(), b.size());
    }
    ASSERT_TRUE(w.close());
  }
  RecordingInfo info = read_recording_info(late.string());
  ASSERT_TRUE(info.scan.complete);
  EXPECT_EQ(info.run_first_tick, 10u);
  EXPECT_EQ(info.run_first_tick_source, "poise/robot_description");
  ASSERT_EQ(info.topics.size(), 3u);
  for (const TopicInfo& t : info.topics) {
    if (!t.per_tick) continue;
    EXPECT_EQ(t.first_tick, 2453u) << t.topic;
    EXPECT_EQ(t.missing_at_start, 2443u) << t.topic;
    EXPECT_EQ(t.missing_ticks, 0u) << t.topic;
  }
  const std::string text = format_recording_info(info);
  EXPECT_NE(text.find("first tick 2453 on poise/sensors, expected 10: 2443 ticks missing at the "
                      "start"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("2453..3000, 2443 missing at the start"), std::string::npos) << text;
  const auto j = recording_info_json(info);
  EXPECT_EQ(j["run_first_tick"], 10);
  EXPECT_EQ(j["topics"][1]["missing_at_start"], 2443);

  // No description (or one that does not say): the earliest tick of any per-tick topic is the
  // reference; a topic that began later misses the ticks before.
  const fs::path partial = temp_dir() / "partial.mcap";
  {
    McapWriter w(partial.string());
    const auto s = w.add_channel(w.add_schema("poise::msg::Sensors", "omgidl", "x"),
                                 "poise/sensors", "cdr");
    const auto st =
        w.add_channel(w.add_schema("poise::msg::State", "omgidl", "x"), "poise/state", "cdr");
    for (std::uint64_t tick = 1; tick <= 1000; ++tick) {
      const auto b = poise_payload(tick);
      w.write_message(s, static_cast<std::uint32_t>(tick), tick * 1'000'000ULL,
                      tick * 1'000'000ULL, b.data(), b.size());
      if (tick >= 50)
        w.write_message(st, static_cast<std::uint32_t>(tick - 49), tick * 1'000'000ULL,
                        tick * 1'000'000ULL, b.data(), b.size());
    }
    ASSERT_TRUE(w.close());
  }
  info = read_recording_info(partial.string());
  EXPECT_EQ(info.run_first_tick, 1u);
  EXPECT_EQ(info.run_first_tick_source, "earliest per-tick topic");
  ASSERT_EQ(info.topics.size(), 2u);
  EXPECT_EQ(info.topics[0].topic, "poise/sensors");
  EXPECT_EQ(info.topics[0].missing_at_start, 0u);
  EXPECT_EQ(info.topics[1].missing_at_start, 49u);
  EXPECT_NE(format_recording_info(info).find(
                "first tick 50 on poise/state, expected 1: 49 ticks missing at the start"),
            std::string::npos)
      << format_recording_info(info);
}
