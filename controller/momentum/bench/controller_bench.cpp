// One controller tick on the project humanoid, WITHOUT the contact optimiser (its solution is
// computed once beforehand and handed in): phase A (kinematics, A, A_dot qd, Jacobians, eqs
// (10)-(11), (36), contact problem) + phase B (eq (33), inverse dynamics, references).
// Target: median <= 20 us, no allocation (the no-allocation proof is tests/controller's
// poise_controller_no_malloc_test). Also: each phase alone, and the paper's eq (33) alone.
//   build-*/bin/poise-bench-controller --benchmark_repetitions=5
#include <benchmark/benchmark.h>

#include <random>
#include <string>

#include "poise/contact/sequential_optimizer.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/model/kinematics.hpp"

namespace {

using namespace poise;

struct Setup {
  model::RobotConfig robot = model::load_robot_config(std::string(POISE_SOURCE_DIR) +
                                                      "/deploy/robots/poise_humanoid/robot.yaml");
  model::Model model = model::load_robot_model(robot);
  controller::BalanceController ctrl{model, robot, controller::ControllerConfig{}};
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

void BM_ControllerTick_NoContactOptimiser(benchmark::State& st) {
  Setup& s = setup();
  std::size_t k = 0;
  for (auto _ : st) {
    const std::size_t i = k++ % s.states.size();
    s.ctrl.prepare(s.states[i], s.ref, s.problem);
    s.ctrl.finish(s.solutions[i], s.cmd);
    benchmark::DoNotOptimize(s.cmd.tau_ff.data());
  }
  st.counters["qp_iterations_last"] = s.ctrl.diagnostics().qp_iterations;
}
BENCHMARK(BM_ControllerTick_NoContactOptimiser)->Unit(benchmark::kMicrosecond);

void BM_PhaseA_ContactProblem(benchmark::State& st) {
  Setup& s = setup();
  std::size_t k = 0;
  for (auto _ : st) {
    s.ctrl.prepare(s.states[k++ % s.states.size()], s.ref, s.problem);
    benchmark::DoNotOptimize(s.problem.l_dot_desired.data());
  }
}
BENCHMARK(BM_PhaseA_ContactProblem)->Unit(benchmark::kMicrosecond);

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
void BM_Eq33_Alone(benchmark::State& st) {
  Setup& s = setup();
  s.ctrl.prepare(s.states[0], s.ref, s.problem);
  s.ctrl.finish(s.solutions[0], s.cmd);
  controller::AccelerationSolver solver(s.model.nv, 12);
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
BENCHMARK(BM_Eq33_Alone)->Unit(benchmark::kMicrosecond);

// With the paper's sequential contact optimiser included (for reference: the whole in-process
// tick).
void BM_ControllerTick_WithContactOptimiser(benchmark::State& st) {
  Setup& s = setup();
  contact::SequentialOptimizer opt;
  contact::ContactSolution sol;
  std::size_t k = 0;
  for (auto _ : st) {
    s.ctrl.prepare(s.states[k++ % s.states.size()], s.ref, s.problem);
    opt.solve(s.problem, sol);
    s.ctrl.finish(sol, s.cmd);
    benchmark::DoNotOptimize(s.cmd.tau_ff.data());
  }
}
BENCHMARK(BM_ControllerTick_WithContactOptimiser)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
