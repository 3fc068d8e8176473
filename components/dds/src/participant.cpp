#include "poise/dds/participant.hpp"

#include <algorithm>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <utility>

#include "poise/dds/domain_claim.hpp"
#include "poise/dds/log.hpp"

namespace poise::dds {
namespace {

// Once per domain and process: a domain whose ports lie in the ephemeral range can be discovered
// from another domain (domain_claim.hpp says how).
void warn_if_domain_exposed(int domain) {
  static std::mutex mutex;
  static std::set<int> warned;
  std::lock_guard lock(mutex);
  if (!warned.insert(domain).second) return;
  const std::string warning = domain_port_warning(domain);
  if (!warning.empty()) log(LogLevel::warn, "%s", warning.c_str());
}

}  // namespace

Participant::Participant(const DdsOptions& options)
    : vendor_(options.vendor),
      domain_id_(options.domain_id),
      name_(options.participant_name.empty() ? "poise" : options.participant_name) {
  const std::string where = "DDS participant (" + std::string(to_string(vendor_)) + ", domain " +
                            std::to_string(domain_id_) + ")";
  if (domain_id_ < 0 || domain_id_ > 232) {
    throw std::runtime_error(where + ": domain id must be in 0..232");
  }
  warn_if_domain_exposed(domain_id_);
  config_path_ = options.config_path.empty() ? default_config_path(vendor_) : options.config_path;
  if (config_path_.empty()) {
    throw std::runtime_error(where + ": cannot find deploy/dds/" + std::string(to_string(vendor_)) +
                             "-loopback.xml; set POISE_DDS_CONFIG_DIR or pass --dds-config");
  }
  std::error_code ec;
  if (!std::filesystem::is_regular_file(config_path_, ec)) {
    throw std::runtime_error(where + ": config file '" + config_path_ + "' does not exist");
  }
  config_path_ = std::filesystem::absolute(config_path_, ec).lexically_normal().string();

  detail::BackendOptions bo;
  bo.vendor = vendor_;
  bo.domain_id = domain_id_;
  bo.config_path = config_path_;
  bo.participant_name = name_;
  if (!options.security_dir.empty()) {
    namespace fs = std::filesystem;
    const fs::path dir = fs::absolute(options.security_dir, ec).lexically_normal();
    if (options.identity.empty())
      throw std::runtime_error(where + ": DDS Security (" + dir.string() +
                               ") needs an identity (--identity NAME or POISE_DDS_IDENTITY)");
    const fs::path id = dir / options.identity;
    auto need = [&](const fs::path& p) {
      if (!fs::is_regular_file(p, ec))
        throw std::runtime_error(where + ": DDS Security file " + p.string() +
                                 " does not exist (identity '" + options.identity +
                                 "'; make them with `poise security init`)");
      return p.string();
    };
    bo.security.ca = need(dir / "ca.pem");
    bo.security.governance = need(dir / "governance.p7s");
    bo.security.certificate = need(id / "cert.pem");
    bo.security.private_key = need(id / "key.pem");
    bo.security.permissions = need(id / "permissions.p7s");
  }
  bo.on_endpoint = [this](const detail::EndpointEvent& e) { on_endpoint(e); };
  try {
    backend_ = vendor_ == Vendor::fastdds ? detail::make_fastdds_backend(bo)
                                          : detail::make_cyclone_backend(bo);
  } catch (const std::exception& e) {
    throw std::runtime_error(where + " with config '" + config_path_ + "': " + e.what());
  }
}

Participant::~Participant() {
  backend_.reset();  // stops discovery callbacks before the tables go
}

void Participant::on_endpoint(const detail::EndpointEvent& event) {
  std::lock_guard lock(mutex_);
  auto it = std::find_if(endpoints_.begin(), endpoints_.end(),
                         [&](const Endpoint& e) { return e.event.guid == event.guid; });
  if (!event.alive) {
    if (it != endpoints_.end()) endpoints_.erase(it);
    return;
  }
  if (it != endpoints_.end()) {
    it->event = event;  // QoS change; already checked
    return;
  }
  endpoints_.push_back(Endpoint{event});
  if (event.is_writer) {
    for (const auto& w : watches_)
      check_mismatch_locked(event, w);
  }
}

void Participant::check_mismatch_locked(const detail::EndpointEvent& event, const Watch& watch) {
  if (!event.is_writer || event.topic_name != watch.topic_name ||
      event.type_name == watch.type_name) {
    return;
  }
  type_mismatches_.fetch_add(1);
  if (watch.counters) watch.counters->type_mismatches.fetch_add(1);
  log(LogLevel::warn,
      "topic '%s': ignoring a writer of type '%s' (this subscriber expects '%s'); type mismatch",
      event.topic_name.c_str(), event.type_name.c_str(), watch.type_name.c_str());
}

int Participant::watch_topic(const std::string& topic_name, const std::string& type_name,
                             SubscriberCounters* counters) {
  std::lock_guard lock(mutex_);
  const int token = next_token_++;
  watches_.push_back(Watch{token, topic_name, type_name, counters});
  for (const auto& e : endpoints_)
    check_mismatch_locked(e.event, watches_.back());
  return token;
}

void Participant::unwatch_topic(int token) {
  std::lock_guard lock(mutex_);
  std::erase_if(watches_, [token](const Watch& w) { return w.token == token; });
}

int Participant::writers_of(std::string_view topic_name) const noexcept {
  std::lock_guard lock(mutex_);
  int n = 0;
  for (const auto& e : endpoints_)
    if (e.event.is_writer && e.event.topic_name == topic_name) ++n;
  return n;
}

std::vector<DiscoveredTopic> Participant::discovered_topics() const {
  std::map<std::pair<std::string, std::string>, DiscoveredTopic> m;
  {
    std::lock_guard lock(mutex_);
    for (const auto& e : endpoints_) {
      auto& t = m[{e.event.topic_name, e.event.type_name}];
      t.topic_name = e.event.topic_name;
      t.type_name = e.event.type_name;
      (e.event.is_writer ? t.writers : t.readers) += 1;
    }
  }
  std::vector<DiscoveredTopic> out;
  out.reserve(m.size());
  for (auto& [k, v] : m)
    out.push_back(std::move(v));
  return out;
}

}  // namespace poise::dds
