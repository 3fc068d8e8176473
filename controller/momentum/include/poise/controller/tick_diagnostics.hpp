#pragma once
// What one controller tick computed, for the diagnostics topic, tests and plots (paper Fig. 8).

#include <Eigen/Core>
#include <array>
#include <string>
#include <cstdint>

#include "poise/contact/solver_status.hpp"
#include "poise/model/spatial.hpp"

namespace poise::controller {

/// How the contact wrenches of a tick were obtained.
enum class ContactSource : std::uint8_t {
  kSolution = 0,             ///< the optimiser's solution of this tick
  kReusedSolution = 1,       ///< fallback: the previous solution (same supports), re-evaluated
  kGravityDistribution = 2,  ///< fallback: static weight distribution over the supports
};

const char* to_string(ContactSource s);

/// Which FallConfig rule declared the fall.
enum class FallReason : std::uint8_t { kNone = 0, kTilt = 1, kComHeight = 2 };

const char* to_string(FallReason r);

struct TickDiagnostics {
  std::int64_t tick = -1;
  std::array<bool, 2> support{false, false};  ///< feet used as supports this tick
  std::array<bool, 2> resting{false, false};  ///< measured CoP inside the safe region (Sec. 4.2)
  Eigen::Vector3d com_W = Eigen::Vector3d::Zero();           ///< r_G (model)
  Eigen::Vector3d com_velocity_W = Eigen::Vector3d::Zero();  ///< rdot_G (model)
  Eigen::Vector3d com_target_W = Eigen::Vector3d::Zero();    ///< r_G,d
  /// ControllerConfig::com_offset: the robot's CoM minus the model's, as observed (horizontal;
  /// zero when off); (10)-(11) use com_W + this.
  Eigen::Vector3d com_offset_W = Eigen::Vector3d::Zero();
  bool com_offset_learning = false;  ///< the observer learnt this tick (its gates were open)
  Eigen::Vector3d com_velocity_target_W = Eigen::Vector3d::Zero();
  /// The supports' filtered acceleration a_s fed forward into (11)
  /// (MomentumGains::support_acceleration_hz; zero when off or with a reference's CoM target)
  /// [m/s^2].
  Eigen::Vector3d support_acceleration_W = Eigen::Vector3d::Zero();
  model::Vector6 h_W = model::Vector6::Zero();              ///< centroidal momentum [k; l] (model)
  model::Vector6 hdot_desired = model::Vector6::Zero();     ///< [k_dot_d; l_dot_d], eqs (10)-(11)
  model::Vector6 hdot_admissible = model::Vector6::Zero();  ///< [k_dot_a; l_dot_a] of the wrenches
  model::Vector6 hdot_achieved =
      model::Vector6::Zero();  ///< A qdd + A_dot qd of the eq (33) output
  /// MomentumGains::ankle_first_blend: 0 = the horizontal demand of (11) replaced by the ankle
  /// strategy's, 1 = (11) as it is (also when the rule is off), between: blended.
  double ankle_first_beta = 1.0;
  std::array<model::Motion, 2> foot_acceleration_desired{model::Motion::Zero(),
                                                         model::Motion::Zero()};  ///< a_d (36)
  std::array<model::Vector6, 2> foot_wrench_W{model::Vector6::Zero(),
                                              model::Vector6::Zero()};  ///< [f; tau_ankle] used
  ContactSource contact_source = ContactSource::kSolution;
  contact::SolverStatus qp_status = contact::SolverStatus::kOptimal;  ///< eq (33) solve
  int qp_iterations = 0;
  int active_bounds = 0;              ///< joint-acceleration bounds active in eq (33)
  int dependent_rows = 0;  ///< eq (33) equality rows dependent on the others (dropped; see solver)
  bool bounds_dropped = false;        ///< eq (33) infeasible with bounds: solved without them
  double momentum_residual = 0.0;     ///< |A qdd + A_dot qd - hdot_a|
  double constraint_residual = 0.0;   ///< |J qdd + J_dot qd - a_d| (max over rows)
  double base_wrench_residual = 0.0;  ///< |tau[0:6]| of the inverse dynamics (0 when consistent)
  int torque_saturations = 0;         ///< joints whose tau_ff was clamped to the effort limit
  int reference_clamps = 0;           ///< joints whose theta* / theta_dot* was clamped

  // ---- counters since configure() ---------------------------------------------------------------
  std::uint64_t ticks = 0;
  std::uint64_t late_solutions = 0;  ///< ticks finished with a fallback
  std::uint64_t qp_failures = 0;     ///< eq (33) not optimal (bounds dropped or last iterate)

  // ---- a fallen robot (FallConfig; latched until reset()) ------------------------------------
  bool fallen = false;             ///< damping is commanded: the robot has fallen
  FallReason fall_reason = FallReason::kNone;
  std::int64_t fall_tick = -1;     ///< the state tick that met the rule
  double fall_tilt_deg = 0.0;      ///< the base's tilt from its start orientation then [deg]
  double fall_com_height_fraction = 1.0;  ///< the CoM height over its standing height then
};

/// What declared the fall, with the figures and the limits ("base tilt 61.2 deg > 60 deg");
/// "" when not fallen. Allocates: for logs and results, not the control loop.
std::string describe_fall(const TickDiagnostics& diag, double tilt_limit_deg,
                          double com_height_fraction_limit);

}  // namespace poise::controller
