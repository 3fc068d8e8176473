#pragma once
// The recording verbs of the `poise` tool: record, info, replay.

#include <cstdio>
#include <string>

#include "poise/record/recorder.hpp"

namespace poise::record {

int record_main(int argc, char** argv);
int info_main(int argc, char** argv);
int replay_main(int argc, char** argv);

/// The per-topic table and totals printed at the end of a recording (also by `poise run --record`).
void print_recording_summary(const RecorderStatus& status, std::FILE* out);

/// Where `poise record -o output` records, by its --if-exists: `output` when none of its files
/// exists (`output`, or when `splitting` any `<stem>_<n><ext>`), or with "overwrite"; with
/// "next" the first `<stem>.<k><ext>` (k = 1, 2, ...) none of whose files exists; with "refuse"
/// (or nothing free) "" and `*error` says why, naming a file in the way.
std::string recording_path(const std::string& output, bool splitting, const std::string& if_exists,
                           std::string* error);

}  // namespace poise::record
