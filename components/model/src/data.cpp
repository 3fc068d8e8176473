// Workspace allocation.
#include "poise/model/data.hpp"

namespace poise::model {

Data::Data(const Model& model)
    : liMi(model.nbodies),
      oMi(model.nbodies),
      v(model.nbodies, Motion::Zero()),
      a(model.nbodies, Motion::Zero()),
      a_bias(model.nbodies, Motion::Zero()),
      a_gf(model.nbodies, Motion::Zero()),
      f(model.nbodies, Force::Zero()),
      Ycrb(model.nbodies),
      oYcrb(model.nbodies),
      f_ext_W(model.nbodies, Force::Zero()),
      oMf(model.frames.size()),
      tau(Eigen::VectorXd::Zero(model.nv)),
      M(Eigen::MatrixXd::Zero(model.nv, model.nv)),
      J(Matrix6X::Zero(6, model.nv)),
      mass(model.total_mass),
      Jcom(Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, model.nv)),
      Ag(Matrix6X::Zero(6, model.nv)) {}

}  // namespace poise::model
