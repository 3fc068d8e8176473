#pragma once
// A deployment file: which Poise components run on which machine, from one YAML file
// (`poise launch FILE --host NAME`). Format: deploy/deployments/README.md.
//
//   name: robot_and_desk
//   domain: 42
//   scenario: forward_push_double_support   # the simulator's world (a file or a name)
//   mode: lockstep                          # or realtime
//   security: secrets/poise                 # optional: DDS Security (poise security init)
//   hosts:
//     robot: {address: 10.77.0.1}
//     desk:  {address: 10.77.0.2}
//   components:
//     sim:        {host: robot, dds: fastdds}
//     estimator:  {host: desk, dds: cyclone, cpu: [1], priority: 50, restart: on-failure}
//     controller: {host: desk}
//     contact:    {host: desk, options: [--method, qp]}
//     recorder:   {host: desk, output: results/run.mcap}
//     driver:     {host: robot, kind: command, command: [/opt/robot/driver, --port, /dev/ttyS0]}
//
// Parsing checks everything it can without starting anything and throws DeploymentError naming
// each problem with its place in the file (all of them, not only the first).

#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace poise::launch {

struct DeploymentError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

enum class Restart { never, on_failure, always };
const char* to_string(Restart r);

struct Host {
  std::string name;
  std::string address;  ///< IPv4 address on the DDS network (127.0.0.1: one machine)
};

struct Component {
  std::string name;  ///< key in `components`
  std::string kind;  ///< sim, estimator, controller, contact, recorder, command
  std::string host;
  std::string dds;                   ///< cyclone or fastdds
  std::vector<std::string> options;  ///< extra command-line options, appended
  std::vector<std::string> command;  ///< kind command: the program and its arguments
  std::string output;                ///< kind recorder: the MCAP file
  std::vector<int> cpus;             ///< CPU affinity (empty: any)
  int priority = 0;                  ///< SCHED_FIFO priority 1..99 (0: normal scheduling)
  Restart restart = Restart::never;
  int max_restarts = 3;
};

}  // namespace poise::launch
namespace poise::scenario {
struct Scenario;
}
namespace poise::launch {

/// poise-estimator's options that a scenario sets, as `poise run` and `poise launch` pass them:
/// --supports, --estimator (the scenario's type), --ground-height and --support-heights (where the
/// soles start: the estimator section or the platforms' placement), --initial-xy, --stance-rate-hz,
/// --contact-ft-noise (the section's or the simulated F/T's), --imu-delay-ticks (the section's or
/// the simulated IMU's), every number to the last bit. `estimator_type`: "" = the scenario's.
std::vector<std::string> estimator_scenario_args(const scenario::Scenario& scenario,
                                                 const std::string& estimator_type = "");

struct Deployment {
  std::filesystem::path file;
  std::string name;
  int domain = 0;
  std::string scenario;  ///< resolved path of the scenario file ("" without a simulator)
  /// What the nodes take from the scenario (its estimator.supports and contact.method; "" =
  /// the nodes' defaults), read without loading the scenario's robot.
  std::string estimator_supports, contact_method;
  /// poise-estimator's options from the scenario (estimator_scenario_args) when this host could
  /// load it (the simulator's host); empty otherwise (then --supports alone, from the YAML).
  std::vector<std::string> estimator_args;
  /// The scenario's `controller:` section (YAML text, checked by the controller's parser; ""
  /// = none): written to the logs as controller.yaml for poise-controller --config, and its
  /// contact.priority / torsion_limit given to poise-contact, as `poise run` does.
  std::string controller_yaml;
  std::string contact_priority, contact_torsion_limit;
  std::string planned_support;  ///< the scenario's initial.support (controller --planned-support)
  std::string robot;     ///< --robot for the nodes ("" = none: the robot of the description)
  bool realtime = false;
  std::string security;  ///< DDS Security directory (poise security init), "" = none
  std::vector<Host> hosts;
  std::vector<Component> components;  ///< in start order: recorder, contact, estimator,
                                      ///< controller, command, sim

  const Host* find_host(const std::string& name) const;
  std::vector<const Component*> components_on(const std::string& host) const;
};

/// The directory of Poise's executables: $POISE_BIN_DIR, else this executable's directory.
std::filesystem::path bin_dir();

/// A scenario file as given (relative to the working directory, else to `base`), or a name in
/// deploy/scenarios/ of this tree, searched upwards from bin_dir() and from `base`. Returns the
/// argument unchanged when nothing matches (the loader then names the missing file).
std::string resolve_scenario(const std::string& file_or_name,
                             const std::filesystem::path& base = ".");

/// Reads and validates a deployment file. Relative paths (scenario, robot, outputs) are taken
/// relative to the working directory if they exist there, else to the file's directory.
/// `host` (--host): the machine this launcher starts. The scenario (and the robot files it names)
/// is loaded and validated in full where the simulator runs, or for every host when `host` is
/// empty (--check of the whole file); on a host without the simulator only the scenario file's
/// estimator.supports and contact.method are read: its nodes take the robot from
/// poise/robot_description, so that host needs no robot files.
Deployment load_deployment(const std::filesystem::path& file, const std::string& host = "");

/// The DDS configuration of `host` for `vendor` ("cyclone" or "fastdds"): unicast discovery to
/// every host of the deployment, bound to this host's address only, no multicast.
std::string dds_config_xml(const Deployment& d, const Host& host, const std::string& vendor);

/// A recorder component whose `options` choose what happens to an existing output file
/// (`--if-exists`, `poise record --help`); otherwise the launcher clears its output once at the
/// launch's start and a restarted recorder goes on in the next free numbered file.
bool recorder_sets_if_exists(const Component& c);

/// The command line of a component, given the directory of the built executables and the DDS
/// configuration file it uses.
std::vector<std::string> command_line(const Deployment& d, const Component& c,
                                      const std::filesystem::path& bin_dir,
                                      const std::filesystem::path& dds_config);

}  // namespace poise::launch
