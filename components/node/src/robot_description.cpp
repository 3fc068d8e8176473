#include "poise/node/robot_description.hpp"
#include "poise/cli/read_file.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <fstream>
#include <stdexcept>
#include <thread>

namespace poise::node {
namespace {

constexpr const char* kTopic = "poise/robot_description";

std::string join_lines(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines)
    out += "\n  - " + l;
  return out;
}

}  // namespace

RobotFromDescription robot_from_description(const msg::RobotDescription& d) {
  const std::string who = "robot '" + d.robot_name() + "'";
  if (d.robot_config().empty())
    throw std::runtime_error(
        std::string(kTopic) + " of " + who +
        " carries no robot configuration (its robot_config is empty: an older or minimal "
        "driver): pass the robot's configuration with --robot FILE (robot.yaml; schema in "
        "deploy/robots/README.md)");
  if (d.urdf().empty())
    throw std::runtime_error(std::string(kTopic) + " of " + who +
                             " carries no URDF (its urdf is empty): pass --robot FILE");
  RobotFromDescription r;
  try {
    r.config = model::parse_robot_config(d.robot_config(), d.urdf(),
                                         "from " + std::string(kTopic) + " (" + who + ")");
    r.model = model::load_robot_model(r.config);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("the robot on ") + kTopic + " does not load: " +
                             e.what());
  }
  r.source = kTopic;
  return r;
}

std::vector<std::string> description_differences(const RobotFromDescription& robot,
                                                 const std::string& label,
                                                 const msg::RobotDescription& d) {
  const std::string desc = "the description";
  std::vector<std::string> out;
  auto pair = [&](const std::string& what, const auto& x, const auto& y) {
    std::ostringstream os;
    os.precision(12);
    os << what << ": " << x << " in " << label << ", " << y << " in " << desc;
    out.push_back(os.str());
  };
  if (!d.robot_config().empty()) {
    const RobotFromDescription wire = robot_from_description(d);
    out = model::robot_differences(robot.config, robot.model, label, wire.config, wire.model,
                                   desc);
  } else if (!d.urdf().empty()) {
    // No configuration on the wire: compare the models (the configuration against itself).
    model::Model wire_model;
    try {
      wire_model = model::build_model_from_urdf_string(d.urdf(), "of " + std::string(kTopic));
    } catch (const std::exception& e) {
      throw std::runtime_error(std::string("the URDF on ") + kTopic + " does not load: " +
                               e.what());
    }
    out = model::robot_differences(robot.config, robot.model, label, robot.config, wire_model,
                                   desc);
  }
  // What the description says in its own fields (also without robot_config / urdf).
  if (!d.robot_name().empty() && d.robot_name() != robot.config.name &&
      (d.robot_config().empty() ? d.robot_name() != robot.model.name : true))
    pair("robot name", "'" + robot.config.name + "'", "'" + d.robot_name() + "'");
  const std::set<std::string> wire_joints(d.joint_names().begin(), d.joint_names().end());
  const std::set<std::string> model_joints(robot.model.joint_names.begin(),
                                           robot.model.joint_names.end());
  if (wire_joints != model_joints) {
    std::string only_model, only_wire;
    for (const auto& j : model_joints)
      if (!wire_joints.count(j)) only_model += (only_model.empty() ? "" : ", ") + j;
    for (const auto& j : wire_joints)
      if (!model_joints.count(j)) only_wire += (only_wire.empty() ? "" : ", ") + j;
    if (!only_model.empty()) out.push_back("joints only in " + label + ": " + only_model);
    if (!only_wire.empty())
      out.push_back("joints only in " + desc + " (joint_names): " + only_wire);
  }
  if (!d.imu_frame().empty() && d.imu_frame() != robot.config.imu_frame)
    pair("imu_frame", "'" + robot.config.imu_frame + "'", "'" + d.imu_frame() + "'");
  const char* side[2] = {"right", "left"};
  for (int f = 0; f < 2; ++f) {
    const msg::SoleGeometry& s = d.feet()[f];
    if (s.foot_frame().empty()) continue;  // not given
    const model::FootConfig& c = robot.config.feet[f];
    const std::string k = std::string("feet.") + side[f];
    if (s.foot_frame() != c.frame) pair(k + ".frame", "'" + c.frame + "'", "'" + s.foot_frame() + "'");
    auto num = [&](const std::string& what, double x, double y) {
      if (std::abs(x - y) > 1e-9 * std::max(1.0, std::abs(x))) pair(k + "." + what, x, y);
    };
    num("sole.x_min [m]", c.sole.x_min, s.x_min());
    num("sole.x_max [m]", c.sole.x_max, s.x_max());
    num("sole.y_min [m]", c.sole.y_min, s.y_min());
    num("sole.y_max [m]", c.sole.y_max, s.y_max());
    num("sole.height [m]", c.sole.height, s.sole_height());
    if (!d.robot_config().empty()) {  // a driver without a configuration may leave these to us
      num("safety_margin [m]", robot.config.safety_margin, s.safety_margin());
      num("mu", robot.config.friction_mu, s.mu());
      num("mu_torsion [m]", robot.config.torsional_mu, s.mu_torsion());
    }
  }
  // One line per difference: the full comparison and the field checks may name the same one.
  std::vector<std::string> unique;
  for (const auto& l : out)
    if (std::find(unique.begin(), unique.end(), l) == unique.end()) unique.push_back(l);
  return unique;
}

RobotFromDescription resolve_robot(Node& node, const msg::RobotDescription& description,
                                   const std::string& override_path) {
  (void)node;
  if (override_path.empty()) {
    RobotFromDescription r = robot_from_description(description);
    dds::log(dds::LogLevel::info, "robot from %s: %s, %d joints, %.2f kg (no robot files read)",
             kTopic, r.config.name.c_str(), r.model.njoints, r.model.total_mass);
    return r;
  }
  RobotFromDescription r;
  try {
    r.config = model::load_robot_config(override_path);
    r.model = model::load_robot_model(r.config);
  } catch (const std::exception& e) {
    throw std::runtime_error("--robot '" + override_path + "': " + e.what());
  }
  r.source = override_path;
  const std::string label = "--robot '" + override_path + "'";
  const std::vector<std::string> diff = description_differences(r, label, description);
  if (!diff.empty())
    throw std::runtime_error("the robot of " + label + " is not the robot on " + kTopic +
                             " ('" + description.robot_name() + "'); refusing to run. " +
                             std::to_string(diff.size()) + " difference" +
                             (diff.size() == 1 ? "" : "s") + ":" + join_lines(diff) +
                             "\n(run without --robot to use the robot of the description)");
  dds::log(dds::LogLevel::info, "robot from %s (checked against %s: the same robot): %s",
           override_path.c_str(), kTopic, r.config.name.c_str());
  return r;
}

msg::RobotDescription describe_robot(const model::RobotConfig& robot, const model::Model& model,
                                     const std::string& robot_yaml, double control_period_s) {
  msg::RobotDescription d;
  d.robot_name(robot.name);
  std::string urdf = robot.urdf_xml;
  if (urdf.empty()) {
    urdf = cli::read_regular_file(robot.urdf_path, "URDF", model::kMaxFileBytes);
  }
  d.urdf(urdf);
  d.robot_config(robot_yaml);
  for (const auto& name : model.joint_names)
    d.joint_names().push_back(name);
  d.imu_frame(robot.imu_frame);
  for (std::size_t f = 0; f < 2; ++f) {
    const model::FootConfig& fc = robot.feet[f];
    msg::SoleGeometry& s = d.feet()[f];
    s.foot_frame(fc.frame);
    s.x_min(fc.sole.x_min);
    s.x_max(fc.sole.x_max);
    s.y_min(fc.sole.y_min);
    s.y_max(fc.sole.y_max);
    s.sole_height(fc.sole.height);
    s.safety_margin(robot.safety_margin);
    s.mu(robot.friction_mu);
    s.mu_torsion(robot.torsional_mu);
  }
  d.control_period_s(control_period_s);
  return d;
}

msg::RobotDescription wait_for_robot_description(Node& node, std::chrono::milliseconds timeout) {
  dds::Subscriber<msg::RobotDescription> sub(node.participant());
  msg::RobotDescription d;
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!sub.take_latest(d)) {
    if (shutdown_requested())
      throw std::runtime_error("shutdown while waiting for the robot description");
    if (std::chrono::steady_clock::now() >= end)
      throw std::runtime_error("no robot description on poise/robot_description within " +
                               std::to_string(timeout.count()) +
                               " ms (is the robot/simulator running on domain " +
                               std::to_string(node.participant().domain_id()) + "?)");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  dds::log(dds::LogLevel::info, "robot description: %s, %zu joints", d.robot_name().c_str(),
           d.joint_names().size());
  return d;
}

std::vector<int> model_to_wire_map(const std::vector<std::string>& wire_joints,
                                   const std::vector<std::string>& model_joints) {
  if (wire_joints.size() > 64)
    throw std::runtime_error("robot description has " + std::to_string(wire_joints.size()) +
                             " joints; MAX_JOINTS is 64");
  std::vector<int> map(model_joints.size(), -1);
  for (std::size_t j = 0; j < model_joints.size(); ++j) {
    for (std::size_t i = 0; i < wire_joints.size(); ++i)
      if (wire_joints[i] == model_joints[j]) map[j] = static_cast<int>(i);
    if (map[j] < 0)
      throw std::runtime_error("joint '" + model_joints[j] +
                               "' of the robot model is not in the robot description");
  }
  for (const auto& w : wire_joints) {
    bool found = false;
    for (const auto& m : model_joints)
      found = found || m == w;
    if (!found)
      throw std::runtime_error("joint '" + w +
                               "' of the robot description is not in the robot model");
  }
  return map;
}

}  // namespace poise::node
