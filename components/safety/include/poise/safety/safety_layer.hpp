#pragma once
// The robot-side safety layer: what stands between the joint commands arriving over DDS and the
// actuators, on every robot backend (poise-sim, poise-gantry, a hardware driver in C++). A
// driver in another language implements the same rules (deploy/examples/README.md).
//
//   safety::SafetyLayer safety(safety::make_config(robot, model, joint_names, dt));
//   safety.start(q0, now);                                  // start-up: hold q0
//   per tick k:
//     while (new command c) safety.on_command(c, k, now);   // validated, or rejected + counted
//     const safety::Command& apply = safety.update(now, q); // the command to apply this tick
//     tau = safety::evaluate(apply, q, qd, effort)          // or hand it to the motor drivers
//
// Modes (Mode), one per tick:
//   STARTUP  before the first accepted command: hold the start posture q0 with the hold gains.
//   ACTIVE   the newest accepted command, as sent.
//   HOLD     no accepted command for `watchdog_s`: hold the last command's joint targets (q_ref,
//            qd_ref = 0) with the hold gains, plus its feed-forward torque (`hold_feedforward`),
//            for `hold_s`: a component restart (kill -9, back within a second) finds the robot
//            standing. A fresh command resumes ACTIVE.
//   DAMP     HOLD lasted `hold_s`: tau = -damping_kd * qd. A fresh command resumes ACTIVE
//            (`resume_from_damp`).
//   ESTOP    an engaged emergency stop (poise/estop, STOP_EMERGENCY_DAMP): damping, commands
//            ignored, until released; then HOLD of the posture at the release until a fresh
//            command. A standing humanoid falls.
//   PROTECTIVE_STOP  an engaged protective stop (STOP_PROTECTIVE_HOLD, machine-safety category
//            2): the posture at the stop held with the hold gains and the last command's
//            feed-forward, commands ignored, no time limit; released like ESTOP. A standing
//            humanoid stays up. An emergency stop takes over from it at once; a protective
//            request during ESTOP is refused (a damping stop is never eased into a hold).
// Hold gains (make_config): the robot configuration's PD gains, raised where they are too soft
// to hold the joint's load against gravity, then bounded for stability of the 1 kHz explicit PD
// loop on that joint's own inertia.
//  - A held humanoid is a statue, and a statue on its ankles is an inverted pendulum: gravity's
//    torque about a joint grows by k = m g h per radian (gravity_stiffness()), and the joint falls
//    over unless kp > k. kp is raised to 2 k. The project humanoid's ankles carry 378 N m/rad
//    against a configured 150: at the configured gains the held robot tips over within seconds
//    (3 s measured), at 757 it stands through the hold (HoldTest, 10 s).
//  - Bound: kp <= 0.2 I / dt^2, kd <= 0.5 I / dt, where I is the joint-space inertia M_ii at the
//    start posture. A wrist of 1e-4 kg m^2 gets kd <= 0.05 N m s/rad (a constant kd of 10 makes
//    it explode at 1 kHz).
// A command is rejected (counted by reason, last_error names the field and joint) when it has
// another joint_count, a non-finite number, a negative gain, a gain above `max_gain_ratio` times
// the hold gain, a position target outside the joint limits by more than `q_ref_margin`, a
// feed-forward above `tau_ff_ratio` times the effort limit, or a tick older than
// `max_command_age_ticks` behind the robot's tick or ahead of it.
// Real-time: on_command(), on_estop(), update() and evaluate() do not allocate or throw.
// The clock is an input (ns, any monotonic origin): testable with a fake clock.

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

#include <poise/msg/diagnostics.h>
#include <poise/msg/estop.h>
#include <poise/msg/joint_command.h>

#include "poise/model/model.hpp"
#include "poise/model/robot_config.hpp"

namespace poise::safety {

enum class Mode : std::uint8_t { kStartup, kActive, kHold, kDamp, kEStop, kProtectiveStop };
/// What an engaged stop does (poise/estop's StopKind).
enum class Stop : std::uint8_t { kEmergencyDamp, kProtectiveHold };
/// The wire's stop kind; an unknown value is the emergency stop (the safe reading).
inline Stop to_stop(msg::StopKind kind) noexcept {
  return kind == msg::STOP_PROTECTIVE_HOLD ? Stop::kProtectiveHold : Stop::kEmergencyDamp;
}
/// The stop a mode holds, for poise/estop_state.
inline msg::StopKind held_stop(Mode mode) noexcept {
  return mode == Mode::kProtectiveStop ? msg::STOP_PROTECTIVE_HOLD : msg::STOP_EMERGENCY_DAMP;
}
const char* to_string(Mode mode) noexcept;

/// How a backend reports a mode in its diagnostics (Node::set_condition): HOLD is DEGRADED,
/// DAMP and ESTOP are FAULT; STARTUP and ACTIVE clear the condition (text nullptr).
struct ModeReport {
  msg::NodeHealth health;
  const char* text;  ///< a literal
};
ModeReport report(Mode mode) noexcept;

/// What the robot applies in one tick: tau = tau_ff + kp (q_ref - q) + kd (qd_ref - qd),
/// clamped to the effort limits (damping: tau_ff = 0, kp = 0, qd_ref = 0). Robot joint order.
struct Command {
  std::int64_t tick = -1;  ///< tick of the sensor frame it answers (-1: made by the layer)
  Eigen::VectorXd tau_ff, q_ref, qd_ref, kp, kd;
  void resize(int n);  ///< all zero, dim n (allocates: configuration time)
};

/// tau = tau_ff + kp (q_ref - q) + kd (qd_ref - qd), clamped to +-effort. No allocation.
void evaluate(const Command& command, const Eigen::Ref<const Eigen::VectorXd>& q,
              const Eigen::Ref<const Eigen::VectorXd>& qd,
              const Eigen::Ref<const Eigen::VectorXd>& effort, Eigen::Ref<Eigen::VectorXd> tau);

struct Config {
  std::vector<std::string> joint_names;  ///< robot (wire) joint order
  Eigen::VectorXd hold_kp, hold_kd;      ///< PD gains to hold a posture (dim n)
  /// The robot configuration's kp bounded by inertia, without the gravity floor (dim n, or empty:
  /// hold_kp), for a simulator's settle only: the few ticks that set the robot down onto its
  /// feet before the first sensor frame (start(q0, now, true)). The robot hangs from nothing
  /// there, so no statue needs holding, and the settled state stays that of the robot's gains.
  Eigen::VectorXd settle_kp;
  Eigen::VectorXd damping_kd;            ///< DAMP / ESTOP gains (dim n)
  Eigen::VectorXd effort;                ///< effort limits (dim n; +inf: none)
  Eigen::VectorXd q_min, q_max;          ///< position limits (dim n; +-inf: none)
  double watchdog_s = 0.005;             ///< ACTIVE -> HOLD after this long without a command
  double hold_s = 5.0;                   ///< HOLD -> DAMP after this long (0: DAMP at once)
  bool hold_feedforward = true;          ///< HOLD keeps the last command's tau_ff
  bool resume_from_damp = true;          ///< a fresh command ends DAMP
  std::int64_t max_command_age_ticks = 20;  ///< oldest command accepted [ticks behind the robot]
  double q_ref_margin = 0.05;            ///< tolerance of q_ref beyond the joint limits [rad]
  double tau_ff_ratio = 2.0;             ///< |tau_ff| above this x effort: rejected
  double max_gain_ratio = 50.0;          ///< kp, kd above this x the hold gains: rejected
  /// make_config's findings for the operator's log: a joint whose inertia bound keeps its hold
  /// gain below gravity's stiffness on its load (a held robot tips over). Not used by the layer.
  std::vector<std::string> warnings;
};

/// Hold/damping gains raised against gravity and bounded for stability (see above), limits from
/// the model. `joint_names`:
/// the robot's wire order (every name a model joint). `robot` may be null: the gains then
/// default to kp 100, kd 2 before the bound. `damping_kd` is the wanted damping gain (bounded
/// the same way). `q0` (dim model.nq, or empty: the robot's nominal posture or neutral) is the
/// posture whose M_ii bounds the gains. Throws model::ModelError on an unknown joint.
Config make_config(const model::Model& model, const model::RobotConfig* robot,
                   const std::vector<std::string>& joint_names, double dt, double damping_kd,
                   const Eigen::VectorXd& q0 = Eigen::VectorXd());

/// Per model joint (dim njoints): how fast gravity's torque about the joint axis grows as the
/// joint's load turns about it at posture q [N m/rad]; positive: the load tips further (an
/// inverted pendulum over an ankle: m g h). The load of a joint between the base and one of the
/// robot's feet is everything outside the joint's subtree (the robot stands on that foot);
/// any other joint's load is its subtree. A held joint is statically stable when kp exceeds it.
Eigen::VectorXd gravity_stiffness(const model::Model& model, const model::RobotConfig* robot,
                                  const Eigen::VectorXd& q);

struct Counters {
  std::uint64_t accepted = 0;
  std::uint64_t rejected = 0;          ///< all reasons
  std::uint64_t rejected_size = 0, rejected_non_finite = 0, rejected_gain = 0,
                rejected_range = 0, rejected_tick = 0, ignored_estop = 0;
  std::uint64_t hold_events = 0;       ///< ACTIVE -> HOLD
  std::uint64_t damp_events = 0;       ///< HOLD -> DAMP
  std::uint64_t estop_events = 0;
  std::uint64_t protective_stop_events = 0;
  std::uint64_t refused_protective_stops = 0;  ///< asked for during an emergency stop
  std::uint64_t ticks_startup = 0, ticks_active = 0, ticks_hold = 0, ticks_damp = 0,
                ticks_estop = 0, ticks_protective_stop = 0;
};

class SafetyLayer {
 public:
  /// Throws std::invalid_argument when a vector does not have one entry per joint or a gain is
  /// negative.
  explicit SafetyLayer(Config config);

  int num_joints() const noexcept { return n_; }
  const Config& config() const noexcept { return config_; }

  /// Start-up (STARTUP): holds q0 (dim n) from now until the first accepted command. `settling`:
  /// with settle_kp (a simulator setting the robot down before its first sensor frame).
  void start(const Eigen::Ref<const Eigen::VectorXd>& q0, std::int64_t now_ns,
             bool settling = false) noexcept;

  /// A command from poise/joint_command (description joint order). `robot_tick`: the robot's
  /// current tick (< 0: not checked). Returns true when accepted (it then drives the robot).
  bool on_command(const msg::JointCommand& command, std::int64_t robot_tick,
                  std::int64_t now_ns) noexcept;

  /// poise/estop: engaged -> ESTOP or PROTECTIVE_STOP (by `kind`; `q`, the posture now, is held
  /// by a protective stop) at once; released -> HOLD of `q` until a fresh command.
  void on_estop(bool engaged, Stop kind, const char* reason,
                const Eigen::Ref<const Eigen::VectorXd>& q, std::int64_t now_ns) noexcept;
  /// True in ESTOP and PROTECTIVE_STOP: a stop is engaged.
  bool stopped() const noexcept {
    return mode_ == Mode::kEStop || mode_ == Mode::kProtectiveStop;
  }

  /// Mode transitions due at now_ns, then the command to apply this tick. Counts the tick.
  /// `q`: the joint positions now (held when the last command has no position targets).
  const Command& update(std::int64_t now_ns, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;

  Mode mode() const noexcept { return mode_; }
  /// True when the mode changed in the last update() / on_command() / on_estop().
  bool mode_changed() const noexcept { return changed_; }
  /// Newest rejection reason or transition ("HOLD: no joint command for 5.0 ms", ...).
  const char* last_error() const noexcept { return last_error_; }
  const Counters& counters() const noexcept { return counters_; }
  /// Time of the last accepted command (0: none).
  std::int64_t last_command_ns() const noexcept { return last_command_ns_; }

 private:
  void set_mode(Mode mode, std::int64_t now_ns) noexcept;
  void hold_targets(const Eigen::Ref<const Eigen::VectorXd>& q, bool feedforward) noexcept;
  bool reject(std::uint64_t& counter, const char* format, ...) noexcept
      __attribute__((format(printf, 3, 4)));

  Config config_;
  int n_ = 0;
  Mode mode_ = Mode::kStartup;
  bool changed_ = false;
  Command latest_;  ///< the newest accepted command (converted)
  Command hold_;    ///< STARTUP / HOLD command
  Command damp_;    ///< DAMP / ESTOP command
  Command scratch_;
  std::int64_t last_command_ns_ = 0;
  std::int64_t hold_since_ns_ = 0;
  bool have_command_ = false;
  Counters counters_;
  char last_error_[256] = {};
};

}  // namespace poise::safety
