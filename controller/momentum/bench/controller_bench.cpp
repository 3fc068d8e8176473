// One controller tick on the project humanoid, WITHOUT the contact optimiser (its solution is
// computed once beforehand and handed in): phase A (kinematics, A, A_dot qd, Jacobians, eqs
// (10)-(11), (36), contact problem) + phase B (eq (33), inverse dynamics, references).
// Target: median <= 20 us, no allocation (the no-allocation proof is tests/controller's
// poise_controller_no_malloc_test). Also: each phase alone, and the paper's eq (33) alone.
//   build-*/bin/poise-bench-controller --benchmark_repetitions=5
//
// First it prints PAIRED figures: one sequence of ticks (prepare -> sequential optimiser ->
// finish), each stage timed on its own, so the tick without the optimiser (A + B) and with it
// (A + optimiser + B) are medians over the very same ticks and their difference is the
// optimiser's time. (The Google Benchmark loops below time each variant in its own loop: the
// two tick loops used to report the same 12.6 us because the difference, the optimiser's
// ~2 us, was inside the run-to-run spread of the shared machine; the paired figures separate
// it.)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <string>

#include "poise/contact/sequential_optimizer.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/model/kinematics.hpp"

namespace {

using namespace poise;

controller::ControllerConfig without_upright(bool nor_ankle_first) {
  controller::ControllerConfig c;
  c.momentum.upright_pitch_rate = 0.0;
  c.momentum.upright_roll_rate = 0.0;
  if (nor_ankle_first) c.momentum.ankle_first_blend = 0.0;
  return c;
}

struct Setup {
  model::RobotConfig robot = model::load_robot_config(std::string(POISE_SOURCE_DIR) +
                                                      "/deploy/robots/poise_humanoid/robot.yaml");
  model::Model model = model::load_robot_model(robot);
  controller::BalanceController ctrl{model, robot, controller::ControllerConfig{}};
  /// The same without FeedbackConfig::internal_force_leak_hz (the paper's references): the paired
  /// cost of the legs' internal-force split.
  controller::BalanceController paper_refs{model, robot, [] {
                                             controller::ControllerConfig c;
                                             c.feedback.internal_force_leak_hz = 0.0;
                                             return c;
                                           }()};
  /// The same without MomentumGains::upright_pitch_rate (the paired cost of the trunk-upright
  /// target), and without it and ankle_first_blend (the paper's (10)-(11): the cost of both).
  controller::BalanceController no_upright{model, robot, without_upright(false)};
  controller::BalanceController paper_eq{model, robot, without_upright(true)};
  std::vector<controller::RobotState> states;
  std::vector<contact::ContactSolution> solutions;
  controller::BalanceReference ref = ctrl.make_reference();
  controller::JointCommand cmd = ctrl.make_command();
  contact::ContactProblem problem;

  Setup() {
    std::mt19937 rng(42);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    contact::SequentialOptimizer opt;
    model::Data data(model);
    for (int k = 0; k < 64; ++k) {
      controller::RobotState s = ctrl.make_state();
      s.X_WB = model::base_pose(robot.q_nominal);
      s.X_WB.p += 0.01 * Eigen::Vector3d(U(rng), U(rng), U(rng));
      for (int j = 0; j < model.njoints; ++j) {
        s.q[j] = robot.q_nominal[7 + j] + 0.05 * U(rng);
        s.qd[j] = 0.2 * U(rng);
      }
      s.v_WB = 0.05 * Eigen::Vector3d(U(rng), U(rng), U(rng));
      s.omega_WB = 0.1 * Eigen::Vector3d(U(rng), U(rng), U(rng));
      Eigen::VectorXd q = robot.q_nominal;
      q.tail(model.njoints) = s.q;
      model::forward_kinematics(model, data, q);
      for (int i = 0; i < 2; ++i) {
        const auto& f = robot.feet[i];
        const model::SE3 X = model::frame_placement(model, data, f.frame_id);
        s.feet[i].in_contact = (k % 8 != 7) || i == 1;  // some single-support ticks
        s.feet[i].cop_W = X.act(Eigen::Vector3d(0.03, 0.0, -f.sole.height));
        // Loaded as when standing (half the weight each, +-30 %): the both-feet-loaded paths
        // (the legs' internal-force split) run on the double-support ticks.
        s.feet[i].normal_force =
            s.feet[i].in_contact ? 0.5 * 50.8 * 9.81 * (1.0 + 0.3 * U(rng)) : 0.0;
      }
      contact::ContactSolution sol;
      ctrl.prepare(s, ref, problem);
      opt.solve(problem, sol);
      states.push_back(s);
      solutions.push_back(sol);
    }
  }
};

Setup& setup() {
  static Setup s;
  return s;
}

// Which eq (33) path the ticks took (bounds active: the primal active set, or DualQp; fallback
// wrenches): the two tick loops must do the same work for their difference to be the optimiser's
// time.
void count_paths(const Setup& s, std::int64_t& active, std::int64_t& fallback) {
  active += s.ctrl.diagnostics().active_bounds > 0;
  fallback += s.ctrl.diagnostics().contact_source != controller::ContactSource::kSolution;
}
void report_paths(benchmark::State& st, std::int64_t active, std::int64_t fallback) {
  st.counters["bounds_active"] =
      benchmark::Counter(static_cast<double>(active), benchmark::Counter::kAvgIterations);
  st.counters["fallback"] =
      benchmark::Counter(static_cast<double>(fallback), benchmark::Counter::kAvgIterations);
}

void BM_ControllerTick_NoContactOptimiser(benchmark::State& st) {
  Setup& s = setup();
  std::int64_t active = 0, fallback = 0;
  std::size_t k = 0;
  for (auto _ : st) {
    const std::size_t i = k++ % s.states.size();
    s.ctrl.prepare(s.states[i], s.ref, s.problem);
    s.ctrl.finish(s.solutions[i], s.cmd);
    benchmark::DoNotOptimize(s.cmd.tau_ff.data());
    count_paths(s, active, fallback);
  }
  report_paths(st, active, fallback);
}
BENCHMARK(BM_ControllerTick_NoContactOptimiser)->Unit(benchmark::kMicrosecond);

// Arg 0: the defaults (the ankle strategy's support polygon and the trunk-upright target every
// tick); 1: without the upright target; 2: without either (the paper's (10)-(11)).
void BM_PhaseA_ContactProblem(benchmark::State& st) {
  Setup& s = setup();
  controller::BalanceController& c =
      st.range(0) == 0 ? s.ctrl : st.range(0) == 1 ? s.no_upright : s.paper_eq;
  std::size_t k = 0;
  for (auto _ : st) {
    c.prepare(s.states[k++ % s.states.size()], s.ref, s.problem);
    benchmark::DoNotOptimize(s.problem.l_dot_desired.data());
  }
}
BENCHMARK(BM_PhaseA_ContactProblem)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

void BM_PhaseB_Eq33_InverseDynamics(benchmark::State& st) {
  Setup& s = setup();
  s.ctrl.prepare(s.states[0], s.ref, s.problem);
  for (auto _ : st) {
    s.ctrl.finish(s.solutions[0], s.cmd);
    benchmark::DoNotOptimize(s.cmd.tau_ff.data());
  }
}
BENCHMARK(BM_PhaseB_Eq33_InverseDynamics)->Unit(benchmark::kMicrosecond);

// Eq (33) alone (the paper: 0.11 ms on a 2.66 GHz Core2 Quad), with the data of one tick.
// Arg 0: the solver as the controller runs it (Woodbury form of G^-1); arg 1: G factorised densely
// (the method before the Woodbury form, kept for the before/after ratio).
void BM_Eq33_Alone(benchmark::State& st) {
  Setup& s = setup();
  s.ctrl.prepare(s.states[0], s.ref, s.problem);
  s.ctrl.finish(s.solutions[0], s.cmd);
  controller::AccelerationSolver solver(s.model.nv, 12);
  solver.set_dense_equality_path(st.range(0) != 0);
  st.SetLabel(st.range(0) != 0 ? "dense Cholesky of G" : "Woodbury");
  const auto& c = s.ctrl;
  const model::Vector6 b = c.diagnostics().hdot_admissible - c.centroidal_bias();
  Eigen::VectorXd d = c.foot_bias_acceleration();
  for (int i = 0; i < 2; ++i)
    d.segment<6>(6 * i) = c.diagnostics().foot_acceleration_desired[i] - d.segment<6>(6 * i);
  Eigen::VectorXd x(s.model.nv);
  int active_set = 0;
  for (auto _ : st) {
    auto r =
        solver.solve(c.centroidal_matrix(), b, s.ctrl.config().acceleration.w_b, c.qp_weights(),
                     c.qp_targets(), c.foot_jacobians(), d, c.qdd_lower(), c.qdd_upper(), x);
    active_set += r.used_active_set;
    benchmark::DoNotOptimize(r);
    benchmark::DoNotOptimize(x.data());
  }
  st.counters["active_set_path"] =
      benchmark::Counter(active_set, benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_Eq33_Alone)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Eq (33) on the ticks of the set where a joint-acceleration bound is active (about 8 % of the
// controller's ticks; they make its p99). Arg 0: the primal active set on the Woodbury factors (as
// the controller runs it); arg 1: straight to DualQp (the method before it).
void BM_Eq33_BoundsActive(benchmark::State& st) {
  Setup& s = setup();
  struct Tick {
    Eigen::MatrixXd A, C;
    model::Vector6 b;
    Eigen::VectorXd w, t, d, lo, hi;
  };
  std::vector<Tick> ticks;
  for (std::size_t k = 0; k < s.states.size(); ++k) {
    s.ctrl.prepare(s.states[k], s.ref, s.problem);
    s.ctrl.finish(s.solutions[k], s.cmd);
    const auto& c = s.ctrl;
    if (c.diagnostics().active_bounds == 0) continue;
    Tick tk;
    tk.A = c.centroidal_matrix();
    tk.C = c.foot_jacobians();
    tk.b = c.diagnostics().hdot_admissible - c.centroidal_bias();
    tk.w = c.qp_weights();
    tk.t = c.qp_targets();
    tk.d = c.foot_bias_acceleration();
    for (int i = 0; i < 2; ++i)
      tk.d.segment<6>(6 * i) =
          c.diagnostics().foot_acceleration_desired[i] - tk.d.segment<6>(6 * i);
    tk.lo = c.qdd_lower();
    tk.hi = c.qdd_upper();
    ticks.push_back(tk);
  }
  if (ticks.empty()) {
    st.SkipWithError("no tick of the set has an active bound");
    return;
  }
  controller::AccelerationSolver solver(s.model.nv, 12);
  solver.set_primal_active_set(st.range(0) == 0);
  st.SetLabel(st.range(0) == 0 ? "primal active set" : "DualQp");
  const double w_b = s.ctrl.config().acceleration.w_b;
  Eigen::VectorXd x(s.model.nv);
  std::int64_t dual = 0, bounds = 0;
  std::size_t k = 0;
  for (auto _ : st) {
    const Tick& tk = ticks[k++ % ticks.size()];
    auto r = solver.solve(tk.A, tk.b, w_b, tk.w, tk.t, tk.C, tk.d, tk.lo, tk.hi, x);
    dual += r.used_dual_qp;
    bounds += r.active_bounds;
    benchmark::DoNotOptimize(r);
    benchmark::DoNotOptimize(x.data());
  }
  st.counters["ticks"] = static_cast<double>(ticks.size());
  st.counters["dual_qp"] =
      benchmark::Counter(static_cast<double>(dual), benchmark::Counter::kAvgIterations);
  st.counters["active_bounds"] =
      benchmark::Counter(static_cast<double>(bounds), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_Eq33_BoundsActive)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// With the paper's sequential contact optimiser included (for reference: the whole in-process
// tick).
void BM_ControllerTick_WithContactOptimiser(benchmark::State& st) {
  Setup& s = setup();
  contact::SequentialOptimizer opt;
  contact::ContactSolution sol;
  std::int64_t active = 0, fallback = 0;
  std::size_t k = 0;
  for (auto _ : st) {
    s.ctrl.prepare(s.states[k++ % s.states.size()], s.ref, s.problem);
    opt.solve(s.problem, sol);
    s.ctrl.finish(sol, s.cmd);
    benchmark::DoNotOptimize(s.cmd.tau_ff.data());
    count_paths(s, active, fallback);
  }
  report_paths(st, active, fallback);
}
BENCHMARK(BM_ControllerTick_WithContactOptimiser)->Unit(benchmark::kMicrosecond);

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}
double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

/// Paired per-stage timing over one sequence of ticks (see the file comment).
void print_paired_figures(int ticks) {
  using Clock = std::chrono::steady_clock;
  auto us = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::micro>(b - a).count();
  };
  Setup& s = setup();
  contact::SequentialOptimizer opt;
  contact::ContactSolution sol;
  std::vector<double> a, solve, b, without, with, b_paper;
  controller::JointCommand cmd_paper = s.paper_refs.make_command();
  contact::ContactProblem problem_paper;
  const int warmup = 2000;
  for (int it = 0; it < warmup + ticks; ++it) {
    const auto& state = s.states[static_cast<std::size_t>(it) % s.states.size()];
    const auto t0 = Clock::now();
    s.ctrl.prepare(state, s.ref, s.problem);
    const auto t1 = Clock::now();
    opt.solve(s.problem, sol);
    const auto t2 = Clock::now();
    s.ctrl.finish(sol, s.cmd);
    const auto t3 = Clock::now();
    benchmark::DoNotOptimize(s.cmd.tau_ff.data());
    s.paper_refs.prepare(state, s.ref, problem_paper);
    const auto t4 = Clock::now();
    s.paper_refs.finish(sol, cmd_paper);
    const auto t5 = Clock::now();
    benchmark::DoNotOptimize(cmd_paper.tau_ff.data());
    if (it < warmup) continue;
    b_paper.push_back(us(t4, t5));
    a.push_back(us(t0, t1));
    solve.push_back(us(t1, t2));
    b.push_back(us(t2, t3));
    without.push_back(us(t0, t1) + us(t2, t3));
    with.push_back(us(t0, t3));
  }
  const double m_without = median(without), m_with = median(with);
  std::printf(
      "paired, %d ticks (same ticks for every column), median / p99 [us]:\n"
      "  phase A                          %6.2f / %6.2f\n"
      "  sequential contact optimiser     %6.2f / %6.2f\n"
      "  phase B                          %6.2f / %6.2f\n"
      "  phase B, paper's references      %6.2f / %6.2f   (internal_force_leak_hz 0)\n"
      "  tick WITHOUT optimiser (A + B)   %6.2f / %6.2f   (target <= 20 us)\n"
      "  tick WITH optimiser (A + opt + B) %5.2f / %6.2f\n"
      "  with / without                   %6.3f\n",
      ticks, median(a), percentile(a, 0.99), median(solve), percentile(solve, 0.99), median(b),
      percentile(b, 0.99), median(b_paper), percentile(b_paper, 0.99), m_without,
      percentile(without, 0.99), m_with, percentile(with, 0.99), m_with / m_without);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  // --paired-ticks=N (default 50000; 0 skips the paired figures, e.g. when profiling one benchmark)
  int paired_ticks = 50000;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--paired-ticks=", 0) == 0) {
      paired_ticks = std::stoi(arg.substr(15));
      for (int j = i; j + 1 < argc; ++j)
        argv[j] = argv[j + 1];
      --argc;
      --i;
    }
  }
  if (paired_ticks > 0) print_paired_figures(paired_ticks);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
