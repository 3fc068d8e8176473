// poise-bench-estimator: one estimator tick on the project humanoid (issue 7: <= 10 us median),
// and its parts. Frames: the robot standing at its nominal posture, IMU with seeded noise.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "poise/estimator/estimator.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"

namespace {

using namespace poise;
using estimator::Vector3;

struct Setup {
  model::RobotConfig config = model::load_robot_config(std::string(POISE_SOURCE_DIR) +
                                                       "/deploy/robots/poise_humanoid/robot.yaml");
  model::Model model = model::load_robot_model(config);
  model::RobotConfig run_config;  ///< config with the IMU where the benchmark puts it
  estimator::Estimator est;
  std::vector<estimator::SensorFrame> frames;

  static estimator::EstimatorConfig with_supports(estimator::SupportModel supports,
                                                  int imu_delay_ticks) {
    estimator::EstimatorConfig c;
    c.supports = supports;
    c.moving_support_calibration = 0.1;  // the free-contact path from tick 100 on
    c.imu_delay_ticks = imu_delay_ticks;
    return c;
  }
  /// imu 0: the robot's (on the pelvis); 1: on the torso, behind the waist joint; 2: the same
  /// with a 1-tick IMU latency allowed for (the kinematics of the delayed joint positions).
  static model::RobotConfig with_imu(model::RobotConfig c, const model::Model& m, int imu) {
    if (imu > 0) {
      c.imu_frame = "torso";
      c.imu_frame_id = m.frame_id("torso");
    }
    return c;
  }

  explicit Setup(estimator::SupportModel supports = estimator::SupportModel::kFixed, int imu = 0)
      : run_config(with_imu(config, model, imu)),
        est(model, run_config, with_supports(supports, imu == 2 ? 1 : 0)) {
    model::Data data(model);
    model::forward_kinematics(model, data, config.q_nominal);
    const model::SE3 X_WI = model::frame_placement(model, data, run_config.imu_frame_id);
    std::mt19937 rng(3);
    std::normal_distribution<double> n(0.0, 1.0);
    for (int i = 0; i < 1000; ++i) {
      estimator::SensorFrame f = est.make_sensor_frame();
      f.q = config.q_nominal.tail(model.njoints);
      f.imu_q_WI = Eigen::Quaterniond(X_WI.R);
      f.imu_omega_I = 0.01 * Vector3(n(rng), n(rng), n(rng));
      f.imu_specific_force_I =
          X_WI.R.transpose() * Vector3(0, 0, 9.81) + 0.06 * Vector3(n(rng), n(rng), n(rng));
      for (int s = 0; s < 2; ++s) {
        f.foot_wrench_Fo_F[s].setZero();
        f.foot_wrench_Fo_F[s][2] = 0.5 * model.total_mass * 9.81;
      }
      frames.push_back(f);
    }
  }
};

// Arguments: support model (0 fixed = the default, 1 moving, 2 translating); IMU (Setup: 0 on
// the pelvis, 1 on the torso behind the waist, 2 the same with a 1-tick latency allowed for).
void BM_EstimatorTick(benchmark::State& st) {
  Setup s(static_cast<estimator::SupportModel>(st.range(0)), static_cast<int>(st.range(1)));
  estimator::EstimatorState out = s.est.make_state();
  std::int64_t k = 0;
  for (auto _ : st) {
    estimator::SensorFrame& f = s.frames[k % s.frames.size()];
    f.tick = k++;
    benchmark::DoNotOptimize(s.est.update(f, out));
  }
  st.counters["joints"] = s.model.njoints;
}
BENCHMARK(BM_EstimatorTick)
    ->Args({0, 0})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Args({0, 1})
    ->Args({0, 2})
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

void BM_FilterPropagate(benchmark::State& st) {
  estimator::InvariantEkf ekf(estimator::ImuNoise{}, Vector3(0, 0, -9.81));
  ekf.reset(estimator::InvariantEkf::Mean{}, estimator::InvariantEkf::Covariance::Identity());
  const Vector3 gyro(0.01, -0.02, 0.03), acc(0.1, 0.2, 9.8);
  for (auto _ : st) {
    ekf.propagate(gyro, acc, 1e-3);
    benchmark::DoNotOptimize(ekf.covariance().data());
  }
}
BENCHMARK(BM_FilterPropagate);

void BM_FilterCorrectTwoFeet(benchmark::State& st) {
  estimator::InvariantEkf ekf(estimator::ImuNoise{}, Vector3(0, 0, -9.81));
  ekf.reset(estimator::InvariantEkf::Mean{}, estimator::InvariantEkf::Covariance::Identity());
  const Vector3 s0(0.0, -0.1, -0.9), s1(0.0, 0.1, -0.9);
  ekf.set_contact(0, true, s0);
  ekf.set_contact(1, true, s1);
  for (auto _ : st) {
    benchmark::DoNotOptimize(ekf.correct(0, s0));
    benchmark::DoNotOptimize(ekf.correct(1, s1));
  }
}
BENCHMARK(BM_FilterCorrectTwoFeet);

}  // namespace

BENCHMARK_MAIN();
