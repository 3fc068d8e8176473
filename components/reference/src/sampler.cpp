#include "poise/reference/sampler.hpp"

#include <stdexcept>
#include <utility>

namespace poise::reference {

Sampler::Sampler(Trajectory trajectory, const model::Model& model,
                 const model::RobotConfig& robot)
    : traj_(std::move(trajectory)),
      swing_joint_(swing_joint_indices(traj_, model, robot)),
      sole_F_(stand_points_F(robot)) {
  q_nominal_ = robot.q_nominal.tail(model.njoints);
}

std::array<Eigen::Vector3d, 2> stand_points_F(const model::RobotConfig& robot) {
  return {robot.feet[0].stand_point_F(), robot.feet[1].stand_point_F()};
}

std::vector<int> swing_joint_indices(const Trajectory& trajectory, const model::Model& model,
                                     const model::RobotConfig& robot) {
  std::vector<int> out;
  for (const JointSwing& s : trajectory.joints) {
    const int j = model.joint_index(s.joint);
    if (j < 0)
      throw std::runtime_error("reference '" + trajectory.name + "': joint '" + s.joint +
                               "' is not in the robot");
    bool upper = false;
    for (int u : robot.upper_body_joint_indices)
      upper = upper || u == j;
    if (!upper)
      throw std::runtime_error("reference '" + trajectory.name + "': joint '" + s.joint +
                               "' is not an upper-body joint (robot.yaml joint_groups)");
    out.push_back(j);
  }
  return out;
}

void step_target(const FootStep& s, double t, const model::SE3& X_stood, model::SE3& X_target,
                 model::Motion& V_target) noexcept {
  double z = 0.0, zd = 0.0, zdd = 0.0;
  step_lift(s, t, z, zd, zdd);
  X_target = X_stood;
  X_target.p.z() += z;
  V_target.setZero();
  V_target[2] = zd;
}

void Sampler::sample(double t, const Eigen::Vector3d& com_W,
                     const std::array<model::SE3, 2>& X_WF,
                     controller::BalanceReference& ref) noexcept {
  if (t < traj_.begin()) return;
  if (!traj_.com.empty() && t >= traj_.com.front().start) {
    if (!origin_set_) {
      origin_ = com_W;
      origin_set_ = true;
    }
    resolve_com_moves(traj_, t, origin_, X_WF[0].act(sole_F_[0]), X_WF[1].act(sole_F_[1]));
  }
  Eigen::Vector3d offset, velocity;
  if (com_offset(traj_, t, offset, velocity)) {
    ref.has_com_target = true;
    ref.com_W = origin_ + offset;
    ref.com_velocity_W = velocity;
  }
  if (!traj_.joints.empty() && ref.upper_body_q.size() == q_nominal_.size()) {
    ref.has_upper_body_q = has_joint_motion(traj_, t);
    ref.upper_body_q = q_nominal_;
    ref.upper_body_qd.setZero();
    ref.upper_body_qdd.setZero();
    for (std::size_t s = 0; s < traj_.joints.size(); ++s) {
      double q, qd, qdd;
      swing_offset(traj_.joints[s], t, q, qd, qdd);
      ref.upper_body_q[swing_joint_[s]] += q;
      ref.upper_body_qd[swing_joint_[s]] += qd;
      ref.upper_body_qdd[swing_joint_[s]] += qdd;
    }
  }
  if (!traj_.feet.empty()) {
    const FootStep* s = active_step(traj_, t);
    const int index = s != nullptr ? static_cast<int>(s - traj_.feet.data()) : -1;
    if (s != nullptr && index != step_) {
      step_ = index;
      X_stood_ = X_WF[static_cast<std::size_t>(s->side)];
    }
    for (int side = 0; side < 2; ++side) {
      controller::FootReference& f = ref.feet[static_cast<std::size_t>(side)];
      if (s != nullptr && s->side == side) {
        f.mode = controller::FootMode::kSwing;
        f.has_target = true;
        step_target(*s, t, X_stood_, f.X_WF_target, f.V_WF_target);
      } else {
        f.mode = controller::FootMode::kSupport;
        f.has_target = false;
        f.V_WF_target.setZero();
      }
    }
  }
}

}  // namespace poise::reference
