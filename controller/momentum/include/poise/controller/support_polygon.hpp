#pragma once
// The support polygon in the horizontal plane and the "ankle first" horizontal linear-momentum
// demand (MomentumGains::ankle_first_blend; not in the paper).
//
// Why: eq (11) with the paper's gains (Gamma21 = 40 /s on the CoM velocity) asks, after a push
// of a few tenths of a m/s, for a horizontal force whose centre of pressure under the linear
// inverted pendulum (LIP) lies metres outside the feet. The optimiser gives the linear rate first
// and the angular momentum takes the rest: the trunk rolls or pitches (the hip strategy) even
// when the CoP alone, at the edge of the support polygon, could stop the CoM. A push that the
// ankle could hold then ends with a leg at its joint limits (deploy/envelope/README.md).
//
// The rule, in the horizontal plane (world x, y), for the feedback part of (11):
//   p_pd = r_G - a_pd / omega^2        the LIP centre of pressure of (11)'s demand a_pd
//   xi   = r_G - e_v / omega           the divergent component of motion (capture point),
//                                      e_v = rdot_G,d - rdot_G
// If p_pd is inside the polygon nothing changes. Otherwise, with xi at depth s inside the
// polygon (signed distance, negative outside):
//   p = the point where the ray from xi towards p_pd leaves the polygon (beyond xi, so that the
//       LIP drives xi back: xi_dot = omega (xi - p)),
//   a_ankle = omega^2 (r_G - p)        (no angular momentum needed: the ankle strategy)
//   a = (1 - beta) a_ankle + beta a_pd,  beta = clamp(1 - s / blend, 0, 1)
// so the paper's demand (and with it the hip strategy) returns continuously as the capture point
// comes within `blend` of the polygon's edge, and in full once it is outside (the ankle alone
// can no longer stop the CoM).
//
// Allocation-free; at most kMaxVertices corners (two feet of four corners each).

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace poise::controller {

/// Convex polygon (counter-clockwise) of at most kMaxVertices points, built as the convex hull of
/// the given points. Fixed capacity: no allocation.
class SupportPolygon {
 public:
  static constexpr int kMaxVertices = 8;

  void clear() noexcept { n_points_ = 0, n_ = 0; }
  /// Adds a point (ignored beyond kMaxVertices). Call hull() after the last one.
  void add(const Eigen::Vector2d& p) noexcept {
    if (n_points_ < kMaxVertices) points_[static_cast<std::size_t>(n_points_++)] = p;
  }
  /// Convex hull of the points added (Andrew's monotone chain); collinear points dropped.
  void hull() noexcept;

  int size() const noexcept { return n_; }
  const Eigen::Vector2d& vertex(int i) const noexcept {
    return v_[static_cast<std::size_t>(i)];
  }
  /// Signed distance from p to the boundary: positive inside, negative outside. A polygon of
  /// fewer than 3 vertices (a segment or a point) has no inside: the distance is minus the
  /// distance to it. Empty: -infinity.
  double signed_distance(const Eigen::Vector2d& p) const noexcept;
  bool contains(const Eigen::Vector2d& p) const noexcept { return signed_distance(p) >= 0.0; }
  /// For `from` inside: the point where the ray from `from` through `towards` leaves the polygon
  /// (towards itself when it is inside). `from` outside or a degenerate polygon: `from`.
  Eigen::Vector2d ray_exit(const Eigen::Vector2d& from, const Eigen::Vector2d& towards) const
      noexcept;

 private:
  std::array<Eigen::Vector2d, kMaxVertices> points_{};
  std::array<Eigen::Vector2d, 2 * kMaxVertices> v_{};  // Andrew's chain needs up to 2 n
  int n_points_ = 0;
  int n_ = 0;
};

/// Result of ankle_first_rate().
struct AnkleFirstRate {
  Eigen::Vector2d acceleration = Eigen::Vector2d::Zero();  ///< horizontal CoM demand [m/s^2]
  /// 0: the ankle strategy alone (the demand's LIP CoP at the polygon's edge); 1: the paper's
  /// demand unchanged (its CoP inside the polygon, or the capture point outside it).
  double beta = 1.0;
};

/// The rule of this file's header. a_pd: the horizontal feedback demand of (11) [m/s^2];
/// com: r_G, horizontal [m]; velocity_error: rdot_G,d - rdot_G, horizontal [m/s]; omega: the
/// LIP's sqrt(g / h) [1/s]; polygon: the support polygon (the supports' safe regions) in the same
/// horizontal coordinates; blend: width [m] over which the paper's demand returns (> 0).
inline AnkleFirstRate ankle_first_rate(const Eigen::Vector2d& a_pd, const Eigen::Vector2d& com,
                                       const Eigen::Vector2d& velocity_error, double omega,
                                       const SupportPolygon& polygon, double blend) noexcept {
  AnkleFirstRate out;
  out.acceleration = a_pd;
  if (!(omega > 0.0) || !(blend > 0.0) || polygon.size() < 3) return out;
  const double w2 = omega * omega;
  const Eigen::Vector2d p_pd = com - a_pd / w2;
  if (polygon.contains(p_pd)) return out;
  const Eigen::Vector2d xi = com - velocity_error / omega;
  const double s = polygon.signed_distance(xi);
  const double beta = std::clamp(1.0 - s / blend, 0.0, 1.0);
  out.beta = beta;
  if (beta >= 1.0) return out;
  const Eigen::Vector2d p = polygon.ray_exit(xi, p_pd);
  out.acceleration = (1.0 - beta) * (w2 * (com - p)) + beta * a_pd;
  return out;
}

// ---- SupportPolygon ------------------------------------------------------------------------------

inline void SupportPolygon::hull() noexcept {
  auto& p = points_;
  const auto first = p.begin(), last = p.begin() + n_points_;
  std::sort(first, last, [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  n_ = 0;
  if (n_points_ == 0) return;
  if (n_points_ == 1) {
    v_[0] = p[0];
    n_ = 1;
    return;
  }
  // Lower hull, then upper hull (v_ has room for the 2 n points the chain may hold).
  int k = 0;
  for (int i = 0; i < n_points_; ++i) {
    while (k >= 2 && cross(v_[static_cast<std::size_t>(k - 2)], v_[static_cast<std::size_t>(k - 1)],
                           p[static_cast<std::size_t>(i)]) <= 0.0)
      --k;
    v_[static_cast<std::size_t>(k++)] = p[static_cast<std::size_t>(i)];
  }
  for (int i = n_points_ - 2, lower = k + 1; i >= 0; --i) {
    while (k >= lower && cross(v_[static_cast<std::size_t>(k - 2)],
                               v_[static_cast<std::size_t>(k - 1)],
                               p[static_cast<std::size_t>(i)]) <= 0.0)
      --k;
    v_[static_cast<std::size_t>(k++)] = p[static_cast<std::size_t>(i)];
  }
  n_ = std::max(1, k - 1);  // the last point repeats the first
}

inline double SupportPolygon::signed_distance(const Eigen::Vector2d& p) const noexcept {
  if (n_ == 0) return -std::numeric_limits<double>::infinity();
  // Distance to the boundary (segments), and inside = left of every edge (counter-clockwise).
  double dist = std::numeric_limits<double>::infinity();
  bool inside = n_ >= 3;
  for (int i = 0; i < n_; ++i) {
    const Eigen::Vector2d& a = v_[static_cast<std::size_t>(i)];
    const Eigen::Vector2d& b = v_[static_cast<std::size_t>((i + 1) % n_)];
    const Eigen::Vector2d ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    dist = std::min(dist, (a + t * ab - p).norm());
    if (ab.x() * (p.y() - a.y()) - ab.y() * (p.x() - a.x()) < 0.0) inside = false;
  }
  return inside ? dist : -dist;
}

inline Eigen::Vector2d SupportPolygon::ray_exit(const Eigen::Vector2d& from,
                                                const Eigen::Vector2d& towards) const noexcept {
  if (n_ < 3 || !contains(from)) return from;
  if (contains(towards)) return towards;
  const Eigen::Vector2d d = towards - from;
  // Largest t in [0, 1] with from + t d inside: the smallest exit parameter over the edges'
  // half-planes (inside = left of each counter-clockwise edge).
  double t_max = 1.0;
  for (int i = 0; i < n_; ++i) {
    const Eigen::Vector2d& a = v_[static_cast<std::size_t>(i)];
    const Eigen::Vector2d& b = v_[static_cast<std::size_t>((i + 1) % n_)];
    const Eigen::Vector2d ab = b - a;
    // g(t) = cross(ab, from + t d - a) >= 0 inside; g(0) >= 0.
    const double g0 = ab.x() * (from.y() - a.y()) - ab.y() * (from.x() - a.x());
    const double gd = ab.x() * d.y() - ab.y() * d.x();
    if (gd < 0.0) t_max = std::min(t_max, std::max(0.0, g0 / -gd));
  }
  return from + t_max * d;
}

}  // namespace poise::controller
