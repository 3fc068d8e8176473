// Eq (36) foot feedback against finite differences of poses, and the Sec. 4.2 resting test.
#include <gtest/gtest.h>

#include <random>

#include "controller_test_util.hpp"
#include "poise/controller/foot_motion.hpp"

namespace poise::controller {
namespace {

// A pose moved for a short time h with a constant LOCAL_WORLD_ALIGNED velocity V = [v_Fo; omega]
// (world axes): p' = p + v h, R' = exp(omega h) R. With kp = 1/h and kd = 0, eq (36) must
// return V (to O(h)), i.e. the log error is converted to the same convention as J qdd.
TEST(FootMotion, LogFeedbackMatchesFiniteDifferenceOfPoses) {
  std::mt19937 rng(36);
  for (int trial = 0; trial < 100; ++trial) {
    const model::SE3 X(test::random_rotation(rng, 3.0), test::random_vec3(rng, 1.0));
    model::Motion V;
    V << test::random_vec3(rng, 1.0), test::random_vec3(rng, 2.0);
    const double h = 1e-6;
    const model::SE3 X_d(model::so3_exp(V.tail<3>() * h) * X.R, X.p + V.head<3>() * h);
    FootGains g;
    g.kp = 1.0 / h;
    g.kd = 0.0;
    const model::Motion a =
        foot_acceleration(g, X, model::Motion::Zero(), X_d, model::Motion::Zero());
    EXPECT_LT((a - V).norm(), 1e-5 * (1.0 + V.norm())) << a.transpose() << " vs " << V.transpose();
  }
}

TEST(FootMotion, DerivativeTermAndZeroError) {
  std::mt19937 rng(37);
  const model::SE3 X(test::random_rotation(rng, 3.0), test::random_vec3(rng, 1.0));
  model::Motion V, Vd;
  V << test::random_vec3(rng, 1.0), test::random_vec3(rng, 1.0);
  Vd << test::random_vec3(rng, 1.0), test::random_vec3(rng, 1.0);
  FootGains g{100.0, 20.0};
  const model::Motion a = foot_acceleration(g, X, V, X, Vd);
  EXPECT_LT((a - 20.0 * (Vd - V)).norm(), 1e-10);
  // A resting foot follows itself: T_d = T, v_d = v gives zero acceleration.
  EXPECT_LT(foot_acceleration(g, X, V, X, V).norm(), 1e-12);
}

TEST(FootMotion, LargeRotationErrorIsTheRotationVector) {
  // A rotation of 2 rad about the world z axis: the angular part is 2 rad * kp about z.
  const model::SE3 X(model::so3_exp(Eigen::Vector3d(0.3, -0.2, 0.1)), Eigen::Vector3d(1, 2, 3));
  const Eigen::Vector3d w_W(0, 0, 2.0);
  const model::SE3 X_d(model::so3_exp(w_W) * X.R, X.p);
  const model::Motion a =
      foot_acceleration(FootGains{1.0, 0.0}, X, model::Motion::Zero(), X_d, model::Motion::Zero());
  EXPECT_LT((a.tail<3>() - w_W).norm(), 1e-9);
}

TEST(FootMotion, CopSafeRegionByHand) {
  model::SoleRectangle sole;
  sole.x_min = -0.08;
  sole.x_max = 0.14;
  sole.y_min = -0.05;
  sole.y_max = 0.06;
  sole.height = 0.08;
  std::mt19937 rng(38);
  for (int trial = 0; trial < 200; ++trial) {
    const model::SE3 X(test::random_rotation(rng, 0.5), test::random_vec3(rng, 1.0));
    const double dx = test::uniform(rng, -0.12, 0.18), dy = test::uniform(rng, -0.09, 0.1);
    const double margin = 0.01;
    const Eigen::Vector3d cop = X.p + X.R * Eigen::Vector3d(dx, dy, -0.08);
    const bool inside = dx > -0.07 && dx < 0.13 && dy > -0.04 && dy < 0.05;
    const bool border = std::abs(dx + 0.07) < 1e-9 || std::abs(dx - 0.13) < 1e-9 ||
                        std::abs(dy + 0.04) < 1e-9 || std::abs(dy - 0.05) < 1e-9;
    if (!border) {
      EXPECT_EQ(cop_in_safe_region(X, cop, sole, margin), inside) << dx << " " << dy;
    }
  }
  const model::SE3 I;
  EXPECT_TRUE(sole_center_W(I, sole).isApprox(Eigen::Vector3d(0.03, 0.005, -0.08)));
}

}  // namespace
}  // namespace poise::controller
