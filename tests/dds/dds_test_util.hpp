#pragma once
// Test helpers: a DDS domain of one's own, and bounded waiting.

#include <chrono>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>

#include "../support/test_domain.hpp"

namespace poise::dds::test {

using poise::testing::claim_test_domain;

/// Polls `done` every millisecond until it is true or `timeout` passes.
inline bool eventually(const std::function<bool()>& done,
                       std::chrono::milliseconds timeout = std::chrono::milliseconds(10000)) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

}  // namespace poise::dds::test
