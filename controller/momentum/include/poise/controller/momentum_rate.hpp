#pragma once
// Desired momentum rate change, paper eqs (10)-(11).

#include <Eigen/Core>

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

}  // namespace poise::controller
