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
  std::chrono::nanoseconds deadline = infinite;
  Liveliness liveliness = Liveliness::automatic;
  std::chrono::nanoseconds liveliness_lease = infinite;

  /// 1 kHz control topics: reliable, volatile, keep-last 1.
  static constexpr Qos control() { return Qos{}; }
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
