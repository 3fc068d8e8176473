// Configuration errors are clear and thrown at construction; joint-order helpers.
#include <gtest/gtest.h>

#include <stdexcept>
#include <sstream>
#include <fstream>
#include <filesystem>
#include <algorithm>

#include "poise/sim/world.hpp"
#include "poise/sim/simulator.hpp"
#if POISE_SIM_TEST_HAVE_MODEL
#include "poise/model/model.hpp"
#endif
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

std::string error_of(const SimulatorConfig& cfg) {
  try {
    Simulator sim(cfg);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(SimConfig, MeshOnlyFeetWithoutSoleIsAClearError) {
  const std::string e = error_of(test::biped_config("biped_mesh_feet.urdf"));
  EXPECT_NE(e.find("robot.feet.left"), std::string::npos) << e;
  EXPECT_NE(e.find("only mesh collision geometry"), std::string::npos) << e;
  EXPECT_NE(e.find("sole"), std::string::npos) << e;
}

TEST(SimConfig, MeshOnlyFeetWithSoleConfigStandOnTheSoleBox) {
  SimulatorConfig cfg = test::biped_config("biped_mesh_feet.urdf");
  for (auto& f : cfg.robot.feet) {
    f.has_sole = true;
    f.sole = test::biped_sole();
  }
  Simulator sim(cfg);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  sim.read(s, g);
  // auto base height: the sole plane (z = 0 in the sole frame) is on the ground
  EXPECT_NEAR(g.feet[0].X_WF.translation().z(), 0.0, 1e-9);
  JointCommand c = sim.make_command();
  c.mode = CommandMode::kPd;
  c.q_ref = s.q;
  c.kp.setConstant(600);
  c.kd.setConstant(20);
  for (int k = 0; k < 500; ++k)
    sim.step(c, s, g);
  EXPECT_TRUE(g.feet[0].in_contact && g.feet[1].in_contact);
  EXPECT_NEAR(g.feet[0].force_W.z() + g.feet[1].force_W.z(), sim.total_mass() * 9.81,
              0.02 * sim.total_mass() * 9.81);
}

TEST(SimConfig, BadInputsNameTheProblem) {
  SimulatorConfig cfg = test::biped_config();
  cfg.robot.urdf_path = "/nonexistent/robot.urdf";
  EXPECT_NE(error_of(cfg).find("/nonexistent/robot.urdf"), std::string::npos);

  cfg = test::biped_config();
  cfg.robot.feet[1].frame = "no_such_link";
  EXPECT_NE(error_of(cfg).find("'no_such_link' is not a link"), std::string::npos);

  cfg = test::biped_config();
  cfg.robot.feet.clear();
  EXPECT_NE(error_of(cfg).find("robot.feet"), std::string::npos);

  cfg = test::biped_config();
  cfg.robot.imu_frame = "nope";
  EXPECT_NE(error_of(cfg).find("robot.imu_frame"), std::string::npos);

  cfg = test::biped_config();
  cfg.initial.joint_names.push_back("elbow_that_does_not_exist");
  cfg.initial.joint_positions.push_back(0.1);
  EXPECT_NE(error_of(cfg).find("elbow_that_does_not_exist"), std::string::npos);

  cfg = test::biped_config();
  cfg.pushes = {Push{"ghost", {}, {1, 0, 0}, 0.0, 0.1}};
  EXPECT_NE(error_of(cfg).find("'ghost'"), std::string::npos);

  cfg = test::biped_config();
  PlatformConfig p;
  p.foot = "middle";
  cfg.world.platforms = {p};
  EXPECT_NE(error_of(cfg).find("'middle' is not a foot"), std::string::npos);

  cfg = test::biped_config();
  cfg.solver.dt = 0.0;
  EXPECT_NE(error_of(cfg).find("solver.dt"), std::string::npos);
}

TEST(SimConfig, JointNamesAndMapping) {
  Simulator sim(test::biped_config());
  const auto& names = sim.joint_names();
  ASSERT_EQ(sim.num_joints(), 10);
  // depth-first, children by joint name: l_hip_roll's subtree before r_hip_roll's
  EXPECT_EQ(names.front(), "l_hip_roll");
  EXPECT_EQ(names[4], "l_ankle_roll");
  EXPECT_EQ(names[5], "r_hip_roll");
  EXPECT_TRUE(std::isinf(sim.effort_limits()[0]) || sim.effort_limits()[0] == 300.0);

  std::vector<std::string> other(names.rbegin(), names.rend());
  other.push_back("neck");
  const std::vector<int> map = joint_index_map(names, other);
  Eigen::VectorXd in = Eigen::VectorXd::LinSpaced(10, 0, 9),
                  out = Eigen::VectorXd::Constant(11, -1);
  remap_joint_vector(map, in, out);
  for (int i = 0; i < 10; ++i)
    EXPECT_EQ(out[9 - i], i);
  EXPECT_EQ(out[10], -1);
  const std::vector<std::string> dup = {"a", "a"};
  EXPECT_THROW(joint_index_map(names, dup), std::runtime_error);
}

}  // namespace
}  // namespace poise::sim

#if POISE_SIM_TEST_HAVE_MODEL
namespace poise::sim {
namespace {

// A movable <mimic> joint (a finger following the elbow) is frozen at its offset by the
// simulator exactly as by poise::model: both see the same joints (before the fix the simulator
// had one more, a free joint nobody commands), and the robot stands.
// `limit` and `mimic`: the finger joint's <limit> and <mimic> lines; `dir_name` its output folder.
void expect_frozen_like_the_model(const std::string& limit, const std::string& mimic,
                                  const std::string& dir_name) {
  namespace fs = std::filesystem;
  const fs::path src = fs::path(POISE_SOURCE_DIR) / "deploy/robots/poise_humanoid";
  std::ifstream in(src / "poise_humanoid.urdf");
  std::stringstream ss;
  ss << in.rdbuf();
  std::string urdf = ss.str();
  const std::string finger = R"(
  <joint name="r_finger" type="revolute">
    <parent link="r_hand"/>
    <child link="r_finger_link"/>
    <origin xyz="0 0 -0.08" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    )" + limit + "\n    " + mimic + R"(
  </joint>
  <link name="r_finger_link">
    <inertial><origin xyz="0 0 -0.02"/><mass value="0.02"/>
      <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial>
    <collision><origin xyz="0 0 -0.02"/><geometry><sphere radius="0.01"/></geometry></collision>
  </link>
</robot>)";
  const auto end = urdf.rfind("</robot>");
  ASSERT_NE(end, std::string::npos);
  urdf = urdf.substr(0, end) + finger;
  const fs::path dir = fs::path(POISE_BINARY_DIR) / "test_output" / dir_name;
  fs::create_directories(dir);
  std::ofstream(dir / "finger.urdf") << urdf;
  {
    std::ifstream yin(src / "robot.yaml");
    std::stringstream y;
    y << yin.rdbuf();
    std::string yaml = y.str();
    const auto at = yaml.find("poise_humanoid.urdf");
    ASSERT_NE(at, std::string::npos);
    yaml.replace(at, std::string("poise_humanoid.urdf").size(), "finger.urdf");
    std::ofstream(dir / "robot.yaml") << yaml;
  }
  std::ofstream(dir / "stand.yaml") << "name: stand\nrobot: {config: robot.yaml}\nduration: 0.5\n";
  const model::Model m = model::build_model_from_urdf_file(dir / "finger.urdf");
  ASSERT_EQ(m.frozen_joints.size(), 1u);
  EXPECT_EQ(m.frozen_joints[0], "r_finger");

  const World sc = load_world(dir / "stand.yaml");
  Simulator sim(sc.sim);
  std::vector<std::string> sim_joints = sim.joint_names();
  std::vector<std::string> model_joints = m.joint_names;
  EXPECT_EQ(std::count(sim_joints.begin(), sim_joints.end(), "r_finger"), 0);
  std::sort(model_joints.begin(), model_joints.end());
  std::sort(sim_joints.begin(), sim_joints.end());
  EXPECT_EQ(sim_joints, model_joints);
}

TEST(SimConfig, MimicJointIsFrozenLikeTheModelFreezesIt) {
  expect_frozen_like_the_model(R"(<limit lower="-1" upper="1" effort="5" velocity="5"/>)",
                               R"(<mimic joint="r_elbow" multiplier="0.5" offset="0.3"/>)",
                               "sim_mimic");
}

// A joint whose <limit> says it is not actuated (effort or velocity 0: hands' passive joints,
// Aldebaran Romeo's) is frozen by both as well.
TEST(SimConfig, AJointThatIsNotActuatedIsFrozenLikeTheModelFreezesIt) {
  expect_frozen_like_the_model(R"(<limit lower="-1" upper="1" effort="0" velocity="0"/>)", "",
                               "sim_unactuated");
  expect_frozen_like_the_model(R"(<limit lower="0.1" upper="1" effort="0" velocity="2"/>)", "",
                               "sim_unactuated_effort");
}

}  // namespace
}  // namespace poise::sim
#endif
