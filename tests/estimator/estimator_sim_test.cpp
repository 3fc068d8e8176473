// Estimator accuracy against the Bullet simulator's ground truth (issue 7, section 4): the same
// sensor stream goes to the invariant EKF and to the plain leg-odometry baseline; both are
// compared with the truth and printed. The robot is held by the simulator's joint PD to its
// nominal posture (stiffened gains) plus a static gravity-compensation feed-forward (no balance
// controller).
// IMU noise from the scenario files plus constant biases set here.
#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <cstdio>

#include "poise/estimator/estimator.hpp"
#include "poise/inprocess/estimator_frame.hpp"
#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/simulator.hpp"

namespace poise::estimator {
namespace {

struct Errors {
  double v_rms = 0.0;          ///< base velocity RMS error [m/s]
  double omega_rms = 0.0;      ///< base angular velocity RMS error [rad/s]
  double angle_max_deg = 0.0;  ///< total orientation error, max [deg]
  double com_drift = 0.0;      ///< max change of the CoM position error since t0 [m]
};

struct Accumulator {
  double sq = 0.0, sq_omega = 0.0;
  int n = 0;
  Errors e;
  bool have_ref = false;
  Vector3 com_err0 = Vector3::Zero();
  void add(const Matrix3& R, const Vector3& v, const Vector3& omega, const Vector3& com,
           const sim::GroundTruth& t) {
    sq += (v - t.v_WB).squaredNorm();
    sq_omega += (omega - t.omega_WB).squaredNorm();
    ++n;
    e.v_rms = std::sqrt(sq / n);
    e.omega_rms = std::sqrt(sq_omega / n);
    const double a = model::so3_log(R * t.X_WB.linear().transpose()).norm() * 180 / M_PI;
    e.angle_max_deg = std::max(e.angle_max_deg, a);
    const Vector3 err = com - t.com_W;
    if (!have_ref) {
      com_err0 = err;
      have_ref = true;
    }
    e.com_drift = std::max(e.com_drift, (err - com_err0).norm());
  }
};

struct RunResult {
  Errors filter, baseline;
  bool finite = true;
  StatusFlags flags_seen = 0;
  int contacts_wrong = 0;  ///< ticks where a detected contact disagrees with the truth
  double sim_fell_height = 0.0;
};

std::string scenario_path(const std::string& name) {
  return std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/" + name + ".yaml";
}

/// A joint the hold command swings: q_ref = q0 + amplitude sin(2 pi frequency t).
struct Swing {
  std::string joint;
  double amplitude = 0.0;  ///< [rad]
  double frequency = 0.0;  ///< [Hz]
};

/// Runs `duration` seconds of the scenario with the estimator in the loop. `imu_link`: the IMU
/// frame for the simulator and the estimator instead of the robot's (empty: the robot's).
RunResult run(const std::string& scenario_name, double duration, bool add_biases,
              bool remove_pushes = false, const std::string& imu_link = "",
              const std::vector<Swing>& swings = {}) {
  scenario::Scenario sc = scenario::load_scenario(scenario_path(scenario_name));
  if (remove_pushes) sc.sim.pushes.clear();
  if (!imu_link.empty()) sc.sim.robot.imu_frame = imu_link;
  if (add_biases) {
    sc.sim.imu.gyro_bias = Eigen::Vector3d(0.002, -0.0015, 0.001);
    sc.sim.imu.accel_bias = Eigen::Vector3d(0.02, -0.015, 0.05);
  }
  model::RobotConfig rc = model::load_robot_config(
      sc.robot_config.empty()
          ? std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/robot.yaml"
          : sc.robot_config.string());
  const model::Model model = model::load_robot_model(rc);
  if (!imu_link.empty()) {
    rc.imu_frame = imu_link;
    rc.imu_frame_id = model.frame_id(imu_link);
  }
  sim::Simulator sim(sc.sim);
  const int n = model.njoints;
  const std::vector<int> sim_to_model = sim::joint_index_map(sim.joint_names(), model.joint_names);
  std::vector<int> model_to_sim(n, -1);
  for (int i = 0; i < static_cast<int>(sim_to_model.size()); ++i)
    if (sim_to_model[i] >= 0) model_to_sim[sim_to_model[i]] = i;
  // Feet: the simulator's foot order by name.
  std::array<int, 2> sim_foot{-1, -1};
  for (int i = 0; i < static_cast<int>(sim.foot_names().size()); ++i) {
    const std::string& name = sim.foot_names()[i];
    const std::string& frame = sc.sim.robot.feet[i].frame;
    for (int f = 0; f < 2; ++f)
      if (frame == rc.feet[f].frame || name == (f == 0 ? "right" : "left")) sim_foot[f] = i;
  }
  EXPECT_GE(sim_foot[0], 0);
  EXPECT_GE(sim_foot[1], 0);

  sim::SensorFrame sensors = sim.make_sensor_frame();
  sim::GroundTruth truth = sim.make_ground_truth();
  sim.read(sensors, truth);

  // Hold command: PD to the initial joint positions + static gravity compensation with the
  // weight shared by both feet (least-norm contact wrenches balancing the base).
  model::Data data(model);
  Eigen::VectorXd q0(model.nq);
  q0.head<3>() = truth.X_WB.translation();
  q0.segment<4>(3) = Eigen::Quaterniond(truth.X_WB.linear()).coeffs();
  Eigen::VectorXd qj(n);
  sim::remap_joint_vector(sim_to_model, sensors.q, qj);
  q0.tail(n) = qj;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.nv);
  const Eigen::VectorXd tau_g = model::rnea(model, data, q0, zero, zero);
  model::compute_joint_jacobians(model, data, q0);
  Eigen::MatrixXd Jc(12, model.nv);
  for (int f = 0; f < 2; ++f) {
    model::Matrix6X J(6, model.nv);
    model::frame_jacobian(model, data, rc.feet[f].frame_id, J);
    Jc.middleRows(6 * f, 6) = J;
  }
  const Eigen::MatrixXd JbT = Jc.leftCols(6).transpose();  // 6 x 12
  const Eigen::VectorXd fc = JbT.completeOrthogonalDecomposition().solve(tau_g.head(6));
  const Eigen::VectorXd tau_joints = tau_g.tail(n) - Jc.rightCols(n).transpose() * fc;

  sim::JointCommand cmd = sim.make_command();
  cmd.mode = sim::CommandMode::kPd;
  for (int j = 0; j < n; ++j) {
    const int s = model_to_sim[j];
    cmd.tau_ff[s] = tau_joints[j];
    cmd.q_ref[s] = qj[j];
    cmd.qd_ref[s] = 0.0;
    // The suggested gains leave the ankles softer than the inverted pendulum (m g h ~ 400 N m/rad):
    // stiffen them so the held robot stands (it is a test fixture, not a controller).
    cmd.kp[s] = 4.0 * rc.gains[j].kp;
    cmd.kd[s] = 2.0 * rc.gains[j].kd;
  }

  EstimatorConfig ecfg;  // the scenario's IMU latency, as poise run configures it
  ecfg.imu_delay_ticks = scenario::estimator_imu_delay_ticks(sc);
  Estimator est(model, rc, ecfg);
  SensorFrame frame = est.make_sensor_frame();
  EstimatorState state = est.make_state();

  RunResult r;
  Accumulator acc_f, acc_b;
  const int steps = static_cast<int>(duration / sim.dt());
  double min_height = 1e9;
  std::vector<std::pair<int, Swing>> swung;  // simulator joint index, swing
  for (const Swing& w : swings) {
    const int j = model.joint_index(w.joint);
    EXPECT_GE(j, 0) << w.joint;
    if (j >= 0) swung.emplace_back(model_to_sim[j], w);
  }
  const Eigen::VectorXd q_ref0 = cmd.q_ref;
  for (int k = 0; k < steps; ++k) {
    cmd.tick = sensors.tick;
    const double t = k * sim.dt(), two_pi = 2.0 * M_PI;
    for (const auto& [s, w] : swung) {
      cmd.q_ref[s] = q_ref0[s] + w.amplitude * std::sin(two_pi * w.frequency * t);
      cmd.qd_ref[s] = w.amplitude * two_pi * w.frequency * std::cos(two_pi * w.frequency * t);
    }
    sim.step(cmd, sensors, truth);
    inprocess::to_estimator_frame(sensors, sim_to_model, sim_foot, frame);
    const StatusFlags flags = est.update(frame, state);
    r.flags_seen |= flags;
    const bool finite_now = state.X_WB.p.allFinite() && state.v_WB.allFinite() &&
                            state.com_W.allFinite() && state.k_W.allFinite();
    r.finite = r.finite && finite_now;
    min_height = std::min(min_height, truth.X_WB.translation().z());
    for (int f = 0; f < 2; ++f)
      if (state.feet[f].in_contact != truth.feet[sim_foot[f]].in_contact) ++r.contacts_wrong;
    if (flags & kInitializing) continue;
    acc_f.add(state.X_WB.R, state.v_WB, state.omega_WB, state.com_W, truth);
    // The baseline's CoM: the model CoM at the baseline base pose (same joints).
    Eigen::VectorXd qb = state.q_model;
    const SE3& Xb = est.leg_odometry().X_WB();
    qb.head<3>() = Xb.p;
    qb.segment<4>(3) = Eigen::Quaterniond(Xb.R).coeffs();
    model::center_of_mass(model, data, qb);
    acc_b.add(Xb.R, est.leg_odometry().v_WB(), truth.omega_WB /* not compared */, data.com,
              truth);
  }
  r.filter = acc_f.e;
  r.baseline = acc_b.e;
  r.sim_fell_height = min_height;
  std::printf(
      "%-28s %5.1f s IMU on %s | IEKF: v RMS %.4f m/s, omega RMS %.4f rad/s, angle max %.3f deg, "
      "CoM drift %.4f m | leg odometry: v RMS %.4f m/s, angle max %.3f deg, CoM drift %.4f m | base z min %.3f, contact mismatch ticks %d\n",
      scenario_name.c_str(), duration, rc.imu_frame.c_str(), r.filter.v_rms, r.filter.omega_rms,
      r.filter.angle_max_deg, r.filter.com_drift, r.baseline.v_rms, r.baseline.angle_max_deg, r.baseline.com_drift, min_height, r.contacts_wrong);
  return r;
}

TEST(EstimatorSim, StandingTwentySecondsWithImuNoiseAndBias) {
  const RunResult r = run("forward_push_double_support", 20.0, true, /*remove_pushes=*/true);
  EXPECT_TRUE(r.finite);
  EXPECT_LT(r.filter.com_drift, 0.01);
  EXPECT_LT(r.filter.v_rms, 0.02);
  EXPECT_LT(r.filter.angle_max_deg, 0.5);
}

TEST(EstimatorSim, ForwardPushOfThePaper) {
  const RunResult r = run("forward_push_double_support", 4.0, true);
  EXPECT_TRUE(r.finite);
  EXPECT_GT(r.sim_fell_height, 0.5);  // the held robot did not fall (else the run is not valid)
  EXPECT_LT(r.filter.v_rms, 0.02);
  EXPECT_LT(r.filter.angle_max_deg, 0.5);
  EXPECT_LT(r.filter.com_drift, 0.01);
}

// An IMU behind joints (a torso's behind a waist: Unitree's H1, PAL's TALOS): the estimator
// takes the IMU's pose and motion relative to the base from the joint encoders. Here the IMU sits
// on the left upper arm, behind the waist yaw and the shoulder's pitch and roll, and those three
// joints swing (0.3-0.4 rad at 0.7-1.3 Hz: the IMU turns about every axis at up to ~3 rad/s and
// its origin moves relative to the base at up to ~1 m/s) while the held robot stands, with the
// scenario's sensors (the IMU 1 ms late, encoder velocities low-passed at 100 Hz, biases added).
// The base's attitude, angular velocity and velocity must stay close to those of the same run
// with the IMU on the base. Measured 2026-12-05: attitude max 0.42 deg (base IMU 0.16), rate RMS
// 13 mrad/s (1.9), velocity RMS 7.6 mm/s (0.8), CoM drift 5.9 mm (0.8). With the IMU's 1 ms
// latency not allowed for (imu_delay_ticks 0) 1.6 deg, 19 mrad/s, 34 mm/s, 28 mm; the IMU's
// motion taken for the base's would be errors of ~0.4 rad and ~3 rad/s.
TEST(EstimatorSim, AnImuBehindSwingingJointsGivesTheBaseMotion) {
  const std::vector<Swing> swings = {
      {"torso_yaw", 0.3, 0.7}, {"l_shoulder_pitch", 0.4, 1.3}, {"l_shoulder_roll", 0.3, 0.9}};
  const RunResult base =
      run("forward_push_double_support", 6.0, true, /*remove_pushes=*/true, "", swings);
  const RunResult arm = run("forward_push_double_support", 6.0, true, /*remove_pushes=*/true,
                            "l_upper_arm", swings);
  for (const RunResult* r : {&base, &arm}) {
    EXPECT_TRUE(r->finite);
    EXPECT_GT(r->sim_fell_height, 0.5);
  }
  EXPECT_LT(base.filter.angle_max_deg, 0.3);
  EXPECT_LT(arm.filter.angle_max_deg, 0.6);
  EXPECT_LT(arm.filter.omega_rms, 0.02);
  EXPECT_LT(arm.filter.v_rms, 0.015);
  EXPECT_LT(arm.filter.com_drift, 0.01);
  // Leg odometry takes its attitude from the IMU's own filter, which the arm's accelerations
  // disturb (1.7 deg: the simulated AHRS, SENSORS.md); its velocity still follows the base.
  EXPECT_LT(arm.baseline.v_rms, 0.02);
}

}  // namespace
}  // namespace poise::estimator
