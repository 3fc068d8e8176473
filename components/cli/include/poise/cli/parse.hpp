#pragma once
// One exit status for a usage error on every Poise command line (the `poise` verbs and the
// nodes): 2, as POSIX tools and the ros2 CLI use; 0 for --help. CLI11's own codes (105 for a
// failed check, 106 for a missing argument, ...) are not exit statuses a script can rely on.
//
//   CLI::App app{"..."};
//   POISE_CLI_PARSE(app, argc, argv);   // instead of CLI11_PARSE

#include <CLI/CLI.hpp>

namespace poise::cli {

/// Prints the error (or the help) as CLI11 does and returns the exit status: 0 or 2.
template <class App>
int usage_exit(App& app, const CLI::ParseError& e) {
  return app.exit(e) == 0 ? 0 : 2;
}

}  // namespace poise::cli

#define POISE_CLI_PARSE(app, argc, argv)                      \
  do {                                                        \
    try {                                                     \
      (app).parse((argc), (argv));                            \
    } catch (const CLI::ParseError& poise_cli_error_) {       \
      return ::poise::cli::usage_exit((app), poise_cli_error_); \
    }                                                         \
  } while (false)
