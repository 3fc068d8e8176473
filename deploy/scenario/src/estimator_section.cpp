// The scenario's `estimator:` section, declared once: the table below drives the allowed keys,
// the parser and its checks, and the generated reference estimator/CONFIG.md. The defaults are
// EstimatorHints' member initialisers and, where the scenario leaves a setting to the estimator,
// EstimatorConfig's.
#include "poise/cli/reference_text.hpp"
#include "estimator_section.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <limits>
#include <variant>

#include "poise/estimator/estimator.hpp"
#include "poise/estimator/settings.hpp"

namespace poise::scenario {
namespace {

using estimator::kContactFtNoiseSetting;
using estimator::kContactRestTimeSetting;
using estimator::kImuDelayTicksSetting;
using estimator::kStanceRateSetting;
using estimator::kSupportsSetting;
using estimator::kTypeSetting;

using FootHeights = std::vector<std::pair<std::string, double>>;

struct EstimatorKey {
  std::string_view key;
  /// Where the value goes; its type is the key's kind: a name out of `choices`, a number, a whole
  /// number, a mapping foot -> height.
  std::variant<std::string EstimatorHints::*, double EstimatorHints::*, int EstimatorHints::*,
               FootHeights EstimatorHints::*>
      field;
  std::string_view unit;
  std::array<std::string_view, 3> choices;  ///< names: the allowed values ("" unused)
  double lo, hi;                            ///< numbers: inclusive bounds (infinite: none)
  std::string_view note;                    ///< appended to the range in errors and docs
  std::string (*default_text)();            ///< what holds when the key is not given
  std::string_view doc;                     ///< one line
};

constexpr double kInf = std::numeric_limits<double>::infinity();

using cli::number_text;

const estimator::EstimatorConfig& config_defaults() {
  static const estimator::EstimatorConfig c;
  return c;
}

// One row a key: clang-format would put each of a row's fields on a line of its own.
// clang-format off
const EstimatorKey kKeys[] = {
    {kTypeSetting.name, &EstimatorHints::type, "", kTypeSetting.choices, 0, 0, "",
     [] { return EstimatorHints{}.type; }, kTypeSetting.doc},
    {kSupportsSetting.name, &EstimatorHints::supports, "", kSupportsSetting.choices, 0, 0, "",
     [] { return EstimatorHints{}.supports; }, kSupportsSetting.doc},
    {"ground_height", &EstimatorHints::ground_height, "m", {}, -kInf, kInf, "",
     [] { return std::string("the ground plane's (platforms: each foot's at t = 0)"); },
     "z of the ground under both soles at the start"},
    {"support_height", &EstimatorHints::support_height, "m", {}, -kInf, kInf,
     "a mapping foot -> height (m), feet of the robot", [] { return std::string("ground_height"); },
     "z of each named foot's sole point at the start (feet on supports of their own)"},
    {kStanceRateSetting.name, &EstimatorHints::stance_rate_hz, kStanceRateSetting.unit, {},
     kStanceRateSetting.lo, kStanceRateSetting.hi, kStanceRateSetting.note,
     [] { return number_text(config_defaults().stance_rate_filter_hz); }, kStanceRateSetting.doc},
    {kContactFtNoiseSetting.name, &EstimatorHints::contact_ft_noise, kContactFtNoiseSetting.unit, {},
     kContactFtNoiseSetting.lo, kContactFtNoiseSetting.hi, kContactFtNoiseSetting.note,
     [] { return "the simulated F/T's force_noise_std when > 0, else " +
                 number_text(config_defaults().contact_ft_noise); },
     kContactFtNoiseSetting.doc},
    {kContactRestTimeSetting.name, &EstimatorHints::contact_rest_time, kContactRestTimeSetting.unit,
     {}, kContactRestTimeSetting.lo, kContactRestTimeSetting.hi, kContactRestTimeSetting.note,
     [] { return number_text(config_defaults().contact_rest_time); }, kContactRestTimeSetting.doc},
    {kImuDelayTicksSetting.name, &EstimatorHints::imu_delay_ticks, kImuDelayTicksSetting.unit, {},
     kImuDelayTicksSetting.lo, kImuDelayTicksSetting.hi, kImuDelayTicksSetting.note,
     [] { return std::string("the simulated IMU's delay_ticks"); }, kImuDelayTicksSetting.doc},
};
// clang-format on

/// "'a', 'b' or 'c'".
std::string choices_text(const EstimatorKey& k) {
  std::string out;
  std::size_t n = 0;
  for (const auto c : k.choices)
    n += !c.empty();
  for (std::size_t i = 0; i < n; ++i) {
    out += i == 0 ? "" : i + 1 == n ? " or " : ", ";
    out.append("'").append(k.choices[i]).append("'");
  }
  return out;
}

/// "a finite number >= 0", "a whole number within 0..100", ...
std::string range_text(const EstimatorKey& k) {
  const bool whole = std::holds_alternative<int EstimatorHints::*>(k.field);
  std::string out = whole ? "a whole number" : "a finite number";
  if (std::isfinite(k.lo) && std::isfinite(k.hi))
    out += " within " + number_text(k.lo) + ".." + number_text(k.hi);
  else if (std::isfinite(k.lo))
    out += " >= " + number_text(k.lo);
  return out;
}

/// What a value of `k` must be, in words (errors and docs).
std::string must_text(const EstimatorKey& k) {
  if (std::holds_alternative<FootHeights EstimatorHints::*>(k.field)) return std::string(k.note);
  const std::string what = std::holds_alternative<std::string EstimatorHints::*>(k.field)
                               ? choices_text(k)
                               : range_text(k);
  return k.note.empty() ? what : what + " (" + std::string(k.note) + ")";
}

void read_number(const YAML::Node& v, const EstimatorKey& k, const sim::YamlChecks& c,
                 double& out) {
  const std::string key = "estimator." + std::string(k.key);
  const double d = c.num(v, key);
  if (!(d >= k.lo && d <= k.hi)) c.fail(key, "must be " + must_text(k));
  out = d;
}

void read_key(const YAML::Node& v, const EstimatorKey& k, const sim::YamlChecks& c,
              const sim::World& world, EstimatorHints& hints) {
  const std::string key = "estimator." + std::string(k.key);
  if (const auto* f = std::get_if<std::string EstimatorHints::*>(&k.field)) {
    const std::string s = c.str(v, key);
    if (std::find(k.choices.begin(), k.choices.end(), s) == k.choices.end() || s.empty())
      c.fail(key, "must be " + must_text(k));
    hints.*(*f) = s;
  } else if (const auto* f = std::get_if<double EstimatorHints::*>(&k.field)) {
    read_number(v, k, c, hints.*(*f));
  } else if (const auto* f = std::get_if<int EstimatorHints::*>(&k.field)) {
    double d = 0.0;
    read_number(v, k, c, d);
    if (d != std::floor(d)) c.fail(key, "must be " + must_text(k));
    hints.*(*f) = static_cast<int>(d);
  } else {
    if (!v.IsMap()) c.fail(key, "must be " + must_text(k));
    auto& out = hints.*std::get<FootHeights EstimatorHints::*>(k.field);
    for (const auto& kv : v) {
      const std::string foot = kv.first.as<std::string>();
      const bool known = std::any_of(world.sim.robot.feet.begin(), world.sim.robot.feet.end(),
                                     [&](const auto& f) { return f.name == foot; });
      if (!known) c.fail(key + "." + foot, "is not a foot of the robot");
      out.emplace_back(foot, c.num(kv.second, key + "." + foot));
    }
  }
}

std::string cell(std::string_view s) { return cli::markdown_cell(s); }

}  // namespace

std::vector<std::string_view> estimator_section_keys() {
  std::vector<std::string_view> out;
  for (const auto& k : kKeys)
    out.push_back(k.key);
  return out;
}

void parse_estimator_section(const YAML::Node& section, const sim::YamlChecks& c,
                             const sim::World& world, EstimatorHints& hints) {
  if (!section.IsMap()) c.fail("estimator", "must be a mapping");
  for (const auto& kv : section) {
    const std::string k = kv.first.as<std::string>();
    const auto it = std::find_if(std::begin(kKeys), std::end(kKeys),
                                 [&](const EstimatorKey& e) { return e.key == k; });
    if (it == std::end(kKeys)) {
      std::string list;
      for (const auto& e : kKeys)
        list += (list.empty() ? "" : ", ") + std::string(e.key);
      c.fail("estimator." + k, "unknown key (allowed: " + list + ")");
    }
  }
  for (const auto& k : kKeys)
    if (const YAML::Node v = section[std::string(k.key)]) read_key(v, k, c, world, hints);
}

std::string estimator_section_markdown() {
  std::string out =
      "| key | default | unit | allowed | description |\n"
      "|---|---|---|---|---|\n";
  for (const auto& k : kKeys)
    out += "| `estimator." + std::string(k.key) + "` | " + cell(k.default_text()) + " | " +
           cell(k.unit.empty() ? "—" : k.unit) + " | " + cell(must_text(k)) + " | " + cell(k.doc) +
           " |\n";
  return out;
}

}  // namespace poise::scenario
