// Scenario files: the shipped paper scenarios load and put the robot on its supports; schema
// errors name the key; the monitor's verdict quantities. The format is poise::scenario
// (deploy/scenario), the world part of it and the monitor poise::sim (simulator/sim).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
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

TEST(SimScenario, MonitorTellsASlideFromAPivotAndFromALandingElsewhere) {
  // Foot slide: the sole point under the CoP against where that point of the sole was when the
  // contact began. Foot slip (the criterion): the foot frame's displacement since the start.
  Scenario sc = parse_scenario(kInline, fs::path(POISE_SOURCE_DIR) / "tests/simulator");
  sc.sim.world.platforms.clear();
  ScenarioMonitor mon(sc, platforms_of_feet(sc));
  GroundTruth g;
  g.feet.resize(2);
  g.non_foot_contact.assign(3, 0);
  g.com_W = Eigen::Vector3d(0.0, 0.0, 0.8);
  const Eigen::Vector3d toe_corner_F(0.13, -0.045, -0.08);  // a sole corner, ankle 8 cm up
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
  stand(X0, toe_corner_F, true);
  // Pivot: the foot turns 6 deg in yaw and 2 deg of pitch about its toe corner (the CoP stays
  // there). The ankle moves ~14 mm: slip, no slide.
  const Eigen::Vector3d corner_W = X0 * toe_corner_F;
  const Eigen::Isometry3d turn =
      Eigen::Translation3d(corner_W) *
      Eigen::AngleAxisd(6.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()) *
      Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()) *
      Eigen::Translation3d(-corner_W);
  stand(turn * X0, toe_corner_F, true);
  auto r = mon.result();
  EXPECT_GT(r.foot_slip_max_m, 0.012);
  EXPECT_LT(r.foot_slide_max_m, 1e-12);
  // Lifted, and set down 20 mm to the side, flat: a landing elsewhere, no slide.
  stand(Eigen::Translation3d(0.0, 0.0, 0.01) * X0, toe_corner_F, false);
  const Eigen::Isometry3d X1 = Eigen::Translation3d(0.0, -0.02, 0.0) * X0;
  stand(X1, Eigen::Vector3d(0.0, 0.0, -0.08), true);
  r = mon.result();
  EXPECT_NEAR(r.foot_slip_max_m, 0.02, 1e-12);
  EXPECT_LT(r.foot_slide_max_m, 1e-12);
  // Then it slides 4 mm forward, flat, with its CoP at the sole centre: slide 4 mm.
  stand(Eigen::Translation3d(0.004, 0.0, 0.0) * X1, Eigen::Vector3d(0.0, 0.0, -0.08), true);
  r = mon.result();
  EXPECT_NEAR(r.foot_slide_max_m, 0.004, 1e-12);
}

}  // namespace
}  // namespace poise::sim
