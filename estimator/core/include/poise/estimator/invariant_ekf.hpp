#pragma once
// Contact-aided right-invariant extended Kalman filter (Hartley, Ghaffari, Eustice, Grizzle,
// "Contact-aided invariant extended Kalman filtering for robot state estimation", IJRR 2020),
// with IMU biases, for a biped (two contact points).
//
// WHY THIS FILTER (and not the quaternion EKF of Bloesch et al. 2012)
// Both fuse IMU propagation with the leg kinematics of stance feet and carry the same unknowns
// (IMU orientation, velocity, position, stance-foot positions, gyro and accelerometer biases).
// The invariant EKF writes the state as one element of the matrix Lie group SE_4(3) and its
// error as eta = X_hat * X^-1 (right-invariant). Then
//  - the leg-kinematics measurement error is EXACTLY linear in the error (z = H xi with a constant
//    H = [0 0 I -I], derived in invariant_ekf.cpp), and the error dynamics do not depend on the
//    estimate except through the bias terms: the filter does not linearise about a wrong
//    estimate, which is what makes the Bloesch EKF inconsistent (it gains spurious information on
//    yaw) and slow to converge from a bad initial guess;
//  - the yaw and absolute-position unobservability is kept by construction (no false
//    confidence), so the reported covariance stays meaningful over long runs;
//  - the price is the same as the Bloesch EKF: a 21-dimensional error state. Everything is
//    fixed-size (Eigen::Matrix<double, 21, 21>), so one tick is a few microseconds.
// The biases break exact invariance ("imperfect IEKF", Hartley Sec. 5.4): they are carried in a
// separate vector with a linearised error zeta = b_hat - b, as in the paper.
//
// STATE (I = IMU frame, W = world)
//   R_WI (3x3), v_WI (velocity of the IMU origin, W), p_WI (position of the IMU origin, W),
//   d_W[f] (position of foot f's contact point in W; f = 0 right, 1 left), b_g, b_a (IMU axes).
// ERROR  xi (dim 21) = [xi_R, xi_v, xi_p, xi_d0, xi_d1, zeta_g, zeta_a] with
//   exp(xi[0:15]) = X_hat X^-1 on SE_4(3), i.e. R_hat R^T = Exp(xi_R),
//   x_hat - R_hat R^T x = J_l(xi_R) xi_x for x in {v, p, d}; zeta = b_hat - b.
// PROCESS  gyro = omega + b_g + w_g, accel = R^T (a - g) + b_a + w_a, d_dot = R w_d (foot slip),
//   b_dot = w_b. The w are white with the continuous densities of ImuNoise.
// MEASUREMENT  s_f = R^T (d_f - p) + n (foot contact point in IMU coordinates, from forward
//   kinematics of the joint encoders), used while foot f is in contact.
// Units: SI. A foot out of contact has no measurement; when it touches down its contact point is
// added at p_hat + R_hat s (covariance "augmentation" of Hartley Sec. 6).
//
// Yaw and absolute position are unobservable (only drift-bounded by the gyro); roll, pitch,
// velocity, biases (except the accelerometer bias component that mimics tilt while standing
// still) are observable with a foot in contact.

#include <Eigen/Core>
#include <array>
#include <limits>

#include "poise/estimator/types.hpp"

namespace poise::estimator {

/// Noise densities of the process and the measurement (continuous time for the process).
struct ImuNoise {
  // Defaults: a mid-range MEMS IMU (per-sample std at 1 kHz: 0.0095 rad/s, 0.063 m/s^2).
  double gyro = 3e-4;             ///< gyro white noise density [rad/s/sqrt(Hz)]
  double accel = 2e-3;            ///< accelerometer white noise density [m/s^2/sqrt(Hz)]
  double gyro_bias_walk = 1e-4;   ///< gyro bias random walk [rad/s^2/sqrt(Hz)]
  double accel_bias_walk = 1e-3;  ///< accelerometer bias random walk [m/s^3/sqrt(Hz)]
  double foot_slip = 1e-3;        ///< velocity noise of a stance contact point [m/s/sqrt(Hz)]
  double position = 0.0;          ///< extra IMU position process noise [m/s/sqrt(Hz)]
  double kinematics = 3e-3;       ///< std of the leg-kinematics contact position [m]
};

class InvariantEkf {
 public:
  static constexpr int kDim = 21;
  static constexpr int kR = 0, kV = 3, kP = 6, kD = 9, kBg = 15, kBa = 18;
  static constexpr int d_index(int foot) { return kD + 3 * foot; }
  using Covariance = Eigen::Matrix<double, kDim, kDim>;
  using ErrorVector = Eigen::Matrix<double, kDim, 1>;

  struct Mean {
    Matrix3 R_WI = Matrix3::Identity();
    Vector3 v_WI = Vector3::Zero();
    Vector3 p_WI = Vector3::Zero();
    std::array<Vector3, kNumFeet> d_W{Vector3::Zero(), Vector3::Zero()};
    Vector3 b_g = Vector3::Zero();  ///< gyro bias, I axes
    Vector3 b_a = Vector3::Zero();  ///< accelerometer bias, I axes
  };

  InvariantEkf() = default;
  /// Throws std::invalid_argument when a density is negative or non-finite, or kinematics <= 0.
  InvariantEkf(const ImuNoise& noise, const Vector3& gravity_W);

  /// Sets mean and covariance; every foot is marked out of contact.
  void reset(const Mean& mean, const Covariance& P) noexcept;

  /// Propagates mean and covariance over dt with the IMU sample (held constant over dt).
  void propagate(const Vector3& gyro_I, const Vector3& specific_force_I, double dt) noexcept;

  /// Declares foot `foot` in contact with its contact point measured at s_I (IMU coordinates).
  /// At touch-down (false -> true) the contact point is added to the state; while in contact
  /// nothing happens (call correct()). true -> false removes it from the state.
  void set_contact(int foot, bool in_contact, const Vector3& s_I) noexcept;
  bool in_contact(int foot) const noexcept { return contact_[foot]; }

  /// Leg-kinematics correction with foot `foot`'s contact point s_I (IMU coordinates). No-op when
  /// the foot is not in contact. Returns the squared Mahalanobis norm of the innovation (chi2,
  /// 3 dof) for monitoring.
  double correct(int foot, const Vector3& s_I) noexcept;
  /// Orientation correction with a measured IMU orientation R_WI (isotropic std, rad): used on
  /// supports that translate without rotating (a stance foot keeps its orientation in W). Returns
  /// chi2 (3 dof); applied only when chi2 <= max_chi2; no-op for std <= 0 or a non-finite
  /// measurement.
  double correct_orientation(const Matrix3& R_WI_measured, double std_rad,
                             double max_chi2 = std::numeric_limits<double>::infinity()) noexcept;

  /// Replaces R, v, p of the mean (keeps biases, covariance, contact points relative to the IMU):
  /// used by the kinematics-only fallback.
  void set_pose_velocity(const Matrix3& R_WI, const Vector3& v_WI, const Vector3& p_WI) noexcept;

  const Mean& mean() const noexcept { return mean_; }
  const Covariance& covariance() const noexcept { return P_; }
  const ImuNoise& noise() const noexcept { return noise_; }
  /// Replaces the bias estimates with calibrated values of the given standard deviations (the
  /// bias block of the covariance becomes diagonal, its cross-covariances zero).
  void set_biases(const Vector3& b_g, const Vector3& b_a, double std_g, double std_a) noexcept;
  /// Changes the velocity noise density of the stance contact points (noise().foot_slip), from
  /// the next propagation on (the estimator's switch to free contact points on moving supports).
  void set_foot_slip(double density) noexcept { noise_.foot_slip = density; }
  const Vector3& gravity() const noexcept { return g_; }

  /// Linearised error transition Phi (kDim x kDim) for a step of dt from the mean `m` with the
  /// IMU sample (exposed for tests: checked against the nonlinear propagation).
  static Covariance error_transition(const Mean& m, const Vector3& gravity_W, double dt) noexcept;
  /// Applies a correction: X <- exp(-dx[0:15]) X (SE_4(3)), b <- b - dx[15:21].
  static void apply_correction(const ErrorVector& dx, Mean& m) noexcept;
  /// Propagates a mean (no covariance), the same discretisation as propagate().
  static void propagate_mean(const Vector3& gyro_I, const Vector3& specific_force_I, double dt,
                             const Vector3& gravity_W, Mean& m) noexcept;

 private:
  /// Kalman update with a 3-dim measurement: P H^T, S = H P H^T + R, innovation z.
  double update(const Eigen::Matrix<double, kDim, 3>& PHt, Matrix3 S, const Vector3& z,
                double max_chi2 = std::numeric_limits<double>::infinity()) noexcept;

  ImuNoise noise_{};
  Vector3 g_{0.0, 0.0, -9.81};
  Mean mean_{};
  Covariance P_ = Covariance::Identity();
  std::array<bool, kNumFeet> contact_{false, false};
};

/// Right-invariant error of `estimate` relative to `truth` (dim 21): the xi with
/// exp(xi[0:15]) = X_est X_true^-1 and zeta = b_est - b_true (tests, consistency checks).
InvariantEkf::ErrorVector invariant_error(const InvariantEkf::Mean& estimate,
                                          const InvariantEkf::Mean& truth) noexcept;

}  // namespace poise::estimator
