// Issue #15 item 1, "the description on the wire is enough":
//  - the robot a node builds from poise/robot_description (robot_config + urdf) equals the one of
//    the files; an empty robot_config is a clear error telling to pass --robot;
//  - the stack (sim, estimator, contact, controller; mixed vendors) balances a short lockstep
//    scenario with the nodes started with no --robot from a folder with no robot files, on a
//    robot that exists only in a folder the nodes are never told about;
//  - a node given --robot of another robot refuses to run and names each difference;
//  - a description with a ~150 kB URDF goes between Fast DDS and Cyclone DDS both ways, and a node
//    of the other vendor builds its robot from it.
// Every DDS participant stays on loopback on a domain this test process claimed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include <poise/msg/robot_description.h>

#include "dds/dds_test_util.hpp"
#include "poise/dds/dds.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/robot_description.hpp"
#include "support/child_process.hpp"

namespace {

using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
namespace fs = std::filesystem;
namespace msg = poise::msg;
namespace dds = poise::dds;
namespace model = poise::model;
namespace node = poise::node;

const std::string kSource = POISE_SOURCE_DIR;
const std::string kRobotDir = kSource + "/deploy/robots/poise_humanoid";

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

fs::path scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() /
                     ("poise-robot-from-description-" + std::to_string(::getpid())) / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

int domain() {
  return dds::test::claim_test_domain();
}

dds::DdsOptions options(const std::string& vendor) {
  dds::DdsOptions o;
  o.vendor = dds::parse_vendor(vendor);
  o.domain_id = domain();
  o.participant_name = "robot_from_description_test";
  return o;
}

/// The description poise-sim sends for the project humanoid (robot_config + urdf), with
/// another URDF text if given.
msg::RobotDescription humanoid_description(const std::string& urdf = "") {
  const model::RobotConfig cfg = model::load_robot_config(kRobotDir + "/robot.yaml");
  const model::Model m = model::load_robot_model(cfg);
  msg::RobotDescription d;
  d.robot_name(cfg.name);
  d.urdf(urdf.empty() ? cfg.urdf_xml : urdf);
  d.robot_config(read(kRobotDir + "/robot.yaml"));
  d.joint_names(m.joint_names);
  d.imu_frame(cfg.imu_frame);
  for (int f = 0; f < 2; ++f) {
    msg::SoleGeometry& s = d.feet()[f];
    s.foot_frame(cfg.feet[f].frame);
    s.x_min(cfg.feet[f].sole.x_min);
    s.x_max(cfg.feet[f].sole.x_max);
    s.y_min(cfg.feet[f].sole.y_min);
    s.y_max(cfg.feet[f].sole.y_max);
    s.sole_height(cfg.feet[f].sole.height);
    s.safety_margin(cfg.safety_margin);
    s.mu(cfg.friction_mu);
    s.mu_torsion(cfg.torsional_mu);
  }
  d.control_period_s(0.001);
  return d;
}

/// The humanoid's URDF grown to at least `bytes` with small sensor links fixed to the pelvis
/// (mass, inertia, visual and collision each, like a real robot's sensor/cover links): the
/// same moving joints, so the humanoid's robot.yaml still fits it.
std::string grown_urdf(std::size_t bytes) {
  std::string urdf = read(kRobotDir + "/poise_humanoid.urdf");
  const auto end = urdf.rfind("</robot>");
  std::string extra;
  for (int i = 0; urdf.size() + extra.size() < bytes; ++i) {
    const std::string n = std::to_string(i);
    extra += "  <!-- cover and sensor mount " + n + " of the pelvis shell -->\n"
             "  <link name=\"pelvis_mount_" + n + "\">\n"
             "    <inertial>\n"
             "      <origin xyz=\"0.001 0.002 0.003\" rpy=\"0 0 0\"/>\n"
             "      <mass value=\"0.0001\"/>\n"
             "      <inertia ixx=\"1e-8\" ixy=\"0\" ixz=\"0\" iyy=\"1e-8\" iyz=\"0\" izz=\"1e-8\"/>\n"
             "    </inertial>\n"
             "    <visual>\n"
             "      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n"
             "      <geometry><box size=\"0.01 0.01 0.002\"/></geometry>\n"
             "      <material name=\"mount_grey\"><color rgba=\"0.5 0.5 0.5 1\"/></material>\n"
             "    </visual>\n"
             "    <collision>\n"
             "      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n"
             "      <geometry><box size=\"0.01 0.01 0.002\"/></geometry>\n"
             "    </collision>\n"
             "  </link>\n"
             "  <joint name=\"pelvis_mount_" + n + "_fixed\" type=\"fixed\">\n"
             "    <parent link=\"pelvis\"/>\n"
             "    <child link=\"pelvis_mount_" + n + "\"/>\n"
             "    <origin xyz=\"0.0" + std::to_string(i % 10) + " 0.01 0.02\" rpy=\"0 0 0\"/>\n"
             "  </joint>\n";
  }
  urdf.insert(end, extra);
  return urdf;
}

std::vector<std::string> node_args(const std::string& exe, const std::string& vendor,
                                   std::vector<std::string> extra = {}) {
  std::vector<std::string> a{bin(exe), "--dds", vendor, "--domain", std::to_string(domain())};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

/// argv run with `dir` as the working directory.
std::vector<std::string> in_dir(const fs::path& dir, const std::vector<std::string>& argv) {
  std::string cmd = "cd '" + dir.string() + "' && exec";
  for (const auto& a : argv)
    cmd += " '" + a + "'";
  return {"/bin/sh", "-c", cmd};
}

// ---------------------------------------------------------------------------------------------
// The library side (no DDS).

TEST(RobotFromDescription, EqualsTheRobotOfTheFiles) {
  const node::RobotFromDescription r = node::robot_from_description(humanoid_description());
  const model::RobotConfig cfg = model::load_robot_config(kRobotDir + "/robot.yaml");
  const auto d =
      model::robot_differences(r.config, r.model, "wire", cfg, model::load_robot_model(cfg), "file");
  EXPECT_TRUE(d.empty()) << d.front();
  EXPECT_EQ(r.source, "poise/robot_description");
  node::RobotFromDescription file{cfg, model::load_robot_model(cfg), "file"};
  EXPECT_TRUE(node::description_differences(file, "file", humanoid_description()).empty());
}

TEST(RobotFromDescription, EmptyConfigurationTellsToPassRobot) {
  msg::RobotDescription d = humanoid_description();
  d.robot_config("");
  try {
    node::robot_from_description(d);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("carries no robot configuration"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("--robot FILE"), std::string::npos) << e.what();
  }
}

TEST(RobotFromDescription, WithoutConfigurationTheFieldsAndTheUrdfAreChecked) {
  const model::RobotConfig cfg = model::load_robot_config(kRobotDir + "/robot.yaml");
  node::RobotFromDescription file{cfg, model::load_robot_model(cfg), "file"};
  msg::RobotDescription d = humanoid_description();
  d.robot_config("");
  EXPECT_TRUE(node::description_differences(file, "file", d).empty());
  d.feet()[1].y_max(0.07);
  d.urdf(std::regex_replace(d.urdf(), std::regex("<mass value=\"[0-9.]+\""), "<mass value=\"77\"",
                            std::regex_constants::format_first_only));
  const auto diff = node::description_differences(file, "file", d);
  std::string all;
  for (const auto& l : diff)
    all += l + "\n";
  EXPECT_NE(all.find("feet.left.sole.y_max [m]: 0.055 in file, 0.07 in the description"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find("mass [kg]"), std::string::npos) << all;
}

// ---------------------------------------------------------------------------------------------
// Real processes.

/// The humanoid copied into `dir` under another robot name (the URDF is the same): a robot no
/// node can know but from the description.
fs::path copy_robot(const fs::path& dir, const std::string& name) {
  write(dir / "poise_humanoid.urdf", read(kRobotDir + "/poise_humanoid.urdf"));
  write(dir / "robot.yaml", std::regex_replace(read(kRobotDir + "/robot.yaml"),
                                               std::regex("name: poise_humanoid"), "name: " + name));
  return dir / "robot.yaml";
}

TEST(RobotFromDescriptionProcesses, StackBalancesWithNoRobotFilesOnTheNodesSide) {
  const fs::path robot_dir = scratch("robot");        // only the simulator reads it
  const fs::path empty = scratch("empty");            // the launcher's and the nodes' cwd
  const fs::path out = scratch("out");
  const fs::path robot = copy_robot(robot_dir, "poise_humanoid_on_the_wire");
  std::string scenario = read(kSource + "/tests/nodes/standing_short.yaml");
  scenario = std::regex_replace(scenario, std::regex("config: [^\n]*"), "config: " + robot.string());
  write(robot_dir / "standing_wire.yaml", scenario);

  ChildProcess run(in_dir(empty, {bin("poise-launch"), (robot_dir / "standing_wire.yaml").string(),
                                  "--domain", std::to_string(domain()), "--dds-sim", "fastdds",
                                  "--dds-estimator", "cyclone", "--dds-contact", "fastdds",
                                  "--dds-controller", "cyclone", "--output",
                                  (out / "result.json").string(), "--log-dir",
                                  (out / "logs").string(), "--quiet"}),
                   {}, false, true);
  const auto code = run.wait_for(150s);
  ASSERT_TRUE(code.has_value()) << run.output();
  EXPECT_EQ(*code, 0) << run.output();
  const auto result = nlohmann::json::parse(read(out / "result.json"), nullptr, false);
  ASSERT_TRUE(result.is_object()) << run.output();
  EXPECT_TRUE(result.value("survived", false)) << result.dump(2);
  EXPECT_TRUE(result.value("completed", false)) << result.dump(2);
  EXPECT_TRUE(fs::is_empty(empty)) << "the nodes wrote into their working directory";
  for (const char* n : {"estimator", "controller"}) {
    const std::string log = read(out / "logs" / (std::string(n) + ".err")) +
                            read(out / "logs" / (std::string(n) + ".out"));
    EXPECT_NE(log.find("robot from poise/robot_description: poise_humanoid_on_the_wire"),
              std::string::npos)
        << n << ":\n"
        << log;
  }
}

/// Another robot: renamed, the right sole 1 cm longer, the first link of the URDF heavier.
fs::path other_robot(const fs::path& dir) {
  std::string urdf = read(kRobotDir + "/poise_humanoid.urdf");
  urdf = std::regex_replace(urdf, std::regex("<mass value=\"[0-9.]+\""), "<mass value=\"12.5\"",
                            std::regex_constants::format_first_only);
  write(dir / "poise_humanoid.urdf", urdf);
  std::string yaml = read(kRobotDir + "/robot.yaml");
  yaml = std::regex_replace(yaml, std::regex("name: poise_humanoid"), "name: other_robot");
  yaml = std::regex_replace(yaml, std::regex("x_max: 0.14"), "x_max: 0.15",
                            std::regex_constants::format_first_only);
  write(dir / "robot.yaml", yaml);
  return dir / "robot.yaml";
}

TEST(RobotFromDescriptionProcesses, NodeWithAnotherRobotRefusesAndNamesTheDifferences) {
  dds::Participant participant(options("cyclone"));
  dds::Publisher<msg::RobotDescription> description(participant);
  ASSERT_TRUE(description.publish(humanoid_description()));
  const fs::path other = other_robot(scratch("other"));
  for (const auto& [exe, vendor] : std::vector<std::pair<std::string, std::string>>{
           {"poise-estimator", "fastdds"}, {"poise-controller", "cyclone"},
           {"poise-contact", "fastdds"}}) {
    ChildProcess p(node_args(exe, vendor, {"--robot", other.string()}), {}, false, true);
    const auto code = p.wait_for(40s);
    ASSERT_TRUE(code.has_value()) << exe << " did not end\n" << p.output();
    EXPECT_NE(*code, 0) << exe << "\n" << p.output();
    const std::string out = p.output();
    const std::string label = "--robot '" + other.string() + "'";
    for (const std::string& expected :
         {"the robot of " + label + " is not the robot on poise/robot_description",
          "robot name: 'other_robot' in " + label + ", 'poise_humanoid' in the description",
          "feet.right.sole.x_max [m]: 0.15 in " + label + ", 0.14 in the description",
          "mass [kg]: 12.5 in " + label, std::string("total mass [kg]")})
      EXPECT_NE(out.find(expected), std::string::npos) << exe << ": no '" << expected << "' in\n"
                                                       << out;
  }
  // The same robot given with --robot (a copy in another folder, comments dropped): accepted.
  const fs::path same_dir = scratch("same");
  write(same_dir / "poise_humanoid.urdf", read(kRobotDir + "/poise_humanoid.urdf"));
  write(same_dir / "robot.yaml",
        std::regex_replace(read(kRobotDir + "/robot.yaml"), std::regex("#[^\n]*"), ""));
  ChildProcess same(node_args("poise-estimator", "fastdds",
                              {"--robot", (same_dir / "robot.yaml").string()}),
                    {}, false, true);
  EXPECT_TRUE(same.wait_for_output("the same robot", 30s)) << same.output();
  EXPECT_EQ(same.interrupt(10s).value_or(-1), 0) << same.output();
}

TEST(RobotFromDescriptionProcesses, DescriptionWithoutConfigurationAndNoRobotIsAClearError) {
  dds::Participant participant(options("fastdds"));
  dds::Publisher<msg::RobotDescription> description(participant);
  msg::RobotDescription d = humanoid_description();
  d.robot_config("");
  ASSERT_TRUE(description.publish(d));
  ChildProcess p(node_args("poise-estimator", "cyclone"), {}, false, true);
  const auto code = p.wait_for(40s);
  ASSERT_TRUE(code.has_value()) << p.output();
  EXPECT_NE(*code, 0) << p.output();
  EXPECT_NE(p.output().find("carries no robot configuration"), std::string::npos) << p.output();
  EXPECT_NE(p.output().find("pass the robot's configuration with --robot FILE"), std::string::npos)
      << p.output();
}

// Both ways between the vendors: the test's participant publishes a description whose URDF is
// POISE_LARGE_URDF_KB kB (default 150); `poise topic echo` of the other vendor prints it
// (compared byte for byte) and poise-estimator of the other vendor builds its robot from it.
class LargeDescription : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

TEST_P(LargeDescription, CrossesVendorsAndANodeBuildsItsRobotFromIt) {
  const auto [pub_vendor, sub_vendor] = GetParam();
  const char* kb_env = std::getenv("POISE_LARGE_URDF_KB");
  const std::size_t kb = kb_env ? std::stoul(kb_env) : 150;
  const std::string urdf = grown_urdf(kb * 1000);
  const msg::RobotDescription sent = humanoid_description(urdf);
  std::printf("description: urdf %zu bytes, robot_config %zu bytes, %s -> %s\n",
              sent.urdf().size(), sent.robot_config().size(), pub_vendor, sub_vendor);

  dds::Participant participant(options(pub_vendor));
  dds::Publisher<msg::RobotDescription> description(participant);
  ASSERT_TRUE(description.publish(sent));

  const auto t0 = std::chrono::steady_clock::now();
  ChildProcess echo_run({bin("poise"), "topic", "echo", "poise/robot_description", "--once",
                         "--json", "--timeout", "30", "--dds", sub_vendor, "--domain",
                         std::to_string(domain())},
                        {}, false, false);
  const auto code = echo_run.wait_for(45s);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(code.has_value());
  ASSERT_EQ(*code, 0) << echo_run.output().substr(0, 2000);
  const auto j = nlohmann::json::parse(echo_run.output(), nullptr, false);
  ASSERT_TRUE(j.is_object()) << echo_run.output().substr(0, 2000);
  EXPECT_EQ(j["urdf"].get<std::string>(), sent.urdf());
  EXPECT_EQ(j["robot_config"].get<std::string>(), sent.robot_config());
  std::printf("received by poise topic echo (%s) %.2f s after its start\n", sub_vendor, seconds);

  const fs::path empty = scratch(std::string("large-") + sub_vendor);
  ChildProcess estimator(in_dir(empty, node_args("poise-estimator", sub_vendor)), {}, false, true);
  EXPECT_TRUE(estimator.wait_for_output("robot from poise/robot_description: poise_humanoid", 40s))
      << estimator.output();
  EXPECT_EQ(estimator.interrupt(10s).value_or(-1), 0) << estimator.output();
}

INSTANTIATE_TEST_SUITE_P(Vendors, LargeDescription,
                         ::testing::Values(std::pair{"fastdds", "cyclone"},
                                           std::pair{"cyclone", "fastdds"}),
                         [](const auto& info) {
                           return std::string(info.param.first) + "_to_" + info.param.second;
                         });

}  // namespace
