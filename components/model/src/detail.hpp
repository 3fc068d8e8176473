#pragma once
// Internal helpers shared by the algorithm sources (not installed).

#include <cmath>
#include <string>

#include "poise/model/data.hpp"
#include "poise/model/model.hpp"

namespace poise::model::detail {

/// Motion subspace S of the 1-DoF joint of body b (b >= 1), body frame (6).
inline Motion motion_subspace(const Model& model, int b) {
  Motion S;
  if (model.joint_type[b] == JointType::kPrismatic) {
    S.head<3>() = model.axis[b];
    S.tail<3>().setZero();
  } else {
    S.head<3>().setZero();
    S.tail<3>() = model.axis[b];
  }
  return S;
}

/// S^T f for the joint of body b.
inline double project_force(const Model& model, int b, const Force& f) {
  return model.joint_type[b] == JointType::kPrismatic ? model.axis[b].dot(f.head<3>())
                                                      : model.axis[b].dot(f.tail<3>());
}

/// liMi for joint of body b at position qj.
void joint_transform(const Model& model, int b, double qj, SE3& liMi);
/// data.J from data.oMi.
void fill_world_jacobian(const Model& model, Data& data);

/// Throws ModelError("<what>: XML elements nested deeper than ...") when XML text nests its
/// elements deeper than tinyxml can parse without overflowing the stack (model.cpp).
void check_xml_depth(const std::string& xml, const std::string& what);

}  // namespace poise::model::detail
