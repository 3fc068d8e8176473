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

bool ContactDetector::update(const Force& wrench_Fo_F, const FootKinematics& kin) noexcept {
  const ContactThresholds& t = thresholds_;
  const double raw = wrench_Fo_F[2];
  if (!std::isfinite(raw)) return in_contact_;

  // Kinematics: height of the sole above where it last stood, and whether it rises.
  const bool have_kin = std::isfinite(kin.sole_z) && std::isfinite(kin.dt) && kin.dt > 0.0;
  double height = std::numeric_limits<double>::quiet_NaN();
  bool rising = false;
  if (have_kin) {
    if (!have_support_) {
      support_z_ = kin.sole_z;
      have_support_ = true;
    }
    height = kin.sole_z - support_z_;
    rising = have_z_ && kin.sole_z > z_prev_;
    z_prev_ = kin.sole_z;
    have_z_ = true;
  } else {
    have_z_ = false;
  }
  // The sole's corners: their heights over the last swing_corner_window.
  const bool have_corners = have_kin && std::isfinite(kin.corner_z[0]) &&
                            std::isfinite(kin.corner_z[1]) && std::isfinite(kin.corner_z[2]) &&
                            std::isfinite(kin.corner_z[3]);
  bool corners_lifted = false;
  bool corners_still = !have_corners;  // no corners: the sole height's rule alone
  if (have_corners && kin.corner_reference != corner_reference_) {
    // Heights from another reference: the history and the swing's and rest's starts restart.
    corner_count_ = 0;
    corner_reference_ = kin.corner_reference;
    swing_start_corner_ = kin.corner_z;
    rest_start_corner_ = kin.corner_z;
  }
  if (have_corners) {
    corner_clock_ += kin.dt;
    // Every corner rose more than swing_corner_rise since the newest sample at least
    // swing_corner_window old (none that old yet: not lifted).
    for (int k = 1; k <= corner_count_; ++k) {
      const int i = (corner_next_ - k + kCornerHistory) % kCornerHistory;
      if (corner_clock_ - corner_time_[i] < t.swing_corner_window - 1e-9) continue;
      corners_lifted = true;
      corners_still = true;
      for (int c = 0; c < 4; ++c) {
        const double moved = kin.corner_z[c] - corner_ring_[i][c];
        corners_lifted = corners_lifted && moved > t.swing_corner_rise;
        corners_still = corners_still && std::abs(moved) < t.rest_corner_motion;
      }
      break;
    }
    corner_ring_[corner_next_] = kin.corner_z;
    corner_time_[corner_next_] = corner_clock_;
    corner_next_ = (corner_next_ + 1) % kCornerHistory;
    corner_count_ = std::min(corner_count_ + 1, kCornerHistory);
  } else {
    corner_count_ = 0;
  }
  // The plan: the lowest sole height since it said swing, and the corners then.
  const bool swing = kin.plan == FootPlan::kSwing;
  if (swing && have_kin) {
    if (!swing_seen_ && have_corners) swing_start_corner_ = kin.corner_z;
    swing_low_z_ = swing_seen_ ? std::min(swing_low_z_, kin.sole_z) : kin.sole_z;
    swing_seen_ = true;
  } else {
    swing_seen_ = false;
  }
  bool swing_corners_lifted = corners_lifted && swing_seen_;
  if (swing_corners_lifted)
    for (int c = 0; c < 4; ++c)
      swing_corners_lifted = swing_corners_lifted && kin.corner_z[c] > swing_start_corner_[c];

  // F/T offset: learnt while the foot is clearly in the air (the reading is then the offset).
  if (!in_contact_ && have_kin && height > t.tare_height) {
    const double a = std::min(1.0, kin.dt / t.tare_time);
    offset_ += a * (raw - offset_);
  }
  const double fn = raw - offset_;
  const double rate = have_prev_ ? (fn - fn_prev_) / (have_kin ? kin.dt : 0.001) : 0.0;
  fn_prev_ = fn;
  have_prev_ = true;

  const double step = have_kin ? kin.dt : 0.001;
  const double sigma = t.light_noise;
  // The light-touch CUSUM's threshold (header comment): 6 sigma.
  const double cusum_limit = 6.0 * sigma;

  if (in_contact_) {
    if (light_) {
      // An ordinary contact once its load stays above touch_force for confirm_ticks (one tick
      // of an impact spike does not make it one: the 1 % rule would then end it at once).
      pending_ = fn > t.touch_force ? pending_ + 1 : 0;
      if (pending_ >= t.confirm_ticks) {
        light_ = false;
        pending_ = 0;
      }
    }
    light_time_ = fn < t.touch_force ? light_time_ + step : 0.0;
    loaded_time_ = fn > t.touch_force ? loaded_time_ + step : 0.0;
    if (loaded_time_ >= t.rest_time) landed_ = false;
    // Resting (rule on when rest_time > 0): lightly loaded for rest_time with the sole where it
    // stood (kinematics given), or lightly loaded after a landing that never carried the load
    // for rest_time (the impact's transient is not a load the foot stood on).
    const bool was_resting = resting_;
    resting_ = t.rest_time > 0.0 && have_kin && !(height > t.lift_height) &&
               (light_time_ >= t.rest_time || (landed_ && fn < t.touch_force)) &&
               (was_resting || corners_still);
    if (resting_ && !was_resting && have_corners) rest_start_corner_ = kin.corner_z;
    // A resting foot (no load to tell) leaves the ground when its corners do, as a planned
    // swing's (the corner rule), or once its sole is lift_height up.
    bool rest_lifted = resting_ && was_resting && have_corners && corners_lifted;
    if (rest_lifted)
      for (int c = 0; c < 4; ++c)
        rest_lifted = rest_lifted && kin.corner_z[c] > rest_start_corner_[c];
    const bool lifted = (have_kin && height > t.lift_height && rising) || rest_lifted;
    // Planned swing: the load must fall to swing_off_force (the controller unloads the foot to
    // zero), or below it the sole leaves its lowest height since the swing began. A light
    // contact's load is measured from its baseline.
    const double off = swing_seen_ ? t.swing_off_force : t.off_force;
    const double load = light_ ? fn - baseline_ : fn;
    const bool swing_left_ground = have_corners
                                       ? swing_corners_lifted
                                       : rising && kin.sole_z - swing_low_z_ > t.swing_lift_height;
    const bool swing_lifted = swing_seen_ && load < (light_ ? 0.0 : off) && swing_left_ground;
    if (lifted || swing_lifted) {
      in_contact_ = false;
      pending_ = 0;
    } else if (light_) {
      // The release CUSUM: the reading back within sigma of the baseline.
      cusum_ = std::max(0.0, cusum_ + (baseline_ + sigma - fn));
      if (cusum_ > cusum_limit) in_contact_ = false;
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
  } else {
    const bool too_high = have_kin && height > t.max_touch_height;
    if (too_high) {
      pending_ = 0;
    } else if (fn > t.on_force || (fn > t.touch_force && rate > t.touch_rate)) {
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
    // The light touch: a step in the reading above its baseline out of contact, with the sole
    // down where it stood and not rising (kinematics given).
    const bool baseline_ready = baseline_age_ >= t.light_baseline_time;
    if (!in_contact_ && sigma > 0.0 && baseline_ready && have_kin && !(height > t.lift_height) &&
        !rising) {
      cusum_ = std::max(0.0, cusum_ + (fn - baseline_ - 2.0 * sigma));
      if (cusum_ > cusum_limit) {
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
      const double a = baseline_age_ > 0.0 ? std::min(1.0, step / t.light_baseline_time) : 1.0;
      baseline_ += a * (fn - baseline_);
      baseline_age_ += step;
    }
  }
  // Where the foot stands: its height while it carries a load.
  if (in_contact_ && have_kin && fn > t.touch_force) support_z_ = kin.sole_z;
  return in_contact_;
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
