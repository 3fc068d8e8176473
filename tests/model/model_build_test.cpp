// Model structure from URDF and clear errors on malformed input.
#include <gtest/gtest.h>

#include <fstream>

#include "poise/model/kinematics.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

// Expects ModelError whose message contains every fragment.
void expect_error(const std::string& xml, std::initializer_list<std::string> fragments) {
  try {
    build_model_from_urdf_string(xml, "test.urdf");
    ADD_FAILURE() << "no error for:\n" << xml;
  } catch (const ModelError& e) {
    const std::string msg = e.what();
    for (const auto& f : fragments)
      EXPECT_NE(msg.find(f), std::string::npos) << msg;
  }
}

std::string robot(const std::string& body) {
  return "<?xml version=\"1.0\"?><robot name=\"r\">" + body + "</robot>";
}
const std::string kLink = R"(<link name="%"><inertial><mass value="1"/>
  <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>)";
std::string link(const std::string& name) {
  std::string s = kLink;
  s.replace(s.find('%'), 1, name);
  return s;
}
std::string joint(const std::string& name, const std::string& parent, const std::string& child,
                  const std::string& type = "revolute") {
  return "<joint name=\"" + name + "\" type=\"" + type + "\"><parent link=\"" + parent +
         "\"/><child link=\"" + child +
         "\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" "
         "velocity=\"1\"/></joint>";
}

TEST(ModelBuild, MissingFile) {
  try {
    build_model_from_urdf_file("/nonexistent/robot.urdf");
    FAIL();
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("not found"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/nonexistent/robot.urdf"), std::string::npos);
  }
}

TEST(ModelBuild, BadXml) {
  expect_error("<robot name=\"r\"><link name=\"a\"></robot>", {"bad XML", "line"});
  expect_error("<notarobot/>", {"no <robot>"});
}

TEST(ModelBuild, KinematicLoopNamesTheLink) {
  // b has two parents
  expect_error(robot(link("a") + link("b") + link("c") + joint("ab", "a", "b") +
                     joint("ac", "a", "c") + joint("cb", "c", "b")),
               {"kinematic loop", "'b'"});
  // a cycle detached from the root: c -> d -> c
  expect_error(robot(link("a") + link("b") + link("c") + link("d") + joint("ab", "a", "b") +
                     joint("cd", "c", "d") + joint("dc", "d", "c")),
               {"kinematic loop"});
  expect_error(robot(link("a") + joint("aa", "a", "a")), {"kinematic loop", "'a'"});
}

TEST(ModelBuild, NegativeMassNamesTheLink) {
  expect_error(robot(link("a") + R"(<link name="heavy"><inertial><mass value="-2"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>)" +
                     joint("j", "a", "heavy")),
               {"'heavy'", "negative mass"});
}

TEST(ModelBuild, NonPositiveDefiniteInertiaNamesTheLink) {
  expect_error(robot(link("a") + R"(<link name="bad"><inertial><mass value="1"/>
      <inertia ixx="0.1" ixy="0.5" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>)" +
                     joint("j", "a", "bad")),
               {"'bad'", "not positive definite"});
  expect_error(robot(link("a") + R"(<link name="flat"><inertial><mass value="1"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.5"/></inertial></link>)" +
                     joint("j", "a", "flat")),
               {"'flat'", "triangle inequality"});
}

TEST(ModelBuild, OtherErrors) {
  expect_error(robot(link("a") + link("b") +
                     R"(<joint name="m" type="revolute"><parent link="a"/><child link="b"/>
      <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
      <mimic joint="x"/></joint>)"),
               {"'m'", "mimic"});
  expect_error(robot(link("a") + link("b") + joint("j", "a", "nope")), {"'nope'", "'j'"});
  expect_error(robot(link("a") + link("b") + joint("j", "a", "b", "floating")),
               {"'j'", "unsupported"});
  expect_error(robot(link("a") + link("b")), {"several root links"});
}

TEST(ModelBuild, StructureOfFixedChainsAndMasslessLinks) {
  const Model m = build_model_from_urdf_file(test::test_urdf("fixed_chains_massless.urdf"));
  EXPECT_EQ(m.njoints, 5);
  EXPECT_EQ(m.nq, 12);
  EXPECT_EQ(m.nv, 11);
  // Every link is a frame, merged ones included.
  EXPECT_EQ(m.frames.size(), 10u);
  for (const char* name :
       {"root", "body", "link1", "link1b", "link1c", "link2", "link3", "link4", "sensor", "link5"})
    EXPECT_TRUE(m.has_frame(name)) << name;
  // Depth-first, siblings by joint name: body's children j1, j3, to_sensor(fixed)->j5.
  EXPECT_EQ(m.joint_names, (std::vector<std::string>{"j1", "j2", "j3", "j4", "j5"}));
  EXPECT_EQ(m.body_name[0], "root");
  EXPECT_EQ(m.frames[m.frame_id("link1c")].body, m.joint_index("j1") + 1);
  EXPECT_NEAR(m.total_mass, 6.0 + 1.5 + 0.8 + 1.1 + 2.0 + 0.4, 1e-12);
  EXPECT_DOUBLE_EQ(m.inertia[m.joint_index("j3") + 1].mass, 0.0);  // massless moving link
  EXPECT_DOUBLE_EQ(m.limits[m.joint_index("j2")].lower, -2.0);
  EXPECT_DOUBLE_EQ(m.limits[m.joint_index("j2")].effort, 30.0);
  EXPECT_THROW(m.joint_index("nope"), ModelError);
  EXPECT_THROW(m.frame_id("nope"), ModelError);
  // A merged frame sits where the URDF puts it: sensor = body origin * (0, 0.1, 0.08) rotated.
  Data d(m);
  forward_kinematics(m, d, m.neutral());
  const SE3 X_body = frame_placement(m, d, m.frame_id("body"));
  const SE3 X_sensor = frame_placement(m, d, m.frame_id("sensor"));
  EXPECT_LT((X_body.act_inv(X_sensor.p) - Vector3(0, 0.1, 0.08)).norm(), 1e-12);
}

TEST(ModelBuild, PrismaticAndContinuousLimits) {
  const Model m = build_model_from_urdf_file(test::test_urdf("prismatic_continuous.urdf"));
  const int wheel = m.joint_index("wheel");
  EXPECT_EQ(m.joint_type[wheel + 1], JointType::kContinuous);
  EXPECT_TRUE(std::isinf(m.limits[wheel].lower));
  const int tel = m.joint_index("telescope");
  EXPECT_EQ(m.joint_type[tel + 1], JointType::kPrismatic);
  EXPECT_DOUBLE_EQ(m.limits[tel].upper, 0.3);
  EXPECT_NEAR(m.axis[tel + 1].norm(), 1.0, 1e-12);
}

TEST(ModelBuild, ConfigurationChecks) {
  const Model m = build_model_from_urdf_file(test::test_urdf("prismatic_continuous.urdf"));
  EXPECT_NO_THROW(check_configuration(m, m.neutral()));
  EXPECT_THROW(check_configuration(m, Eigen::VectorXd::Zero(m.nq)), ModelError);  // quat norm 0
  EXPECT_THROW(check_configuration(m, Eigen::VectorXd::Zero(3)), ModelError);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(m.nv);
  v[2] = std::nan("");
  EXPECT_THROW(check_velocity(m, v), ModelError);
}

TEST(ModelBuild, BaseVelocityConversionRoundTrip) {
  const Matrix3 R = so3_exp(Vector3(0.3, -0.5, 0.8));
  const Vector3 v(1, 2, 3), w(-0.5, 0.2, 0.1);
  const Motion V = base_velocity_from_world(R, v, w);
  EXPECT_TRUE(V.head<3>().isApprox(R.transpose() * v));
  const Motion back = base_velocity_to_world(R, V);
  EXPECT_TRUE(back.head<3>().isApprox(v));
  EXPECT_TRUE(back.tail<3>().isApprox(w));
}

}  // namespace
}  // namespace poise::model
