// `poise robot init URDF [-o DIR] [--name NAME] [--force] [--wn W]`: guesses a robot.yaml from a
// URDF alone (legs, feet, soles, IMU, nominal posture, PD gains), writes it, checks it with the
// loader and prints what it guessed. README: components/robot_init/README.md.
#include <urdf_parser/urdf_parser.h>
#include <CLI/CLI.hpp>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/mesh.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/cli/parse.hpp"

namespace fs = std::filesystem;

namespace poise::robot_init {

namespace {

using model::Matrix3;
using model::SE3;
using model::Vector3;

struct InitError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Options {
  std::string urdf;
  std::string out_dir;
  std::string name;
  bool force = false;
  double wn = 100.0;           ///< rad/s, natural frequency of each joint's PD loop
  double knee_bend = 0.5;      ///< rad
  double dt = 0.001;           ///< s, control period
  bool stand_centres = false;  ///< --stand centres: never stand points (the paper's rule)
};

// Points of one collision shape in its link frame (boxes: corners; cylinders and spheres: points
// on their surface, enough for a bounding rectangle to 1 mm at foot sizes).
bool shape_points(const urdf::Geometry& g, std::vector<Vector3>& out) {
  switch (g.type) {
    case urdf::Geometry::BOX: {
      const auto& b = static_cast<const urdf::Box&>(g);
      for (int i = 0; i < 8; ++i)
        out.emplace_back((i & 1 ? 0.5 : -0.5) * b.dim.x, (i & 2 ? 0.5 : -0.5) * b.dim.y,
                         (i & 4 ? 0.5 : -0.5) * b.dim.z);
      return true;
    }
    case urdf::Geometry::CYLINDER: {
      const auto& c = static_cast<const urdf::Cylinder&>(g);
      for (int k = 0; k < 64; ++k) {
        const double a = 2.0 * M_PI * k / 64.0;
        for (double z : {-0.5 * c.length, 0.5 * c.length})
          out.emplace_back(c.radius * std::cos(a), c.radius * std::sin(a), z);
      }
      return true;
    }
    case urdf::Geometry::SPHERE: {
      const auto& s = static_cast<const urdf::Sphere&>(g);
      for (int i = 0; i <= 16; ++i)
        for (int k = 0; k < 32; ++k) {
          const double t = M_PI * i / 16.0, a = 2.0 * M_PI * k / 32.0;
          out.emplace_back(s.radius * std::sin(t) * std::cos(a),
                           s.radius * std::sin(t) * std::sin(a), s.radius * std::cos(t));
        }
      return true;
    }
    default:
      return false;  // meshes: not read here
  }
}

SE3 pose_of(const urdf::Pose& p) {
  double x, y, z, w;
  p.rotation.getQuaternion(x, y, z, w);
  const Eigen::Quaterniond q(w, x, y, z);
  return SE3(q.normalized().toRotationMatrix(), Vector3(p.position.x, p.position.y, p.position.z));
}

struct BodyGeometry {
  std::vector<Vector3> points_B;   ///< collision points in the body frame
  std::vector<std::string> mesh_files;  ///< mesh files read
};

std::string fmt(double v, int prec = 4) {
  std::ostringstream os;
  os << std::setprecision(prec) << std::fixed << v;
  std::string s = os.str();
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

// Significant digits (gains span 1e-4 to 1e3).
std::string sig(double v, int digits = 4) {
  std::ostringstream os;
  os << std::setprecision(digits) << v;
  return os.str();
}

struct Leg {
  std::string side;  ///< "left" / "right"
  int foot_body = -1;
  std::string foot_frame;
  std::vector<int> joints;  ///< model joints from the hip down
  model::SoleRectangle sole;
  /// Where the robot stands on this sole (robot.yaml feet.<side>.stand_point; unset: the centre).
  std::optional<Eigen::Vector2d> stand;
  Vector3 stand_F() const { return sole.stand_point_F(stand); }
  std::string sole_frame;
  bool sole_added = false;
  SE3 X_BA;                  ///< foot frame in the foot body (an added upright frame or I)
  bool frame_added = false;  ///< the foot frame is an upright frame robot.yaml adds
  Vector3 sole_offset = Vector3::Zero();      ///< sole_added: sole frame origin in the foot link
  Vector3 sole_rpy = Vector3::Zero();         ///< sole_added: its rotation (URDF rpy)
  int hip = -1, knee = -1, ankle = -1;        ///< pitch joints (model indices), -1 when not found
  double s_hip = 1, s_knee = 1, s_ankle = 1;  ///< sign of each pitch axis along world +y
};

// Joint value from a rotation about world +y, clamped to the limits.
double clamp_limits(const model::Model& m, int j, double v) {
  return std::clamp(v, m.limits[j].lower, m.limits[j].upper);
}

// The URDF file as read: its absolute path and its text.
struct UrdfText {
  fs::path path;
  std::string xml;
};

UrdfText read_urdf(const Options& opt) {
  const fs::path urdf_path = fs::absolute(opt.urdf).lexically_normal();
  if (!fs::exists(urdf_path)) throw InitError("no such file: " + opt.urdf);
  if (!fs::is_regular_file(urdf_path)) throw InitError("not a regular file: " + opt.urdf);
  return {urdf_path, model::read_text_file_limited(urdf_path, "URDF")};
}

// Where the CoM stands in a posture, against the soles (RobotInit::stance()).
struct Stance {
  Eigen::Vector2d com_error;  ///< CoM minus the mid-point of the stand points (world xy)
  double tilt = 0.0;          ///< worst sole tilt (rad)
  double dz = 0.0;            ///< sole height difference
  bool inside = false;        ///< CoM inside the bounding box of the soles
};

// How far a sole's CoP can move along the sole's x and y (r_x, r_y in
// RobotInit::place_stand_points_for_efforts()), from its stand point and from its centre.
struct CopReach {
  Eigen::Vector2d stand, centre;
};

// The standing torques (RobotInit::standing_torques()) with the feet's forces at the sole centres,
// then moved by h along the soles' x, then their y (RobotInit::place_stand_points_for_efforts()).
struct TorqueSteps {
  Eigen::VectorXd at_centre, x_step, y_step;
  double h = 0.0;
};

// What robot init finds, phase by phase: run_init() calls the phases in order, each one reads
// what the ones before it decided and adds to `checks` what the user should check.
struct RobotInit {
  RobotInit(const Options& options, const UrdfText& input);

  const Options& opt;
  const fs::path urdf_path;
  const model::Model m;
  const urdf::ModelInterfaceSharedPtr u;
  std::vector<std::string> checks;  // what the user should check

  // choose_output()
  std::string robot_name;
  fs::path out_dir, yaml_path;
  // choose_imu()
  std::string imu;                                 ///< the IMU frame
  std::string imu_where = "on the floating base";  ///< where it is (robot.yaml, the report)
  // read_collision_geometry()
  std::vector<BodyGeometry> geo;  ///< collision geometry per body
  // The legs and feet at the zero configuration (find_feet() to choose_left_and_right()).
  model::Data data;
  Eigen::VectorXd q;                  ///< the zero configuration, then the nominal posture
  std::vector<Leg> legs;              ///< [0] right, [1] left (model::Side)
  Vector3 forward = Vector3::Zero();  ///< forward_axis, in the floating base's frame
  Vector3 ey = Vector3::Zero();       ///< the pitch axis: the robot's left
  // The nominal posture (choose_knee_bend() to check_standing_efforts()).
  Eigen::Vector2d fwd2, left2;  ///< the robot's forward and left on the ground
  double knee = 0.0;            ///< knee bend (rad)
  double lean = 0.0;            ///< the legs' lean (rad; d in set_posture())
  Stance st;                    ///< its stance
  bool com_stand_points = false;  // stand points under the CoM (not for the joints' efforts)
  // choose_gains()
  Eigen::MatrixXd Minv;     ///< M^-1 at the nominal posture
  std::vector<int> leg_of;  ///< per joint: its leg (index in `legs`), -1 outside the legs
  std::vector<model::JointGains> gains;
  std::vector<double> inertia, inertia_stance;  ///< per joint: swing and stance inertia
  double leg_scale = 1.0;                       ///< factor on the leg gains for stability
  double margin = 2.0, margin_hi = 4.0;  ///< factor on every gain at which the loop turns unstable
  // write_robot_yaml()
  std::vector<int> leg_joints, upper;  ///< robot.yaml's joint_groups

  // The phases, in the order run_init() calls them.
  void choose_output();
  void require_enough_joints() const;
  void choose_imu();
  void read_collision_geometry();
  void find_feet();
  void find_leg_joints();
  void find_soles();
  void choose_forward_axis();
  void choose_left_and_right();
  void find_pitch_joints();
  void choose_knee_bend();
  void choose_nominal_posture();
  void check_nominal_posture();
  void check_standing_efforts();
  void choose_gains();
  void write_robot_yaml();
  model::RobotConfig check_with_loader() const;
  void report(const model::RobotConfig& cfg) const;

  // The phases' steps.
  void choose_imu_link();
  double lowest_z(int b) const;
  bool has_shapes(int b) const { return !geo[b].points_B.empty(); }
  std::vector<int> joints_to_base(const std::string& name) const;
  void choose_foot_frame(Leg& leg);
  double find_sole_rectangle(Leg& leg);
  void choose_sole_frame(Leg& leg, double zmin);
  void level_soles();
  void set_posture(double d);
  Stance stance();
  void lean_legs();
  void stand_points_under_the_com();
  double weight() const { return m.total_mass * m.gravity.norm(); }  ///< N
  Eigen::VectorXd standing_torques(const std::array<Vector3, 2>& at_F);
  double effort(int j) const;
  std::pair<double, int> most_loaded_joint(const Eigen::VectorXd& tau, const Leg& leg) const;
  void place_stand_points_for_efforts();
  CopReach place_stand_point(Leg& leg, const TorqueSteps& tau);
  void report_stand_points(const std::array<CopReach, 2>& reach);
  double spectral_radius(double f, double leg) const;
  void stabilise_leg_gains();
  void find_gain_margin();
  std::string joint_list(const std::vector<int>& js) const;
  void write_feet(std::ostream& y) const;
  void write_posture_and_gains(std::ostream& y) const;
};

RobotInit::RobotInit(const Options& options, const UrdfText& input)
    : opt(options),
      urdf_path(input.path),
      m(model::build_model_from_urdf_string(input.xml, input.path.string())),
      u(urdf::parseURDF(model::urdf_for_urdfdom(input.xml, input.path.string()))),
      data(m) {
  if (!u) throw InitError(urdf_path.string() + ": urdfdom could not parse the URDF");
}

void RobotInit::choose_output() {
  robot_name = !opt.name.empty() ? opt.name : m.name;
  out_dir = fs::absolute(opt.out_dir.empty() ? fs::path(urdf_path.stem().string() + "_poise")
                                             : fs::path(opt.out_dir))
                .lexically_normal();
  yaml_path = out_dir / "robot.yaml";
  if (fs::exists(yaml_path) && !opt.force)
    throw InitError(yaml_path.string() + " exists (--force to overwrite it)");
}

void RobotInit::require_enough_joints() const {
  if (m.njoints < 4)
    throw InitError("the URDF has " + std::to_string(m.njoints) +
                    " movable joints: a humanoid needs two legs of several joints each");
}

void RobotInit::choose_imu() {
  // IMU: the floating base's link; when the root link is massless (a "world" or "base_link"
  // dummy), the first link with mass fixed to it.
  imu = m.body_name[0];
  if (const urdf::LinkConstSharedPtr root = u->getRoot(); root && !root->inertial) {
    for (const auto& child : root->child_links)
      if (child && child->inertial && m.has_frame(child->name) &&
          m.frames[m.frame_id(child->name)].body == 0) {
        imu = child->name;
        checks.push_back("the URDF root '" + m.body_name[0] + "' is massless: it is the floating "
                         "base (q, base height criteria of scenarios, pushes on it), the IMU is "
                         "put on '" + imu + "'; consider removing the dummy root");
        break;
      }
  }
  choose_imu_link();
}

// The model joints between the floating base and a frame, base first.
std::vector<int> RobotInit::joints_to_base(const std::string& name) const {
  std::vector<int> js;  // base to the link
  for (int b = m.frames[m.frame_id(name)].body; b > 0; b = m.parent[static_cast<std::size_t>(b)])
    js.insert(js.begin(), b - 1);
  return js;
}

void RobotInit::choose_imu_link() {
  // An IMU link the URDF names (a link whose name contains "imu", any case): one fixed to the
  // floating base is the IMU frame (its lever arm then counts in the simulated IMU and the
  // estimator); without one, the IMU link nearest the base (fewest joints between: a torso's
  // behind a waist) is, and the estimator takes its motion relative to the base from those
  // joints' encoders.
  std::vector<std::string> on_base, elsewhere;
  for (const auto& [name, link] : u->links_) {
    std::string lower = name;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (lower.find("imu") == std::string::npos || !m.has_frame(name)) continue;
    (m.frames[m.frame_id(name)].body == 0 ? on_base : elsewhere).push_back(name);
  }
  std::sort(on_base.begin(), on_base.end());
  std::stable_sort(elsewhere.begin(), elsewhere.end(), [&](const auto& a, const auto& b) {
    const std::size_t da = joints_to_base(a).size(), db = joints_to_base(b).size();
    return da != db ? da < db : a < b;
  });
  if (!on_base.empty()) {
    imu = on_base.front();
    if (on_base.size() > 1) {
      std::string all;
      for (const std::string& n : on_base) all += (all.empty() ? "" : ", ") + n;
      checks.push_back("IMU links on the floating base: " + all + "; '" + imu +
                       "' taken (imu_frame)");
    }
  } else if (!elsewhere.empty()) {
    imu = elsewhere.front();
    const std::vector<int> js = joints_to_base(imu);
    std::string via;
    for (int j : js) via += (via.empty() ? "" : ", ") + m.joint_names[static_cast<std::size_t>(j)];
    imu_where = "on '" + m.body_name[static_cast<std::size_t>(m.frames[m.frame_id(imu)].body)] +
                "', behind " + via;
    checks.push_back("the IMU frame '" + imu + "' is not on the floating base '" +
                     m.body_name[0] + "' but " + imu_where + ": the estimator takes its motion "
                     "relative to the base from " + (js.size() == 1 ? "that joint's" : "those "
                     "joints'") + " encoders (their errors become attitude and velocity errors); "
                     "imu_frame: " + m.body_name[0] + " simulates an IMU on the base instead");
  }
  for (const std::string& name : elsewhere) {
    if (name == imu) continue;
    const int body = m.frames[m.frame_id(name)].body;
    checks.push_back("the URDF's IMU link '" + name + "' (on '" + m.body_name[body] +
                     "') is not used: the IMU frame is '" + imu + "'");
  }
}

// ---- collision geometry per body, in the body frame ---------------------------------------------
void RobotInit::read_collision_geometry() {
  geo.resize(m.nbodies);
  std::vector<std::string> unreadable_meshes;  // the simulator would refuse the robot for these
  for (const model::Frame& f : m.frames) {
    const auto it = u->links_.find(f.name);
    if (it == u->links_.end() || !it->second) continue;
    for (const auto& c : it->second->collision_array) {
      if (!c || !c->geometry) continue;
      std::vector<Vector3> pts;
      if (!shape_points(*c->geometry, pts)) {
        if (c->geometry->type != urdf::Geometry::MESH) continue;
        const auto& mesh = static_cast<const urdf::Mesh&>(*c->geometry);
        const std::string why = model::read_collision_mesh(
            mesh.filename, Vector3(mesh.scale.x, mesh.scale.y, mesh.scale.z),
            urdf_path.parent_path(), pts);
        if (!why.empty()) {
          unreadable_meshes.push_back("link '" + f.name + "': collision mesh '" + mesh.filename +
                                      "': " + why);
          continue;
        }
        geo[f.body].mesh_files.push_back(
            model::resolve_mesh_path(mesh.filename, urdf_path.parent_path()).string());
      }
      const SE3 X_BC = f.X_BF * pose_of(c->origin);
      for (const Vector3& p : pts) geo[f.body].points_B.push_back(X_BC.act(p));
    }
  }

  if (!unreadable_meshes.empty()) {
    std::string all = std::to_string(unreadable_meshes.size()) +
                      " collision mesh(es) cannot be read (the simulator would refuse the robot; "
                      "are the robot's mesh files beside its URDF?):";
    for (std::size_t i = 0; i < unreadable_meshes.size() && i < 8; ++i)
      all += "\n  " + unreadable_meshes[i];
    if (unreadable_meshes.size() > 8)
      all += "\n  ... and " + std::to_string(unreadable_meshes.size() - 8) + " more";
    throw InitError(all);
  }

  // A floating base without collision geometry passes through the floor when the robot falls
  // (Unitree's G1 pelvis: its base ended 0.21 m below the ground after a fall).
  if (geo[0].points_B.empty() && geo[0].mesh_files.empty())
    checks.push_back("the floating base '" + m.body_name[0] + "' has no collision geometry: in "
                     "the simulator it passes through the floor when the robot falls (a "
                     "scenario's min_base_height then measures that); give it a <collision>");
}

// The lowest point of a body's collision geometry (or its origin), world z.
double RobotInit::lowest_z(int b) const {
  double z = data.oMi[b].p.z();
  for (const Vector3& p : geo[b].points_B) z = std::min(z, data.oMi[b].act(p).z());
  return z;
}

void RobotInit::find_feet() {
  // ---- zero configuration: base at the origin, upright ------------------------------------------
  q = m.neutral();
  model::forward_kinematics(m, data, q);

  // ---- feet: the lowest body, then the lowest body on another branch with y of the other sign ---
  int a = -1;
  for (int b = 1; b < m.nbodies; ++b)
    if (has_shapes(b) && (a < 0 || lowest_z(b) < lowest_z(a) - 1e-9)) a = b;
  if (a < 0)
    throw InitError("no movable link carries collision geometry (box, cylinder, sphere, STL, OBJ "
                    "or COLLADA mesh): the feet are found by their collision geometry");
  auto related = [&](int x, int y) {
    return (x <= y && y <= m.subtree_end[x]) || (y <= x && x <= m.subtree_end[y]);
  };
  const double ya = data.oMi[a].p.y();
  int b2 = -1;
  for (int b = 1; b < m.nbodies; ++b) {
    if (!has_shapes(b) || related(a, b)) continue;
    if (data.oMi[b].p.y() * ya >= 0.0) continue;
    if (b2 < 0 || lowest_z(b) < lowest_z(b2) - 1e-9) b2 = b;
  }
  if (b2 < 0 || std::abs(ya) < 1e-4) {
    // Legs side by side along the base's x (a URDF whose base frame is not x forward, y left,
    // as REP 103 asks; K-Scale's Zeroth): the lowest body on another branch at the same height
    // (within 1 cm) and at least 2 cm away horizontally. The robot's left and forward come
    // from the feet later (forward_axis), whatever the base frame says.
    int alt = -1;
    for (int b = 1; b < m.nbodies; ++b) {
      if (!has_shapes(b) || related(a, b)) continue;
      if ((data.oMi[b].p - data.oMi[a].p).head<2>().norm() < 0.02) continue;
      if (alt < 0 || lowest_z(b) < lowest_z(alt) - 1e-9) alt = b;
    }
    if (alt >= 0 && std::abs(lowest_z(alt) - lowest_z(a)) <= 0.01) {
      b2 = alt;
      checks.push_back("the feet '" + m.body_name[a] + "' and '" + m.body_name[b2] +
                       "' are side by side along (" +
                       fmt((data.oMi[b2].p - data.oMi[a].p).x(), 3) + ", " +
                       fmt((data.oMi[b2].p - data.oMi[a].p).y(), 3) +
                       ") in the floating base's frame, not along its y: its x is not the "
                       "robot's forward (REP 103); forward_axis below comes from the toes");
    }
  }
  if (b2 < 0)
    throw InitError("found one leg ending in '" + m.body_name[a] +
                    "' (lowest collision point z = " + fmt(lowest_z(a)) +
                    " m at the zero configuration) but no second leg: no other chain from the "
                    "floating base ends on the other side (y of the other sign), or within 1 cm "
                    "of its height 2 cm or more away, in a link with collision geometry");
  if (std::abs(lowest_z(a) - lowest_z(b2)) > 0.01)
    checks.push_back("the two feet are " + fmt(std::abs(lowest_z(a) - lowest_z(b2)) * 1000, 1) +
                     " mm apart in height at the zero configuration: are '" + m.body_name[a] +
                     "' and '" + m.body_name[b2] + "' the feet?");

  legs.resize(2);  // [0] right, [1] left (model::Side)
  legs[ya > 0 ? 1 : 0].foot_body = a;
  legs[ya > 0 ? 0 : 1].foot_body = b2;
  legs[0].side = "right";
  legs[1].side = "left";
}

void RobotInit::find_leg_joints() {
  // Leg joints: those on one foot's chain from the floating base and not on the other's.
  std::vector<std::set<int>> chain(2);
  for (int s = 0; s < 2; ++s)
    for (int b = legs[s].foot_body; b > 0; b = m.parent[b]) chain[s].insert(b - 1);
  for (int s = 0; s < 2; ++s) {
    for (int j : chain[s])
      if (!chain[1 - s].count(j)) legs[s].joints.push_back(j);
    std::sort(legs[s].joints.begin(), legs[s].joints.end());  // pre-order: hip first
    if (legs[s].joints.size() < 3)
      checks.push_back("the " + legs[s].side + " leg has only " +
                       std::to_string(legs[s].joints.size()) + " joints of its own");
    else if (legs[s].joints.size() < 6)
      checks.push_back("the " + legs[s].side + " leg has " +
                       std::to_string(legs[s].joints.size()) +
                       " joints: its foot cannot take every pose under the hip (with both feet "
                       "flat the pelvis cannot move in every direction, e.g. sideways without "
                       "ankle rolls); the controller drops the feet's dependent constraint rows "
                       "(controller/momentum/README.md, \"Legs with fewer than six joints\")");
  }
}

// ---- feet and soles -----------------------------------------------------------------------------
void RobotInit::find_soles() {
  for (Leg& leg : legs) {
    choose_foot_frame(leg);
    choose_sole_frame(leg, find_sole_rectangle(leg));
  }
}

void RobotInit::choose_foot_frame(Leg& leg) {
  const int fb = leg.foot_body;
  leg.foot_frame = m.body_name[fb];
  if (m.subtree_end[fb] > fb)
    checks.push_back("the " + leg.side + " foot '" + leg.foot_frame + "' has " +
                     std::to_string(m.subtree_end[fb] - fb) + " movable joint(s) below it (" +
                     m.joint_names[fb] + ", ...): toes, or a foot whose collision geometry "
                     "could not be read?");
  // A foot link whose z axis is not up at the zero configuration (z down, tilted): the sole
  // is found in an upright frame A at the link's origin (z up, x along the link's heading);
  // robot.yaml gives the sole frame with that rotation (sole_frame: {offset, rpy}), and the
  // loader adds the foot frame '<link>_foot_poise' (no URDF edit).
  leg.X_BA = SE3(Matrix3::Identity(), Vector3::Zero());
  const SE3& X_WB = data.oMi[fb];
  if (X_WB.R.col(2).z() < std::cos(1e-3)) {
    const Vector3 xw = X_WB.R.col(0);
    const double yaw = std::hypot(xw.x(), xw.y()) > 1e-6 ? std::atan2(xw.y(), xw.x()) : 0.0;
    const Matrix3 R_WA = Eigen::AngleAxisd(yaw, Vector3::UnitZ()).toRotationMatrix();
    leg.X_BA = SE3(X_WB.R.transpose() * R_WA, Vector3::Zero());
    checks.push_back("the " + leg.side + " foot link '" + leg.foot_frame + "' has its z axis " +
                     (X_WB.R.col(2).z() < -std::cos(1e-3) ? "down" : "tilted") +
                     " at the zero configuration: the foot frame is '" + leg.foot_frame +
                     "_foot_poise', added by robot.yaml (sole_frame rpy) at its origin with z up");
    leg.frame_added = true;
  }
}

// The sole rectangle of a foot (leg.sole), in its frame A; returns the lowest collision point's z
// in A.
double RobotInit::find_sole_rectangle(Leg& leg) {
  const int fb = leg.foot_body;
  const SE3 A_inv = leg.X_BA.inverse();
  std::vector<Vector3> pts_A;
  for (const Vector3& p : geo[fb].points_B) pts_A.push_back(A_inv.act(p));
  for (const std::string& file : geo[fb].mesh_files)
    checks.push_back("the " + leg.side + " sole comes from the mesh " + file +
                     ": the simulator collides a box of that rectangle, not the mesh");
  double zmin = 1e9;
  for (const Vector3& p : pts_A) zmin = std::min(zmin, p.z());
  double xl = 1e9, xh = -1e9, yl = 1e9, yh = -1e9;
  // The bottom face: points within 1 mm of the lowest (5 mm for a slightly curved mesh sole).
  for (double tol : {1e-3, 5e-3}) {
    xl = yl = 1e9;
    xh = yh = -1e9;
    for (const Vector3& p : pts_A)
      if (p.z() <= zmin + tol) {
        xl = std::min(xl, p.x());
        xh = std::max(xh, p.x());
        yl = std::min(yl, p.y());
        yh = std::max(yh, p.y());
      }
    if (xh - xl >= 0.02 && yh - yl >= 0.02) {
      if (tol > 1e-3)
        checks.push_back("the " + leg.side + " sole is not flat: its rectangle is the collision "
                         "points within 5 mm of the lowest");
      break;
    }
  }
  if (!(xh - xl >= 0.02 && yh - yl >= 0.02))
    throw InitError("the " + leg.side + " foot '" + leg.foot_frame +
                    "' has no flat bottom face in its collision geometry (bottom " +
                    fmt((xh - xl) * 1000, 1) + " x " + fmt((yh - yl) * 1000, 1) +
                    " mm within 5 mm of its lowest point): poise needs a flat sole (a box)");
  if (!(zmin < -1e-4))
    throw InitError("the " + leg.side + " foot '" + leg.foot_frame +
                    "': the bottom of its collision geometry is not below the foot frame origin");
  leg.sole = {xl, xh, yl, yh, -zmin};
  return zmin;
}

void RobotInit::choose_sole_frame(Leg& leg, double zmin) {
  // An existing link on the sole plane, same axes?
  for (const model::Frame& f : m.frames) {
    if (f.body != leg.foot_body || f.is_body || leg.frame_added) continue;
    if ((f.X_BF.p - Vector3(0, 0, zmin)).norm() <= 1e-4 &&
        f.X_BF.R.isApprox(Matrix3::Identity(), 1e-9)) {
      leg.sole_frame = f.name;
      break;
    }
  }
  if (leg.sole_frame.empty()) {  // robot.yaml gives it: sole_frame: {offset, rpy}
    leg.sole_frame = leg.foot_frame + "_sole_poise";
    leg.sole_added = true;
    leg.sole_offset = leg.X_BA.act(Vector3(0, 0, zmin));
    const Vector3 ypr = leg.X_BA.R.eulerAngles(2, 1, 0);  // R = Rz(yaw) Ry(pitch) Rx(roll)
    leg.sole_rpy = leg.frame_added ? Vector3(ypr[2], ypr[1], ypr[0]) : Vector3::Zero();
  }
}

// ---- forward axis: the toes' direction ----------------------------------------------------------
void RobotInit::choose_forward_axis() {
  // Each sole rectangle's long axis, pointing to the end farther from the ankle (the foot frame
  // origin): the toes. Both feet's directions at the zero configuration (base frame = world
  // there), averaged and made horizontal.
  forward = Vector3::Zero();
  std::array<Vector3, 2> toe_dirs;
  for (std::size_t s = 0; s < legs.size(); ++s) {
    const Leg& L = legs[s];
    const auto& r = L.sole;
    Vector3 toe_A;
    if (r.x_max - r.x_min >= r.y_max - r.y_min)
      toe_A = Vector3(r.x_max >= -r.x_min ? 1.0 : -1.0, 0, 0);
    else
      toe_A = Vector3(0, r.y_max >= -r.y_min ? 1.0 : -1.0, 0);
    toe_dirs[s] = (data.oMi[L.foot_body] * L.X_BA).R * toe_A;
    forward += toe_dirs[s];
  }
  forward.z() = 0.0;
  if (forward.norm() < 1e-6 || toe_dirs[0].dot(toe_dirs[1]) < 0.5) {
    checks.push_back("the toes of the two feet do not point the same way: forward_axis left at +x");
    forward = Vector3::UnitX();
  }
  forward.normalize();
  for (int k = 0; k < 3; ++k)
    if (std::abs(forward[k]) < 1e-9) forward[k] = 0.0;
  if (!forward.isApprox(Vector3::UnitX(), 1e-9))
    checks.push_back("the toes point along (" + fmt(forward.x(), 4) + ", " + fmt(forward.y(), 4) +
                     ") of the floating base, not its +x: forward_axis says so (pushes 'forward' "
                     "and the trunk pitch use it; scenarios' initial.facing_deg turns it in the "
                     "world)");
}

// ---- nominal posture: bent knees, soles flat, CoM over the sole centres -------------------------
void RobotInit::choose_left_and_right() {
  // Pitch axis: the robot's left (world +y for a robot whose toes point along +x), so that the
  // knees bend toward its own forward.
  ey = Vector3::UnitZ().cross(forward).normalized();
  // The robot's own left leg is the one on its left (ey), whatever the world y says.
  if ((data.oMi[legs[1].foot_body].p - data.oMi[legs[0].foot_body].p).dot(ey) < 0.0) {
    std::swap(legs[0], legs[1]);
    legs[0].side = "right";
    legs[1].side = "left";
    checks.push_back("the robot's own left foot is '" + legs[1].foot_frame +
                     "' (on its left, seen along its forward axis)");
  }
}

void RobotInit::find_pitch_joints() {
  // Pitch joints by geometry: the leg's sagittal plane holds the robot's forward and the line
  // from the hip to the ankle; a joint is a pitch joint when its axis is within 45 deg of that
  // plane's normal, so that most of its motion is in the plane (Unitree's H2 and R1 cant their
  // hip pitch axes 30 and 25 deg about x: |a.n| = 0.87 and 0.91; roll and yaw axes are near 0).
  const double kPitchCos = std::cos(M_PI / 4.0);
  for (Leg& leg : legs) {
    Vector3 n = ey;
    if (!leg.joints.empty()) {
      const Vector3 hip_to_ankle =
          data.oMi[leg.foot_body].p - data.oMi[leg.joints.front() + 1].p;
      const Vector3 c = hip_to_ankle.cross(forward);
      if (c.norm() > 1e-6) n = (c.dot(ey) >= 0.0 ? 1.0 : -1.0) * c.normalized();
    }
    std::vector<std::pair<int, double>> pitch;  // joint, sign of its world axis along n
    std::string others;  // the leg's other revolute joints, with their axes' angle to n
    for (int j : leg.joints) {
      if (m.joint_type[j + 1] != model::JointType::kRevolute &&
          m.joint_type[j + 1] != model::JointType::kContinuous)
        continue;
      const Vector3 aw = data.oMi[j + 1].R * m.axis[j + 1];
      if (std::abs(aw.dot(n)) > kPitchCos)
        pitch.emplace_back(j, aw.dot(n) > 0 ? 1.0 : -1.0);
      else
        others += (others.empty() ? "" : ", ") + m.joint_names[j] + " (" +
                  fmt(std::acos(std::min(1.0, std::abs(aw.dot(n)))) * 180.0 / M_PI, 0) + " deg)";
    }
    if (pitch.size() >= 3) {
      leg.hip = pitch.front().first;
      leg.s_hip = pitch.front().second;
      leg.knee = pitch[pitch.size() / 2].first;  // the middle one of three
      leg.s_knee = pitch[pitch.size() / 2].second;
      leg.ankle = pitch.back().first;
      leg.s_ankle = pitch.back().second;
    } else {
      std::string found;
      for (const auto& pj : pitch) found += (found.empty() ? "" : ", ") + m.joint_names[pj.first];
      checks.push_back("the " + leg.side + " leg has " + std::to_string(pitch.size()) +
                       " pitch joint(s) (axis within 45 deg of the normal of its sagittal plane)" +
                       (found.empty() ? std::string() : ": " + found) +
                       ", not 3 (hip, knee, ankle): knees not bent; its other joints' axes from "
                       "that normal: " + (others.empty() ? std::string("none") : others));
    }
  }
}

void RobotInit::choose_knee_bend() {
  const bool can_bend = legs[0].knee >= 0 && legs[1].knee >= 0;
  // Rotations about ey (the robot's left): knee +k (the knee forward), hip -k/2 + d, ankle
  // -k/2 - d: the sum is 0, so the sole stays parallel to the pelvis; d leans the legs to put the
  // CoM over the feet.
  knee = 0.0;
  if (can_bend) {
    knee = opt.knee_bend;
    for (const Leg& leg : legs) {
      const double lim = leg.s_knee > 0 ? m.limits[leg.knee].upper : -m.limits[leg.knee].lower;
      knee = std::min(knee, 0.9 * lim);
    }
    if (!(knee > 0.05)) {
      checks.push_back("the knee limits do not allow bending the knees forward: knees straight");
      knee = 0.0;
    }
  }
}

// The rule above keeps a sole flat only when the hip, knee and ankle pitch axes are parallel,
// and both soles level only when the legs and feet are mirror images. Otherwise (EngineAI's
// PM01: hip pitch axes canted 15 deg; its SA01: foot meshes 1.2 mm apart in height) each leg's
// joints are corrected by a damped, weighted least-squares leg IK, the pelvis held: the sole's
// normal onto the vertical and its height onto the two soles' mean (weight 1), its horizontal
// place and heading kept (weight 0.1), joint limits clamped.
void RobotInit::level_soles() {
  model::Matrix6X J_foot(6, m.nv);
  for (int it = 0; it < 60; ++it) {
    model::compute_joint_jacobians(m, data, q);
    std::array<Vector3, 2> p_sole, normal;
    double z_mean = 0.0, worst = 0.0;
    for (int s = 0; s < 2; ++s) {
      const SE3 X = data.oMi[legs[s].foot_body] * legs[s].X_BA;
      p_sole[s] = X.act(Vector3(0, 0, -legs[s].sole.height));
      normal[s] = X.R.col(2);
      z_mean += 0.5 * p_sole[s].z();
    }
    for (int s = 0; s < 2; ++s)
      worst = std::max({worst, std::abs(z_mean - p_sole[s].z()),
                        normal[s].cross(Vector3::UnitZ()).norm()});
    // Left alone when already flat and level to 0.1 mm / 1e-4 rad (the rule's posture as it
    // was, to the bit: iCub V2.7's soles are 2e-4 rad from flat there); else down to 1e-9.
    if (worst < (it == 0 ? 1e-4 : 1e-9)) return;
    for (int s = 0; s < 2; ++s) {
      const Leg& leg = legs[s];
      model::frame_point_jacobian(m, data, m.frame_id(leg.foot_frame),
                                  leg.X_BA.act(Vector3(0, 0, -leg.sole.height)), J_foot);
      Eigen::Matrix<double, 6, 1> r, w;
      const Vector3 e = normal[s].cross(Vector3::UnitZ());  // rotates the normal up
      r << 0.0, 0.0, z_mean - p_sole[s].z(), e.x(), e.y(), 0.0;
      w << 0.1, 0.1, 1.0, 1.0, 1.0, 0.1;
      const int n = static_cast<int>(leg.joints.size());
      Eigen::MatrixXd A(6, n);
      for (int k = 0; k < n; ++k) A.col(k) = w.cwiseProduct(J_foot.col(m.idx_v(leg.joints[k])));
      const Eigen::VectorXd dq =
          (A.transpose() * A + 1e-9 * Eigen::MatrixXd::Identity(n, n))
              .ldlt()
              .solve(A.transpose() * w.cwiseProduct(r));
      for (int k = 0; k < n; ++k) {
        const int j = leg.joints[k];
        q[m.idx_q(j)] = clamp_limits(m, j, q[m.idx_q(j)] + dq[k]);
      }
    }
  }
}

// q: the knees bent by `knee`, the legs leaned by d, the soles levelled.
void RobotInit::set_posture(double d) {
  q = m.neutral();
  if (knee > 0.0)
    for (const Leg& leg : legs) {
      q[m.idx_q(leg.knee)] = clamp_limits(m, leg.knee, knee * leg.s_knee);
      q[m.idx_q(leg.hip)] = clamp_limits(m, leg.hip, (-0.5 * knee + d) * leg.s_hip);
      q[m.idx_q(leg.ankle)] = clamp_limits(m, leg.ankle, (-0.5 * knee - d) * leg.s_ankle);
    }
  level_soles();
}

// The posture q with the soles' mid-height on z = 0 (sets q's base height, data's kinematics and
// CoM).
Stance RobotInit::stance() {
  Stance st;
  q[2] = 0.0;
  model::forward_kinematics(m, data, q);
  double zs = 0.0;
  for (const Leg& leg : legs)
    zs += (data.oMi[leg.foot_body] * leg.X_BA).act(Vector3(0, 0, -leg.sole.height)).z();
  q[2] = -0.5 * zs;
  model::forward_kinematics(m, data, q);
  model::center_of_mass(m, data, q);
  Eigen::Vector2d mid = Eigen::Vector2d::Zero(), lo(1e9, 1e9), hi(-1e9, -1e9);
  std::vector<double> z;
  for (const Leg& leg : legs) {
    const SE3 X = data.oMi[leg.foot_body] * leg.X_BA;
    const auto& s = leg.sole;
    mid += 0.5 * X.act(leg.stand_F()).head<2>();
    for (double x : {s.x_min, s.x_max})
      for (double y : {s.y_min, s.y_max}) {
        const Vector3 c = X.act(Vector3(x, y, -s.height));
        lo = lo.cwiseMin(c.head<2>());
        hi = hi.cwiseMax(c.head<2>());
      }
    st.tilt = std::max(st.tilt, std::acos(std::clamp(X.R.col(2).z(), -1.0, 1.0)));
    z.push_back(X.act(Vector3(0, 0, -s.height)).z());
  }
  st.dz = std::abs(z[0] - z[1]);
  st.com_error = data.com.head<2>() - mid;
  st.inside = (data.com.head<2>().array() >= lo.array()).all() &&
              (data.com.head<2>().array() <= hi.array()).all();
  return st;
}

// Lean the legs (d) to put the CoM over the mid-point of the stand points: secant on d for the
// CoM x error (sagittal). Leaves q at the posture found.
void RobotInit::lean_legs() {
  lean = 0.0;
  set_posture(lean);
  st = stance();
  if (!(knee > 0.0)) return;
  double d0 = 0.0, e0 = st.com_error.dot(fwd2), d1 = 0.05;
  set_posture(d1);
  double e1 = stance().com_error.dot(fwd2);
  for (int it = 0; it < 30 && std::abs(e1) > 1e-5 && std::abs(e1 - e0) > 1e-12; ++it) {
    const double d2 = std::clamp(d1 - e1 * (d1 - d0) / (e1 - e0), -0.5, 0.5);
    d0 = d1;
    e0 = e1;
    d1 = d2;
    set_posture(d1);
    e1 = stance().com_error.dot(fwd2);
  }
  lean = d1;
  set_posture(lean);
  st = stance();
}

void RobotInit::choose_nominal_posture() {
  // The robot's forward and left on the ground (the base frame's x and y for a REP 103 URDF).
  fwd2 = forward.head<2>().normalized();
  left2 = Eigen::Vector2d(-fwd2.y(), fwd2.x());
  lean_legs();
  // The CoM over the stance, always. Where the legs cannot lean it over the sole centres (knees
  // that cannot bend, or a lean that falls short), the stand points go under the CoM: the
  // controller's CoM target is then where the robot's CoM stands (Unitree H2, hip pitch axes
  // canted 30 deg: knees straight, CoM 37.5 mm behind the centres, every run failed).
  if (std::abs(st.com_error.dot(fwd2)) > 0.005 && !opt.stand_centres) stand_points_under_the_com();
}

void RobotInit::stand_points_under_the_com() {
  const double off_mm = st.com_error.dot(fwd2) * 1000;
  const Vector3 e_W(fwd2.x() * st.com_error.dot(fwd2), fwd2.y() * st.com_error.dot(fwd2), 0.0);
  bool inside = true;
  for (Leg& leg : legs) {
    const SE3 X = data.oMi[leg.foot_body] * leg.X_BA;
    const Eigen::Vector2d p = leg.stand_F().head<2>() + (X.R.transpose() * e_W).head<2>();
    leg.stand = Eigen::Vector2d(std::round(p.x() * 1e4) / 1e4, std::round(p.y() * 1e4) / 1e4);
    const auto& so = leg.sole;
    inside = inside && p.x() > so.x_min + 0.01 && p.x() < so.x_max - 0.01;  // safety_margin
  }
  if (!inside)
    throw InitError("in the nominal posture the CoM is " + fmt(off_mm, 1) +
                    " mm off forward of the sole centres and the legs cannot lean it over "
                    "them (" + std::string(knee > 0.0 ? "the lean falls short" : "knees straight") +
                    "); under the CoM is outside the soles' safe region: it cannot stand");
  st = stance();
  com_stand_points = true;
  checks.push_back("the CoM is " + fmt(off_mm, 1) + " mm off forward of the sole centres (" +
                   std::string(knee > 0.0 ? "leaning the legs falls short"
                                          : "the knees cannot bend, so the legs cannot lean") +
                   "): feet.<side>.stand_point puts the controller's CoM target over the points "
                   "under the CoM, (" + fmt(legs[1].stand->x(), 4) + ", " +
                   fmt(legs[1].stand->y(), 4) + ") and (" + fmt(legs[0].stand->x(), 4) + ", " +
                   fmt(legs[0].stand->y(), 4) + ") of the left and right soles");
}

void RobotInit::check_nominal_posture() {
  if (st.tilt > 1e-3)
    throw InitError("in the nominal posture a sole is tilted by " + fmt(st.tilt, 4) +
                    " rad (joint limits?)");
  if (st.dz > 1e-3)
    throw InitError("in the nominal posture the soles differ in height by " + fmt(st.dz * 1000, 2) +
                    " mm");
  if (!st.inside)
    throw InitError("in the nominal posture the CoM is not above the feet (" +
                    fmt(st.com_error.x() * 1000, 1) + ", " + fmt(st.com_error.y() * 1000, 1) +
                    " mm from the mid-point of the sole centres)");
  if (!(data.com.z() > 0.0)) {
    // The "feet" found are not the legs' ends (K-Scale's K-Bot without its foot meshes: two hip
    // links, the real legs hanging below them as "upper body").
    std::string below;
    for (const Leg& leg : legs)
      if (m.subtree_end[leg.foot_body] > leg.foot_body)
        below += " '" + leg.foot_frame + "' has " +
                 std::to_string(m.subtree_end[leg.foot_body] - leg.foot_body) +
                 " movable joint(s) below it;";
    throw InitError("in the nominal posture the CoM is " + fmt(-data.com.z(), 3) +
                    " m below the soles of '" + legs[0].foot_frame + "' and '" +
                    legs[1].foot_frame + "': these are not the feet." + below +
                    " the feet are the lowest links with collision geometry (box, cylinder, "
                    "sphere or a mesh that could be read): is the real feet's geometry missing?");
  }
  if (q[2] < 0.5 * data.com.z())
    checks.push_back("the floating base's frame origin ('" + m.body_name[0] + "') is " +
                     fmt(q[2], 3) + " m above the soles in the nominal posture, the CoM " +
                     fmt(data.com.z(), 3) + " m: a scenario's success.min_base_height_m "
                     "measures that origin (a fall criterion), so set it well below " +
                     fmt(q[2], 3) + " m for this robot");
  if (std::abs(st.com_error.dot(left2)) > 0.01)
    checks.push_back("the CoM is " + fmt(st.com_error.dot(left2) * 1000, 1) +
                     " mm sideways from the mid-point of the soles: is the robot symmetric?");
}

// ---- standing within the joints' effort limits --------------------------------------------------
// The balance controller stands the robot with its CoM over the mid-point of the sole centres,
// half the weight on each sole. The static joint torques of that stance (inverse dynamics at
// rest with those two forces at the sole centres) against the URDF's effort limits: a joint
// that needs most of its limit just to stand saturates under the controller's corrections
// (Fourier GR1T1: ankle pitch effort 15 N m, the sole centre 5 cm ahead of the ankle, 13 N m to
// stand; it tipped forward within 1.5 s, its torques clipped every tick). Where some leg joint
// needs more than half its effort, each foot gets a stand point instead: the point of its sole
// (inside the contact safety margin) where the leg's most loaded joint, as a fraction of its
// effort, needs least; the legs are leaned again to put the CoM over their mid-point.

// Joint torques of the nominal posture, soles on z = 0, half the weight on each sole at the
// given points (foot frames).
Eigen::VectorXd RobotInit::standing_torques(const std::array<Vector3, 2>& at_F) {
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(m.nv);
  set_posture(lean);
  (void)stance();
  model::clear_external_forces(data);
  for (int s = 0; s < 2; ++s) {
    const Leg& leg = legs[s];
    const SE3 X = data.oMi[leg.foot_body] * leg.X_BA;
    model::add_external_wrench(m, data, m.frame_id(leg.foot_frame), X.act(at_F[s]),
                               Vector3(0.0, 0.0, 0.5 * weight()), Vector3::Zero());
  }
  const Eigen::VectorXd tau = model::rnea(m, data, q, zero, zero);
  model::clear_external_forces(data);
  return tau;
}

double RobotInit::effort(int j) const {
  const double limit = m.limits[j].effort;
  return std::isfinite(limit) && limit > 0.0 ? limit : std::numeric_limits<double>::infinity();
}

// The leg's most loaded joint as a fraction of its effort: {fraction, joint}.
std::pair<double, int> RobotInit::most_loaded_joint(const Eigen::VectorXd& tau,
                                                    const Leg& leg) const {
  std::pair<double, int> w{0.0, -1};
  for (int j : leg.joints) {
    const double f = std::abs(tau[6 + j]) / effort(j);
    if (f > w.first) w = {f, j};
  }
  return w;
}

void RobotInit::check_standing_efforts() {
  const std::array<Vector3, 2> centres{legs[0].sole.center_F(), legs[1].sole.center_F()};
  const Eigen::VectorXd tau_c = standing_torques(centres);
  bool too_much = false;
  for (const Leg& leg : legs)
    for (int j : leg.joints) {
      const double need = std::abs(tau_c[6 + j]), limit = effort(j);
      if (need > 0.5 * limit) {
        too_much = true;
        checks.push_back(
            "standing with the CoM over the sole centres, half the weight on each, "
            "needs " +
            fmt(need, 1) + " N m of '" + m.joint_names[j] + "', " + fmt(100.0 * need / limit, 0) +
            " % of its URDF effort " + fmt(limit, 1) +
            (opt.stand_centres ? std::string(": the balance controller's corrections will "
                                             "saturate it (--stand centres; without it robot "
                                             "init puts stand points where the leg joints "
                                             "can hold the robot)")
                               : std::string(": robot.yaml stands the robot over stand points "
                                             "instead (next line)")));
      }
    }
  if (too_much && !opt.stand_centres) place_stand_points_for_efforts();
}

void RobotInit::place_stand_points_for_efforts() {
  // Each leg's joint torques are affine in where its own foot's force acts (the other foot's
  // force does not reach them): tau_j(p) = tau_j(c) + g_j . (p - c), slopes g_j by finite
  // steps along the sole's x and y. A correction moves the CoP, and every joint's torque
  // with it: along the sole's x the CoP can go r_x(p) either way from p before a leg joint
  // reaches its effort or the CoP the sole's safe edge,
  //   r_x(p) = min( min_j (L_j - |tau_j(p)|) / |g_j,x|, distances from p to the x edges ),
  // and r_y(p) the same across. The stand point maximises r_x + r_y over a grid of the safe
  // region (nearest the centre among equals; a narrow sole's r_y then does not pull x off the
  // middle of what the joints allow); a slope below 1e-6 W does not count. Leaning the legs
  // over the new points changes the torques a little: three rounds.
  const std::array<Vector3, 2> centres{legs[0].sole.center_F(), legs[1].sole.center_F()};
  std::array<CopReach, 2> reach;
  for (int round = 0; round < 3; ++round) {
    TorqueSteps tau;
    tau.at_centre = standing_torques(centres);
    tau.h = 0.01;
    std::array<Vector3, 2> px = centres, py = centres;
    for (int s = 0; s < 2; ++s) {
      px[s].x() += tau.h;
      py[s].y() += tau.h;
    }
    tau.x_step = standing_torques(px);
    tau.y_step = standing_torques(py);
    for (int s = 0; s < 2; ++s) reach[s] = place_stand_point(legs[s], tau);
    lean_legs();
  }
  report_stand_points(reach);
  set_posture(lean);
  (void)stance();
}

// One leg's stand point (leg.stand): r_x + r_y at its best over the sole's safe region
// (place_stand_points_for_efforts()).
CopReach RobotInit::place_stand_point(Leg& leg, const TorqueSteps& tau) {
  const double sole_margin = 0.01;  // robot.yaml's contact.safety_margin, written below
  const Eigen::VectorXd &tau0 = tau.at_centre, &tau_x = tau.x_step, &tau_y = tau.y_step;
  const double h = tau.h;
  const auto& so = leg.sole;
  const double mx = std::min(sole_margin, 0.25 * (so.x_max - so.x_min));
  const double my = std::min(sole_margin, 0.25 * (so.y_max - so.y_min));
  const double x0 = so.x_min + mx, x1 = so.x_max - mx, y0 = so.y_min + my,
               y1 = so.y_max - my;
  const Eigen::Vector2d c = so.center_F().head<2>();
  auto r_at = [&](const Eigen::Vector2d& p) {
    Eigen::Vector2d r(std::min(p.x() - x0, x1 - p.x()), std::min(p.y() - y0, y1 - p.y()));
    for (int j : leg.joints) {
      if (!std::isfinite(effort(j))) continue;
      const Eigen::Vector2d g((tau_x[6 + j] - tau0[6 + j]) / h,
                              (tau_y[6 + j] - tau0[6 + j]) / h);
      const double room = effort(j) - std::abs(tau0[6 + j] + g.dot(p - c));
      for (int k = 0; k < 2; ++k)
        if (std::abs(g[k]) >= 1e-6 * weight()) r[k] = std::min(r[k], room / std::abs(g[k]));
    }
    return r;
  };
  constexpr int kGrid = 120;
  double best = -std::numeric_limits<double>::infinity();
  Eigen::Vector2d best_p = c;
  auto consider = [&](const Eigen::Vector2d& p) {
    const double f = r_at(p).sum() - 1e-9 * (p - c).norm();
    if (f > best) {
      best = f;
      best_p = p;
    }
  };
  for (int a = 0; a <= kGrid; ++a)
    for (int b = 0; b <= kGrid; ++b)
      consider({x0 + (x1 - x0) * a / kGrid, y0 + (y1 - y0) * b / kGrid});
  // A finer grid over the best cell and its neighbours.
  const double sx = (x1 - x0) / kGrid, sy = (y1 - y0) / kGrid;
  const Eigen::Vector2d coarse = best_p;
  for (int a = -kGrid / 2; a <= kGrid / 2; ++a)
    for (int b = -kGrid / 2; b <= kGrid / 2; ++b)
      consider({std::clamp(coarse.x() + 4.0 * sx * a / kGrid, x0, x1),
                std::clamp(coarse.y() + 4.0 * sy * b / kGrid, y0, y1)});
  leg.stand = Eigen::Vector2d(std::round(best_p.x() * 1e4) / 1e4,
                              std::round(best_p.y() * 1e4) / 1e4);
  return {r_at(*leg.stand), r_at(c)};
}

void RobotInit::report_stand_points(const std::array<CopReach, 2>& reach) {
  const Eigen::VectorXd tau_s = standing_torques({legs[0].stand_F(), legs[1].stand_F()});
  std::string line = "the robot stands over";
  std::pair<double, int> w{0.0, -1};
  for (int s : {1, 0}) {
    const Leg& leg = legs[s];
    line += std::string(s == 1 ? " " : " and ") + "(" + fmt(leg.stand->x(), 4) + ", " +
            fmt(leg.stand->y(), 4) + ") of the " + leg.side + " sole (centre (" +
            fmt(leg.sole.center_F().x(), 4) + ", " + fmt(leg.sole.center_F().y(), 4) + "))";
    const auto ws = most_loaded_joint(tau_s, leg);
    if (ws.first > w.first) w = ws;
  }
  line +=
      ", feet.<side>.stand_point in robot.yaml: the balance controller keeps the CoM over "
      "their mid-point. From there a sole's CoP can move " +
      fmt(1000.0 * std::min(reach[0].stand.x(), reach[1].stand.x()), 1) +
      " mm forward or back and " +
      fmt(1000.0 * std::min(reach[0].stand.y(), reach[1].stand.y()), 1) +
      " mm sideways before a leg joint reaches its effort or the CoP the sole's safe edge "
      "(from the centre: " +
      fmt(1000.0 * std::min(reach[0].centre.x(), reach[1].centre.x()), 1) + " and " +
      fmt(1000.0 * std::min(reach[0].centre.y(), reach[1].centre.y()), 1) + " mm)";
  if (w.second >= 0) {
    line += "; there the most loaded leg joint, '" + m.joint_names[w.second] + "', needs " +
            fmt(std::abs(tau_s[6 + w.second]), 1) + " N m, " + fmt(100.0 * w.first, 0) +
            " % of its effort";
    if (w.first > 0.5)
      line +=
          ": still more than half; the controller's corrections will saturate it (is the "
          "effort the actuator's, or a motor's before a linkage?)";
  }
  checks.push_back(line);
}

// ---- PD gains from the joint inertias at the nominal posture ------------------------------------
// A joint's PD loop acts on the inertia the joint meets, 1 / (M^-1)_jj with the other joints
// torque-free, and that depends on what holds the robot:
//  - swing, nothing held (the floating base free): the smallest, I_swing. A leg joint meets it
//    whenever its foot is off the ground (lift-off, a foot rolling on an edge): the ankle then
//    moves the foot alone (badger of tests/robots: 0.0026 kg m^2 for an ankle roll).
//  - stance (leg joints): the leg's own foot held by the ground (6D: a flat sole), M^-1 becomes
//    M^-1 - M^-1 J^T (J M^-1 J^T)^-1 J M^-1 (J: the foot body's Jacobian). Holding a body only
//    takes freedom away, so I_stance >= I_swing: the ankle now moves the robot above it (badger:
//    5.4 kg m^2, 2100 x), a knee or a hip yaw 4.9-7 x, a hip roll or pitch 2.2-3.3 x.
// The explicit PD at the control period dt must be stable on the SMALLER inertia, the one it
// sees in swing (in stance the same gains only gain margin): kp dt^2 / I_swing <= 0.04,
// kd dt / I_swing <= 0.4. (A one-joint semi-implicit Euler loop is stable for
// kp dt^2/I + 2 kd dt/I < 4 and kd dt/I < 2; at 0.04/0.4 it also stays stable with position
// and velocity measured two ticks late, at 0.04/0.8 it does not.)
// Stiffness from the swing inertia: kp = I_swing wn^2 (kp dt^2 / I_swing = 0.01), ceiling
// kp_max. Stiffer legs were measured worse: kp = I_stance wn^2 up to the cap above (4 x on
// every leg joint below the ceiling) made badger and kestrel slip 30-37 mm after the pushes
// (likely, not verified: the double-support chain is closed through the ground, and joint
// stiffness the plan does not know about pushes the feet against each other).
// Damping: kd = 2 zeta sqrt(kp I_swing) damps the swing loop critically, but leaves the stance
// loop the damping ratio sqrt(I_swing / I_stance): 0.02 for an ankle roll, whose foot then
// rocks on its edges after a push (badger fell). Where that ratio is below 1 / sqrt(3) (stance
// inertia more than 3 x the swing one: ankles, knees, hip yaws), kd = 2 zeta sqrt(kp I_stance)
// damps the stance loop critically instead, within the cap above. Hip roll and pitch below 3 x
// keep the swing kd (the 3 is measured, not derived: damping every leg joint for stance made
// badger slip 17-19 mm, seeds 1 and 5; tests/robots/README.md).
// Joints outside the legs carry no foot: I_stance = I_swing.
// The caps bound each joint alone, not the coupled loop. So the whole robot's explicit loop
// (free floating, every joint's PD, as the simulator applies it) is checked to stay stable
// with every gain doubled; where it does not, the leg gains are scaled down together until it
// does.

// Ceiling and floor (N m/rad); the floor only where it stays within the bounds above.
constexpr double kKpMax = 2000.0, kKpMin = 1.0;
constexpr double kStanceRatio = 3.0;  // I_stance / I_swing above which kd damps the stance loop
constexpr double kRhoTol = 1e-6;      // a spectral radius above 1 + kRhoTol: unstable

void RobotInit::choose_gains() {
  model::crba(m, data, q);
  Minv = data.M.inverse();
  model::compute_joint_jacobians(m, data, q);
  auto foot_held = [&](int foot_body) {
    model::Matrix6X J(6, m.nv);
    model::frame_jacobian(m, data, m.frame_id(m.body_name[foot_body]), J);
    const Eigen::MatrixXd MJt = Minv * J.transpose();
    return Eigen::MatrixXd(Minv - MJt * (J * MJt).ldlt().solve(MJt.transpose()));
  };
  const std::array<Eigen::MatrixXd, 2> Minv_stance = {foot_held(legs[0].foot_body),
                                                      foot_held(legs[1].foot_body)};
  const double zeta = 1.0;
  leg_of.assign(m.njoints, -1);
  for (int s = 0; s < 2; ++s)
    for (int j : legs[s].joints) leg_of[j] = s;
  gains.resize(m.njoints);
  inertia.resize(m.njoints);
  inertia_stance.resize(m.njoints);
  for (int j = 0; j < m.njoints; ++j) {
    const int i = m.idx_v(j);
    const double I = 1.0 / Minv(i, i);  // swing
    const double Is = leg_of[j] >= 0 ? 1.0 / Minv_stance[leg_of[j]](i, i) : I;
    inertia[j] = I;
    inertia_stance[j] = Is;
    double kp = std::min(I * opt.wn * opt.wn, kKpMax);
    kp = std::max(kp, std::min(kKpMin, 0.04 * I / (opt.dt * opt.dt)));
    const double I_damped = Is > kStanceRatio * I ? Is : I;
    const double kd = std::min(2.0 * zeta * std::sqrt(kp * I_damped), 0.4 * I / opt.dt);
    gains[j] = {kp, kd};
  }
  stabilise_leg_gains();
  find_gain_margin();
}

// Spectral radius of the whole robot's explicit PD loop (semi-implicit Euler, [q; v] ->
// [q + dt v+; v+], v+ = v - dt M^-1 (Kp q + Kd v)) with the gains times f, the legs' also
// times `leg`. The free floating base has eigenvalues 1 (no gain on it).
double RobotInit::spectral_radius(double f, double leg) const {
  const int N = m.nv;
  Eigen::VectorXd kp = Eigen::VectorXd::Zero(N), kd = Eigen::VectorXd::Zero(N);
  for (int j = 0; j < m.njoints; ++j) {
    const double g = f * (leg_of[j] >= 0 ? leg : 1.0);
    kp[m.idx_v(j)] = g * gains[j].kp;
    kd[m.idx_v(j)] = g * gains[j].kd;
  }
  const Eigen::MatrixXd Id = Eigen::MatrixXd::Identity(N, N);
  const Eigen::MatrixXd Aq = -opt.dt * Minv * kp.asDiagonal();
  const Eigen::MatrixXd Av = Id - opt.dt * Minv * kd.asDiagonal();
  Eigen::MatrixXd A(2 * N, 2 * N);
  A << Id + opt.dt * Aq, opt.dt * Av, Aq, Av;
  return Eigen::EigenSolver<Eigen::MatrixXd>(A, false).eigenvalues().cwiseAbs().maxCoeff();
}

void RobotInit::stabilise_leg_gains() {
  leg_scale = 1.0;
  if (spectral_radius(2.0, 1.0) > 1.0 + kRhoTol) {
    double lo = 0.0, hi = 1.0;  // stable at lo (legs without gains: the upper body's own rule)
    for (int it = 0; it < 30; ++it) {
      const double mid = 0.5 * (lo + hi);
      (spectral_radius(2.0, mid) > 1.0 + kRhoTol ? hi : lo) = mid;
    }
    leg_scale = lo;
    for (int j = 0; j < m.njoints; ++j)
      if (leg_of[j] >= 0) gains[j] = {leg_scale * gains[j].kp, leg_scale * gains[j].kd};
    checks.push_back("the leg gains were scaled by " + fmt(leg_scale, 3) +
                     " so that the whole robot's explicit PD loop stays stable with every gain "
                     "doubled (the joints' own bounds did not ensure it)");
  }
}

void RobotInit::find_gain_margin() {
  // How far the gains are from instability: the factor on every gain at which it begins (to 1 %).
  margin = 2.0;
  margin_hi = 4.0;
  while (margin_hi < 1000.0 && spectral_radius(margin_hi, 1.0) <= 1.0 + kRhoTol) {
    margin = margin_hi;
    margin_hi *= 2.0;
  }
  while (margin_hi - margin > 0.01 * margin) {
    const double mid = 0.5 * (margin + margin_hi);
    (spectral_radius(mid, 1.0) > 1.0 + kRhoTol ? margin_hi : margin) = mid;
  }
}

// ---- write --------------------------------------------------------------------------------------
std::string RobotInit::joint_list(const std::vector<int>& js) const {
  std::string s = "[";
  for (std::size_t k = 0; k < js.size(); ++k)
    s += (k ? ", " : "") + m.joint_names[js[k]];
  return s + "]";
}

void RobotInit::write_robot_yaml() {
  fs::create_directories(out_dir);
  const fs::path urdf_ref = urdf_path;  // the user's own URDF: never copied or edited
  // Relative when the URDF is in the output folder, else absolute.
  std::string urdf_entry = urdf_ref.parent_path() == out_dir ? urdf_ref.filename().string()
                                                              : urdf_ref.string();

  for (int s : {1, 0})
    for (int j : legs[s].joints) leg_joints.push_back(j);
  for (int j = 0; j < m.njoints; ++j)
    if (std::find(leg_joints.begin(), leg_joints.end(), j) == leg_joints.end()) upper.push_back(j);

  std::ostringstream y;
  y << "# Generated by `poise robot init " << urdf_path.filename().string()
    << "` (components/robot_init/README.md): a first guess to check (schema: "
       "deploy/robots/README.md).\n"
    << "name: " << robot_name << "\n"
    << "urdf: " << urdf_entry << "\n"
    << "imu_frame: " << imu << "             # " << imu_where << "\n\n"
    << "feet:\n";
  write_feet(y);
  y << "\n# The robot's forward in the floating base's frame: the toes' direction (each sole's "
       "long\n"
       "# axis, toward the end farther from the ankle), both feet averaged.\n"
    << "forward_axis: [" << fmt(forward.x(), 6) << ", " << fmt(forward.y(), 6) << ", 0]\n";
  y << "\ncontact:\n  safety_margin: 0.01\n  friction_mu: 0.8\n  torsional_mu: 0.02\n";
  if ((legs[0].stand || legs[1].stand) && !com_stand_points)
    y << "  effort_limited_sole: true   # weak leg joints (stand points): the CoP only where they "
         "hold the load\n";
  y << "\n"
    << "joint_groups:\n  legs: " << joint_list(leg_joints) << "\n  upper_body: "
    << joint_list(upper) << "\n";
  write_posture_and_gains(y);
  {
    std::ofstream f(yaml_path);
    f << y.str();
    if (!f) throw InitError("cannot write " + yaml_path.string());
  }
}

void RobotInit::write_feet(std::ostream& y) const {
  for (int s : {0, 1}) {
    const Leg& L = legs[s];
    y << "  " << L.side << ":\n    frame: " << L.foot_frame << "\n    sole_frame: ";
    if (L.sole_added) {
      // the offset's z is minus the height exactly, so that the foot frame is the link itself
      const std::string h = fmt(L.sole.height);
      const std::string z = L.frame_added ? fmt(L.sole_offset.z(), 6) : (h == "0" ? h : "-" + h);
      y << "{offset: [" << fmt(L.sole_offset.x(), 6) << ", " << fmt(L.sole_offset.y(), 6) << ", "
        << z << "], rpy: [" << fmt(L.sole_rpy.x(), 9) << ", " << fmt(L.sole_rpy.y(), 9) << ", "
        << fmt(L.sole_rpy.z(), 9) << "]}   # the sole plane in " << L.foot_frame
        << " (no URDF link)";
    } else {
      y << L.sole_frame;
    }
    y << "\n    sole: {x_min: " << fmt(L.sole.x_min) << ", x_max: " << fmt(L.sole.x_max)
      << ", y_min: " << fmt(L.sole.y_min) << ", y_max: " << fmt(L.sole.y_max)
      << ", height: " << fmt(L.sole.height) << "}\n";
    if (L.stand)
      y << "    stand_point: [" << fmt(L.stand->x(), 4) << ", " << fmt(L.stand->y(), 4)
        << "]   # the CoM stands over these points, not the sole centres: their leg joints' "
           "efforts (robot init's check)\n";
  }
}

void RobotInit::write_posture_and_gains(std::ostream& y) const {
  y << "\n# Knees bent, hip + knee + ankle pitch = 0 (soles flat), legs leaned so the CoM is "
       "over "
       "the\n# mid-point of the "
    << (legs[0].stand ? "stand points" : "sole centres")
    << ". Joints not listed are 0.\nnominal_posture:\n";
  bool any = false;
  for (int j = 0; j < m.njoints; ++j)
    if (q[m.idx_q(j)] != 0.0) {
      y << "  " << m.joint_names[j] << ": " << fmt(q[m.idx_q(j)], 4) << "\n";
      any = true;
    }
  if (!any) y << "  {}\n";
  y << "\n# I = 1 / (M^-1)_jj at the nominal posture: swing (the robot free) and, for leg joints, "
       "stance (the\n# leg's own foot held). kp = min(I_swing wn^2, "
    << fmt(kKpMax, 0) << "), kd = min(2 sqrt(kp I), 0.4 I_swing / dt) with I = I_stance\n# where "
       "I_stance > " << fmt(kStanceRatio, 1) << " I_swing, else I_swing; wn = "
    << fmt(opt.wn, 1) << " rad/s, dt = " << fmt(opt.dt, 4)
    << " s (components/robot_init/README.md).";
  if (leg_scale < 1.0) y << " Leg gains then scaled by " << fmt(leg_scale, 3) << ".";
  y << "\npd_gains:\n";
  for (int j = 0; j < m.njoints; ++j) {
    y << "  " << m.joint_names[j] << ": {kp: " << sig(gains[j].kp) << ", kd: " << sig(gains[j].kd)
      << "}   # I swing " << sig(inertia[j], 3);
    if (leg_of[j] >= 0) y << ", stance " << sig(inertia_stance[j], 3);
    y << "\n";
  }
}

// ---- check with the loader, then report ---------------------------------------------------------
model::RobotConfig RobotInit::check_with_loader() const {
  try {
    return model::load_robot_config(yaml_path);
  } catch (const std::exception& e) {
    throw InitError("wrote " + yaml_path.string() + " but the loader refuses it (kept for "
                    "inspection):\n" + e.what());
  }
}

void RobotInit::report(const model::RobotConfig& cfg) const {
  std::cout << "poise robot init: " << urdf_path.string() << " (" << m.name << ", "
            << fmt(m.total_mass, 2) << " kg, " << m.njoints << " joints)\n"
            << "  floating base: " << m.body_name[0] << ", IMU frame: " << imu << "\n";
  for (int s : {1, 0}) {
    const Leg& L = legs[s];
    std::cout << "  " << L.side << " leg: " << joint_list(L.joints) << "\n    foot "
              << L.foot_frame << ", sole x [" << fmt(L.sole.x_min) << ", " << fmt(L.sole.x_max)
              << "] y [" << fmt(L.sole.y_min) << ", " << fmt(L.sole.y_max) << "], "
              << fmt(L.sole.height) << " m below the foot frame, sole frame " << L.sole_frame
              << (L.sole_added ? " (added) by robot.yaml, no URDF edit" : " (in the URDF)") << "\n";
    if (L.knee >= 0)
      std::cout << "    pitch joints: hip " << m.joint_names[L.hip] << ", knee "
                << m.joint_names[L.knee] << ", ankle " << m.joint_names[L.ankle] << "\n";
  }
  std::cout << "  forward_axis [" << fmt(forward.x(), 4) << ", " << fmt(forward.y(), 4)
            << ", 0] (base frame, from the toes)\n";
  std::cout << "  upper body: " << joint_list(upper) << "\n  nominal posture: knees "
            << fmt(knee, 3) << " rad, lean " << fmt(lean, 4) << " rad; CoM "
            << fmt(st.com_error.x() * 1000, 2) << ", " << fmt(st.com_error.y() * 1000, 2)
            << " mm from the " << (legs[0].stand ? "stand points'" : "sole centres'")
            << " mid-point; CoM height " << fmt(data.com.z(), 3) << " m\n  gains (wn "
            << fmt(opt.wn, 1)
            << " rad/s on the swing inertia, kd damping the stance inertia where it is more than "
            << fmt(kStanceRatio, 0) << " x; the whole robot's explicit PD loop becomes unstable at "
            << (margin_hi >= 1000.0 ? "more than 1000" : fmt(margin, 2))
            << " x these gains; joint kp/kd):";
  for (int j = 0; j < m.njoints; ++j)
    std::cout << (j % 4 == 0 ? "\n    " : "  ") << m.joint_names[j] << " " << sig(gains[j].kp, 4)
              << "/" << sig(gains[j].kd, 3);
  std::cout << "\n";
  std::cout << "wrote " << yaml_path.string() << " (checked by the loader: "
            << cfg.leg_joints.size() << " leg joints, " << cfg.upper_body_joints.size()
            << " upper-body joints)\n";
  std::cout << "check:\n"
            << "  - the feet, soles and leg joints above; the sole rectangle is the bottom face of "
               "the foot collision shapes\n"
            << "  - the IMU frame '" << imu
            << "': " << imu_where
            << " (an IMU link the URDF names is taken, one on the base first)\n"
            << "  - the gains: each joint a " << fmt(opt.wn, 0)
            << " rad/s loop on the inertia it meets in swing, critically damped on the inertia it "
               "carries in stance where that is larger, within the 1 kHz explicit-PD bound; tune "
               "for your actuators\n";
  for (const std::string& c : checks) std::cout << "  - " << c << "\n";
  std::cout << "next: poise model info " << yaml_path.string() << "\n";
}

int run_init(const Options& opt) {
  RobotInit init(opt, read_urdf(opt));
  init.choose_output();
  init.require_enough_joints();
  init.choose_imu();
  init.read_collision_geometry();
  init.find_feet();
  init.find_leg_joints();
  init.find_soles();
  init.choose_forward_axis();
  init.choose_left_and_right();
  init.find_pitch_joints();
  init.choose_knee_bend();
  init.choose_nominal_posture();
  init.check_nominal_posture();
  init.check_standing_efforts();
  init.choose_gains();
  init.write_robot_yaml();
  init.report(init.check_with_loader());
  return 0;
}

}  // namespace

int cli_main(int argc, char** argv) {
  CLI::App app{"Create robot configurations", "poise robot"};
  app.require_subcommand(1);
  Options opt;
  CLI::App* init = app.add_subcommand(
      "init",
      "Guess a robot.yaml from a URDF alone: legs and feet (the two lowest chains), sole "
      "rectangles (foot collision boxes), IMU on the floating base, a bent-knee nominal posture "
      "with the CoM over the feet, PD gains from each joint's effective inertia. Prints what it "
      "guessed and what to check");
  init->add_option("urdf", opt.urdf, "URDF file")->required();
  init->add_option("-o,--output", opt.out_dir,
                   "folder for the robot.yaml it writes (default: ./<urdf stem>_poise/)");
  init->add_option("--name", opt.name, "robot name (default: the URDF's)");
  init->add_flag("--force", opt.force, "overwrite an existing robot.yaml");
  init->add_option("--wn", opt.wn, "natural frequency of each joint's PD loop, rad/s")
      ->check(CLI::Range(1.0, 200.0))
      ->capture_default_str();
  std::string stand = "auto";
  init->add_option("--stand", stand,
                   "where the robot stands on its soles: auto (the sole centres, as the paper, "
                   "unless that needs more than half a leg joint's URDF effort: then stand "
                   "points where the joints hold it, feet.<side>.stand_point) or centres (always "
                   "the sole centres)")
      ->check(CLI::IsMember({"auto", "centres"}))
      ->capture_default_str();
  init->add_option("--knee", opt.knee_bend, "knee bend of the nominal posture, rad")
      ->check(CLI::Range(0.0, 1.5))
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return poise::cli::usage_exit(app, e);
  }
  opt.stand_centres = stand == "centres";
  try {
    if (*init) return run_init(opt);
  } catch (const std::exception& e) {
    std::cerr << "poise robot init: error: " << e.what() << "\n";
    return 1;
  }
  return 2;
}

}  // namespace poise::robot_init
