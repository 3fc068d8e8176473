#pragma once
// Minimal logging for nodes and the DDS layer: one line per message on stderr, prefixed with the
// process's node name, e.g. "[estimator] warn: ...". Thread-safe (one write(2) per line).

#include <cstdarg>
#include <string_view>

namespace poise::dds {

enum class LogLevel { debug, info, warn, error };

/// Sets the node name printed in front of every line (default: "poise").
void set_log_name(std::string_view name);
/// Lines below this level are dropped (default: info; POISE_LOG_LEVEL=debug|info|warn|error).
void set_log_level(LogLevel level);

void log(LogLevel level, const char* format, ...) __attribute__((format(printf, 2, 3)));

}  // namespace poise::dds
