#pragma once
// Clean shutdown on SIGINT / SIGTERM: the handler only sets a flag that node loops poll (every
// loop waits with a timeout of at most ~100 ms, so a node stops within that time).

namespace poise::node {

/// Installs the SIGINT and SIGTERM handlers (idempotent). Configuration time.
void install_shutdown_handlers();

/// True once SIGINT or SIGTERM arrived, or request_shutdown() was called. Lock-free, noexcept.
bool shutdown_requested() noexcept;

/// Asks the loops of this process to stop (e.g. at the end of a scenario).
void request_shutdown() noexcept;

}  // namespace poise::node
