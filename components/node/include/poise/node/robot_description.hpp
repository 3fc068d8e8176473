#pragma once
// Start-up helpers around the latched "poise/robot_description" topic: every component learns
// the robot's joint order from it (the order of every per-joint array on the 1 kHz topics).

#include <chrono>
#include <string>
#include <vector>

#include <poise/msg/robot_description.h>

#include "poise/node/node.hpp"

namespace poise::node {

/// Waits for the robot description (reliable, transient-local). Throws std::runtime_error after
/// `timeout` or on shutdown. Configuration time.
msg::RobotDescription wait_for_robot_description(Node& node, std::chrono::milliseconds timeout);

/// Index map between the description's joint order and a model's joint order, by name:
/// model_to_wire[j] = index in the description of model joint j. Throws std::runtime_error naming
/// the first joint that one side has and the other has not, or when there are more than
/// MAX_JOINTS joints.
std::vector<int> model_to_wire_map(const std::vector<std::string>& wire_joints,
                                   const std::vector<std::string>& model_joints);

}  // namespace poise::node
