#pragma once

#include <span>
#include <string_view>

namespace poise::cli {

/// One `poise VERB` sub-command. `run` receives argv with argv[0] = "poise VERB".
struct Verb {
  std::string_view name;
  std::string_view summary;
  int (*run)(int argc, char** argv);
};

/// The verbs registered by the areas (generated at configure time, see CMakeLists.txt).
std::span<const Verb> verbs();

}  // namespace poise::cli
