#pragma once
// Vendor-neutral quality of service of one publisher or subscriber.

#include <chrono>

namespace poise::dds {

enum class Reliability { best_effort, reliable };
enum class Durability { volatile_, transient_local };
enum class Liveliness { automatic, manual_by_participant, manual_by_topic };

/// The QoS both vendors map 1:1. A period of nanoseconds::max() means infinite.
struct Qos {
  static constexpr std::chrono::nanoseconds infinite = std::chrono::nanoseconds::max();

  Reliability reliability = Reliability::reliable;
  Durability durability = Durability::volatile_;
  int history_depth = 1;  ///< keep-last depth, >= 1 (also the late-joiner history if latched)
  /// Keep-last depth of writers, if deeper than `history_depth` (0: `history_depth`). A reliable
  /// keep-last writer can repair a reader's loss only from what its history still holds: a
  /// deeper writer history lets a briefly starved reader (a recorder) catch up, while readers in
  /// the loop keep only the newest sample.
  int writer_history_depth = 0;
  std::chrono::nanoseconds deadline = infinite;
  Liveliness liveliness = Liveliness::automatic;
  std::chrono::nanoseconds liveliness_lease = infinite;

  /// Writer history of the control topics: 32 ticks at 1 kHz. A reader that falls up to 32 ms
  /// behind (a recorder starved of CPU) still receives every sample. Cyclone blocks a reliable
  /// writer whose unacknowledged bytes exceed its WHC high-water mark: the Cyclone backend raises
  /// that mark above kControlWriterDepth x the largest sample (cyclone_backend.cpp).
  static constexpr int kControlWriterDepth = 32;
  /// 1 kHz control topics: reliable, volatile; readers keep-last 1, writers keep-last 32.
  static constexpr Qos control() {
    Qos q;
    q.writer_history_depth = kControlWriterDepth;
    return q;
  }
  /// Keep-last depth a writer of this QoS uses.
  constexpr int writer_depth() const {
    return writer_history_depth > history_depth ? writer_history_depth
                                                : (history_depth < 1 ? 1 : history_depth);
  }
  /// Sparse state that late joiners need: reliable, transient-local, keep-last `depth`.
  static constexpr Qos latched(int depth = 1) {
    Qos q;
    q.durability = Durability::transient_local;
    q.history_depth = depth;
    return q;
  }
  /// Reliable, volatile, keep-last `depth` (event streams).
  static constexpr Qos reliable(int depth) {
    Qos q;
    q.history_depth = depth;
    return q;
  }
  /// Best-effort, volatile, keep-last `depth` (diagnostics).
  static constexpr Qos best_effort(int depth = 1) {
    Qos q;
    q.reliability = Reliability::best_effort;
    q.history_depth = depth;
    return q;
  }

  friend constexpr bool operator==(const Qos&, const Qos&) = default;
};

}  // namespace poise::dds
