#pragma once
// The momentum-based balance controller of Lee & Goswami (paper Sec. 3.2, 3.5-3.7, 4.2) as a
// library: no DDS, no threads, no clocks, no files after configuration.
//
// One tick is split in two phases so that a node can send the contact problem to a separate
// contact-optimiser process and wait for the answer:
//
//   prepare(state k, reference)  -> contact problem k       (phase A: eqs (10)-(11), supports,
//                                                             foot motion (36), Sec. 4.2 rule)
//   finish(contact solution k)   -> joint command k         (phase B: eq (33), inverse dynamics,
//                                                             theta*, theta_dot*, gains (34)-(35))
//   finish_fallback()            -> joint command k         (phase B without a usable solution:
//                                                             previous solution or gravity
//                                                             distribution; counted)
//
// In one process, tick() does A, calls the optimiser, then B.
// Every per-tick call is noexcept and allocation-free (tests prove it with
// EIGEN_RUNTIME_NO_MALLOC). Joint vectors are in the MODEL joint order; the node remaps.

#include <Eigen/Core>
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <array>
#include <vector>

#include "poise/contact/contact_problem.hpp"
#include "poise/controller/acceleration_solver.hpp"
#include "poise/controller/balance_reference.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/controller/joint_command.hpp"
#include "poise/controller/robot_state.hpp"
#include "poise/controller/support_polygon.hpp"
#include "poise/controller/tick_diagnostics.hpp"
#include "poise/model/data.hpp"
#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"

namespace poise::controller {

class BalanceController {
 public:
  /// Copies the model and robot configuration, validates `config`, preallocates everything.
  /// Throws ConfigError (bad config, model and robot config that do not match).
  BalanceController(const model::Model& model, const model::RobotConfig& robot,
                    const ControllerConfig& config);

  const model::Model& model() const { return model_; }
  const model::RobotConfig& robot() const { return robot_; }
  const ControllerConfig& config() const { return config_; }
  int num_joints() const { return model_.njoints; }

  /// Preallocated inputs/outputs of the right sizes (configuration time: allocate).
  RobotState make_state() const;
  BalanceReference make_reference() const;  ///< stand: automatic feet and CoM, nominal arms
  JointCommand make_command() const;

  /// Phase A. Validates the state sizes and finiteness (a bad state makes finish() command
  /// damping). Writes the contact problem of this tick.
  void prepare(const RobotState& state, const BalanceReference& reference,
               contact::ContactProblem& problem) noexcept;

  /// Phase B with the optimiser's solution of the problem written by the last prepare().
  /// `command` must come from make_command() (a wrongly sized command is left untouched).
  /// A solution with status kInvalidInput or kSolverFailure, or with non-finite numbers, is not
  /// used: the fallback is taken instead (counted as a late solution).
  void finish(const contact::ContactSolution& solution, JointCommand& command) noexcept;

  /// Phase B when the solution of this tick is late: reuses the previous solution (same supports,
  /// at most FallbackConfig::max_reuse_ticks in a row), else the gravity distribution. Counted.
  void finish_fallback(JointCommand& command) noexcept;

  /// One whole tick in one process: prepare, `solve(problem, solution)` (returns false when it
  /// has no usable answer), finish or finish_fallback.
  template <class Solve>
  void tick(const RobotState& state, const BalanceReference& reference, Solve&& solve,
            JointCommand& command) noexcept {
    prepare(state, reference, problem_);
    if (solve(static_cast<const contact::ContactProblem&>(problem_), solution_))
      finish(solution_, command);
    else
      finish_fallback(command);
  }

  /// Forgets the integrated references theta*, theta_dot* and the held foot poses (they restart
  /// from the next measured state). Counters are kept.
  void reset() noexcept;

  const TickDiagnostics& diagnostics() const { return diag_; }
  /// This tick's internal parts of the legs' position and velocity reference errors
  /// (FeedbackConfig::internal_force_leak_hz; taken before the leak; zero when the leak is off,
  /// not both feet bear load, or the split was not solvable). For tests.
  const Eigen::VectorXd& internal_position_error() const { return internal_q_; }
  const Eigen::VectorXd& internal_velocity_error() const { return internal_qd_; }
  /// The contact problem of the last prepare() (also what tick() sent to the optimiser).
  const contact::ContactProblem& problem() const { return problem_; }
  /// Joint accelerations qdd (dim nv) of the last eq (33) solve.
  const Eigen::VectorXd& generalized_acceleration() const { return qdd_; }
  /// Generalized velocity v (dim nv) and configuration q (dim nq) of the last prepare().
  const Eigen::VectorXd& generalized_velocity() const { return v_; }
  const Eigen::VectorXd& configuration() const { return q_; }
  /// Joint torques of the last inverse dynamics, all nv rows (base rows = residual).
  const Eigen::VectorXd& inverse_dynamics_torque() const { return tau_; }
  /// Foot Jacobians (6 x nv, LOCAL_WORLD_ALIGNED) and J_dot qd of the last prepare().
  const Eigen::MatrixXd& foot_jacobians() const { return C_; }
  const Eigen::VectorXd& foot_bias_acceleration() const { return jdot_v_; }
  /// Centroidal momentum matrix A (6 x nv) and A_dot qd of the last prepare().
  const model::Matrix6X& centroidal_matrix() const { return data_.Ag; }
  const model::Vector6& centroidal_bias() const { return data_.dAg_v; }
  /// Weights w, targets t and joint-acceleration bounds of the last eq (33) solve.
  const Eigen::VectorXd& qp_weights() const { return w_; }
  const Eigen::VectorXd& qp_targets() const { return t_; }
  const Eigen::VectorXd& qdd_lower() const { return lo_; }
  const Eigen::VectorXd& qdd_upper() const { return hi_; }
  const AccelerationSolver& acceleration_solver() const { return solver_; }

 private:
  // ---- construction (configuration time) ------------------------------------------------------
  void check_robot_matches_model() const;
  void init_joint_tables();
  void find_effort_limited_chains();
  void init_upper_body();
  void find_base_up();
  void find_leg_joints();
  void init_reference_leaks();
  double nominal_com_height();
  void allocate_workspace();
  void init_contact_problem();

  // ---- phase A, prepare() -----------------------------------------------------------------------
  /// The support feet of a tick: their number and the sums of their stand points, linear
  /// velocities and measured linear accelerations.
  struct SupportSums {
    int count = 0;
    Eigen::Vector3d stand_point = Eigen::Vector3d::Zero();
    Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
    Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();
  };
  bool inputs_usable(const RobotState& state, const BalanceReference& reference) const noexcept;
  void problem_without_support(contact::ContactProblem& problem) const noexcept;
  Eigen::Matrix3d set_model_state(const RobotState& state) noexcept;
  SupportSums plan_feet(const RobotState& state, const BalanceReference& reference,
                        double weight) noexcept;
  void foot_kinematics(int i) noexcept;
  Eigen::Vector3d measured_foot_acceleration(int i) noexcept;
  bool foot_is_support(int i, const FootMeasurement& meas, FootMode mode, double weight) noexcept;
  bool apply_resting_rule(int i, const FootMeasurement& meas, bool support, double weight,
                          bool& loaded) noexcept;
  void foot_motion_row_eq_36(int i, const FootReference& ref, bool support, bool resting,
                             bool loaded) noexcept;
  void contact_problem_foot(int i, bool support, double normal_force) noexcept;
  void filter_support_acceleration(const SupportSums& supports) noexcept;
  void desired_com(const BalanceReference& reference, const SupportSums& supports) noexcept;
  void desired_momentum_rate_eqs_10_11(const BalanceReference& reference,
                                       const Eigen::Matrix3d& R_WB, const Eigen::Vector3d& com,
                                       double mass) noexcept;
  void blend_ankle_first(const Eigen::Vector3d& com, double mass, int num_support) noexcept;
  void upper_body_objective(const BalanceReference& reference) noexcept;

  // ---- phase B, finish() ------------------------------------------------------------------------
  void finish_with(const contact::ContactSolution& solution, ContactSource source,
                   JointCommand& command) noexcept;
  void record_applied_wrenches(const contact::ContactSolution& solution,
                               ContactSource source) noexcept;
  void joint_accelerations_eq_33() noexcept;
  void posture_objective() noexcept;
  void inverse_dynamics_torques(const contact::ContactSolution& solution,
                                JointCommand& command) noexcept;
  void joint_references_eqs_34_35(const contact::ContactSolution& solution) noexcept;
  void restart_references() noexcept;
  void internal_reference_errors() noexcept;
  int integrate_references() noexcept;
  void follow_touched_down_legs(const contact::ContactSolution& solution) noexcept;
  void command_damping(JointCommand& command) noexcept;
  bool command_sized(const JointCommand& command) const noexcept;

  model::Model model_;
  model::RobotConfig robot_;
  ControllerConfig config_;
  model::Data data_;
  AccelerationSolver solver_;

  // ---- fixed per robot
  // ---------------------------------------------------------------------------
  Eigen::VectorXd q_min_, q_max_, effort_;  // dim n
  Eigen::VectorXd kp_, kd_;                 // dim n, robot gains * gain_scale
  Eigen::VectorXd is_upper_;                // dim n, 1 for upper-body joints
  Eigen::VectorXd q_nominal_;               // dim n
  double com_height_ = 0.0;
  SupportPolygon polygon_;  ///< MomentumGains::ankle_first_blend, rebuilt every tick

  // ---- per tick
  // ----------------------------------------------------------------------------------
  bool state_ok_ = false;
  Eigen::VectorXd q_, v_;        // nq, nv
  Eigen::VectorXd qd_joint_;     // n (measured)
  Eigen::VectorXd qdd_;          // nv
  Eigen::VectorXd tau_;          // nv
  Eigen::MatrixXd C_;            // 12 x nv stacked foot Jacobians [right; left]
  Eigen::VectorXd jdot_v_;       // 12
  Eigen::VectorXd d_;            // 12: a_d - J_dot qd
  Eigen::VectorXd w_, t_;        // nv
  Eigen::VectorXd lo_, hi_;      // n
  Eigen::VectorXd qdd_u_ref_;    // n: reference upper-body accelerations of this tick
  Eigen::VectorXd q_u_target_;   // n: upper-body posture target of this tick
  Eigen::VectorXd qd_u_target_;  // n: its velocity
  model::Matrix6X J_foot_;       // 6 x nv scratch
  std::array<model::SE3, 2> X_WF_;
  std::array<model::Motion, 2> V_WF_;

  // ---- across ticks
  // ------------------------------------------------------------------------------
  bool have_references_ = false;
  Eigen::VectorXd q_ref_, qd_ref_;  // n: theta*, theta_dot*
  std::array<bool, 2> have_hold_{false, false};
  /// Per foot: how long a planned support has been measured off the ground [s]
  /// (ControllerConfig::planned_support_release).
  std::array<double, 2> planned_off_time_{0.0, 0.0};
  std::array<model::SE3, 2> X_WF_hold_;  // desired pose of each foot when not resting
  // Rested and not back from the air since (ControllerConfig::resting_touchdown_force_fraction);
  // true at start: a robot started standing rests on the low threshold.
  std::array<bool, 2> rested_on_ground_{true, true};
  std::array<double, 2> flag_off_time_{0.0, 0.0};  // contact flag off for this long [s]
  std::array<bool, 2> placed_{false, false};  // the foot has rested or followed a target
  bool both_feet_loaded_ = false;  // this tick: both supports carry support_force_fraction
  std::array<bool, 2> touch_down_{false, false};  // became a support this tick
  // FeedbackConfig::touchdown_follow_fraction: touched down and not yet planned a load.
  std::array<bool, 2> landed_unloaded_{false, false};
  double touchdown_follow_keep_ = 1.0;  // per-tick factor of that following
  bool have_hold_seen_ = false;                   // a tick has been prepared (supports known)
  std::array<std::vector<int>, 2> leg_joints_;    // joints between the base and each foot
  Eigen::VectorXd leg_keep_;  // dim n: exp(-2 pi support_leg_leak_hz dt) on the legs, else 1
  // FeedbackConfig::internal_force_leak_hz: 1 - exp(-2 pi f dt) (0 = off), and its workspace
  double internal_drop_ = 0.0;
  Eigen::VectorXd inv_kp_, inv_kd_;        // dim n: 1/gain where the gain is > 0, else 0
  Eigen::VectorXd internal_q_, internal_qd_;  // dim n: this tick's internal parts of the errors
  Eigen::VectorXd error_scratch_;          // dim n
  // The internal torques of this tick are the range of internal_basis_ (n x 6): J_q^T lambda
  // over the lambda with J_b^T lambda = 0 (internal_split_basis()).
  Eigen::Matrix<double, Eigen::Dynamic, 6> internal_basis_, weighted_basis_;
  Eigen::Matrix<double, 6, 6> base_map_;  // J_b of foot 0, then its inverse times J_b of foot 1
  Eigen::PartialPivLU<Eigen::Matrix<double, 6, 6>> base_lu_;
  Eigen::LDLT<Eigen::Matrix<double, 6, 6>> internal_ldlt_;
  Eigen::Matrix<double, 6, 1> internal_rhs_;
  /// internal_basis_ from this tick's foot Jacobians C_; false if not finite.
  bool internal_split_basis();
  /// FallConfig: sets diag_.fallen (latched) when the base tilts or the CoM sinks past the limits.
  void detect_fall(const Eigen::Matrix3d& R_WB) noexcept;
  /// The part of the joint error e (dim n, joints) whose torque diag(1/w) e is a pure internal
  /// force of the two feet, for the metric w (inv_kp_ or inv_kd_); false if not solvable.
  bool internal_part(const Eigen::VectorXd& e, const Eigen::VectorXd& w, Eigen::VectorXd& out);
  bool have_foot_velocity_ = false;
  void observe_com_offset(const RobotState& state, int num_support,
                          const Eigen::Vector3d& foot_vel_sum) noexcept;
  ComOffsetObserver com_offset_;  // ControllerConfig::com_offset
  // (10)-(11) feedback through MomentumGains::feedback_filter_hz: the filtered CoM velocity error
  // (target - measured) and centroidal angular momentum (world axes), valid once have_feedback_.
  Eigen::Vector3d vcom_error_filtered_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d k_filtered_ = Eigen::Vector3d::Zero();
  /// MomentumGains::upright_pitch_rate: the base's "up" in its own frame (both soles flat in the
  /// nominal posture).
  Eigen::Vector3d base_up_B_ = Eigen::Vector3d::UnitZ();
  bool have_feedback_ = false;
  std::array<model::Motion, 2> V_WF_previous_;  // foot velocity of the previous tick
  std::array<model::Motion, 2> A_WF_filtered_;  // low-pass filtered measured foot acceleration
  // MomentumGains::support_acceleration_hz: three first-order stages; the last is a_s, and the
  // difference of the last two gives its rate without differencing noise.
  std::array<Eigen::Vector3d, 3> support_acc_stage_{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                                    Eigen::Vector3d::Zero()};
  bool have_previous_solution_ = false;
  std::array<bool, 2> previous_support_{false, false};
  int reuse_count_ = 0;
  contact::ContactProblem problem_;
  contact::ContactSolution solution_;           // scratch for tick() and fallbacks
  contact::ContactSolution previous_solution_;  // last solution used
  TickDiagnostics diag_;
  // FeedbackConfig::velocity_leak_hz: exp(-2 pi f dt), the velocity error kept per tick (1 = off).
  double velocity_keep_ = 1.0;
  // RobotConfig::effort_limited_sole: each foot's chain of joints to the floating base (model
  // joint indices, those with a finite effort), and the sole rectangle it leaves this tick.
  std::array<std::vector<int>, 2> foot_chain_;
  /// Shrinks `sole` (foot i's rectangle in F, on the sole plane h below F) to where a CoP keeps
  /// every joint of foot_chain_[i] within its effort with the normal force fz on the foot and
  /// gravity on the leg below each joint (statics). A load that is not finite or at most 0.1 %
  /// of the weight (a foot in the air, a failed F/T reading) leaves the sole whole. No
  /// allocation.
  void limit_sole_by_effort(int i, double fz, double h, contact::SoleRectangle& sole) const noexcept;
};

}  // namespace poise::controller
