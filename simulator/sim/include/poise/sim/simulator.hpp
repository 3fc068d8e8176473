#pragma once
// Bullet btMultiBody simulation of a floating-base robot built from a URDF.
//
// Contract of one tick (the node that drives it is a thin shell around this class):
//   in : JointCommand for tick k (mode torque / PD / damping; PD evaluated here at 1 kHz)
//   out: SensorFrame of tick k+1 (only what a real robot measures) and GroundTruth of tick k+1
// Lockstep: call step() once per received command. Real time: call step() every 1 ms with the
// newest command, through the robot-side safety layer (components/safety), which decides when
// to hold or damp instead.
//
// Physics: double-precision Bullet (BT_USE_DOUBLE_PRECISION, the -float64 libraries) behind a
// pimpl; floating base; revolute / continuous / prismatic joints under torque control; URDF
// limits (joint-limit constraints), damping (viscous, explicit) and friction (velocity motor with
// the friction as its force bound); URDF collision primitives; fixed joints are merged into their
// parent body. See simulator/README.md for contact settings and how foot F/T is measured.

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "poise/sim/sim_config.hpp"
#include "poise/sim/types.hpp"

namespace poise::sim {

/// Trunk pitch and roll [rad] of a base with orientation R_WB whose forward direction in its
/// own frame is forward_B (unit, horizontal): pitch = asin(-f.z) with f = R_WB forward_B, positive
/// when the robot leans forward; roll = atan2(l.z, z_B.z) with l = R_WB (e_z x forward_B) its left,
/// positive when its left side rises. For forward_B = +x these are the ZYX pitch and roll. With
/// the base's z pointing down (a fall) they are the elevations of the forward and left axes,
/// the larger going on past 90 deg to 180: a forward fall is pitch, never 180 deg of roll.
Eigen::Vector2d trunk_pitch_roll(const Eigen::Matrix3d& R_WB, const Eigen::Vector3d& forward_B);

class Simulator {
 public:
  /// Builds the world. Throws std::runtime_error naming the problem (file, link, joint, key).
  explicit Simulator(const SimulatorConfig& config);
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  /// Joint names in the simulator's joint order: depth-first over the URDF tree from the root,
  /// children visited in increasing joint-name order; fixed joints excluded.
  const std::vector<std::string>& joint_names() const;
  int num_joints() const;
  /// Simulated bodies (a body = a URDF link plus everything fixed to it), named after that link.
  const std::vector<std::string>& body_names() const;
  const std::vector<std::string>& foot_names() const;
  double total_mass() const;
  double dt() const;
  std::int64_t tick() const;
  double time() const;
  /// Effort limit per joint (infinity when the URDF gives none), joint order.
  const Eigen::VectorXd& effort_limits() const;
  /// What the simulator changed of the URDF to step it stably, one readable line each (joint
  /// damping and friction too strong for the explicit step of a light link); empty for most
  /// robots. The constructor prints each on stderr ("simulator 'URDF': note: ..."), so every
  /// tool that builds a simulator shows them; the reality section's joint friction
  /// (reality.hpp) is counted in them too.
  const std::vector<std::string>& notes() const;
  /// How the simulated robot differs from its URDF (SimulatorConfig::reality, drawn at
  /// construction); enabled false without a reality configuration.
  const RealityDraw& reality() const;

  /// Preallocated outputs / command of the right sizes (configuration time: allocates).
  SensorFrame make_sensor_frame() const;
  GroundTruth make_ground_truth() const;
  JointCommand make_command() const;

  /// Advances one dt with `command`; writes sensors and truth of the new tick.
  /// Real-time safe: no allocation, no exception. A command of the wrong size or with a
  /// non-finite value is rejected: the joints are damped for this step (kRejectedCommand).
  StepStatus step(const JointCommand& command, SensorFrame& sensors, GroundTruth& truth);

  /// Sensors and truth of the current tick without stepping (e.g. tick 0 after construction).
  void read(SensorFrame& sensors, GroundTruth& truth);

  /// Schedules a push (live disturbance). Real-time safe up to max_live_pushes pending pushes;
  /// returns false (and ignores it) when the link is unknown or the queue is full.
  bool add_push(const Push& push);

  /// Torque applied in damping mode: tau = -damping_kd * qd.
  double damping_kd() const;

  /// Contact-solver iterations used by the last step (<= solver.iterations; fewer when the
  /// residual fell under solver.residual_threshold). For benchmarks and diagnostics.
  int solver_iterations_used() const;

  /// Constraint rows the contact solver built for the last step. For benchmarks and diagnostics.
  SolverRows solver_rows() const;

  /// Wall time of the steps so far, split (StepTimes). Four clock reads a step.
  const StepTimes& step_times() const;
  void reset_step_times();

  /// Joint positions / base pose setters for tests (configuration time).
  void set_state(const Eigen::Isometry3d& X_WB, const Eigen::VectorXd& q,
                 const Eigen::Vector3d& v_WB = Eigen::Vector3d::Zero(),
                 const Eigen::Vector3d& omega_WB = Eigen::Vector3d::Zero(),
                 const Eigen::VectorXd& qd = Eigen::VectorXd());

  /// Pose of a URDF link frame in W (any link, including ones merged by fixed joints).
  /// Throws std::out_of_range for an unknown name (not for loop use).
  Eigen::Isometry3d frame_pose(const std::string& urdf_link) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

/// Index map from one joint order to another, by name.
/// map[i] = index in `to` of joint from[i]; -1 when absent. Throws on duplicate names.
std::vector<int> joint_index_map(std::span<const std::string> from,
                                 std::span<const std::string> to);

/// Copies a vector from one order to the other: out[map[i]] = in[i] (entries with -1 skipped).
/// No allocation; `out` must already have the right size.
void remap_joint_vector(const std::vector<int>& map, const Eigen::VectorXd& in,
                        Eigen::VectorXd& out);

}  // namespace poise::sim
