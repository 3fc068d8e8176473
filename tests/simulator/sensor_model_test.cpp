// The realistic sensor models (#20 item 1, simulator/sim/SENSORS.md): IMU orientation output
// (off / filter / truth), sample rate and delay, encoder quantisation and differencing, F/T
// offset and noise, the scenario defaults and clear errors for bad settings.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <vector>
#include <stdexcept>
#include <string>

#include "poise/sim/world.hpp"
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

using test::biped_config;
using test::box_config;

struct Rig {
  Simulator sim;
  SensorFrame s;
  GroundTruth g;
  JointCommand cmd;
  explicit Rig(const SimulatorConfig& c)
      : sim(c), s(sim.make_sensor_frame()), g(sim.make_ground_truth()), cmd(sim.make_command()) {
    sim.read(s, g);
  }
  void run(int steps) {
    for (int k = 0; k < steps; ++k)
      sim.step(cmd, s, g);
  }
};

/// The biped tumbling in free fall: a gyro and accelerometer signal that changes every tick.
SimulatorConfig tumbling(const ImuNoiseConfig& imu) {
  SimulatorConfig cfg = biped_config();
  cfg.world.ground.enabled = false;
  cfg.imu = imu;
  return cfg;
}
void start_tumbling(Rig& r) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation().z() = 2.0;
  r.sim.set_state(X, r.s.q, Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d(0.4, -0.7, 1.1));
  r.sim.read(r.s, r.g);
}

double angle_deg(const Eigen::Matrix3d& R) {
  return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
}

TEST(SimSensorModel, OrientationOffIsAllZerosAndTruthIsExact) {
  ImuNoiseConfig imu;
  imu.orientation = ImuOrientationOutput::kOff;
  Rig off(tumbling(imu));
  start_tumbling(off);
  imu.orientation = ImuOrientationOutput::kTruth;
  Rig truth(tumbling(imu));
  start_tumbling(truth);
  for (int k = 0; k < 50; ++k) {
    off.run(1);
    truth.run(1);
    EXPECT_EQ(off.s.imu_q_WI.coeffs(), Eigen::Vector4d::Zero());
    // same physics, same rates: only the orientation field differs
    EXPECT_EQ(off.s.imu_omega_I, truth.s.imu_omega_I);
  }
  const Eigen::Matrix3d R_WI = truth.sim.frame_pose("imu_link").linear();
  EXPECT_LT(angle_deg(truth.s.imu_q_WI.toRotationMatrix().transpose() * R_WI), 1e-9);
}

TEST(SimSensorModel, AttitudeFilterTiltErrorIsBoundedAndItsYawDriftsWithTheGyroBias) {
  // The box at rest on the ground, the industrial IMU (its biases, noise, misalignment).
  SimulatorConfig cfg = box_config();
  cfg.imu = industrial_mems_imu();
  cfg.imu.seed = 5;
  Rig r(cfg);
  const int n = 20000;  // 20 s
  double tilt_max = 0.0;
  for (int k = 0; k < n; ++k) {
    r.run(1);
    const Eigen::Matrix3d R = r.s.imu_q_WI.toRotationMatrix();
    if (k > 5000)  // after 2.5 filter time constants
      tilt_max = std::max(tilt_max, std::acos(std::min(1.0, R(2, 2))) * 180.0 / M_PI);
  }
  const Eigen::Matrix3d R_true = r.sim.frame_pose("body").linear();
  const Eigen::Matrix3d dR = r.s.imu_q_WI.toRotationMatrix() * R_true.transpose();
  const double yaw_deg = std::atan2(dR(1, 0), dR(0, 0)) * 180.0 / M_PI;
  // Tilt: accelerometer bias / g (0.15 deg) + gyro bias / gain (0.2 deg) + noise: not exact,
  // below 0.6 deg.
  EXPECT_GT(tilt_max, 0.05);
  EXPECT_LT(tilt_max, 0.6);
  // Yaw integrates the z gyro bias 0.05 deg/s (and its walk): ~1.0 deg after 20 s.
  EXPECT_NEAR(yaw_deg, 0.05 * 20.0, 0.25) << yaw_deg;
}

TEST(SimSensorModel, DelayShiftsAndRateHoldsTheSamples) {
  ImuNoiseConfig imu;  // noise-free: the streams are comparable sample by sample
  Rig ref(tumbling(imu));
  start_tumbling(ref);
  imu.delay_ticks = 3;
  Rig delayed(tumbling(imu));
  start_tumbling(delayed);
  imu.delay_ticks = 0;
  imu.rate_hz = 250.0;
  Rig slow(tumbling(imu));
  start_tumbling(slow);
  std::vector<Eigen::Vector3d> w;
  for (int k = 1; k <= 40; ++k) {
    ref.run(1);
    delayed.run(1);
    slow.run(1);
    w.push_back(ref.s.imu_omega_I);
    if (k > 3) {
      EXPECT_EQ(delayed.s.imu_omega_I, w[static_cast<std::size_t>(k - 4)]) << k;
    }
    // 250 Hz: a new sample at ticks 4, 8, ..., held in between
    const int last_sample = k - k % 4;
    if (last_sample > 0) {
      EXPECT_EQ(slow.s.imu_omega_I, w[static_cast<std::size_t>(last_sample - 1)]) << k;
    }
  }
  EXPECT_GT((w.back() - w.front()).norm(), 1e-3);  // the signal did change
}

TEST(SimSensorModel, EncodersQuantiseAndDifference) {
  SimulatorConfig cfg = tumbling(ImuNoiseConfig{});
  cfg.encoders.counts_per_rev = 4096.0;
  Rig r(cfg);
  start_tumbling(r);
  r.cmd.mode = CommandMode::kTorque;
  r.cmd.tau_ff.setConstant(0.5);  // joints move
  const double step = 2.0 * M_PI / 4096.0;
  Eigen::VectorXd prev = r.s.q;
  bool moved = false;
  for (int k = 0; k < 100; ++k) {
    r.run(1);
    for (Eigen::Index i = 0; i < r.s.q.size(); ++i) {
      const double counts = r.s.q[i] / step;
      EXPECT_NEAR(counts, std::round(counts), 1e-6);
      EXPECT_NEAR(r.s.qd[i], (r.s.q[i] - prev[i]) / r.sim.dt(), 1e-9);
    }
    moved = moved || r.s.q != prev;
    prev = r.s.q;
  }
  EXPECT_TRUE(moved);
}

TEST(SimSensorModel, FootForceTorqueHasItsOffsetAndNoise) {
  SimulatorConfig cfg = box_config();
  cfg.foot_ft.force_noise_std = 0.5;
  cfg.foot_ft.force_offset = Eigen::Vector3d(1.0, -2.0, 3.0);
  cfg.imu.seed = 3;
  Rig r(cfg);
  r.run(500);  // settle
  const int n = 4000;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
  Eigen::Vector3d truth = Eigen::Vector3d::Zero();
  for (int k = 0; k < n; ++k) {
    r.run(1);
    const Eigen::Vector3d f = r.s.foot_wrench_Fo_F[0].tail<3>();
    mean += f;
    sq += f.cwiseAbs2();
    truth += r.g.feet[0].X_WF.linear().transpose() * r.g.feet[0].force_W;
  }
  mean /= n;
  truth /= n;
  const Eigen::Vector3d sd = (sq / n - mean.cwiseAbs2()).cwiseSqrt();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(mean[i] - truth[i], cfg.foot_ft.force_offset[i], 5 * 0.5 / std::sqrt(n));
    EXPECT_NEAR(sd[i], 0.5, 0.05);
  }
}

TEST(SimSensorModel, SameSeedSameStreamOtherSeedOther) {
  SimulatorConfig cfg = box_config();
  cfg.imu = industrial_mems_imu();
  cfg.encoders = industrial_encoder();
  cfg.foot_ft = industrial_foot_ft();
  Rig a(cfg), b(cfg);
  cfg.imu.seed = 2;
  Rig c(cfg);
  a.run(100);
  b.run(100);
  c.run(100);
  EXPECT_EQ(a.s.imu_omega_I, b.s.imu_omega_I);
  EXPECT_EQ(a.s.foot_wrench_Fo_F[0], b.s.foot_wrench_Fo_F[0]);
  EXPECT_NE(a.s.imu_omega_I, c.s.imu_omega_I);
}

TEST(SimSensorModel, BadSettingsNameTheKey) {
  const auto error_of = [](SimulatorConfig cfg) -> std::string {
    try {
      Simulator sim(cfg);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  };
  SimulatorConfig cfg = box_config();
  cfg.imu.gyro_noise_density = std::nan("");
  EXPECT_NE(error_of(cfg).find("imu.gyro_noise_density"), std::string::npos);
  cfg = box_config();
  cfg.imu.accel_bias_walk = -1.0;
  EXPECT_NE(error_of(cfg).find("imu.accel_bias_walk"), std::string::npos);
  cfg = box_config();
  cfg.imu.rate_hz = 2000.0;  // above 1 / dt
  EXPECT_NE(error_of(cfg).find("imu.rate_hz"), std::string::npos);
  cfg = box_config();
  cfg.imu.delay_ticks = -1;
  EXPECT_NE(error_of(cfg).find("imu.delay_ticks"), std::string::npos);
  cfg = box_config();
  cfg.encoders.counts_per_rev = -4096.0;
  EXPECT_NE(error_of(cfg).find("encoders.counts_per_rev"), std::string::npos);
  cfg = box_config();
  cfg.foot_ft.force_offset.x() = std::numeric_limits<double>::infinity();
  EXPECT_NE(error_of(cfg).find("foot_ft.force_offset"), std::string::npos);
}

TEST(SimSensorModel, ScenarioDefaultsAreIndustrialAndKeysAreChecked) {
  const std::string base =
      "name: t\nduration: 1\nrobot:\n  config: deploy/robots/poise_humanoid/robot.yaml\n";
  const std::filesystem::path dir(POISE_SOURCE_DIR);
  const World d = parse_world(base, dir, "t.yaml");
  EXPECT_EQ(d.sim.imu.orientation, ImuOrientationOutput::kFilter);
  EXPECT_EQ(d.sim.imu.gyro_noise_density, industrial_mems_imu().gyro_noise_density);
  EXPECT_EQ(d.sim.encoders.counts_per_rev, industrial_encoder().counts_per_rev);
  EXPECT_EQ(d.sim.foot_ft.force_noise_std, industrial_foot_ft().force_noise_std);
  const World ideal = parse_world(
      base + "sensors: {preset: ideal, imu: {orientation: off, delay_ticks: 2}}\n", dir, "t.yaml");
  EXPECT_EQ(ideal.sim.imu.gyro_noise_density, 0.0);
  EXPECT_EQ(ideal.sim.imu.orientation, ImuOrientationOutput::kOff);
  EXPECT_EQ(ideal.sim.imu.delay_ticks, 2);
  EXPECT_EQ(ideal.sim.encoders.counts_per_rev, 0.0);
  const auto error_of = [&](const std::string& sensors) -> std::string {
    try {
      parse_world(base + sensors, dir, "t.yaml");
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error_of("sensors: {imu: {gyro_noise: 1}}\n").find("sensors.imu.gyro_noise"),
            std::string::npos);
  EXPECT_NE(error_of("sensors: {imu: {orientation: maybe}}\n").find("sensors.imu.orientation"),
            std::string::npos);
  EXPECT_NE(error_of("sensors: {preset: perfect}\n").find("sensors.preset"), std::string::npos);
  EXPECT_NE(error_of("sensors: {encoders: {counts_per_rev: -1}}\n")
                .find("sensors.encoders.counts_per_rev"),
            std::string::npos);
  EXPECT_NE(error_of("sensors: {imu: {delay_ticks: 1.5}}\n").find("sensors.imu.delay_ticks"),
            std::string::npos);
  EXPECT_NE(error_of("sensors: {foot_ft: {force_offset: [1, .nan, 0]}}\n")
                .find("sensors.foot_ft.force_offset"),
            std::string::npos);
}

}  // namespace
}  // namespace poise::sim
