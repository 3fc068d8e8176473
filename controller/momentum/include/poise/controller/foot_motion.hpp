#pragma once
// Desired motion of the feet, paper Sec. 3.6 eq (36), and the moving-support rule of Sec. 4.2.

#include <Eigen/Core>

#include "poise/controller/controller_config.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/model/spatial.hpp"

namespace poise::controller {

/// Eq (36) for one foot: a_d = kp log(T^-1 T_d) + kd (v_d - v).
/// The SE(3) logarithm gives a twist in the FOOT frame; it is rotated to world axes, so that the
/// result is in the LOCAL_WORLD_ALIGNED convention of poise::model::frame_jacobian: rows
/// [classical acceleration of the foot origin; angular acceleration], world axes (dim 6), the
/// right-hand side of J qdd + J_dot qd = a_d.
/// X_WF: current foot pose, V_WF: current [v_Fo; omega] (world axes); X_WF_d, V_WF_d: desired.
inline model::Motion foot_acceleration(const FootGains& gains, const model::SE3& X_WF,
                                       const model::Motion& V_WF, const model::SE3& X_WF_d,
                                       const model::Motion& V_WF_d) {
  const model::Motion err_F = model::se3_log(X_WF.inverse() * X_WF_d);
  model::Motion a;
  a.head<3>() =
      gains.kp * (X_WF.R * err_F.head<3>()) + gains.kd * (V_WF_d.head<3>() - V_WF.head<3>());
  a.tail<3>() =
      gains.kp * (X_WF.R * err_F.tail<3>()) + gains.kd * (V_WF_d.tail<3>() - V_WF.tail<3>());
  return a;
}

/// Sec. 4.2 resting test: true when the measured CoP (world, dim 3), expressed in the foot frame,
/// lies inside the sole rectangle shrunk by `margin` [m] on every side.
inline bool cop_in_safe_region(const model::SE3& X_WF, const Eigen::Vector3d& cop_W,
                               const model::SoleRectangle& sole, double margin) {
  const Eigen::Vector3d d = X_WF.act_inv(cop_W);
  return d.x() >= sole.x_min + margin && d.x() <= sole.x_max - margin &&
         d.y() >= sole.y_min + margin && d.y() <= sole.y_max - margin;
}

/// Centre of the sole rectangle, on the sole plane, in world coordinates (dim 3).
inline Eigen::Vector3d sole_center_W(const model::SE3& X_WF, const model::SoleRectangle& sole) {
  return X_WF.act(sole.center_F());
}

/// Where the robot stands on this foot (model::FootConfig::stand_point_F: the sole centre unless
/// robot.yaml says), on the sole plane, in world coordinates (dim 3).
inline Eigen::Vector3d stand_point_W(const model::SE3& X_WF, const model::FootConfig& foot) {
  return X_WF.act(foot.stand_point_F());
}

}  // namespace poise::controller
