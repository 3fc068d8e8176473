// The controller configuration's key table (controller_config_keys.hpp) drives the parser, the
// checks and the reference: every shipped file parses to its defaults plus what it says, every
// key round-trips through YAML, and a value out of a key's range is refused naming the key.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "poise/controller/controller_config.hpp"
#include "poise/controller/controller_config_keys.hpp"

namespace poise::controller {
namespace {

namespace fs = std::filesystem;
const fs::path kSource = POISE_SOURCE_DIR;

/// `key: value` as YAML, the dotted key as a section ("momentum.gamma11" -> momentum: {...}).
std::string yaml_of(std::string_view key, const std::string& value) {
  const auto dot = key.find('.');
  if (dot == std::string_view::npos) return std::string(key) + ": " + value + "\n";
  return std::string(key.substr(0, dot)) + ":\n  " + std::string(key.substr(dot + 1)) + ": " +
         value + "\n";
}

std::string error_of(const std::string& yaml) {
  try {
    parse_controller_config(yaml, "test.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "accepted";
}

/// The YAML node of a dotted key in `root` (undefined when absent).
YAML::Node node_of(const YAML::Node& root, std::string_view key) {
  const auto dot = key.find('.');
  if (dot == std::string_view::npos) return root[std::string(key)];
  const YAML::Node section = root[std::string(key.substr(0, dot))];
  return section ? section[std::string(key.substr(dot + 1))]
                 : YAML::Node(YAML::NodeType::Undefined);
}

/// Whether the value written in a file (`given`) is what the parser stored (`parsed`, as text).
bool same_value(const YAML::Node& given, const std::string& parsed) {
  const YAML::Node p = YAML::Load(parsed);
  if (given.IsSequence()) {
    if (!p.IsSequence() || p.size() != given.size()) return false;
    for (std::size_t i = 0; i < given.size(); ++i)
      if (given[i].as<double>() != p[i].as<double>()) return false;
    return true;
  }
  double a = 0.0, b = 0.0;
  if (YAML::convert<double>::decode(given, a) && YAML::convert<double>::decode(p, b)) return a == b;
  return given.as<std::string>() == p.as<std::string>();
}

/// Every key of `parsed`: the file's value where it gives one, else the default.
void expect_defaults_plus_file(const ControllerConfig& parsed, const YAML::Node& root,
                               const std::string& what) {
  const ControllerConfig defaults;
  for (const ConfigKey& k : controller_config_keys()) {
    const std::string got = controller_config_value_text(k, parsed);
    if (const YAML::Node given = node_of(root, k.key))
      EXPECT_TRUE(same_value(given, got)) << what << ": " << k.key << " parsed as " << got;
    else
      EXPECT_EQ(got, controller_config_value_text(k, defaults)) << what << ": " << k.key;
  }
}

TEST(ControllerConfigKeys, ShippedFilesParseToTheirValues) {
  int files = 0;
  for (const auto& e : fs::directory_iterator(kSource / "controller/momentum/config")) {
    if (e.path().extension() != ".yaml") continue;
    ++files;
    const ControllerConfig c = load_controller_config(e.path());
    expect_defaults_plus_file(c, YAML::LoadFile(e.path().string()), e.path().string());
  }
  EXPECT_EQ(files, 3);
  int sections = 0;
  for (const auto& e : fs::directory_iterator(kSource / "deploy/scenarios")) {
    if (e.path().extension() != ".yaml") continue;
    const YAML::Node section = YAML::LoadFile(e.path().string())["controller"];
    if (!section) continue;
    ++sections;
    YAML::Emitter out;
    out << section;
    const ControllerConfig c = parse_controller_config(out.c_str(), e.path().string());
    expect_defaults_plus_file(c, section, e.path().string());
  }
  EXPECT_GE(sections, 3);
  // A few values, written out (the generic check above holds for a parser that ignores a file).
  const ControllerConfig paper =
      load_controller_config(kSource / "controller/momentum/config/paper.yaml");
  EXPECT_EQ(paper.momentum.gamma21, Eigen::Vector3d(40, 40, 20));
  EXPECT_EQ(paper.momentum.gamma22, Eigen::Vector3d(8, 8, 3));
  EXPECT_EQ(paper.momentum.ankle_first_blend, 0.0);
  EXPECT_EQ(paper.feedback.touchdown_follow_fraction, 0.0);
  EXPECT_EQ(paper.foot.kp, 100.0);
  const ControllerConfig ankle =
      load_controller_config(kSource / "controller/momentum/config/ankle_first.yaml");
  EXPECT_EQ(ankle.momentum.upright_pitch_rate, 0.0);
  EXPECT_EQ(ankle.momentum.ankle_first_blend, 0.1);
  const YAML::Node platforms =
      YAML::LoadFile((kSource / "deploy/scenarios/platforms_out_of_phase.yaml").string());
  YAML::Emitter out;
  out << platforms["controller"];
  const ControllerConfig p = parse_controller_config(out.c_str(), "platforms_out_of_phase");
  EXPECT_EQ(p.feedback.support_leg_leak_hz, 300.0);
  EXPECT_EQ(p.feedback.internal_force_leak_hz, 0.0);
  EXPECT_EQ(p.foot.support_acceleration_tau, 0.01);
  EXPECT_EQ(p.acceleration.w_b, 0.95);
}

TEST(ControllerConfigKeys, TheSchemaFileShowsEveryKeyWithItsDefault) {
  const YAML::Node root =
      YAML::LoadFile((kSource / "controller/momentum/config/balance_controller.yaml").string());
  for (const ConfigKey& k : controller_config_keys())
    EXPECT_TRUE(node_of(root, k.key)) << k.key << " is missing from balance_controller.yaml";
}

TEST(ControllerConfigKeys, TheTableIsWellFormed) {
  std::set<std::string_view> seen;
  const ControllerConfig defaults;
  for (const ConfigKey& k : controller_config_keys()) {
    EXPECT_TRUE(seen.insert(k.key).second) << k.key << " twice";
    EXPECT_FALSE(k.equation.empty()) << k.key;
    EXPECT_FALSE(k.doc.empty()) << k.key;
    EXPECT_EQ(k.doc.find('\n'), std::string_view::npos) << k.key << ": one line";
    EXPECT_EQ(find_controller_config_key(k.key), &k);
  }
  EXPECT_EQ(find_controller_config_key("momentum.nothing"), nullptr);
  EXPECT_NO_THROW(defaults.validate());
  const std::string md = controller_config_markdown();
  for (const ConfigKey& k : controller_config_keys())
    EXPECT_NE(md.find("| `" + std::string(k.key) + "` | " +
                      controller_config_value_text(k, defaults) + " |"),
              std::string::npos)
        << k.key << " has no row with its default";
}

/// The names an enum key allows, from its note ("'a' or 'b'").
std::vector<std::string> enum_names(const ConfigKey& k) {
  std::vector<std::string> out;
  const std::string note(k.note);
  const std::regex quoted("'([^']+)'");
  for (std::sregex_iterator it(note.begin(), note.end(), quoted), end; it != end; ++it)
    out.push_back((*it)[1]);
  return out;
}

/// A value of `k` other than its default and inside its range, as YAML text.
std::string other_value(const ConfigKey& k) {
  const ControllerConfig defaults;
  const std::string dflt = controller_config_value_text(k, defaults);
  if (!config_key_is_numeric(k)) {
    for (const std::string& name : enum_names(k))
      if (name != dflt) return name;
    return "";
  }
  const KeyRange& r = k.range;
  double v = std::isfinite(r.lo) && std::isfinite(r.hi) ? 0.5 * (r.lo + r.hi) : 0.0;
  if (!(std::isfinite(r.lo) && std::isfinite(r.hi)))
    v = YAML::Load(dflt).IsSequence() ? 1.0 : YAML::Load(dflt).as<double>() + 1.0;
  if (std::holds_alternative<Eigen::Vector3d& (*)(ControllerConfig&)>(k.field)) {
    std::ostringstream s;
    s << "[" << v + 1 << ", " << v + 2 << ", " << v + 3 << "]";
    return s.str();
  }
  if (std::holds_alternative<int& (*)(ControllerConfig&)>(k.field)) v = std::round(v + 1);
  std::ostringstream s;
  s << v;
  if (s.str() == dflt) s << "5";  // 0.5 -> 0.55
  return s.str();
}

TEST(ControllerConfigKeys, EveryKeyRoundTrips) {
  const ControllerConfig defaults;
  for (const ConfigKey& k : controller_config_keys()) {
    const std::string value = other_value(k);
    ASSERT_FALSE(value.empty()) << k.key;
    const std::string yaml = yaml_of(k.key, value);
    ControllerConfig c;
    ASSERT_NO_THROW(c = parse_controller_config(yaml, "test.yaml")) << yaml;
    const std::string got = controller_config_value_text(k, c);
    EXPECT_NE(got, controller_config_value_text(k, defaults)) << yaml << " left the default";
    EXPECT_TRUE(same_value(YAML::Load(value), got)) << yaml << " parsed as " << got;
    for (const ConfigKey& other : controller_config_keys()) {
      if (&other == &k) continue;
      EXPECT_EQ(controller_config_value_text(other, c),
                controller_config_value_text(other, defaults))
          << yaml << " changed " << other.key;
    }
  }
}

/// Values just outside `r` (none for a key without bounds); whole numbers for an integer key.
std::vector<double> outside(const KeyRange& r, bool integer) {
  const double step = integer ? 1.0 : 0.5;
  std::vector<double> out;
  if (std::isfinite(r.lo)) out.push_back(r.lo_open ? r.lo : r.lo - step);
  if (std::isfinite(r.hi)) out.push_back(r.hi_open ? r.hi : r.hi + step);
  return out;
}

TEST(ControllerConfigKeys, OutOfRangeValuesAreRefusedNamingTheKey) {
  int ranged = 0;
  for (const ConfigKey& k : controller_config_keys()) {
    if (!config_key_is_numeric(k)) continue;
    const bool vec3 = std::holds_alternative<Eigen::Vector3d& (*)(ControllerConfig&)>(k.field);
    const bool integer = std::holds_alternative<int& (*)(ControllerConfig&)>(k.field);
    for (const double bad : outside(k.range, integer)) {
      ++ranged;
      std::ostringstream v;
      if (vec3)
        v << "[1, 1, " << bad << "]";
      else
        v << bad;
      const std::string message = error_of(yaml_of(k.key, v.str()));
      EXPECT_NE(message.find(std::string(k.key) + " must be"), std::string::npos)
          << yaml_of(k.key, v.str()) << " -> " << message;
      EXPECT_NE(message.find("test.yaml"), std::string::npos) << message;
    }
    // A value of the wrong type: the key and what it expects.
    const std::string wrong = error_of(yaml_of(k.key, "abc"));
    EXPECT_NE(wrong.find("test.yaml: " + std::string(k.key) + ": expected a"), std::string::npos)
        << wrong;
  }
  EXPECT_GE(ranged, 40);
  // The checks across keys: cut-offs below half the control rate.
  EXPECT_NE(
      error_of("momentum: {support_acceleration_hz: 500}").find("momentum.support_acceleration_hz"),
      std::string::npos);
  EXPECT_NE(error_of("dt: 0.01\ncom_offset: {bandwidth_hz: 60}").find("com_offset.bandwidth_hz"),
            std::string::npos);
  EXPECT_EQ(error_of("dt: 0.01\ncom_offset: {bandwidth_hz: 40}"), "accepted");
}

TEST(ControllerConfigKeys, UnknownKeysAndBadEnumsAreNamed) {
  std::set<std::string> sections;
  for (const ConfigKey& k : controller_config_keys()) {
    const auto dot = k.key.find('.');
    if (dot != std::string_view::npos) sections.insert(std::string(k.key.substr(0, dot)));
    if (!config_key_is_numeric(k)) {
      const std::string m = error_of(yaml_of(k.key, "nonsense"));
      EXPECT_NE(
          m.find(std::string(k.key) + ": must be " + std::string(k.note) + ", got 'nonsense'"),
          std::string::npos)
          << m;
    }
  }
  EXPECT_EQ(sections.size(), 8u);
  for (const std::string& s : sections) {
    EXPECT_NE(error_of(s + ": {nothing: 1}").find("test.yaml: " + s + ".nothing: unknown key"),
              std::string::npos)
        << s;
    EXPECT_NE(error_of(s + ": 3").find("test.yaml: " + s + ": expected a mapping"),
              std::string::npos)
        << s;
  }
  EXPECT_NE(error_of("nothing: 1").find("test.yaml: nothing: unknown key"), std::string::npos);
  EXPECT_NE(error_of("- 1").find("<root>: expected a mapping"), std::string::npos);
  EXPECT_EQ(error_of(""), "accepted");
}

}  // namespace
}  // namespace poise::controller
