// RNEA and CRBA in body coordinates (Featherstone, Pinocchio-style model/data).
#include "poise/model/dynamics.hpp"

#include "detail.hpp"
#include "poise/model/kinematics.hpp"

namespace poise::model {

void clear_external_forces(Data& data) {
  for (Force& f : data.f_ext_W)
    f.setZero();
}

void add_external_wrench(const Model& model, Data& data, int frame_id, const Vector3& point_W,
                         const Vector3& force_W, const Vector3& torque_W) {
  Force& F = data.f_ext_W[model.frames[frame_id].body];
  data.any_f_ext = true;
  F.head<3>() += force_W;
  F.tail<3>() += torque_W + point_W.cross(force_W);
}

const Eigen::VectorXd& rnea(const Model& model, Data& data,
                            const Eigen::Ref<const Eigen::VectorXd>& q,
                            const Eigen::Ref<const Eigen::VectorXd>& v,
                            const Eigen::Ref<const Eigen::VectorXd>& a) {
  // Forward pass. Gravity enters as a fictitious upward acceleration of the base.
  SE3& X0 = data.oMi[0];
  X0 = base_pose(q);
  data.liMi[0] = X0;
  data.v[0] = v.head<6>();
  Motion a_gf0 = a.head<6>();
  a_gf0.head<3>() -= X0.R.transpose() * model.gravity;
  data.a_gf[0] = a_gf0;
  {
    const Inertia& I = model.inertia[0];
    data.f[0] = I * a_gf0 + cross_force(data.v[0], I * data.v[0]);
    if (data.any_f_ext) data.f[0] -= X0.act_inv_force(data.f_ext_W[0]);
  }
  const bool ext = data.any_f_ext;
  for (int b = 1; b < model.nbodies; ++b) {
    const int p = model.parent[b];
    const int j = b - 1;
    SE3& liMi = data.liMi[b];
    detail::joint_transform(model, b, q[7 + j], liMi);
    if (ext) data.oMi[b] = data.oMi[p] * liMi;
    const Vector3 u_qd = model.axis[b] * v[6 + j];
    const Vector3 u_qdd = model.axis[b] * a[6 + j];
    Motion& vb = data.v[b];
    Motion& ab = data.a_gf[b];
    vb = liMi.act_inv_motion(data.v[p]);
    ab = liMi.act_inv_motion(data.a_gf[p]);
    if (model.joint_type[b] == JointType::kPrismatic) {
      // v x [u qd; 0] = [w x u qd; 0]
      ab.head<3>() += vb.tail<3>().cross(u_qd) + u_qdd;
      vb.head<3>() += u_qd;
    } else {
      // v x [0; u qd] = [v_lin x u qd; w x u qd]
      ab.head<3>() += vb.head<3>().cross(u_qd);
      ab.tail<3>() += vb.tail<3>().cross(u_qd) + u_qdd;
      vb.tail<3>() += u_qd;
    }
    const Inertia& I = model.inertia[b];
    data.f[b] = I * ab + cross_force(vb, I * vb);
    if (ext) data.f[b] -= data.oMi[b].act_inv_force(data.f_ext_W[b]);
  }
  // Backward pass.
  for (int b = model.nbodies - 1; b > 0; --b) {
    data.tau[6 + b - 1] = detail::project_force(model, b, data.f[b]);
    data.f[model.parent[b]] += data.liMi[b].act_force(data.f[b]);
  }
  data.tau.head<6>() = data.f[0];
  return data.tau;
}

const Eigen::MatrixXd& crba(const Model& model, Data& data,
                            const Eigen::Ref<const Eigen::VectorXd>& q) {
  forward_kinematics(model, data, q);
  for (int b = 0; b < model.nbodies; ++b)
    data.Ycrb[b] = model.inertia[b];
  for (int b = model.nbodies - 1; b > 0; --b)
    data.Ycrb[model.parent[b]] += data.Ycrb[b].transformed(data.liMi[b]);

  auto& M = data.M;
  for (int b = model.nbodies - 1; b > 0; --b) {
    const int i = 6 + b - 1;
    Force F = data.Ycrb[b] * detail::motion_subspace(model, b);
    M(i, i) = detail::project_force(model, b, F);
    int k = b;
    while (model.parent[k] > 0) {
      F = data.liMi[k].act_force(F);
      k = model.parent[k];
      const int jk = 6 + k - 1;
      M(jk, i) = M(i, jk) = detail::project_force(model, k, F);
    }
    F = data.liMi[k].act_force(F);  // into the base frame
    M.block<6, 1>(0, i) = F;
    M.block<1, 6>(i, 0) = F.transpose();
  }
  M.topLeftCorner<6, 6>() = data.Ycrb[0].matrix();
  return M;
}

}  // namespace poise::model
