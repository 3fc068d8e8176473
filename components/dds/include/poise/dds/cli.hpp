#pragma once
// CLI11 glue: adds --dds, --domain and --dds-config to an application.
//
//   poise::dds::DdsOptions dds = poise::dds::dds_options_from_env();
//   CLI::App app{"my node"};
//   poise::dds::add_dds_options(app, dds);
//   POISE_CLI_PARSE(app, argc, argv);
//   poise::dds::Participant participant(dds);

#include <CLI/CLI.hpp>

#include "poise/dds/vendor.hpp"

namespace poise::dds {

/// Registers the DDS options on `app`; parsed values are written into `options` (whose current
/// values, e.g. from dds_options_from_env(), are the defaults shown by --help).
inline void add_dds_options(CLI::App& app, DdsOptions& options) {
  app.add_option_function<std::string>(
         "--dds", [&options](const std::string& v) { options.vendor = parse_vendor(v); },
         "DDS vendor: fastdds, or cyclone (also spelt cyclonedds) (default: $POISE_DDS, else "
         "cyclone)")
      ->check(CLI::IsMember({"fastdds", "cyclone", "cyclonedds"}))
      ->default_str(std::string(to_string(options.vendor)));
  app.add_option("--domain", options.domain_id, "DDS domain id (default: $POISE_DDS_DOMAIN or 0)")
      ->check(CLI::Range(0, 232))
      ->capture_default_str();
  app.add_option("--dds-config", options.config_path,
                 "vendor XML configuration (default: deploy/dds/<vendor>-loopback.xml)")
      ->check(CLI::ExistingFile);
  app.add_option("--security", options.security_dir,
                 "DDS Security: directory made by `poise security init` (authentication, access "
                 "control, encryption; default: $POISE_DDS_SECURITY)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--identity", options.identity,
                 "DDS Security identity to authenticate as (a subdirectory of --security; "
                 "default: $POISE_DDS_IDENTITY, for nodes their name)");
}

}  // namespace poise::dds
