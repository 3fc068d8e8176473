// Eqs (10)-(11) by hand, component by component, with seeded random inputs; and the config file.
#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "controller_test_util.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/controller/momentum_rate.hpp"

namespace poise::controller {
namespace {

TEST(MomentumRate, MatchesEquations10And11ComponentWise) {
  std::mt19937 rng(10);
  for (int trial = 0; trial < 50; ++trial) {
    MomentumGains g;
    g.gamma11 = test::random_vec3(rng, 10.0).cwiseAbs();
    g.gamma21 = test::random_vec3(rng, 50.0).cwiseAbs();
    g.gamma22 = test::random_vec3(rng, 10.0).cwiseAbs();
    const double m = test::uniform(rng, 1.0, 100.0);
    const Eigen::Vector3d k = test::random_vec3(rng, 5), kd = test::random_vec3(rng, 5);
    const Eigen::Vector3d c = test::random_vec3(rng, 1), cd = test::random_vec3(rng, 1);
    const Eigen::Vector3d v = test::random_vec3(rng, 1), vd = test::random_vec3(rng, 1);
    const model::Vector6 h = desired_momentum_rate(g, m, k, kd, c, cd, v, vd);
    for (int i = 0; i < 3; ++i) {
      const double kdot = g.gamma11[i] * (kd[i] - k[i]);
      const double ldot = m * g.gamma21[i] * (vd[i] - v[i]) + m * g.gamma22[i] * (cd[i] - c[i]);
      EXPECT_NEAR(h[i], kdot, 1e-12 * (1 + std::abs(kdot)));
      EXPECT_NEAR(h[3 + i], ldot, 1e-12 * (1 + std::abs(ldot)));
    }
  }
}

// upright_angular_momentum's edges, with a diagonal locked inertia I (so the answer is
// I R^T omega_u) and the rotation vector written by hand: upright and upside down give nothing
// (no unique axis); a pitch of theta about the lateral axis gives -r_pitch theta y, a roll about
// the forward -r_roll theta x, each rate only about its own axis; a trunk pitched to the vertical
// (its forward vertical) gets the pitch rate; the base's up need not be its z.
TEST(MomentumRate, UprightTargetAtItsEdges) {
  const Eigen::Matrix3d I = Eigen::Vector3d(2.0, 3.0, 4.0).asDiagonal();
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ(), x = Eigen::Vector3d::UnitX(),
                        y = Eigen::Vector3d::UnitY();
  auto rot = [](double angle, const Eigen::Vector3d& axis) {
    return Eigen::AngleAxisd(angle, axis).toRotationMatrix();
  };
  auto k = [&](const Eigen::Matrix3d& R, double rp, double rr,
               const Eigen::Vector3d& up_B = Eigen::Vector3d::UnitZ()) {
    return upright_angular_momentum(R, up_B, x, z, I, rp, rr);
  };
  EXPECT_EQ(k(Eigen::Matrix3d::Identity(), 1.0, 1.0), Eigen::Vector3d::Zero());
  EXPECT_EQ(k(rot(M_PI, x), 1.0, 1.0), Eigen::Vector3d::Zero());
  const double th = 0.3;
  const Eigen::Matrix3d P = rot(th, y), Rl = rot(th, x);
  EXPECT_LT((k(P, 1.5, 0.7) - I * P.transpose() * (-1.5 * th * y)).norm(), 1e-12);
  EXPECT_LT((k(Rl, 1.5, 0.7) - I * Rl.transpose() * (-0.7 * th * x)).norm(), 1e-12);
  EXPECT_LT(k(P, 0.0, 0.7).norm(), 1e-12);   // roll only: a pitch is left
  EXPECT_LT(k(Rl, 1.5, 0.0).norm(), 1e-12);  // pitch only: a roll is left
  const Eigen::Matrix3d V = rot(M_PI / 2, y);  // forward pointing down
  EXPECT_LT((k(V, 1.5, 0.0) - I * V.transpose() * (-1.5 * (M_PI / 2) * y)).norm(), 1e-12);
  // A base whose up is its x axis, turned so that axis is vertical: upright, nothing.
  EXPECT_LT(k(rot(-M_PI / 2, y), 1.0, 1.0, x).norm(), 1e-12);
  // Yaw changes only the axes: a pitch after a 90 deg yaw is about the world's -x.
  const Eigen::Matrix3d Y = rot(M_PI / 2, z) * P;
  EXPECT_LT((k(Y, 1.5, 0.7) - I * Y.transpose() * (-1.5 * th * (rot(M_PI / 2, z) * y))).norm(),
            1e-12);
}

TEST(MomentumRate, PaperGainsMappedToZUp) {
  // config/paper.yaml: the paper's controller (the defaults until 2026-12-04).
  const ControllerConfig c = load_controller_config(
      std::string(POISE_SOURCE_DIR) + "/controller/momentum/config/paper.yaml");
  EXPECT_EQ(c.momentum.ankle_first_blend, 0.0);
  EXPECT_EQ(c.momentum.upright_pitch_rate, 0.0);
  EXPECT_EQ(c.momentum.upright_roll_rate, 0.0);
  EXPECT_EQ(c.feedback.touchdown_follow_fraction, 0.0);
  // Paper Sec. 4.2, Y up: Gamma21 = diag{40, 20, 40}, Gamma22 = diag{8, 3, 8}; vertical is z here.
  EXPECT_EQ(c.momentum.gamma11, Eigen::Vector3d(5, 5, 5));
  EXPECT_EQ(c.momentum.gamma21, Eigen::Vector3d(40, 40, 20));
  EXPECT_EQ(c.momentum.gamma22, Eigen::Vector3d(8, 8, 3));
  EXPECT_EQ(c.contact.w_k, 0.1);
  // Paper 0.01 as a row scale of eqs (24), (29): weight 1e-4 (see controller_config.hpp).
  EXPECT_EQ(c.contact.eps_f, 1e-4);
  EXPECT_EQ(c.contact.eps_cop, 1e-4);
}

TEST(ControllerConfig, ShippedFileLoadsWithTheDefaults) {
  const ControllerConfig c = load_controller_config(
      std::string(POISE_SOURCE_DIR) + "/controller/momentum/config/balance_controller.yaml");
  const ControllerConfig d;
  EXPECT_EQ(c.momentum.gamma21, d.momentum.gamma21);
  EXPECT_EQ(c.momentum.ankle_first_blend, d.momentum.ankle_first_blend);
  EXPECT_EQ(c.momentum.upright_pitch_rate, d.momentum.upright_pitch_rate);
  EXPECT_EQ(c.momentum.upright_roll_rate, d.momentum.upright_roll_rate);
  EXPECT_EQ(c.momentum.gamma22, d.momentum.gamma22);
  EXPECT_EQ(c.feedback.touchdown_follow_fraction, d.feedback.touchdown_follow_fraction);
  EXPECT_EQ(c.feedback.touchdown_follow_hz, d.feedback.touchdown_follow_hz);
  // The ankle strategy first with faster CoM gains (controller_config.hpp), since 2026-12-04.
  EXPECT_EQ(d.momentum.ankle_first_blend, 0.1);
  EXPECT_EQ(d.momentum.gamma21, Eigen::Vector3d(20, 20, 20));
  EXPECT_EQ(d.momentum.gamma22, Eigen::Vector3d(15, 15, 3));
  EXPECT_GT(d.feedback.touchdown_follow_fraction, 0.0);
  EXPECT_EQ(d.momentum.upright_pitch_rate, 1.0);  // the trunk's pitch back, since 2026-12-05
  EXPECT_EQ(d.momentum.upright_roll_rate, 0.0);
  EXPECT_EQ(c.acceleration.w_b, d.acceleration.w_b);
  EXPECT_EQ(c.foot.kp, d.foot.kp);
  EXPECT_EQ(c.foot.unloaded_kp, d.foot.unloaded_kp);
  EXPECT_EQ(c.foot.unloaded_kd, d.foot.unloaded_kd);
  EXPECT_EQ(c.foot.support_acceleration_tau, d.foot.support_acceleration_tau);
  EXPECT_EQ(c.feedback.max_position_error, d.feedback.max_position_error);
  EXPECT_EQ(c.resting_force_fraction, d.resting_force_fraction);
  EXPECT_EQ(c.resting_touchdown_force_fraction, d.resting_touchdown_force_fraction);
  EXPECT_EQ(c.resting_touchdown_air_time, d.resting_touchdown_air_time);
  EXPECT_EQ(c.contact.priority, d.contact.priority);
  EXPECT_EQ(c.contact.torsion_limit, d.contact.torsion_limit);
  EXPECT_EQ(d.contact.torsion_limit, contact::TorsionLimit::kFrictionCoupled);
  EXPECT_EQ(c.fall.tilt_deg, d.fall.tilt_deg);
  EXPECT_EQ(c.fall.com_height_fraction, d.fall.com_height_fraction);
}

std::string write_temp(const std::string& name, const std::string& text) {
  const std::string path = std::string(POISE_BINARY_DIR) + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(ControllerConfig, BadFilesNameTheProblem) {
  auto expect_error = [](const std::string& text, const std::string& needle) {
    const std::string p = write_temp("controller_config_bad.yaml", text);
    try {
      load_controller_config(p);
      ADD_FAILURE() << "no error for: " << text;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error("acceleration: {w_b: 1.0}\n", "w_b");
  expect_error("momentum: {gamma21: [1, 2]}\n", "gamma21");
  expect_error("momentum: {gamma22: [1, -2, 3]}\n", "gamma22");
  expect_error("foot: {kp: abc}\n", "foot.kp");
  expect_error("foot: {support_acceleration_tau: -0.01}\n", "foot.support_acceleration_tau");
  expect_error("fot: {kp: 1}\n", "fot");
  expect_error("foot: {kq: 1}\n", "foot.kq");
  expect_error("dt: -1\n", "dt");
  expect_error("resting_force_fraction: -0.01\n", "resting_force_fraction");
  expect_error("resting_force_fraction: 1.5\n", "resting_force_fraction");
  expect_error("resting_touchdown_force_fraction: 1.0\n", "resting_touchdown_force_fraction");
  expect_error("resting_touchdown_air_time: -0.001\n", "resting_touchdown_air_time");
  expect_error("contact: {torsion_limit: coupled}\n", "contact.torsion_limit");
  expect_error("momentum: {ankle_first_blend: -0.01}\n", "momentum.ankle_first_blend");
  expect_error("momentum: {ankle_first_blend: .nan}\n", "momentum.ankle_first_blend");
  expect_error("momentum: {upright_pitch_rate: -1}\n", "momentum.upright_pitch_rate");
  expect_error("momentum: {upright_pitch_rate: fast}\n", "momentum.upright_pitch_rate");
  expect_error("momentum: {upright_roll_rate: 101}\n", "momentum.upright_roll_rate");
  expect_error("momentum: {upright_rate: 1}\n", "momentum.upright_rate");
  expect_error("feedback: {touchdown_follow_fraction: 1.0}\n",
               "feedback.touchdown_follow_fraction");
  expect_error("feedback: {touchdown_follow_fraction: -0.1}\n",
               "feedback.touchdown_follow_fraction");
  expect_error("feedback: {touchdown_follow_hz: 0}\n", "feedback.touchdown_follow_hz");
  expect_error("feedback: {velocity_leak_hz: -1}\n", "feedback.velocity_leak_hz");
  expect_error("feedback: {velocity_leak_hz: .nan}\n", "feedback.velocity_leak_hz");
  expect_error("feedback: {velocity_leak: 1}\n", "feedback.velocity_leak");
  expect_error("foot: {unloaded_kp: .nan}\n", "foot.unloaded_kp");
  expect_error("foot: {unloaded_kd: .inf}\n", "foot.unloaded_kd");
  expect_error("foot: {unloaded_kp: []}\n", "foot.unloaded_kp");
  expect_error("foot: {unloaded_kp: -1}\n", "foot.unloaded_kp");
  expect_error("foot: {unloaded_kd: -0.5}\n", "foot.unloaded_kd");
  expect_error("contact: {torsion_limit: [independent]}\n", "contact.torsion_limit");
  expect_error("fall: {tilt_deg: 0}\n", "fall.tilt_deg");
  expect_error("fall: {tilt_deg: 181}\n", "fall.tilt_deg");
  expect_error("fall: {com_height_fraction: 1}\n", "fall.com_height_fraction");
  expect_error("fall: {com_height_fraction: -0.1}\n", "fall.com_height_fraction");
  expect_error("fall: {tilt: 45}\n", "fall.tilt");
  try {
    load_controller_config("/nonexistent/controller.yaml");
    ADD_FAILURE();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/controller.yaml"), std::string::npos);
  }
  const std::string p = write_temp("controller_config_ok.yaml", "acceleration: {w_b: 0.9}\n");
  EXPECT_EQ(load_controller_config(p).acceleration.w_b, 0.9);
  const std::string q = write_temp("controller_config_rest.yaml", "resting_force_fraction: 0.05\n");
  EXPECT_EQ(load_controller_config(q).resting_force_fraction, 0.05);
  const std::string r = write_temp("controller_config_touchdown.yaml",
                                   "resting_touchdown_force_fraction: 0.03\n"
                                   "resting_touchdown_air_time: 0.05\n");
  EXPECT_EQ(load_controller_config(r).resting_touchdown_force_fraction, 0.03);
  EXPECT_EQ(load_controller_config(r).resting_touchdown_air_time, 0.05);
  const std::string a = write_temp("controller_config_ankle.yaml",
                                   "momentum: {ankle_first_blend: 0.02}\n");
  EXPECT_EQ(load_controller_config(a).momentum.ankle_first_blend, 0.02);
  const std::string up = write_temp("controller_config_upright.yaml",
                                   "momentum: {upright_pitch_rate: 0.5, upright_roll_rate: 2}\n");
  EXPECT_EQ(load_controller_config(up).momentum.upright_pitch_rate, 0.5);
  EXPECT_EQ(load_controller_config(up).momentum.upright_roll_rate, 2.0);
  const std::string u = write_temp("controller_config_unloaded.yaml",
                                   "foot: {unloaded_kp: 250, unloaded_kd: 30}\n");
  EXPECT_EQ(load_controller_config(u).foot.unloaded_kp, 250.0);
  EXPECT_EQ(load_controller_config(u).foot.unloaded_kd, 30.0);
  EXPECT_EQ(load_controller_config(u).foot.kp, ControllerConfig{}.foot.kp);
  const std::string t = write_temp("controller_config_torsion.yaml",
                                   "contact: {torsion_limit: independent}\n");
  EXPECT_EQ(load_controller_config(t).contact.torsion_limit, contact::TorsionLimit::kIndependent);
  const std::string f = write_temp("controller_config_fall.yaml",
                                   "fall: {tilt_deg: 45, com_height_fraction: 0}\n");
  EXPECT_EQ(load_controller_config(f).fall.tilt_deg, 45.0);
  EXPECT_EQ(load_controller_config(f).fall.com_height_fraction, 0.0);
}

}  // namespace
}  // namespace poise::controller
