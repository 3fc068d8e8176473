// Issue #18 item 5: test robots nobody here tuned for (tests/robots/README.md). For each robot,
// `poise robot init URDF -o DIR` with no hand edit, then `poise run` on a scenario written here:
// stand 10 s, a forward push at 3 s and a lateral push at 6 s of 0.2 N s/kg each (2 * mass N
// for 0.1 s on the floating base), in process and distributed (lockstep, loopback DDS, a domain
// of this test's own). The run must survive (exit 0, result JSON "survived": true, no failed
// criterion); the figures (CoM error, foot slip, trunk pitch/roll) go to the test's output.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "child_process.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
using poise::testing::run_command;

namespace {

// What each robot is (tests/robots/generate_robots.py): the figures the generator was given, so
// that what `poise robot init` found is checked against something it did not compute.
struct Robot {
  const char* name;
  double mass;            ///< kg, as generated
  const char* left_foot;  ///< the URDF link of the robot's own left foot
  const char* right_foot;
  std::vector<std::string> init_says;  ///< lines `poise robot init` must print (traits handled)
  const char* waits_for = nullptr;     ///< not run yet (DISABLED_): the change it waits for
  const char* distributed_fails = nullptr;  ///< distributed run DISABLED_: what was measured
  const char* in_process_fails = nullptr;   ///< in-process run DISABLED_: what was measured
  double forward_x = 1.0;                   ///< x of the forward axis init must find (base frame)
  double facing_deg = 0.0;                  ///< scenario initial.facing_deg (world yaw of forward)
  unsigned leg_joints = 12;                 ///< movable joints of both legs, as generated
};

void PrintTo(const Robot& r, std::ostream* os) {
  *os << r.name;
}

const std::vector<Robot>& robots() {
  static const std::vector<Robot> r = {
      {"wren",
       30.0,
       "L_FOOT_LINK",
       "R_FOOT_LINK",
       {"sole frame L_FOOT_LINK_sole_poise (added)", "IMU frame: imu",
        "the IMU frame 'imu' is not on the floating base 'PELVIS' but on 'CHEST', behind "
        "WAIST_YAW",
        "joint 'L_FINGER_B' mimics 'L_FINGER_A': frozen"}},
      {"auroch",
       90.0,
       "leg_left_foot_link",
       "leg_right_foot_link",
       {"'leg_left_foot_link' has its z axis down",
        "joint 'arm_left_finger_b' mimics 'arm_left_finger_a': frozen"}},
      {"heron",
       55.0,
       "foot_link_left",
       "foot_link_right",
       {"left sole comes from the mesh", "IMU frame: imu",
        "the IMU frame 'imu' is not on the floating base 'pelvis' but on 'trunk', behind "
        "waist_yaw"}},
      // Its URDF sole links are 10 mm above the foot boxes: the sole plane is the boxes' bottom
      // (0.07 m ankle height + 10 mm), not the URDF's l_sole.
      // Until init damped the ankles for the inertia they carry in stance (2 December 2026,
      // components/robot_init/README.md), distributed (seed 1) it was thrown at 8.8 s: the lateral
      // rocking after the 6 s push did not die out, both CoPs sat on the feet's outer edges,
      // the base yawed, a foot slipped 15 mm, lifted, and an ankle roll reached its limit.
      {"badger",
       45.0,
       "l_foot",
       "r_foot",
       {"foot l_foot, sole x [-0.088, 0.132] y [-0.06, 0.06], 0.08 m below the foot frame"}},
      // Base facing -x: the robot's own left leg is at y < 0 in its base frame; init must find
      // forward_axis [-1, 0, 0]. The scenario faces it to world -x (facing_deg 180: base not
      // turned), its pushes in its heading.
      {"kestrel",
       65.0,
       "LeftFootLink",
       "RightFootLink",
       {"forward_axis [-1, 0, 0] (base frame, from the toes)"},
       nullptr,
       nullptr,
       nullptr,
       -1.0,
       180.0},
      // Five-joint legs (no ankle roll, as on Unitree's H1): with both feet flat the pelvis
      // cannot move sideways and eq (33)'s twelve foot rows have rank 11. Until the
      // acceleration solver dropped dependent rows (2026-12-05) a plain Cholesky of its Schur
      // complement took a round-off pivot and x came out as noise (momentum-rate errors of
      // 1e4 N): an H1 from its public URDF pitched 20 deg standing and, on the true state, fell.
      {"ibis",
       50.0,
       "left_foot_link",
       "right_foot_link",
       {"the left leg has 5 joints: its foot cannot take every pose under the hip",
        "IMU frame: imu_in_pelvis",
        "the URDF's IMU link 'imu' (on 'torso_link') is not used: the IMU frame is "
        "'imu_in_pelvis'"},
       nullptr,
       nullptr,
       nullptr,
       1.0,
       0.0,
       10},
  };
  return r;
}

fs::path work_dir(const std::string& name) {
  const fs::path d = fs::path(POISE_BINARY_DIR) / "test_output" / "test_robots" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}


std::string read(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

fs::path urdf_of(const Robot& r) {
  return fs::path(POISE_SOURCE_DIR) / "tests/robots" / r.name / (std::string(r.name) + ".urdf");
}

// `poise robot init`, checked against the generator's figures; then the push scenario written
// next to the robot.yaml. Returns the scenario path (empty on failure).
fs::path init_and_write_scenario(const Robot& r, const fs::path& dir) {
  const fs::path urdf = urdf_of(r);
  const std::string before = read(urdf);
  const fs::path out = dir / "robot";
  auto [code, text] =
      run_command({bin("poise"), "robot", "init", urdf.string(), "-o", out.string()}, 60s);
  std::cout << text;
  if (code != 0) {
    ADD_FAILURE() << "poise robot init " << r.name << " exited " << code << ":\n" << text;
    return {};
  }
  EXPECT_EQ(read(urdf), before) << "the URDF was modified";
  for (const std::string& s : r.init_says)
    EXPECT_NE(text.find(s), std::string::npos) << s;

  const poise::model::RobotConfig cfg = poise::model::load_robot_config(out / "robot.yaml");
  const poise::model::Model m = poise::model::load_robot_model(cfg);
  EXPECT_NEAR(m.total_mass, r.mass, 0.01 * r.mass);
  EXPECT_EQ(cfg.leg_joints.size(), r.leg_joints);
  // The feet found are the robot's own left and right foot links (their frame may be one added
  // by init on the same body).
  const auto foot_body = [&](poise::model::Side s) {
    return m.body_name[m.frames[cfg.feet[s].frame_id].body];
  };
  EXPECT_EQ(foot_body(poise::model::kLeft), r.left_foot);
  EXPECT_EQ(foot_body(poise::model::kRight), r.right_foot);

  // The gains init chose (components/robot_init/README.md), checked on the model: each joint's
  // explicit PD at 1 kHz within kp dt^2 / I <= 0.04, kd dt / I <= 0.4 on the smallest inertia it
  // meets (1 / (M^-1)_jj, the robot free), and the whole robot's loop (free floating, every
  // joint's PD, semi-implicit Euler as the simulator applies it) stable with the gains doubled.
  poise::model::Data data(m);
  {
    const Eigen::MatrixXd Minv = poise::model::crba(m, data, cfg.q_nominal).inverse();
    const int N = m.nv;
    const double dt = 0.001;
    Eigen::VectorXd kp = Eigen::VectorXd::Zero(N), kd = Eigen::VectorXd::Zero(N);
    for (int j = 0; j < m.njoints; ++j) {
      const auto& g = cfg.gains[static_cast<std::size_t>(j)];
      const double I = 1.0 / Minv(m.idx_v(j), m.idx_v(j));
      EXPECT_LE(g.kp * dt * dt / I, 0.04 * 1.001) << m.joint_names[j];
      EXPECT_LE(g.kd * dt / I, 0.4 * 1.001) << m.joint_names[j];
      kp[m.idx_v(j)] = 2.0 * g.kp;
      kd[m.idx_v(j)] = 2.0 * g.kd;
    }
    const Eigen::MatrixXd Id = Eigen::MatrixXd::Identity(N, N);
    const Eigen::MatrixXd Aq = -dt * Minv * kp.asDiagonal(), Av = Id - dt * Minv * kd.asDiagonal();
    Eigen::MatrixXd A(2 * N, 2 * N);
    A << Id + dt * Aq, dt * Av, Aq, Av;  // [q; v] -> [q + dt v+; v+]
    EXPECT_LE(Eigen::EigenSolver<Eigen::MatrixXd>(A, false).eigenvalues().cwiseAbs().maxCoeff(),
              1.0 + 1e-6)
        << "the explicit PD loop with the gains doubled";
  }

  // Standing height of the floating base in the nominal posture (soles on the ground).
  poise::model::forward_kinematics(m, data, cfg.q_nominal);
  const double sole_z =
      poise::model::frame_placement(m, data, cfg.feet[poise::model::kLeft].sole_frame_id).p.z();
  const double base_height = cfg.q_nominal[2] - sole_z;
  EXPECT_GT(base_height, 0.3);

  auto [info_code, info] =
      run_command({bin("poise"), "model", "info", (out / "robot.yaml").string()}, 30s);
  EXPECT_EQ(info_code, 0) << info;

  // 0.2 N s/kg: 2 * mass N for 0.1 s, forward at 3 s, leftward at 6 s, in the robot's own
  // heading (push frame: heading: x the robot's forward, robot.yaml forward_axis, at the start),
  // the robot facing initial.facing_deg in the world.
  const double f = 2.0 * m.total_mass;
  EXPECT_NEAR(cfg.forward_axis.x(), r.forward_x, 1e-5) << "robot.yaml forward_axis";
  const std::string base = m.body_name[0];
  const fs::path scenario = dir / "push.yaml";
  std::ofstream(scenario) << "name: " << r.name
                          << "_push\nrobot: {config: " << (out / "robot.yaml").string()
                          << "}\nduration: 10.0\ninitial: {posture: nominal, support: double, "
                             "facing_deg: "
                          << r.facing_deg
                          << "}\n"
                             "world:\n  ground: {friction: 0.8}\n"
                             "disturbances:\n  pushes:\n"
                          << "    - {link: " << base
                          << ", point: [0, 0, 0], frame: heading, force: [" << f
                          << ", 0, 0], start: 3.0, duration: 0.1}\n"
                          << "    - {link: " << base
                          << ", point: [0, 0, 0], frame: heading, force: [0, " << f
                          << ", 0], start: 6.0, duration: 0.1}\n"
                          << "sensors: {seed: 1}\nsuccess:\n  com_error_max_m: 0.05\n"
                             "  com_error_final_m: 0.01\n  foot_slip_max_m: 0.01\n"
                             "  allow_non_foot_contacts: false\n  min_base_height_m: "
                          << 0.8 * base_height << "\n";
  return scenario;
}

// The verdict from the result JSON, and the figures into the test's output.
void check_result(const Robot& r, const std::string& mode, int code, const std::string& out,
                  const fs::path& json_path, double seconds) {
  EXPECT_EQ(code, 0) << out;
  ASSERT_TRUE(fs::exists(json_path)) << out;
  const nlohmann::json j = nlohmann::json::parse(read(json_path));
  EXPECT_TRUE(j.at("survived").get<bool>()) << j.dump(2);
  EXPECT_TRUE(j.at("failed_criteria").empty()) << j.dump(2);
  EXPECT_DOUBLE_EQ(j.at("sim_time_s").get<double>(), 10.0) << j.dump(2);
  std::ostringstream fig;
  fig << r.name << " " << mode << ": survived " << j.at("survived").get<bool>()
      << ", CoM error max " << j.at("com_error_max_m").get<double>() * 1000 << " mm, final "
      << j.at("com_error_final_m").get<double>() * 1000 << " mm, foot slip max "
      << j.at("foot_slip_max_m").get<double>() * 1000 << " mm, trunk pitch/roll max "
      << j.at("trunk_pitch_max_deg").get<double>() << "/"
      << j.at("trunk_roll_max_deg").get<double>() << " deg, run " << seconds << " s wall";
  std::cout << fig.str() << "\n";
  ::testing::Test::RecordProperty("figures", fig.str());
}

class TestRobot : public ::testing::TestWithParam<Robot> {};
class TestRobotDistributed : public ::testing::TestWithParam<Robot> {};

TEST_P(TestRobot, InitThenStandAndPushInProcess) {
  const Robot& r = GetParam();
  const fs::path dir = work_dir(std::string(r.name) + "_inprocess");
  const fs::path scenario = init_and_write_scenario(r, dir);
  ASSERT_FALSE(scenario.empty());
  const auto t0 = std::chrono::steady_clock::now();
  auto [code, out] = run_command({bin("poise"), "run", scenario.string(), "--in-process", "-q", "-o",
                              (dir / "result.json").string()},
                             120s);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  check_result(r, "in process", code, out, dir / "result.json", s);
}

TEST_P(TestRobotDistributed, InitThenStandAndPushDistributed) {
  const Robot& r = GetParam();
  const fs::path dir = work_dir(std::string(r.name) + "_distributed");
  const fs::path scenario = init_and_write_scenario(r, dir);
  ASSERT_FALSE(scenario.empty());
  const auto t0 = std::chrono::steady_clock::now();
  auto [code, out] = run_command(
      {bin("poise"), "run", scenario.string(), "-q", "--lockstep", "--domain",
       std::to_string(poise::testing::unique_domain_id()), "-o", (dir / "result.json").string(),
       "--log-dir", (dir / "logs").string(), "--timeout", "150"},
      180s);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  check_result(r, "distributed", code, out, dir / "result.json", s);
}

// The runs not made yet are instantiated as DISABLED_Robots/... (ctest registers them as
// disabled: the prefix must begin the suite name, not the parameter's).
std::vector<Robot> robots_where(bool distributed, bool disabled) {
  std::vector<Robot> out;
  for (const Robot& r : robots()) {
    const bool off = r.waits_for || (distributed ? r.distributed_fails : r.in_process_fails);
    if (off == disabled) out.push_back(r);
  }
  return out;
}
std::string param_name(const ::testing::TestParamInfo<Robot>& i) {
  return i.param.name;
}

INSTANTIATE_TEST_SUITE_P(Robots, TestRobot, ::testing::ValuesIn(robots_where(false, false)),
                         param_name);
INSTANTIATE_TEST_SUITE_P(DISABLED_Robots, TestRobot, ::testing::ValuesIn(robots_where(false, true)),
                         param_name);
INSTANTIATE_TEST_SUITE_P(Robots, TestRobotDistributed,
                         ::testing::ValuesIn(robots_where(true, false)), param_name);
INSTANTIATE_TEST_SUITE_P(DISABLED_Robots, TestRobotDistributed,
                         ::testing::ValuesIn(robots_where(true, true)), param_name);

// badger as its makers describe it: the sole plane at the URDF's l_sole / r_sole links, 10 mm
// above the bottom of the foot boxes (a hand edit of init's robot.yaml, the only one here).
// Writes the edited robot.yaml and the push scenario in `dir`; returns the scenario.
fs::path badger_with_its_own_soles(const fs::path& dir) {
  const Robot& r = robots()[3];
  EXPECT_STREQ(r.name, "badger");
  const fs::path scenario = init_and_write_scenario(r, dir);
  if (scenario.empty()) return {};
  std::string yaml = read(dir / "robot" / "robot.yaml");
  // (sole_frame as init wrote it: a link name, or {offset, rpy} in the foot link)
  yaml = std::regex_replace(yaml, std::regex(R"((frame: ([lr])_foot\n\s*sole_frame: )[^\n]*)"),
                            "$1$2_sole");
  yaml = std::regex_replace(yaml, std::regex("height: 0.08\\}"), "height: 0.07}");
  yaml = std::regex_replace(yaml, std::regex("urdf: .*"), "urdf: " + urdf_of(r).string());
  EXPECT_NE(yaml.find("sole_frame: l_sole"), std::string::npos) << yaml;
  EXPECT_EQ(yaml.find("height: 0.08"), std::string::npos) << yaml;
  std::ofstream(dir / "robot" / "robot.yaml") << yaml;
  return scenario;
}

// The loader warns with both heights.
TEST(TestRobotTraits, FootBoxOffTheSolePlaneIsAWarningWithBothHeights) {
  const fs::path dir = work_dir("badger_own_soles");
  ASSERT_FALSE(badger_with_its_own_soles(dir).empty());
  auto [info_code, info] =
      run_command({bin("poise"), "model", "info", (dir / "robot" / "robot.yaml").string()}, 30s);
  EXPECT_EQ(info_code, 0) << info;
  for (const char* side : {"left", "right"}) {
    const std::regex warn(
        std::string("warning: feet\\.") + side +
        ": the sole plane is at z = -0\\.0700 m [^\\n]* collision geometry bottom "
        "is at z = -0\\.0800 m");
    EXPECT_TRUE(std::regex_search(info, warn)) << info;
  }
}

// It stands and survives the pushes in process: DISABLED_, at the edge of the 10 mm foot-slip
// limit. Measured 2 December 2026 12:40-12:46 UTC on the tree then (dc89d09 and other helpers'
// work in progress), in process, sensor seeds 1-5, foot slip max: with init's stance-aware
// damping (c61a220) 19.7, 6.4, 1.7, 24.1, 2.2 mm (seeds 1 and 4 fail; at 12:27 UTC, before
// dc89d09, seed 1 gave 2.9 mm); with the rule before 1.5, 1.3, 23.3, 1.4, 3.7 mm (seed 3 fails);
// none of these ten runs fell. The same robot with the soles init finds (Robots/badger): now
// 7.4, 1.6, 16.4, 1.8, 2.2 mm; with the rule before thrown (581 mm), 1.1, 1.4, 1.4, 74.9 mm.
TEST(TestRobotTraits, DISABLED_FootBoxOffTheSolePlaneStandsAndSurvivesThePushes) {
  const Robot& r = robots()[3];
  const fs::path dir = work_dir("badger_own_soles_run");
  const fs::path scenario = badger_with_its_own_soles(dir);
  ASSERT_FALSE(scenario.empty());
  const auto t0 = std::chrono::steady_clock::now();
  auto [code, out] = run_command({bin("poise"), "run", scenario.string(), "--in-process", "-q", "-o",
                              (dir / "result.json").string()},
                             120s);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  check_result(r, "in process, its own sole links", code, out, dir / "result.json", s);
}

// The traits the README lists are in the committed files.
TEST(TestRobotFiles, CarryTheirTraits) {
  const auto urdf = [](const char* n) { return read(urdf_of(Robot{n, 0, "", "", {}})); };
  const std::string wren = urdf("wren"), auroch = urdf("auroch"), heron = urdf("heron");
  EXPECT_FALSE(std::regex_search(wren, std::regex(R"(<link name="[^"]*(sole|SOLE))")));
  EXPECT_NE(wren.find(R"(<joint name="imu_mount" type="fixed">
    <parent link="CHEST"/>)"),
            std::string::npos);
  EXPECT_TRUE(std::regex_search(
      wren,
      std::regex(R"(<joint name="L_FINGER_B" type="revolute">[\s\S]*?<mimic joint="L_FINGER_A")")));
  // auroch: a fixed joint with <mimic>, the foot frame turned upside down, degenerate leaves.
  EXPECT_TRUE(std::regex_search(
      auroch, std::regex(R"(type="fixed">[^/]*/>\s*<child[^/]*/>\s*<origin[^/]*/>\s*<mimic )")));
  EXPECT_TRUE(std::regex_search(
      auroch,
      std::regex(
          R"(<child link="leg_left_foot_link"/>\s*<origin xyz="0 0 0" rpy="3.14159 0 0"/>)")));
  EXPECT_NE(auroch.find(R"(<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>)"),
            std::string::npos);
  EXPECT_NE(auroch.find(R"(ixx="1e-05" ixy="0" ixz="0" iyy="1e-05" iyz="0" izz="0.002")"),
            std::string::npos);
  // heron: the feet collide as meshes only.
  EXPECT_TRUE(std::regex_search(
      heron,
      std::regex(
          R"(<link name="foot_link_left">[\s\S]*?<collision>\s*<origin[^>]*>\s*<geometry><mesh )")));
  EXPECT_EQ(std::regex_search(
                heron, std::regex(R"(<link name="foot_link_left">(?:(?!</link>)[\s\S])*<box)")),
            false);
}

// The committed files are what the generator writes (python3 is part of Debian; skipped without).
TEST(TestRobotFiles, AreWhatTheGeneratorWrites) {
  if (std::system("python3 --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "no python3";
  const fs::path dir = work_dir("generated");
  const fs::path src = fs::path(POISE_SOURCE_DIR) / "tests/robots";
  auto [code, out] = run_command(
      {"/usr/bin/env", "python3", (src / "generate_robots.py").string(), "--out", dir.string()},
      60s);
  ASSERT_EQ(code, 0) << out;
  int files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), dir);
    EXPECT_EQ(read(e.path()), read(src / rel)) << rel << ": re-run tests/robots/generate_robots.py";
    ++files;
  }
  EXPECT_GE(files, 6);
}

}  // namespace
