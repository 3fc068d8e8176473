// `poise envelope` tested as users run it: the boundaries it reports agree with the runs it made
// (runs.csv), the distributed mode runs the same study, and bad input is refused clearly.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include "child_process.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
using poise::testing::run_command;

fs::path work_dir(const std::string& name) {
  const fs::path d = fs::path(POISE_BINARY_DIR) / "test_output" / "envelope" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}


/// CSV rows as maps column -> text (no quoted commas in the columns read here).
std::vector<std::map<std::string, std::string>> read_csv(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::vector<std::string> head;
  std::vector<std::map<std::string, std::string>> rows;
  auto split = [](const std::string& l) {
    std::vector<std::string> out;
    std::string cell;
    bool quoted = false;
    for (char c : l) {
      if (c == '"') quoted = !quoted;
      else if (c == ',' && !quoted) {
        out.push_back(cell);
        cell.clear();
      } else
        cell += c;
    }
    out.push_back(cell);
    return out;
  };
  if (!std::getline(in, line)) return rows;
  head = split(line);
  while (std::getline(in, line)) {
    const auto cells = split(line);
    std::map<std::string, std::string> r;
    for (std::size_t i = 0; i < head.size() && i < cells.size(); ++i) r[head[i]] = cells[i];
    rows.push_back(r);
  }
  return rows;
}

void check_push_study(const fs::path& dir, double step) {
  const auto runs = read_csv(dir / "runs.csv");
  const auto env = read_csv(dir / "envelope.csv");
  ASSERT_EQ(env.size(), 2u);  // one double-support and one single-support direction
  for (const auto& e : env) {
    SCOPED_TRACE(e.at("support_or_scenario"));
    const double boundary = std::stod(e.at("boundary"));
    const double monotone = std::stod(e.at("monotone"));
    EXPECT_GE(boundary, monotone);
    // The boundary was run and survived; every scan step up to `monotone` survived; some force
    // within one step above the boundary failed (it is an edge, not a guess).
    bool boundary_survived = false, failed_above = false;
    for (const auto& r : runs) {
      if (r.at("study") != "push" || r.at("support") != e.at("support_or_scenario")) continue;
      const double f = std::stod(r.at("force_N"));
      const bool ok = r.at("survived") == "1";
      if (std::abs(f - boundary) < 1e-6) boundary_survived = boundary_survived || ok;
      if (f <= monotone + 1e-6 && std::fmod(f + 1e-6, step) < 1e-3) {
        EXPECT_TRUE(ok) << f;
      }
      if (!ok && f > boundary && f <= boundary + step + 1e-6) failed_above = true;
      if (!ok) {
        EXPECT_FALSE(r.at("failed").empty()) << "a failed run names why";
      }
    }
    if (monotone > 0.0) {
      EXPECT_TRUE(boundary_survived);
    }
    EXPECT_TRUE(failed_above);
    // first_failure: the smallest force that failed, and each of its runs' kind of failure.
    double smallest = 1e18;
    for (const auto& r : runs)
      if (r.at("study") == "push" && r.at("support") == e.at("support_or_scenario") &&
          r.at("survived") != "1")
        smallest = std::min(smallest, std::stod(r.at("force_N")));
    const std::string first = e.at("first_failure");
    char force[32];
    std::snprintf(force, sizeof(force), "%.1f N: ", smallest);
    ASSERT_EQ(first.rfind(force, 0), 0u) << first << " (smallest failure " << smallest << " N)";
    // Each failed run's most severe kind is named.
    for (const auto& r : runs) {
      if (r.at("study") != "push" || r.at("support") != e.at("support_or_scenario") ||
          r.at("survived") == "1" || std::abs(std::stod(r.at("force_N")) - smallest) > 1e-9)
        continue;
      const std::string& f = r.at("failed");
      const auto has = [&](const char* c) { return f.find(c) != std::string::npos; };
      const char* kind = has("com_error_max") || has("min_base_height") || has("non_foot")
                             ? "fall"
                         : has("foot_slip_max") ? "slip"
                         : has("com_error_final") || has("recovery_time") ? "slow recovery"
                                                                            : "";
      EXPECT_NE(first.find(kind), std::string::npos) << first << " / " << f;
    }
  }
  std::ifstream md(dir / "envelope.md");
  std::stringstream text;
  text << md.rdbuf();
  EXPECT_NE(text.str().find("| double | 0.0 |"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("120 N survived (Fig. 8)"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("| failure above it |"), std::string::npos) << text.str();
}

TEST(Envelope, PushBoundariesAgreeWithTheRunsInProcess) {
  const fs::path dir = work_dir("pushes");
  auto [code, out] =
      run_command({bin("poise"), "envelope", "pushes", "--directions", "1", "--single-directions", "1",
               "--force-step", "120", "--force-tol", "30", "--force-max", "480", "--probes", "1",
               "-o", dir.string()},
              240s);
  ASSERT_EQ(code, 0) << out;
  check_push_study(dir, 120.0);
  for (const char* pic : {"push_envelope.png", "push_envelope.svg"})
    EXPECT_GT(fs::file_size(dir / pic), 1000u) << pic;
}

// --jitter-deg J: every force of the sweep is run at the direction and at -+J; it counts as
// survived only if all three did, and the summary counts the forces whose three runs disagreed.
TEST(Envelope, JitterRunsEachForceThreeTimesAndNeedsAllThree) {
  const fs::path dir = work_dir("jitter");
  auto [code, out] =
      run_command({bin("poise"), "envelope", "pushes", "--supports", "double", "--directions", "1",
                   "--force-step", "120", "--force-tol", "60", "--force-max", "480", "--probes",
                   "0", "--jitter-deg", "0.5", "-o", dir.string()},
                  240s);
  ASSERT_EQ(code, 0) << out;
  std::map<double, std::vector<std::pair<double, bool>>> by_force;  // force -> (angle, survived)
  for (const auto& r : read_csv(dir / "runs.csv"))
    by_force[std::stod(r.at("force_N"))].push_back(
        {std::stod(r.at("direction_deg")), r.at("survived") == "1"});
  ASSERT_GE(by_force.size(), 2u);
  int split = 0;
  double last_all = 0.0, first_not_all = 1e9;
  for (const auto& [force, runs] : by_force) {
    ASSERT_EQ(runs.size(), 3u) << force;
    std::vector<double> angles;
    int survived = 0;
    for (const auto& [a, ok] : runs) {
      angles.push_back(a < 180.0 ? a : a - 360.0);
      survived += ok ? 1 : 0;
    }
    std::sort(angles.begin(), angles.end());
    EXPECT_NEAR(angles[0], -0.5, 1e-9);
    EXPECT_NEAR(angles[1], 0.0, 1e-9);
    EXPECT_NEAR(angles[2], 0.5, 1e-9);
    if (survived != 0 && survived != 3) ++split;
    if (survived == 3) last_all = std::max(last_all, force);
    else first_not_all = std::min(first_not_all, force);
  }
  const auto env = read_csv(dir / "envelope.csv");
  ASSERT_EQ(env.size(), 1u);
  const double boundary = std::stod(env[0].at("boundary"));
  EXPECT_NEAR(boundary, last_all, 1e-6) << "the boundary is the largest force all three survived";
  EXPECT_LT(boundary, first_not_all);
  std::ifstream md(dir / "envelope.md");
  std::stringstream text;
  text << md.rdbuf();
  EXPECT_NE(text.str().find("disagreed at " + std::to_string(split) + " forces"),
            std::string::npos)
      << text.str();
}

// --grid-forces: exactly the forces given (each once: 400 is given twice), in every direction
// (here with the jitter), no search;
// the summary tabulates every verdict, and the boundary is the largest force all runs survived.
TEST(Envelope, GridRunsExactlyTheForcesGivenAndTabulatesEveryVerdict) {
  const fs::path dir = work_dir("grid");
  auto [code, out] =
      run_command({bin("poise"), "envelope", "pushes", "--supports", "double", "--directions", "1",
                   "--grid-forces", "400,100,400", "--jitter-deg", "0.5", "-o", dir.string()},
                  240s);
  ASSERT_EQ(code, 0) << out;
  const auto runs = read_csv(dir / "runs.csv");
  ASSERT_EQ(runs.size(), 6u);
  std::map<double, std::string> cells;  // force -> S or not, ordered -0.5, 0, +0.5
  std::map<double, std::map<double, bool>> by;
  int survived = 0;
  for (const auto& r : runs) {
    const double f = std::stod(r.at("force_N"));
    double a = std::stod(r.at("direction_deg"));
    if (a > 180.0) a -= 360.0;
    by[f][a] = r.at("survived") == "1";
    survived += r.at("survived") == "1" ? 1 : 0;
  }
  ASSERT_EQ(by.size(), 2u);
  ASSERT_TRUE(by.count(100.0) && by.count(400.0));
  std::ifstream md(dir / "envelope.md");
  std::stringstream text;
  text << md.rdbuf();
  std::string row = "| double | 0.0 |";
  for (const auto& [f, angles] : by) {
    ASSERT_EQ(angles.size(), 3u) << f;
    // A survival is S, a failure one of the kind letters.
    row += " ";
    const std::size_t table = text.str().find("Every run (");
    ASSERT_NE(table, std::string::npos) << text.str();
    std::size_t at = text.str().find(row, table);
    ASSERT_NE(at, std::string::npos) << row << "\n" << text.str();
    const std::string cell = text.str().substr(at + row.size(), 3);
    for (std::size_t i = 0; i < 3; ++i) {
      const bool ok = std::next(angles.begin(), static_cast<long>(i))->second;
      EXPECT_EQ(cell[i] == 'S', ok) << f << " N, cell " << cell;
      if (!ok) {
        EXPECT_NE(std::string("fsctex").find(cell[i]), std::string::npos) << cell;
      }
    }
    row += cell + " |";
  }
  EXPECT_NE(text.str().find(std::to_string(survived) + " of 6 runs survived"), std::string::npos)
      << text.str();
  const auto env = read_csv(dir / "envelope.csv");
  ASSERT_EQ(env.size(), 1u);
  double largest_all = 0.0;
  for (const auto& [f, angles] : by) {
    bool all = true;
    for (const auto& [a, ok] : angles) all = all && ok;
    if (all) largest_all = f;
  }
  EXPECT_NEAR(std::stod(env[0].at("boundary")), largest_all, 1e-9);
}

TEST(Envelope, Fig11ReportsTheLongestPushSurvived) {
  const fs::path dir = work_dir("fig11");
  auto [code, out] = run_command(
      {bin("poise"), "envelope", "fig11", "--fig11-forces", "150", "--duration-max", "0.4",
       "--duration-tol", "0.05", "-o", dir.string()},
      240s);
  ASSERT_EQ(code, 0) << out;
  const auto env = read_csv(dir / "envelope.csv");
  ASSERT_EQ(env.size(), 1u);
  const double d = std::stod(env[0].at("boundary"));
  EXPECT_GT(d, 0.0);  // a 150 N push of some duration is survived (0.1 s is, measured)
  bool edge_failed = false;
  for (const auto& r : read_csv(dir / "runs.csv")) {
    const double t = std::stod(r.at("duration_s"));
    if (t <= d + 1e-9) {
      EXPECT_EQ(r.at("survived"), "1") << t;  // no failure below the edge
    }
    if (t > d && t <= d + 0.05 + 1e-9 && r.at("survived") == "0") edge_failed = true;
  }
  EXPECT_TRUE(edge_failed || env[0].at("reached_max") == "1");
  EXPECT_GT(fs::file_size(dir / "fig11.png"), 1000u);
}

// A platform run of the envelope is the scenario's own run at that frequency: the base scenario's
// settings (here platforms_in_phase's contact.method qp) hold in process as in `poise run`.
// Until this test the in-process envelope ran the sequential optimiser on these supports
// (0.05 Hz on ground truth: CoM error 28 mm and trunk pitch 30 deg against 2.5 mm and 4.5 deg).
TEST(Envelope, APlatformRunIsTheScenariosOwnRun) {
  const fs::path dir = work_dir("platform_run");
  const std::string base = std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/platforms_in_phase.yaml";
  auto [code, out] = run_command({bin("poise"), "envelope", "platforms", "--platforms", base,
                                  "--ground-truth-state", "--freq-step", "0.4", "--freq-max", "0.4",
                                  "--freq-tol", "0.4", "--probes", "0", "--periods", "1", "-o", dir.string()},
                                 240s);
  ASSERT_EQ(code, 0) << out;
  const auto runs = read_csv(dir / "runs.csv");
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_DOUBLE_EQ(std::stod(runs[0].at("frequency_Hz")), 0.4);
  // The same run by hand: the base scenario at 0.4 Hz for the ramp (2 + 4 s) plus one period.
  std::ifstream in(base);
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  for (std::size_t at = yaml.find("frequency: 0.12"); at != std::string::npos;
       at = yaml.find("frequency: 0.12", at))
    yaml.replace(at, 15, "frequency: 0.4");
  const std::size_t d = yaml.find("duration: 14.0");
  ASSERT_NE(d, std::string::npos);
  yaml.replace(d, 14, "duration: 8.5");
  const std::size_t r = yaml.find("../robots/");
  ASSERT_NE(r, std::string::npos);
  yaml.replace(r, 3, std::string(POISE_SOURCE_DIR) + "/deploy/");
  std::ofstream(dir / "by_hand.yaml") << yaml;
  auto [run_code, run_out] =
      run_command({bin("poise"), "run", (dir / "by_hand.yaml").string(), "--in-process",
                   "--ground-truth-state", "--quiet", "-o", (dir / "by_hand.json").string()},
                  120s);
  ASSERT_TRUE(run_code == 0 || run_code == 1) << run_out;
  std::ifstream j(dir / "by_hand.json");
  std::stringstream js;
  js << j.rdbuf();
  const std::string json = js.str();
  EXPECT_NE(json.find("\"contact_method\": \"qp\""), std::string::npos) << json;
  const auto number = [&](const std::string& key) {
    const std::size_t k = json.find("\"" + key + "\":");
    EXPECT_NE(k, std::string::npos) << key << " in " << json;
    return k == std::string::npos ? -1.0 : std::stod(json.substr(k + key.size() + 3));
  };
  EXPECT_EQ(runs[0].at("survived"), run_code == 0 ? "1" : "0") << run_out;
  EXPECT_NEAR(std::stod(runs[0].at("com_error_max_m")), number("com_error_max_m"), 1e-6);
  // runs.csv keeps 6 significant digits: 3 decimals for a fall's 100-180 deg.
  EXPECT_NEAR(std::stod(runs[0].at("trunk_pitch_max_deg")), number("trunk_pitch_max_deg"), 5e-4);
}

TEST(Envelope, DistributedLockstepRunsTheSameStudy) {
  const fs::path dir = work_dir("lockstep");
  auto [code, out] =
      run_command({bin("poise"), "envelope", "pushes", "--mode", "lockstep", "--directions", "1",
               "--single-directions", "1", "--force-step", "150", "--force-tol", "150",
               "--force-max", "450", "--probes", "0", "-o", dir.string()},
              280s);
  ASSERT_EQ(code, 0) << out;
  check_push_study(dir, 150.0);
  // Each run left its distributed result (one process per component).
  bool saw_logs = false;
  for (const auto& e : fs::directory_iterator(dir / "runs"))
    saw_logs = saw_logs || e.path().extension() == ".logs";
  EXPECT_TRUE(saw_logs);
}

// --controller-config FILE replaces every run's controller: section (--priority still applies on
// top); each run's scenario is kept in runs/, and `poise run` of one gives the run's verdict.
TEST(Envelope, AControllerConfigReplacesEveryRunsSection) {
  const fs::path dir = work_dir("controller_config");
  const fs::path cfg = dir / "ankle.yaml";
  std::ofstream(cfg) << "momentum: {ankle_first_blend: 0.1, gamma21: [20, 20, 20]}\n";
  auto [code, out] = run_command(
      {bin("poise"), "envelope", "pushes", "--supports", "double", "--directions", "1",
       "--force-step", "200", "--force-tol", "100", "--force-max", "400", "--probes", "0",
       "--priority", "weighted", "--controller-config", cfg.string(), "-o", dir.string()},
      240s);
  ASSERT_EQ(code, 0) << out;
  std::stringstream md;
  md << std::ifstream(dir / "envelope.md").rdbuf();
  EXPECT_NE(md.str().find("Controller: `" + cfg.string() + "`"), std::string::npos) << md.str();
  const auto rows = read_csv(dir / "runs.csv");
  ASSERT_GE(rows.size(), 2u);
  for (const auto& row : rows) {
    char name[96];
    std::snprintf(name, sizeof(name), "push_double_%05.1fdeg_%06.1fN",
                  std::stod(row.at("direction_deg")), std::stod(row.at("force_N")));
    const fs::path run_file = dir / "runs" / (std::string(name) + ".yaml");
    ASSERT_TRUE(fs::exists(run_file)) << run_file;
    const YAML::Node sc = YAML::LoadFile(run_file.string());
    EXPECT_EQ(sc["controller"]["momentum"]["ankle_first_blend"].as<double>(), 0.1) << name;
    EXPECT_EQ(sc["controller"]["momentum"]["gamma21"][0].as<double>(), 20.0) << name;
    EXPECT_EQ(sc["controller"]["contact"]["priority"].as<std::string>(), "weighted") << name;
  }
  // The first run again, by itself, in process: the same verdict.
  const auto& first = rows.front();
  char name[96];
  std::snprintf(name, sizeof(name), "push_double_%05.1fdeg_%06.1fN",
                std::stod(first.at("direction_deg")), std::stod(first.at("force_N")));
  const fs::path json = dir / "rerun.json";
  auto [rc, rout] = run_command({bin("poise"), "run", (dir / "runs" / (std::string(name) + ".yaml")).string(),
                                 "--in-process", "-q", "-o", json.string()},
                                120s);
  std::ifstream js(json);
  ASSERT_TRUE(js) << rout;
  const bool survived = nlohmann::json::parse(js).at("survived").get<bool>();
  EXPECT_EQ(survived, first.at("survived") == "1") << rout;
  EXPECT_EQ(rc, survived ? 0 : 1) << rout;

  // A bad controller file is refused before any run, naming the key.
  const fs::path bad_dir = work_dir("controller_config_bad");
  std::ofstream(bad_dir / "bad.yaml") << "momentum: {ankle_first_blend: -1}\n";
  auto [bcode, bout] = run_command(
      {bin("poise"), "envelope", "pushes", "--controller-config", (bad_dir / "bad.yaml").string(),
       "-o", bad_dir.string()},
      60s);
  EXPECT_EQ(bcode, 2) << bout;
  EXPECT_NE(bout.find("momentum.ankle_first_blend"), std::string::npos) << bout;
  EXPECT_FALSE(fs::exists(bad_dir / "runs.csv"));
}

TEST(Envelope, BadInputIsRefusedNamingTheProblem) {
  const fs::path dir = work_dir("bad");
  std::ofstream(dir / "nopush.yaml")
      << "name: nopush\nrobot: {config: "
      << (fs::path(POISE_SOURCE_DIR) / "deploy/robots/poise_humanoid/robot.yaml").string()
      << "}\nduration: 1.0\n";
  auto [code, out] = run_command({bin("poise"), "envelope", "pushes", "--supports", "double",
                              "--double", (dir / "nopush.yaml").string(), "-o", dir.string()},
                             60s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("has no push to vary"), std::string::npos) << out;
  auto [code2, out2] = run_command({bin("poise"), "envelope", "sideways"}, 30s);
  EXPECT_NE(code2, 0);
  EXPECT_NE(out2.find("sideways"), std::string::npos) << out2;
}

}  // namespace
