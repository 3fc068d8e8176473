// `poise push`: one push on the disturbance topic (the simulator applies it live).
#include <CLI/CLI.hpp>

#include <array>
#include <chrono>
#include <cstdio>
#include <thread>

#include <poise/msg/disturbance.h>

#include "poise/dds/cli.hpp"
#include "poise/dds/dds.hpp"
#include "poise/launch/launch.hpp"
#include "poise/cli/parse.hpp"

namespace poise::launch {

int push_main(int argc, char** argv) {
  dds::DdsOptions options = dds::dds_options_from_env();
  std::string link = "pelvis";
  std::array<double, 3> force{0.0, 0.0, 0.0}, point{0.0, 0.0, 0.0};
  double duration = 0.1, start = -1.0;
  unsigned id = 1;
  int wait_ms = 5000;
  CLI::App app{
      "Push a link of the simulated robot: publishes one Disturbance (PUSH) on "
      "poise/disturbance. Use the domain that `poise run` printed."};
  app.name(argc > 0 ? argv[0] : "poise push");
  app.add_option("--link", link, "URDF link to push")->capture_default_str();
  app.add_option("--force", force, "force in world axes FX FY FZ [N]")->required();
  app.add_option("--point", point, "point of application in the link frame X Y Z [m]");
  app.add_option("--duration", duration, "[s]")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--start", start, "robot time when it starts [s]; < 0: at once")
      ->capture_default_str();
  app.add_option("--id", id, "id echoed in the simulator's log")->capture_default_str();
  app.add_option("--wait-ms", wait_ms, "how long to wait for the simulator to match")
      ->capture_default_str();
  dds::add_dds_options(app, options);
  POISE_CLI_PARSE(app, argc, argv);
  for (double v : force)
    if (!std::isfinite(v)) {
      std::fprintf(stderr, "poise push: --force must be finite\n");
      return 2;
    }
  if (link.size() > 64) {
    std::fprintf(stderr, "poise push: --link is longer than 64 characters\n");
    return 2;
  }
  try {
    options.participant_name = "poise/push";
    dds::Participant participant(options);
    dds::Publisher<msg::Disturbance> pub(participant);
    if (!pub.wait_for_matches(1, std::chrono::milliseconds(wait_ms))) {
      std::fprintf(stderr,
                   "poise push: no simulator subscribed to poise/disturbance on domain %d "
                   "(%s) within %d ms\n",
                   options.domain_id, std::string(dds::to_string(options.vendor)).c_str(), wait_ms);
      return 1;
    }
    msg::Disturbance d;
    d.id(id);
    d.kind(msg::DISTURBANCE_PUSH);
    d.link(link);
    d.point_L(point);
    d.force_W(force);
    d.start_time_s(start);
    d.duration_s(duration);
    d.axis_W({1.0, 0.0, 0.0});
    // The reader may not have matched this writer yet (discovery is per side): give it time.
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    if (!pub.publish(d)) {
      std::fprintf(stderr, "poise push: publish failed\n");
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // reliable delivery
    std::printf("pushed %s with (%.1f, %.1f, %.1f) N for %.3f s (id %u, domain %d)\n", link.c_str(),
                force[0], force[1], force[2], duration, id, options.domain_id);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise push: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::launch
