// Estimator accuracy with the realistic sensors (#20 item 1), closed loop in process: the
// estimator's state drives the controller, and is compared every tick with the simulator's
// truth. Three sensor sets on standing (10 s) and the paper's forward push (4 s):
//   ideal     sensors.preset: ideal (exact IMU orientation, white IMU noise only: the old setup)
//   industrial the defaults (simulator/sim/SENSORS.md), IMU orientation from its own filter
//   no-orientation the defaults with imu.orientation: off (all-zero quaternion on the wire)
// Printed figures are quoted in simulator/sim/SENSORS.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "poise/inprocess/in_process_loop.hpp"
#include "poise/model/spatial.hpp"
#include "poise/scenario/scenario.hpp"

namespace poise::inprocess {
namespace {

struct Errors {
  double v_rms = 0.0;        ///< base velocity [m/s]
  double tilt_max_deg = 0.0;  ///< angle between the estimated and true base z axes
  double yaw_final_deg = 0.0;
  double com_drift = 0.0;  ///< max change of the CoM error since the first estimated tick [m]
  bool survived = false;
};

enum class Imu { kIdeal, kIndustrial, kNoOrientation };

Errors run(const std::string& name, double duration, Imu imu,
           const std::string& estimator = "invariant-ekf") {
  scenario::Scenario sc =
      scenario::load_scenario(std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/" + name + ".yaml");
  if (imu == Imu::kIdeal) {
    const std::uint64_t seed = sc.sim.imu.seed;
    sc.sim.imu = sim::ImuNoiseConfig{};
    sc.sim.imu.seed = seed;
    sc.sim.imu.gyro_noise_std = 0.0005;  // what the shipped scenarios had before #20
    sc.sim.imu.accel_noise_std = 0.01;
    sc.sim.encoders = sim::EncoderConfig{};
    sc.sim.foot_ft = sim::ForceTorqueSensorConfig{};
  } else if (imu == Imu::kNoOrientation) {
    sc.sim.imu.orientation = sim::ImuOrientationOutput::kOff;
  }
  LoopOptions opt;
  opt.duration = duration;
  opt.estimator = estimator;
  InProcessLoop loop(sc, opt);
  const int steps = static_cast<int>(std::lround(duration / loop.simulator().dt()));
  Errors e;
  double sq = 0.0;
  int n = 0;
  bool have0 = false;
  Eigen::Vector3d com_err0 = Eigen::Vector3d::Zero();
  for (int k = 0; k < steps; ++k) {
    const sim::GroundTruth truth = loop.truth();  // tick k (the state below is of tick k)
    loop.step();
    if (k < 500) continue;  // the estimator's start-up (kInitializing) and settling
    const controller::RobotState& s = loop.state();
    sq += (s.v_WB - truth.v_WB).squaredNorm();
    ++n;
    const Eigen::Matrix3d R_true = truth.X_WB.linear();
    const double tilt = std::acos(std::clamp(s.X_WB.R.col(2).dot(R_true.col(2)), -1.0, 1.0));
    e.tilt_max_deg = std::max(e.tilt_max_deg, tilt * 180.0 / M_PI);
    const Eigen::Matrix3d dR = s.X_WB.R * R_true.transpose();
    e.yaw_final_deg = std::atan2(dR(1, 0), dR(0, 0)) * 180.0 / M_PI;
    const Eigen::Vector3d err = s.com_W - truth.com_W;
    if (!have0) {
      com_err0 = err;
      have0 = true;
    }
    e.com_drift = std::max(e.com_drift, (err - com_err0).norm());
  }
  e.v_rms = std::sqrt(sq / std::max(1, n));
  e.survived = loop.result().survived;
  static const char* names[] = {"ideal", "industrial", "no-orientation"};
  std::printf(
      "%-28s %-13s %-15s %4.1f s | v RMS %.4f m/s, tilt max %.3f deg, yaw at end %+.3f deg, "
      "CoM drift %.4f m, survived %d\n",
      name.c_str(), estimator.c_str(), names[static_cast<int>(imu)], duration, e.v_rms, e.tilt_max_deg,
      e.yaw_final_deg, e.com_drift, e.survived);
  return e;
}

void expect_usable(const Errors& e) {
  EXPECT_TRUE(e.survived);
  EXPECT_LT(e.v_rms, 0.02);
  EXPECT_LT(e.tilt_max_deg, 1.0);
  EXPECT_LT(std::abs(e.yaw_final_deg), 2.0);
  EXPECT_LT(e.com_drift, 0.02);
}

TEST(SensorAccuracy, Standing) {
  for (Imu imu : {Imu::kIdeal, Imu::kIndustrial, Imu::kNoOrientation})
    expect_usable(run("standing", 10.0, imu));
  // The leg-odometry baseline in the loop, for comparison (printed). With the IMU's orientation
  // it keeps the robot up; without it it integrates the biased gyro (0.1 deg/s turn-on bias):
  // the tilt grows ~1 deg in 10 s and the standing criteria fail (measured, not asserted).
  EXPECT_TRUE(run("standing", 10.0, Imu::kIndustrial, "leg-odometry").survived);
  run("standing", 10.0, Imu::kNoOrientation, "leg-odometry");
}

TEST(SensorAccuracy, ForwardPush) {
  for (Imu imu : {Imu::kIdeal, Imu::kIndustrial, Imu::kNoOrientation})
    expect_usable(run("forward_push_double_support", 4.0, imu));
  for (Imu imu : {Imu::kIndustrial, Imu::kNoOrientation})
    EXPECT_TRUE(run("forward_push_double_support", 4.0, imu, "leg-odometry").survived);
}

}  // namespace
}  // namespace poise::inprocess
