#pragma once

// Seeded random contact problems for the tests: feasible ones built from a random admissible
// wrench per foot (so the desired rate is known to be reachable), and arbitrary ones.

#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "poise/contact/contact_problem.hpp"
#include "random_problems.hpp"

namespace poise::contact::test {

inline Eigen::Matrix3d rpy(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

/// A standing robot: feet at y = -+0.1, tilted up to max_tilt about x and y, CoM about 0.8 m up.
inline ContactProblem random_geometry(std::mt19937& rng, bool right, bool left,
                                      double max_tilt = 10.0 * M_PI / 180.0) {
  ContactProblem p;
  p.mass = uniform(rng, 30.0, 80.0);
  p.gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
  p.com =
      Eigen::Vector3d(uniform(rng, -0.05, 0.05), uniform(rng, -0.05, 0.05), uniform(rng, 0.6, 0.9));
  for (int i = 0; i < kMaxFeet; ++i) {
    FootContact& f = p.feet[i];
    f.in_contact = i == 0 ? right : left;
    f.R_WF = rpy(uniform(rng, -max_tilt, max_tilt), uniform(rng, -max_tilt, max_tilt),
                 uniform(rng, -0.3, 0.3));
    f.p_WF =
        Eigen::Vector3d(uniform(rng, -0.1, 0.1), (i == 0 ? -1.0 : 1.0) * uniform(rng, 0.08, 0.15),
                        uniform(rng, 0.05, 0.12));
    f.sole = {uniform(rng, -0.1, -0.05), uniform(rng, 0.1, 0.15), uniform(rng, -0.06, -0.04),
              uniform(rng, 0.04, 0.06)};
    f.safety_margin = uniform(rng, 0.0, 0.01);
    f.ankle_height = uniform(rng, 0.04, 0.1);
    f.mu = uniform(rng, 0.3, 1.0);
    f.mu_torsion = uniform(rng, 0.005, 0.05);
  }
  return p;
}

/// Random admissible wrench of one foot: force inside the inscribed pyramid with a normal
/// component around f_n_mean, CoP inside the safe region, |tau_n| <= mu_torsion f_n.
inline FootWrench random_admissible_wrench(std::mt19937& rng, const FootContact& foot,
                                           double f_n_mean) {
  const double f_n = uniform(rng, 0.2, 1.8) * f_n_mean;
  const double a = uniform(rng, -1.0, 1.0);
  const double budget = uniform(rng, 0.0, 0.95) * foot.mu * f_n;  // |f_x| + |f_y| <= mu f_n
  const Eigen::Vector3d f_F(
      a * budget, (1.0 - std::abs(a)) * budget * (uniform(rng, 0, 1) < 0.5 ? -1 : 1), f_n);
  const Eigen::Vector4d region = safe_region(foot);
  const double d_x = uniform(rng, region[0], region[1]);
  const double d_y = uniform(rng, region[2], region[3]);
  const double tau_n = uniform(rng, -1.0, 1.0) * foot.mu_torsion * f_n;
  return make_foot_wrench(foot, foot.R_WF * f_F, d_x, d_y, tau_n);
}

/// A non-negative decomposition of a force inside the inscribed pyramid on friction_basis_W:
/// the tangential parts on the matching edges, the rest of the normal force spread evenly.
inline Eigen::Vector4d pyramid_decomposition(const FootContact& foot, const Eigen::Vector3d& f_W) {
  const Eigen::Vector3d f = foot.R_WF.transpose() * f_W;
  const double s = 1.0 / std::sqrt(1.0 + foot.mu * foot.mu);
  const double a = foot.mu > 0.0 ? f.x() / (s * foot.mu) : 0.0;
  const double b = foot.mu > 0.0 ? f.y() / (s * foot.mu) : 0.0;
  const double c = f.z() / s;
  const double t = std::max(0.0, (c - std::abs(a) - std::abs(b)) / 4.0);
  return Eigen::Vector4d(std::max(a, 0.0) + t, std::max(b, 0.0) + t, std::max(-a, 0.0) + t,
                         std::max(-b, 0.0) + t);
}

/// Sets the desired rate to the one produced by the given wrenches (feasible by construction).
inline void set_desired_from_wrenches(ContactProblem& p, const FootWrench wrenches[kMaxFeet]) {
  p.l_dot_desired = p.mass * p.gravity;
  p.k_dot_desired.setZero();
  for (int i = 0; i < kMaxFeet; ++i) {
    if (!p.feet[i].in_contact) continue;
    p.l_dot_desired += wrenches[i].force_W;
    p.k_dot_desired +=
        (p.feet[i].p_WF - p.com).cross(wrenches[i].force_W) + wrenches[i].torque_ankle_W;
  }
}

/// A feasible problem: desired rate from random admissible wrenches.
inline ContactProblem random_feasible(std::mt19937& rng, bool right, bool left,
                                      FootWrench* wrenches_out = nullptr) {
  ContactProblem p = random_geometry(rng, right, left);
  const int n = (right ? 1 : 0) + (left ? 1 : 0);
  FootWrench local[kMaxFeet];
  FootWrench* w = wrenches_out != nullptr ? wrenches_out : local;
  for (int i = 0; i < kMaxFeet; ++i) {
    if (p.feet[i].in_contact) w[i] = random_admissible_wrench(rng, p.feet[i], p.mass * 9.81 / n);
  }
  set_desired_from_wrenches(p, w);
  return p;
}

/// An arbitrary problem: desired rates far outside what the feet can do, now and then.
inline ContactProblem random_arbitrary(std::mt19937& rng, bool right, bool left) {
  ContactProblem p = random_geometry(rng, right, left);
  const double mg = p.mass * 9.81;
  p.l_dot_desired = random_matrix(rng, 3, 1, 0.5 * mg);
  p.k_dot_desired = random_matrix(rng, 3, 1, 0.3 * mg);
  return p;
}

}  // namespace poise::contact::test
