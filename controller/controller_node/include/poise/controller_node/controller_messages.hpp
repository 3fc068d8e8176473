#pragma once
// IDL (idl/state.idl, idl/balance_reference.idl, idl/joint_command.idl) <-> controller library
// conversions. Per-joint IDL arrays are in the robot description's joint order; the library
// uses the model's: `model_to_wire[j]` is the IDL index of model joint j. Allocation-free,
// noexcept. Quaternions are normalised on the way in (the wire carries 8-byte doubles of unit
// quaternions; normalising removes the last-bit drift without hiding garbage, which the DDS
// layer has already refused as non-finite).

#include <vector>

#include <poise/msg/balance_reference.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/state.h>

#include "poise/controller/balance_reference.hpp"
#include "poise/controller/joint_command.hpp"
#include "poise/controller/robot_state.hpp"

namespace poise::controller_node {

/// State (wire order) -> RobotState (model order, sized by BalanceController::make_state()).
void from_msg(const msg::State& in, const std::vector<int>& model_to_wire,
              controller::RobotState& out) noexcept;

/// BalanceReference (wire order) -> library reference (model order). Per-joint arrays are used
/// only when joint_count equals the number of joints; otherwise they are left as they were and
/// false is returned (the rest is applied).
bool from_msg(const msg::BalanceReference& in, const std::vector<int>& model_to_wire,
              controller::BalanceReference& out) noexcept;

/// JointCommand (model order) -> JointCommand (wire order) with the given header.
void to_msg(const controller::JointCommand& in, const msg::Header& header,
            const std::vector<int>& model_to_wire, msg::JointCommand& out) noexcept;

}  // namespace poise::controller_node
