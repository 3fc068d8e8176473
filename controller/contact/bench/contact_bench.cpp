// poise-bench-contact: timing and quality of the two contact optimisers on one corpus, in one run.
//
// Part 1 (corpus report): every problem is solved by every variant in turn, each timed with
// std::chrono::steady_clock as the minimum of --reps repetitions (to drop interrupts). Printed, per
// group of problems (source: random / recorded from the simulator; support: single / double):
// median and p99 of each method and stage, the QP / sequential time ratio, and the objective gap
// between the two methods. The sequential method is timed twice: as it runs (normal equations
// formed from the structure of Phi and Psi) and with the dense NNLS / BVLS calls it used before
// (SequentialOptimizer::set_use_normal_equations(false)), so the speed-up is measured in the
// same run on the same problems.
// Part 2: Google Benchmark loops over the same corpus (mean time per solve).
//
//   poise-bench-contact [--corpus FILE | --count N --seed S] [--recorded FILE]... [--reps R]
//                       [--benchmark_* flags]
// Random part: --corpus FILE (written by poise-contact-corpus), else N (default 10000) problems
// generated in memory from seed S (default 20240601). --recorded FILE (poise-contact-record)
// appends problems recorded from the simulator's push scenarios.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
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

constexpr double kNone = std::numeric_limits<double>::quiet_NaN();

/// Everything measured on one problem.
struct Record {
  bool recorded = false;
  bool two = false;  // double support
  bool feasible = false;
  double t_seq = 0, t_seq_dense = 0, t_qp = 0, t_qp2 = 0, t_dual = 0;
  // Stage times exist for double support only (NaN otherwise).
  double t_nnls = kNone, t_nnls_dense = kNone, t_bvls = kNone, t_bvls_dense = kNone;
  double gap = 0;         // (T_qp - T_seq) / (m g)^2, tracking cost
  double gap2 = 0;        // same with the 2-pass QP
  double dense_diff = 0;  // |answer(normal eq.) - answer(dense)| / (m g)
  double jqp_gap = 0;     // (J_qp(qp) - J_qp(seq)) / (m g)^2 where comparable
  bool comparable = false, jqp_le = false;
  bool qp_adjusted = false, qp2_adjusted = false;
  double err_seq = 0, err_qp = 0;  // |h_dot_a - h_dot_d| / (m g), feasible problems
  ContactStatus st_seq{}, st_qp{};
};

double wrench_difference(const ContactSolution& a, const ContactSolution& b) {
  double d = 0.0;
  for (int i = 0; i < kMaxFeet; ++i) {
    d = std::max(d, (a.feet[i].force_W - b.feet[i].force_W).norm());
    d = std::max(d, (a.feet[i].torque_ankle_W - b.feet[i].torque_ankle_W).norm());
  }
  return d;
}

std::vector<Record> measure(int reps) {
  SequentialOptimizer seq;
  SequentialOptimizer seq_dense;
  seq_dense.set_use_normal_equations(false);
  SequentialOptimizer stage_runner;  // stages timed on a copy of seq's stage data
  SequentialOptimizer stage_runner_dense;
  stage_runner_dense.set_use_normal_equations(false);
  QpOptimizer qp;
  QpOptimizer qp2;
  qp2.set_torsion_passes(2);
  DualQp dual(QpOptimizer::kMaxVars, 0, QpOptimizer::kMaxConstraints);
  Eigen::Matrix<double, QpOptimizer::kMaxVars, 1> y;
  ContactSolution s_seq, s_dense, s_qp, s_qp2;
  std::vector<Record> out;
  out.reserve(g_corpus.size());

  for (const CorpusEntry& e : g_corpus) {
    const ContactProblem& p = e.problem;
    Record r;
    r.recorded = bench::is_recorded(e.kind);
    r.two = p.feet[0].in_contact && p.feet[1].in_contact;
    r.feasible = bench::is_feasible_by_construction(e.kind);
    const double mg = p.mass * p.gravity.norm();
    r.t_seq = time_us(reps, [&] { seq.solve(p, s_seq); });
    r.t_seq_dense = time_us(reps, [&] { seq_dense.solve(p, s_dense); });
    r.dense_diff = wrench_difference(s_seq, s_dense) / mg;
    if (r.two) {
      stage_runner.solve(p, s_dense);  // fills its stages (same data as seq's)
      stage_runner_dense.solve(p, s_dense);
      r.t_nnls = time_us(reps, [&] { stage_runner.solve_force_stage(); });
      r.t_nnls_dense = time_us(reps, [&] { stage_runner_dense.solve_force_stage(); });
      r.t_bvls = time_us(reps, [&] { stage_runner.solve_cop_stage(); });
      r.t_bvls_dense = time_us(reps, [&] { stage_runner_dense.solve_cop_stage(); });
    }
    r.t_qp = time_us(reps, [&] { qp.solve(p, s_qp); });
    {
      const int n = qp.num_vars();
      const int m = n / QpOptimizer::kVarsPerFoot * QpOptimizer::kConstraintsPerFoot;
      const auto& G = qp.hessian();
      const auto& g = qp.gradient();
      const auto& A = qp.inequality_matrix();
      const auto& b = qp.inequality_bounds();
      r.t_dual = time_us(reps, [&] {
        dual.solve(G.topLeftCorner(n, n), g.head(n), G.topRows(0).leftCols(n), g.head(0),
                   A.topLeftCorner(m, n), b.head(m), y.head(n));
      });
    }
    r.t_qp2 = time_us(reps, [&] { qp2.solve(p, s_qp2); });
    r.qp_adjusted = qp.adjusted();
    r.qp2_adjusted = qp2.adjusted();
    r.st_seq = s_seq.status;
    r.st_qp = s_qp.status;
    const double mg2 = mg * mg;
    const double tc_seq = tracking_cost(p, s_seq);
    r.gap = (tracking_cost(p, s_qp) - tc_seq) / mg2;
    r.gap2 = (tracking_cost(p, s_qp2) - tc_seq) / mg2;
    // J_qp comparison (double support) where the sequential answer lies in the QP's feasible set.
    bool in_set = r.two;
    for (int i = 0; in_set && i < kMaxFeet; ++i) {
      const FootWrench& w = s_seq.feet[i];
      const Eigen::Vector3d f = p.feet[i].R_WF.transpose() * w.force_W;
      const double m_z = w.normal_torque + w.cop_F.x() * f.y() - w.cop_F.y() * f.x();
      in_set = std::abs(m_z) <= p.feet[i].mu_torsion * f.z();
    }
    if (in_set) {
      r.comparable = true;
      const double j_seq = qp_objective(p, s_seq, seq.stages().rho);
      r.jqp_gap = (qp.raw_objective() - j_seq) / mg2;
      r.jqp_le = qp.raw_objective() <= j_seq * (1 + 1e-9) + 1e-9;
    }
    auto err = [&](const ContactSolution& s) {
      return std::sqrt((p.l_dot_desired - s.l_dot_admissible).squaredNorm() +
                       (p.k_dot_desired - s.k_dot_admissible).squaredNorm()) /
             mg;
    };
    r.err_seq = err(s_seq);
    r.err_qp = err(s_qp);
    out.push_back(r);
  }
  return out;
}

struct Group {
  const char* name;
  std::function<bool(const Record&)> member;
};

std::vector<double> column(const std::vector<Record>& rs, const Group& g, double Record::*field) {
  std::vector<double> v;
  for (const Record& r : rs)
    if (g.member(r) && !std::isnan(r.*field)) v.push_back(r.*field);
  return v;
}

// The groups of problems every table has a row for.
const std::vector<Group>& report_groups() {
  static const std::vector<Group> groups = {
      {"all", [](const Record&) { return true; }},
      {"all, single support", [](const Record& r) { return !r.two; }},
      {"all, double support", [](const Record& r) { return r.two; }},
      {"random", [](const Record& r) { return !r.recorded; }},
      {"random, single", [](const Record& r) { return !r.recorded && !r.two; }},
      {"random, double", [](const Record& r) { return !r.recorded && r.two; }},
      {"recorded", [](const Record& r) { return r.recorded; }},
      {"recorded, single", [](const Record& r) { return r.recorded && !r.two; }},
      {"recorded, double", [](const Record& r) { return r.recorded && r.two; }},
  };
  return groups;
}

void print_corpus(int reps) {
  std::map<std::string, int> composition;
  for (const CorpusEntry& e : g_corpus)
    ++composition[bench::to_string(e.kind)];
  std::printf("Corpus: %zu problems (", g_corpus.size());
  const char* sep = "";
  for (const auto& [k, v] : composition) {
    std::printf("%s%s %d", sep, k.c_str(), v);
    sep = ", ";
  }
  std::printf("); timings = min of %d repetitions per problem, steady_clock\n\n", reps);
}

// Time per problem of each method and stage, median / p99, per group.
void print_times(const std::vector<Record>& rs, const std::vector<Group>& groups) {
  struct Col {
    const char* title;
    double Record::*field;
  };
  const std::vector<Col> cols = {
      {"seq total", &Record::t_seq}, {"seq dense", &Record::t_seq_dense},
      {"NNLS", &Record::t_nnls},     {"NNLS dense", &Record::t_nnls_dense},
      {"BVLS", &Record::t_bvls},     {"BVLS dense", &Record::t_bvls_dense},
      {"QP total", &Record::t_qp},   {"QP solve", &Record::t_dual},
      {"QP 2-pass", &Record::t_qp2},
  };
  std::printf(
      "Time per problem, microseconds, median / p99. seq = the paper's sequential method as it "
      "runs (stages on\nthe normal equations); seq dense = the same with the dense NNLS/BVLS "
      "calls used before (same run);\nNNLS = stage (21)-(26) 14x8, BVLS = stage (27)-(30) 9x6 "
      "(double support only); QP = one dual active-set QP\n(Goldfarb-Idnani), QP solve = its "
      "DualQp call alone; ratio = median QP total / median seq total.\n");
  std::printf("%-20s %6s", "group", "n");
  for (const Col& c : cols)
    std::printf(" %15s", c.title);
  std::printf(" %6s\n", "ratio");
  for (const Group& g : groups) {
    const std::vector<double> seq = column(rs, g, &Record::t_seq);
    if (seq.empty()) continue;
    std::printf("%-20s %6zu", g.name, seq.size());
    for (const Col& c : cols) {
      const std::vector<double> v = column(rs, g, c.field);
      if (v.empty()) {
        std::printf(" %15s", "-");
      } else {
        char cell[32];
        std::snprintf(cell, sizeof cell, "%.3f/%.3f", percentile(v, 0.5), percentile(v, 0.99));
        std::printf(" %15s", cell);
      }
    }
    std::printf(" %6.2f\n", percentile(column(rs, g, &Record::t_qp), 0.5) / percentile(seq, 0.5));
  }
}

// The sequential method's speed-up from the normal equations (double support), against the paper.
void print_speedup(const std::vector<Record>& rs, const std::vector<Group>& groups) {
  const Group all_double = groups[2];
  const double before = percentile(column(rs, all_double, &Record::t_seq_dense), 0.5);
  const double after = percentile(column(rs, all_double, &Record::t_seq), 0.5);
  std::printf(
      "\nSequential, double support, median: %.3f us (normal equations) vs %.3f us (dense stages): "
      "%.2fx faster.\n",
      after, before, before / after);
  std::printf(
      "Paper (Core2 2.66 GHz): NNLS 9 us, BVLS 6-10 us, QP 30 us. Target: sequential median "
      "<= 2 us.\n\n");
}

// The objective gap between the methods, per group.
void print_gaps(const std::vector<Record>& rs, const std::vector<Group>& groups) {
  std::printf(
      "Objective gap between the methods, tracking cost T = |l_dot_d - l_dot_a|^2 + w_k "
      "|k_dot_d - k_dot_a|^2,\n(T_qp - T_seq) / (m g)^2, and J_qp(qp) vs J_qp(seq) where the "
      "sequential answer is QP-feasible:\n");
  std::printf("%-20s %6s %11s %11s %11s %6s %6s %6s  %8s %8s %11s\n", "group", "n", "gap median",
              "gap p1", "gap p99", "QP<", "QP>", "QP=", "J-comp.", "J_qp<=", "J gap max");
  for (const Group& g : groups) {
    const std::vector<double> gap = column(rs, g, &Record::gap);
    if (gap.empty()) continue;
    int lower = 0, higher = 0, equal = 0, comparable = 0, le = 0;
    std::vector<double> jgap;
    for (const Record& r : rs) {
      if (!g.member(r)) continue;
      lower += r.gap < -1e-9 ? 1 : 0;
      higher += r.gap > 1e-9 ? 1 : 0;
      equal += std::abs(r.gap) <= 1e-9 ? 1 : 0;
      if (r.comparable) {
        ++comparable;
        le += r.jqp_le ? 1 : 0;
        jgap.push_back(r.jqp_gap);
      }
    }
    std::printf("%-20s %6zu %11.3e %11.3e %11.3e %6d %6d %6d  %8d %8d %11.3e\n", g.name, gap.size(),
                percentile(gap, 0.5), percentile(gap, 0.01), percentile(gap, 0.99), lower, higher,
                equal, comparable, le, jgap.empty() ? 0.0 : percentile(jgap, 1.0));
  }
}

// Whole-corpus figures: round-off of the dense stages, QP clean-ups, accuracy, statuses.
void print_totals(const std::vector<Record>& rs) {
  int qp_adjusted = 0, qp2_adjusted = 0, feasible = 0, ok_seq = 0, ok_qp = 0;
  std::vector<double> gap2, err_seq, err_qp, dense_diff;
  std::map<std::string, int> status_seq, status_qp;
  for (const Record& r : rs) {
    qp_adjusted += r.qp_adjusted ? 1 : 0;
    qp2_adjusted += r.qp2_adjusted ? 1 : 0;
    gap2.push_back(r.gap2);
    dense_diff.push_back(r.dense_diff);
    ++status_seq[to_string(r.st_seq)];
    ++status_qp[to_string(r.st_qp)];
    if (r.feasible) {
      ++feasible;
      ok_seq += r.st_seq == ContactStatus::kOk ? 1 : 0;
      ok_qp += r.st_qp == ContactStatus::kOk ? 1 : 0;
      err_seq.push_back(r.err_seq);
      err_qp.push_back(r.err_qp);
    }
  }
  std::printf(
      "\nNormal-equation vs dense stages, answer difference max |wrench| / (m g): %.2e "
      "(round-off)\n",
      percentile(dense_diff, 1.0));
  std::printf("QP answers changed by the torsion clean-up (paper model): %d of %zu\n", qp_adjusted,
              rs.size());
  std::printf(
      "QP with torsion refinement (2 passes): clean-up needed on %d; tracking gap vs sequential "
      "median %.3e p1 %.3e p99 %.3e\n",
      qp2_adjusted, percentile(gap2, 0.5), percentile(gap2, 0.01), percentile(gap2, 0.99));
  std::printf(
      "Random feasible problems (%d): status ok  seq %d, qp %d;  |h_dot_a - h_dot_d| / (m g) "
      "median seq %.2e qp %.2e, p99 seq %.2e qp %.2e\n",
      feasible, ok_seq, ok_qp, percentile(err_seq, 0.5), percentile(err_qp, 0.5),
      percentile(err_seq, 0.99), percentile(err_qp, 0.99));
  std::printf("Status counts  sequential:");
  for (const auto& [k, v] : status_seq)
    std::printf(" %s=%d", k.c_str(), v);
  std::printf("   qp:");
  for (const auto& [k, v] : status_qp)
    std::printf(" %s=%d", k.c_str(), v);
  std::printf("\n\n");
}

void report(const std::vector<Record>& rs, int reps) {
  const std::vector<Group>& groups = report_groups();
  print_corpus(reps);
  print_times(rs, groups);
  print_speedup(rs, groups);
  print_gaps(rs, groups);
  print_totals(rs);
}

// One solve per iteration, cycling through the corpus.
template <typename Optimizer>
void solve_loop(benchmark::State& state, Optimizer& optimizer) {
  ContactSolution s;
  std::size_t i = 0;
  for (auto _ : state) {
    optimizer.solve(g_corpus[i].problem, s);
    benchmark::DoNotOptimize(s);
    i = (i + 1) % g_corpus.size();
  }
}

void BM_Sequential(benchmark::State& state) {
  SequentialOptimizer seq;
  seq.set_use_normal_equations(state.range(0) != 0);
  solve_loop(state, seq);
}
BENCHMARK(BM_Sequential)->ArgName("normal_equations")->Arg(1)->Arg(0);

void BM_Qp(benchmark::State& state) {
  QpOptimizer qp;
  solve_loop(state, qp);
}
BENCHMARK(BM_Qp);

}  // namespace

int main(int argc, char** argv) {
  std::string corpus_path;
  std::vector<std::string> recorded_paths;
  int count = 10000;
  int reps = 3;
  unsigned seed = 20240601;
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--corpus") == 0 && i + 1 < argc) {
      corpus_path = argv[++i];
    } else if (std::strcmp(argv[i], "--recorded") == 0 && i + 1 < argc) {
      recorded_paths.emplace_back(argv[++i]);
    } else if (std::strcmp(argv[i], "--count") == 0 && i + 1 < argc) {
      count = std::max(0, std::atoi(argv[++i]));
    } else if (std::strcmp(argv[i], "--seed") == 0 && i + 1 < argc) {
      seed = static_cast<unsigned>(std::strtoul(argv[++i], nullptr, 10));
    } else if (std::strcmp(argv[i], "--reps") == 0 && i + 1 < argc) {
      reps = std::max(1, std::atoi(argv[++i]));
    } else {
      rest.push_back(argv[i]);
    }
  }
  try {
    g_corpus =
        corpus_path.empty() ? bench::generate_corpus(count, seed) : bench::read_corpus(corpus_path);
    for (const std::string& path : recorded_paths) {
      const std::vector<CorpusEntry> more = bench::read_corpus(path);
      g_corpus.insert(g_corpus.end(), more.begin(), more.end());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-bench-contact: error: %s\n", e.what());
    return 1;
  }
  if (g_corpus.empty()) {
    std::fprintf(stderr, "poise-bench-contact: error: empty corpus\n");
    return 1;
  }
  std::printf("poise-bench-contact: random part %s", corpus_path.c_str());
  if (corpus_path.empty()) std::printf("generated (seed %u)", seed);
  for (const std::string& path : recorded_paths)
    std::printf(", recorded %s", path.c_str());
  std::printf("\n");
  report(measure(reps), reps);
  int bargc = static_cast<int>(rest.size());
  benchmark::Initialize(&bargc, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
