// Content comparison of two robots (configuration + model): what a node says when the robot it
// was given differs from the one on poise/robot_description.
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "poise/model/robot_config.hpp"

namespace poise::model {
namespace {

class Diff {
 public:
  Diff(std::string a, std::string b, std::size_t max_lines)
      : a_(std::move(a)), b_(std::move(b)), max_(max_lines) {}

  void add(const std::string& line) {
    ++count_;
    if (lines_.size() < max_) lines_.push_back(line);
  }
  /// "what: X in A, Y in B"
  template <class T>
  void pair(const std::string& what, const T& x, const T& y) {
    std::ostringstream os;
    os.precision(12);
    os << what << ": " << x << " in " << a_ << ", " << y << " in " << b_;
    add(os.str());
  }
  void text(const std::string& what, const std::string& x, const std::string& y) {
    if (x != y) pair(what, quote(x), quote(y));
  }
  void number(const std::string& what, double x, double y) {
    if (!same(x, y)) pair(what, x, y);
  }
  template <class M>
  void matrix(const std::string& what, const M& x, const M& y) {
    bool eq = x.rows() == y.rows() && x.cols() == y.cols();
    for (Eigen::Index i = 0; eq && i < x.size(); ++i)
      eq = same(x.data()[i], y.data()[i]);
    if (eq) return;
    std::ostringstream ox, oy;
    ox.precision(12);
    oy.precision(12);
    ox << "(" << x.transpose().reshaped().transpose() << ")";
    oy << "(" << y.transpose().reshaped().transpose() << ")";
    pair(what, ox.str(), oy.str());
  }
  void names(const std::string& what, const std::vector<std::string>& x,
             const std::vector<std::string>& y) {
    if (x == y) return;
    const std::set<std::string> sx(x.begin(), x.end()), sy(y.begin(), y.end());
    std::string only_x, only_y;
    for (const auto& n : x)
      if (!sy.count(n)) only_x += (only_x.empty() ? "" : ", ") + n;
    for (const auto& n : y)
      if (!sx.count(n)) only_y += (only_y.empty() ? "" : ", ") + n;
    if (!only_x.empty()) add(what + ": only in " + a_ + ": " + only_x);
    if (!only_y.empty()) add(what + ": only in " + b_ + ": " + only_y);
    if (only_x.empty() && only_y.empty()) {
      if (x.size() != y.size()) {
        pair(what + " count", x.size(), y.size());
        return;
      }
      for (std::size_t i = 0; i < x.size(); ++i)
        if (x[i] != y[i]) {
          pair(what + " order, entry " + std::to_string(i), quote(x[i]), quote(y[i]));
          return;
        }
    }
  }

  std::vector<std::string> result() && {
    if (count_ > lines_.size())
      lines_.push_back("... and " + std::to_string(count_ - lines_.size()) + " more");
    return std::move(lines_);
  }

 private:
  static bool same(double x, double y) {
    if (x == y) return true;  // also equal infinities
    if (!std::isfinite(x) || !std::isfinite(y)) return false;
    return std::abs(x - y) <= 1e-9 * std::max({1.0, std::abs(x), std::abs(y)});
  }
  static std::string quote(const std::string& s) { return "'" + s + "'"; }

  std::string a_, b_;
  std::size_t max_;
  std::size_t count_ = 0;
  std::vector<std::string> lines_;
};

std::vector<std::string> frame_names(const Model& m) {
  std::vector<std::string> out;
  for (const Frame& f : m.frames)
    out.push_back(f.name);
  std::sort(out.begin(), out.end());  // frame order is not meaningful
  return out;
}

const char* type_name(JointType t) {
  switch (t) {
    case JointType::kFloating: return "floating";
    case JointType::kRevolute: return "revolute";
    case JointType::kContinuous: return "continuous";
    case JointType::kPrismatic: return "prismatic";
  }
  return "?";
}

}  // namespace

std::vector<std::string> robot_differences(const RobotConfig& ca, const Model& ma,
                                           const std::string& a, const RobotConfig& cb,
                                           const Model& mb, const std::string& b,
                                           std::size_t max_lines) {
  Diff d(a, b, max_lines);
  d.text("robot name", ca.name, cb.name);
  d.text("URDF robot name", ma.name, mb.name);
  d.names("joints", ma.joint_names, mb.joint_names);
  d.names("links", frame_names(ma), frame_names(mb));
  d.number("total mass [kg]", ma.total_mass, mb.total_mass);
  // Bodies: compared when both models have the same joints in the same order (then body b is
  // moved by the same joint on both sides); otherwise the joint difference above says enough.
  if (ma.joint_names == mb.joint_names && ma.nbodies == mb.nbodies) {
    for (int i = 0; i < ma.nbodies; ++i) {
      const std::string body = "link '" + ma.body_name[i] + "'";
      d.text("body " + std::to_string(i) + " link", ma.body_name[i], mb.body_name[i]);
      d.number(body + " mass [kg]", ma.inertia[i].mass, mb.inertia[i].mass);
      d.matrix(body + " centre of mass [m]", ma.inertia[i].com, mb.inertia[i].com);
      d.matrix(body + " inertia [kg m^2]", ma.inertia[i].I_com, mb.inertia[i].I_com);
      d.number(body + " parent", ma.parent[i], mb.parent[i]);
      if (i == 0) continue;
      const std::string joint = "joint '" + ma.joint_names[i - 1] + "'";
      if (ma.joint_type[i] != mb.joint_type[i])
        d.pair(joint + " type", std::string(type_name(ma.joint_type[i])),
               std::string(type_name(mb.joint_type[i])));
      d.matrix(joint + " position [m]", ma.X_parent_joint[i].p, mb.X_parent_joint[i].p);
      d.matrix(joint + " rotation", ma.X_parent_joint[i].R, mb.X_parent_joint[i].R);
      d.matrix(joint + " axis", ma.axis[i], mb.axis[i]);
      const JointLimits &la = ma.limits[i - 1], &lb = mb.limits[i - 1];
      d.number(joint + " lower limit", la.lower, lb.lower);
      d.number(joint + " upper limit", la.upper, lb.upper);
      d.number(joint + " velocity limit", la.velocity, lb.velocity);
      d.number(joint + " effort limit", la.effort, lb.effort);
      d.number(joint + " damping", ma.damping[i - 1], mb.damping[i - 1]);
      d.number(joint + " friction", ma.friction[i - 1], mb.friction[i - 1]);
    }
  }
  d.text("imu_frame", ca.imu_frame, cb.imu_frame);
  const char* side[2] = {"right", "left"};
  for (int s = 0; s < 2; ++s) {
    const FootConfig &fa = ca.feet[s], &fb = cb.feet[s];
    const std::string k = std::string("feet.") + side[s];
    d.text(k + ".frame", fa.frame, fb.frame);
    d.text(k + ".link", fa.link, fb.link);
    d.text(k + ".sole_frame", fa.sole_frame, fb.sole_frame);
    for (int i = 0; i < 3; ++i) {
      d.number(k + ".sole_frame.offset[" + std::to_string(i) + "] [m]", fa.X_link_sole.p[i],
               fb.X_link_sole.p[i]);
      for (int c = 0; c < 3; ++c)
        d.number(k + ".sole_frame rotation(" + std::to_string(i) + "," + std::to_string(c) + ")",
                 fa.X_link_sole.R(i, c), fb.X_link_sole.R(i, c));
    }
    d.number(k + ".sole.x_min [m]", fa.sole.x_min, fb.sole.x_min);
    d.number(k + ".sole.x_max [m]", fa.sole.x_max, fb.sole.x_max);
    d.number(k + ".sole.y_min [m]", fa.sole.y_min, fb.sole.y_min);
    d.number(k + ".sole.y_max [m]", fa.sole.y_max, fb.sole.y_max);
    d.number(k + ".sole.height [m]", fa.sole.height, fb.sole.height);
  }
  for (int i = 0; i < 3; ++i)
    d.number("forward_axis[" + std::to_string(i) + "]", ca.forward_axis[i], cb.forward_axis[i]);
  d.number("contact.safety_margin [m]", ca.safety_margin, cb.safety_margin);
  d.number("contact.friction_mu", ca.friction_mu, cb.friction_mu);
  d.number("contact.torsional_mu [m]", ca.torsional_mu, cb.torsional_mu);
  d.names("joint_groups.legs", ca.leg_joints, cb.leg_joints);
  d.names("joint_groups.upper_body", ca.upper_body_joints, cb.upper_body_joints);
  if (ma.joint_names == mb.joint_names && ca.q_nominal.size() == cb.q_nominal.size() &&
      ca.gains.size() == cb.gains.size() && ca.gains.size() == ma.joint_names.size()) {
    for (std::size_t j = 0; j < ma.joint_names.size(); ++j) {
      const std::string& n = ma.joint_names[j];
      const auto iq = static_cast<Eigen::Index>(7 + j);
      d.number("nominal_posture." + n + " [rad]", ca.q_nominal[iq], cb.q_nominal[iq]);
      d.number("pd_gains." + n + ".kp", ca.gains[j].kp, cb.gains[j].kp);
      d.number("pd_gains." + n + ".kd", ca.gains[j].kd, cb.gains[j].kd);
    }
  }
  return std::move(d).result();
}

}  // namespace poise::model
