#pragma once
// Values held until the tick they are for: the timing rule of poise/balance_reference
// (idl/balance_reference.idl: header.tick is the first tick a value applies to, 0 = at once),
// shared by the controller's ReferenceQueue and the estimator's FootPlanQueue.
//
//   node::TickQueue<Plan> q(512);
//   listener thread:  q.put(tick, plan);
//   loop thread, k:   Plan p; const auto t = q.take_due(k, p, [](std::uint64_t, const Plan&) {});
//
// put() copies a value into one of `capacity` slots allocated at construction; when every slot
// is taken, the value with the smallest tick is dropped (counted in overflows()). take_due(k)
// removes every value whose tick is <= k and hands out the one with the largest tick (ties: the
// one that arrived last); the others were superseded before their turn. `visit(tick, value)` sees
// each removed value (the one handed out included) once the one handed out is known, under the
// queue's lock (keep it short; it must not call the queue). No allocation, no exception.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>

namespace poise::node {

template <class T>
class TickQueue {
 public:
  explicit TickQueue(std::size_t capacity)
      : capacity_(capacity < 1 ? 1 : capacity), slots_(std::make_unique<Slot[]>(capacity_)) {}
  TickQueue(const TickQueue&) = delete;
  TickQueue& operator=(const TickQueue&) = delete;

  void put(std::uint64_t tick, const T& value) noexcept {
    std::lock_guard lock(mutex_);
    std::size_t slot = capacity_;
    for (std::size_t i = 0; i < capacity_ && slot == capacity_; ++i)
      if (!slots_[i].used) slot = i;
    if (slot == capacity_) {  // full: drop the earliest
      slot = 0;
      for (std::size_t i = 1; i < capacity_; ++i)
        if (slots_[i].tick < slots_[slot].tick) slot = i;
      ++overflows_;
    }
    Slot& s = slots_[slot];
    s.used = true;
    s.tick = tick;
    s.order = ++arrivals_;
    s.value = value;
  }

  struct Taken {
    bool taken = false;         ///< `out` holds the value that applies from this tick
    std::uint64_t tick = 0;     ///< its tick
    std::uint32_t removed = 0;  ///< values removed by this call (handed out + superseded)
  };

  /// Removes the values due at tick `k` (tick <= k), copies the one that applies into `out`
  /// (left alone when none is due) and calls `visit(tick, value)` for each removed value.
  template <class Visit>
  Taken take_due(std::uint64_t k, T& out, Visit&& visit) noexcept {
    std::lock_guard lock(mutex_);
    Taken t;
    std::size_t best = capacity_;
    for (std::size_t i = 0; i < capacity_; ++i) {
      const Slot& s = slots_[i];
      if (!s.used || s.tick > k) continue;
      ++t.removed;
      if (best == capacity_ || s.tick > slots_[best].tick ||
          (s.tick == slots_[best].tick && s.order > slots_[best].order))
        best = i;
    }
    if (best == capacity_) return t;
    t.taken = true;
    t.tick = slots_[best].tick;
    out = slots_[best].value;
    for (std::size_t i = 0; i < capacity_; ++i) {
      Slot& s = slots_[i];
      if (!s.used || s.tick > k) continue;
      visit(s.tick, static_cast<const T&>(s.value));
      s.used = false;
    }
    return t;
  }

  std::uint64_t overflows() const noexcept {
    std::lock_guard lock(mutex_);
    return overflows_;
  }
  std::uint64_t received() const noexcept {
    std::lock_guard lock(mutex_);
    return arrivals_;
  }

 private:
  struct Slot {
    bool used = false;
    std::uint64_t tick = 0;
    std::uint64_t order = 0;  ///< arrival number (ties between equal ticks)
    T value{};
  };
  mutable std::mutex mutex_;
  std::size_t capacity_;
  std::unique_ptr<Slot[]> slots_;
  std::uint64_t overflows_ = 0;
  std::uint64_t arrivals_ = 0;
};

}  // namespace poise::node
