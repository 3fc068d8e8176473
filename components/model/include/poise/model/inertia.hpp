#pragma once
// Rigid-body spatial inertia in compact form (mass, centre of mass, rotational inertia about the
// centre of mass), expressed in some body frame B.

#include "poise/model/spatial.hpp"

namespace poise::model {

struct Inertia {
  double mass = 0.0;
  Vector3 com = Vector3::Zero();    ///< centre of mass in B (3)
  Matrix3 I_com = Matrix3::Zero();  ///< rotational inertia about the CoM, B axes (3x3)

  Inertia() = default;
  Inertia(double m, const Vector3& c, const Matrix3& Ic) : mass(m), com(c), I_com(Ic) {}
  static Inertia Zero() { return Inertia(); }

  /// Momentum of the body moving with twist v (both in B, about B's origin): h = I * v (dim 6).
  Force operator*(const Motion& v) const {
    Force h;
    // linear momentum: m (v_o + w x c); angular about origin: I_c w + c x l
    const Vector3 w = v.tail<3>();
    const Vector3 l = mass * (v.head<3>() + w.cross(com));
    h.head<3>() = l;
    h.tail<3>() = I_com * w + com.cross(l);
    return h;
  }
  /// Sum of two inertias expressed in the same frame (the composite rigid body).
  Inertia operator+(const Inertia& o) const {
    const double m = mass + o.mass;
    if (m <= 0.0) return Inertia(0.0, Vector3::Zero(), I_com + o.I_com);
    const Vector3 c = (mass * com + o.mass * o.com) / m;
    const Vector3 d1 = com - c;
    const Vector3 d2 = o.com - c;
    const Matrix3 I = I_com + o.I_com +
                      mass * (d1.squaredNorm() * Matrix3::Identity() - d1 * d1.transpose()) +
                      o.mass * (d2.squaredNorm() * Matrix3::Identity() - d2 * d2.transpose());
    return Inertia(m, c, I);
  }
  Inertia& operator+=(const Inertia& o) { return *this = *this + o; }

  /// The same inertia expressed in A, given X_AB.
  Inertia transformed(const SE3& X_AB) const {
    return Inertia(mass, X_AB.act(com), X_AB.R * I_com * X_AB.R.transpose());
  }
  /// Rotational inertia about B's origin (3x3).
  Matrix3 inertia_about_origin() const {
    return I_com + mass * (com.squaredNorm() * Matrix3::Identity() - com * com.transpose());
  }
  /// 6x6 matrix acting on [v; w] motions, giving [f; tau] momenta.
  Matrix6 matrix() const {
    Matrix6 M;
    const Matrix3 C = skew(com);
    M.topLeftCorner<3, 3>() = mass * Matrix3::Identity();
    M.topRightCorner<3, 3>() = -mass * C;
    M.bottomLeftCorner<3, 3>() = mass * C;
    M.bottomRightCorner<3, 3>() = I_com - mass * C * C;
    return M;
  }
};

/// Spatial inertia in "origin form": mass, first moment h = m c and rotational inertia about the
/// frame origin. Sums are plain additions, which makes composite inertias in one frame cheap.
struct InertiaAtOrigin {
  double mass = 0.0;
  Vector3 h = Vector3::Zero();  ///< m * c (3)
  Matrix3 I = Matrix3::Zero();  ///< about the origin (3x3)

  /// Inertia `Y` given in B, expressed in A about A's origin, with X_AB.
  static InertiaAtOrigin from(const Inertia& Y, const SE3& X_AB) {
    InertiaAtOrigin o;
    o.mass = Y.mass;
    const Vector3 c = X_AB.act(Y.com);
    o.h = Y.mass * c;
    o.I.noalias() = X_AB.R * Y.I_com * X_AB.R.transpose();
    o.I.diagonal().array() += Y.mass * c.squaredNorm();
    o.I.noalias() -= Y.mass * c * c.transpose();
    return o;
  }
  InertiaAtOrigin& operator+=(const InertiaAtOrigin& o) {
    mass += o.mass;
    h += o.h;
    I += o.I;
    return *this;
  }
  /// Momentum [l; k_origin] of the body moving with twist v = [v_o; w] (dim 6).
  Force operator*(const Motion& v) const {
    Force out;
    out.head<3>() = mass * v.head<3>() + v.tail<3>().cross(h);
    out.tail<3>() = I * v.tail<3>() + h.cross(v.head<3>());
    return out;
  }
};

}  // namespace poise::model
