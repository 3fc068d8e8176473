// `poise export FILE --csv [-o DIR] [--topics T...]`: argument parsing and the report printed
// around export_csv().
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "export_problems.hpp"
#include "poise/plot/cli.hpp"
#include "poise/plot/csv_export.hpp"
#include "poise/cli/parse.hpp"

namespace poise::plot {

int print_export_problems(const char* verb, const std::string& file, const ExportReport& report) {
  int code = 0;
  for (const auto& s : report.skipped) {
    std::fprintf(stderr, "poise %s: skipped %s (%llu messages, schema '%s'): %s\n", verb,
                 s.topic.c_str(), static_cast<unsigned long long>(s.messages),
                 s.schema_name.c_str(), s.reason.c_str());
  }
  for (const auto& t : report.topics) {
    if (t.decode_failures) {
      std::fprintf(stderr,
                   "poise %s: %s: %llu message(s) do not decode as %s and are not exported "
                   "(first: %s)\n",
                   verb, t.topic.c_str(), static_cast<unsigned long long>(t.decode_failures),
                   t.type_name.c_str(), t.first_failure.c_str());
      code = 1;
    }
    if (t.invalid) {
      std::fprintf(stderr,
                   "poise %s: warning: %s: %llu message(s) fail validation, exported as recorded "
                   "(first: %s)\n",
                   verb, t.topic.c_str(), static_cast<unsigned long long>(t.invalid),
                   t.first_invalid.c_str());
    }
  }
  if (!report.scan.ok()) {
    std::fprintf(stderr, "poise %s: %s is damaged: %s; exported what comes before\n", verb,
                 file.c_str(), report.scan.error.c_str());
    code = 1;
  } else if (!report.scan.complete) {
    std::fprintf(stderr,
                 "poise %s: %s is incomplete (cut short: %s); exported the %llu messages it "
                 "holds\n",
                 verb, file.c_str(), report.scan.truncation.c_str(),
                 static_cast<unsigned long long>(report.scan.messages));
    code = 1;
  }
  return code;
}

int export_main(int argc, char** argv) {
  std::string file, output_dir;
  bool csv = false;
  bool quiet = false;
  std::vector<std::string> topics;
  CLI::App app{
      "Export the Poise topics of an MCAP recording (`poise record`, `poise run --record`) to CSV: "
      "one file per topic, DIR/<topic with / replaced by _>.csv, one row per message.\n"
      "Columns: log_time_s (MCAP log time, seconds since the earliest message of the file), "
      "publish_time_s (the writer's time stamp, same origin; empty if not recorded), then every "
      "member of the type in IDL order, named by its path: header.tick, header.stamp_ns, com_W[0], "
      "feet[1].cop_F[0], ... Arrays bounded by a length field (q by joint_count) get as many "
      "columns as the largest length in the file; cells past a message's own length are empty. "
      "Numbers in shortest round-trip form, booleans 1/0, enums by name, strings double-quoted "
      "(RFC 4180).\n"
      "Channels that are not Poise topic types are skipped (and listed). Messages that do not "
      "decode are counted and reported per topic, with the reason. A file cut short (crash) is "
      "exported up to its last complete record.\n"
      "Exit status: 0 done; 1 written, but messages did not decode or the file is incomplete or "
      "damaged; 2 nothing written (not MCAP, unknown topic, bad arguments, output not writable)."};
  app.name("poise export");
  app.add_option("file", file, "MCAP file")->required();
  app.add_flag("--csv", csv, "write CSV (the one format so far; required)");
  app.add_option("-o,--output", output_dir,
                 "directory for one CSV file per topic (default: <file stem>_csv next to the "
                 "file)");
  app.add_option("--topics", topics, "export only these topics, e.g. poise/state poise/sensors");
  app.add_flag("-q,--quiet", quiet, "print nothing but problems");
  POISE_CLI_PARSE(app, argc, argv);
  if (!csv) {
    std::fprintf(stderr, "poise export: choose the output format: --csv\n");
    return 2;
  }
  if (!std::filesystem::exists(file)) {
    std::fprintf(stderr, "poise export: %s: no such file\n", file.c_str());
    return 2;
  }
  if (output_dir.empty()) {
    const std::filesystem::path p(file);
    output_dir = (p.parent_path() / (p.stem().string() + "_csv")).string();
  }

  ExportOptions options;
  options.output_dir = output_dir;
  options.topics = topics;
  options.progress = quiet ? nullptr : stderr;
  const ExportReport report = export_csv(file, options);
  if (!report.scan.is_mcap) {
    std::fprintf(stderr, "poise export: %s: not an MCAP file (%s)\n", file.c_str(),
                 report.error.c_str());
    return 2;
  }
  if (!report.error.empty() && report.topics.empty()) {
    std::fprintf(stderr, "poise export: %s: %s\n", file.c_str(), report.error.c_str());
    return 2;
  }
  if (!quiet) {
    for (const auto& t : report.topics) {
      std::printf("%-26s %8llu rows %5zu columns  %s\n", t.topic.c_str(),
                  static_cast<unsigned long long>(t.rows), t.columns.size(), t.csv_path.c_str());
    }
    if (report.topics.empty())
      std::printf("no Poise topic in %s: nothing exported\n", file.c_str());
  }
  int code = print_export_problems("export", file, report);
  if (!report.error.empty()) {
    std::fprintf(stderr, "poise export: %s\n", report.error.c_str());
    code = 2;
  }
  return code;
}

}  // namespace poise::plot
