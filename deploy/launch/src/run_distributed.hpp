#pragma once
// The distributed `poise run SCENARIO` (run_distributed.cpp: the command line, the plan, the
// processes) and its result file and summary lines (run_result.cpp), which share these types.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "poise/controller/controller_config.hpp"
#include "poise/launch/child.hpp"
#include "poise/launch/log_dir.hpp"
#include "poise/launch/run_settings.hpp"
#include "poise/launch/supervisor.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/sim_config.hpp"

namespace poise::launch::distributed {

/// `poise run`'s options (run_settings.hpp: one command line for both modes).
using Settings = RunSettings;

/// What a run decided before it starts a process: the scenario, the vendors, the domain, its
/// files and every component's command line.
struct Plan {
  scenario::Scenario scenario;
  double duration = 0.0;
  std::map<std::string, std::string> vendor;  ///< component ("sim", ...) -> vendor
  int domain = -1;
  std::string run_suffix;  ///< ".2" etc. while other runs hold the default log directory
  std::optional<LogDirLock> logs_lock;  ///< held for the whole run
  std::filesystem::path logs, output, bin;
  std::filesystem::path start_file;  ///< with a recorder: the simulator starts once it exists
  double deadline_us = 0.0, timeout_s = 0.0;
  bool recording_run = false;
  bool passive = false;
  std::vector<std::string> sim_args, est_args, contact_args, ctrl_args;
  controller::ControllerConfig ccfg;
  std::filesystem::path ctrl_config_file;  ///< "" = the controller's built-in values
};

/// The processes of the run. One supervisor with `poise launch`: every process of the run is
/// its Child (own process group, ended with the launcher), each end is said in words, and the
/// stop is ordered.
struct Processes {
  explicit Processes(const std::filesystem::path& logs) : supervisor("poise run", logs) {}
  Supervisor supervisor;
  Child* recorder = nullptr;
  std::vector<Child*> children;
  std::filesystem::path recording;
};

/// A run that fails still writes its result file: failed, with the reason and how each
/// process ended.
void write_failure(const Settings& s, const Plan& p, Processes& procs, const std::string& reason);

/// The run's result from the components' summaries: written to the result file and summed up
/// on stdout. Returns the exit status: 0 survived, 1 failed the scenario's criteria, 2 no result
/// from the simulator or a failed recording.
int write_result(const Settings& s, const Plan& p, Processes& procs,
                 const std::string& record_problem);

}  // namespace poise::launch::distributed
