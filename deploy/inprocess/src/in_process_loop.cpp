#include "poise/inprocess/in_process_loop.hpp"

#include <algorithm>
#include <numeric>
#include <cstdio>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <poise/msg/ground_truth.h>

#include "poise/contact_node/contact_messages.hpp"
#include "poise/controller_node/controller_messages.hpp"
#include "poise/controller_node/reference_applier.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/node/convert.hpp"
#include "poise/reflect/validate.hpp"
#include "poise/safety/safety_layer.hpp"
#include "poise/sim_node/sim_messages.hpp"
#if POISE_INPROCESS_HAVE_ESTIMATOR
#include "poise/estimator/estimator.hpp"
#include "poise/estimator_node/estimator_messages.hpp"
#include "poise/estimator_node/foot_plan_queue.hpp"
#endif

namespace poise::inprocess {

const char* to_string(StateSource s) {
  switch (s) {
    case StateSource::kEstimator:
      return "estimator";
    case StateSource::kGroundTruth:
      return "ground_truth";
  }
  return "unknown";
}

bool estimator_available() {
  return POISE_INPROCESS_HAVE_ESTIMATOR != 0;
}

#if POISE_INPROCESS_HAVE_ESTIMATOR
struct InProcessLoop::EstimatorParts {
  EstimatorParts(const model::Model& model, const model::RobotConfig& robot,
                 const estimator::EstimatorConfig& cfg)
      : est(model, robot, cfg), frame(est.make_sensor_frame()), out(est.make_state()) {}
  estimator::Estimator est;
  estimator::SensorFrame frame;
  estimator::EstimatorState out;
  /// poise-estimator's plan queue: the feet's planned modes of the balance references, each
  /// from its tick on (the contact detector's prior).
  estimator_node::FootPlanQueue plans{512};
};
#else
struct InProcessLoop::EstimatorParts {};
#endif

contact::Method contact_method_of(const scenario::Scenario& scenario, const LoopOptions& options) {
  if (options.contact_method) return *options.contact_method;
  if (scenario.contact_method.empty()) return contact::Method::kSequential;
  const auto m = contact::parse_method(scenario.contact_method);
  if (!m)
    throw std::runtime_error("scenario '" + scenario.name + "': unknown contact.method '" +
                             scenario.contact_method + "'");
  return *m;
}

InProcessLoop::InProcessLoop(const scenario::Scenario& scenario, const LoopOptions& options)
    : scenario_(scenario),
      options_(options),
      optimizer_(contact_method_of(scenario, options)),
      monitor_(scenario, sim::platforms_of_feet(scenario)) {
  if (scenario_.robot_config.empty())
    throw std::runtime_error("scenario '" + scenario_.name +
                             "': the in-process loop needs a robot configuration (robot.config)");
  robot_ = model::load_robot_config(scenario_.robot_config);
  model_ = model::load_robot_model(robot_);
  duration_ = options_.duration > 0.0 ? options_.duration : scenario_.duration;
  if (!(duration_ > 0.0))
    throw std::runtime_error("scenario '" + scenario_.name + "': duration must be > 0");

  sim_ = std::make_unique<sim::Simulator>(scenario_.sim);
  controller_ = std::make_unique<controller::BalanceController>(model_, robot_,
                                                                controller_config());
  map_joints_and_feet();
  make_estimator();
  make_messages_and_safety();
  make_buffers_and_first_reference();
  make_reference_player();
  start_up();
}

// The controller's tuning: LoopOptions::controller, else its file, else the scenario's section,
// else the defaults; at the simulator's period.
controller::ControllerConfig InProcessLoop::controller_config() const {
  controller::ControllerConfig ccfg;
  if (options_.controller) {
    ccfg = *options_.controller;
  } else if (!options_.controller_config_file.empty()) {
    ccfg = controller::load_controller_config(options_.controller_config_file);
  } else if (!scenario_.controller_yaml.empty()) {
    ccfg = controller::parse_controller_config(scenario_.controller_yaml,
                                               "scenario '" + scenario_.name + "', controller");
  }
  ccfg.dt = sim_->dt();
  return ccfg;
}

void InProcessLoop::map_joints_and_feet() {
  // Joint orders (both are depth-first by joint name today; mapped by name to be safe).
  sim_to_model_ = sim::joint_index_map(sim_->joint_names(), model_.joint_names);
  model_to_sim_ = sim::joint_index_map(model_.joint_names, sim_->joint_names());
  for (std::size_t j = 0; j < model_to_sim_.size(); ++j)
    if (model_to_sim_[j] < 0)
      throw std::runtime_error("joint '" + model_.joint_names[j] + "' is not simulated");
  // Feet: simulator feet are matched to the robot config's sides by frame name.
  const auto& sim_feet = scenario_.sim.robot.feet;
  for (int side = 0; side < 2; ++side) {
    for (std::size_t f = 0; f < sim_feet.size(); ++f)
      if (sim_feet[f].frame == robot_.feet[side].frame)
        sim_foot_of_side_[side] = static_cast<int>(f);
    if (sim_foot_of_side_[side] < 0)
      throw std::runtime_error("foot frame '" + robot_.feet[side].frame +
                               "' of the robot config is not a simulated foot");
  }
}

void InProcessLoop::make_estimator() {
  // The ground-truth state is poise-estimator --ground-truth-state's: the estimator runs and its
  // state is partly overwritten (read_state). Without the estimator library: the truth alone.
  if (options_.state_source == StateSource::kEstimator || estimator_available()) {
#if POISE_INPROCESS_HAVE_ESTIMATOR
    estimator::EstimatorConfig ecfg;
    ecfg.dt = sim_->dt();
    ecfg.frozen_imu_ticks = kNodeFrozenImuTicks;  // as poise run starts poise-estimator
    ecfg.init_base_x = scenario_.sim.initial.base_position.x();
    ecfg.init_base_y = scenario_.sim.initial.base_position.y();
    ecfg.supports = estimator::parse_support_model(scenario_.estimator.supports);
    ecfg.kind = estimator::parse_estimator_kind(
        options_.estimator.empty() ? scenario_.estimator.type : options_.estimator);
    if (std::isfinite(scenario_.estimator.stance_rate_hz))
      ecfg.stance_rate_filter_hz = scenario_.estimator.stance_rate_hz;
    if (const double n = scenario::estimator_contact_ft_noise(scenario_); std::isfinite(n))
      ecfg.contact_ft_noise = n;
    if (std::isfinite(scenario_.estimator.contact_rest_time))
      ecfg.contact_rest_time = scenario_.estimator.contact_rest_time;
    ecfg.imu_delay_ticks = scenario::estimator_imu_delay_ticks(scenario_);
    // Where the soles start: the scenario's estimator section, or the platforms at t = 0.
    const scenario::EstimatorStart start = scenario::estimator_start(scenario_);
    ecfg.ground_height = start.ground_height;
    for (int side = 0; side < 2; ++side)
      ecfg.support_height[static_cast<std::size_t>(side)] =
          start.support_height[static_cast<std::size_t>(side)];
    estimator_ = std::make_unique<EstimatorParts>(model_, robot_, ecfg);
#else
    throw std::runtime_error(
        "the estimator library is not part of this build: use the ground-truth state (debug)");
#endif
  }

}

// The topics' messages of a tick, and the robot side's safety layer.
void InProcessLoop::make_messages_and_safety() {
  wire_feet_ = sim_node::foot_order(*sim_);
  sensors_msg_ = std::make_unique<msg::Sensors>();
  state_msg_ = std::make_unique<msg::State>();
  truth_msg_ = std::make_unique<msg::GroundTruth>();
  problem_msg_ = std::make_unique<msg::ContactProblem>();
  solution_msg_ = std::make_unique<msg::ContactSolution>();
  command_msg_ = std::make_unique<msg::JointCommand>();
  priority_ = controller_->config().contact.priority;
  torsion_ = controller_->config().contact.torsion_limit;
  {
    // The robot side of poise-sim: its safety layer, configured as poise-sim configures it.
    safety::Config sc =
        safety::make_config(model_, &robot_, sim_->joint_names(), sim_->dt(), sim_->damping_kd());
    sc.watchdog_s = options_.watchdog_ms * 1e-3;  // poise-sim --watchdog-ms
    sc.hold_s = options_.hold_s;                   // poise-sim --hold-s
    safety_ = std::make_unique<safety::SafetyLayer>(std::move(sc));
  }
}

void InProcessLoop::make_buffers_and_first_reference() {
  const auto& sim_feet = scenario_.sim.robot.feet;
  sensors_ = sim_->make_sensor_frame();
  truth_ = sim_->make_ground_truth();
  sim_command_ = sim_->make_command();
  state_ = controller_->make_state();
  reference_ = controller_->make_reference();
  command_ = controller_->make_command();
  // The scenario's planned support (the balance reference's foot modes, paper Fig. 6 inputs):
  // the controller loads those feet from the first tick instead of waiting for a contact
  // detector that only sees contact once the feet are loaded.
  for (int side = 0; side < 2; ++side) {
    const std::string& name = sim_feet[sim_foot_of_side_[side]].name;
    const bool support = scenario_.support == "double" || scenario_.support == name;
    reference_.feet[side].mode =
        support ? controller::FootMode::kSupport : controller::FootMode::kSwing;
  }
}

void InProcessLoop::make_reference_player() {
  if (!scenario_.reference.empty()) {
    try {
      // As `poise run` starts poise-reference (the file's lead ticks) and poise-controller (a
      // queue of 512 references, the description's control period).
      reference::Trajectory traj = reference::load_trajectory(scenario_.reference.string());
      const int lead = traj.lead_ticks;
      reference_player_ = std::make_unique<reference::Player>(std::move(traj), model_, robot_,
                                                              model_to_sim_, sim_->dt(), lead);
      reference_applier_ =
          std::make_unique<controller_node::ReferenceApplier>(512, model_to_sim_, sim_->dt());
    } catch (const std::exception& e) {
      throw std::runtime_error("scenario '" + scenario_.name + "', reference: " + e.what());
    }
  }
}

void InProcessLoop::start_up() {
  sim_command_.mode = sim::CommandMode::kPd;  // the safety layer's command is a PD law
  // Start-up as poise-sim: the safety layer holds the initial posture for settle_ticks steps so
  // that the first frame measures the feet loaded; it then holds where it settled until the
  // first command. The scenario monitor sees the settled state first.
  const int settle = options_.settle_ticks < 0 ? kDefaultSettleTicks : options_.settle_ticks;
  sim_->read(sensors_, truth_);
  safety_->start(sensors_.q, clock_ns(), true);
  for (int i = 0; i < settle; ++i) {
    apply_safety_command(clock_ns());
    sim_->step(sim_command_, sensors_, truth_);
  }
  safety_->start(sensors_.q, clock_ns());
  monitor_.update(truth_);
  first_tick_ = sim_->tick();
  steps_ = static_cast<std::int64_t>(std::llround(duration_ / sim_->dt()));
  for (auto* v : {&latency_us_, &estimator_us_, &contact_us_})
    v->reserve(static_cast<std::size_t>(steps_) + 16);
}

std::int64_t InProcessLoop::clock_ns() const {
  return std::llround(sim_->time() * 1e9) + clock_offset_ns_;
}

void InProcessLoop::apply_safety_command(std::int64_t now_ns) {
  sim_node::to_sim(safety_->update(now_ns, sensors_.q), sim_command_);
}

namespace {

/// Count, mean and order statistics of per-tick times (the percentile: the smallest value with
/// at least that share of the ticks at or below it).
LatencyStats latency_stats(std::vector<double> v) {
  LatencyStats s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  const auto pct = [&](double p) {
    const auto idx = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size()))) - 1;
    return v[std::min(idx, v.size() - 1)];
  };
  s.count = v.size();
  s.mean_us = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  s.p50_us = pct(0.5);
  s.p99_us = pct(0.99);
  s.max_us = v.back();
  return s;
}

}  // namespace

InProcessLoop::~InProcessLoop() = default;

const std::vector<std::string>& InProcessLoop::safety_warnings() const {
  return safety_->config().warnings;
}

double InProcessLoop::time() const {
  return sim_->time();
}

bool InProcessLoop::read_state() {
  const int n = model_.njoints;
#if POISE_INPROCESS_HAVE_ESTIMATOR
  if (estimator_) {
    // poise-sim publishes the sensors, poise-estimator decodes them, estimates and publishes the
    // state, poise-controller decodes it.
    sim_node::to_msg(sensors_, wire_feet_, *sensors_msg_);
    estimator_node::from_msg(*sensors_msg_, model_to_sim_, estimator_->frame);
    // The contact detector's prior, as poise-estimator takes it from poise/balance_reference:
    // the planned foot modes of the reference due at this tick (none before any reference).
    estimator_->frame.foot_plan = estimator_->plans.at(static_cast<std::uint64_t>(sensors_.tick));
    const std::uint64_t rejected = estimator_->est.diagnostics().rejected_frames;
    estimator_->est.update(estimator_->frame, estimator_->out);
    if (estimator_->est.diagnostics().rejected_frames != rejected) return false;  // no state
    estimator_node::to_msg(estimator_->out, model_to_sim_, *state_msg_);
    if (options_.state_source == StateSource::kGroundTruth) {
      // poise-estimator --ground-truth-state: the truth of the same tick over the estimate.
      msg::GroundTruth& g = *truth_msg_;
      node::put_pose(truth_.X_WB.linear(), truth_.X_WB.translation(), g.base_W());
      node::put3(truth_.v_WB, g.base_velocity_W().linear());
      node::put3(truth_.omega_WB, g.base_velocity_W().angular());
      node::put3(truth_.com_W, g.com_W());
      node::put3(truth_.com_vel_W, g.com_velocity_W());
      for (int f = 0; f < 2; ++f) {  // as sim_node::to_msg(GroundTruth)
        const sim::FootContactTruth& t = truth_.feet[static_cast<std::size_t>(wire_feet_[f])];
        g.feet()[f].in_contact(t.in_contact);
        node::put3(t.in_contact ? t.cop_W : Eigen::Vector3d::Zero(), g.feet()[f].cop_W());
      }
      estimator_node::overwrite_with_ground_truth(g, model_.total_mass, *state_msg_);
    }
    controller_node::from_msg(*state_msg_, model_to_sim_, state_);
    return true;
  }
#endif
  // Ground truth in a build without the estimator library: the simulator's truth (joints from the
  // encoders), not what poise-estimator --ground-truth-state sends.
  state_.tick = sensors_.tick;
  state_.time = sensors_.time;
  state_.X_WB = model::SE3(truth_.X_WB.linear(), truth_.X_WB.translation());
  state_.v_WB = truth_.v_WB;
  state_.omega_WB = truth_.omega_WB;
  for (int i = 0; i < n; ++i) {
    const int j = sim_to_model_[i];
    state_.q[j] = sensors_.q[i];
    state_.qd[j] = sensors_.qd[i];
  }
  state_.com_W = truth_.com_W;
  state_.com_velocity_W = truth_.com_vel_W;
  for (int side = 0; side < 2; ++side) {
    const auto& t = truth_.feet[sim_foot_of_side_[side]];
    auto& f = state_.feet[side];
    f.in_contact = t.in_contact;
    f.X_WF = model::SE3(t.X_WF.linear(), t.X_WF.translation());
    f.V_WF.head<3>() = t.v_WF;
    f.V_WF.tail<3>().setZero();
    f.cop_W = t.cop_W;
    f.normal_force = t.in_contact ? (t.X_WF.linear().transpose() * t.force_W).z() : 0.0;
  }
  state_msg_->header().tick(static_cast<std::uint64_t>(sensors_.tick));
  state_msg_->header().stamp_ns(std::llround(sensors_.time * 1e9));
  node::put3(state_.com_W, state_msg_->com_W());  // what the reference player reads
  for (int side = 0; side < 2; ++side)
    node::put_pose(state_.feet[side].X_WF.R, state_.feet[side].X_WF.p,
                   state_msg_->feet()[static_cast<std::size_t>(side)].pose_W());
  return true;
}

void InProcessLoop::apply_references() {
  if (!reference_applier_) return;
  // poise-controller at state k: the references due, applied as the node applies them.
  const auto k = static_cast<std::uint64_t>(sensors_.tick);
  reference_applier_->apply(k, have_handled_, handled_tick_, reference_);
  have_handled_ = true;
  handled_tick_ = k;
}

void InProcessLoop::play_reference() {
  if (!reference_player_) return;
  // poise-reference on the same state: the references of the next lead ticks, to the controller's
  // queue and to the estimator's (both subscribe to poise/balance_reference).
  reference_player_->on_state(*state_msg_, [this](const msg::BalanceReference& r) {
    reference_applier_->queue().put(r);
    if (reference_tap_) reference_tap_(r);
    com_shift_.put(r.header().tick(), r.has_com_target(),
                   Eigen::Vector3d(r.com_W()[0], r.com_W()[1], r.com_W()[2]));
#if POISE_INPROCESS_HAVE_ESTIMATOR
    if (estimator_)
      estimator_->plans.put(r.header().tick(),
                            {estimator::foot_plan_of_mode(static_cast<int>(r.feet()[0].mode())),
                             estimator::foot_plan_of_mode(static_cast<int>(r.feet()[1].mode()))});
#endif
    return true;
  });
}

void InProcessLoop::control() {
  // poise-controller, phase A: the contact problem of this tick, sent.
  controller_->prepare(state_, reference_, problem_);
  contact_node::to_msg(problem_, *problem_msg_);
  problem_msg_->header(state_msg_->header());
  // poise-contact: decode, check, solve, answer (never a non-finite answer).
  const auto t_contact = std::chrono::steady_clock::now();
  const char* bad = reflect::validate(*problem_msg_)
                        ? contact_node::from_msg(*problem_msg_, solver_problem_)
                        : "invalid contact problem";
  if (bad) {
    ++invalid_messages_;
    contact::set_safe_solution(contact::ContactStatus::kInvalidInput, solution_);
  } else {
    solver_problem_.weights.priority = priority_;
    solver_problem_.weights.torsion = torsion_;
    optimizer_.solve(solver_problem_, solution_);
  }
  contact_node::to_msg(solution_, problem_msg_->header(), 0.0, optimizer_.method(), *solution_msg_);
  if (!reflect::validate(*solution_msg_)) {
    ++invalid_messages_;
    contact::set_safe_solution(contact::ContactStatus::kSolverFailure, solution_);
    contact_node::to_msg(solution_, problem_msg_->header(), 0.0, optimizer_.method(),
                         *solution_msg_);
  }
  contact_tick_us_ = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() -
                                                               t_contact)
                         .count();
  // poise-controller, phase B: the solution decoded, the joint command of this tick sent.
  contact_node::from_msg(*solution_msg_, answer_);
  controller_->finish(answer_, command_);
  controller_node::to_msg(command_, state_msg_->header(), model_to_sim_, *command_msg_);
}

void InProcessLoop::step() {
  if (aborted_) return;
  const auto t0 = std::chrono::steady_clock::now();
  last_tick_ = sensors_.tick;
  last_controlled_ = read_state();
  if (!last_controlled_) {
    // No state, so no command: poise-sim waits for it until its timeout, then applies what the
    // safety layer says at that moment, or gives up after too many such ticks in a row.
    ++command_timeouts_;
    clock_offset_ns_ += std::llround(options_.command_timeout_ms * 1e6);
    if (++consecutive_timeouts_ >= options_.max_consecutive_timeouts) {
      aborted_ = true;
      return;
    }
    apply_safety_command(clock_ns());
    if (sim_->step(sim_command_, sensors_, truth_) != sim::StepStatus::kOk) ++rejected_commands_;
    after_step();
    wall_ += std::chrono::steady_clock::now() - t0;
    return;
  }
  const auto t_state = std::chrono::steady_clock::now();
  consecutive_timeouts_ = 0;
  apply_references();
  control();
  play_reference();
  const auto t1 = std::chrono::steady_clock::now();
  const double us = std::chrono::duration<double, std::micro>(t1 - t0).count();
  if (latency_us_.size() < latency_us_.capacity()) {
    latency_us_.push_back(us);
    estimator_us_.push_back(std::chrono::duration<double, std::micro>(t_state - t0).count());
    contact_us_.push_back(contact_tick_us_);
  }
  if (us > 1e6 * sim_->dt()) ++deadline_misses_;

  // poise-sim: the command through the robot's safety layer (a rejected one is counted and the
  // layer keeps applying what it applied), then the step.
  const std::int64_t now = clock_ns();
  if (!safety_->on_command(*command_msg_, sensors_.tick, now) &&
      !safety_->stopped())
    ++rejected_commands_;
  apply_safety_command(now);
  if (sim_->step(sim_command_, sensors_, truth_) != sim::StepStatus::kOk) ++rejected_commands_;
  after_step();
  wall_ += std::chrono::steady_clock::now() - t0;
}

// poise-sim after a step: the monitor, and the fastest joint of the run.
void InProcessLoop::after_step() {
  update_monitor();
  for (Eigen::Index j = 0; j < sensors_.qd.size(); ++j)
    if (std::abs(sensors_.qd[j]) > max_joint_speed_) {
      max_joint_speed_ = std::abs(sensors_.qd[j]);
      fastest_joint_ = static_cast<int>(j);
    }
}

bool InProcessLoop::done() const {
  return aborted_ || sim_->tick() >= first_tick_ + steps_;
}

InProcessLoop::TickMessages InProcessLoop::last_messages() const {
  TickMessages m;
  m.tick = last_tick_;
  m.controlled = last_controlled_;
  m.sensors = sensors_msg_.get();
  if (last_controlled_) {
    m.state = state_msg_.get();
    m.problem = problem_msg_.get();
    m.solution = solution_msg_.get();
    m.command = command_msg_.get();
  }
  return m;
}

// poise-sim after a step: the references' CoM target shift due at the tick stepped, then the
// monitor on the new truth.
void InProcessLoop::update_monitor() {
  const std::int64_t stepped = sensors_.tick - 1;
  monitor_.set_com_target_shift(com_shift_.due(static_cast<std::uint64_t>(std::max<std::int64_t>(0, stepped))));
  monitor_.update(truth_);
}

RunResult InProcessLoop::run(const std::function<void(double)>& progress) {
  const double dt = sim_->dt();
  double next_report = 1.0;
  while (!done()) {
    step();
    if (progress && time() >= next_report - 0.5 * dt) {
      progress(time());
      next_report += 1.0;
    }
  }
  return result();
}

RunResult InProcessLoop::result() const {
  RunResult r;
  const auto m = monitor_.result();
  r.scenario = scenario_.name;
  r.survived = m.survived;
  r.com_error_max_m = m.com_error_max_m;
  r.com_error_final_m = m.com_error_final_m;
  r.foot_slip_max_m = m.foot_slip_max_m;
  r.foot_slide_max_m = m.foot_slide_max_m;
  r.foot_displacement_max_m = m.foot_displacement_max_m;
  r.foot_tilt_max_deg = m.foot_tilt_max_deg;
  r.non_foot_contacts = m.non_foot_contacts;
  r.min_base_height_m = m.min_base_height_m;
  r.recovery_time_s = m.last_recovery_time_s;
  r.trunk_pitch_max_deg = m.trunk_pitch_max_deg;
  r.trunk_roll_max_deg = m.trunk_roll_max_deg;
  r.failed = monitor_.failed_criteria();
  r.completed = !aborted_;
  r.command_timeouts = command_timeouts_;
  if (controller_) {  // the controller declared a fall: it damps the joints from then on
    const controller::TickDiagnostics& d = controller_->diagnostics();
    const controller::FallConfig& fc = controller_->config().fall;
    r.controller_fall = controller::describe_fall(d, fc.tilt_deg, fc.com_height_fraction);
    if (d.fallen) {
      r.controller_fall_time_s = static_cast<double>(d.fall_tick) * sim_->dt();  // sim time
      char t[32];
      std::snprintf(t, sizeof t, "%.3f", r.controller_fall_time_s);
      r.failed.push_back("the controller declared a fall at " + std::string(t) + " s (" +
                         r.controller_fall + "): joints damped");
      r.survived = false;
      r.recovery_time_s = std::numeric_limits<double>::infinity();  // a fall never recovered
    }
  }
  if (aborted_) {  // as poise-sim's result
    r.survived = false;
    r.failed.push_back("run aborted before its end");
  }
  r.tick_latency_us = latency_stats(latency_us_);
  r.estimator_us = latency_stats(estimator_us_);
  r.contact_us = latency_stats(contact_us_);
  std::vector<double> controller_us(latency_us_.size());
  for (std::size_t i = 0; i < latency_us_.size(); ++i)
    controller_us[i] = latency_us_[i] - estimator_us_[i] - contact_us_[i];
  r.controller_us = latency_stats(std::move(controller_us));
  r.deadline_misses = deadline_misses_;
  const double wall = std::chrono::duration<double>(wall_).count();
  r.sim_time_s = static_cast<double>(sim_->tick() - first_tick_) * sim_->dt();
  r.realtime_factor = wall > 0.0 ? r.sim_time_s / wall : 0.0;
  r.state_source = options_.state_source;
  r.ticks = controller_->diagnostics().ticks;
  r.contact_fallbacks = controller_->diagnostics().late_solutions;
  r.qp_failures = controller_->diagnostics().qp_failures;
  r.rejected_commands = rejected_commands_;
  r.reality = sim_->reality();
  r.invalid_messages = invalid_messages_;
  r.wall_time_s = wall;
  add_robot_side(r);
  return r;
}

// As poise-sim's summary and `poise run`'s verdict: the safety layer's figures, and damping ticks
// over the scenario's tolerance fail the run.
void InProcessLoop::add_robot_side(RunResult& r) const {
  r.safety = safety_->counters();
  r.safety_mode = safety_->mode();
  r.hold_ticks = r.safety.ticks_hold;
  r.damping_ticks = r.safety.ticks_damp + r.safety.ticks_estop;
  r.estop_ticks = r.safety.ticks_estop;
  r.max_joint_speed = max_joint_speed_;
  if (fastest_joint_ >= 0)
    r.fastest_joint = sim_->joint_names()[static_cast<std::size_t>(fastest_joint_)];
  const long long tolerance = scenario_.success.max_damping_ticks;
  if (static_cast<long long>(r.damping_ticks) > tolerance) {
    r.failed.push_back(std::to_string(r.damping_ticks) + " damping ticks > " +
                       std::to_string(tolerance));
    r.survived = false;
  }
}

}  // namespace poise::inprocess
