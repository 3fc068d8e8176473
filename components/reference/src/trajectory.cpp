#include "poise/reference/trajectory.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

namespace poise::reference {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& key, const std::string& why) {
  throw std::runtime_error(path + ": " + key + ": " + why);
}

void check_keys(const std::string& path, const std::string& where, const YAML::Node& n,
                const std::set<std::string>& allowed) {
  if (!n.IsMap()) fail(path, where, "expected a mapping");
  for (const auto& kv : n) {
    const std::string k = kv.first.as<std::string>();
    if (!allowed.count(k)) {
      std::string list;
      for (const auto& a : allowed)
        list += (list.empty() ? "" : ", ") + a;
      fail(path, where.empty() ? k : where + "." + k, "unknown key (allowed: " + list + ")");
    }
  }
}

double number(const std::string& path, const std::string& key, const YAML::Node& n, double fallback,
              bool required = false) {
  if (!n) {
    if (required) fail(path, key, "missing");
    return fallback;
  }
  double v = 0.0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    fail(path, key, "expected a number");
  }
  if (!std::isfinite(v)) fail(path, key, "must be finite");
  return v;
}

/// Quintic smooth step s(x) on [0, 1] and its derivatives with respect to x.
void smooth_step(double x, double& s, double& ds, double& dds) noexcept {
  if (x <= 0.0) {
    s = ds = dds = 0.0;
  } else if (x >= 1.0) {
    s = 1.0;
    ds = dds = 0.0;
  } else {
    s = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x);
    ds = 30.0 * x * x * (1.0 - x) * (1.0 - x);
    dds = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x);
  }
}

}  // namespace

double Trajectory::begin() const {
  double b = std::numeric_limits<double>::infinity();
  for (const auto& m : com)
    b = std::min(b, m.start);
  for (const auto& s : joints)
    b = std::min(b, s.start);
  for (const auto& s : feet)
    b = std::min(b, s.start);
  return b;
}

double Trajectory::end() const {
  double e = -std::numeric_limits<double>::infinity();
  for (const auto& m : com)
    e = std::max(e, m.start + m.duration);
  for (const auto& s : joints)
    e = std::max(e, s.start + s.duration);
  for (const auto& s : feet)
    e = std::max(e, s.start + s.duration);
  return e;
}

namespace {

// com[i].over (right, left, between: resolved when the move starts) or com[i].shift.
void read_com_target(const std::string& path, const std::string& key, const YAML::Node& n,
                     ComMove& m) {
  if (n["shift"] && n["over"]) fail(path, key + ".over", "give either shift or over, not both");
  if (const YAML::Node o = n["over"]) {
    const std::string name = o.IsScalar() ? o.as<std::string>() : std::string();
    if (name == "right")
      m.over = ComOver::kRight;
    else if (name == "left")
      m.over = ComOver::kLeft;
    else if (name == "between")
      m.over = ComOver::kBetween;
    else
      fail(path, key + ".over", "must be right, left or between, got '" + name + "'");
    m.resolved = false;
  } else {
    const YAML::Node s = n["shift"];
    if (!s || !s.IsSequence() || s.size() != 3)
      fail(path, key + ".shift", "expected [x, y, z] (or over: right|left|between)");
    for (int k = 0; k < 3; ++k)
      m.shift[k] = number(path, key + ".shift", s[k], 0.0, true);
  }
}

void read_com_moves(const std::string& path, const YAML::Node& com, Trajectory& t) {
  if (!com.IsSequence()) fail(path, "com", "expected a list of moves");
  for (std::size_t i = 0; i < com.size(); ++i) {
    const std::string key = "com[" + std::to_string(i) + "]";
    check_keys(path, key, com[i], {"start", "duration", "shift", "over"});
    ComMove m;
    m.start = number(path, key + ".start", com[i]["start"], 0.0, true);
    m.duration = number(path, key + ".duration", com[i]["duration"], 0.0, true);
    if (!(m.duration > 0.0)) fail(path, key + ".duration", "must be > 0");
    read_com_target(path, key, com[i], m);
    if (m.start < 0.0) fail(path, key + ".start", "must be >= 0");
    if (!t.com.empty() && m.start < t.com.back().start + t.com.back().duration)
      fail(path, key + ".start", "CoM moves must be in time order and must not overlap");
    t.com.push_back(m);
  }
}

void read_joint_swings(const std::string& path, const YAML::Node& joints, Trajectory& t) {
  if (!joints.IsSequence()) fail(path, "joints", "expected a list of swings");
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const std::string key = "joints[" + std::to_string(i) + "]";
    check_keys(path, key, joints[i],
               {"joint", "start", "duration", "amplitude", "frequency", "phase_deg", "fade"});
    JointSwing s;
    if (!joints[i]["joint"]) fail(path, key + ".joint", "missing");
    s.joint = joints[i]["joint"].as<std::string>();
    s.start = number(path, key + ".start", joints[i]["start"], 0.0, true);
    s.duration = number(path, key + ".duration", joints[i]["duration"], 0.0, true);
    s.amplitude = number(path, key + ".amplitude", joints[i]["amplitude"], 0.0, true);
    s.frequency = number(path, key + ".frequency", joints[i]["frequency"], 1.0);
    s.phase = number(path, key + ".phase_deg", joints[i]["phase_deg"], 0.0) * M_PI / 180.0;
    s.fade = number(path, key + ".fade", joints[i]["fade"], 0.5);
    if (s.start < 0.0) fail(path, key + ".start", "must be >= 0");
    if (!(s.duration > 0.0)) fail(path, key + ".duration", "must be > 0");
    if (s.frequency < 0.0) fail(path, key + ".frequency", "must be >= 0");
    if (!(s.fade > 0.0) || s.fade > 0.5 * s.duration)
      fail(path, key + ".fade", "must be in (0, duration / 2]");
    t.joints.push_back(s);
  }
}

// feet[i].foot: right (side 0) or left (side 1).
void read_step_foot(const std::string& path, const std::string& key, const YAML::Node& n,
                    FootStep& s) {
  if (!n["foot"]) fail(path, key + ".foot", "missing (right or left)");
  try {
    s.foot = n["foot"].as<std::string>();
  } catch (const YAML::Exception&) {
    fail(path, key + ".foot", "expected right or left");
  }
  if (s.foot == "right")
    s.side = 0;
  else if (s.foot == "left")
    s.side = 1;
  else
    fail(path, key + ".foot", "'" + s.foot + "': expected right or left");
}

void read_foot_steps(const std::string& path, const YAML::Node& feet, Trajectory& t) {
  if (!feet.IsSequence()) fail(path, "feet", "expected a list of steps");
  for (std::size_t i = 0; i < feet.size(); ++i) {
    const std::string key = "feet[" + std::to_string(i) + "]";
    check_keys(path, key, feet[i], {"foot", "start", "duration", "lift"});
    FootStep s;
    read_step_foot(path, key, feet[i], s);
    s.start = number(path, key + ".start", feet[i]["start"], 0.0, true);
    s.duration = number(path, key + ".duration", feet[i]["duration"], 0.0, true);
    s.lift = number(path, key + ".lift", feet[i]["lift"], s.lift);
    if (s.start < 0.0) fail(path, key + ".start", "must be >= 0");
    if (!(s.duration >= 0.1) || s.duration > 10.0)
      fail(path, key + ".duration", "must be in [0.1, 10] s");
    if (!(s.lift > 0.0) || s.lift > 0.10) fail(path, key + ".lift", "must be in (0, 0.10] m");
    if (!t.feet.empty() && s.start < t.feet.back().start + t.feet.back().duration)
      fail(path, key + ".start",
           "steps must be in time order and must not overlap (one foot in the air at a time)");
    t.feet.push_back(s);
  }
}

}  // namespace

Trajectory load_trajectory(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  check_keys(path, "", root, {"name", "description", "lead_ticks", "com", "joints", "feet"});
  Trajectory t;
  if (!root["name"]) fail(path, "name", "missing");
  t.name = root["name"].as<std::string>();
  if (root["description"]) t.description = root["description"].as<std::string>();
  t.lead_ticks = static_cast<int>(number(path, "lead_ticks", root["lead_ticks"], t.lead_ticks));
  if (t.lead_ticks < 1 || t.lead_ticks > 400) fail(path, "lead_ticks", "must be in 1..400");
  if (const YAML::Node com = root["com"]) read_com_moves(path, com, t);
  if (const YAML::Node joints = root["joints"]) read_joint_swings(path, joints, t);
  if (const YAML::Node feet = root["feet"]) read_foot_steps(path, feet, t);
  if (t.com.empty() && t.joints.empty() && t.feet.empty())
    fail(path, "com", "neither CoM moves, joint swings nor steps");
  return t;
}

void resolve_com_moves(Trajectory& traj, double t, const Eigen::Vector3d& origin,
                       const Eigen::Vector3d& right_sole_W,
                       const Eigen::Vector3d& left_sole_W) noexcept {
  Eigen::Vector3d target = origin;  // the CoM target before each move
  for (ComMove& m : traj.com) {
    if (!m.resolved && t >= m.start) {
      const Eigen::Vector3d point = m.over == ComOver::kRight  ? right_sole_W
                                    : m.over == ComOver::kLeft ? left_sole_W
                                                               : 0.5 * (right_sole_W + left_sole_W);
      m.shift = Eigen::Vector3d(point.x() - target.x(), point.y() - target.y(), 0.0);
      m.resolved = true;
    }
    if (!m.resolved) break;  // later moves start later still
    target += m.shift;
  }
}

bool com_offset(const Trajectory& traj, double t, Eigen::Vector3d& offset,
                Eigen::Vector3d& velocity) noexcept {
  offset.setZero();
  velocity.setZero();
  if (traj.com.empty() || t < traj.com.front().start) return false;
  for (const ComMove& m : traj.com) {
    if (!m.resolved) break;
    double s = 0.0, ds = 0.0, dds = 0.0;
    smooth_step((t - m.start) / m.duration, s, ds, dds);
    offset += s * m.shift;
    velocity += (ds / m.duration) * m.shift;
  }
  return true;
}

void swing_offset(const JointSwing& s, double t, double& q, double& qd, double& qdd) noexcept {
  q = qd = qdd = 0.0;
  const double tau = t - s.start;
  if (tau <= 0.0 || tau >= s.duration) return;
  // Envelope: rise over [0, fade], fall over [duration - fade, duration].
  double e = 1.0, de = 0.0, dde = 0.0;
  if (tau < s.fade) {
    double a, da, dda;
    smooth_step(tau / s.fade, a, da, dda);
    e = a;
    de = da / s.fade;
    dde = dda / (s.fade * s.fade);
  } else if (tau > s.duration - s.fade) {
    double a, da, dda;
    smooth_step((s.duration - tau) / s.fade, a, da, dda);
    e = a;
    de = -da / s.fade;
    dde = dda / (s.fade * s.fade);
  }
  const double w = 2.0 * M_PI * s.frequency;
  const double sn = std::sin(w * tau + s.phase), cs = std::cos(w * tau + s.phase);
  const double A = s.amplitude;
  q = e * A * sn;
  qd = de * A * sn + e * A * w * cs;
  qdd = dde * A * sn + 2.0 * de * A * w * cs - e * A * w * w * sn;
}

bool step_lift(const FootStep& s, double t, double& z, double& zd, double& zdd) noexcept {
  z = zd = zdd = 0.0;
  const double tau = t - s.start;
  if (!(tau >= 0.0) || tau >= s.duration) return false;
  // Up over the first half, down over the second: z = lift * step(x), x the phase of the half.
  const double half = 0.5 * s.duration;
  double a = 0.0, da = 0.0, dda = 0.0;
  if (tau < half) {
    smooth_step(tau / half, a, da, dda);
    zd = s.lift * da / half;
  } else {
    smooth_step((s.duration - tau) / half, a, da, dda);
    zd = -s.lift * da / half;
  }
  z = s.lift * a;
  zdd = s.lift * dda / (half * half);
  return true;
}

const FootStep* active_step(const Trajectory& traj, double t) noexcept {
  for (const FootStep& s : traj.feet)
    if (t >= s.start && t < s.start + s.duration) return &s;
  return nullptr;
}

bool has_joint_motion(const Trajectory& traj, double t) noexcept {
  for (const JointSwing& s : traj.joints)
    if (t >= s.start) return true;
  return false;
}

}  // namespace poise::reference
