#include "poise/node/robot_description.hpp"

#include <stdexcept>
#include <thread>

namespace poise::node {

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
