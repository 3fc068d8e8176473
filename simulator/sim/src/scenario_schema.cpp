// The scenario file's keys (scenario_schema.hpp): one table, read by the parsers for the keys a
// mapping may hold, and by the generator of deploy/scenarios/SCHEMA.md. The defaults shown are the
// configuration structs' own (sim_config.hpp, world.hpp, reality.hpp, the sensor presets).
#include "poise/sim/scenario_schema.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "poise/cli/reference_text.hpp"
#include "poise/sim/reality.hpp"
#include "poise/sim/simulator.hpp"
#include "poise/sim/world.hpp"
#include "poise/sim/yaml_checks.hpp"

namespace poise::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kDeg = M_PI / 180.0;

std::string num(double v) {
  if (std::isinf(v)) return v > 0 ? "none" : "-none";
  return cli::number_text(v);
}
std::string vec(const Eigen::Vector3d& v, double scale = 1.0) {
  std::string out = "[";
  for (int i = 0; i < 3; ++i) {
    out.append(num(v[i] / scale));
    out.append(i < 2 ? ", " : "]");
  }
  return out;
}
std::string yes_no(bool b) { return b ? "true" : "false"; }

using K = KeyKind;

// Shorthands of the rows below: the key kinds without bounds.
ScenarioKey section(std::string_view path, std::string_view doc, bool required = false) {
  return {path, K::kSection, "", "", -kInf, kInf, false, required, nullptr, "", doc, ""};
}

// One row a key, in the order of the page. Bounds are those the parsers enforce (the schema test
// checks each against them).
// clang-format off
const std::vector<ScenarioKey> kKeys = {
  {"name", K::kText, "", "", -kInf, kInf, false, true, nullptr,
   "1 to 100 of A-Z a-z 0-9 . _ -, no '..' (it names the result files)",
   "the experiment's name", "my_push"},
  {"description", K::kText, "", "", -kInf, kInf, false, false, nullptr, "", "free text", "\"a push\""},
  {"duration", K::kNumber, "s", "", 0.001, 1e6, false, true, nullptr, "", "how long the run lasts", "2.0"},
  {"reference", K::kFile, "", "", -kInf, kInf, false, false, nullptr, "",
   "a balance-reference trajectory played during the run (references/README.md)", "references/step_in_place.yaml"},

  section("robot", "the robot: a robot configuration (config), or a URDF with its feet (urdf + feet)", true),
  {"robot.config", K::kFile, "", "", -kInf, kInf, false, false, nullptr, "not with urdf, feet, imu_frame",
   "the robot configuration (robot.yaml: URDF, feet, soles, IMU, nominal posture)",
   "../robots/poise_humanoid/robot.yaml"},
  {"robot.urdf", K::kFile, "", "", -kInf, kInf, false, false, nullptr, "a regular file of at most 16 MB",
   "the URDF of a robot given inline (test robots); needs feet", "urdf/biped.urdf"},
  {"robot.imu_frame", K::kText, "", "", -kInf, kInf, false, false, [] { return std::string("the URDF's root link"); },
   "", "the link the IMU is fixed to", "imu_link"},
  {"robot.feet", K::kNames, "", "", -kInf, kInf, false, false, nullptr, "with urdf: at least one foot",
   "foot name -> its frame and sole", ""},
  {"robot.feet.*.frame", K::kText, "", "", -kInf, kInf, false, true, nullptr, "", "the foot's frame (a URDF link)", "l_sole"},
  section("robot.feet.*.sole", "the sole rectangle in the foot frame (all of x_min, x_max, y_min, y_max, height)"),
  {"robot.feet.*.sole.x_min", K::kNumber, "m", "", -kInf, kInf, false, true, nullptr, "", "back edge", "-0.1"},
  {"robot.feet.*.sole.x_max", K::kNumber, "m", "", -kInf, kInf, false, true, nullptr, "", "front edge", "0.1"},
  {"robot.feet.*.sole.y_min", K::kNumber, "m", "", -kInf, kInf, false, true, nullptr, "", "right edge", "-0.05"},
  {"robot.feet.*.sole.y_max", K::kNumber, "m", "", -kInf, kInf, false, true, nullptr, "", "left edge", "0.05"},
  {"robot.feet.*.sole.height", K::kNumber, "m", "", -kInf, kInf, false, true, nullptr, "", "depth of the sole plane below the frame", "0.0"},
  {"robot.feet.*.sole.thickness", K::kNumber, "m", "", -kInf, kInf, false, false,
   [] { return num(SoleConfig{}.thickness); }, "", "thickness of the collision box above the sole plane", "0.02"},
  {"robot.self_collision", K::kBool, "", "", -kInf, kInf, false, false, [] { return yes_no(false); },
   "", "collisions between the robot's own links", "false"},
  {"robot.damping_mode_kd", K::kNumber, "N m s/rad", "", 0.0, kInf, false, false,
   [] { return num(RobotConfig{}.damping_mode_kd); }, "",
   "the joints' damping gain in damping mode (the safety layer's fallback)", "5.0"},

  section("initial", "the initial posture and pose"),
  {"initial.posture", K::kChoice, "", "nominal | zero", -kInf, kInf, false, false,
   [] { return std::string("nominal"); }, "",
   "the joint angles before `joints`: the robot configuration's nominal posture, or all zero", "zero"},
  {"initial.joints", K::kNames, "", "", -kInf, kInf, false, false, nullptr, "", "joint name -> angle, over the posture", ""},
  {"initial.joints.*", K::kNumber, "rad", "", -kInf, kInf, false, false, nullptr, "within the joint's limits",
   "the joint's angle", "0.5"},
  {"initial.base_xy", K::kVec2, "m", "", -kInf, kInf, false, false, [] { return std::string("[0, 0]"); },
   "", "the base's x and y", "[0.1, 0.0]"},
  {"initial.base_height", K::kNumber, "m", "", -kInf, kInf, false, false, [] { return std::string("auto"); },
   "or auto; at least the ground height and at most 100 m above it",
   "the base's z; auto: the lowest sole corner on its support (plus clearance)", "auto"},
  {"initial.base_rpy_deg", K::kVec3, "deg", "", -kInf, kInf, false, false, [] { return std::string("[0, 0, 0]"); },
   "", "the base's roll, pitch, yaw", "[0, 0, 10]"},
  {"initial.facing_deg", K::kNumber, "deg", "", -360.0, 360.0, false, false, [] { return num(0.0); }, "",
   "world yaw of the robot's forward (robot.yaml forward_axis), applied on top of base_rpy_deg", "90"},
  {"initial.clearance", K::kNumber, "m", "", -kInf, kInf, false, false, [] { return num(0.0); }, "",
   "gap left under the lowest sole corner (base_height auto)", "0.03"},
  {"initial.support", K::kChoice, "", "double | <foot name>", -kInf, kInf, false, false,
   [] { return std::string("double"); },
   "a foot (robot.config robots): the other sole >= 1 mm higher and the CoM above this sole",
   "which feet carry the robot at the start", "double"},

  section("world", "the ground, gravity and moving supports"),
  {"world.gravity", K::kVec3, "m/s^2", "", -kInf, kInf, false, false, [] { return vec(WorldConfig{}.gravity); },
   "|g| <= 100", "gravity in the world frame", "[0, 0, -9.81]"},
  section("world.ground", "the ground plane"),
  {"world.ground.enabled", K::kBool, "", "", -kInf, kInf, false, false, [] { return yes_no(GroundConfig{}.enabled); },
   "", "whether there is a ground plane", "true"},
  {"world.ground.height", K::kNumber, "m", "", -kInf, kInf, false, false, [] { return num(GroundConfig{}.height); },
   "", "z of the plane", "0.0"},
  {"world.ground.friction", K::kNumber, "", "", 0.0, kInf, false, false, [] { return num(GroundConfig{}.friction); },
   "", "the simulated floor's Coulomb coefficient (what the feet get; the controller's own is "
   "`controller: {contact: {friction_mu: X}}`)", "0.8"},
  {"world.platforms", K::kList, "", "", -kInf, kInf, false, false, nullptr, "",
   "boxes under the feet, moving on prescribed paths", ""},
  {"world.platforms[].name", K::kText, "", "", -kInf, kInf, false, false, [] { return std::string("platform<i>"); },
   "", "its name", "left_support"},
  {"world.platforms[].foot", K::kText, "", "", -kInf, kInf, false, false, nullptr, "a foot of the robot",
   "the foot it supports (auto placement, slip measurement)", "left"},
  {"world.platforms[].size", K::kVec3, "m", "", -kInf, kInf, false, false,
   [] { return vec(2.0 * PlatformConfig{}.half_extents); }, "all three > 0", "full box size", "[0.6, 0.14, 0.1]"},
  {"world.platforms[].auto_place", K::kBool, "", "", -kInf, kInf, false, false,
   [] { return std::string("true with a foot"); }, "needs a foot",
   "top face under the sole, box on the ground (base_height auto lifts the robot)", "false"},
  {"world.platforms[].position", K::kVec3, "m", "", -kInf, kInf, false, false, [] { return vec(PlatformConfig{}.position); },
   "", "offset (auto_place) or top-centre position", "[0, 0, 0]"},
  {"world.platforms[].roll_deg", K::kNumber, "deg", "", -kInf, kInf, false, false, [] { return num(0.0); }, "",
   "inclination about x", "5"},
  {"world.platforms[].pitch_deg", K::kNumber, "deg", "", -kInf, kInf, false, false, [] { return num(0.0); }, "",
   "inclination about y", "10"},
  {"world.platforms[].yaw_deg", K::kNumber, "deg", "", -kInf, kInf, false, false, [] { return num(0.0); }, "",
   "turn about z", "0"},
  {"world.platforms[].friction", K::kNumber, "", "", 0.0, kInf, false, false, [] { return num(PlatformConfig{}.friction); },
   "", "Coulomb coefficient foot / platform", "0.8"},
  {"world.platforms[].motion_start", K::kNumber, "s", "", 0.0, kInf, false, false, [] { return num(0.0); }, "",
   "still before this time", "1.0"},
  {"world.platforms[].motion_ramp", K::kNumber, "s", "", 0.0, kInf, false, false, [] { return num(0.0); }, "",
   "smooth rise of the amplitude (the platform starts at rest)", "4.0"},
  section("world.platforms[].translation", "a sinusoidal translation: axis, amplitude, frequency, phase"),
  {"world.platforms[].translation.axis", K::kVec3, "", "", -kInf, kInf, false, false,
   [] { return vec(PlatformConfig{}.translation_axis); }, "non-zero (normalised)", "direction in the world", "[1, 0, 0]"},
  {"world.platforms[].translation.amplitude", K::kNumber, "m", "", -kInf, kInf, false, false, [] { return num(0.0); },
   "", "amplitude", "0.2"},
  {"world.platforms[].translation.frequency", K::kNumber, "Hz", "", 0.0, kInf, false, false, [] { return num(0.0); },
   "", "frequency", "1.0"},
  {"world.platforms[].translation.phase_deg", K::kNumber, "deg", "", -kInf, kInf, false, false, [] { return num(0.0); },
   "", "phase", "180"},
  section("world.platforms[].rotation", "a sinusoidal rotation about an axis of the inclined frame"),
  {"world.platforms[].rotation.axis", K::kVec3, "", "", -kInf, kInf, false, false,
   [] { return vec(PlatformConfig{}.rotation_axis); }, "non-zero (normalised)", "axis in the inclined frame", "[0, 1, 0]"},
  {"world.platforms[].rotation.amplitude_deg", K::kNumber, "deg", "", -kInf, kInf, false, false,
   [] { return num(0.0); }, "", "amplitude", "5"},
  {"world.platforms[].rotation.frequency", K::kNumber, "Hz", "", 0.0, kInf, false, false, [] { return num(0.0); },
   "", "frequency", "0.5"},
  {"world.platforms[].rotation.phase_deg", K::kNumber, "deg", "", -kInf, kInf, false, false, [] { return num(0.0); },
   "", "phase", "90"},

  section("disturbances", "scripted pushes"),
  {"disturbances.pushes", K::kList, "", "", -kInf, kInf, false, false, nullptr, "", "the pushes", ""},
  {"disturbances.pushes[].link", K::kText, "", "", -kInf, kInf, false, true, nullptr, "a link of the URDF",
   "the link pushed", "torso"},
  {"disturbances.pushes[].point", K::kVec3, "m", "", -kInf, kInf, false, false, [] { return vec(Push{}.point_L); },
   "|point| <= 5", "where, in the link's frame", "[0, 0, 0.05]"},
  {"disturbances.pushes[].force", K::kVec3, "N", "", -kInf, kInf, false, true, nullptr, "|force| <= 5000",
   "the force, in the world frame (or the heading frame, see frame)", "[120, 0, 0]"},
  {"disturbances.pushes[].frame", K::kChoice, "", "world | heading", -kInf, kInf, false, false,
   [] { return std::string("world"); }, "",
   "heading: x the robot's forward at the start (initial.facing_deg), y its left, z up", "heading"},
  {"disturbances.pushes[].start", K::kNumber, "s", "", 0.0, kInf, false, true, nullptr, "before the run's end",
   "when it starts", "0.2"},
  {"disturbances.pushes[].duration", K::kNumber, "s", "", 0.0, kInf, true, true, nullptr, "at most the run's duration",
   "how long it lasts (a live `poise push` is capped at 1000 N and 5 s by poise-sim)", "0.1"},

  section("sensors", "the simulated sensors (simulator/sim/SENSORS.md); absent keys keep the preset's"),
  {"sensors.preset", K::kChoice, "", "industrial_mems | ideal", -kInf, kInf, false, false,
   [] { return std::string("industrial_mems"); }, "",
   "industrial_mems: ADIS16470-class IMU, 2^20 counts/rev encoders, noisy F/T; ideal: exact", "ideal"},
  {"sensors.seed", K::kWhole, "", "", 0.0, 9007199254740992.0, false, false, [] { return num(double(ImuNoiseConfig{}.seed)); },
   "", "the noise generator's seed (runs are reproducible)", "7"},
  section("sensors.imu", "the IMU"),
  {"sensors.imu.orientation", K::kChoice, "", "filter | off | truth", -kInf, kInf, false, false,
   [] { return std::string("filter"); }, "", "the IMU's orientation output: its own drifting filter, zeros, or the truth", "truth"},
  {"sensors.imu.gyro_noise_std", K::kNumber, "rad/s", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().gyro_noise_std); }, "", "white noise per sample, added", "0.001"},
  {"sensors.imu.gyro_noise_density", K::kNumber, "rad/s/sqrt(Hz)", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().gyro_noise_density); }, "", "noise density", "1e-4"},
  {"sensors.imu.gyro_bias", K::kVec3, "rad/s", "", -kInf, kInf, false, false,
   [] { return vec(industrial_mems_imu().gyro_bias); }, "", "bias at power-up", "[0.001, 0, 0]"},
  {"sensors.imu.gyro_bias_walk", K::kNumber, "rad/s/sqrt(s)", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().gyro_bias_walk); }, "", "bias random walk", "4e-6"},
  {"sensors.imu.gyro_scale_error", K::kVec3, "", "", -kInf, kInf, false, false,
   [] { return vec(industrial_mems_imu().gyro_scale_error); }, "", "scale factor error per axis", "[0.001, 0, 0]"},
  {"sensors.imu.gyro_misalignment_deg", K::kVec3, "deg", "", -kInf, kInf, false, false,
   [] { return vec(industrial_mems_imu().gyro_misalignment, kDeg); }, "", "axis misalignment", "[0.05, 0, 0]"},
  {"sensors.imu.gyro_range", K::kNumber, "rad/s", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().gyro_range); }, "0: none", "saturation", "30"},
  {"sensors.imu.accel_noise_std", K::kNumber, "m/s^2", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().accel_noise_std); }, "", "white noise per sample, added", "0.01"},
  {"sensors.imu.accel_noise_density", K::kNumber, "m/s^2/sqrt(Hz)", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().accel_noise_density); }, "", "noise density", "1e-3"},
  {"sensors.imu.accel_bias", K::kVec3, "m/s^2", "", -kInf, kInf, false, false,
   [] { return vec(industrial_mems_imu().accel_bias); }, "", "bias at power-up", "[0.02, 0, 0]"},
  {"sensors.imu.accel_bias_walk", K::kNumber, "m/s^2/sqrt(s)", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().accel_bias_walk); }, "", "bias random walk", "1e-5"},
  {"sensors.imu.accel_scale_error", K::kVec3, "", "", -kInf, kInf, false, false,
   [] { return vec(industrial_mems_imu().accel_scale_error); }, "", "scale factor error per axis", "[0.001, 0, 0]"},
  {"sensors.imu.accel_misalignment_deg", K::kVec3, "deg", "", -kInf, kInf, false, false,
   [] { return vec(industrial_mems_imu().accel_misalignment, kDeg); }, "", "axis misalignment", "[0.05, 0, 0]"},
  {"sensors.imu.accel_range", K::kNumber, "m/s^2", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().accel_range); }, "0: none", "saturation", "160"},
  {"sensors.imu.rate_hz", K::kNumber, "Hz", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().rate_hz); }, "0: every step", "sample rate (sample and hold)", "500"},
  {"sensors.imu.delay_ticks", K::kWhole, "ticks", "", 0.0, 1000.0, false, false,
   [] { return num(industrial_mems_imu().delay_ticks); }, "", "output latency in simulator ticks", "2"},
  {"sensors.imu.filter_gain", K::kNumber, "rad/s", "", 0.0, kInf, false, false,
   [] { return num(industrial_mems_imu().filter_gain); }, "", "the attitude filter's accelerometer correction gain", "0.3"},
  {"sensors.imu.filter_accel_gate", K::kNumber, "g", "", 0.0, kInf, true, false,
   [] { return num(industrial_mems_imu().filter_accel_gate); }, "",
   "the filter corrects only while | |f| - g | is below this fraction of g", "0.2"},
  section("sensors.encoders", "the joint encoders"),
  {"sensors.encoders.counts_per_rev", K::kNumber, "counts", "", 0.0, kInf, false, false,
   [] { return num(industrial_encoder().counts_per_rev); }, "0: exact", "resolution", "65536"},
  {"sensors.encoders.velocity_filter_hz", K::kNumber, "Hz", "", 0.0, kInf, false, false,
   [] { return num(industrial_encoder().velocity_filter_hz); }, "0: exact", "first-order velocity filter", "200"},
  section("sensors.foot_ft", "the foot force/torque sensors"),
  {"sensors.foot_ft.force_noise_std", K::kNumber, "N", "", 0.0, kInf, false, false,
   [] { return num(industrial_foot_ft().force_noise_std); }, "", "white force noise", "1.0"},
  {"sensors.foot_ft.torque_noise_std", K::kNumber, "N m", "", 0.0, kInf, false, false,
   [] { return num(industrial_foot_ft().torque_noise_std); }, "", "white torque noise", "0.05"},
  {"sensors.foot_ft.force_offset", K::kVec3, "N", "", -kInf, kInf, false, false,
   [] { return vec(industrial_foot_ft().force_offset); }, "", "force offset", "[1, 0, 0]"},
  {"sensors.foot_ft.torque_offset", K::kVec3, "N m", "", -kInf, kInf, false, false,
   [] { return vec(industrial_foot_ft().torque_offset); }, "", "torque offset", "[0.01, 0, 0]"},

  section("solver", "Bullet's step and contact solver"),
  {"solver.dt", K::kNumber, "s", "", 0.0, 0.01, true, false, [] { return num(SolverConfig{}.dt); }, "",
   "the step (one control tick)", "0.001"},
  {"solver.iterations", K::kWhole, "", "", 1.0, 10000.0, false, false, [] { return num(SolverConfig{}.iterations); },
   "", "sequential-impulse iterations", "80"},
  {"solver.contact_erp", K::kNumber, "", "", -kInf, kInf, false, false, [] { return num(SolverConfig{}.contact_erp); },
   "", "penetration correction factor", "0.3"},
  {"solver.contact_cfm", K::kNumber, "", "", -kInf, kInf, false, false, [] { return num(SolverConfig{}.contact_cfm); },
   "", "constraint force mixing", "0.0"},
  {"solver.friction_anchor", K::kBool, "", "", -kInf, kInf, false, false,
   [] { return yes_no(SolverConfig{}.friction_anchor); }, "", "anchor static foot contacts (no slow creep)", "false"},
  {"solver.residual_threshold", K::kNumber, "", "", -kInf, kInf, false, false,
   [] { return num(SolverConfig{}.residual_threshold); }, "0: always all iterations",
   "stop iterating below this solver residual", "1e-9"},
  {"solver.joint_friction_constraint", K::kBool, "", "", -kInf, kInf, false, false,
   [] { return yes_no(SolverConfig{}.joint_friction_constraint); }, "",
   "exact Coulomb joint friction as a constraint (slower)", "true"},
  {"solver.joint_friction_velocity", K::kNumber, "rad/s", "", 0.0, kInf, true, false,
   [] { return num(SolverConfig{}.joint_friction_velocity); }, "",
   "the smooth joint friction's saturation velocity", "0.02"},
  {"solver.warm_start", K::kBool, "", "", -kInf, kInf, false, false, [] { return yes_no(SolverConfig{}.warm_start); },
   "", "start each contact's impulse from the last step's", "false"},
  {"solver.warm_start_factor", K::kNumber, "", "", 0.0, 1.0, false, false,
   [] { return num(SolverConfig{}.warm_start_factor); }, "", "fraction of the last step's impulse", "0.5"},

  {"reality", K::kSection, "", "", -kInf, kInf, false, false, [] { return std::string("none (the robot is its model)"); },
   "or a profile name: typical | none",
   "the simulated robot differs from the description the nodes get (simulator/README.md)", ""},
  {"reality.profile", K::kChoice, "", "typical | none", -kInf, kInf, false, false, [] { return std::string("none"); },
   "", "the values the keys below start from", "typical"},
  {"reality.seed", K::kWhole, "", "", 0.0, 9007199254740992.0, false, false, [] { return num(double(RealityConfig{}.seed)); },
   "", "seed of every draw (the run's result records the draw)", "3"},
  section("reality.links", "each simulated body's mass properties, drawn N(0,1) clipped at 3 std"),
  {"reality.links.mass_scale_std", K::kNumber, "", "", 0.0, kRealityMaxScaleStd, false, false,
   [] { return num(LinkReality{}.mass_scale_std); }, "", "mass x (1 + std z)", "0.05"},
  {"reality.links.inertia_scale_std", K::kNumber, "", "", 0.0, kRealityMaxScaleStd, false, false,
   [] { return num(LinkReality{}.inertia_scale_std); }, "", "inertia about the CoM x mass factor x (1 + std z)", "0.1"},
  {"reality.links.com_offset_std_m", K::kNumber, "m", "", 0.0, 0.1, false, false,
   [] { return num(LinkReality{}.com_offset_std_m); }, "", "CoM moved by std z per axis, in the link frame", "0.01"},
  {"reality.links.mass_scale", K::kNames, "", "", -kInf, kInf, false, false, nullptr, "", "explicit mass factor by link", ""},
  {"reality.links.mass_scale.*", K::kNumber, "", "", 0.0, 10.0, true, false, nullptr, "", "the link's mass factor", "1.1"},
  {"reality.links.inertia_scale", K::kNames, "", "", -kInf, kInf, false, false, nullptr, "", "explicit inertia factor by link", ""},
  {"reality.links.inertia_scale.*", K::kNumber, "", "", 0.0, 10.0, true, false, nullptr, "", "the link's inertia factor", "1.2"},
  {"reality.links.com_offset", K::kNames, "", "", -kInf, kInf, false, false, nullptr, "", "explicit CoM offset by link", ""},
  {"reality.links.com_offset.*", K::kVec3, "m", "", -kInf, kInf, false, false, nullptr, "at most 1 m long",
   "the link's CoM offset, link frame", "[0.02, 0, 0]"},
  {"reality.payloads", K::kList, "", "", -kInf, kInf, false, false, nullptr, "", "rigid masses the model does not have", ""},
  {"reality.payloads[].link", K::kText, "", "", -kInf, kInf, false, true, nullptr, "a link of the URDF", "the link it is fixed to", "torso"},
  {"reality.payloads[].mass", K::kNumber, "kg", "", 0.0, 1e4, true, true, nullptr, "", "its mass", "2.0"},
  {"reality.payloads[].offset", K::kVec3, "m", "", -kInf, kInf, false, false, [] { return vec(Payload{}.offset); },
   "at most 2 m from the link", "its CoM in the link frame", "[0, 0, 0.1]"},
  {"reality.payloads[].inertia", K::kVec3, "kg m^2", "", -kInf, kInf, false, false, [] { return vec(Payload{}.inertia); },
   "each >= 0, triangle inequality", "principal moments about its CoM, link axes", "[0.01, 0.01, 0.01]"},
  section("reality.actuators", "every joint's actuator (reality.hpp ActuatorReality: the model)"),
  {"reality.actuators.bandwidth_hz", K::kNumber, "Hz", "", 0.0, kInf, false, false,
   [] { return num(ActuatorReality{}.bandwidth_hz); }, "0: none", "first-order torque lag", "40"},
  {"reality.actuators.delay_ticks", K::kWhole, "ticks", "", 0.0, 1000.0, false, false,
   [] { return num(ActuatorReality{}.delay_ticks); }, "", "transport delay of the commanded torque", "2"},
  {"reality.actuators.torque_noise_std", K::kNumber, "N m", "", 0.0, kInf, false, false,
   [] { return num(ActuatorReality{}.torque_noise_std); }, "", "white torque noise", "0.1"},
  {"reality.actuators.torque_noise_of_effort", K::kNumber, "", "", 0.0, 1.0, false, false,
   [] { return num(ActuatorReality{}.torque_noise_of_effort); }, "", "plus this fraction of the effort limit", "0.01"},
  {"reality.actuators.coulomb_friction", K::kNumber, "N m", "", 0.0, kInf, false, false,
   [] { return num(ActuatorReality{}.coulomb_friction); }, "", "Coulomb friction, added to the URDF's", "0.5"},
  {"reality.actuators.coulomb_friction_of_effort", K::kNumber, "", "", 0.0, 1.0, false, false,
   [] { return num(ActuatorReality{}.coulomb_friction_of_effort); }, "", "plus this fraction of the effort limit", "0.008"},
  {"reality.actuators.viscous_friction", K::kNumber, "N m s/rad", "", 0.0, kInf, false, false,
   [] { return num(ActuatorReality{}.viscous_friction); }, "", "viscous friction, added to the URDF's", "0.3"},
  {"reality.actuators.effort_scale", K::kNumber, "", "", 0.0, 1.0, true, false,
   [] { return num(ActuatorReality{}.effort_scale); }, "", "the effort limit the joints really have, x the URDF's", "0.85"},
  section("reality.ground", "the ground and every platform"),
  {"reality.ground.friction", K::kRange, "", "", 0.0, 10.0, false, false, [] { return std::string("as the world"); },
   "min <= max", "drawn uniformly from [min, max] (a number: that value); replaces world.ground.friction and the platforms'", "[0.6, 1.0]"},
  {"reality.ground.stiffness", K::kNumber, "N/m", "", 0.0, 1e12, false, false,
   [] { return num(GroundReality{}.stiffness); }, "0: rigid", "per contact point", "7.5e4"},
  {"reality.ground.damping", K::kNumber, "N s/m", "", 0.0, kInf, false, false,
   [] { return num(GroundReality{}.damping); }, "needs a stiffness", "per contact point", "0"},

  section("success", "the verdict's criteria; absent bounds are not checked"),
  {"success.com_error_max_m", K::kNumber, "m", "", 0.0, kInf, false, false, [] { return num(SuccessCriteria{}.com_error_max_m); },
   "", "horizontal CoM error over the run (from the initial offset over the support feet's centroid, "
   "shifted by the run's balance references)", "0.15"},
  {"success.com_error_final_m", K::kNumber, "m", "", 0.0, kInf, false, false,
   [] { return num(SuccessCriteria{}.com_error_final_m); }, "", "CoM error at the end", "0.02"},
  {"success.foot_slip_max_m", K::kNumber, "m", "", 0.0, kInf, false, false,
   [] { return num(SuccessCriteria{}.foot_slip_max_m); }, "",
   "a supporting foot's sole centre, relative to its support", "0.01"},
  {"success.foot_tilt_max_deg", K::kNumber, "deg", "", 0.0, kInf, false, false,
   [] { return num(SuccessCriteria{}.foot_tilt_max_deg); }, "", "a supporting foot's sole against its support", "10"},
  {"success.recovery_time_s", K::kNumber, "s", "", -kInf, kInf, false, false,
   [] { return num(SuccessCriteria{}.recovery_time_s); }, "",
   "after the last push, until the CoM error stays below com_error_final_m", "2.5"},
  {"success.allow_non_foot_contacts", K::kBool, "", "", -kInf, kInf, false, false,
   [] { return yes_no(SuccessCriteria{}.allow_non_foot_contacts); }, "", "false: a knee, hand or trunk touching is a fall", "true"},
  {"success.min_base_height_m", K::kNumber, "m", "", -kInf, kInf, false, false,
   [] { return num(SuccessCriteria{}.min_base_height_m); }, "", "the base below this is a fall", "0.5"},
  {"success.max_damping_ticks", K::kWhole, "ticks", "", 0.0, 1e15, false, false,
   [] { return num(double(SuccessCriteria{}.max_damping_ticks)); }, "",
   "`poise run`: ticks the robot side may damp (no command for its hold time) before the run fails", "5"},

  section("contact", "the contact optimiser `poise run` starts (--contact-method wins)"),
  {"contact.method", K::kChoice, "", "sequential | qp", -kInf, kInf, false, false,
   [] { return std::string("sequential"); }, "", "the paper's two-stage optimiser, or the QP", "qp"},
  {"controller", K::kSection, "", "", -kInf, kInf, false, false, [] { return std::string("the controller's defaults"); },
   "", "the controller configuration for this run: every key in controller/momentum/CONFIG.md "
   "(--controller-config FILE replaces the section)", ""},
  {"estimator", K::kSection, "", "", -kInf, kInf, false, false, nullptr, "",
   "what the estimator assumes for this run: every key in estimator/CONFIG.md", ""},
  section("dds", "DDS vendors `poise run` starts the components on (--dds wins)"),
  {"dds.vendor", K::kChoice, "", "fastdds | cyclone | cyclonedds", -kInf, kInf, false, false, nullptr, "",
   "every component's vendor", "fastdds"},
  {"dds.components", K::kNames, "", "", -kInf, kInf, false, false, nullptr, "", "component -> vendor", ""},
  {"dds.components.*", K::kChoice, "", "fastdds | cyclone | cyclonedds", -kInf, kInf, false, false, nullptr, "",
   "that component's vendor", "cyclone"},
};
// clang-format on

/// "platforms[12]" -> "platforms[]".
std::string strip_index(std::string_view seg) {
  std::string out(seg);
  const auto open = out.find('[');
  if (open != std::string::npos) out = out.substr(0, open) + "[]";
  return out;
}

std::vector<std::string> split(std::string_view path) {
  std::vector<std::string> out;
  if (path.empty()) return out;
  std::size_t start = 0;
  while (true) {
    const auto dot = path.find('.', start);
    out.emplace_back(path.substr(start, dot == std::string_view::npos ? std::string_view::npos
                                                                       : dot - start));
    if (dot == std::string_view::npos) break;
    start = dot + 1;
  }
  return out;
}

/// The declared pattern `pattern` names the concrete key `key` ("*" any name; "x[]" any "x[N]").
bool matches(std::string_view pattern, std::string_view key) {
  const auto p = split(pattern), k = split(key);
  if (p.size() != k.size()) return false;
  for (std::size_t i = 0; i < p.size(); ++i)
    if (p[i] != "*" && p[i] != strip_index(k[i])) return false;
  return true;
}

std::string parent_of(std::string_view path) {
  const auto dot = path.rfind('.');
  return dot == std::string_view::npos ? std::string() : std::string(path.substr(0, dot));
}

std::string last_of(std::string_view path) {
  const auto dot = path.rfind('.');
  return std::string(dot == std::string_view::npos ? path : path.substr(dot + 1));
}

std::string choices_text(std::string_view choices) {
  std::vector<std::string> names;
  std::size_t start = 0;
  while (start < choices.size()) {
    auto bar = choices.find(" | ", start);
    if (bar == std::string_view::npos) bar = choices.size();
    names.emplace_back(choices.substr(start, bar - start));
    start = bar + 3;
  }
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += i + 1 == names.size() ? " or " : ", ";
    out += names[i].front() == '<' ? names[i] : "'" + names[i] + "'";
  }
  return out;
}

std::string kind_text(const ScenarioKey& k) {
  switch (k.kind) {
    case K::kSection: return "a mapping";
    case K::kList: return "a list of mappings";
    case K::kNames: return "a mapping by name";
    case K::kNumber: return "a number";
    case K::kWhole: return "a whole number";
    case K::kBool: return "true or false";
    case K::kText: return "text";
    case K::kChoice: return choices_text(k.choices);
    case K::kVec2: return "[x, y]";
    case K::kVec3: return "[x, y, z]";
    case K::kFile: return "a file name (relative: to the scenario's folder)";
    case K::kRange: return "a number or [min, max]";
  }
  return "";
}

}  // namespace

const std::vector<ScenarioKey>& scenario_keys() { return kKeys; }

const ScenarioKey* find_scenario_key(std::string_view key) {
  for (const auto& k : kKeys)
    if (matches(k.path, key)) return &k;
  return nullptr;
}

std::vector<std::string> scenario_children(std::string_view key) {
  std::vector<std::string> out;
  for (const auto& k : kKeys) {
    const std::string parent = parent_of(k.path);
    if (key.empty() ? parent.empty() : (!parent.empty() && matches(parent, key)))
      out.push_back(last_of(k.path));
  }
  return out;
}

std::string allowed_text(const ScenarioKey& k) {
  std::string out = kind_text(k);
  const bool bounded = k.kind == K::kNumber || k.kind == K::kWhole || k.kind == K::kRange;
  if (bounded && std::isfinite(k.lo) && std::isfinite(k.hi))
    out += std::string(k.lo_open ? " in (" : " in [") + num(k.lo) + ", " + num(k.hi) + "]";
  else if (bounded && std::isfinite(k.lo))
    out += std::string(k.lo_open ? " > " : " >= ") + num(k.lo);
  else if (bounded && std::isfinite(k.hi))
    out += " <= " + num(k.hi);
  if (!k.note.empty()) out += "; " + std::string(k.note);
  if (k.required) out += "; required";
  return out;
}

std::string scenario_schema_markdown() {
  std::string out;
  std::string section;
  for (const auto& k : kKeys) {
    // A top-level scalar (name, duration, reference) goes in the table of the top level.
    const bool scalar_at_top = k.path.find('.') == std::string_view::npos &&
                               (k.kind != K::kSection && k.kind != K::kList && k.kind != K::kNames);
    const std::string top = scalar_at_top ? "top level" : split(k.path).front();
    if (top != section) {
      section = top;
      out += (top == "top level" ? std::string("\n### The top level\n\n")
                                 : "\n### `" + top + "`\n\n") +
             "| key | allowed | unit | default | description |\n"
             "|---|---|---|---|---|\n";
    }
    const std::string dflt = k.default_text ? k.default_text() : (k.required ? "—" : "none");
    out += "| `" + std::string(k.path) + "` | " + cli::markdown_cell(allowed_text(k)) + " | " +
           cli::markdown_cell(k.unit.empty() ? "—" : k.unit) + " | " + cli::markdown_cell(dflt) +
           " | " + cli::markdown_cell(k.doc) + " |\n";
  }
  return out;
}

void YamlChecks::allow_declared(const YAML::Node& n, const std::string& key) const {
  if (!n) return;
  if (!n.IsMap()) fail(key.empty() ? "(document)" : key, "must be a mapping");
  const std::vector<std::string> names = scenario_children(key);
  for (const auto& kv : n) {
    const std::string k = kv.first.as<std::string>();
    if (std::find(names.begin(), names.end(), k) != names.end()) continue;
    std::string list;
    for (const auto& a : names)
      list += (list.empty() ? "" : ", ") + a;
    fail(key.empty() ? k : key + "." + k, "unknown key (allowed: " + list + ")");
  }
}

}  // namespace poise::sim
