// `poise replay FILE`: publishes recorded samples with their original timing, on either vendor.
//
// Its main use: replay poise/sensors (and poise/robot_description) from a robot's recording in
// place of the robot, so that a changed estimator, controller or contact optimiser runs on real
// data. Samples are published as the bytes recorded (no re-encoding), on writers with the topic's
// own QoS (a latched topic stays available to late joiners). Timing follows the log times,
// scaled by --rate; --rate 0 publishes as fast as the readers allow.
//
// --lockstep: the samples of a tick of the per-tick topics replayed (poise/sensors, ...) are
// published only once the replayed component has answered the previous tick on its output topic
// (--answer, e.g. poise/state for poise/sensors: the estimator publishes one State per Sensors,
// with the same Header.tick), at most --answer-timeout seconds per tick; the first tick is
// repeated every 100 ms until answered (the components answer a repeated tick again, as for
// the simulator's start-up). A component that never answers, or (poise/state) says it missed
// sensor ticks (STATE_DROPPED_FRAMES), fails the replay (exit 1, with the tick). --answer without
// --lockstep checks the same at the end, without waiting for each tick.
#include <signal.h>

#include <condition_variable>
#include <mutex>

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
#include "poise/record/recording_info.hpp"
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
  bool lockstep = false;
  std::string answer;  // the replayed component's output topic ("" : none checked)
  double answer_timeout_s = 5;
};

/// The topic on which the component that reads `topic` answers each of its ticks with the same
/// Header.tick ("" if none): the loop's order, sim -> estimator -> controller <-> contact.
std::string default_answer(const std::string& topic) {
  using dds::TopicTraits;
  // (input, the answer of the component that reads it); names from the topic declarations.
  static constexpr std::pair<std::string_view, std::string_view> kAnswers[] = {
      {TopicTraits<msg::Sensors>::topic_name, TopicTraits<msg::State>::topic_name},  // estimator
      {TopicTraits<msg::State>::topic_name, TopicTraits<msg::ContactProblem>::topic_name},
      {TopicTraits<msg::ContactProblem>::topic_name, TopicTraits<msg::ContactSolution>::topic_name},
      {TopicTraits<msg::ContactSolution>::topic_name, TopicTraits<msg::JointCommand>::topic_name},
      {TopicTraits<msg::JointCommand>::topic_name, TopicTraits<msg::Sensors>::topic_name},  // sim
  };
  for (const auto& [input, answer] : kAnswers)
    if (topic == input) return std::string(answer);
  return "";
}

/// The replayed component's answers: the ticks seen on the answer topic, and those it flagged
/// (poise/state with STATE_DROPPED_FRAMES: sensor ticks missed before this one).
class AnswerWatch {
 public:
  AnswerWatch(dds::Participant& participant, const std::string& topic) : topic_(topic) {
    const dds::TopicDescription* d = dds::find_topic(topic);
    dds::Qos q = d->qos;
    q.history_depth = 1000;  // a burst of answers is all kept (the callback takes each)
    q.deadline = dds::Qos::infinite;
    reader_ = std::make_unique<dds::RawSubscriber>(
        participant, d->topic_name, d->type_name, q,
        [this](const std::vector<std::uint8_t>& bytes, const dds::SampleMeta&) { on(bytes); });
  }
  const std::string& topic() const { return topic_; }
  int writers() const { return reader_->matched(); }
  bool wait_for_writer(double seconds) const {
    return reader_->wait_for_matches(
        1, std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::duration<double>(seconds)));
  }
  /// Waits until tick `k` is answered, at most until `deadline`.
  bool wait(std::uint64_t k, std::chrono::steady_clock::time_point deadline) {
    std::unique_lock lock(mutex_);
    return cv_.wait_until(lock, deadline, [&] { return answered_.count(k) > 0; });
  }
  bool answered(std::uint64_t k) {
    std::lock_guard lock(mutex_);
    return answered_.count(k) > 0;
  }
  /// The first tick answered with STATE_DROPPED_FRAMES (0: none).
  std::uint64_t first_flagged() {
    std::lock_guard lock(mutex_);
    return first_flagged_;
  }

 private:
  void on(const std::vector<std::uint8_t>& bytes) {
    std::uint64_t tick = 0;
    if (!header_tick(bytes.data(), bytes.size(), tick)) return;
    bool dropped_frames = false;
    if (topic_ == "poise/state" && bytes.size() >= 24) {
      // State: Header (tick, stamp_ns: 16 bytes), then status_flags (4 bytes), after the 4-byte
      // encapsulation header.
      const bool little = bytes[1] == 1;
      std::uint32_t flags = 0;
      for (int i = 0; i < 4; ++i)
        flags |= static_cast<std::uint32_t>(bytes[static_cast<std::size_t>(20 + (little ? i : 3 - i))])
                 << (8 * i);
      dropped_frames = (flags & 1u) != 0;  // STATE_DROPPED_FRAMES
    }
    {
      std::lock_guard lock(mutex_);
      answered_.insert(tick);
      if (dropped_frames && first_flagged_ == 0) first_flagged_ = tick;
    }
    cv_.notify_all();
  }

  std::string topic_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::set<std::uint64_t> answered_;
  std::uint64_t first_flagged_ = 0;
  std::unique_ptr<dds::RawSubscriber> reader_;
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
  app.add_flag("--lockstep", a.lockstep,
               "publish the samples of a tick of the per-tick topics replayed only once the "
               "replayed component has answered the previous tick on --answer (same "
               "Header.tick); the first tick is repeated every 100 ms until answered; --rate "
               "still paces (0: as fast as the answers come). Fails (exit 1) when a tick is not "
               "answered within --answer-timeout or the answer says it missed ticks");
  app.add_option("--answer", a.answer,
                 "the replayed component's output topic (default with --lockstep: the output of "
                 "the component reading the first per-tick topic replayed: poise/state for "
                 "poise/sensors, poise/contact_problem for poise/state, poise/contact_solution "
                 "for poise/contact_problem, poise/joint_command for poise/contact_solution, "
                 "poise/sensors for poise/joint_command). Without --lockstep: checked at the end "
                 "(every tick sent answered, none with STATE_DROPPED_FRAMES; else exit 1)");
  app.add_option("--answer-timeout", a.answer_timeout_s,
                 "seconds to wait for the answer to one tick (--lockstep), or after the last "
                 "sample for every answer")
      ->check(CLI::Range(0.001, 3600.0))
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

/// --answer: a Poise topic not replayed; with --lockstep and none given, the default for the
/// first per-tick topic replayed. Returns "" or the error.
std::string choose_answer(ReplayArgs& a, const FileIndex& index) {
  if (a.lockstep && a.answer.empty()) {
    for (const char* t : {"poise/sensors", "poise/state", "poise/contact_problem",
                          "poise/contact_solution", "poise/joint_command"}) {
      bool replayed = a.topics.empty() || std::count(a.topics.begin(), a.topics.end(), t) > 0;
      bool in_file = false;
      for (const auto& [id, c] : index.channels) in_file = in_file || c.topic == t;
      if (replayed && in_file) {
        a.answer = default_answer(t);
        break;
      }
    }
    if (a.answer.empty())
      return "--lockstep: no per-tick topic (poise/sensors, poise/state, ...) to replay";
  }
  if (a.answer.empty()) return "";
  const dds::TopicDescription* d = dds::find_topic(a.answer);
  if (!d) return "--answer: unknown topic '" + a.answer + "'";
  if (!(d->qos == dds::Qos::control()))
    return "--answer: " + a.answer + " is not a per-tick topic (no answer per tick)";
  const bool replayed_too = a.topics.empty()
                                ? std::any_of(index.channels.begin(), index.channels.end(),
                                              [&](const auto& c) { return c.second.topic == a.answer; })
                                : std::count(a.topics.begin(), a.topics.end(), a.answer) > 0;
  if (replayed_too)
    return "--answer " + a.answer + " is replayed too: give --topics without it (the answers "
           "must come from the component alone)";
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
  Pass(const ReplayArgs& a, const FileIndex& index, std::set<const dds::RawPublisher*>& ready,
       AnswerWatch* answers)
      : a_(a), index_(index), ready_(ready), answers_(answers) {
    from_ = index.first_time + static_cast<std::uint64_t>(a.start_s * 1e9);
    to_ = a.end_s < 0 ? UINT64_MAX : index.first_time + static_cast<std::uint64_t>(a.end_s * 1e9);
  }

  std::string run(std::uint64_t& total) {
    wall_start_ = std::chrono::steady_clock::now();
    ScanHandlers h;
    h.on_message = [&](const MessageView& m) { return publish(m, total); };
    const ScanResult r = scan(a_.file, h);
    if (!r.ok()) return a_.file + ": " + r.error;
    if (!wait_failure_.empty()) return wait_failure_;
    // --lockstep: the last tick's answer too.
    if (a_.lockstep && any_tick_sent_ && !g_replay_signal.load() && !wait_for_answer())
      return wait_failure_;
    return "";
  }

  /// Ticks of the per-tick topics published in this pass, in order.
  const std::vector<std::uint64_t>& ticks_sent() const { return ticks_sent_; }

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
    // A sample of a per-tick topic: the tick it belongs to (answered by the component).
    std::uint64_t tick = 0;
    const bool per_tick = dds::find_topic(it->second.topic)->qos == dds::Qos::control() &&
                          header_tick(m.data.data(), m.data.size(), tick);
    // A later tick (a sample of an earlier one, recorded a little after the next tick's, goes
    // out without waiting).
    const bool new_tick = per_tick && (!any_tick_sent_ || tick > last_tick_);
    // Before the first tick, the answer's writer (a node creates it only once it has the robot
    // description, which may be replayed just before).
    if (answers_ && new_tick && !any_tick_sent_ && !answers_->wait_for_writer(a_.wait_s)) {
      char b[300];
      std::snprintf(b, sizeof(b),
                    "no writer of %s after %g s: the replayed component is not running on "
                    "domain %d (or does not publish %s)",
                    answers_->topic().c_str(), a_.wait_s, a_.dds_options.domain_id,
                    answers_->topic().c_str());
      wait_failure_ = b;
      return false;
    }
    if (a_.lockstep && new_tick && any_tick_sent_ && !wait_for_answer()) return false;
    if (a_.rate > 0)
      std::this_thread::sleep_until(
          wall_start_ +
          std::chrono::nanoseconds(static_cast<std::int64_t>((m.log_time - from_) / a_.rate)));
    pub->publish(m.data.data(), m.data.size());
    ++total;
    if (new_tick) {
      if (!any_tick_sent_) first_tick_ = tick;
      any_tick_sent_ = true;
      last_tick_ = tick;
      ticks_sent_.push_back(tick);
    }
    if (per_tick && tick == first_tick_ && a_.lockstep)  // repeated until answered
      first_samples_.emplace_back(pub, std::vector<std::uint8_t>(m.data.begin(), m.data.end()));
    return true;
  }

  /// --lockstep: waits for the answer to the last tick sent (the first one is repeated every
  /// 100 ms until answered); the timeline waits too. False (wait_failure_ set) on a timeout.
  bool wait_for_answer() {
    const auto before = std::chrono::steady_clock::now();
    const auto deadline =
        before + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                     std::chrono::duration<double>(a_.answer_timeout_s));
    bool ok = false;
    if (last_tick_ == first_tick_ && !first_samples_.empty()) {
      while (!(ok = answers_->wait(last_tick_, std::min(deadline, std::chrono::steady_clock::now() +
                                                                     std::chrono::milliseconds(100)))) &&
             std::chrono::steady_clock::now() < deadline && !g_replay_signal.load())
        for (const auto& [p, bytes] : first_samples_)
          p->publish(bytes.data(), bytes.size());
      first_samples_.clear();
    } else {
      ok = answers_->wait(last_tick_, deadline);
    }
    if (!ok) {
      if (g_replay_signal.load()) return false;
      char b[400];
      std::snprintf(b, sizeof(b),
                    "--lockstep: no %s for tick %llu within %g s (%d writer%s of it matched): "
                    "the replayed component stopped answering (%llu ticks answered before)",
                    answers_->topic().c_str(), static_cast<unsigned long long>(last_tick_),
                    a_.answer_timeout_s, answers_->writers(), answers_->writers() == 1 ? "" : "s",
                    static_cast<unsigned long long>(ticks_sent_.empty() ? 0 : ticks_sent_.size() - 1));
      wait_failure_ = b;
      return false;
    }
    if (const std::uint64_t f = answers_->first_flagged(); f != 0) {
      wait_failure_ = "--lockstep: the " + answers_->topic() + " of tick " + std::to_string(f) +
                      " says sensor ticks were missed before it (STATE_DROPPED_FRAMES)";
      return false;
    }
    wall_start_ += std::chrono::steady_clock::now() - before;  // the timeline waits too
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
  AnswerWatch* answers_;  // null: no --answer
  std::uint64_t from_ = 0, to_ = 0;
  std::chrono::steady_clock::time_point wall_start_;
  std::string wait_failure_;
  bool any_tick_sent_ = false;
  std::uint64_t first_tick_ = 0, last_tick_ = 0;
  std::vector<std::uint64_t> ticks_sent_;
  std::vector<std::pair<dds::RawPublisher*, std::vector<std::uint8_t>>> first_samples_;
};

/// --answer without --lockstep, after the last sample: every tick sent answered (waiting up to
/// --answer-timeout for the last ones), none flagged. Returns "" or what is wrong.
std::string check_answers(const ReplayArgs& a, AnswerWatch& answers,
                          const std::vector<std::uint64_t>& sent) {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(a.answer_timeout_s));
  if (!sent.empty()) answers.wait(sent.back(), deadline);
  std::uint64_t missing = 0, first_missing = 0;
  for (const std::uint64_t k : sent)
    if (!answers.answered(k) && missing++ == 0) first_missing = k;
  std::string why;
  if (missing > 0)
    why = std::to_string(missing) + " of " + std::to_string(sent.size()) + " ticks sent got no " +
          answers.topic() + " (the first: tick " + std::to_string(first_missing) +
          "): the replayed component missed them (input stale or overwritten; --lockstep waits "
          "for each answer)";
  if (const std::uint64_t f = answers.first_flagged(); f != 0)
    why += std::string(why.empty() ? "" : "; ") + "the " + answers.topic() + " of tick " +
           std::to_string(f) + " says sensor ticks were missed before it (STATE_DROPPED_FRAMES)";
  return why;
}

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
  std::unique_ptr<AnswerWatch> answers;
  if (!a.answer.empty()) {
    answers = std::make_unique<AnswerWatch>(participant, a.answer);
    std::fprintf(stderr, "poise replay: %s: the replayed component's answers on %s\n",
                 a.lockstep ? "lockstep" : "checking", a.answer.c_str());
  }
  std::uint64_t total = 0, ticks = 0;
  int pass = 0;
  std::set<const dds::RawPublisher*> ready;
  std::vector<std::uint64_t> sent;
  do {
    Pass p(a, index, ready, answers.get());
    const std::string why = p.run(total);
    ticks += p.ticks_sent().size();
    if (!why.empty()) {
      std::fprintf(stderr, "poise replay: %s\n", why.c_str());
      return 1;
    }
    if (answers && !a.lockstep && !a.loop) sent = p.ticks_sent();
    ++pass;
  } while (a.loop && !g_replay_signal.load());
  std::fprintf(stderr, "poise replay: published %llu samples in %d pass%s\n",
               static_cast<unsigned long long>(total), pass, pass == 1 ? "" : "es");
  if (answers && a.lockstep && !g_replay_signal.load())
    std::fprintf(stderr, "poise replay: lockstep: %llu ticks, each answered on %s\n",
                 static_cast<unsigned long long>(ticks), a.answer.c_str());
  if (answers && !a.lockstep && !g_replay_signal.load()) {
    if (const std::string why = check_answers(a, *answers, sent); !why.empty()) {
      std::fprintf(stderr, "poise replay: error: %s\n", why.c_str());
      return 1;
    }
    std::fprintf(stderr, "poise replay: every one of the %zu ticks sent was answered on %s\n",
                 sent.size(), a.answer.c_str());
  }
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
      "(for example poise/sensors and poise/robot_description in place of the robot).\n"
      "--lockstep feeds a component tick by tick: the next tick only once it has answered the "
      "previous one (poise/state for poise/sensors, ...), so that a loaded machine cannot make "
      "its input stale. Exit status: 0 done, 1 a failure (readers or answers missing, file "
      "unreadable), 2 bad arguments."};
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
  if (const std::string why = choose_answer(a, index); !why.empty()) {
    std::fprintf(stderr, "poise replay: %s\n", why.c_str());
    return 2;
  }
  return replay(a, index);
}

}  // namespace poise::record
