// `poise security init DIR`: a certificate authority, one identity per component and signed
// governance / permissions documents for DDS Security (OMG DDS Security 1.1 builtin plugins:
// PKI-DH authentication, Access-Permissions, AES-GCM-GMAC), made with Debian's openssl.
//
// Access control gives each identity write access to its own topics only: only `controller` may
// write poise/joint_command, only `sim` (or a driver using that identity) poise/sensors;
// `operator` (poise push, poise reference, poise topic) may write the disturbance and balance
// reference and read everything; `recorder` reads everything and writes nothing.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "poise/launch/deployment.hpp"
#include "poise/launch/launch.hpp"
#include "poise/cli/parse.hpp"

namespace poise::launch {
namespace {

namespace fs = std::filesystem;

struct Grant {
  std::vector<std::string> publish, subscribe;
};

const std::vector<std::string> kAllTopics{
    "poise/robot_description", "poise/sensors",          "poise/ground_truth",
    "poise/state",             "poise/balance_reference", "poise/contact_problem",
    "poise/contact_solution",  "poise/joint_command",    "poise/disturbance",
    "poise/estop",             "poise/estop_state",       "poise/diagnostics"};

std::map<std::string, Grant> grants() {
  return {
      {"sim",
       {{"poise/robot_description", "poise/sensors", "poise/ground_truth", "poise/estop_state",
         "poise/diagnostics"},
        {"poise/joint_command", "poise/disturbance", "poise/estop",
         "poise/balance_reference"}}},  // the CoM target, for the scenario monitor
      {"estimator",
       {{"poise/state", "poise/diagnostics"},
        {"poise/robot_description", "poise/sensors", "poise/ground_truth",
         "poise/balance_reference"}}},  // the contact plan: the detector's prior
      {"controller",
       {{"poise/contact_problem", "poise/joint_command", "poise/diagnostics"},
        {"poise/robot_description", "poise/state", "poise/contact_solution",
         "poise/balance_reference",
         "poise/estop_state"}}},  // a held stop: the references follow the robot
      {"contact",
       {{"poise/contact_solution", "poise/diagnostics"},
        {"poise/robot_description", "poise/contact_problem"}}},
      {"recorder", {{}, kAllTopics}},
      {"operator", {{"poise/disturbance", "poise/balance_reference", "poise/estop"}, kAllTopics}},
  };
}

/// Runs a program (no shell); its output goes to `log`. Returns its exit code.
int run(const std::vector<std::string>& argv, const fs::path& log) {
  std::vector<char*> args;
  std::vector<std::string> copy = argv;
  for (auto& a : copy)
    args.push_back(a.data());
  args.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    if (std::FILE* f = std::fopen(log.c_str(), "a")) {
      ::dup2(::fileno(f), STDOUT_FILENO);
      ::dup2(::fileno(f), STDERR_FILENO);
    }
    ::execvp(args[0], args.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string topics_xml(const std::vector<std::string>& topics, const char* indent) {
  std::string s;
  for (const auto& t : topics)
    s += std::string(indent) + "<topic>" + t + "</topic>\n";
  return s;
}

std::string governance_xml() {
  // No XML comments: Cyclone's parser of these documents refuses them.
  // No unauthenticated participant joins; discovery, liveliness and every topic's data are
  // encrypted; reading and writing any topic needs a grant in the signed permissions.
  return R"(<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>0</min><max>230</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>false</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
)";
}

std::string permissions_xml(const std::string& name, const Grant& g) {
  std::string s = R"(<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name=")" + name + R"(">
      <subject_name>CN=)" + name + R"(</subject_name>
      <validity><not_before>2020-01-01T00:00:00</not_before><not_after>2045-01-01T00:00:00</not_after></validity>
      <allow_rule>
        <domains><id_range><min>0</min><max>230</max></id_range></domains>
)";
  if (!g.publish.empty())
    s += "        <publish>\n          <topics>\n" + topics_xml(g.publish, "            ") +
         "          </topics>\n        </publish>\n";
  if (!g.subscribe.empty())
    s += "        <subscribe>\n          <topics>\n" + topics_xml(g.subscribe, "            ") +
         "          </topics>\n        </subscribe>\n";
  s += R"(      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
)";
  return s;
}

/// openssl, its output appended to `log`; false (after saying so) when it failed.
struct OpenSsl {
  fs::path log;
  bool operator()(const std::vector<std::string>& argv) const {
    if (run(argv, log) == 0) return true;
    std::fprintf(stderr, "poise security init: `%s ...` failed; see %s\n", argv[1].c_str(),
                 log.c_str());
    return false;
  }
};

constexpr fs::perms kOwnerOnlyDir = fs::perms::owner_all;
constexpr fs::perms kOwnerOnlyFile = fs::perms::owner_read | fs::perms::owner_write;

/// The certificate authority in `authority` (ca.key, never needed at run time, and ca.pem), the
/// signed governance in `root`, and ca.pem copied beside it.
bool make_authority(const fs::path& root, const fs::path& authority, const OpenSsl& ok) {
  fs::create_directories(authority);
  fs::permissions(authority, kOwnerOnlyDir);
  const std::string ca_key = (authority / "ca.key").string(), ca = (authority / "ca.pem").string();
  if (!ok({"openssl", "ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", ca_key}))
    return false;
  fs::permissions(ca_key, kOwnerOnlyFile);
  if (!ok({"openssl", "req", "-x509", "-new", "-key", ca_key, "-out", ca, "-days", "7300",
           "-sha256", "-subj", "/CN=Poise CA"}))
    return false;
  fs::copy_file(ca, root / "ca.pem", fs::copy_options::overwrite_existing);
  std::ofstream(root / "governance.xml") << governance_xml();
  return ok({"openssl", "smime", "-sign", "-in", (root / "governance.xml").string(), "-text",
             "-out", (root / "governance.p7s").string(), "-signer", ca, "-inkey", ca_key});
}

/// Identity `name` in root/name: key (0600), certificate and signed permissions.
bool make_identity(const fs::path& root, const fs::path& authority, const std::string& name,
                   const Grant& g, const OpenSsl& ok) {
  const std::string ca = (authority / "ca.pem").string(), ca_key = (authority / "ca.key").string();
  const fs::path id = root / name;
  fs::create_directories(id);
  fs::permissions(id, kOwnerOnlyDir);
  const std::string key = (id / "key.pem").string(), csr = (id / "cert.csr").string();
  if (!ok({"openssl", "ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", key}))
    return false;
  fs::permissions(key, kOwnerOnlyFile);
  if (!ok({"openssl", "req", "-new", "-key", key, "-out", csr, "-subj", "/CN=" + name}) ||
      !ok({"openssl", "x509", "-req", "-in", csr, "-CA", ca, "-CAkey", ca_key, "-CAcreateserial",
           "-out", (id / "cert.pem").string(), "-days", "7300", "-sha256"}))
    return false;
  fs::remove(csr);
  std::ofstream(id / "permissions.xml") << permissions_xml(name, g);
  return ok({"openssl", "smime", "-sign", "-in", (id / "permissions.xml").string(), "-text",
             "-out", (id / "permissions.p7s").string(), "-signer", ca, "-inkey", ca_key});
}

/// The identity a component authenticates as (launch passes its kind; a driver stands for the
/// simulator).
std::string identity_of(const Component& c) { return c.kind == "command" ? "sim" : c.kind; }

/// One directory per host of the deployment, holding what that host needs and nothing else:
/// ca.pem, governance.p7s and the identities of the components it runs; plus `operator`, for
/// the desk that runs the tools. Returns the bundles written.
std::vector<std::string> write_host_bundles(const fs::path& root, const Deployment& d) {
  std::map<std::string, std::set<std::string>> identities;
  for (const Host& h : d.hosts)
    identities[h.name];
  for (const Component& c : d.components)
    identities[c.host].insert(identity_of(c));
  identities["operator"].insert("operator");
  const fs::path hosts = root / "hosts";
  fs::create_directories(hosts);
  fs::permissions(hosts, kOwnerOnlyDir);
  std::vector<std::string> written;
  for (const auto& [host, ids] : identities) {
    const fs::path b = hosts / host;
    fs::remove_all(b);
    fs::create_directories(b);
    fs::permissions(b, kOwnerOnlyDir);
    for (const char* f : {"ca.pem", "governance.p7s"})
      fs::copy_file(root / f, b / f);
    for (const std::string& id : ids) {
      fs::copy(root / id, b / id, fs::copy_options::recursive);
      fs::permissions(b / id, kOwnerOnlyDir);
      fs::permissions(b / id / "key.pem", kOwnerOnlyFile);
    }
    written.push_back(host);
  }
  return written;
}

}  // namespace

int security_main(int argc, char** argv) {
  std::string dir, deployment_file;
  bool force = false;
  CLI::App app{
      "DDS Security for a Poise deployment: `poise security init DIR` makes a certificate "
      "authority (DIR/authority: its key, needed only to sign, belongs on no robot), an identity "
      "per component (sim, estimator, controller, contact, recorder, operator) and signed "
      "governance and permissions documents, with openssl. With --deployment FILE it also writes "
      "DIR/hosts/<host>/ for each host of the deployment (and DIR/hosts/operator/ for a desk): "
      "only that host's identities, to copy to it. Use them with `--security DIR` on every "
      "process (nodes authenticate as their name; tools with `--identity operator`), or "
      "`POISE_DDS_SECURITY`."};
  app.name("poise security");
  app.require_subcommand(1);
  auto* init = app.add_subcommand("init", "make the CA, identities and signed documents in DIR");
  init->add_option("dir", dir, "output directory (made with owner-only permissions)")->required();
  init->add_option("--deployment", deployment_file,
                   "deployment file: also write one bundle per host in DIR/hosts/")
      ->check(CLI::ExistingFile);
  init->add_flag("--force", force, "replace an existing directory's contents");
  POISE_CLI_PARSE(app, argc, argv);

  const fs::path root = fs::absolute(dir);
  if (fs::exists(root / "ca.pem") && !force) {
    std::fprintf(stderr,
                 "poise security init: %s already holds a CA (ca.pem); --force replaces it "
                 "(every identity signed by it stops working)\n",
                 root.c_str());
    return 2;
  }
  fs::create_directories(root);
  fs::permissions(root, kOwnerOnlyDir);
  const fs::path authority = root / "authority";
  const OpenSsl ok{authority / "openssl.log"};
  fs::create_directories(authority);
  std::ofstream(ok.log, std::ios::trunc).close();
  if (!make_authority(root, authority, ok)) return 1;
  for (const auto& [name, g] : grants())
    if (!make_identity(root, authority, name, g, ok)) return 1;
  std::printf("poise security init: identities sim, estimator, controller, contact, recorder, "
              "operator in %s; the CA's key in %s (keep it off the robot)\n",
              root.c_str(), authority.c_str());
  if (!deployment_file.empty()) {
    // Read now: its `security:` may name DIR, which holds a CA only from here on.
    Deployment deployment;
    try {
      deployment = load_deployment(deployment_file);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "poise security init: %s\n", e.what());
      return 2;
    }
    std::string list;
    for (const std::string& h : write_host_bundles(root, deployment))
      list += (list.empty() ? "" : ", ") + h;
    std::printf("  one bundle per host in %s: %s (copy each to its host)\n",
                (root / "hosts").c_str(), list.c_str());
  }
  return 0;
}

}  // namespace poise::launch
