// Node diagnostics of a stale input (idl/README.md "Fault semantics"): a real poise::node::Node on
// a claimed loopback domain, driven through its public calls, no other process.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>

#include "poise/node/node.hpp"
#include "support/test_domain.hpp"

namespace {

poise::node::NodeOptions options() {
  poise::node::NodeOptions o;
  o.name = "diag_test";
  o.dds.vendor = poise::dds::Vendor::cyclone;
  o.dds.domain_id = poise::testing::claim_test_domain();
  return o;
}

std::string last_error(const poise::node::Node& n) { return n.diagnostics().last_error().to_string(); }

// Every sample of an input rejected (here: error() for each) makes the input stale; the stale
// message must still name the rejection, or the FAULT's cause never reaches the wire.
TEST(NodeDiagnostics, AStaleInputNamesTheNewestErrorSinceTheLastSample) {
  poise::node::Node node(options());
  const int in = node.expect_input("poise/sensors", 5.0);
  node.input_seen(in, 100);
  node.error("tick %d: poise/sensors joint_count 18, the robot has 19 joints: rejected", 101);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  node.publish_diagnostics();
  EXPECT_EQ(node.diagnostics().health(), poise::msg::HEALTH_FAULT);
  EXPECT_NE(last_error(node).find("no poise/sensors for"), std::string::npos) << last_error(node);
  EXPECT_NE(last_error(node).find("input stale; newest error: tick 101: poise/sensors joint_count 18"),
            std::string::npos)
      << last_error(node);

  // No error since that sample: the stale message alone (an old error is not repeated forever).
  node.publish_diagnostics();
  EXPECT_EQ(node.diagnostics().health(), poise::msg::HEALTH_FAULT);
  EXPECT_EQ(last_error(node).find("newest error"), std::string::npos) << last_error(node);

  // Fresh again: no FAULT.
  node.input_seen(in, 200);
  node.publish_diagnostics();
  EXPECT_NE(node.diagnostics().health(), poise::msg::HEALTH_FAULT);
}

}  // namespace
