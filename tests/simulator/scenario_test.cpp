// Scenario files: the shipped paper scenarios load and put the robot on its supports; schema
// errors name the key; the monitor's verdict quantities. The format is poise::scenario
// (deploy/scenario), the world part of it and the monitor poise::sim (simulator/sim).
#include <gtest/gtest.h>

#include <limits>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <fstream>
#include <vector>

#include "poise/scenario/scenario.hpp"
#include "poise/sim/simulator.hpp"
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

namespace fs = std::filesystem;
using scenario::load_scenario;
using scenario::parse_scenario;
using scenario::Scenario;

// PD hold of the posture in `s` (kp 300, kd 6 on every joint).
JointCommand hold_posture_command(const Simulator& sim, const SensorFrame& s) {
  JointCommand c = sim.make_command();
  c.mode = CommandMode::kPd;
  c.q_ref = s.q;
  c.kp.setConstant(300);
  c.kd.setConstant(6);
  return c;
}
const fs::path kScenarios = fs::path(POISE_SOURCE_DIR) / "deploy/scenarios";

std::string error_of(const std::string& yaml) {
  try {
    parse_scenario(yaml, fs::path(POISE_SOURCE_DIR) / "tests/simulator", "test.yaml");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

const char* kInline = R"(
name: inline
duration: 1.0
robot:
  urdf: urdf/biped.urdf
  imu_frame: imu_link
  feet:
    left: {frame: l_sole}
    right: {frame: r_sole}
initial:
  posture: zero
  joints: {l_knee: 0.6, r_knee: 0.6, l_hip_pitch: -0.3, r_hip_pitch: -0.3,
           l_ankle_pitch: -0.3, r_ankle_pitch: -0.3}
disturbances:
  pushes:
    - {link: torso, point: [0, 0, 0.1], force: [50, 0, 0], start: 0.2, duration: 0.05}
)";

TEST(SimScenario, InlineRobotScenarioLoads) {
  const Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  EXPECT_EQ(sc.name, "inline");
  ASSERT_EQ(sc.sim.robot.feet.size(), 2u);
  ASSERT_EQ(sc.sim.pushes.size(), 1u);
  EXPECT_EQ(sc.sim.pushes[0].force_W, Eigen::Vector3d(50, 0, 0));
  Simulator sim(sc.sim);
  EXPECT_EQ(sim.num_joints(), 10);
}

TEST(SimScenario, SchemaErrorsNameTheKey) {
  const std::string base = kInline;
  EXPECT_NE(error_of(base + "colour: red\n").find("colour: unknown key"), std::string::npos);
  EXPECT_NE(error_of("name: x\nrobot: {urdf: urdf/biped.urdf, feet: {l: {frame: l_sole}}}\n")
                .find("duration"),
            std::string::npos);
  std::string e = error_of(base + "world:\n  platforms:\n    - {foot: left, frction: 0.5}\n");
  EXPECT_NE(e.find("world.platforms[0].frction: unknown key"), std::string::npos) << e;
  e = error_of(base + "world:\n  platforms:\n    - {foot: middle}\n");
  EXPECT_NE(e.find("world.platforms[0].foot"), std::string::npos) << e;
  e = error_of(base + "success: {com_error_max_m: big}\n");
  EXPECT_NE(e.find("success.com_error_max_m: must be a number"), std::string::npos) << e;
  e = error_of(base + "dds: {vendor: zeromq}\n");
  EXPECT_NE(e.find("dds.vendor"), std::string::npos) << e;
  e = error_of(base + "estimator: {supports: ship}\n");
  EXPECT_NE(e.find("estimator.supports: must be 'fixed', 'moving' or 'translating'"), std::string::npos) << e;
  e = error_of(base + "estimator: {suports: moving}\n");
  EXPECT_NE(e.find("estimator.suports: unknown key"), std::string::npos) << e;
  e = error_of(base + "contact: {method: lcp}\n");
  EXPECT_NE(e.find("contact.method: must be 'sequential' or 'qp'"), std::string::npos) << e;
  const Scenario hinted = parse_scenario(
      base + "estimator: {supports: moving}\ncontact: {method: qp}\n",
      fs::path(POISE_SOURCE_DIR) / "tests/simulator", "test.yaml");
  EXPECT_EQ(hinted.estimator.supports, "moving");
  EXPECT_EQ(hinted.contact_method, "qp");
  e = error_of(std::string(kInline).replace(std::string(kInline).find("urdf/biped.urdf"), 15,
                                            "urdf/none.urdf"));
  EXPECT_NE(e.find("robot.urdf: file 'urdf/none.urdf' not found"), std::string::npos) << e;
  e = error_of(base + "sensors: {imu: {gyro_noise_std: -1}}\n");
  EXPECT_NE(e.find("sensors.imu.gyro_noise_std"), std::string::npos) << e;
  EXPECT_NE(error_of("[1, 2").find("invalid YAML"), std::string::npos);
}

#ifdef POISE_SIM_TEST_HAVE_MODEL
// initial.support names one foot: the start must be one the robot can stand in. The shipped
// single-support scenario loads; the same with both legs in the nominal posture (the other sole
// on the ground too) and with the leg folded but the CoM not leaned over the sole are refused,
// naming the key and the figure, before anything runs (with the nominal posture the robot fell:
// the controller held the right foot as lifted while it stood on the ground).
TEST(SimScenario, ASingleSupportStartTheRobotCannotStandInIsRefused) {
  const fs::path file = kScenarios / "lateral_push_single_support.yaml";
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string shipped = ss.str();
  EXPECT_NO_THROW(parse_scenario(shipped, kScenarios, "single.yaml"));
  const auto error = [&](const std::string& yaml) {
    try {
      parse_scenario(yaml, kScenarios, "single.yaml");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  // Both legs as in double support.
  std::string both = shipped;
  const std::size_t j0 = both.find("  joints:"), j1 = both.find("world:");
  ASSERT_NE(j0, std::string::npos);
  ASSERT_NE(j1, std::string::npos);
  both.erase(j0, j1 - j0);
  std::string e = error(both);
  EXPECT_NE(e.find("initial.support: 'left', but in the initial posture the right sole is 0.0 mm "
                   "above the left one"),
            std::string::npos)
      << e;
  // Right leg folded, no lean: the CoM stays between the feet.
  std::string nolean = shipped;
  for (const char* key : {"    l_hip_roll: -0.15\n", "    l_ankle_roll: 0.15\n",
                          "    r_hip_roll: -0.15\n", "    r_ankle_roll: 0.15\n"}) {
    const std::size_t at = nolean.find(key);
    ASSERT_NE(at, std::string::npos) << key;
    nolean.erase(at, std::string(key).size());
  }
  e = error(nolean);
  EXPECT_NE(e.find("initial.support: 'left', but in the initial posture the CoM is 35.0 mm "
                   "outside the left sole"),
            std::string::npos)
      << e;
  // Double support with the same folded leg is not checked here (the monitor's business).
  std::string dbl = nolean;
  dbl.replace(dbl.find("support: left"), 13, "support: double");
  EXPECT_EQ(error(dbl), "");
}

// The ground's finite broadphase box (solver.ground_aabb_band) only drops link/ground pairs the
// narrowphase would not have given a contact point: the pushed humanoid (held by PD only) moves
// the same as with Bullet's infinite plane box, contacts and non-foot contacts included.
struct Trace {
  std::vector<Eigen::Vector3d> com;
  std::vector<Eigen::Vector3d> total_force;
  std::vector<int> points, non_foot;
};
Trace run_pushed(const Scenario& sc, double band, int ticks) {
  SimulatorConfig cfg = sc.sim;
  cfg.solver.ground_aabb_band = band;
  Simulator sim(cfg);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  sim.read(s, g);
  JointCommand c = hold_posture_command(sim, s);
  Trace t;
  for (int k = 0; k < ticks; ++k) {
    sim.step(c, s, g);
    t.com.push_back(g.com_W);
    t.total_force.push_back(g.total_contact_force_W);
    int points = 0;
    for (const auto& f : g.feet)
      points += f.num_points;
    t.points.push_back(points);
    t.non_foot.push_back(g.num_non_foot_contacts);
  }
  return t;
}

TEST(SimScenario, GroundBroadphaseBandLeavesTheMotionUnchanged) {
  for (const char* name : {"forward_push_double_support", "lateral_push_single_support"}) {
    SCOPED_TRACE(name);
    Scenario sc = load_scenario(kScenarios / (std::string(name) + ".yaml"));
    ASSERT_FALSE(sc.sim.pushes.empty());
    const double push_end = sc.sim.pushes[0].start + sc.sim.pushes[0].duration;
    const int ticks = static_cast<int>(std::lround((push_end + 0.9) / sc.sim.solver.dt));
    ASSERT_GT(SolverConfig{}.ground_aabb_band, 0.0);
    const Trace banded = run_pushed(sc, SolverConfig{}.ground_aabb_band, ticks);
    const Trace infinite = run_pushed(sc, 0.0, ticks);
    // Fewer ground pairs reorder Bullet's contact manifolds, i.e. the sequential-impulse rows:
    // the runs may part at round-off level, never by a physical difference (a contact the other
    // run has not). Before they part (1e-9 m) contacts and forces agree; afterwards the
    // difference stays far below the scenarios' tolerances (cm).
    int parted = ticks;
    double com_diff = 0.0, force_diff = 0.0, moved = 0.0;
    for (int k = 0; k < ticks; ++k) {
      const auto i = static_cast<std::size_t>(k);
      const double d = (banded.com[i] - infinite.com[i]).norm();
      com_diff = std::max(com_diff, d);
      moved = std::max(moved, (infinite.com[i] - infinite.com[0]).norm());
      if (parted == ticks && d > 1e-9) parted = k;
      if (k >= parted) continue;
      force_diff = std::max(force_diff, (banded.total_force[i] - infinite.total_force[i]).norm());
      EXPECT_EQ(banded.points[i], infinite.points[i]) << "tick " << k;
      EXPECT_EQ(banded.non_foot[i], infinite.non_foot[i]) << "tick " << k;
    }
    EXPECT_GT(moved, 0.01) << "the push moves the robot";
    EXPECT_LT(force_diff, 1e-3);
    EXPECT_LT(com_diff, 1e-3);
    if (sc.support == "double") {
      EXPECT_EQ(parted, ticks) << "standing on both feet: no parting";
    }
    std::printf("%s: parted at tick %d of %d, max CoM difference %.3g m\n", name, parted, ticks,
                com_diff);
  }
}

TEST(SimScenario, PaperScenariosLoadAndStandOnTheirSupports) {
  int count = 0;
  for (const char* name : {"forward_push_double_support", "lateral_push_single_support",
                           "platforms_in_phase", "platforms_out_of_phase"}) {
    SCOPED_TRACE(name);
    const Scenario sc = load_scenario(kScenarios / (std::string(name) + ".yaml"));
    EXPECT_EQ(sc.name, name);
    EXPECT_GT(sc.duration, 0.0);
    Simulator sim(sc.sim);
    SensorFrame s = sim.make_sensor_frame();
    GroundTruth g = sim.make_ground_truth();
    sim.read(s, g);
    JointCommand c = hold_posture_command(sim, s);
    for (int k = 0; k < 100; ++k)
      sim.step(c, s, g);
    // the supporting feet carry the robot, nothing else touches
    double fz = 0.0;
    for (std::size_t f = 0; f < g.feet.size(); ++f) {
      const bool support = sc.support == "double" || sim.foot_names()[f] == sc.support;
      EXPECT_EQ(g.feet[f].in_contact, support) << sim.foot_names()[f];
      fz += g.feet[f].force_W.z();
    }
    EXPECT_NEAR(fz, sim.total_mass() * 9.81, 0.25 * sim.total_mass() * 9.81);
    EXPECT_EQ(g.num_non_foot_contacts, 0);
    ++count;
  }
  EXPECT_EQ(count, 4);
  const Scenario fwd = load_scenario(kScenarios / "forward_push_double_support.yaml");
  ASSERT_EQ(fwd.sim.pushes.size(), 1u);
  EXPECT_DOUBLE_EQ(fwd.sim.pushes[0].force_W.norm() * fwd.sim.pushes[0].duration, 12.0);
  const Scenario oop = load_scenario(kScenarios / "platforms_out_of_phase.yaml");
  ASSERT_EQ(oop.sim.world.platforms.size(), 2u);
  EXPECT_NEAR(std::abs(oop.sim.world.platforms[0].translation.phase -
                       oop.sim.world.platforms[1].translation.phase),
              M_PI, 1e-12);
  EXPECT_NEAR(oop.sim.world.platforms[0].pitch, -oop.sim.world.platforms[1].pitch, 1e-12);
}
#endif

TEST(SimScenario, MonitorMeasuresComErrorAndSlipAgainstTheSupports) {
  Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  sc.sim.world.platforms.resize(1);
  sc.sim.world.platforms[0].foot = "left";
  sc.success.com_error_final_m = 0.05;
  sc.success.foot_slip_max_m = 0.01;
  ScenarioMonitor mon(sc, platforms_of_feet(sc));
  GroundTruth g;
  g.feet.resize(2);
  g.platform_X_WP.assign(1, Eigen::Isometry3d::Identity());
  g.non_foot_contact.assign(3, 0);
  // feet at y = +-0.1 (left on a platform), CoM 2 cm ahead of their centre
  auto set = [&](double t, double platform_x, double com_x, double left_slip) {
    g.time = t;
    g.platform_X_WP[0].translation().x() = platform_x;
    g.feet[0].X_WF.translation() = Eigen::Vector3d(platform_x + left_slip, 0.1, 0.0);
    g.feet[1].X_WF.translation() = Eigen::Vector3d(0.0, -0.1, 0.0);
    g.feet[0].in_contact = g.feet[1].in_contact = true;
    g.com_W = Eigen::Vector3d(com_x, 0.0, 0.8);
    mon.update(g);
  };
  set(0.0, 0.0, 0.02, 0.0);
  set(0.1, 0.3, 0.17, 0.0);  // platform moved 0.3: feet centre +0.15, CoM followed exactly
  EXPECT_NEAR(mon.result().com_error_max_m, 0.0, 1e-12);
  set(0.2, 0.3, 0.27, 0.004);  // CoM 0.1 ahead of its reference; left foot slid 4 mm
  auto r = mon.result();
  EXPECT_NEAR(r.com_error_max_m, 0.1 - 0.002, 1e-12);  // reference moved 2 mm with the slip
  EXPECT_NEAR(r.foot_slip_max_m, 0.004, 1e-12);
  EXPECT_FALSE(r.survived);  // final error 0.098 > 0.05
  set(0.3, 0.3, 0.172, 0.004);
  r = mon.result();
  EXPECT_NEAR(r.com_error_final_m, 0.0, 1e-12);
  EXPECT_TRUE(r.survived);
  g.num_non_foot_contacts = 1;
  set(0.4, 0.3, 0.172, 0.004);
  EXPECT_FALSE(mon.result().survived);
  EXPECT_EQ(mon.result().non_foot_contacts, 1);
}

/// The truth of a robot on both feet at y = +-0.1 m (no CoM, no time yet).
GroundTruth standing_on_both_feet() {
  GroundTruth g;
  g.feet.resize(2);
  g.non_foot_contact.assign(3, 0);
  g.feet[0].X_WF.translation() = Eigen::Vector3d(0.0, 0.1, 0.0);
  g.feet[1].X_WF.translation() = Eigen::Vector3d(0.0, -0.1, 0.0);
  g.feet[0].in_contact = g.feet[1].in_contact = true;
  return g;
}

// A fall is never a recovery (#54): with no final-error bound (the platform scenarios) a robot
// on the floor reported recovery 0.
TEST(SimScenario, AFallNeverReportsARecoveryTime) {
  Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  sc.sim.world.platforms.clear();
  sc.success.com_error_final_m = std::numeric_limits<double>::infinity();
  sc.success.allow_non_foot_contacts = false;
  ScenarioMonitor mon(sc, platforms_of_feet(sc));
  GroundTruth g = standing_on_both_feet();
  g.com_W = Eigen::Vector3d(0.0, 0.0, 0.8);
  mon.update(g);
  EXPECT_EQ(mon.result().last_recovery_time_s, 0.0) << "standing: recovered at once";
  g.time = 1.0;
  g.num_non_foot_contacts = 1;
  g.com_W = Eigen::Vector3d(0.5, 0.0, 0.2);
  mon.update(g);
  EXPECT_TRUE(std::isinf(mon.result().last_recovery_time_s));
  EXPECT_FALSE(mon.result().survived);
}

// A robot that is not its model (`reality:`): the reference is where the description puts the
// CoM at the start (GroundTruth::model_com_shift_W), so a robot that stands with its own CoM
// where the model's was reads the model's error, and one that moved its CoM there reads 0.
TEST(SimScenario, MonitorCountsTheModelsCoMErrorAsError) {
  Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  sc.sim.world.platforms.clear();
  ScenarioMonitor stays(sc, platforms_of_feet(sc)), moves(sc, platforms_of_feet(sc));
  GroundTruth g = standing_on_both_feet();
  // The robot's CoM 6 mm ahead and 8 mm left of the model's at the start.
  g.com_W = Eigen::Vector3d(0.026, 0.008, 0.8);
  g.model_com_shift_W = Eigen::Vector3d(-0.006, -0.008, 0.0);
  stays.update(g);
  moves.update(g);
  g.time = 1.0;
  stays.update(g);
  g.com_W = Eigen::Vector3d(0.02, 0.0, 0.8);
  moves.update(g);
  EXPECT_NEAR(stays.result().com_error_final_m, 0.01, 1e-12);
  EXPECT_NEAR(moves.result().com_error_final_m, 0.0, 1e-12);
}

// A balance reference's CoM move is not error: the monitor's reference is shifted by the move
// (ReferenceComShift: the applied reference's com_W minus the first CoM target's), so a CoM that
// follows a 0.1 m move over the left foot reads 0, and one that stays behind reads the move.
TEST(SimScenario, MonitorDoesNotCountABalanceReferencesCoMMoveAsError) {
  Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  sc.sim.world.platforms.clear();
  ScenarioMonitor follows(sc, platforms_of_feet(sc)), stays(sc, platforms_of_feet(sc));
  GroundTruth g = standing_on_both_feet();
  // The references (estimator frame, offset by (5, -3) m from the truth's: only their
  // differences count): none before tick 100, then a move of 0.1 m to the left over ticks
  // 100..199, held; tick 300 drops the CoM target (back over the feet's mid-point).
  ReferenceComShift refs(64);
  const Eigen::Vector3d origin(5.0, -3.0, 0.8);
  std::uint64_t sent = 0;
  double worst_follow = 0.0, worst_stay = 0.0;
  for (std::uint64_t k = 0; k < 400; ++k) {
    // The player sends 20 ticks ahead, in order.
    for (; sent <= k + 20; ++sent)
      if (sent >= 100) {
        const double y = 0.1 * std::min(1.0, static_cast<double>(sent - 100) / 99.0);
        refs.put(sent, sent < 300, origin + Eigen::Vector3d(0.0, y, 0.0));
      }
    const Eigen::Vector2d shift = refs.due(k);
    const double expected_y = k < 100 || k >= 300 ? 0.0 : 0.1 * std::min(1.0, (k - 100) / 99.0);
    ASSERT_NEAR(shift.y(), expected_y, 1e-12) << k;
    ASSERT_NEAR(shift.x(), 0.0, 1e-12) << k;
    g.time = 1e-3 * static_cast<double>(k);
    g.com_W = Eigen::Vector3d(0.0, expected_y, 0.8);
    follows.set_com_target_shift(shift);
    follows.update(g);
    worst_follow = std::max(worst_follow, follows.result().com_error_final_m);
    g.com_W = Eigen::Vector3d(0.0, 0.0, 0.8);
    stays.set_com_target_shift(shift);
    stays.update(g);
    worst_stay = std::max(worst_stay, stays.result().com_error_final_m);
  }
  EXPECT_NEAR(worst_follow, 0.0, 1e-12);
  EXPECT_NEAR(worst_stay, 0.1, 1e-12);
  EXPECT_EQ(refs.overflows(), 0u);
  // Tick 0 applies at once, a later tick only at its tick.
  ReferenceComShift now(4);
  now.put(0, true, origin);
  now.put(50, true, origin + Eigen::Vector3d(0.02, 0.0, 0.0));
  EXPECT_NEAR(now.due(1).x(), 0.0, 1e-12);
  EXPECT_NEAR(now.due(49).x(), 0.0, 1e-12);
  EXPECT_NEAR(now.due(50).x(), 0.02, 1e-12);
  // A reference whose CoM target is not finite is not taken: the shift stays (counted).
  now.put(60, true, Eigen::Vector3d(std::nan(""), 0.0, 0.8));
  EXPECT_NEAR(now.due(60).x(), 0.02, 1e-12);
  EXPECT_EQ(now.rejected(), 1u);
  // Past the capacity the oldest held go (counted).
  ReferenceComShift small(4);
  small.put(0, true, origin);
  for (std::uint64_t t = 10; t < 16; ++t) small.put(t, true, origin + Eigen::Vector3d(0.01 * t, 0, 0));
  EXPECT_EQ(small.overflows(), 3u);
  EXPECT_NEAR(small.due(12).x(), 0.0, 1e-12);  // base: tick 12's, the first held with a target
  EXPECT_NEAR(small.due(15).x(), 0.03, 1e-12);
}

TEST(SimScenario, MonitorTellsASlipFromARollOntoTheToeAndATwist) {
  // Foot slip (the criterion): the sole centre's displacement since the start. Foot
  // displacement: the foot frame's (the ankle's). Foot slide: the sole point under the CoP
  // against where that point of the sole was when the contact began. Foot tilt: the sole
  // normal's angle to the support's.
  Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  sc.sim.world.platforms.clear();
  sc.sim.robot.feet[0].has_sole = true;
  sc.sim.robot.feet[0].sole = SoleConfig{-0.08, 0.14, -0.055, 0.055, 0.08, 0.02};
  sc.success.foot_slip_max_m = 0.01;
  const Eigen::Vector3d centre_F(0.03, 0.0, -0.08);  // of that sole, 8 cm below the ankle
  ScenarioMonitor mon(sc, platforms_of_feet(sc));
  GroundTruth g;
  g.feet.resize(2);
  g.non_foot_contact.assign(3, 0);
  g.com_W = Eigen::Vector3d(0.0, 0.0, 0.8);
  auto stand = [&](const Eigen::Isometry3d& X_WF0, const Eigen::Vector3d& cop_F, bool contact) {
    g.feet[0].X_WF = X_WF0;
    g.feet[0].cop_W = X_WF0 * cop_F;
    g.feet[0].in_contact = contact;
    g.feet[1].X_WF = Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.1, 0.08));
    g.feet[1].cop_W = g.feet[1].X_WF * Eigen::Vector3d(0.0, 0.0, -0.08);
    g.feet[1].in_contact = true;
    mon.update(g);
    g.time += 0.001;
  };
  const Eigen::Isometry3d X0(Eigen::Translation3d(0.0, -0.1, 0.08));
  stand(X0, centre_F, true);
  auto about = [](const Eigen::Vector3d& p_W, const Eigen::AngleAxisd& rotation) {
    return Eigen::Isometry3d(Eigen::Translation3d(p_W) * rotation * Eigen::Translation3d(-p_W));
  };
  // Rolled 7.5 deg onto the toe edge (heel up, the CoP on that edge): the ankle swings ~11 mm
  // forward, the sole centre 0.11 (1 - cos 7.5 deg) = 0.94 mm; nothing slides.
  const Eigen::Vector3d toe_F(0.14, 0.0, -0.08);
  const double tilt = 7.5 * M_PI / 180.0;
  const Eigen::Isometry3d rolled =
      about(X0 * toe_F, Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY())) * X0;
  stand(rolled, toe_F, true);
  auto r = mon.result();
  EXPECT_NEAR(r.foot_slip_max_m, 0.11 * (1.0 - std::cos(tilt)), 1e-12);
  EXPECT_NEAR(r.foot_displacement_max_m, (rolled.translation() - X0.translation()).head<2>().norm(),
              1e-12);
  EXPECT_GT(r.foot_displacement_max_m, 0.010);
  EXPECT_LT(r.foot_slide_max_m, 1e-12);
  EXPECT_NEAR(r.foot_tilt_max_deg, 7.5, 1e-9);
  EXPECT_TRUE(r.survived) << "slip 0.9 mm of the 10 mm allowed; no tilt criterion";
  // Back flat, then twisted 6 deg about its toe's outer corner (the CoP there): the sole centre
  // swings 2 |corner - centre| sin(3 deg) = 12.9 mm: slip, no slide (the loaded point stays).
  stand(X0, centre_F, true);
  const Eigen::Vector3d corner_F(0.14, -0.055, -0.08);
  const Eigen::Isometry3d twisted =
      about(X0 * corner_F, Eigen::AngleAxisd(6.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ())) * X0;
  stand(twisted, corner_F, true);
  r = mon.result();
  const double arm = (corner_F - centre_F).norm();
  EXPECT_NEAR(r.foot_slip_max_m, 2.0 * arm * std::sin(3.0 * M_PI / 180.0), 1e-12);
  EXPECT_LT(r.foot_slide_max_m, 1e-12);
  EXPECT_NEAR(r.foot_tilt_max_deg, 7.5, 1e-9) << "a turn about the normal is no tilt";
  // Lifted, and set down 20 mm to the side, flat: a landing elsewhere, slip 20 mm, no slide.
  stand(Eigen::Translation3d(0.0, 0.0, 0.01) * X0, centre_F, false);
  const Eigen::Isometry3d X1 = Eigen::Translation3d(0.0, -0.02, 0.0) * X0;
  stand(X1, centre_F, true);
  r = mon.result();
  EXPECT_NEAR(r.foot_slip_max_m, 0.02, 1e-12);
  EXPECT_GE(r.foot_displacement_max_m, 0.02 - 1e-12);
  EXPECT_LT(r.foot_slide_max_m, 1e-12);
  stand(Eigen::Translation3d(0.0, -0.01, 0.0) * X1, centre_F, true);
  r = mon.result();
  EXPECT_NEAR(r.foot_slip_max_m, 0.03, 1e-12);
  // It slid 10 mm of that within its contact: slide 10 mm.
  EXPECT_NEAR(r.foot_slide_max_m, 0.01, 1e-12);
  EXPECT_FALSE(r.survived);
  EXPECT_NE(mon.failed_criteria().at(0).find("foot_slip_max 0.03 m"), std::string::npos)
      << mon.failed_criteria().at(0);
}

// Without a sole in the robot config the slip point is the point of the sole plane below the
// foot frame, the plane taken from the first contact that carries a load: a first contact
// without one (the simulator then reports its CoP at the foot frame's origin) does not teach it.
TEST(SimScenario, WithoutASoleTheSlipPlaneComesFromALoadedContact) {
  Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  sc.sim.world.platforms.clear();
  ASSERT_FALSE(sc.sim.robot.feet[0].has_sole);
  ScenarioMonitor mon(sc, platforms_of_feet(sc));
  GroundTruth g;
  g.feet.resize(2);
  g.non_foot_contact.assign(3, 0);
  const Eigen::Isometry3d X0(Eigen::Translation3d(0.0, -0.1, 0.08));  // ankle 8 cm up
  g.feet[1].X_WF = Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.1, 0.08));
  g.feet[1].in_contact = true;
  auto stand = [&](const Eigen::Isometry3d& X, const Eigen::Vector3d& cop_W, double load) {
    g.feet[0].X_WF = X;
    g.feet[0].cop_W = cop_W;
    g.feet[0].force_W = Eigen::Vector3d(0.0, 0.0, load);
    g.feet[0].in_contact = true;
    mon.update(g);
    g.time += 0.001;
  };
  stand(X0, X0.translation(), 0.0);                           // touching, no load
  stand(X0, X0 * Eigen::Vector3d(0.03, 0.0, -0.08), 250.0);  // loaded: the sole plane, 8 cm down
  const Eigen::Vector3d toe_F(0.14, 0.0, -0.08);
  const double tilt = 7.5 * M_PI / 180.0;
  const Eigen::Vector3d toe_W = X0 * toe_F;
  const Eigen::Isometry3d rolled =
      Eigen::Translation3d(toe_W) * Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY()) *
      Eigen::Translation3d(-toe_W) * X0;
  stand(rolled, toe_W, 250.0);
  // The point 8 cm below the ankle, 14 cm behind the toe: 0.14 (1 - cos 7.5 deg) = 1.2 mm (the
  // ankle itself: 11 mm).
  EXPECT_NEAR(mon.result().foot_slip_max_m, 0.14 * (1.0 - std::cos(tilt)), 1e-12);
  EXPECT_GT(mon.result().foot_displacement_max_m, 0.010);
}

TEST(SimScenario, FootTiltIsACriterionOnlyWhenAsked) {
  Scenario sc = parse_scenario(kInline + std::string("success: {foot_tilt_max_deg: 5}\n"),
                               fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  EXPECT_EQ(sc.success.foot_tilt_max_deg, 5.0);
  EXPECT_NE(error_of(kInline + std::string("success: {foot_tilt_max_deg: -1}\n"))
                .find("success.foot_tilt_max_deg: must be >= 0"),
            std::string::npos);
  EXPECT_TRUE(std::isinf(parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator")
                             .success.foot_tilt_max_deg));
  sc.sim.world.platforms.clear();
  ScenarioMonitor mon(sc, platforms_of_feet(sc));
  GroundTruth g;
  g.feet.resize(2);
  g.non_foot_contact.assign(3, 0);
  for (int f = 0; f < 2; ++f) {
    g.feet[f].X_WF = Eigen::Isometry3d(Eigen::Translation3d(0.0, f ? 0.1 : -0.1, 0.0));
    g.feet[f].cop_W = g.feet[f].X_WF.translation();
    g.feet[f].in_contact = true;
  }
  mon.update(g);
  EXPECT_TRUE(mon.result().survived);
  // The left foot rolled 6 deg about its outer edge (x axis): over the 5 deg asked.
  g.feet[0].X_WF.linear() =
      Eigen::AngleAxisd(6.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  g.time = 0.001;
  mon.update(g);
  EXPECT_NEAR(mon.result().foot_tilt_max_deg, 6.0, 1e-9);
  EXPECT_FALSE(mon.result().survived);
  ASSERT_EQ(mon.failed_criteria().size(), 1u);
  EXPECT_EQ(mon.failed_criteria()[0], "foot_tilt_max 6 deg > 5 deg");
}

}  // namespace
}  // namespace poise::sim
