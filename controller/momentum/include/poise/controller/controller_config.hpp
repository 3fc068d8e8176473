#pragma once
// Tuning of the momentum-based balance controller (paper Sec. 3.2, 3.5-3.7, 4.2).
//
// Defaults are the paper's Sec. 4.2 values mapped from its Y-up world to this project's Z-up world
// (swap the Y and Z entries: the VERTICAL gains are the paper's middle entries), plus the values
// this project chose where the paper gives none (documented field by field; measured on the
// project humanoid, see controller/momentum/README.md).
//
// The YAML keys, their units, paper equations and allowed ranges are declared once, in the table
// of controller_config_keys.hpp: it drives load_controller_config(), validate() and the reference
// controller/momentum/CONFIG.md. A new field needs its row there.

#include <Eigen/Core>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "poise/contact/contact_problem.hpp"
#include "poise/controller/com_offset_observer.hpp"

namespace poise::controller {

/// Thrown for every configuration-time error (bad file, bad key, out-of-range value).
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Eqs (10)-(11): k_dot_d = G11 (k_d - k);  l_dot_d / m = G21 (rdot_G,d - rdot_G) + G22 (r_G,d -
/// r_G). Diagonals in world axes (x forward, y left, z up).
struct MomentumGains {
  Eigen::Vector3d gamma11{5.0, 5.0, 5.0};     ///< angular momentum damping [1/s]
  /// CoM velocity and position gains, [1/s] and [1/s^2]. Not the paper's ({40, 20, 40} and {8, 3,
  /// 8} in its Y-up world, i.e. {40, 40, 20} and {8, 8, 3} here: config/paper.yaml): with the
  /// ankle strategy first (ankle_first_blend) a push leaves a larger CoM excursion, which the
  /// paper's over-damped pair (poles -0.2 and -39.8 /s) brought back too slowly for the pushes'
  /// 2.5 s recovery criterion; 20 and 15 put them at -0.78 and -19.2 /s horizontally
  /// (controller/momentum/README.md "Ankle strategy first").
  Eigen::Vector3d gamma21{20.0, 20.0, 20.0};
  Eigen::Vector3d gamma22{15.0, 15.0, 3.0};
  /// First-order low-pass [Hz] of what (10)-(11) feed back: the CoM velocity error (target -
  /// measured) and the centroidal angular momentum (0: none, the paper's equations as written).
  /// The base angular velocity on the wire is the gyro's, sample by sample; over the ~0.84 m from
  /// the soles to the CoM its white noise is ~2.6 mm/s of CoM velocity relative to the feet, which
  /// Gamma21 turned into ~5 N of desired linear-rate noise and the optimiser into normal-force
  /// shifts between the feet and CoPs at the sole edges (simulator/sim/SENSORS.md). Exact at the
  /// first tick after a reset. Off by default until measured everywhere: at 30 Hz the forward
  /// push's post-push ticks with a CoP at a sole edge fell from 24 % to 2 %, but the step in place
  /// then showed 10 contact-flag changes against 6 true ones (SENSORS.md).
  double feedback_filter_hz = 0.0;
  /// Accelerating supports (not in the paper: Sec. 4.2 gives the CoM target the supports'
  /// velocity, and nothing of their acceleration). > 0: a_s, the mean over the support feet of
  /// their measured linear acceleration (velocity differenced over the tick, clamped to 3 g, then
  /// three first-order low-pass stages at this cut-off [Hz]), is
  /// - fed forward into (11): l_dot_d += m a_s, the CoM target moving with the supports;
  /// - leant into: the CoM target moves (h / (g + a_s,z)) a_s horizontally (h: com_height), and
  ///   its velocity target by the rate of that, where an inverted pendulum riding the supports
  ///   keeps its CoP under the sole centres; without it the CoPs go to the sole edges while the
  ///   supports decelerate and the feet tip.
  /// Only with the Sec. 4.2 target (not a reference's CoM target). 0: off (the paper's (11)).
  /// Measured: controller/momentum/README.md "Accelerating supports".
  double support_acceleration_hz = 0.0;
  /// Ankle strategy first (not in the paper; support_polygon.hpp): > 0: when (11)'s horizontal
  /// demand has its inverted-pendulum CoP outside the support polygon (the supports' safe
  /// regions) while the capture point is inside it, the demand is replaced by the one that puts
  /// the CoP on the polygon's edge beyond the capture point, which stops the CoM without
  /// angular momentum; the paper's demand (and the hip strategy with it) returns linearly as the
  /// capture point comes within this distance [m] of the edge. 0: off (the paper's (11),
  /// config/paper.yaml). On by default since 2026-12-04 (with the gains above and
  /// FeedbackConfig::touchdown_follow_fraction).
  double ankle_first_blend = 0.1;
  /// Trunk upright (not in the paper: (10) damps the angular momentum to the reference's k_d
  /// and nothing brings the trunk back, so after a push the hip strategy leaves it pitched).
  /// > 0 [1/s]: k_d += I_G omega_u, omega_u = these rates x the rotation vector that takes the
  /// base's "up" (its direction when both soles lie flat in the nominal posture) to the world's
  /// up, split into pitch (about the horizontal axis across the robot's forward, robot.yaml
  /// forward_axis) and roll (about that forward); I_G the locked centroidal inertia; the trunk's
  /// yaw is left as the paper's. With (10)'s Gamma11 a tilt then follows theta'' + Gamma11
  /// theta' + Gamma11 r theta = 0. Angular momentum comes after the linear in the contact
  /// optimiser's priority, so the hip strategy still takes what the linear rate leaves.
  /// 0: off (the paper's (10), config/paper.yaml). Pitch 1 /s by default since 2026-12-05
  /// (poles -1.4 and -3.6 /s with Gamma11 5): without it the trunk stayed pitched 13-49 deg
  /// 1.5-3 s after pushes of 150-265 N; with it, 3-4 deg. Roll 0 by default: in double support a
  /// roll moment is a difference of the feet's normal forces, and bringing the roll back took
  /// the load off a foot the CoM was moving away from (the step in place: 2.5-5 N on it for the
  /// 0.65 s before its swing, below what the contact flags resolve) (controller/momentum/
  /// README.md "Trunk upright"). The tilt is the state's base orientation: an attitude estimate
  /// off by e leans the trunk by e (the estimator's attitude error, estimator/README.md); no
  /// state of its own (nothing to go stale or to reset).
  double upright_pitch_rate = 1.0;
  double upright_roll_rate = 0.0;
};

/// Weights of the contact problem, eqs (21) and (29) (copied into the problem sent out; the
/// optimiser uses them as weights of squared norms, scaling its least-squares rows by their square
/// roots, see poise/contact/contact_problem.hpp).
/// The paper's Sec. 4.2 gives eps_f = eps = 0.01; its eq. (24) applies eps_f as a ROW scale,
/// i.e. a weight of 0.01^2 = 1e-4, which is the default here. Used as a weight, 0.01 biases the
/// admissible vertical force by ~1 N on this 51 kg robot (measured), and with the paper's weak CoM
/// position gain (Gamma22_z = 3) that bias alone sags the CoM by ~7 mm.
struct ContactWeights {
  double w_k = 0.1;       ///< angular momentum weight in (21) (paper: 0.1)
  double eps_f = 1e-4;    ///< force regularisation in (21) (paper: 0.01 as a row scale)
  double eps_cop = 1e-4;  ///< CoP / normal torque regularisation in (29) (same reading)
  /// > 0: the Coulomb coefficient the contact optimiser assumes, instead of robot.yaml's
  /// contact.friction_mu (a scenario's `controller: {contact: {friction_mu: X}}`: a floor the
  /// robot is told is slippery). Not the simulated ground's (world.ground.friction) nor a
  /// reality draw's: what the controller believes, not what the floor does. 0: robot.yaml's.
  double friction_mu = 0.0;
  /// Linear momentum first strictly (lexicographic, the paper's stated priority) or eq. (21)'s
  /// weighted sum. Not on the wire: `poise run` passes it to poise-contact as --priority.
  contact::Priority priority = contact::Priority::kLexicographic;
  /// The feet's normal-torque bound (contact_problem.hpp TorsionLimit). Not on the wire either:
  /// `poise run` passes it to poise-contact as --torsion-limit. friction-coupled: the twist
  /// shares the friction the tangential force uses (why, and the measurement behind this
  /// default: controller/contact/README.md); independent: the paper's |tau_n| <= mu_t f_n.
  contact::TorsionLimit torsion_limit = contact::TorsionLimit::kFrictionCoupled;
};

/// Eq (36): a_d = kp log(T^-1 T_d) + kd (v_d - v) for each foot.
struct FootGains {
  double kp = 100.0;  ///< [1/s^2]
  double kd = 20.0;   ///< [1/s]
  /// Horizontal gains of a foot held where it last rested (no target) that is back from the air
  /// (its contact flag off for more than resting_touchdown_air_time since it last rested) and
  /// measures no load (below the resting threshold): a support a push has lifted. In the
  /// air it carries none of the contact problem's forces, so nothing but these gains keeps it
  /// over its spot while the body it hangs from rolls above it; with kp, kd the far foot of a
  /// 160-165 N sideways push (config/ankle_first.yaml) drifted 12-15 mm in the air and landed
  /// there (failed) while 170-215 N survived, and the defaults failed 190 and 210 N the same way
  /// (controller/momentum/README.md "A lifted foot held where it stood"). Height and tilt keep
  /// kp, kd (a swing's landing is unchanged), and so does a foot that touches or lost its flag
  /// for a few ticks only (stiffer, it was pulled against an accelerating platform). The paper
  /// gives no values for (36). >= 0; equal to kp, kd: every held foot as (36) with kp, kd.
  double unloaded_kp = 400.0;  ///< [1/s^2] (critically damped with unloaded_kd)
  double unloaded_kd = 40.0;   ///< [1/s]
  /// Sec. 4.2 moving supports: a resting foot follows its support, v_d = v and T_d = T, so eq
  /// (36) alone asks it zero acceleration while the support may accelerate (16 m/s^2 on the
  /// out-of-phase platforms). > 0: the foot's measured acceleration (its velocity differenced
  /// over one tick, low-pass filtered with this time constant [s]) is added to a_d of a resting
  /// foot as the support's acceleration. 0 (default): eq (36) as written. Measured
  /// (controller/momentum/README.md): 0.01 lets the robot ride out-of-phase supports of 0.1 m at
  /// 1 Hz that it falls from without, but makes the in-phase platforms fail on the estimator.
  double support_acceleration_tau = 0.0;
};

/// Eq (33) and its companions.
struct AccelerationConfig {
  /// Balance weight w_b in (33): w_b ||A qdd + Adot qd - hdot_a||^2 + (1 - w_b) ||qdd_u -
  /// qdd_u,d||^2.
  double w_b = 0.95;
  /// Weak posture prior added to (33) (not in the paper): w_posture ||qdd - qdd_posture||^2 over
  /// every DoF, with qdd_posture = posture_kp (q_nominal - q) - posture_kd qd for joints and
  /// -posture_kd v for the base. It makes the Hessian positive definite (the paper's (33) alone
  /// is singular when w_b -> 1 on the leg DoFs left free by the foot constraints) and slowly brings
  /// the posture back after a push, inside the null space of the momentum task.
  double posture_weight = 1e-3;
  double posture_kp = 20.0;  ///< [1/s^2]
  double posture_kd = 9.0;   ///< [1/s]
  /// Upper-body (arms, torso) desired accelerations qdd_u,d = reference qdd + PD to the reference
  /// posture (or the nominal posture): the arms are not balance joints (paper Sec. 4).
  double upper_body_kp = 100.0;  ///< [1/s^2]
  double upper_body_kd = 20.0;   ///< [1/s]
  /// Joint-acceleration bounds from position limits: qdd_u = 2 (q_max - q - qd T) / T^2 with the
  /// horizon T, then clamped to +-max_joint_acceleration.
  double limit_horizon = 0.1;             ///< T [s]
  double max_joint_acceleration = 500.0;  ///< [rad/s^2]
};

/// Joint-level references theta*, theta_dot* of eqs (34)-(35).
struct FeedbackConfig {
  double gain_scale = 1.0;           ///< multiplies the robot config's kp and kd
  double max_position_error = 0.05;  ///< |theta* - theta| is clamped to this [rad]
  double max_velocity_error = 0.5;   ///< |theta_dot* - theta_dot| is clamped to this [rad/s]
  /// [Hz] While both feet are supports carrying support_force_fraction of the weight each,
  /// the references of the legs' joints decay towards the measured joint state at this rate
  /// (theta* - theta and theta_dot* - theta_dot multiplied by exp(-2 pi f dt) each tick
  /// before qdd_a is integrated). Both feet on the ground close a kinematic loop through
  /// the floating base: references integrated open loop drift off it (any difference between
  /// the planned and the real motion of the base or the supports), and the joint PD then
  /// squeezes the legs against each other with internal forces the contact problem never
  /// planned (after a 175 N sideways push: 35 N / 23 N of it at each foot, and 70 N of
  /// normal force moved between the feet, for as long as the robot stands). 0 = the paper's pure
  /// integration (the default: 3 Hz removes that squeeze after a push but regresses the
  /// contact-change scenarios); the other joints always integrate. The out-of-phase platform
  /// scenarios set 300 (controller/momentum/README.md).
  double support_leg_leak_hz = 0.0;
  /// [Hz] While both feet bear load (as above), only the part of the legs' reference errors
  /// whose PD torque is a pure internal force decays at this rate: the torque kp (theta* -
  /// theta) is split into J_q^T lambda with J_b^T lambda = 0 (balanced by equal and opposite
  /// foot wrenches: it squeezes the feet, moves nothing) and the rest, orthogonal to it, whose
  /// reference error keeps the base and both feet on the loop (a motion the legs can make with
  /// both feet where they are). That rest is the paper's integration, untouched; the same split
  /// with kd for theta_dot*. J_b, J_q: the stacked foot Jacobians' base and joint columns.
  /// It composes with support_leg_leak_hz. 0 = the paper's integration. Default 3 Hz: after
  /// a 175 N sideways push the feet's true forces then match the used ones within a few N
  /// (25 N tangential without), and the double-support push envelope (+-0.5 deg jitter) is
  /// monotone in all 8 directions and higher in 7 of them (controller/momentum/README.md
  /// "Joint references in a closed loop").
  double internal_force_leak_hz = 3.0;
  /// A support that touches down (a swing foot set down, a lifted foot back on the ground) gets
  /// its leg's references reset to the measured joints (eqs (34)-(35) restarted); after that,
  /// while the contact solution gives that foot no more than this fraction of the weight, the
  /// leg's references keep following the measured joint state at touchdown_follow_hz, so its
  /// joint PD adds no load the contact problem did not plan. The first tick the solution plans
  /// more, or the foot is no longer a support, the paper's integration resumes. Why: after the
  /// step in place's landing the plan gave the landed foot 0 N for 0.85 s (the CoM still over
  /// the other foot) while the leg's PD pressed it with 26-81 N; when that faded the foot rose
  /// 1.7 mm for ~0.2 s, and the load planned later lagged the plan until the foot rocked on its
  /// edges (943 N); with the rule the foot stays down (controller/momentum/README.md "A landed
  /// foot the plan does not load"). 0: the reset at the touch-down tick only. In [0, 1).
  /// The planned force is that of the solution the tick uses: the contact optimiser's, or the
  /// fallback's (a reused solution, the gravity distribution) when that one is late or unusable;
  /// a tick refused for a bad state leaves the rule where it was, and reset() ends it.
  double touchdown_follow_fraction = 0.01;
  /// [Hz] The rate of that following (exp(-2 pi f dt) of the reference error kept per tick). > 0.
  double touchdown_follow_hz = 300.0;
  /// [Hz] Every joint's theta_dot* decays towards the measured joint velocity at this rate
  /// (theta_dot* - theta_dot multiplied by exp(-2 pi f dt) each tick before qdd_a is
  /// integrated; composes with support_leg_leak_hz); theta* is integrated as before. Why: the
  /// error e = theta* - theta of references integrated open loop is a mode of its own that
  /// the momentum loop cannot see (with an exact inverse dynamics, e'' = -M^-1 (K e + D e')
  /// whatever qdd_a is), and the robot's joint gains leave it lightly damped: on the project
  /// humanoid the whole body rocks on its ankles after a push (period 2.4 s, damping ratio
  /// ~0.04; controller/momentum/README.md "The joint references' own mode"). The leak adds
  /// 2 pi f to that mode's damping rate and leaves the references' stiffness. 0 = the
  /// paper's integration (the default: 1 Hz stops the rocking, but the double-support push
  /// envelope gets survivals above its first failure in more directions).
  double velocity_leak_hz = 0.0;
};

/// What to do when the contact solution of a tick is late or unusable.
struct FallbackConfig {
  /// Reuse the previous solution (same supports) for at most this many consecutive ticks; after
  /// that, or if the supports changed, use the gravity-compensating distribution.
  int max_reuse_ticks = 5;
};

/// A fallen robot: balance is over. From the first tick that meets either rule the controller
/// commands damping (the safe mode, tau = -kd qd) and says so (TickDiagnostics::fallen), until it
/// is reset: a fallen humanoid driven by a balance controller whose model no longer holds (feet
/// in the air, the trunk on the ground) gets joint torques at their limits, which on a real robot
/// break it and in the simulator threw a fallen G1 200 m into the air (controller/momentum/
/// README.md "A fallen robot"). Latched: a robot that lies on the floor does not stand up by
/// balancing.
struct FallConfig {
  /// The floating base turned this far from its orientation at the first tick (the robot
  /// standing) about a horizontal axis [deg]. Balanced pushes tilt the trunk at most ~20 deg
  /// (controller/momentum/README.md); no robot recovers from 60 deg. In (0, 180]; 180: never.
  double tilt_deg = 60.0;
  /// The CoM's height above the lowest sole below this fraction of its height at the first tick.
  /// [0, 1); 0: never.
  double com_height_fraction = 0.5;
};

struct ControllerConfig {
  double dt = 0.001;  ///< control period [s]
  MomentumGains momentum;
  ContactWeights contact;
  FootGains foot;
  AccelerationConfig acceleration;
  FeedbackConfig feedback;
  FallbackConfig fallback;
  FallConfig fall;
  /// The model's CoM error observed from the measured CoP (com_offset_observer.hpp): section
  /// `com_offset:` {bandwidth_hz, limit, speed_gate}. Off by default (bandwidth_hz 0; 0.5 turns
  /// it on, the figures of controller/momentum/README.md).
  ComOffsetObserverConfig com_offset;
  /// Measured CoP inside the safe region shrunk by this extra margin => the foot is resting
  /// (Sec. 4.2 moving-support rule) [m]. 0: the safe region itself.
  double resting_extra_margin = 0.0;
  /// FootMode::kAuto: a foot is a support when the state says in_contact, or when its measured
  /// normal force exceeds this fraction of the robot's weight (guards against a contact detector
  /// that is late, e.g. while the estimator initialises; a support wrongly dropped makes the
  /// controller plan a fall). <= 0: the contact flag only.
  double support_force_fraction = 0.1;
  /// FootMode::kSupport (a planned support): a foot measured off the ground -- its contact flag
  /// off and its load below support_force_fraction -- for this long leaves the contact problem
  /// until it touches again; meanwhile eq (36) holds it where it last rested, so it comes back
  /// down there [s]. Why: a push can lift a planned support (a lateral push unloads the far
  /// foot); kept in the contact problem, it was given a ground force it cannot get, and the
  /// inverse dynamics' torques for that force swung the lifted leg out (16 cm on a 175 N
  /// lateral push of the project humanoid), which then landed there. 0: never, the plan alone
  /// decides (the paper's Fig. 6 input taken literally). >= 0.
  double planned_support_release = 0.01;
  /// ... and its foot frame this far above where it last rested [m] (a planned support the
  /// weight went off -- a step in place before its swing -- rests on the ground with a load
  /// below the contact flag's threshold: it stays in the contact problem). >= 0.
  double planned_support_release_height = 0.003;
  /// Sec. 4.2: a support foot rests (follows its own, possibly moving, support) only when its
  /// measured normal force exceeds this fraction of the robot's weight, whatever its contact flag
  /// says: the flag means "touching" (idl/README.md "Contact flags"), and a foot that measures no
  /// load cannot rest on anything. 0.002 (1 N on the project humanoid, 2 x the F/T noise): a
  /// measured choice, not a physical bound; with 0.005 and 0.02 the badger test robot's push
  /// slipped 85 and 21 mm in process (a touching foot with 1-5 % of the weight held where it
  /// last rested and dragged back), with 0 and 0.002 1.7 mm (controller/momentum/README.md).
  /// >= 0 (0: any positive load).
  double resting_force_fraction = 0.002;
  /// ... except for a foot back from the air (its contact flag off for more than
  /// resting_touchdown_air_time since it last rested): it starts to rest only above this larger
  /// fraction, and then keeps resting down to resting_force_fraction. Why: a foot comes down with
  /// its swing's velocity, not its support's; resting (v_d = v) on the first newton of a light
  /// touch kept it moving (step in place, seed 3, the estimator's light-touch rule on: the
  /// landed foot bounced, came back with 1.8 N while moving forward and slid 18 mm/s for 0.55 s,
  /// 14 mm of slip). A foot that never left the ground keeps the low threshold: on accelerating
  /// supports a resting foot's load dips to a few newtons (with 0.01 for every foot,
  /// platforms_out_of_phase_20cm's CoM error was 38.9 mm against 13.2). In [0, 1).
  double resting_touchdown_force_fraction = 0.01;
  /// The contact flag off for longer than this [s] counts as back from the air (0.02: a foot
  /// on the out-of-phase platforms loses contact for a few ticks at a time). >= 0.
  double resting_touchdown_air_time = 0.02;
  /// Desired CoM height above the mean sole height of the support feet when the reference gives
  /// no CoM target [m]; <= 0: the nominal posture's CoM height.
  double com_height = 0.0;

  /// Throws ConfigError naming the first bad field: a value outside its key's range in the table
  /// (controller_config_keys.hpp), or a cut-off not below half the control rate.
  void validate() const;
};

/// Loads a YAML file (schema: controller/momentum/config/balance_controller.yaml); missing keys
/// keep their defaults, unknown keys are an error. Throws ConfigError naming the file and key.
ControllerConfig load_controller_config(const std::filesystem::path& path);

/// Same from YAML text (e.g. a scenario's `controller:` section); `origin` names the source in
/// error messages ("scenario 'x.yaml', controller"). Empty or null text: the defaults.
ControllerConfig parse_controller_config(const std::string& yaml_text, const std::string& origin);

}  // namespace poise::controller
