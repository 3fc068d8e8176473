#include "poise/scenario/scenario.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "estimator_section.hpp"
#include "poise/sim/simulator.hpp"
#include "poise/sim/yaml_checks.hpp"

namespace poise::scenario {
namespace {

namespace fs = std::filesystem;

// The sections read here are checked as the world's are (poise::sim::parse_world): same messages.
using Ctx = sim::YamlChecks;

}  // namespace

bool is_plain_name(const std::string& name) { return plain_name_problem(name).empty(); }

std::string plain_name_problem(const std::string& name) {
  const bool ok = !name.empty() && name.size() <= 100 && name != "." &&
                  name.find("..") == std::string::npos &&
                  std::all_of(name.begin(), name.end(), [](char ch) {
                    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' ||
                           ch == '_' || ch == '-';
                  });
  if (ok) return "";
  std::string why = "'";
  why.append(name, 0, 100);
  why += "' is not a plain file name (1 to 100 of A-Z a-z 0-9 . _ -, no '..'): it names the "
         "result files";
  return why;
}

Scenario parse_scenario(const std::string& yaml_text, const fs::path& base_dir,
                        const std::string& what) {
  Scenario sc;
  // The world first: it checks the YAML, the top-level keys and the sections it owns.
  static_cast<sim::World&>(sc) = sim::parse_world(yaml_text, base_dir, what);
  Ctx c{what};
  if (const std::string problem = plain_name_problem(sc.name); !problem.empty())
    c.fail("name", problem);
  const YAML::Node root = YAML::Load(yaml_text);

  // dds hints
  if (const YAML::Node d = root["dds"]) {
    c.allow_declared(d, "dds");
    auto check = [&](const std::string& v, const std::string& key) {
      if (v != "fastdds" && v != "cyclone" && v != "cyclonedds")
        c.fail(key, "must be 'fastdds' or 'cyclone' (also spelt 'cyclonedds')");
    };
    if (d["vendor"]) {
      sc.dds.vendor = c.str(d["vendor"], "dds.vendor");
      check(sc.dds.vendor, "dds.vendor");
    }
    if (const YAML::Node comps = d["components"]) {
      if (!comps.IsMap()) c.fail("dds.components", "must be a mapping component -> vendor");
      for (const auto& kv : comps) {
        const std::string comp = kv.first.as<std::string>();
        const std::string v = c.str(kv.second, "dds.components." + comp);
        check(v, "dds.components." + comp);
        sc.dds.per_component.emplace_back(comp, v);
      }
    }
  }

  // estimator setting (estimator_section.cpp: the table of its keys)
  if (const YAML::Node e = root["estimator"]) parse_estimator_section(e, c, sc, sc.estimator);

  // contact optimiser hint for poise run
  if (const YAML::Node cn = root["contact"]) {
    c.allow_declared(cn, "contact");
    if (cn["method"]) {
      sc.contact_method = c.str(cn["method"], "contact.method");
      if (sc.contact_method != "sequential" && sc.contact_method != "qp")
        c.fail("contact.method", "must be 'sequential' or 'qp'");
    }
  }

  // controller configuration: checked by the controller's parser when a run starts
  if (const YAML::Node cn = root["controller"]) {
    if (!cn.IsMap()) c.fail("controller", "must be a mapping (the controller configuration's keys)");
    YAML::Emitter out;
    out << cn;
    sc.controller_yaml = out.c_str();
  }

  // balance-reference trajectory played during the run (loaded and checked when a run starts)
  if (const YAML::Node r = root["reference"]) {
    if (!r.IsScalar()) c.fail("reference", "must be a file name (a balance-reference trajectory)");
    const fs::path p = c.str(r, "reference");
    fs::path found;
    if (p.is_absolute()) {
      found = p;
    } else if (fs::exists(base_dir / p)) {
      found = fs::weakly_canonical(base_dir / p);
    }
    if (found.empty() || !fs::is_regular_file(found))
      c.fail("reference", "file '" + p.string() + "' not found (relative to the scenario's "
                              "folder " + base_dir.string() + ")");
    sc.reference = found;
  }

  return sc;
}

Scenario load_scenario(const fs::path& path) {
  const std::string text = sim::read_scenario_text(path);
  const fs::path abs = fs::absolute(path);
  Scenario sc = parse_scenario(text, abs.parent_path(), "scenario '" + path.string() + "'");
  sc.file = abs;
  return sc;
}

double estimator_contact_ft_noise(const Scenario& sc) {
  if (std::isfinite(sc.estimator.contact_ft_noise)) return sc.estimator.contact_ft_noise;
  if (sc.sim.foot_ft.force_noise_std > 0.0) return sc.sim.foot_ft.force_noise_std;
  return std::numeric_limits<double>::quiet_NaN();
}

int estimator_imu_delay_ticks(const Scenario& sc) {
  return sc.estimator.imu_delay_ticks >= 0 ? sc.estimator.imu_delay_ticks
                                            : std::clamp(sc.sim.imu.delay_ticks, 0, 100);
}

EstimatorStart estimator_start(const Scenario& sc) {
  EstimatorStart out;
  out.ground_height = sc.sim.world.ground.height;
  const char* side_name[2] = {"right", "left"};
  if (!sc.estimator.support_height.empty()) {
    if (std::isfinite(sc.estimator.ground_height)) out.ground_height = sc.estimator.ground_height;
    for (const auto& [foot, h] : sc.estimator.support_height)
      for (int s = 0; s < 2; ++s)
        if (foot == side_name[s]) out.support_height[static_cast<std::size_t>(s)] = h;
    out.per_foot = true;
    out.source = "scenario support_height";
    return out;
  }
  if (std::isfinite(sc.estimator.ground_height)) {
    out.ground_height = sc.estimator.ground_height;
    out.source = "scenario ground_height";
    return out;
  }
  if (sc.sim.world.platforms.empty()) {
    out.source = "ground plane";
    return out;
  }
  // Platforms: the simulator's own placement at t = 0 (no step taken).
  sim::Simulator sim(sc.sim);
  sim::SensorFrame sensors = sim.make_sensor_frame();
  sim::GroundTruth truth = sim.make_ground_truth();
  sim.read(sensors, truth);
  const auto& feet = sc.sim.robot.feet;
  for (std::size_t f = 0; f < feet.size() && f < truth.feet.size(); ++f)
    for (int s = 0; s < 2; ++s)
      if (feet[f].name == side_name[s]) {
        const double h = feet[f].has_sole ? feet[f].sole.height : 0.0;
        out.support_height[static_cast<std::size_t>(s)] =
            (truth.feet[f].X_WF * Eigen::Vector3d(0.0, 0.0, -h)).z();
        out.per_foot = true;
      }
  out.source = "platforms at t = 0";
  return out;
}

}  // namespace poise::scenario
