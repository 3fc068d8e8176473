#pragma once
// Configuration of a simulated robot and its world. Plain structs filled by the scenario loader
// (the world of a scenario file: world.hpp, deploy/scenario) or by code; validated once by the Simulator constructor.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "poise/sim/reality.hpp"

namespace poise::sim {

/// Lockstep: how long poise-sim waits for the joint command of a tick by default [ms]
/// (--command-timeout-ms). The launchers give the estimator and the controller the same
/// staleness bound in lockstep (deploy/launch).
inline constexpr int kDefaultCommandTimeoutMs = 2000;

/// Rectangular foot sole, in the foot frame F (x forward, z up). The sole plane is z = -height
/// (paper Fig. 5: h is the height of the foot frame above the sole).
struct SoleConfig {
  double x_min = 0.0, x_max = 0.0;  ///< back / front edge [m]
  double y_min = 0.0, y_max = 0.0;  ///< right / left edge [m]
  double height = 0.0;              ///< foot frame height above the sole [m]
  double thickness = 0.02;          ///< thickness of the collision box above the sole plane [m]
};

/// One foot: the URDF frame (link) that is the foot frame F, and optionally its sole.
struct FootConfig {
  std::string name;   ///< e.g. "left"
  std::string frame;  ///< URDF link name of the foot frame (may be a fixed child of the ankle)
  bool has_sole = false;
  SoleConfig sole;
};

/// A frame that is not a URDF link, fixed to one (robot.yaml soles given as offset + rotation:
/// model::FootConfig::X_link_foot). Feet and the IMU may name it.
struct AddedFrame {
  std::string name;
  std::string link;  ///< URDF link it is fixed to
  Eigen::Isometry3d X_link_frame = Eigen::Isometry3d::Identity();
};

/// Robot side of the simulation.
struct RobotConfig {
  std::string urdf_path;         ///< URDF file (absolute, or relative to the working dir)
  std::vector<FootConfig> feet;  ///< at least one
  std::vector<AddedFrame> added_frames;  ///< frames beside the URDF links (usually none)
  std::string imu_frame;         ///< URDF link name of the IMU frame (default: root link)
  bool self_collision = false;
  /// Damping gain used in damping mode and by the watchdog [N m s/rad] (all joints).
  double damping_mode_kd = 5.0;
  /// The robot's forward direction in its base frame (robot.yaml forward_axis): the verdict's
  /// trunk pitch and roll are taken about the axes it defines (trunk_pitch_roll()).
  Eigen::Vector3d forward_axis = Eigen::Vector3d::UnitX();
};

/// Sinusoid s(t) = amplitude * sin(2 pi frequency t + phase).
struct Sinusoid {
  double amplitude = 0.0;  ///< [m] for translations, [rad] for rotations
  double frequency = 0.0;  ///< [Hz]
  double phase = 0.0;      ///< [rad]
};

/// A box-shaped support under one foot. Its top face centre is the platform origin P.
/// Pose: p_WP(t) = position + axis * e(t) translation(t - motion_start),
///       R_WP(t) = AngleAxis(e(t) rotation(t - motion_start), R_incline rotation_axis) R_incline,
///       R_incline = Rz(yaw) Ry(pitch) Rx(roll),
/// where the envelope e(t) rises smoothly (3s^2 - 2s^3, s = (t - motion_start) / motion_ramp)
/// from 0 at motion_start to 1 after motion_ramp, so the support starts at rest.
struct PlatformConfig {
  std::string name;
  std::string foot;  ///< foot name it supports (used for automatic placement), may be empty
  Eigen::Vector3d half_extents = Eigen::Vector3d(0.25, 0.15, 0.05);  ///< [m]
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< top-centre position at t = 0 [m]
  /// When true, position x, y, z are placed under the foot at the initial posture (the top face
  /// touches the lowest sole corner), after which `position` is an offset added to that.
  bool auto_place = true;
  double roll = 0.0, pitch = 0.0, yaw = 0.0;  ///< inclination [rad] about x, y, z
  double friction = 1.0;                      ///< Coulomb coefficient with the robot
  Eigen::Vector3d translation_axis = Eigen::Vector3d::UnitX();  ///< unit, in W
  Sinusoid translation;
  Eigen::Vector3d rotation_axis = Eigen::Vector3d::UnitY();  ///< unit, in the inclined frame
  Sinusoid rotation;
  double motion_start = 0.0;  ///< [s] the support is still before this time
  double motion_ramp = 0.0;   ///< [s] envelope rise time (0 = full amplitude at once)
};

struct GroundConfig {
  bool enabled = true;
  double height = 0.0;    ///< z of the plane [m]
  double friction = 1.0;  ///< Coulomb coefficient with the robot
};

struct WorldConfig {
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -9.81);  ///< [m/s^2]
  GroundConfig ground;
  std::vector<PlatformConfig> platforms;
};

/// External push: force_W applied at point_L (in the link frame of `link`) during
/// [start, start + duration).
struct Push {
  std::string link;                                   ///< URDF link name
  Eigen::Vector3d point_L = Eigen::Vector3d::Zero();  ///< [m]
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();  ///< [N]
  double start = 0.0;                                 ///< [s]
  double duration = 0.0;                              ///< [s]
};

/// What the IMU reports as its orientation (Sensors.imu.orientation_wxyz on the wire).
enum class ImuOrientationOutput : std::uint8_t {
  kOff = 0,     ///< no orientation output (an IMU without attitude filter): all zeros on the wire
  kFilter = 1,  ///< the IMU's own attitude filter (complementary: its noisy, biased gyro
                ///< integrated, tilt pulled slowly to its accelerometer): yaw drifts, roll and
                ///< pitch carry the accelerometer's errors
  kTruth = 2,   ///< the exact orientation of the IMU frame (tests only; no real IMU does this)
};

/// IMU model (simulator/sim/SENSORS.md). Per axis, at each IMU sample:
///   omega_meas = sat(S_g R_g^T omega_I + b_g + n_g),  f_meas = sat(S_a R_a^T f_I + b_a + n_a)
/// with S = I + diag(scale_error), R = exp(misalignment) the rotation of the sensor triad from
/// the IMU frame I, b = bias (turn-on value, then a random walk), n white noise, sat clamping to
/// +-range. Samples are taken every 1/rate_hz (held between samples) and come out delay_ticks
/// simulator ticks late. The defaults here are the ideal IMU (tests that build a configuration
/// in code); scenario files start from industrial_mems_imu() instead (world.cpp).
struct ImuNoiseConfig {
  double gyro_noise_std = 0.0;      ///< white noise per sample [rad/s] (added to the density's)
  double gyro_noise_density = 0.0;  ///< white noise density [rad/s/sqrt(Hz)]: per-sample std is
                                    ///< density * sqrt(rate / 2)
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();  ///< turn-on bias [rad/s]
  double gyro_bias_walk = 0.0;  ///< bias random walk [rad/s/sqrt(s)]
  Eigen::Vector3d gyro_scale_error = Eigen::Vector3d::Zero();   ///< per axis [-] (0.001 = 0.1 %)
  Eigen::Vector3d gyro_misalignment = Eigen::Vector3d::Zero();  ///< rotation vector [rad]
  double gyro_range = 0.0;  ///< saturation [rad/s] (0 = none)

  double accel_noise_std = 0.0;      ///< [m/s^2] per sample
  double accel_noise_density = 0.0;  ///< [m/s^2/sqrt(Hz)]
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();  ///< [m/s^2]
  double accel_bias_walk = 0.0;                          ///< [m/s^2/sqrt(s)]
  Eigen::Vector3d accel_scale_error = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_misalignment = Eigen::Vector3d::Zero();  ///< [rad]
  double accel_range = 0.0;                                      ///< [m/s^2] (0 = none)

  double rate_hz = 0.0;  ///< IMU sample rate (0 = every simulator step); <= 1 / dt
  int delay_ticks = 0;   ///< output latency in simulator ticks (>= 0)
  ImuOrientationOutput orientation = ImuOrientationOutput::kTruth;
  /// Attitude filter (orientation = filter): accelerometer correction gain [rad/s] (tilt time
  /// constant 1 / gain), used only while | |f| - g | < filter_accel_gate * g.
  double filter_gain = 0.5;
  double filter_accel_gate = 0.1;
  std::uint64_t seed = 1;  ///< seed of every sensor's noise (IMU, encoders, F/T)
};

/// Joint encoders: position quantised to counts_per_rev counts per 2 pi (per metre for a
/// prismatic joint's unit); velocity = difference of consecutive quantised positions / dt.
/// counts_per_rev = 0: exact position and velocity from the simulator. velocity_filter_hz > 0:
/// the differenced velocity goes through a first-order low-pass of that cut-off (as a drive's
/// firmware does), 0 = raw difference.
struct EncoderConfig {
  double counts_per_rev = 0.0;
  double velocity_filter_hz = 0.0;
};

/// Foot force/torque sensors: white noise per sample and a constant offset, in the foot frame.
struct ForceTorqueSensorConfig {
  double force_noise_std = 0.0;   ///< [N]
  double torque_noise_std = 0.0;  ///< [N m]
  Eigen::Vector3d force_offset = Eigen::Vector3d::Zero();   ///< [N]
  Eigen::Vector3d torque_offset = Eigen::Vector3d::Zero();  ///< [N m]
};

/// The defaults of a scenario file without sensors: section: an industrial MEMS IMU with the
/// inertial figures of the ADIS16470 datasheet and an on-board attitude filter, a 17-bit
/// absolute joint encoder, a strain-gauge foot F/T sensor (figures and conversions in
/// simulator/sim/SENSORS.md). Defined in simulator.cpp.
ImuNoiseConfig industrial_mems_imu();
EncoderConfig industrial_encoder();
ForceTorqueSensorConfig industrial_foot_ft();

/// Contact / solver settings. Defaults were measured on the project humanoid (README).
struct SolverConfig {
  double dt = 0.001;            ///< step [s]; one substep per step
  int iterations = 50;          ///< sequential-impulse iterations
  double contact_erp = 0.2;     ///< penetration correction factor
  double contact_cfm = 0.0;     ///< constraint force mixing
  bool friction_anchor = true;  ///< anchor static foot contacts (no slow creep)
  /// Stop iterating once the solver residual is below this (0 = always run all iterations).
  double residual_threshold = 1e-7;
  /// URDF joint friction as exact Coulomb friction (one velocity-motor row per joint in the
  /// contact solver: about doubles the step time of the humanoid) instead of the default smooth
  /// explicit model tau_f = -friction * clamp(qd / joint_friction_velocity, -1, 1).
  bool joint_friction_constraint = false;
  double joint_friction_velocity = 0.01;  ///< [rad/s] or [m/s]
  /// Start each contact's normal impulse from the previous step's (Bullet's articulated warm
  /// starting, scaled by warm_start_factor) instead of from zero: a resting contact then
  /// converges in a few iterations instead of running into the iteration cap.
  bool warm_start = true;
  double warm_start_factor = 0.85;
  /// Broadphase bounding box of the ground plane: infinite below the plane and this far [m]
  /// above it, so a link more than this (plus Bullet's 0.02 m AABB margin) above the ground has
  /// no ground pair at all instead of one that the narrowphase tests every step. The contact
  /// generation itself is unchanged (same plane shape and algorithm; a link this far up gets
  /// no contact point either way). <= 0: infinite box (every link always paired).
  double ground_aabb_band = 0.1;
};

/// Initial state. Unset joints start at 0; the base height is chosen so that the feet rest on
/// the ground (or the lowest sole corner touches z = ground height) when auto_base_height.
struct InitialState {
  Eigen::Vector3d base_position = Eigen::Vector3d(0.0, 0.0, 1.0);  ///< [m]
  Eigen::Vector4d base_orientation_wxyz = Eigen::Vector4d(1.0, 0.0, 0.0, 0.0);
  bool auto_base_height = true;
  double clearance = 0.0;                ///< gap between the lowest sole corner and its support [m]
  std::vector<std::string> joint_names;  ///< joints to set (any order, subset)
  std::vector<double> joint_positions;   ///< same size
  Eigen::Vector3d base_linear_velocity = Eigen::Vector3d::Zero();  ///< in W [m/s]
};

/// Everything the Simulator needs.
struct SimulatorConfig {
  RobotConfig robot;
  WorldConfig world;
  SolverConfig solver;
  ImuNoiseConfig imu;
  EncoderConfig encoders;
  ForceTorqueSensorConfig foot_ft;
  InitialState initial;
  std::vector<Push> pushes;  ///< scheduled pushes (more can be added live)
  int max_live_pushes = 16;  ///< capacity reserved for pushes added while running
  /// How the simulated robot differs from its URDF (reality.hpp); disabled by default.
  RealityConfig reality;
};

}  // namespace poise::sim
