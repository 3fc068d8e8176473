// The robot configuration and model from text (what a node builds from poise/robot_description)
// equal the ones loaded from the files; robot_differences names what differs, and only that.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>

#include "poise/model/centroidal.hpp"
#include "poise/model/data.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

namespace fs = std::filesystem;

std::string read(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Runs `f` with the working directory set to a fresh empty folder (no robot files reachable by
/// a relative path).
template <class F>
void in_empty_dir(F&& f) {
  const fs::path old = fs::current_path();
  const fs::path dir =
      fs::temp_directory_path() / ("poise-config-text-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  fs::current_path(dir);
  f();
  fs::current_path(old);
  fs::remove_all(dir);
}

TEST(RobotConfigText, ParsedFromTextEqualsLoadedFromFile) {
  const RobotConfig file = load_robot_config(test::humanoid_config());
  const Model file_model = load_robot_model(file);
  const std::string yaml = read(test::humanoid_config());
  const std::string urdf = read(test::humanoid_urdf());
  RobotConfig text;
  Model text_model;
  in_empty_dir([&] {
    text = parse_robot_config(yaml, urdf, "from test");
    text_model = load_robot_model(text);
  });
  EXPECT_TRUE(text.config_path.empty());
  EXPECT_TRUE(text.urdf_path.empty());
  EXPECT_EQ(text.urdf_xml, urdf);
  EXPECT_EQ(file.urdf_xml, urdf);
  // Structural: every field.
  EXPECT_EQ(text.name, file.name);
  EXPECT_EQ(text.imu_frame, file.imu_frame);
  EXPECT_EQ(text.imu_frame_id, file.imu_frame_id);
  for (int s = 0; s < 2; ++s) {
    EXPECT_EQ(text.feet[s].frame, file.feet[s].frame);
    EXPECT_EQ(text.feet[s].frame_id, file.feet[s].frame_id);
    EXPECT_EQ(text.feet[s].sole_frame_id, file.feet[s].sole_frame_id);
    EXPECT_EQ(text.feet[s].sole.x_min, file.feet[s].sole.x_min);
    EXPECT_EQ(text.feet[s].sole.x_max, file.feet[s].sole.x_max);
    EXPECT_EQ(text.feet[s].sole.y_min, file.feet[s].sole.y_min);
    EXPECT_EQ(text.feet[s].sole.y_max, file.feet[s].sole.y_max);
    EXPECT_EQ(text.feet[s].sole.height, file.feet[s].sole.height);
  }
  EXPECT_EQ(text.safety_margin, file.safety_margin);
  EXPECT_EQ(text.friction_mu, file.friction_mu);
  EXPECT_EQ(text.torsional_mu, file.torsional_mu);
  EXPECT_EQ(text.leg_joints, file.leg_joints);
  EXPECT_EQ(text.upper_body_joints, file.upper_body_joints);
  EXPECT_EQ(text.leg_joint_indices, file.leg_joint_indices);
  EXPECT_EQ(text.upper_body_joint_indices, file.upper_body_joint_indices);
  EXPECT_EQ(text.q_nominal, file.q_nominal);
  ASSERT_EQ(text.gains.size(), file.gains.size());
  for (std::size_t j = 0; j < file.gains.size(); ++j) {
    EXPECT_EQ(text.gains[j].kp, file.gains[j].kp);
    EXPECT_EQ(text.gains[j].kd, file.gains[j].kd);
  }
  EXPECT_TRUE(robot_differences(text, text_model, "text", file, file_model, "file").empty());

  // Model: same structure, and the same numbers at seeded random states.
  ASSERT_EQ(text_model.joint_names, file_model.joint_names);
  ASSERT_EQ(text_model.nq, file_model.nq);
  ASSERT_EQ(text_model.nbodies, file_model.nbodies);
  EXPECT_EQ(text_model.total_mass, file_model.total_mass);
  std::mt19937 rng(15);
  Data dt(text_model), df(file_model);
  for (int i = 0; i < 20; ++i) {
    const test::State s = test::random_state(file_model, rng);
    forward_kinematics(text_model, dt, s.q);
    forward_kinematics(file_model, df, s.q);
    for (std::size_t f = 0; f < file_model.frames.size(); ++f) {
      const int id = static_cast<int>(f);
      EXPECT_EQ(frame_placement(text_model, dt, id).p, frame_placement(file_model, df, id).p);
    }
    center_of_mass(text_model, dt, s.q);
    center_of_mass(file_model, df, s.q);
    EXPECT_EQ(dt.com, df.com);
    EXPECT_EQ(rnea(text_model, dt, s.q, s.v, s.a), rnea(file_model, df, s.q, s.v, s.a));
  }
}

TEST(RobotConfigText, UrdfEntryIgnoredAndOptional) {
  std::string yaml = read(test::humanoid_config());
  const std::string urdf = read(test::humanoid_urdf());
  const RobotConfig a = parse_robot_config(
      std::regex_replace(yaml, std::regex("urdf: .*"), "urdf: /nonexistent/x.urdf"), urdf, "a");
  const RobotConfig b =
      parse_robot_config(std::regex_replace(yaml, std::regex("urdf: .*\n"), ""), urdf, "b");
  EXPECT_TRUE(robot_differences(a, load_robot_model(a), "a", b, load_robot_model(b), "b").empty());
}

TEST(RobotConfigText, ErrorsNameTheOrigin) {
  const std::string yaml = read(test::humanoid_config());
  const std::string urdf = read(test::humanoid_urdf());
  try {
    parse_robot_config(std::regex_replace(yaml, std::regex("imu_frame: imu_link"),
                                          "imu_frame: no_such_link"),
                       urdf, "from poise/robot_description");
    FAIL() << "no error";
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("from poise/robot_description"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("no_such_link"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_robot_config("[1, 2", urdf, "x"), ModelError);
  EXPECT_THROW(parse_robot_config(yaml, "<robot", "x"), ModelError);
  EXPECT_THROW(parse_robot_config("", urdf, "x"), ModelError);
}

std::vector<std::string> differences(const std::string& yaml_a, const std::string& urdf_a,
                                     const std::string& yaml_b, const std::string& urdf_b) {
  const RobotConfig a = parse_robot_config(yaml_a, urdf_a, "A");
  const RobotConfig b = parse_robot_config(yaml_b, urdf_b, "B");
  return robot_differences(a, load_robot_model(a), "A", b, load_robot_model(b), "B");
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& l : v)
    s += l + "\n";
  return s;
}

TEST(RobotDifferences, WhitespaceCommentsAndAttributeLayoutAreNotDifferences) {
  const std::string yaml = read(test::humanoid_config());
  const std::string urdf = read(test::humanoid_urdf());
  std::string urdf2 = std::regex_replace(urdf, std::regex("\n"), "\n  \n");
  urdf2 = std::regex_replace(urdf2, std::regex("<link "), "<!-- a comment -->\n<link   ");
  std::string yaml2 = std::regex_replace(yaml, std::regex("#[^\n]*"), "");
  yaml2 = std::regex_replace(yaml2, std::regex("\n"), "\n\n");
  const auto d = differences(yaml, urdf, yaml2, urdf2);
  EXPECT_TRUE(d.empty()) << joined(d);
}

TEST(RobotDifferences, NameTheDifference) {
  const std::string yaml = read(test::humanoid_config());
  const std::string urdf = read(test::humanoid_urdf());
  {  // robot name
    const auto d = differences(
        yaml, urdf, std::regex_replace(yaml, std::regex("name: poise_humanoid"), "name: other"),
        urdf);
    ASSERT_EQ(d.size(), 1u) << joined(d);
    EXPECT_EQ(d[0], "robot name: 'poise_humanoid' in A, 'other' in B");
  }
  {  // sole geometry of one foot
    const std::string yaml2 = std::regex_replace(
        yaml, std::regex("sole: \\{x_min: -0.08, x_max: 0.14"), "sole: {x_min: -0.08, x_max: 0.15",
        std::regex_constants::format_first_only);
    const auto d = differences(yaml, urdf, yaml2, urdf);
    ASSERT_EQ(d.size(), 1u) << joined(d);
    EXPECT_EQ(d[0], "feet.right.sole.x_max [m]: 0.14 in A, 0.15 in B");
  }
  {  // a link's mass (URDF): the link, its mass and the total mass are named
    std::smatch m;
    ASSERT_TRUE(std::regex_search(urdf, m, std::regex("<mass value=\"([0-9.]+)\"")));
    const std::string urdf2 = std::regex_replace(urdf, std::regex("<mass value=\"[0-9.]+\""),
                                                 "<mass value=\"77\"",
                                                 std::regex_constants::format_first_only);
    const auto d = differences(yaml, urdf, yaml, urdf2);
    const std::string all = joined(d);
    EXPECT_NE(all.find("total mass [kg]"), std::string::npos) << all;
    EXPECT_NE(all.find("mass [kg]: " + m[1].str() + " in A, 77 in B"), std::string::npos) << all;
  }
  {  // a joint renamed in the URDF (and the configuration that names it)
    const std::string urdf2 = std::regex_replace(urdf, std::regex("\"l_elbow\""), "\"l_elbow2\"");
    const std::string yaml2 = std::regex_replace(yaml, std::regex("l_elbow\\b"), "l_elbow2");
    const auto d = differences(yaml, urdf, yaml2, urdf2);
    const std::string all = joined(d);
    EXPECT_NE(all.find("joints: only in A: l_elbow"), std::string::npos) << all;
    EXPECT_NE(all.find("joints: only in B: l_elbow2"), std::string::npos) << all;
  }
}

}  // namespace
}  // namespace poise::model
