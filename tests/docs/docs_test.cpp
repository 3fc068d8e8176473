// Every documented command runs: the ```sh blocks of README.md and of every README.md below the
// source tree, one test per README, commands in the order written.
//
// - Working directory: a scratch directory with a symbolic link to each top-level entry of the
//   source tree and `build` -> this build, so `build/bin/poise`, `deploy/...` and `results/...`
//   resolve as in a clone; what commands write stays in the scratch directory.
// - DDS domains: each distinct `--domain N` becomes a domain claimed for this test, and
//   POISE_DDS_DOMAIN is a claimed one for commands that name none (except `poise run`, which
//   then gets a free one of its own: the variable would put it on the live stack's). When a README runs tools that
//   need a live stack on that default domain (`poise topic`, `poise push`, `poise record`), a
//   real-time `poise run standing` runs there in the background.
// - A command ending in `&` runs in the background and is stopped (SIGINT, then SIGKILL by pid)
//   after the README's last command; every other command must exit 0 within 3 minutes.
// - `<!-- docs-test: skip REASON -->` before a block skips it (printed with the reason);
//   `<!-- docs-test: live-stack -->` says the block needs the live stack on the default domain.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <poise/dds/domain_claim.hpp>

#include "child_process.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using poise::testing::ChildProcess;

struct Block {
  int line = 0;                       ///< line of the opening fence
  std::vector<std::string> commands;  ///< continuation lines joined
  std::string skip;                   ///< reason, if marked
  bool live_stack = false;            ///< marked: needs a stack on the default domain
};

std::vector<Block> sh_blocks(const fs::path& readme) {
  std::ifstream in(readme);
  std::vector<Block> out;
  std::string line, pending_skip;
  bool pending_live = false;
  bool in_block = false, is_sh = false;
  Block b;
  std::string joined;
  int n = 0;
  const std::regex skip_re(R"(<!--\s*docs-test:\s*skip\s+(.*?)\s*-->)");
  const std::regex live_re(R"(<!--\s*docs-test:\s*live-stack\s*-->)");
  while (std::getline(in, line)) {
    ++n;
    if (line.rfind("```", 0) == 0) {
      if (!in_block) {
        const std::string lang = line.substr(3);
        in_block = true;
        is_sh = lang == "sh" || lang == "bash" || lang == "shell";
        b = Block{};
        b.line = n;
        b.skip = pending_skip;
        b.live_stack = pending_live;
        pending_skip.clear();
        pending_live = false;
      } else {
        in_block = false;
        if (is_sh) out.push_back(b);
      }
      continue;
    }
    if (!in_block) {
      std::smatch m;
      if (std::regex_search(line, m, skip_re)) {
        pending_skip = m[1];
      } else if (std::regex_search(line, live_re)) {
        pending_live = true;
      } else if (!line.empty()) {
        pending_skip.clear();
        pending_live = false;
      }
      continue;
    }
    if (!is_sh) continue;
    if (!line.empty() && line.back() == '\\') {
      joined += line.substr(0, line.size() - 1) + " ";
      continue;
    }
    joined += line;
    const auto first = joined.find_first_not_of(" \t");
    if (first != std::string::npos && joined[first] != '#') b.commands.push_back(joined);
    joined.clear();
  }
  return out;
}

std::vector<std::string> readmes() {
  std::vector<std::string> out;
  const fs::path src(POISE_SOURCE_DIR);
  for (auto it = fs::recursive_directory_iterator(src); it != fs::recursive_directory_iterator();
       ++it) {
    const std::string name = it->path().filename().string();
    if (it->is_directory() && (name == "build" || name == "node_modules" || name == ".git" ||
                               name == "results" || name.rfind("build", 0) == 0)) {
      it.disable_recursion_pending();
      continue;
    }
    if (name == "README.md") out.push_back(fs::relative(it->path(), src).string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// The command without a trailing `&` (and its comment); `background` says whether it had one.
std::string strip_background(const std::string& cmd, bool& background) {
  static const std::regex bg(R"(^(.*?)\s*&\s*(#.*)?$)");
  std::smatch m;
  background = std::regex_match(cmd, m, bg) && m[1].str().find("&&") != m[1].str().size() - 1;
  return background ? m[1].str() : cmd;
}

class DocCommands : public ::testing::TestWithParam<std::string> {};

TEST_P(DocCommands, EveryCommandRunsAndExitsZero) {
  const fs::path src(POISE_SOURCE_DIR);
  const fs::path readme = src / GetParam();
  std::string slug = GetParam();
  for (auto& c : slug)
    if (c == '/' || c == '.') c = '_';
  const fs::path scratch = fs::path(POISE_BINARY_DIR) / "test_output" / "docs" / slug;
  fs::remove_all(scratch);
  fs::create_directories(scratch);
  for (const auto& e : fs::directory_iterator(src)) {
    const std::string name = e.path().filename().string();
    if (name == "build" || name == "results" || name == ".git" || name.rfind("build", 0) == 0)
      continue;
    fs::create_directory_symlink(e.path(), scratch / name);
  }
  fs::create_directory_symlink(fs::path(POISE_BINARY_DIR), scratch / "build");

  std::map<std::string, int> domains;
  auto domain_for = [&](const std::string& literal) {
    auto it = domains.find(literal);
    if (it == domains.end()) it = domains.emplace(literal, poise::dds::claim_free_domain()).first;
    return it->second;
  };
  const int default_domain = domain_for("<default>");
  const std::vector<std::string> env{"POISE_DDS_DOMAIN=" + std::to_string(default_domain)};

  const std::vector<Block> blocks = sh_blocks(readme);
  std::vector<std::string> commands;
  bool need_live_stack = false;
  for (const auto& b : blocks) {
    if (b.live_stack && b.skip.empty()) need_live_stack = true;
    if (!b.skip.empty()) {
      std::printf("[docs] %s:%d skipped (%s):\n", GetParam().c_str(), b.line, b.skip.c_str());
      for (const auto& c : b.commands)
        std::printf("         %s\n", c.c_str());
      continue;
    }
    commands.insert(commands.end(), b.commands.begin(), b.commands.end());
  }
  if (commands.empty()) GTEST_SKIP() << "no command blocks";

  static const std::regex domain_re(R"(--domain\s+(\d+))");
  static const std::regex needs_stack(R"(\bpoise (topic|push|record)\b)");
  for (const auto& c : commands)
    if (std::regex_search(c, needs_stack) && !std::regex_search(c, domain_re) &&
        c.find("--dds-config") == std::string::npos)
      need_live_stack = true;

  std::vector<std::unique_ptr<ChildProcess>> background;
  auto shell = [&](const std::string& cmd) {
    return std::make_unique<ChildProcess>(
        std::vector<std::string>{"/bin/bash", "-c", "cd '" + scratch.string() + "' && " + cmd}, env,
        false, true);
  };
  if (need_live_stack) {
    // `poise run` claims a free domain unless told: name the default one.
    background.push_back(shell("exec build/bin/poise run standing --realtime --duration 600 "
                               "--domain " + std::to_string(default_domain) +
                               " -o results/live.json --log-dir results/live.logs"));
    ASSERT_TRUE(background.back()->wait_for_output("t=1.0 s", 120s))
        << "the live stack did not start:\n"
        << background.back()->output();
  }
  for (const std::string& written : commands) {
    // Each literal domain of the README becomes a claimed one.
    std::string cmd;
    std::sregex_iterator it(written.begin(), written.end(), domain_re), end;
    std::size_t pos = 0;
    for (; it != end; ++it) {
      cmd += written.substr(pos, static_cast<std::size_t>(it->position()) - pos);
      cmd += "--domain " + std::to_string(domain_for((*it)[1]));
      pos = static_cast<std::size_t>(it->position() + it->length());
    }
    cmd += written.substr(pos);
    bool bg = false;
    cmd = strip_background(cmd, bg);
    std::printf("[docs] %s: %s%s\n", GetParam().c_str(), cmd.c_str(), bg ? "  (background)" : "");
    std::fflush(stdout);
    // `poise run` takes $POISE_DDS_DOMAIN too, which here is the live stack's: a run that names
    // no domain gets one of its own, as in a shell where the variable is not set.
    static const std::regex poise_run(R"(\bpoise run\b)");
    const std::string own_domain =
        std::regex_search(cmd, poise_run) && !std::regex_search(cmd, domain_re)
            ? "unset POISE_DDS_DOMAIN; "
            : "";
    if (bg) {
      background.push_back(shell(own_domain + "exec " + cmd));
      // A background stack is meant to be running when the next command needs it.
      if (cmd.find("poise run") != std::string::npos) {
        EXPECT_TRUE(background.back()->wait_for_output("t=1.0 s", 120s))
            << written << "\n"
            << background.back()->output();
      }
      continue;
    }
    auto p = shell(own_domain + cmd);
    const auto code = p->wait_for(180s);
    EXPECT_TRUE(code.has_value() && *code == 0)
        << GetParam() << ": `" << written << "` "
        << (code ? "exited with " + std::to_string(*code) : std::string("timed out")) << ":\n"
        << p->output();
  }
  for (auto& b : background)
    b->interrupt(10s);
}

INSTANTIATE_TEST_SUITE_P(Readmes, DocCommands, ::testing::ValuesIn(readmes()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string n = info.param;
                           for (auto& c : n)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return n;
                         });

}  // namespace
