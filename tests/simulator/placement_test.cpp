// Placement by what collides (#18 item 3): the robot starts with the bottom of its foot collision
// shapes on the ground, whatever robot.yaml's sole plane says; frames robot.yaml adds (soles given
// as link + offset + rotation) exist in the simulator.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "poise/sim/simulator.hpp"
#include "poise/sim/world.hpp"

namespace poise::sim {
namespace {

namespace fs = std::filesystem;

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

const fs::path kRobotDir = fs::path(POISE_SOURCE_DIR) / "deploy/robots/poise_humanoid";

// A copy of the shipped humanoid (URDF text edited by `edit_urdf`, robot.yaml by `edit_yaml`) in
// its own folder; returns the robot.yaml path.
fs::path robot_variant(const std::string& name, std::string (*edit_urdf)(std::string),
                       std::string (*edit_yaml)(std::string)) {
  const fs::path d = fs::path(POISE_BINARY_DIR) / "test_output" / "sim_placement" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  std::ofstream(d / "robot.urdf") << edit_urdf(read(kRobotDir / "poise_humanoid.urdf"));
  std::string yaml = read(kRobotDir / "robot.yaml");
  yaml = std::regex_replace(yaml, std::regex("urdf: [^\\n]*"), "urdf: robot.urdf");
  std::ofstream(d / "robot.yaml") << edit_yaml(yaml);
  return d / "robot.yaml";
}

std::string same(std::string s) { return s; }

// Both foot collision boxes 10.5 mm lower (centre z -0.055 -> -0.0655): their bottom is at
// -0.0905 m in the foot frame, robot.yaml's sole plane at -0.08 m.
std::string lowered_boxes(std::string u) {
  const std::string box = "<collision>\n      <origin xyz=\"0.03 0 -0.055\"";
  int n = 0;
  for (auto pos = u.find(box); pos != std::string::npos; pos = u.find(box, pos + 1), ++n)
    u.replace(pos, box.size(), "<collision>\n      <origin xyz=\"0.03 0 -0.0655\"");
  EXPECT_EQ(n, 2);
  return u;
}

World world_of(const fs::path& robot_yaml) {
  const std::string scenario = "name: placement\nrobot: {config: " + robot_yaml.string() +
                               "}\nduration: 2.0\ninitial: {posture: nominal, support: double}\n"
                               "sensors: {seed: 1}\n";
  return parse_world(scenario, robot_yaml.parent_path(), "placement test");
}

// Runs `seconds` with every joint held by PD at its initial position (what `poise sim` does);
// returns the largest horizontal displacement of either foot frame and of the base.
struct Held {
  double foot_slip = 0.0, base_shift = 0.0, base_drop = 0.0;
};
Held hold(Simulator& sim, double seconds) {
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  sim.read(s, g);
  JointCommand c = sim.make_command();
  c.mode = CommandMode::kPd;
  c.q_ref = s.q;
  c.qd_ref.setZero(sim.num_joints());
  c.kp.setConstant(sim.num_joints(), 400.0);
  c.kd.setConstant(sim.num_joints(), 10.0);
  const Eigen::Vector3d base0 = g.X_WB.translation();
  const Eigen::Vector3d r0 = sim.frame_pose("r_foot").translation();
  const Eigen::Vector3d l0 = sim.frame_pose("l_foot").translation();
  Held h;
  const int steps = static_cast<int>(std::lround(seconds / sim.dt()));
  for (int k = 0; k < steps; ++k) {
    c.tick = s.tick;
    sim.step(c, s, g);
    h.foot_slip = std::max({h.foot_slip, (sim.frame_pose("r_foot").translation() - r0).head<2>().norm(),
                            (sim.frame_pose("l_foot").translation() - l0).head<2>().norm()});
    h.base_shift = std::max(h.base_shift, (g.X_WB.translation() - base0).head<2>().norm());
    h.base_drop = std::max(h.base_drop, base0.z() - g.X_WB.translation().z());
  }
  return h;
}

TEST(Placement, FootBoxesBelowTheSolePlaneStartOnTheGroundAndStand) {
  const World w = world_of(robot_variant("lowered_boxes", lowered_boxes, same));
  Simulator sim(w.sim);
  // The foot frame starts 0.0905 m up (box bottom on the ground), not 0.08 m (the sole plane).
  for (const char* foot : {"r_foot", "l_foot"})
    EXPECT_NEAR(sim.frame_pose(foot).translation().z(), 0.0905, 1e-6) << foot;
  const Held h = hold(sim, 2.0);
  EXPECT_LT(h.foot_slip, 0.005);
  EXPECT_LT(h.base_shift, 0.05);
  EXPECT_LT(h.base_drop, 0.05);
}

TEST(Placement, TheShippedRobotIsPlacedByItsSolePlaneWhereTheyAgree) {
  const World w = world_of(robot_variant("shipped", same, same));
  Simulator sim(w.sim);
  for (const char* foot : {"r_foot", "l_foot"})
    EXPECT_NEAR(sim.frame_pose(foot).translation().z(), 0.08, 1e-6) << foot;
}

// No URDF sole links; robot.yaml gives each sole 3 cm forward of the ankle, turned 180 deg about
// z (x to the heel), F 5 cm above the sole: the simulator has the added foot frames.
std::string no_sole_links(std::string u) {
  for (const char* s : {"r", "l"})
    u = std::regex_replace(u, std::regex(std::string("<joint name=\"") + s +
                                         "_sole_joint\"[^]*?</joint>\\s*<link name=\"" + s +
                                         "_sole\">\\s*</link>"),
                           "");
  EXPECT_EQ(u.find("_sole\""), std::string::npos);
  return u;
}
std::string rotated_soles(std::string y) {
  y = std::regex_replace(y, std::regex("sole_frame: [lr]_sole[^\\n]*"),
                         "sole_frame: {offset: [0.03, 0, -0.08], rpy: [0, 0, 3.141592653589793]}");
  y = std::regex_replace(
      y, std::regex("sole: \\{[^}]*\\}"),
      "sole: {x_min: -0.11, x_max: 0.11, y_min: -0.055, y_max: 0.055, height: 0.05}");
  return y;
}

TEST(Placement, SoleFramesGivenAsOffsetsAreFramesOfTheSimulator) {
  const World w = world_of(robot_variant("rotated_soles", no_sole_links, rotated_soles));
  ASSERT_EQ(w.sim.robot.feet.size(), 2u);
  EXPECT_EQ(w.sim.robot.feet[0].frame, "r_foot_foot_poise");
  ASSERT_EQ(w.sim.robot.added_frames.size(), 2u);
  Simulator sim(w.sim);
  for (const char* side : {"r", "l"}) {
    const Eigen::Isometry3d X_link = sim.frame_pose(std::string(side) + "_foot");
    const Eigen::Isometry3d X_F = sim.frame_pose(std::string(side) + "_foot_foot_poise");
    // F = link * (0.03, 0, -0.03) turned by pi about z; expected independently of the loader.
    const Eigen::Vector3d p = X_link * Eigen::Vector3d(0.03, 0.0, -0.03);
    EXPECT_LT((X_F.translation() - p).norm(), 1e-9);
    EXPECT_LT((X_F.linear().col(0) + X_link.linear().col(0)).norm(), 1e-9) << "x to the heel";
    EXPECT_NEAR(X_F.translation().z(), 0.05, 1e-6) << "sole (box bottom) on the ground";
  }
  const Held h = hold(sim, 1.0);
  EXPECT_LT(h.foot_slip, 0.005);
}

}  // namespace
}  // namespace poise::sim
