#pragma once
// Validation of incoming samples: the checks every subscriber runs before a sample reaches node
// code. Allocation-free and exception-free, so it can run in the 1 kHz loop.
//
// A sample is rejected when
//  - a length field (e.g. joint_count) exceeds its maximum (the "(<= MAX)" marker in the IDL);
//  - any floating-point value is NaN or infinite (no Poise field allows a non-finite value);
//  - a bounded string or sequence is longer than its bound;
//  - an enum holds a value that is not one of its enumerators.

#include <cmath>
#include <cstdio>
#include <cstring>

#include "poise/reflect/traits.hpp"

namespace poise::reflect {

/// Why a sample was rejected: the field path (e.g. "feet[1].pose_W.position[2]") and the reason.
struct ValidationError {
  char path[96] = {};
  char reason[96] = {};
  /// "path: reason", for one log line.
  void format(char* out, std::size_t size) const {
    std::snprintf(out, size, "%s: %s", path, reason);
  }
};

namespace detail {

/// Walks a sample. With kTrackPath = false it only decides valid/invalid (the fast path every
/// sample takes); with true it also builds the path of the first bad field (only run on failure).
template <bool kTrackPath>
struct Validator {
  ValidationError* error;
  char path[96] = {};
  std::size_t path_len = 0;
  bool failed = false;

  void fail(const char* fmt, double a = 0, double b = 0) {
    if (failed) return;
    failed = true;
    if (kTrackPath && error) {
      std::memcpy(error->path, path, sizeof(path));
      std::snprintf(error->reason, sizeof(error->reason), fmt, a, b);
    }
  }

  // Appends ".name" or "[i]" to the path; returns the old length to restore.
  std::size_t push(std::string_view name) {
    if constexpr (!kTrackPath) return 0;
    const std::size_t old = path_len;
    const int n = std::snprintf(path + path_len, sizeof(path) - path_len, "%s%.*s",
                                path_len ? "." : "", static_cast<int>(name.size()), name.data());
    if (n > 0) path_len = std::min(sizeof(path) - 1, path_len + static_cast<std::size_t>(n));
    return old;
  }
  std::size_t push_index(std::size_t i) {
    if constexpr (!kTrackPath) return 0;
    const std::size_t old = path_len;
    const int n = std::snprintf(path + path_len, sizeof(path) - path_len, "[%zu]", i);
    if (n > 0) path_len = std::min(sizeof(path) - 1, path_len + static_cast<std::size_t>(n));
    return old;
  }
  void pop(std::size_t old) {
    if constexpr (!kTrackPath) return;
    path_len = old;
    path[path_len] = '\0';
  }

  template <class T>
  void value(const FieldInfo& info, const T& v) {
    if (failed) return;
    if constexpr (is_struct_v<T>) {
      msg::visit_fields(v, *this);
    } else if constexpr (is_float_array_v<T> && !kTrackPath) {
      // Fast path: NaN and +-inf survive x * 0, finite values give 0; this loop vectorises.
      typename T::value_type sum = 0;
      for (const auto& e : v)
        sum += e * 0;
      if (sum != 0) fail("non-finite");
    } else if constexpr (is_array_v<T>) {
      for (std::size_t i = 0; i < v.size() && !failed; ++i) {
        const auto old = push_index(i);
        value(info, v[i]);
        pop(old);
      }
    } else if constexpr (is_vector_v<T>) {
      if (info.max_length && v.size() > info.max_length) {
        fail("sequence length %.0f exceeds its bound %.0f", static_cast<double>(v.size()),
             static_cast<double>(info.max_length));
        return;
      }
      for (std::size_t i = 0; i < v.size() && !failed; ++i) {
        const auto old = push_index(i);
        value(FieldInfo{info.name, info.idl_type, 0, {}, 0}, v[i]);
        pop(old);
      }
    } else if constexpr (is_string_v<T>) {
      if (info.max_length && v.size() > info.max_length) {
        fail("string length %.0f exceeds its bound %.0f", static_cast<double>(v.size()),
             static_cast<double>(info.max_length));
      }
    } else if constexpr (is_enum_v<T>) {
      if (enum_name(v).empty()) fail("%.0f is not a valid enumerator", static_cast<double>(v));
    } else if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(v)) fail(std::isnan(v) ? "is NaN" : "is infinite");
    } else if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
      if (info.count_bound && static_cast<unsigned long long>(v) > info.count_bound) {
        fail("length field %.0f exceeds the fixed maximum %.0f", static_cast<double>(v),
             static_cast<double>(info.count_bound));
      }
    }
  }

  template <class T>
  void operator()(const FieldInfo& info, const T& v) {
    if (failed) return;
    const auto old = push(info.name);
    value(info, v);
    pop(old);
  }
};

}  // namespace detail

/// Checks `sample`. Returns true when it is valid; otherwise fills `error` (if not null) with the
/// first offending field. Allocation-free, noexcept.
template <class T>
bool validate(const T& sample, ValidationError* error = nullptr) noexcept {
  detail::Validator<false> fast{nullptr};
  msg::visit_fields(sample, fast);
  if (!fast.failed) return true;
  if (error) {
    detail::Validator<true> named{error};
    msg::visit_fields(sample, named);
  }
  return false;
}

}  // namespace poise::reflect
