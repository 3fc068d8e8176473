// Contact hysteresis and the measured centre of pressure, against a wrench built from a known
// point force (independent: the wrench is assembled with a cross product at a chosen point).
#include <gtest/gtest.h>

#include <random>

#include "poise/estimator/contact_detector.hpp"

namespace poise::estimator {
namespace {

Force wrench_with_fz(double fz) {
  Force w = Force::Zero();
  w[2] = fz;
  return w;
}

TEST(ContactDetector, HysteresisOnTheNormalForce) {
  ContactDetector c(ContactThresholds{100.0, 30.0});
  EXPECT_FALSE(c.update(wrench_with_fz(50.0)));   // below on
  EXPECT_FALSE(c.update(wrench_with_fz(100.0)));  // not strictly above
  EXPECT_TRUE(c.update(wrench_with_fz(100.5)));
  EXPECT_TRUE(c.update(wrench_with_fz(50.0)));  // between: stays on
  EXPECT_TRUE(c.update(wrench_with_fz(30.0)));
  EXPECT_FALSE(c.update(wrench_with_fz(29.9)));
  EXPECT_FALSE(c.update(wrench_with_fz(99.0)));  // between: stays off
  EXPECT_TRUE(c.update(wrench_with_fz(1000.0)));
  EXPECT_TRUE(c.update(wrench_with_fz(std::nan(""))));  // non-finite: unchanged
  EXPECT_FALSE(c.update(wrench_with_fz(-5.0)));
}

TEST(ContactDetector, RejectsBadThresholds) {
  EXPECT_THROW(ContactDetector(ContactThresholds{10.0, 10.0}), std::invalid_argument);
  EXPECT_THROW(ContactDetector(ContactThresholds{10.0, -1.0}), std::invalid_argument);
  EXPECT_THROW(ContactDetector(ContactThresholds{std::nan(""), 1.0}), std::invalid_argument);
}

TEST(CenterOfPressure, RecoversThePointOfApplicationOfAForceOnTheSole) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 50; ++trial) {
    const double h = 0.05 + 0.05 * (u(rng) + 1.0);
    const Vector3 p(0.1 * u(rng), 0.05 * u(rng), -h);  // on the sole plane
    const Vector3 f(20 * u(rng), 20 * u(rng), 200 + 100 * u(rng));
    const double tau_n = 2.0 * u(rng);  // normal torque about p: does not move the CoP
    Force w;
    w.head<3>() = f;
    w.tail<3>() = p.cross(f) + Vector3(0, 0, tau_n);
    Vector3 cop;
    ASSERT_TRUE(center_of_pressure(w, h, 1.0, cop));
    EXPECT_LT((cop - p).norm(), 1e-12);
  }
  Vector3 cop(7, 7, 7);
  EXPECT_FALSE(center_of_pressure(wrench_with_fz(0.5), 0.08, 1.0, cop));
  EXPECT_EQ(cop, Vector3(7, 7, 7));
}

}  // namespace
}  // namespace poise::estimator
