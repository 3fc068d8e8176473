// `poise model info|eval` through its entry point.
#include <gtest/gtest.h>

#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "test_util.hpp"

namespace poise::model {
int cli_main(int argc, char** argv);
namespace {

struct Result {
  int code;
  std::string out, err;
};

Result run(std::vector<std::string> args, const std::string& stdin_text = "") {
  args.insert(args.begin(), "poise model");
  std::vector<char*> argv;
  for (auto& a : args)
    argv.push_back(a.data());
  std::istringstream in(stdin_text);
  std::ostringstream out, err;
  auto* cin_buf = std::cin.rdbuf(in.rdbuf());
  auto* cout_buf = std::cout.rdbuf(out.rdbuf());
  auto* cerr_buf = std::cerr.rdbuf(err.rdbuf());
  const int code = cli_main(static_cast<int>(argv.size()), argv.data());
  std::cin.rdbuf(cin_buf);
  std::cout.rdbuf(cout_buf);
  std::cerr.rdbuf(cerr_buf);
  return {code, out.str(), err.str()};
}

TEST(ModelCli, InfoListsJointsMassAndFeet) {
  const Result r = run({"info", test::humanoid_urdf()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("l_knee"), std::string::npos);
  EXPECT_NE(r.out.find("total mass: 50.8"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("right foot: frame r_foot"), std::string::npos) << r.out;
  const Result bad = run({"info", "/nonexistent.urdf"});
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.err.find("not found"), std::string::npos);
}

TEST(ModelCli, EvalStaticHoldingForceIsTheWeight) {
  // At rest with all joint accelerations zero, the base must carry the whole weight:
  // base_force = -m g and base_torque = (c - p_B) x (-m g).
  nlohmann::json q = {
      {"urdf", test::humanoid_urdf()},
      {"base",
       {{"position", {0.1, -0.2, 0.9}}, {"orientation_wxyz", {0.9659258, 0.0, 0.0, 0.2588190}}}},
      {"joints", {{"l_knee", {{"q", 0.5}}}, {"r_elbow", {{"q", -1.0}}}}},
      {"frames", {"l_sole", "imu_link"}}};
  const Result r = run({"eval"}, q.dump());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto out = nlohmann::json::parse(r.out);
  const double m = out["mass"];
  EXPECT_NEAR(m, 50.8, 1e-9);
  const Vector3 c(out["com"][0], out["com"][1], out["com"][2]);
  const Vector3 f(out["base_force"][0], out["base_force"][1], out["base_force"][2]);
  const Vector3 t(out["base_torque"][0], out["base_torque"][1], out["base_torque"][2]);
  const Vector3 w(0, 0, -9.81 * m);
  EXPECT_LT((f + w).norm(), 1e-9);
  EXPECT_LT((t - (c - Vector3(0.1, -0.2, 0.9)).cross(-w)).norm(), 1e-9);
  for (const auto& [name, tau] : out["joint_torques"].items())
    EXPECT_TRUE(std::isfinite(double(tau)));
  EXPECT_TRUE(out["frames"].contains("l_sole"));
  // Frame positions agree with the library.
  const Model model = build_model_from_urdf_file(test::humanoid_urdf());
  Data d(model);
  Eigen::VectorXd qv = model.neutral();
  qv.head<3>() << 0.1, -0.2, 0.9;
  qv.segment<4>(3) = Eigen::Quaterniond(0.9659258, 0, 0, 0.2588190).normalized().coeffs();
  qv[model.idx_q(model.joint_index("l_knee"))] = 0.5;
  qv[model.idx_q(model.joint_index("r_elbow"))] = -1.0;
  forward_kinematics(model, d, qv);
  const SE3 X = frame_placement(model, d, model.frame_id("l_sole"));
  const auto& p = out["frames"]["l_sole"]["position"];
  EXPECT_LT((Vector3(p[0], p[1], p[2]) - X.p).norm(), 1e-9);
}

TEST(ModelCli, EvalMomentumBalanceWithMotionAndExternalForce) {
  // l_dot = m g + f_ext + base_force, where l_dot = m * (CoM acceleration); the CoM acceleration
  // is computed here by finite differences of the reported CoM velocity along the motion.
  const Model model = build_model_from_urdf_file(test::test_urdf("prismatic_continuous.urdf"));
  nlohmann::json q = {
      {"urdf", test::test_urdf("prismatic_continuous.urdf")},
      {"base", {{"linear_velocity", {0.3, 0.0, 0.0}}, {"angular_velocity", {0.0, 0.0, 0.0}}}},
      {"joints", {{"slider", {{"q", 0.1}, {"qd", 0.2}, {"qdd", 0.7}}}}},
      {"gravity", {0, 0, -9.81}},
      {"external_forces",
       {{{"link", "tip"},
         {"point", {0.3, 0.1, 0.2}},
         {"force", {1, 2, 3}},
         {"torque", {0, 0, 0}}}}}};
  const Result r = run({"eval"}, q.dump());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto out = nlohmann::json::parse(r.out);
  // Pure translation of the base plus the slider: CoM acceleration = (m_moving / m) * slider
  // acceleration along the rotated slider axis (rpy yaw 0.3), base acceleration zero.
  const double m = out["mass"];
  double m_moving = 0.0;
  for (int b = 1; b < model.nbodies; ++b)
    if (b != model.joint_index("spin") + 1) m_moving += model.inertia[b].mass;
  const Vector3 axis(std::cos(0.3), std::sin(0.3), 0.0);
  const Vector3 ldot = m_moving * 0.7 * axis;
  const Vector3 f(out["base_force"][0], out["base_force"][1], out["base_force"][2]);
  EXPECT_LT((ldot - (m * Vector3(0, 0, -9.81) + Vector3(1, 2, 3) + f)).norm(), 1e-9);
}

TEST(ModelCli, EvalErrorsNameTheProblem) {
  const std::string urdf = test::humanoid_urdf();
  auto err = [&](const std::string& text) {
    const Result r = run({"eval"}, text);
    EXPECT_NE(r.code, 0) << text;
    return r.err;
  };
  EXPECT_NE(err("{not json").find("bad JSON"), std::string::npos);
  EXPECT_NE(err(R"({"urdf": ")" + urdf + R"(", "joints": {"l_kne": {"q": 1}}})").find("l_kne"),
            std::string::npos);
  EXPECT_NE(err(R"({"urdf": ")" + urdf + R"(", "frames": ["nose"]})").find("nose"),
            std::string::npos);
  EXPECT_NE(err(R"({"urdf": ")" + urdf +
                R"(", "external_forces": [{"link": "tail", "point": [0,0,0], "force": [1,0,0]}]})")
                .find("tail"),
            std::string::npos);
  EXPECT_NE(err(R"({"urdf": "/nonexistent.urdf"})").find("not found"), std::string::npos);
  EXPECT_NE(err(R"({"urdf": ")" + urdf + R"(", "gravity": [0, 0]})").find("gravity"),
            std::string::npos);
}

}  // namespace
}  // namespace poise::model
