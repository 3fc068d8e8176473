#include "poise/dds/vendor.hpp"

#include <unistd.h>

#include <charconv>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace poise::dds {
namespace {

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v ? std::string(v) : std::string();
}

int parse_domain(std::string_view text, const char* what) {
  int value = -1;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || value < 0 || value > 232) {
    throw std::invalid_argument(std::string(what) + ": bad DDS domain id '" + std::string(text) +
                                "' (expected an integer 0..232)");
  }
  return value;
}

}  // namespace

Vendor parse_vendor(std::string_view name) {
  if (name == "fastdds") return Vendor::fastdds;
  if (name == "cyclone" || name == "cyclonedds") return Vendor::cyclone;
  throw std::invalid_argument("unknown DDS vendor '" + std::string(name) +
                              "' (expected 'fastdds', 'cyclone' or 'cyclonedds')");
}

std::string_view to_string(Vendor vendor) {
  return vendor == Vendor::fastdds ? "fastdds" : "cyclone";
}

Vendor vendor_from_env_or(Vendor fallback) {
  const std::string v = env("POISE_DDS");
  if (v.empty()) return fallback;
  try {
    return parse_vendor(v);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("POISE_DDS: ") + e.what());
  }
}

DdsOptions dds_options_from_env() {
  DdsOptions o;
  o.vendor = vendor_from_env_or(Vendor::cyclone);
  if (const std::string d = env("POISE_DDS_DOMAIN"); !d.empty()) {
    o.domain_id = parse_domain(d, "POISE_DDS_DOMAIN");
  }
  o.config_path = env("POISE_DDS_CONFIG");
  o.security_dir = env("POISE_DDS_SECURITY");
  o.identity = env("POISE_DDS_IDENTITY");
  return o;
}

DdsOptions consume_dds_args(int& argc, char** argv) {
  DdsOptions o = dds_options_from_env();
  int out = argc > 0 ? 1 : 0;
  for (int i = out; i < argc; ++i) {
    const std::string_view arg = argv[i];
    std::string_view flag = arg;
    std::string_view value;
    bool has_value = false;
    if (const auto eq = arg.find('='); arg.starts_with("--") && eq != std::string_view::npos) {
      flag = arg.substr(0, eq);
      value = arg.substr(eq + 1);
      has_value = true;
    }
    if (flag != "--dds" && flag != "--domain" && flag != "--dds-config") {
      argv[out++] = argv[i];
      continue;
    }
    if (!has_value) {
      if (i + 1 >= argc) throw std::invalid_argument(std::string(flag) + " needs a value");
      value = argv[++i];
    }
    if (flag == "--dds") {
      o.vendor = parse_vendor(value);
    } else if (flag == "--domain") {
      o.domain_id = parse_domain(value, "--domain");
    } else {
      o.config_path = std::string(value);
    }
  }
  argc = out;
  if (argc > 0) argv[out] = nullptr;
  return o;
}

std::string dds_config_dir() {
  namespace fs = std::filesystem;
  std::error_code ec;
  auto ok = [&ec](const fs::path& p) {
    return fs::exists(p / "cyclone-loopback.xml", ec) && fs::exists(p / "fastdds-loopback.xml", ec);
  };
  if (const std::string e = env("POISE_DDS_CONFIG_DIR"); !e.empty() && ok(e)) {
    return fs::absolute(e, ec).lexically_normal().string();
  }
  char exe[4096];
  const ssize_t n = ::readlink("/proc/self/exe", exe, sizeof(exe) - 1);
  if (n > 0) {
    exe[n] = '\0';
    const fs::path p = fs::path(exe).parent_path() / ".." / ".." / "deploy" / "dds";
    if (ok(p)) return p.lexically_normal().string();
  }
#ifdef POISE_SOURCE_DIR
  if (const fs::path p = fs::path(POISE_SOURCE_DIR) / "deploy" / "dds"; ok(p)) return p.string();
#endif
#ifdef POISE_INSTALL_DATADIR
  if (const fs::path p = fs::path(POISE_INSTALL_DATADIR) / "poise" / "dds"; ok(p))
    return p.string();
#endif
  return {};
}

std::string default_config_path(Vendor vendor) {
  const std::string dir = dds_config_dir();
  if (dir.empty()) return {};
  return dir + "/" + std::string(to_string(vendor)) + "-loopback.xml";
}

}  // namespace poise::dds
