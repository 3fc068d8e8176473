#pragma once
// Scenario files (YAML; schema in deploy/scenarios/README.md): robot, world, initial posture,
// disturbances, duration and success criteria of one experiment, plus a monitor that turns the
// ground truth of a run into the verdict quantities (CoM error, foot slip, non-foot contacts).

#include <array>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "poise/sim/sim_config.hpp"
#include "poise/sim/types.hpp"

namespace poise::sim {

struct SuccessCriteria {
  double com_error_max_m = std::numeric_limits<double>::infinity();    ///< over the whole run
  double com_error_final_m = std::numeric_limits<double>::infinity();  ///< at the end
  double foot_slip_max_m = std::numeric_limits<double>::infinity();    ///< of a supporting foot
  double recovery_time_s = std::numeric_limits<double>::infinity();    ///< after the last push
  bool allow_non_foot_contacts = false;  ///< a knee / hand / trunk touching = fall
  double min_base_height_m = 0.0;        ///< base below this height = fall
  /// Distributed runs (`poise run`): ticks the robot's safety layer may spend damping (no joint
  /// command for its whole hold time) before the run fails. A damping tick is a lost tick of
  /// balance control.
  long long max_damping_ticks = 0;
};

/// Optional hints for `poise run` (which DDS vendor each component uses).
struct DdsHints {
  std::string vendor;  ///< default vendor for every component ("" = launcher default)
  std::vector<std::pair<std::string, std::string>> per_component;  ///< component -> vendor
};

/// Optional setting of the state estimator for this world (`estimator:` in the file): which
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
};

struct Scenario {
  std::string name;
  std::string description;
  std::filesystem::path file;          ///< the YAML file (absolute)
  std::filesystem::path robot_config;  ///< robot configuration YAML ("" when inline)
  double duration = 0.0;               ///< [s]
  std::string support = "double";      ///< initial support: double | left | right
  SimulatorConfig sim;                 ///< robot, world, initial state, pushes, noise, solver
  SuccessCriteria success;
  DdsHints dds;
  EstimatorHints estimator;
  /// `contact: {method: ...}`: the contact optimiser `poise run` uses for this scenario unless
  /// --contact-method says otherwise ("" = the launcher's default, sequential).
  std::string contact_method;
  /// `controller:` section: the controller configuration (same keys as the controller's YAML file,
  /// controller/momentum/config/balance_controller.yaml), kept as YAML text and validated by the
  /// controller's parser (poise::controller::parse_controller_config) when a run starts; "" = none.
  std::string controller_yaml;
};

/// Loads and validates a scenario file. Relative paths inside it are resolved against the
/// scenario's directory first, then against the source tree. Throws std::runtime_error naming
/// the file and the offending key.
Scenario load_scenario(const std::filesystem::path& path);

/// Same from YAML text; `base_dir` resolves relative paths, `what` names the source in errors.
Scenario parse_scenario(const std::string& yaml_text, const std::filesystem::path& base_dir,
                        const std::string& what = "scenario");

/// Accumulates the verdict quantities of a run from its ground truth (one update per tick).
/// CoM error: horizontal distance between the CoM and its reference, the reference being the
/// initial CoM offset from the centroid of the support feet, carried along with that centroid
/// (so moving supports are not counted as error). Foot slip: largest displacement of a
/// supporting foot relative to the support it stands on (platform or ground), while in contact.
class ScenarioMonitor {
 public:
  struct Result {
    double com_error_max_m = 0.0;
    double com_error_final_m = 0.0;
    double foot_slip_max_m = 0.0;
    int non_foot_contacts = 0;  ///< ticks with at least one non-foot contact
    double min_base_height_m = std::numeric_limits<double>::infinity();
    double last_recovery_time_s = 0.0;  ///< time after the last push until the CoM error stayed
                                        ///< below com_error_final_m (inf if it never did)
    /// Largest |pitch| and |roll| of the floating base (the robot's trunk link) in W over the
    /// run [deg] (ZYX angles): a robot that "survives" bent far over shows it.
    double trunk_pitch_max_deg = 0.0;
    double trunk_roll_max_deg = 0.0;
    bool survived = false;
    /// The success criteria that failed, one readable item each ("com_error_max 0.182 m > 0.150
    /// m"); empty when survived.
    std::vector<std::string> failed;
  };

  /// `platform_of_foot[f]` = index of the platform under foot f, or -1 for the ground.
  ScenarioMonitor(const Scenario& scenario, std::vector<int> platform_of_foot);
  void update(const GroundTruth& truth);
  /// Evaluates the success criteria on what was seen so far.
  Result result() const;

 private:
  Scenario scenario_;
  std::vector<int> platform_of_foot_;
  std::vector<int> support_feet_;
  bool initialised_ = false;
  Eigen::Vector2d com_offset_ = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector3d> foot_in_support_0_;
  double last_push_end_ = 0.0;
  double last_bad_time_ = 0.0;
  double time_ = 0.0;
  Result r_;
};

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

/// Index of the platform that supports each foot (by PlatformConfig::foot), -1 = ground.
std::vector<int> platforms_of_feet(const Scenario& scenario);

}  // namespace poise::sim
