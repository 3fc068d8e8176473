#include "poise/sim/simulator.hpp"

// btBoxShape::getPlane (inline, emitted here for PaddedBoxShape's vtable) trips GCC's
// -Wmaybe-uninitialized inside Bullet's own header.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <BulletCollision/CollisionShapes/btBoxShape.h>
#include <BulletCollision/CollisionShapes/btCompoundShape.h>
#include <BulletCollision/CollisionShapes/btConvexHullShape.h>
#include <BulletCollision/CollisionShapes/btCylinderShape.h>
#include <BulletCollision/CollisionShapes/btShapeHull.h>
#include <BulletCollision/CollisionShapes/btSphereShape.h>
#include <BulletCollision/CollisionShapes/btStaticPlaneShape.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointLimitConstraint.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointMotor.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>
#include <btBulletDynamicsCommon.h>
#pragma GCC diagnostic pop

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "reality_detail.hpp"
#include "robot_tree.hpp"

#ifndef BT_USE_DOUBLE_PRECISION
#error "poise_sim must be compiled against double-precision Bullet (BT_USE_DOUBLE_PRECISION)"
#endif

namespace poise::sim {

void JointCommand::resize(int n) {
  tick = -1;
  mode = CommandMode::kTorque;
  tau_ff = Eigen::VectorXd::Zero(n);
  q_ref = Eigen::VectorXd::Zero(n);
  qd_ref = Eigen::VectorXd::Zero(n);
  kp = Eigen::VectorXd::Zero(n);
  kd = Eigen::VectorXd::Zero(n);
}

namespace {

using detail::BodySpec;
using detail::RobotTree;
using detail::ShapeSpec;

constexpr int kRobotGroup = 1;
constexpr int kEnvGroup = 2;
constexpr int kGroundIndex = -1;  // collision-object user index of the ground
// platform k has user index -2 - k; robot bodies have their body index (>= 0)

btVector3 bt(const Eigen::Vector3d& v) {
  return btVector3(v.x(), v.y(), v.z());
}
Eigen::Vector3d eig(const btVector3& v) {
  return Eigen::Vector3d(v.x(), v.y(), v.z());
}
btQuaternion bt(const Eigen::Quaterniond& q) {
  return btQuaternion(q.x(), q.y(), q.z(), q.w());
}
btTransform bt(const Eigen::Isometry3d& X) {
  return btTransform(bt(Eigen::Quaterniond(X.linear())), bt(Eigen::Vector3d(X.translation())));
}
Eigen::Isometry3d eig(const btTransform& t) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  const btQuaternion q = t.getRotation();
  X.linear() = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z()).toRotationMatrix();
  X.translation() = eig(t.getOrigin());
  return X;
}

double sinusoid(const Sinusoid& s, double t) {
  return s.amplitude * std::sin(2.0 * M_PI * s.frequency * t + s.phase);
}
double sinusoid_rate(const Sinusoid& s, double t) {
  return s.amplitude * 2.0 * M_PI * s.frequency * std::cos(2.0 * M_PI * s.frequency * t + s.phase);
}

struct ResolvedPush {
  int body = 0;
  Eigen::Vector3d point_K = Eigen::Vector3d::Zero();  // in the body COM frame K
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();
  std::int64_t start_tick = 0, end_tick = 0;  // active for start <= k < end
};

struct Platform {
  PlatformConfig cfg;
  Eigen::Matrix3d R_incline = Eigen::Matrix3d::Identity();
  Eigen::Vector3d base_position = Eigen::Vector3d::Zero();
  std::unique_ptr<btBoxShape> shape;  // a PaddedBoxShape
  std::unique_ptr<btRigidBody> body;

  // Top-centre pose and its velocity (world) at time t.
  void pose(double t, Eigen::Isometry3d& X_WP, Eigen::Vector3d& v, Eigen::Vector3d& w) const {
    const Eigen::Vector3d axis_t = cfg.translation_axis;
    const Eigen::Vector3d axis_r = R_incline * cfg.rotation_axis;
    const double tau = t - cfg.motion_start;
    double e = 0.0, de = 0.0;  // envelope and its rate
    if (tau > 0.0) {
      if (cfg.motion_ramp > 0.0 && tau < cfg.motion_ramp) {
        const double s = tau / cfg.motion_ramp;
        e = s * s * (3.0 - 2.0 * s);
        de = 6.0 * s * (1.0 - s) / cfg.motion_ramp;
      } else {
        e = 1.0;
      }
    }
    const double tr = e * sinusoid(cfg.translation, tau);
    const double rot = e * sinusoid(cfg.rotation, tau);
    X_WP = Eigen::Isometry3d::Identity();
    X_WP.translation() = base_position + axis_t * tr;
    X_WP.linear() = Eigen::AngleAxisd(rot, axis_r).toRotationMatrix() * R_incline;
    v = axis_t * (de * sinusoid(cfg.translation, tau) + e * sinusoid_rate(cfg.translation, tau));
    w = axis_r * (de * sinusoid(cfg.rotation, tau) + e * sinusoid_rate(cfg.rotation, tau));
  }
};

// The ground plane with a broadphase box that ends `band` above the plane (Bullet gives a plane an
// infinite box, so every link is paired with it and tested by the narrowphase every step). Only
// the world-space box (identity rotation, which is how the ground is placed) is bounded; in any
// other frame (e.g. a compound's child culling) the box stays infinite. The shape type and thus
// the plane/convex contact algorithm are Bullet's.
class BandedPlaneShape : public btStaticPlaneShape {
 public:
  BandedPlaneShape(double height, double band)
      : btStaticPlaneShape(btVector3(0, 0, 1), height), top_(height + band) {}
  void getAabb(const btTransform& t, btVector3& aabb_min, btVector3& aabb_max) const override {
    btStaticPlaneShape::getAabb(t, aabb_min, aabb_max);
    const btMatrix3x3& R = t.getBasis();
    if (R == btMatrix3x3::getIdentity()) aabb_max.setZ(top_ + t.getOrigin().z());
  }

 private:
  double top_;
};

// A platform box whose bounding box is `pad` larger on every side than the box itself.
// Bullet's compound-shape algorithm (every robot link is a compound) drops a child's contact
// algorithm, and with it the contact manifold and its warm-start impulses, as soon as the child's
// exact box stops overlapping the other shape's exact box. A sole resting flat on a level
// platform touches the platform's box exactly at its top face, so a nanometre of rise dropped
// every contact point of that foot for one step (then re-created them with a penetration impulse
// spike): on the moving-platform scenarios thousands of such steps. The pad keeps the child
// algorithm alive while the sole is within it; contact generation itself is unchanged.
constexpr double kPlatformAabbPad = 0.02;  // [m] Bullet's default contact breaking threshold

class PaddedBoxShape : public btBoxShape {
 public:
  PaddedBoxShape(const btVector3& half_extents, double pad) : btBoxShape(half_extents), pad_(pad) {}
  void getAabb(const btTransform& t, btVector3& aabb_min, btVector3& aabb_max) const override {
    btBoxShape::getAabb(t, aabb_min, aabb_max);
    aabb_min -= btVector3(pad_, pad_, pad_);
    aabb_max += btVector3(pad_, pad_, pad_);
  }

 private:
  double pad_;
};

// Bullet's multibody solver with read access to the rows it built for the last step
// (diagnostics: poise-bench-sim counters).
class RowCountingSolver : public btMultiBodyConstraintSolver {
 public:
  int normal_rows() const { return m_multiBodyNormalContactConstraints.size(); }
  int friction_rows() const { return m_multiBodyFrictionContactConstraints.size(); }
  int other_rows() const {
    return m_multiBodyNonContactConstraints.size() +
           m_multiBodyTorsionalFrictionContactConstraints.size() +
           m_multiBodySpinningFrictionContactConstraints.size();
  }
};

}  // namespace

namespace {

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double a = w.norm();
  if (a < 1e-12) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

double yaw_of(const Eigen::Matrix3d& R) {
  return std::atan2(R(1, 0), R(0, 0));
}

/// Throws std::runtime_error naming the first bad sensor setting.
void validate_sensors(const SimulatorConfig& c) {
  const auto bad = [](const std::string& key, const std::string& msg) {
    throw std::runtime_error("sensors: " + key + ": " + msg);
  };
  const auto nonneg = [&](double v, const char* key) {
    if (!std::isfinite(v) || v < 0.0) bad(key, "must be a finite number >= 0");
  };
  const auto finite3 = [&](const Eigen::Vector3d& v, const char* key) {
    if (!v.allFinite()) bad(key, "must be finite");
  };
  const ImuNoiseConfig& m = c.imu;
  nonneg(m.gyro_noise_std, "imu.gyro_noise_std");
  nonneg(m.gyro_noise_density, "imu.gyro_noise_density");
  nonneg(m.gyro_bias_walk, "imu.gyro_bias_walk");
  nonneg(m.gyro_range, "imu.gyro_range");
  nonneg(m.accel_noise_std, "imu.accel_noise_std");
  nonneg(m.accel_noise_density, "imu.accel_noise_density");
  nonneg(m.accel_bias_walk, "imu.accel_bias_walk");
  nonneg(m.accel_range, "imu.accel_range");
  finite3(m.gyro_bias, "imu.gyro_bias");
  finite3(m.gyro_scale_error, "imu.gyro_scale_error");
  finite3(m.gyro_misalignment, "imu.gyro_misalignment");
  finite3(m.accel_bias, "imu.accel_bias");
  finite3(m.accel_scale_error, "imu.accel_scale_error");
  finite3(m.accel_misalignment, "imu.accel_misalignment");
  if ((m.gyro_scale_error.array() <= -1.0).any() || (m.accel_scale_error.array() <= -1.0).any())
    bad("imu.*_scale_error", "must be > -1");
  nonneg(m.rate_hz, "imu.rate_hz");
  if (m.rate_hz > 1.0 / c.solver.dt + 1e-9)
    bad("imu.rate_hz", "must not exceed the simulator rate 1 / solver.dt = " +
                           std::to_string(1.0 / c.solver.dt) + " Hz");
  if (m.delay_ticks < 0 || m.delay_ticks > 1000) bad("imu.delay_ticks", "must be in [0, 1000]");
  if (static_cast<int>(m.orientation) > 2) bad("imu.orientation", "must be off, filter or truth");
  nonneg(m.filter_gain, "imu.filter_gain");
  if (!std::isfinite(m.filter_accel_gate) || m.filter_accel_gate <= 0.0)
    bad("imu.filter_accel_gate", "must be a finite number > 0");
  nonneg(c.encoders.counts_per_rev, "encoders.counts_per_rev");
  nonneg(c.encoders.velocity_filter_hz, "encoders.velocity_filter_hz");
  nonneg(c.foot_ft.force_noise_std, "foot_ft.force_noise_std");
  nonneg(c.foot_ft.torque_noise_std, "foot_ft.torque_noise_std");
  finite3(c.foot_ft.force_offset, "foot_ft.force_offset");
  finite3(c.foot_ft.torque_offset, "foot_ft.torque_offset");
}

/// The robot's sensors as a real robot would report them: IMU (sampled, held, delayed, with its
/// own attitude filter), encoders (quantised, differenced), foot F/T (noise, offset).
/// configure() allocates; everything else is allocation-free.
class SensorModel {
 public:
  void configure(const SimulatorConfig& c, int n, std::size_t num_feet) {
    validate_sensors(c);
    imu_ = c.imu;
    enc_ = c.encoders;
    ft_ = c.foot_ft;
    dt_ = c.solver.dt;
    gravity_ = c.world.gravity.norm();
    const double rate = imu_.rate_hz > 0.0 ? imu_.rate_hz : 1.0 / dt_;
    imu_dt_ = 1.0 / rate;
    every_tick_ = imu_.rate_hz <= 0.0 || imu_.rate_hz * dt_ > 1.0 - 1e-9;
    gyro_std_ = std::sqrt(imu_.gyro_noise_std * imu_.gyro_noise_std +
                          imu_.gyro_noise_density * imu_.gyro_noise_density * rate / 2.0);
    accel_std_ = std::sqrt(imu_.accel_noise_std * imu_.accel_noise_std +
                           imu_.accel_noise_density * imu_.accel_noise_density * rate / 2.0);
    M_g_ = (Eigen::Vector3d::Ones() + imu_.gyro_scale_error).asDiagonal() *
           exp_so3(imu_.gyro_misalignment).transpose();
    M_a_ = (Eigen::Vector3d::Ones() + imu_.accel_scale_error).asDiagonal() *
           exp_so3(imu_.accel_misalignment).transpose();
    ring_.assign(static_cast<std::size_t>(imu_.delay_ticks) + 1, Sample{});
    q_meas_ = Eigen::VectorXd::Zero(n);
    vel_alpha_ = enc_.velocity_filter_hz > 0.0
                     ? dt_ / (dt_ + 1.0 / (2.0 * M_PI * enc_.velocity_filter_hz))
                     : 1.0;
    qd_meas_ = Eigen::VectorXd::Zero(n);
    ft_noise_.assign(num_feet, Eigen::Matrix<double, 6, 1>::Zero());
    rng_.seed(imu_.seed);
    b_g_ = imu_.gyro_bias;
    b_a_ = imu_.accel_bias;
  }

  /// After a state change (start, Simulator::set_state): the next reading is a fresh first
  /// sample (the IMU's filter restarts), encoders restart from the true velocity.
  void reset(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
    have_sample_ = false;
    k_ = 0;
    quantise(q, q_meas_);
    qd_meas_ = qd;
  }

  /// IMU. advance: one simulator step was taken (else: a read of the current output, no draw
  /// unless there was no sample yet).
  void imu(bool advance, const Eigen::Matrix3d& R_WI, const Eigen::Vector3d& omega_I,
           const Eigen::Vector3d& f_I, SensorFrame& s) {
    if (!have_sample_) {
      held_ = measure(R_WI, omega_I, f_I, true);
      for (auto& r : ring_)
        r = held_;
      have_sample_ = true;
      k_ = 0;
    } else if (advance) {
      ++k_;
      const double a = static_cast<double>(k_) * dt_ * imu_.rate_hz;
      const double b = static_cast<double>(k_ - 1) * dt_ * imu_.rate_hz;
      if (every_tick_ || std::floor(a + 1e-9) > std::floor(b + 1e-9))
        held_ = measure(R_WI, omega_I, f_I, false);
      ring_[static_cast<std::size_t>(k_ % static_cast<std::int64_t>(ring_.size()))] = held_;
    }
    const Sample& out =
        ring_[static_cast<std::size_t>((k_ + 1) % static_cast<std::int64_t>(ring_.size()))];
    s.imu_omega_I = out.omega;
    s.imu_specific_force_I = out.f;
    s.imu_q_WI = out.q;
  }

  void encoders(bool advance, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, SensorFrame& s) {
    if (enc_.counts_per_rev <= 0.0) {
      s.q = q;
      s.qd = qd;
      return;
    }
    if (advance) {
      for (Eigen::Index i = 0; i < q.size(); ++i) {
        const double prev = q_meas_[i];
        q_meas_[i] = quantise(q[i]);
        const double raw = (q_meas_[i] - prev) / dt_;
        qd_meas_[i] += vel_alpha_ * (raw - qd_meas_[i]);
      }
    }
    s.q = q_meas_;
    s.qd = qd_meas_;
  }

  /// Adds offset and noise to the exact wrench [torque; force] of foot f.
  void foot_ft(bool advance, std::size_t f, Eigen::Matrix<double, 6, 1>& w) {
    auto& nz = ft_noise_[f];
    if (advance) {
      for (int k = 0; k < 3; ++k) {
        nz[k] = ft_.torque_noise_std > 0.0 ? ft_.torque_noise_std * normal_(rng_) : 0.0;
        nz[3 + k] = ft_.force_noise_std > 0.0 ? ft_.force_noise_std * normal_(rng_) : 0.0;
      }
    }
    w.head<3>() += ft_.torque_offset + nz.head<3>();
    w.tail<3>() += ft_.force_offset + nz.tail<3>();
  }

 private:
  struct Sample {
    Eigen::Vector3d omega = Eigen::Vector3d::Zero();
    Eigen::Vector3d f = Eigen::Vector3d::Zero();
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  };

  double quantise(double x) const {
    const double step = 2.0 * M_PI / enc_.counts_per_rev;
    return std::round(x / step) * step;
  }
  void quantise(const Eigen::VectorXd& q, Eigen::VectorXd& out) const {
    out = q;
    if (enc_.counts_per_rev > 0.0)
      for (Eigen::Index i = 0; i < q.size(); ++i)
        out[i] = quantise(q[i]);
  }

  Sample measure(const Eigen::Matrix3d& R_WI, const Eigen::Vector3d& omega_I,
                 const Eigen::Vector3d& f_I, bool first) {
    if (!first) {
      const double sq = std::sqrt(imu_dt_);
      if (imu_.gyro_bias_walk > 0.0)
        for (int k = 0; k < 3; ++k)
          b_g_[k] += imu_.gyro_bias_walk * sq * normal_(rng_);
      if (imu_.accel_bias_walk > 0.0)
        for (int k = 0; k < 3; ++k)
          b_a_[k] += imu_.accel_bias_walk * sq * normal_(rng_);
    }
    Sample s;
    s.omega = M_g_ * omega_I + b_g_;
    s.f = M_a_ * f_I + b_a_;
    if (gyro_std_ > 0.0)
      for (int k = 0; k < 3; ++k)
        s.omega[k] += gyro_std_ * normal_(rng_);
    if (accel_std_ > 0.0)
      for (int k = 0; k < 3; ++k)
        s.f[k] += accel_std_ * normal_(rng_);
    if (imu_.gyro_range > 0.0)
      s.omega = s.omega.cwiseMax(-imu_.gyro_range).cwiseMin(imu_.gyro_range);
    if (imu_.accel_range > 0.0) s.f = s.f.cwiseMax(-imu_.accel_range).cwiseMin(imu_.accel_range);
    switch (imu_.orientation) {
      case ImuOrientationOutput::kOff:
        s.q.coeffs().setZero();
        break;
      case ImuOrientationOutput::kTruth:
        s.q = Eigen::Quaterniond(R_WI);
        break;
      case ImuOrientationOutput::kFilter:
        s.q = attitude_filter(R_WI, s, first);
        break;
    }
    return s;
  }

  /// The IMU's own attitude filter (complementary, Mahony-type without bias estimation): the
  /// measured rate integrated, the tilt pulled toward the measured gravity direction with gain
  /// filter_gain while the specific force is within filter_accel_gate of g. Starts with the
  /// tilt of its first accelerometer sample and the true yaw (a heading reset at power-up).
  Eigen::Quaterniond attitude_filter(const Eigen::Matrix3d& R_WI, const Sample& s, bool first) {
    const double fn = s.f.norm();
    if (first) {
      Eigen::Quaterniond q = fn > 1e-6
                                 ? Eigen::Quaterniond::FromTwoVectors(s.f, Eigen::Vector3d::UnitZ())
                                 : Eigen::Quaterniond(R_WI);
      const double dpsi = yaw_of(R_WI) - yaw_of(q.toRotationMatrix());
      ahrs_q_ = (Eigen::AngleAxisd(dpsi, Eigen::Vector3d::UnitZ()) * q).normalized();
      return ahrs_q_;
    }
    Eigen::Vector3d w = s.omega;
    if (fn > 1e-6 && std::abs(fn - gravity_) < imu_.filter_accel_gate * gravity_) {
      const Eigen::Vector3d v_est = ahrs_q_.toRotationMatrix().transpose().col(2);
      w += imu_.filter_gain * (s.f / fn).cross(v_est);
    }
    ahrs_q_ = (ahrs_q_ * Eigen::Quaterniond(exp_so3(w * imu_dt_))).normalized();
    return ahrs_q_;
  }

  ImuNoiseConfig imu_;
  EncoderConfig enc_;
  ForceTorqueSensorConfig ft_;
  double dt_ = 0.001, imu_dt_ = 0.001, gravity_ = 9.81;
  bool every_tick_ = true;
  double vel_alpha_ = 1.0;
  double gyro_std_ = 0.0, accel_std_ = 0.0;
  Eigen::Matrix3d M_g_ = Eigen::Matrix3d::Identity(), M_a_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d b_g_ = Eigen::Vector3d::Zero(), b_a_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond ahrs_q_ = Eigen::Quaterniond::Identity();
  std::vector<Sample> ring_;
  Sample held_;
  bool have_sample_ = false;
  std::int64_t k_ = 0;
  Eigen::VectorXd q_meas_, qd_meas_;
  std::vector<Eigen::Matrix<double, 6, 1>> ft_noise_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace

struct Simulator::Impl {
  SimulatorConfig cfg;
  RobotTree tree;
  int n = 0;  // joints = bodies - 1
  std::vector<std::string> joint_names, body_names, foot_names;
  Eigen::VectorXd effort, damping, friction;
  // Per joint: the velocity over which URDF friction saturates (solver.joint_friction_velocity,
  // widened where the explicit step needs it: Impl::limit_explicit_joint_damping).
  Eigen::VectorXd friction_velocity;
  std::vector<std::string> notes;  // what the simulator changed of the URDF, one line each
  RealityDraw reality;             // how the simulated robot differs from its URDF
  // Actuators of the reality configuration (ActuatorReality): the commanded torques of the last
  // delay ticks (ring, column per tick), the lagged torque, per joint Coulomb friction level,
  // noise std and effort limit.
  struct Actuators {
    bool enabled = false;
    Eigen::MatrixXd delayed;  // n x delay_ticks
    int head = 0;
    double alpha = 1.0;  // lag step: 1 = no lag
    Eigen::VectorXd y, noise_std, effort;
    detail::PortableNormal noise{0};
    double torque(int i, double u);  // the applied torque of joint i for command u (one tick)
    void advance() {
      if (delayed.cols() > 0) head = (head + 1) % static_cast<int>(delayed.cols());
    }
  } actuators;
  void configure_actuators();
  std::vector<Eigen::Isometry3d> X_LK;  // body COM frame K in the URDF body frame L
  double mass = 0.0;
  // The description's mass properties (before the reality section), for GroundTruth::model_com_W:
  // per body its mass and CoM in L; empty when the robot is its model.
  std::vector<double> nominal_mass;
  std::vector<Eigen::Vector3d> nominal_com_L;
  double nominal_total_mass = 0.0;
  double dt = 0.001;
  std::int64_t tick = 0;

  // Bullet objects (destroyed in reverse order in ~Impl).
  std::unique_ptr<btDefaultCollisionConfiguration> collision_config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<RowCountingSolver> solver;
  StepTimes step_times;
  std::unique_ptr<btMultiBodyDynamicsWorld> world;
  std::unique_ptr<btMultiBody> mb;
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btMultiBodyLinkCollider>> colliders;
  std::vector<std::unique_ptr<btMultiBodyConstraint>> constraints;
  // Joint-limit constraints are in the solver only while their joint is near a limit (each
  // costs two solver rows per iteration otherwise).
  struct Limit {
    int joint = 0;
    double lower = 0.0, upper = 0.0;
    btMultiBodyConstraint* constraint = nullptr;
    bool active = false;
  };
  std::vector<Limit> limits;
  void update_limits();
  std::unique_ptr<btStaticPlaneShape> ground_shape;
  std::unique_ptr<btCollisionObject> ground;
  std::vector<Platform> platforms;

  // Feet, IMU.
  struct Foot {
    int body = 0;
    Eigen::Isometry3d X_KF = Eigen::Isometry3d::Identity();
    std::vector<Eigen::Vector3d> sole_corners_F;  // sole rectangle (or shape box) corners
    std::vector<ShapeSpec> shapes_F;              // the foot body's collision shapes, X_LS in F
  };
  std::vector<Foot> feet;
  std::vector<int> foot_of_body;  // body -> foot index or -1
  int imu_body = 0;
  Eigen::Isometry3d X_KI = Eigen::Isometry3d::Identity();

  // Pushes.
  std::vector<ResolvedPush> pushes;
  Eigen::Vector3d push_force_W = Eigen::Vector3d::Zero();  // applied in the last step

  // Workspace (allocated once).
  btAlignedObjectArray<btQuaternion> scratch_q;
  btAlignedObjectArray<btVector3> scratch_m;
  btAlignedObjectArray<btVector3> omega_K, vel_K;  // per body, in K
  std::vector<Eigen::Isometry3d> X_WK;
  std::vector<Eigen::Vector3d> v_WK, w_W;  // COM velocity and angular velocity in W
  Eigen::VectorXd tau;
  Eigen::Vector3d imu_v_prev = Eigen::Vector3d::Zero();
  Eigen::Vector3d imu_a = Eigen::Vector3d::Zero();
  SensorModel sensors;
  Eigen::VectorXd q_true, qd_true;
  std::vector<std::uint8_t> contact_scratch;

  explicit Impl(const SimulatorConfig& c);
  ~Impl();
  void build_robot();
  int robot_collision_mask() const;
  void build_multibody();
  static std::unique_ptr<btCollisionShape> make_shape(const ShapeSpec& s);
  void add_colliders();
  void add_joint_constraints();
  void build_world();
  void resolve_feet_and_imu();
  void add_configured_frames();
  void add_sole_box(const FootConfig& f, const detail::FrameSpec& fr, BodySpec& body);
  void find_sole_corners();
  ResolvedPush resolve_push(const Push& p) const;
  void apply_initial_state();
  void set_state(const Eigen::Isometry3d& X_WB, const Eigen::VectorXd& q,
                 const Eigen::Vector3d& v_WB, const Eigen::Vector3d& omega_WB,
                 const Eigen::VectorXd& qd);
  void update_kinematics();
  void update_platforms(double t);
  Eigen::Isometry3d frame_pose(int body, const Eigen::Isometry3d& X_KF) const {
    return X_WK[static_cast<std::size_t>(body)] * X_KF;
  }
  Eigen::Vector3d point_velocity(int body, const Eigen::Vector3d& p_W) const {
    const auto b = static_cast<std::size_t>(body);
    return v_WK[b] + w_W[b].cross(p_W - X_WK[b].translation());
  }
  void fill(SensorFrame& s, GroundTruth& g, bool measure_imu);
  void fill_imu(SensorFrame& s, bool measure_imu);
  void fill_base_and_com(GroundTruth& g);
  void reset_contact_truth(GroundTruth& g);
  void add_manifold(const btPersistentManifold& man, GroundTruth& g, double* weight);
  void finish_foot_wrenches(SensorFrame& s, GroundTruth& g, const double* weight,
                            bool measure_imu);
  double lowest_foot_point(int foot, const Eigen::Vector3d& normal) const;
  void limit_explicit_joint_damping();
};

Simulator::Impl::Impl(const SimulatorConfig& c) : cfg(c) {
  if (!(cfg.solver.dt > 0.0) || !std::isfinite(cfg.solver.dt))
    throw std::runtime_error("solver.dt must be > 0");
  if (cfg.solver.iterations < 1) throw std::runtime_error("solver.iterations must be >= 1");
  if (cfg.robot.feet.empty()) throw std::runtime_error("robot.feet: at least one foot is required");
  dt = cfg.solver.dt;
  tree = detail::load_robot_tree(cfg.robot.urdf_path);
  if (cfg.reality.enabled) {
    for (const auto& b : tree.bodies) {
      nominal_mass.push_back(b.mass);
      nominal_com_L.push_back(b.com_L);
      nominal_total_mass += b.mass;
    }
  }
  reality = detail::apply_reality(cfg.reality, tree);
  n = static_cast<int>(tree.bodies.size()) - 1;
  effort.resize(n);
  damping.resize(n);
  friction = Eigen::VectorXd::Zero(n);
  if (!(cfg.solver.joint_friction_velocity > 0.0))
    throw std::runtime_error("solver.joint_friction_velocity must be > 0");
  for (int i = 0; i < n; ++i) {
    const BodySpec& b = tree.bodies[static_cast<std::size_t>(i + 1)];
    joint_names.push_back(b.joint_name);
    effort[i] = b.effort > 0.0 ? b.effort : std::numeric_limits<double>::infinity();
    damping[i] = b.damping;
    if (!cfg.solver.joint_friction_constraint) friction[i] = b.friction;
  }
  configure_actuators();
  limit_explicit_joint_damping();
  for (const auto& b : tree.bodies)
    body_names.push_back(b.name);
  for (const auto& b : tree.bodies)
    mass += b.mass;
  resolve_feet_and_imu();

  collision_config = std::make_unique<btDefaultCollisionConfiguration>();
  // Several contact points per box/plane pair in one detection pass (stable flat feet).
  collision_config->setPlaneConvexMultipointIterations(5, 4);
  collision_config->setConvexConvexMultipointIterations(5, 4);
  dispatcher = std::make_unique<btCollisionDispatcher>(collision_config.get());
  broadphase = std::make_unique<btDbvtBroadphase>();
  solver = std::make_unique<RowCountingSolver>();
  world = std::make_unique<btMultiBodyDynamicsWorld>(dispatcher.get(), broadphase.get(),
                                                     solver.get(), collision_config.get());
  world->setGravity(bt(cfg.world.gravity));
  btContactSolverInfo& info = world->getSolverInfo();
  info.m_numIterations = cfg.solver.iterations;
  info.m_erp2 = cfg.solver.contact_erp;
  info.m_globalCfm = cfg.solver.contact_cfm;
  info.m_solverMode |= SOLVER_USE_2_FRICTION_DIRECTIONS;
  info.m_timeStep = dt;
  info.m_leastSquaresResidualThreshold = cfg.solver.residual_threshold;
  if (cfg.solver.warm_start) {
    if (!(cfg.solver.warm_start_factor >= 0.0 && cfg.solver.warm_start_factor <= 1.0))
      throw std::runtime_error("solver.warm_start_factor must be in [0, 1]");
    info.m_solverMode |= SOLVER_USE_ARTICULATED_WARMSTARTING;
    info.m_articulatedWarmstartingFactor = cfg.solver.warm_start_factor;
  }

  build_robot();
  build_world();

  pushes.reserve(cfg.pushes.size() + static_cast<std::size_t>(std::max(0, cfg.max_live_pushes)));
  for (const Push& p : cfg.pushes)
    pushes.push_back(resolve_push(p));

  const std::size_t nb = tree.bodies.size();
  X_WK.assign(nb, Eigen::Isometry3d::Identity());
  v_WK.assign(nb, Eigen::Vector3d::Zero());
  w_W.assign(nb, Eigen::Vector3d::Zero());
  omega_K.resize(static_cast<int>(nb));
  vel_K.resize(static_cast<int>(nb));
  scratch_q.resize(static_cast<int>(nb));
  scratch_m.resize(static_cast<int>(nb));
  tau = Eigen::VectorXd::Zero(n);
  q_true = Eigen::VectorXd::Zero(n);
  qd_true = Eigen::VectorXd::Zero(n);
  sensors.configure(cfg, n, feet.size());
  contact_scratch.assign(nb, 0);

  apply_initial_state();
}

Simulator::Impl::~Impl() {
  if (world) {
    for (auto& l : limits)
      if (!l.active) world->addMultiBodyConstraint(l.constraint);
    for (auto& c : constraints)
      world->removeMultiBodyConstraint(c.get());
    for (auto& c : colliders)
      world->removeCollisionObject(c.get());
    if (mb) world->removeMultiBody(mb.get());
    for (auto& p : platforms)
      world->removeRigidBody(p.body.get());
    if (ground) world->removeCollisionObject(ground.get());
  }
  constraints.clear();
  colliders.clear();
  mb.reset();
  world.reset();
}

void Simulator::Impl::resolve_feet_and_imu() {
  foot_of_body.assign(tree.bodies.size(), -1);
  add_configured_frames();
  // A foot touches with its primitives or the configured sole box, never with a mesh's hull
  // (the contact model of the soles, README "Collision"); other bodies keep theirs.
  for (const FootConfig& f : cfg.robot.feet)
    if (const detail::FrameSpec* fr = tree.find_frame(f.frame)) {
      auto& shapes = tree.bodies[static_cast<std::size_t>(fr->body)].shapes;
      shapes.erase(
          std::remove_if(shapes.begin(), shapes.end(),
                         [](const ShapeSpec& sh) { return sh.type == ShapeSpec::Type::kConvex; }),
          shapes.end());
    }
  for (const FootConfig& f : cfg.robot.feet) {
    const detail::FrameSpec* fr = tree.find_frame(f.frame);
    if (!fr)
      throw std::runtime_error("robot.feet." + f.name + ": frame '" + f.frame +
                               "' is not a link of the URDF");
    if (foot_of_body[static_cast<std::size_t>(fr->body)] >= 0)
      throw std::runtime_error("robot.feet." + f.name + ": frame '" + f.frame +
                               "' is on the same body as another foot");
    BodySpec& body = tree.bodies[static_cast<std::size_t>(fr->body)];
    Foot foot;
    foot.body = fr->body;
    if (body.shapes.empty()) add_sole_box(f, *fr, body);
    foot_of_body[static_cast<std::size_t>(fr->body)] = static_cast<int>(feet.size());
    feet.push_back(foot);
    foot_names.push_back(f.name);
  }
  X_LK.resize(tree.bodies.size());
  find_sole_corners();
  // What collides: every collision shape of the foot body (the sole box substitute included),
  // in F; the robot is placed by these, not by the configured sole plane (they can differ).
  for (std::size_t i = 0; i < feet.size(); ++i) {
    const detail::FrameSpec* fr = tree.find_frame(cfg.robot.feet[i].frame);
    for (ShapeSpec sh : tree.bodies[static_cast<std::size_t>(fr->body)].shapes) {
      sh.X_LS = fr->X_LF.inverse() * sh.X_LS;
      feet[i].shapes_F.push_back(sh);
    }
  }
  const std::string imu = cfg.robot.imu_frame.empty() ? tree.bodies[0].name : cfg.robot.imu_frame;
  if (!tree.find_frame(imu))
    throw std::runtime_error("robot.imu_frame: '" + imu + "' is not a link of the URDF");
}

// Frames fixed to a link at an offset (robot.yaml soles given as offset + rotation).
void Simulator::Impl::add_configured_frames() {
  for (const AddedFrame& a : cfg.robot.added_frames) {
    if (tree.find_frame(a.name))
      throw std::runtime_error("robot.added_frames: '" + a.name + "' is already a URDF link");
    const detail::FrameSpec* lf = tree.find_frame(a.link);
    if (!lf)
      throw std::runtime_error("robot.added_frames: '" + a.name + "': link '" + a.link +
                               "' is not a link of the URDF");
    if (!a.X_link_frame.matrix().allFinite())
      throw std::runtime_error("robot.added_frames: the pose of '" + a.name + "' in '" + a.link +
                               "' is not finite");
    detail::FrameSpec added;
    added.name = a.name;
    added.body = lf->body;
    added.X_LF = lf->X_LF * a.X_link_frame;
    tree.frames.push_back(added);
  }
}

// A foot link without collision primitives touches with the configured sole rectangle: a box
// of the sole's thickness under the sole plane.
void Simulator::Impl::add_sole_box(const FootConfig& f, const detail::FrameSpec& fr,
                                   BodySpec& body) {
  if (!f.has_sole)
    throw std::runtime_error(
        "robot.feet." + f.name + ": foot link '" + f.frame + "' (body '" + body.name +
        "') has " + (body.has_mesh ? "only mesh collision geometry" : "no collision geometry") +
        " and the robot configuration gives no sole rectangle for it: add a sole "
        "(x_min, x_max, y_min, y_max, height) for this foot");
  const SoleConfig& s = f.sole;
  if (!(s.x_max > s.x_min) || !(s.y_max > s.y_min) || !(s.thickness > 0.0) ||
      !std::isfinite(s.height))
    throw std::runtime_error("robot.feet." + f.name +
                             ".sole: needs x_max > x_min, y_max > y_min, thickness > 0");
  ShapeSpec box;
  box.type = ShapeSpec::Type::kBox;
  box.size = 0.5 * Eigen::Vector3d(s.x_max - s.x_min, s.y_max - s.y_min, s.thickness);
  Eigen::Isometry3d X_FS = Eigen::Isometry3d::Identity();
  X_FS.translation() = Eigen::Vector3d(0.5 * (s.x_min + s.x_max), 0.5 * (s.y_min + s.y_max),
                                       -s.height + 0.5 * s.thickness);
  box.X_LS = fr.X_LF * X_FS;
  body.shapes.push_back(box);
}

// Sole corners (for initial placement): the configured rectangle, else the bottom of the
// foot shapes' bounding box in F.
void Simulator::Impl::find_sole_corners() {
  for (std::size_t i = 0; i < feet.size(); ++i) {
    const FootConfig& f = cfg.robot.feet[i];
    const detail::FrameSpec* fr = tree.find_frame(f.frame);
    if (f.has_sole) {
      const SoleConfig& s = f.sole;
      for (double x : {s.x_min, s.x_max})
        for (double y : {s.y_min, s.y_max})
          feet[i].sole_corners_F.emplace_back(x, y, -s.height);
    } else {
      // corners of every primitive's bounding box, expressed in F
      const BodySpec& body = tree.bodies[static_cast<std::size_t>(fr->body)];
      for (const ShapeSpec& sh : body.shapes) {
        Eigen::Vector3d h = sh.size;
        if (sh.type == ShapeSpec::Type::kSphere) h = Eigen::Vector3d::Constant(sh.size.x());
        if (sh.type == ShapeSpec::Type::kCylinder)
          h = Eigen::Vector3d(sh.size.x(), sh.size.x(), 0.5 * sh.size.y());
        for (int k = 0; k < 8; ++k) {
          const Eigen::Vector3d p_S((k & 1 ? 1 : -1) * h.x(), (k & 2 ? 1 : -1) * h.y(),
                                    (k & 4 ? 1 : -1) * h.z());
          feet[i].sole_corners_F.push_back(fr->X_LF.inverse() * (sh.X_LS * p_S));
        }
      }
    }
  }
}

// The reality configuration's actuators (ActuatorReality): its friction joins the URDF's explicit
// friction and damping (so the explicit step's limit below covers it too); lag, delay, noise and
// the lower effort limit act in Actuators::torque.
void Simulator::Impl::configure_actuators() {
  const ActuatorReality& a = cfg.reality.actuators;
  if (!cfg.reality.enabled) return;
  const auto of_effort = [&](int i, double fraction) {
    return std::isfinite(effort[i]) ? fraction * effort[i] : 0.0;
  };
  Actuators& act = actuators;
  act.enabled = true;
  act.delayed = Eigen::MatrixXd::Zero(n, a.delay_ticks);
  act.alpha = a.bandwidth_hz > 0.0 ? 1.0 - std::exp(-2.0 * M_PI * a.bandwidth_hz * dt) : 1.0;
  act.y = Eigen::VectorXd::Zero(n);
  act.noise_std.resize(n);
  act.effort.resize(n);
  act.noise = detail::PortableNormal(cfg.reality.seed ^ 0xac7a7035eedULL);
  for (int i = 0; i < n; ++i) {
    friction[i] += a.coulomb_friction + of_effort(i, a.coulomb_friction_of_effort);
    damping[i] += a.viscous_friction;
    act.noise_std[i] = a.torque_noise_std + of_effort(i, a.torque_noise_of_effort);
    act.effort[i] = a.effort_scale * effort[i];
  }
}

double Simulator::Impl::Actuators::torque(int i, double u) {
  if (!enabled) return u;
  if (delayed.cols() > 0) {  // the slot at head holds the command of delay ticks ago
    double& slot = delayed(i, head);
    const double due = slot;
    slot = u;
    u = due;
  }
  y[i] += alpha * (u - y[i]);
  const double t = noise_std[i] > 0.0 ? y[i] + noise_std[i] * noise() : y[i];
  return std::clamp(t, -effort[i], effort[i]);
}

// The URDF's joint damping and smooth friction are explicit torques, -c qd with c = damping +
// friction / joint_friction_velocity below the friction's saturation: over one step of dt they
// are stable only while c dt / I < 2, I the inertia the joint moves. A hand's last finger link
// (Valkyrie: 6 g, 1e-6 kg m^2 about its joint, damping 0.5 and friction 0.5 N m) has c dt / I ~
// 5e4, and the whole robot blew up within 15 ms of the start. Where c exceeds I / dt (a velocity
// damped to zero in one step: the limit of any stronger damping), damping and friction slope are
// scaled down together to I / dt, the friction keeping its level (its saturation velocity
// widened). I: the joint's articulated-body inertia about its axis at q = 0 with its parent held
// (what its torque accelerates when every joint below it is free: the least it can meet).
void Simulator::Impl::limit_explicit_joint_damping() {
  friction_velocity = Eigen::VectorXd::Constant(n, cfg.solver.joint_friction_velocity);
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  auto skew = [](const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
    return m;
  };
  const std::size_t nb = tree.bodies.size();
  std::vector<Mat6> IA(nb);
  std::vector<Vec6> S(nb, Vec6::Zero());
  for (std::size_t b = 0; b < nb; ++b) {  // spatial inertias (angular; linear) at the body frame
    const BodySpec& body = tree.bodies[b];
    const Eigen::Matrix3d cx = skew(body.com_L);
    IA[b].setZero();
    IA[b].topLeftCorner<3, 3>() = body.inertia_com_L + body.mass * cx * cx.transpose();
    IA[b].topRightCorner<3, 3>() = body.mass * cx;
    IA[b].bottomLeftCorner<3, 3>() = body.mass * cx.transpose();
    IA[b].bottomRightCorner<3, 3>() = body.mass * Eigen::Matrix3d::Identity();
    const Eigen::Vector3d a = body.axis_L.normalized();
    if (body.joint == BodySpec::Joint::kRevolute) S[b].head<3>() = a;
    if (body.joint == BodySpec::Joint::kPrismatic) S[b].tail<3>() = a;
  }
  std::vector<double> d(nb, 0.0);
  for (std::size_t b = nb - 1; b >= 1; --b) {  // leaves first: parents precede children
    const Vec6 U = IA[b] * S[b];
    d[b] = S[b].dot(U);
    const BodySpec& body = tree.bodies[b];
    if (body.parent < 0 || !(d[b] > 0.0)) continue;
    const Mat6 Ia = IA[b] - U * U.transpose() / d[b];
    // Motion transform from the parent's frame to this body's (its frame at q = 0 is X_PJ).
    const Eigen::Matrix3d Rt = body.X_PJ.linear().transpose();
    Mat6 X = Mat6::Zero();
    X.topLeftCorner<3, 3>() = Rt;
    X.bottomRightCorner<3, 3>() = Rt;
    X.bottomLeftCorner<3, 3>() = -Rt * skew(body.X_PJ.translation());
    IA[static_cast<std::size_t>(body.parent)] += X.transpose() * Ia * X;
  }
  for (int i = 0; i < n; ++i) {
    const std::size_t b = static_cast<std::size_t>(i + 1);
    const double c = damping[i] + friction[i] / friction_velocity[i];
    const double c_max = d[b] / dt;
    if (!(c > 0.0) || c <= c_max) continue;
    const double scale = c_max / c;
    std::ostringstream os;
    os << "joint '" << tree.bodies[b].joint_name << "': URDF damping " << damping[i]
       << " and friction " << friction[i] << " damp it by " << c
       << " (SI) at low speed, more than what it moves (" << d[b]
       << " kg m^2 about the axis, the joints below it free) takes in an explicit step of " << dt
       << " s: simulated as " << c_max << " (damping " << damping[i] * scale
       << ", friction saturating at " << friction_velocity[i] / scale << " instead of "
       << friction_velocity[i] << ")";
    notes.push_back(os.str());
    damping[i] *= scale;
    friction_velocity[i] /= scale;
  }
}

void Simulator::Impl::build_robot() {
  build_multibody();
  add_colliders();
  add_joint_constraints();
}

// Without self-collision the robot's links only meet the environment: robot-robot pairs are
// then not even created by the broadphase (instead of being created and rejected each step).
int Simulator::Impl::robot_collision_mask() const {
  return cfg.robot.self_collision ? (kRobotGroup | kEnvGroup) : kEnvGroup;
}

// The articulated body: each link's frame K at its CoM along its principal axes.
void Simulator::Impl::build_multibody() {
  const std::size_t nb = tree.bodies.size();
  std::vector<Eigen::Vector3d> principal(nb);
  for (std::size_t b = 0; b < nb; ++b) {
    const BodySpec& body = tree.bodies[b];
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(body.inertia_com_L);
    Eigen::Matrix3d R = es.eigenvectors();
    if (R.determinant() < 0.0) R.col(2) = -R.col(2);
    X_LK[b] = Eigen::Isometry3d::Identity();
    X_LK[b].linear() = R;
    X_LK[b].translation() = body.com_L;
    // Featherstone needs a positive-definite inertia: point masses get a tiny sphere inertia.
    principal[b] = es.eigenvalues().cwiseMax(1e-9);
  }
  mb = std::make_unique<btMultiBody>(n, tree.bodies[0].mass, bt(principal[0]), false, false);
  for (int i = 0; i < n; ++i) {
    const std::size_t b = static_cast<std::size_t>(i + 1);
    const BodySpec& body = tree.bodies[b];
    const std::size_t p = static_cast<std::size_t>(body.parent);
    const Eigen::Isometry3d X_KpJ = X_LK[p].inverse() * body.X_PJ;
    const Eigen::Matrix3d R_KpKb = X_KpJ.linear() * X_LK[b].linear();
    const btQuaternion rot_parent_to_this = bt(Eigen::Quaterniond(R_KpKb.transpose()));
    const btVector3 axis = bt(Eigen::Vector3d(X_LK[b].linear().transpose() * body.axis_L));
    const btVector3 parent_com_to_pivot = bt(Eigen::Vector3d(X_KpJ.translation()));
    const btVector3 pivot_to_com = bt(Eigen::Vector3d(X_LK[b].linear().transpose() * body.com_L));
    const bool disable_parent_collision = true;
    if (body.joint == BodySpec::Joint::kRevolute)
      mb->setupRevolute(i, body.mass, bt(principal[b]), body.parent - 1, rot_parent_to_this, axis,
                        parent_com_to_pivot, pivot_to_com, disable_parent_collision);
    else
      mb->setupPrismatic(i, body.mass, bt(principal[b]), body.parent - 1, rot_parent_to_this, axis,
                         parent_com_to_pivot, pivot_to_com, disable_parent_collision);
  }
  mb->finalizeMultiDof();
  mb->setLinearDamping(0.0);
  mb->setAngularDamping(0.0);
  mb->setHasSelfCollision(cfg.robot.self_collision);
  mb->setCanSleep(false);
  mb->setUseGyroTerm(true);
  mb->setMaxCoordinateVelocity(1000.0);
  const int robot_mask = robot_collision_mask();
  world->addMultiBody(mb.get(), kRobotGroup, robot_mask);
}

// One collision primitive of a link (a mesh as its reduced convex hull).
std::unique_ptr<btCollisionShape> Simulator::Impl::make_shape(const ShapeSpec& s) {
  std::unique_ptr<btCollisionShape> shape;
  switch (s.type) {
    case ShapeSpec::Type::kBox:
      shape = std::make_unique<btBoxShape>(bt(s.size));
      break;
    case ShapeSpec::Type::kSphere:
      shape = std::make_unique<btSphereShape>(s.size.x());
      break;
    case ShapeSpec::Type::kCylinder:
      shape = std::make_unique<btCylinderShapeZ>(
          btVector3(s.size.x(), s.size.x(), 0.5 * s.size.y()));
      break;
    case ShapeSpec::Type::kConvex: {
      // The mesh's convex hull, reduced by Bullet's hull builder to a few dozen vertices
      // (a support-point query per contact test walks them all).
      btConvexHullShape all;
      for (const Eigen::Vector3d& p : s.points)
        all.addPoint(bt(p), false);
      all.setMargin(0.0);  // the reduction samples support points, margin included
      all.recalcLocalAabb();
      btShapeHull reduced(&all);
      reduced.buildHull(0.0);
      auto hull = std::make_unique<btConvexHullShape>();
      for (int v = 0; v < reduced.numVertices(); ++v)
        hull->addPoint(reduced.getVertexPointer()[v], false);
      // Bullet inflates a hull by its margin (0.04 m by default, unlike its box, sphere and
      // cylinder, whose margin is inside): a shank 3 cm above the ground then touched it.
      // 0.1 mm: a box mesh rests where the box does (tests/simulator/physics_test.cpp).
      hull->setMargin(1e-4);
      hull->recalcLocalAabb();
      shape = std::move(hull);
      break;
    }
  }
  return shape;
}

// Each link's collision shapes, one compound per link, in the world.
void Simulator::Impl::add_colliders() {
  const int robot_mask = robot_collision_mask();
  for (std::size_t b = 0; b < tree.bodies.size(); ++b) {
    const BodySpec& body = tree.bodies[b];
    if (body.shapes.empty()) continue;
    auto compound = std::make_unique<btCompoundShape>(false, static_cast<int>(body.shapes.size()));
    for (const ShapeSpec& s : body.shapes) {
      std::unique_ptr<btCollisionShape> shape = make_shape(s);
      compound->addChildShape(bt(Eigen::Isometry3d(X_LK[b].inverse() * s.X_LS)), shape.get());
      shapes.push_back(std::move(shape));
    }
    auto col = std::make_unique<btMultiBodyLinkCollider>(mb.get(), static_cast<int>(b) - 1);
    col->setCollisionShape(compound.get());
    col->setFriction(1.0);  // Bullet multiplies the two coefficients: the support sets mu
    col->setRestitution(0.0);
    col->setRollingFriction(0.0);
    col->setSpinningFriction(0.0);
    col->setUserIndex(static_cast<int>(b));
    if (cfg.solver.friction_anchor && foot_of_body[b] >= 0)
      col->setCollisionFlags(col->getCollisionFlags() | btCollisionObject::CF_HAS_FRICTION_ANCHOR);
    shapes.push_back(std::move(compound));
    world->addCollisionObject(col.get(), kRobotGroup, robot_mask);
    if (b == 0)
      mb->setBaseCollider(col.get());
    else
      mb->getLink(static_cast<int>(b) - 1).m_collider = col.get();
    colliders.push_back(std::move(col));
  }
}

// Joint limits and Coulomb joint friction, as multibody constraints.
void Simulator::Impl::add_joint_constraints() {
  for (int i = 0; i < n; ++i) {
    const BodySpec& body = tree.bodies[static_cast<std::size_t>(i + 1)];
    if (body.limited) {
      auto lim =
          std::make_unique<btMultiBodyJointLimitConstraint>(mb.get(), i, body.lower, body.upper);
      world->addMultiBodyConstraint(lim.get());  // all in once: the array keeps its capacity
      limits.push_back(Limit{i, body.lower, body.upper, lim.get(), true});
      constraints.push_back(std::move(lim));
    }
    if (body.friction > 0.0 && cfg.solver.joint_friction_constraint) {
      // Coulomb joint friction: a zero-velocity motor whose force is bounded by the friction.
      auto fr = std::make_unique<btMultiBodyJointMotor>(mb.get(), i, 0.0, body.friction * dt);
      world->addMultiBodyConstraint(fr.get());
      constraints.push_back(std::move(fr));
    }
  }
}

void Simulator::Impl::build_world() {
  // A compliant ground (reality.ground): Bullet turns a contact's stiffness k and damping c into
  // the contact row's ERP = dt k / (dt k + c) and CFM = 1 / (dt k + c), per contact point. The
  // robot's colliders keep Bullet's defaults (stiffness 1e18, damping 0.1), which combine with
  // these in series and in parallel.
  const auto make_compliant = [&](btCollisionObject& o) {
    if (cfg.reality.enabled && cfg.reality.ground.stiffness > 0.0)
      o.setContactStiffnessAndDamping(cfg.reality.ground.stiffness, cfg.reality.ground.damping);
  };
  if (cfg.world.ground.enabled) {
    if (!(cfg.world.ground.friction >= 0.0))
      throw std::runtime_error("world.ground.friction must be >= 0");
    if (cfg.solver.ground_aabb_band > 0.0)
      ground_shape =
          std::make_unique<BandedPlaneShape>(cfg.world.ground.height, cfg.solver.ground_aabb_band);
    else
      ground_shape =
          std::make_unique<btStaticPlaneShape>(btVector3(0, 0, 1), cfg.world.ground.height);
    ground = std::make_unique<btCollisionObject>();
    ground->setCollisionShape(ground_shape.get());
    ground->setFriction(std::isfinite(reality.ground_friction) ? reality.ground_friction
                                                               : cfg.world.ground.friction);
    make_compliant(*ground);
    ground->setRestitution(0.0);
    ground->setUserIndex(kGroundIndex);
    world->addCollisionObject(ground.get(), kEnvGroup, kRobotGroup);
  }
  platforms.reserve(cfg.world.platforms.size());
  for (std::size_t k = 0; k < cfg.world.platforms.size(); ++k) {
    const PlatformConfig& pc = cfg.world.platforms[k];
    const std::string key = "world.platforms[" + std::to_string(k) + "] ('" + pc.name + "')";
    if (!(pc.half_extents.array() > 0.0).all()) throw std::runtime_error(key + ".size must be > 0");
    if (!(pc.friction >= 0.0)) throw std::runtime_error(key + ".friction must be >= 0");
    if (pc.motion_ramp < 0.0 || !std::isfinite(pc.motion_start))
      throw std::runtime_error(key + ": motion_ramp must be >= 0 and motion_start finite");
    if (pc.translation_axis.norm() < 1e-9 || pc.rotation_axis.norm() < 1e-9)
      throw std::runtime_error(key + ": motion axes must be non-zero");
    if (pc.auto_place &&
        std::find(foot_names.begin(), foot_names.end(), pc.foot) == foot_names.end())
      throw std::runtime_error(key + ".foot: '" + pc.foot + "' is not a foot of the robot");
    Platform p;
    p.cfg = pc;
    p.cfg.translation_axis.normalize();
    p.cfg.rotation_axis.normalize();
    p.R_incline = (Eigen::AngleAxisd(pc.yaw, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(pc.pitch, Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(pc.roll, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
    p.base_position = pc.position;
    p.shape = std::make_unique<PaddedBoxShape>(bt(pc.half_extents), kPlatformAabbPad);
    btRigidBody::btRigidBodyConstructionInfo ci(0.0, nullptr, p.shape.get());
    p.body = std::make_unique<btRigidBody>(ci);
    p.body->setCollisionFlags(p.body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
    p.body->setActivationState(DISABLE_DEACTIVATION);
    p.body->setFriction(std::isfinite(reality.ground_friction) ? reality.ground_friction
                                                               : pc.friction);
    make_compliant(*p.body);
    p.body->setRestitution(0.0);
    p.body->setUserIndex(-2 - static_cast<int>(k));
    world->addRigidBody(p.body.get(), kEnvGroup, kRobotGroup);
    platforms.push_back(std::move(p));
  }
}

ResolvedPush Simulator::Impl::resolve_push(const Push& p) const {
  const detail::FrameSpec* fr = tree.find_frame(p.link);
  if (!fr) throw std::runtime_error("push: link '" + p.link + "' is not a link of the URDF");
  if (!p.point_L.allFinite() || !p.force_W.allFinite() || !std::isfinite(p.start) ||
      !std::isfinite(p.duration) || p.duration < 0.0 || p.start < 0.0)
    throw std::runtime_error("push on '" + p.link + "': non-finite or negative value");
  ResolvedPush r;
  r.body = fr->body;
  r.point_K = X_LK[static_cast<std::size_t>(fr->body)].inverse() * (fr->X_LF * p.point_L);
  r.force_W = p.force_W;
  r.start_tick = std::llround(p.start / dt);
  r.end_tick = r.start_tick + std::llround(p.duration / dt);
  return r;
}

void Simulator::Impl::update_limits() {
  for (Limit& l : limits) {
    const double q = mb->getJointPos(l.joint), qd = mb->getJointVel(l.joint);
    // near = within 0.05 rad (or m) plus 20 steps of travel of the limit
    const double margin = 0.05 + 20.0 * dt * std::abs(qd);
    const bool near = q - l.lower < margin || l.upper - q < margin;
    if (near && !l.active) world->addMultiBodyConstraint(l.constraint);
    if (!near && l.active) world->removeMultiBodyConstraint(l.constraint);
    l.active = near;
  }
}

void Simulator::Impl::update_kinematics() {
  mb->forwardKinematics(scratch_q, scratch_m);
  mb->compTreeLinkVelocities(&omega_K[0], &vel_K[0]);
  const std::size_t nb = tree.bodies.size();
  for (std::size_t b = 0; b < nb; ++b) {
    X_WK[b] = b == 0 ? eig(mb->getBaseWorldTransform())
                     : eig(mb->getLink(static_cast<int>(b) - 1).m_cachedWorldTransform);
    const Eigen::Matrix3d& R = X_WK[b].linear();
    v_WK[b] = R * eig(vel_K[static_cast<int>(b)]);
    w_W[b] = R * eig(omega_K[static_cast<int>(b)]);
  }
}

void Simulator::Impl::update_platforms(double t) {
  for (Platform& p : platforms) {
    // The solver sees the support velocity at mid-step; the pose is exact at t.
    Eigen::Isometry3d X_WP, X_mid;
    Eigen::Vector3d v, w, v_mid, w_mid;
    p.pose(t, X_WP, v, w);
    p.pose(t + 0.5 * dt, X_mid, v_mid, w_mid);
    Eigen::Isometry3d X_WC = X_WP;  // box centre: half a thickness below the top face
    X_WC.translation() = X_WP * Eigen::Vector3d(0.0, 0.0, -p.cfg.half_extents.z());
    // Bullet derives a kinematic body's velocity from (interpolation -> current) transforms:
    // place the interpolation transform one step "behind" with exactly the mid-step velocity.
    Eigen::Isometry3d X_prev = Eigen::Isometry3d::Identity();
    const double wn = w_mid.norm();
    X_prev.linear() = (wn > 0.0 ? Eigen::AngleAxisd(-wn * dt, w_mid / wn).toRotationMatrix()
                                : Eigen::Matrix3d::Identity()) *
                      X_WC.linear();
    // velocity of the box centre = v_mid + w_mid x (centre - top point)
    const Eigen::Vector3d v_c = v_mid + w_mid.cross(X_WC.translation() - X_WP.translation());
    X_prev.translation() = X_WC.translation() - v_c * dt;
    p.body->setWorldTransform(bt(X_WC));
    p.body->setInterpolationWorldTransform(bt(X_prev));
    p.body->setLinearVelocity(bt(v_c));
    p.body->setAngularVelocity(bt(w_mid));
  }
}

double Simulator::Impl::lowest_foot_point(int foot, const Eigen::Vector3d& normal) const {
  const Foot& f = feet[static_cast<std::size_t>(foot)];
  const Eigen::Isometry3d X_WF = frame_pose(f.body, f.X_KF);
  double lo = std::numeric_limits<double>::infinity();
  for (const ShapeSpec& sh : f.shapes_F) {
    const Eigen::Isometry3d X_WS = X_WF * sh.X_LS;
    const Eigen::Vector3d n_S = X_WS.linear().transpose() * normal;
    const double c = normal.dot(X_WS.translation());
    switch (sh.type) {
      case ShapeSpec::Type::kBox:
        lo = std::min(lo, c - n_S.cwiseAbs().dot(sh.size));
        break;
      case ShapeSpec::Type::kSphere:
        lo = std::min(lo, c - sh.size.x());
        break;
      case ShapeSpec::Type::kCylinder: {  // size: (radius, length), axis z
        const double az = std::min(1.0, std::abs(n_S.z()));
        lo = std::min(
            lo, c - sh.size.x() * std::sqrt(std::max(0.0, 1.0 - az * az)) - 0.5 * sh.size.y() * az);
        break;
      }
      case ShapeSpec::Type::kConvex:  // (not on a foot: removed when the feet are set up)
        for (const Eigen::Vector3d& p : sh.points)
          lo = std::min(lo, c + n_S.dot(p));
        break;
    }
  }
  if (f.shapes_F.empty())  // (not reached: a foot without shapes gets the sole box)
    for (const auto& p : f.sole_corners_F)
      lo = std::min(lo, normal.dot(X_WF * p));
  return lo;
}

void Simulator::Impl::apply_initial_state() {
  for (std::size_t i = 0; i < feet.size(); ++i) {
    const detail::FrameSpec* fr = tree.find_frame(cfg.robot.feet[i].frame);
    feet[i].X_KF = X_LK[static_cast<std::size_t>(fr->body)].inverse() * fr->X_LF;
  }
  {
    const std::string imu = cfg.robot.imu_frame.empty() ? tree.bodies[0].name : cfg.robot.imu_frame;
    const detail::FrameSpec* fr = tree.find_frame(imu);
    imu_body = fr->body;
    X_KI = X_LK[static_cast<std::size_t>(fr->body)].inverse() * fr->X_LF;
  }
  const InitialState& ini = cfg.initial;
  if (ini.joint_names.size() != ini.joint_positions.size())
    throw std::runtime_error("initial: joint names and positions differ in size");
  Eigen::VectorXd q = Eigen::VectorXd::Zero(n);
  for (std::size_t k = 0; k < ini.joint_names.size(); ++k) {
    auto it = std::find(joint_names.begin(), joint_names.end(), ini.joint_names[k]);
    if (it == joint_names.end())
      throw std::runtime_error("initial.joints: '" + ini.joint_names[k] +
                               "' is not a movable joint of the URDF");
    if (!std::isfinite(ini.joint_positions[k]))
      throw std::runtime_error("initial.joints: '" + ini.joint_names[k] + "' is not finite");
    q[it - joint_names.begin()] = ini.joint_positions[k];
  }
  Eigen::Quaterniond qb(ini.base_orientation_wxyz[0], ini.base_orientation_wxyz[1],
                        ini.base_orientation_wxyz[2], ini.base_orientation_wxyz[3]);
  if (!ini.base_orientation_wxyz.allFinite() || qb.norm() < 1e-9 || !ini.base_position.allFinite())
    throw std::runtime_error("initial.base: invalid pose");
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  X_WB.linear() = qb.normalized().toRotationMatrix();
  X_WB.translation() = ini.base_position;
  set_state(X_WB, q, ini.base_linear_velocity, Eigen::Vector3d::Zero(), Eigen::VectorXd());

  if (ini.auto_base_height) {
    double support_top = cfg.world.ground.enabled ? cfg.world.ground.height : 0.0;
    for (const Platform& p : platforms)
      if (p.cfg.auto_place)
        support_top = std::max(support_top, cfg.world.ground.height + 2.0 * p.cfg.half_extents.z());
    double lo = std::numeric_limits<double>::infinity();
    for (std::size_t f = 0; f < feet.size(); ++f)
      lo = std::min(lo, lowest_foot_point(static_cast<int>(f), Eigen::Vector3d::UnitZ()));
    X_WB.translation().z() += support_top + ini.clearance - lo;
    set_state(X_WB, q, ini.base_linear_velocity, Eigen::Vector3d::Zero(), Eigen::VectorXd());
  }
  // Platforms under their feet: the top plane touches the lowest sole corner.
  for (Platform& p : platforms) {
    if (!p.cfg.auto_place) continue;
    const int f = static_cast<int>(std::find(foot_names.begin(), foot_names.end(), p.cfg.foot) -
                                   foot_names.begin());
    const Foot& foot = feet[static_cast<std::size_t>(f)];
    const Eigen::Isometry3d X_WF = frame_pose(foot.body, foot.X_KF);
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& c : foot.sole_corners_F)
      centre += X_WF * c;
    centre /= static_cast<double>(foot.sole_corners_F.size());
    const Eigen::Vector3d nrm = p.R_incline.col(2);
    const double top = lowest_foot_point(f, nrm) - ini.clearance;
    Eigen::Vector3d P(centre.x(), centre.y(), 0.0);
    P.z() = (top - nrm.x() * P.x() - nrm.y() * P.y()) / nrm.z();
    p.base_position = P + p.cfg.position;
  }
  update_platforms(0.0);
}

void Simulator::Impl::set_state(const Eigen::Isometry3d& X_WB, const Eigen::VectorXd& q,
                                const Eigen::Vector3d& v_WB, const Eigen::Vector3d& omega_WB,
                                const Eigen::VectorXd& qd) {
  if (q.size() != n || (qd.size() != 0 && qd.size() != n))
    throw std::runtime_error("set_state: q / qd must have dim " + std::to_string(n));
  const Eigen::Isometry3d X_WK0 = X_WB * X_LK[0];
  mb->setBasePos(bt(Eigen::Vector3d(X_WK0.translation())));
  mb->setWorldToBaseRot(bt(Eigen::Quaterniond(X_WK0.linear()).conjugate()));
  mb->setBaseVel(
      bt(Eigen::Vector3d(v_WB + omega_WB.cross(X_WK0.translation() - X_WB.translation()))));
  mb->setBaseOmega(bt(omega_WB));
  for (int i = 0; i < n; ++i) {
    mb->setJointPos(i, q[i]);
    mb->setJointVel(i, qd.size() == n ? qd[i] : 0.0);
  }
  mb->updateCollisionObjectWorldTransforms(scratch_q, scratch_m);
  update_kinematics();
  for (auto& c : colliders)
    world->updateSingleAabb(c.get());
  const Eigen::Isometry3d X_WI = frame_pose(imu_body, X_KI);
  imu_v_prev = point_velocity(imu_body, X_WI.translation());
  imu_a.setZero();
  for (int i = 0; i < n; ++i) {
    q_true[i] = q[i];
    qd_true[i] = qd.size() == n ? qd[i] : 0.0;
  }
  sensors.reset(q_true, qd_true);
}

void Simulator::Impl::fill(SensorFrame& s, GroundTruth& g, bool measure_imu) {
  const double t = static_cast<double>(tick) * dt;
  s.tick = tick;
  s.time = t;
  g.tick = tick;
  g.time = t;
  g.push_force_W = push_force_W;
  for (int i = 0; i < n; ++i) {
    q_true[i] = mb->getJointPos(i);
    qd_true[i] = mb->getJointVel(i);
  }
  sensors.encoders(measure_imu, q_true, qd_true, s);
  s.tau_measured = tau;

  fill_imu(s, measure_imu);
  fill_base_and_com(g);
  for (std::size_t k = 0; k < platforms.size() && k < g.platform_X_WP.size(); ++k) {
    Eigen::Vector3d v, w;
    platforms[k].pose(t, g.platform_X_WP[k], v, w);
  }
  // Contacts: impulses of the step just taken, from every robot/support manifold.
  double weight[16] = {};
  reset_contact_truth(g);
  const int num_manifolds = dispatcher->getNumManifolds();
  for (int m = 0; m < num_manifolds; ++m)
    add_manifold(*dispatcher->getManifoldByIndexInternal(m), g, weight);
  finish_foot_wrenches(s, g, weight, measure_imu);
}

void Simulator::Impl::fill_imu(SensorFrame& s, bool measure_imu) {
  const Eigen::Isometry3d X_WI = frame_pose(imu_body, X_KI);
  const Eigen::Matrix3d R_WI = X_WI.linear();
  const Eigen::Vector3d v_I = point_velocity(imu_body, X_WI.translation());
  if (measure_imu) {
    imu_a = (v_I - imu_v_prev) / dt;
    imu_v_prev = v_I;
  }
  sensors.imu(measure_imu, R_WI, R_WI.transpose() * w_W[static_cast<std::size_t>(imu_body)],
              R_WI.transpose() * (imu_a - cfg.world.gravity), s);

}

// The base's pose and twist, the CoM and its velocity, and the CoM of the robot's model (reality:
// the simulated robot's masses differ from the description's).
void Simulator::Impl::fill_base_and_com(GroundTruth& g) {
  g.X_WB = X_WK[0] * X_LK[0].inverse();
  g.omega_WB = w_W[0];
  g.v_WB = point_velocity(0, g.X_WB.translation());
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), cv = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < tree.bodies.size(); ++b) {
    c += tree.bodies[b].mass * X_WK[b].translation();
    cv += tree.bodies[b].mass * v_WK[b];
  }
  g.com_W = c / mass;
  g.com_vel_W = cv / mass;
  if (!nominal_mass.empty() && nominal_total_mass > 0.0) {
    Eigen::Vector3d cn = Eigen::Vector3d::Zero();
    for (std::size_t b = 0; b < tree.bodies.size(); ++b)
      cn += nominal_mass[b] * (X_WK[b] * (X_LK[b].inverse() * nominal_com_L[b]));
    g.model_com_shift_W = cn / nominal_total_mass - g.com_W;
  }
}

void Simulator::Impl::reset_contact_truth(GroundTruth& g) {
  for (std::size_t f = 0; f < feet.size(); ++f) {
    FootContactTruth& ft = g.feet[f];
    ft.X_WF = frame_pose(feet[f].body, feet[f].X_KF);
    ft.v_WF = point_velocity(feet[f].body, ft.X_WF.translation());
    ft.in_contact = false;
    ft.num_points = 0;
    ft.force_W.setZero();
    ft.torque_Fo_W.setZero();
    ft.cop_W.setZero();
  }
  std::fill(g.non_foot_contact.begin(), g.non_foot_contact.end(), 0);
  g.num_non_foot_contacts = 0;
  g.total_contact_force_W.setZero();
}

// One robot/support manifold's touching points into the feet's wrenches and CoPs (weight: each
// foot's normal impulse, for the CoP) or the non-foot contacts.
void Simulator::Impl::add_manifold(const btPersistentManifold& man, GroundTruth& g,
                                   double* weight) {
  const int u0 = man.getBody0()->getUserIndex();
  const int u1 = man.getBody1()->getUserIndex();
  if ((u0 >= 0) == (u1 >= 0)) return;  // robot-robot or env-env
  const bool robot_is_a = u0 >= 0;
  const int body = robot_is_a ? u0 : u1;
  const double sign = robot_is_a ? 1.0 : -1.0;
  const int foot = foot_of_body[static_cast<std::size_t>(body)];
  for (int j = 0; j < man.getNumContacts(); ++j) {
    const btManifoldPoint& pt = man.getContactPoint(j);
    const double ln = pt.getAppliedImpulse();
    const bool touching = ln > 0.0 || pt.getDistance() < 0.0;
    if (!touching) continue;
    const Eigen::Vector3d f = sign *
                              (eig(pt.m_normalWorldOnB) * ln +
                               eig(pt.m_lateralFrictionDir1) * pt.m_appliedImpulseLateral1 +
                               eig(pt.m_lateralFrictionDir2) * pt.m_appliedImpulseLateral2) /
                              dt;
    g.total_contact_force_W += f;
    if (foot < 0) {
      if (!g.non_foot_contact[static_cast<std::size_t>(body)]) ++g.num_non_foot_contacts;
      g.non_foot_contact[static_cast<std::size_t>(body)] = 1;
      continue;
    }
    FootContactTruth& ft = g.feet[static_cast<std::size_t>(foot)];
    const Eigen::Vector3d p =
        eig(robot_is_a ? pt.getPositionWorldOnA() : pt.getPositionWorldOnB());
    ft.force_W += f;
    ft.torque_Fo_W += (p - ft.X_WF.translation()).cross(f);
    ft.cop_W += ln * p;
    weight[foot] += ln;
    ++ft.num_points;
    ft.in_contact = true;
  }
}

// The feet's CoPs and F/T readings (wrench at the foot frame origin, in the foot frame).
void Simulator::Impl::finish_foot_wrenches(SensorFrame& s, GroundTruth& g, const double* weight,
                                           bool measure_imu) {
  for (std::size_t f = 0; f < feet.size(); ++f) {
    FootContactTruth& ft = g.feet[f];
    if (weight[f] > 0.0)
      ft.cop_W /= weight[f];
    else
      ft.cop_W = ft.X_WF.translation();
    const Eigen::Matrix3d R_FW = ft.X_WF.linear().transpose();
    s.foot_wrench_Fo_F[f].head<3>() = R_FW * ft.torque_Fo_W;
    s.foot_wrench_Fo_F[f].tail<3>() = R_FW * ft.force_W;
    sensors.foot_ft(measure_imu, f, s.foot_wrench_Fo_F[f]);
  }
}

// ---------------------------------------------------------------------------------------------

Simulator::Simulator(const SimulatorConfig& config) {
  if (config.robot.feet.size() > 16) throw std::runtime_error("robot.feet: at most 16 feet");
  impl_ = std::make_unique<Impl>(config);
  for (const std::string& n : impl_->notes)
    std::fprintf(stderr, "simulator '%s': note: %s\n", config.robot.urdf_path.c_str(), n.c_str());
}
Simulator::~Simulator() = default;

const std::vector<std::string>& Simulator::joint_names() const {
  return impl_->joint_names;
}
int Simulator::num_joints() const {
  return impl_->n;
}
const std::vector<std::string>& Simulator::body_names() const {
  return impl_->body_names;
}
const std::vector<std::string>& Simulator::foot_names() const {
  return impl_->foot_names;
}
const RealityDraw& Simulator::reality() const {
  return impl_->reality;
}

double Simulator::total_mass() const {
  return impl_->mass;
}
double Simulator::dt() const {
  return impl_->dt;
}
std::int64_t Simulator::tick() const {
  return impl_->tick;
}
double Simulator::time() const {
  return static_cast<double>(impl_->tick) * impl_->dt;
}
const Eigen::VectorXd& Simulator::effort_limits() const {
  return impl_->effort;
}
const std::vector<std::string>& Simulator::notes() const {
  return impl_->notes;
}
double Simulator::damping_kd() const {
  return impl_->cfg.robot.damping_mode_kd;
}
int Simulator::solver_iterations_used() const {
  return impl_->solver->m_analyticsData.m_numIterationsUsed;
}
SolverRows Simulator::solver_rows() const {
  const auto& s = *impl_->solver;
  return SolverRows{s.normal_rows(), s.friction_rows(), s.other_rows()};
}

SensorFrame Simulator::make_sensor_frame() const {
  SensorFrame s;
  s.q = Eigen::VectorXd::Zero(impl_->n);
  s.qd = Eigen::VectorXd::Zero(impl_->n);
  s.tau_measured = Eigen::VectorXd::Zero(impl_->n);
  s.foot_wrench_Fo_F.assign(impl_->feet.size(), Eigen::Matrix<double, 6, 1>::Zero());
  return s;
}

GroundTruth Simulator::make_ground_truth() const {
  GroundTruth g;
  g.feet.assign(impl_->feet.size(), FootContactTruth{});
  g.non_foot_contact.assign(impl_->tree.bodies.size(), 0);
  g.platform_X_WP.assign(impl_->platforms.size(), Eigen::Isometry3d::Identity());
  return g;
}

JointCommand Simulator::make_command() const {
  JointCommand c;
  c.resize(impl_->n);
  return c;
}

void Simulator::read(SensorFrame& sensors, GroundTruth& truth) {
  impl_->fill(sensors, truth, false);
}

const StepTimes& Simulator::step_times() const {
  return impl_->step_times;
}

void Simulator::reset_step_times() {
  impl_->step_times = StepTimes{};
}

StepStatus Simulator::step(const JointCommand& cmd, SensorFrame& sensors, GroundTruth& truth) {
  Impl& s = *impl_;
  const std::int64_t t_begin = steady_ns();
  const int n = s.n;
  StepStatus status = StepStatus::kOk;
  const bool sized = cmd.tau_ff.size() == n && cmd.q_ref.size() == n && cmd.qd_ref.size() == n &&
                     cmd.kp.size() == n && cmd.kd.size() == n;
  bool ok = sized && static_cast<std::uint8_t>(cmd.mode) <= 2;
  if (ok) {
    switch (cmd.mode) {
      case CommandMode::kTorque:
        ok = cmd.tau_ff.allFinite();
        break;
      case CommandMode::kPd:
        ok = cmd.tau_ff.allFinite() && cmd.q_ref.allFinite() && cmd.qd_ref.allFinite() &&
             cmd.kp.allFinite() && cmd.kd.allFinite();
        break;
      case CommandMode::kDamping:
        ok = cmd.kd.allFinite();
        break;
    }
  }
  btMultiBody& mb = *s.mb;
  mb.clearForcesAndTorques();
  for (int i = 0; i < n; ++i) {
    const double q = mb.getJointPos(i), qd = mb.getJointVel(i);
    double t = 0.0;
    if (!ok) {
      t = -s.cfg.robot.damping_mode_kd * qd;
    } else if (cmd.mode == CommandMode::kTorque) {
      t = cmd.tau_ff[i];
    } else if (cmd.mode == CommandMode::kPd) {
      t = cmd.tau_ff[i] + cmd.kp[i] * (cmd.q_ref[i] - q) + cmd.kd[i] * (cmd.qd_ref[i] - qd);
    } else {
      t = -cmd.kd[i] * qd;
    }
    t = s.actuators.torque(i, std::clamp(t, -s.effort[i], s.effort[i]));
    s.tau[i] = t;
    const double fr = s.friction[i] * std::clamp(qd / s.friction_velocity[i], -1.0, 1.0);
    mb.addJointTorque(i, t - s.damping[i] * qd - fr);
  }
  s.actuators.advance();
  if (!ok) status = StepStatus::kRejectedCommand;

  // Pushes active during [k dt, (k+1) dt).
  const std::int64_t k = s.tick;
  s.push_force_W.setZero();
  for (std::size_t i = 0; i < s.pushes.size();) {
    const ResolvedPush& p = s.pushes[i];
    if (k >= p.end_tick) {  // expired: swap-remove, no allocation
      s.pushes[i] = s.pushes.back();
      s.pushes.pop_back();
      continue;
    }
    if (k >= p.start_tick) {
      const Eigen::Isometry3d& X = s.X_WK[static_cast<std::size_t>(p.body)];
      const Eigen::Vector3d r = X.linear() * p.point_K;  // from the body COM to the point
      const btVector3 f = bt(p.force_W), tq = bt(Eigen::Vector3d(r.cross(p.force_W)));
      s.push_force_W += p.force_W;
      if (p.body == 0) {
        mb.addBaseForce(f);
        mb.addBaseTorque(tq);
      } else {
        mb.addLinkForce(p.body - 1, f);
        mb.addLinkTorque(p.body - 1, tq);
      }
    }
    ++i;
  }

  s.update_platforms(static_cast<double>(k) * s.dt);
  s.update_limits();
  const std::int64_t t_bullet = steady_ns();
  s.world->stepSimulation(s.dt, 0, s.dt);
  const std::int64_t t_sensors = steady_ns();
  ++s.tick;
  s.update_kinematics();
  s.fill(sensors, truth, true);
  const std::int64_t t_end = steady_ns();
  StepTimes& st = s.step_times;
  ++st.steps;
  st.bullet_ns += t_sensors - t_bullet;
  st.sensors_ns += t_end - t_sensors;
  st.other_ns += (t_bullet - t_begin);
  return status;
}

bool Simulator::add_push(const Push& push) {
  Impl& s = *impl_;
  if (s.pushes.size() >= s.pushes.capacity()) return false;
  for (const auto& fr : s.tree.frames) {
    if (fr.name != push.link) continue;
    if (!push.point_L.allFinite() || !push.force_W.allFinite() || !std::isfinite(push.start) ||
        !std::isfinite(push.duration) || push.duration < 0.0)
      return false;
    ResolvedPush r;
    r.body = fr.body;
    r.point_K = s.X_LK[static_cast<std::size_t>(fr.body)].inverse() * (fr.X_LF * push.point_L);
    r.force_W = push.force_W;
    r.start_tick = std::max<std::int64_t>(std::llround(push.start / s.dt), s.tick);
    r.end_tick = r.start_tick + std::llround(push.duration / s.dt);
    s.pushes.push_back(r);
    return true;
  }
  return false;
}

void Simulator::set_state(const Eigen::Isometry3d& X_WB, const Eigen::VectorXd& q,
                          const Eigen::Vector3d& v_WB, const Eigen::Vector3d& omega_WB,
                          const Eigen::VectorXd& qd) {
  impl_->set_state(X_WB, q, v_WB, omega_WB, qd);
}

Eigen::Isometry3d Simulator::frame_pose(const std::string& urdf_link) const {
  const detail::FrameSpec* fr = impl_->tree.find_frame(urdf_link);
  if (!fr) throw std::out_of_range("frame_pose: unknown link '" + urdf_link + "'");
  const auto b = static_cast<std::size_t>(fr->body);
  return impl_->X_WK[b] * impl_->X_LK[b].inverse() * fr->X_LF;
}

ImuNoiseConfig industrial_mems_imu() {
  // Figures and unit conversions: simulator/sim/SENSORS.md.
  constexpr double kDeg = M_PI / 180.0;
  constexpr double kG = 9.80665;
  ImuNoiseConfig c;
  c.gyro_noise_density = 0.008 * kDeg;            // 0.008 deg/s/sqrt(Hz) (ADIS16470)
  c.gyro_bias_walk = 8.0 * kDeg / 3600.0 / 10.0;  // 8 deg/h in-run stability reached in 100 s
  c.gyro_bias = Eigen::Vector3d(0.1, -0.08, 0.05) * kDeg;           // turn-on residual [rad/s]
  c.gyro_scale_error = Eigen::Vector3d(0.001, -0.0008, 0.0005);     // 0.1 %
  c.gyro_misalignment = Eigen::Vector3d(0.05, -0.03, 0.04) * kDeg;  // 0.05 deg
  c.gyro_range = 2000.0 * kDeg;                                     // +-2000 deg/s
  c.accel_noise_density = std::sqrt(2.0) * 0.037 / 60.0;  // VRW 0.037 m/s/sqrt(h), one-sided
  c.accel_bias_walk = 13e-6 * kG / 10.0;                  // 13 ug in-run stability reached in 100 s
  c.accel_bias = Eigen::Vector3d(2.0, -1.5, 1.0) * 1e-3 * kG;  // 2 mg turn-on residual
  c.accel_scale_error = Eigen::Vector3d(-0.001, 0.0007, 0.0005);
  c.accel_misalignment = Eigen::Vector3d(-0.04, 0.05, -0.03) * kDeg;
  c.accel_range = 40.0 * kG;  // +-40 g
  c.rate_hz = 0.0;            // every simulator step (the part runs at 2 kHz)
  c.delay_ticks = 1;          // 1 ms: sensor filters and transfer
  c.orientation = ImuOrientationOutput::kFilter;
  c.filter_gain = 0.5;
  c.filter_accel_gate = 0.1;
  return c;
}

EncoderConfig industrial_encoder() {
  EncoderConfig e;
  e.counts_per_rev = 1048576.0;  // 14-bit motor encoder through a 64:1 reduction (2^20 / rev)
  e.velocity_filter_hz = 100.0;  // the drive's first-order velocity filter
  return e;
}

ForceTorqueSensorConfig industrial_foot_ft() {
  ForceTorqueSensorConfig f;
  f.force_noise_std = 0.5;    // [N]
  f.torque_noise_std = 0.02;  // [N m]
  f.force_offset = Eigen::Vector3d(1.0, -0.8, 1.5);
  f.torque_offset = Eigen::Vector3d(0.03, -0.02, 0.01);
  return f;
}

std::vector<int> joint_index_map(std::span<const std::string> from,
                                 std::span<const std::string> to) {
  std::unordered_map<std::string, int> idx;
  for (std::size_t i = 0; i < to.size(); ++i)
    if (!idx.emplace(to[i], static_cast<int>(i)).second)
      throw std::runtime_error("joint_index_map: duplicate joint name '" + to[i] + "'");
  std::vector<int> map(from.size(), -1);
  std::unordered_map<std::string, int> seen;
  for (std::size_t i = 0; i < from.size(); ++i) {
    if (!seen.emplace(from[i], 0).second)
      throw std::runtime_error("joint_index_map: duplicate joint name '" + from[i] + "'");
    auto it = idx.find(from[i]);
    if (it != idx.end()) map[i] = it->second;
  }
  return map;
}

void remap_joint_vector(const std::vector<int>& map, const Eigen::VectorXd& in,
                        Eigen::VectorXd& out) {
  const Eigen::Index m = std::min<Eigen::Index>(in.size(), static_cast<Eigen::Index>(map.size()));
  for (Eigen::Index i = 0; i < m; ++i) {
    const int j = map[static_cast<std::size_t>(i)];
    if (j >= 0 && j < out.size()) out[j] = in[i];
  }
}

Eigen::Vector2d trunk_pitch_roll(const Eigen::Matrix3d& R_WB, const Eigen::Vector3d& forward_B) {
  const Eigen::Vector3d f = R_WB * forward_B;
  const Eigen::Vector3d l = R_WB * Eigen::Vector3d::UnitZ().cross(forward_B);
  const double pitch = std::asin(std::clamp(-f.z(), -1.0, 1.0));
  if (R_WB(2, 2) >= 0.0) return {pitch, std::atan2(l.z(), R_WB(2, 2))};
  // The trunk's up points down: Euler angles would call a forward fall 180 deg of roll. Here
  // each axis's elevation, and the one that turned further goes on past 90 deg (continuous
  // with the above at the horizon).
  double roll = std::asin(std::clamp(l.z(), -1.0, 1.0));
  double pitch_past = pitch;
  double& past = std::abs(pitch) >= std::abs(roll) ? pitch_past : roll;
  past = std::copysign(M_PI - std::abs(past), past);
  return {pitch_past, roll};
}

}  // namespace poise::sim
