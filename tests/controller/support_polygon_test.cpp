// The support polygon and the "ankle first" horizontal demand (support_polygon.hpp), checked
// against brute-force geometry on seeded random inputs, and the rule inside the controller.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "controller_test_util.hpp"
#include "poise/controller/support_polygon.hpp"

namespace poise::controller {
namespace {

using Eigen::Vector2d;

double cross(const Vector2d& o, const Vector2d& a, const Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}
double segment_distance(const Vector2d& q, const Vector2d& a, const Vector2d& b) {
  const Vector2d ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0 ? std::clamp((q - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (a + t * ab - q).norm();
}
// Carathéodory in the plane: q is in the convex hull of the points iff it is in one of their
// triangles.
bool in_hull_brute(const std::vector<Vector2d>& p, const Vector2d& q) {
  const std::size_t n = p.size();
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      for (std::size_t k = j + 1; k < n; ++k) {
        const double c1 = cross(p[i], p[j], q), c2 = cross(p[j], p[k], q),
                     c3 = cross(p[k], p[i], q);
        if ((c1 >= 0 && c2 >= 0 && c3 >= 0) || (c1 <= 0 && c2 <= 0 && c3 <= 0)) return true;
      }
  return false;
}
// Distance from q to the hull's boundary: the boundary edges are the pairs with every other point
// on one side; outside, the closest point of the hull is on one of them as well.
double boundary_distance_brute(const std::vector<Vector2d>& p, const Vector2d& q) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = 0; j < p.size(); ++j) {
      if (i == j) continue;
      bool edge = true;
      for (std::size_t k = 0; k < p.size() && edge; ++k)
        if (cross(p[i], p[j], p[k]) < -1e-12) edge = false;
      if (edge) best = std::min(best, segment_distance(q, p[i], p[j]));
    }
  return best;
}

SupportPolygon make(const std::vector<Vector2d>& p) {
  SupportPolygon poly;
  for (const auto& v : p) poly.add(v);
  poly.hull();
  return poly;
}

TEST(SupportPolygon, HullContainmentAndDistanceMatchBruteForce) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (int trial = 0; trial < 300; ++trial) {
    const int n = 3 + trial % 6;  // 3..8 points
    std::vector<Vector2d> p;
    for (int i = 0; i < n; ++i) p.emplace_back(u(rng), u(rng));
    const SupportPolygon poly = make(p);
    ASSERT_GE(poly.size(), 3) << trial;
    // Counter-clockwise and convex; every vertex is an input point.
    for (int i = 0; i < poly.size(); ++i) {
      EXPECT_GT(cross(poly.vertex(i), poly.vertex((i + 1) % poly.size()),
                      poly.vertex((i + 2) % poly.size())),
                0.0)
          << trial;
      bool input = false;
      for (const auto& v : p) input = input || v == poly.vertex(i);
      EXPECT_TRUE(input) << trial;
    }
    for (int k = 0; k < 20; ++k) {
      const Vector2d q(1.5 * u(rng), 1.5 * u(rng));
      const double sd = poly.signed_distance(q);
      const double d = boundary_distance_brute(p, q);
      if (std::abs(sd) > 1e-9) {
        EXPECT_EQ(sd > 0, in_hull_brute(p, q)) << trial << " " << k;
      }
      EXPECT_NEAR(std::abs(sd), d, 1e-12) << trial << " " << k;
    }
  }
}

TEST(SupportPolygon, RayExitIsOnTheBoundaryBetweenTheEnds) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  int checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<Vector2d> p;
    for (int i = 0; i < 8; ++i) p.emplace_back(u(rng), u(rng));
    const SupportPolygon poly = make(p);
    const Vector2d from(0.3 * u(rng), 0.3 * u(rng)), to(3 * u(rng), 3 * u(rng));
    const Vector2d r = poly.ray_exit(from, to);
    if (!poly.contains(from)) {
      EXPECT_EQ(r, from);
      continue;
    }
    if (poly.contains(to)) {
      EXPECT_EQ(r, to);
      continue;
    }
    ++checked;
    EXPECT_NEAR(poly.signed_distance(r), 0.0, 1e-12) << trial;
    // On the segment, and the segment is outside right after it.
    const Vector2d d = to - from;
    const double t = (r - from).dot(d) / d.squaredNorm();
    EXPECT_GE(t, 0.0);
    EXPECT_LE(t, 1.0);
    EXPECT_NEAR(segment_distance(r, from, to), 0.0, 1e-12);
    EXPECT_LT(poly.signed_distance(r + 1e-6 * d.normalized()), 0.0) << trial;
  }
  EXPECT_GT(checked, 50);
}

TEST(SupportPolygon, AnkleFirstRateIsTheEdgeCoPBeyondTheCapturePoint) {
  // Two feet, 0.22 x 0.09 m safe regions, 0.18 m apart.
  const SupportPolygon poly = make({{-0.07, -0.135}, {0.13, -0.135}, {-0.07, -0.045},
                                    {0.13, -0.045}, {-0.07, 0.045}, {0.13, 0.045},
                                    {-0.07, 0.135}, {0.13, 0.135}});
  const double omega = std::sqrt(9.81 / 0.84), blend = 0.02;
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int ankle = 0, blended = 0, paper_inside = 0, paper_outside = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Vector2d com(0.05 * u(rng), 0.08 * u(rng));
    const Vector2d ev(0.5 * u(rng), 0.5 * u(rng));   // target - measured velocity
    const Vector2d a_pd = 40.0 * ev + 8.0 * Vector2d(0.05 * u(rng), 0.05 * u(rng));
    const AnkleFirstRate r = ankle_first_rate(a_pd, com, ev, omega, poly, blend);
    const Vector2d p_pd = com - a_pd / (omega * omega);
    const Vector2d xi = com - ev / omega;
    const double s = poly.signed_distance(xi);
    if (poly.contains(p_pd) || s <= 0.0) {
      // Nothing to do, or the ankle alone cannot stop the CoM: the paper's demand.
      EXPECT_EQ(r.beta, 1.0);
      EXPECT_EQ(r.acceleration, a_pd);
      (poly.contains(p_pd) ? paper_inside : paper_outside)++;
      continue;
    }
    // The LIP identity: the ankle demand's CoP is on the edge, on the ray from xi to p_pd.
    const Vector2d p_edge = poly.ray_exit(xi, p_pd);
    EXPECT_NEAR(poly.signed_distance(p_edge), 0.0, 1e-12);
    EXPECT_NEAR(segment_distance(p_edge, xi, p_pd), 0.0, 1e-12);
    const double beta = std::clamp(1.0 - s / blend, 0.0, 1.0);
    EXPECT_NEAR(r.beta, beta, 1e-15);
    const Vector2d a_ankle = omega * omega * (com - p_edge);
    EXPECT_LT((r.acceleration - ((1 - beta) * a_ankle + beta * a_pd)).norm(),
              1e-12 * (1 + a_pd.norm()));
    if (beta == 0.0) {
      ++ankle;
      const Vector2d p = com - r.acceleration / (omega * omega);
      EXPECT_NEAR(poly.signed_distance(p), 0.0, 1e-12);
      // xi_dot = omega (xi - p) points back from the edge: p is beyond xi towards p_pd.
      EXPECT_GT((p - xi).dot(p_pd - xi), 0.0);
      // Less horizontal force than the paper asks for (the point of the rule).
      EXPECT_LT(r.acceleration.norm(), a_pd.norm());
    } else {
      ++blended;
    }
  }
  EXPECT_GT(ankle, 100);
  EXPECT_GT(blended, 10);
  EXPECT_GT(paper_inside, 5);
  EXPECT_GT(paper_outside, 100);
  // Off, or no polygon: unchanged.
  const Vector2d a(3.0, -2.0);
  EXPECT_EQ(ankle_first_rate(a, Vector2d::Zero(), Vector2d(0.1, 0), omega, poly, 0.0).acceleration,
            a);
  EXPECT_EQ(ankle_first_rate(a, Vector2d::Zero(), Vector2d(0.1, 0), omega, SupportPolygon{}, 0.02)
                .acceleration,
            a);
}

// In the controller: a standing robot asked to move right (the same CoM velocity error as a
// leftward push) gets the ankle's demand with the option, the paper's without it or once the
// capture point is outside the feet.
TEST(SupportPolygon, TheControllerCutsOnlyTheHorizontalDemand) {
  double mass = 0.0;
  auto demand = [&mass](double blend, double vy, TickDiagnostics* diag) {
    ControllerConfig cfg;
    cfg.momentum.ankle_first_blend = blend;
    BalanceController c(test::humanoid().model, test::humanoid().robot, cfg);
    const RobotState s = test::standing_state(c);
    BalanceReference ref = c.make_reference();
    contact::ContactProblem p;
    c.prepare(s, ref, p);  // for the CoM
    ref.has_com_target = true;
    ref.com_W = c.diagnostics().com_W;
    ref.com_velocity_W = Eigen::Vector3d(0.0, -vy, 0.0);
    c.prepare(s, ref, p);
    if (diag) *diag = c.diagnostics();
    mass = p.mass;
    model::Vector6 h;
    h << p.k_dot_desired, p.l_dot_desired;
    return h;
  };
  TickDiagnostics d;
  const model::Vector6 paper = demand(0.0, 0.3, &d);
  EXPECT_EQ(d.ankle_first_beta, 1.0);
  const model::Vector6 ankle = demand(0.02, 0.3, &d);
  EXPECT_EQ(d.ankle_first_beta, 0.0);
  // Angular and vertical rows untouched; the horizontal force smaller.
  EXPECT_EQ(ankle.head<3>(), paper.head<3>());
  EXPECT_EQ(ankle[5], paper[5]);
  EXPECT_LT(ankle.segment<2>(3).norm(), 0.5 * paper.segment<2>(3).norm());
  // Its pendulum CoP is on the outer safe edge of the left foot (y = sole y_max - margin).
  const auto& robot = test::humanoid().robot;
  model::Data data(test::humanoid().model);
  model::forward_kinematics(test::humanoid().model, data, robot.q_nominal);
  const model::SE3 X_L = model::frame_placement(test::humanoid().model, data,
                                                robot.feet[1].frame_id);
  const double y_edge = X_L.p.y() + robot.feet[1].sole.y_max - robot.safety_margin;
  const double sole_height = X_L.p.z() - robot.feet[1].sole.height;
  // omega^2 = g / h, h the CoM target's height above the soles (com_target = sole mean + h).
  const double omega2 = test::humanoid().model.gravity.norm() / (d.com_target_W.z() - sole_height);
  const double cop_y = d.com_W.y() - ankle[4] / (mass * omega2);
  EXPECT_NEAR(cop_y, y_edge, 1e-9);
  // Faster than the feet can stop alone: the capture point is outside, the paper's demand.
  const model::Vector6 fast_paper = demand(0.0, 1.0, nullptr);
  const model::Vector6 fast = demand(0.02, 1.0, &d);
  EXPECT_EQ(d.ankle_first_beta, 1.0);
  EXPECT_EQ(fast, fast_paper);
}

}  // namespace
}  // namespace poise::controller
