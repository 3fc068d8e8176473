#include "poise/estimator_bench/wire_accuracy.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>
#include <thread>
#include <unordered_map>

#include <poise/dds/topics.hpp>
#include <poise/msg/ground_truth.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/state.h>

#include "poise/model/data.hpp"
#include "poise/model/kinematics.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/record/mcap_reader.hpp"
#include "poise/sim/world.hpp"

namespace poise::estimator_bench {
namespace {

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

template <class A>
Vector3d v3(const A& a) {
  return Vector3d(a[0], a[1], a[2]);
}
template <class A>
Quaterniond quat(const A& a) {
  return Quaterniond(a[0], a[1], a[2], a[3]).normalized();
}

struct StateSample {
  std::uint32_t flags = 0;
  Vector3d p, v, com, vcom;
  Quaterniond q;
  std::array<Vector3d, 2> foot_p, foot_v;
  std::vector<double> joints_q, joints_qd;  // wire order
};
struct TruthSample {
  Vector3d p, v, w, com, vcom;
  Quaterniond q;
  std::array<bool, 2> contact{false, false};
  bool other_contact = false;  ///< a link other than the feet touches something
  double stamp_s = 0.0;
};

template <class T>
bool decode(const record::MessageView& m, T& out) {
  char why[256] = {};
  return dds::TopicTraits<T>::type_support().deserialize(m.data.data(), m.data.size(), &out, why,
                                                         sizeof(why));
}

// Velocities of the true feet: central differences over +-kHalf ticks (the encoders' qd is the
// drive's filtered velocity: using it would put the filter's lag into the truth).
constexpr int kHalf = 5;

// What the analysis takes from a recording, by tick.
struct Recording {
  std::vector<std::string> wire_joints;
  std::map<std::uint64_t, StateSample> states;
  std::map<std::uint64_t, TruthSample> truths;
};

StateSample state_sample(const msg::State& st) {
  StateSample s;
  s.flags = st.status_flags();
  s.p = v3(st.base_W().position());
  s.q = quat(st.base_W().orientation_wxyz());
  s.v = v3(st.base_velocity_W().linear());
  s.com = v3(st.com_W());
  s.vcom = v3(st.com_velocity_W());
  for (int f = 0; f < 2; ++f) {
    s.foot_p[f] = v3(st.feet()[f].pose_W().position());
    s.foot_v[f] = v3(st.feet()[f].velocity_W().linear());
  }
  s.joints_q.assign(st.q().begin(), st.q().begin() + st.joint_count());
  s.joints_qd.assign(st.qd().begin(), st.qd().begin() + st.joint_count());
  return s;
}

TruthSample truth_sample(const msg::GroundTruth& gt) {
  TruthSample t;
  t.p = v3(gt.base_W().position());
  t.q = quat(gt.base_W().orientation_wxyz());
  t.v = v3(gt.base_velocity_W().linear());
  t.w = v3(gt.base_velocity_W().angular());
  t.com = v3(gt.com_W());
  t.vcom = v3(gt.com_velocity_W());
  for (int f = 0; f < 2; ++f)
    t.contact[f] = gt.feet()[f].in_contact();
  t.stamp_s = 1e-9 * static_cast<double>(gt.header().stamp_ns());
  t.other_contact = gt.other_contact_count() > 0;
  return t;
}

// poise/state, poise/ground_truth and the first poise/robot_description of the file into `rec`.
record::ScanResult read_recording(const std::string& mcap, Recording& rec) {
  std::map<std::uint16_t, std::string> topic_of;
  msg::State st;
  msg::GroundTruth gt;
  msg::RobotDescription desc;
  record::ScanHandlers h;
  h.on_channel = [&](const record::ChannelRecord& c) { topic_of[c.id] = c.topic; };
  h.on_message = [&](const record::MessageView& m) {
    const std::string& topic = topic_of[m.channel_id];
    if (topic == "poise/state") {
      if (!decode(m, st)) return true;
      rec.states[st.header().tick()] = state_sample(st);
    } else if (topic == "poise/ground_truth") {
      if (!decode(m, gt)) return true;
      rec.truths[gt.header().tick()] = truth_sample(gt);
    } else if (topic == "poise/robot_description" && rec.wire_joints.empty()) {
      if (decode(m, desc))
        rec.wire_joints.assign(desc.joint_names().begin(), desc.joint_names().end());
    }
    return true;
  };
  return record::scan(mcap, h);
}

// Wire index of each model joint; "" or the error (a model joint missing from the wire).
std::string wire_indices(const model::Model& model, const std::vector<std::string>& wire_joints,
                         std::vector<int>& wire_of) {
  wire_of.assign(model.joint_names.size(), -1);
  for (std::size_t j = 0; j < model.joint_names.size(); ++j)
    for (std::size_t w = 0; w < wire_joints.size(); ++w)
      if (wire_joints[w] == model.joint_names[j]) wire_of[j] = static_cast<int>(w);
  for (std::size_t j = 0; j < wire_of.size(); ++j)
    if (wire_of[j] < 0)
      return "joint '" + model.joint_names[j] + "' is not in the robot description";
  return "";
}

// True foot positions of every tick with both topics: forward kinematics with the base at
// identity and the encoders' q, then the true base pose.
std::map<std::uint64_t, std::array<Vector3d, 2>> true_foot_positions(
    const model::Model& model, const model::RobotConfig& robot, const Recording& rec,
    const std::vector<int>& wire_of) {
  model::Data data(model);
  const std::array<int, 2> foot_frame{model.frame_id(robot.feet[0].frame),
                                      model.frame_id(robot.feet[1].frame)};
  Eigen::VectorXd q = model.neutral(), v = Eigen::VectorXd::Zero(model.nv);
  std::map<std::uint64_t, std::array<Vector3d, 2>> true_feet;
  for (const auto& [tick, s] : rec.states) {
    const auto it = rec.truths.find(tick);
    if (it == rec.truths.end() || s.joints_q.size() != rec.wire_joints.size()) continue;
    for (std::size_t j = 0; j < wire_of.size(); ++j)
      q[7 + static_cast<Eigen::Index>(j)] = s.joints_q[static_cast<std::size_t>(wire_of[j])];
    model::forward_kinematics(model, data, q, v);
    std::array<Vector3d, 2> p;
    for (int f = 0; f < 2; ++f)
      p[f] = it->second.p + it->second.q * model::frame_placement(model, data, foot_frame[f]).p;
    true_feet[tick] = p;
  }
  return true_feet;
}

// Errors in the world frame of one tick, `time` s into the run; the drift at the next of
// acc.drift_t once reached.
void add_world_errors(Accuracy& acc, const StateSample& s, const TruthSample& t, double time,
                      int& next_drift) {
  acc.base_pos.add((s.p - t.p).norm());
  if (time < 2.0) acc.base_pos_early.add((s.p - t.p).norm());
  acc.base_vel.add((s.v - t.v).norm());
  acc.com_pos.add((s.com - t.com).norm());
  acc.com_vel.add((s.vcom - t.vcom).norm());
  const Matrix3d R_est = s.q.toRotationMatrix(), R_true = t.q.toRotationMatrix();
  acc.attitude_deg.add(Eigen::AngleAxisd(R_est.transpose() * R_true).angle() * kRadToDeg);
  const double c = std::clamp(R_est.col(2).dot(R_true.col(2)), -1.0, 1.0);
  acc.tilt_deg.add(std::acos(c) * kRadToDeg);
  // (a run of D s ends at its tick D/dt - 1: 5 ms of tolerance)
  while (next_drift < 3 && time >= acc.drift_t[next_drift] - 0.005) {
    acc.base_drift[next_drift] = (s.p - t.p).norm();
    acc.com_drift[next_drift] = (s.com - t.com).norm();
    ++next_drift;
  }
}

// Errors relative to the supporting feet (truth's contact flags) of one tick with support.
void add_relative_errors(Accuracy& acc, const StateSample& s, const TruthSample& t,
                         std::uint64_t tick, const Recording& rec,
                         std::map<std::uint64_t, std::array<Vector3d, 2>>& true_feet) {
  const auto before = true_feet.find(tick - kHalf), after = true_feet.find(tick + kHalf);
  if (before == true_feet.end() || after == true_feet.end()) return;  // run's ends
  const double span = rec.truths.at(tick + kHalf).stamp_s - rec.truths.at(tick - kHalf).stamp_s;
  if (!(span > 0.0)) return;
  Vector3d sup_est = Vector3d::Zero(), sup_vest = Vector3d::Zero();
  Vector3d sup_true = Vector3d::Zero(), sup_vtrue = Vector3d::Zero();
  int n = 0;
  for (int f = 0; f < 2; ++f) {
    if (!t.contact[f]) continue;
    sup_true += true_feet[tick][f];
    sup_vtrue += (after->second[f] - before->second[f]) / span;
    sup_est += s.foot_p[f];
    sup_vest += s.foot_v[f];
    ++n;
  }
  sup_est /= n;
  sup_vest /= n;
  sup_true /= n;
  sup_vtrue /= n;
  acc.rel_com_pos.add(((s.com - sup_est) - (t.com - sup_true)).norm());
  acc.rel_com_vel.add(((s.vcom - sup_vest) - (t.vcom - sup_vtrue)).norm());
  acc.rel_base_pos.add(((s.p - sup_est) - (t.p - sup_true)).norm());
  acc.rel_base_vel.add(((s.v - sup_vest) - (t.v - sup_vtrue)).norm());
}

// Every tick with both topics, from the first, until a link other than the feet touches
// something (a fall).
void compare_to_truth(Accuracy& acc, const Recording& rec,
                      std::map<std::uint64_t, std::array<Vector3d, 2>>& true_feet) {
  bool have_t0 = false;
  double t0 = 0.0;
  int next_drift = 0;
  for (int i = 0; i < 3; ++i)
    acc.base_drift[i] = acc.com_drift[i] = kNaN;
  for (const auto& [tick, s] : rec.states) {
    const auto it = rec.truths.find(tick);
    if (it == rec.truths.end()) continue;
    const TruthSample& t = it->second;
    if (!have_t0) {
      t0 = t.stamp_s;
      have_t0 = true;
    }
    if (s.flags & 16u) continue;  // STATE_INITIALIZING
    if (s.joints_q.size() != rec.wire_joints.size()) continue;
    const double time = t.stamp_s - t0;
    if (t.other_contact) {
      acc.fell_at_s = time;
      break;
    }
    ++acc.matched_ticks;
    acc.duration_s = time;
    add_world_errors(acc, s, t, time, next_drift);
    if (!t.contact[0] && !t.contact[1]) {
      ++acc.no_support_ticks;
      continue;
    }
    add_relative_errors(acc, s, t, tick, rec, true_feet);
  }
}

}  // namespace

Accuracy analyse_recording(const std::string& mcap, const std::string& scenario_file) {
  Accuracy acc;
  const sim::World scenario = sim::load_world(scenario_file);
  acc.scenario = scenario.name;
  if (scenario.robot_config.empty()) {
    acc.error = "the scenario has no robot.config (the model is built from it)";
    return acc;
  }
  const model::RobotConfig robot = model::load_robot_config(scenario.robot_config);
  const model::Model model = model::load_robot_model(robot);

  Recording rec;
  const record::ScanResult scan = read_recording(mcap, rec);
  if (!scan.ok()) {
    acc.error = mcap + ": " + scan.error;
    return acc;
  }
  acc.state_ticks = rec.states.size();
  acc.truth_ticks = rec.truths.size();
  if (rec.wire_joints.empty()) {
    acc.error = mcap + ": no poise/robot_description";
    return acc;
  }
  std::vector<int> wire_of;
  acc.error = wire_indices(model, rec.wire_joints, wire_of);
  if (!acc.error.empty()) return acc;

  auto true_feet = true_foot_positions(model, robot, rec, wire_of);
  compare_to_truth(acc, rec, true_feet);
  if (acc.matched_ticks == 0) acc.error = mcap + ": no tick with both poise/state and poise/ground_truth";
  return acc;
}

Accuracy run_and_analyse(const RunOptions& o) {
  Accuracy acc;
  acc.estimator = o.estimator;
  std::error_code ec;
  fs::create_directories(o.dir, ec);
  const std::string scenario_file = o.scenario;
  const fs::path mcap = fs::path(o.dir) / "run.mcap";
  const fs::path log = fs::path(o.dir) / "poise_run.log";
  fs::remove(mcap, ec);
  std::vector<std::string> args{o.poise_bin, "run", o.scenario, "--record", mcap.string(),
                                "-o", (fs::path(o.dir) / "run.json").string(), "--log-dir",
                                (fs::path(o.dir) / "logs").string(), "-q"};
  if (!o.estimator.empty()) args.insert(args.end(), {"--estimator", o.estimator});
  if (o.duration > 0) args.insert(args.end(), {"--duration", std::to_string(o.duration)});
  if (o.domain >= 0) args.insert(args.end(), {"--domain", std::to_string(o.domain)});
  args.insert(args.end(), o.extra.begin(), o.extra.end());

  const pid_t pid = ::fork();
  if (pid < 0) {
    acc.error = "fork failed";
    return acc;
  }
  if (pid == 0) {
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, STDOUT_FILENO);
      ::dup2(fd, STDERR_FILENO);
    }
    std::vector<char*> argv;
    for (auto& a : args)
      argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  // Bounded: SIGTERM (poise run stops its children), SIGKILL 10 s later, by pid.
  const auto start = std::chrono::steady_clock::now();
  int status = 0;
  bool timed_out = false, term_sent = false;
  for (;;) {
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) break;
    const double waited =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!term_sent && waited > o.timeout_s) {
      ::kill(pid, SIGTERM);
      term_sent = timed_out = true;
    } else if (term_sent && waited > o.timeout_s + 10.0) {
      ::kill(pid, SIGKILL);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  acc.survived = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (timed_out) {
    acc.error = "poise run did not end within " + std::to_string(o.timeout_s) + " s: killed (log " +
                log.string() + ")";
    return acc;
  }
  if (!fs::exists(mcap)) {
    acc.error = "poise run made no recording (exit status " +
                std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ", log " +
                log.string() + ")";
    return acc;
  }
  // A scenario name resolves like poise run does: deploy/scenarios/NAME.yaml under the source tree.
  std::string file = scenario_file;
  if (!fs::exists(file)) {
    for (const fs::path& dir : {fs::path("deploy/scenarios"),
                               fs::path(o.poise_bin).parent_path() / "../../deploy/scenarios"}) {
      const fs::path p = dir / (scenario_file + ".yaml");
      if (fs::exists(p)) {
        file = p.string();
        break;
      }
    }
  }
  const bool survived = acc.survived;
  const std::string estimator = acc.estimator;
  acc = analyse_recording(mcap.string(), file);
  acc.survived = survived;
  acc.ran = true;
  acc.estimator = estimator;
  return acc;
}

std::string format_table(const std::vector<Accuracy>& results) {
  std::ostringstream o;
  char line[512];
  std::snprintf(line, sizeof line,
                "%-24s %-13s %5s | %-15s %-17s %-13s %-11s | %-15s %-17s %-15s %-17s | %s\n",
                "scenario", "estimator", "t[s]", "base pos mm", "base vel mm/s", "att deg",
                "tilt deg", "rel CoM mm", "rel CoM vel mm/s", "rel base mm",
                "rel base vel mm/s", "base/CoM drift mm at 5/10/20 s");
  o << line;
  o << "  (each: RMS/max; ticks flagged INITIALIZING left out)\n";
  auto d = [](double x) {
    char b[32];
    if (std::isnan(x)) return std::string("-");
    std::snprintf(b, sizeof b, "%.1f", 1e3 * x);
    return std::string(b);
  };
  for (const Accuracy& a : results) {
    if (!a.error.empty()) {
      o << a.scenario << " " << a.estimator << ": ERROR " << a.error << "\n";
      continue;
    }
    auto mm = [](const Stat& s) {
      char b[64];
      std::snprintf(b, sizeof b, "%.2f/%.2f", 1e3 * s.rms, 1e3 * s.max);
      return std::string(b);
    };
    auto deg = [](const Stat& s) {
      char b[64];
      std::snprintf(b, sizeof b, "%.3f/%.3f", s.rms, s.max);
      return std::string(b);
    };
    std::snprintf(line, sizeof line,
                  "%-24s %-13s %5.1f | %-15s %-17s %-13s %-11s | %-15s %-17s %-15s %-17s | "
                  "%s/%s/%s, %s/%s/%s%s\n",
                  a.scenario.c_str(), a.estimator.empty() ? "(scenario)" : a.estimator.c_str(),
                  a.duration_s, mm(a.base_pos).c_str(), mm(a.base_vel).c_str(),
                  deg(a.attitude_deg).c_str(), deg(a.tilt_deg).c_str(), mm(a.rel_com_pos).c_str(),
                  mm(a.rel_com_vel).c_str(), mm(a.rel_base_pos).c_str(), mm(a.rel_base_vel).c_str(),
                  d(a.base_drift[0]).c_str(), d(a.base_drift[1]).c_str(),
                  d(a.base_drift[2]).c_str(), d(a.com_drift[0]).c_str(), d(a.com_drift[1]).c_str(),
                  d(a.com_drift[2]).c_str(), !a.ran || a.survived ? "" : "  (run FAILED)");
    o << line;
    if (!std::isnan(a.fell_at_s)) {
      std::snprintf(line, sizeof line, "    fell at %.2f s: figures up to then\n", a.fell_at_s);
    } else {
      line[0] = '\0';
    }
    o << line;
  }
  return o.str();
}

std::string to_json(const std::vector<Accuracy>& results) {
  std::ostringstream o;
  auto stat = [&](const char* name, const Stat& s) {
    o << "\"" << name << "\": {\"rms\": " << s.rms << ", \"max\": " << s.max << "}, ";
  };
  auto num = [](double x) { return std::isnan(x) ? std::string("null") : std::to_string(x); };
  o << "[\n";
  for (std::size_t i = 0; i < results.size(); ++i) {
    const Accuracy& a = results[i];
    o << "  {\"scenario\": \"" << a.scenario << "\", \"estimator\": \"" << a.estimator
      << "\", \"error\": \"" << a.error << "\", \"survived\": " << (a.survived ? "true" : "false")
      << ", \"fell_at_s\": " << num(a.fell_at_s) << ", \"duration_s\": " << a.duration_s << ", \"matched_ticks\": " << a.matched_ticks << ", ";
    stat("base_pos_m", a.base_pos);
    stat("base_pos_before_2s_m", a.base_pos_early);
    stat("base_vel_mps", a.base_vel);
    stat("com_pos_m", a.com_pos);
    stat("com_vel_mps", a.com_vel);
    stat("attitude_deg", a.attitude_deg);
    stat("tilt_deg", a.tilt_deg);
    stat("rel_com_pos_m", a.rel_com_pos);
    stat("rel_com_vel_mps", a.rel_com_vel);
    stat("rel_base_pos_m", a.rel_base_pos);
    stat("rel_base_vel_mps", a.rel_base_vel);
    o << "\"base_drift_m\": [" << num(a.base_drift[0]) << ", " << num(a.base_drift[1]) << ", "
      << num(a.base_drift[2]) << "], \"com_drift_m\": [" << num(a.com_drift[0]) << ", "
      << num(a.com_drift[1]) << ", " << num(a.com_drift[2]) << "]}"
      << (i + 1 < results.size() ? ",\n" : "\n");
  }
  o << "]\n";
  return o.str();
}

}  // namespace poise::estimator_bench
