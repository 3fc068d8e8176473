#include "poise/estimator/contact_detector.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace poise::estimator {

ContactDetector::ContactDetector(const ContactThresholds& thresholds) : thresholds_(thresholds) {
  ContactThresholds& t = thresholds_;
  const auto fail = [&](const std::string& what) {
    throw std::invalid_argument("ContactDetector: " + what + " (got on_force = " +
                                std::to_string(t.on_force) +
                                ", off_force = " + std::to_string(t.off_force) +
                                ", touch_force = " + std::to_string(t.touch_force) + ")");
  };
  if (!std::isfinite(t.on_force) || !std::isfinite(t.off_force) || t.off_force < 0.0 ||
      t.off_force >= t.on_force)
    fail("thresholds must satisfy 0 <= off_force < on_force");
  if (!std::isfinite(t.touch_force)) fail("touch_force must be finite");
  if (t.touch_force <= 0.0) t.touch_force = t.off_force + 0.25 * (t.on_force - t.off_force);
  if (t.touch_force < t.off_force || t.touch_force >= t.on_force)
    fail("touch_force must be in [off_force, on_force)");
  if (!(t.touch_rate > 0.0) || !std::isfinite(t.touch_rate)) fail("touch_rate must be > 0");
  if (t.confirm_ticks < 1 || t.confirm_ticks > 1000) fail("confirm_ticks must be in [1, 1000]");
  if (!(t.max_touch_height >= 0.0) || !(t.lift_height >= 0.0) || !(t.tare_height >= 0.0) ||
      !std::isfinite(t.max_touch_height) || !std::isfinite(t.lift_height) ||
      !std::isfinite(t.tare_height))
    fail("max_touch_height, lift_height and tare_height must be finite and >= 0");
  if (!(t.tare_time > 0.0) || !std::isfinite(t.tare_time)) fail("tare_time must be > 0");
  if (!(t.rest_time >= 0.0) || !std::isfinite(t.rest_time)) fail("rest_time must be >= 0");
  if (!std::isfinite(t.swing_off_force)) fail("swing_off_force must be finite");
  if (t.swing_off_force <= 0.0) t.swing_off_force = 0.5 * t.off_force;
  if (t.swing_off_force > t.off_force) fail("swing_off_force must be <= off_force");
  if (!(t.swing_lift_height >= 0.0) || !std::isfinite(t.swing_lift_height))
    fail("swing_lift_height must be finite and >= 0");
  if (!(t.swing_corner_rise >= 0.0) || !std::isfinite(t.swing_corner_rise))
    fail("swing_corner_rise must be finite and >= 0");
  if (!(t.swing_corner_window > 0.0) || !std::isfinite(t.swing_corner_window))
    fail("swing_corner_window must be finite and > 0");
  if (!(t.light_noise >= 0.0) || !std::isfinite(t.light_noise))
    fail("light_noise must be finite and >= 0");
  if (!(t.light_baseline_time > 0.0) || !std::isfinite(t.light_baseline_time))
    fail("light_baseline_time must be > 0");
  if (!(t.rest_corner_motion >= 0.0) || !std::isfinite(t.rest_corner_motion))
    fail("rest_corner_motion must be finite and >= 0");
}

void ContactDetector::reset(bool in_contact) noexcept {
  in_contact_ = in_contact;
  pending_ = 0;
  have_prev_ = false;
  have_support_ = false;
  have_z_ = false;
  light_time_ = 0.0;
  resting_ = false;
  swing_seen_ = false;
  light_ = false;
  baseline_age_ = 0.0;
  cusum_ = 0.0;
  corner_count_ = 0;
  landed_ = false;
  loaded_time_ = 0.0;
}

/// What one tick's inputs say, before the contact decision.
struct ContactDetector::Signals {
  bool have_kin = false;
  double height = std::numeric_limits<double>::quiet_NaN();  ///< sole over where it last stood
  bool rising = false;
  bool have_corners = false;
  bool corners_lifted = false;  ///< every corner rose by swing_corner_rise over the window
  bool corners_still = true;    ///< no corner moved by rest_corner_motion over the window
  bool swing_corners_lifted = false;  ///< lifted, and above where they were when the swing began
  double fn = 0.0;    ///< normal force less the learnt offset [N]
  double rate = 0.0;  ///< its rate [N/s]
  double step = 0.001;
};

bool ContactDetector::update(const Force& wrench_Fo_F, const FootKinematics& kin) noexcept {
  const double raw = wrench_Fo_F[2];
  if (!std::isfinite(raw)) return in_contact_;
  Signals sig;
  read_sole_height(kin, sig);
  read_corners(kin, sig);
  read_swing_plan(kin, sig);
  read_normal_force(raw, kin, sig);
  if (in_contact_)
    update_in_contact(kin, sig);
  else
    update_out_of_contact(sig);
  // Where the foot stands: its height while it carries a load.
  if (in_contact_ && sig.have_kin && sig.fn > thresholds_.touch_force) support_z_ = kin.sole_z;
  return in_contact_;
}

// Kinematics: height of the sole above where it last stood, and whether it rises.
void ContactDetector::read_sole_height(const FootKinematics& kin, Signals& sig) noexcept {
  sig.have_kin = std::isfinite(kin.sole_z) && std::isfinite(kin.dt) && kin.dt > 0.0;
  if (!sig.have_kin) {
    have_z_ = false;
    return;
  }
  if (!have_support_) {
    support_z_ = kin.sole_z;
    have_support_ = true;
  }
  sig.height = kin.sole_z - support_z_;
  sig.rising = have_z_ && kin.sole_z > z_prev_;
  z_prev_ = kin.sole_z;
  have_z_ = true;
}

// The sole's corners: their heights over the last swing_corner_window.
void ContactDetector::read_corners(const FootKinematics& kin, Signals& sig) noexcept {
  const ContactThresholds& t = thresholds_;
  sig.have_corners = sig.have_kin && std::isfinite(kin.corner_z[0]) &&
                     std::isfinite(kin.corner_z[1]) && std::isfinite(kin.corner_z[2]) &&
                     std::isfinite(kin.corner_z[3]);
  sig.corners_still = !sig.have_corners;  // no corners: the sole height's rule alone
  if (!sig.have_corners) {
    corner_count_ = 0;
    return;
  }
  if (kin.corner_reference != corner_reference_) {
    // Heights from another reference: the history and the swing's and rest's starts restart.
    corner_count_ = 0;
    corner_reference_ = kin.corner_reference;
    swing_start_corner_ = kin.corner_z;
    rest_start_corner_ = kin.corner_z;
  }
  corner_clock_ += kin.dt;
  // Every corner rose more than swing_corner_rise since the newest sample at least
  // swing_corner_window old (none that old yet: not lifted).
  for (int k = 1; k <= corner_count_; ++k) {
    const int i = (corner_next_ - k + kCornerHistory) % kCornerHistory;
    if (corner_clock_ - corner_time_[i] < t.swing_corner_window - 1e-9) continue;
    sig.corners_lifted = true;
    sig.corners_still = true;
    for (int c = 0; c < 4; ++c) {
      const double moved = kin.corner_z[c] - corner_ring_[i][c];
      sig.corners_lifted = sig.corners_lifted && moved > t.swing_corner_rise;
      sig.corners_still = sig.corners_still && std::abs(moved) < t.rest_corner_motion;
    }
    break;
  }
  corner_ring_[corner_next_] = kin.corner_z;
  corner_time_[corner_next_] = corner_clock_;
  corner_next_ = (corner_next_ + 1) % kCornerHistory;
  corner_count_ = std::min(corner_count_ + 1, kCornerHistory);
}

// The plan: the lowest sole height since it said swing, and the corners then.
void ContactDetector::read_swing_plan(const FootKinematics& kin, Signals& sig) noexcept {
  const bool swing = kin.plan == FootPlan::kSwing;
  if (swing && sig.have_kin) {
    if (!swing_seen_ && sig.have_corners) swing_start_corner_ = kin.corner_z;
    swing_low_z_ = swing_seen_ ? std::min(swing_low_z_, kin.sole_z) : kin.sole_z;
    swing_seen_ = true;
  } else {
    swing_seen_ = false;
  }
  sig.swing_corners_lifted = sig.corners_lifted && swing_seen_;
  if (sig.swing_corners_lifted)
    for (int c = 0; c < 4; ++c)
      sig.swing_corners_lifted = sig.swing_corners_lifted && kin.corner_z[c] > swing_start_corner_[c];
}

// F/T offset: learnt while the foot is clearly in the air (the reading is then the offset); the
// normal force less it, and its rate.
void ContactDetector::read_normal_force(double raw, const FootKinematics& kin,
                                        Signals& sig) noexcept {
  const ContactThresholds& t = thresholds_;
  if (!in_contact_ && sig.have_kin && sig.height > t.tare_height) {
    const double a = std::min(1.0, kin.dt / t.tare_time);
    offset_ += a * (raw - offset_);
  }
  sig.fn = raw - offset_;
  sig.rate = have_prev_ ? (sig.fn - fn_prev_) / (sig.have_kin ? kin.dt : 0.001) : 0.0;
  fn_prev_ = sig.fn;
  have_prev_ = true;
  sig.step = sig.have_kin ? kin.dt : 0.001;
}

// In contact: the load's timers, resting, and whether the contact ends (lifted, a planned swing
// that left the ground, a light contact's release, or a load below off_force).
void ContactDetector::update_in_contact(const FootKinematics& kin, const Signals& sig) noexcept {
  const ContactThresholds& t = thresholds_;
  const double fn = sig.fn;
  if (light_) {
    // An ordinary contact once its load stays above touch_force for confirm_ticks (one tick
    // of an impact spike does not make it one: the 1 % rule would then end it at once).
    pending_ = fn > t.touch_force ? pending_ + 1 : 0;
    if (pending_ >= t.confirm_ticks) {
      light_ = false;
      pending_ = 0;
    }
  }
  light_time_ = fn < t.touch_force ? light_time_ + sig.step : 0.0;
  loaded_time_ = fn > t.touch_force ? loaded_time_ + sig.step : 0.0;
  if (loaded_time_ >= t.rest_time) landed_ = false;
  const bool lifted = update_resting(kin, sig);
  // Planned swing: the load must fall to swing_off_force (the controller unloads the foot to
  // zero), or below it the sole leaves its lowest height since the swing began. A light
  // contact's load is measured from its baseline.
  const double off = swing_seen_ ? t.swing_off_force : t.off_force;
  const double load = light_ ? fn - baseline_ : fn;
  const bool swing_left_ground =
      sig.have_corners ? sig.swing_corners_lifted
                       : sig.rising && kin.sole_z - swing_low_z_ > t.swing_lift_height;
  const bool swing_lifted = swing_seen_ && load < (light_ ? 0.0 : off) && swing_left_ground;
  if (lifted || swing_lifted) {
    in_contact_ = false;
    pending_ = 0;
  } else if (light_) {
    // The release CUSUM: the reading back within sigma of the baseline.
    cusum_ = std::max(0.0, cusum_ + (baseline_ + t.light_noise - fn));
    if (cusum_ > 6.0 * t.light_noise) in_contact_ = false;  // the CUSUM's threshold: 6 sigma
  } else if (fn < off) {
    ++pending_;
    if (!resting_ && pending_ >= t.confirm_ticks) {
      in_contact_ = false;
      pending_ = 0;
    }
  } else {
    pending_ = 0;
  }
  if (!in_contact_) {
    light_time_ = 0.0;
    landed_ = false;
    resting_ = false;
    light_ = false;
    cusum_ = 0.0;
    baseline_age_ = 0.0;
  }
}

// Resting (rule on when rest_time > 0): lightly loaded for rest_time with the sole where it
// stood (kinematics given), or lightly loaded after a landing that never carried the load for
// rest_time (the impact's transient is not a load the foot stood on). Returns whether the foot
// lifted: its sole lift_height up and rising, or, resting (no load to tell), its corners left
// the ground as a planned swing's (the corner rule).
bool ContactDetector::update_resting(const FootKinematics& kin, const Signals& sig) noexcept {
  const ContactThresholds& t = thresholds_;
  const bool was_resting = resting_;
  resting_ = t.rest_time > 0.0 && sig.have_kin && !(sig.height > t.lift_height) &&
             (light_time_ >= t.rest_time || (landed_ && sig.fn < t.touch_force)) &&
             (was_resting || sig.corners_still);
  if (resting_ && !was_resting && sig.have_corners) rest_start_corner_ = kin.corner_z;
  bool rest_lifted = resting_ && was_resting && sig.have_corners && sig.corners_lifted;
  if (rest_lifted)
    for (int c = 0; c < 4; ++c)
      rest_lifted = rest_lifted && kin.corner_z[c] > rest_start_corner_[c];
  return (sig.have_kin && sig.height > t.lift_height && sig.rising) || rest_lifted;
}

// Out of contact: a touch (above on_force, or above touch_force rising fast or for confirm_ticks,
// the sole not too high), or a light touch (a step in the reading above its baseline, with the
// sole down where it stood and not rising: a CUSUM); the baseline learns meanwhile.
void ContactDetector::update_out_of_contact(const Signals& sig) noexcept {
  const ContactThresholds& t = thresholds_;
  const double fn = sig.fn;
  const double sigma = t.light_noise;
  if (sig.have_kin && sig.height > t.max_touch_height) {
    pending_ = 0;
  } else if (fn > t.on_force || (fn > t.touch_force && sig.rate > t.touch_rate)) {
    in_contact_ = true;
    pending_ = 0;
  } else if (fn > t.touch_force) {
    if (++pending_ >= t.confirm_ticks) {
      in_contact_ = true;
      pending_ = 0;
    }
  } else {
    pending_ = 0;
  }
  const bool baseline_ready = baseline_age_ >= t.light_baseline_time;
  if (!in_contact_ && sigma > 0.0 && baseline_ready && sig.have_kin &&
      !(sig.height > t.lift_height) && !sig.rising) {
    cusum_ = std::max(0.0, cusum_ + (fn - baseline_ - 2.0 * sigma));
    if (cusum_ > 6.0 * sigma) {  // the light-touch CUSUM's threshold (header comment): 6 sigma
      in_contact_ = true;
      light_ = true;
    }
  } else {
    cusum_ = 0.0;
  }
  if (in_contact_) {
    cusum_ = 0.0;
    landed_ = true;
    loaded_time_ = 0.0;
  } else if (cusum_ == 0.0) {
    // The baseline learns while no touch is suspected (a mean over light_baseline_time).
    const double a = baseline_age_ > 0.0 ? std::min(1.0, sig.step / t.light_baseline_time) : 1.0;
    baseline_ += a * (fn - baseline_);
    baseline_age_ += sig.step;
  }
}

bool center_of_pressure(const Force& wrench_Fo_F, double sole_height, double min_normal_force,
                        Vector3& cop_F) noexcept {
  const double fz = wrench_Fo_F[2];
  if (!(fz > min_normal_force) || !(fz > 0.0)) return false;
  const double h = sole_height;
  cop_F.x() = (-wrench_Fo_F[4] - h * wrench_Fo_F[0]) / fz;
  cop_F.y() = (wrench_Fo_F[3] - h * wrench_Fo_F[1]) / fz;
  cop_F.z() = -h;
  return true;
}

}  // namespace poise::estimator
