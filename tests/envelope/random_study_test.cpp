// `poise envelope random` and `poise envelope merge` as users run them: a study split into shards
// run by GNU parallel (the batch engine a cluster user would put in front: parallel over ssh, or
// a Slurm job array running one shard per task) and merged is the study run whole, file for
// file; a merge of shards that are not one study, or miss runs, is refused naming the problem.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "child_process.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::run_command;

fs::path work_dir(const std::string& name) {
  const fs::path d = fs::path(POISE_BINARY_DIR) / "test_output" / "envelope_random" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& f) {
  std::ifstream in(f);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A shipped scenario shortened to `duration` seconds (the push at 1.0 s stays), paths absolute.
fs::path short_base(const fs::path& dir, const std::string& shipped, double duration) {
  std::string text = slurp(fs::path(POISE_SOURCE_DIR) / "deploy/scenarios" / (shipped + ".yaml"));
  const std::string rel = "config: ../robots/";
  const auto at = text.find(rel);
  EXPECT_NE(at, std::string::npos);
  text.replace(at, rel.size(), "config: " + (fs::path(POISE_SOURCE_DIR) / "deploy/robots").string() + "/");
  const auto d = text.find("\nduration:");
  EXPECT_NE(d, std::string::npos);
  text.replace(d, text.find('\n', d + 1) - d, "\nduration: " + std::to_string(duration));
  const fs::path out = dir / (shipped + ".yaml");
  std::ofstream(out) << text;
  return out;
}

std::vector<std::string> study_args(const fs::path& dir, const fs::path& out) {
  return {bin("poise"), "envelope", "random", "--runs", "9", "--seed", "20261207",
          "--double", short_base(dir, "forward_push_double_support", 1.6).string(),
          "--single", short_base(dir, "lateral_push_single_support", 1.6).string(),
          "--impulse-double", "5,40", "--start-spread", "0.2", "--no-picture", "-q",
          "-o", out.string()};
}

TEST(RandomStudy, ShardsRunByGnuParallelAndMergedAreTheWholeStudy) {
  const fs::path dir = work_dir("sharded");
  // The whole study, two runs at a time.
  std::vector<std::string> whole = study_args(dir, dir / "whole");
  whole.insert(whole.end(), {"--jobs", "2"});
  auto [code, out] = run_command(whole, 240s);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("seed 20261207, 9 of 9 runs"), std::string::npos) << out;

  // Three shards through GNU parallel, one run at a time each, then merged.
  const std::string parallel = "/usr/bin/parallel";
  ASSERT_TRUE(fs::exists(parallel)) << "GNU parallel (Debian package parallel) is needed";
  std::vector<std::string> sharded{parallel, "--will-cite", "--halt", "now,fail=1", "-j", "2"};
  std::vector<std::string> args = study_args(dir, dir / "shard{}");
  sharded.insert(sharded.end(), args.begin(), args.end());
  sharded.insert(sharded.end(), {"--jobs", "1", "--shard", "{}/3", ":::", "0", "1", "2"});
  auto [pcode, pout] = run_command(sharded, 240s);
  ASSERT_EQ(pcode, 0) << pout;
  auto [mcode, mout] = run_command({bin("poise"), "envelope", "merge", (dir / "shard0").string(),
                                    (dir / "shard1").string(), (dir / "shard2").string(),
                                    "--no-picture", "-o", (dir / "merged").string()},
                                   60s);
  ASSERT_EQ(mcode, 0) << mout;

  // File for file: every run with the same draw and the same verdict, the same report.
  for (const char* f : {"runs.csv", "summary.json", "envelope.md"})
    EXPECT_EQ(slurp(dir / "merged" / f), slurp(dir / "whole" / f)) << f;
  const auto summary = nlohmann::json::parse(slurp(dir / "whole" / "summary.json"));
  EXPECT_TRUE(summary["complete"].get<bool>());
  int runs = 0;
  for (const auto& s : summary["supports"]) runs += s["runs"].get<int>();
  EXPECT_EQ(runs, 9);
  // Each shard holds its own third.
  for (int k = 0; k < 3; ++k) {
    const auto shard = nlohmann::json::parse(slurp(dir / ("shard" + std::to_string(k)) / "summary.json"));
    EXPECT_FALSE(shard["complete"].get<bool>());
    int n = 0;
    for (const auto& s : shard["supports"]) n += s["runs"].get<int>();
    EXPECT_EQ(n, 3) << k;
  }

  // A merge that misses a shard names the missing runs; shards of two studies are refused.
  auto [c1, o1] = run_command({bin("poise"), "envelope", "merge", (dir / "shard0").string(),
                               (dir / "shard1").string(), "-o", (dir / "partial").string()},
                              60s);
  EXPECT_EQ(c1, 2) << o1;
  EXPECT_NE(o1.find("3 of 9 runs are in no shard (2, 5, 8)"), std::string::npos) << o1;
  std::vector<std::string> other = study_args(dir, dir / "other");
  other[6] = "1";  // another seed
  other.insert(other.end(), {"--shard", "2/3"});
  ASSERT_EQ(run_command(other, 240s).first, 0);
  auto [c2, o2] = run_command({bin("poise"), "envelope", "merge", (dir / "shard0").string(),
                               (dir / "shard1").string(), (dir / "other").string(), "-o",
                               (dir / "mixed").string()},
                              60s);
  EXPECT_EQ(c2, 2) << o2;
  EXPECT_NE(o2.find("is a shard of another study"), std::string::npos) << o2;
  auto [c3, o3] = run_command({bin("poise"), "envelope", "random", "--shard", "3/3", "--seed", "1"}, 30s);
  EXPECT_EQ(c3, 2) << o3;
  EXPECT_NE(o3.find("--shard '3/3': expected I/N with 0 <= I < N"), std::string::npos) << o3;
  auto [c4, o4] = run_command({bin("poise"), "envelope", "random", "--shard", "0/2"}, 30s);
  EXPECT_EQ(c4, 2) << o4;
  EXPECT_NE(o4.find("--shard needs --seed"), std::string::npos) << o4;
  auto [c5, o5] = run_command({bin("poise"), "envelope", "random", "--seed", "12x"}, 30s);
  EXPECT_EQ(c5, 2) << o5;
  EXPECT_NE(o5.find("--seed '12x': not a whole number"), std::string::npos) << o5;
}

}  // namespace
