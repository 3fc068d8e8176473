// export_csv(): two streaming passes over an MCAP file, one typed sink per exported topic.
#include "poise/plot/csv_export.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <tuple>
#include <type_traits>

#include <poise/dds/topics.hpp>
#include <poise/msg/reflection_gen.hpp>

#include "flatten.hpp"

namespace poise::plot {

namespace fs = std::filesystem;

std::string csv_file_name(std::string_view topic) {
  std::string name(topic);
  std::replace(name.begin(), name.end(), '/', '_');
  return name + ".csv";
}

std::string csv_quote(std::string_view text) {
  std::string out;
  out.reserve(text.size() + 2);
  out.push_back('"');
  for (char c : text) {
    if (c == '"') out.push_back('"');
    out.push_back(c);
  }
  out.push_back('"');
  return out;
}

int TopicExport::column(std::string_view name) const {
  const auto it = std::find(columns.begin(), columns.end(), name);
  return it == columns.end() ? 0 : static_cast<int>(it - columns.begin()) + 1;
}

std::uint64_t ExportReport::decode_failures() const {
  std::uint64_t n = 0;
  for (const auto& t : topics)
    n += t.decode_failures;
  return n;
}

const TopicExport* ExportReport::find(std::string_view topic) const {
  for (const auto& t : topics)
    if (t.topic == topic) return &t;
  return nullptr;
}

namespace {

/// Decodes and flattens the samples of one topic type.
class Sink {
 public:
  virtual ~Sink() = default;
  /// Decodes `data` into the held sample; false with `why` when it does not decode.
  virtual bool decode(std::span<const std::uint8_t> data, std::string& why) = 0;
  /// "" or the first field of the held sample that fails validation.
  virtual std::string invalid() const = 0;
  virtual void measure() = 0;
  virtual std::vector<std::string> header() = 0;
  /// Appends the held sample's cells, each preceded by a comma.
  virtual void append_row(std::string& line) = 0;
  virtual const void* sample() const = 0;
};

template <class T>
class TypedSink final : public Sink {
 public:
  TypedSink() : type_(dds::TopicTraits<T>::type_support()) {}
  bool decode(std::span<const std::uint8_t> data, std::string& why) override {
    char reason[256] = {};
    if (type_.deserialize(data.data(), data.size(), &sample_, reason, sizeof(reason))) return true;
    why = reason[0] ? reason : "malformed CDR";
    return false;
  }
  std::string invalid() const override {
    char reason[256] = {};
    return type_.validate(&sample_, reason, sizeof(reason)) ? std::string() : std::string(reason);
  }
  void measure() override {
    detail::Walk w(detail::WalkMode::measure, widths_);
    detail::walk_struct(w, sample_, false);
  }
  std::vector<std::string> header() override {
    std::vector<std::string> names;
    detail::Walk w(detail::WalkMode::header, widths_, &names);
    detail::walk_struct(w, sample_, false);
    return names;
  }
  void append_row(std::string& line) override {
    detail::Walk w(detail::WalkMode::row, widths_, nullptr, &line);
    detail::walk_struct(w, sample_, false);
  }
  const void* sample() const override { return &sample_; }

 private:
  const dds::TypeSupport& type_;
  detail::Widths widths_;
  T sample_;
};

/// A sink for the Poise topic type whose DDS type name is `type_name`, or nullptr.
std::unique_ptr<Sink> make_sink(std::string_view type_name) {
  std::unique_ptr<Sink> sink;
  [&]<class... Ts>(std::type_identity<std::tuple<Ts...>>) {
    ((msg::IdlName<Ts>::value == type_name ? (void)(sink = std::make_unique<TypedSink<Ts>>())
                                           : (void)0),
     ...);
  }(std::type_identity<msg::TopicTypeList>{});
  return sink;
}

struct TopicState {
  TopicExport out;
  std::unique_ptr<Sink> sink;
  std::FILE* file = nullptr;
};

struct ChannelState {
  TopicState* topic = nullptr;     // nullptr: not exported
  std::size_t skipped = SIZE_MAX;  // index in ExportReport::skipped, or SIZE_MAX
};

/// Prints "<what> N messages" about once a second once a pass has run for a second.
class Progress {
 public:
  Progress(std::FILE* out, const char* what, std::uint64_t total)
      : out_(out), what_(what), total_(total), last_(std::chrono::steady_clock::now()) {}
  void tick(std::uint64_t done) {
    if (!out_ || (done & 1023u) != 0) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::seconds(1)) return;
    last_ = now;
    if (total_) {
      std::fprintf(out_, "poise export: %s %llu of %llu messages (%.0f%%)\n", what_,
                   static_cast<unsigned long long>(done), static_cast<unsigned long long>(total_),
                   100.0 * static_cast<double>(done) / static_cast<double>(total_));
    } else {
      std::fprintf(out_, "poise export: %s %llu messages\n", what_,
                   static_cast<unsigned long long>(done));
    }
    std::fflush(out_);
  }

 private:
  std::FILE* out_;
  const char* what_;
  std::uint64_t total_;
  std::chrono::steady_clock::time_point last_;
};

/// Seconds of `t - origin` (ns), exact to the nanosecond for any realistic recording length.
void append_seconds(std::string& line, std::uint64_t t, std::uint64_t origin) {
  const double s = t >= origin ? static_cast<double>(t - origin) * 1e-9
                               : -static_cast<double>(origin - t) * 1e-9;
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), s);
  line.append(buf, static_cast<std::size_t>(r.ptr - buf));
}

/// One export: two passes over the file (pass 1: column widths, decode failures, the time origin;
/// pass 2: the rows), one CSV file per exported topic.
class Exporter {
 public:
  Exporter(const std::string& path, const ExportOptions& options)
      : path_(path), options_(options), wanted_(options.topics.begin(), options.topics.end()) {}

  ExportReport run() {
    if (!read_pass() || !check_topics()) return std::move(report_);
    if (open_outputs()) write_pass();
    return finish();
  }

 private:
  /// Channel -> topic state, the same in both passes (channel records come before their
  /// messages).
  void on_channel(const record::ChannelRecord& c) {
    if (channels_.count(c.id)) return;  // second pass: known already
    present_.insert(c.topic);
    ChannelState& state = channels_[c.id];
    if (!wanted_.empty() && !wanted_.count(c.topic)) return;
    const auto schema = schemas_.find(c.schema_id);
    const std::string schema_name = schema == schemas_.end() ? std::string() : schema->second.name;
    auto skip = [&](std::string reason) {
      state.skipped = report_.skipped.size();
      report_.skipped.push_back({c.topic, schema_name, std::move(reason), 0});
    };
    if (schema == schemas_.end())
      return skip("its schema (id " + std::to_string(c.schema_id) + ") is not in the file");
    if (c.message_encoding != "cdr")
      return skip("message encoding '" + c.message_encoding + "', not cdr");
    auto it = topics_.find(c.topic);
    if (it != topics_.end()) {
      if (it->second.out.type_name != schema_name)
        return skip("a second channel of the topic with another type (first: " +
                    it->second.out.type_name + ")");
      state.topic = &it->second;
      return;
    }
    std::unique_ptr<Sink> sink = make_sink(schema_name);
    if (!sink) return skip("not a Poise topic type");
    TopicState& t = topics_[c.topic];
    t.out.topic = c.topic;
    t.out.type_name = schema_name;
    t.sink = std::move(sink);
    state.topic = &t;
  }

  /// Pass 1 on one message: the time origin, skipped and failed messages, column widths.
  void measure(const record::MessageView& m) {
    if (!any_message_ || m.log_time < report_.first_log_time) report_.first_log_time = m.log_time;
    any_message_ = true;
    const auto ch = channels_.find(m.channel_id);
    if (ch == channels_.end()) return;
    if (ch->second.skipped != SIZE_MAX) ++report_.skipped[ch->second.skipped].messages;
    TopicState* t = ch->second.topic;
    if (!t) return;
    std::string why;
    if (!t->sink->decode(m.data, why)) {
      if (t->out.decode_failures++ == 0) t->out.first_failure = why;
      return;
    }
    t->sink->measure();
    if (const std::string bad = t->sink->invalid(); !bad.empty())
      if (t->out.invalid++ == 0) t->out.first_invalid = bad;
  }

  /// False when the file is not MCAP.
  bool read_pass() {
    Progress progress(options_.progress, "reading", 0);
    record::ScanHandlers h;
    h.on_schema = [&](const record::SchemaRecord& s) { schemas_.emplace(s.id, s); };
    h.on_channel = [&](const record::ChannelRecord& c) { on_channel(c); };
    h.on_message = [&](const record::MessageView& m) {
      progress.tick(++messages_);
      measure(m);
      return true;
    };
    report_.scan = record::scan(path_, h);
    if (report_.scan.is_mcap) return true;
    report_.error = report_.scan.error.empty() ? "not an MCAP file" : report_.scan.error;
    return false;
  }

  /// The topics asked for that the file does not have; false when that is an error.
  bool check_topics() {
    for (const auto& name : options_.topics)
      if (!present_.count(name)) report_.absent_topics.push_back(name);
    if (!options_.topics_must_exist || report_.absent_topics.empty()) return true;
    std::string held;
    for (const auto& p : present_) held += (held.empty() ? "" : ", ") + p;
    report_.error = "topic '" + report_.absent_topics.front() + "' is not in the recording (" +
                    (held.empty() ? std::string("it holds no topic") : "it holds: " + held) + ")";
    return false;
  }

  /// Opens the outputs (every exported topic, even one whose messages all failed to decode) and
  /// writes their header lines. False (with the error) when one cannot be made.
  bool open_outputs() {
    std::error_code ec;
    fs::create_directories(
        options_.output_dir.empty() ? fs::path(".") : fs::path(options_.output_dir), ec);
    if (ec) {
      report_.error = "cannot create " + options_.output_dir + ": " + ec.message();
      return false;
    }
    for (auto& [name, t] : topics_) {
      t.out.csv_path = (fs::path(options_.output_dir) / csv_file_name(name)).string();
      t.out.columns = {"log_time_s", "publish_time_s"};
      const auto fields = t.sink->header();
      t.out.columns.insert(t.out.columns.end(), fields.begin(), fields.end());
      t.file = std::fopen(t.out.csv_path.c_str(), "w");
      if (!t.file) {
        report_.error = "cannot create " + t.out.csv_path + ": " + std::strerror(errno);
        return false;
      }
      static constexpr std::size_t kBuffer = 1 << 20;
      std::setvbuf(t.file, nullptr, _IOFBF, kBuffer);
      line_.clear();
      for (std::size_t i = 0; i < t.out.columns.size(); ++i) {
        if (i) line_.push_back(',');
        const std::string& c = t.out.columns[i];
        line_ += c.find_first_of(",\"\n\r") == std::string::npos ? c : csv_quote(c);
      }
      line_.push_back('\n');
      std::fwrite(line_.data(), 1, line_.size(), t.file);
    }
    return true;
  }

  /// Pass 2 on one message: its row.
  void write_row(const record::MessageView& m) {
    const auto ch = channels_.find(m.channel_id);
    if (ch == channels_.end() || !ch->second.topic) return;
    TopicState& t = *ch->second.topic;
    std::string why;
    if (!t.sink->decode(m.data, why)) return;  // counted in pass 1
    line_.clear();
    append_seconds(line_, m.log_time, report_.first_log_time);
    line_.push_back(',');
    if (m.publish_time != 0) append_seconds(line_, m.publish_time, report_.first_log_time);
    t.sink->append_row(line_);
    line_.push_back('\n');
    std::fwrite(line_.data(), 1, line_.size(), t.file);
    ++t.out.rows;
    if (options_.on_sample) options_.on_sample(t.out.topic, t.out.type_name, t.sink->sample(), m);
  }

  void write_pass() {
    std::uint64_t count = 0;
    Progress progress(options_.progress, "writing", messages_);
    record::ScanHandlers h;
    h.on_channel = [&](const record::ChannelRecord& c) { on_channel(c); };
    h.on_message = [&](const record::MessageView& m) {
      progress.tick(++count);
      write_row(m);
      return true;
    };
    report_.scan = record::scan(path_, h);
  }

  /// Closes the outputs (a write error becomes the report's error) and hands over the topics.
  ExportReport finish() {
    for (auto& [name, t] : topics_) {
      if (t.file) {
        const bool failed = std::ferror(t.file) != 0;
        if ((std::fclose(t.file) != 0 || failed) && report_.error.empty())
          report_.error = "cannot write " + t.out.csv_path;
        t.file = nullptr;
      }
      report_.topics.push_back(std::move(t.out));
    }
    return std::move(report_);
  }

  const std::string& path_;
  const ExportOptions& options_;
  const std::set<std::string, std::less<>> wanted_;
  ExportReport report_;
  std::map<std::string, TopicState, std::less<>> topics_;
  std::map<std::uint16_t, record::SchemaRecord> schemas_;
  std::map<std::uint16_t, ChannelState> channels_;
  std::set<std::string, std::less<>> present_;  // every topic with a channel in the file
  bool any_message_ = false;
  std::uint64_t messages_ = 0;
  std::string line_;
};

}  // namespace

ExportReport export_csv(const std::string& mcap_path, const ExportOptions& options) {
  return Exporter(mcap_path, options).run();
}

}  // namespace poise::plot
