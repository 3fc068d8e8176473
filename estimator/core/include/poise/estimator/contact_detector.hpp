#pragma once
// Contact detection from a foot force/torque sensor (Schmitt trigger on the normal force) and the
// measured centre of pressure on the sole plane.

#include "poise/estimator/types.hpp"

namespace poise::estimator {

/// Hysteresis thresholds on the force along the foot normal (the foot frame's z axis).
struct ContactThresholds {
  double on_force = 0.0;   ///< contact starts when the normal force rises above this [N]
  double off_force = 0.0;  ///< contact ends when it falls below this [N] (< on_force)
};

/// One foot's contact state. Real-time safe (no allocation, no exception).
class ContactDetector {
 public:
  ContactDetector() = default;
  /// Throws std::invalid_argument unless 0 <= off_force < on_force (finite).
  explicit ContactDetector(const ContactThresholds& thresholds);

  /// Feeds one wrench [force; torque] at Fo in F axes; returns the contact state after it.
  /// A non-finite normal force leaves the state unchanged.
  bool update(const Force& wrench_Fo_F) noexcept;
  bool in_contact() const noexcept { return in_contact_; }
  void reset(bool in_contact = false) noexcept { in_contact_ = in_contact; }
  const ContactThresholds& thresholds() const noexcept { return thresholds_; }

 private:
  ContactThresholds thresholds_{};
  bool in_contact_ = false;
};

/// Centre of pressure on the sole plane z = -sole_height of the foot frame F, in F coordinates:
/// the point of that plane about which the measured wrench has no tangential torque,
///   p_x = (-tau_y - h f_x) / f_z,  p_y = (tau_x - h f_y) / f_z,  p_z = -h.
/// Returns false (and leaves cop_F unchanged) when f_z <= min_normal_force.
bool center_of_pressure(const Force& wrench_Fo_F, double sole_height, double min_normal_force,
                        Vector3& cop_F) noexcept;

}  // namespace poise::estimator
