#include "poise/dds/log.hpp"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>

namespace poise::dds {
namespace {

std::mutex g_name_mutex;
char g_name[64] = "poise";

LogLevel level_from_env() {
  const char* v = std::getenv("POISE_LOG_LEVEL");
  if (!v) return LogLevel::info;
  if (!std::strcmp(v, "debug")) return LogLevel::debug;
  if (!std::strcmp(v, "warn")) return LogLevel::warn;
  if (!std::strcmp(v, "error")) return LogLevel::error;
  return LogLevel::info;
}

std::atomic<LogLevel> g_level{level_from_env()};

const char* level_name(LogLevel l) {
  switch (l) {
    case LogLevel::debug:
      return "debug";
    case LogLevel::info:
      return "info";
    case LogLevel::warn:
      return "warn";
    case LogLevel::error:
      return "error";
  }
  return "?";
}

}  // namespace

void set_log_name(std::string_view name) {
  std::lock_guard lock(g_name_mutex);
  const std::size_t n = std::min(name.size(), sizeof(g_name) - 1);
  std::memcpy(g_name, name.data(), n);
  g_name[n] = '\0';
}

void set_log_level(LogLevel level) {
  g_level.store(level);
}

void log(LogLevel level, const char* format, ...) {
  if (level < g_level.load(std::memory_order_relaxed)) return;
  char line[1024];
  int n;
  {
    std::lock_guard lock(g_name_mutex);
    n = std::snprintf(line, sizeof(line), "[%s] %s: ", g_name, level_name(level));
  }
  if (n < 0) return;
  va_list args;
  va_start(args, format);
  const int m =
      std::vsnprintf(line + n, sizeof(line) - static_cast<std::size_t>(n) - 1, format, args);
  va_end(args);
  std::size_t len = static_cast<std::size_t>(n) + (m > 0 ? static_cast<std::size_t>(m) : 0);
  len = std::min(len, sizeof(line) - 2);
  line[len++] = '\n';
  [[maybe_unused]] const ssize_t w = ::write(STDERR_FILENO, line, len);
}

}  // namespace poise::dds
