// `poise push`: one push on the disturbance topic (the simulator applies it live), reported done
// only when the simulator's ground truth (poise/ground_truth, which only a simulator publishes)
// shows the force applied. A recorder's reader of poise/disturbance is never taken for a
// simulator.
#include <CLI/CLI.hpp>

#include <array>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <thread>

#include <poise/msg/disturbance.h>
#include <poise/msg/ground_truth.h>

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
  app.add_option("--wait-ms", wait_ms, "how long to wait for the simulator to match, and then for its ground truth to show the push")
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
    // A deep history: a short push lasts only a few samples, and none may be overwritten unseen.
    dds::Qos truth_qos = dds::TopicTraits<msg::GroundTruth>::default_qos();
    truth_qos.history_depth = 1024;
    dds::Subscriber<msg::GroundTruth> truth(participant, truth_qos);
    using Clock = std::chrono::steady_clock;
    const auto give_up = Clock::now() + std::chrono::milliseconds(wait_ms);
    // A simulator: the one publisher of poise/ground_truth (it publishes while a reader matches).
    msg::GroundTruth gt;
    bool simulator = false;
    while (!(simulator && pub.matched() > 0) && Clock::now() < give_up) {
      while (truth.take(gt))
        simulator = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (!simulator || pub.matched() == 0) {
      std::fprintf(stderr,
                   "poise push: no simulator on domain %d (%s) within %d ms: %s; nothing sent\n",
                   options.domain_id, std::string(dds::to_string(options.vendor)).c_str(), wait_ms,
                   !simulator ? "nothing publishes poise/ground_truth (readers of "
                                "poise/disturbance such as recorders are not simulators)"
                              : "the simulator's poise/disturbance reader did not match");
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
    while (truth.take(gt)) {
    }
    const double sent_at = static_cast<double>(gt.header().stamp_ns()) * 1e-9;
    if (!pub.publish(d)) {
      std::fprintf(stderr, "poise push: publish failed\n");
      return 1;
    }
    // Applied: a ground-truth step whose push force holds this one (its component along it is
    // at least half of it). A zero force is applied when its start has passed.
    const double f2 = force[0] * force[0] + force[1] * force[1] + force[2] * force[2];
    const double begins = start < 0.0 ? sent_at : start;
    auto deadline = Clock::now() + std::chrono::milliseconds(wait_ms);
    double last_time = sent_at, applied_at = -1.0;
    while (applied_at < 0.0 && Clock::now() < deadline) {
      while (truth.take(gt)) {
        const double t = static_cast<double>(gt.header().stamp_ns()) * 1e-9;
        const auto& p = gt.push_force_W();
        const double along = p[0] * force[0] + p[1] * force[1] + p[2] * force[2];
        if (applied_at < 0.0 && t >= begins && (f2 == 0.0 ? true : along >= 0.5 * f2))
          applied_at = t;
        if (t > last_time) {
          last_time = t;
          deadline = std::max(deadline, Clock::now() + std::chrono::milliseconds(wait_ms));
        }
        if (applied_at < 0.0 && t > begins + duration + 0.05) break;  // its window has passed
      }
      if (applied_at < 0.0 && last_time > begins + duration + 0.05) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    if (applied_at < 0.0) {
      std::fprintf(stderr,
                   "poise push: the simulator did not apply the push (id %u) to '%s': its ground "
                   "truth at robot time %.3f s shows no such force (an unknown link, a start in "
                   "the past, or a simulator that stopped)\n",
                   id, link.c_str(), last_time);
      return 1;
    }
    std::printf("pushed %s with (%.1f, %.1f, %.1f) N for %.3f s: applied from robot time %.3f s "
                "(id %u, domain %d)\n",
                link.c_str(), force[0], force[1], force[2], duration, applied_at, id,
                options.domain_id);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise push: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::launch
