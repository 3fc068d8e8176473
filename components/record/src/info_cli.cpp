// `poise info FILE`: what a recording holds.
#include <cstdio>

#include <CLI/CLI.hpp>

#include "poise/record/cli.hpp"
#include "poise/record/recording_info.hpp"
#include "poise/cli/parse.hpp"

namespace poise::record {

int info_main(int argc, char** argv) {
  std::string file;
  bool json = false;
  CLI::App app{
      "What an MCAP recording holds: duration, start and end, per topic the type, message count, "
      "mean rate, longest gap, missing and repeated ticks, size; compression; the recorder's loss "
      "counters. Ticks missing at the start of a per-tick topic (a recorder started after the "
      "stack) are counted against the run's first tick: the one poise-sim puts in "
      "poise/robot_description, or the earliest tick of any per-tick topic in the file. Reads "
      "files cut short by a crash or a full disk too (and says how much they hold).\n"
      "Exit status: 0 complete file, 1 incomplete (cut short) or unreadable, 2 not MCAP."};
  app.name("poise info");
  app.add_option("file", file, "MCAP file")->required();
  app.add_flag("--json", json, "print the report as JSON");
  POISE_CLI_PARSE(app, argc, argv);
  const RecordingInfo info = read_recording_info(file);
  if (!info.scan.is_mcap) {
    std::fprintf(stderr, "poise info: %s: %s\n", file.c_str(),
                 info.scan.error.empty() ? "not an MCAP file" : info.scan.error.c_str());
    return 2;
  }
  if (json) {
    std::printf("%s\n", recording_info_json(info).dump(2).c_str());
  } else {
    std::fputs(format_recording_info(info).c_str(), stdout);
  }
  if (!info.scan.ok()) {
    std::fprintf(stderr, "poise info: %s: %s\n", file.c_str(), info.scan.error.c_str());
    return 1;
  }
  if (!info.scan.complete) {
    std::fprintf(stderr, "poise info: %s is incomplete (%s)\n", file.c_str(),
                 info.scan.truncation.c_str());
    return 1;
  }
  return 0;
}

}  // namespace poise::record
