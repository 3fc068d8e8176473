// Sensor consistency (IMU, joint torques, foot F/T), the PD-in-simulator law, supports and
// allocation-free stepping.
#define EIGEN_RUNTIME_NO_MALLOC
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "poise/sim/simulator.hpp"
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

using test::biped_config;
using test::box_config;

struct Rig {
  Simulator sim;
  SensorFrame s;
  GroundTruth g;
  JointCommand cmd;
  explicit Rig(const SimulatorConfig& c)
      : sim(c), s(sim.make_sensor_frame()), g(sim.make_ground_truth()), cmd(sim.make_command()) {
    sim.read(s, g);
  }
  void hold_posture(double kp = 600.0, double kd = 20.0) {
    cmd.mode = CommandMode::kPd;
    cmd.q_ref = s.q;
    cmd.kp.setConstant(kp);
    cmd.kd.setConstant(kd);
  }
  void run(int steps) {
    for (int k = 0; k < steps; ++k)
      sim.step(cmd, s, g);
  }
};

TEST(SimSensors, ImuSpecificForceAtRestIsMinusGravityInImuFrame) {
  Rig r(biped_config());
  r.hold_posture(600.0, 60.0);
  r.run(1500);
  // Standing (swaying by a few mrad): over a window the mean acceleration vanishes, so the mean
  // reading equals the mean of R_WI^T (0, 0, g) taken from the reported orientation.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), expected = Eigen::Vector3d::Zero();
  const int window = 1000;
  for (int k = 0; k < window; ++k) {
    r.run(1);
    mean += r.s.imu_specific_force_I / window;
    expected += r.s.imu_q_WI.toRotationMatrix().transpose() * Eigen::Vector3d(0, 0, 9.81) / window;
  }
  EXPECT_LT((mean - expected).norm(), 0.02) << mean.transpose() << " vs " << expected.transpose();
  const Eigen::Matrix3d R_WI = r.sim.frame_pose("imu_link").linear();
  // The IMU frame is pitched by 0.1 rad in the torso: x must see part of gravity.
  EXPECT_GT(std::abs(expected.x()), 0.5);
  EXPECT_TRUE(r.s.imu_q_WI.toRotationMatrix().isApprox(R_WI, 1e-12));
}

TEST(SimSensors, ImuInFreeFallReadsZeroAndGyroMatchesOrientationChange) {
  SimulatorConfig cfg = biped_config();
  cfg.world.ground.enabled = false;
  Rig r(cfg);
  Eigen::VectorXd q = r.s.q;
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation().z() = 2.0;
  r.sim.set_state(X, q, Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d(0.4, -0.7, 1.1));
  r.hold_posture(0.0, 0.0);
  r.cmd.mode = CommandMode::kTorque;
  r.run(1);
  Eigen::Quaterniond q_prev = r.s.imu_q_WI;
  double max_err = 0.0;
  for (int k = 0; k < 200; ++k) {
    r.run(1);
    // gyro vs finite difference of the reported orientation (in I): log(R_prev^T R) / dt
    const Eigen::AngleAxisd d(q_prev.conjugate() * r.s.imu_q_WI);
    const Eigen::Vector3d w_fd = d.axis() * d.angle() / r.sim.dt();
    max_err = std::max(max_err, (w_fd - r.s.imu_omega_I).norm());
    q_prev = r.s.imu_q_WI;
  }
  // the body spins, so its gyro changes within a step; the finite difference is a mid-step value
  EXPECT_LT(max_err, 0.02);
  EXPECT_GT(r.s.imu_omega_I.norm(), 0.5);
  // an unconstrained body in free fall with locked-ish joints: accelerometer reads only the
  // rotational (centripetal/Euler) acceleration of the off-COM IMU point, far below g
  EXPECT_LT(r.s.imu_specific_force_I.norm(), 1.0);
}

TEST(SimSensors, ImuNoiseAndBiasHaveTheConfiguredStatistics) {
  SimulatorConfig cfg = box_config();
  cfg.world.ground.enabled = false;
  cfg.world.gravity.setZero();
  cfg.imu.gyro_noise_std = 0.02;
  cfg.imu.accel_noise_std = 0.3;
  cfg.imu.gyro_bias = Eigen::Vector3d(0.01, -0.02, 0.03);
  cfg.imu.accel_bias = Eigen::Vector3d(-0.1, 0.2, 0.05);
  cfg.imu.seed = 11;
  Rig r(cfg);
  const int n = 4000;
  Eigen::Vector3d mg = Eigen::Vector3d::Zero(), ma = Eigen::Vector3d::Zero();
  Eigen::Vector3d sg = Eigen::Vector3d::Zero(), sa = Eigen::Vector3d::Zero();
  for (int k = 0; k < n; ++k) {
    r.run(1);
    mg += r.s.imu_omega_I;
    ma += r.s.imu_specific_force_I;
    sg += r.s.imu_omega_I.cwiseAbs2();
    sa += r.s.imu_specific_force_I.cwiseAbs2();
  }
  mg /= n;
  ma /= n;
  const Eigen::Vector3d stdg = (sg / n - mg.cwiseAbs2()).cwiseSqrt();
  const Eigen::Vector3d stda = (sa / n - ma.cwiseAbs2()).cwiseSqrt();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(mg[i], cfg.imu.gyro_bias[i], 5 * 0.02 / std::sqrt(n));
    EXPECT_NEAR(ma[i], cfg.imu.accel_bias[i], 5 * 0.3 / std::sqrt(n));
    EXPECT_NEAR(stdg[i], 0.02, 0.1 * 0.02);
    EXPECT_NEAR(stda[i], 0.3, 0.1 * 0.3);
  }
  // noise-free when the std is 0: exact bias
  cfg.imu.gyro_noise_std = cfg.imu.accel_noise_std = 0.0;
  Rig clean(cfg);
  clean.run(3);
  EXPECT_EQ(clean.s.imu_omega_I, cfg.imu.gyro_bias);
  EXPECT_LT((clean.s.imu_specific_force_I - cfg.imu.accel_bias).norm(), 1e-12);
}

TEST(SimSensors, FootForceTorqueCarriesTheWeightAndGivesTheCop) {
  Rig r(biped_config());
  r.hold_posture();
  r.run(1500);
  const double mg = r.sim.total_mass() * 9.81;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const int window = 500;
  for (int k = 0; k < window; ++k) {
    r.run(1);
    for (std::size_t f = 0; f < 2; ++f) {
      // sensor wrench (foot frame) -> world, compared with ground truth
      const Eigen::Matrix3d R_WF = r.g.feet[f].X_WF.linear();
      const Eigen::Vector3d f_W = R_WF * r.s.foot_wrench_Fo_F[f].tail<3>();
      EXPECT_LT((f_W - r.g.feet[f].force_W).norm(), 1e-9);
      sum += f_W / window;
    }
  }
  EXPECT_NEAR(sum.z(), mg, 0.01 * mg);
  EXPECT_LT(sum.head<2>().norm(), 0.01 * mg);
  for (std::size_t f = 0; f < 2; ++f) {
    EXPECT_TRUE(r.g.feet[f].in_contact);
    // CoP from the moment about the foot frame (sole plane z = 0 in the sole frame) against the
    // ground-truth CoP (impulse-weighted contact points): two independent computations.
    const auto& w = r.s.foot_wrench_Fo_F[f];
    const Eigen::Vector3d cop_F(-w[1] / w[5], w[0] / w[5], 0.0);
    const Eigen::Vector3d cop_W = r.g.feet[f].X_WF * cop_F;
    EXPECT_LT((cop_W - r.g.feet[f].cop_W).norm(), 1e-3)
        << cop_W.transpose() << " vs " << r.g.feet[f].cop_W.transpose();
  }
  EXPECT_EQ(r.g.num_non_foot_contacts, 0);
  // standing still: the feet do not slip
  EXPECT_LT(r.g.feet[0].v_WF.norm(), 1e-3);
}

TEST(SimSensors, PdLawIsEvaluatedInsideTheSimulatorAndClamped) {
  SimulatorConfig cfg = biped_config();
  cfg.world.ground.enabled = false;
  cfg.world.gravity.setZero();
  Rig r(cfg);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = r.sim.num_joints();
  for (int k = 0; k < 50; ++k) {
    const Eigen::VectorXd q = r.s.q, qd = r.s.qd;
    r.cmd.mode = CommandMode::kPd;
    for (int i = 0; i < n; ++i) {
      r.cmd.tau_ff[i] = 5 * u(rng);
      r.cmd.q_ref[i] = 0.3 * u(rng);
      r.cmd.qd_ref[i] = u(rng);
      r.cmd.kp[i] = 100 + 50 * u(rng);
      r.cmd.kd[i] = 5 + 2 * u(rng);
    }
    if (k == 40) r.cmd.kp.setConstant(1e6);  // saturates at the URDF effort limit (300)
    ASSERT_EQ(r.sim.step(r.cmd, r.s, r.g), StepStatus::kOk);
    for (int i = 0; i < n; ++i) {
      double tau = r.cmd.tau_ff[i] + r.cmd.kp[i] * (r.cmd.q_ref[i] - q[i]) +
                   r.cmd.kd[i] * (r.cmd.qd_ref[i] - qd[i]);
      tau = std::clamp(tau, -300.0, 300.0);
      EXPECT_NEAR(r.s.tau_measured[i], tau, 1e-9 * (1 + std::abs(tau)));
    }
    if (k == 40) {
      EXPECT_EQ(r.s.tau_measured.cwiseAbs().maxCoeff(), 300.0);
    }
  }
  // damping mode and rejection of bad commands
  const Eigen::VectorXd qd = r.s.qd;
  r.cmd.mode = CommandMode::kDamping;
  r.cmd.kd.setConstant(3.0);
  r.sim.step(r.cmd, r.s, r.g);
  EXPECT_LT((r.s.tau_measured + 3.0 * qd).norm(), 1e-9);
  const Eigen::VectorXd qd2 = r.s.qd;
  r.cmd.mode = CommandMode::kTorque;
  r.cmd.tau_ff[3] = std::nan("");
  EXPECT_EQ(r.sim.step(r.cmd, r.s, r.g), StepStatus::kRejectedCommand);
  EXPECT_LT((r.s.tau_measured + r.sim.damping_kd() * qd2).norm(), 1e-9);
  JointCommand wrong;
  wrong.resize(n - 1);
  EXPECT_EQ(r.sim.step(wrong, r.s, r.g), StepStatus::kRejectedCommand);
}

TEST(SimSensors, InclinedPlatformHoldsTheBoxByFriction) {
  SimulatorConfig cfg = box_config();
  PlatformConfig p;
  p.name = "slope";
  p.foot = "box";
  p.roll = 0.0;
  p.pitch = 10.0 * M_PI / 180.0;
  p.friction = 0.8;
  cfg.world.platforms = {p};
  cfg.initial.clearance = 0.001;
  // Box frame orientation = the platform's, so it lands flat.
  const Eigen::Quaterniond q(Eigen::AngleAxisd(p.pitch, Eigen::Vector3d::UnitY()));
  cfg.initial.base_orientation_wxyz << q.w(), q.x(), q.y(), q.z();
  Rig r(cfg);
  r.run(500);
  const Eigen::Vector3d x0 = r.g.X_WB.translation();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int k = 0; k < 500; ++k) {
    r.run(1);
    mean += r.g.total_contact_force_W / 500;
  }
  const double mg = r.sim.total_mass() * 9.81;
  // friction along the slope + normal force = exactly the weight: checks friction signs
  EXPECT_LT((mean - Eigen::Vector3d(0, 0, mg)).norm(), 0.01 * mg) << mean.transpose();
  EXPECT_LT((r.g.X_WB.translation() - x0).norm(), 1e-3) << "no creep on a 10 deg slope, mu 0.8";
}

TEST(SimSensors, MovingPlatformCarriesTheFootAlong) {
  SimulatorConfig cfg = box_config();
  PlatformConfig p;
  p.name = "shaker";
  p.foot = "box";
  p.friction = 1.0;
  p.translation_axis = Eigen::Vector3d::UnitX();
  p.translation = Sinusoid{0.2, 0.5, 0.0};  // peak acceleration 2 m/s^2 < mu g
  cfg.world.platforms = {p};
  Rig r(cfg);
  r.run(50);
  const double x0 = r.g.X_WB.translation().x();
  const double p0 = 0.2 * std::sin(2 * M_PI * 0.5 * 0.05);
  double worst = 0.0;
  for (int k = 0; k < 1500; ++k) {
    r.run(1);
    const double pt = 0.2 * std::sin(2 * M_PI * 0.5 * r.s.time);
    worst = std::max(worst, std::abs((r.g.X_WB.translation().x() - x0) - (pt - p0)));
  }
  EXPECT_LT(worst, 2e-3);
  EXPECT_TRUE(r.g.feet[0].in_contact);
}

TEST(SimSensors, StepDoesNotAllocateWithEigen) {
  SimulatorConfig cfg = biped_config();
  cfg.pushes = {Push{"torso", Eigen::Vector3d::Zero(), Eigen::Vector3d(10, 0, 0), 0.0, 0.05}};
  cfg.imu.accel_noise_std = 0.1;
  Rig r(cfg);
  r.hold_posture();
  r.run(20);
  Eigen::internal::set_is_malloc_allowed(false);
  r.run(100);
  const bool pushed =
      r.sim.add_push(Push{"pelvis", Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 5, 0), 0.2, 0.01});
  r.run(100);
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_TRUE(pushed);
}

}  // namespace
}  // namespace poise::sim
