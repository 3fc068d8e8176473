#pragma once
// poise-bench-loop --realtime (realtime_bench.cpp): the issue #19 real-time targets, measured.

#include <filesystem>

namespace poise::bench {

/// Runs the real-time benchmark with poise-bench-loop's arguments (see --realtime --help);
/// `bin_dir` holds poise-launch and the nodes. Returns the process exit code; throws
/// std::invalid_argument on a bad option.
int run_realtime_bench(int argc, char** argv, const std::filesystem::path& bin_dir);

}  // namespace poise::bench
