#include "poise/contact/sequential_optimizer.hpp"

#include <algorithm>
#include <cmath>

namespace poise::contact {

namespace {

// Below this normal force (relative to m |g| + 1 N) a foot is treated as unloaded.
double unloaded_threshold(const ContactProblem& p) {
  return 1e-9 * (p.mass * p.gravity.norm() + 1.0);
}

}  // namespace

Eigen::Vector3d project_on_friction_cone(const Eigen::Vector3d& f, double mu) {
  const double f_n = f.z();
  const double f_t = std::hypot(f.x(), f.y());
  if (f_t <= mu * f_n) return f;                            // inside the cone
  if (mu * f_t <= -f_n) return Eigen::Vector3d::Zero();      // inside the polar cone
  // Onto the cone's surface, in the plane of f and the normal.
  const double n = (f_n + mu * f_t) / (1.0 + mu * mu);
  const double t = mu * n;
  return Eigen::Vector3d(f.x() * t / f_t, f.y() * t / f_t, n);
}

SequentialOptimizer::SequentialOptimizer() : nnls_(14, 8), bvls_(9, 6) {}

void SequentialOptimizer::solve(const ContactProblem& problem, ContactSolution& solution) {
  stages_.double_support = false;
  if (!detail::prepare(problem, solution)) return;
  ContactStatus status;
  if (problem.feet[0].in_contact && problem.feet[1].in_contact) {
    status = solve_double(problem, solution);
  } else {
    status = solve_single(problem, problem.feet[0].in_contact ? 0 : 1, solution);
  }
  detail::finish(problem, status, solution);
}

ContactStatus SequentialOptimizer::solve_single(const ContactProblem& p, int i,
                                                ContactSolution& solution) {
  const FootContact& foot = p.feet[i];
  const Eigen::Matrix3d& R = foot.R_WF;
  const double h = foot.ankle_height;
  const Eigen::Vector4d region = safe_region(foot);

  // (12): the force that produces l_dot_d, in the foot frame.
  Eigen::Vector3d f_F = R.transpose() * (p.l_dot_desired - p.mass * p.gravity);
  // A force the foot cannot give at all (inside the polar cone, e.g. any pull) projects to zero:
  // no force, CoP at the centre of the safe region; finish() reports kCompromised.
  // Friction cone: the closest admissible force (Euclidean projection onto |f_t| <= mu f_n),
  // which keeps the most of l_dot_d. Scaling the tangential part alone, as (12) reads, is not
  // the closest point when the cone is narrow or the force points sideways.
  f_F = project_on_friction_cone(f_F, foot.mu);
  const double f_n = f_F.z();
  if (!(f_n > unloaded_threshold(p))) {
    solution.feet[i] =
        make_foot_wrench(foot, Eigen::Vector3d::Zero(), 0.5 * (region[0] + region[1]),
                         0.5 * (region[2] + region[3]), 0.0);
    return ContactStatus::kOk;
  }
  const Eigen::Vector3d f_W = R * f_F;
  // (13)-(14) generalised: CoP from the ankle torque needed for k_dot_d.
  const Eigen::Vector3d tau_F = R.transpose() * (p.k_dot_desired - (foot.p_WF - p.com).cross(f_W));
  const double d_x = std::clamp((-tau_F.y() - h * f_F.x()) / f_n, region[0], region[1]);
  const double d_y = std::clamp((tau_F.x() - h * f_F.y()) / f_n, region[2], region[3]);
  const double tau_n_max = torsion_limit(foot, f_F, p.weights.torsion);
  const double tau_n =
      std::clamp(tau_F.z() - (d_x * f_F.y() - d_y * f_F.x()), -tau_n_max, tau_n_max);
  solution.feet[i] = make_foot_wrench(foot, f_W, d_x, d_y, tau_n);
  return ContactStatus::kOk;
}

// Phi = [B; se_f I] with B the 6 x 8 force / moment block, xi = [xi_6; 0]: the normal equations are
// B^T B + eps_f I and B^T xi_6, formed from the small block alone (the dense NNLS would multiply
// the 8 regularisation rows too).
SolverStatus SequentialOptimizer::solve_force_stage() {
  SequentialStages& st = stages_;
  if (use_normal_equations_) {
    const auto B = st.Phi.topRows<6>();
    nnls_H_.noalias() = B.transpose().lazyProduct(B);
    nnls_H_.diagonal() += st.Phi.bottomRows<8>().diagonal().cwiseAbs2();
    nnls_c_.noalias() = B.transpose() * st.xi.head<6>();
    const SolverStatus s = nnls_.solve_normal(nnls_H_, nnls_c_, st.xi.head<6>().norm(), st.rho);
    if (s != SolverStatus::kNotPositiveDefinite) return s;
  }
  return nnls_.solve(st.Phi, st.xi, st.rho);
}

// Psi = [P; se_c I] with P the 3 x 6 torque block, kappa = [kappa_k; se_c eta_d].
SolverStatus SequentialOptimizer::solve_cop_stage() {
  SequentialStages& st = stages_;
  if (use_normal_equations_) {
    const auto P = st.Psi.topRows<3>();
    const auto D = st.Psi.bottomRows<6>().diagonal();
    bvls_H_.noalias() = P.transpose().lazyProduct(P);
    bvls_H_.diagonal() += D.cwiseAbs2();
    bvls_c_.noalias() = P.transpose() * st.kappa.head<3>();
    bvls_c_ += D.cwiseProduct(st.kappa.tail<6>());
    const SolverStatus s =
        bvls_.solve_normal(bvls_H_, bvls_c_, st.kappa.norm(), st.eta_lower, st.eta_upper, st.eta);
    if (s != SolverStatus::kNotPositiveDefinite) return s;
  }
  return bvls_.solve(st.Psi, st.kappa, st.eta_lower, st.eta_upper, st.eta);
}

ContactStatus SequentialOptimizer::solve_double(const ContactProblem& p,
                                                ContactSolution& solution) {
  SequentialStages& st = stages_;
  st.double_support = true;
  const double sw_k = std::sqrt(p.weights.w_k * p.weights.scale());
  const double se_f = std::sqrt(p.weights.eps_f * p.weights.scale());
  const double se_c = std::sqrt(p.weights.eps_cop);

  // ---- (21)-(26): foot GRFs by NNLS over rho.
  // Every entry of Phi's top 6 rows and of Psi's top 3 rows is written below; their lower blocks
  // are diagonal (set below) and their off-diagonal zeros come from SequentialStages' initialiser.
  for (int i = 0; i < 2; ++i) {
    const FootContact& foot = p.feet[i];
    const Eigen::Matrix<double, 3, 4> beta = friction_basis_W(foot);
    st.Phi.block<3, 4>(0, 4 * i) = beta;
    st.Phi.block<3, 4>(3, 4 * i).noalias() =
        sw_k * detail::skew(foot.p_WF - p.com) * beta;  // delta_i
  }
  st.Phi.block<8, 8>(6, 0).diagonal().setConstant(se_f);
  st.xi.segment<3>(0) = p.l_dot_desired - p.mass * p.gravity;
  st.xi.segment<3>(3) = sw_k * p.k_dot_desired;
  st.xi.segment<8>(6).setZero();
  st.nnls_status = solve_force_stage();
  if (st.nnls_status == SolverStatus::kInvalidInput) return ContactStatus::kSolverFailure;

  // ---- (27)-(30): CoPs and normal torques by BVLS over eta.
  Eigen::Vector3d f_W[2];
  Eigen::Vector3d f_F[2];
  Eigen::Vector3d k_dot_f = Eigen::Vector3d::Zero();
  for (int i = 0; i < 2; ++i) {
    const FootContact& foot = p.feet[i];
    f_W[i].noalias() = st.Phi.block<3, 4>(0, 4 * i) * st.rho.segment<4>(4 * i);
    f_F[i].noalias() = foot.R_WF.transpose() * f_W[i];
    k_dot_f += (foot.p_WF - p.com).cross(f_W[i]);
  }
  Eigen::Vector3d kappa_k = p.k_dot_desired - k_dot_f;  // k_dot_tau,d
  const double threshold = unloaded_threshold(p);
  for (int i = 0; i < 2; ++i) {
    const FootContact& foot = p.feet[i];
    const Eigen::Matrix3d& R = foot.R_WF;
    const Eigen::Vector3d& f = f_F[i];
    const double h = foot.ankle_height;
    st.Psi.col(3 * i + 0).head<3>() = -R.col(1) * f.z() + R.col(2) * f.y();
    st.Psi.col(3 * i + 1).head<3>() = R.col(0) * f.z() - R.col(2) * f.x();
    st.Psi.col(3 * i + 2).head<3>() = R.col(2);
    kappa_k += h * (R.col(1) * f.x() - R.col(0) * f.y());
    const Eigen::Vector4d region = safe_region(foot);
    const double f_n = std::max(f.z(), 0.0);
    const double tau_n_max = torsion_limit(foot, f, p.weights.torsion);
    st.eta_lower.segment<3>(3 * i) << region[0], region[2], -tau_n_max;
    st.eta_upper.segment<3>(3 * i) << region[1], region[3], tau_n_max;
    if (f_n > threshold) {
      st.eta_desired.segment<3>(3 * i) << -h * f.x() / f_n, -h * f.y() / f_n, 0.0;
    } else {
      st.eta_desired.segment<3>(3 * i) << 0.5 * (region[0] + region[1]),
          0.5 * (region[2] + region[3]), 0.0;
    }
  }
  st.Psi.block<6, 6>(3, 0).diagonal().setConstant(se_c);
  st.kappa.head<3>() = kappa_k;
  st.kappa.tail<6>() = se_c * st.eta_desired;
  st.bvls_status = solve_cop_stage();
  if (st.bvls_status == SolverStatus::kInvalidInput) return ContactStatus::kSolverFailure;

  for (int i = 0; i < 2; ++i) {
    solution.feet[i] =
        make_foot_wrench(p.feet[i], f_W[i], st.eta[3 * i], st.eta[3 * i + 1], st.eta[3 * i + 2]);
  }
  if (st.nnls_status == SolverStatus::kIterationLimit ||
      st.bvls_status == SolverStatus::kIterationLimit) {
    return ContactStatus::kIterationLimit;
  }
  return ContactStatus::kOk;
}

}  // namespace poise::contact
