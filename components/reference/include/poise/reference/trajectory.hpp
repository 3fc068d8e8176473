#pragma once
// A balance-reference trajectory (file format: deploy/scenarios/references/README.md): CoM moves
// and upper-body joint swings as functions of robot time, played over DDS by
// `poise reference play` (components/reference/src/play.cpp). Pure functions, no DDS.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace poise::reference {

/// Where a CoM move ends: `shift` as given, or (horizontally) over a foot's stand point (its sole
/// centre unless robot.yaml says, model::FootConfig::stand_point) or the mid-point of both, taken
/// when the move begins (resolve_com_moves): a file that says "over the left foot" fits any
/// robot's stance.
enum class ComOver { kShift, kRight, kLeft, kBetween };

/// The CoM target moves by `shift` [m] along a minimum-jerk profile in [start, start + duration].
struct ComMove {
  double start = 0.0;
  double duration = 1.0;
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  ComOver over = ComOver::kShift;
  bool resolved = true;  ///< `shift` is known (false for an `over` move until it begins)
};

/// An upper-body joint swings about its nominal angle:
/// q = q_nominal + e(t) * amplitude * sin(2 pi frequency (t - start) + phase), the envelope e(t)
/// rising from 0 to 1 over `fade` seconds after `start` and falling back over the last `fade`
/// seconds before start + duration (quintic smooth steps, so q, qd, qdd are continuous).
struct JointSwing {
  std::string joint;
  double start = 0.0;
  double duration = 1.0;
  double amplitude = 0.0;  ///< [rad]
  double frequency = 1.0;  ///< [Hz]
  double phase = 0.0;      ///< [rad]
  double fade = 0.5;       ///< [s], <= duration / 2
};

/// A step in place: the foot leaves support at `start`, its sole rises `lift` [m] above where it
/// stood along a quintic smooth step over the first half of `duration`, comes back down along the
/// mirrored one over the second half, and is a support again from start + duration. The player
/// sends it as FOOT_SWING with the target pose (the stood pose raised by the profile) and
/// velocity of eq. (36); the other foot is FOOT_SUPPORT meanwhile. The CoM is not moved by the
/// step: put it over the stance foot with `com:` moves before `start` (the file says so).
struct FootStep {
  std::string foot;  ///< "right" or "left"
  int side = 0;      ///< model::Side: 0 right, 1 left
  double start = 0.0;
  double duration = 0.6;
  double lift = 0.03;  ///< [m], in (0, 0.10]
};

struct Trajectory {
  std::string name;
  std::string description;
  int lead_ticks = 200;      ///< how far ahead of the state the player sends each reference
  std::vector<ComMove> com;  ///< in time order, not overlapping
  std::vector<JointSwing> joints;
  std::vector<FootStep> feet;  ///< in time order, not overlapping (one foot in the air at a time)
  /// First and last time at which the trajectory changes anything [s].
  double begin() const;
  double end() const;
};

/// Loads and checks a trajectory file. Throws std::runtime_error naming the file and the key
/// (unknown keys, missing or non-positive durations, overlapping CoM moves, fades too long).
Trajectory load_trajectory(const std::string& path);

/// Gives each `over` move that has begun by time t (t >= start) and is not yet resolved its
/// shift: the horizontal vector from the CoM target before it (origin + the earlier moves'
/// shifts) to the stand point it names, or the mid-point of both (`*_sole_W`, indexed by
/// model::Side: 0 right, 1 left, in W, measured now); no vertical change. Allocation-free.
void resolve_com_moves(Trajectory& traj, double t, const Eigen::Vector3d& origin,
                       const Eigen::Vector3d& right_sole_W,
                       const Eigen::Vector3d& left_sole_W) noexcept;

/// CoM target offset and velocity at time t, relative to the CoM at the first move's start
/// (moves add up; an unresolved `over` move counts as no move). False before the first move
/// (no CoM target yet).
bool com_offset(const Trajectory& traj, double t, Eigen::Vector3d& offset,
                Eigen::Vector3d& velocity) noexcept;

/// Offset of one swing from the nominal angle at time t, with its first and second derivatives
/// (all zero outside [start, start + duration]).
void swing_offset(const JointSwing& s, double t, double& q, double& qd, double& qdd) noexcept;

/// Height of a step's swing foot above where it stood at time t, with its first and second
/// derivatives. False outside [start, start + duration) (the foot is a support then).
bool step_lift(const FootStep& s, double t, double& z, double& zd, double& zdd) noexcept;

/// The step whose foot is in the air at time t, or nullptr.
const FootStep* active_step(const Trajectory& traj, double t) noexcept;

/// True once any joint swing has started (t >= its start): the reference then carries an
/// upper-body posture target.
bool has_joint_motion(const Trajectory& traj, double t) noexcept;

}  // namespace poise::reference
