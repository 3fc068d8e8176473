// poise-sim: the Bullet simulator (simulator/sim) as a DDS node: the robot side of the topics.
//
// ------------------------------------------------------------------------------------------------
// Contract
//   publishes   poise/robot_description  RobotDescription  once at start (reliable,
//                                                          transient-local: late joiners get it);
//                                                          header.tick = k0, the first tick the
//                                                          run publishes (after --settle-ticks):
//                                                          `poise info` finds a recording's
//                                                          missing start with it
//               poise/sensors            Sensors           every tick k (reliable, keep-last 1)
//               poise/ground_truth       GroundTruth       every tick k while a reader is
//                                                          matched (reliable, keep-last 1)
//               poise/diagnostics        Diagnostics       ~10 Hz best-effort (compute = step)
//   subscribes  poise/joint_command      JointCommand      reliable, keep-last 1
//               poise/balance_reference  BalanceReference  latched, 512 held: only the CoM target,
//                                                            for the scenario monitor's CoM error
//               poise/disturbance        Disturbance       reliable, keep-last 16: pushes applied
//                                                          live (start < 0: at once)
//   --lockstep  (default) publish sensors k, wait for the command with header.tick == k (at most
//               --command-timeout-ms; on a timeout: logged, counted, damping for that step), then
//               step. Tick 0 is repeated every 100 ms until the loop answers (start-up). The
//               step and the next sensors are done in the command callback on the DDS listener
//               thread (no wake-up of the main thread per tick); the main thread publishes the
//               diagnostics and handles the start-up repeats and the timeouts.
//   --realtime  1 kHz on the wall clock with the newest command.
//   safety      every command goes through the robot-side safety layer (components/safety), as
//               on a hardware driver: validated (joint_count, finite, gains, limits, tick age),
//               watchdog (no accepted command for --watchdog-ms, default 5: HOLD the last
//               targets with the robot's PD gains for --hold-s, then DAMP; a fresh command
//               resumes), e-stop (poise/estop: damping until released). Modes are logged and
//               reported in the diagnostics (HOLD: DEGRADED, DAMP/ESTOP: FAULT). In lockstep a
//               command timeout holds the same way.
//   start-up    waits for --wait-readers sensors readers (and --wait-truth-readers ground-truth
//               readers) and for --start-file to exist (a launcher's go signal); real time publishes the frame k0 and waits for its acknowledgment by
//               every matched reader before the wall clock starts. With --start-when-answered
//               (what `poise run` and `poise launch` use) real time also repeats k0 every 100 ms
//               until a joint command for k0 comes back (at most --startup-timeout-ms), as
//               lockstep does: every link of the loop has then carried a sample, in the
//               direction it is used (a writer that has matched a reader does not mean that the
//               reader has matched the writer: between vendors that takes up to ~1 s).
//               --settle-ticks (10) steps with the joints held by the safety layer's start-up
//               hold (the robot's PD gains, bounded by each joint's inertia) before tick k0:
//               the frame right after construction has no contact forces yet, and the
//               estimator would report "no contact" (flight) to the controller.
//   measures    tick latency: sensors k published -> command k received (this process's clock);
//               realtime factor; the scenario monitor's verdict. Printed at exit as one line
//               "poise-sim result {json}" and written to --summary.
// ------------------------------------------------------------------------------------------------
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>
#include <nlohmann/json.hpp>

#include "poise/sim/reality_json.hpp"

#include <poise/msg/balance_reference.h>

#include "poise/node/mailbox.hpp"
#include "poise/node/estop_channel.hpp"
#include "poise/safety/writer_gate.hpp"
#include "poise/node/node.hpp"
#include "poise/node/shutdown.hpp"
#include "poise/sim/world.hpp"
#include "poise/sim/simulator.hpp"
#include "poise/safety/counters_json.hpp"
#include "poise/safety/safety_layer.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/sim_node/sim_messages.hpp"
#include "poise/cli/parse.hpp"

namespace {

using namespace poise;

struct Settings {
  std::string scenario;
  bool realtime = false;
  double duration = -1.0;
  int command_timeout_ms = sim::kDefaultCommandTimeoutMs;
  int startup_timeout_ms = 30000;
  int max_consecutive_timeouts = 3;
  double watchdog_ms = 5.0;
  double hold_s = 5.0;  ///< safety layer: HOLD this long, then DAMP
  bool progress = false;
  int settle_ticks = 10;
  int wait_readers = 1;        ///< poise/sensors readers to wait for before tick k0
  int wait_truth_readers = 0;  ///< poise/ground_truth readers to wait for before tick k0
  std::string start_file;      ///< wait until this file exists before tick k0 ("": no wait)
  bool start_when_answered = false;  ///< real time: repeat k0 until command k0 came back
  double max_push_force = 1000.0;   ///< pushes from poise/disturbance above this are refused [N]
  double max_push_duration = 5.0;   ///< ... and longer than this [s]
};

/// Everything one run measures (the node's summary).
struct Figures {
  node::LatencyHistogram latency;
  node::LatencyHistogram loop_wait;
  node::LatencyHistogram publish;  ///< publishing sensors + ground truth of one tick  ///< sensors
                                   ///< k published -> the loop holds command k
  std::uint64_t ticks = 0, command_timeouts = 0, rejected_commands = 0, damping_ticks = 0,
                hold_ticks = 0, estop_ticks = 0;
  std::uint64_t overruns = 0, pushes = 0, refused_pushes = 0,
                total_other_contacts = 0;
  std::uint64_t start_repeats = 0;  ///< real time, --start-when-answered: k0 sent again
  double wall_s = 0.0;
  double max_joint_speed = 0.0;  ///< largest |qd| of any joint over the run [rad/s | m/s]
  int fastest_joint = -1;
  bool aborted = false;
};

constexpr std::size_t kReferenceQueue = 512;  // balance references held ahead of their tick

class SimNode {
 public:
  SimNode(node::Node& node, const Settings& settings)
      : node_(node),
        settings_(settings),
        scenario_(sim::load_world(settings.scenario)),
        sim_(scenario_.sim),
        feet_(sim_node::foot_order(sim_)),
        monitor_(scenario_, sim::platforms_of_feet(scenario_)),
        slip_(sim_platforms()),
        sensors_(sim_.make_sensor_frame()),
        truth_(sim_.make_ground_truth()),
        safety_(make_safety_config(scenario_, sim_, settings)),
        disturbances_(node.participant()),
        estops_(node.participant(), node::robot_side_name("poise-" + node.name())),
        description_pub_(node.participant()),
        sensors_pub_(node.participant()),
        truth_pub_(node.participant()),
        publish_ns_(1024, 0),
        commands_in_(node.participant(),
                     [this](const msg::JointCommand& c, const dds::detail::SampleMeta& m) {
                       on_command_from(c, m.writer_id);
                     }),
        references_(
            node.participant(),
            [this](const msg::BalanceReference& r) {
              com_shift_.put(r.header().tick(), r.has_com_target(),
                             Eigen::Vector3d(r.com_W()[0], r.com_W()[1], r.com_W()[2]));
            },
            dds::Qos::latched(static_cast<int>(kReferenceQueue))) {
    node.watch(commands_in_);
    node.watch(references_);
    node.expect_one_writer(commands_in_);
    node.watch(disturbances_);
    node.watch(estops_.subscriber());
    applied_ = sim_.make_command();
    applied_.mode = sim::CommandMode::kPd;
    msg::RobotDescription description = sim_node::make_robot_description(scenario_, sim_, feet_);
    // The tick of the first frame the run publishes (k0, after settling): a recorder that joins
    // late still gets this latched sample, so a recording says how many ticks it missed.
    description.header().tick(static_cast<std::uint64_t>(sim_.tick() + settings_.settle_ticks));
    urdf_link_of_body_ = sim_node::urdf_link_index_of_bodies(description.urdf(), sim_.body_names());
    description_pub_.publish(description);
    settle();
    monitor_.update(truth_);
    slip_.update(truth_);
    dds::log(dds::LogLevel::info, "initial base height %.3f m, CoM (%.3f, %.3f, %.3f) m",
             truth_.X_WB.translation().z(), truth_.com_W.x(), truth_.com_W.y(), truth_.com_W.z());
    if (sim_.reality().enabled)
      dds::log(dds::LogLevel::info, "%s", sim::describe_reality(sim_.reality()).c_str());
  }

  const sim::World& scenario() const { return scenario_; }
  double duration() const {
    return settings_.duration > 0 ? settings_.duration : scenario_.duration;
  }

  /// Runs the scenario in the chosen mode. Returns false when aborted.
  bool run() {
    const auto steps = static_cast<std::int64_t>(std::llround(duration() / sim_.dt()));
    dds::log(dds::LogLevel::info, "%s: %d joints, %.1f s, %s", scenario_.name.c_str(),
             sim_.num_joints(), duration(), settings_.realtime ? "real time" : "lockstep");
    // Every expected reader first: what a reader (the estimator, a recorder) matches late misses
    // the first ticks of the run. A timeout is not fatal: the run starts with whoever is there.
    const auto startup = std::chrono::milliseconds(settings_.startup_timeout_ms);
    if (!sensors_pub_.wait_for_matches(settings_.wait_readers, startup) ||
        !truth_pub_.wait_for_matches(settings_.wait_truth_readers, startup))
      dds::log(dds::LogLevel::warn,
               "start-up: %d of %d sensors readers and %d of %d ground-truth readers matched "
               "after %d ms; starting anyway",
               sensors_pub_.matched(), settings_.wait_readers, truth_pub_.matched(),
               settings_.wait_truth_readers, settings_.startup_timeout_ms);
    if (!settings_.start_file.empty()) {
      const auto deadline = std::chrono::steady_clock::now() + startup;
      while (!std::filesystem::exists(settings_.start_file) &&
             std::chrono::steady_clock::now() < deadline && !node::shutdown_requested())
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      if (!std::filesystem::exists(settings_.start_file))
        dds::log(dds::LogLevel::warn, "start-up: no start file %s after %d ms; starting anyway",
                 settings_.start_file.c_str(), settings_.startup_timeout_ms);
    }
    if (settings_.realtime) {
      // The settled frame k0 first, and its acknowledgment by every matched reader: a reader
      // matched on this side only would miss the first ticks of the wall clock. (Lockstep
      // repeats k0 until the loop answers, which proves the same for the loop's readers.)
      start_tick_.store(sensors_.tick);
      const std::int64_t t_start = node::now_ns();
      publish_tick();
      if (!sensors_pub_.wait_for_acknowledgments(startup) ||
          !truth_pub_.wait_for_acknowledgments(startup))
        dds::log(dds::LogLevel::warn, "start-up: frame %lld not acknowledged by every reader",
                 static_cast<long long>(sensors_.tick));
      if (settings_.start_when_answered && !wait_for_answer(t_start)) return false;
    }
    return settings_.realtime ? run_realtime(steps) : run_lockstep(steps);
  }

  /// One-line JSON of the run's figures and the monitor's verdict.
  std::string result_json() const {
    const sim::ScenarioMonitor::Result r = monitor_.result();
    const double sim_s = static_cast<double>(figures_.ticks) * sim_.dt();
    auto hist = [](const node::LatencyHistogram& h) {
      return nlohmann::json{{"p50", h.percentile(0.5)},
                            {"p99", h.percentile(0.99)},
                            {"max", h.max()},
                            {"mean", h.mean()},
                            {"count", h.count()}};
    };
    nlohmann::json j;
    j["scenario"] = scenario_.name;
    j["mode"] = settings_.realtime ? "realtime" : "lockstep";
    j["completed"] = !figures_.aborted;
    j["survived"] = r.survived && !figures_.aborted;
    j["com_error_max_m"] = r.com_error_max_m;
    j["com_error_final_m"] = r.com_error_final_m;
    j["foot_slip_max_m"] = r.foot_slip_max_m;
    j["foot_slide_max_m"] = r.foot_slide_max_m;
    j["foot_displacement_max_m"] = r.foot_displacement_max_m;
    j["foot_tilt_max_deg"] = r.foot_tilt_max_deg;
    j["non_foot_contacts"] = r.non_foot_contacts;
    j["min_base_height_m"] = std::isfinite(r.min_base_height_m) ? r.min_base_height_m : -1.0;
    j["last_recovery_time_s"] =
        std::isfinite(r.last_recovery_time_s) ? r.last_recovery_time_s : -1.0;
    // The same fields as `poise run --in-process` writes.
    j["recovery_time_s"] = std::isfinite(r.last_recovery_time_s)
                               ? nlohmann::json(r.last_recovery_time_s)
                               : nlohmann::json(nullptr);
    j["trunk_pitch_max_deg"] = r.trunk_pitch_max_deg;
    j["trunk_roll_max_deg"] = r.trunk_roll_max_deg;
    j["failed_criteria"] = monitor_.failed_criteria();
    j["reality"] = sim::reality_to_json(sim_.reality());
    // poise/balance_reference as the monitor took it: references not taken (a non-finite CoM
    // target) or dropped from a full queue; both 0 in a sound run.
    j["reference_com_rejected"] = com_shift_.rejected();
    j["reference_com_overflows"] = com_shift_.overflows();
    if (figures_.aborted) j["failed_criteria"].push_back("run aborted before its end");
    j["tick_latency_us"] = hist(figures_.latency);
    j["loop_wait_us"] = hist(figures_.loop_wait);
    j["publish_us"] = hist(figures_.publish);
    j["command_timeouts"] = figures_.command_timeouts;
    j["start_repeats"] = figures_.start_repeats;
    j["rejected_commands"] = figures_.rejected_commands;
    j["foreign_commands"] = foreign_.refused();  // from a second writer, refused
    j["command_writer_handovers"] = writer_handovers_.load();  // a restarted controller adopted
    j["damping_ticks"] = figures_.damping_ticks;
    const safety::Counters& sc = safety_.counters();
    j["watchdog_stale_events"] = sc.hold_events;
    j["hold_ticks"] = figures_.hold_ticks;
    j["estop_ticks"] = figures_.estop_ticks;
    j["safety"] = safety::counters_to_json(sc, safety_.mode());
    j["overruns"] = figures_.overruns;
    j["max_joint_speed"] = {
        {"joint", figures_.fastest_joint >= 0 ? sim_.joint_names()[static_cast<std::size_t>(
                                                    figures_.fastest_joint)]
                                              : std::string()},
        {"speed", figures_.max_joint_speed}};
    j["pushes_received"] = figures_.pushes;
    j["pushes_refused"] = figures_.refused_pushes;
    j["sim_time_s"] = sim_s;
    j["wall_time_s"] = figures_.wall_s;
    j["realtime_factor"] = figures_.wall_s > 0 ? sim_s / figures_.wall_s : 0.0;
    return j.dump();
  }

 private:
  /// The safety layer of this robot: gains from the scenario's robot configuration (or the
  /// URDF alone), bounded by each joint's inertia.
  static safety::Config make_safety_config(const sim::World& scenario, const sim::Simulator& sim,
                                           const Settings& settings) {
    std::unique_ptr<model::RobotConfig> robot;
    model::Model model;
    if (!scenario.robot_config.empty()) {
      robot = std::make_unique<model::RobotConfig>(model::load_robot_config(scenario.robot_config));
      model = model::load_robot_model(*robot);
    } else {
      model = model::build_model_from_urdf_file(scenario.sim.robot.urdf_path);
    }
    safety::Config c =
        safety::make_config(model, robot.get(), sim.joint_names(), sim.dt(), sim.damping_kd());
    for (const std::string& w : c.warnings)
      dds::log(dds::LogLevel::warn, "safety: %s", w.c_str());
    c.watchdog_s = settings.watchdog_ms * 1e-3;
    c.hold_s = settings.hold_s;
    return c;
  }

  /// Safety layer command -> simulator command (kPd: the same law).
  void apply_safety(const safety::Command& c) noexcept { sim_node::to_sim(c, applied_); }

  /// Start-up: the safety layer holds the initial posture for --settle-ticks steps, so that the
  /// first frame the components see measures the feet loaded.
  void settle() {
    sim_.read(sensors_, truth_);
    safety_.start(sensors_.q, node::now_ns(), true);
    for (int i = 0; i < settings_.settle_ticks; ++i) {
      apply_safety(safety_.update(node::now_ns(), sensors_.q));
      sim_.step(applied_, sensors_, truth_);
    }
    safety_.start(sensors_.q, node::now_ns());  // hold where it settled until the first command
  }

  /// E-stops, then the safety layer's command for this tick; mode changes logged and reported.
  const safety::Command& safety_command() noexcept {
    report_foreign_commands();
    while (const msg::EStop* e = estops_.take()) {
      safety_.on_estop(e->engaged(), safety::to_stop(e->kind()), e->reason().c_str(), sensors_.q,
                       node::now_ns());
      estops_.acknowledge(*e, safety_.stopped(), safety::held_stop(safety_.mode()),
                          static_cast<std::uint64_t>(sensors_.tick));
      note_safety_mode();
    }
    const safety::Command& c = safety_.update(node::now_ns(), sensors_.q);
    note_safety_mode();
    switch (safety_.mode()) {
      case safety::Mode::kHold: ++figures_.hold_ticks; break;
      case safety::Mode::kDamp: ++figures_.damping_ticks; break;
      case safety::Mode::kEStop:
        ++figures_.damping_ticks;
        ++figures_.estop_ticks;
        break;
      default: break;
    }
    return c;
  }

  /// Reports the safety layer's mode: the node's health condition at once, and a log line at
  /// most every 100 ms with the newest mode and the transitions in between (flapping cannot
  /// flood the log; the mode that lasts is always logged). Called every tick.
  void note_safety_mode() noexcept {
    const safety::Mode mode = safety_.mode();
    if (mode != noted_mode_) {
      noted_mode_ = mode;
      ++mode_transitions_;
      const safety::ModeReport report = safety::report(mode);
      if (!foreign_.faulted()) node_.set_condition(report.health, report.text);
    }
    if (mode == logged_mode_) return;
    const std::int64_t now = node::now_ns();
    if (now - last_mode_log_ns_ < 100'000'000) return;
    last_mode_log_ns_ = now;
    logged_mode_ = mode;
    dds::log(mode == safety::Mode::kActive ? dds::LogLevel::info : dds::LogLevel::warn,
             "safety: %s at t=%.3f s (%s; %llu transitions since the last line)",
             safety::to_string(mode), sensors_.time,
             mode == safety::Mode::kActive ? "joint commands fresh: control resumed"
                                           : safety_.last_error(),
             static_cast<unsigned long long>(mode_transitions_));
    mode_transitions_ = 0;
  }

  std::vector<int> sim_platforms() const {
    // platforms_of_feet() is indexed like the scenario's feet, which is the simulator's order.
    return sim::platforms_of_feet(scenario_);
  }

  /// Sensors first (they start the loop), then the ground truth, while the others compute.
  void publish_tick() noexcept {
    const std::int64_t sensors_ns = publish_sensors();
    publish_truth(sensors_ns);
  }

  /// Sensors of the current tick; returns the time it took [ns].
  std::int64_t publish_sensors() noexcept {
    const std::int64_t t0 = node::now_ns();
    sim_node::to_msg(sensors_, feet_, sensors_msg_);
    node_.publish(sensors_pub_, sensors_msg_);
    const std::int64_t t1 = node::now_ns();
    publish_ns_[static_cast<std::size_t>(sensors_.tick) % publish_ns_.size()] = t1;
    return t1 - t0;
  }

  /// Ground truth of the current tick (needs observe() done for it), while a reader is matched:
  /// with nobody to send it to, its conversion and write are saved. `sensors_ns`: the time the
  /// sensors of the tick took to publish (figures).
  void publish_truth(std::int64_t sensors_ns) noexcept {
    const std::int64_t t0 = node::now_ns();
    if (truth_pub_.matched() > 0) {
      sim_node::to_msg(truth_, feet_, slip_, urdf_link_of_body_, figures_.total_other_contacts,
                       truth_msg_);
      node_.publish(truth_pub_, truth_msg_);
    }
    figures_.publish.add(static_cast<double>(sensors_ns + node::now_ns() - t0) * 1e-3);
  }

  void step_and_observe(const sim::JointCommand& command) noexcept {
    step(command);
    observe();
  }

  void step(const sim::JointCommand& command) noexcept {
    const std::int64_t t0 = node::now_ns();
    if (sim_.step(command, sensors_, truth_) != sim::StepStatus::kOk) {
      ++figures_.rejected_commands;
      node_.error("tick %lld: command rejected by the simulator (size or non-finite): damped",
                  static_cast<long long>(sensors_.tick));
    }
    node_.tick_done(static_cast<std::uint64_t>(sensors_.tick), node::now_ns() - t0);
  }

  /// Everything after a step that the loop does not wait for: the monitor, foot slip, pushes,
  /// progress.
  void observe() noexcept {
    if (truth_.num_non_foot_contacts > 0) ++figures_.total_other_contacts;
    for (Eigen::Index j = 0; j < sensors_.qd.size(); ++j)  // an exploding joint shows here
      if (std::abs(sensors_.qd[j]) > figures_.max_joint_speed) {
        figures_.max_joint_speed = std::abs(sensors_.qd[j]);
        figures_.fastest_joint = static_cast<int>(j);
      }
    monitor_.set_com_target_shift(
        com_shift_.due(static_cast<std::uint64_t>(std::max<std::int64_t>(0, sensors_.tick - 1))));
    monitor_.update(truth_);
    slip_.update(truth_);
    ++figures_.ticks;
    apply_disturbances();
    if (settings_.progress && sensors_.tick % 1000 == 0) {
      const auto r = monitor_.result();
      std::printf(
          "progress t=%.1f s com_error=%.4f m com_error_max=%.4f m base_z=%.3f m "
          "latency_p50=%.0f us\n",
          sensors_.time, r.com_error_final_m, r.com_error_max_m, truth_.X_WB.translation().z(),
          figures_.latency.percentile(0.5));
      std::fflush(stdout);
    }
  }

  void apply_disturbances() noexcept {
    while (disturbances_.take(disturbance_)) {
      ++figures_.pushes;
      if (!sim_node::from_msg(disturbance_, sim_.time(), push_)) {
        node_.error("disturbance %u refused (kind %d, link '%s')", disturbance_.id(),
                    static_cast<int>(disturbance_.kind()), disturbance_.link().c_str());
      } else if (!(push_.force_W.norm() <= settings_.max_push_force) ||
                 !(push_.duration <= settings_.max_push_duration)) {
        // Anyone on the domain can publish a disturbance: a limit keeps a typo or a forged
        // sample from throwing the robot across the room.
        ++figures_.refused_pushes;
        node_.error("disturbance %u refused: %.3g N for %.3g s exceeds the limit (%.0f N, %.1f s; "
                    "--max-push-force, --max-push-duration)",
                    disturbance_.id(), push_.force_W.norm(), push_.duration,
                    settings_.max_push_force, settings_.max_push_duration);
      } else if (!sim_.add_push(push_)) {
        node_.error("disturbance %u refused (kind %d, link '%s')", disturbance_.id(),
                    static_cast<int>(disturbance_.kind()), disturbance_.link().c_str());
      } else
        dds::log(dds::LogLevel::info, "push %u: %.1f N on %s for %.3f s at t=%.3f s",
                 disturbance_.id(), push_.force_W.norm(), push_.link.c_str(), push_.duration,
                 push_.start);
    }
  }

  /// Takes the newest command if it is new. Returns true for a new command (not yet checked).
  bool take_command(std::int64_t* arrival_ns) noexcept {
    return command_box_.take(command_msg_, command_seen_, arrival_ns);
  }

  /// The safety layer's verdict on the command just taken (robot at tick `robot_tick`).
  bool accept_command(std::int64_t robot_tick, std::int64_t arrival_ns) noexcept {
    if (safety_.on_command(command_msg_, robot_tick, arrival_ns)) {
      note_safety_mode();
      return true;
    }
    if (!safety_.stopped()) {
      ++figures_.rejected_commands;
      node_.error("%s", safety_.last_error());
    }
    return false;
  }

  // Lockstep: the command of tick k is taken, the simulator stepped and sensors k+1 published in
  // the command callback, on the DDS listener thread as the command arrives (no wake-up of the
  // main thread per tick). The main thread publishes the diagnostics, repeats tick 0 at start-up
  // and handles a command timeout. Both under lockstep_mutex_.
  struct Lockstep {
    bool active = false;  ///< waiting for command k
    bool done = false;
    std::int64_t i = 0, steps = 0;
    std::uint64_t k = 0;
    std::int64_t t_pub = 0, wall0 = 0;
    int consecutive = 0;
  };

  /// One commanding writer (safety::CommandWriterGate), on the listener thread: a command from
  /// another writer while the commanding one is alive is refused and counted; the loop thread
  /// reports it (report_foreign_commands).
  void on_command_from(const msg::JointCommand& c, std::uint64_t writer) noexcept {
    switch (writer_gate_.check(
        writer, [this] { return commands_in_.matched(); }, node::now_ns())) {
      case safety::CommandWriterGate::Verdict::kForeign:
        foreign_.refuse(writer, writer_gate_.owner());
        return;
      case safety::CommandWriterGate::Verdict::kAdopted:
        writer_handovers_.fetch_add(1, std::memory_order_relaxed);
        break;
      default: break;
    }
    on_command(c);
  }

  /// Loop thread: a FAULT naming both writers once commands from a second writer were refused
  /// (latched for the rest of the run, which fails: deploy/launch).
  void report_foreign_commands() noexcept {
    if (const char* text = foreign_.news()) {
      node_.set_condition(msg::HEALTH_FAULT, text);
      node_.error("%s", text);
    }
  }

  void on_command(const msg::JointCommand& c) noexcept {
    command_box_.put(c);
    if (settings_.realtime) {  // the loop thread takes the newest at its tick
      if (static_cast<std::int64_t>(c.header().tick()) == start_tick_.load())
        start_answered_.store(true);
      return;
    }
    std::lock_guard lock(lockstep_mutex_);
    take_lockstep_commands();
  }

  /// Lockstep, under lockstep_mutex_: takes the commands that came and finishes tick k with the
  /// one for it.
  void take_lockstep_commands() noexcept {
    std::int64_t arrival = 0;
    while (lockstep_.active && take_command(&arrival))
      if (command_msg_.header().tick() == lockstep_.k) {
        accept_command(static_cast<std::int64_t>(lockstep_.k), arrival);
        finish_tick(true, arrival);  // a rejected command: the safety layer holds
      }
  }

  /// Publishes sensors k (the current tick) and waits for its command.
  void start_tick() noexcept {
    lockstep_.k = static_cast<std::uint64_t>(sensors_.tick);
    publish_tick();
    lockstep_.t_pub = node::now_ns();
    lockstep_.active = true;
  }

  void end_lockstep() noexcept {
    lockstep_.active = false;
    lockstep_.done = true;
    lockstep_wake_.notify_one();
  }

  /// Tick k with its command (`got`, received at `arrival`) or after a timeout (damping), then
  /// the next tick. Under lockstep_mutex_.
  void finish_tick(bool got, std::int64_t arrival) noexcept {
    Lockstep& ls = lockstep_;
    ls.active = false;
    if (ls.i == 0) ls.wall0 = node::now_ns();
    if (got) {
      ls.consecutive = 0;
      const std::int64_t published = publish_ns_[ls.k % publish_ns_.size()];
      figures_.latency.add(static_cast<double>(arrival - published) * 1e-3);
      figures_.loop_wait.add(static_cast<double>(node::now_ns() - published) * 1e-3);
    } else {
      ++figures_.command_timeouts;
      node_.deadline_miss();
      node_.error("tick %llu: no joint command within %d ms: safety layer %s",
                  static_cast<unsigned long long>(ls.k),
                  ls.i == 0 ? settings_.startup_timeout_ms : settings_.command_timeout_ms,
                  safety::to_string(safety_.mode()));
      if (++ls.consecutive >= settings_.max_consecutive_timeouts) {
        node_.error("%d ticks in a row without a command: giving up", ls.consecutive);
        figures_.aborted = true;
        end_lockstep();
        return;
      }
    }
    apply_safety(safety_command());
    step(applied_);
    if (++ls.i >= ls.steps || !node_.running()) {
      observe();
      end_lockstep();
      return;
    }
    // Sensors k+1 first: the others compute while this thread observes the step.
    ls.k = static_cast<std::uint64_t>(sensors_.tick);
    const std::int64_t sensors_ns = publish_sensors();
    ls.t_pub = node::now_ns();
    ls.active = true;
    observe();
    publish_truth(sensors_ns);
  }

  bool run_lockstep(std::int64_t steps) {
    std::unique_lock lock(lockstep_mutex_);
    lockstep_ = Lockstep{};
    lockstep_.steps = steps;
    if (steps <= 0) lockstep_.done = true;
    if (!lockstep_.done) {
      start_tick();
      take_lockstep_commands();  // any that came before
    }
    std::int64_t next_repeat = lockstep_.t_pub + 100'000'000;
    while (!lockstep_.done) {
      if (!node_.running()) {
        lockstep_.active = false;
        break;
      }
      const std::int64_t now = node::now_ns();
      const std::int64_t timeout_ns =
          std::int64_t{lockstep_.i == 0 ? settings_.startup_timeout_ms
                                        : settings_.command_timeout_ms} *
          1'000'000;
      if (now >= lockstep_.t_pub + timeout_ns) {
        finish_tick(false, 0);
        continue;
      }
      if (lockstep_.i == 0 && now >= next_repeat) {
        publish_tick();  // start-up: the loop may not be connected yet
        next_repeat += 100'000'000;
      }
      std::int64_t until = std::min(lockstep_.t_pub + timeout_ns, node_.poll());
      if (lockstep_.i == 0) until = std::min(until, next_repeat);
      lockstep_wake_.wait_until(
          lock, std::chrono::steady_clock::time_point(std::chrono::nanoseconds(until)));
    }
    node_.poll();
    const std::int64_t end = node::now_ns();
    figures_.wall_s = static_cast<double>(end - (lockstep_.wall0 ? lockstep_.wall0 : end)) * 1e-9;
    if (!node_.running() && figures_.ticks < static_cast<std::uint64_t>(steps))
      figures_.aborted = true;
    return !figures_.aborted;
  }

  /// Real-time start-up (--start-when-answered): frame k0 again every 100 ms until a joint
  /// command for k0 came back. False when the run was interrupted meanwhile; a timeout is not
  /// fatal (the run starts, the safety layer holds until commands come).
  bool wait_for_answer(std::int64_t t_start) {
    const std::int64_t end =
        t_start + std::int64_t{settings_.startup_timeout_ms} * 1'000'000;
    std::int64_t next_repeat = node::now_ns() + 100'000'000;
    int repeats = 0;
    while (!start_answered_.load()) {
      if (!node_.running()) return false;
      const std::int64_t now = node::now_ns();
      if (now >= end) {
        dds::log(dds::LogLevel::warn,
                 "start-up: no joint command for frame %lld within %d ms (%d repeats); starting "
                 "anyway (the safety layer holds until commands come)",
                 static_cast<long long>(sensors_.tick), settings_.startup_timeout_ms, repeats);
        return true;
      }
      if (now >= next_repeat) {
        publish_tick();
        ++repeats;
        next_repeat += 100'000'000;
      }
      node_.poll();
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    figures_.start_repeats = static_cast<std::uint64_t>(repeats);
    dds::log(dds::LogLevel::info, "start-up: the loop answered frame %lld after %.1f ms (%d repeats)",
             static_cast<long long>(sensors_.tick),
             static_cast<double>(node::now_ns() - t_start) * 1e-6, repeats);
    return true;
  }

  bool run_realtime(std::int64_t steps) {
    node::TickTimer timer(static_cast<std::int64_t>(sim_.dt() * 1e9));
    timer.start();
    const std::int64_t wall0 = node::now_ns();
    for (std::int64_t i = 0; i < steps && node_.running(); ++i) {
      std::int64_t arrival = 0;
      while (take_command(&arrival)) {  // newest command, if one came
        if (!accept_command(sensors_.tick, arrival)) continue;
        const auto kc = static_cast<std::uint64_t>(command_msg_.header().tick());
        if (kc <= static_cast<std::uint64_t>(sensors_.tick) &&
            static_cast<std::uint64_t>(sensors_.tick) - kc < publish_ns_.size())
          figures_.latency.add(static_cast<double>(arrival - publish_ns_[kc % publish_ns_.size()]) *
                               1e-3);
      }
      apply_safety(safety_command());
      step_and_observe(applied_);
      publish_tick();
      node_.poll();
      timer.wait_next();
    }
    figures_.overruns = timer.overruns();
    figures_.wall_s = static_cast<double>(node::now_ns() - wall0) * 1e-9;
    figures_.aborted = figures_.ticks < static_cast<std::uint64_t>(steps);
    return !figures_.aborted;
  }

  node::Node& node_;
  Settings settings_;
  sim::World scenario_;
  sim::Simulator sim_;
  sim_node::FootOrder feet_;
  sim::ScenarioMonitor monitor_;
  sim_node::SlipTracker slip_;
  std::vector<std::int32_t> urdf_link_of_body_;  ///< GroundTruth.other_contact_links numbering
  sim::SensorFrame sensors_;
  sim::GroundTruth truth_;
  sim::JointCommand applied_;
  safety::SafetyLayer safety_;
  safety::Mode noted_mode_ = safety::Mode::kStartup, logged_mode_ = safety::Mode::kStartup;
  std::uint64_t mode_transitions_ = 0;
  std::int64_t last_mode_log_ns_ = 0;
  sim::Push push_;
  node::Mailbox<msg::JointCommand> command_box_;
  std::uint64_t command_seen_ = 0;
  std::atomic<std::int64_t> start_tick_{-1};  ///< real time: frame k0 (-1 before it is sent)
  std::atomic<bool> start_answered_{false};      ///< a command for k0 came
  std::mutex lockstep_mutex_;
  std::condition_variable lockstep_wake_;  ///< the lockstep run ended
  Lockstep lockstep_;
  dds::Subscriber<msg::Disturbance> disturbances_;
  node::EStopChannel estops_;
  safety::CommandWriterGate writer_gate_;  // the DDS listener thread's
  safety::ForeignCommands foreign_;
  std::atomic<std::uint64_t> writer_handovers_{0};
  dds::Publisher<msg::RobotDescription> description_pub_;
  dds::Publisher<msg::Sensors> sensors_pub_;
  dds::Publisher<msg::GroundTruth> truth_pub_;
  msg::Sensors sensors_msg_;
  msg::GroundTruth truth_msg_;
  msg::JointCommand command_msg_;
  msg::Disturbance disturbance_;
  std::vector<std::int64_t> publish_ns_;  ///< publication time of sensors k, ring by k
  Figures figures_;
  // The CoM target shifts of poise/balance_reference, for the monitor (ScenarioMonitor's CoM
  // error does not count a reference's deliberate CoM move).
  sim::ReferenceComShift com_shift_{2 * kReferenceQueue};
  // Last: their callbacks use the members above, and they go first.
  dds::Subscriber<msg::JointCommand> commands_in_;
  dds::Subscriber<msg::BalanceReference> references_;
};

int run(int argc, char** argv) {
  node::NodeOptions options;
  Settings s;
  CLI::App app{"Simulator node: runs a scenario and speaks the robot side of the Poise topics."};
  node::add_node_options(app, options, "sim");
  app.add_option("scenario", s.scenario, "scenario YAML file")
      ->required()
      ->check(CLI::ExistingFile);
  bool lockstep_flag = false;
  auto* lock =
      app.add_flag("--lockstep", lockstep_flag, "step k+1 only after command k arrived (default)");
  app.add_flag("--realtime", s.realtime, "1 kHz on the wall clock, newest command, watchdog")
      ->excludes(lock);
  app.add_option("--duration", s.duration, "override the scenario duration [s]");
  app.add_option("--command-timeout-ms", s.command_timeout_ms,
                 "lockstep: longest wait for the command of a tick")
      ->capture_default_str();
  app.add_option("--startup-timeout-ms", s.startup_timeout_ms,
                 "longest wait for the first command (loop start-up)")
      ->capture_default_str();
  app.add_option("--max-consecutive-timeouts", s.max_consecutive_timeouts,
                 "lockstep: give up after this many ticks in a row without a command")
      ->capture_default_str();
  app.add_option("--watchdog-ms", s.watchdog_ms,
                 "safety layer: HOLD after this long without an accepted command")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 60000.0));
  app.add_option("--hold-s", s.hold_s,
                 "safety layer: hold the last joint targets this long, then damp (0: damp at once)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  app.add_flag("--progress", s.progress, "print a progress line every simulated second");
  app.add_option("--wait-readers", s.wait_readers,
                 "start-up: poise/sensors readers to wait for (at most --startup-timeout-ms) "
                 "before the first tick")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  app.add_flag("--start-when-answered", s.start_when_answered,
              "real time: repeat the first frame every 100 ms until a joint command for it comes "
              "back (at most --startup-timeout-ms), then start the wall clock, so that every "
              "link of the loop works before the first deadline (what poise run and poise "
              "launch use)");
  app.add_option("--wait-truth-readers", s.wait_truth_readers,
                 "start-up: poise/ground_truth readers to wait for (a recorder, a test)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  app.add_option("--start-file", s.start_file,
                 "start-up: wait (at most --startup-timeout-ms) until this file exists before the "
                 "first tick: a launcher's go signal, e.g. once a recorder matched every writer");
  app.add_option("--max-push-force", s.max_push_force,
                 "pushes received on poise/disturbance stronger than this are refused and "
                 "counted [N] (the scenario's own pushes are not limited)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--max-push-duration", s.max_push_duration,
                 "... and longer than this [s]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--settle-ticks", s.settle_ticks,
                 "start-up: steps with the joints held by PD before the first sensor frame, so "
                 "that it measures the feet loaded")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  POISE_CLI_PARSE(app, argc, argv);
  // The robot configuration comes from the scenario; --robot is ignored by this node.

  node::Node node(options);
  SimNode sim(node, s);
  const bool ok = sim.run();
  const std::string result = sim.result_json();
  std::printf("poise-sim result %s\n", result.c_str());
  std::fflush(stdout);
  node.write_summary(result);
  return ok ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-sim: %s\n", e.what());
    return 2;
  }
}
