// Kinematics checked against finite differences along exact trajectories of the configuration.
#include <gtest/gtest.h>

#include "poise/model/kinematics.hpp"
#include "poise/model/spatial.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

using test::all_urdfs;
using test::random_state;

// q(t) = q0 (+) v t, with the velocity held constant (so a = 0 along it).
Eigen::VectorXd at(const Model& m, const Eigen::VectorXd& q0, const Eigen::VectorXd& v, double t) {
  Eigen::VectorXd q(m.nq);
  integrate(m, q0, v, t, q);
  return q;
}

TEST(Spatial, ExpLogRoundTrip) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  for (int k = 0; k < 200; ++k) {
    Motion nu;
    for (int i = 0; i < 6; ++i)
      nu[i] = n01(rng);
    if (nu.tail<3>().norm() > 3.0) nu.tail<3>() *= 3.0 / nu.tail<3>().norm();
    if (k % 10 == 0) nu.tail<3>() *= 1e-9;  // near-identity rotations
    const SE3 X = se3_exp(nu);
    EXPECT_TRUE((X.R.transpose() * X.R).isIdentity(1e-12));
    EXPECT_LT((se3_log(X) - nu).norm(), 1e-9) << nu.transpose();
  }
  // log near pi: exp(log(R)) == R
  const Matrix3 R = so3_exp(Vector3(0.0, M_PI - 1e-7, 0.0));
  EXPECT_TRUE(so3_exp(so3_log(R)).isApprox(R, 1e-9));
}

TEST(Spatial, ExpMatchesIntegrationOfConstantTwist) {
  // d/dt X = X * [nu]: integrate with many small steps and compare with the closed form.
  Motion nu;
  nu << 0.3, -0.2, 0.5, 0.7, -0.4, 0.9;
  SE3 X;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const Matrix3 dR = so3_exp(nu.tail<3>() / n);
    X.p += X.R * (nu.head<3>() / n);  // first-order in position
    X.R = X.R * dR;
  }
  const SE3 E = se3_exp(nu);
  EXPECT_LT((X.p - E.p).norm(), 1e-3);
  EXPECT_TRUE(X.R.isApprox(E.R, 1e-9));
}

class KinematicsTest : public ::testing::TestWithParam<std::string> {};

TEST_P(KinematicsTest, FrameVelocityAndJacobianMatchFiniteDifferences) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(1234);
  Matrix6X J(6, model.nv);
  const double h = 1e-6;
  for (int trial = 0; trial < 3; ++trial) {
    const auto s = random_state(model, rng);
    forward_kinematics(model, data, s.q, s.v);
    compute_joint_jacobians(model, data, s.q);
    Data dp(model), dm(model);
    forward_kinematics(model, dp, at(model, s.q, s.v, h));
    forward_kinematics(model, dm, at(model, s.q, s.v, -h));
    for (int f = 0; f < static_cast<int>(model.frames.size()); ++f) {
      const SE3 Xp = frame_placement(model, dp, f), Xm = frame_placement(model, dm, f);
      Motion fd;
      fd.head<3>() = (Xp.p - Xm.p) / (2 * h);
      fd.tail<3>() = so3_log(Xp.R * Xm.R.transpose()) / (2 * h);
      const Motion V = frame_velocity(model, data, f);
      EXPECT_LT((V - fd).norm(), 1e-6 * (1 + V.norm())) << model.frames[f].name;
      frame_jacobian(model, data, f, J);
      EXPECT_LT((J * s.v - V).norm(), 1e-10 * (1 + V.norm())) << model.frames[f].name;
    }
  }
}

TEST_P(KinematicsTest, JacobianColumnsMatchFiniteDifferences) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model), dp(model), dm(model);
  std::mt19937 rng(99);
  const auto s = random_state(model, rng);
  compute_joint_jacobians(model, data, s.q);
  Matrix6X J(6, model.nv);
  const Vector3 offset(0.03, -0.02, 0.05);
  const double h = 1e-6;
  for (int f = 0; f < static_cast<int>(model.frames.size()); ++f) {
    frame_point_jacobian(model, data, f, offset, J);
    for (int k = 0; k < model.nv; ++k) {
      const Eigen::VectorXd e = Eigen::VectorXd::Unit(model.nv, k);
      forward_kinematics(model, dp, at(model, s.q, e, h));
      forward_kinematics(model, dm, at(model, s.q, e, -h));
      const SE3 Xp = frame_placement(model, dp, f), Xm = frame_placement(model, dm, f);
      Motion fd;
      fd.head<3>() = (Xp.act(offset) - Xm.act(offset)) / (2 * h);
      fd.tail<3>() = so3_log(Xp.R * Xm.R.transpose()) / (2 * h);
      EXPECT_LT((J.col(k) - fd).norm(), 1e-6) << model.frames[f].name << " column " << k;
    }
  }
}

TEST_P(KinematicsTest, JdotVMatchesFiniteDifferenceOfJv) {
  // Along q(t) = q0 (+) v t (a = 0): d/dt (J(q(t)) v) = Jdot v.
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model), dp(model), dm(model);
  std::mt19937 rng(4321);
  const double h = 1e-5;
  const Vector3 offset(-0.04, 0.01, 0.02);
  for (int trial = 0; trial < 3; ++trial) {
    const auto s = random_state(model, rng);
    forward_kinematics(model, data, s.q, s.v);
    forward_kinematics(model, dp, at(model, s.q, s.v, h), s.v);
    forward_kinematics(model, dm, at(model, s.q, s.v, -h), s.v);
    for (int f = 0; f < static_cast<int>(model.frames.size()); ++f) {
      const Motion fd = (frame_velocity(model, dp, f) - frame_velocity(model, dm, f)) / (2 * h);
      const Motion b = frame_jdot_v(model, data, f);
      EXPECT_LT((b - fd).norm(), 1e-5 * (1 + b.norm())) << model.frames[f].name;
      // A point on the frame: its velocity is linear part of the point Jacobian times v.
      auto point_vel = [&](const Data& d) {
        const SE3 X = frame_placement(model, d, f);
        const Motion V = frame_velocity(model, d, f);
        return Vector3(V.head<3>() + V.tail<3>().cross(X.R * offset));
      };
      const Vector3 fdp = (point_vel(dp) - point_vel(dm)) / (2 * h);
      const Motion bp = frame_point_jdot_v(model, data, f, offset);
      EXPECT_LT((bp.head<3>() - fdp).norm(), 1e-5 * (1 + fdp.norm())) << model.frames[f].name;
    }
  }
}

TEST_P(KinematicsTest, ClassicalAccelerationIsJaPlusJdotV) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(555);
  Matrix6X J(6, model.nv);
  const auto s = random_state(model, rng);
  forward_kinematics(model, data, s.q, s.v, s.a);
  compute_joint_jacobians(model, data, s.q);
  for (int f = 0; f < static_cast<int>(model.frames.size()); ++f) {
    frame_jacobian(model, data, f, J);
    const Motion expected = J * s.a + frame_jdot_v(model, data, f);
    const Motion acc = frame_classical_acceleration(model, data, f);
    EXPECT_LT((acc - expected).norm(), 1e-10 * (1 + acc.norm())) << model.frames[f].name;
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, KinematicsTest, ::testing::ValuesIn(all_urdfs()));

}  // namespace
}  // namespace poise::model
