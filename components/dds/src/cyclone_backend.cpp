// Cyclone DDS 0.10 backend: one domain per domain id per process (configured from the XML file),
// one participant, topics on the CDR sertype of cyclone_serdata.cpp, builtin-topic readers for
// discovery.
#include <time.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <map>
#include <mutex>
#include <stdexcept>

#include <dds/dds.h>

#include "cyclone_serdata.hpp"
#include "poise/dds/detail/backend.hpp"
#include "poise/dds/log.hpp"

namespace poise::dds::detail {
namespace {

std::string rc_text(dds_return_t rc) {
  return std::string(dds_strretcode(rc));
}

std::int64_t realtime_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

dds_duration_t to_duration(std::chrono::nanoseconds d) {
  return d == Qos::infinite ? DDS_INFINITY : static_cast<dds_duration_t>(d.count());
}

/// Domains are process-wide in Cyclone: create each once with our config, count its users.
class DomainRegistry {
 public:
  static DomainRegistry& instance() {
    static DomainRegistry r;
    return r;
  }
  void acquire(int domain_id, const std::string& config_path) {
    std::lock_guard lock(mutex_);
    auto& e = domains_[domain_id];
    if (e.refs++ > 0) {
      if (e.config != config_path) {
        log(LogLevel::warn,
            "Cyclone domain %d is already configured from '%s' in this process; '%s' is ignored",
            domain_id, e.config.c_str(), config_path.c_str());
      }
      return;
    }
    // Cyclone suspends a reliable writer whose unacknowledged bytes exceed its WHC high-water
    // mark (adaptive: 30 kB at first, grown towards 500 kB while writers hit it). The control
    // topics' writers keep 32 samples of up to 2.6 kB for a lagging reader (Qos::control()):
    // start the mark at its maximum, so that a slow reader never has a writer wait for the mark
    // to grow. The user's file comes second and wins.
    const std::string uri =
        "<Internal><Watermarks><WhcHighInit>500 kB</WhcHighInit></Watermarks></Internal>,file://" +
        config_path;
    const dds_entity_t d = dds_create_domain(static_cast<dds_domainid_t>(domain_id), uri.c_str());
    if (d < 0) {
      --e.refs;
      domains_.erase(domain_id);
      throw std::runtime_error("Cyclone could not create the domain: " + rc_text(d));
    }
    e.handle = d;
    e.config = config_path;
  }
  void release(int domain_id) {
    std::lock_guard lock(mutex_);
    auto it = domains_.find(domain_id);
    if (it == domains_.end() || --it->second.refs > 0) return;
    dds_delete(it->second.handle);
    domains_.erase(it);
  }

 private:
  struct Entry {
    dds_entity_t handle = 0;
    int refs = 0;
    std::string config;
  };
  std::mutex mutex_;
  std::map<int, Entry> domains_;
};

dds_qos_t* make_qos(const Qos& q, bool writer) {
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos,
                       q.reliability == Reliability::reliable ? DDS_RELIABILITY_RELIABLE
                                                              : DDS_RELIABILITY_BEST_EFFORT,
                       DDS_SECS(1));
  dds_qset_durability(qos, q.durability == Durability::transient_local
                               ? DDS_DURABILITY_TRANSIENT_LOCAL
                               : DDS_DURABILITY_VOLATILE);
  const int depth = std::max(1, q.history_depth);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, writer ? q.writer_depth() : depth);
  if (q.durability == Durability::transient_local) {
    // Late joiners get the durability-service history, keep-last 1 by default: match the depth.
    dds_qset_durability_service(qos, 0, DDS_HISTORY_KEEP_LAST, depth, DDS_LENGTH_UNLIMITED,
                                DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  }
  dds_qset_deadline(qos, to_duration(q.deadline));
  dds_liveliness_kind_t kind = DDS_LIVELINESS_AUTOMATIC;
  if (q.liveliness == Liveliness::manual_by_participant)
    kind = DDS_LIVELINESS_MANUAL_BY_PARTICIPANT;
  if (q.liveliness == Liveliness::manual_by_topic) kind = DDS_LIVELINESS_MANUAL_BY_TOPIC;
  dds_qset_liveliness(qos, kind, to_duration(q.liveliness_lease));
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  return qos;
}

/// The plugin library: Debian installs Cyclone's security plugins beside libddsc's private
/// directory, which the loader does not search.
std::string plugin_path(const char* name) {
  const std::string debian = std::string("/usr/lib/x86_64-linux-gnu/libddsc0debian/lib") + name +
                             ".so";
  std::error_code ec;
  return std::filesystem::exists(debian, ec) ? debian : name;
}

/// DDS Security through the participant's QoS properties (the OMG plugins Cyclone ships).
void set_security(dds_qos_t* qos, const BackendOptions::Security& s) {
  auto file = [](const std::string& p) { return "file:" + p; };
  dds_qset_prop(qos, "dds.sec.auth.library.path", plugin_path("dds_security_auth").c_str());
  dds_qset_prop(qos, "dds.sec.auth.library.init", "init_authentication");
  dds_qset_prop(qos, "dds.sec.auth.library.finalize", "finalize_authentication");
  dds_qset_prop(qos, "dds.sec.crypto.library.path", plugin_path("dds_security_crypto").c_str());
  dds_qset_prop(qos, "dds.sec.crypto.library.init", "init_crypto");
  dds_qset_prop(qos, "dds.sec.crypto.library.finalize", "finalize_crypto");
  dds_qset_prop(qos, "dds.sec.access.library.path", plugin_path("dds_security_ac").c_str());
  dds_qset_prop(qos, "dds.sec.access.library.init", "init_access_control");
  dds_qset_prop(qos, "dds.sec.access.library.finalize", "finalize_access_control");
  dds_qset_prop(qos, "dds.sec.auth.identity_ca", file(s.ca).c_str());
  dds_qset_prop(qos, "dds.sec.auth.identity_certificate", file(s.certificate).c_str());
  dds_qset_prop(qos, "dds.sec.auth.private_key", file(s.private_key).c_str());
  dds_qset_prop(qos, "dds.sec.access.permissions_ca", file(s.ca).c_str());
  dds_qset_prop(qos, "dds.sec.access.governance", file(s.governance).c_str());
  dds_qset_prop(qos, "dds.sec.access.permissions", file(s.permissions).c_str());
}

dds_entity_t make_topic(dds_entity_t participant, const std::string& topic_name,
                        const std::string& type_name) {
  ddsi_sertype* st = cyclone_make_cdr_sertype(type_name);
  const dds_entity_t t =
      dds_create_topic_sertype(participant, topic_name.c_str(), &st, nullptr, nullptr, nullptr);
  if (t < 0) {
    cyclone_free_sertype(st);
    throw std::runtime_error("Cyclone refused topic '" + topic_name + "' of type '" + type_name +
                             "': " + rc_text(t));
  }
  return t;
}

class CycloneWriter final : public WriterBackend {
 public:
  CycloneWriter(dds_entity_t topic, dds_entity_t writer) : topic_(topic), writer_(writer) {}
  ~CycloneWriter() override {
    dds_delete(writer_);
    dds_delete(topic_);
  }
  bool write(const std::uint8_t* data, std::size_t size) noexcept override {
    const CycloneCdrSpan span{data, static_cast<std::uint32_t>(size)};
    return dds_write(writer_, &span) == DDS_RETCODE_OK;
  }
  bool wait_for_acks(std::chrono::nanoseconds timeout) noexcept override {
    return dds_wait_for_acks(writer_, static_cast<dds_duration_t>(timeout.count())) ==
           DDS_RETCODE_OK;
  }
  int matched() const noexcept override {
    dds_publication_matched_status_t st{};
    if (dds_get_publication_matched_status(writer_, &st) != DDS_RETCODE_OK) return 0;
    return static_cast<int>(st.current_count);
  }

 private:
  dds_entity_t topic_;
  dds_entity_t writer_;
};

class CycloneReader final : public ReaderBackend {
 public:
  CycloneReader(dds_entity_t participant, const std::string& topic_name,
                const std::string& type_name, const Qos& q) {
    topic_ = make_topic(participant, topic_name, type_name);
    dds_qos_t* qos = make_qos(q, /*writer=*/false);
    dds_listener_t* listener = dds_create_listener(this);
    dds_lset_data_available(listener, &CycloneReader::on_data_available);
    reader_ = dds_create_reader(participant, topic_, qos, listener);
    dds_delete_listener(listener);
    dds_delete_qos(qos);
    if (reader_ < 0) {
      dds_delete(topic_);
      throw std::runtime_error("Cyclone refused a reader on topic '" + topic_name +
                               "': " + rc_text(reader_));
    }
  }
  ~CycloneReader() override {
    dds_set_listener(reader_, nullptr);
    {
      std::lock_guard lock(callback_mutex_);  // wait for a running callback
      callback_ = nullptr;
    }
    dds_delete(reader_);
    dds_delete(topic_);
  }

  bool take(std::vector<std::uint8_t>& bytes, SampleMeta& meta) noexcept override {
    for (;;) {
      ddsi_serdata* sd = nullptr;
      dds_sample_info_t info;
      const dds_return_t n = dds_takecdr(reader_, &sd, 1, &info, DDS_ANY_STATE);
      if (n <= 0) return false;
      const bool ok = info.valid_data && cyclone_serdata_bytes(sd, bytes);
      cyclone_serdata_unref(sd);
      if (!ok) continue;
      meta.source_timestamp_ns = info.source_timestamp;
      meta.reception_timestamp_ns = realtime_ns();
      meta.writer_id = info.publication_handle;
      return true;
    }
  }
  int matched() const noexcept override {
    dds_subscription_matched_status_t st{};
    if (dds_get_subscription_matched_status(reader_, &st) != DDS_RETCODE_OK) return 0;
    return static_cast<int>(st.current_count);
  }
  ReaderLosses losses() const noexcept override {
    ReaderLosses out;
    dds_sample_lost_status_t lost{};
    if (dds_get_sample_lost_status(reader_, &lost) == DDS_RETCODE_OK) out.lost = lost.total_count;
    dds_sample_rejected_status_t rejected{};
    if (dds_get_sample_rejected_status(reader_, &rejected) == DDS_RETCODE_OK)
      out.rejected = rejected.total_count;
    return out;
  }
  void set_on_data_available(std::function<void()> callback) override {
    std::lock_guard lock(callback_mutex_);
    callback_ = std::move(callback);
    if (callback_) callback_();  // data that arrived before the callback was set
  }

 private:
  static void on_data_available(dds_entity_t, void* arg) {
    auto* self = static_cast<CycloneReader*>(arg);
    std::lock_guard lock(self->callback_mutex_);
    if (self->callback_) self->callback_();
  }

  dds_entity_t topic_ = 0;
  dds_entity_t reader_ = 0;
  std::mutex callback_mutex_;
  std::function<void()> callback_;
};

class CycloneParticipant final : public ParticipantBackend {
 public:
  explicit CycloneParticipant(const BackendOptions& o)
      : domain_id_(o.domain_id), on_endpoint_(o.on_endpoint) {
    DomainRegistry::instance().acquire(domain_id_, o.config_path);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_entity_name(qos, o.participant_name.c_str());
    if (!o.security.ca.empty()) set_security(qos, o.security);
    participant_ = dds_create_participant(static_cast<dds_domainid_t>(domain_id_), qos, nullptr);
    dds_delete_qos(qos);
    if (participant_ < 0) {
      DomainRegistry::instance().release(domain_id_);
      throw std::runtime_error("Cyclone refused to create the participant: " +
                               rc_text(participant_));
    }
    dds_get_guid(participant_, &own_guid_);
    if (on_endpoint_) {
      dds_listener_t* l = dds_create_listener(this);
      dds_lset_data_available(l, &CycloneParticipant::on_builtin_writers);
      pub_reader_ = dds_create_reader(participant_, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, l);
      dds_lset_data_available(l, &CycloneParticipant::on_builtin_readers);
      sub_reader_ = dds_create_reader(participant_, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, nullptr, l);
      dds_delete_listener(l);
      // Endpoints known before the listeners were installed.
      drain(pub_reader_, true);
      drain(sub_reader_, false);
    }
  }

  ~CycloneParticipant() override {
    {
      std::lock_guard lock(discovery_mutex_);
      closing_ = true;
    }
    if (pub_reader_ > 0) dds_set_listener(pub_reader_, nullptr);
    if (sub_reader_ > 0) dds_set_listener(sub_reader_, nullptr);
    dds_delete(participant_);
    DomainRegistry::instance().release(domain_id_);
  }

  std::unique_ptr<WriterBackend> create_writer(const std::string& topic_name,
                                               const std::string& type_name, std::size_t,
                                               const Qos& q) override {
    const dds_entity_t topic = make_topic(participant_, topic_name, type_name);
    dds_qos_t* qos = make_qos(q, /*writer=*/true);
    const dds_entity_t w = dds_create_writer(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
    if (w < 0) {
      dds_delete(topic);
      throw std::runtime_error("Cyclone refused a writer on topic '" + topic_name +
                               "': " + rc_text(w));
    }
    return std::make_unique<CycloneWriter>(topic, w);
  }

  std::unique_ptr<ReaderBackend> create_reader(const std::string& topic_name,
                                               const std::string& type_name, std::size_t,
                                               const Qos& q) override {
    return std::make_unique<CycloneReader>(participant_, topic_name, type_name, q);
  }

 private:
  static void on_builtin_writers(dds_entity_t reader, void* arg) {
    static_cast<CycloneParticipant*>(arg)->drain(reader, true);
  }
  static void on_builtin_readers(dds_entity_t reader, void* arg) {
    static_cast<CycloneParticipant*>(arg)->drain(reader, false);
  }

  void drain(dds_entity_t reader, bool writers) {
    std::lock_guard lock(discovery_mutex_);
    if (closing_) return;
    constexpr int kMax = 16;
    void* samples[kMax];
    dds_sample_info_t infos[kMax];
    for (;;) {
      std::fill(std::begin(samples), std::end(samples), nullptr);
      const dds_return_t n = dds_take(reader, samples, infos, kMax, kMax);
      if (n <= 0) break;
      for (int i = 0; i < n; ++i) {
        const auto* ep = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
        if (std::memcmp(ep->participant_key.v, own_guid_.v, 12) == 0 && infos[i].valid_data) {
          continue;  // our own endpoints
        }
        EndpointEvent e;
        e.is_writer = writers;
        e.alive = infos[i].valid_data && infos[i].instance_state == DDS_IST_ALIVE;
        std::memcpy(e.guid.data(), ep->key.v, 16);
        if (infos[i].valid_data) {
          e.topic_name = ep->topic_name ? ep->topic_name : "";
          e.type_name = ep->type_name ? ep->type_name : "";
        }
        on_endpoint_(e);
      }
      dds_return_loan(reader, samples, n);
    }
  }

  int domain_id_;
  std::function<void(const EndpointEvent&)> on_endpoint_;
  dds_entity_t participant_ = 0;
  dds_entity_t pub_reader_ = 0;
  dds_entity_t sub_reader_ = 0;
  dds_guid_t own_guid_{};
  std::mutex discovery_mutex_;
  bool closing_ = false;
};

}  // namespace

std::unique_ptr<ParticipantBackend> make_cyclone_backend(const BackendOptions& options) {
  return std::make_unique<CycloneParticipant>(options);
}

}  // namespace poise::dds::detail
