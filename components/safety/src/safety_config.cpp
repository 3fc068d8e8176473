#include <algorithm>
#include <cmath>
#include <limits>

#include "poise/model/data.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/safety/safety_layer.hpp"

namespace poise::safety {

Config make_config(const model::Model& model, const model::RobotConfig* robot,
                   const std::vector<std::string>& joint_names, double dt, double damping_kd,
                   const Eigen::VectorXd& q0) {
  const auto n = static_cast<Eigen::Index>(joint_names.size());
  Config c;
  c.joint_names = joint_names;
  c.hold_kp.resize(n);
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
    c.hold_kp[w] = std::min(kp, kp_max);
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
