#pragma once
// Shared helpers of the simulator tests: configurations of the small test robots.

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "poise/sim/sim_config.hpp"
#include "poise/sim/simulator.hpp"

namespace poise::sim::test {

inline std::string urdf(const std::string& name) {
  return std::string(POISE_SOURCE_DIR) + "/tests/simulator/urdf/" + name;
}

/// One free 2 kg box whose single "foot" is the box itself.
inline SimulatorConfig box_config() {
  SimulatorConfig c;
  c.robot.urdf_path = urdf("box.urdf");
  c.robot.feet = {FootConfig{"box", "body", false, {}}};
  return c;
}

/// The 12-DoF test biped; feet from the URDF boxes, IMU on the torso.
inline SimulatorConfig biped_config(const std::string& file = "biped.urdf") {
  SimulatorConfig c;
  c.robot.urdf_path = urdf(file);
  c.robot.imu_frame = "imu_link";
  FootConfig l{"left", "l_sole", false, {}}, r{"right", "r_sole", false, {}};
  c.robot.feet = {l, r};
  c.initial.joint_names = {"l_hip_pitch", "l_knee", "l_ankle_pitch",
                           "r_hip_pitch", "r_knee", "r_ankle_pitch"};
  c.initial.joint_positions = {-0.3, 0.6, -0.3, -0.3, 0.6, -0.3};
  return c;
}

/// Sole rectangle of the biped's foot box in the sole frame.
inline SoleConfig biped_sole() {
  SoleConfig s;
  s.x_min = -0.11;
  s.x_max = 0.11;
  s.y_min = -0.06;
  s.y_max = 0.06;
  s.height = 0.0;
  return s;
}

/// The test biped lying on its back (base rotated -90 deg about y), dropped from 5 cm.
inline SimulatorConfig biped_lying_on_back_config() {
  SimulatorConfig cfg = biped_config();
  const Eigen::Quaterniond q(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitY()));
  cfg.initial.base_orientation_wxyz << q.w(), q.x(), q.y(), q.z();
  cfg.initial.auto_base_height = false;
  cfg.initial.base_position = Eigen::Vector3d(0, 0, 0.25);
  return cfg;
}

/// PD hold of the posture in `s` on every joint.
inline JointCommand hold_command(const Simulator& sim, const SensorFrame& s, double kp, double kd) {
  JointCommand c = sim.make_command();
  c.mode = CommandMode::kPd;
  c.q_ref = s.q;
  c.kp.setConstant(kp);
  c.kd.setConstant(kd);
  return c;
}

/// Damping mode on every joint (tau = -kd qd): a passive robot.
inline JointCommand damping_command(const Simulator& sim, double kd) {
  JointCommand c = sim.make_command();
  c.mode = CommandMode::kDamping;
  c.kd.setConstant(kd);
  return c;
}

}  // namespace poise::sim::test
