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

int run(int argc, char** argv) {
  node::NodeOptions options;
  std::string config_path;
  double deadline_us = 400.0;
  int description_timeout_ms = 30000, contact_wait_ms = 10000;
  CLI::App app{
      "Balance controller node: state k in, contact problem k out, contact solution k "
      "in, joint command k out."};
  node::add_node_options(app, options, "controller");
  node::add_input_options(app, options);
  int contact_stale_ticks = 20;
  app.add_option("--contact-stale-ticks", contact_stale_ticks,
                 "after this many ticks in a row without a contact solution, send no joint "
                 "command (the robot holds) until solutions come back")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--config", config_path, "controller YAML (default: the library's defaults)")
      ->check(CLI::ExistingFile);
  app.add_option("--contact-deadline-us", deadline_us,
                 "wait this long for the contact solution of a tick, then use the fallback "
                 "(400 us in real time; `poise run` uses 1 s in lockstep)")
      ->capture_default_str();
  app.add_option("--description-timeout-ms", description_timeout_ms,
                 "how long to wait for the robot description at start")
      ->capture_default_str();
  std::string planned_support = "auto";
  app.add_option("--planned-support", planned_support,
                 "the feet planned as supports until a balance reference says otherwise (paper "
                 "Fig. 6 input): double, left or right loads them from the first tick; auto "
                 "follows the state's contact flags (and measured load). `poise run` passes the "
                 "scenario's initial.support, as `poise run --in-process` plans it")
      ->check(CLI::IsMember({"auto", "double", "left", "right"}))
      ->capture_default_str();
  app.add_option("--contact-wait-ms", contact_wait_ms,
                 "how long to wait at start for the contact optimiser's endpoints")
      ->capture_default_str();
  POISE_CLI_PARSE(app, argc, argv);

  node::Node node(options);
  const msg::RobotDescription description =
      node::wait_for_robot_description(node, std::chrono::milliseconds(description_timeout_ms));
  const node::RobotFromDescription resolved = node::resolve_robot(node, description, options.robot);
  const model::RobotConfig& robot = resolved.config;
  const model::Model& model = resolved.model;
  controller::ControllerConfig config = config_path.empty()
                                            ? controller::ControllerConfig{}
                                            : controller::load_controller_config(config_path);
  // The control period is the robot's (as the in-process loop sets it from the simulator).
  if (description.control_period_s() > 0.0) config.dt = description.control_period_s();
  controller::BalanceController ctrl(model, robot, config);
  const std::vector<int> model_to_wire =
      node::model_to_wire_map(description.joint_names(), model.joint_names);

  controller::RobotState state = ctrl.make_state();
  controller::BalanceReference reference = ctrl.make_reference();
  if (planned_support != "auto") {
    for (int side = 0; side < 2; ++side) {
      const bool support = planned_support == "double" ||
                           (planned_support == "left") == (side == model::kLeft);
      reference.feet[side].mode =
          support ? controller::FootMode::kSupport : controller::FootMode::kSwing;
    }
  }
  controller::JointCommand command = ctrl.make_command();
  contact::ContactProblem problem;
  contact::ContactSolution solution;

  // Posture-target velocity of a reference trajectory played per tick (see the contract above).
  const double period_s =
      description.control_period_s() > 0.0 ? description.control_period_s() : 1e-3;
  controller_node::ReferenceApplier reference_applier(kReferenceQueue, model_to_wire, period_s);
  controller_node::ReferenceQueue& reference_queue = reference_applier.queue();
  dds::Subscriber<msg::BalanceReference> references(
      node.participant(), reference_queue.callback(),
      dds::Qos::latched(static_cast<int>(kReferenceQueue)));
  node.watch(references);
  dds::Publisher<msg::ContactProblem> problems(node.participant());
  dds::Publisher<msg::JointCommand> commands(node.participant());

  msg::ContactProblem problem_out;
  msg::JointCommand out;
  bool have_last = false;
  std::uint64_t last_tick = 0;
  bool last_answered = false;  // command last_tick was sent
  node::TickSequencer sequencer(options.ticks);
  const int state_input = node.expect_input("poise/state", options.input_stale_ms);
  int contact_misses = 0;  // ticks in a row without a contact solution
  std::uint64_t commands_withheld = 0;
  std::uint64_t problems_resent = 0;  // contact problems sent again on a repeated state
  // Start-up: until the optimiser has answered once, a tick waits --contact-wait-ms for its
  // solution (not the real-time deadline) and a newer state replaces it (see Contract).
  bool answered_once = false;
  std::uint64_t startup_skipped = 0;  // ticks replaced by a newer state before the first answer
  const std::int64_t start_wait_ns = std::int64_t{contact_wait_ms} * 1'000'000;
  static constexpr const char* kFallen =
      "the robot has fallen (fall.tilt_deg / fall.com_height_fraction): joints damped until the "
      "controller restarts";
  static constexpr const char* kSilent =
      "contact optimiser silent (no poise/contact_solution for --contact-stale-ticks ticks): no "
      "joint command sent, the robot holds";
  const auto n_joints = static_cast<Eigen::Index>(model_to_wire.size());
  const auto deadline_ns = static_cast<std::int64_t>(deadline_us * 1e3);

  // Threading: phase A runs in the state callback and phase B in the contact-solution callback,
  // on the DDS listener threads as the samples arrive (no wake-up of a loop thread per sample);
  // the main thread publishes the diagnostics and applies the fallback when the solution of the
  // pending tick is not there by its deadline. Everything below is guarded by `mutex`.
  std::mutex mutex;
  std::condition_variable wake;    // a pending deadline earlier than the main thread's wake-up
  std::int64_t main_wakes_at = 0;  // when the waiting main thread wakes up by itself
  struct Pending {
    bool active = false;  ///< problem k sent, command k not yet
    std::uint64_t k = 0;
    std::int64_t t0 = 0, t_sent = 0, deadline = 0;
    std::int64_t lib_ns = 0;  ///< library time of the tick (phases A and B)
    msg::Header header;
  } pending;
  bool started = false;  // setup complete: states are handled
  std::map<std::string, bool> robot_stops;  // robot side -> holds a stop (poise/estop_state)
  bool robot_stopped = false;               // any robot side holds one (see Contract: stops)
  bool fall_reported = false;  // the fall (FallConfig) has been logged
  // A state that cannot be handled yet (before the start, or while another tick is pending in
  // real time): the newest is kept and handled as soon as possible.
  auto held_state = std::make_unique<msg::State>();
  bool have_held = false;

  // Phase B (or the fallback, `answer` null) of the pending tick, then command k. Under `mutex`.
  std::function<void(const msg::ContactSolution*)> complete;
  // State k: references due, phase A, contact problem k out. Under `mutex`.
  auto handle_state = [&](const msg::State& in) noexcept {
    const std::uint64_t k = in.header().tick();
    if (pending.active) {
      if (k > pending.k && !answered_once) {
        // Start-up, no answer yet (see Contract): the newer state replaces the pending tick,
        // which gets no command (it would be stale); its problem may have been lost.
        pending.active = false;
        ++startup_skipped;
        if (++contact_misses >= contact_stale_ticks) node.set_condition(msg::HEALTH_FAULT, kSilent);
      } else {
        if (k > pending.k) {  // a newer tick: handled after the pending one
          *held_state = in;
          have_held = true;
        } else if (k == pending.k) {  // a repeat: problem k may have been lost (see Contract)
          node.publish(problems, problem_out);
          ++problems_resent;
        }
        return;  // an older tick: nothing
      }
    }
    if (in.joint_count() != static_cast<std::uint32_t>(n_joints)) {
      node.error("tick %llu: poise/state joint_count %u, the robot has %lld joints: rejected, "
                 "no command sent",
                 static_cast<unsigned long long>(k), in.joint_count(),
                 static_cast<long long>(n_joints));
      return;
    }
    const std::int64_t t0 = node::now_ns();
    node.tick_begin();  // both writes of the tick (problem, command) count until tick_done
    switch (sequencer.accept(k, t0)) {
      case node::TickSequencer::Verdict::kRepeat:  // repeated state: same answer
        node.input_seen(state_input, k);
        if (have_last && k == last_tick && last_answered) node.publish(commands, out);
        return;
      case node::TickSequencer::Verdict::kOutOfSequence:
        node.error("tick %llu out of sequence (last accepted %llu): rejected, no command sent",
                   static_cast<unsigned long long>(k),
                   static_cast<unsigned long long>(sequencer.last()));
        return;
      case node::TickSequencer::Verdict::kRestart:
        ctrl.reset();
        fall_reported = false;
        have_last = false;
        reference_applier.restart();
        node.error("state stream restarted at tick %llu (previous %llu): controller reset",
                   static_cast<unsigned long long>(k),
                   static_cast<unsigned long long>(sequencer.previous()));
        break;
      default:
        break;
    }
    node.input_seen(state_input, k);
    const auto due = reference_applier.apply(k, have_last, last_tick, reference);
    if (due.late > 0)
      node.error("tick %llu: %u balance reference(s) arrived after their tick",
                 static_cast<unsigned long long>(k), due.late);
    if (due.taken && !due.joints_applied)
      node.error("balance reference with joint_count %u (robot has %zu): joint targets ignored",
                 due.joint_count, model_to_wire.size());
    controller_node::from_msg(in, model_to_wire, state);
    if (robot_stopped) ctrl.reset();  // commands not applied: no open-loop references
    const std::int64_t t_lib = node::now_ns();
    ctrl.prepare(state, reference, problem);
    const std::int64_t lib_a = node::now_ns() - t_lib;
    contact_node::to_msg(problem, problem_out);
    problem_out.header(in.header());
    pending.active = true;
    pending.k = k;
    pending.t0 = t0;
    pending.header = in.header();
    pending.lib_ns = lib_a;
    const bool sent = node.publish(problems, problem_out);
    pending.t_sent = node::now_ns();
    pending.deadline = pending.t_sent + (answered_once ? deadline_ns : start_wait_ns);
    if (!sent)
      complete(nullptr);                        // nobody will answer: the fallback at once
    else if (pending.deadline < main_wakes_at)  // lockstep (1 s deadline): no wake-up per tick
      wake.notify_one();
  };
  complete = [&](const msg::ContactSolution* answer) noexcept {
    const std::int64_t t_back = node::now_ns();
    bool send = true;
    if (answer) {
      answered_once = true;
      contact_misses = 0;
      if (!ctrl.diagnostics().fallen) node.set_condition(msg::HEALTH_OK, nullptr);
      contact_node::from_msg(*answer, solution);
      const std::int64_t t_lib = node::now_ns();
      ctrl.finish(solution, command);
      pending.lib_ns += node::now_ns() - t_lib;
    } else {
      node.deadline_miss();
      if (++contact_misses >= contact_stale_ticks) {
        // The optimiser is gone: fallback wrenches do not balance a humanoid for long; the
        // robot's safety layer holds the posture better, and resumes with the next command.
        send = false;
        ++commands_withheld;
        node.set_condition(msg::HEALTH_FAULT, kSilent);
      } else {
        node.error("tick %llu: no contact solution within %.0f us: fallback wrenches",
                   static_cast<unsigned long long>(pending.k), deadline_us);
        ctrl.finish_fallback(command);
      }
    }
    if (ctrl.diagnostics().fallen) {
      // Latched until the controller restarts: the joints are damped (FallConfig).
      if (!fall_reported) {
        const controller::TickDiagnostics& d = ctrl.diagnostics();
        node.error("tick %lld: the robot has fallen (%s %.2f; fall.tilt_deg %.1f, "
                   "fall.com_height_fraction %.2f): balance stopped, joints damped until the "
                   "controller restarts",
                   static_cast<long long>(d.fall_tick), controller::to_string(d.fall_reason),
                   d.fall_reason == controller::FallReason::kTilt ? d.fall_tilt_deg
                                                                   : d.fall_com_height_fraction,
                   ctrl.config().fall.tilt_deg, ctrl.config().fall.com_height_fraction);
        fall_reported = true;
      }
      node.set_condition(msg::HEALTH_FAULT, kFallen);
    }
    if (send) {
      controller_node::to_msg(command, pending.header, model_to_wire, out);
      node.publish(commands, out);
    }
    last_answered = send;
    pending.active = false;
    have_last = true;
    last_tick = pending.k;
    // Own compute, not the wait for the contact optimiser.
    node.tick_done(pending.k, (pending.t_sent - pending.t0) + (node::now_ns() - t_back),
                   pending.lib_ns);
    if (have_held) {
      have_held = false;
      handle_state(*held_state);
    }
  };

  dds::Subscriber<msg::State> states(node.participant(), [&](const msg::State& in) {
    std::lock_guard lock(mutex);
    if (started) {
      handle_state(in);
    } else {  // kept until the setup is complete
      *held_state = in;
      have_held = true;
    }
  });
  dds::Subscriber<msg::ContactSolution> solutions(
      node.participant(), [&](const msg::ContactSolution& in) {
        std::lock_guard lock(mutex);
        // A solution of another tick (late, or of a tick already answered) is not used.
        if (pending.active && in.header().tick() == pending.k) complete(&in);
      });
  auto on_estop_state = [&](const msg::EStopState& in) {
    std::lock_guard lock(mutex);
    robot_stops[std::string(in.robot().c_str())] = in.engaged();
    bool any = false;
    for (const auto& [robot, engaged] : robot_stops)
      any = any || engaged;
    if (any == robot_stopped) return;
    robot_stopped = any;
    dds::log(dds::LogLevel::info,
             any ? "%s holds a stop: its commands are not applied, the integrated references "
                   "follow the measured state until the release"
                 : "%s released its stop: control resumes from the measured state",
             in.robot().c_str());
  };
  std::unique_ptr<dds::Subscriber<msg::EStopState>> estop_states;
  try {
    estop_states =
        std::make_unique<dds::Subscriber<msg::EStopState>>(node.participant(), on_estop_state);
  } catch (const std::exception& e) {
    // Security bundles made before the controller read this topic do not grant it.
    dds::log(dds::LogLevel::warn,
             "cannot read poise/estop_state (%s): a held stop is not seen, so the release of a "
             "protective stop may jump (regenerate the security bundles: poise security init)",
             e.what());
  }
  node.watch(states);
  node.watch(solutions);
  node.expect_one_writer(states);
  node.expect_one_writer(solutions);
  if (!problems.wait_for_matches(1, std::chrono::milliseconds(contact_wait_ms)) ||
      !solutions.wait_for_matches(1, std::chrono::milliseconds(contact_wait_ms)))
    dds::log(dds::LogLevel::warn,
             "no contact optimiser matched after %d ms: starting anyway "
             "(fallback wrenches until one answers)",
             contact_wait_ms);
  node.wait_for_output_readers(problems, commands);

  {
    std::unique_lock lock(mutex);
    started = true;
    if (have_held) {
      have_held = false;
      handle_state(*held_state);
    }
    while (node.running()) {
      const std::int64_t next_diag = node.poll();
      const std::int64_t now = node::now_ns();
      if (pending.active && now >= pending.deadline) {
        complete(nullptr);
        continue;
      }
      // A shutdown signal may go to another thread: wake at least every 50 ms to notice it.
      std::int64_t until = std::min(next_diag, now + 50'000'000);
      if (pending.active) until = std::min(until, pending.deadline);
      main_wakes_at = until;
      wake.wait_until(lock, std::chrono::steady_clock::time_point(std::chrono::nanoseconds(until)));
    }
  }
  std::lock_guard lock(mutex);
  const auto& d = ctrl.diagnostics();
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
                static_cast<unsigned long long>(reference_applier.applied()),
                static_cast<unsigned long long>(reference_queue.late()),
                static_cast<unsigned long long>(reference_queue.overflows()),
                static_cast<unsigned long long>(sequencer.rejected()),
                static_cast<unsigned long long>(sequencer.restarts()),
                static_cast<unsigned long long>(commands_withheld),
                static_cast<unsigned long long>(node.stale_events()),
                static_cast<unsigned long long>(problems_resent),
                static_cast<unsigned long long>(startup_skipped),
                static_cast<long long>(d.fallen ? d.fall_tick : -1),
                controller::describe_fall(d, ctrl.config().fall.tilt_deg,
                                          ctrl.config().fall.com_height_fraction)
                    .c_str());
  node.write_summary(extra);
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
