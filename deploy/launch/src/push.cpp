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
namespace {

using Clock = std::chrono::steady_clock;

/// `poise push`'s command line.
struct PushArgs {
  dds::DdsOptions options = dds::dds_options_from_env();
  std::string link = "pelvis";
  std::array<double, 3> force{0.0, 0.0, 0.0}, point{0.0, 0.0, 0.0};
  double duration = 0.1, start = -1.0;
  unsigned id = 1;
  int wait_ms = 5000;
};

/// Parses `poise push`'s command line into `a`. Returns the exit status when the command line
/// ends the verb (0 after --help, 2 for a usage error or a bad force or link), else -1.
int parse_push_args(int argc, char** argv, PushArgs& a) {
  CLI::App app{
      "Push a link of the simulated robot: publishes one Disturbance (PUSH) on "
      "poise/disturbance. Use the domain that `poise run` printed."};
  app.name(argc > 0 ? argv[0] : "poise push");
  app.add_option("--link", a.link, "URDF link to push")->capture_default_str();
  app.add_option("--force", a.force, "force in world axes FX FY FZ [N]")->required();
  app.add_option("--point", a.point, "point of application in the link frame X Y Z [m]");
  app.add_option("--duration", a.duration, "[s]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--start", a.start, "robot time when it starts [s]; < 0: at once")
      ->capture_default_str();
  app.add_option("--id", a.id, "id echoed in the simulator's log")->capture_default_str();
  app.add_option("--wait-ms", a.wait_ms,
                 "how long to wait for the simulator to match, and then for its ground truth to "
                 "show the push")
      ->capture_default_str();
  dds::add_dds_options(app, a.options);
  POISE_CLI_PARSE(app, argc, argv);
  for (double v : a.force)
    if (!std::isfinite(v)) {
      std::fprintf(stderr, "poise push: --force must be finite\n");
      return 2;
    }
  if (a.link.size() > 64) {
    std::fprintf(stderr, "poise push: --link is longer than 64 characters\n");
    return 2;
  }
  return -1;
}

/// A simulator: the one publisher of poise/ground_truth (it publishes while a reader matches),
/// whose poise/disturbance reader matched `pub`. False (said) when none did by --wait-ms.
bool wait_for_simulator(const PushArgs& a, dds::Publisher<msg::Disturbance>& pub,
                        dds::Subscriber<msg::GroundTruth>& truth, msg::GroundTruth& gt) {
  const auto give_up = Clock::now() + std::chrono::milliseconds(a.wait_ms);
  bool simulator = false;
  while (!(simulator && pub.matched() > 0) && Clock::now() < give_up) {
    while (truth.take(gt))
      simulator = true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (!simulator || pub.matched() == 0) {
    std::fprintf(stderr,
                 "poise push: no simulator on domain %d (%s) within %d ms: %s; nothing sent\n",
                 a.options.domain_id, std::string(dds::to_string(a.options.vendor)).c_str(),
                 a.wait_ms,
                 !simulator ? "nothing publishes poise/ground_truth (readers of "
                              "poise/disturbance such as recorders are not simulators)"
                            : "the simulator's poise/disturbance reader did not match");
    return false;
  }
  return true;
}

msg::Disturbance push_of(const PushArgs& a) {
  msg::Disturbance d;
  d.id(a.id);
  d.kind(msg::DISTURBANCE_PUSH);
  d.link(a.link);
  d.point_L(a.point);
  d.force_W(a.force);
  d.start_time_s(a.start);
  d.duration_s(a.duration);
  d.axis_W({1.0, 0.0, 0.0});
  return d;
}

/// The robot time at which the ground truth first shows the push applied (< 0: not by the end of
/// its window, or the simulator stopped for --wait-ms). Applied: a ground-truth step whose push
/// force holds this one (its component along it is at least half of it). A zero force is applied
/// when its start has passed. `last_time`: the newest ground truth's robot time.
double wait_until_applied(const PushArgs& a, dds::Subscriber<msg::GroundTruth>& truth,
                          msg::GroundTruth& gt, double sent_at, double& last_time) {
  const auto& force = a.force;
  const double f2 = force[0] * force[0] + force[1] * force[1] + force[2] * force[2];
  const double begins = a.start < 0.0 ? sent_at : a.start;
  auto deadline = Clock::now() + std::chrono::milliseconds(a.wait_ms);
  double applied_at = -1.0;
  last_time = sent_at;
  while (applied_at < 0.0 && Clock::now() < deadline) {
    while (truth.take(gt)) {
      const double t = static_cast<double>(gt.header().stamp_ns()) * 1e-9;
      const auto& p = gt.push_force_W();
      const double along = p[0] * force[0] + p[1] * force[1] + p[2] * force[2];
      if (applied_at < 0.0 && t >= begins && (f2 == 0.0 ? true : along >= 0.5 * f2))
        applied_at = t;
      if (t > last_time) {
        last_time = t;
        deadline = std::max(deadline, Clock::now() + std::chrono::milliseconds(a.wait_ms));
      }
      if (applied_at < 0.0 && t > begins + a.duration + 0.05) break;  // its window has passed
    }
    if (applied_at < 0.0 && last_time > begins + a.duration + 0.05) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return applied_at;
}

}  // namespace

int push_main(int argc, char** argv) {
  PushArgs a;
  if (const int status = parse_push_args(argc, argv, a); status >= 0) return status;
  try {
    a.options.participant_name = "poise/push";
    dds::Participant participant(a.options);
    dds::Publisher<msg::Disturbance> pub(participant);
    // A deep history: a short push lasts only a few samples, and none may be overwritten unseen.
    dds::Qos truth_qos = dds::TopicTraits<msg::GroundTruth>::default_qos();
    truth_qos.history_depth = 1024;
    dds::Subscriber<msg::GroundTruth> truth(participant, truth_qos);
    msg::GroundTruth gt;
    if (!wait_for_simulator(a, pub, truth, gt)) return 1;
    const msg::Disturbance d = push_of(a);
    // The reader may not have matched this writer yet (discovery is per side): give it time.
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    while (truth.take(gt)) {
    }
    const double sent_at = static_cast<double>(gt.header().stamp_ns()) * 1e-9;
    if (!pub.publish(d)) {
      std::fprintf(stderr, "poise push: publish failed\n");
      return 1;
    }
    double last_time = sent_at;
    const double applied_at = wait_until_applied(a, truth, gt, sent_at, last_time);
    if (applied_at < 0.0) {
      std::fprintf(stderr,
                   "poise push: the simulator did not apply the push (id %u) to '%s': its ground "
                   "truth at robot time %.3f s shows no such force (an unknown link, a start in "
                   "the past, or a simulator that stopped)\n",
                   a.id, a.link.c_str(), last_time);
      return 1;
    }
    std::printf("pushed %s with (%.1f, %.1f, %.1f) N for %.3f s: applied from robot time %.3f s "
                "(id %u, domain %d)\n",
                a.link.c_str(), a.force[0], a.force[1], a.force[2], a.duration, applied_at, a.id,
                a.options.domain_id);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise push: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::launch
