// The scenario schema (simulator/sim scenario_schema.cpp, the table behind deploy/scenarios/SCHEMA.md)
// against the parsers that read the files (poise::scenario::parse_scenario and the world's parser).
// For every declared key: its example is accepted; a value of the wrong kind, a value past each of
// its declared bounds and a name outside its choices are refused with an error naming the key; a
// closed bound is accepted. For every declared section: an undeclared key is refused with the
// declared list. So a key the parsers do not read, or read with other bounds than the page says,
// fails here.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "poise/scenario/scenario.hpp"
#include "poise/sim/scenario_schema.hpp"

namespace poise::sim {
namespace {

namespace fs = std::filesystem;
using K = KeyKind;

const fs::path kSource = POISE_SOURCE_DIR;

// A small inline robot (tests/simulator/urdf/biped.urdf) with one push: the document every key is
// set in. Keys whose example names a file of deploy/scenarios are parsed from there.
std::string base_text() {
  return "name: schema\nduration: 1.0\nrobot:\n  urdf: " +
         (kSource / "tests/simulator/urdf/biped.urdf").string() +
         "\n  imu_frame: imu_link\n  feet:\n    left: {frame: l_sole}\n    right: {frame: r_sole}\n"
         "initial:\n  posture: zero\n  joints: {l_knee: 0.6, r_knee: 0.6}\n"
         "disturbances:\n  pushes:\n"
         "    - {link: torso, point: [0, 0, 0.1], force: [50, 0, 0], start: 0.2, duration: 0.05}\n";
}

bool is_leaf(const ScenarioKey& k) {
  return k.kind != K::kSection && k.kind != K::kList && k.kind != K::kNames;
}

/// Sections the schema points elsewhere for (their own tables and tests).
bool external(const ScenarioKey& k) {
  const std::string p(k.path);
  return p.rfind("controller", 0) == 0 || p.rfind("estimator", 0) == 0;
}

std::vector<std::string> segments(std::string_view path) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const auto dot = path.find('.', start);
    out.emplace_back(path.substr(start, dot == std::string_view::npos ? path.npos : dot - start));
    if (dot == std::string_view::npos) return out;
    start = dot + 1;
  }
}

/// The name a test gives a `*` under `parent`.
std::string name_under(const std::string& parent) {
  if (parent == "feet") return "left";
  if (parent == "joints") return "l_knee";
  if (parent == "components") return "simulator";
  return "torso";
}

/// The declared pattern made concrete: `[]` the list's first element, `*` a name.
std::string concrete(std::string_view pattern) {
  std::string out, prev;
  for (const std::string& s : segments(pattern)) {
    std::string seg = s;
    if (seg == "*") seg = name_under(prev);
    if (seg.size() > 2 && seg.compare(seg.size() - 2, 2, "[]") == 0)
      seg = seg.substr(0, seg.size() - 2) + "[0]";
    out += (out.empty() ? "" : ".") + seg;
    prev = s;
  }
  return out;
}

/// Fills the required keys declared under `pattern` that `node` lacks with their examples.
void fill_required(YAML::Node node, const std::string& pattern) {
  for (const ScenarioKey& k : scenario_keys()) {
    const std::string p(k.path);
    const auto dot = p.rfind('.');
    if (!k.required || k.example.empty() || dot == std::string::npos || p.substr(0, dot) != pattern)
      continue;
    const std::string name = p.substr(dot + 1);
    if (!node[name]) node[name] = YAML::Load(std::string(k.example));
  }
}

/// The base document with the value `value` (YAML text) at the declared key `k`.
YAML::Node with_value(const ScenarioKey& k, const std::string& value) {
  YAML::Node root = YAML::Load(base_text());
  const std::string path(k.path);
  if (path == "robot.config") {
    root["robot"] = YAML::Node(YAML::NodeType::Map);
    root.remove("initial");
  }
  if (path == "duration") root.remove("disturbances");
  std::vector<YAML::Node> chain{root};
  std::string pattern, prev;
  const auto segs = segments(path);
  for (std::size_t i = 0; i < segs.size(); ++i) {
    std::string seg = segs[i];
    pattern += (pattern.empty() ? "" : ".") + seg;
    const bool list = seg.size() > 2 && seg.compare(seg.size() - 2, 2, "[]") == 0;
    if (seg == "*") seg = name_under(prev);
    if (list) seg = seg.substr(0, seg.size() - 2);
    prev = segs[i];
    YAML::Node here = chain.back();
    if (i + 1 == segs.size()) {
      here[seg] = YAML::Load(value);
      break;
    }
    if (list) {
      if (!here[seg] || !here[seg].IsSequence()) {
        YAML::Node seq(YAML::NodeType::Sequence);
        seq.push_back(YAML::Node(YAML::NodeType::Map));
        here[seg] = seq;
      }
      chain.push_back(here[seg][0]);
    } else {
      if (!here[seg] || !here[seg].IsMap()) here[seg] = YAML::Node(YAML::NodeType::Map);
      chain.push_back(here[seg]);
    }
    fill_required(chain.back(), pattern);
  }
  return root;
}

/// "" when the document parses, else the error.
std::string parse_error(const ScenarioKey& k, const YAML::Node& doc) {
  const std::string path(k.path);
  const bool from_scenarios = path == "robot.config" || path == "reference";
  YAML::Emitter out;
  out << doc;
  try {
    scenario::parse_scenario(out.c_str(),
                             from_scenarios ? kSource / "deploy/scenarios" : kSource / "tests/simulator",
                             "schema-test");
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

TEST(ScenarioSchema, EveryKeysExampleIsAccepted) {
  int checked = 0;
  for (const ScenarioKey& k : scenario_keys()) {
    if (!is_leaf(k) || external(k)) continue;
    ASSERT_FALSE(k.example.empty()) << k.path << ": no example";
    EXPECT_EQ(parse_error(k, with_value(k, std::string(k.example))), "")
        << k.path << ": " << k.example;
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(ScenarioSchema, AValueOfTheWrongKindIsRefusedNamingTheKey) {
  for (const ScenarioKey& k : scenario_keys()) {
    if (!is_leaf(k) || external(k)) continue;
    const std::string err = parse_error(k, with_value(k, "{not: this}"));
    EXPECT_NE(err.find(concrete(k.path)), std::string::npos)
        << k.path << " took a mapping: '" << err << "'";
  }
}

TEST(ScenarioSchema, EachDeclaredBoundIsTheParsers) {
  int bounds = 0;
  for (const ScenarioKey& k : scenario_keys()) {
    if (external(k) || !(k.kind == K::kNumber || k.kind == K::kWhole || k.kind == K::kRange))
      continue;
    const std::string key = concrete(k.path);
    const bool whole = k.kind == K::kWhole;
    if (std::isfinite(k.lo)) {
      const double below = k.lo_open ? k.lo : (whole ? k.lo - 1 : k.lo - std::max(1e-3, std::abs(k.lo) * 1e-3));
      const std::string err = parse_error(k, with_value(k, number(below)));
      EXPECT_NE(err.find(key), std::string::npos) << k.path << " = " << below << ": '" << err << "'";
      if (!k.lo_open)
        EXPECT_EQ(parse_error(k, with_value(k, number(k.lo))), "") << k.path << " = " << k.lo;
      ++bounds;
    }
    if (std::isfinite(k.hi)) {
      const double above = whole ? k.hi + std::max(1.0, k.hi) : k.hi + std::max(1e-3, std::abs(k.hi) * 1e-3);
      const std::string err = parse_error(k, with_value(k, number(above)));
      EXPECT_NE(err.find(key), std::string::npos) << k.path << " = " << above << ": '" << err << "'";
      EXPECT_EQ(parse_error(k, with_value(k, number(k.hi))), "") << k.path << " = " << k.hi;
      ++bounds;
    }
    if (whole && std::isfinite(k.lo)) {
      const std::string err = parse_error(k, with_value(k, number(k.lo + 0.5)));
      EXPECT_NE(err.find(key), std::string::npos) << k.path << " = lo + 0.5: '" << err << "'";
    }
  }
  EXPECT_GT(bounds, 40);
}

TEST(ScenarioSchema, ANameOutsideTheChoicesIsRefusedNamingTheKey) {
  int checked = 0;
  for (const ScenarioKey& k : scenario_keys()) {
    if (k.kind != K::kChoice || external(k)) continue;
    const std::string err = parse_error(k, with_value(k, "no_such_choice"));
    EXPECT_NE(err.find(concrete(k.path)), std::string::npos) << k.path << ": '" << err << "'";
    ++checked;
  }
  EXPECT_GE(checked, 9);
}

TEST(ScenarioSchema, AnUndeclaredKeyInEverySectionIsRefusedWithTheDeclaredList) {
  int checked = 0;
  for (const ScenarioKey& k : scenario_keys()) {
    if (external(k) || !(k.kind == K::kSection || k.kind == K::kList)) continue;
    const std::string inner = std::string(k.path) + (k.kind == K::kList ? "[]" : "");
    ScenarioKey at = k;
    const std::string bogus_path = inner + ".no_such_key";
    at.path = bogus_path;
    const std::string err = parse_error(at, with_value(at, "1"));
    std::string list;
    for (const std::string& c : scenario_children(concrete(inner)))
      list += (list.empty() ? "" : ", ") + c;
    EXPECT_NE(err.find(concrete(bogus_path) + ": unknown key (allowed: " + list + ")"),
              std::string::npos)
        << k.path << ": '" << err << "'";
    ++checked;
  }
  EXPECT_GE(checked, 20);
}

TEST(ScenarioSchema, TheTopLevelListsEverySection) {
  const std::string err = parse_error(scenario_keys().front(),
                                      YAML::Load(base_text() + "colour: red\n"));
  std::string list;
  for (const std::string& c : scenario_children(""))
    list += (list.empty() ? "" : ", ") + c;
  EXPECT_NE(err.find("colour: unknown key (allowed: " + list + ")"), std::string::npos) << err;
  for (const char* s : {"robot", "world", "initial", "disturbances", "sensors", "solver", "reality",
                        "success", "reference", "contact", "controller", "estimator", "dds"})
    EXPECT_NE(list.find(s), std::string::npos) << s;
}

TEST(ScenarioSchema, TheReadmesExampleScenarioParses) {
  std::ifstream in(kSource / "deploy/scenarios/README.md");
  std::stringstream text;
  text << in.rdbuf();
  const std::string doc = text.str();
  const auto schema = doc.find("## Schema");
  ASSERT_NE(schema, std::string::npos);
  const auto begin = doc.find("```yaml\n", schema);
  ASSERT_NE(begin, std::string::npos);
  const auto end = doc.find("```", begin + 8);
  const std::string yaml = doc.substr(begin + 8, end - begin - 8);
  EXPECT_NO_THROW(scenario::parse_scenario(yaml, kSource / "deploy/scenarios", "README example"));
}

}  // namespace
}  // namespace poise::sim
