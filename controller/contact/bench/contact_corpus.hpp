#pragma once

// Corpus of contact problems for the benchmark, from two sources:
// - random: feasible and infeasible standing states, single and double support, feet tilted up to
//   +-10 deg, generated from a fixed seed (generate_corpus);
// - recorded: the problems the balance controller posed, tick by tick, while the simulator ran the
//   paper's push scenarios (poise-contact-record, contact_record_main.cpp).
// A text file form (one problem per line) lets other solvers be run on exactly the same problems.

#include <cstdint>
#include <string>
#include <vector>

#include "poise/contact/contact_problem.hpp"

namespace poise::contact::bench {

enum class Kind : int {
  kFeasibleDouble = 0,   ///< random, feasible by construction, double support
  kFeasibleSingle = 1,   ///< random, feasible by construction, single support
  kArbitraryDouble = 2,  ///< random desired rate (mostly infeasible), double support
  kArbitrarySingle = 3,  ///< random desired rate (mostly infeasible), single support
  kRecordedDouble = 4,   ///< recorded from a simulated scenario, double support
  kRecordedSingle = 5,   ///< recorded from a simulated scenario, single support
};
const char* to_string(Kind k);
inline bool is_recorded(Kind k) {
  return k == Kind::kRecordedDouble || k == Kind::kRecordedSingle;
}
inline bool is_feasible_by_construction(Kind k) {
  return k == Kind::kFeasibleDouble || k == Kind::kFeasibleSingle;
}

struct CorpusEntry {
  Kind kind;
  ContactProblem problem;
};

/// `count` problems from `seed`: 40 % feasible double support, 20 % feasible single support,
/// 25 % arbitrary (mostly infeasible) double support, 15 % arbitrary single support.
std::vector<CorpusEntry> generate_corpus(int count, std::uint32_t seed);

/// Text form: a header line, then one problem per line (lines starting with '#' are comments)
/// (kind, mass, gravity, com, k_dot_d, l_dot_d, weights w_k eps_f eps_cop eps_tau, then per foot:
/// in_contact, R_WF row-major, p_WF, sole x_min x_max y_min y_max, safety_margin, ankle_height, mu,
/// mu_torsion). Throws std::runtime_error naming the file and line on failure. `comments` are
/// written after the header as '# ' lines (provenance).
void write_corpus(const std::string& path, const std::vector<CorpusEntry>& corpus,
                  const std::vector<std::string>& comments = {});
std::vector<CorpusEntry> read_corpus(const std::string& path);

}  // namespace poise::contact::bench
