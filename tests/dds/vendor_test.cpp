// Vendor, domain and config selection from the command line and the environment; the topic
// table against the IDL files it was written from.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <poise/dds/cli.hpp>
#include <poise/dds/dds.hpp>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

namespace poise::dds {
namespace {

struct EnvGuard {
  explicit EnvGuard(const char* name) : name_(name) {
    if (const char* v = std::getenv(name)) old_ = v;
  }
  ~EnvGuard() {
    if (old_)
      ::setenv(name_, old_->c_str(), 1);
    else
      ::unsetenv(name_);
  }
  const char* name_;
  std::optional<std::string> old_;
};

TEST(Vendor, ParsesBothNamesAndRejectsOthersByName) {
  EXPECT_EQ(parse_vendor("fastdds"), Vendor::fastdds);
  EXPECT_EQ(parse_vendor("cyclone"), Vendor::cyclone);
  try {
    parse_vendor("opendds");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("opendds"), std::string::npos);
  }
}

TEST(Vendor, EnvironmentIsTheFallback) {
  EnvGuard g("POISE_DDS");
  ::unsetenv("POISE_DDS");
  EXPECT_EQ(vendor_from_env_or(Vendor::cyclone), Vendor::cyclone);
  EXPECT_EQ(vendor_from_env_or(Vendor::fastdds), Vendor::fastdds);
  ::setenv("POISE_DDS", "fastdds", 1);
  EXPECT_EQ(vendor_from_env_or(Vendor::cyclone), Vendor::fastdds);
  ::setenv("POISE_DDS", "bogus", 1);
  EXPECT_THROW(vendor_from_env_or(Vendor::cyclone), std::invalid_argument);
}

TEST(Vendor, CommandLineOverridesEnvironmentAndIsRemovedFromArgv) {
  EnvGuard g("POISE_DDS");
  EnvGuard gd("POISE_DDS_DOMAIN");
  ::setenv("POISE_DDS", "cyclone", 1);
  ::setenv("POISE_DDS_DOMAIN", "3", 1);
  std::vector<std::string> args = {"prog",        "--dds",        "fastdds", "--rate", "5",
                                   "--domain=42", "--dds-config", "/x.xml",  "tail"};
  std::vector<char*> argv;
  for (auto& a : args)
    argv.push_back(a.data());
  argv.push_back(nullptr);
  int argc = static_cast<int>(args.size());
  const DdsOptions o = consume_dds_args(argc, argv.data());
  EXPECT_EQ(o.vendor, Vendor::fastdds);
  EXPECT_EQ(o.domain_id, 42);
  EXPECT_EQ(o.config_path, "/x.xml");
  ASSERT_EQ(argc, 4);
  EXPECT_STREQ(argv[1], "--rate");
  EXPECT_STREQ(argv[2], "5");
  EXPECT_STREQ(argv[3], "tail");
  EXPECT_EQ(argv[4], nullptr);

  int argc2 = 1;
  char* argv2[] = {args[0].data(), nullptr};
  const DdsOptions o2 = consume_dds_args(argc2, argv2);
  EXPECT_EQ(o2.vendor, Vendor::cyclone);  // from POISE_DDS
  EXPECT_EQ(o2.domain_id, 3);             // from POISE_DDS_DOMAIN

  std::vector<std::string> bad = {"prog", "--domain", "999"};
  std::vector<char*> badv = {bad[0].data(), bad[1].data(), bad[2].data(), nullptr};
  int badc = 3;
  EXPECT_THROW(consume_dds_args(badc, badv.data()), std::invalid_argument);
}

TEST(Vendor, Cli11OptionsSetTheOptions) {
  DdsOptions o;
  CLI::App app{"test"};
  add_dds_options(app, o);
  const char* argv[] = {"prog", "--dds", "fastdds", "--domain", "17"};
  app.parse(5, const_cast<char**>(argv));
  EXPECT_EQ(o.vendor, Vendor::fastdds);
  EXPECT_EQ(o.domain_id, 17);
  CLI::App app2{"test"};
  DdsOptions o2;
  add_dds_options(app2, o2);
  const char* argv2[] = {"prog", "--dds", "rti"};
  EXPECT_THROW(app2.parse(3, const_cast<char**>(argv2)), CLI::ValidationError);
}

TEST(Vendor, DefaultConfigsAreTheShippedLoopbackFiles) {
  for (Vendor v : {Vendor::fastdds, Vendor::cyclone}) {
    const std::string p = default_config_path(v);
    ASSERT_FALSE(p.empty());
    EXPECT_TRUE(std::filesystem::exists(p)) << p;
    EXPECT_NE(p.find(std::string(to_string(v)) + "-loopback.xml"), std::string::npos);
  }
}

TEST(Vendor, MissingConfigFileIsAClearError) {
  DdsOptions o;
  o.config_path = "/nonexistent/poise.xml";
  try {
    Participant p(o);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/poise.xml"), std::string::npos);
  }
}

// The table's QoS must say what the header comment of each IDL file says.
TEST(TopicTable, DefaultQosMatchesTheIdlHeaderComments) {
  ASSERT_EQ(topic_table().size(), 12u);
  for (const auto& row : topic_table()) {
    const std::string file = std::string(row.topic_name.substr(row.topic_name.find('/') + 1));
    std::ifstream in(std::string(POISE_SOURCE_DIR) + "/idl/" + file + ".idl");
    ASSERT_TRUE(in) << file;
    std::string head, line;
    while (std::getline(in, line) && line.starts_with("//"))
      head += line + " ";
    EXPECT_NE(head.find("\"" + std::string(row.topic_name) + "\""), std::string::npos) << head;
    const bool best_effort = head.find("Best-effort") != std::string::npos;
    EXPECT_EQ(row.qos.reliability, best_effort ? Reliability::best_effort : Reliability::reliable)
        << row.topic_name;
    const bool latched = head.find("transient-local") != std::string::npos;
    EXPECT_EQ(row.qos.durability, latched ? Durability::transient_local : Durability::volatile_)
        << row.topic_name;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(head, m, std::regex("keep-last (\\d+)"))) << row.topic_name;
    EXPECT_EQ(row.qos.history_depth, std::stoi(m[1])) << row.topic_name;
    const int writer_depth = std::regex_search(head, m, std::regex("writers keep-last (\\d+)"))
                                 ? std::stoi(m[1])
                                 : row.qos.history_depth;
    EXPECT_EQ(row.qos.writer_depth(), writer_depth) << row.topic_name;
    EXPECT_EQ(find_topic(row.topic_name), &row);
    EXPECT_EQ(find_topic_by_type(row.type_name), &row);
    EXPECT_EQ(std::string_view(row.type->type_name), row.type_name);
  }
}

}  // namespace
}  // namespace poise::dds
