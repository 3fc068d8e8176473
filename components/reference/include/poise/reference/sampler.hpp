#pragma once
// A balance-reference trajectory (trajectory.hpp) sampled into the controller library's
// BalanceReference, without DDS: what the in-process loop plays for a scenario's `reference:`
// and what tests drive InProcessLoop::reference() with. The same rules as the DDS player
// (src/play.cpp, deploy/scenarios/references/README.md): CoM moves relative to the CoM measured
// when the first move is due, joint swings about the nominal posture, steps as FOOT_SWING with
// the eq. (36) target of the stood pose raised by the lift profile, the other foot FOOT_SUPPORT.

#include <array>
#include <vector>

#include "poise/controller/balance_reference.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/model/spatial.hpp"
#include "poise/reference/trajectory.hpp"

namespace poise::reference {

class Sampler {
 public:
  /// Resolves the swings' joints in the model. Throws std::runtime_error naming the joint (not
  /// in the model, not an upper-body joint). Allocates: configuration time.
  Sampler(Trajectory trajectory, const model::Model& model, const model::RobotConfig& robot);

  /// Writes the reference of time t (robot time) into `ref` (sized by the controller's
  /// make_reference()). `com_W` and `X_WF` (indexed by model::Side) are measured now: the first
  /// CoM move takes its origin from `com_W`, a move `over` a foot its end from `X_WF` when it
  /// begins, a step its stood pose from `X_WF` when it begins.
  /// Before the trajectory's first change `ref` is left untouched. Allocation-free.
  void sample(double t, const Eigen::Vector3d& com_W, const std::array<model::SE3, 2>& X_WF,
              controller::BalanceReference& ref) noexcept;

  const Trajectory& trajectory() const { return traj_; }

 private:
  Trajectory traj_;
  std::vector<int> swing_joint_;  // model joint index of each swing
  Eigen::VectorXd q_nominal_;     // n
  bool origin_set_ = false;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  int step_ = -1;  // index of the step whose stood pose is held
  model::SE3 X_stood_;
  std::array<Eigen::Vector3d, 2> sole_F_;  // stand points in the foot frames (ComOver)
};

/// The model joint index of each of the trajectory's swings. Throws std::runtime_error naming
/// the joint when it is not in the model or not an upper-body joint (robot.yaml joint_groups).
/// Shared by the sampler and the player (player.hpp).
std::vector<int> swing_joint_indices(const Trajectory& trajectory, const model::Model& model,
                                     const model::RobotConfig& robot);

/// Each foot's stand point in its foot frame (model::Side order; FootConfig::stand_point_F, the
/// sole centre unless robot.yaml says): where a CoM move `over` a foot ends (ComOver). Shared by
/// the sampler and the player.
std::array<Eigen::Vector3d, 2> stand_points_F(const model::RobotConfig& robot);

/// Foot reference of a step at time t from the stood pose: FOOT_SWING, target raised by the lift
/// profile (vertical velocity as the target velocity). Shared by the DDS player.
void step_target(const FootStep& s, double t, const model::SE3& X_stood, model::SE3& X_target,
                 model::Motion& V_target) noexcept;

}  // namespace poise::reference
