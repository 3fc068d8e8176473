// `poise`: the user-facing command-line tool. Dispatches to the verbs the areas register.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "verbs.hpp"

namespace {

void print_usage(std::FILE* out) {
  std::fprintf(out,
               "Usage: poise VERB [ARGS...]\n"
               "Poise: momentum-based humanoid balance control over DDS.\n\n"
               "Verbs:\n");
  for (const auto& verb : poise::cli::verbs()) {
    std::fprintf(out, "  %-10.*s %.*s\n", static_cast<int>(verb.name.size()), verb.name.data(),
                 static_cast<int>(verb.summary.size()), verb.summary.data());
  }
  std::fprintf(out, "\nRun `poise VERB --help` for the options of one verb.\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    print_usage(argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  for (const auto& verb : poise::cli::verbs()) {
    if (verb.name == argv[1]) {
      std::string name = std::string("poise ") + argv[1];
      argv[1] = name.data();
      try {
        return verb.run(argc - 1, argv + 1);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "poise %s: error: %s\n", verb.name.data(), e.what());
        return 1;
      }
    }
  }
  std::fprintf(stderr, "poise: unknown verb '%s'\n\n", argv[1]);
  print_usage(stderr);
  return 2;
}
