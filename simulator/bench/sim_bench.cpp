// poise-bench-sim: time of one 1 ms simulation step of the project humanoid (target <= 50 us).
// Counters: p50_us / p99_us / max_us of single steps, rt_factor = 1 ms / mean step time.
// The robot holds its posture with the PD law evaluated inside the simulator; it is put back to
// its initial state every 2 s of simulated time (untimed) so it never lies on the floor.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "poise/sim/simulator.hpp"
#include "poise/sim/world.hpp"

namespace {

using namespace poise::sim;

void run(benchmark::State& state, const std::string& scenario_name) {
  const int iterations = static_cast<int>(state.range(0));
  const bool warm_start = state.range(1) != 0;
  const bool ground_band = state.range(2) != 0;
  const double residual = std::pow(10.0, -static_cast<double>(state.range(3)));
  const std::filesystem::path file =
      std::filesystem::path(POISE_SOURCE_DIR) / "deploy/scenarios" / (scenario_name + ".yaml");
  World sc;
  try {
    sc = load_world(file);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  sc.sim.pushes.clear();  // steady standing
  sc.sim.solver.iterations = iterations;
  sc.sim.solver.warm_start = warm_start;
  if (!ground_band) sc.sim.solver.ground_aabb_band = 0.0;
  sc.sim.solver.residual_threshold = residual;
  Simulator sim(sc.sim);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  sim.read(s, g);
  const Eigen::Isometry3d X0 = g.X_WB;
  const Eigen::VectorXd q0 = s.q;
  JointCommand c = sim.make_command();
  c.mode = CommandMode::kPd;
  c.q_ref = q0;
  c.kp.setConstant(300.0);
  c.kd.setConstant(6.0);
  for (int k = 0; k < 300; ++k)
    sim.step(c, s, g);  // settle the contacts
  std::vector<double> us;
  us.reserve(1 << 20);
  long n = 0;
  double solver_iterations = 0.0;
  double rows_normal = 0.0, rows_friction = 0.0, rows_other = 0.0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    sim.step(c, s, g);
    const auto t1 = std::chrono::steady_clock::now();
    solver_iterations += sim.solver_iterations_used();
    const SolverRows rows = sim.solver_rows();
    rows_normal += rows.contact_normal;
    rows_friction += rows.contact_friction;
    rows_other += rows.other;
    if (us.size() < us.capacity())
      us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    if (++n % 2000 == 0) {
      state.PauseTiming();
      sim.set_state(X0, q0);
      state.ResumeTiming();
    }
  }
  std::sort(us.begin(), us.end());
  if (!us.empty()) {
    state.counters["p50_us"] = us[us.size() / 2];
    state.counters["p99_us"] = us[us.size() * 99 / 100];
    state.counters["max_us"] = us.back();
    double mean = 0.0;
    for (double v : us)
      mean += v;
    mean /= static_cast<double>(us.size());
    state.counters["rt_factor"] = 1e6 * sim.dt() / mean;
  }
  state.counters["joints"] = sim.num_joints();
  if (n > 0) {
    state.counters["solver_iters"] = solver_iterations / static_cast<double>(n);
    state.counters["rows_n"] = rows_normal / static_cast<double>(n);
    state.counters["rows_f"] = rows_friction / static_cast<double>(n);
    state.counters["rows_o"] = rows_other / static_cast<double>(n);
  }
}

// Arguments: {solver iterations, articulated warm starting (1 = the default, 0 = off), ground
// broadphase box (1 = the default band above the plane, 0 = infinite: every link paired with the
// ground), solver residual threshold 10^-arg (7 = the default)}; the
// first row of each case is the default, the others change one setting (same run, A/B).
void BM_StepStandingDoubleSupport(benchmark::State& st) {
  run(st, "forward_push_double_support");
}
void BM_StepSingleSupport(benchmark::State& st) {
  run(st, "lateral_push_single_support");
}
void BM_StepMovingPlatforms(benchmark::State& st) {
  run(st, "platforms_out_of_phase");
}

}  // namespace

BENCHMARK(BM_StepStandingDoubleSupport)
    ->Args({50, 1, 1, 7})
    ->Args({50, 1, 1, 9})
    ->Args({50, 1, 0, 7})
    ->Args({50, 0, 1, 7})
    ->Args({20, 1, 1, 7})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StepSingleSupport)
    ->Args({50, 1, 1, 7})
    ->Args({50, 1, 1, 9})
    ->Args({50, 1, 0, 7})
    ->Args({50, 0, 1, 7})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StepMovingPlatforms)
    ->Args({50, 1, 1, 7})
    ->Args({50, 1, 1, 9})
    ->Args({50, 1, 0, 7})
    ->Args({50, 0, 1, 7})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_MAIN();
