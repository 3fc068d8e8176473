#pragma once
// IDL (poise::msg, idl/contact_problem.idl, idl/contact_solution.idl) <-> contact library
// (poise::contact) conversions. Allocation-free, noexcept. Feet: index 0 = right, 1 = left in
// both. Quaternions: w, x, y, z in the IDL, unit norm.

#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>

#include "poise/contact/contact_optimizer.hpp"

namespace poise::contact_node {

/// msg -> library. IDL weights all 0 mean the paper's values (contact::ContactWeights{}).
/// Returns nullptr, or a static message naming a foot orientation that is not a unit quaternion
/// (|q| off 1 by more than 1e-6; such a problem must be answered as invalid input).
const char* from_msg(const msg::ContactProblem& in, contact::ContactProblem& out) noexcept;
/// library -> msg (header left untouched).
void to_msg(const contact::ContactProblem& in, msg::ContactProblem& out) noexcept;

/// library -> msg. `header` is copied from the problem; `solve_time_us` and `method` as given.
/// kSolverFailure has no IDL enumerator: it is sent as CONTACT_INVALID_INPUT (safe answer).
void to_msg(const contact::ContactSolution& in, const msg::Header& header, double solve_time_us,
            contact::Method method, msg::ContactSolution& out) noexcept;
/// msg -> library.
void from_msg(const msg::ContactSolution& in, contact::ContactSolution& out) noexcept;

msg::ContactStatus to_msg(contact::ContactStatus status) noexcept;
contact::ContactStatus from_msg(msg::ContactStatus status) noexcept;

}  // namespace poise::contact_node
