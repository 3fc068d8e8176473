#include "poise/estimator/contact_detector.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace poise::estimator {

ContactDetector::ContactDetector(const ContactThresholds& thresholds) : thresholds_(thresholds) {
  if (!std::isfinite(thresholds.on_force) || !std::isfinite(thresholds.off_force) ||
      thresholds.off_force < 0.0 || thresholds.off_force >= thresholds.on_force) {
    throw std::invalid_argument(
        "ContactDetector: thresholds must satisfy 0 <= off_force < on_force (got on_force = " +
        std::to_string(thresholds.on_force) +
        ", off_force = " + std::to_string(thresholds.off_force) + ")");
  }
}

bool ContactDetector::update(const Force& wrench_Fo_F) noexcept {
  const double fn = wrench_Fo_F[2];
  if (!std::isfinite(fn)) return in_contact_;
  if (in_contact_) {
    if (fn < thresholds_.off_force) in_contact_ = false;
  } else {
    if (fn > thresholds_.on_force) in_contact_ = true;
  }
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
