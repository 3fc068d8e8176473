#include "poise/reference/player.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "poise/node/convert.hpp"
#include "poise/reference/sampler.hpp"

namespace poise::reference {

Player::Player(Trajectory trajectory, const model::Model& model, const model::RobotConfig& robot,
               const std::vector<int>& model_to_wire, double period_s, int lead_ticks)
    : traj_(std::move(trajectory)),
      period_(period_s),
      period_ns_(std::llround(period_s * 1e9)),
      lead_(lead_ticks) {
  if (lead_ < 1) throw std::runtime_error("reference player: lead ticks must be >= 1");
  if (!(period_ > 0.0)) throw std::runtime_error("reference player: the period must be > 0");
  if (model_to_wire.size() != static_cast<std::size_t>(model.njoints) ||
      model_to_wire.size() > msg::MAX_JOINTS)
    throw std::runtime_error("reference player: the joint map does not fit the robot");
  for (int j : swing_joint_indices(traj_, model, robot))
    swing_wire_.push_back(model_to_wire[static_cast<std::size_t>(j)]);
  ref_.joint_count(static_cast<std::uint32_t>(model_to_wire.size()));
  for (std::size_t j = 0; j < model_to_wire.size(); ++j)
    ref_.upper_body_q()[static_cast<std::size_t>(model_to_wire[j])] =
        robot.q_nominal[7 + static_cast<Eigen::Index>(j)];
  nominal_q_ = ref_.upper_body_q();
  sole_F_ = stand_points_F(robot);
}

void Player::begin(const msg::State& in) noexcept {
  const std::uint64_t k = in.header().tick();
  // A state stream that restarts (a tick below one seen before: the robot side restarted) keeps
  // the player's timeline: the ticks it already produced are not produced again, so nothing is
  // sent until the stream is past them. Counted (restarts()); poise-reference reports it.
  if (started_ && k < last_state_tick_) ++restarts_;
  k_ = k;
  k_stamp_ns_ = in.header().stamp_ns();
  if (started_) return;
  started_ = true;
  t_first_ = static_cast<double>(k_stamp_ns_) * 1e-9;
  const double ticks_left = std::max(0.0, std::ceil((traj_.end() - t_first_) / period_));
  end_tick_ = k_ + static_cast<std::uint64_t>(ticks_left);
  next_ = k_ + 1;
  // Not counted as skipped: the player cannot tell a first state it saw late from the first
  // state of the loop (poise-sim's first frame is tick 10, after its start-up hold, in both
  // modes); started_late() reports it.
  started_late_ = t_first_ + period_ > traj_.begin();
}

std::uint64_t Player::trajectory_ticks(std::uint64_t from, std::uint64_t to) const noexcept {
  // The first tick fill() produces (t >= begin - dt / 2), from the stamp of the state handled.
  const double t_k = static_cast<double>(k_stamp_ns_) * 1e-9;
  const double first = std::ceil((traj_.begin() - 0.5 * period_ - t_k) / period_ - 1e-9);
  const long long begin_tick = static_cast<long long>(k_) + static_cast<long long>(first);
  const std::uint64_t lo =
      std::max<std::uint64_t>(from, static_cast<std::uint64_t>(std::max(0LL, begin_tick)));
  const std::uint64_t hi = std::min<std::uint64_t>(to, end_tick_);
  return hi >= lo ? hi - lo + 1 : 0;
}

void Player::count_skipped(std::uint64_t k) noexcept {
  if (next_ >= k + 1) return;  // nothing left behind (or a restarted stream: next_ is ahead)
  // Ticks next_ .. k - 1: due before this state. Tick k itself is this state's own tick, which
  // no player produces (references go to the ticks after the state), as at the first state.
  if (k > next_) skipped_ += trajectory_ticks(next_, k - 1);
  next_ = k + 1;  // those ticks are gone: counted once
}

bool Player::fill(std::uint64_t j, const msg::State& in) noexcept {
  // Integer nanoseconds from the state's stamp: the time of tick j comes out the same whichever
  // state it is computed from.
  const long long stamp_ns = k_stamp_ns_ + static_cast<long long>(j - k_) * period_ns_;
  const double t = static_cast<double>(stamp_ns) * 1e-9;
  if (t < traj_.begin() - 0.5 * period_) return false;
  ref_.header().tick(j);
  ref_.header().stamp_ns(stamp_ns);
  if (!traj_.com.empty() && t >= traj_.com.front().start) {
    if (!origin_set_) {
      origin_ = Eigen::Vector3d(in.com_W()[0], in.com_W()[1], in.com_W()[2]);
      origin_set_ = true;
    }
    model::SE3 X_WF[2];
    for (std::size_t side = 0; side < 2; ++side) {
      const msg::Pose& p = in.feet()[side].pose_W();
      X_WF[side] = model::SE3(node::rotation(p), node::vec3(p.position()));
    }
    resolve_com_moves(traj_, t, origin_, X_WF[0].act(sole_F_[0]), X_WF[1].act(sole_F_[1]));
  }
  Eigen::Vector3d offset, velocity;
  const bool com = com_offset(traj_, t, offset, velocity);
  ref_.has_com_target(com);
  for (int i = 0; i < 3; ++i) {
    ref_.com_W()[i] = com ? origin_[i] + offset[i] : 0.0;
    ref_.com_velocity_W()[i] = com ? velocity[i] : 0.0;
  }
  ref_.has_upper_body_q(has_joint_motion(traj_, t));
  ref_.upper_body_q() = nominal_q_;
  ref_.upper_body_qdd().fill(0.0);
  for (std::size_t s = 0; s < traj_.joints.size(); ++s) {
    double q, qd, qdd;
    swing_offset(traj_.joints[s], t, q, qd, qdd);
    ref_.upper_body_q()[static_cast<std::size_t>(swing_wire_[s])] += q;
    ref_.upper_body_qdd()[static_cast<std::size_t>(swing_wire_[s])] += qdd;
  }
  if (!traj_.feet.empty()) {
    const FootStep* step = active_step(traj_, t);
    const int index = step != nullptr ? static_cast<int>(step - traj_.feet.data()) : -1;
    if (step != nullptr && index != step_index_) {
      step_index_ = index;
      const msg::Pose& p = in.feet()[static_cast<std::size_t>(step->side)].pose_W();
      X_stood_ = model::SE3(node::rotation(p), node::vec3(p.position()));
    }
    model::SE3 X_target;
    model::Motion V_target;
    for (int side = 0; side < 2; ++side) {
      msg::FootReference& f = ref_.feet()[static_cast<std::size_t>(side)];
      const bool swing = step != nullptr && step->side == side;
      f.mode(swing ? msg::FOOT_SWING : msg::FOOT_SUPPORT);
      f.has_target(swing);
      if (!swing) continue;
      step_target(*step, t, X_stood_, X_target, V_target);
      node::put_pose(X_target.R, X_target.p, f.target_W());
      node::put3(V_target.head<3>(), f.target_velocity_W().linear());
      node::put3(V_target.tail<3>(), f.target_velocity_W().angular());
    }
  }
  return true;
}

}  // namespace poise::reference
