#pragma once
// A robot one joint over the wire's limit (MAX_JOINTS = 64): the shipped 64-joint humanoid with
// an extra wrist joint, its robot.yaml, and a standing scenario for it, written into `dir`.
// Every tool must refuse it by name (it once ran in process and wrote past the command arrays).

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace poise::testing {

inline std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Writes poise_humanoid_64.urdf (65 joints), robot.yaml and standing_65.yaml into `dir` (made
/// if missing) and returns `dir`. `source_dir`: the project's source tree.
inline std::filesystem::path write_sixty_five_joint_robot(const std::filesystem::path& dir,
                                                          const std::filesystem::path& source_dir) {
  namespace fs = std::filesystem;
  fs::create_directories(dir);
  const fs::path robot64 = source_dir / "deploy/robots/poise_humanoid_64";
  std::string urdf = read_text(robot64 / "poise_humanoid_64.urdf");
  const std::string extra =
      "  <joint name=\"extra_joint\" type=\"revolute\"><parent link=\"l_wrist_yaw_link\"/>"
      "<child link=\"extra_link\"/><axis xyz=\"0 0 1\"/>"
      "<limit lower=\"-1\" upper=\"1\" effort=\"10\" velocity=\"5\"/></joint>\n"
      "  <link name=\"extra_link\"><inertial><mass value=\"0.01\"/>"
      "<inertia ixx=\"1e-6\" iyy=\"1e-6\" izz=\"1e-6\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"
      "</inertial></link>\n</robot>";
  urdf.replace(urdf.rfind("</robot>"), 8, extra);
  std::ofstream(dir / "poise_humanoid_64.urdf") << urdf;
  std::ofstream(dir / "robot.yaml") << read_text(robot64 / "robot.yaml");
  std::string scenario = read_text(source_dir / "deploy/scenarios/scaling/standing_64.yaml");
  const std::string rel = "../../robots/poise_humanoid_64/robot.yaml";
  scenario.replace(scenario.find(rel), rel.size(), (dir / "robot.yaml").string());
  std::ofstream(dir / "standing_65.yaml") << scenario;
  return dir;
}

}  // namespace poise::testing
