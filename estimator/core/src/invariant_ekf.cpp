#include "poise/estimator/invariant_ekf.hpp"

#include <cmath>
#include <stdexcept>

namespace poise::estimator {

using model::skew;
using model::so3_exp;
using model::so3_left_jacobian;
using model::so3_log;

// Derivation notes (right-invariant error eta = X_hat X^-1, first order xi):
//   eta_R = R_hat R^T = I + [xi_R]x,   eta_x = x_hat - eta_R x = xi_x   (x = v, p, d).
// Error dynamics (Hartley 2020, eq. (37) with biases):
//   xi_R' = -R zeta_g                                 + R w_g
//   xi_v' = [g]x xi_R - [v]x R zeta_g - R zeta_a        + [v]x R w_g + R w_a
//   xi_p' = xi_v      - [p]x R zeta_g                   + [p]x R w_g
//   xi_d' = xi_u      - [d]x R zeta_g                   + [d]x R w_g - w_d
//   xi_u' = -xi_u/tau - [u]x R zeta_g                   + [u]x R w_g - w_u
// (R, v, p, d, u of the estimate; d' = u and u' = -u/tau are linear in the group's columns, so
// they add no estimate-dependent terms). Measurement: with s = R^T (d - p) (true state),
//   z = R_hat s - d_hat + p_hat = eta_R (d - p) - d_hat + p_hat = xi_p - xi_d   exactly.

InvariantEkf::InvariantEkf(const ImuNoise& noise, const Vector3& gravity_W)
    : noise_(noise), g_(gravity_W) {
  const double values[] = {noise.gyro,
                           noise.accel,
                           noise.gyro_bias_walk,
                           noise.accel_bias_walk,
                           noise.foot_slip,
                           noise.position,
                           noise.kinematics,
                           noise.support_velocity_std,
                           noise.support_velocity_diff_std,
                           noise.support_velocity_tau,
                           noise.touchdown_velocity};
  for (double v : values) {
    if (!std::isfinite(v) || v < 0.0)
      throw std::invalid_argument("InvariantEkf: noise densities must be finite and >= 0");
  }
  if (!(noise.kinematics > 0.0))
    throw std::invalid_argument("InvariantEkf: kinematics noise must be > 0");
  if (!(noise.support_velocity_tau > 0.0))
    throw std::invalid_argument("InvariantEkf: support_velocity_tau must be > 0");
  if (!gravity_W.allFinite()) throw std::invalid_argument("InvariantEkf: gravity is not finite");
}

void InvariantEkf::reset(const Mean& mean, const Covariance& P) noexcept {
  mean_ = mean;
  P_ = 0.5 * (P + P.transpose());
  contact_ = {false, false};
}

void InvariantEkf::propagate_mean(const Vector3& gyro_I, const Vector3& specific_force_I, double dt,
                                  const Vector3& gravity_W, double tau, Mean& m) noexcept {
  // Constant body rate and specific force over dt (Hartley 2020, eq. (26)): the specific force
  // turns with the body during the step, Gamma_1 = J_l(w dt), Gamma_2 ~ I/2 + [w dt]x / 6.
  const Vector3 w = gyro_I - m.b_g;
  const Vector3 a_I = specific_force_I - m.b_a;
  const Vector3 phi = w * dt;
  const Vector3 dv = m.R_WI * (so3_left_jacobian(phi) * a_I) * dt + gravity_W * dt;
  const Vector3 dp = m.v_WI * dt + m.R_WI * (0.5 * a_I + phi.cross(a_I) / 6.0) * (dt * dt) +
                     0.5 * dt * dt * gravity_W;
  m.p_WI += dp;
  m.v_WI += dv;
  // Support velocities: exact Ornstein-Uhlenbeck mean, d moves with the integral of u.
  const double decay = std::exp(-dt / tau);
  for (int f = 0; f < kNumFeet; ++f) {
    m.d_W[f] += (tau * (1.0 - decay)) * m.u_W[f];
    m.u_W[f] *= decay;
  }
  m.R_WI = m.R_WI * so3_exp(phi);
  // Keep R orthonormal against round-off (cheap: one Gram-Schmidt-like pass via quaternion).
  m.R_WI = Eigen::Quaterniond(m.R_WI).normalized().toRotationMatrix();
}

InvariantEkf::Covariance InvariantEkf::error_transition(const Mean& m, const Vector3& g, double dt,
                                                        double tau) noexcept {
  // Phi = I + A dt + A^2 dt^2 / 2 (A^3 terms are O(dt^3) and only touch p/bias).
  Covariance Phi = Covariance::Identity();
  const Matrix3 G = skew(g);
  const Matrix3& R = m.R_WI;
  const Matrix3 vxR = skew(m.v_WI) * R;
  const Matrix3 pxR = skew(m.p_WI) * R;
  const double dt2 = 0.5 * dt * dt;
  Phi.block<3, 3>(kV, kR) = G * dt;
  Phi.block<3, 3>(kP, kR) = G * dt2;
  Phi.block<3, 3>(kP, kV) = Matrix3::Identity() * dt;
  Phi.block<3, 3>(kR, kBg) = -R * dt;
  Phi.block<3, 3>(kV, kBg) = -vxR * dt - G * R * dt2;
  Phi.block<3, 3>(kV, kBa) = -R * dt;
  Phi.block<3, 3>(kP, kBg) = -pxR * dt - vxR * dt2;
  Phi.block<3, 3>(kP, kBa) = -R * dt2;
  const double decay = std::exp(-dt / tau);
  for (int f = 0; f < kNumFeet; ++f) {
    const Matrix3 uxR = skew(m.u_W[f]) * R;
    Phi.block<3, 3>(d_index(f), kBg) = -skew(m.d_W[f]) * R * dt - uxR * dt2;
    Phi.block<3, 3>(d_index(f), u_index(f)) = Matrix3::Identity() * (tau * (1.0 - decay));
    Phi.block<3, 3>(u_index(f), u_index(f)) = Matrix3::Identity() * decay;
    Phi.block<3, 3>(u_index(f), kBg) = -uxR * dt;
  }
  return Phi;
}

namespace {

/// out = Phi * M for the error transition of error_transition(): identity plus the blocks
/// (v,R) (p,R) (p,v) (d,u), the scaled (u,u) and the bias columns. ~5x fewer operations than
/// the dense product.
void apply_transition(const InvariantEkf::Covariance& Phi, const InvariantEkf::Covariance& M,
                      InvariantEkf::Covariance& out) noexcept {
  using K = InvariantEkf;
  constexpr int n = K::kDim;
  out = M;
  const auto rows = [&](int i) { return M.block<3, n>(i, 0); };
  const auto blk = [&](int i, int j) { return Phi.block<3, 3>(i, j); };
  out.block<3, n>(K::kR, 0).noalias() += blk(K::kR, K::kBg) * rows(K::kBg);
  out.block<3, n>(K::kV, 0).noalias() += blk(K::kV, K::kR) * rows(K::kR);
  out.block<3, n>(K::kV, 0).noalias() += blk(K::kV, K::kBg) * rows(K::kBg);
  out.block<3, n>(K::kV, 0).noalias() += blk(K::kV, K::kBa) * rows(K::kBa);
  out.block<3, n>(K::kP, 0).noalias() += blk(K::kP, K::kR) * rows(K::kR);
  out.block<3, n>(K::kP, 0).noalias() += blk(K::kP, K::kV) * rows(K::kV);
  out.block<3, n>(K::kP, 0).noalias() += blk(K::kP, K::kBg) * rows(K::kBg);
  out.block<3, n>(K::kP, 0).noalias() += blk(K::kP, K::kBa) * rows(K::kBa);
  for (int f = 0; f < kNumFeet; ++f) {
    const int d = K::d_index(f), u = K::u_index(f);
    out.block<3, n>(d, 0).noalias() += blk(d, K::kBg) * rows(K::kBg);
    out.block<3, n>(d, 0) += Phi(d, u) * rows(u);  // (d,u) and (u,u) are multiples of I
    out.block<3, n>(u, 0) *= Phi(u, u);
    out.block<3, n>(u, 0).noalias() += blk(u, K::kBg) * rows(K::kBg);
  }
}

}  // namespace

void InvariantEkf::propagate(const Vector3& gyro_I, const Vector3& specific_force_I,
                             double dt) noexcept {
  if (!(dt > 0.0)) return;
  const double tau = noise_.support_velocity_tau;
  const Covariance Phi = error_transition(mean_, g_, dt, tau);

  // Process noise Ad_X Q Ad_X^T dt (state block) and bias random walks.
  Covariance Q = Covariance::Zero();
  Eigen::Matrix<double, kGroupDim, 3> S;
  S.block<3, 3>(kR, 0).setIdentity();
  S.block<3, 3>(kV, 0) = skew(mean_.v_WI);
  S.block<3, 3>(kP, 0) = skew(mean_.p_WI);
  for (int f = 0; f < kNumFeet; ++f) {
    S.block<3, 3>(d_index(f), 0) = skew(mean_.d_W[f]);
    S.block<3, 3>(u_index(f), 0) = skew(mean_.u_W[f]);
  }
  const double sg2 = noise_.gyro * noise_.gyro;
  Q.topLeftCorner<kGroupDim, kGroupDim>().noalias() = sg2 * S * S.transpose();
  // Ornstein-Uhlenbeck driving noise: density^2 = 2 sigma^2 / tau, for the common part c and the
  // differential part e of u_0 = c + e, u_1 = c - e (e only while both feet are in contact).
  const double qc = 2.0 * noise_.support_velocity_std * noise_.support_velocity_std / tau;
  // The differential part is horizontal only (in W): vertical differential motion (one support
  // rising while the other sinks) would look exactly like a roll of the robot, and the fixed
  // vertical difference is what keeps the roll gyro bias observable.
  const Matrix3 Eh = Eigen::Vector3d(1.0, 1.0, 0.0).asDiagonal();
  const double qe = contact_[0] && contact_[1] ? 2.0 * noise_.support_velocity_diff_std *
                                                     noise_.support_velocity_diff_std / tau
                                               : 0.0;
  const Matrix3 I3 = Matrix3::Identity();
  Q.block<3, 3>(kV, kV) += noise_.accel * noise_.accel * I3;
  Q.block<3, 3>(kP, kP) += noise_.position * noise_.position * I3;
  for (int f = 0; f < kNumFeet; ++f) {
    Q.block<3, 3>(d_index(f), d_index(f)) += noise_.foot_slip * noise_.foot_slip * I3;
    if (contact_[f]) Q.block<3, 3>(u_index(f), u_index(f)) += qc * I3 + qe * Eh;
  }
  if (contact_[0] && contact_[1]) {
    Q.block<3, 3>(u_index(0), u_index(1)) += qc * I3 - qe * Eh;
    Q.block<3, 3>(u_index(1), u_index(0)) += qc * I3 - qe * Eh;
  }
  Q.block<3, 3>(kBg, kBg) = noise_.gyro_bias_walk * noise_.gyro_bias_walk * I3;
  Q.block<3, 3>(kBa, kBa) = noise_.accel_bias_walk * noise_.accel_bias_walk * I3;

  propagate_mean(gyro_I, specific_force_I, dt, g_, tau, mean_);

  // Phi P Phi^T = Phi (Phi P)^T (P symmetric), each product using the block sparsity of Phi.
  Covariance PhiP;
  apply_transition(Phi, P_, PhiP);
  const Covariance PhiP_T = PhiP.transpose();
  apply_transition(Phi, PhiP_T, P_);
  P_ += Q * dt;
  P_ = 0.5 * (P_ + P_.transpose()).eval();
}

void InvariantEkf::set_contact(int foot, bool in_contact, const Vector3& s_I,
                               const Vector3& sdot_I) noexcept {
  if (foot < 0 || foot >= kNumFeet) return;
  const int d = d_index(foot);
  const int u = u_index(foot);
  const Matrix3 I3 = Matrix3::Identity();
  if (in_contact && !contact_[foot]) {
    // Augmentation: d = p + R s  =>  xi_d = xi_p + R n (exact, see header); likewise
    // u = v + R sdot  =>  xi_u = xi_v + noise (the gyro-bias part of sdot is left to the noise).
    mean_.d_W[foot] = mean_.p_WI + mean_.R_WI * s_I;
    P_.block<3, kDim>(d, 0) = P_.block<3, kDim>(kP, 0);
    P_.block<kDim, 3>(0, d) = P_.block<kDim, 3>(0, kP);
    P_.block<3, 3>(d, d) = P_.block<3, 3>(kP, kP) + noise_.kinematics * noise_.kinematics * I3;
    const int other = 1 - foot;
    if (noise_.support_velocity_std > 0.0) {
      // The supports may move as a whole: the contact point moves as the kinematics say.
      mean_.u_W[foot] = mean_.v_WI + mean_.R_WI * sdot_I;
      P_.block<3, kDim>(u, 0) = P_.block<3, kDim>(kV, 0);
      P_.block<kDim, 3>(0, u) = P_.block<kDim, 3>(0, kV);
      P_.block<3, 3>(u, u) =
          P_.block<3, 3>(kV, kV) + noise_.touchdown_velocity * noise_.touchdown_velocity * I3;
      P_.block<3, 3>(d, u) = P_.block<3, 3>(kP, kV);
      P_.block<3, 3>(u, d) = P_.block<3, 3>(kV, kP);
    } else if (contact_[other] && noise_.support_velocity_diff_std > 0.0) {
      // Only the difference of the support velocities is free: the new contact starts with the
      // other support's velocity, exactly (the common velocity keeps its information); the
      // differential process noise lets them part.
      const int uo = u_index(other);
      mean_.u_W[foot] = mean_.u_W[other];
      P_.block<3, kDim>(u, 0) = P_.block<3, kDim>(uo, 0);
      P_.block<kDim, 3>(0, u) = P_.block<kDim, 3>(0, uo);
      P_.block<3, 3>(u, u) = P_.block<3, 3>(uo, uo);
      P_.block<3, 3>(d, u) = P_.block<3, 3>(kP, uo);
      P_.block<3, 3>(u, d) = P_.block<3, 3>(uo, kP);
    } else {  // a support that cannot move: u = 0 exactly
      mean_.u_W[foot].setZero();
      P_.block<3, kDim>(u, 0).setZero();
      P_.block<kDim, 3>(0, u).setZero();
    }
  } else if (!in_contact && contact_[foot]) {
    for (int x : {d, u}) {
      P_.block<3, kDim>(x, 0).setZero();
      P_.block<kDim, 3>(0, x).setZero();
      P_.block<3, 3>(x, x).setIdentity();
    }
    mean_.u_W[foot].setZero();
  }
  contact_[foot] = in_contact;
}

double InvariantEkf::correct(int foot, const Vector3& s_I) noexcept {
  if (foot < 0 || foot >= kNumFeet || !contact_[foot]) return 0.0;
  const int d = d_index(foot);
  // H = [0 0 I -I(at d) 0]: P H^T = P(:, p) - P(:, d).
  Eigen::Matrix<double, kDim, 3> PHt = P_.block<kDim, 3>(0, kP) - P_.block<kDim, 3>(0, d);
  Matrix3 S = PHt.block<3, 3>(kP, 0) - PHt.block<3, 3>(d, 0);
  S += noise_.kinematics * noise_.kinematics * Matrix3::Identity();
  S = 0.5 * (S + S.transpose()).eval();
  const Eigen::LLT<Matrix3> llt(S);
  if (llt.info() != Eigen::Success) return 0.0;
  const Vector3 z = mean_.R_WI * s_I - mean_.d_W[foot] + mean_.p_WI;
  const Eigen::Matrix<double, 3, kDim> KT = llt.solve(PHt.transpose());  // (P H^T S^-1)^T
  const ErrorVector dx = KT.transpose() * z;
  P_.noalias() -= KT.transpose() * PHt.transpose();
  P_ = 0.5 * (P_ + P_.transpose()).eval();
  apply_correction(dx, mean_);
  return z.dot(llt.solve(z));
}

void InvariantEkf::set_pose_velocity(const Matrix3& R_WI, const Vector3& v_WI,
                                     const Vector3& p_WI) noexcept {
  mean_.R_WI = R_WI;
  mean_.v_WI = v_WI;
  mean_.p_WI = p_WI;
}

void InvariantEkf::apply_correction(const ErrorVector& dx, Mean& m) noexcept {
  // X+ = exp(-dx) X: exp(xi) = (Exp(phi), J_l(phi) xi_x).
  const Vector3 phi = -dx.segment<3>(kR);
  const Matrix3 Re = so3_exp(phi);
  const Matrix3 Jl = so3_left_jacobian(phi);
  m.R_WI = Re * m.R_WI;
  m.v_WI = Re * m.v_WI - Jl * dx.segment<3>(kV);
  m.p_WI = Re * m.p_WI - Jl * dx.segment<3>(kP);
  for (int f = 0; f < kNumFeet; ++f) {
    m.d_W[f] = Re * m.d_W[f] - Jl * dx.segment<3>(d_index(f));
    m.u_W[f] = Re * m.u_W[f] - Jl * dx.segment<3>(u_index(f));
  }
  m.b_g -= dx.segment<3>(kBg);
  m.b_a -= dx.segment<3>(kBa);
}

InvariantEkf::ErrorVector invariant_error(const InvariantEkf::Mean& est,
                                          const InvariantEkf::Mean& truth) noexcept {
  using K = InvariantEkf;
  K::ErrorVector xi;
  const Matrix3 eta_R = est.R_WI * truth.R_WI.transpose();
  const Vector3 phi = so3_log(eta_R);
  const Matrix3 Jinv = so3_left_jacobian(phi).inverse();
  xi.segment<3>(K::kR) = phi;
  xi.segment<3>(K::kV) = Jinv * (est.v_WI - eta_R * truth.v_WI);
  xi.segment<3>(K::kP) = Jinv * (est.p_WI - eta_R * truth.p_WI);
  for (int f = 0; f < kNumFeet; ++f) {
    xi.segment<3>(K::d_index(f)) = Jinv * (est.d_W[f] - eta_R * truth.d_W[f]);
    xi.segment<3>(K::u_index(f)) = Jinv * (est.u_W[f] - eta_R * truth.u_W[f]);
  }
  xi.segment<3>(K::kBg) = est.b_g - truth.b_g;
  xi.segment<3>(K::kBa) = est.b_a - truth.b_a;
  return xi;
}

}  // namespace poise::estimator
