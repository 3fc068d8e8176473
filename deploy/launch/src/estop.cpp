// `poise estop`: engage (or release) the robot's e-stop on poise/estop, and report it done only
// when every robot side has acknowledged it.
//
// A robot side is what publishes poise/estop_state (the safety layer of poise-sim, poise-gantry or
// a driver): the readers of poise/estop also include recorders and monitors, which must never be
// taken for a robot. The command learns the robot sides from their (latched) states, sends the
// stop with a fresh request id, and waits until each of them echoes that id. The stop itself is
// latched (transient-local): a robot side that matches while the command waits still gets it,
// and with --hold the stop stays on the domain for robot sides that start later.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <thread>

#include <poise/msg/estop.h>
#include <poise/msg/estop_state.h>

#include "poise/cli/parse.hpp"
#include "poise/dds/cli.hpp"
#include "poise/dds/dds.hpp"
#include "poise/launch/launch.hpp"
#include "poise/node/shutdown.hpp"

namespace poise::launch {
namespace {

using Clock = std::chrono::steady_clock;

struct RobotSide {
  msg::EStopState state;  // the newest state it published
  bool reported = false;  // its acknowledgement was printed
};

/// Takes every waiting state into `robots` (one entry per robot-side name, the newest wins).
void take_states(dds::Subscriber<msg::EStopState>& sub, std::map<std::string, RobotSide>& robots) {
  msg::EStopState s;
  while (sub.take(s))
    robots[std::string(s.robot())].state = s;
}

bool acknowledged(const RobotSide& r, std::uint64_t request, bool engage, msg::StopKind kind) {
  return r.state.request() == request && r.state.engaged() == engage &&
         (!engage || r.state.kind() == kind);
}

const char* describe(msg::StopKind kind) {
  return kind == msg::STOP_PROTECTIVE_HOLD ? "protective stop (holding)" : "e-stop (damping)";
}

std::uint64_t fresh_request_id() {
  std::random_device rd;
  const std::uint64_t id =
      (static_cast<std::uint64_t>(rd()) << 32) ^ rd() ^
      static_cast<std::uint64_t>(Clock::now().time_since_epoch().count());
  return id == 0 ? 1 : id;
}

}  // namespace

int estop_main(int argc, char** argv) {
  dds::DdsOptions options = dds::dds_options_from_env();
  bool release = false, hold = false, protective = false;
  std::string reason = "poise estop";
  int wait_ms = 5000, discover_ms = 500;
  CLI::App app{
      "Engage the robot's e-stop (poise/estop): its safety layer damps every joint and ignores "
      "joint commands until released with --release (a standing humanoid falls). With "
      "--protective, a protective stop (category 2) instead: the posture at the stop is held, "
      "powered, until released (a standing humanoid stays up). Succeeds (exit 0) only when every "
      "robot side (a safety layer publishing poise/estop_state) has acknowledged; otherwise "
      "names the ones that did not and exits 1."};
  app.name(argc > 0 ? argv[0] : "poise estop");
  auto* release_flag =
      app.add_flag("--release", release, "release the stop (the robot then holds its posture "
                                         "until a fresh joint command)");
  app.add_flag("--protective", protective,
               "a protective stop (category 2): hold the posture at the stop with power on "
               "instead of damping. Refused by a robot side whose e-stop is damping (release "
               "that first)")
      ->excludes(release_flag);
  app.add_option("--reason", reason, "why (shown in the robot's log and diagnostics)")
      ->capture_default_str()
      ->check([](const std::string& s) {
        return s.size() <= 128 ? std::string() : std::string("at most 128 characters");
      });
  app.add_flag("--hold", hold,
               "stay on the domain until Ctrl-C, so that a robot side that starts later still "
               "gets the (latched) e-stop; each acknowledgement is printed as it comes");
  app.add_option("--wait-ms", wait_ms,
                 "how long to wait for a robot side to appear, and then for the acknowledgements")
      ->capture_default_str()
      ->check(CLI::Range(0, 600000));
  app.add_option("--discover-ms", discover_ms,
                 "after the first robot side appears, how long to look for more before sending")
      ->capture_default_str()
      ->check(CLI::Range(0, 60000));
  dds::add_dds_options(app, options);
  POISE_CLI_PARSE(app, argc, argv);
  const bool engage = !release;
  const msg::StopKind kind = protective ? msg::STOP_PROTECTIVE_HOLD : msg::STOP_EMERGENCY_DAMP;
  const char* verb = engage ? "ENGAGED" : "RELEASED";
  const char* what = engage ? describe(kind) : "stop";
  try {
    options.participant_name = "poise/estop";
    dds::Participant participant(options);
    dds::Subscriber<msg::EStopState> states(participant);
    dds::Publisher<msg::EStop> pub(participant);
    std::map<std::string, RobotSide> robots;

    // 1. The robot sides: their latched states arrive on matching.
    const auto start = Clock::now();
    const auto give_up = start + std::chrono::milliseconds(wait_ms);
    while (robots.empty() && Clock::now() < give_up) {
      take_states(states, robots);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (robots.empty() && !hold) {
      std::fprintf(stderr,
                   "poise estop: no robot side published poise/estop_state on domain %d (%s) "
                   "within %d ms: nothing sent (%d other reader(s) of poise/estop, such as "
                   "recorders, are not robots)\n",
                   options.domain_id, std::string(dds::to_string(options.vendor)).c_str(), wait_ms,
                   pub.matched());
      return 1;
    }
    const auto discovered = Clock::now() + std::chrono::milliseconds(discover_ms);
    while (Clock::now() < discovered) {
      take_states(states, robots);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }

    // 2. The stop, latched, with a request id the robot sides echo.
    const std::uint64_t request = fresh_request_id();
    msg::EStop e;
    e.engaged(engage);
    e.source("poise estop");
    e.reason(reason);
    e.request(request);
    e.kind(kind);
    if (!pub.publish(e)) {
      std::fprintf(stderr, "poise estop: publish failed\n");
      return 1;
    }

    // 3. Every robot side known (including any that appears meanwhile) echoes the request.
    const auto report = [&] {
      for (auto& [name, r] : robots)
        if (!r.reported && acknowledged(r, request, engage, kind)) {
          r.reported = true;
          std::printf("  %s: %s %s (robot tick %llu)\n", name.c_str(), what, verb,
                      static_cast<unsigned long long>(r.state.header().tick()));
        }
      std::fflush(stdout);
    };
    const auto all_acknowledged = [&] {
      for (const auto& [name, r] : robots)
        if (!acknowledged(r, request, engage, kind)) return false;
      return !robots.empty();
    };
    const auto ack_deadline = Clock::now() + std::chrono::milliseconds(wait_ms);
    while (!all_acknowledged() && Clock::now() < ack_deadline) {
      take_states(states, robots);
      report();
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    take_states(states, robots);
    report();
    int missing = 0;
    for (const auto& [name, r] : robots)
      if (!acknowledged(r, request, engage, kind)) {
        ++missing;
        if (r.state.request() == request && r.state.engaged() && engage)
          std::fprintf(stderr,
                       "poise estop: %s answered the %s but holds an %s: release that first\n",
                       name.c_str(), what, describe(r.state.kind()));
        else
          std::fprintf(stderr,
                       "poise estop: %s did not acknowledge the %s within %d ms (its state: %s, "
                       "request %llu)\n",
                       name.c_str(), engage ? what : "release", wait_ms,
                       r.state.engaged() ? describe(r.state.kind()) : "released",
                       static_cast<unsigned long long>(r.state.request()));
      }
    if (missing == 0 && !robots.empty())
      std::printf("%s %s (%s) on domain %d: acknowledged by %zu robot side(s)\n", what, verb,
                  reason.c_str(), options.domain_id, robots.size());
    else if (!hold)
      std::printf("%s NOT %s everywhere on domain %d: %d of %zu robot side(s) did not "
                  "acknowledge\n",
                  what, verb, options.domain_id, missing, robots.size());
    std::fflush(stdout);
    if (hold) {
      std::printf("holding the e-stop on domain %d until Ctrl-C\n", options.domain_id);
      std::fflush(stdout);
      node::install_shutdown_handlers();
      while (!node::shutdown_requested()) {
        take_states(states, robots);
        report();
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      return 0;
    }
    return missing == 0 ? 0 : 1;
  } catch (const std::exception& ex) {
    std::fprintf(stderr, "poise estop: %s\n", ex.what());
    return 2;
  }
}

}  // namespace poise::launch
