#include "poise/contact/contact_problem.hpp"

#include <algorithm>
#include <cmath>

namespace poise::contact {

namespace {

// Beyond this magnitude the squares in the objectives lose meaning; treated as invalid input.
constexpr double kMaxMagnitude = 1e9;

bool finite_and_bounded(double v) {
  return std::isfinite(v) && std::abs(v) <= kMaxMagnitude;
}

template <typename Derived>
bool finite_and_bounded(const Eigen::MatrixBase<Derived>& m) {
  for (Eigen::Index i = 0; i < m.size(); ++i)
    if (!finite_and_bounded(m.derived().coeff(i))) return false;
  return true;
}

const char* validate_foot(const FootContact& foot, int i) {
  // Messages are static so that validate() never allocates.
  static constexpr const char* kMsg[][kMaxFeet] = {
      {"feet[0]: R_WF has a non-finite entry", "feet[1]: R_WF has a non-finite entry"},
      {"feet[0]: R_WF is not a rotation (R^T R != I or det != 1)",
       "feet[1]: R_WF is not a rotation (R^T R != I or det != 1)"},
      {"feet[0]: p_WF is not finite", "feet[1]: p_WF is not finite"},
      {"feet[0]: sole bounds are not finite or min >= max",
       "feet[1]: sole bounds are not finite or min >= max"},
      {"feet[0]: safety_margin is negative, not finite, or leaves no safe region",
       "feet[1]: safety_margin is negative, not finite, or leaves no safe region"},
      {"feet[0]: ankle_height is negative or not finite",
       "feet[1]: ankle_height is negative or not finite"},
      {"feet[0]: mu is negative or not finite", "feet[1]: mu is negative or not finite"},
      {"feet[0]: mu_torsion is negative or not finite",
       "feet[1]: mu_torsion is negative or not finite"},
  };
  if (!finite_and_bounded(foot.R_WF)) return kMsg[0][i];
  const double ortho2 =
      (foot.R_WF.transpose() * foot.R_WF - Eigen::Matrix3d::Identity()).squaredNorm();
  if (!(ortho2 < 1e-12) || !(foot.R_WF.determinant() > 0.0)) return kMsg[1][i];  // |.| < 1e-6
  if (!finite_and_bounded(foot.p_WF)) return kMsg[2][i];
  const SoleRectangle& s = foot.sole;
  if (!finite_and_bounded(s.x_min) || !finite_and_bounded(s.x_max) ||
      !finite_and_bounded(s.y_min) || !finite_and_bounded(s.y_max) || !(s.x_min < s.x_max) ||
      !(s.y_min < s.y_max)) {
    return kMsg[3][i];
  }
  const double mgn = foot.safety_margin;
  if (!finite_and_bounded(mgn) || mgn < 0.0 || s.x_min + mgn > s.x_max - mgn ||
      s.y_min + mgn > s.y_max - mgn) {
    return kMsg[4][i];
  }
  if (!finite_and_bounded(foot.ankle_height) || foot.ankle_height < 0.0) return kMsg[5][i];
  if (!finite_and_bounded(foot.mu) || foot.mu < 0.0) return kMsg[6][i];
  if (!finite_and_bounded(foot.mu_torsion) || foot.mu_torsion < 0.0) return kMsg[7][i];
  return nullptr;
}

}  // namespace

const char* to_string(ContactStatus s) {
  switch (s) {
    case ContactStatus::kOk:
      return "ok";
    case ContactStatus::kCompromised:
      return "compromised";
    case ContactStatus::kNoContact:
      return "no_contact";
    case ContactStatus::kIterationLimit:
      return "iteration_limit";
    case ContactStatus::kInvalidInput:
      return "invalid_input";
    case ContactStatus::kSolverFailure:
      return "solver_failure";
  }
  return "unknown";
}

const char* validate(const ContactProblem& p) {
  if (!finite_and_bounded(p.mass) || !(p.mass > 0.0)) return "mass is not finite and positive";
  if (!finite_and_bounded(p.gravity)) return "gravity is not finite";
  if (!finite_and_bounded(p.com)) return "com is not finite";
  if (!finite_and_bounded(p.k_dot_desired)) return "k_dot_desired is not finite (or > 1e9)";
  if (!finite_and_bounded(p.l_dot_desired)) return "l_dot_desired is not finite (or > 1e9)";
  const ContactWeights& w = p.weights;
  if (!finite_and_bounded(w.w_k) || w.w_k < 0.0) return "weights.w_k is negative or not finite";
  if (!finite_and_bounded(w.eps_f) || w.eps_f < 0.0) {
    return "weights.eps_f is negative or not finite";
  }
  if (!finite_and_bounded(w.eps_cop) || w.eps_cop < 0.0) {
    return "weights.eps_cop is negative or not finite";
  }
  if (!finite_and_bounded(w.eps_tau) || w.eps_tau < 0.0) {
    return "weights.eps_tau is negative or not finite";
  }
  for (int i = 0; i < kMaxFeet; ++i) {
    if (!p.feet[i].in_contact) continue;
    if (const char* msg = validate_foot(p.feet[i], i)) return msg;
  }
  return nullptr;
}

const char* to_string(TorsionLimit t) {
  return t == TorsionLimit::kFrictionCoupled ? "friction-coupled" : "independent";
}

double torsion_limit(const FootContact& foot, const Eigen::Vector3d& f_F, TorsionLimit model) {
  const double f_n = std::max(f_F.z(), 0.0);
  if (model != TorsionLimit::kFrictionCoupled || !(foot.mu > 0.0)) return foot.mu_torsion * f_n;
  const double f_t = std::hypot(f_F.x(), f_F.y());
  return foot.mu_torsion * std::max(f_n - f_t / foot.mu, 0.0);
}

Eigen::Vector4d safe_region(const FootContact& foot) {
  const double m = foot.safety_margin;
  return Eigen::Vector4d(foot.sole.x_min + m, foot.sole.x_max - m, foot.sole.y_min + m,
                         foot.sole.y_max - m);
}

FootWrench make_foot_wrench(const FootContact& foot, const Eigen::Vector3d& force_W, double d_x,
                            double d_y, double normal_torque) {
  FootWrench w;
  const Eigen::Vector3d d_F(d_x, d_y, -foot.ankle_height);
  const Eigen::Vector3d d_W = foot.R_WF * d_F;
  w.force_W = force_W;
  // eq. (19): tau_i = (R_i d_i) x f_i + R_i (0, 0, tau_n)
  w.torque_ankle_W = d_W.cross(force_W) + normal_torque * foot.R_WF.col(2);
  w.cop_W = foot.p_WF + d_W;
  w.cop_F = Eigen::Vector2d(d_x, d_y);
  w.normal_torque = normal_torque;
  return w;
}

Eigen::Matrix<double, 3, 4> friction_basis_W(const FootContact& foot) {
  const double mu = foot.mu;
  const double s = 1.0 / std::sqrt(1.0 + mu * mu);
  Eigen::Matrix<double, 3, 4> b;
  b << mu, 0.0, -mu, 0.0,  //
      0.0, mu, 0.0, -mu,   //
      1.0, 1.0, 1.0, 1.0;
  return foot.R_WF * (s * b);
}

void momentum_rate_from_wrenches(const ContactProblem& p, ContactSolution& s) {
  Eigen::Vector3d l = p.mass * p.gravity;
  Eigen::Vector3d k = Eigen::Vector3d::Zero();
  for (int i = 0; i < kMaxFeet; ++i) {
    if (!p.feet[i].in_contact) continue;
    const FootWrench& w = s.feet[i];
    l += w.force_W;
    k += (p.feet[i].p_WF - p.com).cross(w.force_W) + w.torque_ankle_W;
  }
  s.l_dot_admissible = l;
  s.k_dot_admissible = k;
}

double tracking_cost(const ContactProblem& p, const ContactSolution& s) {
  return (p.l_dot_desired - s.l_dot_admissible).squaredNorm() +
         p.weights.w_k * (p.k_dot_desired - s.k_dot_admissible).squaredNorm();
}

double qp_objective(const ContactProblem& p, const ContactSolution& s,
                    const Eigen::Matrix<double, 4 * kMaxFeet, 1>& rho) {
  const double sc = p.weights.scale();
  double j = (p.l_dot_desired - s.l_dot_admissible).squaredNorm() +
             sc * p.weights.w_k * (p.k_dot_desired - s.k_dot_admissible).squaredNorm();
  for (int i = 0; i < kMaxFeet; ++i) {
    if (!p.feet[i].in_contact) continue;
    j += sc * (p.weights.eps_f * rho.segment<4>(4 * i).squaredNorm() +
               p.weights.eps_tau * s.feet[i].torque_ankle_W.squaredNorm());
  }
  return j;
}

void set_safe_solution(ContactStatus status, ContactSolution& s) {
  s.status = status;
  s.k_dot_admissible.setZero();
  s.l_dot_admissible.setZero();
  for (FootWrench& w : s.feet)
    w = FootWrench{};
}

namespace detail {

bool prepare(const ContactProblem& p, ContactSolution& s) {
  if (validate(p) != nullptr) {
    set_safe_solution(ContactStatus::kInvalidInput, s);
    return false;
  }
  for (FootWrench& w : s.feet)
    w = FootWrench{};
  if (!p.feet[0].in_contact && !p.feet[1].in_contact) {
    s.status = ContactStatus::kNoContact;
    s.l_dot_admissible = p.mass * p.gravity;
    s.k_dot_admissible.setZero();
    return false;
  }
  return true;
}

void finish(const ContactProblem& p, ContactStatus status, ContactSolution& s) {
  momentum_rate_from_wrenches(p, s);
  bool finite = s.k_dot_admissible.allFinite() && s.l_dot_admissible.allFinite();
  for (const FootWrench& w : s.feet) {
    finite = finite && w.force_W.allFinite() && w.torque_ankle_W.allFinite() &&
             w.cop_W.allFinite() && w.cop_F.allFinite() && std::isfinite(w.normal_torque);
  }
  if (!finite) {
    set_safe_solution(ContactStatus::kSolverFailure, s);
    return;
  }
  if (status != ContactStatus::kOk) {
    s.status = status;
    return;
  }
  const double err = std::sqrt((p.k_dot_desired - s.k_dot_admissible).squaredNorm() +
                               (p.l_dot_desired - s.l_dot_admissible).squaredNorm());
  const double scale = p.mass * p.gravity.norm() +
                       std::sqrt(p.k_dot_desired.squaredNorm() + p.l_dot_desired.squaredNorm());
  const double linear_err = (p.l_dot_desired - s.l_dot_admissible).norm();
  s.status = err <= kRateTolerance * scale && linear_err <= kLinearTolerance * p.mass * p.gravity.norm()
                 ? ContactStatus::kOk
                 : ContactStatus::kCompromised;
}

}  // namespace detail

}  // namespace poise::contact
