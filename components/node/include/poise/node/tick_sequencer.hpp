#pragma once
// Tick sequencing of a node's per-tick input stream: the one rule every node applies to the
// header tick of its input (poise/sensors for the estimator, poise/state for the controller), so
// that a restarted robot, a forged sample or a replayed one can never be answered with a state
// or a command computed from another stream. Fault semantics table: idl/README.md.
//
//   k == last                       repeat: answer again with the same output
//   last < k <= last + max_jump     next tick (k - last - 1 ticks were dropped)
//   anything else                   out of sequence: REJECTED (no output, counted), unless it is
//                                   a restart of the stream, which is accepted (the node
//                                   re-initialises and says so) when either
//                                   - the accepted stream has been silent for `restart_silence_ns`
//                                     (the old robot stopped: a driver or simulator restart), or
//                                   - `confirm` consecutive ticks k, k+1, ... of the new stream
//                                     arrived (the old stream cannot be told to stop).
// So a single forged sample with tick 10^12 (or 1) in a live stream is rejected, while a robot
// that comes back from tick 0 after a restart is followed within one sample (after the silence)
// or `confirm` samples.
// Real-time safe: no allocation, no exceptions; the clock is an input (testable).

#include <cstdint>

namespace poise::node {

class TickSequencer {
 public:
  struct Config {
    std::uint64_t max_jump = 1000;              ///< largest forward step accepted as "next" [ticks]
    int confirm = 5;                            ///< consecutive ticks that confirm a new stream
    std::int64_t restart_silence_ns = 20'000'000;  ///< silence of the old stream that ends it
  };
  enum class Verdict : std::uint8_t {
    kFirst,          ///< first sample: accepted
    kNext,           ///< accepted, follows the previous tick (dropped() ticks missing)
    kRepeat,         ///< same tick as the last accepted: answer again
    kRestart,        ///< accepted as the start of a new stream: re-initialise
    kOutOfSequence,  ///< rejected: no output
  };

  TickSequencer() = default;
  explicit TickSequencer(const Config& config) : config_(config) {}

  /// Classifies tick `k` received at `now_ns`; updates the state for accepted ticks.
  Verdict accept(std::uint64_t k, std::int64_t now_ns) noexcept {
    dropped_ = 0;
    if (!have_last_) {
      take(k, now_ns);
      return Verdict::kFirst;
    }
    if (k == last_) {
      last_ns_ = now_ns;
      return Verdict::kRepeat;
    }
    if (k > last_ && k - last_ <= config_.max_jump) {
      dropped_ = k - last_ - 1;
      take(k, now_ns);
      return Verdict::kNext;
    }
    // Out of sequence: a candidate new stream?
    if (have_candidate_ && k == candidate_last_ + 1) {
      ++candidate_count_;
      candidate_last_ = k;
    } else if (!(have_candidate_ && k == candidate_last_)) {
      have_candidate_ = true;
      candidate_last_ = k;
      candidate_count_ = 1;
    }
    const bool silent = now_ns - last_ns_ >= config_.restart_silence_ns;
    if (silent || candidate_count_ >= config_.confirm) {
      previous_ = last_;
      ++restarts_;
      take(k, now_ns);
      return Verdict::kRestart;
    }
    ++rejected_;
    return Verdict::kOutOfSequence;
  }

  /// Forgets the stream (the next tick is kFirst).
  void reset() noexcept {
    have_last_ = false;
    have_candidate_ = false;
  }

  bool started() const noexcept { return have_last_; }
  std::uint64_t last() const noexcept { return last_; }
  /// The last accepted tick before the latest restart.
  std::uint64_t previous() const noexcept { return previous_; }
  /// Ticks missing before the tick just accepted (kNext).
  std::uint64_t dropped() const noexcept { return dropped_; }
  std::uint64_t restarts() const noexcept { return restarts_; }
  std::uint64_t rejected() const noexcept { return rejected_; }
  const Config& config() const noexcept { return config_; }

 private:
  void take(std::uint64_t k, std::int64_t now_ns) noexcept {
    have_last_ = true;
    last_ = k;
    last_ns_ = now_ns;
    have_candidate_ = false;
    candidate_count_ = 0;
  }

  Config config_;
  bool have_last_ = false;
  std::uint64_t last_ = 0, previous_ = 0, dropped_ = 0;
  std::int64_t last_ns_ = 0;
  bool have_candidate_ = false;
  std::uint64_t candidate_last_ = 0;
  int candidate_count_ = 0;
  std::uint64_t restarts_ = 0, rejected_ = 0;
};

}  // namespace poise::node
