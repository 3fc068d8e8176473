#pragma once
// Balance reference (paper Fig. 6 inputs; idl/balance_reference.idl): desired CoM, angular
// momentum, upper-body motion and foot targets. Joint vectors in the MODEL joint order.

#include <Eigen/Core>
#include <array>

#include "poise/model/spatial.hpp"

namespace poise::controller {

enum class FootMode : std::uint8_t {
  kAuto = 0,     ///< support when the foot is measured in contact (moving-support rule, Sec. 4.2)
  kSupport = 1,  ///< support, at its target if has_target, else where it rests
  kSwing = 2,    ///< not a support: moved to its target by eq (36) (held where it is if no target)
};

struct FootReference {
  FootMode mode = FootMode::kAuto;
  bool has_target = false;
  model::SE3 X_WF_target;                             ///< desired pose T_d of the foot frame
  model::Motion V_WF_target = model::Motion::Zero();  ///< desired [v_Fo; omega], W axes
};

struct BalanceReference {
  /// false: CoM above the mid-point of the support feet, velocity the mean of theirs (Sec. 4.2).
  bool has_com_target = false;
  Eigen::Vector3d com_W = Eigen::Vector3d::Zero();           ///< r_G,d [m]
  Eigen::Vector3d com_velocity_W = Eigen::Vector3d::Zero();  ///< rdot_G,d [m/s]
  Eigen::Vector3d k_W = Eigen::Vector3d::Zero();             ///< k_d [N m s]
  Eigen::VectorXd upper_body_qdd;  ///< theta_dd^u_d feed-forward (dim n; leg entries ignored)
  bool has_upper_body_q = false;
  Eigen::VectorXd upper_body_q;  ///< upper-body posture target (dim n; leg entries ignored)
  /// Velocity of the posture target (dim n; leg entries ignored; zero for a fixed posture).
  /// Not in idl/balance_reference.idl yet: the node leaves it zero (a moving posture target then
  /// lags, the PD damping it towards zero velocity).
  Eigen::VectorXd upper_body_qd;
  std::array<FootReference, 2> feet;

  /// Sizes the joint vectors (zeros). Allocates: configuration time only.
  void resize(int n) {
    upper_body_qdd.setZero(n);
    upper_body_q.setZero(n);
    upper_body_qd.setZero(n);
  }
};

}  // namespace poise::controller
