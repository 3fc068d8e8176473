// Centre of mass and centroidal momentum matrix (composite-rigid-body form, world frame).
#include "poise/model/centroidal.hpp"

#include "detail.hpp"
#include "poise/model/kinematics.hpp"

namespace poise::model {

namespace {

// World-origin momentum [l; k_O] -> centroidal [k_G; l] about com.
inline Vector6 to_centroidal(const Force& h_O, const Vector3& com) {
  Vector6 h;
  h.tail<3>() = h_O.head<3>();
  h.head<3>() = h_O.tail<3>() - com.cross(h_O.head<3>());
  return h;
}

// data.oYcrb from data.oMi.
void composite_inertias_world(const Model& model, Data& data) {
  for (int b = 0; b < model.nbodies; ++b)
    data.oYcrb[b] = InertiaAtOrigin::from(model.inertia[b], data.oMi[b]);
  for (int b = model.nbodies - 1; b > 0; --b)
    data.oYcrb[model.parent[b]] += data.oYcrb[b];
}

}  // namespace

void center_of_mass(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q) {
  forward_kinematics(model, data, q);
  Vector3 mc = Vector3::Zero();
  double m = 0.0;
  for (int b = 0; b < model.nbodies; ++b) {
    const Inertia& I = model.inertia[b];
    mc += I.mass * data.oMi[b].act(I.com);
    m += I.mass;
  }
  data.mass = m;
  data.com = m > 0.0 ? Vector3(mc / m) : Vector3::Zero();
}

void centroidal_momentum(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                         const Eigen::Ref<const Eigen::VectorXd>& v) {
  forward_kinematics(model, data, q, v);
  Vector3 mc = Vector3::Zero();
  double m = 0.0;
  Force h_O = Force::Zero();
  for (int b = 0; b < model.nbodies; ++b) {
    const Inertia& I = model.inertia[b];
    mc += I.mass * data.oMi[b].act(I.com);
    m += I.mass;
    h_O += data.oMi[b].act_force(I * data.v[b]);
  }
  data.mass = m;
  data.com = m > 0.0 ? Vector3(mc / m) : Vector3::Zero();
  data.hg = to_centroidal(h_O, data.com);
  data.vcom = m > 0.0 ? Vector3(data.hg.tail<3>() / m) : Vector3::Zero();
}

void com_jacobian(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q) {
  compute_joint_jacobians(model, data, q);
  composite_inertias_world(model, data);
  const InertiaAtOrigin& Y0 = data.oYcrb[0];
  data.mass = Y0.mass;
  const double inv_m = data.mass > 0.0 ? 1.0 / data.mass : 0.0;
  data.com = Y0.h * inv_m;
  for (int k = 0; k < model.nv; ++k) {
    const int b = k < 6 ? 0 : k - 5;
    data.Jcom.col(k) = (data.oYcrb[b] * Motion(data.J.col(k))).head<3>() * inv_m;
  }
}

void centroidal_momentum_matrix(const Model& model, Data& data,
                                const Eigen::Ref<const Eigen::VectorXd>& q,
                                const Eigen::Ref<const Eigen::VectorXd>& v) {
  forward_kinematics(model, data, q, v);
  detail::fill_world_jacobian(model, data);
  composite_inertias_world(model, data);
  data.mass = data.oYcrb[0].mass;
  const double inv_m = data.mass > 0.0 ? 1.0 / data.mass : 0.0;
  data.com = data.oYcrb[0].h * inv_m;
  const Vector3& c = data.com;

  for (int k = 0; k < model.nv; ++k) {
    const int b = k < 6 ? 0 : k - 5;
    const Force h_O = data.oYcrb[b] * Motion(data.J.col(k));
    data.Ag.col(k) = to_centroidal(h_O, c);
  }
  data.Jcom = data.Ag.bottomRows<3>() * inv_m;
  data.hg.noalias() = data.Ag * v;
  data.vcom = data.hg.tail<3>() * inv_m;

  // Bias: rate of change of momentum for a = 0, summed over bodies at the world origin.
  Force hdot_O = Force::Zero();
  for (int b = 0; b < model.nbodies; ++b) {
    const Inertia& I = model.inertia[b];
    const Force f = I * data.a_bias[b] + cross_force(data.v[b], I * data.v[b]);
    hdot_O += data.oMi[b].act_force(f);
  }
  // d/dt (k_O - c x l) = kdot_O - cdot x l - c x ldot, and cdot x l = 0.
  data.dAg_v = to_centroidal(hdot_O, c);
}

}  // namespace poise::model
