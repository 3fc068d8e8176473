#pragma once
// Balance references held until the tick they are for (idl/balance_reference.idl: header.tick is
// the first tick a reference applies to, 0 = at once).
//
//   ReferenceQueue refs(512);
//   dds::Subscriber<msg::BalanceReference> sub(participant, refs.callback(), qos);
//   ...
//   const auto due = refs.take_due(k, last_tick_handled, ref);   // loop thread, state k
//   if (due.taken) apply(ref);
//
// put() (DDS listener thread) copies a reference into one of `capacity` slots allocated at
// construction. take_due(k) (loop thread) removes every reference whose tick is <= k and hands
// out the one with the largest tick (ties: the one that arrived last); the others were superseded
// before their turn. A reference that a player sends ahead of time is therefore applied exactly
// at its tick, however the DDS delivery and the loop interleave, as long as it arrives before
// the state of that tick is handled. One that arrives later is applied at the next state and
// counted as late (its tick <= the tick handled before). No allocation, no exception.

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include <poise/msg/balance_reference.h>

namespace poise::controller_node {

class ReferenceQueue {
 public:
  explicit ReferenceQueue(std::size_t capacity)
      : slots_(std::make_unique<msg::BalanceReference[]>(capacity)),
        used_(capacity, 0),
        order_(capacity, 0),
        capacity_(capacity) {}
  ReferenceQueue(const ReferenceQueue&) = delete;
  ReferenceQueue& operator=(const ReferenceQueue&) = delete;

  /// A subscriber callback that queues every sample (the queue must outlive it).
  std::function<void(const msg::BalanceReference&)> callback() {
    return [this](const msg::BalanceReference& r) { put(r); };
  }

  /// Queues `r`. When every slot is taken the reference with the smallest tick is dropped
  /// (counted in overflows()).
  void put(const msg::BalanceReference& r) noexcept {
    std::lock_guard lock(mutex_);
    std::size_t slot = capacity_;
    for (std::size_t i = 0; i < capacity_ && slot == capacity_; ++i)
      if (!used_[i]) slot = i;
    if (slot == capacity_) {  // full: drop the earliest
      slot = 0;
      for (std::size_t i = 1; i < capacity_; ++i)
        if (slots_[i].header().tick() < slots_[slot].header().tick()) slot = i;
      ++overflows_;
    }
    slots_[slot] = r;
    used_[slot] = 1;
    order_[slot] = ++arrivals_;
  }

  struct Due {
    bool taken = false;         ///< `out` holds the reference that applies from this tick
    std::uint64_t tick = 0;     ///< its header tick
    bool has_previous = false;  ///< a reference with upper_body_q for tick - 1 was also due
    std::uint32_t removed = 0;  ///< references removed by this call (applied + superseded)
    std::uint32_t late = 0;     ///< of those, arrived after the state of their tick was handled
  };

  /// Takes the references due at state tick `k` (header tick <= k; 0 = at once). `handled` is
  /// the tick handled before this one (`have_handled` false at the first state): a reference
  /// with 0 < tick <= handled is late. When a reference for tick - 1 of the one applied is also
  /// due, its upper_body_q is copied into `previous_q` (wire order, joint_count entries).
  Due take_due(std::uint64_t k, bool have_handled, std::uint64_t handled,
               msg::BalanceReference& out, double* previous_q = nullptr,
               std::size_t previous_q_size = 0) noexcept {
    std::lock_guard lock(mutex_);
    Due d;
    std::size_t best = capacity_;
    for (std::size_t i = 0; i < capacity_; ++i) {
      if (!used_[i]) continue;
      const std::uint64_t t = slots_[i].header().tick();
      if (t > k) continue;
      ++d.removed;
      if (t != 0 && have_handled && t <= handled) ++d.late;
      if (best == capacity_ || t > slots_[best].header().tick() ||
          (t == slots_[best].header().tick() && order_[i] > order_[best]))
        best = i;
    }
    if (best == capacity_) return d;
    d.taken = true;
    d.tick = slots_[best].header().tick();
    out = slots_[best];
    for (std::size_t i = 0; i < capacity_; ++i) {
      if (!used_[i] || slots_[i].header().tick() > k) continue;
      if (d.tick > 1 && slots_[i].header().tick() == d.tick - 1 && previous_q &&
          slots_[i].has_upper_body_q()) {
        d.has_previous = true;
        for (std::size_t j = 0; j < previous_q_size && j < slots_[i].upper_body_q().size(); ++j)
          previous_q[j] = slots_[i].upper_body_q()[j];
      }
      used_[i] = 0;
    }
    late_ += d.late;
    return d;
  }

  std::uint64_t overflows() const noexcept {
    std::lock_guard lock(mutex_);
    return overflows_;
  }
  std::uint64_t late() const noexcept {
    std::lock_guard lock(mutex_);
    return late_;
  }
  std::uint64_t received() const noexcept {
    std::lock_guard lock(mutex_);
    return arrivals_;
  }

 private:
  mutable std::mutex mutex_;
  std::unique_ptr<msg::BalanceReference[]> slots_;
  std::vector<char> used_;
  std::vector<std::uint64_t> order_;
  std::size_t capacity_;
  std::uint64_t overflows_ = 0;
  std::uint64_t late_ = 0;
  std::uint64_t arrivals_ = 0;
};

}  // namespace poise::controller_node
