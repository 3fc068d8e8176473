#include "poise/controller/contact_fallback.hpp"

#include <algorithm>

namespace poise::controller {

void gravity_distribution(const contact::ContactProblem& problem,
                          contact::ContactSolution& solution) {
  for (auto& f : solution.feet)
    f = contact::FootWrench{};
  const bool r = problem.feet[0].in_contact;
  const bool l = problem.feet[1].in_contact;
  solution.status = contact::ContactStatus::kCompromised;
  if (!r && !l) {
    solution.status = contact::ContactStatus::kNoContact;
    solution.k_dot_admissible.setZero();
    solution.l_dot_admissible = problem.mass * problem.gravity;
    return;
  }
  // Share of the left foot: horizontal projection of the CoM on the segment between the ankles.
  double alpha_l = l ? 1.0 : 0.0;
  if (r && l) {
    const Eigen::Vector2d a = problem.feet[0].p_WF.head<2>();
    const Eigen::Vector2d b = problem.feet[1].p_WF.head<2>();
    const Eigen::Vector2d ab = b - a;
    const double len2 = ab.squaredNorm();
    alpha_l = len2 > 1e-12 ? std::clamp((problem.com.head<2>() - a).dot(ab) / len2, 0.0, 1.0) : 0.5;
  }
  const double share[2] = {1.0 - alpha_l, alpha_l};
  const Eigen::Vector3d weight = -problem.mass * problem.gravity;  // upward support force
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  for (int i = 0; i < 2; ++i) {
    if (!problem.feet[i].in_contact) continue;
    solution.feet[i].force_W = share[i] * weight;
    moment += (problem.feet[i].p_WF - problem.com).cross(solution.feet[i].force_W);
  }
  for (int i = 0; i < 2; ++i) {
    if (!problem.feet[i].in_contact) continue;
    auto& f = solution.feet[i];
    f.torque_ankle_W = -share[i] * moment;
    // CoP where the line of action meets the sole plane (informational).
    const auto& foot = problem.feet[i];
    const Eigen::Vector3d f_F = foot.R_WF.transpose() * f.force_W;
    const Eigen::Vector3d t_F = foot.R_WF.transpose() * f.torque_ankle_W;
    if (f_F.z() > 1e-9) {
      // tau = d x f + tau_n e_z with d = (dx, dy, -h): solve the x, y rows for dx, dy.
      const double h = foot.ankle_height;
      const double dx = (-t_F.y() - h * f_F.x()) / f_F.z();
      const double dy = (t_F.x() - h * f_F.y()) / f_F.z();
      f.cop_F = Eigen::Vector2d(dx, dy);
      f.cop_W = foot.p_WF + foot.R_WF * Eigen::Vector3d(dx, dy, -h);
      f.normal_torque = t_F.z() - (dx * f_F.y() - dy * f_F.x());
    } else {
      f.cop_W = foot.p_WF;
    }
  }
  const auto hdot = momentum_rate_of_wrenches(problem, solution);
  solution.k_dot_admissible = hdot.head<3>();
  solution.l_dot_admissible = hdot.tail<3>();
}

Eigen::Matrix<double, 6, 1> momentum_rate_of_wrenches(const contact::ContactProblem& problem,
                                                      const contact::ContactSolution& solution) {
  Eigen::Matrix<double, 6, 1> hdot;
  hdot.head<3>().setZero();
  hdot.tail<3>() = problem.mass * problem.gravity;
  for (int i = 0; i < 2; ++i) {
    if (!problem.feet[i].in_contact) continue;
    const auto& f = solution.feet[i];
    hdot.head<3>() += (problem.feet[i].p_WF - problem.com).cross(f.force_W) + f.torque_ankle_W;
    hdot.tail<3>() += f.force_W;
  }
  return hdot;
}

}  // namespace poise::controller
