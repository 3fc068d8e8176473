#pragma once
// Centre of mass and centroidal momentum (Orin & Goswami). h_G = [k; l]: ANGULAR FIRST (paper
// order), k about the CoM, world axes. All functions are allocation-free.

#include <Eigen/Core>

#include "poise/model/data.hpp"
#include "poise/model/model.hpp"

namespace poise::model {

/// data.com (and data.mass); runs forward_kinematics(q).
void center_of_mass(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q);
/// data.com, data.vcom, data.hg (centroidal momentum) in one pass over the bodies; runs
/// forward_kinematics(q, v). The fast way to get CoM and momentum without A.
void centroidal_momentum(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                         const Eigen::Ref<const Eigen::VectorXd>& v);
/// data.Jcom (3 x nv) and data.com; runs compute_joint_jacobians(q).
void com_jacobian(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q);
/// Centroidal momentum matrix data.Ag (6 x nv, rows [k; l]), data.hg = Ag * v, data.com,
/// data.vcom, data.dAg_v (bias, 6), data.J (WORLD joint Jacobian), data.Jcom.
/// Also leaves forward_kinematics(q, v) results in data.
void centroidal_momentum_matrix(const Model& model, Data& data,
                                const Eigen::Ref<const Eigen::VectorXd>& q,
                                const Eigen::Ref<const Eigen::VectorXd>& v);

}  // namespace poise::model
