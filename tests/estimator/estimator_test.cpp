// The Estimator on the project humanoid with exact sensor frames of a robot standing still:
// outputs against the model evaluated at the true state and against the statics the frames were
// built from, then every robustness case of issue 7 section 5.
#include <gtest/gtest.h>

#include <cstring>

#include "estimator_test_util.hpp"

namespace poise::estimator {
namespace {

using test::all_finite;
using test::StandingRobot;

double angle_between(const Matrix3& A, const Matrix3& B) {
  return model::so3_log(A * B.transpose()).norm();
}

struct Fixture : ::testing::Test {
  StandingRobot robot;
  EstimatorConfig cfg;
  Estimator est{robot.model, robot.config, cfg};
  SensorFrame frame = est.make_sensor_frame();
  EstimatorState state = est.make_state();
  std::int64_t k = 0;

  StatusFlags step() {
    robot.fill(k++, frame);
    return est.update(frame, state);
  }
  void run(int ticks) {
    for (int i = 0; i < ticks; ++i)
      step();
  }
  void expect_accurate(double pos_tol = 2e-3, double angle_tol_deg = 0.1) {
    const SE3 X_WB_true = model::base_pose(robot.q_true);
    EXPECT_LT((state.X_WB.p - X_WB_true.p).norm(), pos_tol);
    EXPECT_LT(angle_between(state.X_WB.R, X_WB_true.R) * 180 / M_PI, angle_tol_deg);
    EXPECT_LT(state.v_WB.norm(), 0.01);
    EXPECT_LT((state.com_W - robot.com_W).norm(), pos_tol);
    EXPECT_TRUE(all_finite(state));
  }
};

TEST_F(Fixture, StandingStillConvergesToTheTrueStateAndOutputsAreConsistent) {
  EXPECT_TRUE(step() & kInitializing);
  run(4000);
  EXPECT_EQ(state.status_flags, kStateOk);
  EXPECT_EQ(state.tick, k - 1);
  EXPECT_EQ(state.stamp_ns, (k - 1) * 1000000);
  expect_accurate(1e-3, 0.1);
  // Feet: contact, pose from the model at the true state, CoP where the wrench put it.
  for (int f = 0; f < kNumFeet; ++f) {
    EXPECT_TRUE(state.feet[f].in_contact);
    EXPECT_LT((state.feet[f].X_WF.p - robot.X_WF[f].p).norm(), 1e-3);
    EXPECT_LT((state.feet[f].cop_W - robot.cop_W[f]).norm(), 1.5e-3) << "foot " << f;
    EXPECT_NEAR(state.feet[f].normal_force, robot.wrench_Fo_F[f][2], 1e-12);
    // Stance foot velocity: zero up to the gyro's per-sample noise times the ~0.9 m lever arm.
    EXPECT_LT(state.feet[f].V_WF.head<3>().norm(), 0.03);
  }
  // Standing still: momentum ~ 0 (l = m vcom).
  EXPECT_LT(state.l_W.norm(), 0.01 * robot.model.total_mass);
  EXPECT_LT((state.l_W - robot.model.total_mass * state.com_velocity_W).norm(), 1e-9);
  // q_model / v_model are the same state in model coordinates.
  EXPECT_LT(
      (state.q_model.tail(robot.model.njoints) - robot.q_true.tail(robot.model.njoints)).norm(),
      1e-15);
  EXPECT_LT((model::base_pose(state.q_model).p - state.X_WB.p).norm(), 1e-12);
  EXPECT_LT((state.X_WB.R * state.v_model.head<3>() - state.v_WB).norm(), 1e-12);
  // The observable gyro bias is found (truth 4, -3, 2 mrad/s).
  EXPECT_LT((state.gyro_bias_I - robot.gyro_bias).norm(), 1.5e-3);
  // The baseline runs alongside and stands still too.
  EXPECT_LT((est.leg_odometry().X_WB().p - model::base_pose(robot.q_true).p).norm(), 1e-3);
}

TEST_F(Fixture, NonFiniteFieldsAreRejectedAndThePreviousStateIsHeld) {
  run(1000);
  const double nan = std::nan("");
  const auto corruptions = std::to_array<std::function<void(SensorFrame&)>>({
      [&](SensorFrame& s) { s.q[3] = nan; },
      [&](SensorFrame& s) { s.qd[0] = INFINITY; },
      [&](SensorFrame& s) { s.tau_measured[5] = nan; },
      [&](SensorFrame& s) { s.imu_q_WI.w() = nan; },
      [&](SensorFrame& s) { s.imu_omega_I.y() = nan; },
      [&](SensorFrame& s) { s.imu_specific_force_I.z() = -INFINITY; },
      [&](SensorFrame& s) { s.foot_wrench_Fo_F[0][2] = nan; },
      [&](SensorFrame& s) { s.foot_wrench_Fo_F[1][4] = nan; },
  });
  for (const auto& corrupt : corruptions) {
    const EstimatorState before = state;
    robot.fill(k++, frame);
    corrupt(frame);
    const std::uint64_t rejected = est.diagnostics().rejected_frames;
    const StatusFlags flags = est.update(frame, state);
    EXPECT_TRUE(flags & kNonFiniteInput);
    EXPECT_EQ(state.tick, frame.tick);
    EXPECT_EQ(est.diagnostics().rejected_frames, rejected + 1);
    EXPECT_GT(std::strlen(est.diagnostics().last_error), 10u);
    EXPECT_TRUE(all_finite(state));
    EXPECT_EQ(state.X_WB.p, before.X_WB.p);  // held
    EXPECT_EQ(state.com_W, before.com_W);
    // The next good frame continues; the rejected one counts as a dropped tick.
    EXPECT_TRUE(step() & kDroppedFrames);
    EXPECT_FALSE(state.status_flags & kNonFiniteInput);
    run(20);
  }
  expect_accurate();
}

TEST_F(Fixture, WrongSizesAreRejectedWithoutTouchingTheOutput) {
  run(10);
  SensorFrame bad = est.make_sensor_frame();
  robot.fill(k++, bad);
  bad.q.resize(3);
  EXPECT_TRUE(est.update(bad, state) & kNonFiniteInput);
  EXPECT_NE(std::string(est.diagnostics().last_error).find("one entry per joint"),
            std::string::npos);
  EstimatorState wrong;  // not made by make_state()
  robot.fill(k++, frame);
  EXPECT_EQ(est.update(frame, wrong), kNonFiniteInput);
  EXPECT_EQ(wrong.q.size(), 0);
}

TEST_F(Fixture, DroppedFramesAreFlaggedCountedAndPropagatedOver) {
  run(1000);
  k += 7;  // ticks k..k+6 never arrive
  EXPECT_TRUE(step() & kDroppedFrames);
  EXPECT_EQ(est.diagnostics().dropped_frames, 7u);
  EXPECT_FALSE(step() & kDroppedFrames);
  run(200);
  expect_accurate();
  // Out of order / repeated tick: rejected, state held, flagged.
  const EstimatorState before = state;
  robot.fill(k - 5, frame);
  EXPECT_TRUE(est.update(frame, state) & kDroppedFrames);
  EXPECT_EQ(state.X_WB.p, before.X_WB.p);
  // A gap longer than max_gap restarts the filter.
  k += 1000;
  EXPECT_TRUE(step() & kInitializing);
  run(1000);
  expect_accurate();
  EXPECT_EQ(state.status_flags, kStateOk);
}

TEST_F(Fixture, FrozenImuIsDetectedAndKinematicsCarryTheStateUntilItRecovers) {
  run(1000);
  robot.fill(k, frame);
  const SensorFrame frozen = frame;
  int flagged_at = -1;
  for (int i = 0; i < 500; ++i) {
    robot.fill(k++, frame);
    frame.imu_q_WI = frozen.imu_q_WI;
    frame.imu_omega_I = frozen.imu_omega_I;
    frame.imu_specific_force_I = frozen.imu_specific_force_I;
    const StatusFlags flags = est.update(frame, state);
    if ((flags & kImuFrozen) && flagged_at < 0) flagged_at = i;
    ASSERT_TRUE(all_finite(state));
  }
  EXPECT_EQ(flagged_at, cfg.frozen_imu_ticks);
  EXPECT_TRUE(est.imu_frozen());
  EXPECT_EQ(est.diagnostics().frozen_imu_ticks, 500u - cfg.frozen_imu_ticks);
  expect_accurate(2e-3, 0.1);
  // Recovery: the flag clears, the filter restarts from the kinematic state.
  EXPECT_FALSE(step() & kImuFrozen);
  EXPECT_TRUE(state.status_flags & kInitializing);
  run(1000);
  EXPECT_EQ(state.status_flags, kStateOk);
  expect_accurate();
}

TEST_F(Fixture, AFootLiftingOffIsDetectedWithHysteresisAndNoContactIsFlagged) {
  run(1000);
  const double mg = robot.model.total_mass * 9.81;
  // Right foot unloads gradually: stays in contact down to 1 % of the weight
  // (contact_detector.hpp: lift-off below it for 2 ticks).
  for (double fz : {0.3 * mg, 0.1 * mg, 0.02 * mg}) {
    robot.fill(k++, frame);
    frame.foot_wrench_Fo_F[0] *= fz / frame.foot_wrench_Fo_F[0][2];
    est.update(frame, state);
    EXPECT_TRUE(state.feet[0].in_contact) << fz;
  }
  for (int tick = 0; tick < 2; ++tick) {
    robot.fill(k++, frame);
    frame.foot_wrench_Fo_F[0].setZero();
    est.update(frame, state);
    EXPECT_EQ(state.feet[0].in_contact, tick == 0) << tick;  // confirmed on the second tick
  }
  EXPECT_TRUE(state.feet[1].in_contact);
  EXPECT_EQ(state.feet[0].cop_W, Vector3::Zero());
  EXPECT_FALSE(state.status_flags & kNoContact);
  // Both feet off (e.g. the robot is lifted): flagged, still finite.
  for (int tick = 0; tick < 2; ++tick) {
    robot.fill(k++, frame);
    frame.foot_wrench_Fo_F[0].setZero();
    frame.foot_wrench_Fo_F[1].setZero();
    est.update(frame, state);
  }
  EXPECT_TRUE(state.status_flags & kNoContact);
  EXPECT_TRUE(all_finite(state));
  // Touch-down again: 1.5 % of the weight (below the 2 % light-contact level) is not contact.
  robot.fill(k++, frame);
  frame.foot_wrench_Fo_F[0] *= 0.015 * mg / frame.foot_wrench_Fo_F[0][2];
  frame.foot_wrench_Fo_F[1].setZero();
  est.update(frame, state);
  EXPECT_FALSE(state.feet[0].in_contact);
  run(1000);
  EXPECT_TRUE(state.feet[0].in_contact && state.feet[1].in_contact);
  expect_accurate(3e-3, 0.2);
}

TEST_F(Fixture, GarbageFramesNeverProduceNonFiniteOutput) {
  std::mt19937 rng(77);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> e(-300, 300);
  for (int i = 0; i < 2000; ++i) {
    robot.fill(k++, frame);
    if (i % 3 == 0) {
      for (int j = 0; j < frame.q.size(); ++j)
        frame.q[j] = u(rng) * std::pow(10.0, e(rng));
      frame.imu_specific_force_I = Vector3(u(rng), u(rng), u(rng)) * std::pow(10.0, e(rng));
      frame.imu_omega_I = Vector3(u(rng), u(rng), u(rng)) * std::pow(10.0, e(rng));
      frame.imu_q_WI.coeffs() = Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng));
      frame.foot_wrench_Fo_F[i % 2] *= std::pow(10.0, e(rng));
    }
    est.update(frame, state);
    ASSERT_TRUE(all_finite(state)) << "frame " << i;
  }
}

TEST_F(Fixture, MovingRobotOutputsEqualTheModelAtTheOutputState) {
  // Joints moving (seeded random q offsets and qd), the base turning and moving (IMU rates,
  // feet alternately lifting): CoM, momentum and foot poses/twists must be those of the model
  // evaluated at the published q_model / v_model (a separate forward kinematics with the base
  // pose, against the estimator's reuse of its base-at-identity kinematics).
  std::mt19937 rng(91);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  model::Data data(robot.model);
  const int n = robot.model.njoints;
  const Eigen::VectorXd q0 = robot.q_true.tail(n);
  int checked = 0;
  for (int i = 0; i < 600; ++i) {
    robot.fill(k++, frame);
    for (int j = 0; j < n; ++j) {
      frame.q[j] = q0[j] + 0.1 * u(rng);
      frame.qd[j] = 2.0 * u(rng);
    }
    frame.imu_omega_I += 0.5 * Vector3(u(rng), u(rng), u(rng));
    frame.imu_specific_force_I += Vector3(u(rng), u(rng), u(rng));
    if ((i / 50) % 3 == 1) frame.foot_wrench_Fo_F[(i / 150) % 2].setZero();
    est.update(frame, state);
    ASSERT_TRUE(all_finite(state));
    if (i < 5) continue;
    model::centroidal_momentum(robot.model, data, state.q_model, state.v_model);
    const double m = robot.model.total_mass;
    const double scale_k = 1.0 + data.hg.head<3>().norm(), scale_l = 1.0 + data.hg.tail<3>().norm();
    EXPECT_LT((state.com_W - data.com).norm(), 1e-12 * (1.0 + data.com.norm()));
    EXPECT_LT((state.com_velocity_W - data.vcom).norm(), 1e-12 * (1.0 + data.vcom.norm()));
    EXPECT_LT((state.k_W - data.hg.head<3>()).norm(), 1e-12 * scale_k);
    EXPECT_LT((state.l_W - data.hg.tail<3>()).norm(), 1e-12 * scale_l);
    EXPECT_LT((state.l_W - m * state.com_velocity_W).norm(), 1e-12 * scale_l);
    for (int f = 0; f < kNumFeet; ++f) {
      const int id = robot.config.feet[f].frame_id;
      const SE3 X = model::frame_placement(robot.model, data, id);
      const Motion V = model::frame_velocity(robot.model, data, id);
      EXPECT_LT((state.feet[f].X_WF.R - X.R).norm(), 1e-12);
      EXPECT_LT((state.feet[f].X_WF.p - X.p).norm(), 1e-12 * (1.0 + X.p.norm()));
      EXPECT_LT((state.feet[f].V_WF - V).norm(), 1e-12 * (1.0 + V.norm()));
    }
    ++checked;
  }
  EXPECT_EQ(checked, 595);
  // The scenario did move: momentum and foot velocities far from zero.
  EXPECT_GT(state.k_W.norm(), 0.1);
}

TEST(EstimatorConfiguration, BadConfigurationsThrowNamingTheProblem) {
  StandingRobot robot;
  const auto message = [&](model::RobotConfig rc, EstimatorConfig c) -> std::string {
    try {
      Estimator e(robot.model, rc, c);
    } catch (const EstimatorError& err) {
      return err.what();
    }
    return "";
  };
  model::RobotConfig rc = robot.config;
  rc.imu_frame = "no_such_link";
  EXPECT_NE(message(rc, {}).find("no_such_link"), std::string::npos);
  rc = robot.config;
  rc.imu_frame = "torso";  // behind the waist joint: taken (the torso IMU tests below)
  EXPECT_EQ(message(rc, {}), "");
  rc = robot.config;
  rc.feet[1].frame = "l_nothing";
  EXPECT_NE(message(rc, {}).find("left foot frame 'l_nothing'"), std::string::npos);
  EstimatorConfig c;
  c.contact_off_fraction = 0.2;
  EXPECT_NE(message(robot.config, c).find("contact thresholds"), std::string::npos);
  c = {};
  c.noise.kinematics = 0.0;
  EXPECT_NE(message(robot.config, c).find("kinematics noise"), std::string::npos);
  c = {};
  c.dt = std::nan("");
  EXPECT_NE(message(robot.config, c).find("dt"), std::string::npos);
  c = {};
  c.frozen_imu_ticks = 1;
  EXPECT_NE(message(robot.config, c).find("frozen_imu_ticks"), std::string::npos);
}


// An IMU behind joints with a latency of d ticks: its pose relative to the base is that of the
// joint positions d frames back, and after dropped frames (a gap) that of the new frame until d
// frames have come again (the old positions are not d ticks old any more). The waist angle
// of each frame is its tick in mrad, so the pose says which frame it came from.
TEST(Estimator, AnImuBehindJointsTakesTheJointPositionsOfItsDelayAndRestartsThemAfterAGap) {
  test::StandingRobot robot;
  model::RobotConfig rc = robot.config;
  rc.imu_frame = "torso";
  rc.imu_frame_id = robot.model.frame_id("torso");
  EstimatorConfig c;
  c.imu_delay_ticks = 3;
  Estimator est(robot.model, rc, c);
  ASSERT_FALSE(est.imu_on_base());
  const int waist = robot.model.joint_index("torso_yaw");
  SensorFrame frame = est.make_sensor_frame();
  EstimatorState out = est.make_state();
  const SE3 X0 = robot.model.frames[rc.imu_frame_id].X_BF;  // the torso frame at yaw 0
  const auto yaw = [&] {  // the torso's yaw relative to the base in est.X_BI()
    const Eigen::Matrix3d R = X0.R.transpose() * est.X_BI().R;
    return std::atan2(R(1, 0), R(0, 0));
  };
  const auto send = [&](std::int64_t tick) {
    robot.fill(tick, frame);
    frame.q[waist] = 1e-3 * static_cast<double>(tick);
    est.update(frame, out);
  };
  for (std::int64_t k = 1; k <= 10; ++k) send(k);
  EXPECT_NEAR(yaw(), 1e-3 * 7, 1e-9);  // 3 frames back
  send(20);                                  // ticks 11..19 dropped
  EXPECT_NEAR(yaw(), 1e-3 * 20, 1e-9);  // the ring starts again
  send(21);
  send(22);
  send(23);
  EXPECT_NEAR(yaw(), 1e-3 * 20, 1e-9);  // 3 frames back again
}
}  // namespace
}  // namespace poise::estimator
