// Placement by what collides (#18 item 3): the robot starts with the bottom of its foot collision
// shapes on the ground, whatever robot.yaml's sole plane says; frames robot.yaml adds (soles given
// as link + offset + rotation) exist in the simulator.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
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

// The robot's own forward (#18 item 3).
TEST(Facing, TrunkPitchIsPositiveLeaningForwardAboutTheRobotsOwnForward) {
  // A base turned to face world -x (its forward is -x in its frame, turned by pi), leaning
  // 0.1 rad toward world +x, its forward: pitch +0.1 rad. About the base's own x it would be -0.1.
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()))
                                .toRotationMatrix();
  const Eigen::Vector2d pr = trunk_pitch_roll(R, -Eigen::Vector3d::UnitX());
  EXPECT_NEAR(pr.x(), 0.1, 1e-12);
  EXPECT_NEAR(pr.y(), 0.0, 1e-12);
  EXPECT_NEAR(trunk_pitch_roll(R, Eigen::Vector3d::UnitX()).x(), -0.1, 1e-12);
  // Turned by -0.05 rad about world x: its left (world +y, it faces +x) goes down: roll -0.05.
  const Eigen::Matrix3d Rr = (Eigen::AngleAxisd(-0.05, Eigen::Vector3d::UnitX()) *
                              Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()))
                                 .toRotationMatrix();
  EXPECT_NEAR(trunk_pitch_roll(Rr, -Eigen::Vector3d::UnitX()).y(), -0.05, 1e-12);
}

// A fall past the horizon (#54): a forward fall is pitch up to 180 deg with no roll, a sideways
// fall roll with no pitch, never 180 deg of roll as Euler angles would say; seeded random
// angles, headings and small sideways leans, against the angles the rotations were built from.
TEST(Facing, AFallPastTheHorizonIsPitchOrRollNever180DegOfTheOther) {
  std::mt19937_64 rng(54);
  std::uniform_real_distribution<double> big(-3.1, 3.1), yaw(-M_PI, M_PI), small(-0.2, 0.2);
  for (int k = 0; k < 200; ++k) {
    const double a = big(rng), psi = yaw(rng), e = small(rng);
    const Eigen::Matrix3d Rz = Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d fwd = Rz.col(0), left = Rz.col(1);
    // Pitch a about the robot's left (forward pitch positive: about +left).
    const Eigen::Matrix3d Rp = Eigen::AngleAxisd(a, left).toRotationMatrix() * Rz;
    const Eigen::Vector2d p = trunk_pitch_roll(Rp, Eigen::Vector3d::UnitX());
    EXPECT_NEAR(p.x(), a, 1e-9) << "pitch " << a;
    EXPECT_NEAR(p.y(), 0.0, 1e-9) << "pitch " << a;
    // Roll a about the robot's forward (left side rising: about +forward).
    const Eigen::Matrix3d Rr = Eigen::AngleAxisd(a, fwd).toRotationMatrix() * Rz;
    const Eigen::Vector2d r = trunk_pitch_roll(Rr, Eigen::Vector3d::UnitX());
    EXPECT_NEAR(r.y(), a, 1e-9) << "roll " << a;
    EXPECT_NEAR(r.x(), 0.0, 1e-9) << "roll " << a;
    // A forward or backward fall with a small lean sideways: most of it pitch, the roll stays
    // small (up to 140 deg: near a head stand, 180 deg, the two are not told apart).
    if (std::abs(a) > 2.45) continue;
    const Eigen::Matrix3d Rc =
        Eigen::AngleAxisd(a, left).toRotationMatrix() * Eigen::AngleAxisd(e, fwd).toRotationMatrix() * Rz;
    const Eigen::Vector2d c = trunk_pitch_roll(Rc, Eigen::Vector3d::UnitX());
    EXPECT_LE(std::abs(c.y()), std::abs(e) + 1e-9) << "pitch " << a << " lean " << e;
    EXPECT_NEAR(c.x(), a, 1e-9) << "pitch " << a << " lean " << e;
  }
}

// The humanoid with a new root link whose x points backward (the pelvis fixed to it turned by
// pi): its base faces -x, robot.yaml says forward_axis: [-1, 0, 0].
std::string base_facing_back(std::string u) {
  const std::string first_joint = "<joint ";
  const auto pos = u.find(first_joint);
  EXPECT_NE(pos, std::string::npos);
  u.insert(pos,
           "<link name=\"base_back\"/>\n  <joint name=\"base_back_to_pelvis\" type=\"fixed\">\n"
           "    <parent link=\"base_back\"/>\n    <child link=\"pelvis\"/>\n"
           "    <origin xyz=\"0 0 0\" rpy=\"0 0 3.141592653589793\"/>\n  </joint>\n  ");
  return u;
}
std::string forward_minus_x(std::string y) { return y + "\nforward_axis: [-1, 0, 0]\n"; }

TEST(Facing, ABaseFacingMinusXFacesTheScenarioWayAndAForwardPushMovesItForward) {
  const fs::path cfg = robot_variant("base_facing_back", base_facing_back, forward_minus_x);
  const std::string scenario =
      "name: facing\nrobot: {config: " + cfg.string() +
      "}\nduration: 2.0\ninitial: {posture: nominal, support: double}\nsensors: {seed: 1}\n"
      "disturbances:\n  pushes:\n    - {link: pelvis, force: [60, 0, 0], frame: heading, start: 0.2, "
      "duration: 0.2}\n";
  const World w = parse_world(scenario, cfg.parent_path(), "facing test");
  EXPECT_TRUE(w.sim.robot.forward_axis.isApprox(-Eigen::Vector3d::UnitX()));
  Simulator sim(w.sim);
  // Facing 0: the robot's forward (the pelvis' x) along world +x; its base link's x along -x.
  EXPECT_GT(sim.frame_pose("pelvis").linear()(0, 0), 0.999);
  EXPECT_LT(sim.frame_pose("base_back").linear()(0, 0), -0.999);
  GroundTruth g = sim.make_ground_truth();
  SensorFrame s = sim.make_sensor_frame();
  sim.read(s, g);
  const double com_x0 = g.com_W.x();
  hold(sim, 0.6);
  sim.read(s, g);
  EXPECT_GT(g.com_W.x() - com_x0, 0.002) << "a forward push moves the robot forward (+x)";
  EXPECT_GT(trunk_pitch_roll(g.X_WB.rotation(), w.sim.robot.forward_axis).x(), 0.0)
      << "it leans forward: positive pitch";
  // facing_deg: 90 turns it to world +y, and a heading push along its forward pushes +y.
  const World w90 = parse_world(
      std::regex_replace(scenario, std::regex("support: double\\}"), "support: double, facing_deg: 90}"),
      cfg.parent_path(), "facing test");
  EXPECT_LT((w90.sim.pushes.at(0).force_W - Eigen::Vector3d(0, 60, 0)).norm(), 1e-9);
  Simulator sim90(w90.sim);
  EXPECT_GT(sim90.frame_pose("pelvis").linear()(1, 0), 0.999);
}

}  // namespace
}  // namespace poise::sim
