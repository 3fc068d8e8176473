// `poise plot FILE`, run as a child process on a small synthetic push recording (1 kHz state,
// ground truth, contact problem and solution, robot description, one push): PNG and SVG are
// written, the PNG has its signature, the SVG is well-formed XML text carrying the panel titles.
// Missing topics draw what exists; bad input fails with a message.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "plot_test_support.hpp"

namespace poise::plot_test {
namespace {

bool have_gnuplot() {
  return std::system("command -v gnuplot > /dev/null 2>&1") == 0;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// "" when `text` is well-formed XML as far as tags go (every element closed in order), else why.
std::string xml_problem(const std::string& text) {
  std::vector<std::string> open;
  std::size_t i = 0;
  while ((i = text.find('<', i)) != std::string::npos) {
    if (text.compare(i, 4, "<!--") == 0) {
      i = text.find("-->", i);
      if (i == std::string::npos) return "unterminated comment";
      continue;
    }
    if (text.compare(i, 9, "<![CDATA[") == 0) {
      i = text.find("]]>", i);
      if (i == std::string::npos) return "unterminated CDATA";
      continue;
    }
    const std::size_t end = text.find('>', i);
    if (end == std::string::npos) return "unterminated tag at " + std::to_string(i);
    const std::string tag = text.substr(i + 1, end - i - 1);
    i = end + 1;
    if (tag.empty()) return "empty tag";
    if (tag[0] == '?' || tag[0] == '!') continue;  // declaration, DOCTYPE
    if (tag.back() == '/') continue;               // self-closing
    if (tag[0] == '/') {
      const std::string name = tag.substr(1, tag.find_first_of(" \t\r\n", 1) - 1);
      if (open.empty() || open.back() != name)
        return "</" + name + "> closes <" + (open.empty() ? "" : open.back()) + ">";
      open.pop_back();
      continue;
    }
    open.push_back(tag.substr(0, tag.find_first_of(" \t\r\n")));
  }
  if (!open.empty()) return "<" + open.back() + "> never closed";
  return {};
}

constexpr std::uint64_t kLog0 = 1'760'000'000'000'000'000ULL;

/// A 2 s double-support push run at 1 kHz: push of 120 N for 0.1 s at robot time 1.0 s.
void write_push_recording(const std::string& path, bool only_state) {
  Recording rec(path);
  const double mass = 60.0;
  if (!only_state) {
    msg::RobotDescription d;
    d.robot_name("synthetic");
    for (auto& f : d.feet()) {
      f.x_min(-0.08);
      f.x_max(0.16);
      f.y_min(-0.05);
      f.y_max(0.05);
      f.safety_margin(0.005);
    }
    d.control_period_s(0.001);
    rec.write(d, kLog0, kLog0);
    msg::Disturbance push;
    push.kind(msg::DISTURBANCE_PUSH);
    push.link("pelvis");
    push.force_W({120.0, 0.0, 0.0});
    push.start_time_s(1.0);
    push.duration_s(0.1);
    rec.write(push, kLog0 + 1000, kLog0 + 1000);
  }
  for (int k = 0; k < 2000; ++k) {
    const double t = 0.01 + 0.001 * k;
    const std::int64_t stamp = std::llround(t * 1e9);
    const std::uint64_t log = kLog0 + 2'000'000 + static_cast<std::uint64_t>(k) * 1'000'000;
    const double after = t > 1.0 ? t - 1.0 : 0.0;
    const double bump = 0.04 * after * std::exp(-after / 0.3) / 0.3;  // CoM moves forward, returns
    msg::State s;
    s.header().tick(static_cast<std::uint64_t>(k));
    s.header().stamp_ns(stamp);
    s.joint_count(30);
    s.com_W({0.02 + bump, 0.001, 0.82 - 0.1 * bump});
    rec.write(s, log, log);
    if (only_state) continue;
    msg::GroundTruth g;
    g.header() = s.header();
    g.com_W({0.021 + bump, 0.0, 0.82 - 0.1 * bump});
    for (auto& f : g.feet())
      f.wrench_W().force({0.0, 0.0, mass * 9.81 / 2 + 40 * bump});
    rec.write(g, log + 10, log + 10);
    msg::ContactProblem p;
    p.header() = s.header();
    p.mass(mass);
    const double l = t > 1.0 && t < 1.1 ? -120.0 : -300.0 * bump;
    p.l_dot_desired_W({l, 0.0, 0.0});
    p.k_dot_desired_W({0.0, 30.0 * bump, 0.0});
    rec.write(p, log + 20, log + 20);
    msg::ContactSolution c;
    c.header() = s.header();
    c.l_dot_admissible_W({l, 0.0, 0.0});
    c.k_dot_admissible_W({0.0, 30.0 * bump > 5 ? 5.0 : 30.0 * bump, 0.0});
    for (auto& f : c.feet()) {
      f.wrench_at_ankle_W().force({l / 2, 0.0, mass * 9.81 / 2 + 40 * bump});
      f.cop_F({std::min(0.155, 0.02 + 2 * bump), 0.0});
    }
    rec.write(c, log + 30, log + 30);
  }
  rec.close();
}

class PlotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_gnuplot()) GTEST_SKIP() << "gnuplot is not installed (Debian: gnuplot-nox)";
  }
  ScratchDir dir;
};

TEST_F(PlotTest, PushRunGivesPngAndSvgWithThePanels) {
  const std::string file = dir / "push.mcap";
  write_push_recording(file, false);
  const std::string out = dir / "sheets";
  const PoiseRun r = run_poise({"plot", file, "-o", out, "--title", "Synthetic forward push"});
  ASSERT_EQ(r.code, 0) << r.output;

  const std::string png = read_file(out + "/push_balance.png");
  ASSERT_GT(png.size(), 20'000u) << r.output;
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));

  const std::string svg = read_file(out + "/push_balance.svg");
  ASSERT_GT(svg.size(), 20'000u);
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_EQ(xml_problem(svg), "");
  for (const char* title :
       {"Synthetic forward push", "(a) CoM x, y", "(b) CoM z", "(c) Linear momentum rate",
        "(d) Angular momentum rate", "(e) Vertical ground reaction force",
        "(f) Admissible CoP x in the foot frame", "(g) Admissible CoP y in the foot frame",
        "safe region", "robot time [s] (header.stamp_ns)",
        "Push: 1.000 s to 1.100 s robot time (0.100 s), from poise/disturbance"}) {
    EXPECT_NE(svg.find(title), std::string::npos) << "missing in the SVG: " << title;
  }
  EXPECT_EQ(r.output.find("not in the recording"), std::string::npos) << r.output;
}

TEST_F(PlotTest, MissingTopicsDrawWhatExistsAndSaySo) {
  const std::string file = dir / "state_only.mcap";
  write_push_recording(file, true);
  const PoiseRun r = run_poise({"plot", file, "-o", dir / "sheets", "--push", "1.0,0.1"});
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("poise/contact_solution is not in the recording"), std::string::npos)
      << r.output;
  const std::string png = read_file(dir / "sheets/state_only_balance.png");
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const std::string svg = read_file(dir / "sheets/state_only_balance.svg");
  EXPECT_EQ(xml_problem(svg), "");
  EXPECT_NE(svg.find("from --push"), std::string::npos);
  EXPECT_NE(svg.find("no data: not in the recording: poise/contact_problem"), std::string::npos);
}

TEST_F(PlotTest, NotMcapIsAnError) {
  const std::string file = dir / "junk.mcap";
  std::ofstream(file) << "not a recording";
  const PoiseRun r = run_poise({"plot", file, "-o", dir / "sheets"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("not an MCAP file"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "sheets/junk_balance.png"));
}

TEST_F(PlotTest, MissingGnuplotIsSaidClearly) {
  const std::string file = dir / "push.mcap";
  write_push_recording(file, true);
  const PoiseRun r = run_poise({"plot", file, "--gnuplot", dir / "no-such-gnuplot"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("not found"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("gnuplot-nox"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace poise::plot_test
