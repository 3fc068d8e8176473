#pragma once

// The contact optimiser as a node or the CLI sees it: one object created at start with a method,
// one solve() per problem.

#include <optional>
#include <string_view>

#include "poise/contact/contact_problem.hpp"
#include "poise/contact/qp_optimizer.hpp"
#include "poise/contact/sequential_optimizer.hpp"

namespace poise::contact {

/// Which implementation solves the problems.
enum class Method : std::uint8_t {
  kSequential = 0,  ///< the paper's NNLS + BVLS method (SequentialOptimizer)
  kQp = 1,          ///< one dual active-set QP (QpOptimizer)
};

/// "sequential" or "qp".
const char* to_string(Method m);
/// Parses "sequential" / "qp"; std::nullopt otherwise.
std::optional<Method> parse_method(std::string_view name);

/// Parses "lexicographic" / "weighted"; std::nullopt otherwise.
std::optional<Priority> parse_priority(std::string_view name);
/// Parses "independent" / "friction-coupled"; std::nullopt otherwise.
std::optional<TorsionLimit> parse_torsion_limit(std::string_view name);

/// Facade selecting one method at construction. Construct once (allocates); solve() never
/// allocates, never throws and never outputs a non-finite number.
class ContactOptimizer {
 public:
  explicit ContactOptimizer(Method method = Method::kSequential) : method_(method) {}

  void solve(const ContactProblem& problem, ContactSolution& solution) {
    if (method_ == Method::kSequential) {
      sequential_.solve(problem, solution);
    } else {
      qp_.solve(problem, solution);
    }
  }
  Method method() const { return method_; }
  SequentialOptimizer& sequential() { return sequential_; }
  QpOptimizer& qp() { return qp_; }

 private:
  Method method_;
  SequentialOptimizer sequential_;
  QpOptimizer qp_;
};

}  // namespace poise::contact
