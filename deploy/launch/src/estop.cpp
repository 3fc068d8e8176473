// `poise estop`: engage (or release) the robot's e-stop on poise/estop. The robot's safety layer
// (components/safety) damps every joint while it is engaged and ignores joint commands; the stop
// is latched until released.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <thread>

#include <poise/msg/estop.h>

#include "poise/dds/cli.hpp"
#include "poise/dds/dds.hpp"
#include "poise/launch/launch.hpp"
#include "poise/node/shutdown.hpp"
#include "poise/cli/parse.hpp"

namespace poise::launch {

int estop_main(int argc, char** argv) {
  dds::DdsOptions options = dds::dds_options_from_env();
  bool release = false, hold = false;
  std::string reason = "poise estop";
  int wait_ms = 5000;
  CLI::App app{
      "Engage the robot's e-stop (poise/estop): its safety layer damps every joint and ignores "
      "joint commands until released with --release."};
  app.name(argc > 0 ? argv[0] : "poise estop");
  app.add_flag("--release", release, "release the e-stop (the robot then holds its posture "
                                      "until a fresh joint command)");
  app.add_option("--reason", reason, "why (shown in the robot's log and diagnostics)")
      ->capture_default_str()
      ->check([](const std::string& s) {
        return s.size() <= 128 ? std::string() : std::string("at most 128 characters");
      });
  app.add_flag("--hold", hold,
               "stay on the domain until Ctrl-C, so that a robot side that starts later still "
               "sees the (latched) e-stop");
  app.add_option("--wait-ms", wait_ms, "how long to wait for a robot to match")
      ->capture_default_str()
      ->check(CLI::Range(0, 600000));
  dds::add_dds_options(app, options);
  POISE_CLI_PARSE(app, argc, argv);
  try {
    options.participant_name = "poise/estop";
    dds::Participant participant(options);
    dds::Publisher<msg::EStop> pub(participant);
    const bool matched = pub.wait_for_matches(1, std::chrono::milliseconds(wait_ms));
    if (!matched && !hold) {
      std::fprintf(stderr,
                   "poise estop: no robot subscribed to poise/estop on domain %d (%s) within %d "
                   "ms: nothing sent\n",
                   options.domain_id, std::string(dds::to_string(options.vendor)).c_str(),
                   wait_ms);
      return 1;
    }
    msg::EStop e;
    e.engaged(!release);
    e.source("poise estop");
    e.reason(reason);
    if (!pub.publish(e)) {
      std::fprintf(stderr, "poise estop: publish failed\n");
      return 1;
    }
    if (!pub.wait_for_acknowledgments(std::chrono::milliseconds(wait_ms)))
      std::fprintf(stderr, "poise estop: not acknowledged by every robot within %d ms\n", wait_ms);
    std::printf("e-stop %s (%s) on domain %d: %d robot reader(s)\n",
                release ? "RELEASED" : "ENGAGED", reason.c_str(), options.domain_id,
                pub.matched());
    std::fflush(stdout);
    if (hold) {
      node::install_shutdown_handlers();
      while (!node::shutdown_requested())
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise estop: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::launch
