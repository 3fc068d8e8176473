#pragma once
// Internal: a URDF reduced to the bodies the simulator needs (fixed joints merged). Bullet-free.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace poise::sim::detail {

/// Collision primitive in the body frame L (the URDF frame of the body's own link).
struct ShapeSpec {
  /// kConvex: a URDF <mesh> that could be read (STL, OBJ), colliding as its convex hull.
  enum class Type { kBox, kSphere, kCylinder, kConvex } type = Type::kBox;
  Eigen::Vector3d size =
      Eigen::Vector3d::Zero();  ///< box half extents | (radius) | (radius, length)
  Eigen::Isometry3d X_LS = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> points;  ///< kConvex: the mesh's vertices in S, scaled
};

struct BodySpec {
  std::string name;  ///< URDF link that starts the body
  int parent = -1;   ///< parent body index, -1 for the root (floating base)
  enum class Joint { kRoot, kRevolute, kPrismatic } joint = Joint::kRoot;
  std::string joint_name;
  Eigen::Vector3d axis_L = Eigen::Vector3d::UnitZ();       ///< joint axis in L (unit)
  Eigen::Isometry3d X_PJ = Eigen::Isometry3d::Identity();  ///< joint frame in parent L at q=0
  bool limited = false;
  double lower = 0.0, upper = 0.0;
  double effort = 0.0;  ///< 0 = unlimited
  double damping = 0.0, friction = 0.0;
  double mass = 0.0;
  Eigen::Vector3d com_L = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia_com_L = Eigen::Matrix3d::Zero();  ///< about the COM, L axes
  std::vector<ShapeSpec> shapes;
  bool has_mesh = false;  ///< some collision geometry was a mesh (ignored)
};

struct FrameSpec {
  std::string name;  ///< URDF link name
  int body = 0;
  Eigen::Isometry3d X_LF = Eigen::Isometry3d::Identity();  ///< frame in its body frame L
};

struct RobotTree {
  std::vector<BodySpec> bodies;   ///< bodies[0] is the root; parents precede children
  std::vector<FrameSpec> frames;  ///< every URDF link
  const FrameSpec* find_frame(const std::string& name) const;
};

/// Parses and reduces a URDF file. Throws std::runtime_error naming the problem.
RobotTree load_robot_tree(const std::string& urdf_path);
/// Same from URDF text (`what` names the source in error messages). `mesh_dir`: the URDF's
/// folder, where mesh filenames are resolved (model::resolve_mesh_path); empty: meshes are not
/// read (the body only notes has_mesh).
RobotTree parse_robot_tree(const std::string& urdf_xml, const std::string& what,
                           const std::string& mesh_dir = {});

}  // namespace poise::sim::detail
