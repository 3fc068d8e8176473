// `poise sim SCENARIO`: runs the simulator alone on a scenario, the joints held by PD at the
// initial posture (no balance controller, no DDS). For checking scenario files and the physics:
// the verdict shows what the bare robot does under the scenario's disturbances.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <string>

#include "poise/sim/world.hpp"
#include "poise/sim/simulator.hpp"
#include "poise/cli/parse.hpp"

namespace poise::sim {

int sim_cli_main(int argc, char** argv) {
  CLI::App app{
      "Run the Bullet simulator alone on a scenario: joints held by PD at the initial "
      "posture, no balance controller. Prints progress and the scenario monitor's verdict."};
  std::string file;
  double kp = 400.0, kd = 10.0, duration = -1.0;
  bool quiet = false;
  app.add_option("scenario", file, "scenario YAML file")->required();
  app.add_option("--kp", kp, "PD stiffness for every joint [N m/rad]");
  app.add_option("--kd", kd, "PD damping for every joint [N m s/rad]");
  app.add_option("--duration", duration, "override the scenario duration [s]");
  app.add_flag("-q,--quiet", quiet, "only the verdict line");
  POISE_CLI_PARSE(app, argc, argv);
  try {
    const World sc = load_world(file);
    Simulator sim(sc.sim);
    SensorFrame s = sim.make_sensor_frame();
    GroundTruth g = sim.make_ground_truth();
    sim.read(s, g);
    JointCommand cmd = sim.make_command();
    cmd.mode = CommandMode::kPd;
    cmd.q_ref = s.q;
    cmd.kp.setConstant(kp);
    cmd.kd.setConstant(kd);
    ScenarioMonitor monitor(sc, platforms_of_feet(sc));
    monitor.update(g);
    const double T = duration > 0.0 ? duration : sc.duration;
    const auto steps = static_cast<long>(T / sim.dt() + 0.5);
    if (!quiet)
      std::printf("%s: %d joints, %.2f kg, CoM (%.3f, %.3f, %.3f) m\n", sc.name.c_str(),
                  sim.num_joints(), sim.total_mass(), g.com_W.x(), g.com_W.y(), g.com_W.z());
    for (long k = 0; k < steps; ++k) {
      sim.step(cmd, s, g);
      monitor.update(g);
      if (!quiet && (k + 1) % 500 == 0) {
        std::printf("  t=%6.2f s  CoM (%.3f, %.3f, %.3f)  foot Fz", g.time, g.com_W.x(),
                    g.com_W.y(), g.com_W.z());
        for (const auto& f : g.feet)
          std::printf(" %7.1f", f.force_W.z());
        std::printf("  non-foot contacts %d\n", g.num_non_foot_contacts);
      }
    }
    const auto r = monitor.result();
    std::printf(
        "%s %s: com_error_max %.3f m, com_error_final %.3f m, foot_slip_max %.4f m, "
        "non_foot_contact_ticks %d\n",
        r.survived ? "SURVIVED" : "FAILED", sc.name.c_str(), r.com_error_max_m, r.com_error_final_m,
        r.foot_slip_max_m, r.non_foot_contacts);
    return r.survived ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise sim: %s\n", e.what());
    return 2;
  }
}

}  // namespace poise::sim
