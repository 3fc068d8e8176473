#include "poise/sim/world.hpp"
#include "poise/cli/read_file.hpp"
#include "poise/sim/simulator.hpp"
#include "poise/sim/yaml_checks.hpp"
#include "reality_detail.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#ifdef POISE_SIM_HAVE_MODEL
#include "poise/model/centroidal.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#endif

namespace poise::sim {
namespace {

namespace fs = std::filesystem;

// The checks shared with the scenario format (yaml_checks.hpp), and files relative to the world's
// own file.
struct Ctx : YamlChecks {
  fs::path base_dir;
  fs::path path(const YAML::Node& n, const std::string& key) const {
    const fs::path p = str(n, key);
    if (p.is_absolute()) return p;
    const fs::path a = base_dir / p;
    if (fs::exists(a)) return fs::weakly_canonical(a);
#ifdef POISE_SIM_SOURCE_DIR
    const fs::path b = fs::path(POISE_SIM_SOURCE_DIR) / p;
    if (fs::exists(b)) return fs::weakly_canonical(b);
#endif
    fail(key, "file '" + p.string() + "' not found (relative to " + base_dir.string() +
                  " or the source tree)");
  }
};

constexpr double kDeg = M_PI / 180.0;
// Physical ranges of a scenario (scenario_schema.cpp declares them for the docs).
constexpr double kMaxGravity = 100.0;     // m/s^2, |world.gravity|
constexpr double kMaxPushForce = 5000.0;  // N, |force| of a scripted push
constexpr double kMaxPushLever = 5.0;     // m, |point| of a push in its link's frame
constexpr double kMinDuration = 0.001;    // s, one control period

Sinusoid sinusoid(const Ctx& c, const YAML::Node& n, const std::string& key, bool angular,
                  Eigen::Vector3d& axis) {
  c.allow_declared(n, key);
  Sinusoid s;
  if (n["axis"]) {
    axis = c.vec3(n["axis"], key + ".axis");
    if (axis.norm() < 1e-9) c.fail(key + ".axis", "must be non-zero");
    axis.normalize();
  }
  // A rotation's amplitude is amplitude_deg, a translation's amplitude (m): the schema has each.
  s.amplitude = angular ? c.num(n, "amplitude_deg", key, 0.0) * kDeg : c.num(n, "amplitude", key, 0.0);
  s.frequency = c.num(n, "frequency", key, 0.0);
  if (s.frequency < 0.0) c.fail(key + ".frequency", "must be >= 0");
  s.phase = c.num(n, "phase_deg", key, 0.0) * kDeg;
  return s;
}

// The robot configuration and model load_robot read (robot.config), for the checks that need
// the robot's kinematics; empty for a robot given as urdf + feet.
#ifdef POISE_SIM_HAVE_MODEL
struct LoadedRobot {
  std::optional<model::RobotConfig> config;
  std::optional<model::Model> model;
};
#else
struct LoadedRobot {};
#endif

#ifdef POISE_SIM_HAVE_MODEL
// A single-support start (initial.support: a foot) the robot cannot stand in: the other sole
// touching the ground too (it would carry the robot while the controller plans it as lifted), or
// the CoM outside the support sole (the robot starts falling). Both found from the initial
// posture with the model, before anything runs; the shipped lateral_push_single_support.yaml
// shows how initial.joints fold the other leg and lean the CoM over the sole.
void check_single_support(const Ctx& c, const World& sc, const model::RobotConfig& rc,
                          const model::Model& m) {
  const InitialState& ini = sc.sim.initial;
  Eigen::VectorXd q = m.neutral();
  const Eigen::Quaterniond qb = Eigen::Quaterniond(
      ini.base_orientation_wxyz[0], ini.base_orientation_wxyz[1], ini.base_orientation_wxyz[2],
      ini.base_orientation_wxyz[3]).normalized();
  q.segment<4>(3) << qb.x(), qb.y(), qb.z(), qb.w();
  for (std::size_t k = 0; k < ini.joint_names.size(); ++k)
    if (m.has_joint(ini.joint_names[k]))
      q[7 + m.joint_index(ini.joint_names[k])] = ini.joint_positions[k];
  model::Data d(m);
  model::forward_kinematics(m, d, q);
  model::update_frame_placements(m, d);
  model::center_of_mass(m, d, q);
  int support = -1;
  const char* side_name[2] = {"right", "left"};
  for (int s = 0; s < 2; ++s)
    if (sc.support == side_name[s]) support = s;
  if (support < 0) return;
  const auto lowest = [&](int s) {
    const model::FootConfig& f = rc.feet[static_cast<std::size_t>(s)];
    const model::SE3 X = model::frame_placement(m, d, f.sole_frame_id);
    double z = std::numeric_limits<double>::infinity();
    for (double x : {f.sole.x_min, f.sole.x_max})
      for (double y : {f.sole.y_min, f.sole.y_max})
        z = std::min(z, X.act(model::Vector3(x, y, 0.0)).z());
    return z;
  };
  const int other = 1 - support;
  bool other_on_platform = false;
  for (const auto& p : sc.sim.world.platforms) other_on_platform |= p.foot == side_name[other];
  const double gap = lowest(other) - lowest(support);
  if (!other_on_platform && sc.sim.world.platforms.empty() && gap < 1e-3) {
    std::ostringstream os;
    os.setf(std::ios::fixed);
    os.precision(1);
    os << "'" << sc.support << "', but in the initial posture the " << side_name[other]
       << " sole is " << gap * 1000.0 << " mm above the " << sc.support
       << " one: it would stand on the ground too while the controller holds it lifted (use "
          "support: double, or lift it with initial.joints as "
          "deploy/scenarios/lateral_push_single_support.yaml does)";
    c.fail("initial.support", os.str());
  }
  const model::FootConfig& f = rc.feet[static_cast<std::size_t>(support)];
  const model::SE3 X_WS = model::frame_placement(m, d, f.sole_frame_id);
  // The CoM in the sole frame, along the world vertical onto the sole plane.
  const model::Vector3 up_S = X_WS.R.transpose() * model::Vector3::UnitZ();
  model::Vector3 c_S = X_WS.R.transpose() * (d.com - X_WS.p);
  if (std::abs(up_S.z()) > 1e-6) c_S -= up_S * (c_S.z() / up_S.z());
  const double dx = std::max({f.sole.x_min - c_S.x(), c_S.x() - f.sole.x_max, 0.0});
  const double dy = std::max({f.sole.y_min - c_S.y(), c_S.y() - f.sole.y_max, 0.0});
  if (dx > 0.0 || dy > 0.0) {
    std::ostringstream os;
    os.setf(std::ios::fixed);
    os.precision(1);
    os << "'" << sc.support << "', but in the initial posture the CoM is "
       << std::hypot(dx, dy) * 1000.0 << " mm outside the " << sc.support << " sole (at x "
       << c_S.x() * 1000.0 << ", y " << c_S.y() * 1000.0 << " mm in the sole frame; the sole "
       << "spans x " << f.sole.x_min * 1000.0 << ".." << f.sole.x_max * 1000.0 << ", y "
       << f.sole.y_min * 1000.0 << ".." << f.sole.y_max * 1000.0
       << " mm): the robot would start falling (lean it over the sole with initial.joints, as "
          "deploy/scenarios/lateral_push_single_support.yaml does)";
    c.fail("initial.support", os.str());
  }
}
#endif

void load_robot(const Ctx& c, const YAML::Node& n, World& sc,
                std::vector<std::pair<std::string, double>>& nominal,
                std::map<std::string, std::pair<double, double>>& limits, LoadedRobot& loaded) {
  const std::string key = "robot";
  if (!n) c.fail(key, "is required");
  c.allow_declared(n, key);
  RobotConfig& r = sc.sim.robot;
  if (n["config"]) {
    if (n["urdf"] || n["feet"] || n["imu_frame"])
      c.fail(key, "give either 'config' (robot configuration file) or 'urdf' + 'feet', not both");
    sc.robot_config = c.path(n["config"], key + ".config");
#ifdef POISE_SIM_HAVE_MODEL
    model::RobotConfig rc;
    try {
      rc = model::load_robot_config(sc.robot_config);
    } catch (const std::exception& e) {
      c.fail(key + ".config", e.what());
    }
    r.urdf_path = rc.urdf_path.string();
    r.imu_frame = rc.imu_frame;
    r.forward_axis = rc.forward_axis;
    r.feet.clear();
    const char* side_name[2] = {"right", "left"};
    for (int s = 0; s < 2; ++s) {
      const model::FootConfig& f = rc.feet[static_cast<std::size_t>(s)];
      FootConfig ff;
      ff.name = side_name[s];
      ff.frame = f.frame;
      ff.has_sole = true;
      ff.sole.x_min = f.sole.x_min;
      ff.sole.x_max = f.sole.x_max;
      ff.sole.y_min = f.sole.y_min;
      ff.sole.y_max = f.sole.y_max;
      ff.sole.height = f.sole.height;
      r.feet.push_back(ff);
      if (f.frame != f.link) {  // a foot frame robot.yaml adds (sole given as offset + rpy)
        AddedFrame a;
        a.name = f.frame;
        a.link = f.link;
        a.X_link_frame.linear() = f.X_link_foot.R;
        a.X_link_frame.translation() = f.X_link_foot.p;
        r.added_frames.push_back(a);
      }
    }
    // nominal posture: joint entries of q_nominal (q = [p (3); quat (4); joints])
    const model::Model& m = loaded.model.emplace(model::load_robot_model(rc));
    for (std::size_t j = 0; j < m.joint_names.size(); ++j) {
      nominal.emplace_back(m.joint_names[j], rc.q_nominal[7 + static_cast<Eigen::Index>(j)]);
      limits[m.joint_names[j]] = {m.limits[j].lower, m.limits[j].upper};
    }
    loaded.config = std::move(rc);
#else
    c.fail(key + ".config",
           "this build has no robot-configuration loader (poise_model); use "
           "'urdf' + 'feet'");
#endif
  } else {
    if (!n["urdf"]) c.fail(key, "needs 'config' or 'urdf'");
    r.urdf_path = c.path(n["urdf"], key + ".urdf").string();
    {  // the simulator reads it whole later: refuse what is not a file of sane size now
      std::error_code ec;
      if (!fs::is_regular_file(r.urdf_path, ec))
        c.fail(key + ".urdf", "'" + r.urdf_path + "' is not a regular file");
      if (fs::file_size(r.urdf_path, ec) > (std::uintmax_t{16} << 20))
        c.fail(key + ".urdf", "'" + r.urdf_path + "' is larger than the limit of 16 MB");
    }
    if (n["imu_frame"]) r.imu_frame = c.str(n["imu_frame"], key + ".imu_frame");
    const YAML::Node feet = n["feet"];
    if (!feet || !feet.IsMap() || feet.size() == 0)
      c.fail(key + ".feet", "a mapping of foot name -> {frame, sole} is required");
    r.feet.clear();
    for (const auto& kv : feet) {
      const std::string name = kv.first.as<std::string>();
      const std::string fk = key + ".feet." + name;
      c.allow_declared(kv.second, fk);
      FootConfig f;
      f.name = name;
      if (!kv.second["frame"]) c.fail(fk + ".frame", "is required");
      f.frame = c.str(kv.second["frame"], fk + ".frame");
      if (const YAML::Node s = kv.second["sole"]) {
        c.allow_declared(s, fk + ".sole");
        for (const char* k : {"x_min", "x_max", "y_min", "y_max", "height"})
          if (!s[k]) c.fail(fk + ".sole." + k, "is required");
        f.has_sole = true;
        f.sole.x_min = c.num(s["x_min"], fk + ".sole.x_min");
        f.sole.x_max = c.num(s["x_max"], fk + ".sole.x_max");
        f.sole.y_min = c.num(s["y_min"], fk + ".sole.y_min");
        f.sole.y_max = c.num(s["y_max"], fk + ".sole.y_max");
        f.sole.height = c.num(s["height"], fk + ".sole.height");
        f.sole.thickness = c.num(s, "thickness", fk + ".sole", f.sole.thickness);
      }
      r.feet.push_back(f);
    }
  }
  r.self_collision = c.boolean(n, "self_collision", key, false);
  r.damping_mode_kd = c.num(n, "damping_mode_kd", key, r.damping_mode_kd);
  // A negative damping gain would turn the safety damping into an energy source.
  if (r.damping_mode_kd < 0.0) c.fail(key + ".damping_mode_kd", "must be >= 0");
}

void load_world(const Ctx& c, const YAML::Node& n, World& sc) {
  const std::string key = "world";
  c.allow_declared(n, key);
  WorldConfig& w = sc.sim.world;
  if (!n) return;
  if (n["gravity"]) w.gravity = c.vec3(n["gravity"], key + ".gravity");
  if (!(w.gravity.norm() <= kMaxGravity))
    c.fail(key + ".gravity", "|g| must be at most " + std::to_string(int(kMaxGravity)) +
                                 " m/s^2 (Earth: 9.81)");
  if (const YAML::Node g = n["ground"]) {
    c.allow_declared(g, key + ".ground");
    w.ground.enabled = c.boolean(g, "enabled", key + ".ground", true);
    w.ground.height = c.num(g, "height", key + ".ground", 0.0);
    w.ground.friction = c.num(g, "friction", key + ".ground", w.ground.friction);
    if (w.ground.friction < 0.0) c.fail(key + ".ground.friction", "must be >= 0");
  }
  if (const YAML::Node ps = n["platforms"]) {
    if (!ps.IsSequence()) c.fail(key + ".platforms", "must be a list");
    for (std::size_t i = 0; i < ps.size(); ++i) {
      const YAML::Node p = ps[i];
      const std::string pk = key + ".platforms[" + std::to_string(i) + "]";
      c.allow_declared(p, pk);
      PlatformConfig pc;
      pc.name = p["name"] ? c.str(p["name"], pk + ".name") : "platform" + std::to_string(i);
      if (p["foot"]) pc.foot = c.str(p["foot"], pk + ".foot");
      if (p["size"]) {
        const Eigen::Vector3d s = c.vec3(p["size"], pk + ".size");
        if ((s.array() <= 0.0).any()) c.fail(pk + ".size", "all three sizes must be > 0");
        pc.half_extents = 0.5 * s;
      }
      pc.auto_place = c.boolean(p, "auto_place", pk, !pc.foot.empty());
      if (pc.auto_place && pc.foot.empty()) c.fail(pk + ".foot", "auto_place needs a foot");
      if (p["position"]) pc.position = c.vec3(p["position"], pk + ".position");
      pc.roll = c.num(p, "roll_deg", pk, 0.0) * kDeg;
      pc.pitch = c.num(p, "pitch_deg", pk, 0.0) * kDeg;
      pc.yaw = c.num(p, "yaw_deg", pk, 0.0) * kDeg;
      pc.friction = c.num(p, "friction", pk, pc.friction);
      if (pc.friction < 0.0) c.fail(pk + ".friction", "must be >= 0");
      if (p["translation"])
        pc.translation =
            sinusoid(c, p["translation"], pk + ".translation", false, pc.translation_axis);
      if (p["rotation"])
        pc.rotation = sinusoid(c, p["rotation"], pk + ".rotation", true, pc.rotation_axis);
      pc.motion_start = c.num(p, "motion_start", pk, 0.0);
      pc.motion_ramp = c.num(p, "motion_ramp", pk, 0.0);
      if (pc.motion_start < 0.0) c.fail(pk + ".motion_start", "must be >= 0");
      if (pc.motion_ramp < 0.0) c.fail(pk + ".motion_ramp", "must be >= 0");
      w.platforms.push_back(pc);
    }
  }
}

}  // namespace

namespace {

/// `initial.joints`: angles by joint name, within the joint's limits, over the posture.
void load_initial_joints(const Ctx& c, const YAML::Node& j,
                         const std::map<std::string, std::pair<double, double>>& limits,
                         InitialState& ini) {
  if (!j.IsMap()) c.fail("initial.joints", "must be a mapping joint -> angle (rad)");
  for (const auto& kv : j) {
    const std::string name = kv.first.as<std::string>();
    const double v = c.num(kv.second, "initial.joints." + name);
    if (const auto l = limits.find(name);
        l != limits.end() && (v < l->second.first || v > l->second.second)) {
      std::ostringstream os;
      os << v << " is outside the joint limits [" << l->second.first << ", " << l->second.second
         << "]";
      c.fail("initial.joints." + name, os.str());
    }
    auto it = std::find(ini.joint_names.begin(), ini.joint_names.end(), name);
    if (it != ini.joint_names.end()) {
      ini.joint_positions[static_cast<std::size_t>(it - ini.joint_names.begin())] = v;
    } else {
      ini.joint_names.push_back(name);
      ini.joint_positions.push_back(v);
    }
  }
}

/// `initial.base_xy`, `base_height` (a number, or auto), `base_rpy_deg`.
void load_initial_base(const Ctx& c, const YAML::Node& n, World& sc) {
  InitialState& ini = sc.sim.initial;
  if (n["base_xy"]) {
    if (!n["base_xy"].IsSequence() || n["base_xy"].size() != 2)
      c.fail("initial.base_xy", "must be a list of 2 numbers");
    ini.base_position.x() = c.num(n["base_xy"][0], "initial.base_xy[0]");
    ini.base_position.y() = c.num(n["base_xy"][1], "initial.base_xy[1]");
  }
  if (n["base_height"] &&
      !(n["base_height"].IsScalar() && n["base_height"].as<std::string>() == "auto")) {
    ini.auto_base_height = false;
    ini.base_position.z() = c.num(n["base_height"], "initial.base_height");
    const double ground = sc.sim.world.ground.height;
    if (ini.base_position.z() < ground || ini.base_position.z() > ground + 100.0)
      c.fail("initial.base_height", "must be between the ground height and 100 m above it");
  }
  if (n["base_rpy_deg"]) {
    const Eigen::Vector3d rpy = c.vec3(n["base_rpy_deg"], "initial.base_rpy_deg") * kDeg;
    const Eigen::Quaterniond q(Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()));
    ini.base_orientation_wxyz << q.w(), q.x(), q.y(), q.z();
  }
}

/// The base's yaw: the robot's forward (in its base frame) points along the facing direction;
/// the support must be double or a foot.
void apply_facing_and_check_support(const Ctx& c, double facing, World& sc) {
  InitialState& ini = sc.sim.initial;
  const Eigen::Vector3d& fwd = sc.sim.robot.forward_axis;
  const double turn = facing - std::atan2(fwd.y(), fwd.x());
  Eigen::Quaterniond q(ini.base_orientation_wxyz[0], ini.base_orientation_wxyz[1],
                       ini.base_orientation_wxyz[2], ini.base_orientation_wxyz[3]);
  q = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ()) * q;
  ini.base_orientation_wxyz << q.w(), q.x(), q.y(), q.z();
  bool support_ok = sc.support == "double";
  for (const auto& f : sc.sim.robot.feet) support_ok = support_ok || f.name == sc.support;
  if (!support_ok)
    c.fail("initial.support", "must be 'double' or a foot name, got '" + sc.support + "'");
}

/// `initial:`: the posture (nominal, zero, joints by name within their limits), the base pose and
/// the facing direction, the support. Returns the facing [rad] (initial.facing_deg).
double load_initial(const Ctx& c, const YAML::Node& n, World& sc,
                    const std::vector<std::pair<std::string, double>>& nominal,
                    const std::map<std::string, std::pair<double, double>>& limits) {
  InitialState& ini = sc.sim.initial;
  if (!n) {
    for (const auto& [name, v] : nominal) {
      ini.joint_names.push_back(name);
      ini.joint_positions.push_back(v);
    }
    return 0.0;
  }
  c.allow_declared(n, "initial");
  const std::string posture = n["posture"] ? c.str(n["posture"], "initial.posture") : "nominal";
  if (posture != "nominal" && posture != "zero")
    c.fail("initial.posture", "must be 'nominal' or 'zero'");
  if (posture == "nominal")
    for (const auto& [name, v] : nominal) {
      ini.joint_names.push_back(name);
      ini.joint_positions.push_back(v);
    }
  if (const YAML::Node j = n["joints"]) load_initial_joints(c, j, limits, ini);
  load_initial_base(c, n, sc);
  // The way the robot faces: its forward (robot.yaml forward_axis) turned to this world yaw.
  const double facing = c.num(n, "facing_deg", "initial", 0.0) * kDeg;
  if (std::abs(facing) > 2.0 * M_PI + 1e-9) c.fail("initial.facing_deg", "must be in [-360, 360]");
  ini.clearance = c.num(n, "clearance", "initial", 0.0);
  if (n["support"]) sc.support = c.str(n["support"], "initial.support");
  return facing;
}

/// One push of `disturbances.pushes` (key `pk`): link, point, force (world or heading frame),
/// start and duration, within physical ranges and the run.
Push load_push(const Ctx& c, const YAML::Node& p, const std::string& pk, const World& sc,
               double facing) {
  c.allow_declared(p, pk);
  for (const char* k : {"link", "force", "start", "duration"})
    if (!p[k]) c.fail(pk + "." + k, "is required");
  Push push;
  push.link = c.str(p["link"], pk + ".link");
  if (p["point"]) push.point_L = c.vec3(p["point"], pk + ".point");
  push.force_W = c.vec3(p["force"], pk + ".force");
  // force in `world` (default, the meaning of existing files) or `heading`: x the robot's
  // forward at the start (initial.facing_deg), y its left, z up
  const std::string frame = p["frame"] ? c.str(p["frame"], pk + ".frame") : "world";
  if (frame == "heading")
    push.force_W = Eigen::AngleAxisd(facing, Eigen::Vector3d::UnitZ()) * push.force_W;
  else if (frame != "world")
    c.fail(pk + ".frame", "must be 'world' or 'heading', got '" + frame + "'");
  push.start = c.num(p["start"], pk + ".start");
  push.duration = c.num(p["duration"], pk + ".duration");
  if (push.start < 0.0) c.fail(pk + ".start", "must be >= 0");
  if (push.duration <= 0.0) c.fail(pk + ".duration", "must be > 0");
  // Physical ranges: a push that could throw a humanoid across the room, or that never
  // happens within the run, is a mistake in the file.
  if (!(push.force_W.norm() <= kMaxPushForce))
    c.fail(pk + ".force", "|force| must be at most " + std::to_string(int(kMaxPushForce)) +
                              " N");
  if (!(push.point_L.norm() <= kMaxPushLever))
    c.fail(pk + ".point", "must be within " + std::to_string(int(kMaxPushLever)) +
                              " m of the link's origin");
  if (push.start >= sc.duration)
    c.fail(pk + ".start", "must be before the end of the run (duration " +
                              std::to_string(sc.duration) + " s)");
  if (push.duration > sc.duration)
    c.fail(pk + ".duration", "must be at most the run's duration (" +
                                 std::to_string(sc.duration) + " s)");
  return push;
}

/// `disturbances:`: the scheduled pushes.
void load_disturbances(const Ctx& c, const YAML::Node& d, World& sc, double facing) {
  if (!d) return;
  c.allow_declared(d, "disturbances");
  const YAML::Node ps = d["pushes"];
  if (!ps) return;
  if (!ps.IsSequence()) c.fail("disturbances.pushes", "must be a list");
  for (std::size_t i = 0; i < ps.size(); ++i)
    sc.sim.pushes.push_back(
        load_push(c, ps[i], "disturbances.pushes[" + std::to_string(i) + "]", sc, facing));
}

/// A number >= 0 at n[k] (key `key`.k), when given.
void nonneg(const Ctx& c, const YAML::Node& n, const char* k, const std::string& key, double& v) {
  if (!n[k]) return;
  v = c.num(n[k], key + "." + k);
  if (v < 0.0) c.fail(key + "." + k, "must be >= 0");
}

/// A 3-vector at n[k] times `scale`, when given.
void vec(const Ctx& c, const YAML::Node& n, const char* k, const std::string& key,
         Eigen::Vector3d& v, double scale) {
  if (n[k]) v = scale * c.vec3(n[k], key + "." + k);
}

/// `sensors.imu.orientation`: off, filter or truth.
void load_imu_orientation(const Ctx& c, const YAML::Node& i, const std::string& key,
                          ImuNoiseConfig& imu) {
  if (!i["orientation"]) return;
  const std::string o = c.str(i["orientation"], key + ".orientation");
  if (o == "off")
    imu.orientation = ImuOrientationOutput::kOff;
  else if (o == "filter")
    imu.orientation = ImuOrientationOutput::kFilter;
  else if (o == "truth")
    imu.orientation = ImuOrientationOutput::kTruth;
  else
    c.fail(key + ".orientation", "must be off, filter or truth (got '" + o + "')");
}

/// `sensors.imu`: noise, biases, scale, misalignment, range, rate, delay, orientation filter.
void load_imu(const Ctx& c, const YAML::Node& i, ImuNoiseConfig& imu) {
  const std::string key = "sensors.imu";
  c.allow_declared(i, key);
  load_imu_orientation(c, i, key, imu);
  nonneg(c, i, "gyro_noise_std", key, imu.gyro_noise_std);
  nonneg(c, i, "gyro_noise_density", key, imu.gyro_noise_density);
  nonneg(c, i, "gyro_bias_walk", key, imu.gyro_bias_walk);
  nonneg(c, i, "gyro_range", key, imu.gyro_range);
  nonneg(c, i, "accel_noise_std", key, imu.accel_noise_std);
  nonneg(c, i, "accel_noise_density", key, imu.accel_noise_density);
  nonneg(c, i, "accel_bias_walk", key, imu.accel_bias_walk);
  nonneg(c, i, "accel_range", key, imu.accel_range);
  nonneg(c, i, "rate_hz", key, imu.rate_hz);
  nonneg(c, i, "filter_gain", key, imu.filter_gain);
  nonneg(c, i, "filter_accel_gate", key, imu.filter_accel_gate);
  if (i["filter_accel_gate"] && imu.filter_accel_gate <= 0.0)
    c.fail(key + ".filter_accel_gate", "must be > 0");
  vec(c, i, "gyro_bias", key, imu.gyro_bias, 1.0);
  vec(c, i, "gyro_scale_error", key, imu.gyro_scale_error, 1.0);
  vec(c, i, "gyro_misalignment_deg", key, imu.gyro_misalignment, kDeg);
  vec(c, i, "accel_bias", key, imu.accel_bias, 1.0);
  vec(c, i, "accel_scale_error", key, imu.accel_scale_error, 1.0);
  vec(c, i, "accel_misalignment_deg", key, imu.accel_misalignment, kDeg);
  if (i["delay_ticks"]) {
    const double d = c.num(i["delay_ticks"], key + ".delay_ticks");
    if (d < 0.0 || d > 1000.0 || d != std::floor(d))
      c.fail(key + ".delay_ticks", "must be an integer in [0, 1000]");
    imu.delay_ticks = static_cast<int>(d);
  }
}

/// `sensors:`: a preset (industrial_mems, the default without the section, or ideal), the
/// seed, and the IMU's, encoders' and foot F/Ts' settings over it (SENSORS.md).
void load_sensors(const Ctx& c, const YAML::Node& s, World& sc) {
  sc.sim.imu = industrial_mems_imu();
  sc.sim.encoders = industrial_encoder();
  sc.sim.foot_ft = industrial_foot_ft();
  if (!s) return;
  c.allow_declared(s, "sensors");
  if (s["preset"]) {
    const std::string p = c.str(s["preset"], "sensors.preset");
    if (p == "ideal") {
      sc.sim.imu = ImuNoiseConfig{};
      sc.sim.encoders = EncoderConfig{};
      sc.sim.foot_ft = ForceTorqueSensorConfig{};
    } else if (p != "industrial_mems") {
      c.fail("sensors.preset", "must be industrial_mems or ideal (got '" + p + "')");
    }
  }
  if (s["seed"]) {
    const double seed = c.num(s["seed"], "sensors.seed");
    if (!(seed >= 0.0 && seed <= 9007199254740992.0) || seed != std::floor(seed))
      c.fail("sensors.seed", "must be an integer in [0, 2^53]");
    sc.sim.imu.seed = static_cast<std::uint64_t>(seed);
  }
  if (const YAML::Node i = s["imu"]) load_imu(c, i, sc.sim.imu);
  if (const YAML::Node e = s["encoders"]) {
    c.allow_declared(e, "sensors.encoders");
    nonneg(c, e, "counts_per_rev", "sensors.encoders", sc.sim.encoders.counts_per_rev);
    nonneg(c, e, "velocity_filter_hz", "sensors.encoders", sc.sim.encoders.velocity_filter_hz);
  }
  if (const YAML::Node f = s["foot_ft"]) {
    const std::string key = "sensors.foot_ft";
    c.allow_declared(f, key);
    nonneg(c, f, "force_noise_std", key, sc.sim.foot_ft.force_noise_std);
    nonneg(c, f, "torque_noise_std", key, sc.sim.foot_ft.torque_noise_std);
    vec(c, f, "force_offset", key, sc.sim.foot_ft.force_offset, 1.0);
    vec(c, f, "torque_offset", key, sc.sim.foot_ft.torque_offset, 1.0);
  }
}

/// `solver:`: Bullet's step, iterations, contact and friction settings, warm starting.
void load_solver(const Ctx& c, const YAML::Node& s, World& sc) {
  if (!s) return;
  c.allow_declared(s, "solver");
  SolverConfig& sv = sc.sim.solver;
  sv.dt = c.num(s, "dt", "solver", sv.dt);
  if (!(sv.dt > 0.0 && sv.dt <= 0.01)) c.fail("solver.dt", "must be in (0, 0.01] s");
  const double it = c.num(s, "iterations", "solver", sv.iterations);
  if (!(it >= 1 && it <= 10000) || it != std::floor(it))
    c.fail("solver.iterations", "must be an integer in [1, 10000]");
  sv.iterations = static_cast<int>(it);
  sv.contact_erp = c.num(s, "contact_erp", "solver", sv.contact_erp);
  sv.contact_cfm = c.num(s, "contact_cfm", "solver", sv.contact_cfm);
  sv.friction_anchor = c.boolean(s, "friction_anchor", "solver", sv.friction_anchor);
  sv.residual_threshold = c.num(s, "residual_threshold", "solver", sv.residual_threshold);
  sv.joint_friction_constraint =
      c.boolean(s, "joint_friction_constraint", "solver", sv.joint_friction_constraint);
  sv.joint_friction_velocity =
      c.num(s, "joint_friction_velocity", "solver", sv.joint_friction_velocity);
  if (!(sv.joint_friction_velocity > 0.0))
    c.fail("solver.joint_friction_velocity", "must be > 0");
  sv.warm_start = c.boolean(s, "warm_start", "solver", sv.warm_start);
  sv.warm_start_factor = c.num(s, "warm_start_factor", "solver", sv.warm_start_factor);
  if (!(sv.warm_start_factor >= 0.0 && sv.warm_start_factor <= 1.0))
    c.fail("solver.warm_start_factor", "must be in [0, 1]");
}

/// `success:`: the verdict's criteria.
void load_success(const Ctx& c, const YAML::Node& s, World& sc) {
  if (!s) return;
  c.allow_declared(s, "success");
  SuccessCriteria& k = sc.success;
  k.com_error_max_m = c.num(s, "com_error_max_m", "success", k.com_error_max_m);
  k.com_error_final_m = c.num(s, "com_error_final_m", "success", k.com_error_final_m);
  k.foot_slip_max_m = c.num(s, "foot_slip_max_m", "success", k.foot_slip_max_m);
  for (const auto& [name, v] :
       {std::pair<const char*, double>{"com_error_max_m", k.com_error_max_m},
        {"com_error_final_m", k.com_error_final_m},
        {"foot_slip_max_m", k.foot_slip_max_m}})
    if (s[name] && !(v >= 0.0)) c.fail(std::string("success.") + name, "must be >= 0");
  k.foot_tilt_max_deg = c.num(s, "foot_tilt_max_deg", "success", k.foot_tilt_max_deg);
  if (!(k.foot_tilt_max_deg >= 0.0)) c.fail("success.foot_tilt_max_deg", "must be >= 0");
  k.recovery_time_s = c.num(s, "recovery_time_s", "success", k.recovery_time_s);
  k.allow_non_foot_contacts = c.boolean(s, "allow_non_foot_contacts", "success", false);
  k.min_base_height_m = c.num(s, "min_base_height_m", "success", k.min_base_height_m);
  const double damping = c.num(s, "max_damping_ticks", "success",
                               static_cast<double>(k.max_damping_ticks));
  if (!(damping >= 0.0 && damping <= 1e15) || damping != std::floor(damping))
    c.fail("success.max_damping_ticks", "must be a whole number in [0, 1e15]");
  else
    k.max_damping_ticks = static_cast<long long>(damping);
}

/// Platforms must name feet of the robot.
void check_platform_feet(const Ctx& c, const World& sc) {
  for (std::size_t i = 0; i < sc.sim.world.platforms.size(); ++i) {
    const std::string& foot = sc.sim.world.platforms[i].foot;
    if (foot.empty()) continue;
    bool found = false;
    for (const auto& f : sc.sim.robot.feet)
      found = found || f.name == foot;
    if (!found)
      c.fail("world.platforms[" + std::to_string(i) + "].foot",
             "'" + foot + "' is not a foot of the robot");
  }
}

}  // namespace

World parse_world(const std::string& yaml_text, const fs::path& base_dir,
                  const std::string& what) {
  Ctx c{{what}, base_dir};
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(what + ": invalid YAML: " + e.what());
  }
  if (!root.IsMap()) throw std::runtime_error(what + ": the top level must be a mapping");
  c.refuse_duplicated_keys(root);
  c.allow_declared(root, "");
  // dds, estimator, contact, controller, reference configure the other components: the scenario format
  // (deploy/scenario, poise::scenario::parse_scenario) reads and checks them; the world skips them.
  World sc;
  if (!root["name"]) c.fail("name", "is required");
  sc.name = c.str(root["name"], "name");
  if (root["description"]) sc.description = c.str(root["description"], "description");
  if (!root["duration"]) c.fail("duration", "is required");
  sc.duration = c.num(root["duration"], "duration");
  if (!(sc.duration >= kMinDuration))
    c.fail("duration", "must be at least one control period (0.001 s)");
  if (sc.duration > 1e6) c.fail("duration", "must be at most 1e6 s");

  std::vector<std::pair<std::string, double>> nominal;
  std::map<std::string, std::pair<double, double>> limits;  // joint -> (lower, upper)
  LoadedRobot robot;
  load_robot(c, root["robot"], sc, nominal, limits, robot);
  load_world(c, root["world"], sc);

  const double facing = load_initial(c, root["initial"], sc, nominal, limits);
  apply_facing_and_check_support(c, facing, sc);
  load_disturbances(c, root["disturbances"], sc, facing);
  load_sensors(c, root["sensors"], sc);
  load_solver(c, root["solver"], sc);
  // reality: how the simulated robot differs from the description the nodes get (reality.hpp)
  if (const YAML::Node r = root["reality"]) sc.sim.reality = detail::parse_reality(c, r);

  load_success(c, root["success"], sc);
  check_platform_feet(c, sc);
#ifdef POISE_SIM_HAVE_MODEL
  if (sc.support != "double" && robot.config)
    check_single_support(c, sc, *robot.config, *robot.model);
#endif
  return sc;
}

std::string read_scenario_text(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw std::runtime_error("scenario '" + path.string() + "' is a directory, not a file");
  if (!fs::exists(path, ec)) {
    // A name that is not shipped (`poise run standnig`): say which are.
    std::string names;
#ifdef POISE_SIM_SOURCE_DIR
    std::vector<std::string> shipped;
    for (const auto& e : fs::directory_iterator(fs::path(POISE_SIM_SOURCE_DIR) / "deploy/scenarios", ec))
      if (e.path().extension() == ".yaml") shipped.push_back(e.path().stem().string());
    std::sort(shipped.begin(), shipped.end());
    for (const auto& n : shipped) names += (names.empty() ? "" : ", ") + n;
#endif
    throw std::runtime_error("scenario '" + path.string() + "': no such file" +
                             (names.empty() ? std::string()
                                            : "; the shipped scenarios (by name) are " + names));
  }
  // At most 16 MB (a scenario is a few kB), a regular file only (a FIFO would block).
  return poise::cli::read_regular_file(path, "scenario", std::size_t{16} << 20);
}

World load_world(const fs::path& path) {
  const std::string text = read_scenario_text(path);
  const fs::path abs = fs::absolute(path);
  World w = parse_world(text, abs.parent_path(), "scenario '" + path.string() + "'");
  w.file = abs;
  return w;
}

std::vector<int> platforms_of_feet(const World& sc) {
  std::vector<int> out(sc.sim.robot.feet.size(), -1);
  for (std::size_t f = 0; f < out.size(); ++f)
    for (std::size_t k = 0; k < sc.sim.world.platforms.size(); ++k)
      if (sc.sim.world.platforms[k].foot == sc.sim.robot.feet[f].name) out[f] = static_cast<int>(k);
  return out;
}

ScenarioMonitor::ScenarioMonitor(const World& scenario, std::vector<int> platform_of_foot)
    : scenario_(scenario), platform_of_foot_(std::move(platform_of_foot)) {
  for (std::size_t f = 0; f < scenario.sim.robot.feet.size(); ++f)
    if (scenario.support == "double" || scenario.sim.robot.feet[f].name == scenario.support)
      support_feet_.push_back(static_cast<int>(f));
  for (const Push& p : scenario.sim.pushes)
    last_push_end_ = std::max(last_push_end_, p.start + p.duration);
  foot_in_support_0_.assign(scenario.sim.robot.feet.size(), Eigen::Isometry3d::Identity());
  contact_start_X_SF_.assign(scenario.sim.robot.feet.size(), Eigen::Isometry3d::Identity());
  in_contact_before_.assign(scenario.sim.robot.feet.size(), 0);
  sole_point_F_.assign(scenario.sim.robot.feet.size(), Eigen::Vector3d::Zero());
  sole_known_.assign(scenario.sim.robot.feet.size(), 0);
  for (std::size_t f = 0; f < scenario.sim.robot.feet.size(); ++f) {
    const FootConfig& foot = scenario.sim.robot.feet[f];
    if (!foot.has_sole) continue;
    const SoleConfig& sole = foot.sole;
    sole_point_F_[f] = Eigen::Vector3d(0.5 * (sole.x_min + sole.x_max),
                                       0.5 * (sole.y_min + sole.y_max), -sole.height);
    sole_known_[f] = 1;
  }
  r_.last_recovery_time_s = std::numeric_limits<double>::infinity();
}

void ScenarioMonitor::update(const GroundTruth& g) {
  auto support_pose = [&](int f) {
    const int k = platform_of_foot_[static_cast<std::size_t>(f)];
    return k >= 0 && static_cast<std::size_t>(k) < g.platform_X_WP.size()
               ? g.platform_X_WP[static_cast<std::size_t>(k)]
               : Eigen::Isometry3d::Identity();
  };
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (int f : support_feet_)
    centre += g.feet[static_cast<std::size_t>(f)].X_WF.translation().head<2>();
  centre /= static_cast<double>(std::max<std::size_t>(1, support_feet_.size()));
  if (!initialised_) {
    // The offset the description puts the CoM at: where the controller is asked to keep it.
    com_offset_ = (g.com_W + g.model_com_shift_W).head<2>() - centre;
    for (int f : support_feet_)
      foot_in_support_0_[static_cast<std::size_t>(f)] =
          support_pose(f).inverse() * g.feet[static_cast<std::size_t>(f)].X_WF;
    initialised_ = true;
  }
  time_ = g.time;
  const double err = (g.com_W.head<2>() - (centre + com_offset_ + com_shift_)).norm();
  r_.com_error_max_m = std::max(r_.com_error_max_m, err);
  r_.com_error_final_m = err;
  if (err > scenario_.success.com_error_final_m) last_bad_time_ = g.time;
  for (int f : support_feet_) {
    const auto& ft = g.feet[static_cast<std::size_t>(f)];
    if (!ft.in_contact) continue;
    const Eigen::Isometry3d X_SW = support_pose(f).inverse();
    const auto fi = static_cast<std::size_t>(f);
    const Eigen::Isometry3d X_SF = X_SW * ft.X_WF;
    const Eigen::Isometry3d& X_SF0 = foot_in_support_0_[fi];
    r_.foot_displacement_max_m = std::max(
        r_.foot_displacement_max_m, (X_SF.translation() - X_SF0.translation()).head<2>().norm());
    if (!in_contact_before_[fi]) contact_start_X_SF_[fi] = X_SF;
    const Eigen::Vector3d cop_S = X_SW * ft.cop_W;
    const Eigen::Vector3d cop_F = X_SF.inverse() * cop_S;
    // Slip: the sole's centre point against where it was at the start. Without a sole in the
    // robot config, the point of the sole plane below the foot frame's origin, the plane learnt
    // from the first contact that carries a load (a contact without one reports its CoP at the
    // foot frame's origin, GroundTruth); until then the origin itself.
    if (!sole_known_[fi] && ft.force_W.norm() > 0.0 && cop_F.allFinite()) {
      sole_point_F_[fi] = Eigen::Vector3d(0.0, 0.0, cop_F.z());
      sole_known_[fi] = 1;
    }
    const Eigen::Vector3d& sole_F = sole_point_F_[fi];
    r_.foot_slip_max_m =
        std::max(r_.foot_slip_max_m, (X_SF * sole_F - X_SF0 * sole_F).head<2>().norm());
    // Slide: the sole point under the CoP now, against where that point of the sole was when
    // this contact began.
    r_.foot_slide_max_m = std::max(r_.foot_slide_max_m,
                                   (cop_S - contact_start_X_SF_[fi] * cop_F).head<2>().norm());
    // Tilt: the angle between the sole's normal (the support's z when the foot stood at the
    // start, in F: whatever the foot frame's axes) and the support's z now.
    const Eigen::Vector3d n_F = X_SF0.linear().transpose().col(2);
    const double c = (X_SF.linear() * n_F).z();
    r_.foot_tilt_max_deg =
        std::max(r_.foot_tilt_max_deg, std::acos(std::clamp(c, -1.0, 1.0)) * (180.0 / M_PI));
  }
  for (int f : support_feet_)
    in_contact_before_[static_cast<std::size_t>(f)] = g.feet[static_cast<std::size_t>(f)].in_contact;
  if (g.num_non_foot_contacts > 0) ++r_.non_foot_contacts;
  {
    // about the robot's own forward (robot.yaml forward_axis), not the base's x axis
    const Eigen::Vector2d pr =
        trunk_pitch_roll(g.X_WB.rotation(), scenario_.sim.robot.forward_axis) * (180.0 / M_PI);
    const double pitch = pr.x(), roll = pr.y();
    r_.trunk_pitch_max_deg = std::max(r_.trunk_pitch_max_deg, std::abs(pitch));
    r_.trunk_roll_max_deg = std::max(r_.trunk_roll_max_deg, std::abs(roll));
  }
  r_.min_base_height_m = std::min(r_.min_base_height_m, g.X_WB.translation().z());
}

ReferenceComShift::ReferenceComShift(std::size_t capacity) : ring_(std::max<std::size_t>(1, capacity)) {}

void ReferenceComShift::put(std::uint64_t tick, bool has_com_target,
                            const Eigen::Vector3d& com_W) noexcept {
  std::lock_guard<std::mutex> lock(mutex_);
  if (has_com_target && !com_W.allFinite()) {  // the controller refuses such a tick too
    ++rejected_;
    return;
  }
  if (size_ == ring_.size()) {  // full: the oldest held goes
    head_ = (head_ + 1) % ring_.size();
    --size_;
    ++overflows_;
  }
  Entry& e = ring_[(head_ + size_) % ring_.size()];
  e.tick = tick;
  e.has_com_target = has_com_target;
  e.com_W = com_W;
  ++size_;
}

Eigen::Vector2d ReferenceComShift::due(std::uint64_t k) noexcept {
  std::lock_guard<std::mutex> lock(mutex_);
  // Every held reference due at k (tick 0: at once), in arrival order: the last one wins, as
  // the controller applies the one with the largest tick.
  while (size_ > 0) {
    const Entry& e = ring_[head_];
    if (e.tick != 0 && e.tick > k) break;
    if (e.has_com_target) {
      if (!have_base_) {
        base_ = e.com_W.head<2>();
        have_base_ = true;
      }
      shift_ = e.com_W.head<2>() - base_;
    } else {
      shift_.setZero();
    }
    head_ = (head_ + 1) % ring_.size();
    --size_;
  }
  return shift_;
}

std::uint64_t ReferenceComShift::overflows() const noexcept {
  std::lock_guard<std::mutex> lock(mutex_);
  return overflows_;
}

std::uint64_t ReferenceComShift::rejected() const noexcept {
  std::lock_guard<std::mutex> lock(mutex_);
  return rejected_;
}

ScenarioMonitor::Result ScenarioMonitor::result() const {
  Result r = r_;
  const SuccessCriteria& k = scenario_.success;
  // A robot that fell (on something else than its feet where that is not allowed, or with its
  // base below the bound) never recovered, whatever its CoM error says.
  const bool fell = (!k.allow_non_foot_contacts && r.non_foot_contacts > 0) ||
                    r.min_base_height_m < k.min_base_height_m;
  r.last_recovery_time_s = !fell && r.com_error_final_m <= k.com_error_final_m
                               ? std::max(0.0, last_bad_time_ - last_push_end_)
                               : std::numeric_limits<double>::infinity();
  r.survived = initialised_ && r.com_error_max_m <= k.com_error_max_m &&
               r.com_error_final_m <= k.com_error_final_m &&
               r.foot_slip_max_m <= k.foot_slip_max_m &&
               (std::isinf(k.foot_tilt_max_deg) || r.foot_tilt_max_deg <= k.foot_tilt_max_deg) &&
               (k.allow_non_foot_contacts || r.non_foot_contacts == 0) &&
               r.min_base_height_m >= k.min_base_height_m &&
               (std::isinf(k.recovery_time_s) || r.last_recovery_time_s <= k.recovery_time_s);
  return r;
}

std::vector<std::string> ScenarioMonitor::failed_criteria() const {
  const Result r = result();
  const SuccessCriteria& k = scenario_.success;
  std::vector<std::string> failed;
  auto over = [&](const char* name, double value, double limit, const char* unit, bool bad) {
    if (!bad) return;
    char line[160];
    std::snprintf(line, sizeof(line), "%s %.4g %s %s %.4g %s", name, value, unit,
                  std::string(name) == "min_base_height" ? "<" : ">", limit, unit);
    failed.emplace_back(line);
  };
  if (!initialised_) failed.emplace_back("no ground truth seen");
  over("com_error_max", r.com_error_max_m, k.com_error_max_m, "m",
       !(r.com_error_max_m <= k.com_error_max_m));
  over("com_error_final", r.com_error_final_m, k.com_error_final_m, "m",
       !(r.com_error_final_m <= k.com_error_final_m));
  over("foot_slip_max", r.foot_slip_max_m, k.foot_slip_max_m, "m",
       !(r.foot_slip_max_m <= k.foot_slip_max_m));
  if (!std::isinf(k.foot_tilt_max_deg))
    over("foot_tilt_max", r.foot_tilt_max_deg, k.foot_tilt_max_deg, "deg",
         !(r.foot_tilt_max_deg <= k.foot_tilt_max_deg));
  if (!k.allow_non_foot_contacts && r.non_foot_contacts > 0)
    failed.push_back("non_foot_contacts on " + std::to_string(r.non_foot_contacts) + " ticks");
  over("min_base_height", r.min_base_height_m, k.min_base_height_m, "m",
       !(r.min_base_height_m >= k.min_base_height_m));
  if (!std::isinf(k.recovery_time_s) && !(r.last_recovery_time_s <= k.recovery_time_s))
    over("recovery_time", r.last_recovery_time_s, k.recovery_time_s, "s", true);
  return failed;
}

}  // namespace poise::sim
