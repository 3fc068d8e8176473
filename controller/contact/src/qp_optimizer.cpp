#include "poise/contact/qp_optimizer.hpp"

#include <algorithm>
#include <cmath>

namespace poise::contact {

QpOptimizer::QpOptimizer() : qp_(kMaxVars, 0, kMaxConstraints) {
  M_.setZero();
  c_.setZero();
  G_.setZero();
  g_.setZero();
  A_.setZero();
  b_.setZero();
  y_.setZero();
  y_first_.setZero();
  rho_.setZero();
}

void QpOptimizer::solve(const ContactProblem& p, ContactSolution& solution) {
  adjusted_ = false;
  raw_objective_ = 0.0;
  n_ = 0;
  if (!detail::prepare(p, solution)) return;
  int slots[kMaxFeet];
  int nf = 0;
  for (int i = 0; i < kMaxFeet; ++i)
    if (p.feet[i].in_contact) slots[nf++] = i;
  const int n = kVarsPerFoot * nf;
  const int mi = kConstraintsPerFoot * nf;
  n_ = n;
  // Residual M y - c, y = [rho; m_F] per foot; f_F = B rho with B the local pyramid basis.
  // Priority::kLexicographic: the angular and regularisation rows scaled down together (see
  // ContactWeights::scale()), so the linear rows rule and the rest is optimised given them.
  const double scale = p.weights.scale();
  const double sw_k = std::sqrt(p.weights.w_k * scale);
  M_.setZero();
  c_.setZero();
  A_.setZero();
  b_.setZero();
  c_.segment<3>(0) = p.l_dot_desired - p.mass * p.gravity;
  c_.segment<3>(3) = sw_k * p.k_dot_desired;
  for (int s = 0; s < nf; ++s)
    add_foot_rows(p, p.feet[slots[s]], s, sw_k, std::sqrt(p.weights.eps_f * scale),
                  std::sqrt(p.weights.eps_tau * scale));
  G_.noalias() = M_.transpose() * M_;
  g_.noalias() = -M_.transpose() * c_;
  const double ridge = 1e-10 * (G_.trace() / n + 1e-12);
  G_.diagonal().head(n).array() += ridge;

  qp_status_ = qp_.solve(G_.topLeftCorner(n, n), g_.head(n), G_.topRows(0).leftCols(n), g_.head(0),
                         A_.topLeftCorner(mi, n), b_.head(mi), y_.head(n));
  if (qp_status_ == SolverStatus::kInvalidInput ||
      qp_status_ == SolverStatus::kNotPositiveDefinite || qp_status_ == SolverStatus::kInfeasible) {
    set_safe_solution(ContactStatus::kSolverFailure, solution);
    return;
  }
  if (passes_ > 1 && qp_status_ == SolverStatus::kOptimal) {
    // Refinement: torsion rows about the CoP d* of the first pass (linear for fixed d*).
    for (int s = 0; s < nf; ++s)
      refine_torsion_rows(p, p.feet[slots[s]], s);
    y_first_ = y_;
    const SolverStatus second =
        qp_.solve(G_.topLeftCorner(n, n), g_.head(n), G_.topRows(0).leftCols(n), g_.head(0),
                  A_.topLeftCorner(mi, n), b_.head(mi), y_.head(n));
    if (second != SolverStatus::kOptimal) y_ = y_first_;  // keep the first pass
  }
  // J_qp = |M y - c|^2 (the ridge is not part of the objective).
  raw_objective_ = (M_ * y_ - c_).squaredNorm();  // unused columns of M_ are zero
  rho_.setZero();
  for (int s = 0; s < nf; ++s)
    solution.feet[slots[s]] = admissible_wrench(p, p.feet[slots[s]], s, slots[s]);
  detail::finish(p,
                 qp_status_ == SolverStatus::kIterationLimit ? ContactStatus::kIterationLimit
                                                             : ContactStatus::kOk,
                 solution);
}

// The residual rows (linear and angular momentum, regularisation) and the inequality rows
// (rho >= 0, CoP in the safe region, torsion) of the foot in slot s.
void QpOptimizer::add_foot_rows(const ContactProblem& p, const FootContact& foot, int s,
                                double sw_k, double se_f, double se_t) {
  const Eigen::Matrix3d& R = foot.R_WF;
  const double h = foot.ankle_height;
  const Eigen::Matrix<double, 3, 4> B = R.transpose() * friction_basis_W(foot);  // in F
  Eigen::Matrix3d S;  // o x f with o = (0, 0, -h): (h f_y, -h f_x, 0)
  S << 0.0, h, 0.0, -h, 0.0, 0.0, 0.0, 0.0, 0.0;
  const int col = kVarsPerFoot * s;
  M_.block<3, 4>(0, col).noalias() = R * B;
  M_.block<3, 4>(3, col).noalias() = sw_k * (detail::skew(foot.p_WF - p.com) * R + R * S) * B;
  M_.block<3, 3>(3, col + 4) = sw_k * R;
  M_.block<4, 4>(6 + 7 * s, col) = se_f * Eigen::Matrix4d::Identity();
  M_.block<3, 4>(10 + 7 * s, col).noalias() = se_t * S * B;
  M_.block<3, 3>(10 + 7 * s, col + 4) = se_t * Eigen::Matrix3d::Identity();

  // Inequalities A y >= 0. Columns: rho_1..4, m_x, m_y, m_z; f_z = B.row(2) rho.
  const int r = kConstraintsPerFoot * s;
  const Eigen::Vector4d region = safe_region(foot);
  const Eigen::Matrix<double, 1, 4> fz = B.row(2);
  for (int j = 0; j < 4; ++j)
    A_(r + j, col + j) = 1.0;                    // rho >= 0
  A_.block<1, 4>(r + 4, col) = -region[0] * fz;  // -m_y - x_lo f_z >= 0
  A_(r + 4, col + 5) = -1.0;
  A_.block<1, 4>(r + 5, col) = region[1] * fz;  // m_y + x_hi f_z >= 0
  A_(r + 5, col + 5) = 1.0;
  A_.block<1, 4>(r + 6, col) = -region[2] * fz;  // m_x - y_lo f_z >= 0
  A_(r + 6, col + 4) = 1.0;
  A_.block<1, 4>(r + 7, col) = region[3] * fz;  // y_hi f_z - m_x >= 0
  A_(r + 7, col + 4) = -1.0;
  A_.block<1, 4>(r + 8, col) = foot.mu_torsion * fz;  // mu_t f_z - m_z >= 0
  A_(r + 8, col + 6) = -1.0;
  A_.block<1, 4>(r + 9, col) = foot.mu_torsion * fz;  // mu_t f_z + m_z >= 0
  A_(r + 9, col + 6) = 1.0;
}

// The second pass's torsion rows of the foot in slot s, about the first pass's CoP.
void QpOptimizer::refine_torsion_rows(const ContactProblem& p, const FootContact& foot, int s) {
  const double threshold = 1e-9 * (p.mass * p.gravity.norm() + 1.0);
  const int col = kVarsPerFoot * s;
  const int r = kConstraintsPerFoot * s;
  const Eigen::Matrix<double, 3, 4> B = foot.R_WF.transpose() * friction_basis_W(foot);
  const double f_z = B.row(2).dot(y_.segment<4>(col));
  if (!(f_z > threshold)) return;
  const Eigen::Vector4d region = safe_region(foot);
  const double d_x = std::clamp(-y_[col + 5] / f_z, region[0], region[1]);
  const double d_y = std::clamp(y_[col + 4] / f_z, region[2], region[3]);
  // tau_n = m_z - (d_x f_y - d_y f_x) = m_z - c^T rho
  const Eigen::Matrix<double, 1, 4> c = d_x * B.row(1) - d_y * B.row(0);
  // The friction-coupled limit mu_t (f_z - |f_t| / mu), linearised about the first pass's
  // tangential direction u (exact along u; the clean-up below clamps to the exact limit).
  Eigen::Matrix<double, 1, 4> limit = foot.mu_torsion * B.row(2);
  const Eigen::Vector2d f_t = B.topRows<2>() * y_.segment<4>(col);
  if (p.weights.torsion == TorsionLimit::kFrictionCoupled && foot.mu > 0.0 &&
      f_t.norm() > 0.0) {
    const Eigen::Vector2d u = f_t.normalized();
    limit -= (foot.mu_torsion / foot.mu) * (u.x() * B.row(0) + u.y() * B.row(1));
  }
  A_.block<1, 4>(r + 8, col) = limit + c;
  A_.block<1, 4>(r + 9, col) = limit - c;
}

// Admissibility clean-up in the paper's model: the foot's wrench from the QP's answer, with its
// CoP clamped into the safe region and its normal torque into the torsion limit (adjusted_ says
// whether anything moved beyond round-off).
FootWrench QpOptimizer::admissible_wrench(const ContactProblem& p, const FootContact& foot, int s,
                                          int slot) {
  const double threshold = 1e-9 * (p.mass * p.gravity.norm() + 1.0);
  const Eigen::Vector4d region = safe_region(foot);
  const Eigen::Vector4d rho = y_.segment<4>(kVarsPerFoot * s).cwiseMax(0.0);  // round-off
  rho_.segment<4>(4 * slot) = rho;
  const Eigen::Vector3d f_W = friction_basis_W(foot) * rho;
  const Eigen::Vector3d f = foot.R_WF.transpose() * f_W;
  const Eigen::Vector3d m = y_.segment<3>(kVarsPerFoot * s + 4);
  const double tol = 1e-9 * (f.norm() + m.norm() + threshold);
  if (!(f.z() > threshold)) {
    adjusted_ = adjusted_ || f.norm() > tol;
    return make_foot_wrench(foot, Eigen::Vector3d::Zero(), 0.5 * (region[0] + region[1]),
                            0.5 * (region[2] + region[3]), 0.0);
  }
  const double d_x_raw = -m.y() / f.z();
  const double d_y_raw = m.x() / f.z();
  const double d_x = std::clamp(d_x_raw, region[0], region[1]);
  const double d_y = std::clamp(d_y_raw, region[2], region[3]);
  const double tau_n_raw = m.z() - (d_x * f.y() - d_y * f.x());
  const double tau_n_max = torsion_limit(foot, f, p.weights.torsion);
  const double tau_n = std::clamp(tau_n_raw, -tau_n_max, tau_n_max);
  adjusted_ = adjusted_ || std::abs(d_x - d_x_raw) * f.z() > tol ||
              std::abs(d_y - d_y_raw) * f.z() > tol || std::abs(tau_n - tau_n_raw) > tol;
  return make_foot_wrench(foot, f_W, d_x, d_y, tau_n);
}

}  // namespace poise::contact
