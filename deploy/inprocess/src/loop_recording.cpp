#include "poise/inprocess/loop_recording.hpp"

#include <time.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string_view>

#include <poise/dds/topics.hpp>
#include <poise/msg/balance_reference.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/idl_schemas_gen.hpp>
#include <poise/msg/robot_description.h>

#include "poise/record/mcap_writer.hpp"

namespace poise::inprocess {
namespace {

std::string_view schema_of(std::string_view type_name) {
  for (const auto& s : msg::kIdlSchemas)
    if (s.type_name == type_name) return s.idl;
  throw std::logic_error("no IDL schema generated for " + std::string(type_name));
}

std::uint64_t realtime_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL +
         static_cast<std::uint64_t>(ts.tv_nsec);
}

}  // namespace

LoopRecording::LoopRecording(const std::filesystem::path& file, InProcessLoop& loop)
    : file_(file), loop_(loop), slip_(sim::platforms_of_feet(loop.scenario())) {
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path());
  record::WriterOptions options;
  options.library = "poise run --in-process";
  try {
    writer_ = std::make_unique<record::McapWriter>(file.string(), options);
  } catch (const std::exception& e) {
    throw std::runtime_error("--record " + file.string() + ": " + e.what());
  }
  start_realtime_ns_ = realtime_ns();
  feet_ = sim_node::foot_order(loop.simulator());
  const msg::RobotDescription description =
      sim_node::make_robot_description(loop.scenario(), loop.simulator(), feet_);
  urdf_link_of_body_ =
      sim_node::urdf_link_index_of_bodies(description.urdf(), loop.simulator().body_names());
  truth_msg_ = std::make_unique<msg::GroundTruth>();
  slip_.update(loop.truth());
  write(description, loop.truth().tick);
  loop.on_reference([this](const msg::BalanceReference& r) {
    write(r, static_cast<std::int64_t>(r.header().tick()));
  });
}

LoopRecording::~LoopRecording() {
  loop_.on_reference({});
  close();
}

std::uint64_t LoopRecording::log_time_ns(std::int64_t tick) const {
  const double t = static_cast<double>(tick) * loop_.simulator().dt();
  return start_realtime_ns_ + static_cast<std::uint64_t>(std::max(0.0, t) * 1e9);
}

template <class T>
void LoopRecording::write(const T& message, std::int64_t tick) {
  using Traits = dds::TopicTraits<T>;
  const dds::TypeSupport& ts = Traits::type_support();
  Channel* channel = nullptr;
  for (Channel& c : channels_)
    if (c.topic == Traits::topic_name) channel = &c;
  if (channel == nullptr) {
    const std::uint16_t schema = writer_->add_schema(ts.type_name, "omgidl", schema_of(ts.type_name));
    channels_.push_back({std::string(Traits::topic_name),
                         writer_->add_channel(schema, Traits::topic_name, "cdr")});
    channel = &channels_.back();
  }
  buffer_.assign(ts.serialized_size(&message), 0);  // the padding between fields written as 0
  const std::size_t n = ts.serialize(&message, buffer_.data(), buffer_.size());
  if (n == 0) return;  // cannot happen with the size asked for; nothing half-written
  const std::uint64_t t = log_time_ns(tick);
  // Counted as written once its chunk is in the file (close()), not when accepted here.
  writer_->write_message(channel->id, channel->sequence++, t, t, buffer_.data(), n);
}

void LoopRecording::before_step() {
  const sim::GroundTruth& truth = loop_.truth();
  sim_node::to_msg(truth, feet_, slip_, urdf_link_of_body_, other_contacts_, *truth_msg_);
  write(*truth_msg_, truth.tick);
}

void LoopRecording::after_step() {
  const InProcessLoop::TickMessages m = loop_.last_messages();
  write(*m.sensors, m.tick);
  if (m.controlled) {
    write(*m.state, m.tick);
    write(*m.problem, m.tick);
    write(*m.solution, m.tick);
    write(*m.command, m.tick);
  }
  // As poise-sim after its step: other contacts counted, foot slip followed.
  const sim::GroundTruth& truth = loop_.truth();
  if (truth.num_non_foot_contacts > 0) ++other_contacts_;
  slip_.update(truth);
}

std::string LoopRecording::close() {
  if (closed_) return writer_->error();
  closed_ = true;
  // The open chunk first: the counts below are of the messages in the file (after a failed
  // write, the failed chunk's are not).
  writer_->flush();
  messages_ = 0;
  for (Channel& c : channels_) {
    c.written = static_cast<std::uint32_t>(writer_->messages_in_file(c.id));
    messages_ += c.written;
  }
  writer_->write_metadata("poise_recording", {{"capture", "in process (no DDS)"},
                                               {"messages", std::to_string(messages_)}});
  // The losses `poise info` reports, in the recorder's terms: every message of the loop is
  // handed to the file; one the file refused counts as dropped. No DDS: nothing lost on the way.
  std::map<std::string, std::string> m;
  std::uint64_t dropped = 0;
  for (const Channel& c : channels_) {
    m[c.topic + ".received"] = std::to_string(c.sequence);
    m[c.topic + ".written"] = std::to_string(c.written);
    m[c.topic + ".dropped"] = std::to_string(c.sequence - c.written);
    m[c.topic + ".vendor_lost"] = "0";
    m[c.topic + ".vendor_rejected"] = "0";
    dropped += c.sequence - c.written;
  }
  m["total.dropped"] = std::to_string(dropped);
  m["total.vendor_lost"] = "0";
  m["total.tick_gaps"] = "0";
  writer_->write_metadata("poise_recorder", m);
  writer_->close();
  messages_ = writer_->stats().messages_in_file;
  return writer_->error();
}

}  // namespace poise::inprocess
