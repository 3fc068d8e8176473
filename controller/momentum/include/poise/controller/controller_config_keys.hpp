#pragma once
// The controller configuration's keys, declared once: the table below drives the YAML parser
// (which keys exist, their types), ControllerConfig::validate() (every key's range) and the
// generated reference controller/momentum/CONFIG.md (key, default, unit, paper equation, one
// line). The defaults are ControllerConfig's member initialisers; the table reads them from a
// default-constructed ControllerConfig.
//
// Adding a key: the field (with its default and the why) in controller_config.hpp, one row in
// controller_config_keys.cpp, then regenerate CONFIG.md (its README says how).

#include <Eigen/Core>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <variant>

#include "poise/controller/controller_config.hpp"

namespace poise::controller {

/// The interval a key's value must lie in (each entry of a vec3); every value is also finite.
struct KeyRange {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;  ///< lo itself excluded
  bool hi_open = false;  ///< hi itself excluded

  bool contains(double v) const;
  /// "> 0", ">= 0", "in [0, 1)", "finite".
  std::string text() const;
};

/// Where a key's value lives in a ControllerConfig; the alternative is the key's kind: a number,
/// an integer, a list of 3 numbers (world x, y, z) or one of the contact optimiser's enums.
using ConfigField =
    std::variant<double& (*)(ControllerConfig&), int& (*)(ControllerConfig&),
                 Eigen::Vector3d& (*)(ControllerConfig&), contact::Priority& (*)(ControllerConfig&),
                 contact::TorsionLimit& (*)(ControllerConfig&)>;

struct ConfigKey {
  std::string_view key;       ///< dotted YAML path: "dt", "momentum.gamma11"
  ConfigField field;          ///< the value in a ControllerConfig
  std::string_view unit;      ///< "1/s", "Hz", "" (none)
  std::string_view equation;  ///< the paper's: "(11)", "Sec. 4.2"; "—": not in the paper
  KeyRange range;             ///< numbers only; enums are checked by their parser
  /// What the range's special values mean ("0: off"), may be ""; an enum's: its names.
  std::string_view note;
  std::string_view doc;  ///< one line
};

/// Every key, in the order of the reference (the sections of balance_controller.yaml).
std::span<const ConfigKey> controller_config_keys();

/// A number, an integer or a vec3 (checked against `range`); else an enum.
bool config_key_is_numeric(const ConfigKey& key);

/// The key named `dotted`, or nullptr.
const ConfigKey* find_controller_config_key(std::string_view dotted);

/// A key's value in `c` as YAML text: "0.001", "[5, 5, 5]", "friction-coupled".
std::string controller_config_value_text(const ConfigKey& key, const ControllerConfig& c);

/// The reference page controller/momentum/CONFIG.md: one Markdown table row per key.
std::string controller_config_markdown();

}  // namespace poise::controller
