// The `reality:` section (poise/sim/reality.hpp): a simulated robot that is not its model. Each
// change is checked against physics the test computes on its own (the weight the ground carries,
// the centre of pressure under an offset CoM, impulse and momentum, a first-order step
// response, sliding friction, a contact spring's sinkage) and the draws against their stated
// distributions, with fixed seeds.
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "poise/sim/simulator.hpp"
#include "poise/sim/world.hpp"
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

using test::biped_config;
using test::biped_lying_on_back_config;
using test::box_config;

/// The test biped's world with `reality_yaml` appended.
World parse(const std::string& reality_yaml) {
  const std::string yaml =
      "name: r\nduration: 1\nrobot:\n  urdf: urdf/biped.urdf\n"
      "  imu_frame: imu_link\n  feet:\n"
      "    left: {frame: l_sole}\n"
      "    right: {frame: r_sole}\n" +
      reality_yaml;
  return parse_world(yaml, std::filesystem::path(POISE_SOURCE_DIR) / "tests/simulator", "r.yaml");
}

/// The error that parsing and building the world with `reality_yaml` raises ("" if none).
std::string parse_error(const std::string& reality_yaml) {
  try {
    Simulator sim(parse(reality_yaml).sim);  // names of links are checked against the URDF here
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(RealityConfig, ProfilesParseAndBadValuesNameTheirKey) {
  EXPECT_FALSE(parse("").sim.reality.enabled) << "no section: the robot is its model";
  EXPECT_FALSE(parse("reality: none\n").sim.reality.enabled);
  const World t = parse("reality: typical\n");
  EXPECT_TRUE(t.sim.reality.enabled);
  EXPECT_EQ(t.sim.reality.profile, "typical");
  EXPECT_EQ(t.sim.reality.links.mass_scale_std, typical_reality().links.mass_scale_std);
  EXPECT_EQ(t.sim.reality.actuators.delay_ticks, typical_reality().actuators.delay_ticks);
  // A profile with overrides keeps the rest of the profile.
  const World o = parse(
      "reality:\n  profile: typical\n  seed: 42\n  actuators: {delay_ticks: 0}\n"
      "  ground: {friction: [0.3, 0.4]}\n");
  EXPECT_EQ(o.sim.reality.seed, 42u);
  EXPECT_EQ(o.sim.reality.actuators.delay_ticks, 0);
  EXPECT_EQ(o.sim.reality.actuators.bandwidth_hz, typical_reality().actuators.bandwidth_hz);
  EXPECT_EQ(o.sim.reality.ground.friction_min, 0.3);
  EXPECT_EQ(o.sim.reality.ground.friction_max, 0.4);

  EXPECT_NE(parse_error("reality: bogus\n").find("reality: unknown profile 'bogus'"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {masses: 1}\n").find("reality.masses: unknown key"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {links: {mass_scale_std: 0.5}}\n")
                .find("reality.links.mass_scale_std: must be at most"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {links: {mass_scale: {l_thigh: -1}}}\n")
                .find("reality.links.mass_scale.l_thigh: must be in (0, 10]"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {links: {mass_scale: {no_such_link: 1.1}}}\n")
                .find("'no_such_link' is not a link of the URDF"),
            std::string::npos);
  // A link fixed to another is named by the body it moves with.
  EXPECT_NE(parse_error("reality: {links: {com_offset: {imu_link: [0, 0, 0.01]}}}\n")
                .find("link 'imu_link' is fixed to 'pelvis'"),
            std::string::npos)
      << parse_error("reality: {links: {com_offset: {imu_link: [0, 0, 0.01]}}}\n");
  EXPECT_NE(parse_error("reality: {payloads: [{link: torso, mass: 0}]}\n")
                .find("reality.payloads[0].mass: must be in (0, 1e4] kg"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {payloads: [{link: torso, mass: 1, inertia: [1, 0, 0]}]}\n")
                .find("triangle inequality"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {actuators: {effort_scale: 1.5}}\n")
                .find("reality.actuators.effort_scale: must be in (0, 1]"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {actuators: {delay_ticks: 1.5}}\n")
                .find("reality.actuators.delay_ticks: must be an integer"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {ground: {friction: [0.9, 0.5]}}\n")
                .find("reality.ground.friction: must satisfy"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {ground: {damping: 10}}\n").find("needs a stiffness"),
            std::string::npos);
  EXPECT_NE(parse_error("reality: {seed: -1}\n").find("reality.seed: must be an integer"),
            std::string::npos);
}

/// Steps `sim` `steps` times with `cmd`; returns the last truth.
GroundTruth run(Simulator& sim, const JointCommand& cmd, int steps) {
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  for (int k = 0; k < steps; ++k)
    sim.step(cmd, s, g);
  return g;
}

// A section whose every value is neutral steps the very same robot as no section, bit for bit:
// the mechanism itself changes nothing.
TEST(Reality, NeutralValuesStepTheRobotBitForBitAsWithoutTheSection) {
  SimulatorConfig plain = biped_lying_on_back_config();
  SimulatorConfig neutral = plain;
  neutral.reality.enabled = true;
  neutral.reality.seed = 99;
  Simulator a(plain), b(neutral);
  JointCommand cmd = a.make_command();
  cmd.mode = CommandMode::kPd;
  cmd.kp.setConstant(50.0);
  cmd.kd.setConstant(2.0);
  cmd.q_ref.setConstant(0.3);
  const GroundTruth ga = run(a, cmd, 600), gb = run(b, cmd, 600);
  EXPECT_EQ(ga.X_WB.matrix(), gb.X_WB.matrix());
  EXPECT_EQ(ga.com_W, gb.com_W);
  EXPECT_TRUE(b.reality().enabled);
  EXPECT_EQ(b.reality().mass, a.total_mass());
}

// Draws: the same seed gives the same robot; over many seeds each body's scale has mean 1 and
// the stated std (clipped at 3 std), the CoM offsets mean 0 and their std; an explicit value
// replaces only its own body's draw.
TEST(Reality, DrawsAreSeededAndFollowTheirStatedDistributions) {
  SimulatorConfig cfg = biped_config();
  cfg.reality.enabled = true;
  cfg.reality.links.mass_scale_std = 0.05;
  cfg.reality.links.inertia_scale_std = 0.15;
  cfg.reality.links.com_offset_std_m = 0.01;
  cfg.reality.seed = 7;
  const RealityDraw d1 = Simulator(cfg).reality();
  const RealityDraw d2 = Simulator(cfg).reality();
  ASSERT_EQ(d1.bodies.size(), d2.bodies.size());
  for (std::size_t b = 0; b < d1.bodies.size(); ++b) {
    EXPECT_EQ(d1.bodies[b].mass_scale, d2.bodies[b].mass_scale);
    EXPECT_EQ(d1.bodies[b].com_offset, d2.bodies[b].com_offset);
  }
  // Explicit value for one body: the others keep their draw.
  SimulatorConfig one = cfg;
  one.reality.links.mass_scale = {{d1.bodies[2].name, 1.5}};
  const RealityDraw d3 = Simulator(one).reality();
  for (std::size_t b = 0; b < d1.bodies.size(); ++b)
    EXPECT_EQ(d3.bodies[b].mass_scale, b == 2 ? 1.5 : d1.bodies[b].mass_scale);

  double sm = 0, smm = 0, si = 0, sii = 0, sc = 0, scc = 0, max_dev = 0;
  int n = 0, nc = 0;
  for (std::uint64_t seed = 1; seed <= 150; ++seed) {
    cfg.reality.seed = seed;
    const RealityDraw d = Simulator(cfg).reality();
    if (seed != 7) {
      EXPECT_NE(d.bodies[1].mass_scale, d1.bodies[1].mass_scale);
    }
    double total = 0.0;
    for (const auto& b : d.bodies) {
      sm += b.mass_scale - 1;
      smm += (b.mass_scale - 1) * (b.mass_scale - 1);
      si += b.inertia_scale - 1;
      sii += (b.inertia_scale - 1) * (b.inertia_scale - 1);
      max_dev = std::max(max_dev, std::abs(b.mass_scale - 1));
      for (int k = 0; k < 3; ++k) {
        sc += b.com_offset[k];
        scc += b.com_offset[k] * b.com_offset[k];
        ++nc;
      }
      total += b.mass;
      ++n;
    }
    EXPECT_NEAR(total, d.mass, 1e-9);
  }
  const double N = n, NC = nc;
  // Standard errors: std / sqrt(N) with N ~ 2000 bodies; tolerances of ~4 standard errors.
  EXPECT_NEAR(sm / N, 0.0, 4 * 0.05 / std::sqrt(N));
  EXPECT_NEAR(std::sqrt(smm / N), 0.05, 0.05 * 0.06);
  EXPECT_NEAR(si / N, 0.0, 4 * 0.15 / std::sqrt(N));
  EXPECT_NEAR(std::sqrt(sii / N), 0.15, 0.15 * 0.06);
  EXPECT_NEAR(sc / NC, 0.0, 4 * 0.01 / std::sqrt(NC));
  EXPECT_NEAR(std::sqrt(scc / NC), 0.01, 0.01 * 0.05);
  EXPECT_LE(max_dev, 3 * 0.05 + 1e-12) << "clipped at 3 std";
}

// Every body 20 % heavier: the ground carries 1.2 times the model's weight (Bullet's contact
// forces, against the nominal robot's mass).
TEST(Reality, HeavierLinksAreCarriedByTheGround) {
  SimulatorConfig cfg = biped_lying_on_back_config();
  const double nominal = Simulator(cfg).total_mass();
  cfg.reality.enabled = true;
  Simulator probe(cfg);
  for (const std::string& b : probe.body_names())
    cfg.reality.links.mass_scale.emplace_back(b, 1.2);
  Simulator sim(cfg);
  EXPECT_NEAR(sim.reality().mass, 1.2 * nominal, 1e-9);
  EXPECT_NEAR(sim.reality().mass_nominal, nominal, 1e-9);
  const JointCommand cmd = test::damping_command(sim, 2.0);
  run(sim, cmd, 2500);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  double fz = 0.0;
  for (int k = 0; k < 500; ++k) {
    sim.step(cmd, s, g);
    fz += g.total_contact_force_W.z() / 500;
  }
  EXPECT_NEAR(fz, 1.2 * nominal * 9.81, 0.01 * nominal * 9.81);
}

// The box's CoM moved 4 cm forward in its own frame: at rest its centre of pressure (Bullet's
// contact points weighted by their impulses) sits under the moved CoM, and its ground-truth CoM
// follows.
TEST(Reality, ACentreOfMassOffsetMovesTheCentreOfPressureUnderIt) {
  SimulatorConfig cfg = box_config();
  Simulator plain(cfg);
  const GroundTruth g0 = run(plain, plain.make_command(), 800);
  cfg.reality.enabled = true;
  cfg.reality.links.com_offset = {{"body", Eigen::Vector3d(0.04, 0.0, 0.0)}};
  Simulator sim(cfg);
  const GroundTruth g = run(sim, sim.make_command(), 800);
  const Eigen::Vector3d shift_W = g.X_WB.linear() * Eigen::Vector3d(0.04, 0.0, 0.0);
  EXPECT_NEAR((g0.feet[0].cop_W - g0.com_W).head<2>().norm(), 0.0, 1e-3);
  EXPECT_NEAR((g.feet[0].cop_W - g.com_W).head<2>().norm(), 0.0, 1e-3);
  // In the body's own frame the CoM moved by the offset exactly (each run settles to its own
  // tilt, nanoradians apart, so world vectors are compared through their own rotations).
  const Eigen::Vector3d c_B = g.X_WB.linear().transpose() * (g.com_W - g.X_WB.translation());
  const Eigen::Vector3d c0_B = g0.X_WB.linear().transpose() * (g0.com_W - g0.X_WB.translation());
  EXPECT_NEAR((c_B - c0_B - Eigen::Vector3d(0.04, 0.0, 0.0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR(sim.reality().com_shift_at_zero.x(), 0.04, 1e-12);
  // The CoM the description puts there is the unmoved one: the verdict's reference
  // (ScenarioMonitor) starts from it, so standing with the moved CoM there is an error.
  EXPECT_NEAR((g.model_com_shift_W + shift_W).norm(), 0.0, 1e-9);
  EXPECT_EQ(g0.model_com_shift_W, Eigen::Vector3d::Zero()) << "without reality: zero, exactly";
}

// A 1 kg payload on the box with its own inertia, and the box's inertia scaled: in free space a
// push of J N s changes the CoM velocity by J / (2 + 1) kg, and a pure couple tau spins it at
// I^-1 tau t, with I the parallel-axis sum the test computes from the URDF's numbers.
TEST(Reality, PayloadAndInertiaScaleObeyImpulseAndMomentum) {
  SimulatorConfig cfg = box_config();
  cfg.world.ground.enabled = false;
  cfg.world.gravity.setZero();
  cfg.reality.enabled = true;
  cfg.reality.links.inertia_scale = {{"body", 1.3}};
  Payload p;
  p.link = "sole";  // fixed 5 cm above the box's frame
  p.mass = 1.0;
  p.offset = Eigen::Vector3d(0.1, 0.0, 0.0);
  p.inertia = Eigen::Vector3d(0.001, 0.002, 0.002);
  cfg.reality.payloads = {p};

  // The box's URDF inertia (tests/simulator/urdf/box.urdf), about its CoM, in the body frame.
  Eigen::Matrix3d I_urdf;
  I_urdf << 0.0083, 0.001, 0.0, 0.001, 0.0167, 0.0, 0.0, 0.0, 0.0217;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d c_box(0.02, -0.01, 0.0), c_pay(0.1, 0.0, 0.05);
  const double m = 3.0;
  const Eigen::Vector3d c = (2.0 * c_box + 1.0 * c_pay) / m;
  auto steiner = [](double mass, const Eigen::Vector3d& d) {
    return Eigen::Matrix3d(mass *
                           (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose()));
  };
  const Eigen::Matrix3d I = 1.3 * R * I_urdf * R.transpose() + steiner(2.0, c_box - c) +
                            Eigen::Matrix3d(p.inertia.asDiagonal()) + steiner(1.0, c_pay - c);

  // Linear: 10 N at the CoM for 0.1 s.
  {
    SimulatorConfig lin = cfg;
    Push push;
    push.link = "body";
    push.point_L = c;
    push.force_W = Eigen::Vector3d(10.0, 0.0, 0.0);
    push.duration = 0.1;
    lin.pushes = {push};
    Simulator sim(lin);
    EXPECT_NEAR(sim.total_mass(), 3.0, 1e-12);
    const GroundTruth g = run(sim, sim.make_command(), 200);
    EXPECT_NEAR(g.com_vel_W.x(), 10.0 * 0.1 / 3.0, 1e-9);
    EXPECT_NEAR(g.omega_WB.norm(), 0.0, 1e-9) << "a push through the CoM turns nothing";
  }
  // Angular: a couple of 2 x 0.5 N at +-0.1 m about z for 20 ms (small rotation).
  {
    SimulatorConfig ang = cfg;
    Push a, b;
    a.link = b.link = "body";
    a.point_L = Eigen::Vector3d(0.0, 0.1, 0.0);
    b.point_L = Eigen::Vector3d(0.0, -0.1, 0.0);
    a.force_W = Eigen::Vector3d(0.5, 0.0, 0.0);
    b.force_W = -a.force_W;
    a.duration = b.duration = 0.02;
    ang.pushes = {a, b};
    Simulator sim(ang);
    const GroundTruth g = run(sim, sim.make_command(), 20);
    const Eigen::Vector3d tau(0.0, 0.0, -2 * 0.1 * 0.5);
    const Eigen::Vector3d expected = I.inverse() * tau * 0.02;
    EXPECT_NEAR((g.omega_WB - expected).norm(), 0.0, 0.01 * expected.norm())
        << g.omega_WB.transpose() << " vs " << expected.transpose();
    // Without the scale and payload the answer is clearly different (the check can fail).
    const Eigen::Vector3d plain = (R * I_urdf * R.transpose()).inverse() * tau * 0.02;
    EXPECT_GT((plain - expected).norm(), 0.2 * expected.norm());
  }
}

// Actuators: a torque step of 10 N m commanded on one joint of the floating biped comes out
// `delay` ticks later and then as the sampled first-order response 1 - exp(-2 pi f t); a step
// beyond the lowered effort limit is clamped at effort_scale x the URDF's 300 N m.
TEST(Reality, ActuatorTorqueIsDelayedLaggedAndClamped) {
  SimulatorConfig cfg = biped_config();
  cfg.world.ground.enabled = false;
  cfg.world.gravity.setZero();
  cfg.reality.enabled = true;
  cfg.reality.actuators.bandwidth_hz = 25.0;
  cfg.reality.actuators.delay_ticks = 3;
  cfg.reality.actuators.effort_scale = 0.5;
  Simulator sim(cfg);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  JointCommand cmd = sim.make_command();
  cmd.mode = CommandMode::kTorque;
  cmd.tau_ff[0] = 10.0;
  cmd.tau_ff[1] = 1000.0;  // beyond the nominal 300 N m: clamped there, then at 150 N m
  const double dt = sim.dt(), f = 25.0;
  for (int k = 0; k < 120; ++k) {
    sim.step(cmd, s, g);
    // Tick k applies the command of tick k - 3; the lag has then taken m = k - 2 samples of it.
    const int m = k - 3 + 1;
    const double expected = m <= 0 ? 0.0 : 10.0 * (1.0 - std::exp(-2.0 * M_PI * f * dt * m));
    EXPECT_NEAR(s.tau_measured[0], expected, 1e-7) << "tick " << k;
    if (m > 0) {
      EXPECT_LE(std::abs(s.tau_measured[1]), 150.0 + 1e-12);
    }
  }
  EXPECT_NEAR(s.tau_measured[1], 150.0, 1e-9);
  EXPECT_NEAR(s.tau_measured[0], 10.0 * (1.0 - std::exp(-2.0 * M_PI * f * dt * 118)), 1e-7);
}

// Torque noise: the applied torque minus the command has the stated std (absolute plus a
// fraction of the effort limit) and no mean; the noise is the same for the same seed.
TEST(Reality, TorqueNoiseHasItsStatedStd) {
  SimulatorConfig cfg = biped_config();
  cfg.world.ground.enabled = false;
  cfg.world.gravity.setZero();
  cfg.reality.enabled = true;
  cfg.reality.actuators.torque_noise_std = 0.2;
  cfg.reality.actuators.torque_noise_of_effort = 0.001;  // 0.3 N m of 300
  Simulator sim(cfg), twin(cfg);
  SensorFrame s = sim.make_sensor_frame(), s2 = twin.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth(), g2 = twin.make_ground_truth();
  JointCommand cmd = sim.make_command();
  cmd.mode = CommandMode::kTorque;
  double sum = 0.0, sq = 0.0;
  const int N = 2000;
  for (int k = 0; k < N; ++k) {
    sim.step(cmd, s, g);
    twin.step(cmd, s2, g2);
    EXPECT_EQ(s.tau_measured, s2.tau_measured);
    sum += s.tau_measured.sum();
    sq += s.tau_measured.squaredNorm();
  }
  const double n = N * sim.num_joints();
  EXPECT_NEAR(sum / n, 0.0, 4 * 0.5 / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(sq / n), 0.5, 0.5 * 0.03);
}

// Joint friction: reality's Coulomb F and viscous b are the URDF's joint friction and damping
// raised by that much (the same trajectory, to round-off, as a copy of the URDF written with
// friction F and damping 0.5 + b), and a knee driven in free space with 1.5 F turns near the
// speed where they take the torque: qd = (tau - F) / (0.5 + b) (within 10 %: the free-floating
// chain's inertial coupling; without friction it turns 12 times faster).
TEST(Reality, JointFrictionIsTheUrdfsRaisedAndSetsTheSpeed) {
  SimulatorConfig cfg = biped_config();
  cfg.world.ground.enabled = false;
  cfg.world.gravity.setZero();
  SimulatorConfig urdf = cfg;
  cfg.reality.enabled = true;
  cfg.reality.actuators.coulomb_friction = 1.0;
  cfg.reality.actuators.viscous_friction = 1.5;
  {
    std::ifstream in(cfg.robot.urdf_path);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (const auto& [from, to] :
         {std::pair<std::string, std::string>{"damping=\"0.5\"", "damping=\"2\""},
          {"friction=\"0.0\"", "friction=\"1.0\""}})
      for (auto at = text.find(from); at != std::string::npos; at = text.find(from, at))
        text.replace(at, from.size(), to);
    urdf.robot.urdf_path = (std::filesystem::temp_directory_path() /
                            ("poise_reality_friction_" + std::to_string(::getpid()) + ".urdf"))
                               .string();
    std::ofstream(urdf.robot.urdf_path) << text;
  }
  Simulator sim(cfg), same(urdf);
  std::filesystem::remove(urdf.robot.urdf_path);
  const int knee =
      static_cast<int>(std::find(sim.joint_names().begin(), sim.joint_names().end(), "l_knee") -
                       sim.joint_names().begin());
  ASSERT_LT(knee, sim.num_joints());
  for (const std::string& note : sim.notes())  // the explicit step's limit leaves the knee be
    ASSERT_EQ(note.find("'l_knee'"), std::string::npos) << note;
  SensorFrame s = sim.make_sensor_frame(), s2 = same.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth(), g2 = same.make_ground_truth();
  JointCommand cmd = sim.make_command();
  cmd.mode = CommandMode::kTorque;
  cmd.tau_ff[knee] = 1.5;
  double mean = 0.0;
  for (int k = 0; k < 300; ++k) {
    sim.step(cmd, s, g);
    same.step(cmd, s2, g2);
    ASSERT_NEAR((s.qd - s2.qd).norm(), 0.0, 1e-12) << "tick " << k;
    if (k >= 200) mean += s.qd[knee] / 100;
  }
  const double expected = (1.5 - 1.0) / (0.5 + 1.5);
  EXPECT_NEAR(mean, expected, 0.1 * expected);
}

// A compliant ground: the box rests sunk by its weight over 4 corner springs, m g / (4 k),
// below where it rests on the rigid ground; the damping settles it.
TEST(Reality, ACompliantGroundSinksByTheLoadOverItsStiffness) {
  SimulatorConfig cfg = box_config();
  Simulator rigid(cfg);
  const GroundTruth g0 = run(rigid, rigid.make_command(), 1500);
  for (const double k : {2e4, 1e5}) {
    SimulatorConfig soft = cfg;
    soft.reality.enabled = true;
    soft.reality.ground.stiffness = k;
    soft.reality.ground.damping = 2.0 * std::sqrt(k * 0.5);  // critical for 0.5 kg a corner
    Simulator sim(soft);
    const GroundTruth g = run(sim, sim.make_command(), 1500);
    const double sink = g0.X_WB.translation().z() - g.X_WB.translation().z();
    EXPECT_EQ(g.feet[0].num_points, 4);
    EXPECT_NEAR(sink, 2.0 * 9.81 / (4 * k), 0.05 * 2.0 * 9.81 / (4 * k)) << "k " << k;
    EXPECT_LT(g.com_vel_W.norm(), 1e-4);
  }
}

// A compliant ground holds a resting box against a sideways force below its friction as the
// rigid ground does: no creep (the box moves less than 0.5 mm in 1 s of 0.5 mu m g).
TEST(Reality, ACompliantGroundHoldsAStaticFrictionLoadWithoutCreep) {
  for (const double k : {0.0, 7.5e4, 2e4}) {
    SimulatorConfig c = box_config();
    c.world.ground.friction = 0.6;
    if (k > 0.0) {
      c.reality.enabled = true;
      c.reality.ground.stiffness = k;
      c.reality.ground.damping = 1e3;
    }
    Simulator probe(c);
    const GroundTruth rest = run(probe, probe.make_command(), 300);
    Push p;
    p.link = "body";
    p.point_L = Eigen::Vector3d(0.02, -0.01, -0.03);
    p.force_W = Eigen::Vector3d(0.5 * 0.6 * 2.0 * 9.81, 0.0, 0.0);
    p.start = 0.3;
    p.duration = 1.0;
    c.pushes = {p};
    Simulator sim(c);
    const GroundTruth g = run(sim, sim.make_command(), 1300);
    EXPECT_LT((g.com_W - rest.com_W).head<2>().norm(), 5e-4) << "stiffness " << k;
  }
}

// Ground friction drawn in a range replaces the world's: the box, pushed sideways with 0.9 of
// mu m g, stays; with 1.1 of it, it slides.
TEST(Reality, DrawnGroundFrictionDecidesWhenTheBoxSlides) {
  SimulatorConfig cfg = box_config();
  cfg.world.ground.friction = 5.0;  // replaced by the draw
  cfg.reality.enabled = true;
  cfg.reality.ground.friction_min = 0.3;
  cfg.reality.ground.friction_max = 0.5;
  cfg.reality.seed = 11;
  const double mu = Simulator(cfg).reality().ground_friction;
  ASSERT_GE(mu, 0.3);
  ASSERT_LE(mu, 0.5);
  cfg.reality.seed = 12;
  EXPECT_NE(Simulator(cfg).reality().ground_friction, mu);
  cfg.reality.seed = 11;
  for (const double fraction : {0.9, 1.1}) {
    SimulatorConfig c = cfg;
    Simulator probe(c);
    const GroundTruth rest = run(probe, probe.make_command(), 300);
    Push p;
    p.link = "body";
    p.point_L = Eigen::Vector3d(0.02, -0.01, -0.03);  // low, near the CoM: no tipping
    p.force_W = Eigen::Vector3d(fraction * mu * 2.0 * 9.81, 0.0, 0.0);
    p.start = 0.3;
    p.duration = 0.5;
    c.pushes = {p};
    Simulator sim(c);
    const GroundTruth g = run(sim, sim.make_command(), 800);
    const double moved = (g.com_W - rest.com_W).head<2>().norm();
    if (fraction < 1.0)
      EXPECT_LT(moved, 1e-3) << "mu " << mu;
    else
      EXPECT_GT(moved, 0.02) << "mu " << mu;
  }
}

}  // namespace
}  // namespace poise::sim
