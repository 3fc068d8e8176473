#pragma once
// Scenario files (YAML; schema in deploy/scenarios/README.md): one experiment, composed. The
// simulator's world description (poise::sim::World: robot, world, initial posture, disturbances,
// sensors, duration, success criteria) plus the sections that configure the other components for
// this experiment: DDS vendors, the state estimator, the contact optimiser and the controller.
// Composition (deploy/): `poise run`, `poise launch`, the in-process loop and `poise envelope`
// read it; the areas do not.

#include <array>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "poise/sim/world.hpp"

namespace poise::scenario {

/// Optional hints for `poise run` (which DDS vendor each component uses).
struct DdsHints {
  std::string vendor;  ///< default vendor for every component ("" = launcher default)
  std::vector<std::pair<std::string, std::string>> per_component;  ///< component -> vendor
};

/// Optional setting of the state estimator for this world (`estimator:` in the file; its keys,
/// defaults and ranges: one table, estimator_section.cpp, and estimator/CONFIG.md): which
/// estimator publishes the state, whether the feet stand on supports that move in W (the
/// estimator's SupportModel; see estimator.hpp) and the height of what the soles stand on at the
/// start. A property of the deployment the user knows, not information from the simulation.
struct EstimatorHints {
  std::string type = "invariant-ekf";  ///< "invariant-ekf" | "leg-odometry"
  std::string supports = "fixed";      ///< "fixed" | "moving" | "translating"
  /// `ground_height: H`: z of the ground under both soles at the start [m]; NaN: not given
  /// (`poise run` then uses the ground plane's height, or derives per-foot heights for a world
  /// with platforms).
  double ground_height = std::numeric_limits<double>::quiet_NaN();
  /// `support_height: {FOOT: H, ...}`: z of each named foot's sole point at the start [m]
  /// (feet on supports of their own); empty: not given.
  std::vector<std::pair<std::string, double>> support_height;
  /// `stance_rate_hz: F`: the cut-off of the estimator's gyro / stance-kinematics complementary
  /// filter (EstimatorConfig::stance_rate_filter_hz; 0: the gyro alone); NaN: the default.
  double stance_rate_hz = std::numeric_limits<double>::quiet_NaN();
  /// `contact_ft_noise: N`: the contact detector's light-touch rule, the F/T normal-force noise
  /// (EstimatorConfig::contact_ft_noise; 0: off); NaN: not given (estimator_contact_ft_noise()).
  double contact_ft_noise = std::numeric_limits<double>::quiet_NaN();
  /// `contact_rest_time: S`: the contact detector's resting rule (EstimatorConfig::
  /// contact_rest_time; 0: off); NaN: not given (the estimator's default).
  double contact_rest_time = std::numeric_limits<double>::quiet_NaN();
  /// `imu_delay_ticks: N`: the IMU's latency the estimator allows for with an IMU behind joints
  /// (EstimatorConfig::imu_delay_ticks); -1: not given (estimator_imu_delay_ticks()).
  int imu_delay_ticks = -1;
};

/// The keys of a scenario's `estimator:` section, in the table's order.
std::vector<std::string_view> estimator_section_keys();
/// The reference page estimator/CONFIG.md: one Markdown table row per `estimator:` key (key,
/// default, unit, allowed values, one line), from the table the parser uses.
std::string estimator_section_markdown();

/// A scenario: the simulator's world (name, duration, robot_config, sim, success, support...)
/// and the configuration of the other components.
struct Scenario : sim::World {
  DdsHints dds;
  EstimatorHints estimator;
  /// `contact: {method: ...}`: the contact optimiser `poise run` uses for this scenario unless
  /// --contact-method says otherwise ("" = the launcher's default, sequential).
  std::string contact_method;
  /// `controller:` section: the controller configuration (same keys as the controller's YAML file,
  /// controller/momentum/config/balance_controller.yaml), kept as YAML text and validated by the
  /// controller's parser (poise::controller::parse_controller_config) when a run starts; "" = none.
  std::string controller_yaml;
  /// `reference: FILE`: a balance-reference trajectory (deploy/scenarios/references/README.md)
  /// played during the run: by the in-process loop, and by a poise-reference process that
  /// `poise run` starts. Resolved like every path of the file (absolute); empty: none.
  std::filesystem::path reference;
};

/// The rule for a scenario's name, and a deployment's (poise::launch::load_deployment): it names
/// files under results/, so it must be a plain file name: 1 to 100 of A-Z a-z 0-9 . _ -, not ".",
/// no "..".
bool is_plain_name(const std::string& name);
/// Why `name` breaks that rule, in words ("" when it does not).
std::string plain_name_problem(const std::string& name);

/// Loads and validates a scenario file. Relative paths inside it are resolved against the
/// scenario's directory first, then against the source tree. Throws std::runtime_error naming
/// the file and the offending key.
Scenario load_scenario(const std::filesystem::path& path);

/// Same from YAML text; `base_dir` resolves relative paths, `what` names the source in errors.
Scenario parse_scenario(const std::string& yaml_text, const std::filesystem::path& base_dir,
                        const std::string& what = "scenario");

/// Where the state estimator starts the soles (`poise-estimator --ground-height` /
/// `--support-heights`), resolved from the scenario by `poise run` (both forms):
///  1. `estimator.support_height` when given (named feet; others: ground_height);
///  2. else `estimator.ground_height` when given;
///  3. else, in a world with platforms, the height of each foot's sole point (foot frame origin
///     moved sole.height down its z axis) at t = 0 as the simulator places the robot and the
///     platforms before its first step: the scenario's geometry, not ground truth of a run;
///  4. else the ground plane's height.
/// Feet in the estimator's order: 0 = the foot named "right", 1 = "left" (robot.config scenarios).
struct EstimatorStart {
  double ground_height = 0.0;
  /// NaN where not given (that foot uses ground_height).
  std::array<double, 2> support_height{std::numeric_limits<double>::quiet_NaN(),
                                       std::numeric_limits<double>::quiet_NaN()};
  bool per_foot = false;  ///< support_height has at least one entry
  std::string source;     ///< "scenario support_height" | "scenario ground_height" | "platforms at t = 0" | "ground plane"
};
EstimatorStart estimator_start(const Scenario& scenario);

/// The F/T noise the estimator's contact detector is given for this scenario, in both modes: the
/// estimator section's contact_ft_noise; without it the simulated F/T's force_noise_std when > 0
/// (an estimator configured with its sensor's figure, as on hardware); else NaN: the estimator's
/// own default (EstimatorConfig::contact_ft_noise).
double estimator_contact_ft_noise(const Scenario& scenario);

/// The IMU latency the estimator is given for this scenario, in both modes: the estimator
/// section's imu_delay_ticks; without it the simulated IMU's delay_ticks (an estimator
/// configured with its sensor's figure, as on hardware).
int estimator_imu_delay_ticks(const Scenario& scenario);

}  // namespace poise::scenario
