#pragma once
// The balance-reference player without its transport: on the state of tick k it produces the
// poise/balance_reference messages of ticks k+1 .. k+lead (each stamped with its tick and time),
// from a trajectory (trajectory.hpp). `poise reference play` publishes them on DDS; the in-process
// loop hands them to the controller's and the estimator's queues directly. One player, so that a
// scenario with a `reference:` gives the same trajectory in process and distributed.
//
//   Player p(load_trajectory(file), model, robot, model_to_wire, period_s, lead_ticks);
//   on every state:  p.on_state(state, [&](const msg::BalanceReference& r) { return send(r); });
//
// Rules (deploy/scenarios/references/README.md): CoM moves relative to the CoM of the state on
// which the first move is produced (lead ticks before it is due); joint swings about the robot's
// nominal posture (upper-body joints only); a step swings its foot (FOOT_SWING, eq. 36 target of
// the pose the foot stood at when the step's first reference is produced, raised by the lift
// profile) and makes the other FOOT_SUPPORT (with feet: every foot not stepping is FOOT_SUPPORT
// from the first reference on). Nothing is produced for times before the trajectory begins, nor
// after its last tick. on_state() neither allocates nor throws.
#include <array>
#include <cstdint>
#include <vector>

#include <poise/msg/balance_reference.h>
#include <poise/msg/state.h>

#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/model/spatial.hpp"
#include "poise/reference/trajectory.hpp"

namespace poise::reference {

class Player {
 public:
  /// `model_to_wire[j]`: the wire (message) index of model joint j. Throws std::runtime_error
  /// naming the joint when a swing's joint is not in the model or not an upper-body joint, or
  /// when lead_ticks < 1. Allocates: configuration time.
  Player(Trajectory trajectory, const model::Model& model, const model::RobotConfig& robot,
         const std::vector<int>& model_to_wire, double period_s, int lead_ticks);

  /// On the state of tick k: calls `emit(const msg::BalanceReference&)` for every reference not
  /// yet produced of ticks k+1 .. k+lead (and not past the trajectory's end), in tick order.
  /// `emit` returns whether the reference went out (a failed send is not counted as sent).
  template <class Emit>
  void on_state(const msg::State& in, Emit&& emit) noexcept {
    const std::uint64_t k = in.header().tick();
    begin(in);
    count_skipped(k);
    for (std::uint64_t j = next_ > k + 1 ? next_ : k + 1;
         j <= k + static_cast<std::uint64_t>(lead_) && j <= end_tick_; ++j) {
      next_ = j + 1;
      if (!fill(j, in)) continue;  // before the trajectory begins: nothing to change yet
      if (!emit(static_cast<const msg::BalanceReference&>(ref_))) continue;
      if (sent_++ == 0) first_sent_ = j;
      last_sent_ = j;
    }
    last_state_tick_ = k;
  }

  /// The state of the trajectory's last tick has been seen: nothing more will be produced.
  bool done() const noexcept { return started_ && last_state_tick_ >= end_tick_; }
  /// The first state came after the trajectory began (its start is lost).
  bool started_late() const noexcept { return started_late_; }
  double first_state_time() const noexcept { return t_first_; }
  /// States whose tick was below one seen before (a restarted state stream). The player keeps
  /// its timeline: it produces nothing until the stream is past the ticks already produced.
  std::uint64_t restarts() const noexcept { return restarts_; }
  std::uint64_t sent() const noexcept { return sent_; }
  /// Ticks of the trajectory never produced because the states jumped past them (a player that
  /// fell behind and lost states: those references are missing, not late). Not the ticks before
  /// the first state (started_late()).
  std::uint64_t skipped() const noexcept { return skipped_; }
  std::uint64_t first_sent() const noexcept { return first_sent_; }
  std::uint64_t last_sent() const noexcept { return last_sent_; }
  int lead_ticks() const noexcept { return lead_; }
  const Trajectory& trajectory() const noexcept { return traj_; }

 private:
  void begin(const msg::State& in) noexcept;
  /// Adds to skipped_ the trajectory's ticks next_ .. k that state k leaves behind unproduced.
  void count_skipped(std::uint64_t k) noexcept;
  /// The trajectory's ticks (those fill() produces) in [from, to].
  std::uint64_t trajectory_ticks(std::uint64_t from, std::uint64_t to) const noexcept;
  /// Writes the reference of tick j into ref_ from state `in`; false before the trajectory.
  bool fill(std::uint64_t j, const msg::State& in) noexcept;

  Trajectory traj_;
  double period_;
  long long period_ns_;
  int lead_;
  std::vector<int> swing_wire_;  // wire index of each swing's joint
  msg::BalanceReference ref_;    // the constant part set at construction
  std::array<double, msg::MAX_JOINTS> nominal_q_{};
  bool started_ = false, started_late_ = false, origin_set_ = false;
  std::uint64_t next_ = 0, end_tick_ = 0, last_state_tick_ = 0;
  std::uint64_t sent_ = 0, first_sent_ = 0, last_sent_ = 0, skipped_ = 0;
  double t_first_ = 0.0;
  std::uint64_t k_ = 0;       // tick of the state being handled
  long long k_stamp_ns_ = 0;  // its stamp
  std::uint64_t restarts_ = 0;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  int step_index_ = -1;
  model::SE3 X_stood_;
  std::array<Eigen::Vector3d, 2> sole_F_;  // stand points in the foot frames (ComOver)
};

}  // namespace poise::reference
