// Fast DDS 2.9 backend: DomainParticipant + one Publisher and Subscriber, a generic TopicDataType
// that moves the serialised bytes (4-byte encapsulation header + CDR) of any type.
#include <time.h>

#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>

#include <fastdds/rtps/common/SerializedPayload.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "poise/dds/detail/backend.hpp"
#include "poise/dds/log.hpp"

namespace poise::dds::detail {
namespace {

namespace fdds = eprosima::fastdds::dds;
namespace frtps = eprosima::fastrtps::rtps;
using eprosima::fastrtps::Duration_t;

/// The "sample" our TopicDataType handles: bytes to write, or a vector to receive into.
struct CdrSample {
  const std::uint8_t* data = nullptr;
  std::uint32_t size = 0;
  std::vector<std::uint8_t>* out = nullptr;  // receive target; `own` when null
  std::vector<std::uint8_t> own;
};

class CdrTopicDataType final : public fdds::TopicDataType {
 public:
  CdrTopicDataType(const std::string& type_name, std::size_t max_size) {
    setName(type_name.c_str());
    m_typeSize = static_cast<std::uint32_t>(max_size > 0 ? max_size : 4096);
    m_isGetKeyDefined = false;
  }

  bool serialize(void* data, frtps::SerializedPayload_t* payload) override {
    const auto* s = static_cast<const CdrSample*>(data);
    if (s->size < 4 || s->size > payload->max_size) return false;
    std::memcpy(payload->data, s->data, s->size);
    payload->length = s->size;
    payload->encapsulation = s->data[1] == 0 ? CDR_BE : CDR_LE;
    return true;
  }

  bool deserialize(frtps::SerializedPayload_t* payload, void* data) override {
    auto* s = static_cast<CdrSample*>(data);
    auto* target = s->out ? s->out : &s->own;
    try {
      target->assign(payload->data, payload->data + payload->length);
    } catch (...) {
      return false;
    }
    s->data = target->data();
    s->size = payload->length;
    return true;
  }

  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data]() -> std::uint32_t { return static_cast<const CdrSample*>(data)->size; };
  }

  void* createData() override { return new CdrSample(); }
  void deleteData(void* data) override { delete static_cast<CdrSample*>(data); }
  bool getKey(void*, frtps::InstanceHandle_t*, bool) override { return false; }
};

/// A 64-bit identifier of an instance handle (a writer's GUID): FNV-1a of its 16 bytes.
std::uint64_t handle_id(const frtps::InstanceHandle_t& h) {
  std::uint64_t x = 1469598103934665603ULL;
  for (std::size_t i = 0; i < 16; ++i) {
    x ^= static_cast<std::uint8_t>(h.value[i]);
    x *= 1099511628211ULL;
  }
  return x;
}

Duration_t to_duration(std::chrono::nanoseconds d) {
  if (d == Qos::infinite) return eprosima::fastrtps::c_TimeInfinite;
  const auto ns = d.count();
  return Duration_t(static_cast<std::int32_t>(ns / 1000000000),
                    static_cast<std::uint32_t>(ns % 1000000000));
}

template <class EndpointQos>
void apply_common(const Qos& q, EndpointQos& eq, bool writer) {
  eq.reliability().kind = q.reliability == Reliability::reliable
                              ? fdds::RELIABLE_RELIABILITY_QOS
                              : fdds::BEST_EFFORT_RELIABILITY_QOS;
  eq.durability().kind = q.durability == Durability::transient_local
                             ? fdds::TRANSIENT_LOCAL_DURABILITY_QOS
                             : fdds::VOLATILE_DURABILITY_QOS;
  eq.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  eq.history().depth = writer ? q.writer_depth() : std::max(1, q.history_depth);
  eq.deadline().period = to_duration(q.deadline);
  switch (q.liveliness) {
    case Liveliness::automatic:
      eq.liveliness().kind = fdds::AUTOMATIC_LIVELINESS_QOS;
      break;
    case Liveliness::manual_by_participant:
      eq.liveliness().kind = fdds::MANUAL_BY_PARTICIPANT_LIVELINESS_QOS;
      break;
    case Liveliness::manual_by_topic:
      eq.liveliness().kind = fdds::MANUAL_BY_TOPIC_LIVELINESS_QOS;
      break;
  }
  eq.liveliness().lease_duration = to_duration(q.liveliness_lease);
  if (q.liveliness_lease != Qos::infinite) {
    eq.liveliness().announcement_period = to_duration(q.liveliness_lease / 3);
  }
  // Samples may grow past the type's bound guess (unbounded strings): reallocate on demand.
  eq.endpoint().history_memory_policy = frtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
}

std::array<std::uint8_t, 16> to_bytes(const frtps::GUID_t& g) {
  std::array<std::uint8_t, 16> out{};
  std::memcpy(out.data(), g.guidPrefix.value, 12);
  std::memcpy(out.data() + 12, g.entityId.value, 4);
  return out;
}

class FastddsWriter final : public WriterBackend {
 public:
  FastddsWriter(fdds::Publisher* pub, fdds::DataWriter* w, std::function<void()> release)
      : publisher_(pub), writer_(w), release_(std::move(release)) {}
  ~FastddsWriter() override {
    publisher_->delete_datawriter(writer_);
    release_();
  }
  bool write(const std::uint8_t* data, std::size_t size) noexcept override {
    CdrSample s;
    s.data = data;
    s.size = static_cast<std::uint32_t>(size);
    return writer_->write(&s);
  }
  bool wait_for_acks(std::chrono::nanoseconds timeout) noexcept override {
    const auto ns = timeout.count();
    return writer_->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(
               static_cast<std::int32_t>(ns / 1000000000),
               static_cast<std::uint32_t>(ns % 1000000000))) == ReturnCode_t::RETCODE_OK;
  }
  int matched() const noexcept override {
    fdds::PublicationMatchedStatus st;
    writer_->get_publication_matched_status(st);
    return st.current_count;
  }

 private:
  fdds::Publisher* publisher_;
  fdds::DataWriter* writer_;
  std::function<void()> release_;
};

class FastddsReader final : public ReaderBackend, public fdds::DataReaderListener {
 public:
  FastddsReader(fdds::Subscriber* sub, std::function<void()> release)
      : subscriber_(sub), release_(std::move(release)) {}
  ~FastddsReader() override {
    if (reader_) {
      reader_->set_listener(nullptr);
      std::lock_guard lock(callback_mutex_);  // wait for a running callback
      subscriber_->delete_datareader(reader_);
    }
    release_();
  }
  void attach(fdds::DataReader* r) { reader_ = r; }

  bool take(std::vector<std::uint8_t>& bytes, SampleMeta& meta) noexcept override {
    CdrSample s;
    s.out = &bytes;
    fdds::SampleInfo info;
    while (reader_->take_next_sample(&s, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      meta.source_timestamp_ns = info.source_timestamp.to_ns();
      meta.reception_timestamp_ns = info.reception_timestamp.to_ns();
      meta.writer_id = handle_id(info.publication_handle);
      return true;
    }
    return false;
  }
  int matched() const noexcept override {
    fdds::SubscriptionMatchedStatus st;
    reader_->get_subscription_matched_status(st);
    return st.current_count;
  }
  ReaderLosses losses() const noexcept override {
    ReaderLosses out;
    fdds::SampleLostStatus lost;
    if (reader_->get_sample_lost_status(lost) == ReturnCode_t::RETCODE_OK)
      out.lost = static_cast<std::uint64_t>(lost.total_count);
    fdds::SampleRejectedStatus rejected;
    if (reader_->get_sample_rejected_status(rejected) == ReturnCode_t::RETCODE_OK)
      out.rejected = rejected.total_count;
    return out;
  }
  void set_on_data_available(std::function<void()> callback) override {
    std::lock_guard lock(callback_mutex_);
    callback_ = std::move(callback);
    if (callback_) callback_();  // data that arrived before the callback was set
  }
  void on_data_available(fdds::DataReader*) override {
    std::lock_guard lock(callback_mutex_);
    if (callback_) callback_();
  }

 private:
  fdds::Subscriber* subscriber_;
  fdds::DataReader* reader_ = nullptr;
  std::function<void()> release_;
  std::mutex callback_mutex_;
  std::function<void()> callback_;
};

class FastddsParticipant final : public ParticipantBackend, public fdds::DomainParticipantListener {
 public:
  explicit FastddsParticipant(const BackendOptions& o) : on_endpoint_(o.on_endpoint) {
    auto* factory = fdds::DomainParticipantFactory::get_instance();
    {
      // Profiles are process-wide in Fast DDS; loading the same file twice is harmless.
      static std::mutex load_mutex;
      std::lock_guard lock(load_mutex);
      if (factory->load_XML_profiles_file(o.config_path) != ReturnCode_t::RETCODE_OK) {
        throw std::runtime_error("Fast DDS could not load the XML profiles");
      }
    }
    fdds::DomainParticipantQos pqos;
    if (factory->get_participant_qos_from_profile("poise_participant", pqos) !=
        ReturnCode_t::RETCODE_OK) {
      pqos = factory->get_default_participant_qos();
    }
    pqos.name(o.participant_name);
    if (!o.security.ca.empty()) {
      // DDS Security: the builtin PKI-DH, Access-Permissions and AES-GCM-GMAC plugins.
      auto& props = pqos.properties().properties();
      auto file = [](const std::string& p) { return "file://" + p; };
      const std::pair<const char*, std::string> sec[] = {
          {"dds.sec.auth.plugin", "builtin.PKI-DH"},
          {"dds.sec.auth.builtin.PKI-DH.identity_ca", file(o.security.ca)},
          {"dds.sec.auth.builtin.PKI-DH.identity_certificate", file(o.security.certificate)},
          {"dds.sec.auth.builtin.PKI-DH.private_key", file(o.security.private_key)},
          {"dds.sec.access.plugin", "builtin.Access-Permissions"},
          {"dds.sec.access.builtin.Access-Permissions.permissions_ca", file(o.security.ca)},
          {"dds.sec.access.builtin.Access-Permissions.governance", file(o.security.governance)},
          {"dds.sec.access.builtin.Access-Permissions.permissions", file(o.security.permissions)},
          {"dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC"}};
      for (const auto& [k, v] : sec)
        props.emplace_back(k, v);
    }
    participant_ = factory->create_participant(static_cast<fdds::DomainId_t>(o.domain_id), pqos,
                                               this, fdds::StatusMask::none());
    if (!participant_) throw std::runtime_error("Fast DDS refused to create the participant");
    publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
    subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
    if (!publisher_ || !subscriber_) {
      throw std::runtime_error("Fast DDS refused to create the publisher/subscriber");
    }
  }

  ~FastddsParticipant() override {
    {
      std::lock_guard lock(mutex_);
      closing_ = true;
    }
    participant_->set_listener(nullptr);
    participant_->delete_contained_entities();
    fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
  }

  std::unique_ptr<WriterBackend> create_writer(const std::string& topic_name,
                                               const std::string& type_name, std::size_t max_size,
                                               const Qos& qos) override {
    fdds::Topic* topic = acquire_topic(topic_name, type_name, max_size);
    fdds::DataWriterQos wq = publisher_->get_default_datawriter_qos();
    apply_common(qos, wq, /*writer=*/true);
    // Cyclone readers wait for a heartbeat before they acknowledge: the default 3 s period
    // delays reliable delivery to them (dds-notes.md).
    wq.reliable_writer_qos().times.heartbeatPeriod = Duration_t(0, 100000000);
    fdds::DataWriter* w = publisher_->create_datawriter(topic, wq, nullptr);
    if (!w) {
      release_topic(topic_name);
      throw std::runtime_error("Fast DDS refused a writer on topic '" + topic_name + "'");
    }
    return std::make_unique<FastddsWriter>(publisher_, w,
                                           [this, topic_name] { release_topic(topic_name); });
  }

  std::unique_ptr<ReaderBackend> create_reader(const std::string& topic_name,
                                               const std::string& type_name, std::size_t max_size,
                                               const Qos& qos) override {
    fdds::Topic* topic = acquire_topic(topic_name, type_name, max_size);
    fdds::DataReaderQos rq = subscriber_->get_default_datareader_qos();
    apply_common(qos, rq, /*writer=*/false);
    auto reader = std::make_unique<FastddsReader>(
        subscriber_, [this, topic_name] { release_topic(topic_name); });
    fdds::DataReader* r =
        subscriber_->create_datareader(topic, rq, reader.get(), fdds::StatusMask::data_available());
    if (!r) {
      throw std::runtime_error("Fast DDS refused a reader on topic '" + topic_name + "'");
    }
    reader->attach(r);
    return reader;
  }

  // Discovery of other participants' endpoints.
  void on_publisher_discovery(fdds::DomainParticipant*,
                              frtps::WriterDiscoveryInfo&& info) override {
    report(true, info.status != frtps::WriterDiscoveryInfo::REMOVED_WRITER, info.info.guid(),
           info.info.topicName().to_string(), info.info.typeName().to_string());
  }
  void on_subscriber_discovery(fdds::DomainParticipant*,
                               frtps::ReaderDiscoveryInfo&& info) override {
    report(false, info.status != frtps::ReaderDiscoveryInfo::REMOVED_READER, info.info.guid(),
           info.info.topicName().to_string(), info.info.typeName().to_string());
  }

 private:
  void report(bool writer, bool alive, const frtps::GUID_t& guid, std::string topic,
              std::string type) {
    {
      std::lock_guard lock(mutex_);
      if (closing_) return;
    }
    if (!on_endpoint_) return;
    EndpointEvent e;
    e.is_writer = writer;
    e.alive = alive;
    e.guid = to_bytes(guid);
    e.topic_name = std::move(topic);
    e.type_name = std::move(type);
    on_endpoint_(e);
  }

  fdds::Topic* acquire_topic(const std::string& topic_name, const std::string& type_name,
                             std::size_t max_size) {
    std::lock_guard lock(mutex_);
    if (auto it = topics_.find(topic_name); it != topics_.end()) {
      if (it->second.topic->get_type_name() != type_name) {
        throw std::runtime_error("topic '" + topic_name + "' already exists in this participant " +
                                 "with type '" + it->second.topic->get_type_name() + "', not '" +
                                 type_name + "'");
      }
      ++it->second.refs;
      return it->second.topic;
    }
    if (participant_->find_type(type_name).empty()) {
      fdds::TypeSupport ts(new CdrTopicDataType(type_name, max_size));
      if (ts.register_type(participant_) != ReturnCode_t::RETCODE_OK) {
        throw std::runtime_error("Fast DDS refused to register type '" + type_name + "'");
      }
    }
    fdds::Topic* t = participant_->create_topic(topic_name, type_name, fdds::TOPIC_QOS_DEFAULT);
    if (!t) throw std::runtime_error("Fast DDS refused to create topic '" + topic_name + "'");
    topics_[topic_name] = TopicRef{t, 1};
    return t;
  }

  void release_topic(const std::string& topic_name) {
    std::lock_guard lock(mutex_);
    auto it = topics_.find(topic_name);
    if (it == topics_.end() || --it->second.refs > 0) return;
    participant_->delete_topic(it->second.topic);
    topics_.erase(it);
  }

  struct TopicRef {
    fdds::Topic* topic;
    int refs;
  };
  std::function<void(const EndpointEvent&)> on_endpoint_;
  std::mutex mutex_;
  bool closing_ = false;
  std::map<std::string, TopicRef> topics_;
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
};

}  // namespace

std::unique_ptr<ParticipantBackend> make_fastdds_backend(const BackendOptions& options) {
  return std::make_unique<FastddsParticipant>(options);
}

}  // namespace poise::dds::detail
