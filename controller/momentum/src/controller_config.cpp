#include "poise/controller/controller_config.hpp"

#include <yaml-cpp/yaml.h>

#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/controller_config_keys.hpp"

#include <cmath>
#include <optional>
#include <string>
#include <type_traits>
#include <variant>

namespace poise::controller {

namespace {

void require(bool ok, const std::string& field, const std::string& what) {
  if (!ok) throw ConfigError("controller config: " + field + " " + what);
}

/// The table's range of `key` (controller_config_keys.cpp) holds for its value in `c`.
void check_range(const ConfigKey& key, ControllerConfig& c) {
  bool vec3 = false;
  const bool ok = std::visit(
      [&](auto get) {
        const auto& v = get(c);
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, double> || std::is_same_v<T, int>) {
          return key.range.contains(static_cast<double>(v));
        } else if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
          vec3 = true;
          return key.range.contains(v[0]) && key.range.contains(v[1]) && key.range.contains(v[2]);
        } else {
          return true;  // an enum: its parser took only its names
        }
      },
      key.field);
  if (ok) return;
  const std::string note = key.note.empty() ? "" : " (" + std::string(key.note) + ")";
  require(false, std::string(key.key),
          "must be " + key.range.text() + note + (vec3 ? " (each entry)" : ""));
}

template <class E>
std::optional<E> parse_enum(std::string_view name) {
  if constexpr (std::is_same_v<E, contact::Priority>)
    return contact::parse_priority(name);
  else
    return contact::parse_torsion_limit(name);
}

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw ConfigError(file_ + ": " + key + ": " + what);
  }

  /// Every key of `root` names a table row or a section of rows; sections are mappings.
  void check_keys(const YAML::Node& root) const {
    if (!root.IsMap()) fail("<root>", "expected a mapping");
    for (const auto& kv : root) {
      const std::string k = kv.first.as<std::string>();
      if (find_controller_config_key(k)) continue;
      if (!is_section(k)) fail(k, "unknown key");
      if (!kv.second.IsMap()) fail(k, "expected a mapping");
      for (const auto& sub : kv.second) {
        const std::string dotted = k + "." + sub.first.as<std::string>();
        if (!find_controller_config_key(dotted)) fail(dotted, "unknown key");
      }
    }
  }

  /// Reads `v` (present) into `key`'s field of `c`, by the field's kind.
  void read(const YAML::Node& v, const ConfigKey& key, ControllerConfig& c) const {
    const std::string name(key.key);
    std::visit([&](auto get) { read_value(v, name, key.note, get(c)); }, key.field);
  }

 private:
  static bool is_section(const std::string& k) {
    for (const ConfigKey& key : controller_config_keys())
      if (key.key.starts_with(k + ".")) return true;
    return false;
  }

  void read_value(const YAML::Node& v, const std::string& key, std::string_view,
                  double& out) const {
    try {
      out = v.as<double>();
    } catch (const YAML::Exception&) {
      fail(key, "expected a number");
    }
    if (!std::isfinite(out)) fail(key, "must be finite");
  }

  void read_value(const YAML::Node& v, const std::string& key, std::string_view, int& out) const {
    try {
      out = v.as<int>();
    } catch (const YAML::Exception&) {
      fail(key, "expected an integer");
    }
  }

  void read_value(const YAML::Node& v, const std::string& key, std::string_view,
                  Eigen::Vector3d& out) const {
    if (!v.IsSequence() || v.size() != 3) fail(key, "expected a list of 3 numbers");
    for (int i = 0; i < 3; ++i) {
      try {
        out[i] = v[i].as<double>();
      } catch (const YAML::Exception&) {
        fail(key, "expected a list of 3 numbers");
      }
    }
  }

  template <class E>
  requires std::is_enum_v<E>
  void read_value(const YAML::Node& v, const std::string& key, std::string_view names,
                  E& out) const {
    const std::string name = v.IsScalar() ? v.as<std::string>() : std::string();
    const auto parsed = parse_enum<E>(name);
    if (!parsed) fail(key, "must be " + std::string(names) + ", got '" + name + "'");
    out = *parsed;
  }

  std::string file_;
};

/// The node of a dotted key ("momentum.gamma11": root["momentum"]["gamma11"]); null if absent.
YAML::Node lookup(const YAML::Node& root, std::string_view dotted) {
  const auto dot = dotted.find('.');
  if (dot == std::string_view::npos) return root[std::string(dotted)];
  const YAML::Node section = root[std::string(dotted.substr(0, dot))];
  if (!section) return YAML::Node(YAML::NodeType::Undefined);
  return section[std::string(dotted.substr(dot + 1))];
}

}  // namespace

void ControllerConfig::validate() const {
  ControllerConfig c = *this;  // the table's accessors take a mutable config
  for (const ConfigKey& key : controller_config_keys())
    check_range(key, c);
  // Across fields: the filters' cut-offs below the Nyquist rate of the control period.
  require(momentum.support_acceleration_hz < 0.5 / dt, "momentum.support_acceleration_hz",
          "must be below half the control rate, 0.5 / dt (0: off)");
  require(com_offset.bandwidth_hz < 0.5 / dt, "com_offset.bandwidth_hz",
          "must be below half the control rate, 0.5 / dt (0: off)");
}

namespace {

ControllerConfig from_yaml(const YAML::Node& root, const std::string& file) {
  ControllerConfig c;
  Reader r(file);
  if (root.IsNull()) return c;
  r.check_keys(root);
  for (const ConfigKey& key : controller_config_keys())
    if (const YAML::Node v = lookup(root, key.key)) r.read(v, key, c);
  try {
    c.validate();
  } catch (const ConfigError& e) {
    throw ConfigError(file + ": " + e.what());
  }
  return c;
}

}  // namespace

ControllerConfig load_controller_config(const std::filesystem::path& path) {
  const std::string file = path.string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    throw ConfigError(file + ": cannot open the controller config");
  } catch (const YAML::Exception& e) {
    throw ConfigError(file + ": YAML error: " + e.what());
  }
  return from_yaml(root, file);
}

ControllerConfig parse_controller_config(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin + ": YAML error: " + e.what());
  }
  return from_yaml(root, origin);
}

}  // namespace poise::controller
