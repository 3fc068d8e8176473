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

namespace {

using Ekf = InvariantEkf;
constexpr int kN = Ekf::kDim;

/// The nonzero 3x3 blocks of N = Phi - I (error_transition()); N(P, V) = PV * I.
struct TransitionBlocks {
  Matrix3 VR, PR, RBg, VBg, VBa, PBg, PBa;
  std::array<Matrix3, kNumFeet> DBg;
  double PV = 0.0;
};

TransitionBlocks transition_blocks(const Ekf::Mean& m, const Vector3& g, double dt) noexcept {
  // Phi = I + A dt + A^2 dt^2 / 2 (A^3 terms are O(dt^3) and only touch p/bias).
  TransitionBlocks N;
  const Matrix3 G = skew(g);
  const Matrix3& R = m.R_WI;
  const Matrix3 vxR = skew(m.v_WI) * R;
  const Matrix3 pxR = skew(m.p_WI) * R;
  const double dt2 = 0.5 * dt * dt;
  N.VR = G * dt;
  N.PR = G * dt2;
  N.PV = dt;
  N.RBg = -R * dt;
  N.VBg = -vxR * dt - G * R * dt2;
  N.VBa = -R * dt;
  N.PBg = -pxR * dt - vxR * dt2;
  N.PBa = -R * dt2;
  for (int f = 0; f < kNumFeet; ++f)
    N.DBg[f] = -skew(m.d_W[f]) * R * dt;
  return N;
}

/// Columns [c, c + 3) of P.
inline auto cols(Ekf::Covariance& P, int c) {
  return P.block<kN, 3>(0, c);
}

/// Row block [r, r + 3) of P from column C on (C a multiple of 3, known at compile time).
template <int C>
inline auto row_tail(Ekf::Covariance& P, int r) {
  return P.block<3, kN - C>(r, C);
}

/// Copies the upper triangle of P onto its lower triangle.
inline void mirror_upper(Ekf::Covariance& P) noexcept {
  for (int c = 0; c < kN; ++c)
    for (int r = c + 1; r < kN; ++r)
      P(r, c) = P(c, r);
}

/// P <- P - W W^T on the upper triangle only (W is kN x 3), by 3-column blocks.
template <int J = 0>
inline void subtract_upper_outer(Ekf::Covariance& P, const Eigen::Matrix<double, kN, 3>& W) {
  if constexpr (J < kN / 3) {
    constexpr int rows = 3 * (J + 1);
    P.block<rows, 3>(0, 3 * J).noalias() -=
        W.topRows<rows>().lazyProduct(W.block<3, 3>(3 * J, 0).transpose());
    subtract_upper_outer<J + 1>(P, W);
  }
}

}  // namespace

InvariantEkf::Covariance InvariantEkf::error_transition(const Mean& m, const Vector3& g,
                                                        double dt) noexcept {
  const TransitionBlocks N = transition_blocks(m, g, dt);
  Covariance Phi = Covariance::Identity();
  Phi.block<3, 3>(kV, kR) = N.VR;
  Phi.block<3, 3>(kP, kR) = N.PR;
  Phi.block<3, 3>(kP, kV) = N.PV * Matrix3::Identity();
  Phi.block<3, 3>(kR, kBg) = N.RBg;
  Phi.block<3, 3>(kV, kBg) = N.VBg;
  Phi.block<3, 3>(kV, kBa) = N.VBa;
  Phi.block<3, 3>(kP, kBg) = N.PBg;
  Phi.block<3, 3>(kP, kBa) = N.PBa;
  for (int f = 0; f < kNumFeet; ++f)
    Phi.block<3, 3>(d_index(f), kBg) = N.DBg[f];
  return Phi;
}

void InvariantEkf::propagate(const Vector3& gyro_I, const Vector3& specific_force_I,
                             double dt) noexcept {
  if (!(dt > 0.0)) return;
  // Everything below linearises about the mean BEFORE the step.
  const TransitionBlocks N = transition_blocks(mean_, g_, dt);
  const std::array<Vector3, 4> x{mean_.v_WI, mean_.p_WI, mean_.d_W[0], mean_.d_W[1]};
  propagate_mean(gyro_I, specific_force_I, dt, g_, mean_);

  // P <- Phi P Phi^T with Phi = I + N, N block-sparse (TransitionBlocks), in place.
  // 1) B = P Phi^T, column blocks: B(:, j) = P(:, j) + sum_k P(:, k) N(j, k)^T. The order P, V,
  //    D, R reads every source column before it is overwritten (bias columns never change).
  Covariance& P = P_;
  cols(P, kP).noalias() += cols(P, kR).lazyProduct(N.PR.transpose()) + N.PV * cols(P, kV) +
                           cols(P, kBg).lazyProduct(N.PBg.transpose()) +
                           cols(P, kBa).lazyProduct(N.PBa.transpose());
  cols(P, kV).noalias() += cols(P, kR).lazyProduct(N.VR.transpose()) +
                           cols(P, kBg).lazyProduct(N.VBg.transpose()) +
                           cols(P, kBa).lazyProduct(N.VBa.transpose());
  for (int f = 0; f < kNumFeet; ++f)
    cols(P, d_index(f)).noalias() += cols(P, kBg).lazyProduct(N.DBg[f].transpose());
  cols(P, kR).noalias() += cols(P, kBg).lazyProduct(N.RBg.transpose());
  // 2) Phi B = B + N B, row blocks, upper triangle only (the result is symmetric): row block i
  //    from column 3 * (i / 3) on, same order.
  row_tail<kP>(P, kP).noalias() +=
      N.PR.lazyProduct(row_tail<kP>(P, kR)) + N.PV * row_tail<kP>(P, kV) +
      N.PBg.lazyProduct(row_tail<kP>(P, kBg)) + N.PBa.lazyProduct(row_tail<kP>(P, kBa));
  row_tail<kV>(P, kV).noalias() += N.VR.lazyProduct(row_tail<kV>(P, kR)) +
                                   N.VBg.lazyProduct(row_tail<kV>(P, kBg)) +
                                   N.VBa.lazyProduct(row_tail<kV>(P, kBa));
  row_tail<kD>(P, kD).noalias() += N.DBg[0].lazyProduct(row_tail<kD>(P, kBg));
  row_tail<kD + 3>(P, kD + 3).noalias() += N.DBg[1].lazyProduct(row_tail<kD + 3>(P, kBg));
  row_tail<kR>(P, kR).noalias() += N.RBg.lazyProduct(row_tail<kR>(P, kBg));

  // 3) Process noise (G Qc G^T) dt, upper blocks: G = blockdiag(Ad_X, I), the gyro noise enters
  //    the state block through S = [I; [v]x; [p]x; [d0]x; [d1]x] (the R column of Ad_X R^T), so
  //    Q(i, j) = q_g S_i S_j^T with [a]x [b]x^T = (a.b) I - b a^T.
  const double qg = noise_.gyro * noise_.gyro * dt;
  const double qa = noise_.accel * noise_.accel * dt;
  const double qp = noise_.position * noise_.position * dt;
  const double qd = noise_.foot_slip * noise_.foot_slip * dt;
  const int idx[4] = {kV, kP, kD, kD + 3};
  P.block<3, 3>(kR, kR).diagonal().array() += qg;
  for (int j = 0; j < 4; ++j) {
    P.block<3, 3>(kR, idx[j]) -= qg * skew(x[j]);
    for (int i = 0; i <= j; ++i) {
      auto B = P.block<3, 3>(idx[i], idx[j]);
      B.noalias() -= (qg * x[j]) * x[i].transpose();
      B.diagonal().array() += qg * x[i].dot(x[j]);
    }
  }
  P.block<3, 3>(kV, kV).diagonal().array() += qa;
  P.block<3, 3>(kP, kP).diagonal().array() += qp;
  for (int f = 0; f < kNumFeet; ++f)
    P.block<3, 3>(d_index(f), d_index(f)).diagonal().array() += qd;
  P.block<3, 3>(kBg, kBg).diagonal().array() += noise_.gyro_bias_walk * noise_.gyro_bias_walk * dt;
  P.block<3, 3>(kBa, kBa).diagonal().array() +=
      noise_.accel_bias_walk * noise_.accel_bias_walk * dt;
  mirror_upper(P);
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
  const Eigen::Matrix<double, kDim, 3> PHt = P_.block<kDim, 3>(0, kP) - P_.block<kDim, 3>(0, d);
  Matrix3 S = PHt.block<3, 3>(kP, 0) - PHt.block<3, 3>(d, 0);
  S += noise_.kinematics * noise_.kinematics * Matrix3::Identity();
  const Vector3 z = mean_.R_WI * s_I - mean_.d_W[foot] + mean_.p_WI;
  return update(PHt, S, z);
}

double InvariantEkf::correct_orientation(const Matrix3& R_WI_measured, double std_rad,
                                         double max_chi2) noexcept {
  if (!(std_rad > 0.0) || !R_WI_measured.allFinite()) return 0.0;
  // eta_R = R_hat R^T = Exp(xi_R): z = Log(R_hat R_measured^T) = xi_R, H = [I 0 ...].
  const Eigen::Matrix<double, kDim, 3> PHt = P_.block<kDim, 3>(0, kR);
  Matrix3 S = PHt.block<3, 3>(kR, 0);
  S += std_rad * std_rad * Matrix3::Identity();
  return update(PHt, S, so3_log(mean_.R_WI * R_WI_measured.transpose()), max_chi2);
}

double InvariantEkf::update(const Eigen::Matrix<double, kDim, 3>& PHt, Matrix3 S,
                            const Vector3& z, double max_chi2) noexcept {
  S = 0.5 * (S + S.transpose()).eval();
  const Eigen::LLT<Matrix3> llt(S);
  if (llt.info() != Eigen::Success) return 0.0;
  // With S = L L^T and W = P H^T L^-T (forward substitution, column by column):
  //   K = P H^T S^-1 = W L^-1,  K H P = W W^T,  dx = K z = W (L^-1 z),  chi2 = |L^-1 z|^2.
  const Matrix3& L = llt.matrixLLT();  // lower triangle
  Eigen::Matrix<double, kDim, 3> W;
  W.col(0) = PHt.col(0) / L(0, 0);
  W.col(1) = (PHt.col(1) - L(1, 0) * W.col(0)) / L(1, 1);
  W.col(2) = (PHt.col(2) - L(2, 0) * W.col(0) - L(2, 1) * W.col(1)) / L(2, 2);
  Vector3 y;
  y[0] = z[0] / L(0, 0);
  y[1] = (z[1] - L(1, 0) * y[0]) / L(1, 1);
  y[2] = (z[2] - L(2, 0) * y[0] - L(2, 1) * y[1]) / L(2, 2);
  if (!(y.squaredNorm() <= max_chi2)) return y.squaredNorm();  // gated out: no update
  const ErrorVector dx = W.col(0) * y[0] + W.col(1) * y[1] + W.col(2) * y[2];
  subtract_upper_outer(P_, W);
  mirror_upper(P_);
  apply_correction(dx, mean_);
  return y.squaredNorm();
}

void InvariantEkf::set_pose_velocity(const Matrix3& R_WI, const Vector3& v_WI,
                                     const Vector3& p_WI) noexcept {
  mean_.R_WI = R_WI;
  mean_.v_WI = v_WI;
  mean_.p_WI = p_WI;
}

void InvariantEkf::set_biases(const Vector3& b_g, const Vector3& b_a, double std_g,
                              double std_a) noexcept {
  mean_.b_g = b_g;
  mean_.b_a = b_a;
  P_.middleRows<6>(kBg).setZero();
  P_.middleCols<6>(kBg).setZero();
  P_.block<3, 3>(kBg, kBg).diagonal().setConstant(std_g * std_g);
  P_.block<3, 3>(kBa, kBa).diagonal().setConstant(std_a * std_a);
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
