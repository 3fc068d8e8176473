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

// Everything of robot.yaml but `name` and `urdf`, checked against `model`; `urdf_origin` names
// the model's source in messages.
void read_config_body(const YAML::Node& root, const Reader& r, const Model& model,
                      const std::string& urdf_origin, RobotConfig& cfg) {
  auto frame = [&](const std::string& name, const std::string& key) {
    if (!model.has_frame(name)) r.fail(key, "'" + name + "' is not a link of " + urdf_origin);
    return model.frame_id(name);
  };
  auto frozen = [&](const std::string& name) {
    return std::find(model.frozen_joints.begin(), model.frozen_joints.end(), name) !=
           model.frozen_joints.end();
  };
  auto joint = [&](const std::string& name, const std::string& key) {
    if (!model.has_joint(name))
      r.fail(key, "'" + name + "' is not a (non-fixed) joint of " + urdf_origin);
    return model.joint_index(name);
  };

  r.attempt([&] {
    cfg.imu_frame = r.text(r.child(root, "", "imu_frame"), "imu_frame");
    cfg.imu_frame_id = frame(cfg.imu_frame, "imu_frame");
    const int body = model.frames[cfg.imu_frame_id].body;
    if (body != 0)
      r.fail("imu_frame", "IMU frame '" + cfg.imu_frame + "' is attached to body '" +
                              model.body_name[body] + "', not to the floating base '" +
                              model.body_name[0] + "' (only a base-mounted IMU is supported)");
  });

  // ---- feet -----------------------------------------------------------------------------------
  bool feet_ok = true;
  const std::size_t errors_before_feet = r.count();
  r.attempt([&] {
  const YAML::Node feet = r.child(root, "", "feet");
  r.keys(feet, "feet", {"right", "left"});
  for (const auto& [side, key] : {std::pair{kRight, "right"}, std::pair{kLeft, "left"}}) {
    const std::string base = std::string("feet.") + key;
    r.attempt([&, side = side, key = key] {
    const YAML::Node fn = r.child(feet, "feet", key);
    r.keys(fn, base, {"frame", "sole_frame", "sole"});
    FootConfig& foot = cfg.feet[side];
    foot.frame = r.text(r.child(fn, base, "frame"), base + ".frame");
    foot.frame_id = frame(foot.frame, base + ".frame");
    foot.sole_frame = r.text(r.child(fn, base, "sole_frame"), base + ".sole_frame");
    foot.sole_frame_id = frame(foot.sole_frame, base + ".sole_frame");
    const YAML::Node sn = r.child(fn, base, "sole");
    const std::string sb = base + ".sole";
    r.keys(sn, sb, {"x_min", "x_max", "y_min", "y_max", "height"});
    SoleRectangle& s = foot.sole;
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
    const Frame& ff = model.frames[foot.frame_id];
    const Frame& sf = model.frames[foot.sole_frame_id];
    if (ff.body != sf.body)
      r.fail(base + ".sole_frame",
             "'" + foot.sole_frame + "' is not rigidly attached to '" + foot.frame + "'");
    const SE3 X_FS = ff.X_BF.inverse() * sf.X_BF;
    if ((X_FS.p - Vector3(0.0, 0.0, -s.height)).norm() > 1e-3 ||
        !X_FS.R.isApprox(Matrix3::Identity(), 1e-6)) {
      std::ostringstream os;
      os << "sole frame '" << foot.sole_frame << "' is at " << X_FS.p.transpose() << " in '"
         << foot.frame << "'; expected (0, 0, " << -s.height << ") with the same axes";
      r.fail(base, os.str());
    }
    });
  }
  if (r.count() == errors_before_feet && cfg.feet[kRight].frame == cfg.feet[kLeft].frame)
    r.fail("feet", "left and right use the same frame");
  });
  if (r.count() != errors_before_feet) feet_ok = false;

  // ---- contact --------------------------------------------------------------------------------
  r.attempt([&] {
  const YAML::Node contact = r.child(root, "", "contact");
  r.keys(contact, "contact", {"safety_margin", "friction_mu", "torsional_mu"});
  cfg.safety_margin =
      r.number(r.child(contact, "contact", "safety_margin"), "contact.safety_margin");
  cfg.friction_mu = r.number(r.child(contact, "contact", "friction_mu"), "contact.friction_mu");
  cfg.torsional_mu = r.number(r.child(contact, "contact", "torsional_mu"), "contact.torsional_mu");
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

  // ---- joint groups ---------------------------------------------------------------------------
  r.attempt([&] {
  const YAML::Node groups = r.child(root, "", "joint_groups");
  r.keys(groups, "joint_groups", {"legs", "upper_body"});
  cfg.leg_joints = r.text_list(r.child(groups, "joint_groups", "legs"), "joint_groups.legs");
  cfg.upper_body_joints =
      r.text_list(r.child(groups, "joint_groups", "upper_body"), "joint_groups.upper_body");
  std::vector<int> group_of(model.njoints, -1);
  for (int g = 0; g < 2; ++g) {
    auto& names = g == 0 ? cfg.leg_joints : cfg.upper_body_joints;
    auto& idx = g == 0 ? cfg.leg_joint_indices : cfg.upper_body_joint_indices;
    const std::string key = g == 0 ? "joint_groups.legs" : "joint_groups.upper_body";
    std::vector<std::string> kept;
    for (const std::string& n : names) {
      if (frozen(n)) continue;  // a frozen mimic joint is no model joint: entry ignored
      r.attempt([&] {
        const int j = joint(n, key);
        if (group_of[j] != -1) r.fail(key, "joint '" + n + "' is listed twice");
        group_of[j] = g;
        idx.push_back(j);
        kept.push_back(n);
      });
    }
    names = kept;
  }
  for (int j = 0; j < model.njoints; ++j)
    if (group_of[j] == -1)
      r.record("joint_groups", "joint '" + model.joint_names[j] + "' belongs to no group");
  });

  // ---- nominal posture ------------------------------------------------------------------------
  Eigen::VectorXd q = model.neutral();
  const std::size_t errors_before_posture = r.count();
  bool posture_ok = true;
  r.attempt([&] {
  const YAML::Node posture = r.child(root, "", "nominal_posture");
  if (!posture.IsMap()) r.fail("nominal_posture", "expected a mapping joint: angle");
  for (const auto& kv : posture) {
    r.attempt([&] {
    const std::string n = r.text(kv.first, "nominal_posture");
    const std::string key = "nominal_posture." + n;
    if (frozen(n)) return;  // frozen mimic joint: the model fixed it (README "Mimic joints")
    const int j = joint(n, key);
    const double x = r.number(kv.second, key);
    if (x < model.limits[j].lower || x > model.limits[j].upper) {
      std::ostringstream os;
      os << x << " is outside the joint limits [" << model.limits[j].lower << ", "
         << model.limits[j].upper << "]";
      posture_ok = false;
      r.fail(key, os.str());
    }
    q[model.idx_q(j)] = x;
    });
  }
  });
  if (r.count() != errors_before_posture) posture_ok = false;
  // The stance checks need valid feet and posture.
  if (posture_ok && feet_ok) r.attempt([&] {
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
        const Vector3 c = X.act(Vector3(x, y, -f.sole.height));
        lo = lo.cwiseMin(c.head<2>());
        hi = hi.cwiseMax(c.head<2>());
      }
  }
  const Eigen::Vector2d com = data.com.head<2>();
  if ((com.array() < lo.array()).any() || (com.array() > hi.array()).any()) {
    std::ostringstream os;
    os << "the CoM (" << com.transpose() << ") is not above the feet";
    r.fail("nominal_posture", os.str());
  }
  });
  cfg.q_nominal = q;

  // ---- gains ----------------------------------------------------------------------------------
  r.attempt([&] {
  const YAML::Node gains = r.child(root, "", "pd_gains");
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
    if (frozen(n)) return;
    const int j = joint(n, key);
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

// Structure of the document: duplicated keys anywhere, unknown top-level keys.
void check_structure(const YAML::Node& root, const Reader& r) {
  std::size_t budget = 1000000;
  r.duplicates(root, "", budget);
  r.keys(root, "",
         {"name", "urdf", "imu_frame", "feet", "contact", "joint_groups", "nominal_posture",
          "pd_gains"});
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
  const Model model = model_or_throw(
      r, [&] { return build_model_from_urdf_string(cfg.urdf_xml, "'" + cfg.urdf_path.string() + "'"); });
  read_config_body(root, r, model, cfg.urdf_path.string(), cfg);
  r.throw_if_errors();
  for (const std::string& n : model.notes)
    std::fprintf(stderr, "robot config '%s': note: %s\n", path.string().c_str(), n.c_str());
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
  const Model model =
      model_or_throw(r, [&] { return build_model_from_urdf_string(urdf_text, urdf_origin); });
  cfg.urdf_xml = urdf_text;
  read_config_body(root, r, model, urdf_origin, cfg);
  r.throw_if_errors();
  return cfg;
}

Model load_robot_model(const RobotConfig& config) {
  if (!config.urdf_xml.empty())
    return build_model_from_urdf_string(
        config.urdf_xml,
        config.urdf_path.empty() ? "of robot '" + config.name + "'" : "'" + config.urdf_path.string() + "'");
  return build_model_from_urdf_file(config.urdf_path);
}

}  // namespace poise::model
