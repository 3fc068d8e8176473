#pragma once

// The paper's contact-force optimiser (Lee & Goswami, Sec. 3.3-3.4).
//
// Single support (one foot in contact), eqs. (12)-(14) generalised to any foot orientation, linear
// momentum first (Fig. 3 left):
//   f = l_dot_d - m g. In the foot frame F, f is replaced by its Euclidean projection onto the
//   friction cone |f_t| <= mu f_n (project_on_friction_cone): the closest admissible force, so the
//   linear rate is the best one this foot can give (zero when f points into the polar cone, e.g.
//   a pull).
//   The ankle torque needed for k_dot_d, tau = k_dot_d - (r - r_G) x f, fixes the CoP in the sole
//   plane, (d_x, d_y) = ((-tau_y - h f_x) / f_n, (tau_x - h f_y) / f_n) in F; the CoP is moved to
//   the nearest point of the safe rectangle (the force is kept); the normal torque is the residual
//   about the normal, tau_n = tau_z - (d_x f_y - d_y f_x), clamped to +-mu_torsion f_n.
//
// Double support, two bounded least-squares problems:
//   (21)-(26) NNLS over the 8 friction-pyramid magnitudes rho:
//     min |l_dot_d - m g - sum f_i|^2 + s w_k |k_dot_d - k_dot_f|^2 + s eps_f |rho|^2, rho >= 0,
//     s = ContactWeights::scale(): 1 for Priority::kWeighted (the paper's (21) as written),
//     kLexicographicScale for Priority::kLexicographic (linear first strictly: the penalty form
//     of the two-stage problem "best linear rate, then best angular rate given it"),
//     f_i = beta_i rho_i, k_dot_f = sum (r_i - r_G) x f_i. Rows scaled by sqrt(w_k), sqrt(eps_f).
//     Note: (21) writes eps_f |f|^2; (24) regularises rho, which is what is implemented (it keeps
//     Phi of full column rank, so the solution is unique).
//   (27)-(30) BVLS over eta = (d_x, d_y, tau_n) per foot:
//     min |Psi_k eta - kappa_k|^2 + eps_cop |eta - eta_d|^2, bounds: the safe rectangle and
//     |tau_n| <= mu_torsion f_n, with (derived from (27), replacing the garbled footnote 5):
//       Psi_k columns of foot i:  d_x: -R_i^1 f_z + R_i^2 f_y,  d_y: R_i^0 f_z - R_i^2 f_x,
//                                 tau_n: R_i^2          (R_i^j = column j, f = R_i^T f_i)
//       kappa_k = k_dot_d - k_dot_f + sum_i h_i (R_i^1 f_x - R_i^0 f_y)
//     and eta_d the zero-ankle-torque point (-h f_x / f_z, -h f_y / f_z, 0).
//
// Friction pyramid: 4 unit vectors per foot, (+-mu, 0, 1) and (0, +-mu, 1) normalised, in F. Its
// edges lie on the cone |f_t| <= mu f_n, so the pyramid |f_x| + |f_y| <= mu f_n is INSCRIBED: every
// double-support force lies inside the true friction cone.

#include <Eigen/Core>

#include "poise/contact/bvls.hpp"
#include "poise/contact/contact_problem.hpp"
#include "poise/contact/nnls.hpp"

namespace poise::contact {

/// Euclidean projection of a force given in the foot frame (z = sole normal) onto the friction
/// cone |f_t| <= mu f_n: f itself inside, zero inside the polar cone, else the nearest point of the
/// cone's surface.
Eigen::Vector3d project_on_friction_cone(const Eigen::Vector3d& f_F, double mu);

/// Intermediate data of the last double-support solve (for tests and the stage benchmark).
struct SequentialStages {
  Eigen::Matrix<double, 14, 8> Phi = Eigen::Matrix<double, 14, 8>::Zero();  ///< eq. (24)
  Eigen::Matrix<double, 14, 1> xi = Eigen::Matrix<double, 14, 1>::Zero();
  Eigen::Matrix<double, 8, 1> rho = Eigen::Matrix<double, 8, 1>::Zero();  ///< eq. (25)
  Eigen::Matrix<double, 9, 6> Psi = Eigen::Matrix<double, 9, 6>::Zero();  ///< eq. (29)
  Eigen::Matrix<double, 9, 1> kappa = Eigen::Matrix<double, 9, 1>::Zero();
  Eigen::Matrix<double, 6, 1> eta_lower = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 1> eta_upper = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 1> eta_desired = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 1> eta = Eigen::Matrix<double, 6, 1>::Zero();  ///< eq. (30)
  SolverStatus nnls_status = SolverStatus::kOptimal;
  SolverStatus bvls_status = SolverStatus::kOptimal;
  bool double_support = false;  ///< false: the last solve was single support (or no solve)
};

/// The paper's sequential method. Construct once (allocates); solve() never allocates, never
/// throws, and never outputs a non-finite number (see ContactStatus for the safe answers).
class SequentialOptimizer {
 public:
  SequentialOptimizer();

  /// Solves one problem. On invalid input: status kInvalidInput and every output zero.
  void solve(const ContactProblem& problem, ContactSolution& solution);

  const SequentialStages& stages() const { return stages_; }
  Nnls& nnls() { return nnls_; }
  Bvls& bvls() { return bvls_; }

  /// How the two stages call their solvers. true (default): on the normal equations formed from
  /// the structure of Phi and Psi (their lower blocks are diagonal), Nnls/Bvls::solve_normal(),
  /// with the dense form as the fallback when a sub-problem is ill-conditioned. false: always the
  /// dense form, Nnls/Bvls::solve(Phi, xi) (the method before the normal-equation shortcut; kept
  /// for the benchmark's same-run comparison). Both give the same answer to round-off.
  void set_use_normal_equations(bool on) { use_normal_equations_ = on; }
  bool use_normal_equations() const { return use_normal_equations_; }

  /// The two double-support stages on their own, as solve() runs them, on the data in stages()
  /// (Phi, xi -> rho; Psi, kappa, bounds -> eta) as the last double-support solve() left it. For
  /// the stage benchmark; solve() is the only entry point a user needs.
  SolverStatus solve_force_stage();
  SolverStatus solve_cop_stage();

 private:
  ContactStatus solve_single(const ContactProblem& problem, int foot, ContactSolution& solution);
  ContactStatus solve_double(const ContactProblem& problem, ContactSolution& solution);

  Nnls nnls_;
  Bvls bvls_;
  SequentialStages stages_;
  bool use_normal_equations_ = true;
  Eigen::Matrix<double, 8, 8> nnls_H_;  // Phi^T Phi
  Eigen::Matrix<double, 8, 1> nnls_c_;  // Phi^T xi
  Eigen::Matrix<double, 6, 6> bvls_H_;  // Psi^T Psi
  Eigen::Matrix<double, 6, 1> bvls_c_;  // Psi^T kappa
};

}  // namespace poise::contact
