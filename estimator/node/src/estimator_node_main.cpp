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
#include <string_view>
#include <vector>

#include <poise/msg/balance_reference.h>

#include "poise/estimator/estimator.hpp"
#include "poise/estimator/settings.hpp"
#include "poise/estimator_node/estimator_messages.hpp"
#include "poise/estimator_node/foot_plan_queue.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/mailbox.hpp"
#include "poise/node/node.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/cli/parse.hpp"

namespace {

using namespace poise;

/// The command line.
struct Options {
  node::NodeOptions node;
  bool ground_truth_state = false;
  int description_timeout_ms = 30000;
  int truth_timeout_ms = 200;
  std::string supports = "fixed";
  std::string kind = "invariant-ekf";
  double ground_height = 0.0;
  std::vector<double> support_heights;
  std::vector<double> initial_xy;
  int frozen_imu_ticks = 100;
  bool ignore_plan = false;
  double contact_rest_time = estimator::EstimatorConfig{}.contact_rest_time;
  double contact_ft_noise = estimator::EstimatorConfig{}.contact_ft_noise;
  int imu_delay_ticks = estimator::EstimatorConfig{}.imu_delay_ticks;
  double stance_rate_hz = estimator::EstimatorConfig{}.stance_rate_filter_hz;
};

/// The names a setting allows (settings.hpp: the scenario's `estimator:` section checks the same).
std::vector<std::string> choices_of(const estimator::NameSetting& s) {
  std::vector<std::string> out;
  for (const std::string_view c : s.choices)
    if (!c.empty()) out.emplace_back(c);
  return out;
}

/// The bounds of a numeric setting (settings.hpp), as a command-line check.
CLI::Range range_of(const estimator::NumberSetting& s) { return CLI::Range(s.lo, s.hi); }
CLI::Range whole_range_of(const estimator::NumberSetting& s) {
  return CLI::Range(static_cast<int>(s.lo), static_cast<int>(s.hi));
}

/// The options of the estimate's start and of what the feet stand on.
void add_start_options(CLI::App& app, Options& o) {
  app.add_option("--supports", o.supports,
                 "what the feet stand on: 'fixed' (static ground: the leg kinematics correct "
                 "velocity and tilt), 'moving' (supports that move in W by unknown amounts: "
                 "velocity and attitude from the IMU alone) or 'translating' (as moving, the "
                 "supports do not rotate: attitude from the stance feet); the supports must be "
                 "still for the first 2 s (IMU calibration); see estimator.hpp")
      ->check(CLI::IsMember(choices_of(estimator::kSupportsSetting)))
      ->capture_default_str();
  app.add_option("--estimator", o.kind,
                 "which estimate the state carries: 'invariant-ekf' (contact-aided invariant EKF) "
                 "or 'leg-odometry' (baseline: IMU orientation, or the integrated gyro when the "
                 "IMU sends none, plus stance-foot kinematics; no filter, no bias estimate); "
                 "estimator/README.md compares them")
      ->check(CLI::IsMember(choices_of(estimator::kTypeSetting)))
      ->capture_default_str();
  app.add_option("--ground-height", o.ground_height,
                 "height in W of the ground the soles stand on at the start [m] (the lowest sole "
                 "in contact is put there)")
      ->check(CLI::Number)
      ->capture_default_str();
  app.add_option("--support-heights", o.support_heights,
                 "RIGHT LEFT: height in W of each foot's sole point at the start [m], for feet "
                 "on supports of their own (platforms); overrides --ground-height for feet in "
                 "contact")
      ->expected(2);
  app.add_option("--initial-xy", o.initial_xy, "X Y: the base's start position in W [m]")
      ->expected(2);
}

/// The options of the sensors' handling: frozen IMU, contact detection, IMU latency, the
/// published angular velocity.
void add_sensor_options(CLI::App& app, Options& o) {
  app.add_option("--frozen-imu-ticks", o.frozen_imu_ticks,
                 "bit-identical IMU samples in a row that count as a frozen IMU (kinematics-only "
                 "fallback, health DEGRADED); 100 = 0.1 s keeps a still, coarsely quantised IMU "
                 "from being taken for a dead one")
      ->check(CLI::Range(2, 1000000))
      ->capture_default_str();
  app.add_flag("--ignore-plan", o.ignore_plan,
               "do not subscribe to poise/balance_reference: contact from the sensors alone "
               "(no FOOT_SWING prior for the contact detector)");
  app.add_option("--contact-rest-time", o.contact_rest_time,
                 "contact detector's resting rule: a foot whose load stayed below 2 % of the "
                 "weight this long with its sole still, or that landed and never carried 2 % "
                 "this long since, keeps its contact until its sole leaves (the flag means "
                 "touching); 0: off, the flag drops below 1 % of the weight [s]")
      ->check(range_of(estimator::kContactRestTimeSetting))
      ->capture_default_str();
  app.add_option("--contact-ft-noise", o.contact_ft_noise,
                 "the foot F/T sensors' normal-force noise (1 sigma) for the contact detector's "
                 "light-touch rule: a touch too light for the 1 % load threshold is flagged from "
                 "its step in the reading, with the sole down where it stood (default: the "
                 "simulator's F/T, an industrial strain-gauge class); 0: the rule is off [N]")
      ->check(range_of(estimator::kContactFtNoiseSetting))
      ->capture_default_str();
  app.add_option("--imu-delay-ticks", o.imu_delay_ticks,
                 "the IMU's output latency in ticks (its filters and transfer), used when the IMU "
                 "sits behind joints (a torso IMU behind a waist): its pose relative to the base "
                 "is then taken from the encoders of that many ticks earlier (estimator/README.md)")
      ->check(whole_range_of(estimator::kImuDelayTicksSetting))
      ->capture_default_str();
  app.add_option("--stance-rate-hz", o.stance_rate_hz,
                 "cut-off of the complementary filter of the gyro and the stance feet's "
                 "kinematics for the published base angular velocity (a flat stance foot does "
                 "not turn; below the cut-off the gyro, above it the encoders); 0: the gyro "
                 "alone [Hz]")
      ->check(range_of(estimator::kStanceRateSetting))
      ->capture_default_str();
}

/// Parses the command line into `o`. Returns the exit status when the command line ends the run
/// (0 after --help, 2 for a usage error), else -1.
int parse_options(int argc, char** argv, Options& o) {
  CLI::App app{"State estimator node: sensors k in, state k out."};
  node::add_node_options(app, o.node, "estimator");
  node::add_input_options(app, o.node);
  app.add_flag("--ground-truth-state", o.ground_truth_state,
               "DEBUG: copy the simulator's ground truth into the state (sets STATE_GROUND_TRUTH)");
  app.add_option("--description-timeout-ms", o.description_timeout_ms,
                 "how long to wait for the robot description at start")
      ->capture_default_str();
  app.add_option("--truth-timeout-ms", o.truth_timeout_ms,
                 "with --ground-truth-state: how long to wait for the ground truth of a tick")
      ->capture_default_str();
  add_start_options(app, o);
  add_sensor_options(app, o);
  POISE_CLI_PARSE(app, argc, argv);
  return -1;
}

/// The estimator's configuration from the command line, at the robot's sample period. Throws
/// std::runtime_error for a non-finite start height.
estimator::EstimatorConfig make_config(const Options& o, const msg::RobotDescription& description) {
  estimator::EstimatorConfig config;
  config.supports = estimator::parse_support_model(o.supports);
  config.frozen_imu_ticks = o.frozen_imu_ticks;
  config.contact_rest_time = o.contact_rest_time;
  config.contact_ft_noise = o.contact_ft_noise;
  config.imu_delay_ticks = o.imu_delay_ticks;
  config.stance_rate_filter_hz = o.stance_rate_hz;
  config.kind = estimator::parse_estimator_kind(o.kind);
  config.ground_height = o.ground_height;
  if (o.support_heights.size() == 2)
    config.support_height = {o.support_heights[0], o.support_heights[1]};
  if (o.initial_xy.size() == 2) {
    config.init_base_x = o.initial_xy[0];
    config.init_base_y = o.initial_xy[1];
  }
  for (double v : o.support_heights)
    if (!std::isfinite(v)) throw std::runtime_error("--support-heights: values must be finite");
  if (!std::isfinite(o.ground_height)) throw std::runtime_error("--ground-height must be finite");
  // The sample period is the robot's (a tick gap of g ticks propagates over g periods): a robot
  // at 500 Hz is integrated over 2 ms per tick, as the in-process loop does.
  if (description.control_period_s() > 0.0) config.dt = description.control_period_s();
  dds::log(dds::LogLevel::info, "sample period %.6g s (%s)", config.dt,
           description.control_period_s() > 0.0 ? "poise/robot_description"
                                                : "not in the description: the 1 kHz default");
  return config;
}

/// The estimator node: its endpoints, the estimator and its buffers. Each sensor sample is
/// handled on the DDS listener thread as it arrives, under `state_mutex_` (--ground-truth-state:
/// on the main thread, which waits for the tick's ground truth).
class EstimatorNode {
 public:
  /// Waits for the robot description, builds the estimator and the endpoints.
  explicit EstimatorNode(const Options& o);
  /// Handles the sensor samples until shutdown; the diagnostics meanwhile.
  void serve();
  /// The summary file's extra figures.
  void write_summary();

 private:
  void log_start() const;
  std::unique_ptr<dds::Subscriber<msg::GroundTruth>> subscribe_ground_truth();
  std::unique_ptr<dds::Subscriber<msg::BalanceReference>> subscribe_plans();
  void serve_on_listener();
  void serve_with_ground_truth();
  // ---- one sensor sample (allocation-free; one thread at a time) ----------------------------
  void handle(const msg::Sensors& in) noexcept;
  bool accept_tick(std::uint64_t k, std::int64_t t0) noexcept;
  bool estimate(const msg::Sensors& in, std::uint64_t k, std::int64_t& lib_ns) noexcept;
  void overwrite_with_ground_truth(std::uint64_t k) noexcept;

  // The feet's planned modes, held until their tick (the contact detector's prior).
  static constexpr std::size_t kPlanQueue = 512;

  const Options o_;
  node::Node node_;
  const msg::RobotDescription description_;
  const node::RobotFromDescription resolved_;
  const std::vector<int> model_to_wire_;
  const estimator::EstimatorConfig config_;
  estimator::Estimator estimator_;
  estimator::SensorFrame frame_;
  estimator::EstimatorState state_;

  node::Mailbox<msg::GroundTruth> truth_box_;
  std::unique_ptr<dds::Subscriber<msg::GroundTruth>> truths_;
  dds::Publisher<msg::State> states_;
  estimator_node::FootPlanQueue plans_;
  std::unique_ptr<dds::Subscriber<msg::BalanceReference>> references_;

  msg::GroundTruth truth_;
  msg::State out_;
  std::uint64_t truth_seen_ = 0;
  std::uint64_t library_rejected_ = 0;
  node::TickSequencer sequencer_;
  const int sensors_input_;
  const std::size_t joints_;

  std::mutex state_mutex_;
  node::Mailbox<msg::Sensors> sensor_box_;
  std::unique_ptr<dds::Subscriber<msg::Sensors>> sensors_;
};

EstimatorNode::EstimatorNode(const Options& o)
    : o_(o),
      node_(o.node),
      description_(node::wait_for_robot_description(
          node_, std::chrono::milliseconds(o.description_timeout_ms))),
      resolved_(node::resolve_robot(node_, description_, o.node.robot)),
      model_to_wire_(
          node::model_to_wire_map(description_.joint_names(), resolved_.model.joint_names)),
      config_(make_config(o, description_)),
      estimator_(resolved_.model, resolved_.config, config_),
      // The start is logged once the estimator is built.
      frame_((log_start(), estimator_.make_sensor_frame())),
      state_(estimator_.make_state()),
      truths_(subscribe_ground_truth()),
      states_(node_.participant()),
      plans_(kPlanQueue),
      references_(subscribe_plans()),
      sequencer_(o.node.ticks),
      sensors_input_(node_.expect_input("poise/sensors", o.node.input_stale_ms)),
      joints_(model_to_wire_.size()) {}

void EstimatorNode::log_start() const {
  if (o_.support_heights.size() == 2)
    dds::log(dds::LogLevel::info, "estimator: %s, start: right sole at z %.4f m, left sole %.4f m",
             estimator::to_string(config_.kind), o_.support_heights[0], o_.support_heights[1]);
  else
    dds::log(dds::LogLevel::info, "estimator: %s, start: soles on the ground at z %.4f m",
             estimator::to_string(config_.kind), o_.ground_height);
  if (config_.supports != estimator::SupportModel::kFixed)
    dds::log(dds::LogLevel::info,
             "supports: %s (stance contact points free after %.1f s of IMU calibration on still "
             "supports)",
             estimator::to_string(config_.supports), config_.moving_support_calibration);
}

// --ground-truth-state: the simulator's ground truth, into truth_box_ (else none).
std::unique_ptr<dds::Subscriber<msg::GroundTruth>> EstimatorNode::subscribe_ground_truth() {
  if (!o_.ground_truth_state) return nullptr;
  dds::log(dds::LogLevel::warn, "DEBUG --ground-truth-state: the state is the simulator's truth");
  auto truths = std::make_unique<dds::Subscriber<msg::GroundTruth>>(node_.participant(),
                                                                    truth_box_.callback());
  node_.watch(*truths);
  return truths;
}

// The feet's planned modes of the balance references, into plans_ (none with --ignore-plan).
std::unique_ptr<dds::Subscriber<msg::BalanceReference>> EstimatorNode::subscribe_plans() {
  if (o_.ignore_plan) return nullptr;
  auto references = std::make_unique<dds::Subscriber<msg::BalanceReference>>(
      node_.participant(),
      [this](const msg::BalanceReference& r) {
        plans_.put(r.header().tick(),
                   {estimator::foot_plan_of_mode(static_cast<int>(r.feet()[0].mode())),
                    estimator::foot_plan_of_mode(static_cast<int>(r.feet()[1].mode()))});
      },
      dds::Qos::latched(static_cast<int>(kPlanQueue)));
  node_.watch(*references);
  return references;
}

// One sensor sample: estimate, answer. Allocation-free; runs on one thread at a time.
void EstimatorNode::handle(const msg::Sensors& in) noexcept {
  const std::uint64_t k = in.header().tick();
  if (in.joint_count() != joints_) {
    node_.error("tick %llu: poise/sensors joint_count %u, the robot has %zu joints: rejected, "
                "no state sent",
                static_cast<unsigned long long>(k), in.joint_count(), joints_);
    return;
  }
  const std::int64_t t0 = node::now_ns();
  node_.tick_begin();
  if (!accept_tick(k, t0)) return;
  std::int64_t lib_ns = 0;
  if (!estimate(in, k, lib_ns)) return;
  if (o_.ground_truth_state) overwrite_with_ground_truth(k);
  node_.publish(states_, out_);
  node_.tick_done(k, node::now_ns() - t0, lib_ns);
}

// The tick sequencer's verdict on sample k. False when the sample is dealt with here (a repeat
// answered with the same state, a tick out of sequence rejected).
bool EstimatorNode::accept_tick(std::uint64_t k, std::int64_t t0) noexcept {
  switch (sequencer_.accept(k, t0)) {
    case node::TickSequencer::Verdict::kRepeat:  // repeated sample: same answer
      node_.input_seen(sensors_input_, k);
      node_.publish(states_, out_);
      return false;
    case node::TickSequencer::Verdict::kOutOfSequence:
      node_.error("tick %llu out of sequence (last accepted %llu): rejected, no state sent",
                  static_cast<unsigned long long>(k),
                  static_cast<unsigned long long>(sequencer_.last()));
      return false;
    case node::TickSequencer::Verdict::kRestart:
      estimator_.reset();
      library_rejected_ = 0;
      node_.error("sensor stream restarted at tick %llu (previous %llu): estimator "
                  "re-initialised",
                  static_cast<unsigned long long>(k),
                  static_cast<unsigned long long>(sequencer_.previous()));
      break;
    default:
      break;
  }
  node_.input_seen(sensors_input_, k);
  return true;
}

// The estimator's update with sample k, into out_. False when the library rejected the frame
// (no state sent). `lib_ns`: the library's time.
bool EstimatorNode::estimate(const msg::Sensors& in, std::uint64_t k,
                             std::int64_t& lib_ns) noexcept {
  estimator_node::from_msg(in, model_to_wire_, frame_);
  frame_.foot_plan = plans_.at(k);
  const std::int64_t t_lib = node::now_ns();
  const estimator::StatusFlags flags = estimator_.update(frame_, state_);
  lib_ns = node::now_ns() - t_lib;
  if (estimator_.diagnostics().rejected_frames != library_rejected_) {
    library_rejected_ = estimator_.diagnostics().rejected_frames;
    node_.error("tick %llu: sensor frame rejected: %s: no state sent",
                static_cast<unsigned long long>(k), estimator_.diagnostics().last_error);
    return false;
  }
  node_.set_condition(msg::HEALTH_DEGRADED,
                      (flags & estimator::kImuFrozen)
                          ? "IMU frozen (bit-identical samples): base tracked by leg kinematics "
                            "only (STATE_IMU_FROZEN)"
                          : nullptr);
  estimator_node::to_msg(state_, model_to_wire_, out_);
  return true;
}

// --ground-truth-state: out_ from the simulator's ground truth of tick k (waited for up to
// --truth-timeout-ms; without it the estimated state is sent).
void EstimatorNode::overwrite_with_ground_truth(std::uint64_t k) noexcept {
  const std::int64_t deadline = node::now_ns() + std::int64_t{o_.truth_timeout_ms} * 1'000'000;
  bool found = truth_.header().tick() == k;
  while (!found && truth_box_.wait(truth_seen_, deadline))
    found = truth_box_.take(truth_, truth_seen_) && truth_.header().tick() == k;
  if (found)
    estimator_node::overwrite_with_ground_truth(truth_, resolved_.model.total_mass, out_);
  else
    node_.error("tick %llu: no ground truth of this tick: estimated state sent",
                static_cast<unsigned long long>(k));
}

void EstimatorNode::serve() {
  node_.wait_for_output_readers(states_);
  if (!o_.ground_truth_state)
    serve_on_listener();
  else
    serve_with_ground_truth();
}

// Estimate on the DDS listener thread as the sample arrives (no hand-off to a loop thread).
void EstimatorNode::serve_on_listener() {
  sensors_ = std::make_unique<dds::Subscriber<msg::Sensors>>(node_.participant(),
                                                             [this](const msg::Sensors& in) {
                                                               std::lock_guard lock(state_mutex_);
                                                               handle(in);
                                                             });
  node_.watch(*sensors_);
  node_.expect_one_writer(*sensors_);
  node_.serve(state_mutex_);
}

// Debug mode: the loop thread waits for the ground truth of the tick, which arrives on the
// listener thread, so the sensors go through a mailbox.
void EstimatorNode::serve_with_ground_truth() {
  sensors_ =
      std::make_unique<dds::Subscriber<msg::Sensors>>(node_.participant(), sensor_box_.callback());
  node_.watch(*sensors_);
  node_.expect_one_writer(*sensors_);
  msg::Sensors in;
  std::uint64_t seen = 0;
  while (node_.running()) {
    const std::int64_t next_diag = node_.poll();
    if (!sensor_box_.wait(seen, next_diag) || !sensor_box_.take(in, seen)) continue;
    handle(in);
  }
}

void EstimatorNode::write_summary() {
  std::lock_guard lock(state_mutex_);
  const estimator::EstimatorDiagnostics& d = estimator_.diagnostics();
  char extra[1024];
  std::snprintf(extra, sizeof(extra),
                "{\"state_source\": \"%s\", \"estimator\": \"%s\", \"supports\": \"%s\", "
                "\"filter_resets\": %llu, "
                "\"rejected_frames\": %llu, \"dropped_frames\": %llu, \"frozen_imu_ticks\": %llu, "
                "\"orientation_rejections\": %llu, \"stance_rate_hz\": %g, \"stance_rate_gated_ticks\": %llu, "
                "\"contact_ft_noise\": %g, \"contact_rest_time\": %g, \"imu_delay_ticks\": %d, "
                "\"out_of_sequence\": %llu, \"stream_restarts\": %llu, "
                "\"stale_events\": %llu, \"plans_received\": %llu, \"plan_overflows\": %llu}",
                o_.ground_truth_state ? "ground_truth" : "estimator",
                estimator::to_string(config_.kind), estimator::to_string(config_.supports), static_cast<unsigned long long>(d.resets),
                static_cast<unsigned long long>(d.rejected_frames),
                static_cast<unsigned long long>(d.dropped_frames),
                static_cast<unsigned long long>(d.frozen_imu_ticks),
                static_cast<unsigned long long>(d.orientation_rejections),
                config_.stance_rate_filter_hz,
                static_cast<unsigned long long>(d.stance_rate_gated_ticks),
                config_.contact_ft_noise, config_.contact_rest_time, config_.imu_delay_ticks,
                static_cast<unsigned long long>(sequencer_.rejected()),
                static_cast<unsigned long long>(sequencer_.restarts()),
                static_cast<unsigned long long>(node_.stale_events()),
                static_cast<unsigned long long>(plans_.received()),
                static_cast<unsigned long long>(plans_.overflows()));
  node_.write_summary(extra);
}

int run(int argc, char** argv) {
  Options o;
  if (const int status = parse_options(argc, argv, o); status >= 0) return status;
  EstimatorNode estimator(o);
  estimator.serve();
  estimator.write_summary();
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
