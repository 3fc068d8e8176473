// poise-bench-loop [SCENARIO] [--duration S] [--skip-distributed] [--verbose]
// poise-bench-loop --realtime ...   (real time, distributed, against the targets:
// realtime_bench.cpp)
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
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "poise/contact_node/contact_messages.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/controller_node/controller_messages.hpp"
#include "poise/estimator/estimator.hpp"
#include "poise/estimator_node/estimator_messages.hpp"
#include "poise/node/compute_stats.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/node/tick_timer.hpp"
#include "poise/sim/bullet_profile.hpp"
#include "poise/sim_node/sim_messages.hpp"
#include "realtime_bench.hpp"

namespace {

using namespace poise;
namespace fs = std::filesystem;

// Where an in-process tick goes, in the order the loop runs it.
enum Phase : int {
  kSensorsToState,  // sensor message out and in
  kEstimator,
  kStateToController,  // state message out and in
  kControllerA,        // prepare: momentum, the contact problem
  kProblemWire,        // problem message out and in
  kContact,            // the contact optimiser
  kSolutionWire,       // solution message out and in
  kControllerB,        // finish: accelerations, inverse dynamics, torques
  kCommandWire,        // command message out and in
  kSimStep,            // Simulator::step (split further by its StepTimes)
  kMonitor,
  kPhases
};
constexpr const char* kPhaseNames[kPhases] = {
    "sensors msg (out+in)", "estimator",         "state msg (out+in)",    "controller phase A",
    "problem msg (out+in)", "contact optimiser", "solution msg (out+in)", "controller phase B",
    "command msg (out+in)", "simulator step",    "scenario monitor"};

struct InProcessResult {
  double realtime_factor = 0.0;
  double us_per_tick = 0.0;
  bool survived = false;
  double com_error_max = 0.0;
  std::array<double, kPhases> phase_us{};  // mean per tick
  sim::StepTimes step{};
  std::vector<sim::BulletProfile::Zone> zones;  // with --profile
  long ticks = 0;
};

// Adds the time since the last mark to a phase.
class PhaseClock {
 public:
  explicit PhaseClock(std::array<std::int64_t, kPhases>& ns) : ns_(ns), last_(node::now_ns()) {}
  void mark(Phase p) {
    const std::int64_t t = node::now_ns();
    ns_[static_cast<std::size_t>(p)] += t - last_;
    last_ = t;
  }

 private:
  std::array<std::int64_t, kPhases>& ns_;
  std::int64_t last_;
};

// Busy work for --add-work-us (a deliberate slowdown that loop_guard.sh must flag).
void spin_us(double us) {
  const std::int64_t until = node::now_ns() + static_cast<std::int64_t>(us * 1e3);
  while (node::now_ns() < until) {
  }
}

// The in-process loop's pieces, built from a scenario as the nodes build theirs, and the messages
// between them (the same IDL conversions as the nodes, no DDS).
struct InProcessStack {
  sim::World world;
  sim::Simulator simulator;
  sim_node::FootOrder feet;
  model::RobotConfig robot;
  model::Model robot_model;
  std::vector<int> map;

  estimator::Estimator est;
  estimator::SensorFrame frame;
  estimator::EstimatorState est_state;
  controller::BalanceController ctrl;
  controller::RobotState state;
  controller::BalanceReference reference;
  controller::JointCommand command;
  contact::ContactOptimizer optimizer;
  contact::ContactProblem problem, problem_in;
  contact::ContactSolution solution, solution_in;

  sim::ScenarioMonitor monitor;
  sim_node::SlipTracker slip;
  sim::SensorFrame sensors;
  sim::GroundTruth truth;
  sim::JointCommand sim_cmd;

  std::unique_ptr<msg::Sensors> m_sensors;
  std::unique_ptr<msg::State> m_state;
  std::unique_ptr<msg::ContactProblem> m_problem;
  std::unique_ptr<msg::ContactSolution> m_solution;
  std::unique_ptr<msg::JointCommand> m_command;

  InProcessStack(const std::string& file, int settle_ticks)
      : world(sim::load_world(file)),
        simulator(world.sim),
        feet(sim_node::foot_order(simulator)),
        robot(model::load_robot_config(world.robot_config.empty()
                                           ? node::default_robot_config()
                                           : world.robot_config.string())),
        robot_model(model::load_robot_model(robot)),
        map(node::model_to_wire_map(simulator.joint_names(), robot_model.joint_names)),
        est(robot_model, robot),
        frame(est.make_sensor_frame()),
        est_state(est.make_state()),
        ctrl(robot_model, robot, controller::ControllerConfig{}),
        state(ctrl.make_state()),
        reference(ctrl.make_reference()),
        command(ctrl.make_command()),
        monitor(world, sim::platforms_of_feet(world)),
        slip(sim::platforms_of_feet(world)),
        sensors(simulator.make_sensor_frame()),
        truth(simulator.make_ground_truth()),
        sim_cmd(simulator.make_command()) {
    sim_node::settle(simulator, settle_ticks, sensors, truth);
    monitor.update(truth);
    m_sensors = std::make_unique<msg::Sensors>();
    m_state = std::make_unique<msg::State>();
    m_problem = std::make_unique<msg::ContactProblem>();
    m_solution = std::make_unique<msg::ContactSolution>();
    m_command = std::make_unique<msg::JointCommand>();
  }

  // One tick, each phase's time added to `clock`.
  void tick(PhaseClock& clock) {
    sim_node::to_msg(sensors, feet, *m_sensors);
    estimator_node::from_msg(*m_sensors, map, frame);
    clock.mark(kSensorsToState);
    est.update(frame, est_state);
    clock.mark(kEstimator);
    estimator_node::to_msg(est_state, map, *m_state);
    controller_node::from_msg(*m_state, map, state);
    clock.mark(kStateToController);
    ctrl.prepare(state, reference, problem);
    clock.mark(kControllerA);
    contact_node::to_msg(problem, *m_problem);
    m_problem->header(m_state->header());
    contact_node::from_msg(*m_problem, problem_in);
    clock.mark(kProblemWire);
    optimizer.solve(problem_in, solution);
    clock.mark(kContact);
    contact_node::to_msg(solution, m_problem->header(), 0.0, contact::Method::kSequential,
                         *m_solution);
    contact_node::from_msg(*m_solution, solution_in);
    clock.mark(kSolutionWire);
    ctrl.finish(solution_in, command);
    clock.mark(kControllerB);
    controller_node::to_msg(command, m_state->header(), map, *m_command);
    sim_node::from_msg(*m_command, sim_cmd);
    clock.mark(kCommandWire);
    simulator.step(sim_cmd, sensors, truth);
    clock.mark(kSimStep);
    monitor.update(truth);
    clock.mark(kMonitor);
  }

  // --verbose: contact and support of the first 40 ticks, base and CoM every 100.
  void print_verbose(long i) const {
    if (i < 40)
      std::printf(
          "k=%ld Fz_meas R %.1f L %.1f | contact est %d %d | support %d %d | mode %d | "
          "contact status %s | tau_ff max %.1f | truth contact %d %d\n",
          i, frame.foot_wrench_Fo_F[0][2], frame.foot_wrench_Fo_F[1][2],
          est_state.feet[0].in_contact, est_state.feet[1].in_contact, ctrl.diagnostics().support[0],
          ctrl.diagnostics().support[1], static_cast<int>(command.mode),
          contact::to_string(solution.status), command.tau_ff.cwiseAbs().maxCoeff(),
          truth.feet[feet[0]].in_contact, truth.feet[feet[1]].in_contact);
    if (i % 100 == 0)
      std::printf(
          "t=%.2f base z true %.4f est %.4f | vz true %.4f est %.4f | pitch-ish true "
          "%.4f est %.4f | com z true %.4f est %.4f | flags %u\n",
          truth.time, truth.X_WB.translation().z(), est_state.X_WB.p.z(), truth.v_WB.z(),
          est_state.v_WB.z(), truth.X_WB.linear()(0, 2), est_state.X_WB.R(0, 2), truth.com_W.z(),
          est_state.com_W.z(), est_state.status_flags);
  }
};

InProcessResult run_in_process(const std::string& file, double duration, bool verbose,
                               int settle_ticks, bool profile, double add_work_us) {
  InProcessStack s(file, settle_ticks);
  const auto steps = static_cast<long>(duration / s.simulator.dt() + 0.5);
  std::array<std::int64_t, kPhases> phase_ns{};
  std::unique_ptr<sim::BulletProfile> zones;
  if (profile) zones = std::make_unique<sim::BulletProfile>();
  s.simulator.reset_step_times();
  const std::int64_t t0 = node::now_ns();
  PhaseClock clock(phase_ns);
  for (long i = 0; i < steps; ++i) {
    s.tick(clock);
    if (add_work_us > 0.0) spin_us(add_work_us);
    if (verbose) s.print_verbose(i);
  }
  const double wall = static_cast<double>(node::now_ns() - t0) * 1e-9;
  InProcessResult r;
  r.ticks = steps;
  for (int p = 0; p < kPhases; ++p)
    r.phase_us[static_cast<std::size_t>(p)] =
        1e-3 * static_cast<double>(phase_ns[static_cast<std::size_t>(p)]) /
        static_cast<double>(std::max(1L, steps));
  r.step = s.simulator.step_times();
  if (zones) r.zones = zones->zones();
  r.realtime_factor = static_cast<double>(steps) * s.simulator.dt() / wall;
  r.us_per_tick = wall * 1e6 / static_cast<double>(steps);
  const auto m = s.monitor.result();
  r.survived = m.survived;
  r.com_error_max = m.com_error_max_m;
  return r;
}

void print_split(const InProcessResult& in) {
  std::printf("  where an in-process tick goes (mean us per tick):\n");
  for (int p = 0; p < kPhases; ++p)
    std::printf("    %-22s %6.1f\n", kPhaseNames[p], in.phase_us[static_cast<std::size_t>(p)]);
  const double n = static_cast<double>(std::max<std::int64_t>(1, in.step.steps));
  std::printf(
      "      of the step: Bullet %.1f, sensor models + ground truth %.1f, commands + "
      "actuators + pushes + limits %.1f\n",
      1e-3 * static_cast<double>(in.step.bullet_ns) / n,
      1e-3 * static_cast<double>(in.step.sensors_ns) / n,
      1e-3 * static_cast<double>(in.step.other_ns) / n);
}

void print_zones(const InProcessResult& in) {
  const double n = static_cast<double>(std::max(1L, in.ticks));
  std::printf(
      "  Bullet's profile zones (inclusive mean us per tick, calls per tick; timed in a "
      "second run):\n");
  for (const auto& z : in.zones)
    if (z.total_us / n >= 0.05)
      std::printf("    %*s%-*s %6.2f us %6.1f calls\n", 2 * z.depth, "", 52 - 2 * z.depth,
                  z.name.c_str(), z.total_us / n, static_cast<double>(z.calls) / n);
}

// The nodes' own split of their compute (poise run's result: library, node, DDS write).
void print_node_split(const nlohmann::json& r) {
  for (const char* n : {"estimator", "controller", "contact"}) {
    auto p50 = [&](const char* key) {
      const auto it = r.find(key);
      if (it == r.end() || !it->contains(n)) return -1.0;
      return (*it)[n].value("p50", -1.0);
    };
    std::printf("  %-10s p50: library %.1f us, node %.1f us, DDS write %.1f us\n", n,
                p50("library_us"), p50("overhead_us"), p50("dds_write_us"));
  }
}

fs::path self_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path(".") : exe.parent_path();
}

struct BenchArgs {
  std::string scenario;
  double duration = 3.0;
  bool skip_distributed = false, verbose = false, profile = false;
  double add_work_us = 0.0;
  int settle_ticks = 10;
};

void print_usage() {
  std::printf(
      "usage: poise-bench-loop [SCENARIO] [--duration S] [--skip-distributed] "
      "[--profile] [--add-work-us US] [--verbose]\n"
      "  --profile  also time Bullet's own profile zones in the in-process loop (adds about\n"
      "             5 us a tick, so the loop's own figure is measured without it first)\n"
      "  --add-work-us US  busy-wait this long in every in-process tick: a deliberate\n"
      "             slowdown, to check that loop_guard.sh flags one\n"
      "       poise-bench-loop --realtime [--help] ...  (the real-time targets: see "
      "--realtime --help)\n");
}

// False after --help (printed).
bool parse_args(int argc, char** argv, BenchArgs& b) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--duration" && i + 1 < argc)
      b.duration = std::atof(argv[++i]);
    else if (a == "--skip-distributed")
      b.skip_distributed = true;
    else if (a == "--verbose")
      b.verbose = true;
    else if (a == "--profile")
      b.profile = true;
    else if (a == "--add-work-us" && i + 1 < argc)
      b.add_work_us = std::atof(argv[++i]);
    else if (a == "--settle-ticks" && i + 1 < argc)
      b.settle_ticks = std::atoi(argv[++i]);
    else if (a == "--help" || a == "-h") {
      print_usage();
      return false;
    } else
      b.scenario = a;
  }
  if (b.scenario.empty()) {
    for (fs::path d = self_dir(); !d.empty() && d != d.root_path(); d = d.parent_path())
      if (fs::exists(d / "tests/nodes/standing_short.yaml")) {
        b.scenario = (d / "tests/nodes/standing_short.yaml").string();
        break;
      }
  }
  return true;
}

// The distributed run's figures (its result JSON) and the CPU of its processes.
void print_distributed(const nlohmann::json& r, const rusage& before, const rusage& after,
                       const InProcessResult& in) {
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
  auto seconds = [](const timeval& t) { return static_cast<double>(t.tv_sec) + t.tv_usec * 1e-6; };
  const double cpu_s = seconds(after.ru_utime) - seconds(before.ru_utime) +
                       seconds(after.ru_stime) - seconds(before.ru_stime);
  std::printf(
      "distributed CPU (5 processes, start-up and exit included): %.0f us per tick; context "
      "switches per tick: %.1f voluntary, %.1f involuntary\n",
      cpu_s * 1e6 / ticks, static_cast<double>(after.ru_nvcsw - before.ru_nvcsw) / ticks,
      static_cast<double>(after.ru_nivcsw - before.ru_nivcsw) / ticks);
  print_node_split(r);
  std::printf("DDS + process overhead: %.1f us per tick; distributed / in-process speed: %.2f\n",
              (rtf > 0 ? 1e3 / rtf : 0.0) - in.us_per_tick,
              in.realtime_factor > 0 ? rtf / in.realtime_factor : 0.0);
}

// `poise-launch SCENARIO` in lockstep on Cyclone; 0, or 1 when it wrote no result.
int run_distributed(const BenchArgs& b, const InProcessResult& in) {
  const fs::path dir =
      fs::temp_directory_path() / ("poise-bench-loop-" + std::to_string(::getpid()));
  const std::string cmd = (self_dir() / "poise-launch").string() + " " + b.scenario +
                          " --quiet --dds cyclone --duration " + std::to_string(b.duration) +
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
  print_distributed(nlohmann::json::parse(f), before, after, in);
  fs::remove_all(dir);
  return 0;
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
  BenchArgs b;
  if (!parse_args(argc, argv, b)) return 0;
  try {
    const InProcessResult in =
        run_in_process(b.scenario, b.duration, b.verbose, b.settle_ticks, false, b.add_work_us);
    std::printf("in-process loop : %.2fx real time (%.1f us per tick), %s, com_error_max %.4f m\n",
                in.realtime_factor, in.us_per_tick, in.survived ? "survived" : "FELL",
                in.com_error_max);
    print_split(in);
    if (b.profile)
      print_zones(run_in_process(b.scenario, b.duration, false, b.settle_ticks, true, 0.0));
    if (b.skip_distributed) return 0;
    return run_distributed(b, in);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-bench-loop: %s\n", e.what());
    return 2;
  }
}
