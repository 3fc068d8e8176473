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
#include "poise/launch/supervisor.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/sim_config.hpp"

namespace poise::launch::distributed {

/// `poise run`'s options.
struct Settings {
  std::string scenario;
  bool lockstep = false;  ///< --lockstep: the default, said explicitly (excludes --realtime)
  bool realtime = false;
  std::string dds_all, dds_sim, dds_estimator, dds_contact, dds_controller;
  int domain = -1;
  std::string output, log_dir;
  double duration = -1.0;
  bool ground_truth_state = false;
  std::string method;             ///< "" = the scenario's contact.method, else sequential
  std::string estimator;          ///< "" = the scenario's estimator.type, else invariant-ekf
  std::string controller_config;  ///< "" = the scenario's controller: section, else defaults
  double contact_deadline_us = -1.0;
  int command_timeout_ms = sim::kDefaultCommandTimeoutMs;
  int settle_ticks = -1;      ///< simulator start-up hold steps (-1: the simulator's default)
  double watchdog_ms = -1.0;  ///< safety layer watchdog (-1: default)
  double hold_s = -1.0;       ///< safety layer hold before damping (-1: default)
  double timeout_s = -1.0;
  bool quiet = false;
  bool record_given = false;  ///< `--record` was given (with a file or alone)
  std::string record;  ///< MCAP file of `--record` ("" with the flag alone: the default path)
  bool record_passive = false;  ///< `--record --passive`: `poise record --passive` (packet capture)
  std::string security;         ///< DDS Security directory (poise security init), "" = none
  int rt_priority = 0;       ///< SCHED_FIFO base priority of the processes (0: normal scheduling)
  bool lock_memory = false;  ///< every process locks its memory (mlockall)
  std::string cpus;          ///< CPU affinity of every process ("": any CPU)
};

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
