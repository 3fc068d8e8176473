// The 32- and 64-joint variants of the humanoid (deploy/robots/poise_humanoid_32, _64; issue #19
// item 4): the committed files are the generator's output, the model sees the joints, mass and CoM
// of the URDF (summed here independently of poise::model), the added joints' gains are stable as
// an explicit PD at 1 kHz, and the 64-joint robot stands in process.
#include <gtest/gtest.h>
#include <urdf_model/model.h>
#include <urdf_parser/urdf_parser.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <vector>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "poise/model/centroidal.hpp"
#include "poise/model/data.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "support/child_process.hpp"
#include "support/sixty_five_joints.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const fs::path kRobots = fs::path(POISE_SOURCE_DIR) / "deploy" / "robots";

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path folder(int joints) {
  return kRobots / (joints == 19 ? "poise_humanoid" : "poise_humanoid_" + std::to_string(joints));
}

// (a) The committed URDFs (and the variants' robot.yaml) are what the generator writes.
TEST(ScaledRobots, CommittedFilesAreTheGeneratorsOutput) {
  for (int joints : {19, 32, 64}) {
    const fs::path out = fs::path(::testing::TempDir()) / ("gen_" + std::to_string(joints));
    fs::remove_all(out);
    const std::string cmd = "python3 '" + (kRobots / "poise_humanoid" / "generate_urdf.py").string() +
                            "' --joints " + std::to_string(joints) + " --out '" + out.string() +
                            "' > /dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const std::string name = folder(joints).filename().string();
    std::vector<std::string> files{name + ".urdf"};
    if (joints != 19) files.push_back("robot.yaml");
    for (const auto& f : files) {
      ASSERT_TRUE(fs::exists(out / f)) << f;
      EXPECT_EQ(slurp(out / f), slurp(folder(joints) / f))
          << folder(joints) / f << " differs from the generator's output: re-run "
          << "deploy/robots/poise_humanoid/generate_urdf.py --joints " << joints;
    }
    if (joints == 19) {
      EXPECT_FALSE(fs::exists(out / "robot.yaml"));  // hand-written for 19
    }
  }
}

// Independent sum over the URDF links: forward kinematics from urdfdom's joints (origin, axis),
// no poise::model code. Returns total mass and CoM in the base frame for the joint angles given.
struct MassCom {
  double mass = 0.0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
};

Eigen::Isometry3d pose(const urdf::Pose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  double x, y, z, w;
  p.rotation.getQuaternion(x, y, z, w);
  T.linear() = Eigen::Quaterniond(w, x, y, z).toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return T;
}

void accumulate(const urdf::ModelInterface& m, const urdf::LinkConstSharedPtr& link,
                const Eigen::Isometry3d& T_BL, const std::map<std::string, double>& q,
                MassCom& acc) {
  if (link->inertial) {
    const double mi = link->inertial->mass;
    acc.mass += mi;
    acc.com += mi * (T_BL * pose(link->inertial->origin).translation());
  }
  for (const auto& j : link->child_joints) {
    Eigen::Isometry3d T = T_BL * pose(j->parent_to_joint_origin_transform);
    if (j->type == urdf::Joint::REVOLUTE || j->type == urdf::Joint::CONTINUOUS) {
      const auto it = q.find(j->name);
      const double angle = it == q.end() ? 0.0 : it->second;
      T.rotate(Eigen::AngleAxisd(angle, Eigen::Vector3d(j->axis.x, j->axis.y, j->axis.z)));
    }
    accumulate(m, m.getLink(j->child_link_name), T, q, acc);
  }
}

int non_fixed_joints(const urdf::ModelInterface& m) {
  int n = 0;
  for (const auto& [name, j] : m.joints_)
    if (j->type != urdf::Joint::FIXED) ++n;
  return n;
}

// (b) Joint count, total mass and CoM in the nominal posture agree with the URDF.
TEST(ScaledRobots, ModelMatchesTheUrdf) {
  for (int joints : {32, 64}) {
    SCOPED_TRACE(joints);
    const auto rc = poise::model::load_robot_config(folder(joints) / "robot.yaml");
    const auto model = poise::model::build_model_from_urdf_string(rc.urdf_xml);
    EXPECT_EQ(model.njoints, joints);
    EXPECT_EQ(model.nv, joints + 6);

    const auto urdf = urdf::parseURDF(slurp(folder(joints) / (folder(joints).filename().string() + ".urdf")));
    ASSERT_TRUE(urdf);
    EXPECT_EQ(non_fixed_joints(*urdf), joints);
    std::map<std::string, double> q;
    for (int j = 0; j < model.njoints; ++j)
      q[model.joint_names[static_cast<std::size_t>(j)]] = rc.q_nominal[model.idx_q(j)];
    MassCom acc;
    accumulate(*urdf, urdf->getRoot(), Eigen::Isometry3d::Identity(), q, acc);
    acc.com /= acc.mass;

    EXPECT_NEAR(model.total_mass, acc.mass, 1e-9);
    EXPECT_NEAR(acc.mass, 50.8, 1e-6);  // the base robot's mass: the hands were split, not grown
    poise::model::Data data(model);
    poise::model::center_of_mass(model, data, rc.q_nominal);
    // CoM in the base frame from the model (q_nominal's base is upright at p_WB).
    const Eigen::Vector3d com_B = data.com - rc.q_nominal.head<3>();
    EXPECT_LT((com_B - acc.com).norm(), 1e-9) << com_B.transpose() << " vs " << acc.com.transpose();

    // Same CoM as the 19-joint robot's within 1 mm: the balance task is the same.
    const auto base = poise::model::load_robot_config(folder(19) / "robot.yaml");
    const auto base_model = poise::model::build_model_from_urdf_string(base.urdf_xml);
    poise::model::Data base_data(base_model);
    poise::model::center_of_mass(base_model, base_data, base.q_nominal);
    EXPECT_LT((data.com - base_data.com).norm(), 1e-3);
  }
}

// The robot's gains as the simulator applies them (explicit PD, semi-implicit Euler at 1 kHz) on
// the whole joint-space inertia of the nominal posture: no mode grows. With gains from the
// diagonal M_jj instead of the effective inertia the finger chains grow (spectral radius 5).
TEST(ScaledRobots, GainsAreStableAsExplicitPd) {
  for (int joints : {19, 32, 64}) {
    SCOPED_TRACE(joints);
    const auto rc = poise::model::load_robot_config(folder(joints) / "robot.yaml");
    const auto model = poise::model::build_model_from_urdf_string(rc.urdf_xml);
    poise::model::Data data(model);
    const Eigen::MatrixXd M = poise::model::crba(model, data, rc.q_nominal);
    const int N = model.nv;
    const double dt = 0.001;
    Eigen::VectorXd kp = Eigen::VectorXd::Zero(N), kd = Eigen::VectorXd::Zero(N);
    for (int j = 0; j < model.njoints; ++j) {
      kp[model.idx_v(j)] = rc.gains[static_cast<std::size_t>(j)].kp;
      kd[model.idx_v(j)] = rc.gains[static_cast<std::size_t>(j)].kd;
    }
    const Eigen::MatrixXd Minv = M.inverse();
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(N, N);
    const Eigen::MatrixXd Aq = -dt * Minv * kp.asDiagonal(), Av = I - dt * Minv * kd.asDiagonal();
    Eigen::MatrixXd A(2 * N, 2 * N);
    A << I + dt * Aq, dt * Av, Aq, Av;  // [q; v] -> [q + dt v+; v+]
    const double rho = Eigen::EigenSolver<Eigen::MatrixXd>(A, false).eigenvalues().cwiseAbs().maxCoeff();
    EXPECT_LE(rho, 1.0 + 1e-9);
  }
}

// (c) The 64-joint robot stands (in process: simulator, estimator, contact, controller).
TEST(ScaledRobots, SixtyFourJointsStandInProcess) {
  const std::string scenario =
      std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/scaling/standing_64.yaml";
  const std::string out = ::testing::TempDir() + "scaled_standing_64.json";
  fs::remove(out);
  poise::testing::ChildProcess p(
      {poise::testing::bin("poise"), "run", scenario, "--in-process", "--duration", "3", "-o", out},
      {}, false, true);
  const auto code = p.wait_for(120s);
  ASSERT_TRUE(code.has_value()) << p.output();
  std::ifstream in(out);
  ASSERT_TRUE(in.good()) << p.output();
  const auto j = nlohmann::json::parse(in);
  EXPECT_TRUE(j.value("survived", false)) << p.output();
  EXPECT_LT(j.value("com_error_max_m", 1.0), 0.02) << p.output();
}

}  // namespace

namespace {

// The 64-joint URDF with one more joint (on the left wrist), beside a copy of its robot.yaml.
struct Ran {
  std::optional<int> code;
  std::string output;
};

Ran run_poise(std::vector<std::string> args) {
  args.insert(args.begin(), poise::testing::bin("poise"));
  poise::testing::ChildProcess p(args, {}, false, true);
  Ran r;
  r.code = p.wait_for(120s);
  r.output = p.output();
  return r;
}

}  // namespace

// (d) The wire carries 64 joints (MAX_JOINTS): a robot with 65 is refused by every tool with a
// message naming the count and the limit (it used to run in process and write past the joint
// command's arrays), while the 64-joint robot runs in both modes.
TEST(ScaledRobots, SixtyFiveJointsAreRefusedByEveryToolSixtyFourRunInBothModes) {
  const fs::path dir = poise::testing::write_sixty_five_joint_robot(
      fs::path(::testing::TempDir()) / ("poise_65_" + std::to_string(::getpid())),
      POISE_SOURCE_DIR);
  const std::string urdf = (dir / "poise_humanoid_64.urdf").string();
  const std::string scenario = (dir / "standing_65.yaml").string();
  const std::vector<std::vector<std::string>> refusing = {
      {"model", "info", urdf},
      {"robot", "init", urdf, "-o", (dir / "init").string()},
      {"run", scenario, "--in-process", "--duration", "0.01"},
      {"run", scenario, "--duration", "0.01"},
  };
  for (const auto& args : refusing) {
    const Ran r = run_poise(args);
    ASSERT_TRUE(r.code.has_value()) << args[0] << " did not end:\n" << r.output;
    EXPECT_NE(*r.code, 0) << args[0] << " " << args[1] << ":\n" << r.output;
    EXPECT_NE(r.output.find("65 moving joints"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("at most 64"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("double free"), std::string::npos) << r.output;
  }
  EXPECT_FALSE(fs::exists(dir / "init" / "robot.yaml"));

  const std::string standing_64 =
      std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/scaling/standing_64.yaml";
  for (const bool in_process : {true, false}) {
    const std::string out = (dir / (in_process ? "inproc.json" : "dist.json")).string();
    std::vector<std::string> args = {"run", standing_64, "--duration", "0.3", "-o", out};
    if (in_process) args.push_back("--in-process");
    const Ran r = run_poise(args);
    ASSERT_TRUE(r.code.has_value()) << r.output;
    EXPECT_EQ(*r.code, 0) << r.output;
    std::ifstream in(out);
    ASSERT_TRUE(in.good()) << r.output;
    const auto j = nlohmann::json::parse(in);
    EXPECT_TRUE(j.value("survived", false)) << (in_process ? "in process\n" : "distributed\n")
                                            << r.output;
  }
  fs::remove_all(dir);
}
