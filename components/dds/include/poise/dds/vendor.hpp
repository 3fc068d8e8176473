#pragma once
// Choosing the DDS vendor, domain and configuration of a process.
//
// Every executable accepts `--dds fastdds|cyclone`, `--domain N` and `--dds-config PATH`. When a
// flag is absent, the environment decides: POISE_DDS (vendor), POISE_DDS_DOMAIN (domain id),
// POISE_DDS_CONFIG (config file). Without either, the vendor is Cyclone DDS, the domain is 0 and
// the configuration is the loopback-only file of that vendor in deploy/dds/.

#include <string>
#include <string_view>

namespace poise::dds {

enum class Vendor { fastdds, cyclone };

/// "fastdds" or "cyclone". Throws std::invalid_argument naming the bad value otherwise.
Vendor parse_vendor(std::string_view name);

/// "fastdds" or "cyclone".
std::string_view to_string(Vendor vendor);

/// The vendor named by the environment variable POISE_DDS, or `fallback` when it is unset or
/// empty. Throws std::invalid_argument when it is set to something else.
Vendor vendor_from_env_or(Vendor fallback);

/// What a process needs to join a DDS domain. Defaults are filled in from the environment by
/// dds_options_from_env().
struct DdsOptions {
  Vendor vendor = Vendor::cyclone;
  int domain_id = 0;        ///< 0..232 (both vendors' port mapping allows 232 domains)
  std::string config_path;  ///< vendor XML file; empty = deploy/dds/<vendor>-loopback.xml
  std::string participant_name = "poise";
  /// DDS Security: the directory `poise security init` made ("" = no security), and the
  /// identity (a subdirectory of it) this participant authenticates as.
  std::string security_dir;
  std::string identity;
};

/// Options from POISE_DDS, POISE_DDS_DOMAIN and POISE_DDS_CONFIG, with the defaults above.
/// Throws std::invalid_argument on a malformed value (naming the variable).
DdsOptions dds_options_from_env();

/// Removes `--dds X`, `--domain N`, `--dds-config PATH` (also the `--flag=value` forms) from
/// argv, updating argc, and applies them on top of dds_options_from_env(). For programs that do
/// not use CLI11. Throws std::invalid_argument naming a malformed or missing value.
DdsOptions consume_dds_args(int& argc, char** argv);

/// The directory holding the shipped DDS configurations: $POISE_DDS_CONFIG_DIR, else
/// <executable>/../../deploy/dds (build trees inside the source tree), else the source tree
/// known at compile time, else the installed share directory. Returns "" when none exists.
std::string dds_config_dir();

/// deploy/dds/<vendor>-loopback.xml (absolute path) or "" when it cannot be found.
std::string default_config_path(Vendor vendor);

}  // namespace poise::dds
