#pragma once
// The simulator's world description: the part of a scenario file (YAML; schema in
// deploy/scenarios/README.md) that the simulator owns: robot, world, initial posture,
// disturbances, sensors, solver, duration and success criteria of one experiment, plus a monitor
// that turns the ground truth of a run into the verdict quantities (CoM error, foot slip,
// non-foot contacts). The sections that configure the other components (dds, estimator, contact,
// controller) belong to the scenario format, poise::scenario (deploy/scenario), and are skipped
// here.

#include <Eigen/Core>
#include <filesystem>
#include <cstdint>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include "poise/sim/sim_config.hpp"
#include "poise/sim/types.hpp"

namespace poise::sim {

struct SuccessCriteria {
  double com_error_max_m = std::numeric_limits<double>::infinity();    ///< over the whole run
  double com_error_final_m = std::numeric_limits<double>::infinity();  ///< at the end
  double foot_slip_max_m = std::numeric_limits<double>::infinity();    ///< of a supporting foot
  /// Largest tilt of a supporting foot against its support [deg] (inf: not checked, the
  /// default: a foot rolled onto its toe is one of the ways a push is ridden out).
  double foot_tilt_max_deg = std::numeric_limits<double>::infinity();
  double recovery_time_s = std::numeric_limits<double>::infinity();    ///< after the last push
  bool allow_non_foot_contacts = false;  ///< a knee / hand / trunk touching = fall
  double min_base_height_m = 0.0;        ///< base below this height = fall
  /// Distributed runs (`poise run`): ticks the robot's safety layer may spend damping (no joint
  /// command for its whole hold time) before the run fails. A damping tick is a lost tick of
  /// balance control.
  long long max_damping_ticks = 0;
};

/// The world of one experiment, as the simulator reads it from a scenario file.
struct World {
  std::string name;
  std::string description;
  std::filesystem::path file;          ///< the YAML file (absolute)
  std::filesystem::path robot_config;  ///< robot configuration YAML ("" when inline)
  double duration = 0.0;               ///< [s]
  std::string support = "double";      ///< initial support: double | left | right
  SimulatorConfig sim;                 ///< robot, world, initial state, pushes, noise, solver
  SuccessCriteria success;
};

/// Reads a scenario file's text (at most 16 MB). Throws std::runtime_error naming the file.
std::string read_scenario_text(const std::filesystem::path& path);

/// Loads and validates the world part of a scenario file. Relative paths inside it are resolved
/// against the scenario's directory first, then against the source tree. Throws
/// std::runtime_error naming the file and the offending key.
World load_world(const std::filesystem::path& path);

/// Same from YAML text; `base_dir` resolves relative paths, `what` names the source in errors.
World parse_world(const std::string& yaml_text, const std::filesystem::path& base_dir,
                  const std::string& what = "scenario");

/// Accumulates the verdict quantities of a run from its ground truth (one update per tick).
/// CoM error: horizontal distance between the CoM and its reference, the reference being the
/// initial offset from the centroid of the support feet of the CoM the robot's description puts
/// there (GroundTruth::model_com_shift_W: with a `reality:` section the robot's own CoM starts
/// elsewhere, and standing there is an error), carried along with that centroid
/// (so moving supports are not counted as error), plus the CoM target shift of the run's
/// balance references (set_com_target_shift: a step in place's deliberate move over one foot is
/// not counted as error either). Relative to the support each foot stands on
/// (platform or ground), horizontally, while the foot is in contact:
///   foot slip (the criterion): largest displacement of the sole's centre point (on the sole
///     plane; without a sole in the robot config, the point of the sole plane below the foot
///     frame's origin, the plane taken from the CoP of the first contact with a load) from
///     where it was at the start. It counts a foot sliding or twisting on its support and one
///     lifted and set down elsewhere; a foot rolled onto an edge moves that point only by the
///     edge's distance x (1 - cos tilt) (0.9 mm for a toe 11 cm ahead of the centre at 7.5 deg).
///   foot displacement (informational): largest displacement of the foot frame (the ankle) from
///     where it stood: the slip criterion before 2026-12-04. A foot rolled onto its toe moves its
///     ankle forward by ~ ankle height x sin(tilt) without sliding (11 mm at 7.5 deg).
///   foot slide (informational): the sole point under the CoP against where that point of the
///     sole was when the current contact began (a landing elsewhere is not a slide).
///   foot tilt (criterion when success.foot_tilt_max_deg is set): largest angle between a
///     supporting foot's sole normal and its support's.
class ScenarioMonitor {
 public:
  struct Result {
    double com_error_max_m = 0.0;
    double com_error_final_m = 0.0;
    double foot_slip_max_m = 0.0;
    double foot_slide_max_m = 0.0;         ///< see the class comment
    double foot_displacement_max_m = 0.0;  ///< see the class comment
    double foot_tilt_max_deg = 0.0;        ///< see the class comment
    int non_foot_contacts = 0;  ///< ticks with at least one non-foot contact
    double min_base_height_m = std::numeric_limits<double>::infinity();
    double last_recovery_time_s = 0.0;  ///< time after the last push until the CoM error stayed
                                        ///< below com_error_final_m (inf if it never did)
    /// Largest |pitch| and |roll| of the floating base (the robot's trunk link) in W over the
    /// run [deg] (ZYX angles): a robot that "survives" bent far over shows it.
    double trunk_pitch_max_deg = 0.0;
    double trunk_roll_max_deg = 0.0;
    bool survived = false;
  };

  /// `platform_of_foot[f]` = index of the platform under foot f, or -1 for the ground.
  ScenarioMonitor(const World& world, std::vector<int> platform_of_foot);
  void update(const GroundTruth& truth);
  /// The horizontal CoM target shift the balance references ask for at the next update
  /// (ReferenceComShift::due); zero until set.
  void set_com_target_shift(const Eigen::Vector2d& shift_W) noexcept { com_shift_ = shift_W; }
  /// Evaluates the success criteria on what was seen so far. Allocates nothing: fit for the
  /// simulator's 1 kHz loop (progress lines).
  Result result() const;
  /// The success criteria that failed so far, one readable item each ("com_error_max 0.182 m >
  /// 0.150 m"); empty when survived. Allocates: for the result file and the verdict only.
  std::vector<std::string> failed_criteria() const;

 private:
  World scenario_;
  std::vector<int> platform_of_foot_;
  std::vector<int> support_feet_;
  bool initialised_ = false;
  Eigen::Vector2d com_offset_ = Eigen::Vector2d::Zero();
  std::vector<Eigen::Isometry3d> foot_in_support_0_;  ///< per foot: its pose at the start
  /// Per foot: its pose in its support's frame when the current contact began (foot slide).
  std::vector<Eigen::Isometry3d> contact_start_X_SF_;
  std::vector<std::uint8_t> in_contact_before_;
  /// Per foot: the sole point whose displacement is the slip, in F (the sole's centre).
  std::vector<Eigen::Vector3d> sole_point_F_;
  std::vector<std::uint8_t> sole_known_;
  double last_push_end_ = 0.0;
  double last_bad_time_ = 0.0;
  double time_ = 0.0;
  Result r_;
  Eigen::Vector2d com_shift_ = Eigen::Vector2d::Zero();
};

/// The CoM target shifts a run's balance references (poise/balance_reference) ask for, by tick,
/// for ScenarioMonitor: the simulator does not see the controller, so it follows the references
/// as poise-controller applies them (at tick k the one with the largest header tick <= k, tick 0
/// at once, later ones held). The shift is the horizontal difference between the applied
/// reference's com_W and the com_W of the first reference that had a CoM target (the references
/// are in the estimator's frame: differences of them are what the simulator can compare); zero
/// without a CoM target. put() from a subscriber thread, due() from the loop; no allocation
/// after construction; a reference beyond the capacity drops the oldest held (counted).
class ReferenceComShift {
 public:
  explicit ReferenceComShift(std::size_t capacity = 1024);
  void put(std::uint64_t tick, bool has_com_target, const Eigen::Vector3d& com_W) noexcept;
  /// The shift applied at tick k (references with tick <= k taken).
  Eigen::Vector2d due(std::uint64_t k) noexcept;
  std::uint64_t overflows() const noexcept;
  /// References with a CoM target that is not finite: not taken (the shift stays as it was).
  std::uint64_t rejected() const noexcept;

 private:
  struct Entry {
    std::uint64_t tick = 0;
    bool has_com_target = false;
    Eigen::Vector3d com_W = Eigen::Vector3d::Zero();
  };
  mutable std::mutex mutex_;
  std::vector<Entry> ring_;  // held references in arrival order (ticks non-decreasing)
  std::size_t head_ = 0, size_ = 0;
  std::uint64_t overflows_ = 0, rejected_ = 0;
  bool have_base_ = false;
  Eigen::Vector2d base_ = Eigen::Vector2d::Zero(), shift_ = Eigen::Vector2d::Zero();
};

/// Index of the platform that supports each foot (by PlatformConfig::foot), -1 = ground.
std::vector<int> platforms_of_feet(const World& world);

}  // namespace poise::sim
