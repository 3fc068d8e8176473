// Benchmarks of the dynamics library on the project's humanoid (19 joints, nv = 25).
// Run: build/bin/poise-bench-model
#include <benchmark/benchmark.h>

#include <random>

#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/model.hpp"

namespace {

using namespace poise::model;

struct Fixture {
  Model model = build_model_from_urdf_file(std::string(POISE_SOURCE_DIR) +
                                           "/deploy/robots/poise_humanoid/poise_humanoid.urdf");
  Data data{model};
  Eigen::VectorXd q, v, a;
  Matrix6X J;
  int foot = model.frame_id("l_sole");
  Fixture() {
    std::mt19937 rng(42);
    std::normal_distribution<double> n01;
    q = model.neutral();
    v.resize(model.nv);
    a.resize(model.nv);
    for (int j = 0; j < model.njoints; ++j)
      q[model.idx_q(j)] = 0.3 * n01(rng);
    for (int i = 0; i < model.nv; ++i) {
      v[i] = n01(rng);
      a[i] = n01(rng);
    }
    J.resize(6, model.nv);
  }
};

Fixture& fx() {
  static Fixture f;
  return f;
}

void BM_ForwardKinematicsPositions(benchmark::State& st) {
  auto& f = fx();
  for (auto _ : st) {
    forward_kinematics(f.model, f.data, f.q);
    benchmark::DoNotOptimize(f.data.oMi.back().p.data());
  }
}
void BM_ForwardKinematicsPosVelAcc(benchmark::State& st) {
  auto& f = fx();
  for (auto _ : st) {
    forward_kinematics(f.model, f.data, f.q, f.v, f.a);
    benchmark::DoNotOptimize(f.data.a.back().data());
  }
}
void BM_JointJacobians(benchmark::State& st) {
  auto& f = fx();
  for (auto _ : st) {
    compute_joint_jacobians(f.model, f.data, f.q);
    benchmark::DoNotOptimize(f.data.J.data());
  }
}
void BM_JointJacobiansPlusTwoFootJacobians(benchmark::State& st) {
  auto& f = fx();
  const int r = f.model.frame_id("r_sole");
  for (auto _ : st) {
    compute_joint_jacobians(f.model, f.data, f.q);
    frame_jacobian(f.model, f.data, f.foot, f.J);
    frame_jacobian(f.model, f.data, r, f.J);
    benchmark::DoNotOptimize(f.J.data());
  }
}
void BM_CentroidalMomentumMatrixPlusBias(benchmark::State& st) {
  auto& f = fx();
  for (auto _ : st) {
    centroidal_momentum_matrix(f.model, f.data, f.q, f.v);
    benchmark::DoNotOptimize(f.data.Ag.data());
    benchmark::DoNotOptimize(f.data.dAg_v.data());
  }
}
void BM_ComAndCentroidalMomentum(benchmark::State& st) {
  auto& f = fx();
  for (auto _ : st) {
    centroidal_momentum(f.model, f.data, f.q, f.v);
    benchmark::DoNotOptimize(f.data.hg.data());
  }
}
void BM_Rnea(benchmark::State& st) {
  auto& f = fx();
  clear_external_forces(f.data);
  for (auto _ : st) {
    benchmark::DoNotOptimize(rnea(f.model, f.data, f.q, f.v, f.a).data());
  }
}
void BM_Crba(benchmark::State& st) {
  auto& f = fx();
  for (auto _ : st) {
    benchmark::DoNotOptimize(crba(f.model, f.data, f.q).data());
  }
}

BENCHMARK(BM_ForwardKinematicsPositions);
BENCHMARK(BM_ForwardKinematicsPosVelAcc);
BENCHMARK(BM_JointJacobians);
BENCHMARK(BM_JointJacobiansPlusTwoFootJacobians);
BENCHMARK(BM_CentroidalMomentumMatrixPlusBias);
BENCHMARK(BM_ComAndCentroidalMomentum);
BENCHMARK(BM_Rnea);
BENCHMARK(BM_Crba);

}  // namespace

BENCHMARK_MAIN();
