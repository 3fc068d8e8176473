#pragma once
// IDL (idl/sensors.idl, idl/state.idl, idl/ground_truth.idl) <-> estimator library conversions.
// Per-joint IDL arrays are in the robot description's joint order; the library uses the model's
// joint order: `model_to_wire[j]` (node::model_to_wire_map) is the IDL index of model joint j.
// Allocation-free, noexcept.

#include <vector>

#include <poise/msg/ground_truth.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>

#include "poise/estimator/types.hpp"

namespace poise::estimator_node {

/// Sensors (wire order) -> SensorFrame (model order, sized by Estimator::make_sensor_frame()).
void from_msg(const msg::Sensors& in, const std::vector<int>& model_to_wire,
              estimator::SensorFrame& out) noexcept;

/// EstimatorState (model order) -> State (wire order); entries past joint_count are zero.
void to_msg(const estimator::EstimatorState& in, const std::vector<int>& model_to_wire,
            msg::State& out) noexcept;

/// Debug (--ground-truth-state): overwrites the base pose and twist, the CoM, its velocity, the
/// linear momentum (mass * CoM velocity) and the feet's contact flags and centres of pressure of
/// `state` with the simulator's ground truth, and sets STATE_GROUND_TRUTH.
void overwrite_with_ground_truth(const msg::GroundTruth& truth, double mass,
                                 msg::State& state) noexcept;

}  // namespace poise::estimator_node
