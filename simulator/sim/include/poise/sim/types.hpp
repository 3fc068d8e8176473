#pragma once
// Plain data exchanged with the simulator once per 1 ms tick. No Bullet, no DDS.
// Every vector is sized once (by Simulator::make_*) and only written in place in the loop.
//
// Conventions: world frame W is Z up, x forward. Quaternions are Eigen (w, x, y, z) and rotate
// vectors from the named child frame into the named parent frame (q_WB maps B coordinates to W).
// Joint-space vectors are in the simulator's joint order (Simulator::joint_names()).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace poise::sim {

/// How a joint command is turned into joint torque, evaluated inside the simulator at 1 kHz.
enum class CommandMode : std::uint8_t {
  kTorque = 0,   ///< tau = tau_ff
  kPd = 1,       ///< tau = tau_ff + kp (q_ref - q) + kd (qd_ref - qd)   (paper eqs (34)-(35))
  kDamping = 2,  ///< tau = -kd qd (safe mode; kd per joint, see Simulator damping gains)
};

/// One joint command (controller -> robot). All vectors have dim n = Simulator::num_joints().
/// The applied torque is clamped to the URDF effort limit of each joint.
struct JointCommand {
  std::int64_t tick = -1;  ///< tick k of the sensor frame this command derives from
  CommandMode mode = CommandMode::kTorque;
  Eigen::VectorXd tau_ff;  ///< feed-forward torque [N m] or force [N] (dim n)
  Eigen::VectorXd q_ref;   ///< reference position [rad] or [m] (dim n)
  Eigen::VectorXd qd_ref;  ///< reference velocity [rad/s] or [m/s] (dim n)
  Eigen::VectorXd kp;      ///< position gain [N m/rad] (dim n)
  Eigen::VectorXd kd;      ///< velocity gain [N m s/rad] (dim n)

  /// Zero command of dim n (mode torque, all zeros). Allocates: configuration time only.
  void resize(int n);
};

/// What a real robot could publish on the sensor topic at 1 kHz.
struct SensorFrame {
  std::int64_t tick = 0;         ///< tick number k (0 after reset)
  double time = 0.0;             ///< robot time [s] = k * dt
  Eigen::VectorXd q;             ///< joint positions [rad | m] (dim n)
  Eigen::VectorXd qd;            ///< joint velocities [rad/s | m/s] (dim n)
  Eigen::VectorXd tau_measured;  ///< joint torque actually applied by the actuator (dim n)

  Eigen::Quaterniond imu_q_WI = Eigen::Quaterniond::Identity();  ///< IMU orientation in W
  Eigen::Vector3d imu_omega_I = Eigen::Vector3d::Zero();  ///< angular velocity of I, in I [rad/s]
  /// Specific force (accelerometer reading) in I [m/s^2]: R_WI^T (a_I - g); +9.81 up at rest.
  Eigen::Vector3d imu_specific_force_I = Eigen::Vector3d::Zero();

  /// Per foot (order of the robot's feet): wrench the support exerts on the foot, measured at
  /// the foot frame origin Fo and expressed in the foot frame F: [torque (3); force (3)].
  std::vector<Eigen::Matrix<double, 6, 1>> foot_wrench_Fo_F;
};

/// Per-foot contact ground truth (never on the sensor topic).
struct FootContactTruth {
  bool in_contact = false;                            ///< any contact point with a support
  int num_points = 0;                                 ///< contact points this tick
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();  ///< total contact force on the foot [N]
  /// Contact torque about the foot frame origin Fo, in W [N m].
  Eigen::Vector3d torque_Fo_W = Eigen::Vector3d::Zero();
  /// Centre of pressure in W [m] (normal-impulse-weighted mean of the contact points);
  /// the foot frame origin when not in contact.
  Eigen::Vector3d cop_W = Eigen::Vector3d::Zero();
  Eigen::Isometry3d X_WF = Eigen::Isometry3d::Identity();  ///< foot frame pose
  Eigen::Vector3d v_WF = Eigen::Vector3d::Zero();          ///< foot frame origin velocity in W
};

/// Simulator ground truth: published on its own topic, for tests and the recorder.
struct GroundTruth {
  std::int64_t tick = 0;
  double time = 0.0;
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();  ///< base (URDF root link) pose
  Eigen::Vector3d v_WB = Eigen::Vector3d::Zero();          ///< base origin velocity, in W [m/s]
  Eigen::Vector3d omega_WB = Eigen::Vector3d::Zero();      ///< base angular velocity, in W [rad/s]
  Eigen::Vector3d com_W = Eigen::Vector3d::Zero();         ///< whole-body centre of mass [m]
  Eigen::Vector3d com_vel_W = Eigen::Vector3d::Zero();     ///< its velocity [m/s]
  /// The centre of mass the robot's description (the URDF the nodes get) puts at this
  /// configuration, minus com_W: zero unless a scenario's `reality:` section changes the
  /// masses [m].
  Eigen::Vector3d model_com_shift_W = Eigen::Vector3d::Zero();
  std::vector<FootContactTruth> feet;  ///< one per foot
  /// Per simulated body (order of Simulator::body_names()): 1 when a body that is not a foot
  /// touches the environment this tick.
  std::vector<std::uint8_t> non_foot_contact;
  int num_non_foot_contacts = 0;  ///< number of bodies flagged in non_foot_contact
  /// Sum of every contact force the environment exerts on the robot (feet and others) [N].
  Eigen::Vector3d total_contact_force_W = Eigen::Vector3d::Zero();
  /// Pose of each platform's top-face centre (order of WorldConfig::platforms).
  std::vector<Eigen::Isometry3d> platform_X_WP;
  /// Sum of the pushes applied during the step that led to this tick (0 when none) [N].
  Eigen::Vector3d push_force_W = Eigen::Vector3d::Zero();
};

/// Result of one simulation step. A step never throws.
enum class StepStatus : std::uint8_t {
  kOk = 0,
  kRejectedCommand = 1,  ///< wrong size, tick or non-finite value: joints were damped instead
};

/// Constraint rows of the contact solver in one step (diagnostics).
/// Where the steps' wall time went, summed since the simulator was made (or reset_step_times()):
/// Bullet's stepSimulation (collision detection, constraint solver, integration), the sensor
/// models with the ground truth (forward kinematics, IMU, encoders, F/T, contact summary), and
/// the rest (command checks, actuator models, pushes, platforms, joint limits). For benchmarks.
struct StepTimes {
  std::int64_t steps = 0;
  std::int64_t bullet_ns = 0;
  std::int64_t sensors_ns = 0;
  std::int64_t other_ns = 0;
};

struct SolverRows {
  int contact_normal = 0;    ///< one per contact point
  int contact_friction = 0;  ///< two per contact point (two friction directions)
  int other = 0;             ///< joint limits, joint-friction motors, torsional friction
};

}  // namespace poise::sim
