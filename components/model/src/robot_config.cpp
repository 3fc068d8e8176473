// robot.yaml loader and validation.
#include "poise/model/robot_config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "poise/model/centroidal.hpp"
#include "poise/model/data.hpp"
#include "poise/model/kinematics.hpp"

#include <Eigen/Geometry>
#include <urdf_parser/urdf_parser.h>

namespace poise::model {

namespace {

struct Abort {};  // ends the current section once its error is recorded

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  // Records the problem and abandons the current section (see attempt()).
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    record(key, what);
    throw Abort{};
  }
  void record(const std::string& key, const std::string& what) const {
    errors_.push_back("robot config '" + file_ + "': " + key + ": " + what);
  }
  void record_line(const std::string& line) const { errors_.push_back(line); }
  // Runs one section; its first problem is recorded and the next section still runs, so every
  // defect of a file is reported in one run.
  template <class F>
  void attempt(F&& f) const {
    try {
      f();
    } catch (const Abort&) {
    }
  }
  bool ok() const { return errors_.empty(); }
  std::size_t count() const { return errors_.size(); }
  void throw_if_errors() const {
    if (errors_.empty()) return;
    std::string all;
    for (std::size_t i = 0; i < errors_.size() && i < 60; ++i)
      all += (i == 0 ? "" : "\n") + errors_[i];
    if (errors_.size() > 60)
      all += "\n... and " + std::to_string(errors_.size() - 60) + " more problems";
    throw ModelError(all);
  }

  YAML::Node child(const YAML::Node& n, const std::string& parent, const std::string& key) const {
    if (!n.IsMap()) fail(parent, "expected a mapping");
    const YAML::Node c = n[key];
    if (!c) fail(parent.empty() ? key : parent + "." + key, "missing");
    return c;
  }
  double number(const YAML::Node& n, const std::string& key) const {
    try {
      if (!n.IsScalar()) fail(key, "expected a number");
      const double x = n.as<double>();
      if (!std::isfinite(x)) fail(key, "not a finite number");
      return x;
    } catch (const YAML::Exception&) {
      fail(key, "expected a number, got '" + n.Scalar().substr(0, 40) + "'");
    }
  }
  Vector3 vector3(const YAML::Node& n, const std::string& key) const {
    if (!n.IsSequence() || n.size() != 3) fail(key, "expected a list of 3 numbers [x, y, z]");
    Vector3 v;
    for (std::size_t i = 0; i < 3; ++i)
      v[static_cast<Eigen::Index>(i)] = number(n[i], key + "[" + std::to_string(i) + "]");
    return v;
  }
  std::string text(const YAML::Node& n, const std::string& key) const {
    if (!n.IsScalar()) fail(key, "expected a string");
    return n.as<std::string>();
  }
  std::vector<std::string> text_list(const YAML::Node& n, const std::string& key) const {
    if (!n.IsSequence()) fail(key, "expected a list of names");
    std::vector<std::string> out;
    for (const auto& e : n)
      out.push_back(text(e, key));
    return out;
  }
  // Unknown keys of a mapping (allowed empty: any key).
  void keys(const YAML::Node& n, const std::string& key,
            std::initializer_list<const char*> allowed) const {
    if (!n || !n.IsMap()) return;
    for (const auto& kv : n) {
      const std::string k = kv.first.IsScalar() ? kv.first.Scalar() : "?";
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return k == a; })) {
        std::string list;
        for (const char* a : allowed)
          list += std::string(list.empty() ? "" : ", ") + a;
        record(key.empty() ? k : key + "." + k, "unknown key (allowed: " + list + ")");
      }
    }
  }
  // Duplicated mapping keys anywhere (yaml-cpp keeps both and reads the first).
  void duplicates(const YAML::Node& n, const std::string& key, std::size_t& budget) const {
    if (budget == 0) return;
    --budget;
    if (budget == 0) {
      record(key.empty() ? "(document)" : key,
             "more than a million nodes (aliases expanding?); refused");
      return;
    }
    if (n.IsMap()) {
      std::set<std::string> seen;
      for (const auto& kv : n) {
        const std::string k = kv.first.IsScalar() ? kv.first.Scalar() : "?";
        const std::string path = key.empty() ? k : key + "." + k;
        if (!seen.insert(k).second) record(path, "duplicated key");
        duplicates(kv.second, path, budget);
      }
    } else if (n.IsSequence()) {
      std::size_t i = 0;
      for (const auto& e : n)
        duplicates(e, key + "[" + std::to_string(i++) + "]", budget);
    }
  }

 private:
  std::string file_;
  mutable std::vector<std::string> errors_;
};

}  // namespace

namespace {


// URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll).
Matrix3 rpy_to_matrix(const Vector3& rpy) {
  return (Eigen::AngleAxisd(rpy.z(), Vector3::UnitZ()) *
          Eigen::AngleAxisd(rpy.y(), Vector3::UnitY()) *
          Eigen::AngleAxisd(rpy.x(), Vector3::UnitX()))
      .toRotationMatrix();
}

SE3 urdf_pose(const urdf::Pose& p) {
  double x, y, z, w;
  p.rotation.getQuaternion(x, y, z, w);
  const Eigen::Quaterniond q(w, x, y, z);
  return SE3(q.normalized().toRotationMatrix(), Vector3(p.position.x, p.position.y, p.position.z));
}

// Lowest point of one collision primitive along +z of frame S (X_SG: the primitive in S);
// +infinity for meshes (the simulator does not collide them).
double lowest_z(const urdf::Geometry& g, const SE3& X_SG) {
  switch (g.type) {
    case urdf::Geometry::BOX: {
      const auto& b = static_cast<const urdf::Box&>(g);
      const Vector3 h(0.5 * b.dim.x, 0.5 * b.dim.y, 0.5 * b.dim.z);
      return X_SG.p.z() - X_SG.R.row(2).cwiseAbs().dot(h);
    }
    case urdf::Geometry::SPHERE:
      return X_SG.p.z() - static_cast<const urdf::Sphere&>(g).radius;
    case urdf::Geometry::CYLINDER: {
      const auto& c = static_cast<const urdf::Cylinder&>(g);
      const double az = std::min(1.0, std::abs(X_SG.R(2, 2)));
      return X_SG.p.z() - c.radius * std::sqrt(std::max(0.0, 1.0 - az * az)) - 0.5 * c.length * az;
    }
    default:
      return std::numeric_limits<double>::infinity();
  }
}



// Each foot's collision bottom relative to its sole plane (FootConfig::collision_bottom); a
// difference beyond 1 mm is a warning with both heights (the simulator places and collides
// the robot by the collision geometry, the controller by the sole plane).
void collision_bottoms(const Model& model, RobotConfig& cfg, const Reader& r) {
  const urdf::ModelInterfaceSharedPtr u = urdf::parseURDF(urdf_for_urdfdom(cfg.urdf_xml));
  if (!u) return;  // the model was built from it: not expected
  const char* side_name[2] = {"right", "left"};
  for (int side = 0; side < 2; ++side) {
    FootConfig& f = cfg.feet[static_cast<std::size_t>(side)];
    const Frame& sole = model.frames[static_cast<std::size_t>(f.sole_frame_id)];
    double lo = std::numeric_limits<double>::infinity();
    for (const auto& [name, link] : u->links_) {
      if (!link || !model.has_frame(name)) continue;
      const Frame& lf = model.frames[static_cast<std::size_t>(model.frame_id(name))];
      if (lf.body != sole.body) continue;
      for (const auto& c : link->collision_array) {
        if (!c || !c->geometry) continue;
        lo = std::min(lo, lowest_z(*c->geometry,
                                   sole.X_BF.inverse() * lf.X_BF * urdf_pose(c->origin)));
      }
    }
    if (!std::isfinite(lo)) continue;
    f.collision_bottom = lo;
    if (std::abs(lo) > 1e-3) {
      std::ostringstream os;
      os.setf(std::ios::fixed);
      os.precision(4);
      os << "feet." << side_name[side] << ": the sole plane is at z = " << -f.sole.height
         << " m in the foot frame '" << f.frame << "' but the foot's collision geometry bottom is at z = "
         << -f.sole.height + lo << " m (" << (lo < 0 ? "below" : "above") << " the sole plane by ";
      os.precision(1);
      os << std::abs(lo) * 1000.0 << " mm): the simulator places and collides the robot by its "
            "collision geometry, the controller assumes the sole plane; check sole.height or the "
            "URDF foot collision";
      cfg.warnings.push_back(os.str());
    }
  }
  (void)r;
}

// What every section of robot.yaml reads against: the document, the reader, the model (feet add
// frames to it) and the configuration being filled.
struct BodyContext {
  const YAML::Node& root;
  const Reader& r;
  Model& model;
  const std::string& urdf_origin;
  RobotConfig& cfg;

  int frame(const std::string& name, const std::string& key) const {
    if (!model.has_frame(name)) r.fail(key, "'" + name + "' is not a link of " + urdf_origin);
    return model.frame_id(name);
  }
  bool frozen(const std::string& name) const {
    return std::find(model.frozen_joints.begin(), model.frozen_joints.end(), name) !=
           model.frozen_joints.end();
  }
  int joint(const std::string& name, const std::string& key) const {
    if (!model.has_joint(name))
      r.fail(key, "'" + name + "' is not a (non-fixed) joint of " + urdf_origin);
    return model.joint_index(name);
  }
};

void read_imu_frame(const BodyContext& c) {
  c.r.attempt([&] {
    c.cfg.imu_frame = c.r.text(c.r.child(c.root, "", "imu_frame"), "imu_frame");
    c.cfg.imu_frame_id = c.frame(c.cfg.imu_frame, "imu_frame");  // on any body (estimator.hpp)
  });
}

// feet.<side>.sole: the rectangle in the foot frame and the sole's height below it.
void read_sole_rectangle(const Reader& r, const YAML::Node& fn, const std::string& base,
                         SoleRectangle& s) {
  const YAML::Node sn = r.child(fn, base, "sole");
  const std::string sb = base + ".sole";
  r.keys(sn, sb, {"x_min", "x_max", "y_min", "y_max", "height"});
  s.x_min = r.number(r.child(sn, sb, "x_min"), sb + ".x_min");
  s.x_max = r.number(r.child(sn, sb, "x_max"), sb + ".x_max");
  s.y_min = r.number(r.child(sn, sb, "y_min"), sb + ".y_min");
  s.y_max = r.number(r.child(sn, sb, "y_max"), sb + ".y_max");
  s.height = r.number(r.child(sn, sb, "height"), sb + ".height");
  if (!(s.x_min < s.x_max) || !(s.y_min < s.y_max))
    r.fail(sb, "empty rectangle (need x_min < x_max and y_min < y_max)");
  if (!(s.height >= 0.0)) r.fail(sb + ".height", "must be >= 0");
  for (double v : {s.x_min, s.x_max, s.y_min, s.y_max, s.height})
    if (std::abs(v) > 10.0) r.fail(sb, "implausible: a sole coordinate beyond 10 m");
}

// feet.<side>.stand_point (optional): a point inside the sole rectangle.
void read_stand_point(const Reader& r, const YAML::Node& fn, const std::string& base,
                      FootConfig& foot) {
  const YAML::Node pn = fn["stand_point"];
  if (!pn) return;
  const SoleRectangle& s = foot.sole;
  const std::string pk = base + ".stand_point";
  if (!pn.IsSequence() || pn.size() != 2) r.fail(pk, "expected a list of 2 numbers [x, y]");
  const Eigen::Vector2d p(r.number(pn[0], pk + "[0]"), r.number(pn[1], pk + "[1]"));
  if (!(p.x() >= s.x_min && p.x() <= s.x_max && p.y() >= s.y_min && p.y() <= s.y_max))
    r.fail(pk, "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) +
                   ") is outside the sole rectangle x [" + std::to_string(s.x_min) + ", " +
                   std::to_string(s.x_max) + "] y [" + std::to_string(s.y_min) + ", " +
                   std::to_string(s.y_max) + "]");
  foot.stand_point = p;
}

// The sole frame given as an offset and rotation in the foot link: no URDF link needed.
void read_sole_frame_offset(const BodyContext& c, const YAML::Node& sfn, const std::string& sk,
                            FootConfig& foot) {
  const Reader& r = c.r;
  r.keys(sfn, sk, {"offset", "rpy"});
  const Vector3 offset = r.vector3(r.child(sfn, sk, "offset"), sk + ".offset");
  const Vector3 rpy = sfn["rpy"] ? r.vector3(sfn["rpy"], sk + ".rpy") : Vector3::Zero();
  if (offset.norm() > 10.0) r.fail(sk + ".offset", "implausible: more than 10 m from the link");
  for (int k = 0; k < 3; ++k)
    if (std::abs(rpy[k]) > 2.0 * M_PI + 1e-9)
      r.fail(sk + ".rpy", "bad rotation: an angle beyond 2 pi (radians, not degrees)");
  foot.sole_from_offset = true;
  foot.X_link_sole = SE3(rpy_to_matrix(rpy), offset);
  foot.sole_frame = foot.link + "_sole_poise";
  foot.X_link_foot =
      foot.X_link_sole * SE3(Matrix3::Identity(), Vector3(0.0, 0.0, foot.sole.height));
  if (foot.X_link_foot.is_approx(SE3::Identity(), 1e-12)) {
    foot.frame = foot.link;  // F is the link itself
    foot.X_link_foot = SE3::Identity();
  } else {
    foot.frame = foot.link + "_foot_poise";
  }
  for (const std::string& n : {foot.sole_frame, foot.frame})
    if (n != foot.link && c.model.has_frame(n))
      r.fail(sk, "'" + n + "' (the frame this entry adds) is already a link of " + c.urdf_origin);
}

// The sole frame given as a URDF link: rigidly attached to the foot link, at the sole height
// below it, with the foot link's axes.
void read_sole_frame_link(const BodyContext& c, const YAML::Node& sfn, const std::string& base,
                          const std::string& sk, int link_id, FootConfig& foot) {
  const Reader& r = c.r;
  const double height = foot.sole.height;
  const Frame& lf = c.model.frames[link_id];
  foot.frame = foot.link;
  foot.sole_frame = r.text(sfn, sk + " (a link name, or {offset: [x, y, z], rpy: [r, p, y]})");
  foot.sole_frame_id = c.frame(foot.sole_frame, sk);
  const Frame& sf = c.model.frames[foot.sole_frame_id];
  if (lf.body != sf.body)
    r.fail(sk, "'" + foot.sole_frame + "' is not rigidly attached to '" + foot.link + "'");
  foot.X_link_sole = lf.X_BF.inverse() * sf.X_BF;
  const SE3& X_FS = foot.X_link_sole;
  const bool at = (X_FS.p - Vector3(0.0, 0.0, -height)).norm() <= 1e-3;
  const bool axes = X_FS.R.isApprox(Matrix3::Identity(), 1e-6);
  if (!at || !axes) {
    std::ostringstream os;
    os << "sole frame '" << foot.sole_frame << "' is at (" << X_FS.p.transpose() << ") in '"
       << foot.link << "'";
    if (!axes)
      os << " and its axes differ from the foot frame's (its z axis is ("
         << X_FS.R.col(2).transpose() << ") in '" << foot.link << "')";
    os << "; expected (0, 0, " << -height
       << ") with the same axes. Give the sole instead as sole_frame: {offset: [x, y, z], "
          "rpy: [roll, pitch, yaw]} in '"
       << foot.link << "' (no URDF link needed; deploy/robots/README.md)";
    r.fail(base, os.str());
  }
}

// feet.right or feet.left.
void read_foot(const BodyContext& c, const YAML::Node& feet, Side side, const char* key) {
  const Reader& r = c.r;
  const std::string base = std::string("feet.") + key;
  const YAML::Node fn = r.child(feet, "feet", key);
  r.keys(fn, base, {"frame", "sole_frame", "sole", "stand_point"});
  FootConfig& foot = c.cfg.feet[side];
  foot.link = r.text(r.child(fn, base, "frame"), base + ".frame");
  const int link_id = c.frame(foot.link, base + ".frame");
  read_sole_rectangle(r, fn, base, foot.sole);
  read_stand_point(r, fn, base, foot);
  const YAML::Node sfn = r.child(fn, base, "sole_frame");
  const std::string sk = base + ".sole_frame";
  if (sfn.IsMap())
    read_sole_frame_offset(c, sfn, sk, foot);
  else
    read_sole_frame_link(c, sfn, base, sk, link_id, foot);
}

// The feet; when they are valid, their frames are added to the model. Returns whether they are.
bool read_feet(const BodyContext& c) {
  const Reader& r = c.r;
  RobotConfig& cfg = c.cfg;
  const std::size_t errors_before_feet = r.count();
  r.attempt([&] {
    const YAML::Node feet = r.child(c.root, "", "feet");
    r.keys(feet, "feet", {"right", "left"});
    for (const auto& [side, key] : {std::pair{kRight, "right"}, std::pair{kLeft, "left"}})
      r.attempt([&, side = side, key = key] { read_foot(c, feet, side, key); });
    if (r.count() == errors_before_feet && cfg.feet[kRight].frame == cfg.feet[kLeft].frame)
      r.fail("feet", "left and right use the same frame");
  });
  const bool feet_ok = r.count() == errors_before_feet;
  if (feet_ok) {
    add_config_frames(c.model, cfg);
    for (FootConfig& f : cfg.feet) {
      f.frame_id = c.model.frame_id(f.frame);
      f.sole_frame_id = c.model.frame_id(f.sole_frame);
    }
    collision_bottoms(c.model, cfg, r);
  }
  return feet_ok;
}

void read_forward_axis(const BodyContext& c) {
  c.r.attempt([&] {
    if (!c.root["forward_axis"]) return;
    const Vector3 a = c.r.vector3(c.root["forward_axis"], "forward_axis");
    if (a.norm() < 1e-6) c.r.fail("forward_axis", "must not be zero");
    const Vector3 u = a.normalized();
    if (std::abs(u.z()) > 0.1)
      c.r.fail("forward_axis",
               "must be (nearly) horizontal in the base frame (z component <= 0.1)");
    c.cfg.forward_axis = Vector3(u.x(), u.y(), 0.0).normalized();
  });
}

// contact: margins and friction; the margin is checked against the soles when the feet are valid.
void read_contact(const BodyContext& c, bool feet_ok) {
  const Reader& r = c.r;
  RobotConfig& cfg = c.cfg;
  r.attempt([&] {
    const YAML::Node contact = r.child(c.root, "", "contact");
    r.keys(contact, "contact",
           {"safety_margin", "friction_mu", "torsional_mu", "effort_limited_sole"});
    if (const YAML::Node e = contact["effort_limited_sole"]) {
      if (!e.IsScalar() || (e.Scalar() != "true" && e.Scalar() != "false"))
        r.fail("contact.effort_limited_sole", "expected true or false");
      cfg.effort_limited_sole = e.Scalar() == "true";
    }
    cfg.safety_margin =
        r.number(r.child(contact, "contact", "safety_margin"), "contact.safety_margin");
    cfg.friction_mu = r.number(r.child(contact, "contact", "friction_mu"), "contact.friction_mu");
    cfg.torsional_mu =
        r.number(r.child(contact, "contact", "torsional_mu"), "contact.torsional_mu");
    if (cfg.safety_margin < 0.0) r.fail("contact.safety_margin", "must be >= 0");
    if (!(cfg.friction_mu > 0.0)) r.fail("contact.friction_mu", "must be > 0");
    if (cfg.torsional_mu < 0.0) r.fail("contact.torsional_mu", "must be >= 0");
    for (const FootConfig& f : cfg.feet) {
      if (!feet_ok) break;
      if (2.0 * cfg.safety_margin >=
          std::min(f.sole.x_max - f.sole.x_min, f.sole.y_max - f.sole.y_min))
        r.fail("contact.safety_margin", "leaves no safe region inside the sole of " + f.frame);
    }
  });
}

// joint_groups: every (non-frozen) joint in exactly one of legs and upper_body.
void read_joint_groups(const BodyContext& c) {
  const Reader& r = c.r;
  RobotConfig& cfg = c.cfg;
  r.attempt([&] {
    const YAML::Node groups = r.child(c.root, "", "joint_groups");
    r.keys(groups, "joint_groups", {"legs", "upper_body"});
    cfg.leg_joints = r.text_list(r.child(groups, "joint_groups", "legs"), "joint_groups.legs");
    cfg.upper_body_joints =
        r.text_list(r.child(groups, "joint_groups", "upper_body"), "joint_groups.upper_body");
    std::vector<int> group_of(c.model.njoints, -1);
    for (int g = 0; g < 2; ++g) {
      auto& names = g == 0 ? cfg.leg_joints : cfg.upper_body_joints;
      auto& idx = g == 0 ? cfg.leg_joint_indices : cfg.upper_body_joint_indices;
      const std::string key = g == 0 ? "joint_groups.legs" : "joint_groups.upper_body";
      std::vector<std::string> kept;
      for (const std::string& n : names) {
        if (c.frozen(n)) continue;  // a frozen mimic joint is no model joint: entry ignored
        r.attempt([&] {
          const int j = c.joint(n, key);
          if (group_of[j] != -1) r.fail(key, "joint '" + n + "' is listed twice");
          group_of[j] = g;
          idx.push_back(j);
          kept.push_back(n);
        });
      }
      names = kept;
    }
    for (int j = 0; j < c.model.njoints; ++j)
      if (group_of[j] == -1)
        r.record("joint_groups", "joint '" + c.model.joint_names[j] + "' belongs to no group");
  });
}

// nominal_posture into `q` (the model's neutral configuration); returns whether it is valid.
bool read_nominal_posture(const BodyContext& c, Eigen::VectorXd& q) {
  const Reader& r = c.r;
  const Model& model = c.model;
  const std::size_t errors_before_posture = r.count();
  r.attempt([&] {
    const YAML::Node posture = r.child(c.root, "", "nominal_posture");
    if (!posture.IsMap()) r.fail("nominal_posture", "expected a mapping joint: angle");
    for (const auto& kv : posture) {
      r.attempt([&] {
        const std::string n = r.text(kv.first, "nominal_posture");
        const std::string key = "nominal_posture." + n;
        if (c.frozen(n)) return;  // frozen mimic joint: the model fixed it (README "Mimic joints")
        const int j = c.joint(n, key);
        const double x = r.number(kv.second, key);
        if (x < model.limits[j].lower || x > model.limits[j].upper) {
          std::ostringstream os;
          os << x << " is outside the joint limits [" << model.limits[j].lower << ", "
             << model.limits[j].upper << "]";
          r.fail(key, os.str());
        }
        q[model.idx_q(j)] = x;
      });
    }
  });
  return r.count() == errors_before_posture;
}

// The nominal stance: both soles flat and level (the base height `q[2]` is set so that they are
// at z = 0), the CoM above the box of the feet.
void check_nominal_stance(const BodyContext& c, Eigen::VectorXd& q) {
  const Reader& r = c.r;
  const Model& model = c.model;
  const RobotConfig& cfg = c.cfg;
  r.attempt([&] {
    Data data(model);
    forward_kinematics(model, data, q);
    double z_sum = 0.0;
    for (const FootConfig& f : cfg.feet) {
      const SE3 X = frame_placement(model, data, f.sole_frame_id);
      if (X.R.col(2).z() < std::cos(1e-3))
        r.fail("nominal_posture", "the sole of '" + f.frame + "' is not flat (tilted)");
      z_sum += X.p.z();
    }
    q[2] = -0.5 * z_sum;
    forward_kinematics(model, data, q);
    const double dz = frame_placement(model, data, cfg.feet[0].sole_frame_id).p.z() -
                      frame_placement(model, data, cfg.feet[1].sole_frame_id).p.z();
    if (std::abs(dz) > 1e-3) r.fail("nominal_posture", "the two soles are not at the same height");
    center_of_mass(model, data, q);
    Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
    for (const FootConfig& f : cfg.feet) {
      const SE3 X = frame_placement(model, data, f.frame_id);
      for (double x : {f.sole.x_min, f.sole.x_max})
        for (double y : {f.sole.y_min, f.sole.y_max}) {
          const Vector3 p = X.act(Vector3(x, y, -f.sole.height));
          lo = lo.cwiseMin(p.head<2>());
          hi = hi.cwiseMax(p.head<2>());
        }
    }
    const Eigen::Vector2d com = data.com.head<2>();
    if ((com.array() < lo.array()).any() || (com.array() > hi.array()).any()) {
      std::ostringstream os;
      os << "the CoM (" << com.transpose() << ") is not above the feet";
      r.fail("nominal_posture", os.str());
    }
  });
}

// pd_gains: per joint or `default`; every (non-frozen) joint needs gains.
void read_pd_gains(const BodyContext& c) {
  const Reader& r = c.r;
  const Model& model = c.model;
  RobotConfig& cfg = c.cfg;
  r.attempt([&] {
    const YAML::Node gains = r.child(c.root, "", "pd_gains");
    if (!gains.IsMap()) r.fail("pd_gains", "expected a mapping");
    auto read_gains = [&](const YAML::Node& n, const std::string& key) {
      JointGains g;
      r.keys(n, key, {"kp", "kd"});
      g.kp = r.number(r.child(n, key, "kp"), key + ".kp");
      g.kd = r.number(r.child(n, key, "kd"), key + ".kd");
      if (g.kp < 0.0) r.fail(key + ".kp", "must be >= 0");
      if (g.kd < 0.0) r.fail(key + ".kd", "must be >= 0");
      return g;
    };
    bool have_default = false;
    JointGains def;
    std::vector<bool> set(model.njoints, false);
    cfg.gains.assign(model.njoints, JointGains{});
    for (const auto& kv : gains) {
      r.attempt([&] {
        const std::string n = r.text(kv.first, "pd_gains");
        const std::string key = "pd_gains." + n;
        if (n == "default") {
          have_default = true;
          def = read_gains(kv.second, key);
          return;
        }
        if (c.frozen(n)) return;
        const int j = c.joint(n, key);
        set[j] = true;
        cfg.gains[j] = read_gains(kv.second, key);
      });
    }
    for (int j = 0; j < model.njoints; ++j) {
      if (set[j]) continue;
      if (!have_default)
        r.record("pd_gains", "no gains for joint '" + model.joint_names[j] + "' and no default");
      cfg.gains[j] = def;
    }
  });
}

// Everything of robot.yaml but `name` and `urdf`, checked against `model`; `urdf_origin` names
// the model's source in messages. Each section records its first problem and the next still
// runs (Reader::attempt).
void read_config_body(const YAML::Node& root, const Reader& r, Model& model,
                      const std::string& urdf_origin, RobotConfig& cfg) {
  const BodyContext c{root, r, model, urdf_origin, cfg};
  read_imu_frame(c);
  const bool feet_ok = read_feet(c);
  read_forward_axis(c);
  read_contact(c, feet_ok);
  read_joint_groups(c);
  Eigen::VectorXd q = model.neutral();
  const bool posture_ok = read_nominal_posture(c, q);
  // The stance checks need valid feet and posture.
  if (posture_ok && feet_ok) check_nominal_stance(c, q);
  cfg.q_nominal = q;
  read_pd_gains(c);
}

// Structure of the document: duplicated keys anywhere, unknown top-level keys.
void check_structure(const YAML::Node& root, const Reader& r) {
  std::size_t budget = 1000000;
  r.duplicates(root, "", budget);
  r.keys(root, "",
         {"name", "urdf", "imu_frame", "feet", "contact", "joint_groups", "nominal_posture",
          "pd_gains", "forward_axis"});
}

// 'text' (appended piece by piece: GCC 12 warns, wrongly, of overlapping copies in "'" + s + "'").
std::string quoted(const std::string& text) {
  std::string q;
  q.reserve(text.size() + 2);
  q += '\'';
  q += text;
  q += '\'';
  return q;
}

// Builds the model; a URDF problem is recorded with the robot.yaml ones and all are thrown.
template <class Build>
Model model_or_throw(const Reader& r, Build&& build) {
  try {
    return build();
  } catch (const ModelError& e) {
    r.record_line(e.what());
    r.throw_if_errors();
    throw;
  }
}

}  // namespace

RobotConfig load_robot_config(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw ModelError("robot config not found: '" + path.string() + "'");
  const std::string text = read_text_file_limited(path, "robot config");
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ModelError("robot config '" + path.string() + "': bad YAML: " + e.what());
  }
  if (!root.IsMap()) throw ModelError("robot config '" + path.string() + "': expected a mapping");
  const Reader r(path.string());
  check_structure(root, r);
  RobotConfig cfg;
  cfg.config_path = std::filesystem::absolute(path);
  std::filesystem::path urdf;
  r.attempt([&] { cfg.name = r.text(r.child(root, "", "name"), "name"); });
  r.attempt([&] { urdf = r.text(r.child(root, "", "urdf"), "urdf"); });
  if (urdf.empty()) r.throw_if_errors();
  cfg.urdf_path = urdf.is_absolute() ? urdf : cfg.config_path.parent_path() / urdf;
  bool have_urdf = false;
  r.attempt([&] {
    try {
      cfg.urdf_xml = read_text_file_limited(cfg.urdf_path, "URDF");
      have_urdf = true;
    } catch (const ModelError& e) {
      r.fail("urdf", e.what());
    }
  });
  if (!have_urdf) r.throw_if_errors();
  Model model = model_or_throw(
      r, [&] { return build_model_from_urdf_string(cfg.urdf_xml, quoted(cfg.urdf_path.string())); });
  read_config_body(root, r, model, cfg.urdf_path.string(), cfg);
  r.throw_if_errors();
  for (const std::string& n : model.notes)
    std::fprintf(stderr, "robot config '%s': note: %s\n", path.string().c_str(), n.c_str());
  for (const std::string& w : cfg.warnings)
    std::fprintf(stderr, "robot config '%s': warning: %s\n", path.string().c_str(), w.c_str());
  return cfg;
}

RobotConfig parse_robot_config(const std::string& yaml_text, const std::string& urdf_text,
                               const std::string& origin) {
  if (yaml_text.size() > kMaxFileBytes)
    throw ModelError("robot config " + origin + ": larger than the limit of " +
                     std::to_string(kMaxFileBytes) + " bytes");
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ModelError("robot config " + origin + ": bad YAML: " + e.what());
  }
  if (!root.IsMap()) throw ModelError("robot config " + origin + ": expected a mapping");
  const Reader r(origin);
  check_structure(root, r);
  RobotConfig cfg;
  r.attempt([&] { cfg.name = r.text(r.child(root, "", "name"), "name"); });
  const std::string urdf_origin = "the URDF of " + origin;
  Model model =
      model_or_throw(r, [&] { return build_model_from_urdf_string(urdf_text, urdf_origin); });
  cfg.urdf_xml = urdf_text;
  read_config_body(root, r, model, urdf_origin, cfg);
  r.throw_if_errors();
  return cfg;
}

Model load_robot_model(const RobotConfig& config) {
  Model model =
      !config.urdf_xml.empty()
          ? build_model_from_urdf_string(config.urdf_xml, config.urdf_path.empty()
                                                              ? "of robot '" + config.name + "'"
                                                              : quoted(config.urdf_path.string()))
          : build_model_from_urdf_file(config.urdf_path);
  add_config_frames(model, config);
  return model;
}

void add_config_frames(Model& model, const RobotConfig& config) {
  for (const FootConfig& f : config.feet) {
    if (!f.sole_from_offset || f.link.empty()) continue;
    const Frame link = model.frames[static_cast<std::size_t>(model.frame_id(f.link))];
    auto add = [&](const std::string& name, const SE3& X_LF) {
      if (name == f.link || model.has_frame(name)) return;
      Frame fr;
      fr.name = name;
      fr.body = link.body;
      fr.X_BF = link.X_BF * X_LF;
      fr.is_body = false;
      model.frames.push_back(fr);
    };
    add(f.sole_frame, f.X_link_sole);
    add(f.frame, f.X_link_foot);
  }
}

}  // namespace poise::model
