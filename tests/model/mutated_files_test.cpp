// Mutated robot files (issue #18 item 4): generated from the shipped humanoid's URDF and
// robot.yaml (and, when built with the scenario parser, a shipped scenario) with a seeded RNG.
// For every mutation the loader must throw an error whose message names the problem (the link,
// joint or key, and the attribute), and never crash or hang. A few positive cases check what the
// loader must accept (mimic on a fixed joint, frozen mimic joints, degenerate fixed leaves).
//
// Built twice (tests/model/CMakeLists.txt): against poise::model with the scenario parser, and,
// without it, together with the model sources under AddressSanitizer + UndefinedBehaviorSanitizer.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "test_util.hpp"

#ifdef POISE_MUTATED_WITH_SCENARIO
#include "poise/scenario/scenario.hpp"
#endif

namespace poise::model {
namespace {

namespace fs = std::filesystem;

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

const std::string& urdf_text() {
  static const std::string t = read_file(test::humanoid_urdf());
  return t;
}
const std::string& yaml_text() {
  static const std::string t = read_file(test::humanoid_config());
  return t;
}

// The message of the exception `f` throws; "(no error)" when it returns.
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

std::string urdf_error(const std::string& xml) {
  return error_of([&] { build_model_from_urdf_string(xml, "'mutant.urdf'"); });
}
std::string config_error(const std::string& yaml, const std::string& xml = urdf_text()) {
  return error_of([&] { parse_robot_config(yaml, xml, "'mutant.yaml'"); });
}

int g_mutations = 0;  // counted over the whole suite, printed at the end

// Asserts that the message names every one of `needles` (and is an error at all).
void expect_names(const std::string& msg, const std::vector<std::string>& needles,
                  const std::string& what) {
  ++g_mutations;
  if (std::getenv("POISE_SHOW_MESSAGES") != nullptr)
    std::printf("--- %s\n%s\n", what.c_str(), msg.c_str());
  EXPECT_NE(msg, "(no error)") << what << ": accepted";
  for (const std::string& n : needles)
    EXPECT_NE(msg.find(n), std::string::npos)
        << what << ": the message does not name '" << n << "':\n"
        << msg;
}

// ---- URDF attribute mutations --------------------------------------------------------------

// The name of the <link> or <joint> element that encloses text offset `pos`.
std::string owner_at(const std::string& xml, std::size_t pos) {
  const std::size_t l = xml.rfind("<link name=\"", pos);
  const std::size_t j = xml.rfind("<joint name=\"", pos);
  const std::size_t at = (l == std::string::npos) ? j
                         : (j == std::string::npos) ? l
                                                    : std::max(l, j);
  const std::size_t q = xml.find('"', at) + 1;
  return xml.substr(q, xml.find('"', q) - q);
}

struct Site {
  std::size_t begin, end;  // the attribute value, without quotes
  std::string owner;       // link or joint name
};

// Every value of attribute `attr` of elements `elem` (regex on the text), with its owner.
// `context` (optional) restricts to elements directly preceded by that text, e.g. inside
// <collision>.
std::vector<Site> sites(const std::string& xml, const std::string& elem, const std::string& attr,
                        const std::string& inside = "") {
  std::vector<Site> out;
  const std::regex re("<" + elem + "\\b[^>]*\\b" + attr + "=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), re); it != std::sregex_iterator();
       ++it) {
    const auto pos = static_cast<std::size_t>(it->position(1));
    if (!inside.empty()) {
      // the nearest opening of a block (<inertial>, <collision>, <visual>, <joint>) must be `inside`
      std::size_t best = 0;
      std::string which;
      for (const char* b : {"<inertial>", "<collision>", "<visual>", "<joint "}) {
        const std::size_t p = xml.rfind(b, pos);
        if (p != std::string::npos && p >= best) {
          best = p;
          which = b;
        }
      }
      if (which != inside) continue;
    }
    out.push_back({pos, pos + static_cast<std::size_t>(it->length(1)), owner_at(xml, pos)});
  }
  return out;
}

std::string replaced(const std::string& xml, const Site& s, const std::string& value) {
  return xml.substr(0, s.begin) + value + xml.substr(s.end);
}

struct AttrCase {
  std::string elem, attr, inside;  // where
  std::string keyword;             // the message must contain it (besides the owner)
  std::vector<std::string> bad;    // values that must be refused
};

const std::vector<std::string> kScalarJunk = {"nan", "NaN", "inf", "-inf", "abc", "", "1e999",
                                              "0x", "1 2"};
const std::vector<std::string> kVectorJunk = {"0 nan 0", "inf 0 0", "0 0 -inf", "a b c",
                                              "0 0",     "",        "1 2 3 4", "0 0 1e999"};

std::vector<AttrCase> attr_cases() {
  auto plus = [](std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  return {
      {"mass", "value", "<inertial>", "mass", plus(kScalarJunk, {"-1", "-1e-9", "1e30", "2e4"})},
      {"inertia", "ixx", "<inertial>", "inertia", plus(kScalarJunk, {"1e300", "-5"})},
      {"inertia", "ixy", "<inertial>", "inertia", plus(kScalarJunk, {"1e300"})},
      {"inertia", "izz", "<inertial>", "inertia", plus(kScalarJunk, {"-1e9"})},
      {"origin", "xyz", "<inertial>", "xyz", plus(kVectorJunk, {"1e300 0 0", "0 0 101"})},
      {"origin", "rpy", "<inertial>", "rpy", kVectorJunk},
      {"origin", "xyz", "<collision>", "xyz", plus(kVectorJunk, {"0 -1e30 0"})},
      {"origin", "rpy", "<collision>", "rpy", kVectorJunk},
      {"origin", "xyz", "<visual>", "xyz", kVectorJunk},
      {"box", "size", "<collision>", "size", plus(kVectorJunk, {"0.1 0 0.1", "-1 1 1", "1e9 1 1"})},
      {"sphere", "radius", "<collision>", "radius", plus(kScalarJunk, {"-0.1", "1e6"})},  // 0: a contact point
      {"cylinder", "radius", "<collision>", "radius", plus(kScalarJunk, {"0", "-0.1"})},
      {"cylinder", "length", "<collision>", "length", plus(kScalarJunk, {"-1", "1e300"})},
      {"origin", "xyz", "<joint ", "xyz", plus(kVectorJunk, {"1e300 0 0", "0 0 -250"})},
      {"origin", "rpy", "<joint ", "rpy", plus(kVectorJunk, {"1e300 0 0"})},
      {"limit", "effort", "<joint ", "effort", plus(kScalarJunk, {"-1", "-1e-3"})},
      {"limit", "velocity", "<joint ", "velocity", plus(kScalarJunk, {"-4"})},
      {"limit", "lower", "<joint ", "lower", plus(kScalarJunk, {"5", "1e300"})},
      {"limit", "upper", "<joint ", "upper", plus(kScalarJunk, {"-5", "-1e300"})},
      {"axis", "xyz", "<joint ", "axis", plus(kVectorJunk, {"0 0 0"})},
      {"dynamics", "damping", "<joint ", "damping", plus(kScalarJunk, {"-1"})},
      {"dynamics", "friction", "<joint ", "friction", plus(kScalarJunk, {"-0.5"})},
  };
}

TEST(MutatedUrdf, EveryBadNumberIsRefusedNamingTheOwnerAndAttribute) {
  std::mt19937 rng(18);
  const std::string& xml = urdf_text();
  int n = 0;
  for (const AttrCase& c : attr_cases()) {
    const std::vector<Site> all = sites(xml, c.elem, c.attr, c.inside);
    ASSERT_FALSE(all.empty()) << c.elem << " " << c.attr << " " << c.inside;
    for (const std::string& bad : c.bad) {
      // a random occurrence for each bad value (seeded)
      const Site& s = all[std::uniform_int_distribution<std::size_t>(0, all.size() - 1)(rng)];
      const std::string what = "<" + c.elem + " " + c.attr + "=\"" + bad + "\"> in " + c.inside +
                               " of '" + s.owner + "'";
      expect_names(urdf_error(replaced(xml, s, bad)), {"'" + s.owner + "'", c.keyword}, what);
      ++n;
    }
  }
  EXPECT_GT(n, 150);
}

// Removing or duplicating an element, one random occurrence each.
TEST(MutatedUrdf, MissingAndDuplicatedElementsAreRefused) {
  std::mt19937 rng(1818);
  const std::string& xml = urdf_text();
  auto pick = [&](const std::regex& re) {
    std::vector<std::pair<std::size_t, std::size_t>> all;
    for (auto it = std::sregex_iterator(xml.begin(), xml.end(), re);
         it != std::sregex_iterator(); ++it)
      all.emplace_back(static_cast<std::size_t>(it->position(0)),
                       static_cast<std::size_t>(it->length(0)));
    EXPECT_FALSE(all.empty());
    return all[std::uniform_int_distribution<std::size_t>(0, all.size() - 1)(rng)];
  };
  struct Case {
    std::string re, keyword;
    bool duplicate;  // else remove
  };
  const std::vector<Case> cases = {
      {"<mass [^>]*/>", "no <mass>", false},
      {"<inertia [^>]*/>", "no <inertia>", false},
      {"<mass [^>]*/>", "more than one <mass>", true},
      {"<inertia [^>]*/>", "more than one <inertia>", true},
      {"<inertial>[\\s\\S]*?</inertial>", "more than one <inertial>", true},
      {"<limit [^>]*/>", "needs a <limit>", false},
      {"<limit [^>]*/>", "more than one <limit>", true},
      {"<axis [^>]*/>", "more than one <axis>", true},
      {"<geometry>[^\\n]*</geometry>", "no <geometry>", false},
      {"<box [^>]*/>", "more than one shape", true},
      {"<link name=\"[^\"]*\">[\\s\\S]*?</link>", "defined twice", true},
      {"<joint name=\"[^\"]*\" type=\"revolute\">[\\s\\S]*?</joint>", "", true},
      {"<parent link=\"[^\"]*\"/>", "parent or child", false},
      {"<child link=\"[^\"]*\"/>", "parent or child", false},
  };
  for (const Case& c : cases)
    for (int rep = 0; rep < 3; ++rep) {
      const auto [pos, len] = pick(std::regex(c.re));
      const std::string owner = owner_at(xml, pos + 1);
      const std::string frag = xml.substr(pos, len);
      const std::string m = c.duplicate ? xml.substr(0, pos) + frag + "\n" + frag + xml.substr(pos)
                                        : xml.substr(0, pos) + xml.substr(pos + len);
      std::vector<std::string> needles = {"'" + owner + "'"};
      if (!c.keyword.empty()) needles.push_back(c.keyword);
      expect_names(urdf_error(m), needles,
                   (c.duplicate ? "duplicated " : "removed ") + c.re + " of '" + owner + "'");
    }
}

TEST(MutatedUrdf, StructuralDefects) {
  const std::string& xml = urdf_text();
  auto sub = [&](const std::string& from, const std::string& to) {
    const std::size_t p = xml.find(from);
    EXPECT_NE(p, std::string::npos) << from;
    return xml.substr(0, p) + to + xml.substr(p + from.size());
  };
  // cycle: torso hangs below the head, which hangs below the torso
  expect_names(urdf_error(sub("<parent link=\"pelvis\"/>\n    <child link=\"torso\"/>",
                              "<parent link=\"head\"/>\n    <child link=\"torso\"/>")),
               {"kinematic loop"}, "cycle torso-head");
  expect_names(urdf_error(sub("<child link=\"torso\"/>", "<child link=\"pelvis\"/>")),
               {"'pelvis'"}, "joint connecting pelvis to itself");
  expect_names(urdf_error(sub("<child link=\"head\"/>", "<child link=\"l_foot\"/>")),
               {"'l_foot'", "child of two joints"}, "a link with two parents");
  expect_names(urdf_error(sub("<child link=\"head\"/>", "<child link=\"no_such\"/>")),
               {"'no_such'", "'neck_fixed'"}, "unknown child link");
  expect_names(urdf_error(sub("type=\"revolute\"", "type=\"planar\"")), {"planar"},
               "planar joint");
  expect_names(urdf_error(sub("type=\"revolute\"", "type=\"spherical\"")), {"spherical"},
               "unknown joint type");
  expect_names(urdf_error(sub("<robot name=\"poise_humanoid\">", "<robot>\n<robot>")), {"XML"},
               "nested robots");
  expect_names(urdf_error(sub("<joint name=\"neck_fixed\" type=\"fixed\">",
                              "<joint name=\"torso_yaw\" type=\"fixed\">")),
               {"'torso_yaw'", "defined twice"}, "duplicated joint name");
  expect_names(urdf_error(sub("<box size=\"0.18 0.26 0.14\"/>", "<cone size=\"1\"/>")),
               {"'pelvis'", "cone"}, "unknown shape");
}

// Masses (issue #51 item 4): a denormal mass on a moving link, a massless floating base and a joint
// that moves nothing are refused by the model as by the simulator (they passed `model info`, and
// robot init wrote kp: -nan for the last); a massless link between joints stays accepted.
TEST(MutatedUrdf, MassesTheSimulatorCannotIntegrateAreRefused) {
  // The mass of `link` set to `value`.
  auto with_mass = [](std::string xml, const std::string& link, const std::string& value) {
    const std::size_t at = xml.find("<link name=\"" + link + "\">");
    EXPECT_NE(at, std::string::npos) << link;
    const std::size_t m = xml.find("<mass value=\"", at) + 13;
    xml.replace(m, xml.find('"', m) - m, value);
    return xml;
  };
  expect_names(urdf_error(with_mass(urdf_text(), "l_forearm", "1e-320")),
               {"'l_forearm'", "at least 1e-06 kg"}, "forearm 1e-320 kg");
  expect_names(urdf_error(with_mass(urdf_text(), "pelvis", "0")),
               {"'pelvis'", "floating base"}, "massless pelvis");
  expect_names(urdf_error(with_mass(with_mass(urdf_text(), "l_forearm", "0"), "l_hand", "0")),
               {"'l_forearm'", "moves no mass"}, "massless forearm and hand");
  EXPECT_EQ(urdf_error(with_mass(urdf_text(), "l_forearm", "0")), "(no error)")
      << "a massless link with a massive link fixed below it is one body with mass";
}

// Several defects in one file: every one reported in one run, one per line.
TEST(MutatedUrdf, EveryDefectReportedInOneRun) {
  std::string xml = urdf_text();
  const std::vector<std::pair<std::string, std::string>> edits = {
      {"<mass value=\"14\"/>", "<mass value=\"nan\"/>"},              // torso
      {"effort=\"100\"", "effort=\"-1\""},                          // torso_yaw
      {"<sphere radius=\"0.085\"/>", "<sphere radius=\"-1\"/>"},    // head
      {"<origin xyz=\"0 0.2 0.34\"", "<origin xyz=\"0 1e300 0.34\""}  // l_shoulder_pitch
  };
  for (const auto& [a, b] : edits) {
    const std::size_t p = xml.find(a);
    ASSERT_NE(p, std::string::npos) << a;
    xml.replace(p, a.size(), b);
  }
  const std::string msg = urdf_error(xml);
  expect_names(msg, {"'torso'", "mass", "'torso_yaw'", "effort", "'head'", "radius",
                     "'l_shoulder_pitch'", "xyz"},
               "four defects");
  EXPECT_GE(std::count(msg.begin(), msg.end(), '\n'), 3) << msg;
}

TEST(MutatedUrdf, SizeDepthTruncationAndBinary) {
  const std::string& xml = urdf_text();
  // 100,000 nested elements (tinyxml recursed until SIGSEGV)
  {
    std::string deep = "<robot name=\"r\"><link name=\"a\"/>";
    for (int i = 0; i < 100000; ++i) deep += "<x>";
    for (int i = 0; i < 100000; ++i) deep += "</x>";
    deep += "</robot>";
    expect_names(urdf_error(deep), {"nested deeper"}, "100000 nested elements");
    // nesting hidden in attribute values and comments does not count
    std::string fine = xml;
    fine.insert(fine.find("<robot"), "<!-- " + std::string(5000, '<') + " -->");
    EXPECT_EQ(urdf_error(fine), "(no error)");
  }
  // a kinematic chain 2000 links deep (recursion of every tree walk)
  {
    std::string chain = "<robot name=\"r\">";
    const std::string in =
        "<inertial><mass value=\"1\"/><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" "
        "iyz=\"0\" izz=\"1\"/></inertial>";
    for (int i = 0; i <= 2000; ++i)
      chain += "<link name=\"l" + std::to_string(i) + "\">" + in + "</link>";
    for (int i = 0; i < 2000; ++i)
      chain += "<joint name=\"j" + std::to_string(i) + "\" type=\"fixed\"><parent link=\"l" +
               std::to_string(i) + "\"/><child link=\"l" + std::to_string(i + 1) + "\"/></joint>";
    chain += "</robot>";
    expect_names(urdf_error(chain), {"'l2000'", "below the root"}, "2000-deep chain");
  }
  // too many links
  {
    std::string many = "<robot name=\"r\">";
    for (int i = 0; i < 10001; ++i) many += "<link name=\"l" + std::to_string(i) + "\"/>";
    many += "</robot>";
    expect_names(urdf_error(many), {"10001 links"}, "10001 links");
  }
  // truncation at random offsets: always bad XML, never a crash
  std::mt19937 rng(180);
  const std::size_t end = xml.rfind("</robot>");
  for (int i = 0; i < 40; ++i) {
    const std::size_t at = std::uniform_int_distribution<std::size_t>(0, end - 1)(rng);
    expect_names(urdf_error(xml.substr(0, at)), {"URDF 'mutant.urdf'"},
                 "truncated at " + std::to_string(at));
  }
  // random binary files
  for (int i = 0; i < 20; ++i) {
    std::string bin(std::uniform_int_distribution<std::size_t>(1, 4000)(rng), '\0');
    // half of them without NUL bytes (those get past the NUL check into the parsers)
    for (char& ch : bin) ch = static_cast<char>(i % 2 ? (rng() % 255) + 1 : rng() & 0xff);
    expect_names(urdf_error(bin), {"URDF 'mutant.urdf'"}, "random binary " + std::to_string(i));
  }
  // random bytes overwriting a span: an error naming the URDF, or (rarely) still a valid robot
  for (int i = 0; i < 40; ++i) {
    std::string m = xml;
    const std::size_t at = std::uniform_int_distribution<std::size_t>(0, m.size() - 17)(rng);
    for (std::size_t k = 0; k < 16; ++k) m[at + k] = static_cast<char>(rng() & 0xff);
    const std::string msg = urdf_error(m);
    if (msg != "(no error)") {
      EXPECT_NE(msg.find("URDF 'mutant.urdf'"), std::string::npos) << msg;
    }
    ++g_mutations;
  }
  expect_names(urdf_error(""), {"URDF 'mutant.urdf'"}, "empty text");
  expect_names(urdf_error(std::string(xml).insert(100, 1, '\0')), {"NUL"}, "a NUL byte");
}

TEST(MutatedUrdf, FilesEmptyZeroOversizedMissing) {
  const fs::path dir = fs::temp_directory_path() / ("poise_mutated_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path empty = dir / "empty.urdf";
  std::ofstream(empty).close();
  expect_names(error_of([&] { build_model_from_urdf_file(empty); }), {"empty.urdf"}, "empty file");
  const auto t0 = std::chrono::steady_clock::now();
  expect_names(error_of([] { build_model_from_urdf_file("/dev/zero"); }),
               {"/dev/zero", "not a regular file"}, "/dev/zero");
  // A FIFO where a file is expected is refused at once (reading it would wait for a writer).
  const fs::path fifo = dir / "fifo.urdf";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  expect_names(error_of([&] { build_model_from_urdf_file(fifo); }),
               {"fifo.urdf", "not a regular file"}, "a FIFO");
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(10));
  const fs::path big = dir / "big.urdf";
  {
    std::ofstream out(big);
    out << urdf_text();
    out << std::string(kMaxFileBytes, ' ');
  }
  expect_names(error_of([&] { build_model_from_urdf_file(big); }), {"big.urdf", "limit"},
               "17 MB URDF");
  expect_names(error_of([&] { build_model_from_urdf_file(dir); }), {"directory"}, "directory");
  expect_names(error_of([&] { build_model_from_urdf_file(dir / "none.urdf"); }),
               {"none.urdf", "not found"}, "missing file");
  // robot.yaml pointing at /dev/zero, and robot.yaml being /dev/zero
  const fs::path yaml = dir / "robot.yaml";
  std::ofstream(yaml) << std::regex_replace(yaml_text(), std::regex("urdf: [^\\n]*"),
                                            "urdf: /dev/zero");
  expect_names(error_of([&] { load_robot_config(yaml); }), {"/dev/zero", "not a regular file"},
               "urdf: /dev/zero");
  expect_names(error_of([] { load_robot_config("/dev/zero"); }),
               {"/dev/zero", "not a regular file"}, "robot config /dev/zero");
  expect_names(error_of([&] { load_robot_config(fifo); }), {"fifo.urdf", "not a regular file"},
               "robot config FIFO");
  // from files too, URDF and robot.yaml defects come in one message
  const fs::path urdf = dir / "robot.urdf";
  std::string xml = urdf_text();
  xml.replace(xml.find("effort=\"100\""), 13, "effort=\"-1\"");
  std::ofstream(urdf) << xml;
  std::ofstream(yaml) << std::regex_replace(yaml_text(), std::regex("urdf: [^\\n]*"),
                                            "urdf: robot.urdf\ncolour: blue");
  expect_names(error_of([&] { load_robot_config(yaml); }), {"'torso_yaw'", "effort", "colour"},
               "robot.yaml and URDF files with defects");
  fs::remove_all(dir);
}

// ---- positive cases: what the loader must accept ---------------------------------------------

std::string with_hand_parts(const std::string& parts) {
  std::string xml = urdf_text();
  xml.insert(xml.rfind("</robot>"), parts);
  return xml;
}

std::string link_xml(const std::string& name, double mass, const std::string& inertia) {
  std::ostringstream os;
  os << "<link name=\"" << name << "\"><inertial><origin xyz=\"0.01 0 0\"/><mass value=\"" << mass
     << "\"/><inertia " << inertia << "/></inertial></link>\n";
  return os.str();
}

// A joint whose <limit> has effort or velocity 0 (hands' passive joints: Aldebaran Romeo's
// fingers write effort="0" velocity="0") is not actuated: frozen at 0 clamped to its limits,
// like a mimic joint, and said; a negative limit is still refused.
TEST(MutatedUrdf, AJointWithZeroEffortOrVelocityIsFrozenAsNotActuated) {
  const std::string inertia = "ixx=\"1e-6\" ixy=\"0\" ixz=\"0\" iyy=\"1e-6\" iyz=\"0\" izz=\"1e-6\"";
  const std::string parts =
      link_xml("l_finger", 0.02, inertia) + link_xml("r_finger", 0.03, inertia) +
      "<joint name=\"l_finger_joint\" type=\"revolute\"><parent link=\"l_hand\"/>"
      "<child link=\"l_finger\"/><origin xyz=\"0 0 -0.05\"/><axis xyz=\"0 1 0\"/>"
      "<limit lower=\"0.1\" upper=\"1\" effort=\"0\" velocity=\"0\"/></joint>\n"
      "<joint name=\"r_finger_joint\" type=\"revolute\"><parent link=\"r_hand\"/>"
      "<child link=\"r_finger\"/><origin xyz=\"0 0 -0.05\"/><axis xyz=\"0 1 0\"/>"
      "<limit lower=\"-1\" upper=\"1\" effort=\"2\" velocity=\"0\"/></joint>\n";
  const Model ref = build_model_from_urdf_string(urdf_text());
  const Model m = build_model_from_urdf_string(with_hand_parts(parts));
  EXPECT_EQ(m.njoints, ref.njoints);
  ASSERT_EQ(m.frozen_joints.size(), 2u);
  EXPECT_NEAR(m.total_mass, ref.total_mass + 0.05, 1e-12);
  for (const char* name : {"l_finger_joint", "r_finger_joint"}) {
    EXPECT_NE(std::find(m.frozen_joints.begin(), m.frozen_joints.end(), name), m.frozen_joints.end());
    bool said = false;
    for (const std::string& n : m.notes)
      said = said || (n.find(name) != std::string::npos && n.find("not actuated") != std::string::npos);
    EXPECT_TRUE(said) << name;
  }
  // frozen at 0 clamped to [0.1, 1]: the left finger frame turned by 0.1 rad, the right by 0
  const auto turn = [&](const char* link, const char* hand) {
    const Frame& f = m.frames[m.frame_id(link)];
    const Frame& h = m.frames[m.frame_id(hand)];
    EXPECT_EQ(f.body, h.body);
    return Eigen::AngleAxisd((h.X_BF.inverse() * f.X_BF).R).angle();
  };
  EXPECT_NEAR(turn("l_finger", "l_hand"), 0.1, 1e-12);
  EXPECT_NEAR(turn("r_finger", "r_hand"), 0.0, 1e-12);
  std::string bad = with_hand_parts(parts);
  bad.replace(bad.find("effort=\"2\""), 10, "effort=\"-2\"");
  expect_names(urdf_error(bad), {"'r_finger_joint'", "effort", ">= 0"}, "negative effort");
}

// A massless `world` root whose only joint is `floating` to the pelvis (URDFs for Drake, from
// MJCF, for Gazebo): that joint is the floating base; the model is the robot's own, to the
// digit. A floating joint anywhere else, or from a root with mass or geometry, is refused naming
// it.
TEST(MutatedUrdf, AFloatingJointFromAMasslessRootIsTheFloatingBase) {
  const std::string xml = urdf_text();
  const auto pelvis = xml.find("<link name=\"pelvis\"");
  ASSERT_NE(pelvis, std::string::npos);
  auto with_root = [&](const std::string& root_link, const std::string& type) {
    std::string x = xml;
    x.insert(pelvis, root_link + "\n<joint name=\"world_to_pelvis\" type=\"" + type +
                         "\"><parent link=\"world\"/><child link=\"pelvis\"/>"
                         "<origin xyz=\"0.3 -0.2 1.0\" rpy=\"0 0 0.5\"/></joint>\n");
    return x;
  };
  const Model ref = build_model_from_urdf_string(xml);
  for (const std::string& world : {std::string("<link name=\"world\"/>"),
                                   std::string("<link name=\"world\"><inertial><mass value=\"0\"/>"
                                               "<inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" "
                                               "iyz=\"0\" izz=\"0\"/></inertial></link>")}) {
    const Model m = build_model_from_urdf_string(with_root(world, "floating"));
    EXPECT_EQ(m.body_name[0], "pelvis");
    EXPECT_EQ(m.nbodies, ref.nbodies);
    EXPECT_EQ(m.njoints, ref.njoints);
    EXPECT_EQ(m.joint_names, ref.joint_names);
    EXPECT_EQ(m.total_mass, ref.total_mass);
    for (int b = 0; b < m.nbodies; ++b) {
      EXPECT_EQ(m.inertia[b].mass, ref.inertia[b].mass) << b;
      EXPECT_EQ(m.inertia[b].com, ref.inertia[b].com) << b;
    }
  }
  // A root with mass, or with geometry: not a dummy; the floating joint is refused.
  expect_names(urdf_error(with_root("<link name=\"world\"><inertial><mass value=\"1\"/><inertia "
                                    "ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" "
                                    "izz=\"0.01\"/></inertial></link>",
                                    "floating")),
               {"'world_to_pelvis'", "floating", "massless root"}, "root with mass");
  expect_names(urdf_error(with_root("<link name=\"world\"><collision><geometry><box size=\"1 1 "
                                    "0.1\"/></geometry></collision></link>",
                                    "floating")),
               {"'world_to_pelvis'", "floating"}, "root with geometry");
  // A floating joint inside the robot.
  std::string inner = xml;
  const std::string wrist = "<joint name=\"l_wrist_fixed\" type=\"fixed\">";
  ASSERT_NE(inner.find(wrist), std::string::npos);
  inner.replace(inner.find(wrist), wrist.size(), "<joint name=\"l_wrist_fixed\" type=\"floating\">");
  expect_names(urdf_error(inner), {"'l_wrist_fixed'", "floating"}, "floating inside");
}

TEST(MutatedUrdf, MimicOnFixedJointIsIgnored) {
  std::string xml = urdf_text();
  const std::string a = "<joint name=\"neck_fixed\" type=\"fixed\">";
  xml.insert(xml.find(a) + a.size(), "<mimic joint=\"no_such_joint\" multiplier=\"nan\"/>");
  const Model ref = build_model_from_urdf_string(urdf_text());
  const Model m = build_model_from_urdf_string(xml);
  EXPECT_EQ(m.njoints, ref.njoints);
  EXPECT_TRUE(m.frozen_joints.empty());
  EXPECT_NEAR(m.total_mass, ref.total_mass, 1e-12);
}

TEST(MutatedUrdf, MovableMimicJointIsFrozenAtItsOffset) {
  const std::string parts =
      link_xml("l_finger", 0.02, "ixx=\"1e-6\" ixy=\"0\" ixz=\"0\" iyy=\"1e-6\" iyz=\"0\" izz=\"1e-6\"") +
      "<joint name=\"l_finger_joint\" type=\"revolute\"><parent link=\"l_hand\"/>"
      "<child link=\"l_finger\"/><origin xyz=\"0 0 -0.05\"/><axis xyz=\"0 1 0\"/>"
      "<limit lower=\"-1\" upper=\"0.2\" effort=\"1\" velocity=\"1\"/>"
      "<mimic joint=\"l_elbow\" multiplier=\"2\" offset=\"0.5\"/></joint>\n";
  const std::string xml = with_hand_parts(parts);
  const Model ref = build_model_from_urdf_string(urdf_text());
  const Model m = build_model_from_urdf_string(xml);
  EXPECT_EQ(m.njoints, ref.njoints);
  ASSERT_EQ(m.frozen_joints, std::vector<std::string>{"l_finger_joint"});
  ASSERT_EQ(m.notes.size(), 1u);
  EXPECT_NE(m.notes[0].find("l_elbow"), std::string::npos) << m.notes[0];
  EXPECT_NEAR(m.total_mass, ref.total_mass + 0.02, 1e-12);
  // frozen at the offset clamped to the upper limit 0.2: the finger frame is rotated by 0.2 rad
  const Frame& f = m.frames[m.frame_id("l_finger")];
  const Frame& h = m.frames[m.frame_id("l_hand")];
  EXPECT_EQ(f.body, h.body);
  const SE3 X = h.X_BF.inverse() * f.X_BF;
  EXPECT_NEAR(Eigen::AngleAxisd(X.R).angle(), 0.2, 1e-12);
  // robot.yaml may still list the frozen joint (groups, gains, posture): ignored
  std::string yaml = yaml_text();
  yaml = std::regex_replace(yaml, std::regex("r_shoulder_roll, r_elbow\\]"),
                            "r_shoulder_roll, r_elbow, l_finger_joint]");
  yaml += "  l_finger_joint: {kp: 1.0, kd: 0.01}\n";
  const RobotConfig cfg = parse_robot_config(yaml, xml, "'mimic'");
  EXPECT_EQ(cfg.upper_body_joints.size(), 7u);
}

TEST(MutatedUrdf, DegenerateFixedLeavesAreMergedBeforeTheyAreChecked) {
  const std::string zero = "ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"";
  const std::string flat = "ixx=\"1e-4\" ixy=\"0\" ixz=\"0\" iyy=\"1e-4\" iyz=\"0\" izz=\"1e-2\"";
  auto fixed = [](const std::string& name, const std::string& parent) {
    return "<joint name=\"" + name + "_joint\" type=\"fixed\"><parent link=\"" + parent +
           "\"/><child link=\"" + name + "\"/><origin xyz=\"0 0 -0.02\"/></joint>\n";
  };
  const std::string parts = link_xml("l_marker", 0.1, zero) + fixed("l_marker", "l_hand") +
                            link_xml("r_plate", 0.05, flat) + fixed("r_plate", "r_hand") +
                            "<link name=\"l_tip\"/>\n" + fixed("l_tip", "l_marker");
  const Model ref = build_model_from_urdf_string(urdf_text());
  const Model m = build_model_from_urdf_string(with_hand_parts(parts));
  EXPECT_EQ(m.njoints, ref.njoints);
  EXPECT_NEAR(m.total_mass, ref.total_mass + 0.15, 1e-12);
  // the same degenerate link on a revolute joint is a body of its own: refused, named
  const std::string moving =
      link_xml("l_blade", 0.05, flat) +
      "<joint name=\"l_blade_joint\" type=\"revolute\"><parent link=\"l_hand\"/><child "
      "link=\"l_blade\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" "
      "velocity=\"1\"/></joint>\n";
  expect_names(urdf_error(with_hand_parts(moving)), {"'l_blade'", "triangle inequality"},
               "triangle-violating body");
  const std::string point = link_xml("l_point", 0.05, zero) +
                            "<joint name=\"l_point_joint\" type=\"revolute\"><parent "
                            "link=\"l_hand\"/><child link=\"l_point\"/><axis xyz=\"0 0 1\"/><limit "
                            "lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\n";
  expect_names(urdf_error(with_hand_parts(point)), {"'l_point'", "not positive definite"},
               "point-mass body");
}

// ---- robot.yaml mutations --------------------------------------------------------------------

// (text in robot.yaml, key path the message must name)
const std::vector<std::pair<std::string, std::string>>& yaml_number_sites() {
  static const std::vector<std::pair<std::string, std::string>> s = {
      {"x_min: -0.08", "feet.right.sole.x_min"},
      {"height: 0.08}", "feet.right.sole.height"},
      {"safety_margin: 0.01", "contact.safety_margin"},
      {"friction_mu: 0.8", "contact.friction_mu"},
      {"torsional_mu: 0.02", "contact.torsional_mu"},
      {"l_knee: 0.556", "nominal_posture.l_knee"},
      {"r_ankle_pitch: -0.3", "nominal_posture.r_ankle_pitch"},
      {"default: {kp: 100.0", "pd_gains.default.kp"},
      {"l_knee: {kp: 300.0, kd: 6.0", "pd_gains.l_knee.kd"},
      {"r_elbow: {kp: 40.0", "pd_gains.r_elbow.kp"},
  };
  return s;
}

// Replaces the last number of `site` inside the text with `value`.
std::string yaml_with(const std::string& yaml, const std::string& site, const std::string& value) {
  const std::size_t p = yaml.find(site);
  EXPECT_NE(p, std::string::npos) << site;
  const std::size_t num = site.find_last_of(' ') + 1;
  std::string s = site.substr(0, num) + value + (site.back() == '}' ? "}" : "");
  return yaml.substr(0, p) + s + yaml.substr(p + site.size());
}

TEST(MutatedRobotYaml, EveryBadNumberIsRefusedNamingTheKey) {
  const std::vector<std::string> junk = {".nan", ".inf", "-.inf", "abc", "1e999", "[1, 2]",
                                         "{a: 1}", "''"};
  for (const auto& [site, key] : yaml_number_sites())
    for (const std::string& v : junk)
      expect_names(config_error(yaml_with(yaml_text(), site, v)), {key},
                   key + " = " + v);
  // values out of range
  const std::vector<std::tuple<std::string, std::string, std::string>> range = {
      {"l_knee: 0.556", "10", "nominal_posture.l_knee"},  // limit [0, 2.4]
      {"l_knee: 0.556", "-1e300", "nominal_posture.l_knee"},
      {"default: {kp: 100.0", "-1", "pd_gains.default.kp"},
      {"l_knee: {kp: 300.0, kd: 6.0", "-6", "pd_gains.l_knee.kd"},
      {"height: 0.08}", "-0.08", "feet.right.sole.height"},
      {"x_min: -0.08", "-1e30", "feet.right.sole"},
      {"friction_mu: 0.8", "0", "contact.friction_mu"},
      {"safety_margin: 0.01", "-0.01", "contact.safety_margin"},
  };
  for (const auto& [site, v, key] : range)
    expect_names(config_error(yaml_with(yaml_text(), site, v)), {key}, key + " = " + v);
}

TEST(MutatedRobotYaml, UnknownAndDuplicatedKeysAreErrors) {
  const std::string& y = yaml_text();
  auto after = [&](const std::string& anchor, const std::string& text) {
    const std::size_t p = y.find(anchor);
    EXPECT_NE(p, std::string::npos) << anchor;
    return y.substr(0, p + anchor.size()) + text + y.substr(p + anchor.size());
  };
  expect_names(config_error(y + "colour: blue\n"), {"colour", "unknown key"}, "top-level key");
  expect_names(config_error(after("contact:\n", "  frictoin_mu: 0.5\n")),
               {"contact.frictoin_mu", "unknown key"}, "contact key");
  expect_names(config_error(after("  right:\n", "    toe: r_toe\n")),
               {"feet.right.toe", "unknown key"}, "foot key");
  expect_names(config_error(std::regex_replace(y, std::regex("height: 0.08\\}"),
                                               "height: 0.08, z: 1}")),
               {"feet.right.sole.z", "unknown key"}, "sole key");
  expect_names(config_error(after("joint_groups:\n", "  arms: [l_elbow]\n")),
               {"joint_groups.arms", "unknown key"}, "group key");
  expect_names(config_error(after("  default: {kp: 100.0, kd: 2.0", ", ki: 1.0")),
               {"pd_gains.default.ki", "unknown key"}, "gain key");
  expect_names(config_error(after("contact:\n", "  friction_mu: 0.1\n")),
               {"contact.friction_mu", "duplicated key"}, "duplicated contact key");
  expect_names(config_error(y + "imu_frame: torso\n"), {"imu_frame", "duplicated key"},
               "duplicated top-level key");
  expect_names(config_error(after("nominal_posture:\n", "  l_knee: 0.3\n")),
               {"nominal_posture.l_knee", "duplicated key"}, "duplicated posture joint");
  expect_names(config_error(after("pd_gains:\n", "  l_knee: {kp: 1.0, kd: 1.0}\n")),
               {"pd_gains.l_knee", "duplicated key"}, "duplicated gains joint");
  for (const char* section : {"imu_frame:", "feet:", "contact:", "joint_groups:",
                              "nominal_posture:", "pd_gains:", "name:"}) {
    const std::string s = std::regex_replace(y, std::regex(std::string("\\n") + section),
                                             std::string("\nx_") + section);
    expect_names(config_error(s), {std::string(section).substr(0, std::string(section).size() - 1),
                                   "missing"},
                 std::string("missing ") + section);
  }
}

TEST(MutatedRobotYaml, ImuOnALinkTheUrdfLacksIsRefusedAtLoad) {
  const std::string y = std::regex_replace(yaml_text(), std::regex("imu_frame: imu_link"),
                                           "imu_frame: imu_lnik");
  expect_names(config_error(y), {"imu_frame", "'imu_lnik'"}, "IMU on an unknown link");
}

TEST(MutatedRobotYaml, EveryDefectReportedInOneRun) {
  std::string y = yaml_with(yaml_text(), "l_knee: 0.556", "10");
  y = yaml_with(y, "r_elbow: {kp: 40.0", "-1");
  y = yaml_with(y, "friction_mu: 0.8", ".nan");
  y += "colour: blue\n";
  y = std::regex_replace(y, std::regex("imu_frame: imu_link"), "imu_frame: imu_lnik");
  const std::string msg = config_error(y);
  expect_names(msg,
               {"nominal_posture.l_knee", "pd_gains.r_elbow.kp", "contact.friction_mu", "colour",
                "'imu_lnik'"},
               "five robot.yaml defects");
  EXPECT_GE(std::count(msg.begin(), msg.end(), '\n'), 4) << msg;
  // a URDF defect and a robot.yaml defect together
  std::string xml = urdf_text();
  xml.replace(xml.find("<mass value=\"14\"/>"), 18, "<mass value=\"inf\"/>");
  expect_names(config_error(yaml_text() + "colour: blue\n", xml), {"'torso'", "mass", "colour"},
               "URDF and robot.yaml defects");
}

TEST(MutatedRobotYaml, TruncationAndBinary) {
  std::mt19937 rng(1800);
  const std::string& y = yaml_text();
  for (int i = 0; i < 30; ++i) {
    const std::size_t at = std::uniform_int_distribution<std::size_t>(0, y.size() - 1)(rng);
    // the file ends early: some required entry is missing or YAML is bad; never accepted unless
    // the cut falls inside the trailing gains (all joints then take the default gains)
    const std::string msg = config_error(y.substr(0, at));
    ++g_mutations;
    if (at < y.find("pd_gains:")) {
      EXPECT_NE(msg, "(no error)") << "truncated at " << at;
      EXPECT_NE(msg.find("robot config"), std::string::npos) << msg;
    }
  }
  for (int i = 0; i < 20; ++i) {
    std::string bin(std::uniform_int_distribution<std::size_t>(1, 2000)(rng), '\0');
    for (char& ch : bin) ch = static_cast<char>(i % 2 ? (rng() % 255) + 1 : rng() & 0xff);
    expect_names(config_error(bin), {"robot config"}, "binary robot.yaml");
  }
  expect_names(config_error(""), {"robot config"}, "empty robot.yaml");
  // aliases that expand exponentially (billion laughs): bounded
  std::string laughs = "a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i < 9; ++i) {
    laughs += "a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 10; ++k) laughs += std::string(k ? ", " : "") + "*a" + std::to_string(i - 1);
    laughs += "]\n";
  }
  const auto t0 = std::chrono::steady_clock::now();
  expect_names(config_error(yaml_text() + laughs), {"a0"}, "billion laughs");
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(20));
}

#ifdef POISE_MUTATED_WITH_SCENARIO
// ---- scenario mutations (top-level fields, numbers anywhere) ---------------------------------

const std::string& scenario_text() {
  static const std::string t =
      read_file(std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/forward_push_double_support.yaml");
  return t;
}
std::string scenario_error(const std::string& text) {
  return error_of([&] {
    scenario::parse_scenario(text, std::string(POISE_SOURCE_DIR) + "/deploy/scenarios", "mutant");
  });
}

TEST(MutatedScenario, EveryBadNumberIsRefusedNamingTheKey) {
  ASSERT_EQ(scenario_error(scenario_text()), "(no error)");
  const std::vector<std::pair<std::string, std::string>> sites = {
      {"duration: 4.0", "duration"},
      {"ground: {friction: 0.8", "world.ground.friction"},
      {"point: [0.0", "disturbances.pushes[0].point[0]"},
      {"force: [120.0", "disturbances.pushes[0].force[0]"},
      {"start: 1.0", "disturbances.pushes[0].start"},
      {"duration: 0.1", "disturbances.pushes[0].duration"},
      {"com_error_max_m: 0.15", "success.com_error_max_m"},
      {"foot_slip_max_m: 0.01", "success.foot_slip_max_m"},
      {"recovery_time_s: 2.5", "success.recovery_time_s"},
      {"min_base_height_m: 0.5", "success.min_base_height_m"},
  };
  const std::vector<std::string> junk = {".nan", ".inf", "-.inf", "abc", "1e999", "{a: 1}"};
  for (const auto& [site, key] : sites)
    for (const std::string& v : junk) {
      std::string t = scenario_text();
      const std::size_t p = t.find(site);
      ASSERT_NE(p, std::string::npos) << site;
      const std::size_t num = site.find_last_of(" [") + 1;
      t.replace(p + num, site.size() - num, v);
      expect_names(scenario_error(t), {key}, key + " = " + v);
    }
}

// Physical ranges and duplicated keys (issue #51 item 4): each refused naming the key, none run.
TEST(MutatedScenario, PhysicalRangesAndDuplicatedKeysAreRefused) {
  const std::string& s = scenario_text();
  auto sub = [&](const std::string& a, const std::string& b) {
    const std::size_t p = s.find(a);
    EXPECT_NE(p, std::string::npos) << a;
    return s.substr(0, p) + b + s.substr(p + a.size());
  };
  const std::vector<std::tuple<std::string, std::string, std::vector<std::string>>> cases = {
      {"ground: {friction: 0.8", "gravity: [0, 0, -1e6]\n  ground: {friction: 0.8",
       {"world.gravity", "at most 100"}},
      {"force: [120.0", "force: [1e9", {"disturbances.pushes[0].force", "at most 5000 N"}},
      {"force: [120.0", "force: [1e300", {"disturbances.pushes[0].force"}},
      {"point: [0.0", "point: [1000.0", {"disturbances.pushes[0].point", "within 5 m"}},
      {"start: 1.0", "start: 1e300", {"disturbances.pushes[0].start", "before the end"}},
      {"duration: 0.1", "duration: 1e300", {"disturbances.pushes[0].duration", "at most the run"}},
      {"com_error_max_m: 0.15", "com_error_max_m: -1", {"success.com_error_max_m", ">= 0"}},
      {"foot_slip_max_m: 0.01", "foot_slip_max_m: -0.01", {"success.foot_slip_max_m", ">= 0"}},
      {"duration: 4.0", "duration: 1e-9", {"duration", "one control period"}},
      {"duration: 4.0", "duration: 4.0\nduration: 8.0", {"duration", "duplicated key"}},
      {"com_error_max_m: 0.15", "com_error_max_m: 0.15\n  com_error_max_m: 0.5",
       {"success.com_error_max_m", "duplicated key"}},
  };
  for (const auto& [from, to, names] : cases) expect_names(scenario_error(sub(from, to)), names, to);
}

TEST(MutatedScenario, TopLevelFields) {
  const std::string& s = scenario_text();
  auto sub = [&](const std::string& a, const std::string& b) {
    const std::size_t p = s.find(a);
    EXPECT_NE(p, std::string::npos) << a;
    return s.substr(0, p) + b + s.substr(p + a.size());
  };
  expect_names(scenario_error(sub("duration: 4.0", "duration: 1e300")), {"duration", "1e6"},
               "duration 1e300");
  expect_names(scenario_error(sub("duration: 4.0", "duration: 4.0\nsolver: {iterations: 1e12}")),
               {"solver.iterations", "integer in [1,"}, "iterations 1e12");
  expect_names(scenario_error(sub("duration: 4.0", "duration: 4.0\nsolver: {iterations: 2.5}")),
               {"solver.iterations"}, "iterations 2.5");
  for (const char* name : {"../escape", "a/b", "..", ".", "/etc/passwd", "x y", "", "na\\me",
                           "\"r\\u00e9sultat\""})
    expect_names(scenario_error(sub("name: forward_push_double_support",
                                    std::string("name: ") + (*name ? name : "''"))),
                 {"name"}, std::string("name ") + name);
  expect_names(scenario_error(sub("name: forward_push_double_support",
                                  "name: " + std::string(200, 'a'))),
               {"name"}, "200-character name");
  expect_names(scenario_error(sub("  config: ../robots/poise_humanoid/robot.yaml",
                                  "  config: ../robots/poise_humanoid/robot.yaml\n"
                                  "  damping_mode_kd: -5")),
               {"robot.damping_mode_kd", ">= 0"}, "damping_mode_kd -5");
  expect_names(scenario_error(sub("  posture: nominal", "  posture: nominal\n  base_height: -1")),
               {"initial.base_height"}, "base height -1");
  expect_names(scenario_error(sub("  posture: nominal", "  posture: nominal\n  joints: {l_knee: 10}")),
               {"initial.joints.l_knee", "outside the joint limits"}, "initial knee 10 rad");
  expect_names(scenario_error(s + "colour: blue\n"), {"colour", "unknown key"}, "unknown key");
  expect_names(scenario_error(sub("  min_base_height_m: 0.5",
                                  "  min_base_height_m: 0.5\n  max_damping_ticks: 1e300")),
               {"success.max_damping_ticks"}, "max_damping_ticks 1e300 (an overflowing cast)");
  expect_names(scenario_error("name: x\nduration: 1\n"
                              "robot: {urdf: /dev/zero, feet: {l: {frame: l_foot}}}\n"),
               {"robot.urdf", "not a regular file"}, "scenario robot.urdf /dev/zero");
  // a scenario whose robot.yaml is broken: the robot's errors come through, naming the key
  const fs::path dir = fs::temp_directory_path() / ("poise_mutscen_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "robot.yaml")
      << std::regex_replace(yaml_text(), std::regex("urdf: [^\\n]*"),
                            "urdf: " + test::humanoid_urdf() + "\ncolour: blue");
  expect_names(scenario_error(sub("../robots/poise_humanoid/robot.yaml",
                                  (dir / "robot.yaml").string())),
               {"robot.config", "colour"}, "scenario with a bad robot.yaml");
  expect_names(error_of([] { scenario::load_scenario("/dev/zero"); }),
               {"/dev/zero", "not a regular file"}, "scenario /dev/zero");
  {
    const fs::path fifo = dir / "fifo.yaml";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    expect_names(error_of([&] { scenario::load_scenario(fifo); }),
                 {"fifo.yaml", "not a regular file"}, "scenario FIFO");
    expect_names(scenario_error(sub("  config: ../robots/poise_humanoid/robot.yaml",
                                    "  config: " + fifo.string())),
                 {"robot.config", "not a regular file"}, "robot.config FIFO");
  }
  fs::remove_all(dir);
  // shipped scenarios all still load
  for (const auto& e : fs::directory_iterator(std::string(POISE_SOURCE_DIR) + "/deploy/scenarios")) {
    if (e.path().extension() == ".yaml") {
      EXPECT_EQ(error_of([&] { scenario::load_scenario(e.path()); }), "(no error)") << e.path();
    }
  }
}
#endif

// The shipped robots load unchanged (no false alarm from the new checks).
TEST(MutatedFiles, ShippedRobotsStillLoad) {
  for (const char* r : {"poise_humanoid", "poise_humanoid_32", "poise_humanoid_64"}) {
    const std::string p = std::string(POISE_SOURCE_DIR) + "/deploy/robots/" + r + "/robot.yaml";
    EXPECT_EQ(error_of([&] { load_robot_config(p); }), "(no error)") << r;
  }
  const std::string light =
      std::string(POISE_SOURCE_DIR) + "/tests/data/robots/light_wrist/robot.yaml";
  EXPECT_EQ(error_of([&] { load_robot_config(light); }), "(no error)");
  for (const std::string& u : test::all_urdfs())
    EXPECT_EQ(error_of([&] { build_model_from_urdf_file(u); }), "(no error)") << u;
}

// Prints how many mutations this process checked (ctest runs each test in its own process).
class CountPrinter : public ::testing::Environment {
 public:
  void TearDown() override { std::printf("mutated files checked: %d\n", g_mutations); }
};
const auto* const g_printer = ::testing::AddGlobalTestEnvironment(new CountPrinter);

}  // namespace
}  // namespace poise::model
