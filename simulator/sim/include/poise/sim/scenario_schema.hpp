#pragma once
// The scenario file's keys, declared once: the table in scenario_schema.cpp gives each key's
// kind, unit, default, allowed values and one line of description. The parsers of the world
// (world.cpp, reality.cpp) and of the scenario format (deploy/scenario) take the keys a mapping may
// hold from it, the reference page deploy/scenarios/SCHEMA.md is generated from it, and
// tests/simulator/scenario_schema_test.cpp checks every key against the parsers (a value of the
// wrong kind, out of its range or not among its choices is refused naming the key; the example is
// accepted).
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace poise::sim {

enum class KeyKind {
  kSection,   ///< a mapping of the keys below it
  kList,      ///< a list of mappings; an element's keys are declared under "path[]"
  kNames,     ///< a mapping whose keys are names (of feet, joints, links, components): "path.*"
  kNumber,    ///< a finite number
  kWhole,     ///< a whole number
  kBool,      ///< true or false
  kText,      ///< free text
  kChoice,    ///< one of `choices`
  kVec2,      ///< [x, y]
  kVec3,      ///< [x, y, z]
  kFile,      ///< a file name, relative to the scenario's folder
  kRange,     ///< a number, or [min, max] to draw from
};

struct ScenarioKey {
  /// Dotted path: `world.platforms[].friction` is `friction:` of an element of the list
  /// `world.platforms`; `robot.feet.*.frame` is `frame:` under any foot name.
  std::string_view path;
  KeyKind kind;
  std::string_view unit;     ///< "" none
  std::string_view choices;  ///< kChoice: "a | b | c" (the values the parser accepts)
  /// kNumber, kWhole, kRange: bounds the parser enforces (infinite: none); `lo_open`: > lo.
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool required = false;           ///< must be given (where its section is)
  std::string (*default_text)();   ///< what holds when the key is absent (nullptr: nothing)
  std::string_view note;           ///< further conditions the parser checks, in words
  std::string_view doc;            ///< one line
  std::string_view example;        ///< a valid value, as YAML ("" for sections and lists)
};

/// Every key of a scenario file, in the order of the reference page.
const std::vector<ScenarioKey>& scenario_keys();

/// The declared key `key` names (a concrete key such as "world.platforms[2].friction" or
/// "robot.feet.left.frame"); nullptr when it is not declared.
const ScenarioKey* find_scenario_key(std::string_view key);

/// The names allowed directly under the concrete key `key` ("" the top level), in table order.
std::vector<std::string> scenario_children(std::string_view key);

/// The allowed values of `k` in words ("a number >= 0", "'qp' or 'sequential'", ...).
std::string allowed_text(const ScenarioKey& k);

/// deploy/scenarios/SCHEMA.md's tables (one per top-level section).
std::string scenario_schema_markdown();

}  // namespace poise::sim
