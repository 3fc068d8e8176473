// `poise run` supervision and CLI, tested from outside: real processes, real signals.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/types.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <functional>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <tuple>
#include <vector>

#include <poise/msg/joint_command.h>
#include <poise/msg/sensors.h>
#include <nlohmann/json.hpp>
#include <poise/dds/dds.hpp>
#include <poise/estimator/estimator.hpp>
#include <poise/sim/sim_config.hpp>

#include "child_process.hpp"

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using namespace std::chrono_literals;
using poise::testing::bin;
using poise::testing::ChildProcess;
using poise::testing::run_command;

fs::path work_dir(const std::string& name) {
  const fs::path d = fs::path(POISE_BINARY_DIR) / "test_output" / "launch" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

/// Field 4 (ppid) and field 3 (state) of /proc/<pid>/stat; false if the process is gone.
bool proc_stat(pid_t pid, pid_t& ppid, char& state) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return false;
  const auto close = line.rfind(')');
  if (close == std::string::npos) return false;
  std::istringstream rest(line.substr(close + 2));
  rest >> state >> ppid;
  return true;
}

/// Live (not zombie) processes whose parent is `parent`.
std::set<pid_t> children_of(pid_t parent) {
  std::set<pid_t> out;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    pid_t ppid = 0;
    char state = 0;
    const auto pid = static_cast<pid_t>(std::stol(name));
    if (proc_stat(pid, ppid, state) && ppid == parent && state != 'Z') out.insert(pid);
  }
  return out;
}

bool alive(pid_t pid) {
  pid_t ppid = 0;
  char state = 0;
  return proc_stat(pid, ppid, state) && state != 'Z';
}

std::vector<std::string> run_args(const std::string& scenario, int domain, const fs::path& dir,
                                  std::vector<std::string> extra) {
  std::vector<std::string> a{bin("poise"),     "run",   scenario, "--domain",
                             std::to_string(domain), "-o",    (dir / "run.json").string(),
                             "--log-dir",      (dir / "logs").string()};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

/// A real-time deployment of `standing` on this machine: the four components (the simulator
/// runs `sim_seconds`), `contact_extra` added to the contact optimiser's map ("restart:
/// on-failure") and `more` appended to the components (a recorder's line).
void write_local_deployment(const fs::path& file, const std::string& name, int domain,
                            int sim_seconds, const std::string& contact_extra = "",
                            const std::string& more = "") {
  std::ofstream(file) << "name: " << name << "\ndomain: " << domain
                      << "\nscenario: standing\nmode: realtime\nhosts:\n"
                         "  local: {address: 127.0.0.1}\ncomponents:\n"
                         "  sim: {host: local, options: [--duration, "
                      << sim_seconds
                      << "]}\n  estimator: {host: local}\n  controller: {host: local}\n"
                         "  contact: {host: local"
                      << (contact_extra.empty() ? "" : ", " + contact_extra) << "}\n"
                      << more;
}

/// The child of `parent` whose command line (argv) satisfies `is_it`; 0 if none.
pid_t child_with(pid_t parent, const std::function<bool(const std::vector<std::string>&)>& is_it) {
  for (pid_t p : children_of(parent)) {
    std::ifstream cmd("/proc/" + std::to_string(p) + "/cmdline");
    std::vector<std::string> argv;
    for (std::string arg; std::getline(cmd, arg, '\0');)
      argv.push_back(arg);
    if (is_it(argv)) return p;
  }
  return 0;
}

}  // namespace

// SIGKILL of the launcher leaves no orphan: each node gets SIGTERM from the kernel
// (PR_SET_PDEATHSIG) and ends. The recorder, too, and its file is finished properly.
TEST(Launch, NoOrphanSurvivesASigkilledLauncher) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("sigkill");
  ChildProcess launcher(run_args("standing", domain, dir,
                                 {"--realtime", "--duration", "60", "--record",
                                  (dir / "run.mcap").string()}),
                        {}, false, true);
  ASSERT_TRUE(launcher.wait_for_output("t=1.0 s", 60s)) << launcher.output();
  const std::set<pid_t> kids = children_of(launcher.pid());
  ASSERT_EQ(kids.size(), 5u) << "sim, estimator, contact, controller, recorder\n"
                             << launcher.output();
  ASSERT_EQ(::kill(launcher.pid(), SIGKILL), 0);
  launcher.wait_for(10s);
  const auto end = std::chrono::steady_clock::now() + 20s;
  std::set<pid_t> left = kids;
  while (!left.empty() && std::chrono::steady_clock::now() < end) {
    for (auto it = left.begin(); it != left.end();)
      it = alive(*it) ? std::next(it) : left.erase(it);
    std::this_thread::sleep_for(20ms);
  }
  for (pid_t p : left) {
    ADD_FAILURE() << "orphan pid " << p << " survived the launcher";
    ::kill(p, SIGKILL);
  }
  // The recorder ended on SIGTERM: the file has its summary.
  auto [code, out] = [&] {
    ChildProcess info({bin("poise"), "info", (dir / "run.mcap").string()}, {}, false, true);
    auto c = info.wait_for(60s);
    return std::pair<int, std::string>(c.value_or(-1), info.output());
  }();
  EXPECT_EQ(code, 0) << out;
  EXPECT_EQ(out.find("incomplete"), std::string::npos) << out;
}

// A run that fails still writes its result, marked failed, with the reason in words; an older
// "survived": true at the same path never stands for it.
TEST(Launch, AFailedRunWritesAFailedResultNamingTheSignal) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("failed");
  std::ofstream(dir / "run.json") << R"({"scenario": "standing", "survived": true})" << "\n";
  ChildProcess launcher(run_args("standing", domain, dir, {"--realtime", "--duration", "60"}),
                        {}, false, true);
  ASSERT_TRUE(launcher.wait_for_output("t=1.0 s", 60s)) << launcher.output();
  EXPECT_FALSE(fs::exists(dir / "run.json")) << "the stale result is still there during the run";
  // The controller's pid: the child whose command line is poise-controller.
  pid_t controller = 0;
  for (pid_t p : children_of(launcher.pid())) {
    std::ifstream cmd("/proc/" + std::to_string(p) + "/cmdline");
    std::string argv0;
    std::getline(cmd, argv0, '\0');
    if (argv0.find("poise-controller") != std::string::npos) controller = p;
  }
  ASSERT_GT(controller, 0) << launcher.output();
  ASSERT_EQ(::kill(controller, SIGKILL), 0);
  const auto code = launcher.wait_for(60s);
  ASSERT_TRUE(code.has_value()) << launcher.output();
  EXPECT_EQ(*code, 2) << launcher.output();
  EXPECT_NE(launcher.output().find("controller killed by SIGKILL"), std::string::npos)
      << launcher.output();
  const Json r = Json::parse(std::ifstream(dir / "run.json"));
  EXPECT_FALSE(r["survived"].get<bool>()) << r.dump(2);
  EXPECT_TRUE(r["failed"].get<bool>()) << r.dump(2);
  EXPECT_NE(r["failure"].get<std::string>().find("controller killed by SIGKILL"),
            std::string::npos)
      << r.dump(2);
  EXPECT_NE(r["exits"]["controller"].get<std::string>().find("code 137"), std::string::npos)
      << r.dump(2);
  EXPECT_EQ(r["pids"]["controller"].get<int>(), controller);
}

// The CLI as documented: verb-group options after the verb (as in `ros2 topic`), and
// `poise push --force FX FY FZ` against a live stack.
TEST(Launch, DocumentedCommandLinesParse) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("cli");
  ChildProcess launcher(run_args("standing", domain, dir, {"--realtime", "--duration", "8"}), {},
                        false, true);
  ASSERT_TRUE(launcher.wait_for_output("t=1.0 s", 60s)) << launcher.output();
  auto run = [](std::vector<std::string> argv) { return run_command(std::move(argv), 30s); };
  const std::string d = std::to_string(domain);
  {
    auto [code, out] = run({bin("poise"), "topic", "echo", "poise/state", "--domain", d, "--once",
                            "--timeout", "10"});
    EXPECT_EQ(code, 0) << out;
    EXPECT_NE(out.find("com_W"), std::string::npos) << out;
  }
  {
    auto [code, out] = run({bin("poise"), "topic", "list", "--domain", d, "--wait", "1"});
    EXPECT_EQ(code, 0) << out;
    EXPECT_NE(out.find("poise/joint_command"), std::string::npos) << out;
  }
  {
    auto [code, out] = run({bin("poise"), "topic", "list", "--dds", "fastdds", "--domain", d,
                            "--wait", "2"});
    EXPECT_EQ(code, 0) << out;
    EXPECT_NE(out.find("poise/sensors"), std::string::npos) << out;
  }
  {
    auto [code, out] = run({bin("poise"), "push", "--domain", d, "--force", "20", "0", "0",
                            "--duration", "0.1"});
    EXPECT_EQ(code, 0) << out;
  }
  const auto code = launcher.wait_for(60s);
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 0) << launcher.output();
  std::ifstream sim_log(dir / "logs" / "sim.err");
  const std::string log((std::istreambuf_iterator<char>(sim_log)), {});
  EXPECT_NE(log.find("push"), std::string::npos) << "the simulator did not log the push:\n" << log;
}

namespace {


}  // namespace

// A bad deployment file gets every problem at once, each with its place in the file.
TEST(Launch, ABadDeploymentFileIsRefusedWithEveryProblemNamed) {
  const fs::path dir = work_dir("bad_deployment");
  std::ofstream(dir / "bad.yaml") << "name: a..b\n"
                                     "domain: 300\n"
                                     "mode: fast\n"
                                     "scenario: no_such_scenario\n"
                                     "hosts:\n"
                                     "  a: {address: 10.0.0.1}\n"
                                     "  b: {address: 10.0.0.300}\n"
                                     "components:\n"
                                     "  sim: {host: a, restart: always}\n"
                                     "  estimator: {host: c, dds: rti, cpu: [4096]}\n"
                                     "  driver: {host: a}\n"
                                     "  contact: {host: b, colour: red}\n";
  auto [code, out] = run_command({bin("poise"), "launch", (dir / "bad.yaml").string(), "--check"}, 30s);
  EXPECT_EQ(code, 2) << out;
  for (const char* expected :
       {"name: 'a..b' is not a plain file name", "domain: 300 is outside 0..232",
        "mode: 'fast' is not lockstep or realtime",
        "scenario: no such file or scenario name: no_such_scenario",
        "hosts.b.address: '10.0.0.300' is not an IPv4 address",
        "components.sim.restart: the simulator is the run",
        "components.estimator.host: 'c' is not among the hosts",
        "components.estimator.dds: 'rti' is not cyclone (cyclonedds) or fastdds",
        "components.estimator.cpu: CPU 4096 does not exist", "components.driver: say its kind",
        "components.contact: unknown key 'colour'"})
    EXPECT_NE(out.find(expected), std::string::npos) << expected << "\n" << out;
  std::ofstream(dir / "not_yaml.yaml") << "hosts: [a, b\n";
  auto [code2, out2] =
      run_command({bin("poise"), "launch", (dir / "not_yaml.yaml").string(), "--check"}, 30s);
  EXPECT_EQ(code2, 2) << out2;
  EXPECT_NE(out2.find("not valid YAML"), std::string::npos) << out2;
}

// Honest accounting: the result names every kind of miss and splits each node's compute time
// into its library call, its own overhead and its DDS writes; a run whose robot damped (no
// command for the safety layer's whole hold time) fails above the scenario's tolerance (default
// 0 ticks).
TEST(Launch, TheResultCountsEveryMissAndDampingFailsTheRun) {
  const fs::path dir = work_dir("accounting");
  const std::string ok_json = (dir / "lockstep.json").string();
  auto [ok_code, ok_out] = run_command({bin("poise"), "run", "standing", "--duration", "1", "-o",
                                    ok_json, "--log-dir", (dir / "lockstep.logs").string()},
                                   120s);
  ASSERT_EQ(ok_code, 0) << ok_out;
  const Json ok = Json::parse(std::ifstream(ok_json));
  for (const char* key : {"controller_contact_wait", "sim_overruns", "robot_hold_ticks",
                          "robot_damping_ticks", "robot_late_commands", "samples_rejected"})
    EXPECT_TRUE(ok["misses"].contains(key)) << key << "\n" << ok.dump(2);
  EXPECT_EQ(ok["misses"]["robot_damping_ticks"], 0);
  for (const char* node : {"estimator", "controller", "contact"}) {
    SCOPED_TRACE(node);
    ASSERT_TRUE(ok["library_us"].contains(node)) << ok.dump(2);
    EXPECT_GT(ok["library_us"][node]["count"].get<int>(), 900);
    // library + overhead (the node's own work) + dds write = compute, per tick; so their means
    // add up (exact sums, whatever the bins)
    ASSERT_TRUE(ok["dds_write_us"].contains(node)) << ok.dump(2);
    EXPECT_EQ(ok["dds_write_us"][node]["count"], ok["library_us"][node]["count"]);
    EXPECT_GT(ok["dds_write_us"][node]["mean"].get<double>(), 0.0);
    EXPECT_NEAR(ok["library_us"][node]["mean"].get<double>() +
                    ok["overhead_us"][node]["mean"].get<double>() +
                    ok["dds_write_us"][node]["mean"].get<double>(),
                ok["compute_us"][node]["mean"].get<double>(), 1.5);
  }
  EXPECT_NE(ok_out.find("  misses: contact wait"), std::string::npos) << ok_out;

  // A watchdog of 0.2 ms and no hold: the robot damps between commands -> the run fails.
  const std::string bad_json = (dir / "damping.json").string();
  auto [bad_code, bad_out] =
      run_command({bin("poise"), "run", "standing", "--realtime", "--duration", "1", "--watchdog-ms",
               "0.2", "--hold-s", "0", "-o", bad_json, "--log-dir",
               (dir / "damping.logs").string()},
              120s);
  EXPECT_EQ(bad_code, 1) << bad_out;
  const Json bad = Json::parse(std::ifstream(bad_json));
  EXPECT_FALSE(bad["survived"].get<bool>());
  EXPECT_GT(bad["misses"]["robot_damping_ticks"].get<int>(), 0);
  EXPECT_NE(bad.value("failure", std::string()).find("damping ticks > 0"), std::string::npos)
      << bad.dump(2);
}

// A reference player that falls behind (stopped for 0.4 s of wall time, SIGSTOP, in the middle
// of step_in_place's trajectory: the lockstep loop runs on without it) loses states and never
// sends the references of the ticks it skipped; those it sends after their tick are applied
// late. Before, such a run "survived" although its step was never played. Now the verdict fails
// naming both, the result counts them (misses), and an undisturbed run has neither.
TEST(Launch, AReferencePlayerThatFallsBehindFailsTheRun) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("stalled_player");
  ChildProcess launcher(run_args("step_in_place", domain, dir, {"--lockstep", "--duration", "6"}),
                        {}, false, true);
  pid_t player = -1;
  for (int i = 0; i < 600 && player < 0; ++i) {  // the launcher's child named poise-reference
    for (pid_t c : children_of(launcher.pid())) {
      std::ifstream comm("/proc/" + std::to_string(c) + "/comm");
      std::string name;
      if (std::getline(comm, name) && name == "poise-reference") player = c;
    }
    if (player < 0) std::this_thread::sleep_for(10ms);
  }
  ASSERT_GT(player, 0) << launcher.output();
  // The CoM move begins at 2.0 s: stall the player once the loop is at 2.0 s (progress lines).
  ASSERT_TRUE(launcher.wait_for_output("t=2.0 s", 120s)) << launcher.output();
  ASSERT_EQ(::kill(player, SIGSTOP), 0);
  std::this_thread::sleep_for(400ms);
  ::kill(player, SIGCONT);
  const auto code = launcher.wait_for(180s);
  ASSERT_TRUE(code.has_value()) << launcher.output();
  EXPECT_EQ(*code, 1) << launcher.output();
  const Json r = Json::parse(std::ifstream(dir / "run.json"), nullptr, false);
  ASSERT_TRUE(r.is_object()) << launcher.output();
  std::printf("stalled player: %s\n  misses: skipped %s, late %s\n",
              r.value("failure", std::string()).c_str(),
              r["misses"].value("reference_skipped_ticks", Json()).dump().c_str(),
              r["misses"].value("controller_late_references", Json()).dump().c_str());
  EXPECT_FALSE(r.value("survived", true));
  const std::string failure = r.value("failure", std::string());
  EXPECT_GT(r["misses"].value("reference_skipped_ticks", 0) +
                r["misses"].value("controller_late_references", 0),
            0)
      << r.dump(2);
  EXPECT_TRUE(failure.find("reference player skipped") != std::string::npos ||
              failure.find("after their tick") != std::string::npos)
      << failure;

  // Undisturbed: neither, and the step is played (the run survives).
  const fs::path ok_dir = work_dir("undisturbed_player");
  auto [ok_code, ok_out] =
      run_command(run_args("step_in_place", domain, ok_dir, {"--lockstep", "--duration", "6"}),
                  180s);
  EXPECT_EQ(ok_code, 0) << ok_out;
  const Json ok = Json::parse(std::ifstream(ok_dir / "run.json"), nullptr, false);
  ASSERT_TRUE(ok.is_object()) << ok_out;
  EXPECT_EQ(ok["misses"].value("reference_skipped_ticks", -1), 0) << ok.dump(2);
  EXPECT_EQ(ok["misses"].value("controller_late_references", -1), 0) << ok.dump(2);
}

// A scenario's controller: section configures the controller in both modes (its contact.priority
// reaches the contact optimiser process), a bad key in it is refused before anything starts, and
// both modes' results carry the same verdict fields, naming the criteria that failed.
TEST(Launch, TheScenarioConfiguresTheControllerAndTheVerdictNamesWhatFailed) {
  const fs::path dir = work_dir("controller_section");
  const std::string robot =
      (fs::path(POISE_SOURCE_DIR) / "deploy/robots/poise_humanoid/robot.yaml").string();
  auto scenario = [&](const std::string& name, const std::string& controller) {
    const fs::path f = dir / (name + ".yaml");
    std::ofstream(f) << "name: " << name << "\nrobot: {config: " << robot
                     << "}\nduration: 0.6\nsuccess: {com_error_max_m: 0.15, com_error_final_m: "
                        "0.00001}\ncontroller:\n"
                     << controller;
    return f.string();
  };
  const std::string good =
      scenario("weighted", "  contact: {priority: weighted, torsion_limit: independent}\n"
                           "  momentum: {gamma22: [9, 9, 3]}\n");
  const std::string bad = scenario("bad_key", "  contact: {priority: weighted, w_x: 1}\n");

  // In process.
  auto [in_code, in_out] = run_command({bin("poise"), "run", good, "--in-process", "-o",
                                    (dir / "in.json").string()}, 120s);
  EXPECT_EQ(in_code, 1) << in_out;  // the 0.01 mm final CoM error cannot be met
  EXPECT_NE(in_out.find("FAILED on com_error_final"), std::string::npos) << in_out;
  const Json in = Json::parse(std::ifstream(dir / "in.json"));
  EXPECT_EQ(in["contact_priority"], "weighted") << in.dump(2);
  EXPECT_EQ(in["contact_torsion_limit"], "independent") << in.dump(2);

  // Distributed, lockstep.
  auto [d_code, d_out] = run_command({bin("poise"), "run", good, "-q", "-o", (dir / "d.json").string(),
                                  "--log-dir", (dir / "d.logs").string()}, 180s);
  EXPECT_EQ(d_code, 1) << d_out;
  EXPECT_NE(d_out.find("FAILED weighted (lockstep, cyclone) on com_error_final"), std::string::npos)
      << d_out;
  const Json d = Json::parse(std::ifstream(dir / "d.json"));
  EXPECT_EQ(d["contact_priority"], "weighted") << d.dump(2);
  EXPECT_EQ(d["contact_torsion_limit"], "independent") << d.dump(2);
  const Json contact = Json::parse(std::ifstream(dir / "d.logs" / "contact.summary.json"));
  EXPECT_NE(contact.dump().find("\"priority\":\"weighted\""), std::string::npos) << contact.dump();
  EXPECT_NE(contact.dump().find("\"torsion_limit\":\"independent\""), std::string::npos)
      << contact.dump();
  std::ifstream written(dir / "d.logs" / "controller.yaml");
  std::stringstream text;
  text << written.rdbuf();
  EXPECT_NE(text.str().find("gamma22"), std::string::npos) << text.str();

  // The same verdict fields in both modes.
  for (const char* key : {"survived", "com_error_max_m", "com_error_final_m", "foot_slip_max_m",
                          "non_foot_contacts", "min_base_height_m", "recovery_time_s",
                          "trunk_pitch_max_deg", "trunk_roll_max_deg", "failed_criteria",
                          "failure", "contact_method", "contact_priority",
                          "contact_torsion_limit", "controller_fall"}) {
    EXPECT_TRUE(in.contains(key)) << key << "\n" << in.dump(2);
    EXPECT_TRUE(d.contains(key)) << key << "\n" << d.dump(2);
  }
  ASSERT_TRUE(in["failed_criteria"].is_array() && d["failed_criteria"].is_array());
  EXPECT_EQ(in["failed_criteria"].size(), 1u) << in.dump(2);
  EXPECT_EQ(d["failed_criteria"].size(), 1u) << d.dump(2);
  // Standing: the trunk stays upright (a few degrees at most), and this is measured, not zero.
  for (const Json* j : {&in, &d}) {
    EXPECT_LT((*j)["trunk_pitch_max_deg"].get<double>(), 5.0);
    EXPECT_GT((*j)["trunk_pitch_max_deg"].get<double>() + (*j)["trunk_roll_max_deg"].get<double>(),
              0.0);
  }

  // A bad key is refused in both modes, naming it, before any process starts.
  for (const bool in_process : {true, false}) {
    std::vector<std::string> args{bin("poise"), "run", bad, "-o", (dir / "bad.json").string()};
    if (in_process) args.push_back("--in-process");
    auto [code, out] = run_command(args, 60s);
    EXPECT_EQ(code, 2) << out;
    EXPECT_NE(out.find("controller: contact.w_x: unknown key"), std::string::npos) << out;
  }
}

// A robot pushed over (600 N for 0.2 s on the torso): the controller declares the fall
// (FallConfig: the base tilted past 60 deg), damps the joints from then on and says so, and the
// verdict names it, the same in process and distributed. Without the rule (fall: {tilt_deg: 180,
// com_height_fraction: 0}) the fallen robot, still driven by the balance controller, slid 2.3 m
// across the floor (0.16 m with it) and a fallen Unitree G1 was thrown 200 m into the air.
TEST(Launch, AFallenRobotIsDampedAndTheVerdictSaysWhen) {
  const fs::path dir = work_dir("fall");
  const fs::path f = dir / "fall.yaml";
  std::ofstream(f) << "name: fall\nrobot: {config: "
                   << (fs::path(POISE_SOURCE_DIR) / "deploy/robots/poise_humanoid/robot.yaml").string()
                   << "}\nduration: 2.0\ndisturbances:\n  pushes:\n    - {link: torso, point: [0, 0, 0], "
                      "force: [600.0, 0.0, 0.0], start: 0.5, duration: 0.2}\n";
  auto [in_code, in_out] =
      run_command({bin("poise"), "run", f.string(), "--in-process", "-q", "-o",
                   (dir / "in.json").string()}, 120s);
  EXPECT_EQ(in_code, 1) << in_out;
  EXPECT_NE(in_out.find("the controller declared a fall at"), std::string::npos) << in_out;
  auto [d_code, d_out] = run_command({bin("poise"), "run", f.string(), "-q", "-o",
                                      (dir / "d.json").string(), "--log-dir",
                                      (dir / "d.logs").string()}, 180s);
  EXPECT_EQ(d_code, 1) << d_out;
  const Json in = Json::parse(std::ifstream(dir / "in.json"));
  const Json d = Json::parse(std::ifstream(dir / "d.json"));
  for (const Json* j : {&in, &d}) {
    ASSERT_TRUE((*j)["controller_fall"].is_object()) << j->dump(2);
    const double t = (*j)["controller_fall"]["time_s"].get<double>();
    EXPECT_GT(t, 0.5) << j->dump(2);  // after the push began
    EXPECT_LT(t, 1.5) << j->dump(2);
    EXPECT_NE((*j)["controller_fall"]["reason"].get<std::string>().find("base tilt"),
              std::string::npos);
    EXPECT_FALSE((*j)["survived"].get<bool>());
    EXPECT_LT((*j)["foot_slip_max_m"].get<double>(), 0.5) << j->dump(2);  // lying still
  }
  EXPECT_EQ(in["controller_fall"], d["controller_fall"]);
  std::ifstream err(dir / "d.logs" / "controller.err");
  std::stringstream text;
  text << err.rdbuf();
  EXPECT_NE(text.str().find("the robot has fallen"), std::string::npos) << text.str();

  // From a deployment file (one machine, lockstep): the host's result says it too, at the tick
  // of the same time.
  std::ofstream(dir / "one.yaml") << "name: one\ndomain: " << poise::testing::unique_domain_id()
                                  << "\nscenario: " << f.string()
                                  << "\nhosts:\n  local: {address: 127.0.0.1}\ncomponents:\n"
                                     "  sim: {host: local}\n  estimator: {host: local}\n"
                                     "  controller: {host: local}\n  contact: {host: local}\n";
  auto [l_code, l_out] = run_command({bin("poise"), "launch", (dir / "one.yaml").string(), "-o",
                                      (dir / "one.json").string(), "--log-dir",
                                      (dir / "one.logs").string()},
                                     180s);
  EXPECT_EQ(l_code, 1) << l_out;
  EXPECT_NE(l_out.find("the controller declared the robot fallen at tick"), std::string::npos)
      << l_out;
  const Json l = Json::parse(std::ifstream(dir / "one.json"));
  ASSERT_TRUE(l["controller_fall"].is_object()) << l.dump(2);
  EXPECT_EQ(l["controller_fall"]["reason"], d["controller_fall"]["reason"]) << l.dump(2);
  EXPECT_NEAR(l["controller_fall"]["tick"].get<double>() * 1e-3,
              d["controller_fall"]["time_s"].get<double>(), 1e-9);
  EXPECT_FALSE(l["survived"].get<bool>());
}

// `poise launch` gives poise-estimator what `poise run` gives it (one function makes both:
// launch::estimator_scenario_args): on platforms, the soles' start heights derived from the
// platforms' placement, and the scenario's sensor figures (F/T noise, IMU latency).
TEST(Launch, ADeploymentGivesTheEstimatorWhatPoiseRunGivesIt) {
  const fs::path dir = work_dir("deployment_estimator_args");
  std::ofstream(dir / "deployment.yaml") << "domain: 45\n"
                                            "scenario: platforms_in_phase\n"
                                            "hosts:\n  local: {address: 127.0.0.1}\n"
                                            "components:\n"
                                            "  sim: {host: local}\n  estimator: {host: local}\n"
                                            "  contact: {host: local}\n  controller: {host: local}\n";
  auto [code, out] =
      run_command({bin("poise"), "launch", (dir / "deployment.yaml").string(), "--check"}, 30s);
  EXPECT_EQ(code, 0) << out;
  for (const char* arg : {"--supports translating", "--estimator invariant-ekf", "--support-heights",
                          "--initial-xy", "--contact-ft-noise 0.5", "--imu-delay-ticks 1",
                          // its controller: section, as poise run passes it
                          "controller.yaml", "--priority lexicographic",
                          "--torsion-limit friction-coupled"})
    EXPECT_NE(out.find(arg), std::string::npos) << arg << "\n" << out;
  // A bad key of the section is a problem of the file, named.
  std::ofstream(dir / "bad.yaml") << "name: bad\nduration: 1.0\ncontroller: {fall: {tilt: 45}}\n";
  std::ofstream(dir / "bad_deployment.yaml") << "domain: 45\nscenario: bad.yaml\n"
                                                "hosts:\n  desk: {address: 127.0.0.1}\n"
                                                "  robot: {address: 127.0.0.2}\n"
                                                "components:\n  sim: {host: robot}\n"
                                                "  controller: {host: desk}\n";
  auto [bad_code, bad] = run_command({bin("poise"), "launch", (dir / "bad_deployment.yaml").string(),
                                      "--check", "--host", "desk"},
                                     30s);
  EXPECT_EQ(bad_code, 2) << bad;
  EXPECT_NE(bad.find("fall.tilt"), std::string::npos) << bad;
}

// A desk host needs the scenario file but no robot files: its nodes take the robot from
// poise/robot_description. The scenario here names a robot configuration that does not exist:
// the desk's share is valid (and its nodes get the scenario's support model), the robot's share
// (the simulator loads the robot) and a whole-file --check name the missing file.
TEST(Launch, ADeskHostNeedsNoRobotFiles) {
  const fs::path dir = work_dir("desk_without_robot");
  std::ofstream(dir / "scenario.yaml") << "name: far_robot\n"
                                          "robot:\n  config: /nonexistent/robots/far/robot.yaml\n"
                                          "duration: 1.0\n"
                                          "estimator: {supports: translating}\n"
                                          "contact: {method: qp}\n";
  std::ofstream(dir / "deployment.yaml") << "domain: 44\n"
                                            "scenario: scenario.yaml\n"
                                            "hosts:\n"
                                            "  robot: {address: 10.0.0.1}\n"
                                            "  desk: {address: 10.0.0.2}\n"
                                            "components:\n"
                                            "  sim: {host: robot}\n"
                                            "  estimator: {host: desk}\n"
                                            "  contact: {host: desk}\n"
                                            "  controller: {host: desk}\n";
  const std::string file = (dir / "deployment.yaml").string();
  auto [desk_code, desk] = run_command({bin("poise"), "launch", file, "--check", "--host", "desk"}, 30s);
  EXPECT_EQ(desk_code, 0) << desk;
  EXPECT_NE(desk.find("--supports translating"), std::string::npos) << desk;
  EXPECT_NE(desk.find("--method qp"), std::string::npos) << desk;
  EXPECT_EQ(desk.find("--robot"), std::string::npos) << desk;
  auto [robot_code, robot] =
      run_command({bin("poise"), "launch", file, "--check", "--host", "robot"}, 30s);
  EXPECT_EQ(robot_code, 2) << robot;
  EXPECT_NE(robot.find("/nonexistent/robots/far/robot.yaml"), std::string::npos) << robot;
  auto [all_code, all] = run_command({bin("poise"), "launch", file, "--check"}, 30s);
  EXPECT_EQ(all_code, 2) << all;
}

// Lockstep: the nodes wait as long for their input as the simulator waits for a command (a
// loaded machine stalls the loop for 100+ ms; a 50 ms wall-clock staleness called that a fault in
// a CI run). Real time keeps the nodes' 50 ms default; a file's own option wins.
TEST(Launch, LockstepNodesWaitForTheirInputAsLongAsTheSimulator) {
  const fs::path dir = work_dir("lockstep_stale");
  auto check = [&](const std::string& mode, const std::string& estimator_options,
                   const std::string& sim_options = "",
                   const std::string& expected = "--input-stale-ms 2000") {
    std::ofstream(dir / "deployment.yaml")
        << "domain: 44\nmode: " << mode << "\nscenario: " << POISE_SOURCE_DIR
        << "/deploy/scenarios/standing.yaml\n"
           "hosts:\n  robot: {address: 10.0.0.1}\n  desk: {address: 10.0.0.2}\n"
           "components:\n  sim: {host: robot"
        << sim_options << "}\n  estimator: {host: desk"
        << estimator_options << "}\n  contact: {host: desk}\n  controller: {host: desk}\n";
    auto [code, out] = run_command(
        {bin("poise"), "launch", (dir / "deployment.yaml").string(), "--check", "--host", "desk"},
        30s);
    EXPECT_EQ(code, 0) << out;
    std::size_t n = 0;
    for (std::size_t at = out.find(expected); at != std::string::npos;
         at = out.find(expected, at + 1))
      ++n;
    return std::make_pair(n, out);
  };
  auto [lockstep, lockstep_out] = check("lockstep", "");
  EXPECT_EQ(lockstep, 2u) << "estimator and controller\n" << lockstep_out;
  auto [realtime, realtime_out] = check("realtime", "");
  EXPECT_EQ(realtime, 0u) << realtime_out;
  EXPECT_EQ(realtime_out.find("--input-stale-ms"), std::string::npos) << realtime_out;
  auto [own, own_out] = check("lockstep", ", options: [--input-stale-ms, '300']");
  EXPECT_EQ(own, 1u) << "the controller only\n" << own_out;
  EXPECT_NE(own_out.find("--input-stale-ms 300"), std::string::npos) << own_out;
  // The simulator told to wait 5 s for a command: the nodes wait as long.
  auto [longer, longer_out] = check("lockstep", "", ", options: [--command-timeout-ms, '5000']",
                                    "--input-stale-ms 5000");
  EXPECT_EQ(longer, 2u) << longer_out;
}

// A component that dies is restarted by its policy, and the run goes on to the verdict: kill -9
// of the contact optimiser (restart: on-failure) in a lockstep run on one machine.
TEST(Launch, AKilledComponentIsRestartedByItsPolicy) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("restart");
  write_local_deployment(dir / "one.yaml", "one", domain, 6, "restart: on-failure");
  ChildProcess launcher({bin("poise"), "launch", (dir / "one.yaml").string(), "-o",
                         (dir / "one.json").string(), "--log-dir", (dir / "logs").string()},
                        {}, false, true);
  ASSERT_TRUE(launcher.wait_for_output("t=1.0 s", 60s)) << launcher.output();
  const pid_t contact = child_with(launcher.pid(), [](const std::vector<std::string>& a) {
    return !a.empty() && a[0].find("poise-contact") != std::string::npos;
  });
  ASSERT_GT(contact, 0) << launcher.output();
  ASSERT_EQ(::kill(contact, SIGKILL), 0);
  const auto code = launcher.wait_for(120s);
  ASSERT_TRUE(code.has_value()) << launcher.output();
  EXPECT_NE(launcher.output().find("contact killed by SIGKILL"), std::string::npos)
      << launcher.output();
  EXPECT_NE(launcher.output().find("restarting it (1 of 3)"), std::string::npos)
      << launcher.output();
  const Json r = Json::parse(std::ifstream(dir / "one.json"));
  EXPECT_EQ(r["components"]["contact"]["restarts"], 1) << r.dump(2);
  EXPECT_FALSE(r["failed"].get<bool>()) << r.dump(2);
  EXPECT_NE(r["components"]["contact"]["pid"].get<int>(), contact) << r.dump(2);
  // The restarted optimiser's log follows the killed one's: appended, never truncated.
  for (const char* ext : {".out", ".err"}) {
    std::ifstream in(dir / "logs" / (std::string("contact") + ext));
    const std::string log((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto mark = log.find("a new instance starts here");
    if (std::string(ext) == ".out" && mark == std::string::npos) continue;  // nothing printed
    ASSERT_NE(mark, std::string::npos) << ext << ":\n" << log;
    EXPECT_EQ(log.find("a new instance starts here", mark + 1), std::string::npos) << log;
    EXPECT_LT(log.find_first_not_of(" \n"), mark) << ext << ": the first instance's lines are lost\n"
                                                   << log;
  }
  // Whether the robot survived 0.5 s without contact solutions is #15's business (the
  // controller's fallback); the launcher's job was to bring the optimiser back.
  std::printf("after a restart of the contact optimiser: exit %d, survived %s\n", *code,
              r.value("survived", false) ? "yes" : "no");
}

// A recorder restarted by its policy goes on in a numbered file and what it recorded before the
// crash is kept (its restart used to truncate the file: the part before a crash, often what one
// wants to see, was lost without a word). The launch itself replaces the last launch's recording.
TEST(Launch, ARestartedRecorderKeepsWhatItRecordedBefore) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("recorder_restart");
  const fs::path rec = dir / "rec.mcap";
  { std::ofstream(rec) << "the last launch's recording"; }
  write_local_deployment(
      dir / "rec.yaml", "rec", domain, 4, "",
      "  recorder: {host: local, output: " + rec.string() + ", restart: on-failure}\n");
  ChildProcess launcher({bin("poise"), "launch", (dir / "rec.yaml").string(), "-o",
                         (dir / "rec.json").string(), "--log-dir", (dir / "logs").string()},
                        {}, false, true);
  ASSERT_TRUE(launcher.wait_for_output("t=1.0 s", 60s)) << launcher.output();
  const pid_t recorder = child_with(launcher.pid(), [](const std::vector<std::string>& a) {
    return a.size() > 1 && a[1] == "record";
  });
  ASSERT_GT(recorder, 0) << launcher.output();
  ASSERT_EQ(::kill(recorder, SIGKILL), 0);
  const auto code = launcher.wait_for(120s);
  ASSERT_TRUE(code.has_value()) << launcher.output();
  EXPECT_NE(launcher.output().find("recorder killed by SIGKILL"), std::string::npos)
      << launcher.output();
  // Messages of poise/sensors in a file, by `poise info --json` (exit 0 complete, 1 cut short).
  auto sensors = [](const fs::path& file, int expected_code) {
    // The JSON report alone (stdout; an incomplete file's warning on stderr would interleave).
    auto [rc, out] =
        run_command({"/bin/sh", "-c",
                     "exec '" + bin("poise") + "' info --json '" + file.string() + "' 2>/dev/null"},
                    60s);
    EXPECT_EQ(rc, expected_code) << file << ":\n" << out;
    const Json info = Json::parse(out, nullptr, false);
    if (info.is_discarded() || !info.contains("topics")) return std::uint64_t{0};
    for (const auto& t : info["topics"])
      if (t.value("topic", "") == "poise/sensors") return t.value("messages", std::uint64_t{0});
    return std::uint64_t{0};
  };
  // Killed after t = 1 s: the file it was writing holds that second, cut short (SIGKILL).
  EXPECT_GT(sensors(rec, 1), 500u) << "the recording before the crash is kept";
  // Its restart recorded the rest of the run to rec.1.mcap and ended it properly.
  ASSERT_TRUE(fs::exists(dir / "rec.1.mcap")) << launcher.output();
  EXPECT_GT(sensors(dir / "rec.1.mcap", 0), 500u);
  // The launch's result names both files.
  const Json r = Json::parse(std::ifstream(dir / "rec.json"));
  EXPECT_EQ(r["components"]["recorder"]["restarts"], 1) << r.dump(2);
  EXPECT_EQ(r["components"]["recorder"]["recordings"],
            Json::array({rec.string(), (dir / "rec.1.mcap").string()}))
      << r.dump(2);
}

// A second launch of a host of a running deployment is refused: it would put a second simulator
// and controller on the deployment's DDS domain (and share its logs and recording). Both are
// started the way a user in the file's directory would, `poise launch twice.yaml`: a bare file
// name used to fail ("cannot make absolute path").
TEST(Launch, ASecondLaunchOfARunningHostIsRefused) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("second_launch");
  write_local_deployment(dir / "twice.yaml", "twice", domain, 30);
  auto in_dir = [&](const std::string& args) {
    return std::vector<std::string>{
        "/bin/sh", "-c",
        "cd '" + dir.string() + "' && exec '" + bin("poise") + "' launch twice.yaml " + args};
  };
  ChildProcess first(in_dir(""), {}, false, true);
  ASSERT_TRUE(first.wait_for_output("t=1.0 s", 60s)) << first.output();
  auto [code, out] = run_command(in_dir("-q"), 60s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("twice on host local is already running (pid " + std::to_string(first.pid()) +
                     ", logs in results/twice.local.logs)"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("share its DDS domain " + std::to_string(domain)), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "results" / "twice.local.2.logs"));
  ASSERT_EQ(::kill(first.pid(), SIGINT), 0);
  const auto first_code = first.wait_for(60s);
  EXPECT_TRUE(first_code.has_value()) << first.output();
}

// Anyone on the domain can publish: the simulator refuses an absurd push (it threw the robot
// 604 m before), and joint commands from a second writer are refused by the robot side (one
// commanding writer): a forger publishing zero-gain commands stamped with the live tick (read
// from poise/sensors) for 0.5 s does not move the robot (it fell from 0.87 to 0.15 m within
// 0.25 s before), and the run fails naming the cause.
TEST(Launch, AnAbsurdPushAndASecondCommandWriterAreRefusedAndTheRobotStands) {
  const int domain = poise::testing::unique_domain_id();
  const fs::path dir = work_dir("forged");
  ChildProcess launcher(run_args("standing", domain, dir, {"--realtime", "--duration", "5"}), {},
                        false, true);
  ASSERT_TRUE(launcher.wait_for_output("t=1.0 s", 60s)) << launcher.output();
  auto [code, out] = run_command({bin("poise"), "push", "--domain", std::to_string(domain), "--force",
                              "1e9", "0", "0", "--duration", "0.1"},
                             30s);
  EXPECT_EQ(code, 1) << out;  // refused: the ground truth never shows it
  EXPECT_NE(out.find("did not apply"), std::string::npos) << out;
  std::uint64_t forged_sent = 0;
  {
    poise::dds::DdsOptions o = poise::dds::dds_options_from_env();
    o.domain_id = domain;
    poise::dds::Participant participant(o);
    poise::dds::Subscriber<poise::msg::Sensors> sensors(participant);
    poise::dds::Publisher<poise::msg::JointCommand> forged(participant);
    EXPECT_TRUE(forged.wait_for_matches(1, 10s));
    poise::msg::Sensors frame;
    poise::msg::JointCommand c;  // zero gains, zero torque: the robot would collapse
    c.mode(poise::msg::COMMAND_TORQUE);
    const auto end = std::chrono::steady_clock::now() + 500ms;
    while (std::chrono::steady_clock::now() < end) {
      if (sensors.take_latest(frame)) {
        c.header(frame.header());
        c.joint_count(frame.joint_count());
        for (std::size_t j = 0; j < frame.joint_count(); ++j) c.q_ref()[j] = frame.q()[j];
        forged_sent += forged.publish(c) ? 1 : 0;
      }
      std::this_thread::sleep_for(200us);
    }
  }
  ASSERT_GT(forged_sent, 100u);
  const auto rc = launcher.wait_for(60s);
  ASSERT_TRUE(rc.has_value()) << launcher.output();
  EXPECT_EQ(*rc, 1) << launcher.output();
  const Json result = Json::parse(std::ifstream(dir / "run.json"));
  std::printf("forged %llu commands: %s\n", static_cast<unsigned long long>(forged_sent),
              result["failed_criteria"].dump().c_str());
  // The robot stood: the only failed criterion is the second writer.
  ASSERT_EQ(result["failed_criteria"].size(), 1u) << result.dump(2);
  EXPECT_NE(result["failed_criteria"][0].get<std::string>().find("second writer"),
            std::string::npos)
      << result.dump(2);
  EXPECT_GT(result["misses"]["robot_foreign_commands"].get<std::uint64_t>(), 0u);
  EXPECT_TRUE(result["controller_fall"].is_null()) << result.dump(2);
  std::ifstream err(dir / "logs" / "sim.err");
  const std::string log((std::istreambuf_iterator<char>(err)), {});
  EXPECT_NE(log.find("exceeds the limit"), std::string::npos) << log;
  EXPECT_NE(log.find("from a second writer"), std::string::npos) << log;
  const Json summary = Json::parse(std::ifstream(dir / "logs" / "sim.summary.json"));
  EXPECT_EQ(summary["pushes_refused"], 1) << summary.dump(2);
  EXPECT_GT(summary["foreign_commands"].get<std::uint64_t>(), 100u) << summary.dump(2);
}

// DDS Security (Cyclone): the secured stack balances; a participant without credentials can
// neither read the state nor push the robot; an authenticated operator can push but may not
// write joint commands (access control). Lockstep, so that the verdict does not depend on how
// busy the machine is (the secured loop's real-time latency is in deploy/dds/README.md).
TEST(Launch, SecuredStackKeepsOutsidersAndEnforcesWhoWritesWhat) {
  int domain = poise::testing::unique_domain_id();
  if (domain > 230) GTEST_SKIP() << "Cyclone's security plugins take domains 0..230 only";
  const fs::path dir = work_dir("security");
  const std::string sec = (dir / "sec").string();
  {
    auto [code, out] = run_command({bin("poise"), "security", "init", sec}, 120s);
    ASSERT_EQ(code, 0) << out;
  }
  ChildProcess launcher(
      run_args("standing", domain, dir, {"--lockstep", "--duration", "60", "--security", sec}),
      {}, false, true);
  ASSERT_TRUE(launcher.wait_for_output("t=1.0 s", 60s)) << launcher.output();
  const std::string d = std::to_string(domain);
  {  // no credentials: sees nothing
    auto [code, out] = run_command({bin("poise"), "topic", "echo", "poise/state", "--domain", d,
                                "--once", "--timeout", "3"},
                               30s);
    EXPECT_EQ(code, 1) << out;
  }
  {  // no credentials: the simulator never matches the push
    auto [code, out] = run_command({bin("poise"), "push", "--domain", d, "--force", "50", "0", "0",
                                "--wait-ms", "3000"},
                               30s);
    EXPECT_NE(code, 0) << out;
    EXPECT_NE(out.find("no simulator"), std::string::npos) << out;
  }
  {  // the operator reads the state
    auto [code, out] = run_command({bin("poise"), "topic", "echo", "poise/state", "--domain", d,
                                "--once", "--timeout", "10", "--security", sec, "--identity",
                                "operator"},
                               30s);
    EXPECT_EQ(code, 0) << out;
    EXPECT_NE(out.find("com_W"), std::string::npos) << out;
  }
  {  // the operator may push
    auto [code, out] = run_command({bin("poise"), "push", "--domain", d, "--force", "20", "0", "0",
                                "--security", sec, "--identity", "operator"},
                               30s);
    EXPECT_EQ(code, 0) << out;
  }
  {  // ... but not command the joints
    auto [code, out] = run_command({bin("poise"), "topic", "pub", "poise/joint_command", "{}",
                                "--count", "1", "--domain", d, "--security", sec, "--identity",
                                "operator"},
                               30s);
    EXPECT_NE(code, 0) << out;
    EXPECT_NE(out.find("Not Allowed By Security"), std::string::npos) << out;
  }
  const auto rc = launcher.wait_for(240s);
  ASSERT_TRUE(rc.has_value()) << launcher.output();
  EXPECT_EQ(*rc, 0) << launcher.output();
  std::ifstream err(dir / "logs" / "sim.err");
  const std::string log((std::istreambuf_iterator<char>(err)), {});
  EXPECT_NE(log.find("push 1: 20.0 N"), std::string::npos) << log;
  const Json r = Json::parse(std::ifstream(dir / "run.json"));
  std::printf("secured lockstep stack: tick latency p50 %.0f us, p99 %.0f us\n",
              r["tick_latency_us"]["p50"].get<double>(), r["tick_latency_us"]["p99"].get<double>());
}

// The shipped scenarios in which contacts change (#20 item 3), distributed in lockstep as
// `poise run NAME` runs them: the estimator's contact flags drive the controller node, and the
// step in place is played by a poise-reference process that `poise run` starts from the
// scenario's `reference:` key. The in-process twins are tests/estimator/contact_events_test.cpp
// and tests/controller/step_in_place_test.cpp.
// The scenario's estimator: {contact_ft_noise: N} (the contact detector's light-touch rule) and
// {contact_rest_time: S} (its resting rule) reach the distributed estimator (its summary says what
// it ran with).
TEST(Launch, TheScenarioSetsTheEstimatorsLightTouchRule) {
  // scenario::estimator_contact_ft_noise: the estimator section's value (0: the rule off), else
  // the simulated F/T's noise (sensors.foot_ft.force_noise_std), else the default sensors' 0.5 N.
  const fs::path dir = work_dir("light_touch");
  const std::string robot =
      (fs::path(POISE_SOURCE_DIR) / "deploy/robots/poise_humanoid/robot.yaml").string();
  const poise::sim::ForceTorqueSensorConfig default_ft = poise::sim::industrial_foot_ft();
  ASSERT_GT(default_ft.force_noise_std, 0.0);
  struct Case {
    std::string name, section;
    double expected;
    /// The resting rule (estimator: {contact_rest_time: S}; EstimatorConfig's when not given).
    double rest_time = poise::estimator::EstimatorConfig{}.contact_rest_time;
  };
  const std::vector<Case> cases{
      {"set", "estimator: {contact_ft_noise: 0.25, contact_rest_time: 0.05}\n", 0.25, 0.05},
      {"off", "estimator: {contact_ft_noise: 0, contact_rest_time: 0}\n", 0.0, 0.0},
      {"from_sensor", "sensors: {foot_ft: {force_noise_std: 0.8}}\n", 0.8},
      {"default", "", default_ft.force_noise_std}};
  for (const Case& c : cases) {
    const fs::path file = dir / (c.name + ".yaml");
    std::ofstream(file) << "name: " << c.name << "\nrobot: {config: " << robot
                        << "}\nduration: 0.5\n" << c.section;
    const fs::path logs = dir / (c.name + ".logs");
    auto [code, out] = run_command({bin("poise"), "run", file.string(), "-q", "--domain",
                                    std::to_string(poise::testing::unique_domain_id()), "-o",
                                    (dir / (c.name + ".json")).string(), "--log-dir",
                                    logs.string()},
                                   120s);
    EXPECT_EQ(code, 0) << c.name << ":\n" << out;
    std::ifstream summary_file(logs / "estimator.summary.json");
    ASSERT_TRUE(summary_file.good()) << c.name << ": no estimator summary";
    const Json summary = Json::parse(summary_file);
    ASSERT_TRUE(summary.contains("contact_ft_noise")) << summary.dump(2);
    EXPECT_DOUBLE_EQ(summary["contact_ft_noise"].get<double>(), c.expected) << c.name;
    ASSERT_TRUE(summary.contains("contact_rest_time")) << summary.dump(2);
    EXPECT_DOUBLE_EQ(summary["contact_rest_time"].get<double>(), c.rest_time) << c.name;
  }
}

TEST(Launch, ScenariosInWhichContactsChangeSurviveDistributed) {
  const fs::path dir = work_dir("contact_changes");
  for (const std::string name : {"drop_onto_feet", "lateral_push_unloads_foot", "step_in_place"}) {
    const fs::path json = dir / (name + ".json");
    auto [code, out] =
        run_command({bin("poise"), "run", name, "-q", "--domain",
                 std::to_string(poise::testing::unique_domain_id()), "-o", json.string(),
                 "--log-dir", (dir / (name + ".logs")).string()},
                240s);
    EXPECT_EQ(code, 0) << name << ":\n" << out;
    if (!fs::exists(json)) {
      ADD_FAILURE() << name << ": no result file";
      continue;
    }
    const Json r = Json::parse(std::ifstream(json));
    EXPECT_TRUE(r["survived"].get<bool>()) << name << ": " << r.dump(2);
    std::printf("%-26s distributed lockstep: survived %d, CoM error max %.1f mm, foot slip max "
                "%.1f mm\n",
                name.c_str(), r["survived"].get<bool>() ? 1 : 0,
                r.value("com_error_max_m", -1.0) * 1e3, r.value("foot_slip_max_m", -1.0) * 1e3);
  }
}

// Two runs at once of scenarios with one name (a parallel sweep, two copies of a scenario) each
// report their own run. `poise run` reads its components' results from its log directory: with a
// shared results/<name>.logs each read the other's files and said nothing (found running two
// pushes of one scenario at once, 2026-12-05). Now a run holds its log directory (log_dir.hpp):
// the second default one takes <name>.2.logs and <name>.2.json; a --log-dir in use is refused
// naming the run that holds it, and is free again once that run is gone, however it ended.
TEST(Launch, TwoRunsOfOneScenarioAtOnceEachReportTheirOwn) {
  const fs::path dir = work_dir("twin");
  const std::string robot =
      (fs::path(POISE_SOURCE_DIR) / "deploy/robots/poise_humanoid/robot.yaml").string();
  const std::vector<double> durations{0.5, 1.0};
  for (double d : durations)
    std::ofstream(dir / ("twin_" + std::to_string(static_cast<int>(d * 10)) + ".yaml"))
        << "name: twin\nrobot: {config: " << robot << "}\nduration: " << d << "\n";
  // Default output and log directory, both started in `dir`.
  std::vector<std::unique_ptr<ChildProcess>> runs;
  for (double d : durations) {
    const std::string file = "twin_" + std::to_string(static_cast<int>(d * 10)) + ".yaml";
    runs.push_back(std::make_unique<ChildProcess>(
        std::vector<std::string>{
            "/bin/sh", "-c",
            "cd '" + dir.string() + "' && exec '" + bin("poise") + "' run -q " + file},
        std::vector<std::string>{}, false, true));
  }
  for (auto& r : runs) {
    const auto code = r->wait_for(180s);
    EXPECT_EQ(code.value_or(-1), 0) << r->output();
  }
  std::set<double> reported;
  for (const char* name : {"twin.json", "twin.2.json"}) {
    std::ifstream in(dir / "results" / name);
    ASSERT_TRUE(in.good()) << "no " << name;
    const Json r = Json::parse(in);
    reported.insert(std::round(r.at("sim_time_s").get<double>() * 10) / 10);
  }
  EXPECT_EQ(reported, (std::set<double>{0.5, 1.0})) << "each run reports its own simulated time";
  for (const char* logs : {"twin.logs", "twin.2.logs"})
    EXPECT_TRUE(fs::exists(dir / "results" / logs / "sim.summary.json")) << logs;

  // A --log-dir in use is refused, naming the run that holds it.
  const fs::path shared = dir / "shared.logs";
  const fs::path file = dir / "twin_10.yaml";
  ChildProcess holder({bin("poise"), "run", file.string(), "--realtime", "--duration", "60",
                       "--domain", std::to_string(poise::testing::unique_domain_id()), "-o",
                       (dir / "holder.json").string(), "--log-dir", shared.string()},
                      {}, false, true);
  ASSERT_TRUE(holder.wait_for_output("t=1.0 s", 60s)) << holder.output();
  auto [code, out] = run_command({bin("poise"), "run", file.string(), "-q", "-o",
                                  (dir / "second.json").string(), "--log-dir", shared.string()},
                                 60s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("is in use by another run (pid " + std::to_string(holder.pid()) + ")"),
            std::string::npos)
      << out;
  EXPECT_FALSE(fs::exists(dir / "second.json")) << "a refused run writes no result";
  // Killed without a chance to clean up, the holder leaves the directory free.
  ASSERT_EQ(::kill(holder.pid(), SIGKILL), 0);
  holder.wait_for(10s);
  std::tie(code, out) =
      run_command({bin("poise"), "run", file.string(), "-q", "--duration", "0.3", "-o",
                   (dir / "third.json").string(), "--log-dir", shared.string()},
                  120s);
  EXPECT_EQ(code, 0) << out;
}
