#pragma once
// The launcher's supervision, one piece of code for `poise launch` (one host's share of a
// deployment) and `poise run` (a scenario on one machine): it starts the components as Child
// processes (own process group, ended with the launcher), watches them, restarts one by its
// policy, says how each ended in words (signal names), and stops them in a given order. The
// caller decides what a run's end is and writes the result file (failed or not).

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "poise/launch/child.hpp"
#include "poise/launch/deployment.hpp"

namespace poise::launch {

/// One supervised component.
struct ComponentSpec {
  std::string name;
  std::vector<std::string> argv;
  Scheduling scheduling;
  Restart restart = Restart::never;
  int max_restarts = 0;
  /// Its end is the end of the run (the simulator): never restarted, never a failure here.
  bool ends_run = false;
  /// It runs until the launcher stops it: any end, code 0 included, is a failure (after its
  /// restarts). Otherwise an end with code 0 is "finished".
  bool runs_until_stopped = false;
  int stop_grace_ms = 3000;  ///< SIGTERM, then SIGKILL after this long
};

class Supervisor {
 public:
  struct Entry {
    ComponentSpec spec;
    std::unique_ptr<Child> child;  ///< null while waiting to be restarted
    int restarts = 0;
    std::vector<std::string> exits;  ///< how each instance ended, in words
    bool done = false;               ///< ended and not to be restarted
    std::chrono::steady_clock::time_point restart_at{};
  };
  /// What one round of supervision saw.
  struct Status {
    bool run_ended = false;  ///< the component that ends the run has ended
    bool all_ended = false;  ///< nothing runs or waits for a restart
    std::string failure;     ///< "estimator killed by SIGKILL (Killed, code 137) ..." or ""
  };

  /// `who` starts the messages ("poise launch"); the children's logs go to `log_dir`.
  Supervisor(std::string who, std::filesystem::path log_dir);
  ~Supervisor();
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;

  /// Called after each start and restart (to print the pid, say).
  std::function<void(const Entry&)> on_start;
  /// Called when a component finished with code 0 and is not restarted.
  std::function<void(const Entry&)> on_finish;

  /// Adds a component and starts it. Throws std::runtime_error when it cannot be started.
  Child& start(ComponentSpec spec);
  /// One round: every ended component is restarted by its policy (0.5 s later) or marked done;
  /// the first that failed is named in `failure`, with `phase` appended ("during start-up").
  Status poll(const std::string& phase = "");
  /// Stops what still runs: the names in `order` first, then the others in start order. Each
  /// stop is recorded in its exits ("... (stopped by the launcher)").
  void stop(const std::vector<std::string>& order = {});

  const std::vector<std::unique_ptr<Entry>>& entries() const { return entries_; }
  /// The entry of that name, or null.
  Entry* find(const std::string& name);

 private:
  void launch(Entry& e);
  std::string who_;
  std::filesystem::path log_dir_;
  std::vector<std::unique_ptr<Entry>> entries_;
};

}  // namespace poise::launch
