
#include "poise/controller_node/controller_messages.hpp"
#include "poise/node/convert.hpp"

#include <Eigen/Geometry>

namespace poise::controller_node {
namespace {

using node::vec3;
model::SE3 pose(const msg::Pose& p) {
  return model::SE3(node::rotation(p), vec3(p.position()));
}
model::Motion twist(const msg::Twist& t) {
  model::Motion m;
  m << vec3(t.linear()), vec3(t.angular());
  return m;
}

}  // namespace

void from_msg(const msg::State& in, const std::vector<int>& model_to_wire,
              controller::RobotState& out) noexcept {
  out.tick = static_cast<std::int64_t>(in.header().tick());
  out.time = static_cast<double>(in.header().stamp_ns()) * 1e-9;
  out.X_WB = pose(in.base_W());
  out.v_WB = vec3(in.base_velocity_W().linear());
  out.omega_WB = vec3(in.base_velocity_W().angular());
  for (std::size_t j = 0; j < model_to_wire.size(); ++j) {
    out.q[static_cast<Eigen::Index>(j)] = in.q()[model_to_wire[j]];
    out.qd[static_cast<Eigen::Index>(j)] = in.qd()[model_to_wire[j]];
  }
  out.com_W = vec3(in.com_W());
  out.com_velocity_W = vec3(in.com_velocity_W());
  out.k_W = vec3(in.angular_momentum_W());
  out.l_W = vec3(in.linear_momentum_W());
  for (int f = 0; f < 2; ++f) {
    const msg::FootState& s = in.feet()[f];
    controller::FootMeasurement& o = out.feet[f];
    o.in_contact = s.in_contact();
    o.X_WF = pose(s.pose_W());
    o.V_WF = twist(s.velocity_W());
    o.cop_W = vec3(s.cop_W());
    o.normal_force = s.normal_force();
  }
}

bool from_msg(const msg::BalanceReference& in, const std::vector<int>& model_to_wire,
              controller::BalanceReference& out) noexcept {
  out.has_com_target = in.has_com_target();
  out.com_W = vec3(in.com_W());
  out.com_velocity_W = vec3(in.com_velocity_W());
  out.k_W = vec3(in.angular_momentum_W());
  for (int f = 0; f < 2; ++f) {
    const msg::FootReference& r = in.feet()[f];
    controller::FootReference& o = out.feet[f];
    o.mode = r.mode() == msg::FOOT_SUPPORT ? controller::FootMode::kSupport
             : r.mode() == msg::FOOT_SWING ? controller::FootMode::kSwing
                                           : controller::FootMode::kAuto;
    o.has_target = r.has_target();
    o.X_WF_target = pose(r.target_W());
    o.V_WF_target = twist(r.target_velocity_W());
  }
  if (in.joint_count() != model_to_wire.size()) return false;
  out.has_upper_body_q = in.has_upper_body_q();
  for (std::size_t j = 0; j < model_to_wire.size(); ++j) {
    out.upper_body_qdd[static_cast<Eigen::Index>(j)] = in.upper_body_qdd()[model_to_wire[j]];
    out.upper_body_q[static_cast<Eigen::Index>(j)] = in.upper_body_q()[model_to_wire[j]];
  }
  return true;
}

void to_msg(const controller::JointCommand& in, const msg::Header& header,
            const std::vector<int>& model_to_wire, msg::JointCommand& out) noexcept {
  out.header(header);
  out.mode(in.mode == controller::CommandMode::kTorque    ? msg::COMMAND_TORQUE
           : in.mode == controller::CommandMode::kDamping ? msg::COMMAND_DAMPING
                                                          : msg::COMMAND_ZERO);
  out.joint_count(static_cast<std::uint32_t>(model_to_wire.size()));
  for (std::size_t j = 0; j < model_to_wire.size(); ++j) {
    const auto i = static_cast<Eigen::Index>(j);
    const int w = model_to_wire[j];
    if (w < 0 || w >= static_cast<int>(msg::MAX_JOINTS)) continue;  // loaders refuse such robots
    out.tau_ff()[w] = in.tau_ff[i];
    out.q_ref()[w] = in.q_ref[i];
    out.qd_ref()[w] = in.qd_ref[i];
    out.kp()[w] = in.kp[i];
    out.kd()[w] = in.kd[i];
  }
}

}  // namespace poise::controller_node
