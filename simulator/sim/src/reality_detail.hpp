#pragma once
// Internal: the `reality:` section's parser (world.cpp) and what the simulator does with it
// (simulator.cpp). The public types are in poise/sim/reality.hpp.

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <random>

#include "poise/sim/reality.hpp"
#include "poise/sim/yaml_checks.hpp"
#include "robot_tree.hpp"

namespace poise::sim::detail {

/// Reads a scenario's `reality:` node (a profile name, or a mapping). Throws through `c` naming
/// the key.
RealityConfig parse_reality(const YamlChecks& c, const YAML::Node& node);

/// Checks `config` (ranges, names of links) and applies its mass properties and payloads to
/// `tree`, drawing what it asks to draw. Throws std::runtime_error naming the key or link.
RealityDraw apply_reality(const RealityConfig& config, RobotTree& tree);

/// Standard normal numbers that are the same on every platform and library (std's
/// distributions are not specified bit for bit): Box-Muller on 53-bit uniforms of mt19937_64.
class PortableNormal {
 public:
  explicit PortableNormal(std::uint64_t seed) : rng_(seed) {}
  double uniform() noexcept {  // in (0, 1)
    return (static_cast<double>(rng_() >> 11) + 0.5) * 0x1.0p-53;
  }
  double operator()() noexcept;
  /// N(0, 1) clipped to [-limit, limit].
  double clipped(double limit) noexcept;

 private:
  std::mt19937_64 rng_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace poise::sim::detail
