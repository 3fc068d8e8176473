// Every algorithm runs without heap allocation. Built against a copy of the library compiled
// with EIGEN_RUNTIME_NO_MALLOC (Eigen asserts on any allocation while forbidden), and the global
// operator new is counted as well (catches std:: containers too).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "poise/model/centroidal.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "test_util.hpp"

static std::atomic<long> g_news{0};
void* operator new(std::size_t n) {
  ++g_news;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace poise::model {
namespace {

#ifdef NDEBUG
#error "this test needs eigen_assert active (no NDEBUG)"
#endif

TEST(NoMallocDeathTest, GuardIsActiveInThisBuild) {
  // Proves the check below can fail: a dynamic Eigen allocation while forbidden aborts.
  EXPECT_DEATH(
      {
        Eigen::internal::set_is_malloc_allowed(false);
        Eigen::VectorXd x(100);
        x.setZero();
      },
      "");
}

TEST(NoMalloc, OneTickOfEveryAlgorithm) {
  for (const std::string& path : test::all_urdfs()) {
    const Model model = build_model_from_urdf_file(path);
    Data data(model);
    std::mt19937 rng(5);
    const auto s = test::random_state(model, rng);
    Matrix6X J(6, model.nv);
    Eigen::VectorXd q_next(model.nq);
    const int f = static_cast<int>(model.frames.size()) - 1;

    Eigen::internal::set_is_malloc_allowed(false);
    const long before = g_news.load();
    forward_kinematics(model, data, s.q);
    forward_kinematics(model, data, s.q, s.v);
    forward_kinematics(model, data, s.q, s.v, s.a);
    update_frame_placements(model, data);
    volatile double sink = frame_velocity(model, data, f)[0];
    sink = frame_classical_acceleration(model, data, f)[0] + frame_jdot_v(model, data, f)[0];
    sink = frame_point_jdot_v(model, data, f, Vector3(0.1, 0, 0))[1];
    compute_joint_jacobians(model, data, s.q);
    frame_jacobian(model, data, f, J);
    frame_point_jacobian(model, data, f, Vector3(0.1, 0.0, 0.0), J);
    center_of_mass(model, data, s.q);
    centroidal_momentum(model, data, s.q, s.v);
    com_jacobian(model, data, s.q);
    centroidal_momentum_matrix(model, data, s.q, s.v);
    clear_external_forces(data);
    add_external_wrench(model, data, f, Vector3(0, 0, 0), Vector3(1, 2, 3), Vector3(0, 0, 1));
    rnea(model, data, s.q, s.v, s.a);
    crba(model, data, s.q);
    integrate(model, s.q, s.v, 1e-3, q_next);
    sink = se3_log(se3_exp(Motion::Constant(0.1)))[0];
    const long after = g_news.load();
    Eigen::internal::set_is_malloc_allowed(true);
    (void)sink;
    EXPECT_EQ(after - before, 0) << path;
  }
}

}  // namespace
}  // namespace poise::model
