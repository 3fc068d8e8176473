// RNEA and CRBA checked against identities built from independently tested Jacobians.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

using test::all_urdfs;
using test::random_state;

// A frame id per body, to evaluate Jacobians of points fixed on each body.
std::vector<int> body_frames(const Model& m) {
  std::vector<int> out(m.nbodies, -1);
  for (int f = 0; f < static_cast<int>(m.frames.size()); ++f)
    if (m.frames[f].is_body) out[m.frames[f].body] = f;
  return out;
}

// Point on body b given in body coordinates -> coordinates in the frame of body b's own link.
Vector3 in_frame(const Model& m, int f, const Vector3& p_B) {
  return m.frames[f].X_BF.act_inv(p_B);
}

class DynamicsTest : public ::testing::TestWithParam<std::string> {};

TEST_P(DynamicsTest, RneaAtRestEqualsGravityGeneralizedForce) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  const auto bf = body_frames(model);
  std::mt19937 rng(11);
  Matrix6X J(6, model.nv);
  for (int trial = 0; trial < 3; ++trial) {
    const auto s = random_state(model, rng);
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.nv);
    const Eigen::VectorXd tau = rnea(model, data, s.q, zero, zero);
    // g(q) = - sum_b J_cb^T m_b g  (virtual work of gravity at each body's centre of mass)
    compute_joint_jacobians(model, data, s.q);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(model.nv);
    for (int b = 0; b < model.nbodies; ++b) {
      const Inertia& I = model.inertia[b];
      if (I.mass == 0.0) continue;
      frame_point_jacobian(model, data, bf[b], in_frame(model, bf[b], I.com), J);
      g -= J.topRows<3>().transpose() * (I.mass * model.gravity);
    }
    EXPECT_LT((tau - g).norm(), 1e-10 * (1 + g.norm())) << "\n"
                                                        << tau.transpose() << "\n"
                                                        << g.transpose();
  }
}

TEST_P(DynamicsTest, RneaEqualsMassMatrixTimesAPlusBias) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(12);
  for (int trial = 0; trial < 5; ++trial) {
    const auto s = random_state(model, rng);
    const Eigen::VectorXd tau = rnea(model, data, s.q, s.v, s.a);
    const Eigen::VectorXd bias = rnea(model, data, s.q, s.v, Eigen::VectorXd::Zero(model.nv));
    const Eigen::MatrixXd M = crba(model, data, s.q);
    EXPECT_LT((tau - (M * s.a + bias)).norm(), 1e-10 * (1 + tau.norm()));
    EXPECT_TRUE(M.isApprox(M.transpose(), 1e-14));
  }
}

TEST_P(DynamicsTest, KineticEnergyFromMassMatrixEqualsSumOverBodies) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(13);
  for (int trial = 0; trial < 3; ++trial) {
    const auto s = random_state(model, rng);
    const Eigen::MatrixXd M = crba(model, data, s.q);
    forward_kinematics(model, data, s.q, s.v);
    double T = 0.0;
    for (int b = 0; b < model.nbodies; ++b) {
      const Inertia& I = model.inertia[b];
      const Vector3 w = data.v[b].tail<3>();
      const Vector3 vc = data.v[b].head<3>() + w.cross(I.com);
      T += 0.5 * (I.mass * vc.squaredNorm() + w.dot(I.I_com * w));
    }
    EXPECT_NEAR(0.5 * s.v.dot(M * s.v), T, 1e-10 * (1 + T));
    // Positive definite when every DoF moves some mass (true for these robots).
    EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(M).info(), Eigen::Success);
  }
}

TEST_P(DynamicsTest, ExternalWrenchEntersAsJacobianTranspose) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(14);
  std::normal_distribution<double> n01;
  Matrix6X J(6, model.nv);
  const auto s = random_state(model, rng);
  clear_external_forces(data);
  const Eigen::VectorXd tau0 = rnea(model, data, s.q, s.v, s.a);
  compute_joint_jacobians(model, data, s.q);
  Eigen::VectorXd expected = tau0;
  for (int f = 0; f < static_cast<int>(model.frames.size()); f += 2) {
    const Vector3 p(n01(rng), n01(rng), n01(rng)), force(n01(rng), n01(rng), n01(rng)),
        torque(n01(rng), n01(rng), n01(rng));
    add_external_wrench(model, data, f, p, force, torque);
    // Jacobian of the body point that is currently at p.
    const SE3 X = frame_placement(model, data, f);
    frame_point_jacobian(model, data, f, X.act_inv(p), J);
    Force F;
    F << force, torque;
    expected -= J.transpose() * F;
  }
  const Eigen::VectorXd tau = rnea(model, data, s.q, s.v, s.a);
  EXPECT_LT((tau - expected).norm(), 1e-10 * (1 + tau.norm()));
  clear_external_forces(data);
  EXPECT_LT((rnea(model, data, s.q, s.v, s.a) - tau0).norm(), 1e-12 * (1 + tau0.norm()));
}

TEST_P(DynamicsTest, MassMatrixIsTheMomentumJacobian) {
  // The base rows of M times v are the system's spatial momentum (base frame, base origin).
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(15);
  const auto s = random_state(model, rng);
  const Eigen::MatrixXd M = crba(model, data, s.q);
  // Compare with the centroidal momentum moved to the base origin.
  centroidal_momentum(model, data, s.q, s.v);
  const SE3 X_WB = base_pose(s.q);
  const Vector6 hB = M.topRows<6>() * s.v;  // [l_B; k_Bo_B]
  const Vector3 l_W = X_WB.R * hB.head<3>();
  const Vector3 kBo_W = X_WB.R * hB.tail<3>();
  EXPECT_LT((l_W - data.hg.tail<3>()).norm(), 1e-10 * (1 + l_W.norm()));
  const Vector3 kG_from_M = kBo_W - (data.com - X_WB.p).cross(l_W);
  EXPECT_LT((kG_from_M - data.hg.head<3>()).norm(), 1e-10 * (1 + kG_from_M.norm()));
}

INSTANTIATE_TEST_SUITE_P(Robots, DynamicsTest, ::testing::ValuesIn(all_urdfs()));

}  // namespace
}  // namespace poise::model
