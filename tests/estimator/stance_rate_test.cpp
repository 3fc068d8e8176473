// The published base angular velocity: a complementary filter of the gyro and the stance feet's
// kinematics (EstimatorConfig::stance_rate_filter_hz, stance_rate_gate; #17 item 2: the gyro's
// white noise through the momentum feedback put the CoPs at the sole edges).
//  - open loop, exact frames of a robot standing still: the noise that reaches the output is the
//    first-order low-pass's share of the gyro's (an identity of the filter, computed here), the
//    output's mean is the gyro's (a foot turning slowly is followed), and a fast disagreement
//    publishes the gyro alone at once and for the hold time;
//  - closed loop in process with the industrial sensors: the published rate against the
//    simulator's truth, with the filter and with the gyro alone.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "estimator_test_util.hpp"
#include "poise/inprocess/in_process_loop.hpp"
#include "poise/scenario/scenario.hpp"

namespace poise::estimator {
namespace {

using test::StandingRobot;

constexpr double kSameAsGyro = 2e-4;  // [rad/s]

struct OpenLoop {
  StandingRobot robot;
  EstimatorConfig cfg;
  Estimator est;
  SensorFrame frame;
  EstimatorState state;
  std::int64_t k = 0;
  explicit OpenLoop(const EstimatorConfig& c, double gyro_std)
      : cfg(c), est(robot.model, robot.config, cfg) {
    robot.gyro_std = gyro_std;
    frame = est.make_sensor_frame();
    state = est.make_state();
  }
  /// One tick; `extra_I` is added to the gyro (the base turning while the feet's kinematics say
  /// it does not: a foot turning on the ground).
  void step(const Vector3& extra_I = Vector3::Zero()) {
    robot.fill(k++, frame);
    frame.imu_omega_I += extra_I;
    est.update(frame, state);
  }
  /// The published rate in base axes minus what the bias-corrected gyro says, this tick. The
  /// output used the bias before this tick's contact correction, which moves it by up to ~1e-4
  /// rad/s while the gyro and the kinematics disagree (the filter reads part of it as bias):
  /// hence kSameAsGyro below, against the 8-50 mrad/s the cases put between the two.
  Vector3 published_minus_gyro() const {
    const Matrix3 R_BI = est.X_BI().R;
    const Vector3 gyro_B = R_BI * (frame.imu_omega_I - est.filter().mean().b_g);
    return state.X_WB.R.transpose() * state.omega_WB - gyro_B;
  }
};

double published_noise_std(double filter_hz, double gyro_std) {
  EstimatorConfig c;
  c.stance_rate_filter_hz = filter_hz;
  c.stance_rate_gate = 1.0;  // no gating: the filter's noise transfer alone
  OpenLoop o(c, gyro_std);
  for (int i = 0; i < 2000; ++i) o.step();  // the bias estimate settles
  double sq = 0.0;
  int n = 0;
  for (int i = 0; i < 20000; ++i) {
    o.step();
    // The robot stands still: the truth is zero.
    const Vector3 w_B = o.state.X_WB.R.transpose() * o.state.omega_WB;
    sq += w_B.squaredNorm();
    n += 3;
  }
  return std::sqrt(sq / n);
}

TEST(StanceRate, TheGyroNoiseLeftIsTheLowPassShareOfIt) {
  const double sigma = 3.12e-3;  // ADIS16470-class per 1 kHz sample (simulator/sim/SENSORS.md)
  const double gyro_alone = published_noise_std(0.0, sigma);
  EXPECT_NEAR(gyro_alone, sigma, 0.1 * sigma);
  for (double hz : {5.0, 10.0, 30.0}) {
    // White noise through y += a (x - y): variance a / (2 - a) of the input's (exact kinematics
    // here, so the kinematic rate adds nothing).
    const double a = 1.0 - std::exp(-2.0 * M_PI * hz * 1e-3);
    const double expected = sigma * std::sqrt(a / (2.0 - a));
    const double fused = published_noise_std(hz, sigma);
    std::printf("stance rate filter %4.1f Hz: published noise %.3f mrad/s (gyro alone %.3f, "
                "low-pass share %.3f)\n",
                hz, 1e3 * fused, 1e3 * gyro_alone, 1e3 * expected);
    EXPECT_NEAR(fused, expected, 0.15 * expected) << hz << " Hz";
  }
}

TEST(StanceRate, AFootTurningSlowlyIsFollowedAtTheGyroRate) {
  // Below the cut-off the output is the gyro's: a steady 8 mrad/s the feet's kinematics do not
  // show (a foot rolling over its edge, a deck turning) comes through whole.
  EstimatorConfig c;
  OpenLoop o(c, 0.0);
  for (int i = 0; i < 1000; ++i) o.step();
  const Vector3 extra(0.0, 0.0, 0.008);
  for (int i = 0; i < 100; ++i) o.step(extra * (i / 100.0));  // ramp in, below the gate
  for (int i = 0; i < 1000; ++i) o.step(extra);
  EXPECT_LT(o.published_minus_gyro().norm(), kSameAsGyro);
  EXPECT_EQ(o.est.diagnostics().stance_rate_gated_ticks, 0u);
}

TEST(StanceRate, AFastDisagreementPublishesTheGyroAtOnceAndForTheHoldTime) {
  EstimatorConfig c;  // gate 0.02 rad/s, hold 0.05 s
  OpenLoop o(c, 0.0);
  for (int i = 0; i < 1000; ++i) o.step();
  ASSERT_EQ(o.est.diagnostics().stance_rate_gated_ticks, 0u);
  // Before: the fused rate, at the gyro's mean (the bias estimate is still settling).
  EXPECT_LT(o.published_minus_gyro().norm(), kSameAsGyro);
  const Vector3 jump(0.05, 0.0, 0.0);  // a foot tips: 50 mrad/s at once
  o.step(jump);
  EXPECT_LT(o.published_minus_gyro().norm(), kSameAsGyro) << "the gyro on the very tick";
  for (int i = 0; i < 40; ++i) {
    o.step(jump);
    EXPECT_LT(o.published_minus_gyro().norm(), kSameAsGyro) << "tick " << i << " of the jump";
  }
  // The foot stops turning: the disagreement goes; after the hold the fused rate again, at the
  // gyro's mean (the filter took part of the jump for bias, so that is not quite zero).
  for (int i = 0; i < 400; ++i) o.step();
  const std::uint64_t gated = o.est.diagnostics().stance_rate_gated_ticks;
  EXPECT_GE(gated, 41u + 50u);  // 41 ticks of the jump, then the jump's end, then the hold
  EXPECT_LE(gated, 41u + 70u);
  EXPECT_LT(o.published_minus_gyro().norm(), kSameAsGyro);
}

TEST(StanceRate, AFilterRestartStartsTheFusionAgainFromTheGyro) {
  // The low-passed offset belongs to the stream it was learnt on: after a filter restart
  // (reset(), or a gap longer than max_gap) the first published rate on the feet is the gyro's,
  // not the kinematics plus an offset learnt before. The base turned at 8 mrad/s the feet did
  // not show before the restart and does not after: an old offset would be 8 mrad/s off (below
  // the gate, so only the restart can remove it at once).
  EstimatorConfig c;
  OpenLoop o(c, 0.0);
  for (int i = 0; i < 1000; ++i) o.step(Vector3(0.0, 0.0, 0.008));  // an offset is learnt
  o.est.reset();
  o.step();  // initialises
  o.step();  // the first fused tick, without the 8 mrad/s
  EXPECT_LT(o.published_minus_gyro().norm(), kSameAsGyro);
  // A gap longer than max_gap restarts the filter the same way.
  for (int i = 0; i < 500; ++i) o.step(Vector3(0.0, 0.0, 0.008));
  o.k += static_cast<std::int64_t>(std::lround(c.max_gap / c.dt)) + 10;
  o.step();  // restarts
  o.step();
  EXPECT_LT(o.published_minus_gyro().norm(), kSameAsGyro);
}

TEST(StanceRate, BadSettingsAreRefusedNamingTheField) {
  StandingRobot robot;
  const auto refused = [&](EstimatorConfig c, const std::string& field) {
    try {
      Estimator e(robot.model, robot.config, c);
      ADD_FAILURE() << field << " accepted";
    } catch (const EstimatorError& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  EstimatorConfig c;
  c.stance_rate_filter_hz = -1.0;
  refused(c, "stance_rate_filter_hz");
  c = EstimatorConfig{};
  c.stance_rate_filter_hz = std::nan("");
  refused(c, "stance_rate_filter_hz");
  c = EstimatorConfig{};
  c.stance_rate_gate = 0.0;
  refused(c, "stance_rate_gate");
  c = EstimatorConfig{};
  c.stance_rate_hold = -0.1;
  refused(c, "stance_rate_hold");
}

/// Closed loop in process, industrial sensors (forward push of the paper, 8 s): RMS per axis of
/// the published base rate against the truth over the ticks from `from_tick` on.
struct RateError {
  double after_3s = 0.0, after_4s = 0.0;
};
RateError closed_loop_rate_error(double filter_hz, bool* survived) {
  scenario::Scenario sc = scenario::load_scenario(std::string(POISE_SOURCE_DIR) +
                                                  "/deploy/scenarios/forward_push_double_support.yaml");
  sc.estimator.stance_rate_hz = filter_hz;
  inprocess::LoopOptions opt;
  opt.duration = 8.0;
  inprocess::InProcessLoop loop(sc, opt);
  double sq3 = 0.0, sq4 = 0.0;
  int n3 = 0, n4 = 0;
  for (int k = 0; k < 8000; ++k) {
    const sim::GroundTruth truth = loop.truth();
    loop.step();
    if (k < 3000) continue;
    const double e = (loop.state().omega_WB - truth.omega_WB).squaredNorm();
    sq3 += e;
    n3 += 3;
    if (k < 4000) continue;
    sq4 += e;
    n4 += 3;
  }
  *survived = loop.result().survived;
  return {std::sqrt(sq3 / n3), std::sqrt(sq4 / n4)};
}

TEST(StanceRate, ClosedLoopTheFusedRateIsCloserToTheTruthThanTheGyro) {
  bool survived_gyro = false, survived_fused = false;
  const RateError gyro = closed_loop_rate_error(0.0, &survived_gyro);
  const RateError fused =
      closed_loop_rate_error(EstimatorConfig{}.stance_rate_filter_hz, &survived_fused);
  std::printf("forward push, industrial sensors: base rate RMS error after 3 s gyro alone "
              "%.2f mrad/s, fused %.2f mrad/s; after 4 s %.2f and %.2f mrad/s\n",
              1e3 * gyro.after_3s, 1e3 * fused.after_3s, 1e3 * gyro.after_4s,
              1e3 * fused.after_4s);
  EXPECT_TRUE(survived_gyro);
  EXPECT_TRUE(survived_fused);
  // The gyro's own per-sample noise (3.1 mrad/s) is what the gyro alone publishes.
  EXPECT_NEAR(gyro.after_3s, 3.12e-3, 0.5e-3);
  EXPECT_NEAR(gyro.after_4s, 3.12e-3, 0.5e-3);
  // Closer to the truth from 2 s after the push on. With the contact optimiser's
  // friction-coupled torsion limit (the default since 2026-12-03) the fused rate of this run is
  // 13 mrad/s RMS off between 3.0 and 3.5 s (recorded in lockstep), mostly in yaw, under the
  // 20 mrad/s gate of stance_rate_gate (the stance feet turn there, which the fusion assumes not):
  // 2.63 against 3.22 mrad/s from 3 s. With the independent limit it was 0.97 against 3.24.
  EXPECT_LT(fused.after_3s, gyro.after_3s);
  // Once the feet are still again (from 4 s), at most half the gyro's error.
  EXPECT_LT(fused.after_4s, 0.5 * gyro.after_4s);
}

}  // namespace
}  // namespace poise::estimator
