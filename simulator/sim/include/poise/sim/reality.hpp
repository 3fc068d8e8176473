#pragma once
// The simulated robot is not its model. A scenario's `reality:` section (simulator/README.md
// "Reality: a robot that is not its model") changes the robot the simulator steps while every
// node keeps the nominal description it is given, as on hardware, where the nodes get the maker's
// URDF and the robot is what it is:
//   - mass properties per simulated body (a URDF link and the links fixed to it): mass scale,
//     rotational inertia scale, CoM offset; explicit or drawn from stated distributions;
//   - unmodelled payloads fixed to links;
//   - actuators: first-order torque lag, transport delay, torque noise, Coulomb and viscous joint
//     friction, an effort limit below the URDF's;
//   - ground: friction coefficient (replacing the world's), compliance (stiffness, damping).
// Every draw comes from `seed` alone and in body order, so a scenario gives the same robot in
// process and distributed. Without the section nothing changes (RealityConfig::enabled false).

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace poise::sim {

/// A value drawn per body: x = 1 + std * z (scales) or std * z (offsets), z ~ N(0, 1) clipped to
/// [-kRealityClip, kRealityClip].
inline constexpr double kRealityClip = 3.0;
/// Largest relative std of a scale (mass, inertia): 1 - 3 std stays >= 0.25.
inline constexpr double kRealityMaxScaleStd = 0.25;

/// Mass properties of the simulated bodies.
struct LinkReality {
  double mass_scale_std = 0.0;     ///< relative std of each body's mass [-]
  double inertia_scale_std = 0.0;  ///< relative std of its rotational inertia about its CoM, on
                                   ///< top of the mass factor (inertia scales with mass) [-]
  double com_offset_std_m = 0.0;   ///< std of each axis of its CoM offset, body frame [m]
  /// Explicit values, by the URDF link that starts a body; they replace that body's draw.
  std::vector<std::pair<std::string, double>> mass_scale, inertia_scale;
  std::vector<std::pair<std::string, Eigen::Vector3d>> com_offset;
};

/// A rigid mass fixed to a link that the model does not have (a battery, cables, a sensor head).
struct Payload {
  std::string link;                                     ///< URDF link it is fixed to
  double mass = 0.0;                                    ///< [kg] > 0
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();     ///< its CoM in the link frame [m]
  Eigen::Vector3d inertia = Eigen::Vector3d::Zero();    ///< principal moments about its CoM,
                                                        ///< link axes [kg m^2] (>= 0)
};

/// Joint actuators (every joint). Per tick, from the commanded torque u (PD evaluated as today):
///   u_d[k]   = u[k - delay_ticks]                               transport delay
///   y[k]     = y[k-1] + a (u_d[k] - y[k-1]), a = 1 - exp(-2 pi bandwidth_hz dt)   torque lag
///   tau[k]   = clamp(y[k] + noise, -effort_scale E, effort_scale E)   applied, E = URDF effort
///   friction = coulomb sat(qd / v) + viscous qd   opposing the motion (the smooth model of
///              the URDF's friction, v = solver.joint_friction_velocity), added to the URDF's
/// noise ~ N(0, torque_noise_std + torque_noise_of_effort E); Coulomb = coulomb_friction +
/// coulomb_friction_of_effort E (joints without an effort limit: the absolute part only).
/// Sensors report tau[k] as the measured joint torque (what a drive's current says).
struct ActuatorReality {
  double bandwidth_hz = 0.0;           ///< 0: no lag
  int delay_ticks = 0;                 ///< [ticks] >= 0
  double torque_noise_std = 0.0;       ///< [N m]
  double torque_noise_of_effort = 0.0; ///< [-] fraction of the effort limit
  double coulomb_friction = 0.0;       ///< [N m]
  double coulomb_friction_of_effort = 0.0;  ///< [-]
  double viscous_friction = 0.0;       ///< [N m s/rad]
  double effort_scale = 1.0;           ///< (0, 1]
};

/// The ground and every platform.
struct GroundReality {
  /// Coulomb coefficient drawn uniformly in [friction_min, friction_max] (equal: that value),
  /// replacing world.ground.friction and each platform's; NaN: the world's friction is kept.
  double friction_min = std::numeric_limits<double>::quiet_NaN();
  double friction_max = std::numeric_limits<double>::quiet_NaN();
  /// Compliance of each contact point [N/m] and [N s/m] (Bullet's contact stiffness and damping:
  /// a flat sole rests on its 4 corners, so the sole sinks load / (4 stiffness)); 0: rigid.
  double stiffness = 0.0;
  double damping = 0.0;
};

struct RealityConfig {
  bool enabled = false;
  std::string profile;     ///< "" (none) or the profile it started from ("typical")
  std::uint64_t seed = 1;  ///< seed of every draw (mass properties, ground friction, torque noise)
  LinkReality links;
  std::vector<Payload> payloads;
  ActuatorReality actuators;
  GroundReality ground;
};

/// `reality: typical`: the figures humanoid makers and identification papers report
/// (simulator/README.md "The typical profile" gives each figure's source).
RealityConfig typical_reality();

/// What the simulator made of a RealityConfig: the draw, recorded in run results.
struct RealityDraw {
  struct Body {
    std::string name;  ///< the URDF link that starts the body
    double mass_nominal = 0.0, mass = 0.0;  ///< [kg] payloads included in `mass`
    double mass_scale = 1.0, inertia_scale = 1.0;
    Eigen::Vector3d com_offset = Eigen::Vector3d::Zero();  ///< of the body itself (no payload) [m]
  };
  bool enabled = false;
  std::string profile;
  std::uint64_t seed = 0;
  std::vector<Body> bodies;
  double mass_nominal = 0.0, mass = 0.0;  ///< whole robot [kg]
  /// CoM of the whole robot at q = 0, true minus nominal, in the root body's frame [m].
  Eigen::Vector3d com_shift_at_zero = Eigen::Vector3d::Zero();
  double ground_friction = std::numeric_limits<double>::quiet_NaN();  ///< NaN: the world's
  RealityConfig config;  ///< what was asked (the profile's values included)
};

/// One readable line of a draw for logs and progress output: profile, seed, true and nominal
/// mass, CoM shift, ground friction, actuators ("" when the robot is its model).
std::string describe_reality(const RealityDraw& draw);

}  // namespace poise::sim
