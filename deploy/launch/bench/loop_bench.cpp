// poise-bench-loop [SCENARIO] [--duration S] [--skip-distributed] [--verbose]
// poise-bench-loop --realtime ...   (real time, distributed, against the targets: realtime_bench.cpp)
//
// Measures, in one run:
//  1. the in-process loop: simulator -> estimator -> controller phase A -> contact optimiser ->
//     phase B -> simulator, with the SAME IDL conversions as the nodes but no DDS (the baseline);
//  2. the distributed lockstep loop: `poise-launch SCENARIO` (four processes, Cyclone DDS on
//     loopback) and its sensor -> command tick latency (p50/p99/max);
// and prints the realtime factors (simulated time / wall time) and the DDS overhead per tick, and
// the CPU time and context switches per tick of all the processes of the distributed run (less
// sensitive to other load on the machine than the wall time).
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "poise/contact_node/contact_messages.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/controller_node/controller_messages.hpp"
#include "poise/estimator/estimator.hpp"
#include "poise/estimator_node/estimator_messages.hpp"
#include "poise/node/compute_stats.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/node/tick_timer.hpp"
#include "poise/sim_node/sim_messages.hpp"
#include "realtime_bench.hpp"

namespace {

using namespace poise;
namespace fs = std::filesystem;

struct InProcessResult {
  double realtime_factor = 0.0;
  double us_per_tick = 0.0;
  bool survived = false;
  double com_error_max = 0.0;
};

InProcessResult run_in_process(const std::string& file, double duration, bool verbose,
                               int settle_ticks) {
  const sim::World sc = sim::load_world(file);
  sim::Simulator sim(sc.sim);
  const auto feet = sim_node::foot_order(sim);
  const model::RobotConfig robot = model::load_robot_config(
      sc.robot_config.empty() ? node::default_robot_config() : sc.robot_config.string());
  const model::Model model = model::load_robot_model(robot);
  const std::vector<int> map = node::model_to_wire_map(sim.joint_names(), model.joint_names);

  estimator::Estimator est(model, robot);
  estimator::SensorFrame frame = est.make_sensor_frame();
  estimator::EstimatorState est_state = est.make_state();
  controller::BalanceController ctrl(model, robot, controller::ControllerConfig{});
  controller::RobotState state = ctrl.make_state();
  const controller::BalanceReference reference = ctrl.make_reference();
  controller::JointCommand command = ctrl.make_command();
  contact::ContactOptimizer optimizer;
  contact::ContactProblem problem, problem_in;
  contact::ContactSolution solution, solution_in;

  sim::ScenarioMonitor monitor(sc, sim::platforms_of_feet(sc));
  sim_node::SlipTracker slip(sim::platforms_of_feet(sc));
  sim::SensorFrame sensors = sim.make_sensor_frame();
  sim::GroundTruth truth = sim.make_ground_truth();
  sim::JointCommand sim_cmd = sim.make_command();
  sim_node::settle(sim, settle_ticks, sensors, truth);
  monitor.update(truth);

  auto m_sensors = std::make_unique<msg::Sensors>();
  auto m_state = std::make_unique<msg::State>();
  auto m_problem = std::make_unique<msg::ContactProblem>();
  auto m_solution = std::make_unique<msg::ContactSolution>();
  auto m_command = std::make_unique<msg::JointCommand>();

  const auto steps = static_cast<long>(duration / sim.dt() + 0.5);
  const std::int64_t t0 = node::now_ns();
  for (long i = 0; i < steps; ++i) {
    sim_node::to_msg(sensors, feet, *m_sensors);
    estimator_node::from_msg(*m_sensors, map, frame);
    est.update(frame, est_state);
    estimator_node::to_msg(est_state, map, *m_state);
    controller_node::from_msg(*m_state, map, state);
    ctrl.prepare(state, reference, problem);
    contact_node::to_msg(problem, *m_problem);
    m_problem->header(m_state->header());
    contact_node::from_msg(*m_problem, problem_in);
    optimizer.solve(problem_in, solution);
    contact_node::to_msg(solution, m_problem->header(), 0.0, contact::Method::kSequential,
                         *m_solution);
    contact_node::from_msg(*m_solution, solution_in);
    ctrl.finish(solution_in, command);
    controller_node::to_msg(command, m_state->header(), map, *m_command);
    sim_node::from_msg(*m_command, sim_cmd);
    sim.step(sim_cmd, sensors, truth);
    monitor.update(truth);
    if (verbose && i < 40)
      std::printf(
          "k=%ld Fz_meas R %.1f L %.1f | contact est %d %d | support %d %d | mode %d | "
          "contact status %s | tau_ff max %.1f | truth contact %d %d\n",
          i, frame.foot_wrench_Fo_F[0][2], frame.foot_wrench_Fo_F[1][2],
          est_state.feet[0].in_contact, est_state.feet[1].in_contact, ctrl.diagnostics().support[0],
          ctrl.diagnostics().support[1], static_cast<int>(command.mode),
          contact::to_string(solution.status), command.tau_ff.cwiseAbs().maxCoeff(),
          truth.feet[feet[0]].in_contact, truth.feet[feet[1]].in_contact);
    if (verbose && i % 100 == 0)
      std::printf(
          "t=%.2f base z true %.4f est %.4f | vz true %.4f est %.4f | pitch-ish true "
          "%.4f est %.4f | com z true %.4f est %.4f | flags %u\n",
          truth.time, truth.X_WB.translation().z(), est_state.X_WB.p.z(), truth.v_WB.z(),
          est_state.v_WB.z(), truth.X_WB.linear()(0, 2), est_state.X_WB.R(0, 2), truth.com_W.z(),
          est_state.com_W.z(), est_state.status_flags);
  }
  const double wall = static_cast<double>(node::now_ns() - t0) * 1e-9;
  InProcessResult r;
  r.realtime_factor = static_cast<double>(steps) * sim.dt() / wall;
  r.us_per_tick = wall * 1e6 / static_cast<double>(steps);
  const auto m = monitor.result();
  r.survived = m.survived;
  r.com_error_max = m.com_error_max_m;
  return r;
}

fs::path self_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path(".") : exe.parent_path();
}

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--realtime") {
      try {
        return poise::bench::run_realtime_bench(argc, argv, self_dir());
      } catch (const std::exception& e) {
        std::fprintf(stderr, "poise-bench-loop --realtime: %s\n", e.what());
        return 2;
      }
    }
  std::string scenario;
  double duration = 3.0;
  bool skip_distributed = false, verbose = false;
  int settle_ticks = 10;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--duration" && i + 1 < argc)
      duration = std::atof(argv[++i]);
    else if (a == "--skip-distributed")
      skip_distributed = true;
    else if (a == "--verbose")
      verbose = true;
    else if (a == "--settle-ticks" && i + 1 < argc)
      settle_ticks = std::atoi(argv[++i]);
    else if (a == "--help" || a == "-h") {
      std::printf(
          "usage: poise-bench-loop [SCENARIO] [--duration S] [--skip-distributed] "
          "[--verbose]\n"
          "       poise-bench-loop --realtime [--help] ...  (the real-time targets: see "
          "--realtime --help)\n");
      return 0;
    } else
      scenario = a;
  }
  if (scenario.empty()) {
    for (fs::path d = self_dir(); !d.empty() && d != d.root_path(); d = d.parent_path())
      if (fs::exists(d / "tests/nodes/standing_short.yaml")) {
        scenario = (d / "tests/nodes/standing_short.yaml").string();
        break;
      }
  }
  try {
    const InProcessResult in = run_in_process(scenario, duration, verbose, settle_ticks);
    std::printf("in-process loop : %.2fx real time (%.1f us per tick), %s, com_error_max %.4f m\n",
                in.realtime_factor, in.us_per_tick, in.survived ? "survived" : "FELL",
                in.com_error_max);
    if (skip_distributed) return 0;
    const fs::path dir =
        fs::temp_directory_path() / ("poise-bench-loop-" + std::to_string(::getpid()));
    const std::string cmd = (self_dir() / "poise-launch").string() + " " + scenario +
                            " --quiet --dds cyclone --duration " + std::to_string(duration) +
                            " --output " + (dir / "r.json").string() + " --log-dir " +
                            (dir / "logs").string();
    std::fflush(stdout);
    // CPU time and context switches of every process of the run (the launcher waits for its
    // children, so they count): less sensitive to other load on the machine than the wall time.
    rusage before{}, after{};
    getrusage(RUSAGE_CHILDREN, &before);
    const int code = std::system(cmd.c_str());
    getrusage(RUSAGE_CHILDREN, &after);
    std::ifstream f(dir / "r.json");
    if (!f) {
      std::fprintf(stderr, "distributed run failed (exit %d): see %s\n", code, dir.c_str());
      return 1;
    }
    const auto r = nlohmann::json::parse(f);
    const double rtf = r.value("realtime_factor", 0.0);
    const auto& lat = r["tick_latency_us"];
    std::printf(
        "distributed loop: %.2fx real time (%.1f us per tick), %s, 4 processes, Cyclone "
        "DDS loopback, lockstep\n",
        rtf, rtf > 0 ? 1e3 / rtf : 0.0, r.value("survived", false) ? "survived" : "FELL");
    std::printf(
        "tick latency (sensors k published -> command k received): p50 %.0f us, p99 %.0f "
        "us, max %.0f us, mean %.0f us over %d ticks\n",
        lat.value("p50", 0.0), lat.value("p99", 0.0), lat.value("max", 0.0), lat.value("mean", 0.0),
        lat.value("count", 0));
    for (const char* n : {"sim", "estimator", "controller", "contact"}) {
      const auto& c = r["compute_us"][n];
      if (c.is_object())
        std::printf("  %-10s compute per tick: p50 %.0f us, p99 %.0f us, max %.0f us\n", n,
                    c.value("p50", 0.0), c.value("p99", 0.0), c.value("max", 0.0));
    }
    const double ticks = std::max(1.0, lat.value("count", 0.0));
    auto seconds = [](const timeval& t) {
      return static_cast<double>(t.tv_sec) + t.tv_usec * 1e-6;
    };
    const double cpu_s = seconds(after.ru_utime) - seconds(before.ru_utime) +
                         seconds(after.ru_stime) - seconds(before.ru_stime);
    std::printf(
        "distributed CPU (5 processes, start-up and exit included): %.0f us per tick; context "
        "switches per tick: %.1f voluntary, %.1f involuntary\n",
        cpu_s * 1e6 / ticks, static_cast<double>(after.ru_nvcsw - before.ru_nvcsw) / ticks,
        static_cast<double>(after.ru_nivcsw - before.ru_nivcsw) / ticks);
    std::printf("DDS + process overhead: %.1f us per tick; distributed / in-process speed: %.2f\n",
                (rtf > 0 ? 1e3 / rtf : 0.0) - in.us_per_tick,
                in.realtime_factor > 0 ? rtf / in.realtime_factor : 0.0);
    fs::remove_all(dir);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-bench-loop: %s\n", e.what());
    return 2;
  }
}
