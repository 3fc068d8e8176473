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
// construction (node::TickQueue). take_due(k) (loop thread) removes every reference whose tick is <= k and hands
// out the one with the largest tick (ties: the one that arrived last); the others were superseded
// before their turn. A reference that a player sends ahead of time is therefore applied exactly
// at its tick, however the DDS delivery and the loop interleave, as long as it arrives before
// the state of that tick is handled. One that arrives later is applied at the next state and
// counted as late (its tick <= the tick handled before). No allocation, no exception.

#include <atomic>
#include <cstdint>
#include <functional>

#include <poise/msg/balance_reference.h>

#include "poise/node/tick_queue.hpp"

namespace poise::controller_node {

class ReferenceQueue {
 public:
  explicit ReferenceQueue(std::size_t capacity) : queue_(capacity) {}

  /// A subscriber callback that queues every sample (the queue must outlive it).
  std::function<void(const msg::BalanceReference&)> callback() {
    return [this](const msg::BalanceReference& r) { put(r); };
  }

  /// Queues `r`. When every slot is taken the reference with the smallest tick is dropped
  /// (counted in overflows()).
  void put(const msg::BalanceReference& r) noexcept { queue_.put(r.header().tick(), r); }

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
    Due d;
    // The tick handed out is known before the visits (node::TickQueue), so tick - 1 is too.
    std::uint64_t applied = 0;
    bool have_applied = false;
    const auto taken = queue_.take_due(k, out, [&](std::uint64_t t, const msg::BalanceReference& r) {
      if (t != 0 && have_handled && t <= handled) ++d.late;
      if (!have_applied) {  // the first visit: `out` is already the reference handed out
        applied = out.header().tick();
        have_applied = true;
      }
      if (applied > 1 && t == applied - 1 && previous_q && r.has_upper_body_q()) {
        d.has_previous = true;
        for (std::size_t j = 0; j < previous_q_size && j < r.upper_body_q().size(); ++j)
          previous_q[j] = r.upper_body_q()[j];
      }
    });
    d.taken = taken.taken;
    d.tick = taken.tick;
    d.removed = taken.removed;
    late_.fetch_add(d.late, std::memory_order_relaxed);
    return d;
  }

  std::uint64_t overflows() const noexcept { return queue_.overflows(); }
  std::uint64_t late() const noexcept { return late_.load(std::memory_order_relaxed); }
  std::uint64_t received() const noexcept { return queue_.received(); }

 private:
  node::TickQueue<msg::BalanceReference> queue_;
  std::atomic<std::uint64_t> late_{0};
};

}  // namespace poise::controller_node
