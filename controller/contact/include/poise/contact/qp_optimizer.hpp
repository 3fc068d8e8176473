#pragma once

// The contact problem as ONE strictly convex QP, solved by the Goldfarb-Idnani dual active-set
// method (the paper's baseline, Sec. 4.3). A swap-in for SequentialOptimizer and a reference to
// compare it against.
//
// Variables, per foot in contact (7 per foot, 14 at most): the 4 friction-pyramid magnitudes rho
//   (the sequential method's basis, so the friction model and the force regularisation are the
//   same) and m, the moment about the sole point o = (0, 0, -h) below the ankle, in F.
// Objective (the sequential method's weights; eq. (20) with w_l = 1, w_tau = eps_tau):
//   J_qp = |l_dot_d - l_dot|^2 + w_k |k_dot_d - k_dot|^2 + eps_f |rho|^2 + eps_tau sum |tau_i|^2
//   with tau_i = R_i (m_i + o_i x f_i) the ankle torque; see qp_objective().
// Constraints per foot (10): rho >= 0 (the inscribed pyramid, hence f_z >= 0), CoP in the safe
//   rectangle (d_x = -m_y / f_z, d_y = m_x / f_z; 4 rows linear in (f_z, m)), torsion
//   |m_z| <= mu_torsion f_z (2 rows).
//
// Modelling difference (stated, not hidden): the paper bounds the normal torque about the CoP,
// tau_n = m_z - (d_x f_y - d_y f_x), which is bilinear in the wrench; a QP can only bound m_z, the
// normal torque about the point below the ankle. After the solve, the answer is made admissible
// in the paper's sense: tau_n is clamped to +-mu_torsion f_z (and round-off outside the pyramid or
// the rectangle is removed); the admissible rate is then recomputed from the final wrench.
// adjusted() says whether that clean-up changed the wrench by more than round-off.
// Optional refinement (set_torsion_passes(2)): a second QP in which each torsion row bounds the
// normal torque about the first pass's CoP d*, |m_z - (d*_x f_y - d*_y f_x)| <= mu_torsion f_z
// (linear for fixed d*), which makes the clean-up much smaller at twice the cost. Default: 1 pass,
// the plain one-QP baseline of the paper.
// TorsionLimit::kFrictionCoupled (weights.torsion): the clean-up clamps tau_n to
// mu_torsion (f_z - |f_t| / mu) instead; the refinement pass bounds it by that limit linearised
// at the first pass's tangential direction u, mu_torsion (f_z - u . f_t / mu) (exact along u).
// The first pass bounds m_z as above.

#include <Eigen/Core>

#include "poise/contact/contact_problem.hpp"
#include "poise/contact/dual_qp.hpp"

namespace poise::contact {

/// One-QP contact optimiser. Construct once (allocates); solve() never allocates, never throws,
/// never outputs a non-finite number.
class QpOptimizer {
 public:
  static constexpr int kVarsPerFoot = 7;
  static constexpr int kConstraintsPerFoot = 10;
  static constexpr int kMaxVars = kVarsPerFoot * kMaxFeet;
  static constexpr int kMaxConstraints = kConstraintsPerFoot * kMaxFeet;
  static constexpr int kResidualRows = 6 + 7 * kMaxFeet;

  QpOptimizer();

  /// 1 (default): one QP. 2: one refinement QP with the torsion rows linearised at the CoPs of
  /// the first. Values outside [1, 2] are clamped.
  void set_torsion_passes(int passes) { passes_ = passes < 1 ? 1 : (passes > 2 ? 2 : passes); }
  int torsion_passes() const { return passes_; }

  void solve(const ContactProblem& problem, ContactSolution& solution);

  /// J_qp at the raw QP optimum of the last solve (before the admissibility clean-up).
  double raw_objective() const { return raw_objective_; }
  /// True when the last clean-up changed the QP's wrench by more than round-off.
  bool adjusted() const { return adjusted_; }
  SolverStatus qp_status() const { return qp_status_; }
  /// Pyramid magnitudes of the last QP answer, 4 per foot (foot i at 4 i), zero for feet not in
  /// contact; with the wrenches of the solution, the arguments of qp_objective().
  const Eigen::Matrix<double, 4 * kMaxFeet, 1>& rho() const { return rho_; }
  DualQp& qp() { return qp_; }

  /// QP data of the last solve, for the stage benchmark: n = 7 * feet in contact variables,
  /// 10 * feet inequality rows; G = M^T M (+ a 1e-10 relative ridge), g = -M^T c.
  int num_vars() const { return n_; }
  const Eigen::Matrix<double, kMaxVars, kMaxVars>& hessian() const { return G_; }
  const Eigen::Matrix<double, kMaxVars, 1>& gradient() const { return g_; }
  const Eigen::Matrix<double, kMaxConstraints, kMaxVars>& inequality_matrix() const { return A_; }
  const Eigen::Matrix<double, kMaxConstraints, 1>& inequality_bounds() const { return b_; }

 private:
  void add_foot_rows(const ContactProblem& p, const FootContact& foot, int s, double sw_k,
                     double se_f, double se_t);
  void refine_torsion_rows(const ContactProblem& p, const FootContact& foot, int s);
  FootWrench admissible_wrench(const ContactProblem& p, const FootContact& foot, int s, int slot);

  DualQp qp_;
  int n_ = 0;
  Eigen::Matrix<double, kResidualRows, kMaxVars> M_;
  Eigen::Matrix<double, kResidualRows, 1> c_;
  Eigen::Matrix<double, kMaxVars, kMaxVars> G_;
  Eigen::Matrix<double, kMaxVars, 1> g_;
  Eigen::Matrix<double, kMaxConstraints, kMaxVars> A_;
  Eigen::Matrix<double, kMaxConstraints, 1> b_;
  Eigen::Matrix<double, kMaxVars, 1> y_;
  Eigen::Matrix<double, kMaxVars, 1> y_first_;
  Eigen::Matrix<double, 4 * kMaxFeet, 1> rho_;
  double raw_objective_ = 0.0;
  bool adjusted_ = false;
  int passes_ = 1;
  SolverStatus qp_status_ = SolverStatus::kOptimal;
};

}  // namespace poise::contact
