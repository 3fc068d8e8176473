#include "poise/estimator/leg_odometry.hpp"

namespace poise::estimator {

void LegOdometry::reset(const SE3& X_WB, const Vector3& v_WB, const LegKinematics& legs) noexcept {
  X_WB_ = X_WB;
  v_WB_ = v_WB;
  for (int f = 0; f < kNumFeet; ++f) {
    anchored_[f] = legs.contact[f];
    if (anchored_[f]) X_WF_anchor_[f] = X_WB_ * legs.X_BF[f];
  }
}

void LegOdometry::update(OrientationSource source, const Matrix3& R_WB_imu,
                         const LegKinematics& legs, double dt) noexcept {
  // Feet that lost contact are released.
  for (int f = 0; f < kNumFeet; ++f)
    if (!legs.contact[f]) anchored_[f] = false;

  // Orientation.
  int orient_foot = -1;
  for (int f = 0; f < kNumFeet; ++f) {
    if (anchored_[f] && (orient_foot < 0 || legs.normal_force[f] > legs.normal_force[orient_foot]))
      orient_foot = f;
  }
  if (source == OrientationSource::kStanceFoot && orient_foot >= 0) {
    X_WB_.R = X_WF_anchor_[orient_foot].R * legs.X_BF[orient_foot].R.transpose();
  } else if (R_WB_imu.allFinite()) {
    X_WB_.R = R_WB_imu;
  }

  // Position and velocity from the anchored stance feet.
  Vector3 p_sum = Vector3::Zero(), v_sum = Vector3::Zero();
  int n = 0;
  for (int f = 0; f < kNumFeet; ++f) {
    if (!anchored_[f]) continue;
    p_sum += X_WF_anchor_[f].p - X_WB_.R * legs.X_BF[f].p;
    v_sum += -(X_WB_.R * legs.v_BF_B[f]);
    ++n;
  }
  if (n > 0) {
    X_WB_.p = p_sum / n;
    v_WB_ = v_sum / n;
  } else {
    X_WB_.p += v_WB_ * dt + 0.5 * dt * dt * g_;
    v_WB_ += g_ * dt;
  }

  // New stance feet are anchored where the kinematics puts them now (after a flight phase: at
  // the ballistic prediction of the base).
  for (int f = 0; f < kNumFeet; ++f) {
    if (legs.contact[f] && !anchored_[f]) {
      X_WF_anchor_[f] = X_WB_ * legs.X_BF[f];
      anchored_[f] = true;
    }
  }
}

}  // namespace poise::estimator
