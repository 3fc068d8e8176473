#pragma once

// Input and output of the contact-force optimiser (paper Sec. 3.3-3.4), shared by both methods.
//
// Frames and conventions
// - W: world frame, Z up; gravity is an input vector (e.g. (0, 0, -9.81)).
// - F: the frame of one foot, at the ankle joint (paper Fig. 4-5); its z axis is the sole normal.
//   The sole is the plane z_F = -h (h = ankle_height); the sole rectangle and the CoP are given in
//   F's x-y coordinates. Any orientation R_WF is allowed (non-level ground).
// - Momentum h = [k; l]: angular about the CoM first, then linear (as in the paper).
// - Foot index 0 is the right foot, 1 the left foot (paper's r, l).

#include <array>
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace poise::contact {

inline constexpr int kMaxFeet = 2;

/// Sole rectangle in the foot frame F (x-y of the sole plane), metres. Requires min < max.
struct SoleRectangle {
  double x_min = -0.08;
  double x_max = 0.12;
  double y_min = -0.045;
  double y_max = 0.045;
};

/// One foot as seen by the optimiser.
struct FootContact {
  bool in_contact = false;
  Eigen::Matrix3d R_WF = Eigen::Matrix3d::Identity();  ///< orientation of F in W (rotation)
  Eigen::Vector3d p_WF = Eigen::Vector3d::Zero();      ///< ankle (origin of F) in W, m
  SoleRectangle sole;                                  ///< in F, m
  double safety_margin = 0.005;  ///< m; the CoP stays this far inside the sole edges (>= 0)
  double ankle_height = 0.08;    ///< h, m: sole plane at z_F = -h (>= 0)
  double mu = 0.7;               ///< Coulomb friction coefficient (>= 0)
  double mu_torsion = 0.02;      ///< |tau_n| <= mu_torsion * f_n, m (>= 0)
};

/// How the optimiser ranks the linear against the angular momentum rate.
enum class Priority : std::uint8_t {
  /// Linear first, strictly: the admissible linear rate is the best achievable one (closest to
  /// l_dot_d over every admissible force set), and the angular rate is the best given that (the
  /// paper's stated priority, Sec. 3.3). Solved as the weighted problem with w_k, eps_f and eps_tau
  /// multiplied by kLexicographicScale: the linear rate is then within ~1e-4 relative of the
  /// lexicographic optimum, far inside kLinearTolerance.
  kLexicographic = 0,
  /// The paper's eq. (21) as written: one weighted sum, w_k trading angular against linear.
  kWeighted = 1,
};

/// "lexicographic" or "weighted" (static strings).
const char* to_string(Priority p);

/// How a foot's normal (torsional) torque is bounded.
enum class TorsionLimit : std::uint8_t {
  /// |tau_n| <= mu_torsion f_n, whatever the tangential force (the paper's box, eq. (30)).
  kIndependent = 0,
  /// Torsion and the tangential force share one friction budget (a linear limit surface):
  /// |tau_n| <= mu_torsion (f_n - |f_t| / mu). A foot already pushing sideways at its friction
  /// limit can resist no twist. Why: a sole twists on the friction of its contact points, and the
  /// friction the tangential force uses is not there for the twist. For two contact points a
  /// distance w apart (a foot on one edge) the capacity is exactly (w / 2)(mu f_n - |f_t|); with
  /// mu_torsion <= mu w / 2 this bound lies inside it. mu = 0: as kIndependent.
  kFrictionCoupled = 1,
};

/// "independent" or "friction-coupled" (static strings).
const char* to_string(TorsionLimit t);

/// The largest |tau_n| a foot carrying the force f_F (in its frame F: z the normal) may resist.
double torsion_limit(const FootContact& foot, const Eigen::Vector3d& f_F, TorsionLimit model);

/// Scale of the angular and regularisation weights under Priority::kLexicographic.
inline constexpr double kLexicographicScale = 1e-4;

/// Objective weights. Each weight multiplies a squared norm in the objective; the least-squares
/// rows are scaled by its square root (paper eq. (24) and (29) write the row scale; Sec. 4.2's
/// values are used here as weights, the reading of (21) and (20)).
struct ContactWeights {
  double w_k = 0.1;       ///< angular tracking weight, eq. (21) (linear tracking weight is 1)
  double eps_f = 0.01;    ///< force regularisation, eq. (21): sequential on rho, QP on f
  double eps_cop = 0.01;  ///< CoP / normal-torque regularisation towards eta_d, eq. (29)
  double eps_tau = 1e-4;  ///< QP only: ankle-torque regularisation (paper eq. (20), w_tau)
  /// Linear first strictly (default) or the weighted sum of eq. (21). Not on the wire
  /// (idl/contact_problem.idl): the contact node takes it as an option (`--priority`).
  Priority priority = Priority::kLexicographic;
  /// The normal-torque bound. Not on the wire either (poise-contact `--torsion-limit`).
  TorsionLimit torsion = TorsionLimit::kIndependent;
  /// The weights the solvers use: w_k, eps_f, eps_tau scaled for the lexicographic priority.
  double scale() const { return priority == Priority::kLexicographic ? kLexicographicScale : 1.0; }
};

/// One contact problem: desired momentum rate change and the feet.
struct ContactProblem {
  double mass = 0.0;                                           ///< total mass, kg (> 0)
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -9.81);  ///< m/s^2, world
  Eigen::Vector3d com = Eigen::Vector3d::Zero();               ///< r_G, m, world
  Eigen::Vector3d k_dot_desired = Eigen::Vector3d::Zero();     ///< N m, world, about the CoM
  Eigen::Vector3d l_dot_desired = Eigen::Vector3d::Zero();     ///< N, world
  std::array<FootContact, kMaxFeet> feet;
  ContactWeights weights;
};

/// Overall result of one solve.
enum class ContactStatus : std::uint8_t {
  kOk = 0,              ///< admissible rate equals the desired one (see kRateTolerance)
  kCompromised = 1,     ///< constraints active: admissible rate differs from the desired one
  kNoContact = 2,       ///< no foot in contact: zero forces, l_dot_a = m g, k_dot_a = 0
  kIterationLimit = 3,  ///< a solver hit its iteration cap; the answer is admissible, not optimal
  kInvalidInput = 4,    ///< non-finite or inconsistent input; safe answer (every output zero)
  kSolverFailure = 5,   ///< numerical failure; safe answer (every output zero)
};

/// Short lower-case name ("ok", "compromised", ...), static string.
const char* to_string(ContactStatus s);

/// kOk is reported when |h_dot_a - h_dot_d| <= kRateTolerance * (m |g| + |h_dot_d|) AND the
/// linear rate alone is within kLinearTolerance * m |g| of l_dot_d: a solution that gives away
/// linear momentum (the priority of Sec. 3.3) by more than 0.1 % of the weight is never `ok`.
inline constexpr double kRateTolerance = 1e-2;
inline constexpr double kLinearTolerance = 1e-3;

/// The ground reaction on one foot.
struct FootWrench {
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();         ///< f_i, N, world
  Eigen::Vector3d torque_ankle_W = Eigen::Vector3d::Zero();  ///< tau_i about the ankle, N m, world
  Eigen::Vector3d cop_W = Eigen::Vector3d::Zero();           ///< CoP p_i, m, world
  Eigen::Vector2d cop_F = Eigen::Vector2d::Zero();           ///< (d_x, d_y) in F, m (d_z = -h)
  double normal_torque = 0.0;  ///< tau_n about the sole normal through the CoP, N m

  /// The wrench on the foot expressed at the foot-frame origin (ankle) in world coordinates:
  /// [torque_ankle_W; force_W], what inverse dynamics needs as the external wrench on the foot.
  Eigen::Matrix<double, 6, 1> wrench_at_ankle_W() const {
    Eigen::Matrix<double, 6, 1> w;
    w << torque_ankle_W, force_W;
    return w;
  }
};

/// Output of one solve. Every number is finite, whatever the input.
struct ContactSolution {
  ContactStatus status = ContactStatus::kInvalidInput;
  Eigen::Vector3d k_dot_admissible = Eigen::Vector3d::Zero();  ///< N m, world, about the CoM
  Eigen::Vector3d l_dot_admissible = Eigen::Vector3d::Zero();  ///< N, world
  std::array<FootWrench, kMaxFeet> feet;                       ///< zero for feet not in contact
};

/// Checks the problem. Returns nullptr when valid, else a static message naming the problem
/// (e.g. "feet[1]: R_WF is not a rotation"). Never allocates.
const char* validate(const ContactProblem& problem);

/// Safe region of a foot's CoP in F: the sole shrunk by the safety margin, [x_lo, x_hi, y_lo,
/// y_hi].
Eigen::Vector4d safe_region(const FootContact& foot);

/// Wrench of a foot from its force (world), CoP (d_x, d_y) in F and normal torque (paper eq. (19)).
FootWrench make_foot_wrench(const FootContact& foot, const Eigen::Vector3d& force_W, double d_x,
                            double d_y, double normal_torque);

/// World-frame friction-pyramid basis of a foot (used by both methods): 4 unit columns
/// beta_ij = R_WF b_j, b_j = (+-mu, 0, 1) and (0, +-mu, 1) normalised. The pyramid is inscribed
/// in the friction cone (its edges lie on the cone).
Eigen::Matrix<double, 3, 4> friction_basis_W(const FootContact& foot);

/// Admissible momentum rate from the foot wrenches: l_dot = m g + sum f_i (18),
/// k_dot = sum (r_i - r_G) x f_i + tau_i (15)-(17).
void momentum_rate_from_wrenches(const ContactProblem& problem, ContactSolution& solution);

/// Tracking cost, the objective both methods are compared on:
/// |l_dot_d - l_dot_a|^2 + w_k |k_dot_d - k_dot_a|^2.
double tracking_cost(const ContactProblem& problem, const ContactSolution& solution);

/// Objective of the one-QP method (QpOptimizer) at any answer given as wrenches plus the
/// friction-pyramid magnitudes rho of its forces (4 per foot, foot i at 4 i):
/// |l_dot_d - l_dot_a|^2 + s (w_k |k_dot_d - k_dot_a|^2 + eps_f |rho|^2 + eps_tau sum |tau_i|^2),
/// s = weights.scale() (1 for the weighted priority: tracking_cost + the regularisation).
double qp_objective(const ContactProblem& problem, const ContactSolution& solution,
                    const Eigen::Matrix<double, 4 * kMaxFeet, 1>& rho);

/// Sets the safe answer: every output zero and the given status.
void set_safe_solution(ContactStatus status, ContactSolution& solution);

namespace detail {
/// Cross-product matrix: skew(v) w = v x w.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}
/// Shared prologue of both methods: validates, handles zero contacts. Returns true when the caller
/// must still solve (>= 1 foot in contact); otherwise `solution` is complete.
bool prepare(const ContactProblem& problem, ContactSolution& solution);
/// Shared epilogue: computes the admissible rate, guards finiteness, sets kOk / kCompromised
/// unless `status` is already an error or iteration-limit status.
void finish(const ContactProblem& problem, ContactStatus status, ContactSolution& solution);
}  // namespace detail

}  // namespace poise::contact
