#pragma once

// Corpus of contact problems for the benchmark: random feasible and infeasible standing states,
// single and double support, feet tilted up to +-10 deg, generated from a fixed seed. A text file
// form (one problem per line) lets other solvers be run on exactly the same problems.
// TODO(simulator): add states recorded from push scenarios once the simulator exists.

#include <cstdint>
#include <string>
#include <vector>

#include "poise/contact/contact_problem.hpp"

namespace poise::contact::bench {

enum class Kind : int {
  kFeasibleDouble = 0,
  kFeasibleSingle = 1,
  kArbitraryDouble = 2,
  kArbitrarySingle = 3
};
const char* to_string(Kind k);

struct CorpusEntry {
  Kind kind;
  ContactProblem problem;
};

/// `count` problems from `seed`: 40 % feasible double support, 20 % feasible single support,
/// 25 % arbitrary (mostly infeasible) double support, 15 % arbitrary single support.
std::vector<CorpusEntry> generate_corpus(int count, std::uint32_t seed);

/// Text form: a header line, then one problem per line (kind, mass, gravity, com, k_dot_d,
/// l_dot_d, weights w_k eps_f eps_cop eps_tau, then per foot: in_contact, R_WF row-major,
/// p_WF, sole x_min x_max y_min y_max, safety_margin, ankle_height, mu, mu_torsion).
/// Throws std::runtime_error naming the file and line on failure.
void write_corpus(const std::string& path, const std::vector<CorpusEntry>& corpus);
std::vector<CorpusEntry> read_corpus(const std::string& path);

}  // namespace poise::contact::bench
