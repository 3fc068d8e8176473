#include "poise/controller/controller_config.hpp"

#include <yaml-cpp/yaml.h>

#include "poise/contact/contact_optimizer.hpp"

#include <cmath>
#include <set>
#include <string>

namespace poise::controller {

namespace {

void require(bool ok, const std::string& field, const std::string& what) {
  if (!ok) throw ConfigError("controller config: " + field + " " + what);
}

void positive_vec(const Eigen::Vector3d& v, const std::string& field) {
  require(v.allFinite() && (v.array() >= 0.0).all(), field, "must be finite and >= 0");
}

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw ConfigError(file_ + ": " + key + ": " + what);
  }

  /// Checks that `node` is a map whose keys are all in `allowed`.
  void keys(const YAML::Node& node, const std::string& path, std::set<std::string> allowed) const {
    if (!node.IsMap()) fail(path.empty() ? "<root>" : path, "expected a mapping");
    for (const auto& kv : node) {
      const std::string k = kv.first.as<std::string>();
      if (!allowed.count(k)) fail(path.empty() ? k : path + "." + k, "unknown key");
    }
  }

  void number(const YAML::Node& node, const std::string& key, const std::string& path,
              double& out) const {
    const YAML::Node v = node[key];
    if (!v) return;
    try {
      out = v.as<double>();
    } catch (const YAML::Exception&) {
      fail(path + key, "expected a number");
    }
    if (!std::isfinite(out)) fail(path + key, "must be finite");
  }

  void integer(const YAML::Node& node, const std::string& key, const std::string& path,
               int& out) const {
    const YAML::Node v = node[key];
    if (!v) return;
    try {
      out = v.as<int>();
    } catch (const YAML::Exception&) {
      fail(path + key, "expected an integer");
    }
  }

  void vec3(const YAML::Node& node, const std::string& key, const std::string& path,
            Eigen::Vector3d& out) const {
    const YAML::Node v = node[key];
    if (!v) return;
    if (!v.IsSequence() || v.size() != 3) fail(path + key, "expected a list of 3 numbers");
    for (int i = 0; i < 3; ++i) {
      try {
        out[i] = v[i].as<double>();
      } catch (const YAML::Exception&) {
        fail(path + key, "expected a list of 3 numbers");
      }
    }
  }

 private:
  std::string file_;
};

}  // namespace

void ControllerConfig::validate() const {
  require(std::isfinite(dt) && dt > 0.0, "dt", "must be > 0");
  positive_vec(momentum.gamma11, "momentum.gamma11");
  positive_vec(momentum.gamma21, "momentum.gamma21");
  positive_vec(momentum.gamma22, "momentum.gamma22");
  require(std::isfinite(momentum.feedback_filter_hz) && momentum.feedback_filter_hz >= 0.0,
          "momentum.feedback_filter_hz", "must be >= 0 (0: no filter)");
  require(std::isfinite(momentum.support_acceleration_hz) &&
              momentum.support_acceleration_hz >= 0.0 &&
              momentum.support_acceleration_hz < 0.5 / dt,
          "momentum.support_acceleration_hz", "must be >= 0 and below half the control rate (0: off)");
  require(std::isfinite(momentum.ankle_first_blend) && momentum.ankle_first_blend >= 0.0 &&
              momentum.ankle_first_blend <= 1.0,
          "momentum.ankle_first_blend", "must be in [0, 1] m (0: off)");
  require(std::isfinite(momentum.upright_pitch_rate) && momentum.upright_pitch_rate >= 0.0 &&
              momentum.upright_pitch_rate <= 100.0,
          "momentum.upright_pitch_rate", "must be in [0, 100] 1/s (0: off)");
  require(std::isfinite(momentum.upright_roll_rate) && momentum.upright_roll_rate >= 0.0 &&
              momentum.upright_roll_rate <= 100.0,
          "momentum.upright_roll_rate", "must be in [0, 100] 1/s (0: off)");
  require(std::isfinite(com_offset.bandwidth_hz) && com_offset.bandwidth_hz >= 0.0 &&
              com_offset.bandwidth_hz < 0.5 / dt,
          "com_offset.bandwidth_hz", "must be >= 0 and below half the control rate (0: off)");
  require(std::isfinite(com_offset.limit) && com_offset.limit >= 0.0 && com_offset.limit <= 0.2,
          "com_offset.limit", "must be in [0, 0.2] m");
  require(std::isfinite(com_offset.speed_gate) && com_offset.speed_gate > 0.0,
          "com_offset.speed_gate", "must be > 0 m/s");
  require(std::isfinite(contact.friction_mu) && contact.friction_mu >= 0.0 &&
              contact.friction_mu <= 10.0,
          "contact.friction_mu", "must be in [0, 10] (0: robot.yaml's contact.friction_mu)");
  require(contact.w_k >= 0.0 && contact.eps_f >= 0.0 && contact.eps_cop >= 0.0, "contact",
          "weights must be >= 0");
  require(foot.kp >= 0.0 && foot.kd >= 0.0, "foot", "gains must be >= 0");
  require(foot.unloaded_kp >= 0.0, "foot.unloaded_kp", "must be >= 0 (foot.kp: as the others)");
  require(foot.unloaded_kd >= 0.0, "foot.unloaded_kd", "must be >= 0 (foot.kd: as the others)");
  require(foot.support_acceleration_tau >= 0.0, "foot.support_acceleration_tau",
          "must be >= 0 (0: no support acceleration feed-forward)");
  const auto& a = acceleration;
  require(a.w_b > 0.0 && a.w_b < 1.0, "acceleration.w_b",
          "must be inside (0, 1) (paper Sec. 3.5: w_b = 1 makes eq (33) indeterminate)");
  require(a.posture_weight > 0.0, "acceleration.posture_weight",
          "must be > 0 (it keeps the Hessian of eq (33) positive definite)");
  require(a.posture_kp >= 0.0 && a.posture_kd >= 0.0, "acceleration.posture_kp/kd", "must be >= 0");
  require(a.upper_body_kp >= 0.0 && a.upper_body_kd >= 0.0, "acceleration.upper_body_kp/kd",
          "must be >= 0");
  require(a.limit_horizon > 0.0, "acceleration.limit_horizon", "must be > 0");
  require(a.max_joint_acceleration > 0.0, "acceleration.max_joint_acceleration", "must be > 0");
  require(feedback.gain_scale >= 0.0, "feedback.gain_scale", "must be >= 0");
  require(feedback.max_position_error >= 0.0 && feedback.max_velocity_error >= 0.0,
          "feedback.max_*_error", "must be >= 0");
  require(std::isfinite(feedback.support_leg_leak_hz) && feedback.support_leg_leak_hz >= 0.0,
          "feedback.support_leg_leak_hz", "must be >= 0 (0 = pure integration)");
  require(std::isfinite(feedback.internal_force_leak_hz) && feedback.internal_force_leak_hz >= 0.0,
          "feedback.internal_force_leak_hz", "must be >= 0 (0 = off)");
  require(std::isfinite(feedback.velocity_leak_hz) && feedback.velocity_leak_hz >= 0.0,
          "feedback.velocity_leak_hz", "must be >= 0 (0 = pure integration)");
  require(std::isfinite(feedback.touchdown_follow_fraction) &&
              feedback.touchdown_follow_fraction >= 0.0 && feedback.touchdown_follow_fraction < 1.0,
          "feedback.touchdown_follow_fraction", "must be in [0, 1) (0 = off)");
  require(std::isfinite(feedback.touchdown_follow_hz) && feedback.touchdown_follow_hz > 0.0,
          "feedback.touchdown_follow_hz", "must be > 0");
  require(fallback.max_reuse_ticks >= 0, "fallback.max_reuse_ticks", "must be >= 0");
  require(fall.tilt_deg > 0.0 && fall.tilt_deg <= 180.0, "fall.tilt_deg",
          "must be in (0, 180] (degrees; 180: never)");
  require(fall.com_height_fraction >= 0.0 && fall.com_height_fraction < 1.0,
          "fall.com_height_fraction", "must be in [0, 1) (0: never)");
  require(std::isfinite(resting_extra_margin), "resting_extra_margin", "must be finite");
  require(std::isfinite(resting_force_fraction) && resting_force_fraction >= 0.0 &&
              resting_force_fraction < 1.0,
          "resting_force_fraction", "must be in [0, 1)");
  require(std::isfinite(resting_touchdown_force_fraction) &&
              resting_touchdown_force_fraction >= 0.0 && resting_touchdown_force_fraction < 1.0,
          "resting_touchdown_force_fraction", "must be in [0, 1)");
  require(std::isfinite(resting_touchdown_air_time) && resting_touchdown_air_time >= 0.0,
          "resting_touchdown_air_time", "must be finite and >= 0 (s)");
  require(std::isfinite(com_height), "com_height", "must be finite");
  require(std::isfinite(planned_support_release) && planned_support_release >= 0.0,
          "planned_support_release", "must be finite and >= 0 (s; 0: never)");
  require(std::isfinite(planned_support_release_height) && planned_support_release_height >= 0.0,
          "planned_support_release_height", "must be finite and >= 0 (m)");
}

namespace {

ControllerConfig from_yaml(const YAML::Node& root, const std::string& file) {
  ControllerConfig c;
  Reader r(file);
  if (root.IsNull()) return c;
  r.keys(root, "",
         {"dt", "momentum", "contact", "foot", "acceleration", "feedback", "fallback", "fall",
          "com_offset",
          "resting_extra_margin", "resting_force_fraction", "resting_touchdown_force_fraction",
          "resting_touchdown_air_time", "com_height",
          "planned_support_release", "planned_support_release_height"});
  r.number(root, "dt", "", c.dt);
  r.number(root, "resting_extra_margin", "", c.resting_extra_margin);
  r.number(root, "resting_force_fraction", "", c.resting_force_fraction);
  r.number(root, "resting_touchdown_force_fraction", "", c.resting_touchdown_force_fraction);
  r.number(root, "resting_touchdown_air_time", "", c.resting_touchdown_air_time);
  r.number(root, "com_height", "", c.com_height);
  r.number(root, "planned_support_release", "", c.planned_support_release);
  r.number(root, "planned_support_release_height", "", c.planned_support_release_height);
  if (const auto m = root["momentum"]) {
    r.keys(m, "momentum",
           {"gamma11", "gamma21", "gamma22", "feedback_filter_hz", "support_acceleration_hz",
            "ankle_first_blend", "upright_pitch_rate", "upright_roll_rate"});
    r.number(m, "upright_pitch_rate", "momentum.", c.momentum.upright_pitch_rate);
    r.number(m, "upright_roll_rate", "momentum.", c.momentum.upright_roll_rate);
    r.number(m, "feedback_filter_hz", "momentum.", c.momentum.feedback_filter_hz);
    r.number(m, "ankle_first_blend", "momentum.", c.momentum.ankle_first_blend);
    r.number(m, "support_acceleration_hz", "momentum.", c.momentum.support_acceleration_hz);
    r.vec3(m, "gamma11", "momentum.", c.momentum.gamma11);
    r.vec3(m, "gamma21", "momentum.", c.momentum.gamma21);
    r.vec3(m, "gamma22", "momentum.", c.momentum.gamma22);
  }
  if (const auto m = root["contact"]) {
    r.keys(m, "contact", {"w_k", "eps_f", "eps_cop", "priority", "torsion_limit", "friction_mu"});
    r.number(m, "friction_mu", "contact.", c.contact.friction_mu);
    if (const YAML::Node tl = m["torsion_limit"]) {
      const std::string name = tl.IsScalar() ? tl.as<std::string>() : std::string();
      const auto parsed = contact::parse_torsion_limit(name);
      if (!parsed)
        r.fail("contact.torsion_limit",
               "must be 'independent' or 'friction-coupled', got '" + name + "'");
      else
        c.contact.torsion_limit = *parsed;
    }
    if (const YAML::Node pr = m["priority"]) {
      const std::string name = pr.IsScalar() ? pr.as<std::string>() : std::string();
      const auto parsed = contact::parse_priority(name);
      if (!parsed) r.fail("contact.priority", "must be 'lexicographic' or 'weighted', got '" + name + "'");
      c.contact.priority = *parsed;
    }
    r.number(m, "w_k", "contact.", c.contact.w_k);
    r.number(m, "eps_f", "contact.", c.contact.eps_f);
    r.number(m, "eps_cop", "contact.", c.contact.eps_cop);
  }
  if (const auto m = root["foot"]) {
    r.keys(m, "foot", {"kp", "kd", "unloaded_kp", "unloaded_kd", "support_acceleration_tau"});
    r.number(m, "kp", "foot.", c.foot.kp);
    r.number(m, "kd", "foot.", c.foot.kd);
    r.number(m, "unloaded_kp", "foot.", c.foot.unloaded_kp);
    r.number(m, "unloaded_kd", "foot.", c.foot.unloaded_kd);
    r.number(m, "support_acceleration_tau", "foot.", c.foot.support_acceleration_tau);
  }
  if (const auto m = root["acceleration"]) {
    r.keys(m, "acceleration",
           {"w_b", "posture_weight", "posture_kp", "posture_kd", "upper_body_kp", "upper_body_kd",
            "limit_horizon", "max_joint_acceleration"});
    auto& a = c.acceleration;
    r.number(m, "w_b", "acceleration.", a.w_b);
    r.number(m, "posture_weight", "acceleration.", a.posture_weight);
    r.number(m, "posture_kp", "acceleration.", a.posture_kp);
    r.number(m, "posture_kd", "acceleration.", a.posture_kd);
    r.number(m, "upper_body_kp", "acceleration.", a.upper_body_kp);
    r.number(m, "upper_body_kd", "acceleration.", a.upper_body_kd);
    r.number(m, "limit_horizon", "acceleration.", a.limit_horizon);
    r.number(m, "max_joint_acceleration", "acceleration.", a.max_joint_acceleration);
  }
  if (const auto m = root["feedback"]) {
    r.keys(m, "feedback",
           {"gain_scale", "max_position_error", "max_velocity_error", "support_leg_leak_hz",
            "internal_force_leak_hz", "touchdown_follow_fraction", "touchdown_follow_hz", "velocity_leak_hz"});
    r.number(m, "gain_scale", "feedback.", c.feedback.gain_scale);
    r.number(m, "max_position_error", "feedback.", c.feedback.max_position_error);
    r.number(m, "max_velocity_error", "feedback.", c.feedback.max_velocity_error);
    r.number(m, "support_leg_leak_hz", "feedback.", c.feedback.support_leg_leak_hz);
    r.number(m, "internal_force_leak_hz", "feedback.", c.feedback.internal_force_leak_hz);
    r.number(m, "velocity_leak_hz", "feedback.", c.feedback.velocity_leak_hz);
    r.number(m, "touchdown_follow_fraction", "feedback.", c.feedback.touchdown_follow_fraction);
    r.number(m, "touchdown_follow_hz", "feedback.", c.feedback.touchdown_follow_hz);
  }
  if (const auto m = root["fallback"]) {
    r.keys(m, "fallback", {"max_reuse_ticks"});
    r.integer(m, "max_reuse_ticks", "fallback.", c.fallback.max_reuse_ticks);
  }
  if (const auto m = root["com_offset"]) {
    r.keys(m, "com_offset", {"bandwidth_hz", "limit", "speed_gate"});
    r.number(m, "bandwidth_hz", "com_offset.", c.com_offset.bandwidth_hz);
    r.number(m, "limit", "com_offset.", c.com_offset.limit);
    r.number(m, "speed_gate", "com_offset.", c.com_offset.speed_gate);
  }
  if (const auto m = root["fall"]) {
    r.keys(m, "fall", {"tilt_deg", "com_height_fraction"});
    r.number(m, "tilt_deg", "fall.", c.fall.tilt_deg);
    r.number(m, "com_height_fraction", "fall.", c.fall.com_height_fraction);
  }
  try {
    c.validate();
  } catch (const ConfigError& e) {
    throw ConfigError(file + ": " + e.what());
  }
  return c;
}

}  // namespace

ControllerConfig load_controller_config(const std::filesystem::path& path) {
  const std::string file = path.string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    throw ConfigError(file + ": cannot open the controller config");
  } catch (const YAML::Exception& e) {
    throw ConfigError(file + ": YAML error: " + e.what());
  }
  return from_yaml(root, file);
}

ControllerConfig parse_controller_config(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin + ": YAML error: " + e.what());
  }
  return from_yaml(root, origin);
}

}  // namespace poise::controller
