#pragma once
// Robot configuration that sits beside a URDF (deploy/robots/<robot>/robot.yaml): feet, soles,
// IMU frame, joint groups, nominal posture, PD gains, contact defaults. The simulator, estimator
// and controller all read it through load_robot_config(). Schema: deploy/robots/README.md.

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "poise/model/model.hpp"

namespace poise::model {

enum Side : int { kRight = 0, kLeft = 1 };

/// Sole rectangle in the FOOT frame (x forward, y left): the sole plane lies `height` metres
/// below the foot frame origin (the ankle), along the foot frame's -z axis.
struct SoleRectangle {
  double x_min = 0.0, x_max = 0.0, y_min = 0.0, y_max = 0.0;
  double height = 0.0;
  /// The rectangle's centre on the sole plane, in the foot frame (dim 3).
  Eigen::Vector3d center_F() const {
    return {0.5 * (x_min + x_max), 0.5 * (y_min + y_max), -height};
  }
  /// A stand point (x, y) on the sole plane in the foot frame (dim 3); unset: the centre.
  Eigen::Vector3d stand_point_F(const std::optional<Eigen::Vector2d>& p) const {
    return p ? Eigen::Vector3d(p->x(), p->y(), -height) : center_F();
  }
};

struct FootConfig {
  /// The foot frame F the whole stack uses (sole rectangle, F/T wrench, contact): the foot link
  /// itself, or, when the sole is given as an offset and rotation whose F is not the link, a
  /// frame the loader adds to the model ("<link>_foot_poise", see add_config_frames()).
  std::string frame;
  int frame_id = -1;       ///< Model::frame_id(frame) (in a model from load_robot_model())
  std::string link;        ///< URDF link of the foot (robot.yaml feet.<side>.frame)
  /// Frame on the sole plane (same axes as F, `sole.height` below F): a URDF link (robot.yaml
  /// sole_frame: NAME), or "<link>_sole_poise" added by the loader (sole_frame: {offset, rpy}).
  std::string sole_frame;
  int sole_frame_id = -1;
  bool sole_from_offset = false;  ///< sole_frame given as {offset, rpy} in robot.yaml
  SE3 X_link_sole;                ///< sole frame in `link` (both forms)
  SE3 X_link_foot;                ///< F in `link` (identity when F is the link)
  SoleRectangle sole;
  /// Lowest point of the foot's collision primitives (boxes, cylinders, spheres of the links
  /// fixed to the foot body; meshes are not simulated) relative to the sole plane, along the
  /// sole normal, in metres (negative: below the sole plane). NaN when the foot has none.
  double collision_bottom = std::numeric_limits<double>::quiet_NaN();
  /// Where on this sole the robot stands: the balance controller's CoM target is above the
  /// mid-point of its supports' stand points (paper Sec. 4.2 says the sole centres), and a
  /// reference's `over` CoM moves end above them. In the foot frame, on the sole plane (x, y);
  /// robot.yaml `feet.<side>.stand_point` (inside the sole rectangle), unset: the sole centre.
  /// `poise robot init` sets it only when standing over the sole centre needs most of a leg
  /// joint's effort (components/robot_init/README.md, "Standing within the efforts").
  std::optional<Eigen::Vector2d> stand_point;
  /// The stand point on the sole plane, in the foot frame (dim 3): stand_point, else the centre.
  Eigen::Vector3d stand_point_F() const { return sole.stand_point_F(stand_point); }
};

struct JointGains {
  double kp = 0.0;  ///< N m / rad (N / m for prismatic)
  double kd = 0.0;  ///< N m s / rad
};

struct RobotConfig {
  std::string name;
  std::filesystem::path config_path;  ///< the YAML file ("" when parsed from text)
  std::filesystem::path urdf_path;    ///< absolute path of the URDF ("" when parsed from text)
  std::string urdf_xml;               ///< the URDF text the model is built from
  std::string imu_frame;
  int imu_frame_id = -1;
  std::array<FootConfig, 2> feet;              ///< indexed by Side (kRight, kLeft)
  double safety_margin = 0.0;                  ///< m, shrinks the sole rectangle for CoP limits
  double friction_mu = 0.0;                    ///< Coulomb friction coefficient
  double torsional_mu = 0.0;                   ///< torsional friction coefficient mu_tau (m)
  std::vector<std::string> leg_joints;         ///< legs (balance joints)
  std::vector<std::string> upper_body_joints;  ///< arms, torso, head
  std::vector<int> leg_joint_indices;          ///< Model::joint_index of leg_joints
  std::vector<int> upper_body_joint_indices;
  /// Nominal standing configuration (dim nq): joints from the YAML; base upright above the
  /// origin, at the height that puts both soles on z = 0.
  Eigen::VectorXd q_nominal;
  std::vector<JointGains> gains;  ///< per model joint, model joint order (dim njoints)
  /// The robot's forward direction in the base frame (unit, horizontal at the nominal posture):
  /// robot.yaml forward_axis, default +x. Pushes "forward" and the verdict's trunk pitch use it.
  Vector3 forward_axis = Vector3::UnitX();
  /// Warnings found at load (e.g. a sole plane that is not the foot's collision bottom), one
  /// line each; load_robot_config() also prints them once to stderr.
  std::vector<std::string> warnings;
  /// robot.yaml contact.effort_limited_sole (default false): each tick the balance controller
  /// gives the contact optimiser only the part of each sole where a CoP keeps every joint of that
  /// leg within its URDF effort at the foot's measured load (statics of the leg; controller/
  /// momentum/README.md, "Soles limited by the joints' efforts"). `poise robot init` sets it
  /// with stand points (weak joints).
  bool effort_limited_sole = false;
};

/// Adds the frames robot.yaml defines (sole and foot frames given as offset + rotation) to a
/// model built from the configuration's URDF. load_robot_model() does it; call it on a model
/// built otherwise. Idempotent.
void add_config_frames(Model& model, const RobotConfig& config);

/// Loads and validates a robot configuration: builds the URDF model and checks every frame and
/// joint name, the sole geometry against the sole frames, the joint groups (each model joint in
/// exactly one group), gains, and that the nominal posture is within limits with flat feet and
/// the CoM above the feet. Throws ModelError naming the problem.
RobotConfig load_robot_config(const std::filesystem::path& path);

/// Same from text, with no file access: `yaml_text` in the robot.yaml format (its `urdf:` entry,
/// if any, is ignored), the model built from `urdf_text`. `origin` names the source in error
/// messages (e.g. "from poise/robot_description"). Same checks and errors as load_robot_config.
RobotConfig parse_robot_config(const std::string& yaml_text, const std::string& urdf_text,
                               const std::string& origin);

/// The model of a loaded configuration (built from its urdf_xml; from urdf_path if that is empty).
Model load_robot_model(const RobotConfig& config);

/// What differs between two robots (configuration + model), one readable line per difference
/// ("joint 3: 'l_knee' in A, 'l_hip_pitch' in B", "link 'pelvis' mass: 10 in A, 12 in B"),
/// at most `max_lines` (then "... and N more"). `a` and `b` name the two sides. Compares content,
/// not text: robot name, URDF robot name, joint names and order, per-body mass / CoM / inertia /
/// placement / axis / limits, links, IMU frame, feet and sole geometry, contact parameters,
/// joint groups, nominal posture, PD gains; numbers to a relative 1e-9. Paths and the URDF
/// text itself (whitespace, comments, attribute order) are not compared. Empty: the same robot.
std::vector<std::string> robot_differences(const RobotConfig& config_a, const Model& model_a,
                                           const std::string& a, const RobotConfig& config_b,
                                           const Model& model_b, const std::string& b,
                                           std::size_t max_lines = 20);

}  // namespace poise::model
