// robot.yaml soles given as a link + offset + rotation (no URDF sole link), and the warning for a
// sole plane that is not the bottom of the foot's collision geometry (#18 items 1 and 3).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

std::string read(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The shipped humanoid's URDF without its two sole links (r_sole, l_sole and their joints).
std::string urdf_without_sole_links() {
  std::string u = read(test::humanoid_urdf());
  for (const char* s : {"r", "l"}) {
    const std::regex joint(std::string("<joint name=\"") + s +
                           "_sole_joint\"[^]*?</joint>\\s*<link name=\"" + s +
                           "_sole\">\\s*</link>");
    const std::string before = u;
    u = std::regex_replace(u, joint, "");
    EXPECT_NE(u, before) << "sole link " << s << "_sole not found in the shipped URDF";
  }
  return u;
}

// The shipped robot.yaml with both feet's `sole_frame: X_sole` and `sole:` lines replaced.
std::string yaml_with_feet(const std::string& right_sole_frame, const std::string& right_sole,
                           const std::string& left_sole_frame, const std::string& left_sole) {
  std::string y = read(test::humanoid_config());
  const std::regex r_frame("sole_frame: r_sole[^\\n]*"), l_frame("sole_frame: l_sole[^\\n]*");
  y = std::regex_replace(y, r_frame, "sole_frame: " + right_sole_frame);
  y = std::regex_replace(y, l_frame, "sole_frame: " + left_sole_frame);
  // the two `sole: {...}` lines, right first
  const auto a = y.find("    sole: {");
  const auto a_end = y.find('\n', a);
  y.replace(a, a_end - a, "    sole: " + right_sole);
  const auto b = y.find("    sole: {", a + 10);
  const auto b_end = y.find('\n', b);
  y.replace(b, b_end - b, "    sole: " + left_sole);
  return y;
}

const char* kShippedSole = "{x_min: -0.08, x_max: 0.14, y_min: -0.055, y_max: 0.055, height: 0.08}";

// World positions of the four sole corners of each foot at the nominal posture.
std::vector<Vector3> sole_corners(const RobotConfig& cfg) {
  const Model m = load_robot_model(cfg);
  Data d(m);
  forward_kinematics(m, d, cfg.q_nominal);
  std::vector<Vector3> out;
  for (const FootConfig& f : cfg.feet) {
    const SE3 X = frame_placement(m, d, f.frame_id);
    for (double x : {f.sole.x_min, f.sole.x_max})
      for (double y : {f.sole.y_min, f.sole.y_max}) out.push_back(X.act(Vector3(x, y, -f.sole.height)));
  }
  return out;
}

std::vector<Vector3> sorted(std::vector<Vector3> v) {
  std::sort(v.begin(), v.end(), [](const Vector3& a, const Vector3& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  return v;
}

TEST(SoleFrames, OffsetBelowTheAnkleNeedsNoSoleLinkAndIsTheShippedRobot) {
  const RobotConfig shipped = load_robot_config(test::humanoid_config());
  const std::string y = yaml_with_feet("{offset: [0, 0, -0.08]}", kShippedSole,
                                       "{offset: [0, 0, -0.08], rpy: [0, 0, 0]}", kShippedSole);
  const RobotConfig cfg = parse_robot_config(y, urdf_without_sole_links(), "(test)");
  for (const FootConfig& f : cfg.feet) {
    EXPECT_TRUE(f.sole_from_offset);
    EXPECT_EQ(f.frame, f.link) << "F is the foot link itself when the offset is (0, 0, -height)";
    EXPECT_EQ(f.sole_frame, f.link + "_sole_poise");
  }
  ASSERT_EQ(cfg.q_nominal.size(), shipped.q_nominal.size());
  EXPECT_LT((cfg.q_nominal - shipped.q_nominal).cwiseAbs().maxCoeff(), 1e-12);
  // The sole frame added to the model is where the shipped URDF's sole link is.
  const Model m = load_robot_model(cfg);
  const Model ms = load_robot_model(shipped);
  Data d(m), ds(ms);
  forward_kinematics(m, d, cfg.q_nominal);
  forward_kinematics(ms, ds, shipped.q_nominal);
  for (int s = 0; s < 2; ++s) {
    const SE3 a = frame_placement(m, d, cfg.feet[s].sole_frame_id);
    const SE3 b = frame_placement(ms, ds, shipped.feet[s].sole_frame_id);
    EXPECT_TRUE(a.is_approx(b, 1e-12)) << a.p.transpose() << " vs " << b.p.transpose();
    EXPECT_NEAR(a.p.z(), 0.0, 1e-12) << "soles on the ground";
  }
  // Same robot for robot_differences, apart from the sole frame names.
  for (const std::string& line : robot_differences(cfg, m, "offset", shipped, ms, "shipped"))
    EXPECT_NE(line.find("sole"), std::string::npos) << line;
}

TEST(SoleFrames, ShiftedAndRotatedSoleFrameGivesTheSameSoleInTheWorld) {
  const RobotConfig shipped = load_robot_config(test::humanoid_config());
  // Sole frame 3 cm forward and turned by 180 deg about z: x points to the heel, y to the right,
  // so the rectangle is mirrored and shifted; the sole in the world must not move.
  const std::string sole = "{x_min: -0.11, x_max: 0.11, y_min: -0.055, y_max: 0.055, height: 0.05}";
  const std::string frame = "{offset: [0.03, 0, -0.08], rpy: [0, 0, 3.141592653589793]}";
  const RobotConfig cfg =
      parse_robot_config(yaml_with_feet(frame, sole, frame, sole), urdf_without_sole_links(), "(test)");
  EXPECT_EQ(cfg.feet[kRight].frame, "r_foot_foot_poise");
  EXPECT_EQ(cfg.feet[kLeft].frame, "l_foot_foot_poise");
  EXPECT_LT((cfg.q_nominal - shipped.q_nominal).cwiseAbs().maxCoeff(), 1e-12);
  const auto a = sorted(sole_corners(cfg)), b = sorted(sole_corners(shipped));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    EXPECT_LT((a[i] - b[i]).norm(), 1e-12) << a[i].transpose() << " vs " << b[i].transpose();
  // F is 5 cm above the sole plane, x toward the heel.
  const Model m = load_robot_model(cfg);
  Data d(m);
  forward_kinematics(m, d, cfg.q_nominal);
  const SE3 X = frame_placement(m, d, cfg.feet[kLeft].frame_id);
  EXPECT_NEAR(X.p.z(), 0.05, 1e-12);
  EXPECT_NEAR(X.R.col(0).x(), -1.0, 1e-12);
  // The collision box bottom is on the sole plane: no warning.
  EXPECT_TRUE(cfg.warnings.empty()) << cfg.warnings.front();
  EXPECT_NEAR(cfg.feet[kLeft].collision_bottom, 0.0, 1e-12);
}

void expect_error(const std::string& frame, const std::string& fragment) {
  try {
    parse_robot_config(yaml_with_feet(frame, kShippedSole, "{offset: [0, 0, -0.08]}", kShippedSole),
                       urdf_without_sole_links(), "(test)");
    ADD_FAILURE() << "no error for " << frame;
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(SoleFrames, ErrorsNameTheProblem) {
  expect_error("{offset: [0, 0, .nan]}", "feet.right.sole_frame.offset[2]: not a finite number");
  expect_error("{offset: [0, -0.08]}", "feet.right.sole_frame.offset: expected a list of 3 numbers");
  expect_error("{offset: [0, 0, -0.08], rpy: [0, 0, 180]}", "feet.right.sole_frame.rpy: bad rotation");
  expect_error("{offset: [0, 0, -0.08], rpy: [0, x, 0]}", "feet.right.sole_frame.rpy[1]: expected a number");
  expect_error("{offset: [0, 0, -0.08], quat: [0, 0, 0, 1]}", "feet.right.sole_frame.quat: unknown key");
  expect_error("{rpy: [0, 0, 0]}", "feet.right.sole_frame.offset: missing");
  expect_error("r_sole", "'r_sole' is not a link");  // the link is gone from this URDF
  // Unknown foot link with the new form.
  std::string y = yaml_with_feet("{offset: [0, 0, -0.08]}", kShippedSole, "{offset: [0, 0, -0.08]}",
                                 kShippedSole);
  y = std::regex_replace(y, std::regex("frame: r_foot"), "frame: r_fot");
  try {
    parse_robot_config(y, urdf_without_sole_links(), "(test)");
    ADD_FAILURE();
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("feet.right.frame: 'r_fot' is not a link"), std::string::npos)
        << e.what();
  }
}

TEST(SoleFrames, SoleLinkWithOtherAxesIsNamedAsSuch) {
  // The shipped r_sole link turned upside down (z down): refused, naming the axes and the fix.
  std::string u = read(test::humanoid_urdf());
  const std::string from = "<child link=\"r_sole\"/>\n    <origin xyz=\"0 0 -0.08\" rpy=\"0 0 0\"/>";
  const auto pos = u.find(from);
  ASSERT_NE(pos, std::string::npos);
  u.replace(pos, from.size(),
            "<child link=\"r_sole\"/>\n    <origin xyz=\"0 0 -0.08\" rpy=\"3.141592653589793 0 0\"/>");
  try {
    parse_robot_config(read(test::humanoid_config()), u, "(test)");
    ADD_FAILURE();
  } catch (const ModelError& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("axes differ"), std::string::npos) << w;
    EXPECT_NE(w.find("sole_frame: {offset"), std::string::npos) << w;
  }
}

TEST(SoleFrames, CollisionBottomBelowTheSolePlaneIsAWarningWithBothHeights) {
  // Both foot boxes lowered by 10.5 mm (centre z -0.055 -> -0.0655): their bottom is at
  // -0.0905 m in the foot frame, the sole plane at -0.08 m.
  std::string u = read(test::humanoid_urdf());
  const std::string box = "<collision>\n      <origin xyz=\"0.03 0 -0.055\"";
  std::size_t n = 0;
  for (auto pos = u.find(box); pos != std::string::npos; pos = u.find(box, pos + 1), ++n)
    u.replace(pos, box.size(), "<collision>\n      <origin xyz=\"0.03 0 -0.0655\"");
  ASSERT_EQ(n, 2u);
  const RobotConfig cfg = parse_robot_config(read(test::humanoid_config()), u, "(test)");
  ASSERT_EQ(cfg.warnings.size(), 2u);
  for (const std::string& w : cfg.warnings) {
    EXPECT_NE(w.find("z = -0.0800 m"), std::string::npos) << w;
    EXPECT_NE(w.find("z = -0.0905 m"), std::string::npos) << w;
    EXPECT_NE(w.find("below the sole plane by 10.5 mm"), std::string::npos) << w;
  }
  EXPECT_NEAR(cfg.feet[kRight].collision_bottom, -0.0105, 1e-12);
  // The shipped robot: no warning.
  EXPECT_TRUE(load_robot_config(test::humanoid_config()).warnings.empty());
}

TEST(ForwardAxis, DefaultPlusXAndReadFromRobotYaml) {
  EXPECT_TRUE(load_robot_config(test::humanoid_config()).forward_axis.isApprox(Vector3::UnitX()));
  const std::string urdf = read(test::humanoid_urdf());
  const RobotConfig back =
      parse_robot_config(read(test::humanoid_config()) + "\nforward_axis: [-2, 0, 0]\n", urdf, "(t)");
  EXPECT_TRUE(back.forward_axis.isApprox(-Vector3::UnitX())) << back.forward_axis.transpose();
  for (const auto& [bad, what] :
       {std::pair<std::string, std::string>{"[0, 0, 0]", "must not be zero"},
        {"[0, 0, 1]", "must be (nearly) horizontal"},
        {"[1, 0]", "expected a list of 3 numbers"}}) {
    try {
      parse_robot_config(read(test::humanoid_config()) + "\nforward_axis: " + bad + "\n", urdf, "(t)");
      ADD_FAILURE() << bad;
    } catch (const ModelError& e) {
      EXPECT_NE(std::string(e.what()).find("forward_axis: " + what), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace poise::model
