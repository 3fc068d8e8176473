#pragma once
// Input state of one controller tick: what the estimator provides (idl/state.idl), as plain
// preallocated Eigen data. Joint vectors are in the MODEL joint order (poise::model).

#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "poise/model/spatial.hpp"

namespace poise::controller {

/// Per foot (index poise::model::kRight = 0, kLeft = 1).
struct FootMeasurement {
  bool in_contact = false;                     ///< contact detected (F/T with hysteresis)
  model::SE3 X_WF;                             ///< foot frame pose (informational; the controller
                                               ///< recomputes it from q by forward kinematics)
  model::Motion V_WF = model::Motion::Zero();  ///< [v_Fo; omega] world axes (informational)
  Eigen::Vector3d cop_W = Eigen::Vector3d::Zero();  ///< measured centre of pressure [m]
  double normal_force = 0.0;                        ///< measured force along the sole normal [N]
};

struct RobotState {
  std::int64_t tick = 0;  ///< tick k of the sensor frame this state derives from
  double time = 0.0;      ///< robot time [s]
  model::SE3 X_WB;        ///< base (URDF root link) pose in W
  Eigen::Vector3d v_WB = Eigen::Vector3d::Zero();      ///< base origin velocity, W axes [m/s]
  Eigen::Vector3d omega_WB = Eigen::Vector3d::Zero();  ///< base angular velocity, W axes [rad/s]
  Eigen::VectorXd q;                                   ///< joint positions (dim n = model.njoints)
  Eigen::VectorXd qd;                                  ///< joint velocities (dim n)
  /// Centroidal quantities from the estimator (informational: the controller recomputes them
  /// with its own model so that they are consistent with A and A_dot*q_dot).
  Eigen::Vector3d com_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d com_velocity_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d k_W = Eigen::Vector3d::Zero();  ///< angular momentum about the CoM
  Eigen::Vector3d l_W = Eigen::Vector3d::Zero();  ///< linear momentum
  std::array<FootMeasurement, 2> feet;

  /// Sizes the joint vectors (zeros). Allocates: configuration time only.
  void resize(int n) {
    q.setZero(n);
    qd.setZero(n);
  }
};

}  // namespace poise::controller
