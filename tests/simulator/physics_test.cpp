// Physical sanity of the Bullet simulator (issue section 7): free fall, resting normal force,
// impulse-momentum, lockstep determinism; plus kinematics against an independent URDF chain.
#include <gtest/gtest.h>
#include <cstdint>
#include <sstream>
#include <fstream>
#include <filesystem>

#include <urdf_parser/urdf_parser.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "poise/sim/simulator.hpp"
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

using test::biped_config;
using test::biped_lying_on_back_config;
using test::box_config;

// Holds the biped posture with stiff PD around its initial joint angles.
using test::hold_command;

// A link that collides through a <mesh> (most public humanoid URDFs: Unitree's, all of their
// links) collides as the mesh's convex hull. The biped's torso box (0.2 x 0.3 x 0.4 m) replaced
// by an STL of the same box (binary; and an ASCII unit cube with <mesh scale>): lying on its
// back, the biped rests where it rests on the box, within 1 mm; so does a COLLADA file of the
// box in decimetres placed by a node. Before, meshes were ignored and the torso sank into the
// ground until the pelvis held it. A mesh that cannot be read is refused.
TEST(SimPhysics, AMeshCollidesAsItsConvexHull) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(POISE_BINARY_DIR) / "test_output" / "sim_mesh";
  fs::create_directories(dir);
  // The 12 triangles of a box of half extents h (binary STL), or of the unit cube (ASCII).
  const auto corner = [](int k, const Eigen::Vector3d& h) {
    return Eigen::Vector3d((k & 1 ? 1 : -1) * h.x(), (k & 2 ? 1 : -1) * h.y(),
                           (k & 4 ? 1 : -1) * h.z());
  };
  const int tri[12][3] = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}, {0, 4, 5}, {0, 5, 1},
                          {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
  {
    std::ofstream bin(dir / "torso.stl", std::ios::binary);
    const std::string header(80, ' ');
    bin.write(header.data(), 80);
    const std::uint32_t n = 12;
    bin.write(reinterpret_cast<const char*>(&n), 4);
    for (const auto& t : tri) {
      float f[12] = {0, 0, 0};
      for (int v = 0; v < 3; ++v) {
        const Eigen::Vector3d p = corner(t[v], Eigen::Vector3d(0.1, 0.15, 0.2));
        for (int a = 0; a < 3; ++a) f[3 + 3 * v + a] = static_cast<float>(p[a]);
      }
      bin.write(reinterpret_cast<const char*>(f), 48);
      const std::uint16_t attr = 0;
      bin.write(reinterpret_cast<const char*>(&attr), 2);
    }
    std::ofstream ascii(dir / "cube.stl");
    ascii << "solid cube\n";
    for (const auto& t : tri) {
      ascii << " facet normal 0 0 0\n  outer loop\n";
      for (int v = 0; v < 3; ++v) {
        const Eigen::Vector3d p = corner(t[v], Eigen::Vector3d::Ones());
        ascii << "   vertex " << p.x() << " " << p.y() << " " << p.z() << "\n";
      }
      ascii << "  endloop\n endfacet\n";
    }
    ascii << "endsolid cube\n";
    // The same box as COLLADA: its 8 corners in decimetres, shifted by 1 dm in x, which the
    // node's <translate> takes back.
    std::ofstream dae(dir / "torso.dae");
    dae << "<?xml version=\"1.0\"?>\n<COLLADA><asset><unit meter=\"0.1\"/><up_axis>Y_UP</up_axis>"
           "</asset><library_geometries><geometry id=\"box\"><mesh><source id=\"p\">"
           "<float_array id=\"pa\" count=\"24\">";
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d p = 10.0 * corner(k, Eigen::Vector3d(0.1, 0.15, 0.2));
      dae << p.x() + 1.0 << " " << p.y() << " " << p.z() << " ";
    }
    dae << "</float_array><technique_common><accessor source=\"#pa\" count=\"8\" stride=\"3\"/>"
           "</technique_common></source><vertices id=\"v\"><input semantic=\"POSITION\" "
           "source=\"#p\"/></vertices></mesh></geometry></library_geometries>"
           "<library_visual_scenes><visual_scene id=\"s\"><node><translate>-1 0 0</translate>"
           "<instance_geometry url=\"#box\"/></node></visual_scene></library_visual_scenes>"
           "<scene><instance_visual_scene url=\"#s\"/></scene></COLLADA>\n";
  }
  std::stringstream text;
  text << std::ifstream(test::urdf("biped.urdf")).rdbuf();
  const std::string box = "<box size=\"0.2 0.3 0.4\"/>";
  const auto variant = [&](const std::string& name, const std::string& geometry) {
    std::string u = text.str();
    const auto at = u.find(box);
    EXPECT_NE(at, std::string::npos);
    u.replace(at, box.size(), geometry);
    std::ofstream(dir / name) << u;
    return (dir / name).string();
  };
  const auto rest_height = [&](const std::string& urdf_path) {
    SimulatorConfig cfg = biped_lying_on_back_config();
    cfg.robot.urdf_path = urdf_path;
    Simulator sim(cfg);
    SensorFrame s = sim.make_sensor_frame();
    GroundTruth g = sim.make_ground_truth();
    const JointCommand cmd = test::damping_command(sim, 2.0);
    for (int k = 0; k < 2500; ++k)
      sim.step(cmd, s, g);
    EXPECT_LT(g.com_vel_W.norm(), 1e-2) << urdf_path;
    return g.X_WB.translation().z();
  };
  const double on_box = rest_height(test::urdf("biped.urdf"));
  const double on_mesh = rest_height(variant("mesh.urdf", "<mesh filename=\"torso.stl\"/>"));
  const double on_scaled = rest_height(variant(
      "scaled.urdf", "<mesh filename=\"package://biped/cube.stl\" scale=\"0.1 0.15 0.2\"/>"));
  const double on_dae = rest_height(variant("dae.urdf", "<mesh filename=\"torso.dae\"/>"));
  EXPECT_NEAR(on_mesh, on_box, 1e-3);
  EXPECT_NEAR(on_scaled, on_box, 1e-3);
  EXPECT_NEAR(on_dae, on_box, 1e-3);
  std::printf("base height lying on the torso: box %.4f m, STL %.4f m, scaled ASCII STL %.4f m, "
              "COLLADA %.4f m\n",
              on_box, on_mesh, on_scaled, on_dae);
  // A collision mesh the simulator cannot read is refused, naming the link and the file (it
  // used to be skipped: the link then had no collision at all), as `poise model info` and
  // `poise robot init` refuse it: missing, not a regular file, empty, a zero scale.
  std::ofstream(dir / "empty.stl").close();
  for (const auto& [geometry, words] :
       std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"<mesh filename=\"no_such_torso.stl\"/>", {"'torso'", "no_such_torso.stl", "not found"}},
           {"<mesh filename=\"/dev/zero\"/>", {"'torso'", "/dev/zero", "not found"}},
           {"<mesh filename=\"empty.stl\"/>", {"'torso'", "empty.stl"}},
           {"<mesh filename=\"torso.stl\" scale=\"0 0 0\"/>", {"'torso'", "scale"}}}) {
    SimulatorConfig cfg = biped_lying_on_back_config();
    cfg.robot.urdf_path = variant("bad_mesh.urdf", geometry);
    std::string error;
    try {
      Simulator sim(cfg);
    } catch (const std::exception& e) {
      error = e.what();
    }
    for (const std::string& w : words) EXPECT_NE(error.find(w), std::string::npos) << geometry << ": " << error;
  }
}

// URDF joint damping and friction are explicit torques in the simulator's step; on a link too
// light for them (a hand's finger: Valkyrie's last phalanges, 6 g, damping and friction 0.5)
// they blew the whole robot up within 15 ms. The simulator scales them down to what the joint
// moves takes in one step, I / dt, I its articulated inertia about the axis (the joints below
// it free, its parent held), and says so. A two-link finger on the biped's torso, both joints
// about y: the I of each note against the closed form of the chain (M11 - M12^2 / M22, M22);
// the biped lying on its back with zero joint torques stays finite, its fingers slow; the
// biped's own joints (heavier links, damping 0.5) are left as they are.
TEST(SimPhysics, AJointDampingTooStrongForItsLightLinkIsScaledToWhatTheStepTakes) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(POISE_BINARY_DIR) / "test_output" / "sim_finger";
  fs::create_directories(dir);
  const double ma = 0.02, ca = 0.02, la = 0.04, Ia = 2e-6;  // proximal: mass, COM, length, Iyy
  const double mb = 0.01, cb = 0.015, Ib = 6e-7;            // distal
  std::stringstream text;
  text << std::ifstream(test::urdf("biped.urdf")).rdbuf();
  std::string u = text.str();
  char finger[2048];
  std::snprintf(finger, sizeof finger, R"(
  <link name="fa"><inertial><origin xyz="%g 0 0"/><mass value="%g"/>
    <inertia ixx="1e-6" ixy="0" ixz="0" iyy="%g" iyz="0" izz="1e-6"/></inertial></link>
  <link name="fb"><inertial><origin xyz="%g 0 0"/><mass value="%g"/>
    <inertia ixx="5e-7" ixy="0" ixz="0" iyy="%g" iyz="0" izz="5e-7"/></inertial></link>
  <joint name="f1" type="revolute"><parent link="torso"/><child link="fa"/>
    <origin xyz="0.12 0 0.1" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="1" velocity="10"/><dynamics damping="0.5" friction="0.5"/></joint>
  <joint name="f2" type="revolute"><parent link="fa"/><child link="fb"/>
    <origin xyz="%g 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="1" velocity="10"/><dynamics damping="0.5" friction="0.5"/></joint>
)", ca, ma, Ia, cb, mb, Ib, la);
  u.insert(u.rfind("</robot>"), finger);
  std::ofstream(dir / "finger.urdf") << u;

  SimulatorConfig cfg = biped_lying_on_back_config();
  cfg.robot.urdf_path = (dir / "finger.urdf").string();
  Simulator sim(cfg);
  const double M22 = Ib + mb * cb * cb;
  const double M12 = Ib + mb * cb * (la + cb);
  const double M11 = Ia + ma * ca * ca + Ib + mb * (la + cb) * (la + cb);
  const std::pair<std::string, double> expected[] = {{"'f1'", M11 - M12 * M12 / M22},
                                                     {"'f2'", M22}};
  ASSERT_EQ(sim.notes().size(), 2u) << (sim.notes().empty() ? "" : sim.notes()[0]);
  for (const auto& [name, inertia] : expected) {
    const std::string* note = nullptr;
    for (const std::string& n : sim.notes())
      if (n.find(name) != std::string::npos) note = &n;
    ASSERT_NE(note, nullptr) << name;
    const auto at = note->find("moves (");
    ASSERT_NE(at, std::string::npos) << *note;
    const double printed = std::stod(note->substr(at + 7));
    EXPECT_NEAR(printed, inertia, 1e-5 * inertia) << *note;
    std::printf("%s: articulated inertia %.6g kg m^2 (closed form %.6g)\n", name.c_str(), printed,
                inertia);
  }
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  JointCommand cmd = sim.make_command();
  cmd.mode = CommandMode::kTorque;
  cmd.tau_ff.setZero();
  std::vector<int> fingers;
  for (int j = 0; j < sim.num_joints(); ++j)
    if (sim.joint_names()[j] == "f1" || sim.joint_names()[j] == "f2") fingers.push_back(j);
  ASSERT_EQ(fingers.size(), 2u);
  double fastest = 0.0, base_speed = 0.0;
  for (int k = 0; k < 2000; ++k) {
    sim.step(cmd, s, g);
    ASSERT_TRUE(s.qd.allFinite() && g.X_WB.translation().allFinite()) << "tick " << k;
    if (k < 1000) continue;
    for (int j : fingers) fastest = std::max(fastest, std::abs(s.qd[j]));
    base_speed = std::max(base_speed, g.com_vel_W.norm());
  }
  std::printf("over the last second: fastest finger joint %.3g rad/s, CoM speed %.3g m/s; base "
              "at %.4f m\n", fastest, base_speed, g.X_WB.translation().z());
  // Bounded, not blown up: with I / dt of damping the finger creeps down under its weight at
  // about its gravity torque over I / dt (~0.7 rad/s; the URDF's damping would hold it at ~2e-4),
  // until its joint limit stops it.
  EXPECT_LT(fastest, 1.0);
  EXPECT_LT(base_speed, 0.05);
  EXPECT_LT(g.X_WB.translation().z(), 0.3);
  // The biped alone: nothing to scale.
  EXPECT_TRUE(Simulator(biped_lying_on_back_config()).notes().empty());
}

TEST(SimPhysics, FreeFallingRobotAcceleratesAtG) {
  for (const bool biped : {false, true}) {
    SimulatorConfig cfg = biped ? biped_config() : box_config();
    cfg.world.ground.enabled = false;
    cfg.initial.base_linear_velocity = Eigen::Vector3d(0.3, -0.2, 0.5);
    Simulator sim(cfg);
    SensorFrame s = sim.make_sensor_frame();
    GroundTruth g = sim.make_ground_truth();
    sim.read(s, g);
    const Eigen::Vector3d c0 = g.com_W, v0 = g.com_vel_W;
    // Internal joint torques (PD posture + URDF damping) must not change the CoM motion.
    JointCommand cmd = hold_command(sim, s, 200.0, 5.0);
    cmd.q_ref.array() += 0.2;
    const int steps = 400;
    for (int k = 0; k < steps; ++k)
      sim.step(cmd, s, g);
    const double t = steps * sim.dt();
    const Eigen::Vector3d gvec = cfg.world.gravity;
    // A rigid body falls exactly; an articulated one with moving joints only up to the
    // discretisation of its internal (Coriolis) terms, well below 0.1 % of g t.
    const double tol = biped ? 1e-3 * 9.81 * t : 1e-9;
    EXPECT_NEAR((g.com_vel_W - v0 - gvec * t).norm(), 0.0, tol) << "biped=" << biped;
    // Semi-implicit Euler: x_N = x_0 + v_0 t + g dt^2 N(N+1)/2
    const Eigen::Vector3d expected =
        c0 + v0 * t + gvec * sim.dt() * sim.dt() * steps * (steps + 1) / 2.0;
    EXPECT_NEAR((g.com_W - expected).norm(), 0.0, tol * t) << "biped=" << biped;
    // And close to the continuous-time parabola (1/2 g t^2) within the O(dt) integration error.
    EXPECT_NEAR((g.com_W - (c0 + v0 * t + 0.5 * gvec * t * t)).norm(), 0.0,
                0.5 * 9.81 * sim.dt() * t + 1e-9);
    EXPECT_EQ(g.num_non_foot_contacts, 0);
    for (const auto& f : g.feet)
      EXPECT_FALSE(f.in_contact);
  }
}

TEST(SimPhysics, PassiveRobotLyingOnGroundCarriesItsWeight) {
  Simulator sim(biped_lying_on_back_config());
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  const JointCommand cmd = test::damping_command(sim, 2.0);
  for (int k = 0; k < 2500; ++k)
    sim.step(cmd, s, g);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  const int window = 500;
  for (int k = 0; k < window; ++k) {
    sim.step(cmd, s, g);
    mean += g.total_contact_force_W / window;
  }
  const double mg = sim.total_mass() * 9.81;
  EXPECT_NEAR(mean.z(), mg, 0.01 * mg);
  EXPECT_NEAR(mean.head<2>().norm(), 0.0, 0.01 * mg);
  EXPECT_GT(g.num_non_foot_contacts, 0) << "the trunk lies on the ground";
  EXPECT_LT(g.com_vel_W.norm(), 1e-2);
}

// The trunk and legs of the robot falling onto its back reach the ground through the ground's
// finite broadphase box exactly as through Bullet's infinite one (solver.ground_aabb_band).
TEST(SimPhysics, GroundBroadphaseBandKeepsNonFootContacts) {
  std::vector<std::vector<std::uint8_t>> touching[2];
  std::vector<Eigen::Vector3d> force[2];
  for (int run = 0; run < 2; ++run) {
    SimulatorConfig cfg = biped_lying_on_back_config();
    if (run == 1) cfg.solver.ground_aabb_band = 0.0;
    Simulator sim(cfg);
    SensorFrame s = sim.make_sensor_frame();
    GroundTruth g = sim.make_ground_truth();
    const JointCommand cmd = test::damping_command(sim, 2.0);
    for (int k = 0; k < 600; ++k) {
      sim.step(cmd, s, g);
      touching[run].push_back(g.non_foot_contact);
      force[run].push_back(g.total_contact_force_W);
    }
  }
  int non_foot_ticks = 0;
  double force_diff = 0.0;
  for (std::size_t k = 0; k < touching[0].size(); ++k) {
    EXPECT_EQ(touching[0][k], touching[1][k]) << "tick " << k;
    non_foot_ticks += std::count(touching[0][k].begin(), touching[0][k].end(), 1) > 0;
    force_diff = std::max(force_diff, (force[0][k] - force[1][k]).norm());
  }
  EXPECT_GT(non_foot_ticks, 300) << "the robot lies on non-foot links";
  EXPECT_LT(force_diff, 1e-6);
}

// A body resting flat on a level platform that translates back and forth is carried by it with
// its contact intact every step. Bullet drops a compound child's contact manifold when the
// child's box and the other shape's box stop overlapping; a sole flat on a level platform touches
// the platform's box exactly at its top face, so before the padded platform box the contact
// vanished for single steps (zero force, then a penetration spike).
TEST(SimPhysics, LevelMovingPlatformCarriesARestingBodyWithoutContactDropouts) {
  SimulatorConfig cfg = box_config();
  cfg.world.ground.enabled = true;
  PlatformConfig p;
  p.foot = "box";
  p.friction = 1.0;
  p.half_extents = Eigen::Vector3d(0.4, 0.3, 0.05);
  p.translation_axis = Eigen::Vector3d::UnitX();
  p.translation.amplitude = 0.2;  // 0.2 m at 0.5 Hz: up to 2 m/s^2, inside the friction cone
  p.translation.frequency = 0.5;
  p.motion_start = 0.5;
  p.motion_ramp = 1.0;
  cfg.world.platforms = {p};
  Simulator sim(cfg);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  JointCommand cmd = sim.make_command();
  const double mg = sim.total_mass() * 9.81;
  for (int k = 0; k < 300; ++k)  // settle
    sim.step(cmd, s, g);
  ASSERT_TRUE(g.feet[0].in_contact);
  const Eigen::Vector3d offset = g.feet[0].X_WF.translation() - g.platform_X_WP[0].translation();
  int dropouts = 0, first_dropout = -1;
  double max_fz_error = 0.0, max_slip = 0.0, max_platform_speed = 0.0;
  for (int k = 300; k < 4500; ++k) {
    sim.step(cmd, s, g);
    const double fz = g.feet[0].force_W.z();
    if (!g.feet[0].in_contact || fz < 0.5 * mg) {
      if (dropouts++ == 0) first_dropout = k;
    }
    // Vertical force: weight; the platform moves horizontally only.
    max_fz_error = std::max(max_fz_error, std::abs(fz - mg));
    const Eigen::Vector3d rel = g.feet[0].X_WF.translation() - g.platform_X_WP[0].translation();
    max_slip = std::max(max_slip, (rel - offset).norm());
    if (k > 0) max_platform_speed = std::max(max_platform_speed, std::abs(g.feet[0].v_WF.x()));
  }
  std::printf(
      "dropouts %d, max |fz - mg| %.4f N (mg %.2f N), max slip %.2e m, max speed %.3f m/s\n",
      dropouts, max_fz_error, mg, max_slip, max_platform_speed);
  EXPECT_EQ(dropouts, 0) << "first at tick " << first_dropout;
  EXPECT_LT(max_fz_error, 0.05 * mg);
  EXPECT_LT(max_slip, 1e-3);
  EXPECT_GT(max_platform_speed, 0.5) << "the platform moved the body";
}

TEST(SimPhysics, PushChangesMomentumByForceTimesDuration) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 3; ++trial) {
    SimulatorConfig cfg = trial == 2 ? biped_config() : box_config();
    cfg.world.ground.enabled = false;
    cfg.world.gravity = trial == 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(0, 0, -9.81);
    Push p;
    p.link = trial == 2 ? "torso" : "body";
    p.point_L = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.1;
    p.force_W = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 120.0;
    p.start = 0.05;
    p.duration = 0.1;
    cfg.pushes = {p};
    Simulator sim(cfg);
    SensorFrame s = sim.make_sensor_frame();
    GroundTruth g = sim.make_ground_truth();
    sim.read(s, g);
    const double m = sim.total_mass();
    const Eigen::Vector3d l0 = m * g.com_vel_W;
    JointCommand cmd = sim.make_command();
    const int steps = 250;
    for (int k = 0; k < steps; ++k)
      sim.step(cmd, s, g);
    const Eigen::Vector3d dl = m * g.com_vel_W - l0;
    const Eigen::Vector3d expected =
        p.force_W * p.duration + m * cfg.world.gravity * steps * sim.dt();
    // exact for the rigid box; within 0.1 % for the articulated biped (see free fall)
    const double tol = trial == 2 ? 1e-3 * expected.norm() : 1e-9 * expected.norm() + 1e-12;
    EXPECT_NEAR((dl - expected).norm(), 0.0, tol) << "trial " << trial;
  }
}

TEST(SimPhysics, LiveAndScheduledPushesAgree) {
  SimulatorConfig cfg = box_config();
  cfg.world.ground.enabled = false;
  cfg.world.gravity.setZero();
  Push p{"sole", Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d(0, 30, 0), 0.01, 0.02};
  SimulatorConfig cfg2 = cfg;
  cfg2.pushes = {p};
  Simulator a(cfg), b(cfg2);
  ASSERT_TRUE(a.add_push(p));
  EXPECT_FALSE(a.add_push(Push{"no_such_link", {}, {}, 0, 1}));
  SensorFrame s = a.make_sensor_frame();
  GroundTruth ga = a.make_ground_truth(), gb = b.make_ground_truth();
  JointCommand cmd = a.make_command();
  for (int k = 0; k < 50; ++k) {
    a.step(cmd, s, ga);
    b.step(cmd, s, gb);
  }
  EXPECT_EQ(ga.X_WB.matrix(), gb.X_WB.matrix());
  EXPECT_NEAR(ga.com_vel_W.y() * a.total_mass(), 30 * 0.02, 1e-9);
  EXPECT_GT(ga.omega_WB.norm(), 0.1) << "an off-centre push also spins the box";
}

void run_scenario(GroundTruth& g, std::vector<double>& trace) {
  SimulatorConfig cfg = biped_config();
  cfg.pushes = {Push{"torso", Eigen::Vector3d(0, 0, 0.2), Eigen::Vector3d(60, 20, 0), 0.2, 0.1}};
  cfg.imu.gyro_noise_std = 0.01;
  cfg.imu.accel_noise_std = 0.1;
  cfg.imu.seed = 7;
  Simulator sim(cfg);
  SensorFrame s = sim.make_sensor_frame();
  g = sim.make_ground_truth();
  sim.read(s, g);
  JointCommand cmd = hold_command(sim, s, 400.0, 10.0);
  for (int k = 0; k < 600; ++k) {
    sim.step(cmd, s, g);
    trace.insert(trace.end(), g.X_WB.matrix().data(), g.X_WB.matrix().data() + 16);
    trace.insert(trace.end(), g.com_W.data(), g.com_W.data() + 3);
    for (const auto& f : g.feet)
      trace.insert(trace.end(), f.force_W.data(), f.force_W.data() + 3);
    trace.insert(trace.end(), s.q.data(), s.q.data() + s.q.size());
    trace.insert(trace.end(), s.imu_specific_force_I.data(), s.imu_specific_force_I.data() + 3);
  }
}

TEST(SimPhysics, LockstepRunsAreBitIdentical) {
  GroundTruth g1, g2;
  std::vector<double> t1, t2;
  run_scenario(g1, t1);
  run_scenario(g2, t2);
  ASSERT_EQ(t1.size(), t2.size());
  std::size_t first_diff = t1.size();
  for (std::size_t i = 0; i < t1.size(); ++i)
    if (std::memcmp(&t1[i], &t2[i], sizeof(double)) != 0) {
      first_diff = i;
      break;
    }
  EXPECT_EQ(first_diff, t1.size()) << "first differing value at index " << first_diff;
  // the run is not trivially static: the push moved the robot
  EXPECT_GT(std::abs(t1[16 * 0 + 12] - t1[t1.size() / 2]), 0.0);
}

// Independent forward kinematics: compose the URDF joint transforms directly with urdfdom.
Eigen::Isometry3d urdf_fk(const urdf::ModelInterface& model, const std::string& link_name,
                          const Eigen::Isometry3d& X_WB, const std::map<std::string, double>& q) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  urdf::LinkConstSharedPtr link = model.getLink(link_name);
  while (link->parent_joint) {
    const urdf::Joint& j = *link->parent_joint;
    const auto& p = j.parent_to_joint_origin_transform;
    Eigen::Isometry3d Xj = Eigen::Isometry3d::Identity();
    Xj.linear() = Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z)
                      .toRotationMatrix();
    Xj.translation() << p.position.x, p.position.y, p.position.z;
    Eigen::Isometry3d Xq = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d axis(j.axis.x, j.axis.y, j.axis.z);
    if (j.type == urdf::Joint::REVOLUTE || j.type == urdf::Joint::CONTINUOUS)
      Xq.linear() = Eigen::AngleAxisd(q.at(j.name), axis).toRotationMatrix();
    else if (j.type == urdf::Joint::PRISMATIC)
      Xq.translation() = axis * q.at(j.name);
    X = Xj * Xq * X;
    link = model.getLink(j.parent_link_name);
  }
  return X_WB * X;
}

TEST(SimPhysics, LinkPosesMatchIndependentUrdfKinematics) {
  SimulatorConfig cfg = biped_config();
  cfg.world.ground.enabled = false;
  Simulator sim(cfg);
  auto model = urdf::parseURDFFile(cfg.robot.urdf_path);
  ASSERT_TRUE(model);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd q(sim.num_joints());
    std::map<std::string, double> qm;
    for (int i = 0; i < q.size(); ++i) {
      q[i] = u(rng);
      qm[sim.joint_names()[static_cast<std::size_t>(i)]] = q[i];
    }
    Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
    X_WB.linear() = Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), 1.0).normalized())
                        .toRotationMatrix();
    X_WB.translation() << u(rng), u(rng), 1.0 + u(rng);
    sim.set_state(X_WB, q);
    for (const char* link : {"pelvis", "imu_link", "l_sole", "r_sole", "l_shank", "r_thigh"}) {
      const Eigen::Isometry3d expected = urdf_fk(*model, link, X_WB, qm);
      const Eigen::Isometry3d got = sim.frame_pose(link);
      EXPECT_LT((got.matrix() - expected.matrix()).norm(), 1e-9) << link;
    }
  }
}

}  // namespace
}  // namespace poise::sim
