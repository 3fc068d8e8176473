#pragma once
// Shared helpers of the estimator tests: the project humanoid and exact sensor frames of a robot
// standing still (built from the model and statics, independently of the estimator).

#include <Eigen/Geometry>
#include <random>
#include <string>

#include "poise/estimator/estimator.hpp"
#include "poise/model/centroidal.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"

namespace poise::estimator::test {

inline std::string humanoid_yaml() {
  return std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/robot.yaml";
}

inline bool all_finite(const EstimatorState& s) {
  bool ok = s.X_WB.R.allFinite() && s.X_WB.p.allFinite() && s.v_WB.allFinite() &&
            s.omega_WB.allFinite() && s.q.allFinite() && s.qd.allFinite() &&
            s.q_model.allFinite() && s.v_model.allFinite() && s.com_W.allFinite() &&
            s.com_velocity_W.allFinite() && s.k_W.allFinite() && s.l_W.allFinite() &&
            s.gyro_bias_I.allFinite() && s.accel_bias_I.allFinite();
  for (const auto& f : s.feet)
    ok = ok && f.X_WF.R.allFinite() && f.X_WF.p.allFinite() && f.V_WF.allFinite() &&
         f.cop_W.allFinite() && std::isfinite(f.normal_force);
  return ok;
}

/// Sensor frames of the humanoid standing still at its nominal posture: exact kinematics, the
/// IMU reading gravity (plus seeded noise and a constant bias), foot wrenches of a static
/// weight distribution with the CoM above the weighted mean of the chosen foot CoPs.
struct StandingRobot {
  model::RobotConfig config;
  model::Model model;
  model::Data data;
  Eigen::VectorXd q_true;               ///< nq
  SE3 X_WI;                             ///< true IMU pose
  std::array<SE3, kNumFeet> X_WF;       ///< true foot poses
  std::array<Vector3, kNumFeet> cop_W;  ///< chosen CoP per foot
  std::array<Force, kNumFeet> wrench_Fo_F;
  Vector3 com_W;
  Vector3 gyro_bias{0.004, -0.003, 0.002};
  Vector3 accel_bias{0.0, 0.0, 0.05};
  double gyro_std = 3e-4 / std::sqrt(1e-3);
  double accel_std = 2e-3 / std::sqrt(1e-3);
  std::mt19937 rng{41};

  StandingRobot()
      : config(model::load_robot_config(humanoid_yaml())),
        model(model::load_robot_model(config)),
        data(model) {
    q_true = config.q_nominal;
    model::centroidal_momentum(model, data, q_true, Eigen::VectorXd::Zero(model.nv));
    com_W = data.com;
    model::forward_kinematics(model, data, q_true);
    X_WI = model::frame_placement(model, data, config.imu_frame_id);
    for (int f = 0; f < kNumFeet; ++f)
      X_WF[f] = model::frame_placement(model, data, config.feet[f].frame_id);
    // Weights so that the CoM lies above the weighted mean of the CoPs: CoP_x = com_x under
    // each foot's centre line, CoP_y at the foot frame's y; w_r y_r + w_l y_l = com_y.
    const double yr = X_WF[0].p.y(), yl = X_WF[1].p.y();
    const double wl = (com_W.y() - yr) / (yl - yr);
    const std::array<double, 2> w{1.0 - wl, wl};
    const double mg = model.total_mass * 9.81;
    for (int f = 0; f < kNumFeet; ++f) {
      cop_W[f] = Vector3(com_W.x(), X_WF[f].p.y(), 0.0);
      const Vector3 force_W(0.0, 0.0, w[f] * mg);
      const Vector3 force_F = X_WF[f].R.transpose() * force_W;
      const Vector3 cop_F = X_WF[f].act_inv(cop_W[f]);
      wrench_Fo_F[f].head<3>() = force_F;
      wrench_Fo_F[f].tail<3>() = cop_F.cross(force_F);
    }
  }

  /// Fills one frame of tick k.
  void fill(std::int64_t k, SensorFrame& s) {
    std::normal_distribution<double> n01(0.0, 1.0);
    s.tick = k;
    s.stamp_ns = k * 1000000;
    s.q = q_true.tail(model.njoints);
    s.qd.setZero();
    s.tau_measured.setZero();
    s.imu_q_WI = Eigen::Quaterniond(X_WI.R);
    s.imu_omega_I = gyro_bias + gyro_std * Vector3(n01(rng), n01(rng), n01(rng));
    s.imu_specific_force_I = X_WI.R.transpose() * Vector3(0, 0, 9.81) + accel_bias +
                             accel_std * Vector3(n01(rng), n01(rng), n01(rng));
    s.foot_wrench_Fo_F = wrench_Fo_F;
  }
};

}  // namespace poise::estimator::test
