// Contact hysteresis and the measured centre of pressure, against a wrench built from a known
// point force (independent: the wrench is assembled with a cross product at a chosen point).
#include <gtest/gtest.h>

#include <cmath>
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
  // touch_force defaults to off + (on - off) / 4 = 47.5 N; light loads and lift-off are
  // confirmed over confirm_ticks = 2 ticks, a load above on_force at once.
  ContactDetector c(ContactThresholds{100.0, 30.0});
  EXPECT_DOUBLE_EQ(c.thresholds().touch_force, 47.5);
  EXPECT_FALSE(c.update(wrench_with_fz(46.0)));  // below touch
  EXPECT_FALSE(c.update(wrench_with_fz(47.0)));
  EXPECT_FALSE(c.update(wrench_with_fz(48.0)));  // light, rising at 1 kN/s: first tick
  EXPECT_TRUE(c.update(wrench_with_fz(48.5)));   // light: confirmed
  EXPECT_TRUE(c.update(wrench_with_fz(50.0)));   // between: stays on
  EXPECT_TRUE(c.update(wrench_with_fz(30.0)));
  EXPECT_TRUE(c.update(wrench_with_fz(29.9)));  // below off: first tick
  EXPECT_TRUE(c.update(wrench_with_fz(31.0)));  // back above: not confirmed, count restarts
  EXPECT_TRUE(c.update(wrench_with_fz(29.9)));
  EXPECT_FALSE(c.update(wrench_with_fz(29.9)));  // confirmed
  EXPECT_FALSE(c.update(wrench_with_fz(29.0)));
  EXPECT_TRUE(c.update(wrench_with_fz(1000.0)));  // above on: at once
  EXPECT_TRUE(c.update(wrench_with_fz(std::nan(""))));  // non-finite: unchanged
  EXPECT_TRUE(c.update(wrench_with_fz(-5.0)));
  EXPECT_FALSE(c.update(wrench_with_fz(-5.0)));
  // An impact: 60 N one tick after 20 N rises at 40 kN/s > touch_rate: contact at once.
  EXPECT_FALSE(c.update(wrench_with_fz(20.0)));
  EXPECT_TRUE(c.update(wrench_with_fz(60.0)));
}

TEST(ContactDetector, KinematicsGateTouchDownAndLiftOffAndLearnTheOffset) {
  ContactThresholds t{100.0, 5.0};
  t.touch_force = 10.0;
  ContactDetector c(t);
  FootKinematics k;
  k.sole_z = 0.0;
  EXPECT_TRUE(c.update(wrench_with_fz(300.0), k));  // standing at z = 0
  // Unloading while rising: below off for one tick only, but 5 mm up and rising: lift-off.
  k.sole_z = 0.002;
  EXPECT_TRUE(c.update(wrench_with_fz(4.0), k));
  k.sole_z = 0.005;
  EXPECT_FALSE(c.update(wrench_with_fz(20.0), k));  // a load reading up there is not contact
  // High in the air the reading (8 N: an offset) is learnt, and never makes a touch-down.
  k.sole_z = 0.05;
  for (int i = 0; i < 500; ++i)
    EXPECT_FALSE(c.update(wrench_with_fz(8.0 + (i % 2 ? 0.5 : -0.5)), k));
  EXPECT_NEAR(c.force_offset(), 8.0, 0.3);
  // Back down: 8 N is then no load; 8 + 12 N within a tick is an impact (at once).
  k.sole_z = 0.001;
  EXPECT_FALSE(c.update(wrench_with_fz(8.0), k));
  EXPECT_TRUE(c.update(wrench_with_fz(20.0), k));
}

TEST(ContactDetector, NoChatterWhileALoadedFootSlides) {
  // A sliding foot: load 150-350 N with noise, the sole at the support height +-1 mm.
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  ContactThresholds t{75.0, 5.0};
  t.touch_force = 10.0;
  ContactDetector c(t);
  FootKinematics k;
  int changes = 0;
  bool prev = false;
  for (int i = 0; i < 2000; ++i) {
    k.sole_z = 0.001 * std::sin(0.05 * i);
    const bool s = c.update(wrench_with_fz(250.0 + 100.0 * std::sin(0.02 * i) + 2.0 * n(rng)), k);
    if (i > 0 && s != prev) ++changes;
    prev = s;
  }
  EXPECT_TRUE(prev);
  EXPECT_EQ(changes, 0);
}

TEST(ContactDetector, RejectsBadThresholds) {
  EXPECT_THROW(ContactDetector(ContactThresholds{10.0, 10.0}), std::invalid_argument);
  EXPECT_THROW(ContactDetector(ContactThresholds{10.0, -1.0}), std::invalid_argument);
  EXPECT_THROW(ContactDetector(ContactThresholds{std::nan(""), 1.0}), std::invalid_argument);
  ContactThresholds t{100.0, 10.0};
  t.touch_force = 100.0;  // must be below on_force
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.confirm_ticks = 0;
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.lift_height = std::nan("");
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
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
