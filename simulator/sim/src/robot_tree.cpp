#include "robot_tree.hpp"
#include "poise/cli/read_file.hpp"

#include <urdf_parser/urdf_parser.h>
#if POISE_SIM_HAVE_MODEL
#include "poise/model/mesh.hpp"
#include "poise/model/model.hpp"
#endif
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace poise::sim::detail {
namespace {

Eigen::Isometry3d to_iso(const urdf::Pose& p) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z)
                   .normalized()
                   .toRotationMatrix();
  X.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return X;
}

// A <sphere radius="0"> collides as a sphere of this radius, m.
constexpr double kPointContactRadius = 1e-4;

[[noreturn]] void fail(const std::string& what, const std::string& msg) {
  throw std::runtime_error("URDF " + what + ": " + msg);
}

struct Builder {
  const urdf::ModelInterface& model;
  std::string what;
  RobotTree tree;
  std::string mesh_dir;  ///< where mesh files are resolved; empty: not read

  // Adds the link's inertia and collision geometry to body b; the link frame is X_LK in L.
  void merge_link(const urdf::Link& link, int b, const Eigen::Isometry3d& X_LK) {
    BodySpec& body = tree.bodies[static_cast<std::size_t>(b)];
    tree.frames.push_back(FrameSpec{link.name, b, X_LK});
    if (link.inertial) {
      const urdf::Inertial& in = *link.inertial;
      if (!std::isfinite(in.mass) || in.mass < 0.0)
        fail(what, "link '" + link.name + "' has an invalid mass");
      Eigen::Matrix3d I_C;
      I_C << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
      if (!I_C.allFinite()) fail(what, "link '" + link.name + "' has a non-finite inertia");
      const Eigen::Isometry3d X_LC = X_LK * to_iso(in.origin);
      const Eigen::Matrix3d I_C_L = X_LC.linear() * I_C * X_LC.linear().transpose();
      const Eigen::Vector3d c = X_LC.translation();
      const double m0 = body.mass, m1 = in.mass, m = m0 + m1;
      if (m > 0.0) {
        const Eigen::Vector3d com = (m0 * body.com_L + m1 * c) / m;
        auto shift = [](double mass, const Eigen::Vector3d& d) {
          return mass * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
        };
        body.inertia_com_L =
            body.inertia_com_L + shift(m0, body.com_L - com) + I_C_L + shift(m1, c - com);
        body.com_L = com;
        body.mass = m;
      }
    }
    for (const auto& col : link.collision_array) {
      if (!col || !col->geometry) continue;
      ShapeSpec s;
      s.X_LS = X_LK * to_iso(col->origin);
      switch (col->geometry->type) {
        case urdf::Geometry::BOX: {
          const auto& g = static_cast<const urdf::Box&>(*col->geometry);
          s.type = ShapeSpec::Type::kBox;
          s.size = 0.5 * Eigen::Vector3d(g.dim.x, g.dim.y, g.dim.z);
          break;
        }
        case urdf::Geometry::SPHERE: {
          const auto& g = static_cast<const urdf::Sphere&>(*col->geometry);
          s.type = ShapeSpec::Type::kSphere;
          // radius 0 is a contact point (Drake's point contacts): a 0.1 mm sphere to Bullet
          s.size = Eigen::Vector3d(std::max(g.radius, kPointContactRadius), 0.0, 0.0);
          break;
        }
        case urdf::Geometry::CYLINDER: {
          const auto& g = static_cast<const urdf::Cylinder&>(*col->geometry);
          s.type = ShapeSpec::Type::kCylinder;
          s.size = Eigen::Vector3d(g.radius, g.length, 0.0);
          break;
        }
        case urdf::Geometry::MESH: {
          body.has_mesh = true;
          if (!read_mesh(link, static_cast<const urdf::Mesh&>(*col->geometry), s.points)) continue;
          s.type = ShapeSpec::Type::kConvex;
          break;
        }
        default:
          continue;
      }
      if (!s.size.allFinite() || (s.size.array() < 0.0).any())
        fail(what, "link '" + link.name + "' has an invalid collision size");
      body.shapes.push_back(s);
    }
  }

  // The mesh's vertices, scaled (its frame is the collision's origin); false when it is not found
  // or not readable (another format than STL, OBJ or COLLADA): the link then has no such collision.
  // The mesh's vertices, scaled (its frame is the collision's origin); false when meshes are not
  // read (no folder to find them in). A mesh that cannot be read (missing, not a regular file,
  // malformed, a zero scale) is refused, naming the link and the file, as by `poise model info`
  // and `poise robot init` (model::read_collision_mesh).
  bool read_mesh(const urdf::Link& link, const urdf::Mesh& mesh,
                 std::vector<Eigen::Vector3d>& points) const {
#if POISE_SIM_HAVE_MODEL
    if (mesh_dir.empty()) return false;
    const std::string why = model::read_collision_mesh(
        mesh.filename, Eigen::Vector3d(mesh.scale.x, mesh.scale.y, mesh.scale.z), mesh_dir,
        points);
    if (!why.empty())
      fail(what, "link '" + link.name + "': collision mesh '" + mesh.filename + "': " + why);
    return true;
#else
    (void)link;
    (void)mesh;
    (void)points;
    return false;
#endif
  }

  void visit(const urdf::Link& link, int b, const Eigen::Isometry3d& X_LK) {
    merge_link(link, b, X_LK);
    std::vector<urdf::JointSharedPtr> joints = link.child_joints;
    std::sort(joints.begin(), joints.end(),
              [](const auto& a, const auto& c) { return a->name < c->name; });
    for (const auto& j : joints) {
      const urdf::LinkConstSharedPtr child = model.getLink(j->child_link_name);
      if (!child) fail(what, "joint '" + j->name + "' has no child link");
      const Eigen::Isometry3d X_LJ = X_LK * to_iso(j->parent_to_joint_origin_transform);
      if (j->type == urdf::Joint::FIXED) {
        visit(*child, b, X_LJ);
        continue;
      }
      const bool movable = j->type == urdf::Joint::REVOLUTE ||
                           j->type == urdf::Joint::CONTINUOUS || j->type == urdf::Joint::PRISMATIC;
      const bool unactuated =
          j->limits && (j->limits->effort == 0.0 || j->limits->velocity == 0.0);
      if (movable && (j->mimic || unactuated)) {
        // A movable mimic joint is frozen at its offset (leader at 0), one whose <limit> says it
        // is not actuated (effort or velocity 0) at 0, clamped to its limits: the same rule as
        // poise::model (Model::frozen_joints), so both see the same tree.
        double v = j->mimic && std::isfinite(j->mimic->offset) ? j->mimic->offset : 0.0;
        if (j->limits && j->type != urdf::Joint::CONTINUOUS)
          v = std::clamp(v, j->limits->lower, j->limits->upper);
        Eigen::Vector3d axis(j->axis.x, j->axis.y, j->axis.z);
        if (!axis.allFinite() || axis.norm() < 1e-9)
          fail(what, "joint '" + j->name + "' has a zero or invalid axis");
        axis.normalize();
        Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
        if (j->type == urdf::Joint::PRISMATIC)
          motion.translation() = v * axis;
        else
          motion.linear() = Eigen::AngleAxisd(v, axis).toRotationMatrix();
        visit(*child, b, X_LJ * motion);
        continue;
      }
      BodySpec body;
      body.name = child->name;
      body.parent = b;
      body.joint_name = j->name;
      body.X_PJ = X_LJ;
      Eigen::Vector3d axis(j->axis.x, j->axis.y, j->axis.z);
      if (!axis.allFinite() || axis.norm() < 1e-9)
        fail(what, "joint '" + j->name + "' has a zero or invalid axis");
      body.axis_L = axis.normalized();
      switch (j->type) {
        case urdf::Joint::REVOLUTE:
          body.joint = BodySpec::Joint::kRevolute;
          body.limited = true;
          break;
        case urdf::Joint::CONTINUOUS:
          body.joint = BodySpec::Joint::kRevolute;
          break;
        case urdf::Joint::PRISMATIC:
          body.joint = BodySpec::Joint::kPrismatic;
          body.limited = true;
          break;
        default:
          fail(what, "joint '" + j->name +
                         "' has an unsupported type (only revolute, continuous, prismatic, "
                         "fixed)");
      }
      if (j->limits) {
        body.lower = j->limits->lower;
        body.upper = j->limits->upper;
        body.effort = j->limits->effort;
        if (body.limited && !(body.lower <= body.upper))
          fail(what, "joint '" + j->name + "' has lower limit > upper limit");
      } else if (body.limited) {
        fail(what, "joint '" + j->name + "' needs a <limit> element");
      }
      if (j->dynamics) {
        body.damping = j->dynamics->damping;
        body.friction = j->dynamics->friction;
        if (body.damping < 0.0 || body.friction < 0.0)
          fail(what, "joint '" + j->name + "' has negative damping or friction");
      }
      tree.bodies.push_back(body);
      const int cb = static_cast<int>(tree.bodies.size()) - 1;
      visit(*child, cb, Eigen::Isometry3d::Identity());
      const BodySpec& made = tree.bodies[static_cast<std::size_t>(cb)];
      if (!(made.mass >= 1e-6))  // poise::model::kMinBodyMass: the same rule as every loader
        fail(what, "link '" + made.name + "' (moved by joint '" + j->name +
                       "') has no mass: a movable body needs an <inertial> with mass >= 1e-6 kg");
    }
  }
};

}  // namespace

const FrameSpec* RobotTree::find_frame(const std::string& name) const {
  for (const auto& f : frames)
    if (f.name == name) return &f;
  return nullptr;
}

RobotTree parse_robot_tree(const std::string& urdf_xml, const std::string& what,
                           const std::string& mesh_dir) {
#if POISE_SIM_HAVE_MODEL
  // The text the model library checked and stripped of visuals (model.hpp urdf_for_urdfdom).
  urdf::ModelInterfaceSharedPtr model =
      urdf::parseURDF(poise::model::urdf_for_urdfdom(urdf_xml, what));
#else
  urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
#endif
  if (!model) fail(what, "could not be parsed (see the urdfdom message above)");
  const urdf::LinkConstSharedPtr root = model->getRoot();
  if (!root) fail(what, "has no root link");
  Builder b{*model, what, {}, mesh_dir};
  BodySpec base;
  base.name = root->name;
  b.tree.bodies.push_back(base);
  b.visit(*root, 0, Eigen::Isometry3d::Identity());
  if (!(b.tree.bodies[0].mass >= 1e-6))
    fail(what, "the root link '" + root->name + "' and the links fixed to it have no mass");
  // Every per-joint array on the wire has 64 entries (MAX_JOINTS of idl/common.idl).
  constexpr std::size_t kMaxWireJoints = 64;
  if (b.tree.bodies.size() - 1 > kMaxWireJoints)
    fail(what, std::to_string(b.tree.bodies.size() - 1) +
                   " moving joints; Poise's messages carry at most 64 (MAX_JOINTS of "
                   "idl/common.idl)");
  return b.tree;
}

RobotTree load_robot_tree(const std::string& urdf_path) {
  return parse_robot_tree(poise::cli::read_regular_file(urdf_path, "URDF", std::size_t{16} << 20), "'" + urdf_path + "'",
                          std::filesystem::absolute(urdf_path).parent_path().string());
}

}  // namespace poise::sim::detail
