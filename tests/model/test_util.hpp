#pragma once
// Shared helpers of the model tests: robot paths and seeded random states.
#include <Eigen/Core>
#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "poise/model/model.hpp"

namespace poise::model::test {

inline std::string humanoid_urdf() {
  return std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/poise_humanoid.urdf";
}
inline std::string humanoid_config() {
  return std::string(POISE_SOURCE_DIR) + "/deploy/robots/poise_humanoid/robot.yaml";
}
inline std::string test_urdf(const std::string& name) {
  return std::string(POISE_SOURCE_DIR) + "/tests/model/urdf/" + name;
}
/// The three robots every algorithm is checked on.
inline std::vector<std::string> all_urdfs() {
  return {humanoid_urdf(), test_urdf("fixed_chains_massless.urdf"),
          test_urdf("prismatic_continuous.urdf")};
}

struct State {
  Eigen::VectorXd q, v, a;
};

/// Random state: base anywhere near the origin with a random orientation, joints uniform within
/// their limits (+-2 for unbounded joints), velocities and accelerations N(0, 1).
inline State random_state(const Model& model, std::mt19937& rng) {
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  State s;
  s.q = model.neutral();
  for (int i = 0; i < 3; ++i)
    s.q[i] = 0.5 * n01(rng);
  Eigen::Vector4d quat;
  for (int i = 0; i < 4; ++i)
    quat[i] = n01(rng);
  s.q.segment<4>(3) = quat.normalized();
  for (int j = 0; j < model.njoints; ++j) {
    const double lo = std::max(model.limits[j].lower, -2.0);
    const double hi = std::min(model.limits[j].upper, 2.0);
    s.q[model.idx_q(j)] = lo + (hi - lo) * u01(rng);
  }
  s.v.resize(model.nv);
  s.a.resize(model.nv);
  for (int i = 0; i < model.nv; ++i) {
    s.v[i] = n01(rng);
    s.a[i] = n01(rng);
  }
  return s;
}

}  // namespace poise::model::test
