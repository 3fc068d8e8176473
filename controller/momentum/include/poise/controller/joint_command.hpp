#pragma once
// Output of one controller tick (idl/joint_command.idl): the robot evaluates
// tau = tau_ff + kp (q_ref - q) + kd (qd_ref - qd)   (paper eqs (34)-(35)) at its own rate.
// Joint vectors in the MODEL joint order.

#include <Eigen/Core>
#include <cstdint>

namespace poise::controller {

enum class CommandMode : std::uint8_t {
  kTorque = 0,   ///< tau_ff plus the PD terms
  kDamping = 1,  ///< safe mode: tau = -kd qd
  kZero = 2,     ///< limp
};

struct JointCommand {
  std::int64_t tick = -1;  ///< tick of the state this command answers
  CommandMode mode = CommandMode::kDamping;
  Eigen::VectorXd tau_ff;  ///< feed-forward torque from inverse dynamics [N m] (dim n)
  Eigen::VectorXd q_ref;   ///< theta* [rad] (dim n)
  Eigen::VectorXd qd_ref;  ///< theta_dot* [rad/s] (dim n)
  Eigen::VectorXd kp;      ///< [N m/rad] (dim n)
  Eigen::VectorXd kd;      ///< [N m s/rad] (dim n)

  /// Sizes every vector (zeros). Allocates: configuration time only.
  void resize(int n) {
    tau_ff.setZero(n);
    q_ref.setZero(n);
    qd_ref.setZero(n);
    kp.setZero(n);
    kd.setZero(n);
  }
};

}  // namespace poise::controller
