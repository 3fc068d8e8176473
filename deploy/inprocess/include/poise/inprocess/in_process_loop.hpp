#pragma once
// The whole stack in one process, no DDS: simulator -> state source (estimator, or ground truth
// for debugging) -> balance controller -> contact optimiser -> controller -> simulator, in
// lockstep at the simulator's period. Used by `poise run --in-process SCENARIO`, by the closed-loop
// tests, and as the baseline the DDS-distributed run is compared against.
//
// One answer wherever the components run (issue #17 item 4): the loop does what `poise run`
// (distributed, lockstep) does, tick for tick, without the DDS transport:
//   start-up     the simulator steps `settle_ticks` times (poise-sim --settle-ticks, default 10)
//                with the joints held by the robot's safety layer (start-up hold), then the
//                scenario monitor sees the settled state; the first control tick is tick
//                settle_ticks, and the run is `duration` of control ticks after it (as poise-sim).
//   messages     every hand-over goes through the topic's message type with the nodes' own
//                conversions (sim_node, estimator_node, contact_node, controller_node): sensors,
//                state, contact problem, contact solution, joint command. DDS serialisation of
//                these types is lossless (doubles), so the numbers are the ones the nodes see.
//   estimator    configured as poise run configures poise-estimator (frozen_imu_ticks 100).
//   ground truth (debug state) as poise-estimator --ground-truth-state: the estimator's state with
//                the base pose and twist, the CoM, its velocity, the linear momentum and the
//                contact flags replaced by the simulator's truth (estimator_node::
//                overwrite_with_ground_truth); the simulator's truth alone only in a build without
//                the estimator library.
//   robot side   each joint command goes through the robot's safety layer (poise::safety, as in
//                poise-sim): validated, applied as the PD law, held when rejected.
// What is not the same is listed in README.md ("One answer: in process and distributed").
//
// Per tick k:
//   state k      = estimator.update(sensors k)            (or ground truth k: debug option)
//   command k    = controller.tick(state k, reference, contact optimiser)
//   sensors k+1  = simulator.step(safety layer(command k))
// The measured tick latency is the compute time of state + controller + optimiser, message
// conversions included (not the simulator step); a tick whose latency exceeds the control period
// counts as a deadline miss.

#include <array>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>

#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/reference/player.hpp"
#include "poise/safety/safety_layer.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/simulator.hpp"

namespace poise::controller_node {
class ReferenceApplier;
}

namespace poise::inprocess {

/// poise-sim's default start-up hold (--settle-ticks): simulator steps before the first frame.
inline constexpr int kDefaultSettleTicks = 10;
/// poise-estimator's default --frozen-imu-ticks (the library's default is 20).
inline constexpr int kNodeFrozenImuTicks = 100;

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
  /// Unset: the scenario's contact.method, else sequential (as `poise run` in both modes).
  std::optional<contact::Method> contact_method;
  /// Controller tuning; unset: controller_config_file if given, else the scenario's `controller:`
  /// section, else the defaults.
  std::optional<controller::ControllerConfig> controller;
  std::filesystem::path controller_config_file;
  double duration = 0.0;  ///< [s]; <= 0: the scenario's duration
  /// Estimator that makes the state: "invariant-ekf" or "leg-odometry"; "": the scenario's
  /// estimator.type.
  std::string estimator;
  /// Start-up hold: simulator steps with the joints held by the safety layer before the first
  /// control tick (poise-sim --settle-ticks); < 0: poise-sim's default (kDefaultSettleTicks).
  int settle_ticks = -1;
  /// A tick without a joint command (the estimator refused its sensor frame: poise-estimator
  /// sends no state then) is handled as poise-sim handles it in lockstep: after this wait
  /// (poise run --command-timeout-ms) the safety layer's command of that moment is applied (the
  /// watchdog has expired: HOLD of the last targets), and after `max_consecutive_timeouts`
  /// such ticks in a row the run is aborted (poise-sim --max-consecutive-timeouts).
  double command_timeout_ms = 2000.0;
  int max_consecutive_timeouts = 3;
  /// The robot side's safety layer (poise-sim --watchdog-ms, --hold-s): HOLD after this long
  /// without a command, DAMP after holding this long. In lockstep a command is applied as it
  /// arrives, so only ticks without a command (above) ever reach them.
  double watchdog_ms = 5.0;
  double hold_s = 5.0;
};

/// Per-tick times of a run [us]: order statistics over every tick.
struct LatencyStats {
  std::uint64_t count = 0;
  double mean_us = 0.0;
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
  double foot_slide_max_m = 0.0;  ///< the sliding part of it (ScenarioMonitor)
  double foot_displacement_max_m = 0.0;  ///< of the foot frame (ScenarioMonitor)
  double foot_tilt_max_deg = 0.0;        ///< of a supporting foot (ScenarioMonitor)
  int non_foot_contacts = 0;  ///< ticks with a non-foot body touching something
  double min_base_height_m = 0.0;
  double recovery_time_s = 0.0;      ///< after the last push
  double trunk_pitch_max_deg = 0.0;  ///< ScenarioMonitor::Result
  double trunk_roll_max_deg = 0.0;
  std::vector<std::string> failed;  ///< the success criteria that failed, readable
  /// The controller's FallConfig declared a fall (controller::describe_fall); "" when not.
  std::string controller_fall;
  double controller_fall_time_s = -1.0;  ///< when (scenario time) [s]; -1: no fall
  bool completed = true;            ///< false: aborted (ticks without a command, see LoopOptions)
  std::uint64_t command_timeouts = 0;  ///< ticks without a joint command
  LatencyStats tick_latency_us;        ///< compute time of state + controller + optimiser per tick
  std::uint64_t deadline_misses = 0;   ///< ticks whose latency exceeded the control period
  double realtime_factor = 0.0;        ///< simulated time / wall time (whole loop incl. simulator)
  StateSource state_source = StateSource::kGroundTruth;
  double sim_time_s = 0.0;
  std::uint64_t ticks = 0;
  std::uint64_t contact_fallbacks = 0;  ///< controller ticks finished with a fallback
  std::uint64_t qp_failures = 0;        ///< eq (33) not solved as posed
  std::uint64_t rejected_commands = 0;  ///< commands the simulator refused
  sim::RealityDraw reality;             ///< how the simulated robot differed from its model
  /// Compute time of each library's part of the tick, message conversions included: the
  /// estimator (sensors -> state), the contact optimiser (problem -> solution) and the controller
  /// (the rest of the tick).
  LatencyStats estimator_us, controller_us, contact_us;
  std::uint64_t invalid_messages = 0;  ///< contact problems or solutions that failed validation
  /// The robot side (as poise-sim's summary): ticks its safety layer spent in HOLD, in DAMP or
  /// E-STOP (damping), in E-STOP; its counters and final mode.
  std::uint64_t hold_ticks = 0, damping_ticks = 0, estop_ticks = 0;
  safety::Counters safety;
  safety::Mode safety_mode = safety::Mode::kStartup;
  double max_joint_speed = 0.0;  ///< largest |qd| of any joint over the run [rad/s | m/s]
  std::string fastest_joint;     ///< whose
  double wall_time_s = 0.0;      ///< wall time of the ticks (start-up excluded)
};

/// The contact method a loop with these options runs: LoopOptions::contact_method if set, else
/// the scenario's contact.method, else sequential. Throws std::runtime_error on an unknown name.
contact::Method contact_method_of(const scenario::Scenario& scenario, const LoopOptions& options);

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
  /// True once the run's duration is stepped (or the run was aborted).
  bool done() const;
  /// The topics' messages of the last control tick, as the nodes publish them: sensors, state,
  /// contact problem, contact solution and joint command of tick `tick`. `controlled` is false
  /// for a tick without a state (the estimator refused its frame: no state, no command).
  struct TickMessages {
    std::int64_t tick = -1;
    bool controlled = false;
    const msg::Sensors* sensors = nullptr;
    const msg::State* state = nullptr;
    const msg::ContactProblem* problem = nullptr;
    const msg::ContactSolution* solution = nullptr;
    const msg::JointCommand* command = nullptr;
  };
  TickMessages last_messages() const;
  /// Called with every balance reference the scenario's reference player sends (as
  /// poise-reference publishes them on poise/balance_reference); empty: none.
  void on_reference(std::function<void(const msg::BalanceReference&)> f) {
    reference_tap_ = std::move(f);
  }
  /// Steps until the run's duration; `progress` (may be empty) is called about once per
  /// simulated second with the current time. Returns result().
  RunResult run(const std::function<void(double)>& progress = {});
  /// Verdict and statistics of the ticks run so far.
  RunResult result() const;

  double time() const;
  double duration() const { return duration_; }
  /// Tick of the first control tick (after the start-up hold).
  std::int64_t first_tick() const { return first_tick_; }
  /// The balance reference used every tick (tests change it: CoM shift, upper-body motion).
  /// With a scenario `reference:` file, step() applies the player's references due at the tick
  /// first, as poise-controller applies those of poise-reference. The estimator's plan (its
  /// contact detector's prior) comes from the player's references only, as poise-estimator's
  /// comes from poise/balance_reference: foot modes set here directly reach the controller, not
  /// the estimator.
  controller::BalanceReference& reference() { return reference_; }
  const controller::BalanceController& controller() const { return *controller_; }
  sim::Simulator& simulator() { return *sim_; }
  const sim::GroundTruth& truth() const { return truth_; }
  const controller::RobotState& state() const { return state_; }
  const scenario::Scenario& scenario() const { return scenario_; }
  /// What the robot side's safety configuration warns about (as poise-sim logs at start: e.g. a
  /// hold gain the inertia bound keeps below gravity's stiffness).
  const std::vector<std::string>& safety_warnings() const;

 private:
  struct EstimatorParts;
  // Construction, phase by phase.
  controller::ControllerConfig controller_config() const;
  void map_joints_and_feet();
  void make_estimator();
  void make_messages_and_safety();
  void make_buffers_and_first_reference();
  void make_reference_player();
  void start_up();
  /// False when the estimator refused the frame (no state: poise-estimator sends none).
  bool read_state();
  void apply_references();
  void update_monitor();
  void after_step();
  void add_robot_side(RunResult& r) const;
  void play_reference();
  void control();
  void apply_safety_command(std::int64_t now_ns);
  /// The safety layer's clock: the simulated time [ns] (poise-sim uses its wall clock; in
  /// lockstep a command is applied as it arrives, so the watchdog never sees an age either way).
  std::int64_t clock_ns() const;

  scenario::Scenario scenario_;
  LoopOptions options_;
  double duration_ = 0.0;
  model::RobotConfig robot_;
  model::Model model_;
  std::unique_ptr<sim::Simulator> sim_;
  std::unique_ptr<controller::BalanceController> controller_;
  std::unique_ptr<EstimatorParts> estimator_;
  /// The scenario's `reference:` trajectory: the player poise-reference runs, fed the state of
  /// every tick; its references go to the controller's queue and the estimator's plan queue, as
  /// over DDS (null: no reference file).
  std::unique_ptr<reference::Player> reference_player_;
  /// poise-controller's reference queue and how it applies a reference (null: no reference file).
  std::unique_ptr<controller_node::ReferenceApplier> reference_applier_;
  bool have_handled_ = false;      // the controller handled a state before (its last tick below)
  std::uint64_t handled_tick_ = 0;
  contact::ContactOptimizer optimizer_;
  sim::ScenarioMonitor monitor_;

  std::vector<int> sim_to_model_;  // sim joint i -> model joint
  std::vector<int> model_to_sim_;  // model joint j -> sim joint
  std::array<int, 2> sim_foot_of_side_{-1, -1};
  std::array<int, 2> wire_feet_{-1, -1};  // sim_node::foot_order: message foot f -> sim foot
  std::int64_t first_tick_ = 0;
  std::int64_t steps_ = 0;            // control ticks of the run
  std::int64_t clock_offset_ns_ = 0;  // command waits that timed out (added to the safety clock)
  int consecutive_timeouts_ = 0;
  std::uint64_t command_timeouts_ = 0;
  bool aborted_ = false;

  // The topics' message types of one tick (what the nodes exchange).
  std::unique_ptr<msg::Sensors> sensors_msg_;
  std::unique_ptr<msg::State> state_msg_;
  std::unique_ptr<msg::GroundTruth> truth_msg_;  // the fields --ground-truth-state uses
  std::unique_ptr<msg::ContactProblem> problem_msg_;
  std::unique_ptr<msg::ContactSolution> solution_msg_;
  std::unique_ptr<msg::JointCommand> command_msg_;
  contact::ContactProblem problem_;         // the controller's (phase A)
  contact::ContactProblem solver_problem_;  // as the contact node decodes it
  contact::ContactSolution solution_;       // the optimiser's
  contact::ContactSolution answer_;         // as the controller node decodes it
  contact::Priority priority_ = contact::Priority::kLexicographic;  // poise-contact --priority
  contact::TorsionLimit torsion_ = contact::TorsionLimit::kIndependent;  // --torsion-limit
  std::unique_ptr<safety::SafetyLayer> safety_;

  sim::SensorFrame sensors_;
  sim::GroundTruth truth_;
  sim::JointCommand sim_command_;
  controller::RobotState state_;
  controller::BalanceReference reference_;
  controller::JointCommand command_;

  std::vector<double> latency_us_, estimator_us_, contact_us_;
  double contact_tick_us_ = 0.0;  // the contact optimiser's part of the tick being stepped
  std::int64_t last_tick_ = -1;   // the tick of the last control tick's messages
  bool last_controlled_ = false;
  std::uint64_t invalid_messages_ = 0;
  double max_joint_speed_ = 0.0;
  int fastest_joint_ = -1;  // sim joint
  std::function<void(const msg::BalanceReference&)> reference_tap_;
  std::uint64_t deadline_misses_ = 0;
  std::uint64_t rejected_commands_ = 0;
  std::chrono::steady_clock::duration wall_{};
  // The CoM target shifts of the played references, for the monitor (as poise-sim follows
  // poise/balance_reference).
  sim::ReferenceComShift com_shift_;
};

}  // namespace poise::inprocess
