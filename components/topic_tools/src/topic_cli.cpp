// `poise topic ...`: argument parsing for the verbs in topic_commands.cpp.
#include <iostream>

#include <CLI/CLI.hpp>
#include <poise/dds/cli.hpp>
#include <poise/dds/dds.hpp>

#include "topic_commands.hpp"
#include "poise/cli/parse.hpp"

namespace poise::topic_tools {

int cli_main(int argc, char** argv) {
  dds::DdsOptions dds_options = dds::dds_options_from_env();
  dds_options.participant_name = "poise-topic";
  CLI::App app{
      "List, echo, measure and publish Poise DDS topics, on either vendor.\n"
      "Samples print and parse in the JSON form described in idl/README.md."};
  app.name("poise topic");
  app.require_subcommand(1);
  // The verbs inherit this: options of the group (--dds, --domain, ...) are accepted after the
  // verb as well, as in `ros2 topic echo X --domain 7`.
  app.fallthrough();
  dds::add_dds_options(app, dds_options);

  ListOptions list;
  auto* list_cmd =
      app.add_subcommand("list", "Topics and types on the domain, with writer/reader counts");
  list_cmd->add_option("--wait", list.wait_s, "seconds of discovery before printing")
      ->capture_default_str();

  EchoOptions echo;
  auto* echo_cmd = app.add_subcommand("echo", "Print the samples of a topic");
  echo_cmd->add_option("topic", echo.topic, "topic name, e.g. poise/state")->required();
  echo_cmd->add_flag("--once", echo.once, "print one sample and exit");
  echo_cmd->add_flag("--json", echo.json, "one JSON object per line (the form `pub` reads)");
  echo_cmd->add_option("--count", echo.count, "exit after this many samples")
      ->check(CLI::NonNegativeNumber);
  echo_cmd
      ->add_option("--timeout", echo.timeout_s,
                   "exit with status 1 after this many seconds without a sample")
      ->check(CLI::NonNegativeNumber);

  HzOptions hz;
  auto* hz_cmd = app.add_subcommand("hz", "Publication rate with min/max/std-dev of the period");
  hz_cmd->add_option("topic", hz.topic, "topic name")->required();
  hz_cmd->add_option("--window", hz.window, "periods in the statistics window")
      ->check(CLI::Range(2, 1000000))
      ->capture_default_str();
  hz_cmd->add_option("--duration", hz.duration_s, "stop after this many seconds (0: until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);

  PubOptions pub;
  auto* pub_cmd = app.add_subcommand(
      "pub", "Publish samples given as JSON (argument, or one object per line on stdin)");
  pub_cmd->add_option("topic", pub.topic, "topic name")->required();
  pub_cmd->add_option("sample", pub.json,
                      "one sample as JSON; without it, JSON lines are read from stdin");
  pub_cmd->add_option("--rate", pub.rate_hz, "publications per second (0: as fast as possible)")
      ->check(CLI::NonNegativeNumber);
  pub_cmd->add_option("--count", pub.count, "publish each sample this many times (0: until Ctrl-C)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  pub_cmd
      ->add_option("--wait-readers", pub.wait_readers, "wait for this many matched readers first")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  pub_cmd->add_option("--wait", pub.wait_s, "... for at most this many seconds")
      ->capture_default_str();

  POISE_CLI_PARSE(app, argc, argv);
  install_signal_handlers();
  dds::set_log_name("poise-topic");
  dds::Participant participant(dds_options);
  if (*list_cmd) return list_topics(participant, list, std::cout);
  if (*echo_cmd) return echo_topic(participant, echo, std::cout);
  if (*hz_cmd) return topic_hz(participant, hz, std::cout);
  return publish_topic(participant, pub, std::cin, std::cout);
}

}  // namespace poise::topic_tools
