// The controller's tick on the project humanoid, checked against independent computations:
// the contact problem against forward kinematics and eqs (10)-(11) by hand; the eq (33) output
// against finite differences of the foot poses (J qdd + J_dot qd = a_d); the momentum identity
// A qdd + A_dot qd = hdot_a of the admissible wrenches; the inverse-dynamics base residual against
// the momentum residual (Newton-Euler of the whole body); fallbacks; bad input.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <random>

#include "controller_test_util.hpp"
#include "poise/contact/sequential_optimizer.hpp"
#include "poise/controller/contact_fallback.hpp"
#include "poise/controller/foot_motion.hpp"
#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"

namespace poise::controller {
namespace {

using test::humanoid;

// The defaults with eqs (10)-(11) as written (the ankle strategy's rule and the trunk-upright
// target off), for the tests that check (10)-(11) by hand.
ControllerConfig eq11_config() {
  ControllerConfig cfg;
  cfg.momentum.ankle_first_blend = 0.0;
  cfg.momentum.upright_pitch_rate = 0.0;  // (10) as written: k_d from the reference
  cfg.momentum.upright_roll_rate = 0.0;
  return cfg;
}

// The model's q, v of a state (the base velocity in the base frame, model.hpp).
void configuration_of(const model::Model& model, const RobotState& s, Eigen::VectorXd& q,
                      Eigen::VectorXd& v) {
  q.resize(model.nq);
  v.resize(model.nv);
  q.head<3>() = s.X_WB.p;
  q.segment<4>(3) = Eigen::Quaterniond(s.X_WB.R).coeffs();
  q.tail(model.njoints) = s.q;
  v.head<3>() = s.X_WB.R.transpose() * s.v_WB;
  v.segment<3>(3) = s.X_WB.R.transpose() * s.omega_WB;
  v.tail(model.njoints) = s.qd;
}

BalanceController make_controller(ControllerConfig cfg = {}) {
  return BalanceController(humanoid().model, humanoid().robot, cfg);
}

// robot.yaml's stand points (model::FootConfig::stand_point): the CoM target is above their
// mid-point in double support and above the one stand point in single support, on seeded random
// states and random points of the soles; unset, the sole centres (the paper's rule).
TEST(BalanceController, TheCoMTargetIsAboveTheStandPointsWhereRobotYamlPutsThem) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 10; ++trial) {
    model::RobotConfig robot = humanoid().robot;
    for (auto& f : robot.feet)
      f.stand_point = Eigen::Vector2d(f.sole.x_min + u(rng) * (f.sole.x_max - f.sole.x_min),
                                      f.sole.y_min + u(rng) * (f.sole.y_max - f.sole.y_min));
    BalanceController c(humanoid().model, robot, eq11_config());
    BalanceController centre(humanoid().model, humanoid().robot, eq11_config());
    const RobotState s = test::random_state(c, rng);
    BalanceReference ref = c.make_reference();
    contact::ContactProblem p;
    c.prepare(s, ref, p);
    centre.prepare(s, ref, p);
    Eigen::Vector3d mid = Eigen::Vector3d::Zero(), mid_centre = Eigen::Vector3d::Zero();
    std::array<Eigen::Vector3d, 2> point_W;
    for (int i = 0; i < 2; ++i) {
      const auto& f = robot.feet[i];
      const model::SE3 X(p.feet[i].R_WF, p.feet[i].p_WF);
      // by hand: the point in the foot frame, on the sole plane
      point_W[i] =
          X.R * Eigen::Vector3d(f.stand_point->x(), f.stand_point->y(), -f.sole.height) + X.p;
      mid += 0.5 * point_W[i];
      mid_centre += 0.5 * sole_center_W(X, f.sole);
    }
    const Eigen::Vector3d d = c.diagnostics().com_target_W - mid;
    const Eigen::Vector3d dc = centre.diagnostics().com_target_W - mid_centre;
    EXPECT_LT(d.head<2>().norm(), 1e-12) << trial;
    EXPECT_LT(dc.head<2>().norm(), 1e-12) << trial;
    EXPECT_NEAR(d.z(), dc.z(), 1e-9) << trial;  // the same height above the soles
    EXPECT_GT((mid - mid_centre).head<2>().norm(), 1e-4) << trial;  // the points did move it
    // Single support on the left foot: above its stand point.
    RobotState one = s;
    one.feet[0].in_contact = false;
    one.feet[0].normal_force = 0.0;
    c.prepare(one, ref, p);
    if (!p.feet[0].in_contact && p.feet[1].in_contact)
      EXPECT_LT((c.diagnostics().com_target_W - point_W[1]).head<2>().norm(), 1e-12) << trial;
    else
      ADD_FAILURE() << "not single support on the left foot: " << trial;
  }
}

// RobotConfig::effort_limited_sole: the sole rectangle the contact problem gets keeps every joint
// of that leg within its effort for a CoP anywhere in it, at the foot's measured load, checked by
// an independent inverse dynamics (RNEA at rest, the load up at each corner of the rectangle) on
// seeded random static postures with weakened ankles; the cut is tight (its edge 1 mm further
// out takes some joint past its effort at the sole's full width); off, the sole as configured.
TEST(BalanceController, AnEffortLimitedSoleKeepsEveryLegJointWithinItsEffort) {
  model::Model m = humanoid().model;
  for (const char* ankle : {"l_ankle_pitch", "r_ankle_pitch"}) m.limits[m.joint_index(ankle)].effort = 6.0;
  for (const char* ankle : {"l_ankle_roll", "r_ankle_roll"}) m.limits[m.joint_index(ankle)].effort = 8.0;
  model::RobotConfig robot = humanoid().robot;
  robot.effort_limited_sole = true;
  BalanceController c(m, robot, eq11_config());
  BalanceController off(m, humanoid().robot, eq11_config());
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> load(100.0, 450.0);
  const Eigen::Vector3d up(0, 0, 1);
  const double w = 2.0 * robot.safety_margin + 0.004;
  int cuts = 0, tight = 0;
  for (int trial = 0; trial < 20; ++trial) {
    RobotState s = test::random_state(c, rng, 0.05, 0.0);
    std::array<double, 2> fz{load(rng), load(rng)};
    for (int i = 0; i < 2; ++i) {
      s.feet[i].in_contact = true;
      s.feet[i].normal_force = fz[i];
    }
    BalanceReference ref = c.make_reference();
    contact::ContactProblem p, p_off;
    c.prepare(s, ref, p);
    off.prepare(s, ref, p_off);
    Eigen::VectorXd q, v;
    configuration_of(m, s, q, v);
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(m.nv);
    for (int i = 0; i < 2; ++i) {
      const auto& foot = robot.feet[i];
      const auto& so = p.feet[i].sole;
      const auto& full = p_off.feet[i].sole;
      EXPECT_EQ(full.x_min, foot.sole.x_min);
      EXPECT_EQ(full.y_max, foot.sole.y_max);
      EXPECT_GE(so.x_min, full.x_min);
      EXPECT_LE(so.x_max, full.x_max);
      EXPECT_GE(so.y_min, full.y_min);
      EXPECT_LE(so.y_max, full.y_max);
      const bool x_cut = so.x_min > full.x_min || so.x_max < full.x_max;
      const bool y_cut = so.y_min > full.y_min || so.y_max < full.y_max;
      cuts += x_cut || y_cut;
      const bool kept = std::abs(so.x_max - so.x_min - w) < 1e-12 ||
                        std::abs(so.y_max - so.y_min - w) < 1e-12;
      if (kept) continue;  // a joint that holds the load nowhere: the minimum width kept
      // The leg's joints: the foot body's chain to the floating base.
      std::vector<int> chain;
      for (int b = m.frames[foot.frame_id].body; b > 0; b = m.parent[b]) chain.push_back(b - 1);
      const model::SE3 X(p.feet[i].R_WF, p.feet[i].p_WF);
      auto worst = [&](double x, double y) {  // largest |tau_j| / L_j of the leg, CoP at (x, y)
        model::Data d(m);
        model::clear_external_forces(d);
        model::add_external_wrench(m, d, foot.frame_id,
                                   X.act(Eigen::Vector3d(x, y, -foot.sole.height)), fz[i] * up,
                                   Eigen::Vector3d::Zero());
        const Eigen::VectorXd tau = model::rnea(m, d, q, zero, zero);
        double r = 0.0;
        for (int j : chain)
          if (std::isfinite(m.limits[j].effort))
            r = std::max(r, std::abs(tau[m.idx_v(j)]) / m.limits[j].effort);
        return r;
      };
      for (double x : {so.x_min, so.x_max})
        for (double y : {so.y_min, so.y_max})
          EXPECT_LE(worst(x, y), 1.0 + 1e-9) << trial << " foot " << i << " at " << x << ", " << y;
      // Tight: an x edge the cut moved, 1 mm further out, breaks some joint at a full-width y.
      if (so.x_max < full.x_max - 1e-3) {
        EXPECT_GT(std::max(worst(so.x_max + 1e-3, full.y_min), worst(so.x_max + 1e-3, full.y_max)),
                  1.0) << trial;
        ++tight;
      }
      if (so.x_min > full.x_min + 1e-3) {
        EXPECT_GT(std::max(worst(so.x_min - 1e-3, full.y_min), worst(so.x_min - 1e-3, full.y_max)),
                  1.0) << trial;
        ++tight;
      }
    }
  }
  // A load the controller cannot use (NaN, negative, zero: a failed F/T reading or a foot in the
  // air) leaves the sole whole, this tick, whatever the previous tick cut.
  for (const double bad : {std::numeric_limits<double>::quiet_NaN(), -50.0, 0.0}) {
    RobotState s = test::random_state(c, rng, 0.05, 0.0);
    s.feet[0].normal_force = 400.0;  // cut the left foot first
    s.feet[1].normal_force = 400.0;
    BalanceReference ref = c.make_reference();
    contact::ContactProblem p;
    c.prepare(s, ref, p);
    ASSERT_LT(p.feet[1].sole.x_max, robot.feet[1].sole.x_max);
    s.feet[1].normal_force = bad;
    c.prepare(s, ref, p);
    EXPECT_EQ(p.feet[1].sole.x_min, robot.feet[1].sole.x_min) << bad;
    EXPECT_EQ(p.feet[1].sole.x_max, robot.feet[1].sole.x_max) << bad;
    EXPECT_EQ(p.feet[1].sole.y_min, robot.feet[1].sole.y_min) << bad;
    EXPECT_EQ(p.feet[1].sole.y_max, robot.feet[1].sole.y_max) << bad;
    EXPECT_LT(p.feet[0].sole.x_max, robot.feet[0].sole.x_max) << bad;
  }
  std::printf("effort-limited soles: %d of 40 cut, %d cut x edges checked tight\n", cuts, tight);
  EXPECT_GE(cuts, 20);
  EXPECT_GE(tight, 10);
}

TEST(BalanceController, ContactProblemMatchesKinematicsAndEquations10And11) {
  BalanceController c = make_controller(eq11_config());
  const auto& model = c.model();
  const auto& robot = c.robot();
  std::mt19937 rng(1);
  for (int trial = 0; trial < 20; ++trial) {
    const RobotState s = test::random_state(c, rng);
    BalanceReference ref = c.make_reference();
    contact::ContactProblem p;
    c.prepare(s, ref, p);

    // Independent kinematics: configuration from the state, model FK and CoM.
    Eigen::VectorXd q, v;
    configuration_of(model, s, q, v);
    model::Data data(model);
    model::centroidal_momentum(model, data, q, v);
    double mass = 0.0;
    for (const auto& I : model.inertia)
      mass += I.mass;
    EXPECT_NEAR(p.mass, mass, 1e-9);
    EXPECT_LT((p.com - data.com).norm(), 1e-12);
    EXPECT_EQ(p.gravity, Eigen::Vector3d(0, 0, -9.81));

    Eigen::Vector3d sole_mid = Eigen::Vector3d::Zero();
    for (int i = 0; i < 2; ++i) {
      const auto& f = robot.feet[i];
      const model::SE3 X = model::frame_placement(model, data, f.frame_id);
      EXPECT_TRUE(p.feet[i].in_contact);
      EXPECT_LT((p.feet[i].p_WF - X.p).norm(), 1e-12);
      EXPECT_LT((p.feet[i].R_WF - X.R).norm(), 1e-12);
      // The sole frame lies h below the ankle along the foot's z: the problem's ankle height.
      const model::SE3 Xs = model::frame_placement(model, data, f.sole_frame_id);
      EXPECT_NEAR((X.R.transpose() * (Xs.p - X.p)).z(), -p.feet[i].ankle_height, 1e-9);
      EXPECT_EQ(p.feet[i].sole.x_max, f.sole.x_max);
      EXPECT_EQ(p.feet[i].sole.y_min, f.sole.y_min);
      EXPECT_EQ(p.feet[i].mu, robot.friction_mu);
      EXPECT_EQ(p.feet[i].mu_torsion, robot.torsional_mu);
      EXPECT_EQ(p.feet[i].safety_margin, robot.safety_margin);
      sole_mid += 0.5 * X.act(Eigen::Vector3d(0.5 * (f.sole.x_min + f.sole.x_max),
                                              0.5 * (f.sole.y_min + f.sole.y_max), -f.sole.height));
    }
    // CoM target: above the mid-point of the soles at the nominal CoM height.
    model::Data dn(model);
    model::center_of_mass(model, dn, robot.q_nominal);
    const double nominal_height =
        dn.com.z() - model::frame_placement(model, dn, robot.feet[0].sole_frame_id).p.z();
    const Eigen::Vector3d target = sole_mid + Eigen::Vector3d(0, 0, nominal_height);
    EXPECT_LT((c.diagnostics().com_target_W - target).norm(), 1e-9);
    // Eqs (10)-(11) by hand with the default gains (Z up).
    const ControllerConfig cfg = eq11_config();
    for (int a = 0; a < 3; ++a) {
      const double k = data.hg[a];
      EXPECT_NEAR(p.k_dot_desired[a], cfg.momentum.gamma11[a] * (0.0 - k), 1e-9);
      const double ldot = mass * (cfg.momentum.gamma21[a] *
                                      (c.diagnostics().com_velocity_target_W[a] - data.vcom[a]) +
                                  cfg.momentum.gamma22[a] * (target[a] - data.com[a]));
      EXPECT_NEAR(p.l_dot_desired[a], ldot, 1e-8 * (1 + std::abs(ldot)));
    }
  }
}

// MomentumGains::support_acceleration_hz: the whole robot standing still relative to its feet
// while its supports accelerate (every body translated by p0 + v0 t + a t^2 / 2 + j t^3 / 6, joints
// fixed). Checked against the trajectory itself: the supports' acceleration estimate is a (+ the
// three-stage filter's lag 3 / w times j), the CoM target is the sole mid-point leaning
// h / (g + a_z) a horizontally -- where the inverted pendulum's zero-moment point c - h a / g of
// that acceleration lies under the sole mid-point -- its velocity target is the feet's velocity
// plus that lean's rate h j / g, and (11) carries m a on top of the feedback. Off: none of it;
// with a reference's CoM target: none of it either.
// The optimiser's mu: robot.yaml's contact.friction_mu unless the controller configuration
// (a scenario's `controller: {contact: {friction_mu: X}}`) says otherwise; bad values named.
TEST(BalanceController, TheOptimisersFrictionIsRobotYamlsUnlessTheConfigurationSetsIt) {
  std::mt19937 rng(3);
  ControllerConfig cfg = eq11_config();
  cfg.contact.friction_mu = 0.45;
  BalanceController told = make_controller(cfg);
  BalanceController plain = make_controller(eq11_config());
  ASSERT_NE(plain.robot().friction_mu, 0.45);
  const RobotState s = test::random_state(told, rng);
  contact::ContactProblem p_told, p_plain;
  told.prepare(s, told.make_reference(), p_told);
  plain.prepare(s, plain.make_reference(), p_plain);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(p_told.feet[i].mu, 0.45);
    EXPECT_EQ(p_plain.feet[i].mu, plain.robot().friction_mu);
  }
  EXPECT_EQ(parse_controller_config("contact: {friction_mu: 0.3}", "t").contact.friction_mu, 0.3);
  for (const char* bad : {"contact: {friction_mu: -0.1}", "contact: {friction_mu: .nan}",
                          "contact: {friction_mu: 11}"}) {
    try {
      parse_controller_config(bad, "t");
      ADD_FAILURE() << bad << " was accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("contact.friction_mu"), std::string::npos) << e.what();
    }
  }
}

TEST(BalanceController, AcceleratingSupportsLeanTheCoMTargetAndFeedTheirAccelerationForward) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 6; ++trial) {
    const Eigen::Vector3d acc(test::uniform(rng, -3, 3), test::uniform(rng, -3, 3),
                              test::uniform(rng, -1, 1));
    const Eigen::Vector3d jerk =
        trial % 2 ? Eigen::Vector3d(test::uniform(rng, -2, 2), test::uniform(rng, -2, 2), 0.0)
                  : Eigen::Vector3d::Zero();
    const Eigen::Vector3d v0 = test::random_vec3(rng, 0.5);
    const double hz = test::uniform(rng, 1.0, 5.0);
    ControllerConfig cfg = eq11_config();
    cfg.momentum.support_acceleration_hz = hz;
    BalanceController c = make_controller(cfg);
    ControllerConfig off_cfg = eq11_config();
    BalanceController off = make_controller(off_cfg);
    const RobotState s0 = test::standing_state(c);
    const int ticks = static_cast<int>(std::ceil(3.0 / hz / cfg.dt)) + 200;  // settled
    contact::ContactProblem p, p_off;
    RobotState s = s0;
    for (int k = 0; k <= ticks; ++k) {
      const double t = k * cfg.dt;
      const Eigen::Vector3d shift = v0 * t + 0.5 * acc * t * t + jerk * t * t * t / 6.0;
      const Eigen::Vector3d vel = v0 + acc * t + 0.5 * jerk * t * t;
      s = s0;
      s.X_WB.p += shift;
      s.v_WB = vel;
      for (auto& f : s.feet) {
        f.X_WF.p += shift;
        f.cop_W += shift;
      }
      c.prepare(s, c.make_reference(), p);
      off.prepare(s, off.make_reference(), p_off);
    }
    const double t = ticks * cfg.dt;
    const Eigen::Vector3d a_now = acc + jerk * t;
    const Eigen::Vector3d vel_now = v0 + acc * t + 0.5 * jerk * t * t;
    const double w = 2.0 * M_PI * hz;
    const auto& d = c.diagnostics();
    const auto& d_off = off.diagnostics();
    // The estimate: a ramp through three first-order stages lags 3 / w (exact in the limit).
    const Eigen::Vector3d a_est = a_now - jerk * (3.0 / w);
    EXPECT_LT((d.support_acceleration_W - a_est).norm(), 2e-3 * (1.0 + a_est.norm())) << trial;
    // Without the option: the paper's target (the sole mid-point, the feet's velocity).
    EXPECT_LT(d_off.support_acceleration_W.norm(), 1e-12);
    EXPECT_LT((d_off.com_velocity_target_W - vel_now).norm(), 1e-6);
    const double g = 9.81;
    const Eigen::Vector3d base_target = d_off.com_target_W;
    const double h = base_target.z() - 0.5 * (s.feet[0].cop_W.z() + s.feet[1].cop_W.z());
    const double k_lean = h / (g + d.support_acceleration_W.z());
    Eigen::Vector3d lean = k_lean * d.support_acceleration_W;
    lean.z() = 0.0;
    EXPECT_LT((d.com_target_W - (base_target + lean)).norm(), 1e-9) << trial;
    // The zero-moment point of the leant target under that acceleration is the sole mid-point.
    const Eigen::Vector2d zmp = d.com_target_W.head<2>() - k_lean * d.support_acceleration_W.head<2>();
    EXPECT_LT((zmp - base_target.head<2>()).norm(), 1e-9);
    // Velocity target: the feet's, plus the lean's rate (h / g) j once settled.
    Eigen::Vector3d lean_rate = k_lean * jerk;
    lean_rate.z() = 0.0;
    EXPECT_LT((d.com_velocity_target_W - (vel_now + lean_rate)).norm(),
              1e-3 * (1.0 + lean_rate.norm()))
        << trial;
    // (11) by hand, plus m a.
    for (int i = 0; i < 3; ++i) {
      const double ldot = p.mass * (cfg.momentum.gamma21[i] *
                                        (d.com_velocity_target_W[i] - d.com_velocity_W[i]) +
                                    cfg.momentum.gamma22[i] * (d.com_target_W[i] - d.com_W[i]) +
                                    d.support_acceleration_W[i]);
      EXPECT_NEAR(p.l_dot_desired[i], ldot, 1e-8 * (1 + std::abs(ldot))) << trial;
    }
    // A reference's CoM target is taken as it is.
    BalanceReference ref = c.make_reference();
    ref.has_com_target = true;
    ref.com_W = d.com_W + Eigen::Vector3d(0.01, 0.0, 0.0);
    ref.com_velocity_W = vel_now;
    c.prepare(s, ref, p);
    EXPECT_LT(c.diagnostics().support_acceleration_W.norm(), 1e-12);
    EXPECT_LT((c.diagnostics().com_target_W - ref.com_W).norm(), 1e-12);
  }
  // A restart (reset) starts from zero; a jump of the measured velocity (an estimator re-placing
  // the robot: 10 m/s in one tick, 1e4 m/s^2 if differenced) is clamped to 3 g for that tick, so
  // the estimate stays small (unclamped it would peak at several m/s^2).
  {
    ControllerConfig cfg = eq11_config();
    cfg.momentum.support_acceleration_hz = 1.0;
    BalanceController c = make_controller(cfg);
    const RobotState s0 = test::standing_state(c);
    contact::ContactProblem p;
    c.prepare(s0, c.make_reference(), p);
    c.reset();
    c.prepare(s0, c.make_reference(), p);
    EXPECT_LT(c.diagnostics().support_acceleration_W.norm(), 1e-12);
    RobotState jumped = s0;
    jumped.v_WB = Eigen::Vector3d(10.0, 0.0, 0.0);
    double peak = 0.0;
    for (int k = 0; k < 2000; ++k) {
      c.prepare(jumped, c.make_reference(), p);
      peak = std::max(peak, c.diagnostics().support_acceleration_W.norm());
    }
    EXPECT_LT(peak, 0.05) << "a velocity jump taken for a support's motion";
  }
  ControllerConfig bad;
  bad.momentum.support_acceleration_hz = 600.0;  // above half the 1 kHz rate
  EXPECT_THROW(bad.validate(), ConfigError);
  bad.momentum.support_acceleration_hz = -1.0;
  EXPECT_THROW(bad.validate(), ConfigError);
}

// MomentumGains::feedback_filter_hz: (10)-(11) feed back the first-order low-pass of the CoM
// velocity error (target - measured) and of the angular momentum, y += a (x - y) with
// a = dt / (dt + 1 / (2 pi f)), exact at the first tick and again after reset(). Checked against
// that recurrence on the controller's own measured values over random states.
TEST(BalanceController, FeedbackFilterIsTheFirstOrderRecurrence) {
  ControllerConfig cfg = eq11_config();
  cfg.momentum.feedback_filter_hz = 30.0;
  BalanceController c = make_controller(cfg);
  const double a = cfg.dt / (cfg.dt + 1.0 / (2.0 * M_PI * 30.0));
  std::mt19937 rng(7);
  Eigen::Vector3d e_f = Eigen::Vector3d::Zero(), k_f = Eigen::Vector3d::Zero();
  for (int tick = 0; tick < 8; ++tick) {
    if (tick == 5) c.reset();
    const RobotState s = test::random_state(c, rng);
    BalanceReference ref = c.make_reference();
    contact::ContactProblem p;
    c.prepare(s, ref, p);
    const auto& d = c.diagnostics();
    const Eigen::Vector3d e = d.com_velocity_target_W - d.com_velocity_W;
    const Eigen::Vector3d k = d.h_W.head<3>();
    if (tick == 0 || tick == 5) {
      e_f = e;
      k_f = k;
    } else {
      e_f += a * (e - e_f);
      k_f += a * (k - k_f);
    }
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(p.k_dot_desired[i], cfg.momentum.gamma11[i] * (0.0 - k_f[i]), 1e-9) << tick;
      const double ldot = p.mass * (cfg.momentum.gamma21[i] * e_f[i] +
                                    cfg.momentum.gamma22[i] * (d.com_target_W[i] - d.com_W[i]));
      EXPECT_NEAR(p.l_dot_desired[i], ldot, 1e-8 * (1 + std::abs(ldot))) << tick;
    }
    // The filter does something: random states differ, so the unfiltered answer is far off.
    if (tick != 0 && tick != 5) {
      EXPECT_GT(std::abs(p.k_dot_desired[0] - cfg.momentum.gamma11[0] * (0.0 - k[0])), 1e-6);
    }
  }
  EXPECT_THROW(
      [] {
        ControllerConfig bad;
        bad.momentum.feedback_filter_hz = -1.0;
        bad.validate();
      }(),
      ConfigError);
}

// MomentumGains::upright_pitch_rate, upright_roll_rate: (10)'s k_d gains I_G omega_u, the
// angular momentum of the robot turning rigidly (joints locked) with omega_u = the rates x the
// rotation vector that brings the trunk upright, split about the robot's horizontal forward
// (roll) and the axis across it (pitch). The robot is tilted about a horizontal axis n by theta,
// then yawed by psi (the nominal posture has both soles flat and the base level, checked): the
// rotation vector is -theta R_z(psi) n; the robot's forward is +x (robot.yaml), and n = its
// lateral or forward axis gives pure pitch or roll. I_G omega_u from the model's centroidal
// momentum of that rigid motion (not A_G); a pure yaw adds nothing; 0 is the paper's (10); bad
// values are refused by name.
TEST(BalanceController, TrunkUprightAddsTheLockedInertiaTimesTheTiltRate) {
  const double r_pitch = 1.7, r_roll = 0.6;
  ControllerConfig cfg = eq11_config();
  cfg.momentum.upright_pitch_rate = r_pitch;
  cfg.momentum.upright_roll_rate = r_roll;
  BalanceController c = make_controller(cfg);
  BalanceController off = make_controller(eq11_config());
  const auto& model = c.model();
  const auto& robot = c.robot();
  {  // premises
    model::Data dn(model);
    model::forward_kinematics(model, dn, robot.q_nominal);
    for (int i = 0; i < 2; ++i)
      ASSERT_NEAR(model::frame_placement(model, dn, robot.feet[i].frame_id).R(2, 2), 1.0, 1e-9);
    ASSERT_LT((model::base_pose(robot.q_nominal).R - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    ASSERT_EQ(robot.forward_axis, Eigen::Vector3d::UnitX());
  }
  std::mt19937 rng(23);
  for (int trial = 0; trial < 16; ++trial) {
    RobotState s = test::random_state(c, rng);
    const double phi = trial == 1 ? M_PI / 2 : trial == 2 ? 0.0 : test::uniform(rng, -M_PI, M_PI);
    const Eigen::Vector3d n(std::cos(phi), std::sin(phi), 0.0);  // trial 1: pitch, 2: roll
    const double theta = trial == 0 ? 0.0 : test::uniform(rng, -0.8, 0.8);  // trial 0: yaw only
    const double psi = test::uniform(rng, -M_PI, M_PI);
    const Eigen::Matrix3d Rz = Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    s.X_WB = model::SE3(Rz * Eigen::AngleAxisd(theta, n).toRotationMatrix(), s.X_WB.p);
    BalanceReference ref = c.make_reference();
    contact::ContactProblem p, p_off;
    c.prepare(s, ref, p);
    off.prepare(s, ref, p_off);

    // The expected rate: the tilt's rotation vector, its component along the robot's forward
    // made horizontal at r_roll, the rest at r_pitch.
    const Eigen::Vector3d tilt = -theta * (Rz * n);
    Eigen::Vector3d f = s.X_WB.R * Eigen::Vector3d::UnitX();
    f.z() = 0.0;
    f.normalize();
    const Eigen::Vector3d omega_u = r_roll * tilt.dot(f) * f + r_pitch * (tilt - tilt.dot(f) * f);
    if (trial == 1) {
      EXPECT_LT((omega_u - r_pitch * tilt).norm(), 1e-12);
    }
    if (trial == 2) {
      EXPECT_LT((omega_u - r_roll * tilt).norm(), 1e-12);
    }

    Eigen::VectorXd q, v, v_locked = Eigen::VectorXd::Zero(model.nv);
    configuration_of(model, s, q, v);
    model::Data data(model);
    model::centroidal_momentum(model, data, q, v);
    const Eigen::Vector3d k = data.hg.head<3>();
    v_locked.segment<3>(3) = s.X_WB.R.transpose() * omega_u;
    model::centroidal_momentum(model, data, q, v_locked);
    const Eigen::Vector3d k_u = data.hg.head<3>();
    if (trial == 0) {
      EXPECT_EQ(k_u.norm(), 0.0);
    } else {
      // the tilt's rate is of the order of the trunk's inertia: the check is not vacuous
      EXPECT_GT(k_u.norm(), 0.05 * std::abs(theta)) << trial;
    }
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(p.k_dot_desired[a], cfg.momentum.gamma11[a] * (k_u[a] - k[a]), 1e-9) << trial;
      EXPECT_NEAR(p_off.k_dot_desired[a], cfg.momentum.gamma11[a] * (0.0 - k[a]), 1e-9) << trial;
      EXPECT_NEAR(p.l_dot_desired[a], p_off.l_dot_desired[a], 1e-9) << trial;
    }
  }
  for (const double bad : {-0.1, 101.0, std::nan("")}) {
    for (const bool pitch : {true, false}) {
      ControllerConfig b;
      (pitch ? b.momentum.upright_pitch_rate : b.momentum.upright_roll_rate) = bad;
      const std::string key =
          pitch ? "momentum.upright_pitch_rate" : "momentum.upright_roll_rate";
      try {
        b.validate();
        ADD_FAILURE() << "accepted " << bad;
      } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
      }
    }
  }
}

TEST(BalanceController, SupportsFollowModesAndMeasuredContacts) {
  BalanceController c = make_controller();
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  contact::ContactProblem p;
  s.feet[0].in_contact = false;
  // Not flagged but loaded (> 10 % of the weight): still a support (a late contact detector).
  c.prepare(s, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);
  s.feet[0].normal_force = 0.05 * p.mass * 9.81;
  c.prepare(s, ref, p);
  EXPECT_FALSE(p.feet[0].in_contact);
  EXPECT_TRUE(p.feet[1].in_contact);
  // Single support: the CoM target is above the left sole centre.
  const auto& f = c.robot().feet[1];
  const Eigen::Vector3d left = sole_center_W(model::SE3(p.feet[1].R_WF, p.feet[1].p_WF), f.sole);
  EXPECT_LT((c.diagnostics().com_target_W.head<2>() - left.head<2>()).norm(), 1e-12);
  ref.feet[0].mode = FootMode::kSupport;
  ref.feet[1].mode = FootMode::kSwing;
  c.prepare(s, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);
  EXPECT_FALSE(p.feet[1].in_contact);
  // A support foot whose CoP is at the sole edge is not resting (Sec. 4.2).
  ref = c.make_reference();
  s = test::standing_state(c);
  s.feet[1].cop_W = s.feet[1].X_WF.act(Eigen::Vector3d(f.sole.x_max - 0.002, 0.0, -f.sole.height));
  c.prepare(s, ref, p);
  EXPECT_TRUE(c.diagnostics().resting[0]);
  EXPECT_FALSE(c.diagnostics().resting[1]);
}

TEST(BalanceController, AFootRestsOnItsMeasuredLoadNotOnItsContactFlag) {
  // Sec. 4.2 with the flag meaning "touching" (idl/README.md "Contact flags"): a foot flagged in
  // contact with a load below resting_force_fraction of the weight (its CoP, here at the sole
  // centre, would be noise) is a support but does not rest: it is held where it last rested
  // instead of following its own velocity. A loaded foot rests whatever its flag.
  BalanceController c = make_controller();
  const double weight = humanoid().model.total_mass * humanoid().model.gravity.norm();
  const double threshold = ControllerConfig{}.resting_force_fraction * weight;
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  contact::ContactProblem p;
  c.prepare(s, ref, p);  // both feet rest: their pose is the hold pose
  ASSERT_TRUE(c.diagnostics().resting[0] && c.diagnostics().resting[1]);

  s.feet[0].in_contact = true;
  s.feet[0].normal_force = 0.9 * threshold;
  c.prepare(s, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);  // touching: still a support (kAuto)
  EXPECT_FALSE(c.diagnostics().resting[0]);
  EXPECT_TRUE(c.diagnostics().resting[1]);
  // Not resting: held. With the foot moving 0.1 m/s forward in the state, a resting foot would
  // be asked zero acceleration (v_d = v, T_d = T); a held one is pulled back (kd (0 - v)).
  s.feet[0].normal_force = 0.9 * threshold;
  RobotState moving = s;
  moving.v_WB.x() += 0.1;  // the whole robot, both feet included, moves forward
  c.prepare(moving, ref, p);
  EXPECT_FALSE(c.diagnostics().resting[0]);
  EXPECT_LT(c.diagnostics().foot_acceleration_desired[0][0], -1.0);
  EXPECT_NEAR(c.diagnostics().foot_acceleration_desired[1][0], 0.0, 1e-9);
  // Loaded just above the threshold: rests again.
  s.feet[0].normal_force = 1.1 * threshold;
  c.prepare(s, ref, p);
  EXPECT_TRUE(c.diagnostics().resting[0]);
  // Not flagged (a late detector) but loaded above support_force_fraction: a support, resting.
  // Not flagged and lightly loaded: no support in kAuto, so not resting.
  s.feet[0].in_contact = false;
  c.prepare(s, ref, p);
  EXPECT_FALSE(p.feet[0].in_contact);
  EXPECT_FALSE(c.diagnostics().resting[0]);
  s.feet[0].normal_force = 250.0;
  c.prepare(s, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);
  EXPECT_TRUE(c.diagnostics().resting[0]);
  // A planned support (FOOT_SUPPORT) is a support at any load, and rests only when loaded.
  ref.feet[0].mode = FootMode::kSupport;
  s.feet[0].normal_force = 0.0;
  c.prepare(s, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);
  EXPECT_FALSE(c.diagnostics().resting[0]);
}

TEST(BalanceController, AFootBackFromTheAirRestsOnlyOnceItCarriesTheTouchDownLoad) {
  // ControllerConfig::resting_touchdown_force_fraction: a foot whose contact flag was off for
  // longer than resting_touchdown_air_time comes down with its swing's velocity; between the two
  // thresholds it is held where it last rested (pulled back against its velocity), above the
  // touch-down one it rests, and then keeps resting down to resting_force_fraction. A foot that
  // never left the ground (the flag off for less than the air time) keeps the low threshold.
  BalanceController c = make_controller();
  const ControllerConfig cfg;
  ASSERT_GT(cfg.resting_touchdown_force_fraction, 2.0 * cfg.resting_force_fraction);
  const double weight = humanoid().model.total_mass * humanoid().model.gravity.norm();
  const double between =
      0.5 * (cfg.resting_force_fraction + cfg.resting_touchdown_force_fraction) * weight;
  const int air_ticks = static_cast<int>(std::lround(cfg.resting_touchdown_air_time / cfg.dt));
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  ref.feet[0].mode = FootMode::kSupport;  // planned: a support whatever its flag
  contact::ContactProblem p;
  c.prepare(s, ref, p);
  ASSERT_TRUE(c.diagnostics().resting[0]);
  // Never left the ground: the flag off for one tick less than the air time, back with the load
  // between the thresholds: rests.
  s.feet[0].in_contact = false;
  s.feet[0].normal_force = 0.0;
  for (int k = 0; k < air_ticks; ++k) c.prepare(s, ref, p);
  EXPECT_FALSE(c.diagnostics().resting[0]);
  s.feet[0].in_contact = true;
  s.feet[0].normal_force = between;
  c.prepare(s, ref, p);
  EXPECT_TRUE(c.diagnostics().resting[0]);
  // Back from the air (one tick more than the air time), moving forward 0.1 m/s: between the
  // thresholds it is held (pulled back), not resting; tick after tick.
  s.feet[0].in_contact = false;
  s.feet[0].normal_force = 0.0;
  for (int k = 0; k < air_ticks + 1; ++k) c.prepare(s, ref, p);
  RobotState moving = s;
  moving.v_WB.x() += 0.1;
  moving.feet[0].in_contact = true;
  moving.feet[0].normal_force = between;
  for (int k = 0; k < 5; ++k) {
    c.prepare(moving, ref, p);
    EXPECT_TRUE(p.feet[0].in_contact);
    EXPECT_FALSE(c.diagnostics().resting[0]) << "tick " << k;
    EXPECT_LT(c.diagnostics().foot_acceleration_desired[0][0], -1.0);
  }
  // Above the touch-down threshold: rests (zero acceleration asked with v_d = v) ...
  moving.feet[0].normal_force = 1.1 * cfg.resting_touchdown_force_fraction * weight;
  c.prepare(moving, ref, p);
  EXPECT_TRUE(c.diagnostics().resting[0]);
  EXPECT_NEAR(c.diagnostics().foot_acceleration_desired[0][0], 0.0, 1e-9);
  // ... and keeps resting with the load back between the thresholds, down to the low one.
  moving.feet[0].normal_force = between;
  c.prepare(moving, ref, p);
  EXPECT_TRUE(c.diagnostics().resting[0]);
  moving.feet[0].normal_force = 0.9 * cfg.resting_force_fraction * weight;
  c.prepare(moving, ref, p);
  EXPECT_FALSE(c.diagnostics().resting[0]);
  // reset() starts a standing robot: the low threshold.
  c.reset();
  s = test::standing_state(c);
  s.feet[0].normal_force = between;
  c.prepare(s, ref, p);
  EXPECT_TRUE(c.diagnostics().resting[0]);
}

// FootGains::unloaded_kp, unloaded_kd: a foot held where it last rested (no target), back from
// the air (flag off longer than resting_touchdown_air_time) and without load gets them on its
// horizontal rows; height and tilt, a loaded foot, a foot off the ground for less than the air
// time (also right after reset()) and a foot with a target keep kp, kd. Checked against eq (36)
// written out for a pure translation of the robot (the foot moved by d at velocity v from where
// it rested): a = -k_p d - k_d v per row, on seeded random d, v.
TEST(BalanceController, AHeldFootBackFromTheAirGetsTheUnloadedGainsHorizontally) {
  ControllerConfig cfg;
  cfg.foot.unloaded_kp = 400.0;
  cfg.foot.unloaded_kd = 40.0;
  ASSERT_NE(cfg.foot.unloaded_kp, cfg.foot.kp);
  BalanceController c = make_controller(cfg);
  const double weight = humanoid().model.total_mass * humanoid().model.gravity.norm();
  const int air_ticks = static_cast<int>(std::lround(cfg.resting_touchdown_air_time / cfg.dt));
  BalanceReference ref = c.make_reference();
  ref.feet[0].mode = FootMode::kSupport;
  contact::ContactProblem p;
  std::mt19937 rng(3);
  // The standing robot rests, then foot 0 leaves the ground for `off_ticks` ticks (the last one
  // with the whole robot translated by d and moving at v); returns foot 0's a_d.
  auto a_d_after = [&](int off_ticks, const Eigen::Vector3d& d, const Eigen::Vector3d& v,
                       double load, bool cop_outside) {
    c.reset();
    RobotState s = test::standing_state(c);
    c.prepare(s, ref, p);
    EXPECT_TRUE(c.diagnostics().resting[0]);
    s.feet[0].in_contact = false;
    s.feet[0].normal_force = 0.0;
    for (int k = 0; k < off_ticks - 1; ++k) c.prepare(s, ref, p);
    RobotState moved = s;
    moved.X_WB.p += d;
    moved.v_WB = v;
    moved.feet[0].normal_force = load;
    if (cop_outside) moved.feet[0].cop_W += Eigen::Vector3d(1.0, 0.0, 0.0);
    c.prepare(moved, ref, p);
    EXPECT_FALSE(c.diagnostics().resting[0]);
    return model::Motion(c.diagnostics().foot_acceleration_desired[0]);
  };
  auto expect_rows = [](const model::Motion& a, double kp_xy, double kd_xy, double kp_z,
                        double kd_z, const Eigen::Vector3d& d, const Eigen::Vector3d& v,
                        const char* what) {
    for (int r = 0; r < 3; ++r) {
      const double kp = r < 2 ? kp_xy : kp_z, kd = r < 2 ? kd_xy : kd_z;
      const double expected = -kp * d[r] - kd * v[r];
      EXPECT_NEAR(a[r], expected, 1e-9 * (1.0 + std::abs(expected))) << what << ", row " << r;
    }
    EXPECT_LT(a.tail<3>().norm(), 1e-9) << what << ": no tilt asked";
  };
  const double touch_load = 2.0 * cfg.resting_touchdown_force_fraction * weight;
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::Vector3d d(test::uniform(rng, -0.02, 0.02), test::uniform(rng, -0.02, 0.02),
                            test::uniform(rng, 0.0, 0.002));  // below the release height
    const Eigen::Vector3d v = test::random_vec3(rng, 0.2);
    const FootGains& k = cfg.foot;
    expect_rows(a_d_after(air_ticks + 1, d, v, 0.0, false), k.unloaded_kp, k.unloaded_kd, k.kp,
                k.kd, d, v, "back from the air, no load");
    expect_rows(a_d_after(air_ticks, d, v, 0.0, false), k.kp, k.kd, k.kp, k.kd, d, v,
                "off for the air time only");
    expect_rows(a_d_after(air_ticks + 1, d, v, touch_load, true), k.kp, k.kd, k.kp, k.kd, d, v,
                "back from the air with load (CoP outside: not resting)");
  }
  // A foot with a target keeps kp, kd (its target is where it stood).
  ref.feet[0].has_target = true;
  ref.feet[0].X_WF_target = test::standing_state(c).feet[0].X_WF;
  const Eigen::Vector3d d(0.01, -0.015, 0.001), v(0.1, 0.05, 0.0);
  expect_rows(a_d_after(air_ticks + 1, d, v, 0.0, false), cfg.foot.kp, cfg.foot.kd, cfg.foot.kp,
              cfg.foot.kd, d, v, "with a target");
}

TEST(BalanceController, APlannedSupportLiftedOffTheGroundLeavesTheContactProblem) {
  // ControllerConfig::planned_support_release: a planned support (FOOT_SUPPORT) measured off the
  // ground -- no contact flag, no load, its foot frame risen from where it last rested -- for
  // planned_support_release leaves the contact problem (no ground force for a foot in the air)
  // until it touches again, and is held where it last rested. A foot that rests on the ground
  // unflagged (no rise) stays.
  const ControllerConfig cfg;
  BalanceController c = make_controller(cfg);
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  ref.feet[0].mode = ref.feet[1].mode = FootMode::kSupport;
  contact::ContactProblem p;
  c.prepare(s, ref, p);  // both rest: the hold poses
  const int release_ticks = static_cast<int>(std::lround(cfg.planned_support_release / cfg.dt));
  ASSERT_GE(release_ticks, 2);

  // The right foot unflagged and unloaded, on the ground: stays a support however long.
  RobotState resting = s;
  resting.feet[0].in_contact = false;
  resting.feet[0].normal_force = 0.0;
  for (int i = 0; i < 3 * release_ticks; ++i) c.prepare(resting, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);

  // Lifted: the whole robot 1 cm up (above planned_support_release_height), the left foot still
  // flagged and loaded. The right foot leaves after planned_support_release, not before.
  ASSERT_LT(cfg.planned_support_release_height, 0.01);
  RobotState lifted = resting;
  lifted.X_WB.p.z() += 0.01;
  for (int i = 0; i < release_ticks - 1; ++i) {
    c.prepare(lifted, ref, p);
    EXPECT_TRUE(p.feet[0].in_contact) << "tick " << i;
  }
  c.prepare(lifted, ref, p);
  EXPECT_FALSE(p.feet[0].in_contact);
  EXPECT_TRUE(p.feet[1].in_contact);
  EXPECT_FALSE(c.diagnostics().support[0]);
  // Held where it rested: pulled back down (eq (36) towards the hold pose 1 cm below).
  EXPECT_LT(c.diagnostics().foot_acceleration_desired[0][2], -0.5);
  // It touches again (flag): a support at once.
  lifted.feet[0].in_contact = true;
  c.prepare(lifted, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);
  // Or loaded above support_force_fraction without a flag.
  lifted.feet[0].in_contact = false;
  for (int i = 0; i < 2 * release_ticks; ++i) c.prepare(lifted, ref, p);
  ASSERT_FALSE(p.feet[0].in_contact);
  lifted.feet[0].normal_force = 1.1 * cfg.support_force_fraction * p.mass * 9.81;
  c.prepare(lifted, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);

  // planned_support_release 0: the plan alone (never released).
  ControllerConfig never = cfg;
  never.planned_support_release = 0.0;
  BalanceController c0 = make_controller(never);
  c0.prepare(s, ref, p);
  lifted.feet[0].normal_force = 0.0;
  for (int i = 0; i < 3 * release_ticks; ++i) c0.prepare(lifted, ref, p);
  EXPECT_TRUE(p.feet[0].in_contact);

  // Bad values are refused naming the key.
  ControllerConfig bad = cfg;
  bad.planned_support_release = -0.01;
  EXPECT_THROW(bad.validate(), ConfigError);
  bad = cfg;
  bad.planned_support_release_height = std::nan("");
  EXPECT_THROW(bad.validate(), ConfigError);
}

// Central second difference of the foot frame along q(t) = q (+) (v t + qdd t^2 / 2).
model::Motion foot_acceleration_fd(const model::Model& model, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& v, const Eigen::VectorXd& qdd, int frame,
                                   double h) {
  model::Data data(model);
  Eigen::VectorXd qp(model.nq), qm(model.nq);
  model::integrate(model, q, h * v + 0.5 * h * h * qdd, 1.0, qp);
  model::integrate(model, q, -h * v + 0.5 * h * h * qdd, 1.0, qm);
  model::forward_kinematics(model, data, q);
  const model::SE3 X0 = model::frame_placement(model, data, frame);
  model::forward_kinematics(model, data, qp);
  const model::SE3 Xp = model::frame_placement(model, data, frame);
  model::forward_kinematics(model, data, qm);
  const model::SE3 Xm = model::frame_placement(model, data, frame);
  model::Motion a;
  a.head<3>() = (Xp.p - 2.0 * X0.p + Xm.p) / (h * h);
  a.tail<3>() =
      (model::so3_log(Xp.R * X0.R.transpose()) + model::so3_log(Xm.R * X0.R.transpose())) / (h * h);
  return a;
}

TEST(BalanceController, Eq33OutputRealisesFootAccelerationsAndAdmissibleMomentum) {
  BalanceController c = make_controller();
  const auto& model = c.model();
  contact::SequentialOptimizer opt;
  JointCommand cmd = c.make_command();
  std::mt19937 rng(2);
  int checked = 0;
  for (int trial = 0; trial < 20; ++trial) {
    RobotState s = test::random_state(c, rng, 0.1, 0.3);
    BalanceReference ref = c.make_reference();
    // Swing targets for some trials: the constraint must hold for any a_d.
    if (trial % 3 == 1) {
      ref.feet[1].mode = FootMode::kSwing;
      ref.feet[1].has_target = true;
      ref.feet[1].X_WF_target = model::SE3(test::random_rotation(rng, 0.2) * s.feet[1].X_WF.R,
                                           s.feet[1].X_WF.p + test::random_vec3(rng, 0.05));
    }
    contact::ContactProblem p;
    contact::ContactSolution sol;
    c.prepare(s, ref, p);
    opt.solve(p, sol);
    ASSERT_NE(sol.status, contact::ContactStatus::kInvalidInput);
    c.finish(sol, cmd);
    const auto& d = c.diagnostics();
    ASSERT_EQ(d.qp_status, contact::SolverStatus::kOptimal) << trial;
    ASSERT_EQ(d.contact_source, ContactSource::kSolution);
    if (d.active_bounds > 0 || d.bounds_dropped) continue;
    ++checked;
    const Eigen::VectorXd& qdd = c.generalized_acceleration();
    // (1) Foot constraints: finite differences of the model's kinematics.
    for (int i = 0; i < 2; ++i) {
      const model::Motion fd =
          foot_acceleration_fd(model, c.configuration(), c.generalized_velocity(), qdd,
                               c.robot().feet[i].frame_id, 1e-4);
      const model::Motion& a_d = d.foot_acceleration_desired[i];
      EXPECT_LT((fd - a_d).norm(), 1e-4 * (1.0 + a_d.norm())) << trial << " foot " << i << "\n"
                                                              << fd.transpose() << "\n"
                                                              << a_d.transpose();
    }
    // (2) Momentum identity: the admissible rate is the optimiser's and is realised by qdd.
    model::Vector6 h_opt;
    h_opt << sol.k_dot_admissible, sol.l_dot_admissible;
    EXPECT_LT((d.hdot_admissible - h_opt).norm(), 1e-6 * (1.0 + h_opt.norm()));
    const double scale = p.mass * 9.81;
    EXPECT_LT((d.hdot_achieved - d.hdot_admissible).norm(), 2e-3 * scale)
        << trial << "\n achieved " << d.hdot_achieved.transpose() << "\n admissible "
        << d.hdot_admissible.transpose();
    // (3) Newton-Euler of the whole body: the RNEA base wrench is the momentum residual moved to
    // the base origin and base axes.
    const Eigen::VectorXd& tau = c.inverse_dynamics_torque();
    const model::Vector6 e = d.hdot_achieved - d.hdot_admissible;  // [k; l] about the CoM
    const Eigen::Vector3d pB = c.configuration().head<3>();
    const Eigen::Matrix3d R = s.X_WB.R;
    const Eigen::Vector3d f_B = R.transpose() * e.tail<3>();
    const Eigen::Vector3d t_B = R.transpose() * (e.head<3>() + (d.com_W - pB).cross(e.tail<3>()));
    EXPECT_LT((tau.head<3>() - f_B).norm(), 1e-7 * scale) << trial;
    EXPECT_LT((tau.segment<3>(3) - t_B).norm(), 1e-7 * scale) << trial;
    EXPECT_LT(d.base_wrench_residual, 5e-3 * scale);
    // (4) Command: tau_ff = joint rows of the inverse dynamics (within the effort limits).
    for (int j = 0; j < model.njoints; ++j)
      EXPECT_NEAR(cmd.tau_ff[j],
                  std::clamp(tau[6 + j], -model.limits[j].effort, model.limits[j].effort), 1e-12);
    EXPECT_EQ(cmd.mode, CommandMode::kTorque);
  }
  EXPECT_GT(checked, 10);
}

TEST(BalanceController, StandingStillNeedsOnlyGravityCompensation) {
  // At the nominal posture with the CoM target equal to the CoM, the robot at rest: desired and
  // admissible rates ~0, qdd ~0, and the base residual ~0 (the wrenches carry the weight).
  BalanceController c = make_controller();
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  contact::ContactProblem p;
  c.prepare(s, ref, p);
  ref.has_com_target = true;
  ref.com_W = p.com;
  c.reset();
  c.prepare(s, ref, p);
  contact::SequentialOptimizer opt;
  contact::ContactSolution sol;
  opt.solve(p, sol);
  EXPECT_EQ(sol.status, contact::ContactStatus::kOk);
  JointCommand cmd = c.make_command();
  c.finish(sol, cmd);
  const auto& d = c.diagnostics();
  EXPECT_LT(d.hdot_desired.norm(), 1e-9);
  // Regularisation bias of the optimiser only (its kOk tolerance: contact::kRateTolerance m g).
  const double tol = contact::kRateTolerance * p.mass * 9.81;
  EXPECT_LT(d.hdot_admissible.norm(), tol);
  EXPECT_LT(c.generalized_acceleration().norm(), 0.5);
  EXPECT_LT(d.base_wrench_residual, 1.0);
  // The legs carry the weight: sum of vertical forces = m g.
  EXPECT_NEAR(d.foot_wrench_W[0][2] + d.foot_wrench_W[1][2], p.mass * 9.81, tol);
  // References start at the measured state.
  EXPECT_LT((cmd.q_ref - s.q).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(BalanceController, FallbackReusesThenDistributesGravity) {
  ControllerConfig cfg;
  cfg.fallback.max_reuse_ticks = 2;
  BalanceController c = make_controller(cfg);
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  contact::ContactProblem p;
  contact::ContactSolution sol;
  contact::SequentialOptimizer opt;
  JointCommand cmd = c.make_command();
  c.prepare(s, ref, p);
  opt.solve(p, sol);
  c.finish(sol, cmd);
  const auto first = c.diagnostics().foot_wrench_W;
  for (int k = 0; k < 2; ++k) {
    c.prepare(s, ref, p);
    c.finish_fallback(cmd);
    EXPECT_EQ(c.diagnostics().contact_source, ContactSource::kReusedSolution);
    EXPECT_EQ(c.diagnostics().foot_wrench_W[0], first[0]);
  }
  c.prepare(s, ref, p);
  c.finish_fallback(cmd);
  EXPECT_EQ(c.diagnostics().contact_source, ContactSource::kGravityDistribution);
  EXPECT_EQ(c.diagnostics().late_solutions, 3u);
  EXPECT_EQ(cmd.mode, CommandMode::kTorque);
  // An unusable solution is a fallback too.
  contact::ContactSolution bad;
  bad.status = contact::ContactStatus::kSolverFailure;
  c.prepare(s, ref, p);
  c.finish(bad, cmd);
  EXPECT_EQ(c.diagnostics().late_solutions, 4u);
  EXPECT_NE(c.diagnostics().contact_source, ContactSource::kSolution);
}

TEST(ContactFallback, GravityDistributionIsStaticEquilibrium) {
  std::mt19937 rng(4);
  for (int trial = 0; trial < 50; ++trial) {
    contact::ContactProblem p;
    p.mass = test::uniform(rng, 10, 100);
    p.com = test::random_vec3(rng, 0.2) + Eigen::Vector3d(0, 0, 0.8);
    p.feet[0].in_contact = trial % 3 != 0;
    p.feet[1].in_contact = trial % 3 != 1;
    p.feet[0].p_WF = Eigen::Vector3d(0, -0.1, 0.08) + test::random_vec3(rng, 0.05);
    p.feet[1].p_WF = Eigen::Vector3d(0, 0.1, 0.08) + test::random_vec3(rng, 0.05);
    p.feet[0].R_WF = test::random_rotation(rng, 0.2);
    p.feet[1].R_WF = test::random_rotation(rng, 0.2);
    contact::ContactSolution s;
    gravity_distribution(p, s);
    Eigen::Vector3d f = Eigen::Vector3d::Zero(), k = Eigen::Vector3d::Zero();
    for (int i = 0; i < 2; ++i) {
      f += s.feet[i].force_W;
      k += (p.feet[i].p_WF - p.com).cross(s.feet[i].force_W) + s.feet[i].torque_ankle_W;
      if (!p.feet[i].in_contact) continue;
      // The reported CoP reproduces the ankle torque (paper eq. (19)).
      const auto& ft = p.feet[i];
      const Eigen::Vector3d d(s.feet[i].cop_F.x(), s.feet[i].cop_F.y(), -ft.ankle_height);
      const Eigen::Vector3d tau = (ft.R_WF * d).cross(s.feet[i].force_W) +
                                  ft.R_WF * Eigen::Vector3d(0, 0, s.feet[i].normal_torque);
      EXPECT_LT((tau - s.feet[i].torque_ankle_W).norm(), 1e-9);
    }
    EXPECT_LT((f + p.mass * p.gravity).norm(), 1e-9);
    EXPECT_LT(k.norm(), 1e-9);
    EXPECT_LT(s.k_dot_admissible.norm() + s.l_dot_admissible.norm(), 1e-9);
  }
  contact::ContactProblem none;
  none.mass = 50;
  none.feet[0].in_contact = none.feet[1].in_contact = false;
  contact::ContactSolution s;
  gravity_distribution(none, s);
  EXPECT_EQ(s.status, contact::ContactStatus::kNoContact);
  EXPECT_LT((s.l_dot_admissible - 50 * none.gravity).norm(), 1e-12);
}

TEST(BalanceController, ReferencesIntegrateAccelerationsAndStayNearTheState) {
  ControllerConfig paper;  // the paper's integration (the legs' leak: the test below)
  paper.feedback.support_leg_leak_hz = 0.0;
  paper.feedback.internal_force_leak_hz = 0.0;
  BalanceController c = make_controller(paper);
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  contact::ContactProblem p;
  contact::ContactSolution sol;
  contact::SequentialOptimizer opt;
  JointCommand cmd = c.make_command();
  ref.has_upper_body_q = true;
  const int elbow = c.model().joint_index("l_elbow");
  ref.upper_body_q[elbow] -= 0.5;  // ask the arm to move: large qdd on the elbow
  Eigen::VectorXd q_ref_prev, qd_ref_prev;
  for (int k = 0; k < 200; ++k) {
    c.prepare(s, ref, p);
    opt.solve(p, sol);
    c.finish(sol, cmd);
    const auto& qdd = c.generalized_acceleration();
    if (k > 0 && c.diagnostics().reference_clamps == 0) {
      // theta_dot* += qdd dt; theta* += theta_dot* dt (semi-implicit Euler).
      EXPECT_LT((cmd.qd_ref - (qd_ref_prev + 1e-3 * qdd.tail(c.num_joints()))).norm(), 1e-12);
      EXPECT_LT((cmd.q_ref - (q_ref_prev + 1e-3 * cmd.qd_ref)).norm(), 1e-12);
    }
    q_ref_prev = cmd.q_ref;
    qd_ref_prev = cmd.qd_ref;
    // The robot does not move (state frozen): the references saturate at the configured errors.
    EXPECT_LE((cmd.q_ref - s.q).cwiseAbs().maxCoeff(), 0.05 + 1e-12);
    EXPECT_LE((cmd.qd_ref - s.qd).cwiseAbs().maxCoeff(), 0.5 + 1e-12);
  }
  EXPECT_LT(cmd.q_ref[elbow] - s.q[elbow], -0.04);  // it moves the way the reference asks
  EXPECT_GT(c.diagnostics().reference_clamps, 0);
}

/// The same references and torques, to the bit.
void expect_same_commands(const JointCommand& a, const JointCommand& b) {
  EXPECT_EQ(a.q_ref, b.q_ref);
  EXPECT_EQ(a.qd_ref, b.qd_ref);
  EXPECT_EQ(a.tau_ff, b.tau_ff);
}

/// A negative and a NaN value, put in by `set`, are refused by validate() with `key` named.
void expect_refused_naming(const std::string& key,
                           const std::function<void(ControllerConfig&, double)>& set) {
  for (const double bad_value : {-1.0, std::nan("")}) {
    ControllerConfig bad;
    set(bad, bad_value);
    try {
      bad.validate();
      ADD_FAILURE() << key << " = " << bad_value << " accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

/// A tick of the reference-rule tests below: the legs' measured joints wander off the plan (a
/// drifting loop closure: q and qd), then both controllers tick on that same state.
void wander_and_tick(RobotState& s, const std::vector<int>& legs, std::mt19937& rng,
                     const BalanceReference& ref, contact::SequentialOptimizer& opt,
                     BalanceController& a, JointCommand& cmd_a, BalanceController& b,
                     JointCommand& cmd_b) {
  std::uniform_real_distribution<double> off(-0.02, 0.02);
  for (int j : legs) {
    s.q[j] += off(rng) * 0.1;
    s.qd[j] = off(rng);
  }
  contact::ContactProblem p;
  contact::ContactSolution sol;
  a.prepare(s, ref, p);
  opt.solve(p, sol);
  a.finish(sol, cmd_a);
  b.prepare(s, ref, p);
  opt.solve(p, sol);
  b.finish(sol, cmd_b);
}

/// The bench of the reference-rule tests below: a controller with the rule under test (`cfg`)
/// and one with the paper's integration, on the standing state; the left elbow's posture target
/// moves (its references integrate qdd); with `one_unloaded` the right foot touches with 5 % of
/// the weight (below support_force_fraction: not a load-bearing foot).
struct ReferenceRuleBench {
  BalanceController leaky, plain;
  RobotState s;
  BalanceReference ref;
  int elbow = -1;
  contact::SequentialOptimizer opt;
  JointCommand cmd, cmd_plain;

  ReferenceRuleBench(const ControllerConfig& cfg, bool one_unloaded)
      : leaky(make_controller(cfg)), plain(make_controller(paper())) {
    s = test::standing_state(leaky);
    const model::Model& m = leaky.model();
    if (one_unloaded) s.feet[1].normal_force = 0.05 * m.total_mass * m.gravity.norm();
    ref = leaky.make_reference();
    ref.has_upper_body_q = true;
    elbow = m.joint_index("l_elbow");
    ref.upper_body_q[elbow] -= 0.3;
    cmd = leaky.make_command();
    cmd_plain = plain.make_command();
  }
  static ControllerConfig paper() {
    ControllerConfig c;
    c.feedback.support_leg_leak_hz = 0.0;
    c.feedback.internal_force_leak_hz = 0.0;
    return c;
  }
  void tick(const std::vector<int>& legs, std::mt19937& rng) {
    wander_and_tick(s, legs, rng, ref, opt, leaky, cmd, plain, cmd_plain);
  }
};

// FeedbackConfig::support_leg_leak_hz: while both feet bear load, a leg's references decay
// towards the measured joints before qdd_a is integrated; the arms always integrate; with one
// foot unloaded, or the option off, nothing changes (bit for bit the paper's integration).
TEST(BalanceController, BothLoadedLegsReferencesLeakTowardsTheMeasuredJoints) {
  std::mt19937 rng(1717);
  std::uniform_real_distribution<double> hz(5.0, 500.0);
  for (int trial = 0; trial < 4; ++trial) {
    SCOPED_TRACE(trial);
    ControllerConfig cfg;
    cfg.feedback.support_leg_leak_hz = hz(rng);
    cfg.feedback.internal_force_leak_hz = 0.0;  // this rule alone (the split: the test below)
    const double keep = std::exp(-2.0 * M_PI * cfg.feedback.support_leg_leak_hz * 1e-3);
    const bool one_unloaded = trial == 3;
    ReferenceRuleBench b(cfg, one_unloaded);
    const BalanceController& leaky = b.leaky;
    const RobotState& s = b.s;
    const JointCommand &cmd = b.cmd, &cmd_plain = b.cmd_plain;
    const int elbow = b.elbow;
    std::vector<int> legs;
    for (const char* j : {"l_hip_pitch", "l_knee", "r_hip_roll", "r_ankle_pitch"})
      legs.push_back(leaky.model().joint_index(j));
    Eigen::VectorXd q_ref_prev, qd_ref_prev;
    double leg_error_max = 0.0;
    // The rule by hand, the clamps of FeedbackConfig included (the frozen arm reaches them).
    auto step = [&](double keep_j, double ref_prev, double meas, double rate, double max_err) {
      return meas + std::clamp(keep_j * (ref_prev - meas) + rate * 1e-3, -max_err, max_err);
    };
    for (int k = 0; k < 60; ++k) {
      b.tick(legs, rng);
      const Eigen::VectorXd qdd = leaky.generalized_acceleration().tail(leaky.num_joints());
      if (k > 0) {
        std::vector<std::pair<int, double>> checks{{elbow, 1.0}};  // the arm: pure integration
        for (int j : legs) checks.emplace_back(j, one_unloaded ? 1.0 : keep);
        for (const auto& [j, kk] : checks) {
          const double vr = step(kk, qd_ref_prev[j], s.qd[j], qdd[j], 0.5);
          EXPECT_NEAR(cmd.qd_ref[j], vr, 1e-12) << j;
          EXPECT_NEAR(cmd.q_ref[j], step(kk, q_ref_prev[j], s.q[j], vr, 0.05), 1e-12) << j;
        }
      }
      for (int j : legs)
        leg_error_max = std::max(leg_error_max, std::abs(cmd.qd_ref[j] - s.qd[j]));
      q_ref_prev = cmd.q_ref;
      qd_ref_prev = cmd.qd_ref;
    }
    if (one_unloaded) {
      expect_same_commands(cmd, cmd_plain);  // both integrate: the same commands to the bit
    } else {
      // The plain references carry the wandering of 60 ticks; the leaky ones a few ticks' worth.
      EXPECT_GT((cmd.q_ref - cmd_plain.q_ref).cwiseAbs().maxCoeff(), 1e-4);
      EXPECT_LT(leg_error_max, 0.5) << "never at the velocity clamp";
    }
  }
  expect_refused_naming("feedback.support_leg_leak_hz",
                        [](ControllerConfig& c, double v) { c.feedback.support_leg_leak_hz = v; });
}

// FeedbackConfig::velocity_leak_hz: every joint's theta_dot* (the arms', and the legs' with both
// feet loaded or one unloaded) decays towards the measured velocity before qdd_a is integrated;
// theta* integrates the leaked theta_dot* as before. Off, the paper's commands to the bit.
TEST(BalanceController, EveryJointsVelocityReferenceLeaksTowardsTheMeasuredVelocity) {
  std::mt19937 rng(2027);
  std::uniform_real_distribution<double> hz(0.2, 50.0);
  for (int trial = 0; trial < 4; ++trial) {
    SCOPED_TRACE(trial);
    ControllerConfig cfg = ReferenceRuleBench::paper();  // this rule alone
    cfg.feedback.velocity_leak_hz = trial == 3 ? 0.0 : hz(rng);
    const double keep = std::exp(-2.0 * M_PI * cfg.feedback.velocity_leak_hz * 1e-3);
    ReferenceRuleBench b(cfg, /*one_unloaded=*/trial == 1);
    const BalanceController& leaky = b.leaky;
    const RobotState& s = b.s;
    std::vector<int> legs;
    for (const char* j : {"l_hip_pitch", "l_knee", "r_hip_roll", "r_ankle_pitch"})
      legs.push_back(leaky.model().joint_index(j));
    std::vector<int> checked = legs;
    checked.push_back(b.elbow);
    Eigen::VectorXd q_ref_prev, qd_ref_prev;
    for (int k = 0; k < 60; ++k) {
      b.tick(legs, rng);
      const Eigen::VectorXd qdd = leaky.generalized_acceleration().tail(leaky.num_joints());
      if (k > 0) {
        for (int j : checked) {
          // By hand, FeedbackConfig's clamps included (the moving elbow reaches them).
          const double vr =
              s.qd[j] + std::clamp(keep * (qd_ref_prev[j] - s.qd[j]) + qdd[j] * 1e-3, -0.5, 0.5);
          EXPECT_NEAR(b.cmd.qd_ref[j], vr, 1e-12) << j;
          const double pr = s.q[j] + std::clamp(q_ref_prev[j] + vr * 1e-3 - s.q[j], -0.05, 0.05);
          EXPECT_NEAR(b.cmd.q_ref[j], pr, 1e-12) << j;
        }
      }
      q_ref_prev = b.cmd.q_ref;
      qd_ref_prev = b.cmd.qd_ref;
    }
    if (trial == 3)
      expect_same_commands(b.cmd, b.cmd_plain);
    else
      EXPECT_GT((b.cmd.qd_ref - b.cmd_plain.qd_ref).cwiseAbs().maxCoeff(), 1e-4);
  }
  expect_refused_naming("feedback.velocity_leak_hz",
                        [](ControllerConfig& c, double v) { c.feedback.velocity_leak_hz = v; });
}

// FeedbackConfig::touchdown_follow_fraction: from a support's touch-down until the contact
// solution plans that foot more than the fraction of the weight, its leg's references are pulled
// towards the measured joints at touchdown_follow_hz after the integration; the other leg and the
// arms integrate as before, and once the plan has loaded the foot the leg integrates again even
// if the plan unloads it later (only a new touch-down restarts the following). Off (0): the
// touch-down tick's reset only, every tick the same as with it on before the touch-down.
TEST(BalanceController, ALandedLegFollowsItsJointsUntilThePlanLoadsItsFoot) {
  ControllerConfig cfg;
  cfg.feedback.support_leg_leak_hz = 0.0;    // these rules alone
  cfg.feedback.internal_force_leak_hz = 0.0;
  ASSERT_GT(cfg.feedback.touchdown_follow_fraction, 0.0);
  ControllerConfig off = cfg;
  off.feedback.touchdown_follow_fraction = 0.0;
  BalanceController a = make_controller(cfg), b = make_controller(off);
  const model::Model& m = a.model();
  const double weight = m.total_mass * m.gravity.norm();
  const double keep = std::exp(-2.0 * M_PI * cfg.feedback.touchdown_follow_hz * cfg.dt);
  std::vector<int> right_leg, others;
  for (int j = 0; j < m.njoints; ++j) {
    const std::string& name = m.joint_names[j];
    const bool leg = name.rfind("r_hip", 0) == 0 || name.rfind("r_knee", 0) == 0 ||
                     name.rfind("r_ankle", 0) == 0;
    (leg ? right_leg : others).push_back(j);
  }
  ASSERT_EQ(right_leg.size(), 6u);
  const BalanceReference ref = a.make_reference();  // automatic feet
  RobotState s = test::standing_state(a);
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> off_q(-0.002, 0.002), off_qd(-0.02, 0.02);
  contact::SequentialOptimizer opt;
  JointCommand ca = a.make_command(), cb = b.make_command();
  // One tick of both controllers on the same state and the same solution, the right foot's
  // planned force set to `right_load` (times its normal) when it is a support; the joints move
  // a little every tick, so the references and the measured state differ.
  auto tick = [&](bool right_touching, double right_load) {
    for (int j = 0; j < m.njoints; ++j) s.q[j] += off_q(rng), s.qd[j] = off_qd(rng);
    s.feet[0].in_contact = right_touching;
    s.feet[0].normal_force = right_touching ? 0.001 * weight : 0.0;
    contact::ContactProblem p;
    contact::ContactSolution sol;
    a.prepare(s, ref, p);
    contact::ContactProblem pb;
    b.prepare(s, ref, pb);
    EXPECT_EQ(p.feet[0].in_contact, right_touching);
    opt.solve(p, sol);
    if (p.feet[0].in_contact) sol.feet[0].force_W = right_load * p.feet[0].R_WF.col(2);
    a.finish(sol, ca);
    b.finish(sol, cb);
  };
  // The rule by hand: the paper's integration (with FeedbackConfig's clamps), then the
  // following when `follow`.
  auto expect_rule = [&](const Eigen::VectorXd& q_prev, const Eigen::VectorXd& qd_prev,
                         const JointCommand& c, const BalanceController& ctl, bool follow,
                         const char* what) {
    const Eigen::VectorXd qdd = ctl.generalized_acceleration().tail(ctl.num_joints());
    for (int j : right_leg) {
      double vr = s.qd[j] + std::clamp(qd_prev[j] - s.qd[j] + qdd[j] * cfg.dt,
                                       -cfg.feedback.max_velocity_error,
                                       cfg.feedback.max_velocity_error);
      double pr = s.q[j] + std::clamp(q_prev[j] - s.q[j] + vr * cfg.dt,
                                      -cfg.feedback.max_position_error,
                                      cfg.feedback.max_position_error);
      if (follow) {
        vr = s.qd[j] + keep * (vr - s.qd[j]);
        pr = s.q[j] + keep * (pr - s.q[j]);
      }
      EXPECT_NEAR(c.qd_ref[j], vr, 1e-12) << what << ", joint " << m.joint_names[j];
      EXPECT_NEAR(c.q_ref[j], pr, 1e-12) << what << ", joint " << m.joint_names[j];
    }
  };
  // The right foot in the air: no support, the same commands either way.
  for (int k = 0; k < 5; ++k) tick(false, 0.0);
  expect_same_commands(ca, cb);
  // Touch-down, planned no load: the touch-down reset in both, the following in `a` only.
  tick(true, 0.0);
  for (int j : right_leg) {
    EXPECT_NEAR(ca.q_ref[j] - s.q[j], keep * (cb.q_ref[j] - s.q[j]), 1e-12);
    EXPECT_NEAR(ca.qd_ref[j] - s.qd[j], keep * (cb.qd_ref[j] - s.qd[j]), 1e-12);
  }
  for (int j : others) {
    EXPECT_EQ(ca.q_ref[j], cb.q_ref[j]);
    EXPECT_EQ(ca.qd_ref[j], cb.qd_ref[j]);
  }
  // Still planned no more than the fraction: it keeps following.
  for (int k = 0; k < 3; ++k) {
    const Eigen::VectorXd q_prev = ca.q_ref, qd_prev = ca.qd_ref;
    tick(true, 0.9 * cfg.feedback.touchdown_follow_fraction * weight);
    expect_rule(q_prev, qd_prev, ca, a, true, "planned below the fraction");
  }
  // Planned a load: integration from this tick on, also when the plan unloads it again.
  for (const double load : {2.0 * cfg.feedback.touchdown_follow_fraction * weight, 0.0}) {
    const Eigen::VectorXd q_prev = ca.q_ref, qd_prev = ca.qd_ref;
    tick(true, load);
    expect_rule(q_prev, qd_prev, ca, a, false, load > 0.0 ? "planned a load" : "unloaded again");
  }
  // Off: the right leg integrates from the touch-down on.
  const Eigen::VectorXd q_prev = cb.q_ref, qd_prev = cb.qd_ref;
  tick(true, 0.0);
  expect_rule(q_prev, qd_prev, cb, b, false, "off");
  expect_refused_naming("feedback.touchdown_follow_fraction", [](ControllerConfig& c, double v) {
    c.feedback.touchdown_follow_fraction = v;
  });
}

// FeedbackConfig::internal_force_leak_hz: while both feet bear load, the legs' reference errors
// lose only their internal part: the part whose PD torque kp e is balanced by the two feet's
// wrenches alone (J_q^T lambda with J_b^T lambda = 0: a squeeze, no motion). The split is
// checked against its two defining properties with an SVD least-squares solve (not the
// controller's KKT system): the internal torque is J_q^T lambda with J_b^T lambda = 0, and the
// rest of the error keeps both feet on the base's loop (J_b db + J_q de = 0 for some db). Then
// the update rule by hand; one foot unloaded or the option off: the paper's integration, bit
// for bit.
TEST(BalanceController, InternalForceLeakRemovesOnlyTheLegsSqueeze) {
  std::mt19937 rng(2020);
  std::uniform_real_distribution<double> hz(2.0, 300.0);
  for (int trial = 0; trial < 4; ++trial) {
    SCOPED_TRACE(trial);
    ControllerConfig cfg;
    cfg.feedback.support_leg_leak_hz = 0.0;  // this rule alone
    cfg.feedback.internal_force_leak_hz = hz(rng);
    const double drop = 1.0 - std::exp(-2.0 * M_PI * cfg.feedback.internal_force_leak_hz * 1e-3);
    const bool one_unloaded = trial == 3;
    ReferenceRuleBench b(cfg, one_unloaded);
    const BalanceController& leaky = b.leaky;
    const RobotState& s = b.s;
    const JointCommand &cmd = b.cmd, &cmd_plain = b.cmd_plain;
    const int elbow = b.elbow;
    const int n = leaky.num_joints();
    std::vector<int> legs;
    for (const char* side : {"l_", "r_"})
      for (const char* j : {"hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll"})
        legs.push_back(leaky.model().joint_index(std::string(side) + j));
    Eigen::VectorXd q_ref_prev, qd_ref_prev;
    double internal_max = 0.0, rest_max = 0.0;
    auto step = [&](double ref_prev, double meas, double rate, double max_err) {
      return meas + std::clamp(ref_prev - meas + rate * 1e-3, -max_err, max_err);
    };
    for (int k = 0; k < 60; ++k) {
      b.tick(legs, rng);
      const Eigen::VectorXd qdd = leaky.generalized_acceleration().tail(n);
      const Eigen::VectorXd& iq = leaky.internal_position_error();
      const Eigen::VectorXd& iv = leaky.internal_velocity_error();
      if (k == 0 || one_unloaded) {
        EXPECT_TRUE(iq.isZero()) << "no references yet, or not both feet loaded";
        EXPECT_TRUE(iv.isZero());
      } else {
        const Eigen::MatrixXd& C = leaky.foot_jacobians();
        const Eigen::MatrixXd Cb = C.leftCols(6), Cq = C.rightCols(n);
        struct Split {
          Eigen::VectorXd error, internal, gain;
        };
        ASSERT_GT(cmd.kp.minCoeff(), 0.0);
        ASSERT_GT(cmd.kd.minCoeff(), 0.0);
        for (const Split& sp :
             {Split{q_ref_prev - s.q, iq, cmd.kp}, Split{qd_ref_prev - s.qd, iv, cmd.kd}}) {
          // The internal torque is J_q^T lambda, with J_b^T lambda = 0.
          const Eigen::VectorXd t = sp.gain.cwiseProduct(sp.internal);
          const Eigen::VectorXd lambda =
              Cq.transpose().jacobiSvd(Eigen::ComputeThinU | Eigen::ComputeThinV).solve(t);
          EXPECT_LT((Cq.transpose() * lambda - t).norm(), 1e-7 * (1.0 + t.norm()));
          EXPECT_LT((Cb.transpose() * lambda).norm(), 1e-7 * (1.0 + t.norm()));
          // The rest keeps the loop: some base motion db closes it.
          const Eigen::VectorXd rest = sp.error - sp.internal;
          const Eigen::VectorXd feet = Cq * rest;
          const Eigen::VectorXd db =
              Cb.jacobiSvd(Eigen::ComputeThinU | Eigen::ComputeThinV).solve(-feet);
          EXPECT_LT((Cb * db + feet).norm(), 1e-7 * (1.0 + feet.norm()));
          // The arms are no part of the loop.
          EXPECT_EQ(sp.internal[elbow], 0.0);
          internal_max = std::max(internal_max, sp.internal.cwiseAbs().maxCoeff());
          rest_max = std::max(rest_max, rest.cwiseAbs().maxCoeff());
        }
        // The rule: the internal part scaled by drop is taken off, then the paper's update.
        for (int j = 0; j < n; ++j) {
          const double vr = step(qd_ref_prev[j] - drop * iv[j], s.qd[j], qdd[j], 0.5);
          EXPECT_NEAR(cmd.qd_ref[j], vr, 1e-12) << j;
          EXPECT_NEAR(cmd.q_ref[j], step(q_ref_prev[j] - drop * iq[j], s.q[j], vr, 0.05), 1e-12)
              << j;
        }
      }
      q_ref_prev = cmd.q_ref;
      qd_ref_prev = cmd.qd_ref;
    }
    if (one_unloaded) {
      expect_same_commands(cmd, cmd_plain);
    } else {
      // Both parts are really there (the split is not trivially all or nothing).
      EXPECT_GT(internal_max, 1e-4);
      EXPECT_GT(rest_max, 1e-4);
      EXPECT_GT((cmd.q_ref - cmd_plain.q_ref).cwiseAbs().maxCoeff(), 1e-5);
    }
  }
  expect_refused_naming("feedback.internal_force_leak_hz",
                        [](ControllerConfig& c, double v) { c.feedback.internal_force_leak_hz = v; });
}

// A fallen robot (FallConfig): from the tick whose base has turned more than fall.tilt_deg from
// standing, or whose CoM has sunk below fall.com_height_fraction of its standing height above
// the lowest sole, the controller damps the joints, offers the optimiser no support and says
// so; latched until reset().
TEST(BalanceController, AFallenRobotIsDampedUntilReset) {
  std::mt19937 rng(17);
  const auto tilted = [&](const BalanceController& c, double deg) {
    RobotState s = test::standing_state(c);
    const double a = test::uniform(rng, 0.0, 2.0 * M_PI);  // a horizontal axis, seeded
    const Eigen::Vector3d axis(std::cos(a), std::sin(a), 0.0);
    s.X_WB.R = Eigen::AngleAxisd(deg * M_PI / 180.0, axis).toRotationMatrix() * s.X_WB.R;
    return s;
  };
  BalanceController c = make_controller();
  BalanceReference ref = c.make_reference();
  contact::ContactProblem p;
  contact::ContactSolution sol;
  contact::SequentialOptimizer opt;
  JointCommand cmd = c.make_command();
  const auto tick = [&](const RobotState& s) {
    c.prepare(s, ref, p);
    opt.solve(p, sol);
    c.finish(sol, cmd);
  };
  for (double deg : {0.0, 30.0, 55.0}) {  // balancing, however hard
    tick(tilted(c, deg));
    EXPECT_FALSE(c.diagnostics().fallen) << deg;
    EXPECT_NE(cmd.mode, CommandMode::kDamping) << deg;
  }
  RobotState s = tilted(c, 65.0);
  s.tick = 42;
  tick(s);
  const TickDiagnostics& d = c.diagnostics();
  ASSERT_TRUE(d.fallen);
  EXPECT_EQ(d.fall_reason, FallReason::kTilt);
  EXPECT_EQ(d.fall_tick, 42);
  EXPECT_NEAR(d.fall_tilt_deg, 65.0, 0.5);  // the base stands upright in the nominal posture
  EXPECT_EQ(cmd.mode, CommandMode::kDamping);
  EXPECT_TRUE(cmd.tau_ff.isZero());
  EXPECT_FALSE(p.feet[0].in_contact || p.feet[1].in_contact);
  EXPECT_EQ(describe_fall(d, 60.0, 0.5), "base tilt 65.00 deg > 60.0 deg");
  // Latched: upright again, still damped; the fall's figures kept.
  s = test::standing_state(c);
  s.tick = 43;
  tick(s);
  EXPECT_TRUE(c.diagnostics().fallen);
  EXPECT_EQ(c.diagnostics().fall_tick, 42);
  EXPECT_EQ(cmd.mode, CommandMode::kDamping);
  c.finish_fallback(cmd);
  EXPECT_EQ(cmd.mode, CommandMode::kDamping);
  c.reset();
  tick(s);
  EXPECT_FALSE(c.diagnostics().fallen);
  EXPECT_EQ(describe_fall(c.diagnostics(), 60.0, 0.5), "");
  EXPECT_NE(cmd.mode, CommandMode::kDamping);

  // 180: never by tilt (upside down is still "balancing").
  ControllerConfig never;
  never.fall.tilt_deg = 180.0;
  never.fall.com_height_fraction = 0.0;
  BalanceController n = make_controller(never);
  n.prepare(tilted(n, 170.0), ref, p);
  EXPECT_FALSE(n.diagnostics().fallen);

  // The CoM rule: knees bent 0.6 rad more (hips and ankles taking half each, soles flat). Its
  // height fraction computed here from the model: CoM z minus the lowest sole's z, over the
  // same at the nominal posture.
  ControllerConfig low;
  low.fall.com_height_fraction = 0.97;
  BalanceController k = make_controller(low);
  const auto& model = k.model();
  const auto& robot = k.robot();
  const auto height = [&](const Eigen::VectorXd& q) {
    model::Data data(model);
    model::forward_kinematics(model, data, q);
    model::center_of_mass(model, data, q);
    const Eigen::Vector3d com = data.com;
    double sole = 1e9;
    for (const auto& f : robot.feet)
      sole = std::min(sole, model::frame_placement(model, data, f.frame_id)
                                .act(Eigen::Vector3d(0.5 * (f.sole.x_min + f.sole.x_max),
                                                     0.5 * (f.sole.y_min + f.sole.y_max),
                                                     -f.sole.height))
                                .z());
    return com.z() - sole;
  };
  RobotState crouch = test::standing_state(k);
  for (const char* side : {"l_", "r_"}) {
    crouch.q[model.joint_index(std::string(side) + "knee")] += 0.6;
    crouch.q[model.joint_index(std::string(side) + "hip_pitch")] -= 0.3;
    crouch.q[model.joint_index(std::string(side) + "ankle_pitch")] -= 0.3;
  }
  Eigen::VectorXd qc = robot.q_nominal;
  qc.tail(model.njoints) = crouch.q;
  const double expected = height(qc) / height(robot.q_nominal);
  ASSERT_LT(expected, 0.97);
  k.prepare(crouch, ref, p);
  EXPECT_TRUE(k.diagnostics().fallen);
  EXPECT_EQ(k.diagnostics().fall_reason, FallReason::kComHeight);
  EXPECT_NEAR(k.diagnostics().fall_com_height_fraction, expected, 1e-9);
}

TEST(BalanceController, BadInputGivesDampingAndBadConfigThrows) {
  BalanceController c = make_controller();
  RobotState s = test::standing_state(c);
  BalanceReference ref = c.make_reference();
  contact::ContactProblem p;
  contact::ContactSolution sol;
  JointCommand cmd = c.make_command();
  s.qd[3] = std::nan("");
  c.prepare(s, ref, p);
  EXPECT_FALSE(p.feet[0].in_contact || p.feet[1].in_contact);
  c.finish(sol, cmd);
  EXPECT_EQ(cmd.mode, CommandMode::kDamping);
  EXPECT_TRUE(cmd.tau_ff.isZero());
  RobotState wrong = c.make_state();
  wrong.q.resize(3);
  c.prepare(wrong, ref, p);
  c.finish_fallback(cmd);
  EXPECT_EQ(cmd.mode, CommandMode::kDamping);
  JointCommand small;
  small.resize(2);
  c.finish(sol, small);
  EXPECT_TRUE(small.tau_ff.isZero());  // untouched

  ControllerConfig bad;
  bad.acceleration.w_b = 1.0;
  EXPECT_THROW(make_controller(bad), ConfigError);
  model::RobotConfig other = humanoid().robot;
  other.q_nominal.resize(5);
  EXPECT_THROW(BalanceController(humanoid().model, other, ControllerConfig{}), ConfigError);
}

}  // namespace
}  // namespace poise::controller
