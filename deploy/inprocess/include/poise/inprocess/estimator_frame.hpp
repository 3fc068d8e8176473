#pragma once
// The simulator's sensor frame as the estimator's input, without DDS: used by the in-process loop
// and by the tests that run the estimator on a simulator (needs the estimator library).

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "poise/estimator/types.hpp"
#include "poise/sim/simulator.hpp"

namespace poise::inprocess {

/// Copies `s` into `out` (sized by Estimator::make_sensor_frame()): joints through `sim_to_model`
/// (sim::joint_index_map), estimator foot f from simulator foot `sim_foot[f]`; the simulator's
/// wrenches are [torque; force], the estimator's [force; torque] (both at Fo, F axes).
/// Allocation-free.
inline void to_estimator_frame(const sim::SensorFrame& s, const std::vector<int>& sim_to_model,
                               const std::array<int, 2>& sim_foot,
                               estimator::SensorFrame& out) noexcept {
  out.tick = s.tick;
  out.stamp_ns = static_cast<std::int64_t>(std::llround(s.time * 1e9));
  sim::remap_joint_vector(sim_to_model, s.q, out.q);
  sim::remap_joint_vector(sim_to_model, s.qd, out.qd);
  sim::remap_joint_vector(sim_to_model, s.tau_measured, out.tau_measured);
  out.imu_q_WI = s.imu_q_WI;
  out.imu_omega_I = s.imu_omega_I;
  out.imu_specific_force_I = s.imu_specific_force_I;
  for (int f = 0; f < 2; ++f) {
    const auto& w = s.foot_wrench_Fo_F[sim_foot[f]];
    out.foot_wrench_Fo_F[f].head<3>() = w.tail<3>();
    out.foot_wrench_Fo_F[f].tail<3>() = w.head<3>();
  }
}

}  // namespace poise::inprocess
