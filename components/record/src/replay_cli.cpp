// `poise replay FILE`: publishes recorded samples with their original timing, on either vendor.
//
// Its main use: replay poise/sensors (and poise/robot_description) from a robot's recording in
// place of the robot, so that a changed estimator, controller or contact optimiser runs on real
// data. Samples are published as the bytes recorded (no re-encoding), on writers with the topic's
// own QoS (a latched topic stays available to late joiners). Timing follows the log times,
// scaled by --rate; --rate 0 publishes as fast as the readers allow.
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <set>
#include <thread>

#include <CLI/CLI.hpp>
#include <poise/dds/cli.hpp>
#include <poise/dds/dds.hpp>

#include "poise/record/cli.hpp"
#include "poise/record/mcap_reader.hpp"
#include "poise/cli/parse.hpp"

namespace poise::record {
namespace {

std::atomic<int> g_replay_signal{0};
extern "C" void replay_on_signal(int sig) {
  g_replay_signal.store(sig);
}

struct ReplayChannel {
  std::string topic;
  std::string type_name;
  dds::RawPublisher* publisher = nullptr;  // null: not replayed
};

/// `poise replay`'s command line.
struct ReplayArgs {
  dds::DdsOptions dds_options;
  std::string file;
  std::vector<std::string> topics;
  double rate = 1.0;
  bool loop = false;
  double start_s = 0, end_s = -1;
  int wait_readers = 0;
  double wait_s = 10;
  double linger_s = 0.5;
};

void add_replay_options(CLI::App& app, ReplayArgs& a) {
  dds::add_dds_options(app, a.dds_options);
  app.add_option("file", a.file, "MCAP file written by poise record")->required();
  app.add_option("--topics", a.topics, "topics to publish (default: every recorded Poise topic)");
  app.add_option("--rate", a.rate, "time scale: 2 = twice as fast, 0 = as fast as possible")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  app.add_flag("--loop", a.loop, "start again at the end, until Ctrl-C");
  app.add_option("--start", a.start_s, "skip the first S seconds of the recording")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--end", a.end_s, "stop S seconds after the start of the recording")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--wait-readers", a.wait_readers,
                 "before the first sample of each topic, wait until it has this many readers")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--wait", a.wait_s, "... for at most this many seconds (then fail)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  app.add_option("--linger", a.linger_s,
                 "seconds to stay on the domain after the last sample (reliable delivery)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
}

/// What the file holds: its channels and the first log time.
struct FileIndex {
  std::map<std::uint16_t, ReplayChannel> channels;
  std::uint64_t first_time = 0;
};

/// First pass over the file (and whether it is MCAP at all). Returns "" or the error.
std::string index_file(const std::string& file, FileIndex& index) {
  std::map<std::uint16_t, std::string> schema_names;
  ScanHandlers h;
  h.on_schema = [&](const SchemaRecord& s) { schema_names[s.id] = s.name; };
  h.on_channel = [&](const ChannelRecord& c) {
    index.channels[c.id] = ReplayChannel{c.topic, schema_names[c.schema_id], nullptr};
  };
  h.on_message = [&](const MessageView& m) {
    if (index.first_time == 0 || m.log_time < index.first_time) index.first_time = m.log_time;
    return true;
  };
  const ScanResult r = scan(file, h);
  if (!r.ok()) return file + ": " + r.error;
  if (!r.complete)
    std::fprintf(stderr, "poise replay: warning: %s is incomplete (%s); replaying what it holds\n",
                 file.c_str(), r.truncation.c_str());
  return "";
}

/// --topics: each a Poise topic the file has. Returns "" or the error.
std::string check_topics(const ReplayArgs& a, const FileIndex& index) {
  for (const auto& t : a.topics)
    if (!dds::find_topic(t)) return "unknown topic '" + t + "'";
  std::set<std::string> found;
  for (const auto& [id, c] : index.channels) found.insert(c.topic);
  for (const auto& t : a.topics)
    if (!found.count(t)) return "topic '" + t + "' is not in " + a.file;
  return "";
}

/// One writer per topic replayed, shared by the channels (files split or merged) that carry it;
/// each channel gets its publisher.
std::map<std::string, std::unique_ptr<dds::RawPublisher>> make_publishers(
    dds::Participant& participant, const ReplayArgs& a, FileIndex& index) {
  const std::set<std::string> wanted(a.topics.begin(), a.topics.end());
  std::map<std::string, std::unique_ptr<dds::RawPublisher>> by_topic;
  for (auto& [id, c] : index.channels) {
    const auto* desc = dds::find_topic(c.topic);
    if (!desc || (!wanted.empty() && !wanted.count(c.topic))) continue;
    if (desc->type_name != c.type_name) {
      std::fprintf(stderr,
                   "poise replay: topic '%s' was recorded with type '%s', Poise expects '%s': "
                   "not replayed\n",
                   c.topic.c_str(), c.type_name.c_str(), std::string(desc->type_name).c_str());
      continue;
    }
    auto& pub = by_topic[c.topic];
    if (!pub)
      pub = std::make_unique<dds::RawPublisher>(participant, c.topic, c.type_name, desc->qos);
    c.publisher = pub.get();
  }
  return by_topic;
}

/// Publishes the samples of one pass over the file. --wait-readers: each topic waits for its
/// readers before its first sample, not all topics before the first: a component often
/// subscribes to its inputs only after an earlier one arrived (the nodes read
/// poise/robot_description before they subscribe to poise/sensors). Returns "" or the error.
class Pass {
 public:
  Pass(const ReplayArgs& a, const FileIndex& index, std::set<const dds::RawPublisher*>& ready)
      : a_(a), index_(index), ready_(ready) {
    from_ = index.first_time + static_cast<std::uint64_t>(a.start_s * 1e9);
    to_ = a.end_s < 0 ? UINT64_MAX : index.first_time + static_cast<std::uint64_t>(a.end_s * 1e9);
  }

  std::string run(std::uint64_t& total) {
    wall_start_ = std::chrono::steady_clock::now();
    ScanHandlers h;
    h.on_message = [&](const MessageView& m) { return publish(m, total); };
    const ScanResult r = scan(a_.file, h);
    if (!r.ok()) return a_.file + ": " + r.error;
    return wait_failure_;
  }

 private:
  bool publish(const MessageView& m, std::uint64_t& total) {
    if (g_replay_signal.load()) return false;
    if (m.log_time < from_) return true;
    if (m.log_time > to_) return false;
    auto it = index_.channels.find(m.channel_id);
    if (it == index_.channels.end() || !it->second.publisher) return true;
    dds::RawPublisher* pub = it->second.publisher;
    if (a_.wait_readers > 0 && !ready_.count(pub) && !wait_for_readers(*pub, it->second.topic))
      return false;
    if (a_.rate > 0)
      std::this_thread::sleep_until(
          wall_start_ +
          std::chrono::nanoseconds(static_cast<std::int64_t>((m.log_time - from_) / a_.rate)));
    pub->publish(m.data.data(), m.data.size());
    ++total;
    return true;
  }

  bool wait_for_readers(dds::RawPublisher& pub, const std::string& topic) {
    const auto before = std::chrono::steady_clock::now();
    if (!pub.wait_for_matches(a_.wait_readers,
                              std::chrono::duration_cast<std::chrono::nanoseconds>(
                                  std::chrono::duration<double>(a_.wait_s)))) {
      wait_failure_ = topic + ": " + std::to_string(pub.matched()) + " of " +
                      std::to_string(a_.wait_readers) + " readers matched after " +
                      std::to_string(a_.wait_s) + " s";
      return false;
    }
    ready_.insert(&pub);
    wall_start_ += std::chrono::steady_clock::now() - before;  // the timeline waits too
    return true;
  }

  const ReplayArgs& a_;
  const FileIndex& index_;
  std::set<const dds::RawPublisher*>& ready_;
  std::uint64_t from_ = 0, to_ = 0;
  std::chrono::steady_clock::time_point wall_start_;
  std::string wait_failure_;
};

/// Publishes the file (again and again with --loop). Returns the exit status.
int replay(const ReplayArgs& a, FileIndex& index) {
  struct sigaction sa {};
  sa.sa_handler = replay_on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  dds::set_log_name("poise-replay");
  dds::Participant participant(a.dds_options);
  const auto by_topic = make_publishers(participant, a, index);
  if (by_topic.empty()) {
    std::fprintf(stderr, "poise replay: nothing to replay in %s\n", a.file.c_str());
    return 2;
  }
  std::string names;
  for (const auto& [topic, pub] : by_topic) names += (names.empty() ? "" : ", ") + topic;
  std::fprintf(stderr, "poise replay: %s on %s domain %d, rate %g: %s\n", a.file.c_str(),
               std::string(dds::to_string(participant.vendor())).c_str(), participant.domain_id(),
               a.rate, names.c_str());
  std::uint64_t total = 0;
  int pass = 0;
  std::set<const dds::RawPublisher*> ready;
  do {
    if (const std::string why = Pass(a, index, ready).run(total); !why.empty()) {
      std::fprintf(stderr, "poise replay: %s\n", why.c_str());
      return 1;
    }
    ++pass;
  } while (a.loop && !g_replay_signal.load());
  std::fprintf(stderr, "poise replay: published %llu samples in %d pass%s\n",
               static_cast<unsigned long long>(total), pass, pass == 1 ? "" : "es");
  if (a.linger_s > 0 && !g_replay_signal.load())
    std::this_thread::sleep_for(std::chrono::duration<double>(a.linger_s));
  return 0;
}

}  // namespace

int replay_main(int argc, char** argv) {
  ReplayArgs a;
  a.dds_options = dds::dds_options_from_env();
  a.dds_options.participant_name = "poise-replay";
  CLI::App app{
      "Publish the samples of an MCAP recording with their original timing, on either vendor "
      "(for example poise/sensors and poise/robot_description in place of the robot)."};
  app.name("poise replay");
  add_replay_options(app, a);
  POISE_CLI_PARSE(app, argc, argv);
  if (a.end_s >= 0 && a.end_s <= a.start_s) {
    std::fprintf(stderr, "poise replay: --end (%g) must be after --start (%g)\n", a.end_s,
                 a.start_s);
    return 2;
  }
  for (const auto& t : a.topics)
    if (!dds::find_topic(t)) {
      std::fprintf(stderr, "poise replay: unknown topic '%s'\n", t.c_str());
      return 2;
    }
  FileIndex index;
  if (const std::string why = index_file(a.file, index); !why.empty()) {
    std::fprintf(stderr, "poise replay: %s\n", why.c_str());
    return 1;
  }
  if (const std::string why = check_topics(a, index); !why.empty()) {
    std::fprintf(stderr, "poise replay: %s\n", why.c_str());
    return 2;
  }
  return replay(a, index);
}

}  // namespace poise::record
