#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "poise/model/data.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/safety/safety_layer.hpp"

namespace poise::safety {

namespace {

// Mass and first moment (mass x CoM, world) of bodies [first, last] after forward kinematics.
struct Load {
  double mass = 0.0;
  model::Vector3 moment = model::Vector3::Zero();
  void add(const model::Model& model, const model::Data& data, int first, int last) {
    for (int b = first; b <= last; ++b) {
      const model::Inertia& I = model.inertia[static_cast<std::size_t>(b)];
      const model::SE3& X = data.oMi[static_cast<std::size_t>(b)];
      mass += I.mass;
      moment += I.mass * (X.R * I.com + X.p);
    }
  }
};

}  // namespace

Eigen::VectorXd gravity_stiffness(const model::Model& model, const model::RobotConfig* robot,
                                  const Eigen::VectorXd& q) {
  model::Data data(model);
  model::forward_kinematics(model, data, q);
  std::vector<int> foot_bodies;
  if (robot)
    for (const model::FootConfig& f : robot->feet)
      if (model.has_frame(f.link))
        foot_bodies.push_back(model.frames[static_cast<std::size_t>(model.frame_id(f.link))].body);
  Eigen::VectorXd k(model.njoints);
  for (int j = 0; j < model.njoints; ++j) {
    const int b = j + 1, end = model.subtree_end[static_cast<std::size_t>(b)];
    const bool carries_a_foot = std::any_of(foot_bodies.begin(), foot_bodies.end(),
                                            [&](int f) { return f >= b && f <= end; });
    // Standing on that foot, the joint carries everything outside its subtree; otherwise it
    // carries its subtree.
    Load load;
    if (carries_a_foot) {
      load.add(model, data, 0, b - 1);
      load.add(model, data, end + 1, model.nbodies - 1);
    } else {
      load.add(model, data, b, end);
    }
    if (load.mass <= 0.0) {
      k[j] = 0.0;
      continue;
    }
    const model::SE3& X = data.oMi[static_cast<std::size_t>(b)];
    const model::Vector3 a = X.R * model.axis[static_cast<std::size_t>(b)];
    const model::Vector3 r = load.moment / load.mass - X.p;
    // Gravity's torque about the axis, a . (r x m g), grows by a . ((a x r) x m g) per radian the
    // load turns: positive means it tips further.
    k[j] = a.dot(a.cross(r).cross(load.mass * model.gravity));
  }
  return k;
}

Config make_config(const model::Model& model, const model::RobotConfig* robot,
                   const std::vector<std::string>& joint_names, double dt, double damping_kd,
                   const Eigen::VectorXd& q0) {
  const auto n = static_cast<Eigen::Index>(joint_names.size());
  Config c;
  c.joint_names = joint_names;
  c.hold_kp.resize(n);
  c.settle_kp.resize(n);
  c.hold_kd.resize(n);
  c.damping_kd.resize(n);
  c.effort.resize(n);
  c.q_min.resize(n);
  c.q_max.resize(n);
  Eigen::VectorXd q = q0;
  if (q.size() != model.nq)
    q = robot && robot->q_nominal.size() == model.nq ? robot->q_nominal : model.neutral();
  model::Data data(model);
  const Eigen::MatrixXd& M = model::crba(model, data, q);
  const Eigen::VectorXd k_gravity = gravity_stiffness(model, robot, q);
  for (Eigen::Index w = 0; w < n; ++w) {
    const int j = model.joint_index(joint_names[static_cast<std::size_t>(w)]);
    const double inertia = M(model.idx_v(j), model.idx_v(j));
    // Stability of an explicit PD at period dt on this joint alone (see the header).
    const double kp_max = 0.2 * inertia / (dt * dt), kd_max = 0.5 * inertia / dt;
    double kp = 100.0, kd = 2.0;
    if (robot && robot->gains.size() == static_cast<std::size_t>(model.njoints)) {
      kp = robot->gains[static_cast<std::size_t>(j)].kp;
      kd = robot->gains[static_cast<std::size_t>(j)].kd;
    }
    // A held posture is a statue: each joint must be stiffer than gravity's pull on its load
    // (the inverted pendulum over an ankle needs m g h), with a margin of 2.
    c.settle_kp[w] = std::min(kp, kp_max);
    kp = std::max(kp, 2.0 * k_gravity[j]);
    c.hold_kp[w] = std::min(kp, kp_max);
    if (c.hold_kp[w] < k_gravity[j]) {
      char line[256];
      std::snprintf(line, sizeof line,
                    "hold gain of %s bounded at %.0f N m/rad by its inertia, below gravity's "
                    "stiffness on its load (%.0f N m/rad): standing on one foot, the held robot "
                    "tips over about this joint",
                    joint_names[static_cast<std::size_t>(w)].c_str(), c.hold_kp[w], k_gravity[j]);
      c.warnings.emplace_back(line);
    }
    c.hold_kd[w] = std::min(kd, kd_max);
    c.damping_kd[w] = std::min(damping_kd, kd_max);
    const model::JointLimits& l = model.limits[static_cast<std::size_t>(j)];
    c.effort[w] = l.effort > 0 ? l.effort : std::numeric_limits<double>::infinity();
    c.q_min[w] = l.lower;
    c.q_max[w] = l.upper;
  }
  return c;
}

}  // namespace poise::safety
