#pragma once
// Hand-off of the newest sample from a DDS listener thread to a node's loop thread.
//
//   Mailbox<msg::State> states;
//   dds::Subscriber<msg::State> sub(participant, states.callback());
//   ...
//   if (states.wait(seen, deadline)) states.take(state);   // loop thread
//
// put() copies the sample into a slot allocated at construction and wakes the waiter: no
// allocation for fixed-size types, no exception. Only the newest sample is kept: a node that is
// slower than its input skips samples, which is what a 1 kHz loop wants.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>

#include "poise/node/tick_timer.hpp"

namespace poise::node {

template <class T>
class Mailbox {
 public:
  Mailbox() : slot_(std::make_unique<T>()) {}
  Mailbox(const Mailbox&) = delete;
  Mailbox& operator=(const Mailbox&) = delete;

  /// A subscriber callback that puts every sample here (the mailbox must outlive it).
  std::function<void(const T&)> callback() {
    return [this](const T& sample) { put(sample); };
  }

  /// Stores `sample` as the newest and wakes the waiter. Records the arrival time.
  void put(const T& sample) noexcept {
    {
      std::lock_guard lock(mutex_);
      *slot_ = sample;
      arrival_ns_ = now_ns();
      ++sequence_;
    }
    cv_.notify_one();
  }

  /// Number of samples put so far.
  std::uint64_t sequence() const noexcept {
    std::lock_guard lock(mutex_);
    return sequence_;
  }

  /// Waits until a sample newer than `seen` (a sequence number) is there, or until
  /// `deadline_ns` (monotonic, see now_ns()). True when there is one.
  bool wait(std::uint64_t seen, std::int64_t deadline_ns) noexcept {
    std::unique_lock lock(mutex_);
    const auto deadline =
        std::chrono::steady_clock::time_point(std::chrono::nanoseconds(deadline_ns));
    return cv_.wait_until(lock, deadline, [&] { return sequence_ > seen; });
  }

  /// Copies the newest sample into `out` if it is newer than `seen`; updates `seen` and the
  /// arrival time [ns]. False (nothing written) when there is nothing new.
  bool take(T& out, std::uint64_t& seen, std::int64_t* arrival_ns = nullptr) noexcept {
    std::lock_guard lock(mutex_);
    if (sequence_ <= seen) return false;
    out = *slot_;
    seen = sequence_;
    if (arrival_ns) *arrival_ns = arrival_ns_;
    return true;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::unique_ptr<T> slot_;
  std::uint64_t sequence_ = 0;
  std::int64_t arrival_ns_ = 0;
};

/// Hand-off of EVERY sample, in arrival order, from a DDS listener thread to a loop thread: for a
/// node whose output depends on each input, not only on the newest (the reference player takes
/// its CoM origin and step poses from the state of a given tick). `capacity` slots are allocated
/// at construction; when they are all taken the oldest sample is dropped and counted (dropped()).
/// put() and pop() neither allocate (fixed-size types) nor throw.
template <class T>
class SampleQueue {
 public:
  explicit SampleQueue(std::size_t capacity)
      : slots_(std::make_unique<T[]>(capacity > 0 ? capacity : 1)),
        capacity_(capacity > 0 ? capacity : 1) {}
  SampleQueue(const SampleQueue&) = delete;
  SampleQueue& operator=(const SampleQueue&) = delete;

  std::function<void(const T&)> callback() {
    return [this](const T& sample) { put(sample); };
  }

  void put(const T& sample) noexcept {
    {
      std::lock_guard lock(mutex_);
      if (size_ == capacity_) {  // full: the oldest goes
        head_ = (head_ + 1) % capacity_;
        --size_;
        ++dropped_;
      }
      slots_[(head_ + size_) % capacity_] = sample;
      ++size_;
    }
    cv_.notify_one();
  }

  /// Waits until a sample is queued or until `deadline_ns` (monotonic, see now_ns()); moves the
  /// oldest into `out`. False (nothing written) at the deadline.
  bool pop(T& out, std::int64_t deadline_ns) noexcept {
    std::unique_lock lock(mutex_);
    const auto deadline =
        std::chrono::steady_clock::time_point(std::chrono::nanoseconds(deadline_ns));
    if (!cv_.wait_until(lock, deadline, [&] { return size_ > 0; })) return false;
    out = slots_[head_];
    head_ = (head_ + 1) % capacity_;
    --size_;
    return true;
  }

  std::uint64_t dropped() const noexcept {
    std::lock_guard lock(mutex_);
    return dropped_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::unique_ptr<T[]> slots_;
  std::size_t capacity_;
  std::size_t head_ = 0, size_ = 0;
  std::uint64_t dropped_ = 0;
};

}  // namespace poise::node
