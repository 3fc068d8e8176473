#pragma once
// Declarations of the part of Bullet's inverse-dynamics library (libBulletInverseDynamics-float64,
// Debian package libbullet-extras-dev 3.24) used by the cross-check test.
//
// Why this file exists: Debian's libbullet-extras-dev ships the library but not its headers
// (/usr/include/bullet/BulletInverseDynamics/ contains only an unrelated header and an empty
// details/ folder). These declarations restate the library's public interface as exported by the
// shared object (check with: nm -DC --defined-only libBulletInverseDynamics-float64.so), for the
// default configuration it was built with: Bullet's own linear-math types, double precision,
// namespace btInverseDynamicsBullet3. Only the members the test calls are declared; the class
// layout (three bools and two pointers, pimpl) must match because the test constructs the object.

#ifndef BT_USE_DOUBLE_PRECISION
#error "define BT_USE_DOUBLE_PRECISION to match libBulletInverseDynamics-float64"
#endif

#include <LinearMath/btMatrix3x3.h>
#include <LinearMath/btMatrixX.h>
#include <LinearMath/btVector3.h>

namespace btInverseDynamicsBullet3 {

using idScalar = btScalar;

enum JointType { FIXED = 0, REVOLUTE, PRISMATIC, FLOATING };

class vec3 : public btVector3 {
 public:
  vec3() : btVector3() {}
  vec3(double x, double y, double z) : btVector3(x, y, z) {}
};

class mat33 : public btMatrix3x3 {
 public:
  mat33() : btMatrix3x3() {}
  double& operator()(int i, int j) { return (*this)[i][j]; }
};

class vecx : public btVectorX<idScalar> {
 public:
  explicit vecx(int size) : btVectorX<idScalar>(size) {}
  double& operator()(int i) { return (*this)[i]; }
  const double& operator()(int i) const { return (*this)[i]; }
};

using matxx = btMatrixX<idScalar>;

class MultiBodyTree {
 public:
  MultiBodyTree();
  ~MultiBodyTree();
  MultiBodyTree(const MultiBodyTree&) = delete;
  MultiBodyTree& operator=(const MultiBodyTree&) = delete;

  /// Body frames sit on the joint axis; body_T_parent_ref maps parent coordinates to body
  /// coordinates at q = 0; body_I_body is the inertia about the body origin. Returns 0 / -1.
  int addBody(int body_index, int parent_index, JointType joint_type,
              const vec3& parent_r_parent_body_ref, const mat33& body_T_parent_ref,
              const vec3& body_axis_of_motion, idScalar mass, const vec3& body_r_body_com,
              const mat33& body_I_body, const int user_int, void* user_ptr);
  void setAcceptInvalidMassParameters(bool flag);
  int finalize();
  int calculateInverseDynamics(const vecx& q, const vecx& u, const vecx& dot_u, vecx* joint_forces);
  int calculateMassMatrix(const vecx& q, matxx* mass_matrix);
  int setGravityInWorldFrame(const vec3& gravity);
  int getBodyOrigin(const int body_index, vec3* world_origin) const;
  void clearAllUserForcesAndMoments();
  /// Force at the body origin, body coordinates.
  int addUserForce(const int body_index, const vec3& body_force);
  /// Moment, body coordinates.
  int addUserMoment(const int body_index, const vec3& body_moment);

 private:
  bool m_is_finalized;
  bool m_mass_parameters_are_valid;
  bool m_accept_invalid_mass_parameters;
  class MultiBodyImpl;
  MultiBodyImpl* m_impl;
  class InitCache;
  InitCache* m_init_cache;
};

}  // namespace btInverseDynamicsBullet3
