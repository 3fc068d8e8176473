// poise-gantry: a humanoid held by its pelvis on a gantry as the robot side of the topics: a
// second backend of the robot-side safety layer (poise-sim is the first), and the shape of a
// C++ hardware driver.
//
// ------------------------------------------------------------------------------------------------
// Plant (no Bullet; the project's own rigid-body model, components/model)
//   The base is fixed at the robot's nominal standing pose. Each foot rests on a sprung force
//   plate that pushes it up with half the robot's weight at the sole centre (world +z), so the
//   legs carry the load they carry when standing and the balance stack runs as on the ground.
//   Joints: M_jj(q) qdd = tau - b(q, qd), where M_jj is the joint block of the CRBA mass matrix
//   and b = RNEA(q, qd, 0) with gravity and the two plate forces (the base cannot move), plus the
//   URDF joint damping; semi-implicit Euler at 1 kHz on the wall clock; the URDF position
//   limits are hard stops.
//   Sensors: q, qd, the torque applied, the IMU at rest in the pelvis' pose (with seeded gyro
//   noise: a real IMU is never bit-identical), each plate's force as the foot F/T reading.
// Contract: as poise-sim (robot_description latched, sensors every tick, joint_command in,
//   poise/estop in), ticks from 0, one per millisecond of wall clock.
// What it is for: the robot side (the contract, the safety layer, a driver's structure), not
//   balance. The balance controller assumes a free-floating base; held by the gantry, the base
//   never moves as the controller's momentum feedback expects, and the joints drift (measured:
//   1-2 rad over 5 s, to the limits), as on any fixed-base rig.
// Safety: every command through safety::SafetyLayer (validation, watchdog HOLD of the last
//   targets with the robot's PD gains, then DAMP after --hold-s; e-stop); the mode is in the
//   diagnostics and the summary.
// ------------------------------------------------------------------------------------------------
#include <CLI/CLI.hpp>

#include <atomic>
#include <cstdio>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include <poise/msg/estop.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>

#include "poise/model/data.hpp"
#include "poise/model/dynamics.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/node/mailbox.hpp"
#include "poise/node/estop_channel.hpp"
#include "poise/safety/writer_gate.hpp"
#include "poise/node/node.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/safety/safety_layer.hpp"
#include "poise/cli/parse.hpp"
#include "poise/cli/read_file.hpp"

namespace {

using namespace poise;

std::string read_text(const std::string& path) {
  return cli::read_regular_file(path, "robot", model::kMaxFileBytes);
}

struct Settings {
  double duration = 10.0;
  double watchdog_ms = 5.0;
  double hold_s = 5.0;
  int wait_readers = 1;
  int startup_timeout_ms = 30000;
  unsigned seed = 1;
};

class Gantry {
 public:
  Gantry(node::Node& node, const std::string& robot_path, const Settings& settings)
      : node_(node),
        settings_(settings),
        robot_(model::load_robot_config(robot_path)),
        model_(model::load_robot_model(robot_)),
        data_(model_),
        n_(model_.njoints),
        safety_(make_safety(robot_, model_, settings)),
        description_pub_(node.participant()),
        sensors_pub_(node.participant()),
        estops_(node.participant(), node::robot_side_name("poise-" + node.name())),
        commands_(node.participant(),
                  [this](const msg::JointCommand& c, const dds::detail::SampleMeta& m) {
                    // One commanding writer (safety::CommandWriterGate); the loop reports.
                    if (gate_.check(
                            m.writer_id, [this] { return commands_.matched(); }, node::now_ns()) ==
                        safety::CommandWriterGate::Verdict::kForeign) {
                      foreign_.refuse(m.writer_id, gate_.owner());
                      return;
                    }
                    box_.put(c);
                  }),
        rng_(settings.seed) {
    node.watch(commands_);
    node.watch(estops_.subscriber());
    node.expect_one_writer(commands_);
    q_full_ = robot_.q_nominal;
    v_full_ = Eigen::VectorXd::Zero(model_.nv);
    zero_a_ = Eigen::VectorXd::Zero(model_.nv);
    q_ = q_full_.tail(n_);
    qd_ = Eigen::VectorXd::Zero(n_);
    tau_ = Eigen::VectorXd::Zero(n_);
    qdd_ = Eigen::VectorXd::Zero(n_);
    rhs_ = Eigen::VectorXd::Zero(n_);
    Mjj_ = Eigen::MatrixXd::Zero(n_, n_);
    ldlt_ = Eigen::LDLT<Eigen::MatrixXd>(n_);
    effort_.resize(n_);
    for (int j = 0; j < n_; ++j)
      effort_[j] = std::isfinite(model_.limits[static_cast<std::size_t>(j)].effort)
                       ? model_.limits[static_cast<std::size_t>(j)].effort
                       : 1e9;
    plate_force_ = 0.5 * model_.total_mass * 9.81;
    publish_description(robot_path);
  }

  /// Runs --duration seconds at 1 kHz. Returns false when interrupted early.
  bool run() {
    const auto startup = std::chrono::milliseconds(settings_.startup_timeout_ms);
    if (!sensors_pub_.wait_for_matches(settings_.wait_readers, startup))
      dds::log(dds::LogLevel::warn, "start-up: %d of %d sensors readers after %d ms: starting",
               sensors_pub_.matched(), settings_.wait_readers, settings_.startup_timeout_ms);
    safety_.start(q_, node::now_ns());
    const auto steps = static_cast<std::int64_t>(std::llround(settings_.duration * 1000.0));
    dds::log(dds::LogLevel::info, "gantry: %s, %d joints, %.1f s at 1 kHz", robot_.name.c_str(),
             n_, settings_.duration);
    node::TickTimer timer(1'000'000);
    timer.start();
    std::int64_t k = 0;
    for (; k < steps && node_.running(); ++k) {
      tick_ = k;
      publish_sensors();
      timer.wait_next();
      const std::int64_t t0 = node::now_ns();
      std::int64_t arrival = 0;
      report_foreign_commands();
      while (box_.take(command_, seen_, &arrival))
        if (!safety_.on_command(command_, k, arrival) && !safety_.stopped()) {
          ++rejected_;
          node_.error("%s", safety_.last_error());
        }
      while (const msg::EStop* e = estops_.take()) {
        safety_.on_estop(e->engaged(), safety::to_stop(e->kind()), e->reason().c_str(), q_,
                         node::now_ns());
        estops_.acknowledge(*e, safety_.stopped(), safety::held_stop(safety_.mode()),
                            static_cast<std::uint64_t>(k));
      }
      const safety::Command& c = safety_.update(node::now_ns(), q_);
      report_mode();
      safety::evaluate(c, q_, qd_, effort_, tau_);
      if (safety_.mode() == safety::Mode::kHold)
        hold_drift_ = std::max(hold_drift_, (q_ - c.q_ref).cwiseAbs().maxCoeff());
      if (safety_.mode() == safety::Mode::kActive)
        active_error_ = std::max(active_error_, (q_ - c.q_ref).cwiseAbs().maxCoeff());
      step();
      node_.tick_done(static_cast<std::uint64_t>(k), node::now_ns() - t0);
      node_.poll();
    }
    overruns_ = timer.overruns();
    ticks_ = k;
    return k >= steps;
  }

  /// A FAULT naming both writers once commands from a second writer were refused (latched).
  void report_foreign_commands() noexcept {
    if (const char* text = foreign_.news()) {
      node_.set_condition(msg::HEALTH_FAULT, text);
      node_.error("%s", text);
    }
  }

  std::string result_json() const {
    const safety::Counters& s = safety_.counters();
    nlohmann::json j;
    j["robot"] = robot_.name;
    j["ticks"] = ticks_;
    j["overruns"] = overruns_;
    j["final_mode"] = safety::to_string(safety_.mode());
    j["max_deviation_from_nominal_rad"] = (q_ - robot_.q_nominal.tail(n_)).cwiseAbs().maxCoeff();
    j["hold_drift_rad"] = hold_drift_;        // max |q - q_ref| while holding
    j["active_tracking_rad"] = active_error_;  // max |q - q_ref| under control
    j["finite"] = q_.allFinite() && qd_.allFinite();
    j["foreign_commands"] = foreign_.refused();
    j["safety"] = {{"accepted", s.accepted},         {"rejected", s.rejected},
                   {"rejected_tick", s.rejected_tick}, {"ignored_during_estop", s.ignored_estop},
                   {"hold_events", s.hold_events},   {"damp_events", s.damp_events},
                   {"estop_events", s.estop_events}, {"ticks_startup", s.ticks_startup},
                   {"ticks_active", s.ticks_active}, {"ticks_hold", s.ticks_hold},
                   {"ticks_damp", s.ticks_damp},     {"ticks_estop", s.ticks_estop},
                   {"protective_stop_events", s.protective_stop_events},
                   {"refused_protective_stops", s.refused_protective_stops},
                   {"ticks_protective_stop", s.ticks_protective_stop}};
    return j.dump();
  }

 private:
  static safety::Config make_safety(const model::RobotConfig& robot, const model::Model& model,
                                    const Settings& settings) {
    safety::Config c = safety::make_config(model, &robot, model.joint_names, 0.001, 5.0);
    for (const std::string& w : c.warnings)
      dds::log(dds::LogLevel::warn, "safety: %s", w.c_str());
    c.watchdog_s = settings.watchdog_ms * 1e-3;
    c.hold_s = settings.hold_s;
    return c;
  }

  void publish_description(const std::string& robot_path) {
    description_pub_.publish(node::describe_robot(robot_, model_, read_text(robot_path), 0.001));
  }

  /// The plate force at the sole centre of foot f, for the dynamics and the F/T reading.
  Eigen::Vector3d sole_centre_F(std::size_t f) const {
    return robot_.feet[f].sole.center_F();
  }

  void step() noexcept {
    q_full_.tail(n_) = q_;
    v_full_.tail(n_) = qd_;
    const Eigen::MatrixXd& M = model::crba(model_, data_, q_full_);  // also forward kinematics
    Mjj_ = M.bottomRightCorner(n_, n_);
    model::clear_external_forces(data_);
    for (std::size_t f = 0; f < 2; ++f) {
      const model::SE3 X_WF = model::frame_placement(model_, data_, robot_.feet[f].frame_id);
      add_external_wrench(model_, data_, robot_.feet[f].frame_id, X_WF.act(sole_centre_F(f)),
                          Eigen::Vector3d(0, 0, plate_force_), Eigen::Vector3d::Zero());
    }
    const Eigen::VectorXd& b = model::rnea(model_, data_, q_full_, v_full_, zero_a_);
    for (int j = 0; j < n_; ++j)
      rhs_[j] = tau_[j] - b[6 + j] - model_.damping[static_cast<std::size_t>(j)] * qd_[j];
    ldlt_.compute(Mjj_);
    qdd_ = ldlt_.solve(rhs_);
    const double dt = 0.001;
    for (int j = 0; j < n_; ++j) {
      qd_[j] += dt * qdd_[j];
      q_[j] += dt * qd_[j];
      const auto& l = model_.limits[static_cast<std::size_t>(j)];
      if (q_[j] < l.lower || q_[j] > l.upper) {  // hard stop
        q_[j] = std::clamp(q_[j], l.lower, l.upper);
        qd_[j] = 0.0;
      }
    }
  }

  void publish_sensors() noexcept {
    msg::Sensors& s = sensors_;
    s.header().tick(static_cast<std::uint64_t>(tick_));
    s.header().stamp_ns(tick_ * 1'000'000);
    s.joint_count(static_cast<std::uint32_t>(n_));
    for (int j = 0; j < n_; ++j) {
      const auto u = static_cast<std::size_t>(j);
      s.q()[u] = q_[j];
      s.qd()[u] = qd_[j];
      s.tau_measured()[u] = tau_[j];
    }
    // IMU at rest in the fixed pelvis pose (the nominal pose's base orientation).
    q_full_.tail(n_) = q_;
    model::forward_kinematics(model_, data_, q_full_);
    const model::SE3 X_WI = model::frame_placement(model_, data_, robot_.imu_frame_id);
    const Eigen::Quaterniond q_WI(X_WI.R);
    s.imu().orientation_wxyz({q_WI.w(), q_WI.x(), q_WI.y(), q_WI.z()});
    const Eigen::Vector3d f_I = X_WI.R.transpose() * Eigen::Vector3d(0, 0, 9.81);
    std::normal_distribution<double> noise(0.0, 5e-4);
    for (int a = 0; a < 3; ++a) {
      s.imu().specific_force_I()[static_cast<std::size_t>(a)] = f_I[a];
      s.imu().angular_velocity_I()[static_cast<std::size_t>(a)] = noise(rng_);
    }
    for (std::size_t f = 0; f < 2; ++f) {
      const model::SE3 X_WF = model::frame_placement(model_, data_, robot_.feet[f].frame_id);
      const Eigen::Vector3d force_F = X_WF.R.transpose() * Eigen::Vector3d(0, 0, plate_force_);
      const Eigen::Vector3d torque_F = sole_centre_F(f).cross(force_F);
      for (int a = 0; a < 3; ++a) {
        s.foot_wrench_F()[f].force()[static_cast<std::size_t>(a)] = force_F[a];
        s.foot_wrench_F()[f].torque()[static_cast<std::size_t>(a)] = torque_F[a];
      }
    }
    node_.publish(sensors_pub_, s);
  }

  /// The mode in the diagnostics at once; in the log at most every 100 ms (the newest mode).
  void report_mode() noexcept {
    const safety::Mode mode = safety_.mode();
    if (mode != reported_) {
      reported_ = mode;
      ++transitions_;
      const safety::ModeReport r = safety::report(mode);
      if (!foreign_.faulted()) node_.set_condition(r.health, r.text);
    }
    if (mode == logged_) return;
    const std::int64_t now = node::now_ns();
    if (now - last_log_ns_ < 100'000'000) return;
    last_log_ns_ = now;
    logged_ = mode;
    dds::log(mode == safety::Mode::kActive ? dds::LogLevel::info : dds::LogLevel::warn,
             "safety: %s at tick %lld (%s; %llu transitions since the last line)",
             safety::to_string(mode), static_cast<long long>(tick_),
             mode == safety::Mode::kActive ? "commands fresh" : safety_.last_error(),
             static_cast<unsigned long long>(transitions_));
    transitions_ = 0;
  }

  node::Node& node_;
  Settings settings_;
  model::RobotConfig robot_;
  model::Model model_;
  model::Data data_;
  int n_;
  safety::SafetyLayer safety_;
  dds::Publisher<msg::RobotDescription> description_pub_;
  dds::Publisher<msg::Sensors> sensors_pub_;
  node::EStopChannel estops_;
  node::Mailbox<msg::JointCommand> box_;
  safety::CommandWriterGate gate_;  // the DDS listener thread's
  safety::ForeignCommands foreign_;
  dds::Subscriber<msg::JointCommand> commands_;
  std::mt19937 rng_;
  Eigen::VectorXd q_full_, v_full_, zero_a_, q_, qd_, tau_, qdd_, rhs_, effort_;
  Eigen::MatrixXd Mjj_;
  Eigen::LDLT<Eigen::MatrixXd> ldlt_;
  double plate_force_ = 0.0, hold_drift_ = 0.0, active_error_ = 0.0;
  msg::Sensors sensors_;
  msg::JointCommand command_;
  std::uint64_t seen_ = 0, rejected_ = 0, overruns_ = 0;
  std::int64_t tick_ = 0, ticks_ = 0;
  safety::Mode reported_ = safety::Mode::kStartup, logged_ = safety::Mode::kStartup;
  std::uint64_t transitions_ = 0;
  std::int64_t last_log_ns_ = 0;
};

int run(int argc, char** argv) {
  node::NodeOptions options;
  Settings s;
  CLI::App app{
      "Gantry robot backend: the humanoid held by its pelvis, feet on sprung force plates, joint "
      "dynamics from the rigid-body model; commands through the robot-side safety layer."};
  node::add_node_options(app, options, "gantry");
  app.add_option("--duration", s.duration, "[s]")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--watchdog-ms", s.watchdog_ms,
                 "safety layer: HOLD after this long without an accepted command")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 60000.0));
  app.add_option("--hold-s", s.hold_s, "safety layer: hold this long, then damp")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--wait-readers", s.wait_readers, "poise/sensors readers to wait for at start")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  app.add_option("--startup-timeout-ms", s.startup_timeout_ms, "longest wait for them")
      ->capture_default_str();
  app.add_option("--seed", s.seed, "IMU noise seed")->capture_default_str();
  POISE_CLI_PARSE(app, argc, argv);
  // The robot side owns the robot files: --robot, default the project humanoid.
  const std::string robot = options.robot.empty() ? node::default_robot_config() : options.robot;
  node::Node node(options);
  Gantry gantry(node, robot, s);
  const bool ok = gantry.run();
  const std::string result = gantry.result_json();
  std::printf("poise-gantry result %s\n", result.c_str());
  std::fflush(stdout);
  node.write_summary(result);
  return ok ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-gantry: %s\n", e.what());
    return 2;
  }
}
