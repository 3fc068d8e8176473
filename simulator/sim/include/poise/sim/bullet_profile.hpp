#pragma once
// Where Bullet's step spends its time: the library's own named profile zones (BT_PROFILE), timed
// while a BulletProfile is alive. For benchmarks and `poise-bench-loop --profile`; it costs about
// 5 us a step of the standing humanoid (some 75 zones entered), so it is off in normal runs.
#include <cstdint>
#include <string>
#include <vector>

namespace poise::sim {

class BulletProfile {
 public:
  /// Installs the zone hooks (Bullet's are process-wide). Throws std::logic_error when another
  /// BulletProfile is alive.
  BulletProfile();
  ~BulletProfile();
  BulletProfile(const BulletProfile&) = delete;
  BulletProfile& operator=(const BulletProfile&) = delete;

  struct Zone {
    std::string name;  ///< Bullet's zone name, e.g. "solveGroupCacheFriendlyIterations"
    int depth = 0;     ///< nesting depth where it was first entered (0 = outermost)
    std::string parent;
    double total_us = 0.0;  ///< inclusive time
    std::int64_t calls = 0;
  };
  /// The zones entered since construction or reset(), in the order first entered.
  std::vector<Zone> zones() const;
  void reset();
  /// Zones nested deeper than 64 or more than 128 distinct zones are not timed; counted here.
  std::int64_t dropped() const;
};

}  // namespace poise::sim
