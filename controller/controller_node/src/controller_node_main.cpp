// poise-controller: the momentum-based balance controller (controller/momentum) as a DDS node.
//
// ------------------------------------------------------------------------------------------------
// Contract
//   subscribes  poise/robot_description   RobotDescription  once at start (latched): joint order
//               poise/state               State             1 kHz  reliable, keep-last 1
//               poise/balance_reference   BalanceReference  on change (latched, reader keeps up
//                                                           to 512); default: stand
//               poise/contact_solution    ContactSolution   one per problem, tick k
//               poise/estop_state         EStopState        each robot side's stop (latched)
//   publishes   poise/contact_problem     ContactProblem    one per state, tick k
//               poise/joint_command       JointCommand      one per state, tick k
//               poise/diagnostics         Diagnostics       ~10 Hz best-effort (compute time per
//                                                           tick, contact deadline misses)
//   one tick    state k -> phase A (eqs 10-11, supports, eq 36) -> contact problem k -> wait for
//               contact solution k until --contact-deadline-us after the problem was sent ->
//               phase B (eq 33, inverse dynamics, PD references), or the library's fallback on a
//               miss (counted as a deadline miss) -> joint command k
//   faults      (table: idl/README.md "Fault semantics") a rejected state gets NO command:
//               joint_count other than the robot's, a tick out of sequence (node::TickSequencer;
//               a restarted state stream is followed: the controller resets and says so). No
//               state for --input-stale-ms: health FAULT. No contact solution for
//               --contact-stale-ticks ticks in a row: NO joint command is sent (the robot's
//               safety layer holds the posture; the fallback wrenches are for isolated misses
//               only), health FAULT, until solutions come back.
//   stops       while a robot side holds a stop (poise/estop_state engaged, either kind) it
//               applies none of these commands: the references theta*, theta_dot* (eqs 34-35,
//               integrated open loop from the accelerations) would drift from the held robot to
//               their clamps and come back as a jump on the release. So every tick restarts them
//               from the measured state (BalanceController::reset) until the stop is released.
//               Kept per robot side by name: a robot side restarted under its name clears its
//               stop with the state it announces at start; one that dies holding a stop and
//               never returns leaves the references following the measured state (control
//               goes on, without the integrated references) until this controller restarts.
//   repeats     a state with the tick just handled is answered with the same command again; one
//               with the tick still waiting for its contact solution sends contact problem k
//               again (the deadline is not moved): at start-up the optimiser's reader may discover
//               this writer after the writer discovered it, and the first problem is then lost
//               (the simulator repeats tick 0 in lockstep until it has a command, so a lost
//               problem costs a repeat, not a fallback); the optimiser answers each copy the same
//               and the first answer is used. States that arrive before the start-up is complete
//               are kept (the newest)
//   start-up    until the optimiser has answered once, no fallback wrenches: a tick waits up to
//               --contact-wait-ms for its solution (the real-time deadline applies from the
//               first answer on), and a newer state replaces the pending tick (no command for
//               it: it would be stale; counted as startup_skipped, and as a contact miss towards
//               --contact-stale-ticks). So a loop whose optimiser has not yet matched the
//               controller's writer sends nothing (the robot's safety layer holds) rather than
//               fallback wrenches, and `poise-sim --start-when-answered` starts its clock on an
//               answer computed with a contact solution
//   threading   phase A runs in the state callback, phase B in the contact-solution callback, on
//               the DDS listener threads as the samples arrive (no loop-thread wake-up per
//               sample), under one mutex; the main thread publishes the diagnostics and applies
//               the fallback when the solution is not there by the deadline
//   references  applied by header tick: state k takes every reference with 0 < tick <= k (or
//               tick 0 = at once) and applies the one with the largest tick; a reference sent
//               ahead of its tick (`poise reference play` sends them --lead-ticks ahead) is
//               applied exactly at its tick, also in lockstep. One arriving after the state of
//               its tick was handled is applied at the next state and counted (late_references,
//               an error). The IDL has no posture-target velocity: when the reference applied at
//               tick t follows one for tick t-1 (a trajectory played per tick), upper_body_qd is
//               their difference over the control period, else zero.
// ------------------------------------------------------------------------------------------------
#include <CLI/CLI.hpp>

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>

#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/estop_state.h>

#include "poise/contact_node/contact_messages.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/controller_node/controller_messages.hpp"
#include "poise/controller_node/reference_applier.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/node.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/cli/parse.hpp"

namespace {

using namespace poise;

constexpr std::size_t kReferenceQueue = 512;  // references held ahead of their tick

constexpr const char* kFallen =
    "the robot has fallen (fall.tilt_deg / fall.com_height_fraction): joints damped until the "
    "controller restarts";
constexpr const char* kSilent =
    "contact optimiser silent (no poise/contact_solution for --contact-stale-ticks ticks): no "
    "joint command sent, the robot holds";

/// The command line.
struct Options {
  node::NodeOptions node;
  std::string config_path;
  double deadline_us = 400.0;
  int description_timeout_ms = 30000, contact_wait_ms = 10000;
  int contact_stale_ticks = 20;
  std::string planned_support = "auto";
};

/// Parses the command line into `o`. Returns the exit status when the command line ends the run
/// (0 after --help, 2 for a usage error), else -1.
int parse_options(int argc, char** argv, Options& o) {
  CLI::App app{
      "Balance controller node: state k in, contact problem k out, contact solution k "
      "in, joint command k out."};
  node::add_node_options(app, o.node, "controller");
  node::add_input_options(app, o.node);
  app.add_option("--contact-stale-ticks", o.contact_stale_ticks,
                 "after this many ticks in a row without a contact solution, send no joint "
                 "command (the robot holds) until solutions come back")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--config", o.config_path, "controller YAML (default: the library's defaults)")
      ->check(CLI::ExistingFile);
  app.add_option("--contact-deadline-us", o.deadline_us,
                 "wait this long for the contact solution of a tick, then use the fallback "
                 "(400 us in real time; `poise run` uses 1 s in lockstep)")
      ->capture_default_str();
  app.add_option("--description-timeout-ms", o.description_timeout_ms,
                 "how long to wait for the robot description at start")
      ->capture_default_str();
  app.add_option("--planned-support", o.planned_support,
                 "the feet planned as supports until a balance reference says otherwise (paper "
                 "Fig. 6 input): double, left or right loads them from the first tick; auto "
                 "follows the state's contact flags (and measured load). `poise run` passes the "
                 "scenario's initial.support, as `poise run --in-process` plans it")
      ->check(CLI::IsMember({"auto", "double", "left", "right"}))
      ->capture_default_str();
  app.add_option("--contact-wait-ms", o.contact_wait_ms,
                 "how long to wait at start for the contact optimiser's endpoints")
      ->capture_default_str();
  POISE_CLI_PARSE(app, argc, argv);
  return -1;
}

/// The controller YAML (or the library's defaults) at the robot's control period.
controller::ControllerConfig load_config(const std::string& path,
                                         const msg::RobotDescription& description) {
  controller::ControllerConfig config =
      path.empty() ? controller::ControllerConfig{} : controller::load_controller_config(path);
  // The control period is the robot's (as the in-process loop sets it from the simulator).
  if (description.control_period_s() > 0.0) config.dt = description.control_period_s();
  return config;
}

/// The standing reference, with the feet --planned-support names as supports (auto: the
/// library's automatic feet).
controller::BalanceReference planned_reference(const controller::BalanceController& ctrl,
                                               const std::string& planned_support) {
  controller::BalanceReference reference = ctrl.make_reference();
  if (planned_support != "auto") {
    for (int side = 0; side < 2; ++side) {
      const bool support =
          planned_support == "double" || (planned_support == "left") == (side == model::kLeft);
      reference.feet[side].mode =
          support ? controller::FootMode::kSupport : controller::FootMode::kSwing;
    }
  }
  return reference;
}

/// The controller node: its endpoints, the controller and the state of the tick in flight.
/// Threading: phase A runs in the state callback and phase B in the contact-solution callback,
/// on the DDS listener threads as the samples arrive (no wake-up of a loop thread per sample);
/// the main thread publishes the diagnostics and applies the fallback when the solution of the
/// pending tick is not there by its deadline. The tick's state is guarded by `mutex_`.
class ControllerNode {
 public:
  /// Waits for the robot description, builds the controller and the endpoints.
  explicit ControllerNode(const Options& o);
  /// Start-up: waits for the contact optimiser's endpoints and the outputs' readers.
  void wait_for_peers();
  /// Handles states from now on; the main thread's loop (diagnostics, deadlines) until shutdown.
  void serve();
  /// The summary file's extra figures.
  void write_summary();

 private:
  // ---- the tick (under mutex_; allocation-free) --------------------------------------------
  void on_state(const msg::State& in);
  void on_solution(const msg::ContactSolution& in);
  void handle_state(const msg::State& in) noexcept;
  bool defer_while_pending(const msg::State& in) noexcept;
  bool accept_tick(std::uint64_t k, std::int64_t t0) noexcept;
  void apply_due_references(std::uint64_t k) noexcept;
  void prepare_and_send_problem(const msg::Header& header, std::uint64_t k,
                                std::int64_t t0) noexcept;
  void complete(const msg::ContactSolution* answer) noexcept;
  bool finish_with_solution(const msg::ContactSolution& answer) noexcept;
  bool finish_without_solution() noexcept;
  void report_fall() noexcept;
  void handle_held_state() noexcept;
  // ---- robot sides' stops ---------------------------------------------------------------------
  void subscribe_estop_state();
  void on_estop_state(const msg::EStopState& in);

  const Options o_;
  node::Node node_;
  const msg::RobotDescription description_;
  const node::RobotFromDescription resolved_;
  controller::BalanceController ctrl_;
  const std::vector<int> model_to_wire_;
  controller::RobotState state_;
  controller::BalanceReference reference_;
  controller::JointCommand command_;
  contact::ContactProblem problem_;
  contact::ContactSolution solution_;
  // Posture-target velocity of a reference trajectory played per tick (see the contract above).
  controller_node::ReferenceApplier reference_applier_;
  dds::Subscriber<msg::BalanceReference> references_;
  dds::Publisher<msg::ContactProblem> problems_;
  dds::Publisher<msg::JointCommand> commands_;

  msg::ContactProblem problem_out_;
  msg::JointCommand out_;
  bool have_last_ = false;
  std::uint64_t last_tick_ = 0;
  bool last_answered_ = false;  // command last_tick_ was sent
  node::TickSequencer sequencer_;
  const int state_input_;
  int contact_misses_ = 0;  // ticks in a row without a contact solution
  std::uint64_t commands_withheld_ = 0;
  std::uint64_t problems_resent_ = 0;  // contact problems sent again on a repeated state
  // Start-up: until the optimiser has answered once, a tick waits --contact-wait-ms for its
  // solution (not the real-time deadline) and a newer state replaces it (see Contract).
  bool answered_once_ = false;
  std::uint64_t startup_skipped_ = 0;  // ticks replaced by a newer state before the first answer
  const std::int64_t start_wait_ns_;
  const Eigen::Index n_joints_;
  const std::int64_t deadline_ns_;

  std::mutex mutex_;
  std::condition_variable wake_;    // a pending deadline earlier than the main thread's wake-up
  std::int64_t main_wakes_at_ = 0;  // when the waiting main thread wakes up by itself
  struct Pending {
    bool active = false;  ///< problem k sent, command k not yet
    std::uint64_t k = 0;
    std::int64_t t0 = 0, t_sent = 0, deadline = 0;
    std::int64_t lib_ns = 0;  ///< library time of the tick (phases A and B)
    msg::Header header;
  } pending_;
  bool started_ = false;                     // setup complete: states are handled
  std::map<std::string, bool> robot_stops_;  // robot side -> holds a stop (poise/estop_state)
  bool robot_stopped_ = false;               // any robot side holds one (see Contract: stops)
  bool fall_reported_ = false;               // the fall (FallConfig) has been logged
  // A state that cannot be handled yet (before the start, or while another tick is pending in
  // real time): the newest is kept and handled as soon as possible.
  std::unique_ptr<msg::State> held_state_;
  bool have_held_ = false;

  dds::Subscriber<msg::State> states_;
  dds::Subscriber<msg::ContactSolution> solutions_;
  std::unique_ptr<dds::Subscriber<msg::EStopState>> estop_states_;
};

ControllerNode::ControllerNode(const Options& o)
    : o_(o),
      node_(o.node),
      description_(node::wait_for_robot_description(
          node_, std::chrono::milliseconds(o.description_timeout_ms))),
      resolved_(node::resolve_robot(node_, description_, o.node.robot)),
      ctrl_(resolved_.model, resolved_.config, load_config(o.config_path, description_)),
      model_to_wire_(
          node::model_to_wire_map(description_.joint_names(), resolved_.model.joint_names)),
      state_(ctrl_.make_state()),
      reference_(planned_reference(ctrl_, o.planned_support)),
      command_(ctrl_.make_command()),
      reference_applier_(
          kReferenceQueue, model_to_wire_,
          description_.control_period_s() > 0.0 ? description_.control_period_s() : 1e-3),
      references_(node_.participant(), reference_applier_.queue().callback(),
                  dds::Qos::latched(static_cast<int>(kReferenceQueue))),
      problems_(node_.participant()),
      commands_(node_.participant()),
      sequencer_(o.node.ticks),
      state_input_(node_.expect_input("poise/state", o.node.input_stale_ms)),
      start_wait_ns_(std::int64_t{o.contact_wait_ms} * 1'000'000),
      n_joints_(static_cast<Eigen::Index>(model_to_wire_.size())),
      deadline_ns_(static_cast<std::int64_t>(o.deadline_us * 1e3)),
      held_state_(std::make_unique<msg::State>()),
      states_(node_.participant(), [this](const msg::State& in) { on_state(in); }),
      solutions_(node_.participant(), [this](const msg::ContactSolution& in) { on_solution(in); }) {
  node_.watch(references_);
  subscribe_estop_state();
}

void ControllerNode::on_state(const msg::State& in) {
  std::lock_guard lock(mutex_);
  if (started_) {
    handle_state(in);
  } else {  // kept until the setup is complete
    *held_state_ = in;
    have_held_ = true;
  }
}

void ControllerNode::on_solution(const msg::ContactSolution& in) {
  std::lock_guard lock(mutex_);
  // A solution of another tick (late, or of a tick already answered) is not used.
  if (pending_.active && in.header().tick() == pending_.k) complete(&in);
}

// State k: references due, phase A, contact problem k out. Under `mutex_`.
void ControllerNode::handle_state(const msg::State& in) noexcept {
  if (pending_.active && defer_while_pending(in)) return;
  const std::uint64_t k = in.header().tick();
  if (in.joint_count() != static_cast<std::uint32_t>(n_joints_)) {
    node_.error("tick %llu: poise/state joint_count %u, the robot has %lld joints: rejected, "
                "no command sent",
                static_cast<unsigned long long>(k), in.joint_count(),
                static_cast<long long>(n_joints_));
    return;
  }
  const std::int64_t t0 = node::now_ns();
  node_.tick_begin();  // both writes of the tick (problem, command) count until tick_done
  if (!accept_tick(k, t0)) return;
  apply_due_references(k);
  controller_node::from_msg(in, model_to_wire_, state_);
  if (robot_stopped_) ctrl_.reset();  // commands not applied: no open-loop references
  prepare_and_send_problem(in.header(), k, t0);
}

// A state while tick pending_.k waits for its contact solution. True when the state is dealt
// with here (kept for later, a repeat answered, an older tick ignored); false when it is handled
// now, the pending tick given up.
bool ControllerNode::defer_while_pending(const msg::State& in) noexcept {
  const std::uint64_t k = in.header().tick();
  if (k > pending_.k && !answered_once_) {
    // Start-up, no answer yet (see Contract): the newer state replaces the pending tick,
    // which gets no command (it would be stale); its problem may have been lost.
    pending_.active = false;
    ++startup_skipped_;
    if (++contact_misses_ >= o_.contact_stale_ticks)
      node_.set_condition(msg::HEALTH_FAULT, kSilent);
    return false;
  }
  if (k > pending_.k) {  // a newer tick: handled after the pending one
    *held_state_ = in;
    have_held_ = true;
  } else if (k == pending_.k) {  // a repeat: problem k may have been lost (see Contract)
    node_.publish(problems_, problem_out_);
    ++problems_resent_;
  }
  return true;  // an older tick: nothing
}

// The tick sequencer's verdict on state k. False when the state is dealt with here (a repeat
// answered with the same command, a tick out of sequence rejected).
bool ControllerNode::accept_tick(std::uint64_t k, std::int64_t t0) noexcept {
  switch (sequencer_.accept(k, t0)) {
    case node::TickSequencer::Verdict::kRepeat:  // repeated state: same answer
      node_.input_seen(state_input_, k);
      if (have_last_ && k == last_tick_ && last_answered_) node_.publish(commands_, out_);
      return false;
    case node::TickSequencer::Verdict::kOutOfSequence:
      node_.error("tick %llu out of sequence (last accepted %llu): rejected, no command sent",
                  static_cast<unsigned long long>(k),
                  static_cast<unsigned long long>(sequencer_.last()));
      return false;
    case node::TickSequencer::Verdict::kRestart:
      ctrl_.reset();
      fall_reported_ = false;
      have_last_ = false;
      reference_applier_.restart();
      node_.error("state stream restarted at tick %llu (previous %llu): controller reset",
                  static_cast<unsigned long long>(k),
                  static_cast<unsigned long long>(sequencer_.previous()));
      break;
    default:
      break;
  }
  node_.input_seen(state_input_, k);
  return true;
}

// The balance references due at state k into reference_ (see Contract: references).
void ControllerNode::apply_due_references(std::uint64_t k) noexcept {
  const auto due = reference_applier_.apply(k, have_last_, last_tick_, reference_);
  if (due.late > 0)
    node_.error("tick %llu: %u balance reference(s) arrived after their tick",
                static_cast<unsigned long long>(k), due.late);
  if (due.taken && !due.joints_applied)
    node_.error("balance reference with joint_count %u (robot has %zu): joint targets ignored",
                due.joint_count, model_to_wire_.size());
}

// Phase A of state k (eqs 10-11, supports, eq 36), contact problem k out; tick k then waits for
// its solution until its deadline.
void ControllerNode::prepare_and_send_problem(const msg::Header& header, std::uint64_t k,
                                              std::int64_t t0) noexcept {
  const std::int64_t t_lib = node::now_ns();
  ctrl_.prepare(state_, reference_, problem_);
  const std::int64_t lib_a = node::now_ns() - t_lib;
  contact_node::to_msg(problem_, problem_out_);
  problem_out_.header(header);
  pending_.active = true;
  pending_.k = k;
  pending_.t0 = t0;
  pending_.header = header;
  pending_.lib_ns = lib_a;
  const bool sent = node_.publish(problems_, problem_out_);
  pending_.t_sent = node::now_ns();
  pending_.deadline = pending_.t_sent + (answered_once_ ? deadline_ns_ : start_wait_ns_);
  if (!sent)
    complete(nullptr);                          // nobody will answer: the fallback at once
  else if (pending_.deadline < main_wakes_at_)  // lockstep (1 s deadline): no wake-up per tick
    wake_.notify_one();
}

// Phase B (or the fallback, `answer` null) of the pending tick, then command k. Under `mutex_`.
void ControllerNode::complete(const msg::ContactSolution* answer) noexcept {
  const std::int64_t t_back = node::now_ns();
  const bool send = answer ? finish_with_solution(*answer) : finish_without_solution();
  if (ctrl_.diagnostics().fallen) report_fall();
  if (send) {
    controller_node::to_msg(command_, pending_.header, model_to_wire_, out_);
    node_.publish(commands_, out_);
  }
  last_answered_ = send;
  pending_.active = false;
  have_last_ = true;
  last_tick_ = pending_.k;
  // Own compute, not the wait for the contact optimiser.
  node_.tick_done(pending_.k, (pending_.t_sent - pending_.t0) + (node::now_ns() - t_back),
                  pending_.lib_ns);
  handle_held_state();
}

// Phase B (eq 33, inverse dynamics, PD references) with the optimiser's solution. True: the
// command is sent.
bool ControllerNode::finish_with_solution(const msg::ContactSolution& answer) noexcept {
  answered_once_ = true;
  contact_misses_ = 0;
  if (!ctrl_.diagnostics().fallen) node_.set_condition(msg::HEALTH_OK, nullptr);
  contact_node::from_msg(answer, solution_);
  const std::int64_t t_lib = node::now_ns();
  ctrl_.finish(solution_, command_);
  pending_.lib_ns += node::now_ns() - t_lib;
  return true;
}

// No solution by the deadline: the library's fallback wrenches, or no command once the optimiser
// has been silent for --contact-stale-ticks ticks. True: the command is sent.
bool ControllerNode::finish_without_solution() noexcept {
  node_.deadline_miss();
  if (++contact_misses_ >= o_.contact_stale_ticks) {
    // The optimiser is gone: fallback wrenches do not balance a humanoid for long; the
    // robot's safety layer holds the posture better, and resumes with the next command.
    ++commands_withheld_;
    node_.set_condition(msg::HEALTH_FAULT, kSilent);
    return false;
  }
  node_.error("tick %llu: no contact solution within %.0f us: fallback wrenches",
              static_cast<unsigned long long>(pending_.k), o_.deadline_us);
  ctrl_.finish_fallback(command_);
  return true;
}

// Latched until the controller restarts: the joints are damped (FallConfig).
void ControllerNode::report_fall() noexcept {
  if (!fall_reported_) {
    const controller::TickDiagnostics& d = ctrl_.diagnostics();
    node_.error("tick %lld: the robot has fallen (%s %.2f; fall.tilt_deg %.1f, "
                "fall.com_height_fraction %.2f): balance stopped, joints damped until the "
                "controller restarts",
                static_cast<long long>(d.fall_tick), controller::to_string(d.fall_reason),
                d.fall_reason == controller::FallReason::kTilt ? d.fall_tilt_deg
                                                                : d.fall_com_height_fraction,
                ctrl_.config().fall.tilt_deg, ctrl_.config().fall.com_height_fraction);
    fall_reported_ = true;
  }
  node_.set_condition(msg::HEALTH_FAULT, kFallen);
}

// The state kept while it could not be handled, now.
void ControllerNode::handle_held_state() noexcept {
  if (have_held_) {
    have_held_ = false;
    handle_state(*held_state_);
  }
}

void ControllerNode::subscribe_estop_state() {
  try {
    estop_states_ = std::make_unique<dds::Subscriber<msg::EStopState>>(
        node_.participant(), [this](const msg::EStopState& in) { on_estop_state(in); });
  } catch (const std::exception& e) {
    // Security bundles made before the controller read this topic do not grant it.
    dds::log(dds::LogLevel::warn,
             "cannot read poise/estop_state (%s): a held stop is not seen, so the release of a "
             "protective stop may jump (regenerate the security bundles: poise security init)",
             e.what());
  }
}

// A robot side's stop (see Contract: stops).
void ControllerNode::on_estop_state(const msg::EStopState& in) {
  std::lock_guard lock(mutex_);
  robot_stops_[std::string(in.robot().c_str())] = in.engaged();
  bool any = false;
  for (const auto& [robot, engaged] : robot_stops_)
    any = any || engaged;
  if (any == robot_stopped_) return;
  robot_stopped_ = any;
  dds::log(dds::LogLevel::info,
           any ? "%s holds a stop: its commands are not applied, the integrated references "
                 "follow the measured state until the release"
               : "%s released its stop: control resumes from the measured state",
           in.robot().c_str());
}

void ControllerNode::wait_for_peers() {
  node_.watch(states_);
  node_.watch(solutions_);
  node_.expect_one_writer(states_);
  node_.expect_one_writer(solutions_);
  if (!problems_.wait_for_matches(1, std::chrono::milliseconds(o_.contact_wait_ms)) ||
      !solutions_.wait_for_matches(1, std::chrono::milliseconds(o_.contact_wait_ms)))
    dds::log(dds::LogLevel::warn,
             "no contact optimiser matched after %d ms: starting anyway "
             "(fallback wrenches until one answers)",
             o_.contact_wait_ms);
  node_.wait_for_output_readers(problems_, commands_);
}

void ControllerNode::serve() {
  std::unique_lock lock(mutex_);
  started_ = true;
  handle_held_state();
  while (node_.running()) {
    const std::int64_t next_diag = node_.poll();
    const std::int64_t now = node::now_ns();
    if (pending_.active && now >= pending_.deadline) {
      complete(nullptr);
      continue;
    }
    // A shutdown signal may go to another thread: wake at least every 50 ms to notice it.
    std::int64_t until = std::min(next_diag, now + 50'000'000);
    if (pending_.active) until = std::min(until, pending_.deadline);
    main_wakes_at_ = until;
    wake_.wait_until(lock, std::chrono::steady_clock::time_point(std::chrono::nanoseconds(until)));
  }
}

void ControllerNode::write_summary() {
  std::lock_guard lock(mutex_);
  const auto& d = ctrl_.diagnostics();
  const controller_node::ReferenceQueue& reference_queue = reference_applier_.queue();
  char extra[1024];
  std::snprintf(extra, sizeof(extra),
                "{\"late_solutions\": %llu, \"qp_failures\": %llu, \"controller_ticks\": %llu, "
                "\"references_received\": %llu, \"references_applied\": %llu, "
                "\"late_references\": %llu, \"reference_overflows\": %llu, \"out_of_sequence\": %llu, "
                "\"stream_restarts\": %llu, \"commands_withheld\": %llu, \"stale_events\": %llu, "
                "\"problems_resent\": %llu, \"startup_skipped\": %llu, \"fall_tick\": %lld, "
                "\"fall\": \"%s\"}",
                static_cast<unsigned long long>(d.late_solutions),
                static_cast<unsigned long long>(d.qp_failures),
                static_cast<unsigned long long>(d.ticks),
                static_cast<unsigned long long>(reference_queue.received()),
                static_cast<unsigned long long>(reference_applier_.applied()),
                static_cast<unsigned long long>(reference_queue.late()),
                static_cast<unsigned long long>(reference_queue.overflows()),
                static_cast<unsigned long long>(sequencer_.rejected()),
                static_cast<unsigned long long>(sequencer_.restarts()),
                static_cast<unsigned long long>(commands_withheld_),
                static_cast<unsigned long long>(node_.stale_events()),
                static_cast<unsigned long long>(problems_resent_),
                static_cast<unsigned long long>(startup_skipped_),
                static_cast<long long>(d.fallen ? d.fall_tick : -1),
                controller::describe_fall(d, ctrl_.config().fall.tilt_deg,
                                          ctrl_.config().fall.com_height_fraction)
                    .c_str());
  node_.write_summary(extra);
}

int run(int argc, char** argv) {
  Options o;
  if (const int status = parse_options(argc, argv, o); status >= 0) return status;
  ControllerNode controller(o);
  controller.wait_for_peers();
  controller.serve();
  controller.write_summary();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-controller: %s\n", e.what());
    return 2;
  }
}
