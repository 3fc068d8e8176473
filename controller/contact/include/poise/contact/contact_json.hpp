#pragma once

// JSON form of the contact problem and solution (the fields of the contact-problem / solution
// topics; SI units, world frame). Documented in controller/contact/README.md. Configuration-time
// code: allocates and throws, never used in the 1 kHz loop.

#include <array>
#include <string>

#include <nlohmann/json.hpp>

#include "poise/contact/contact_problem.hpp"

namespace poise::contact {

/// Parses one problem. Throws std::invalid_argument naming the bad field (e.g.
/// "feet[1].orientation_wxyz: expected an array of 4 numbers"). `present` tells which feet the JSON
/// listed (index 0 right, 1 left), so that the solution lists the same feet.
ContactProblem problem_from_json(const nlohmann::json& j, std::array<bool, kMaxFeet>* present);

/// The solution as JSON; feet listed where present[i]. solve_time_us < 0 omits the field.
nlohmann::json solution_to_json(const ContactSolution& s, const std::array<bool, kMaxFeet>& present,
                                double solve_time_us);

}  // namespace poise::contact
