#pragma once
// Plain leg odometry, no filter: the baseline the issue asks to compare the invariant EKF with,
// and the estimator's fallback when the IMU freezes.
//
// Each stance foot is assumed not to move in W. At touch-down its pose X_WF is recorded (the
// "anchor"); afterwards
//   p_WB = mean over stance feet of (p_WF_anchor - R_WB p_BF(q)),
//   v_WB = mean over stance feet of -R_WB v_BF_B,
// with v_BF_B the velocity of the foot origin relative to a base that rotates with the measured
// angular velocity (omega_B x p_BF + J_BF(q) qd), base axes. The orientation comes either from the
// IMU's own orientation output (baseline) or, when the IMU cannot be trusted, from the anchored
// orientation of a stance foot: R_WB = R_WF_anchor R_BF(q)^T. With no foot in contact the base
// is propagated ballistically (gravity only).

#include <array>

#include "poise/estimator/types.hpp"

namespace poise::estimator {

/// Leg kinematics of one tick, base frame B (from forward kinematics with the base at identity).
struct LegKinematics {
  std::array<SE3, kNumFeet> X_BF;  ///< foot frame poses in B
  /// Velocity of each foot origin relative to the base's origin, with the base rotating at the
  /// measured angular velocity and not translating, base axes (3).
  std::array<Vector3, kNumFeet> v_BF_B{Vector3::Zero(), Vector3::Zero()};
  std::array<bool, kNumFeet> contact{false, false};
  std::array<double, kNumFeet> normal_force{0.0, 0.0};  ///< [N] (weights, feet)
};

class LegOdometry {
 public:
  enum class OrientationSource { kImu, kStanceFoot };

  LegOdometry() = default;
  explicit LegOdometry(const Vector3& gravity_W) : g_(gravity_W) {}

  /// Starts from a known base pose and velocity; anchors the feet in contact at the pose.
  void reset(const SE3& X_WB, const Vector3& v_WB, const LegKinematics& legs) noexcept;

  /// One tick. R_WB_imu is used with OrientationSource::kImu; with kStanceFoot it is ignored
  /// while a foot is anchored (and used otherwise if finite).
  void update(OrientationSource source, const Matrix3& R_WB_imu, const LegKinematics& legs,
              double dt) noexcept;

  const SE3& X_WB() const noexcept { return X_WB_; }
  const Vector3& v_WB() const noexcept { return v_WB_; }
  bool anchored(int foot) const noexcept { return anchored_[foot]; }
  const SE3& anchor(int foot) const noexcept { return X_WF_anchor_[foot]; }

 private:
  Vector3 g_{0.0, 0.0, -9.81};
  SE3 X_WB_;
  Vector3 v_WB_ = Vector3::Zero();
  std::array<bool, kNumFeet> anchored_{false, false};
  std::array<SE3, kNumFeet> X_WF_anchor_;
};

}  // namespace poise::estimator
