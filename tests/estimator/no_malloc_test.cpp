// One estimator tick allocates nothing: built against copies of the estimator and model libraries
// compiled with EIGEN_RUNTIME_NO_MALLOC (Eigen asserts on any heap allocation while forbidden);
// the global operator new is counted as well (std:: containers). Covers the normal tick, a
// rejected frame, dropped frames, the frozen-IMU fallback, a planned swing (the corner rule) and
// lift-off, with every support model
// (moving / translating with a short calibration, so their free-contact path runs).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "estimator_test_util.hpp"

static std::atomic<long> g_news{0};
void* operator new(std::size_t n) {
  ++g_news;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace poise::estimator {
namespace {

/// The IMU on the base, or on the torso (behind the waist joint) with a 2-tick latency (the
/// kinematics of the delayed joint positions run every tick).
class EstimatorNoMalloc : public ::testing::TestWithParam<std::tuple<SupportModel, bool>> {};

TEST_P(EstimatorNoMalloc, EveryKindOfTickIsAllocationFree) {
  test::StandingRobot robot;
  EstimatorConfig config;
  config.supports = std::get<0>(GetParam());
  config.moving_support_calibration = 0.05;  // within the warm-up
  config.contact_rest_time = 0.01;           // the resting rule on
  model::RobotConfig rc = robot.config;
  if (std::get<1>(GetParam())) {
    rc.imu_frame = "torso";
    rc.imu_frame_id = robot.model.frame_id("torso");
    config.imu_delay_ticks = 2;
  }
  Estimator est(robot.model, rc, config);
  ASSERT_EQ(est.imu_on_base(), !std::get<1>(GetParam()));
  SensorFrame frame = est.make_sensor_frame();
  EstimatorState state = est.make_state();
  std::int64_t k = 0;
  for (int i = 0; i < 100; ++i) {  // warm up: initialised and converging
    robot.fill(k++, frame);
    est.update(frame, state);
  }
  // Frames prepared beforehand (the generator itself is not under test).
  std::vector<SensorFrame> frames(300, est.make_sensor_frame());
  for (auto& f : frames)
    robot.fill(k++, f);
  frames[10].q[2] = std::nan("");  // rejected
  for (int i = 20; i < 40; ++i)
    frames[i].tick += 5;  // a gap, then steady
  for (int i = 40; i < 300; ++i)
    frames[i].tick += 5;
  for (int i = 50; i < 120; ++i) {  // frozen IMU
    frames[i].imu_omega_I = frames[49].imu_omega_I;
    frames[i].imu_specific_force_I = frames[49].imu_specific_force_I;
    frames[i].imu_q_WI = frames[49].imu_q_WI;
  }
  for (int i = 130; i < 200; ++i)
    frames[i].foot_plan[0] = FootPlan::kSwing;  // the plan's swing (its corner rule) ...
  for (int i = 130; i < 136; ++i)
    frames[i].foot_wrench_Fo_F[0] *= 0.01;  // ... on a light foot (not yet resting: the lift-off
                                            // below still ends its contact by the load)
  for (int i = 150; i < 200; ++i)
    frames[i].foot_wrench_Fo_F[0].setZero();  // lift-off
  for (int i = 200; i < 210; ++i) {           // no contact
    frames[i].foot_wrench_Fo_F[0].setZero();
    frames[i].foot_wrench_Fo_F[1].setZero();
  }

  StatusFlags seen = 0;
  Eigen::internal::set_is_malloc_allowed(false);
  const long before = g_news.load();
  for (const auto& f : frames)
    seen |= est.update(f, state);
  const long news = g_news.load() - before;
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_EQ(news, 0);
  EXPECT_TRUE(seen & kNonFiniteInput);
  EXPECT_TRUE(seen & kDroppedFrames);
  EXPECT_TRUE(seen & kImuFrozen);
  EXPECT_TRUE(seen & kNoContact);
}

INSTANTIATE_TEST_SUITE_P(Supports, EstimatorNoMalloc,
                         ::testing::Combine(::testing::Values(SupportModel::kFixed,
                                                              SupportModel::kMoving,
                                                              SupportModel::kTranslating),
                                            ::testing::Bool()),
                         [](const auto& info) {
                           return std::string(to_string(std::get<0>(info.param))) +
                                  (std::get<1>(info.param) ? "_torso_imu" : "");
                         });

}  // namespace
}  // namespace poise::estimator
