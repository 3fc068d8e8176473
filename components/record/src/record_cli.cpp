// `poise record`: records Poise DDS topics to MCAP until Ctrl-C, SIGTERM or --duration.
#include <sched.h>
#include <signal.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <poise/dds/cli.hpp>
#include <poise/dds/dds.hpp>
#include <poise/dds/subscriber.hpp>
#include <poise/dds/topics.hpp>

#include "poise/record/cli.hpp"
#include "poise/record/recorder.hpp"
#include "poise/cli/parse.hpp"

namespace poise::record {
namespace {

std::atomic<int> g_signal{0};
extern "C" void record_on_signal(int sig) {
  g_signal.store(sig);
}

std::string default_output() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  localtime_r(&now, &tm);
  char name[64];
  std::strftime(name, sizeof(name), "poise_%Y%m%d-%H%M%S.mcap", &tm);
  return name;
}

void print_progress(const RecorderStatus& s, double elapsed, bool tty) {
  std::fprintf(stderr,
               "%srecording %.1f s: %zu topics, %llu messages, %.1f MB, %llu dropped, "
               "%llu lost by DDS%s",
               tty ? "\r" : "", elapsed, s.topics.size(),
               static_cast<unsigned long long>(s.messages), s.bytes / 1e6,
               static_cast<unsigned long long>(s.dropped),
               static_cast<unsigned long long>(s.vendor_lost), tty ? "   " : "\n");
  std::fflush(stderr);
}

}  // namespace

std::string recording_path(const std::string& output, bool splitting, const std::string& if_exists,
                           std::string* error) {
  namespace fs = std::filesystem;
  const fs::path p(output);
  const std::string ext = p.has_extension() ? p.extension().string() : ".mcap";
  // A file a recording to `path` would create that exists already ("" if none). Split: any
  // <stem>_<n><ext>, not only _0 (a later split file in the way would stop the recording there).
  auto existing = [&](const fs::path& path) -> std::string {
    std::error_code ec;
    if (!splitting) return fs::exists(path, ec) ? path.string() : std::string();
    const std::string prefix = path.stem().string() + "_";
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    std::string first;  // the lowest-numbered, so that the message does not depend on the order
    long first_n = -1;
    for (const auto& f : fs::directory_iterator(dir, ec)) {
      const std::string name = f.path().filename().string();
      if (name.size() <= prefix.size() + ext.size() ||
          name.compare(0, prefix.size(), prefix) != 0 ||
          name.compare(name.size() - ext.size(), ext.size(), ext) != 0)
        continue;
      const std::string n = name.substr(prefix.size(), name.size() - prefix.size() - ext.size());
      if (n.size() > 9 || n.find_first_not_of("0123456789") != std::string::npos) continue;
      if (first_n < 0 || std::stol(n) < first_n) {
        first_n = std::stol(n);
        first = (path.parent_path() / name).string();
      }
    }
    return first;
  };
  const std::string in_the_way = existing(p);
  if (if_exists == "overwrite" || in_the_way.empty()) return output;
  if (if_exists == "next") {
    for (int k = 1; k <= 9999; ++k) {
      const fs::path candidate =
          p.parent_path() / (p.stem().string() + "." + std::to_string(k) + ext);
      if (existing(candidate).empty()) return candidate.string();
    }
    if (error) *error = output + " and its numbered successors up to .9999 all exist";
    return {};
  }
  if (error)
    *error = in_the_way +
             " exists: a recording is not written over it (give another -o, or --if-exists "
             "overwrite to replace it, or --if-exists next to record to the first free " +
             p.stem().string() + ".<k>" + ext + ")";
  return {};
}

void print_recording_summary(const RecorderStatus& s, std::FILE* out) {
  std::fprintf(out, "%-26s %-30s %10s %10s %8s %8s %9s\n", "TOPIC", "TYPE", "RECEIVED",
               "WRITTEN", "DROPPED", "DDS-LOST", "TICK-GAPS");
  for (const auto& t : s.topics) {
    std::fprintf(out, "%-26s %-30s %10llu %10llu %8llu %8llu %9llu\n", t.topic.c_str(),
                 t.type_name.c_str(), static_cast<unsigned long long>(t.received),
                 static_cast<unsigned long long>(t.written),
                 static_cast<unsigned long long>(t.dropped),
                 static_cast<unsigned long long>(t.vendor_lost + t.vendor_rejected),
                 static_cast<unsigned long long>(t.tick_gaps));
  }
  std::string files;
  for (const auto& f : s.files)
    files += (files.empty() ? "" : ", ") + f;
  std::fprintf(
      out,
      "%llu messages, %.2f MB in %s; %llu dropped by the recorder, %llu lost by DDS, %llu ticks "
      "skipped by writers of per-tick topics\n",
      static_cast<unsigned long long>(s.messages), s.bytes / 1e6, files.c_str(),
      static_cast<unsigned long long>(s.dropped), static_cast<unsigned long long>(s.vendor_lost),
      static_cast<unsigned long long>(s.tick_gaps));
}

namespace {

/// `poise record`'s command line.
struct RecordArgs {
  dds::DdsOptions dds_options;
  RecorderOptions options;
  std::string compression = "zstd";
  std::string if_exists;
  double duration_s = 0;
  double progress_s = -1;
  int nice_value = 0;
  bool idle = false;
  bool all = false;
  // Passive: topics whose writers would otherwise send to nobody (nothing in a plain run reads
  // them), so that they are on the wire and in the file.
  std::vector<std::string> passive_read{"poise/ground_truth", "poise/diagnostics"};
  bool passive_read_given = false;
  bool no_passive_read = false;
};

/// The options of the file: topics, output, splitting, compression, chunks, duration, progress.
void add_file_options(CLI::App& app, RecordArgs& a) {
  RecorderOptions& options = a.options;
  app.add_option("topics", options.topics, "topics to record (default: every Poise topic)");
  app.add_flag("-a,--all", a.all, "record every Poise topic (the default when none is named)");
  app.add_option("-o,--output", options.output,
                 "MCAP file to write (default: poise_<date>-<time>.mcap in the working "
                 "directory); with splitting, <stem>_<k>.mcap");
  app.add_option("--if-exists", a.if_exists,
                 "when the output file exists: refuse (exit 2, the default for a named -o), "
                 "overwrite, or next: the first free <stem>.1.mcap, <stem>.2.mcap, ... (the "
                 "default for the dated name; a restarted recorder keeps what it wrote before)")
      ->check(CLI::IsMember({"refuse", "overwrite", "next"}));
  app.add_option("--duration", a.duration_s, "stop after this many seconds (0: until Ctrl-C)")
      ->check(CLI::Range(0.0, 1e7));
  app.add_option("--split-size", options.split_size_mb, "start a new file past this many MB")
      ->check(CLI::Range(0.0, 1e7));
  app.add_option("--split-duration", options.split_duration_s,
                 "start a new file every this many seconds")
      ->check(CLI::Range(0.0, 1e7));
  app.add_option("--compression", a.compression, "chunk compression")
      ->check(CLI::IsMember({"zstd", "lz4", "none"}))
      ->capture_default_str();
  app.add_option("--chunk-size", options.writer.chunk_size,
                 "bytes of messages per chunk (the most a crash can cost, with --flush-interval)")
      ->check(CLI::Range(std::size_t{1024}, std::size_t{1} << 30))
      ->capture_default_str();
  app.add_option("--flush-interval", options.flush_interval_s,
                 "write the open chunk at least this often [s]")
      ->check(CLI::Range(0.001, 60.0))
      ->capture_default_str();
  app.add_flag("!--no-sync", options.writer.sync_chunks,
               "do not fdatasync after each chunk (faster; a power loss may cost more)");
  app.add_option("--progress", a.progress_s,
                 "seconds between progress lines (default: 0.5 on a terminal, 5 otherwise; "
                 "0: none)");
}

/// The options of how the recorder runs: scheduling, and the passive capture. Returns the
/// --passive-read option.
CLI::Option* add_capture_options(CLI::App& app, RecordArgs& a) {
  app.add_option("--nice", a.nice_value,
                 "scheduling niceness of the recorder (all its threads): 19 leaves the CPU to the "
                 "control loop on a busy machine; the 1 kHz writers keep 32 samples for it, and "
                 "what it still misses is counted as tick gaps")
      ->check(CLI::Range(-20, 19))
      ->capture_default_str();
  app.add_flag("--idle", a.idle,
               "run every thread of the recorder under SCHED_IDLE: it never preempts the control "
               "loop's processes and runs only on CPU time they leave (what it then misses is "
               "counted as tick gaps)");
  app.add_flag("--passive", a.options.passive,
               "record without subscribing: read the domain's UDP datagrams on --interface and "
               "take the samples out of them (the writers do no extra work for the recorder; "
               "needs CAP_NET_RAW; only traffic passing this machine; no repair of a datagram "
               "the capture missed, counted as lost: components/record/README.md)");
  app.add_option("--interface", a.options.capture_interface,
                 "network interface of --passive (default lo)")
      ->capture_default_str();
  auto* passive_read_opt =
      app.add_option("--passive-read", a.passive_read,
                     "--passive: topics to hold a DDS reader of, so that their writers send them "
                     "(a writer sends only to matched readers; the samples are still taken from the "
                     "datagrams). Give the topics nothing else reads: a reader of a loop topic "
                     "costs its writer one more send per sample (default: poise/ground_truth "
                     "poise/diagnostics, which no node reads)")
          ->capture_default_str();
  app.add_flag("--no-passive-read", a.no_passive_read,
               "--passive: no DDS reader at all (topics nobody else reads are then not recorded)")
      ->excludes(passive_read_opt);
  return passive_read_opt;
}

/// Checks the combinations the parser cannot; keeps only recorded topics in --passive-read.
/// Returns "" or the error.
std::string check_args(RecordArgs& a) {
  if (!a.options.passive && (a.passive_read_given || a.no_passive_read))
    return "--passive-read and --no-passive-read need --passive";
  if (a.options.passive && !a.dds_options.security_dir.empty())
    // The governance `poise security init` writes encrypts data, discovery and liveliness
    // (ENCRYPT): captured datagrams are ciphertext, and a passive capture holds no keys.
    return "--passive cannot record a domain with DDS Security (--security): its samples and "
           "discovery are encrypted on the wire; record without --passive (the subscribing "
           "recorder authenticates as --identity, e.g. recorder)";
  if (a.no_passive_read) a.passive_read.clear();
  for (const auto& t : a.passive_read)
    if (dds::find_topic(t) == nullptr) {
      std::string known;
      for (const auto& k : dds::topic_table())
        known += (known.empty() ? "" : ", ") + std::string(k.topic_name);
      return "--passive-read: unknown topic '" + t + "'; Poise topics: " + known;
    }
  const auto& topics = a.options.topics;
  if (!topics.empty())
    std::erase_if(a.passive_read, [&](const std::string& t) {
      return std::find(topics.begin(), topics.end(), t) == topics.end();
    });
  if (a.all && !topics.empty()) return "name topics or give --all, not both";
  return "";
}

/// --idle and --nice, before any thread exists: DDS and writer threads inherit them.
void apply_scheduling(const RecordArgs& a) {
  if (a.idle) {
    sched_param sp{};
    if (::sched_setscheduler(0, SCHED_IDLE, &sp) != 0)
      std::fprintf(stderr, "poise record: warning: cannot use SCHED_IDLE (%s)\n",
                   std::strerror(errno));
  }
  if (a.nice_value != 0 && ::setpriority(PRIO_PROCESS, 0, a.nice_value) != 0)
    std::fprintf(stderr, "poise record: warning: cannot set niceness %d (%s); running at %d\n",
                 a.nice_value, std::strerror(errno), ::getpriority(PRIO_PROCESS, 0));
}

/// The file to write (--if-exists), and the writer's compression. Returns "" or the error.
std::string choose_output(RecordArgs& a) {
  RecorderOptions& options = a.options;
  options.writer.compression = parse_compression(a.compression);
  if (a.if_exists.empty()) a.if_exists = options.output.empty() ? "next" : "refuse";
  if (options.output.empty()) options.output = default_output();
  const bool splitting = options.split_size_mb > 0 || options.split_duration_s > 0;
  std::string error;
  const std::string out = recording_path(options.output, splitting, a.if_exists, &error);
  if (out.empty()) return error;
  if (out != options.output)
    std::fprintf(stderr, "poise record: %s exists: recording to %s\n", options.output.c_str(),
                 out.c_str());
  options.output = out;
  // Later split files are created exclusively too: nothing recorded is ever written over.
  options.writer.overwrite = a.if_exists == "overwrite";
  return "";
}

void catch_signals() {
  struct sigaction sa {};
  sa.sa_handler = record_on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  // Past a file size limit, write() should fail (EFBIG, reported like a full disk), not kill us.
  std::signal(SIGXFSZ, SIG_IGN);
}

/// Passive readers: best effort, keep-last 1, no callback. A reliable writer serves a best-effort
/// reader with one send per sample and nothing else (no heartbeats, acknowledgments or repairs
/// for it); what this reader receives is never read: the capture takes the sample from the
/// datagram, once per (writer, sequence number).
std::vector<std::unique_ptr<dds::RawSubscriber>> make_passive_readers(
    dds::Participant& participant, const std::vector<std::string>& topics) {
  std::vector<std::unique_ptr<dds::RawSubscriber>> readers;
  for (const auto& t : topics) {
    const dds::TopicDescription* d = dds::find_topic(t);
    dds::Qos q = d->qos;
    q.reliability = dds::Reliability::best_effort;
    q.durability = dds::Durability::volatile_;
    q.history_depth = 1;
    q.writer_history_depth = 0;
    q.deadline = dds::Qos::infinite;
    readers.push_back(
        std::make_unique<dds::RawSubscriber>(participant, d->topic_name, d->type_name, q));
  }
  return readers;
}

void print_start(const RecordArgs& a, const dds::Participant& participant) {
  const RecorderOptions& options = a.options;
  std::fprintf(stderr, "poise record: %s, domain %d, %s -> %s\n",
               options.passive ? ("passive capture on " + options.capture_interface).c_str()
                               : std::string(dds::to_string(participant.vendor())).c_str(),
               participant.domain_id(),
               options.topics.empty() ? "every Poise topic" : "the topics named",
               options.output.c_str());
  if (options.passive) {
    std::string names;
    for (const auto& t : a.passive_read) names += (names.empty() ? "" : ", ") + t;
    std::fprintf(stderr, "poise record: passive readers (their writers send to them): %s\n",
                 names.empty() ? "none" : names.c_str());
  }
}

/// Records until a signal, --duration or a failure of the recorder: one line per change of a
/// topic's writers ("poise record: poise/state: 1 writer": a launcher starts its run once every
/// expected writer is matched, `poise run --record`), a progress line every --progress.
void follow(Recorder& recorder, const RecordArgs& a, bool tty) {
  const auto start = std::chrono::steady_clock::now();
  auto next_progress = start + std::chrono::duration<double>(a.progress_s);
  std::map<std::string, int> writers;
  while (g_signal.load() == 0) {
    const auto now = std::chrono::steady_clock::now();
    const double elapsed = std::chrono::duration<double>(now - start).count();
    if (a.duration_s > 0 && elapsed >= a.duration_s) break;
    const RecorderStatus status = recorder.status();
    for (const auto& t : status.topics) {
      int& known = writers[t.topic];
      if (t.writers == known) continue;
      known = t.writers;
      std::fprintf(stderr, "%spoise record: %s: %d writer%s\n", tty ? "\r" : "", t.topic.c_str(),
                   t.writers, t.writers == 1 ? "" : "s");
    }
    if (a.progress_s > 0 && now >= next_progress) {
      print_progress(status, elapsed, tty);
      next_progress += std::chrono::duration<double>(a.progress_s);
    }
    if (!status.error.empty()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (tty && a.progress_s > 0) std::fprintf(stderr, "\n");
}

/// The recording, started, followed and finished. Returns the exit status (0, or 1 on a failure
/// of the recorder: what it wrote before is kept).
int record(RecordArgs& a) {
  dds::set_log_name("poise-record");
  // Passive: the capture starts before the participant, whose discovery makes every writer of
  // the domain announce itself (SEDP) to this machine: the capture must see those announcements.
  std::unique_ptr<Recorder> passive_recorder;
  if (a.options.passive) {
    try {
      passive_recorder = std::make_unique<Recorder>(a.dds_options.domain_id, a.options);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "poise record: error: %s\n", e.what());
      return 1;
    }
  }
  dds::Participant participant(a.dds_options);
  std::unique_ptr<Recorder> subscribing_recorder;
  if (!a.options.passive) subscribing_recorder = std::make_unique<Recorder>(participant, a.options);
  Recorder& recorder = a.options.passive ? *passive_recorder : *subscribing_recorder;
  auto passive_readers = a.options.passive ? make_passive_readers(participant, a.passive_read)
                                           : std::vector<std::unique_ptr<dds::RawSubscriber>>{};
  print_start(a, participant);
  follow(recorder, a, ::isatty(2) != 0);
  const RecorderStatus final_status = recorder.finish();
  passive_readers.clear();
  print_recording_summary(final_status, stderr);
  if (!final_status.error.empty()) {
    // The counts above are of the file: the samples of the chunk that failed, and every one
    // after it, are counted as dropped.
    std::fprintf(stderr,
                 "poise record: error: %s\nThe recording stopped there: the file ends with the "
                 "last chunk written completely (the %llu messages counted as written above); a "
                 "streaming reader (poise info) reads it and says it is incomplete.\n",
                 final_status.error.c_str(),
                 static_cast<unsigned long long>(final_status.messages));
    return 1;
  }
  return 0;
}

}  // namespace

int record_main(int argc, char** argv) {
  RecordArgs a;
  a.dds_options = dds::dds_options_from_env();
  a.dds_options.participant_name = "poise-record";
  CLI::App app{
      "Record Poise DDS topics to an MCAP file (schema encoding omgidl, message encoding cdr), "
      "from writers of either vendor, until Ctrl-C, SIGTERM or --duration.\n"
      "Read it with `poise info`, `poise replay`, `poise export`, `poise plot` or any MCAP tool.\n"
      "Exit status: 0 recorded; 1 the recording failed (e.g. a full disk: the error names the "
      "file and the reason, the file ends with its last complete chunk, and the summary counts "
      "as written only the messages in the file); 2 bad arguments or the output file exists."};
  app.name("poise record");
  dds::add_dds_options(app, a.dds_options);
  add_file_options(app, a);
  const CLI::Option* passive_read_opt = add_capture_options(app, a);
  POISE_CLI_PARSE(app, argc, argv);
  a.passive_read_given = passive_read_opt->count() > 0;
  if (std::string why = check_args(a); !why.empty()) {
    std::fprintf(stderr, "poise record: %s\n", why.c_str());
    return 2;
  }
  apply_scheduling(a);
  if (std::string why = choose_output(a); !why.empty()) {
    std::fprintf(stderr, "poise record: %s\n", why.c_str());
    return 2;
  }
  if (a.progress_s < 0) a.progress_s = ::isatty(2) != 0 ? 0.5 : 5.0;
  catch_signals();
  return record(a);
}

}  // namespace poise::record
