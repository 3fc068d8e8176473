// `poise record`, `poise info`, `poise replay` and `poise run --record` as users run them: real
// processes on a DDS domain of this test's own (loopback only), real files, and every file read
// by the independent MCAP reader (npm @mcap/core + @foxglove/omgidl-*, mcap_reader_js/).
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <linux/if_ether.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>

#include <poise/msg/balance_reference.h>
#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/diagnostics.h>
#include <poise/msg/disturbance.h>
#include <poise/msg/estop.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>
#include <nlohmann/json.hpp>
#include <poise/dds/dds.hpp>
#include <poise/dds/domain_claim.hpp>
#include <poise/record/mcap_reader.hpp>
#include <poise/record/mcap_writer.hpp>
#include <poise/reflect/fill.hpp>

#include "child_process.hpp"

namespace fs = std::filesystem;
using Json = nlohmann::json;
using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;

namespace {

using AllTypes =
    std::tuple<poise::msg::RobotDescription, poise::msg::Sensors, poise::msg::GroundTruth,
               poise::msg::State, poise::msg::BalanceReference, poise::msg::ContactProblem,
               poise::msg::ContactSolution, poise::msg::JointCommand, poise::msg::Disturbance, poise::msg::EStop,
               poise::msg::Diagnostics>;

template <class F>
void for_each_type(F&& f) {
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (f(std::integral_constant<std::size_t, I>{}), ...);
  }
  (std::make_index_sequence<std::tuple_size_v<AllTypes>>{});
}

fs::path work_dir(const std::string& name) {
  const fs::path d =
      fs::temp_directory_path() / ("poise_record_test_" + std::to_string(::getpid())) / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

/// Runs a command to completion (bounded); returns {exit code, stdout (+stderr if merged)}.
std::pair<int, std::string> run(std::vector<std::string> argv, std::chrono::seconds limit = 120s,
                                bool merge_stderr = true) {
  ChildProcess p(std::move(argv), {}, false, merge_stderr);
  const auto code = p.wait_for(limit);
  return {code.value_or(-1), p.output()};
}

/// The independent reader's report of a file ({exit code, report}).
std::pair<int, Json> check_independently(const fs::path& file, bool streaming,
                                         const fs::path& dump = {}) {
  std::vector<std::string> argv{POISE_NODE, POISE_MCAP_CHECK_JS};
  if (streaming) argv.push_back("--streaming");
  if (!dump.empty()) {
    argv.push_back("--dump");
    argv.push_back(dump.string());
  }
  argv.push_back(file.string());
  const auto [code, out] = run(argv, 300s, false);
  Json report;
  try {
    report = Json::parse(out);
  } catch (...) {
    ADD_FAILURE() << "the MCAP checker printed no JSON report: " << out;
  }
  return {code, report};
}

Json info_json(const fs::path& file, int* code = nullptr) {
  const auto [rc, out] = run({bin("poise"), "info", "--json", file.string()}, 120s, false);
  if (code) *code = rc;
  try {
    return Json::parse(out);
  } catch (...) {
    ADD_FAILURE() << "poise info --json printed no JSON: " << out;
    return Json();
  }
}

/// The per-tick topics of the distributed stack and the node that writes each.
const std::vector<std::pair<std::string, std::string>> kPerTickTopicWriters{
    {"poise/sensors", "sim"},           {"poise/ground_truth", "sim"},
    {"poise/state", "estimator"},       {"poise/contact_problem", "controller"},
    {"poise/contact_solution", "contact"}, {"poise/joint_command", "controller"}};

/// The ticks a node says it handled (its --summary file in `logs`: diagnostics.ticks).
std::uint64_t summary_ticks(const fs::path& logs, const std::string& node) {
  const Json j = Json::parse(std::ifstream(logs / (node + ".summary.json")));
  return j["diagnostics"]["ticks"].get<std::uint64_t>();
}

const Json* find_topic(const Json& info, const std::string& topic) {
  for (const auto& t : info["topics"])
    if (t["topic"] == topic) return &t;
  return nullptr;
}

// ---- comparing what the independent decoder returned with what was published --------------

std::optional<std::string> diff(const auto& v, const Json& j, const std::string& path);

template <class T>
std::optional<std::string> diff_value(const T& v, const Json& j, const std::string& path) {
  using namespace poise::reflect;
  if constexpr (is_struct_v<T>) {
    if (!j.is_object()) return path + ": not an object";
    std::optional<std::string> d;
    poise::msg::visit_fields(v, [&](const FieldInfo& info, const auto& m) {
      if (d) return;
      const auto it = j.find(std::string(info.name));
      const std::string p =
          path.empty() ? std::string(info.name) : path + "." + std::string(info.name);
      if (it == j.end()) {
        d = p + ": missing";
        return;
      }
      d = diff_value(m, *it, p);
    });
    return d;
  } else if constexpr (is_array_v<T> || is_vector_v<T>) {
    if (!j.is_array() || j.size() != v.size())
      return path + ": expected " + std::to_string(v.size()) + " entries, got " + j.dump();
    for (std::size_t i = 0; i < v.size(); ++i)
      if (auto d = diff_value(v[i], j[i], path + "[" + std::to_string(i) + "]")) return d;
    return std::nullopt;
  } else if constexpr (is_fixed_string_v<T>) {
    if (j != v.to_string()) return path + ": " + j.dump() + " vs \"" + v.to_string() + "\"";
    return std::nullopt;
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (j != v) return path + ": " + j.dump() + " vs \"" + v + "\"";
    return std::nullopt;
  } else if constexpr (is_enum_v<T>) {
    if (!j.is_number_integer() || j.get<long long>() != static_cast<long long>(v))
      return path + ": " + j.dump() + " vs enumerator " + std::to_string(static_cast<int>(v));
    return std::nullopt;
  } else if constexpr (is_bool_v<T>) {
    if (j != v) return path + ": " + j.dump();
    return std::nullopt;
  } else if constexpr (std::is_floating_point_v<T>) {
    if (!j.is_number() || static_cast<T>(j.get<double>()) != v)
      return path + ": " + j.dump() + " vs " + std::to_string(v);
    return std::nullopt;
  } else {
    static_assert(std::is_integral_v<T>);
    // 64-bit integers come as decimal strings (JavaScript BigInt).
    std::string text = j.is_string() ? j.get<std::string>() : j.dump();
    const std::string want = std::to_string(v);
    if (text != want) return path + ": " + text + " vs " + want;
    return std::nullopt;
  }
}

template <class T>
T sample_of(std::size_t type_index, std::uint64_t k, std::uint64_t seed) {
  std::mt19937_64 rng(seed * 7919u + type_index * 1000003u + k);
  T s;
  poise::reflect::fill_random(s, rng);
  s.header().tick(k);
  return s;
}

struct RecorderProcess {
  ChildProcess process;
  RecorderProcess(const std::vector<std::string>& args) : process(args, {}, false, true) {
    EXPECT_TRUE(process.wait_for_output("poise record: ", 20s)) << process.output();
  }
};

std::vector<std::string> record_args(const std::string& vendor, int domain, const fs::path& out,
                                     std::vector<std::string> extra = {}) {
  std::vector<std::string> a{
      bin("poise"),           "record", "--dds",      vendor,       "--domain",
      std::to_string(domain), "-o",     out.string(), "--progress", "0"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

/// Publishes Sensors with ticks 1, 2, ... at 1 kHz on `domain` once a reader matched, until
/// `last` ticks were sent or `keep_going()` says stop; returns the last tick published.
template <class KeepGoing>
std::uint64_t publish_sensors_1khz(int domain, std::uint64_t last, KeepGoing keep_going) {
  poise::dds::DdsOptions o = poise::dds::dds_options_from_env();
  o.domain_id = domain;
  poise::dds::Participant participant(o);
  poise::dds::Publisher<poise::msg::Sensors> pub(participant);
  EXPECT_TRUE(pub.wait_for_matches(1, 20s));
  std::this_thread::sleep_for(200ms);
  auto next = std::chrono::steady_clock::now();
  std::uint64_t tick = 0;
  while (tick < last && keep_going()) {
    pub.publish(sample_of<poise::msg::Sensors>(1, ++tick, 9));
    next += 1ms;
    std::this_thread::sleep_until(next);
  }
  return tick;
}

void publish_sensors_1khz(int domain, std::uint64_t last) {
  publish_sensors_1khz(domain, last, [] { return true; });
  std::this_thread::sleep_for(500ms);  // reliable delivery of the last samples
}

class RecordVendors : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {};

}  // namespace

// Writers of one vendor, the recorder on the other (both directions): every message of every
// topic type is in the file exactly once, and the independent decoder gives back the very field
// values that were published.
TEST_P(RecordVendors, EveryTopicDecodesIndependentlyWithTheValuesPublished) {
  const auto [recorder_vendor, writer_vendor] = GetParam();
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("vendors_" + recorder_vendor + "_" + writer_vendor);
  const fs::path file = dir / "all_types.mcap";
  constexpr std::uint64_t kSamples = 40;
  constexpr std::uint64_t kSeed = 2026;

  RecorderProcess recorder(record_args(recorder_vendor, domain, file, {"--compression", "lz4"}));
  {
    poise::dds::DdsOptions o = poise::dds::dds_options_from_env();
    o.vendor = poise::dds::parse_vendor(writer_vendor);
    o.domain_id = domain;
    poise::dds::Participant participant(o);
    std::vector<std::function<void(std::uint64_t)>> publish;
    std::vector<std::shared_ptr<void>> keep;
    for_each_type([&](auto index) {
      using T = std::tuple_element_t<decltype(index)::value, AllTypes>;
      auto pub = std::make_shared<poise::dds::Publisher<T>>(participant);
      ASSERT_TRUE(pub->wait_for_matches(1, 20s)) << pub->topic_name();
      keep.push_back(pub);
      publish.push_back([pub, i = decltype(index)::value](std::uint64_t k) {
        pub->publish(sample_of<T>(i, k, kSeed));
      });
    });
    std::this_thread::sleep_for(200ms);  // both sides matched (writer side seen above)
    for (std::uint64_t k = 1; k <= kSamples; ++k) {
      for (auto& p : publish)
        p(k);
      std::this_thread::sleep_for(5ms);
    }
    std::this_thread::sleep_for(1s);  // reliable delivery of the last samples
  }
  const auto code = recorder.process.interrupt(20s);
  ASSERT_EQ(code, 0) << recorder.process.output();

  // The independent reader: indexed (summary, chunk indexes, statistics, CRCs) and streaming.
  const fs::path dump = dir / "decoded.jsonl";
  auto [indexed_code, indexed] = check_independently(file, false, dump);
  ASSERT_EQ(indexed_code, 0) << indexed.dump(2);
  EXPECT_TRUE(indexed["complete"].get<bool>());
  auto [stream_code, streamed] = check_independently(file, true);
  ASSERT_EQ(stream_code, 0) << streamed.dump(2);
  EXPECT_EQ(streamed["decoded"], kSamples * std::tuple_size_v<AllTypes>);

  // Values: each decoded message equals the sample published with its tick.
  std::map<std::string, std::map<std::uint64_t, Json>> decoded;  // topic -> tick -> data
  std::map<std::string, int> duplicates;
  std::ifstream in(dump);
  for (std::string line; std::getline(in, line);) {
    const Json m = Json::parse(line);
    const std::string topic = m["topic"];
    const std::uint64_t tick = std::stoull(m["data"]["header"]["tick"].get<std::string>());
    if (!decoded[topic].emplace(tick, m["data"]).second) ++duplicates[topic];
  }
  for_each_type([&](auto index) {
    using T = std::tuple_element_t<decltype(index)::value, AllTypes>;
    const std::string topic(poise::dds::TopicTraits<T>::topic_name);
    EXPECT_EQ(duplicates[topic], 0) << topic;
    ASSERT_EQ(decoded[topic].size(), kSamples)
        << topic << " (recorder " << recorder_vendor << ", writer " << writer_vendor << ")";
    for (std::uint64_t k = 1; k <= kSamples; ++k) {
      const auto d =
          diff_value(sample_of<T>(decltype(index)::value, k, kSeed), decoded[topic][k], "");
      ASSERT_FALSE(d) << topic << " tick " << k << ": " << *d;
    }
  });

  // poise info agrees, and the recorder's loss counters are in the file.
  int info_code = -1;
  const Json info = info_json(file, &info_code);
  EXPECT_EQ(info_code, 0);
  EXPECT_TRUE(info["complete"].get<bool>());
  EXPECT_EQ(info["topics"].size(), std::tuple_size_v<AllTypes>);
  for (const auto& t : info["topics"]) {
    EXPECT_EQ(t["messages"], kSamples) << t["topic"];
    EXPECT_EQ(t["schema_encoding"], "omgidl");
    EXPECT_EQ(t["message_encoding"], "cdr");
  }
  EXPECT_EQ(info["metadata"]["poise_recorder"]["total.dropped"], "0");
  EXPECT_EQ(info["metadata"]["poise_recording"]["dds_vendor"], recorder_vendor);
}

INSTANTIATE_TEST_SUITE_P(Vendors, RecordVendors,
                         ::testing::Values(std::make_tuple("cyclone", "fastdds"),
                                           std::make_tuple("fastdds", "cyclone")),
                         [](const auto& info) {
                           return "recorder_" + std::get<0>(info.param) + "_writer_" +
                                  std::get<1>(info.param);
                         });

// SIGKILL of the recorder during a 1 kHz stream: the file opens in the independent reader in
// streaming mode and holds every tick up to the stated tail (the open chunk: at most 1.5 flush
// intervals = 150 ms at 1 kHz; the test allows 100 ms more for scheduling on a busy machine).
TEST(Record, SigkillCostsAtMostTheOpenChunk) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("sigkill");
  const fs::path file = dir / "killed.mcap";
  RecorderProcess recorder(record_args("cyclone", domain, file));
  // The kill happens inside the stream, at 2.5 s: samples keep flowing until then.
  std::chrono::steady_clock::time_point kill_at{};
  const std::uint64_t last_published = publish_sensors_1khz(domain, ~0ULL, [&] {
    const auto now = std::chrono::steady_clock::now();
    if (kill_at == std::chrono::steady_clock::time_point{}) kill_at = now + 2500ms;
    if (now < kill_at) return true;
    ::kill(recorder.process.pid(), SIGKILL);
    return false;
  });
  recorder.process.wait_for(10s);

  auto [code, report] = check_independently(file, true);
  EXPECT_EQ(code, 0) << report.dump(2);
  EXPECT_FALSE(report["complete"].get<bool>());
  int info_code = 0;
  const Json info = info_json(file, &info_code);
  EXPECT_EQ(info_code, 1) << "an incomplete file is exit status 1";
  EXPECT_FALSE(info["complete"].get<bool>());
  const Json* sensors = find_topic(info, "poise/sensors");
  ASSERT_NE(sensors, nullptr) << info.dump(2);
  EXPECT_EQ(report["topics"]["poise/sensors"]["decoded"], (*sensors)["messages"]);
  EXPECT_EQ((*sensors)["first_tick"], 1);
  EXPECT_EQ((*sensors)["missing_ticks"], 0);
  EXPECT_EQ((*sensors)["duplicate_ticks"], 0);
  const std::uint64_t last_recorded = (*sensors)["last_tick"];
  EXPECT_GE(last_recorded + 250, last_published)
      << "lost " << last_published - last_recorded << " ticks at 1 kHz";
  std::printf("SIGKILL after tick %llu: the file holds ticks 1..%llu (%llu ms lost)\n",
              static_cast<unsigned long long>(last_published),
              static_cast<unsigned long long>(last_recorded),
              static_cast<unsigned long long>(last_published - last_recorded));
}

// Bad input to the verbs: a clear message and a non-zero exit, nothing written over.
TEST(Record, BadInputIsRefusedWithAClearMessage) {
  const fs::path dir = work_dir("bad_input");
  { std::ofstream(dir / "notes.txt") << "not a recording\n"; }
  auto [c1, o1] = run({bin("poise"), "info", (dir / "notes.txt").string()});
  EXPECT_EQ(c1, 2);
  EXPECT_NE(o1.find("not an MCAP file"), std::string::npos) << o1;
  auto [c2, o2] = run({bin("poise"), "replay", (dir / "notes.txt").string()});
  EXPECT_NE(c2, 0);
  EXPECT_NE(o2.find("not an MCAP file"), std::string::npos) << o2;
  auto [c3, o3] = run({bin("poise"), "record", "--domain", "5", "-o", (dir / "x.mcap").string(),
                       "poise/no_such_topic"});
  EXPECT_NE(c3, 0);
  EXPECT_NE(o3.find("unknown topic 'poise/no_such_topic'"), std::string::npos) << o3;
  EXPECT_FALSE(fs::exists(dir / "x.mcap") && fs::file_size(dir / "x.mcap") > 0 && c3 == 0);
  auto [c4, o4] = run({bin("poise"), "record", "--domain", "5", "-o", "/nonexistent/dir/x.mcap",
                       "--duration", "1"});
  EXPECT_NE(c4, 0);
  EXPECT_NE(o4.find("cannot create '/nonexistent/dir/x.mcap'"), std::string::npos) << o4;
}

// A recording is never written over unless asked: `poise record -o FILE` refuses an existing
// FILE (exit 2, the file untouched), `--if-exists next` records to the first free FILE's
// stem.<k>.mcap, `--if-exists overwrite` replaces it; with splitting any split file of the name is
// in the way.
// (Before, the writer truncated whatever was there, and a recorder restarted by `poise launch`
// truncated what it had recorded before its crash.)
TEST(Record, AnExistingRecordingIsNeverWrittenOverUnlessAsked) {
  const fs::path dir = work_dir("if_exists");
  const std::string domain = std::to_string(poise::testing::unique_domain_id());
  const fs::path old = dir / "old.mcap";
  { std::ofstream(old) << "precious"; }
  auto contents = [](const fs::path& f) {
    std::ifstream in(f);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  auto record = [&](const fs::path& out, std::vector<std::string> extra) {
    std::vector<std::string> a{bin("poise"), "record",     "--domain",   domain,
                               "-o",         out.string(), "--duration", "0.2"};
    a.insert(a.end(), extra.begin(), extra.end());
    return run(a);
  };
  auto [c1, o1] = record(old, {});
  EXPECT_EQ(c1, 2) << o1;
  EXPECT_NE(o1.find(old.string() + " exists: a recording is not written over it"),
            std::string::npos)
      << o1;
  EXPECT_EQ(contents(old), "precious");
  for (const char* expected : {"old.1.mcap", "old.2.mcap"}) {
    auto [c, o] = record(old, {"--if-exists", "next"});
    EXPECT_EQ(c, 0) << o;
    EXPECT_NE(o.find("recording to " + (dir / expected).string()), std::string::npos) << o;
    int info_code = -1;
    info_json(dir / expected, &info_code);
    EXPECT_EQ(info_code, 0) << expected << " is a complete recording";
  }
  EXPECT_EQ(contents(old), "precious");
  auto [c2, o2] = record(old, {"--if-exists", "overwrite"});
  EXPECT_EQ(c2, 0) << o2;
  int info_code = -1;
  info_json(old, &info_code);
  EXPECT_EQ(info_code, 0) << "replaced by a complete recording";

  // Split recordings: <stem>_0.mcap, _1, ...: any of them is in the way (named: the lowest).
  const std::vector<std::string> split{"--split-duration", "0.05"};
  auto [c3, o3] = record(dir / "run.mcap", split);
  ASSERT_EQ(c3, 0) << o3;
  ASSERT_TRUE(fs::exists(dir / "run_0.mcap")) << o3;
  const auto first_size = fs::file_size(dir / "run_0.mcap");
  auto [c4, o4] = record(dir / "run.mcap", split);
  EXPECT_EQ(c4, 2) << o4;
  EXPECT_NE(o4.find((dir / "run_0.mcap").string() + " exists"), std::string::npos) << o4;
  EXPECT_EQ(fs::file_size(dir / "run_0.mcap"), first_size);
  auto [c5, o5] = record(dir / "run.mcap", {"--split-duration", "0.05", "--if-exists", "next"});
  EXPECT_EQ(c5, 0) << o5;
  EXPECT_TRUE(fs::exists(dir / "run.1_0.mcap")) << o5;
  EXPECT_EQ(fs::file_size(dir / "run_0.mcap"), first_size);
  // A later split file alone is in the way too (it would stop the recording at that split).
  { std::ofstream(dir / "late_3.mcap") << "precious"; }
  auto [c7, o7] = record(dir / "late.mcap", split);
  EXPECT_EQ(c7, 2) << o7;
  EXPECT_NE(o7.find((dir / "late_3.mcap").string() + " exists"), std::string::npos) << o7;
  EXPECT_EQ(contents(dir / "late_3.mcap"), "precious");

  auto [c6, o6] = record(old, {"--if-exists", "maybe"});
  EXPECT_NE(c6, 0);
  EXPECT_NE(o6.find("maybe not in {refuse,overwrite,next}"), std::string::npos) << o6;
}

namespace {

/// poise/state of a recording, decoded, by tick (the first sample of each tick).
std::map<std::uint64_t, poise::msg::State> states_by_tick(const fs::path& file) {
  std::map<std::uint64_t, poise::msg::State> out;
  std::map<std::uint16_t, std::string> topics;
  const auto& type = poise::dds::TopicTraits<poise::msg::State>::type_support();
  poise::record::ScanHandlers h;
  h.on_channel = [&](const poise::record::ChannelRecord& c) { topics[c.id] = c.topic; };
  h.on_message = [&](const poise::record::MessageView& m) {
    if (topics[m.channel_id] != "poise/state") return true;
    poise::msg::State s;
    char why[256];
    EXPECT_TRUE(type.deserialize(m.data.data(), m.data.size(), &s, why, sizeof(why))) << why;
    out.emplace(s.header().tick(), s);
    return true;
  };
  const auto r = poise::record::scan(file.string(), h);
  EXPECT_TRUE(r.ok() && r.complete) << file << ": " << r.error << r.truncation;
  return out;
}

}  // namespace

// The main use of replay: a recorded run's sensors (and robot description) drive a fresh
// estimator in place of the robot. Same binary, same input: the replayed estimator's poise/state
// equals the recorded one on every tick. In lockstep (each tick sent once the estimator answered
// the previous one on poise/state): timed replay was bit-exact in only 2 of 4 tries on a loaded
// machine (ticks > 50 ms apart, input stale, samples of the following burst overwritten).
// POISE_REPLAY_TRIES=N replays into N fresh estimators in turn (default 1).
TEST(Record, ReplayedSensorsReproduceTheRecordedEstimate) {
  const fs::path dir = work_dir("replay");
  const fs::path original = dir / "push.mcap";
  const int run_domain = poise::testing::unique_domain_id();
  {
    // Mixed vendors (endpoint discovery across vendors takes ~1 s): the run starts only once
    // the recorder and every writer have matched, so the file holds every tick from the first.
    auto [code, out] =
        run({bin("poise"), "run", "forward_push_double_support", "--domain",
             std::to_string(run_domain), "--duration", "2.5", "--dds-sim", "fastdds",
             "--dds-estimator", "fastdds", "--record", original.string(), "-o",
             (dir / "run.json").string(), "--log-dir", (dir / "logs").string()},
            300s);
    ASSERT_EQ(code, 0) << out;
    EXPECT_NE(out.find("recorded: "), std::string::npos) << out;
    EXPECT_NE(out.find("every writer and reader of the run matched"), std::string::npos) << out;
  }
  {
    const Json info = info_json(original);
    const Json* sensors = find_topic(info, "poise/sensors");
    ASSERT_NE(sensors, nullptr);
    const auto first = (*sensors)["first_tick"].get<std::uint64_t>();
    for (const char* t : {"poise/sensors", "poise/ground_truth", "poise/state",
                          "poise/contact_problem", "poise/contact_solution",
                          "poise/joint_command"}) {
      const Json* topic = find_topic(info, t);
      ASSERT_NE(topic, nullptr) << t;
      EXPECT_EQ((*topic)["first_tick"].get<std::uint64_t>(), first) << t << " misses the start";
      EXPECT_EQ((*topic)["missing_ticks"].get<std::uint64_t>(), 0u) << t;
    }
    EXPECT_EQ(info["metadata"]["poise_recorder"]["total.tick_gaps"], "0");
  }
  auto [check_code, report] = check_independently(original, false);
  ASSERT_EQ(check_code, 0) << report.dump(2);
  for (const char* t : {"poise/robot_description", "poise/sensors", "poise/ground_truth",
                        "poise/state", "poise/contact_problem", "poise/contact_solution",
                        "poise/joint_command", "poise/diagnostics"})
    EXPECT_GT(report["topics"][t]["decoded"].get<int>(), 0) << t << " not recorded";

  const int tries = std::getenv("POISE_REPLAY_TRIES") ? std::atoi(std::getenv("POISE_REPLAY_TRIES")) : 1;
  int exact = 0;
  for (int attempt = 1; attempt <= tries; ++attempt) {
  SCOPED_TRACE("try " + std::to_string(attempt));
  const fs::path replayed = dir / ("replayed_state_" + std::to_string(attempt) + ".mcap");
  // A second domain: a fresh estimator fed by the replay, its output recorded.
  const int replay_domain = poise::dds::claim_free_domain();
  const std::string d = std::to_string(replay_domain);
  // The recorder first; the estimator takes no sensors before its state writer has matched it
  // (--output-readers 1), and the replay starts once the recorder has matched that writer.
  RecorderProcess recorder(record_args("cyclone", replay_domain, replayed, {"poise/state"}));
  ChildProcess estimator(
      {bin("poise-estimator"), "--dds", "fastdds", "--domain", d, "--robot",
       std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/robot.yaml",
       "--output-readers", "1"},
      {}, false, true);
  {
    // The estimator creates its state writer once it has the robot description.
    auto [code, out] = run({bin("poise"), "replay", original.string(), "--domain", d, "--topics",
                            "poise/robot_description", "--wait-readers", "1", "--wait", "30"},
                           120s);
    ASSERT_EQ(code, 0) << out;
  }
  ASSERT_TRUE(recorder.process.wait_for_output("poise/state: 1 writer", 30s))
      << recorder.process.output();
  ASSERT_TRUE(estimator.wait_for_output("output readers matched", 30s)) << estimator.output();
  {
    // On the recorded timing, with the replay stopped for 300 ms in the middle (what a loaded
    // machine does to it): without --lockstep, the estimator's input goes stale and it misses
    // ~200 ticks of the burst that follows (measured: 209 and 218 ticks without a state).
    ChildProcess replay({bin("poise"), "replay", original.string(), "--domain", d, "--topics",
                         "poise/sensors", "--wait-readers", "1", "--wait", "30", "--lockstep",
                         "--rate", "1", "--linger", "1"},
                        {}, false, true);
    ASSERT_TRUE(replay.wait_for_output("lockstep: the replayed component", 30s)) << replay.output();
    std::this_thread::sleep_for(1200ms);
    ::kill(replay.pid(), SIGSTOP);
    std::this_thread::sleep_for(300ms);
    ::kill(replay.pid(), SIGCONT);
    const auto code = replay.wait_for(300s);
    ASSERT_TRUE(code.has_value()) << replay.output();
    ASSERT_EQ(*code, 0) << replay.output();
    EXPECT_NE(replay.output().find("each answered on poise/state"), std::string::npos)
        << replay.output();
  }
  ASSERT_EQ(recorder.process.interrupt(20s), 0) << recorder.process.output();
  estimator.interrupt(10s);

  const auto want = states_by_tick(original);
  const auto got = states_by_tick(replayed);
  ASSERT_GT(want.size(), 2000u);
  EXPECT_EQ(got.size(), want.size());
  std::size_t compared = 0;
  double worst = 0;
  for (const auto& [tick, w] : want) {
    const auto it = got.find(tick);
    ASSERT_NE(it, got.end()) << "tick " << tick << " has no replayed state";
    const auto& g = it->second;
    for (int i = 0; i < 3; ++i) {
      worst = std::max(worst, std::abs(g.com_W()[i] - w.com_W()[i]));
      worst = std::max(worst,
                       std::abs(g.base_velocity_W().linear()[i] - w.base_velocity_W().linear()[i]));
    }
    const auto d2 = poise::reflect::first_difference(w, g);
    if (d2) ADD_FAILURE() << "tick " << tick << ": " << *d2;
    ++compared;
    if (::testing::Test::HasFailure()) break;
  }
  std::printf("replayed %zu ticks: largest CoM / base velocity difference %.3g\n", compared, worst);
  if (::testing::Test::HasFailure()) break;
  ++exact;
  }
  std::printf("lockstep replay bit-exact in %d of %d tries\n", exact, tries);
}

// A replay whose component does not answer every tick fails (exit 1) and says so; before, a
// replay always said "published N samples", exit 0. --lockstep with no component, and with a
// component killed during the replay; a timed replay checked with --answer, stopped for 300 ms
// in the middle (the estimator's input goes stale, and it misses ticks of the burst after).
TEST(Record, AReplayFailsWhenTheComponentDoesNotAnswerEveryTick) {
  const fs::path dir = work_dir("lockstep_fail");
  const fs::path original = dir / "standing.mcap";
  const int run_domain = poise::testing::unique_domain_id();
  {
    auto [code, out] = run({bin("poise"), "run", "standing", "--domain", std::to_string(run_domain),
                            "--duration", "2", "--record", original.string(), "-o",
                            (dir / "run.json").string(), "--log-dir", (dir / "logs").string()},
                           300s);
    ASSERT_EQ(code, 0) << out;
  }
  const int replay_domain = poise::dds::claim_free_domain();
  const std::string d = std::to_string(replay_domain);
  {
    SCOPED_TRACE("no component");
    const auto t0 = std::chrono::steady_clock::now();
    auto [code, out] = run({bin("poise"), "replay", original.string(), "--domain", d, "--topics",
                            "poise/robot_description", "poise/sensors", "--lockstep", "--wait",
                            "3", "--linger", "0"},
                           60s);
    EXPECT_EQ(code, 1) << out;
    EXPECT_NE(out.find("no writer of poise/state after 3 s: the replayed component is not "
                       "running on domain " + d),
              std::string::npos)
        << out;
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 30s);
  }
  {
    SCOPED_TRACE("component killed");
    ChildProcess estimator(
        {bin("poise-estimator"), "--dds", "cyclone", "--domain", d, "--robot",
         std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/robot.yaml",
         "--output-readers", "1"},  // the replay's reader of poise/state
        {}, false, true);
    {
      auto [code, out] = run({bin("poise"), "replay", original.string(), "--domain", d,
                              "--topics", "poise/robot_description", "--wait-readers", "1",
                              "--wait", "30"},
                             120s);
      ASSERT_EQ(code, 0) << out;
    }
    // On the recorded timing (about 2 s), so that the estimator dies in the middle.
    ChildProcess replay({bin("poise"), "replay", original.string(), "--domain", d, "--topics",
                         "poise/sensors", "--wait-readers", "1", "--wait", "30", "--lockstep",
                         "--rate", "1", "--answer-timeout", "2", "--linger", "0"},
                        {}, false, true);
    ASSERT_TRUE(estimator.wait_for_output("output readers matched", 30s)) << estimator.output();
    std::this_thread::sleep_for(1s);
    ASSERT_EQ(::kill(estimator.pid(), SIGKILL), 0);
    const auto code = replay.wait_for(60s);
    ASSERT_TRUE(code.has_value()) << replay.output();
    EXPECT_EQ(*code, 1) << replay.output();
    const std::string out = replay.output();
    EXPECT_NE(out.find("--lockstep: no poise/state for tick "), std::string::npos) << out;
    EXPECT_NE(out.find("the replayed component stopped answering"), std::string::npos) << out;
    EXPECT_EQ(out.find("each answered"), std::string::npos) << out;
    std::printf("killed estimator: %s\n", out.substr(out.find("--lockstep: no")).c_str());
  }
  {
    SCOPED_TRACE("timed replay, stalled");
    const std::string d2 = std::to_string(poise::dds::claim_free_domain());
    // Fast DDS (the replay on Cyclone): its keep-last-1 reader loses samples of the burst.
    ChildProcess estimator(
        {bin("poise-estimator"), "--dds", "fastdds", "--domain", d2, "--robot",
         std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/robot.yaml",
         "--output-readers", "1"},
        {}, false, true);
    {
      auto [code, out] = run({bin("poise"), "replay", original.string(), "--domain", d2,
                              "--topics", "poise/robot_description", "--wait-readers", "1",
                              "--wait", "30"},
                             120s);
      ASSERT_EQ(code, 0) << out;
    }
    ChildProcess replay({bin("poise"), "replay", original.string(), "--domain", d2, "--topics",
                         "poise/sensors", "--wait-readers", "1", "--wait", "30", "--answer",
                         "poise/state", "--rate", "1", "--linger", "0"},
                        {}, false, true);
    ASSERT_TRUE(estimator.wait_for_output("output readers matched", 30s)) << estimator.output();
    std::this_thread::sleep_for(800ms);
    ::kill(replay.pid(), SIGSTOP);
    std::this_thread::sleep_for(300ms);
    ::kill(replay.pid(), SIGCONT);
    const auto code = replay.wait_for(60s);
    ASSERT_TRUE(code.has_value()) << replay.output();
    const std::string out = replay.output();
    EXPECT_EQ(*code, 1) << out << estimator.interrupt(10s).value_or(-1) << estimator.output();
    EXPECT_NE(out.find("ticks sent got no poise/state"), std::string::npos) << out;
    estimator.interrupt(10s);
    if (out.find("error: ") != std::string::npos)
      std::printf("stalled timed replay: %s", out.substr(out.find("error: ")).c_str());
  }
}

// Ticks a writer skips on a per-tick topic are counted live, per writer, and stored as metadata:
// the loss that neither the recorder's queue nor DDS can see (a reliable keep-last writer that
// overwrote a sample before a lagging reader took it) shows there. Two writers on one topic, one
// with 5 + 1 skipped ticks and a repeat, the other with 3 skipped after a restart at tick 1.
TEST(Record, TicksSkippedByEachWriterAreCountedLive) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path file = work_dir("tick_gaps") / "gaps.mcap";
  RecorderProcess recorder(record_args("cyclone", domain, file));
  std::vector<std::uint64_t> ticks_a, ticks_b;
  for (std::uint64_t k = 1; k <= 100; ++k)
    if (k < 50 || k > 54) ticks_a.push_back(k);  // 50..54 skipped: 5
  ticks_a.push_back(100);                          // a repeat: not a gap
  ticks_a.push_back(102);                          // 101 skipped: 1
  for (std::uint64_t k = 500; k <= 520; ++k) ticks_b.push_back(k);
  for (std::uint64_t k = 1; k <= 20; ++k)  // restarted at 1 (not a gap), then 8..10 skipped: 3
    if (k < 8 || k > 10) ticks_b.push_back(k);
  {
    poise::dds::DdsOptions o = poise::dds::dds_options_from_env();
    o.domain_id = domain;
    o.vendor = poise::dds::Vendor::fastdds;
    poise::dds::Participant participant(o);
    poise::dds::Publisher<poise::msg::Sensors> a(participant), b(participant);
    ASSERT_TRUE(a.wait_for_matches(1, 20s));
    ASSERT_TRUE(b.wait_for_matches(1, 20s));
    ASSERT_TRUE(recorder.process.wait_for_output("poise/sensors: 2 writers", 20s))
        << recorder.process.output();
    for (std::size_t i = 0; i < std::max(ticks_a.size(), ticks_b.size()); ++i) {
      if (i < ticks_a.size()) a.publish(sample_of<poise::msg::Sensors>(1, ticks_a[i], 9));
      if (i < ticks_b.size()) b.publish(sample_of<poise::msg::Sensors>(2, ticks_b[i], 9));
      std::this_thread::sleep_for(1ms);
    }
    EXPECT_TRUE(a.wait_for_acknowledgments(10s));
    EXPECT_TRUE(b.wait_for_acknowledgments(10s));
  }
  ASSERT_EQ(recorder.process.interrupt(20s), 0) << recorder.process.output();
  EXPECT_NE(recorder.process.output().find("9 ticks skipped by writers"), std::string::npos)
      << recorder.process.output();
  const Json info = info_json(file);
  const auto& m = info["metadata"]["poise_recorder"];
  EXPECT_EQ(m["poise/sensors.tick_gaps"], "9") << m.dump(2);
  EXPECT_EQ(m["total.tick_gaps"], "9") << m.dump(2);
  EXPECT_EQ(m["poise/sensors.received"], std::to_string(ticks_a.size() + ticks_b.size()));
}

// A recorder that stops taking samples (SIGSTOP: the extreme of a starved recorder) must never
// suspend the robot's writers, although they now keep 32 unacknowledged samples for it (Cyclone
// suspends a reliable writer past its WHC high-water mark, and a suspended write fails after the
// 1 s max_blocking_time): every one of 300 writes at 1 kHz succeeds. Once the recorder runs
// again it has every sample (buffered by the kernel, or resent from the writer's history), and
// whatever it had not would be counted as tick gaps.
TEST(Record, AStoppedRecorderNeverSuspendsAWriter) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path file = work_dir("stopped") / "stopped.mcap";
  RecorderProcess recorder(record_args("cyclone", domain, file, {"poise/sensors"}));
  std::uint64_t failed = 0;
  constexpr std::uint64_t kTicks = 300;
  {
    poise::dds::DdsOptions o = poise::dds::dds_options_from_env();
    o.domain_id = domain;
    o.vendor = poise::dds::Vendor::cyclone;
    poise::dds::Participant participant(o);
    poise::dds::Publisher<poise::msg::Sensors> pub(participant);
    ASSERT_TRUE(pub.wait_for_matches(1, 20s));
    ASSERT_TRUE(recorder.process.wait_for_output("poise/sensors: 1 writer", 20s))
        << recorder.process.output();
    pub.publish(sample_of<poise::msg::Sensors>(1, 1, 9));
    ASSERT_TRUE(pub.wait_for_acknowledgments(10s));
    ASSERT_EQ(::kill(recorder.process.pid(), SIGSTOP), 0);
    for (std::uint64_t k = 2; k <= kTicks; ++k) {
      if (!pub.publish(sample_of<poise::msg::Sensors>(1, k, 9))) ++failed;
      std::this_thread::sleep_for(1ms);
    }
    ::kill(recorder.process.pid(), SIGCONT);
    EXPECT_TRUE(pub.wait_for_acknowledgments(10s));
  }
  EXPECT_EQ(failed, 0u) << "writes suspended by a stopped reader";
  ASSERT_EQ(recorder.process.interrupt(20s), 0) << recorder.process.output();
  const Json info = info_json(file);
  const Json* sensors = find_topic(info, "poise/sensors");
  ASSERT_NE(sensors, nullptr);
  const auto messages = (*sensors)["messages"].get<std::uint64_t>();
  const auto gaps = std::stoull(info["metadata"]["poise_recorder"]["poise/sensors.tick_gaps"]
                                    .get<std::string>());
  // At least tick 1 and the writer's last 32; the rest in the file or counted.
  EXPECT_GE(messages, 1u + poise::dds::Qos::kControlWriterDepth);
  EXPECT_EQ(messages + gaps, kTicks) << info.dump(2);
  std::printf("stopped recorder: %llu of %llu samples in the file, %llu counted as tick gaps\n",
              static_cast<unsigned long long>(messages), static_cast<unsigned long long>(kTicks),
              static_cast<unsigned long long>(gaps));
}

// --split-duration: a series of complete files that together hold every tick once.
TEST(Record, SplitFilesAreEachCompleteAndTogetherHoldEveryTick) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("split");
  RecorderProcess recorder(record_args("cyclone", domain, dir / "run.mcap",
                                       {"--split-duration", "1", "--compression", "none"}));
  publish_sensors_1khz(domain, 2600);
  ASSERT_EQ(recorder.process.interrupt(20s), 0) << recorder.process.output();
  std::vector<fs::path> files;
  for (int k = 0; fs::exists(dir / ("run_" + std::to_string(k) + ".mcap")); ++k)
    files.push_back(dir / ("run_" + std::to_string(k) + ".mcap"));
  ASSERT_GE(files.size(), 3u) << recorder.process.output();
  std::uint64_t next_tick = 1;
  for (const auto& f : files) {
    auto [code, report] = check_independently(f, false);
    EXPECT_EQ(code, 0) << f << ": " << report.dump(2);
    const Json info = info_json(f);
    EXPECT_TRUE(info["complete"].get<bool>()) << f;
    const Json* s = find_topic(info, "poise/sensors");
    if (!s) continue;  // a last file opened after the stream ended
    EXPECT_EQ((*s)["first_tick"], next_tick) << f;
    EXPECT_EQ((*s)["missing_ticks"], 0) << f;
    next_tick = (*s)["last_tick"].get<std::uint64_t>() + 1;
  }
  EXPECT_EQ(next_tick, 2601u);
}

// A full disk (here: a file size limit, which fails write() the same way): the recorder stops
// with a clear error naming the file and a non-zero exit, what it wrote stays readable, and its
// summary counts what is in the file: not the samples of the chunk whose write failed (before,
// it counted them as written: 5667 written against 5063 in the file).
TEST(Record, AFullDiskStopsTheRecorderWithAClearErrorAndKeepsTheFile) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("full_disk");
  const fs::path file = dir / "full.mcap";
  std::vector<std::string> args{"/usr/bin/prlimit", "--fsize=1000000"};
  const auto rec = record_args("cyclone", domain, file, {"--compression", "none"});
  args.insert(args.end(), rec.begin(), rec.end());
  RecorderProcess recorder(args);
  publish_sensors_1khz(domain, 1500);
  const auto code = recorder.process.wait_for(20s);
  ASSERT_TRUE(code.has_value()) << "the recorder went on past a full disk";
  EXPECT_EQ(*code, 1);
  const std::string out = recorder.process.output();
  EXPECT_NE(out.find("File too large"), std::string::npos) << out;
  EXPECT_NE(out.find("error: writing '" + file.string() + "' failed"), std::string::npos) << out;
  auto [check_code, report] = check_independently(file, true);
  EXPECT_EQ(check_code, 0) << report.dump(2);
  EXPECT_FALSE(report["complete"].get<bool>());
  int info_code = 0;
  const Json info = info_json(file, &info_code);
  EXPECT_EQ(info_code, 1) << "poise info must say the file is incomplete";
  EXPECT_FALSE(info["complete"].get<bool>());
  EXPECT_EQ(info["bytes_read"], info["file_size"]) << "the file ends inside a record";
  const Json* s = find_topic(info, "poise/sensors");
  ASSERT_NE(s, nullptr);
  const auto in_file = (*s)["messages"].get<std::uint64_t>();
  EXPECT_GT(in_file, 300u);
  EXPECT_EQ((*s)["first_tick"], 1);
  EXPECT_EQ((*s)["missing_ticks"], 0);
  // The summary's row of poise/sensors and its total: what is in the file.
  std::istringstream lines(out);
  std::string line;
  std::uint64_t received = 0, written = 0, dropped = 0, total = 0;
  bool row = false, total_line = false;
  while (std::getline(lines, line)) {
    std::istringstream l(line);
    std::string topic, type;
    if (line.rfind("poise/sensors ", 0) == 0 && (l >> topic >> type >> received >> written >> dropped))
      row = true;
    if (line.find(" messages, ") != std::string::npos && line.find(file.string()) != std::string::npos &&
        (std::istringstream(line) >> total))
      total_line = true;
  }
  ASSERT_TRUE(row && total_line) << out;
  EXPECT_EQ(written, in_file) << "the summary counts samples that are not in the file\n" << out;
  EXPECT_EQ(total, in_file) << out;
  EXPECT_EQ(received, written + dropped) << out;
  EXPECT_GT(dropped, 0u) << out;
  std::printf("full disk: %llu samples received, %llu in the file (summary: %llu written, %llu "
              "dropped)\n",
              static_cast<unsigned long long>(received), static_cast<unsigned long long>(in_file),
              static_cast<unsigned long long>(written), static_cast<unsigned long long>(dropped));
}

// A recorder started after the stack: the file begins at a late tick, and `poise info` says how
// many ticks of the run are missing before it, against the run's first tick that poise-sim puts
// in the latched robot description (which the late recorder still receives). Before, info said
// "0 missing". A real simulator in real time (publishing sensors at 1 kHz with nobody
// answering: the safety layer holds the robot), the recorder started ~1.5 s later.
TEST(Record, ARecordingStartedLateSaysHowManyTicksItMissedAtTheStart) {
  const int domain = poise::testing::unique_domain_id();
  const std::string d = std::to_string(domain);
  const fs::path file = work_dir("late") / "late.mcap";
  ChildProcess sim({bin("poise-sim"), "--dds", "cyclone", "--domain", d,
                    std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/standing.yaml",
                    "--realtime", "--duration", "30", "--wait-readers", "0"},
                   {}, false, true);
  ASSERT_TRUE(sim.wait_for_output("real time", 30s)) << sim.output();
  std::this_thread::sleep_for(1500ms);
  RecorderProcess recorder(
      record_args("cyclone", domain, file, {"poise/robot_description", "poise/sensors"}));
  ASSERT_TRUE(recorder.process.wait_for_output("poise/sensors: 1 writer", 20s))
      << recorder.process.output();
  std::this_thread::sleep_for(1s);
  ASSERT_EQ(recorder.process.interrupt(20s), 0) << recorder.process.output();
  sim.interrupt(10s);
  const Json info = info_json(file);
  const Json* sensors = find_topic(info, "poise/sensors");
  ASSERT_NE(sensors, nullptr) << info.dump(2);
  ASSERT_NE(find_topic(info, "poise/robot_description"), nullptr) << info.dump(2);
  const auto first = (*sensors)["first_tick"].get<std::uint64_t>();
  EXPECT_GT(first, 500u) << "the recorder did not start late: " << sim.output();
  ASSERT_TRUE(info.contains("run_first_tick")) << info.dump(2);
  EXPECT_EQ(info["run_first_tick"], 10) << "the simulator's k0 (10 settle ticks)";
  EXPECT_EQ(info["run_first_tick_source"], "poise/robot_description");
  EXPECT_EQ((*sensors)["missing_at_start"], first - 10) << info.dump(2);
  const auto [code, text] = run({bin("poise"), "info", file.string()}, 60s, false);
  EXPECT_EQ(code, 0) << text;
  const std::string want = "first tick " + std::to_string(first) +
                           " on poise/sensors, expected 10: " + std::to_string(first - 10) +
                           " ticks missing at the start";
  EXPECT_NE(text.find(want), std::string::npos) << text;
  std::printf("late recorder: poise/sensors from tick %llu, %llu ticks missing at the start\n",
              static_cast<unsigned long long>(first), static_cast<unsigned long long>(first - 10));
}

// A file with a schema Poise does not know on a Poise topic name: shown by info, refused by
// replay with the reason.
TEST(Record, AForeignSchemaIsShownAndNotReplayed) {
  const fs::path dir = work_dir("foreign");
  const fs::path file = dir / "foreign.mcap";
  {
    poise::record::McapWriter w(file.string());
    const auto s = w.add_schema("sensor_msgs/msg/Imu", "ros2msg", "float64 x");
    const auto ch = w.add_channel(s, "poise/sensors", "cdr");
    const std::uint8_t bytes[] = {0, 1, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8};
    for (int i = 1; i <= 10; ++i)
      w.write_message(ch, i, i * 1000000ULL, i * 1000000ULL, bytes, sizeof(bytes));
    ASSERT_TRUE(w.close());
  }
  const Json info = info_json(file);
  const Json* s = find_topic(info, "poise/sensors");
  ASSERT_NE(s, nullptr);
  EXPECT_EQ((*s)["schema"], "sensor_msgs/msg/Imu");
  EXPECT_EQ((*s)["messages"], 10);
  auto [code, out] = run({bin("poise"), "replay", file.string(), "--domain", "5"});
  EXPECT_EQ(code, 2);
  EXPECT_NE(out.find("recorded with type 'sensor_msgs/msg/Imu'"), std::string::npos) << out;
}

// The loss test of the issue: 10 s of the whole distributed stack at 1 kHz (real time), recorded
// with `poise run --record`. Every sensor tick the simulator published is in the file exactly
// once, and so is every tick of the other per-tick topics; the recorder dropped nothing.
TEST(Record, TenSecondsOfTheStackInRealTimeAreRecordedTickByTick) {
  const fs::path dir = work_dir("realtime");
  const fs::path file = dir / "standing.mcap";
  auto [code, out] =
      run({bin("poise"), "run", "standing", "--realtime", "--duration", "10", "--domain",
           std::to_string(poise::testing::unique_domain_id()), "--record", file.string(), "-o",
           (dir / "run.json").string(), "--log-dir", (dir / "logs").string()},
          200s);
  ASSERT_TRUE(code == 0 || code == 1) << out;  // the verdict is not this test's business
  const Json result = Json::parse(std::ifstream(dir / "run.json"));
  EXPECT_TRUE(result["recording_ok"].get<bool>()) << out;
  const Json info = info_json(file);
  ASSERT_TRUE(info["complete"].get<bool>()) << info.dump(2);
  const Json* sensors = find_topic(info, "poise/sensors");
  ASSERT_NE(sensors, nullptr);
  // Each node counts the ticks it handled (its summary): the file holds exactly one sample of
  // each. A tick a node skipped (real time on a busy machine) is missing from its own output,
  // not from the recording.
  auto node_ticks = [&](const std::string& node) { return summary_ticks(dir / "logs", node); };
  const std::uint64_t sim_ticks = node_ticks("sim");
  EXPECT_GE(sim_ticks, 9900u);
  // The real-time start (`poise-sim --start-when-answered`) sends the start frame k0 again every
  // 100 ms until the loop answers it: those copies, and the loop's answers to them, are in the
  // file as sent (usually none: the loop answers within 100 ms).
  const Json sim_summary = Json::parse(std::ifstream(dir / "logs" / "sim.summary.json"));
  const std::uint64_t repeats = sim_summary.value("start_repeats", std::uint64_t{0});
  EXPECT_EQ((*sensors)["missing_ticks"], 0);
  EXPECT_EQ((*sensors)["duplicate_ticks"].get<std::uint64_t>(), repeats);
  for (const auto& [topic, node] : kPerTickTopicWriters) {
    const Json* s = find_topic(info, topic);
    ASSERT_NE(s, nullptr) << topic;
    EXPECT_TRUE((*s)["per_tick"].get<bool>()) << topic;
    // The simulator publishes its settled start frame k0 before its first step (the ground
    // truth of k0 only to the readers matched by then).
    const std::uint64_t published = node_ticks(node) + (node == "sim" ? 1 : 0);
    const std::uint64_t count = (*s)["messages"].get<std::uint64_t>();
    EXPECT_LE(count, published + repeats) << topic;
    const std::uint64_t distinct = (*s)["distinct_ticks"].get<std::uint64_t>();
    EXPECT_LE(distinct, count) << topic;
    EXPECT_LE(count - std::min(distinct, count), repeats) << topic << ": duplicates";
    // Writers keep 32 samples for a lagging reader (Qos::control()): nothing is missed. And a
    // miss could never be silent: the recorder counts it live as a tick gap of the writer
    // (the node's own skipped ticks are not in `published`, so they do not count here).
    const std::uint64_t missed = published - std::min(distinct + repeats, published);
    EXPECT_EQ(missed, 0u) << topic << ": " << missed << " of " << published;
    const std::string gaps = info["metadata"]["poise_recorder"].value(topic + ".tick_gaps", "?");
    ASSERT_NE(gaps, "?") << topic;
    EXPECT_GE(std::stoull(gaps) + (node == "sim" ? 1 : 0), missed) << topic << " lost silently";
    EXPECT_EQ((*s)["sequence_gaps"], 0) << topic;
  }
  EXPECT_EQ(info["metadata"]["poise_recorder"]["total.dropped"], "0");
  EXPECT_EQ(info["metadata"]["poise_recorder"]["total.vendor_lost"], "0");
  auto [check_code, report] = check_independently(file, false);
  EXPECT_EQ(check_code, 0) << report.dump(2);
  std::printf("recorder tick gaps (ticks the nodes skipped): %s\n",
              info["metadata"]["poise_recorder"]["total.tick_gaps"].dump().c_str());
  std::printf("10 s real time: %s messages, sensors ticks %s..%s, file %.1f MB\n",
              info["messages"].dump().c_str(), (*sensors)["first_tick"].dump().c_str(),
              (*sensors)["last_tick"].dump().c_str(), info["file_size"].get<double>() / 1e6);
}

// ---- passive capture (`poise record --passive`) ---------------------------------------------

namespace {

/// Per topic, the samples of a file in the order they were written: (publish time, bytes).
std::map<std::string, std::vector<std::pair<std::uint64_t, std::vector<std::uint8_t>>>>
samples_by_topic(const fs::path& file) {
  std::map<std::uint16_t, std::string> topic_of;
  std::map<std::string, std::vector<std::pair<std::uint64_t, std::vector<std::uint8_t>>>> out;
  poise::record::ScanHandlers h;
  h.on_channel = [&](const poise::record::ChannelRecord& c) { topic_of[c.id] = c.topic; };
  h.on_message = [&](const poise::record::MessageView& m) {
    out[topic_of[m.channel_id]].emplace_back(
        m.publish_time, std::vector<std::uint8_t>(m.data.begin(), m.data.end()));
    return true;
  };
  const auto r = poise::record::scan(file.string(), h);
  EXPECT_TRUE(r.ok()) << file << ": " << r.error;
  return out;
}

/// Whether this process may open a packet socket (CAP_NET_RAW), as `poise record --passive` does.
bool can_capture() {
  const int fd = ::socket(AF_PACKET, SOCK_DGRAM | SOCK_CLOEXEC, htons(ETH_P_IP));
  if (fd < 0) return false;
  ::close(fd);
  return true;
}

// The passive recorder is no reader of the loop's topics: it takes the samples out of the UDP
// datagrams the loop sends anyway (RTPS DATA and DATA_FRAG, announced by SEDP). Checked against
// a subscribing recorder on the same run, mixed vendors (the simulator on Fast DDS, the rest on
// Cyclone, which fragments samples above 1344 bytes): every topic, the same samples, byte for
// byte, with the same source timestamps; and the independent reader decodes the file.
TEST(Record, PassiveCaptureHoldsWhatASubscribingRecorderHolds) {
  if (!can_capture()) GTEST_SKIP() << "no CAP_NET_RAW: passive capture needs root or the capability";
  const fs::path dir = work_dir("passive");
  const int domain = poise::testing::unique_domain_id();
  const fs::path passive = dir / "passive.mcap", subscribing = dir / "subscribing.mcap";
  ChildProcess cap({bin("poise"), "record", "--passive", "--domain", std::to_string(domain), "-o",
                    passive.string(), "--progress", "0", "--duration", "100"},
                   {}, false, true);
  ASSERT_TRUE(cap.wait_for_output("poise record: passive capture on lo", 20s)) << cap.output();
  // The subscribing recorder of `poise run --record`: the run starts once it has matched every
  // writer, so it holds the whole run; the passive one captures from before the run.
  auto [code, out] =
      run({bin("poise"), "run", "standing", "--duration", "2", "--domain", std::to_string(domain),
           "--dds-sim", "fastdds", "--record", subscribing.string(), "-o",
           (dir / "run.json").string()},
          120s);
  EXPECT_EQ(code, 0) << out;
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(cap.interrupt(10s).value_or(-1), 0) << cap.output();

  const auto a = samples_by_topic(passive), b = samples_by_topic(subscribing);
  for (const char* topic : {"poise/robot_description", "poise/sensors", "poise/ground_truth",
                            "poise/state", "poise/contact_problem", "poise/contact_solution",
                            "poise/joint_command"}) {
    ASSERT_TRUE(a.count(topic) && b.count(topic)) << topic;
    const auto& pa = a.at(topic);
    const auto& pb = b.at(topic);
    EXPECT_GE(pb.size(), std::string(topic) == "poise/robot_description" ? 1u : 2000u)
        << topic;  // 2 s at 1 kHz
    ASSERT_EQ(pa.size(), pb.size()) << topic;
    std::size_t bytes_differ = 0, time_differ = 0;
    for (std::size_t i = 0; i < pa.size(); ++i) {
      if (pa[i].second != pb[i].second) ++bytes_differ;
      // INFO_TS carries 2^-32 s fractions: the vendors round them to ns their own way.
      const auto dt = static_cast<std::int64_t>(pa[i].first - pb[i].first);
      if (std::llabs(dt) > 1) ++time_differ;
    }
    EXPECT_EQ(bytes_differ, 0u) << topic;
    EXPECT_EQ(time_differ, 0u) << topic;
  }
  // The sensors samples (Fast DDS, one datagram) and the state (Cyclone, fragmented) are the
  // biggest; diagnostics come from four writers.
  EXPECT_GT(a.at("poise/state").front().second.size(), 1344u);
  const Json info = info_json(passive);
  ASSERT_TRUE(info["complete"].get<bool>()) << info.dump(2);
  EXPECT_EQ(info["metadata"]["poise_recording"]["capture"], "passive:lo");
  EXPECT_EQ(info["metadata"]["poise_recorder"]["total.vendor_lost"], "0") << info.dump(2);
  EXPECT_EQ(info["metadata"]["poise_recorder"]["capture.kernel_drops"], "0");
  EXPECT_EQ(info["metadata"]["poise_recorder"]["capture.malformed"], "0");
  EXPECT_NE(info["metadata"]["poise_recorder"]["capture.duplicates"], "0")
      << "each sample reaches its reader and the subscribing recorder: two copies on the wire";
  auto [check_code, report] = check_independently(passive, false);
  EXPECT_EQ(check_code, 0) << report.dump(2);
}

TEST(Record, PassiveCaptureRefusesAnUnknownInterface) {
  const fs::path dir = work_dir("passive_bad");
  auto [code, out] = run({bin("poise"), "record", "--passive", "--interface", "nosuchif0",
                          "--domain", "3", "-o", (dir / "x.mcap").string()},
                         30s);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("no network interface 'nosuchif0'"), std::string::npos) << out;
}

}  // namespace

// `poise run --record --passive`: the recording a user gets without slowing the loop. The
// passive recorder starts first, holds DDS readers of the ground truth and the diagnostics only
// (nothing else reads them; a writer sends only to matched readers), the nodes wait for their
// consumer alone, and the file holds every per-tick topic from the first tick, each tick exactly
// once (one copy per writer and sequence number out of the datagrams), decoded independently.
TEST(Record, RunRecordPassiveHoldsEveryTickOfEveryPerTickTopicOnce) {
  if (!can_capture()) GTEST_SKIP() << "no CAP_NET_RAW: passive capture needs root or the capability";
  const fs::path dir = work_dir("run_passive");
  const fs::path file = dir / "push.mcap";
  auto [code, out] =
      run({bin("poise"), "run", "forward_push_double_support", "--domain",
           std::to_string(poise::testing::unique_domain_id()), "--record", file.string(),
           "--passive", "-o", (dir / "run.json").string(), "--log-dir", (dir / "logs").string()},
          300s);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("(passive capture on lo)"), std::string::npos) << out;
  const Json result = Json::parse(std::ifstream(dir / "run.json"));
  EXPECT_TRUE(result["recording_ok"].get<bool>()) << out;
  // The recorder had no reader of the loop's topics: its readers are the passive ones.
  {
    std::ifstream err(dir / "logs" / "recorder.err");
    const std::string text((std::istreambuf_iterator<char>(err)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("poise record: passive readers (their writers send to them): "
                        "poise/ground_truth, poise/diagnostics"),
              std::string::npos)
        << text;
  }
  const Json info = info_json(file);
  ASSERT_TRUE(info["complete"].get<bool>()) << info.dump(2);
  EXPECT_EQ(info["metadata"]["poise_recording"]["capture"], "passive:lo");
  auto node_ticks = [&](const std::string& node) { return summary_ticks(dir / "logs", node); };
  const std::uint64_t sim_ticks = node_ticks("sim");
  EXPECT_GE(sim_ticks, 3900u);  // 4 s at 1 kHz, lockstep
  const Json* sensors = find_topic(info, "poise/sensors");
  ASSERT_NE(sensors, nullptr);
  const std::uint64_t first = (*sensors)["first_tick"].get<std::uint64_t>();
  for (const auto& [topic, node] : kPerTickTopicWriters) {
    const Json* s = find_topic(info, topic);
    ASSERT_NE(s, nullptr) << topic << " is not in the file";
    EXPECT_TRUE((*s)["per_tick"].get<bool>()) << topic;
    // Lockstep: every node handles every tick the simulator published.
    EXPECT_EQ(node_ticks(node), sim_ticks) << node;
    EXPECT_EQ((*s)["messages"].get<std::uint64_t>(), sim_ticks) << topic;
    EXPECT_EQ((*s)["distinct_ticks"].get<std::uint64_t>(), sim_ticks) << topic;
    EXPECT_EQ((*s)["missing_ticks"], 0) << topic;
    EXPECT_EQ((*s)["duplicate_ticks"], 0) << topic;
    EXPECT_EQ((*s)["first_tick"].get<std::uint64_t>(), first) << topic << " began late";
    EXPECT_EQ((*s)["last_tick"].get<std::uint64_t>(), first + sim_ticks - 1) << topic;
    EXPECT_EQ((*s)["sequence_gaps"], 0) << topic;
  }
  for (const char* topic : {"poise/robot_description", "poise/diagnostics"})
    EXPECT_NE(find_topic(info, topic), nullptr) << topic << " is not in the file";
  const Json& m = info["metadata"]["poise_recorder"];
  EXPECT_EQ(m["total.dropped"], "0") << m.dump(2);
  EXPECT_EQ(m["total.vendor_lost"], "0") << m.dump(2);
  EXPECT_EQ(m["total.tick_gaps"], "0") << m.dump(2);
  EXPECT_EQ(m["capture.kernel_drops"], "0") << m.dump(2);
  EXPECT_EQ(m["capture.malformed"], "0") << m.dump(2);
  EXPECT_EQ(m["capture.unknown_writer"], "0") << m.dump(2);
  // Every message of every topic decodes against its stored schema, in an indexed and a
  // streaming read.
  for (const bool streaming : {false, true}) {
    auto [check_code, report] = check_independently(file, streaming);
    EXPECT_EQ(check_code, 0) << (streaming ? "streaming: " : "indexed: ") << report.dump(2);
  }
}

// Without CAP_NET_RAW `poise run --record --passive` fails before the run with the cause and
// the remedy. As root, the capability is dropped for the run (setpriv).
TEST(Record, RunRecordPassiveWithoutCapNetRawSaysWhy) {
  std::vector<std::string> argv;
  if (can_capture()) {
    if (!fs::exists("/usr/bin/setpriv")) GTEST_SKIP() << "cannot drop CAP_NET_RAW: no setpriv";
    argv = {"/usr/bin/setpriv", "--inh-caps", "-net_raw", "--bounding-set", "-net_raw"};
  }
  const fs::path dir = work_dir("run_passive_nocap");
  argv.insert(argv.end(),
              {bin("poise"), "run", "forward_push_double_support", "--duration", "1", "--domain",
               std::to_string(poise::testing::unique_domain_id()), "--record",
               (dir / "x.mcap").string(), "--passive", "-o", (dir / "run.json").string(),
               "--log-dir", (dir / "logs").string()});
  auto [code, out] = run(argv, 120s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("cannot record to"), std::string::npos) << out;
  EXPECT_NE(out.find("needs CAP_NET_RAW"), std::string::npos) << out;
  // It failed at once: no component ran.
  EXPECT_FALSE(fs::exists(dir / "logs" / "sim.summary.json"));
  const Json result = Json::parse(std::ifstream(dir / "run.json"));
  EXPECT_TRUE(result["failed"].get<bool>());
}

TEST(Record, PassiveReadNamesKnownTopicsOnlyAndNeedsPassive) {
  const fs::path dir = work_dir("passive_read_bad");
  auto [code, out] = run({bin("poise"), "record", "--passive", "--passive-read", "poise/nope",
                          "--domain", "3", "-o", (dir / "x.mcap").string()},
                         30s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--passive-read: unknown topic 'poise/nope'"), std::string::npos) << out;
  std::tie(code, out) = run({bin("poise"), "record", "--passive-read", "poise/ground_truth",
                             "--domain", "3", "-o", (dir / "y.mcap").string()},
                            30s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("need --passive"), std::string::npos) << out;
}

// A packet capture cannot read a secured domain (the governance of `poise security init`
// encrypts samples and discovery): both `poise record --passive` and `poise run --record
// --passive` refuse --security at once, with the reason, before any DDS participant exists.
TEST(Record, PassiveRefusesDdsSecurityWithTheReason) {
  const fs::path dir = work_dir("passive_security");
  auto [code, out] = run({bin("poise"), "record", "--passive", "--security", dir.string(),
                          "--domain", "3", "-o", (dir / "x.mcap").string()},
                         30s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--passive cannot record a domain with DDS Security"), std::string::npos)
      << out;
  EXPECT_FALSE(fs::exists(dir / "x.mcap"));
  std::tie(code, out) =
      run({bin("poise"), "run", "forward_push_double_support", "--duration", "1", "--record",
           (dir / "y.mcap").string(), "--passive", "--security", dir.string(), "-o",
           (dir / "run.json").string(), "--log-dir", (dir / "logs").string()},
          30s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--passive cannot record a run with --security"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "logs" / "sim.summary.json"));  // nothing started
}
