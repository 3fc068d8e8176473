#include "poise/launch/supervisor.hpp"

#include <cstdio>
#include <stdexcept>

namespace poise::launch {

Supervisor::Supervisor(std::string who, std::filesystem::path log_dir)
    : who_(std::move(who)), log_dir_(std::move(log_dir)) {}

Supervisor::~Supervisor() {
  stop();
}

void Supervisor::launch(Entry& e) {
  e.child = std::make_unique<Child>(e.spec.name, e.spec.argv, log_dir_, e.spec.scheduling);
  if (on_start) on_start(e);
}

Child& Supervisor::start(ComponentSpec spec) {
  auto e = std::make_unique<Entry>();
  e->spec = std::move(spec);
  Entry& ref = *e;
  entries_.push_back(std::move(e));
  launch(ref);
  return *ref.child;
}

Supervisor::Entry* Supervisor::find(const std::string& name) {
  for (auto& e : entries_)
    if (e->spec.name == name) return e.get();
  return nullptr;
}

Supervisor::Status Supervisor::poll(const std::string& phase) {
  Status s;
  const auto now = std::chrono::steady_clock::now();
  bool any_left = false;
  for (auto& ep : entries_) {
    Entry& e = *ep;
    if (e.done) continue;
    if (!e.child) {  // waiting to be restarted
      any_left = true;
      if (now >= e.restart_at) {
        try {
          launch(e);
        } catch (const std::exception& ex) {
          e.done = true;
          if (s.failure.empty())
            s.failure = e.spec.name + " could not be restarted: " + ex.what();
        }
      }
      continue;
    }
    const auto code = e.child->poll();
    if (!code) {
      any_left = true;
      continue;
    }
    const ComponentSpec& c = e.spec;
    const std::string how = e.child->exit_description();
    e.exits.push_back(how);
    if (c.ends_run) {
      e.done = true;
      s.run_ended = true;
      continue;
    }
    const bool failed = *code != 0 || c.runs_until_stopped;
    const bool again = c.restart == Restart::always || (c.restart == Restart::on_failure && failed);
    if (again && e.restarts < c.max_restarts) {
      ++e.restarts;
      std::fprintf(stderr, "%s: %s %s; restarting it (%d of %d)\n", who_.c_str(), c.name.c_str(),
                   how.c_str(), e.restarts, c.max_restarts);
      e.child.reset();
      e.restart_at = now + std::chrono::milliseconds(500);
      any_left = true;
      continue;
    }
    e.done = true;
    if (failed) {
      if (s.failure.empty())
        s.failure = c.name + " " + how + (phase.empty() ? "" : " " + phase) +
                    (again ? " (restarted " + std::to_string(e.restarts) + " times already)" : "");
      continue;
    }
    if (on_finish) on_finish(e);
  }
  s.all_ended = !any_left;
  return s;
}

void Supervisor::stop(const std::vector<std::string>& order) {
  auto stop_one = [](Entry& e) {
    if (!e.child || e.child->poll()) return;
    e.child->stop(e.spec.stop_grace_ms);
    e.exits.push_back(e.child->exit_description() + " (stopped by the launcher)");
  };
  for (const auto& name : order)
    for (auto& e : entries_)
      if (e->spec.name == name) stop_one(*e);
  for (auto& e : entries_)
    stop_one(*e);
}

}  // namespace poise::launch
