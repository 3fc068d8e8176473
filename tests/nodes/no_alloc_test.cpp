// The per-tick code of the nodes allocates nothing: every IDL <-> library conversion, the
// mailbox hand-off, the statistics and the simulator's start-up-free per-tick helpers run with
// a global operator-new counter that must stay at zero (after one warm-up call).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "poise/contact_node/contact_messages.hpp"
#include "poise/controller/balance_controller.hpp"
#include "poise/controller_node/controller_messages.hpp"
#include "poise/estimator/estimator.hpp"
#include "poise/estimator_node/estimator_messages.hpp"
#include "poise/node/compute_stats.hpp"
#include "poise/node/mailbox.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/reflect/validate.hpp"
#include "poise/sim_node/sim_messages.hpp"

namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
}  // namespace

void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace {

using namespace poise;

struct Counting {
  Counting() {
    g_allocations = 0;
    g_counting = true;
  }
  ~Counting() { g_counting = false; }
  long count() const { return g_allocations.load(); }
};

TEST(NodesNoAlloc, OneTickOfEveryConversionAllocatesNothing) {
  {  // the counter sees an allocation (else this test could not fail)
    Counting c;
    auto p = std::make_unique<double>(1.0);
    EXPECT_EQ(c.count(), 1);
  }
  const sim::World sc =
      sim::load_world(std::string(POISE_SOURCE_DIR) + "/tests/nodes/standing_short.yaml");
  sim::Simulator simulator(sc.sim);
  const auto feet = sim_node::foot_order(simulator);
  const auto robot = model::load_robot_config(sc.robot_config);
  const auto model = model::load_robot_model(robot);
  const auto map = node::model_to_wire_map(simulator.joint_names(), model.joint_names);
  estimator::Estimator est(model, robot);
  auto frame = est.make_sensor_frame();
  auto est_state = est.make_state();
  controller::BalanceController ctrl(model, robot, controller::ControllerConfig{});
  auto state = ctrl.make_state();
  auto reference = ctrl.make_reference();
  auto command = ctrl.make_command();
  contact::ContactProblem problem;
  contact::ContactSolution solution;
  sim::SensorFrame sensors = simulator.make_sensor_frame();
  sim::GroundTruth truth = simulator.make_ground_truth();
  sim::JointCommand sim_cmd = simulator.make_command();
  sim_node::settle(simulator, 5, sensors, truth);
  sim_node::SlipTracker slip(sim::platforms_of_feet(sc));
  const std::vector<std::int32_t> urdf_link_of_body(simulator.body_names().size(), 0);
  auto m_sensors = std::make_unique<msg::Sensors>();
  auto m_truth = std::make_unique<msg::GroundTruth>();
  auto m_state = std::make_unique<msg::State>();
  auto m_problem = std::make_unique<msg::ContactProblem>();
  auto m_solution = std::make_unique<msg::ContactSolution>();
  auto m_command = std::make_unique<msg::JointCommand>();
  auto m_reference = std::make_unique<msg::BalanceReference>();
  node::Mailbox<msg::JointCommand> box;
  node::ComputeStats stats(64);
  node::LatencyHistogram hist(1000);
  std::uint64_t seen = 0;

  auto one_tick = [&] {
    sim_node::to_msg(sensors, feet, *m_sensors);
    slip.update(truth);
    sim_node::to_msg(truth, feet, slip, urdf_link_of_body, 0, *m_truth);
    estimator_node::from_msg(*m_sensors, map, frame);
    est.update(frame, est_state);
    estimator_node::to_msg(est_state, map, *m_state);
    controller_node::from_msg(*m_state, map, state);
    controller_node::from_msg(*m_reference, map, reference);
    contact_node::to_msg(ctrl.problem(), *m_problem);
    contact_node::from_msg(*m_problem, problem);
    contact_node::to_msg(solution, m_problem->header(), 1.0, contact::Method::kSequential,
                         *m_solution);
    contact_node::from_msg(*m_solution, solution);
    controller_node::to_msg(command, m_state->header(), map, *m_command);
    EXPECT_TRUE(reflect::validate(*m_command));
    box.put(*m_command);
    box.take(*m_command, seen);
    EXPECT_TRUE(sim_node::from_msg(*m_command, sim_cmd));
    stats.add(12.0);
    hist.add(34.0);
  };
  one_tick();  // warm-up
  Counting counting;
  one_tick();
  one_tick();
  EXPECT_EQ(counting.count(), 0);
}

}  // namespace
