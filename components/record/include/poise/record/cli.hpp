#pragma once
// The recording verbs of the `poise` tool: record, info, replay.

#include <cstdio>

#include "poise/record/recorder.hpp"

namespace poise::record {

int record_main(int argc, char** argv);
int info_main(int argc, char** argv);
int replay_main(int argc, char** argv);

/// The per-topic table and totals printed at the end of a recording (also by `poise run --record`).
void print_recording_summary(const RecorderStatus& status, std::FILE* out);

}  // namespace poise::record
