// Proves that solve() of every contact solver and optimiser never allocates: the library sources
// are compiled into this test with EIGEN_RUNTIME_NO_MALLOC and assertions on (Eigen asserts on any
// heap allocation of its own, which goes through malloc, while allocation is forbidden), and a
// replaced global operator new counts every other allocation.
#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "this test must be compiled with EIGEN_RUNTIME_NO_MALLOC"
#endif
#ifdef NDEBUG
#error \
    "this test needs assertions: Eigen's no-malloc check is an eigen_assert (compile with -UNDEBUG)"
#endif

#include <atomic>
#include <cstdlib>
#include <new>
#include <random>

#include <gtest/gtest.h>

#include "contact_fixtures.hpp"
#include "poise/contact/contact_optimizer.hpp"

namespace {
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace poise::contact {
namespace {

class NoMalloc {
 public:
  NoMalloc() : before_(g_allocations.load()) { Eigen::internal::set_is_malloc_allowed(false); }
  ~NoMalloc() { Eigen::internal::set_is_malloc_allowed(true); }
  long count() const { return g_allocations.load() - before_; }

 private:
  long before_;
};

TEST(NoMalloc, OptimisersAndSolversDoNotAllocateInSolve) {
  std::mt19937 rng(21);
  SequentialOptimizer seq;
  QpOptimizer qp;
  QpOptimizer qp2;  // the refinement pass (torsion rows linearised, coupled limit below)
  qp2.set_torsion_passes(2);
  ContactOptimizer facade(Method::kQp);
  SequentialOptimizer seq_dense;  // the dense-stage variant and, with tiny eps, the fallback path
  seq_dense.set_use_normal_equations(false);
  std::vector<ContactProblem> problems;
  for (int i = 0; i < 60; ++i) {
    const bool right = i % 3 != 1, left = i % 3 != 2;
    problems.push_back(i % 2 ? test::random_feasible(rng, right, left)
                             : test::random_arbitrary(rng, right, left));
  }
  problems[5].com.x() = std::numeric_limits<double>::quiet_NaN();           // invalid input path
  problems[6].feet[0].in_contact = problems[6].feet[1].in_contact = false;  // no contact
  for (int i = 0; i < 60; i += 2)  // half of them with the friction-coupled torsion limit
    problems[i].weights.torsion = TorsionLimit::kFrictionCoupled;
  for (int i = 9; i < 60; i += 10) {  // ill-conditioned stages: normal equations fall back to dense
    problems[i].weights.eps_f = problems[i].weights.eps_cop = 1e-12;
  }
  ContactSolution s;
  {
    NoMalloc guard;
    for (const ContactProblem& p : problems) {
      seq.solve(p, s);
      seq_dense.solve(p, s);
      qp.solve(p, s);
      qp2.solve(p, s);
      facade.solve(p, s);
      (void)validate(p);
    }
    EXPECT_EQ(guard.count(), 0);
  }
  // Generic solvers on their own, with dynamic-size inputs prepared outside the guard.
  Nnls nnls(10, 8);
  Bvls bvls(10, 8);
  DualQp dual(8, 2, 10);
  const Eigen::MatrixXd A = test::random_matrix(rng, 10, 8);
  const Eigen::VectorXd b = test::random_matrix(rng, 10, 1);
  const Eigen::VectorXd lo = -Eigen::VectorXd::Ones(8), hi = Eigen::VectorXd::Ones(8);
  const Eigen::MatrixXd G = A.transpose() * A + Eigen::MatrixXd::Identity(8, 8);
  const Eigen::VectorXd g = A.transpose() * b;
  const Eigen::MatrixXd Ae = test::random_matrix(rng, 2, 8), Ai = test::random_matrix(rng, 10, 8);
  const Eigen::VectorXd be = test::random_matrix(rng, 2, 1), bi = test::random_matrix(rng, 10, 1);
  Eigen::VectorXd x(8);
  const Eigen::MatrixXd AtA = A.transpose() * A;
  SolverStatus status[5];
  long count = 0;
  {
    NoMalloc guard;
    status[0] = nnls.solve(A, b, x);
    status[1] = bvls.solve(A, b, lo, hi, x);
    status[2] = dual.solve(G, g, Ae, be, Ai, bi, x);
    status[3] = nnls.solve_normal(AtA, g, b.norm(), x);
    status[4] = bvls.solve_normal(AtA, g, b.norm(), lo, hi, x);
    count = guard.count();
  }
  EXPECT_EQ(count, 0);
  for (SolverStatus st : status)
    EXPECT_NE(st, SolverStatus::kInvalidInput);
}

}  // namespace
}  // namespace poise::contact
