#pragma once
// Per-tick compute-time statistics over a window (diagnostics: p50 / p99 / max since the last
// publication) from a ring buffer preallocated at construction. add() is allocation-free and
// O(1); window() sorts a preallocated copy (called at ~10 Hz).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace poise::node {

struct WindowStats {
  std::size_t count = 0;
  double p50 = 0.0;
  double p99 = 0.0;
  double max = 0.0;
};

/// Nearest-rank percentile (p in [0, 1]) of a sorted, non-empty range.
inline double percentile_sorted(const double* sorted, std::size_t n, double p) noexcept {
  if (n == 0) return 0.0;
  std::size_t rank = static_cast<std::size_t>(p * static_cast<double>(n) + 0.999999);
  rank = std::clamp<std::size_t>(rank, 1, n);
  return sorted[rank - 1];
}

class ComputeStats {
 public:
  /// `capacity`: most samples kept per window (older ones are overwritten). Allocates.
  explicit ComputeStats(std::size_t capacity = 8192) : ring_(capacity), scratch_(capacity) {}

  /// One tick's value (e.g. compute time in microseconds). No allocation.
  void add(double value) noexcept {
    ring_[head_] = value;
    head_ = (head_ + 1) % ring_.size();
    if (count_ < ring_.size()) ++count_;
    if (value > max_all_) max_all_ = value;
  }

  /// Statistics of the samples added since the last window() call, then starts a new window.
  WindowStats window() noexcept {
    WindowStats s;
    s.count = count_;
    if (count_ == 0) return s;
    const std::size_t start = (head_ + ring_.size() - count_) % ring_.size();
    for (std::size_t i = 0; i < count_; ++i)
      scratch_[i] = ring_[(start + i) % ring_.size()];
    std::sort(scratch_.begin(), scratch_.begin() + static_cast<std::ptrdiff_t>(count_));
    s.p50 = percentile_sorted(scratch_.data(), count_, 0.50);
    s.p99 = percentile_sorted(scratch_.data(), count_, 0.99);
    s.max = scratch_[count_ - 1];
    count_ = 0;
    return s;
  }

  /// Largest value since construction.
  double max_all() const noexcept { return max_all_; }

 private:
  std::vector<double> ring_;
  std::vector<double> scratch_;
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  double max_all_ = 0.0;
};

/// Histogram of durations with `bin_us` bins (default 1 us) up to `max_us` (larger values go to
/// the last bin, and the exact maximum is kept): percentiles over a whole run at O(1) per sample,
/// no allocation after construction. Used for the sensor-to-command tick latency (1 us bins) and
/// the per-tick split of a node's compute time (0.1 us bins: parts of a few microseconds).
class LatencyHistogram {
 public:
  explicit LatencyHistogram(std::size_t max_us = 100000, double bin_us = 1.0)
      : bin_us_(bin_us > 0.0 ? bin_us : 1.0),
        bins_(static_cast<std::size_t>(static_cast<double>(max_us) / bin_us_) + 1, 0) {}

  void add(double us) noexcept {
    if (!(us >= 0.0)) us = 0.0;
    const double bin = us / bin_us_;
    const std::size_t i = bin >= static_cast<double>(bins_.size() - 1)
                              ? bins_.size() - 1
                              : static_cast<std::size_t>(bin);
    ++bins_[i];
    ++count_;
    if (us > max_) max_ = us;
    sum_ += us;
  }
  std::size_t count() const noexcept { return count_; }
  double max() const noexcept { return max_; }
  double mean() const noexcept { return count_ ? sum_ / static_cast<double>(count_) : 0.0; }
  /// Nearest-rank percentile; values are the upper edge of their bin (capped at max()).
  double percentile(double p) const noexcept {
    if (count_ == 0) return 0.0;
    std::size_t rank = static_cast<std::size_t>(p * static_cast<double>(count_) + 0.999999);
    rank = std::clamp<std::size_t>(rank, 1, count_);
    std::size_t seen = 0;
    for (std::size_t i = 0; i < bins_.size(); ++i) {
      seen += bins_[i];
      if (seen >= rank) return std::min(static_cast<double>(i + 1) * bin_us_, max_);
    }
    return max_;
  }

 private:
  double bin_us_;
  std::vector<std::uint32_t> bins_;
  std::size_t count_ = 0;
  double max_ = 0.0;
  double sum_ = 0.0;
};

}  // namespace poise::node
