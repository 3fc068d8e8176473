#pragma once
// Shared fixtures of the controller tests: the project humanoid, seeded random states.

#include <Eigen/Geometry>
#include <random>
#include <string>

#include "poise/controller/balance_controller.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"

namespace poise::controller::test {

inline std::string humanoid_config_path() {
  return std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/robot.yaml";
}

struct Humanoid {
  model::RobotConfig robot = model::load_robot_config(humanoid_config_path());
  model::Model model = model::load_robot_model(robot);
};

inline const Humanoid& humanoid() {
  static const Humanoid h;
  return h;
}

inline double uniform(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

inline Eigen::Vector3d random_vec3(std::mt19937& rng, double scale) {
  return Eigen::Vector3d(uniform(rng, -scale, scale), uniform(rng, -scale, scale),
                         uniform(rng, -scale, scale));
}

inline Eigen::Matrix3d random_rotation(std::mt19937& rng, double max_angle) {
  const Eigen::Vector3d axis = random_vec3(rng, 1.0).normalized();
  return Eigen::AngleAxisd(uniform(rng, -max_angle, max_angle), axis).toRotationMatrix();
}

/// The nominal standing state, feet in contact, CoP at the sole centres (from the robot config's
/// q_nominal and the model's forward kinematics).
inline RobotState standing_state(const BalanceController& c) {
  const auto& model = c.model();
  const auto& robot = c.robot();
  RobotState s = c.make_state();
  s.X_WB = model::base_pose(robot.q_nominal);
  s.q = robot.q_nominal.tail(model.njoints);
  model::Data data(model);
  model::forward_kinematics(model, data, robot.q_nominal);
  for (int i = 0; i < 2; ++i) {
    const auto& f = robot.feet[i];
    const model::SE3 X = model::frame_placement(model, data, f.frame_id);
    s.feet[i].in_contact = true;
    s.feet[i].X_WF = X;
    s.feet[i].cop_W = X.act(Eigen::Vector3d(0.5 * (f.sole.x_min + f.sole.x_max),
                                            0.5 * (f.sole.y_min + f.sole.y_max), -f.sole.height));
    s.feet[i].normal_force = 250.0;
  }
  return s;
}

/// Standing state perturbed: joints +-dq, velocities +-dv, base tilted and moving.
inline RobotState random_state(const BalanceController& c, std::mt19937& rng, double dq = 0.1,
                               double dv = 0.5) {
  RobotState s = standing_state(c);
  const auto& model = c.model();
  for (int j = 0; j < model.njoints; ++j) {
    const double lo = model.limits[j].lower + 0.02, hi = model.limits[j].upper - 0.02;
    s.q[j] = std::clamp(s.q[j] + uniform(rng, -dq, dq), lo, hi);
    s.qd[j] = uniform(rng, -dv, dv);
  }
  s.X_WB = model::SE3(random_rotation(rng, 0.1) * s.X_WB.R, s.X_WB.p + random_vec3(rng, 0.02));
  s.v_WB = random_vec3(rng, 0.2 * dv);
  s.omega_WB = random_vec3(rng, 0.5 * dv);
  return s;
}

}  // namespace poise::controller::test
