#pragma once
// Spatial algebra used by the dynamics library (and by the controller, e.g. eq (36) of the paper).
//
// Conventions (the same everywhere in poise::model):
//  - Motion (twist, spatial velocity/acceleration) 6-vectors are [linear; angular].
//  - Force (wrench) 6-vectors are [force; torque].
//  - A pose X_AB (type SE3) maps coordinates in B to coordinates in A: p_A = R_AB p_B + p_AB.
//  - Spatial vectors of a body are expressed in the body frame at the body origin unless the name
//    says otherwise (suffix _W: world-aligned axes).
//
// All functions are inline, allocation-free, and use fixed-size Eigen types.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace poise::model {

using Vector3 = Eigen::Vector3d;
using Matrix3 = Eigen::Matrix3d;
using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;
using Matrix6X = Eigen::Matrix<double, 6, Eigen::Dynamic>;
using Motion = Vector6;  ///< [v (3); omega (3)]
using Force = Vector6;   ///< [f (3); tau (3)]

/// Skew-symmetric matrix: skew(a) * b = a x b.
inline Matrix3 skew(const Vector3& a) {
  Matrix3 S;
  S << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return S;
}

/// Rigid transform X_AB: rotation R (3x3, orthonormal) and translation p (3), see file comment.
struct SE3 {
  Matrix3 R = Matrix3::Identity();
  Vector3 p = Vector3::Zero();

  SE3() = default;
  SE3(const Matrix3& R_in, const Vector3& p_in) : R(R_in), p(p_in) {}
  static SE3 Identity() { return SE3(); }

  /// Composition: (X_AB * X_BC) = X_AC.
  SE3 operator*(const SE3& o) const { return SE3(R * o.R, R * o.p + p); }
  /// Inverse: X_BA.
  SE3 inverse() const { return SE3(R.transpose(), -(R.transpose() * p)); }
  /// Point in B -> point in A.
  Vector3 act(const Vector3& point_B) const { return R * point_B + p; }
  /// Point in A -> point in B.
  Vector3 act_inv(const Vector3& point_A) const { return R.transpose() * (point_A - p); }

  /// Motion expressed in B (at B's origin) -> same motion expressed in A (at A's origin).
  Motion act_motion(const Motion& m_B) const {
    Motion out;
    const Vector3 w = R * m_B.tail<3>();
    out.head<3>() = R * m_B.head<3>() + p.cross(w);
    out.tail<3>() = w;
    return out;
  }
  /// Motion expressed in A -> expressed in B.
  Motion act_inv_motion(const Motion& m_A) const {
    Motion out;
    out.head<3>() = R.transpose() * (m_A.head<3>() - p.cross(m_A.tail<3>()));
    out.tail<3>() = R.transpose() * m_A.tail<3>();
    return out;
  }
  /// Force expressed in B (about B's origin) -> expressed in A (about A's origin).
  Force act_force(const Force& f_B) const {
    Force out;
    const Vector3 f = R * f_B.head<3>();
    out.head<3>() = f;
    out.tail<3>() = R * f_B.tail<3>() + p.cross(f);
    return out;
  }
  /// Force expressed in A -> expressed in B.
  Force act_inv_force(const Force& f_A) const {
    Force out;
    out.head<3>() = R.transpose() * f_A.head<3>();
    out.tail<3>() = R.transpose() * (f_A.tail<3>() - p.cross(f_A.head<3>()));
    return out;
  }
  /// 6x6 motion transform matrix (maps motion in B to motion in A).
  Matrix6 to_motion_matrix() const {
    Matrix6 X;
    X.topLeftCorner<3, 3>() = R;
    X.topRightCorner<3, 3>() = skew(p) * R;
    X.bottomLeftCorner<3, 3>().setZero();
    X.bottomRightCorner<3, 3>() = R;
    return X;
  }
  /// 4x4 homogeneous matrix.
  Eigen::Matrix4d to_homogeneous() const {
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = R;
    T.topRightCorner<3, 1>() = p;
    return T;
  }
  bool is_approx(const SE3& o, double tol = 1e-12) const {
    return R.isApprox(o.R, tol) && (p - o.p).norm() <= tol * (1.0 + p.norm());
  }
};

/// Spatial cross product for motions: v x m (dim 6).
inline Motion cross_motion(const Motion& v, const Motion& m) {
  Motion out;
  const auto vl = v.head<3>();
  const auto w = v.tail<3>();
  out.head<3>() = w.cross(m.head<3>()) + vl.cross(m.tail<3>());
  out.tail<3>() = w.cross(m.tail<3>());
  return out;
}

/// Spatial cross product for forces: v x* f (dim 6).
inline Force cross_force(const Motion& v, const Force& f) {
  Force out;
  const auto vl = v.head<3>();
  const auto w = v.tail<3>();
  out.head<3>() = w.cross(f.head<3>());
  out.tail<3>() = w.cross(f.tail<3>()) + vl.cross(f.head<3>());
  return out;
}

/// SO(3) exponential: rotation by angle |w| about w/|w|.
inline Matrix3 so3_exp(const Vector3& w) {
  const double t2 = w.squaredNorm();
  const double t = std::sqrt(t2);
  double a, b;  // sin(t)/t, (1-cos t)/t^2
  if (t < 1e-4) {
    a = 1.0 - t2 / 6.0;
    b = 0.5 - t2 / 24.0;
  } else {
    a = std::sin(t) / t;
    b = (1.0 - std::cos(t)) / t2;
  }
  const Matrix3 S = skew(w);
  return Matrix3::Identity() + a * S + b * S * S;
}

/// SO(3) logarithm: rotation vector w (|w| <= pi) with so3_exp(w) = R.
inline Vector3 so3_log(const Matrix3& R) {
  // Use the quaternion: robust near 0 and near pi.
  Eigen::Quaterniond q(R);
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const double s = q.vec().norm();
  const double angle = 2.0 * std::atan2(s, q.w());
  if (s < 1e-12) return 2.0 * q.vec() / q.w();  // small angle: angle/s -> 2/w
  return (angle / s) * q.vec();
}

/// Left Jacobian helper V(w) of SO(3): p = V(w) * v in the SE(3) exponential.
inline Matrix3 so3_left_jacobian(const Vector3& w) {
  const double t2 = w.squaredNorm();
  const double t = std::sqrt(t2);
  double b, c;  // (1-cos t)/t^2, (t - sin t)/t^3
  if (t < 1e-4) {
    b = 0.5 - t2 / 24.0;
    c = 1.0 / 6.0 - t2 / 120.0;
  } else {
    b = (1.0 - std::cos(t)) / t2;
    c = (t - std::sin(t)) / (t2 * t);
  }
  const Matrix3 S = skew(w);
  return Matrix3::Identity() + b * S + c * S * S;
}

/// SE(3) exponential of a twist nu = [v; w] (dim 6): the pose reached after moving for unit time
/// with constant body twist nu, starting at the identity.
inline SE3 se3_exp(const Motion& nu) {
  const Vector3 w = nu.tail<3>();
  return SE3(so3_exp(w), so3_left_jacobian(w) * nu.head<3>());
}

/// SE(3) logarithm: the twist nu = [v; w] (dim 6, |w| <= pi) with se3_exp(nu) = X.
/// For X = X_WA^-1 * X_WB this is the body twist (in A) that moves A onto B in unit time, the
/// usual pose error of task-space controllers.
inline Motion se3_log(const SE3& X) {
  Motion nu;
  const Vector3 w = so3_log(X.R);
  nu.tail<3>() = w;
  nu.head<3>() = so3_left_jacobian(w).inverse() * X.p;
  return nu;
}

}  // namespace poise::model
