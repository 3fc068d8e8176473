// GroundTruth.other_contact_links numbers links as the IDL says: by their position among the
// <link> elements of the URDF (document order), not by the simulator's body order.
#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <regex>
#include <sstream>

#include "poise/sim_node/sim_messages.hpp"
#include "sim_test_util.hpp"

namespace poise::sim {
namespace {

using test::biped_lying_on_back_config;

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

/// Link names in document order, read with a regular expression (independent of the XML parser
/// the node uses).
std::vector<std::string> links_in_document_order(const std::string& urdf) {
  std::vector<std::string> names;
  const std::regex link_re(R"re(<link\s+name\s*=\s*"([^"]+)")re");
  for (auto it = std::sregex_iterator(urdf.begin(), urdf.end(), link_re);
       it != std::sregex_iterator(); ++it)
    names.push_back((*it)[1].str());
  return names;
}

/// Names of the links GroundTruth.other_contact_links reports, through the document order.
std::vector<std::string> reported_links(const msg::GroundTruth& m,
                                        const std::vector<std::string>& links) {
  std::vector<std::string> names;
  for (std::uint32_t i = 0; i < m.other_contact_count(); ++i) {
    const std::int32_t l = m.other_contact_links()[i];
    EXPECT_GE(l, 0);
    if (l < 0 || static_cast<std::size_t>(l) >= links.size()) {
      ADD_FAILURE() << "link index " << l << " out of range";
      continue;
    }
    names.push_back(links[static_cast<std::size_t>(l)]);
  }
  for (std::size_t i = m.other_contact_count(); i < m.other_contact_links().size(); ++i)
    EXPECT_EQ(m.other_contact_links()[i], -1);
  return names;
}

std::vector<std::string> flagged_bodies(const GroundTruth& g, const Simulator& sim) {
  std::vector<std::string> names;
  for (std::size_t b = 0; b < g.non_foot_contact.size(); ++b)
    if (g.non_foot_contact[b]) names.push_back(sim.body_names()[b]);
  return names;
}

TEST(SimGroundTruthMsg, OtherContactLinksAreUrdfLinkIndices) {
  const SimulatorConfig cfg = biped_lying_on_back_config();  // the trunk touches the ground
  Simulator sim(cfg);
  SensorFrame s = sim.make_sensor_frame();
  GroundTruth g = sim.make_ground_truth();
  const JointCommand cmd = test::damping_command(sim, 2.0);
  for (int k = 0; k < 600; ++k)
    sim.step(cmd, s, g);
  ASSERT_GT(g.num_non_foot_contacts, 0) << "the robot lies on the ground";

  const std::string urdf = read_text(cfg.robot.urdf_path);
  const std::vector<std::string> links = links_in_document_order(urdf);
  const std::vector<std::int32_t> index =
      sim_node::urdf_link_index_of_bodies(urdf, sim.body_names());
  ASSERT_EQ(index.size(), sim.body_names().size());
  // The test URDF lists torso and imu_link (merged into the pelvis body) before the legs, so
  // the two numberings differ: a body index is not a link index.
  std::size_t differ = 0;
  for (std::size_t b = 0; b < sim.body_names().size(); ++b)
    differ += links[b] != sim.body_names()[b];
  ASSERT_GT(differ, 0u);

  const sim_node::FootOrder feet = sim_node::foot_order(sim);
  sim_node::SlipTracker slip(std::vector<int>(sim.foot_names().size(), -1));
  slip.update(g);
  auto out = std::make_unique<msg::GroundTruth>();
  sim_node::to_msg(g, feet, slip, index, 7, *out);
  EXPECT_EQ(reported_links(*out, links), flagged_bodies(g, sim)) << "simulated contact";
  EXPECT_EQ(out->total_other_contacts(), 7u);

  // Every body, in seeded random subsets (the conversion is the same for any contact set).
  std::mt19937_64 rng(6);
  std::bernoulli_distribution pick(0.3);
  for (int trial = 0; trial < 50; ++trial) {
    std::size_t count = 0;
    for (auto& c : g.non_foot_contact) {
      c = count < out->other_contact_links().size() && pick(rng);
      count += c;
    }
    sim_node::to_msg(g, feet, slip, index, 0, *out);
    EXPECT_EQ(reported_links(*out, links), flagged_bodies(g, sim)) << "trial " << trial;
  }
}

TEST(SimGroundTruthMsg, BodyWithoutUrdfLinkOrBadXmlIsAClearError) {
  EXPECT_THROW(
      sim_node::urdf_link_index_of_bodies("<robot name='r'><link name='a'/></robot>", {"a", "b"}),
      std::runtime_error);
  EXPECT_THROW(sim_node::urdf_link_index_of_bodies("not xml <", {"a"}), std::runtime_error);
  const auto idx = sim_node::urdf_link_index_of_bodies(
      "<robot name='r'><link name='z'/><joint name='j'/><link name='a'/></robot>", {"a", "z"});
  EXPECT_EQ(idx, (std::vector<std::int32_t>{1, 0}));
}

}  // namespace
}  // namespace poise::sim
