#pragma once
// What `poise export` and `poise plot` print about an export's problems (skipped channels,
// messages that do not decode, samples failing validation, a file cut short or damaged).

#include <string>

#include "poise/plot/csv_export.hpp"

namespace poise::plot {

/// Prints the problems of `report` to stderr, prefixed "poise <verb>: ". Returns 1 when messages
/// did not decode or the file is incomplete or damaged, else 0.
int print_export_problems(const char* verb, const std::string& file, const ExportReport& report);

}  // namespace poise::plot
