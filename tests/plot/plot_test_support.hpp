#pragma once
// Test support of tests/plot: MCAP files of Poise samples written with poise::record::McapWriter,
// an RFC 4180 CSV reader, a scratch directory, and `build/bin/poise` run as a bounded child.

#include <stdlib.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <poise/dds/topics.hpp>
#include <poise/msg/idl_schemas_gen.hpp>
#include <poise/msg/reflection_gen.hpp>
#include <poise/record/mcap_writer.hpp>

#include "child_process.hpp"

namespace poise::plot_test {

namespace fs = std::filesystem;

/// A fresh directory under /tmp, removed with its contents at the end of the test.
class ScratchDir {
 public:
  ScratchDir() {
    std::string pattern = (fs::temp_directory_path() / "poise-plot-test-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const fs::path& path() const { return path_; }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

/// CDR bytes of a sample (encapsulation header included), as the recorder stores them.
template <class T>
std::vector<std::uint8_t> cdr_bytes(const T& sample) {
  const dds::TypeSupport& ts = dds::TopicTraits<T>::type_support();
  std::vector<std::uint8_t> bytes(ts.serialized_size(&sample));
  const std::size_t n = ts.serialize(&sample, bytes.data(), bytes.size());
  if (n == 0) throw std::runtime_error("serialize failed");
  bytes.resize(n);
  return bytes;
}

/// A recording under construction: one channel per topic type, as `poise record` writes them.
class Recording {
 public:
  explicit Recording(const std::string& path, std::size_t chunk_size = 1 << 20) {
    record::WriterOptions o;
    o.sync_chunks = false;
    o.chunk_size = chunk_size;
    writer_ = std::make_unique<record::McapWriter>(path, o);
  }
  template <class T>
  std::uint16_t channel() {
    const std::string_view type = msg::IdlName<T>::value;
    if (auto it = channels_.find(std::string(type)); it != channels_.end()) return it->second;
    std::string_view schema;
    for (const auto& s : msg::kIdlSchemas)
      if (s.type_name == type) schema = s.idl;
    const std::uint16_t sid = writer_->add_schema(type, "omgidl", schema);
    const std::uint16_t cid = writer_->add_channel(sid, dds::TopicTraits<T>::topic_name, "cdr");
    channels_[std::string(type)] = cid;
    return cid;
  }
  template <class T>
  void write(const T& sample, std::uint64_t log_time, std::uint64_t publish_time) {
    const auto bytes = cdr_bytes(sample);
    write_raw(channel<T>(), log_time, publish_time, bytes);
  }
  void write_raw(std::uint16_t channel, std::uint64_t log_time, std::uint64_t publish_time,
                 const std::vector<std::uint8_t>& bytes) {
    if (!writer_->write_message(channel, sequence_++, log_time, publish_time, bytes.data(),
                                bytes.size()))
      throw std::runtime_error("write_message failed: " + writer_->error());
  }
  record::McapWriter& writer() { return *writer_; }
  void close() {
    if (!writer_->close()) throw std::runtime_error("close failed: " + writer_->error());
  }

 private:
  std::unique_ptr<record::McapWriter> writer_;
  std::map<std::string, std::uint16_t> channels_;
  std::uint32_t sequence_ = 0;
};

/// One CSV cell: its text (quotes removed) and whether it was quoted.
struct Cell {
  std::string text;
  bool quoted = false;
};
using CsvRow = std::vector<Cell>;

/// Reads an RFC 4180 file (quoted fields may hold commas, quotes doubled, line breaks).
inline std::vector<CsvRow> read_csv(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::ostringstream s;
  s << in.rdbuf();
  const std::string text = s.str();
  std::vector<CsvRow> rows;
  CsvRow row;
  Cell cell;
  std::size_t i = 0;
  bool any = false;
  while (i < text.size()) {
    const char c = text[i];
    if (c == '"' && cell.text.empty() && !cell.quoted) {
      cell.quoted = true;
      ++i;
      for (;;) {
        if (i >= text.size()) throw std::runtime_error(path + ": unterminated quoted field");
        if (text[i] == '"') {
          if (i + 1 < text.size() && text[i + 1] == '"') {
            cell.text.push_back('"');
            i += 2;
            continue;
          }
          ++i;
          break;
        }
        cell.text.push_back(text[i++]);
      }
      any = true;
      continue;
    }
    if (c == ',') {
      row.push_back(std::move(cell));
      cell = {};
      any = true;
    } else if (c == '\n') {
      row.push_back(std::move(cell));
      cell = {};
      rows.push_back(std::move(row));
      row = {};
      any = false;
    } else {
      if (cell.quoted) throw std::runtime_error(path + ": text after a closing quote");
      cell.text.push_back(c);
      any = true;
    }
    ++i;
  }
  if (any) {
    row.push_back(std::move(cell));
    rows.push_back(std::move(row));
  }
  return rows;
}

/// What `poise <args>` printed (stdout and stderr) and its exit code (nullopt: killed).
struct PoiseRun {
  std::optional<int> code;
  std::string output;
};

inline PoiseRun run_poise(std::vector<std::string> args,
                          std::chrono::milliseconds timeout = std::chrono::seconds(120)) {
  args.insert(args.begin(), testing::bin("poise"));
  testing::ChildProcess child(args, {}, false, /*merge_stderr=*/true);
  PoiseRun r;
  r.code = child.wait_for(timeout);
  r.output = child.output();
  return r;
}

}  // namespace poise::plot_test
