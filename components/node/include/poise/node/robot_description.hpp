#pragma once
// Start-up helpers around the latched "poise/robot_description" topic: every component learns
// the robot from it (configuration + model: resolve_robot) and its joint order (the order of
// every per-joint array on the 1 kHz topics).

#include <chrono>
#include <string>
#include <vector>

#include <poise/msg/robot_description.h>

#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/node.hpp"

namespace poise::node {

/// The robot a node runs with, and where it came from.
struct RobotFromDescription {
  model::RobotConfig config;
  model::Model model;
  std::string source;  ///< "poise/robot_description" or the --robot file
};

/// The robot of a description alone (no file access): its robot_config text and urdf. Throws
/// std::runtime_error when the description carries no robot_config (an old or minimal driver:
/// the message tells to pass --robot) or when either does not load (the loader's message).
RobotFromDescription robot_from_description(const msg::RobotDescription& description);

/// What differs between a robot and a description (one line per difference; empty = the same):
/// with a robot_config in the description, the full comparison (model::robot_differences);
/// always the robot name, the joint names against the description's joint list (as a set: the
/// wire order is the robot's own, model_to_wire_map maps it), the IMU frame and the sole
/// geometry of each foot. `label` names the robot's side (e.g. "--robot 'x.yaml'").
std::vector<std::string> description_differences(const RobotFromDescription& robot,
                                                 const std::string& label,
                                                 const msg::RobotDescription& description);

/// The one call every node makes once it has the description: with an empty `override_path`,
/// the robot of the description (robot_from_description); with `--robot FILE`, that file's robot,
/// which must be the description's: a difference throws std::runtime_error listing every
/// difference ("the robot of --robot 'FILE' is not the robot on poise/robot_description: ...").
/// Logs which robot the node runs with. Configuration time.
RobotFromDescription resolve_robot(Node& node, const msg::RobotDescription& description,
                                   const std::string& override_path);

/// The description a robot side publishes for `robot` (what a driver with robot files sends):
/// name, the URDF text (`robot.urdf_xml`, else the file), `robot_yaml` as robot_config, the
/// model's joint order, the IMU frame, each foot's sole and contact parameters, the control
/// period. Throws std::runtime_error when the URDF cannot be read. Configuration time.
msg::RobotDescription describe_robot(const model::RobotConfig& robot, const model::Model& model,
                                     const std::string& robot_yaml, double control_period_s);

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
