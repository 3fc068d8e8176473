#pragma once
// Validation of incoming samples before delivery to node code.
//
// With the reflection library (components/reflect, generated visit_fields) every field is
// checked: length fields against their maximum, every floating-point value finite, enums valid,
// bounded strings and sequences within their bound. Without it (POISE_DDS_HAVE_REFLECT unset)
// a hand-written subset checks the length fields and the per-joint arrays.

#include <cmath>
#include <cstddef>
#include <cstdio>

#include <poise/msg/balance_reference.h>
#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/diagnostics.h>
#include <poise/msg/disturbance.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>

#if POISE_DDS_HAVE_REFLECT
#include <poise/reflect/validate.hpp>
#endif

namespace poise::dds::detail {

#if POISE_DDS_HAVE_REFLECT

/// The same checks as poise::reflect::validate, without building the field path (which costs
/// ~10-25 us per 1 kHz sample): runs on every sample; the full validator runs only on failure,
/// to name the field.
struct FastCheck {
  bool ok = true;

  template <class T>
  void value(const poise::reflect::FieldInfo& info, const T& v) {
    using namespace poise::reflect;
    if constexpr (is_struct_v<T>) {
      poise::msg::visit_fields(v, *this);
    } else if constexpr (is_array_v<T>) {
      using E = typename T::value_type;
      if constexpr (std::is_floating_point_v<E>) {
        E sum = 0;  // NaN and +-inf survive x * 0; finite values give 0
        for (const E& e : v)
          sum += e * 0;
        ok &= sum == 0;
      } else {
        for (const auto& e : v)
          value(info, e);
      }
    } else if constexpr (is_vector_v<T>) {
      if (info.max_length && v.size() > info.max_length) {
        ok = false;
        return;
      }
      for (const auto& e : v)
        value(FieldInfo{info.name, info.idl_type, 0, {}, 0}, e);
    } else if constexpr (is_string_v<T>) {
      if (info.max_length && v.size() > info.max_length) ok = false;
    } else if constexpr (is_enum_v<T>) {
      if (enum_name(v).empty()) ok = false;
    } else if constexpr (std::is_floating_point_v<T>) {
      ok &= static_cast<bool>(std::isfinite(v));
    } else if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
      if (info.count_bound && static_cast<unsigned long long>(v) > info.count_bound) ok = false;
    }
  }

  template <class T>
  void operator()(const poise::reflect::FieldInfo& info, const T& v) {
    if (ok) value(info, v);
  }
};

template <class T>
bool validate_sample(const T& sample, char* why, std::size_t why_size) noexcept {
  FastCheck fast;
  poise::msg::visit_fields(sample, fast);
  if (fast.ok) return true;
  poise::reflect::ValidationError error;
  if (poise::reflect::validate(sample, &error)) return true;  // cannot happen: same checks
  error.format(why, why_size);
  return false;
}

#else

inline bool check_count(const char* name, unsigned long long value, unsigned long long max,
                        char* why, std::size_t n) {
  if (value <= max) return true;
  std::snprintf(why, n, "%s: length field %llu exceeds the fixed maximum %llu", name, value, max);
  return false;
}

template <std::size_t N>
bool check_finite(const char* name, const std::array<double, N>& a, char* why, std::size_t n) {
  for (std::size_t i = 0; i < N; ++i) {
    if (!std::isfinite(a[i])) {
      std::snprintf(why, n, "%s[%zu]: %s", name, i, std::isnan(a[i]) ? "is NaN" : "is infinite");
      return false;
    }
  }
  return true;
}

template <class T>
bool validate_sample(const T&, char*, std::size_t) noexcept {
  return true;
}

inline bool validate_sample(const poise::msg::Sensors& s, char* why, std::size_t n) noexcept {
  return check_count("joint_count", s.joint_count(), 64, why, n) &&
         check_finite("q", s.q(), why, n) && check_finite("qd", s.qd(), why, n) &&
         check_finite("tau_measured", s.tau_measured(), why, n);
}
inline bool validate_sample(const poise::msg::State& s, char* why, std::size_t n) noexcept {
  return check_count("joint_count", s.joint_count(), 64, why, n) &&
         check_finite("q", s.q(), why, n) && check_finite("qd", s.qd(), why, n) &&
         check_finite("com_W", s.com_W(), why, n);
}
inline bool validate_sample(const poise::msg::JointCommand& s, char* why, std::size_t n) noexcept {
  return check_count("joint_count", s.joint_count(), 64, why, n) &&
         check_finite("tau_ff", s.tau_ff(), why, n) && check_finite("q_ref", s.q_ref(), why, n) &&
         check_finite("qd_ref", s.qd_ref(), why, n) && check_finite("kp", s.kp(), why, n) &&
         check_finite("kd", s.kd(), why, n);
}
inline bool validate_sample(const poise::msg::BalanceReference& s, char* why,
                            std::size_t n) noexcept {
  return check_count("joint_count", s.joint_count(), 64, why, n) &&
         check_finite("com_W", s.com_W(), why, n) &&
         check_finite("upper_body_qdd", s.upper_body_qdd(), why, n);
}
inline bool validate_sample(const poise::msg::GroundTruth& s, char* why, std::size_t n) noexcept {
  return check_count("other_contact_count", s.other_contact_count(), 8, why, n) &&
         check_finite("com_W", s.com_W(), why, n);
}
inline bool validate_sample(const poise::msg::RobotDescription& s, char* why,
                            std::size_t n) noexcept {
  return check_count("joint_names (sequence length)", s.joint_names().size(), 64, why, n);
}

#endif

}  // namespace poise::dds::detail
