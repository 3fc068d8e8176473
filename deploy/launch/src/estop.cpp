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

/// `poise estop`'s command line.
struct EStopArgs {
  dds::DdsOptions options = dds::dds_options_from_env();
  bool release = false, hold = false, protective = false;
  std::string reason = "poise estop";
  int wait_ms = 5000, discover_ms = 500;
};

/// Parses `poise estop`'s command line into `a`. Returns the exit status when the command line
/// ends the verb (0 after --help, 2 for a usage error), else -1.
int parse_estop_args(int argc, char** argv, EStopArgs& a) {
  CLI::App app{
      "Engage the robot's e-stop (poise/estop): its safety layer damps every joint and ignores "
      "joint commands until released with --release (a standing humanoid falls). With "
      "--protective, a protective stop (category 2) instead: the posture at the stop is held, "
      "powered, until released (a standing humanoid stays up). Succeeds (exit 0) only when every "
      "robot side (a safety layer publishing poise/estop_state) has acknowledged; otherwise "
      "names the ones that did not and exits 1."};
  app.name(argc > 0 ? argv[0] : "poise estop");
  auto* release_flag =
      app.add_flag("--release", a.release, "release the stop (the robot then holds its posture "
                                           "until a fresh joint command)");
  app.add_flag("--protective", a.protective,
               "a protective stop (category 2): hold the posture at the stop with power on "
               "instead of damping. Refused by a robot side whose e-stop is damping (release "
               "that first)")
      ->excludes(release_flag);
  app.add_option("--reason", a.reason, "why (shown in the robot's log and diagnostics)")
      ->capture_default_str()
      ->check([](const std::string& s) {
        return s.size() <= 128 ? std::string() : std::string("at most 128 characters");
      });
  app.add_flag("--hold", a.hold,
               "stay on the domain until Ctrl-C, so that a robot side that starts later still "
               "gets the (latched) e-stop; each acknowledgement is printed as it comes");
  app.add_option("--wait-ms", a.wait_ms,
                 "how long to wait for a robot side to appear, and then for the acknowledgements")
      ->capture_default_str()
      ->check(CLI::Range(0, 600000));
  app.add_option("--discover-ms", a.discover_ms,
                 "after the first robot side appears, how long to look for more before sending")
      ->capture_default_str()
      ->check(CLI::Range(0, 60000));
  dds::add_dds_options(app, a.options);
  POISE_CLI_PARSE(app, argc, argv);
  return -1;
}

/// One stop (or release): the robot sides found, the stop sent, their acknowledgements.
class EStopCommand {
 public:
  explicit EStopCommand(const EStopArgs& a)
      : a_(a),
        engage_(!a.release),
        kind_(a.protective ? msg::STOP_PROTECTIVE_HOLD : msg::STOP_EMERGENCY_DAMP),
        verb_(engage_ ? "ENGAGED" : "RELEASED"),
        what_(engage_ ? describe(kind_) : "stop"),
        participant_(a.options),
        states_(participant_),
        pub_(participant_) {}

  /// 1. The robot sides: their latched states arrive on matching. False (said) when none
  /// appeared and the stop is not held on the domain.
  bool discover() {
    const auto start = Clock::now();
    const auto give_up = start + std::chrono::milliseconds(a_.wait_ms);
    while (robots_.empty() && Clock::now() < give_up) {
      take_states(states_, robots_);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (robots_.empty() && !a_.hold) {
      std::fprintf(stderr,
                   "poise estop: no robot side published poise/estop_state on domain %d (%s) "
                   "within %d ms: nothing sent (%d other reader(s) of poise/estop, such as "
                   "recorders, are not robots)\n",
                   a_.options.domain_id, std::string(dds::to_string(a_.options.vendor)).c_str(),
                   a_.wait_ms, pub_.matched());
      return false;
    }
    const auto discovered = Clock::now() + std::chrono::milliseconds(a_.discover_ms);
    while (Clock::now() < discovered) {
      take_states(states_, robots_);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return true;
  }

  /// 2. The stop, latched, with a request id the robot sides echo. False (said) when it could not
  /// be published.
  bool send() {
    request_ = fresh_request_id();
    msg::EStop e;
    e.engaged(engage_);
    e.source("poise estop");
    e.reason(a_.reason);
    e.request(request_);
    e.kind(kind_);
    if (!pub_.publish(e)) {
      std::fprintf(stderr, "poise estop: publish failed\n");
      return false;
    }
    return true;
  }

  /// 3. Every robot side known (including any that appears meanwhile) echoes the request, within
  /// --wait-ms. Returns how many did not (each named).
  int wait_for_acknowledgements() {
    const auto ack_deadline = Clock::now() + std::chrono::milliseconds(a_.wait_ms);
    while (!all_acknowledged() && Clock::now() < ack_deadline) {
      take_states(states_, robots_);
      report();
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    take_states(states_, robots_);
    report();
    int missing = 0;
    for (const auto& [name, r] : robots_)
      if (!acknowledged(r, request_, engage_, kind_)) {
        ++missing;
        report_missing(name, r);
      }
    return missing;
  }

  /// The final line: acknowledged by every robot side, or not.
  void print_verdict(int missing) const {
    if (missing == 0 && !robots_.empty())
      std::printf("%s %s (%s) on domain %d: acknowledged by %zu robot side(s)\n", what_, verb_,
                  a_.reason.c_str(), a_.options.domain_id, robots_.size());
    else if (!a_.hold)
      std::printf("%s NOT %s everywhere on domain %d: %d of %zu robot side(s) did not "
                  "acknowledge\n",
                  what_, verb_, a_.options.domain_id, missing, robots_.size());
    std::fflush(stdout);
  }

  /// --hold: stays on the domain until Ctrl-C, printing each acknowledgement as it comes.
  void hold() {
    std::printf("holding the e-stop on domain %d until Ctrl-C\n", a_.options.domain_id);
    std::fflush(stdout);
    node::install_shutdown_handlers();
    while (!node::shutdown_requested()) {
      take_states(states_, robots_);
      report();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

 private:
  /// Each new acknowledgement, once.
  void report() {
    for (auto& [name, r] : robots_)
      if (!r.reported && acknowledged(r, request_, engage_, kind_)) {
        r.reported = true;
        std::printf("  %s: %s %s (robot tick %llu)\n", name.c_str(), what_, verb_,
                    static_cast<unsigned long long>(r.state.header().tick()));
      }
    std::fflush(stdout);
  }

  bool all_acknowledged() const {
    for (const auto& [name, r] : robots_)
      if (!acknowledged(r, request_, engage_, kind_)) return false;
    return !robots_.empty();
  }

  void report_missing(const std::string& name, const RobotSide& r) const {
    if (r.state.request() == request_ && r.state.engaged() && engage_)
      std::fprintf(stderr,
                   "poise estop: %s answered the %s but holds an %s: release that first\n",
                   name.c_str(), what_, describe(r.state.kind()));
    else
      std::fprintf(stderr,
                   "poise estop: %s did not acknowledge the %s within %d ms (its state: %s, "
                   "request %llu)\n",
                   name.c_str(), engage_ ? what_ : "release", a_.wait_ms,
                   r.state.engaged() ? describe(r.state.kind()) : "released",
                   static_cast<unsigned long long>(r.state.request()));
  }

  const EStopArgs& a_;
  const bool engage_;
  const msg::StopKind kind_;
  const char* const verb_;
  const char* const what_;
  dds::Participant participant_;
  dds::Subscriber<msg::EStopState> states_;
  dds::Publisher<msg::EStop> pub_;
  std::map<std::string, RobotSide> robots_;
  std::uint64_t request_ = 0;
};

}  // namespace

int estop_main(int argc, char** argv) {
  EStopArgs a;
  if (const int status = parse_estop_args(argc, argv, a); status >= 0) return status;
  try {
    a.options.participant_name = "poise/estop";
    EStopCommand command(a);
    if (!command.discover() || !command.send()) return 1;
    const int missing = command.wait_for_acknowledgements();
    command.print_verdict(missing);
    if (a.hold) {
      command.hold();
      return 0;
    }
    return missing == 0 ? 0 : 1;
  } catch (const std::exception& ex) {
    std::fprintf(stderr, "poise estop: %s\n", ex.what());
    return 2;
  }
}

}  // namespace poise::launch
