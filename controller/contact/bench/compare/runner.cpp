// One side of compare_revisions.sh: the sequential optimiser of one source tree, compiled with its
// namespace renamed (-Dpoise=poise_<TAG>) so that two revisions link into one program. Exposes
// C functions <TAG>_make / _count / _time / _result over the double-support problems of the
// benchmark's random corpus (seed 20240601) plus an optional recorded corpus file.
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <vector>

#include "contact_corpus.hpp"
#include "poise/contact/sequential_optimizer.hpp"

#ifndef TAG
#error "compile with -DTAG=A or -DTAG=B"
#endif
#define POISE_CAT2(a, b) a##b
#define POISE_CAT(a, b) POISE_CAT2(a, b)

namespace {
using namespace poise::contact;
struct Side {
  std::vector<ContactProblem> problems;
  SequentialOptimizer seq;
  ContactSolution solution;
};
}  // namespace

extern "C" void* POISE_CAT(TAG, _make)(const char* recorded, int dense) {
  auto* side = new Side;
#ifdef POISE_COMPARE_DENSE_SWITCH
  side->seq.set_use_normal_equations(dense == 0);
#else
  (void)dense;
#endif
  std::vector<bench::CorpusEntry> corpus = bench::generate_corpus(10000, 20240601);
  if (recorded != nullptr && *recorded != '\0') {
    const std::vector<bench::CorpusEntry> more = bench::read_corpus(recorded);
    corpus.insert(corpus.end(), more.begin(), more.end());
  }
  for (const bench::CorpusEntry& e : corpus)
    if (e.problem.feet[0].in_contact && e.problem.feet[1].in_contact)
      side->problems.push_back(e.problem);
  return side;
}

extern "C" int POISE_CAT(TAG, _count)(void* s) {
  return static_cast<int>(static_cast<Side*>(s)->problems.size());
}

extern "C" double POISE_CAT(TAG, _time)(void* s, int i, int reps) {
  Side* side = static_cast<Side*>(s);
  double best = 1e300;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    side->seq.solve(side->problems[i], side->solution);
    const auto t1 = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  return best;
}

/// Summary of the last answer (to check that both sides solve the same problems alike).
extern "C" double POISE_CAT(TAG, _result)(void* s) {
  const ContactSolution& x = static_cast<Side*>(s)->solution;
  return x.feet[0].force_W.norm() + x.feet[1].force_W.norm() + x.feet[0].cop_F.x();
}
