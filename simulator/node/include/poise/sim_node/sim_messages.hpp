#pragma once
// IDL (idl/robot_description.idl, sensors.idl, ground_truth.idl, joint_command.idl,
// disturbance.idl) <-> simulator library conversions. The simulator's joint order IS the wire
// joint order (the robot description lists Simulator::joint_names()); feet are reordered to the
// wire's [right, left]. Per-tick functions are allocation-free and noexcept.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <poise/msg/disturbance.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>

#include "poise/safety/safety_layer.hpp"
#include "poise/sim/world.hpp"
#include "poise/sim/simulator.hpp"

namespace poise::sim_node {

/// wire foot f (0 = right, 1 = left) -> simulator foot index.
using FootOrder = std::array<int, 2>;

/// Finds the right and left feet among the simulator's feet by name ("right"/"r..."/"left"/...).
/// Throws std::runtime_error naming the feet when it cannot (configuration time).
FootOrder foot_order(const sim::Simulator& sim);

/// The robot description of a scenario: URDF text (read from the file), joint order, IMU frame,
/// soles (geometry from the scenario; safety margin and friction from the robot configuration
/// when the scenario names one, else 0 margin and the ground friction). Throws on I/O errors.
msg::RobotDescription make_robot_description(const sim::World& scenario,
                                             const sim::Simulator& sim, const FootOrder& feet);

/// SensorFrame -> Sensors.
void to_msg(const sim::SensorFrame& in, const FootOrder& feet, msg::Sensors& out) noexcept;

/// Tracks each foot's slip relative to its support (ground or platform) since touch-down.
class SlipTracker {
 public:
  explicit SlipTracker(std::vector<int> platform_of_sim_foot);
  /// Updates from the truth of one tick; slip_W(f) afterwards. No allocation.
  void update(const sim::GroundTruth& truth) noexcept;
  Eigen::Vector3d slip_W(int sim_foot) const noexcept { return slip_[sim_foot]; }

 private:
  std::vector<int> platform_;
  std::vector<bool> was_in_contact_;
  std::vector<Eigen::Vector3d> p_support_0_;  // foot origin in the support frame at touch-down
  std::vector<Eigen::Vector3d> slip_;
};

/// URDF link index of every simulator body: the position of the body's link (a body is named
/// after its URDF link, Simulator::body_names()) among the <link> elements of `urdf_xml`, in
/// document order, as GroundTruth.other_contact_links counts them. Configuration time; throws
/// std::runtime_error on unreadable XML or a body whose link the URDF does not have.
std::vector<std::int32_t> urdf_link_index_of_bodies(const std::string& urdf_xml,
                                                    const std::vector<std::string>& body_names);

/// GroundTruth -> GroundTruth. Non-foot contacts are listed by URDF link index
/// (`urdf_link_of_body`[body], see urdf_link_index_of_bodies()), at most MAX_OTHER_CONTACTS.
void to_msg(const sim::GroundTruth& in, const FootOrder& feet, const SlipTracker& slip,
            const std::vector<std::int32_t>& urdf_link_of_body, std::uint64_t total_other_contacts,
            msg::GroundTruth& out) noexcept;

/// JointCommand -> simulator command (sized by Simulator::make_command()). COMMAND_TORQUE is
/// tau_ff plus the PD terms (the simulator's kPd), COMMAND_DAMPING is -kd qd, COMMAND_ZERO is no
/// torque. False (out untouched) when joint_count differs from the simulator's joint count.
bool from_msg(const msg::JointCommand& in, sim::JointCommand& out) noexcept;

/// The robot safety layer's command -> simulator command (kPd: the same law). poise-sim and the
/// in-process loop both apply the layer's output through this. No allocation once `out` is sized.
void to_sim(const safety::Command& in, sim::JointCommand& out) noexcept;

/// Disturbance (PUSH) -> Push; a negative start time means now (`now_s`). False for a kind the
/// simulator cannot apply live (PLATFORM).
bool from_msg(const msg::Disturbance& in, double now_s, sim::Push& out);

/// Start-up settling: holds the joints at their current positions by PD (kp, kd, all joints) for
/// `ticks` steps, so that the robot rests on its supports and the first sensor frame the
/// components see already measures the foot loads (the frame after construction has none: no
/// contact has been solved yet, and an estimator would report "no contact" = flight).
/// Configuration time (allocates).
void settle(sim::Simulator& sim, int ticks, sim::SensorFrame& sensors, sim::GroundTruth& truth,
            double kp = 400.0, double kd = 10.0);

}  // namespace poise::sim_node
