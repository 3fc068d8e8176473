// Closed loop with the real Bullet simulator, all libraries in one process (poise::inprocess):
// standing, the paper's forward and lateral pushes (Sec. 4.1, Figs. 8-9), CoM shift and
// upper-body motion from the balance reference, and the Fig. 8 relation between desired and
// admissible momentum rates. The state comes from the simulator's ground truth unless the test
// says otherwise (the estimator is exercised by its own test below).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "poise/inprocess/in_process_loop.hpp"

namespace poise::inprocess {
namespace {

scenario::Scenario scenario(const std::string& name) {
  return scenario::load_scenario(std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/" + name + ".yaml");
}

scenario::Scenario standing(double duration) {
  scenario::Scenario s = scenario("forward_push_double_support");
  s.name = "stand";
  s.sim.pushes.clear();
  s.duration = duration;
  return s;
}

LoopOptions ground_truth() {
  LoopOptions o;
  o.state_source = StateSource::kGroundTruth;
  return o;
}

double tilt(const Eigen::Isometry3d& X) {
  return std::acos(std::clamp(X.linear()(2, 2), -1.0, 1.0));  // angle of the foot z from vertical
}

/// Quantities watched over a run, per tick.
struct Watch {
  double com_err_max_after_settle = 0.0;  ///< |CoM - controller target| after t_settle
  double max_foot_tilt = 0.0;             ///< of the support feet [rad]
  double max_foot_slip = 0.0;             ///< horizontal displacement of support feet [m]
  int non_foot_ticks = 0;
  bool support_lost = false;
  double last_time_com_err_above_1cm = 0.0;
  double max_trunk_pitch_change = 0.0;
  double max_trunk_roll_change = 0.0;
};

/// The simulator's index of each controller foot (robot_description order: right, left).
std::array<int, 2> sim_foot_of_side(const InProcessLoop& loop) {
  const auto& sim_feet = loop.scenario().sim.robot.feet;
  const auto& robot = loop.controller().robot();
  std::array<int, 2> sim_of_side{};
  for (int side = 0; side < 2; ++side)
    for (std::size_t f = 0; f < sim_feet.size(); ++f)
      if (sim_feet[f].frame == robot.feet[side].frame) sim_of_side[side] = static_cast<int>(f);
  return sim_of_side;
}

Watch run_and_watch(InProcessLoop& loop, double t_settle, const std::array<bool, 2>& support,
                    const std::function<void(InProcessLoop&)>& each_tick = {}) {
  Watch w;
  std::array<Eigen::Vector3d, 2> foot0;
  for (int i = 0; i < 2; ++i)
    foot0[i] = loop.truth().feet[i].X_WF.translation();
  const Eigen::Matrix3d R0 = loop.truth().X_WB.linear();
  const std::array<int, 2> sim_of_side = sim_foot_of_side(loop);
  const auto steps = static_cast<long>(std::llround(loop.duration() / 1e-3));
  for (long k = 0; k < steps; ++k) {
    if (each_tick) each_tick(loop);
    loop.step();
    const auto& t = loop.truth();
    const double time = loop.time();
    const Eigen::Vector3d err = t.com_W - loop.controller().diagnostics().com_target_W;
    if (time > t_settle)
      w.com_err_max_after_settle = std::max(w.com_err_max_after_settle, err.norm());
    if (err.head<2>().norm() > 0.01) w.last_time_com_err_above_1cm = time;
    w.non_foot_ticks += t.num_non_foot_contacts > 0;
    for (int side = 0; side < 2; ++side) {
      const auto& f = t.feet[sim_of_side[side]];
      if (!support[side]) continue;
      if (!f.in_contact && time > 0.05) w.support_lost = true;
      w.max_foot_tilt = std::max(w.max_foot_tilt, tilt(f.X_WF));
      w.max_foot_slip = std::max(
          w.max_foot_slip, (f.X_WF.translation() - foot0[sim_of_side[side]]).head<2>().norm());
    }
    const Eigen::Matrix3d dR = R0.transpose() * t.X_WB.linear();
    w.max_trunk_pitch_change = std::max(w.max_trunk_pitch_change, std::abs(std::asin(-dR(2, 0))));
    w.max_trunk_roll_change =
        std::max(w.max_trunk_roll_change, std::abs(std::atan2(dR(2, 1), dR(2, 2))));
  }
  return w;
}

void print(const char* name, const Watch& w, const RunResult& r) {
  std::printf(
      "[%s] com_err_max %.4f m, tilt %.4f rad, slip %.4f m, non-foot ticks %d, last >1cm %.2f s, "
      "trunk pitch %.3f roll %.3f rad | monitor: max %.4f final %.4f slip %.4f survived %d | "
      "fallbacks %llu qp_failures %llu tick p50 %.1f us\n",
      name, w.com_err_max_after_settle, w.max_foot_tilt, w.max_foot_slip, w.non_foot_ticks,
      w.last_time_com_err_above_1cm, w.max_trunk_pitch_change, w.max_trunk_roll_change,
      r.com_error_max_m, r.com_error_final_m, r.foot_slip_max_m, r.survived,
      static_cast<unsigned long long>(r.contact_fallbacks),
      static_cast<unsigned long long>(r.qp_failures), r.tick_latency_us.p50_us);
}

// The stand: 10 s on both feet, CoM within 5 mm of the controller's target (above the
// mid-point of the sole centres, Sec. 4.2) and no drift. The nominal posture of robot.yaml puts
// the CoM above that target, so the window starts once the robot has settled on its soles
// (0.5 s) and the first 0.5 s are checked too, against 1 cm.
TEST(ClosedLoop, StandsTenSeconds) {
  const double t_settle = 0.5, t_end = t_settle + 10.0;
  InProcessLoop loop(standing(t_end + 0.001), ground_truth());
  // CoM and its error at 0.5 s, 5.5 s and 10.5 s.
  std::array<Eigen::Vector3d, 3> com, err;
  double err_first = 0.0;
  const Watch w = run_and_watch(loop, t_settle, {true, true}, [&](InProcessLoop& l) {
    const double t = l.time();
    if (l.controller().diagnostics().ticks == 0) return;  // no target before the first tick
    const Eigen::Vector3d c = l.truth().com_W;
    const Eigen::Vector3d e = c - l.controller().diagnostics().com_target_W;
    if (t <= t_settle) err_first = std::max(err_first, e.norm());
    for (int i = 0; i < 3; ++i)
      if (std::abs(t - (t_settle + 5.0 * i)) < 5e-4) {
        com[i] = c;
        err[i] = e;
      }
  });
  const RunResult r = loop.result();
  print("stand", w, r);
  std::printf(
      "[stand] CoM error max %.4f m in (0, %.1f] s, %.4f m in [%.1f, %.1f] s; error at 0.5 / 5.5 "
      "/ 10.5 s (x y z, mm): (%.2f %.2f %.2f) (%.2f %.2f %.2f) (%.2f %.2f %.2f); CoM moved "
      "%.5f m in the first 5 s, %.5f m in the last 5 s\n",
      err_first, t_settle, w.com_err_max_after_settle, t_settle, t_end, 1e3 * err[0].x(),
      1e3 * err[0].y(), 1e3 * err[0].z(), 1e3 * err[1].x(), 1e3 * err[1].y(), 1e3 * err[1].z(),
      1e3 * err[2].x(), 1e3 * err[2].y(), 1e3 * err[2].z(), (com[1] - com[0]).norm(),
      (com[2] - com[1]).norm());
  EXPECT_LT(err_first, 0.01);
  EXPECT_LT(w.com_err_max_after_settle, 0.005);
  EXPECT_LT((com[2] - com[1]).norm(), 0.001) << "CoM drift over the last 5 s";
  EXPECT_EQ(w.non_foot_ticks, 0);
  EXPECT_FALSE(w.support_lost);
  EXPECT_LT(w.max_foot_slip, 0.001);
  EXPECT_EQ(r.contact_fallbacks, 0u);
  EXPECT_EQ(r.qp_failures, 0u);
}

// Smooth (minimum-jerk) CoM trajectory from the balance reference: 3 cm towards the left foot and
// 2 cm down in 1 s, with its velocity; the CoM follows it and settles on the new target.
TEST(ClosedLoop, TracksCommandedComShift) {
  InProcessLoop loop(standing(5.0), ground_truth());
  double err_max = 0.0, err_final = 0.0;
  Eigen::Vector3d c0 = Eigen::Vector3d::Zero();
  const Eigen::Vector3d delta(0.0, 0.03, -0.02);
  const double t0 = 2.0, T = 1.0;
  const Watch w = run_and_watch(loop, 0.0, {true, true}, [&](InProcessLoop& l) {
    const double t = l.time();
    if (t < t0) return;
    auto& ref = l.reference();
    if (!ref.has_com_target) c0 = l.controller().diagnostics().com_target_W;
    const double s = std::clamp((t - t0) / T, 0.0, 1.0);
    const double pos = s * s * s * (10 - 15 * s + 6 * s * s);
    const double vel = (t - t0 < T) ? 30 * s * s * (1 - s) * (1 - s) / T : 0.0;
    ref.has_com_target = true;
    ref.com_W = c0 + pos * delta;
    ref.com_velocity_W = vel * delta;
    const double e = (l.truth().com_W - ref.com_W).norm();
    if (t > t0) err_max = std::max(err_max, e);
    err_final = e;
  });
  std::printf("[com shift] tracking error max %.4f m, final %.4f m\n", err_max, err_final);
  EXPECT_LT(err_max, 0.01);
  EXPECT_LT(err_final, 0.005);
  EXPECT_EQ(w.non_foot_ticks, 0);
  EXPECT_FALSE(w.support_lost);
  EXPECT_LT(w.max_foot_slip, 0.002);
}

// Upper-body motion from the balance reference (paper Sec. 3.5 theta_dd^u_d): both shoulders swing
// 0.4 rad at 1 Hz (posture target plus its acceleration). The arms follow; the balance task keeps
// the CoM where it was.
TEST(ClosedLoop, TracksUpperBodyMotionWhileBalancing) {
  InProcessLoop loop(standing(5.0), ground_truth());
  const auto& model = loop.controller().model();
  const int ls = model.joint_index("l_shoulder_pitch");
  const int rs = model.joint_index("r_shoulder_pitch");
  const Eigen::VectorXd q_nom = loop.controller().robot().q_nominal.tail(model.njoints);
  double arm_err_max = 0.0, com_err_max = 0.0, arm_amp = 0.0;
  Eigen::Vector3d com_start = Eigen::Vector3d::Zero();
  const double t0 = 2.0, A = 0.4, w0 = 2 * M_PI;
  run_and_watch(loop, 0.0, {true, true}, [&](InProcessLoop& l) {
    const double t = l.time();
    auto& ref = l.reference();
    if (t < t0) {
      com_start = l.truth().com_W;
      return;
    }
    const double ramp = std::min(1.0, (t - t0) / 0.5);  // fade in over 0.5 s
    ref.has_upper_body_q = true;
    ref.upper_body_q = q_nom;
    ref.upper_body_qdd.setZero();
    ref.upper_body_qd.setZero();
    for (int j : {ls, rs}) {
      ref.upper_body_q[j] = q_nom[j] + ramp * A * std::sin(w0 * (t - t0));
      ref.upper_body_qd[j] = ramp * A * w0 * std::cos(w0 * (t - t0));
      ref.upper_body_qdd[j] = -ramp * A * w0 * w0 * std::sin(w0 * (t - t0));
    }
    if (t > t0 + 1.0) {
      const auto& q = l.state().q;
      arm_err_max = std::max(arm_err_max, std::abs(q[ls] - ref.upper_body_q[ls]));
      arm_amp = std::max(arm_amp, std::abs(q[ls] - q_nom[ls]));
      com_err_max = std::max(com_err_max, (l.truth().com_W - com_start).head<2>().norm());
    }
  });
  std::printf(
      "[upper body] arm error max %.3f rad (amplitude %.3f), CoM horizontal change max %.4f m\n",
      arm_err_max, arm_amp, com_err_max);
  EXPECT_GT(arm_amp, 0.3);        // the arms really moved
  EXPECT_LT(arm_err_max, 0.08);   // and followed the reference
  EXPECT_LT(com_err_max, 0.005);  // while the CoM stayed put
}

// Paper Fig. 8: for a small push the admissible momentum rate equals the desired one; for the
// paper's push (120 N, 0.1 s) the CoP reaches the edge of the safe region, the admissible LINEAR
// rate still equals the desired one while the ANGULAR rate gives way, and the trunk rotates.
struct RateGap {
  double k_gap_max = 0.0;  ///< max |k_dot_d - k_dot_a| [N m]
  double l_gap_max = 0.0;  ///< max |l_dot_d - l_dot_a| [N]
  double l_max = 0.0;      ///< max |l_dot_d| [N] during the push response
  double trunk_pitch = 0.0;
  double l_gap_quiet = 0.0;  ///< max |l_dot_d - l_dot_a| in the 0.5 s before the push [N]
};

RateGap push_rates(double force) {
  scenario::Scenario s = scenario("forward_push_double_support");
  s.sim.pushes[0].force_W = Eigen::Vector3d(force, 0, 0);
  const double start = s.sim.pushes[0].start;
  s.duration = start + 1.5;
  InProcessLoop loop(s, ground_truth());
  RateGap g;
  const Watch w = run_and_watch(loop, 0.0, {true, true}, [&](InProcessLoop& l) {
    const auto& d = l.controller().diagnostics();
    if (l.time() < start) {
      if (l.time() > start - 0.5)
        g.l_gap_quiet = std::max(g.l_gap_quiet,
                                 (d.hdot_desired.tail<3>() - d.hdot_admissible.tail<3>()).norm());
      return;
    }
    g.k_gap_max =
        std::max(g.k_gap_max, (d.hdot_desired.head<3>() - d.hdot_admissible.head<3>()).norm());
    g.l_gap_max =
        std::max(g.l_gap_max, (d.hdot_desired.tail<3>() - d.hdot_admissible.tail<3>()).norm());
    g.l_max = std::max(g.l_max, (d.hdot_desired.tail<3>() -
                                 l.controller().problem().mass * l.controller().problem().gravity)
                                    .head<2>()
                                    .norm());
  });
  g.trunk_pitch = w.max_trunk_pitch_change;
  std::printf(
      "[fig8 %.0f N] |k_d - k_a| max %.2f N m, |l_d - l_a| max %.2f N, |l_d,xy| max %.1f N, "
      "trunk pitch %.3f rad; before the push |l_d - l_a| max %.2f N\n",
      force, g.k_gap_max, g.l_gap_max, g.l_max, g.trunk_pitch, g.l_gap_quiet);
  return g;
}

TEST(ClosedLoop, Fig8DesiredAndAdmissibleMomentumRates) {
  const RateGap small = push_rates(20.0);
  const RateGap large = push_rates(120.0);
  // Small push: admissible == desired, to the optimiser's regularisation (the linear gap is
  // ~1.2 N standing still, ~2.2 N during the push: below 1 % of the weight).
  EXPECT_LT(small.k_gap_max, 0.5);
  EXPECT_LT(small.l_gap_max, 0.01 * 50.8 * 9.81);
  // Large push: angular momentum gives way, linear momentum is kept.
  EXPECT_GT(large.k_gap_max, 10.0);  // N m
  // Linear: within 10 % (eq. (21) trades a little linear momentum for ankle torque, w_k = 0.1).
  EXPECT_LT(large.l_gap_max, 0.1 * large.l_max);
  EXPECT_GT(large.trunk_pitch, small.trunk_pitch + 0.1);  // the trunk rotates
}

/// A run on the platform scenarios (controller on ground truth): the feet's slip on their own
/// platform, the CoM error against the controller's target, contact losses.
struct PlatformRun {
  double slip = 0.0, com_err = 0.0, com_travel = 0.0;
  int lost = 0, non_foot = 0;
  bool survived = false;
};

PlatformRun ride_platforms(scenario::Scenario s, contact::Method method, const char* name,
                           const std::optional<controller::ControllerConfig>& config = {}) {
  LoopOptions opt = ground_truth();
  opt.contact_method = method;
  opt.controller = config;
  InProcessLoop loop(s, opt);
  // Foot f stands on platform platform_of[f].
  const auto& feet = s.sim.robot.feet;
  std::array<int, 2> platform_of{-1, -1};
  for (std::size_t k = 0; k < s.sim.world.platforms.size(); ++k)
    for (std::size_t f = 0; f < feet.size(); ++f)
      if (feet[f].name == s.sim.world.platforms[k].foot) platform_of[f] = static_cast<int>(k);
  EXPECT_GE(platform_of[0], 0);
  EXPECT_GE(platform_of[1], 0);
  PlatformRun run;
  if (platform_of[0] < 0 || platform_of[1] < 0) return run;
  std::array<Eigen::Vector3d, 2> offset0;
  for (int f = 0; f < 2; ++f)
    offset0[f] = loop.truth().feet[f].X_WF.translation() -
                 loop.truth().platform_X_WP[platform_of[f]].translation();
  double com_x_min = 1e9, com_x_max = -1e9;
  const auto steps = static_cast<long>(std::llround(loop.duration() / 1e-3));
  for (long k = 0; k < steps; ++k) {
    loop.step();
    const auto& t = loop.truth();
    for (int f = 0; f < 2; ++f) {
      const Eigen::Vector3d off =
          t.feet[f].X_WF.translation() - t.platform_X_WP[platform_of[f]].translation();
      run.slip = std::max(run.slip, (off - offset0[f]).norm());
      run.lost += !t.feet[f].in_contact;
    }
    run.non_foot += t.num_non_foot_contacts > 0;
    if (loop.time() > 0.5)
      run.com_err =
          std::max(run.com_err, (t.com_W - loop.controller().diagnostics().com_target_W).norm());
    com_x_min = std::min(com_x_min, t.com_W.x());
    com_x_max = std::max(com_x_max, t.com_W.x());
  }
  run.com_travel = com_x_max - com_x_min;
  run.survived = loop.result().survived;
  std::printf(
      "[%s] %.1f s: CoM error max %.4f m, foot slip on its platform %.5f m, CoM travelled %.3f m, "
      "foot-contact losses %d, non-foot ticks %d, survived %d\n",
      name, loop.time(), run.com_err, run.slip, run.com_travel, run.lost, run.non_foot,
      run.survived);
  return run;
}

/// Survived, carried along (> 1.5 m), CoM within 3 cm of its target, feet stuck to their
/// platforms (< 5 mm), never a lost foot contact or a non-foot contact.
void expect_rode_the_platforms(const PlatformRun& r) {
  EXPECT_TRUE(r.survived);
  EXPECT_GT(r.com_travel, 1.5) << "the supports carried the robot";
  EXPECT_LT(r.com_err, 0.03);
  EXPECT_LT(r.slip, 0.005);
  EXPECT_EQ(r.lost, 0);
  EXPECT_EQ(r.non_foot, 0);
}

// Paper Sec. 4.2 on level supports: both feet on platforms moving in sync (1 m at 0.12 Hz, as
// platforms_in_phase but not inclined), controller on ground truth. The resting-foot rule makes
// the feet's desired motion follow the supports and the CoM target ride above their mid-point
// with their mean velocity. Before the simulator's padded platform boxes, Bullet dropped a
// resting sole's contact points for single steps and this run fell at 8.5 s.
TEST(ClosedLoop, RidesLevelPlatformsMovingInSync) {
  scenario::Scenario s = scenario("platforms_in_phase");
  ASSERT_EQ(s.sim.world.platforms.size(), 2u);
  for (auto& p : s.sim.world.platforms)
    p.pitch = 0.0;
  for (std::size_t j = 0; j < s.sim.initial.joint_names.size(); ++j)
    if (s.sim.initial.joint_names[j] == "l_ankle_pitch" ||
        s.sim.initial.joint_names[j] == "r_ankle_pitch")
      s.sim.initial.joint_positions[j] = -0.3;  // soles flat, as robot.yaml's nominal posture
  const PlatformRun r = ride_platforms(s, contact::Method::kSequential, "level platforms in sync");
  expect_rode_the_platforms(r);
}

// The paper's Fig. 10 top as shipped (+10 / -10 deg supports in sync, 1 m at 0.12 Hz) with the QP
// contact optimiser, which bounds the normal torque |m_z| <= mu_torsion f_z at each foot. (The
// sequential optimiser does not survive it yet: with the supports pitched in opposite directions
// the normal forces make a yaw moment, and its CoPs end up at the soles' inner edges.)
TEST(ClosedLoop, RidesInclinedPlatformsInSyncWithQpContacts) {
  const PlatformRun r = ride_platforms(scenario("platforms_in_phase"), contact::Method::kQp,
                                       "inclined platforms in sync, qp");
  expect_rode_the_platforms(r);
}

// The shipped inclined supports in sync at 0.15 Hz (issue #17 item 1's target) over three full
// periods: up to 0.89 m/s^2 of support acceleration. With the CoM target on the sole mid-point
// (the paper's Sec. 4.2) the decelerating supports put both CoPs at the toes and the feet tip
// (measured: falls at 4.7 s, the first deceleration); leaning the target into the supports'
// acceleration (momentum.support_acceleration_hz, on in the scenario) keeps the CoPs mid-sole.
TEST(ClosedLoop, RidesInclinedPlatformsInSyncAt015HzOnlyByLeaningIntoTheirAcceleration) {
  scenario::Scenario s = scenario("platforms_in_phase");
  ASSERT_EQ(s.sim.world.platforms.size(), 2u);
  for (auto& p : s.sim.world.platforms) p.translation.frequency = 0.15;
  s.duration = 2.0 + 4.0 + 3.0 / 0.15;
  ASSERT_FALSE(s.controller_yaml.empty()) << "the scenario configures its moving supports";
  controller::ControllerConfig with =
      controller::parse_controller_config(s.controller_yaml, "platforms_in_phase controller");
  ASSERT_GT(with.momentum.support_acceleration_hz, 0.0);
  ASSERT_GT(with.foot.support_acceleration_tau, 0.0);
  controller::ControllerConfig without = with;
  without.momentum.support_acceleration_hz = 0.0;
  const PlatformRun lean =
      ride_platforms(s, contact::Method::kQp, "in sync 0.15 Hz, leaning into a_s", with);
  const PlatformRun upright =
      ride_platforms(s, contact::Method::kQp, "in sync 0.15 Hz, Sec. 4.2 target", without);
  expect_rode_the_platforms(lean);
  EXPECT_FALSE(upright.survived);
}

// Out-of-phase supports (the shipped platforms_out_of_phase, +-10 deg, 1 Hz) at 0.1 m instead of
// 0.4 m amplitude: up to 3.9 m/s^2 of support acceleration, opposite at the two feet. Eq (36)
// as written asks a resting foot zero acceleration, and the robot falls; with the feet's
// measured acceleration fed forward (foot.support_acceleration_tau) it rides them.
TEST(ClosedLoop, RidesSmallOutOfPhasePlatformsOnlyWithSupportAccelerationFeedForward) {
  scenario::Scenario s = scenario("platforms_out_of_phase");
  ASSERT_EQ(s.sim.world.platforms.size(), 2u);
  for (auto& p : s.sim.world.platforms)
    p.translation.amplitude = 0.1;
  controller::ControllerConfig config;
  config.foot.support_acceleration_tau = 0.0;
  const PlatformRun without =
      ride_platforms(s, contact::Method::kQp, "out of phase 0.1 m, eq (36) as written", config);
  config.foot.support_acceleration_tau = 0.01;
  const PlatformRun with =
      ride_platforms(s, contact::Method::kQp, "out of phase 0.1 m, feed-forward", config);
  EXPECT_TRUE(with.survived);
  EXPECT_LT(with.com_err, 0.01);
  EXPECT_LT(with.slip, 0.005);
  EXPECT_EQ(with.lost, 0);
  EXPECT_EQ(with.non_foot, 0);
  // Measured: without the start-up hold it falls; with it (10 ticks, poise-sim's and now the
  // in-process loop's default) it stays up, a foot slipping 13.7 mm with 39 foot-contact losses
  // (0 mm and 0 with the feed-forward).
  EXPECT_TRUE(!without.survived || without.slip > 0.01 || without.lost > 10)
      << "without the feed-forward the feet slip or the robot falls";
}

// Issue #17 item 1's target, shipped as platforms_out_of_phase_20cm: +-0.2 m at 1 Hz, up to
// 7.9 m/s^2 opposite at the two feet. Both feet on the ground close a loop through the legs; the
// legs' joint references, integrated open loop (eqs (34)-(35)), drift off it, and the joint PD
// squeezed the feet apart (measured before: +-17 N m on the hip pitches, 40 N of tangential
// force at each foot the contact problem never planned, then stick-slip and the feet tipping).
// With the scenario's feedback.support_leg_leak_hz the references follow the measured legs.
TEST(ClosedLoop, RidesOutOfPhasePlatformsAt1HzOnlyWhenTheLegsReferencesDoNotSqueeze) {
  scenario::Scenario s = scenario("platforms_out_of_phase_20cm");
  ASSERT_EQ(s.sim.world.platforms.size(), 2u);
  EXPECT_DOUBLE_EQ(s.sim.world.platforms[0].translation.amplitude, 0.2);
  EXPECT_DOUBLE_EQ(s.sim.world.platforms[0].translation.frequency, 1.0);
  ASSERT_FALSE(s.controller_yaml.empty()) << "the scenario configures its moving supports";
  controller::ControllerConfig with = controller::parse_controller_config(
      s.controller_yaml, "platforms_out_of_phase_20cm controller");
  ASSERT_GT(with.feedback.support_leg_leak_hz, 0.0);
  controller::ControllerConfig without = with;
  without.feedback.support_leg_leak_hz = 0.0;
  for (const auto method : {contact::Method::kSequential, contact::Method::kQp}) {
    const bool qp = method == contact::Method::kQp;
    SCOPED_TRACE(qp ? "qp" : "sequential");
    const PlatformRun leak = ride_platforms(s, method, qp ? "1 Hz, leak, qp" : "1 Hz, leak", with);
    const PlatformRun squeeze =
        ride_platforms(s, method, qp ? "1 Hz, no leak, qp" : "1 Hz, no leak", without);
    EXPECT_TRUE(leak.survived);
    EXPECT_LT(leak.com_err, 0.02);
    EXPECT_LT(leak.slip, 0.005);
    EXPECT_EQ(leak.non_foot, 0);
    EXPECT_TRUE(!squeeze.survived || squeeze.slip > 0.02) << "without it the feet slide or it falls";
  }
}

/// After a push in double support: the mean gap, over the window from 0.5 s after the push to
/// the end, between each foot's true ground force (Bullet) and the force the controller used
/// (TickDiagnostics::foot_wrench_W), tangential and normal [N].
struct ForceGap {
  double tangential = 0.0, normal = 0.0;  // the larger of the two feet's mean gaps
  bool survived = false;
};

ForceGap push_force_gap(const Eigen::Vector3d& force, const controller::ControllerConfig& config,
                        const char* name) {
  scenario::Scenario s = scenario("forward_push_double_support");
  s.sim.pushes[0].force_W = force;
  const double after = s.sim.pushes[0].start + s.sim.pushes[0].duration + 0.5;
  s.duration = after + 2.0;
  LoopOptions opt = ground_truth();
  opt.controller = config;
  InProcessLoop loop(s, opt);
  const std::array<int, 2> sim_of_side = sim_foot_of_side(loop);
  std::array<Eigen::Vector3d, 2> gap_sum{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  long n = 0;
  const auto steps = static_cast<long>(std::llround(loop.duration() / 1e-3));
  for (long k = 0; k < steps; ++k) {
    loop.step();
    if (loop.time() < after) continue;
    const auto& d = loop.controller().diagnostics();
    for (int side = 0; side < 2; ++side)
      gap_sum[side] +=
          loop.truth().feet[sim_of_side[side]].force_W - d.foot_wrench_W[side].head<3>();
    ++n;
  }
  ForceGap g;
  for (int side = 0; side < 2; ++side) {
    const Eigen::Vector3d mean = gap_sum[side] / static_cast<double>(std::max(n, 1L));
    g.tangential = std::max(g.tangential, mean.head<2>().norm());
    g.normal = std::max(g.normal, std::abs(mean.z()));
  }
  g.survived = loop.result().survived;
  std::printf("[%s] mean true - used foot force from 0.5 s after the push: tangential %.1f N, "
              "normal %.1f N; survived %d\n",
              name, g.tangential, g.normal, g.survived);
  return g;
}

// Issue #17 item 2, why the feet end up at opposite sole edges and slide after a push: the legs'
// joint references, integrated open loop (eqs (34)-(35)), leave the loop the two feet close
// through the ground, and the joint PD then squeezes the feet with forces the contact problem
// never planned, for as long as the robot stands (measured on the estimator: 35 N and 23 N
// tangential, 70 N of normal force moved between the feet). FeedbackConfig::
// internal_force_leak_hz removes only that squeeze: the feet then carry the planned forces.
TEST(ClosedLoop, AfterASidewaysPushTheFeetCarryThePlannedForcesNotASqueeze) {
  const controller::ControllerConfig with;  // the default
  ASSERT_GT(with.feedback.internal_force_leak_hz, 0.0);
  controller::ControllerConfig without = with;
  without.feedback.internal_force_leak_hz = 0.0;
  const Eigen::Vector3d push(0.0, -175.0, 0.0);
  const ForceGap leak = push_force_gap(push, with, "175 N rightward, internal-force leak (default)");
  const ForceGap squeeze = push_force_gap(push, without, "175 N rightward, paper's integration");
  // (Measured: 2.9 N / 13.0 N at the default 3 Hz, 1.7 N / 1.2 N at 30 Hz; 25.5 N / 33.3 N without.
  // Since the lifted foot is held where it stood (FootGains::unloaded_kp, 2026-12-04) the far foot
  // lands on its spot and the loop the legs close through the ground is nearly the one they left:
  // 1.2 N / 4.8 N with the leak, 15.7 N / 2.1 N without; the normal squeeze is gone either way.)
  EXPECT_LT(leak.tangential, 8.0);
  EXPECT_LT(leak.normal, 20.0);
  EXPECT_GT(squeeze.tangential, 2.0 * leak.tangential + 10.0);
  // (Survival is not the point here: on ground truth this push slides a foot 15 mm during the
  // push itself, with or without the leak; on the estimator both survive.)
}

// The ankle strategy first (the defaults; controller/momentum/
// README.md "Ankle strategy first"): sideways pushes of 190 and 210 N in double support, both
// ways. With the paper's (11) the trunk rolls ~18 deg, the lifted leg runs into its joint limits
// and that foot lands elsewhere; with the ankle's demand the robot holds them.
TEST(ClosedLoop, HoldsSidewaysPushesInDoubleSupportWithTheAnkleFirst) {
  // The defaults put the ankle strategy first (since 2026-12-04; config/ankle_first.yaml before).
  const controller::ControllerConfig ankle;
  ASSERT_GT(ankle.momentum.ankle_first_blend, 0.0);
  // The paper's (11) (config/paper.yaml) with the lifted foot held by (36)'s kp, kd as before
  // 2026-12-04: with the default held foot (FootGains::unloaded_kp) it holds these four as well
  // (ClosedLoop.AFootAPushLiftsIsHeldWhereItStood).
  controller::ControllerConfig paper = controller::load_controller_config(
      std::string(POISE_SOURCE_DIR) + "/controller/momentum/config/paper.yaml");
  ASSERT_EQ(paper.momentum.ankle_first_blend, 0.0);
  paper.foot.unloaded_kp = paper.foot.kp;
  paper.foot.unloaded_kd = paper.foot.kd;
  int paper_failures = 0;
  for (const double force : {190.0, 210.0}) {
    for (const double side : {1.0, -1.0}) {
      scenario::Scenario s = scenario("forward_push_double_support");
      ASSERT_EQ(s.sim.pushes.size(), 1u);
      s.sim.pushes[0].force_W = Eigen::Vector3d(0.0, side * force, 0.0);
      auto run = [&s](const controller::ControllerConfig& c) {
        LoopOptions o;  // the estimator's state
        o.controller = c;
        InProcessLoop loop(s, o);
        return loop.run();
      };
      const RunResult a = run(ankle);
      const RunResult p = run(paper);
      std::printf("%+.0f N sideways: ankle first %s slip %.1f mm roll %.1f deg; paper %s slip %.1f mm "
                  "roll %.1f deg\n",
                  side * force, a.survived ? "survived" : "FAILED", 1e3 * a.foot_slip_max_m,
                  a.trunk_roll_max_deg, p.survived ? "survived" : "FAILED",
                  1e3 * p.foot_slip_max_m, p.trunk_roll_max_deg);
      EXPECT_TRUE(a.survived) << side * force << " N";
      EXPECT_LT(a.foot_slip_max_m, 0.008) << side * force << " N";
      paper_failures += p.survived ? 0 : 1;
    }
  }
  // (Measured 2026-12-04: the paper's (11) with the lifted foot at kp, kd failed all four on
  // 14.2-19.7 mm of slip, trunk roll 17.6-20.4 deg; the ankle first, its foot held: 2.3-4.6 mm,
  // 12.8-16.4 deg (2.9-5.3 mm, 12.8-15.8 deg with kp, kd before the held foot).)
  EXPECT_GE(paper_failures, 3);
}

// A support foot that a push lifts carries none of the contact forces: only the gains it is held
// with (FootGains::unloaded_kp, unloaded_kd; controller/momentum/README.md "A lifted foot held
// where it stood") keep it over the spot it left while the body rolls above it. Sideways pushes in
// double support, both ways, on the estimator's state: 160 and 165 N with config/ankle_first.yaml
// (its band of failures before) and 190 and 210 N with config/paper.yaml (the paper's (11), the
// defaults before 2026-12-04), each as
// shipped (held foot 400, 40) and with (36)'s kp, kd (100, 20) for that foot: the largest
// horizontal distance of each foot from where it stood, in the air or on the ground (the
// simulator's truth).
TEST(ClosedLoop, AFootAPushLiftsIsHeldWhereItStood) {
  struct Case {
    const char* name;
    controller::ControllerConfig config;
    std::array<double, 2> forces;
    double drift_max, slip_max;  // held: bounds above the measured (see below)
  };
  const std::vector<Case> cases{
      {"ankle first",
       controller::load_controller_config(std::string(POISE_SOURCE_DIR) +
                                          "/controller/momentum/config/ankle_first.yaml"),
       {160.0, 165.0},
       0.008,
       0.005},
      {"paper", controller::load_controller_config(std::string(POISE_SOURCE_DIR) +
                                                   "/controller/momentum/config/paper.yaml"),
       {190.0, 210.0},
       0.035,
       0.011}};
  for (const Case& c : cases) {
    ASSERT_GT(c.config.foot.unloaded_kp, c.config.foot.kp);
    controller::ControllerConfig loose = c.config;
    loose.foot.unloaded_kp = loose.foot.kp;
    loose.foot.unloaded_kd = loose.foot.kd;
    double loose_worst = 0.0;
    int loose_failures = 0;
    int held_survivals = 0;
    double held_worst_slip = 0.0, loose_best_slip = 1e9;
    for (const double force : c.forces) {
      for (const double side : {1.0, -1.0}) {
        scenario::Scenario s = scenario("forward_push_double_support");
        ASSERT_EQ(s.sim.pushes.size(), 1u);
        s.sim.pushes[0].force_W = Eigen::Vector3d(0.0, side * force, 0.0);
        auto run = [&s](const controller::ControllerConfig& config, double* drift) {
          LoopOptions o;  // the estimator's state
          o.controller = config;
          InProcessLoop loop(s, o);
          std::vector<Eigen::Vector2d> start;
          *drift = 0.0;
          while (loop.time() < loop.duration() - 1e-9) {
            loop.step();
            const auto& feet = loop.truth().feet;
            if (start.empty())
              for (const auto& f : feet) start.push_back(f.X_WF.translation().head<2>());
            for (std::size_t i = 0; i < feet.size(); ++i)
              *drift = std::max(*drift, (feet[i].X_WF.translation().head<2>() - start[i]).norm());
          }
          return loop.result();
        };
        double dh = 0.0, dl = 0.0;
        const RunResult h = run(c.config, &dh);
        const RunResult l = run(loose, &dl);
        std::printf("%s, %+.0f N sideways: held foot %s drift %.1f mm slip %.1f mm; kp, kd %s "
                    "drift %.1f mm slip %.1f mm\n",
                    c.name, side * force, h.survived ? "survived" : "FAILED", 1e3 * dh,
                    1e3 * h.foot_slip_max_m, l.survived ? "survived" : "FAILED", 1e3 * dl,
                    1e3 * l.foot_slip_max_m);
        held_survivals += h.survived ? 1 : 0;
        held_worst_slip = std::max(held_worst_slip, h.foot_slip_max_m);
        loose_best_slip = std::min(loose_best_slip, l.foot_slip_max_m);
        EXPECT_LT(dh, c.drift_max) << c.name << ", " << side * force << " N";
        EXPECT_LT(h.foot_slip_max_m, c.slip_max) << c.name << ", " << side * force << " N";
        loose_worst = std::max(loose_worst, dl);
        loose_failures += l.survived ? 0 : 1;
      }
    }
    // Measured 2026-12-04. Ankle first: held, drift 4.7-5.8 mm, slip 1.6-2.0 mm, all survive;
    // kp, kd: drift 11.6-14.6 mm, slip 11.3-14.3 mm, all four fail. Defaults: held, the foot
    // swings 15.6-28.0 mm out in the air (the trunk rolls 17-18 deg; the hip roll's limit,
    // recorded at 30599eb in deploy/logs/2026-12-05-envelope-by-direction.md, is what stops
    // it) but is brought back before it lands: slip 1.8-9.6 mm, all survive; kp, kd: drift 25.3-52.4 mm, slip 13.2-17.4
    // mm, all four fail. (Slip is the sole centre's since 2026-12-04; with the ankle's, as
    // before, held 1.8-2.5 / 2.2-7.4 mm, kp, kd 11.6-14.6 / 14.2-19.7 mm.) The test can tell the
    // two apart by what the held foot controls, where it lands:
    EXPECT_GT(loose_worst, 0.010) << c.name;
    EXPECT_GE(loose_failures, 3) << c.name;
    EXPECT_LT(held_worst_slip, loose_best_slip) << c.name;
    // Survival itself is asked of 3 of the 4 held runs, not all: 210 N rightward with the defaults
    // sits on the recovery criterion's edge, where round-off decides. Measured 2026-12-04: the
    // same eq (36) with the held gains applied to errors computed once instead of twice (equal in
    // exact arithmetic) turned its recovery from 1.48 s into 2.62 s (> 2.5 s: failed) with slip
    // 7.6 mm; the other held runs moved by up to 0.4 mm, one kp, kd run's slip by 4.9 mm.
    EXPECT_GE(held_survivals, 3) << c.name;
  }
}

class ClosedLoopPush : public ::testing::TestWithParam<StateSource> {};

TEST_P(ClosedLoopPush, SurvivesForwardPushInDoubleSupport) {
  // Paper Fig. 8: 120 N for 0.1 s at the CoM, forward. Back within 1 cm within 3 s of the push.
  scenario::Scenario s = scenario("forward_push_double_support");
  ASSERT_EQ(s.sim.pushes.size(), 1u);
  // The IMU of the paper's simulation (ideal): with the shipped industrial MEMS IMU the gyro's
  // white noise (3.1e-3 rad/s per sample) random-walks the weakly held trunk by 1-3.6 deg of roll,
  // and in 4 of 12 noise realisations measured a foot edge lifts for a few ticks (the run still
  // survives its scenario criteria: poise run, and sensor_accuracy_test for the estimator).
  s.sim.imu = sim::ImuNoiseConfig{};
  const double push_end = s.sim.pushes[0].start + s.sim.pushes[0].duration;
  s.duration = push_end + 3.2;
  LoopOptions opt;
  opt.state_source = GetParam();
  InProcessLoop loop(s, opt);
  ASSERT_EQ(loop.result().state_source, GetParam());
  const Watch w = run_and_watch(loop, 0.5, {true, true});
  const RunResult r = loop.result();
  print("forward push", w, r);
  EXPECT_EQ(w.non_foot_ticks, 0);
  EXPECT_FALSE(w.support_lost);
  EXPECT_LT(w.max_foot_slip, 0.01);
  EXPECT_LT(w.max_foot_tilt, 0.035) << "a foot tipped (> 2 deg)";
  EXPECT_LT(w.last_time_com_err_above_1cm, push_end + 3.0);
}

TEST_P(ClosedLoopPush, SurvivesLateralPushInSingleSupport) {
  // Paper Fig. 9: 100 N for 0.1 s, leftward, standing on the left foot.
  scenario::Scenario s = scenario("lateral_push_single_support");
  ASSERT_EQ(s.sim.pushes.size(), 1u);
  const double push_end = s.sim.pushes[0].start + s.sim.pushes[0].duration;
  s.duration = push_end + 3.2;
  LoopOptions opt;
  opt.state_source = GetParam();
  InProcessLoop loop(s, opt);
  ASSERT_EQ(loop.result().state_source, GetParam());
  const Watch w = run_and_watch(loop, 0.5, {false, true});
  const RunResult r = loop.result();
  print("lateral push", w, r);
  EXPECT_EQ(w.non_foot_ticks, 0);
  EXPECT_FALSE(w.support_lost);
  EXPECT_LT(w.max_foot_slip, 0.01);
  EXPECT_LT(w.max_foot_tilt, 0.035) << "the support foot tipped (> 2 deg)";
  EXPECT_LT(w.last_time_com_err_above_1cm, push_end + 3.0);
}

// FeedbackConfig::touchdown_follow_fraction: the step in place sets the right foot down at
// 4.3 s (references/step_in_place.yaml: the swing from 3.7 s for 0.6 s) while the CoM is still
// over the left foot, so the contact solution plans the landed foot no load for a while. With
// the leg's references following its measured joints until the plan loads it, the foot stays
// down; with the touch-down tick's reset only, the leg's PD pressed it with an unplanned load
// that faded, the foot rose and, loaded again late, rocked on its edges (measured 2026-12-04,
// estimator, the other defaults: 2 against 196 ticks a support in the air, largest load 390
// against 943 N).
TEST(ClosedLoop, ALandedFootThePlanDoesNotLoadYetStaysDown) {
  const scenario::Scenario s = scenario("step_in_place");
  struct Landing {
    bool survived = false;
    int support_in_air = 0;  // ticks the controller has it a support, not touching in the truth
    double max_load = 0.0;   // largest true normal force on it [N]
    double slip = 0.0;
  };
  auto run = [&s](double fraction) {
    LoopOptions o;  // the estimator's state
    controller::ControllerConfig c;
    c.feedback.touchdown_follow_fraction = fraction;
    o.controller = c;
    InProcessLoop loop(s, o);
    Landing l;
    while (loop.time() < loop.duration() - 1e-9) {
      loop.step();
      if (loop.time() < 4.3) continue;
      const auto& right = loop.truth().feet[0];
      if (loop.controller().diagnostics().support[0] && !right.in_contact) ++l.support_in_air;
      l.max_load = std::max(l.max_load, right.force_W.z());
    }
    const RunResult r = loop.result();
    l.survived = r.survived;
    l.slip = r.foot_slip_max_m;
    std::printf("touchdown_follow_fraction %.3f: %s, right foot a support in the air %d ticks, "
                "largest load %.0f N, slip %.1f mm\n",
                fraction, r.survived ? "survived" : "FAILED", l.support_in_air, l.max_load,
                1e3 * r.foot_slip_max_m);
    return l;
  };
  const controller::ControllerConfig defaults;
  ASSERT_GT(defaults.feedback.touchdown_follow_fraction, 0.0);
  const Landing follow = run(defaults.feedback.touchdown_follow_fraction);
  const Landing reset_only = run(0.0);
  EXPECT_TRUE(follow.survived);
  EXPECT_LT(follow.support_in_air, 30);
  EXPECT_LT(follow.max_load, 600.0);
  EXPECT_LT(follow.slip, 0.005);
  EXPECT_GT(reset_only.support_in_air, 100) << "the touch-down reset alone left the foot down";
}

// The scenario monitor's CoM error does not count a balance reference's deliberate CoM move
// (sim::ReferenceComShift): on `step_in_place` the CoM truly travels ~0.1 m over the left foot
// and back, and the verdict's CoM error is the distance from the reference's target, a few mm
// (0.10 m before; distributed gives the same figure: OneAnswer.StepInPlaceReferenceCyclone).
TEST(ClosedLoop, AReferencesCoMMoveIsNotCountedAsCoMError) {
  const scenario::Scenario s = scenario("step_in_place");
  ASSERT_FALSE(s.reference.empty());
  InProcessLoop loop(s, LoopOptions{});
  const double y0 = loop.truth().com_W.y();
  double travel = 0.0;
  while (loop.time() < loop.duration() - 1e-9) {
    loop.step();
    travel = std::max(travel, loop.truth().com_W.y() - y0);
  }
  const RunResult r = loop.result();
  std::printf("step_in_place: the CoM travelled %.3f m to the left; verdict CoM error max %.4f m, "
              "final %.4f m\n", travel, r.com_error_max_m, r.com_error_final_m);
  EXPECT_TRUE(r.survived);
  EXPECT_GT(travel, 0.08);
  EXPECT_LT(r.com_error_max_m, 0.02);
}

// MomentumGains::upright_pitch_rate: (10) as written damps the angular momentum and brings
// nothing back, so a push the hip strategy holds leaves the trunk pitched for good. Forward and
// backward pushes in double support (inside the envelope either way), on the estimator's state:
// the trunk's largest tilt over the run's last 0.5 s (2.4-2.9 s after the push), the simulator's
// truth, with the default rate and with it off.
TEST(ClosedLoop, TheTrunkComesBackUprightAfterThePush) {
  const controller::ControllerConfig defaults;
  ASSERT_GT(defaults.momentum.upright_pitch_rate, 0.0);
  for (const double force : {200.0, -230.0}) {
    scenario::Scenario s = scenario("forward_push_double_support");
    ASSERT_EQ(s.sim.pushes.size(), 1u);
    s.sim.pushes[0].force_W = Eigen::Vector3d(force, 0.0, 0.0);
    auto run = [&s](double rate, double& late_tilt_deg) {
      LoopOptions o;  // the estimator's state
      controller::ControllerConfig c;
      c.momentum.upright_pitch_rate = rate;
      o.controller = c;
      InProcessLoop loop(s, o);
      late_tilt_deg = 0.0;
      while (loop.time() < loop.duration() - 1e-9) {
        loop.step();
        if (loop.time() < loop.duration() - 0.5) continue;
        const double c22 = std::clamp(loop.truth().X_WB.rotation()(2, 2), -1.0, 1.0);
        late_tilt_deg = std::max(late_tilt_deg, std::acos(c22) * 180.0 / M_PI);
      }
      return loop.result();
    };
    double upright = 0.0, left = 0.0;
    const RunResult a = run(defaults.momentum.upright_pitch_rate, upright);
    const RunResult b = run(0.0, left);
    std::printf("%+.0f N: upright pitch rate %.1f /s: %s, trunk pitch max %.1f deg, last 0.5 s %.1f deg; "
                "off: %s, %.1f deg, last 0.5 s %.1f deg\n",
                force, defaults.momentum.upright_pitch_rate, a.survived ? "survived" : "FAILED",
                a.trunk_pitch_max_deg, upright, b.survived ? "survived" : "FAILED",
                b.trunk_pitch_max_deg, left);
    EXPECT_TRUE(a.survived) << force << " N";
    EXPECT_GT(a.trunk_pitch_max_deg, 10.0) << "the hip strategy was used";
    EXPECT_LT(upright, 6.0) << force << " N";
    EXPECT_GT(left, 12.0) << force << " N: without it the trunk stays pitched";
  }
}

// FeedbackConfig::velocity_leak_hz: the paper's references integrated open loop carry a mode of
// their own (e = theta* - theta obeys e'' = -M^-1 (K e + D e') whatever the momentum loop asks),
// which the robot's joint gains leave lightly damped: after the paper's 120 N forward push the
// whole robot rocks on its ankles for seconds. The trunk's pitch and the CoM's forward error
// (the simulator's truth, the estimator's state) from 2 to 5 s after the push: without the
// leak they swing back and forth; with 1 Hz they settle.
TEST(ClosedLoop, TheJointReferencesModeRocksTheRobotAfterAPushUnlessTheirVelocityLeaks) {
  scenario::Scenario s = scenario("forward_push_double_support");
  ASSERT_EQ(s.sim.pushes.size(), 1u);
  const double push_end = s.sim.pushes[0].start + s.sim.pushes[0].duration;
  s.duration = push_end + 5.0;
  struct Rocking {
    double pitch_lo = 1e9, pitch_hi = -1e9, com_error = 0.0;
    int pitch_turns = 0;
    bool survived = false;
  };
  auto run = [&](double leak_hz) {
    LoopOptions o;  // the estimator's state
    controller::ControllerConfig c;
    c.feedback.velocity_leak_hz = leak_hz;
    o.controller = c;
    InProcessLoop loop(s, o);
    Rocking r;
    double com_x0 = 0.0, last = 0.0;
    int direction = 0;
    bool first = true;
    while (loop.time() < loop.duration() - 1e-9) {
      loop.step();
      if (first) com_x0 = loop.truth().com_W.x(), first = false;
      if (loop.time() < push_end + 2.0) continue;
      const Eigen::Matrix3d R = loop.truth().X_WB.rotation();
      const double pitch = std::atan2(-R(2, 0), R(2, 2)) * 180.0 / M_PI;
      r.pitch_lo = std::min(r.pitch_lo, pitch);
      r.pitch_hi = std::max(r.pitch_hi, pitch);
      // Turns of the pitch, from moves of more than 0.2 deg (noise and round-off aside).
      if (std::abs(pitch - last) > 0.2) {
        const int d = pitch > last ? 1 : -1;
        if (direction != 0 && d != direction) ++r.pitch_turns;
        direction = d;
        last = pitch;
      }
      r.com_error = std::max(r.com_error, std::abs(loop.truth().com_W.x() - com_x0));
    }
    r.survived = loop.result().survived;
    std::printf("velocity_leak_hz %.1f: %s; 2-5 s after the push: trunk pitch %.2f..%.2f deg, "
                "%d turns, CoM forward error max %.1f mm\n",
                leak_hz, r.survived ? "survived" : "FAILED", r.pitch_lo, r.pitch_hi,
                r.pitch_turns, 1e3 * r.com_error);
    return r;
  };
  const Rocking plain = run(0.0);
  const Rocking leaky = run(1.0);
  EXPECT_TRUE(plain.survived);
  EXPECT_TRUE(leaky.survived);
  EXPECT_GT(plain.pitch_hi - plain.pitch_lo, 4.0) << "the mode shows without the leak";
  EXPECT_GE(plain.pitch_turns, 2);
  EXPECT_GT(plain.com_error, 0.004);
  EXPECT_LT(leaky.pitch_hi - leaky.pitch_lo, 1.5);
  EXPECT_LE(leaky.pitch_turns, 1);
  EXPECT_LT(leaky.com_error, 0.003);
}

INSTANTIATE_TEST_SUITE_P(StateSources, ClosedLoopPush,
                         ::testing::Values(StateSource::kGroundTruth, StateSource::kEstimator),
                         [](const auto& info) { return std::string(to_string(info.param)); });

}  // namespace
}  // namespace poise::inprocess
