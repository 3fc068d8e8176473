#pragma once
// Workspace of the algorithms: allocated once from a Model, then reused every tick. Every
// algorithm writes its results here; nothing in the algorithms allocates.

#include <Eigen/Core>
#include <vector>

#include "poise/model/model.hpp"

namespace poise::model {

struct Data {
  explicit Data(const Model& model);

  // ---- per body (dim model.nbodies), body quantities in the body frame -------------------------
  std::vector<SE3> liMi;               ///< X_parent_body at the current q
  std::vector<SE3> oMi;                ///< X_WB: body pose in world
  std::vector<Motion> v;               ///< body twist, body frame
  std::vector<Motion> a;               ///< body spatial acceleration, body frame (FK with a)
  std::vector<Motion> a_bias;          ///< body spatial acceleration for a = 0 (FK with v)
  std::vector<Motion> a_gf;            ///< RNEA: acceleration minus gravity, body frame
  std::vector<Force> f;                ///< RNEA: wrench transmitted by the body's joint, body frame
  std::vector<Inertia> Ycrb;           ///< CRBA: composite inertia of the subtree, body frame
  std::vector<InertiaAtOrigin> oYcrb;  ///< CMM: composite inertia, world axes, world origin
  /// External wrench on each body, world axes, about the WORLD ORIGIN. Fill it with
  /// add_external_wrench and reset it with clear_external_forces; if you write it directly, also
  /// set any_f_ext = true, or rnea ignores it.
  std::vector<Force> f_ext_W;
  bool any_f_ext = false;  ///< set by add_external_wrench, cleared by clear_external_forces

  // ---- per frame (dim model.frames.size()) ----------------------------------------------------
  std::vector<SE3> oMf;  ///< X_WF (update_frame_placements)

  // ---- generalized quantities -----------------------------------------------------------------
  Eigen::VectorXd tau;  ///< RNEA output (dim nv)
  Eigen::MatrixXd M;    ///< CRBA output, full symmetric (nv x nv)
  Matrix6X J;           ///< joint Jacobian, WORLD convention: spatial velocity at the world
                        ///< origin, world axes, rows [v_O; omega] (6 x nv)

  // ---- centre of mass and centroidal momentum -------------------------------------------------
  double mass = 0.0;                              ///< total mass
  Vector3 com = Vector3::Zero();                  ///< CoM in world (3)
  Vector3 vcom = Vector3::Zero();                 ///< CoM velocity in world (3)
  Eigen::Matrix<double, 3, Eigen::Dynamic> Jcom;  ///< CoM Jacobian, world (3 x nv)
  /// Centroidal momentum h_G = [k; l] (ANGULAR FIRST, as in the paper): k angular momentum about
  /// the CoM, l linear momentum, both world axes (6).
  Vector6 hg = Vector6::Zero();
  /// Centroidal momentum matrix A(q) with h_G = A * v, rows [k; l] (6 x nv).
  Matrix6X Ag;
  /// Bias dA/dt * v, rows [k; l] (6): d/dt h_G = A * a + dAg_v.
  Vector6 dAg_v = Vector6::Zero();
};

}  // namespace poise::model
