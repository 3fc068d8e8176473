// CoM and centroidal momentum matrix: sums over bodies, finite differences, Newton-Euler.
#include <gtest/gtest.h>

#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

using test::all_urdfs;
using test::random_state;

class CentroidalTest : public ::testing::TestWithParam<std::string> {};

// Momentum about the CoM summed body by body from their velocities: [k; l].
Vector6 sum_of_body_momenta(const Model& model, const Data& data, const Vector3& G) {
  Vector6 h = Vector6::Zero();
  for (int b = 0; b < model.nbodies; ++b) {
    const Inertia& I = model.inertia[b];
    const SE3& X = data.oMi[b];
    const Vector3 w_W = X.R * data.v[b].tail<3>();
    const Vector3 c_W = X.act(I.com);
    const Vector3 vc_W = X.R * (data.v[b].head<3>() + data.v[b].tail<3>().cross(I.com));
    const Vector3 l = I.mass * vc_W;
    h.tail<3>() += l;
    h.head<3>() += X.R * I.I_com * X.R.transpose() * w_W + (c_W - G).cross(l);
  }
  return h;
}

TEST_P(CentroidalTest, AvEqualsSumOfBodyMomenta) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(21);
  for (int trial = 0; trial < 3; ++trial) {
    const auto s = random_state(model, rng);
    centroidal_momentum_matrix(model, data, s.q, s.v);
    // independent CoM: mass-weighted body CoMs
    Vector3 mc = Vector3::Zero();
    for (int b = 0; b < model.nbodies; ++b)
      mc += model.inertia[b].mass * data.oMi[b].act(model.inertia[b].com);
    const Vector3 G = mc / model.total_mass;
    EXPECT_LT((data.com - G).norm(), 1e-12);
    EXPECT_NEAR(data.mass, model.total_mass, 1e-12);
    const Vector6 h = sum_of_body_momenta(model, data, G);
    EXPECT_LT((data.Ag * s.v - h).norm(), 1e-10 * (1 + h.norm()));
    EXPECT_LT((data.hg - h).norm(), 1e-10 * (1 + h.norm()));
    EXPECT_LT((data.vcom - h.tail<3>() / model.total_mass).norm(), 1e-10);
    // the fast path agrees
    Data d2(model);
    centroidal_momentum(model, d2, s.q, s.v);
    EXPECT_LT((d2.hg - h).norm(), 1e-10 * (1 + h.norm()));
    EXPECT_LT((d2.com - G).norm(), 1e-12);
  }
}

TEST_P(CentroidalTest, ComJacobianMatchesFiniteDifferences) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model), dp(model), dm(model);
  std::mt19937 rng(22);
  const auto s = random_state(model, rng);
  com_jacobian(model, data, s.q);
  const double h = 1e-6;
  Eigen::VectorXd qp(model.nq), qm(model.nq);
  for (int k = 0; k < model.nv; ++k) {
    const Eigen::VectorXd e = Eigen::VectorXd::Unit(model.nv, k);
    integrate(model, s.q, e, h, qp);
    integrate(model, s.q, e, -h, qm);
    center_of_mass(model, dp, qp);
    center_of_mass(model, dm, qm);
    EXPECT_LT((data.Jcom.col(k) - (dp.com - dm.com) / (2 * h)).norm(), 1e-7) << "column " << k;
  }
  Data d2(model);
  centroidal_momentum_matrix(model, d2, s.q, s.v);
  EXPECT_LT((d2.Jcom - data.Jcom).norm(), 1e-12);
}

TEST_P(CentroidalTest, BiasMatchesMomentumDerivativeAtZeroAcceleration) {
  // Along q(t) = q0 (+) v t with constant v: a = 0, so d/dt h = dA/dt v.
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model), dp(model), dm(model);
  std::mt19937 rng(23);
  const double h = 1e-5;
  Eigen::VectorXd qp(model.nq), qm(model.nq);
  for (int trial = 0; trial < 3; ++trial) {
    const auto s = random_state(model, rng);
    centroidal_momentum_matrix(model, data, s.q, s.v);
    integrate(model, s.q, s.v, h, qp);
    integrate(model, s.q, s.v, -h, qm);
    centroidal_momentum(model, dp, qp, s.v);
    centroidal_momentum(model, dm, qm, s.v);
    const Vector6 fd = (dp.hg - dm.hg) / (2 * h);
    EXPECT_LT((data.dAg_v - fd).norm(), 1e-5 * (1 + fd.norm())) << data.dAg_v.transpose() << "\n"
                                                                << fd.transpose();
  }
}

TEST_P(CentroidalTest, AMatchesMomentumDerivativeWithAcceleration) {
  // v(t) = v0 + a t, q(t) = q0 (+) (v0 + a t / 2) t: d/dt h = A a + dA/dt v.
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model), dp(model), dm(model);
  std::mt19937 rng(24);
  const double h = 1e-4;
  Eigen::VectorXd qp(model.nq), qm(model.nq);
  for (int trial = 0; trial < 3; ++trial) {
    const auto s = random_state(model, rng);
    centroidal_momentum_matrix(model, data, s.q, s.v);
    integrate(model, s.q, s.v + 0.5 * h * s.a, h, qp);
    integrate(model, s.q, s.v - 0.5 * h * s.a, -h, qm);
    centroidal_momentum(model, dp, qp, s.v + h * s.a);
    centroidal_momentum(model, dm, qm, s.v - h * s.a);
    const Vector6 fd = (dp.hg - dm.hg) / (2 * h);
    const Vector6 hdot = data.Ag * s.a + data.dAg_v;
    EXPECT_LT((hdot - fd).norm(), 1e-5 * (1 + fd.norm())) << hdot.transpose() << "\n"
                                                          << fd.transpose();
  }
}

TEST_P(CentroidalTest, NewtonEulerOfTheWholeRobot) {
  // The momentum rate equals gravity + external wrenches + the base wrench from RNEA (joint
  // torques are internal): links CMM, its bias and the floating-base rows of RNEA.
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  std::mt19937 rng(25);
  std::normal_distribution<double> n01;
  const auto s = random_state(model, rng);
  clear_external_forces(data);
  Vector3 f_sum = Vector3::Zero(), k_sum = Vector3::Zero();
  centroidal_momentum_matrix(model, data, s.q, s.v);
  const Vector3 G = data.com;
  const Vector6 hdot = data.Ag * s.a + data.dAg_v;
  for (int f = 1; f < static_cast<int>(model.frames.size()); f += 3) {
    const Vector3 p(n01(rng), n01(rng), n01(rng)), force(n01(rng), n01(rng), n01(rng)),
        torque(n01(rng), n01(rng), n01(rng));
    add_external_wrench(model, data, f, p, force, torque);
    f_sum += force;
    k_sum += torque + (p - G).cross(force);
  }
  const Eigen::VectorXd tau = rnea(model, data, s.q, s.v, s.a);
  const SE3 X_WB = base_pose(s.q);
  const Vector3 fB = X_WB.R * tau.head<3>();
  const Vector3 tB = X_WB.R * tau.segment<3>(3);
  const Vector3 ldot = model.total_mass * model.gravity + f_sum + fB;
  const Vector3 kdot = k_sum + tB + (X_WB.p - G).cross(fB);
  EXPECT_LT((hdot.tail<3>() - ldot).norm(), 1e-9 * (1 + ldot.norm()));
  EXPECT_LT((hdot.head<3>() - kdot).norm(), 1e-9 * (1 + kdot.norm()));
}

INSTANTIATE_TEST_SUITE_P(Robots, CentroidalTest, ::testing::ValuesIn(all_urdfs()));

}  // namespace
}  // namespace poise::model
