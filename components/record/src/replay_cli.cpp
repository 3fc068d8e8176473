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

}  // namespace

int replay_main(int argc, char** argv) {
  dds::DdsOptions dds_options = dds::dds_options_from_env();
  dds_options.participant_name = "poise-replay";
  std::string file;
  std::vector<std::string> topics;
  double rate = 1.0;
  bool loop = false;
  double start_s = 0, end_s = -1;
  int wait_readers = 0;
  double wait_s = 10;
  double linger_s = 0.5;
  CLI::App app{
      "Publish the samples of an MCAP recording with their original timing, on either vendor "
      "(for example poise/sensors and poise/robot_description in place of the robot)."};
  app.name("poise replay");
  dds::add_dds_options(app, dds_options);
  app.add_option("file", file, "MCAP file written by poise record")->required();
  app.add_option("--topics", topics, "topics to publish (default: every recorded Poise topic)");
  app.add_option("--rate", rate, "time scale: 2 = twice as fast, 0 = as fast as possible")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  app.add_flag("--loop", loop, "start again at the end, until Ctrl-C");
  app.add_option("--start", start_s, "skip the first S seconds of the recording")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--end", end_s, "stop S seconds after the start of the recording")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--wait-readers", wait_readers,
                 "before the first sample of each topic, wait until it has this many readers")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--wait", wait_s, "... for at most this many seconds (then fail)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  app.add_option("--linger", linger_s,
                 "seconds to stay on the domain after the last sample (reliable delivery)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  POISE_CLI_PARSE(app, argc, argv);
  if (end_s >= 0 && end_s <= start_s) {
    std::fprintf(stderr, "poise replay: --end (%g) must be after --start (%g)\n", end_s, start_s);
    return 2;
  }
  for (const auto& t : topics) {
    if (!dds::find_topic(t)) {
      std::fprintf(stderr, "poise replay: unknown topic '%s'\n", t.c_str());
      return 2;
    }
  }

  // First pass: what the file holds (and whether it is MCAP at all).
  std::map<std::uint16_t, std::string> schema_names;
  std::map<std::uint16_t, ReplayChannel> channels;
  std::uint64_t first_time = 0;
  {
    ScanHandlers h;
    h.on_schema = [&](const SchemaRecord& s) { schema_names[s.id] = s.name; };
    h.on_channel = [&](const ChannelRecord& c) {
      channels[c.id] = ReplayChannel{c.topic, schema_names[c.schema_id], nullptr};
    };
    h.on_message = [&](const MessageView& m) {
      if (first_time == 0 || m.log_time < first_time) first_time = m.log_time;
      return true;
    };
    const ScanResult r = scan(file, h);
    if (!r.ok()) {
      std::fprintf(stderr, "poise replay: %s: %s\n", file.c_str(), r.error.c_str());
      return 1;
    }
    if (!r.complete)
      std::fprintf(stderr,
                   "poise replay: warning: %s is incomplete (%s); replaying what it holds\n",
                   file.c_str(), r.truncation.c_str());
  }
  std::set<std::string> wanted(topics.begin(), topics.end());
  std::set<std::string> found;
  for (const auto& [id, c] : channels)
    found.insert(c.topic);
  for (const auto& t : wanted) {
    if (!found.count(t)) {
      std::fprintf(stderr, "poise replay: topic '%s' is not in %s\n", t.c_str(), file.c_str());
      return 2;
    }
  }

  struct sigaction sa {};
  sa.sa_handler = replay_on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  dds::set_log_name("poise-replay");
  dds::Participant participant(dds_options);
  // One writer per topic, shared by the channels (files split or merged) that carry it.
  std::map<std::string, std::unique_ptr<dds::RawPublisher>> by_topic;
  for (auto& [id, c] : channels) {
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
  if (by_topic.empty()) {
    std::fprintf(stderr, "poise replay: nothing to replay in %s\n", file.c_str());
    return 2;
  }
  std::string names;
  for (const auto& [topic, pub] : by_topic)
    names += (names.empty() ? "" : ", ") + topic;
  std::fprintf(stderr, "poise replay: %s on %s domain %d, rate %g: %s\n", file.c_str(),
               std::string(dds::to_string(participant.vendor())).c_str(), participant.domain_id(),
               rate, names.c_str());

  const std::uint64_t from = first_time + static_cast<std::uint64_t>(start_s * 1e9);
  const std::uint64_t to =
      end_s < 0 ? UINT64_MAX : first_time + static_cast<std::uint64_t>(end_s * 1e9);
  std::uint64_t total = 0;
  int pass = 0;
  // --wait-readers: each topic waits for its readers before its first sample, not all topics
  // before the first: a component often subscribes to its inputs only after an earlier one
  // arrived (the nodes read poise/robot_description before they subscribe to poise/sensors).
  std::set<const dds::RawPublisher*> ready;
  std::string wait_failure;
  do {
    auto wall_start = std::chrono::steady_clock::now();
    ScanHandlers h;
    h.on_message = [&](const MessageView& m) {
      if (g_replay_signal.load()) return false;
      if (m.log_time < from) return true;
      if (m.log_time > to) return false;
      auto it = channels.find(m.channel_id);
      if (it == channels.end() || !it->second.publisher) return true;
      dds::RawPublisher* pub = it->second.publisher;
      if (wait_readers > 0 && !ready.count(pub)) {
        const auto before = std::chrono::steady_clock::now();
        if (!pub->wait_for_matches(wait_readers,
                                   std::chrono::duration_cast<std::chrono::nanoseconds>(
                                       std::chrono::duration<double>(wait_s)))) {
          wait_failure = it->second.topic + ": " + std::to_string(pub->matched()) + " of " +
                         std::to_string(wait_readers) + " readers matched after " +
                         std::to_string(wait_s) + " s";
          return false;
        }
        ready.insert(pub);
        wall_start += std::chrono::steady_clock::now() - before;  // the timeline waits too
      }
      if (rate > 0) {
        const auto due = wall_start + std::chrono::nanoseconds(
                                          static_cast<std::int64_t>((m.log_time - from) / rate));
        std::this_thread::sleep_until(due);
      }
      pub->publish(m.data.data(), m.data.size());
      ++total;
      return true;
    };
    const ScanResult r = scan(file, h);
    if (!r.ok()) {
      std::fprintf(stderr, "poise replay: %s: %s\n", file.c_str(), r.error.c_str());
      return 1;
    }
    if (!wait_failure.empty()) {
      std::fprintf(stderr, "poise replay: %s\n", wait_failure.c_str());
      return 1;
    }
    ++pass;
  } while (loop && !g_replay_signal.load());
  std::fprintf(stderr, "poise replay: published %llu samples in %d pass%s\n",
               static_cast<unsigned long long>(total), pass, pass == 1 ? "" : "es");
  if (linger_s > 0 && !g_replay_signal.load())
    std::this_thread::sleep_for(std::chrono::duration<double>(linger_s));
  return 0;
}

}  // namespace poise::record
