// `poise model ...`: inspect a URDF model and evaluate its dynamics from a JSON query.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "poise/model/centroidal.hpp"
#include "poise/model/mesh.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/cli/parse.hpp"

namespace poise::model {

namespace {

using nlohmann::json;

const char* type_name(JointType t) {
  switch (t) {
    case JointType::kFloating:
      return "floating";
    case JointType::kRevolute:
      return "revolute";
    case JointType::kContinuous:
      return "continuous";
    case JointType::kPrismatic:
      return "prismatic";
  }
  return "?";
}

// Finds a robot.yaml beside the URDF that refers to it.
std::optional<RobotConfig> config_beside(const std::filesystem::path& urdf) {
  const auto candidate = urdf.parent_path() / "robot.yaml";
  std::error_code ec;
  if (!std::filesystem::exists(candidate, ec)) return std::nullopt;
  RobotConfig cfg = load_robot_config(candidate);
  if (!std::filesystem::equivalent(cfg.urdf_path, urdf, ec)) return std::nullopt;
  return cfg;
}

int run_info(const std::string& path_arg, const std::string& config_arg) {
  std::filesystem::path urdf = path_arg;
  std::optional<RobotConfig> cfg;
  if (!config_arg.empty()) {
    cfg = load_robot_config(config_arg);
  } else if (urdf.extension() == ".yaml" || urdf.extension() == ".yml") {
    cfg = load_robot_config(urdf);
  }
  if (cfg) urdf = cfg->urdf_path;
  Model model = build_model_from_urdf_file(urdf);
  // Collision meshes as strictly as the simulator and robot init read them.
  const std::vector<std::string> meshes =
      collision_mesh_problems(read_text_file_limited(urdf, "URDF"), urdf.parent_path());
  if (!meshes.empty()) {
    std::string all = "URDF '" + urdf.string() + "': " + std::to_string(meshes.size()) +
                      " collision mesh(es) the simulator cannot read:";
    for (const std::string& m : meshes) all += "\n  " + m;
    throw ModelError(all);
  }
  if (!cfg) cfg = config_beside(urdf);
  if (cfg) add_config_frames(model, *cfg);  // sole frames given as offsets in robot.yaml

  std::cout << "robot: " << model.name << "  (" << urdf.string() << ")\n";
  std::cout << "DoF: " << model.njoints << " joints + 6 floating base  (nq = " << model.nq
            << ", nv = " << model.nv << ")\n";
  std::cout << "total mass: " << model.total_mass << " kg\n";
  std::cout << "base link: " << model.body_name[0] << "\n";
  for (const std::string& n : model.notes) std::cout << "note: " << n << "\n";
  std::cout << "\n";
  std::cout << "joints (model order; q index, v index):\n";
  std::size_t name_width = 22;  // long names must not run into the type column
  for (const std::string& n : model.joint_names) name_width = std::max(name_width, n.size() + 1);
  for (int j = 0; j < model.njoints; ++j) {
    const JointLimits& l = model.limits[j];
    const int b = j + 1;
    std::cout << "  " << std::setw(3) << j << "  " << std::left
              << std::setw(static_cast<int>(name_width)) << model.joint_names[j] << std::setw(11)
              << type_name(model.joint_type[b])
              << std::right << " " << model.body_name[model.parent[b]] << " -> "
              << model.body_name[b] << "  q[" << model.idx_q(j) << "] v[" << model.idx_v(j)
              << "]  pos [" << l.lower << ", " << l.upper << "]  vel " << l.velocity << "  effort "
              << l.effort << "\n";
  }
  std::cout << "\nlinks (frames):\n";
  for (const Frame& f : model.frames) {
    const Inertia& I = model.inertia[f.body];
    std::cout << "  " << std::left << std::setw(22) << f.name << std::right;
    if (f.is_body)
      std::cout << "body " << f.body << ", mass " << I.mass << " kg (incl. merged links)\n";
    else
      std::cout << "fixed to body '" << model.body_name[f.body] << "' at [" << f.X_BF.p.transpose()
                << "]\n";
  }
  if (cfg) {
    std::cout << "\nrobot configuration: " << cfg->config_path.string() << "\n";
    std::cout << "  imu frame: " << cfg->imu_frame << "\n";
    for (int s : {kRight, kLeft}) {
      const FootConfig& f = cfg->feet[s];
      std::cout << "  " << (s == kRight ? "right" : "left") << " foot: frame " << f.frame
                << ", sole frame " << f.sole_frame;
      if (f.sole_from_offset)
        std::cout << " (added: offset [" << f.X_link_sole.p.transpose() << "] in '" << f.link
                  << "')";
      std::cout << ", sole x [" << f.sole.x_min << ", " << f.sole.x_max << "] y [" << f.sole.y_min
                << ", " << f.sole.y_max << "], " << f.sole.height << " m below the foot frame";
      if (std::isfinite(f.collision_bottom))
        std::cout << ", collision bottom " << f.collision_bottom * 1000.0
                  << " mm from the sole plane";
      std::cout << "\n";
    }
    std::cout << "  forward axis (base frame): [" << cfg->forward_axis.transpose() << "]\n";
    // cfg->warnings: printed once to stderr by load_robot_config
    std::cout << "  friction mu " << cfg->friction_mu << ", torsional mu " << cfg->torsional_mu
              << ", safety margin " << cfg->safety_margin << " m\n";
    std::cout << "  leg joints: " << cfg->leg_joints.size()
              << ", upper-body joints: " << cfg->upper_body_joints.size() << "\n";
  } else {
    std::cout << "\nno robot configuration (feet) found beside the URDF\n";
  }
  return 0;
}

[[noreturn]] void bad(const std::string& msg) {
  throw ModelError("query: " + msg);
}

Vector3 vec3(const json& j, const std::string& key) {
  if (!j.is_array() || j.size() != 3) bad(key + " must be an array of 3 numbers");
  Vector3 v;
  for (int i = 0; i < 3; ++i) {
    if (!j[i].is_number()) bad(key + " must be an array of 3 numbers");
    v[i] = j[i].get<double>();
  }
  if (!v.allFinite()) bad(key + " has non-finite entries");
  return v;
}

double number(const json& j, const std::string& key) {
  if (!j.is_number()) bad(key + " must be a number");
  const double x = j.get<double>();
  if (!std::isfinite(x)) bad(key + " is not finite");
  return x;
}

json to_json(const Vector3& v) {
  return json::array({v.x(), v.y(), v.z()});
}

// The query of `poise model eval`: a JSON object with known keys and a URDF path.
json read_eval_query(std::istream& in) {
  json query;
  try {
    query = json::parse(in);
  } catch (const json::parse_error& e) {
    bad(std::string("bad JSON: ") + e.what());
  }
  if (!query.is_object()) bad("expected a JSON object");
  static const std::set<std::string> known = {
      "urdf", "base", "joints", "gravity", "external_forces", "frames"};
  for (const auto& [k, _] : query.items())
    if (!known.count(k)) bad("unknown key '" + k + "'");
  if (!query.contains("urdf") || !query["urdf"].is_string()) bad("'urdf' (path) is required");
  return query;
}

// The robot's state of the query: configuration, velocity and acceleration.
struct EvalState {
  Eigen::VectorXd q, v, a;
};

// query.base: the base pose and velocity (world frame) into `s`.
void read_eval_base(const json& query, EvalState& s) {
  Matrix3 R = Matrix3::Identity();
  Vector3 v_W = Vector3::Zero(), w_W = Vector3::Zero();
  if (query.contains("base")) {
    const json& b = query["base"];
    if (!b.is_object()) bad("'base' must be an object");
    for (const auto& [k, _] : b.items())
      if (k != "position" && k != "orientation_wxyz" && k != "linear_velocity" &&
          k != "angular_velocity")
        bad("unknown key 'base." + k + "'");
    if (b.contains("position")) s.q.head<3>() = vec3(b["position"], "base.position");
    if (b.contains("orientation_wxyz")) {
      const json& o = b["orientation_wxyz"];
      if (!o.is_array() || o.size() != 4) bad("base.orientation_wxyz must have 4 numbers");
      Eigen::Quaterniond quat(
          number(o[0], "base.orientation_wxyz"), number(o[1], "base.orientation_wxyz"),
          number(o[2], "base.orientation_wxyz"), number(o[3], "base.orientation_wxyz"));
      const double n = quat.norm();
      if (std::abs(n - 1.0) > 1e-3)
        bad("base.orientation_wxyz is not a unit quaternion (norm " + std::to_string(n) + ")");
      quat.coeffs() /= n;
      s.q.segment<4>(3) = quat.coeffs();
      R = quat.toRotationMatrix();
    }
    if (b.contains("linear_velocity")) v_W = vec3(b["linear_velocity"], "base.linear_velocity");
    if (b.contains("angular_velocity")) w_W = vec3(b["angular_velocity"], "base.angular_velocity");
  }
  s.v.head<6>() = base_velocity_from_world(R, v_W, w_W);
  // Zero angular acceleration and zero linear acceleration of the base origin (world frame):
  // d/dt v_B = R^T p_ddot - omega_B x v_B = -omega_B x v_B.
  s.a.head<3>() = -s.v.segment<3>(3).cross(s.v.head<3>());
}

// query.joints: {name: {q, qd, qdd}} into `s`.
void read_eval_joints(const json& query, const Model& model, EvalState& s) {
  if (!query.contains("joints")) return;
  const json& js = query["joints"];
  if (!js.is_object()) bad("'joints' must be an object {name: {q, qd, qdd}}");
  for (const auto& [name, val] : js.items()) {
    if (!model.has_joint(name)) bad("unknown joint '" + name + "'");
    const int j = model.joint_index(name);
    if (!val.is_object()) bad("joints." + name + " must be an object");
    for (const auto& [k, x] : val.items()) {
      const double d = number(x, "joints." + name + "." + k);
      if (k == "q")
        s.q[model.idx_q(j)] = d;
      else if (k == "qd")
        s.v[model.idx_v(j)] = d;
      else if (k == "qdd")
        s.a[model.idx_v(j)] = d;
      else
        bad("unknown key 'joints." + name + "." + k + "' (expected q, qd, qdd)");
    }
  }
}

// query.external_forces: wrenches at world points on links, into `data`.
void read_eval_external_forces(const json& query, const Model& model, Data& data) {
  clear_external_forces(data);
  if (!query.contains("external_forces")) return;
  const json& ef = query["external_forces"];
  if (!ef.is_array()) bad("'external_forces' must be an array");
  for (std::size_t i = 0; i < ef.size(); ++i) {
    const json& e = ef[i];
    const std::string key = "external_forces[" + std::to_string(i) + "]";
    if (!e.is_object() || !e.contains("link") || !e["link"].is_string())
      bad(key + " needs a 'link' name");
    const std::string link = e["link"].get<std::string>();
    if (!model.has_frame(link)) bad(key + ": unknown link '" + link + "'");
    const Vector3 f = e.contains("force") ? vec3(e["force"], key + ".force") : Vector3::Zero();
    const Vector3 t = e.contains("torque") ? vec3(e["torque"], key + ".torque") : Vector3::Zero();
    Vector3 p;
    if (e.contains("point")) {
      p = vec3(e["point"], key + ".point");
    } else {
      bad(key + ": 'point' (world coordinates) is required");
    }
    add_external_wrench(model, data, model.frame_id(link), p, f, t);
  }
}

// query.frames: the links whose placement is reported.
std::vector<std::string> read_eval_frames(const json& query, const Model& model) {
  std::vector<std::string> frames;
  if (!query.contains("frames")) return frames;
  if (!query["frames"].is_array()) bad("'frames' must be an array of link names");
  for (const json& f : query["frames"]) {
    if (!f.is_string()) bad("'frames' must be an array of link names");
    if (!model.has_frame(f.get<std::string>()))
      bad("unknown link '" + f.get<std::string>() + "' in frames");
    frames.push_back(f.get<std::string>());
  }
  return frames;
}

// The answer: centroidal quantities, the frames' placements, the inverse dynamics.
json evaluate(const Model& m, Data& data, const EvalState& s,
              const std::vector<std::string>& frames) {
  centroidal_momentum(m, data, s.q, s.v);
  json out;
  out["mass"] = data.mass;
  out["com"] = to_json(data.com);
  out["com_velocity"] = to_json(data.vcom);
  out["linear_momentum"] = to_json(data.hg.tail<3>());
  out["angular_momentum"] = to_json(data.hg.head<3>());
  json jf = json::object();
  for (const std::string& name : frames) {
    const SE3 X = frame_placement(m, data, m.frame_id(name));
    const Eigen::Quaterniond quat(X.R);
    jf[name] = {{"position", to_json(X.p)},
                {"orientation_wxyz", json::array({quat.w(), quat.x(), quat.y(), quat.z()})}};
  }
  out["frames"] = jf;
  const Eigen::VectorXd& tau = rnea(m, data, s.q, s.v, s.a);
  const Matrix3 R_WB = base_pose(s.q).R;
  out["base_force"] = to_json(R_WB * tau.head<3>());
  out["base_torque"] = to_json(R_WB * tau.segment<3>(3));
  json jt = json::object();
  for (int j = 0; j < m.njoints; ++j)
    jt[m.joint_names[j]] = tau[m.idx_v(j)];
  out["joint_torques"] = jt;
  return out;
}

int run_eval(std::istream& in) {
  const json query = read_eval_query(in);
  const Model model = build_model_from_urdf_file(query["urdf"].get<std::string>());
  Data data(model);
  EvalState s{model.neutral(), Eigen::VectorXd::Zero(model.nv), Eigen::VectorXd::Zero(model.nv)};
  read_eval_base(query, s);
  read_eval_joints(query, model, s);
  Model m = model;
  if (query.contains("gravity")) m.gravity = vec3(query["gravity"], "gravity");
  read_eval_external_forces(query, model, data);
  const std::vector<std::string> frames = read_eval_frames(query, model);
  std::cout << evaluate(m, data, s, frames).dump(2) << "\n";
  return 0;
}

}  // namespace

int cli_main(int argc, char** argv) {
  CLI::App app{"Inspect robot models and evaluate their dynamics", "poise model"};
  app.require_subcommand(1);
  std::string path, config;
  CLI::App* info = app.add_subcommand(
      "info", "Links, joints with limits, DoF, total mass, feet (if a robot.yaml is beside it)");
  info->add_option("path", path, "URDF file (or robot.yaml)")->required();
  info->add_option("--config", config, "robot.yaml to use for the feet");
  CLI::App* eval = app.add_subcommand(
      "eval",
      "Read one JSON query on stdin, print mass, CoM, momentum, frame poses and inverse-dynamics "
      "generalized forces as JSON (see components/model/README.md)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return poise::cli::usage_exit(app, e);
  }
  try {
    if (*info) return run_info(path, config);
    if (*eval) return run_eval(std::cin);
  } catch (const std::exception& e) {
    std::cerr << "poise model: error: " << e.what() << "\n";
    return 1;
  }
  return 2;
}

}  // namespace poise::model
