#pragma once
// The whole stack in one process, no DDS: simulator -> state source (estimator, or ground truth
// for debugging) -> balance controller -> contact optimiser -> controller -> simulator, in
// lockstep at the simulator's period. Used by `poise run --in-process SCENARIO`, by the closed-loop
// tests, and as the baseline the DDS-distributed run is compared against.
//
// Per tick k:
//   state k      = estimator.update(sensors k)            (or ground truth k: debug option)
//   command k    = controller.tick(state k, reference, contact optimiser)
//   sensors k+1  = simulator.step(command k)
// The measured tick latency is the compute time of state + controller + optimiser (not the
// simulator step); a tick whose latency exceeds the control period counts as a deadline miss.

#include <array>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/reference/sampler.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/simulator.hpp"

namespace poise::inprocess {

/// Where the controller's state comes from.
enum class StateSource : std::uint8_t {
  kEstimator = 0,    ///< poise::estimator from the simulated sensors (what a robot would do)
  kGroundTruth = 1,  ///< DEBUG: the simulator's ground truth (perfect state)
};
const char* to_string(StateSource s);

/// True when this build contains the estimator library.
bool estimator_available();

struct LoopOptions {
  StateSource state_source = StateSource::kEstimator;
  contact::Method contact_method = contact::Method::kSequential;
  /// Controller tuning; unset: controller_config_file if given, else the scenario's `controller:`
  /// section, else the defaults.
  std::optional<controller::ControllerConfig> controller;
  std::filesystem::path controller_config_file;
  double duration = 0.0;  ///< [s]; <= 0: the scenario's duration
  /// Estimator that makes the state: "invariant-ekf" or "leg-odometry"; "": the scenario's
  /// estimator.type.
  std::string estimator;
};

struct LatencyStats {
  double p50_us = 0.0;
  double p99_us = 0.0;
  double max_us = 0.0;
};

/// Outcome of a run (the JSON written by `poise run --in-process --output`).
struct RunResult {
  std::string scenario;
  bool survived = false;
  double com_error_max_m = 0.0;  ///< ScenarioMonitor definition (horizontal, see scenario.hpp)
  double com_error_final_m = 0.0;
  double foot_slip_max_m = 0.0;
  int non_foot_contacts = 0;  ///< ticks with a non-foot body touching something
  double min_base_height_m = 0.0;
  double recovery_time_s = 0.0;       ///< after the last push
  double trunk_pitch_max_deg = 0.0;   ///< ScenarioMonitor::Result
  double trunk_roll_max_deg = 0.0;
  std::vector<std::string> failed;    ///< the success criteria that failed, readable
  LatencyStats tick_latency_us;       ///< compute time of state + controller + optimiser per tick
  std::uint64_t deadline_misses = 0;  ///< ticks whose latency exceeded the control period
  double realtime_factor = 0.0;       ///< simulated time / wall time (whole loop incl. simulator)
  StateSource state_source = StateSource::kGroundTruth;
  double sim_time_s = 0.0;
  std::uint64_t ticks = 0;
  std::uint64_t contact_fallbacks = 0;  ///< controller ticks finished with a fallback
  std::uint64_t qp_failures = 0;        ///< eq (33) not solved as posed
  std::uint64_t rejected_commands = 0;  ///< commands the simulator refused
};

class InProcessLoop {
 public:
  /// Builds the simulator, the robot model, the estimator (if used), the controller and the
  /// contact optimiser. Throws std::runtime_error naming the problem (bad scenario, robot config,
  /// controller config, estimator requested but not built).
  InProcessLoop(const scenario::Scenario& scenario, const LoopOptions& options);
  ~InProcessLoop();
  InProcessLoop(const InProcessLoop&) = delete;
  InProcessLoop& operator=(const InProcessLoop&) = delete;

  /// One control tick and one simulator step.
  void step();
  /// Steps until the run's duration; `progress` (may be empty) is called about once per
  /// simulated second with the current time. Returns result().
  RunResult run(const std::function<void(double)>& progress = {});
  /// Verdict and statistics of the ticks run so far.
  RunResult result() const;

  double time() const;
  double duration() const { return duration_; }
  /// The balance reference used every tick (tests change it: CoM shift, upper-body motion).
  /// With a scenario `reference:` file, step() writes the trajectory's part of it first.
  controller::BalanceReference& reference() { return reference_; }
  const controller::BalanceController& controller() const { return *controller_; }
  sim::Simulator& simulator() { return *sim_; }
  const sim::GroundTruth& truth() const { return truth_; }
  const controller::RobotState& state() const { return state_; }
  const scenario::Scenario& scenario() const { return scenario_; }

 private:
  struct EstimatorParts;
  void read_state();
  void play_reference();

  scenario::Scenario scenario_;
  LoopOptions options_;
  double duration_ = 0.0;
  model::RobotConfig robot_;
  model::Model model_;
  std::unique_ptr<sim::Simulator> sim_;
  std::unique_ptr<controller::BalanceController> controller_;
  std::unique_ptr<EstimatorParts> estimator_;
  /// The scenario's `reference:` trajectory, sampled into reference_ every tick (null: none).
  std::unique_ptr<reference::Sampler> reference_player_;
  contact::ContactOptimizer optimizer_;
  sim::ScenarioMonitor monitor_;

  std::vector<int> sim_to_model_;  // sim joint i -> model joint
  std::vector<int> model_to_sim_;  // model joint j -> sim joint
  std::array<int, 2> sim_foot_of_side_{-1, -1};

  sim::SensorFrame sensors_;
  sim::GroundTruth truth_;
  sim::JointCommand sim_command_;
  controller::RobotState state_;
  controller::BalanceReference reference_;
  controller::JointCommand command_;

  std::vector<double> latency_us_;
  std::uint64_t deadline_misses_ = 0;
  std::uint64_t rejected_commands_ = 0;
  std::chrono::steady_clock::duration wall_{};
};

}  // namespace poise::inprocess
