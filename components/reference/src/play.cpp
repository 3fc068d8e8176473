// `poise reference play FILE`: plays a balance-reference trajectory on poise/balance_reference in
// step with poise/state (see include/poise/reference/play.hpp).
#include "poise/reference/play.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <exception>

#include <poise/msg/balance_reference.h>
#include <poise/msg/state.h>

#include "poise/model/robot_config.hpp"
#include "poise/node/convert.hpp"
#include "poise/node/mailbox.hpp"
#include "poise/node/node.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/reference/player.hpp"
#include "poise/reference/trajectory.hpp"
#include "poise/cli/parse.hpp"

namespace poise::reference {
namespace {

constexpr int kWriterHistory = 512;  // late joiners get the references not yet due
constexpr std::size_t kStateQueue = 256;  // states held for the player, in order

// The command line of `poise reference play`.
struct PlayArgs {
  node::NodeOptions options;
  std::string path;
  int lead_ticks = -1, description_timeout_ms = 30000;
  bool hold = false;
};

void add_play_options(CLI::App& app, PlayArgs& args) {
  app.add_option("file", args.path, "trajectory YAML")->required()->check(CLI::ExistingFile);
  app.add_option("--lead-ticks", args.lead_ticks,
                 "send each reference this many ticks ahead of the state (default: the file's "
                 "lead_ticks, else 200)");
  app.add_option("--description-timeout-ms", args.description_timeout_ms,
                 "how long to wait for the robot description")
      ->capture_default_str();
  app.add_flag("--hold", args.hold, "keep running after the end (until SIGINT/SIGTERM)");
  node::add_node_options(app, args.options, "reference");
}

// The problems of one state's references, reported as the player's counters moved.
struct PlayerCounters {
  bool was_late;
  std::uint64_t restarts, skipped;
};

void report_player_events(node::Node& node, const Player& player, const Trajectory& traj,
                          const PlayerCounters& before, std::uint64_t k) {
  if (player.skipped() != before.skipped)
    node.error("tick %llu: %llu ticks of the trajectory skipped (states lost: the player fell "
               "behind); their references are not sent",
               static_cast<unsigned long long>(k),
               static_cast<unsigned long long>(player.skipped() - before.skipped));
  if (player.started_late() && !before.was_late)
    node.error("started late: the trajectory begins at %.3f s, the state is at %.3f s",
               traj.begin(), player.first_state_time());
  if (player.restarts() != before.restarts)
    node.error("poise/state restarted at tick %llu: references already sent are not sent again",
               static_cast<unsigned long long>(k));
}

// Feeds the player every state of `state_queue` in order until the trajectory is played (and,
// with --hold, until the node stops); returns whether it was played to the end.
bool play_states(node::Node& node, Player& player, const Trajectory& traj,
                 node::SampleQueue<msg::State>& state_queue,
                 dds::Publisher<msg::BalanceReference>& pub, bool hold) {
  bool done = false;
  std::uint64_t dropped = 0;
  msg::State in;
  while (node.running()) {
    const std::int64_t next_diag = node.poll();
    if (!state_queue.pop(in, next_diag)) continue;
    if (state_queue.dropped() != dropped) {
      node.error("%llu poise/state samples dropped: the player fell more than %zu ticks behind",
                 static_cast<unsigned long long>(state_queue.dropped() - dropped), kStateQueue);
      dropped = state_queue.dropped();
    }
    const std::int64_t t0 = node::now_ns();
    const std::uint64_t k = in.header().tick();
    const PlayerCounters before{player.started_late(), player.restarts(), player.skipped()};
    player.on_state(in, [&](const msg::BalanceReference& r) { return node.publish(pub, r); });
    report_player_events(node, player, traj, before, k);
    node.tick_done(k, node::now_ns() - t0);
    if (player.done() && !done) {
      done = true;
      std::printf("poise reference: played %llu references, ticks %llu..%llu\n",
                  static_cast<unsigned long long>(player.sent()),
                  static_cast<unsigned long long>(player.first_sent()),
                  static_cast<unsigned long long>(player.last_sent()));
      std::fflush(stdout);
      if (!hold) break;
    }
  }
  return done;
}

void write_play_summary(node::Node& node, const Player& player, bool done) {
  char extra[256];
  std::snprintf(extra, sizeof(extra),
                "{\"references_sent\": %llu, \"first_tick\": %llu, \"last_tick\": %llu, "
                "\"skipped_ticks\": %llu, \"started_late\": %s, \"completed\": %s}",
                static_cast<unsigned long long>(player.sent()),
                static_cast<unsigned long long>(player.first_sent()),
                static_cast<unsigned long long>(player.last_sent()),
                static_cast<unsigned long long>(player.skipped()),
                player.started_late() ? "true" : "false", done ? "true" : "false");
  node.write_summary(extra);
}

// 0 once the trajectory was played to the end, 3 when it was not or nothing reached the robot.
int play_exit_code(const Player& player, const Trajectory& traj, bool done) {
  if (done && player.sent() == 0) {
    // Every tick of the trajectory had passed when the player saw the robot: nothing reached it.
    std::fprintf(stderr,
                 "poise reference: played nothing: the robot's state was at %.3f s, past the "
                 "trajectory's end (%.3f s); start the player before the robot, or the robot "
                 "with --realtime\n",
                 player.first_state_time(), traj.end());
    return 3;
  }
  return done ? 0 : 3;
}

int play(int argc, char** argv) {
  PlayArgs args;
  CLI::App app{
      "Play a balance-reference trajectory (CoM moves, upper-body joint swings; format in "
      "deploy/scenarios/references/README.md) on poise/balance_reference, in step with "
      "poise/state: on the state of tick k it sends the references of the ticks up to k + "
      "--lead-ticks, each stamped with its tick, and poise-controller applies each at exactly "
      "its tick (also in lockstep). CoM shifts are relative to the measured CoM when the first "
      "move is sent; joint swings are about the robot's nominal posture; a step swings the "
      "foot (FOOT_SWING) up and back down to the pose it stood at when its first reference is "
      "sent, the other foot FOOT_SUPPORT (with feet: every foot not stepping is FOOT_SUPPORT "
      "from the first reference on). Ends (code 0) once "
      "the state has reached the trajectory's last tick."};
  app.name(argc > 0 ? argv[0] : "poise reference play");
  add_play_options(app, args);
  POISE_CLI_PARSE(app, argc, argv);

  const Trajectory traj = load_trajectory(args.path);
  const int lead = args.lead_ticks > 0 ? args.lead_ticks : traj.lead_ticks;
  if (lead >= kWriterHistory) throw std::runtime_error("--lead-ticks must be < 512");
  node::Node node(args.options);
  std::printf(
      "poise reference: %s, %.3f..%.3f s, lead %d ticks, domain %d: waiting for the robot\n",
      traj.name.c_str(), traj.begin(), traj.end(), lead, args.options.dds.domain_id);
  std::fflush(stdout);
  const msg::RobotDescription description = node::wait_for_robot_description(
      node, std::chrono::milliseconds(args.description_timeout_ms));
  const node::RobotFromDescription resolved =
      node::resolve_robot(node, description, args.options.robot);
  const model::RobotConfig& robot = resolved.config;
  const model::Model& model = resolved.model;
  const std::vector<int> model_to_wire =
      node::model_to_wire_map(description.joint_names(), model.joint_names);
  const double period =
      description.control_period_s() > 0.0 ? description.control_period_s() : 1e-3;
  Player player(traj, model, robot, model_to_wire, period, lead);

  // Every state in order, not only the newest: the references of a tick do not depend on which
  // states a busy player happened to see (one answer with the in-process loop, also in lockstep).
  node::SampleQueue<msg::State> state_queue(kStateQueue);
  dds::Subscriber<msg::State> states(node.participant(), state_queue.callback());
  node.watch(states);
  dds::Publisher<msg::BalanceReference> pub(node.participant(), dds::Qos::latched(kWriterHistory));

  const bool done = play_states(node, player, traj, state_queue, pub, args.hold);
  write_play_summary(node, player, done);
  return play_exit_code(player, traj, done);
}

}  // namespace

int play_main(int argc, char** argv) {
  try {
    return play(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise reference: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::reference
