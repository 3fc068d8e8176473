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

TEST(ContactDetector, APlannedSwingEndsTheContactAtTheLowerLoadOrWhenTheSoleLeaves) {
  // off 5 N, so swing_off_force = 2.5 N by default.
  ContactThresholds t{75.0, 5.0};
  t.touch_force = 10.0;
  ContactDetector c(t);
  EXPECT_DOUBLE_EQ(c.thresholds().swing_off_force, 2.5);
  FootKinematics k;
  k.sole_z = 0.0;
  EXPECT_TRUE(c.update(wrench_with_fz(200.0), k));
  // The plan says swing; the controller unloads the foot: 4 N and 3 N (below off, above
  // swing_off) keep the contact however long, where without the plan two ticks end it.
  k.plan = FootPlan::kSwing;
  for (int i = 0; i < 10; ++i)
    EXPECT_TRUE(c.update(wrench_with_fz(i % 2 ? 4.0 : 3.0), k));
  // Below 2.5 N for two ticks (confirm_ticks): lift-off.
  EXPECT_TRUE(c.update(wrench_with_fz(2.0), k));
  EXPECT_FALSE(c.update(wrench_with_fz(2.0), k));

  // The same unloading without a plan: two ticks below 5 N end the contact.
  ContactDetector d(t);
  k = FootKinematics{};
  k.sole_z = 0.0;
  EXPECT_TRUE(d.update(wrench_with_fz(200.0), k));
  EXPECT_TRUE(d.update(wrench_with_fz(4.0), k));
  EXPECT_FALSE(d.update(wrench_with_fz(3.0), k));

  // Planned swing, the load below 2.5 N for one tick, the sole rising from its lowest height
  // since the swing began: 0.02 mm up is within swing_lift_height (0.03 mm), 0.04 mm is not.
  ContactDetector e(t);
  k = FootKinematics{};
  k.sole_z = 0.0;
  EXPECT_TRUE(e.update(wrench_with_fz(200.0), k));
  k.plan = FootPlan::kSwing;
  k.sole_z = -1e-5;  // the lowest since the swing began
  EXPECT_TRUE(e.update(wrench_with_fz(3.0), k));
  k.sole_z = 1e-5;  // 0.02 mm above it, rising, but the load 3 N > 2.5 N
  EXPECT_TRUE(e.update(wrench_with_fz(3.0), k));
  k.sole_z = 2.5e-5;  // 0.035 mm above the lowest, rising, load 2 N: lift-off at once
  EXPECT_FALSE(e.update(wrench_with_fz(2.0), k));

  // A planned support is no evidence: it unloads as without a plan.
  ContactDetector g(t);
  k = FootKinematics{};
  k.sole_z = 0.0;
  k.plan = FootPlan::kSupport;
  EXPECT_TRUE(g.update(wrench_with_fz(200.0), k));
  EXPECT_TRUE(g.update(wrench_with_fz(4.0), k));
  EXPECT_FALSE(g.update(wrench_with_fz(4.0), k));
}

TEST(ContactDetector, AFootRestingLightlyKeepsItsContactWhenTheRuleIsOn) {
  ContactThresholds t{75.0, 5.0};
  t.touch_force = 10.0;
  t.rest_time = 0.05;
  ContactDetector c(t);
  FootKinematics k;
  k.sole_z = 0.0;
  EXPECT_TRUE(c.update(wrench_with_fz(200.0), k));
  // Unloaded slowly by a weight shift: 8 N (below touch_force) for 60 ticks, the sole still.
  for (int i = 0; i < 60; ++i)
    EXPECT_TRUE(c.update(wrench_with_fz(8.0), k));
  EXPECT_TRUE(c.resting());
  // Then 0-4 N (below off) for 200 ticks: still in contact.
  for (int i = 0; i < 200; ++i)
    EXPECT_TRUE(c.update(wrench_with_fz(0.02 * (i % 200)), k));
  // The sole rises 5 mm: lift-off.
  k.sole_z = 0.002;
  EXPECT_TRUE(c.update(wrench_with_fz(1.0), k));
  k.sole_z = 0.005;
  EXPECT_FALSE(c.update(wrench_with_fz(1.0), k));
  EXPECT_FALSE(c.resting());

  // A foot that stood loaded (longer than rest_time: not a landing's impact) and is unloaded
  // fast (a push): below touch_force for 3 ticks only, then below off: the force rule ends its
  // contact as without the resting rule.
  ContactDetector d(t);
  k = FootKinematics{};
  k.sole_z = 0.0;
  for (int i = 0; i < 60; ++i)
    EXPECT_TRUE(d.update(wrench_with_fz(200.0), k));
  EXPECT_TRUE(d.update(wrench_with_fz(9.0), k));
  EXPECT_TRUE(d.update(wrench_with_fz(4.0), k));
  EXPECT_FALSE(d.update(wrench_with_fz(1.0), k));

  // Off by default: the resting foot loses its contact two ticks below off.
  ContactDetector e(ContactThresholds{75.0, 5.0});
  k = FootKinematics{};
  k.sole_z = 0.0;
  EXPECT_TRUE(e.update(wrench_with_fz(200.0), k));
  for (int i = 0; i < 100; ++i)
    EXPECT_TRUE(e.update(wrench_with_fz(8.0), k));
  EXPECT_TRUE(e.update(wrench_with_fz(1.0), k));
  EXPECT_FALSE(e.update(wrench_with_fz(1.0), k));
}

TEST(ContactDetector, ALightTouchIsFlaggedFromItsStepAboveTheReadingInTheAir) {
  // The project humanoid's thresholds (W = 504 N: on 15 %, off 1 %, touch 2 %) and the default
  // F/T (noise 0.5 N, normal offset 1.5 N, never learnt: the foot is never 3 cm up). The
  // reading is drawn here, seeded; the detector sees only it and the sole height.
  const double sigma = 0.5, offset = 1.5;
  ContactThresholds t{75.6, 5.04};
  t.touch_force = 10.08;
  t.light_noise = sigma;
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, sigma);
  const auto reading = [&](double load) { return wrench_with_fz(load + offset + noise(rng)); };
  ContactDetector c(t);
  FootKinematics k;
  k.sole_z = 0.0;
  ASSERT_TRUE(c.update(reading(250.0), k));
  // The weight moves off the foot; it leaves the ground 0.2 mm and hovers there.
  for (int i = 0; i < 10; ++i)
    c.update(reading(250.0 * (1.0 - 0.1 * (i + 1))), k);
  k.sole_z = 2e-4;
  for (int i = 0; i < 3; ++i)
    c.update(reading(0.0), k);
  ASSERT_FALSE(c.in_contact());
  // Noise alone, 20 s with the sole down where it stood: never a touch.
  int false_touches = 0;
  for (int i = 0; i < 20000; ++i)
    false_touches += c.update(reading(0.0), k) ? 1 : 0;
  EXPECT_EQ(false_touches, 0);
  // It touches down again with 2 N (0.4 % of W, four sigma): flagged within 5 ticks, below
  // every load threshold.
  k.sole_z = 0.0;
  int ticks = 0;
  while (!c.update(reading(2.0), k) && ticks < 100)
    ++ticks;
  EXPECT_LE(ticks, 4);
  EXPECT_TRUE(c.light());
  // It rests there with 2 N for 2 s: no chatter.
  int dropped = 0;
  for (int i = 0; i < 2000; ++i)
    dropped += c.update(reading(2.0), k) ? 0 : 1;
  EXPECT_EQ(dropped, 0);
  // The load leaves (the sole stays: a separation without motion): released within 10 ticks.
  ticks = 0;
  while (c.update(reading(0.0), k) && ticks < 100)
    ++ticks;
  EXPECT_LE(ticks, 9);
  EXPECT_FALSE(c.light());
  // A load in the dead band between one and two sigma (0.75 N) changes the flag at most once
  // in 5 s.
  int changes = 0;
  bool prev = c.in_contact();
  for (int i = 0; i < 5000; ++i) {
    const bool now = c.update(reading(0.75), k);
    changes += now != prev ? 1 : 0;
    prev = now;
  }
  EXPECT_LE(changes, 1);
  for (int i = 0; i < 200; ++i)
    c.update(reading(0.0), k);
  ASSERT_FALSE(c.in_contact());
  // A light touch whose load stays above touch_force for 2 ticks becomes an ordinary contact,
  // which the 1 % rule then ends in 2 ticks.
  while (!c.update(reading(3.0), k)) {
  }
  EXPECT_TRUE(c.light());
  c.update(reading(30.0), k);  // one tick of a spike: still light
  EXPECT_TRUE(c.light());
  EXPECT_TRUE(c.update(reading(3.0), k));
  EXPECT_TRUE(c.update(reading(3.0), k));
  c.update(reading(30.0), k);
  c.update(reading(30.0), k);
  EXPECT_FALSE(c.light());
  c.update(reading(0.0), k);
  EXPECT_FALSE(c.update(reading(0.0), k));

  // A restart (ContactDetector::reset, as Estimator::reset does): the baseline is learnt again
  // for light_baseline_time (50 ms) before the rule may fire. A 2 N load already there then is
  // learnt as the baseline and not flagged (it is not told from the offset); one that comes
  // after is.
  c.reset(false);
  int touches = 0;
  for (int i = 0; i < 30; ++i)
    touches += c.update(reading(2.0), k) ? 1 : 0;
  for (int i = 0; i < 500; ++i)
    touches += c.update(reading(2.0), k) ? 1 : 0;
  EXPECT_EQ(touches, 0) << "a load present at the restart is the baseline";
  c.reset(false);
  for (int i = 0; i < 60; ++i)
    touches += c.update(reading(0.0), k) ? 1 : 0;
  EXPECT_EQ(touches, 0);
  ticks = 0;
  while (!c.update(reading(2.0), k) && ticks < 100)
    ++ticks;
  EXPECT_LE(ticks, 4) << "after the baseline is learnt again";

  // With the sole 5 mm up (the light rule needs it within lift_height of where it stood) or with
  // the rule off, the same 2 N step is never a touch.
  for (int variant = 0; variant < 2; ++variant) {
    ContactThresholds tv = t;
    if (variant == 1) tv.light_noise = 0.0;
    ContactDetector d(tv);
    FootKinematics kv;
    kv.sole_z = 0.0;
    d.update(reading(250.0), kv);
    kv.sole_z = variant == 0 ? 0.005 : 0.0;
    for (int i = 0; i < 200; ++i)
      d.update(reading(0.0), kv);
    int touches = 0;
    for (int i = 0; i < 500; ++i)
      touches += d.update(reading(2.0), kv) ? 1 : 0;
    EXPECT_EQ(touches, 0) << (variant == 0 ? "sole 5 mm up" : "rule off");
  }
}

// A planned swing's foot that tips about its heel edge with a light load keeps its contact (the
// heel corners stay on the ground, as the simulator's truth says: contact lasts while one corner
// touches); once the whole sole leaves, accelerating from rest, the corner rule flags the
// lift-off within a few ticks. Geometry built here independently: a 0.2 m x 0.1 m sole turned by
// theta about its heel edge, then translated up.
TEST(ContactDetector, APlannedSwingEndsWhenEveryCornerOfTheSoleLeaves) {
  // The resting rule on: the foot, unloaded to 1 N before its swing, keeps its contact at any
  // load (without it the load rule ends the contact below swing_off_force whatever the sole).
  ContactThresholds t{75.0, 5.0};
  t.touch_force = 10.0;
  t.rest_time = 0.02;
  const double length = 0.2, dt = 0.001;
  const auto kinematics = [&](double theta, double lift, bool corners, FootPlan plan) {
    FootKinematics k;
    k.dt = dt;
    k.plan = plan;
    // Heel corners (x = 0) at the lift; toe corners (x = length) raised by the tip.
    const double toe = lift + length * std::sin(theta);
    k.sole_z = lift + 0.5 * length * std::sin(theta);  // the sole centre
    if (corners) k.corner_z = {lift, lift, toe, toe};
    return k;
  };
  // Loaded, then unloaded by a weight shift (8 N: below touch_force, above off_force) for 30 ms:
  // it rests.
  const auto rest = [&](ContactDetector& c, bool corners) {
    const FootKinematics k0 = kinematics(0.0, 0.0, corners, FootPlan::kNone);
    c.update(wrench_with_fz(200.0), k0);
    for (int i = 0; i < 30; ++i)
      c.update(wrench_with_fz(8.0), k0);
    return c.in_contact() && c.resting();
  };
  // The plan's swing with and without the corners; without a plan (the resting foot's own
  // corner rule: well before its sole is lift_height, 4 mm, up).
  struct Case {
    FootPlan plan;
    bool corners;
  };
  for (const Case& cs : {Case{FootPlan::kSwing, true}, Case{FootPlan::kSwing, false},
                         Case{FootPlan::kNone, true}}) {
    ContactDetector c(t);
    ASSERT_TRUE(rest(c, cs.corners));
    // 80 ms of tipping about the heel edge at 0.05 rad/s under 1 N (below swing_off_force
    // 2.5 N): the toe rises 0.8 mm, the centre 0.4 mm, the heel corners stay down.
    int ended = -1;
    for (int i = 1; i <= 80 && ended < 0; ++i)
      if (!c.update(wrench_with_fz(1.0), kinematics(5e-5 * i, 0.0, cs.corners, cs.plan)))
        ended = i;
    if (!cs.corners) {
      // The sole centre's rule takes the tip for a lift-off (the centre 0.03 mm up).
      EXPECT_GT(ended, 0);
      continue;
    }
    EXPECT_EQ(ended, -1) << "the heel corners never left the ground";
    // The whole sole leaves at 0.5 m/s^2 from rest: 5 um of rise within 5 ms after ~4.5 ms.
    for (int i = 1; i <= 20 && ended < 0; ++i) {
      const double s = i * dt;
      if (!c.update(wrench_with_fz(1.0), kinematics(5e-5 * 80, 0.25 * s * s, true, cs.plan)))
        ended = i;
    }
    EXPECT_GE(ended, 4);
    EXPECT_LE(ended, 6);
  }
  // Heights from another reference (the estimator switched from W to the other sole's plane):
  // the jump is not a lift; the history restarts.
  ContactDetector d(t);
  ASSERT_TRUE(rest(d, true));
  FootKinematics k = kinematics(0.0, 0.0, true, FootPlan::kSwing);
  for (int i = 0; i < 10; ++i)
    ASSERT_TRUE(d.update(wrench_with_fz(1.0), k));
  k.corner_reference = 1;
  for (double& z : k.corner_z)
    z += 0.8;  // the same foot seen from elsewhere
  k.sole_z = 0.0;
  for (int i = 0; i < 10; ++i)
    EXPECT_TRUE(d.update(wrench_with_fz(1.0), k)) << i;
}

TEST(ContactDetector, ALandingWhoseLoadFallsBackKeepsItsContactUntilTheSoleLeaves) {
  // The step in place's landing: the impact carries the foot above touch_force for ~12 ms, then
  // the weight stays on the other foot and this one touches with 2-5 N. The resting rule alone
  // needs rest_time below touch_force before the load may fall below off_force; a landing that
  // never carried its load for rest_time rests at once instead, and leaves by the sole or its
  // corners. A foot that stood loaded longer and is unloaded fast (a push) still leaves by load.
  ContactThresholds t{75.0, 5.0};
  t.touch_force = 10.0;
  const double dt = 0.001;
  const auto at = [&](double lift, bool corners) {
    FootKinematics k;
    k.dt = dt;
    k.sole_z = lift;
    if (corners) k.corner_z = {lift, lift, lift, lift};
    return k;
  };
  struct Case {
    double rest_time;
    bool corners;
    bool kept;  // the contact outlives 200 ms of 3 N
  };
  for (const Case& cs : {Case{0.02, true, true}, Case{0.02, false, true}, Case{0.0, true, false}}) {
    t.rest_time = cs.rest_time;
    ContactDetector c(t);
    // Coming down from 10 cm in the air (the F/T reads nothing).
    for (int i = 0; i < 100; ++i)
      c.update(wrench_with_fz(0.0), at(0.1 - 0.001 * i, cs.corners));
    ASSERT_FALSE(c.in_contact());
    // The impact: 120 N for 12 ms (touch-down at once), then 3 N, the sole still.
    for (int i = 0; i < 12; ++i)
      EXPECT_TRUE(c.update(wrench_with_fz(120.0), at(0.0, cs.corners))) << i;
    int dropped = -1;
    for (int i = 1; i <= 200 && dropped < 0; ++i)
      if (!c.update(wrench_with_fz(3.0), at(0.0, cs.corners))) dropped = i;
    if (!cs.kept) {
      EXPECT_EQ(dropped, t.confirm_ticks) << "the rule off: the load rule ends it";
      continue;
    }
    EXPECT_EQ(dropped, -1) << "rest " << cs.rest_time << " corners " << cs.corners;
    EXPECT_TRUE(c.resting());
    // The sole then leaves at 0.5 m/s^2: the corners' rule within ~6 ms, the sole's lift_height
    // (4 mm, rising) after ~127 ms without corners.
    for (int i = 1; i <= 200 && dropped < 0; ++i) {
      const double s = i * dt;
      if (!c.update(wrench_with_fz(0.0), at(0.25 * s * s, cs.corners))) dropped = i;
    }
    if (cs.corners) {
      EXPECT_GE(dropped, 4);
      EXPECT_LE(dropped, 6);
    } else {
      EXPECT_GE(dropped, 126);
      EXPECT_LE(dropped, 128);
    }
  }
  // A foot rocking on its edge taps the ground with a corner (a 265 N push at 45 deg: 12 N for
  // 3 ticks, the foot rolling at ~0.3 rad/s, its high corners coming down 0.1-0.2 mm per 5 ms
  // while the low ones leave): not at rest, so no rule holds it; the load rule ends the contact
  // as without the resting rule (a rest there kept the flag on for 113 ms in the air).
  {
    t.rest_time = 0.02;
    ContactDetector r(t);
    const double width = 0.1, rate = 0.3;  // across the sole [m], roll rate [rad/s]
    double theta = 0.15;                   // the heel-to-toe roll; low edge on the ground
    const auto rocking = [&](double low) {
      FootKinematics k;
      k.dt = dt;
      const double high = low + width * std::sin(theta);
      k.sole_z = 0.5 * (low + high);
      k.corner_z = {low, high, low, high};
      return k;
    };
    for (int i = 0; i < 100; ++i, theta -= rate * dt)
      r.update(wrench_with_fz(0.0), rocking(0.002 - 0.00002 * i));
    ASSERT_FALSE(r.in_contact());
    for (int i = 0; i < 3; ++i, theta -= rate * dt)
      EXPECT_TRUE(r.update(wrench_with_fz(12.0), rocking(0.0))) << i;
    int ended = -1;
    for (int i = 1; i <= 20 && ended < 0; ++i, theta -= rate * dt)
      if (!r.update(wrench_with_fz(0.5), rocking(1e-6 * i))) ended = i;
    EXPECT_EQ(ended, t.confirm_ticks) << "the rocking foot was taken to rest";
  }
  // Stood loaded for longer than rest_time after the landing, then unloaded within a tick (a push
  // lifts the foot): the load rule ends the contact after confirm_ticks, before the sole moves.
  t.rest_time = 0.02;
  ContactDetector p(t);
  for (int i = 0; i < 100; ++i)
    p.update(wrench_with_fz(0.0), at(0.1 - 0.001 * i, true));
  for (int i = 0; i < 30; ++i)
    ASSERT_TRUE(p.update(wrench_with_fz(200.0), at(0.0, true)));
  int dropped = -1;
  for (int i = 1; i <= 10 && dropped < 0; ++i)
    if (!p.update(wrench_with_fz(0.0), at(0.0, true))) dropped = i;
  EXPECT_EQ(dropped, t.confirm_ticks);
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
  t = ContactThresholds{100.0, 10.0};
  t.rest_time = -0.1;
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.swing_off_force = 11.0;  // above off_force
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.swing_lift_height = -1e-5;
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.light_noise = -0.5;
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.swing_corner_rise = std::nan("");
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.swing_corner_window = 0.0;
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.light_baseline_time = 0.0;
  EXPECT_THROW(ContactDetector{t}, std::invalid_argument);
  t = ContactThresholds{100.0, 10.0};
  t.rest_corner_motion = -1e-5;
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
