#pragma once
// Inverse dynamics (RNEA) with external wrenches and the joint-space mass matrix (CRBA).
// Rigid bodies only: URDF joint damping and friction are NOT included. Allocation-free.

#include <Eigen/Core>

#include "poise/model/data.hpp"
#include "poise/model/model.hpp"

namespace poise::model {

/// Sets every external wrench in data.f_ext_W to zero.
void clear_external_forces(Data& data);
/// Adds a wrench acting on the body that carries frame `frame_id`: force_W (3) applied at the
/// world point point_W (3) plus a pure torque_W (3), all world coordinates. Cumulative.
void add_external_wrench(const Model& model, Data& data, int frame_id, const Vector3& point_W,
                         const Vector3& force_W, const Vector3& torque_W);

/// Inverse dynamics: data.tau (dim nv) = M(q) a + C(q, v) v + g(q) - sum_k J_k^T F_k, where F_k are
/// the external wrenches in data.f_ext_W and gravity is model.gravity. tau[0:6] is the base
/// wrench (base frame, about the base origin) needed to realise the base acceleration a[0:6].
/// Also updates data.liMi, data.v (twists), data.a_gf (accelerations minus gravity) and data.f
/// (joint wrenches). data.oMi is updated only when external wrenches are set (it is needed for
/// them; skipping it saves ~15 %); data.a and data.a_bias are NOT updated. Returns data.tau.
const Eigen::VectorXd& rnea(const Model& model, Data& data,
                            const Eigen::Ref<const Eigen::VectorXd>& q,
                            const Eigen::Ref<const Eigen::VectorXd>& v,
                            const Eigen::Ref<const Eigen::VectorXd>& a);

/// Joint-space mass matrix data.M (nv x nv, both triangles filled); runs forward_kinematics(q).
const Eigen::MatrixXd& crba(const Model& model, Data& data,
                            const Eigen::Ref<const Eigen::VectorXd>& q);

}  // namespace poise::model
