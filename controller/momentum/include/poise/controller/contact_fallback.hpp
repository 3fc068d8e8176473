#pragma once
// Contact wrenches used when the optimiser's solution of a tick is late or unusable.

#include <Eigen/Core>
#include <array>

#include "poise/contact/contact_problem.hpp"

namespace poise::controller {

/// Gravity-compensating distribution over the support feet of `problem` (feet[i].in_contact):
/// the weight -m g is shared by the feet in proportion to how close the CoM is (horizontally) to
/// each ankle, and ankle torques cancel the moment of those forces about the CoM, so that the
/// admissible rate is zero: sum f_i = -m g, sum (r_i - r_G) x f_i + tau_i = 0.
/// No support: every wrench zero and the rate is [0; m g]. Writes `solution` (feet, rates,
/// status kCompromised). Allocation-free.
void gravity_distribution(const contact::ContactProblem& problem,
                          contact::ContactSolution& solution);

/// Momentum rate of the given foot wrenches (support feet of `problem` only), paper (15)-(18):
/// [sum (r_i - r_G) x f_i + tau_i; m g + sum f_i] (dim 6). Allocation-free.
Eigen::Matrix<double, 6, 1> momentum_rate_of_wrenches(const contact::ContactProblem& problem,
                                                      const contact::ContactSolution& solution);

}  // namespace poise::controller
