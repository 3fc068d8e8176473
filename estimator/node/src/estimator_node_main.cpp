// poise-estimator: the state estimator (contact-aided invariant EKF, estimator/core) as a DDS node;
// --estimator leg-odometry publishes the leg-odometry baseline instead (estimator/README.md).
//
// ------------------------------------------------------------------------------------------------
// Contract
//   subscribes  poise/robot_description  RobotDescription  once at start (latched): joint order,
//                                                        and the sample period (control_period_s)
//               poise/sensors            Sensors           1 kHz  reliable, keep-last 1
//               poise/ground_truth       GroundTruth       only with --ground-truth-state (debug)
//               poise/balance_reference  BalanceReference  on change (latched, 512 held): the
//                                                           feet's planned modes, the contact
//                                                           detector's prior (off: --ignore-plan)
//   publishes   poise/state              State             one per sensor sample, same tick k
//                                                           reliable, keep-last 1
//               poise/diagnostics        Diagnostics       ~10 Hz best-effort, keep-last 1
//   repeats     a sensor sample with the tick just handled is answered with the same state again
//               (the simulator repeats tick 0 until the loop is connected)
//   faults      (table: idl/README.md "Fault semantics") a rejected sample gets NO state:
//               non-finite / over-long (DDS layer), joint_count other than the robot's, a tick
//               out of sequence (node::TickSequencer: a regression or a jump > --max-tick-jump is
//               rejected unless it restarts the stream: then the estimator re-initialises and
//               says so). No sensors for --input-stale-ms: health FAULT. IMU frozen: health
//               DEGRADED, kinematics-only fallback (status bit). Reasons in last_error.
//   threading   each sensor sample is handled on the DDS listener thread as it arrives (no
//               wake-up of a loop thread per tick); the main thread publishes the diagnostics.
//   plan        the plan of state k is that of the reference with the largest header tick <= k
//               (held until due, as poise-controller applies references: FootPlanQueue); before
//               any reference, and with --ignore-plan, no plan (the detector's rules alone).
//   debug       --ground-truth-state: base pose/twist, CoM and contacts copied from the
//               simulator's ground truth of the same tick (STATE_GROUND_TRUTH set). Off by default.
// ------------------------------------------------------------------------------------------------
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <poise/msg/balance_reference.h>

#include "poise/estimator/estimator.hpp"
#include "poise/estimator_node/estimator_messages.hpp"
#include "poise/estimator_node/foot_plan_queue.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/mailbox.hpp"
#include "poise/node/node.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/cli/parse.hpp"

namespace {

using namespace poise;

int run(int argc, char** argv) {
  node::NodeOptions options;
  bool ground_truth_state = false;
  int description_timeout_ms = 30000;
  int truth_timeout_ms = 200;
  std::string supports = "fixed";
  CLI::App app{"State estimator node: sensors k in, state k out."};
  node::add_node_options(app, options, "estimator");
  node::add_input_options(app, options);
  app.add_flag("--ground-truth-state", ground_truth_state,
               "DEBUG: copy the simulator's ground truth into the state (sets STATE_GROUND_TRUTH)");
  app.add_option("--description-timeout-ms", description_timeout_ms,
                 "how long to wait for the robot description at start")
      ->capture_default_str();
  app.add_option("--truth-timeout-ms", truth_timeout_ms,
                 "with --ground-truth-state: how long to wait for the ground truth of a tick")
      ->capture_default_str();
  app.add_option("--supports", supports,
                 "what the feet stand on: 'fixed' (static ground: the leg kinematics correct "
                 "velocity and tilt), 'moving' (supports that move in W by unknown amounts: "
                 "velocity and attitude from the IMU alone) or 'translating' (as moving, the "
                 "supports do not rotate: attitude from the stance feet); the supports must be "
                 "still for the first 2 s (IMU calibration); see estimator.hpp")
      ->check(CLI::IsMember({"fixed", "moving", "translating"}))
      ->capture_default_str();
  std::string kind = "invariant-ekf";
  app.add_option("--estimator", kind,
                 "which estimate the state carries: 'invariant-ekf' (contact-aided invariant EKF) "
                 "or 'leg-odometry' (baseline: IMU orientation, or the integrated gyro when the "
                 "IMU sends none, plus stance-foot kinematics; no filter, no bias estimate); "
                 "estimator/README.md compares them")
      ->check(CLI::IsMember({"invariant-ekf", "leg-odometry"}))
      ->capture_default_str();
  double ground_height = 0.0;
  app.add_option("--ground-height", ground_height,
                 "height in W of the ground the soles stand on at the start [m] (the lowest sole "
                 "in contact is put there)")
      ->check(CLI::Number)
      ->capture_default_str();
  std::vector<double> support_heights;
  app.add_option("--support-heights", support_heights,
                 "RIGHT LEFT: height in W of each foot's sole point at the start [m], for feet "
                 "on supports of their own (platforms); overrides --ground-height for feet in "
                 "contact")
      ->expected(2);
  std::vector<double> initial_xy;
  app.add_option("--initial-xy", initial_xy, "X Y: the base's start position in W [m]")
      ->expected(2);
  int frozen_imu_ticks = 100;
  app.add_option("--frozen-imu-ticks", frozen_imu_ticks,
                 "bit-identical IMU samples in a row that count as a frozen IMU (kinematics-only "
                 "fallback, health DEGRADED); 100 = 0.1 s keeps a still, coarsely quantised IMU "
                 "from being taken for a dead one")
      ->check(CLI::Range(2, 1000000))
      ->capture_default_str();
  bool ignore_plan = false;
  app.add_flag("--ignore-plan", ignore_plan,
               "do not subscribe to poise/balance_reference: contact from the sensors alone "
               "(no FOOT_SWING prior for the contact detector)");
  double contact_rest_time = estimator::EstimatorConfig{}.contact_rest_time;
  app.add_option("--contact-rest-time", contact_rest_time,
                 "contact detector's resting rule: a foot whose load stayed below 2 % of the "
                 "weight this long with its sole still, or that landed and never carried 2 % "
                 "this long since, keeps its contact until its sole leaves (the flag means "
                 "touching); 0: off, the flag drops below 1 % of the weight [s]")
      ->check(CLI::Range(0.0, 10.0))
      ->capture_default_str();
  double contact_ft_noise = estimator::EstimatorConfig{}.contact_ft_noise;
  app.add_option("--contact-ft-noise", contact_ft_noise,
                 "the foot F/T sensors' normal-force noise (1 sigma) for the contact detector's "
                 "light-touch rule: a touch too light for the 1 % load threshold is flagged from "
                 "its step in the reading, with the sole down where it stood (default: the "
                 "simulator's F/T, an industrial strain-gauge class); 0: the rule is off [N]")
      ->check(CLI::Range(0.0, 1.0e4))
      ->capture_default_str();
  int imu_delay_ticks = estimator::EstimatorConfig{}.imu_delay_ticks;
  app.add_option("--imu-delay-ticks", imu_delay_ticks,
                 "the IMU's output latency in ticks (its filters and transfer), used when the IMU "
                 "sits behind joints (a torso IMU behind a waist): its pose relative to the base "
                 "is then taken from the encoders of that many ticks earlier (estimator/README.md)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  double stance_rate_hz = estimator::EstimatorConfig{}.stance_rate_filter_hz;
  app.add_option("--stance-rate-hz", stance_rate_hz,
                 "cut-off of the complementary filter of the gyro and the stance feet's "
                 "kinematics for the published base angular velocity (a flat stance foot does "
                 "not turn; below the cut-off the gyro, above it the encoders); 0: the gyro "
                 "alone [Hz]")
      ->check(CLI::Range(0.0, 1.0e4))
      ->capture_default_str();
  POISE_CLI_PARSE(app, argc, argv);

  node::Node node(options);
  const msg::RobotDescription description =
      node::wait_for_robot_description(node, std::chrono::milliseconds(description_timeout_ms));
  const node::RobotFromDescription resolved = node::resolve_robot(node, description, options.robot);
  const model::RobotConfig& robot = resolved.config;
  const model::Model& model = resolved.model;
  const std::vector<int> model_to_wire =
      node::model_to_wire_map(description.joint_names(), model.joint_names);

  estimator::EstimatorConfig config;
  config.supports = estimator::parse_support_model(supports);
  config.frozen_imu_ticks = frozen_imu_ticks;
  config.contact_rest_time = contact_rest_time;
  config.contact_ft_noise = contact_ft_noise;
  config.imu_delay_ticks = imu_delay_ticks;
  config.stance_rate_filter_hz = stance_rate_hz;
  config.kind = estimator::parse_estimator_kind(kind);
  config.ground_height = ground_height;
  if (support_heights.size() == 2) config.support_height = {support_heights[0], support_heights[1]};
  if (initial_xy.size() == 2) {
    config.init_base_x = initial_xy[0];
    config.init_base_y = initial_xy[1];
  }
  for (double v : support_heights)
    if (!std::isfinite(v)) throw std::runtime_error("--support-heights: values must be finite");
  if (!std::isfinite(ground_height)) throw std::runtime_error("--ground-height must be finite");
  // The sample period is the robot's (a tick gap of g ticks propagates over g periods): a robot
  // at 500 Hz is integrated over 2 ms per tick, as the in-process loop does.
  if (description.control_period_s() > 0.0) config.dt = description.control_period_s();
  dds::log(dds::LogLevel::info, "sample period %.6g s (%s)", config.dt,
           description.control_period_s() > 0.0 ? "poise/robot_description"
                                                 : "not in the description: the 1 kHz default");
  estimator::Estimator estimator(model, robot, config);
  if (support_heights.size() == 2)
    dds::log(dds::LogLevel::info, "estimator: %s, start: right sole at z %.4f m, left sole %.4f m",
             estimator::to_string(config.kind), support_heights[0], support_heights[1]);
  else
    dds::log(dds::LogLevel::info, "estimator: %s, start: soles on the ground at z %.4f m",
             estimator::to_string(config.kind), ground_height);
  if (config.supports != estimator::SupportModel::kFixed)
    dds::log(dds::LogLevel::info,
             "supports: %s (stance contact points free after %.1f s of IMU calibration on still "
             "supports)",
             estimator::to_string(config.supports), config.moving_support_calibration);
  estimator::SensorFrame frame = estimator.make_sensor_frame();
  estimator::EstimatorState state = estimator.make_state();

  node::Mailbox<msg::GroundTruth> truth_box;
  std::unique_ptr<dds::Subscriber<msg::GroundTruth>> truths;
  if (ground_truth_state) {
    dds::log(dds::LogLevel::warn, "DEBUG --ground-truth-state: the state is the simulator's truth");
    truths = std::make_unique<dds::Subscriber<msg::GroundTruth>>(node.participant(),
                                                                 truth_box.callback());
    node.watch(*truths);
  }
  dds::Publisher<msg::State> states(node.participant());
  // The feet's planned modes, held until their tick (the contact detector's prior).
  constexpr std::size_t kPlanQueue = 512;
  estimator_node::FootPlanQueue plans(kPlanQueue);
  std::unique_ptr<dds::Subscriber<msg::BalanceReference>> references;
  if (!ignore_plan) {
    references = std::make_unique<dds::Subscriber<msg::BalanceReference>>(
        node.participant(),
        [&plans](const msg::BalanceReference& r) {
          plans.put(r.header().tick(),
                    {estimator::foot_plan_of_mode(static_cast<int>(r.feet()[0].mode())),
                     estimator::foot_plan_of_mode(static_cast<int>(r.feet()[1].mode()))});
        },
        dds::Qos::latched(static_cast<int>(kPlanQueue)));
    node.watch(*references);
  }

  msg::GroundTruth truth;
  msg::State out;
  std::uint64_t truth_seen = 0;
  std::uint64_t library_rejected = 0;
  node::TickSequencer sequencer(options.ticks);
  const int sensors_input = node.expect_input("poise/sensors", options.input_stale_ms);
  const std::size_t joints = model_to_wire.size();
  // One sensor sample: estimate, answer. Allocation-free; runs on one thread at a time.
  auto handle = [&](const msg::Sensors& in) noexcept {
    const std::uint64_t k = in.header().tick();
    if (in.joint_count() != joints) {
      node.error("tick %llu: poise/sensors joint_count %u, the robot has %zu joints: rejected, "
                 "no state sent",
                 static_cast<unsigned long long>(k), in.joint_count(), joints);
      return;
    }
    const std::int64_t t0 = node::now_ns();
    node.tick_begin();
    switch (sequencer.accept(k, t0)) {
      case node::TickSequencer::Verdict::kRepeat:  // repeated sample: same answer
        node.input_seen(sensors_input, k);
        node.publish(states, out);
        return;
      case node::TickSequencer::Verdict::kOutOfSequence:
        node.error("tick %llu out of sequence (last accepted %llu): rejected, no state sent",
                   static_cast<unsigned long long>(k),
                   static_cast<unsigned long long>(sequencer.last()));
        return;
      case node::TickSequencer::Verdict::kRestart:
        estimator.reset();
        library_rejected = 0;
        node.error("sensor stream restarted at tick %llu (previous %llu): estimator "
                   "re-initialised",
                   static_cast<unsigned long long>(k),
                   static_cast<unsigned long long>(sequencer.previous()));
        break;
      default:
        break;
    }
    node.input_seen(sensors_input, k);
    estimator_node::from_msg(in, model_to_wire, frame);
    frame.foot_plan = plans.at(k);
    const std::int64_t t_lib = node::now_ns();
    const estimator::StatusFlags flags = estimator.update(frame, state);
    const std::int64_t lib_ns = node::now_ns() - t_lib;
    if (estimator.diagnostics().rejected_frames != library_rejected) {
      library_rejected = estimator.diagnostics().rejected_frames;
      node.error("tick %llu: sensor frame rejected: %s: no state sent",
                 static_cast<unsigned long long>(k), estimator.diagnostics().last_error);
      return;
    }
    node.set_condition(msg::HEALTH_DEGRADED,
                       (flags & estimator::kImuFrozen)
                           ? "IMU frozen (bit-identical samples): base tracked by leg kinematics "
                             "only (STATE_IMU_FROZEN)"
                           : nullptr);
    estimator_node::to_msg(state, model_to_wire, out);
    if (ground_truth_state) {
      const std::int64_t deadline = node::now_ns() + std::int64_t{truth_timeout_ms} * 1'000'000;
      bool found = truth.header().tick() == k;
      while (!found && truth_box.wait(truth_seen, deadline))
        found = truth_box.take(truth, truth_seen) && truth.header().tick() == k;
      if (found)
        estimator_node::overwrite_with_ground_truth(truth, model.total_mass, out);
      else
        node.error("tick %llu: no ground truth of this tick: estimated state sent",
                   static_cast<unsigned long long>(k));
    }
    node.publish(states, out);
    node.tick_done(k, node::now_ns() - t0, lib_ns);
  };

  std::mutex state_mutex;
  node::Mailbox<msg::Sensors> sensor_box;
  std::unique_ptr<dds::Subscriber<msg::Sensors>> sensors;
  node.wait_for_output_readers(states);
  if (!ground_truth_state) {
    // Estimate on the DDS listener thread as the sample arrives (no hand-off to a loop thread).
    sensors = std::make_unique<dds::Subscriber<msg::Sensors>>(node.participant(),
                                                              [&](const msg::Sensors& in) {
                                                                std::lock_guard lock(state_mutex);
                                                                handle(in);
                                                              });
    node.watch(*sensors);
    node.expect_one_writer(*sensors);
    node.serve(state_mutex);
  } else {
    // Debug mode: the loop thread waits for the ground truth of the tick, which arrives on the
    // listener thread, so the sensors go through a mailbox.
    sensors =
        std::make_unique<dds::Subscriber<msg::Sensors>>(node.participant(), sensor_box.callback());
    node.watch(*sensors);
    node.expect_one_writer(*sensors);
    msg::Sensors in;
    std::uint64_t seen = 0;
    while (node.running()) {
      const std::int64_t next_diag = node.poll();
      if (!sensor_box.wait(seen, next_diag) || !sensor_box.take(in, seen)) continue;
      handle(in);
    }
  }
  std::lock_guard lock(state_mutex);
  const estimator::EstimatorDiagnostics& d = estimator.diagnostics();
  char extra[1024];
  std::snprintf(extra, sizeof(extra),
                "{\"state_source\": \"%s\", \"estimator\": \"%s\", \"supports\": \"%s\", "
                "\"filter_resets\": %llu, "
                "\"rejected_frames\": %llu, \"dropped_frames\": %llu, \"frozen_imu_ticks\": %llu, "
                "\"orientation_rejections\": %llu, \"stance_rate_hz\": %g, \"stance_rate_gated_ticks\": %llu, "
                "\"contact_ft_noise\": %g, \"contact_rest_time\": %g, \"imu_delay_ticks\": %d, "
                "\"out_of_sequence\": %llu, \"stream_restarts\": %llu, "
                "\"stale_events\": %llu, \"plans_received\": %llu, \"plan_overflows\": %llu}",
                ground_truth_state ? "ground_truth" : "estimator",
                estimator::to_string(config.kind), estimator::to_string(config.supports), static_cast<unsigned long long>(d.resets),
                static_cast<unsigned long long>(d.rejected_frames),
                static_cast<unsigned long long>(d.dropped_frames),
                static_cast<unsigned long long>(d.frozen_imu_ticks),
                static_cast<unsigned long long>(d.orientation_rejections),
                config.stance_rate_filter_hz,
                static_cast<unsigned long long>(d.stance_rate_gated_ticks),
                config.contact_ft_noise, config.contact_rest_time, config.imu_delay_ticks,
                static_cast<unsigned long long>(sequencer.rejected()),
                static_cast<unsigned long long>(sequencer.restarts()),
                static_cast<unsigned long long>(node.stale_events()),
                static_cast<unsigned long long>(plans.received()),
                static_cast<unsigned long long>(plans.overflows()));
  node.write_summary(extra);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-estimator: %s\n", e.what());
    return 2;
  }
}
