// The in-process loop under AddressSanitizer and UndefinedBehaviorSanitizer (issue #51 item 3):
// built only in a POISE_SANITIZE=ON build (tests/sanitized/README.md), where every library it
// runs (model, simulator with Bullet's calls, estimator, contact optimiser, controller, safety
// layer, scenario loader, message conversions) is instrumented. A memory or UB error aborts the
// test with the sanitizer's report. Each run is also judged as the normal build judges it.
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "poise/inprocess/in_process_loop.hpp"
#include "poise/scenario/scenario.hpp"
#include "support/sixty_five_joints.hpp"

namespace {

namespace fs = std::filesystem;
namespace inprocess = poise::inprocess;
namespace scenario = poise::scenario;

const fs::path kScenarios = fs::path(POISE_SOURCE_DIR) / "deploy/scenarios";

struct Case {
  const char* file;
  double seconds;  // <= 0: the scenario's duration
  const char* estimator;
  bool qp;
};

class SanitizedLoop : public ::testing::TestWithParam<Case> {};

// Pushes, a drop, moving platforms, a step from a reference, both contact methods, both
// estimators, and the 64-joint robot: each run survives and reports finite figures.
TEST_P(SanitizedLoop, RunsCleanAndSurvives) {
  const Case c = GetParam();
  const scenario::Scenario s = scenario::load_scenario((kScenarios / c.file).string());
  inprocess::LoopOptions o;
  o.duration = c.seconds;
  o.estimator = c.estimator;
  if (c.qp) o.contact_method = poise::contact::Method::kQp;
  inprocess::InProcessLoop loop(s, o);
  const inprocess::RunResult r = loop.run();
  std::printf("[sanitized] %s %.1f s %s%s: survived %d, CoM error max %.4f m\n", c.file,
              c.seconds, c.estimator, c.qp ? " qp" : "", r.survived, r.com_error_max_m);
  EXPECT_TRUE(r.survived) << c.file;
  EXPECT_TRUE(std::isfinite(r.com_error_max_m));
}

INSTANTIATE_TEST_SUITE_P(
    Scenarios, SanitizedLoop,
    ::testing::Values(Case{"standing.yaml", 1.0, "invariant-ekf", false},
                      Case{"standing.yaml", 1.0, "leg-odometry", true},
                      Case{"forward_push_double_support.yaml", 0.0, "", false},
                      Case{"lateral_push_single_support.yaml", 0.0, "", true},
                      Case{"drop_onto_feet.yaml", 1.5, "", false},
                      Case{"platforms_out_of_phase.yaml", 2.0, "", false},
                      Case{"step_in_place.yaml", 0.0, "", false},
                      Case{"scaling/standing_64.yaml", 0.3, "", false}),
    [](const auto& info) {
      std::string name = fs::path(info.param.file).stem().string() + "_" +
                         std::to_string(info.index);
      for (auto& ch : name)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return name;
    });

// One joint over the wire's 64: refused by name when the loop is built (it used to run and
// write past the joint command's arrays: "double free or corruption").
TEST(SanitizedLoopLimits, SixtyFiveJointsAreRefusedBeforeAnythingRuns) {
  const fs::path dir = poise::testing::write_sixty_five_joint_robot(
      fs::path(::testing::TempDir()) / "poise_sanitized_65", POISE_SOURCE_DIR);
  try {
    const scenario::Scenario s = scenario::load_scenario((dir / "standing_65.yaml").string());
    inprocess::LoopOptions o;
    o.duration = 0.01;
    inprocess::InProcessLoop loop(s, o);
    loop.run();
    ADD_FAILURE() << "a 65-joint robot ran";
  } catch (const std::exception& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("65 moving joints"), std::string::npos) << what;
    EXPECT_NE(what.find("at most 64"), std::string::npos) << what;
  }
}

}  // namespace
