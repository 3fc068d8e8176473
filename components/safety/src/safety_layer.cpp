#include "poise/safety/safety_layer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <stdexcept>

namespace poise::safety {

const char* to_string(Mode mode) noexcept {
  switch (mode) {
    case Mode::kStartup: return "STARTUP";
    case Mode::kActive: return "ACTIVE";
    case Mode::kHold: return "HOLD";
    case Mode::kDamp: return "DAMP";
    case Mode::kEStop: return "ESTOP";
    case Mode::kProtectiveStop: return "PROTECTIVE_STOP";
  }
  return "?";
}

ModeReport report(Mode mode) noexcept {
  switch (mode) {
    case Mode::kHold:
      return {msg::HEALTH_DEGRADED, "safety layer HOLD: no fresh joint command"};
    case Mode::kDamp:
      return {msg::HEALTH_FAULT, "safety layer DAMP: no joint command for the hold time"};
    case Mode::kEStop:
      return {msg::HEALTH_FAULT, "safety layer ESTOP: e-stop engaged (poise/estop)"};
    case Mode::kProtectiveStop:
      return {msg::HEALTH_FAULT,
              "safety layer PROTECTIVE_STOP: protective stop engaged, posture held (poise/estop)"};
    default:
      return {msg::HEALTH_OK, nullptr};
  }
}

void Command::resize(int n) {
  tau_ff = q_ref = qd_ref = kp = kd = Eigen::VectorXd::Zero(n);
}

void evaluate(const Command& c, const Eigen::Ref<const Eigen::VectorXd>& q,
              const Eigen::Ref<const Eigen::VectorXd>& qd,
              const Eigen::Ref<const Eigen::VectorXd>& effort, Eigen::Ref<Eigen::VectorXd> tau) {
  for (Eigen::Index i = 0; i < tau.size(); ++i) {
    const double t = c.tau_ff[i] + c.kp[i] * (c.q_ref[i] - q[i]) + c.kd[i] * (c.qd_ref[i] - qd[i]);
    tau[i] = std::clamp(t, -effort[i], effort[i]);
  }
}

SafetyLayer::SafetyLayer(Config config) : config_(std::move(config)) {
  n_ = static_cast<int>(config_.joint_names.size());
  const auto check = [&](const Eigen::VectorXd& v, const char* name) {
    if (v.size() != n_)
      throw std::invalid_argument(std::string("safety config: ") + name + " has " +
                                  std::to_string(v.size()) + " entries, the robot has " +
                                  std::to_string(n_) + " joints");
  };
  check(config_.hold_kp, "hold_kp");
  check(config_.hold_kd, "hold_kd");
  check(config_.damping_kd, "damping_kd");
  if (config_.settle_kp.size() != 0) check(config_.settle_kp, "settle_kp");
  check(config_.effort, "effort");
  check(config_.q_min, "q_min");
  check(config_.q_max, "q_max");
  if ((config_.hold_kp.array() < 0).any() || (config_.hold_kd.array() < 0).any() ||
      (config_.damping_kd.array() < 0).any() || !config_.hold_kp.allFinite() ||
      !config_.hold_kd.allFinite() || !config_.damping_kd.allFinite())
    throw std::invalid_argument("safety config: hold and damping gains must be finite and >= 0");
  if (!(config_.watchdog_s > 0) || !(config_.hold_s >= 0))
    throw std::invalid_argument("safety config: watchdog_s must be > 0 and hold_s >= 0");
  latest_.resize(n_);
  hold_.resize(n_);
  damp_.resize(n_);
  scratch_.resize(n_);
  damp_.kd = config_.damping_kd;
  hold_.kp = config_.hold_kp;
  hold_.kd = config_.hold_kd;
}

void SafetyLayer::start(const Eigen::Ref<const Eigen::VectorXd>& q0, std::int64_t now_ns,
                        bool settling) noexcept {
  have_command_ = false;
  hold_targets(q0, false);
  if (settling && config_.settle_kp.size() == n_) hold_.kp = config_.settle_kp;
  mode_ = Mode::kStartup;
  hold_since_ns_ = now_ns;
  changed_ = true;
}

void SafetyLayer::hold_targets(const Eigen::Ref<const Eigen::VectorXd>& q, bool feedforward) noexcept {
  if (q.size() == n_ && q.allFinite()) hold_.q_ref = q;
  hold_.qd_ref.setZero();
  if (feedforward)
    hold_.tau_ff = latest_.tau_ff;
  else
    hold_.tau_ff.setZero();
  hold_.kp = config_.hold_kp;
  hold_.kd = config_.hold_kd;
}

bool SafetyLayer::reject(std::uint64_t& counter, const char* format, ...) noexcept {
  ++counter;
  ++counters_.rejected;
  va_list args;
  va_start(args, format);
  std::vsnprintf(last_error_, sizeof(last_error_), format, args);
  va_end(args);
  return false;
}

bool SafetyLayer::on_command(const msg::JointCommand& c, std::int64_t robot_tick,
                             std::int64_t now_ns) noexcept {
  changed_ = false;
  const auto k = static_cast<unsigned long long>(c.header().tick());
  if (stopped()) {
    ++counters_.ignored_estop;
    return false;
  }
  if (c.joint_count() != static_cast<std::uint32_t>(n_))
    return reject(counters_.rejected_size,
                  "command of tick %llu rejected: joint_count %u, the robot has %d joints", k,
                  c.joint_count(), n_);
  if (robot_tick >= 0) {
    const std::int64_t age = robot_tick - static_cast<std::int64_t>(c.header().tick());
    if (age < 0 || age > config_.max_command_age_ticks)
      return reject(counters_.rejected_tick,
                    "command of tick %llu rejected: the robot is at tick %lld (%s)", k,
                    static_cast<long long>(robot_tick),
                    age < 0 ? "a tick in the future" : "too old");
  }
  Command& s = scratch_;
  s.tick = static_cast<std::int64_t>(c.header().tick());
  for (int i = 0; i < n_; ++i) {
    const auto u = static_cast<std::size_t>(i);
    switch (c.mode()) {
      case msg::COMMAND_TORQUE:
        s.tau_ff[i] = c.tau_ff()[u];
        s.q_ref[i] = c.q_ref()[u];
        s.qd_ref[i] = c.qd_ref()[u];
        s.kp[i] = c.kp()[u];
        s.kd[i] = c.kd()[u];
        break;
      case msg::COMMAND_DAMPING:
        s.tau_ff[i] = s.q_ref[i] = s.qd_ref[i] = s.kp[i] = 0.0;
        s.kd[i] = c.kd()[u];
        break;
      default:  // COMMAND_ZERO
        s.tau_ff[i] = s.q_ref[i] = s.qd_ref[i] = s.kp[i] = s.kd[i] = 0.0;
        break;
    }
    const char* joint = config_.joint_names[u].c_str();
    if (!std::isfinite(s.tau_ff[i]) || !std::isfinite(s.q_ref[i]) || !std::isfinite(s.qd_ref[i]) ||
        !std::isfinite(s.kp[i]) || !std::isfinite(s.kd[i]))
      return reject(counters_.rejected_non_finite,
                    "command of tick %llu rejected: non-finite value for joint %s", k, joint);
    if (s.kp[i] < 0 || s.kd[i] < 0)
      return reject(counters_.rejected_gain,
                    "command of tick %llu rejected: negative gain for joint %s (kp %g, kd %g)", k,
                    joint, s.kp[i], s.kd[i]);
    const double kp_max = config_.max_gain_ratio * config_.hold_kp[i];
    const double kd_max = config_.max_gain_ratio * config_.hold_kd[i];
    if ((kp_max > 0 && s.kp[i] > kp_max) || (kd_max > 0 && s.kd[i] > kd_max))
      return reject(counters_.rejected_gain,
                    "command of tick %llu rejected: gain for joint %s above %g x the hold gain "
                    "(kp %g > %g or kd %g > %g)",
                    k, joint, config_.max_gain_ratio, s.kp[i], kp_max, s.kd[i], kd_max);
    if (s.kp[i] > 0 && (s.q_ref[i] < config_.q_min[i] - config_.q_ref_margin ||
                        s.q_ref[i] > config_.q_max[i] + config_.q_ref_margin))
      return reject(counters_.rejected_range,
                    "command of tick %llu rejected: q_ref %g of joint %s outside its limits "
                    "[%g, %g]",
                    k, s.q_ref[i], joint, config_.q_min[i], config_.q_max[i]);
    if (std::abs(s.tau_ff[i]) > config_.tau_ff_ratio * config_.effort[i])
      return reject(counters_.rejected_range,
                    "command of tick %llu rejected: tau_ff %g of joint %s above %g x its effort "
                    "limit %g",
                    k, s.tau_ff[i], joint, config_.tau_ff_ratio, config_.effort[i]);
  }
  std::swap(latest_, scratch_);
  ++counters_.accepted;
  have_command_ = true;
  last_command_ns_ = now_ns;
  if (mode_ != Mode::kActive && (mode_ != Mode::kDamp || config_.resume_from_damp))
    set_mode(Mode::kActive, now_ns);
  return true;
}

void SafetyLayer::on_estop(bool engaged, Stop kind, const char* reason,
                           const Eigen::Ref<const Eigen::VectorXd>& q, std::int64_t now_ns) noexcept {
  changed_ = false;
  const char* why = reason && *reason ? reason : "(no reason given)";
  if (engaged && kind == Stop::kEmergencyDamp) {
    if (mode_ != Mode::kEStop) {
      ++counters_.estop_events;
      std::snprintf(last_error_, sizeof(last_error_), "ESTOP engaged: %s: damping", why);
      set_mode(Mode::kEStop, now_ns);
    }
    return;
  }
  if (engaged) {  // protective
    if (mode_ == Mode::kEStop) {
      ++counters_.refused_protective_stops;
      std::snprintf(last_error_, sizeof(last_error_),
                    "protective stop refused: the e-stop is damping (release it first): %s", why);
    } else if (mode_ != Mode::kProtectiveStop) {
      ++counters_.protective_stop_events;
      // The posture now, with the feed-forward that was carrying it (gravity, while standing).
      hold_targets(q, have_command_ && config_.hold_feedforward);
      std::snprintf(last_error_, sizeof(last_error_),
                    "PROTECTIVE_STOP engaged: %s: holding the posture until released", why);
      set_mode(Mode::kProtectiveStop, now_ns);
    }
    return;
  }
  if (stopped()) {
    const bool was_protective = mode_ == Mode::kProtectiveStop;
    // A protective stop's hold goes on (its targets and feed-forward); after a damping stop, the
    // posture now, without the feed-forward of a command from before the stop.
    if (!was_protective) hold_targets(q, false);
    have_command_ = false;  // only a command newer than the release resumes control
    std::snprintf(last_error_, sizeof(last_error_),
                  "%s released: holding the posture until a fresh command",
                  was_protective ? "PROTECTIVE_STOP" : "ESTOP");
    set_mode(Mode::kHold, now_ns);
  }
}

void SafetyLayer::set_mode(Mode mode, std::int64_t now_ns) noexcept {
  if (mode == mode_) return;
  if (mode == Mode::kHold) hold_since_ns_ = now_ns;
  mode_ = mode;
  changed_ = true;
}

const Command& SafetyLayer::update(std::int64_t now_ns,
                                   const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  changed_ = false;
  const auto watchdog_ns = static_cast<std::int64_t>(config_.watchdog_s * 1e9);
  const auto hold_ns = static_cast<std::int64_t>(config_.hold_s * 1e9);
  if (mode_ == Mode::kActive && now_ns - last_command_ns_ > watchdog_ns) {
    // The last command's targets; a damping or zero command has none: the posture now.
    if ((latest_.kp.array() > 0.0).any())
      hold_targets(latest_.q_ref, config_.hold_feedforward);
    else
      hold_targets(q, false);
    ++counters_.hold_events;
    std::snprintf(last_error_, sizeof(last_error_),
                  "HOLD: no joint command for %.1f ms: holding the last targets for %.1f s",
                  static_cast<double>(now_ns - last_command_ns_) * 1e-6, config_.hold_s);
    set_mode(Mode::kHold, now_ns);
  }
  // hold_s 0: no hold at all, DAMP on the tick the watchdog fires (otherwise a stale tick would
  // be a one-tick HOLD and only a second stale tick in a row would damp).
  if (mode_ == Mode::kHold && (hold_ns == 0 || now_ns - hold_since_ns_ > hold_ns)) {
    ++counters_.damp_events;
    std::snprintf(last_error_, sizeof(last_error_),
                  "DAMP: held %.1f s without a joint command: damping", config_.hold_s);
    set_mode(Mode::kDamp, now_ns);
  }
  switch (mode_) {
    case Mode::kStartup: ++counters_.ticks_startup; return hold_;
    case Mode::kActive: ++counters_.ticks_active; return latest_;
    case Mode::kHold: ++counters_.ticks_hold; return hold_;
    case Mode::kDamp: ++counters_.ticks_damp; return damp_;
    case Mode::kEStop: ++counters_.ticks_estop; return damp_;
    case Mode::kProtectiveStop: ++counters_.ticks_protective_stop; return hold_;
  }
  return damp_;
}

}  // namespace poise::safety
