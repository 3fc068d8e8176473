#pragma once
// The reality draw as JSON: the `reality` object of a run's result (poise run, in process and
// distributed; poise-sim's summary). Header-only so that poise_sim itself needs no JSON library.
#include <nlohmann/json.hpp>

#include <cmath>

#include "poise/sim/reality.hpp"

namespace poise::sim {

/// null when the robot is its model; otherwise what was asked and what was drawn.
inline nlohmann::json reality_to_json(const RealityDraw& d) {
  if (!d.enabled) return nullptr;
  using nlohmann::json;
  const auto vec = [](const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); };
  const RealityConfig& c = d.config;
  json links = json::object();
  for (const auto& b : d.bodies)
    links[b.name] = {{"mass_nominal_kg", b.mass_nominal},
                     {"mass_kg", b.mass},
                     {"mass_scale", b.mass_scale},
                     {"inertia_scale", b.inertia_scale},
                     {"com_offset_m", vec(b.com_offset)}};
  json payloads = json::array();
  for (const auto& p : c.payloads)
    payloads.push_back({{"link", p.link},
                        {"mass_kg", p.mass},
                        {"offset_m", vec(p.offset)},
                        {"inertia_kg_m2", vec(p.inertia)}});
  const ActuatorReality& a = c.actuators;
  const GroundReality& g = c.ground;
  return {
      {"profile", c.profile.empty() ? json(nullptr) : json(c.profile)},
      {"seed", d.seed},
      {"mass_nominal_kg", d.mass_nominal},
      {"mass_kg", d.mass},
      {"com_shift_at_zero_m", vec(d.com_shift_at_zero)},
      {"distributions",
       {{"mass_scale_std", c.links.mass_scale_std},
        {"inertia_scale_std", c.links.inertia_scale_std},
        {"com_offset_std_m", c.links.com_offset_std_m}}},
      {"links", links},
      {"payloads", payloads},
      {"actuators",
       {{"bandwidth_hz", a.bandwidth_hz},
        {"delay_ticks", a.delay_ticks},
        {"torque_noise_std", a.torque_noise_std},
        {"torque_noise_of_effort", a.torque_noise_of_effort},
        {"coulomb_friction", a.coulomb_friction},
        {"coulomb_friction_of_effort", a.coulomb_friction_of_effort},
        {"viscous_friction", a.viscous_friction},
        {"effort_scale", a.effort_scale}}},
      {"ground",
       {{"friction", std::isfinite(d.ground_friction) ? json(d.ground_friction) : json(nullptr)},
        {"friction_range", std::isfinite(g.friction_min)
                               ? json::array({g.friction_min, g.friction_max})
                               : json(nullptr)},
        {"stiffness", g.stiffness},
        {"damping", g.damping}}}};
}

}  // namespace poise::sim
