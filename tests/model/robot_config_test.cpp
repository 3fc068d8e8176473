// The project's humanoid and its robot.yaml.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>

#include <Eigen/Eigenvalues>

#include "poise/model/centroidal.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

TEST(Humanoid, SizeMassAndFeetAsSpecified) {
  const RobotConfig cfg = load_robot_config(test::humanoid_config());
  const Model m = load_robot_model(cfg);
  EXPECT_EQ(m.name, "poise_humanoid");
  EXPECT_NEAR(m.total_mass, 50.0, 2.0);
  EXPECT_EQ(cfg.leg_joints.size(), 12u);
  EXPECT_EQ(m.body_name[0], "pelvis");
  Data d(m);
  forward_kinematics(m, d, cfg.q_nominal);
  for (const FootConfig& f : cfg.feet) {
    const SE3 X_foot = frame_placement(m, d, f.frame_id);
    const SE3 X_sole = frame_placement(m, d, f.sole_frame_id);
    EXPECT_NEAR(X_sole.p.z(), 0.0, 1e-9) << "nominal posture puts the soles on the ground";
    EXPECT_NEAR(X_foot.p.z() - X_sole.p.z(), 0.08, 1e-9) << "ankle 8 cm above the sole";
    EXPECT_NEAR(f.sole.x_max - f.sole.x_min, 0.22, 1e-9);
    EXPECT_NEAR(f.sole.y_max - f.sole.y_min, 0.11, 1e-9);
  }
  // Height: top of the head sphere (radius read from the URDF text) on straight legs.
  Eigen::VectorXd q = m.neutral();
  forward_kinematics(m, d, q);
  const double sole_z = frame_placement(m, d, cfg.feet[kLeft].sole_frame_id).p.z();
  const double head_z = frame_placement(m, d, m.frame_id("head")).p.z();
  EXPECT_NEAR(head_z + 0.04 + 0.085 - sole_z, 1.5, 0.08);
  // IMU on the pelvis.
  EXPECT_EQ(m.frames[cfg.imu_frame_id].body, 0);
  // CoM of the nominal posture above the feet, between them.
  center_of_mass(m, d, cfg.q_nominal);
  EXPECT_NEAR(d.com.y(), 0.0, 0.01);
  EXPECT_GT(d.com.z(), 0.6);
}

TEST(Humanoid, InertiasArePhysical) {
  const Model m = build_model_from_urdf_file(test::humanoid_urdf());
  for (int b = 0; b < m.nbodies; ++b) {
    EXPECT_GT(m.inertia[b].mass, 0.0) << m.body_name[b];
    Eigen::SelfAdjointEigenSolver<Matrix3> es(m.inertia[b].I_com);
    EXPECT_GT(es.eigenvalues().minCoeff(), 0.0) << m.body_name[b];
  }
  for (int j = 0; j < m.njoints; ++j) {
    EXPECT_TRUE(std::isfinite(m.limits[j].lower) && std::isfinite(m.limits[j].upper));
    EXPECT_GT(m.limits[j].effort, 0.0);
    EXPECT_GT(m.damping[j], 0.0);
  }
}

// Writes a variant of robot.yaml (text replaced) next to the URDF and expects an error naming it.
void expect_config_error(const std::string& from, const std::string& to,
                         const std::string& fragment) {
  std::ifstream in(test::humanoid_config());
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  const auto pos = text.find(from);
  ASSERT_NE(pos, std::string::npos) << from;
  text.replace(pos, from.size(), to);
  const std::string path = std::string(POISE_BINARY_DIR) + "/tests/model_bad_robot.yaml";
  std::ofstream(path) << std::regex_replace(text, std::regex("urdf: poise_humanoid.urdf"),
                                            "urdf: " + test::humanoid_urdf());
  try {
    load_robot_config(path);
    ADD_FAILURE() << "no error for " << to;
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(RobotConfig, AStandPointIsReadInTheFootFrameOnTheSolePlane) {
  std::ifstream in(test::humanoid_config());
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  const std::string sole =
      "sole: {x_min: -0.08, x_max: 0.14, y_min: -0.055, y_max: 0.055, height: 0.08}";
  const auto pos = text.find(sole);  // the right foot's (listed first)
  ASSERT_NE(pos, std::string::npos);
  text.insert(pos + sole.size(), "\n    stand_point: [-0.0125, 0.02]");
  const std::string path = std::string(POISE_BINARY_DIR) + "/tests/model_stand_point_robot.yaml";
  std::ofstream(path) << std::regex_replace(text, std::regex("urdf: poise_humanoid.urdf"),
                                            "urdf: " + test::humanoid_urdf());
  const RobotConfig cfg = load_robot_config(path);
  ASSERT_TRUE(cfg.feet[kRight].stand_point.has_value());
  EXPECT_FALSE(cfg.feet[kLeft].stand_point.has_value());
  EXPECT_EQ(cfg.feet[kRight].stand_point_F(), Eigen::Vector3d(-0.0125, 0.02, -0.08));
  EXPECT_EQ(cfg.feet[kLeft].stand_point_F(), cfg.feet[kLeft].sole.center_F());
  EXPECT_LT((cfg.feet[kLeft].stand_point_F() - Eigen::Vector3d(0.03, 0.0, -0.08)).norm(), 1e-15);
  EXPECT_FALSE(cfg.effort_limited_sole);  // absent: off

}

TEST(RobotConfig, ErrorsNameTheProblem) {
  expect_config_error("imu_frame: imu_link", "imu_frame: imu_lnk", "imu_lnk");
  expect_config_error("frame: r_foot", "frame: r_fot", "r_fot");
  expect_config_error("sole_frame: l_sole", "sole_frame: l_foot", "sole frame 'l_foot'");
  expect_config_error("l_knee: 0.556", "l_kne: 0.556", "l_kne");
  expect_config_error("l_knee: 0.556", "l_knee: 3.5", "outside the joint limits");
  expect_config_error("l_knee: 0.556", "l_knee: 0.2", "not flat");
  expect_config_error("torso_yaw, l_shoulder_pitch", "l_shoulder_pitch", "torso_yaw");
  expect_config_error("friction_mu: 0.8", "friction_mu: -1", "friction_mu");
  expect_config_error("default: {kp: 100.0, kd: 2.0}", "default: {kp: 100.0}", "kd");
  expect_config_error("urdf: poise_humanoid.urdf", "urdf: missing.urdf", "not found");
  // stand_point: inside the sole rectangle, two numbers
  const std::string sole =
      "sole: {x_min: -0.08, x_max: 0.14, y_min: -0.055, y_max: 0.055, height: 0.08}";
  expect_config_error(sole, sole + "\n    stand_point: [0.15, 0]", "outside the sole rectangle");
  expect_config_error(sole, sole + "\n    stand_point: [0.0, -0.06]", "outside the sole rectangle");
  expect_config_error(sole, sole + "\n    stand_point: [0.0]", "stand_point");
  expect_config_error(sole, sole + "\n    stand_point: [0.0, .nan]", "stand_point[1]");
  expect_config_error(sole, sole + "\n    stand_pont: [0.0, 0.0]", "stand_pont");
  expect_config_error("torsional_mu: 0.02", "torsional_mu: 0.02\n  effort_limited_sole: yes",
                      "contact.effort_limited_sole");
  EXPECT_THROW(load_robot_config("/nonexistent/robot.yaml"), ModelError);
}

}  // namespace
}  // namespace poise::model
