#pragma once
// Desired momentum rate change, paper eqs (10)-(11).

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "poise/controller/controller_config.hpp"
#include "poise/model/spatial.hpp"

namespace poise::controller {

/// Eqs (10)-(11), all vectors world axes (dim 3):
///   k_dot_d = Gamma11 (k_d - k)
///   l_dot_d = m [Gamma21 (rdot_G,d - rdot_G) + Gamma22 (r_G,d - r_G)]
/// Returns [k_dot_d; l_dot_d] (dim 6, angular first as in the paper). Allocation-free.
inline model::Vector6 desired_momentum_rate(const MomentumGains& gains, double mass,
                                            const Eigen::Vector3d& k, const Eigen::Vector3d& k_d,
                                            const Eigen::Vector3d& com,
                                            const Eigen::Vector3d& com_d,
                                            const Eigen::Vector3d& vcom,
                                            const Eigen::Vector3d& vcom_d) {
  model::Vector6 hdot;
  hdot.head<3>() = gains.gamma11.cwiseProduct(k_d - k);
  hdot.tail<3>() =
      mass * (gains.gamma21.cwiseProduct(vcom_d - vcom) + gains.gamma22.cwiseProduct(com_d - com));
  return hdot;
}

/// MomentumGains::upright_pitch_rate, upright_roll_rate: the angular momentum that (10)'s k_d
/// gains to bring the trunk upright, I_G omega_u (world axes). omega_u = the rotation vector that
/// takes the base's up (base_up_B, in the base frame) to the world's up (up_W, unit), times
/// r_roll about the robot's forward made horizontal (forward_B, in the base frame) and r_pitch
/// about the horizontal axis across it (about every axis when the forward is vertical). I_G is
/// the locked centroidal inertia, I_locked_B = the base's angular columns of A_G's angular rows
/// (they take the base's angular velocity in the base frame). Zero when upright or upside down
/// (no unique axis). The trunk's yaw is not touched. Allocation-free.
inline Eigen::Vector3d upright_angular_momentum(const Eigen::Matrix3d& R_WB,
                                                const Eigen::Vector3d& base_up_B,
                                                const Eigen::Vector3d& forward_B,
                                                const Eigen::Vector3d& up_W,
                                                const Eigen::Matrix3d& I_locked_B, double r_pitch,
                                                double r_roll) {
  const Eigen::Vector3d a = R_WB * base_up_B;
  const Eigen::Vector3d axis = a.cross(up_W);
  const double s = axis.norm();
  if (!(s > 1e-12)) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d tilt = std::atan2(s, a.dot(up_W)) / s * axis;  // horizontal
  Eigen::Vector3d f = R_WB * forward_B;
  f -= f.dot(up_W) * up_W;
  Eigen::Vector3d omega_u = r_pitch * tilt;
  if (f.norm() > 1e-6) {
    f.normalize();
    omega_u += (r_roll - r_pitch) * tilt.dot(f) * f;
  }
  return I_locked_B * (R_WB.transpose() * omega_u);
}

}  // namespace poise::controller
