#pragma once
// Contact detection from a foot force/torque sensor and, when the estimator provides it, the
// foot's kinematic height (idl/README.md "Contact flags"), plus the measured centre of pressure
// on the sole plane.
//
// Per tick, with fn the force along the foot normal (the foot frame's z axis) minus the
// sensor offset learnt while the foot is clearly in the air:
//   touch-down when fn > on_force (at once), or fn > touch_force and rising faster than
//              touch_rate (at once: an impact), or fn > touch_force for confirm_ticks ticks;
//              never while the sole is more than max_touch_height above where it last stood
//              (kinematics given);
//   lift-off   when (kinematics given) the sole is lift_height above where it stood and still
//              rising, or when fn < off_force for confirm_ticks ticks;
//   plan       FootPlan::kSwing (the balance reference's FOOT_SWING): the controller unloads
//              the foot to zero, so the load must fall below swing_off_force (default
//              off_force / 2) for confirm_ticks ticks, or below it the sole (kinematics given)
//              must leave the ground: with the sole's corners given (FootKinematics::corner_z),
//              every corner rose more than swing_corner_rise (5 um) within the last
//              swing_corner_window (5 ms) and is higher than it was when the plan said swing (a
//              foot unloading to zero tips about an edge, and the truth's contact lasts while
//              one corner stays down: its centre rises 0.1 mm before it leaves); without
//              corners the sole centre must rise swing_lift_height (0.03 mm) above the lowest
//              it was since the plan said swing (the lift of a swing starts at zero velocity:
//              the 4 mm of lift_height come ~0.1 s after the sole left). kNone / kSupport: the
//              rules above (a planned support may still be lifted by a push);
//   resting    with rest_time > 0 (0 here: off by default for the detector alone; 0.02 s in
//              EstimatorConfig::contact_rest_time, see there; poise-estimator
//              --contact-rest-time S), a foot whose load stayed below touch_force for rest_time
//              with its sole within lift_height of where it stood, or whose contact began with a
//              touch-down and has not carried more than touch_force for rest_time since (a
//              landing: its impact is not a load it stood on, and on the step in place the
//              landed foot's load fell below off_force 12-15 ms after the impact while it kept
//              touching with 2-5 N), keeps its contact whatever its load -- provided the
//              sole was still when it began to rest (corners given: every corner moved less
//              than rest_corner_motion within swing_corner_window; a foot rocking on its edge
//              that taps the ground with a corner is not resting) -- until
//              its sole rises (lift_height), every corner of its sole (corners given) rose as
//              the plan's corner rule asks above where it was when the foot began to rest, or
//              the plan's swing rule fires: the flag then means
//              "touching", not "loaded" (a foot the weight shifted off rests on the ground with
//              3-10 N). The balance controller rests a foot (Sec. 4.2, its CoP rule) on the
//              measured load, not on this flag (ControllerConfig::resting_force_fraction).
//              rest_time tells a fast unloading (pushes, the drop's bounces: the load went from
//              touch_force to below off_force within 0-9 ms, measured) from the weight moving
//              off a foot that stays down (40-58 ms on the step in place); the former still ends
//              the contact by force. A planned swing's foot (below touch_force for 29 ms before
//              its sole left) may rest too: its lift-off then comes from the plan's rule
//              (the sole swing_lift_height up), or without a plan once the sole is lift_height up.
//   light      with light_noise > 0 (the F/T normal-force noise, 1 sigma, 0.5 N for the
//              simulator's; the Estimator's EstimatorConfig::contact_ft_noise, 0.5 N by
//              default), a touch too light for the rules above
//              (below touch_force: a foot that re-touches with 2 N while the weight is on the
//              other one) is told from the air by the step it makes in the reading: a CUSUM of
//              fn - (baseline + 2 sigma), the baseline being the reading's mean while the foot
//              was out of contact (the sensor offset plus any load too light to matter, learnt
//              over light_baseline_time; the rule waits until that is learnt), touches down
//              once it passes 6 sigma with the sole within lift_height of where it stood and not
//              rising. A 2 sigma step is then flagged after ~3 ticks, a 4 sigma one sooner;
//              noise alone needs several 2 sigma excesses in a row. The light contact ends by
//              the mirror CUSUM of (baseline + sigma) - fn passing 6 sigma (the dead band
//              between sigma and 2 sigma keeps a load there from chattering), by the lift and
//              plan rules (the plan's with the reading at or below the baseline), and becomes an
//              ordinary contact above touch_force (confirm_ticks);
// A sliding foot keeps its load, so neither rule fires while it slides (no chatter).

#include <array>
#include <limits>

#include "poise/estimator/types.hpp"

namespace poise::estimator {

/// Thresholds of the detector. The two-number form {on_force, off_force} of earlier versions is
/// still valid (the others keep their defaults; touch_force <= 0 means off_force + the
/// hysteresis gap to on_force / 4).
struct ContactThresholds {
  double on_force = 0.0;   ///< contact starts at once above this [N]
  double off_force = 0.0;  ///< contact ends below this (confirmed) [N] (< on_force)
  double touch_force = 0.0;    ///< light-contact threshold (confirmed, or with touch_rate) [N]
  double touch_rate = 2000.0;  ///< force rise that marks an impact [N/s]
  int confirm_ticks = 2;       ///< ticks a light or vanishing load must persist (>= 1)
  double max_touch_height = 0.02;  ///< no touch-down with the sole this far up [m]
  double lift_height = 0.004;      ///< lift-off once the sole is this far up and rising [m]
  double tare_height = 0.03;  ///< above this (in the air) the F/T reading is learnt as offset [m]
  double tare_time = 0.05;    ///< time constant of that offset estimate [s]
  /// A foot whose load stayed below touch_force this long without its sole rising rests: low
  /// force alone no longer ends its contact [s] (>= 0; 0: the resting rule is off, the default
  /// of the detector alone; the Estimator's is EstimatorConfig::contact_rest_time).
  double rest_time = 0.0;
  /// With the plan kSwing: lift-off below this load [N] (<= off_force; <= 0: off_force / 2).
  double swing_off_force = 0.0;
  /// With the plan kSwing and fn < swing_off_force: lift-off once the sole is this far above the
  /// lowest it was since the plan said swing, and rising [m] (>= 0).
  double swing_lift_height = 3e-5;
  /// With the plan kSwing, fn < swing_off_force and the corners given: lift-off once every
  /// corner of the sole rose more than swing_corner_rise within the last swing_corner_window
  /// and stands above where it was when the plan said swing [m] (>= 0; 5 um: 3 sigma of the
  /// estimated sole's tick-to-tick noise in the simulator's closed loop, idl/README.md).
  double swing_corner_rise = 5e-6;
  double swing_corner_window = 0.005;  ///< [s] (> 0; at most kCornerHistory ticks are kept)
  /// The F/T normal-force noise (1 sigma) for the light-touch rule [N] (>= 0; 0: the rule is off,
  /// the default of the detector alone; the Estimator's is EstimatorConfig::contact_ft_noise).
  double light_noise = 0.0;
  /// How long the foot must have been out of contact before the light-touch rule may fire: the
  /// baseline's time constant [s] (> 0).
  double light_baseline_time = 0.05;
  /// With the corners given, a foot begins to rest (either resting rule) only while every corner
  /// of its sole moved less than this within the last swing_corner_window [m] (>= 0): a foot
  /// rocking on an edge or tapping the ground with a corner is not resting, and a resting
  /// foot's contact ends only when every corner rises (a rocking foot's high corners come down
  /// while its low ones leave: 0.1-0.2 mm per 5 ms, measured on a 265 N push at 45 deg).
  /// Until swing_corner_window of corners is kept (the first ticks, after a change of
  /// corner_reference or a tick without corners) no foot begins to rest; without corners at
  /// all the gate is off (the sole height's rules alone).
  double rest_corner_motion = 5e-5;
};

/// What the estimator knows of the foot's motion this tick (NaN: unknown).
struct FootKinematics {
  double sole_z = std::numeric_limits<double>::quiet_NaN();  ///< sole centre height in W [m]
  double dt = 0.001;                                         ///< since the previous tick [s]
  /// Heights in W of the sole rectangle's four corners [m] (NaN: unknown; the plan's swing rule
  /// then uses sole_z).
  std::array<double, 4> corner_z{
      std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
      std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  /// What corner_z is measured from (0: W; another value: another frame, e.g. the other foot's
  /// sole); the detector compares heights of one reference only.
  int corner_reference = 0;
  FootPlan plan = FootPlan::kNone;  ///< the plan in force (not kinematics: the detector's prior)
};

/// One foot's contact state. Real-time safe (no allocation, no exception).
class ContactDetector {
 public:
  ContactDetector() = default;
  /// Throws std::invalid_argument unless 0 <= off_force < on_force and the other fields are
  /// finite and in range (touch_force < on_force, touch_rate > 0, confirm_ticks >= 1, heights
  /// >= 0, tare_time > 0, rest_time >= 0, swing_off_force <= off_force, swing_lift_height >= 0,
  /// swing_corner_rise >= 0, swing_corner_window > 0).
  explicit ContactDetector(const ContactThresholds& thresholds);

  /// Feeds one wrench [force; torque] at Fo in F axes, and optionally the foot's kinematics;
  /// returns the contact state after it. A non-finite normal force leaves the state unchanged.
  bool update(const Force& wrench_Fo_F, const FootKinematics& kin = FootKinematics{}) noexcept;
  bool in_contact() const noexcept { return in_contact_; }
  /// The foot is in contact and rests (see the header comment).
  bool resting() const noexcept { return resting_; }
  /// The foot is in contact by the light-touch rule (its load stayed below touch_force).
  bool light() const noexcept { return light_; }
  void reset(bool in_contact = false) noexcept;
  const ContactThresholds& thresholds() const noexcept { return thresholds_; }
  /// Normal force offset learnt in the air [N] (0 until the foot was clearly up once).
  double force_offset() const noexcept { return offset_; }

 private:
  struct Signals;
  void read_sole_height(const FootKinematics& kin, Signals& sig) noexcept;
  void read_corners(const FootKinematics& kin, Signals& sig) noexcept;
  void read_swing_plan(const FootKinematics& kin, Signals& sig) noexcept;
  void read_normal_force(double raw, const FootKinematics& kin, Signals& sig) noexcept;
  void update_in_contact(const FootKinematics& kin, const Signals& sig) noexcept;
  bool update_resting(const FootKinematics& kin, const Signals& sig) noexcept;
  void update_out_of_contact(const Signals& sig) noexcept;

  ContactThresholds thresholds_{};
  bool in_contact_ = false;
  int pending_ = 0;        ///< consecutive ticks the opposite condition held
  double fn_prev_ = 0.0;   ///< previous corrected normal force
  bool have_prev_ = false;
  double support_z_ = 0.0;  ///< sole height when the foot last stood [m]
  bool have_support_ = false;
  double z_prev_ = 0.0;
  bool have_z_ = false;
  double offset_ = 0.0;
  double light_time_ = 0.0;  ///< how long the load has stayed below touch_force in contact [s]
  bool resting_ = false;
  bool swing_seen_ = false;  ///< the plan says kSwing (and said so at the previous update)
  double swing_low_z_ = 0.0;  ///< lowest sole height since then [m]
  bool light_ = false;        ///< in contact by the light-touch rule
  /// The sole corners' heights of the last ticks (ring) and the time they were taken, for the
  /// plan's corner rule; the corners when the plan said swing.
  static constexpr int kCornerHistory = 64;
  std::array<std::array<double, 4>, kCornerHistory> corner_ring_{};
  std::array<double, kCornerHistory> corner_time_{};
  int corner_next_ = 0;
  int corner_count_ = 0;
  int corner_reference_ = 0;
  double corner_clock_ = 0.0;
  std::array<double, 4> swing_start_corner_{};
  std::array<double, 4> rest_start_corner_{};  ///< the corners when the foot began to rest
  double baseline_ = 0.0;     ///< mean reading out of contact [N]
  double baseline_age_ = 0.0;  ///< how long it has been learnt [s]
  double cusum_ = 0.0;        ///< the touch (out of contact) or release (light) CUSUM [N]
  /// The contact began by a touch-down and the foot has not yet carried more than touch_force
  /// for rest_time since (a landing whose load falls back rests at once: the header comment).
  bool landed_ = false;
  double loaded_time_ = 0.0;  ///< how long the load has stayed above touch_force [s]
};

/// Centre of pressure on the sole plane z = -sole_height of the foot frame F, in F coordinates:
/// the point of that plane about which the measured wrench has no tangential torque,
///   p_x = (-tau_y - h f_x) / f_z,  p_y = (tau_x - h f_y) / f_z,  p_z = -h.
/// Returns false (and leaves cop_F unchanged) when f_z <= min_normal_force.
bool center_of_pressure(const Force& wrench_Fo_F, double sole_height, double min_normal_force,
                        Vector3& cop_F) noexcept;

}  // namespace poise::estimator
