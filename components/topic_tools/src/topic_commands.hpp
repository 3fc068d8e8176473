#pragma once
// The four `poise topic` verbs as functions, so that tests and other tools can call them.

#include <cstdint>
#include <iosfwd>
#include <string>

#include <poise/dds/participant.hpp>

namespace poise::topic_tools {

/// Set by SIGINT/SIGTERM; every verb checks it and returns cleanly.
bool stop_requested() noexcept;
void install_signal_handlers();

struct ListOptions {
  double wait_s = 1.5;  ///< discovery time before printing (other vendor: ~1 s)
};
/// Prints the topics seen on the domain with writer/reader counts. Returns an exit code.
int list_topics(dds::Participant& participant, const ListOptions& options, std::ostream& out);

struct EchoOptions {
  std::string topic;
  bool once = false;
  bool json = false;
  std::int64_t count = 0;  ///< stop after this many samples (0 = no limit)
  double timeout_s = 0.0;  ///< give up after this long without a sample (0 = wait forever)
};
/// Prints received samples (text, or one JSON object per line). Exit code 0 when at least one
/// sample was printed or no limit was hit; 1 on timeout without samples; 2 on a bad topic.
int echo_topic(dds::Participant& participant, const EchoOptions& options, std::ostream& out);

struct HzOptions {
  std::string topic;
  int window = 1000;        ///< periods in the statistics window
  double duration_s = 0.0;  ///< stop after this long (0 = until interrupted)
  double report_s = 1.0;    ///< print every this many seconds
};
/// Prints rate and min/max/std-dev of the period. Works on raw bytes: any topic, any type.
int topic_hz(dds::Participant& participant, const HzOptions& options, std::ostream& out);

struct PubOptions {
  std::string topic;
  std::string json;        ///< one sample; empty = read JSON lines from `in`
  double rate_hz = 0.0;    ///< 0 = as fast as read (stdin) / once (argument)
  std::int64_t count = 1;  ///< times to publish each sample (0 = until interrupted)
  int wait_readers = 1;    ///< wait for this many matched readers first
  double wait_s = 3.0;     ///< ... for at most this long
};
/// Publishes JSON samples (the form echo --json prints). Exit code 0, or 2 on bad input.
int publish_topic(dds::Participant& participant, const PubOptions& options, std::istream& in,
                  std::ostream& out);

}  // namespace poise::topic_tools
