// EstimatorConfig::kind = kLegOdometry (poise-estimator --estimator leg-odometry), an IMU without
// orientation output (all-zero quaternion) and the per-foot start heights, on the synthetic
// standing robot of estimator_test_util.hpp (exact kinematics, IMU with noise and a gyro bias of
// (4, -3, 2) mrad/s).
#include <gtest/gtest.h>

#include "estimator_test_util.hpp"
#include "poise/estimator/estimator.hpp"
#include "poise/model/kinematics.hpp"

namespace poise::estimator {
namespace {

using test::all_finite;
using test::StandingRobot;

double angle_deg(const Matrix3& A, const Matrix3& B) {
  return model::so3_log(A * B.transpose()).norm() * 180.0 / M_PI;
}

struct Ticks {
  StandingRobot robot;
  Estimator est;
  SensorFrame frame;
  EstimatorState state;
  std::int64_t k = 0;
  bool imu_orientation = true;
  explicit Ticks(EstimatorConfig cfg)
      : est(robot.model, robot.config, cfg),
        frame(est.make_sensor_frame()),
        state(est.make_state()) {}
  void run(int ticks) {
    for (int i = 0; i < ticks; ++i) {
      robot.fill(k++, frame);
      if (!imu_orientation) frame.imu_q_WI.coeffs().setZero();
      est.update(frame, state);
    }
  }
};

EstimatorConfig with_kind(EstimatorKind kind) {
  EstimatorConfig c;
  c.kind = kind;
  return c;
}

TEST(LegOdometryKind, PublishesTheBaselineWithoutBiases) {
  Ticks r(with_kind(EstimatorKind::kLegOdometry));
  r.run(1000);
  EXPECT_EQ(r.est.kind(), EstimatorKind::kLegOdometry);
  EXPECT_EQ(r.state.X_WB.p, r.est.leg_odometry().X_WB().p);
  EXPECT_EQ(r.state.X_WB.R, r.est.leg_odometry().X_WB().R);
  EXPECT_EQ(r.state.v_WB, r.est.leg_odometry().v_WB());
  EXPECT_EQ(r.state.gyro_bias_I, Vector3::Zero());
  EXPECT_EQ(r.state.accel_bias_I, Vector3::Zero());
  // Its orientation is the IMU's (exact here), its position the stance feet's.
  const SE3 X_WB_true = model::base_pose(r.robot.q_true);
  EXPECT_LT(angle_deg(r.state.X_WB.R, X_WB_true.R), 1e-6);
  EXPECT_LT((r.state.X_WB.p - X_WB_true.p).norm(), 2e-3);
  EXPECT_LT((r.state.com_W - r.robot.com_W).norm(), 2e-3);
  EXPECT_TRUE(all_finite(r.state));
  // The filter's output differs from it: the kinds really select.
  Ticks ekf(with_kind(EstimatorKind::kInvariantEkf));
  ekf.run(1000);
  EXPECT_NE(ekf.state.gyro_bias_I, Vector3::Zero());
}

// Without an IMU orientation: nothing is rejected; the attitude is the filter's at the end of the
// initialising 0.5 s, then the raw gyro integrated, so its error grows at the gyro bias.
TEST(LegOdometryKind, WithoutImuOrientationIntegratesTheRawGyro) {
  Ticks r(with_kind(EstimatorKind::kLegOdometry));
  r.imu_orientation = false;
  r.run(500);
  const SE3 X_WB_true = model::base_pose(r.robot.q_true);
  const double at_start = angle_deg(r.state.X_WB.R, X_WB_true.R);
  EXPECT_LT(at_start, 0.2);
  r.run(1000);  // 1 s of integration
  EXPECT_EQ(r.est.diagnostics().rejected_frames, 0u);
  const double grown = angle_deg(r.state.X_WB.R, X_WB_true.R) - at_start;
  const double bias_deg = r.robot.gyro_bias.norm() * 1.0 * 180.0 / M_PI;  // 0.31 deg
  EXPECT_NEAR(grown, bias_deg, 0.3 * bias_deg);
  EXPECT_TRUE(all_finite(r.state));
}

// The filter without an IMU orientation starts its tilt from one accelerometer sample (here
// 0.063 m/s^2 of noise per sample: ~0.4 deg per axis, which standing cannot tell from a
// horizontal accelerometer bias, estimator.hpp); after its 0.5 s the base is re-placed so that
// the soles are at the start height with the filter's attitude, whatever that tilt.
TEST(LegOdometryKind, FilterWithoutImuOrientationIsRePlacedAtTheStartHeight) {
  Ticks r(with_kind(EstimatorKind::kInvariantEkf));
  r.imu_orientation = false;
  r.run(501);  // the tick after the 0.5 s: re-placed, the lowest sole at the ground's height
  double lowest = 1e9;
  for (int f = 0; f < kNumFeet; ++f) {
    const double h = r.robot.config.feet[static_cast<std::size_t>(f)].sole.height;
    lowest = std::min(lowest, r.state.feet[f].X_WF.act(Vector3(0.0, 0.0, -h)).z());
  }
  EXPECT_NEAR(lowest, 0.0, 5e-4);
  const SE3 X_WB_true = model::base_pose(r.robot.q_true);
  const double tilt = std::acos(std::clamp(r.state.X_WB.R.col(2).dot(X_WB_true.R.col(2)), -1.0, 1.0));
  EXPECT_LT(tilt * 180.0 / M_PI, 1.0);
  EXPECT_EQ(r.est.diagnostics().rejected_frames, 0u);
}

// Per-foot start heights: the soles in contact start where they say.
TEST(LegOdometryKind, SupportHeightsPlaceTheStart) {
  for (EstimatorKind kind : {EstimatorKind::kInvariantEkf, EstimatorKind::kLegOdometry}) {
    EstimatorConfig c = with_kind(kind);
    c.support_height = {0.30, 0.30};
    Ticks r(c);
    r.run(1);
    for (int f = 0; f < kNumFeet; ++f) {
      const double h = r.robot.config.feet[static_cast<std::size_t>(f)].sole.height;
      const Vector3 sole = r.state.feet[f].X_WF.act(Vector3(0.0, 0.0, -h));
      EXPECT_NEAR(sole.z(), 0.30, 1e-3) << to_string(kind) << " foot " << f;
    }
  }
}

}  // namespace
}  // namespace poise::estimator
