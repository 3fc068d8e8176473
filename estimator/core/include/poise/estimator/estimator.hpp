#pragma once
// The state estimator: sensor frame in, state out, once per tick (1 kHz). No DDS, no threads, no
// clocks; the `poise-estimator` node is a thin shell around Estimator::update().
//
// What one update() does (all from the sensor stream, never from ground truth):
//  1. checks the frame (sizes, finite values, tick order); a bad frame is rejected and the
//     previous state is held (kNonFiniteInput / kDroppedFrames), a tick gap propagates over the
//     missed time (kDroppedFrames);
//  2. detects contact per foot from its F/T normal force with hysteresis (ContactDetector);
//  3. leg kinematics with the base at identity: foot poses X_BF and foot velocities relative to
//     the base;
//  4. contact-aided invariant EKF (invariant_ekf.hpp, which says why this filter): IMU
//     propagation, touch-down/lift-off of contact points, leg-kinematics corrections;
//     if the IMU stops changing for `frozen_imu_ticks` ticks (kImuFrozen) the base is tracked by
//     leg odometry with stance-foot orientation until the IMU changes again (then the filter
//     restarts from there, kInitializing);
//  5. outputs: base pose and twist, q/qd, CoM, its velocity and the centroidal momentum (k about
//     the CoM, l), foot poses/twists, contact states, measured CoP per foot, IMU biases;
//  6. a plain leg-odometry baseline (IMU orientation + stance-foot kinematics, no filter) runs
//     alongside for comparison (leg_odometry()); EstimatorConfig::kind = kLegOdometry makes it the
//     published estimate (step 5 then uses its base pose and twist).
// Status bits are those of idl/state.idl (types.hpp). Yaw and absolute position are unobservable:
// they drift slowly with the gyro bias and foot slip; roll, pitch and velocity are observable.
// While standing still, the horizontal accelerometer bias and the tilt cannot be told apart
// (a bias b shows up as a tilt error of about b / 9.81 rad).
// Supports (EstimatorConfig::supports):
//  - kFixed (default): a stance foot stands on the ground, static in W; its contact point is a
//    filter state with a small random walk (noise.foot_slip), so the leg kinematics correct the
//    base velocity, the tilt and the biases. On a support that moves (a ship's deck, the paper's
//    platforms) this model is wrong: the base velocity comes out relative to the support, and the
//    mismatch also tilts the attitude (measured below).
//  - kMoving: the supports may move in W by unknown amounts. A stance contact point then follows a
//    free random walk (moving_support_noise, 100 m/s/sqrt(Hz) by default: 3 m per tick), so the
//    kinematics no longer say anything about the base's motion in W; base velocity and attitude
//    come from the IMU propagation alone (strapdown), with the biases held at their estimates.
//    The biases are calibrated first: for moving_support_calibration seconds after the start
//    (2 s by default) the supports are taken as still and the fixed-contact model runs. The gyro
//    bias is then set to the mean of the gyro minus the base's angular rate from the loaded stance
//    foot's kinematics (the filter alone converges too slowly: its 1 s estimate left 0.06 m/s of
//    velocity error); the accelerometer bias keeps the filter's estimate (averaging the specific
//    force is spoilt by the balancing robot's sway: measured worse).
//    No proprioceptive sensor can tell a common motion of both supports from the IMU's
//    integration (a constant velocity of the whole support is unobservable in principle), so
//    the accuracy is that of the IMU: accelerometer white noise sigma_a per sample gives a
//    velocity error of sigma_a sqrt(t dt); an accelerometer bias b gives b t; a gyro bias error
//    beta tilts the attitude by beta t and leaks gravity into the velocity (g beta t^2 / 2). The
//    last one dominates: the calibrated gyro bias is off by ~1.3e-5 rad/s (1500 samples of
//    5e-4 rad/s noise), 0.009 m/s after 12 s.
//    Measured (tests/estimator/estimator_platform_test.cpp; controller on ground truth, estimators
//    open loop; simulator IMU noise 5e-4 rad/s and 0.01 m/s^2 per sample): level supports moving
//    in sync, 1 m at 0.12 Hz for 12 s after 2 s at rest: base velocity RMS error 0.0036 to
//    0.0203 m/s over IMU noise seeds 1..8 (median 0.0045), attitude error <= 0.04 deg; with
//    kFixed 0.52 m/s and 21 to 25 deg; leg odometry 0.45 m/s. With constant IMU biases (gyro
//    2e-3, accel 5e-2 per axis at most) 0.021 m/s and 0.17 deg (0.89 m/s without the
//    calibration). The paper's pitched supports: 0.0197 m/s.
//    Use it only where the supports move: on the ground kFixed is better (it estimates the
//    biases and bounds the drift).
//  - kTranslating: as kMoving, for supports that move without rotating (the paper's platforms
//    translate): a stance foot then keeps its orientation in W, taken from the estimate when the
//    contact points become free or the foot touches down, and the leg kinematics give the base
//    orientation from it (a measurement of std translating_orientation_std, with the most loaded
//    stance foot). That removes the attitude drift of kMoving. A foot that turns on its support
//    (tips over an edge) makes the measurement's chi2 exceed translating_orientation_max_chi2: it
//    is not used and that foot's orientation is taken again (diagnostics().orientation_rejections).
//    Wrong on supports that rotate (a ship's deck rolling): use kMoving there.
//    Measured in the same runs as kMoving above: 0.0026 to 0.0099 m/s over seeds 1..8, attitude
//    error <= 0.015 deg; with the IMU biases 0.0098 m/s and 0.15 deg; the paper's pitched
//    supports 0.0099 m/s; the out-of-phase supports until the robot falls (1.8 s of motion, 115
//    gated measurements) 0.0025 m/s and 0.17 deg. The shipped platform scenarios use it.

#include <Eigen/Core>
#include <array>
#include <limits>
#include <stdexcept>
#include <string>

#include "poise/estimator/contact_detector.hpp"
#include "poise/estimator/invariant_ekf.hpp"
#include "poise/estimator/leg_odometry.hpp"
#include "poise/estimator/types.hpp"
#include "poise/model/data.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"

namespace poise::estimator {

/// Thrown by the Estimator constructor for a bad configuration (names the bad field).
class EstimatorError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What the stance feet stand on (see the header comment).
enum class SupportModel { kFixed, kMoving, kTranslating };

/// Which estimate the state carries (`poise-estimator --estimator`). Both run on every tick;
/// the choice says which one is published.
///  - kInvariantEkf (default): the contact-aided invariant EKF (invariant_ekf.hpp).
///  - kLegOdometry: the plain leg-odometry baseline (leg_odometry.hpp), no filter: base
///    orientation from the IMU's own orientation output (from the gyro integrated from the
///    start tilt when the IMU gives none: an all-zero quaternion), position and velocity from the
///    stance feet's kinematics with each stance foot held still in W since its touch-down, angular
///    velocity the raw gyro (without an IMU orientation, the attitude is the filter's during the
///    first initializing_time and the gyro integrated from there). It estimates no IMU bias
///    (published as 0) and, with no foot in
///    contact, propagates the base ballistically. While the IMU is frozen both use the same
///    kinematics-only fallback.
enum class EstimatorKind { kInvariantEkf, kLegOdometry };

/// "invariant-ekf" / "leg-odometry".
const char* to_string(EstimatorKind k) noexcept;
/// Parses "invariant-ekf" / "leg-odometry"; throws EstimatorError naming the accepted values.
EstimatorKind parse_estimator_kind(const std::string& text);

/// An IMU orientation sample counts as absent (the IMU has no orientation output) when it is
/// all zeros (any quaternion of norm < 0.5; a non-finite one is a bad frame and rejected).
bool imu_orientation_present(const Eigen::Quaterniond& q_WI) noexcept;

/// "fixed" / "moving" / "translating".
const char* to_string(SupportModel s) noexcept;
/// Parses "fixed" / "moving" / "translating"; throws EstimatorError naming the accepted values otherwise.
SupportModel parse_support_model(const std::string& text);

struct EstimatorConfig {
  EstimatorKind kind = EstimatorKind::kInvariantEkf;  ///< which estimate the state carries
  double dt = 0.001;  ///< nominal sensor period [s]; a tick gap of g propagates over g * dt
  ImuNoise noise;     ///< process / measurement noise of the filter
  SupportModel supports = SupportModel::kFixed;
  /// With kMoving / kTranslating: velocity noise density of a stance contact point, replacing
  /// noise.foot_slip [m/s/sqrt(Hz)]. Large on purpose: the supports' motion is not modelled.
  double moving_support_noise = 100.0;
  /// With kMoving / kTranslating: for this long after the filter's first start the supports are
  /// taken as still (the fixed-contact model), so the IMU biases are estimated before the free
  /// contact points take over [s]. The supports must then really be still. 0: free from the
  /// start, the biases stay at init_gyro_bias_I / init_accel_bias_I (a calibrated IMU).
  double moving_support_calibration = 2.0;
  /// With kTranslating: std of the base orientation from a stance foot's kept orientation and
  /// the leg kinematics [rad].
  double translating_orientation_std = 2e-3;
  /// With kTranslating: an orientation measurement whose innovation chi2 (3 dof) exceeds this is
  /// not used and the foot's kept orientation is taken again (the foot turned: it tips).
  double translating_orientation_max_chi2 = 16.3;  // 99.9 % of chi2(3)
  /// Contact thresholds as fractions of the robot's weight m |g| on the foot normal force:
  /// touch-down at once above on, lift-off confirmed below off (ContactDetector; a light load of
  /// 2 % of the weight, or an impact, also makes a touch-down; kinematics gate both; when the
  /// plan, SensorFrame::foot_plan, says a foot swings, its contact ends below off / 2).
  double contact_on_fraction = 0.15;
  double contact_off_fraction = 0.01;
  /// The detector's resting rule (ContactThresholds::rest_time): a foot whose load stayed below
  /// 2 % of the weight this long with its sole where it stood keeps its contact at any load, so
  /// the flag means "touching" (idl/README.md "Contact flags") [s]; a landed foot whose load
  /// falls back before it carried 2 % of the weight this long rests at once (the landing rule).
  /// 0.02 s by default since 2026-12-05: longer than a push unloads a foot (<= 9 ms from 2 % to
  /// 1 %), shorter than the weight moves off a foot that stays down (40-58 ms); with the plan's
  /// corner rule and the landing rule every true event of the step in place is flagged within
  /// -3..+6 ms in process and lockstep (idl/README.md "The landing rule"). 0: off, the flag
  /// drops below contact_off_fraction ("loaded"): the swing's lift-off of a foot the weight left
  /// then went unflagged (the flag was off 0.06-0.4 s before it) in 6 of 8 seeds. Measured limit
  /// with it: a resting foot that peels off slowly about an edge (config/ankle_first.yaml's
  /// pre-swing roll-off) is flagged +30 ms (-5 ms without). Scenario key
  /// `estimator: {contact_rest_time: S}`. >= 0.
  double contact_rest_time = 0.02;
  /// The contact detector's light-touch rule (ContactThresholds::light_noise): the foot F/T's
  /// normal-force noise, 1 sigma [N]. A touch too light for the load thresholds (a foot that
  /// re-touches with 2 N while the weight is on the other one) is flagged from the step it makes
  /// in the reading above the reading in the air, with the sole where it stood, until the reading
  /// is back there (contact_detector.hpp); set it to the sensor's own figure (0.5 N: the
  /// simulator's default F/T, simulator/sim/SENSORS.md, the default). With 0.5 N every
  /// touch-down of the step in place was flagged, 14 of 17 within 2 ms (8 seeds; 8 were more
  /// than 100 ms late without). A lightly touching foot is a support to the balance controller;
  /// one back from the air rests (follows its own velocity, Sec. 4.2) only once it carries 1 %
  /// of W (ControllerConfig::resting_touchdown_force_fraction), else it kept sliding (idl/README.md
  /// "Contact flags"). 0: off. >= 0.
  double contact_ft_noise = 0.5;
  /// The published base angular velocity: a complementary filter of the gyro and the stance
  /// feet's kinematics [Hz]. A flat stance foot does not turn, so while feet are in contact the
  /// base turns at -omega_F0_B (the leg's joint rates through its Jacobian, load-weighted over
  /// the feet in contact); the gyro minus that rate (what the feet really turn, a tipping foot,
  /// a rotating deck, plus both sensors' noise) is low-passed at this cut-off and added back.
  /// Below the cut-off the output is the gyro's; above it, the encoders'. Why: the gyro's white
  /// noise (3.1 mrad/s per sample for an ADIS16470-class part) times the ~0.84 m soles-to-CoM
  /// lever is CoM velocity noise relative to the feet, which the momentum feedback turns into
  /// normal-force noise between the feet (simulator/sim/SENSORS.md). With no foot in contact,
  /// or 0 here: the bias-corrected gyro alone. The filter itself (propagation) always takes the
  /// gyro. >= 0.
  double stance_rate_filter_hz = 10.0;
  /// A foot that turns fast (tips, rocks after an impact) breaks the flat-foot premise above the
  /// cut-off: when the gyro and the stance kinematics disagree by more than this on an axis,
  /// beyond their low-passed difference, the gyro alone is published until they have agreed for
  /// stance_rate_hold seconds [rad/s]. The default is ~6 sigma of the disagreement of an
  /// ADIS16470-class gyro (3.1 mrad/s per 1 kHz sample) with 2^20-count encoders (~1 mrad/s):
  /// raise it for a noisier gyro. > 0.
  double stance_rate_gate = 0.02;
  double stance_rate_hold = 0.05;  ///< [s], >= 0
  /// Identical consecutive IMU samples (gyro, accelerometer and orientation bit for bit) after
  /// which the IMU counts as frozen.
  int frozen_imu_ticks = 20;
  /// A gap between accepted frames longer than this restarts the filter [s].
  double max_gap = 0.25;
  /// After a (re)start the state carries kInitializing for this long [s].
  double initializing_time = 0.5;
  /// Initial standard deviations (filter start and restart).
  double init_std_orientation = 0.02;           ///< [rad] per axis
  double init_std_velocity = 0.05;              ///< [m/s]
  double init_std_position = 0.01;              ///< [m]
  double init_std_gyro_bias = 0.01;             ///< [rad/s]
  double init_std_accel_bias = 0.05;            ///< [m/s^2]
  Vector3 init_gyro_bias_I = Vector3::Zero();   ///< [rad/s]
  Vector3 init_accel_bias_I = Vector3::Zero();  ///< [m/s^2]
  /// The start position: base x, y in W; z such that the lowest sole in contact (of both soles
  /// when none is) lies at ground_height.
  double init_base_x = 0.0;
  double init_base_y = 0.0;
  double ground_height = 0.0;
  /// Per foot (0 right, 1 left): height in W of the foot's sole point (the foot frame origin
  /// moved sole.height down its z axis) at the start, when it stands on a support of its own (a
  /// platform). NaN: not given, ground_height is used. With feet in contact that have a
  /// height, the start z is the mean over them of what each one says; otherwise as above.
  std::array<double, kNumFeet> support_height{std::numeric_limits<double>::quiet_NaN(),
                                              std::numeric_limits<double>::quiet_NaN()};
  /// The IMU's output latency in ticks (its filters and transfer: 1 for the simulator's default
  /// IMU, simulator/sim/SENSORS.md). Used only for an IMU behind joints (a torso IMU behind a
  /// waist): its pose relative to the base is then taken from the joint positions of this many
  /// ticks earlier, the time its sample describes, so that the base's attitude is consistently
  /// that IMU sample's (delayed as a base-mounted IMU's is); its rate relative to the base from
  /// this tick's joint velocities (estimator.cpp says why). Measured with the IMU on a swinging
  /// arm, the simulator's default sensors (tests/estimator/estimator_sim_test.cpp): attitude
  /// error max 1.6 deg with the 1 ms unaccounted for, 0.42 deg with it; base velocity RMS 34 ->
  /// 7.6 mm/s. 0..100.
  int imu_delay_ticks = 0;
};

class Estimator {
 public:
  /// Configures everything (allocates). Throws EstimatorError naming the problem: robot config
  /// frames unknown to the model, bad thresholds or noise. The IMU may sit on any body (a torso
  /// behind waist joints): its pose and velocity relative to the base then come from the joint
  /// encoders each tick.
  Estimator(const model::Model& model, const model::RobotConfig& robot,
            const EstimatorConfig& config = {});

  /// A state / sensor frame with every vector sized for this robot (configuration time).
  EstimatorState make_state() const;
  SensorFrame make_sensor_frame() const;

  /// One tick: consumes `frame`, writes `out` (never a non-finite number), returns its status
  /// flags (also in out.status_flags). Real-time safe: no allocation, no exception, no I/O.
  /// `out` must come from make_state(); otherwise kNonFiniteInput is returned and `out` untouched.
  StatusFlags update(const SensorFrame& frame, EstimatorState& out) noexcept;

  /// Forgets everything; the next frame initialises the filter.
  void reset() noexcept;

  const EstimatorDiagnostics& diagnostics() const noexcept { return diag_; }
  /// Plain leg-odometry baseline of the same frames (base pose and velocity of the base origin).
  const LegOdometry& leg_odometry() const noexcept { return baseline_; }
  EstimatorKind kind() const noexcept { return config_.kind; }
  const InvariantEkf& filter() const noexcept { return ekf_; }
  const model::Model& model() const noexcept { return model_; }
  bool initialized() const noexcept { return initialized_; }
  bool imu_frozen() const noexcept { return imu_frozen_; }
  /// Pose of the IMU frame in the base frame: fixed for a base-mounted IMU, this tick's joint
  /// positions' otherwise.
  const SE3& X_BI() const noexcept { return X_BI_; }
  /// True when the IMU frame is fixed to the floating base.
  bool imu_on_base() const noexcept { return imu_on_base_; }

 private:
  bool frame_is_valid(const SensorFrame& frame) noexcept;
  /// The foot in contact carrying the largest normal force, -1 when none is in contact.
  int loaded_stance_foot() const noexcept;
  void correct_with_kept_foot_orientations() noexcept;
  void calibrate_on_still_supports(const SensorFrame& frame, StatusFlags flags) noexcept;
  void compute_leg_kinematics(const SensorFrame& frame) noexcept;
  // One tick of update(), phase by phase.
  bool accept_tick(const SensorFrame& frame, StatusFlags& flags, double& dt,
                   EstimatorState& out) noexcept;
  void update_contacts(const SensorFrame& frame, double dt) noexcept;
  bool imu_is_frozen(const SensorFrame& frame) noexcept;
  void restart_from_fallback(const SensorFrame& frame) noexcept;
  void correct_with_stance_feet(const SensorFrame& frame, double dt) noexcept;
  void run_kinematic_fallback(double dt) noexcept;
  void update_baseline(const SensorFrame& frame, double dt) noexcept;
  void initialize(const SensorFrame& frame) noexcept;
  /// Base position for a base orientation: x, y from the config, z such that the soles in
  /// contact are at their start heights (initialize()).
  Vector3 start_position(const Matrix3& R_WB) const noexcept;
  /// End of the initialising window after a start without an IMU orientation: the start
  /// attitude came from one accelerometer sample (degrees off while the robot settles); the
  /// filter has corrected it since with the leg kinematics, so the base is re-placed at the
  /// start heights with the filter's attitude, and leg odometry integrates the gyro from there.
  void relevel_from_filter() noexcept;
  /// The base angular velocity published this tick from the bias-corrected gyro (base axes) and
  /// the stance feet (EstimatorConfig::stance_rate_filter_hz).
  Vector3 fuse_stance_rate(const Vector3& omega_gyro_B, double dt) noexcept;
  /// The base's angular velocity (base axes) from the IMU's (IMU axes): rotated, minus the IMU
  /// body's rate relative to the base from the joint velocities (zero on the base).
  Vector3 base_rate(const Vector3& omega_I) const noexcept {
    return X_BI_.R * omega_I - omega_I0_B_;
  }
  /// The IMU origin's velocity in W from the base's (v_WB, omega_WB in W, X_WB the base pose):
  /// rigid transport plus the IMU's motion relative to the base (R_WB v_I0_B).
  Vector3 imu_velocity(const SE3& X_WB, const Vector3& v_WB, const Vector3& omega_WB) const noexcept {
    return v_WB + omega_WB.cross(X_WB.R * X_BI_.p) + X_WB.R * v_I0_B_;
  }
  void write_output(const SensorFrame& frame, StatusFlags flags, EstimatorState& out) noexcept;
  void hold_output(const SensorFrame& frame, StatusFlags flags, EstimatorState& out) noexcept;
  InvariantEkf::Covariance initial_covariance() const noexcept;

  model::Model model_;
  model::Data data_;
  EstimatorConfig config_;
  std::array<int, kNumFeet> foot_frame_{-1, -1};
  std::array<double, kNumFeet> sole_height_{0.0, 0.0};
  SE3 X_BI_, X_IB_;  ///< this tick's (compute_leg_kinematics), fixed on the base
  double weight_ = 0.0;

  std::array<ContactDetector, kNumFeet> contact_;
  /// 16-byte aligned whatever the members before it: Eigen's kernels on its fixed-size 21 x 21
  /// covariance (not a multiple of 16 bytes, so not aligned by Eigen itself) take an alignment-
  /// dependent path, and a field added to EstimatorConfig moved it by 8 bytes and changed the
  /// round-off of every closed-loop run (ContactEvents.StepInPlace's pre-swing separation -5 ->
  /// -7 ms, 2026-12-05).
  alignas(16) InvariantEkf ekf_;
  LegOdometry baseline_;  ///< IMU orientation + kinematics (comparison)
  LegOdometry fallback_;  ///< stance-foot orientation + kinematics (IMU frozen)
  /// Leg odometry's orientation when the IMU gives none: the raw gyro integrated from the
  /// start orientation (or from the IMU's last orientation when it had one).
  Matrix3 R_WB_gyro_ = Matrix3::Identity();
  Vector3 omega_B_raw_ = Vector3::Zero();  ///< raw gyro in base axes, this tick
  bool started_without_orientation_ = false;  ///< initialize() had no IMU orientation

  // Workspaces (sized at construction).
  Eigen::VectorXd q_rel_, v_rel_;  ///< base at identity, base twist zero
  LegKinematics legs_;
  std::array<Vector3, kNumFeet> omega_F0_B_{Vector3::Zero(), Vector3::Zero()};  ///< J_ang qd
  std::array<Vector3, kNumFeet> v_F0_B_{Vector3::Zero(), Vector3::Zero()};      ///< J_lin qd
  Vector3 omega_B_ = Vector3::Zero();  ///< base angular velocity used this tick, base axes
  /// fuse_stance_rate(): low-passed gyro minus stance kinematic rate; valid while feet touch.
  Vector3 stance_rate_offset_ = Vector3::Zero();
  bool stance_rate_valid_ = false;
  double stance_rate_gated_for_ = 0.0;  ///< the gyro alone for this much longer [s]
  EstimatorState held_;                ///< last good output

  bool initialized_ = false;
  bool imu_frozen_ = false;
  bool have_last_imu_ = false;
  int same_imu_count_ = 0;
  Eigen::Quaterniond last_imu_q_ = Eigen::Quaterniond::Identity();
  Vector3 last_gyro_ = Vector3::Zero();
  Vector3 last_accel_ = Vector3::Zero();
  std::int64_t last_tick_ = 0;
  double time_since_init_ = 0.0;
  double time_since_start_ = 0.0;  ///< since the first start (restarts do not reset it)
  bool contacts_free_ = false;     ///< kMoving after its calibration: free contact points
  /// kTranslating: a stance foot's orientation in W, kept while it stays in contact.
  std::array<Matrix3, kNumFeet> R_WF_kept_{Matrix3::Identity(), Matrix3::Identity()};
  std::array<bool, kNumFeet> have_R_WF_{false, false};
  /// kMoving calibration: sum of gyro - the base's angular rate from the stance foot.
  Vector3 calib_gyro_sum_ = Vector3::Zero();
  long calib_samples_ = 0;
  EstimatorDiagnostics diag_;

  // The IMU frame.
  int imu_frame_ = -1;
  bool imu_on_base_ = true;
  /// The IMU frame's velocity relative to the base (base fixed, joint velocities): linear of its
  /// origin and angular, base axes; zero for a base-mounted IMU.
  Vector3 v_I0_B_ = Vector3::Zero();
  Vector3 omega_I0_B_ = Vector3::Zero();
  /// imu_delay_ticks > 0 with an IMU behind joints: the last imu_delay_ticks + 1 joint
  /// positions (columns, ring) and a model data for the IMU's kinematics.
  Eigen::MatrixXd q_ring_;
  int ring_next_ = 0;
  bool ring_full_ = false;
  model::Data imu_data_;
  Eigen::VectorXd q_imu_, v_imu_;
  /// The corners of each sole rectangle in its foot frame (the contact detector's swing rule).
  std::array<std::array<Vector3, 4>, kNumFeet> sole_corners_F_{};
};

}  // namespace poise::estimator
