// The `reality:` section: its parser, the typical profile, and the draw applied to the robot tree
// (reality.hpp, reality_detail.hpp; simulator/README.md "Reality: a robot that is not its model").
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "reality_detail.hpp"

namespace poise::sim {

RealityConfig typical_reality() {
  // Figures and their sources: simulator/README.md "The typical profile".
  RealityConfig r;
  r.enabled = true;
  r.profile = "typical";
  r.links.mass_scale_std = 0.05;
  r.links.inertia_scale_std = 0.15;
  r.links.com_offset_std_m = 0.01;
  r.actuators.bandwidth_hz = 40.0;
  r.actuators.delay_ticks = 2;
  r.actuators.torque_noise_of_effort = 0.01;
  r.actuators.coulomb_friction_of_effort = 0.008;
  r.actuators.viscous_friction = 0.3;
  r.actuators.effort_scale = 0.85;
  r.ground.friction_min = 0.6;
  r.ground.friction_max = 1.0;
  r.ground.stiffness = 7.5e4;
  r.ground.damping = 1e3;
  return r;
}

std::string describe_reality(const RealityDraw& d) {
  if (!d.enabled) return {};
  const RealityConfig& c = d.config;
  const ActuatorReality& a = c.actuators;
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "reality %s, seed %llu: mass %.2f kg (model %.2f), CoM shift (%.1f, %.1f, %.1f) mm "
                "at q = 0, %zu payload(s); ground mu %s, stiffness %.3g N/m; actuators: lag %.4g Hz, "
                "delay %d ticks, effort x%.2f",
                c.profile.empty() ? "(custom)" : c.profile.c_str(),
                static_cast<unsigned long long>(d.seed), d.mass, d.mass_nominal,
                1e3 * d.com_shift_at_zero.x(), 1e3 * d.com_shift_at_zero.y(),
                1e3 * d.com_shift_at_zero.z(), c.payloads.size(),
                std::isfinite(d.ground_friction) ? std::to_string(d.ground_friction).substr(0, 5).c_str()
                                                 : "as the world",
                c.ground.stiffness, a.bandwidth_hz, a.delay_ticks, a.effort_scale);
  return buf;
}

namespace detail {

double PortableNormal::operator()() noexcept {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  const double r = std::sqrt(-2.0 * std::log(uniform()));
  const double t = 2.0 * M_PI * uniform();
  spare_ = r * std::sin(t);
  has_spare_ = true;
  return r * std::cos(t);
}

double PortableNormal::clipped(double limit) noexcept {
  const double z = (*this)();
  return z < -limit ? -limit : (z > limit ? limit : z);
}

namespace {

constexpr const char* kKey = "reality";

double nonneg(const YamlChecks& c, const YAML::Node& n, const char* k, const std::string& key,
              double dflt) {
  const double v = c.num(n, k, key, dflt);
  if (!(v >= 0.0)) c.fail(key + "." + k, "must be >= 0");
  return v;
}

double scale_std(const YamlChecks& c, const YAML::Node& n, const char* k, const std::string& key,
                 double dflt) {
  const double v = nonneg(c, n, k, key, dflt);
  if (v > kRealityMaxScaleStd)
    c.fail(key + "." + k, "must be at most " + std::to_string(kRealityMaxScaleStd) +
                              " (a scale of 1 - 3 std must stay positive)");
  return v;
}

template <typename T, typename F>
void named_map(const YamlChecks& c, const YAML::Node& n, const std::string& key,
               std::vector<std::pair<std::string, T>>& out, F value) {
  if (!n) return;
  if (!n.IsMap()) c.fail(key, "must be a mapping of link name to value");
  out.clear();
  for (const auto& kv : n) {
    const std::string link = kv.first.as<std::string>();
    for (const auto& [name, v] : out)
      if (name == link) c.fail(key + "." + link, "given twice");
    out.emplace_back(link, value(kv.second, key + "." + link));
  }
}

void parse_links(const YamlChecks& c, const YAML::Node& n, LinkReality& l) {
  const std::string key = std::string(kKey) + ".links";
  c.allow_declared(n, key);
  l.mass_scale_std = scale_std(c, n, "mass_scale_std", key, l.mass_scale_std);
  l.inertia_scale_std = scale_std(c, n, "inertia_scale_std", key, l.inertia_scale_std);
  l.com_offset_std_m = nonneg(c, n, "com_offset_std_m", key, l.com_offset_std_m);
  if (l.com_offset_std_m > 0.1) c.fail(key + ".com_offset_std_m", "must be at most 0.1 m");
  const auto positive_scale = [&](const YAML::Node& v, const std::string& k) {
    const double s = c.num(v, k);
    if (!(s > 0.0 && s <= 10.0)) c.fail(k, "must be in (0, 10]");
    return s;
  };
  named_map(c, n["mass_scale"], key + ".mass_scale", l.mass_scale, positive_scale);
  named_map(c, n["inertia_scale"], key + ".inertia_scale", l.inertia_scale, positive_scale);
  named_map(c, n["com_offset"], key + ".com_offset", l.com_offset,
            [&](const YAML::Node& v, const std::string& k) {
              const Eigen::Vector3d d = c.vec3(v, k);
              if (d.norm() > 1.0) c.fail(k, "must be at most 1 m long");
              return d;
            });
}

void parse_payloads(const YamlChecks& c, const YAML::Node& n, std::vector<Payload>& out) {
  const std::string key = std::string(kKey) + ".payloads";
  if (!n.IsSequence()) c.fail(key, "must be a list of {link, mass, offset, inertia}");
  out.clear();
  for (std::size_t i = 0; i < n.size(); ++i) {
    const std::string pk = key + "[" + std::to_string(i) + "]";
    const YAML::Node p = n[i];
    c.allow_declared(p, pk);
    if (!p["link"]) c.fail(pk + ".link", "is required");
    if (!p["mass"]) c.fail(pk + ".mass", "is required");
    Payload pl;
    pl.link = c.str(p["link"], pk + ".link");
    pl.mass = c.num(p["mass"], pk + ".mass");
    if (!(pl.mass > 0.0 && pl.mass <= 1e4)) c.fail(pk + ".mass", "must be in (0, 1e4] kg");
    if (p["offset"]) pl.offset = c.vec3(p["offset"], pk + ".offset");
    if (pl.offset.norm() > 2.0) c.fail(pk + ".offset", "must be at most 2 m from the link");
    if (p["inertia"]) pl.inertia = c.vec3(p["inertia"], pk + ".inertia");
    if (!(pl.inertia.array() >= 0.0).all())
      c.fail(pk + ".inertia", "principal moments must be >= 0");
    const Eigen::Vector3d& J = pl.inertia;
    if (J.x() + J.y() < J.z() * (1 - 1e-9) || J.y() + J.z() < J.x() * (1 - 1e-9) ||
        J.z() + J.x() < J.y() * (1 - 1e-9))
      c.fail(pk + ".inertia", "violates the triangle inequality (no rigid body has it)");
    out.push_back(pl);
  }
}

void parse_actuators(const YamlChecks& c, const YAML::Node& n, ActuatorReality& a) {
  const std::string key = std::string(kKey) + ".actuators";
  c.allow_declared(n, key);
  a.bandwidth_hz = nonneg(c, n, "bandwidth_hz", key, a.bandwidth_hz);
  if (n["delay_ticks"]) {
    const double d = c.num(n["delay_ticks"], key + ".delay_ticks");
    if (d < 0.0 || d > 1000.0 || d != std::floor(d))
      c.fail(key + ".delay_ticks", "must be an integer in [0, 1000]");
    a.delay_ticks = static_cast<int>(d);
  }
  a.torque_noise_std = nonneg(c, n, "torque_noise_std", key, a.torque_noise_std);
  a.torque_noise_of_effort = nonneg(c, n, "torque_noise_of_effort", key, a.torque_noise_of_effort);
  a.coulomb_friction = nonneg(c, n, "coulomb_friction", key, a.coulomb_friction);
  a.coulomb_friction_of_effort =
      nonneg(c, n, "coulomb_friction_of_effort", key, a.coulomb_friction_of_effort);
  a.viscous_friction = nonneg(c, n, "viscous_friction", key, a.viscous_friction);
  for (const auto& [k, v] : {std::pair<const char*, double>{"torque_noise_of_effort", a.torque_noise_of_effort},
                              {"coulomb_friction_of_effort", a.coulomb_friction_of_effort}})
    if (v > 1.0) c.fail(key + "." + k, "a fraction of the effort limit: must be at most 1");
  a.effort_scale = c.num(n, "effort_scale", key, a.effort_scale);
  if (!(a.effort_scale > 0.0 && a.effort_scale <= 1.0))
    c.fail(key + ".effort_scale", "must be in (0, 1]");
}

void parse_ground(const YamlChecks& c, const YAML::Node& n, GroundReality& g) {
  const std::string key = std::string(kKey) + ".ground";
  c.allow_declared(n, key);
  if (const YAML::Node f = n["friction"]) {
    const std::string fk = key + ".friction";
    if (f.IsSequence()) {
      if (f.size() != 2) c.fail(fk, "must be a number or a range [min, max]");
      g.friction_min = c.num(f[0], fk + "[0]");
      g.friction_max = c.num(f[1], fk + "[1]");
    } else {
      g.friction_min = g.friction_max = c.num(f, fk);
    }
    if (!(g.friction_min >= 0.0 && g.friction_max >= g.friction_min && g.friction_max <= 10.0))
      c.fail(fk, "must satisfy 0 <= min <= max <= 10");
  }
  g.stiffness = nonneg(c, n, "stiffness", key, g.stiffness);
  g.damping = nonneg(c, n, "damping", key, g.damping);
  if (g.stiffness > 1e12) c.fail(key + ".stiffness", "must be at most 1e12 N/m (0 = rigid)");
  if (g.damping > 0.0 && !(g.stiffness > 0.0))
    c.fail(key + ".damping", "needs a stiffness (a rigid ground has no contact damping)");
}

}  // namespace

RealityConfig parse_reality(const YamlChecks& c, const YAML::Node& node) {
  RealityConfig r;
  const auto profile = [&](const std::string& name, const std::string& key) {
    if (name == "typical") return typical_reality();
    if (name == "none" || name == "nominal") return RealityConfig{};
    c.fail(key, "unknown profile '" + name + "' (known: typical, none)");
  };
  if (node.IsScalar()) return profile(c.str(node, kKey), kKey);
  c.allow_declared(node, kKey);
  if (node["profile"]) r = profile(c.str(node["profile"], "reality.profile"), "reality.profile");
  r.enabled = true;
  if (node["seed"]) {
    const double seed = c.num(node["seed"], "reality.seed");
    if (!(seed >= 0.0 && seed <= 9007199254740992.0) || seed != std::floor(seed))
      c.fail("reality.seed", "must be an integer in [0, 2^53]");
    r.seed = static_cast<std::uint64_t>(seed);
  }
  if (node["links"]) parse_links(c, node["links"], r.links);
  if (node["payloads"]) parse_payloads(c, node["payloads"], r.payloads);
  if (node["actuators"]) parse_actuators(c, node["actuators"], r.actuators);
  if (node["ground"]) parse_ground(c, node["ground"], r.ground);
  return r;
}

namespace {

Eigen::Matrix3d shift(double m, const Eigen::Vector3d& d) {  // parallel-axis term
  return m * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
}

/// Index of the body a configured name means: the URDF link that starts it. A link merged into
/// another body by a fixed joint is named by that body's link instead.
int body_named(const RobotTree& tree, const std::string& name, const std::string& key) {
  for (std::size_t b = 0; b < tree.bodies.size(); ++b)
    if (tree.bodies[b].name == name) return static_cast<int>(b);
  if (const FrameSpec* f = tree.find_frame(name))
    throw std::runtime_error(key + ": link '" + name + "' is fixed to '" +
                             tree.bodies[static_cast<std::size_t>(f->body)].name +
                             "' (the two move as one body): name '" +
                             tree.bodies[static_cast<std::size_t>(f->body)].name + "' instead");
  throw std::runtime_error(key + ": '" + name + "' is not a link of the URDF");
}

/// The whole robot's CoM at q = 0 in the root body's frame.
Eigen::Vector3d com_at_zero(const RobotTree& tree) {
  std::vector<Eigen::Isometry3d> X(tree.bodies.size(), Eigen::Isometry3d::Identity());
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  double m = 0.0;
  for (std::size_t b = 0; b < tree.bodies.size(); ++b) {
    const BodySpec& body = tree.bodies[b];
    if (body.parent >= 0) X[b] = X[static_cast<std::size_t>(body.parent)] * body.X_PJ;
    c += body.mass * (X[b] * body.com_L);
    m += body.mass;
  }
  return m > 0.0 ? Eigen::Vector3d(c / m) : Eigen::Vector3d::Zero();
}

}  // namespace

RealityDraw apply_reality(const RealityConfig& config, RobotTree& tree) {
  RealityDraw d;
  d.enabled = config.enabled;
  d.profile = config.profile;
  d.seed = config.seed;
  d.config = config;
  if (!config.enabled) return d;
  const LinkReality& l = config.links;
  const Eigen::Vector3d com0 = com_at_zero(tree);

  // Draws: five normals per body in body order whether or not used (an explicit value for one
  // link leaves every other link's draw as it was), then the ground friction.
  PortableNormal z(config.seed);
  const std::size_t nb = tree.bodies.size();
  d.bodies.resize(nb);
  for (std::size_t b = 0; b < nb; ++b) {
    RealityDraw::Body& r = d.bodies[b];
    r.name = tree.bodies[b].name;
    r.mass_scale = 1.0 + l.mass_scale_std * z.clipped(kRealityClip);
    r.inertia_scale = 1.0 + l.inertia_scale_std * z.clipped(kRealityClip);
    for (int k = 0; k < 3; ++k) r.com_offset[k] = l.com_offset_std_m * z.clipped(kRealityClip);
  }
  if (std::isfinite(config.ground.friction_min))
    d.ground_friction = config.ground.friction_min +
                        (config.ground.friction_max - config.ground.friction_min) * z.uniform();

  for (const auto& [name, v] : l.mass_scale)
    d.bodies[static_cast<std::size_t>(body_named(tree, name, "reality.links.mass_scale"))]
        .mass_scale = v;
  for (const auto& [name, v] : l.inertia_scale)
    d.bodies[static_cast<std::size_t>(body_named(tree, name, "reality.links.inertia_scale"))]
        .inertia_scale = v;
  for (const auto& [name, v] : l.com_offset)
    d.bodies[static_cast<std::size_t>(body_named(tree, name, "reality.links.com_offset"))]
        .com_offset = v;

  for (std::size_t b = 0; b < nb; ++b) {
    BodySpec& body = tree.bodies[b];
    RealityDraw::Body& r = d.bodies[b];
    r.mass_nominal = body.mass;
    d.mass_nominal += body.mass;
    body.mass *= r.mass_scale;
    body.inertia_com_L *= r.mass_scale * r.inertia_scale;
    body.com_L += r.com_offset;
  }
  for (std::size_t i = 0; i < config.payloads.size(); ++i) {
    const Payload& p = config.payloads[i];
    const std::string key = "reality.payloads[" + std::to_string(i) + "]";
    const FrameSpec* f = tree.find_frame(p.link);
    if (!f) throw std::runtime_error(key + ".link: '" + p.link + "' is not a link of the URDF");
    BodySpec& body = tree.bodies[static_cast<std::size_t>(f->body)];
    const Eigen::Vector3d c_p = f->X_LF * p.offset;  // in the body frame
    const Eigen::Matrix3d R = f->X_LF.linear();
    const Eigen::Matrix3d I_p = R * p.inertia.asDiagonal() * R.transpose();
    const double m = body.mass + p.mass;
    const Eigen::Vector3d c = (body.mass * body.com_L + p.mass * c_p) / m;
    body.inertia_com_L =
        body.inertia_com_L + shift(body.mass, body.com_L - c) + I_p + shift(p.mass, c_p - c);
    body.com_L = c;
    body.mass = m;
  }
  for (std::size_t b = 0; b < nb; ++b) {
    d.bodies[b].mass = tree.bodies[b].mass;
    d.mass += tree.bodies[b].mass;
  }
  d.com_shift_at_zero = com_at_zero(tree) - com0;
  return d;
}

}  // namespace detail
}  // namespace poise::sim
