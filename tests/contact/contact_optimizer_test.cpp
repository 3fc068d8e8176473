// Physical checks of both contact optimisers: admissibility of every result, exact reproduction of
// feasible desired rates, the derived Psi_k / kappa_k against eq. (27), stage optimality against
// the directly evaluated objectives (21) and (29), non-level feet, degenerate cases, bad input.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "contact_fixtures.hpp"
#include "poise/contact/contact_optimizer.hpp"

namespace poise::contact {
namespace {

using test::random_arbitrary;
using test::random_feasible;
using test::random_geometry;
using test::rpy;
using test::uniform;

// Independent admissibility check in the paper's model: unilateral, friction cone (and the
// inscribed pyramid when `pyramid`), CoP inside the safe region and on the sole plane, torsion
// bound; and the momentum identities (1)-(2) evaluated with the world CoP.
void expect_admissible(const ContactProblem& p, const ContactSolution& s, bool pyramid,
                       const char* what) {
  const double mg = p.mass * std::max(p.gravity.norm(), 1.0);
  const double tol = 1e-9 * mg;
  Eigen::Vector3d l = p.mass * p.gravity;
  Eigen::Vector3d k = Eigen::Vector3d::Zero();
  for (int i = 0; i < kMaxFeet; ++i) {
    const FootContact& foot = p.feet[i];
    const FootWrench& w = s.feet[i];
    if (!foot.in_contact) {
      EXPECT_TRUE(w.force_W.isZero()) << what;
      continue;
    }
    const Eigen::Vector3d f = foot.R_WF.transpose() * w.force_W;
    EXPECT_GE(f.z(), -tol) << what << " foot " << i << ": pulls on the ground";
    EXPECT_LE(std::hypot(f.x(), f.y()), foot.mu * f.z() + tol) << what << " foot " << i;
    if (pyramid) {
      EXPECT_LE(std::abs(f.x()) + std::abs(f.y()), foot.mu * f.z() + tol) << what;
    }
    const Eigen::Vector4d r = safe_region(foot);
    if (f.z() > tol) {
      EXPECT_GE(w.cop_F.x(), r[0] - 1e-12) << what;
      EXPECT_LE(w.cop_F.x(), r[1] + 1e-12) << what;
      EXPECT_GE(w.cop_F.y(), r[2] - 1e-12) << what;
      EXPECT_LE(w.cop_F.y(), r[3] + 1e-12) << what;
    }
    const Eigen::Vector3d cop_F = foot.R_WF.transpose() * (w.cop_W - foot.p_WF);
    EXPECT_NEAR(cop_F.z(), -foot.ankle_height, 1e-12) << what << ": CoP off the sole plane";
    EXPECT_NEAR(cop_F.x(), w.cop_F.x(), 1e-12);
    EXPECT_NEAR(cop_F.y(), w.cop_F.y(), 1e-12);
    EXPECT_LE(std::abs(w.normal_torque), foot.mu_torsion * std::max(f.z(), 0.0) + tol) << what;
    // (1): moment about the CoM from the CoP, the force and the normal torque.
    l += w.force_W;
    k += (w.cop_W - p.com).cross(w.force_W) + w.normal_torque * foot.R_WF.col(2);
  }
  EXPECT_LT((l - s.l_dot_admissible).norm(), tol) << what;
  EXPECT_LT((k - s.k_dot_admissible).norm(), tol) << what;
}

ContactSolution solve(Method m, const ContactProblem& p) {
  ContactOptimizer opt(m);
  ContactSolution s;
  opt.solve(p, s);
  return s;
}

double rate_error(const ContactProblem& p, const ContactSolution& s) {
  return std::sqrt((p.l_dot_desired - s.l_dot_admissible).squaredNorm() +
                   (p.k_dot_desired - s.k_dot_admissible).squaredNorm());
}

TEST(ContactOptimizer, EveryResultIsAdmissible) {
  std::mt19937 rng(1);
  SequentialOptimizer seq;
  QpOptimizer qp, qp2;
  qp2.set_torsion_passes(2);
  for (int trial = 0; trial < 600; ++trial) {
    const bool right = trial % 3 != 1, left = trial % 3 != 2;
    const ContactProblem p =
        trial % 2 ? random_feasible(rng, right, left) : random_arbitrary(rng, right, left);
    ContactSolution s;
    seq.solve(p, s);
    ASSERT_TRUE(s.status == ContactStatus::kOk || s.status == ContactStatus::kCompromised)
        << to_string(s.status);
    expect_admissible(p, s, right && left, "sequential");
    qp.solve(p, s);
    ASSERT_TRUE(s.status == ContactStatus::kOk || s.status == ContactStatus::kCompromised)
        << to_string(s.status);
    expect_admissible(p, s, true, "qp");
    qp2.solve(p, s);
    ASSERT_TRUE(s.status == ContactStatus::kOk || s.status == ContactStatus::kCompromised)
        << to_string(s.status);
    expect_admissible(p, s, true, "qp, 2 passes");
  }
}

TEST(QpOptimizer, TorsionRefinementReducesTheCleanUp) {
  // The second pass bounds the normal torque about the first pass's CoP, so the answer needs the
  // torsion clean-up less often, and its tracking cost is no worse on average.
  std::mt19937 rng(15);
  QpOptimizer one, two;
  two.set_torsion_passes(2);
  int adjusted_one = 0, adjusted_two = 0;
  double cost_one = 0.0, cost_two = 0.0;
  for (int trial = 0; trial < 300; ++trial) {
    const ContactProblem p = trial % 2 ? random_feasible(rng, true, trial % 3 != 0)
                                       : random_arbitrary(rng, true, trial % 3 != 0);
    ContactSolution a, b;
    one.solve(p, a);
    two.solve(p, b);
    adjusted_one += one.adjusted();
    adjusted_two += two.adjusted();
    const double mg2 = std::pow(p.mass * 9.81, 2);
    cost_one += tracking_cost(p, a) / mg2;
    cost_two += tracking_cost(p, b) / mg2;
  }
  std::printf("torsion clean-up needed: 1 pass %d / 300, 2 passes %d / 300\n", adjusted_one,
              adjusted_two);
  EXPECT_LT(adjusted_two, adjusted_one);
  EXPECT_LE(cost_two, cost_one * 1.01);
}

TEST(ContactOptimizer, SingleSupportReproducesFeasibleRateExactly) {
  std::mt19937 rng(2);
  for (int trial = 0; trial < 200; ++trial) {
    const ContactProblem p = random_feasible(rng, trial % 2 == 0, trial % 2 == 1);
    const ContactSolution s = solve(Method::kSequential, p);
    EXPECT_EQ(s.status, ContactStatus::kOk);
    EXPECT_LT(rate_error(p, s), 1e-9 * p.mass * 9.81) << "trial " << trial;
  }
}

TEST(ContactOptimizer, SingleSupportKeepsLinearMomentumWhenCopLeavesTheSole) {
  // Fig. 3 left: a CoP outside the sole is moved to the edge; l_dot_d is kept exactly.
  std::mt19937 rng(3);
  for (int trial = 0; trial < 100; ++trial) {
    ContactProblem p = random_feasible(rng, true, false);
    p.k_dot_desired += Eigen::Vector3d(0.0, 5000.0, 0.0);  // pitch far beyond the sole
    const ContactSolution s = solve(Method::kSequential, p);
    EXPECT_EQ(s.status, ContactStatus::kCompromised);
    EXPECT_LT((s.l_dot_admissible - p.l_dot_desired).norm(), 1e-9 * p.mass * 9.81);
    const Eigen::Vector4d r = safe_region(p.feet[0]);
    EXPECT_TRUE(s.feet[0].cop_F.x() == r[0] || s.feet[0].cop_F.x() == r[1]);
  }
}

// True when the wrench also satisfies the QP's torsion model |m_z| <= mu_torsion f_z, m_z being
// the normal moment about the sole point below the ankle.
bool in_qp_torsion_model(const FootContact& foot, const FootWrench& w) {
  const Eigen::Vector3d f = foot.R_WF.transpose() * w.force_W;
  const double m_z = w.normal_torque + w.cop_F.x() * f.y() - w.cop_F.y() * f.x();
  return std::abs(m_z) <= foot.mu_torsion * f.z();
}

TEST(ContactOptimizer, QpReproducesFeasibleRateWithSmallRegularisation) {
  // Feasible in the paper's model AND in the QP's torsion model: the QP optimum reproduces the
  // rate (raw objective ~ 0). The final answer equals it unless the clean-up had to clamp tau_n
  // into the paper's torsion bound (the QP picked, among near-optimal wrenches, one whose normal
  // torque about the CoP is too large): then only the yaw part may differ.
  std::mt19937 rng(4);
  QpOptimizer qp;
  int checked = 0, exact = 0;
  for (int trial = 0; trial < 600; ++trial) {
    FootWrench w[kMaxFeet];
    ContactProblem p = random_feasible(rng, trial % 3 != 1, trial % 3 != 2, w);
    bool comparable = true;
    for (int i = 0; i < kMaxFeet; ++i)
      comparable = comparable && (!p.feet[i].in_contact || in_qp_torsion_model(p.feet[i], w[i]));
    if (!comparable) continue;
    ++checked;
    p.weights.priority = Priority::kWeighted;  // tiny eps: the weighted objective itself
    p.weights.eps_f = 1e-10;
    p.weights.eps_tau = 1e-12;
    ContactSolution s;
    qp.solve(p, s);
    const double mg = p.mass * 9.81;
    // J_qp(optimum) <= J_qp(truth) = regularisation of the true wrenches (zero tracking error).
    double j_truth = 0.0;
    for (int i = 0; i < kMaxFeet; ++i) {
      if (!p.feet[i].in_contact) continue;
      const Eigen::Vector4d rho = test::pyramid_decomposition(p.feet[i], w[i].force_W);
      ASSERT_LT((friction_basis_W(p.feet[i]) * rho - w[i].force_W).norm(), 1e-9 * mg);
      j_truth += p.weights.eps_f * rho.squaredNorm() +
                 p.weights.eps_tau * w[i].torque_ankle_W.squaredNorm();
    }
    EXPECT_LE(qp.raw_objective(), j_truth * (1.0 + 1e-6) + 1e-9) << "trial " << trial;
    EXPECT_LT((s.l_dot_admissible - p.l_dot_desired).norm(), 1e-6 * mg) << "trial " << trial;
    if (!qp.adjusted()) {
      ++exact;
      EXPECT_LT(rate_error(p, s), 1e-6 * mg) << "trial " << trial;
    }
  }
  EXPECT_GT(checked, 100);
  EXPECT_GT(exact, 0);
  std::printf("QP: %d of %d feasible problems reproduced without torsion clean-up\n", exact,
              checked);
}

TEST(ContactOptimizer, SequentialReproducesFeasibleRateWhenAnkleTorquesCanBeZero) {
  // Double support, desired rate from forces whose lines of action pass through the ankles (zero
  // ankle torque) with the zero-torque CoP inside the sole: NNLS can match l_dot_d and k_dot_d with
  // forces alone, and the CoP stage then has nothing left to do.
  std::mt19937 rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    ContactProblem p = random_geometry(rng, true, true);
    for (FootContact& f : p.feet) {
      f.sole = {-0.1, 0.15, -0.06, 0.06};
      f.safety_margin = 0.0;
      f.ankle_height = 0.05;  // |zero-torque CoP| <= h mu <= 0.05
    }
    FootWrench w[kMaxFeet];
    for (int i = 0; i < kMaxFeet; ++i) {
      const FootContact& foot = p.feet[i];
      const double f_n = uniform(rng, 0.3, 0.7) * p.mass * 9.81;
      const Eigen::Vector3d f_F(uniform(rng, -0.4, 0.4) * foot.mu * f_n,
                                uniform(rng, -0.4, 0.4) * foot.mu * f_n, f_n);
      w[i] = make_foot_wrench(foot, foot.R_WF * f_F, -foot.ankle_height * f_F.x() / f_n,
                              -foot.ankle_height * f_F.y() / f_n, 0.0);
      EXPECT_LT(w[i].torque_ankle_W.norm(), 1e-9 * f_n);
    }
    test::set_desired_from_wrenches(p, w);
    p.weights.eps_f = 1e-12;
    p.weights.eps_cop = 1e-12;
    const ContactSolution s = solve(Method::kSequential, p);
    EXPECT_EQ(s.status, ContactStatus::kOk);
    EXPECT_LT(rate_error(p, s), 1e-6 * p.mass * 9.81) << "trial " << trial;
  }
}

TEST(ContactOptimizer, PaperWeightsBiasIsBoundedByTheRegularisation) {
  // With eps_f > 0 the NNLS optimum rho* satisfies J21(rho*) <= J21(rho_true) for any feasible
  // rho_true, so the force-stage tracking error is at most eps_f |rho_true|^2. Here the true
  // wrenches have zero ankle torque, so rho_true is a decomposition of the true forces.
  std::mt19937 rng(6);
  SequentialOptimizer seq;
  for (int trial = 0; trial < 200; ++trial) {
    ContactProblem p = random_geometry(rng, true, true);
    FootWrench w[kMaxFeet];
    Eigen::Matrix<double, 8, 1> rho_true;
    for (int i = 0; i < kMaxFeet; ++i) {
      const FootContact& foot = p.feet[i];
      for (int j = 0; j < 4; ++j)
        rho_true[4 * i + j] = uniform(rng, 0.0, 0.5) * p.mass * 9.81;
      const Eigen::Vector3d f_W = friction_basis_W(foot) * rho_true.segment<4>(4 * i);
      const Eigen::Vector3d f_F = foot.R_WF.transpose() * f_W;
      w[i] = make_foot_wrench(foot, f_W, -foot.ankle_height * f_F.x() / f_F.z(),
                              -foot.ankle_height * f_F.y() / f_F.z(), 0.0);
    }
    test::set_desired_from_wrenches(p, w);
    ContactSolution s;
    seq.solve(p, s);
    const SequentialStages& st = seq.stages();
    Eigen::Vector3d f_sum = Eigen::Vector3d::Zero(), k_f = Eigen::Vector3d::Zero();
    for (int i = 0; i < kMaxFeet; ++i) {
      const Eigen::Vector3d f = s.feet[i].force_W;
      f_sum += f;
      k_f += (p.feet[i].p_WF - p.com).cross(f);
    }
    const double tracking = (p.l_dot_desired - p.mass * p.gravity - f_sum).squaredNorm() +
                            p.weights.w_k * (p.k_dot_desired - k_f).squaredNorm();
    EXPECT_LE(tracking + p.weights.eps_f * st.rho.squaredNorm(),
              p.weights.eps_f * rho_true.squaredNorm() * (1.0 + 1e-9));
  }
}

// Objective (21) evaluated directly from rho (forces, cross products), not from Phi.
double objective21(const ContactProblem& p, const Eigen::Matrix<double, 8, 1>& rho) {
  Eigen::Vector3d f_sum = Eigen::Vector3d::Zero(), k_f = Eigen::Vector3d::Zero();
  for (int i = 0; i < kMaxFeet; ++i) {
    const Eigen::Vector3d f = friction_basis_W(p.feet[i]) * rho.segment<4>(4 * i);
    f_sum += f;
    k_f += (p.feet[i].p_WF - p.com).cross(f);
  }
  return (p.l_dot_desired - p.mass * p.gravity - f_sum).squaredNorm() +
         p.weights.w_k * (p.k_dot_desired - k_f).squaredNorm() +
         p.weights.eps_f * rho.squaredNorm();
}

TEST(SequentialOptimizer, NnlsStageMinimisesObjective21) {
  std::mt19937 rng(7);
  SequentialOptimizer seq;
  for (int trial = 0; trial < 200; ++trial) {
    ContactProblem p = random_arbitrary(rng, true, true);
    p.weights.priority = Priority::kWeighted;  // (21) as the paper writes it
    ContactSolution s;
    seq.solve(p, s);
    const SequentialStages& st = seq.stages();
    const double j = objective21(p, st.rho);
    // The sqrt-weighted rows of Phi reproduce (21).
    EXPECT_NEAR((st.Phi * st.rho - st.xi).squaredNorm(), j, 1e-9 * (1.0 + j));
    // KKT of (21) with finite-difference gradients: >= 0 at rho_j = 0, = 0 where rho_j > 0.
    const double scale = p.mass * 9.81;
    for (int k = 0; k < 8; ++k) {
      const double hstep = 1e-4 * scale;
      Eigen::Matrix<double, 8, 1> up = st.rho, dn = st.rho;
      up[k] += hstep;
      dn[k] -= hstep;
      const double grad = (objective21(p, up) - objective21(p, dn)) / (2 * hstep);
      if (st.rho[k] > 1e-9 * scale) {
        EXPECT_NEAR(grad, 0.0, 1e-6 * scale) << "trial " << trial << " k " << k;
      } else {
        EXPECT_GE(grad, -1e-6 * scale) << "trial " << trial << " k " << k;
      }
    }
  }
}

TEST(SequentialOptimizer, NormalEquationStagesMatchDenseStages) {
  // The default stages (normal equations formed from the structure of Phi and Psi) and the dense
  // NNLS / BVLS calls solve the same problems: same answers to round-off, same statuses.
  std::mt19937 rng(2718);
  SequentialOptimizer fast, dense;
  dense.set_use_normal_equations(false);
  ASSERT_TRUE(fast.use_normal_equations());
  for (int trial = 0; trial < 300; ++trial) {
    ContactProblem p =
        trial % 2 ? random_feasible(rng, true, true) : random_arbitrary(rng, true, true);
    if (trial % 7 == 0) p.weights.eps_f = p.weights.eps_cop = 1e-9;  // ill-conditioned stages
    if (trial % 3 == 0) p.weights.priority = Priority::kWeighted;
    ContactSolution a, b;
    fast.solve(p, a);
    dense.solve(p, b);
    ASSERT_EQ(a.status, b.status) << "trial " << trial;
    const double mg = p.mass * 9.81;
    for (int i = 0; i < kMaxFeet; ++i) {
      EXPECT_LT((a.feet[i].force_W - b.feet[i].force_W).norm(), 1e-6 * mg) << "trial " << trial;
      EXPECT_LT((a.feet[i].torque_ankle_W - b.feet[i].torque_ankle_W).norm(), 1e-6 * mg)
          << "trial " << trial;
    }
    EXPECT_LT((fast.stages().rho - dense.stages().rho).norm(), 1e-6 * mg) << "trial " << trial;
  }
}

TEST(SequentialOptimizer, DerivedPsiAndKappaMatchEq27) {
  // Psi_k eta - kappa_k must equal sum_i tau_i(eta) - (k_dot_d - k_dot_f), with tau_i from (19)
  // evaluated directly (make_foot_wrench) for random eta.
  std::mt19937 rng(8);
  SequentialOptimizer seq;
  for (int trial = 0; trial < 200; ++trial) {
    const ContactProblem p = random_arbitrary(rng, true, true);
    ContactSolution s;
    seq.solve(p, s);
    const SequentialStages& st = seq.stages();
    Eigen::Vector3d k_f = Eigen::Vector3d::Zero();
    for (int i = 0; i < kMaxFeet; ++i)
      k_f += (p.feet[i].p_WF - p.com).cross(s.feet[i].force_W);
    for (int rep = 0; rep < 5; ++rep) {
      Eigen::Matrix<double, 6, 1> eta;
      for (int j = 0; j < 6; ++j)
        eta[j] = uniform(rng, -0.2, 0.2);
      Eigen::Vector3d tau_sum = Eigen::Vector3d::Zero();
      for (int i = 0; i < kMaxFeet; ++i) {
        tau_sum += make_foot_wrench(p.feet[i], s.feet[i].force_W, eta[3 * i], eta[3 * i + 1],
                                    eta[3 * i + 2])
                       .torque_ankle_W;
      }
      const Eigen::Vector3d lhs = st.Psi.topRows<3>() * eta - st.kappa.head<3>();
      const Eigen::Vector3d rhs = tau_sum - (p.k_dot_desired - k_f);
      EXPECT_LT((lhs - rhs).norm(), 1e-9 * (1.0 + rhs.norm())) << "trial " << trial;
    }
    // eta_d gives zero ankle torque whenever the foot is loaded.
    for (int i = 0; i < kMaxFeet; ++i) {
      const double f_n = (p.feet[i].R_WF.transpose() * s.feet[i].force_W).z();
      if (f_n < 1e-6) continue;
      const FootWrench w0 = make_foot_wrench(p.feet[i], s.feet[i].force_W, st.eta_desired[3 * i],
                                             st.eta_desired[3 * i + 1], 0.0);
      EXPECT_LT(w0.torque_ankle_W.norm(), 1e-9 * (1.0 + s.feet[i].force_W.norm()));
    }
  }
}

TEST(SequentialOptimizer, BvlsStageMinimisesObjective29) {
  std::mt19937 rng(9);
  SequentialOptimizer seq;
  for (int trial = 0; trial < 200; ++trial) {
    const ContactProblem p = random_arbitrary(rng, true, true);
    ContactSolution s;
    seq.solve(p, s);
    const SequentialStages& st = seq.stages();
    Eigen::Vector3d k_f = Eigen::Vector3d::Zero();
    for (int i = 0; i < kMaxFeet; ++i)
      k_f += (p.feet[i].p_WF - p.com).cross(s.feet[i].force_W);
    auto j29 = [&](const Eigen::Matrix<double, 6, 1>& eta) {
      Eigen::Vector3d tau = Eigen::Vector3d::Zero();
      for (int i = 0; i < kMaxFeet; ++i) {
        tau += make_foot_wrench(p.feet[i], s.feet[i].force_W, eta[3 * i], eta[3 * i + 1],
                                eta[3 * i + 2])
                   .torque_ankle_W;
      }
      return (tau - (p.k_dot_desired - k_f)).squaredNorm() +
             p.weights.eps_cop * (eta - st.eta_desired).squaredNorm();
    };
    const double scale = 1.0 + j29(st.eta);
    for (int k = 0; k < 6; ++k) {
      const double hstep = 1e-7;
      Eigen::Matrix<double, 6, 1> up = st.eta, dn = st.eta;
      up[k] += hstep;
      dn[k] -= hstep;
      const double grad = (j29(up) - j29(dn)) / (2 * hstep);
      const double g_tol = 1e-5 * scale;
      if (st.eta_lower[k] == st.eta_upper[k]) continue;
      if (st.eta[k] <= st.eta_lower[k]) {
        EXPECT_GE(grad, -g_tol) << "trial " << trial;
      } else if (st.eta[k] >= st.eta_upper[k]) {
        EXPECT_LE(grad, g_tol) << "trial " << trial;
      } else {
        EXPECT_NEAR(grad, 0.0, g_tol) << "trial " << trial << " k " << k;
      }
    }
  }
}

TEST(ContactOptimizer, QpObjectiveIsAtMostSequentialsWhenComparable) {
  // The QP is the exact optimum of J_qp over its feasible set. In double support, wherever the
  // sequential answer (rho from its NNLS stage, CoPs and normal torques from BVLS) lies in that
  // set (|m_z| <= mu_torsion f_z, m_z the normal moment below the ankle), J_qp(qp) <=
  // J_qp(sequential).
  std::mt19937 rng(10);
  SequentialOptimizer seq;
  QpOptimizer qp;
  int compared = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const bool right = trial % 4 != 1, left = trial % 4 != 2;
    const ContactProblem p =
        trial % 2 ? random_feasible(rng, right, left) : random_arbitrary(rng, right, left);
    ContactSolution s_seq, s_qp;
    seq.solve(p, s_seq);
    qp.solve(p, s_qp);
    if (!qp.adjusted()) {
      // Two independent evaluations of J_qp agree: from the QP matrices and from the wrenches.
      EXPECT_NEAR(qp.raw_objective(), qp_objective(p, s_qp, qp.rho()),
                  1e-8 * (1.0 + qp.raw_objective()));
    }
    if (!(right && left)) continue;
    bool in_qp_set = true;
    for (int i = 0; i < kMaxFeet; ++i)
      in_qp_set &= in_qp_torsion_model(p.feet[i], s_seq.feet[i]);
    if (!in_qp_set) continue;
    ++compared;
    const double j_seq = qp_objective(p, s_seq, seq.stages().rho);
    EXPECT_LE(qp.raw_objective(), j_seq + 1e-8 * (1.0 + j_seq)) << "trial " << trial;
  }
  EXPECT_GT(compared, 50);
}

TEST(ContactOptimizer, NonLevelFeetAreRotationEquivariant) {
  // Rotating the whole problem (feet, CoM, gravity, desired rates) by Q rotates the answer by Q:
  // a level problem and its +-10 deg tilted copy must agree.
  std::mt19937 rng(11);
  for (double roll : {-10.0, 10.0}) {
    for (double pitch : {-10.0, 10.0}) {
      const Eigen::Matrix3d Q = rpy(roll * M_PI / 180.0, pitch * M_PI / 180.0, 0.0);
      for (int trial = 0; trial < 20; ++trial) {
        const ContactProblem p = trial % 2 ? random_feasible(rng, true, trial % 4 != 1)
                                           : random_arbitrary(rng, true, trial % 4 != 0);
        ContactProblem q = p;
        q.gravity = Q * p.gravity;
        q.com = Q * p.com;
        q.k_dot_desired = Q * p.k_dot_desired;
        q.l_dot_desired = Q * p.l_dot_desired;
        for (int i = 0; i < kMaxFeet; ++i) {
          q.feet[i].R_WF = Q * p.feet[i].R_WF;
          q.feet[i].p_WF = Q * p.feet[i].p_WF;
        }
        for (Method m : {Method::kSequential, Method::kQp}) {
          const ContactSolution a = solve(m, p), b = solve(m, q);
          EXPECT_EQ(a.status, b.status);
          const double tol = 1e-7 * p.mass * 9.81;
          EXPECT_LT((Q * a.l_dot_admissible - b.l_dot_admissible).norm(), tol);
          EXPECT_LT((Q * a.k_dot_admissible - b.k_dot_admissible).norm(), tol);
          for (int i = 0; i < kMaxFeet; ++i) {
            EXPECT_LT((Q * a.feet[i].force_W - b.feet[i].force_W).norm(), tol) << to_string(m);
            EXPECT_LT((a.feet[i].cop_F - b.feet[i].cop_F).norm(), 1e-7);
          }
        }
      }
    }
  }
}

TEST(ContactOptimizer, DegenerateCases) {
  std::mt19937 rng(12);
  for (Method m : {Method::kSequential, Method::kQp}) {
    // One foot nearly unloaded: all the weight on the right foot.
    {
      ContactProblem p = random_geometry(rng, true, true);
      FootWrench w[kMaxFeet];
      w[0] = test::random_admissible_wrench(rng, p.feet[0], p.mass * 9.81);
      w[1] = test::random_admissible_wrench(rng, p.feet[1], 1e-6);
      test::set_desired_from_wrenches(p, w);
      const ContactSolution s = solve(m, p);
      expect_admissible(p, s, true, "unloaded");
      EXPECT_TRUE(s.status == ContactStatus::kOk || s.status == ContactStatus::kCompromised);
    }
    // Overlapping feet: both at the same pose.
    {
      ContactProblem p = random_feasible(rng, true, true);
      p.feet[1] = p.feet[0];
      const ContactSolution s = solve(m, p);
      expect_admissible(p, s, true, "overlap");
      EXPECT_TRUE(s.status == ContactStatus::kOk || s.status == ContactStatus::kCompromised);
    }
    // mu = 0: only normal forces; a sideways l_dot_d cannot be produced.
    for (bool two : {false, true}) {
      ContactProblem p = random_feasible(rng, true, two);
      for (FootContact& f : p.feet)
        f.mu = 0.0;
      p.l_dot_desired += Eigen::Vector3d(30.0, -20.0, 0.0);
      const ContactSolution s = solve(m, p);
      expect_admissible(p, s, two, "mu=0");
      for (int i = 0; i < kMaxFeet; ++i) {
        const Eigen::Vector3d f = p.feet[i].R_WF.transpose() * s.feet[i].force_W;
        EXPECT_LT(std::hypot(f.x(), f.y()), 1e-9 * p.mass * 9.81);
      }
      EXPECT_EQ(s.status, ContactStatus::kCompromised);
    }
    // A huge k_dot_d.
    for (bool two : {false, true}) {
      ContactProblem p = random_feasible(rng, true, two);
      p.k_dot_desired = Eigen::Vector3d(3e6, -2e6, 1e6);
      const ContactSolution s = solve(m, p);
      expect_admissible(p, s, two || m == Method::kQp, "huge k");
      EXPECT_EQ(s.status, ContactStatus::kCompromised);
    }
    // Zero gravity: nothing to hold; desired zero rate -> zero forces.
    for (bool two : {false, true}) {
      ContactProblem p = random_geometry(rng, true, two);
      p.gravity.setZero();
      const ContactSolution s = solve(m, p);
      expect_admissible(p, s, two || m == Method::kQp, "zero g");
      EXPECT_LT(s.l_dot_admissible.norm() + s.k_dot_admissible.norm(), 1e-9);
      EXPECT_EQ(s.status, ContactStatus::kOk);
    }
    // No foot in contact.
    {
      const ContactProblem p = random_arbitrary(rng, false, false);
      const ContactSolution s = solve(m, p);
      EXPECT_EQ(s.status, ContactStatus::kNoContact);
      EXPECT_LT((s.l_dot_admissible - p.mass * p.gravity).norm(), 1e-12);
    }
  }
}

TEST(ContactOptimizer, BadInputGivesErrorStatusAndFiniteSafeAnswer) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  std::mt19937 rng(13);
  const ContactProblem good = random_feasible(rng, true, true);
  ASSERT_EQ(validate(good), nullptr);
  struct Case {
    const char* expected;
    void (*mutate)(ContactProblem&, double, double);
  };
  const Case cases[] = {
      {"mass", [](ContactProblem& p, double n, double) { p.mass = n; }},
      {"mass", [](ContactProblem& p, double, double) { p.mass = -1.0; }},
      {"gravity", [](ContactProblem& p, double, double i) { p.gravity.y() = i; }},
      {"com", [](ContactProblem& p, double n, double) { p.com.x() = n; }},
      {"k_dot_desired", [](ContactProblem& p, double, double) { p.k_dot_desired.z() = 1e300; }},
      {"l_dot_desired", [](ContactProblem& p, double n, double) { p.l_dot_desired.z() = n; }},
      {"feet[0]: R_WF is not a rotation",
       [](ContactProblem& p, double, double) { p.feet[0].R_WF(0, 0) = 2.0; }},
      {"feet[1]: R_WF is not a rotation",
       [](ContactProblem& p, double, double) { p.feet[1].R_WF = -p.feet[1].R_WF; }},
      {"feet[1]: R_WF has a non-finite",
       [](ContactProblem& p, double n, double) { p.feet[1].R_WF(2, 1) = n; }},
      {"feet[0]: p_WF", [](ContactProblem& p, double, double i) { p.feet[0].p_WF.z() = i; }},
      {"feet[0]: sole", [](ContactProblem& p, double, double) { p.feet[0].sole.x_min = 0.5; }},
      {"feet[1]: safety_margin",
       [](ContactProblem& p, double, double) { p.feet[1].safety_margin = 0.2; }},
      {"feet[0]: ankle_height",
       [](ContactProblem& p, double, double) { p.feet[0].ankle_height = -0.1; }},
      {"feet[1]: mu is", [](ContactProblem& p, double n, double) { p.feet[1].mu = n; }},
      {"feet[0]: mu_torsion",
       [](ContactProblem& p, double, double) { p.feet[0].mu_torsion = -1.0; }},
      {"weights.w_k", [](ContactProblem& p, double n, double) { p.weights.w_k = n; }},
  };
  for (const Case& c : cases) {
    ContactProblem p = good;
    c.mutate(p, nan, inf);
    const char* msg = validate(p);
    ASSERT_NE(msg, nullptr) << c.expected;
    EXPECT_NE(std::string(msg).find(c.expected), std::string::npos) << msg;
    for (Method m : {Method::kSequential, Method::kQp}) {
      const ContactSolution s = solve(m, p);
      EXPECT_EQ(s.status, ContactStatus::kInvalidInput);
      EXPECT_TRUE(s.l_dot_admissible.isZero() && s.k_dot_admissible.isZero());
      for (const FootWrench& w : s.feet)
        EXPECT_TRUE(w.force_W.isZero() && w.cop_W.isZero());
    }
  }
  // A foot not in contact is not validated: garbage there is ignored.
  ContactProblem p = good;
  p.feet[1].in_contact = false;
  p.feet[1].R_WF(0, 0) = nan;
  EXPECT_EQ(validate(p), nullptr);
  EXPECT_NE(solve(Method::kSequential, p).status, ContactStatus::kInvalidInput);
}

TEST(ContactOptimizer, FuzzedInputNeverGivesNonFiniteOutput) {
  std::mt19937 rng(14);
  const double specials[] = {std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::infinity(),
                             -1e300,
                             1e12,
                             -5.0,
                             0.0,
                             1e-300};
  SequentialOptimizer seq;
  QpOptimizer qp;
  for (int trial = 0; trial < 2000; ++trial) {
    ContactProblem p = random_arbitrary(rng, trial % 3 != 1, trial % 3 != 2);
    double* fields[] = {&p.mass,
                        &p.gravity.z(),
                        &p.com.y(),
                        &p.k_dot_desired.x(),
                        &p.l_dot_desired.z(),
                        &p.feet[0].R_WF(1, 2),
                        &p.feet[1].p_WF.x(),
                        &p.feet[0].sole.y_max,
                        &p.feet[1].safety_margin,
                        &p.feet[0].ankle_height,
                        &p.feet[1].mu,
                        &p.feet[0].mu_torsion,
                        &p.weights.eps_f};
    *fields[test::uniform_int(rng, 0, 12)] = specials[test::uniform_int(rng, 0, 6)];
    ContactSolution s;
    for (int which = 0; which < 2; ++which) {
      if (which == 0) seq.solve(p, s);
      if (which == 1) qp.solve(p, s);
      bool finite = s.k_dot_admissible.allFinite() && s.l_dot_admissible.allFinite();
      for (const FootWrench& w : s.feet) {
        finite = finite && w.force_W.allFinite() && w.torque_ankle_W.allFinite() &&
                 w.cop_W.allFinite() && w.cop_F.allFinite() && std::isfinite(w.normal_torque);
      }
      ASSERT_TRUE(finite) << "trial " << trial;
    }
  }
}

}  // namespace
}  // namespace poise::contact
