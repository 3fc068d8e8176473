// poise-bench-dds-latency: round-trip latency of one Sensors sample (64 joints, 1.7 KB on the
// wire; reliable, keep-last 1, loopback config) between two processes, for
//   cyclone-cyclone, fastdds-fastdds and cyclone-fastdds (ping side - echo side),
// through our layer (poise::dds Publisher/Subscriber) and through the raw vendor APIs (Fast DDS
// DataWriter/DataReader with the fastddsgen type; Cyclone dds_write/dds_take with the idlc C type),
// plus `ddsperf ping/pong` (1 KB, same loopback config) as the floor. Prints median, p99, max.
// Api "wd1" is the layer with writers keep-last 1 instead of the control topics' 32: the cost of
// the deeper writer history that lets a lagging recorder catch up.
//
// Both sides wait the same way (vendor listener -> condition variable), so the layer-vs-raw
// difference is our serialisation, copies and dispatch. The echo side is this program started
// again with --echo; every child is bounded in time and killed by pid at the end.
//
//   poise-bench-dds-latency [--samples 5000] [--warmup 500] [--domain N]
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <dds/dds.h>
#include <poise/msg/sensors.h>
#include <poise/msg/sensorsPubSubTypes.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <poise/dds/dds.hpp>

#include "sensors.h"  // idlc C type poise_msg_Sensors

extern char** environ;

#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

// Counts operator new calls (this process, our code and vendor code alike).
static std::atomic<std::uint64_t> g_allocations{0};
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
constexpr const char* kPing = "bench/ping";
constexpr const char* kPong = "bench/pong";

/// Newest tick seen by the receiving side; the ping thread waits on it.
struct Arrival {
  std::mutex mutex;
  std::condition_variable cv;
  std::uint64_t tick = 0;
  void set(std::uint64_t t) {
    {
      std::lock_guard lock(mutex);
      tick = t;
    }
    cv.notify_one();
  }
  bool wait_for(std::uint64_t t, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex);
    return cv.wait_for(lock, timeout, [&] { return tick >= t; });
  }
};

/// One side of one API on one vendor: send(tick) publishes a sample; received ticks go to
/// `on_tick` (ping side) or are echoed (echo side).
class Endpoint {
 public:
  virtual ~Endpoint() = default;
  virtual void send(std::uint64_t tick) = 0;
  virtual int matched() = 0;
};

void fill(poise::msg::Sensors& s) {
  s.joint_count(64);
  for (std::size_t i = 0; i < 64; ++i) {
    s.q()[i] = 0.01 * static_cast<double>(i);
    s.qd()[i] = -0.02 * static_cast<double>(i);
    s.tau_measured()[i] = 1.5;
  }
  s.imu().orientation_wxyz()[0] = 1.0;
}

// ---------------- our layer ----------------
class LayerEndpoint final : public Endpoint {
 public:
  /// writer_depth 0: the control topics' QoS as shipped (writers keep-last 32).
  LayerEndpoint(poise::dds::Vendor v, int domain, bool echo, Arrival* arrival,
                int writer_depth = 0) {
    poise::dds::DdsOptions o;
    o.vendor = v;
    o.domain_id = domain;
    o.participant_name = echo ? "bench-echo" : "bench-ping";
    participant_ = std::make_unique<poise::dds::Participant>(o);
    auto qos = poise::dds::Qos::control();
    if (writer_depth > 0) qos.writer_history_depth = writer_depth;
    fill(sample_);
    pub_ = std::make_unique<poise::dds::Publisher<poise::msg::Sensors>>(*participant_, qos,
                                                                        echo ? kPong : kPing);
    if (echo) {
      sub_ = std::make_unique<poise::dds::Subscriber<poise::msg::Sensors>>(
          *participant_, [this](const poise::msg::Sensors& s) { pub_->publish(s); }, qos, kPing);
    } else {
      sub_ = std::make_unique<poise::dds::Subscriber<poise::msg::Sensors>>(
          *participant_,
          [arrival](const poise::msg::Sensors& s) { arrival->set(s.header().tick()); }, qos, kPong);
    }
  }
  ~LayerEndpoint() override {
    sub_.reset();
    pub_.reset();
  }
  void send(std::uint64_t tick) override {
    sample_.header().tick(tick);
    pub_->publish(sample_);
  }
  int matched() override { return std::min(pub_->matched(), sub_->matched()); }

 private:
  poise::msg::Sensors sample_;
  std::unique_ptr<poise::dds::Participant> participant_;
  std::unique_ptr<poise::dds::Publisher<poise::msg::Sensors>> pub_;
  std::unique_ptr<poise::dds::Subscriber<poise::msg::Sensors>> sub_;
};

// ---------------- raw Fast DDS ----------------
namespace fdds = eprosima::fastdds::dds;

class RawFastddsEndpoint final : public Endpoint, public fdds::DataReaderListener {
 public:
  RawFastddsEndpoint(int domain, bool echo, Arrival* arrival) : echo_(echo), arrival_(arrival) {
    auto* f = fdds::DomainParticipantFactory::get_instance();
    f->load_XML_profiles_file(poise::dds::default_config_path(poise::dds::Vendor::fastdds));
    fdds::DomainParticipantQos pq;
    f->get_participant_qos_from_profile("poise_participant", pq);
    participant_ = f->create_participant(domain, pq);
    type_ = fdds::TypeSupport(new poise::msg::SensorsPubSubType());
    type_.register_type(participant_);
    ping_ = participant_->create_topic(kPing, type_.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
    pong_ = participant_->create_topic(kPong, type_.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
    auto* pub = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
    auto* sub = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
    fdds::DataWriterQos wq = pub->get_default_datawriter_qos();
    wq.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
    wq.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    wq.history().depth = 1;
    wq.reliable_writer_qos().times.heartbeatPeriod = eprosima::fastrtps::Duration_t(0, 100000000);
    // Same transport as our layer (UDP loopback): the generated type is bounded and plain, so
    // Fast DDS would otherwise pick data-sharing (shared memory) on its own.
    wq.data_sharing().off();
    writer_ = pub->create_datawriter(echo ? pong_ : ping_, wq);
    fdds::DataReaderQos rq = sub->get_default_datareader_qos();
    rq.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
    rq.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    rq.history().depth = 1;
    rq.data_sharing().off();
    reader_ = sub->create_datareader(echo ? ping_ : pong_, rq, this);
    fill(sample_);
  }
  ~RawFastddsEndpoint() override {
    reader_->set_listener(nullptr);
    participant_->delete_contained_entities();
    fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
  }
  void on_data_available(fdds::DataReader* r) override {
    fdds::SampleInfo info;
    while (r->take_next_sample(&received_, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      if (echo_)
        writer_->write(&received_);
      else
        arrival_->set(received_.header().tick());
    }
  }
  void send(std::uint64_t tick) override {
    sample_.header().tick(tick);
    writer_->write(&sample_);
  }
  int matched() override {
    fdds::PublicationMatchedStatus a;
    fdds::SubscriptionMatchedStatus b;
    writer_->get_publication_matched_status(a);
    reader_->get_subscription_matched_status(b);
    return std::min(a.current_count, b.current_count);
  }

 private:
  bool echo_;
  Arrival* arrival_;
  poise::msg::Sensors sample_, received_;
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::TypeSupport type_;
  fdds::Topic* ping_ = nullptr;
  fdds::Topic* pong_ = nullptr;
  fdds::DataWriter* writer_ = nullptr;
  fdds::DataReader* reader_ = nullptr;
};

// ---------------- raw Cyclone ----------------
class RawCycloneEndpoint final : public Endpoint {
 public:
  RawCycloneEndpoint(int domain, bool echo, Arrival* arrival) : echo_(echo), arrival_(arrival) {
    const std::string uri =
        "file://" + poise::dds::default_config_path(poise::dds::Vendor::cyclone);
    domain_ = dds_create_domain(static_cast<dds_domainid_t>(domain), uri.c_str());
    participant_ = dds_create_participant(static_cast<dds_domainid_t>(domain), nullptr, nullptr);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
    dds_qset_data_representation(q, 1, &xcdr1);
    const dds_entity_t ping =
        dds_create_topic(participant_, &poise_msg_Sensors_desc, kPing, q, nullptr);
    const dds_entity_t pong =
        dds_create_topic(participant_, &poise_msg_Sensors_desc, kPong, q, nullptr);
    writer_ = dds_create_writer(participant_, echo ? pong : ping, q, nullptr);
    dds_listener_t* l = dds_create_listener(this);
    dds_lset_data_available(l, &RawCycloneEndpoint::on_data);
    reader_ = dds_create_reader(participant_, echo ? ping : pong, q, l);
    dds_delete_listener(l);
    dds_delete_qos(q);
    std::memset(&sample_, 0, sizeof(sample_));
    sample_.joint_count = 64;
    for (int i = 0; i < 64; ++i) {
      sample_.q[i] = 0.01 * i;
      sample_.qd[i] = -0.02 * i;
      sample_.tau_measured[i] = 1.5;
    }
    sample_.imu.orientation_wxyz[0] = 1.0;
  }
  ~RawCycloneEndpoint() override {
    dds_set_listener(reader_, nullptr);
    dds_delete(participant_);
    dds_delete(domain_);
  }
  static void on_data(dds_entity_t reader, void* arg) {
    auto* self = static_cast<RawCycloneEndpoint*>(arg);
    void* ptr = &self->received_;
    dds_sample_info_t info;
    while (dds_take(reader, &ptr, &info, 1, 1) > 0) {
      if (!info.valid_data) continue;
      if (self->echo_)
        dds_write(self->writer_, &self->received_);
      else
        self->arrival_->set(self->received_.header.tick);
    }
  }
  void send(std::uint64_t tick) override {
    sample_.header.tick = tick;
    dds_write(writer_, &sample_);
  }
  int matched() override {
    dds_publication_matched_status_t a{};
    dds_subscription_matched_status_t b{};
    dds_get_publication_matched_status(writer_, &a);
    dds_get_subscription_matched_status(reader_, &b);
    return static_cast<int>(std::min(a.current_count, b.current_count));
  }

 private:
  bool echo_;
  Arrival* arrival_;
  poise_msg_Sensors sample_{}, received_{};
  dds_entity_t domain_ = 0, participant_ = 0, writer_ = 0, reader_ = 0;
};

std::unique_ptr<Endpoint> make_endpoint(const std::string& api, poise::dds::Vendor v, int domain,
                                        bool echo, Arrival* arrival) {
  if (api == "layer") return std::make_unique<LayerEndpoint>(v, domain, echo, arrival);
  // The layer with writers keep-last 1 (before Qos::control() kept 32 for lagging readers).
  if (api == "wd1") return std::make_unique<LayerEndpoint>(v, domain, echo, arrival, 1);
  if (v == poise::dds::Vendor::fastdds)
    return std::make_unique<RawFastddsEndpoint>(domain, echo, arrival);
  return std::make_unique<RawCycloneEndpoint>(domain, echo, arrival);
}

// ---------------- processes ----------------
struct Child {
  pid_t pid = -1;
  std::string log;
  Child(const std::vector<std::string>& args, std::string log_path,
        const std::vector<std::string>& extra_env = {})
      : log(std::move(log_path)) {
    std::vector<char*> argv;
    for (const auto& a : args)
      argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    std::vector<std::string> env_store;
    for (char** e = environ; *e; ++e)
      env_store.emplace_back(*e);
    for (const auto& e : extra_env)
      env_store.push_back(e);
    std::vector<char*> envp;
    for (auto& e : env_store)
      envp.push_back(e.data());
    envp.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    posix_spawn_file_actions_adddup2(&fa, STDOUT_FILENO, STDERR_FILENO);
    if (posix_spawnp(&pid, argv[0], &fa, nullptr, argv.data(), envp.data()) != 0) pid = -1;
    posix_spawn_file_actions_destroy(&fa);
  }
  ~Child() { stop(); }
  void stop() {
    if (pid <= 0) return;
    ::kill(pid, SIGKILL);
    int st = 0;
    ::waitpid(pid, &st, 0);
    pid = -1;
  }
  std::string output() const {
    std::ifstream in(log);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
};

std::string self_exe() {
  char buf[4096];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  return n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : "poise-bench-dds-latency";
}

struct Stats {
  double median = 0, p99 = 0, max = 0;
  std::size_t n = 0;
  double allocs_per_rt = 0;
  std::string error;
};

Stats run_pairing(const std::string& api, poise::dds::Vendor ping_v, poise::dds::Vendor echo_v,
                  int domain, int samples, int warmup) {
  Stats st;
  const std::string log = "/tmp/poise-bench-echo-" + std::to_string(::getpid()) + ".log";
  Child echo(
      {self_exe(), "--echo", "--api", api, "--dds", std::string(poise::dds::to_string(echo_v)),
       "--domain", std::to_string(domain), "--timeout-s", "120"},
      log);
  if (echo.pid <= 0) {
    st.error = "cannot start the echo process";
    return st;
  }
  Arrival arrival;
  auto ep = make_endpoint(api, ping_v, domain, false, &arrival);
  const auto deadline = Clock::now() + 20s;
  while (ep->matched() < 1) {
    if (Clock::now() > deadline) {
      st.error = "no match within 20 s; echo log: " + echo.output();
      return st;
    }
    std::this_thread::sleep_for(1ms);
  }
  std::this_thread::sleep_for(1500ms);  // remote side's matching (mixed vendors: ~1 s)
  std::vector<double> rt;
  rt.reserve(static_cast<std::size_t>(samples));
  std::uint64_t tick = 0;
  int lost = 0;
  std::uint64_t alloc_before = 0;
  for (int i = 0; i < warmup + samples; ++i) {
    if (i == warmup) alloc_before = g_allocations.load();
    ++tick;
    const auto t0 = Clock::now();
    ep->send(tick);
    if (!arrival.wait_for(tick, 1000ms)) {
      if (++lost > 5) {
        st.error = "echo lost (5 timeouts)";
        return st;
      }
      continue;
    }
    const auto t1 = Clock::now();
    if (i >= warmup) rt.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  st.allocs_per_rt = static_cast<double>(g_allocations.load() - alloc_before) / samples;
  ep.reset();
  echo.stop();
  std::remove(log.c_str());
  std::sort(rt.begin(), rt.end());
  st.n = rt.size();
  if (!rt.empty()) {
    st.median = rt[rt.size() / 2];
    st.p99 = rt[std::min(rt.size() - 1, rt.size() * 99 / 100)];
    st.max = rt.back();
  }
  return st;
}

int run_echo(const std::string& api, poise::dds::Vendor v, int domain, double timeout_s) {
  auto ep = make_endpoint(api, v, domain, true, nullptr);
  std::this_thread::sleep_for(std::chrono::duration<double>(timeout_s));
  return 0;
}

/// ddsperf ping/pong with the loopback config; returns the summary lines' 50%/99%/max (us, as
/// ddsperf prints them) averaged over its per-second reports after the first.
std::string run_ddsperf(int domain, double& p50, double& p99, double& max) {
  const std::string cfg =
      "CYCLONEDDS_URI=file://" + poise::dds::default_config_path(poise::dds::Vendor::cyclone);
  const std::string d = std::to_string(domain);
  const std::string tag = std::to_string(::getpid());
  Child pong({"ddsperf", "-i", d, "-D", "8", "pong"}, "/tmp/poise-ddsperf-pong-" + tag + ".log",
             {cfg});
  Child ping({"ddsperf", "-i", d, "-D", "6", "ping", "size", "1k"},
             "/tmp/poise-ddsperf-ping-" + tag + ".log", {cfg});
  if (ping.pid <= 0 || pong.pid <= 0) return "ddsperf not found";
  for (int i = 0; i < 100; ++i) {  // bounded: 10 s
    int stt = 0;
    if (::waitpid(ping.pid, &stt, WNOHANG) == ping.pid) {
      ping.pid = -1;
      break;
    }
    std::this_thread::sleep_for(100ms);
  }
  ping.stop();
  pong.stop();
  const std::string out = ping.output();
  std::remove(ping.log.c_str());
  std::remove(pong.log.c_str());
  std::regex re(
      R"(size (\d+) mean [\d.]+us min [\d.]+us 50% ([\d.]+)us 90% [\d.]+us 99% ([\d.]+)us max ([\d.]+)us)");
  std::vector<std::array<double, 3>> rows;
  for (std::sregex_iterator it(out.begin(), out.end(), re), end; it != end; ++it) {
    rows.push_back({std::stod((*it)[2]), std::stod((*it)[3]), std::stod((*it)[4])});
  }
  if (rows.size() < 2) return "could not parse ddsperf output:\n" + out;
  p50 = p99 = max = 0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    p50 += rows[i][0];
    p99 += rows[i][1];
    max = std::max(max, rows[i][2]);
  }
  p50 /= static_cast<double>(rows.size() - 1);
  p99 /= static_cast<double>(rows.size() - 1);
  return {};
}

// The command line.
struct BenchArgs {
  poise::dds::DdsOptions dds;
  bool echo = false;
  std::string api = "layer";
  int samples = 5000, warmup = 500;
  double timeout_s = 120;
};

/// Parses the command line (the DDS options first); 0 after --help, else nullopt. Throws
/// std::invalid_argument on a bad option.
std::optional<int> parse_args(int argc, char** argv, BenchArgs& args) {
  args.dds = poise::dds::consume_dds_args(argc, argv);
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--echo") {
      args.echo = true;
    } else if (a == "--api") {
      args.api = next();
    } else if (a == "--samples") {
      args.samples = std::stoi(next());
    } else if (a == "--warmup") {
      args.warmup = std::stoi(next());
    } else if (a == "--timeout-s") {
      args.timeout_s = std::stod(next());
    } else if (a == "--help" || a == "-h") {
      std::printf(
          "usage: poise-bench-dds-latency [--samples N] [--warmup N] [--domain FIRST]\n"
          "Uses 7 consecutive DDS domains from FIRST (default: derived from the pid).\n");
      return 0;
    } else {
      throw std::invalid_argument("unknown option " + a);
    }
  }
  return std::nullopt;
}

// The pairings measured, one domain each: ping side, echo side, api.
struct Row {
  const char* name;
  const char* api;
  poise::dds::Vendor ping, echo;
};
using poise::dds::Vendor;
constexpr Row kRows[] = {
    {"cyclone-cyclone", "layer", Vendor::cyclone, Vendor::cyclone},
    {"cyclone-cyclone", "raw", Vendor::cyclone, Vendor::cyclone},
    {"cyclone-cyclone", "wd1", Vendor::cyclone, Vendor::cyclone},
    {"fastdds-fastdds", "layer", Vendor::fastdds, Vendor::fastdds},
    {"fastdds-fastdds", "raw", Vendor::fastdds, Vendor::fastdds},
    {"fastdds-fastdds", "wd1", Vendor::fastdds, Vendor::fastdds},
    {"cyclone-fastdds", "layer", Vendor::cyclone, Vendor::fastdds},
    {"cyclone-fastdds", "raw", Vendor::cyclone, Vendor::fastdds},
    {"cyclone-fastdds", "wd1", Vendor::cyclone, Vendor::fastdds},
};

/// CPU cost of what our layer adds per sample (same process, no DDS).
void print_layer_cpu(const poise::msg::Sensors& probe) {
  const auto& ts = poise::dds::TopicTraits<poise::msg::Sensors>::type_support();
  std::vector<std::uint8_t> buf(ts.max_serialized_size);
  poise::msg::Sensors out;
  char why[256];
  constexpr int kIter = 20000;
  std::size_t n = 0;
  bool ok = true;
  auto t0 = Clock::now();
  for (int i = 0; i < kIter; ++i)
    n = ts.serialize(&probe, buf.data(), buf.size());
  auto t1 = Clock::now();
  for (int i = 0; i < kIter; ++i)
    ok &= ts.deserialize(buf.data(), n, &out, why, sizeof(why));
  auto t2 = Clock::now();
  for (int i = 0; i < kIter; ++i)
    ok &= ts.validate(&out, why, sizeof(why));
  auto t3 = Clock::now();
  auto us = [](auto d) { return std::chrono::duration<double, std::micro>(d).count() / kIter; };
  std::printf(
      "Layer CPU per sample: serialize %.2f us, deserialize %.2f us, validate %.2f us%s\n\n",
      us(t1 - t0), us(t2 - t1), us(t3 - t2), ok ? "" : " (FAILED)");
}

/// One line per pairing, on the domains from `base`; returns the next free domain.
int run_pairings(int base, int samples, int warmup) {
  std::printf("%-16s %-6s %10s %10s %10s %14s\n", "ping-echo", "api", "median", "p99", "max",
              "allocs/rt*");
  std::fflush(stdout);
  int domain = base;
  double layer_median = 0;
  for (const Row& r : kRows) {
    const Stats s = run_pairing(r.api, r.ping, r.echo, domain++, samples, warmup);
    if (!s.error.empty()) {
      std::printf("%-16s %-6s FAILED: %s\n", r.name, r.api, s.error.c_str());
      continue;
    }
    std::printf("%-16s %-6s %10.1f %10.1f %10.1f %14.2f", r.name, r.api, s.median, s.p99, s.max,
                s.allocs_per_rt);
    if (std::string(r.api) == "layer") {
      layer_median = s.median;
    } else if (std::string(r.api) == "raw") {
      std::printf("   layer - raw (median): %+.1f", layer_median - s.median);
    } else {
      std::printf("   layer (writers keep-last 32) / writers keep-last 1 (median): %.2f",
                  layer_median / s.median);
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  return domain;
}

/// The floor: ddsperf ping/pong on `domain`.
void print_ddsperf_floor(int domain) {
  double p50 = 0, p99 = 0, max = 0;
  const std::string err = run_ddsperf(domain, p50, p99, max);
  if (!err.empty()) {
    std::printf("ddsperf: %s\n", err.c_str());
  } else {
    std::printf(
        "%-16s %-6s %10.1f %10.1f %10.1f   (ddsperf ping size 1k; it prints half the round "
        "trip: %.1f / %.1f / %.1f)\n",
        "ddsperf", "floor", 2 * p50, 2 * p99, 2 * max, p50, p99, max);
  }
}

int run_bench(const BenchArgs& args) {
  if (args.samples < 100) throw std::invalid_argument("--samples must be >= 100");
  const int base = args.dds.domain_id != 0 ? args.dds.domain_id
                                           : 10 + static_cast<int>(::getpid() % 20) * 10;
  if (base + 9 > 232) throw std::invalid_argument("--domain must be <= 223");
  poise::msg::Sensors probe;
  fill(probe);
  const auto& ts = poise::dds::TopicTraits<poise::msg::Sensors>::type_support();
  std::printf(
      "DDS round trip: Sensors sample of %zu bytes (CDR incl. header), reliable keep-last 1,\n"
      "loopback configs (deploy/dds), separate echo process, %d round trips after %d warm-up,\n"
      "domains %d..%d. Times in microseconds.\n\n",
      ts.serialized_size(&probe), args.samples, args.warmup, base, base + 9);
  print_layer_cpu(probe);
  const int domain = run_pairings(base, args.samples, args.warmup);
  print_ddsperf_floor(domain);
  std::printf(
      "\n* operator new calls per round trip in the ping process (our code + vendor internals;\n"
      "  the Cyclone path also mallocs one serdata per sample, not counted here).\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    BenchArgs args;
    if (const auto code = parse_args(argc, argv, args)) return *code;
    if (args.echo) return run_echo(args.api, args.dds.vendor, args.dds.domain_id, args.timeout_s);
    return run_bench(args);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-bench-dds-latency: %s\n", e.what());
    return 2;
  }
}
