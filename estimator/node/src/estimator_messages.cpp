#include "poise/estimator_node/estimator_messages.hpp"

#include <Eigen/Geometry>
#include "poise/node/convert.hpp"

namespace poise::estimator_node {
namespace {

using node::put3;
using node::vec3;
void put_pose(const model::SE3& X, msg::Pose& out) {
  node::put_pose(X.R, X.p, out);
}

}  // namespace

void from_msg(const msg::Sensors& in, const std::vector<int>& model_to_wire,
              estimator::SensorFrame& out) noexcept {
  out.tick = static_cast<std::int64_t>(in.header().tick());
  out.stamp_ns = in.header().stamp_ns();
  const int n = static_cast<int>(model_to_wire.size());
  for (int j = 0; j < n && j < out.q.size(); ++j) {
    const int w = model_to_wire[j];
    out.q[j] = in.q()[w];
    out.qd[j] = in.qd()[w];
    out.tau_measured[j] = in.tau_measured()[w];
  }
  const auto& imu = in.imu();
  out.imu_q_WI = Eigen::Quaterniond(imu.orientation_wxyz()[0], imu.orientation_wxyz()[1],
                                    imu.orientation_wxyz()[2], imu.orientation_wxyz()[3]);
  out.imu_omega_I = vec3(imu.angular_velocity_I());
  out.imu_specific_force_I = vec3(imu.specific_force_I());
  for (int f = 0; f < estimator::kNumFeet; ++f) {
    const msg::Wrench& w = in.foot_wrench_F()[f];
    out.foot_wrench_Fo_F[f] << vec3(w.force()), vec3(w.torque());
  }
}

void to_msg(const estimator::EstimatorState& in, const std::vector<int>& model_to_wire,
            msg::State& out) noexcept {
  out.header().tick(static_cast<std::uint64_t>(in.tick));
  out.header().stamp_ns(in.stamp_ns);
  out.status_flags(in.status_flags);
  put_pose(in.X_WB, out.base_W());
  put3(in.v_WB, out.base_velocity_W().linear());
  put3(in.omega_WB, out.base_velocity_W().angular());
  out.joint_count(static_cast<std::uint32_t>(model_to_wire.size()));
  out.q().fill(0.0);
  out.qd().fill(0.0);
  for (std::size_t j = 0; j < model_to_wire.size(); ++j) {
    if (model_to_wire[j] < 0 || model_to_wire[j] >= static_cast<int>(msg::MAX_JOINTS))
      continue;  // loaders refuse robots with more joints than the wire carries
    out.q()[model_to_wire[j]] = in.q[static_cast<Eigen::Index>(j)];
    out.qd()[model_to_wire[j]] = in.qd[static_cast<Eigen::Index>(j)];
  }
  put3(in.com_W, out.com_W());
  put3(in.com_velocity_W, out.com_velocity_W());
  put3(in.k_W, out.angular_momentum_W());
  put3(in.l_W, out.linear_momentum_W());
  for (int f = 0; f < estimator::kNumFeet; ++f) {
    const estimator::FootEstimate& e = in.feet[f];
    msg::FootState& o = out.feet()[f];
    o.in_contact(e.in_contact);
    put_pose(e.X_WF, o.pose_W());
    put3(e.V_WF.head<3>(), o.velocity_W().linear());
    put3(e.V_WF.tail<3>(), o.velocity_W().angular());
    put3(e.cop_W, o.cop_W());
    o.normal_force(e.normal_force);
  }
  put3(in.gyro_bias_I, out.imu_gyro_bias_I());
  put3(in.accel_bias_I, out.imu_accel_bias_I());
}

void overwrite_with_ground_truth(const msg::GroundTruth& truth, double mass,
                                 msg::State& state) noexcept {
  state.base_W(truth.base_W());
  state.base_velocity_W(truth.base_velocity_W());
  state.com_W(truth.com_W());
  state.com_velocity_W(truth.com_velocity_W());
  for (int i = 0; i < 3; ++i)
    state.linear_momentum_W()[i] = mass * truth.com_velocity_W()[i];
  // The contacts and their centres of pressure too: the estimate's CoP lies in the estimate's
  // world, which is not the truth's when the base estimate is off (moving supports); with the
  // true base pose the controller needs the true CoP (its resting rule compares the two).
  for (int f = 0; f < 2; ++f) {
    state.feet()[f].in_contact(truth.feet()[f].in_contact());
    state.feet()[f].cop_W(truth.feet()[f].cop_W());
  }
  state.status_flags((state.status_flags() & ~msg::STATE_INITIALIZING) | msg::STATE_GROUND_TRUTH);
}

}  // namespace poise::estimator_node
