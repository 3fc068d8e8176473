#include "poise/estimator/estimator.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "poise/model/centroidal.hpp"
#include "poise/model/kinematics.hpp"

namespace poise::estimator {

namespace {

bool positive_finite(double x) {
  return std::isfinite(x) && x > 0.0;
}

void require(bool ok, const std::string& what) {
  if (!ok) throw EstimatorError("Estimator configuration: " + what);
}

int frame_of(const model::Model& model, const std::string& name, const char* what) {
  if (!model.has_frame(name))
    throw EstimatorError(std::string("Estimator configuration: ") + what + " frame '" + name +
                         "' is not a link of model '" + model.name + "'");
  return model.frame_id(name);
}

bool finite(const SE3& X) {
  return X.R.allFinite() && X.p.allFinite();
}

}  // namespace

const char* to_string(EstimatorKind k) noexcept {
  return k == EstimatorKind::kLegOdometry ? "leg-odometry" : "invariant-ekf";
}

EstimatorKind parse_estimator_kind(const std::string& text) {
  if (text == "invariant-ekf") return EstimatorKind::kInvariantEkf;
  if (text == "leg-odometry") return EstimatorKind::kLegOdometry;
  throw EstimatorError("unknown estimator '" + text + "' (accepted: invariant-ekf, leg-odometry)");
}

bool imu_orientation_present(const Eigen::Quaterniond& q_WI) noexcept {
  const double n = q_WI.norm();
  return std::isfinite(n) && n >= 0.5;
}

const char* to_string(SupportModel s) noexcept {
  switch (s) {
    case SupportModel::kMoving:
      return "moving";
    case SupportModel::kTranslating:
      return "translating";
    case SupportModel::kFixed:
      break;
  }
  return "fixed";
}

SupportModel parse_support_model(const std::string& text) {
  if (text == "fixed") return SupportModel::kFixed;
  if (text == "moving") return SupportModel::kMoving;
  if (text == "translating") return SupportModel::kTranslating;
  throw EstimatorError("unknown support model '" + text +
                       "' (accepted: fixed, moving, translating)");
}

Estimator::Estimator(const model::Model& model, const model::RobotConfig& robot,
                     const EstimatorConfig& config)
    : model_(model), data_(model_), config_(config), imu_data_(model_) {
  require(positive_finite(config.dt), "dt must be finite and > 0");
  require(std::isfinite(config.contact_on_fraction) && std::isfinite(config.contact_off_fraction) &&
              config.contact_off_fraction >= 0.0 &&
              config.contact_off_fraction < config.contact_on_fraction,
          "contact thresholds must satisfy 0 <= contact_off_fraction < contact_on_fraction");
  require(std::isfinite(config.stance_rate_filter_hz) && config.stance_rate_filter_hz >= 0.0,
          "stance_rate_filter_hz must be finite and >= 0");
  require(std::isfinite(config.stance_rate_gate) && config.stance_rate_gate > 0.0,
          "stance_rate_gate must be finite and > 0");
  require(std::isfinite(config.stance_rate_hold) && config.stance_rate_hold >= 0.0,
          "stance_rate_hold must be finite and >= 0");
  require(std::isfinite(config.contact_rest_time) && config.contact_rest_time >= 0.0,
          "contact_rest_time must be finite and >= 0");
  require(std::isfinite(config.contact_ft_noise) && config.contact_ft_noise >= 0.0,
          "contact_ft_noise must be finite and >= 0");
  require(config.frozen_imu_ticks >= 2, "frozen_imu_ticks must be >= 2");
  require(positive_finite(config.max_gap) && config.max_gap > config.dt,
          "max_gap must be finite and > dt");
  require(std::isfinite(config.initializing_time) && config.initializing_time >= 0.0,
          "initializing_time must be finite and >= 0");
  require(
      positive_finite(config.init_std_orientation) && positive_finite(config.init_std_velocity) &&
          positive_finite(config.init_std_position) && positive_finite(config.init_std_gyro_bias) &&
          positive_finite(config.init_std_accel_bias),
      "init_std_* must be finite and > 0");
  require(config.init_gyro_bias_I.allFinite() && config.init_accel_bias_I.allFinite() &&
              std::isfinite(config.init_base_x) && std::isfinite(config.init_base_y) &&
              std::isfinite(config.ground_height),
          "initial biases, base x/y and ground height must be finite");
  for (double h : config.support_height)
    require(!std::isinf(h), "support heights must be finite (or NaN: not given)");
  require(config.kind == EstimatorKind::kInvariantEkf || config.kind == EstimatorKind::kLegOdometry,
          "kind must be invariant-ekf or leg-odometry");

  require(config.imu_delay_ticks >= 0 && config.imu_delay_ticks <= 100,
          "imu_delay_ticks must be within 0..100");
  imu_frame_ = frame_of(model_, robot.imu_frame, "IMU");
  imu_on_base_ = model_.frames[imu_frame_].body == 0;
  X_BI_ = model_.frames[imu_frame_].X_BF;
  if (!imu_on_base_) {  // at the neutral posture until the first frame
    model::forward_kinematics(model_, data_, model_.neutral());
    X_BI_ = model::frame_placement(model_, data_, imu_frame_);
    if (config.imu_delay_ticks > 0) {
      q_ring_ = Eigen::MatrixXd::Zero(model_.njoints, config.imu_delay_ticks + 1);
      q_imu_ = model_.neutral();
      v_imu_ = Eigen::VectorXd::Zero(model_.nv);
    }
  }
  X_IB_ = X_BI_.inverse();
  for (int f = 0; f < kNumFeet; ++f) {
    foot_frame_[f] =
        frame_of(model_, robot.feet[f].frame, f == model::kRight ? "right foot" : "left foot");
    sole_height_[f] = robot.feet[f].sole.height;
    require(std::isfinite(sole_height_[f]) && sole_height_[f] >= 0.0,
            "sole height of foot '" + robot.feet[f].frame + "' must be finite and >= 0");
    const model::SoleRectangle& sole = robot.feet[f].sole;
    std::size_t c = 0;
    for (double x : {sole.x_min, sole.x_max})
      for (double y : {sole.y_min, sole.y_max})
        sole_corners_F_[f][c++] = Vector3(x, y, -sole.height);
  }
  weight_ = model_.total_mass * model_.gravity.norm();
  require(positive_finite(weight_), "the model's weight (total mass * |g|) must be > 0");

  for (int f = 0; f < kNumFeet; ++f) {
    ContactThresholds t{config.contact_on_fraction * weight_, config.contact_off_fraction * weight_};
    t.touch_force = std::max(t.off_force, std::min(0.02 * weight_, 0.5 * t.on_force));
    t.rest_time = config.contact_rest_time;
    t.light_noise = config.contact_ft_noise;
    contact_[f] = ContactDetector(t);
  }
  require(config.supports == SupportModel::kFixed || config.supports == SupportModel::kMoving ||
              config.supports == SupportModel::kTranslating,
          "supports must be fixed, moving or translating");
  require(positive_finite(config.translating_orientation_std),
          "translating_orientation_std must be finite and > 0");
  require(positive_finite(config.moving_support_noise),
          "moving_support_noise must be finite and > 0");
  require(std::isfinite(config.moving_support_calibration) &&
              config.moving_support_calibration >= 0.0,
          "moving_support_calibration must be finite and >= 0");
  ImuNoise noise = config.noise;
  if (config.supports != SupportModel::kFixed && config.moving_support_calibration == 0.0) {
    noise.foot_slip = config.moving_support_noise;
    contacts_free_ = true;
  }
  try {
    ekf_ = InvariantEkf(noise, model_.gravity);
  } catch (const std::invalid_argument& e) {
    throw EstimatorError(std::string("Estimator configuration: ") + e.what());
  }
  baseline_ = LegOdometry(model_.gravity);
  fallback_ = LegOdometry(model_.gravity);
  q_rel_ = model_.neutral();
  v_rel_ = Eigen::VectorXd::Zero(model_.nv);
  held_ = make_state();
}

EstimatorState Estimator::make_state() const {
  EstimatorState s;
  s.q = Eigen::VectorXd::Zero(model_.njoints);
  s.qd = Eigen::VectorXd::Zero(model_.njoints);
  s.q_model = model_.neutral();
  s.v_model = Eigen::VectorXd::Zero(model_.nv);
  return s;
}

SensorFrame Estimator::make_sensor_frame() const {
  SensorFrame s;
  s.q = Eigen::VectorXd::Zero(model_.njoints);
  s.qd = Eigen::VectorXd::Zero(model_.njoints);
  s.tau_measured = Eigen::VectorXd::Zero(model_.njoints);
  return s;
}

void Estimator::reset() noexcept {
  initialized_ = false;
  ring_next_ = 0;
  ring_full_ = false;
  imu_frozen_ = false;
  have_last_imu_ = false;
  same_imu_count_ = 0;
  for (auto& c : contact_)
    c.reset(false);
  diag_ = EstimatorDiagnostics{};
}

bool Estimator::frame_is_valid(const SensorFrame& frame) noexcept {
  const Eigen::Index n = model_.njoints;
  if (frame.q.size() != n || frame.qd.size() != n || frame.tau_measured.size() != n) {
    diag_.last_error = "sensor frame: q, qd or tau_measured does not have one entry per joint";
    return false;
  }
  if (!frame.q.allFinite()) {
    diag_.last_error = "sensor frame: non-finite joint position q";
    return false;
  }
  if (!frame.qd.allFinite()) {
    diag_.last_error = "sensor frame: non-finite joint velocity qd";
    return false;
  }
  if (!frame.tau_measured.allFinite()) {
    diag_.last_error = "sensor frame: non-finite tau_measured";
    return false;
  }
  if (!frame.imu_q_WI.coeffs().allFinite()) {
    diag_.last_error = "sensor frame: non-finite IMU orientation";
    return false;
  }
  if (!frame.imu_omega_I.allFinite()) {
    diag_.last_error = "sensor frame: non-finite IMU angular velocity";
    return false;
  }
  if (!frame.imu_specific_force_I.allFinite()) {
    diag_.last_error = "sensor frame: non-finite IMU specific force";
    return false;
  }
  for (int f = 0; f < kNumFeet; ++f) {
    if (!frame.foot_wrench_Fo_F[f].allFinite()) {
      diag_.last_error = f == 0 ? "sensor frame: non-finite right foot wrench"
                                : "sensor frame: non-finite left foot wrench";
      return false;
    }
  }
  return true;
}

void Estimator::compute_leg_kinematics(const SensorFrame& frame) noexcept {
  const int n = model_.njoints;
  q_rel_.tail(n) = frame.q;
  v_rel_.tail(n) = frame.qd;
  model::forward_kinematics(model_, data_, q_rel_, v_rel_);
  for (int f = 0; f < kNumFeet; ++f) {
    legs_.X_BF[f] = model::frame_placement(model_, data_, foot_frame_[f]);
    const Motion V = model::frame_velocity(model_, data_, foot_frame_[f]);
    v_F0_B_[f] = V.head<3>();
    omega_F0_B_[f] = V.tail<3>();
  }
  if (imu_on_base_) return;
  if (config_.imu_delay_ticks == 0) {
    X_BI_ = model::frame_placement(model_, data_, imu_frame_);
    const Motion V = model::frame_velocity(model_, data_, imu_frame_);
    v_I0_B_ = V.head<3>();
    omega_I0_B_ = V.tail<3>();
  } else {
    // The joint positions of the time the IMU's sample describes (imu_delay_ticks ago; the
    // oldest held until that many frames have come). The joint velocities are this tick's: an
    // encoder velocity is itself a filtered, lagging signal on most drives (the simulator's:
    // 100 Hz first order, 1.6 ms), nearer in time to the IMU's sample than the one d ticks old
    // (measured with the IMU on a swinging arm: base rate error RMS 13 mrad/s this way, 34 with
    // the delayed velocities; with unfiltered encoders 22 and 5: EstimatorConfig).
    q_ring_.col(ring_next_) = frame.q;
    ring_next_ = (ring_next_ + 1) % static_cast<int>(q_ring_.cols());
    if (ring_next_ == 0) ring_full_ = true;
    const int oldest = ring_full_ ? ring_next_ : 0;
    q_imu_.tail(n) = q_ring_.col(oldest);
    v_imu_.tail(n) = frame.qd;
    model::forward_kinematics(model_, imu_data_, q_imu_, v_imu_);
    X_BI_ = model::frame_placement(model_, imu_data_, imu_frame_);
    const Motion V = model::frame_velocity(model_, imu_data_, imu_frame_);
    v_I0_B_ = V.head<3>();
    omega_I0_B_ = V.tail<3>();
  }
  X_IB_ = X_BI_.inverse();
}

InvariantEkf::Covariance Estimator::initial_covariance() const noexcept {
  InvariantEkf::Covariance P = InvariantEkf::Covariance::Zero();
  const auto sq = [](double x) { return x * x; };
  const Matrix3 I3 = Matrix3::Identity();
  P.block<3, 3>(InvariantEkf::kR, InvariantEkf::kR) = sq(config_.init_std_orientation) * I3;
  P.block<3, 3>(InvariantEkf::kV, InvariantEkf::kV) = sq(config_.init_std_velocity) * I3;
  P.block<3, 3>(InvariantEkf::kP, InvariantEkf::kP) = sq(config_.init_std_position) * I3;
  for (int f = 0; f < kNumFeet; ++f)
    P.block<3, 3>(InvariantEkf::d_index(f), InvariantEkf::d_index(f)) = I3;
  P.block<3, 3>(InvariantEkf::kBg, InvariantEkf::kBg) = sq(config_.init_std_gyro_bias) * I3;
  P.block<3, 3>(InvariantEkf::kBa, InvariantEkf::kBa) = sq(config_.init_std_accel_bias) * I3;
  return P;
}

Vector3 Estimator::start_position(const Matrix3& R_WB) const noexcept {
  SE3 X_WB;
  X_WB.R = R_WB;
  bool any_contact = legs_.contact[0] || legs_.contact[1];
  double z_min = 0.0;
  bool first = true;
  for (int f = 0; f < kNumFeet; ++f) {
    if (any_contact && !legs_.contact[f]) continue;
    const Vector3 sole_B = legs_.X_BF[f].act(Vector3(0.0, 0.0, -sole_height_[f]));
    const double z = (X_WB.R * sole_B).z();
    if (first || z < z_min) z_min = z;
    first = false;
  }
  X_WB.p = Vector3(config_.init_base_x, config_.init_base_y, config_.ground_height - z_min);
  // Feet on supports of known height (platforms): each says where the base is; their mean.
  double z_sum = 0.0;
  int z_count = 0;
  for (int f = 0; f < kNumFeet; ++f) {
    if (!legs_.contact[f] || !std::isfinite(config_.support_height[f])) continue;
    const Vector3 sole_B = legs_.X_BF[f].act(Vector3(0.0, 0.0, -sole_height_[f]));
    z_sum += config_.support_height[f] - (X_WB.R * sole_B).z();
    ++z_count;
  }
  if (z_count > 0) X_WB.p.z() = z_sum / z_count;

  return X_WB.p;
}

void Estimator::relevel_from_filter() noexcept {
  started_without_orientation_ = false;
  const InvariantEkf::Mean& m = ekf_.mean();
  SE3 X_WB;
  X_WB.R = m.R_WI * X_IB_.R;
  X_WB.p = start_position(X_WB.R);
  ekf_.set_pose_velocity(m.R_WI, m.v_WI, X_WB.act(X_BI_.p));
  baseline_.reset(X_WB, baseline_.v_WB(), legs_);
  fallback_.reset(X_WB, fallback_.v_WB(), legs_);
  R_WB_gyro_ = X_WB.R;
}

void Estimator::initialize(const SensorFrame& frame) noexcept {
  // Orientation: the IMU's own estimate when it is a plausible quaternion, else the tilt from
  // the accelerometer (yaw 0).
  Matrix3 R_WI;
  const double qn = frame.imu_q_WI.norm();
  if (imu_orientation_present(frame.imu_q_WI) && qn < 1.5) {
    R_WI = frame.imu_q_WI.normalized().toRotationMatrix();
  } else {
    const Vector3 f = frame.imu_specific_force_I;
    R_WI = f.norm() > 1e-6
               ? Eigen::Quaterniond::FromTwoVectors(f, Vector3::UnitZ()).toRotationMatrix()
               : Matrix3::Identity();
  }
  SE3 X_WB;
  X_WB.R = R_WI * X_IB_.R;
  X_WB.p = start_position(X_WB.R);
  started_without_orientation_ = !(imu_orientation_present(frame.imu_q_WI) && qn < 1.5);

  InvariantEkf::Mean m;
  m.R_WI = R_WI;
  m.p_WI = X_WB.act(X_BI_.p);
  m.v_WI = X_WB.R * v_I0_B_;  // the base at rest (zero for a base-mounted IMU)
  m.b_g = config_.init_gyro_bias_I;
  m.b_a = config_.init_accel_bias_I;
  m.d_W[0] = m.d_W[1] = m.p_WI;
  ekf_.reset(m, initial_covariance());
  for (int f = 0; f < kNumFeet; ++f) {
    ekf_.set_contact(f, legs_.contact[f], X_IB_.act(legs_.X_BF[f].p));
  }
  const Vector3 omega_B = base_rate(frame.imu_omega_I - m.b_g);
  for (int f = 0; f < kNumFeet; ++f)
    legs_.v_BF_B[f] = omega_B.cross(legs_.X_BF[f].p) + v_F0_B_[f];
  omega_B_ = omega_B;
  stance_rate_valid_ = false;
  baseline_.reset(X_WB, Vector3::Zero(), legs_);
  fallback_.reset(X_WB, Vector3::Zero(), legs_);
  R_WB_gyro_ = X_WB.R;
  omega_B_raw_ = base_rate(frame.imu_omega_I);
  initialized_ = true;
  imu_frozen_ = false;
  time_since_init_ = 0.0;
  ++diag_.resets;
}

Vector3 Estimator::fuse_stance_rate(const Vector3& omega_gyro_B, double dt) noexcept {
  if (!(config_.stance_rate_filter_hz > 0.0)) return omega_gyro_B;
  // The base's rate if the feet in contact do not turn, weighted by their loads (a lightly
  // loaded foot is the one that may tip).
  Vector3 omega_kin = Vector3::Zero();
  double load = 0.0;
  for (int f = 0; f < kNumFeet; ++f) {
    if (!legs_.contact[f]) continue;
    const double w = std::max(legs_.normal_force[f], 1e-3 * weight_);
    omega_kin -= w * omega_F0_B_[f];
    load += w;
  }
  if (!(load > 0.0)) {
    stance_rate_valid_ = false;
    return omega_gyro_B;
  }
  omega_kin /= load;
  const Vector3 offset = omega_gyro_B - omega_kin;
  if (!stance_rate_valid_) {
    // First tick on the feet: start from the gyro (no jump in the published rate).
    stance_rate_offset_ = offset;
    stance_rate_valid_ = true;
    stance_rate_gated_for_ = 0.0;
    return omega_gyro_B;
  }
  // The fast part of the disagreement: noise, or a foot turning (the premise fails).
  const bool disagree =
      (offset - stance_rate_offset_).cwiseAbs().maxCoeff() > config_.stance_rate_gate;
  const double alpha = 1.0 - std::exp(-2.0 * M_PI * config_.stance_rate_filter_hz * dt);
  stance_rate_offset_ += alpha * (offset - stance_rate_offset_);
  if (disagree) {
    stance_rate_gated_for_ = config_.stance_rate_hold;
    ++diag_.stance_rate_gated_ticks;
    return omega_gyro_B;
  }
  if (stance_rate_gated_for_ > 0.0) {
    stance_rate_gated_for_ -= dt;
    ++diag_.stance_rate_gated_ticks;
    return omega_gyro_B;
  }
  return omega_kin + stance_rate_offset_;
}

int Estimator::loaded_stance_foot() const noexcept {
  int stance = -1;
  for (int f = 0; f < kNumFeet; ++f)
    if (legs_.contact[f] && (stance < 0 || legs_.normal_force[f] > legs_.normal_force[stance]))
      stance = f;
  return stance;
}

void Estimator::correct_with_kept_foot_orientations() noexcept {
  // Keep each stance foot's orientation from its touch-down (or from the moment the contacts
  // became free); correct with the most loaded one (the other says the same, one update is
  // cheaper).
  int best = -1;
  for (int f = 0; f < kNumFeet; ++f) {
    if (!legs_.contact[f]) {
      have_R_WF_[f] = false;
      continue;
    }
    if (!have_R_WF_[f]) {
      R_WF_kept_[f] = ekf_.mean().R_WI * X_IB_.R * legs_.X_BF[f].R;
      have_R_WF_[f] = true;
      continue;
    }
    if (best < 0 || legs_.normal_force[f] > legs_.normal_force[best]) best = f;
  }
  if (best < 0) return;
  const Matrix3 R_IF = X_IB_.R * legs_.X_BF[best].R;
  const double chi2 = ekf_.correct_orientation(
      R_WF_kept_[best] * R_IF.transpose(), config_.translating_orientation_std,
      config_.translating_orientation_max_chi2);
  if (!(chi2 <= config_.translating_orientation_max_chi2)) {
    // The foot turned on its support (it tips over an edge): keep its new orientation instead.
    have_R_WF_[best] = false;
    ++diag_.orientation_rejections;
  }
}

void Estimator::calibrate_on_still_supports(const SensorFrame& frame, StatusFlags flags) noexcept {
  const int stance = loaded_stance_foot();
  if (stance >= 0 && !(flags & (kImuFrozen | kInitializing))) {
    // The stance foot does not rotate: the base turns at -omega_F0_B.
    calib_gyro_sum_ += frame.imu_omega_I - X_IB_.R * (omega_I0_B_ - omega_F0_B_[stance]);
    ++calib_samples_;
  }
  if (time_since_start_ < config_.moving_support_calibration) return;
  if (calib_samples_ >= 50) {
    const double n = static_cast<double>(calib_samples_);
    const InvariantEkf::Mean& m = ekf_.mean();
    ekf_.set_biases(calib_gyro_sum_ / n, m.b_a, config_.noise.gyro / std::sqrt(n * config_.dt),
                    std::sqrt(ekf_.covariance().block<3, 3>(InvariantEkf::kBa, InvariantEkf::kBa)
                                  .diagonal()
                                  .maxCoeff()));
  } else {
    diag_.last_error = "moving supports: too few still samples to calibrate the gyro bias";
  }
  ekf_.set_foot_slip(config_.moving_support_noise);  // from here on the contacts are free
  contacts_free_ = true;
}

StatusFlags Estimator::update(const SensorFrame& frame, EstimatorState& out) noexcept {
  ++diag_.ticks;
  const Eigen::Index n = model_.njoints;
  if (out.q.size() != n || out.qd.size() != n || out.q_model.size() != model_.nq ||
      out.v_model.size() != model_.nv) {
    diag_.last_error = "output state was not made by Estimator::make_state()";
    return kNonFiniteInput;
  }
  if (!frame_is_valid(frame)) {
    ++diag_.rejected_frames;
    hold_output(frame, kNonFiniteInput, out);
    return out.status_flags;
  }
  StatusFlags flags = kStateOk;
  double dt = config_.dt;
  if (!accept_tick(frame, flags, dt, out)) return out.status_flags;
  last_tick_ = frame.tick;
  update_contacts(frame, dt);
  const bool frozen = imu_is_frozen(frame);
  if (!initialized_) {
    initialize(frame);
    flags |= kInitializing;
    if (frozen) imu_frozen_ = true;  // restart from a frozen IMU: the fallback takes over
  } else if (!frozen) {
    if (imu_frozen_)
      restart_from_fallback(frame);
    else
      ekf_.propagate(frame.imu_omega_I, frame.imu_specific_force_I, dt);
    correct_with_stance_feet(frame, dt);
  }
  if (frozen) {
    flags |= kImuFrozen;
    run_kinematic_fallback(dt);
  }
  // Not on the tick that (re)started the filter (initialize() placed it there; only that tick
  // has kInitializing at this point).
  if (!(flags & kInitializing)) update_baseline(frame, dt);
  time_since_init_ += dt;
  if (started_without_orientation_ && time_since_init_ >= config_.initializing_time)
    relevel_from_filter();
  if (time_since_init_ < config_.initializing_time) flags |= kInitializing;
  time_since_start_ += dt;
  if (!contacts_free_ && config_.supports != SupportModel::kFixed)
    calibrate_on_still_supports(frame, flags);
  if (!legs_.contact[0] && !legs_.contact[1]) {
    flags |= kNoContact;
    ++diag_.no_contact_ticks;
  }
  write_output(frame, flags, out);
  return out.status_flags;
}

// The frame's tick against the last accepted one: refused (the output held, false) when not
// after it; dropped frames flagged and the step dt made their span; a gap too long to propagate
// restarts the filter.
bool Estimator::accept_tick(const SensorFrame& frame, StatusFlags& flags, double& dt,
                            EstimatorState& out) noexcept {
  if (initialized_) {
    const std::int64_t gap = frame.tick - last_tick_;
    if (gap <= 0) {
      ++diag_.rejected_frames;
      diag_.last_error = "sensor frame: tick not after the previous accepted tick";
      hold_output(frame, kDroppedFrames, out);
      return false;
    }
    if (gap > 1) {
      flags |= kDroppedFrames;
      diag_.dropped_frames += static_cast<std::uint64_t>(gap - 1);
      diag_.last_error = "sensor frames dropped";
    }
    dt = static_cast<double>(gap) * config_.dt;
    if (dt > config_.max_gap) initialized_ = false;  // too long to propagate: restart
    if (gap > 1) {
      // The joint positions imu_delay_ticks ticks old are not in the ring after dropped frames:
      // it starts again (this frame's positions until that many frames have come).
      ring_next_ = 0;
      ring_full_ = false;
    }
  }
  return true;
}

void Estimator::update_contacts(const SensorFrame& frame, double dt) noexcept {
  // Contact: F/T load, and the sole's height from this tick's leg kinematics placed by the
  // previous tick's filter state (contact_detector.hpp).
  compute_leg_kinematics(frame);
  // Which foot carries the weight (in contact at the previous tick, this tick's load above 2 %
  // of W): the other foot's corners are measured above its sole. Both decided before either
  // detector updates, so neither foot sees the other's newer state.
  std::array<bool, kNumFeet> stands{};
  for (int f = 0; f < kNumFeet; ++f)
    stands[f] = contact_[f].in_contact() && frame.foot_wrench_Fo_F[f][2] > 0.02 * weight_;
  for (int f = 0; f < kNumFeet; ++f) {
    FootKinematics kin;
    kin.dt = dt;
    kin.plan = frame.foot_plan[f];
    if (initialized_) {
      const InvariantEkf::Mean& m = ekf_.mean();
      const Vector3 sole_B = legs_.X_BF[f].act(Vector3(0.0, 0.0, -sole_height_[f]));
      kin.sole_z = (m.p_WI + m.R_WI * X_IB_.act(sole_B)).z();
      // The sole's corners: above the other sole's plane while that foot carries the weight
      // (the legs' kinematics alone: no attitude error; that sole lies on its support), else in W.
      const int o = 1 - f;
      const bool other_stands = stands[o];
      for (std::size_t c = 0; c < 4; ++c) {
        const Vector3 corner_B = legs_.X_BF[f].act(sole_corners_F_[f][c]);
        kin.corner_z[c] = other_stands ? legs_.X_BF[o].act_inv(corner_B).z() + sole_height_[o]
                                       : (m.p_WI + m.R_WI * X_IB_.act(corner_B)).z();
      }
      kin.corner_reference = other_stands ? 1 + o : 0;
    }
    legs_.contact[f] = contact_[f].update(frame.foot_wrench_Fo_F[f], kin);
    legs_.normal_force[f] = frame.foot_wrench_Fo_F[f][2];
  }
}

// Frozen IMU: every field bit-identical to the previous sample for frozen_imu_ticks samples.
bool Estimator::imu_is_frozen(const SensorFrame& frame) noexcept {
  const bool same = have_last_imu_ && frame.imu_omega_I == last_gyro_ &&
                    frame.imu_specific_force_I == last_accel_ &&
                    frame.imu_q_WI.coeffs() == last_imu_q_.coeffs();
  same_imu_count_ = same ? same_imu_count_ + 1 : 0;
  have_last_imu_ = true;
  last_gyro_ = frame.imu_omega_I;
  last_accel_ = frame.imu_specific_force_I;
  last_imu_q_ = frame.imu_q_WI;
  const bool frozen = same_imu_count_ >= config_.frozen_imu_ticks;
  if (frozen && !imu_frozen_) diag_.last_error = "IMU frozen: kinematics-only fallback";
  return frozen;
}

// The IMU is back: restart the filter from the fallback pose, keeping the biases.
void Estimator::restart_from_fallback(const SensorFrame& frame) noexcept {
  const SE3& X_WB = fallback_.X_WB();
  InvariantEkf::Mean m = ekf_.mean();
  m.R_WI = X_WB.R * X_BI_.R;
  m.p_WI = X_WB.act(X_BI_.p);
  m.v_WI = imu_velocity(X_WB, fallback_.v_WB(),
                        X_WB.R * base_rate(frame.imu_omega_I - m.b_g));
  InvariantEkf::Covariance P = initial_covariance();
  P.bottomRightCorner<6, 6>() = ekf_.covariance().bottomRightCorner<6, 6>();
  ekf_.reset(m, P);
  imu_frozen_ = false;
  time_since_init_ = 0.0;
  ++diag_.resets;
}

// The base rate (gyro less bias, fused with the stance feet's), the feet's velocities, and the
// filter's contact corrections.
void Estimator::correct_with_stance_feet(const SensorFrame& frame, double dt) noexcept {
  omega_B_ = fuse_stance_rate(base_rate(frame.imu_omega_I - ekf_.mean().b_g), dt);
  for (int f = 0; f < kNumFeet; ++f) {
    legs_.v_BF_B[f] = omega_B_.cross(legs_.X_BF[f].p) + v_F0_B_[f];
    const Vector3 s_I = X_IB_.act(legs_.X_BF[f].p);
    ekf_.set_contact(f, legs_.contact[f], s_I);
    if (legs_.contact[f]) ekf_.correct(f, s_I);
  }
  if (contacts_free_ && config_.supports == SupportModel::kTranslating)
    correct_with_kept_foot_orientations();
}

// The frozen IMU's kinematics-only fallback: leg odometry from the filter's last pose, the base
// rate from the most loaded stance foot; the filter's mean follows it.
void Estimator::run_kinematic_fallback(double dt) noexcept {
  ++diag_.frozen_imu_ticks;
  const auto& m = ekf_.mean();
  const Matrix3 R_WB = m.R_WI * X_IB_.R;
  if (!imu_frozen_) {
    SE3 X_WB(R_WB, m.p_WI + m.R_WI * X_IB_.p);
    fallback_.reset(X_WB, m.v_WI, legs_);
  }
  imu_frozen_ = true;
  // Angular velocity from the stance foot that carries most load (it does not rotate).
  const int stance = loaded_stance_foot();
  omega_B_ = stance >= 0 ? Vector3(-omega_F0_B_[stance]) : Vector3::Zero();
  stance_rate_valid_ = false;  // the IMU's return starts the fusion afresh
  for (int f = 0; f < kNumFeet; ++f)
    legs_.v_BF_B[f] = omega_B_.cross(legs_.X_BF[f].p) + v_F0_B_[f];
  fallback_.update(LegOdometry::OrientationSource::kStanceFoot, R_WB, legs_, dt);
  const SE3& X_WB = fallback_.X_WB();
  const Matrix3 R_WI = X_WB.R * X_BI_.R;
  const Vector3 p_WI = X_WB.act(X_BI_.p);
  const Vector3 v_WI = imu_velocity(X_WB, fallback_.v_WB(), X_WB.R * omega_B_);
  ekf_.set_pose_velocity(R_WI, v_WI, p_WI);
}

// Baseline: IMU orientation (or the raw gyro integrated, when the IMU gives no orientation),
// raw gyro, stance-foot kinematics, no filter.
void Estimator::update_baseline(const SensorFrame& frame, double dt) noexcept {
  LegKinematics legs_baseline = legs_;
  const Vector3 omega_B_raw = base_rate(frame.imu_omega_I);
  omega_B_raw_ = omega_B_raw;
  for (int f = 0; f < kNumFeet; ++f)
    legs_baseline.v_BF_B[f] = omega_B_raw.cross(legs_.X_BF[f].p) + v_F0_B_[f];
  if (imu_orientation_present(frame.imu_q_WI)) {
    R_WB_gyro_ = frame.imu_q_WI.normalized().toRotationMatrix() * X_IB_.R;
  } else if (started_without_orientation_) {
    R_WB_gyro_ = ekf_.mean().R_WI * X_IB_.R;  // the filter's, until relevel_from_filter()
  } else {
    // Integrate the body rate: R <- R exp([omega dt]x) (exact for a constant rate).
    const double angle = omega_B_raw.norm() * dt;
    if (angle > 0.0) {
      R_WB_gyro_ = R_WB_gyro_ * Eigen::AngleAxisd(angle, omega_B_raw.normalized()).toRotationMatrix();
      R_WB_gyro_ = Eigen::Quaterniond(R_WB_gyro_).normalized().toRotationMatrix();
    }
  }
  baseline_.update(LegOdometry::OrientationSource::kImu, R_WB_gyro_, legs_baseline, dt);
}

void Estimator::write_output(const SensorFrame& frame, StatusFlags flags,
                             EstimatorState& out) noexcept {
  const auto& m = ekf_.mean();
  const int n = model_.njoints;
  out.tick = frame.tick;
  out.stamp_ns = frame.stamp_ns;
  // Leg odometry as the published estimate: its pose and base velocity, the raw gyro (while the
  // IMU is frozen both kinds publish the kinematics-only fallback, held in the filter's mean).
  const bool leg_odometry = config_.kind == EstimatorKind::kLegOdometry && !imu_frozen_;
  const Vector3 omega_B = leg_odometry ? omega_B_raw_ : omega_B_;
  if (leg_odometry) {
    out.X_WB = baseline_.X_WB();
    out.omega_WB = out.X_WB.R * omega_B;
    out.v_WB = baseline_.v_WB();
  } else {
    out.X_WB = SE3(m.R_WI * X_IB_.R, m.R_WI * X_IB_.p + m.p_WI);
    out.omega_WB = out.X_WB.R * omega_B;
    out.v_WB = m.v_WI + out.omega_WB.cross(out.X_WB.p - m.p_WI) - out.X_WB.R * v_I0_B_;
  }
  out.q = frame.q;
  out.qd = frame.qd;
  out.q_model.head<3>() = out.X_WB.p;
  out.q_model.segment<4>(3) = Eigen::Quaterniond(out.X_WB.R).normalized().coeffs();
  out.q_model.tail(n) = frame.q;
  out.v_model.head<3>() = out.X_WB.R.transpose() * out.v_WB;
  out.v_model.segment<3>(3) = omega_B;
  out.v_model.tail(n) = frame.qd;
  // CoM, momentum and feet from this tick's kinematics (compute_leg_kinematics: base at identity,
  // base twist zero) and the base pose and twist V_B = [v; omega] (base axes), instead of a second
  // forward kinematics: oMi = X_WB oMi_rel, v_b = v_b_rel + X_bB V_B (the twist is linear in v).
  Motion V_B;
  V_B.head<3>() = out.v_model.head<3>();
  V_B.tail<3>() = omega_B;
  Vector3 mc_B = Vector3::Zero();
  double mass = 0.0;
  Force h_B = Force::Zero();  // [l; k about the base origin], base axes
  for (int b = 0; b < model_.nbodies; ++b) {
    const model::Inertia& I = model_.inertia[b];
    const SE3& X_Bb = data_.oMi[b];
    mc_B += I.mass * X_Bb.act(I.com);
    mass += I.mass;
    h_B += X_Bb.act_force(I * (data_.v[b] + X_Bb.act_inv_motion(V_B)));
  }
  const Force h_O = out.X_WB.act_force(h_B);  // about the world origin, world axes
  out.com_W = out.X_WB.act(mc_B / mass);
  out.l_W = h_O.head<3>();
  out.k_W = h_O.tail<3>() - out.com_W.cross(out.l_W);
  out.com_velocity_W = out.l_W / mass;
  for (int f = 0; f < kNumFeet; ++f) {
    FootEstimate& foot = out.feet[f];
    const Force& w = frame.foot_wrench_Fo_F[f];
    foot.in_contact = legs_.contact[f];
    foot.X_WF = out.X_WB * legs_.X_BF[f];
    foot.V_WF.head<3>() = out.v_WB + out.X_WB.R * (omega_B.cross(legs_.X_BF[f].p) + v_F0_B_[f]);
    foot.V_WF.tail<3>() = out.X_WB.R * (omega_B + omega_F0_B_[f]);
    foot.normal_force = w[2];
    Vector3 cop_F;
    if (foot.in_contact && center_of_pressure(w, sole_height_[f], 0.0, cop_F))
      foot.cop_W = foot.X_WF.act(cop_F);
    else
      foot.cop_W.setZero();
  }
  // Leg odometry estimates no bias.
  out.gyro_bias_I = leg_odometry ? Vector3::Zero() : m.b_g;
  out.accel_bias_I = leg_odometry ? Vector3::Zero() : m.b_a;
  out.status_flags = flags;

  bool ok = finite(out.X_WB) && out.v_WB.allFinite() && out.omega_WB.allFinite() &&
            out.q_model.allFinite() && out.v_model.allFinite() && out.com_W.allFinite() &&
            out.com_velocity_W.allFinite() && out.k_W.allFinite() && out.l_W.allFinite() &&
            out.gyro_bias_I.allFinite() && out.accel_bias_I.allFinite() &&
            ekf_.covariance().allFinite();
  for (const auto& foot : out.feet)
    ok = ok && finite(foot.X_WF) && foot.V_WF.allFinite() && foot.cop_W.allFinite() &&
         std::isfinite(foot.normal_force);
  if (!ok) {
    // Numerical failure: never publish it; restart from the next frame.
    diag_.last_error = "estimator produced a non-finite state: restarting";
    initialized_ = false;
    hold_output(frame, flags | kInitializing, out);
    return;
  }
  held_ = out;
}

void Estimator::hold_output(const SensorFrame& frame, StatusFlags flags,
                            EstimatorState& out) noexcept {
  out = held_;
  out.tick = frame.tick;
  out.stamp_ns = frame.stamp_ns;
  out.status_flags = flags | (initialized_ ? 0u : static_cast<StatusFlags>(kInitializing));
}

}  // namespace poise::estimator
