#include "topic_commands.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <deque>
#include <iomanip>
#include <iostream>
#include <istream>
#include <mutex>
#include <ostream>
#include <sstream>
#include <thread>
#include <tuple>
#include <type_traits>

#include <poise/dds/dds.hpp>
#include <poise/reflect/json.hpp>
#include <poise/reflect/print.hpp>
#include <poise/reflect/validate.hpp>

namespace poise::topic_tools {

namespace {

using Clock = std::chrono::steady_clock;

std::atomic<bool> g_stop{false};

extern "C" void topic_tools_on_signal(int) {
  g_stop.store(true);
}

/// Calls f(std::type_identity<T>{}) for the topic type T whose DDS type name is `type_name`.
template <class F>
bool with_topic_type(std::string_view type_name, F&& f) {
  bool found = false;
  [&]<class... Ts>(std::type_identity<std::tuple<Ts...>>) {
    (
        [&] {
          if (!found && msg::IdlName<Ts>::value == type_name) {
            found = true;
            f(std::type_identity<Ts>{});
          }
        }(),
        ...);
  }(std::type_identity<msg::TopicTypeList>{});
  return found;
}

std::string known_topics() {
  std::string names;
  for (const auto& t : dds::topic_table()) {
    names += (names.empty() ? "" : ", ") + std::string(t.topic_name);
  }
  return names;
}

const dds::TopicDescription* require_topic(const std::string& name, std::ostream& err) {
  const auto* desc = dds::find_topic(name);
  if (!desc) err << "unknown topic '" << name << "'; Poise topics: " << known_topics() << "\n";
  return desc;
}

void sleep_s(double s) {
  std::this_thread::sleep_for(std::chrono::duration<double>(s));
}

}  // namespace

bool stop_requested() noexcept {
  return g_stop.load();
}

void install_signal_handlers() {
  std::signal(SIGINT, topic_tools_on_signal);
  std::signal(SIGTERM, topic_tools_on_signal);
}

int list_topics(dds::Participant& participant, const ListOptions& options, std::ostream& out) {
  const auto end = Clock::now() + std::chrono::duration<double>(options.wait_s);
  while (Clock::now() < end && !stop_requested())
    sleep_s(0.02);
  const auto topics = participant.discovered_topics();
  std::size_t wt = 5, wy = 4;
  for (const auto& t : topics) {
    wt = std::max(wt, t.topic_name.size());
    wy = std::max(wy, t.type_name.size());
  }
  out << std::left << std::setw(static_cast<int>(wt) + 2) << "TOPIC"
      << std::setw(static_cast<int>(wy) + 2) << "TYPE"
      << "WRITERS  READERS\n";
  for (const auto& t : topics) {
    std::string note;
    if (const auto* known = dds::find_topic(t.topic_name);
        known && known->type_name != t.type_name) {
      note = "  (type mismatch: Poise expects " + std::string(known->type_name) + ")";
    }
    out << std::left << std::setw(static_cast<int>(wt) + 2) << t.topic_name
        << std::setw(static_cast<int>(wy) + 2) << t.type_name << std::right << std::setw(7)
        << t.writers << "  " << std::setw(7) << t.readers << note << "\n";
  }
  if (topics.empty()) {
    out << "(no topics seen on domain " << participant.domain_id() << " with "
        << dds::to_string(participant.vendor()) << " after " << options.wait_s << " s)\n";
  }
  return 0;
}

int echo_topic(dds::Participant& participant, const EchoOptions& options, std::ostream& out) {
  const auto* desc = require_topic(options.topic, std::cerr);
  if (!desc) return 2;
  int rc = 0;
  with_topic_type(desc->type_name, [&]<class T>(std::type_identity<T>) {
    dds::Subscriber<T> sub(participant, desc->qos, desc->topic_name);
    T sample;
    std::int64_t printed = 0;
    const std::int64_t limit = options.once ? 1 : options.count;
    auto last = Clock::now();
    const auto start = last;
    std::cerr << "waiting for " << options.topic << " on DDS domain " << participant.domain_id()
              << " (" << dds::to_string(participant.vendor()) << ")"
              << (options.timeout_s > 0 ? "" : "; Ctrl-C to stop") << "\n";
    bool hinted = false;
    while (!stop_requested()) {
      if (!hinted && printed == 0 && Clock::now() - start > std::chrono::seconds(3)) {
        hinted = true;
        if (sub.matched() == 0)
          std::cerr << "no writer of " << options.topic << " on domain " << participant.domain_id()
                    << " yet: `poise run` uses a domain of its own unless given --domain N or "
                       "$POISE_DDS_DOMAIN (it prints the one it uses)\n";
      }
      if (sub.take(sample)) {
        if (options.json) {
          out << reflect::to_json(sample).dump() << "\n";
        } else {
          if (printed) out << "---\n";
          out << reflect::to_text(sample);
        }
        out.flush();
        last = Clock::now();
        if (limit && ++printed >= limit) break;
        continue;
      }
      if (options.timeout_s > 0 &&
          Clock::now() - last > std::chrono::duration<double>(options.timeout_s)) {
        std::cerr << "no sample on " << options.topic << " within " << options.timeout_s << " s ("
                  << sub.matched() << " writers matched)\n";
        rc = 1;
        break;
      }
      sleep_s(0.0005);
    }
    const auto& c = sub.counters();
    if (c.rejected || c.deserialize_errors || c.type_mismatches) {
      std::cerr << options.topic << ": rejected " << c.rejected << " invalid samples, "
                << c.deserialize_errors << " undecodable, " << c.type_mismatches
                << " writers of another type\n";
    }
  });
  return rc;
}

int topic_hz(dds::Participant& participant, const HzOptions& options, std::ostream& out) {
  // Known topics: their registered type and QoS. Other topics: the type seen by discovery, and a
  // best-effort reader, which matches reliable and best-effort writers alike.
  std::string type_name;
  dds::Qos qos = dds::Qos::best_effort(1);
  if (const auto* desc = dds::find_topic(options.topic)) {
    type_name = desc->type_name;
    qos = desc->qos;
  } else {
    const auto end = Clock::now() + std::chrono::seconds(2);
    while (type_name.empty() && Clock::now() < end && !stop_requested()) {
      for (const auto& t : participant.discovered_topics()) {
        if (t.topic_name == options.topic && t.writers > 0) type_name = t.type_name;
      }
      sleep_s(0.05);
    }
    if (type_name.empty()) {
      std::cerr << "topic '" << options.topic << "' is not a Poise topic and no writer of it was "
                << "seen within 2 s; Poise topics: " << known_topics() << "\n";
      return 2;
    }
  }
  std::mutex mutex;
  std::deque<double> periods;  // seconds, newest at the back
  std::int64_t total = 0;
  Clock::time_point previous{};
  dds::RawSubscriber sub(
      participant, options.topic, type_name, qos,
      [&](const std::vector<std::uint8_t>&, const dds::SampleMeta&) {
        const auto now = Clock::now();
        std::lock_guard lock(mutex);
        if (total > 0) {
          periods.push_back(std::chrono::duration<double>(now - previous).count());
          if (static_cast<int>(periods.size()) > options.window) periods.pop_front();
        }
        previous = now;
        ++total;
      });
  const auto start = Clock::now();
  auto next_report = start + std::chrono::duration<double>(options.report_s);
  std::int64_t reported_total = -1;
  while (!stop_requested()) {
    if (options.duration_s > 0 &&
        Clock::now() - start >= std::chrono::duration<double>(options.duration_s)) {
      break;
    }
    if (Clock::now() < next_report) {
      sleep_s(0.01);
      continue;
    }
    next_report += std::chrono::duration<double>(options.report_s);
    std::lock_guard lock(mutex);
    if (periods.empty()) {
      if (reported_total != total) out << "no new messages\n";
      reported_total = total;
      continue;
    }
    double sum = 0, mn = periods.front(), mx = periods.front();
    for (double p : periods) {
      sum += p;
      mn = std::min(mn, p);
      mx = std::max(mx, p);
    }
    const double mean = sum / static_cast<double>(periods.size());
    double var = 0;
    for (double p : periods)
      var += (p - mean) * (p - mean);
    const double sd = std::sqrt(var / static_cast<double>(periods.size()));
    out << std::fixed << std::setprecision(3) << "average rate: " << 1.0 / mean << " Hz\n"
        << "  min: " << mn * 1e3 << " ms  max: " << mx * 1e3 << " ms  std dev: " << sd * 1e3
        << " ms  window: " << periods.size() << "  total: " << total << "\n";
    out.flush();
    reported_total = total;
  }
  return 0;
}

int publish_topic(dds::Participant& participant, const PubOptions& options, std::istream& in,
                  std::ostream& out) {
  const auto* desc = require_topic(options.topic, std::cerr);
  if (!desc) return 2;
  int rc = 0;
  with_topic_type(desc->type_name, [&]<class T>(std::type_identity<T>) {
    // Parse one JSON text into a valid sample, or say exactly what is wrong.
    auto parse = [&](const std::string& text, const std::string& where, T& sample) {
      try {
        reflect::from_json(reflect::Json::parse(text), sample);
      } catch (const std::exception& e) {
        std::cerr << where << ": " << e.what() << "\n";
        return false;
      }
      reflect::ValidationError error;
      if (!reflect::validate(sample, &error)) {
        std::cerr << where << ": " << error.path << ": " << error.reason << "\n";
        return false;
      }
      return true;
    };
    // Validate everything first when the samples come as an argument.
    T sample;
    if (!options.json.empty() && !parse(options.json, "sample", sample)) {
      rc = 2;
      return;
    }
    dds::Publisher<T> pub(participant, desc->qos, desc->topic_name);
    if (options.wait_readers > 0 &&
        !pub.wait_for_matches(options.wait_readers,
                              std::chrono::duration_cast<std::chrono::nanoseconds>(
                                  std::chrono::duration<double>(options.wait_s)))) {
      std::cerr << "warning: " << pub.matched() << " of " << options.wait_readers
                << " readers matched on " << options.topic << " after " << options.wait_s
                << " s; publishing anyway\n";
    }
    const auto period = options.rate_hz > 0 ? std::chrono::duration<double>(1.0 / options.rate_hz)
                                            : std::chrono::duration<double>(0);
    auto next = Clock::now();
    std::int64_t published = 0;
    auto send = [&](const T& s) {
      for (std::int64_t i = 0; (options.count == 0 || i < options.count) && !stop_requested();
           ++i) {
        if (period.count() > 0) {
          std::this_thread::sleep_until(next);
          next += std::chrono::duration_cast<Clock::duration>(period);
        }
        if (!pub.publish(s)) {
          std::cerr << "publish on " << options.topic << " failed\n";
          rc = 1;
          return;
        }
        ++published;
      }
    };
    if (!options.json.empty()) {
      send(sample);
    } else {
      std::string line;
      int lineno = 0;
      while (!stop_requested() && std::getline(in, line)) {
        ++lineno;
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        if (!parse(line, "stdin line " + std::to_string(lineno), sample)) {
          rc = 2;
          break;
        }
        send(sample);
        if (rc) break;
      }
    }
    // Let reliable delivery finish before the writer goes away.
    sleep_s(0.3);
    out << "published " << published << " sample" << (published == 1 ? "" : "s") << " on "
        << options.topic << "\n";
  });
  return rc;
}

}  // namespace poise::topic_tools
