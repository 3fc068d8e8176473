#pragma once

#include <cstdint>

namespace poise::contact {

/// Result of one solve of the generic solvers (Nnls, Bvls, DualQp).
enum class SolverStatus : std::uint8_t {
  kOptimal = 0,         ///< KKT conditions hold to the solver tolerance.
  kIterationLimit = 1,  ///< Iteration cap hit; the output is the last iterate (see each solver).
  kInvalidInput = 2,    ///< Wrong size, non-finite entry or inconsistent bounds; output zeroed.
  kInfeasible = 3,      ///< (DualQp only) the constraints admit no point.
  kNotPositiveDefinite = 4,  ///< DualQp: the Hessian is not positive definite; Nnls / Bvls
                             ///< solve_normal(): a sub-problem too ill-conditioned for the
                             ///< normal equations (solve() with A handles it).
};

/// Short lower-case name of a status, e.g. "optimal" (static string, never null).
constexpr const char* to_string(SolverStatus s) {
  switch (s) {
    case SolverStatus::kOptimal:
      return "optimal";
    case SolverStatus::kIterationLimit:
      return "iteration_limit";
    case SolverStatus::kInvalidInput:
      return "invalid_input";
    case SolverStatus::kInfeasible:
      return "infeasible";
    case SolverStatus::kNotPositiveDefinite:
      return "not_positive_definite";
  }
  return "unknown";
}

}  // namespace poise::contact
