// The invariant EKF on its own, against independent references: finite differences of the
// nonlinear propagation (error transition), the exact linearity of the contact measurement, and
// convergence plus consistency on an analytic trajectory with seeded noise.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "poise/estimator/invariant_ekf.hpp"

namespace poise::estimator {
namespace {

using Ekf = InvariantEkf;

Vector3 random_vec(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return Vector3(u(rng), u(rng), u(rng));
}

Ekf::Mean random_mean(std::mt19937& rng) {
  Ekf::Mean m;
  m.R_WI = model::so3_exp(random_vec(rng, 2.0));
  m.v_WI = random_vec(rng, 1.0);
  m.p_WI = random_vec(rng, 1.0);
  m.d_W[0] = random_vec(rng, 1.0);
  m.d_W[1] = random_vec(rng, 1.0);
  m.b_g = random_vec(rng, 0.05);
  m.b_a = random_vec(rng, 0.2);
  return m;
}

const Vector3 kGravity(0.0, 0.0, -9.81);

TEST(InvariantEkf, ErrorTransitionMatchesNonlinearPropagation) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    const Ekf::Mean est = random_mean(rng);
    const Vector3 gyro = random_vec(rng, 2.0);
    const Vector3 acc = random_vec(rng, 5.0) + Vector3(0, 0, 9.81);
    const double dt = trial % 2 ? 1e-3 : 4e-3;
    Ekf::ErrorVector xi;
    for (int i = 0; i < Ekf::kDim; ++i)
      xi[i] = std::uniform_real_distribution<double>(-1, 1)(rng);
    xi *= 1e-6;
    Ekf::Mean truth = est;
    Ekf::apply_correction(xi, truth);  // truth = exp(-xi) * est, b = b_est - zeta
    // Sanity of the error definition: invariant_error recovers xi.
    ASSERT_LT((invariant_error(est, truth) - xi).norm(), 1e-12);

    Ekf::Mean est1 = est, truth1 = truth;
    Ekf::propagate_mean(gyro, acc, dt, kGravity, est1);
    Ekf::propagate_mean(gyro, acc, dt, kGravity, truth1);
    const Ekf::ErrorVector xi1 = invariant_error(est1, truth1);
    const Ekf::Covariance Phi = Ekf::error_transition(est, kGravity, dt);
    // Change of the error over the step: the linearisation must predict it up to O(dt^2) terms
    // the continuous-time Phi neglects (relative 5 %, errors are 1e-6: second order is 1e-12).
    const Ekf::ErrorVector change = xi1 - xi;
    const Ekf::ErrorVector predicted = Phi * xi - xi;
    EXPECT_LT((change - predicted).norm(), 0.05 * change.norm() + 1e-11) << "trial " << trial;
  }
}

TEST(InvariantEkf, CovariancePropagationIsPhiPPhiTPlusNoise) {
  // The block-sparse products of propagate() against the dense formula with the same Phi and the
  // process noise built densely from its definition G Qc G^T dt, G = blockdiag(Ad_X, I).
  std::mt19937 rng(15);
  ImuNoise noise;
  noise.position = 1e-3;
  for (int trial = 0; trial < 5; ++trial) {
    Ekf ekf(noise, kGravity);
    const Ekf::Mean m = random_mean(rng);
    Eigen::Matrix<double, Ekf::kDim, Ekf::kDim> A;
    for (int i = 0; i < A.size(); ++i)
      A(i) = std::uniform_real_distribution<double>(-0.1, 0.1)(rng);
    const Ekf::Covariance P0 = A * A.transpose();
    ekf.reset(m, P0);
    const double dt = 2e-3;
    const Ekf::Covariance Phi = Ekf::error_transition(m, kGravity, dt);
    // Ad_X of SE_4(3): rows [R; v^R; p^R; d0^R; d1^R] in the first block column, R on the diagonal.
    Ekf::Covariance G = Ekf::Covariance::Identity();
    const Matrix3& R = m.R_WI;
    const std::array<Vector3, 4> x{m.v_WI, m.p_WI, m.d_W[0], m.d_W[1]};
    G.block<3, 3>(0, 0) = R;
    for (int i = 0; i < 4; ++i) {
      G.block<3, 3>(3 + 3 * i, 0) = model::skew(x[i]) * R;
      G.block<3, 3>(3 + 3 * i, 3 + 3 * i) = R;
    }
    Ekf::ErrorVector qc;
    qc << Vector3::Constant(noise.gyro * noise.gyro), Vector3::Constant(noise.accel * noise.accel),
        Vector3::Constant(noise.position * noise.position),
        Vector3::Constant(noise.foot_slip * noise.foot_slip),
        Vector3::Constant(noise.foot_slip * noise.foot_slip),
        Vector3::Constant(noise.gyro_bias_walk * noise.gyro_bias_walk),
        Vector3::Constant(noise.accel_bias_walk * noise.accel_bias_walk);
    const Ekf::Covariance expected =
        Phi * P0 * Phi.transpose() + G * qc.asDiagonal() * G.transpose() * dt;
    ekf.propagate(random_vec(rng, 1.0), random_vec(rng, 10.0), dt);
    EXPECT_LT((ekf.covariance() - expected).norm(), 1e-12 * expected.norm());
  }
}

TEST(InvariantEkf, ContactMeasurementIsExactlyLinearInTheInvariantError) {
  // z = R_hat s - d_hat + p_hat = J_l(xi_R) (xi_p - xi_d) for ANY error size (no linearisation).
  std::mt19937 rng(12);
  for (int trial = 0; trial < 20; ++trial) {
    const Ekf::Mean est = random_mean(rng);
    const Ekf::Mean truth = random_mean(rng);
    const Ekf::ErrorVector xi = invariant_error(est, truth);
    for (int f = 0; f < 2; ++f) {
      const Vector3 s = truth.R_WI.transpose() * (truth.d_W[f] - truth.p_WI);
      const Vector3 z = est.R_WI * s - est.d_W[f] + est.p_WI;
      const Vector3 expected = model::so3_left_jacobian(xi.segment<3>(Ekf::kR)) *
                               (xi.segment<3>(Ekf::kP) - xi.segment<3>(Ekf::d_index(f)));
      EXPECT_LT((z - expected).norm(), 1e-10);
    }
  }
}

TEST(InvariantEkf, CorrectionEqualsTextbookKalmanUpdateWithDenseH) {
  // The block-sparse update of correct() against a dense textbook Kalman update with the
  // explicit H = [0 0 I (p) -I (d_f) 0] and the SE_4(3) correction exp(-dx) X.
  std::mt19937 rng(13);
  ImuNoise noise;
  noise.kinematics = 3e-3;
  for (int trial = 0; trial < 10; ++trial) {
    Ekf ekf(noise, kGravity);
    const Ekf::Mean est = random_mean(rng);
    Eigen::Matrix<double, Ekf::kDim, Ekf::kDim> A;
    for (int i = 0; i < A.size(); ++i)
      A(i) = std::uniform_real_distribution<double>(-0.1, 0.1)(rng);
    const Ekf::Covariance P0 = A * A.transpose() + 1e-3 * Ekf::Covariance::Identity();
    ekf.reset(est, P0);
    const int f = trial % 2;
    ekf.set_contact(f, true, random_vec(rng, 0.5));
    const Ekf::Mean before = ekf.mean();
    const Ekf::Covariance P = ekf.covariance();
    const Vector3 s = random_vec(rng, 0.5);

    Eigen::Matrix<double, 3, Ekf::kDim> H = Eigen::Matrix<double, 3, Ekf::kDim>::Zero();
    H.block<3, 3>(0, Ekf::kP).setIdentity();
    H.block<3, 3>(0, Ekf::d_index(f)) = -Matrix3::Identity();
    const Matrix3 S =
        H * P * H.transpose() + noise.kinematics * noise.kinematics * Matrix3::Identity();
    const Eigen::Matrix<double, Ekf::kDim, 3> K = P * H.transpose() * S.inverse();
    const Vector3 z = before.R_WI * s - before.d_W[f] + before.p_WI;
    const Ekf::ErrorVector dx = K * z;
    const Ekf::Covariance P_expected = (Ekf::Covariance::Identity() - K * H) * P;
    Ekf::Mean expected = before;
    Ekf::apply_correction(dx, expected);

    const double chi2 = ekf.correct(f, s);
    EXPECT_NEAR(chi2, z.dot(S.inverse() * z), 1e-9 * (1 + chi2));
    EXPECT_LT((ekf.covariance() - P_expected).norm(), 1e-10);
    EXPECT_LT(invariant_error(ekf.mean(), expected).norm(), 1e-10);
    // And the dense formula on the SE_4(3) exponential by hand for the rotation.
    EXPECT_LT((ekf.mean().R_WI - model::so3_exp(-dx.segment<3>(Ekf::kR)) * before.R_WI).norm(),
              1e-12);
  }
}

TEST(InvariantEkf, TouchDownAugmentsTheContactPointFromThePosition) {
  std::mt19937 rng(14);
  Ekf ekf(ImuNoise{}, kGravity);
  const Ekf::Mean est = random_mean(rng);
  Eigen::Matrix<double, Ekf::kDim, Ekf::kDim> A;
  for (int i = 0; i < A.size(); ++i)
    A(i) = std::uniform_real_distribution<double>(-0.1, 0.1)(rng);
  ekf.reset(est, A * A.transpose());
  const Vector3 s = random_vec(rng, 0.5);
  ekf.set_contact(1, true, s);
  EXPECT_LT((ekf.mean().d_W[1] - (est.p_WI + est.R_WI * s)).norm(), 1e-14);
  const auto& P = ekf.covariance();
  const int d = Ekf::d_index(1);
  // Cross-covariances of d equal those of p; its variance is p's plus the kinematics noise.
  for (int j = 0; j < Ekf::kDim; ++j) {
    if (j >= d && j < d + 3) continue;
    EXPECT_LT((P.block<3, 1>(d, j) - P.block<3, 1>(Ekf::kP, j)).norm(), 1e-15);
  }
  const double k2 = ImuNoise{}.kinematics * ImuNoise{}.kinematics;
  EXPECT_LT(
      (P.block<3, 3>(d, d) - P.block<3, 3>(Ekf::kP, Ekf::kP) - k2 * Matrix3::Identity()).norm(),
      1e-15);
  // Lift-off decouples it again.
  ekf.set_contact(1, false, s);
  EXPECT_FALSE(ekf.in_contact(1));
  EXPECT_EQ((ekf.covariance().block<3, 3>(d, Ekf::kP).norm()), 0.0);
}

/// Analytic motion: IMU position and body rates are sums of sinusoids; R is integrated finely.
struct Trajectory {
  static Vector3 p(double t) {
    return Vector3(0.05 * std::sin(2 * M_PI * 0.5 * t), 0.03 * std::sin(2 * M_PI * 0.7 * t + 1.0),
                   0.9 + 0.02 * std::sin(2 * M_PI * 1.1 * t));
  }
  static Vector3 v(double t) {
    return Vector3(0.05 * 2 * M_PI * 0.5 * std::cos(2 * M_PI * 0.5 * t),
                   0.03 * 2 * M_PI * 0.7 * std::cos(2 * M_PI * 0.7 * t + 1.0),
                   0.02 * 2 * M_PI * 1.1 * std::cos(2 * M_PI * 1.1 * t));
  }
  static Vector3 a(double t) {
    const auto w = [](double f) { return 2 * M_PI * f; };
    return Vector3(-0.05 * w(0.5) * w(0.5) * std::sin(w(0.5) * t),
                   -0.03 * w(0.7) * w(0.7) * std::sin(w(0.7) * t + 1.0),
                   -0.02 * w(1.1) * w(1.1) * std::sin(w(1.1) * t));
  }
  static Vector3 omega_I(double t) {
    return Vector3(0.3 * std::sin(2 * M_PI * 0.4 * t), 0.4 * std::sin(2 * M_PI * 0.3 * t + 0.5),
                   0.2 * std::sin(2 * M_PI * 0.2 * t + 1.0));
  }
};

struct RunResult {
  double tilt_error_deg_max = 0.0;  ///< roll/pitch error (angle between up axes), second half
  double yaw_error_deg_max = 0.0;   ///< remaining heading error (unobservable), second half
  double velocity_rms = 0.0;        ///< over the second half
  double gyro_bias_error = 0.0;     ///< at the end
  double mean_nees = 0.0;           ///< over the second half
};

/// Runs the filter for `duration` s at 1 kHz on the analytic trajectory with feet fixed at two
/// world points; foot `lift` (if >= 0) is lifted between 2 s and 2.4 s of every 3 s, moved, and
/// put down elsewhere.
RunResult run_trajectory(double duration, int lift, std::uint32_t seed) {
  const double dt = 1e-3;
  const int sub = 20;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const auto noise3 = [&](double s) { return Vector3(s * n01(rng), s * n01(rng), s * n01(rng)); };

  ImuNoise noise;  // defaults; the simulated noise has exactly these densities
  noise.kinematics = 1e-3;
  noise.foot_slip = 1e-3;
  const double gyro_std = noise.gyro / std::sqrt(dt), acc_std = noise.accel / std::sqrt(dt);
  const double kin_std = noise.kinematics;
  const Vector3 b_g(0.01, -0.02, 0.015), b_a(0.05, -0.04, 0.06);

  Ekf::Mean truth;
  truth.R_WI = model::so3_exp(Vector3(0.05, -0.03, 0.2));
  truth.p_WI = Trajectory::p(0);
  truth.v_WI = Trajectory::v(0);
  truth.d_W = {Vector3(0.02, -0.1, 0.0), Vector3(0.0, 0.1, 0.0)};
  truth.b_g = b_g;
  truth.b_a = b_a;

  Ekf ekf(noise, kGravity);
  Ekf::Mean est = truth;
  est.R_WI = model::so3_exp(Vector3(0.03, -0.02, 0.01)) * truth.R_WI;
  est.v_WI += Vector3(0.05, -0.05, 0.02);
  est.p_WI += Vector3(0.01, 0.01, -0.01);
  est.b_g.setZero();
  est.b_a.setZero();
  Ekf::Covariance P = Ekf::Covariance::Zero();
  P.block<3, 3>(Ekf::kR, Ekf::kR) = 0.05 * 0.05 * Matrix3::Identity();
  P.block<3, 3>(Ekf::kV, Ekf::kV) = 0.1 * 0.1 * Matrix3::Identity();
  P.block<3, 3>(Ekf::kP, Ekf::kP) = 0.02 * 0.02 * Matrix3::Identity();
  P.block<6, 6>(Ekf::kD, Ekf::kD).setIdentity();
  P.block<3, 3>(Ekf::kBg, Ekf::kBg) = 0.03 * 0.03 * Matrix3::Identity();
  P.block<3, 3>(Ekf::kBa, Ekf::kBa) = 0.1 * 0.1 * Matrix3::Identity();
  ekf.reset(est, P);
  const auto s_meas = [&](int f) {
    return Vector3(truth.R_WI.transpose() * (truth.d_W[f] - truth.p_WI) + noise3(kin_std));
  };
  for (int f = 0; f < 2; ++f)
    ekf.set_contact(f, true, s_meas(f));

  RunResult r;
  double sq_sum = 0.0, nees_sum = 0.0;
  int count = 0;
  const int steps = static_cast<int>(duration / dt);
  for (int k = 0; k < steps; ++k) {
    const double t0 = k * dt;
    // Truth over [t0, t0 + dt]; the IMU sample is the mid-interval value (sample and hold).
    Matrix3 R_mid = truth.R_WI;
    for (int j = 0; j < sub; ++j) {
      const double h = dt / sub;
      truth.R_WI = truth.R_WI * model::so3_exp(Trajectory::omega_I(t0 + (j + 0.5) * h) * h);
      if (j == sub / 2 - 1) R_mid = truth.R_WI;
    }
    const double tm = t0 + 0.5 * dt, t1 = t0 + dt;
    truth.p_WI = Trajectory::p(t1);
    truth.v_WI = Trajectory::v(t1);
    const Vector3 gyro = Trajectory::omega_I(tm) + b_g + noise3(gyro_std);
    const Vector3 acc = R_mid.transpose() * (Trajectory::a(tm) - kGravity) + b_a + noise3(acc_std);
    ekf.propagate(gyro, acc, dt);

    // Contacts; the lifted foot moves by 5 cm while in the air.
    const double phase = std::fmod(t1, 3.0);
    for (int f = 0; f < 2; ++f) {
      const bool contact = !(f == lift && phase > 2.0 && phase < 2.4);
      if (!contact && ekf.in_contact(f)) truth.d_W[f] += Vector3(0.05, 0.0, 0.0);
      const Vector3 s = s_meas(f);
      ekf.set_contact(f, contact, s);
      if (contact) ekf.correct(f, s);
    }
    // Truth of an out-of-contact foot is meaningless to the filter: copy the estimate.
    Ekf::Mean truth_cmp = truth;
    for (int f = 0; f < 2; ++f)
      if (!ekf.in_contact(f)) truth_cmp.d_W[f] = ekf.mean().d_W[f];
    if (t1 > duration / 2) {
      const Ekf::ErrorVector xi = invariant_error(ekf.mean(), truth_cmp);
      const Vector3 up_est = ekf.mean().R_WI.transpose().col(2);
      const Vector3 up_true = truth.R_WI.transpose().col(2);
      const double tilt = std::atan2(up_est.cross(up_true).norm(), up_est.dot(up_true));
      const double yaw = std::abs(model::so3_log(ekf.mean().R_WI * truth.R_WI.transpose()).z());
      r.tilt_error_deg_max = std::max(r.tilt_error_deg_max, tilt * 180 / M_PI);
      r.yaw_error_deg_max = std::max(r.yaw_error_deg_max, yaw * 180 / M_PI);
      sq_sum += (ekf.mean().v_WI - truth.v_WI).squaredNorm();
      nees_sum += xi.dot(ekf.covariance().ldlt().solve(xi));
      ++count;
    }
    EXPECT_TRUE(ekf.covariance().allFinite());
  }
  r.velocity_rms = std::sqrt(sq_sum / count);
  r.gyro_bias_error = (ekf.mean().b_g - b_g).norm();
  r.mean_nees = nees_sum / count;
  return r;
}

TEST(InvariantEkf, ConvergesOnAnalyticTrajectoryWithNoiseAndBiases) {
  const RunResult r = run_trajectory(12.0, -1, 21);
  std::printf(
      "double support: tilt max %.3f deg, yaw max %.3f deg, velocity RMS %.4f m/s, gyro "
      "bias error %.4f rad/s, mean NEES %.1f (dim 21)\n",
      r.tilt_error_deg_max, r.yaw_error_deg_max, r.velocity_rms, r.gyro_bias_error, r.mean_nees);
  EXPECT_LT(r.tilt_error_deg_max, 0.5);
  // Yaw: unobservable in absolute terms; the initial 0.57 deg heading error stays, plus drift.
  EXPECT_LT(r.yaw_error_deg_max, 3.0);
  EXPECT_LT(r.velocity_rms, 0.02);
  EXPECT_LT(r.gyro_bias_error, 3e-3);
  // Consistency: the normalised estimation error squared averages the state dimension.
  EXPECT_GT(r.mean_nees, 21.0 / 4);
  EXPECT_LT(r.mean_nees, 21.0 * 3);
}

TEST(InvariantEkf, ConvergesWithAFootLiftingAndTouchingDownElsewhere) {
  const RunResult r = run_trajectory(12.0, 1, 22);
  std::printf(
      "foot lifting: tilt max %.3f deg, yaw max %.3f deg, velocity RMS %.4f m/s, gyro bias "
      "error %.4f rad/s, mean NEES %.1f\n",
      r.tilt_error_deg_max, r.yaw_error_deg_max, r.velocity_rms, r.gyro_bias_error, r.mean_nees);
  EXPECT_LT(r.tilt_error_deg_max, 0.5);
  EXPECT_LT(r.velocity_rms, 0.02);
  EXPECT_LT(r.mean_nees, 21.0 * 3);
}

TEST(InvariantEkf, RejectsBadNoise) {
  ImuNoise bad;
  bad.gyro = -1.0;
  EXPECT_THROW(Ekf(bad, kGravity), std::invalid_argument);
  ImuNoise zero_kin;
  zero_kin.kinematics = 0.0;
  EXPECT_THROW(Ekf(zero_kin, kGravity), std::invalid_argument);
  ImuNoise nan_noise;
  nan_noise.accel = std::nan("");
  EXPECT_THROW(Ekf(nan_noise, kGravity), std::invalid_argument);
}

}  // namespace
}  // namespace poise::estimator
