#pragma once
// Plain data of the estimator: its input (one sensor frame), its output (the state, mirroring
// idl/state.idl) and its status bits. No DDS: the estimator node converts poise::msg samples to
// and from these types. Every vector is sized once (Estimator::make_*) and written in place.
//
// Conventions (the same as idl/common.idl): world W is z up, x forward, gravity (0, 0, -9.81).
// Joint-space vectors are in MODEL joint order (poise::model::Model::joint_names). Feet are indexed
// by poise::model::Side: 0 = right, 1 = left.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>

#include "poise/model/spatial.hpp"

namespace poise::estimator {

using model::Force;
using model::Matrix3;
using model::Motion;
using model::SE3;
using model::Vector3;

inline constexpr int kNumFeet = 2;

/// Bits of EstimatorState::status_flags. Values are those of the STATE_* constants of
/// idl/state.idl (the node copies the word unchanged). 0 = all good.
enum StatusFlag : std::uint32_t {
  kStateOk = 0,
  kDroppedFrames = 1,   ///< sensor ticks were missed (or arrived out of order) before this one
  kImuFrozen = 2,       ///< IMU samples did not change for too long: kinematics-only fallback
  kNonFiniteInput = 4,  ///< a sensor field was NaN/Inf or had a wrong size: frame rejected,
                        ///< previous state held
  kNoContact = 8,       ///< no foot in contact: position/velocity only propagated by the IMU
  kInitializing = 16,   ///< filter (re)initialised recently, not converged yet
  kGroundTruth = 32,    ///< debug only: copied from ground truth (never set by this library)
};
using StatusFlags = std::uint32_t;

/// What the plan says of a foot (the balance reference's FootMode, idl/balance_reference.idl):
/// the contact detector's prior. kNone: no plan (FOOT_AUTO, or no planner at all).
enum class FootPlan : std::uint8_t {
  kNone = 0,     ///< FOOT_AUTO or no reference: contact from the sensors alone
  kSupport = 1,  ///< FOOT_SUPPORT: planned to stand (not used as evidence: a push may lift it)
  kSwing = 2,    ///< FOOT_SWING: planned to leave the ground (a light load ends the contact)
};

/// The plan of a FootMode value (0 FOOT_AUTO, 1 FOOT_SUPPORT, 2 FOOT_SWING, as in the IDL and
/// poise::controller::FootMode); any other value: kNone.
constexpr FootPlan foot_plan_of_mode(int mode) noexcept {
  return mode == 1 ? FootPlan::kSupport : mode == 2 ? FootPlan::kSwing : FootPlan::kNone;
}

/// One sensor frame (robot -> estimator), the content of poise::msg::Sensors.
struct SensorFrame {
  std::int64_t tick = 0;         ///< sensor tick k
  std::int64_t stamp_ns = 0;     ///< robot time of the frame [ns]
  Eigen::VectorXd q;             ///< joint positions [rad | m] (dim n = model.njoints)
  Eigen::VectorXd qd;            ///< joint velocities [rad/s | m/s] (dim n)
  Eigen::VectorXd tau_measured;  ///< measured joint torques [N m | N] (dim n); checked, unused
  /// Orientation of the IMU frame I in W as the IMU's own filter reports it. Used only to
  /// initialise the filter's orientation and by the leg-odometry baseline.
  Eigen::Quaterniond imu_q_WI = Eigen::Quaterniond::Identity();
  Vector3 imu_omega_I = Vector3::Zero();           ///< gyroscope, I axes [rad/s]
  Vector3 imu_specific_force_I = Vector3::Zero();  ///< accelerometer a - g, I axes [m/s^2]
  /// Per foot: wrench the ground exerts on the foot, at the foot frame origin Fo, foot axes F,
  /// ordered [force (3); torque (3)] (poise::model Force convention).
  std::array<Force, kNumFeet> foot_wrench_Fo_F{Force::Zero(), Force::Zero()};
  /// Per foot: the planned mode in force at this tick (not a sensor: the node takes it from
  /// poise/balance_reference, the in-process loop from its reference). kNone when no plan.
  std::array<FootPlan, kNumFeet> foot_plan{FootPlan::kNone, FootPlan::kNone};
};

/// Estimated state of one foot (idl FootState).
struct FootEstimate {
  bool in_contact = false;          ///< contact from the foot F/T, with hysteresis
  SE3 X_WF;                         ///< pose of the foot frame F in W
  Motion V_WF = Motion::Zero();     ///< [velocity of the F origin; angular velocity], W axes
  Vector3 cop_W = Vector3::Zero();  ///< measured CoP on the sole plane, W [m] (0: no contact)
  double normal_force = 0.0;        ///< force along the foot normal (F z axis) [N]
};

/// Output of one estimator tick (idl State).
struct EstimatorState {
  std::int64_t tick = 0;      ///< tick of the sensor frame this state answers
  std::int64_t stamp_ns = 0;  ///< its robot time [ns]
  StatusFlags status_flags = kInitializing;
  SE3 X_WB;                            ///< base (URDF root link) pose in W
  Vector3 v_WB = Vector3::Zero();      ///< velocity of the base origin, W axes [m/s]
  Vector3 omega_WB = Vector3::Zero();  ///< base angular velocity, W axes [rad/s]
  Eigen::VectorXd q;                   ///< joint positions (dim n), from the encoders
  Eigen::VectorXd qd;                  ///< joint velocities (dim n)
  /// The same state as model coordinates (see poise/model/model.hpp): q_model (dim nq) and
  /// v_model (dim nv, base twist in base axes), ready for the dynamics library.
  Eigen::VectorXd q_model;
  Eigen::VectorXd v_model;
  Vector3 com_W = Vector3::Zero();           ///< centre of mass [m]
  Vector3 com_velocity_W = Vector3::Zero();  ///< [m/s]
  Vector3 k_W = Vector3::Zero();  ///< centroidal angular momentum about the CoM, W axes [N m s]
  Vector3 l_W = Vector3::Zero();  ///< linear momentum, W axes [kg m/s]
  std::array<FootEstimate, kNumFeet> feet;
  Vector3 gyro_bias_I = Vector3::Zero();   ///< estimated gyro bias, I axes [rad/s]
  Vector3 accel_bias_I = Vector3::Zero();  ///< estimated accelerometer bias, I axes [m/s^2]
};

/// Counters for the node's diagnostics topic (since construction or reset()).
struct EstimatorDiagnostics {
  std::uint64_t ticks = 0;             ///< frames handled (accepted or not)
  std::uint64_t dropped_frames = 0;    ///< sensor ticks missing between accepted frames
  std::uint64_t rejected_frames = 0;   ///< frames refused: non-finite, wrong size, out of order
  std::uint64_t frozen_imu_ticks = 0;  ///< ticks run in the IMU-frozen fallback
  std::uint64_t no_contact_ticks = 0;  ///< ticks with no foot in contact
  std::uint64_t resets = 0;            ///< filter (re)initialisations
  /// kTranslating: foot-orientation measurements refused by the chi2 gate (the foot turned)
  std::uint64_t orientation_rejections = 0;
  /// Ticks on feet whose published angular velocity was the gyro alone because the gyro and the
  /// stance kinematics disagreed (a foot turning; EstimatorConfig::stance_rate_gate)
  std::uint64_t stance_rate_gated_ticks = 0;
  /// Static text naming the newest problem ("" when none): which field was bad, etc.
  const char* last_error = "";
};

}  // namespace poise::estimator
