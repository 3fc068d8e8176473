
#include "poise/sim_node/sim_messages.hpp"
#include "poise/cli/read_file.hpp"
#include "poise/node/convert.hpp"

#include <tinyxml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "poise/model/robot_config.hpp"

namespace poise::sim_node {
namespace {

using node::put3;
void put_pose(const Eigen::Isometry3d& X, msg::Pose& out) {
  node::put_pose(X.linear(), X.translation(), out);
}
bool is_side(const std::string& name, char side) {
  const std::string full = side == 'r' ? "right" : "left";
  return name == full || name == std::string(1, side) || name.rfind(full, 0) == 0 ||
         name.rfind(std::string(1, side) + "_", 0) == 0;
}

}  // namespace

FootOrder foot_order(const sim::Simulator& sim) {
  FootOrder order{-1, -1};
  const auto& names = sim.foot_names();
  for (int i = 0; i < static_cast<int>(names.size()); ++i) {
    if (is_side(names[i], 'r')) order[0] = i;
    if (is_side(names[i], 'l')) order[1] = i;
  }
  if (order[0] < 0 || order[1] < 0) {
    std::string list;
    for (const auto& n : names)
      list += (list.empty() ? "" : ", ") + n;
    throw std::runtime_error("the topics need a right and a left foot; the simulator's feet are: " +
                             list);
  }
  return order;
}

msg::RobotDescription make_robot_description(const sim::World& scenario,
                                             const sim::Simulator& sim, const FootOrder& feet) {
  msg::RobotDescription d;
  d.urdf(cli::read_regular_file(scenario.sim.robot.urdf_path, "URDF", model::kMaxFileBytes));
  d.joint_names(sim.joint_names());
  d.imu_frame(scenario.sim.robot.imu_frame);
  double margin = 0.0, mu = scenario.sim.world.ground.friction, mu_torsion = 0.0;
  if (!scenario.robot_config.empty()) {
    const model::RobotConfig rc = model::load_robot_config(scenario.robot_config);
    d.robot_name(rc.name);
    margin = rc.safety_margin;
    mu = rc.friction_mu;
    mu_torsion = rc.torsional_mu;
    // The configuration text as the scenario's robot has it: the nodes build their robot from it
    // and the urdf field (its `urdf:` entry is ignored on the receiving side).
    d.robot_config(
        cli::read_regular_file(scenario.robot_config, "robot config", model::kMaxFileBytes));
  } else {
    // A robot given inline (urdf + feet): no configuration to send (nodes need --robot); the
    // name is the URDF's robot name.
    TiXmlDocument doc;
    doc.Parse(d.urdf().c_str());
    const TiXmlElement* root = doc.RootElement();
    const char* name = root ? root->Attribute("name") : nullptr;
    d.robot_name(name ? name : scenario.name);
  }
  for (int f = 0; f < 2; ++f) {
    const sim::FootConfig& fc = scenario.sim.robot.feet[feet[f]];
    msg::SoleGeometry& s = d.feet()[f];
    s.foot_frame(fc.frame);
    s.x_min(fc.sole.x_min);
    s.x_max(fc.sole.x_max);
    s.y_min(fc.sole.y_min);
    s.y_max(fc.sole.y_max);
    s.sole_height(fc.sole.height);
    s.safety_margin(margin);
    s.mu(mu);
    s.mu_torsion(mu_torsion);
  }
  d.control_period_s(sim.dt());
  return d;
}

void to_msg(const sim::SensorFrame& in, const FootOrder& feet, msg::Sensors& out) noexcept {
  out.header().tick(static_cast<std::uint64_t>(in.tick));
  out.header().stamp_ns(std::llround(in.time * 1e9));
  // Loaders refuse robots with more joints than the wire carries; never write past the arrays.
  const auto n = std::min(static_cast<std::size_t>(in.q.size()), std::size_t{msg::MAX_JOINTS});
  out.joint_count(static_cast<std::uint32_t>(n));
  for (std::size_t j = 0; j < n; ++j) {
    const auto i = static_cast<Eigen::Index>(j);
    out.q()[j] = in.q[i];
    out.qd()[j] = in.qd[i];
    out.tau_measured()[j] = in.tau_measured[i];
  }
  const Eigen::Quaterniond& q = in.imu_q_WI;
  out.imu().orientation_wxyz() = {q.w(), q.x(), q.y(), q.z()};
  put3(in.imu_omega_I, out.imu().angular_velocity_I());
  put3(in.imu_specific_force_I, out.imu().specific_force_I());
  for (int f = 0; f < 2; ++f) {
    const auto& w = in.foot_wrench_Fo_F[static_cast<std::size_t>(feet[f])];  // [torque; force]
    put3(w.tail<3>(), out.foot_wrench_F()[f].force());
    put3(w.head<3>(), out.foot_wrench_F()[f].torque());
  }
}

SlipTracker::SlipTracker(std::vector<int> platform_of_sim_foot)
    : platform_(std::move(platform_of_sim_foot)),
      was_in_contact_(platform_.size(), false),
      p_support_0_(platform_.size(), Eigen::Vector3d::Zero()),
      slip_(platform_.size(), Eigen::Vector3d::Zero()) {}

void SlipTracker::update(const sim::GroundTruth& truth) noexcept {
  for (std::size_t f = 0; f < platform_.size() && f < truth.feet.size(); ++f) {
    const auto& foot = truth.feet[f];
    const int p = platform_[f];
    const bool on_platform = p >= 0 && static_cast<std::size_t>(p) < truth.platform_X_WP.size();
    const Eigen::Vector3d p_S =
        on_platform ? Eigen::Vector3d(truth.platform_X_WP[static_cast<std::size_t>(p)].inverse() *
                                      foot.X_WF.translation())
                    : Eigen::Vector3d(foot.X_WF.translation());
    if (!foot.in_contact) {
      slip_[f].setZero();
    } else if (!was_in_contact_[f]) {
      p_support_0_[f] = p_S;
      slip_[f].setZero();
    } else {
      const Eigen::Vector3d d_S = p_S - p_support_0_[f];
      slip_[f] =
          on_platform
              ? Eigen::Vector3d(truth.platform_X_WP[static_cast<std::size_t>(p)].linear() * d_S)
              : d_S;
    }
    was_in_contact_[f] = foot.in_contact;
  }
}

std::vector<std::int32_t> urdf_link_index_of_bodies(const std::string& urdf_xml,
                                                    const std::vector<std::string>& body_names) {
  TiXmlDocument doc;
  doc.Parse(urdf_xml.c_str());
  const TiXmlElement* robot = doc.Error() ? nullptr : doc.FirstChildElement("robot");
  if (robot == nullptr) throw std::runtime_error("the URDF text is not a readable <robot>");
  std::vector<std::string> links;
  for (const TiXmlElement* e = robot->FirstChildElement("link"); e != nullptr;
       e = e->NextSiblingElement("link"))
    links.emplace_back(e->Attribute("name") ? e->Attribute("name") : "");
  std::vector<std::int32_t> index;
  index.reserve(body_names.size());
  for (const std::string& b : body_names) {
    const auto it = std::find(links.begin(), links.end(), b);
    if (it == links.end())
      throw std::runtime_error("simulator body '" + b + "' is not a <link> of the URDF");
    index.push_back(static_cast<std::int32_t>(it - links.begin()));
  }
  return index;
}

void to_msg(const sim::GroundTruth& in, const FootOrder& feet, const SlipTracker& slip,
            const std::vector<std::int32_t>& urdf_link_of_body, std::uint64_t total_other_contacts,
            msg::GroundTruth& out) noexcept {
  out.header().tick(static_cast<std::uint64_t>(in.tick));
  out.header().stamp_ns(std::llround(in.time * 1e9));
  put_pose(in.X_WB, out.base_W());
  put3(in.v_WB, out.base_velocity_W().linear());
  put3(in.omega_WB, out.base_velocity_W().angular());
  put3(in.com_W, out.com_W());
  put3(in.com_vel_W, out.com_velocity_W());
  for (int f = 0; f < 2; ++f) {
    const sim::FootContactTruth& t = in.feet[static_cast<std::size_t>(feet[f])];
    msg::FootContactTruth& o = out.feet()[f];
    o.in_contact(t.in_contact);
    put3(t.force_W, o.wrench_W().force());
    put3(t.torque_Fo_W, o.wrench_W().torque());
    put3(t.in_contact ? t.cop_W : Eigen::Vector3d::Zero(), o.cop_W());
    put3(slip.slip_W(feet[f]), o.slip_W());
  }
  std::uint32_t count = 0;
  out.other_contact_links().fill(-1);
  const std::size_t capacity = out.other_contact_links().size();
  for (std::size_t b = 0; b < in.non_foot_contact.size() && count < capacity; ++b)
    if (in.non_foot_contact[b])
      out.other_contact_links()[count++] =
          b < urdf_link_of_body.size() ? urdf_link_of_body[b] : std::int32_t{-1};
  out.other_contact_count(count);
  out.total_other_contacts(total_other_contacts);
  put3(in.push_force_W, out.push_force_W());
}

bool from_msg(const msg::JointCommand& in, sim::JointCommand& out) noexcept {
  const auto n = static_cast<std::size_t>(out.tau_ff.size());
  if (in.joint_count() != n) return false;
  out.tick = static_cast<std::int64_t>(in.header().tick());
  for (std::size_t j = 0; j < n; ++j) {
    const auto i = static_cast<Eigen::Index>(j);
    out.tau_ff[i] = in.tau_ff()[j];
    out.q_ref[i] = in.q_ref()[j];
    out.qd_ref[i] = in.qd_ref()[j];
    out.kp[i] = in.kp()[j];
    out.kd[i] = in.kd()[j];
  }
  switch (in.mode()) {
    case msg::COMMAND_TORQUE:
      out.mode = sim::CommandMode::kPd;
      break;
    case msg::COMMAND_DAMPING:
      out.mode = sim::CommandMode::kDamping;
      break;
    case msg::COMMAND_ZERO:
      out.mode = sim::CommandMode::kTorque;
      out.tau_ff.setZero();
      break;
  }
  return true;
}

bool from_msg(const msg::Disturbance& in, double now_s, sim::Push& out) {
  if (in.kind() != msg::DISTURBANCE_PUSH) return false;
  out.link = in.link().to_string();
  out.point_L = Eigen::Vector3d(in.point_L()[0], in.point_L()[1], in.point_L()[2]);
  out.force_W = Eigen::Vector3d(in.force_W()[0], in.force_W()[1], in.force_W()[2]);
  out.start = in.start_time_s() < 0.0 ? now_s : in.start_time_s();
  out.duration = in.duration_s();
  return true;
}

void settle(sim::Simulator& sim, int ticks, sim::SensorFrame& sensors, sim::GroundTruth& truth,
            double kp, double kd) {
  sim.read(sensors, truth);
  sim::JointCommand hold = sim.make_command();
  hold.mode = sim::CommandMode::kPd;
  hold.q_ref = sensors.q;
  hold.kp.setConstant(kp);
  hold.kd.setConstant(kd);
  for (int i = 0; i < ticks; ++i) {
    hold.tick = sensors.tick;
    sim.step(hold, sensors, truth);
  }
}

void to_sim(const safety::Command& in, sim::JointCommand& out) noexcept {
  out.tick = in.tick;
  out.tau_ff = in.tau_ff;
  out.q_ref = in.q_ref;
  out.qd_ref = in.qd_ref;
  out.kp = in.kp;
  out.kd = in.kd;
}

}  // namespace poise::sim_node
