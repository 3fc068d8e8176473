#include "poise/contact/contact_json.hpp"
#include "poise/contact/contact_optimizer.hpp"

#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>

namespace poise::contact {

namespace {

using nlohmann::json;

[[noreturn]] void fail(const std::string& field, const std::string& what) {
  throw std::invalid_argument(field + ": " + what);
}

const json& member(const json& j, const std::string& path, const char* key) {
  if (!j.contains(key)) fail(path.empty() ? key : path + "." + key, "missing field");
  return j.at(key);
}

double number(const json& j, const std::string& path) {
  if (!j.is_number()) fail(path, "expected a number, got " + std::string(j.type_name()));
  const double v = j.get<double>();
  if (!std::isfinite(v)) fail(path, "not a finite number");
  return v;
}

double number_field(const json& j, const std::string& path, const char* key) {
  return number(member(j, path, key), path.empty() ? key : path + "." + key);
}

template <int N>
Eigen::Matrix<double, N, 1> vector_field(const json& j, const std::string& path, const char* key) {
  const std::string name = path.empty() ? key : path + "." + key;
  const json& a = member(j, path, key);
  if (!a.is_array() || a.size() != N) {
    fail(name, "expected an array of " + std::to_string(N) + " numbers");
  }
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i)
    v[i] = number(a[i], name + "[" + std::to_string(i) + "]");
  return v;
}

json to_array(const Eigen::Ref<const Eigen::VectorXd>& v) {
  json a = json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i)
    a.push_back(v[i]);
  return a;
}

constexpr const char* kFootNames[kMaxFeet] = {"right", "left"};

}  // namespace

ContactProblem problem_from_json(const json& j, std::array<bool, kMaxFeet>* present) {
  if (!j.is_object()) fail("problem", "expected a JSON object");
  ContactProblem p;
  p.mass = number_field(j, "", "mass");
  p.gravity = vector_field<3>(j, "", "gravity");
  p.com = vector_field<3>(j, "", "com");
  p.k_dot_desired = vector_field<3>(j, "", "k_dot_desired");
  p.l_dot_desired = vector_field<3>(j, "", "l_dot_desired");
  const json& feet = member(j, "", "feet");
  if (!feet.is_array() || feet.size() > kMaxFeet) fail("feet", "expected an array of 0 to 2 feet");
  present->fill(false);
  for (std::size_t k = 0; k < feet.size(); ++k) {
    const std::string path = "feet[" + std::to_string(k) + "]";
    const json& f = feet[k];
    if (!f.is_object()) fail(path, "expected an object");
    const json& name = member(f, path, "name");
    int i = -1;
    if (name.is_string() && name.get<std::string>() == "right") i = 0;
    if (name.is_string() && name.get<std::string>() == "left") i = 1;
    if (i < 0) fail(path + ".name", "expected \"right\" or \"left\"");
    if ((*present)[i]) fail(path + ".name", "foot listed twice");
    (*present)[i] = true;
    FootContact& foot = p.feet[i];
    const json& c = member(f, path, "in_contact");
    if (!c.is_boolean()) fail(path + ".in_contact", "expected true or false");
    foot.in_contact = c.get<bool>();
    foot.p_WF = vector_field<3>(f, path, "position");
    const Eigen::Vector4d q = vector_field<4>(f, path, "orientation_wxyz");
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      fail(path + ".orientation_wxyz",
           "not a unit quaternion (norm " + std::to_string(q.norm()) + ")");
    }
    foot.R_WF = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    const json& sole = member(f, path, "sole");
    if (!sole.is_object()) fail(path + ".sole", "expected an object");
    foot.sole.x_min = number_field(sole, path + ".sole", "x_min");
    foot.sole.x_max = number_field(sole, path + ".sole", "x_max");
    foot.sole.y_min = number_field(sole, path + ".sole", "y_min");
    foot.sole.y_max = number_field(sole, path + ".sole", "y_max");
    foot.safety_margin = number_field(f, path, "safety_margin");
    foot.ankle_height = number_field(f, path, "ankle_height");
    foot.mu = number_field(f, path, "mu");
    foot.mu_torsion = number_field(f, path, "mu_torsion");
  }
  if (j.contains("weights")) {
    const json& w = j.at("weights");
    if (!w.is_object()) fail("weights", "expected an object");
    if (w.contains("w_k")) p.weights.w_k = number_field(w, "weights", "w_k");
    if (w.contains("eps_f")) p.weights.eps_f = number_field(w, "weights", "eps_f");
    if (w.contains("eps_cop")) p.weights.eps_cop = number_field(w, "weights", "eps_cop");
    if (w.contains("eps_tau")) p.weights.eps_tau = number_field(w, "weights", "eps_tau");
    if (w.contains("priority")) {
      const json& pr = w.at("priority");
      const auto parsed = pr.is_string() ? parse_priority(pr.get<std::string>()) : std::nullopt;
      if (!parsed) fail("weights.priority", "expected \"lexicographic\" or \"weighted\"");
      p.weights.priority = *parsed;
    }
    if (w.contains("torsion_limit")) {
      const json& tl = w.at("torsion_limit");
      const auto parsed =
          tl.is_string() ? parse_torsion_limit(tl.get<std::string>()) : std::nullopt;
      if (!parsed)
        fail("weights.torsion_limit", "expected \"independent\" or \"friction-coupled\"");
      p.weights.torsion = *parsed;
    }
  }
  return p;
}

json solution_to_json(const ContactSolution& s, const std::array<bool, kMaxFeet>& present,
                      double solve_time_us) {
  json out;
  out["status"] = to_string(s.status);
  out["k_dot_admissible"] = to_array(s.k_dot_admissible);
  out["l_dot_admissible"] = to_array(s.l_dot_admissible);
  json feet = json::array();
  for (int i = 0; i < kMaxFeet; ++i) {
    if (!present[i]) continue;
    const FootWrench& w = s.feet[i];
    feet.push_back({{"name", kFootNames[i]},
                    {"force", to_array(w.force_W)},
                    {"torque_at_ankle", to_array(w.torque_ankle_W)},
                    {"cop", to_array(w.cop_W)},
                    {"cop_local", to_array(w.cop_F)},
                    {"normal_torque", w.normal_torque}});
  }
  out["feet"] = feet;
  if (solve_time_us >= 0.0) out["solve_time_us"] = solve_time_us;
  return out;
}

}  // namespace poise::contact
