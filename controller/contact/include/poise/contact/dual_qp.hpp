#pragma once

#include <Eigen/Core>

#include "poise/contact/solver_status.hpp"

namespace poise::contact {

/// Strictly convex quadratic program
///   min 0.5 x^T G x + g^T x   s.t.   A_eq x = b_eq,   A_in x >= b_in
/// by the dual active-set method of Goldfarb and Idnani ("A numerically stable dual method for
/// solving strictly convex quadratic programs", Math. Programming 27, 1983): start from the
/// unconstrained minimum, add the most violated constraint, drop constraints whose multiplier would
/// turn negative. G must be symmetric positive definite (only its lower triangle is read).
///
/// Usage: construct (or resize()) once with the largest sizes; solve() then never allocates.
/// The iterates are dual feasible but primal infeasible until the end: on kIterationLimit the
/// output x may violate constraints (the caller must make it safe). Not thread-safe.
class DualQp {
 public:
  DualQp() = default;
  /// Throws std::invalid_argument if max_vars <= 0 or a count is negative.
  DualQp(int max_vars, int max_eq, int max_ineq) { resize(max_vars, max_eq, max_ineq); }
  void resize(int max_vars, int max_eq, int max_ineq);

  /// Cap on the number of steps (each adds or drops one constraint). Default 4 * (n + m) + 20.
  void set_max_iterations(int n) { max_iterations_ = n; }

  /// G: n x n, g: n, A_eq: m_eq x n, b_eq: m_eq, A_in: m_in x n, b_in: m_in, x: n (output).
  /// Pass 0-row matrices for absent constraint kinds.
  /// Failure results: kInvalidInput (sizes, non-finite), kNotPositiveDefinite (Cholesky of G
  /// failed), kInfeasible (no point satisfies the constraints, or dependent equalities),
  /// kIterationLimit. On any failure x holds the last iterate (zero on kInvalidInput).
  SolverStatus solve(const Eigen::Ref<const Eigen::MatrixXd>& G,
                     const Eigen::Ref<const Eigen::VectorXd>& g,
                     const Eigen::Ref<const Eigen::MatrixXd>& A_eq,
                     const Eigen::Ref<const Eigen::VectorXd>& b_eq,
                     const Eigen::Ref<const Eigen::MatrixXd>& A_in,
                     const Eigen::Ref<const Eigen::VectorXd>& b_in, Eigen::Ref<Eigen::VectorXd> x);

  /// Multipliers of the last solve: lambda_eq (m_eq entries), u_in (m_in entries, >= 0, zero for
  /// inactive constraints), such that G x + g = A_eq^T lambda_eq + A_in^T u_in at the optimum.
  const Eigen::VectorXd& multipliers_eq() const { return lambda_eq_; }
  const Eigen::VectorXd& multipliers_in() const { return u_in_; }
  /// Objective 0.5 x^T G x + g^T x at the returned x.
  double objective() const { return objective_; }
  int iterations() const { return iterations_; }
  /// Number of constraints (equalities included) in the final active set.
  int active_set_size() const { return q_; }

 private:
  void add_to_active_set(int n);  // uses d_; q_ += 1
  void drop_from_active_set(int n, int k);
  bool factor(const Eigen::Ref<const Eigen::MatrixXd>& G);
  void unconstrained_minimum(const Eigen::Ref<const Eigen::VectorXd>& g,
                             Eigen::Ref<Eigen::VectorXd> x);
  void compute_directions(int n);
  double dot_np(const Eigen::Ref<const Eigen::VectorXd>& v, int n) const;
  SolverStatus add_equalities(const Eigen::Ref<const Eigen::MatrixXd>& A_eq,
                              const Eigen::Ref<const Eigen::VectorXd>& b_eq,
                              Eigen::Ref<Eigen::VectorXd> x);
  int most_violated(const Eigen::Ref<const Eigen::MatrixXd>& A_in,
                    const Eigen::Ref<const Eigen::VectorXd>& b_in,
                    const Eigen::Ref<const Eigen::VectorXd>& x) const;
  SolverStatus add_inequality(int p, double b_p, Eigen::Ref<Eigen::VectorXd> x);
  void store_multipliers();
  double objective_at(const Eigen::Ref<const Eigen::MatrixXd>& G,
                      const Eigen::Ref<const Eigen::VectorXd>& g,
                      const Eigen::Ref<const Eigen::VectorXd>& x) const;

  int max_vars_ = 0;
  int max_eq_ = 0;
  int max_ineq_ = 0;
  int max_iterations_ = 0;
  int iterations_ = 0;
  int q_ = 0;
  double objective_ = 0.0;
  Eigen::MatrixXd L_;  // Cholesky factor of G
  Eigen::MatrixXd J_;  // L^{-T}, then rotated: J^T G J = I
  Eigen::MatrixXd R_;  // upper triangular, q x q used
  Eigen::VectorXd d_, z_, r_, u_, np_;
  Eigen::VectorXi active_;  // >= 0: inequality index; < 0: equality -(index + 1)
  Eigen::VectorXd lambda_eq_, u_in_;
  Eigen::VectorXi is_active_;
};

}  // namespace poise::contact
