#pragma once
// IDL <-> Eigen conversions shared by every node's message conversions. Allocation-free.

#include <array>

#include <poise/msg/common.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace poise::node {

/// A 3-array of an IDL sample as an Eigen vector.
inline Eigen::Vector3d vec3(const std::array<double, 3>& a) {
  return {a[0], a[1], a[2]};
}

/// Writes an Eigen vector into a 3-array of an IDL sample.
inline void put3(const Eigen::Vector3d& v, std::array<double, 3>& a) {
  a[0] = v.x();
  a[1] = v.y();
  a[2] = v.z();
}

/// Writes the pose (rotation R_WB, position p_WB) into an IDL Pose (quaternion w, x, y, z).
inline void put_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& p, msg::Pose& out) {
  put3(p, out.position());
  const Eigen::Quaterniond q(R);
  out.orientation_wxyz() = {q.w(), q.x(), q.y(), q.z()};
}

/// The rotation of an IDL Pose, its quaternion normalised (identity if it is ~zero).
inline Eigen::Matrix3d rotation(const msg::Pose& p) {
  const auto& q = p.orientation_wxyz();
  Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
  const double n = quat.norm();
  if (n < 1e-9) return Eigen::Matrix3d::Identity();
  quat.coeffs() /= n;
  return quat.toRotationMatrix();
}

}  // namespace poise::node
