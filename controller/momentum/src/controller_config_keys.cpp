#include "poise/cli/reference_text.hpp"
#include "poise/controller/controller_config_keys.hpp"

#include <charconv>
#include <cmath>
#include <type_traits>

namespace poise::controller {

namespace {

// One row a key: clang-format would put each of a row's fields on a line of its own.
// clang-format off
// The field of a ControllerConfig a row reads and writes: c.momentum.gamma11, ...
#define POISE_FIELD(member) +[](ControllerConfig& c) -> auto& { return c.member; }

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr KeyRange kAny{};
constexpr KeyRange kNonNegative{0.0, kInf};
constexpr KeyRange kPositive{0.0, kInf, true};
constexpr KeyRange kFraction{0.0, 1.0, false, true};  // [0, 1)

const ConfigKey kKeys[] = {
    {"dt", POISE_FIELD(dt), "s", "—", kPositive, "", "control period"},
    // eqs (10)-(11)
    {"momentum.gamma11", POISE_FIELD(momentum.gamma11), "1/s", "(10)", kNonNegative, "",
     "Γ11, angular momentum damping (diagonal, world x y z)"},
    {"momentum.gamma21", POISE_FIELD(momentum.gamma21), "1/s", "(11)", kNonNegative, "",
     "Γ21, CoM velocity gain (paper {40, 20, 40} in its Y-up world: config/paper.yaml)"},
    {"momentum.gamma22", POISE_FIELD(momentum.gamma22), "1/s²", "(11)", kNonNegative, "",
     "Γ22, CoM position gain (paper {8, 3, 8} in its Y-up world)"},
    {"momentum.feedback_filter_hz", POISE_FIELD(momentum.feedback_filter_hz), "Hz", "(10)-(11)",
     kNonNegative, "0: no filter",
     "low-pass of the CoM velocity error and the angular momentum fed back"},
    {"momentum.support_acceleration_hz", POISE_FIELD(momentum.support_acceleration_hz), "Hz",
     "(11), Sec. 4.2", kNonNegative, "0: off",
     "cut-off of the supports' acceleration fed into (11) and leant into by the CoM target "
     "(below half the control rate)"},
    {"momentum.ankle_first_blend", POISE_FIELD(momentum.ankle_first_blend), "m", "(11)", {0.0, 1.0},
     "0: off",
     "ankle strategy first: the paper's demand returns as the capture point comes within this "
     "of the support polygon's edge"},
    {"momentum.upright_pitch_rate", POISE_FIELD(momentum.upright_pitch_rate), "1/s", "(10)",
     {0.0, 100.0}, "0: off", "rate that brings the trunk's pitch back upright (k_d += I_G ω_u)"},
    {"momentum.upright_roll_rate", POISE_FIELD(momentum.upright_roll_rate), "1/s", "(10)",
     {0.0, 100.0}, "0: off", "the same about the robot's forward axis (roll)"},
    // eqs (21), (29)
    {"contact.w_k", POISE_FIELD(contact.w_k), "", "(21)", kNonNegative, "",
     "angular momentum weight"},
    {"contact.eps_f", POISE_FIELD(contact.eps_f), "", "(21)", kNonNegative, "",
     "force regularisation weight (the paper's 0.01 as a row scale)"},
    {"contact.eps_cop", POISE_FIELD(contact.eps_cop), "", "(29)", kNonNegative, "",
     "CoP / normal-torque regularisation weight (the paper's 0.01 as a row scale)"},
    {"contact.friction_mu", POISE_FIELD(contact.friction_mu), "", "Sec. 3.3-3.4", {0.0, 10.0},
     "0: robot.yaml's contact.friction_mu",
     "the Coulomb coefficient the contact optimiser assumes (what the controller believes)"},
    {"contact.priority", POISE_FIELD(contact.priority), "", "Sec. 3.3, (21)", kAny,
     "'lexicographic' or 'weighted'",
     "lexicographic (linear momentum first) or weighted (eq. (21) as written)"},
    {"contact.torsion_limit", POISE_FIELD(contact.torsion_limit), "", "Sec. 3.4", kAny,
     "'independent' or 'friction-coupled'",
     "friction-coupled (the twist shares the friction) or independent (the paper's bound)"},
    // eq (36)
    {"foot.kp", POISE_FIELD(foot.kp), "1/s²", "(36)", kNonNegative, "", "foot position gain"},
    {"foot.kd", POISE_FIELD(foot.kd), "1/s", "(36)", kNonNegative, "", "foot velocity gain"},
    {"foot.unloaded_kp", POISE_FIELD(foot.unloaded_kp), "1/s²", "(36)", kNonNegative,
     "foot.kp: as the others", "horizontal position gain of a held foot a push lifted"},
    {"foot.unloaded_kd", POISE_FIELD(foot.unloaded_kd), "1/s", "(36)", kNonNegative,
     "foot.kd: as the others", "horizontal velocity gain of a held foot a push lifted"},
    {"foot.support_acceleration_tau", POISE_FIELD(foot.support_acceleration_tau), "s",
     "(36), Sec. 4.2", kNonNegative, "0: no support acceleration feed-forward",
     "time constant of a resting foot's measured acceleration added to its a_d"},
    // eq (33)
    {"acceleration.w_b", POISE_FIELD(acceleration.w_b), "", "(33)", {0.0, 1.0, true, true},
     "paper Sec. 3.5: w_b = 1 makes eq (33) indeterminate", "balance weight"},
    {"acceleration.posture_weight", POISE_FIELD(acceleration.posture_weight), "", "—", kPositive,
     "it keeps the Hessian of eq (33) positive definite",
     "weight of the posture prior on every DoF"},
    {"acceleration.posture_kp", POISE_FIELD(acceleration.posture_kp), "1/s²", "—", kNonNegative, "",
     "posture prior's position gain"},
    {"acceleration.posture_kd", POISE_FIELD(acceleration.posture_kd), "1/s", "—", kNonNegative, "",
     "posture prior's velocity gain"},
    {"acceleration.upper_body_kp", POISE_FIELD(acceleration.upper_body_kp), "1/s²", "(33)",
     kNonNegative, "", "position gain of the upper body's desired accelerations q̈_u,d"},
    {"acceleration.upper_body_kd", POISE_FIELD(acceleration.upper_body_kd), "1/s", "(33)",
     kNonNegative, "", "velocity gain of the upper body's desired accelerations q̈_u,d"},
    {"acceleration.limit_horizon", POISE_FIELD(acceleration.limit_horizon), "s", "—", kPositive, "",
     "look-ahead of the joint-acceleration bounds from the position limits"},
    {"acceleration.max_joint_acceleration", POISE_FIELD(acceleration.max_joint_acceleration),
     "rad/s²", "—", kPositive, "", "clamp of the joint-acceleration bounds"},
    // eqs (34)-(35)
    {"feedback.gain_scale", POISE_FIELD(feedback.gain_scale), "", "(34)-(35)", kNonNegative, "",
     "multiplies the robot's pd_gains (robot.yaml)"},
    {"feedback.max_position_error", POISE_FIELD(feedback.max_position_error), "rad", "(34)",
     kNonNegative, "", "clamp of |θ* - θ|"},
    {"feedback.max_velocity_error", POISE_FIELD(feedback.max_velocity_error), "rad/s", "(35)",
     kNonNegative, "", "clamp of |θ̇* - θ̇|"},
    {"feedback.support_leg_leak_hz", POISE_FIELD(feedback.support_leg_leak_hz), "Hz", "(34)-(35)",
     kNonNegative, "0 = pure integration",
     "both feet loaded: the legs' references decay towards the measured joints"},
    {"feedback.internal_force_leak_hz", POISE_FIELD(feedback.internal_force_leak_hz), "Hz",
     "(34)-(35)", kNonNegative, "0 = off",
     "both feet loaded: the part of the legs' reference errors that squeezes the feet decays"},
    {"feedback.touchdown_follow_fraction", POISE_FIELD(feedback.touchdown_follow_fraction), "",
     "(34)-(35)", kFraction, "0 = off",
     "a landed support's leg follows the measured joints while planned at most this fraction "
     "of the weight"},
    {"feedback.touchdown_follow_hz", POISE_FIELD(feedback.touchdown_follow_hz), "Hz", "(34)-(35)",
     kPositive, "", "rate of that following"},
    {"feedback.velocity_leak_hz", POISE_FIELD(feedback.velocity_leak_hz), "Hz", "(35)",
     kNonNegative, "0 = pure integration",
     "every joint's θ̇* decays towards the measured velocity (damps the references' own mode)"},
    {"fallback.max_reuse_ticks", POISE_FIELD(fallback.max_reuse_ticks), "ticks", "—", kNonNegative,
     "", "a late contact solution: the previous one is reused this many ticks"},
    {"fall.tilt_deg", POISE_FIELD(fall.tilt_deg), "deg", "—", {0.0, 180.0, true, false},
     "degrees; 180: never", "fallen: the base turned this far from its start orientation"},
    {"fall.com_height_fraction", POISE_FIELD(fall.com_height_fraction), "", "—", kFraction,
     "0: never", "fallen: the CoM's height below this fraction of its start height"},
    {"com_offset.bandwidth_hz", POISE_FIELD(com_offset.bandwidth_hz), "Hz", "—", kNonNegative,
     "0: off",
     "cut-off of the model's CoM error observed from the measured CoP (below half the control "
     "rate)"},
    {"com_offset.limit", POISE_FIELD(com_offset.limit), "m", "—", {0.0, 0.2}, "",
     "largest horizontal CoM error believed"},
    {"com_offset.speed_gate", POISE_FIELD(com_offset.speed_gate), "m/s", "—", kPositive, "",
     "the observer learns only while the CoM moves slower than this relative to its supports"},
    {"resting_extra_margin", POISE_FIELD(resting_extra_margin), "m", "Sec. 4.2", kAny, "",
     "extra inset of the safe region in the resting test"},
    {"resting_force_fraction", POISE_FIELD(resting_force_fraction), "", "Sec. 4.2", kFraction, "",
     "a support foot rests only above this fraction of the weight on its F/T sensor"},
    {"resting_touchdown_force_fraction", POISE_FIELD(resting_touchdown_force_fraction), "",
     "Sec. 4.2", kFraction, "", "... a foot back from the air only above this fraction"},
    {"resting_touchdown_air_time", POISE_FIELD(resting_touchdown_air_time), "s", "Sec. 4.2",
     kNonNegative, "", "contact flag off longer than this: the foot is back from the air"},
    {"planned_support_release", POISE_FIELD(planned_support_release), "s", "—", kNonNegative,
     "0: never", "a planned support measured off the ground this long leaves the contact problem"},
    {"planned_support_release_height", POISE_FIELD(planned_support_release_height), "m", "—",
     kNonNegative, "", "... and its foot this far above where it last rested"},
    {"com_height", POISE_FIELD(com_height), "m", "Sec. 4.2", kAny, "<= 0: the nominal posture's",
     "CoM height above the soles when the reference gives none"},
};

#undef POISE_FIELD
// clang-format on

using cli::number_text;

std::string cell(std::string_view s) { return cli::markdown_cell(s); }

/// "[5, 5, 5]".
std::string vec3_text(const Eigen::Vector3d& v) {
  std::string out = "[";
  for (int i = 0; i < 3; ++i)
    out.append(i ? ", " : "").append(number_text(v[i]));
  return out.append("]");
}

}  // namespace

bool KeyRange::contains(double v) const {
  if (!std::isfinite(v)) return false;
  const bool above = lo_open ? v > lo : v >= lo;
  const bool below = hi_open ? v < hi : v <= hi;
  return above && below;
}

std::string KeyRange::text() const {
  const bool has_lo = std::isfinite(lo), has_hi = std::isfinite(hi);
  if (has_lo && has_hi)
    return "in " + std::string(lo_open ? "(" : "[") + number_text(lo) + ", " + number_text(hi) +
           (hi_open ? ")" : "]");
  if (has_lo) return (lo_open ? "> " : ">= ") + number_text(lo);
  if (has_hi) return (hi_open ? "< " : "<= ") + number_text(hi);
  return "finite";
}

std::span<const ConfigKey> controller_config_keys() {
  return kKeys;
}

bool config_key_is_numeric(const ConfigKey& key) {
  return key.field.index() <= 2;  // number, integer, vec3
}

const ConfigKey* find_controller_config_key(std::string_view dotted) {
  for (const ConfigKey& k : kKeys)
    if (k.key == dotted) return &k;
  return nullptr;
}

std::string controller_config_value_text(const ConfigKey& key, const ControllerConfig& c) {
  ControllerConfig copy = c;  // the accessors take a mutable config
  return std::visit(
      [&](auto get) -> std::string {
        const auto& v = get(copy);
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, double>)
          return number_text(v);
        else if constexpr (std::is_same_v<T, int>)
          return std::to_string(v);
        else if constexpr (std::is_same_v<T, Eigen::Vector3d>)
          return vec3_text(v);
        else
          return contact::to_string(v);
      },
      key.field);
}

std::string controller_config_markdown() {
  const ControllerConfig defaults;
  std::string out =
      "| key | default | unit | paper | allowed | description |\n"
      "|---|---|---|---|---|---|\n";
  for (const ConfigKey& k : kKeys) {
    std::string allowed = std::string(k.note);  // an enum's: its names
    if (config_key_is_numeric(k))
      allowed = k.range.text() + (k.note.empty() ? "" : " (" + std::string(k.note) + ")");
    out += "| `" + std::string(k.key) + "` | " + controller_config_value_text(k, defaults) + " | " +
           cell(k.unit.empty() ? "—" : k.unit) + " | " + cell(k.equation) + " | " + cell(allowed) +
           " | " + cell(k.doc) + " |\n";
  }
  return out;
}

}  // namespace poise::controller
