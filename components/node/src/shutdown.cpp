#include "poise/node/shutdown.hpp"

#include <signal.h>

#include <atomic>

namespace poise::node {
namespace {

std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void on_signal(int) {
  g_stop.store(true, std::memory_order_relaxed);
}

}  // namespace

void install_shutdown_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: blocking calls return EINTR and loops re-check the flag
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

bool shutdown_requested() noexcept {
  return g_stop.load(std::memory_order_relaxed);
}

void request_shutdown() noexcept {
  g_stop.store(true, std::memory_order_relaxed);
}

}  // namespace poise::node
