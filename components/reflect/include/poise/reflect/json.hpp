#pragma once
// JSON form of every IDL topic type: what `poise topic echo --json` prints and `poise topic pub`
// reads. Members appear in IDL order; enums as their enumerator names; arrays bounded by a length
// field (e.g. q by joint_count) carry only their valid entries. Reading accepts exactly that form:
// members may be left out (they stay 0), unknown members, wrong types, too many or (for fixed
// arrays) too few entries are errors that name the member's path.

#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "poise/reflect/traits.hpp"

namespace poise::reflect {

using Json = nlohmann::ordered_json;

/// Thrown by from_json(); what() names the offending path, e.g. "feet[1].mu: expected a number".
class JsonError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

namespace detail {

template <class T>
Json value_to_json(const T& v, long long count);

template <class S>
Json struct_to_json(const S& s) {
  Json out = Json::object();
  msg::visit_fields(s, [&](const FieldInfo& info, const auto& value) {
    out[std::string(info.name)] = value_to_json(value, count_of(s, info.count_field));
  });
  return out;
}

template <class T>
Json value_to_json(const T& v, long long count) {
  if constexpr (is_struct_v<T>) {
    return struct_to_json(v);
  } else if constexpr (is_array_v<T> || is_vector_v<T>) {
    Json arr = Json::array();
    std::size_t n = v.size();
    if (count >= 0) n = std::min<std::size_t>(n, static_cast<std::size_t>(count));
    for (std::size_t i = 0; i < n; ++i)
      arr.push_back(value_to_json(v[i], -1));
    return arr;
  } else if constexpr (is_fixed_string_v<T>) {
    return Json(v.to_string());
  } else if constexpr (is_enum_v<T>) {
    const auto name = enum_name(v);
    if (name.empty()) return Json(static_cast<long long>(v));
    return Json(std::string(name));
  } else {
    return Json(v);
  }
}

inline std::string join(const std::string& path, std::string_view name) {
  return path.empty() ? std::string(name) : path + "." + std::string(name);
}

template <class T>
void value_from_json(const Json& j, T& v, const std::string& path, const FieldInfo& info,
                     bool bounded_by_count);

template <class S>
void struct_from_json(const Json& j, S& s, const std::string& path) {
  if (!j.is_object()) {
    throw JsonError((path.empty() ? std::string("sample") : path) + ": expected an object of " +
                    std::string(msg::IdlName<S>::value));
  }
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool known = false;
    msg::visit_fields(
        s, [&](const FieldInfo& info, auto&) { known = known || info.name == it.key(); });
    if (!known) {
      std::string valid;
      msg::visit_fields(s, [&](const FieldInfo& info, auto&) {
        valid += (valid.empty() ? "" : ", ") + std::string(info.name);
      });
      throw JsonError(join(path, it.key()) + ": unknown member of " +
                      std::string(msg::IdlName<S>::value) + " (members: " + valid + ")");
    }
  }
  msg::visit_fields(s, [&](const FieldInfo& info, auto& value) {
    const auto it = j.find(std::string(info.name));
    if (it != j.end())
      value_from_json(*it, value, join(path, info.name), info, !info.count_field.empty());
  });
}

template <class T>
void value_from_json(const Json& j, T& v, const std::string& path, const FieldInfo& info,
                     bool bounded_by_count) {
  if constexpr (is_struct_v<T>) {
    struct_from_json(j, v, path);
  } else if constexpr (is_array_v<T>) {
    if (!j.is_array()) throw JsonError(path + ": expected an array");
    if (j.size() > v.size()) {
      throw JsonError(path + ": " + std::to_string(j.size()) + " entries, at most " +
                      std::to_string(v.size()));
    }
    if (!bounded_by_count && j.size() != v.size()) {
      throw JsonError(path + ": " + std::to_string(j.size()) + " entries, expected " +
                      std::to_string(v.size()));
    }
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i < j.size()) {
        value_from_json(j[i], v[i], path + "[" + std::to_string(i) + "]", info, false);
      } else {
        v[i] = {};
      }
    }
  } else if constexpr (is_vector_v<T>) {
    if (!j.is_array()) throw JsonError(path + ": expected an array");
    if (info.max_length && j.size() > info.max_length) {
      throw JsonError(path + ": " + std::to_string(j.size()) + " entries, at most " +
                      std::to_string(info.max_length));
    }
    v.resize(j.size());
    for (std::size_t i = 0; i < j.size(); ++i) {
      value_from_json(j[i], v[i], path + "[" + std::to_string(i) + "]",
                      FieldInfo{info.name, info.idl_type, 0, {}, 0}, false);
    }
  } else if constexpr (is_string_v<T>) {
    if (!j.is_string()) throw JsonError(path + ": expected a string");
    const auto text = j.template get<std::string>();
    if (info.max_length && text.size() > info.max_length) {
      throw JsonError(path + ": string of " + std::to_string(text.size()) +
                      " characters, at most " + std::to_string(info.max_length));
    }
    v = text;
  } else if constexpr (is_enum_v<T>) {
    const auto& names = msg::EnumTraits<T>::names;
    if (j.is_string()) {
      const auto s = j.template get<std::string>();
      for (std::size_t i = 0; i < names.size(); ++i) {
        if (names[i] == s) {
          v = static_cast<T>(i);
          return;
        }
      }
      std::string valid;
      for (auto n : names)
        valid += (valid.empty() ? "" : ", ") + std::string(n);
      throw JsonError(path + ": '" + s + "' is not one of " + valid);
    }
    if (j.is_number_integer() && j.template get<long long>() >= 0 &&
        j.template get<long long>() < static_cast<long long>(names.size())) {
      v = static_cast<T>(j.template get<long long>());
      return;
    }
    throw JsonError(path + ": expected an enumerator name of " +
                    std::string(msg::EnumTraits<T>::idl_name));
  } else if constexpr (is_bool_v<T>) {
    if (!j.is_boolean()) throw JsonError(path + ": expected true or false");
    v = j.template get<bool>();
  } else if constexpr (std::is_floating_point_v<T>) {
    if (!j.is_number()) throw JsonError(path + ": expected a number");
    v = j.template get<T>();
  } else {
    static_assert(std::is_integral_v<T>);
    if (!j.is_number_integer()) throw JsonError(path + ": expected an integer");
    if constexpr (std::is_unsigned_v<T>) {
      if (j.is_number_unsigned() || j.template get<long long>() >= 0) {
        const auto u = j.template get<unsigned long long>();
        if (u <= std::numeric_limits<T>::max()) {
          v = static_cast<T>(u);
          return;
        }
      }
      throw JsonError(path + ": out of range for " + std::string(info.idl_type));
    } else {
      const auto s = j.template get<long long>();
      if (s < std::numeric_limits<T>::min() || s > std::numeric_limits<T>::max()) {
        throw JsonError(path + ": out of range for " + std::string(info.idl_type));
      }
      v = static_cast<T>(s);
    }
  }
}

}  // namespace detail

/// JSON of a sample (see the top of this file for the form).
template <class T>
Json to_json(const T& sample) {
  return detail::struct_to_json(sample);
}

/// Reads `j` into `sample` (members not in `j` are reset to their defaults first).
/// Throws JsonError naming the path of the first problem.
template <class T>
void from_json(const Json& j, T& sample) {
  sample = T{};
  detail::struct_from_json(j, sample, "");
}

}  // namespace poise::reflect
