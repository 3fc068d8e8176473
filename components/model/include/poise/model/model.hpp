#pragma once
// The robot model: built once from a URDF, never changed by an algorithm (Pinocchio style).
//
// ============================ GENERALIZED COORDINATES (others depend on this) ====================
// The URDF root link is the floating base B ("body 0").
//
//   q (dim nq = 7 + n) = [ p_WB (3) ; quat_WB (4) stored x, y, z, w ; joint positions (n) ]
//   v (dim nv = 6 + n) = [ v_B (3) ; omega_B (3) ; joint velocities (n) ]
//
//  - p_WB: position of the base link origin in world; quat_WB: unit quaternion of the base
//    orientation, stored in Eigen's coefficient order (x, y, z, w) so that
//    Eigen::Map<const Eigen::Quaterniond>(q.data() + 3) is the rotation R_WB. Quaternions must be
//    unit; algorithms do not normalise them.
//  - Base velocity (Pinocchio's convention): the base twist expressed in the BASE frame, linear
//    part first: v_B = R_WB^T * (d/dt p_WB) and omega_B = R_WB^T * omega_WB.
//    Use base_velocity_from_world() / base_velocity_to_world() to convert from/to world-frame
//    velocities of the base origin.
//  - The base acceleration a[0:6] is the time derivative of v[0:6] (body-frame components).
//  - Generalized forces tau[0:6] are the base wrench [f_B; tau_B] in the base frame about the base
//    origin, dual to v[0:6].
//  - Joint order: depth-first pre-order of the kinematic tree from the root; the children of a
//    link are visited in alphabetical order of their joint names. Joint j has q index 7 + j and
//    v index 6 + j; body index j + 1. Fixed joints have no coordinates (merged, see below).
// ================================================================================================
//
// Bodies: body 0 is the base; body j+1 is moved by joint j. A link attached through a fixed joint
// is merged into the nearest moving ancestor body (its inertia is added there) and stays
// addressable as a frame. Every URDF link is a frame; frame_id(name) finds it.

#include <Eigen/Core>
#include <filesystem>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "poise/model/inertia.hpp"
#include "poise/model/spatial.hpp"

namespace poise::model {

/// Thrown for every configuration-time error (bad URDF, unknown name, wrong size).
class ModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class JointType { kFloating, kRevolute, kContinuous, kPrismatic };

/// Limits of one joint as read from the URDF (continuous: position limits are +-infinity).
struct JointLimits {
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  double velocity = std::numeric_limits<double>::infinity();
  double effort = std::numeric_limits<double>::infinity();
};

/// A frame attached to a body: every URDF link is one.
struct Frame {
  std::string name;      ///< URDF link name
  int body = 0;          ///< body the frame is rigidly attached to
  SE3 X_BF;              ///< pose of the frame in its body
  bool is_body = false;  ///< true when this link is the body itself (not merged by a fixed joint)
};

struct Model {
  std::string name;  ///< URDF robot name
  int nq = 7;        ///< dim q
  int nv = 6;        ///< dim v
  int njoints = 0;   ///< n: number of actuated (1-DoF) joints
  int nbodies = 1;   ///< n + 1

  // ---- per body (dim nbodies); body 0 is the floating base -------------------------------------
  std::vector<int> parent;            ///< parent body (-1 for the base)
  std::vector<JointType> joint_type;  ///< joint moving the body
  std::vector<SE3> X_parent_joint;    ///< pose of the body frame in its parent body, at q = 0
  std::vector<Vector3> axis;          ///< joint axis in the body frame (unit)
  std::vector<int> axis_id;      ///< 0/1/2 if the axis is exactly +x/+y/+z, else -1 (fast paths)
  std::vector<Inertia> inertia;  ///< body inertia incl. merged fixed links, body frame
  std::vector<std::string> body_name;  ///< link name of the body
  /// Velocity indices (ascending) of the DoFs that move the body: the base's 6, then the joints
  /// on the path from the root. Used by Jacobians.
  std::vector<std::vector<int>> support;
  /// Last body of the subtree rooted at each body (depth-first order makes subtrees contiguous).
  std::vector<int> subtree_end;

  // ---- per joint (dim njoints) -----------------------------------------------------------------
  std::vector<std::string> joint_names;
  std::vector<JointLimits> limits;
  std::vector<double> damping;   ///< URDF <dynamics damping>
  std::vector<double> friction;  ///< URDF <dynamics friction>

  // ---- frames ----------------------------------------------------------------------------------
  std::vector<Frame> frames;

  Vector3 gravity{0.0, 0.0, -9.81};  ///< gravity acceleration in world (3)
  double total_mass = 0.0;
  /// What the loader changed on the way (one line each), e.g. a movable <mimic> joint frozen.
  std::vector<std::string> notes;
  /// Movable <mimic> joints the loader froze (not model joints; see notes).
  std::vector<std::string> frozen_joints;

  /// Index of the joint named `name` (0..njoints-1). Throws ModelError on unknown names.
  int joint_index(const std::string& name) const;
  /// Index of the frame (URDF link) named `name`. Throws ModelError on unknown names.
  int frame_id(const std::string& name) const;
  bool has_frame(const std::string& name) const;
  bool has_joint(const std::string& name) const;
  int idx_q(int joint) const { return 7 + joint; }
  int idx_v(int joint) const { return 6 + joint; }
  /// Neutral configuration: base at the origin, identity orientation, all joints 0 (dim nq).
  Eigen::VectorXd neutral() const;
};

// ---- limits on input files (checked before any parser sees them; components/model/README.md) ----
constexpr std::size_t kMaxFileBytes = std::size_t{16} << 20;  ///< URDF, robot.yaml, scenario
constexpr int kMaxXmlDepth = 256;            ///< element nesting in a URDF (real ones: < 10)
constexpr std::size_t kMaxLinks = 10000;     ///< links (and joints) in a URDF
/// Moving joints a robot may have: every per-joint array on the wire has MAX_JOINTS (64) entries
/// (idl/common.idl), so a robot with more cannot be run, and every loader refuses it.
constexpr int kMaxWireJoints = 64;
constexpr std::size_t kMaxTreeDepth = 1000;  ///< joints between the root and any link
constexpr double kMaxLinkMass = 1e4;         ///< kg, one link
/// kg: every body (a link with the links fixed to it), the floating base included, has at least
/// this mass; lighter (0, a denormal 1e-320) has no dynamics the simulator can integrate.
constexpr double kMinBodyMass = 1e-6;
constexpr double kMaxTotalMass = 1e5;        ///< kg, the whole robot
constexpr double kMaxInertia = 1e5;          ///< kg m^2, any entry of a link's inertia
constexpr double kMaxOffset = 100.0;         ///< m, any origin offset, shape size or prismatic limit

/// Reads a whole text file of at most `max_bytes` (stops reading there: /dev/zero is refused,
/// not read until memory runs out). `what` names the file kind in messages ("URDF").
/// Throws ModelError naming the file and the limit.
std::string read_text_file_limited(const std::filesystem::path& path, const std::string& what,
                                   std::size_t max_bytes = kMaxFileBytes);

/// Builds the model from a URDF file. Throws ModelError naming every problem found (one per
/// line): missing or oversized file, bad or too deeply nested XML, non-finite / textual /
/// missing / negative / implausible numbers (mass, inertia, origins, shapes, limits), kinematic
/// loop, non-positive-definite inertia of a body (after merging its fixed links), unsupported
/// joint type. A <mimic> on a fixed joint is ignored; a movable mimic joint is frozen (made fixed)
/// at `offset` (its leader at 0), clamped to its limits, and reported in Model::notes.
Model build_model_from_urdf_file(const std::filesystem::path& path);
/// Same from URDF text; `origin` is used in error messages.
Model build_model_from_urdf_string(const std::string& xml, const std::string& origin = "<string>");
/// The URDF text Poise gives urdfdom (every parse of a URDF goes through it): checked as
/// build_model_from_urdf_string does (throws ModelError naming each problem) and without what
/// Poise does not use and urdfdom may refuse: <visual> elements (urdfdom 3.0 drops a link whose
/// visual <material> has no name, collisions included) and <mimic> on fixed joints.
std::string urdf_for_urdfdom(const std::string& xml, const std::string& origin = "<string>");

// ---- configuration helpers (dims: q nq, v nv)
// ----------------------------------------------------

/// Base pose X_WB from q.
SE3 base_pose(const Eigen::Ref<const Eigen::VectorXd>& q);
/// Writes position and orientation (normalised) into q[0:7].
void set_base_pose(const SE3& X_WB, Eigen::Ref<Eigen::VectorXd> q);
/// Base velocity v[0:6] (body frame) from the world-frame velocity of the base origin and the
/// world-frame angular velocity, for base orientation R_WB.
Motion base_velocity_from_world(const Matrix3& R_WB, const Vector3& v_WBo, const Vector3& omega_W);
/// Inverse of base_velocity_from_world: returns [v_WBo; omega_W].
Motion base_velocity_to_world(const Matrix3& R_WB, const Motion& V_B);
/// q (+) v*dt: integrates a constant velocity v for dt (base: SE(3) exponential of the body
/// twist). out may alias q.
void integrate(const Model& model, const Eigen::Ref<const Eigen::VectorXd>& q,
               const Eigen::Ref<const Eigen::VectorXd>& v, double dt,
               Eigen::Ref<Eigen::VectorXd> out);
/// Throws ModelError if q / v has the wrong size or non-finite entries (`what` names it).
void check_configuration(const Model& model, const Eigen::Ref<const Eigen::VectorXd>& q);
void check_velocity(const Model& model, const Eigen::Ref<const Eigen::VectorXd>& v,
                    const char* what = "v");

}  // namespace poise::model
