#pragma once
// The scenario's `estimator:` section (estimator_section.cpp: its table of keys).

#include <yaml-cpp/yaml.h>

#include "poise/scenario/scenario.hpp"
#include "poise/sim/yaml_checks.hpp"

namespace poise::scenario {

/// Reads the section into `hints`: every key in the table, each value checked against its row;
/// errors name the key (estimator.KEY). `world`: the robot whose feet support_height may name.
void parse_estimator_section(const YAML::Node& section, const sim::YamlChecks& c,
                             const sim::World& world, EstimatorHints& hints);

}  // namespace poise::scenario
