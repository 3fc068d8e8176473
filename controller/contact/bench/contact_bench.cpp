// poise-bench-contact: timing and quality of the two contact optimisers on one corpus, in one run.
//
// Part 1 (corpus report): for every problem, each stage is timed with std::chrono::steady_clock
// (the minimum of --reps repetitions, to drop interrupts); printed are the median and p99 over
// the corpus per stage and method, the QP / sequential time ratio, and the objective gap.
// Part 2: Google Benchmark loops over the same corpus (mean time per solve).
//
//   poise-bench-contact [--corpus FILE] [--count N] [--reps R] [--benchmark_* flags]
// Without --corpus, a corpus of N (default 10000) problems is generated from a fixed seed.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "contact_corpus.hpp"
#include "poise/contact/contact_optimizer.hpp"

namespace {

using namespace poise::contact;
using bench::CorpusEntry;
using bench::Kind;
using Clock = std::chrono::steady_clock;

std::vector<CorpusEntry> g_corpus;

template <typename F>
double time_us(int reps, F&& f) {
  double best = 1e300;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    f();
    const auto t1 = Clock::now();
    best = std::min(best, std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  return best;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t i = std::min(v.size() - 1, static_cast<std::size_t>(q * (v.size() - 1) + 0.5));
  return v[i];
}

void row(const char* name, const std::vector<double>& v) {
  std::printf("  %-34s n=%-6zu median %8.3f us   p99 %8.3f us\n", name, v.size(),
              percentile(v, 0.5), percentile(v, 0.99));
}

void corpus_report(int reps) {
  SequentialOptimizer seq;
  QpOptimizer qp;
  QpOptimizer qp2;
  qp2.set_torsion_passes(2);
  Nnls nnls(14, 8);
  Bvls bvls(9, 6);
  DualQp dual(QpOptimizer::kMaxVars, 0, QpOptimizer::kMaxConstraints);
  std::vector<double> t_seq, t_seq_double, t_seq_single, t_nnls, t_bvls, t_qp, t_qp_double,
      t_qp_single, t_dual;
  std::vector<double> gap_tracking, gap_qpobj, t_qp2, gap_tracking2;
  int qp2_adjusted = 0;
  ContactSolution s_qp2;
  std::map<std::string, int> status_seq, status_qp;
  int qp_better = 0, qp_worse = 0, qp_equal = 0, qp_adjusted = 0, comparable = 0, qp_obj_le = 0;
  int feasible = 0, feasible_ok_seq = 0, feasible_ok_qp = 0;
  std::vector<double> err_seq, err_qp;
  ContactSolution s_seq, s_qp;
  Eigen::Matrix<double, 8, 1> rho;
  Eigen::Matrix<double, 6, 1> eta;
  Eigen::Matrix<double, QpOptimizer::kMaxVars, 1> y;

  for (const CorpusEntry& e : g_corpus) {
    const ContactProblem& p = e.problem;
    const bool two = p.feet[0].in_contact && p.feet[1].in_contact;
    const double ts = time_us(reps, [&] { seq.solve(p, s_seq); });
    t_seq.push_back(ts);
    (two ? t_seq_double : t_seq_single).push_back(ts);
    if (two) {
      const SequentialStages st = seq.stages();
      t_nnls.push_back(time_us(reps, [&] { nnls.solve(st.Phi, st.xi, rho); }));
      t_bvls.push_back(
          time_us(reps, [&] { bvls.solve(st.Psi, st.kappa, st.eta_lower, st.eta_upper, eta); }));
    }
    const double tq = time_us(reps, [&] { qp.solve(p, s_qp); });
    t_qp.push_back(tq);
    (two ? t_qp_double : t_qp_single).push_back(tq);
    const int n = qp.num_vars();
    const int m = n / QpOptimizer::kVarsPerFoot * QpOptimizer::kConstraintsPerFoot;
    const auto G = qp.hessian();
    const auto g = qp.gradient();
    const auto A = qp.inequality_matrix();
    const auto b = qp.inequality_bounds();
    t_dual.push_back(time_us(reps, [&] {
      dual.solve(G.topLeftCorner(n, n), g.head(n), G.topRows(0).leftCols(n), g.head(0),
                 A.topLeftCorner(m, n), b.head(m), y.head(n));
    }));

    t_qp2.push_back(time_us(reps, [&] { qp2.solve(p, s_qp2); }));
    qp2_adjusted += qp2.adjusted() ? 1 : 0;
    gap_tracking2.push_back((tracking_cost(p, s_qp2) - tracking_cost(p, s_seq)) /
                            std::pow(p.mass * 9.81, 2));
    ++status_seq[to_string(s_seq.status)];
    ++status_qp[to_string(s_qp.status)];
    qp_adjusted += qp.adjusted() ? 1 : 0;
    const double mg2 = std::pow(p.mass * 9.81, 2);
    const double tc_seq = tracking_cost(p, s_seq), tc_qp = tracking_cost(p, s_qp);
    const double gap = (tc_qp - tc_seq) / mg2;
    gap_tracking.push_back(gap);
    if (gap < -1e-9) {
      ++qp_better;
    } else if (gap > 1e-9) {
      ++qp_worse;
    } else {
      ++qp_equal;
    }
    // J_qp comparison (double support) where the sequential answer lies in the QP's feasible set.
    bool in_set = two;
    for (int i = 0; in_set && i < kMaxFeet; ++i) {
      const FootWrench& w = s_seq.feet[i];
      const Eigen::Vector3d f = p.feet[i].R_WF.transpose() * w.force_W;
      const double m_z = w.normal_torque + w.cop_F.x() * f.y() - w.cop_F.y() * f.x();
      in_set = std::abs(m_z) <= p.feet[i].mu_torsion * f.z();
    }
    if (in_set) {
      ++comparable;
      const double j_seq = qp_objective(p, s_seq, seq.stages().rho);
      gap_qpobj.push_back((qp.raw_objective() - j_seq) / mg2);
      qp_obj_le += qp.raw_objective() <= j_seq * (1 + 1e-9) + 1e-9 ? 1 : 0;
    }
    if (e.kind == Kind::kFeasibleDouble || e.kind == Kind::kFeasibleSingle) {
      ++feasible;
      feasible_ok_seq += s_seq.status == ContactStatus::kOk ? 1 : 0;
      feasible_ok_qp += s_qp.status == ContactStatus::kOk ? 1 : 0;
      auto err = [&](const ContactSolution& s) {
        return std::sqrt((p.l_dot_desired - s.l_dot_admissible).squaredNorm() +
                         (p.k_dot_desired - s.k_dot_admissible).squaredNorm()) /
               (p.mass * 9.81);
      };
      err_seq.push_back(err(s_seq));
      err_qp.push_back(err(s_qp));
    }
  }

  std::printf("Corpus: %zu problems; timings = min of %d repetitions per problem\n\n",
              g_corpus.size(), reps);
  std::printf("Sequential method (paper Sec. 3.4):\n");
  row("total, all problems", t_seq);
  row("total, double support", t_seq_double);
  row("total, single support", t_seq_single);
  row("stage NNLS (21)-(26), 14x8", t_nnls);
  row("stage BVLS (27)-(30), 9x6", t_bvls);
  std::printf("One QP (Goldfarb-Idnani dual active set):\n");
  row("total, all problems", t_qp);
  row("total, double support", t_qp_double);
  row("total, single support", t_qp_single);
  row("stage dual QP solve (14 vars, 20 ineq)", t_dual);
  std::printf(
      "\nQP / sequential time ratio: median %.2f (all), %.2f (double support); "
      "p99 %.2f (all)\n",
      percentile(t_qp, 0.5) / percentile(t_seq, 0.5),
      percentile(t_qp_double, 0.5) / percentile(t_seq_double, 0.5),
      percentile(t_qp, 0.99) / percentile(t_seq, 0.99));
  std::printf(
      "Paper (Core2 2.66 GHz): NNLS 9 us, BVLS 6-10 us, QP 30 us. Target: sequential "
      "median <= 2 us.\n\n");
  std::printf(
      "Objective gap, tracking cost T = |l_dot_d - l_dot_a|^2 + w_k |k_dot_d - k_dot_a|^2,"
      " (T_qp - T_seq) / (m g)^2:\n");
  std::printf("  median %.3e   p1 %.3e   p99 %.3e;  QP lower on %d, higher on %d, equal on %d\n",
              percentile(gap_tracking, 0.5), percentile(gap_tracking, 0.01),
              percentile(gap_tracking, 0.99), qp_better, qp_worse, qp_equal);
  std::printf(
      "QP objective J_qp, double support, sequential answer QP-feasible (%d problems): "
      "J_qp(qp) <= J_qp(seq) on %d; (J_qp(qp) - J_qp(seq)) / (m g)^2 median %.3e, "
      "max %.3e\n",
      comparable, qp_obj_le, percentile(gap_qpobj, 0.5), percentile(gap_qpobj, 1.0));
  std::printf("QP answers changed by the torsion clean-up (paper model): %d\n", qp_adjusted);
  std::printf("QP with torsion refinement (2 passes): ");
  row("total, all problems", t_qp2);
  std::printf("  clean-up needed on %d; tracking gap vs sequential median %.3e p1 %.3e p99 %.3e\n",
              qp2_adjusted, percentile(gap_tracking2, 0.5), percentile(gap_tracking2, 0.01),
              percentile(gap_tracking2, 0.99));
  std::printf(
      "Feasible problems (%d): status ok  seq %d, qp %d;  |h_dot_a - h_dot_d| / (m g) "
      "median seq %.2e qp %.2e, p99 seq %.2e qp %.2e\n",
      feasible, feasible_ok_seq, feasible_ok_qp, percentile(err_seq, 0.5), percentile(err_qp, 0.5),
      percentile(err_seq, 0.99), percentile(err_qp, 0.99));
  std::printf("Status counts  sequential:");
  for (const auto& [k, v] : status_seq)
    std::printf(" %s=%d", k.c_str(), v);
  std::printf("   qp:");
  for (const auto& [k, v] : status_qp)
    std::printf(" %s=%d", k.c_str(), v);
  std::printf("\n\n");
}

void BM_Sequential(benchmark::State& state) {
  SequentialOptimizer seq;
  ContactSolution s;
  std::size_t i = 0;
  for (auto _ : state) {
    seq.solve(g_corpus[i].problem, s);
    benchmark::DoNotOptimize(s);
    i = (i + 1) % g_corpus.size();
  }
}
BENCHMARK(BM_Sequential);

void BM_Qp(benchmark::State& state) {
  QpOptimizer qp;
  ContactSolution s;
  std::size_t i = 0;
  for (auto _ : state) {
    qp.solve(g_corpus[i].problem, s);
    benchmark::DoNotOptimize(s);
    i = (i + 1) % g_corpus.size();
  }
}
BENCHMARK(BM_Qp);

}  // namespace

int main(int argc, char** argv) {
  std::string corpus_path;
  int count = 10000;
  int reps = 3;
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--corpus") == 0 && i + 1 < argc) {
      corpus_path = argv[++i];
    } else if (std::strcmp(argv[i], "--count") == 0 && i + 1 < argc) {
      count = std::max(1, std::atoi(argv[++i]));
    } else if (std::strcmp(argv[i], "--reps") == 0 && i + 1 < argc) {
      reps = std::max(1, std::atoi(argv[++i]));
    } else {
      rest.push_back(argv[i]);
    }
  }
  try {
    g_corpus = corpus_path.empty() ? bench::generate_corpus(count, 20240601)
                                   : bench::read_corpus(corpus_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-bench-contact: error: %s\n", e.what());
    return 1;
  }
  if (g_corpus.empty()) {
    std::fprintf(stderr, "poise-bench-contact: error: empty corpus\n");
    return 1;
  }
  std::printf("poise-bench-contact: corpus %s\n",
              corpus_path.empty() ? "generated (seed 20240601)" : corpus_path.c_str());
  corpus_report(reps);
  int bargc = static_cast<int>(rest.size());
  benchmark::Initialize(&bargc, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
