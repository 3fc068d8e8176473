#pragma once
// `poise run --in-process --record FILE`: the topics of an in-process run in an MCAP file, as
// `poise record` writes the distributed run's (components/record/README.md): schema encoding
// omgidl, message encoding cdr (the bytes a DDS writer sends, encapsulation header included), one
// channel per topic, so `poise info`, `poise plot`, `poise export` and Foxglove read either.
//
// What is recorded, per control tick k, with the nodes' own conversions:
//   poise/robot_description  once, at the start (as poise-sim publishes it)
//   poise/ground_truth       truth k (as poise-sim: foot slip since touch-down, other contacts)
//   poise/sensors, poise/state, poise/contact_problem, poise/contact_solution,
//   poise/joint_command      the tick's messages (no state, problem, solution or command for a
//                            tick whose sensor frame the estimator refused)
//   poise/balance_reference  each reference the scenario's reference player sends
// Not recorded: poise/diagnostics (no nodes in process). Times: log time and publish time are the
// run's wall-clock start (CLOCK_REALTIME) plus the simulated time of the tick, so a recording's
// timeline is the simulated one whatever the loop's speed. Sequence = count on the topic.
// Writing happens between ticks and is not part of the measured tick latency.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "poise/inprocess/in_process_loop.hpp"
#include "poise/sim_node/sim_messages.hpp"

namespace poise::record {
class McapWriter;
}

namespace poise::inprocess {

class LoopRecording {
 public:
  /// Opens `file` (its directory is created) and writes the robot description. Throws
  /// std::runtime_error naming the file when it cannot be written.
  LoopRecording(const std::filesystem::path& file, InProcessLoop& loop);
  ~LoopRecording();
  LoopRecording(const LoopRecording&) = delete;
  LoopRecording& operator=(const LoopRecording&) = delete;

  /// Before InProcessLoop::step(): the ground truth of the tick about to be stepped.
  void before_step();
  /// After InProcessLoop::step(): the messages of the tick just stepped.
  void after_step();
  /// Writes the counts (metadata "poise_recording") and closes the file. Returns "" or what went
  /// wrong. Idempotent.
  std::string close();

  /// Messages in the file (after close()).
  std::uint64_t messages() const { return messages_; }
  const std::filesystem::path& file() const { return file_; }

 private:
  struct Channel {
    std::string topic;
    std::uint16_t id = 0;
    std::uint32_t sequence = 0;  ///< messages handed to the file
    std::uint32_t written = 0;   ///< of those, in the file (set by close())
  };
  template <class T>
  void write(const T& message, std::int64_t tick);
  std::uint64_t log_time_ns(std::int64_t tick) const;

  std::filesystem::path file_;
  InProcessLoop& loop_;
  std::unique_ptr<record::McapWriter> writer_;
  std::vector<Channel> channels_;
  std::vector<std::uint8_t> buffer_;
  sim_node::FootOrder feet_{};
  sim_node::SlipTracker slip_;
  std::vector<std::int32_t> urdf_link_of_body_;
  std::uint64_t other_contacts_ = 0;
  std::unique_ptr<msg::GroundTruth> truth_msg_;
  std::uint64_t start_realtime_ns_ = 0;
  std::uint64_t messages_ = 0;
  bool closed_ = false;
};

}  // namespace poise::inprocess
