#include "poise/controller/balance_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "poise/controller/contact_fallback.hpp"
#include "poise/controller/foot_motion.hpp"
#include "poise/controller/momentum_rate.hpp"
#include "poise/controller/support_polygon.hpp"
#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"

namespace poise::controller {

namespace {

constexpr int kFeet = 2;

bool finite3(const Eigen::Vector3d& v) {
  return v.allFinite();
}

bool solution_usable(const contact::ContactSolution& s) {
  if (s.status == contact::ContactStatus::kInvalidInput ||
      s.status == contact::ContactStatus::kSolverFailure)
    return false;
  if (!finite3(s.k_dot_admissible) || !finite3(s.l_dot_admissible)) return false;
  for (const auto& f : s.feet)
    if (!finite3(f.force_W) || !finite3(f.torque_ankle_W)) return false;
  return true;
}

}  // namespace

const char* to_string(ContactSource s) {
  switch (s) {
    case ContactSource::kSolution:
      return "solution";
    case ContactSource::kReusedSolution:
      return "reused_solution";
    case ContactSource::kGravityDistribution:
      return "gravity_distribution";
  }
  return "unknown";
}

const char* to_string(FallReason r) {
  switch (r) {
    case FallReason::kNone:
      return "none";
    case FallReason::kTilt:
      return "tilt";
    case FallReason::kComHeight:
      return "com_height";
  }
  return "unknown";
}

std::string describe_fall(const TickDiagnostics& d, double tilt_limit_deg,
                          double com_height_fraction_limit) {
  if (!d.fallen) return "";
  char text[160];
  if (d.fall_reason == FallReason::kTilt)
    std::snprintf(text, sizeof text, "base tilt %.2f deg > %.1f deg", d.fall_tilt_deg,
                  tilt_limit_deg);
  else
    std::snprintf(text, sizeof text,
                  "CoM %.2f of its standing height above the lowest sole < %.2f",
                  d.fall_com_height_fraction, com_height_fraction_limit);
  return text;
}

BalanceController::BalanceController(const model::Model& model, const model::RobotConfig& robot,
                                     const ControllerConfig& config)
    : model_(model), robot_(robot), config_(config), data_(model_) {
  config_.validate();
  check_robot_matches_model();
  init_joint_tables();
  find_effort_limited_chains();
  init_upper_body();
  find_base_up();
  find_leg_joints();
  init_reference_leaks();
  com_height_ = nominal_com_height();
  allocate_workspace();
  init_contact_problem();
}

// Throws ConfigError when the robot configuration is not of this model.
void BalanceController::check_robot_matches_model() const {
  const int n = model_.njoints;
  if (n < 1) throw ConfigError("BalanceController: the model has no joints");
  if (robot_.q_nominal.size() != model_.nq)
    throw ConfigError("BalanceController: robot config q_nominal has size " +
                      std::to_string(robot_.q_nominal.size()) + ", model nq is " +
                      std::to_string(model_.nq) + " (robot config of another model?)");
  if (static_cast<int>(robot_.gains.size()) != n)
    throw ConfigError("BalanceController: robot config has gains for " +
                      std::to_string(robot_.gains.size()) + " joints, model has " +
                      std::to_string(n));
  for (int side = 0; side < kFeet; ++side) {
    const auto& foot = robot_.feet[side];
    if (foot.frame_id < 0 || foot.frame_id >= static_cast<int>(model_.frames.size()) ||
        model_.frames[foot.frame_id].name != foot.frame)
      throw ConfigError("BalanceController: foot frame '" + foot.frame +
                        "' does not match the model");
  }
}

// The joints' limits, efforts and gains (robot gains * gain_scale).
void BalanceController::init_joint_tables() {
  const int n = model_.njoints;
  q_min_.resize(n);
  q_max_.resize(n);
  effort_.resize(n);
  kp_.resize(n);
  kd_.resize(n);
  is_upper_.setZero(n);
  for (int j = 0; j < n; ++j) {
    q_min_[j] = model_.limits[j].lower;
    q_max_[j] = model_.limits[j].upper;
    effort_[j] = model_.limits[j].effort;
    kp_[j] = config_.feedback.gain_scale * robot_.gains[j].kp;
    kd_[j] = config_.feedback.gain_scale * robot_.gains[j].kd;
  }
}

// RobotConfig::effort_limited_sole: each foot's chain of revolute joints with a finite effort.
void BalanceController::find_effort_limited_chains() {
  if (robot_.effort_limited_sole)
    for (int side = 0; side < kFeet; ++side) {
      const int foot_body = model_.frames[robot_.feet[side].frame_id].body;
      for (int b = foot_body; b > 0; b = model_.parent[b]) {
        const int j = b - 1;
        const bool revolute = model_.joint_type[b] == model::JointType::kRevolute ||
                              model_.joint_type[b] == model::JointType::kContinuous;
        if (revolute && std::isfinite(effort_[j]) && effort_[j] > 0.0)
          foot_chain_[side].push_back(j);
      }
    }
}

// The upper-body joints and the nominal posture.
void BalanceController::init_upper_body() {
  const int n = model_.njoints;
  for (int j : robot_.upper_body_joint_indices) {
    if (j < 0 || j >= n)
      throw ConfigError("BalanceController: upper-body joint index out of range");
    is_upper_[j] = 1.0;
  }
  q_nominal_ = robot_.q_nominal.tail(n);
}

// MomentumGains::upright_pitch_rate: the base's up = the soles' normal (the foot frames'
// z, eq (36)'s convention) in the base frame, in the nominal posture.
void BalanceController::find_base_up() {
  model::forward_kinematics(model_, data_, robot_.q_nominal);
  model::update_frame_placements(model_, data_);
  const model::SE3 X_WB = model::base_pose(robot_.q_nominal);
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  for (int side = 0; side < kFeet; ++side)
    up += X_WB.R.transpose() *
          model::frame_placement(model_, data_, robot_.feet[side].frame_id).R.col(2);
  if (up.norm() > 1e-9) base_up_B_ = up.normalized();
}

// The joints between the base and each foot.
void BalanceController::find_leg_joints() {
  for (int side = 0; side < kFeet; ++side) {
    leg_joints_[side].clear();
    const int body = model_.frames[robot_.feet[side].frame_id].body;
    for (int v : model_.support[body])
      if (v >= 6) leg_joints_[side].push_back(v - 6);
  }
}

// The per-tick factors with which the integrated references (34)-(35) leak towards the measured
// joints (FeedbackConfig), and the internal-force split's metrics and workspace.
void BalanceController::init_reference_leaks() {
  const int n = model_.njoints;
  // FeedbackConfig::support_leg_leak_hz: the per-tick factor of a leg joint's reference error
  // while both feet are loaded (1 = the paper's integration; every other joint keeps 1).
  leg_keep_ = Eigen::VectorXd::Ones(n);
  if (config_.feedback.support_leg_leak_hz > 0.0) {
    const double keep = std::exp(-2.0 * M_PI * config_.feedback.support_leg_leak_hz * config_.dt);
    for (const auto& leg : leg_joints_)
      for (int j : leg)
        leg_keep_[j] = keep;
  }
  velocity_keep_ = config_.feedback.velocity_leak_hz > 0.0
                       ? std::exp(-2.0 * M_PI * config_.feedback.velocity_leak_hz * config_.dt)
                       : 1.0;
  touchdown_follow_keep_ =
      std::exp(-2.0 * M_PI * config_.feedback.touchdown_follow_hz * config_.dt);
  // FeedbackConfig::internal_force_leak_hz: the metrics 1/kp and 1/kd (a joint without a gain
  // makes no PD torque: it keeps its reference) and the fixed-size workspace of the split.
  if (config_.feedback.internal_force_leak_hz > 0.0)
    internal_drop_ =
        1.0 - std::exp(-2.0 * M_PI * config_.feedback.internal_force_leak_hz * config_.dt);
  inv_kp_ = Eigen::VectorXd::Zero(n);
  inv_kd_ = Eigen::VectorXd::Zero(n);
  for (int j = 0; j < n; ++j) {
    if (kp_[j] > 0.0) inv_kp_[j] = 1.0 / kp_[j];
    if (kd_[j] > 0.0) inv_kd_[j] = 1.0 / kd_[j];
  }
  internal_q_ = Eigen::VectorXd::Zero(n);
  internal_qd_ = Eigen::VectorXd::Zero(n);
  error_scratch_ = Eigen::VectorXd::Zero(n);
  internal_basis_.setZero(n, 6);
  weighted_basis_.setZero(n, 6);
  base_map_.setZero();
  internal_rhs_.setZero();
}

// Desired CoM height above the soles in the nominal posture (Sec. 4.2 target when no CoM target).
double BalanceController::nominal_com_height() {
  if (config_.com_height > 0.0) return config_.com_height;
  model::center_of_mass(model_, data_, robot_.q_nominal);
  double sole_z = 0.0;
  for (int side = 0; side < kFeet; ++side)
    sole_z += 0.5 * sole_center_W(model::frame_placement(model_, data_, robot_.feet[side].frame_id),
                                  robot_.feet[side].sole)
                        .z();
  const double height = data_.com.z() - sole_z;
  if (!(height > 0.0))
    throw ConfigError("BalanceController: the nominal CoM is not above the soles");
  return height;
}

// Every per-tick vector and matrix at its size (the tick allocates nothing).
void BalanceController::allocate_workspace() {
  const int n = model_.njoints;
  const int nv = model_.nv;
  solver_.resize(nv, 6 * kFeet);
  q_.setZero(model_.nq);
  v_.setZero(nv);
  qd_joint_.setZero(n);
  qdd_.setZero(nv);
  tau_.setZero(nv);
  C_.setZero(6 * kFeet, nv);
  jdot_v_.setZero(6 * kFeet);
  d_.setZero(6 * kFeet);
  w_.setZero(nv);
  t_.setZero(nv);
  lo_.setZero(n);
  hi_.setZero(n);
  qdd_u_ref_.setZero(n);
  q_u_target_.setZero(n);
  qd_u_target_.setZero(n);
  J_foot_.setZero(6, nv);
  q_ref_.setZero(n);
  qd_ref_.setZero(n);
  for (auto& V : V_WF_)
    V.setZero();
  for (auto& V : V_WF_previous_)
    V.setZero();
  for (auto& A : A_WF_filtered_)
    A.setZero();
}

// The contact problem's fields fixed per robot: soles, friction, weights, mass.
void BalanceController::init_contact_problem() {
  problem_.gravity = model_.gravity;
  for (int side = 0; side < kFeet; ++side) {
    const auto& foot = robot_.feet[side];
    auto& pf = problem_.feet[side];
    pf.sole.x_min = foot.sole.x_min;
    pf.sole.x_max = foot.sole.x_max;
    pf.sole.y_min = foot.sole.y_min;
    pf.sole.y_max = foot.sole.y_max;
    pf.ankle_height = foot.sole.height;
    pf.safety_margin = robot_.safety_margin;
    pf.mu = config_.contact.friction_mu > 0.0 ? config_.contact.friction_mu : robot_.friction_mu;
    pf.mu_torsion = robot_.torsional_mu;
  }
  problem_.weights.w_k = config_.contact.w_k;
  problem_.weights.eps_f = config_.contact.eps_f;
  problem_.weights.eps_cop = config_.contact.eps_cop;
  problem_.weights.priority = config_.contact.priority;
  problem_.mass = model_.total_mass;
}

RobotState BalanceController::make_state() const {
  RobotState s;
  s.resize(model_.njoints);
  return s;
}

BalanceReference BalanceController::make_reference() const {
  BalanceReference r;
  r.resize(model_.njoints);
  r.upper_body_q = q_nominal_;
  return r;
}

JointCommand BalanceController::make_command() const {
  JointCommand c;
  c.resize(model_.njoints);
  return c;
}

void BalanceController::reset() noexcept {
  diag_.fallen = false;
  diag_.fall_reason = FallReason::kNone;
  diag_.fall_tick = -1;
  have_references_ = false;
  have_hold_ = {false, false};
  planned_off_time_ = {0.0, 0.0};
  placed_ = {false, false};
  landed_unloaded_ = {false, false};
  rested_on_ground_ = {true, true};
  flag_off_time_ = {0.0, 0.0};
  have_hold_seen_ = false;
  have_foot_velocity_ = false;
  have_feedback_ = false;
  have_previous_solution_ = false;
  reuse_count_ = 0;
  for (auto& s : support_acc_stage_) s.setZero();
  com_offset_.reset();
  diag_.com_offset_W.setZero();
  diag_.hdot_admissible.setZero();
}

void BalanceController::prepare(const RobotState& state, const BalanceReference& reference,
                                contact::ContactProblem& problem) noexcept {
  diag_.tick = state.tick;
  state_ok_ = inputs_usable(state, reference);
  if (!state_ok_) {
    // Keep the previous problem but with no support: the answer is not used anyway.
    problem_without_support(problem);
    return;
  }
  const Eigen::Matrix3d R_WB = set_model_state(state);
  const double mass = data_.mass;

  // ---- a fallen robot (FallConfig): damping from here on, no contact problem ----------------
  if (!diag_.fallen) detect_fall(R_WB);
  if (diag_.fallen) {
    problem_without_support(problem);
    return;
  }

  // ---- feet: kinematics, supports, Sec. 4.2 resting rule, eq (36) -------------------------------
  const SupportSums supports = plan_feet(state, reference, mass * model_.gravity.norm());
  filter_support_acceleration(supports);
  observe_com_offset(state, supports.count, supports.velocity);
  const Eigen::Vector3d com = data_.com + com_offset_.offset();  // the robot's CoM, as estimated

  desired_com(reference, supports);
  desired_momentum_rate_eqs_10_11(reference, R_WB, com, mass);
  blend_ankle_first(com, mass, supports.count);
  diag_.hdot_desired.tail<3>() += mass * diag_.support_acceleration_W;
  upper_body_objective(reference);

  problem_.mass = mass;
  problem_.gravity = model_.gravity;
  problem_.com = com;
  problem_.k_dot_desired = diag_.hdot_desired.head<3>();
  problem_.l_dot_desired = diag_.hdot_desired.tail<3>();
  problem = problem_;
}

// The state and the reference have this robot's sizes and finite numbers.
bool BalanceController::inputs_usable(const RobotState& state,
                                      const BalanceReference& reference) const noexcept {
  const int n = model_.njoints;
  bool ok = state.q.size() == n && state.qd.size() == n && state.q.allFinite() &&
            state.qd.allFinite() && state.X_WB.R.allFinite() && state.X_WB.p.allFinite() &&
            finite3(state.v_WB) && finite3(state.omega_WB) &&
            reference.upper_body_qdd.size() == n && reference.upper_body_q.size() == n &&
            reference.upper_body_qd.size() == n && reference.upper_body_qd.allFinite() &&
            reference.upper_body_qdd.allFinite() && reference.upper_body_q.allFinite() &&
            reference.com_W.allFinite() && reference.com_velocity_W.allFinite() &&
            reference.k_W.allFinite();
  for (const auto& f : state.feet)
    ok = ok && f.cop_W.allFinite();
  return ok;
}

// The previous problem with no foot in contact (its answer is not used).
void BalanceController::problem_without_support(contact::ContactProblem& problem) const noexcept {
  problem = problem_;
  for (auto& f : problem.feet)
    f.in_contact = false;
}

// The model at the measured state: q_, v_, then A, A_dot qd, CoM, momentum, joint Jacobians and
// FK with velocities. Returns the base's orientation R_WB.
Eigen::Matrix3d BalanceController::set_model_state(const RobotState& state) noexcept {
  const int n = model_.njoints;
  // ---- generalized coordinates (model conventions, see model.hpp) ------------------------------
  model::set_base_pose(state.X_WB, q_);
  q_.tail(n) = state.q;
  const Eigen::Matrix3d R_WB = Eigen::Quaterniond(q_.segment<4>(3)).toRotationMatrix();
  v_.head<6>() = model::base_velocity_from_world(R_WB, state.v_WB, state.omega_WB);
  v_.tail(n) = state.qd;
  qd_joint_ = state.qd;

  // A, A_dot qd, CoM, momentum, joint Jacobians and FK with velocities.
  model::centroidal_momentum_matrix(model_, data_, q_, v_);
  diag_.com_W = data_.com;
  diag_.com_velocity_W = data_.vcom;
  diag_.h_W = data_.hg;
  return R_WB;
}

// Both feet: kinematics, support, Sec. 4.2 resting rule, eq (36) row, contact problem entry.
// `weight` = m |g|. Returns the support feet's sums.
BalanceController::SupportSums BalanceController::plan_feet(const RobotState& state,
                                                            const BalanceReference& reference,
                                                            double weight) noexcept {
  SupportSums sums;
  std::array<bool, kFeet> bears_load{false, false};  // support carrying support_force_fraction
  for (int i = 0; i < kFeet; ++i) {
    const auto& meas = state.feet[i];
    const auto& ref = reference.feet[i];
    foot_kinematics(i);
    const Eigen::Vector3d foot_acc = measured_foot_acceleration(i);
    const bool support = foot_is_support(i, meas, ref.mode, weight);
    bool loaded = false;
    const bool resting = apply_resting_rule(i, meas, support, weight, loaded);
    bears_load[i] = support && meas.normal_force > config_.support_force_fraction * weight;
    foot_motion_row_eq_36(i, ref, support, resting, loaded);
    if (support) {
      ++sums.count;
      sums.stand_point += stand_point_W(X_WF_[i], robot_.feet[i]);
      sums.velocity += V_WF_[i].head<3>();
      sums.acceleration += foot_acc;
    }
    contact_problem_foot(i, support, meas.normal_force);
  }
  have_foot_velocity_ = true;
  have_hold_seen_ = true;
  // The legs and the ground close a loop (FeedbackConfig::support_leg_leak_hz).
  both_feet_loaded_ = bears_load[0] && bears_load[1];
  return sums;
}

// Foot i's pose, velocity, Jacobian rows of C_ and J_dot qd; its held pose at the first tick.
void BalanceController::foot_kinematics(int i) noexcept {
  const auto& foot = robot_.feet[i];
  X_WF_[i] = model::frame_placement(model_, data_, foot.frame_id);
  V_WF_[i] = model::frame_velocity(model_, data_, foot.frame_id);
  model::frame_jacobian(model_, data_, foot.frame_id, J_foot_);
  C_.middleRows<6>(6 * i) = J_foot_;
  jdot_v_.segment<6>(6 * i) = model::frame_jdot_v(model_, data_, foot.frame_id);
  if (!have_hold_[i]) {
    X_WF_hold_[i] = X_WF_[i];
    have_hold_[i] = true;
  }
}

// Foot i's measured acceleration: A_WF_filtered_[i] (FootGains::support_acceleration_tau) and,
// returned, its linear part differenced over the tick and clamped (support_acceleration_hz).
Eigen::Vector3d BalanceController::measured_foot_acceleration(int i) noexcept {
  // Measured foot acceleration: velocity differenced over the tick, first-order low-pass.
  if (have_foot_velocity_ && config_.foot.support_acceleration_tau > 0.0) {
    const double alpha = config_.dt / (config_.foot.support_acceleration_tau + config_.dt);
    A_WF_filtered_[i] += alpha * ((V_WF_[i] - V_WF_previous_[i]) / config_.dt - A_WF_filtered_[i]);
  } else {
    A_WF_filtered_[i].setZero();
  }
  // Clamped per axis at 3 g: a support that accelerates more is out of reach anyway, and a
  // contact transient (a foot settling, an impact) is not a support's motion.
  const double acc_max = 3.0 * model_.gravity.norm();
  const Eigen::Vector3d foot_acc =
      have_foot_velocity_
          ? Eigen::Vector3d(((V_WF_[i].head<3>() - V_WF_previous_[i].head<3>()) / config_.dt)
                                .cwiseMax(-acc_max)
                                .cwiseMin(acc_max))
          : Eigen::Vector3d::Zero();
  V_WF_previous_[i] = V_WF_[i];
  return foot_acc;
}

// Whether foot i is a support this tick, from its reference mode (kAuto: its contact flag or
// measured load).
bool BalanceController::foot_is_support(int i, const FootMeasurement& meas, FootMode mode,
                                        double weight) noexcept {
  bool support = false;
  switch (mode) {
    case FootMode::kAuto:
      planned_off_time_[i] = 0.0;
      support = meas.in_contact || (config_.support_force_fraction > 0.0 &&
                                    meas.normal_force > config_.support_force_fraction * weight);
      break;
    case FootMode::kSupport: {
      // Planned, but a push may lift it: measured off the ground for planned_support_release,
      // it leaves the contact problem until it touches again. Off the ground: no contact
      // flag, no load, and the foot risen from where it last rested (a foot the weight went
      // off rests on the ground with a load below the flag's 1 %).
      const bool risen = have_hold_seen_ && X_WF_[i].p.z() - X_WF_hold_[i].p.z() >
                                                config_.planned_support_release_height;
      const bool touching =
          meas.in_contact || !risen || meas.normal_force > config_.support_force_fraction * weight;
      planned_off_time_[i] = touching ? 0.0 : planned_off_time_[i] + config_.dt;
      support = !(config_.planned_support_release > 0.0) ||
                planned_off_time_[i] < config_.planned_support_release - 1e-9;
      break;
    }
    case FootMode::kSwing:
      planned_off_time_[i] = 0.0;
      support = false;
      break;
  }
  return support;
}

// Sec. 4.2's resting rule for foot i; records its support, rest and touch-down of this tick.
// Returns whether it rests; `loaded`: it carries its resting load.
bool BalanceController::apply_resting_rule(int i, const FootMeasurement& meas, bool support,
                                           double weight, bool& loaded) noexcept {
  const auto& foot = robot_.feet[i];
  // Sec. 4.2: a support foot rests when its measured CoP is inside the safe region. The CoP of
  // a foot that carries no load means nothing (the simulator's truth puts it at the foot
  // origin, the estimator at zero; from a load within the F/T noise it is noise), so a foot
  // rests only with a measured load, not on its contact flag (which means "touching": a foot
  // resting on the ground with 0-5 N keeps it). A planned support that is not (or no longer)
  // loaded -- a foot tipped up by the other, a stepping foot just before it lands or after
  // the weight went over the other foot -- is held where it last rested instead of following
  // its own velocity, which let it drift (a step in place: up 0.32 m, or 18-24 mm of slip with
  // the flag of a touching foot taken for a load).
  // A foot back from the air (flag off for resting_touchdown_air_time since it last rested)
  // comes down with its swing's velocity: it rests only once it carries
  // resting_touchdown_force_fraction, then down to resting_force_fraction.
  flag_off_time_[i] = meas.in_contact ? 0.0 : flag_off_time_[i] + config_.dt;
  if (flag_off_time_[i] > config_.resting_touchdown_air_time + 1e-9) rested_on_ground_[i] = false;
  const double rest_fraction = rested_on_ground_[i] ? config_.resting_force_fraction
                                                    : config_.resting_touchdown_force_fraction;
  loaded = meas.normal_force > rest_fraction * weight;
  const bool resting = support && loaded &&
                       cop_in_safe_region(X_WF_[i], meas.cop_W, foot.sole,
                                          robot_.safety_margin + config_.resting_extra_margin);
  // Touch-down of a planned support (a swing foot set down, a support flag that comes back):
  // the leg's integrated references theta*, theta_dot* (34)-(35) ran ahead of the foot while
  // it moved and would press it into the ground through the joint PD with a load the contact
  // problem does not know of (a step in place: 90-170 N on the landed foot, planned 0, which
  // tipped the stance foot). finish() restarts them from the measured joints.
  touch_down_[i] = support && !diag_.support[i] && have_hold_seen_;
  diag_.support[i] = support;
  diag_.resting[i] = resting;
  if (resting) rested_on_ground_[i] = true;
  return resting;
}

// Eq (36): foot i's desired acceleration a_d towards its desired pose and velocity (a
// reference's target, its own when resting, else where it last rested), and its row of the
// foot-motion constraint, d_ = a_d - J_dot qd.
void BalanceController::foot_motion_row_eq_36(int i, const FootReference& ref, bool support,
                                              bool resting, bool loaded) noexcept {
  model::SE3 X_d = X_WF_hold_[i];
  model::Motion V_d = model::Motion::Zero();
  model::Motion a_support = model::Motion::Zero();
  if (ref.has_target) {
    X_d = ref.X_WF_target;
    V_d = ref.V_WF_target;
    X_WF_hold_[i] = ref.X_WF_target;  // where the foot stays when the target is dropped
    placed_[i] = true;
  } else if (resting || (support && !placed_[i])) {
    // Resting, or a support that has never rested nor been placed (released in the air:
    // no pose to hold yet, it moves with the body until it lands).
    placed_[i] = placed_[i] || resting;
    // Resting on a (possibly moving) support: follow it (v_d = v, T_d = T).
    X_d = X_WF_[i];
    V_d = V_WF_[i];
    X_WF_hold_[i] = X_WF_[i];
    a_support = A_WF_filtered_[i];  // shared with its support; zero when the filter is off
  }
  // A held foot back from the air (its flag off for more than resting_touchdown_air_time
  // since it last rested) and without load carries none of the contact forces: only its own
  // gains keep it where it stood (FootGains::unloaded_kp). A foot that touches, or lost its
  // flag for a few ticks only, keeps kp, kd: the ground holds it, and stiffer gains there pull
  // it against its support (a light foot on an accelerating platform).
  // Horizontally only: how the foot comes down (its height, its tilt) stays (36)'s with kp,
  // kd, so a foot set down by a swing lands as before (a stiffer vertical hold at the swing's
  // end pose left the step in place's landing touching with < 1 % of the weight and bouncing).
  model::Motion a_d = foot_acceleration(config_.foot, X_WF_[i], V_WF_[i], X_d, V_d) + a_support;
  if (!ref.has_target && !loaded && !rested_on_ground_[i]) {
    FootGains held;
    held.kp = config_.foot.unloaded_kp;
    held.kd = config_.foot.unloaded_kd;
    a_d.head<2>() =
        foot_acceleration(held, X_WF_[i], V_WF_[i], X_d, V_d).head<2>() + a_support.head<2>();
  }
  diag_.foot_acceleration_desired[i] = a_d;
  d_.segment<6>(6 * i) = a_d - jdot_v_.segment<6>(6 * i);
}

// Foot i in the contact problem: in contact when a support, its pose, and its sole
// (RobotConfig::effort_limited_sole: where the leg's joints can hold the measured load).
void BalanceController::contact_problem_foot(int i, bool support, double normal_force) noexcept {
  const auto& foot = robot_.feet[i];
  auto& pf = problem_.feet[i];
  pf.in_contact = support;
  pf.R_WF = X_WF_[i].R;
  pf.p_WF = X_WF_[i].p;
  if (robot_.effort_limited_sole) {
    pf.sole = {foot.sole.x_min, foot.sole.x_max, foot.sole.y_min, foot.sole.y_max};
    limit_sole_by_effort(i, normal_force, foot.sole.height, pf.sole);
  }
}

// The supports' acceleration (MomentumGains::support_acceleration_hz): three first-order
// stages, whose last is a_s and whose difference gives its rate without differencing noise;
// it decays to zero without a support.
void BalanceController::filter_support_acceleration(const SupportSums& supports) noexcept {
  const double support_w = 2.0 * M_PI * config_.momentum.support_acceleration_hz;  // [rad/s]
  if (support_w > 0.0) {
    const double a = config_.dt / (config_.dt + 1.0 / support_w);
    auto& st = support_acc_stage_;
    const Eigen::Vector3d raw = supports.count > 0
                                    ? Eigen::Vector3d(supports.acceleration / supports.count)
                                    : Eigen::Vector3d::Zero();
    st[0] += a * (raw - st[0]);
    st[1] += a * (st[0] - st[1]);
    st[2] += a * (st[1] - st[2]);
  }
}

// ---- desired CoM (reference, or Sec. 4.2: above the mid-point of the supports) ---------------
// The supports' points are their stand points: the sole centres as in the paper, unless
// robot.yaml puts the robot's weight elsewhere on the soles (FootConfig::stand_point).
void BalanceController::desired_com(const BalanceReference& reference,
                                    const SupportSums& supports) noexcept {
  diag_.support_acceleration_W.setZero();
  if (reference.has_com_target) {
    diag_.com_target_W = reference.com_W;
    diag_.com_velocity_target_W = reference.com_velocity_W;
    return;
  }
  Eigen::Vector3d sole_mean = supports.stand_point;
  Eigen::Vector3d foot_vel_mean = supports.velocity;
  if (supports.count == 0) {
    // No support (flight, or contact not detected yet): the rule over both feet.
    for (int i = 0; i < kFeet; ++i) {
      sole_mean += stand_point_W(X_WF_[i], robot_.feet[i]);
      foot_vel_mean += V_WF_[i].head<3>();
    }
  }
  const double count = supports.count > 0 ? supports.count : kFeet;
  diag_.com_target_W = sole_mean / count + Eigen::Vector3d(0.0, 0.0, com_height_);
  diag_.com_velocity_target_W = foot_vel_mean / count;
  // Accelerating supports (MomentumGains::support_acceleration_hz): the target leans into
  // their acceleration, d = k a_s, and its velocity target gets d's rate.
  const double support_w = 2.0 * M_PI * config_.momentum.support_acceleration_hz;  // [rad/s]
  if (support_w > 0.0) {
    const auto& st = support_acc_stage_;
    const double g_eff = std::max(0.1 * model_.gravity.norm(), model_.gravity.norm() + st[2].z());
    const double k = com_height_ / g_eff;
    diag_.com_target_W.head<2>() += k * st[2].head<2>();
    diag_.com_velocity_target_W.head<2>() += k * support_w * (st[1] - st[2]).head<2>();
    diag_.support_acceleration_W = st[2];
  }
}

// ---- eqs (10)-(11): the desired centroidal momentum rate (diag_.hdot_desired) -------------------
void BalanceController::desired_momentum_rate_eqs_10_11(const BalanceReference& reference,
                                                        const Eigen::Matrix3d& R_WB,
                                                        const Eigen::Vector3d& com,
                                                        double mass) noexcept {
  // MomentumGains::feedback_filter_hz: y += a (x - y), a = dt / (dt + 1 / (2 pi f)); exact at
  // the first tick after a reset.
  const double fc = config_.momentum.feedback_filter_hz;
  const Eigen::Vector3d vcom_error = diag_.com_velocity_target_W - data_.vcom;
  if (fc > 0.0 && have_feedback_) {
    const double a = config_.dt / (config_.dt + 1.0 / (2.0 * M_PI * fc));
    vcom_error_filtered_ += a * (vcom_error - vcom_error_filtered_);
    k_filtered_ += a * (data_.hg.head<3>() - k_filtered_);
  } else {  // no filter (the paper's equations as written), or the first tick
    vcom_error_filtered_ = vcom_error;
    k_filtered_ = data_.hg.head<3>();
  }
  have_feedback_ = true;
  // MomentumGains::upright_pitch_rate, upright_roll_rate: k_d += I_G omega_u.
  Eigen::Vector3d k_d = reference.k_W;
  const double r_pitch = config_.momentum.upright_pitch_rate;
  const double r_roll = config_.momentum.upright_roll_rate;
  if (r_pitch > 0.0 || r_roll > 0.0)
    k_d += upright_angular_momentum(R_WB, base_up_B_, robot_.forward_axis,
                                    -model_.gravity.normalized(), data_.Ag.block<3, 3>(0, 3),
                                    r_pitch, r_roll);
  diag_.hdot_desired =
      desired_momentum_rate(config_.momentum, mass, k_filtered_, k_d, com, diag_.com_target_W,
                            Eigen::Vector3d::Zero(), vcom_error_filtered_);
}

// MomentumGains::ankle_first_blend (support_polygon.hpp): the ankle strategy before the hip's.
void BalanceController::blend_ankle_first(const Eigen::Vector3d& com, double mass,
                                          int num_support) noexcept {
  diag_.ankle_first_beta = 1.0;
  if (config_.momentum.ankle_first_blend > 0.0 && num_support > 0) {
    polygon_.clear();
    const double m = robot_.safety_margin;
    for (int i = 0; i < kFeet; ++i) {
      if (!problem_.feet[i].in_contact) continue;
      const auto& sole = robot_.feet[i].sole;
      for (const double x : {sole.x_min + m, sole.x_max - m})
        for (const double y : {sole.y_min + m, sole.y_max - m})
          polygon_.add(X_WF_[i].act(Eigen::Vector3d(x, y, -sole.height)).head<2>());
    }
    polygon_.hull();
    const double omega = std::sqrt(model_.gravity.norm() / com_height_);
    const AnkleFirstRate r = ankle_first_rate(diag_.hdot_desired.segment<2>(3) / mass,
                                              com.head<2>(), vcom_error_filtered_.head<2>(), omega,
                                              polygon_, config_.momentum.ankle_first_blend);
    diag_.hdot_desired.segment<2>(3) = mass * r.acceleration;
    diag_.ankle_first_beta = r.beta;
  }
}

// Upper-body objective of this tick.
void BalanceController::upper_body_objective(const BalanceReference& reference) noexcept {
  qdd_u_ref_ = reference.upper_body_qdd;
  if (reference.has_upper_body_q) {
    q_u_target_ = reference.upper_body_q;
    qd_u_target_ = reference.upper_body_qd;
  } else {
    q_u_target_ = q_nominal_;
    qd_u_target_.setZero();
  }
}

// ControllerConfig::com_offset (com_offset_observer.hpp): the supports' force-weighted measured
// CoP and the model's CoM velocity relative to the supports.
void BalanceController::observe_com_offset(const RobotState& state, int num_support,
                                           const Eigen::Vector3d& foot_vel_sum) noexcept {
  Eigen::Vector3d cop = Eigen::Vector3d::Zero();
  double fz = 0.0;
  for (int i = 0; i < kFeet; ++i) {
    const auto& meas = state.feet[i];
    if (!diag_.support[i] || !(meas.normal_force > 0.0)) continue;
    cop += meas.normal_force * meas.cop_W;
    fz += meas.normal_force;
  }
  if (fz > 0.0) cop /= fz;
  const Eigen::Vector3d vrel =
      num_support > 0 ? Eigen::Vector3d(data_.vcom - foot_vel_sum / num_support) : data_.vcom;
  com_offset_.update(config_.com_offset, config_.dt, cop, fz, data_.mass * model_.gravity.norm(),
                     data_.com, vrel);
  diag_.com_offset_W = com_offset_.offset();
  diag_.com_offset_learning = com_offset_.learning();
}

// RobotConfig::effort_limited_sole. Statics of the leg below each joint j of the foot's chain
// (axis u through o, world): with the normal force fz at the CoP p and gravity on the bodies
// below j, the joint holds tau_j(p) = a . (g sum_k m_k (c_k - o) - fz (p - o)), a = up x u.
// |tau_j| <= L_j is a slab a . p in [lo, hi]; on the sole plane (p = X_WF (x, y, -h)) a slab
// along the sole's x or y. Each slab cuts the rectangle where it holds for every point of it
// (x-like slabs first over the whole width, then y-like over the x left), conservative for a
// slanted axis. A rectangle cut narrower than 2 margin + 4 mm keeps that width, centred where
// the cuts point (clamped to the sole): the joint cannot hold the load anywhere there, and the
// optimiser still needs a safe region. Horizontal forces and accelerations are not counted.
void BalanceController::limit_sole_by_effort(int i, double fz, double h,
                                             contact::SoleRectangle& sole) const noexcept {
  const double g = model_.gravity.norm();
  if (!(fz > 1e-3 * data_.mass * g)) return;
  const Eigen::Vector3d up = -model_.gravity / g;
  const model::SE3& X = X_WF_[i];
  const contact::SoleRectangle full = sole;
  double xl = full.x_min, xh = full.x_max, yl = full.y_min, yh = full.y_max;
  for (int pass = 0; pass < 2; ++pass)
    for (int j : foot_chain_[i]) {
      const int b = j + 1;
      const Eigen::Vector3d a = up.cross(data_.oMi[b].R * model_.axis[b]);
      const Eigen::Vector3d aF = X.R.transpose() * a;
      const bool along_x = std::abs(aF.x()) >= std::abs(aF.y());
      if (along_x != (pass == 0) || std::max(std::abs(aF.x()), std::abs(aF.y())) < 1e-9) continue;
      const Eigen::Vector3d& o = data_.oMi[b].p;
      Eigen::Vector3d G = Eigen::Vector3d::Zero();
      for (int k = b; k <= model_.subtree_end[b]; ++k)
        G += model_.inertia[k].mass * (data_.oMi[k].act(model_.inertia[k].com) - o);
      // tau = c0 - fz (aF.x x + aF.y y)
      const double c0 = g * a.dot(G) + fz * a.dot(o) - fz * (a.dot(X.p) - aF.z() * h);
      const double lo = (c0 - effort_[j]) / fz, hi = (c0 + effort_[j]) / fz;
      if (along_x) {
        const double t_lo = std::min(aF.y() * yl, aF.y() * yh), t_hi = std::max(aF.y() * yl, aF.y() * yh);
        double x_a = (lo - t_lo) / aF.x(), x_b = (hi - t_hi) / aF.x();
        if (aF.x() < 0.0) std::swap(x_a, x_b);
        xl = std::max(xl, x_a);
        xh = std::min(xh, x_b);
      } else {
        const double t_lo = std::min(aF.x() * xl, aF.x() * xh), t_hi = std::max(aF.x() * xl, aF.x() * xh);
        double y_a = (lo - t_lo) / aF.y(), y_b = (hi - t_hi) / aF.y();
        if (aF.y() < 0.0) std::swap(y_a, y_b);
        yl = std::max(yl, y_a);
        yh = std::min(yh, y_b);
      }
    }
  const double w = 2.0 * robot_.safety_margin + 0.004;
  auto keep_width = [w](double& l, double& hgh, double full_l, double full_h) {
    if (hgh - l >= w || full_h - full_l < w) {
      l = std::clamp(l, full_l, full_h);
      hgh = std::clamp(hgh, full_l, full_h);
      if (hgh - l < w) l = full_l, hgh = full_h;
      return;
    }
    const double c = std::clamp(0.5 * (l + hgh), full_l + 0.5 * w, full_h - 0.5 * w);
    l = c - 0.5 * w;
    hgh = c + 0.5 * w;
  };
  keep_width(xl, xh, full.x_min, full.x_max);
  keep_width(yl, yh, full.y_min, full.y_max);
  sole = {xl, xh, yl, yh};
}

void BalanceController::detect_fall(const Eigen::Matrix3d& R_WB) noexcept {
  const Eigen::Vector3d up = -model_.gravity.normalized();
  const double cos_tilt = std::clamp((R_WB * base_up_B_).dot(up), -1.0, 1.0);
  const double tilt_deg = std::acos(cos_tilt) * 180.0 / M_PI;
  double lowest_sole = std::numeric_limits<double>::infinity();
  for (int i = 0; i < kFeet; ++i)
    lowest_sole = std::min(
        lowest_sole,
        up.dot(sole_center_W(model::frame_placement(model_, data_, robot_.feet[i].frame_id),
                             robot_.feet[i].sole)));
  const double fraction = (up.dot(data_.com) - lowest_sole) / com_height_;
  FallReason reason = FallReason::kNone;
  if (tilt_deg > config_.fall.tilt_deg)
    reason = FallReason::kTilt;
  else if (config_.fall.com_height_fraction > 0.0 && fraction < config_.fall.com_height_fraction)
    reason = FallReason::kComHeight;
  if (reason == FallReason::kNone) return;
  diag_.fallen = true;
  diag_.fall_reason = reason;
  diag_.fall_tick = diag_.tick;
  diag_.fall_tilt_deg = tilt_deg;
  diag_.fall_com_height_fraction = fraction;
}

void BalanceController::finish(const contact::ContactSolution& solution,
                               JointCommand& command) noexcept {
  if (!command_sized(command)) return;
  if (!state_ok_ || diag_.fallen) {
    command_damping(command);
    return;
  }
  if (!solution_usable(solution)) {
    finish_fallback(command);
    return;
  }
  reuse_count_ = 0;
  finish_with(solution, ContactSource::kSolution, command);
}

void BalanceController::finish_fallback(JointCommand& command) noexcept {
  if (!command_sized(command)) return;
  ++diag_.late_solutions;
  if (!state_ok_ || diag_.fallen) {
    command_damping(command);
    return;
  }
  const bool same_support = have_previous_solution_ &&
                            previous_support_[0] == problem_.feet[0].in_contact &&
                            previous_support_[1] == problem_.feet[1].in_contact;
  if (same_support && reuse_count_ < config_.fallback.max_reuse_ticks) {
    ++reuse_count_;
    solution_ = previous_solution_;
    finish_with(solution_, ContactSource::kReusedSolution, command);
    return;
  }
  gravity_distribution(problem_, solution_);
  finish_with(solution_, ContactSource::kGravityDistribution, command);
}

bool BalanceController::command_sized(const JointCommand& command) const noexcept {
  const Eigen::Index n = model_.njoints;
  return command.tau_ff.size() == n && command.q_ref.size() == n && command.qd_ref.size() == n &&
         command.kp.size() == n && command.kd.size() == n;
}

void BalanceController::command_damping(JointCommand& command) noexcept {
  command.tick = diag_.tick;
  command.mode = CommandMode::kDamping;
  command.tau_ff.setZero();
  command.kp.setZero();
  command.kd = kd_;
  ++diag_.ticks;
}

void BalanceController::finish_with(const contact::ContactSolution& solution, ContactSource source,
                                    JointCommand& command) noexcept {
  record_applied_wrenches(solution, source);
  joint_accelerations_eq_33();
  inverse_dynamics_torques(solution, command);
  joint_references_eqs_34_35(solution);

  command.tick = diag_.tick;
  command.mode = CommandMode::kTorque;
  command.q_ref = q_ref_;
  command.qd_ref = qd_ref_;
  command.kp = kp_;
  command.kd = kd_;
  ++diag_.ticks;
}

// The wrenches applied this tick: kept for a later fallback (a fresh solution or the gravity
// distribution), their admissible momentum rate and the feet's wrenches in the diagnostics.
void BalanceController::record_applied_wrenches(const contact::ContactSolution& solution,
                                                ContactSource source) noexcept {
  diag_.contact_source = source;
  if (source == ContactSource::kSolution || source == ContactSource::kGravityDistribution) {
    previous_solution_ = solution;
    previous_support_ = {problem_.feet[0].in_contact, problem_.feet[1].in_contact};
    have_previous_solution_ = true;
  }

  // Admissible momentum rate of the wrenches actually applied, about the current CoM.
  diag_.hdot_admissible = momentum_rate_of_wrenches(problem_, solution);
  for (int i = 0; i < kFeet; ++i) {
    if (problem_.feet[i].in_contact) {
      diag_.foot_wrench_W[i].head<3>() = solution.feet[i].force_W;
      diag_.foot_wrench_W[i].tail<3>() = solution.feet[i].torque_ankle_W;
    } else {
      diag_.foot_wrench_W[i].setZero();
    }
  }
}

// ---- eq (33) ----------------------------------------------------------------------------------
// The joint accelerations qdd_: the admissible momentum rate, the feet's motion rows (36), the
// posture and upper-body objectives, within the joints' acceleration bounds.
void BalanceController::joint_accelerations_eq_33() noexcept {
  const int n = model_.njoints;
  const auto& acfg = config_.acceleration;
  posture_objective();
  joint_acceleration_bounds(q_.tail(n), v_.tail(n), q_min_, q_max_, acfg.limit_horizon,
                            acfg.max_joint_acceleration, lo_, hi_);
  model::Vector6 b = diag_.hdot_admissible - data_.dAg_v;
  const AccelerationSolver::Result r =
      solver_.solve(data_.Ag, b, acfg.w_b, w_, t_, C_, d_, lo_, hi_, qdd_);
  diag_.qp_status = r.status;
  diag_.qp_iterations = r.iterations;
  diag_.active_bounds = r.active_bounds;
  diag_.dependent_rows = r.dependent_rows;
  diag_.bounds_dropped = r.bounds_dropped;
  if (r.status != contact::SolverStatus::kOptimal || r.bounds_dropped) ++diag_.qp_failures;
  if (!qdd_.allFinite() || r.status == contact::SolverStatus::kInvalidInput ||
      r.status == contact::SolverStatus::kNotPositiveDefinite)
    qdd_.setZero();
  diag_.hdot_achieved.noalias() = data_.Ag * qdd_;
  diag_.hdot_achieved += data_.dAg_v;
  diag_.momentum_residual = (diag_.hdot_achieved - diag_.hdot_admissible).norm();
  double cres = 0.0;
  for (int row = 0; row < 6 * kFeet; ++row)
    cres = std::max(cres, std::abs(C_.row(row).dot(qdd_) - d_[row]));
  diag_.constraint_residual = cres;
}

// Eq (33)'s weights w_ and targets t_: the posture prior everywhere, blended with the upper-body
// objective on the upper-body joints.
void BalanceController::posture_objective() noexcept {
  const int n = model_.njoints;
  const auto& acfg = config_.acceleration;
  const double w_u = 1.0 - acfg.w_b;
  const double w_p = acfg.posture_weight;
  // Base: posture prior = damping of the base velocity.
  w_.head<6>().setConstant(w_p);
  t_.head<6>() = -acfg.posture_kd * v_.head<6>();
  for (int j = 0; j < n; ++j) {
    const double q = q_[7 + j];
    const double qd = v_[6 + j];
    const double t_post = acfg.posture_kp * (q_nominal_[j] - q) - acfg.posture_kd * qd;
    if (is_upper_[j] > 0.0) {
      const double t_u = qdd_u_ref_[j] + acfg.upper_body_kp * (q_u_target_[j] - q) +
                         acfg.upper_body_kd * (qd_u_target_[j] - qd);
      w_[6 + j] = w_u + w_p;
      t_[6 + j] = (w_u * t_u + w_p * t_post) / (w_u + w_p);
    } else {
      w_[6 + j] = w_p;
      t_[6 + j] = t_post;
    }
  }
}

// ---- feed-forward torques: inverse dynamics with the admissible wrenches -----------------------
void BalanceController::inverse_dynamics_torques(const contact::ContactSolution& solution,
                                                 JointCommand& command) noexcept {
  const int n = model_.njoints;
  model::clear_external_forces(data_);
  for (int i = 0; i < kFeet; ++i) {
    if (!problem_.feet[i].in_contact) continue;
    model::add_external_wrench(model_, data_, robot_.feet[i].frame_id, X_WF_[i].p,
                               solution.feet[i].force_W, solution.feet[i].torque_ankle_W);
  }
  tau_ = model::rnea(model_, data_, q_, v_, qdd_);
  diag_.base_wrench_residual = tau_.head<6>().norm();
  int sat = 0;
  for (int j = 0; j < n; ++j) {
    double tau = tau_[6 + j];
    if (std::isfinite(effort_[j]) && std::abs(tau) > effort_[j]) {
      tau = std::clamp(tau, -effort_[j], effort_[j]);
      ++sat;
    }
    command.tau_ff[j] = tau;
  }
  diag_.torque_saturations = sat;
}

// ---- theta*, theta_dot* integrated from qdd_a (34)-(35) ----------------------------------------
void BalanceController::joint_references_eqs_34_35(
    const contact::ContactSolution& solution) noexcept {
  restart_references();
  internal_reference_errors();
  diag_.reference_clamps = integrate_references();
  follow_touched_down_legs(solution);
}

// The references restart from the measured joints: at the first tick, and on a touched-down
// foot's leg.
void BalanceController::restart_references() noexcept {
  const int n = model_.njoints;
  if (!have_references_) {
    q_ref_ = q_.tail(n);
    qd_ref_ = qd_joint_;
    have_references_ = true;
  }
  for (int i = 0; i < kFeet; ++i) {
    if (!touch_down_[i]) continue;
    for (int j : leg_joints_[i]) {
      q_ref_[j] = q_[7 + j];
      qd_ref_[j] = 0.0;  // the ground stops the foot: not the leg's velocity at the impact
    }
  }
}

// FeedbackConfig::internal_force_leak_hz: the internal parts of the reference errors, from
// this tick's foot Jacobians (before this tick's integration; zero when off or not both
// feet bear load, or when the split is not solvable).
void BalanceController::internal_reference_errors() noexcept {
  const int n = model_.njoints;
  internal_q_.setZero();
  internal_qd_.setZero();
  if (internal_drop_ > 0.0 && both_feet_loaded_ && internal_split_basis()) {
    error_scratch_ = q_ref_ - q_.tail(n);
    if (!internal_part(error_scratch_, inv_kp_, internal_q_)) internal_q_.setZero();
    error_scratch_ = qd_ref_ - qd_joint_;
    if (!internal_part(error_scratch_, inv_kd_, internal_qd_)) internal_qd_.setZero();
  }
}

// Eqs (34)-(35): theta_dot* += qdd dt, theta* += theta_dot* dt (with the leaks of
// FeedbackConfig), clamped around the measured joints and to the joint limits. Returns the
// number of clamps.
int BalanceController::integrate_references() noexcept {
  const int n = model_.njoints;
  const double dt = config_.dt;
  const auto& fb = config_.feedback;
  int clamps = 0;
  for (int j = 0; j < n; ++j) {
    const double q = q_[7 + j];
    const double qd = qd_joint_[j];
    // The internal part removed at internal_drop_ per tick (zero when off): the rest of the
    // error, and the integration below, are the paper's.
    q_ref_[j] -= internal_drop_ * internal_q_[j];
    qd_ref_[j] -= internal_drop_ * internal_qd_[j];
    // FeedbackConfig::support_leg_leak_hz: only while both feet bear load do the legs' references
    // decay towards the measured joints; a leg whose foot a push lifted keeps its integrated
    // references (its joint PD holds the leg's shape).
    const double keep = both_feet_loaded_ ? leg_keep_[j] : 1.0;
    // FeedbackConfig::velocity_leak_hz: every joint's theta_dot* decays towards the measured
    // velocity as well (composes with the leg leak). keep_v == 1: the paper's integration,
    // written as before (bit for bit).
    const double keep_v = keep * velocity_keep_;
    double vr = keep_v < 1.0 ? qd + keep_v * (qd_ref_[j] - qd) + qdd_[6 + j] * dt
                             : qd_ref_[j] + qdd_[6 + j] * dt;
    if (std::abs(vr - qd) > fb.max_velocity_error) {
      vr = qd + std::clamp(vr - qd, -fb.max_velocity_error, fb.max_velocity_error);
      ++clamps;
    }
    double pr = keep < 1.0 ? q + keep * (q_ref_[j] - q) + vr * dt : q_ref_[j] + vr * dt;
    if (std::abs(pr - q) > fb.max_position_error) {
      pr = q + std::clamp(pr - q, -fb.max_position_error, fb.max_position_error);
      ++clamps;
    }
    if (pr < q_min_[j]) pr = q_min_[j];
    if (pr > q_max_[j]) pr = q_max_[j];
    qd_ref_[j] = vr;
    q_ref_[j] = pr;
  }
  return clamps;
}

// FeedbackConfig::touchdown_follow_fraction: a support touched down and not planned a load
// yet keeps its leg's references on the measured joints (after the integration, which the
// other joints keep), so the leg's PD presses the foot with nothing the plan does not know.
void BalanceController::follow_touched_down_legs(
    const contact::ContactSolution& solution) noexcept {
  const double follow_load =
      config_.feedback.touchdown_follow_fraction * problem_.mass * model_.gravity.norm();
  for (int i = 0; i < kFeet; ++i) {
    if (!problem_.feet[i].in_contact || !(config_.feedback.touchdown_follow_fraction > 0.0)) {
      landed_unloaded_[i] = false;
      continue;
    }
    if (touch_down_[i]) landed_unloaded_[i] = true;
    const double planned = solution.feet[i].force_W.dot(X_WF_[i].R.col(2));
    if (planned > follow_load) landed_unloaded_[i] = false;
    if (!landed_unloaded_[i]) continue;
    const double keep = touchdown_follow_keep_;
    for (int j : leg_joints_[i]) {
      q_ref_[j] = q_[7 + j] + keep * (q_ref_[j] - q_[7 + j]);
      qd_ref_[j] = qd_joint_[j] + keep * (qd_ref_[j] - qd_joint_[j]);
    }
  }
}

// The legs' internal-force split (FeedbackConfig::internal_force_leak_hz). A torque t (dim n) is
// a pure internal force of the two feet when t = J_q^T lambda for foot wrenches lambda (12) that
// balance on the base, J_b^T lambda = 0 (J = C_, stacked [foot 0; foot 1], J_b its 6 base columns,
// J_q its joint columns). With B0, B1 the two feet's 6x6 base blocks (invertible: a foot's twist
// from the floating base's), J_b^T lambda = 0 is lambda_0 = -B0^-T B1^T lambda_1, so the internal
// torques are the range of the n x 6 basis  A = J_q1^T - J_q0^T B0^-T B1^T.
bool BalanceController::internal_split_basis() {
  const int n = static_cast<int>(internal_basis_.rows());
  base_lu_.compute(C_.block<6, 6>(0, 0).transpose());
  base_map_.noalias() = base_lu_.solve(C_.block<6, 6>(6, 0).transpose());  // B0^-T B1^T
  internal_basis_ = C_.block(6, 6, 6, n).transpose();
  internal_basis_.noalias() -= C_.block(0, 6, 6, n).transpose() * base_map_;
  return internal_basis_.allFinite();
}

// The W^-1-orthogonal projection of the joint error e onto the internal directions W range(A),
// W = diag(w) = diag(1/gain): e_int = W A z with (A^T W A) z = A^T e. Then the torque of e_int,
// diag(1/w) e_int = A z, is internal, and the rest e - e_int satisfies A^T (e - e_int) = 0, i.e.
// J_q (e - e_int) lies in the range of J_b: a motion of the legs that a base motion closes (both
// feet stay where they are). Singular legs (a straight knee) make A^T W A singular: a small
// relative regulariser keeps z bounded.
bool BalanceController::internal_part(const Eigen::VectorXd& e, const Eigen::VectorXd& w,
                                      Eigen::VectorXd& out) {
  weighted_basis_.noalias() = w.asDiagonal() * internal_basis_;
  Eigen::Matrix<double, 6, 6> S;
  S.noalias() = internal_basis_.transpose() * weighted_basis_;
  S.diagonal().array() += 1e-12 * (S.trace() / 6.0) + 1e-300;
  internal_ldlt_.compute(S);
  internal_rhs_.noalias() = internal_basis_.transpose() * e;
  internal_rhs_ = internal_ldlt_.solve(internal_rhs_);
  if (!internal_rhs_.allFinite()) return false;
  out.noalias() = weighted_basis_ * internal_rhs_;
  return out.allFinite();
}

}  // namespace poise::controller
