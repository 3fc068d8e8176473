#include "poise/launch/deployment.hpp"

#include <cctype>
#include <arpa/inet.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "poise/contact/contact_optimizer.hpp"
#include "poise/controller/controller_config.hpp"
#include "poise/scenario/scenario.hpp"
#include "poise/sim/sim_config.hpp"

namespace poise::launch {
namespace fs = std::filesystem;

namespace {

const std::set<std::string> kKinds{"sim",     "estimator", "controller",
                                   "contact", "recorder",  "command"};
const std::vector<std::string> kStartOrder{"recorder", "contact", "estimator",
                                           "controller", "command", "sim"};

/// Collects every problem of a file, then throws them together.
class Problems {
 public:
  explicit Problems(fs::path file) : file_(std::move(file)) {}
  void add(const std::string& where, const std::string& what) {
    list_.push_back(where.empty() ? what : where + ": " + what);
  }
  void throw_if_any() const {
    if (list_.empty()) return;
    std::string msg = "deployment file " + file_.string() + ": " +
                      std::to_string(list_.size()) + " problem" + (list_.size() > 1 ? "s" : "");
    for (const auto& p : list_)
      msg += "\n  - " + p;
    throw DeploymentError(msg);
  }

 private:
  fs::path file_;
  std::vector<std::string> list_;
};

void allowed_keys(const YAML::Node& n, const std::string& where, const std::set<std::string>& keys,
                  Problems& p) {
  if (!n.IsMap()) return;
  for (const auto& kv : n) {
    const std::string k = kv.first.as<std::string>();
    if (!keys.count(k)) {
      std::string known;
      for (const auto& x : keys)
        known += (known.empty() ? "" : ", ") + x;
      p.add(where, "unknown key '" + k + "' (known: " + known + ")");
    }
  }
}

template <class T>
bool scalar(const YAML::Node& n, const std::string& where, T& out, Problems& p) {
  try {
    out = n.as<T>();
    return true;
  } catch (const YAML::Exception&) {
    p.add(where, "not a valid value: '" + (n.IsScalar() ? n.Scalar() : std::string("...")) + "'");
    return false;
  }
}

std::vector<std::string> strings(const YAML::Node& n, const std::string& where, Problems& p) {
  std::vector<std::string> out;
  if (!n) return out;
  if (!n.IsSequence()) {
    p.add(where, "must be a list, e.g. [--realtime]");
    return out;
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    std::string s;
    if (scalar(n[i], where + "[" + std::to_string(i) + "]", s, p)) out.push_back(s);
  }
  return out;
}

/// A path as written, relative to the working directory if it exists there, else to `base`.
std::string resolve_path(const std::string& p, const fs::path& base) {
  if (p.empty() || fs::path(p).is_absolute() || fs::exists(p)) return p;
  if (fs::exists(base / p)) return (base / p).string();
  return p;
}

}  // namespace

fs::path bin_dir() {
  if (const char* e = std::getenv("POISE_BIN_DIR"); e && *e) return e;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path(".") : exe.parent_path();
}

std::string resolve_scenario(const std::string& s, const fs::path& base) {
  const std::string direct = resolve_path(s, base);
  if (fs::exists(direct)) return direct;
  for (fs::path start : {fs::absolute(bin_dir()), fs::absolute(base)})
    for (fs::path d = start; !d.empty() && d != d.root_path(); d = d.parent_path())
      if (fs::exists(d / "deploy/scenarios" / (s + ".yaml")))
        return (d / "deploy/scenarios" / (s + ".yaml")).string();
  return s;
}

const char* to_string(Restart r) {
  switch (r) {
    case Restart::never:
      return "never";
    case Restart::on_failure:
      return "on-failure";
    case Restart::always:
      return "always";
  }
  return "?";
}

const Host* Deployment::find_host(const std::string& n) const {
  for (const auto& h : hosts)
    if (h.name == n) return &h;
  return nullptr;
}

std::vector<const Component*> Deployment::components_on(const std::string& host) const {
  std::vector<const Component*> out;
  for (const auto& c : components)
    if (c.host == host) out.push_back(&c);
  return out;
}

/// The scenario's controller section, checked by the controller's parser (a problem names the
/// key), with the contact optimiser's settings it carries.
void set_controller_section(const std::string& yaml, const std::string& scenario, Deployment& d,
                            Problems& p) {
  if (yaml.empty()) return;
  try {
    const controller::ControllerConfig c =
        controller::parse_controller_config(yaml, "scenario '" + scenario + "', controller");
    d.controller_yaml = yaml;
    d.contact_priority = contact::to_string(c.contact.priority);
    d.contact_torsion_limit = contact::to_string(c.contact.torsion_limit);
  } catch (const std::exception& e) {
    p.add("scenario", e.what());
  }
}

/// estimator.supports and contact.method of a scenario file, by YAML alone (no robot loaded).
void read_scenario_hints(const std::string& path, Deployment& d, Problems& p) {
  try {
    const YAML::Node root = YAML::LoadFile(path);
    if (root["estimator"] && root["estimator"]["supports"])
      d.estimator_supports = root["estimator"]["supports"].as<std::string>();
    if (root["contact"] && root["contact"]["method"])
      d.contact_method = root["contact"]["method"].as<std::string>();
    d.planned_support = "double";
    if (root["initial"] && root["initial"]["support"])
      d.planned_support = root["initial"]["support"].as<std::string>();
    if (root["controller"]) {
      YAML::Emitter e;
      e << root["controller"];
      set_controller_section(e.c_str(), path, d, p);
    }
  } catch (const YAML::Exception& e) {
    p.add("scenario", path + ": " + e.what());
  }
}

namespace {

/// The deployment file's YAML, a map. Throws DeploymentError.
YAML::Node read_deployment_yaml(const fs::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::BadFile&) {
    throw DeploymentError("deployment file " + file.string() + ": cannot be read");
  } catch (const YAML::Exception& e) {
    throw DeploymentError("deployment file " + file.string() + ": not valid YAML: " + e.what());
  }
  if (!root.IsMap()) throw DeploymentError("deployment file " + file.string() + ": not a map");
  return root;
}

/// The deployment's own settings: name, domain, mode, security, robot.
void read_settings(const YAML::Node& root, const fs::path& file, const fs::path& base,
                   Deployment& d, Problems& p) {
  d.name = file.stem().string();
  if (root["name"]) scalar(root["name"], "name", d.name, p);
  // It names files under results/ (result, logs, recording): the scenario format's rule.
  if (const std::string problem = scenario::plain_name_problem(d.name); !problem.empty())
    p.add("name", problem);
  if (!root["domain"]) {
    p.add("domain", "missing (the DDS domain id of the deployment, 0..232)");
  } else if (scalar(root["domain"], "domain", d.domain, p) && (d.domain < 0 || d.domain > 232)) {
    p.add("domain", std::to_string(d.domain) + " is outside 0..232");
  }
  std::string mode = "lockstep";
  if (root["mode"]) scalar(root["mode"], "mode", mode, p);
  if (mode != "lockstep" && mode != "realtime")
    p.add("mode", "'" + mode + "' is not lockstep or realtime");
  d.realtime = mode == "realtime";
  if (root["security"]) {
    scalar(root["security"], "security", d.security, p);
    d.security = resolve_path(d.security, base);
    if (!fs::is_directory(d.security) || !fs::exists(fs::path(d.security) / "ca.pem"))
      p.add("security", d.security + " is not a directory made by `poise security init`");
    if (d.domain > 230) p.add("domain", "DDS Security takes domains 0..230 (Cyclone's plugins)");
  }
  if (root["robot"]) {
    scalar(root["robot"], "robot", d.robot, p);
    d.robot = resolve_path(d.robot, base);
    if (!fs::exists(d.robot)) p.add("robot", "no such file: " + d.robot);
  }
}

/// hosts: name -> {address: IPv4}, each address once, loopback only for a single host.
void read_hosts(const YAML::Node& hosts, Deployment& d, Problems& p) {
  if (!hosts || !hosts.IsMap() || hosts.size() == 0) {
    p.add("hosts", "missing: a map of host name -> {address: IPv4}");
    return;
  }
  std::set<std::string> addresses;
  for (const auto& kv : hosts) {
    Host h;
    h.name = kv.first.as<std::string>();
    const std::string where = "hosts." + h.name;
    allowed_keys(kv.second, where, {"address"}, p);
    if (!kv.second.IsMap() || !kv.second["address"]) {
      p.add(where, "missing address (this host's IPv4 address on the DDS network)");
      continue;
    }
    scalar(kv.second["address"], where + ".address", h.address, p);
    in_addr a{};
    if (::inet_pton(AF_INET, h.address.c_str(), &a) != 1)
      p.add(where + ".address", "'" + h.address + "' is not an IPv4 address");
    else if (!addresses.insert(h.address).second)
      p.add(where + ".address", h.address + " is used by another host");
    d.hosts.push_back(h);
  }
  const bool loopback = std::any_of(d.hosts.begin(), d.hosts.end(), [](const Host& h) {
    return h.address.rfind("127.", 0) == 0;
  });
  if (loopback && d.hosts.size() > 1)
    p.add("hosts", "a loopback address (127.x) cannot be one of several hosts");
}

/// A component's kind (its name's when it names one), host, DDS vendor, options and command.
void read_component_what_and_where(const YAML::Node& n, const std::string& where,
                                   const YAML::Node& hosts, const Deployment& d,
                                   std::map<std::string, int>& per_kind, Component& c,
                                   Problems& p) {
  c.kind = kKinds.count(c.name) ? c.name : "";
  if (n["kind"]) scalar(n["kind"], where + ".kind", c.kind, p);
  if (c.kind.empty()) {
    p.add(where, "say its kind (sim, estimator, controller, contact, recorder, command)");
  } else if (!kKinds.count(c.kind)) {
    p.add(where + ".kind", "'" + c.kind +
                               "' is not one of sim, estimator, controller, contact, "
                               "recorder, command");
  }
  ++per_kind[c.kind];
  if (!n["host"]) {
    p.add(where, "missing host");
  } else if (scalar(n["host"], where + ".host", c.host, p) && !d.find_host(c.host) &&
             hosts && hosts.IsMap()) {
    p.add(where + ".host", "'" + c.host + "' is not among the hosts");
  }
  c.dds = "cyclone";
  if (n["dds"]) scalar(n["dds"], where + ".dds", c.dds, p);
  if (c.dds == "cyclonedds") c.dds = "cyclone";  // one vendor, two spellings
  if (c.dds != "cyclone" && c.dds != "fastdds")
    p.add(where + ".dds", "'" + c.dds + "' is not cyclone (cyclonedds) or fastdds");
  c.options = strings(n["options"], where + ".options", p);
  c.command = strings(n["command"], where + ".command", p);
  if (c.kind == "command" && c.command.empty())
    p.add(where + ".command", "a command component needs its program: [program, args...]");
  if (c.kind != "command" && !c.command.empty())
    p.add(where + ".command", "only for kind command; use options for extra arguments");
  if (n["output"]) {
    scalar(n["output"], where + ".output", c.output, p);
    if (c.kind != "recorder") p.add(where + ".output", "only for kind recorder");
  }
  if (c.kind == "recorder" && c.output.empty()) c.output = "results/" + d.name + ".mcap";
}

/// A component's CPUs, priority and restart policy.
void read_component_scheduling(const YAML::Node& n, const std::string& where, long ncpu,
                               Component& c, Problems& p) {
  if (n["cpu"]) {
    const YAML::Node cpu = n["cpu"];
    if (!cpu.IsSequence()) {
      p.add(where + ".cpu", "must be a list of CPU numbers, e.g. [1]");
    } else {
      for (std::size_t i = 0; i < cpu.size(); ++i) {
        int k = -1;
        if (!scalar(cpu[i], where + ".cpu", k, p)) continue;
        if (k < 0 || k >= ncpu)
          p.add(where + ".cpu", "CPU " + std::to_string(k) + " does not exist (this machine: 0.." +
                                    std::to_string(ncpu - 1) + ")");
        else
          c.cpus.push_back(k);
      }
    }
  }
  if (n["priority"] && scalar(n["priority"], where + ".priority", c.priority, p) &&
      (c.priority < 0 || c.priority > 99))
    p.add(where + ".priority", "SCHED_FIFO priority must be 1..99 (0: normal scheduling)");
  if (n["restart"]) {
    std::string r;
    scalar(n["restart"], where + ".restart", r, p);
    if (r == "never")
      c.restart = Restart::never;
    else if (r == "on-failure")
      c.restart = Restart::on_failure;
    else if (r == "always")
      c.restart = Restart::always;
    else
      p.add(where + ".restart", "'" + r + "' is not never, on-failure or always");
  }
  if (n["max_restarts"] && scalar(n["max_restarts"], where + ".max_restarts",
                                  c.max_restarts, p) &&
      c.max_restarts < 0)
    p.add(where + ".max_restarts", "must be >= 0");
  if (c.kind == "sim" && c.restart != Restart::never)
    p.add(where + ".restart", "the simulator is the run: it is never restarted");
}

/// components: name -> {kind, host, dds, options, command, output, cpu, priority, restart,
/// max_restarts}; at most one of each kind of the loop.
void read_components(const YAML::Node& comps, const YAML::Node& hosts, Deployment& d,
                     std::map<std::string, int>& per_kind, Problems& p) {
  const long ncpu = ::sysconf(_SC_NPROCESSORS_CONF);
  for (const auto& kv : comps) {
    Component c;
    c.name = kv.first.as<std::string>();
    const std::string where = "components." + c.name;
    const YAML::Node n = kv.second;
    if (!n.IsMap()) {
      p.add(where, "must be a map with at least a host");
      continue;
    }
    allowed_keys(n,
                 where,
                 {"kind", "host", "dds", "options", "command", "output", "cpu", "priority",
                  "restart", "max_restarts"},
                 p);
    read_component_what_and_where(n, where, hosts, d, per_kind, c, p);
    read_component_scheduling(n, where, ncpu, c, p);
    d.components.push_back(std::move(c));
  }
  for (const char* k : {"sim", "estimator", "controller", "contact"})
    if (per_kind[k] > 1)
      p.add("components", std::string("more than one ") + k +
                              " (two writers on one topic break the loop)");
}

/// The simulator's scenario: loaded when the simulator runs on `host` (or no host is named),
/// else read for its hints only (no robot loaded).
void read_scenario(const YAML::Node& root, const std::string& host, const fs::path& base,
                   Deployment& d, Problems& p) {
  if (!root["scenario"]) {
    p.add("scenario", "missing: the simulator needs a scenario (a file or a name)");
    return;
  }
  std::string s;
  scalar(root["scenario"], "scenario", s, p);
  d.scenario = resolve_scenario(s, base);
  if (!fs::exists(d.scenario)) {
    p.add("scenario", "no such file or scenario name: " + s);
    return;
  }
  bool sim_here = host.empty();
  for (const auto& c : d.components)
    sim_here = sim_here || (c.kind == "sim" && c.host == host);
  if (!sim_here) {
    read_scenario_hints(d.scenario, d, p);
    return;
  }
  try {
    const scenario::Scenario sc = scenario::load_scenario(d.scenario);
    d.estimator_supports = sc.estimator.supports;
    d.estimator_args = estimator_scenario_args(sc);
    set_controller_section(sc.controller_yaml, d.scenario, d, p);
    d.contact_method = sc.contact_method;
    d.planned_support = sc.support;
  } catch (const std::exception& e) {
    p.add("scenario", e.what());
  }
}

}  // namespace

Deployment load_deployment(const fs::path& file, const std::string& host) {
  Deployment d;
  d.file = file;
  Problems p(file);
  const YAML::Node root = read_deployment_yaml(file);
  // The file's directory, "." for a bare name (`poise launch one.yaml`: fs::absolute("") throws).
  const fs::path base = file.has_parent_path() ? file.parent_path() : fs::path(".");
  allowed_keys(root, "",
               {"name", "domain", "scenario", "robot", "mode", "security", "hosts", "components"},
               p);
  read_settings(root, file, base, d, p);
  const YAML::Node hosts = root["hosts"];
  read_hosts(hosts, d, p);
  const YAML::Node comps = root["components"];
  if (!comps || !comps.IsMap() || comps.size() == 0) {
    p.add("components", "missing: a map of component name -> {host: ...}");
  } else {
    std::map<std::string, int> per_kind;
    read_components(comps, hosts, d, per_kind, p);
    if (per_kind["sim"] == 1) read_scenario(root, host, base, d, p);
  }
  p.throw_if_any();
  std::stable_sort(d.components.begin(), d.components.end(),
                   [](const Component& a, const Component& b) {
                     auto rank = [](const std::string& k) {
                       return std::find(kStartOrder.begin(), kStartOrder.end(), k) -
                              kStartOrder.begin();
                     };
                     return rank(a.kind) < rank(b.kind);
                   });
  for (auto& c : d.components)
    if (c.kind == "recorder") c.output = resolve_path(c.output, fs::path("."));
  return d;
}

std::string dds_config_xml(const Deployment& d, const Host& host, const std::string& vendor) {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
    << "<!-- Generated by `poise launch` from " << d.file.string() << " for host " << host.name
    << " (" << host.address
    << "): unicast discovery to every host of the deployment, this host's address only, no "
       "multicast. Do not edit: edit the deployment file. -->\n";
  if (vendor == "cyclone") {
    x << "<CycloneDDS xmlns=\"https://cdds.io/config\">\n"
      << "  <Domain Id=\"any\">\n"
      << "    <General>\n"
      << "      <Interfaces>\n"
      << "        <NetworkInterface address=\"" << host.address << "\"/>\n"
      << "      </Interfaces>\n"
      << "      <AllowMulticast>false</AllowMulticast>\n"
      << "    </General>\n"
      << "    <Discovery>\n"
      << "      <ParticipantIndex>auto</ParticipantIndex>\n"
      << "      <MaxAutoParticipantIndex>60</MaxAutoParticipantIndex>\n"
      << "      <Peers>\n";
    for (const auto& h : d.hosts)
      x << "        <Peer address=\"" << h.address << "\"/>\n";
    x << "      </Peers>\n"
      << "    </Discovery>\n"
      << "  </Domain>\n"
      << "</CycloneDDS>\n";
  } else {
    x << "<dds xmlns=\"http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles\">\n"
      << "  <profiles>\n"
      << "    <transport_descriptors>\n"
      << "      <transport_descriptor>\n"
      << "        <transport_id>poise_udp_deployment</transport_id>\n"
      << "        <type>UDPv4</type>\n"
      << "        <interfaceWhiteList><address>" << host.address << "</address></interfaceWhiteList>\n"
      << "        <maxInitialPeersRange>60</maxInitialPeersRange>\n"
      << "      </transport_descriptor>\n"
      << "    </transport_descriptors>\n"
      << "    <participant profile_name=\"poise_participant\" is_default_profile=\"true\">\n"
      << "      <rtps>\n"
      << "        <useBuiltinTransports>false</useBuiltinTransports>\n"
      << "        <userTransports><transport_id>poise_udp_deployment</transport_id></userTransports>\n"
      << "        <builtin>\n"
      << "          <metatrafficUnicastLocatorList>\n"
      << "            <locator><udpv4><address>" << host.address << "</address></udpv4></locator>\n"
      << "          </metatrafficUnicastLocatorList>\n"
      << "          <initialPeersList>\n";
    for (const auto& h : d.hosts)
      x << "            <locator><udpv4><address>" << h.address << "</address></udpv4></locator>\n";
    x << "          </initialPeersList>\n"
      << "        </builtin>\n"
      << "        <defaultUnicastLocatorList>\n"
      << "          <locator><udpv4><address>" << host.address << "</address></udpv4></locator>\n"
      << "        </defaultUnicastLocatorList>\n"
      << "      </rtps>\n"
      << "    </participant>\n"
      << "  </profiles>\n"
      << "</dds>\n";
  }
  return x.str();
}

namespace {

/// The value of `name` in a component's options ("--name V" or "--name=V"), if given.
std::optional<std::string> option_value(const std::vector<std::string>& options,
                                        const std::string& name) {
  for (std::size_t i = 0; i < options.size(); ++i) {
    if (options[i] == name) return i + 1 < options.size() ? options[i + 1] : std::string();
    if (options[i].rfind(name + "=", 0) == 0) return options[i].substr(name.size() + 1);
  }
  return std::nullopt;
}

/// How long the deployment's simulator waits for a joint command in lockstep [ms, as text].
std::string sim_command_timeout_ms(const Deployment& d) {
  for (const Component& s : d.components)
    if (s.kind == "sim")
      if (const auto v = option_value(s.options, "--command-timeout-ms"); v && !v->empty())
        return *v;
  return std::to_string(sim::kDefaultCommandTimeoutMs);  // poise-sim's default
}

}  // namespace

std::vector<std::string> estimator_scenario_args(const scenario::Scenario& sc,
                                                 const std::string& estimator_type) {
  // Every number to the last bit (%.17g): a start height rounded to 1e-6 m was a difference
  // from the in-process run (issue #17 item 4).
  const auto exact = [](double v) {
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", v);
    return std::string(b);
  };
  std::vector<std::string> a{"--supports", sc.estimator.supports, "--estimator",
                             estimator_type.empty() ? sc.estimator.type : estimator_type};
  const scenario::EstimatorStart start = scenario::estimator_start(sc);
  a.insert(a.end(), {"--ground-height", exact(start.ground_height)});
  if (start.per_foot) {
    // Feet without a given height stand on the ground.
    const auto h = [&](std::size_t f) {
      return std::isfinite(start.support_height[f]) ? start.support_height[f] : start.ground_height;
    };
    a.insert(a.end(), {"--support-heights", exact(h(0)), exact(h(1))});
  }
  a.insert(a.end(), {"--initial-xy", exact(sc.sim.initial.base_position.x()),
                     exact(sc.sim.initial.base_position.y())});
  if (std::isfinite(sc.estimator.stance_rate_hz))
    a.insert(a.end(), {"--stance-rate-hz", exact(sc.estimator.stance_rate_hz)});
  if (const double n = scenario::estimator_contact_ft_noise(sc); std::isfinite(n))
    a.insert(a.end(), {"--contact-ft-noise", exact(n)});
  if (std::isfinite(sc.estimator.contact_rest_time))
    a.insert(a.end(), {"--contact-rest-time", exact(sc.estimator.contact_rest_time)});
  if (const int d = scenario::estimator_imu_delay_ticks(sc); d > 0)
    a.insert(a.end(), {"--imu-delay-ticks", std::to_string(d)});
  return a;
}

bool recorder_sets_if_exists(const Component& c) {
  for (const std::string& o : c.options)
    if (o == "--if-exists" || o.rfind("--if-exists=", 0) == 0) return true;
  return false;
}

std::vector<std::string> command_line(const Deployment& d, const Component& c,
                                      const fs::path& bin_dir, const fs::path& dds_config) {
  std::vector<std::string> a;
  std::vector<std::string> dds{"--dds", c.dds, "--domain", std::to_string(d.domain),
                               "--dds-config", dds_config.string()};
  // Under DDS Security each component authenticates as its kind (the identities of
  // `poise security init`); a command (a driver) reads POISE_DDS_SECURITY itself.
  if (!d.security.empty() && c.kind != "command")
    dds.insert(dds.end(), {"--security", fs::absolute(d.security).string(), "--identity",
                           c.kind});
  if (c.kind == "command") {
    a = c.command;
    a.insert(a.end(), c.options.begin(), c.options.end());
    return a;
  }
  if (c.kind == "recorder") {
    a = {(bin_dir / "poise").string(), "record", "-o", c.output, "--progress", "0"};
    // A restarted recorder goes on in <stem>.1.mcap, ...: what it wrote before is kept (the
    // launcher clears the output once, at the launch's start: launch_cli.cpp).
    if (!recorder_sets_if_exists(c)) a.insert(a.end(), {"--if-exists", "next"});
    a.insert(a.end(), dds.begin(), dds.end());
    a.insert(a.end(), c.options.begin(), c.options.end());
    return a;
  }
  a = {(bin_dir / ("poise-" + c.kind)).string(), "--name", c.name};
  a.insert(a.end(), dds.begin(), dds.end());
  if (c.kind == "sim") {
    a.insert(a.end(), {d.scenario, "--progress", d.realtime ? "--realtime" : "--lockstep"});
    // Real time with a controller in the file (on any host): the clock starts once the loop has
    // answered the first frame.
    if (d.realtime && std::any_of(d.components.begin(), d.components.end(),
                                  [](const auto& o) { return o.kind == "controller"; }))
      a.push_back("--start-when-answered");
  } else {
    // The nodes take the robot from poise/robot_description; `robot:` of the file is an explicit
    // override, which each node checks against the description (and refuses on a difference).
    if (!d.robot.empty()) a.insert(a.end(), {"--robot", d.robot});
    if (c.kind == "estimator" && !d.estimator_args.empty())
      a.insert(a.end(), d.estimator_args.begin(), d.estimator_args.end());
    else if (c.kind == "estimator" && !d.estimator_supports.empty())
      a.insert(a.end(), {"--supports", d.estimator_supports});
    if (c.kind == "contact" && !d.contact_method.empty())
      a.insert(a.end(), {"--method", d.contact_method});
    if (c.kind == "contact" && !d.contact_priority.empty())
      a.insert(a.end(), {"--priority", d.contact_priority, "--torsion-limit",
                         d.contact_torsion_limit});
    // The scenario's controller section, written next to the DDS configurations (launch_cli).
    if (c.kind == "controller" && !d.controller_yaml.empty())
      a.insert(a.end(),
               {"--config", (dds_config.parent_path().parent_path() / "controller.yaml").string()});
    if (c.kind == "controller") {
      a.insert(a.end(), {"--contact-deadline-us", d.realtime ? "400" : "1000000"});
      // The scenario's planned supports from the first tick, as `poise run` plans them.
      if (d.planned_support == "double" || d.planned_support == "left" ||
          d.planned_support == "right")
        a.insert(a.end(), {"--planned-support", d.planned_support});
    }
    // Lockstep: the loop waits for its slowest process, and a loaded machine stalls it for
    // 100+ ms now and then; the 50 ms wall-clock staleness default would call that a fault.
    // The nodes wait as long as poise-sim waits for a command (the sim component's
    // --command-timeout-ms, else poise-sim's 2000 ms default), unless the file's options say
    // otherwise.
    if (!d.realtime && (c.kind == "estimator" || c.kind == "controller") &&
        !option_value(c.options, "--input-stale-ms"))
      a.insert(a.end(), {"--input-stale-ms", sim_command_timeout_ms(d)});
  }
  a.insert(a.end(), c.options.begin(), c.options.end());
  return a;
}

}  // namespace poise::launch
