// Inverse dynamics and mass matrix against Bullet's inverse-dynamics library (MultiBodyTree).
//
// The Bullet tree is built straight from the URDF with urdfdom (fixed joints kept as Bullet FIXED
// bodies, inertias moved to the link origins), independently of poise::model. Bullet's floating
// joint uses Euler angles with a convention that is hard to pin down, so the floating base is
// modelled in Bullet as a chain of massless bodies: prismatic x, y, z (world axes), then revolute
// z, y, x; the base orientation is R = Rz(psi) Ry(theta) Rx(phi). The test maps states and
// generalized forces between that chain and poise's quaternion/body-twist base exactly:
//   v_poise = T u_chain,   tau_chain = T^T tau_poise,   M_chain = T^T M_poise T.
#include <gtest/gtest.h>
#include <urdf_parser/urdf_parser.h>

#include <map>

#include "bullet_id_api.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "test_util.hpp"

namespace poise::model {
namespace {

namespace bid = btInverseDynamicsBullet3;
using test::all_urdfs;

bid::vec3 bv(const Vector3& v) {
  return bid::vec3(v.x(), v.y(), v.z());
}
bid::mat33 bm(const Matrix3& m) {
  bid::mat33 out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      out(i, j) = m(i, j);
  return out;
}
Vector3 ev(const btVector3& v) {
  return Vector3(v.x(), v.y(), v.z());
}

Matrix3 rot_of(const urdf::Rotation& r) {
  return Eigen::Quaterniond(r.w, r.x, r.y, r.z).normalized().toRotationMatrix();
}

struct BulletRobot {
  bid::MultiBodyTree tree;
  int num_dofs = 0;
  std::vector<std::string> dof_joint;  ///< joint name of each Bullet DoF after the base chain
  std::map<std::string, int> link_body;
};

// Adds the URDF subtree below `link` (already added as Bullet body `body`).
void add_subtree(BulletRobot& r, const urdf::Link& link, int body, int& next) {
  std::vector<urdf::JointSharedPtr> joints = link.child_joints;
  std::sort(joints.begin(), joints.end(), [](auto& a, auto& b) { return a->name < b->name; });
  for (const auto& j : joints) {
    urdf::LinkConstSharedPtr child;
    for (const auto& c : link.child_links)
      if (c->name == j->child_link_name) child = c;
    const auto& o = j->parent_to_joint_origin_transform;
    const Vector3 p(o.position.x, o.position.y, o.position.z);
    const Matrix3 R_PC = rot_of(o.rotation);
    bid::JointType type = bid::FIXED;
    if (j->type == urdf::Joint::REVOLUTE || j->type == urdf::Joint::CONTINUOUS)
      type = bid::REVOLUTE;
    if (j->type == urdf::Joint::PRISMATIC) type = bid::PRISMATIC;
    double mass = 0.0;
    Vector3 com = Vector3::Zero();
    Matrix3 I_o = Matrix3::Zero();
    if (child->inertial) {
      const auto& in = *child->inertial;
      mass = in.mass;
      Matrix3 Ic;
      Ic << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
      const Matrix3 R = rot_of(in.origin.rotation);
      com = Vector3(in.origin.position.x, in.origin.position.y, in.origin.position.z);
      I_o = R * Ic * R.transpose() +
            mass * (com.squaredNorm() * Matrix3::Identity() - com * com.transpose());
    }
    const Vector3 axis = Vector3(j->axis.x, j->axis.y, j->axis.z).normalized();
    const int me = next++;
    EXPECT_EQ(0, r.tree.addBody(me, body, type, bv(p), bm(R_PC.transpose()), bv(axis), mass,
                                bv(com), bm(I_o), 0, nullptr))
        << j->name;
    if (type != bid::FIXED) r.dof_joint.push_back(j->name);
    r.link_body[child->name] = me;
    add_subtree(r, *child, me, next);
  }
}

void build_bullet(BulletRobot& r, const std::string& path, const Vector3& gravity) {
  const auto urdf = urdf::parseURDFFile(path);
  ASSERT_TRUE(urdf);
  r.tree.setAcceptInvalidMassParameters(true);  // the massless virtual base chain
  const bid::mat33 I3 = bm(Matrix3::Identity());
  const bid::mat33 Z3 = bm(Matrix3::Zero());
  const Vector3 axes[6] = {Vector3::UnitX(), Vector3::UnitY(), Vector3::UnitZ(),
                           Vector3::UnitZ(), Vector3::UnitY(), Vector3::UnitX()};
  const auto root = urdf->getRoot();
  for (int k = 0; k < 6; ++k) {
    double mass = 0.0;
    Vector3 com = Vector3::Zero();
    Matrix3 I_o = Matrix3::Zero();
    if (k == 5 && root->inertial) {  // the last chain body is the URDF root link
      const auto& in = *root->inertial;
      mass = in.mass;
      Matrix3 Ic;
      Ic << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
      const Matrix3 R = rot_of(in.origin.rotation);
      com = Vector3(in.origin.position.x, in.origin.position.y, in.origin.position.z);
      I_o = R * Ic * R.transpose() +
            mass * (com.squaredNorm() * Matrix3::Identity() - com * com.transpose());
    }
    ASSERT_EQ(
        0, r.tree.addBody(k, k - 1, k < 3 ? bid::PRISMATIC : bid::REVOLUTE, bv(Vector3::Zero()), I3,
                          bv(axes[k]), mass, bv(com), k == 5 ? bm(I_o) : Z3, 0, nullptr));
  }
  r.link_body[root->name] = 5;
  int next = 6;
  add_subtree(r, *root, 5, next);
  ASSERT_EQ(0, r.tree.finalize());
  ASSERT_EQ(0, r.tree.setGravityInWorldFrame(bv(gravity)));
  r.num_dofs = 6 + static_cast<int>(r.dof_joint.size());
}

// Chain state (psi about z, theta about y, phi about x) -> poise state.
struct Mapping {
  Eigen::MatrixXd T;  ///< v_poise = T u_chain (nv x nv)
  Eigen::VectorXd q, v, a;
};

Mapping map_state(const Model& model, const BulletRobot& r, const Eigen::VectorXd& qc,
                  const Eigen::VectorXd& uc, const Eigen::VectorXd& ac) {
  const double psi = qc[3], th = qc[4], ph = qc[5];
  const Matrix3 Rz = Eigen::AngleAxisd(psi, Vector3::UnitZ()).toRotationMatrix();
  const Matrix3 Ry = Eigen::AngleAxisd(th, Vector3::UnitY()).toRotationMatrix();
  const Matrix3 Rx = Eigen::AngleAxisd(ph, Vector3::UnitX()).toRotationMatrix();
  const Matrix3 R = Rz * Ry * Rx;
  const Vector3 a1 = Vector3::UnitZ(), a2 = Rz * Vector3::UnitY(), a3 = Rz * Ry * Vector3::UnitX();
  Mapping m;
  m.T = Eigen::MatrixXd::Zero(model.nv, model.nv);
  m.T.block<3, 3>(0, 0) = R.transpose();
  Matrix3 W;
  W << a1, a2, a3;
  m.T.block<3, 3>(3, 3) = R.transpose() * W;
  m.q = model.neutral();
  m.v = Eigen::VectorXd::Zero(model.nv);
  m.a = Eigen::VectorXd::Zero(model.nv);
  m.q.head<3>() = qc.head<3>();
  m.q.segment<4>(3) = Eigen::Quaterniond(R).coeffs();
  for (std::size_t d = 0; d < r.dof_joint.size(); ++d) {
    const int j = model.joint_index(r.dof_joint[d]);
    m.q[model.idx_q(j)] = qc[6 + d];
    m.T(model.idx_v(j), 6 + d) = 1.0;
  }
  m.v = m.T * uc;
  // accelerations: a_base = d/dt [R^T pdot; R^T omega_W]
  const Vector3 w1 = uc[3] * a1, w2 = w1 + uc[4] * a2;
  const Vector3 wdot_W =
      ac[3] * a1 + ac[4] * a2 + ac[5] * a3 + uc[4] * w1.cross(a2) + uc[5] * w2.cross(a3);
  m.a = m.T * ac;
  const Vector3 vB = m.v.head<3>(), wB = m.v.segment<3>(3);
  m.a.head<3>() = R.transpose() * ac.head<3>() - wB.cross(vB);
  m.a.segment<3>(3) = R.transpose() * wdot_W;
  return m;
}

class BulletCompareTest : public ::testing::TestWithParam<std::string> {};

TEST_P(BulletCompareTest, InverseDynamicsAndMassMatrixAgree) {
  const Model model = build_model_from_urdf_file(GetParam());
  Data data(model);
  BulletRobot br;
  build_bullet(br, GetParam(), model.gravity);
  ASSERT_EQ(br.num_dofs, model.nv);

  std::mt19937 rng(2024);
  std::normal_distribution<double> n01;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = br.num_dofs;
  bid::vecx bq(n), bu(n), ba(n), btau(n);
  bid::matxx bM(n, n);
  for (int trial = 0; trial < 10; ++trial) {
    Eigen::VectorXd qc(n), uc(n), ac(n);
    for (int i = 0; i < n; ++i) {
      qc[i] = u(rng);
      uc[i] = n01(rng);
      ac[i] = n01(rng);
    }
    for (std::size_t d = 0; d < br.dof_joint.size(); ++d) {  // within joint limits
      const JointLimits& l = model.limits[model.joint_index(br.dof_joint[d])];
      const double lo = std::max(l.lower, -2.0), hi = std::min(l.upper, 2.0);
      qc[6 + d] = lo + (hi - lo) * 0.5 * (u(rng) + 1.0);
    }
    const Mapping m = map_state(model, br, qc, uc, ac);
    for (int i = 0; i < n; ++i) {
      bq(i) = qc[i];
      bu(i) = uc[i];
      ba(i) = ac[i];
    }

    // 1. inverse dynamics without external forces
    br.tree.clearAllUserForcesAndMoments();
    ASSERT_EQ(0, br.tree.calculateInverseDynamics(bq, bu, ba, &btau));
    Eigen::VectorXd tau_bullet(n);
    for (int i = 0; i < n; ++i)
      tau_bullet[i] = btau(i);
    clear_external_forces(data);
    ASSERT_GT(tau_bullet.norm(), 1.0);  // a non-trivial comparison
    const Eigen::VectorXd tau = rnea(model, data, m.q, m.v, m.a);
    const Eigen::VectorXd tau_chain = m.T.transpose() * tau;
    EXPECT_LT((tau_chain - tau_bullet).norm(), 1e-9 * (1 + tau_bullet.norm()))
        << "poise:  " << tau_chain.transpose() << "\nbullet: " << tau_bullet.transpose();

    // 2. with external forces on a few links (Bullet: force at the body origin + moment, body
    //    axes; the body pose comes from Bullet itself)
    forward_kinematics(model, data, m.q);
    Eigen::VectorXd tau_ext_expected;
    {
      int count = 0;
      for (const auto& [link, body] : br.link_body) {
        if (count++ % 2) continue;
        const Vector3 force(n01(rng), n01(rng), n01(rng)), torque(n01(rng), n01(rng), n01(rng));
        const Vector3 point(n01(rng), n01(rng), n01(rng));
        add_external_wrench(model, data, model.frame_id(link), point, force, torque);
        // Bullet body origin and orientation from poise's frame = independent check below via
        // Bullet's own origin.
        bid::vec3 o;
        ASSERT_EQ(0, br.tree.getBodyOrigin(body, &o));
        const SE3 X = frame_placement(model, data, model.frame_id(link));
        EXPECT_LT((ev(o) - X.p).norm(), 1e-10) << link;  // link origins agree
        const Vector3 moment = torque + (point - X.p).cross(force);
        ASSERT_EQ(0, br.tree.addUserForce(body, bv(X.R.transpose() * force)));
        ASSERT_EQ(0, br.tree.addUserMoment(body, bv(X.R.transpose() * moment)));
      }
    }
    ASSERT_EQ(0, br.tree.calculateInverseDynamics(bq, bu, ba, &btau));
    for (int i = 0; i < n; ++i)
      tau_bullet[i] = btau(i);
    const Eigen::VectorXd tau_e = m.T.transpose() * rnea(model, data, m.q, m.v, m.a);
    EXPECT_LT((tau_e - tau_bullet).norm(), 1e-9 * (1 + tau_bullet.norm()))
        << "poise:  " << tau_e.transpose() << "\nbullet: " << tau_bullet.transpose();

    // 3. mass matrix
    ASSERT_EQ(0, br.tree.calculateMassMatrix(bq, &bM));
    Eigen::MatrixXd M_bullet(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        M_bullet(i, j) = bM(i, j);
    const Eigen::MatrixXd M_chain = m.T.transpose() * crba(model, data, m.q) * m.T;
    EXPECT_LT((M_chain - M_bullet).norm(), 1e-9 * (1 + M_bullet.norm()));
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, BulletCompareTest, ::testing::ValuesIn(all_urdfs()));

}  // namespace
}  // namespace poise::model
