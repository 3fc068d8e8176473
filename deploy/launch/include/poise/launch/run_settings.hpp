#pragma once
// `poise run SCENARIO`'s command line, one grammar for both modes: the distributed run (four
// processes over DDS, run_distributed) and `--in-process` (every library in one process, no DDS:
// deploy/inprocess). Options that only mean something over DDS (the vendors, the domain,
// DDS Security, the passive recorder, the contact deadline) are accepted by both; in process a
// note says that they have no effect.
#include <string>

#include "poise/sim/sim_config.hpp"

namespace poise::launch {

struct RunSettings {
  std::string scenario;
  bool in_process = false;  ///< --in-process: every library in this process, no DDS
  bool lockstep = false;    ///< --lockstep: the default, said explicitly (excludes --realtime)
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

/// Parses `poise run`'s command line (argv[0]: the program name shown in --help). Returns the
/// exit status when the command line ends the verb (0 after --help, 2 for a usage error), else -1.
int parse_run_settings(int argc, char** argv, RunSettings& s);

/// The options given that have no effect in process (the DDS ones), as the user spelled them:
/// "--domain", "--dds-sim", ... Empty for a distributed run's settings that use none.
std::string dds_only_options(const RunSettings& s);

/// The distributed run of parsed settings (launch.hpp: run_distributed(argc, argv) parses, then
/// calls this). Settings with `in_process` are refused (2): poise_launch does not hold the
/// in-process loop; `poise run` dispatches those to it.
int run_distributed(RunSettings& s);

}  // namespace poise::launch
