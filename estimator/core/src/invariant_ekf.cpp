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
//   xi_d' =           - [d]x R zeta_g                   + [d]x R w_g - R w_d
// (R, v, p, d of the estimate). Measurement: with s = R^T (d - p) (true state),
//   z = R_hat s - d_hat + p_hat = eta_R (d - p) - d_hat + p_hat = xi_p - xi_d   exactly.

InvariantEkf::InvariantEkf(const ImuNoise& noise, const Vector3& gravity_W)
    : noise_(noise), g_(gravity_W) {
  const double values[] = {
      noise.gyro,      noise.accel,    noise.gyro_bias_walk, noise.accel_bias_walk,
      noise.foot_slip, noise.position, noise.kinematics};
  for (double v : values) {
    if (!std::isfinite(v) || v < 0.0)
      throw std::invalid_argument("InvariantEkf: noise densities must be finite and >= 0");
  }
  if (!(noise.kinematics > 0.0))
    throw std::invalid_argument("InvariantEkf: kinematics noise must be > 0");
  if (!gravity_W.allFinite()) throw std::invalid_argument("InvariantEkf: gravity is not finite");
}

void InvariantEkf::reset(const Mean& mean, const Covariance& P) noexcept {
  mean_ = mean;
  P_ = 0.5 * (P + P.transpose());
  contact_ = {false, false};
}

void InvariantEkf::propagate_mean(const Vector3& gyro_I, const Vector3& specific_force_I, double dt,
                                  const Vector3& gravity_W, Mean& m) noexcept {
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
  m.R_WI = m.R_WI * so3_exp(phi);
  // Keep R orthonormal against round-off (cheap: one Gram-Schmidt-like pass via quaternion).
  m.R_WI = Eigen::Quaterniond(m.R_WI).normalized().toRotationMatrix();
}

InvariantEkf::Covariance InvariantEkf::error_transition(const Mean& m, const Vector3& g,
                                                        double dt) noexcept {
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
  for (int f = 0; f < kNumFeet; ++f) {
    Phi.block<3, 3>(d_index(f), kBg) = -skew(m.d_W[f]) * R * dt;
  }
  return Phi;
}

namespace {

/// out = Phi * M for the error transition of error_transition(): identity plus the blocks
/// (v,R) (p,R) (p,v) and the bias columns. ~5x fewer operations than the dense product.
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
  for (int f = 0; f < kNumFeet; ++f)
    out.block<3, n>(K::d_index(f), 0).noalias() += blk(K::d_index(f), K::kBg) * rows(K::kBg);
}

}  // namespace

void InvariantEkf::propagate(const Vector3& gyro_I, const Vector3& specific_force_I,
                             double dt) noexcept {
  if (!(dt > 0.0)) return;
  const Covariance Phi = error_transition(mean_, g_, dt);

  // Process noise Ad_X Q Ad_X^T dt (state block) and bias random walks.
  Covariance Q = Covariance::Zero();
  Eigen::Matrix<double, 15, 3> S;
  S.block<3, 3>(kR, 0).setIdentity();
  S.block<3, 3>(kV, 0) = skew(mean_.v_WI);
  S.block<3, 3>(kP, 0) = skew(mean_.p_WI);
  for (int f = 0; f < kNumFeet; ++f)
    S.block<3, 3>(d_index(f), 0) = skew(mean_.d_W[f]);
  const double sg2 = noise_.gyro * noise_.gyro;
  Q.topLeftCorner<15, 15>().noalias() = sg2 * S * S.transpose();
  const Matrix3 I3 = Matrix3::Identity();
  Q.block<3, 3>(kV, kV) += noise_.accel * noise_.accel * I3;
  Q.block<3, 3>(kP, kP) += noise_.position * noise_.position * I3;
  for (int f = 0; f < kNumFeet; ++f)
    Q.block<3, 3>(d_index(f), d_index(f)) += noise_.foot_slip * noise_.foot_slip * I3;
  Q.block<3, 3>(kBg, kBg) = noise_.gyro_bias_walk * noise_.gyro_bias_walk * I3;
  Q.block<3, 3>(kBa, kBa) = noise_.accel_bias_walk * noise_.accel_bias_walk * I3;

  propagate_mean(gyro_I, specific_force_I, dt, g_, mean_);

  // Phi P Phi^T = Phi (Phi P)^T (P symmetric), each product using the block sparsity of Phi.
  Covariance PhiP;
  apply_transition(Phi, P_, PhiP);
  const Covariance PhiP_T = PhiP.transpose();
  apply_transition(Phi, PhiP_T, P_);
  P_ += Q * dt;
  P_ = 0.5 * (P_ + P_.transpose()).eval();
}

void InvariantEkf::set_contact(int foot, bool in_contact, const Vector3& s_I) noexcept {
  if (foot < 0 || foot >= kNumFeet) return;
  const int d = d_index(foot);
  if (in_contact && !contact_[foot]) {
    // Augmentation: d = p + R s  =>  xi_d = xi_p + R n (exact, see header).
    mean_.d_W[foot] = mean_.p_WI + mean_.R_WI * s_I;
    P_.block<3, kDim>(d, 0) = P_.block<3, kDim>(kP, 0);
    P_.block<kDim, 3>(0, d) = P_.block<kDim, 3>(0, kP);
    P_.block<3, 3>(d, d) =
        P_.block<3, 3>(kP, kP) + noise_.kinematics * noise_.kinematics * Matrix3::Identity();
  } else if (!in_contact && contact_[foot]) {
    P_.block<3, kDim>(d, 0).setZero();
    P_.block<kDim, 3>(0, d).setZero();
    P_.block<3, 3>(d, d).setIdentity();
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
  for (int f = 0; f < kNumFeet; ++f)
    m.d_W[f] = Re * m.d_W[f] - Jl * dx.segment<3>(d_index(f));
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
  for (int f = 0; f < kNumFeet; ++f)
    xi.segment<3>(K::d_index(f)) = Jinv * (est.d_W[f] - eta_R * truth.d_W[f]);
  xi.segment<3>(K::kBg) = est.b_g - truth.b_g;
  xi.segment<3>(K::kBa) = est.b_a - truth.b_a;
  return xi;
}

}  // namespace poise::estimator
