#pragma once
// The runtime every Poise node shares.
//
//   poise::node::NodeOptions options;               // --robot, --name, --summary, --dds ...
//   CLI::App app{"..."};
//   poise::node::add_node_options(app, options, "estimator");
//   POISE_CLI_PARSE(app, argc, argv);
//   poise::node::Node node(options);                // participant, diagnostics, signals
//   ... subscribers, publishers; node.watch(subscriber);
//   while (node.running()) { ...; node.tick_done(k, compute_ns); node.poll(); }
//
// Per-tick accounting (the summary's figures): a tick's compute time splits into the library
// call, the node's own work (conversions, validation, sequencing, diagnostics) and the DDS write
// (serialisation and the vendor's write, loopback send included): node.tick_begin() at the start
// of the tick, node.publish() for its outputs (it times the write), then
// node.tick_done(k, compute_ns, library_ns).
//
// Diagnostics ("poise/diagnostics", best-effort keep-last 1, ~10 Hz): node name, vendor, health,
// heartbeat, ticks, compute time p50/p99/max over the window since the previous publication,
// deadline misses, rejected samples (sum over the watched subscribers), type mismatches, errors
// and the last error. poll() publishes them when due; call it from the loop thread.
//
// Threading: every member except the constructor is meant for the node's loop thread only (or,
// with serve(), for whichever thread holds the node's state mutex).
// Real-time behaviour: tick_done(), deadline_miss(), publish() and poll() do not allocate and do
// not throw; error() logs at most once a second (the others are counted).

#include <CLI/CLI.hpp>

#include <array>
#include <chrono>
#include <cstdarg>
#include <atomic>
#include <condition_variable>
#include <thread>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <poise/msg/diagnostics.h>

#include "poise/dds/cli.hpp"
#include "poise/dds/dds.hpp"
#include "poise/node/compute_stats.hpp"
#include "poise/node/realtime.hpp"
#include "poise/node/shutdown.hpp"
#include "poise/node/tick_sequencer.hpp"
#include "poise/node/tick_timer.hpp"
#include "poise/reflect/validate.hpp"

namespace poise::node {

/// Options common to every node.
struct NodeOptions {
  std::string name;     ///< node name in logs and diagnostics (default: the node kind)
  std::string robot;    ///< --robot: robot configuration YAML; "" (default): from the description
  std::string summary;  ///< write a JSON summary (last diagnostics + node figures) at exit
  dds::DdsOptions dds = dds::dds_options_from_env();
  double diagnostics_hz = 10.0;
  /// Readers each per-tick output topic must have matched before the node takes its first
  /// input (0: no wait), at most `output_readers_timeout_ms`. A reader that the writer has not
  /// matched yet misses the samples written before (volatile topics): a launcher that records
  /// the run asks for the consumer + the recorder.
  int output_readers = 0;
  int output_readers_timeout_ms = 20000;
  /// Nodes with a per-tick input (add_input_options): staleness bound and tick sequencing
  /// (fault semantics table: idl/README.md).
  double input_stale_ms = 50.0;
  TickSequencer::Config ticks;
  /// --rt-priority, --cpus, --lock-memory: applied by Node before the DDS participant exists.
  RealtimeOptions rt;
};

/// deploy/robots/poise_humanoid/robot.yaml, located like the DDS configurations (source tree
/// of this build, or relative to the executable). Not the nodes' default any more (they take the
/// robot from poise/robot_description): for tools and benchmarks that need the project humanoid.
std::string default_robot_config();

/// Adds --name, --robot, --summary, the DDS options (--dds, --domain, --dds-config) and the
/// real-time options (--rt-priority, --cpus, --lock-memory).
/// `kind` is the default name ("sim", "estimator", ...).
void add_node_options(CLI::App& app, NodeOptions& options, const std::string& kind);

/// Adds the options of a node that consumes a per-tick input: --input-stale-ms,
/// --max-tick-jump, --restart-confirm, --restart-silence-ms.
void add_input_options(CLI::App& app, NodeOptions& options);

class Node {
 public:
  /// Sets the log name, installs the SIGINT/SIGTERM handlers, joins the domain and creates the
  /// diagnostics publisher. Throws std::runtime_error (DDS failure) at configuration time.
  explicit Node(const NodeOptions& options);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  dds::Participant& participant() noexcept { return *participant_; }
  const NodeOptions& options() const noexcept { return options_; }
  const std::string& name() const noexcept { return options_.name; }

  /// Sums this subscriber's rejected / deserialize-error / type-mismatch counters into the
  /// diagnostics. The subscriber must outlive the node's last poll().
  /// The newest rejection reason of a watched subscriber ("topic 'poise/sensors': invalid sample
  /// rejected: q[3]: not finite") becomes Diagnostics.last_error when its count grows.
  template <class S>
  void watch(const S& subscriber) {
    watched_.push_back({&subscriber.counters(), [&subscriber] { return subscriber.last_error(); }, 0});
  }

  /// Declares a per-tick input of this node (poise/sensors, poise/state, ...): once a first
  /// sample came, the input is STALE when no sample came for `stale_ms`. While an input is
  /// stale the diagnostics say HEALTH_FAULT with last_error "no <topic> for N ms (last tick k)",
  /// followed by "; newest error: ..." when error() was called since the previous diagnostics
  /// sample (samples arriving but rejected);
  /// both transitions are logged. Returns the id for input_seen(). Configuration time; at most
  /// kMaxInputs inputs.
  int expect_input(const std::string& topic, double stale_ms);
  /// A sample of input `id` arrived (call from the subscriber callback). Any thread; no
  /// allocation, no lock.
  void input_seen(int id, std::uint64_t tick) noexcept;
  /// True while input `id` is stale (as of the last diagnostics).
  bool input_stale(int id) const noexcept;
  /// Times any input went stale since start.
  std::uint64_t stale_events() const noexcept { return stale_events_; }
  static constexpr int kMaxInputs = 8;

  /// A lasting condition of the node (IMU frozen, contact optimiser silent): while set, the
  /// health is at least `health` and last_error is `text` (logged on each change). `text` must
  /// stay valid (a literal); nullptr clears it. No allocation.
  void set_condition(msg::NodeHealth health, const char* text) noexcept;

  /// --output-readers: waits until each publisher has matched `options().output_readers`
  /// readers (at most the timeout; a warning names the ones short of it), then logs
  /// "output readers matched" (launchers wait for that line). Configuration time.
  template <class... P>
  void wait_for_output_readers(const P&... publishers) {
    if (options_.output_readers <= 0) return;
    const auto timeout = std::chrono::milliseconds(options_.output_readers_timeout_ms);
    bool all = true;
    (
        [&] {
          if (!publishers.wait_for_matches(options_.output_readers, timeout)) {
            all = false;
            dds::log(dds::LogLevel::warn, "%s: %d of %d readers matched after %d ms",
                     publishers.topic_name().c_str(), publishers.matched(),
                     options_.output_readers, options_.output_readers_timeout_ms);
          }
        }(),
        ...);
    dds::log(all ? dds::LogLevel::info : dds::LogLevel::warn, "output readers matched%s",
             all ? "" : " (some short, see above): starting anyway");
  }

  /// The node expects one writer on this input topic (the robot's sensors, the controller's
  /// commands): more matched writers are reported as an error (counted, logged,
  /// Diagnostics.last_error) with the next diagnostics, each time their number changes. A second
  /// writer on a control topic is another process driving this node. Configuration time.
  /// The count comes from the participant's own discovery table (Participant::writers_of),
  /// never from a vendor status call: those take the reader's lock, which Fast DDS holds while
  /// it runs a listener that waits for the node's mutex, under which diagnostics are published.
  void expect_one_writer(std::string topic) {
    single_writers_.push_back({std::move(topic), 1});
  }
  template <class S>
  void expect_one_writer(const S& subscriber) {
    expect_one_writer(subscriber.topic_name());
  }
  /// Times a topic of expect_one_writer() was seen with a new number of writers above one.
  std::uint64_t extra_writer_events() const noexcept { return extra_writer_events_; }

  /// False once a shutdown was requested (signal or request_shutdown()).
  bool running() const noexcept { return !shutdown_requested(); }

  /// Starts a tick's accounting: the DDS writes of publish() from here to tick_done() are the
  /// tick's "dds write" time. Call it where the tick's compute time starts (publications outside
  /// a tick, such as the answer to a repeated input, then count for no tick).
  void tick_begin() noexcept { tick_dds_write_ns_ = 0; }
  /// One handled tick: its number and the node's compute time for it [ns].
  void tick_done(std::uint64_t tick, std::int64_t compute_ns) noexcept;
  /// The same, with the part of compute_ns spent in the node's library call (estimator update,
  /// controller phases, contact solve): the summary then splits the compute time into
  /// "library_us_run", "dds_write_us_run" (publish()'s serialisation and vendor write since
  /// tick_begin()) and "overhead_us_run", the rest: the node's own work (conversions,
  /// validation, sequencing, diagnostics, locking). library + overhead + dds write = compute.
  void tick_done(std::uint64_t tick, std::int64_t compute_ns, std::int64_t library_ns) noexcept;
  /// A tick that missed its deadline (counted; the caller logs via error() if it wants).
  void deadline_miss() noexcept { ++deadline_misses_; }
  std::uint64_t deadline_misses() const noexcept { return deadline_misses_; }
  std::uint64_t ticks() const noexcept { return ticks_; }

  /// Counts an error, keeps its text as the last error and logs it (at most one line per second;
  /// lines in between are counted and reported with the next one).
  void error(const char* format, ...) noexcept __attribute__((format(printf, 2, 3)));
  std::uint64_t errors() const noexcept { return errors_; }

  /// Sets the health reported from now on.
  void set_health(msg::NodeHealth health) noexcept { health_ = health; }

  /// Publishes `sample` unless it holds a non-finite number or an out-of-range length (the same
  /// check receivers make): then nothing is sent, the error is counted and logged with the
  /// field, and false is returned. The write (serialisation + vendor write) is timed for the
  /// tick's "dds write" figure (tick_begin()). Never throws, no allocation.
  template <class P, class T>
  bool publish(P& publisher, const T& sample) noexcept {
    reflect::ValidationError why;
    if (!reflect::validate(sample, &why)) {
      ++non_finite_;
      error("not publishing %s: %s: %s", publisher.topic_name().c_str(), why.path, why.reason);
      return false;
    }
    const std::int64_t t_write = now_ns();
    const bool sent = publisher.publish(sample);
    tick_dds_write_ns_ += now_ns() - t_write;
    if (!sent) {
      error("publish on %s failed", publisher.topic_name().c_str());
      return false;
    }
    return true;
  }
  /// Samples refused by publish() since start.
  std::uint64_t non_finite_refused() const noexcept { return non_finite_; }

  /// Publishes the diagnostics if due (at diagnostics_hz). Returns the monotonic time [ns] of
  /// the next publication, so a loop can bound its waits by it.
  std::int64_t poll() noexcept;
  /// Publishes the diagnostics now.
  void publish_diagnostics() noexcept;

  /// For nodes that do their per-tick work in a subscriber callback (on the DDS listener thread,
  /// which saves the wake-up of a loop thread per sample): runs poll() under `state_mutex` at the
  /// diagnostics rate until shutdown is requested. The callback must hold the same mutex while
  /// it uses the node (tick_done, publish, error). Call from the main thread.
  void serve(std::mutex& state_mutex) noexcept;
  /// The last published diagnostics sample.
  const msg::Diagnostics& diagnostics() const noexcept { return diag_; }

  /// Writes the summary file (--summary) if one was asked for: {"node", "diagnostics" (a final
  /// sample, JSON form), "compute_us_run" {p50, p99, max, mean} over the whole run,
  /// "compute_us_max_all", plus the members of `extra_json` (a JSON object text, may be empty)}.
  /// Configuration time (allocates); never throws (logs on failure).
  void write_summary(const std::string& extra_json = "");

 private:
  NodeOptions options_;
  std::unique_ptr<dds::Participant> participant_;
  std::unique_ptr<dds::Publisher<msg::Diagnostics>> diag_pub_;
  struct Watched {
    const dds::SubscriberCounters* counters;
    std::function<std::string()> last_error;
    std::uint64_t seen;  ///< rejections already reported
  };
  std::vector<Watched> watched_;
  struct Input {
    std::string topic;
    std::int64_t stale_ns = 0;
    std::atomic<std::int64_t> last_ns{0};  ///< 0: no sample yet
    std::atomic<std::uint64_t> last_tick{0};
    bool stale = false;
  };
  std::array<Input, kMaxInputs> inputs_;
  int num_inputs_ = 0;
  std::uint64_t stale_events_ = 0;
  msg::NodeHealth condition_health_ = msg::HEALTH_OK;
  const char* condition_ = nullptr;
  struct SingleWriter {
    std::string topic;
    int reported;  ///< the writer count the diagnostics last saw
  };
  std::vector<SingleWriter> single_writers_;
  std::uint64_t extra_writer_events_ = 0;
  msg::Diagnostics diag_;
  ComputeStats compute_;
  LatencyHistogram compute_run_{20000};  ///< whole run, 1 us bins up to 20 ms
  /// The split of compute_run_ (tick_done with library time): 0.1 us bins up to 20 ms.
  LatencyHistogram library_run_{20000, 0.1}, overhead_run_{20000, 0.1}, dds_write_run_{20000, 0.1};
  std::int64_t tick_dds_write_ns_ = 0;  ///< publish() writes since tick_begin()
  msg::NodeHealth health_ = msg::HEALTH_OK;
  std::uint64_t last_tick_ = 0;
  std::uint64_t ticks_ = 0;
  std::uint64_t deadline_misses_ = 0;
  std::uint64_t errors_ = 0;
  std::uint64_t non_finite_ = 0;
  std::vector<std::string> rt_applied_, rt_refused_;  ///< what apply_process_realtime() did
  PageFaults faults_at_first_tick_, faults_in_loop_;  ///< see tick_done()
  std::uint64_t suppressed_logs_ = 0;
  std::int64_t last_log_ns_ = 0;
  std::int64_t period_ns_ = 100'000'000;
  std::int64_t next_diag_ns_ = 0;
  char last_error_[256] = {};
  bool error_since_diag_ = false;  ///< error() called since the last diagnostics sample
};

}  // namespace poise::node
