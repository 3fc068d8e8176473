// JSON form of the contact problem / solution (the `poise contact solve` verb): field errors are
// named, and a problem round-tripped through JSON solves exactly like the struct.
#include "poise/contact/contact_json.hpp"

#include <random>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "contact_fixtures.hpp"
#include "poise/contact/contact_optimizer.hpp"

namespace poise::contact {
namespace {

nlohmann::json to_json(const ContactProblem& p) {
  auto arr = [](const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  nlohmann::json j = {{"mass", p.mass},
                      {"gravity", arr(p.gravity)},
                      {"com", arr(p.com)},
                      {"k_dot_desired", arr(p.k_dot_desired)},
                      {"l_dot_desired", arr(p.l_dot_desired)},
                      {"feet", nlohmann::json::array()}};
  const char* names[] = {"right", "left"};
  for (int i = 0; i < kMaxFeet; ++i) {
    const FootContact& f = p.feet[i];
    const Eigen::Quaterniond q(f.R_WF);
    j["feet"].push_back({{"name", names[i]},
                         {"in_contact", f.in_contact},
                         {"position", arr(f.p_WF)},
                         {"orientation_wxyz", {q.w(), q.x(), q.y(), q.z()}},
                         {"sole",
                          {{"x_min", f.sole.x_min},
                           {"x_max", f.sole.x_max},
                           {"y_min", f.sole.y_min},
                           {"y_max", f.sole.y_max}}},
                         {"safety_margin", f.safety_margin},
                         {"ankle_height", f.ankle_height},
                         {"mu", f.mu},
                         {"mu_torsion", f.mu_torsion}});
  }
  return j;
}

std::string error_of(const nlohmann::json& j) {
  std::array<bool, kMaxFeet> present{};
  try {
    problem_from_json(j, &present);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(ContactJson, RoundTripSolvesLikeTheStruct) {
  std::mt19937 rng(16);
  for (int trial = 0; trial < 50; ++trial) {
    const ContactProblem p = test::random_feasible(rng, true, trial % 2 == 0);
    std::array<bool, kMaxFeet> present{};
    const ContactProblem q = problem_from_json(nlohmann::json::parse(to_json(p).dump()), &present);
    EXPECT_TRUE(present[0] && present[1]);
    ContactOptimizer opt;
    ContactSolution a, b;
    opt.solve(p, a);
    opt.solve(q, b);
    EXPECT_EQ(a.status, b.status);
    EXPECT_LT((a.l_dot_admissible - b.l_dot_admissible).norm(), 1e-9 * p.mass * 9.81);
    EXPECT_LT((a.k_dot_admissible - b.k_dot_admissible).norm(), 1e-9 * p.mass * 9.81);
    const nlohmann::json out = solution_to_json(b, present, 1.5);
    EXPECT_EQ(out["status"], to_string(b.status));
    EXPECT_EQ(out["feet"].size(), 2u);
    EXPECT_DOUBLE_EQ(out["feet"][1]["force"][2].get<double>(), b.feet[1].force_W.z());
    EXPECT_DOUBLE_EQ(out["solve_time_us"].get<double>(), 1.5);
  }
}

TEST(ContactJson, ErrorsNameTheField) {
  std::mt19937 rng(17);
  const nlohmann::json good = to_json(test::random_feasible(rng, true, true));
  EXPECT_EQ(error_of(good), "");
  nlohmann::json j = good;
  j.erase("gravity");
  EXPECT_EQ(error_of(j), "gravity: missing field");
  j = good;
  j["com"] = {1.0, 2.0};
  EXPECT_EQ(error_of(j), "com: expected an array of 3 numbers");
  j = good;
  j["mass"] = "heavy";
  EXPECT_EQ(error_of(j), "mass: expected a number, got string");
  j = good;
  j["feet"][1]["orientation_wxyz"] = {1.0, 1.0, 0.0, 0.0};
  EXPECT_NE(error_of(j).find("feet[1].orientation_wxyz: not a unit quaternion"), std::string::npos);
  j = good;
  j["feet"][0]["sole"].erase("y_max");
  EXPECT_EQ(error_of(j), "feet[0].sole.y_max: missing field");
  j = good;
  j["feet"][1]["name"] = "right";
  EXPECT_EQ(error_of(j), "feet[1].name: foot listed twice");
  j = good;
  j["feet"][0]["in_contact"] = 1;
  EXPECT_EQ(error_of(j), "feet[0].in_contact: expected true or false");
  j = good;
  j["l_dot_desired"][2] = nullptr;
  EXPECT_EQ(error_of(j), "l_dot_desired[2]: expected a number, got null");
  j = good;
  j["weights"] = {{"w_k", std::numeric_limits<double>::infinity()}};
  EXPECT_EQ(error_of(j), "weights.w_k: not a finite number");
  EXPECT_EQ(error_of(nlohmann::json::array()), "problem: expected a JSON object");
}

}  // namespace
}  // namespace poise::contact
