#pragma once
// The model's CoM error, observed from the measured centre of pressure (not in the paper: its
// first future work is robustness to modelling errors).
//
// The controller computes the CoM r_G from its model (the URDF's masses at the estimated joint
// angles). A real robot's masses and CoMs differ, so its CoM is r_G + delta, and eqs (10)-(11)
// then bring the model's CoM, not the robot's, over the supports: the robot stands with its
// weight off the point it was asked to stand on by the error delta.
//
// The feet measure where the weight really is: a robot at rest has its centre of pressure p
// under its CoM, whatever its masses are. The observer learns the horizontal error from that,
//   delta += a (p - r_G - delta),  a = dt / (dt + 1 / (2 pi f)),
// clamped to a disc of radius `limit`, and the controller uses r_G + delta as the CoM in
// (10)-(11), in the ankle strategy and in the contact problem.
//
// Moving, p - r = -(h / f_z) f_xy -/+ k_dot / f_z (h: CoM height over p; the centroidal dynamics
// with the ground wrench at p), which is not noise: the observer learns only while the CoM
// moves slower than `speed_gate` relative to its supports and at least half the weight is on
// the feet, and its low bandwidth averages what is left.
// - It does not correct p by the wrenches the controller planned on the last tick (the state carries no
//   horizontal foot force): on the project humanoid standing still they were not what the
//   feet got (18.8 N forward planned where the CoP said about 5 N backward), and that estimate
//   drove a growing 0.5 Hz sway (CoM error 31.7 mm, trunk roll 9.6 deg, in 10 s);
// - Stability: with the CoP taken as is, the loop of (11) and this observer on a linear
//   inverted pendulum is s^3 + (G21 + w (1 - G22 h / g)) s^2 + (G22 + w G21) s + w G22 (w = 2 pi
//   f), stable for the default gains at any f up to several Hz (Routh); the observer's pole
//   is kept well below (11)'s.
//
// What it cannot see: the vertical CoM error (no static effect on the CoP) and a mass error
// (it moves the CoM only through where the masses are).

#include <cmath>

#include <Eigen/Core>

namespace poise::controller {

struct ComOffsetObserverConfig {
  /// Cut-off of the estimate [Hz]; 0: off (the model's CoM as is), the default: 0.5 helps every
  /// random study of a robot that is not its model but costs the accelerating platforms and the
  /// step in place (controller/momentum/README.md "The model's CoM error").
  double bandwidth_hz = 0.0;
  double limit = 0.03;        ///< largest horizontal error believed [m]
  /// It learns only while the CoM moves slower than this relative to its supports [m/s].
  double speed_gate = 0.05;
};

/// Allocation-free; one update per control tick.
class ComOffsetObserver {
 public:
  /// One sample. `cop_W`: force-weighted CoP of the supports; `normal_force`: their total [N];
  /// `weight`: the model's m |g|; `com_W`, `vcom_rel_W`: the model's CoM and its velocity
  /// relative to the supports (world axes). Learns only with half the weight or more on the
  /// feet and a quasi-static CoM; otherwise the estimate is held.
  void update(const ComOffsetObserverConfig& c, double dt, const Eigen::Vector3d& cop_W,
              double normal_force, double weight, const Eigen::Vector3d& com_W,
              const Eigen::Vector3d& vcom_rel_W) noexcept {
    learning_ = false;
    if (!(c.bandwidth_hz > 0.0) || !(normal_force > 0.5 * weight) || !cop_W.allFinite() ||
        !com_W.allFinite())
      return;
    if (!(vcom_rel_W.head<2>().norm() < c.speed_gate)) return;
    const double a = dt / (dt + 1.0 / (2.0 * M_PI * c.bandwidth_hz));
    delta_ += a * (cop_W.head<2>() - com_W.head<2>() - delta_);
    const double r = delta_.norm();
    if (r > c.limit) delta_ *= c.limit / r;
    learning_ = true;
  }

  /// The estimated horizontal CoM error, robot minus model, world axes [m] (z is 0).
  Eigen::Vector3d offset() const noexcept { return {delta_.x(), delta_.y(), 0.0}; }
  /// Whether the last update learnt (the gates were open).
  bool learning() const noexcept { return learning_; }
  void reset() noexcept {
    delta_.setZero();
    learning_ = false;
  }

 private:
  Eigen::Vector2d delta_ = Eigen::Vector2d::Zero();
  bool learning_ = false;
};

}  // namespace poise::controller
