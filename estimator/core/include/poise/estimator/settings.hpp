#pragma once
// The estimator's settings that a user gives, declared once: their allowed values, units and one
// line each. poise-estimator's command line (--supports, --estimator, --stance-rate-hz, ...) and a
// scenario's `estimator:` section (deploy/scenario estimator_section.cpp, the page
// estimator/CONFIG.md) both check against these; the defaults are EstimatorConfig's.
#include <array>
#include <string_view>

namespace poise::estimator {

/// A numeric setting: inclusive bounds, unit, what a special value means, one line.
struct NumberSetting {
  std::string_view name;  ///< the scenario key; the command-line option is --name-with-dashes
  double lo, hi;
  std::string_view unit;
  std::string_view note;
  std::string_view doc;
};

/// A setting that is one of a few names.
struct NameSetting {
  std::string_view name;
  std::array<std::string_view, 3> choices;  ///< "" unused
  std::string_view doc;
};

inline constexpr NameSetting kSupportsSetting{
    "supports", {"fixed", "moving", "translating"},
    "what the feet stand on: static ground, supports that move in W, or that move without "
    "turning (estimator.hpp SupportModel)"};

inline constexpr NameSetting kTypeSetting{
    "type", {"invariant-ekf", "leg-odometry", ""},
    "which estimate the state carries: the contact-aided invariant EKF or the leg-odometry "
    "baseline"};

inline constexpr NumberSetting kStanceRateSetting{
    "stance_rate_hz", 0.0, 1.0e4, "Hz", "0: the gyro alone",
    "cut-off of the gyro / stance-kinematics complementary filter of the published angular "
    "velocity"};

inline constexpr NumberSetting kContactFtNoiseSetting{
    "contact_ft_noise", 0.0, 1.0e4, "N", "0: the light-touch rule off",
    "the contact detector's light-touch rule: the foot F/T's normal-force noise, 1 sigma"};

inline constexpr NumberSetting kContactRestTimeSetting{
    "contact_rest_time", 0.0, 10.0, "s", "the contact detector's resting rule; 0: off",
    "a foot that stayed below 2 % of the weight this long with its sole still keeps its contact"};

inline constexpr NumberSetting kImuDelayTicksSetting{
    "imu_delay_ticks", 0.0, 100.0, "ticks", "the IMU's latency, used with an IMU behind joints",
    "the IMU's output latency the estimator allows for with an IMU behind joints"};

}  // namespace poise::estimator
