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
#include "poise/reference/sampler.hpp"
#include "poise/reference/trajectory.hpp"

namespace poise::reference {
namespace {

constexpr int kWriterHistory = 512;  // late joiners get the references not yet due

int play(int argc, char** argv) {
  node::NodeOptions options;
  std::string path;
  int lead_ticks = -1, description_timeout_ms = 30000;
  bool hold = false;
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
  app.add_option("file", path, "trajectory YAML")->required()->check(CLI::ExistingFile);
  app.add_option("--lead-ticks", lead_ticks,
                 "send each reference this many ticks ahead of the state (default: the file's "
                 "lead_ticks, else 200)");
  app.add_option("--description-timeout-ms", description_timeout_ms,
                 "how long to wait for the robot description")
      ->capture_default_str();
  app.add_flag("--hold", hold, "keep running after the end (until SIGINT/SIGTERM)");
  node::add_node_options(app, options, "reference");
  CLI11_PARSE(app, argc, argv);

  const Trajectory traj = load_trajectory(path);
  const int lead = lead_ticks > 0 ? lead_ticks : traj.lead_ticks;
  if (lead >= kWriterHistory) throw std::runtime_error("--lead-ticks must be < 512");
  node::Node node(options);
  std::printf(
      "poise reference: %s, %.3f..%.3f s, lead %d ticks, domain %d: waiting for the robot\n",
      traj.name.c_str(), traj.begin(), traj.end(), lead, options.dds.domain_id);
  std::fflush(stdout);
  const msg::RobotDescription description =
      node::wait_for_robot_description(node, std::chrono::milliseconds(description_timeout_ms));
  const node::RobotFromDescription resolved = node::resolve_robot(node, description, options.robot);
  const model::RobotConfig& robot = resolved.config;
  const model::Model& model = resolved.model;
  const std::vector<int> model_to_wire =
      node::model_to_wire_map(description.joint_names(), model.joint_names);
  const double period =
      description.control_period_s() > 0.0 ? description.control_period_s() : 1e-3;
  const auto n = static_cast<std::uint32_t>(model_to_wire.size());

  // Swings -> wire indices (upper-body joints only: the controller ignores leg entries).
  std::vector<int> swing_wire;
  for (const JointSwing& s : traj.joints) {
    const int j = model.joint_index(s.joint);
    if (j < 0) throw std::runtime_error(path + ": joint '" + s.joint + "' is not in the robot");
    bool upper = false;
    for (int u : robot.upper_body_joint_indices)
      upper = upper || u == j;
    if (!upper)
      throw std::runtime_error(path + ": joint '" + s.joint +
                               "' is not an upper-body joint (robot.yaml joint_groups)");
    swing_wire.push_back(model_to_wire[static_cast<std::size_t>(j)]);
  }
  msg::BalanceReference ref;  // the constant part
  ref.joint_count(n);
  for (std::size_t j = 0; j < model_to_wire.size(); ++j)
    ref.upper_body_q()[model_to_wire[j]] = robot.q_nominal[7 + static_cast<Eigen::Index>(j)];
  const auto nominal_q = ref.upper_body_q();

  node::Mailbox<msg::State> state_box;
  dds::Subscriber<msg::State> states(node.participant(), state_box.callback());
  node.watch(states);
  dds::Publisher<msg::BalanceReference> pub(node.participant(), dds::Qos::latched(kWriterHistory));

  // Steps: the stood pose of the step foot, taken from the state when the step's first
  // reference is sent (lead_ticks before it starts: the foot is a support then).
  int step_index = -1;
  model::SE3 X_stood, X_target;
  model::Motion V_target;
  const double t_begin = traj.begin(), t_end = traj.end();
  std::uint64_t seen = 0, next = 0, sent = 0, first_sent = 0, last_sent = 0;
  std::uint64_t end_tick = 0;
  bool end_known = false, origin_set = false, done = false;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero(), offset, velocity;
  msg::State in;
  while (node.running()) {
    const std::int64_t next_diag = node.poll();
    if (!state_box.wait(seen, next_diag) || !state_box.take(in, seen)) continue;
    const std::int64_t t0 = node::now_ns();
    const std::uint64_t k = in.header().tick();
    const double t_k = static_cast<double>(in.header().stamp_ns()) * 1e-9;
    if (!end_known) {
      end_tick = k + static_cast<std::uint64_t>(std::max(0.0, std::ceil((t_end - t_k) / period)));
      end_known = true;
      next = k + 1;
      if (t_k + period > t_begin)
        node.error("started late: the trajectory begins at %.3f s, the state is at %.3f s", t_begin,
                   t_k);
    }
    for (std::uint64_t j = std::max(next, k + 1);
         j <= k + static_cast<std::uint64_t>(lead) && j <= end_tick; ++j) {
      next = j + 1;
      const double t = t_k + static_cast<double>(j - k) * period;
      if (t < t_begin - 0.5 * period) continue;  // nothing to change yet
      ref.header().tick(j);
      ref.header().stamp_ns(static_cast<long long>(std::llround(t * 1e9)));
      const bool com = com_offset(traj, t, offset, velocity);
      if (com && !origin_set) {
        origin = Eigen::Vector3d(in.com_W()[0], in.com_W()[1], in.com_W()[2]);
        origin_set = true;
      }
      ref.has_com_target(com);
      for (int i = 0; i < 3; ++i) {
        ref.com_W()[i] = com ? origin[i] + offset[i] : 0.0;
        ref.com_velocity_W()[i] = com ? velocity[i] : 0.0;
      }
      ref.has_upper_body_q(has_joint_motion(traj, t));
      ref.upper_body_q() = nominal_q;
      ref.upper_body_qdd().fill(0.0);
      for (std::size_t s = 0; s < traj.joints.size(); ++s) {
        double q, qd, qdd;
        swing_offset(traj.joints[s], t, q, qd, qdd);
        ref.upper_body_q()[swing_wire[s]] += q;
        ref.upper_body_qdd()[swing_wire[s]] += qdd;
      }
      if (!traj.feet.empty()) {
        const FootStep* step = active_step(traj, t);
        const int index = step != nullptr ? static_cast<int>(step - traj.feet.data()) : -1;
        if (step != nullptr && index != step_index) {
          step_index = index;
          const msg::Pose& p = in.feet()[static_cast<std::size_t>(step->side)].pose_W();
          X_stood = model::SE3(node::rotation(p), node::vec3(p.position()));
        }
        for (int side = 0; side < 2; ++side) {
          msg::FootReference& f = ref.feet()[static_cast<std::size_t>(side)];
          const bool swing = step != nullptr && step->side == side;
          f.mode(swing ? msg::FOOT_SWING : msg::FOOT_SUPPORT);
          f.has_target(swing);
          if (!swing) continue;
          step_target(*step, t, X_stood, X_target, V_target);
          node::put_pose(X_target.R, X_target.p, f.target_W());
          node::put3(V_target.head<3>(), f.target_velocity_W().linear());
          node::put3(V_target.tail<3>(), f.target_velocity_W().angular());
        }
      }
      if (!node.publish(pub, ref)) continue;
      if (sent++ == 0) first_sent = j;
      last_sent = j;
    }
    node.tick_done(k, node::now_ns() - t0);
    if (end_known && k >= end_tick && !done) {
      done = true;
      std::printf("poise reference: played %llu references, ticks %llu..%llu\n",
                  static_cast<unsigned long long>(sent),
                  static_cast<unsigned long long>(first_sent),
                  static_cast<unsigned long long>(last_sent));
      std::fflush(stdout);
      if (!hold) break;
    }
  }
  char extra[256];
  std::snprintf(extra, sizeof(extra),
                "{\"references_sent\": %llu, \"first_tick\": %llu, \"last_tick\": %llu, "
                "\"completed\": %s}",
                static_cast<unsigned long long>(sent), static_cast<unsigned long long>(first_sent),
                static_cast<unsigned long long>(last_sent), done ? "true" : "false");
  node.write_summary(extra);
  return done ? 0 : 3;
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
