#include "poise/inprocess/in_process_loop.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "poise/model/kinematics.hpp"
#if POISE_INPROCESS_HAVE_ESTIMATOR
#include "poise/estimator/estimator.hpp"
#include "poise/inprocess/estimator_frame.hpp"
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
};
#else
struct InProcessLoop::EstimatorParts {};
#endif

InProcessLoop::InProcessLoop(const scenario::Scenario& scenario, const LoopOptions& options)
    : scenario_(scenario),
      options_(options),
      optimizer_(options.contact_method),
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
  controller_ = std::make_unique<controller::BalanceController>(model_, robot_, ccfg);

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

  if (options_.state_source == StateSource::kEstimator) {
#if POISE_INPROCESS_HAVE_ESTIMATOR
    estimator::EstimatorConfig ecfg;
    ecfg.dt = sim_->dt();
    ecfg.init_base_x = scenario_.sim.initial.base_position.x();
    ecfg.init_base_y = scenario_.sim.initial.base_position.y();
    ecfg.supports = estimator::parse_support_model(scenario_.estimator.supports);
    ecfg.kind = estimator::parse_estimator_kind(
        options_.estimator.empty() ? scenario_.estimator.type : options_.estimator);
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
  if (!scenario_.reference.empty()) {
    try {
      reference_player_ = std::make_unique<reference::Sampler>(
          reference::load_trajectory(scenario_.reference.string()), model_, robot_);
    } catch (const std::exception& e) {
      throw std::runtime_error("scenario '" + scenario_.name + "', reference: " + e.what());
    }
  }
  sim_->read(sensors_, truth_);
  latency_us_.reserve(static_cast<std::size_t>(std::ceil(duration_ / sim_->dt())) + 16);
}

InProcessLoop::~InProcessLoop() = default;

double InProcessLoop::time() const {
  return sim_->time();
}

void InProcessLoop::read_state() {
  const int n = model_.njoints;
  state_.tick = sensors_.tick;
  state_.time = sensors_.time;
#if POISE_INPROCESS_HAVE_ESTIMATOR
  if (estimator_) {
    to_estimator_frame(sensors_, sim_to_model_, sim_foot_of_side_, estimator_->frame);
    auto& e = estimator_->out;
    estimator_->est.update(estimator_->frame, e);
    state_.X_WB = e.X_WB;
    state_.v_WB = e.v_WB;
    state_.omega_WB = e.omega_WB;
    state_.q = e.q;
    state_.qd = e.qd;
    state_.com_W = e.com_W;
    state_.com_velocity_W = e.com_velocity_W;
    state_.k_W = e.k_W;
    state_.l_W = e.l_W;
    for (int side = 0; side < 2; ++side) {
      auto& f = state_.feet[side];
      f.in_contact = e.feet[side].in_contact;
      f.X_WF = e.feet[side].X_WF;
      f.V_WF = e.feet[side].V_WF;
      f.cop_W = e.feet[side].cop_W;
      f.normal_force = e.feet[side].normal_force;
    }
    return;
  }
#endif
  // DEBUG state source: the simulator's ground truth (joints from the encoders).
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
}

void InProcessLoop::play_reference() {
  if (!reference_player_) return;
  const std::array<model::SE3, 2> X_WF{state_.feet[0].X_WF, state_.feet[1].X_WF};
  reference_player_->sample(state_.time, state_.com_W, X_WF, reference_);
}

void InProcessLoop::step() {
  const auto t0 = std::chrono::steady_clock::now();
  read_state();
  play_reference();
  controller_->tick(
      state_, reference_,
      [this](const contact::ContactProblem& p, contact::ContactSolution& s) {
        optimizer_.solve(p, s);
        return true;
      },
      command_);
  const int n = model_.njoints;
  sim_command_.tick = command_.tick;
  switch (command_.mode) {
    case controller::CommandMode::kTorque:
      sim_command_.mode = sim::CommandMode::kPd;
      break;
    case controller::CommandMode::kDamping:
    case controller::CommandMode::kZero:
      sim_command_.mode = sim::CommandMode::kDamping;
      break;
  }
  for (int j = 0; j < n; ++j) {
    const int i = model_to_sim_[j];
    sim_command_.tau_ff[i] = command_.tau_ff[j];
    sim_command_.q_ref[i] = command_.q_ref[j];
    sim_command_.qd_ref[i] = command_.qd_ref[j];
    sim_command_.kp[i] = command_.kp[j];
    sim_command_.kd[i] = command_.kd[j];
  }
  const auto t1 = std::chrono::steady_clock::now();
  const double us = std::chrono::duration<double, std::micro>(t1 - t0).count();
  if (latency_us_.size() < latency_us_.capacity()) latency_us_.push_back(us);
  if (us > 1e6 * sim_->dt()) ++deadline_misses_;

  if (sim_->step(sim_command_, sensors_, truth_) != sim::StepStatus::kOk) ++rejected_commands_;
  monitor_.update(truth_);
  wall_ += std::chrono::steady_clock::now() - t0;
}

RunResult InProcessLoop::run(const std::function<void(double)>& progress) {
  const double dt = sim_->dt();
  const auto steps = static_cast<std::int64_t>(std::llround(duration_ / dt));
  double next_report = 1.0;
  while (sim_->tick() < steps) {
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
  r.non_foot_contacts = m.non_foot_contacts;
  r.min_base_height_m = m.min_base_height_m;
  r.recovery_time_s = m.last_recovery_time_s;
  r.trunk_pitch_max_deg = m.trunk_pitch_max_deg;
  r.trunk_roll_max_deg = m.trunk_roll_max_deg;
  r.failed = monitor_.failed_criteria();
  std::vector<double> lat = latency_us_;
  if (!lat.empty()) {
    std::sort(lat.begin(), lat.end());
    auto pct = [&](double p) {
      const auto idx = static_cast<std::size_t>(std::ceil(p * static_cast<double>(lat.size()))) - 1;
      return lat[std::min(idx, lat.size() - 1)];
    };
    r.tick_latency_us = {pct(0.5), pct(0.99), lat.back()};
  }
  r.deadline_misses = deadline_misses_;
  const double wall = std::chrono::duration<double>(wall_).count();
  r.sim_time_s = time();
  r.realtime_factor = wall > 0.0 ? r.sim_time_s / wall : 0.0;
  r.state_source = estimator_ ? StateSource::kEstimator : StateSource::kGroundTruth;
  r.ticks = controller_->diagnostics().ticks;
  r.contact_fallbacks = controller_->diagnostics().late_solutions;
  r.qp_failures = controller_->diagnostics().qp_failures;
  r.rejected_commands = rejected_commands_;
  return r;
}

}  // namespace poise::inprocess
