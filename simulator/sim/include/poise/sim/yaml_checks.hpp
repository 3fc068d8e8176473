#pragma once
// Key and value checks of the YAML parsers of the world (world.cpp) and of the scenario format
// (deploy/scenario), so that both name the file and the key of a bad value the same way:
// "<what>: <key>: <problem>". Header-only; include it only in a .cpp that parses YAML.
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

namespace poise::sim {

struct YamlChecks {
  std::string what;  ///< the file (or source) named first in every error

  [[noreturn]] void fail(const std::string& key, const std::string& msg) const {
    throw std::runtime_error(what + ": " + key + ": " + msg);
  }
  /// No mapping anywhere below `n` has a key twice (yaml-cpp keeps both and reads the first, so
  /// the second would be ignored without a word). At most a million nodes are walked.
  void refuse_duplicated_keys(const YAML::Node& n, const std::string& key = "") const {
    std::size_t budget = 1000000;
    walk_for_duplicates(n, key, budget);
  }
  void walk_for_duplicates(const YAML::Node& n, const std::string& key,
                           std::size_t& budget) const {
    if (budget-- == 0) fail(key.empty() ? "(document)" : key, "more than a million nodes");
    if (n.IsMap()) {
      std::vector<std::string> seen;
      for (const auto& kv : n) {
        const std::string k = kv.first.IsScalar() ? kv.first.Scalar() : "?";
        const std::string path = key.empty() ? k : key + "." + k;
        if (std::find(seen.begin(), seen.end(), k) != seen.end())
          fail(path, "duplicated key (the second would be ignored)");
        seen.push_back(k);
        walk_for_duplicates(kv.second, path, budget);
      }
    } else if (n.IsSequence()) {
      std::size_t i = 0;
      for (const auto& e : n)
        walk_for_duplicates(e, key + "[" + std::to_string(i++) + "]", budget);
    }
  }
  /// A mapping whose keys are all in `keys` (absent is fine).
  void allow(const YAML::Node& n, const std::string& key,
             std::initializer_list<const char*> keys) const {
    if (!n) return;
    if (!n.IsMap()) fail(key, "must be a mapping");
    for (const auto& kv : n) {
      const std::string k = kv.first.as<std::string>();
      if (std::none_of(keys.begin(), keys.end(), [&](const char* a) { return k == a; })) {
        std::string list;
        for (const char* a : keys)
          list += std::string(list.empty() ? "" : ", ") + a;
        fail(key.empty() ? k : key + "." + k, "unknown key (allowed: " + list + ")");
      }
    }
  }
  /// A mapping whose keys are all declared under the scenario key `key` ("" the top level) in
  /// the scenario schema (scenario_schema.hpp; defined in scenario_schema.cpp, poise_sim).
  void allow_declared(const YAML::Node& n, const std::string& key) const;
  double num(const YAML::Node& n, const std::string& key) const {
    try {
      if (!n.IsScalar()) fail(key, "must be a number");
      const double v = n.as<double>();
      if (!std::isfinite(v)) fail(key, "must be a finite number");
      return v;
    } catch (const YAML::Exception&) {
      fail(key, "must be a number, got '" + n.Scalar().substr(0, 40) + "'");
    }
  }
  double num(const YAML::Node& parent, const char* k, const std::string& key, double dflt) const {
    return parent[k] ? num(parent[k], key + "." + k) : dflt;
  }
  bool boolean(const YAML::Node& parent, const char* k, const std::string& key, bool dflt) const {
    if (!parent[k]) return dflt;
    try {
      return parent[k].as<bool>();
    } catch (const YAML::Exception&) {
      fail(key + "." + k, "must be true or false");
    }
  }
  std::string str(const YAML::Node& n, const std::string& key) const {
    if (!n.IsScalar()) fail(key, "must be a string");
    return n.as<std::string>();
  }
  Eigen::Vector3d vec3(const YAML::Node& n, const std::string& key) const {
    if (!n.IsSequence() || n.size() != 3) fail(key, "must be a list of 3 numbers");
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i)
      v[i] = num(n[i], key + "[" + std::to_string(i) + "]");
    return v;
  }
};

}  // namespace poise::sim
