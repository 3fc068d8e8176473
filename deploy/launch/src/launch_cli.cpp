// `poise launch DEPLOYMENT.yaml [--host NAME] [--check]`: starts one machine's share of a
// deployment (deploy/deployments/README.md) and supervises it.
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sched.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <arpa/inet.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <set>
#include <thread>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "poise/launch/child.hpp"
#include "poise/launch/deployment.hpp"
#include "poise/launch/launch.hpp"
#include "poise/launch/log_dir.hpp"
#include "poise/launch/supervisor.hpp"
#include "poise/cli/parse.hpp"

namespace poise::launch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

std::atomic<int> g_signal{0};
void on_signal(int sig) {
  g_signal.store(sig);
}

std::set<std::string> local_addresses() {
  std::set<std::string> out;
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return out;
  for (ifaddrs* a = list; a; a = a->ifa_next) {
    if (!a->ifa_addr || a->ifa_addr->sa_family != AF_INET) continue;
    char buf[INET_ADDRSTRLEN];
    const auto* sin = reinterpret_cast<const sockaddr_in*>(a->ifa_addr);
    if (::inet_ntop(AF_INET, &sin->sin_addr, buf, sizeof(buf))) out.insert(buf);
  }
  ::freeifaddrs(list);
  return out;
}

/// Why SCHED_FIFO `priority` would be refused here ("" if it is permitted).
std::string fifo_refusal(int priority) {
  if (priority <= 0 || ::geteuid() == 0) return "";
  rlimit rl{};
  if (::getrlimit(RLIMIT_RTPRIO, &rl) == 0 && rl.rlim_cur >= static_cast<rlim_t>(priority))
    return "";
  return "SCHED_FIFO " + std::to_string(priority) +
         " needs root, CAP_SYS_NICE or an RLIMIT_RTPRIO of at least " + std::to_string(priority) +
         " (ulimit -r); it will run with normal scheduling";
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& a : v)
    s += (s.empty() ? "" : " ") + (a.find(' ') == std::string::npos ? a : "'" + a + "'");
  return s;
}

std::string cpus_text(const std::vector<int>& cpus) {
  std::string s;
  for (int c : cpus)
    s += (s.empty() ? "" : ",") + std::to_string(c);
  return s;
}

bool is_node(const Component& c) {
  return c.kind == "sim" || c.kind == "estimator" || c.kind == "controller" ||
         c.kind == "contact";
}

/// The files a recorder to `output` wrote since `since`: `output` itself, the numbered files of
/// its restarts (<stem>.<k><ext>) and the split files of either (<stem>[.<k>]_<n><ext>), by name.
std::vector<std::string> recordings_since(const std::string& output, fs::file_time_type since) {
  const fs::path out(output);
  const std::string stem = out.stem().string();
  const std::string ext = out.has_extension() ? out.extension().string() : ".mcap";
  std::vector<std::pair<std::pair<long, long>, std::string>> found;  // ((k, n), path)
  std::error_code ec;
  const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
  for (const auto& f : fs::directory_iterator(dir, ec)) {
    const std::string name = f.path().filename().string();
    if (name.size() < stem.size() + ext.size() || name.compare(0, stem.size(), stem) != 0 ||
        name.compare(name.size() - ext.size(), ext.size(), ext) != 0)
      continue;
    // What lies between the stem and the extension: "", ".<k>", "_<n>" or ".<k>_<n>".
    const std::string mid = name.substr(stem.size(), name.size() - stem.size() - ext.size());
    static const std::regex numbered(R"((?:\.([0-9]{1,9}))?(?:_([0-9]{1,9}))?)");
    std::smatch m;
    if (!std::regex_match(mid, m, numbered)) continue;
    const auto written = fs::last_write_time(f.path(), ec);
    if (ec || written < since) continue;
    const long k = m[1].matched ? std::stol(m[1].str()) : 0;
    const long n = m[2].matched ? std::stol(m[2].str()) : 0;
    found.push_back({{k, n}, f.path().string()});
  }
  std::sort(found.begin(), found.end());  // in the order they were recorded
  std::vector<std::string> paths;
  for (auto& [key, path] : found)
    paths.push_back(std::move(path));
  return paths;
}

/// `poise launch`'s command line.
struct LaunchArgs {
  std::string file, host_name, output, log_dir, dds_files;
  bool check = false, quiet = false;
  double duration = 0;
  int domain = -1;
};

/// Parses `poise launch`'s command line into `a`. Returns the exit status when the command line
/// ends the verb (0 after --help, 2 for a usage error), else -1.
int parse_launch_args(int argc, char** argv, LaunchArgs& a) {
  CLI::App app{
      "Start this machine's share of a deployment: which components run on which host, with "
      "their DDS vendor, options, CPU affinity, real-time priority and restart policy, from one "
      "YAML file (deploy/deployments/README.md). The DDS configuration of each host is generated "
      "from the file: unicast to the deployment's hosts, this host's address only, no "
      "multicast. The launcher owns its components: none survives it."};
  app.name("poise launch");
  app.add_option("deployment", a.file, "deployment YAML file")->required()->check(
      CLI::ExistingFile);
  app.add_option("--host", a.host_name,
                 "the host to start (default: the one whose address is this machine's, or the "
                 "only one)");
  app.add_flag("--check", a.check,
               "validate the file and print what each host runs; start nothing");
  app.add_option("-o,--output", a.output, "JSON result (default: results/<name>.<host>.json)");
  app.add_option("--log-dir", a.log_dir,
                 "logs and generated DDS files, held by this launch alone: one in use is refused, "
                 "and so is a second launch of this host of the deployment with the default "
                 "(default: results/<name>.<host>.logs)");
  app.add_option("--duration", a.duration,
                 "stop after this many seconds (default: when the simulator of this host ends, "
                 "else at Ctrl-C / SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--dds-files", a.dds_files,
                 "write this host's generated DDS files (cyclone.xml, fastdds.xml) to this "
                 "directory and exit: for tools on the host, e.g. `poise topic list --dds-config "
                 "DIR/cyclone.xml`");
  app.add_option("--domain", a.domain,
                 "DDS domain id instead of the file's (every host of the deployment must be given "
                 "the same; $POISE_DDS_DOMAIN does not override a file's domain)")
      ->check(CLI::Range(0, 232));
  app.add_flag("-q,--quiet", a.quiet, "only problems and the final line");
  POISE_CLI_PARSE(app, argc, argv);
  return -1;
}

/// The deployment file into `d`, with --domain. Returns 2 when it is refused (said), else -1.
int load_for_launch(const LaunchArgs& a, Deployment& d) {
  try {
    d = load_deployment(a.file, a.host_name);
  } catch (const DeploymentError& e) {
    std::fprintf(stderr, "poise launch: %s\n", e.what());
    return 2;
  }
  if (a.domain >= 0) {
    if (!d.security.empty() && a.domain > 230) {
      std::fprintf(stderr, "poise launch: --domain %d: DDS Security takes domains 0..230 "
                           "(Cyclone's plugins)\n", a.domain);
      return 2;
    }
    d.domain = a.domain;
  }
  return -1;
}

/// --check: what each host (or the one named) runs, and how.
void print_check(const Deployment& d, const std::string& host_name) {
  std::printf("deployment %s: domain %d, %s%s%s\n", d.name.c_str(), d.domain,
              d.realtime ? "real time" : "lockstep", d.scenario.empty() ? "" : ", scenario ",
              d.scenario.c_str());
  for (const auto& h : d.hosts) {
    if (!host_name.empty() && h.name != host_name) continue;
    std::printf("host %s (%s):\n", h.name.c_str(), h.address.c_str());
    const auto comps = d.components_on(h.name);
    if (comps.empty()) std::printf("  (nothing)\n");
    for (const Component* c : comps) {
      const fs::path cfg =
          fs::path("results") / (d.name + "." + h.name + ".logs") / "dds" / (c->dds + ".xml");
      std::printf("  %-11s %s\n", c->name.c_str(),
                  join(command_line(d, *c, bin_dir(), cfg)).c_str());
      std::printf("              restart %s (at most %d)%s%s%s%s\n", to_string(c->restart),
                  c->max_restarts, c->cpus.empty() ? "" : ", CPUs ",
                  cpus_text(c->cpus).c_str(),
                  c->priority > 0 ? (", SCHED_FIFO " + std::to_string(c->priority)).c_str() : "",
                  fifo_refusal(c->priority).empty()
                      ? ""
                      : (" (on this machine: " + fifo_refusal(c->priority) + ")").c_str());
    }
  }
}

/// Which host is this: --host, the only one, or the one with an address of this machine. Null
/// when there is none (said).
const Host* this_host(const Deployment& d, const LaunchArgs& a) {
  if (!a.host_name.empty()) {
    const Host* host = d.find_host(a.host_name);
    if (!host) {
      std::string names;
      for (const auto& h : d.hosts)
        names += (names.empty() ? "" : ", ") + h.name;
      std::fprintf(stderr, "poise launch: no host '%s' in %s (hosts: %s)\n", a.host_name.c_str(),
                   a.file.c_str(), names.c_str());
    }
    return host;
  }
  if (d.hosts.size() == 1) return &d.hosts[0];
  const auto mine = local_addresses();
  std::vector<const Host*> matches;
  for (const auto& h : d.hosts)
    if (mine.count(h.address)) matches.push_back(&h);
  if (matches.size() != 1) {
    std::fprintf(stderr,
                 "poise launch: name the host to start with --host (%zu of the file's hosts have "
                 "an address of this machine); --check shows what each runs\n",
                 matches.size());
    return nullptr;
  }
  return matches[0];
}

/// --dds-files: the host's generated DDS files into `dir`.
void write_dds_files(const Deployment& d, const Host& host, const std::string& dir) {
  fs::create_directories(dir);
  for (const char* v : {"cyclone", "fastdds"})
    std::ofstream(fs::path(dir) / (std::string(v) + ".xml")) << dds_config_xml(d, host, v);
  std::printf("%s/cyclone.xml and %s/fastdds.xml: DDS files of host %s (%s), domain %d\n",
              dir.c_str(), dir.c_str(), host.name.c_str(), host.address.c_str(), d.domain);
}

/// The log directory, this launch's alone (log_dir.hpp). A second launch of this host of the
/// deployment is refused: it would share the deployment's DDS domain with the first (two
/// simulators, two controllers on one robot's topics) and its recording. Empty when refused
/// (said).
std::optional<LogDirLock> lock_log_dir(const Deployment& d, const Host& host,
                                       const std::string& log_dir) {
  try {
    const fs::path dir = log_dir.empty()
                             ? fs::path("results") / (d.name + "." + host.name + ".logs")
                             : fs::path(log_dir);
    std::string holder;
    std::optional<LogDirLock> lock = LogDirLock::try_lock(dir, &holder);
    if (!lock) {
      if (log_dir.empty())
        std::fprintf(stderr,
                     "poise launch: %s on host %s is already running (%s, logs in %s): a second "
                     "launch would share its DDS domain %d\n",
                     d.name.c_str(), host.name.c_str(), holder.c_str(), dir.c_str(), d.domain);
      else
        std::fprintf(stderr, "poise launch: the log directory %s is in use by another run (%s)\n",
                     dir.c_str(), holder.c_str());
    }
    return lock;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise launch: %s\n", e.what());
    return std::nullopt;
  }
}

/// The log directory's generated files (DDS, the controller's YAML) and the result's directory;
/// an older result never stands for this run.
void prepare_outputs(const Deployment& d, const Host& host, const fs::path& logs,
                     const fs::path& result_path) {
  fs::create_directories(logs / "dds");
  if (result_path.has_parent_path()) fs::create_directories(result_path.parent_path());
  std::error_code ignored;
  fs::remove(result_path, ignored);  // an older result never stands for this run
  for (const char* v : {"cyclone", "fastdds"})
    std::ofstream(logs / "dds" / (std::string(v) + ".xml")) << dds_config_xml(d, host, v);
  if (!d.controller_yaml.empty())  // poise-controller --config (command_line)
    std::ofstream(logs / "controller.yaml")
        << "# the controller: section of " << d.scenario << "\n" << d.controller_yaml << "\n";
}

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

/// Each start and restart on the console (pid, CPUs, priority), and each clean finish.
void report_starts(Supervisor& supervisor, bool quiet) {
  supervisor.on_start = [quiet](const Supervisor::Entry& e) {
    if (const std::string why = fifo_refusal(e.spec.scheduling.priority); !why.empty())
      std::fprintf(stderr, "poise launch: %s: %s\n", e.spec.name.c_str(), why.c_str());
    if (!quiet)
      std::printf("  %-11s pid %d%s%s%s\n", e.spec.name.c_str(), static_cast<int>(e.child->pid()),
                  e.spec.scheduling.cpus.empty()
                      ? ""
                      : (", CPUs " + cpus_text(e.spec.scheduling.cpus)).c_str(),
                  e.spec.scheduling.priority > 0
                      ? (", SCHED_FIFO " + std::to_string(e.spec.scheduling.priority)).c_str()
                      : "",
                  e.restarts > 0 ? (", restart " + std::to_string(e.restarts)).c_str() : "");
    std::fflush(stdout);
  };
  supervisor.on_finish = [quiet](const Supervisor::Entry& e) {
    if (!quiet) std::printf("  %s finished (%s)\n", e.spec.name.c_str(), e.exits.back().c_str());
  };
}

/// This host's components as the supervisor starts them; `component_of` names each, `sim` is
/// the simulator (null when it runs elsewhere).
std::vector<ComponentSpec> component_specs(const Deployment& d,
                                           const std::vector<const Component*>& components,
                                           const fs::path& logs,
                                           std::map<std::string, const Component*>& component_of,
                                           const Component*& sim) {
  std::vector<ComponentSpec> specs;
  for (const Component* c : components) {
    ComponentSpec spec;
    spec.name = c->name;
    spec.argv = command_line(d, *c, bin_dir(), fs::absolute(logs / "dds" / (c->dds + ".xml")));
    if (is_node(*c))
      spec.argv.insert(spec.argv.end(),
                       {"--summary", (logs / (c->name + ".summary.json")).string()});
    spec.scheduling = Scheduling{c->cpus, c->priority};
    spec.restart = c->restart;
    spec.max_restarts = c->max_restarts;
    spec.ends_run = c->kind == "sim";
    spec.stop_grace_ms = c->kind == "recorder" ? 30000 : 3000;
    if (c->kind == "sim") sim = c;
    component_of[c->name] = c;
    specs.push_back(std::move(spec));
  }
  return specs;
}

/// Supervises the started components until the run ends: the simulator of this host (or every
/// component) ended, one failed, a signal, or --duration. Relays the simulator's progress and
/// the robot side's safety events. Returns the failure ("" for none); `stopped_by` the signal.
std::string supervise(Supervisor& supervisor, const Component* sim, const LaunchArgs& a,
                      std::string& stopped_by) {
  const auto t0 = std::chrono::steady_clock::now();
  std::unique_ptr<LineFollower> progress, robot_log;
  if (sim) {
    const Supervisor::Entry* e = supervisor.find(sim->name);
    if (e && e->child) {
      progress = std::make_unique<LineFollower>(e->child->stdout_path());
      robot_log = std::make_unique<LineFollower>(e->child->stderr_path());
    }
  }
  while (true) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (progress && !a.quiet) {  // relay the simulator's progress lines
      for (const auto& line : progress->poll())
        if (line.rfind("progress ", 0) == 0) std::printf("  %s\n", line.c_str() + 9);
      std::fflush(stdout);
    }
    // The robot side's safety events on this console, even when quiet: commands that stopped
    // (HOLD, DAMP), an e-stop, commands from a second writer.
    if (robot_log) {
      for (const auto& line : robot_log->poll())
        if (line.find("safety: ") != std::string::npos ||
            line.find("second writer") != std::string::npos)
          std::printf("  robot side: %s\n", line.c_str());
      std::fflush(stdout);
    }
    const Supervisor::Status st = supervisor.poll();
    if (!st.failure.empty()) return st.failure;
    if (st.run_ended || st.all_ended) return "";
    if (g_signal.load() != 0) {
      // The normal end of a host without the simulator; an interruption of one with it.
      stopped_by = g_signal.load() == SIGINT ? "SIGINT" : "SIGTERM";
      return sim ? "interrupted by " + stopped_by + " before the simulator finished" : "";
    }
    if (a.duration > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() >= a.duration)
      return "";
  }
}

/// Stop: the simulator first (it writes its result), the nodes, the recorder last.
void stop_components(Supervisor& supervisor, const std::vector<const Component*>& components) {
  std::vector<std::string> order;
  for (const char* kind : {"sim", "estimator", "controller", "contact", "command", "recorder"})
    for (const Component* c : components)
      if (c->kind == kind) order.push_back(c->name);
  supervisor.stop(order);
}

/// The result's description of the launch and of each component (command, restarts, exits, a
/// recorder's files).
Json launch_result(const Deployment& d, const Host& host, const fs::path& logs,
                   const std::string& stopped_by, const Supervisor& supervisor,
                   const std::map<std::string, const Component*>& component_of,
                   fs::file_time_type launch_start) {
  Json j;
  j["deployment"] = d.name;
  j["file"] = fs::absolute(d.file).string();
  j["host"] = host.name;
  j["address"] = host.address;
  j["domain"] = d.domain;
  j["mode"] = d.realtime ? "realtime" : "lockstep";
  j["logs"] = logs.string();
  if (!stopped_by.empty()) j["stopped_by"] = stopped_by;
  j["components"] = Json::object();
  for (const auto& e : supervisor.entries()) {
    const Component& comp = *component_of.at(e->spec.name);
    Json c;
    c["kind"] = comp.kind;
    c["dds"] = comp.dds;
    c["command"] = e->spec.argv;
    c["pid"] = e->child ? e->child->pid() : -1;
    c["restarts"] = e->restarts;
    c["exits"] = e->exits;
    if (comp.kind == "recorder") c["recordings"] = recordings_since(comp.output, launch_start);
    j["components"][comp.name] = c;
  }
  return j;
}

/// A node's summary file (not an object when it wrote none or an unreadable one).
Json read_summary(const fs::path& path) {
  std::ifstream in(path);
  Json summary;
  try {
    summary = Json::parse(in);
  } catch (...) {
  }
  return summary;
}

/// The simulator's verdict into `j`: exit code 0 (survived) or 1; `failure` when it wrote no
/// result or refused commands of a second writer.
int judge_simulator(Supervisor& supervisor, const Component& sim, const fs::path& logs, Json& j,
                    std::string& failure) {
  const Json summary = read_summary(logs / (sim.name + ".summary.json"));
  if (!summary.is_object()) {
    const Supervisor::Entry* e = supervisor.find(sim.name);
    failure = "the simulator wrote no result (" +
              (e && !e->exits.empty() ? e->exits.back() : std::string("it did not start")) + ")";
    return 0;
  }
  j["sim"] = summary;
  j["survived"] = summary.value("survived", false);
  int code = j["survived"].get<bool>() ? 0 : 1;
  // One commanding writer: another process on the domain commanded the robot.
  const auto foreign = summary.value("foreign_commands", 0ULL);
  if (foreign > 0) {
    failure = std::to_string(foreign) +
              " joint commands from a second writer of poise/joint_command were refused by "
              "the simulator (another process on the domain commanded the robot; " +
              sim.name + ".err names both writers)";
    code = 1;
  }
  return code;
}

/// The controller on this host declared the robot fallen (FallConfig): it damps the joints
/// from then on; the result says when and why (as `poise run`'s controller_fall), and a run
/// with the simulator here does not count as survived (`code` 1).
void note_controller_fall(const std::vector<const Component*>& components, const fs::path& logs,
                          const Component* sim, Json& j, int& code) {
  for (const Component* c : components) {
    if (c->kind != "controller") continue;
    const Json summary = read_summary(logs / (c->name + ".summary.json"));
    if (summary.is_object() && summary.value("fall_tick", -1LL) >= 0) {
      j["controller_fall"] = {{"tick", summary.value("fall_tick", -1LL)},
                              {"reason", summary.value("fall", std::string())}};
      if (sim && j.value("survived", false)) {
        j["survived"] = false;
        code = 1;
      }
    }
  }
}

/// The final line(s) on the console.
void print_outcome(const Deployment& d, const Host& host, const Json& j,
                   const std::string& failure, int code, const Component* sim,
                   const fs::path& result_path) {
  if (!failure.empty()) {
    std::fprintf(stderr, "poise launch %s: host %s FAILED: %s -> %s\n", d.name.c_str(),
                 host.name.c_str(), failure.c_str(), result_path.c_str());
  } else if (sim) {
    const Json& s = j["sim"];
    std::printf("%s %s on host %s: com_error max %.3f m, foot slip %.4f m -> %s\n",
                code == 0 ? "SURVIVED" : "FAILED", d.name.c_str(), host.name.c_str(),
                s.value("com_error_max_m", 0.0), s.value("foot_slip_max_m", 0.0),
                result_path.c_str());
  } else {
    std::printf("poise launch %s: host %s stopped cleanly -> %s\n", d.name.c_str(),
                host.name.c_str(), result_path.c_str());
  }
  if (j.contains("controller_fall"))
    std::printf("  the controller declared the robot fallen at tick %lld (%s): joints damped\n",
                j["controller_fall"].value("tick", -1LL),
                j["controller_fall"].value("reason", std::string()).c_str());
}

/// Starts this host's components, supervises them until the run ends, stops them and writes the
/// result. Returns the exit status: 0 survived (or stopped cleanly), 1 fell, 2 failed.
int run_host(const Deployment& d, const Host& host, const LaunchArgs& a, const fs::path& logs,
             const fs::path& result_path) {
  install_signal_handlers();
  Supervisor supervisor("poise launch", logs);
  report_starts(supervisor, a.quiet);
  const auto components = d.components_on(host.name);
  const auto launch_start = fs::file_time_type::clock::now();
  // A launch's recording replaces the last launch's, as its result does (a recorder restarted
  // within this launch then goes on in a numbered file: command_line).
  std::error_code ignored;
  for (const Component* c : components)
    if (c->kind == "recorder" && !recorder_sets_if_exists(*c)) fs::remove(c->output, ignored);
  std::map<std::string, const Component*> component_of;
  const Component* sim = nullptr;
  std::vector<ComponentSpec> specs = component_specs(d, components, logs, component_of, sim);
  if (!a.quiet)
    std::printf("poise launch %s: host %s (%s), domain %d, %zu components, logs in %s\n",
                d.name.c_str(), host.name.c_str(), host.address.c_str(), d.domain,
                specs.size(), logs.c_str());
  std::string failure;
  try {
    for (auto& spec : specs)
      supervisor.start(std::move(spec));
  } catch (const std::exception& e) {
    failure = std::string("cannot start a component: ") + e.what();
  }
  std::string stopped_by;
  if (failure.empty()) failure = supervise(supervisor, sim, a, stopped_by);
  stop_components(supervisor, components);

  Json j = launch_result(d, host, logs, stopped_by, supervisor, component_of, launch_start);
  int code = 0;
  if (sim && failure.empty()) code = judge_simulator(supervisor, *sim, logs, j, failure);
  note_controller_fall(components, logs, sim, j, code);
  j["failed"] = !failure.empty();
  if (!failure.empty()) {
    j["failure"] = failure;
    if (sim) j["survived"] = false;
    code = 2;
  }
  std::ofstream(result_path) << j.dump(2) << "\n";
  print_outcome(d, host, j, failure, code, sim, result_path);
  return code;
}

}  // namespace

int launch_main(int argc, char** argv) {
  LaunchArgs a;
  if (const int status = parse_launch_args(argc, argv, a); status >= 0) return status;
  Deployment d;
  if (const int status = load_for_launch(a, d); status >= 0) return status;
  if (a.check) {
    print_check(d, a.host_name);
    return 0;
  }
  const Host* host = this_host(d, a);
  if (!host) return 2;
  if (!a.dds_files.empty()) {
    write_dds_files(d, *host, a.dds_files);
    return 0;
  }
  if (!local_addresses().count(host->address))
    std::fprintf(stderr,
                 "poise launch: warning: %s is not an address of this machine: DDS will not find "
                 "its interface\n",
                 host->address.c_str());
  const std::optional<LogDirLock> logs_lock = lock_log_dir(d, *host, a.log_dir);
  if (!logs_lock) return 2;
  const fs::path logs = logs_lock->dir();
  const fs::path result_path = a.output.empty()
                                   ? fs::path("results") / (d.name + "." + host->name + ".json")
                                   : fs::path(a.output);
  prepare_outputs(d, *host, logs, result_path);
  return run_host(d, *host, a, logs, result_path);
}

}  // namespace poise::launch
