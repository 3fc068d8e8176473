#pragma once
// Steady-clock helpers for the 1 kHz loops: allocation-free, exception-free.

#include <time.h>

#include <chrono>
#include <cstdint>

namespace poise::node {

/// Monotonic time [ns] (std::chrono::steady_clock = CLOCK_MONOTONIC on Linux).
inline std::int64_t now_ns() noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

/// Sleeps until the absolute monotonic time `t_ns` (returns early only on a signal).
inline void sleep_until_ns(std::int64_t t_ns) noexcept {
  timespec ts{static_cast<time_t>(t_ns / 1'000'000'000), static_cast<long>(t_ns % 1'000'000'000)};
  // EINTR (a signal, e.g. shutdown) returns early: the loop re-checks its flag.
  clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
}

/// Fixed-period tick timer on the steady clock: tick i is due at start + i * period. When the
/// loop overran, the timer skips the periods already past (counted) instead of bursting.
class TickTimer {
 public:
  explicit TickTimer(std::int64_t period_ns) noexcept : period_ns_(period_ns) {}

  /// Sets tick 0 to now.
  void start() noexcept {
    next_ns_ = now_ns();
    overruns_ = 0;
  }
  /// Sleeps until the next tick is due; returns how many periods were skipped (0 normally).
  std::int64_t wait_next() noexcept {
    next_ns_ += period_ns_;
    const std::int64_t now = now_ns();
    std::int64_t skipped = 0;
    if (now > next_ns_ + period_ns_) {  // more than one full period late: drop the backlog
      skipped = (now - next_ns_) / period_ns_;
      next_ns_ += skipped * period_ns_;
      overruns_ += static_cast<std::uint64_t>(skipped);
    }
    sleep_until_ns(next_ns_);
    return skipped;
  }
  std::int64_t period_ns() const noexcept { return period_ns_; }
  std::int64_t next_ns() const noexcept { return next_ns_; }
  /// Periods skipped since start().
  std::uint64_t overruns() const noexcept { return overruns_; }

 private:
  std::int64_t period_ns_;
  std::int64_t next_ns_ = 0;
  std::uint64_t overruns_ = 0;
};

}  // namespace poise::node
