#pragma once
// Test support: fill any IDL sample with seeded pseudo-random but VALID content (counts within
// bounds, finite numbers, valid enumerators, strings within bounds), and compare two samples
// field by field, naming the first difference. Used by the interop test and the JSON round trip.

#include <optional>
#include <random>
#include <string>

#include "poise/reflect/traits.hpp"

namespace poise::reflect {

namespace detail {

template <class T>
void fill_value(T& v, const FieldInfo& info, std::mt19937_64& rng) {
  if constexpr (is_struct_v<T>) {
    msg::visit_fields(v, [&](const FieldInfo& i, auto& m) { fill_value(m, i, rng); });
    // Canonical form: entries past a length field are zero (as the IDL asks of writers).
    msg::visit_fields(v, [&](const FieldInfo& i, auto& m) {
      using M = std::remove_cvref_t<decltype(m)>;
      if constexpr (is_array_v<M>) {
        const long long count = count_of(v, i.count_field);
        for (std::size_t k = count < 0 ? m.size() : static_cast<std::size_t>(count); k < m.size();
             ++k) {
          m[k] = {};
        }
      }
    });
  } else if constexpr (is_array_v<T>) {
    for (auto& e : v)
      fill_value(e, info, rng);
  } else if constexpr (is_vector_v<T>) {
    const std::size_t bound = info.max_length ? info.max_length : 8;
    v.resize(std::uniform_int_distribution<std::size_t>(0, std::min<std::size_t>(bound, 8))(rng));
    for (auto& e : v)
      fill_value(e, FieldInfo{info.name, info.idl_type, 0, {}, 0}, rng);
  } else if constexpr (is_string_v<T>) {
    const std::size_t bound = info.max_length ? info.max_length : 300;
    std::string text(std::uniform_int_distribution<std::size_t>(0, bound)(rng), ' ');
    for (auto& c : text)
      c = static_cast<char>(std::uniform_int_distribution<int>('a', 'z')(rng));
    v = text;
  } else if constexpr (is_enum_v<T>) {
    const auto n = msg::EnumTraits<T>::names.size();
    v = static_cast<T>(std::uniform_int_distribution<std::size_t>(0, n - 1)(rng));
  } else if constexpr (is_bool_v<T>) {
    v = (rng() & 1u) != 0;
  } else if constexpr (std::is_floating_point_v<T>) {
    v = static_cast<T>(std::uniform_real_distribution<double>(-1e3, 1e3)(rng));
  } else {
    static_assert(std::is_integral_v<T>);
    if (info.count_bound) {
      v = static_cast<T>(
          std::uniform_int_distribution<unsigned long long>(0, info.count_bound)(rng));
    } else {
      v = static_cast<T>(rng());
    }
  }
}

template <class T>
std::optional<std::string> diff_value(const T& a, const T& b, const std::string& path) {
  if constexpr (is_struct_v<T>) {
    std::optional<std::string> result;
    msg::visit_fields(a, [&](const FieldInfo& info, const auto& ma) {
      if (result) return;
      // Find the same member in b by name (visit order is identical).
      msg::visit_fields(b, [&](const FieldInfo& ib, const auto& mb) {
        if constexpr (std::is_same_v<decltype(ma), decltype(mb)>) {
          if (!result && ib.name == info.name) {
            result = diff_value(
                ma, mb,
                path.empty() ? std::string(info.name) : path + "." + std::string(info.name));
          }
        }
      });
    });
    return result;
  } else if constexpr (is_array_v<T> || is_vector_v<T>) {
    if (a.size() != b.size()) {
      return path + ": length " + std::to_string(a.size()) + " vs " + std::to_string(b.size());
    }
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (auto d = diff_value(a[i], b[i], path + "[" + std::to_string(i) + "]")) return d;
    }
    return std::nullopt;
  } else if constexpr (is_string_v<T>) {
    if (a != b)
      return path + ": strings differ (length " + std::to_string(a.size()) + " vs " +
             std::to_string(b.size()) + ")";
    return std::nullopt;
  } else {
    if (a != b) {
      if constexpr (is_enum_v<T>) {
        return path + ": " + std::to_string(static_cast<long long>(a)) + " vs " +
               std::to_string(static_cast<long long>(b));
      } else {
        return path + ": " + std::to_string(a) + " vs " + std::to_string(b);
      }
    }
    return std::nullopt;
  }
}

}  // namespace detail

/// Fills every member of `sample` with valid pseudo-random content drawn from `rng`.
template <class T>
void fill_random(T& sample, std::mt19937_64& rng) {
  detail::fill_value(sample, FieldInfo{}, rng);
}

/// The path and values of the first member where `a` and `b` differ, or nullopt if equal.
template <class T>
std::optional<std::string> first_difference(const T& a, const T& b) {
  return detail::diff_value(a, b, "");
}

}  // namespace poise::reflect
