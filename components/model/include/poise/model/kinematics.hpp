#pragma once
// Forward kinematics, frame placements/velocities/accelerations and Jacobians.
// All functions are allocation-free. Sizes: q (dim model.nq), v and a (dim model.nv).

#include <Eigen/Core>

#include "poise/model/data.hpp"
#include "poise/model/model.hpp"

namespace poise::model {

/// Body poses: data.liMi, data.oMi.
void forward_kinematics(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q);
/// Poses, body twists data.v and bias accelerations data.a_bias (accelerations for a = 0).
void forward_kinematics(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& v);
/// Poses, twists, bias accelerations and accelerations data.a.
void forward_kinematics(const Model& model, Data& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& v,
                        const Eigen::Ref<const Eigen::VectorXd>& a);

/// data.oMf for every frame (after forward_kinematics).
void update_frame_placements(const Model& model, Data& data);
/// X_WF of one frame (after forward_kinematics).
SE3 frame_placement(const Model& model, const Data& data, int frame_id);

/// Velocity of the frame origin and angular velocity, world axes: [v_F; omega] (6), i.e. the
/// LOCAL_WORLD_ALIGNED twist. Needs forward_kinematics with v.
Motion frame_velocity(const Model& model, const Data& data, int frame_id);
/// Classical acceleration of the frame origin and angular acceleration, world axes:
/// [d2/dt2 p_WF; d/dt omega] (6). Needs forward_kinematics with v and a.
Motion frame_classical_acceleration(const Model& model, const Data& data, int frame_id);
/// dJ/dt * v for the frame Jacobian of frame_jacobian(): the classical acceleration of the frame
/// origin for a = 0, world axes [linear; angular] (6). Needs forward_kinematics with v.
Motion frame_jdot_v(const Model& model, const Data& data, int frame_id);
/// Same for a point fixed on the frame at p_F (frame coordinates, 3).
Motion frame_point_jdot_v(const Model& model, const Data& data, int frame_id, const Vector3& p_F);

/// data.J (WORLD convention) and body poses. Needed by frame_jacobian.
void compute_joint_jacobians(const Model& model, Data& data,
                             const Eigen::Ref<const Eigen::VectorXd>& q);
/// Frame Jacobian, LOCAL_WORLD_ALIGNED at the frame origin: rows [linear velocity of the frame
/// origin; angular velocity], world axes, so that [v_F; omega] = J * v. J must be 6 x nv; columns
/// of DoFs not supporting the frame are set to zero. Needs compute_joint_jacobians.
void frame_jacobian(const Model& model, const Data& data, int frame_id, Eigen::Ref<Matrix6X> J);
/// Same for the point p_F (frame coordinates, 3) fixed on the frame.
void frame_point_jacobian(const Model& model, const Data& data, int frame_id, const Vector3& p_F,
                          Eigen::Ref<Matrix6X> J);

}  // namespace poise::model
