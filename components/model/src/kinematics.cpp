// Forward kinematics, frames and Jacobians.
#include "poise/model/kinematics.hpp"

#include "detail.hpp"

namespace poise::model {

namespace detail {

void joint_transform(const Model& model, int b, double qj, SE3& liMi) {
  const SE3& X0 = model.X_parent_joint[b];
  const Vector3& u = model.axis[b];
  if (model.joint_type[b] == JointType::kPrismatic) {
    liMi.R = X0.R;
    liMi.p = X0.p + X0.R * (u * qj);
    return;
  }
  const double s = std::sin(qj), c = std::cos(qj);
  liMi.p = X0.p;
  const auto R0 = X0.R.col(0), R1 = X0.R.col(1), R2 = X0.R.col(2);
  switch (model.axis_id[b]) {
    case 0:  // rotation about +x
      liMi.R.col(0) = R0;
      liMi.R.col(1) = c * R1 + s * R2;
      liMi.R.col(2) = c * R2 - s * R1;
      return;
    case 1:  // +y
      liMi.R.col(0) = c * R0 - s * R2;
      liMi.R.col(1) = R1;
      liMi.R.col(2) = s * R0 + c * R2;
      return;
    case 2:  // +z
      liMi.R.col(0) = c * R0 + s * R1;
      liMi.R.col(1) = c * R1 - s * R0;
      liMi.R.col(2) = R2;
      return;
    default: {
      // Rodrigues: R = c I + s [u]x + (1 - c) u u^T
      Matrix3 Rj = (1.0 - c) * (u * u.transpose());
      Rj.diagonal().array() += c;
      Rj(0, 1) -= s * u.z();
      Rj(1, 0) += s * u.z();
      Rj(0, 2) += s * u.y();
      Rj(2, 0) -= s * u.y();
      Rj(1, 2) -= s * u.x();
      Rj(2, 1) += s * u.x();
      liMi.R.noalias() = X0.R * Rj;
    }
  }
}

template <int Level>
void fk_impl(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q,
             const double* v, const double* a) {
  // base
  data.oMi[0] = base_pose(q);
  data.liMi[0] = data.oMi[0];
  if constexpr (Level >= 1) {
    data.v[0] = Eigen::Map<const Vector6>(v);
    data.a_bias[0].setZero();
  }
  if constexpr (Level >= 2) data.a[0] = Eigen::Map<const Vector6>(a);
  for (int b = 1; b < model.nbodies; ++b) {
    const int p = model.parent[b];
    const int j = b - 1;
    SE3& liMi = data.liMi[b];
    joint_transform(model, b, q[7 + j], liMi);
    data.oMi[b] = data.oMi[p] * liMi;
    if constexpr (Level >= 1) {
      const Vector3 u_qd = model.axis[b] * v[6 + j];
      Motion& vb = data.v[b];
      Motion& bb = data.a_bias[b];
      vb = liMi.act_inv_motion(data.v[p]);
      bb = liMi.act_inv_motion(data.a_bias[p]);
      // c = v x S qd, added to both the bias and the full acceleration
      Motion c;
      if (model.joint_type[b] == JointType::kPrismatic) {
        c.head<3>() = vb.tail<3>().cross(u_qd);
        c.tail<3>().setZero();
        vb.head<3>() += u_qd;
      } else {
        c.head<3>() = vb.head<3>().cross(u_qd);
        c.tail<3>() = vb.tail<3>().cross(u_qd);
        vb.tail<3>() += u_qd;
      }
      bb += c;
      if constexpr (Level >= 2) {
        Motion& ab = data.a[b];
        ab = liMi.act_inv_motion(data.a[p]) + c;
        const Vector3 u_qdd = model.axis[b] * a[6 + j];
        if (model.joint_type[b] == JointType::kPrismatic)
          ab.head<3>() += u_qdd;
        else
          ab.tail<3>() += u_qdd;
      }
    }
  }
}

}  // namespace detail

void forward_kinematics(const Model& model, Data& data,
                        const Eigen::Ref<const Eigen::VectorXd>& q) {
  detail::fk_impl<0>(model, data, q, nullptr, nullptr);
}

void forward_kinematics(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& v) {
  detail::fk_impl<1>(model, data, q, v.data(), nullptr);
}

void forward_kinematics(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& v,
                        const Eigen::Ref<const Eigen::VectorXd>& a) {
  detail::fk_impl<2>(model, data, q, v.data(), a.data());
}

void update_frame_placements(const Model& model, Data& data) {
  for (std::size_t f = 0; f < model.frames.size(); ++f)
    data.oMf[f] = data.oMi[model.frames[f].body] * model.frames[f].X_BF;
}

SE3 frame_placement(const Model& model, const Data& data, int frame_id) {
  const Frame& fr = model.frames[frame_id];
  return data.oMi[fr.body] * fr.X_BF;
}

namespace {

// Velocity of the point p (body coordinates) and angular velocity, body axes.
inline void point_velocity_body(const Motion& V, const Vector3& p, Vector3& v_lin, Vector3& w) {
  w = V.tail<3>();
  v_lin = V.head<3>() + w.cross(p);
}

// Classical acceleration of the point p (body coordinates) on a body with twist V and spatial
// acceleration A (both body frame), returned world-aligned using R_WB.
inline Motion classical_point_acc(const Matrix3& R_WB, const Motion& V, const Motion& A,
                                  const Vector3& p) {
  Vector3 v_lin, w;
  point_velocity_body(V, p, v_lin, w);
  const Vector3 a_lin = A.head<3>() + A.tail<3>().cross(p) + w.cross(v_lin);
  Motion out;
  out.head<3>() = R_WB * a_lin;
  out.tail<3>() = R_WB * A.tail<3>();
  return out;
}

}  // namespace

Motion frame_velocity(const Model& model, const Data& data, int frame_id) {
  const Frame& fr = model.frames[frame_id];
  Vector3 v_lin, w;
  point_velocity_body(data.v[fr.body], fr.X_BF.p, v_lin, w);
  const Matrix3& R = data.oMi[fr.body].R;
  Motion out;
  out.head<3>() = R * v_lin;
  out.tail<3>() = R * w;
  return out;
}

Motion frame_classical_acceleration(const Model& model, const Data& data, int frame_id) {
  const Frame& fr = model.frames[frame_id];
  return classical_point_acc(data.oMi[fr.body].R, data.v[fr.body], data.a[fr.body], fr.X_BF.p);
}

Motion frame_jdot_v(const Model& model, const Data& data, int frame_id) {
  const Frame& fr = model.frames[frame_id];
  return classical_point_acc(data.oMi[fr.body].R, data.v[fr.body], data.a_bias[fr.body], fr.X_BF.p);
}

Motion frame_point_jdot_v(const Model& model, const Data& data, int frame_id, const Vector3& p_F) {
  const Frame& fr = model.frames[frame_id];
  return classical_point_acc(data.oMi[fr.body].R, data.v[fr.body], data.a_bias[fr.body],
                             fr.X_BF.act(p_F));
}

void compute_joint_jacobians(const Model& model, Data& data,
                             const Eigen::Ref<const Eigen::VectorXd>& q) {
  forward_kinematics(model, data, q);
  detail::fill_world_jacobian(model, data);
}

namespace detail {
void fill_world_jacobian(const Model& model, Data& data) {
  const SE3& X0 = data.oMi[0];
  for (int k = 0; k < 3; ++k) {
    data.J.col(k).head<3>() = X0.R.col(k);
    data.J.col(k).tail<3>().setZero();
    data.J.col(3 + k).tail<3>() = X0.R.col(k);
    data.J.col(3 + k).head<3>() = X0.p.cross(X0.R.col(k));
  }
  for (int b = 1; b < model.nbodies; ++b) {
    const SE3& X = data.oMi[b];
    const Vector3 u = X.R * model.axis[b];
    auto col = data.J.col(6 + b - 1);
    if (model.joint_type[b] == JointType::kPrismatic) {
      col.head<3>() = u;
      col.tail<3>().setZero();
    } else {
      col.head<3>() = X.p.cross(u);
      col.tail<3>() = u;
    }
  }
}
}  // namespace detail

void frame_point_jacobian(const Model& model, const Data& data, int frame_id, const Vector3& p_F,
                          Eigen::Ref<Matrix6X> J) {
  const Frame& fr = model.frames[frame_id];
  const Vector3 p_W = data.oMi[fr.body].act(fr.X_BF.act(p_F));
  J.setZero();
  for (int k : model.support[fr.body]) {
    const auto src = data.J.col(k);
    J.col(k).head<3>() = src.head<3>() - p_W.cross(src.tail<3>());
    J.col(k).tail<3>() = src.tail<3>();
  }
}

void frame_jacobian(const Model& model, const Data& data, int frame_id, Eigen::Ref<Matrix6X> J) {
  frame_point_jacobian(model, data, frame_id, Vector3::Zero(), J);
}

}  // namespace poise::model
